//! The simulator's state as the ROS 2 messages it publishes each step, the way back, and
//! the babbler's answer as an `Action` message.
//!
//! Shared by the DDS nodes, the in-process `generate` path and the ground truth's
//! re-simulation so all write the same messages with the same values. Nothing here needs
//! the simulator: the joint names come from the caller's arm model.

use causal_arm_msgs::builtin_interfaces::msg::Time;
use causal_arm_msgs::geometry_msgs::msg::{
    Point, Pose, PoseStamped, Quaternion, Transform, TransformStamped, Vector3,
};
use causal_arm_msgs::msg::{Action, Draw as DrawMsg, MagnetState, ObjectColor};
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_msgs::sensor_msgs::msg::JointState;
use causal_arm_msgs::std_msgs::msg::{ColorRGBA, Header, String as RosString};
use causal_arm_msgs::tf2_msgs::msg::TFMessage;
use nalgebra::Isometry3;

use crate::design::Drawn;
use crate::scene::Scene;
use crate::step::{ARM_DOF, SimState};
use crate::topics::{self, frames, ns_from_time, time_from_ns};

/// All state messages of one step.
#[derive(Debug, Clone, PartialEq)]
pub struct StepMessages {
    /// `/joint_states`.
    pub joint_states: JointState,
    /// `/end_effector/pose`.
    pub ef_pose: PoseStamped,
    /// `/object/pose`.
    pub object_pose: PoseStamped,
    /// `/object/color`.
    pub object_color: ObjectColor,
    /// `/magnet/state`.
    pub magnet: MagnetState,
    /// `/clock`.
    pub clock: Clock,
    /// `/tf`.
    pub tf: TFMessage,
}

fn header(stamp: &Time, frame: &str) -> Header {
    Header {
        stamp: stamp.clone(),
        frame_id: frame.to_owned(),
    }
}

fn pose_of(iso: &Isometry3<f64>) -> Pose {
    let t = iso.translation.vector;
    let q = iso.rotation.coords;
    Pose {
        position: Point {
            x: t.x,
            y: t.y,
            z: t.z,
        },
        orientation: Quaternion {
            x: q.x,
            y: q.y,
            z: q.z,
            w: q.w,
        },
    }
}

/// One edge of the tf tree: where `child` is in `parent`'s frame. The arm model makes them
/// from the URDF (one per joint); the messages below stamp them.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameTransform {
    /// Parent frame (the joint's parent link).
    pub parent: String,
    /// Child frame (the joint's child link).
    pub child: String,
    /// The child's pose in the parent's frame.
    pub pose: Isometry3<f64>,
}

fn transform(stamp: &Time, parent: &str, child: &str, iso: &Isometry3<f64>) -> TransformStamped {
    let p = pose_of(iso);
    TransformStamped {
        header: header(stamp, parent),
        child_frame_id: child.to_owned(),
        transform: Transform {
            translation: Vector3 {
                x: p.position.x,
                y: p.position.y,
                z: p.position.z,
            },
            rotation: p.orientation,
        },
    }
}

fn tf_message(stamp: &Time, frames: &[FrameTransform]) -> TFMessage {
    TFMessage {
        transforms: frames
            .iter()
            .map(|f| transform(stamp, &f.parent, &f.child, &f.pose))
            .collect(),
    }
}

/// What a run publishes once, latched, before its first step (`topics::LATCHED`).
#[derive(Debug, Clone, PartialEq)]
pub struct LatchedMessages {
    /// `/robot_description`: the URDF text.
    pub robot_description: RosString,
    /// `/tf_static`: see [`static_tf_message`].
    pub tf_static: TFMessage,
}

/// `/tf_static` of a run, stamped at sim time 0 as robot_state_publisher stamps it at
/// start: the arm's fixed joints (`ArmModel::fixed_frames`) and world → table top.
pub fn static_tf_message(arm_fixed_frames: &[FrameTransform], scene: &Scene) -> TFMessage {
    let mut frames = arm_fixed_frames.to_vec();
    frames.push(FrameTransform {
        parent: frames::WORLD.to_owned(),
        child: frames::TABLE.to_owned(),
        pose: scene.table_pose(),
    });
    tf_message(&time_from_ns(0), &frames)
}

