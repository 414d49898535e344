//! `painterly inspect`: what a painted character contains, and what is wrong
//! with it.
//!
//! Lists rigs, proxies and how they are animated, axes, stroke layers with
//! the columns of Bassett's Table I (strokes, points, pose position keys, pose
//! opacity keys, time keys), view-dependent meshes, and every problem found,
//! each with its prim path.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::bake::Progress;
use crate::error::{Error, Result};
use crate::frames::FrameRange;
use crate::rule::Rule;
use crate::usd_io::clips::{clip_set_status, ChunkState};
use crate::usd_io::scene::{ProxyMotion, Rig, Scene, StrokeLayer};
use crate::usd_io::stage::{Prim, StageMetadata, StageReader, UnresolvedAsset};
use crate::usd_io::values;
use crate::usd_io::view_mesh::{read_view_meshes_lenient, ViewMesh};
use crate::words::plural;

#[derive(Debug, Serialize)]
pub struct Report {
    pub file: PathBuf,
    pub start_time_code: Option<f64>,
    pub end_time_code: Option<f64>,
    pub time_codes_per_second: Option<f64>,
    /// What an unauthored timeCodesPerSecond falls back to (USD: this, else 24).
    #[serde(skip)]
    pub frames_per_second: Option<f64>,
    pub up_axis: Option<String>,
    pub rigs: Vec<RigReport>,
    pub axes: Vec<AxisReport>,
    pub view_dependent_meshes: Vec<ViewMeshReport>,
    /// Sublayers, references and payloads that did not resolve (each is
    /// also a problem: bake refuses such a stage).
    pub unresolved_assets: Vec<UnresolvedAsset>,
    /// For a clip-set layer written by `bake --chunk`: its chunks.
    pub clip_set: Option<ClipSetReport>,
    pub problems: Vec<Problem>,
}

/// A clip-set bake's chunks.
#[derive(Debug, Serialize)]
pub struct ClipSetReport {
    pub chunk_size: usize,
    pub chunks: Vec<ChunkReport>,
}

/// One chunk layer of a clip-set bake.
#[derive(Debug, Serialize)]
pub struct ChunkReport {
    /// Path of the chunk layer.
    pub path: PathBuf,
    /// "done", "missing" or "stale".
    pub state: &'static str,
    /// Why a chunk is stale.
    pub detail: Option<String>,
}

#[derive(Debug, Serialize)]
pub struct RigReport {
    pub path: String,
    pub proxy: String,
    pub proxy_points: usize,
    pub proxy_faces: usize,
    pub animation: String,
    pub skeleton: Option<String>,
    pub animation_source: Option<String>,
    pub layers: Vec<LayerReport>,
    /// How usd-core's UsdSkel rules treat this proxy where that may surprise
    /// (e.g. a blend shape without offsets moves no point); not problems.
    pub notes: Vec<String>,
}

/// One row of Bassett's Table I.
#[derive(Debug, Serialize)]
pub struct LayerReport {
    pub path: String,
    pub strokes: usize,
    pub points: usize,
    pub pose_position_keys: usize,
    pub pose_opacity_keys: usize,
    pub time_keys: usize,
    pub sentinels: usize,
    pub binding: &'static str,
    /// None when `painterly:opacity` has time samples (read per frame).
    pub opacity: Option<f32>,
}

#[derive(Debug, Serialize)]
pub struct AxisReport {
    pub path: String,
    /// None when `kind` cannot be read or is none of the five (a problem says why).
    pub kind: Option<String>,
    pub source: Option<String>,
}

#[derive(Debug, Serialize)]
pub struct ViewMeshReport {
    pub path: String,
    /// Key viewpoints: their direction and key prims (one per key time).
    pub key_viewpoints: Vec<ViewpointReport>,
    pub camera: Option<String>,
    pub uncovered: String,
    pub sharpness: f64,
    /// Whether the key directions' hull encloses the centre.
    pub encloses: bool,
    /// Where USD's rules give a result an author may not expect (key times
    /// read through a layer offset); not problems.
    pub notes: Vec<String>,
}

#[derive(Debug, Serialize)]
pub struct ViewpointReport {
    pub direction: [f64; 3],
    pub keys: Vec<String>,
}

#[derive(Debug, Serialize)]
pub struct Problem {
    pub prim: Option<String>,
    pub attribute: Option<String>,
    pub message: String,
    /// The rule it breaks ([`Rule::id`]); the Python package's validator
    /// for that rule reports it.
    pub rule: Rule,
}

impl Problem {
    /// A problem from an error, under `rule` unless the error names a more specific one.
    fn new(e: Error, rule: Rule) -> Self {
        Problem {
            rule: e.rule.unwrap_or(rule),
            prim: e.prim,
            attribute: e.attribute,
            message: e.message,
        }
    }
}

