//! `causal_arm_sim`: the simulator as a ROS 2 node, stepping in lock-step with the babbler
//! and never more than `ack_window` steps ahead of the recorder.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use causal_arm_datagen::validate;
use causal_arm_kinematics::EMBEDDED_IIWA_URDF;
use causal_arm_msgs::geometry_msgs::msg::PoseStamped;
use causal_arm_msgs::msg::{Action, MagnetState, ObjectColor};
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_msgs::sensor_msgs::msg::JointState;
use causal_arm_msgs::std_msgs::msg::String as RosString;
use causal_arm_msgs::tf2_msgs::msg::TFMessage;
use causal_arm_node::{RosArgs, RosNode, qos};
use causal_arm_protocol::{ARM_DOF, Command, ns_from_time, sim_seed, step_messages, topics};
use causal_arm_sim::{SimConfig, Simulator};
use ros2_client::Publisher;

use crate::{ACK_TOPIC, RunParams, node_param_specs, stop_flag, take_next};

fn publish<M: causal_arm_msgs::RosMessage>(
    p: &Publisher<M>,
    msg: M,
    topic: &str,
) -> anyhow::Result<()> {
    p.publish(msg)
        .map_err(|e| anyhow::anyhow!("publishing on {topic}: {e:?}"))
}

/// Runs the simulator node until the run is complete or SIGINT/SIGTERM.
pub fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    let specs = node_param_specs("causal_arm_sim")?;
    let mut node = RosNode::new("causal_arm_sim", &specs, ros_args)?;
    let run = RunParams::from_params(node.params(), "")?;
    validate(&run.options)?;
    let window = node.params().integer("ack_window") as u64;
    let wait_for_recorder = node.params().bool("wait_for_recorder");
    let timeout = Duration::from_secs_f64(node.params().double("timeout"));
    let stop = stop_flag();

    let recorded = qos::recorded();
    let joint_states = node.publisher::<JointState>(topics::JOINT_STATES, recorded.clone())?;
    let ef_pose = node.publisher::<PoseStamped>(topics::EF_POSE, recorded.clone())?;
    let object_pose = node.publisher::<PoseStamped>(topics::OBJECT_POSE, recorded.clone())?;
    let object_color = node.publisher::<ObjectColor>(topics::OBJECT_COLOR, recorded.clone())?;
    let magnet = node.publisher::<MagnetState>(topics::MAGNET_STATE, recorded.clone())?;
    let clock = node.publisher::<Clock>(topics::CLOCK, recorded.clone())?;
    let tf = node.publisher::<TFMessage>(topics::TF, recorded.clone())?;
    let description = node.publisher::<RosString>(topics::ROBOT_DESCRIPTION, qos::latched())?;
    let actions = node.subscription::<Action>(topics::ACTION, recorded.clone())?;
    let acks = node.subscription::<Clock>(ACK_TOPIC, qos::default_reliable())?;

    let mut sim = Simulator::new(SimConfig {
        seed: sim_seed(run.options.seed),
        ..run.options.sim.clone()
    })?;
    let model = sim.model().clone();
    let joint_names = model.joint_names();
    publish(
        &description,
        RosString {
            data: EMBEDDED_IIWA_URDF.to_owned(),
        },
        topics::ROBOT_DESCRIPTION,
    )?;

    // Wait until the babbler (and the recorder) subscribe, then let their side settle.
    let needed = if wait_for_recorder { 2 } else { 1 };
    if !node.wait_for_subscribers(
        &joint_states,
        needed,
        timeout,
        Duration::from_millis(500),
        &stop,
    ) {
        if stop.load(Ordering::SeqCst) {
            return Ok(());
        }
        bail!(
            "{needed} subscriber(s) of {} did not appear within {timeout:?}",
            topics::JOINT_STATES
        );
    }
    tracing::info!(
        "simulator starting: {} × {} steps",
        run.options.plan.episodes,
        run.options.plan.steps_per_episode
    );

    let step_ns = run.step_ns();
    let mut acked: Option<u64> = None;
    let mut last_stamp = 0;
    for episode in 0..run.options.plan.episodes {
        if episode > 0 {
            sim.reset_episode();
        }
        let mut state = sim.state();
        for _ in 0..run.options.plan.steps_per_episode {
            // Flow control: stay within `window` steps of the recorder.
            while wait_for_recorder && !stop.load(Ordering::SeqCst) {
                while let Some((ack, _)) = acks.take().ok().flatten() {
                    acked = Some(acked.unwrap_or(0).max(ns_from_time(&ack.clock)));
                }
                let lag_ok = match acked {
                    Some(a) => (state.stamp_ns as f64 - a as f64) < window as f64 * step_ns - 1.0,
                    None => (state.stamp_ns as f64) < window as f64 * step_ns - 1.0,
                };
                if lag_ok {
                    break;
                }
                if stop.load(Ordering::SeqCst) {
                    return Ok(());
                }
                std::thread::sleep(Duration::from_micros(100));
            }
            let m = step_messages(&state, &joint_names);
            publish(&joint_states, m.joint_states, topics::JOINT_STATES)?;
            publish(&ef_pose, m.ef_pose, topics::EF_POSE)?;
            publish(&object_pose, m.object_pose, topics::OBJECT_POSE)?;
            publish(&object_color, m.object_color, topics::OBJECT_COLOR)?;
            publish(&magnet, m.magnet, topics::MAGNET_STATE)?;
            publish(&clock, m.clock, topics::CLOCK)?;
            publish(&tf, m.tf, topics::TF)?;
            last_stamp = state.stamp_ns;
            // Wait for the babbler's answer to exactly this state.
            let asked = Instant::now();
            let action = loop {
                if stop.load(Ordering::SeqCst) {
                    return Ok(());
                }
                if asked.elapsed() > timeout {
                    bail!(
                        "no {} answering stamp {} ns within {timeout:?}",
                        topics::ACTION,
                        state.stamp_ns
                    );
                }
                match take_next(&actions, Duration::from_millis(100)) {
                    Some(Ok(a)) if ns_from_time(&a.header.stamp) == state.stamp_ns => break a,
                    Some(Ok(a)) => tracing::warn!(
                        "ignoring action stamped {} ns while waiting for {} ns",
                        ns_from_time(&a.header.stamp),
                        state.stamp_ns
                    ),
                    Some(Err(e)) => tracing::warn!("undecodable action: {e:#}"),
                    None => {}
                }
            };
            let targets: [f64; ARM_DOF] =
                action
                    .joint_targets
                    .as_slice()
                    .try_into()
                    .with_context(|| {
                        format!(
                            "action at {} ns has {} joint targets, expected {ARM_DOF}",
                            state.stamp_ns,
                            action.joint_targets.len()
                        )
                    })?;
            state = sim.step(&Command {
                joint_targets: targets,
                magnet: action.magnet,
            })?;
        }
    }
    // Wait until the recorder has everything.
    let start = Instant::now();
    while wait_for_recorder && acked != Some(last_stamp) {
        while let Some((ack, _)) = acks.take().ok().flatten() {
            acked = Some(acked.unwrap_or(0).max(ns_from_time(&ack.clock)));
        }
        if stop.load(Ordering::SeqCst) || start.elapsed() > timeout {
            break;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    tracing::info!(
        "simulator done at sim time {:.3} s",
        last_stamp as f64 * 1e-9
    );
    Ok(())
}
