//! Value deduplication: a value whose encoded bytes were already written is
//! not written again; its field points at the first copy, as usd-core does
//! (a constant `displayOpacity` sampled every frame is stored once).
//!
//! The writer keeps no copy of what it wrote (bakes stream hundreds of MB),
//! so values are matched by type, length and a 128-bit fingerprint of their
//! bytes ([`fingerprint`]: two independent 64-bit multiply-mix lanes, fast
//! and well mixed but not cryptographic). For values that are not crafted to
//! collide, two different ones of a type and length share a fingerprint with
//! probability near 2^-128: with the at most 16,384 values kept, about 10^-34
//! per value written.
//!
//! The table is bounded: it keeps two generations of [`GENERATION`] entries
//! each; when the newer one fills, the older is dropped. A value found in the
//! older generation moves to the newer one, so a value that recurs (a
//! constant sampled every frame) is never forgotten, and memory stays flat
//! however many values a bake writes.

use std::collections::HashMap;

/// Entries per generation (two generations: about 1.3 MB in all).
const GENERATION: usize = 1 << 13;

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
    newer: HashMap<Key, u64>,
    older: HashMap<Key, u64>,
}

impl Dedup {
    /// The rep stored for these bytes, if any, and their fingerprint.
    pub fn find(&mut self, kind: u16, bytes: &[u8]) -> (Option<u64>, (u64, u64)) {
        let fingerprint = fingerprint(bytes);
        let key = Key {
            kind,
            len: bytes.len() as u64,
            fingerprint,
        };
        if let Some(&rep) = self.newer.get(&key) {
            return (Some(rep), fingerprint);
        }
        let old = self.older.get(&key).copied();
        if let Some(rep) = old {
            self.put(key, rep);
        }
        (old, fingerprint)
    }

    pub fn insert(&mut self, kind: u16, len: usize, fingerprint: (u64, u64), rep: u64) {
        let key = Key {
            kind,
            len: len as u64,
            fingerprint,
        };
        self.put(key, rep);
    }

    fn put(&mut self, key: Key, rep: u64) {
        if self.newer.len() >= GENERATION {
            self.older = std::mem::take(&mut self.newer);
            self.newer.reserve(GENERATION);
        }
        self.newer.insert(key, rep);
    }
}

/// The lanes' keys (arbitrary odd 64-bit constants).
const LANE_KEYS: [u64; 6] = [
    0xa076_1d64_78bd_642f,
    0xe703_7ed1_a0b4_28db,
    0x8ebc_6af0_9c88_c6e3,
    0x5899_65cc_7537_4cc3,
    0x1d8e_4e27_c47d_124f,
    0x9e37_79b9_7f4a_7c15,
];

