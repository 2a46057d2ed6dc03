//! A node's parameter services enforce the descriptors it declares, as rclcpp's do
//! (patches/ros2-client-parameter-descriptor-rules.diff). Before, rclpy's SetParameters of
//! `folds = -5` on the trainer answered `successful = true` although the descriptor said
//! 2..1,000,000, and the node went on with the value it had read at start.
//!
//! Starts DDS participants: run inside `tests/netns-run`, as the test command does.

mod common;

use causal_arm_node::{ParamSpec, ParamValue, RosArgs, RosNode};
use ros2_client::ParameterValue;

#[test]
fn a_node_refuses_to_change_a_parameter_it_read_at_start() {
    let specs = [
        ParamSpec::new("folds", ParamValue::Integer(5), "cross-validation folds")
            .with_range(2.0, 1e6),
    ];
    let mut node = RosNode::with_env(
        common::loopback_env(96),
        "parameter_rules",
        &specs,
        &RosArgs::default(),
    )
    .expect("node");
    let err = node
        .inner()
        .set_parameter("folds", ParameterValue::Integer(-5))
        .unwrap_err();
    assert_eq!(
        err,
        "parameter 'folds' cannot be set because it is read-only"
    );
    assert_eq!(
        node.inner().get_parameter("folds"),
        Some(ParameterValue::Integer(5))
    );
    // use_sim_time is the one the node follows.
    node.inner()
        .set_parameter("use_sim_time", ParameterValue::Boolean(true))
        .unwrap();
    let err = node
        .inner()
        .set_parameter("use_sim_time", ParameterValue::Integer(1))
        .unwrap_err();
    assert!(err.contains("Cannot change type"), "{err}");
}
