//! [`CrateStream`]: writes a crate file front to back with flat memory.
//!
//! Values go into the file as they are handed over (`write_value`, and the
//! fields of each `add_spec`); only the small tables stay in memory (tokens,
//! strings, paths, fields, field sets, specs, and the dedup fingerprints).
//! `finish` writes the six structural sections, the table of contents, and
//! last the bootstrap header at offset 0, whose placeholder `new` wrote.

use std::io::{Seek, SeekFrom, Write};
use std::sync::atomic::{AtomicU64, Ordering};

use openusd::sdf::{self, SpecType, Value};

use super::encode::{Buf, Encoder};
use super::tables::Specs;
use crate::error::{Error, Result};

/// Size of the bootstrap header: magic, version, TOC offset, 8 reserved words.
const BOOTSTRAP_LEN: usize = 88;

/// Numbers streams, so a handle from one is (almost always) refused by
/// another.
static NEXT_STREAM: AtomicU64 = AtomicU64::new(0);

/// Bits 56..59 of a rep, which the crate format leaves unused: a handle
/// carries its stream's tag there (1..=15), cleared before it is stored.
const TAG_SHIFT: u32 = 56;
const TAG_MASK: u64 = 0xF << TAG_SHIFT;

/// A value already in the file: what a time sample refers to. Eight bytes,
/// `Copy`; valid only for the stream that returned it (a handle from another
/// stream is refused unless the two streams' 4-bit tags collide, 1 in 15).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ValueHandle(u64);

impl ValueHandle {
    /// The handle as a plain word, to keep it outside memory (a scratch file).
    pub fn to_bits(self) -> u64 {
        self.0
    }

    /// A handle back from [`to_bits`](Self::to_bits); a word that was not a
    /// handle of the stream it is given to is refused there.
    pub fn from_bits(bits: u64) -> Self {
        ValueHandle(bits)
    }
}

