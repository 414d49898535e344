//! Long bakes as USD value clips: the shot split into chunk layers of N
//! frames, composed by a small clip-set layer.
//!
//! `painterly bake IN -o shot.usda --chunk N` writes
//! - `shot.clips/shot.0000.1-10.usdc`, … : each chunk exactly what
//!   `painterly bake --frames` writes for its frames (names sort by chunk
//!   index and say their first and last frame);
//! - `shot.clips/shot.manifest.usda`: the attributes the clips provide;
//! - `shot.usda`: layer metadata as for a single-file bake, the attribute
//!   declarations (types, primvar interpolation, blocked `skel:skeleton`),
//!   and on every root prim a `painterly` clip set with explicit
//!   `assetPaths`, `active` and `times` (identity mapping). Template clips
//!   assume one file per frame, so they are not used.
//!
//! USD interpolates between the last sample of one clip and the first of the
//! next (the `times` pairs mark each clip's first and last frame), so the
//! clip set composes to the single-file bake at every time, fractional times
//! across chunk boundaries included.

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};

use super::bake_layer::{
    self, quoted, read_provenance, usda_header, BakeLayout, FrameSink, PrimTree, Provenance, Sample, Staged,
    UsdaNumber, UsdcSink,
};
use super::layer::write_atomic_with;
use super::stage::StageReader;
use crate::error::{Error, Result};

/// The clip set's name in `clips`/`clipSets`.
pub const CLIP_SET: &str = "painterly";

/// One chunk of a clip-set bake.
#[derive(Debug, Clone, PartialEq)]
pub struct Chunk {
    pub index: usize,
    /// Indices into the bake's frame list: `start..end`.
    pub start: usize,
    pub end: usize,
    /// File name inside the clips folder.
    pub name: String,
}

/// The chunks of a clip-set bake written to `output`.
#[derive(Debug, Clone)]
pub struct ClipPlan {
    pub output: PathBuf,
    pub dir: PathBuf,
    pub chunk_size: usize,
    pub chunks: Vec<Chunk>,
}

/// The stem of a clip-set layer's name and its clips folder, `<stem>.clips`.
fn clips_dir(output: &Path) -> Result<(String, PathBuf)> {
    let stem = output
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .ok_or_else(|| Error::msg("output path has no file name").in_file(output))?;
    // The clip set names its chunks `@./<stem>.clips/...@`.
    super::layer::check_asset_path(&stem, output)?;
    let dir = output.with_file_name(format!("{stem}.clips"));
    Ok((stem, dir))
}

/// Where a chunked bake into `output` caches its binding:
/// `<stem>.clips/<stem>.binding.usdc` (see [`super::binding_cache`]).
pub fn binding_cache_path(output: &Path) -> Result<PathBuf> {
    let (stem, dir) = clips_dir(output)?;
    Ok(dir.join(format!("{stem}.binding.usdc")))
}

/// The longest file name (bytes) the usual file systems take (ext4, xfs, tmpfs).
const NAME_MAX: usize = 255;

impl ClipPlan {
    /// Splits `times` into chunks of `chunk_size` frames for `output`.
    pub fn new(output: &Path, times: &[f64], chunk_size: usize) -> Result<ClipPlan> {
        if chunk_size == 0 {
            return Err(Error::usage("--chunk must be at least 1"));
        }
        let (stem, dir) = clips_dir(output)?;
        let count = times.len().div_ceil(chunk_size);
        let width = (count.saturating_sub(1)).to_string().len().max(4);
        let chunks = (0..count)
            .map(|index| {
                let start = index * chunk_size;
                let end = (start + chunk_size).min(times.len());
                Chunk {
                    index,
                    start,
                    end,
                    name: format!(
                        "{stem}.{index:0width$}.{}-{}.usdc",
                        UsdaNumber(times[start]),
                        UsdaNumber(times[end - 1])
                    ),
                }
            })
            .collect::<Vec<Chunk>>();
        // A name the file system refuses would fail at the last rename, with
        // earlier chunks already published: refused before anything is written.
        if let Some(long) = chunks
            .iter()
            .map(|c| &c.name)
            .max_by_key(|n| n.len())
            .filter(|n| n.len() > NAME_MAX)
        {
            return Err(Error::msg(format!(
                "its chunks' file names would be up to {} bytes ({long}), over the {NAME_MAX} a file name may have: \
                 shorten the output's name (or give --frames simpler times)",
                long.len()
            ))
            .in_file(output));
        }
        Ok(ClipPlan {
            output: output.to_path_buf(),
            dir,
            chunk_size,
            chunks,
        })
    }

