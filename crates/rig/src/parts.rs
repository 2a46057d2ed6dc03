//! The step parts the babbler and the recorder join, and the feeds that fill them.

use std::rc::Rc;

use causal_arm_msgs::RosMessage;
use causal_arm_msgs::builtin_interfaces::msg::Time;
use causal_arm_msgs::geometry_msgs::msg::PoseStamped;
use causal_arm_msgs::msg::{Action, MagnetState, ObjectColor};
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_msgs::sensor_msgs::msg::JointState;
use causal_arm_msgs::tf2_msgs::msg::TFMessage;
use causal_arm_node::RosNode;
use causal_arm_protocol::{StepMessages, StepParts, WellFormed, fill, step_parts, topics};
use ros2_client::QosProfile;

use crate::feed::{Feed, LocalFeed, TopicFeed};
use crate::intra::{IntraPort, local_receiver};
use crate::screen::{Screen, Screened};

step_parts! {
    /// What the babbler needs of a step: the topics a `SimState` is read from.
    pub struct StateParts {
        joint_states: JointState = topics::JOINT_STATES,
        ef_pose: PoseStamped = topics::EF_POSE,
        object_pose: PoseStamped = topics::OBJECT_POSE,
        object_color: ObjectColor = topics::OBJECT_COLOR,
        magnet: MagnetState = topics::MAGNET_STATE,
    }
}

step_parts! {
    /// What the recorder writes of a step: every state topic and the babbler's answer.
    pub struct RecordParts {
        joint_states: JointState = topics::JOINT_STATES,
        ef_pose: PoseStamped = topics::EF_POSE,
        object_pose: PoseStamped = topics::OBJECT_POSE,
        object_color: ObjectColor = topics::OBJECT_COLOR,
        magnet: MagnetState = topics::MAGNET_STATE,
        clock: Clock = topics::CLOCK,
        tf: TFMessage = topics::TF,
        action: Action = topics::ACTION,
    }
}

impl RecordParts {
    /// The step's state messages and action, in the order a bag holds them; `None` while
    /// a part is missing.
    pub fn into_step(self) -> Option<(StepMessages, Action)> {
        Some((
            StepMessages {
                joint_states: self.joint_states?,
                ef_pose: self.ef_pose?,
                object_pose: self.object_pose?,
                object_color: self.object_color?,
                magnet: self.magnet?,
                clock: self.clock?,
                tf: self.tf?,
            },
            self.action?,
        ))
    }
}

/// The slots of the five state topics both part kinds hold, so one function builds their
/// feeds.
pub trait StateSlots {
    /// `/joint_states`.
    fn joint_states(&mut self) -> &mut Option<JointState>;
    /// `/end_effector/pose`.
    fn ef_pose(&mut self) -> &mut Option<PoseStamped>;
    /// `/object/pose`.
    fn object_pose(&mut self) -> &mut Option<PoseStamped>;
    /// `/object/color`.
    fn object_color(&mut self) -> &mut Option<ObjectColor>;
    /// `/magnet/state`.
    fn magnet(&mut self) -> &mut Option<MagnetState>;
}

macro_rules! state_slots {
    ($parts:ty) => {
        impl StateSlots for $parts {
            fn joint_states(&mut self) -> &mut Option<JointState> {
                &mut self.joint_states
            }
            fn ef_pose(&mut self) -> &mut Option<PoseStamped> {
                &mut self.ef_pose
            }
            fn object_pose(&mut self) -> &mut Option<PoseStamped> {
                &mut self.object_pose
            }
            fn object_color(&mut self) -> &mut Option<ObjectColor> {
                &mut self.object_color
            }
            fn magnet(&mut self) -> &mut Option<MagnetState> {
                &mut self.magnet
            }
        }
    };
}
state_slots!(StateParts);
state_slots!(RecordParts);

/// Where a node's feeds come from: DDS, screened by the node's [`Screen`], or in process
/// for the topics a node composed with it publishes (`port`, see [`crate::intra`]).
pub struct FeedSource<'a, 'p> {
    /// The subscribing node.
    pub node: &'a mut RosNode,
    /// Its screen of DDS writers.
    pub screen: &'a Rc<Screen>,
    /// Its in-process links, when composed.
    pub port: Option<IntraPort<'p>>,
}

