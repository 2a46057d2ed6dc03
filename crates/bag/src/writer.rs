//! Writing bags.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Write as _};
use std::path::{Path, PathBuf};

use causal_arm_msgs::RosMessage;

use crate::BagError;
use crate::files::SplitLimits;
use crate::metadata::{
    BagfileInformation, FileInformation, Nanoseconds, NanosecondsSinceEpoch, TopicMetadata,
    TopicWithCount,
};

/// Chunk compression.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Compression {
    /// zstd (rosbag2's default for MCAP).
    #[default]
    Zstd,
    /// lz4.
    Lz4,
    /// Uncompressed chunks.
    None,
}

causal_arm_protocol::choice!(Compression, "chunk compression", [Compression::Zstd => "zstd", Compression::Lz4 => "lz4", Compression::None => "none"]);

/// Writer settings.
#[derive(Debug, Clone)]
pub struct BagOptions {
    /// Chunk compression.
    pub compression: Compression,
    /// Target chunk size, bytes (rosbag2's MCAP default).
    pub chunk_size: u64,
    /// Replace an existing bag in the directory.
    pub overwrite: bool,
    /// What produced the bag (experiment, seed, plan): stored in `metadata.yaml`'s
    /// `custom_data` and as an MCAP metadata record named [`BAG_METADATA_NAME`] at the
    /// start of the file, so even a bag cut short by a crash says what it holds.
    pub custom_data: BTreeMap<String, String>,
    /// When to start the bag's next file (never, by default).
    pub split: SplitLimits,
}

/// Name of the MCAP metadata record carrying [`BagOptions::custom_data`].
pub const BAG_METADATA_NAME: &str = "causal_arm";

impl Default for BagOptions {
    fn default() -> Self {
        Self {
            compression: Compression::Zstd,
            chunk_size: 786_432,
            overwrite: false,
            custom_data: BTreeMap::new(),
            split: SplitLimits::default(),
        }
    }
}

/// The QoS a publisher offered, as rosbag2 (format 9) stores it per topic: a YAML list.
pub fn offered_qos_yaml(
    reliable: bool,
    transient_local: bool,
    keep_all: bool,
    depth: u32,
) -> String {
    // rmw enum values: history 1 keep_last / 2 keep_all; written by name in format 9.
    format!(
        "- history: {}\n  depth: {}\n  reliability: {}\n  durability: {}\n  deadline:\n    sec: 9223372036\n    nsec: 854775807\n  lifespan:\n    sec: 9223372036\n    nsec: 854775807\n  liveliness: automatic\n  liveliness_lease_duration:\n    sec: 9223372036\n    nsec: 854775807\n  avoid_ros_namespace_conventions: false",
        if keep_all { "keep_all" } else { "keep_last" },
        depth,
        if reliable { "reliable" } else { "best_effort" },
        if transient_local {
            "transient_local"
        } else {
            "volatile"
        },
    )
}

struct TopicEntry {
    channel_id: u16,
    ros_type: &'static str,
    definition: &'static str,
    type_hash: &'static str,
    qos_yaml: String,
    count: u64,
    sequence: u32,
}

/// What a finished bag holds.
#[derive(Debug, Clone)]
pub struct BagSummary {
    /// Bag directory.
    pub dir: PathBuf,
    /// The (first) MCAP file.
    pub mcap_path: PathBuf,
    /// Every MCAP file, in order (one unless the bag was split).
    pub files: Vec<PathBuf>,
    /// Messages written.
    pub message_count: u64,
    /// Messages per topic.
    pub per_topic: BTreeMap<String, u64>,
    /// Last minus first log time, ns.
    pub duration_ns: u64,
}

/// Writes one bag; finish it with [`BagWriter::finish`] (dropping it finishes it too).
pub struct BagWriter {
    dir: PathBuf,
    /// The open MCAP file.
    mcap_path: PathBuf,
    compression: Option<mcap::Compression>,
    split: SplitLimits,
    /// What each file holds, the open one last.
    files: Vec<FileStats>,
    /// Bytes of the open file handed to the OS (kept only when splitting by size).
    file_bytes: u64,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    topics: BTreeMap<String, TopicEntry>,
    custom_data: BTreeMap<String, String>,
    /// Target uncompressed bytes per chunk; the writer closes chunks itself so it can
    /// update `metadata.yaml` after each one lands.
    chunk_size: u64,
    /// Uncompressed bytes in the open chunk.
    chunk_bytes: u64,
    /// Messages written so far that lie in closed chunks (handed to the OS).
    landed: u64,
}