    /// A chunk's layer path.
    pub fn chunk_path(&self, chunk: &Chunk) -> PathBuf {
        self.dir.join(&chunk.name)
    }

    /// Refuses a clip set that could not be written (its manifest or layer
    /// a folder, protected, or read-only).
    pub fn check_clip_set_targets(&self) -> Result<()> {
        super::atomic::check_target(&self.manifest_path())?;
        super::atomic::check_target(&self.output)
    }

    /// The manifest layer's path.
    pub fn manifest_path(&self) -> PathBuf {
        let stem = self.output.file_stem().unwrap_or_default().to_string_lossy();
        self.dir.join(format!("{stem}.manifest.usda"))
    }

    /// Relative path (from the clip-set layer's folder) of a file in the clips folder.
    fn asset(&self, name: &str) -> String {
        let dir = self.dir.file_name().unwrap_or_default().to_string_lossy();
        format!("./{dir}/{name}")
    }

    /// Creates the clips folder.
    pub fn create_dir(&self) -> Result<()> {
        std::fs::create_dir_all(&self.dir)
            .map_err(|e| Error::msg(format!("cannot create the clips folder: {e}")).in_file(&self.dir))
    }
}

/// An advisory lock on a shot's clips folder, held while a process writes
/// there (`flock` on `<stem>.clips/<stem>.lock`): a whole chunked bake and
/// an assembly hold it alone, farm tasks (one chunk each) together. Two
/// local bakes into one output mixed their inputs' chunks under one clip
/// set. `flock` is per machine: tasks on several nodes are kept apart by
/// the farm (one task per chunk) and checked by the assembly.
pub struct ClipsLock {
    _file: std::fs::File,
}

/// Takes the lock of `plan`'s clips folder (which must exist) without
/// waiting: `exclusive` for a whole bake or an assembly, shared for one
/// chunk's task; fails naming the folder when another holds it.
pub fn lock_clips(plan: &ClipPlan, exclusive: bool) -> Result<ClipsLock> {
    use std::os::fd::AsRawFd;
    let stem = plan.output.file_stem().unwrap_or_default().to_string_lossy();
    let path = plan.dir.join(format!("{stem}.lock"));
    use std::os::unix::fs::OpenOptionsExt;
    // Never waits on a FIFO put there.
    let file = super::regular::regular_only(
        std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(&path),
    )
    .map_err(|e| Error::msg(format!("cannot open the clips folder's lock: {e}")).in_file(&path))?;
    let how = if exclusive { libc::LOCK_EX } else { libc::LOCK_SH };
    // SAFETY: flock on a file descriptor this function owns.
    if unsafe { libc::flock(file.as_raw_fd(), how | libc::LOCK_NB) } != 0 {
        let e = std::io::Error::last_os_error();
        return Err(if e.kind() == std::io::ErrorKind::WouldBlock {
            Error::msg(
                "another painterly process is writing this shot's chunks or clip set: wait for it to end (or stop it), then run again",
            )
        } else {
            Error::msg(format!("cannot lock the clips folder: {e}"))
        }
        .in_file(&plan.dir));
    }
    Ok(ClipsLock { _file: file })
}

/// Writes chunk after chunk as frames arrive, each staged under its
/// temporary name; once the last is written, puts every chunk in place,
/// then writes the clip set. A re-bake stopped before its end (a signal, an
/// error) so leaves the clip set already published whole.
pub struct ChunkedSink {
    plan: ClipPlan,
    layout: BakeLayout,
    times: Vec<f64>,
    current: Option<Box<UsdcSink>>,
    staged: Vec<Staged>,
    written: usize,
}

impl ChunkedSink {
    pub fn new(plan: ClipPlan, layout: BakeLayout, times: &[f64]) -> Result<ChunkedSink> {
        // Before baking (and before its folder is made): a clip set that
        // cannot be written is known now.
        plan.check_clip_set_targets()?;
        plan.create_dir()?;
        Ok(ChunkedSink {
            plan,
            layout,
            times: times.to_vec(),
            current: None,
            staged: Vec::new(),
            written: 0,
        })
    }
}