/// A boxed feed of `topic` for `source`'s node: in process if a composed node publishes
/// it, else a DDS subscription with `qos`, screened.
pub fn feed<M, P>(
    source: &mut FeedSource<'_, '_>,
    topic: &'static str,
    qos: &QosProfile,
    stamp: fn(&M) -> &Time,
    put: fn(&mut P, M) -> bool,
) -> anyhow::Result<Box<dyn Feed<P>>>
where
    M: RosMessage + WellFormed + Send + 'static,
    P: StepParts + 'static,
{
    if let Some(receiver) = local_receiver::<M>(source.port, topic)? {
        return Ok(Box::new(LocalFeed::new(topic, receiver, stamp, put)));
    }
    let screened = Screened::new(source.node, topic, qos.clone(), source.screen)?;
    Ok(Box::new(TopicFeed::new(topic, screened, stamp, put)))
}

/// Feeds of the five state topics, in the graph's order.
pub fn state_feeds<P: StepParts + StateSlots + 'static>(
    source: &mut FeedSource<'_, '_>,
    qos: &QosProfile,
) -> anyhow::Result<Vec<Box<dyn Feed<P>>>> {
    Ok(vec![
        feed(
            source,
            topics::JOINT_STATES,
            qos,
            |m: &JointState| &m.header.stamp,
            |p: &mut P, m| fill(p.joint_states(), m),
        )?,
        feed(
            source,
            topics::EF_POSE,
            qos,
            |m: &PoseStamped| &m.header.stamp,
            |p: &mut P, m| fill(p.ef_pose(), m),
        )?,
        feed(
            source,
            topics::OBJECT_POSE,
            qos,
            |m: &PoseStamped| &m.header.stamp,
            |p: &mut P, m| fill(p.object_pose(), m),
        )?,
        feed(
            source,
            topics::OBJECT_COLOR,
            qos,
            |m: &ObjectColor| &m.header.stamp,
            |p: &mut P, m| fill(p.object_color(), m),
        )?,
        feed(
            source,
            topics::MAGNET_STATE,
            qos,
            |m: &MagnetState| &m.header.stamp,
            |p: &mut P, m| fill(p.magnet(), m),
        )?,
    ])
}

/// Feeds of every topic the recorder writes per step.
pub fn record_feeds(
    source: &mut FeedSource<'_, '_>,
    qos: &QosProfile,
) -> anyhow::Result<Vec<Box<dyn Feed<RecordParts>>>> {
    /// The stamp of a `/tf` message: its first transform's (an empty one files under 0,
    /// which is refused as stale once step 0 is written).
    fn tf_stamp(m: &TFMessage) -> &Time {
        const ZERO: Time = Time { sec: 0, nanosec: 0 };
        m.transforms.first().map_or(&ZERO, |t| &t.header.stamp)
    }
    let mut feeds = state_feeds(source, qos)?;
    feeds.push(feed(
        source,
        topics::CLOCK,
        qos,
        |m: &Clock| &m.clock,
        |p: &mut RecordParts, m| fill(&mut p.clock, m),
    )?);
    feeds.push(feed(
        source,
        topics::TF,
        qos,
        tf_stamp,
        |p: &mut RecordParts, m| fill(&mut p.tf, m),
    )?);
    feeds.push(feed(
        source,
        topics::ACTION,
        qos,
        |m: &Action| &m.header.stamp,
        |p: &mut RecordParts, m| fill(&mut p.action, m),
    )?);
    Ok(feeds)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_step_is_complete_only_with_every_topic_and_the_action() {
        let mut parts = RecordParts::default();
        assert_eq!(parts.missing().len(), 8);
        *parts.joint_states() = Some(JointState::default());
        parts.ef_pose = Some(PoseStamped::default());
        parts.object_pose = Some(PoseStamped::default());
        parts.object_color = Some(ObjectColor::default());
        parts.magnet = Some(MagnetState::default());
        parts.clock = Some(Clock::default());
        parts.tf = Some(TFMessage::default());
        assert_eq!(parts.missing(), vec![topics::ACTION]);
        assert!(parts.clone().into_step().is_none());
        parts.action = Some(Action::default());
        assert!(parts.into_step().is_some());
    }

    #[test]
    fn the_babbler_waits_for_the_five_state_topics_only() {
        let parts = StateParts::default();
        assert_eq!(
            parts.missing(),
            vec![
                topics::JOINT_STATES,
                topics::EF_POSE,
                topics::OBJECT_POSE,
                topics::OBJECT_COLOR,
                topics::MAGNET_STATE
            ]
        );
    }
}
