//! Checked reading of one MCAP file: the framing of every record, every chunk's sizes,
//! compression and CRC (with bounded allocation), message indexes against their chunk,
//! the data and summary section CRCs, and the summary's counts against what was read.
//!
//! So damage is found and named (byte offset, chunk), never taken for the end of the data,
//! and a crash tail (a writer killed mid-record, nothing valid after it) is told apart
//! from mid-file corruption. The record parsing itself is the `mcap` crate's.

use std::collections::BTreeMap;
use std::fmt;

use mcap::records::{ChunkHeader, ChunkIndex, Footer, Record, Statistics, op};

/// Largest chunk decompressed: a corrupted size field must not make us allocate more.
const MAX_CHUNK_BYTES: u64 = 1 << 30;
/// Bytes of a record's framing: opcode (1) and length (8).
const FRAME: u64 = 9;
/// Bytes of a footer record with its framing, followed by the closing magic.
const FOOTER_RECORD: u64 = FRAME + 20;

/// One damaged place of a file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Damage {
    /// The file of a split bag the damage is in (`None` for a bag of one file).
    pub file: Option<String>,
    /// Byte offset of the damaged record in the file.
    pub offset: u64,
    /// 0-based index, in file order, of the chunk the damage is in, if it is in one.
    pub chunk: Option<usize>,
    /// What is wrong.
    pub problem: String,
}

impl fmt::Display for Damage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{file} ")?;
        }
        write!(f, "byte {}", self.offset)?;
        if let Some(chunk) = self.chunk {
            write!(f, " (chunk {chunk})")?;
        }
        write!(f, ": {}", self.problem)
    }
}

/// A channel as the file defines it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ChannelDef {
    pub topic: String,
    pub ros_type: String,
    pub offered_qos: String,
}

/// A readable stretch of the file: a checked chunk, or a message record outside chunks.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Span {
    /// Offset of the record's opcode.
    pub offset: u64,
    /// Length of the record's body.
    pub len: u64,
    /// Whether it is a chunk (else a lone message record).
    pub chunk: bool,
}

/// What a scan of the whole file found.
#[derive(Debug, Default)]
pub(crate) struct Scan {
    pub spans: Vec<Span>,
    pub channels: BTreeMap<u16, ChannelDef>,
    pub per_channel: BTreeMap<u16, u64>,
    pub message_count: u64,
    pub chunk_count: usize,
    pub damage: Vec<Damage>,
    /// Why the file ends early, when its writer was cut off (not damage).
    pub tail: Option<String>,
    /// Whether the file has its footer and closing magic.
    pub finished: bool,
    /// The `causal_arm` metadata record, when present.
    pub custom_data: BTreeMap<String, String>,
    /// Messages known to be in damaged chunks (from their message indexes or chunk index).
    pub lost_known: u64,
}

/// One message inside a checked chunk.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MessageAt {
    /// Offset of its record inside the decompressed chunk.
    pub offset: u64,
    pub channel: u16,
    pub log_time: u64,
}

/// Walks record framing over `buf` from `pos`: yields (offset, opcode, body) until the end,
/// or one `Err((offset, problem))` where a record does not fit, then stops.
pub(crate) struct Records<'a> {
    buf: &'a [u8],
    pos: u64,
    broken: bool,
}

impl<'a> Records<'a> {
    pub(crate) fn new(buf: &'a [u8], pos: u64) -> Self {
        Self {
            buf,
            pos,
            broken: false,
        }
    }
}

