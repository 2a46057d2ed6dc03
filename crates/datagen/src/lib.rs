//! Data generation for both experiments: the simulator, babbler and recorder logic of the
//! graph, composed in one process (`causal-arm generate`). The DDS graph runs the same
//! step function in three processes; for one seed both write the same messages.
//!
//! Step protocol (one episode of K steps): for k in 0..K the simulator publishes its state
//! s_k (all topics stamped with one sim time), the babbler answers with action a_k stamped
//! with s_k's time, and the simulator executes it. Every topic therefore holds exactly K
//! messages per episode; the dataset builder forms (s_k, a_k, s_{k+1}) for k < K−1.

use std::path::{Path, PathBuf};

use causal_arm_babbler::{Exp1Babbler, Exp1Config, Exp2Babbler, Exp2Config};
use causal_arm_bag::{BagError, BagOptions, BagWriter, offered_qos_yaml};
/// Where a run's bag starts its next file ([`GenerateOptions::split`]).
pub use causal_arm_bag::{Compression, SplitLimits};
use causal_arm_kinematics::ArmModel;
use causal_arm_msgs::msg::Action;
use causal_arm_msgs::std_msgs::msg::String as RosString;
use causal_arm_protocol::{
    Command, Drawn, Experiment, LatchedMessages, RunPlan, Scene, SimState, StepMessages,
    action_message, babbler_seed, bag_keys, scene_markers, sim_seed, topics,
};
use causal_arm_sim::{SimConfig, SimError, Simulator};
use thiserror::Error;

mod resume;
mod run_params;
mod shards;
pub use resume::{interrupted_dir, resume_point};
pub use shards::{Shard, generate_shards, shard_options, shard_set_manifest};

/// Everything a generation run needs.
#[derive(Debug, Clone)]
pub struct GenerateOptions {
    /// Experiment.
    pub experiment: Experiment,
    /// Size.
    pub plan: RunPlan,
    /// Seed of simulator and babbler.
    pub seed: u64,
    /// Bag directory to write.
    pub out: PathBuf,
    /// Replace an existing bag there.
    pub overwrite: bool,
    /// The step the run starts at: 0, or the steps a cut-short bag holds when resuming.
    pub start_step: u64,
    /// Simulator settings (its seed is derived from `seed`).
    pub sim: SimConfig,
    /// Exp 1 babbling settings (seed derived from `seed`).
    pub exp1: Exp1Config,
    /// Exp 2 babbling settings (seed derived from `seed`).
    pub exp2: Exp2Config,
    /// This run's place in a shard set (`generate --shards`), if it is a shard.
    pub shard: Option<Shard>,
    /// When the bag starts its next file (`--max-bag-size`, `--max-bag-duration`); the
    /// bag's content is the same however it is split.
    pub split: SplitLimits,
    /// How the bag's chunks are compressed (the recorder's `chunk_compression`); the
    /// messages are the same either way.
    pub compression: Compression,
}

impl GenerateOptions {
    /// What the bag records about its run, so the trainer can check a bag is the
    /// experiment it is asked to learn.
    pub fn bag_custom_data(&self) -> std::collections::BTreeMap<String, String> {
        let mut data = std::collections::BTreeMap::from([
            (bag_keys::EXPERIMENT.to_owned(), self.experiment.to_string()),
            (bag_keys::SEED.to_owned(), self.seed.to_string()),
            (
                bag_keys::VELOCITY_SCALE.to_owned(),
                self.sim.velocity_scale.to_string(),
            ),
            (bag_keys::ARM.to_owned(), self.sim.arm.to_string()),
            (
                bag_keys::EPISODES.to_owned(),
                self.plan.episodes.to_string(),
            ),
            (
                bag_keys::STEPS_PER_EPISODE.to_owned(),
                self.plan.steps_per_episode.to_string(),
            ),
        ]);
        if self.experiment == Experiment::Exp1 {
            data.insert(bag_keys::SIGMA.to_owned(), self.exp1.sigma.to_string());
        }
        let design = match self.experiment {
            Experiment::Exp1 => self.exp1.design_words(),
            Experiment::Exp2 => self.exp2_config().design_words(),
        };
        data.insert(bag_keys::DESIGN.to_owned(), design);
        if self.experiment == Experiment::Exp2 {
            data.insert(
                bag_keys::MOVE_WHILE_SWITCHING.to_owned(),
                self.exp2.move_while_switching.to_string(),
            );
        }
        if let Some(shard) = self.shard {
            let place = format!("{}/{}", shard.index, shard.count);
            data.insert(bag_keys::SHARD.to_owned(), place);
            data.insert(
                bag_keys::SHARD_SET_SEED.to_owned(),
                shard.set_seed.to_string(),
            );
        }
        data
    }

