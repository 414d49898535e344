//! painterly's own crate (`.usdc`) writer.
//!
//! Why not openusd 0.8's `CrateWriter`: usd-core could not save its files in
//! place (issue 9 §1), it always wrote crate version 0.12.0, and it needs the
//! whole layer in memory (issue 10 §1). This writer
//!
//! - lays values out as usd-core's `crateFile.cpp` does, and keeps the
//!   tables usd-core's in-place (append) save relies on: it reads the file's
//!   tokens, paths, fields and field sets back as its dedup tables, then
//!   re-derives every path's element token and looks it up
//!   (`_GetIndexForToken`). openusd's writer left out the pseudo-root's
//!   element token (the empty token) and spelled target and relational
//!   attribute paths differently from usd-core, so that lookup failed and
//!   the half-written save damaged the file. Here the PATHS table holds
//!   every path with its complete ancestor chain, and the TOKENS table every
//!   element token ([`paths`]), with `";-)"` at index 0 as usd-core reserves
//!   it ([`tables`]);
//! - writes the lowest crate version the content needs;
//! - streams: values go into the file as they come, the tables at the end
//!   ([`CrateStream`]).
//!
//! # File layout
//!
//! An 88-byte bootstrap header (`PXR-USDC`, version, table-of-contents
//! offset), the values, then the sections TOKENS, STRINGS, FIELDS,
//! FIELDSETS, PATHS, SPECS and the table of contents. Values are described by
//! 8-byte reps ([`encode`]); arrays are 8-byte aligned, integer arrays and
//! integral or few-valued float arrays compressed ([`compress`]), and values
//! already written are referenced rather than written again ([`dedup`]).
//!
//! # Crate versions
//!
//! usd-core 26.11 writes 0.8.0 for new files and raises the version only for
//! content an older reader cannot decode. Measured by writing each value
//! type with usd-core on this machine and reading the header's bytes 8..11
//! (`Sdf.CrateInfo.Open(path).GetFileVersion()` agrees):
//!
//! | content | version |
//! |---|---|
//! | everything else: all scalar and array types, tokens, strings, asset paths, dictionaries, list ops of every kind, references, payloads (with or without layer offsets), payload list ops, variants, value blocks, time samples | 0.8.0 |
//! | `timecode`, `timecode[]` (also inside dictionaries and time samples) | 0.9.0 |
//! | `pathExpression`, `pathExpression[]` | 0.10.0 |
//! | layer `relocates` | 0.11.0 |
//! | splines (openusd holds no spline value; never written here) | 0.12.0 |
//!
//! A reader opens any file of its own major version and at most its own
//! minor version (usd-core 26.11's software version is 0.16.0).
//!
//! # Entry points
//!
//! - [`write_layer`] / [`write_layer_file`]: any layer openusd holds
//!   (`sdf::Data`, a crate layer read from disk and edited).
//! - [`CrateStream`]: values first, specs last, for bakes and clip chunks.

mod compress;
mod dedup;
mod encode;
mod paths;
mod recover;
mod stream;
mod tables;

#[cfg(test)]
mod tests;

use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::Path;

use openusd::sdf::{self, AbstractData};

pub use recover::CrateSource;
pub use stream::{CrateStream, Field, ValueHandle};

/// Time samples whose values a [`CrateStream`] stored: the times (shareable
/// between attributes) and a handle per time.
#[derive(Debug, Clone)]
pub struct Stored {
    pub times: std::sync::Arc<[f64]>,
    pub values: Vec<ValueHandle>,
}

use super::atomic::Publish;
use crate::error::{Error, Result};

/// Serialises a whole layer: every spec in path order, every field in the
/// layer's order. Values openusd read lazily are decoded one spec at a time.
pub fn write_layer<W: Write + Seek>(data: &dyn AbstractData, out: W) -> Result<W> {
    let mut stream = CrateStream::new(out)?;
    add_layer_specs(&mut stream, data, &mut |_| Ok(None))?;
    stream.finish()
}