/// Two independent 64-bit lanes over 16-byte blocks. Each lane folds a
/// 64×64→128-bit product of the block (keyed by the lane's constants) into
/// its state and then scrambles the state with an odd multiply and a
/// rotation, both bijections, so no block can erase what came before and the
/// result depends on block order.
pub fn fingerprint(bytes: &[u8]) -> (u64, u64) {
    const K: [u64; 6] = LANE_KEYS;
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
    fn a_recurring_value_survives_generations() {
        let mut d = Dedup::default();
        let constant = [7u8; 64];
        let (found, fp) = d.find(1, &constant);
        assert_eq!(found, None);
        d.insert(1, constant.len(), fp, 42);
        // Many frames of distinct values, the constant seen once per frame.
        for frame in 0..(4 * GENERATION as u64 / 10) {
            for k in 0..10u64 {
                let v = (frame * 10 + k).to_le_bytes();
                let (found, fp) = d.find(2, &v);
                assert_eq!(found, None);
                d.insert(2, v.len(), fp, frame);
            }
            assert_eq!(d.find(1, &constant).0, Some(42), "frame {frame}");
        }
        assert!(d.newer.len() + d.older.len() <= 2 * GENERATION);
    }

    /// The lane keys of [`fingerprint`]: as inputs they make a lane's block
    /// product zero (lane 1 multiplies `a ^ K[2]` by `b ^ K[3]`, lane 2
    /// `b ^ K[4]` by `a ^ K[0]`), so that only the other lane sees a word.
    const K: [u64; 6] = LANE_KEYS;
    const X: u64 = 0x0123_4567_89ab_cdef;

    fn words(ws: &[u64]) -> Vec<u8> {
        ws.iter().flat_map(|w| w.to_le_bytes()).collect()
    }

    /// `ws` and its 64 single-bit flips of word `w`, as bytes cut to `len`.
    fn flips_of_word(ws: &[u64], w: usize, bits: usize, len: usize) -> Vec<Vec<u8>> {
        let mut out = vec![words(ws)[..len].to_vec()];
        for k in 0..bits {
            let mut v = ws.to_vec();
            v[w] ^= 1 << k;
            out.push(words(&v)[..len].to_vec());
        }
        out
    }

    fn assert_all_distinct(inputs: &[Vec<u8>], what: &str) {
        let mut seen = HashSet::new();
        for (i, v) in inputs.iter().enumerate() {
            assert!(seen.insert(fingerprint(v)), "{what}: input {i} collides");
        }
    }

    /// Each lane keys its words, so a word one lane is blind to (its
    /// product is zero whatever the word) is still told apart by the other:
    /// every bit of it counts, in a block and in the tail.
    #[test]
    fn a_word_one_lane_cannot_see_the_other_tells_apart() {
        // Lane 2 is blind to b when a == K[0]; lane 1 to a when b == K[3].
        assert_all_distinct(&flips_of_word(&[K[0], X], 1, 64, 16), "block b");
        assert_all_distinct(&flips_of_word(&[X, K[3]], 0, 64, 16), "block a");
        // The tail's first word is xored with the tail's length (15 here);
        // its second word has 7 bytes. a ^ 15 == K[0] blinds lane 2 to b,
        // a ^ 15 == K[2] blinds lane 1 to b.
        let b = X & 0x00ff_ffff_ffff_ffff;
        assert_all_distinct(&flips_of_word(&[K[0] ^ 15, b], 1, 56, 15), "tail b, lane 1");
        assert_all_distinct(&flips_of_word(&[K[2] ^ 15, b], 1, 56, 15), "tail b, lane 2");
    }

    /// Folding a block into a lane is a bijection of the lane's state
    /// (xor, odd multiply, rotation): a later block whose product is zero or
    /// all ones must not erase what an earlier block made different.
    #[test]
    fn no_later_block_erases_an_earlier_one() {
        // Word 0 seen by lane 1 only (b == K[4] blinds lane 2), then a block
        // whose lane-1 product is 0 (a == K[2]) or all ones (a ^ K[2] = !0
        // times b ^ K[3] = 1), then a tail whose lane-1 product is 0.
        assert_all_distinct(&flips_of_word(&[X, K[4], K[2], K[4]], 0, 64, 32), "lane 1, zero");
        assert_all_distinct(&flips_of_word(&[X, K[4], !K[2], K[3] ^ 1], 0, 64, 32), "lane 1, ones");
        // In the tail (8 bytes, so its first word is xored with 8): product
        // 0 (a == K[2]) or all ones (a == !K[2]: !0 * y folds to !0).
        assert_all_distinct(&flips_of_word(&[X, K[4], K[2] ^ 8], 0, 64, 24), "lane 1, tail zero");
        assert_all_distinct(&flips_of_word(&[X, K[4], !K[2] ^ 8], 0, 64, 24), "lane 1, tail ones");
        // The same for lane 2: word 1 seen by lane 2 only (a == K[2]).
        assert_all_distinct(&flips_of_word(&[K[2], X, K[2], K[4]], 1, 64, 32), "lane 2, zero");
        assert_all_distinct(&flips_of_word(&[K[2], X, K[0] ^ 1, !K[4]], 1, 64, 32), "lane 2, ones");
        assert_all_distinct(&flips_of_word(&[K[2], X, K[0] ^ 8], 1, 64, 24), "lane 2, tail zero");
        assert_all_distinct(&flips_of_word(&[K[2], X, !K[0] ^ 8], 1, 64, 24), "lane 2, tail ones");
    }

    /// The 128-bit product is folded as low ^ high: a power-of-two factor
    /// makes it a rotation, and a factor of 1 keeps the other factor whole.
    /// Blocks (K[0] ^ 2^k, K[3] ^ 1) give lane 1 a ^ K[2] times 1 and lane
    /// 2 b ^ K[4] times 2^k: all 64 differ.
    #[test]
    fn the_product_keeps_both_halves() {
        let blocks: Vec<Vec<u8>> = (0..64).map(|k| words(&[K[0] ^ (1 << k), K[3] ^ 1])).collect();
        assert_all_distinct(&blocks, "power-of-two factors");
    }

    /// Order counts however far apart two blocks are, also 64 blocks apart
    /// (where lane 2's rotations by 37 per block come round again).
    #[test]
    fn swapping_blocks_64_apart_changes_the_fingerprint() {
        // Lane 1 is blind to every b (a == K[2]); the b between are K[4].
        let blocks = |first: u64, last: u64| -> Vec<u8> {
            let bs = (0..65).map(|i| match i {
                0 => first,
                64 => last,
                _ => K[4],
            });
            words(&bs.flat_map(|b| [K[2], b]).collect::<Vec<_>>())
        };
        assert_all_distinct(&[blocks(1, 2), blocks(2, 1)], "swapped");
    }

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
