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
//! Time samples, dictionaries and reference list ops (each reference's
//! customData) are walked here too, with their other values decoded by
//! openusd. A field openusd reads wrong that the edit changed is refused
//! (the edit's value was made from the wrong reading), as is an unregistered
//! value (or list op) holding anything openusd reads wrong or drops.
//!
//! The walk trusts nothing in the file: every count is bounded by the bytes
//! left, every recursive offset must move forward, nesting is capped, and so
//! is the number of values one field may expand to.

use std::cell::Cell;
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

/// How many values one field may expand to here, at least: values may be
/// shared, so a few bytes can describe exponentially many. The limit is the
/// file's size in bytes when larger (a stored value takes at least 8, and
/// each is visited a few times).
const MAX_VALUES: usize = 1 << 22;

/// List op header bits (`SdfListOp`), in the order the lists are stored.
const LIST_OP_LISTS: [u8; 6] = [1 << 1, 1 << 2, 1 << 5, 1 << 6, 1 << 3, 1 << 4];

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
    /// Values visited for the current field ([`MAX_VALUES`]).
    visited: Cell<usize>,
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

    fn left(&self) -> u64 {
        (self.bytes.len() - self.pos) as u64
    }

    /// A count of items at least `each` bytes long, bounded by the bytes left.
    fn count(&mut self, each: u64, what: &str) -> Res<u64> {
        let n = self.u64()?;
        if n > self.left() / each {
            return Err(format!(
                "{what} of {n} items at offset {} is longer than the file",
                self.pos
            ));
        }
        Ok(n)
    }

    fn u64(&mut self) -> Res<u64> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().unwrap_or_default()))
    }

    fn u32(&mut self) -> Res<u32> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().unwrap_or_default()))
    }

    /// usd-core's recursive offset: an `i64` counted from where it starts,
    /// always forward, past itself (so a walk cannot loop).
    fn jump(&mut self) -> Res<()> {
        let start = self.pos;
        let delta = self.u64()? as i64;
        if delta < 8 {
            return Err(format!(
                "a recursive offset of {delta} bytes at offset {start} does not move forward"
            ));
        }
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
        Ok(CrateSource {
            file,
            specs,
            visited: Cell::new(0),
        })
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
        self.visited.set(0);
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
                // The file's value, unless the edit changed it: then the
                // edit's value was made from openusd's wrong reading.
                match self.file.value(bytemuck::cast(rep)) {
                    Ok(file_value) if same_value(&file_value, v) => self.keep(rep, 0).map(Some),
                    _ => Err(
                        "the file holds a value openusd 0.8 reads wrong (a negative int64, read \
                              zero-extended, or an unregistered value it drops part of), and the edit \
                              changes this field, so it would be written from the wrong reading"
                            .into(),
                    ),
                }
            }
        }
    }

    /// Counts one more value of the current field ([`MAX_VALUES`]) and
    /// checks the nesting.
    fn visit(&self, depth: usize) -> Res<()> {
        if depth > MAX_NESTING {
            return Err(format!("values nested more than {MAX_NESTING} deep"));
        }
        let n = self.visited.get() + 1;
        let most = MAX_VALUES.max(self.file.bytes().len());
        if n > most {
            return Err(format!("a value that expands to more than {most} values"));
        }
        self.visited.set(n);
        Ok(())
    }

    /// Whether openusd reads `rep` without an error but wrong: a negative
    /// inlined int64, also inside time samples, dictionaries, references'
    /// customData and unregistered values; or an unregistered list op item
    /// that is not a string (openusd drops it).
    fn misread(&self, rep: u64, depth: usize) -> Res<bool> {
        self.visit(depth)?;
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
            ty::DICTIONARY => self.any_misread(self.entries(rep)?.into_iter().map(|(_, r)| r), depth),
            ty::REFERENCE_LIST_OP => {
                let dicts = self.reference_dicts(rep)?;
                self.any_misread(dicts.into_iter().flatten().map(|(_, r)| r), depth)
            }
            ty::UNREGISTERED_VALUE => self.misread(self.unregistered(rep)?, depth + 1),
            ty::UNREGISTERED_VALUE_LIST_OP => {
                for r in self.unregistered_items(rep)? {
                    if kind(r) != ty::STRING || self.misread(r, depth + 1)? {
                        return Ok(true);
                    }
                }
                Ok(false)
            }
            _ => Ok(false),
        }
    }

    fn any_misread(&self, reps: impl IntoIterator<Item = u64>, depth: usize) -> Res<bool> {
        for r in reps {
            if self.misread(r, depth + 1)? {
                return Ok(true);
            }
        }
        Ok(false)
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
        self.visit(depth)?;
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
                Value::Dictionary(self.dictionary(self.entries(rep)?, depth)?)
            }
            ty::REFERENCE_LIST_OP if !is(rep, INLINED | ARRAY) => {
                // openusd's reading, with each reference's customData read here.
                let Ok(Value::ReferenceListOp(mut op)) = self.file.value(bytemuck::cast(rep)) else {
                    return Err("openusd 0.8 cannot read this reference list op".into());
                };
                let dicts = self.reference_dicts(rep)?;
                let items = [
                    &mut op.explicit_items,
                    &mut op.added_items,
                    &mut op.prepended_items,
                    &mut op.appended_items,
                    &mut op.deleted_items,
                    &mut op.ordered_items,
                ];
                let mut dicts = dicts.into_iter();
                for r in items.into_iter().flat_map(|v| v.iter_mut()) {
                    let entries = dicts.next().ok_or("a reference list op read with more references")?;
                    r.custom_data = self.dictionary(entries, depth)?;
                }
                if dicts.next().is_some() {
                    return Err("a reference list op read with fewer references".into());
                }
                Value::ReferenceListOp(op)
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

    /// A dictionary of `entries`, its values read by [`Self::nested`].
    fn dictionary(&self, entries: Vec<(String, u64)>, depth: usize) -> Res<HashMap<String, Value>> {
        let mut dict = HashMap::with_capacity(entries.len());
        for (key, r) in entries {
            dict.insert(key, self.nested(r, depth + 1)?);
        }
        Ok(dict)
    }

    /// The times rep and the value reps of a time-samples value.
    fn samples(&self, rep: u64) -> Res<(u64, Vec<u64>)> {
        let mut c = Cursor::at(self.file.bytes(), payload(rep))?;
        c.jump()?;
        let times = c.u64()?;
        c.jump()?;
        let n = c.count(8, "time samples")?;
        let raw = c.take(n * 8)?;
        Ok((
            times,
            raw.chunks_exact(8)
                .map(|b| u64::from_le_bytes(b.try_into().unwrap_or_default()))
                .collect(),
        ))
    }

    /// The keys and value reps of a dictionary.
    fn entries(&self, rep: u64) -> Res<Vec<(String, u64)>> {
        self.entries_at(&mut Cursor::at(self.file.bytes(), payload(rep))?)
    }

    /// The keys and value reps of the dictionary at `c`, leaving `c` past it.
    fn entries_at(&self, c: &mut Cursor<'_>) -> Res<Vec<(String, u64)>> {
        let f = &self.file;
        // An entry: a key, a recursive offset and a rep.
        let n = c.count(20, "a dictionary")?;
        let mut out = Vec::with_capacity(n as usize);
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

    /// Each reference's customData entries in a reference list op, in the
    /// order the lists are stored (explicit, added, prepended, appended,
    /// deleted, ordered): a header byte, then each list's count and
    /// references (an asset string, a path, a layer offset, customData).
    fn reference_dicts(&self, rep: u64) -> Res<Vec<Vec<(String, u64)>>> {
        self.list_op_items(rep, 4 + 4 + 16 + 8, "a reference list", |c| {
            c.take(4 + 4 + 16)?;
            self.entries_at(c)
        })
    }

    /// `item` read for every item of every list a list op at `rep` stores
    /// (a header byte naming the lists, then each list's count and items
    /// of at least `min_size` bytes).
    fn list_op_items<T>(
        &self,
        rep: u64,
        min_size: u64,
        what: &str,
        mut item: impl FnMut(&mut Cursor) -> Res<T>,
    ) -> Res<Vec<T>> {
        let mut c = Cursor::at(self.file.bytes(), payload(rep))?;
        let header = c.take(1)?[0];
        let mut out = Vec::new();
        for bit in LIST_OP_LISTS {
            if header & bit == 0 {
                continue;
            }
            for _ in 0..c.count(min_size, what)? {
                out.push(item(&mut c)?);
            }
        }
        Ok(out)
    }

    /// The rep an unregistered value wraps.
    fn unregistered(&self, rep: u64) -> Res<u64> {
        let mut c = Cursor::at(self.file.bytes(), payload(rep))?;
        c.jump()?;
        c.u64()
    }

    /// The reps of an unregistered list op's items, every list's.
    fn unregistered_items(&self, rep: u64) -> Res<Vec<u64>> {
        self.list_op_items(rep, 16, "an unregistered list", |c| {
            c.jump()?;
            c.u64()
        })
    }
}

/// Whether two values are the same, NaNs included (NaN != NaN), and
/// dictionaries compared key by key (their printed order is the hash's).
fn same_value(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Dictionary(x), Value::Dictionary(y))
        | (Value::UnregisteredDictionary(x), Value::UnregisteredDictionary(y)) => same_dict(x, y),
        (Value::TimeSamples(x), Value::TimeSamples(y)) => {
            x.len() == y.len()
                && x.iter()
                    .zip(y)
                    .all(|((t, v), (u, w))| t.to_bits() == u.to_bits() && same_value(v, w))
        }
        (Value::ReferenceListOp(x), Value::ReferenceListOp(y)) => {
            let lists = |o: &sdf::ListOp<sdf::Reference>| {
                [
                    o.explicit_items.clone(),
                    o.added_items.clone(),
                    o.prepended_items.clone(),
                    o.appended_items.clone(),
                    o.deleted_items.clone(),
                    o.ordered_items.clone(),
                ]
            };
            x.explicit == y.explicit
                && lists(x).iter().zip(lists(y).iter()).all(|(p, q)| {
                    p.len() == q.len()
                        && p.iter().zip(q).all(|(r, s)| {
                            let bare = |r: &sdf::Reference| sdf::Reference {
                                custom_data: HashMap::new(),
                                ..r.clone()
                            };
                            bare(r) == bare(s) && same_dict(&r.custom_data, &s.custom_data)
                        })
                })
        }
        _ => a == b || format!("{a:?}") == format!("{b:?}"),
    }
}

