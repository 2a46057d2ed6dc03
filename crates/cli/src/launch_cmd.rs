//! `causal-arm launch`: start the simulator, babbler and recorder nodes as separate
//! processes (the same graph `ros2 launch` starts), or with `--composed` as three nodes of
//! this process, follow the recorder's progress over DDS, stop everything cleanly and say
//! where the bag is.

use std::os::unix::process::CommandExt as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::rc::Rc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_node::{RosArgs, RosNode, qos};
use causal_arm_protocol::ns_from_time;

use causal_arm_datagen::GenerateOptions;
use causal_arm_graph::RunParams;
use causal_arm_graph::screen::{Screen, Screened};
use causal_arm_protocol::graph::graph;

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

/// Directory holding the node binaries (next to this executable).
fn node_binary(name: &str) -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe().context("locating the causal-arm executable")?;
    let path = exe.parent().unwrap_or(Path::new(".")).join(name);
    if !path.exists() {
        bail!(
            "{} not found; build the nodes with `cargo build --workspace --bins`",
            path.display()
        );
    }
    Ok(path)
}

fn interrupt(child: &Child) {
    // SIGINT lets the nodes finish cleanly (the recorder finalizes its bag).
    unsafe {
        libc::kill(child.id() as libc::pid_t, libc::SIGINT);
    }
}

/// Each node's name and ROS arguments, in the graph file's start order: the run's
/// parameters for every node, and the recorder's output.
pub fn node_commands(options: &GenerateOptions) -> anyhow::Result<Vec<(String, Vec<String>)>> {
    let run = RunParams::ros_params(options);
    let node_values = [
        ("output", options.out.display().to_string()),
        ("overwrite", options.overwrite.to_string()),
        ("max_bag_size", options.split.to_ros2_units().0.to_string()),
        (
            "max_bag_duration",
            options.split.to_ros2_units().1.to_string(),
        ),
    ];
    Ok(graph()?
        .nodes
        .iter()
        .map(|node| {
            let own = node.params.iter().filter_map(|p| {
                let value = node_values.iter().find(|(name, _)| *name == p.name)?;
                Some(format!("{}:={}", p.name, value.1))
            });
            let mut args = vec!["--ros-args".to_owned()];
            for param in run.iter().cloned().chain(own) {
                args.push("-p".to_owned());
                args.push(param);
            }
            (node.name.clone(), args)
        })
        .collect())
}