/// The layout of one chunk: the bake's, with the chunk's provenance.
pub fn chunk_layout(layout: &BakeLayout, plan: &ClipPlan, chunk: &Chunk, times: &[f64], step: f64) -> BakeLayout {
    let mut l = layout.clone();
    l.provenance.frames = chunk_frames(chunk, times, step);
    l.provenance.chunk = Some((chunk.index, plan.chunks.len()));
    l.provenance.chunks = None;
    l
}

impl FrameSink for ChunkedSink {
    fn write_frame(&mut self, time: f64, samples: Vec<Sample>) -> Result<()> {
        let i = self.written;
        let chunk = &self.plan.chunks[i / self.plan.chunk_size];
        if i == chunk.start {
            if let Some(done) = self.current.take() {
                self.staged.push(done.finish_staged()?);
            }
            let step = frame_step(&self.times);
            let layout = chunk_layout(&self.layout, &self.plan, chunk, &self.times, step);
            // Chunk layers are .usdc (ClipPlan names them so).
            self.current = Some(Box::new(UsdcSink::new(&self.plan.chunk_path(chunk), layout)?));
        }
        self.written += 1;
        match &mut self.current {
            Some(sink) => sink.write_frame(time, samples),
            None => Err(Error::msg("internal: no chunk open")),
        }
    }

    fn finish(mut self: Box<Self>) -> Result<()> {
        if let Some(done) = self.current.take() {
            self.staged.push(done.finish_staged()?);
        }
        // The chunks and the clip set are published as one: every target is
        // checked before the first rename, and a signal waits for the last.
        for chunk in &self.staged {
            chunk.check()?;
        }
        // The clip set is written after the chunks: had it become unwritable,
        // new chunks would be published under the old set.
        self.plan.check_clip_set_targets()?;
        let _publishing = super::atomic::hold_signals();
        for chunk in std::mem::take(&mut self.staged) {
            chunk.commit()?;
        }
        write_clip_set(&self.plan, &self.layout, &self.times)
    }
}

/// The step between baked frames (1 for a single frame).
pub fn frame_step(times: &[f64]) -> f64 {
    match times {
        [a, b, ..] => b - a,
        _ => 1.0,
    }
}

/// The root prims (names) the clip set is authored on: those above every
/// prim the bake writes.
fn clip_set_roots(layout: &BakeLayout) -> BTreeSet<&str> {
    layout
        .attrs
        .iter()
        .map(|a| a.prim.as_str())
        .chain(layout.blocked_skeletons.iter().map(String::as_str))
        .chain(layout.blocked_attrs.iter().map(|b| b.prim.as_str()))
        .filter_map(|p| p.split('/').nth(1))
        .collect()
}

/// Refuses a chunked bake of an input that already holds a clip set named
/// [`CLIP_SET`] on a root prim the new set goes on (an earlier chunked bake
/// in its layer stack, e.g. through `painterly view`): `clips` merges key by
/// key, so the new set would silently replace the old one's every entry,
/// and what the old set animated (a baked proxy) would freeze.
pub fn refuse_input_clip_set(r: &StageReader, layout: &BakeLayout) -> Result<()> {
    for root in clip_set_roots(layout) {
        let path = format!("/{root}");
        let Some(prim) = r.prim(&path)? else { continue };
        if r.prim_clip_set_names(&prim)?.iter().any(|n| n == CLIP_SET) {
            return Err(Error::attr(
                &path,
                "clips",
                format!(
                    "the input already holds a value-clip set named \"{CLIP_SET}\" here (an earlier chunked bake \
                     in its layers, e.g. through `painterly view`); a chunked bake would replace it: bake the \
                     input without the earlier bake, or bake to a single file"
                ),
            ));
        }
    }
    Ok(())
}

