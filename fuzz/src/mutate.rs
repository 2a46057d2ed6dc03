//! Byte-level mutations, the kinds that found the bag reader's hangs and silent losses:
//! bit flips, interesting values, truncations, duplicated and spliced ranges.

use rand::Rng;
use rand::rngs::StdRng;

/// Values that sit on the edges of lengths, counts and sizes.
const INTERESTING: [u64; 10] = [
    0,
    1,
    0x7f,
    0xff,
    0x7fff,
    0xffff,
    0x7fff_ffff,
    0xffff_ffff,
    0x7fff_ffff_ffff_ffff,
    u64::MAX,
];

/// One to four random mutations of `base`; `other` is a second corpus entry to splice from.
pub fn mutate(base: &[u8], other: &[u8], rng: &mut StdRng) -> Vec<u8> {
    let mut out = base.to_vec();
    for _ in 0..rng.random_range(1..=4) {
        mutate_once(&mut out, other, rng);
    }
    out
}

fn mutate_once(out: &mut Vec<u8>, other: &[u8], rng: &mut StdRng) {
    if out.is_empty() {
        out.push(rng.random());
        return;
    }
    let at = rng.random_range(0..out.len());
    match rng.random_range(0..7) {
        0 => out[at] ^= 1 << rng.random_range(0..8),
        1 => out[at] = rng.random(),
        2 => {
            // An interesting value, little- or big-endian, 1 to 8 bytes wide.
            let value = INTERESTING[rng.random_range(0..INTERESTING.len())];
            let width = [1, 2, 4, 8][rng.random_range(0..4)];
            let bytes = match rng.random_bool(0.5) {
                true => value.to_le_bytes(),
                false => value.to_be_bytes(),
            };
            let end = (at + width).min(out.len());
            out[at..end].copy_from_slice(&bytes[..end - at]);
        }
        3 => out.truncate(at),
        4 => {
            // Duplicate a range in place.
            let end = rng.random_range(at..=out.len().min(at + 256));
            let copy = out[at..end].to_vec();
            out.splice(at..at, copy);
        }
        5 => {
            // Remove a range.
            let end = rng.random_range(at..=out.len().min(at + 256));
            out.drain(at..end);
        }
        _ => {
            // Splice in a range of the other entry.
            if !other.is_empty() {
                let from = rng.random_range(0..other.len());
                let end = rng.random_range(from..=other.len().min(from + 256));
                out.splice(at..at, other[from..end].iter().copied());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn mutations_change_the_input_and_are_reproducible() {
        let base: Vec<u8> = (0..=255).collect();
        let run = |seed| {
            let mut rng = StdRng::seed_from_u64(seed);
            (0..50)
                .map(|_| mutate(&base, b"other", &mut rng))
                .collect::<Vec<_>>()
        };
        let first = run(7);
        assert_eq!(first, run(7));
        assert!(first.iter().filter(|m| **m != base).count() >= 45);
    }
}
