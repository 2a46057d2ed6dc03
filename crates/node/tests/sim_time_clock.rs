//! A node reads `/clock` only while `use_sim_time` is true, as rclcpp's TimeSource does
//! (patches/ros2-client-clock-on-use-sim-time.diff). Before, every node had its own
//! `/clock` reader, so the simulator sent each tick to every node of the graph (and to
//! itself) on wall time too.
//!
//! Starts DDS participants: run inside `tests/netns-run`, as the test command does.

mod common;

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use causal_arm_msgs::builtin_interfaces::msg::Time;
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_node::{RosNode, qos};
use ros2_client::{ParameterValue, Publisher};

const DOMAIN: u16 = 97;

fn node(name: &str) -> RosNode {
    common::loopback_node(DOMAIN, name)
}

/// Waits up to 20 s until `publisher` has `count` subscribers; returns the last count.
fn wait_for_count(clock: &Publisher<Clock>, talker: &mut RosNode, count: usize) -> usize {
    let start = Instant::now();
    loop {
        let now = clock.get_subscription_count(talker.inner());
        if now == count || start.elapsed() > Duration::from_secs(20) {
            return now;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn a_node_reads_clock_only_while_it_uses_sim_time() {
    let mut talker = node("clock_talker");
    let clock = talker
        .publisher::<Clock>("/clock", qos::recorded())
        .unwrap();
    // A witness reader proves discovery has run when the node on wall time adds none.
    let mut witness = node("clock_witness");
    let _witness_reader = witness
        .subscription::<Clock>("/clock", qos::clock())
        .unwrap();
    let mut listener = node("clock_listener");
    let never = AtomicBool::new(false);
    assert!(talker.wait_for_subscribers(
        &clock,
        1,
        Duration::from_secs(20),
        Duration::ZERO,
        &never
    ));
    std::thread::sleep(Duration::from_secs(2));
    assert_eq!(
        clock.get_subscription_count(talker.inner()),
        1,
        "a node on wall time must not read /clock"
    );

    listener
        .inner()
        .set_parameter("use_sim_time", ParameterValue::Boolean(true))
        .unwrap();
    assert_eq!(
        wait_for_count(&clock, &mut talker, 2),
        2,
        "no /clock reader under sim time"
    );
    let start = Instant::now();
    let ticked = Time {
        sec: 42,
        nanosec: 5,
    };
    while listener.now().to_nanos() != 42_000_000_005 && start.elapsed() < Duration::from_secs(20) {
        clock
            .publish(Clock {
                clock: ticked.clone(),
            })
            .unwrap();
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(
        listener.now().to_nanos(),
        42_000_000_005,
        "sim time did not follow /clock"
    );

    listener
        .inner()
        .set_parameter("use_sim_time", ParameterValue::Boolean(false))
        .unwrap();
    assert_eq!(
        wait_for_count(&clock, &mut talker, 1),
        1,
        "the /clock reader stays after use_sim_time went back to false"
    );
}