impl<'a> Iterator for Records<'a> {
    type Item = Result<(u64, u8, &'a [u8]), (u64, String)>;

    fn next(&mut self) -> Option<Self::Item> {
        let len = self.buf.len() as u64;
        if self.broken || self.pos >= len {
            return None;
        }
        let at = self.pos;
        let left = len - at;
        if left < FRAME {
            self.broken = true;
            return Some(Err((at, format!("{left} bytes left, a record needs 9"))));
        }
        let start = at as usize;
        let opcode = self.buf[start];
        let length = u64::from_le_bytes(self.buf[start + 1..start + 9].try_into().unwrap());
        if length > left - FRAME {
            self.broken = true;
            return Some(Err((
                at,
                format!(
                    "record (opcode {opcode:#04x}) claims {length} bytes, {} are left",
                    left - FRAME
                ),
            )));
        }
        self.pos = at + FRAME + length;
        let body = &self.buf[start + 9..start + 9 + length as usize];
        Some(Ok((at, opcode, body)))
    }
}

/// Decompresses and checks a chunk record's body: sizes before allocating, the
/// compression stream, the CRC, and the records inside (framing, channels, message times).
pub(crate) fn open_chunk(body: &[u8]) -> Result<(ChunkHeader, Vec<u8>), String> {
    let (header, data) = match crate::bounds::parse_record(op::CHUNK, body) {
        Ok(Record::Chunk { header, data }) => (header, data),
        Ok(_) => unreachable!("parse_record(CHUNK) yields chunks"),
        Err(e) => return Err(format!("chunk header unreadable: {e}")),
    };
    if header.compressed_size != data.len() as u64 {
        return Err(format!(
            "chunk header says {} compressed bytes, the record holds {}",
            header.compressed_size,
            data.len()
        ));
    }
    if header.uncompressed_size > MAX_CHUNK_BYTES {
        return Err(format!(
            "chunk header says {} uncompressed bytes, more than the {MAX_CHUNK_BYTES} allowed",
            header.uncompressed_size
        ));
    }
    let records = decompress(&header, &data)?;
    if header.uncompressed_crc != 0 {
        let crc = crc32fast::hash(&records);
        if crc != header.uncompressed_crc {
            return Err(format!(
                "CRC mismatch: stored {:#010x}, computed {crc:#010x}",
                header.uncompressed_crc
            ));
        }
    }
    Ok((header, records))
}

fn decompress(header: &ChunkHeader, data: &[u8]) -> Result<Vec<u8>, String> {
    let want = header.uncompressed_size as usize;
    let out = match header.compression.as_str() {
        "" => data.to_vec(),
        "zstd" => {
            if let Ok(Some(size)) = zstd::zstd_safe::get_frame_content_size(data)
                && size != header.uncompressed_size
            {
                return Err(format!(
                    "chunk header says {want} uncompressed bytes, its zstd frame holds {size}"
                ));
            }
            zstd::bulk::decompress(data, want)
                .map_err(|e| format!("zstd stream does not decompress to {want} bytes: {e}"))?
        }
        "lz4" => {
            use std::io::Read;
            let mut out = Vec::with_capacity(want);
            lz4::Decoder::new(data)
                .and_then(|d| d.take(want as u64 + 1).read_to_end(&mut out))
                .map_err(|e| format!("lz4 stream unreadable: {e}"))?;
            out
        }
        other => return Err(format!("unknown chunk compression {other:?}")),
    };
    if out.len() != want {
        return Err(format!(
            "chunk header says {want} uncompressed bytes, it decompresses to {}",
            out.len()
        ));
    }
    Ok(out)
}

/// The messages of a decompressed chunk, registering its schemas and channels.
pub(crate) fn chunk_messages(
    header: &ChunkHeader,
    records: &[u8],
    channels: &mut Channels,
) -> Result<Vec<MessageAt>, String> {
    let mut messages = Vec::new();
    for item in Records::new(records, 0) {
        let (offset, opcode, body) =
            item.map_err(|(at, problem)| format!("inside the chunk at {at}: {problem}"))?;
        let inside = |e: String| format!("record at {offset} inside the chunk: {e}");
        match opcode {
            op::SCHEMA | op::CHANNEL => {
                let record = crate::bounds::parse_record(opcode, body).map_err(inside)?;
                channels
                    .register(&record)
                    .map_err(|e| format!("{e} (inside the chunk)"))?;
            }
            op::MESSAGE => {
                let Record::Message { header: m, .. } =
                    crate::bounds::parse_record(opcode, body).map_err(inside)?
                else {
                    unreachable!("parse_record(MESSAGE) yields messages")
                };
                if !channels.defs.contains_key(&m.channel_id) {
                    return Err(format!(
                        "message at {offset} inside the chunk names channel {}, which is not defined before it",
                        m.channel_id
                    ));
                }
                messages.push(MessageAt {
                    offset,
                    channel: m.channel_id,
                    log_time: m.log_time,
                });
            }
            other => {
                return Err(format!(
                    "record at {offset} inside the chunk has opcode {other:#04x}; chunks hold schemas, channels and messages only"
                ));
            }
        }
    }
    check_chunk_times(header, &messages)?;
    Ok(messages)
}

fn check_chunk_times(header: &ChunkHeader, messages: &[MessageAt]) -> Result<(), String> {
    let (Some(first), Some(last)) = (
        messages.iter().map(|m| m.log_time).min(),
        messages.iter().map(|m| m.log_time).max(),
    ) else {
        return Ok(());
    };
    if (first, last) != (header.message_start_time, header.message_end_time) {
        return Err(format!(
            "chunk header says its messages span {} to {} ns, they span {first} to {last} ns",
            header.message_start_time, header.message_end_time
        ));
    }
    Ok(())
}

/// Schemas (id → name) and channels as defined so far; a redefinition must agree.
#[derive(Debug, Default)]
pub(crate) struct Channels {
    schemas: BTreeMap<u16, String>,
    pub defs: BTreeMap<u16, ChannelDef>,
}

impl Channels {
    fn register(&mut self, record: &Record<'_>) -> Result<(), String> {
        match record {
            Record::Schema { header, .. } => {
                let old = self.schemas.insert(header.id, header.name.clone());
                if old.as_ref().is_some_and(|old| *old != header.name) {
                    return Err(format!(
                        "schema {} is defined twice, as {old:?} and {:?}",
                        header.id, header.name
                    ));
                }
            }
            Record::Channel(c) => {
                let def = ChannelDef {
                    topic: c.topic.clone(),
                    ros_type: self.schemas.get(&c.schema_id).cloned().unwrap_or_default(),
                    offered_qos: c
                        .metadata
                        .get("offered_qos_profiles")
                        .cloned()
                        .unwrap_or_default(),
                };
                if c.schema_id != 0 && !self.schemas.contains_key(&c.schema_id) {
                    return Err(format!(
                        "channel {} ({}) names schema {}, which is not defined before it",
                        c.id, c.topic, c.schema_id
                    ));
                }
                if let Some(old) = self.defs.get(&c.id)
                    && (old.topic != def.topic || old.ros_type != def.ros_type)
                {
                    return Err(format!(
                        "channel {} is defined twice, as {} ({}) and {} ({})",
                        c.id, old.topic, old.ros_type, def.topic, def.ros_type
                    ));
                }
                self.defs.insert(c.id, def);
            }
            _ => {}
        }
        Ok(())
    }
}

/// The footer, when the file ends with one and the closing magic.
fn footer(bytes: &[u8]) -> Option<(u64, Footer)> {
    let len = bytes.len() as u64;
    let magic = mcap::MAGIC.len() as u64;
    if len < magic * 2 + FOOTER_RECORD || !bytes.ends_with(mcap::MAGIC) {
        return None;
    }
    let at = len - magic - FOOTER_RECORD;
    let record = &bytes[at as usize..(len - magic) as usize];
    if record[0] != op::FOOTER || record[1..9] != 20u64.to_le_bytes() {
        return None;
    }
    match crate::bounds::parse_record(op::FOOTER, &record[9..]) {
        Ok(Record::Footer(f)) => Some((at, f)),
        _ => None,
    }
}

/// Scans the whole file. Never fails: everything wrong is in [`Scan::damage`] or
/// [`Scan::tail`].
pub(crate) fn scan(bytes: &[u8]) -> Scan {
    let mut walk = Walk::default();
    let magic = mcap::MAGIC.len();
    if bytes.is_empty() {
        walk.scan.tail = Some("the file is empty (0 bytes)".into());
        return walk.scan;
    }
    if bytes.len() < magic && mcap::MAGIC.starts_with(bytes) {
        walk.scan.tail = Some(format!(
            "the file ends inside the magic ({} bytes)",
            bytes.len()
        ));
        return walk.scan;
    }
    if !bytes.starts_with(mcap::MAGIC) {
        let shown = &bytes[..bytes.len().min(magic)];
        walk.damage(
            0,
            None,
            format!("not an MCAP file: starts with {shown:02x?}"),
        );
        return walk.scan;
    }
    // A file that ends with the closing magic was finished by its writer: nothing in it
    // can be a crash tail.
    walk.scan.finished = bytes.len() >= 2 * magic && bytes.ends_with(mcap::MAGIC);
    let footer = footer(bytes);
    let data_end = match footer {
        Some((at, f)) => {
            walk.check_summary_crc(bytes, at, &f);
            Some(at)
        }
        None if walk.scan.finished => {
            let at = (bytes.len() - magic).saturating_sub(FOOTER_RECORD as usize) as u64;
            walk.damage(
                at,
                None,
                "footer record unreadable before the closing magic".into(),
            );
            Some(bytes.len() as u64 - magic as u64)
        }
        None => None,
    };
    walk.records(bytes, data_end);
    walk.check_summary();
    walk.scan
}

/// State of one scan in progress.
#[derive(Default)]
struct Walk {
    scan: Scan,
    channels: Channels,
    /// Messages of the chunk read last, for its message indexes.
    last_chunk: Vec<MessageAt>,
    last_chunk_ok: bool,
    chunk_offsets: BTreeMap<u64, (usize, u64, ChunkHeader)>,
    chunk_indexes: Vec<(u64, ChunkIndex)>,
    statistics: Option<(u64, Statistics)>,
    data_crc: Option<crc32fast::Hasher>,
}

impl Walk {
    fn damage(&mut self, offset: u64, chunk: Option<usize>, problem: String) {
        self.scan.damage.push(Damage {
            file: None,
            offset,
            chunk,
            problem,
        });
    }

