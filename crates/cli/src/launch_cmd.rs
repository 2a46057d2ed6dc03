//! `causal-arm launch`: start the simulator, babbler and recorder nodes as separate
//! processes (the same graph `ros2 launch` starts), follow the recorder's progress over
//! DDS, stop everything cleanly and say where the bag is.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_node::{RosArgs, RosNode, qos};
use causal_arm_protocol::ns_from_time;

use crate::generate_cmd::{GenerateArgs, step_progress};

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

fn wait_with_timeout(
    child: &mut Child,
    limit: Duration,
) -> anyhow::Result<Option<std::process::ExitStatus>> {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait()? {
            return Ok(Some(status));
        }
        if start.elapsed() > limit {
            return Ok(None);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs `causal-arm launch`.
pub fn run(args: &GenerateArgs, ros_args: &RosArgs) -> anyhow::Result<()> {
    let options = args.options()?;
    causal_arm_datagen::validate(&options)?;
    if !options.overwrite
        && let Some(found) = causal_arm_recorder::existing_bag(&options.out)
    {
        bail!(
            "{} already holds a bag ({found}); pass --overwrite to replace it",
            options.out.display()
        );
    }
    let plan = options.plan;
    let mut params = vec![
        format!("experiment:={}", options.experiment),
        format!("seed:={}", options.seed),
        format!("sigma:={}", options.exp1.sigma),
        format!("velocity_scale:={}", options.sim.velocity_scale),
        format!(
            "move_while_switching:={}",
            options.exp2.move_while_switching
        ),
        format!("steps:={}", plan.steps_per_episode),
        format!("episodes:={}", plan.episodes),
    ];
    let common = |extra: &[String]| -> Vec<String> {
        let mut v = vec!["--ros-args".to_owned()];
        for p in params.iter().chain(extra) {
            v.push("-p".to_owned());
            v.push(p.clone());
        }
        v
    };
    let recorder_args = common(&[
        format!("output:={}", options.out.display()),
        format!("overwrite:={}", options.overwrite),
    ]);
    let sim_args = common(&[]);
    let babbler_args = common(&[]);
    params.clear();

    let stop = Arc::new(AtomicBool::new(false));
    let setter = stop.clone();
    let _ = ctrlc::set_handler(move || setter.store(true, Ordering::SeqCst));

    let spawn = |name: &str, args: &[String]| -> anyhow::Result<Child> {
        Command::new(node_binary(name)?)
            .args(args)
            .stdin(Stdio::null())
            .spawn()
            .with_context(|| format!("starting {name}"))
    };
    let mut recorder = spawn("causal_arm_recorder", &recorder_args)?;
    let mut babbler = spawn("causal_arm_babbler", &babbler_args)?;
    let mut sim = spawn("causal_arm_sim", &sim_args)?;

    // Follow progress through the recorder's acknowledgements.
    let mut node = RosNode::new("causal_arm_launch", &[], ros_args)?;
    let acks = node.subscription::<Clock>(causal_arm_graph::ACK_TOPIC, qos::default_reliable())?;
    let step_ns = options.sim.dt * options.sim.substeps as f64 * 1e9;
    let total = plan.total_steps();
    let bar = step_progress(
        total,
        &format!("{} seed {} (DDS graph)", options.experiment, options.seed),
    );
    let start = Instant::now();
    let recorder_status = loop {
        while let Ok(Some((ack, _))) = acks.take() {
            bar.set_position(
                ((ns_from_time(&ack.clock) as f64 / step_ns).round() as u64 + 1).min(total),
            );
        }
        if let Some(status) = recorder.try_wait()? {
            break status;
        }
        if stop.load(Ordering::SeqCst) {
            interrupt(&recorder);
        }
        for (name, child) in [
            ("causal_arm_sim", &mut sim),
            ("causal_arm_babbler", &mut babbler),
        ] {
            if let Some(status) = child.try_wait()?
                && !status.success()
            {
                interrupt(&recorder);
                bar.abandon();
                let _ = wait_with_timeout(&mut recorder, Duration::from_secs(30));
                bail!(
                    "{name} failed ({status}); the recorder finalized the bag with the steps it had"
                );
            }
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    bar.finish();
    for child in [&mut sim, &mut babbler] {
        if child.try_wait()?.is_none() {
            interrupt(child);
        }
        if wait_with_timeout(child, Duration::from_secs(10))?.is_none() {
            child.kill()?;
            child.wait()?;
        }
    }
    if !recorder_status.success() {
        bail!("causal_arm_recorder failed ({recorder_status})");
    }
    let secs = start.elapsed().as_secs_f64();
    println!(
        "bag: {} ({total} steps over DDS in {secs:.1} s, {:.0} steps/s)",
        options.out.display(),
        total as f64 / secs
    );
    Ok(())
}
