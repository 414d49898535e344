//! The evaluator thread: owns the [`Character`] (its stage is `Rc`-based,
//! so it stays on one thread) and answers jobs sent over a channel by the
//! async handlers. Every frame goes through the same library code as
//! `bake` ([`Character::read_frame_seen_from`] + [`Model::evaluate`]), one
//! frame at a time, nothing written.
//!
//! [`Model::evaluate`]: crate::character::Model::evaluate

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Instant;

use glam::{DMat4, DVec3, Vec3};
use tokio::sync::oneshot;

use super::protocol::{
    AxisInfo, Buffer, FrameRequest, KeyMark, LayerInfo, MeshInfo, ProblemInfo, RenderRequest, SceneInfo, StartView,
    ViewCamera,
};
use crate::character::{key_weights, Character, FrameOutput};
use crate::error::{Error, Result};
use crate::render::camera::{CameraParams, Projection};
use crate::render::curves::{CurvesData, Primvar};
use crate::render::prepare::MeshData;
use crate::render::{check_bake, render_png, write_root, ImageSize, TempDir};
use crate::usd_io::render_scene::{RenderScene, DEFAULT_COLOR, DEFAULT_WIDTH};
use crate::usd_io::scene::read_face_topology;
use crate::usd_io::stage::StageReader;
use crate::usd_io::values;

/// Why a job failed.
#[derive(Debug, Clone, PartialEq)]
pub enum JobError {
    /// The character cannot be evaluated as asked (HTTP 422).
    Unprocessable(String),
    /// The evaluator failed or is gone (HTTP 500).
    Internal(String),
}

type Reply = oneshot::Sender<std::result::Result<Vec<u8>, JobError>>;

enum Job {
    Frame(FrameRequest, Reply),
    Render(RenderRequest, Reply),
}

/// A handle on the evaluator thread, shared by every handler.
pub struct Evaluator {
    jobs: mpsc::Sender<Job>,
    /// What the page needs once.
    pub scene: SceneInfo,
    /// Per-point stroke widths and colours ([`Buffer`] bytes).
    pub strokes: Vec<u8>,
    /// Every axis path, for checking requests.
    pub axes: Vec<String>,
}

impl Evaluator {
    /// Opens the character on a new thread and waits until it is ready.
    pub fn start(input: &Path, camera: Option<&str>, bake: Option<&Path>) -> Result<Evaluator> {
        let (ready_tx, ready_rx) = mpsc::channel();
        let (jobs, rx) = mpsc::channel::<Job>();
        let input: PathBuf = input.to_path_buf();
        let camera = camera.map(str::to_string);
        let bake = bake.map(Path::to_path_buf);
        std::thread::Builder::new()
            .name("painterly-evaluator".into())
            .spawn(move || {
                let state = match State::open(&input, camera.as_deref(), bake.as_deref()) {
                    Ok((state, scene, strokes)) => {
                        let _ = ready_tx.send(Ok((scene, strokes)));
                        state
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e.in_file(&input)));
                        return;
                    }
                };
                for job in rx {
                    state.run(job);
                }
            })
            .map_err(|e| Error::msg(format!("cannot start the evaluator thread: {e}")))?;
        let (scene, strokes) = ready_rx
            .recv()
            .map_err(|_| Error::msg("the evaluator thread stopped while opening the character"))??;
        let axes = scene.axes.iter().map(|a| a.path.clone()).collect();
        Ok(Evaluator {
            jobs,
            scene,
            strokes,
            axes,
        })
    }

    /// Evaluates one frame: a binary reply (docs/preview.md).
    pub async fn frame(&self, req: FrameRequest) -> std::result::Result<Vec<u8>, JobError> {
        let (tx, rx) = oneshot::channel();
        self.send(Job::Frame(req, tx))?;
        rx.await.map_err(|_| gone())?
    }

    /// Renders the current view with `painterly render`'s renderer: PNG bytes.
    pub async fn render(&self, req: RenderRequest) -> std::result::Result<Vec<u8>, JobError> {
        let (tx, rx) = oneshot::channel();
        self.send(Job::Render(req, tx))?;
        rx.await.map_err(|_| gone())?
    }

    fn send(&self, job: Job) -> std::result::Result<(), JobError> {
        self.jobs.send(job).map_err(|_| gone())
    }
}

fn gone() -> JobError {
    JobError::Internal("the evaluator thread has stopped".into())
}

/// The evaluator thread's side.
struct State {
    ch: Character,
    /// Drawables of the input, for the render button.
    drawables: RenderScene,
    layers: Vec<String>,
    views: Vec<String>,
    proxies: Vec<String>,
    /// The `--bake` layer composed over the input.
    bake: Option<Bake>,
    /// The input's files as opened ([`crate::usd_io::clips::input_stamp`]):
    /// the server reads them once, so an edit saved later is not shown, and
    /// every frame says so.
    opened: String,
}

