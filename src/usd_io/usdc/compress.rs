//! The crate format's two compressors: LZ4 blocks with usd-core's chunk
//! framing (`TfFastCompression`), and the integer coding that runs before
//! LZ4 on index lists and integer arrays (`Sdf_IntegerCompression`).
//!
//! Integer coding: each integer becomes its difference from the previous
//! one; the most common difference is written once, then one 2-bit code per
//! integer (common / small / medium / large) and the non-common differences
//! at the width their code says (8/16/32 bits for 32-bit integers, 16/32/64
//! for 64-bit ones). The decoder in usd-core (and openusd) sums them back.

/// Largest input LZ4 takes in one block (`LZ4_MAX_INPUT_SIZE`); bigger
/// inputs are split into chunks, as usd-core does.
const LZ4_MAX_INPUT: usize = 0x7E00_0000;

/// Appends `input` LZ4-compressed in usd-core's framing: a chunk-count byte
/// (0 = one chunk, no size prefix), else per chunk an `i32` size and the
/// block.
pub fn lz4_frame(input: &[u8], out: &mut Vec<u8>) {
    if input.len() <= LZ4_MAX_INPUT {
        out.push(0);
        out.extend_from_slice(&lz4_flex::block::compress(input));
        return;
    }
    let chunks: Vec<&[u8]> = input.chunks(LZ4_MAX_INPUT).collect();
    out.push(chunks.len() as u8);
    for chunk in chunks {
        let block = lz4_flex::block::compress(chunk);
        out.extend_from_slice(&(block.len() as i32).to_le_bytes());
        out.extend_from_slice(&block);
    }
}

/// An integer type the coding handles: 32- or 64-bit, signed or unsigned,
/// worked on as its two's-complement signed value.
pub trait CodedInt: Copy {
    /// 4 or 8.
    const BYTES: usize;
    fn signed(self) -> i64;
}

impl CodedInt for i32 {
    const BYTES: usize = 4;
    fn signed(self) -> i64 {
        self as i64
    }
}
impl CodedInt for u32 {
    const BYTES: usize = 4;
    fn signed(self) -> i64 {
        self as i32 as i64
    }
}
impl CodedInt for i64 {
    const BYTES: usize = 8;
    fn signed(self) -> i64 {
        self
    }
}
impl CodedInt for u64 {
    const BYTES: usize = 8;
    fn signed(self) -> i64 {
        self as i64
    }
}

/// The integer coding of `ints` (before LZ4).
pub fn encode_ints<I: CodedInt>(ints: &[I]) -> Vec<u8> {
    if ints.is_empty() {
        return Vec::new();
    }
    let wide = I::BYTES == 8;
    // Differences wrap in the integer's own width, as in usd-core.
    let delta = |cur: i64, prev: i64| -> i64 {
        if wide {
            cur.wrapping_sub(prev)
        } else {
            (cur as i32).wrapping_sub(prev as i32) as i64
        }
    };
    // The most common difference; ties go to the largest value (usd-core's
    // rule, which only changes the bytes, never the decoded values).
    let mut counts: std::collections::HashMap<i64, usize> = std::collections::HashMap::new();
    let (mut common, mut common_count, mut prev) = (0i64, 0usize, 0i64);
    for v in ints {
        let d = delta(v.signed(), prev);
        prev = v.signed();
        let c = counts.entry(d).or_insert(0);
        *c += 1;
        if *c > common_count || (*c == common_count && d > common) {
            common = d;
            common_count = *c;
        }
    }
    let n = ints.len();
    let codes_len = (n * 2).div_ceil(8);
    let mut out = Vec::with_capacity(I::BYTES + codes_len + n * I::BYTES / 2);
    if wide {
        out.extend_from_slice(&common.to_le_bytes());
    } else {
        out.extend_from_slice(&(common as i32).to_le_bytes());
    }
    let codes_at = out.len();
    out.resize(codes_at + codes_len, 0);
    let mut prev = 0i64;
    for (i, v) in ints.iter().enumerate() {
        let d = delta(v.signed(), prev);
        prev = v.signed();
        let code: u8 = if d == common {
            0
        } else if wide {
            if i16::try_from(d).is_ok() {
                out.extend_from_slice(&(d as i16).to_le_bytes());
                1
            } else if i32::try_from(d).is_ok() {
                out.extend_from_slice(&(d as i32).to_le_bytes());
                2
            } else {
                out.extend_from_slice(&d.to_le_bytes());
                3
            }
        } else if i8::try_from(d).is_ok() {
            out.push(d as i8 as u8);
            1
        } else if i16::try_from(d).is_ok() {
            out.extend_from_slice(&(d as i16).to_le_bytes());
            2
        } else {
            out.extend_from_slice(&(d as i32).to_le_bytes());
            3
        };
        out[codes_at + i / 4] |= code << (2 * (i % 4));
    }
    out
}

/// Appends `ints` as usd-core stores a compressed integer list: the
/// compressed size (`u64`), then the LZ4-framed integer coding.
pub fn put_compressed_ints<I: CodedInt>(ints: &[I], out: &mut Vec<u8>) {
    put_compressed_coded(&encode_ints(ints), out);
}