/// Counts the key prims under a layer: (position keys, opacity keys, time
/// keys, sentinels). A sentinel carrying points or opacity is a problem:
/// sentinels carry no data, so what was authored there is ignored.
fn count_keys(
    r: &StageReader,
    layer: &str,
    problems: &mut Vec<Problem>,
    notes: &mut Vec<String>,
) -> Result<(usize, usize, usize, usize)> {
    let prim = r.require_prim(layer)?;
    let (mut pos, mut opa, mut time, mut sent) = (0, 0, 0, 0);
    let mut offset_times = Vec::new();
    for c in r.read_children(&prim)? {
        match r.type_name(&c)?.as_str() {
            "PainterlyPoseKey" => {
                pos += r.has_authored(&c, "points")? as usize;
                opa += r.has_authored(&c, "opacity")? as usize;
                // A time key's properties on a pose key (a retyped prim, a
                // copy-paste) are never read: say so rather than ignore them.
                for (attr, rule) in [("sentinel", Rule::SentinelMisuse), ("time", Rule::KeyTime)] {
                    if r.has_authored(&c, attr)? {
                        let e = Error::attr(
                            c.path(),
                            attr,
                            format!(
                                "a pose key has no {attr}: it would be ignored (only a PainterlyTimeKey's {attr} is read; \
                                 a pose key keys its coordinates)"
                            ),
                        );
                        problems.push(Problem::new(e, rule));
                    }
                }
            }
            "PainterlyTimeKey" => {
                offset_times.extend(offset_key_time(r, &c)?);
                if r.has_authored(&c, "coordinates")? {
                    let e = Error::attr(
                        c.path(),
                        "coordinates",
                        "a time key has no coordinates: they would be ignored (only a PainterlyPoseKey's \
                         coordinates are read; a time key keys its time)",
                    );
                    problems.push(Problem::new(e, Rule::KeyCoordinates));
                }
                let s = r
                    .typed(&c, "sentinel", None, "bool", crate::usd_io::values::scalar)?
                    .unwrap_or(0.0)
                    != 0.0;
                if s {
                    sent += 1;
                    for attr in ["points", "opacity"] {
                        if r.has_authored(&c, attr)? {
                            let e = Error::attr(
                                c.path(),
                                attr,
                                format!("a sentinel carries no {attr}: it would be ignored (set `sentinel = 0` for a time key)"),
                            );
                            problems.push(Problem::new(e, Rule::SentinelMisuse));
                        }
                    }
                } else {
                    time += 1;
                }
            }
            _ => {}
        }
    }
    notes.extend(key_times_note(layer, "time key", &offset_times));
    Ok((pos, opa, time, sent))
}

/// A `double` time read through a layer offset: (label, time, (offset,
/// scale, layer)), as [`unretimed_note`] lists it.
type OffsetTime = (String, f64, (f64, f64, String));

/// `attr` of `prim` when its strongest opinion lies behind a layer offset
/// (and it has a value), labelled `label`.
fn offset_time(r: &StageReader, prim: &Prim, attr: &str, label: String) -> Result<Option<OffsetTime>> {
    let Some(offset) = r.value_offset(prim, attr)? else {
        return Ok(None);
    };
    let t = r.typed(prim, attr, None, "double", crate::usd_io::values::scalar)?;
    Ok(t.map(|t| (label, t, offset)))
}

/// A time or view key's `time`, behind a layer offset, labelled by the key's name.
fn offset_key_time(r: &StageReader, key: &Prim) -> Result<Option<OffsetTime>> {
    offset_time(r, key, "time", format!("{} at ", key.path().name().unwrap_or_default()))
}

/// The note of [`unretimed_note`] on `owner`'s (a rig's or a view-dependent
/// mesh's) `painterly:restTime`.
fn rest_time_note(r: &StageReader, owner: &str) -> Result<Option<String>> {
    let prim = r.require_prim(owner)?;
    let times: Vec<_> = offset_time(r, &prim, "painterly:restTime", String::new())?
        .into_iter()
        .collect();
    Ok(unretimed_note(owner, "its `double painterly:restTime` comes", &times))
}

/// The note of [`unretimed_note`] on the `time` of `owner`'s keys (`noun`:
/// "time key", "view key").
fn key_times_note(owner: &str, noun: &str, times: &[OffsetTime]) -> Option<String> {
    let what = match times.len() {
        1 => format!("1 {noun}'s `double time` comes"),
        n => format!("{n} {noun}s' `double time` come"),
    };
    unretimed_note(owner, &what, times)
}

/// A note on `double` times authored through a layer offset: USD retimes
/// the time samples of that layer but never a `double`, so the times are
/// read as written, which a retimed asset may not expect. `what` names the
/// values.
fn unretimed_note(owner: &str, what: &str, times: &[OffsetTime]) -> Option<String> {
    let (_, _, (offset, scale, layer)) = times.first()?;
    let list = crate::words::at_most_five(
        times
            .iter()
            .map(|(label, t, (o, s, _))| format!("{label}{t} (not {})", o + s * t)),
    );
    Some(format!(
        "{owner}: {what} from {layer} through a layer offset (offset {offset}, scale {scale}); USD retimes that \
         layer's time samples but never a double, so the stage reads the times written: {list}"
    ))
}

/// The time samples of a stroke layer's `points` hold as many points as its
/// curves, all finite: bake reads only the rest points (and its layer hides
/// the samples), but whatever draws the input at a time (usdview, `preview`)
/// reads them. At most one problem of each kind per layer, at the first
/// sample that has it; a blocked sample has no points to disagree.
fn check_point_samples(r: &StageReader, layer: &StrokeLayer, problems: &mut Vec<Problem>) -> Result<()> {
    let prim = r.require_prim(&layer.path)?;
    let total = layer.num_points();
    let times = r.sample_times(&prim, "points")?;
    let mut miscounted = Vec::new();
    let mut non_finite = None;
    for &t in &times {
        let Some(points) = r.typed(&prim, "points", Some(t), "point3f[]", values::vec3_array)? else {
            continue;
        };
        if points.len() != total {
            miscounted.push((t, points.len()));
        }
        if non_finite.is_none() {
            non_finite = points.iter().position(|p| !p.is_finite()).map(|i| (t, i, points[i]));
        }
    }
    if let Some(&(t, n)) = miscounted.first() {
        let message = format!(
            "time samples disagreeing with curveVertexCounts (sum {total}): {} of {}, the first at time {t} with {}",
            miscounted.len(),
            times.len(),
            plural(n, "point")
        );
        problems.push(Problem::new(
            Error::attr(&layer.path, "points", message),
            Rule::PointCounts,
        ));
    }
    if let Some((t, i, p)) = non_finite {
        let message = format!("point {i} of the sample at time {t} is not finite ({p})");
        problems.push(Problem::new(
            Error::attr(&layer.path, "points", message),
            Rule::NonFinite,
        ));
    }
    Ok(())
}