/// Server-side timings of one frame, milliseconds.
#[derive(serde::Serialize)]
struct Timing {
    read_ms: f64,
    evaluate_ms: f64,
    encode_ms: f64,
    total_ms: f64,
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

fn mat(m: &DMat4) -> impl Iterator<Item = f32> {
    m.to_cols_array().into_iter().map(|x| x as f32)
}

/// The bake layer to show: checked against the input, and opened through
/// a root layer that puts it over the input, as `painterly view` does.
/// `opened` is the input's stage, open already.
fn open_bake(
    input: &Path,
    opened: &StageReader,
    b: &Path,
    start: f64,
    end: f64,
    warnings: &mut Vec<String>,
) -> Result<Bake> {
    crate::usd_io::stage::require_file(b, "bake layer")?;
    check_bake(input, Some(opened), b, &[start, end], warnings)?;
    let folder = TempDir::new()?;
    let root = write_root(folder.path(), input, Some(b))?;
    let reader = StageReader::open(&root).map_err(|e| e.in_file(b))?;
    // Drawables read through their own stage's attributes: the input's
    // would show the input's points, not the bake's.
    let drawables = RenderScene::discover_drawables(&reader).map_err(|e| e.in_file(b))?;
    let opened = crate::usd_io::clips::input_stamp(&reader).map_err(|e| e.in_file(b))?;
    Ok(Bake {
        _folder: folder,
        reader,
        drawables,
        opened,
    })
}

/// Whether a file `r` reads has changed on disk since its stamp was
/// `opened`. The stamp fails on a file changed since the reader read it
/// (or gone): changed too.
fn changed(r: &StageReader, opened: &str) -> bool {
    crate::usd_io::clips::input_stamp(r).map_or(true, |now| now != opened)
}

/// The `--bake` layer composed over the input, and what `render` draws of it.
struct Bake {
    /// The folder of the composing root layer, kept as long as the reader.
    _folder: TempDir,
    reader: StageReader,
    drawables: RenderScene,
    /// The bake's and the input's files as opened, as [`State::stale`] does.
    opened: String,
}

/// The stage's problems as `inspect` finds them, then the bake's warnings.
fn stage_problems(report: &Result<crate::inspect::Report>, warnings: Vec<String>) -> Vec<ProblemInfo> {
    let mut problems = match report {
        Ok(rep) => rep
            .problems
            .iter()
            .map(|p| ProblemInfo {
                prim: p.prim.clone(),
                attribute: p.attribute.clone(),
                message: p.message.clone(),
            })
            .collect(),
        Err(e) => vec![ProblemInfo {
            prim: None,
            attribute: None,
            message: e.to_string(),
        }],
    };
    problems.extend(warnings.into_iter().map(|message| ProblemInfo {
        prim: None,
        attribute: None,
        message,
    }));
    problems
}

/// One configuration axis of a rig: its keys' coordinates on it (from
/// every layer it drives), and a slider range that holds them and the
/// values the axis takes over the shot.
fn axis_info(
    r: &StageReader,
    rig: &crate::character::RigModel,
    ai: usize,
    kind: String,
    configurations: &[crate::character::Configuration],
) -> Result<AxisInfo> {
    let path = &rig.axes[ai];
    let mut keys = Vec::new();
    for layer in &rig.layers {
        let Some(j) = layer.keys.axes.iter().position(|&a| a == ai) else {
            continue;
        };
        let mut paths: Vec<&String> = Vec::new();
        if let Some(c) = &layer.keys.pose_points {
            paths.extend(&c.paths);
        }
        if let Some(c) = &layer.keys.pose_opacity {
            paths.extend(c.paths.iter().filter(|p| !paths.contains(p)).collect::<Vec<_>>());
        }
        for key in paths {
            let prim = r.require_prim(key)?;
            let coords = r
                .typed(&prim, "coordinates", None, "float[]", values::f32_array)?
                .unwrap_or_default();
            if let Some(&c) = coords.get(j) {
                keys.push(KeyMark {
                    key: key.clone(),
                    coordinate: c as f64,
                });
            }
        }
    }
    let values = keys
        .iter()
        .map(|k| k.coordinate)
        .chain(configurations.iter().filter_map(|c| c.get(path).copied()));
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 1.0) };
    let pad = if hi - lo > 1e-9 { 0.1 * (hi - lo) } else { 1.0 };
    Ok(AxisInfo {
        path: path.clone(),
        rig: rig.path.clone(),
        kind,
        min: lo - pad,
        max: hi + pad,
        keys,
    })
}

/// The strokes' widths and colours, read once (widths in each layer's own
/// space, which the page scales by the frame's `layer/{i}/xform`; linear
/// colours), as one binary buffer; read from layers hidden at `start` too,
/// which may show later (each frame says which are hidden).
fn stroke_buffer(r: &StageReader, drawables: &RenderScene, start: f64, layer_infos: &[LayerInfo]) -> Result<Vec<u8>> {
    let curves = drawables.curves_at_any_visibility(r, start)?;
    let mut strokes = Buffer::default();
    for (i, info) in layer_infos.iter().enumerate() {
        let n = info.points;
        let c = curves
            .iter()
            .find(|c| c.path == info.path && c.points.len() == n && c.counts.len() == info.curve_counts.len());
        let (widths, colors) = match c {
            Some(c) => (
                per_point(c, &c.widths, &info.curve_counts, DEFAULT_WIDTH),
                per_point(c, &c.colors, &info.curve_counts, DEFAULT_COLOR),
            ),
            None => (vec![DEFAULT_WIDTH; n], vec![DEFAULT_COLOR; n]),
        };
        strokes.push(format!("layer/{i}/widths"), widths);
        strokes.push(format!("layer/{i}/colors"), colors.iter().flat_map(|c| c.to_array()));
    }
    Ok(strokes.finish(serde_json::json!({ "layers": layer_infos.len() })))
}