/// Adds every spec of `data` to `stream`; an attribute for which `stored`
/// gives samples (written earlier with [`CrateStream::write_value`]) gets
/// them as its `timeSamples`, after its other fields. `stored` is asked once
/// per attribute, as its spec is written, so it can load the handles then.
pub fn add_layer_specs<W: Write + Seek>(
    stream: &mut CrateStream<W>,
    data: &dyn AbstractData,
    stored: &mut dyn FnMut(&sdf::Path) -> Result<Option<Stored>>,
) -> Result<()> {
    add_specs(stream, data, None, stored)
}

/// A field's value as it will be written.
enum Held<'d> {
    Value(std::borrow::Cow<'d, sdf::Value>),
    Raw(recover::RawValue),
}

/// [`add_layer_specs`]; with `source`, the crate file `data` was read from,
/// the values openusd cannot read (or reads wrong) are taken from it.
fn add_specs<W: Write + Seek>(
    stream: &mut CrateStream<W>,
    data: &dyn AbstractData,
    source: Option<&CrateSource>,
    stored: &mut dyn FnMut(&sdf::Path) -> Result<Option<Stored>>,
) -> Result<()> {
    for path in data.spec_paths() {
        let ty = data
            .spec_type(&path)
            .ok_or_else(|| Error::prim(&path, "the layer lists a spec it does not hold"))?;
        let names = data.list_fields(&path).unwrap_or_default();
        let mut values = Vec::with_capacity(names.len());
        for name in &names {
            let read = data.try_field(&path, name);
            let kept = match source {
                Some(src) => src
                    .correct(&path, name, read.as_ref().map(|v| v.as_deref()))
                    .map_err(|e| Error::prim(&path, format!("cannot keep field `{name}`: {e}")))?,
                None => None,
            };
            let held = match kept {
                Some(recover::Kept::Value(v)) => Held::Value(std::borrow::Cow::Owned(v)),
                Some(recover::Kept::Raw(r)) => Held::Raw(r),
                None => match read.map_err(|e| Error::prim(&path, format!("cannot read field `{name}`: {e}")))? {
                    Some(v) => Held::Value(v),
                    None => continue,
                },
            };
            values.push((name.as_str(), held));
        }
        let mut fields: Vec<(&str, Field<'_>)> = values
            .iter()
            .map(|(n, v)| {
                let f = match v {
                    Held::Value(v) => Field::Value(v.as_ref()),
                    Held::Raw(r) => Field::Raw(r),
                };
                (*n, f)
            })
            .collect();
        let samples = stored(&path)?;
        if let Some(s) = &samples {
            fields.push((
                "timeSamples",
                Field::TimeSamples {
                    times: &s.times,
                    values: &s.values,
                },
            ));
        }
        stream.add_spec(&path, ty, &fields)?;
    }
    Ok(())
}

/// [`write_layer`] into `path`, atomically (a buffered temporary file beside
/// it, then a rename).
pub fn write_layer_file(path: &Path, data: &dyn AbstractData) -> Result<()> {
    write_layer_file_as(path, data, Publish::Replace)
}

/// [`write_layer_file`], taking `path`'s place as `publish` says.
pub fn write_layer_file_as(path: &Path, data: &dyn AbstractData, publish: Publish) -> Result<()> {
    write_atomically(path, publish, |out| write_layer(data, out).map(|_| ()))
}

/// [`write_layer_file`] of `data` read from the crate file `source` and
/// edited: values openusd 0.8 cannot read, or reads wrong, are kept as
/// `source` holds them ([`recover`]); one that cannot be kept is refused
/// naming its spec and field, and nothing is written.
pub fn write_edited_layer_file(
    path: &Path,
    data: &dyn AbstractData,
    source: &CrateSource,
    publish: Publish,
) -> Result<()> {
    write_atomically(path, publish, |out| {
        let mut stream = CrateStream::new(out)?;
        add_specs(&mut stream, data, Some(source), &mut |_| Ok(None))?;
        stream.finish().map(|_| ())
    })
}

/// Runs `write` on a buffered temporary file that becomes `path` only if it
/// succeeds ([`super::atomic::write_atomic_with`]), keeping `write`'s own
/// error (which names the spec and field) rather than an I/O one.
pub fn write_atomically(
    path: &Path,
    publish: Publish,
    write: impl FnOnce(&mut BufWriter<File>) -> Result<()>,
) -> Result<()> {
    super::atomic::write_atomic_as(path, publish, write)
}