/// Builds the report. Fails only when the file cannot be opened at all.
///
/// `camera` and `frames` are what `bake --camera --frames` would be given:
/// the report then vouches for that bake. The stage is opened as bake opens it (mapped), so that
/// its frames are read the same way: a mapped stage reads time samples
/// and fixed transforms through its own paths.
pub fn inspect(path: &Path, camera: Option<&str>, frames: Option<FrameRange>, progress: Progress) -> Result<Report> {
    inspect_reader(StageReader::open_mapped(path)?, camera, frames, progress)
}

/// [`inspect`] of an opened stage (a file, or a layer handed over in
/// memory, see [`crate::usd_io::memory`]): the schema checks, then every
/// frame when they pass.
pub fn inspect_reader(
    reader: StageReader,
    camera: Option<&str>,
    frames: Option<FrameRange>,
    progress: Progress,
) -> Result<Report> {
    // A camera that is no prim path is a bad option (exit 2), not a problem
    // of the stage.
    if let Some(c) = camera {
        crate::usd_io::stage::check_prim_path("--camera", c)?;
    }
    let mut report = inspect_stage_for(&reader, frames)?;
    check_every_frame(reader, camera, frames, &mut report, progress);
    Ok(report)
}

/// When the report has no problem yet, evaluates every frame `bake` (with
/// `camera` as `--camera`, `frames` as `--frames`) would, writing nothing,
/// and reports the first failure, so that inspect passing means that bake
/// succeeds: some inputs fail only when evaluated at a frame (a camera
/// transform, a non-finite posed point), and a stage without a time range
/// needs `frames`. `progress` hears (frames done, frames) as bake's does.
fn check_every_frame(
    reader: StageReader,
    camera: Option<&str>,
    frames: Option<FrameRange>,
    report: &mut Report,
    progress: Progress,
) {
    if !report.problems.is_empty() {
        return;
    }
    if let Err(e) = crate::bake::evaluate_every_frame(reader, camera, frames, progress) {
        report.problems.push(Problem::new(e, Rule::Unreadable));
    }
}

/// Builds the report of an opened stage (a file, or a layer handed over in
/// memory, see [`crate::usd_io::memory`]).
pub fn inspect_stage(r: &StageReader) -> Result<Report> {
    inspect_stage_for(r, None)
}

/// [`inspect_stage`] for a bake given `frames` (`--frames`): the stage's
/// range is checked against them, as bake checks it.
pub fn inspect_stage_for(r: &StageReader, frames: Option<FrameRange>) -> Result<Report> {
    let path = r.file.as_path();
    let (scene, problems) = Scene::read_lenient(r).map_err(|e| e.in_file(path))?;
    let mut problems: Vec<Problem> = problems
        .into_iter()
        .map(|e| Problem::new(e, Rule::Unreadable))
        .collect();
    let meta = r.metadata();
    problems.extend(stage_problems(r, &meta, frames));
    let mut rigs: Vec<RigReport> = scene.rigs.iter().map(|rig| rig_report(r, rig, &mut problems)).collect();
    let axes = axis_reports(r).map_err(|e| e.in_file(path))?;
    // Every axis is checked, not only those keyed layers read: a wrong joint
    // name should show before the first key is made, not at it.
    for a in &axes {
        if let Err(e) = crate::usd_io::axes::Axis::read(r, &a.path) {
            let p = Problem::new(e, Rule::Axis);
            let known = |q: &Problem| (&q.prim, &q.attribute, &q.message) == (&p.prim, &p.attribute, &p.message);
            if !problems.iter().any(known) {
                problems.push(p);
            }
        }
    }
    note_unanimated_blend_shapes(r, &axes, &mut rigs)?;
    let (meshes, view_problems) = read_view_meshes_lenient(r, &r.prim_paths()?).map_err(|e| e.in_file(path))?;
    problems.extend(view_problems.into_iter().map(|e| Problem::new(e, Rule::Unreadable)));
    let view_meshes = meshes.iter().map(|m| view_mesh_report(r, m, &mut problems)).collect();
    let clip_set = clip_set_report(path, &mut problems)?;
    // One cause can surface once per layer that meets it (an axis that three
    // layers' keys use): the report names it once, where it first surfaced.
    let mut seen = std::collections::HashSet::new();
    problems.retain(|p| seen.insert((p.prim.clone(), p.attribute.clone(), p.message.clone(), p.rule)));
    Ok(Report {
        file: path.to_path_buf(),
        start_time_code: meta.start_time_code,
        end_time_code: meta.end_time_code,
        time_codes_per_second: meta.time_codes_per_second,
        frames_per_second: meta.frames_per_second,
        up_axis: meta.up_axis,
        rigs,
        axes,
        view_dependent_meshes: view_meshes,
        unresolved_assets: r.unresolved.clone(),
        clip_set,
        problems,
    })
}