impl State {
    fn open(input: &Path, camera: Option<&str>, bake: Option<&Path>) -> Result<(State, SceneInfo, Vec<u8>)> {
        let ch = Character::open(input, camera)?;
        let r = &ch.reader;
        let opened = crate::usd_io::clips::input_stamp(r)?;
        let meta = r.metadata();
        let start = meta.start_time_code.unwrap_or(0.0);
        let end = meta.end_time_code.unwrap_or(start).max(start);
        let mut warnings = Vec::new();
        let bake_path = bake.map(|b| b.display().to_string());
        let bake = match bake {
            Some(b) => Some(open_bake(input, r, b, start, end, &mut warnings)?),
            None => None,
        };
        // The stage checks of `inspect`, on the stage already open; not its
        // every-frame evaluation, which would make each reload as slow as a
        // bake: a frame that fails to evaluate is reported when shown.
        let report = crate::inspect::inspect_stage(r);
        let problems = stage_problems(&report, warnings);
        let time_keys: Vec<(String, usize)> = report
            .as_ref()
            .map(|rep| {
                rep.rigs
                    .iter()
                    .flat_map(|r| r.layers.iter().map(|l| (l.path.clone(), l.time_keys)))
                    .collect()
            })
            .unwrap_or_default();
        let axis_kinds: Vec<(String, String)> = report
            .as_ref()
            .map(|rep| {
                rep.axes
                    .iter()
                    .filter_map(|a| Some((a.path.clone(), a.kind.clone()?)))
                    .collect()
            })
            .unwrap_or_default();

        // The start view: the --camera, else a view-dependent mesh's camera.
        let start_camera = camera
            .map(str::to_string)
            .or_else(|| ch.model.views.first().map(|v| v.camera.clone()));
        let (drawables, cam_params) = match start_camera.as_deref().map(|c| RenderScene::discover(r, c)) {
            Some(Ok(s)) => {
                let p = s.camera_at(r, start).ok();
                (s, p)
            }
            _ => (RenderScene::discover_drawables(r)?, None),
        };

        let mut layers = Vec::new();
        let mut layer_infos = Vec::new();
        let mut axes = Vec::new();
        let configurations = sample_configurations(&ch, start, end)?;
        for rig in &ch.model.rigs {
            for (ai, path) in rig.axes.iter().enumerate() {
                let kind = axis_kinds
                    .iter()
                    .find(|(p, _)| p == path)
                    .map(|(_, k)| k.clone())
                    .unwrap_or_default();
                axes.push(axis_info(r, rig, ai, kind, &configurations)?);
            }
            for layer in &rig.layers {
                let k = &layer.keys;
                layer_infos.push(LayerInfo {
                    path: layer.path.clone(),
                    rig: rig.path.clone(),
                    strokes: layer.curve_counts.len(),
                    points: layer.rest_points.len(),
                    pose_position_keys: k.pose_points.as_ref().map_or(0, |c| c.paths.len()),
                    pose_opacity_keys: k.pose_opacity.as_ref().map_or(0, |c| c.paths.len()),
                    time_keys: time_keys.iter().find(|(p, _)| *p == layer.path).map_or(0, |(_, n)| *n),
                    sentinels: k.sentinels,
                    curve_counts: layer.curve_counts.clone(),
                    axes: k.axes.iter().map(|&a| rig.axes[a].clone()).collect(),
                });
                layers.push(layer.path.clone());
            }
        }

        // Widths and colours, read once (world-space widths, linear colours).
        let strokes = stroke_buffer(r, &drawables, start, &layer_infos)?;

        // Meshes: view-dependent ones as drawn, proxies as topology.
        let meshes = drawables.meshes_at_any_visibility(r, start)?;
        let mut view_infos = Vec::new();
        for v in &ch.model.views {
            view_infos.push(mesh_info(r, &v.path, &meshes, Some(v.camera.clone()))?);
        }
        let mut proxy_infos = Vec::new();
        for rig in &ch.model.rigs {
            proxy_infos.push(mesh_info(r, &rig.proxy_path, &meshes, None)?);
        }

        let state = State {
            layers,
            views: ch.model.views.iter().map(|v| v.path.clone()).collect(),
            proxies: ch.model.rigs.iter().map(|r| r.proxy_path.clone()).collect(),
            drawables,
            ch,
            bake,
            opened,
        };
        let out = state.evaluate(&FrameRequest {
            id: 0,
            time: start,
            overrides: Default::default(),
            eye: None,
            proxy: true,
            bake: false,
        })?;
        let bounds = state.world_bounds(start, &out)?;
        let up_axis = meta.up_axis.clone().unwrap_or_else(|| "Y".into());
        let view = start_view(cam_params.as_ref(), start_camera, &bounds, &up_axis);
        let scene = SceneInfo {
            file: input.display().to_string(),
            start,
            end,
            frames_per_second: meta.frames_per_second.or(meta.time_codes_per_second).unwrap_or(24.0),
            up_axis,
            layers: layer_infos,
            axes,
            proxies: proxy_infos,
            views: view_infos,
            problems,
            view,
            bounds: [bounds[0].to_array(), bounds[1].to_array()],
            bake: state.bake.as_ref().and(bake_path),
        };
        Ok((state, scene, strokes))
    }

