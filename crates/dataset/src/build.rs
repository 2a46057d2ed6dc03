//! Joining a bag's messages by stamp into simulator steps, then steps into transitions.

use std::path::{Path, PathBuf};

use causal_arm_bag::{BagReader, RawMessage};
use causal_arm_msgs::geometry_msgs::msg::PoseStamped;
use causal_arm_msgs::msg::{Action, MagnetState, ObjectColor};
use causal_arm_msgs::sensor_msgs::msg::JointState;
use causal_arm_protocol::{
    Draw, StepJoiner, StepMessages, StepParts, bag_keys, design_of, fill, ns_from_time, topics,
};
use nalgebra::{Quaternion, UnitQuaternion};

use crate::{ActionSource, Dataset, DatasetError, Experiment, state_names};

/// Where rows of a dataset came from (stored in model files for provenance).
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct BagSource {
    /// Bag directory as given.
    pub path: String,
    /// BLAKE3 of the MCAP file, hex.
    pub blake3: String,
    /// Transitions taken from it.
    pub rows: usize,
}

causal_arm_protocol::step_parts! {
    /// What one simulator step contributed, kept compact (2M steps for the paper's exp 2).
    struct Partial {
        theta: [f64; 7] = topics::JOINT_STATES,
        ef: [f64; 6] = topics::EF_POSE,
        object: [f64; 6] = topics::OBJECT_POSE,
        colour: [f32; 3] = topics::OBJECT_COLOR,
        /// (on, holding).
        magnet: (bool, bool) = topics::MAGNET_STATE,
        /// (episode, step, commanded deltas, magnet command, randomized components).
        action: (u32, u32, [f64; 7], i8, Option<u32>) = topics::ACTION,
    }
}

/// Topics a step needs, in the order used in messages.
fn step_topics() -> Vec<&'static str> {
    Partial::default().missing()
}

/// One complete step.
#[derive(Debug, Clone)]
struct Step {
    stamp: u64,
    values: StepValues,
    /// The magnet held the cube.
    holding: bool,
    episode: u32,
    step: u32,
    commanded: [f64; 7],
    magnet_command: i8,
    /// Which components the design drew at random (bit j), if the action says.
    randomized: Option<u32>,
}

/// The state-bearing values of one simulator step, as the bag's messages carry them.
#[derive(Debug, Clone)]
struct StepValues {
    theta: [f64; 7],
    ef: [f64; 6],
    object: [f64; 6],
    colour: [f32; 3],
    magnet_on: bool,
}

impl StepValues {
    /// s in the experiment's feature order (see [`state_names`]), in f64, one value at a time.
    fn features(&self, experiment: Experiment, mut push: impl FnMut(f64)) {
        match experiment {
            Experiment::Exp1 => {
                self.theta
                    .iter()
                    .chain(&self.ef[..3])
                    .for_each(|&v| push(v));
            }
            Experiment::Exp2 => {
                self.object.iter().for_each(|&v| push(v));
                self.colour.iter().for_each(|&v| push(f64::from(v)));
                self.theta.iter().chain(&self.ef).for_each(|&v| push(v));
                push(if self.magnet_on { 1.0 } else { 0.0 });
            }
        }
    }

    fn state(&self, experiment: Experiment, out: &mut Vec<f32>) {
        self.features(experiment, |v| out.push(v as f32));
    }
}

/// The state vector s(t) of one simulator step, in f64 and in the dataset's feature order
/// and conventions (Euler angles from the messages' quaternions): what the simulator's
/// interventions compare, so truth and learning data cannot disagree on a feature.
pub fn state_features(experiment: Experiment, messages: &StepMessages) -> Vec<f64> {
    let theta = messages
        .joint_states
        .position
        .as_slice()
        .try_into()
        .unwrap_or([f64::NAN; 7]);
    let c = &messages.object_color.color;
    let values = StepValues {
        theta,
        ef: pose6(&messages.ef_pose),
        object: pose6(&messages.object_pose),
        colour: [c.r, c.g, c.b],
        magnet_on: messages.magnet.on,
    };
    let mut out = Vec::with_capacity(23);
    values.features(experiment, |v| out.push(v));
    out
}

