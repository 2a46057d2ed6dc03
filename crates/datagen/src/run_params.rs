//! The run parameters every node of the graph takes (`causal_arm_params::RunParams`, from
//! launch_scripts/graph.toml) as the options `generate` runs with, and back: the one
//! mapping between them, for the nodes, the launcher and `causal-arm generate`.

use std::path::PathBuf;

use causal_arm_params::RunParams;
use causal_arm_protocol::{Experiment, Profile, RunPlan};

use crate::{GenerateError, GenerateOptions, Shard};

impl GenerateOptions {
    /// The run `run` describes; `out` is the bag (only the recorder writes one).
    pub fn from_run_params(
        run: &RunParams,
        out: impl Into<PathBuf>,
    ) -> Result<Self, GenerateError> {
        let bad = GenerateError::Options;
        let experiment: Experiment = run.experiment.parse().map_err(bad)?;
        let profile: Profile = run.profile.parse().map_err(bad)?;
        let mut plan = RunPlan::for_profile(experiment, profile);
        // Declared ranges keep the counts, the seeds and the shard's place non-negative.
        if run.steps > 0 {
            plan.steps_per_episode = run.steps as u64;
        }
        if run.episodes > 0 {
            plan.episodes = run.episodes as u64;
        }
        let mut options = GenerateOptions::new(experiment, plan, run.seed as u64, out);
        options.exp1.sigma = run.sigma;
        options.sim.velocity_scale = run.velocity_scale;
        options.sim.arm = run.arm.parse().map_err(bad)?;
        options.exp2.move_while_switching = run.move_while_switching;
        options.start_step = run.start_step as u64;
        let (index, count) = (run.shard_index, run.shard_count);
        if count > 1 {
            if index >= count {
                return Err(bad(format!(
                    "shard_index {index} is not a shard of a set of {count}"
                )));
            }
            options.shard = Some(Shard {
                index: index as u64,
                count: count as u64,
                set_seed: run.shard_set_seed as u64,
            });
        }
        if options.start_step >= options.plan.total_steps() {
            return Err(bad(format!(
                "start_step {} is not a step of the run (it has {} steps)",
                options.start_step,
                options.plan.total_steps()
            )));
        }
        Ok(options)
    }

    /// The run parameters that make every node run these options (the inverse of
    /// [`GenerateOptions::from_run_params`]; the profile is the default, as the steps and
    /// episodes are given).
    pub fn run_params(&self) -> RunParams {
        let shard = |f: fn(&Shard) -> u64, none: u64| self.shard.as_ref().map_or(none, f) as i64;
        RunParams {
            experiment: self.experiment.to_string(),
            seed: self.seed as i64,
            sigma: self.exp1.sigma,
            velocity_scale: self.sim.velocity_scale,
            arm: self.sim.arm.to_string(),
            move_while_switching: self.exp2.move_while_switching,
            steps: self.plan.steps_per_episode as i64,
            episodes: self.plan.episodes as i64,
            start_step: self.start_step as i64,
            shard_index: shard(|s| s.index, 0),
            shard_count: shard(|s| s.count, 1),
            shard_set_seed: shard(|s| s.set_seed, 0),
            ..RunParams::default()
        }
    }
}
