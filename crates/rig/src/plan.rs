//! The run parameters every node of the graph takes, mapped onto the shared
//! [`GenerateOptions`] so the graph and `causal-arm generate` agree.

use causal_arm_datagen::{GenerateOptions, Shard};
use causal_arm_node::params::RunParams;
use causal_arm_protocol::graph::graph;
use causal_arm_protocol::{Experiment, Profile, RunPlan};

/// How many readers of `topic` the graph file declares, leaving out the recorder (the
/// node publishing its acknowledgements) when the run is not recorded: a node publishing
/// on a volatile topic waits for them, since a sample written before a reader matched
/// never reaches it (with DDS Security each match also waits for a key exchange).
pub fn expected_readers(topic: &str, with_recorder: bool) -> anyhow::Result<usize> {
    let ack = causal_arm_protocol::topics::RECORDER_ACK;
    Ok(graph()?
        .subscribers_of(topic)
        .filter(|n| with_recorder || !n.publishes.iter().any(|t| t == ack))
        .count())
}

/// The run a node of the graph takes part in: its run parameters made into the options
/// `generate` would use.
#[derive(Debug, Clone)]
pub struct RunSetup {
    /// The options `generate` would use.
    pub options: GenerateOptions,
}

impl RunSetup {
    /// From the run's parameters; `out` is only used by the recorder.
    pub fn from_params(run: &RunParams, out: &str) -> anyhow::Result<Self> {
        let experiment: Experiment = run.experiment.parse().map_err(anyhow::Error::msg)?;
        let profile: Profile = run.profile.parse().map_err(anyhow::Error::msg)?;
        let mut plan = RunPlan::for_profile(experiment, profile);
        // Declared ranges keep the counts and the seed non-negative.
        if run.steps > 0 {
            plan.steps_per_episode = run.steps as u64;
        }
        if run.episodes > 0 {
            plan.episodes = run.episodes as u64;
        }
        let mut options = GenerateOptions::new(experiment, plan, run.seed as u64, out);
        options.exp1.sigma = run.sigma;
        options.sim.velocity_scale = run.velocity_scale;
        options.sim.arm = run.arm.parse().map_err(anyhow::Error::msg)?;
        options.exp2.move_while_switching = run.move_while_switching;
        options.start_step = run.start_step as u64;
        let (index, count) = (run.shard_index, run.shard_count);
        if count > 1 {
            if index >= count {
                anyhow::bail!("shard_index {index} is not a shard of a set of {count}");
            }
            options.shard = Some(Shard {
                index: index as u64,
                count: count as u64,
                set_seed: run.shard_set_seed as u64,
            });
        }
        if options.start_step >= options.plan.total_steps() {
            anyhow::bail!(
                "start_step {} is not a step of the run (it has {} steps)",
                options.start_step,
                options.plan.total_steps()
            );
        }
        Ok(Self { options })
    }

    /// The run parameters that make every node run `options` (the inverse of
    /// [`RunSetup::from_params`]; the profile is the default, as the steps and episodes
    /// are given).
    pub fn run_params(options: &GenerateOptions) -> RunParams {
        let shard = |f: fn(&Shard) -> u64, none: u64| options.shard.as_ref().map_or(none, f) as i64;
        RunParams {
            experiment: options.experiment.to_string(),
            seed: options.seed as i64,
            sigma: options.exp1.sigma,
            velocity_scale: options.sim.velocity_scale,
            arm: options.sim.arm.to_string(),
            move_while_switching: options.exp2.move_while_switching,
            steps: options.plan.steps_per_episode as i64,
            episodes: options.plan.episodes as i64,
            start_step: options.start_step as i64,
            shard_index: shard(|s| s.index, 0),
            shard_count: shard(|s| s.count, 1),
            shard_set_seed: shard(|s| s.set_seed, 0),
            ..RunParams::default()
        }
    }

    /// Sim-time duration of one step, ns (to turn stamps into step counts).
    pub fn step_ns(&self) -> f64 {
        self.options.sim.dt * self.options.sim.substeps as f64 * 1e9
    }
}