/// Position and Euler angles (roll, pitch, yaw about fixed x, y, z, as PyBullet reports).
fn pose6(pose: &PoseStamped) -> [f64; 6] {
    let p = &pose.pose.position;
    let o = &pose.pose.orientation;
    let (roll, pitch, yaw) =
        UnitQuaternion::from_quaternion(Quaternion::new(o.w, o.x, o.y, o.z)).euler_angles();
    [p.x, p.y, p.z, roll, pitch, yaw]
}

fn seven(values: &[f64], what: &str, stamp: u64) -> Result<[f64; 7], String> {
    values.try_into().map_err(|_| {
        format!(
            "{what} at stamp {stamp} ns has {} values, expected 7",
            values.len()
        )
    })
}

/// Files one decoded message into its step (see `StepJoiner::insert`).
type PutPart = Box<dyn FnOnce(&mut Partial) -> bool>;

/// Reads one bag into steps, checking the step protocol.
struct StepReader<'a> {
    reader: &'a BagReader,
    bag: PathBuf,
    topics: Vec<&'static str>,
    joiner: StepJoiner<Partial>,
    steps: Vec<Step>,
}

impl StepReader<'_> {
    fn content(&self, problem: String) -> DatasetError {
        content_error(&self.bag, problem)
    }

    fn add(&mut self, raw: &RawMessage) -> Result<(), DatasetError> {
        let Some(topic) = self.topics.iter().copied().find(|t| *t == raw.topic) else {
            return Ok(());
        };
        let (stamp, put): (u64, PutPart) = match topic {
            topics::JOINT_STATES => {
                let m: JointState = self.reader.decode(raw)?;
                let stamp = ns_from_time(&m.header.stamp);
                let theta = seven(&m.position, "/joint_states position", stamp)
                    .map_err(|e| self.content(e))?;
                (stamp, Box::new(move |p| fill(&mut p.theta, theta)))
            }
            topics::EF_POSE | topics::OBJECT_POSE => {
                let m: PoseStamped = self.reader.decode(raw)?;
                let pose = pose6(&m);
                let put: PutPart = if topic == topics::EF_POSE {
                    Box::new(move |p| fill(&mut p.ef, pose))
                } else {
                    Box::new(move |p| fill(&mut p.object, pose))
                };
                (ns_from_time(&m.header.stamp), put)
            }
            topics::OBJECT_COLOR => {
                let m: ObjectColor = self.reader.decode(raw)?;
                let rgb = [m.color.r, m.color.g, m.color.b];
                (
                    ns_from_time(&m.header.stamp),
                    Box::new(move |p| fill(&mut p.colour, rgb)),
                )
            }
            topics::MAGNET_STATE => {
                let m: MagnetState = self.reader.decode(raw)?;
                (
                    ns_from_time(&m.header.stamp),
                    Box::new(move |p| fill(&mut p.magnet, (m.on, m.holding))),
                )
            }
            _ => {
                let m: Action = self.reader.decode(raw)?;
                let stamp = ns_from_time(&m.header.stamp);
                let deltas = seven(&m.joint_deltas, "/babbler/action joint_deltas", stamp)
                    .map_err(|e| self.content(e))?;
                let randomized = randomized_components(&m)
                    .map_err(|e| self.content(format!("{topic} at {stamp} ns: {e}")))?;
                let action = (m.episode, m.step, deltas, m.magnet, randomized);
                (stamp, Box::new(move |p| fill(&mut p.action, action)))
            }
        };
        if self.joiner.insert(topic, stamp, put).is_err() {
            return Err(self.content(format!("two {topic} messages with stamp {stamp} ns")));
        }
        if let Some(p) = self.joiner.take_if_complete(stamp) {
            self.steps.push(Step::from_parts(stamp, p));
        }
        Ok(())
    }
}

impl Step {
    /// The step of a complete `Partial`.
    fn from_parts(stamp: u64, p: Partial) -> Self {
        let (episode, step, commanded, magnet_command, randomized) = p.action.expect("complete");
        let (magnet_on, holding) = p.magnet.expect("complete");
        Self {
            stamp,
            values: StepValues {
                theta: p.theta.expect("complete"),
                ef: p.ef.expect("complete"),
                object: p.object.expect("complete"),
                colour: p.colour.expect("complete"),
                magnet_on,
            },
            holding,
            episode,
            step,
            commanded,
            magnet_command,
            randomized,
        }
    }
}

