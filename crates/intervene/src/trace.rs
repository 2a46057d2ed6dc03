//! A bag read back as the simulator's input: the run's settings and every recorded command,
//! with the recorded joint positions to prove the re-simulation follows the bag exactly.

use std::collections::BTreeMap;
use std::path::Path;

use causal_arm_bag::BagReader;
use causal_arm_msgs::msg::Action;
use causal_arm_msgs::sensor_msgs::msg::JointState;
use causal_arm_protocol::{Command, Experiment, bag_keys, ns_from_time, topics};
use causal_arm_sim::ArmMode;

use crate::InterveneError;

/// One recorded simulator step: the state's stamp and joints, and the command answering it.
#[derive(Debug, Clone)]
pub struct TraceStep {
    /// Sim time of the state, ns.
    pub stamp_ns: u64,
    /// Episode of the state.
    pub episode: u32,
    /// Step within the episode.
    pub step: u32,
    /// Joint positions the bag recorded for the state, rad.
    pub theta: [f64; 7],
    /// The babbler's command answering the state.
    pub command: Command,
}

/// What the simulator needs to revisit every state of a bag.
#[derive(Debug, Clone)]
pub struct Trace {
    /// Experiment the bag holds.
    pub experiment: Experiment,
    /// Run seed (the simulator's seed is derived from it).
    pub seed: u64,
    /// Scale of the URDF joint velocity limits the run used.
    pub velocity_scale: f64,
    /// How the run's simulator moved the arm.
    pub arm: ArmMode,
    /// Every step, in stamp order.
    pub steps: Vec<TraceStep>,
}

fn custom<T: std::str::FromStr>(
    bag: &Path,
    data: &BTreeMap<String, String>,
    key: &str,
) -> Result<T, InterveneError> {
    let text = data.get(key).ok_or_else(|| InterveneError::Bag {
        bag: bag.to_owned(),
        problem: format!(
            "metadata has no custom_data {key}; only bags written by causal-arm generate/launch record the run settings a re-simulation needs"
        ),
    })?;
    text.parse().map_err(|_| InterveneError::Bag {
        bag: bag.to_owned(),
        problem: format!("custom_data {key}={text:?} is not a valid value"),
    })
}

fn seven(values: &[f64], what: &str, stamp: u64, bag: &Path) -> Result<[f64; 7], InterveneError> {
    values.try_into().map_err(|_| InterveneError::Bag {
        bag: bag.to_owned(),
        problem: format!(
            "{what} at stamp {stamp} ns has {} values, expected 7",
            values.len()
        ),
    })
}

impl Trace {
    /// Reads `bag`, refusing one that does not hold `expected` or lacks the run settings.
    pub fn read(bag: &Path, expected: Experiment) -> Result<Self, InterveneError> {
        let reader = BagReader::open(bag)?;
        let data = reader.custom_data();
        let experiment: Experiment = custom(bag, &data, bag_keys::EXPERIMENT)?;
        if experiment != expected {
            return Err(InterveneError::Bag {
                bag: bag.to_owned(),
                problem: format!(
                    "holds {experiment} data (custom_data {}={experiment}), expected {expected}",
                    bag_keys::EXPERIMENT
                ),
            });
        }
        let seed = custom(bag, &data, bag_keys::SEED)?;
        let velocity_scale = custom(bag, &data, bag_keys::VELOCITY_SCALE)?;
        let arm = match data.get(bag_keys::ARM) {
            None => ArmMode::Kinematic, // written before the dynamic arm existed
            Some(_) => custom(bag, &data, bag_keys::ARM)?,
        };
        let mut theta: BTreeMap<u64, [f64; 7]> = BTreeMap::new();
        let mut actions: BTreeMap<u64, Action> = BTreeMap::new();
        for raw in reader.messages() {
            let raw = raw?;
            match raw.topic.as_str() {
                topics::JOINT_STATES => {
                    let m: JointState = reader.decode(&raw)?;
                    let stamp = ns_from_time(&m.header.stamp);
                    theta.insert(stamp, seven(&m.position, "/joint_states", stamp, bag)?);
                }
                topics::ACTION => {
                    let m: Action = reader.decode(&raw)?;
                    actions.insert(ns_from_time(&m.header.stamp), m);
                }
                _ => {}
            }
        }
        let mut steps = Vec::with_capacity(actions.len());
        for (stamp, action) in actions {
            let Some(&joints) = theta.get(&stamp) else {
                return Err(InterveneError::Bag {
                    bag: bag.to_owned(),
                    problem: format!(
                        "{} at stamp {stamp} ns answers no {} message",
                        topics::ACTION,
                        topics::JOINT_STATES
                    ),
                });
            };
            steps.push(TraceStep {
                stamp_ns: stamp,
                episode: action.episode,
                step: action.step,
                theta: joints,
                command: Command {
                    joint_targets: seven(
                        &action.joint_targets,
                        "/babbler/action joint_targets",
                        stamp,
                        bag,
                    )?,
                    magnet: action.magnet,
                },
            });
        }
        if steps.is_empty() {
            return Err(InterveneError::Bag {
                bag: bag.to_owned(),
                problem: format!("no messages on {}", topics::ACTION),
            });
        }
        Ok(Self {
            experiment,
            seed,
            velocity_scale,
            arm,
            steps,
        })
    }

    /// Indices of steps whose next `horizon` steps stay in the same episode (a transition
    /// never crosses an episode reset).
    pub fn transition_starts(&self, horizon: usize) -> Vec<usize> {
        (0..self.steps.len().saturating_sub(horizon))
            .filter(|&i| {
                let s = &self.steps[i];
                let end = &self.steps[i + horizon];
                end.episode == s.episode && end.step as usize == s.step as usize + horizon
            })
            .collect()
    }

    /// Standard deviation of every joint's commanded delta (target − position) over the
    /// bag: the unit of the interventions, so they span what the babbler really commands.
    pub fn command_delta_std(&self) -> [f64; 7] {
        let n = self.steps.len().max(1) as f64;
        std::array::from_fn(|j| {
            let d = |s: &TraceStep| s.command.joint_targets[j] - s.theta[j];
            let mean = self.steps.iter().map(d).sum::<f64>() / n;
            (self
                .steps
                .iter()
                .map(|s| (d(s) - mean).powi(2))
                .sum::<f64>()
                / n)
                .sqrt()
        })
    }
}