/// What bake checks before reading anything: assets, stage metadata and
/// the frame range (`frames`, or the stage's).
fn stage_problems(r: &StageReader, meta: &StageMetadata, frames: Option<FrameRange>) -> Vec<Problem> {
    let mut problems = Vec::new();
    for u in &r.unresolved {
        let e = Error {
            prim: u.prim.clone(),
            ..Error::msg(format!("missing asset: {}", u.describe_asset()))
        };
        problems.push(Problem::new(e, Rule::Unreadable));
    }
    let has_range = meta.start_time_code.is_some() || meta.end_time_code.is_some();
    if let Err(e) = meta.validate() {
        problems.push(Problem::new(e, Rule::Unreadable));
    } else if has_range {
        // Without any range the frame check below says bake needs --frames;
        // half a range, or frames outside it, are wrong whatever else is.
        if let Err(e) = crate::frames::resolve(meta, frames) {
            problems.push(Problem::new(e, Rule::Unreadable));
        }
    }
    problems
}

/// One rig: its proxy, its animation and each stroke layer's counts; what
/// cannot be read goes to `problems`.
fn rig_report(r: &StageReader, rig: &Rig, problems: &mut Vec<Problem>) -> RigReport {
    let (skeleton, animation_source, mut notes) = match &rig.proxy.motion {
        ProxyMotion::Skel(s) => (Some(s.skeleton.clone()), s.animation.clone(), s.notes.clone()),
        _ => (None, None, Vec::new()),
    };
    match rest_time_note(r, &rig.path) {
        Ok(note) => notes.extend(note),
        Err(e) => problems.push(Problem::new(e, Rule::Unreadable)),
    }
    if !matches!(rig.proxy.motion, ProxyMotion::Skel(_)) {
        let note = r
            .require_prim(&rig.proxy.path)
            .and_then(|prim| crate::usd_io::skel::unscoped_binding_note(r, &prim));
        match note {
            Ok(note) => notes.extend(note),
            Err(e) => problems.push(Problem::new(e, Rule::Unreadable)),
        }
    }
    let mut layers = Vec::new();
    for l in &rig.layers {
        if let Err(e) = check_point_samples(r, l, problems) {
            problems.push(Problem::new(e, Rule::Unreadable));
        }
        let (pos, opa, time, sent) = match count_keys(r, &l.path, problems, &mut notes) {
            Ok(c) => c,
            Err(e) => {
                problems.push(Problem::new(e, Rule::Unreadable));
                (0, 0, 0, 0)
            }
        };
        layers.push(LayerReport {
            path: l.path.clone(),
            strokes: l.curve_counts.len(),
            points: l.num_points(),
            pose_position_keys: pos,
            pose_opacity_keys: opa,
            time_keys: time,
            sentinels: sent,
            binding: if l.cached_binding.is_some() {
                "cached"
            } else {
                "computed"
            },
            opacity: (!l.opacity_is_sampled()).then_some(l.opacity),
        });
    }
    RigReport {
        path: rig.path.clone(),
        proxy: rig.proxy.path.clone(),
        proxy_points: rig.proxy.rest.len(),
        proxy_faces: rig.proxy.face_counts.len(),
        animation: rig.proxy.motion.describe().to_string(),
        skeleton,
        animation_source,
        layers,
        notes,
    }
}

/// Every `PainterlyAxis` prim: its kind (`attribute` when unauthored) and source.
/// The `kind` tokens of a PainterlyAxis (SPEC §4).
const AXIS_KINDS: [&str; 5] = ["attribute", "blendShape", "jointRotation", "position", "viewDirection"];

fn axis_reports(r: &StageReader) -> Result<Vec<AxisReport>> {
    let mut axes = Vec::new();
    for p in r.prim_paths()? {
        let prim = r.require_prim(&p)?;
        if r.type_name(&prim)? == "PainterlyAxis" {
            // A bad kind is the axis check's problem, not the end of the report.
            let kind = match r.typed(&prim, "kind", None, "token", crate::usd_io::values::token) {
                Ok(None) => Some("attribute".to_string()),
                Ok(Some(k)) => AXIS_KINDS.contains(&k.as_str()).then_some(k),
                Err(_) => None,
            };
            let source = r.targets(&prim, "source")?.into_iter().next();
            axes.push(AxisReport {
                path: p.clone(),
                kind,
                source,
            });
        }
    }
    Ok(axes)
}

/// A `blendShape` axis whose animation does not animate its `name` reads 0
/// at every frame (SPEC §4). That is right for a shape left still, but it is
/// also what a misspelt name gives: the rig holding the axis gets a note
/// naming the shapes the animation does animate.
fn note_unanimated_blend_shapes(r: &StageReader, axes: &[AxisReport], rigs: &mut [RigReport]) -> Result<()> {
    for axis in axes.iter().filter(|a| a.kind.as_deref() == Some("blendShape")) {
        let (p, Some(anim)) = (&axis.path, &axis.source) else {
            continue;
        };
        let prim = r.require_prim(p)?;
        // An unreadable or unauthored name is the axis reader's problem.
        let Some(name) = r.typed(&prim, "name", None, "token", values::token).ok().flatten() else {
            continue;
        };
        let Some(anim_prim) = r.prim(anim).ok().flatten() else {
            continue;
        };
        let shapes = r
            .typed(&anim_prim, "blendShapes", None, "token[]", values::token_array)
            .ok()
            .flatten()
            .unwrap_or_default();
        if shapes.contains(&name) {
            continue;
        }
        if let Some(rig) = rigs.iter_mut().find(|g| p.starts_with(&format!("{}/", g.path))) {
            let animated = if shapes.is_empty() {
                "none".to_string()
            } else {
                shapes.join(", ")
            };
            rig.notes.push(format!(
                "axis {p} reads 0 at every frame: {anim} does not animate blend shape {name:?} (it animates: {animated})"
            ));
        }
    }
    Ok(())
}

