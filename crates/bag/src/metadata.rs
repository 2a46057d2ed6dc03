//! `metadata.yaml` read back: a bag directory's index must agree with its MCAP file, so a
//! file cut short or damaged after the index was written is never read as a smaller bag.

use std::collections::BTreeMap;
use std::path::Path;

use serde::Deserialize;

use crate::{BagError, BagReader};

/// The parts of rosbag2's `metadata.yaml` (any version) that describe what the file holds.
#[derive(Deserialize)]
struct Index {
    rosbag2_bagfile_information: Information,
}

#[derive(Deserialize)]
struct Information {
    #[serde(default)]
    message_count: u64,
    #[serde(default)]
    relative_file_paths: Vec<String>,
    #[serde(default)]
    topics_with_message_count: Vec<TopicCount>,
}

#[derive(Deserialize)]
struct TopicCount {
    topic_metadata: TopicName,
    message_count: u64,
}

#[derive(Deserialize)]
struct TopicName {
    name: String,
}

/// Checks `dir/metadata.yaml` against what `reader` found in the MCAP file: it must exist,
/// parse, name the file, and count no more messages per topic than the file holds (a
/// writer keeps it current as chunks land, so fewer only means a crash after the last
/// update).
pub(crate) fn check(dir: &Path, reader: &BagReader) -> Result<(), BagError> {
    let path = dir.join("metadata.yaml");
    let problem = |problem: String| BagError::Metadata {
        path: path.clone(),
        problem,
    };
    let text = match std::fs::read_to_string(&path) {
        Ok(text) => text,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Err(problem(
                "missing: a bag directory needs its index (`causal-arm bag recover` writes one)"
                    .into(),
            ));
        }
        Err(error) => {
            return Err(BagError::Io {
                path,
                action: "reading",
                error,
            });
        }
    };
    let index: Index =
        serde_norway::from_str(&text).map_err(|e| problem(format!("not a rosbag2 index: {e}")))?;
    let info = index.rosbag2_bagfile_information;
    let file = reader
        .path()
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    if !info.relative_file_paths.is_empty() && !info.relative_file_paths.contains(&file) {
        return Err(problem(format!(
            "lists files {:?}, not {file}",
            info.relative_file_paths
        )));
    }
    let held: BTreeMap<String, u64> = reader
        .topics()
        .into_iter()
        .map(|t| (t.name, t.message_count))
        .collect();
    for topic in &info.topics_with_message_count {
        let name = &topic.topic_metadata.name;
        let found = held.get(name).copied().unwrap_or(0);
        if topic.message_count > found {
            return Err(problem(format!(
                "counts {} messages on {name}, the MCAP file holds {found}",
                topic.message_count
            )));
        }
    }
    if info.message_count > reader.message_count() {
        return Err(problem(format!(
            "counts {} messages, the MCAP file holds {}",
            info.message_count,
            reader.message_count()
        )));
    }
    Ok(())
}