/// Writes the manifest and the clip-set layer for `plan`.
pub fn write_clip_set(plan: &ClipPlan, layout: &BakeLayout, times: &[f64]) -> Result<()> {
    let manifest = plan.manifest_path();
    let tree = PrimTree::new(layout.attrs.iter().map(|a| a.prim.as_str()));
    write_atomic_with(&manifest, |out| {
        out.write_all(b"#usda 1.0\n")?;
        tree.write(out, &mut |out, prim, depth| {
            declare_attrs(out, layout, prim, depth, false)
        })
    })?;

    let mut provenance: Provenance = layout.provenance.clone();
    provenance.chunks = Some((plan.chunk_size, plan.chunks.iter().map(|c| c.name.clone()).collect()));
    let head = usda_header(&layout.meta, &provenance, bake_layer::DOC);
    let roots = clip_set_roots(layout);
    let full = PrimTree::new(
        layout
            .attrs
            .iter()
            .map(|a| a.prim.as_str())
            .chain(layout.blocked_skeletons.iter().map(String::as_str))
            .chain(layout.blocked_attrs.iter().map(|b| b.prim.as_str())),
    );
    let clip_meta = |root: &str| -> String {
        let mut active = Vec::new();
        let mut map = Vec::new();
        for c in &plan.chunks {
            let (a, b) = (times[c.start], times[c.end - 1]);
            active.push(format!("({}, {})", UsdaNumber(a), c.index));
            map.push(format!("({0}, {0})", UsdaNumber(a)));
            if b != a {
                map.push(format!("({0}, {0})", UsdaNumber(b)));
            }
        }
        let assets: Vec<String> = plan
            .chunks
            .iter()
            .map(|c| format!("@{}@", plan.asset(&c.name)))
            .collect();
        let manifest_name = manifest.file_name().unwrap_or_default().to_string_lossy();
        let mut m = String::new();
        let _ = write!(
            m,
            " (\n    clips = {{\n        dictionary {CLIP_SET} = {{\n            double2[] active = [{}]\n            asset[] assetPaths = [{}]\n            asset manifestAssetPath = @{}@\n            string primPath = {}\n            double2[] times = [{}]\n        }}\n    }}\n    prepend clipSets = [{}]\n)",
            active.join(", "),
            assets.join(", "),
            plan.asset(&manifest_name),
            quoted(&format!("/{root}")),
            map.join(", "),
            quoted(CLIP_SET),
        );
        m
    };
    write_atomic_with(&plan.output, |out| {
        out.write_all(head.as_bytes())?;
        full.write_with_meta(
            out,
            &mut |prim| {
                let is_root = prim.matches('/').count() == 1;
                if is_root && roots.contains(&prim[1..]) {
                    clip_meta(&prim[1..])
                } else {
                    String::new()
                }
            },
            &mut |out, prim, depth| declare_attrs(out, layout, prim, depth, true),
        )
    })
}

/// Attribute declarations (no values) of `prim`; with `full`, also primvar
/// interpolation and blocked relationships.
fn declare_attrs(
    out: &mut dyn Write,
    layout: &BakeLayout,
    prim: &str,
    depth: usize,
    full: bool,
) -> std::io::Result<()> {
    let pad = "    ".repeat(depth + 1);
    for a in layout.attrs.iter().filter(|a| a.prim == prim) {
        match (a.interpolation, full) {
            (Some(i), true) => writeln!(
                out,
                "{pad}{} {} (\n{pad}    interpolation = \"{i}\"\n{pad})",
                a.kind.type_name(),
                a.name
            )?,
            _ => writeln!(out, "{pad}{} {}", a.kind.type_name(), a.name)?,
        }
    }
    if full && layout.blocked_skeletons.iter().any(|p| p == prim) {
        writeln!(out, "{pad}rel skel:skeleton = None")?;
    }
    if full {
        bake_layer::write_blocked_attrs(out, layout, prim, &pad)?;
    }
    Ok(())
}

/// A chunk layer's stamp: its provenance, or why it cannot be read.
enum Stamp {
    Missing,
    /// Truncated, not USD, ...: stale, so that a re-submit bakes it again.
    Unreadable(String),
    Read(Provenance),
}

/// A chunk layer's stamp.
fn read_stamp(path: &Path) -> Stamp {
    if !path.is_file() {
        return Stamp::Missing;
    }
    match read_provenance(path) {
        Ok(p) => Stamp::Read(p.unwrap_or_default()),
        Err(e) => Stamp::Unreadable(format!("unreadable: {}", e.message)),
    }
}

/// SHA-256 over every layer file the stage used (sorted by path: name, then
/// bytes), hex encoded. Packages (`.usdz`) are hashed as one file.
pub fn input_hash(r: &StageReader) -> Result<String> {
    if let Some(h) = r.input_hash.get() {
        return Ok(h.clone());
    }
    let h = hash_layers(r)?;
    Ok(r.input_hash.get_or_init(|| h).clone())
}

