//! Writes a bake as its frames arrive (SPEC §7): a layer of `over` specs
//! whose attributes carry one time sample per baked frame.
//!
//! A bake declares its layout once (which attributes of which prims, which
//! relationships to block, the layer metadata), then hands over each frame's
//! arrays in time order. Writers keep only small per-sample bookkeeping, never
//! the frames themselves, so memory stays flat however long the shot:
//! `.usda` output spills each sample's text to a scratch file and assembles
//! the layer at the end; `.usdc` output writes each sample into the crate file
//! as it arrives ([`super::usdc::CrateStream`]) and the specs last. Either way
//! the output appears only when complete (temporary file, rename).

use std::fmt::Write as _;
use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use glam::Vec3;
use openusd::sdf::Value;

use super::atomic::TempFile;
use super::layer::{Format, OverLayer};
use super::spill::ColumnSpill;
use super::stage::{StageMetadata, StageReader};
use super::usdc::{CrateStream, Stored, ValueHandle};
use crate::error::{Error, Result};

/// One attribute the bake writes, sampled at every frame.
#[derive(Debug, Clone)]
pub struct BakeAttr {
    pub prim: String,
    pub name: &'static str,
    pub kind: SampleKind,
    /// Primvar `interpolation` metadata to author, if any.
    pub interpolation: Option<&'static str>,
}

/// The USD type of a baked attribute.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SampleKind {
    /// `point3f[]`
    Points,
    /// `float3[]` (extents)
    Extent,
    /// `float[]`
    Floats,
    /// `normal3f[]`
    Normals,
}

impl SampleKind {
    pub fn type_name(self) -> &'static str {
        match self {
            SampleKind::Points => "point3f[]",
            SampleKind::Extent => "float3[]",
            SampleKind::Floats => "float[]",
            SampleKind::Normals => "normal3f[]",
        }
    }
}

/// One frame's value of one attribute.
#[derive(Debug, Clone, PartialEq)]
pub enum Sample {
    Vec3s(Vec<Vec3>),
    Floats(Vec<f32>),
}

/// Where a bake came from, recorded in the layer's `customLayerData`
/// (`painterly` dictionary) so a render or a farm can tell which input and
/// frames it holds.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Provenance {
    /// The input's absolute path.
    pub input: String,
    /// The baked frames as `A:B:STEP`.
    pub frames: String,
    /// painterly's version.
    pub version: String,
    /// SHA-256 over the input's layers (chunked bakes: a chunk is reused only
    /// for the same input).
    pub input_hash: Option<String>,
    /// SHA-256 over the input's layer files' paths, sizes and modification
    /// times (every bake: render, view and preview tell a stale bake by it).
    pub input_stamp: Option<String>,
    /// The options that change what is baked besides the input and the
    /// frames, as the CLI spells them (`--bake-proxy --camera /Cam`); None
    /// without any. A chunk baked with other options is stale.
    pub options: Option<String>,
    /// Value-clip bakes: this chunk's index and the chunk count.
    pub chunk: Option<(usize, usize)>,
    /// Value-clip stages: frames per chunk and the chunk layers, in order.
    pub chunks: Option<(usize, Vec<String>)>,
}

/// Reads the provenance painterly recorded in a layer's
/// `customLayerData["painterly"]`; None when the layer has none (it was not
/// written by painterly). Only the layer itself is read, not what it
/// sublayers.
pub fn read_provenance(path: &Path) -> Result<Option<Provenance>> {
    Ok(provenance_of(&open_mapped_layer(path)?))
}

