//! Shard sets: one run recorded as several bags written side by side (one per core), in
//! a directory `SET/` holding `shard-0/`, `shard-1/`, … and the manifest
//! `shard_set.yaml`. Each shard is a complete rosbag2 bag that `ros2 bag`, rosbags and
//! mcap tools open on their own; readers of this crate take the set as one dataset.
//!
//! The manifest is written before any shard starts, so a set cut short by a crash is
//! still recognised, and a shard that is missing from it is an error naming the shard,
//! never read as a smaller dataset.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::BagError;
use crate::writer::existing_bag;

/// File name of a shard set's manifest.
pub const SHARD_SET_FILE: &str = "shard_set.yaml";

/// What `shard_set.yaml` holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ShardSet {
    /// Format version, for readers to refuse what they do not know.
    pub version: u32,
    /// Shard directory names relative to the set, in dataset order.
    pub shards: Vec<String>,
    /// What the writer wants recorded about the set (e.g. the run's seed).
    #[serde(default)]
    pub custom_data: BTreeMap<String, String>,
}

impl ShardSet {
    /// The version this crate writes and reads.
    pub const VERSION: u32 = 1;

    /// A set of `count` shards named `shard-0` … in order.
    pub fn numbered(count: usize, custom_data: BTreeMap<String, String>) -> Self {
        Self {
            version: Self::VERSION,
            shards: (0..count).map(|i| format!("shard-{i}")).collect(),
            custom_data,
        }
    }

    /// Writes the manifest into `dir` (created if missing) atomically. Refuses a `dir`
    /// that holds a bag or another set unless `overwrite`, which then removes that bag's
    /// files or that set's shards (nothing else in `dir` is touched).
    pub fn create(&self, dir: &Path, overwrite: bool) -> Result<(), BagError> {
        let found = existing_bag(dir).or_else(|| {
            dir.join(SHARD_SET_FILE)
                .exists()
                .then(|| SHARD_SET_FILE.to_owned())
        });
        if let Some(found) = found {
            if !overwrite {
                return Err(BagError::Exists {
                    dir: dir.to_owned(),
                    found,
                });
            }
            remove_old(dir)?;
        }
        std::fs::create_dir_all(dir).map_err(BagError::io(dir, "creating the shard set"))?;
        let text = serde_norway::to_string(self).map_err(|e| BagError::Metadata {
            path: dir.join(SHARD_SET_FILE),
            problem: e.to_string(),
        })?;
        crate::write_atomically(&dir.join(SHARD_SET_FILE), &text)
    }

    /// Reads the manifest of the set in `dir`, or `None` when `dir` is not a shard set.
    pub fn read(dir: &Path) -> Result<Option<Self>, BagError> {
        if !dir.is_dir() {
            return Ok(None); // a bare .mcap file or a missing path: the bag reader names it
        }
        let file = dir.join(SHARD_SET_FILE);
        let text = match std::fs::read_to_string(&file) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(BagError::io(&file, "reading")(e)),
        };
        let set: Self = serde_norway::from_str(&text).map_err(|e| BagError::Metadata {
            path: file.clone(),
            problem: format!("not a shard set manifest: {e}"),
        })?;
        if set.version != Self::VERSION {
            return Err(BagError::Metadata {
                path: file,
                problem: format!(
                    "shard set version {} (this build reads {})",
                    set.version,
                    Self::VERSION
                ),
            });
        }
        Ok(Some(set))
    }

    /// The shard bag directories of the set in `dir`, each checked to exist.
    pub fn bags(&self, dir: &Path) -> Result<Vec<PathBuf>, BagError> {
        self.shards
            .iter()
            .map(|name| {
                let bag = dir.join(name);
                match bag.is_dir() {
                    true => Ok(bag),
                    false => Err(BagError::Metadata {
                        path: dir.join(SHARD_SET_FILE),
                        problem: format!(
                            "the set lists shard {name} but {} is missing: the set is incomplete",
                            bag.display()
                        ),
                    }),
                }
            })
            .collect()
    }
}