/// SHA-256 over the layer files the stage used, sorted by resolved path:
/// for each, the path, a NUL byte, then what `content` adds of the file;
/// hex encoded. Packages (`.usdz`) count as one file.
fn layers_digest(r: &StageReader, content: impl Fn(&Path, &mut sha2::Sha256) -> std::io::Result<()>) -> Result<String> {
    use sha2::{Digest, Sha256};
    let mut h = Sha256::new();
    for f in input_files(r) {
        h.update(f.to_string_lossy().as_bytes());
        h.update([0]);
        content(f, &mut h).map_err(|e| Error::msg(format!("cannot read: {e}")).in_file(f))?;
    }
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

/// Every file the stage reads, canonical: its layers (a package counts as
/// one file) and the files its value clips read. The reader composed every
/// prim when it opened, so every referenced layer is among them. Listed
/// once per reader.
pub fn input_files(r: &StageReader) -> &BTreeSet<PathBuf> {
    r.input_files.get_or_init(|| list_input_files(r))
}

fn list_input_files(r: &StageReader) -> BTreeSet<PathBuf> {
    let mut files: BTreeSet<PathBuf> = BTreeSet::new();
    for id in r.stage.layer_identifiers() {
        // "pkg.usdz[inner.usdc]" names a layer inside a package.
        let file = super::stage::package_file(&id);
        let path = PathBuf::from(file);
        if path.is_file() {
            files.insert(path.canonicalize().unwrap_or(path));
        }
        // Value clips are no layer of the stage, yet their samples are part
        // of the input (a point cache delivered as clips).
        if !super::stage::is_package_relative(&id) {
            if let Some(layer) = r.stage.layer(&id) {
                files.extend(input_clip_files(layer.data(), Path::new(file)));
            }
        }
    }
    files
}

/// Refuses an `output` that is a file the input reads (a sublayer, a
/// referenced layer, a clip): writing it would change the input, and
/// inputs are never modified.
pub fn check_not_an_input_file(r: &StageReader, output: &Path) -> Result<()> {
    let Ok(out) = output.canonicalize() else {
        return Ok(()); // a new file is no input
    };
    if input_files(r).contains(&out) {
        let what = if r.file.canonicalize().is_ok_and(|f| f == out) {
            "the input".to_string()
        } else {
            format!("{}, a file the input reads", out.display())
        };
        return Err(Error::msg(format!("output would overwrite {what}; inputs are never modified")).in_file(output));
    }
    Ok(())
}

/// The files the value clips authored in one input layer (at `layer_file`)
/// read: each clip set's `assetPaths` and `manifestAssetPath`, and for a
/// `templateAssetPath` every file beside it its pattern matches (`#` a
/// digit, `.` or `-`; more than the template's times may pick, never fewer).
/// Relative paths are anchored at the layer, as usd-core's resolver does;
/// paths that name no file are left out.
fn input_clip_files(data: &dyn openusd::sdf::AbstractData, layer_file: &Path) -> Vec<PathBuf> {
    use openusd::sdf::{SpecType, Value};
    let anchor = layer_file.parent().unwrap_or(Path::new("."));
    let resolve = |asset: &str| -> Option<PathBuf> {
        let p = anchor.join(asset); // an absolute asset replaces the anchor
        p.is_file().then(|| p.canonicalize().unwrap_or(p))
    };
    let mut out = Vec::new();
    for path in data.spec_paths() {
        if !matches!(data.spec_type(&path), Some(SpecType::Prim | SpecType::Variant)) {
            continue;
        }
        let Ok(Some(clips)) = data.try_field(&path, "clips") else {
            continue;
        };
        let Value::Dictionary(sets) = clips.as_ref() else {
            continue;
        };
        for set in sets.values() {
            let Value::Dictionary(set) = set else { continue };
            // `asset[]`, the only type usd-core's ClipsAPI reads there.
            if let Some(Value::AssetPathVec(v)) = set.get("assetPaths") {
                out.extend(v.iter().filter_map(|a| resolve(&a.authored_path)));
            }
            if let Some(Value::AssetPath(a)) = set.get("manifestAssetPath") {
                out.extend(resolve(&a.authored_path));
            }
            if let Some(Value::String(t)) = set.get("templateAssetPath") {
                out.extend(template_files(&anchor.join(t)));
            }
        }
    }
    out
}

/// The files a clip template such as `anim/cache.###.usdc` can name: those
/// in its folder with its text before and after the `#`s and only digits,
/// `.` or `-` between.
fn template_files(template: &Path) -> Vec<PathBuf> {
    let name = template.file_name().unwrap_or_default().to_string_lossy().into_owned();
    let (Some(first), Some(last)) = (name.find('#'), name.rfind('#')) else {
        return Vec::new();
    };
    let (prefix, suffix) = (&name[..first], &name[last + 1..]);
    let dir = template.parent().unwrap_or(Path::new("."));
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut out: Vec<PathBuf> = entries
        .flatten()
        .filter(|e| {
            let n = e.file_name().to_string_lossy().into_owned();
            n.len() > prefix.len() + suffix.len()
                && n.starts_with(prefix)
                && n.ends_with(suffix)
                && n[prefix.len()..n.len() - suffix.len()]
                    .chars()
                    .all(|c| c.is_ascii_digit() || c == '.' || c == '-')
        })
        .map(|e| e.path())
        .filter(|p| p.is_file())
        .map(|p| p.canonicalize().unwrap_or(p))
        .collect();
    out.sort();
    out
}

/// [`input_hash`]'s digest: each file's bytes.
fn hash_layers(r: &StageReader) -> Result<String> {
    let hash = layers_digest(r, |f, h| {
        std::io::copy(&mut super::regular::open_regular(f)?, h).map(|_| ())
    })?;
    // Checked after hashing: a save before or during it shows.
    r.check_unchanged()?;
    Ok(hash)
}

/// The same digest over each layer file's size and modification time in
/// nanoseconds (`"SIZE MTIME\n"`) instead of its bytes: tells a changed
/// input from the one baked without reading it, which [`input_hash`] does
/// (a 160 MiB input costs it about 0.1 s).
pub fn input_stamp(r: &StageReader) -> Result<String> {
    use sha2::Digest;
    let stamp = layers_digest(r, |f, h| {
        let meta = std::fs::metadata(f)?;
        let modified = meta
            .modified()
            .ok()
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_nanos());
        h.update(format!("{} {modified}\n", meta.len()).as_bytes());
        Ok(())
    })?;
    r.check_unchanged()?;
    Ok(if r.unsaved {
        format!("{UNSAVED_STAMP}{stamp}")
    } else {
        stamp
    })
}