    fn run(&self, job: Job) {
        // A job whose client has gone (its reply dropped) is skipped: the
        // frames queued behind it are the ones still wanted.
        match job {
            Job::Frame(_, reply) | Job::Render(_, reply) if reply.is_closed() => {
                crate::vlog!("preview: a request skipped (its client has gone)");
            }
            // Logged before the reply is sent: once a client has its
            // answer, the line is there.
            Job::Frame(req, reply) => {
                let t0 = Instant::now();
                let answer = guarded(|| self.frame(&req));
                crate::vlog!(
                    "preview: frame request {} at time {} in {:.1} ms",
                    req.id,
                    req.time,
                    ms(t0)
                );
                let _ = reply.send(answer);
            }
            Job::Render(req, reply) => {
                let t0 = Instant::now();
                let answer = guarded(|| self.render(&req));
                let (w, h, t) = (req.width, req.height, req.frame.time);
                crate::vlog!("preview: render of {w}x{h} at time {t} in {:.1} ms", ms(t0));
                let _ = reply.send(answer);
            }
        }
    }

    fn evaluate(&self, req: &FrameRequest) -> Result<FrameOutput> {
        let eye = req.eye.map(DVec3::from_array);
        let input = self.ch.read_frame_seen_from(req.time, &req.overrides, eye)?;
        self.ch.model.evaluate(input, req.proxy)
    }

    fn l2w(&self, path: &str, t: f64) -> Result<DMat4> {
        let r = &self.ch.reader;
        r.local_to_world(&r.require_prim(path)?, t)
    }

    /// The stroke layers and view-dependent meshes `render` would not draw
    /// at `t` (invisible then, or of a guide or proxy purpose), by index.
    fn hidden(&self, t: f64) -> Result<serde_json::Value> {
        let r = &self.ch.reader;
        let hidden = |paths: &[String]| -> Result<Vec<usize>> {
            let mut out = Vec::new();
            for (i, path) in paths.iter().enumerate() {
                if !self.drawables.draws(r, path, t)? {
                    out.push(i);
                }
            }
            Ok(out)
        };
        Ok(serde_json::json!({ "layers": hidden(&self.layers)?, "views": hidden(&self.views)? }))
    }

    /// One frame as a binary reply.
    fn frame(&self, req: &FrameRequest) -> Result<Vec<u8>> {
        if req.bake {
            return self.baked_frame(req);
        }
        let t0 = Instant::now();
        let t = req.time;
        let eye = req.eye.map(DVec3::from_array);
        let input = self.ch.read_frame_seen_from(t, &req.overrides, eye)?;
        let read_ms = ms(t0);
        let mut configuration = serde_json::Map::new();
        let mut weights = serde_json::Map::new();
        for (rig, rf) in self.ch.model.rigs.iter().zip(&input.rigs) {
            for (path, v) in rig.axes.iter().zip(&rf.axis_values) {
                configuration.insert(path.clone(), serde_json::json!(v));
            }
            for layer in &rig.layers {
                let k = &layer.keys;
                if k.uses_axes() || k.time_points.is_some() || k.time_opacity.is_some() {
                    let w = key_weights(k, &rf.axis_values, t);
                    weights.insert(layer.path.clone(), serde_json::to_value(w).unwrap_or_default());
                }
            }
        }
        let t1 = Instant::now();
        let out = self.ch.model.evaluate(input, req.proxy)?;
        let evaluate_ms = ms(t1);
        let t2 = Instant::now();
        let mut b = Buffer::default();
        for (i, (layer, path)) in out.layers.iter().zip(&self.layers).enumerate() {
            b.push(
                format!("layer/{i}/points"),
                layer.points.iter().flat_map(|p| p.to_array()),
            );
            b.push(format!("layer/{i}/opacity"), layer.opacity.iter().copied());
            b.push(format!("layer/{i}/xform"), mat(&self.l2w(path, t)?));
        }
        for (i, (pts, path)) in out.views.iter().zip(&self.views).enumerate() {
            b.push(format!("view/{i}/points"), pts.iter().flat_map(|p| p.to_array()));
            b.push(format!("view/{i}/xform"), mat(&self.l2w(path, t)?));
        }
        for (i, (pts, path)) in out.proxies.iter().zip(&self.proxies).enumerate() {
            if let Some(pts) = pts {
                b.push(format!("proxy/{i}/points"), pts.iter().flat_map(|p| p.to_array()));
                b.push(format!("proxy/{i}/xform"), mat(&self.l2w(path, t)?));
            }
        }
        let encode_ms = ms(t2);
        let timing = Timing {
            read_ms,
            evaluate_ms,
            encode_ms,
            total_ms: ms(t0),
        };
        Ok(b.finish(serde_json::json!({
            "id": req.id,
            "time": t,
            "eye": req.eye,
            "configuration": configuration,
            "weights": weights,
            "hidden": self.hidden(t)?,
            "stale": self.stale(),
            "timing": timing,
        })))
    }

    /// Why the frame may not show the input as it is on disk now: a file it
    /// reads changed since the preview opened it. `None` when none did.
    fn stale(&self) -> Option<String> {
        changed(&self.ch.reader, &self.opened).then(|| {
            "the input changed on disk since this preview opened it: restart `painterly preview` to see the edits"
                .into()
        })
    }