/// Checks that the bake layer `bake` was made from `input` (render, view
/// and preview show a bake over its input) and returns its provenance:
/// a bake of another input is refused; one whose input's layers changed
/// since (their `inputHash` or `inputStamp` differs from the recorded one) or that
/// carries no provenance adds a warning, and is shown. `opened` is the
/// input's stage when the caller has it open (else it is opened, and only
/// when the bake recorded a digest).
pub fn check_baked_from(
    input: &Path,
    opened: Option<&StageReader>,
    bake: &Path,
    warnings: &mut Vec<String>,
) -> Result<Option<Provenance>> {
    let Some(p) = read_provenance(bake)? else {
        warnings.push(format!(
            "{} has no painterly provenance (customLayerData[\"painterly\"]): cannot check it was baked from {}",
            bake.display(),
            input.display()
        ));
        return Ok(None);
    };
    if !super::stage::same_file(input, Path::new(&p.input)) {
        return Err(Error::msg(format!(
            "this bake was made from {}, not from the input {}: bake the input first (painterly bake {} -o LAYER)",
            p.input,
            input.display(),
            input.display()
        ))
        .in_file(bake));
    }
    // (A chunked bake, with its inputHash, is never of unsaved edits.)
    if p.input_stamp
        .as_deref()
        .is_some_and(|s| s.starts_with(super::clips::UNSAVED_STAMP))
    {
        warnings.push(format!(
            "{} was baked from unsaved edits of {} (a layer edited in memory), not from the file: strokes may not match it; save the layer and bake again ({})",
            bake.display(),
            input.display(),
            rebake_command(input, bake, &p)
        ));
        return Ok(Some(p));
    }
    let digest = |of: fn(&StageReader) -> Result<String>| match opened {
        Some(r) => of(r),
        None => of(&StageReader::open_mapped(input)?),
    };
    // A chunked bake's content hash when there is one, else the stamp.
    let changed = match (&p.input_hash, &p.input_stamp) {
        (Some(recorded), _) => Some(("inputHash", digest(super::clips::input_hash)? != *recorded)),
        (None, Some(recorded)) => Some(("inputStamp", digest(super::clips::input_stamp)? != *recorded)),
        (None, None) => None,
    };
    if let Some((field, true)) = changed {
        warnings.push(format!(
            "{} changed since this bake was made (its layers differ from the bake's {field}): strokes show the old bake; bake again ({})",
            input.display(),
            rebake_command(input, bake, &p)
        ));
    }
    Ok(Some(p))
}

/// The command that bakes `bake` again as it was made: its frames, its
/// chunks (a clip set re-baked without `--chunk` would become one file) and
/// its options.
fn rebake_command(input: &Path, bake: &Path, p: &Provenance) -> String {
    let mut cmd = format!("painterly bake {} -o {}", input.display(), bake.display());
    if !p.frames.is_empty() {
        let _ = write!(cmd, " --frames {}", p.frames);
    }
    if let Some((size, _)) = &p.chunks {
        let _ = write!(cmd, " --chunk {size}");
    }
    if let Some(o) = &p.options {
        let _ = write!(cmd, " {o}");
    }
    cmd
}

/// Opens one layer (not what it sublayers) over a read-only memory mapping
/// of its file, so that only the pages a read touches are loaded: reading a
/// chunk's provenance then costs kilobytes, not the chunk's hundreds of MB.
pub fn open_mapped_layer(path: &Path) -> Result<openusd::sdf::Layer> {
    use openusd::sdf;
    let p = path
        .to_str()
        .ok_or_else(|| Error::msg("path is not valid UTF-8").in_file(path))?;
    // Callers keep the layer only while they read from it.
    sdf::Layer::open_with(super::stage::mapped_resolver(), p)
        .map_err(|e| Error::msg(format!("cannot read layer: {e}")).in_file(path))
}

/// The provenance painterly recorded in `layer`, if any.
pub fn provenance_of(layer: &openusd::sdf::Layer) -> Option<Provenance> {
    use openusd::sdf;
    let data = layer
        .data()
        .get_field(&sdf::Path::abs_root(), "customLayerData")
        .ok()
        .map(|v| v.into_owned());
    let Some(Value::Dictionary(d)) = data else {
        return None;
    };
    let Some(Value::Dictionary(info)) = d.get("painterly") else {
        return None;
    };
    let text = |k: &str| match info.get(k) {
        Some(Value::String(s)) => Some(s.clone()),
        _ => None,
    };
    let int = |k: &str| match info.get(k) {
        Some(Value::Int(n)) => usize::try_from(*n).ok(),
        Some(Value::Int64(n)) => usize::try_from(*n).ok(),
        _ => None,
    };
    Some(Provenance {
        input: text("input").unwrap_or_default(),
        frames: text("frames").unwrap_or_default(),
        version: text("version").unwrap_or_default(),
        input_hash: text("inputHash"),
        input_stamp: text("inputStamp"),
        options: text("options"),
        chunk: int("chunkIndex").zip(int("chunkCount")),
        chunks: match (int("chunkSize"), info.get("chunks")) {
            (Some(size), Some(Value::StringVec(names))) => Some((size, names.clone())),
            _ => None,
        },
    })
}

