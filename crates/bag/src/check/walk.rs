//! The scan of a whole file: the top-level records in order, the footer and the summary
//! section checked against what the data section held.

use std::collections::BTreeMap;

use mcap::records::{ChunkHeader, ChunkIndex, Footer, Record, Statistics, op};

use super::chunk::{Channels, chunk_messages, next_valid_chunk, open_chunk};
use super::{Damage, FRAME, MessageAt, Records, Scan, Span};

/// Bytes of a footer record with its framing, followed by the closing magic.
const FOOTER_RECORD: u64 = FRAME + 20;

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
