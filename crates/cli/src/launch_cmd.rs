//! `causal-arm launch`: start the simulator, babbler and recorder nodes as separate
//! processes (the same graph `ros2 launch` starts), or with `--composed` as three nodes of
//! this process, follow the recorder's progress over DDS, stop everything cleanly and say
//! where the bag is. The launcher itself is `causal_arm_rig::launch`.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context as _, bail};
use causal_arm_datagen::GenerateOptions;
use causal_arm_node::RosArgs;
use causal_arm_protocol::graph::graph;
use causal_arm_rig::launch::{self, LaunchPlan, Started};

use crate::generate_cmd::GenerateArgs;
use crate::progress::Counter;

/// `causal-arm launch`: the run's options, as for `generate`.
#[derive(Debug, clap::Args)]
pub struct LaunchArgs {
    #[command(flatten)]
    pub generate: GenerateArgs,
    /// Print each node's command line (from launch_scripts/graph.toml) and exit.
    #[arg(long)]
    pub print_commands: bool,
    /// Run N graphs side by side, shard i in ROS domain ROS_DOMAIN_ID + i, each recording
    /// its share of the run into OUT/shard-i (a shard set, as `generate --shards`).
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub shards: i64,
    /// Run the graph's nodes composed in this one process, as an rclcpp component
    /// container does: each keeps its name, parameters and topics on DDS, and what one
    /// publishes for another is handed over in process (faster; they share one fate).
    #[arg(long)]
    pub composed: bool,
    /// Set by a sharded launch for each of its graphs: this graph's place in the set.
    #[arg(long, hide = true, requires = "shard_count")]
    pub shard_index: Option<u64>,
    /// See `--shard-index`.
    #[arg(long, hide = true, requires = "shard_index")]
    pub shard_count: Option<u64>,
    /// See `--shard-index`.
    #[arg(long, hide = true, default_value_t = 0)]
    pub shard_set_seed: u64,
}

/// Directory holding the node binaries: next to this executable.
pub fn bin_dir() -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe().context("locating the causal-arm executable")?;
    Ok(exe.parent().map(PathBuf::from).unwrap_or_default())
}

/// Runs `causal-arm launch`.
pub fn run(args: &LaunchArgs, ros_args: &RosArgs) -> anyhow::Result<()> {
    let mut options = args.generate.options()?;
    match args.shards {
        n if n < 1 => bail!("--shards must be at least 1, got {n}"),
        1 => {}
        n if args.generate.resume => bail!(
            "--resume continues one bag; give --shards 1, or re-run the shard set with --overwrite (not --shards {n})"
        ),
        _ if args.print_commands => {
            bail!("--print-commands shows one graph's nodes; drop --shards")
        }
        n => return crate::launch_shards::run(&options, n as u64, args.composed, ros_args),
    }
    if let (Some(index), Some(count)) = (args.shard_index, args.shard_count) {
        options.shard = Some(causal_arm_datagen::Shard {
            index,
            count,
            set_seed: args.shard_set_seed,
        });
    }
    causal_arm_datagen::validate(&options)?;
    if args.generate.resume {
        let start = causal_arm_datagen::resume_point(&options.out, &options)
            .with_context(|| format!("resuming the run in {}", options.out.display()))?;
        tracing::info!("resuming at step {start} of {}", options.plan.total_steps());
        options.start_step = start;
        // Not one complete step to keep: the run starts afresh in place.
        options.overwrite |= start == 0;
    }
    // The launcher's enclave is the graph's: each node joins with it, as a launch file
    // passing `--enclave` to every node would.
    let plan = LaunchPlan::from_graph(graph()?, &options, ros_args.enclave.as_deref());
    if args.print_commands {
        for node in &plan.nodes {
            println!("{} {}", node.name, node.args.join(" "));
        }
        return Ok(());
    }
    if !options.overwrite
        && options.start_step == 0
        && let Some(found) = causal_arm_bag::existing_bag(&options.out)
    {
        bail!(
            "{} already holds a bag ({found}); pass --overwrite to replace it",
            options.out.display()
        );
    }
    let start = Instant::now();
    match args.composed {
        true => follow(&options, ros_args, &plan, plan.compose()?)?,
        false => follow(&options, ros_args, &plan, plan.spawn(&bin_dir()?)?)?,
    }
    let secs = start.elapsed().as_secs_f64();
    let total = options.plan.total_steps();
    let recorded = recorded_steps(&options.out)?;
    let how = match args.composed {
        true => "by nodes composed in one process",
        false => "over DDS",
    };
    println!(
        "bag: {} ({recorded} of {total} steps {how} in {secs:.1} s, {:.0} steps/s)",
        options.out.display(),
        recorded as f64 / secs
    );
    if recorded < total {
        bail!(
            "the run stopped after {recorded} of {total} steps; {} holds those steps, finalized",
            options.out.display()
        );
    }
    Ok(())
}

/// Follows the started `nodes` of `plan` until the recorder exits, with a progress bar,
/// and stops the others; fails when the recorder or another node failed. The bag is
/// finalized either way.
pub(crate) fn follow<N: Started>(
    options: &GenerateOptions,
    ros_args: &RosArgs,
    plan: &LaunchPlan,
    nodes: Vec<N>,
) -> anyhow::Result<()> {
    let mut counter = Counter::new(
        options.plan.total_steps(),
        &format!("{} seed {} (DDS graph)", options.experiment, options.seed),
        "steps",
    );
    let outcome = launch::run(
        options,
        ros_args,
        nodes,
        plan.ends_run(graph()?)?,
        &mut |steps| counter.set(steps),
    );
    counter.finish();
    outcome
}

/// Steps in the finished bag: its `/babbler/action` messages, one per step (read from
/// the bag's summary, not assumed from the plan, so an interrupted run says so).
pub(crate) fn recorded_steps(bag: &std::path::Path) -> anyhow::Result<u64> {
    let reader = causal_arm_bag::BagReader::open(bag)
        .with_context(|| format!("reading back the recorded bag {}", bag.display()))?;
    Ok(reader
        .topics()
        .iter()
        .find(|t| t.name == causal_arm_protocol::topics::ACTION)
        .map_or(0, |t| t.message_count))
}