    /// The exp 2 babbler's settings in this run's scene: its table, cube and seed.
    pub fn exp2_config(&self) -> Exp2Config {
        let sim = &self.sim;
        Exp2Config {
            seed: babbler_seed(self.seed),
            table_top_z: sim.table_top_z,
            cube_size: sim.cube_size,
            table_area: (
                sim.table_center,
                [
                    sim.table_half_extents[0] - sim.cube_size,
                    sim.table_half_extents[1] - sim.cube_size,
                ],
            ),
            ..self.exp2.clone()
        }
    }

    /// Defaults for `experiment` with `plan`, `seed` and `out`.
    pub fn new(experiment: Experiment, plan: RunPlan, seed: u64, out: impl Into<PathBuf>) -> Self {
        Self {
            experiment,
            plan,
            seed,
            out: out.into(),
            overwrite: false,
            start_step: 0,
            sim: SimConfig::default(),
            exp1: Exp1Config::default(),
            exp2: Exp2Config::default(),
            shard: None,
            split: SplitLimits::default(),
            compression: Compression::default(),
        }
    }
}

/// Why generation failed.
#[derive(Debug, Error)]
pub enum GenerateError {
    /// Bad options.
    #[error("{0}")]
    Options(String),
    /// The simulator refused.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// Writing the bag failed.
    #[error(transparent)]
    Bag(#[from] BagError),
    /// The graph's transport failed: a message could not be sent, or no answer came.
    #[error("{0}")]
    Transport(String),
    /// SIGINT/SIGTERM asked the run to stop; not a failure.
    #[error("stopped on request")]
    Stopped,
}

/// What a run wrote.
#[derive(Debug, Clone)]
pub struct GenerateSummary {
    /// Bag directory.
    pub bag_dir: PathBuf,
    /// Steps simulated.
    pub steps: u64,
    /// Steps kept from the cut-short bag when resuming (0 for a fresh run).
    pub resumed_at: u64,
    /// Messages written.
    pub messages: u64,
}

/// One babbler of either experiment (one per run, so variant sizes do not matter).
#[allow(clippy::large_enum_variant)]
pub enum Babbler {
    /// Experiment 1.
    Exp1(Exp1Babbler),
    /// Experiment 2.
    Exp2(Exp2Babbler),
}

impl Babbler {
    /// The babbler of `options.experiment`.
    pub fn new(options: &GenerateOptions, model: &ArmModel) -> Result<Self, GenerateError> {
        Ok(match options.experiment {
            Experiment::Exp1 => Self::Exp1(
                Exp1Babbler::new(
                    model,
                    &Exp1Config {
                        seed: babbler_seed(options.seed),
                        ..options.exp1.clone()
                    },
                )
                .map_err(GenerateError::Options)?,
            ),
            Experiment::Exp2 => Self::Exp2(
                Exp2Babbler::new(model, options.exp2_config()).map_err(GenerateError::Options)?,
            ),
        })
    }

    /// Next command for `state`.
    pub fn next(&mut self, state: &SimState) -> Command {
        self.next_drawn(state).command
    }

    /// Next command for `state` and how it was drawn.
    pub fn next_drawn(&mut self, state: &SimState) -> Drawn {
        match self {
            Self::Exp1(b) => b.next_drawn(state),
            Self::Exp2(b) => b.next_drawn(state),
        }
    }

