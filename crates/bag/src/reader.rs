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

/// One MCAP file of a bag: a bag split by size or duration has several, read in order.
struct Part {
    mcap_path: PathBuf,
    bytes: Bytes,
    scan: Scan,
}

impl Part {
    fn open(mcap_path: PathBuf) -> Result<Self, BagError> {
        let io = |action| BagError::io(&mcap_path, action);
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
        Ok(Self {
            mcap_path,
            bytes,
            scan,
        })
    }

    fn file_name(&self) -> String {
        crate::files::file_name(&self.mcap_path)
    }
}

/// One file of a bag as read: what `bag info` and `bag check` list per split.
#[derive(Debug, Clone, PartialEq)]
pub struct BagFile {
    /// The MCAP file.
    pub path: PathBuf,
    /// Messages readable in it.
    pub message_count: u64,
    /// Whether its writer finished it (footer and summary).
    pub finished: bool,
    /// Why it ends early, if it does.
    pub truncation: Option<String>,
}

/// A bag opened for reading: its MCAP files (one, or the splits of a split bag) read as
/// one, in order. The files are memory-mapped; do not modify them while open.
pub struct BagReader {
    parts: Vec<Part>,
    topics: Vec<TopicInfo>,
    /// Damage of every file, named by file for a split bag; a split other than the last
    /// that ends early counts as damage (a closed split is finished before the next opens).
    damage: Vec<Damage>,
}

impl BagReader {
    /// Opens a bag directory (one MCAP file or a split bag's several) or a bare `.mcap`
    /// file with the process's [`ReadPolicy`]. A file cut short by a crash is read up to
    /// its last complete chunk (see [`BagReader::truncation`]); damage anywhere else is an
    /// error unless salvaging.
    pub fn open(path: &Path) -> Result<Self, BagError> {
        Self::open_with(path, ReadPolicy::process_default())
    }

    /// [`BagReader::open`] with an explicit policy.
    pub fn open_with(path: &Path, policy: ReadPolicy) -> Result<Self, BagError> {
        let reader = Self::open_unchecked(path)?;
        reader.judge(path, policy)?;
        Ok(reader)
    }

    /// Judges a bag opened by [`BagReader::open_unchecked`] from `path` as
    /// [`BagReader::open_with`] does: `metadata.yaml` (for a bag directory) and the files'
    /// damage are errors under [`ReadPolicy::Strict`] and warnings when salvaging; a crash
    /// tail is a warning; a bag with no readable message is an error.
    pub fn judge(&self, path: &Path, policy: ReadPolicy) -> Result<(), BagError> {
        if path.is_dir()
            && let Err(e) = crate::metadata::check(path, self)
        {
            if policy == ReadPolicy::Strict {
                return Err(e);
            }
            tracing::warn!("salvaging past: {e}");
        }
        if let Some(first) = self.damage.first() {
            if policy == ReadPolicy::Strict {
                return Err(BagError::Damaged {
                    path: self.damage_path(first),
                    damage: first.clone(),
                    more: self.damage.len() - 1,
                });
            }
            for d in &self.damage {
                tracing::warn!("{}: salvaging past damage at {d}", self.path().display());
            }
        }
        if let Some(t) = self.truncation() {
            tracing::warn!(
                "{}: incomplete bag ({t}); reading its {} complete messages",
                self.last_path().display(),
                self.message_count()
            );
        }
        if self.message_count() == 0 && !self.finished() {
            return Err(BagError::Metadata {
                path: self.last_path().to_owned(),
                problem: format!(
                    "no readable messages ({})",
                    self.truncation().unwrap_or("the file is damaged")
                ),
            });
        }
        Ok(())
    }

    /// Maps and scans the bag's files without judging them: what `bag check` and `bag
    /// recover` build their reports from.
    pub fn open_unchecked(path: &Path) -> Result<Self, BagError> {
        let parts = crate::files::bag_files(path)?
            .into_iter()
            .map(Part::open)
            .collect::<Result<Vec<_>, _>>()?;
        let damage = damage_of(&parts);
        let topics = topics_of(parts.iter().map(|p| &p.scan));
        Ok(Self {
            parts,
            topics,
            damage,
        })
    }

    /// The bag's (first) MCAP file.
    pub fn path(&self) -> &Path {
        &self.parts[0].mcap_path
    }

    /// The bag's last MCAP file: the one a crash leaves open.
    pub fn last_path(&self) -> &Path {
        &self.parts[self.parts.len() - 1].mcap_path
    }

    /// Where `damage` is: its file.
    fn damage_path(&self, damage: &Damage) -> PathBuf {
        damage
            .file
            .as_ref()
            .and_then(|f| self.parts.iter().find(|p| &p.file_name() == f))
            .map_or_else(|| self.path().to_owned(), |p| p.mcap_path.clone())
    }

    /// Every MCAP file of the bag in order (one unless the bag was split).
    pub fn files(&self) -> Vec<BagFile> {
        self.parts
            .iter()
            .map(|p| BagFile {
                path: p.mcap_path.clone(),
                message_count: p.scan.message_count,
                finished: p.scan.finished,
                truncation: p.scan.tail.clone(),
            })
            .collect()
    }

    /// Topics with their types and counts.
    pub fn topics(&self) -> Vec<TopicInfo> {
        self.topics.clone()
    }

