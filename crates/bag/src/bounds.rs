//! Length fields checked before the `mcap` crate parses a record: it reserves a string's or
//! byte array's claimed length before reading it, so one corrupted length inside a
//! 100-byte record asked for 3.6 GB (found by the `bag` fuzz target). Every length prefix
//! of the record's layout (MCAP spec, "Records") must fit in the bytes that follow it.

use mcap::records::{Record, op};

/// One field of a record's layout.
#[derive(Clone, Copy)]
enum Field {
    /// Fixed-width field of this many bytes.
    Fixed(usize),
    /// `uint32` length, then that many bytes (strings, schema data).
    Prefixed32,
    /// `uint64` length, then that many bytes (chunk records, attachment data).
    Prefixed64,
    /// `uint32` byte length, then `map<string, string>` entries filling exactly it.
    StringMap,
    /// `uint32` byte length, then fixed-width entries (maps and arrays of integers).
    FixedArray32,
    /// The rest of the record (message data).
    Rest,
}

use Field::*;

/// The layout of each record the `mcap` crate parses with length-prefixed fields.
fn layout(opcode: u8) -> &'static [Field] {
    match opcode {
        op::HEADER => &[Prefixed32, Prefixed32],
        op::SCHEMA => &[Fixed(2), Prefixed32, Prefixed32, Prefixed32],
        op::CHANNEL => &[Fixed(4), Prefixed32, Prefixed32, StringMap],
        op::CHUNK => &[Fixed(28), Prefixed32, Prefixed64],
        op::MESSAGE_INDEX => &[Fixed(2), FixedArray32],
        op::CHUNK_INDEX => &[Fixed(32), FixedArray32, Fixed(8), Prefixed32, Fixed(16)],
        op::ATTACHMENT => &[Fixed(16), Prefixed32, Prefixed32, Prefixed64, Fixed(4)],
        op::ATTACHMENT_INDEX => &[Fixed(40), Prefixed32, Prefixed32],
        op::STATISTICS => &[Fixed(42), FixedArray32],
        op::METADATA => &[Prefixed32, StringMap],
        op::METADATA_INDEX => &[Fixed(16), Prefixed32],
        _ => &[Rest],
    }
}

/// Reads a little-endian length of `width` bytes at `at`.
fn length(body: &[u8], at: usize, width: usize) -> Result<u64, String> {
    let bytes = body
        .get(at..at + width)
        .ok_or_else(|| format!("a length field at byte {at} runs past the record"))?;
    let mut value = [0u8; 8];
    value[..width].copy_from_slice(bytes);
    Ok(u64::from_le_bytes(value))
}

/// Skips a `width`-byte length and the bytes it claims; the new position.
fn skip_prefixed(body: &[u8], at: usize, width: usize) -> Result<usize, String> {
    let claimed = length(body, at, width)?;
    let start = at + width;
    let left = (body.len() - start) as u64;
    if claimed > left {
        return Err(format!(
            "a field at byte {at} claims {claimed} bytes, the record has {left} left"
        ));
    }
    Ok(start + claimed as usize)
}

/// Checks that every length prefix of the record fits in it.
pub(crate) fn check(opcode: u8, body: &[u8]) -> Result<(), String> {
    let mut at = 0;
    for field in layout(opcode) {
        at = match *field {
            Fixed(n) if at + n <= body.len() => at + n,
            Fixed(_) => return Err(format!("record too short ({} bytes)", body.len())),
            Prefixed32 | FixedArray32 => skip_prefixed(body, at, 4)?,
            Prefixed64 => skip_prefixed(body, at, 8)?,
            StringMap => {
                let end = skip_prefixed(body, at, 4)?;
                let entries = &body[at + 4..end];
                let mut pos = 0;
                while pos < entries.len() {
                    pos = skip_prefixed(entries, pos, 4)?;
                    pos = skip_prefixed(entries, pos, 4)?;
                }
                end
            }
            Rest => body.len(),
        };
    }
    Ok(())
}

/// `mcap::parse_record` after [`check`]: a record's claimed lengths never make it allocate
/// more than the record holds.
pub(crate) fn parse_record(opcode: u8, body: &[u8]) -> Result<Record<'_>, String> {
    check(opcode, body)?;
    mcap::parse_record(opcode, body).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn string(s: &str) -> Vec<u8> {
        let mut out = (s.len() as u32).to_le_bytes().to_vec();
        out.extend_from_slice(s.as_bytes());
        out
    }

    fn channel(metadata: &[u8]) -> Vec<u8> {
        let mut body = vec![1, 0, 1, 0];
        body.extend(string("/joint_states"));
        body.extend(string("cdr"));
        body.extend((metadata.len() as u32).to_le_bytes());
        body.extend_from_slice(metadata);
        body
    }

    #[test]
    fn a_well_formed_channel_passes_and_parses() {
        let mut map = string("offered_qos_profiles");
        map.extend(string("- history: 3"));
        let body = channel(&map);
        assert_eq!(check(op::CHANNEL, &body), Ok(()));
        assert!(matches!(
            parse_record(op::CHANNEL, &body),
            Ok(Record::Channel(_))
        ));
    }

    #[test]
    fn a_string_claiming_more_than_the_record_is_refused_before_parsing() {
        let mut body = channel(&[]);
        // The topic's length says 3.6 GB.
        body[4..8].copy_from_slice(&3_611_797_483u32.to_le_bytes());
        let problem = parse_record(op::CHANNEL, &body).unwrap_err();
        assert!(problem.contains("claims 3611797483 bytes"), "{problem}");
    }

    #[test]
    fn a_map_entry_claiming_more_than_its_map_is_refused() {
        let mut map = string("key");
        map.extend(4_000_000_000u32.to_le_bytes());
        let problem = check(op::CHANNEL, &channel(&map)).unwrap_err();
        assert!(problem.contains("claims 4000000000 bytes"), "{problem}");
    }

    #[test]
    fn a_chunk_whose_records_claim_more_than_it_holds_is_refused() {
        let mut body = vec![0; 28];
        body.extend(string("zstd"));
        body.extend(u64::MAX.to_le_bytes());
        assert!(check(op::CHUNK, &body).is_err());
    }
}