/// What one file of the bag holds, for `metadata.yaml`'s `files` list.
struct FileStats {
    name: String,
    first_ns: Option<u64>,
    last_ns: u64,
    count: u64,
}

impl FileStats {
    fn new(name: String) -> Self {
        Self {
            name,
            first_ns: None,
            last_ns: 0,
            count: 0,
        }
    }

    fn add(&mut self, log_time_ns: u64) {
        self.count += 1;
        self.first_ns = Some(self.first_ns.map_or(log_time_ns, |f| f.min(log_time_ns)));
        self.last_ns = self.last_ns.max(log_time_ns);
    }

    fn duration_ns(&self) -> u64 {
        self.last_ns.saturating_sub(self.first_ns.unwrap_or(0))
    }
}

/// Starts an MCAP file of profile `ros2` at `path`, with the bag's custom data first.
fn open_mcap(
    path: &Path,
    compression: Option<mcap::Compression>,
    custom_data: &BTreeMap<String, String>,
) -> Result<mcap::Writer<BufWriter<File>>, BagError> {
    let file = File::create(path).map_err(BagError::io(path, "creating"))?;
    let mut writer = mcap::WriteOptions::new()
        .profile("ros2")
        .library(concat!("causal-arm ", env!("CARGO_PKG_VERSION")))
        .compression(compression)
        .chunk_size(None)
        .create(BufWriter::with_capacity(1 << 20, file))
        .map_err(|e| mcap_error(path, e))?;
    if !custom_data.is_empty() {
        writer
            .write_metadata(&mcap::records::Metadata {
                name: BAG_METADATA_NAME.to_owned(),
                metadata: custom_data.clone(),
            })
            .map_err(|e| mcap_error(path, e))?;
    }
    Ok(writer)
}

/// The channel metadata rosbag2 stores per topic.
fn channel_metadata(qos_yaml: &str, type_hash: &str) -> BTreeMap<String, String> {
    BTreeMap::from([
        ("offered_qos_profiles".to_owned(), qos_yaml.to_owned()),
        ("topic_type_hash".to_owned(), type_hash.to_owned()),
    ])
}

/// Bytes of a message record besides its data (framing and header).
const MESSAGE_RECORD_OVERHEAD: u64 = 9 + 22;

/// An MCAP failure with its cause: the OS error ("No space left on device") is the
/// `source` of mcap's "I/O error from writing" and must reach the user.
fn mcap_error(path: &Path, e: mcap::McapError) -> BagError {
    let mut message = e.to_string();
    let mut source = std::error::Error::source(&e);
    while let Some(cause) = source {
        message = format!("{message}: {cause}");
        source = cause.source();
    }
    BagError::Mcap {
        path: path.to_owned(),
        message,
    }
}

/// Whether `dir` already holds a bag, and what shows it (so tools refuse before starting work).
pub fn existing_bag(dir: &Path) -> Option<String> {
    let entries = std::fs::read_dir(dir).ok()?;
    let names: Vec<String> = entries
        .filter_map(|e| e.ok().map(|e| e.file_name().to_string_lossy().into_owned()))
        .filter(|n| n == "metadata.yaml" || n.ends_with(".mcap"))
        .collect();
    (!names.is_empty()).then(|| names.join(", "))
}