/// One field of a spec.
#[derive(Debug, Clone, Copy)]
pub enum Field<'a> {
    /// Any value, time samples included (`Value::TimeSamples`).
    Value(&'a Value),
    /// Time samples whose values were written with
    /// [`CrateStream::write_value`]: `values[i]` at `times[i]`, times
    /// increasing. Attributes sampled at the same times can share one slice.
    TimeSamples {
        times: &'a [f64],
        values: &'a [ValueHandle],
    },
    /// A value copied as another crate file stored it (one openusd cannot
    /// hold, see [`super::recover`]).
    Raw(&'a super::recover::RawValue),
}

/// A crate file being written. See the module docs of [`super`].
pub struct CrateStream<W: Write + Seek> {
    out: W,
    /// Bytes written so far (the file offset of the next byte).
    pos: u64,
    enc: Encoder,
    specs: Specs,
    /// This stream's handle tag (1..=15).
    tag: u64,
    /// Reused encoding buffer.
    scratch: Vec<u8>,
    /// Set by a failed write: the file's offsets can no longer be trusted.
    broken: bool,
}

impl<W: Write + Seek> CrateStream<W> {
    /// Starts a crate file at the beginning of `out`, which must be at
    /// position 0 (crate offsets are from the start of the file).
    pub fn new(mut out: W) -> Result<Self> {
        let at = out.stream_position().map_err(io_error)?;
        if at != 0 {
            return Err(Error::msg(format!(
                "a crate file must start at offset 0 of its output (this one is at {at})"
            )));
        }
        out.write_all(&[0u8; BOOTSTRAP_LEN]).map_err(io_error)?;
        Ok(CrateStream {
            out,
            pos: BOOTSTRAP_LEN as u64,
            enc: Encoder::new(),
            specs: Specs::default(),
            tag: NEXT_STREAM.fetch_add(1, Ordering::Relaxed) % 15 + 1,
            scratch: Vec::new(),
            broken: false,
        })
    }

    /// Writes `v` into the file now (unless an identical value already is)
    /// and returns its handle, for [`Field::TimeSamples`]. Small scalars are
    /// held in the handle and write nothing.
    pub fn write_value(&mut self, v: &Value) -> Result<ValueHandle> {
        self.check()?;
        let mut buf = self.buf();
        let rep = self.enc.value(&mut buf, v);
        self.flush(buf)?;
        let rep = rep.map_err(|e| Error::msg(format!("cannot write a {} value: {e}", kind(v))))?;
        Ok(ValueHandle(rep | self.tag << TAG_SHIFT))
    }

    /// Declares the spec at `path` with its fields (in order). Field values
    /// are written now; the spec itself is kept (a few words) for
    /// [`finish`](Self::finish). `propertyChildren` is stored under the
    /// crate's name for it, `properties`.
    pub fn add_spec(&mut self, path: &sdf::Path, ty: SpecType, fields: &[(&str, Field<'_>)]) -> Result<()> {
        self.check()?;
        if ty == SpecType::Unknown {
            return Err(Error::prim(path, "a spec of unknown type cannot be written"));
        }
        if path.is_empty() {
            return Err(Error::msg("a spec needs a path (the empty path was given)"));
        }
        let slot = self
            .enc
            .paths
            .intern(path.as_str(), &mut self.enc.tokens)
            .map_err(|e| Error::prim(path, format!("cannot write spec: {e}")))?;
        let mut field_indexes = Vec::with_capacity(fields.len());
        let mut buf = self.buf();
        let mut failure = None;
        for (i, (name, field)) in fields.iter().enumerate() {
            if fields[..i].iter().any(|(other, _)| other == name) {
                failure = Some(Error::prim(path, format!("field `{name}` given twice")));
                break;
            }
            let rep = match field {
                Field::Value(v) => self.enc.field(&mut buf, name, v),
                Field::TimeSamples { times, values } => self.handle_samples(&mut buf, times, values),
                Field::Raw(v) => self.enc.raw(&mut buf, v),
            };
            match rep {
                Ok(rep) => {
                    let stored_name = if *name == sdf::ChildrenKey::PropertyChildren.as_str() {
                        "properties"
                    } else {
                        name
                    };
                    let token = self.enc.tokens.intern(stored_name);
                    field_indexes.push(self.specs.field(token, rep));
                }
                Err(e) => {
                    failure = Some(Error::prim(path, format!("cannot write field `{name}`: {e}")));
                    break;
                }
            }
        }
        self.flush(buf)?;
        if let Some(e) = failure {
            return Err(e);
        }
        if !self.specs.spec(slot, ty as u32, field_indexes) {
            return Err(Error::prim(path, "two specs at one path"));
        }
        Ok(())
    }

    fn handle_samples(
        &mut self,
        buf: &mut Buf,
        times: &[f64],
        values: &[ValueHandle],
    ) -> std::result::Result<u64, String> {
        if times.len() != values.len() {
            return Err(format!("{} sample times for {} values", times.len(), values.len()));
        }
        if let Some(w) = times.windows(2).find(|w| sdf::compare_sample_times(w[0], w[1]).is_ge()) {
            return Err(format!(
                "sample times out of order or repeated ({} then {})",
                w[0], w[1]
            ));
        }
        let mut reps = Vec::with_capacity(values.len());
        for h in values {
            if h.0 & TAG_MASK != self.tag << TAG_SHIFT {
                return Err("a value handle from another crate stream".into());
            }
            reps.push(h.0 & !TAG_MASK);
        }
        self.enc.time_samples(buf, times, &reps)
    }

    /// Writes the structural sections, the table of contents and the
    /// bootstrap header (with the lowest crate version the content needs),
    /// and returns the output, flushed.
    pub fn finish(mut self) -> Result<W> {
        self.check()?;
        let mut sections: Vec<(&str, u64, u64)> = Vec::new();
        let mut body = Vec::new();
        let mut section = |name: &'static str, body: &mut Vec<u8>, write: &mut dyn FnMut(&mut Vec<u8>)| {
            let start = body.len();
            write(body);
            sections.push((name, start as u64, (body.len() - start) as u64));
        };
        let enc = &mut self.enc;
        section("TOKENS", &mut body, &mut |b| enc.tokens.write_section(b));
        section("STRINGS", &mut body, &mut |b| enc.strings.write_section(b));
        section("FIELDS", &mut body, &mut |b| self.specs.write_fields(b));
        section("FIELDSETS", &mut body, &mut |b| self.specs.write_fieldsets(b));
        section("PATHS", &mut body, &mut |b| enc.paths.write_section(b));
        section("SPECS", &mut body, &mut |b| self.specs.write_specs(b));
        let toc_offset = self.pos + body.len() as u64;
        body.extend_from_slice(&(sections.len() as u64).to_le_bytes());
        for (name, start, size) in &sections {
            let mut n = [0u8; 16];
            n[..name.len()].copy_from_slice(name.as_bytes());
            body.extend_from_slice(&n);
            body.extend_from_slice(&(self.pos + start).to_le_bytes());
            body.extend_from_slice(&size.to_le_bytes());
        }
        self.out.write_all(&body).map_err(io_error)?;
        let mut boot = [0u8; BOOTSTRAP_LEN];
        boot[..8].copy_from_slice(b"PXR-USDC");
        boot[8..11].copy_from_slice(&[0, self.enc.minor, 0]);
        boot[16..24].copy_from_slice(&toc_offset.to_le_bytes());
        self.out.seek(SeekFrom::Start(0)).map_err(io_error)?;
        self.out.write_all(&boot).map_err(io_error)?;
        self.out.seek(SeekFrom::End(0)).map_err(io_error)?;
        self.out.flush().map_err(io_error)?;
        Ok(self.out)
    }

    /// The crate version the content written so far needs, as
    /// `(major, minor, patch)`.
    pub fn version(&self) -> (u8, u8, u8) {
        (0, self.enc.minor, 0)
    }

    #[cfg(test)]
    pub(super) fn tag(&self) -> u64 {
        self.tag
    }

    fn buf(&mut self) -> Buf {
        let mut bytes = std::mem::take(&mut self.scratch);
        bytes.clear();
        Buf { base: self.pos, bytes }
    }

    fn check(&self) -> Result<()> {
        if self.broken {
            return Err(Error::msg(
                "cannot write output: an earlier write to this crate file failed",
            ));
        }
        Ok(())
    }

    /// Writes what `buf` holds; keeps its allocation unless it grew large.
    fn flush(&mut self, buf: Buf) -> Result<()> {
        if let Err(e) = self.out.write_all(&buf.bytes) {
            self.broken = true;
            return Err(io_error(e));
        }
        self.pos += buf.bytes.len() as u64;
        if buf.bytes.capacity() <= 1 << 24 {
            self.scratch = buf.bytes;
        }
        Ok(())
    }
}

fn io_error(e: std::io::Error) -> Error {
    Error::msg(format!("cannot write output: {e}"))
}

fn kind(v: &Value) -> &'static str {
    v.into()
}
