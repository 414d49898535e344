//! `painterly bake`: frames streamed through reader → evaluator → writer.
//!
//! The plan is resolved once ([`Character::open`]: rigs, bindings, cameras,
//! view meshes; then the frames and the output layout). Frames then flow
//! through three stages at once: the stage is read serially on this thread
//! (it is single-threaded), each frame is evaluated on the thread pool, and a
//! writer thread hands finished frames to the layer writer in time order. At
//! most a small window of frames is in flight, so memory does not grow with
//! the length of the shot.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Instant;

use glam::Vec3;

use crate::character::{Character, FrameInput, FrameOutput, Model, RigModel};
use crate::error::{Error, Result};
use crate::extent::{pad_curves_extent, point_based_extent};
use crate::frames::FrameRange;
use crate::usd_io::bake_layer::{self, BakeAttr, BakeLayout, BlockedAttr, FrameSink, Provenance, Sample, SampleKind};
use crate::usd_io::binding_cache::{self, BindingCache};
use crate::usd_io::clips::{self, ChunkedSink, ClipPlan};
use crate::usd_io::guard::OpenedFiles;
use crate::usd_io::layer::Format;
use crate::usd_io::stage::StageReader;

/// What to bake.
#[derive(Debug, Clone, Default)]
pub struct BakeOptions {
    /// Frames to bake; default: the stage's startTimeCode..endTimeCode.
    pub frames: Option<FrameRange>,
    /// Also write every rig proxy's evaluated points (and block its skeleton).
    pub bake_proxy: bool,
    /// Camera prim for `viewDirection` axes without a source (and view-dependent meshes).
    pub camera: Option<String>,
    /// Write value clips of this many frames per chunk layer (plus the
    /// clip-set layer `output`) instead of one file.
    pub chunk: Option<usize>,
    /// With `chunk`: write only this chunk's layer (a farm task).
    pub chunk_index: Option<usize>,
    /// With `chunk`: write only the clip set, after checking that every
    /// chunk layer is there and was baked from this input (a farm's last step).
    pub assemble: bool,
    /// Set from another thread to stop the bake before its next frame: it
    /// then fails with [`INTERRUPTED`] and writes nothing (the Python
    /// binding's Ctrl-C; the CLI's signals remove temporaries themselves).
    pub cancel: Option<Arc<AtomicBool>>,
}

/// The message of a bake stopped through [`BakeOptions::cancel`].
pub const INTERRUPTED: &str = "interrupted: the bake was stopped before its last frame and wrote nothing";

/// What a bake did, for the summary line and `--json`.
#[derive(Debug, Clone, serde::Serialize)]
pub struct BakeSummary {
    pub input: PathBuf,
    pub output: PathBuf,
    pub frames: usize,
    pub rigs: usize,
    pub view_meshes: usize,
    pub layers: usize,
    pub strokes: usize,
    pub points: usize,
    pub seconds: f64,
    /// Chunk layers this run wrote (or, assembling, checked); empty for a
    /// single-file bake.
    pub chunks: Vec<PathBuf>,
}

/// Reports progress: (steps done, total steps); called from worker threads.
pub type Progress<'a> = &'a (dyn Fn(usize, usize) + Sync);

/// Checks an output path before any work: format, directory, not the input.
pub fn check_output(input: &Path, output: &Path) -> Result<Format> {
    let format = Format::from_path(output)?;
    check_output_dir(input, output)?;
    Ok(format)
}

fn check_output_dir(input: &Path, output: &Path) -> Result<()> {
    let dir = match output.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if !dir.is_dir() {
        return Err(Error::msg(format!("output directory {} does not exist", dir.display())).in_file(output));
    }
    if crate::usd_io::stage::same_file(input, output) {
        return Err(Error::msg("output would overwrite the input; inputs are never modified").in_file(output));
    }
    Ok(())
}

/// The frames to bake: the option, checked against the stage's range, or
/// the stage's whole range (see [`crate::frames::resolve`]).
pub fn resolve_frames(r: &StageReader, frames: Option<FrameRange>) -> Result<Vec<f64>> {
    crate::frames::resolve(&r.metadata(), frames)
}

/// Bakes `input` into `output`. A stage with nothing to bake is an error.
pub fn bake(input: &Path, output: &Path, opts: &BakeOptions, progress: Progress) -> Result<BakeSummary> {
    bake_with(input, output, opts, progress, || StageReader::open_mapped(input))
}

/// Like [`bake`], for the stage `open` returns (a layer handed over in
/// memory, see [`crate::usd_io::memory`]); `input` is the path it stands for.
pub fn bake_with(
    input: &Path,
    output: &Path,
    opts: &BakeOptions,
    progress: Progress,
    open: impl FnOnce() -> Result<StageReader>,
) -> Result<BakeSummary> {
    let started = Instant::now();
    let character = open_for_bake_with(input, output, opts, open)?;
    bake_character(&character, input, output, opts, progress, started).map_err(|e| e.in_file(input))
}

/// Every check [`bake`] makes before it bakes a frame (options, output
/// path, the character, something to bake), and the opened character; a
/// farm submission makes them too, before it queues any task.
pub fn open_for_bake(input: &Path, output: &Path, opts: &BakeOptions) -> Result<Character> {
    open_for_bake_with(input, output, opts, || StageReader::open_mapped(input))
}

