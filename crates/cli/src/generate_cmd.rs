//! `causal-arm generate`: run an experiment's simulator, babbler and recorder logic in one
//! process (no DDS) and write the dataset bag — the fast path to the paper's datasets.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use causal_arm_datagen::{Compression, GenerateOptions, generate, generate_shards, shard_options};
use causal_arm_params::{ParamSpec, recorder, run};
use causal_arm_protocol::{Experiment, Profile};
use causal_arm_sim::ArmMode;
use clap::Args;

use crate::choice::choice;
use crate::progress::Counter;

/// `causal-arm generate`: the run's arguments, and how many cores to spread it over.
#[derive(Debug, Args)]
pub struct GenerateCmd {
    #[command(flatten)]
    run: GenerateArgs,
    /// Cut the run into N shards simulated side by side (one core each), written as a
    /// shard set: OUT/shard-0 … each a complete bag, listed in OUT/shard_set.yaml, which
    /// train, explain and rollout take as one dataset. 1 writes one bag at OUT.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    shards: i64,
}

/// Arguments shared by `generate` and `launch`; the run's defaults come from the graph
/// file (launch_scripts/graph.toml), as the nodes' do.
#[derive(Debug, Args)]
pub struct GenerateArgs {
    /// exp1 (kinematics) or exp2 (magnet, cube, table).
    #[arg(value_parser = choice::<Experiment>())]
    experiment: Experiment,
    /// paper (the paper's dataset size) or quick (a demo in about a minute).
    #[arg(long, default_value = run::profile::default_text(), value_parser = choice::<Profile>())]
    profile: Profile,
    /// Override the number of steps (exp1) — must be positive.
    #[arg(long, allow_negative_numbers = true)]
    steps: Option<i64>,
    /// Override the number of episodes (exp2) — must be positive.
    #[arg(long, allow_negative_numbers = true)]
    episodes: Option<i64>,
    /// Seed of simulator and babbler (an int64 ROS parameter of every node: at most
    /// 2^63 − 1).
    #[arg(long, default_value = run::seed::default_text(), value_parser = seed_value)]
    seed: u64,
    /// Bag directory to write (refused if it already holds a bag, unless --overwrite).
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing bag at --out.
    #[arg(long, conflicts_with = "resume")]
    overwrite: bool,
    /// Continue the run that was cut short (killed, crashed, stopped) in --out: keep its
    /// complete steps, re-run the simulator and babbler to them, and record the rest; the
    /// bag ends as an uninterrupted run of the seed would write it.
    #[arg(long)]
    pub resume: bool,
    /// Start the bag's next file (OUT_1.mcap, …) once the open one holds this many bytes,
    /// as `ros2 bag record --max-bag-size`; 0 writes one file. Each closed file is
    /// finished at once; every reader takes the files as one bag.
    #[arg(long, value_name = "BYTES",
          default_value = recorder::max_bag_size::default_text())]
    max_bag_size: u64,
    /// Start the bag's next file before a message more than this many seconds (of the
    /// run's clock) after the open file's first, as `ros2 bag record --max-bag-duration`;
    /// 0 writes one file.
    #[arg(long, value_name = "SECONDS",
          default_value = recorder::max_bag_duration::default_text())]
    max_bag_duration: u64,
    /// How the bag's chunks are compressed: zstd (rosbag2's MCAP default), lz4 (faster)
    /// or none (fastest to write, largest).
    #[arg(long, default_value = recorder::chunk_compression::default_text(),
          value_parser = choice::<Compression>())]
    chunk_compression: Compression,
    /// Standard deviation of the exp1 joint targets, rad.
    #[arg(allow_negative_numbers = true, long, default_value = run::sigma::default_text())]
    sigma: f64,
    /// Scale of the URDF joint velocity limits (1 = the real iiwa; the paper's arm moved
    /// faster, see docs/RESULTS.md).
    #[arg(allow_negative_numbers = true, long, default_value = run::velocity_scale::default_text())]
    velocity_scale: f64,
    /// How the simulator moves the arm: kinematic (links placed by forward kinematics:
    /// exact and fast, but they pass through the table) or dynamic (a multibody under
    /// gravity, moved by motors within the URDF velocities and efforts: it stalls on the table).
    #[arg(long, default_value = run::arm::default_text(), value_parser = choice::<ArmMode>())]
    arm: ArmMode,
    /// Exp 2: move while switching the magnet (default), so the data can show that the
    /// magnet does not move the joints; `false` holds the arm still at every switch, as
    /// bags made before this default did (see docs/RESULTS.md).
    #[arg(long, default_value = run::move_while_switching::default_text(),
          action = clap::ArgAction::Set, num_args = 0..=1,
          default_missing_value = "true", value_name = "BOOL")]
    pub move_while_switching: bool,
}