    fn check_summary_crc(&mut self, bytes: &[u8], footer_at: u64, footer: &Footer) {
        if footer.summary_start == 0 || footer.summary_crc == 0 {
            return;
        }
        let end = footer_at + FRAME + 16;
        if footer.summary_start > footer_at {
            let problem = format!(
                "footer says the summary starts at {}, past the footer",
                footer.summary_start
            );
            self.damage(footer_at, None, problem);
            return;
        }
        let crc = crc32fast::hash(&bytes[footer.summary_start as usize..end as usize]);
        if crc != footer.summary_crc {
            let problem = format!(
                "summary section CRC mismatch: stored {:#010x}, computed {crc:#010x}",
                footer.summary_crc
            );
            self.damage(footer.summary_start, None, problem);
        }
    }

    /// Walks the top-level records from after the magic to the footer (or the end).
    fn records(&mut self, bytes: &[u8], footer_at: Option<u64>) {
        let end = footer_at.unwrap_or(bytes.len() as u64) as usize;
        let mut pos = mcap::MAGIC.len() as u64;
        let mut hasher = crc32fast::Hasher::new();
        hasher.update(mcap::MAGIC);
        self.data_crc = Some(hasher);
        while (pos as usize) < end {
            let mut records = Records::new(&bytes[..end], pos);
            let mut resume = None;
            for item in records.by_ref() {
                match item {
                    Ok((at, opcode, body)) => {
                        let end = at as usize + FRAME as usize + body.len();
                        if opcode == op::FOOTER && mcap::MAGIC.starts_with(&bytes[end..]) {
                            self.scan.tail =
                                Some(format!("cut short in the closing magic at byte {end}"));
                            break;
                        }
                        self.record(at, opcode, body, &bytes[at as usize..end]);
                    }
                    Err((at, problem)) => resume = Some(self.broken_frame(bytes, at, problem)),
                }
            }
            match resume {
                Some(Some(next)) => pos = next,
                _ => break,
            }
        }
        if footer_at.is_none() && self.scan.tail.is_none() && self.scan.damage.is_empty() {
            self.scan.tail = Some("no footer: the writer did not finish the file".into());
        }
    }

