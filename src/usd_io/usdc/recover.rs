//! Values of a crate file that openusd 0.8's reader cannot decode, or
//! decodes wrong, read here from the file's own bytes so that an in-place
//! edit keeps them. Measured with usd-core 26.11's files:
//!
//! - `int64[]`/`uint64[]` arrays whose integer coding holds 64-bit
//!   differences: openusd sizes its decompression buffer for 32-bit ones
//!   ("provided output is too small for the decompressed data");
//! - empty `string[]`/`asset[]` arrays, stored as payload 0: openusd reads
//!   that as a file offset;
//! - negative `int64` scalars, inlined as 32 bits: openusd zero-extends them
//!   (-5 reads as 4294967291, with no error);
//! - types openusd does not know, kept as the file holds them: an
//!   `Sdf.AnimationBlock` (an inlined rep) and a spline (`Ts.Spline`: a
//!   size, the spline's binary data, then its per-knot custom data, which
//!   must be empty: its dictionaries refer to the file's string table and
//!   other offsets, so they are not copied, and such a field is refused).
//!
//! Time samples and dictionaries are walked here too, with their other
//! values decoded by openusd.

use std::collections::HashMap;

use openusd::ar::AssetBuffer;
use openusd::sdf::{self, Value};
use openusd::usdc::CrateFile;

use super::encode::ty;

const ARRAY: u64 = 1 << 63;
const INLINED: u64 = 1 << 62;
const COMPRESSED: u64 = 1 << 61;
const PAYLOAD_MASK: u64 = (1 << 48) - 1;

/// Crate type codes openusd 0.8 does not know (`crateDataTypes.h`).
pub const SPLINE: u8 = 59;
pub const ANIMATION_BLOCK: u8 = 60;

/// Arrays shorter than this are never compressed (usd-core's
/// `MinCompressedArraySize`).
const MIN_COMPRESSED: u64 = 16;

/// How deep dictionaries and time samples may nest here (openusd's limit).
const MAX_NESTING: usize = 32;

/// A value copied as the file holds it.
#[derive(Debug, Clone, PartialEq)]
pub struct RawValue {
    /// The rep; its payload is replaced by the new offset of `bytes` when
    /// they are not empty (an inlined value has none).
    pub rep: u64,
    pub bytes: Vec<u8>,
    /// The crate minor version the written file needs for it: the source
    /// file's, which usd-core chose for what it holds.
    pub minor: u8,
}

/// What to write for a field instead of openusd's reading of it.
#[derive(Debug, Clone, PartialEq)]
pub enum Kept {
    Value(Value),
    Raw(RawValue),
}

/// A crate file's specs and raw field reps, beside openusd's reading of it.
pub struct CrateSource {
    file: CrateFile,
    /// Each spec's first field-set slot.
    specs: HashMap<sdf::Path, usize>,
}

type Res<T> = Result<T, String>;

fn kind(rep: u64) -> u8 {
    (rep >> 48) as u8
}

fn payload(rep: u64) -> u64 {
    rep & PAYLOAD_MASK
}

fn is(rep: u64, flag: u64) -> bool {
    rep & flag != 0
}

/// A bounded cursor over the file's bytes.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn at(bytes: &'a [u8], pos: u64) -> Res<Self> {
        let pos = usize::try_from(pos)
            .ok()
            .filter(|&p| p <= bytes.len())
            .ok_or_else(|| format!("offset {pos} is past the end of the file"))?;
        Ok(Cursor { bytes, pos })
    }

    fn take(&mut self, n: u64) -> Res<&'a [u8]> {
        let end = usize::try_from(n)
            .ok()
            .and_then(|n| self.pos.checked_add(n))
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| format!("{n} bytes at offset {} run past the end of the file", self.pos))?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }

    fn u64(&mut self) -> Res<u64> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap_or_default()))
    }

    fn u32(&mut self) -> Res<u32> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap_or_default()))
    }

    /// usd-core's recursive offset: an `i64` counted from where it starts.
    fn jump(&mut self) -> Res<()> {
        let start = self.pos;
        let delta = self.u64()? as i64;
        let to = isize::try_from(delta)
            .ok()
            .and_then(|d| start.checked_add_signed(d))
            .ok_or_else(|| format!("a jump of {delta} bytes leaves the file"))?;
        *self = Cursor::at(self.bytes, to as u64)?;
        Ok(())
    }
}