impl GenerateArgs {
    /// Validated options.
    pub fn options(&self) -> anyhow::Result<GenerateOptions> {
        let experiment = self.experiment;
        let positive = |v: i64, flag: &str| -> anyhow::Result<i64> {
            if v <= 0 {
                anyhow::bail!("{flag} must be a positive number, got {v}");
            }
            Ok(v)
        };
        // The run's parameters as the nodes take them (0 steps or episodes: the profile's).
        let (steps, episodes) = match (experiment, self.steps, self.episodes) {
            (_, Some(_), Some(_)) => anyhow::bail!("give --steps or --episodes, not both"),
            (Experiment::Exp1, Some(s), None) => (positive(s, "--steps")?, 0),
            (Experiment::Exp2, None, Some(e)) => (0, positive(e, "--episodes")?),
            (Experiment::Exp1, None, Some(_)) => {
                anyhow::bail!("exp1 runs one episode; use --steps")
            }
            (Experiment::Exp2, Some(_), None) => {
                anyhow::bail!("exp2 episodes have 500 steps; use --episodes")
            }
            _ => (0, 0),
        };
        if !(self.velocity_scale.is_finite() && self.velocity_scale > 0.0) {
            anyhow::bail!(
                "--velocity-scale must be a positive number, got {}",
                self.velocity_scale
            );
        }
        within_graph_range(run::velocity_scale::spec()?, self.velocity_scale)?;
        let run = causal_arm_params::RunParams {
            experiment: experiment.to_string(),
            profile: self.profile.to_string(),
            steps,
            episodes,
            // `seed_value` keeps it within int64.
            seed: self.seed as i64,
            sigma: self.sigma,
            velocity_scale: self.velocity_scale,
            arm: self.arm.to_string(),
            move_while_switching: self.move_while_switching,
            ..Default::default()
        };
        let mut options = GenerateOptions::from_run_params(&run, &self.out)?;
        options.overwrite = self.overwrite;
        options.split =
            causal_arm_bag::SplitLimits::from_ros2_units(self.max_bag_size, self.max_bag_duration);
        options.compression = self.chunk_compression;
        Ok(options)
    }
}

/// Parses `--seed` as every node parses its `seed` parameter, so that a seed the nodes
/// would refuse is refused here with the same words, before any work starts.
fn seed_value(raw: &str) -> Result<u64, String> {
    let seed = run::seed::parse(raw).map_err(|e| e.to_string())?;
    // The declared range keeps it non-negative.
    u64::try_from(seed).map_err(|e| e.to_string())
}

/// Refuses `value` outside the range launch_scripts/graph.toml declares for `spec`'s
/// run parameter, as the nodes do for the same parameter.
fn within_graph_range(spec: ParamSpec, value: f64) -> anyhow::Result<()> {
    if let Some((lo, hi)) = spec.range
        && !(lo..=hi).contains(&value)
    {
        anyhow::bail!(
            "--{} must lie in [{lo}, {hi}] (its range in the graph file), got {value}",
            spec.name.replace('_', "-")
        );
    }
    Ok(())
}

/// Runs `causal-arm generate`.
pub fn run(cmd: &GenerateCmd) -> anyhow::Result<()> {
    let args = &cmd.run;
    let options = args.options()?;
    let shards = match cmd.shards {
        n if n >= 1 => n as u64,
        n => anyhow::bail!("--shards must be at least 1, got {n}"),
    };
    if shards > 1 {
        if args.resume {
            anyhow::bail!(
                "--resume continues one bag; give --shards 1, or re-run the shard set with --overwrite"
            );
        }
        return run_shards(&options, shards);
    }
    let total = options.plan.total_steps();
    let mut counter = Counter::new(
        total,
        &format!("{} seed {}", options.experiment, options.seed),
        "steps",
    );
    let start = Instant::now();
    let mut progress = |done: u64, _| {
        if done.is_multiple_of(256) || done == total {
            counter.set(done);
        }
    };
    let generated = match args.resume {
        true => causal_arm_datagen::generate_resumed(&options, &mut progress),
        false => generate(&options, &mut progress),
    };
    counter.finish();
    let summary = generated.with_context(|| {
        format!(
            "generating {} into {}",
            options.experiment,
            options.out.display()
        )
    })?;
    let secs = start.elapsed().as_secs_f64();
    let resumed = match summary.resumed_at {
        0 => String::new(),
        at => format!(", resumed at step {at}"),
    };
    println!(
        "wrote {} ({} steps, {} messages{resumed}) in {:.1} s ({:.0} steps/s)",
        summary.bag_dir.display(),
        summary.steps,
        summary.messages,
        secs,
        (summary.steps - summary.resumed_at) as f64 / secs
    );
    Ok(())
}

/// `generate --shards N` (N > 1): the shard set, one line per shard and one for the set.
fn run_shards(options: &GenerateOptions, shards: u64) -> anyhow::Result<()> {
    let total = options.plan.total_steps();
    let label = format!(
        "{} seed {}, {shards} shards",
        options.experiment, options.seed
    );
    let mut counter = Counter::new(total, &label, "steps");
    let start = Instant::now();
    let generated = generate_shards(options, shards, &mut |done, _| counter.set(done));
    counter.finish();
    let summaries = generated.with_context(|| {
        format!(
            "generating {} into the shard set {}",
            options.experiment,
            options.out.display()
        )
    })?;
    let secs = start.elapsed().as_secs_f64();
    for (shard, summary) in shard_options(options, shards)?.iter().zip(&summaries) {
        println!(
            "wrote {} (seed {}, {} steps, {} messages)",
            summary.bag_dir.display(),
            shard.seed,
            summary.steps,
            summary.messages
        );
    }
    let steps: u64 = summaries.iter().map(|s| s.steps).sum();
    println!(
        "wrote shard set {} ({shards} shards, {steps} steps) in {secs:.1} s ({:.0} steps/s)",
        options.out.display(),
        steps as f64 / secs
    );
    Ok(())
}