    /// The `--bake` layer's frame at `req.time`, read through the input
    /// with the bake sublayered over it (as `painterly render --bake`).
    fn baked_frame(&self, req: &FrameRequest) -> Result<Vec<u8>> {
        let t0 = Instant::now();
        let Some(Bake { reader: r, opened, .. }) = &self.bake else {
            return Err(Error::msg(NO_BAKE));
        };
        let t = req.time;
        let read = |path: &str, name: &str, ty: &str| -> Result<Option<Vec<f32>>> {
            let prim = r.require_prim(path)?;
            if ty == "point3f[]" {
                let v = r.typed(&prim, name, Some(t), ty, values::vec3_array)?;
                Ok(v.map(|v| v.iter().flat_map(|p| p.to_array()).collect()))
            } else {
                r.typed(&prim, name, Some(t), ty, values::f32_array)
            }
        };
        let l2w = |path: &str| -> Result<DMat4> { r.local_to_world(&r.require_prim(path)?, t) };
        let mut b = Buffer::default();
        for (i, path) in self.layers.iter().enumerate() {
            b.push(
                format!("layer/{i}/points"),
                read(path, "points", "point3f[]")?.unwrap_or_default(),
            );
            b.push(
                format!("layer/{i}/opacity"),
                read(path, "primvars:displayOpacity", "float[]")?.unwrap_or_default(),
            );
            b.push(format!("layer/{i}/xform"), mat(&l2w(path)?));
        }
        for (i, path) in self.views.iter().enumerate() {
            b.push(
                format!("view/{i}/points"),
                read(path, "points", "point3f[]")?.unwrap_or_default(),
            );
            b.push(format!("view/{i}/xform"), mat(&l2w(path)?));
        }
        Ok(b.finish(serde_json::json!({
            "id": req.id,
            "time": t,
            "source": "bake",
            "hidden": self.hidden(t)?,
            "stale": changed(r, opened).then_some(
                "the bake layer or the input changed on disk since this preview opened them: restart `painterly preview` to see the new files"
            ),
            "timing": { "total_ms": ms(t0) },
        })))
    }

    /// World-space bounds of everything evaluated.
    fn world_bounds(&self, t: f64, out: &FrameOutput) -> Result<[DVec3; 2]> {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        let mut add = |m: &DMat4, pts: &[Vec3]| {
            for p in pts {
                let w = m.transform_point3(p.as_dvec3());
                lo = lo.min(w);
                hi = hi.max(w);
            }
        };
        for (layer, path) in out.layers.iter().zip(&self.layers) {
            add(&self.l2w(path, t)?, &layer.points);
        }
        for (pts, path) in out.views.iter().zip(&self.views) {
            add(&self.l2w(path, t)?, pts);
        }
        for (pts, path) in out.proxies.iter().zip(&self.proxies) {
            if let Some(pts) = pts {
                add(&self.l2w(path, t)?, pts);
            }
        }
        if !lo.is_finite() || !hi.is_finite() {
            return Ok([DVec3::splat(-1.0), DVec3::splat(1.0)]);
        }
        Ok([lo, hi])
    }

    /// The current view through `painterly render`'s renderer: the input's
    /// drawables with the evaluated frame in place of a bake layer, or with
    /// `bake` the `--bake` layer over the input (as `render --bake`).
    fn render(&self, req: &RenderRequest) -> Result<Vec<u8>> {
        let cam = camera_params(&req.camera, req.width, req.height);
        let size = ImageSize {
            width: req.width,
            height: req.height,
        };
        let t = req.frame.time;
        if req.frame.bake {
            let Some(bake) = &self.bake else {
                return Err(Error::msg(NO_BAKE));
            };
            let curves = bake.drawables.curves_at(&bake.reader, t)?;
            let meshes = bake.drawables.meshes_at(&bake.reader, t)?;
            return render_png(&cam, &curves, &meshes, size, None);
        }
        let f = &req.frame;
        let out = self.evaluate(&FrameRequest {
            proxy: false,
            ..f.clone()
        })?;
        let r = &self.ch.reader;
        let mut curves = self.drawables.curves_at(r, t)?;
        let mut meshes = self.drawables.meshes_at(r, t)?;
        for (layer, path) in out.layers.iter().zip(&self.layers) {
            let m = self.l2w(path, t)?;
            if let Some(c) = curves.iter_mut().find(|c| &c.path == path) {
                if c.points.len() == layer.points.len() && c.counts.len() == layer.opacity.len() {
                    c.points = layer.points.iter().map(|p| m.transform_point3(p.as_dvec3())).collect();
                    c.opacities = Primvar::Uniform(layer.opacity.iter().map(|o| o.clamp(0.0, 1.0)).collect());
                }
            }
        }
        for (pts, path) in out.views.iter().zip(&self.views) {
            let m = self.l2w(path, t)?;
            if let Some(mesh) = meshes.iter_mut().find(|x| &x.path == path) {
                if mesh.points.len() == pts.len() {
                    mesh.points = pts.iter().map(|p| m.transform_point3(p.as_dvec3())).collect();
                }
            }
        }
        render_png(&cam, &curves, &meshes, size, None)
    }
}

