//! `causal-arm launch --shards N`: N DDS graphs side by side, one per core. Shard i is a
//! whole `causal-arm launch` of its share of the run, in ROS domain `ROS_DOMAIN_ID + i` so
//! the graphs never see each other's topics, recording into `OUT/shard-i`; the result is
//! the shard set `generate --shards N` writes, listed in `OUT/shard_set.yaml`.

use std::time::Instant;

use anyhow::{Context as _, bail};
use causal_arm_datagen::{GenerateOptions, shard_options, shard_set_manifest};
use causal_arm_node::env::MAX_DOMAIN_ID;
use causal_arm_node::{RosArgs, RosEnv};
use causal_arm_protocol::Experiment;
use causal_arm_rig::launch::{Process, wait_all};

/// Runs the shard set of `options` as `count` graphs and waits for all of them.
pub fn run(
    options: &GenerateOptions,
    count: u64,
    composed: bool,
    ros_args: &RosArgs,
) -> anyhow::Result<()> {
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
        let exe = std::env::current_exe().context("locating the causal-arm executable")?;
        let name = format!("shard {i} (domain {domain})");
        let env = [("ROS_DOMAIN_ID", domain.to_string())];
        children.push(Process::spawn_env(
            &name,
            &exe,
            &shard_args(shard, composed, ros_args),
            &env,
        )?);
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
            ("--chunk-compression", shard.compression.to_string()),
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