impl CrateSource {
    pub fn open(bytes: AssetBuffer) -> Res<Self> {
        let file = CrateFile::open(bytes).map_err(|e| e.to_string())?;
        let mut specs = HashMap::with_capacity(file.specs.len());
        for s in &file.specs {
            let path = file.paths.get(s.path_index).ok_or("a spec names no path")?;
            specs.insert(path.clone(), s.fieldset_index);
        }
        Ok(CrateSource { file, specs })
    }

    fn minor(&self) -> u8 {
        self.file.version().minor
    }

    /// The rep of field `name` of the spec at `path`, as the file holds it.
    fn rep(&self, path: &sdf::Path, name: &str) -> Option<u64> {
        let start = *self.specs.get(path)?;
        let f = &self.file;
        f.fieldsets
            .get(start..)?
            .iter()
            .map_while(|slot| *slot)
            .filter_map(|i| f.fields.get(i))
            .find(|field| {
                let token = f.tokens.get(field.token_index).map(String::as_str);
                // The crate spells propertyChildren "properties".
                token == Some(name) || (name == "propertyChildren" && token == Some("properties"))
            })
            .map(|field| field.value_rep.0)
    }

    /// What to write for field `name` of `path` in place of `read`,
    /// openusd's reading of it: None when that reading is right, or when the
    /// field holds a value the edit authored (not the file's).
    pub fn correct(
        &self,
        path: &sdf::Path,
        name: &str,
        read: Result<Option<&Value>, &sdf::DataError>,
    ) -> Res<Option<Kept>> {
        let Some(rep) = self.rep(path, name) else {
            return Ok(None); // authored by the edit
        };
        match read {
            // Values the edit authors always read; a failure is the file's.
            Err(e) => {
                let why = std::error::Error::source(e).map_or_else(|| e.to_string(), |s| s.to_string());
                self.keep(rep, 0).map(Some).map_err(|e| format!("{e} (openusd: {why})"))
            }
            Ok(None) => Ok(None),
            Ok(Some(v)) => {
                if !self.misread(rep, 0)? {
                    return Ok(None);
                }
                // The file's value, unless the edit replaced it.
                match self.file.value(bytemuck::cast(rep)) {
                    Ok(file_value) if file_value == *v => self.keep(rep, 0).map(Some),
                    _ => Ok(None),
                }
            }
        }
    }

    /// Whether openusd reads `rep` without an error but wrong (a negative
    /// inlined int64, also inside time samples and dictionaries).
    fn misread(&self, rep: u64, depth: usize) -> Res<bool> {
        if depth > MAX_NESTING {
            return Err(format!("values nested more than {MAX_NESTING} deep"));
        }
        let t = kind(rep);
        if t == ty::INT64 && is(rep, INLINED) && !is(rep, ARRAY) {
            return Ok((payload(rep) as u32 as i32) < 0);
        }
        if is(rep, INLINED) || is(rep, ARRAY) {
            return Ok(false);
        }
        match t {
            ty::TIME_SAMPLES => {
                for r in self.samples(rep)?.1 {
                    if self.misread(r, depth + 1)? {
                        return Ok(true);
                    }
                }
                Ok(false)
            }
            ty::DICTIONARY => {
                for (_, r) in self.entries(rep)? {
                    if self.misread(r, depth + 1)? {
                        return Ok(true);
                    }
                }
                Ok(false)
            }
            _ => Ok(false),
        }
    }

    /// The value of `rep` read here, or openusd's reading when it is right.
    fn nested(&self, rep: u64, depth: usize) -> Res<Value> {
        if !self.misread(rep, depth)? {
            if let Ok(v) = self.file.value(bytemuck::cast(rep)) {
                return Ok(v);
            }
        }
        match self.keep(rep, depth)? {
            Kept::Value(v) => Ok(v),
            Kept::Raw(_) => Err(format!(
                "a {} inside time samples or a dictionary cannot be kept",
                type_name(kind(rep))
            )),
        }
    }