impl BagWriter {
    /// Creates `dir` (or reuses an empty one) and starts `<dir name>_0.mcap` in it (then
    /// `<dir name>_1.mcap` … as [`BagOptions::split`] asks).
    pub fn create(dir: &Path, options: BagOptions) -> Result<Self, BagError> {
        if let Some(found) = existing_bag(dir) {
            if !options.overwrite {
                return Err(BagError::Exists {
                    dir: dir.to_owned(),
                    found,
                });
            }
            for entry in std::fs::read_dir(dir)
                .map_err(BagError::io(dir, "listing"))?
                .flatten()
            {
                let name = entry.file_name().to_string_lossy().into_owned();
                if name == "metadata.yaml" || name.ends_with(".mcap") {
                    std::fs::remove_file(entry.path())
                        .map_err(BagError::io(&entry.path(), "removing old bag file"))?;
                }
            }
        }
        std::fs::create_dir_all(dir).map_err(BagError::io(dir, "creating the bag directory"))?;
        let name = crate::files::split_file_name(dir, 0);
        let mcap_path = dir.join(&name);
        let compression = match options.compression {
            Compression::Zstd => Some(mcap::Compression::Zstd),
            Compression::Lz4 => Some(mcap::Compression::Lz4),
            Compression::None => None,
        };
        let writer = open_mcap(&mcap_path, compression, &options.custom_data)?;
        let bag = Self {
            dir: dir.to_owned(),
            mcap_path,
            compression,
            split: options.split,
            files: vec![FileStats::new(name)],
            file_bytes: 0,
            custom_data: options.custom_data,
            writer: Some(writer),
            topics: BTreeMap::new(),
            chunk_size: options.chunk_size.max(1),
            chunk_bytes: 0,
            landed: 0,
        };
        // As rosbag2 does: the index exists from the start, so a killed run's bag opens.
        bag.write_metadata(&bag.summary())?;
        Ok(bag)
    }

    fn mcap_err(&self, e: mcap::McapError) -> BagError {
        mcap_error(&self.mcap_path, e)
    }

    /// Registers `topic` with type `M` and the publisher's offered QoS (see [`offered_qos_yaml`]).
    pub fn add_topic<M: RosMessage>(
        &mut self,
        topic: &str,
        offered_qos_yaml: &str,
    ) -> Result<(), BagError> {
        if let Some(existing) = self.topics.get(topic) {
            if existing.ros_type == M::ROS_TYPE {
                return Ok(());
            }
            return Err(BagError::Topic {
                path: self.mcap_path.clone(),
                topic: topic.to_owned(),
                problem: format!(
                    "registered as {}, now as {}",
                    existing.ros_type,
                    M::ROS_TYPE
                ),
            });
        }
        let writer = self.writer.as_mut().expect("writer lives until finish");
        let schema = writer
            .add_schema(M::ROS_TYPE, "ros2msg", M::definition().as_bytes())
            .map_err(|e| mcap_error(&self.mcap_path, e))?;
        let metadata = channel_metadata(offered_qos_yaml, M::TYPE_HASH);
        let channel_id = writer
            .add_channel(schema, topic, "cdr", &metadata)
            .map_err(|e| mcap_error(&self.mcap_path, e))?;
        self.topics.insert(
            topic.to_owned(),
            TopicEntry {
                channel_id,
                ros_type: M::ROS_TYPE,
                definition: M::definition(),
                type_hash: M::TYPE_HASH,
                qos_yaml: offered_qos_yaml.to_owned(),
                count: 0,
                sequence: 0,
            },
        );
        Ok(())
    }

    /// Writes `msg` on `topic` at `stamp_ns` (log and publish time).
    pub fn write<M: RosMessage>(
        &mut self,
        topic: &str,
        stamp_ns: u64,
        msg: &M,
    ) -> Result<(), BagError> {
        if let Some(t) = self.topics.get(topic)
            && t.ros_type != M::ROS_TYPE
        {
            return Err(BagError::Topic {
                path: self.mcap_path.clone(),
                topic: topic.to_owned(),
                problem: format!("is {}, not {}", t.ros_type, M::ROS_TYPE),
            });
        }
        let data = causal_arm_msgs::to_cdr(msg).map_err(|e| BagError::Topic {
            path: self.mcap_path.clone(),
            topic: topic.to_owned(),
            problem: e.to_string(),
        })?;
        self.write_cdr(topic, stamp_ns, stamp_ns, &data)
    }