/// Why a request for the bake is refused (422).
const NO_BAKE: &str = "no --bake layer was given to painterly preview";

/// Runs a job, turning errors and panics into [`JobError`]s.
fn guarded(f: impl FnOnce() -> Result<Vec<u8>>) -> std::result::Result<Vec<u8>, JobError> {
    match std::panic::catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(bytes)) => Ok(bytes),
        Ok(Err(e)) => Err(JobError::Unprocessable(e.to_string())),
        Err(_) => Err(JobError::Internal(
            "internal error while evaluating (a bug in painterly; please report it with the input file)".into(),
        )),
    }
}

/// The configuration at up to 200 times over the range (slider ranges).
fn sample_configurations(ch: &Character, start: f64, end: f64) -> Result<Vec<crate::character::Configuration>> {
    if ch.model.rigs.iter().all(|r| r.axes.is_empty()) {
        return Ok(Vec::new());
    }
    let n = ((end - start).floor() as usize + 1).clamp(1, 200);
    (0..n)
        .map(|i| {
            let t = if n == 1 {
                start
            } else {
                start + (end - start) * i as f64 / (n - 1) as f64
            };
            ch.configuration(t)
        })
        .collect()
}

/// A primvar of `curves` expanded to one value per control point (the
/// page draws curves through them); `varying` values sit at span ends
/// ([`CurvesData::varying_at_points`]).
fn per_point<T>(curves: &CurvesData, p: &Primvar<T>, counts: &[u32], fallback: T) -> Vec<T>
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Mul<f32, Output = T>,
{
    let n: usize = counts.iter().map(|&c| c as usize).sum();
    let out = match p {
        Primvar::Constant(v) => vec![*v; n],
        Primvar::Uniform(v) if v.len() == counts.len() => counts
            .iter()
            .zip(v)
            .flat_map(|(&c, &x)| std::iter::repeat_n(x, c as usize))
            .collect(),
        Primvar::Vertex(v) if v.len() == n => v.clone(),
        Primvar::Varying(v) | Primvar::FaceVarying(v) => curves.varying_at_points(v),
        _ => Vec::new(),
    };
    if out.len() == n {
        out
    } else {
        vec![fallback; n]
    }
}

fn mesh_info(r: &StageReader, path: &str, drawn: &[MeshData], camera: Option<String>) -> Result<MeshInfo> {
    if let Some(m) = drawn.iter().find(|m| m.path == path) {
        let color = match &m.colors {
            Primvar::Constant(c) => *c,
            Primvar::Uniform(v) | Primvar::Vertex(v) | Primvar::Varying(v) | Primvar::FaceVarying(v) => {
                v.first().copied().unwrap_or(DEFAULT_COLOR)
            }
        };
        return Ok(MeshInfo {
            path: path.to_string(),
            face_counts: m.face_counts.clone(),
            face_indices: m.face_indices.clone(),
            smooth: m.smooth,
            color: color.to_array(),
            camera,
        });
    }
    // Not drawn by a renderer (a guide proxy): topology only, which needs
    // no points (a proxy may have only time samples and a restTime).
    let (face_counts, face_indices) = read_face_topology(r, &r.require_prim(path)?, path)?;
    Ok(MeshInfo {
        path: path.to_string(),
        face_counts,
        face_indices,
        smooth: true,
        color: DEFAULT_COLOR.to_array(),
        camera,
    })
}

/// Where the orbit starts: the USD camera's position looking at the
/// scene's centre, else a three-quarter view of the bounds.
fn start_view(cam: Option<&CameraParams>, camera: Option<String>, bounds: &[DVec3; 2], up_axis: &str) -> StartView {
    let centre = (bounds[0] + bounds[1]) * 0.5;
    let radius = ((bounds[1] - bounds[0]).length() * 0.5).max(1e-3);
    let up = if up_axis == "Z" { DVec3::Z } else { DVec3::Y };
    if let Some(c) = cam.filter(|c| c.projection == Projection::Perspective) {
        let position = c.camera_to_world.transform_point3(DVec3::ZERO);
        let cam_up = c.camera_to_world.transform_vector3(DVec3::Y).normalize_or_zero();
        let fov_y = 2.0 * (0.5 * c.vertical_aperture / c.focal_length).atan().to_degrees();
        // Aimed where the camera looks (its -Z), at the scene centre's
        // distance, so the page starts on the camera's own view.
        let forward = c.camera_to_world.transform_vector3(DVec3::NEG_Z).normalize_or_zero();
        let target = if forward == DVec3::ZERO {
            centre
        } else {
            position + forward * (centre - position).length().max(1e-3)
        };
        return StartView {
            position: position.to_array(),
            target: target.to_array(),
            up: if cam_up == DVec3::ZERO { up } else { cam_up }.to_array(),
            fov_y,
            aspect: c.horizontal_aperture / c.vertical_aperture,
            camera,
        };
    }
    let dir = if up_axis == "Z" {
        DVec3::new(0.6, -1.0, 0.5)
    } else {
        DVec3::new(0.6, 0.5, 1.0)
    }
    .normalize();
    StartView {
        position: (centre + dir * radius * 2.8).to_array(),
        target: centre.to_array(),
        up: up.to_array(),
        fov_y: 40.0,
        aspect: 1.0,
        camera: None,
    }
}

