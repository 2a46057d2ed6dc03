//! `causal-arm launch --shards N`: N DDS graphs side by side, one per core. Shard i is a
//! whole `causal-arm launch` of its share of the run, in ROS domain `ROS_DOMAIN_ID + i` so
//! the graphs never see each other's topics, recording into `OUT/shard-i`; the result is
//! the shard set `generate --shards N` writes, listed in `OUT/shard_set.yaml`.

use std::os::unix::process::CommandExt as _;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use causal_arm_datagen::{GenerateOptions, shard_options, shard_set_manifest};
use causal_arm_node::env::MAX_DOMAIN_ID;
use causal_arm_node::{RosArgs, RosEnv};
use causal_arm_protocol::Experiment;

use crate::launch_cmd::LaunchArgs;

/// Runs the shard set of `options` as `count` graphs and waits for all of them.
pub fn run(
    args: &LaunchArgs,
    options: &GenerateOptions,
    count: u64,
    ros_args: &RosArgs,
) -> anyhow::Result<()> {
    if args.generate.resume {
        bail!(
            "--resume continues one bag; give --shards 1, or re-run the shard set with --overwrite"
        );
    }
    if args.print_commands {
        bail!("--print-commands shows one graph's nodes; drop --shards");
    }
    let shards = shard_options(options, count)?;
    for shard in &shards {
        causal_arm_datagen::validate(shard)?;
    }
    let base = RosEnv::from_env()?.domain_id as u64;
    if base + count - 1 > MAX_DOMAIN_ID as u64 {
        bail!(
            "{count} shards from ROS_DOMAIN_ID {base} need domains up to {}, past the last valid one ({MAX_DOMAIN_ID})",
            base + count - 1
        );
    }
    shard_set_manifest(options, &shards).create(&options.out, options.overwrite)?;
    let start = Instant::now();
    let mut children = Vec::new();
    for (i, shard) in shards.iter().enumerate() {
        let domain = base + i as u64;
        let child = spawn_shard(shard, domain, args.composed, ros_args)
            .with_context(|| format!("starting shard {i} (domain {domain})"))?;
        children.push((format!("shard {i} (domain {domain})"), child));
    }
    wait_all(&mut children)?;
    let steps = options.plan.total_steps();
    let secs = start.elapsed().as_secs_f64();
    println!(
        "shard set: {} ({count} graphs, {steps} steps in {secs:.1} s, {:.0} steps/s)",
        options.out.display(),
        steps as f64 / secs
    );
    Ok(())
}

/// This executable's `launch` of one shard, in `domain`, dying with its parent.
fn spawn_shard(
    shard: &GenerateOptions,
    domain: u64,
    composed: bool,
    ros_args: &RosArgs,
) -> anyhow::Result<Child> {
    let exe = std::env::current_exe().context("locating the causal-arm executable")?;
    let mut command = Command::new(exe);
    command
        .args(shard_args(shard, composed, ros_args))
        .env("ROS_DOMAIN_ID", domain.to_string())
        .stdin(Stdio::null());
    // SAFETY: prctl is async-signal-safe and touches only the child being started; a
    // shard gets SIGTERM (and finalizes its bag) if this launcher dies.
    unsafe {
        command.pre_exec(|| {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    Ok(command.spawn()?)
}

/// The command line of one shard's `launch`: its share, seed, output and place in the set.
fn shard_args(shard: &GenerateOptions, composed: bool, ros_args: &RosArgs) -> Vec<String> {
    let size = match shard.experiment {
        Experiment::Exp1 => [
            "--steps".to_owned(),
            shard.plan.steps_per_episode.to_string(),
        ],
        Experiment::Exp2 => ["--episodes".to_owned(), shard.plan.episodes.to_string()],
    };
    let place = shard
        .shard
        .expect("shard_options gives every shard its place");
    let mut args = vec!["launch".to_owned(), shard.experiment.to_string()];
    args.extend(size);
    args.extend(
        [
            ("--seed", shard.seed.to_string()),
            ("--out", shard.out.display().to_string()),
            ("--sigma", format!("{:?}", shard.exp1.sigma)),
            (
                "--velocity-scale",
                format!("{:?}", shard.sim.velocity_scale),
            ),
            ("--arm", shard.sim.arm.to_string()),
            (
                "--move-while-switching",
                shard.exp2.move_while_switching.to_string(),
            ),
            ("--shard-index", place.index.to_string()),
            ("--shard-count", place.count.to_string()),
            ("--shard-set-seed", place.set_seed.to_string()),
            ("--max-bag-size", shard.split.to_ros2_units().0.to_string()),
            (
                "--max-bag-duration",
                shard.split.to_ros2_units().1.to_string(),
            ),
        ]
        .into_iter()
        .flat_map(|(flag, value)| [flag.to_owned(), value]),
    );
    if shard.overwrite {
        args.push("--overwrite".to_owned());
    }
    if composed {
        args.push("--composed".to_owned());
    }
    let mut ros = Vec::new();
    if let Some(enclave) = &ros_args.enclave {
        ros.extend(["--enclave".to_owned(), enclave.clone()]);
    }
    if let Some(level) = &ros_args.log_level {
        ros.extend(["--log-level".to_owned(), level.clone()]);
    }
    if !ros.is_empty() {
        args.push("--ros-args".to_owned());
        args.extend(ros);
    }
    args
}

/// Waits for every shard; when one fails, asks the others to stop (each finalizes its
/// bag with the steps it has) and fails naming it. Ctrl-C reaches the shards directly
/// (same process group), so they stop and finalize as a single launch does.
fn wait_all(children: &mut [(String, Child)]) -> anyhow::Result<()> {
    let mut failed = None;
    loop {
        let mut running = 0;
        for (name, child) in children.iter_mut() {
            match child.try_wait()? {
                None => running += 1,
                Some(status) if !status.success() && failed.is_none() => {
                    failed = Some(format!("{name} failed ({status})"));
                }
                Some(_) => {}
            }
        }
        if running == 0 {
            break;
        }
        if failed.is_some() {
            for (_, child) in children.iter_mut() {
                if child.try_wait()?.is_none() {
                    // SAFETY: kill(2) on a child we started and have not reaped.
                    unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
                }
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    match failed {
        Some(why) => bail!("{why}; the other shards stopped and finalized their bags"),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use causal_arm_protocol::RunPlan;

    #[test]
    fn each_shard_launch_gets_its_share_seed_output_and_place() {
        let plan = RunPlan {
            episodes: 3,
            steps_per_episode: 500,
        };
        let options = GenerateOptions::new(Experiment::Exp2, plan, 9, "/tmp/set");
        let shards = shard_options(&options, 2).unwrap();
        let ros = RosArgs {
            enclave: Some("/causal_arm".into()),
            ..RosArgs::default()
        };
        let args = shard_args(&shards[1], false, &ros).join(" ");
        let seed = causal_arm_protocol::shard_seed(9, 1);
        assert!(args.starts_with("launch exp2 --episodes 1 "), "{args}");
        assert!(
            args.contains(&format!("--seed {seed} --out /tmp/set/shard-1 ")),
            "{args}"
        );
        assert!(
            args.contains("--shard-index 1 --shard-count 2 --shard-set-seed 9"),
            "{args}"
        );
        assert!(args.ends_with("--ros-args --enclave /causal_arm"), "{args}");
    }
}