    /// Writes an already serialized message on a registered topic.
    pub fn write_cdr(
        &mut self,
        topic: &str,
        log_time_ns: u64,
        publish_time_ns: u64,
        cdr: &[u8],
    ) -> Result<(), BagError> {
        if !self.topics.contains_key(topic) {
            return Err(BagError::Topic {
                path: self.mcap_path.clone(),
                topic: topic.to_owned(),
                problem: "written before add_topic".to_owned(),
            });
        }
        if self.file_is_full(log_time_ns) {
            self.start_next_file()?;
        }
        let entry = self.topics.get_mut(topic).expect("checked above");
        let header = mcap::records::MessageHeader {
            channel_id: entry.channel_id,
            sequence: entry.sequence,
            log_time: log_time_ns,
            publish_time: publish_time_ns,
        };
        entry.sequence = entry.sequence.wrapping_add(1);
        entry.count += 1;
        self.open_file().add(log_time_ns);
        let result = self
            .writer
            .as_mut()
            .expect("writer lives until finish")
            .write_to_known_channel(&header, cdr);
        result.map_err(|e| self.mcap_err(e))?;
        self.chunk_bytes += cdr.len() as u64 + MESSAGE_RECORD_OVERHEAD;
        if self.chunk_bytes >= self.chunk_size {
            self.close_chunk()?;
        }
        Ok(())
    }

    /// Ends the open chunk (if it holds anything) now rather than at its size: what a
    /// recorder does before it acknowledges steps, so a kill cannot lose them.
    pub fn land(&mut self) -> Result<(), BagError> {
        match self.landed < self.total_messages() {
            true => self.close_chunk(),
            false => Ok(()),
        }
    }

    /// Messages written that lie in closed chunks: a SIGKILL from now on cannot lose
    /// them (the OS has them; the reader reads a crash tail up to its last whole chunk).
    pub fn landed_messages(&self) -> u64 {
        self.landed
    }

    fn total_messages(&self) -> u64 {
        self.topics.values().map(|t| t.count).sum()
    }

    /// Ends the open chunk, hands it to the OS, and brings `metadata.yaml` up to it: the
    /// index never counts a message the file does not hold, even after a SIGKILL.
    fn close_chunk(&mut self) -> Result<(), BagError> {
        self.chunk_bytes = 0;
        self.landed = self.total_messages();
        let result = self
            .writer
            .as_mut()
            .expect("writer lives until finish")
            .flush();
        result.map_err(|e| self.mcap_err(e))?;
        if self.split.max_bytes.is_some() {
            let len = std::fs::metadata(&self.mcap_path)
                .map_err(BagError::io(&self.mcap_path, "reading the size of"))?
                .len();
            self.file_bytes = len;
        }
        self.write_metadata(&self.summary())
    }

    /// Log time of the bag's first message, if any.
    fn first_ns(&self) -> Option<u64> {
        self.files.iter().filter_map(|f| f.first_ns).min()
    }

    /// Log time of the bag's last message (0 if none).
    fn last_ns(&self) -> u64 {
        self.files.iter().map(|f| f.last_ns).max().unwrap_or(0)
    }

    fn open_file(&mut self) -> &mut FileStats {
        self.files
            .last_mut()
            .expect("a bag has a file from the start")
    }

    /// Whether the next message, logged at `log_time_ns`, belongs in a new file, as
    /// rosbag2 decides it: the open file holds something and has reached the size
    /// limit, or the message lies past the duration limit from the file's first.
    fn file_is_full(&self, log_time_ns: u64) -> bool {
        let file = &self.files[self.files.len() - 1];
        let Some(first) = file.first_ns else {
            return false;
        };
        let too_big = self.split.max_bytes.is_some_and(|m| self.file_bytes >= m);
        let too_long = self
            .split
            .max_duration_ns
            .is_some_and(|d| log_time_ns.saturating_sub(first) > d);
        too_big || too_long
    }

    /// Finishes the open file (summary, footer, synced: it opens on its own from now on)
    /// and starts the next, with the same schemas and channels under the same ids.
    fn start_next_file(&mut self) -> Result<(), BagError> {
        self.finish_open_file()?;
        self.landed = self.total_messages();
        let name = crate::files::split_file_name(&self.dir, self.files.len());
        self.mcap_path = self.dir.join(&name);
        let mut writer = open_mcap(&self.mcap_path, self.compression, &self.custom_data)?;
        let mut entries: Vec<_> = self.topics.iter_mut().collect();
        entries.sort_by_key(|(_, e)| e.channel_id);
        for (topic, entry) in entries {
            let path = &self.mcap_path;
            let schema = writer
                .add_schema(entry.ros_type, "ros2msg", entry.definition.as_bytes())
                .map_err(|e| mcap_error(path, e))?;
            let metadata = channel_metadata(&entry.qos_yaml, entry.type_hash);
            entry.channel_id = writer
                .add_channel(schema, topic, "cdr", &metadata)
                .map_err(|e| mcap_error(path, e))?;
        }
        self.writer = Some(writer);
        self.files.push(FileStats::new(name));
        (self.file_bytes, self.chunk_bytes) = (0, 0);
        self.write_metadata(&self.summary())
    }

