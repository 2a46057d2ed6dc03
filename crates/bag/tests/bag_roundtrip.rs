//! Bags written by BagWriter read back identically; bad situations give clear errors.

use causal_arm_bag::{BagError, BagOptions, BagReader, BagWriter, offered_qos_yaml};
use causal_arm_msgs::geometry_msgs::msg::PoseStamped;
use causal_arm_msgs::msg::Action;
use causal_arm_msgs::sensor_msgs::msg::JointState;

fn sample(i: u64) -> (JointState, PoseStamped, Action) {
    let mut js = JointState::default();
    js.header.stamp.sec = (i / 10) as i32;
    js.header.stamp.nanosec = (i % 10) as u32 * 100_000_000;
    js.name = (1..=7).map(|j| format!("iiwa_joint_{j}")).collect();
    js.position = (0..7).map(|j| i as f64 * 0.001 + j as f64).collect();
    let mut pose = PoseStamped {
        header: js.header.clone(),
        ..Default::default()
    };
    pose.pose.position.x = i as f64;
    let action = Action {
        header: js.header.clone(),
        step: i as u32,
        joint_targets: vec![0.1 * i as f64; 7],
        magnet: (i % 3) as i8 - 1,
        ..Default::default()
    };
    (js, pose, action)
}

fn write_bag(dir: &std::path::Path, n: u64, chunk: u64) -> causal_arm_bag::BagSummary {
    let mut w = BagWriter::create(
        dir,
        BagOptions {
            chunk_size: chunk,
            custom_data: [("causal_arm.experiment".to_owned(), "exp1".to_owned())].into(),
            ..BagOptions::default()
        },
    )
    .unwrap();
    let qos = offered_qos_yaml(true, false, true, 0);
    w.add_topic::<JointState>("/joint_states", &qos).unwrap();
    w.add_topic::<PoseStamped>("/end_effector/pose", &qos)
        .unwrap();
    w.add_topic::<Action>("/babbler/action", &qos).unwrap();
    for i in 0..n {
        let (js, pose, action) = sample(i);
        let t = i * 100_000_000;
        w.write("/joint_states", t, &js).unwrap();
        w.write("/end_effector/pose", t, &pose).unwrap();
        w.write("/babbler/action", t, &action).unwrap();
    }
    w.finish().unwrap()
}

#[test]
fn written_messages_read_back_identically() {
    let tmp = tempdir();
    let dir = tmp.path().join("run1");
    let summary = write_bag(&dir, 500, 4096);
    assert_eq!(summary.message_count, 1500);
    assert!(dir.join("run1_0.mcap").exists() && dir.join("metadata.yaml").exists());
    let r = BagReader::open(&dir).unwrap();
    assert!(r.truncation().is_none());
    let topics = r.topics();
    assert_eq!(topics.len(), 3);
    assert!(topics.iter().all(|t| t.message_count == 500));
    let mut i = 0;
    for raw in r.messages() {
        let raw = raw.unwrap();
        let k = i / 3;
        let (js, pose, action) = sample(k);
        match raw.topic.as_str() {
            "/joint_states" => assert_eq!(r.decode::<JointState>(&raw).unwrap(), js),
            "/end_effector/pose" => assert_eq!(r.decode::<PoseStamped>(&raw).unwrap(), pose),
            "/babbler/action" => assert_eq!(r.decode::<Action>(&raw).unwrap(), action),
            other => panic!("unexpected topic {other}"),
        }
        assert_eq!(raw.log_time_ns, k * 100_000_000);
        i += 1;
    }
    assert_eq!(i, 1500);
    let meta = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    assert!(
        meta.contains("storage_identifier: mcap") && meta.contains("message_count: 1500"),
        "{meta}"
    );
    assert!(meta.contains("causal_arm.experiment: exp1"), "{meta}");
    assert_eq!(r.custom_data()["causal_arm.experiment"], "exp1");
}

#[test]
fn wrong_type_decode_is_named() {
    let tmp = tempdir();
    let dir = tmp.path().join("b");
    write_bag(&dir, 3, 4096);
    let r = BagReader::open(&dir).unwrap();
    let raw = r.messages().next().unwrap().unwrap();
    let err = r.decode::<Action>(&raw).unwrap_err().to_string();
    assert!(
        err.contains("/joint_states") && err.contains("stored as sensor_msgs/msg/JointState"),
        "{err}"
    );
}