/// [`open_for_bake`] for the stage `open` returns.
fn open_for_bake_with(
    input: &Path,
    output: &Path,
    opts: &BakeOptions,
    open: impl FnOnce() -> Result<StageReader>,
) -> Result<Character> {
    if opts.chunk == Some(0) {
        return Err(Error::usage("--chunk must be at least 1"));
    }
    if opts.chunk.is_some() && Format::from_path(output)? != Format::Usda {
        return Err(Error::usage("with --chunk the output is the clip-set layer: name it .usda").in_file(output));
    }
    if opts.chunk.is_some() && std::fs::symlink_metadata(output).is_ok_and(|m| m.file_type().is_symlink()) {
        // The chunks go beside the name given, the clip set through the link:
        // opened from the linked file, its ./<stem>.clips paths would miss.
        return Err(Error::msg(
            "with --chunk the output (the clip-set layer) must not be a symbolic link: name the file it links to",
        )
        .in_file(output));
    }
    if opts.chunk.is_none() && (opts.chunk_index.is_some() || opts.assemble) {
        return Err(Error::usage("--chunk-index and --assemble need --chunk N"));
    }
    check_output(input, output)?;
    let opening = Instant::now();
    let reader = open()?;
    crate::character::log_opened(input, &reader, opening);
    clips::check_not_an_input_file(&reader, output)?;
    if reader.unsaved && opts.chunk.is_some() {
        // Chunks, and the binding cache beside them, are matched to the
        // input by the file's content hash, which is not what was baked.
        return Err(Error::msg(
            "a chunked bake needs the input saved: its chunks and binding cache are matched to the file, and this layer has unsaved edits (save it, or bake without chunks)",
        )
        .in_file(input));
    }
    let mut character = match opts.chunk {
        None => Character::from_reader(reader, opts.camera.as_deref()),
        Some(_) => chunked_character(reader, output, opts.camera.as_deref()),
    }
    .map_err(|e| e.in_file(input))?;
    character.proxy_normals = opts.bake_proxy;
    if is_empty(&character.model, opts) {
        return Err(Error::msg(
            "nothing to bake: no stroke layer (PainterlyStrokeLayerAPI under a prim with PainterlyRigAPI) and no view-dependent mesh (PainterlyViewDependentAPI)",
        )
        .in_file(input));
    }
    Ok(character)
}

/// The character of a chunked bake into `output`: bindings come from the
/// clips folder's binding cache when it matches the input (see
/// [`leave_binding_cache`]).
fn chunked_character(reader: StageReader, output: &Path, camera: Option<&str>) -> Result<Character> {
    let hash = clips::input_hash(&reader)?;
    let cache = BindingCache::open(&clips::binding_cache_path(output)?, &hash);
    Character::from_reader_with(reader, camera, cache.as_ref())
}

/// Leaves the bindings `ch` computed in the binding cache of a chunked bake
/// into `output`, so that the other tasks of the shot and its assembly do
/// not bind again. Called once every check has passed (a refused command
/// leaves nothing behind); failing to write the cache fails nothing.
pub fn leave_binding_cache(ch: &Character, output: &Path) {
    if !ch.binding_computed {
        return;
    }
    let written = (|| {
        let hash = clips::input_hash(&ch.reader)?;
        let path = clips::binding_cache_path(output)?;
        std::fs::create_dir_all(path.parent().unwrap_or(Path::new(".")))
            .map_err(|e| Error::msg(format!("cannot create the clips folder: {e}")))?;
        let layers = ch
            .model
            .rigs
            .iter()
            .flat_map(|r| &r.layers)
            .map(|l| (l.path.as_str(), &l.binding));
        binding_cache::write(&path, &ch.reader.file, &hash, layers)
    })();
    if let Err(e) = written {
        crate::vlog!("binding cache not written: {e}");
    }
}

/// Evaluates every frame that `bake` (with `camera` as `--camera` and
/// `frames` as `--frames`) would bake, and writes nothing: what `inspect`
/// runs so that its exit 0 means such a bake succeeds (camera transforms,
/// posed points and opacities can fail only at a frame; a stage without a
/// time range needs `frames`, as bake does). Returns how many frames were
/// evaluated: none for a stage with nothing to bake.
pub fn evaluate_every_frame(
    reader: StageReader,
    camera: Option<&str>,
    frames: Option<FrameRange>,
    progress: Progress,
) -> Result<usize> {
    let ch = Character::from_reader(reader, camera)?;
    if is_empty(&ch.model, &BakeOptions::default()) {
        return Ok(0);
    }
    let times = resolve_frames(&ch.reader, frames)?;
    stream(&ch, &times, false, Box::new(DiscardSink), progress, None)?;
    Ok(times.len())
}

