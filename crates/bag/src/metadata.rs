//! `metadata.yaml`, rosbag2's index of a bag: written atomically by the writer as chunks
//! land, and read back against the MCAP files, so a file cut short, lost or damaged after
//! the index was written is never read as a smaller bag.

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::{BagError, BagFile, BagReader};

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
    #[serde(default)]
    files: Vec<FileCount>,
}

#[derive(Deserialize)]
struct FileCount {
    path: String,
    #[serde(default)]
    message_count: u64,
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

/// Checks `dir/metadata.yaml` against what `reader` found in the MCAP files: it must
/// exist, parse, list the files, and count no more messages per topic than the files hold
/// (a writer keeps it current as chunks land, so fewer only means a crash after the last
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
    let files = reader.files();
    check_files(&info.relative_file_paths, &files).map_err(problem)?;
    if files.len() > 1 {
        check_file_counts(&info.files, &files).map_err(problem)?;
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

/// The files `metadata.yaml` lists must be the bag's: none missing (a lost split would be
/// read as a smaller bag), none unlisted but a last one without messages (a writer killed
/// between opening a split and listing it). An index that lists none (old formats) is
/// not checked.
fn check_files(listed: &[String], files: &[BagFile]) -> Result<(), String> {
    if listed.is_empty() {
        return Ok(());
    }
    let found: Vec<String> = files
        .iter()
        .map(|f| crate::files::file_name(&f.path))
        .collect();
    if let Some(missing) = listed.iter().find(|l| !found.contains(l)) {
        return Err(format!(
            "lists {missing}, which is missing from the bag (it holds {found:?}): a split was lost"
        ));
    }
    for (i, (name, file)) in found.iter().zip(files).enumerate() {
        let fresh_last = i + 1 == files.len() && file.message_count == 0;
        if !listed.contains(name) && !fresh_last {
            return Err(format!("lists files {listed:?}, not {name}"));
        }
    }
    Ok(())
}

/// Each file holds at least what the index counts in it, so the split of a split bag cut
/// short after it was indexed is named.
fn check_file_counts(counted: &[FileCount], files: &[BagFile]) -> Result<(), String> {
    for file in files {
        let name = crate::files::file_name(&file.path);
        if let Some(c) = counted.iter().find(|c| c.path == name)
            && c.message_count > file.message_count
        {
            return Err(format!(
                "counts {} messages in {name}, which holds {}",
                c.message_count, file.message_count
            ));
        }
    }
    Ok(())
}

/// Writes `dir/metadata.yaml` atomically (a temporary file renamed into place), so a
/// reader never sees half an index.
pub(crate) fn write(dir: &Path, info: BagfileInformation) -> Result<(), BagError> {
    let final_path = dir.join("metadata.yaml");
    let text = serde_norway::to_string(&Metadata {
        rosbag2_bagfile_information: info,
    })
    .map_err(|e| BagError::Metadata {
        path: final_path.clone(),
        problem: e.to_string(),
    })?;
    crate::write_atomically(&final_path, &text)
}

/// rosbag2's `metadata.yaml` (format 9) as written.
#[derive(Serialize)]
struct Metadata {
    rosbag2_bagfile_information: BagfileInformation,
}

#[derive(Serialize)]
pub(crate) struct BagfileInformation {
    pub(crate) version: u32,
    pub(crate) storage_identifier: String,
    pub(crate) duration: Nanoseconds,
    pub(crate) starting_time: NanosecondsSinceEpoch,
    pub(crate) message_count: u64,
    pub(crate) topics_with_message_count: Vec<TopicWithCount>,
    pub(crate) compression_format: String,
    pub(crate) compression_mode: String,
    pub(crate) relative_file_paths: Vec<String>,
    pub(crate) files: Vec<FileInformation>,
    pub(crate) custom_data: BTreeMap<String, String>,
    pub(crate) ros_distro: String,
}

#[derive(Serialize)]
pub(crate) struct Nanoseconds {
    pub(crate) nanoseconds: u64,
}

#[derive(Serialize)]
pub(crate) struct NanosecondsSinceEpoch {
    pub(crate) nanoseconds_since_epoch: u64,
}

#[derive(Serialize)]
pub(crate) struct TopicWithCount {
    pub(crate) topic_metadata: TopicMetadata,
    pub(crate) message_count: u64,
}

#[derive(Serialize)]
pub(crate) struct TopicMetadata {
    pub(crate) name: String,
    pub(crate) r#type: String,
    pub(crate) serialization_format: String,
    pub(crate) offered_qos_profiles: serde_norway::Value,
    pub(crate) type_description_hash: String,
}

#[derive(Serialize)]
pub(crate) struct FileInformation {
    pub(crate) path: String,
    pub(crate) starting_time: NanosecondsSinceEpoch,
    pub(crate) duration: Nanoseconds,
    pub(crate) message_count: u64,
}

/// The ROS distribution a bag says it was written under, as rosbag2 reads it: the
/// environment's `ROS_DISTRO` (a plain name), else jazzy, the one our interfaces follow.
pub(crate) fn ros_distro() -> String {
    std::env::var("ROS_DISTRO")
        .ok()
        .filter(|d| !d.is_empty() && d.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'))
        .unwrap_or_else(|| "jazzy".to_owned())
}
