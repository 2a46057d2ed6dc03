//! Reading bags (ours, `ros2 bag record -s mcap` ones, and files cut short by a crash).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use causal_arm_msgs::RosMessage;
use enumset::enum_set;

use crate::BagError;

/// One topic of a bag.
#[derive(Debug, Clone, PartialEq)]
pub struct TopicInfo {
    /// Topic name.
    pub name: String,
    /// ROS type, e.g. `sensor_msgs/msg/JointState`.
    pub ros_type: String,
    /// Messages on it.
    pub message_count: u64,
    /// Offered QoS as stored by the writer (YAML), if any.
    pub offered_qos: String,
}

/// One message as stored.
#[derive(Debug, Clone, PartialEq)]
pub struct RawMessage {
    /// Topic name.
    pub topic: String,
    /// ROS type.
    pub ros_type: String,
    /// Log time, ns.
    pub log_time_ns: u64,
    /// Publish time, ns.
    pub publish_time_ns: u64,
    /// Per-channel sequence number.
    pub sequence: u32,
    /// CDR bytes with encapsulation header.
    pub data: Vec<u8>,
}

/// The file's bytes: memory-mapped, so paper-size bags (~1 GB) are not copied into RAM.
enum Bytes {
    Mapped(memmap2::Mmap),
    Empty,
}

impl std::ops::Deref for Bytes {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        match self {
            Bytes::Mapped(m) => m,
            Bytes::Empty => &[],
        }
    }
}

/// A bag opened for reading (the MCAP file is memory-mapped; do not modify it while open).
pub struct BagReader {
    mcap_path: PathBuf,
    bytes: Bytes,
    topics: Vec<TopicInfo>,
    truncation: Option<String>,
    message_count: u64,
}

fn find_mcap(path: &Path) -> Result<PathBuf, BagError> {
    if path.is_file() {
        return Ok(path.to_owned());
    }
    let entries = std::fs::read_dir(path).map_err(|error| BagError::Io {
        path: path.to_owned(),
        action: "opening the bag",
        error,
    })?;
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "mcap"))
        .collect();
    files.sort();
    match files.len() {
        1 => Ok(files.remove(0)),
        0 => Err(BagError::Metadata {
            path: path.to_owned(),
            problem: "no .mcap file in the bag directory".into(),
        }),
        n => Err(BagError::Metadata {
            path: path.to_owned(),
            problem: format!("{n} .mcap files; split bags are not supported yet"),
        }),
    }
}

