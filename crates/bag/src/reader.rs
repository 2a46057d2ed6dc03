//! Reading bags (ours, `ros2 bag record -s mcap` ones, and files cut short by a crash).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use causal_arm_msgs::RosMessage;

use crate::BagError;
use crate::check::{self, Damage, Scan, Span};

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

/// How a reader treats damage (not a crash tail, which is always read up to its last
/// complete chunk with a warning).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ReadPolicy {
    /// Any damage is an error naming the file and the place: data is never silently less.
    #[default]
    Strict,
    /// Damaged chunks are skipped with a warning and everything intact is read (`--salvage`).
    Salvage,
}

static SALVAGE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

impl ReadPolicy {
    /// Makes [`BagReader::open`] use `self` in this process: set once from the command
    /// line (`--salvage`), so every library that opens bags follows the user's choice.
    pub fn set_process_default(self) {
        SALVAGE.store(self == Self::Salvage, std::sync::atomic::Ordering::Relaxed);
    }

    /// The policy set by [`ReadPolicy::set_process_default`] (strict unless changed).
    pub fn process_default() -> Self {
        if SALVAGE.load(std::sync::atomic::Ordering::Relaxed) {
            Self::Salvage
        } else {
            Self::Strict
        }
    }
}

/// A bag opened for reading (the MCAP file is memory-mapped; do not modify it while open).
pub struct BagReader {
    mcap_path: PathBuf,
    bytes: Bytes,
    scan: Scan,
    topics: Vec<TopicInfo>,
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
    let file = match files.len() {
        1 => files.remove(0),
        0 => {
            return Err(BagError::Metadata {
                path: path.to_owned(),
                problem: "no .mcap file in the bag directory".into(),
            });
        }
        n => {
            return Err(BagError::Metadata {
                path: path.to_owned(),
                problem: format!("{n} .mcap files; split bags are not supported yet"),
            });
        }
    };
    if !file.is_file() {
        return Err(BagError::Metadata {
            path: file,
            problem: "is not a regular file".into(),
        });
    }
    Ok(file)
}