impl Provenance {
    /// The baked frames as (first, last, step), when recorded.
    pub fn frame_range(&self) -> Option<(f64, f64, f64)> {
        let mut it = self.frames.split(':').map(|x| x.parse::<f64>());
        match (it.next(), it.next(), it.next()) {
            (Some(Ok(a)), Some(Ok(b)), Some(Ok(s))) => Some((a, b, s)),
            _ => None,
        }
    }
}

/// A `customLayerData` entry value.
#[derive(Debug, Clone, PartialEq)]
pub enum DataValue {
    Str(String),
    Int(i64),
    Strs(Vec<String>),
}

impl Provenance {
    /// The entries of the `painterly` dictionary, sorted by key.
    pub fn fields(&self) -> Vec<(&'static str, DataValue)> {
        let mut f = vec![
            ("frames", DataValue::Str(self.frames.clone())),
            ("input", DataValue::Str(self.input.clone())),
            ("version", DataValue::Str(self.version.clone())),
        ];
        if let Some(h) = &self.input_hash {
            f.push(("inputHash", DataValue::Str(h.clone())));
        }
        if let Some(h) = &self.input_stamp {
            f.push(("inputStamp", DataValue::Str(h.clone())));
        }
        if let Some(o) = &self.options {
            f.push(("options", DataValue::Str(o.clone())));
        }
        if let Some((index, count)) = self.chunk {
            f.push(("chunkIndex", DataValue::Int(index as i64)));
            f.push(("chunkCount", DataValue::Int(count as i64)));
        }
        if let Some((size, names)) = &self.chunks {
            f.push(("chunkSize", DataValue::Int(*size as i64)));
            f.push(("chunks", DataValue::Strs(names.clone())));
        }
        f.sort_by_key(|(k, _)| *k);
        f
    }
}

/// The layer-metadata block of a usda layer written by painterly: the
/// provenance, a doc string and the input's stage metadata.
pub fn usda_header(meta: &StageMetadata, provenance: &Provenance, doc: &str) -> String {
    let mut out = String::from("#usda 1.0\n(\n    customLayerData = {\n        dictionary painterly = {\n");
    for (key, v) in provenance.fields() {
        let _ = match v {
            DataValue::Str(s) => writeln!(out, "            string {key} = {}", quoted(&s)),
            DataValue::Int(i) => writeln!(out, "            int {key} = {i}"),
            DataValue::Strs(v) => writeln!(
                out,
                "            string[] {key} = [{}]",
                v.iter().map(|s| quoted(s)).collect::<Vec<_>>().join(", ")
            ),
        };
    }
    out.push_str("        }\n    }\n");
    let _ = writeln!(out, "    doc = {}", quoted(doc));
    for (key, v) in [
        ("endTimeCode", meta.end_time_code),
        ("framesPerSecond", meta.frames_per_second),
        ("metersPerUnit", meta.meters_per_unit),
        ("startTimeCode", meta.start_time_code),
        ("timeCodesPerSecond", meta.time_codes_per_second),
    ] {
        if let Some(v) = v {
            let _ = writeln!(out, "    {key} = {}", UsdaNumber(v));
        }
    }
    if let Some(up) = &meta.up_axis {
        let _ = writeln!(out, "    upAxis = {}", quoted(up));
    }
    out.push_str(")\n");
    out
}

/// Everything about a bake layer except its samples.
#[derive(Debug, Clone)]
pub struct BakeLayout {
    pub meta: StageMetadata,
    pub attrs: Vec<BakeAttr>,
    /// Prims whose `skel:skeleton` is blocked (baked skinned meshes).
    pub blocked_skeletons: Vec<String>,
    /// Attributes whose value is blocked: (prim, name, type), such as
    /// the input's `primvars:displayOpacity:indices`, which would re-index
    /// the per-curve opacity the bake writes.
    pub blocked_attrs: Vec<BlockedAttr>,
    pub provenance: Provenance,
}

/// An attribute the bake blocks (`= None`), see [`BakeLayout::blocked_attrs`].
#[derive(Debug, Clone, PartialEq)]
pub struct BlockedAttr {
    pub prim: String,
    pub name: &'static str,
    pub type_name: &'static str,
}

/// Receives a bake's frames in time order.
pub trait FrameSink: Send {
    /// One frame: a sample per declared attribute, in declaration order.
    fn write_frame(&mut self, time: f64, samples: Vec<Sample>) -> Result<()>;
    /// Writes what remains and puts the layer in place.
    fn finish(self: Box<Self>) -> Result<()>;
}

