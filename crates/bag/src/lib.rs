//! rosbag2-compatible MCAP bags: the recorder's writer, the reader the trainer and the
//! player use, and the player.
//!
//! A bag is a directory `NAME/` holding `NAME_0.mcap` (profile `ros2`, schemas in
//! `ros2msg` encoding with full dependent definitions, CDR messages, zstd-compressed
//! chunks, message and chunk indexes, summary) and `metadata.yaml` (rosbag2 format 9), as
//! `ros2 bag record -s mcap` writes them, so `ros2 bag`, rosbags and mcap tools read it.
//! A long recording may be split as `ros2 bag record --max-bag-size / --max-bag-duration`
//! split it ([`SplitLimits`]): `NAME_0.mcap`, `NAME_1.mcap`, … each finished as it
//! closes, all listed in `metadata.yaml`, and read back as one bag.
//!
//! Crash safety: chunks are self-contained, so a writer killed mid-run leaves a file whose
//! complete chunks [`BagReader`] (and `mcap recover`) still read, and `metadata.yaml` is
//! written atomically when the bag opens and after every chunk, so standard readers open
//! a killed run's bag. Reading is checked (framing, sizes, CRCs, indexes, counts): damage
//! is an error naming file and byte, never read as less data ([`ReadPolicy`]).

mod bounds;
mod check;
mod files;
mod metadata;
mod reader;
mod shards;
mod writer;

pub use check::Damage;
pub use files::SplitLimits;
pub use reader::{BagFile, BagReader, RawMessage, ReadPolicy, TopicInfo};
pub use shards::{SHARD_SET_FILE, ShardSet, bags_in};
pub use writer::{
    BAG_METADATA_NAME, BagOptions, BagSummary, BagWriter, Compression, existing_bag,
    offered_qos_yaml,
};

use std::path::{Path, PathBuf};

/// Every bag failure names the bag (or file) and what was expected.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The output already holds a bag.
    #[error("{dir} already holds a bag ({found}); pass --overwrite to replace it")]
    Exists {
        /// Bag directory.
        dir: PathBuf,
        /// What was found there.
        found: String,
    },
    /// Filesystem failure.
    #[error("{path}: {action}: {error}")]
    Io {
        /// Path involved.
        path: PathBuf,
        /// What we were doing.
        action: &'static str,
        /// OS error.
        error: std::io::Error,
    },
    /// MCAP encoding or decoding failure.
    #[error("{path}: MCAP: {message}")]
    Mcap {
        /// File involved.
        path: PathBuf,
        /// What the mcap library said.
        message: String,
    },
    /// A topic was written before being registered, or registered twice with another type.
    #[error("{path}: topic {topic}: {problem}")]
    Topic {
        /// Bag involved.
        path: PathBuf,
        /// Topic.
        topic: String,
        /// What is wrong.
        problem: String,
    },
    /// A message does not decode as the expected type.
    #[error("{path}: topic {topic} at {log_time_ns} ns: {problem}")]
    Decode {
        /// Bag involved.
        path: PathBuf,
        /// Topic.
        topic: String,
        /// Log time of the message.
        log_time_ns: u64,
        /// What is wrong.
        problem: String,
    },
    /// The MCAP file is damaged (not merely cut short by a crash).
    #[error(
        "{path}: damaged at {damage}{}; `causal-arm bag check` lists the damage, `causal-arm bag recover` rebuilds the bag from what is intact, --salvage reads past it",
        if *more > 0 { format!(" (and {more} more places)") } else { String::new() }
    )]
    Damaged {
        /// File involved.
        path: PathBuf,
        /// The first damaged place.
        damage: Damage,
        /// How many more damaged places follow.
        more: usize,
    },
    /// `metadata.yaml` is missing pieces or malformed.
    #[error("{path}: {problem}")]
    Metadata {
        /// File involved.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}

impl BagError {
    /// A filesystem failure on `path` while doing `action`, for `map_err`: every I/O
    /// error of this crate names the path and what was being done.
    pub(crate) fn io(
        path: &Path,
        action: &'static str,
    ) -> impl FnOnce(std::io::Error) -> BagError + use<> {
        let path = path.to_owned();
        move |error| BagError::Io {
            path,
            action,
            error,
        }
    }
}

/// Writes `text` to `path` atomically (a hidden temporary file beside it, renamed into
/// place), so a reader never sees half an index or manifest.
pub(crate) fn write_atomically(path: &Path, text: &str) -> Result<(), BagError> {
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let tmp = path.with_file_name(format!(".{name}.tmp"));
    std::fs::write(&tmp, text).map_err(BagError::io(&tmp, "writing"))?;
    std::fs::rename(&tmp, path).map_err(BagError::io(path, "renaming into place"))
}
