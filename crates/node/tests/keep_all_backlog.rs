//! A recorded-QoS (reliable, keep-all) subscriber that falls far behind its publisher must
//! still take every sample: the recorder lags the simulator by up to its ack window.
//! rustdds 0.15.1 kept only 64 unread samples per topic and evicted the rest after
//! acknowledging them (patches/rustdds-keep-all-reader-cache.diff). Starts DDS
//! participants: run inside `tests/netns-run`, as the test command does.

mod common;

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use causal_arm_msgs::builtin_interfaces::msg::Time;
use causal_arm_msgs::rosgraph_msgs::msg::Clock;
use causal_arm_node::{RosNode, qos};

fn node(name: &str) -> RosNode {
    common::loopback_node(97, name)
}

#[test]
fn a_keep_all_subscriber_that_takes_nothing_for_a_while_still_gets_every_sample() {
    const BACKLOG: u32 = 2000;
    let mut sender = node("backlog_sender");
    let mut receiver = node("backlog_receiver");
    let subscription = receiver
        .subscription::<Clock>("/backlog", qos::recorded())
        .expect("subscription");
    let publisher = sender
        .publisher::<Clock>("/backlog", qos::recorded())
        .expect("publisher");
    let stop = AtomicBool::new(false);
    let matched = sender.wait_for_subscribers(
        &publisher,
        1,
        Duration::from_secs(20),
        Duration::from_millis(500),
        &stop,
    );
    assert!(matched, "the subscriber never matched");
    for sec in 0..BACKLOG {
        let clock = Clock {
            clock: Time {
                sec: sec as i32,
                nanosec: 0,
            },
        };
        publisher.publish(clock).expect("publish");
    }
    // Take nothing until the whole burst has been delivered and acknowledged (the
    // reader cache's periodic clean-up runs every 4 s).
    std::thread::sleep(Duration::from_secs(5));
    let mut got = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(20);
    while got.len() < BACKLOG as usize && Instant::now() < deadline {
        match subscription.take().expect("take") {
            Some((m, _)) => got.push(m.clock.sec as u32),
            None => std::thread::sleep(Duration::from_millis(10)),
        }
    }
    assert_eq!(
        got.len(),
        BACKLOG as usize,
        "first taken: {:?}",
        got.first()
    );
    assert!(
        got.iter().enumerate().all(|(i, &s)| i as u32 == s),
        "out of order"
    );
}