    /// Total messages readable.
    pub fn message_count(&self) -> u64 {
        self.parts.iter().map(|p| p.scan.message_count).sum()
    }

    /// Why the bag ended early, if it did (a crashed writer: its last file was cut
    /// short); `None` for a finished bag.
    pub fn truncation(&self) -> Option<&str> {
        self.parts[self.parts.len() - 1].scan.tail.as_deref()
    }

    /// Everything damaged in the bag's files, in order (empty for a sound bag).
    pub fn damage(&self) -> &[Damage] {
        &self.damage
    }

    /// Whether every file has its footer and summary (the writer finished them).
    pub fn finished(&self) -> bool {
        self.parts.iter().all(|p| p.scan.finished)
    }

    /// Chunks in the files, readable or not.
    pub fn chunk_count(&self) -> usize {
        self.parts.iter().map(|p| p.scan.chunk_count).sum()
    }

    /// Messages known (from message indexes) to sit in damaged chunks.
    pub fn lost_known(&self) -> u64 {
        self.parts.iter().map(|p| p.scan.lost_known).sum()
    }

    /// Every readable message in file order (= log-time order for our bags).
    pub fn messages(&self) -> impl Iterator<Item = Result<RawMessage, BagError>> + '_ {
        self.parts.iter().flat_map(|part| {
            part.scan
                .spans
                .iter()
                .flat_map(move |span| match part_messages(part, span) {
                    Ok(messages) => messages.into_iter().map(Ok).collect::<Vec<_>>(),
                    Err(e) => vec![Err(e)],
                })
        })
    }

    /// What the writer said produced the bag ([`crate::BagOptions::custom_data`]): read
    /// from the metadata record at the start of the (first) file, so crashed bags have it
    /// too. Empty for bags written by other tools.
    pub fn custom_data(&self) -> BTreeMap<String, String> {
        self.parts[0].scan.custom_data.clone()
    }

    /// Decodes `raw` as `M`, checking the stored type.
    pub fn decode<M: RosMessage>(&self, raw: &RawMessage) -> Result<M, BagError> {
        if raw.ros_type != M::ROS_TYPE {
            return Err(BagError::Decode {
                path: self.path().to_owned(),
                topic: raw.topic.clone(),
                log_time_ns: raw.log_time_ns,
                problem: format!("stored as {}, expected {}", raw.ros_type, M::ROS_TYPE),
            });
        }
        causal_arm_msgs::from_cdr(&raw.data).map_err(|e| BagError::Decode {
            path: self.path().to_owned(),
            topic: raw.topic.clone(),
            log_time_ns: raw.log_time_ns,
            problem: e.to_string(),
        })
    }
}

/// The damage of every file, named by file when there are several. A split other than
/// the last that ends early is damage too: a closed split is finished before the next
/// one opens, so it was cut afterwards.
fn damage_of(parts: &[Part]) -> Vec<Damage> {
    let split = parts.len() > 1;
    let mut damage = Vec::new();
    for (i, part) in parts.iter().enumerate() {
        let file = split.then(|| part.file_name());
        damage.extend(part.scan.damage.iter().map(|d| Damage {
            file: file.clone(),
            ..d.clone()
        }));
        if let Some(tail) = part.scan.tail.as_ref().filter(|_| i + 1 < parts.len()) {
            damage.push(Damage {
                file: file.clone(),
                offset: part.bytes.len() as u64,
                chunk: None,
                problem: format!(
                    "{tail}, but a later split follows it (a split is finished before the next one opens)"
                ),
            });
        }
    }
    damage
}

/// The messages of one span (a chunk or a lone message record) of `part`.
fn part_messages(part: &Part, span: &Span) -> Result<Vec<RawMessage>, BagError> {
    let start = (span.offset + 9) as usize;
    let body = &part.bytes[start..start + span.len as usize];
    let damaged = |problem: String| BagError::Damaged {
        path: part.mcap_path.clone(),
        damage: Damage {
            file: None,
            offset: span.offset,
            chunk: None,
            problem: format!("{problem} (the file changed while open?)"),
        },
        more: 0,
    };
    if !span.chunk {
        return part_message(part, body).map(|m| vec![m]).map_err(damaged);
    }
    let (_, records) = check::open_chunk(body).map_err(damaged)?;
    let mut out = Vec::new();
    for item in check::Records::new(&records, 0) {
        let (_, opcode, body) = item.map_err(|(_, p)| damaged(p))?;
        if opcode == mcap::records::op::MESSAGE {
            out.push(part_message(part, body).map_err(damaged)?);
        }
    }
    Ok(out)
}

fn part_message(part: &Part, body: &[u8]) -> Result<RawMessage, String> {
    let Ok(mcap::records::Record::Message { header, data }) =
        crate::bounds::parse_record(mcap::records::op::MESSAGE, body)
    else {
        return Err("message record unreadable".into());
    };
    let channel = part
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

/// Topics in name order, with counts from the scans of the bag's files.
fn topics_of<'a>(scans: impl Iterator<Item = &'a Scan>) -> Vec<TopicInfo> {
    let mut topics: BTreeMap<String, TopicInfo> = BTreeMap::new();
    let channels = scans.flat_map(|scan| scan.channels.iter().map(move |c| (scan, c)));
    for (scan, (id, def)) in channels {
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
