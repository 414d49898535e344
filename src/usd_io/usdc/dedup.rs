//! Value deduplication: a value whose encoded bytes were already written is
//! not written again; its field points at the first copy, as usd-core does
//! (a constant `displayOpacity` sampled every frame is stored once).
//!
//! The writer keeps no copy of what it wrote (bakes stream hundreds of MB),
//! so values are matched by type, length and a 128-bit fingerprint of their
//! bytes. Two different values of one type and length share a fingerprint
//! with probability about 2^-128 per pair: for a million stored values,
//! about 10^-27.
//!
//! The table is bounded: past [`MAX_ENTRIES`] it starts over, which only
//! costs a second copy of a value seen before the reset.

use std::collections::HashMap;

/// Entries kept before the table is cleared (about 3 MB): a bake stores a
/// few hundred values per frame, and the values worth sharing (constant
/// ones) recur every frame, so they are found again right after a reset.
const MAX_ENTRIES: usize = 1 << 16;

/// The key of one stored value: its rep's type and flag bits, its length and
/// its fingerprint.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
struct Key {
    kind: u16,
    len: u64,
    fingerprint: (u64, u64),
}

#[derive(Default)]
pub struct Dedup {
    table: HashMap<Key, u64>,
}

impl Dedup {
    /// The rep stored for these bytes, if any.
    pub fn find(&self, kind: u16, bytes: &[u8]) -> (Option<u64>, (u64, u64)) {
        let fingerprint = fingerprint(bytes);
        let key = Key {
            kind,
            len: bytes.len() as u64,
            fingerprint,
        };
        (self.table.get(&key).copied(), fingerprint)
    }

    pub fn insert(&mut self, kind: u16, len: usize, fingerprint: (u64, u64), rep: u64) {
        if self.table.len() >= MAX_ENTRIES {
            self.table.clear();
        }
        let key = Key {
            kind,
            len: len as u64,
            fingerprint,
        };
        self.table.insert(key, rep);
    }
}

/// Two independent 64-bit lanes over 16-byte blocks. Each lane folds a
/// 64×64→128-bit product of the block (keyed by the lane's constants) into
/// its state and then scrambles the state with an odd multiply and a
/// rotation, both bijections, so no block can erase what came before and the
/// result depends on block order.
pub fn fingerprint(bytes: &[u8]) -> (u64, u64) {
    const K: [u64; 6] = [
        0xa076_1d64_78bd_642f,
        0xe703_7ed1_a0b4_28db,
        0x8ebc_6af0_9c88_c6e3,
        0x5899_65cc_7537_4cc3,
        0x1d8e_4e27_c47d_124f,
        0x9e37_79b9_7f4a_7c15,
    ];
    #[inline(always)]
    fn mum(a: u64, b: u64) -> u64 {
        let r = (a as u128).wrapping_mul(b as u128);
        (r as u64) ^ ((r >> 64) as u64)
    }
    let len = bytes.len() as u64;
    let (mut h1, mut h2) = (K[0] ^ len, K[1] ^ len.rotate_left(32));
    let mut blocks = bytes.chunks_exact(16);
    for block in &mut blocks {
        let a = u64::from_le_bytes(block[..8].try_into().unwrap());
        let b = u64::from_le_bytes(block[8..].try_into().unwrap());
        h1 = (h1 ^ mum(a ^ K[2], b ^ K[3])).wrapping_mul(K[5]).rotate_left(29);
        h2 = (h2 ^ mum(b ^ K[4], a ^ K[0])).wrapping_mul(K[1] | 1).rotate_left(37);
    }
    let mut tail = [0u8; 16];
    let rest = blocks.remainder();
    tail[..rest.len()].copy_from_slice(rest);
    let a = u64::from_le_bytes(tail[..8].try_into().unwrap()) ^ rest.len() as u64;
    let b = u64::from_le_bytes(tail[8..].try_into().unwrap());
    h1 = mum(h1 ^ mum(a ^ K[2], b ^ K[3]), K[5]);
    h2 = mum(h2 ^ mum(b ^ K[4], a ^ K[0]), K[3]);
    (h1, h2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    #[test]
    fn fingerprints_differ_for_nearby_and_reordered_inputs() {
        let mut seen = HashSet::new();
        // Every single-bit flip of a 64-byte block, plus swaps of its halves
        // and every length prefix: all distinct.
        let base: Vec<u8> = (0..64u8).collect();
        assert!(seen.insert(fingerprint(&base)));
        for bit in 0..base.len() * 8 {
            let mut v = base.clone();
            v[bit / 8] ^= 1 << (bit % 8);
            assert!(seen.insert(fingerprint(&v)), "bit {bit}");
        }
        let mut swapped = base.clone();
        swapped.rotate_left(16);
        assert!(seen.insert(fingerprint(&swapped)));
        for n in 0..base.len() {
            assert!(seen.insert(fingerprint(&base[..n])), "prefix {n}");
        }
        // Zero runs of different lengths.
        for n in 1..100 {
            assert!(seen.insert(fingerprint(&vec![0u8; n * 7])), "zeros {n}");
        }
    }
}