/// Which components of an action its design drew at random (bit j: component j), `None`
/// when it records no design; a malformed design is an error.
fn randomized_components(action: &Action) -> Result<Option<u32>, String> {
    // The joints, and the magnet in exp 2 (the experiment is known only once every step
    // has been read).
    let joints = action.joint_deltas.len();
    let components = match action.design.len() == joints {
        true => joints,
        false => joints + 1,
    };
    let Some(design) = design_of(&action.design, components)? else {
        return Ok(None);
    };
    Ok(Some(
        (design.iter().enumerate())
            .filter(|(_, d)| !matches!(d, Draw::Scripted))
            .fold(0, |mask, (j, _)| mask | (1 << j)),
    ))
}

/// The experiment a bag holds: from the run's own record, else from its actions (exp 2
/// switches the magnet and has episodes).
fn experiment_of(reader: &BagReader, steps: &[Step]) -> (Experiment, String) {
    if let Some(label) = reader.custom_data().get(bag_keys::EXPERIMENT)
        && let Ok(exp) = label.parse::<Experiment>()
    {
        return (exp, format!("custom_data {}={label}", bag_keys::EXPERIMENT));
    }
    let magnet = steps.iter().any(|s| s.magnet_command != 0);
    let episodes = steps.iter().any(|s| s.episode > 0);
    if magnet || episodes {
        (
            Experiment::Exp2,
            "its actions switch the magnet or change episode".into(),
        )
    } else {
        (
            Experiment::Exp1,
            "no magnet commands and one episode".into(),
        )
    }
}

/// BLAKE3 of the bag's MCAP files in order, hex (the cache key and the provenance of a
/// model): for a bag of one file, that file's `b3sum`; for a split bag, that of their
/// concatenation.
pub(crate) fn hash_bag(reader: &BagReader) -> Result<String, DatasetError> {
    let mut hasher = blake3::Hasher::new();
    for file in reader.files() {
        let path = &file.path;
        let cannot = |e: std::io::Error| DatasetError::Cache {
            path: path.to_owned(),
            problem: format!("cannot read for hashing: {e}"),
        };
        hasher
            .update_reader(std::fs::File::open(path).map_err(cannot)?)
            .map_err(cannot)?;
    }
    Ok(hasher.finalize().to_hex().to_string())
}

/// A [`DatasetError::Content`] naming `bag`.
fn content_error(bag: &Path, problem: String) -> DatasetError {
    DatasetError::Content {
        bag: bag.to_owned(),
        problem,
    }
}

/// Refuses early, before decoding millions of messages, a bag whose own record says it
/// holds the other experiment.
fn refuse_recorded_experiment(
    reader: &BagReader,
    bag: &Path,
    expected: Option<Experiment>,
) -> Result<(), DatasetError> {
    if let (Some(expected), Some(label)) =
        (expected, reader.custom_data().get(bag_keys::EXPERIMENT))
    {
        // Refuse early, before decoding millions of messages.
        if label
            .parse::<Experiment>()
            .is_ok_and(|found| found != expected)
        {
            return Err(DatasetError::WrongExperiment {
                bag: bag.to_owned(),
                found: label.parse().expect("checked"),
                expected,
                how: format!("custom_data {}={label}", bag_keys::EXPERIMENT),
            });
        }
    }
    Ok(())
}

/// Every complete step of the bag in stamp order; refuses a bag missing a topic or with
/// an incomplete step (except the last one of a bag cut short, which is dropped).
fn read_steps(reader: &BagReader, bag: &Path) -> Result<Vec<Step>, DatasetError> {
    let mut steps = StepReader {
        reader,
        bag: bag.to_owned(),
        topics: step_topics(),
        joiner: StepJoiner::new(),
        steps: Vec::new(),
    };
    for raw in reader.messages() {
        steps.add(&raw?)?;
    }
    for topic in step_topics() {
        if !reader
            .topics()
            .iter()
            .any(|t| t.name == topic && t.message_count > 0)
        {
            return Err(content_error(bag, format!("no messages on {topic}")));
        }
    }
    let StepReader {
        joiner,
        steps: mut all,
        ..
    } = steps;
    let pending = joiner.into_pending();
    all.sort_by_key(|s| s.stamp);
    let last_complete = all.last().map(|s| s.stamp).unwrap_or(0);
    for (stamp, partial) in &pending {
        // A crashed writer may leave the last step half-written; anything else is a hole.
        if reader.truncation().is_some() && *stamp > last_complete {
            tracing::warn!(
                "{}: dropping the incomplete last step at {stamp} ns (bag was cut short; missing {})",
                bag.display(),
                partial.missing().join(", ")
            );
            continue;
        }
        return Err(content_error(
            bag,
            format!(
                "step at stamp {stamp} ns has no message on {}",
                partial.missing().join(", ")
            ),
        ));
    }
    Ok(all)
}