/// Starts each node process of `commands`, in order. Each gets SIGTERM (and finalizes, as
/// on Ctrl-C) if the launcher dies, even by SIGKILL, so no node outlives its launcher.
pub(crate) fn spawn_nodes(
    commands: Vec<(String, Vec<String>)>,
) -> anyhow::Result<Vec<(String, Child)>> {
    let mut children = Vec::new();
    for (name, args) in commands {
        let mut command = Command::new(node_binary(&name)?);
        command.args(&args).stdin(Stdio::null());
        // SAFETY: prctl is async-signal-safe and touches only the child being started.
        unsafe {
            command.pre_exec(|| {
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
        let child = command
            .spawn()
            .with_context(|| format!("starting {name}"))?;
        children.push((name, child));
    }
    Ok(children)
}

/// Interrupts every node still running and waits up to 10 s for it to finalize, then
/// kills it.
pub(crate) fn stop_nodes(children: &mut [(String, Child)]) -> anyhow::Result<()> {
    for node in children {
        if node.exited()?.is_none() {
            node.interrupt();
        }
        if !wait_for_exit(node, Duration::from_secs(10))? {
            node.1.kill()?;
            node.1.wait()?;
        }
    }
    Ok(())
}

/// Runs `causal-arm launch`.
pub fn run(args: &LaunchArgs, ros_args: &RosArgs) -> anyhow::Result<()> {
    let mut options = args.generate.options()?;
    match args.shards {
        n if n < 1 => bail!("--shards must be at least 1, got {n}"),
        1 => {}
        n => return crate::launch_shards::run(args, &options, n as u64, ros_args),
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
    let mut commands = node_commands(&options)?;
    // The launcher's enclave is the graph's: each node joins with it, as a launch file
    // passing `--enclave` to every node would.
    if let Some(enclave) = &ros_args.enclave {
        for (_, node_args) in &mut commands {
            node_args.extend(["--enclave".to_owned(), enclave.clone()]);
        }
    }
    if args.print_commands {
        for (name, args) in &commands {
            println!("{name} {}", args.join(" "));
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
        true => run_composed(&options, commands, ros_args)?,
        false => run_graph(&options, commands, ros_args)?,
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

/// Starts the nodes of `commands` (one of them the graph's run-ending node, the
/// recorder), shows the run's progress until the recorder exits, and stops every node.
/// Fails when the recorder or another node fails; the bag is finalized either way.
pub(crate) fn run_graph(
    options: &GenerateOptions,
    commands: Vec<(String, Vec<String>)>,
    ros_args: &RosArgs,
) -> anyhow::Result<()> {
    let recorder_at = run_ending_position(&commands)?;
    let children = spawn_nodes(commands)?;
    follow_graph(options, ros_args, children, recorder_at, stop_nodes)
}

/// As [`run_graph`], with the nodes composed in this process (`launch --composed`, see
/// [`causal_arm_graph::compose`]): they end as processes would, the recorder last.
fn run_composed(
    options: &GenerateOptions,
    commands: Vec<(String, Vec<String>)>,
    ros_args: &RosArgs,
) -> anyhow::Result<()> {
    let recorder_at = run_ending_position(&commands)?;
    let mut nodes = Vec::new();
    for (name, args) in commands {
        let argv: Vec<String> = std::iter::once(name.clone()).chain(args).collect();
        let (node_args, _) = RosArgs::split(&argv)?;
        nodes.push((name, node_args));
    }
    let running = causal_arm_graph::compose::spawn(nodes)?;
    follow_graph(options, ros_args, running, recorder_at, |others| {
        causal_arm_node::runtime::stop_flag().store(true, Ordering::SeqCst);
        for node in others {
            if let Some(Err(e)) = node.finish() {
                tracing::warn!("{}: {e:#}", node.name);
            }
        }
        Ok(())
    })
}

/// Where the graph file's run-ending node (the recorder) is among `commands`.
fn run_ending_position(commands: &[(String, Vec<String>)]) -> anyhow::Result<usize> {
    let graph = graph()?;
    let ends_run = (graph.nodes.iter())
        .find(|n| n.ends_run)
        .ok_or_else(|| anyhow::anyhow!("the graph has no node that ends the run"))?;
    (commands.iter())
        .position(|(name, _)| *name == ends_run.name)
        .with_context(|| format!("{} is not among the nodes to start", ends_run.name))
}

/// Follows the started `nodes` until the one at `recorder_at` exits (see [`follow_run`]),
/// then ends the others with `stop_others`: whatever ended the run, no node outlives it.
/// Fails naming the recorder when it failed.
fn follow_graph<N: Started>(
    options: &GenerateOptions,
    ros_args: &RosArgs,
    mut nodes: Vec<N>,
    recorder_at: usize,
    stop_others: impl FnOnce(&mut [N]) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    let stop = causal_arm_node::runtime::stop_flag();
    let mut recorder = nodes.remove(recorder_at);
    let outcome = follow_run(options, ros_args, &stop, &mut recorder, &mut nodes);
    stop_others(&mut nodes)?;
    if let Err(failure) = outcome? {
        bail!("{} failed ({failure})", recorder.name());
    }
    Ok(())
}

/// A started node, a process or a composed thread, as [`follow_run`] watches it.
trait Started {
    /// The node's name.
    fn name(&self) -> &str;
    /// `None` while it runs; then `Ok` if it succeeded, else what went wrong.
    fn exited(&mut self) -> anyhow::Result<Option<Result<(), String>>>;
    /// Asks it to finish cleanly (the recorder finalizes its bag).
    fn interrupt(&self);
}

impl Started for (String, Child) {
    fn name(&self) -> &str {
        &self.0
    }

    fn exited(&mut self) -> anyhow::Result<Option<Result<(), String>>> {
        Ok(self.1.try_wait()?.map(|status| match status.success() {
            true => Ok(()),
            false => Err(status.to_string()),
        }))
    }

    fn interrupt(&self) {
        interrupt(&self.1);
    }
}

impl Started for causal_arm_graph::compose::ComposedNode {
    fn name(&self) -> &str {
        &self.name
    }

    fn exited(&mut self) -> anyhow::Result<Option<Result<(), String>>> {
        Ok(self.try_finish().map(|r| r.map_err(|e| format!("{e:#}"))))
    }

    /// Composed nodes share the process's stop flag, as they share its signals.
    fn interrupt(&self) {
        causal_arm_node::runtime::stop_flag().store(true, Ordering::SeqCst);
    }
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

/// Shows the run's progress from the recorder's acknowledgements until the recorder
/// exits; Ctrl-C asks the recorder to finalize, and another node failing ends the run
/// with the bag finalized. Gives the recorder's outcome.
fn follow_run<N: Started>(
    options: &GenerateOptions,
    ros_args: &RosArgs,
    stop: &AtomicBool,
    recorder: &mut N,
    others: &mut [N],
) -> anyhow::Result<Result<(), String>> {
    let mut node = RosNode::new("causal_arm_launch", &[], ros_args)?;
    // Progress only from the recorder's writers: any participant may write on the topic.
    let screen = Rc::new(Screen::of_graph_file(&mut node)?);
    let mut acks = Screened::<Clock, u64>::new(
        &mut node,
        causal_arm_graph::ACK_TOPIC,
        qos::default_reliable(),
        &screen,
    )?;
    let step_ns = options.sim.dt * options.sim.substeps as f64 * 1e9;
    let total = options.plan.total_steps();
    let mut counter = Counter::new(
        total,
        &format!("{} seed {} (DDS graph)", options.experiment, options.seed),
        "steps",
    );
    loop {
        let stamp = |ack: Clock| ns_from_time(&ack.clock);
        let unreadable = |e| tracing::debug!("ignoring an unreadable acknowledgement: {e}");
        for stamp in acks.take_admitted(stamp, unreadable).1 {
            counter.set((stamp as f64 / step_ns).round() as u64 + 1);
        }
        if let Some(outcome) = recorder.exited()? {
            counter.finish();
            return Ok(outcome);
        }
        if stop.load(Ordering::SeqCst) {
            recorder.interrupt();
        }
        for other in others.iter_mut() {
            if let Some(Err(failure)) = other.exited()? {
                recorder.interrupt();
                counter.finish();
                wait_for_exit(recorder, Duration::from_secs(30))?;
                bail!(
                    "{} failed ({failure}); the recorder finalized the bag with the steps it had",
                    other.name()
                );
            }
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Waits up to `limit` for `node` to exit; returns whether it did.
fn wait_for_exit<N: Started>(node: &mut N, limit: Duration) -> anyhow::Result<bool> {
    let start = Instant::now();
    loop {
        if node.exited()?.is_some() {
            return Ok(true);
        }
        if start.elapsed() > limit {
            return Ok(false);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_node_of_the_graph_gets_the_run_and_the_recorder_its_output() {
        let mut options = GenerateOptions::new(
            causal_arm_protocol::Experiment::Exp2,
            causal_arm_protocol::RunPlan {
                episodes: 3,
                steps_per_episode: 500,
            },
            7,
            "bags/x",
        );
        options.exp1.sigma = 0.2;
        let commands = node_commands(&options).unwrap();
        let names: Vec<&str> = commands.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(
            names,
            [
                "causal_arm_recorder",
                "causal_arm_babbler",
                "causal_arm_sim"
            ]
        );
        for (name, args) in &commands {
            let line = args.join(" ");
            for p in ["experiment:=exp2", "seed:=7", "sigma:=0.2", "episodes:=3"] {
                assert!(line.contains(p), "{name}: {line}");
            }
            assert_eq!(
                line.contains("output:=bags/x"),
                name == "causal_arm_recorder",
                "{line}"
            );
        }
    }
}