fn view_mesh_report(r: &StageReader, m: &ViewMesh, problems: &mut Vec<Problem>) -> ViewMeshReport {
    let notes = match view_time_notes(r, m) {
        Ok(notes) => notes,
        Err(e) => {
            problems.push(Problem::new(e, Rule::Unreadable));
            Vec::new()
        }
    };
    ViewMeshReport {
        path: m.path.clone(),
        key_viewpoints: m
            .blend
            .viewpoints
            .iter()
            .map(|v| ViewpointReport {
                direction: v.direction,
                keys: v.paths.clone(),
            })
            .collect(),
        camera: m.camera.clone(),
        uncovered: m.uncovered.token().to_string(),
        sharpness: m.sharpness,
        encloses: m.blend.blender.encloses(),
        notes,
    }
}

/// The notes of [`unretimed_note`] for a view-dependent mesh: its
/// `painterly:restTime` and its keys' `time`.
fn view_time_notes(r: &StageReader, m: &ViewMesh) -> Result<Vec<String>> {
    let mut notes: Vec<String> = rest_time_note(r, &m.path)?.into_iter().collect();
    let mut key_times = Vec::new();
    for path in m.blend.viewpoints.iter().flat_map(|v| &v.paths) {
        key_times.extend(offset_key_time(r, &r.require_prim(path)?)?);
    }
    notes.extend(key_times_note(&m.path, "view key", &key_times));
    Ok(notes)
}

/// The chunks of a clip-set bake, judged against its current input; missing
/// and stale chunks are problems, and so is an input that changed since the
/// clip set was assembled or cannot be read.
fn clip_set_report(path: &Path, problems: &mut Vec<Problem>) -> Result<Option<ClipSetReport>> {
    let Some(status) = clip_set_status(path, None)? else {
        return Ok(None);
    };
    problems.extend(status.problems.into_iter().map(|message| Problem {
        prim: None,
        attribute: None,
        rule: Rule::Chunks,
        message,
    }));
    let stem = path.file_stem().unwrap_or_default().to_string_lossy();
    let dir = path.with_file_name(format!("{stem}.clips"));
    let chunks = status
        .chunks
        .into_iter()
        .map(|(name, state)| {
            let chunk = dir.join(&name);
            let (state, detail) = match state {
                ChunkState::Done => ("done", None),
                ChunkState::Missing => ("missing", None),
                ChunkState::Stale(why) => ("stale", Some(why)),
            };
            if state != "done" {
                problems.push(Problem {
                    prim: None,
                    attribute: None,
                    rule: Rule::Chunks,
                    message: format!(
                        "chunk {} is {state}{}",
                        chunk.display(),
                        detail.as_deref().map(|d| format!(" ({d})")).unwrap_or_default()
                    ),
                });
            }
            ChunkReport {
                path: chunk,
                state,
                detail,
            }
        })
        .collect();
    Ok(Some(ClipSetReport {
        chunk_size: status.chunk_size,
        chunks,
    }))
}