/// Whether `next` follows `now` as a transition: `Ok(false)` at the reset between
/// episodes, an error for a gap in stamps or a hole in the episode/step counters.
fn is_transition(bag: &Path, now: &Step, next: &Step, period: u64) -> Result<bool, DatasetError> {
    let dt = next.stamp - now.stamp;
    if dt.abs_diff(period) > period / 100 + 1 {
        return Err(content_error(
            bag,
            format!(
                "gap on {}: stamp {} ns follows {} ns, expected a step of {period} ns",
                topics::JOINT_STATES,
                next.stamp,
                now.stamp
            ),
        ));
    }
    if next.episode != now.episode {
        if next.step != 0 || next.episode != now.episode + 1 {
            return Err(content_error(
                bag,
                format!(
                    "{} at stamp {} ns: episode {} step {} follows episode {} step {}",
                    topics::ACTION,
                    next.stamp,
                    next.episode,
                    next.step,
                    now.episode,
                    now.step
                ),
            ));
        }
        // The reset between episodes is not a transition.
        return Ok(false);
    }
    if next.step != now.step + 1 {
        return Err(content_error(
            bag,
            format!(
                "{} at stamp {} ns: step {} follows step {} in episode {}",
                topics::ACTION,
                next.stamp,
                next.step,
                now.step,
                now.episode
            ),
        ));
    }
    Ok(true)
}

/// Appends the row of the transition `now` → `next` to `data`.
fn push_transition(data: &mut Dataset, now: &Step, next: &Step, action_source: ActionSource) {
    let experiment = data.experiment;
    now.values.state(experiment, &mut data.states);
    next.values.state(experiment, &mut data.next_states);
    match action_source {
        ActionSource::Realized => data
            .actions
            .extend((0..7).map(|j| (next.values.theta[j] - now.values.theta[j]) as f32)),
        ActionSource::Commanded => data.actions.extend(now.commanded.iter().map(|&v| v as f32)),
    }
    if experiment == Experiment::Exp2 {
        data.actions.push(now.magnet_command as f32);
    }
    data.episodes.push(now.episode);
    data.holding.push(now.holding as u8);
    data.steps.push(now.step);
    data.stamps_ns.push(now.stamp);
}

/// Builds the transitions of one bag. `expected` refuses a bag of the other experiment;
/// `None` accepts either and reports which in [`Dataset::experiment`].
pub fn from_bag(
    bag: &Path,
    expected: Option<Experiment>,
    action_source: ActionSource,
) -> Result<Dataset, DatasetError> {
    let reader = BagReader::open(bag)?;
    refuse_recorded_experiment(&reader, bag, expected)?;
    let all = read_steps(&reader, bag)?;
    if all.len() < 2 {
        return Err(content_error(
            bag,
            format!(
                "{} complete steps; need at least 2 for one transition",
                all.len()
            ),
        ));
    }
    let (experiment, how) = experiment_of(&reader, &all);
    if let Some(expected) = expected
        && expected != experiment
    {
        return Err(DatasetError::WrongExperiment {
            bag: bag.to_owned(),
            found: experiment,
            expected,
            how,
        });
    }

    let period = all[1].stamp - all[0].stamp;
    let width = state_names(experiment).len();
    let mut data = Dataset::empty(experiment, action_source);
    data.states.reserve(all.len() * width);
    data.next_states.reserve(all.len() * width);
    data.episodes.reserve(all.len());
    data.holding.reserve(all.len());
    data.steps.reserve(all.len());
    data.stamps_ns.reserve(all.len());
    let mut randomized = Vec::with_capacity(all.len());
    for pair in all.windows(2) {
        let (now, next) = (&pair[0], &pair[1]);
        if is_transition(bag, now, next, period)? {
            push_transition(&mut data, now, next, action_source);
            randomized.push(now.randomized);
        }
    }
    // Known only where every action says.
    data.randomized = randomized.into_iter().collect();
    data.sources.push(BagSource {
        path: bag.display().to_string(),
        blake3: hash_bag(&reader)?,
        rows: data.rows(),
    });
    Ok(data)
}