    /// Finishes the open MCAP file and hands it to the disk.
    fn finish_open_file(&mut self) -> Result<(), BagError> {
        let Some(mut writer) = self.writer.take() else {
            return Err(BagError::Metadata {
                path: self.dir.clone(),
                problem: "bag already finished".to_owned(),
            });
        };
        writer.finish().map_err(|e| self.mcap_err(e))?;
        let mut inner = writer.into_inner();
        inner
            .flush()
            .map_err(BagError::io(&self.mcap_path, "flushing"))?;
        inner
            .get_ref()
            .sync_all()
            .map_err(BagError::io(&self.mcap_path, "syncing"))
    }

    /// What the bag holds so far.
    fn summary(&self) -> BagSummary {
        BagSummary {
            dir: self.dir.clone(),
            mcap_path: self.dir.join(&self.files[0].name),
            files: self.files.iter().map(|f| self.dir.join(&f.name)).collect(),
            message_count: self.total_messages(),
            per_topic: self
                .topics
                .iter()
                .map(|(k, t)| (k.clone(), t.count))
                .collect(),
            duration_ns: self.last_ns().saturating_sub(self.first_ns().unwrap_or(0)),
        }
    }

    /// Messages written on `topic` so far.
    pub fn message_count(&self, topic: &str) -> u64 {
        self.topics.get(topic).map_or(0, |t| t.count)
    }

    /// Finalizes the MCAP file (summary, indexes) and writes `metadata.yaml`.
    pub fn finish(mut self) -> Result<BagSummary, BagError> {
        self.finish_in_place()
    }

    fn finish_in_place(&mut self) -> Result<BagSummary, BagError> {
        self.finish_open_file()?;
        let summary = self.summary();
        self.write_metadata(&summary)?;
        Ok(summary)
    }

    fn write_metadata(&self, summary: &BagSummary) -> Result<(), BagError> {
        let start = self.first_ns().unwrap_or(0);
        let topics = self
            .topics
            .iter()
            .map(|(name, t)| {
                let qos: serde_norway::Value = serde_norway::from_str(&t.qos_yaml)
                    .unwrap_or(serde_norway::Value::Sequence(vec![]));
                TopicWithCount {
                    topic_metadata: TopicMetadata {
                        name: name.clone(),
                        r#type: t.ros_type.to_owned(),
                        serialization_format: "cdr".to_owned(),
                        offered_qos_profiles: qos,
                        type_description_hash: t.type_hash.to_owned(),
                    },
                    message_count: t.count,
                }
            })
            .collect();
        let info = BagfileInformation {
            version: 9,
            storage_identifier: "mcap".to_owned(),
            duration: Nanoseconds {
                nanoseconds: summary.duration_ns,
            },
            starting_time: NanosecondsSinceEpoch {
                nanoseconds_since_epoch: start,
            },
            message_count: summary.message_count,
            topics_with_message_count: topics,
            compression_format: String::new(),
            compression_mode: String::new(),
            relative_file_paths: self.files.iter().map(|f| f.name.clone()).collect(),
            files: self
                .files
                .iter()
                .map(|f| FileInformation {
                    path: f.name.clone(),
                    starting_time: NanosecondsSinceEpoch {
                        nanoseconds_since_epoch: f.first_ns.unwrap_or(start),
                    },
                    duration: Nanoseconds {
                        nanoseconds: f.duration_ns(),
                    },
                    message_count: f.count,
                })
                .collect(),
            custom_data: self.custom_data.clone(),
            ros_distro: crate::metadata::ros_distro(),
        };
        crate::metadata::write(&self.dir, info)
    }
}

impl Drop for BagWriter {
    fn drop(&mut self) {
        if self.writer.is_some()
            && let Err(e) = self.finish_in_place()
        {
            tracing::error!("finalizing {} on drop failed: {e}", self.dir.display());
        }
    }
}