/// A sink writing `layout` to `path`, in the format its extension names.
pub fn create(path: &Path, layout: BakeLayout) -> Result<Box<dyn FrameSink>> {
    Ok(match Format::from_path(path)? {
        Format::Usda => Box::new(UsdaSink::new(path, layout)?),
        Format::Usdc => Box::new(UsdcSink::new(path, layout)?),
    })
}

/// `prim`'s blocked attributes, as usda lines at `pad`.
pub fn write_blocked_attrs(out: &mut dyn Write, layout: &BakeLayout, prim: &str, pad: &str) -> std::io::Result<()> {
    for b in layout.blocked_attrs.iter().filter(|b| b.prim == prim) {
        writeln!(out, "{pad}{} {} = None", b.type_name, b.name)?;
    }
    Ok(())
}

pub const DOC: &str = "Baked by painterly: over specs only; sublayer above the input.";

fn check_sample(attr: &BakeAttr, s: &Sample) -> Result<()> {
    let ok = matches!(
        (attr.kind, s),
        (
            SampleKind::Points | SampleKind::Extent | SampleKind::Normals,
            Sample::Vec3s(_)
        ) | (SampleKind::Floats, Sample::Floats(_))
    );
    if ok {
        Ok(())
    } else {
        Err(Error::attr(&attr.prim, attr.name, "internal: sample of the wrong kind"))
    }
}

/// Streams `.usdc`: each sample goes into a temporary crate file as it
/// arrives and only its handle is kept; `finish` adds the specs and tables,
/// then renames the file into place.
/// A written layer waiting under its temporary name: [`Staged::commit`]
/// renames it into place; dropped, it is removed. A chunked bake stages
/// every chunk and commits them only once all are written, so a stopped
/// re-bake leaves the clip set already published as it was.
pub struct Staged {
    tmp: TempFile,
    path: PathBuf,
}

impl Staged {
    /// Whether [`Self::commit`] could replace its target.
    pub fn check(&self) -> Result<()> {
        super::atomic::check_target(&self.path)
    }

    pub fn commit(self) -> Result<()> {
        self.tmp.persist(&self.path)
    }
}

pub struct UsdcSink {
    path: PathBuf,
    /// Registered with [`super::atomic`]: removed on failure and on signals.
    tmp: Option<TempFile>,
    layout: BakeLayout,
    stream: Option<CrateStream<BufWriter<File>>>,
    /// The frames written so far, shared by every attribute.
    times: Vec<f64>,
    /// Per attribute (a column, in declaration order): the handle of its
    /// value at each frame, spilled to disk a block of frames at a time.
    handles: ColumnSpill<u64>,
    /// One frame's handles (reused).
    row: Vec<u64>,
}

impl UsdcSink {
    /// A `.usdc` sink whose layer can also be staged ([`UsdcSink::finish_staged`]).
    pub fn new(path: &Path, layout: BakeLayout) -> Result<Self> {
        let (tmp, file) = TempFile::create(path, "")?;
        let n = layout.attrs.len();
        // Owned by the sink from here, so an error below removes the file.
        let mut sink = UsdcSink {
            path: path.to_path_buf(),
            tmp: Some(tmp),
            layout,
            stream: None,
            times: Vec::new(),
            handles: ColumnSpill::new(path, n),
            row: Vec::with_capacity(n),
        };
        sink.stream = Some(CrateStream::new(BufWriter::with_capacity(1 << 20, file)).map_err(|e| e.in_file(path))?);
        Ok(sink)
    }
}