    /// `rep` read here: the cases in the module docs; anything else is
    /// refused with what it is.
    fn keep(&self, rep: u64, depth: usize) -> Res<Kept> {
        if depth > MAX_NESTING {
            return Err(format!("values nested more than {MAX_NESTING} deep"));
        }
        let t = kind(rep);
        let bytes: &[u8] = self.file.bytes();
        let value = match t {
            ty::INT64 if is(rep, INLINED) && !is(rep, ARRAY) => Value::Int64(payload(rep) as u32 as i32 as i64),
            ty::INT64 | ty::UINT64 if is(rep, ARRAY) => {
                let ints = self.int64_array(rep)?;
                if t == ty::INT64 {
                    Value::Int64Vec(ints)
                } else {
                    Value::Uint64Vec(ints.into_iter().map(|x| x as u64).collect())
                }
            }
            ty::STRING if is(rep, ARRAY) && payload(rep) == 0 => Value::StringVec(Vec::new()),
            ty::ASSET_PATH if is(rep, ARRAY) && payload(rep) == 0 => Value::AssetPathVec(Vec::new()),
            ty::TIME_SAMPLES if !is(rep, INLINED | ARRAY) => {
                let (times_rep, reps) = self.samples(rep)?;
                let times = match self.file.value(bytemuck::cast(times_rep)) {
                    Ok(Value::DoubleVec(t)) => t,
                    _ => return Err("time samples whose times cannot be read".into()),
                };
                if times.len() != reps.len() {
                    return Err("time samples with more times than values, or fewer".into());
                }
                let mut samples = Vec::with_capacity(times.len());
                for (time, r) in times.into_iter().zip(reps) {
                    samples.push((time, self.nested(r, depth + 1)?));
                }
                Value::TimeSamples(sdf::normalize_time_samples(samples))
            }
            ty::DICTIONARY if !is(rep, INLINED | ARRAY) => {
                let mut dict = HashMap::new();
                for (key, r) in self.entries(rep)? {
                    dict.insert(key, self.nested(r, depth + 1)?);
                }
                Value::Dictionary(dict)
            }
            ANIMATION_BLOCK if is(rep, INLINED) && !is(rep, ARRAY) => {
                return Ok(Kept::Raw(RawValue {
                    rep,
                    bytes: Vec::new(),
                    minor: self.minor(),
                }))
            }
            SPLINE if !is(rep, ARRAY) => {
                if is(rep, INLINED) {
                    return Ok(Kept::Raw(RawValue {
                        rep,
                        bytes: Vec::new(),
                        minor: self.minor(),
                    }));
                }
                let mut c = Cursor::at(bytes, payload(rep))?;
                let start = c.pos;
                let n = c.u64()?;
                c.take(n)?;
                if c.u64()? != 0 {
                    return Err("a spline whose knots hold custom data cannot be kept".into());
                }
                return Ok(Kept::Raw(RawValue {
                    rep: rep & !PAYLOAD_MASK,
                    bytes: bytes[start..c.pos].to_vec(),
                    minor: self.minor(),
                }));
            }
            _ => {
                return Err(format!(
                    "openusd 0.8 cannot read this {} value{}",
                    type_name(t),
                    if is(rep, ARRAY) { " array" } else { "" }
                ))
            }
        };
        Ok(Kept::Value(value))
    }

    /// An `int64[]`/`uint64[]` (as `i64`s): a count, then the values, or
    /// for compressed ones the compressed size and the LZ4-framed integer
    /// coding with 64-bit differences.
    fn int64_array(&self, rep: u64) -> Res<Vec<i64>> {
        if payload(rep) == 0 {
            return Ok(Vec::new());
        }
        if self.minor() < 7 {
            return Err("an int64 array in a crate file older than 0.7.0".into());
        }
        let mut c = Cursor::at(self.file.bytes(), payload(rep))?;
        let n = c.u64()?;
        if !is(rep, COMPRESSED) || n < MIN_COMPRESSED {
            let raw = c.take(n.checked_mul(8).ok_or("an array too long for the file")?)?;
            return Ok(raw
                .chunks_exact(8)
                .map(|b| i64::from_le_bytes(b.try_into().unwrap_or_default()))
                .collect());
        }
        let size = c.u64()?;
        let framed = c.take(size)?;
        let most = 8 + (n as usize).div_ceil(4) + 8 * n as usize;
        if most > framed.len().saturating_mul(255) + 64 {
            return Err("a compressed array longer than its data can hold".into());
        }
        let coded = unframe(framed, most)?;
        decode_ints64(&coded, n as usize)
    }

    /// The times rep and the value reps of a time-samples value.
    fn samples(&self, rep: u64) -> Res<(u64, Vec<u64>)> {
        let mut c = Cursor::at(self.file.bytes(), payload(rep))?;
        c.jump()?;
        let times = c.u64()?;
        c.jump()?;
        let n = c.u64()?;
        let raw = c.take(n.checked_mul(8).ok_or("too many time samples")?)?;
        Ok((
            times,
            raw.chunks_exact(8)
                .map(|b| u64::from_le_bytes(b.try_into().unwrap_or_default()))
                .collect(),
        ))
    }