impl Report {
    /// The human-readable form.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| v.to_string());
        let _ = writeln!(s, "{}", self.file.display());
        let rate = match (self.time_codes_per_second, self.frames_per_second) {
            (Some(r), _) => format!("{r} per second"),
            (None, Some(f)) => format!("{f} per second (timeCodesPerSecond not authored: USD takes framesPerSecond)"),
            (None, None) => "24 per second (timeCodesPerSecond not authored: USD's default)".to_string(),
        };
        let _ = writeln!(
            s,
            "  time codes {}..{} at {rate}, up axis {}",
            opt(self.start_time_code),
            opt(self.end_time_code),
            self.up_axis.as_deref().unwrap_or("-")
        );
        for rig in &self.rigs {
            let _ = writeln!(s, "rig {}", rig.path);
            let _ = writeln!(
                s,
                "  proxy {} ({} points, {} faces), animated by {}",
                rig.proxy, rig.proxy_points, rig.proxy_faces, rig.animation
            );
            if let Some(sk) = &rig.skeleton {
                let _ = writeln!(
                    s,
                    "  skeleton {}, animation {}",
                    sk,
                    rig.animation_source.as_deref().unwrap_or("(none: rest pose)")
                );
            }
            for n in &rig.notes {
                let _ = writeln!(s, "  note: {n}");
            }
            let _ = writeln!(
                s,
                "  {:<40} {:>8} {:>8} {:>6} {:>6} {:>6} {:>6} {:>8} {:>8}",
                "layer", "strokes", "points", "pos", "opac", "time", "sent", "binding", "opacity"
            );
            for l in &rig.layers {
                let _ = writeln!(
                    s,
                    "  {:<40} {:>8} {:>8} {:>6} {:>6} {:>6} {:>6} {:>8} {:>8}",
                    l.path,
                    l.strokes,
                    l.points,
                    l.pose_position_keys,
                    l.pose_opacity_keys,
                    l.time_keys,
                    l.sentinels,
                    l.binding,
                    l.opacity.map_or("animated".to_string(), |o| o.to_string())
                );
            }
            let strokes: usize = rig.layers.iter().map(|l| l.strokes).sum();
            let points: usize = rig.layers.iter().map(|l| l.points).sum();
            let _ = writeln!(
                s,
                "  total: {} layers, {strokes} strokes, {points} points",
                rig.layers.len()
            );
        }
        for a in &self.axes {
            let _ = writeln!(
                s,
                "axis {} ({}) <- {}",
                a.path,
                a.kind.as_deref().unwrap_or("kind unreadable"),
                a.source.as_deref().unwrap_or("-")
            );
        }
        for v in &self.view_dependent_meshes {
            let _ = writeln!(
                s,
                "view-dependent mesh {} ({} key viewpoints, sharpness {}, uncovered {}, hull {}, camera {})",
                v.path,
                v.key_viewpoints.len(),
                v.sharpness,
                v.uncovered,
                if v.encloses {
                    "encloses the centre"
                } else {
                    "does not enclose the centre"
                },
                v.camera.as_deref().unwrap_or("from --camera")
            );
            for k in &v.key_viewpoints {
                let [x, y, z] = k.direction;
                let _ = writeln!(s, "  ({x:.3}, {y:.3}, {z:.3}): {}", k.keys.join(", "));
            }
            for n in &v.notes {
                let _ = writeln!(s, "  note: {n}");
            }
        }
        for u in &self.unresolved_assets {
            let _ = writeln!(s, "unresolved {}", u.describe());
        }
        if let Some(c) = &self.clip_set {
            let count = |state: &str| c.chunks.iter().filter(|k| k.state == state).count();
            let _ = writeln!(
                s,
                "clip set: {} chunks of {} frames: {} done, {} missing, {} stale",
                c.chunks.len(),
                c.chunk_size,
                count("done"),
                count("missing"),
                count("stale")
            );
        }
        let no_layers = self.rigs.iter().all(|r| r.layers.is_empty());
        if no_layers && self.view_dependent_meshes.is_empty() && self.clip_set.is_none() {
            // Said, because "no problems found" alone reads as "bake will work".
            let what = if !self.problems.is_empty() {
                "nothing painterly could be listed (the problems below say why), so bake has nothing to bake"
            } else if self.rigs.is_empty() {
                "nothing painterly: no rig (PainterlyRigAPI) and no view-dependent mesh, so bake has nothing to bake"
            } else {
                "nothing to bake: no rig has an active stroke layer (PainterlyStrokeLayerAPI) and there is no \
                 view-dependent mesh"
            };
            let _ = writeln!(s, "{what}");
        }
        if self.problems.is_empty() {
            let _ = writeln!(s, "no problems found");
        } else {
            let _ = writeln!(s, "{} problem(s):", self.problems.len());
            for p in &self.problems {
                let e = Error {
                    prim: p.prim.clone(),
                    attribute: p.attribute.clone(),
                    ..Error::msg(p.message.clone())
                };
                let _ = writeln!(s, "  {e}");
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::usd_io::memory::open_bytes;

    fn tube() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/tube.usda")
    }

    /// Half a time range is a problem beside any other (the frame check,
    /// which also finds it, runs only on a stage without problems); no
    /// range at all is left to the frame check, which skips a stage with
    /// nothing to bake.
    #[test]
    fn half_a_range_is_listed_beside_other_problems() {
        let rig = "def Xform \"Rig\" (prepend apiSchemas = [\"PainterlyRigAPI\"]) { rel painterly:proxy = </Nope> }\n";
        let report = |header: &str| {
            let r = crate::usd_io::testutil::stage_from_usda(&format!("#usda 1.0\n{header}\n{rig}"));
            let messages: Vec<String> = inspect_stage(&r)
                .unwrap()
                .problems
                .into_iter()
                .map(|p| p.message)
                .collect();
            messages
        };
        let half = report("(startTimeCode = 1)");
        assert_eq!(half.len(), 2, "{half:?}");
        assert!(half
            .iter()
            .any(|m| m == "the stage has a startTimeCode but no endTimeCode: pass --frames A:B"));
        let none = report("");
        assert_eq!(none.len(), 1, "{none:?}");
        assert!(!none[0].contains("--frames"), "{none:?}");
    }

    /// A blendShape axis gets a note on the rig holding it when its
    /// animation does not animate its name; an animated name, another
    /// kind, and an axis outside every rig get none.
    #[test]
    fn a_blend_shape_the_animation_does_not_animate_is_noted_on_its_rig() {
        let r = crate::usd_io::testutil::stage_from_usda(
            r#"#usda 1.0
def SkelAnimation "Anim" { uniform token[] blendShapes = ["smile", "blink"] }
def SkelAnimation "Still" { }
def Xform "Rig" {
    def PainterlyAxis "typo" { uniform token kind = "blendShape"  rel source = </Anim>  uniform token name = "smlie" }
    def PainterlyAxis "fine" { uniform token kind = "blendShape"  rel source = </Anim>  uniform token name = "blink" }
    def PainterlyAxis "still" { uniform token kind = "blendShape"  rel source = </Still>  uniform token name = "smile" }
    def PainterlyAxis "joint" { uniform token kind = "jointRotation"  rel source = </Anim>  uniform token name = "smlie" }
}
def Xform "Rig2" {
    def PainterlyAxis "typo" { uniform token kind = "blendShape"  rel source = </Anim>  uniform token name = "frown" }
}
def PainterlyAxis "outside" { uniform token kind = "blendShape"  rel source = </Anim>  uniform token name = "frown" }
"#,
        );
        let rig = |p: &str| RigReport {
            path: p.into(),
            proxy: String::new(),
            proxy_points: 0,
            proxy_faces: 0,
            animation: String::new(),
            skeleton: None,
            animation_source: None,
            layers: Vec::new(),
            notes: Vec::new(),
        };
        // "/Rig2" must not take "/Rig"'s axes (a prefix of the path, not a parent).
        let mut rigs = vec![rig("/Rig"), rig("/Rig2"), rig("/Ri")];
        let axes = axis_reports(&r).unwrap();
        note_unanimated_blend_shapes(&r, &axes, &mut rigs).unwrap();
        assert_eq!(
            rigs[0].notes,
            [
                r#"axis /Rig/typo reads 0 at every frame: /Anim does not animate blend shape "smlie" (it animates: smile, blink)"#,
                r#"axis /Rig/still reads 0 at every frame: /Still does not animate blend shape "smile" (it animates: none)"#,
            ]
        );
        assert_eq!(
            rigs[1].notes,
            [
                r#"axis /Rig2/typo reads 0 at every frame: /Anim does not animate blend shape "frown" (it animates: smile, blink)"#
            ]
        );
        assert!(rigs[2].notes.is_empty());
    }

    /// A report with nothing in it but `problems` and `clip_set`.
    fn bare(problems: Vec<Problem>, clip_set: Option<ClipSetReport>) -> Report {
        Report {
            file: PathBuf::from("/shots/a.usda"),
            start_time_code: Some(1.0),
            end_time_code: Some(24.0),
            time_codes_per_second: Some(24.0),
            frames_per_second: None,
            up_axis: Some("Y".into()),
            rigs: Vec::new(),
            axes: Vec::new(),
            view_dependent_meshes: Vec::new(),
            unresolved_assets: Vec::new(),
            clip_set,
            problems,
        }
    }

    #[test]
    fn text_rate_falls_back_as_usd_does() {
        // USD: timeCodesPerSecond, else framesPerSecond, else 24.
        let rate = |tcps, fps| {
            let mut r = bare(Vec::new(), None);
            r.time_codes_per_second = tcps;
            r.frames_per_second = fps;
            r.to_text().lines().nth(1).unwrap().to_string()
        };
        assert!(rate(Some(12.0), Some(30.0)).ends_with("at 12 per second, up axis Y"));
        assert!(rate(None, Some(30.0))
            .contains("at 30 per second (timeCodesPerSecond not authored: USD takes framesPerSecond)"));
        assert!(rate(None, None).contains("at 24 per second (timeCodesPerSecond not authored: USD's default)"));
    }

    #[test]
    fn text_problem_lines_name_prim_and_attribute() {
        // Error's documented form: `prim.attribute: message`, `prim: message`.
        let problem = |prim: Option<&str>, attribute: Option<&str>, message: &str| Problem {
            prim: prim.map(String::from),
            attribute: attribute.map(String::from),
            message: message.into(),
            rule: Rule::Unreadable,
        };
        let text = bare(
            vec![
                problem(Some("/A/Layer"), Some("points"), "too few"),
                problem(Some("/A/Rig"), None, "no proxy"),
            ],
            None,
        )
        .to_text();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[lines.len() - 3..],
            ["2 problem(s):", "  /A/Layer.points: too few", "  /A/Rig: no proxy"]
        );
    }