impl FrameSink for UsdcSink {
    fn write_frame(&mut self, time: f64, samples: Vec<Sample>) -> Result<()> {
        let stream = self
            .stream
            .as_mut()
            .ok_or_else(|| Error::msg("internal: bake already finished"))?;
        self.row.clear();
        for (attr, s) in self.layout.attrs.iter().zip(samples) {
            check_sample(attr, &s)?;
            let value = match s {
                Sample::Vec3s(v) => Value::Vec3fVec(bytemuck::allocation::cast_vec(v)),
                Sample::Floats(v) => Value::FloatVec(v),
            };
            let handle = stream
                .write_value(&value)
                .map_err(|e| Error::attr(&attr.prim, attr.name, e.message).in_file(&self.path))?;
            self.row.push(handle.to_bits());
        }
        self.handles.push_row(&self.row)?;
        self.times.push(time);
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<()> {
        self.finish_staged()?.commit()
    }
}

impl UsdcSink {
    /// Writes the layer under its temporary name, not yet in place.
    pub fn finish_staged(mut self: Box<Self>) -> Result<Staged> {
        let path = self.path.clone();
        let mut stream = self
            .stream
            .take()
            .ok_or_else(|| Error::msg("internal: bake already finished"))?;
        let mut layer = OverLayer::new(self.layout.meta.clone());
        layer.set_provenance(&self.layout.provenance);
        let times: std::sync::Arc<[f64]> = std::mem::take(&mut self.times).into();
        for (column, attr) in self.layout.attrs.iter().enumerate() {
            let metadata = match attr.interpolation {
                Some(i) => vec![("interpolation", Value::Token(i.into()))],
                None => vec![],
            };
            layer.set_streamed_samples(&attr.prim, attr.name, attr.kind.type_name(), column, metadata);
        }
        for prim in &self.layout.blocked_skeletons {
            layer.block_relationship(prim, "skel:skeleton");
        }
        for b in &self.layout.blocked_attrs {
            layer.set_default(&b.prim, b.name, b.type_name, Value::ValueBlock);
        }
        // One attribute's handles in memory at a time.
        let handles = &self.handles;
        let mut samples = |column: usize| -> Result<Stored> {
            let values = handles
                .column(column)?
                .into_iter()
                .map(ValueHandle::from_bits)
                .collect();
            Ok(Stored {
                times: times.clone(),
                values,
            })
        };
        layer
            .write_to_stream(&mut stream, &mut samples)
            .map_err(|e| e.in_file(&path))?;
        let io = |e: std::io::Error| Error::msg(format!("cannot write output: {e}")).in_file(&path);
        // No fsync: the rename makes the write atomic for readers and for a
        // failed bake; durability across power loss is the filesystem's.
        let file = stream
            .finish()
            .map_err(|e| e.in_file(&path))?
            .into_inner()
            .map_err(|e| io(e.into_error()))?;
        drop(file);
        // A bake that fails (or is dropped) before the commit leaves no file.
        let tmp = self
            .tmp
            .take()
            .ok_or_else(|| Error::msg("internal: bake already finished"))?;
        Ok(Staged { tmp, path })
    }
}

/// Streams `.usda`: each sample's text goes to a scratch file as it arrives;
/// `finish` writes the layer, copying each attribute's samples in order.
struct UsdaSink {
    path: PathBuf,
    layout: BakeLayout,
    /// Registered with [`super::atomic`]: removed when dropped and on signals.
    _scratch_file: TempFile,
    scratch: BufWriter<File>,
    written: u64,
    /// Per attribute (a column): [offset, length] of each sample's text in
    /// the scratch file, spilled to disk a block of frames at a time.
    index: ColumnSpill<[u64; 2]>,
    row: Vec<[u64; 2]>,
    text: String,
}

impl UsdaSink {
    fn new(path: &Path, layout: BakeLayout) -> Result<Self> {
        let (scratch_file, file) = TempFile::create(path, ".samples")?;
        let n = layout.attrs.len();
        Ok(UsdaSink {
            path: path.to_path_buf(),
            layout,
            _scratch_file: scratch_file,
            scratch: BufWriter::with_capacity(1 << 20, file),
            written: 0,
            index: ColumnSpill::new(path, n),
            row: Vec::with_capacity(n),
            text: String::new(),
        })
    }

    fn io_error(&self, e: std::io::Error) -> Error {
        Error::msg(format!("cannot write output: {e}")).in_file(&self.path)
    }