/// The bags `path` stands for: the shards of a shard set, in order, or `path` itself
/// (a bag, or whatever the bag reader will then judge).
pub fn bags_in(path: &Path) -> Result<Vec<PathBuf>, BagError> {
    match ShardSet::read(path)? {
        Some(set) => set.bags(path),
        None => Ok(vec![path.to_owned()]),
    }
}

fn remove_old(dir: &Path) -> Result<(), BagError> {
    if let Some(old) = ShardSet::read(dir)? {
        for name in &old.shards {
            let shard = dir.join(name);
            if shard.is_dir() {
                std::fs::remove_dir_all(&shard)
                    .map_err(BagError::io(&shard, "removing an old shard"))?;
            }
        }
    }
    for entry in std::fs::read_dir(dir)
        .map_err(BagError::io(dir, "listing"))?
        .flatten()
    {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name == "metadata.yaml" || name.ends_with(".mcap") || name == SHARD_SET_FILE {
            std::fs::remove_file(entry.path())
                .map_err(BagError::io(&entry.path(), "removing an old bag file"))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_set_lists_its_shards_in_order_and_a_bag_stands_for_itself() {
        let dir = tempfile::tempdir().unwrap();
        let set_dir = dir.path().join("set");
        let set = ShardSet::numbered(3, BTreeMap::from([("seed".into(), "5".into())]));
        set.create(&set_dir, false).unwrap();
        for name in &set.shards {
            std::fs::create_dir(set_dir.join(name)).unwrap();
        }
        assert_eq!(ShardSet::read(&set_dir).unwrap(), Some(set));
        let bags = bags_in(&set_dir).unwrap();
        let names: Vec<_> = bags.iter().map(|b| b.file_name().unwrap()).collect();
        assert_eq!(names, ["shard-0", "shard-1", "shard-2"]);
        let plain = dir.path().join("bag");
        assert_eq!(bags_in(&plain).unwrap(), vec![plain]);
        let file = set_dir.join("shard-0").join("x.mcap");
        std::fs::write(&file, b"").unwrap();
        assert_eq!(
            bags_in(&file).unwrap(),
            vec![file],
            "a bare file is its own bag"
        );
    }

    #[test]
    fn a_missing_shard_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        ShardSet::numbered(2, BTreeMap::new())
            .create(dir.path(), false)
            .unwrap();
        std::fs::create_dir(dir.path().join("shard-0")).unwrap();
        let err = bags_in(dir.path()).unwrap_err().to_string();
        assert!(
            err.contains("shard-1") && err.contains("incomplete"),
            "{err}"
        );
    }

    #[test]
    fn an_existing_set_or_bag_is_refused_unless_overwritten() {
        let dir = tempfile::tempdir().unwrap();
        let set = ShardSet::numbered(2, BTreeMap::new());
        set.create(dir.path(), false).unwrap();
        std::fs::create_dir(dir.path().join("shard-0")).unwrap();
        std::fs::write(dir.path().join("notes.txt"), "mine").unwrap();
        let err = set.create(dir.path(), false).unwrap_err().to_string();
        assert!(err.contains("--overwrite"), "{err}");
        ShardSet::numbered(1, BTreeMap::new())
            .create(dir.path(), true)
            .unwrap();
        assert!(!dir.path().join("shard-0").exists(), "the old shards go");
        assert!(
            dir.path().join("notes.txt").exists(),
            "nothing else is touched"
        );
        std::fs::write(dir.path().join("metadata.yaml"), "x").unwrap();
        assert!(
            set.create(dir.path(), false).is_err(),
            "a bag is refused too"
        );
    }

    #[test]
    fn a_foreign_manifest_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join(SHARD_SET_FILE), "version: 9\nshards: []\n").unwrap();
        let err = bags_in(dir.path()).unwrap_err().to_string();
        assert!(err.contains("version 9"), "{err}");
        std::fs::write(dir.path().join(SHARD_SET_FILE), "[1, 2").unwrap();
        let err = bags_in(dir.path()).unwrap_err().to_string();
        assert!(err.contains("not a shard set manifest"), "{err}");
    }
}