fn same_dict(x: &HashMap<String, Value>, y: &HashMap<String, Value>) -> bool {
    x.len() == y.len() && x.iter().all(|(k, v)| y.get(k).is_some_and(|w| same_value(v, w)))
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
        ty::REFERENCE_LIST_OP => "reference list op".into(),
        ty::UNREGISTERED_VALUE => "unregistered".into(),
        ty::UNREGISTERED_VALUE_LIST_OP => "unregistered list op".into(),
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

    /// `text` as painterly's writer writes it, with its stored int64s
    /// inlined as 32 bits the way usd-core writes small ones.
    fn usd_core_like(text: &str) -> CrateSource {
        let data =
            openusd::sdf::LayerRegistry::read_bytes(AssetBuffer::Owned(text.as_bytes().to_vec()), "t.usda").unwrap();
        let mut bytes = super::super::write_layer(&data, std::io::Cursor::new(Vec::new()))
            .unwrap()
            .into_inner();
        let mut inlined = 0;
        for i in 0..bytes.len() - 8 {
            let rep = u64::from_le_bytes(bytes[i..i + 8].try_into().unwrap());
            let at = payload(rep) as usize;
            if kind(rep) == ty::INT64 && rep >> 56 == 0 && at > 0 && at + 8 <= bytes.len() {
                let v = i64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
                if v == -5 {
                    let new = INLINED | (ty::INT64 as u64) << 48 | (v as i32 as u32) as u64;
                    bytes[i..i + 8].copy_from_slice(&new.to_le_bytes());
                    inlined += 1;
                }
            }
        }
        assert_eq!(inlined, 1, "test setup");
        CrateSource::open(AssetBuffer::Owned(bytes)).unwrap()
    }

    #[test]
    fn a_misread_field_is_kept_unless_changed_and_then_refused() {
        let src = usd_core_like(
            "#usda 1.0\n\ndef \"A\" (\n    customData = {\n        int64 n = -5\n        double d = nan\n    }\n)\n{\n}\n",
        );
        let a = sdf::Path::new("/A").unwrap();
        let rep = src.rep(&a, "customData").unwrap();
        assert!(src.misread(rep, 0).unwrap(), "test setup: -5 inlined as 32 bits");
        let read = src.file.value(bytemuck::cast(rep)).unwrap();
        // Unchanged (NaN and all): the file's value, -5 sign-extended.
        let Some(Kept::Value(Value::Dictionary(kept))) = src.correct(&a, "customData", Ok(Some(&read))).unwrap() else {
            panic!("not kept")
        };
        assert_eq!(kept.get("n"), Some(&Value::Int64(-5)));
        // Changed: made from openusd's wrong reading, so refused.
        let Value::Dictionary(mut changed) = read.clone() else {
            panic!()
        };
        changed.insert("added".into(), Value::Int(1));
        let err = src
            .correct(&a, "customData", Ok(Some(&Value::Dictionary(changed))))
            .unwrap_err();
        assert!(err.contains("the edit changes this field"), "{err}");
        // A field the file does not hold is the edit's.
        assert_eq!(src.correct(&a, "documentation", Ok(Some(&read))).unwrap(), None);
    }

    #[test]
    fn values_compare_with_nans_and_dictionaries_key_by_key() {
        let dict = |pairs: &[(&str, Value)]| {
            Value::Dictionary(pairs.iter().map(|(k, v)| (k.to_string(), v.clone())).collect())
        };
        let many: Vec<(&str, Value)> = ["a", "b", "c", "d", "e", "f", "g", "h"]
            .iter()
            .map(|&k| (k, Value::Double(f64::NAN)))
            .collect();
        let mut reversed = many.clone();
        reversed.reverse();
        assert!(same_value(&dict(&many), &dict(&reversed)));
        assert!(!same_value(
            &dict(&[("a", Value::Int64(-5))]),
            &dict(&[("a", Value::Int64(4294967291))])
        ));
        assert!(!same_value(
            &dict(&[("a", Value::Double(f64::NAN))]),
            &dict(&[("a", Value::Double(0.0))])
        ));
    }
}
