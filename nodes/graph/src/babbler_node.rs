//! `causal_arm_babbler`: answers every simulator state with a babbling action.

use std::collections::BTreeMap;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::bail;
use causal_arm_datagen::{Babbler, validate};
use causal_arm_kinematics::ArmModel;
use causal_arm_msgs::geometry_msgs::msg::PoseStamped;
use causal_arm_msgs::msg::{Action, MagnetState, ObjectColor};
use causal_arm_msgs::sensor_msgs::msg::JointState;
use causal_arm_node::{RosArgs, RosNode, qos};
use causal_arm_protocol::{action_message, ns_from_time, state_from_messages, topics};

use crate::{RunParams, node_param_specs, stop_flag, take_next};

#[derive(Default)]
struct Partial {
    joint_states: Option<JointState>,
    ef_pose: Option<PoseStamped>,
    object_pose: Option<PoseStamped>,
    object_color: Option<ObjectColor>,
    magnet: Option<MagnetState>,
}

/// Runs the babbler node until it answered every step of the run or SIGINT/SIGTERM.
pub fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    let specs = node_param_specs("causal_arm_babbler")?;
    let mut node = RosNode::new("causal_arm_babbler", &specs, ros_args)?;
    let run = RunParams::from_params(node.params(), "")?;
    validate(&run.options)?;
    let timeout = Duration::from_secs_f64(node.params().double("timeout"));
    let stop = stop_flag();
    let recorded = qos::recorded();
    let joint_states = node.subscription::<JointState>(topics::JOINT_STATES, recorded.clone())?;
    let ef_pose = node.subscription::<PoseStamped>(topics::EF_POSE, recorded.clone())?;
    let object_pose = node.subscription::<PoseStamped>(topics::OBJECT_POSE, recorded.clone())?;
    let object_color = node.subscription::<ObjectColor>(topics::OBJECT_COLOR, recorded.clone())?;
    let magnet = node.subscription::<MagnetState>(topics::MAGNET_STATE, recorded.clone())?;
    let actions = node.publisher::<Action>(topics::ACTION, recorded)?;
    let model = ArmModel::embedded();
    let mut babbler = Babbler::new(&run.options, &model)?;

    if !node.wait_for_subscribers(&actions, 1, timeout, Duration::from_millis(500), &stop) {
        if stop.load(Ordering::SeqCst) {
            return Ok(());
        }
        bail!(
            "no subscriber of {} (the simulator) within {timeout:?}",
            topics::ACTION
        );
    }

    let per_episode = run.options.plan.steps_per_episode;
    let total = run.options.plan.total_steps();
    let mut pending: BTreeMap<u64, Partial> = BTreeMap::new();
    let mut answered = 0u64;
    let mut last_activity = Instant::now();
    while answered < total && !stop.load(Ordering::SeqCst) {
        let mut got = false;
        macro_rules! drain {
            ($sub:expr, $field:ident, $stamp:expr) => {
                while let Ok(Some((m, _))) = $sub.take() {
                    got = true;
                    let key = ns_from_time(&$stamp(&m));
                    pending.entry(key).or_default().$field = Some(m);
                }
            };
        }
        drain!(joint_states, joint_states, |m: &JointState| m
            .header
            .stamp
            .clone());
        drain!(ef_pose, ef_pose, |m: &PoseStamped| m.header.stamp.clone());
        drain!(object_pose, object_pose, |m: &PoseStamped| m
            .header
            .stamp
            .clone());
        drain!(object_color, object_color, |m: &ObjectColor| m
            .header
            .stamp
            .clone());
        drain!(magnet, magnet, |m: &MagnetState| m.header.stamp.clone());
        while let Some(entry) = pending.first_entry() {
            let p = entry.get();
            let (Some(js), Some(ef), Some(obj), Some(col), Some(mag)) = (
                &p.joint_states,
                &p.ef_pose,
                &p.object_pose,
                &p.object_color,
                &p.magnet,
            ) else {
                break;
            };
            let k = answered % per_episode;
            let episode = (answered / per_episode) as u32;
            if k == 0 && answered > 0 {
                babbler.reset();
            }
            let state = state_from_messages(js, ef, obj, col, mag, answered, episode)?;
            entry.remove();
            let command = babbler.next(&state);
            actions
                .publish(action_message(&state, &command, k))
                .map_err(|e| anyhow::anyhow!("publishing on {}: {e:?}", topics::ACTION))?;
            answered += 1;
        }
        if got {
            last_activity = Instant::now();
        } else {
            if last_activity.elapsed() > timeout {
                bail!(
                    "no state from the simulator for {timeout:?} after {answered} of {total} steps"
                );
            }
            // Sleep until the sample the oldest pending step still lacks arrives (no polling).
            let missing = pending.values().next().map_or(0, |p| {
                [
                    p.joint_states.is_none(),
                    p.ef_pose.is_none(),
                    p.object_pose.is_none(),
                    p.object_color.is_none(),
                    p.magnet.is_none(),
                ]
                .iter()
                .position(|m| *m)
                .unwrap_or(0)
            });
            let wait = Duration::from_millis(100);
            macro_rules! wait_on {
                ($sub:expr, $field:ident) => {
                    if let Some(Ok(m)) = take_next(&$sub, wait) {
                        let key = ns_from_time(&m.header.stamp);
                        pending.entry(key).or_default().$field = Some(m);
                        last_activity = Instant::now();
                    }
                };
            }
            match missing {
                0 => wait_on!(joint_states, joint_states),
                1 => wait_on!(ef_pose, ef_pose),
                2 => wait_on!(object_pose, object_pose),
                3 => wait_on!(object_color, object_color),
                _ => wait_on!(magnet, magnet),
            }
        }
    }

    // Let reliable delivery of the last action complete.
    std::thread::sleep(Duration::from_millis(200));
    tracing::info!("babbler answered {answered} of {total} steps");
    Ok(())
}