#[test]
fn existing_bag_is_refused_without_overwrite() {
    let tmp = tempdir();
    let dir = tmp.path().join("b");
    write_bag(&dir, 3, 4096);
    let err = BagWriter::create(&dir, BagOptions::default())
        .err()
        .unwrap();
    assert!(matches!(err, BagError::Exists { .. }), "{err}");
    assert!(err.to_string().contains("--overwrite"));
    let w = BagWriter::create(
        &dir,
        BagOptions {
            overwrite: true,
            ..BagOptions::default()
        },
    )
    .unwrap();
    let s = w.finish().unwrap();
    assert_eq!(s.message_count, 0);
}

#[test]
fn unwritable_directory_is_named() {
    let tmp = tempdir();
    let file = tmp.path().join("plain");
    std::fs::write(&file, "x").unwrap();
    let err = BagWriter::create(&file.join("bag"), BagOptions::default())
        .err()
        .unwrap()
        .to_string();
    assert!(
        err.contains("plain") && err.contains("creating the bag directory"),
        "{err}"
    );
}

#[test]
fn dropped_writer_leaves_a_finished_bag() {
    let tmp = tempdir();
    let dir = tmp.path().join("dropped");
    {
        let mut w = BagWriter::create(&dir, BagOptions::default()).unwrap();
        w.add_topic::<JointState>("/joint_states", "").unwrap();
        w.write("/joint_states", 1, &sample(1).0).unwrap();
    }
    let r = BagReader::open(&dir).unwrap();
    assert!(r.truncation().is_none());
    assert_eq!(r.message_count(), 1);
}

#[test]
fn truncated_files_yield_a_prefix() {
    let tmp = tempdir();
    let dir = tmp.path().join("full");
    write_bag(&dir, 2000, 8192);
    let bytes = std::fs::read(dir.join("full_0.mcap")).unwrap();
    let mut last = 0;
    for cut in [
        bytes.len() / 5,
        bytes.len() / 3,
        bytes.len() / 2,
        bytes.len() * 9 / 10,
        bytes.len() - 10,
    ] {
        let file = tmp.path().join(format!("cut_{cut}.mcap"));
        std::fs::write(&file, &bytes[..cut]).unwrap();
        let r = BagReader::open(&file).unwrap();
        assert!(r.truncation().is_some(), "cut at {cut} should be reported");
        assert_eq!(
            r.custom_data()["causal_arm.experiment"],
            "exp1",
            "cut at {cut}"
        );
        let n = r.messages().filter(|m| m.is_ok()).count() as u64;
        assert_eq!(n, r.message_count());
        assert!(n >= last, "longer prefixes hold more messages");
        last = n;
        // Every message read is intact.
        for raw in r.messages() {
            let raw = raw.unwrap();
            if raw.topic == "/joint_states" {
                r.decode::<JointState>(&raw).unwrap();
            }
        }
    }
    assert!(
        last > 3000,
        "most of the data survives a cut near the end (got {last})"
    );
}

/// A scratch directory removed when the test ends (pass or fail).
fn tempdir() -> tempfile::TempDir {
    tempfile::Builder::new()
        .prefix("causal-arm-bag-test-")
        .tempdir()
        .unwrap()
}

/// The same writes give the same file, byte for byte, however many topics (the summary
/// lists schemas and channels by id, not in hash-map order): a bag is reproducible from
/// its seed, and a changed byte means changed data.
#[test]
fn the_same_writes_give_the_same_bytes() {
    let tmp = tempdir();
    let write = |dir: &std::path::Path| {
        let mut w = BagWriter::create(dir, BagOptions::default()).unwrap();
        let qos = offered_qos_yaml(true, false, true, 0);
        for t in 0..12 {
            w.add_topic::<JointState>(&format!("/joint_states_{t}"), &qos)
                .unwrap();
            w.add_topic::<PoseStamped>(&format!("/pose_{t}"), &qos)
                .unwrap();
        }
        for i in 0..50 {
            let (js, pose, _) = sample(i);
            for t in 0..12 {
                w.write(&format!("/joint_states_{t}"), i, &js).unwrap();
                w.write(&format!("/pose_{t}"), i, &pose).unwrap();
            }
        }
        w.finish().unwrap();
    };
    let (a, b) = (
        tmp.path().join("a").join("bag"),
        tmp.path().join("b").join("bag"),
    );
    write(&a);
    write(&b);
    for name in ["bag_0.mcap", "metadata.yaml"] {
        let (x, y) = (
            std::fs::read(a.join(name)).unwrap(),
            std::fs::read(b.join(name)).unwrap(),
        );
        assert!(x == y, "{name} differs between two identical runs");
    }
}