/// Evaluates `ch` at `t` as its bake would, writing nothing: `farm
/// submit`'s check that a frame can be baked at all (a problem every frame
/// meets, such as a viewDirection axis with no source and no camera, shows
/// only when a frame is evaluated).
pub fn evaluate_one_frame(ch: &Character, t: f64, bake_proxy: bool) -> Result<()> {
    if is_empty(
        &ch.model,
        &BakeOptions {
            bake_proxy,
            ..Default::default()
        },
    ) {
        return Ok(());
    }
    stream(ch, &[t], bake_proxy, Box::new(DiscardSink), &|_, _| {}, None)
}

/// A sink that drops every frame: evaluation without output.
struct DiscardSink;

impl FrameSink for DiscardSink {
    fn write_frame(&mut self, _time: f64, _samples: Vec<Sample>) -> Result<()> {
        Ok(())
    }

    fn finish(self: Box<Self>) -> Result<()> {
        Ok(())
    }
}

/// A plain bake of `input` for `render` (read unmapped, as render reads it;
/// no chunks), except that a stage with nothing to bake writes nothing and
/// returns None (a render of a plain scene needs no bake).
/// With the bake, the versions of the files it read ([`StageReader::opened`]):
/// a caller that opens the input again compares them.
pub fn bake_if_any(input: &Path, output: &Path, opts: &BakeOptions) -> Result<Option<(BakeSummary, OpenedFiles)>> {
    let started = Instant::now();
    check_output(input, output)?;
    let mut character = Character::open(input, opts.camera.as_deref())?;
    character.proxy_normals = opts.bake_proxy;
    if is_empty(&character.model, opts) {
        return Ok(None);
    }
    bake_character(&character, input, output, opts, &|_, _| {}, started)
        .map(|s| Some((s, character.reader.opened.clone())))
        .map_err(|e| e.in_file(input))
}

fn is_empty(model: &Model, opts: &BakeOptions) -> bool {
    // --bake-proxy alone still has proxies to write.
    let proxies = opts.bake_proxy && !model.rigs.is_empty();
    !proxies && model.views.is_empty() && model.rigs.iter().all(|r| r.layers.is_empty())
}

/// Bakes `ch` into `output`; `input` is the file it stands for (recorded in
/// the bake; the reader's own path differs for a layer's text served
/// elsewhere).
fn bake_character(
    ch: &Character,
    input: &Path,
    output: &Path,
    opts: &BakeOptions,
    progress: Progress,
    started: Instant,
) -> Result<BakeSummary> {
    // No file this bake writes (a chunk, the manifest, the binding cache)
    // may be one its input reads, even through a link of that name.
    let _inputs = crate::usd_io::atomic::InputGuard::new(clips::input_files(&ch.reader));
    let model = &ch.model;
    let times = resolve_frames(&ch.reader, opts.frames)?;
    let mut layout = BakeLayout {
        meta: ch.reader.metadata(),
        attrs: layout_attrs(model, opts.bake_proxy),
        blocked_skeletons: blocked_skeletons(model, opts.bake_proxy),
        blocked_attrs: blocked_attrs(model),
        provenance: Provenance {
            input: std::fs::canonicalize(input)
                .unwrap_or_else(|_| input.to_path_buf())
                .to_string_lossy()
                .into_owned(),
            frames: frames_text(&times, opts.frames),
            version: env!("CARGO_PKG_VERSION").to_string(),
            // render, view and preview warn when the input changed since.
            input_stamp: Some(clips::input_stamp(&ch.reader)?),
            options: options_text(opts.bake_proxy, opts.camera.as_deref()),
            ..Default::default()
        },
    };
    let (baked, chunks) = match opts.chunk {
        None => {
            stream(
                ch,
                &times,
                opts.bake_proxy,
                bake_layer::create(output, layout)?,
                progress,
                opts.cancel.as_deref(),
            )?;
            (times.len(), Vec::new())
        }
        Some(size) => {
            layout.provenance.input_hash = Some(clips::input_hash(&ch.reader)?);
            let plan = ClipPlan::new(output, &times, size)?;
            clips::refuse_input_clip_set(&ch.reader, &layout)?;
            match (opts.chunk_index, opts.assemble) {
                (Some(k), _) => {
                    let chunk = plan.chunks.get(k).ok_or_else(|| {
                        Error::msg(format!(
                            "--chunk-index {k} is out of range: {} in chunks of {size} make {}, numbered 0 to {}",
                            crate::words::plural(times.len(), "frame"),
                            crate::words::plural(plan.chunks.len(), "chunk"),
                            plan.chunks.len() - 1
                        ))
                    })?;
                    // A task's chunk is published when it ends: had the
                    // assembly no way to write the clip set, the old set
                    // would show new chunks for good.
                    plan.check_clip_set_targets()?;
                    plan.create_dir()?;
                    let _lock = clips::lock_clips(&plan, false)?;
                    leave_binding_cache(ch, output);
                    let path = plan.chunk_path(chunk);
                    let chunk_layout = clips::chunk_layout(&layout, &plan, chunk, &times, clips::frame_step(&times));
                    let frames = &times[chunk.start..chunk.end];
                    stream(
                        ch,
                        frames,
                        opts.bake_proxy,
                        bake_layer::create(&path, chunk_layout)?,
                        progress,
                        opts.cancel.as_deref(),
                    )?;
                    (frames.len(), vec![path])
                }
                (None, true) => {
                    // No folder, no chunks: the check below says so.
                    let _lock = plan.dir.is_dir().then(|| clips::lock_clips(&plan, true)).transpose()?;
                    let hash = layout.provenance.input_hash.clone().unwrap_or_default();
                    clips::check_chunks(&plan, &hash, layout.provenance.options.as_deref(), &times)?;
                    clips::write_clip_set(&plan, &layout, &times)?;
                    (0, plan.chunks.iter().map(|c| plan.chunk_path(c)).collect())
                }
                (None, false) => {
                    let sink = Box::new(ChunkedSink::new(plan.clone(), layout, &times)?);
                    let _lock = clips::lock_clips(&plan, true)?;
                    leave_binding_cache(ch, output);
                    stream(ch, &times, opts.bake_proxy, sink, progress, opts.cancel.as_deref())?;
                    (times.len(), plan.chunks.iter().map(|c| plan.chunk_path(c)).collect())
                }
            }
        }
    };
    Ok(BakeSummary {
        input: ch.reader.file.clone(),
        output: output.to_path_buf(),
        frames: baked,
        rigs: model.rigs.len(),
        view_meshes: model.views.len(),
        layers: model.num_layers(),
        strokes: model
            .rigs
            .iter()
            .flat_map(|r| &r.layers)
            .map(|l| l.curve_counts.len())
            .sum(),
        points: model.rigs.iter().map(|r| r.num_points()).sum(),
        seconds: started.elapsed().as_secs_f64(),
        chunks,
    })
}