    #[test]
    fn text_counts_chunks_by_state() {
        let chunk = |name: &str, state: &'static str| ChunkReport {
            path: PathBuf::from(name),
            state,
            detail: None,
        };
        let clips = ClipSetReport {
            chunk_size: 12,
            chunks: vec![chunk("a", "done"), chunk("b", "missing"), chunk("c", "done")],
        };
        let text = bare(Vec::new(), Some(clips)).to_text();
        assert!(
            text.contains("\nclip set: 3 chunks of 12 frames: 2 done, 1 missing, 0 stale\n"),
            "{text}"
        );
    }

    #[test]
    fn missing_reference_problem_names_its_prim() {
        let usda =
            "#usda 1.0\ndef Xform \"Char\" (\n    prepend references = @./painterly_no_such_asset.usda@\n)\n{\n}\n";
        let path = std::env::temp_dir().join("painterly_inspect_missing_ref.usda");
        let r = open_bytes(usda.as_bytes().to_vec(), &path).unwrap();
        let report = inspect_stage(&r).unwrap();
        // The stage has nothing else wrong: one problem, on the prim that
        // authors the reference.
        assert_eq!(report.problems.len(), 1, "{:?}", report.problems);
        let missing = &report.problems[0];
        assert!(
            missing.message.starts_with("missing asset: reference @"),
            "{}",
            missing.message
        );
        assert!(
            missing.message.contains("painterly_no_such_asset.usda@"),
            "{}",
            missing.message
        );
        assert_eq!(missing.prim.as_deref(), Some("/Char"));
    }

    #[test]
    fn a_problem_three_layers_meet_is_reported_once() {
        // fixtures/apple.usda: the Shading, Highlight and CastShadow layers
        // each key lightX and lightZ. Without lightX's source, each of the
        // three layers' keys fails on it; the report says so once.
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/apple.usda");
        let text = std::fs::read_to_string(&path).unwrap();
        let lightx = text.find("def PainterlyAxis \"lightX\"").unwrap();
        let rel = "rel source = </Apple/Light>";
        let source = lightx + text[lightx..].find(rel).unwrap();
        let text = format!("{}{}", &text[..source], &text[source + rel.len()..]);
        let r = open_bytes(text.into_bytes(), &path).unwrap();
        let problems = inspect_stage(&r).unwrap().problems;
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert_eq!(site(&problems[0]).0, Some("/Apple/Paint/lightX"));
        assert_eq!(
            problems[0].message,
            "a position axis needs `rel source` to an Xformable prim"
        );
    }

    #[test]
    fn a_deactivated_axis_three_layers_use_is_one_problem_and_they_stay_listed() {
        // fixtures/blowfish.usda: Spikes, Cheeks and GapFill key the inflate
        // axis. Deactivated, it is one problem on the axis naming the three,
        // and the three layers are still listed with their strokes.
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/blowfish.usda");
        let text = std::fs::read_to_string(&path).unwrap();
        let text = text.replacen(
            "def PainterlyAxis \"inflate\"",
            "def PainterlyAxis \"inflate\" (active = false)",
            1,
        );
        let r = open_bytes(text.into_bytes(), &path).unwrap();
        let report = inspect_stage(&r).unwrap();
        let problems = &report.problems;
        assert_eq!(problems.len(), 1, "{problems:?}");
        assert_eq!(site(&problems[0]), (Some("/Blowfish/Paint/inflate"), None, Rule::Axis));
        assert_eq!(
            problems[0].message,
            "the axis is deactivated (active = false), but 3 stroke layers target it in `painterly:axes` \
             (/Blowfish/Paint/Spikes, /Blowfish/Paint/Cheeks, /Blowfish/Paint/GapFill): it would go on shaping them unseen"
        );
        let layers = &report.rigs[0].layers;
        assert_eq!(layers.len(), 14);
        let spikes = layers.iter().find(|l| l.path == "/Blowfish/Paint/Spikes").unwrap();
        assert_eq!(
            (spikes.strokes, spikes.points, spikes.pose_position_keys),
            (260, 780, 3)
        );
    }

    #[test]
    fn skel_proxy_reports_its_skeleton_and_animation() {
        // fixtures/tube.usda: the proxy binds rel skel:skeleton = </Tube/Rig/Skel>,
        // whose rel skel:animationSource = </Tube/Rig/Skel/Anim>.
        let r = StageReader::open(&tube()).unwrap();
        let report = inspect_stage(&r).unwrap();
        assert_eq!(report.rigs.len(), 1);
        assert_eq!(report.rigs[0].skeleton.as_deref(), Some("/Tube/Rig/Skel"));
        assert_eq!(report.rigs[0].animation_source.as_deref(), Some("/Tube/Rig/Skel/Anim"));
    }

    /// The tube with `samples` (usda `time: value` entries) authored on the
    /// Rings layer's points, opened from memory.
    fn tube_with_ring_samples(samples: &str) -> StageReader {
        let text = std::fs::read_to_string(tube()).unwrap();
        let at = text.find("def BasisCurves \"Rings\"").unwrap();
        let at = at + text[at..].find("point3f[] points = ").unwrap();
        let text = format!(
            "{}point3f[] points.timeSamples = {{ {samples} }}\n{}",
            &text[..at],
            &text[at..]
        );
        open_bytes(text.into_bytes(), Path::new("/shots/rings.usda")).unwrap()
    }

    /// A sample for the Rings layer: its 250 points, the one at `nan_at` (if
    /// any) not a number.
    fn ring_sample(nan_at: Option<usize>) -> String {
        let points: Vec<String> = (0..250)
            .map(|i| {
                if Some(i) == nan_at {
                    "(1, nan, 0)".into()
                } else {
                    format!("({i}, 0, 0)")
                }
            })
            .collect();
        format!("[{}]", points.join(", "))
    }

    /// Where a problem is and the rule it breaks.
    fn site(p: &Problem) -> (Option<&str>, Option<&str>, Rule) {
        (p.prim.as_deref(), p.attribute.as_deref(), p.rule)
    }

    #[test]
    fn points_samples_must_hold_as_many_points_as_the_curves() {
        // Rings: 25 curves of 10 points. A sample of 250 points is fine; two
        // of 2 points make one problem, at the first of them.
        let good = format!("3: {}", ring_sample(None));
        assert!(inspect_stage(&tube_with_ring_samples(&good))
            .unwrap()
            .problems
            .is_empty());
        let two = "[(0, 0, 0), (1, 1, 1)]";
        let r = tube_with_ring_samples(&format!("{good}, 5: {two}, 7: {two}"));
        let problems = inspect_stage(&r).unwrap().problems;
        assert_eq!(problems.len(), 1, "{problems:?}");
        let p = &problems[0];
        assert_eq!(site(p), (Some("/Tube/Paint/Rings"), Some("points"), Rule::PointCounts));
        assert_eq!(
            p.message,
            "time samples disagreeing with curveVertexCounts (sum 250): 2 of 3, the first at time 5 with 2 points"
        );
        // One point, one sample: the words agree with the numbers.
        let r = tube_with_ring_samples("5: [(0, 0, 0)]");
        let problems = inspect_stage(&r).unwrap().problems;
        assert_eq!(
            problems.iter().map(|p| p.message.as_str()).collect::<Vec<_>>(),
            ["time samples disagreeing with curveVertexCounts (sum 250): 1 of 1, the first at time 5 with 1 point"]
        );
    }

    #[test]
    fn points_samples_must_be_finite_and_a_blocked_one_is_fine() {
        // The first non-finite point of the first sample that has one; the
        // count is right, so it is the only problem. A blocked sample has no
        // points at all.
        let r = tube_with_ring_samples(&format!(
            "2: None, 3: {}, 4: {}, 6: {}",
            ring_sample(None),
            ring_sample(Some(7)),
            ring_sample(Some(3))
        ));
        let problems = inspect_stage(&r).unwrap().problems;
        assert_eq!(problems.len(), 1, "{problems:?}");
        let p = &problems[0];
        assert_eq!(site(p), (Some("/Tube/Paint/Rings"), Some("points"), Rule::NonFinite));
        assert_eq!(p.message, "point 7 of the sample at time 4 is not finite ([1, NaN, 0])");
    }

    #[test]
    fn a_camera_that_is_not_there_is_a_problem() {
        // The stage itself is clean; only evaluating the frames with
        // --camera /NoCam (what bake --camera /NoCam does) fails.
        assert!(inspect(&tube(), None, None, &|_, _| {}).unwrap().problems.is_empty());
        let report = inspect(&tube(), Some("/NoCam"), None, &|_, _| {}).unwrap();
        assert_eq!(report.problems.len(), 1, "{:?}", report.problems);
        // The problem is bake's own error (`/NoCam: the camera named by
        // --camera does not exist`), on the prim --camera names.
        let p = &report.problems[0];
        assert_eq!(p.prim.as_deref(), Some("/NoCam"));
        assert!(p.message.contains("--camera"), "{}", p.message);
    }
}
