//! `causal_arm_recorder`: subscribes to every topic of the graph and writes the bag,
//! one complete step at a time, in the same order `causal-arm generate` writes.
//! SIGINT/SIGTERM finalize the bag with every complete step; incomplete trailing steps
//! are reported, not silently dropped.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::bail;
use causal_arm_datagen::{BagSink, StepSink, validate};
use causal_arm_msgs::geometry_msgs::msg::PoseStamped;
use causal_arm_msgs::msg::{Action, MagnetState, ObjectColor};
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_msgs::sensor_msgs::msg::JointState;
use causal_arm_msgs::std_msgs::msg::String as RosString;
use causal_arm_msgs::tf2_msgs::msg::TFMessage;
use causal_arm_node::{RosArgs, RosNode, qos};
use causal_arm_protocol::{StepMessages, ns_from_time, time_from_ns, topics};

use crate::{ACK_TOPIC, RunParams, node_param_specs, stop_flag};

#[derive(Default)]
struct StepBuffer {
    joint_states: Option<JointState>,
    ef_pose: Option<PoseStamped>,
    object_pose: Option<PoseStamped>,
    object_color: Option<ObjectColor>,
    magnet: Option<MagnetState>,
    clock: Option<Clock>,
    tf: Option<TFMessage>,
    action: Option<Action>,
}

impl StepBuffer {
    fn missing(&self) -> Vec<&'static str> {
        let mut m = Vec::new();
        if self.joint_states.is_none() {
            m.push(topics::JOINT_STATES)
        }
        if self.ef_pose.is_none() {
            m.push(topics::EF_POSE)
        }
        if self.object_pose.is_none() {
            m.push(topics::OBJECT_POSE)
        }
        if self.object_color.is_none() {
            m.push(topics::OBJECT_COLOR)
        }
        if self.magnet.is_none() {
            m.push(topics::MAGNET_STATE)
        }
        if self.clock.is_none() {
            m.push(topics::CLOCK)
        }
        if self.tf.is_none() {
            m.push(topics::TF)
        }
        if self.action.is_none() {
            m.push(topics::ACTION)
        }
        m
    }
}

/// Runs the recorder node until every step is written or SIGINT/SIGTERM.
pub fn run(ros_args: &RosArgs) -> anyhow::Result<()> {
    let specs = node_param_specs("causal_arm_recorder")?;
    let mut node = RosNode::new("causal_arm_recorder", &specs, ros_args)?;
    let output = node.params().string("output").to_owned();
    if output.is_empty() {
        bail!("parameter \"output\" is required: --ros-args -p output:=bags/NAME");
    }
    let run = RunParams::from_params(node.params(), &output)?;
    validate(&run.options)?;
    let timeout = Duration::from_secs_f64(node.params().double("timeout"));
    let stop = stop_flag();
    let recorded = qos::recorded();
    let joint_states = node.subscription::<JointState>(topics::JOINT_STATES, recorded.clone())?;
    let ef_pose = node.subscription::<PoseStamped>(topics::EF_POSE, recorded.clone())?;
    let object_pose = node.subscription::<PoseStamped>(topics::OBJECT_POSE, recorded.clone())?;
    let object_color = node.subscription::<ObjectColor>(topics::OBJECT_COLOR, recorded.clone())?;
    let magnet = node.subscription::<MagnetState>(topics::MAGNET_STATE, recorded.clone())?;
    let clock = node.subscription::<Clock>(topics::CLOCK, recorded.clone())?;
    let tf = node.subscription::<TFMessage>(topics::TF, recorded.clone())?;
    let actions = node.subscription::<Action>(topics::ACTION, recorded)?;
    let description = node.subscription::<RosString>(topics::ROBOT_DESCRIPTION, qos::latched())?;
    let ack = node.publisher::<Clock>(ACK_TOPIC, qos::default_reliable())?;

    let mut sink = BagSink::create(
        &PathBuf::from(&output),
        node.params().bool("overwrite"),
        &run.options,
    )?;
    let total = run.options.plan.total_steps();
    let mut buffers: BTreeMap<u64, StepBuffer> = BTreeMap::new();
    let mut have_description = false;
    let mut written = 0u64;
    let mut last_activity = Instant::now();
    let mut result = Ok(());
    while written < total && !stop.load(Ordering::SeqCst) {
        let mut got = false;
        if !have_description && let Ok(Some((d, _))) = description.take() {
            sink.robot_description(&d)?;
            have_description = true;
            got = true;
        }
        macro_rules! drain {
            ($sub:expr, $field:ident, $stamp:expr) => {
                while let Ok(Some((m, _))) = $sub.take() {
                    got = true;
                    let key = ns_from_time(&$stamp(&m));
                    buffers.entry(key).or_default().$field = Some(m);
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
        drain!(clock, clock, |m: &Clock| m.clock.clone());
        drain!(tf, tf, |m: &TFMessage| m
            .transforms
            .first()
            .map(|t| t.header.stamp.clone())
            .unwrap_or_default());
        drain!(actions, action, |m: &Action| m.header.stamp.clone());
        let mut last_written = None;
        while have_description && let Some(entry) = buffers.first_entry() {
            if !entry.get().missing().is_empty() {
                break;
            }
            let stamp = *entry.key();
            let b = entry.remove();
            let messages = StepMessages {
                joint_states: b.joint_states.expect("complete"),
                ef_pose: b.ef_pose.expect("complete"),
                object_pose: b.object_pose.expect("complete"),
                object_color: b.object_color.expect("complete"),
                magnet: b.magnet.expect("complete"),
                clock: b.clock.expect("complete"),
                tf: b.tf.expect("complete"),
            };
            sink.state(stamp, &messages)?;
            sink.action(stamp, &b.action.expect("complete"))?;
            written += 1;
            last_written = Some(stamp);
        }
        if let Some(stamp) = last_written {
            let _ = ack.publish(Clock {
                clock: time_from_ns(stamp),
            });
            if written.is_multiple_of(1000) || written == total {
                tracing::info!("recorded {written}/{total} steps");
            }
        }
        if got {
            last_activity = Instant::now();
        } else {
            if last_activity.elapsed() > timeout {
                result = Err(anyhow::anyhow!(
                    "nothing received for {timeout:?} after {written} of {total} steps; bag finalized with the complete steps"
                ));
                break;
            }
            std::thread::sleep(Duration::from_micros(50));
        }
    }
    if !buffers.is_empty() {
        let (stamp, first) = buffers.iter().next().expect("non-empty");
        tracing::warn!(
            "{} incomplete step(s) not written (first at {} ns lacks {})",
            buffers.len(),
            stamp,
            first.missing().join(", ")
        );
    }
    let summary = sink.finish()?;
    // Give reliable delivery of the last ack time to reach the simulator.
    std::thread::sleep(Duration::from_millis(300));
    tracing::info!(
        "wrote {} ({written} steps of {total})",
        summary.dir.display()
    );
    println!("bag: {} ({written} steps)", summary.dir.display());
    result
}
