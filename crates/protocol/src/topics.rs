//! Topic names of the graph (absolute, as users type them in `ros2 topic echo`), the frame
//! names of headers and `/tf`, and the conversion between sim time and ROS stamps.
//!
//! The simulator publishes, the babbler and recorder subscribe and the dataset reads bags by
//! these names; one table keeps them from drifting apart.

use causal_arm_msgs::builtin_interfaces::msg::Time;

/// `sensor_msgs/msg/JointState`.
pub const JOINT_STATES: &str = "/joint_states";
/// `geometry_msgs/msg/PoseStamped` of the `ef` frame.
pub const EF_POSE: &str = "/end_effector/pose";
/// `geometry_msgs/msg/PoseStamped` of the cube.
pub const OBJECT_POSE: &str = "/object/pose";
/// `causal_arm_msgs/msg/ObjectColor`.
pub const OBJECT_COLOR: &str = "/object/color";
/// `causal_arm_msgs/msg/MagnetState`.
pub const MAGNET_STATE: &str = "/magnet/state";
/// `rosgraph_msgs/msg/Clock`.
pub const CLOCK: &str = "/clock";
/// `tf2_msgs/msg/TFMessage`, every step: each revolute joint's parent link → child link
/// at the step's joint values (what robot_state_publisher would publish) and world → object.
pub const TF: &str = "/tf";
/// `tf2_msgs/msg/TFMessage`, latched: the fixed joints (world → base, flange → magnet →
/// ef) and world → table top. With `/tf` every frame has exactly one parent.
pub const TF_STATIC: &str = "/tf_static";
/// `visualization_msgs/msg/MarkerArray`: table, cube and magnet for RViz and Foxglove
/// (`markers::scene_markers`). The simulator publishes it when it changes; bags hold it
/// every step, so a viewer seeking anywhere draws the scene.
pub const SCENE_MARKERS: &str = "/scene/markers";
/// `std_msgs/msg/String`, latched.
pub const ROBOT_DESCRIPTION: &str = "/robot_description";
/// `causal_arm_msgs/msg/Action` from the babbler.
pub const ACTION: &str = "/babbler/action";
/// `rosgraph_msgs/msg/Clock` from the recorder: the stamp of the last step that has landed
/// in a closed chunk of the bag (the simulator's flow control).
pub const RECORDER_ACK: &str = "/recorder/ack";

/// The topics of one recorded step, in the order a bag holds them: a step is complete
/// when it has one message on each.
pub const RECORDED_STEP: [&str; 8] = [
    JOINT_STATES,
    EF_POSE,
    OBJECT_POSE,
    OBJECT_COLOR,
    MAGNET_STATE,
    CLOCK,
    TF,
    ACTION,
];

/// Every topic of the graph.
pub const ALL: [&str; 12] = [
    JOINT_STATES,
    EF_POSE,
    OBJECT_POSE,
    OBJECT_COLOR,
    MAGNET_STATE,
    CLOCK,
    TF,
    TF_STATIC,
    SCENE_MARKERS,
    ROBOT_DESCRIPTION,
    ACTION,
    RECORDER_ACK,
];

/// The latched topics of a run: published once before the first step, recorded once at
/// sim time 0, kept by a resumed bag.
pub const LATCHED: [&str; 2] = [ROBOT_DESCRIPTION, TF_STATIC];

/// Frame names used in headers and /tf.
pub mod frames {
    /// Fixed world frame (the URDF root).
    pub const WORLD: &str = "world";
    /// Tool tip: the tool frame whose pose the experiments record (the link the arm
    /// model's kinematic chain ends at; in tf a child of the `magnet` link).
    pub const EF: &str = "ef";
    /// The cube.
    pub const OBJECT: &str = "object";
    /// Centre of the table top (the link of `urdf/table.urdf`).
    pub const TABLE: &str = "table_top";
}

/// ROS time from nanoseconds of sim time.
pub fn time_from_ns(ns: u64) -> Time {
    Time {
        sec: (ns / 1_000_000_000) as i32,
        nanosec: (ns % 1_000_000_000) as u32,
    }
}

/// Nanoseconds from a ROS time (negative times clamp to 0).
pub fn ns_from_time(t: &Time) -> u64 {
    (t.sec.max(0) as u64) * 1_000_000_000 + t.nanosec as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn time_conversion_is_exact() {
        for ns in [
            0,
            1,
            999_999_999,
            1_000_000_000,
            41_666_667,
            123_456_789_012,
        ] {
            assert_eq!(ns_from_time(&time_from_ns(ns)), ns);
        }
    }
}