/// The options that change what a bake writes besides its input and frames,
/// as the CLI spells them, for the provenance ([`Provenance::options`]):
/// None without any.
pub fn options_text(bake_proxy: bool, camera: Option<&str>) -> Option<String> {
    let mut words = Vec::new();
    if bake_proxy {
        words.push("--bake-proxy".to_string());
    }
    if let Some(c) = camera {
        words.push(format!("--camera {c}"));
    }
    (!words.is_empty()).then(|| words.join(" "))
}

/// `A:B:STEP` of the baked frames, as recorded in the layer.
fn frames_text(times: &[f64], range: Option<FrameRange>) -> String {
    match (range, times) {
        (Some(r), _) => format!("{}:{}:{}", r.start, r.end, r.step),
        (None, [first, .., last]) => format!("{first}:{last}:1"),
        (None, [only]) => format!("{only}:{only}:1"),
        (None, []) => String::new(),
    }
}

/// The attributes a bake writes, in the order [`frame_samples`] fills them:
/// per stroke layer points, extent, displayOpacity (and normals, when it
/// has rest normals); per rig (with
/// `--bake-proxy`) the proxy's points and extent; per view-dependent mesh
/// its points and extent.
fn layout_attrs(model: &Model, bake_proxy: bool) -> Vec<BakeAttr> {
    let attr = |prim: &str, name, kind, interpolation| BakeAttr {
        prim: prim.to_string(),
        name,
        kind,
        interpolation,
    };
    let mut attrs = Vec::new();
    for rig in &model.rigs {
        for l in &rig.layers {
            attrs.push(attr(&l.path, "points", SampleKind::Points, None));
            attrs.push(attr(&l.path, "extent", SampleKind::Extent, None));
            attrs.push(attr(
                &l.path,
                "primvars:displayOpacity",
                SampleKind::Floats,
                Some("uniform"),
            ));
            if let Some(n) = &l.rest_normals {
                attrs.push(attr(&l.path, n.attr, SampleKind::Normals, None));
            }
        }
    }
    if bake_proxy {
        for rig in baked_proxies(model) {
            attrs.push(attr(&rig.proxy_path, "points", SampleKind::Points, None));
            attrs.push(attr(&rig.proxy_path, "extent", SampleKind::Extent, None));
            if rig.proxy_normals {
                attrs.push(attr(&rig.proxy_path, "normals", SampleKind::Normals, None));
            }
        }
    }
    for v in &model.views {
        attrs.push(attr(&v.path, "points", SampleKind::Points, None));
        attrs.push(attr(&v.path, "extent", SampleKind::Extent, None));
    }
    attrs
}

/// Per rig, whether `--bake-proxy` writes its proxy: once per proxy mesh,
/// and not when the proxy is also a view-dependent mesh (its view-dependent
/// points are what the bake shows).
fn baked_proxy_mask(model: &Model) -> Vec<bool> {
    (0..model.rigs.len())
        .map(|i| {
            let p = &model.rigs[i].proxy_path;
            !model.views.iter().any(|v| &v.path == p) && !model.rigs[..i].iter().any(|o| &o.proxy_path == p)
        })
        .collect()
}

fn baked_proxies(model: &Model) -> impl Iterator<Item = &RigModel> {
    model
        .rigs
        .iter()
        .zip(baked_proxy_mask(model))
        .filter(|(_, keep)| *keep)
        .map(|(r, _)| r)
}