    /// New episode.
    pub fn reset(&mut self) {
        if let Self::Exp2(b) = self {
            b.reset();
        }
    }
}

/// Receives the messages of a run in graph order (the recorder, or a test).
pub trait StepSink {
    /// Called once before the first step: `/robot_description` and `/tf_static`.
    fn latched(&mut self, messages: &LatchedMessages) -> Result<(), GenerateError>;
    /// All state messages of one step (owned: a DDS sink publishes them without a copy).
    fn state(&mut self, stamp_ns: u64, messages: StepMessages) -> Result<(), GenerateError>;
    /// The babbler's answer to that state.
    fn action(&mut self, stamp_ns: u64, action: &Action) -> Result<(), GenerateError>;
}

/// Checks options before anything is written.
pub fn validate(options: &GenerateOptions) -> Result<(), GenerateError> {
    if options.plan.episodes == 0 || options.plan.steps_per_episode == 0 {
        return Err(GenerateError::Options(format!(
            "episodes ({}) and steps per episode ({}) must be positive",
            options.plan.episodes, options.plan.steps_per_episode
        )));
    }
    let sim = simulator(options)?;
    Babbler::new(options, sim.model())?;
    Ok(())
}

/// Where each step's command comes from: the babbler in this process (`generate`), or the
/// babbler node's answer over DDS (the simulator node).
pub trait CommandSource {
    /// A new episode begins (called before every episode but the first).
    fn new_episode(&mut self);
    /// The command answering `state`, step `k` of its episode, and how it was drawn.
    fn command(&mut self, state: &SimState, k: u64) -> Result<Drawn, GenerateError>;
}

impl CommandSource for Babbler {
    fn new_episode(&mut self) {
        self.reset();
    }