    /// The finished layer, assembled into `out`.
    fn assemble(&mut self, out: &mut impl Write) -> std::io::Result<()> {
        self.scratch.flush()?;
        let file = self.scratch.get_mut();
        let head = usda_header(&self.layout.meta, &self.layout.provenance, DOC);
        out.write_all(head.as_bytes())?;

        // Prims in namespace order with their attributes; ancestors as bare overs.
        let tree = PrimTree::new(
            self.layout
                .attrs
                .iter()
                .map(|a| a.prim.as_str())
                .chain(self.layout.blocked_skeletons.iter().map(String::as_str))
                .chain(self.layout.blocked_attrs.iter().map(|b| b.prim.as_str())),
        );
        let mut copy_buf = Vec::new();
        let mut emit = |out: &mut dyn Write, prim: &str, depth: usize| -> std::io::Result<()> {
            let pad = "    ".repeat(depth + 1);
            for (i, attr) in self.layout.attrs.iter().enumerate().filter(|(_, a)| a.prim == prim) {
                let ty = attr.kind.type_name();
                if let Some(interp) = attr.interpolation {
                    writeln!(
                        out,
                        "{pad}{ty} {} (\n{pad}    interpolation = \"{interp}\"\n{pad})",
                        attr.name
                    )?;
                }
                writeln!(out, "{pad}{ty} {}.timeSamples = {{", attr.name)?;
                let column = self.index.column(i).map_err(|e| std::io::Error::other(e.to_string()))?;
                for [offset, len] in column {
                    copy_buf.resize(len as usize, 0);
                    file.seek(SeekFrom::Start(offset))?;
                    file.read_exact(&mut copy_buf)?;
                    out.write_all(&copy_buf)?;
                }
                writeln!(out, "{pad}}}")?;
            }
            if self.layout.blocked_skeletons.iter().any(|p| p == prim) {
                writeln!(out, "{pad}rel skel:skeleton = None")?;
            }
            write_blocked_attrs(out, &self.layout, prim, &pad)?;
            Ok(())
        };
        tree.write(out, &mut emit)?;
        file.seek(SeekFrom::End(0))?;
        Ok(())
    }
}

impl FrameSink for UsdaSink {
    fn write_frame(&mut self, time: f64, samples: Vec<Sample>) -> Result<()> {
        self.row.clear();
        for (i, s) in samples.iter().enumerate() {
            let attr = &self.layout.attrs[i];
            check_sample(attr, s)?;
            // Sample lines sit two levels inside their prim's block.
            let pad = "    ".repeat(attr.prim.matches('/').count() + 1);
            self.text.clear();
            let _ = write!(self.text, "{pad}{}: [", UsdaNumber(time));
            match s {
                Sample::Vec3s(v) => {
                    for (k, p) in v.iter().enumerate() {
                        let sep = if k == 0 { "" } else { ", " };
                        let _ = write!(self.text, "{sep}({}, {}, {})", p.x, p.y, p.z);
                    }
                }
                Sample::Floats(v) => {
                    for (k, x) in v.iter().enumerate() {
                        let sep = if k == 0 { "" } else { ", " };
                        let _ = write!(self.text, "{sep}{x}");
                    }
                }
            }
            self.text.push_str("],\n");
            let len = self.text.len() as u64;
            if let Err(e) = self.scratch.write_all(self.text.as_bytes()) {
                return Err(self.io_error(e));
            }
            self.row.push([self.written, len]);
            self.written += len;
        }
        self.index.push_row(&self.row)
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        let path = self.path.clone();
        crate::usd_io::layer::write_atomic_with(&path, |out| self.assemble(out))
    }
}

/// An f64 as usda writes it: integers without a fraction, others shortest.
pub struct UsdaNumber(pub f64);

impl std::fmt::Display for UsdaNumber {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)
    }
}

