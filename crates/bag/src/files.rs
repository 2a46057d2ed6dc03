//! A bag's files: when a writer starts the next one, and how rosbag2 names them
//! (`<bag>_<n>.mcap`, `n` counting the splits from 0, the order a reader takes them in).

use std::path::{Path, PathBuf};

use crate::BagError;

/// When a bag starts its next file, as `ros2 bag record --max-bag-size / --max-bag-duration`
/// do: long recordings in files of bounded size, each finished as it closes, so a crash
/// costs at most the open one's unlanded tail and every closed file opens on its own.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SplitLimits {
    /// Start a new file before the next message once the open one holds this many bytes
    /// (files grow by whole chunks, so they end one chunk past it at most).
    pub max_bytes: Option<u64>,
    /// Start a new file before a message logged more than this long after the open
    /// file's first message.
    pub max_duration_ns: Option<u64>,
}

impl SplitLimits {
    /// Limits from rosbag2's command-line units (bytes, whole seconds; 0 = no limit).
    pub fn from_ros2_units(max_bag_size: u64, max_bag_duration_s: u64) -> Self {
        Self {
            max_bytes: (max_bag_size > 0).then_some(max_bag_size),
            max_duration_ns: (max_bag_duration_s > 0)
                .then(|| max_bag_duration_s.saturating_mul(1_000_000_000)),
        }
    }

    /// The limits in rosbag2's command-line units: (bytes, whole seconds), 0 = no limit.
    pub fn to_ros2_units(&self) -> (u64, u64) {
        (
            self.max_bytes.unwrap_or(0),
            self.max_duration_ns.map_or(0, |ns| ns / 1_000_000_000),
        )
    }
}

/// The name rosbag2 gives split `index` of the bag in directory `dir`.
pub(crate) fn split_file_name(dir: &Path, index: usize) -> String {
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .filter(|n| !n.is_empty() && n != "." && n != "..")
        .unwrap_or_else(|| "bag".to_owned());
    format!("{name}_{index}.mcap")
}

/// The last component of `path`, as text.
pub(crate) fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// Where a file falls among a bag's splits: by its split number (`_<n>.mcap`), then by
/// name, so `b_10.mcap` follows `b_9.mcap`.
fn split_order(path: &Path) -> (u64, String) {
    let name = file_name(path);
    let number = name
        .strip_suffix(".mcap")
        .and_then(|stem| stem.rsplit_once('_'))
        .and_then(|(_, n)| n.parse().ok())
        .unwrap_or(u64::MAX);
    (number, name)
}

/// The MCAP files of the bag at `path`, in split order: `path` itself if it is a file,
/// else every `.mcap` file of the directory (`metadata.yaml` is checked against them by
/// the reader's judgement, not trusted to find them).
pub(crate) fn bag_files(path: &Path) -> Result<Vec<PathBuf>, BagError> {
    if path.is_file() {
        return Ok(vec![path.to_owned()]);
    }
    let entries = std::fs::read_dir(path).map_err(BagError::io(path, "opening the bag"))?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    if files.is_empty() {
        return Err(BagError::Metadata {
            path: path.to_owned(),
            problem: "no .mcap file in the bag directory".into(),
        });
    }
    files.sort_by_key(|p| split_order(p));
    if let Some(odd) = files.iter().find(|f| !f.is_file()) {
        return Err(BagError::Metadata {
            path: odd.clone(),
            problem: "is not a regular file".into(),
        });
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_are_taken_by_number_not_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let bag = dir.path().join("run");
        std::fs::create_dir(&bag).unwrap();
        for i in [10, 2, 0, 1] {
            std::fs::write(bag.join(split_file_name(&bag, i)), b"").unwrap();
        }
        let names: Vec<String> = bag_files(&bag)
            .unwrap()
            .iter()
            .map(|p| file_name(p))
            .collect();
        assert_eq!(
            names,
            ["run_0.mcap", "run_1.mcap", "run_2.mcap", "run_10.mcap"]
        );
    }
}