/// Prefixes the `inputStamp` of a bake of unsaved edits ([`StageReader::unsaved`]):
/// no stamp of the files can equal it, and the check says why.
pub const UNSAVED_STAMP: &str = "unsaved:";

/// Checks that every chunk of `plan` is on disk and was baked from an input
/// with `hash` by this painterly, for its frames; the error lists every
/// chunk that is missing or stale.
pub fn check_chunks(plan: &ClipPlan, hash: &str, options: Option<&str>, times: &[f64]) -> Result<()> {
    let mut missing = Vec::new();
    let mut stale = Vec::new();
    for (c, state) in plan.chunks.iter().zip(chunk_states(plan, hash, options, times)?) {
        match state {
            ChunkState::Done => {}
            ChunkState::Missing => missing.push(c.name.clone()),
            ChunkState::Stale(why) => stale.push(format!("{} ({why})", c.name)),
        }
    }
    if missing.is_empty() && stale.is_empty() {
        return Ok(());
    }
    let mut msg = String::from("cannot assemble the clip set:");
    if !missing.is_empty() {
        let _ = write!(
            msg,
            " {} of {} chunks missing: {}",
            missing.len(),
            plan.chunks.len(),
            missing.join(", ")
        );
    }
    if !stale.is_empty() {
        let _ = write!(
            msg,
            "{} {} stale: {}",
            if missing.is_empty() { "" } else { ";" },
            stale.len(),
            stale.join(", ")
        );
    }
    Err(Error::msg(msg).in_file(&plan.dir))
}

/// Whether a chunk layer is done.
#[derive(Debug, Clone, PartialEq)]
pub enum ChunkState {
    Done,
    Missing,
    /// On disk, but from another input, painterly version or frame range.
    Stale(String),
}

/// The state of every chunk of `plan`, for an input with `hash` baked with
/// `options` ([`Provenance::options`]) by this painterly.
pub fn chunk_states(plan: &ClipPlan, hash: &str, options: Option<&str>, times: &[f64]) -> Result<Vec<ChunkState>> {
    let want = Expected {
        hash: Some(hash),
        version: env!("CARGO_PKG_VERSION"),
        options,
    };
    Ok(judge_chunks(plan, &want, Some(times)))
}

