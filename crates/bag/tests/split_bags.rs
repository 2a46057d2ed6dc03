//! Split bags (rosbag2's `--max-bag-size` / `--max-bag-duration`): files named and listed
//! as rosbag2 does, each closed one finished and readable alone, the whole read as the
//! unsplit bag; a killed writer loses nothing landed; a lost split is an error.

use std::path::Path;

use causal_arm_bag::{BagOptions, BagReader, BagWriter, ReadPolicy, SplitLimits};
use causal_arm_msgs::sensor_msgs::msg::JointState;

const STEP_NS: u64 = 100_000_000;

fn joint_state(i: u64) -> JointState {
    JointState {
        name: (1..=7).map(|j| format!("iiwa_joint_{j}")).collect(),
        position: (0..7).map(|j| (i * 7 + j) as f64 * 1e-3).collect(),
        ..Default::default()
    }
}

/// A writer of `dir` with `split`, small chunks, and one topic registered.
fn writer(dir: &Path, split: SplitLimits) -> BagWriter {
    let mut w = BagWriter::create(
        dir,
        BagOptions {
            chunk_size: 4096,
            split,
            custom_data: [("causal_arm.seed".to_owned(), "7".to_owned())].into(),
            ..BagOptions::default()
        },
    )
    .unwrap();
    w.add_topic::<JointState>("/joint_states", "").unwrap();
    w
}

fn write_bag(dir: &Path, n: u64, split: SplitLimits) -> causal_arm_bag::BagSummary {
    let mut w = writer(dir, split);
    for i in 0..n {
        w.write("/joint_states", i * STEP_NS, &joint_state(i))
            .unwrap();
    }
    w.finish().unwrap()
}

fn content(path: &Path) -> Vec<(u64, Vec<u8>)> {
    BagReader::open(path)
        .unwrap()
        .messages()
        .map(|m| m.map(|m| (m.log_time_ns, m.data)).unwrap())
        .collect()
}

fn metadata(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("metadata.yaml")).unwrap();
    let yaml: serde_norway::Value = serde_norway::from_str(&text).unwrap();
    serde_json::to_value(yaml).unwrap()["rosbag2_bagfile_information"].clone()
}

#[test]
fn a_bag_split_by_duration_reads_as_the_unsplit_one() {
    let tmp = tempfile::tempdir().unwrap();
    let (whole, split) = (tmp.path().join("whole"), tmp.path().join("split"));
    write_bag(&whole, 1000, SplitLimits::default());
    // 10 s of messages per file: 1000 messages at 0.1 s make files of 101, 101, … .
    let limits = SplitLimits::from_ros2_units(0, 10);
    let summary = write_bag(&split, 1000, limits);
    let names: Vec<String> = (0..10).map(|i| format!("split_{i}.mcap")).collect();
    let files: Vec<String> = summary
        .files
        .iter()
        .map(|f| f.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(files, names);
    assert_eq!(content(&split), content(&whole));
    let info = metadata(&split);
    assert_eq!(info["relative_file_paths"], serde_json::json!(names));
    let counts: Vec<u64> = info["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["message_count"].as_u64().unwrap())
        .collect();
    assert_eq!(counts, [101, 101, 101, 101, 101, 101, 101, 101, 101, 91]);
    assert_eq!(info["message_count"], 1000);
    // Each file is a finished MCAP of its own, with the run's custom data.
    let mut alone = Vec::new();
    for name in &names {
        let r = BagReader::open(&split.join(name)).unwrap();
        assert!(r.finished() && r.truncation().is_none(), "{name}");
        assert_eq!(r.custom_data()["causal_arm.seed"], "7", "{name}");
        alone.extend(content(&split.join(name)));
    }
    assert_eq!(alone, content(&whole));
}

#[test]
fn a_bag_split_by_size_keeps_each_file_near_the_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let (whole, split) = (tmp.path().join("whole"), tmp.path().join("split"));
    write_bag(&whole, 3000, SplitLimits::default());
    let limit = 20_000;
    let summary = write_bag(&split, 3000, SplitLimits::from_ros2_units(limit, 0));
    assert!(summary.files.len() >= 3, "{:?}", summary.files);
    assert_eq!(content(&split), content(&whole));
    let chunk_max = 4096 * 2; // a chunk closes past 4096 uncompressed bytes
    for f in &summary.files[..summary.files.len() - 1] {
        let len = std::fs::metadata(f).unwrap().len();
        assert!(
            len >= limit && len < limit + chunk_max + 4096,
            "{}: {len} bytes",
            f.display()
        );
    }
}

#[test]
fn an_unsplit_bag_is_byte_identical_with_or_without_limits_it_never_reaches() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("bag"), tmp.path().join("other").join("bag"));
    write_bag(&a, 500, SplitLimits::default());
    write_bag(&b, 500, SplitLimits::from_ros2_units(1 << 40, 1 << 20));
    for name in ["bag_0.mcap", "metadata.yaml"] {
        assert_eq!(
            std::fs::read(a.join(name)).unwrap(),
            std::fs::read(b.join(name)).unwrap(),
            "{name}"
        );
    }
}

#[test]
fn a_killed_split_writer_leaves_finished_splits_and_a_readable_open_one() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("killed");
    let mut w = writer(&dir, SplitLimits::from_ros2_units(0, 10));
    for i in 0..450 {
        w.write("/joint_states", i * STEP_NS, &joint_state(i))
            .unwrap();
    }
    w.land().unwrap();
    for i in 450..460 {
        w.write("/joint_states", i * STEP_NS, &joint_state(i))
            .unwrap();
    }
    std::mem::forget(w); // SIGKILL: no finish, the open file has no footer
    let r = BagReader::open(&dir).unwrap();
    assert_eq!(r.message_count(), 450, "every landed message, none lost");
    assert!(r.truncation().is_some() && r.damage().is_empty());
    let files = r.files();
    assert_eq!(files.len(), 5);
    assert!(
        files[..4]
            .iter()
            .all(|f| f.finished && f.truncation.is_none())
    );
    assert!(!files[4].finished);
}

#[test]
fn a_lost_split_is_an_error_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("holed");
    write_bag(&dir, 400, SplitLimits::from_ros2_units(0, 10));
    std::fs::remove_file(dir.join("holed_2.mcap")).unwrap();
    let err = BagReader::open_with(&dir, ReadPolicy::Strict)
        .err()
        .expect("a missing split is an error")
        .to_string();
    assert!(
        err.contains("metadata.yaml") && err.contains("holed_2.mcap") && err.contains("missing"),
        "{err}"
    );
}

#[test]
fn a_closed_split_cut_short_afterwards_is_damage() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("cut");
    write_bag(&dir, 400, SplitLimits::from_ros2_units(0, 10));
    let file = dir.join("cut_1.mcap");
    let bytes = std::fs::read(&file).unwrap();
    std::fs::write(&file, &bytes[..bytes.len() / 2]).unwrap();
    let err = BagReader::open_with(&dir, ReadPolicy::Strict)
        .err()
        .expect("a cut closed split is an error")
        .to_string();
    assert!(err.contains("cut_1.mcap"), "{err}");
}