    /// A record that does not fit: a crash tail when nothing valid follows, else damage.
    /// Returns where reading can resume (the next valid chunk), if anywhere.
    fn broken_frame(&mut self, bytes: &[u8], at: u64, problem: String) -> Option<u64> {
        let next = next_valid_chunk(bytes, at + 1);
        if next.is_none() && !self.scan.finished {
            self.scan.tail = Some(format!("cut short at byte {at}: {problem}"));
            return None;
        }
        let what = match next {
            Some(next) => format!("{problem}; a valid chunk follows at {next}"),
            None => format!("{problem}; the file has its footer, so this is not a crash tail"),
        };
        self.damage(at, None, what);
        self.data_crc = None;
        next
    }

    fn record(&mut self, at: u64, opcode: u8, body: &[u8], whole: &[u8]) {
        if let Some(h) = self.data_crc.as_mut()
            && opcode != op::DATA_END
        {
            h.update(whole);
        }
        match opcode {
            op::CHUNK => self.chunk(at, body),
            op::MESSAGE_INDEX => self.message_index(at, body),
            op::DATA_END => self.data_end(at, body),
            op::MESSAGE => self.lone_message(at, body),
            op::HEADER
            | op::SCHEMA
            | op::CHANNEL
            | op::CHUNK_INDEX
            | op::ATTACHMENT
            | op::ATTACHMENT_INDEX
            | op::STATISTICS
            | op::METADATA
            | op::METADATA_INDEX
            | op::SUMMARY_OFFSET => self.other(at, opcode, body),
            op::FOOTER => {
                let problem = "a footer before the end of the file".to_string();
                self.damage(at, None, problem);
            }
            other => {
                let problem = format!("unknown record opcode {other:#04x}");
                self.damage(at, None, problem);
            }
        }
    }