/// The messages the simulator publishes for `state`; `joint_names` are the arm model's
/// actuated joints in chain order (`ArmModel::joint_names`) and `arm_frames` its revolute
/// joints' transforms at the state's joint values (`ArmModel::moving_frames`), which `/tf`
/// carries beside world → object.
pub fn step_messages(
    state: &SimState,
    joint_names: &[&str],
    mut arm_frames: Vec<FrameTransform>,
) -> StepMessages {
    let stamp = time_from_ns(state.stamp_ns);
    StepMessages {
        joint_states: JointState {
            header: header(&stamp, ""),
            name: joint_names.iter().map(|n| n.to_string()).collect(),
            position: state.joint_positions.to_vec(),
            velocity: state.joint_velocities.to_vec(),
            effort: state.joint_efforts.to_vec(),
        },
        ef_pose: PoseStamped {
            header: header(&stamp, frames::WORLD),
            pose: pose_of(&state.ef_pose),
        },
        object_pose: PoseStamped {
            header: header(&stamp, frames::WORLD),
            pose: pose_of(&state.cube_pose),
        },
        object_color: ObjectColor {
            header: header(&stamp, frames::OBJECT),
            color: ColorRGBA {
                r: state.cube_rgb[0],
                g: state.cube_rgb[1],
                b: state.cube_rgb[2],
                a: 1.0,
            },
        },
        magnet: MagnetState {
            header: header(&stamp, ""),
            on: state.magnet_on,
            holding: state.holding,
        },
        clock: Clock {
            clock: stamp.clone(),
        },
        tf: {
            arm_frames.push(FrameTransform {
                parent: frames::WORLD.to_owned(),
                child: frames::OBJECT.to_owned(),
                pose: state.cube_pose,
            });
            tf_message(&stamp, &arm_frames)
        },
    }
}

/// Why messages could not be turned back into a [`SimState`].
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("state messages at stamp {stamp_ns} ns: {problem}")]
pub struct StateFromMessagesError {
    /// Stamp being assembled.
    pub stamp_ns: u64,
    /// What is wrong.
    pub problem: String,
}

fn iso_of(pose: &Pose) -> Isometry3<f64> {
    Isometry3::from_parts(
        nalgebra::Translation3::new(pose.position.x, pose.position.y, pose.position.z),
        nalgebra::UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(
            pose.orientation.w,
            pose.orientation.x,
            pose.orientation.y,
            pose.orientation.z,
        )),
    )
}

fn joints7(
    values: &[f64],
    field: &str,
    stamp_ns: u64,
) -> Result<[f64; ARM_DOF], StateFromMessagesError> {
    values.try_into().map_err(|_| StateFromMessagesError {
        stamp_ns,
        problem: format!(
            "/joint_states {field} has {} values, expected {}",
            values.len(),
            ARM_DOF
        ),
    })
}

/// The inverse of [`step_messages`]: what a subscriber (the babbler node) knows of the
/// state. `step` and `episode` are the subscriber's own counts.
pub fn state_from_messages(
    joint_states: &JointState,
    ef_pose: &PoseStamped,
    object_pose: &PoseStamped,
    object_color: &ObjectColor,
    magnet: &MagnetState,
    step: u64,
    episode: u32,
) -> Result<SimState, StateFromMessagesError> {
    let stamp_ns = ns_from_time(&joint_states.header.stamp);
    for (topic, stamp) in [
        (topics::EF_POSE, &ef_pose.header.stamp),
        (topics::OBJECT_POSE, &object_pose.header.stamp),
        (topics::OBJECT_COLOR, &object_color.header.stamp),
        (topics::MAGNET_STATE, &magnet.header.stamp),
    ] {
        if ns_from_time(stamp) != stamp_ns {
            return Err(StateFromMessagesError {
                stamp_ns,
                problem: format!("{topic} has stamp {} ns", ns_from_time(stamp)),
            });
        }
    }
    Ok(SimState {
        stamp_ns,
        step,
        episode,
        joint_positions: joints7(&joint_states.position, "position", stamp_ns)?,
        joint_velocities: joints7(&joint_states.velocity, "velocity", stamp_ns)?,
        joint_efforts: joints7(&joint_states.effort, "effort", stamp_ns)?,
        ef_pose: iso_of(&ef_pose.pose),
        cube_pose: iso_of(&object_pose.pose),
        cube_rgb: [
            object_color.color.r,
            object_color.color.g,
            object_color.color.b,
        ],
        magnet_on: magnet.on,
        holding: magnet.holding,
    })
}