/// Appends already-coded integers, LZ4-framed, after their compressed size.
pub fn put_compressed_coded(coded: &[u8], out: &mut Vec<u8>) {
    let size_at = out.len();
    out.extend_from_slice(&0u64.to_le_bytes());
    lz4_frame(coded, out);
    let size = (out.len() - size_at - 8) as u64;
    out[size_at..size_at + 8].copy_from_slice(&size.to_le_bytes());
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straightforward decoder written from the format description, so
    /// the encoder is checked against the layout rather than against itself.
    fn decode(bytes: &[u8], n: usize, wide: bool) -> Vec<i64> {
        let w = if wide { 8 } else { 4 };
        let common = if wide {
            i64::from_le_bytes(bytes[..8].try_into().unwrap())
        } else {
            i32::from_le_bytes(bytes[..4].try_into().unwrap()) as i64
        };
        let codes = &bytes[w..w + (n * 2).div_ceil(8)];
        let mut at = w + codes.len();
        let (mut prev, mut out) = (0i64, Vec::new());
        for i in 0..n {
            let code = (codes[i / 4] >> (2 * (i % 4))) & 3;
            let size = match (code, wide) {
                (0, _) => 0,
                (1, false) => 1,
                (2, false) | (1, true) => 2,
                (3, false) | (2, true) => 4,
                _ => 8,
            };
            let d = match size {
                0 => common,
                1 => bytes[at] as i8 as i64,
                2 => i16::from_le_bytes(bytes[at..at + 2].try_into().unwrap()) as i64,
                4 => i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as i64,
                _ => i64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()),
            };
            at += size;
            prev = if wide {
                prev.wrapping_add(d)
            } else {
                (prev as i32).wrapping_add(d as i32) as i64
            };
            out.push(prev);
        }
        assert_eq!(at, bytes.len(), "every coded byte is consumed");
        out
    }

    #[test]
    fn the_documented_example_codes_as_usd_core_describes() {
        // integerCoding.cpp's example: diffs [123, 1, 1, 100000, 0, 1, 0],
        // most common 1; codes 01 00 00 11 | 01 00 01; then int8(123),
        // int32(100000), int8(0), int8(0).
        let coded = encode_ints(&[123i32, 124, 125, 100125, 100125, 100126, 100126]);
        let mut expect = 1i32.to_le_bytes().to_vec();
        expect.push(0b11_00_00_01);
        expect.push(0b00_01_00_01);
        expect.push(123);
        expect.extend_from_slice(&100000i32.to_le_bytes());
        expect.extend_from_slice(&[0, 0]);
        assert_eq!(coded, expect);
    }

    /// usd-core's `Sdf_IntegerCompression` (integerCoding.cpp) picks the
    /// common difference online: a count that beats the best so far wins,
    /// and on an equal count the larger difference wins ("Take the largest
    /// common value in case of a tie"). The expected bytes are worked by
    /// hand from that rule: common (int32), 2-bit codes, int8 differences.
    #[test]
    fn ties_for_the_common_difference_go_to_the_larger_as_in_usd_core() {
        // Diffs 5, 1: both once; 5 came first and is larger: common 5,
        // codes 00 01, then int8(1).
        assert_eq!(encode_ints(&[5i32, 6]), [5, 0, 0, 0, 0b01_00, 1]);
        // Diffs 1, 5: both once; 5 ties 1 later and is larger: common 5,
        // codes 01 00, then int8(1).
        assert_eq!(encode_ints(&[1i32, 6]), [5, 0, 0, 0, 0b00_01, 1]);
        // Diffs 1, 1, 5: 5 (once) is larger but 1 (twice) is more common:
        // common 1, codes 00 00 01, then int8(5).
        assert_eq!(encode_ints(&[1i32, 2, 7]), [1, 0, 0, 0, 0b01_00_00, 5]);
    }

    #[test]
    fn round_trips_every_width_and_extreme() {
        let v32: Vec<i32> = vec![0, -1, i32::MAX, i32::MIN, 5, 5, 5, 300, -300, 70000, 1, 2, 3];
        assert_eq!(
            decode(&encode_ints(&v32), v32.len(), false),
            v32.iter().map(|&x| x as i64).collect::<Vec<_>>()
        );
        let u32s: Vec<u32> = vec![u32::MAX, 0, 7, u32::MAX - 1];
        let back = decode(&encode_ints(&u32s), u32s.len(), false);
        assert_eq!(back.iter().map(|&x| x as u32).collect::<Vec<_>>(), u32s);
        let v64: Vec<i64> = vec![i64::MIN, i64::MAX, 0, 40000, -40000, 1 << 40, 3, 3];
        assert_eq!(decode(&encode_ints(&v64), v64.len(), true), v64);
        let u64s: Vec<u64> = vec![u64::MAX, 1, 0];
        let back = decode(&encode_ints(&u64s), u64s.len(), true);
        assert_eq!(back.iter().map(|&x| x as u64).collect::<Vec<_>>(), u64s);
    }

    #[test]
    fn lz4_frame_is_one_chunk_marker_then_a_standard_block() {
        let data: Vec<u8> = (0..10_000u32).flat_map(|i| (i % 97).to_le_bytes()).collect();
        let mut out = Vec::new();
        lz4_frame(&data, &mut out);
        assert_eq!(out[0], 0);
        assert_eq!(lz4_flex::block::decompress(&out[1..], data.len()).unwrap(), data);
    }
}