    fn chunk(&mut self, at: u64, body: &[u8]) {
        let index = self.scan.chunk_count;
        self.scan.chunk_count += 1;
        self.last_chunk.clear();
        self.last_chunk_ok = false;
        let checked = open_chunk(body).and_then(|(header, records)| {
            let messages = chunk_messages(&header, &records, &mut self.channels)?;
            Ok((header, messages))
        });
        match checked {
            Ok((header, messages)) => {
                for m in &messages {
                    *self.scan.per_channel.entry(m.channel).or_default() += 1;
                }
                self.scan.message_count += messages.len() as u64;
                self.last_chunk = messages;
                self.last_chunk_ok = true;
                self.chunk_offsets
                    .insert(at, (index, FRAME + body.len() as u64, header));
                self.scan.spans.push(Span {
                    offset: at,
                    len: body.len() as u64,
                    chunk: true,
                });
            }
            Err(problem) => self.damage(at, Some(index), problem),
        }
    }

    fn message_index(&mut self, at: u64, body: &[u8]) {
        let chunk = self.scan.chunk_count.checked_sub(1);
        let index = match crate::bounds::parse_record(op::MESSAGE_INDEX, body) {
            Ok(Record::MessageIndex(index)) => index,
            Ok(_) => unreachable!("parse_record(MESSAGE_INDEX) yields message indexes"),
            Err(e) => return self.damage(at, chunk, format!("message index unreadable: {e}")),
        };
        if !self.last_chunk_ok {
            self.scan.lost_known += index.records.len() as u64;
            return;
        }
        let mine: Vec<(u64, u64)> = self
            .last_chunk
            .iter()
            .filter(|m| m.channel == index.channel_id)
            .map(|m| (m.log_time, m.offset))
            .collect();
        let mut listed: Vec<(u64, u64)> = index
            .records
            .iter()
            .map(|e| (e.log_time, e.offset))
            .collect();
        listed.sort_unstable();
        let mut sorted = mine.clone();
        sorted.sort_unstable();
        if listed != sorted {
            let problem = format!(
                "message index of channel {} lists {} messages that do not match the chunk's {}",
                index.channel_id,
                listed.len(),
                mine.len()
            );
            self.damage(at, chunk, problem);
        }
    }

    fn data_end(&mut self, at: u64, body: &[u8]) {
        let stored = match crate::bounds::parse_record(op::DATA_END, body) {
            Ok(Record::DataEnd(d)) => d.data_section_crc,
            _ => return self.damage(at, None, "data end record unreadable".into()),
        };
        if let Some(h) = self.data_crc.take()
            && stored != 0
        {
            let crc = h.finalize();
            if crc != stored {
                let problem = format!(
                    "data section CRC mismatch: stored {stored:#010x}, computed {crc:#010x}"
                );
                self.damage(at, None, problem);
            }
        }
    }

    fn lone_message(&mut self, at: u64, body: &[u8]) {
        match crate::bounds::parse_record(op::MESSAGE, body) {
            Ok(Record::Message { header, .. })
                if self.channels.defs.contains_key(&header.channel_id) =>
            {
                *self.scan.per_channel.entry(header.channel_id).or_default() += 1;
                self.scan.message_count += 1;
                self.scan.spans.push(Span {
                    offset: at,
                    len: body.len() as u64,
                    chunk: false,
                });
            }
            Ok(Record::Message { header, .. }) => {
                let problem = format!("message names undefined channel {}", header.channel_id);
                self.damage(at, None, problem);
            }
            Ok(_) => unreachable!("parse_record(MESSAGE) yields messages"),
            Err(e) => self.damage(at, None, format!("message record unreadable: {e}")),
        }
    }

    fn other(&mut self, at: u64, opcode: u8, body: &[u8]) {
        let record = match crate::bounds::parse_record(opcode, body) {
            Ok(record) => record,
            Err(e) => {
                let problem = format!("record (opcode {opcode:#04x}) unreadable: {e}");
                return self.damage(at, None, problem);
            }
        };
        match record {
            Record::Header(h) if at != mcap::MAGIC.len() as u64 => {
                let problem = format!("a second header record (profile {:?})", h.profile);
                self.damage(at, None, problem);
            }
            Record::Schema { .. } | Record::Channel(_) => {
                if let Err(problem) = self.channels.register(&record) {
                    self.damage(at, None, problem);
                }
            }
            Record::Metadata(m) if m.name == crate::BAG_METADATA_NAME => {
                self.scan.custom_data = m.metadata;
            }
            Record::ChunkIndex(index) => self.chunk_indexes.push((at, index)),
            Record::Statistics(stats) => self.statistics = Some((at, stats)),
            _ => {}
        }
    }