/// Indices the bake blocks: of `primvars:displayOpacity` (it writes one
/// value per curve) and of `primvars:normals` (one per point), which the
/// input's indices would re-index.
fn blocked_attrs(model: &Model) -> Vec<BlockedAttr> {
    let layers = model.rigs.iter().flat_map(|r| &r.layers);
    let opacity = layers.clone().filter(|l| l.display_indexed).map(|l| BlockedAttr {
        prim: l.path.clone(),
        name: "primvars:displayOpacity:indices",
        type_name: "int[]",
    });
    // Likewise an indexed `primvars:normals`: the bake writes one per point.
    let normals = layers
        .filter(|l| l.rest_normals.as_ref().is_some_and(|n| n.indexed))
        .map(|l| BlockedAttr {
            prim: l.path.clone(),
            name: "primvars:normals:indices",
            type_name: "int[]",
        });
    opacity.chain(normals).collect()
}

/// Baked skinned meshes: their `skel:skeleton` is blocked so viewers do not
/// deform them twice.
fn blocked_skeletons(model: &Model, bake_proxy: bool) -> Vec<String> {
    let proxies = baked_proxies(model)
        .filter(|r| bake_proxy && r.proxy_skinned)
        .map(|r| r.proxy_path.clone());
    let views = model.views.iter().filter(|v| v.skinned).map(|v| v.path.clone());
    proxies.chain(views).collect()
}

/// One frame's samples in [`layout_attrs`] order (extents computed here, on
/// the worker thread).
fn frame_samples(out: FrameOutput, baked_proxy: &[bool]) -> Vec<Sample> {
    let extent = |p: &[Vec3]| Sample::Vec3s(point_based_extent(p).to_vec());
    let mut s = Vec::with_capacity(3 * out.layers.len() + 2 * (out.proxies.len() + out.views.len()));
    for l in out.layers {
        let e = Sample::Vec3s(pad_curves_extent(l.bounds, l.max_width).to_vec());
        s.push(Sample::Vec3s(l.points));
        s.push(e);
        s.push(Sample::Floats(l.opacity));
        if let Some(n) = l.normals {
            s.push(Sample::Vec3s(n));
        }
    }
    let proxies = out.proxies.into_iter().zip(out.proxy_normals);
    for ((p, n), _) in proxies.zip(baked_proxy).filter(|(_, &keep)| keep) {
        let Some(p) = p else { continue };
        let e = extent(&p);
        s.push(Sample::Vec3s(p));
        s.push(e);
        if let Some(n) = n {
            s.push(Sample::Vec3s(n));
        }
    }
    for v in out.views {
        let e = extent(&v);
        s.push(Sample::Vec3s(v));
        s.push(e);
    }
    s
}

/// Streams every frame through read (this thread) → evaluate (thread pool)
/// → write (a writer thread, in time order), with a bounded window of frames
/// in flight.
fn stream(
    ch: &Character,
    times: &[f64],
    with_proxies: bool,
    sink: Box<dyn FrameSink>,
    progress: Progress,
    cancel: Option<&AtomicBool>,
) -> Result<()> {
    let model: &Model = &ch.model;
    let mask = baked_proxy_mask(model);
    let evaluate = |input| model.evaluate(input, with_proxies).map(|o| frame_samples(o, &mask));
    stream_with(ch, times, &evaluate, sink, progress, cancel)
}

/// Evaluates one frame's input into its samples.
type FrameStep<'a> = dyn Fn(FrameInput) -> Result<Vec<Sample>> + Sync + 'a;

