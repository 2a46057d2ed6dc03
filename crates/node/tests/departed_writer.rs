//! A node that exits right after its last messages are acknowledged must not lose them:
//! a reliable reader that had not yet taken them when the writer's participant left still
//! gets them (patches/rustdds-departed-writer-samples-stay-takeable.diff). Before, rustdds
//! hid every untaken sample of a departed writer, and the recorder lost the babbler's last
//! action when it lagged behind a babbler that had already exited.
//!
//! Starts DDS participants: run inside `tests/netns-run`, as the test command does.

mod common;

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use causal_arm_msgs::builtin_interfaces::msg::Time;
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_node::{RosNode, qos};

const DOMAIN: u16 = 95;

fn node(name: &str) -> RosNode {
    common::loopback_node(DOMAIN, name)
}

fn tick(sec: i32) -> Clock {
    Clock {
        clock: Time { sec, nanosec: 0 },
    }
}

#[test]
fn a_departed_writers_acknowledged_samples_are_still_taken() {
    let mut listener = node("departure_listener");
    let subscription = listener
        .subscription::<Clock>("/departing", qos::recorded())
        .unwrap();
    let mut talker = node("departure_talker");
    let publisher = talker
        .publisher::<Clock>("/departing", qos::recorded())
        .unwrap();
    let never = AtomicBool::new(false);
    assert!(talker.wait_for_subscribers(
        &publisher,
        1,
        Duration::from_secs(20),
        Duration::ZERO,
        &never
    ));
    for sec in 1..=5 {
        publisher.publish(tick(sec)).unwrap();
    }
    assert!(
        publisher
            .wait_for_all_acked(Duration::from_secs(10))
            .unwrap(),
        "the listener never acknowledged the samples"
    );
    drop(publisher);
    drop(talker);

    // Take nothing until the listener has seen the writer go.
    let start = Instant::now();
    while subscription.get_publisher_count(listener.inner()) > 0 {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "the listener never noticed the talker leave"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut taken = Vec::new();
    while let Ok(Some((message, _))) = subscription.take() {
        taken.push(message.clock.sec);
    }
    assert_eq!(
        taken,
        [1, 2, 3, 4, 5],
        "samples of the departed writer were lost"
    );
}