impl BagReader {
    /// Opens a bag directory or a bare `.mcap` file. A file without summary (the writer
    /// was killed) is read up to its last complete record; see [`BagReader::truncation`].
    pub fn open(path: &Path) -> Result<Self, BagError> {
        let mcap_path = find_mcap(path)?;
        let io = |action: &'static str| {
            let path = mcap_path.clone();
            move |error| BagError::Io {
                path,
                action,
                error,
            }
        };
        let file = std::fs::File::open(&mcap_path).map_err(io("opening"))?;
        let len = file.metadata().map_err(io("reading metadata of"))?.len();
        let bytes = if len == 0 {
            Bytes::Empty
        } else {
            // SAFETY: the map is read-only; bags are written once and not modified while
            // read (a writer still appending only adds bytes past the mapped length).
            Bytes::Mapped(unsafe { memmap2::Mmap::map(&file) }.map_err(io("mapping"))?)
        };
        let mut reader = Self {
            mcap_path,
            bytes,
            topics: Vec::new(),
            truncation: None,
            message_count: 0,
        };
        reader.scan()?;
        Ok(reader)
    }

    fn stream(&self) -> Result<mcap::MessageStream<'_>, BagError> {
        mcap::MessageStream::new_with_options(
            &self.bytes,
            enum_set!(mcap::read::Options::IgnoreEndMagic),
        )
        .map_err(|e| BagError::Mcap {
            path: self.mcap_path.clone(),
            message: e.to_string(),
        })
    }

    fn scan(&mut self) -> Result<(), BagError> {
        let mut topics: BTreeMap<String, TopicInfo> = BTreeMap::new();
        let mut count = 0;
        let mut truncation = None;
        for item in self.stream()? {
            match item {
                Ok(m) => {
                    count += 1;
                    let entry =
                        topics
                            .entry(m.channel.topic.clone())
                            .or_insert_with(|| TopicInfo {
                                name: m.channel.topic.clone(),
                                ros_type: m
                                    .channel
                                    .schema
                                    .as_ref()
                                    .map(|s| s.name.clone())
                                    .unwrap_or_default(),
                                message_count: 0,
                                offered_qos: m
                                    .channel
                                    .metadata
                                    .get("offered_qos_profiles")
                                    .cloned()
                                    .unwrap_or_default(),
                            });
                    entry.message_count += 1;
                }
                Err(e) => {
                    truncation = Some(format!("stopped after {count} messages: {e}"));
                    break;
                }
            }
        }
        if truncation.is_none() && mcap::read::footer(&self.bytes).is_err() {
            truncation = Some(format!(
                "no footer (writer did not finish); read {count} messages"
            ));
        }
        if let Some(t) = &truncation {
            tracing::warn!("{}: incomplete bag, {t}", self.mcap_path.display());
        }
        self.topics = topics.into_values().collect();
        self.truncation = truncation;
        self.message_count = count;
        Ok(())
    }

    /// The MCAP file read.
    pub fn path(&self) -> &Path {
        &self.mcap_path
    }

    /// Topics with their types and counts.
    pub fn topics(&self) -> Vec<TopicInfo> {
        self.topics.clone()
    }

    /// Total messages readable.
    pub fn message_count(&self) -> u64 {
        self.message_count
    }

    /// Why the file ended early, if it did (a crashed writer); `None` for a finished bag.
    pub fn truncation(&self) -> Option<&str> {
        self.truncation.as_deref()
    }

    /// Every readable message in file order (= log-time order for our bags).
    pub fn messages(&self) -> impl Iterator<Item = Result<RawMessage, BagError>> + '_ {
        let limit = self.message_count;
        let stream = self.stream();
        let (ok, err) = match stream {
            Ok(s) => (Some(s), None),
            Err(e) => (None, Some(e)),
        };
        err.map(Err)
            .into_iter()
            .chain(ok.into_iter().flatten().take(limit as usize).map(|item| {
                item.map(|m| RawMessage {
                    topic: m.channel.topic.clone(),
                    ros_type: m
                        .channel
                        .schema
                        .as_ref()
                        .map(|s| s.name.clone())
                        .unwrap_or_default(),
                    log_time_ns: m.log_time,
                    publish_time_ns: m.publish_time,
                    sequence: m.sequence,
                    data: m.data.into_owned(),
                })
                .map_err(|e| BagError::Mcap {
                    path: self.mcap_path.clone(),
                    message: e.to_string(),
                })
            }))
    }

    /// What the writer said produced the bag ([`crate::BagOptions::custom_data`]): read
    /// from the metadata record at the start of the file, so crashed bags have it too.
    /// Empty for bags written by other tools.
    pub fn custom_data(&self) -> BTreeMap<String, String> {
        let Ok(records) = mcap::read::LinearReader::new_with_options(
            &self.bytes,
            enum_set!(mcap::read::Options::IgnoreEndMagic),
        ) else {
            return BTreeMap::new();
        };
        for record in records {
            match record {
                Ok(mcap::records::Record::Metadata(m)) if m.name == crate::BAG_METADATA_NAME => {
                    return m.metadata;
                }
                // Our writer puts the record before any data; stop at the first chunk.
                Ok(mcap::records::Record::Chunk { .. } | mcap::records::Record::Message { .. })
                | Err(_) => break,
                Ok(_) => {}
            }
        }
        BTreeMap::new()
    }

    /// Decodes `raw` as `M`, checking the stored type.
    pub fn decode<M: RosMessage>(&self, raw: &RawMessage) -> Result<M, BagError> {
        if raw.ros_type != M::ROS_TYPE {
            return Err(BagError::Decode {
                path: self.mcap_path.clone(),
                topic: raw.topic.clone(),
                log_time_ns: raw.log_time_ns,
                problem: format!("stored as {}, expected {}", raw.ros_type, M::ROS_TYPE),
            });
        }
        causal_arm_msgs::from_cdr(&raw.data).map_err(|e| BagError::Decode {
            path: self.mcap_path.clone(),
            topic: raw.topic.clone(),
            log_time_ns: raw.log_time_ns,
            problem: e.to_string(),
        })
    }
}
