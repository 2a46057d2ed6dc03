//! One chunk record: its sizes, compression and CRC checked before its records are
//! trusted, the schemas and channels it defines, and the search for the next valid one.

use std::collections::BTreeMap;

use mcap::records::{ChunkHeader, Record, op};

use super::{ChannelDef, FRAME, MessageAt, Records};

/// Largest chunk decompressed: a corrupted size field must not make us allocate more.
const MAX_CHUNK_BYTES: u64 = 1 << 30;

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
pub(super) fn chunk_messages(
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
pub(super) struct Channels {
    schemas: BTreeMap<u16, String>,
    pub defs: BTreeMap<u16, ChannelDef>,
}

impl Channels {
    pub(super) fn register(&mut self, record: &Record<'_>) -> Result<(), String> {
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

/// The offset of the first record after `from` that is a chunk passing every check,
/// used to tell mid-file damage from a crash tail and to resume after damage.
pub(super) fn next_valid_chunk(bytes: &[u8], from: u64) -> Option<u64> {
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