/// What a chunk's stamp must say for the chunk to be done.
struct Expected<'a> {
    /// The input's hash (None: a clip set that recorded none).
    hash: Option<&'a str>,
    /// The painterly version.
    version: &'a str,
    /// The options ([`Provenance::options`]).
    options: Option<&'a str>,
}

/// A chunk's frames as its stamp records them, `A:B:STEP`.
fn chunk_frames(chunk: &Chunk, times: &[f64], step: f64) -> String {
    format!("{}:{}:{}", times[chunk.start], times[chunk.end - 1], step)
}

/// The state of every chunk of `plan`: its stamp against `want` and, with
/// `times`, the frames `plan` gives it (the one judge of chunks: assembly,
/// farm status and inspect).
fn judge_chunks(plan: &ClipPlan, want: &Expected, times: Option<&[f64]>) -> Vec<ChunkState> {
    let step = times.map(frame_step);
    plan.chunks
        .iter()
        .map(|c| {
            let stamp = match read_stamp(&plan.chunk_path(c)) {
                Stamp::Missing => return ChunkState::Missing,
                Stamp::Unreadable(why) => return ChunkState::Stale(why),
                Stamp::Read(p) => p,
            };
            let frames = times.zip(step).map(|(t, step)| chunk_frames(c, t, step));
            if stamp.input_hash.as_deref() != want.hash {
                ChunkState::Stale("baked from a different input".into())
            } else if stamp.version != want.version {
                ChunkState::Stale(format!("baked by painterly {}", stamp.version))
            } else if let Some(frames) = frames.filter(|f| stamp.frames != *f) {
                ChunkState::Stale(format!("holds frames {}, expected {frames}", stamp.frames))
            } else if stamp.options.as_deref() != want.options {
                ChunkState::Stale(options_differ(stamp.options.as_deref(), want.options))
            } else {
                ChunkState::Done
            }
        })
        .collect()
}

/// Why a chunk baked with options `had` is stale for a bake with `want`.
fn options_differ(had: Option<&str>, want: Option<&str>) -> String {
    format!(
        "baked with {}, expected {}",
        had.map_or("no options".to_string(), |o| format!("`{o}`")),
        want.map_or("no options".to_string(), |o| format!("`{o}`"))
    )
}

/// A clip-set layer's chunks and their state, for `inspect`.
#[derive(Debug, Clone, PartialEq)]
pub struct ClipSetStatus {
    pub chunk_size: usize,
    /// Chunk file names (in the clips folder) and their state.
    pub chunks: Vec<(String, ChunkState)>,
    /// What is wrong with the clip set besides its chunks: its input changed
    /// since it was assembled, cannot be read (its chunks are then judged
    /// against the input hash the clip set recorded), or its frames do not
    /// make its chunks (their frames are then not checked).
    pub problems: Vec<String>,
}

