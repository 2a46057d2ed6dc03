//! rosbag2-compatible MCAP bags: the recorder's writer, the reader the trainer and the
//! player use, and the player.
//!
//! A bag is a directory `NAME/` holding `NAME_0.mcap` (profile `ros2`, schemas in
//! `ros2msg` encoding with full dependent definitions, CDR messages, zstd-compressed
//! chunks, message and chunk indexes, summary) and `metadata.yaml` (rosbag2 format 9), as
//! `ros2 bag record -s mcap` writes them, so `ros2 bag`, rosbags and mcap tools read it.
//!
//! Crash safety: chunks are self-contained, so a writer killed mid-run leaves a file whose
//! complete chunks [`BagReader`] (and `mcap recover`) still read; `metadata.yaml` is
//! written atomically at the end and the reader does not need it.

mod reader;
mod writer;

pub use reader::{BagReader, RawMessage, TopicInfo};
pub use writer::{
    BAG_METADATA_NAME, BagOptions, BagSummary, BagWriter, Compression, existing_bag,
    offered_qos_yaml,
};

use std::path::PathBuf;

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
    /// `metadata.yaml` is missing pieces or malformed.
    #[error("{path}: {problem}")]
    Metadata {
        /// File involved.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}