/// [`stream`] with the evaluation step given.
fn stream_with(
    ch: &Character,
    times: &[f64],
    evaluate: &FrameStep,
    mut sink: Box<dyn FrameSink>,
    progress: Progress,
    cancel: Option<&AtomicBool>,
) -> Result<()> {
    let window = 2 * rayon::current_num_threads() + 2;
    let (done_tx, done_rx) = mpsc::sync_channel::<(usize, Result<Vec<Sample>>)>(window);
    // A permit per frame in flight: taken before a read, returned by the writer.
    let (permit_tx, permit_rx) = mpsc::sync_channel::<()>(window);
    for _ in 0..window {
        let _ = permit_tx.send(());
    }
    let total = times.len();
    // Time spent in each stage, for --verbose (evaluation summed over threads).
    let evaluating = std::sync::atomic::AtomicU64::new(0);
    let evaluating = &evaluating;
    // A panic while evaluating a frame (a bug) is kept here and raised again
    // once the pipeline is down: the frame it lost would otherwise leave the
    // writer waiting for it and the reader waiting for a permit.
    let panicked = std::sync::Mutex::new(None);
    let panicked = &panicked;
    let started = Instant::now();
    let opened = ch.reader.opened.clone();
    let result = std::thread::scope(|s| {
        let writer = s.spawn(move || -> Result<f64> {
            let mut pending = BTreeMap::new();
            let mut next = 0;
            let mut writing = 0.0;
            for (i, frame) in done_rx {
                pending.insert(i, frame);
                while let Some(frame) = pending.remove(&next) {
                    let t0 = Instant::now();
                    sink.write_frame(times[next], frame?)?;
                    writing += t0.elapsed().as_secs_f64();
                    next += 1;
                    progress(next, total);
                    let _ = permit_tx.send(());
                }
            }
            if next < total {
                // The reader stopped early; its error is the one to report.
                return Err(Error::msg("bake stopped before the last frame"));
            }
            if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                // Stopped after the last frame: the output is still not replaced.
                return Err(Error::msg(INTERRUPTED));
            }
            // A save in place (usd-core writes a .usdc into the same file)
            // changes mapped pages under the reader: refuse what may mix two
            // versions before it replaces the output.
            crate::usd_io::stage::check_unchanged(&opened)?;
            let t0 = Instant::now();
            sink.finish()?;
            Ok(writing + t0.elapsed().as_secs_f64())
        });
        let mut reading = 0.0;
        let read = rayon::in_place_scope(|scope| -> Result<()> {
            for (i, &t) in times.iter().enumerate() {
                if permit_rx.recv().is_err() {
                    break; // the writer failed; it reports why
                }
                if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                    return Err(Error::msg(INTERRUPTED));
                }
                let t0 = Instant::now();
                let input = ch.read_frame(t)?;
                reading += t0.elapsed().as_secs_f64();
                let tx = done_tx.clone();
                scope.spawn(move |_| {
                    let t0 = Instant::now();
                    let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| evaluate(input)))
                        .unwrap_or_else(|payload| {
                            panicked
                                .lock()
                                .unwrap_or_else(|e| e.into_inner())
                                .get_or_insert(payload);
                            Err(Error::msg("internal error: evaluating a frame panicked"))
                        });
                    let ns = t0.elapsed().as_nanos() as u64;
                    evaluating.fetch_add(ns, std::sync::atomic::Ordering::Relaxed);
                    let _ = tx.send((i, out));
                });
            }
            Ok(())
        });
        drop(done_tx);
        let written = writer
            .join()
            .unwrap_or_else(|payload| std::panic::resume_unwind(payload));
        read.and(written).map(|writing| (reading, writing))
    });
    if let Some(payload) = panicked.lock().unwrap_or_else(|e| e.into_inner()).take() {
        std::panic::resume_unwind(payload);
    }
    let (reading, writing) = result?;
    crate::vlog!(
        "{}: read {reading:.3} s, evaluate {:.3} s (summed over threads), write {writing:.3} s; {:.3} s wall",
        crate::words::plural(total, "frame"),
        evaluating.load(std::sync::atomic::Ordering::Relaxed) as f64 * 1e-9,
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::any::Any;
    use std::sync::Mutex;
    use std::time::Duration;

    #[test]
    fn a_chunked_bake_of_unsaved_edits_is_refused_and_a_single_one_is_marked() {
        // The Python package marks a layer with unsaved edits; the CLI never does.
        let dir = crate::test_dir::ScratchDir::new("bake-unsaved");
        let unsaved = || {
            let mut r = StageReader::open_mapped(&tube())?;
            r.unsaved = true;
            Ok(r)
        };
        let chunked = BakeOptions {
            chunk: Some(8),
            ..Default::default()
        };
        let e = bake_with(&tube(), &dir.join("clips.usda"), &chunked, &|_, _| {}, unsaved).unwrap_err();
        assert!(e.to_string().contains("a chunked bake needs the input saved"), "{e}");
        assert_eq!(
            std::fs::read_dir(&*dir).unwrap().count(),
            0,
            "a refused bake wrote files"
        );
        let out = dir.join("one.usda");
        bake_with(&tube(), &out, &BakeOptions::default(), &|_, _| {}, unsaved).unwrap();
        let p = crate::usd_io::bake_layer::read_provenance(&out).unwrap().unwrap();
        assert!(p.input_stamp.unwrap().starts_with(crate::usd_io::clips::UNSAVED_STAMP));
        // Saved (the CLI's reader): chunks are baked.
        let saved = || StageReader::open_mapped(&tube());
        bake_with(&tube(), &dir.join("clips.usda"), &chunked, &|_, _| {}, saved).unwrap();
    }

    /// The tube fixture: 24 frames.
    fn tube() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/tube.usda")
    }

    /// Streams the 24 frames of `src` (the tube or a copy) through
    /// `evaluate` into `sink`, on a thread of its own inside a rayon pool of
    /// `threads` (the global pool when None), and fails the test if that
    /// takes a minute (a hang) instead of returning or panicking.
    fn stream_file<E>(
        src: PathBuf,
        threads: Option<usize>,
        evaluate: E,
        sink: Box<dyn FrameSink>,
        cancel: Option<Arc<AtomicBool>>,
    ) -> std::result::Result<Result<()>, Box<dyn Any + Send>>
    where
        E: Fn(FrameInput) -> Result<Vec<Sample>> + Sync + Send + 'static,
    {
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let run = move || {
                // Opened on the thread that reads (a stage stays on one thread).
                let ch = Character::open(&src, None).unwrap();
                let times = resolve_frames(&ch.reader, None).unwrap();
                assert_eq!(times.len(), 24);
                stream_with(&ch, &times, &evaluate, sink, &|_, _| {}, cancel.as_deref())
            };
            let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match threads {
                Some(n) => rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .unwrap()
                    .install(run),
                None => run(),
            }));
            let _ = tx.send(out);
        });
        rx.recv_timeout(Duration::from_secs(60))
            .expect("the stream hung instead of ending")
    }

    fn stream_tube<E>(evaluate: E, sink: Box<dyn FrameSink>) -> std::result::Result<Result<()>, Box<dyn Any + Send>>
    where
        E: Fn(FrameInput) -> Result<Vec<Sample>> + Sync + Send + 'static,
    {
        stream_file(tube(), None, evaluate, sink, None)
    }

    /// A sink recording the times it was given and whether it was
    /// finished; `panic_at` panics there.
    struct Recorder {
        times: std::sync::Arc<Mutex<Vec<f64>>>,
        finished: std::sync::Arc<std::sync::atomic::AtomicBool>,
        panic_at: Option<f64>,
    }

    impl FrameSink for Recorder {
        fn write_frame(&mut self, time: f64, _samples: Vec<Sample>) -> Result<()> {
            assert_ne!(Some(time), self.panic_at, "writer bug at {time}");
            self.times.lock().unwrap().push(time);
            Ok(())
        }

        fn finish(self: Box<Self>) -> Result<()> {
            self.finished.store(true, std::sync::atomic::Ordering::SeqCst);
            Ok(())
        }
    }

    type Written = std::sync::Arc<Mutex<Vec<f64>>>;
    type Finished = std::sync::Arc<std::sync::atomic::AtomicBool>;

    fn recorder(panic_at: Option<f64>) -> (Box<dyn FrameSink>, Written, Finished) {
        let times = Written::default();
        let finished = Finished::default();
        let sink = Recorder {
            times: times.clone(),
            finished: finished.clone(),
            panic_at,
        };
        (Box::new(sink), times, finished)
    }

    fn message(payload: &(dyn Any + Send)) -> String {
        payload
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
            .unwrap_or_default()
    }

    #[test]
    fn a_cancelled_stream_stops_before_its_next_frame_and_is_not_finished() {
        // Cancelled while frame 5 evaluates: no frame read after that is
        // written, and the sink (the output's rename) is never finished.
        let cancel = Arc::new(AtomicBool::new(false));
        let flag = cancel.clone();
        let evaluate = move |input: FrameInput| {
            if input.time == 5.0 {
                flag.store(true, Ordering::SeqCst);
            }
            Ok(Vec::new())
        };
        let (sink, written, finished) = recorder(None);
        let err = stream_file(tube(), None, evaluate, sink, Some(cancel))
            .unwrap()
            .unwrap_err();
        assert_eq!(err.message, INTERRUPTED);
        assert!(!finished.load(Ordering::SeqCst));
        let written = written.lock().unwrap();
        // At most a window of frames (2 × threads + 2) was read before the flag.
        let window = 2 * rayon::current_num_threads() + 2;
        assert!(written.iter().all(|&t| t <= 5.0 + window as f64), "{written:?}");
    }

    #[test]
    fn every_frame_reaches_the_sink_in_time_order() {
        let (sink, written, _) = recorder(None);
        stream_tube(|_| Ok(Vec::new()), sink).unwrap().unwrap();
        assert_eq!(*written.lock().unwrap(), (1..=24).map(f64::from).collect::<Vec<_>>());
    }

    #[test]
    fn a_frame_that_panics_ends_the_stream_with_its_panic() {
        // A bug at one frame must reach main's handler (exit 3), not leave
        // the writer waiting for the lost frame and the reader for a permit.
        let (sink, written, _) = recorder(None);
        let evaluate = |input: FrameInput| {
            assert!(input.time != 3.0, "evaluation bug at frame 3");
            Ok(Vec::new())
        };
        let payload = stream_tube(evaluate, sink).expect_err("the panic is raised again");
        assert_eq!(message(payload.as_ref()), "evaluation bug at frame 3");
        assert_eq!(*written.lock().unwrap(), vec![1.0, 2.0]);
    }

    #[test]
    fn a_writer_that_panics_ends_the_stream_with_its_panic() {
        let (sink, written, _) = recorder(Some(5.0));
        let payload = stream_tube(|_| Ok(Vec::new()), sink).expect_err("the panic is raised again");
        assert!(
            message(payload.as_ref()).contains("writer bug at 5"),
            "{}",
            message(payload.as_ref())
        );
        assert_eq!(*written.lock().unwrap(), vec![1.0, 2.0, 3.0, 4.0]);
    }

    #[test]
    fn a_frame_that_fails_ends_the_stream_with_its_error() {
        let (sink, written, _) = recorder(None);
        let evaluate = |input: FrameInput| {
            if input.time == 7.0 {
                return Err(Error::msg("frame 7 cannot be evaluated"));
            }
            Ok(Vec::new())
        };
        let err = stream_tube(evaluate, sink).unwrap().unwrap_err();
        assert_eq!(err.to_string(), "frame 7 cannot be evaluated");
        assert_eq!(*written.lock().unwrap(), (1..=6).map(f64::from).collect::<Vec<_>>());
    }

    /// The tube fixture with `painterly:opacity` on /Tube/Paint/Rings keyed
    /// 1 at frames 1, 4 and 6 and 1e39 at frame 5: beyond f32, so frame 5
    /// reads as an infinite opacity, which reading refuses (`opacity_at`).
    fn tube_unreadable_at_frame_5(dir: &Path) -> PathBuf {
        let tube = std::fs::read_to_string(tube()).unwrap();
        let anchor = "            int[] curveVertexCounts = [10, 10";
        let at = tube.find(anchor).expect("the Rings layer's counts");
        let keyed = "            float painterly:opacity.timeSamples = {\n                1: 1,\n                4: 1,\n                5: 1e39,\n                6: 1,\n            }\n";
        let src = dir.join("tube.usda");
        std::fs::write(&src, format!("{}{keyed}{}", &tube[..at], &tube[at..])).unwrap();
        src
    }

    #[test]
    fn a_frame_that_cannot_be_read_ends_the_stream_unfinished_with_its_error() {
        // The reader (not an evaluation) fails at frame 5: frames 1-4 are
        // written, the sink is never finished (a finished sink is a written
        // file, which a failed bake must not leave), and the error is the
        // reader's.
        let dir = crate::test_dir::ScratchDir::new("bake-unreadable-frame");
        let (sink, times, finished) = recorder(None);
        let result = stream_file(tube_unreadable_at_frame_5(&dir), None, |_| Ok(Vec::new()), sink, None).unwrap();
        let err = result.expect_err("reading frame 5 fails").to_string();
        assert!(err.contains("opacity is not finite at time 5"), "{err}");
        assert_eq!(*times.lock().unwrap(), vec![1.0, 2.0, 3.0, 4.0]);
        let finished = finished.load(std::sync::atomic::Ordering::SeqCst);
        assert!(!finished, "a failed stream finished its sink");
    }

    #[test]
    fn a_busy_writer_lets_the_reader_run_ahead_by_the_window_exactly() {
        // The window of frames in flight is 2 * threads + 2 (docs/testing.md):
        // with the writer held on the first frame, the reader reads (and the
        // pool evaluates) exactly that many frames, then waits for a permit:
        // no more (memory stays bounded), no fewer (every worker has work).
        // Three threads, so that 2t + 2 = 8 differs from 4t, t + 4, 2/t + 2
        // and 2t - 2. Run inside the pool, whose thread count the window
        // reads; the reader takes one worker, the other two evaluate.
        const THREADS: usize = 3;
        const WINDOW: usize = 2 * THREADS + 2;
        struct Held {
            evaluated: std::sync::Arc<std::sync::atomic::AtomicUsize>,
            in_flight: std::sync::Arc<Mutex<Option<usize>>>,
        }
        impl FrameSink for Held {
            fn write_frame(&mut self, _time: f64, _samples: Vec<Sample>) -> Result<()> {
                let mut seen = self.in_flight.lock().unwrap();
                if seen.is_none() {
                    let count = || self.evaluated.load(std::sync::atomic::Ordering::SeqCst);
                    // Generous: a starved test machine may take seconds to
                    // schedule the pool; a working stream returns at once.
                    let deadline = Instant::now() + Duration::from_secs(120);
                    while count() < WINDOW && Instant::now() < deadline {
                        std::thread::sleep(Duration::from_millis(5));
                    }
                    // Time for a larger window to show itself.
                    std::thread::sleep(Duration::from_millis(500));
                    *seen = Some(count());
                }
                Ok(())
            }

            fn finish(self: Box<Self>) -> Result<()> {
                Ok(())
            }
        }
        let evaluated = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let in_flight = std::sync::Arc::new(Mutex::new(None));
        let sink = Box::new(Held {
            evaluated: evaluated.clone(),
            in_flight: in_flight.clone(),
        });
        let counter = evaluated.clone();
        let evaluate = move |_: FrameInput| {
            counter.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
            Ok(Vec::new())
        };
        stream_file(tube(), Some(THREADS), evaluate, sink, None)
            .unwrap()
            .unwrap();
        assert_eq!(*in_flight.lock().unwrap(), Some(WINDOW));
        assert_eq!(evaluated.load(std::sync::atomic::Ordering::SeqCst), 24);
    }

    #[test]
    fn a_render_bakes_a_painted_stage_and_skips_a_plain_one() {
        // bake_if_any: the tube (two stroke layers under one rig, frames
        // 1..24, as usd-core reads fixtures/tube.usda) is baked into the
        // output; a stage with no rig and no view-dependent mesh writes
        // nothing and answers None.
        let dir = crate::test_dir::ScratchDir::new("bake-if-any");
        let tube = tube();
        let out = dir.join("tube_bake.usdc");
        let (s, opened) = bake_if_any(&tube, &out, &BakeOptions::default())
            .unwrap()
            .expect("the tube has strokes to bake");
        assert_eq!(opened.keys().collect::<Vec<_>>(), [&tube]);
        assert_eq!((s.frames, s.rigs, s.layers), (24, 1, 2));
        assert!(std::fs::metadata(&out).unwrap().len() > 1000, "a baked layer");
        let plain = dir.join("plain.usda");
        std::fs::write(
            &plain,
            "#usda 1.0\n(\n    startTimeCode = 1\n    endTimeCode = 3\n)\n\ndef Xform \"Plain\"\n{\n}\n",
        )
        .unwrap();
        let none = dir.join("plain_bake.usdc");
        assert!(bake_if_any(&plain, &none, &BakeOptions::default()).unwrap().is_none());
        assert!(!none.exists());
    }
}
