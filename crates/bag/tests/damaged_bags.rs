//! Damage is never read as less data: every single-byte change of a finished file is an
//! error naming the place, a crash tail is told apart from mid-file damage, and salvaging
//! reads every intact chunk.

use causal_arm_bag::{BagError, BagOptions, BagReader, BagWriter, ReadPolicy, offered_qos_yaml};
use causal_arm_msgs::sensor_msgs::msg::JointState;

fn write_bag(dir: &std::path::Path, n: u64, chunk: u64) {
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
    for i in 0..n {
        let js = JointState {
            position: (0..7).map(|j| (i * 7 + j) as f64).collect(),
            ..Default::default()
        };
        w.write("/joint_states", i * 1000, &js).unwrap();
    }
    w.finish().unwrap();
}

fn tempdir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "causal-arm-damage-{name}-{}-{}",
        std::process::id(),
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_nanos()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn small_bag(name: &str) -> (std::path::PathBuf, Vec<u8>) {
    let tmp = tempdir(name);
    write_bag(&tmp.join("bag"), 60, 600);
    let bytes = std::fs::read(tmp.join("bag/bag_0.mcap")).unwrap();
    (tmp, bytes)
}

#[test]
fn every_single_byte_change_of_a_finished_file_is_named_damage() {
    let (tmp, bytes) = small_bag("flip");
    let file = tmp.join("flipped.mcap");
    let mut accepted = Vec::new();
    for at in 0..bytes.len() {
        let mut damaged = bytes.clone();
        damaged[at] ^= 0x5a;
        std::fs::write(&file, &damaged).unwrap();
        match BagReader::open_with(&file, ReadPolicy::Strict) {
            Ok(_) => accepted.push(at),
            Err(BagError::Damaged { path, damage, .. }) => {
                assert_eq!(path, file);
                assert!(
                    damage.offset < bytes.len() as u64,
                    "flip at {at} named at {damage}"
                );
            }
            Err(e) => panic!("flip at {at}: not reported as damage: {e}"),
        }
    }
    assert!(
        accepted.is_empty(),
        "{} flips read as sound: {accepted:?}",
        accepted.len()
    );
}

#[test]
fn crash_tails_warn_and_mid_file_cuts_are_damage() {
    let (tmp, bytes) = small_bag("cut");
    let full = BagReader::open(&tmp.join("bag")).unwrap().message_count();
    let file = tmp.join("cut.mcap");
    for cut in (9..bytes.len()).step_by(7) {
        std::fs::write(&file, &bytes[..cut]).unwrap();
        match BagReader::open_with(&file, ReadPolicy::Strict) {
            Ok(r) => {
                assert!(r.truncation().is_some(), "cut at {cut} not reported");
                assert!(r.message_count() <= full);
                assert_eq!(
                    r.messages().filter(|m| m.is_ok()).count() as u64,
                    r.message_count()
                );
            }
            Err(BagError::Metadata { problem, .. }) => {
                assert!(
                    problem.contains("no readable messages"),
                    "cut at {cut}: {problem}"
                )
            }
            Err(e) => panic!("cut at {cut}: a crash tail must not be damage: {e}"),
        }
    }
    // Cutting a bag directory's file below what its metadata.yaml counts is damage.
    let dir = tmp.join("bag");
    std::fs::write(dir.join("bag_0.mcap"), &bytes[..bytes.len() / 2]).unwrap();
    let err = BagReader::open(&dir)
        .err()
        .expect("a cut bag directory is refused");
    let text = err.to_string();
    assert!(
        text.contains("metadata.yaml") && text.contains("/joint_states"),
        "{text}"
    );
}

#[test]
fn a_damaged_chunk_in_the_middle_is_an_error_and_salvage_reads_the_rest() {
    let (tmp, bytes) = small_bag("salvage");
    let sound = BagReader::open(&tmp.join("bag")).unwrap();
    assert!(sound.chunk_count() >= 4, "{} chunks", sound.chunk_count());
    let full = sound.message_count();
    // Damage the compressed data of the second chunk.
    let second = nth_chunk_offset(&bytes, 1);
    let mut damaged = bytes.clone();
    damaged[second + 60] ^= 0xff;
    let file = tmp.join("damaged.mcap");
    std::fs::write(&file, &damaged).unwrap();
    let err = BagReader::open(&file).err().expect("damage is an error");
    let text = err.to_string();
    assert!(
        text.contains("damaged.mcap") && text.contains(&format!("byte {second} (chunk 1)")),
        "{text}"
    );
    let salvaged = BagReader::open_with(&file, ReadPolicy::Salvage).unwrap();
    assert_eq!(
        salvaged.damage().len(),
        1 + 1,
        "the chunk and the data CRC: {:?}",
        salvaged.damage()
    );
    assert!(salvaged.message_count() < full && salvaged.message_count() > full / 2);
    assert_eq!(salvaged.lost_known() + salvaged.message_count(), full);
    // A length field broken mid-file: the rest is found again.
    let mut broken = bytes.clone();
    broken[second + 1..second + 9].copy_from_slice(&u64::MAX.to_le_bytes());
    std::fs::write(&file, &broken).unwrap();
    let err = BagReader::open(&file)
        .err()
        .expect("a broken frame mid-file is damage");
    assert!(err.to_string().contains(&format!("byte {second}")), "{err}");
    let salvaged = BagReader::open_with(&file, ReadPolicy::Salvage).unwrap();
    assert!(
        salvaged.message_count() >= full - full / 4,
        "{} of {full}",
        salvaged.message_count()
    );
}

#[test]
fn junk_empty_and_magic_only_files_are_refused() {
    let tmp = tempdir("junk");
    let file = tmp.join("x.mcap");
    for (what, bytes) in [
        ("empty", Vec::new()),
        ("magic only", b"\x89MCAP0\r\n".to_vec()),
        ("text", b"this is not a bag\n".to_vec()),
        ("huge chunk", {
            let mut b = b"\x89MCAP0\r\n".to_vec();
            b.push(0x06);
            b.extend_from_slice(&(1u64 << 62).to_le_bytes());
            b
        }),
    ] {
        std::fs::write(&file, &bytes).unwrap();
        let err = BagReader::open(&file)
            .err()
            .unwrap_or_else(|| panic!("{what} accepted"));
        assert!(err.to_string().contains("x.mcap"), "{what}: {err}");
    }
}

/// Offset of the n-th chunk record, found by walking the top-level records.
fn nth_chunk_offset(bytes: &[u8], n: usize) -> usize {
    let mut pos = 8;
    let mut seen = 0;
    loop {
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        if bytes[pos] == 0x06 {
            if seen == n {
                return pos;
            }
            seen += 1;
        }
        pos += 9 + len;
    }
}
