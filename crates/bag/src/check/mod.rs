//! Checked reading of one MCAP file: the framing of every record, every chunk's sizes,
//! compression and CRC (with bounded allocation), message indexes against their chunk,
//! the data and summary section CRCs, and the summary's counts against what was read.
//!
//! So damage is found and named (byte offset, chunk), never taken for the end of the data,
//! and a crash tail (a writer killed mid-record, nothing valid after it) is told apart
//! from mid-file corruption. The record parsing itself is the `mcap` crate's.

mod chunk;
mod walk;

use std::collections::BTreeMap;
use std::fmt;

pub(crate) use chunk::open_chunk;
pub(crate) use walk::scan;

/// Bytes of a record's framing: opcode (1) and length (8).
const FRAME: u64 = 9;

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