/// A UsdGeomCamera with the orbit camera's pose and field of view: focal
/// length 50, vertical aperture from the field of view, horizontal aperture
/// from the image's aspect (so the render keeps the page's framing).
pub fn camera_params(v: &ViewCamera, width: usize, height: usize) -> CameraParams {
    let eye = DVec3::from_array(v.position);
    let z = (eye - DVec3::from_array(v.target)).normalize_or(DVec3::Z);
    let x = DVec3::from_array(v.up)
        .cross(z)
        .normalize_or(z.any_orthonormal_vector());
    let y = z.cross(x);
    let focal = 50.0;
    let vertical = 2.0 * focal * (0.5 * v.fov_y.to_radians()).tan();
    CameraParams {
        focal_length: focal,
        horizontal_aperture: vertical * width as f64 / height as f64,
        vertical_aperture: vertical,
        near: v.near,
        far: v.far,
        camera_to_world: DMat4::from_cols(x.extend(0.0), y.extend(0.0), z.extend(0.0), eye.extend(1.0)),
        ..CameraParams::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::curves::{Basis, CurveType, Wrap};

    #[test]
    fn bounds_of_nothing_are_the_unit_box_around_the_origin() {
        // A frame without a finite point (every world point overflowed, or
        // none evaluated) frames the box [-1, 1]^3, not a point.
        let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/apple.usda");
        let (state, _, _) = State::open(&input, None, None).unwrap();
        let nothing = FrameOutput {
            time: 1.0,
            layers: Vec::new(),
            proxies: Vec::new(),
            proxy_normals: Vec::new(),
            views: Vec::new(),
        };
        let [lo, hi] = state.world_bounds(1.0, &nothing).unwrap();
        assert_eq!((lo, hi), (DVec3::splat(-1.0), DVec3::splat(1.0)));
    }

    /// Curves of `counts` points (their positions do not matter here).
    fn curves_of(curve_type: CurveType, basis: Basis, counts: &[u32]) -> CurvesData {
        let n: u32 = counts.iter().sum();
        CurvesData {
            path: "/L".into(),
            curve_type,
            basis,
            wrap: Wrap::Nonperiodic,
            counts: counts.iter().map(|&c| c as usize).collect(),
            points: vec![DVec3::ZERO; n as usize],
            widths: Primvar::Constant(1.0),
            colors: Primvar::Constant(Vec3::ONE),
            opacities: Primvar::Constant(1.0),
        }
    }

    #[test]
    fn primvars_expand_per_point() {
        let counts = [2, 3];
        let c = curves_of(CurveType::Linear, Basis::Bezier, &counts);
        assert_eq!(per_point(&c, &Primvar::Constant(1.0), &counts, 0.0), [1.0; 5]);
        assert_eq!(
            per_point(&c, &Primvar::Uniform(vec![1.0, 2.0]), &counts, 0.0),
            [1.0, 1.0, 2.0, 2.0, 2.0]
        );
        assert_eq!(per_point(&c, &Primvar::Vertex(vec![1.0; 4]), &counts, 9.0), [9.0; 5]);
        // Linear varying: one per point.
        let v = vec![1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(per_point(&c, &Primvar::Varying(v.clone()), &counts, 9.0), v);
    }

    #[test]
    fn varying_primvars_of_cubic_curves_reach_every_control_point() {
        // Bézier curves of 4 and 7 points: 1 and 2 spans, 2 and 3 span
        // ends (usd-core's ComputeVaryingDataSize: 5). A control point takes
        // the value a third of a span on per point. They fell back to the
        // default width 1 before (a review, 2026-12-07).
        let counts = [4, 7];
        let c = curves_of(CurveType::Cubic, Basis::Bezier, &counts);
        let got = per_point(&c, &Primvar::Varying(vec![0.0, 3.0, 30.0, 33.0, 36.0]), &counts, 9.0);
        let want = [0.0, 1.0, 2.0, 3.0, 30.0, 31.0, 32.0, 33.0, 34.0, 35.0, 36.0];
        assert!(got.iter().zip(want).all(|(g, w)| (g - w).abs() < 1e-5), "{got:?}");
        // Catmull-Rom, 5 points: spans from point 1 to 3, ends at points 1, 2, 3.
        let counts = [5];
        let c = curves_of(CurveType::Cubic, Basis::CatmullRom, &counts);
        let got = per_point(&c, &Primvar::Varying(vec![1.0, 2.0, 3.0]), &counts, 9.0);
        assert_eq!(got, [1.0, 1.0, 2.0, 3.0, 3.0]);
        // A length that fits nothing: the fallback.
        assert_eq!(per_point(&c, &Primvar::Varying(vec![1.0]), &counts, 9.0), [9.0; 5]);
    }

    #[test]
    fn the_orbit_camera_looks_at_its_target() {
        let v = ViewCamera {
            position: [0.0, 0.0, 10.0],
            target: [0.0, 0.0, 0.0],
            up: [0.0, 1.0, 0.0],
            fov_y: 45.0,
            near: 0.1,
            far: 100.0,
        };
        let c = camera_params(&v, 200, 100);
        assert!(c.validate().is_ok());
        // The camera looks down its −Z: the target is straight ahead.
        let p = c.camera_to_world.inverse().transform_point3(DVec3::ZERO);
        assert!((p - DVec3::new(0.0, 0.0, -10.0)).length() < 1e-12);
        assert!((c.horizontal_aperture / c.vertical_aperture - 2.0).abs() < 1e-12);
        let half = (0.5 * c.vertical_aperture / c.focal_length).atan().to_degrees();
        assert!((2.0 * half - 45.0).abs() < 1e-9);
    }

    #[test]
    fn primvars_of_the_wrong_length_fall_back_and_vertex_ones_pass_through() {
        let counts = [2, 3];
        let c = curves_of(CurveType::Linear, Basis::Bezier, &counts);
        // A uniform primvar with one value too many is not per curve.
        assert_eq!(per_point(&c, &Primvar::Uniform(vec![1.0; 3]), &counts, 9.0), [9.0; 5]);
        let v = vec![1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(per_point(&c, &Primvar::Vertex(v.clone()), &counts, 9.0), v);
    }

    #[test]
    fn timings_are_milliseconds_since_the_start() {
        let t0 = Instant::now();
        std::thread::sleep(std::time::Duration::from_millis(20));
        let t = ms(t0);
        assert!((20.0..1000.0).contains(&t), "{t}");
    }

    #[test]
    fn xforms_are_sent_column_major() {
        let m = DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0));
        let got: Vec<f32> = mat(&m).collect();
        assert_eq!(got, [1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 1., 2., 3., 1.]);
    }

    fn close(a: [f64; 3], b: DVec3) -> bool {
        (DVec3::from_array(a) - b).length() < 1e-12
    }

    const BOUNDS: [DVec3; 2] = [DVec3::new(-1.0, -2.0, -3.0), DVec3::new(3.0, 2.0, 1.0)];

    #[test]
    fn without_a_camera_the_orbit_starts_at_a_three_quarter_view() {
        // Centre (1, 0, −1), radius half the diagonal √48; 2.8 radii out.
        let centre = DVec3::new(1.0, 0.0, -1.0);
        let far = 12f64.sqrt() * 2.8;
        let v = start_view(None, None, &BOUNDS, "Y");
        assert!(close(v.target, centre));
        let dir = DVec3::new(0.6, 0.5, 1.0) / 1.61f64.sqrt();
        assert!(close(v.position, centre + dir * far), "{:?}", v.position);
        assert_eq!((v.up, v.fov_y, v.aspect, v.camera), ([0.0, 1.0, 0.0], 40.0, 1.0, None));
        let v = start_view(None, None, &BOUNDS, "Z");
        let dir = DVec3::new(0.6, -1.0, 0.5) / 1.61f64.sqrt();
        assert!(close(v.position, centre + dir * far), "{:?}", v.position);
        assert_eq!(v.up, [0.0, 0.0, 1.0]);
        // An orthographic camera is no orbit start.
        let ortho = CameraParams {
            projection: Projection::Orthographic,
            ..CameraParams::default()
        };
        let v = start_view(Some(&ortho), Some("/C".into()), &BOUNDS, "Y");
        assert_eq!(v.camera, None);
        assert!(close(v.target, centre));
    }

    #[test]
    fn a_perspective_camera_gives_the_orbit_its_pose_and_field_of_view() {
        // Rolled 90° about Z: its up is −X. Aperture 100 at focal 50: 90°;
        // 150 wide, so its frame is 1.5 times as wide as high.
        let cam = CameraParams {
            focal_length: 50.0,
            horizontal_aperture: 150.0,
            vertical_aperture: 100.0,
            camera_to_world: DMat4::from_rotation_translation(
                glam::DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2),
                DVec3::new(5.0, 6.0, 7.0),
            ),
            ..CameraParams::default()
        };
        let v = start_view(Some(&cam), Some("/C".into()), &BOUNDS, "Y");
        assert!(close(v.position, DVec3::new(5.0, 6.0, 7.0)));
        // Along the camera's -Z, as far off as the scene's centre (1, 0, -1).
        let reach = (DVec3::new(1.0, 0.0, -1.0) - DVec3::new(5.0, 6.0, 7.0)).length();
        assert!(close(v.target, DVec3::new(5.0, 6.0, 7.0 - reach)), "{:?}", v.target);
        assert!(close(v.up, DVec3::new(-1.0, 0.0, 0.0)), "{:?}", v.up);
        assert!((v.fov_y - 90.0).abs() < 1e-9, "{}", v.fov_y);
        assert_eq!(v.aspect, 1.5);
        assert_eq!(v.camera.as_deref(), Some("/C"));
    }

    #[test]
    fn an_orbit_camera_off_the_origin_keeps_its_pose_and_clipping() {
        // Looking down −Z from (1, 2, 3): the pose is a pure translation.
        let v = ViewCamera {
            position: [1.0, 2.0, 3.0],
            target: [1.0, 2.0, -7.0],
            up: [0.0, 1.0, 0.0],
            fov_y: 90.0,
            near: 0.5,
            far: 250.0,
        };
        let c = camera_params(&v, 300, 100);
        let want = DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0));
        assert!(c.camera_to_world.abs_diff_eq(want, 1e-12), "{:?}", c.camera_to_world);
        assert!((c.vertical_aperture - 100.0).abs() < 1e-9);
        assert!((c.horizontal_aperture - 300.0).abs() < 1e-9);
        assert_eq!((c.near, c.far), (0.5, 250.0));
    }
}