/// A usda string literal.
pub fn quoted(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// Prim paths as a tree, for writing nested `over` blocks.
pub struct PrimTree {
    /// Path → children names, in the order they were first declared.
    nodes: std::collections::HashMap<String, Vec<String>>,
}

impl PrimTree {
    pub fn new<'a>(paths: impl Iterator<Item = &'a str>) -> Self {
        let mut nodes: std::collections::HashMap<String, Vec<String>> = Default::default();
        let mut seen = std::collections::HashSet::new();
        for path in paths {
            let mut cur = path.to_string();
            while cur != "/" && seen.insert(cur.clone()) {
                let (parent, name) = match cur.rsplit_once('/') {
                    Some(("", name)) => ("/".to_string(), name.to_string()),
                    Some((parent, name)) => (parent.to_string(), name.to_string()),
                    None => break,
                };
                nodes.entry(parent.clone()).or_default().push(name);
                cur = parent;
            }
        }
        PrimTree { nodes }
    }

    /// Writes nested `over` blocks; `emit` writes each prim's contents.
    pub fn write(
        &self,
        out: &mut dyn Write,
        emit: &mut dyn FnMut(&mut dyn Write, &str, usize) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        self.write_with_meta(out, &mut |_| String::new(), emit)
    }

    /// Like [`PrimTree::write`]; `meta` gives each prim's metadata block
    /// (written after its name, e.g. ` (\n    clips = {...}\n)`), or "".
    pub fn write_with_meta(
        &self,
        out: &mut dyn Write,
        meta: &mut dyn FnMut(&str) -> String,
        emit: &mut dyn FnMut(&mut dyn Write, &str, usize) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        for name in self.nodes.get("/").map(Vec::as_slice).unwrap_or_default() {
            writeln!(out)?;
            self.write_prim(out, &format!("/{name}"), 0, meta, emit)?;
        }
        Ok(())
    }

    fn write_prim(
        &self,
        out: &mut dyn Write,
        path: &str,
        depth: usize,
        meta: &mut dyn FnMut(&str) -> String,
        emit: &mut dyn FnMut(&mut dyn Write, &str, usize) -> std::io::Result<()>,
    ) -> std::io::Result<()> {
        let pad = "    ".repeat(depth);
        let name = path.rsplit('/').next().unwrap_or_default();
        writeln!(out, "{pad}over \"{name}\"{}\n{pad}{{", meta(path))?;
        emit(out, path, depth)?;
        for (i, child) in self
            .nodes
            .get(path)
            .map(Vec::as_slice)
            .unwrap_or_default()
            .iter()
            .enumerate()
        {
            if i > 0 {
                writeln!(out)?;
            }
            self.write_prim(out, &format!("{path}/{child}"), depth + 1, meta, emit)?;
        }
        writeln!(out, "{pad}}}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch_dir(tag: &str) -> crate::test_dir::ScratchDir {
        crate::test_dir::ScratchDir::new(&format!("bake-layer-{tag}"))
    }

    fn attr(prim: &str, name: &'static str, kind: SampleKind, interpolation: Option<&'static str>) -> BakeAttr {
        BakeAttr {
            prim: prim.to_string(),
            name,
            kind,
            interpolation,
        }
    }

    /// Every field of the `painterly` dictionary, as a hand-written layer
    /// (another writer's) records it, comes back: strings, ints, the chunk list.
    #[test]
    fn read_provenance_reads_every_field() {
        let dir = scratch_dir("prov");
        let path = dir.join("stamped.usda");
        std::fs::write(
            &path,
            r#"#usda 1.0
(
    customLayerData = {
        dictionary painterly = {
            string chunks = "not read: chunks is a string[]"
            int chunkCount = 4
            int chunkIndex = 1
            int chunkSize = 12
            string frames = "2:10:2"
            string input = "/shots/a.usda"
            string inputHash = "abc123"
            string version = "9.8.7"
        }
    }
)
"#,
        )
        .unwrap();
        let p = read_provenance(&path).unwrap().unwrap();
        assert_eq!(p.input, "/shots/a.usda");
        assert_eq!(p.frames, "2:10:2");
        assert_eq!(p.version, "9.8.7");
        assert_eq!(p.input_hash.as_deref(), Some("abc123"));
        assert_eq!(p.chunk, Some((1, 4)));
        // `chunks` of the wrong type: no chunk list.
        assert_eq!(p.chunks, None);

        std::fs::write(
            &path,
            r#"#usda 1.0
(
    customLayerData = {
        dictionary painterly = {
            int64 chunkCount = 7
            int64 chunkIndex = 3
            int64 chunkSize = 5
            string[] chunks = ["c0.usdc", "c1.usdc"]
        }
    }
)
"#,
        )
        .unwrap();
        // int64 values count as well as int ones; absent strings are empty.
        let p = read_provenance(&path).unwrap().unwrap();
        assert_eq!(p.chunk, Some((3, 7)));
        assert_eq!(p.chunks, Some((5, vec!["c0.usdc".to_string(), "c1.usdc".to_string()])));
        assert_eq!((p.input.as_str(), p.frames.as_str(), p.input_hash), ("", "", None));

        // A layer painterly did not write has no provenance.
        std::fs::write(&path, "#usda 1.0\n").unwrap();
        assert_eq!(read_provenance(&path).unwrap(), None);
    }

    /// `A:B:STEP` gives (A, B, STEP); anything else gives None.
    #[test]
    fn frame_range_parses_first_last_step() {
        let range = |s: &str| {
            Provenance {
                frames: s.to_string(),
                ..Default::default()
            }
            .frame_range()
        };
        assert_eq!(range("2:10:0.5"), Some((2.0, 10.0, 0.5)));
        assert_eq!(range("-3:1:2"), Some((-3.0, 1.0, 2.0)));
        assert_eq!(range("1:3"), None);
        assert_eq!(range("1:x:1"), None);
        assert_eq!(range(""), None);
    }

    /// A sample whose kind does not match its attribute's type is an error
    /// in either format, not a layer with a wrongly typed value.
    #[test]
    fn a_sample_of_the_wrong_kind_is_refused() {
        let dir = scratch_dir("kind");
        for ext in ["usda", "usdc"] {
            let layout = BakeLayout {
                meta: StageMetadata::default(),
                attrs: vec![attr("/A", "widths", SampleKind::Floats, None)],
                blocked_skeletons: vec![],
                blocked_attrs: vec![],
                provenance: Provenance::default(),
            };
            let mut sink = create(&dir.join(format!("out.{ext}")), layout).unwrap();
            let err = sink.write_frame(1.0, vec![Sample::Vec3s(vec![Vec3::ONE])]).unwrap_err();
            assert!(err.to_string().contains("wrong kind"), "{ext}: {err}");
        }
    }

    /// The whole text of a small usda bake, written out by hand: an attribute
    /// on a root prim (with its interpolation), two children (a blank line
    /// between siblings only), sample lines two levels inside their prim,
    /// samples in frame order, the blocked skeleton and primvar indices only
    /// on /Root/B, the options in the provenance.
    #[test]
    fn usda_bake_text() {
        let dir = scratch_dir("text");
        let path = dir.join("bake.usda");
        let layout = BakeLayout {
            meta: StageMetadata {
                end_time_code: Some(2.0),
                up_axis: Some("Z".into()),
                ..Default::default()
            },
            attrs: vec![
                attr("/Root", "widths", SampleKind::Floats, Some("vertex")),
                attr("/Root/A", "points", SampleKind::Points, None),
                attr("/Root/B", "points", SampleKind::Points, None),
            ],
            blocked_skeletons: vec!["/Root/B".into()],
            blocked_attrs: vec![BlockedAttr {
                prim: "/Root/B".into(),
                name: "primvars:displayOpacity:indices",
                type_name: "int[]",
            }],
            provenance: Provenance {
                input: "/in.usda".into(),
                frames: "1:2:1".into(),
                version: "v".into(),
                options: Some("--bake-proxy".into()),
                ..Default::default()
            },
        };
        let mut sink = create(&path, layout).unwrap();
        let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        sink.write_frame(
            1.0,
            vec![
                Sample::Floats(vec![0.5, 2.0]),
                Sample::Vec3s(vec![v(1.0, 2.0, 3.0), v(4.0, 5.0, 6.0)]),
                Sample::Vec3s(vec![v(0.0, 0.0, 0.0)]),
            ],
        )
        .unwrap();
        sink.write_frame(
            2.5,
            vec![
                Sample::Floats(vec![1.0, 1.5, 3.0]),
                Sample::Vec3s(vec![v(-1.0, 0.25, 0.0)]),
                Sample::Vec3s(vec![v(7.0, 8.0, 9.0), v(1.0, 1.0, 1.0)]),
            ],
        )
        .unwrap();
        sink.finish().unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        let expected = r#"#usda 1.0
(
    customLayerData = {
        dictionary painterly = {
            string frames = "1:2:1"
            string input = "/in.usda"
            string options = "--bake-proxy"
            string version = "v"
        }
    }
    doc = "Baked by painterly: over specs only; sublayer above the input."
    endTimeCode = 2
    upAxis = "Z"
)

over "Root"
{
    float[] widths (
        interpolation = "vertex"
    )
    float[] widths.timeSamples = {
        1: [0.5, 2],
        2.5: [1, 1.5, 3],
    }
    over "A"
    {
        point3f[] points.timeSamples = {
            1: [(1, 2, 3), (4, 5, 6)],
            2.5: [(-1, 0.25, 0)],
        }
    }

    over "B"
    {
        point3f[] points.timeSamples = {
            1: [(0, 0, 0)],
            2.5: [(7, 8, 9), (1, 1, 1)],
        }
        rel skel:skeleton = None
        int[] primvars:displayOpacity:indices = None
    }
}
"#;
        assert_eq!(text, expected);
    }
}