impl BagReader {
    /// Opens a bag directory or a bare `.mcap` file with the process's [`ReadPolicy`].
    /// A file cut short by a crash is read up to its last complete chunk (see
    /// [`BagReader::truncation`]); damage anywhere else is an error unless salvaging.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        Self::open_with(path, ReadPolicy::process_default())
    }

    /// [`BagReader::open`] with an explicit policy.
    pub fn open_with(path: &Path, policy: ReadPolicy) -> Result<Self, BagError> {
        let reader = Self::open_unchecked(path)?;
        reader.judge(path, policy)?;
        Ok(reader)
    }

    /// Judges a file opened by [`BagReader::open_unchecked`] from `path` as
    /// [`BagReader::open_with`] does: `metadata.yaml` (for a bag directory) and the file's
    /// damage are errors under [`ReadPolicy::Strict`] and warnings when salvaging; a crash
    /// tail is a warning; a file with no readable message is an error.
    pub fn judge(&self, path: &Path, policy: ReadPolicy) -> Result<(), BagError> {
        if path.is_dir()
            && let Err(e) = crate::metadata::check(path, self)
        {
            if policy == ReadPolicy::Strict {
                return Err(e);
            }
            tracing::warn!("salvaging past: {e}");
        }
        let damage = &self.scan.damage;
        if let Some(first) = damage.first() {
            if policy == ReadPolicy::Strict {
                return Err(BagError::Damaged {
                    path: self.mcap_path.clone(),
                    damage: first.clone(),
                    more: damage.len() - 1,
                });
            }
            for d in damage {
                tracing::warn!("{}: salvaging past damage at {d}", self.mcap_path.display());
            }
        }
        if let Some(t) = self.truncation() {
            tracing::warn!(
                "{}: incomplete bag ({t}); reading its {} complete messages",
                self.mcap_path.display(),
                self.message_count()
            );
        }
        if self.message_count() == 0 && !self.scan.finished {
            return Err(BagError::Metadata {
                path: self.mcap_path.clone(),
                problem: format!(
                    "no readable messages ({})",
                    self.truncation().unwrap_or("the file is damaged")
                ),
            });
        }
        Ok(())
    }

    /// Maps and scans the file without judging it: what `bag check` and `bag recover`
    /// build their reports from.
    pub fn open_unchecked(path: &Path) -> Result<Self, BagError> {
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
        let scan = check::scan(&bytes);
        let topics = topics_of(&scan);
        Ok(Self {
            mcap_path,
            bytes,
            scan,
            topics,
        })
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
        self.scan.message_count
    }

    /// Why the file ended early, if it did (a crashed writer); `None` for a finished bag.
    pub fn truncation(&self) -> Option<&str> {
        self.scan.tail.as_deref()
    }

    /// Everything damaged in the MCAP file, in file order (empty for a sound file).
    pub fn damage(&self) -> &[Damage] {
        &self.scan.damage
    }

    /// Whether the file has its footer and summary (the writer finished it).
    pub fn finished(&self) -> bool {
        self.scan.finished
    }

    /// Chunks in the file, readable or not.
    pub fn chunk_count(&self) -> usize {
        self.scan.chunk_count
    }

    /// Messages known (from message indexes) to sit in damaged chunks.
    pub fn lost_known(&self) -> u64 {
        self.scan.lost_known
    }

    /// Every readable message in file order (= log-time order for our bags).
    pub fn messages(&self) -> impl Iterator<Item = Result<RawMessage, BagError>> + '_ {
        self.scan
            .spans
            .iter()
            .flat_map(move |span| match self.span_messages(span) {
                Ok(messages) => messages.into_iter().map(Ok).collect::<Vec<_>>(),
                Err(e) => vec![Err(e)],
            })
    }

    fn span_messages(&self, span: &Span) -> Result<Vec<RawMessage>, BagError> {
        let start = (span.offset + 9) as usize;
        let body = &self.bytes[start..start + span.len as usize];
        let damaged = |problem: String| BagError::Damaged {
            path: self.mcap_path.clone(),
            damage: Damage {
                offset: span.offset,
                chunk: None,
                problem: format!("{problem} (the file changed while open?)"),
            },
            more: 0,
        };
        if !span.chunk {
            return self.message(body).map(|m| vec![m]).map_err(damaged);
        }
        let (_, records) = check::open_chunk(body).map_err(damaged)?;
        let mut out = Vec::new();
        for item in check::Records::new(&records, 0) {
            let (_, opcode, body) = item.map_err(|(_, p)| damaged(p))?;
            if opcode == mcap::records::op::MESSAGE {
                out.push(self.message(body).map_err(damaged)?);
            }
        }
        Ok(out)
    }

    fn message(&self, body: &[u8]) -> Result<RawMessage, String> {
        let Ok(mcap::records::Record::Message { header, data }) =
            crate::bounds::parse_record(mcap::records::op::MESSAGE, body)
        else {
            return Err("message record unreadable".into());
        };
        let channel = self
            .scan
            .channels
            .get(&header.channel_id)
            .ok_or_else(|| format!("message on undefined channel {}", header.channel_id))?;
        Ok(RawMessage {
            topic: channel.topic.clone(),
            ros_type: channel.ros_type.clone(),
            log_time_ns: header.log_time,
            publish_time_ns: header.publish_time,
            sequence: header.sequence,
            data: data.into_owned(),
        })
    }

    /// What the writer said produced the bag ([`crate::BagOptions::custom_data`]): read
    /// from the metadata record at the start of the file, so crashed bags have it too.
    /// Empty for bags written by other tools.
    pub fn custom_data(&self) -> BTreeMap<String, String> {
        self.scan.custom_data.clone()
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

/// Topics in name order, with counts from the scan.
fn topics_of(scan: &Scan) -> Vec<TopicInfo> {
    let mut topics: BTreeMap<String, TopicInfo> = BTreeMap::new();
    for (id, def) in &scan.channels {
        let count = scan.per_channel.get(id).copied().unwrap_or(0);
        let entry = topics
            .entry(def.topic.clone())
            .or_insert_with(|| TopicInfo {
                name: def.topic.clone(),
                ros_type: def.ros_type.clone(),
                message_count: 0,
                offered_qos: def.offered_qos.clone(),
            });
        entry.message_count += count;
    }
    topics
        .into_values()
        .filter(|t| t.message_count > 0)
        .collect()
}
