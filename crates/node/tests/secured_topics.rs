//! DDS Security between our nodes, with keystores made by `causal_arm_security`: what a
//! ROS 2 graph needs and rustdds 0.15.1 got wrong (patches/rustdds-security-*.diff).
//! - Payloads whose length is not a multiple of 4 were padded by the DATA submessage and
//!   then failed decryption.
//! - A participant with two readers of one topic (a ROS 2 node on sim time has its own
//!   `/clock` reader besides the user's) got each sample in one reader only, and its second
//!   reader's key registration failed.
//! - A node's own reader of its own topic had no crypto handle and made every send of
//!   that topic fail for all readers.
//!
//! Starts DDS participants: run inside `tests/netns-run`, as the test command does.

mod common;

use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use causal_arm_msgs::std_msgs::msg::String as RosString;
use causal_arm_node::{RosArgs, RosEnv, RosNode, qos};
use causal_arm_security::{Keystore, SecurityEnv, Strategy};

const DOMAIN: u16 = 96;

/// The environment of a node on loopback, secured with `keystore` under Enforce if given.
fn env(keystore: Option<&Keystore>) -> RosEnv {
    let security = match keystore {
        Some(ks) => SecurityEnv {
            enable: true,
            strategy: Strategy::Enforce,
            keystore: Some(ks.root().to_owned()),
            enclave_override: None,
        },
        None => SecurityEnv::default(),
    };
    RosEnv {
        security,
        ..common::loopback_env(DOMAIN)
    }
}

fn node(name: &str, keystore: Option<&Keystore>, enclave: &str) -> RosNode {
    let args = RosArgs {
        enclave: Some(enclave.to_owned()),
        ..RosArgs::default()
    };
    RosNode::with_env(env(keystore), name, &[], &args).expect("node")
}

fn take_all(subscription: &ros2_client::Subscription<RosString>, into: &mut Vec<String>) {
    while let Ok(Some((m, _))) = subscription.take() {
        into.push(m.data);
    }
}

#[test]
fn secured_nodes_exchange_every_sample_and_an_unsecured_node_gets_none() {
    let dir = tempfile::tempdir().unwrap();
    let keystore = Keystore::create(dir.path(), DOMAIN).unwrap();
    keystore.create_enclave("/talker", DOMAIN).unwrap();
    keystore.create_enclave("/listener", DOMAIN).unwrap();

    let mut talker = node("secured_talker", Some(&keystore), "/talker");
    let mut listener = node("secured_listener", Some(&keystore), "/listener");
    let mut outsider = node("unsecured_outsider", None, "/");
    let topic = "/secured_chatter";
    let own = talker
        .subscription::<RosString>(topic, qos::recorded())
        .unwrap();
    let first = listener
        .subscription::<RosString>(topic, qos::recorded())
        .unwrap();
    let second = listener
        .subscription::<RosString>(topic, qos::recorded())
        .unwrap();
    let stray = outsider
        .subscription::<RosString>(topic, qos::recorded())
        .unwrap();
    let publisher = talker
        .publisher::<RosString>(topic, qos::recorded())
        .unwrap();
    let stop = AtomicBool::new(false);
    let matched = talker.wait_for_subscribers(
        &publisher,
        2,
        Duration::from_secs(30),
        Duration::from_millis(1000),
        &stop,
    );
    assert!(matched, "the listener's two readers never matched");

    // Lengths 1..=40 cover every padding of the payload to 4 octets.
    let sent: Vec<String> = (1..=40).map(|n| "x".repeat(n)).collect();
    for data in &sent {
        publisher.publish(RosString { data: data.clone() }).unwrap();
    }
    let (mut got_first, mut got_second, mut got_own, mut got_stray) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let deadline = Instant::now() + Duration::from_secs(20);
    while (got_first.len() < sent.len() || got_second.len() < sent.len())
        && Instant::now() < deadline
    {
        take_all(&first, &mut got_first);
        take_all(&second, &mut got_second);
        std::thread::sleep(Duration::from_millis(20));
    }
    take_all(&own, &mut got_own);
    take_all(&stray, &mut got_stray);
    assert_eq!(got_first, sent, "first reader");
    assert_eq!(got_second, sent, "second reader of the same participant");
    assert!(
        got_stray.is_empty(),
        "an unauthenticated node read {} samples",
        got_stray.len()
    );
    // Intra-participant delivery is not supported under DDS Security (documented).
    assert!(got_own.is_empty());
}

#[test]
fn enforce_refuses_a_node_without_an_enclave() {
    let dir = tempfile::tempdir().unwrap();
    let keystore = Keystore::create(dir.path(), DOMAIN).unwrap();
    let err = match RosNode::with_env(env(Some(&keystore)), "no_enclave", &[], &RosArgs::default())
    {
        Ok(_) => panic!("a node without an enclave joined under Enforce"),
        Err(err) => err.to_string(),
    };
    assert!(err.contains("ROS_SECURITY_STRATEGY=Enforce"), "{err}");
}

/// rustdds took the security plugins and then the participant when it created a reader or
/// writer, but the participant and then the plugins when it created a topic: a node whose
/// spinner subscribed while its owner made a topic hung at start (one secured launch in
/// three; patches/rustdds-security-lock-order.diff). Both orders race here many times.
#[test]
fn topics_and_readers_made_at_once_on_a_secured_participant_never_deadlock() {
    use rustdds::{QosPolicyBuilder, TopicKind, no_key::SimpleDataReader};
    type Reader = SimpleDataReader<RosString, rustdds::CDRDeserializerAdapter<RosString>>;
    const ROUNDS: usize = 1000;

    let dir = tempfile::tempdir().unwrap();
    let keystore = Keystore::create(dir.path(), DOMAIN).unwrap();
    keystore.create_enclave("/racer", DOMAIN).unwrap();
    let env = env(Some(&keystore));
    let security = env.security.resolve(Some("/racer")).unwrap();
    let participant = env.domain_participant(&security).unwrap();
    let qos = QosPolicyBuilder::new().build();
    let type_name = "std_msgs::msg::dds_::String_".to_owned();
    let topic = participant
        .create_topic("rt/race".into(), type_name.clone(), &qos, TopicKind::NoKey)
        .unwrap();
    let subscriber = participant.create_subscriber(&qos).unwrap();
    let stop = std::sync::Arc::new(AtomicBool::new(false));
    let (topics_participant, topics_stop) = (participant.clone(), stop.clone());
    let topics = std::thread::spawn(move || {
        while !topics_stop.load(std::sync::atomic::Ordering::Relaxed) {
            topics_participant
                .create_topic("rt/race".into(), type_name.clone(), &qos, TopicKind::NoKey)
                .map_err(|e| format!("{e:?}"))?;
        }
        Ok::<(), String>(())
    });
    let (readers_tx, readers_rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let made = (0..ROUNDS).try_for_each(|_| {
            let reader: Reader = subscriber
                .create_simple_datareader_no_key(&topic, None)
                .map_err(|e| format!("{e:?}"))?;
            drop(reader);
            Ok::<(), String>(())
        });
        readers_tx.send(made).unwrap();
    });
    match readers_rx.recv_timeout(Duration::from_secs(120)) {
        Ok(made) => made.expect("a reader"),
        Err(e) => {
            // The threads hold the participant: dropping it here would wait for them.
            std::mem::forget(participant);
            panic!("making topics and readers at once deadlocked ({e})");
        }
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    topics.join().unwrap().expect("a topic");
}