/// The Action message answering `state` with `drawn`'s command, saying how it was drawn.
pub fn action_message(state: &SimState, drawn: &Drawn, step_in_episode: u64) -> Action {
    let command = &drawn.command;
    Action {
        header: Header {
            stamp: time_from_ns(state.stamp_ns),
            frame_id: String::new(),
        },
        episode: state.episode,
        step: step_in_episode as u32,
        joint_deltas: command
            .joint_targets
            .iter()
            .zip(&state.joint_positions)
            .map(|(t, q)| t - q)
            .collect(),
        joint_targets: command.joint_targets.to_vec(),
        magnet: command.magnet,
        design: drawn.design.iter().map(DrawMsg::from).collect(),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::step::Command;
    use nalgebra::{Translation3, UnitQuaternion};

    const JOINTS: [&str; ARM_DOF] = [
        "iiwa_joint_1",
        "iiwa_joint_2",
        "iiwa_joint_3",
        "iiwa_joint_4",
        "iiwa_joint_5",
        "iiwa_joint_6",
        "iiwa_joint_7",
    ];

    /// A state as the simulator could report it after a few steps, built by hand.
    pub(crate) fn state() -> SimState {
        SimState {
            stamp_ns: 1_041_666_667,
            step: 25,
            episode: 2,
            joint_positions: [0.1, 0.6, 0.0, -1.1, 0.2, 0.7, 0.3],
            joint_velocities: [0.01, -0.2, 0.0, 0.3, -0.05, 0.0, 1.5],
            joint_efforts: [1.0, -2.5, 0.0, 3.25, 0.0, -0.5, 0.125],
            ef_pose: Isometry3::from_parts(
                Translation3::new(0.55, -0.1, 0.42),
                UnitQuaternion::from_euler_angles(3.0, 0.1, -0.4),
            ),
            cube_pose: Isometry3::from_parts(
                Translation3::new(0.6, 0.05, 0.225),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 1.2),
            ),
            cube_rgb: [0.25, 0.5, 0.75],
            magnet_on: true,
            holding: false,
        }
    }

    #[test]
    fn messages_round_trip_to_the_same_state() {
        let state = state();
        let link = FrameTransform {
            parent: "iiwa_link_0".into(),
            child: "iiwa_link_1".into(),
            pose: Isometry3::translation(0.0, 0.0, 0.1575),
        };
        let m = step_messages(&state, &JOINTS, vec![link]);
        assert_eq!(m.joint_states.name[6], "iiwa_joint_7");
        assert_eq!(m.clock.clock, time_from_ns(state.stamp_ns));
        assert_eq!(m.ef_pose.header.frame_id, frames::WORLD);
        assert_eq!(m.object_color.header.frame_id, frames::OBJECT);
        let edges: Vec<_> =
            m.tf.transforms
                .iter()
                .map(|t| (t.header.frame_id.as_str(), t.child_frame_id.as_str()))
                .collect();
        assert_eq!(
            edges,
            [
                ("iiwa_link_0", "iiwa_link_1"),
                (frames::WORLD, frames::OBJECT)
            ]
        );
        assert_eq!(m.tf.transforms[0].transform.translation.z, 0.1575);
        assert_eq!(
            m.tf.transforms[1].header.stamp,
            time_from_ns(state.stamp_ns)
        );
        let back = state_from_messages(
            &m.joint_states,
            &m.ef_pose,
            &m.object_pose,
            &m.object_color,
            &m.magnet,
            state.step,
            state.episode,
        )
        .unwrap();
        assert_eq!(back, state);
        let mut late = m.magnet.clone();
        late.header.stamp.nanosec += 1;
        let err = state_from_messages(
            &m.joint_states,
            &m.ef_pose,
            &m.object_pose,
            &m.object_color,
            &late,
            0,
            0,
        )
        .unwrap_err();
        assert!(err.to_string().contains("/magnet/state has stamp"), "{err}");
        let mut short = m.joint_states.clone();
        short.velocity.pop();
        let err = state_from_messages(
            &short,
            &m.ef_pose,
            &m.object_pose,
            &m.object_color,
            &m.magnet,
            0,
            0,
        )
        .unwrap_err();
        assert!(
            err.to_string()
                .contains("/joint_states velocity has 6 values, expected 7"),
            "{err}"
        );
    }

    #[test]
    fn action_answers_the_state_it_was_computed_from() {
        let state = state();
        let command = Command {
            joint_targets: [0.2, 0.6, -0.5, -1.0, 0.2, 0.7, 0.0],
            magnet: -1,
        };
        let a = action_message(&state, &Drawn::scripted(command.clone(), 8), 7);
        assert_eq!(a.design.len(), 8);
        assert_eq!(a.header.stamp, time_from_ns(state.stamp_ns));
        assert_eq!((a.episode, a.step, a.magnet), (2, 7, -1));
        assert_eq!(a.joint_targets, command.joint_targets);
        let deltas: Vec<f64> = (0..ARM_DOF)
            .map(|i| command.joint_targets[i] - state.joint_positions[i])
            .collect();
        assert_eq!(a.joint_deltas, deltas);
    }
}