    /// The keys and value reps of a dictionary.
    fn entries(&self, rep: u64) -> Res<Vec<(String, u64)>> {
        let f = &self.file;
        let mut c = Cursor::at(f.bytes(), payload(rep))?;
        let n = c.u64()?;
        let mut out = Vec::new();
        for _ in 0..n {
            let s = c.u32()? as usize;
            let key = f
                .strings
                .get(s)
                .and_then(|&t| f.tokens.get(t))
                .ok_or("a dictionary key outside the string table")?
                .clone();
            // A forward jump over the value's bytes to its rep; the next
            // entry follows the rep.
            c.jump()?;
            out.push((key, c.u64()?));
        }
        Ok(out)
    }
}

/// Undoes usd-core's LZ4 framing (`TfFastCompression`): a chunk count (0 is
/// one chunk without a size), else each chunk's `i32` size and block.
fn unframe(framed: &[u8], most: usize) -> Res<Vec<u8>> {
    let bad = |e: lz4_flex::block::DecompressError| format!("cannot decompress: {e}");
    let (&chunks, rest) = framed.split_first().ok_or("an empty compressed block")?;
    if chunks == 0 {
        return lz4_flex::block::decompress(rest, most).map_err(bad);
    }
    let mut out = Vec::new();
    let mut c = Cursor { bytes: rest, pos: 0 };
    for _ in 0..chunks {
        let size = c.u32()? as i32;
        let block = c.take(u64::try_from(size).map_err(|_| "a negative chunk size")?)?;
        out.extend(lz4_flex::block::decompress(block, most.saturating_sub(out.len())).map_err(bad)?);
    }
    Ok(out)
}

/// usd-core's integer coding with 64-bit differences (see `compress`): the
/// common difference, 2-bit codes, then 16/32/64-bit differences.
fn decode_ints64(coded: &[u8], n: usize) -> Res<Vec<i64>> {
    let mut c = Cursor { bytes: coded, pos: 0 };
    let common = c.u64()? as i64;
    let codes = c.take(n.div_ceil(4) as u64)?;
    let mut prev = 0i64;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let d = match (codes[i / 4] >> (2 * (i % 4))) & 3 {
            0 => common,
            1 => i16::from_le_bytes(c.take(2)?.try_into().unwrap_or_default()) as i64,
            2 => i32::from_le_bytes(c.take(4)?.try_into().unwrap_or_default()) as i64,
            _ => c.u64()? as i64,
        };
        prev = prev.wrapping_add(d);
        out.push(prev);
    }
    Ok(out)
}

/// A crate type's name, for messages.
fn type_name(t: u8) -> String {
    match t {
        SPLINE => "spline".into(),
        ANIMATION_BLOCK => "animation block".into(),
        ty::INT64 => "int64".into(),
        ty::UINT64 => "uint64".into(),
        ty::STRING => "string".into(),
        ty::ASSET_PATH => "asset".into(),
        ty::TIME_SAMPLES => "time samples".into(),
        ty::DICTIONARY => "dictionary".into(),
        other => format!("crate type {other}"),
    }
}

#[cfg(test)]
mod tests {
    use super::super::compress::{encode_ints, lz4_frame};
    use super::*;

    #[test]
    fn reads_back_64_bit_integer_coding_in_usd_cores_framing() {
        // Differences of every width, the ones openusd's buffer is too small for.
        let ints: Vec<i64> = (0..1040i64)
            .map(|i| match i % 4 {
                0 => i,
                1 => -(1 << 40) * i,
                2 => i64::MAX - i,
                _ => (i * 7919) % 300,
            })
            .collect();
        let mut framed = Vec::new();
        lz4_frame(&encode_ints(&ints), &mut framed);
        let most = 8 + ints.len().div_ceil(4) + 8 * ints.len();
        assert_eq!(
            decode_ints64(&unframe(&framed, most).unwrap(), ints.len()).unwrap(),
            ints
        );
        // Truncated data is an error, not a panic.
        assert!(decode_ints64(&encode_ints(&ints)[..100], ints.len()).is_err());
        assert!(unframe(&[], 10).is_err());
    }
}