    /// The summary's chunk indexes and statistics against what the data section held.
    fn check_summary(&mut self) {
        self.scan.channels = self.channels.defs.clone();
        let indexes = std::mem::take(&mut self.chunk_indexes);
        let damaged: Vec<u64> = self.scan.damage.iter().map(|d| d.offset).collect();
        for (at, index) in indexes {
            let Some((_, length, header)) = self.chunk_offsets.get(&index.chunk_start_offset)
            else {
                if !damaged.contains(&index.chunk_start_offset) {
                    let problem = format!(
                        "chunk index points at byte {}, where no valid chunk is",
                        index.chunk_start_offset
                    );
                    self.damage(at, None, problem);
                }
                continue;
            };
            let agrees = *length == index.chunk_length
                && header.message_start_time == index.message_start_time
                && header.message_end_time == index.message_end_time
                && header.compressed_size == index.compressed_size
                && header.uncompressed_size == index.uncompressed_size
                && header.compression == index.compression;
            if !agrees {
                let problem = format!(
                    "chunk index for byte {} disagrees with the chunk there",
                    index.chunk_start_offset
                );
                self.damage(at, None, problem);
            }
        }
        self.check_statistics();
    }

    fn check_statistics(&mut self) {
        let Some((at, stats)) = self.statistics.take() else {
            return;
        };
        if !self.scan.damage.is_empty() {
            return;
        }
        let counted: BTreeMap<u16, u64> = self.scan.per_channel.clone();
        let mut problems = Vec::new();
        if stats.message_count != self.scan.message_count {
            problems.push(format!(
                "{} messages, the file holds {}",
                stats.message_count, self.scan.message_count
            ));
        }
        if stats.chunk_count as usize != self.scan.chunk_count {
            problems.push(format!(
                "{} chunks, the file holds {}",
                stats.chunk_count, self.scan.chunk_count
            ));
        }
        let listed: BTreeMap<u16, u64> = stats
            .channel_message_counts
            .into_iter()
            .filter(|(_, n)| *n > 0)
            .collect();
        if listed != counted {
            problems.push(format!(
                "per-channel counts {listed:?}, the file holds {counted:?}"
            ));
        }
        if !problems.is_empty() {
            let problem = format!("statistics record says {}", problems.join("; "));
            self.damage(at, None, problem);
        }
    }
}

/// The offset of the first record after `from` that is a chunk passing every check,
/// used to tell mid-file damage from a crash tail and to resume after damage.
fn next_valid_chunk(bytes: &[u8], from: u64) -> Option<u64> {
    let len = bytes.len() as u64;
    let mut pos = from;
    while pos + FRAME < len {
        let rest = &bytes[pos as usize..];
        let found = rest.iter().position(|b| *b == op::CHUNK)? as u64;
        let at = pos + found;
        pos = at + 1;
        if at + FRAME > len {
            return None;
        }
        let length =
            u64::from_le_bytes(bytes[at as usize + 1..at as usize + 9].try_into().unwrap());
        if length < 40 || length > len - at - FRAME {
            continue;
        }
        let body = &bytes[(at + FRAME) as usize..(at + FRAME + length) as usize];
        if plausible_chunk_header(body) && open_chunk(body).is_ok() {
            return Some(at);
        }
    }
    None
}

/// A cheap filter before decompressing a candidate chunk: its compression name is one
/// we know and its compressed size fills the record exactly.
fn plausible_chunk_header(body: &[u8]) -> bool {
    let Some(name_len) = body.get(28..32) else {
        return false;
    };
    let name_len = u32::from_le_bytes(name_len.try_into().unwrap()) as usize;
    if name_len > 4 {
        return false;
    }
    let name = &body[32..(32 + name_len).min(body.len())];
    let Some(size) = body.get(32 + name_len..40 + name_len) else {
        return false;
    };
    let size = u64::from_le_bytes(size.try_into().unwrap());
    matches!(name, b"" | b"zstd" | b"lz4") && size == (body.len() - 40 - name_len) as u64
}