/// When `path` is a clip-set layer written by `painterly bake --chunk`, the
/// state of each of its chunks, judged as the assembly judges them: on disk
/// and stamped with the current hash of the clip set's input (`input_hash`
/// when the caller has it, else its recorded input is opened and hashed),
/// the clip set's painterly version and options, and the chunk's frames;
/// missing; or stale.
pub fn clip_set_status(path: &Path, input_hash: Option<&str>) -> Result<Option<ClipSetStatus>> {
    let Ok(Some(clip_set)) = read_provenance(path) else {
        return Ok(None);
    };
    let Some((size, names)) = &clip_set.chunks else {
        return Ok(None);
    };
    let mut problems = Vec::new();
    let input = Path::new(&clip_set.input);
    let unchecked = "so its chunks are checked against the input they were baked from, not against the current one";
    let current = match input_hash {
        Some(h) => Ok(h.to_string()),
        None if clip_set.input.is_empty() => Err(format!("the clip set records no input, {unchecked}")),
        None => StageReader::open_mapped(input)
            .and_then(|r| self::input_hash(&r))
            .map_err(|e| {
                format!(
                    "the clip set's input {} cannot be read, {unchecked}: {}",
                    input.display(),
                    e.message
                )
            }),
    };
    let hash = match current {
        Ok(h) => {
            if clip_set.input_hash.as_deref() != Some(h.as_str()) {
                problems.push(format!(
                    "{} changed since this clip set was assembled (its layers differ from the clip set's inputHash): \
                     its chunks baked from the old input are stale; bake them again and assemble the clip set again",
                    input.display()
                ));
            }
            Some(h)
        }
        Err(why) => {
            problems.push(why);
            clip_set.input_hash.clone()
        }
    };
    // The clip set's frames, when they make exactly its chunks.
    let times = clip_set
        .frames
        .parse::<crate::frames::FrameRange>()
        .ok()
        .map(|r| r.times())
        .filter(|t| *size > 0 && t.len().div_ceil(*size) == names.len());
    if times.is_none() {
        problems.push(format!(
            "the clip set's frames {:?} in chunks of {size} do not make its {} chunks: their frames are not checked",
            clip_set.frames,
            names.len()
        ));
    }
    let count = times.as_ref().map_or(0, Vec::len);
    let (_, dir) = clips_dir(path)?;
    let plan = ClipPlan {
        output: path.to_path_buf(),
        dir,
        chunk_size: *size,
        chunks: names
            .iter()
            .enumerate()
            .map(|(index, name)| Chunk {
                index,
                start: index * size,
                end: ((index + 1) * size).min(count),
                name: name.clone(),
            })
            .collect(),
    };
    let want = Expected {
        hash: hash.as_deref(),
        version: &clip_set.version,
        options: clip_set.options.as_deref(),
    };
    let states = judge_chunks(&plan, &want, times.as_deref());
    Ok(Some(ClipSetStatus {
        chunk_size: *size,
        chunks: names.iter().cloned().zip(states).collect(),
        problems,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::usd_io::bake_layer::{BakeAttr, BlockedAttr, SampleKind};

    #[test]
    fn frame_step_is_the_gap_between_the_first_two_frames() {
        assert_eq!(frame_step(&[10.0, 10.25, 10.5]), 0.25);
        // One frame or none: a step of 1, as `--frames A:A:1` would say.
        assert_eq!(frame_step(&[3.0]), 1.0);
        assert_eq!(frame_step(&[]), 1.0);
    }

    /// Two attributes on /A/B (one a primvar), B's skeleton and primvar
    /// indices blocked, frames
    /// 1, 2, 3 in chunks of 2: the manifest declares the attributes, the
    /// clip-set layer also their interpolation and the blocked relationship,
    /// nested like the prims (written out by hand from the module docs).
    #[test]
    fn clip_set_and_manifest_text() {
        let dir = crate::test_dir::ScratchDir::new("clipset-text");
        let output = dir.join("shot.usda");
        let times = [1.0, 2.0, 3.0];
        let plan = ClipPlan::new(&output, &times, 2).unwrap();
        let layout = BakeLayout {
            meta: Default::default(),
            attrs: vec![
                BakeAttr {
                    prim: "/A/B".into(),
                    name: "points",
                    kind: SampleKind::Points,
                    interpolation: None,
                },
                BakeAttr {
                    prim: "/A/B".into(),
                    name: "primvars:displayOpacity",
                    kind: SampleKind::Floats,
                    interpolation: Some("vertex"),
                },
            ],
            blocked_skeletons: vec!["/A/B".into()],
            blocked_attrs: vec![BlockedAttr {
                prim: "/A/B".into(),
                name: "primvars:displayOpacity:indices",
                type_name: "int[]",
            }],
            provenance: Default::default(),
        };
        plan.create_dir().unwrap();
        write_clip_set(&plan, &layout, &times).unwrap();
        let manifest = std::fs::read_to_string(dir.join("shot.clips/shot.manifest.usda")).unwrap();
        assert_eq!(
            manifest,
            "#usda 1.0\n\nover \"A\"\n{\n    over \"B\"\n    {\n        point3f[] points\n        \
             float[] primvars:displayOpacity\n    }\n}\n"
        );
        let text = std::fs::read_to_string(&output).unwrap();
        let body = r#"
over "A" (
    clips = {
        dictionary painterly = {
            double2[] active = [(1, 0), (3, 1)]
            asset[] assetPaths = [@./shot.clips/shot.0000.1-2.usdc@, @./shot.clips/shot.0001.3-3.usdc@]
            asset manifestAssetPath = @./shot.clips/shot.manifest.usda@
            string primPath = "/A"
            double2[] times = [(1, 1), (2, 2), (3, 3)]
        }
    }
    prepend clipSets = ["painterly"]
)
{
    over "B"
    {
        point3f[] points
        float[] primvars:displayOpacity (
            interpolation = "vertex"
        )
        rel skel:skeleton = None
        int[] primvars:displayOpacity:indices = None
    }
}
"#;
        assert!(text.ends_with(body), "{text}");
    }
}