    fn command(&mut self, state: &SimState, _k: u64) -> Result<Drawn, GenerateError> {
        Ok(self.next_drawn(state))
    }
}

/// The one step loop of every run, in process or over DDS: for each step, the state goes
/// to `sink`, `commands` answers it, the answer goes to `sink`, and `sim` executes it.
/// `progress(done, total)` is called after every step. Returns the steps run.
pub fn drive(
    plan: &RunPlan,
    sim: &mut Simulator,
    commands: &mut dyn CommandSource,
    sink: &mut dyn StepSink,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<u64, GenerateError> {
    drive_range(plan, 0..plan.total_steps(), sim, commands, sink, progress)
}

/// The steps `steps` of the run (indices over all episodes), with `sim` and `commands` as
/// a run has them before the first of them: fresh for `0..`, or from [`fast_forward`] for
/// `k..` (what `--resume` does). A new episode begins at every multiple of the episode
/// length but 0. `progress(done, total)` counts from `steps.start`.
pub fn drive_range(
    plan: &RunPlan,
    steps: std::ops::Range<u64>,
    sim: &mut Simulator,
    commands: &mut dyn CommandSource,
    sink: &mut dyn StepSink,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<u64, GenerateError> {
    let total = plan.total_steps();
    let per_episode = plan.steps_per_episode.max(1);
    let mut state = sim.state();
    let mut done = 0;
    for step in steps.start..steps.end.min(total) {
        let k = step % per_episode;
        if k == 0 && step > 0 {
            sim.reset_episode();
            commands.new_episode();
            state = sim.state();
        }
        sink.state(state.stamp_ns, sim.step_messages(&state))?;
        let drawn = commands.command(&state, k)?;
        sink.action(state.stamp_ns, &action_message(&state, &drawn, k))?;
        state = sim.step(&drawn.command)?;
        done += 1;
        progress(steps.start + done, total);
    }
    Ok(done)
}

/// Discards what a run writes.
struct NullSink;

impl StepSink for NullSink {
    fn latched(&mut self, _: &LatchedMessages) -> Result<(), GenerateError> {
        Ok(())
    }
    fn state(&mut self, _: u64, _: StepMessages) -> Result<(), GenerateError> {
        Ok(())
    }
    fn action(&mut self, _: u64, _: &Action) -> Result<(), GenerateError> {
        Ok(())
    }
}

/// The simulator and babbler of run `options` as they are after its first `steps` steps,
/// re-run in this process without writing anything (both are deterministic for a seed):
/// where `--resume` continues a run that was cut short.
pub fn fast_forward(
    options: &GenerateOptions,
    steps: u64,
) -> Result<(Simulator, Babbler), GenerateError> {
    validate(options)?;
    let mut sim = simulator(options)?;
    let mut babbler = Babbler::new(options, sim.model())?;
    drive_range(
        &options.plan,
        0..steps,
        &mut sim,
        &mut babbler,
        &mut NullSink,
        &mut |_, _| {},
    )?;
    Ok((sim, babbler))
}

/// The simulator of a run: `options.sim` seeded from the run's seed.
pub fn simulator(options: &GenerateOptions) -> Result<Simulator, GenerateError> {
    Ok(Simulator::new(SimConfig {
        seed: sim_seed(options.seed),
        ..options.sim.clone()
    })?)
}

/// Runs the experiment in this process, feeding every message to `sink`; `progress(done,
/// total)` is called after every step.
pub fn run(
    options: &GenerateOptions,
    sink: &mut dyn StepSink,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<u64, GenerateError> {
    validate(options)?;
    let mut sim = simulator(options)?;
    let mut babbler = Babbler::new(options, sim.model())?;
    sink.latched(&sim.latched_messages())?;
    drive(&options.plan, &mut sim, &mut babbler, sink, progress)
}

/// Writes a run into a bag.
pub struct BagSink {
    writer: BagWriter,
    /// The run's table and cube, drawn by the markers each step writes.
    scene: Scene,
    messages: u64,
    /// Steps written whose chunk may still be open: (stamp, messages written through it).
    unlanded: std::collections::VecDeque<(u64, u64)>,
    /// Stamp of the last step whose messages all lie in closed chunks.
    landed_stamp: Option<u64>,
}

impl BagSink {
    /// Creates the bag and registers the graph's topics with their offered QoS.
    pub fn create(
        dir: &Path,
        overwrite: bool,
        options: &GenerateOptions,
    ) -> Result<Self, GenerateError> {
        let mut writer = BagWriter::create(
            dir,
            BagOptions {
                overwrite,
                custom_data: options.bag_custom_data(),
                split: options.split,
                compression: options.compression,
                ..BagOptions::default()
            },
        )?;
        let recorded = offered_qos_yaml(true, false, true, 0);
        let latched = offered_qos_yaml(true, true, false, 1);
        use causal_arm_msgs::geometry_msgs::msg::PoseStamped;
        use causal_arm_msgs::msg::{MagnetState, ObjectColor};
        use causal_arm_msgs::rosgraph_msgs::msg::Clock;
        use causal_arm_msgs::sensor_msgs::msg::JointState;
        use causal_arm_msgs::tf2_msgs::msg::TFMessage;
        use causal_arm_msgs::visualization_msgs::msg::MarkerArray;
        writer.add_topic::<RosString>(topics::ROBOT_DESCRIPTION, &latched)?;
        writer.add_topic::<TFMessage>(topics::TF_STATIC, &latched)?;
        writer.add_topic::<JointState>(topics::JOINT_STATES, &recorded)?;
        writer.add_topic::<PoseStamped>(topics::EF_POSE, &recorded)?;
        writer.add_topic::<PoseStamped>(topics::OBJECT_POSE, &recorded)?;
        writer.add_topic::<ObjectColor>(topics::OBJECT_COLOR, &recorded)?;
        writer.add_topic::<MagnetState>(topics::MAGNET_STATE, &recorded)?;
        writer.add_topic::<Clock>(topics::CLOCK, &recorded)?;
        writer.add_topic::<TFMessage>(topics::TF, &recorded)?;
        writer.add_topic::<MarkerArray>(topics::SCENE_MARKERS, &recorded)?;
        writer.add_topic::<Action>(topics::ACTION, &recorded)?;
        Ok(Self {
            writer,
            scene: options.sim.scene(),
            messages: 0,
            unlanded: std::collections::VecDeque::new(),
            landed_stamp: None,
        })
    }

    /// The stamp of the last step a kill of this process can no longer lose: every one of
    /// its messages lies in a closed chunk. What a recorder may acknowledge.
    pub fn landed_stamp(&mut self) -> Option<u64> {
        let landed = self.writer.landed_messages();
        while let Some(&(stamp, through)) = self.unlanded.front() {
            if through > landed {
                break;
            }
            self.landed_stamp = Some(stamp);
            self.unlanded.pop_front();
        }
        self.landed_stamp
    }

    /// Closes the open chunk now, so every step written so far has landed.
    pub fn land(&mut self) -> Result<(), GenerateError> {
        Ok(self.writer.land()?)
    }

    /// Steps written that have not landed yet.
    pub fn unlanded_steps(&self) -> usize {
        self.unlanded.len()
    }

    /// The stamp of the last step written, landed or not.
    pub fn last_step_stamp(&self) -> Option<u64> {
        self.unlanded
            .back()
            .map(|&(stamp, _)| stamp)
            .or(self.landed_stamp)
    }

    /// Finalizes the bag.
    pub fn finish(self) -> Result<causal_arm_bag::BagSummary, GenerateError> {
        Ok(self.writer.finish()?)
    }
}

impl StepSink for BagSink {
    fn latched(&mut self, m: &LatchedMessages) -> Result<(), GenerateError> {
        self.writer
            .write(topics::ROBOT_DESCRIPTION, 0, &m.robot_description)?;
        self.writer.write(topics::TF_STATIC, 0, &m.tf_static)?;
        self.messages += 2;
        Ok(())
    }

    fn state(&mut self, stamp_ns: u64, m: StepMessages) -> Result<(), GenerateError> {
        let w = &mut self.writer;
        w.write(topics::JOINT_STATES, stamp_ns, &m.joint_states)?;
        w.write(topics::EF_POSE, stamp_ns, &m.ef_pose)?;
        w.write(topics::OBJECT_POSE, stamp_ns, &m.object_pose)?;
        w.write(topics::OBJECT_COLOR, stamp_ns, &m.object_color)?;
        w.write(topics::MAGNET_STATE, stamp_ns, &m.magnet)?;
        w.write(topics::CLOCK, stamp_ns, &m.clock)?;
        w.write(topics::TF, stamp_ns, &m.tf)?;
        w.write(
            topics::SCENE_MARKERS,
            stamp_ns,
            &scene_markers(&m, &self.scene),
        )?;
        self.messages += 8;
        Ok(())
    }

    fn action(&mut self, stamp_ns: u64, action: &Action) -> Result<(), GenerateError> {
        self.writer.write(topics::ACTION, stamp_ns, action)?;
        self.messages += 1;
        // The action is a step's last message: the step has landed once it has.
        self.unlanded.push_back((stamp_ns, self.messages));
        self.landed_stamp();
        Ok(())
    }
}

/// Runs the experiment in this process and writes the bag (`causal-arm generate`).
pub fn generate(
    options: &GenerateOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<GenerateSummary, GenerateError> {
    validate(options)?;
    let mut sink = BagSink::create(&options.out, options.overwrite, options)?;
    let steps = run(options, &mut sink, progress)?;
    let messages = sink.messages;
    let summary = sink.finish()?;
    Ok(GenerateSummary {
        bag_dir: summary.dir,
        steps,
        resumed_at: 0,
        messages,
    })
}

/// Continues the cut-short run of `options` in its bag (`generate --resume`): keeps the
/// bag's complete steps, re-runs the simulator and the babbler to them, and writes the
/// rest, so the bag ends as an uninterrupted run's.
pub fn generate_resumed(
    options: &GenerateOptions,
    progress: &mut dyn FnMut(u64, u64),
) -> Result<GenerateSummary, GenerateError> {
    validate(options)?;
    let (mut sink, start) = resume::resume_unfinished(options)?;
    let (mut sim, mut babbler) = fast_forward(options, start)?;
    let run = start..options.plan.total_steps();
    let steps = drive_range(
        &options.plan,
        run,
        &mut sim,
        &mut babbler,
        &mut sink,
        progress,
    )?;
    let messages = sink.messages;
    let summary = sink.finish()?;
    Ok(GenerateSummary {
        bag_dir: summary.dir,
        steps: start + steps,
        resumed_at: start,
        messages,
    })
}
