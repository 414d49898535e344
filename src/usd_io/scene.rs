//! Reads a painted character from a composed stage into plain data.
//!
//! A rig is a prim with `PainterlyRigAPI`; its `painterly:proxy` names the
//! proxy Mesh; its stroke layers are the `BasisCurves` with
//! `PainterlyStrokeLayerAPI` beneath it (SPEC §1–3). API schemas are read from
//! `apiSchemas` metadata and fallbacks are applied here, so painterly never
//! depends on the schema plugin being registered.

use std::collections::HashMap;

use glam::{DMat4, DVec3, Vec3};
use openusd::usd;

use super::axes::Axis;
use super::crate_samples::CrateSamples;
use super::guard::{MAX_PROXY_POINTS, MAX_STROKE_POINTS};
use super::skel::{skeleton_binding, SkelProxy};
use super::stage::{HeldQuery, StageReader};
use super::values;
use crate::bind::Binding;
use crate::error::{Error, Result};
use crate::interp::{InterpError, Method};
use crate::keys::{PoseChannel, TimeChannel, TimeKeyError};
use crate::rule::Rule;

pub const RIG_API: &str = "PainterlyRigAPI";
pub const STROKE_LAYER_API: &str = "PainterlyStrokeLayerAPI";
pub const VIEW_DEPENDENT_API: &str = "PainterlyViewDependentAPI";

/// How a proxy mesh is animated (SPEC §2).
pub enum ProxyMotion {
    /// UsdSkel skinning.
    Skel(Box<SkelProxy>),
    /// Time-sampled `points`.
    Sampled,
    /// Only a default value of `points`.
    Static,
}

impl ProxyMotion {
    /// A word for reports.
    pub fn describe(&self) -> &'static str {
        match self {
            ProxyMotion::Skel(_) => "UsdSkel",
            ProxyMotion::Sampled => "time-sampled points",
            ProxyMotion::Static => "static points",
        }
    }
}

/// A proxy mesh: topology, rest pose, and how it moves.
pub struct Proxy {
    pub path: String,
    pub face_counts: Vec<u32>,
    pub face_indices: Vec<u32>,
    /// Rest pose, mesh-local (SPEC §2).
    pub rest: Vec<DVec3>,
    pub motion: ProxyMotion,
    /// Authored `normals` of a UsdSkel proxy, when BakeSkinning rewrites them.
    normals: Option<RestNormals>,
    prim: usd::Prim,
    /// A cached query on `points`: per-frame reads through a plain attribute
    /// decode every time sample of a crate file each time.
    points_query: HeldQuery,
    /// Time-sampled `points` read one sample at a time from the crate file,
    /// where that gives what `points_query` gives (a point cache).
    points_samples: Option<CrateSamples>,
}

/// A skinned proxy's authored `normals`: per point (`vertex`, `varying`)
/// or per face vertex (`faceVarying`, with the point of each).
struct RestNormals {
    values: Vec<DVec3>,
    point_of: Option<Vec<u32>>,
}

/// The `normals` BakeSkinning deforms (`vertex`, `varying`, `faceVarying`,
/// sized for the mesh); others it leaves alone, and so do we.
fn read_rest_normals(
    r: &StageReader,
    prim: &usd::Prim,
    npts: usize,
    face_indices: &[i64],
) -> Result<Option<RestNormals>> {
    // Not a 3-vector array: usd-core cannot read it as normals either.
    let Some(n) = r.value(prim, "normals", None)?.as_ref().and_then(values::vec3_array) else {
        return Ok(None);
    };
    let values: Vec<DVec3> = n.iter().map(|v| v.as_dvec3()).collect();
    let point_of = match r.primvar_interpolation(prim, "normals", "vertex")?.as_str() {
        "vertex" | "varying" if values.len() == npts => None,
        "faceVarying" if values.len() == face_indices.len() => Some(face_indices.iter().map(|&i| i as u32).collect()),
        _ => return Ok(None),
    };
    Ok(Some(RestNormals { values, point_of }))
}

/// A stroke layer's per-point normals, which the bake turns with its
/// strokes ([`read_stroke_normals`]).
#[derive(Debug, Clone)]
pub struct StrokeNormals {
    /// `primvars:normals` when it has a value (UsdGeom reads it before
    /// `normals`), else `normals`.
    pub attr: &'static str,
    /// The primvar is indexed: the bake writes one normal per point and
    /// blocks its indices, as it does displayOpacity's.
    pub indexed: bool,
    /// One per point, read as proxy-local like points without
    /// `painterly:restPoints`.
    pub rest: Vec<Vec3>,
}

/// A stroke layer's normals the bake turns with its strokes: the default
/// value of the one UsdGeom reads (`primvars:normals`, indices resolved,
/// else `normals`) when it holds one normal per point (`vertex`,
/// `varying` or `faceVarying` interpolation, which for curves count
/// alike), like the proxy normals BakeSkinning deforms; other layouts (per
/// curve, constant, time samples only) compose through unchanged, as they
/// do for a proxy.
fn read_stroke_normals(r: &StageReader, prim: &usd::Prim, path: &str, npoints: usize) -> Result<Option<StrokeNormals>> {
    for attr in ["primvars:normals", "normals"] {
        let Some(values) = r.value(prim, attr, None)?.as_ref().and_then(values::vec3_array) else {
            continue;
        };
        let indices_attr = "primvars:normals:indices";
        let indices = match attr {
            "primvars:normals" => r.typed(prim, indices_attr, None, "int[]", values::int_array)?,
            _ => None,
        };
        let n = match &indices {
            None => values,
            Some(idx) => flatten_indexed(&values, idx, path, indices_attr)?,
        };
        let interpolation = r.primvar_interpolation(prim, attr, "vertex")?;
        if n.len() != npoints || !matches!(interpolation.as_str(), "vertex" | "varying" | "faceVarying") {
            return Ok(None);
        }
        if let Some(i) = n.iter().position(|v| !v.is_finite()) {
            return Err(Error::attr(path, attr, format!("normal {i} is not finite ({})", n[i])).rule(Rule::NonFinite));
        }
        return Ok(Some(StrokeNormals {
            attr,
            indexed: indices.is_some(),
            rest: n,
        }));
    }
    Ok(None)
}

/// An indexed primvar's values, one per index (elementSize 1); an index
/// out of range is an error on `indices_attr` of `path`.
fn flatten_indexed<T: Copy>(values: &[T], indices: &[i64], path: &str, indices_attr: &str) -> Result<Vec<T>> {
    indices
        .iter()
        .map(|&i| usize::try_from(i).ok().and_then(|i| values.get(i).copied()))
        .collect::<Option<Vec<_>>>()
        .ok_or_else(|| Error::attr(path, indices_attr, "index out of range"))
}

/// One stroke layer (a BasisCurves prim).
pub struct StrokeLayer {
    pub path: String,
    /// Points per stroke (`curveVertexCounts`).
    pub curve_counts: Vec<u32>,
    /// Rest positions, proxy-local.
    pub rest_points: Vec<Vec3>,
    /// The default value of `points` (stroke-local, what viewers draw), if authored.
    pub points: Option<Vec<Vec3>>,
    /// `painterly:bindVertices`/`bindWeights` when authored.
    pub cached_binding: Option<Binding>,
    /// `painterly:opacity` (fallback 1).
    pub opacity: f32,
    /// `painterly:opacity` at every time, once read, when it cannot vary
    /// in time (read per frame otherwise).
    fixed_opacity: Option<std::sync::OnceLock<f32>>,
    /// `painterly:opacity` has time samples: its default is never read.
    opacity_sampled: bool,
    /// Authored `primvars:displayOpacity` per curve (1 when absent), its
    /// default value.
    pub display_opacity: Vec<f32>,
    /// Whether `primvars:displayOpacity` or its indices have time samples
    /// (then read per frame: [`StrokeLayer::display_opacity_at`]).
    display_varies: bool,
    /// Whether `primvars:displayOpacity:indices` is authored (a value or a
    /// sample): the bake writes one value per curve, so it blocks them.
    pub display_indexed: bool,
    /// `widths`, as far as the extent needs them (see [`StrokeLayer::max_width_at`]).
    widths: Widths,
    /// Pose and time keys (SPEC §4–5).
    pub keys: LayerKeys,
    /// Per-point normals the bake turns with the strokes.
    pub rest_normals: Option<StrokeNormals>,
    prim: usd::Prim,
}

/// A stroke layer's `widths` for its extent (`UsdGeom.Curves.ComputeExtent`
/// pads by half the largest width, whatever the interpolation).
enum Widths {
    /// Not time-sampled: the largest width (0 when there are none).
    Constant(f32),
    /// Time samples (None: a value block), in time order.
    Sampled(Vec<(f64, Option<Vec<f32>>)>),
}

impl Widths {
    /// The largest width at `t` of widths interpolated as usd-core does
    /// (`Usd_Interpolate`): held outside the samples and next to a block
    /// or a size change, else `(1 − α)·lower + α·upper` per element in
    /// double precision, rounded to float.
    fn max_at(&self, t: f64) -> f32 {
        let samples = match self {
            Widths::Constant(w) => return *w,
            Widths::Sampled(s) => s,
        };
        let value = |w: &Option<Vec<f32>>| w.as_ref().map_or(0.0, |w| crate::extent::max_width(w.iter().copied()));
        let upper = samples.partition_point(|(st, _)| *st <= t);
        if upper == 0 {
            return value(&samples[0].1);
        }
        let (t0, lower) = &samples[upper - 1];
        let Some((t1, next)) = samples.get(upper) else {
            return value(lower);
        };
        let alpha = (t - t0) / (t1 - t0);
        match (lower, next) {
            (Some(a), Some(b)) if a.len() == b.len() && (t1 - t0).abs() >= 1e-6 && alpha != 0.0 => {
                if alpha == 1.0 {
                    return crate::extent::max_width(b.iter().copied());
                }
                let lerp = a
                    .iter()
                    .zip(b)
                    .map(|(&a, &b)| ((1.0 - alpha) * a as f64 + alpha * b as f64) as f32);
                crate::extent::max_width(lerp)
            }
            _ => value(lower),
        }
    }
}

/// Reads `widths`, checking every value (every sample) is finite.
fn read_widths(r: &StageReader, prim: &usd::Prim, path: &str) -> Result<Widths> {
    let check = |w: &[f32], t: Option<f64>| -> Result<()> {
        match w.iter().position(|w| !w.is_finite()) {
            None => Ok(()),
            Some(i) => {
                let at = t.map_or(String::new(), |t| format!(" at time {t}"));
                Err(Error::attr(path, "widths", format!("width {i} is not finite{at}")).rule(Rule::NonFinite))
            }
        }
    };
    let times = r.sample_times(prim, "widths")?;
    if times.is_empty() {
        let w = r
            .typed(prim, "widths", None, "float[]", values::f32_array)?
            .unwrap_or_default();
        check(&w, None)?;
        return Ok(Widths::Constant(crate::extent::max_width(w)));
    }
    let mut samples = Vec::with_capacity(times.len());
    if let Some(read) = r.sample_values(prim, "widths")? {
        // One read of the whole map (see `sample_values`).
        for (t, v) in read {
            let w = super::stage::convert_typed(prim, "widths", "float[]", &v, values::f32_array)?;
            check(&w, Some(t))?;
            samples.push((t, Some(w)));
        }
    } else {
        for t in times {
            let w = r.typed(prim, "widths", Some(t), "float[]", values::f32_array)?;
            if let Some(w) = &w {
                check(w, Some(t))?;
            }
            samples.push((t, w));
        }
    }
    samples.sort_by(|a, b| a.0.total_cmp(&b.0));
    Ok(Widths::Sampled(samples))
}

/// A channel's keys: the precomputed interpolant, the key prims, their values.
pub struct Channel<C, V> {
    pub interp: C,
    pub paths: Vec<String>,
    pub values: Vec<V>,
}

/// A layer's keys.
#[derive(Default)]
pub struct LayerKeys {
    /// The layer's axes, as indices into [`Rig::axes`], in coordinate order.
    pub axes: Vec<usize>,
    /// Each of those axes' `scale`. Key coordinates are authored in axis
    /// units; the pose channels interpolate over scaled coordinates (SPEC
    /// 1.1 §4), see [`LayerKeys::configuration`].
    pub scales: Vec<f64>,
    /// Interpolation method (`painterly:interpolation`).
    pub method: Option<Method>,
    pub pose_points: Option<Channel<PoseChannel, Vec<Vec3>>>,
    pub pose_opacity: Option<Channel<PoseChannel, f32>>,
    pub time_points: Option<Channel<TimeChannel, Vec<Vec3>>>,
    pub time_opacity: Option<Channel<TimeChannel, f32>>,
    /// Number of sentinels.
    pub sentinels: usize,
}

impl LayerKeys {
    /// Whether any pose key needs axis values.
    pub fn uses_axes(&self) -> bool {
        self.pose_points.is_some() || self.pose_opacity.is_some()
    }

    /// The point in configuration space where the pose channels are
    /// evaluated: this layer's axis values (in axis units, indexed by rig
    /// axis) each multiplied by its axis's `scale`, as the keys'
    /// coordinates were. A layer without axes sits at the origin of a 1-D
    /// space.
    pub fn configuration(&self, axis_values: &[f64]) -> Vec<f64> {
        if self.axes.is_empty() {
            return vec![0.0];
        }
        self.axes
            .iter()
            .zip(&self.scales)
            .map(|(&a, &s)| axis_values[a] * s)
            .collect()
    }
}

/// A rig: its proxy and stroke layers.
pub struct Rig {
    pub path: String,
    pub proxy: Proxy,
    pub layers: Vec<StrokeLayer>,
    /// Axes used by the rig's layers (every PainterlyAxis under the rig,
    /// plus any other a layer's `painterly:axes` targets).
    pub axes: Vec<Axis>,
}

/// Everything painterly found in a stage.
pub struct Scene {
    pub rigs: Vec<Rig>,
}

impl Scene {
    /// Discovers and validates every rig and stroke layer; fails on the first problem.
    pub fn read(r: &StageReader) -> Result<Scene> {
        let (scene, mut problems) = Scene::read_lenient(r)?;
        if problems.is_empty() {
            Ok(scene)
        } else {
            Err(problems.swap_remove(0))
        }
    }

    /// Like [`Scene::read`], but skips broken rigs and layers and returns
    /// every problem found (for `painterly inspect`). Fails only when the
    /// stage itself cannot be traversed.
    pub fn read_lenient(r: &StageReader) -> Result<(Scene, Vec<Error>)> {
        let paths = r.prim_paths()?;
        let mut problems = Vec::new();
        let mut rig_paths = Vec::new();
        let mut layer_paths = Vec::new();
        for p in &paths {
            let prim = r.require_prim(p)?;
            let apis = r.api_schemas(&prim)?;
            if apis.iter().any(|a| a == RIG_API) {
                rig_paths.push(p.clone());
            }
            if apis.iter().any(|a| a == STROKE_LAYER_API) {
                layer_paths.push(p.clone());
            }
        }
        check_stroke_point_total(r, &layer_paths, &rig_paths)?;
        problems.extend(instanced_characters(r, &paths)?);
        let mut rigs = Vec::new();
        for rp in &rig_paths {
            let prim = r.require_prim(rp)?;
            match read_proxy(r, &prim) {
                Ok(proxy) => rigs.push(Rig {
                    path: rp.clone(),
                    proxy,
                    layers: Vec::new(),
                    axes: Vec::new(),
                }),
                Err(e) => problems.push(e.or_rule(Rule::Unreadable)),
            }
        }
        for lp in &layer_paths {
            // The nearest enclosing rig owns the layer.
            let owner = rigs
                .iter_mut()
                .filter(|rig| is_descendant(lp, &rig.path))
                .max_by_key(|rig| rig.path.len());
            let Some(owner) = owner else {
                if !rig_paths.iter().any(|rp| is_descendant(lp, rp)) {
                    problems.push(
                        Error::prim(
                            lp,
                            format!("stroke layer ({STROKE_LAYER_API}) is not under a prim with {RIG_API}"),
                        )
                        .rule(Rule::LayerOutsideRig),
                    );
                }
                continue;
            };
            let mut layer = match read_layer(r, lp, owner.proxy.rest.len()) {
                Ok(layer) => layer,
                Err(e) => {
                    problems.push(e.or_rule(Rule::Unreadable));
                    continue;
                }
            };
            // A layer whose keys (or their axes) cannot be read is still the
            // rig's layer, with its strokes and points: it stays, keyless,
            // beside the problem, so inspect lists it. Bake stops at the
            // problem, so the keyless layer is never baked.
            match read_keys(r, &paths, owner, &layer) {
                Ok(keys) => layer.keys = keys,
                Err(e) => problems.push(e.or_rule(Rule::Unreadable)),
            }
            owner.layers.push(layer);
        }
        Ok((Scene { rigs }, problems))
    }
}

/// Instances (`instanceable` prims with a composition arc) that hold a
/// rig, a stroke layer or a view-dependent mesh. Discovery, like usd-core's
/// default traversal, does not look inside an instance, and a bake could not
/// write there anyway: USD ignores a layer's opinions on the prims below an
/// instance. So each such instance is a problem naming the first painterly
/// prim inside; each prototype is searched once.
fn instanced_characters(r: &StageReader, paths: &[String]) -> Result<Vec<Error>> {
    let mut first_inside: HashMap<String, Option<String>> = HashMap::new();
    let mut problems = Vec::new();
    for p in paths {
        let prim = r.require_prim(p)?;
        let fail = |e: &dyn std::fmt::Display| Error::prim(p, format!("cannot read instancing: {e}"));
        if !prim.is_instance().map_err(|e| fail(&e))? {
            continue;
        }
        let prototype = prim
            .prototype()
            .map_err(|e| fail(&e))?
            .map_or_else(|| p.clone(), |q| q.as_str().to_string());
        let relative = match first_inside.get(&prototype) {
            Some(found) => found.clone(),
            None => {
                let found = first_painterly_prim_below(r, &prim)?.map(|q| q[p.len()..].to_string());
                first_inside.insert(prototype, found.clone());
                found
            }
        };
        if let Some(rel) = relative {
            let message = format!(
                "an instance (instanceable = true) holds painterly prims ({p}{rel}), which a bake cannot override: \
                 USD ignores opinions below an instance; set `instanceable = false` on {p} to bake it"
            );
            problems.push(Error::prim(p, message).rule(Rule::Instanced));
        }
    }
    Ok(problems)
}

/// The first prim below `prim` (depth first, instance proxies included)
/// with a painterly API schema.
fn first_painterly_prim_below(r: &StageReader, prim: &usd::Prim) -> Result<Option<String>> {
    let mut stack = r.read_children(prim)?;
    stack.reverse();
    while let Some(c) = stack.pop() {
        let apis = r.api_schemas(&c)?;
        if apis
            .iter()
            .any(|a| a == RIG_API || a == STROKE_LAYER_API || a == VIEW_DEPENDENT_API)
        {
            return Ok(Some(c.path().as_str().to_string()));
        }
        let mut children = r.read_children(&c)?;
        children.reverse();
        stack.extend(children);
    }
    Ok(None)
}

/// README, Limits: the stroke points of all layers under a rig, summed
/// from their `curveVertexCounts` before any layer's points are read, so a
/// run over the limit fails fast and with bounded memory. The error names
/// the layer whose counts cross the limit. Counts that cannot be read or
/// are negative are left to the layer's own checks.
fn check_stroke_point_total(r: &StageReader, layer_paths: &[String], rig_paths: &[String]) -> Result<()> {
    let mut total = 0i64;
    for lp in layer_paths {
        if !rig_paths.iter().any(|rp| is_descendant(lp, rp)) {
            continue;
        }
        let Ok(prim) = r.require_prim(lp) else { continue };
        let Ok(Some(counts)) = r.typed(&prim, "curveVertexCounts", None, "int[]", values::int_array) else {
            continue;
        };
        total = counts.iter().fold(total, |t, &c| t.saturating_add(c.max(0)));
        if total > MAX_STROKE_POINTS as i64 {
            let message = format!(
                "{total} stroke points; painterly bakes at most {MAX_STROKE_POINTS} in one run \
                 (bake its stroke layers in several runs, deactivating the others in a layer over the input)"
            );
            return Err(Error::attr(lp, "curveVertexCounts", message).rule(Rule::PointCounts));
        }
    }
    Ok(())
}

fn is_descendant(path: &str, ancestor: &str) -> bool {
    path.len() > ancestor.len()
        && path.starts_with(ancestor)
        && (ancestor == "/" || path.as_bytes()[ancestor.len()] == b'/')
}

/// An authored opacity must be a number in [0, 1] (UsdGeom's displayOpacity
/// range, and what `painterly key --opacity` takes): outside it a bake would
/// write a meaningless opacity. `when` is "" or " at time t".
fn check_opacity(o: f32, prim: &str, attr: &str, when: &str) -> Result<()> {
    if !o.is_finite() {
        return Err(Error::attr(prim, attr, format!("opacity is not finite{when}")).rule(Rule::NonFinite));
    }
    // A few float steps outside, as float32 sums of weights give, are 0 or 1.
    const ROUNDING: f32 = 1e-6;
    if !(-ROUNDING..=1.0 + ROUNDING).contains(&o) {
        return Err(Error::attr(prim, attr, format!("opacity {o}{when} is outside [0, 1]")).rule(Rule::DisplayOpacity));
    }
    Ok(())
}

fn check_finite(points: &[Vec3], prim: &str, attr: &str) -> Result<()> {
    match points.iter().position(|p| !p.is_finite()) {
        None => Ok(()),
        Some(i) => {
            Err(Error::attr(prim, attr, format!("point {i} is not finite ({})", points[i])).rule(Rule::NonFinite))
        }
    }
}

fn read_proxy(r: &StageReader, rig: &usd::Prim) -> Result<Proxy> {
    let rig_path = rig.path().as_str();
    let targets = r.targets(rig, "painterly:proxy")?;
    let proxy_path = match targets.as_slice() {
        [] => {
            return Err(Error::attr(
                rig_path,
                "painterly:proxy",
                "not authored: a rig must name its proxy Mesh with `rel painterly:proxy`",
            )
            .rule(Rule::MissingProxy))
        }
        [p] => p.clone(),
        many => {
            return Err(Error::attr(
                rig_path,
                "painterly:proxy",
                format!("has {} targets, expected exactly one Mesh", many.len()),
            )
            .rule(Rule::MissingProxy))
        }
    };
    let prim = r.prim(&proxy_path)?.ok_or_else(|| {
        Error::attr(
            rig_path,
            "painterly:proxy",
            format!("targets {proxy_path}, which does not exist"),
        )
        .rule(Rule::MissingProxy)
    })?;
    let ty = r.type_name(&prim)?;
    if ty != "Mesh" {
        return Err(Error::attr(
            rig_path,
            "painterly:proxy",
            format!("targets {proxy_path}, a {:?} prim, expected a Mesh", ty),
        )
        .rule(Rule::MissingProxy));
    }
    read_mesh(r, prim, read_rest_time(r, rig)?)
}

/// `painterly:restTime` on a rig or view-dependent mesh: a finite time.
pub fn read_rest_time(r: &StageReader, prim: &usd::Prim) -> Result<Option<f64>> {
    let t = r.typed(prim, "painterly:restTime", None, "double", values::scalar)?;
    match t {
        Some(t) if !t.is_finite() => Err(Error::attr(
            prim.path().as_str(),
            "painterly:restTime",
            format!("rest time {t} is not finite"),
        )
        .rule(Rule::NonFinite)),
        t => Ok(t),
    }
}

/// UsdGeom.Mesh.ValidateTopology's first two rules for faceVertexCounts:
/// no negative count, and the counts sum to the number of indices.
pub(crate) fn check_face_counts(path: &str, counts: &[i64], indices: &[i64]) -> Result<()> {
    if let Some(bad) = counts.iter().find(|&&c| c < 0) {
        return Err(Error::attr(path, "faceVertexCounts", format!("negative count {bad}")));
    }
    let sum: i64 = counts.iter().sum();
    if sum != indices.len() as i64 {
        return Err(Error::attr(
            path,
            "faceVertexCounts",
            format!("counts sum to {sum}, but there are {} faceVertexIndices", indices.len()),
        ));
    }
    Ok(())
}

/// A mesh's faces as drawn (render's meshes, the preview's proxies): counts
/// and indices checked against each other, no negative index; unauthored
/// topology is empty, USD's fallback.
pub(crate) fn read_face_topology(r: &StageReader, prim: &usd::Prim, path: &str) -> Result<(Vec<u32>, Vec<u32>)> {
    let counts = r
        .typed(prim, "faceVertexCounts", None, "int[]", values::int_array)?
        .unwrap_or_default();
    let indices = r
        .typed(prim, "faceVertexIndices", None, "int[]", values::int_array)?
        .unwrap_or_default();
    check_face_counts(path, &counts, &indices)?;
    if let Some(bad) = indices.iter().find(|&&i| i < 0) {
        return Err(Error::attr(path, "faceVertexIndices", format!("negative index {bad}")));
    }
    Ok((
        counts.iter().map(|&c| c as u32).collect(),
        indices.iter().map(|&i| i as u32).collect(),
    ))
}

/// Reads a Mesh's topology, rest pose and motion kind (SPEC §2).
///
/// `rest_time`: where a non-skinned mesh's rest pose is read (`painterly:restTime`),
/// else its default `points`.
pub fn read_mesh(r: &StageReader, prim: usd::Prim, rest_time: Option<f64>) -> Result<Proxy> {
    let proxy_path = prim.path().as_str().to_string();
    let counts = r
        .typed(&prim, "faceVertexCounts", None, "int[]", values::int_array)?
        .ok_or_else(|| Error::attr(&proxy_path, "faceVertexCounts", "proxy mesh has no faces").rule(Rule::Mesh))?;
    let indices = r
        .typed(&prim, "faceVertexIndices", None, "int[]", values::int_array)?
        .ok_or_else(|| Error::attr(&proxy_path, "faceVertexIndices", "proxy mesh has no faces").rule(Rule::Mesh))?;
    check_face_counts(&proxy_path, &counts, &indices).map_err(|e| e.rule(Rule::Mesh))?;
    if !counts.iter().any(|&c| c >= 3) {
        return Err(Error::attr(
            &proxy_path,
            "faceVertexCounts",
            "proxy mesh has no polygon with 3 or more vertices",
        )
        .rule(Rule::Mesh));
    }

    // Rest pose and motion kind (SPEC §2).
    let skeleton = skeleton_binding(r, &prim).map_err(|e| e.or_rule(Rule::Skinning))?;
    // Crate samples exist only where samples are authored.
    let points_samples = r.crate_samples(&prim, "points");
    let has_samples = points_samples.is_some() || !r.sample_times(&prim, "points")?.is_empty();
    let rest_pts = if skeleton.is_some() {
        // usd-core skins the points it reads at each time; one value serves.
        r.typed_over_time(&prim, "points", "point3f[]", values::vec3_array)?
    } else if let Some(t) = rest_time {
        match &points_samples {
            Some(s) => points_read(&proxy_path, t, s.value_at(t))?,
            None => r.typed(&prim, "points", Some(t), "point3f[]", values::vec3_array)?,
        }
    } else {
        r.typed(&prim, "points", None, "point3f[]", values::vec3_array)?
    };
    let rest_pts = match rest_pts {
        Some(p) if !p.is_empty() => p,
        _ => {
            let why = if skeleton.is_some() {
                "skinned proxy has no `points` (its bind pose)"
            } else if has_samples {
                "proxy has only time-sampled points: author a default value or `double painterly:restTime` on the rig"
            } else {
                "proxy mesh has no points"
            };
            return Err(Error::attr(&proxy_path, "points", why).rule(Rule::Mesh));
        }
    };
    if rest_pts.len() > MAX_PROXY_POINTS {
        return Err(Error::attr(
            &proxy_path,
            "points",
            format!(
                "{} points; painterly binds to proxies of at most {MAX_PROXY_POINTS} points (use a lighter proxy mesh)",
                rest_pts.len()
            ),
        )
        .rule(Rule::Mesh));
    }
    check_finite(&rest_pts, &proxy_path, "points")?;
    let n = rest_pts.len();
    if let Some(bad) = indices.iter().find(|&&i| i < 0 || i as usize >= n) {
        return Err(Error::attr(
            &proxy_path,
            "faceVertexIndices",
            format!("index {bad} is out of range ({n} points)"),
        )
        .rule(Rule::Mesh));
    }
    let rest: Vec<DVec3> = rest_pts.iter().map(|p| p.as_dvec3()).collect();
    let motion = match skeleton {
        Some(s) => ProxyMotion::Skel(Box::new(
            SkelProxy::read(r, &prim, &s, &rest).map_err(|e| e.or_rule(Rule::Skinning))?,
        )),
        None if has_samples => ProxyMotion::Sampled,
        None => ProxyMotion::Static,
    };
    let normals = match &motion {
        ProxyMotion::Skel(s) if s.deforms_normals() => read_rest_normals(r, &prim, n, &indices)?,
        _ => None,
    };
    Ok(Proxy {
        path: proxy_path,
        face_counts: counts.iter().map(|&c| c as u32).collect(),
        face_indices: indices.iter().map(|&i| i as u32).collect(),
        rest,
        motion,
        normals,
        points_query: HeldQuery::new(&prim, "points")?,
        points_samples,
        prim,
    })
}

impl Proxy {
    /// Posed points in the proxy's local space at time `t`.
    pub fn posed_points(&self, r: &StageReader, t: f64) -> Result<Vec<DVec3>> {
        let pts = match &self.motion {
            ProxyMotion::Static => return Ok(self.rest.clone()),
            ProxyMotion::Sampled => {
                let p = self.sampled_points(t)?;
                p.iter().map(|p| p.as_dvec3()).collect::<Vec<_>>()
            }
            ProxyMotion::Skel(s) => {
                let pts = s.deform(t)?;
                if s.skins_joints() {
                    // Skeleton space → mesh space, as BakeSkinning writes them.
                    let skel_prim = r.require_prim(&s.skeleton)?;
                    let to_local = self.local_to_world(r, t)?.inverse() * r.local_to_world(&skel_prim, t)?;
                    pts.iter().map(|p| to_local.transform_point3(*p)).collect()
                } else {
                    pts
                }
            }
        };
        if let Some(i) = pts.iter().position(|p| !p.is_finite()) {
            return Err(Error::attr(
                &self.path,
                "points",
                format!("posed point {i} is not finite at time {t}"),
            ));
        }
        Ok(pts)
    }

    /// Whether the proxy has authored normals that BakeSkinning rewrites
    /// (a UsdSkel proxy's `vertex`, `varying` or `faceVarying` normals).
    pub fn has_deformed_normals(&self) -> bool {
        self.normals.is_some()
    }

    /// The proxy's authored normals at `t`, deformed as BakeSkinning
    /// rewrites them (mesh-local); None when it leaves them alone.
    pub fn posed_normals(&self, r: &StageReader, t: f64) -> Result<Option<Vec<Vec3>>> {
        let (ProxyMotion::Skel(s), Some(rest)) = (&self.motion, &self.normals) else {
            return Ok(None);
        };
        let mut n = s.deform_normals(t, &rest.values, rest.point_of.as_deref())?;
        if s.skins_joints() {
            // Skeleton space → mesh space, not renormalised (as BakeSkinning).
            let skel_prim = r.require_prim(&s.skeleton)?;
            let to_local = self.local_to_world(r, t)?.inverse() * r.local_to_world(&skel_prim, t)?;
            let m = glam::DMat3::from_mat4(to_local).inverse().transpose();
            n.iter_mut().for_each(|v| *v = m * *v);
        }
        if let Some(i) = n.iter().position(|v| !v.is_finite()) {
            return Err(Error::attr(
                &self.path,
                "normals",
                format!("deformed normal {i} is not finite at time {t}"),
            ));
        }
        Ok(Some(n.iter().map(|v| v.as_vec3()).collect()))
    }

    /// Posed points in f32 (what view-dependent blending and output use);
    /// time-sampled points are returned without a round trip through f64.
    pub fn posed_points_f32(&self, r: &StageReader, t: f64) -> Result<Vec<Vec3>> {
        match self.motion {
            ProxyMotion::Sampled => {
                let p = self.sampled_points(t)?;
                if let Some(i) = p.iter().position(|p| !p.is_finite()) {
                    return Err(Error::attr(
                        &self.path,
                        "points",
                        format!("point {i} is not finite at time {t}"),
                    ));
                }
                Ok(p)
            }
            _ => Ok(self.posed_points(r, t)?.iter().map(|p| p.as_vec3()).collect()),
        }
    }

    /// Time-sampled `points` at `t` (USD's linear interpolation), checked for count.
    fn sampled_points(&self, t: f64) -> Result<Vec<Vec3>> {
        let v = match &self.points_samples {
            Some(s) => s.value_at(t),
            None => self.points_query.get_at(t),
        };
        let p = points_read(&self.path, t, v)?.unwrap_or_default();
        if p.len() != self.rest.len() {
            return Err(Error::attr(
                &self.path,
                "points",
                format!(
                    "{} points at time {t}, but the rest pose has {}",
                    p.len(),
                    self.rest.len()
                ),
            ));
        }
        Ok(p)
    }

    /// The proxy's local-to-world transform at `t`.
    pub fn local_to_world(&self, r: &StageReader, t: f64) -> Result<DMat4> {
        r.local_to_world(&self.prim, t)
    }

    /// Whether the proxy is skinned (a bake that writes it must block `skel:skeleton`).
    pub fn is_skinned(&self) -> bool {
        matches!(self.motion, ProxyMotion::Skel(_))
    }
}

/// A mesh's `points` as read at `t` (`None`: no value there), with the
/// errors naming `mesh`.
fn points_read(
    mesh: &str,
    t: f64,
    read: std::result::Result<Option<openusd::sdf::Value>, String>,
) -> Result<Option<Vec<Vec3>>> {
    read.map_err(|e| Error::attr(mesh, "points", format!("cannot read at time {t}: {e}")))?
        .map(|v| {
            values::into_vec3_array(v)
                .map_err(|kind| Error::attr(mesh, "points", format!("expected point3f[], found {kind}")))
        })
        .transpose()
}

fn read_layer(r: &StageReader, path: &str, proxy_points: usize) -> Result<StrokeLayer> {
    let prim = r.require_prim(path)?;
    let ty = r.type_name(&prim)?;
    if ty != "BasisCurves" {
        return Err(Error::prim(
            path,
            format!("{STROKE_LAYER_API} is applied to a {ty:?} prim; stroke layers must be BasisCurves"),
        )
        .rule(Rule::LayerNotCurves));
    }
    let counts = match r.typed(&prim, "curveVertexCounts", None, "int[]", values::int_array)? {
        Some(c) => c,
        // usd-core would read the samples; painterly's strokes keep one topology.
        None if !r.sample_times(&prim, "curveVertexCounts")?.is_empty() => {
            return Err(Error::attr(
                path,
                "curveVertexCounts",
                "authored only as time samples: painterly reads a stroke layer's counts from their default \
                 value (one topology for every frame); author them without a time",
            )
            .rule(Rule::PointCounts))
        }
        None => Vec::new(),
    };
    if let Some(bad) = counts.iter().find(|&&c| c < 0) {
        return Err(Error::attr(path, "curveVertexCounts", format!("negative count {bad}")).rule(Rule::PointCounts));
    }
    // At most MAX_STROKE_POINTS: check_stroke_point_total ran first.
    let total: i64 = counts.iter().sum();
    let points = r.typed(&prim, "points", None, "point3f[]", values::vec3_array)?;
    let rest = r.typed(&prim, "painterly:restPoints", None, "point3f[]", values::vec3_array)?;
    if let Some(p) = &points {
        check_finite(p, path, "points")?;
        if p.len() as i64 != total {
            return Err(Error::attr(
                path,
                "curveVertexCounts",
                format!("counts sum to {total}, but the layer has {} points", p.len()),
            )
            .rule(Rule::PointCounts));
        }
    }
    let authored_points = points.clone();
    let rest_points = match (rest, points) {
        (Some(rest), points) => {
            check_finite(&rest, path, "painterly:restPoints")?;
            if let Some(p) = points {
                if p.len() != rest.len() {
                    return Err(Error::attr(
                        path,
                        "painterly:restPoints",
                        format!("{} rest points, but the layer has {} points", rest.len(), p.len()),
                    )
                    .rule(Rule::PointCounts));
                }
            }
            if rest.len() as i64 != total {
                return Err(Error::attr(
                    path,
                    "painterly:restPoints",
                    format!("{} rest points, but curveVertexCounts sum to {total}", rest.len()),
                )
                .rule(Rule::PointCounts));
            }
            rest
        }
        (None, Some(p)) => p,
        (None, None) => {
            return Err(Error::attr(
                path,
                "points",
                "stroke layer has neither painterly:restPoints nor a default value of points",
            )
            .rule(Rule::MissingRestPoints))
        }
    };

    let cached_binding =
        read_cached_binding(r, &prim, path, rest_points.len(), proxy_points).map_err(|e| e.or_rule(Rule::Binding))?;
    let opacity = r
        .typed(&prim, "painterly:opacity", None, "float", values::scalar)?
        .unwrap_or(1.0) as f32;
    // With time samples the default is never read at a frame (usd-core's
    // value resolution): each frame's value is checked as it is read.
    let opacity_sampled = !r.sample_times(&prim, "painterly:opacity")?.is_empty();
    if !opacity_sampled {
        check_opacity(opacity, path, "painterly:opacity", "")?;
    }
    let opacity_varies = prim
        .attribute("painterly:opacity")
        .value_might_be_time_varying()
        .map_err(|e| Error::attr(path, "painterly:opacity", format!("cannot read: {e}")))?;
    // Any time sample (even one: the default time does not read it) means
    // a read per frame.
    let mut display_varies = false;
    let mut indices_sampled = false;
    let mut first_sample = f64::INFINITY;
    for name in ["primvars:displayOpacity", "primvars:displayOpacity:indices"] {
        let times = r.sample_times(&prim, name)?;
        display_varies |= !times.is_empty();
        indices_sampled |= name.ends_with(":indices") && !times.is_empty();
        first_sample = times.first().map_or(first_sample, |&t| first_sample.min(t));
    }
    let display_indexed = indices_sampled
        || r.typed(
            &prim,
            "primvars:displayOpacity:indices",
            None,
            "int[]",
            values::int_array,
        )?
        .is_some();
    // Sampled values or indices need not fit at the default time (indices
    // authored only as samples): the bake reads them per frame, and what
    // stands for them at no time is their first sample.
    let display_opacity = match read_display_opacity(r, &prim, path, &counts, None) {
        Err(_) if display_varies && first_sample.is_finite() => {
            read_display_opacity(r, &prim, path, &counts, Some(first_sample))
        }
        read => read,
    }
    .map_err(|e| e.or_rule(Rule::DisplayOpacity))?;
    let widths = read_widths(r, &prim, path)?;
    let rest_normals = read_stroke_normals(r, &prim, path, rest_points.len())?;
    Ok(StrokeLayer {
        path: path.to_string(),
        curve_counts: counts.iter().map(|&c| c as u32).collect(),
        rest_points,
        points: authored_points,
        cached_binding,
        opacity,
        fixed_opacity: (!opacity_varies).then(std::sync::OnceLock::new),
        opacity_sampled,
        display_opacity,
        display_varies,
        display_indexed,
        widths,
        keys: LayerKeys::default(),
        rest_normals,
        prim,
    })
}

/// Index of the axis at `path` in the rig's table, reading it on first use.
fn axis_index(r: &StageReader, rig: &mut Rig, path: &str) -> Result<usize> {
    if let Some(i) = rig.axes.iter().position(|a| a.path == path) {
        return Ok(i);
    }
    rig.axes.push(Axis::read(r, path).map_err(|e| e.or_rule(Rule::Axis))?);
    Ok(rig.axes.len() - 1)
}

fn duplicate_error(paths: &[String], e: InterpError, channel: &str) -> Error {
    match e {
        InterpError::DuplicateKeys { first, second } => Error::attr(
            &paths[first],
            "coordinates",
            format!(
                "{} has the same coordinates: two {channel} keys at one configuration",
                paths[second]
            ),
        )
        .rule(Rule::CoincidentKeys),
        InterpError::NonFinite { key } => {
            Error::attr(&paths[key], "coordinates", "coordinates are not finite").rule(Rule::NonFinite)
        }
        InterpError::TooFarApart { first, second } => Error::attr(
            &paths[first],
            "coordinates",
            format!(
                "{} is too far from this key to interpolate {channel} keys between them \
                 (their squared distance overflows)",
                paths[second]
            ),
        )
        .rule(Rule::Interpolation),
        other => {
            Error::prim(&paths[0], format!("cannot interpolate {channel} keys: {other}")).rule(Rule::Interpolation)
        }
    }
}

/// A pose channel over keys whose coordinates are in axis units: the
/// interpolant is built on the coordinates times `scales` (SPEC 1.1 §4).
fn pose_channel<V>(
    method: Method,
    scales: &[f64],
    keys: Vec<(String, Vec<f64>, V)>,
    channel: &str,
) -> Result<Option<Channel<PoseChannel, V>>> {
    if keys.is_empty() {
        return Ok(None);
    }
    let dim = scales.len();
    let paths: Vec<String> = keys.iter().map(|k| k.0.clone()).collect();
    let coords: Vec<f64> = keys
        .iter()
        .flat_map(|k| k.1.iter().zip(scales).map(|(c, s)| c * s))
        .collect();
    // Keys apart in axis units can meet once scaled (an axis with scale 0).
    let scaled_together = |e: InterpError| match e {
        InterpError::DuplicateKeys { first, second } if keys[first].1 != keys[second].1 => Error::attr(
            &paths[first],
            "coordinates",
            format!(
                "{} has the same coordinates once each axis is multiplied by its scale \
                 (an axis with scale 0?): two {channel} keys at one configuration",
                paths[second]
            ),
        )
        .rule(Rule::CoincidentKeys),
        e => duplicate_error(&paths, e, channel),
    };
    let interp = if dim == 0 {
        // No axes: one key is a constant; two would sit at the same point.
        if keys.len() > 1 {
            return Err(duplicate_error(
                &paths,
                InterpError::DuplicateKeys { first: 0, second: 1 },
                channel,
            ));
        }
        PoseChannel::new(method, 1, &[0.0]).map_err(|e| duplicate_error(&paths, e, channel))?
    } else {
        PoseChannel::new(method, dim, &coords).map_err(scaled_together)?
    };
    Ok(Some(Channel {
        interp,
        paths,
        values: keys.into_iter().map(|k| k.2).collect(),
    }))
}

fn time_channel<V>(keys: Vec<(String, f64, V)>, sentinels: &[f64]) -> Result<Option<Channel<TimeChannel, V>>> {
    if keys.is_empty() {
        return Ok(None);
    }
    let paths: Vec<String> = keys.iter().map(|k| k.0.clone()).collect();
    let times: Vec<f64> = keys.iter().map(|k| k.1).collect();
    let interp = TimeChannel::new(&times, sentinels).map_err(|e| match e {
        TimeKeyError::SameTime { first, second } => Error::attr(
            &paths[first],
            "time",
            format!(
                "{} has the same time: two time keys of one channel at one time",
                paths[second]
            ),
        )
        .rule(Rule::CoincidentKeys),
        TimeKeyError::CloseTimes { first, second } => Error::attr(
            &paths[first],
            "time",
            format!(
                "{} is within 1e-12 of the span of the time keys between their sentinels: \
                 the time interpolation counts the two as one time",
                paths[second]
            ),
        )
        .rule(Rule::CoincidentKeys),
        TimeKeyError::NonFinite { key } => Error::attr(&paths[key], "time", "time is not finite").rule(Rule::NonFinite),
        TimeKeyError::FarApart { first, second } => Error::attr(
            &paths[first],
            "time",
            format!(
                "{} is too far from this key in time to interpolate between them \
                 (their squared distance overflows)",
                paths[second]
            ),
        )
        .rule(Rule::Interpolation),
        TimeKeyError::TooMany { count } => Error::prim(
            &paths[0],
            format!("cannot interpolate time keys: {}", InterpError::TooManyKeys { count }),
        )
        .rule(Rule::Interpolation),
    })?;
    Ok(Some(Channel {
        interp,
        paths,
        values: keys.into_iter().map(|k| k.2).collect(),
    }))
}

/// The layer's axes as indices into the rig's axis table: `painterly:axes`
/// when authored, else every `PainterlyAxis` under the rig in namespace order.
pub fn layer_axes(r: &StageReader, all_paths: &[String], rig: &mut Rig, layer: &StrokeLayer) -> Result<Vec<usize>> {
    let path = layer.path.as_str();
    let prim = &layer.prim;
    let authored = prim
        .relationship("painterly:axes")
        .has_authored_targets()
        .map_err(|e| Error::attr(path, "painterly:axes", format!("cannot read: {e}")))?;
    let axis_paths: Vec<String> = if authored {
        r.targets(prim, "painterly:axes")?
    } else {
        let mut v = Vec::new();
        for p in all_paths {
            if is_descendant(p, &rig.path) && r.type_name(&r.require_prim(p)?)? == "PainterlyAxis" {
                v.push(p.clone());
            }
        }
        v
    };
    let mut axes = Vec::new();
    for ap in &axis_paths {
        let Some(axis) = r.prim(ap)? else {
            return Err(
                Error::attr(path, "painterly:axes", format!("targets {ap}, which does not exist")).rule(Rule::Axis),
            );
        };
        // usd-core still reads a deactivated prim's attributes, but an axis
        // switched off must not go on shaping the layer unseen. The cause is
        // the axis, whichever layer meets it first: one problem on the axis,
        // the same for every layer that targets it (as a bad `kind` is), so
        // inspect names it once.
        if let Some(why) = r.unread_reason(&axis)? {
            let users = layers_targeting(r, all_paths, ap)?;
            let (verb, them) = if users.len() == 1 {
                ("targets", "it")
            } else {
                ("target", "them")
            };
            let message = format!(
                "the axis is {why}, but {} {verb} it in `painterly:axes` ({}): it would go on shaping {them} unseen",
                crate::words::plural(users.len(), "stroke layer"),
                crate::words::at_most_five(users.iter().cloned()),
            );
            return Err(Error::prim(ap, message).rule(Rule::Axis));
        }
        // Named from the layer: the relationship is what is wrong, not the prim.
        let ty = r.type_name(&axis)?;
        if ty != "PainterlyAxis" {
            return Err(Error::attr(
                path,
                "painterly:axes",
                format!("targets {ap}, a {ty:?} prim, not a PainterlyAxis"),
            )
            .rule(Rule::Axis));
        }
        axes.push(axis_index(r, rig, ap)?);
    }
    Ok(axes)
}

/// The stroke layers (among `all_paths`) whose `painterly:axes` target
/// `axis`, in namespace order.
fn layers_targeting(r: &StageReader, all_paths: &[String], axis: &str) -> Result<Vec<String>> {
    let mut users = Vec::new();
    for p in all_paths {
        let prim = r.require_prim(p)?;
        if r.api_schemas(&prim)?.iter().any(|a| a == STROKE_LAYER_API)
            && r.targets(&prim, "painterly:axes")?.iter().any(|t| t == axis)
        {
            users.push(p.clone());
        }
    }
    Ok(users)
}

/// Reads a layer's axes, pose keys and time keys.
/// A layer's key prims as read, before they become interpolation channels:
/// (key path, coordinates or time, value) per channel.
#[derive(Default)]
struct KeyPrims {
    pose_points: Vec<(String, Vec<f64>, Vec<Vec3>)>,
    pose_opacity: Vec<(String, Vec<f64>, f32)>,
    time_points: Vec<(String, f64, Vec<Vec3>)>,
    time_opacity: Vec<(String, f64, f32)>,
    sentinels: Vec<f64>,
    has_pose_keys: bool,
}

fn read_keys(r: &StageReader, all_paths: &[String], rig: &mut Rig, layer: &StrokeLayer) -> Result<LayerKeys> {
    let path = layer.path.as_str();
    let keys = read_key_prims(r, layer)?;
    // Axes: the layer's painterly:axes, else every axis under the rig.
    let axes = if keys.has_pose_keys {
        layer_axes(r, all_paths, rig, layer)?
    } else {
        Vec::new()
    };
    let dim = axes.len();
    for (cp, coords) in keys
        .pose_points
        .iter()
        .map(|k| (&k.0, &k.1))
        .chain(keys.pose_opacity.iter().map(|k| (&k.0, &k.1)))
    {
        if coords.len() != dim {
            return Err(Error::attr(
                cp,
                "coordinates",
                format!("{} coordinates, but the layer {path} has {dim} axes", coords.len()),
            )
            .rule(Rule::KeyCoordinates));
        }
    }
    let method = layer_method(r, layer)?;
    let scales: Vec<f64> = axes.iter().map(|&a| rig.axes[a].scale).collect();
    Ok(LayerKeys {
        axes,
        method: Some(method),
        pose_points: pose_channel(method, &scales, keys.pose_points, "position")?,
        pose_opacity: pose_channel(method, &scales, keys.pose_opacity, "opacity")?,
        scales,
        time_points: time_channel(keys.time_points, &keys.sentinels)?,
        time_opacity: time_channel(keys.time_opacity, &keys.sentinels)?,
        sentinels: keys.sentinels.len(),
    })
}

/// The layer's `PainterlyPoseKey` and `PainterlyTimeKey` children, each
/// value checked against the layer (point count, finiteness).
fn read_key_prims(r: &StageReader, layer: &StrokeLayer) -> Result<KeyPrims> {
    let path = layer.path.as_str();
    let npoints = layer.rest_points.len();
    let children = r.read_children(&layer.prim)?;
    let read_points = |c: &usd::Prim, cp: &str| -> Result<Option<Vec<Vec3>>> {
        let Some(p) = r.typed(c, "points", None, "point3f[]", values::vec3_array)? else {
            return Ok(None);
        };
        if p.len() != npoints {
            return Err(Error::attr(
                cp,
                "points",
                format!("{} points, but the layer {path} has {npoints}", p.len()),
            )
            .rule(Rule::KeyPointCounts));
        }
        check_finite(&p, cp, "points")?;
        Ok(Some(p))
    };
    let read_opacity = |c: &usd::Prim, cp: &str| -> Result<Option<f32>> {
        let o = r.typed(c, "opacity", None, "float", values::scalar)?;
        let o = o.map(|o| o as f32);
        if let Some(o) = o {
            check_opacity(o, cp, "opacity", "")?;
        }
        Ok(o)
    };
    let mut keys = KeyPrims::default();
    for c in &children {
        let cp = c.path().as_str().to_string();
        match r.type_name(c)?.as_str() {
            "PainterlyPoseKey" => {
                keys.has_pose_keys = true;
                let coords = r
                    .typed(c, "coordinates", None, "float[]", values::f32_array)?
                    .ok_or_else(|| {
                        Error::attr(&cp, "coordinates", "a pose key needs `float[] coordinates`")
                            .rule(Rule::KeyCoordinates)
                    })?;
                let coords: Vec<f64> = coords.iter().map(|&x| x as f64).collect();
                if let Some(p) = read_points(c, &cp)? {
                    keys.pose_points.push((cp.clone(), coords.clone(), p));
                }
                if let Some(o) = read_opacity(c, &cp)? {
                    keys.pose_opacity.push((cp.clone(), coords, o));
                }
            }
            "PainterlyTimeKey" => {
                let time = r
                    .typed(c, "time", None, "double", values::scalar)?
                    .ok_or_else(|| Error::attr(&cp, "time", "a time key needs `double time`").rule(Rule::KeyTime))?;
                if !time.is_finite() {
                    return Err(Error::attr(&cp, "time", "time is not finite").rule(Rule::NonFinite));
                }
                let sentinel = r.typed(c, "sentinel", None, "bool", values::scalar)?.unwrap_or(0.0) != 0.0;
                if sentinel {
                    keys.sentinels.push(time);
                    continue;
                }
                if let Some(p) = read_points(c, &cp)? {
                    keys.time_points.push((cp.clone(), time, p));
                }
                if let Some(o) = read_opacity(c, &cp)? {
                    keys.time_opacity.push((cp.clone(), time, o));
                }
            }
            _ => {}
        }
    }
    Ok(keys)
}

/// The layer's `painterly:interpolation` (smooth Voronoi unless authored)
/// and, for RBF, its `painterly:rbfRadius`.
fn layer_method(r: &StageReader, layer: &StrokeLayer) -> Result<Method> {
    let (path, prim) = (layer.path.as_str(), &layer.prim);
    let token = r
        .typed(prim, "painterly:interpolation", None, "token", values::token)?
        .unwrap_or_else(|| "smoothVoronoi".into());
    let radius = r
        .typed(prim, "painterly:rbfRadius", None, "float", values::scalar)?
        .unwrap_or(1.0);
    let method = Method::from_token(&token, radius).ok_or_else(|| {
        Error::attr(
            path,
            "painterly:interpolation",
            format!("unknown interpolation {token:?} (expected smoothVoronoi, rbf or shepard)"),
        )
        .rule(Rule::Interpolation)
    })?;
    if let Method::Rbf { radius } = method {
        if !(radius.is_finite() && radius > 0.0) {
            return Err(
                Error::attr(path, "painterly:rbfRadius", format!("radius {radius} must be positive"))
                    .rule(Rule::Interpolation),
            );
        }
    }
    Ok(method)
}

fn read_cached_binding(
    r: &StageReader,
    prim: &usd::Prim,
    path: &str,
    npoints: usize,
    proxy_points: usize,
) -> Result<Option<Binding>> {
    let verts = r.typed(prim, "painterly:bindVertices", None, "int3[]", values::int3_array)?;
    let weights = r.typed(prim, "painterly:bindWeights", None, "float3[]", values::vec3_array)?;
    let (verts, weights) = match (verts, weights) {
        (None, None) => return Ok(None),
        (Some(v), Some(w)) => (v, w),
        (Some(_), None) => {
            return Err(Error::attr(
                path,
                "painterly:bindWeights",
                "painterly:bindVertices is authored without it",
            ))
        }
        (None, Some(_)) => {
            return Err(Error::attr(
                path,
                "painterly:bindVertices",
                "painterly:bindWeights is authored without it",
            ))
        }
    };
    check_binding(path, &verts, &weights, npoints, proxy_points).map(Some)
}

/// A binding of `npoints` points to a proxy of `proxy_points` points, once
/// every entry is checked: one per point, vertex indices in range, finite
/// weights. Errors name the layer prim `path` and the attribute.
pub fn check_binding(
    path: &str,
    verts: &[[i64; 3]],
    weights: &[Vec3],
    npoints: usize,
    proxy_points: usize,
) -> Result<Binding> {
    if verts.len() != npoints {
        return Err(Error::attr(
            path,
            "painterly:bindVertices",
            format!("{} entries for {npoints} points", verts.len()),
        ));
    }
    if weights.len() != npoints {
        return Err(Error::attr(
            path,
            "painterly:bindWeights",
            format!("{} entries for {npoints} points", weights.len()),
        ));
    }
    for (i, v) in verts.iter().enumerate() {
        if let Some(bad) = v.iter().find(|&&x| x < 0 || x as usize >= proxy_points) {
            return Err(Error::attr(
                path,
                "painterly:bindVertices",
                format!("point {i} binds to vertex {bad}, out of range (the proxy has {proxy_points} points)"),
            ));
        }
    }
    check_finite(weights, path, "painterly:bindWeights")?;
    // Barycentric weights of a closest point (SPEC §3): each in [0, 1], summing
    // to 1. Anything else scales or shears the stroke; the tolerance admits
    // float rounding by any writer.
    const TOLERANCE: f32 = 1e-4;
    for (i, w) in weights.iter().enumerate() {
        let sum = w.x + w.y + w.z;
        if w.min_element() < -TOLERANCE || (sum - 1.0).abs() > TOLERANCE {
            return Err(Error::attr(
                path,
                "painterly:bindWeights",
                format!(
                    "point {i} has weights ({}, {}, {}) summing to {sum}: a binding's weights are barycentric, \
                     each in [0, 1] and summing to 1 (re-bind with `painterly bind`)",
                    w.x, w.y, w.z
                ),
            ));
        }
    }
    Ok(Binding {
        vertices: verts.iter().map(|v| v.map(|x| x as u32)).collect(),
        weights: weights.iter().map(|w| [w.x, w.y, w.z]).collect(),
    })
}

/// Authored displayOpacity as one value per curve.
///
/// constant → repeated; uniform → as is; vertex → mean over each curve's
/// points, varying → over its span ends (the bake writes uniform opacity,
/// SPEC §7).
fn read_display_opacity(
    r: &StageReader,
    prim: &usd::Prim,
    path: &str,
    counts: &[i64],
    time: Option<f64>,
) -> Result<Vec<f32>> {
    const NAME: &str = "primvars:displayOpacity";
    let ncurves = counts.len();
    let Some(v) = r.typed(prim, NAME, time, "float[]", values::f32_array)? else {
        return Ok(vec![1.0; ncurves]);
    };
    let interpolation = r.primvar_interpolation(prim, NAME, "constant")?;
    if !matches!(
        interpolation.as_str(),
        "constant" | "uniform" | "varying" | "vertex" | "faceVarying"
    ) {
        return Err(Error::attr(
            path,
            NAME,
            format!("unknown interpolation {interpolation:?}"),
        ));
    }
    r.require_element_size_one(prim, NAME)?;
    let v = match r.typed(
        prim,
        "primvars:displayOpacity:indices",
        time,
        "int[]",
        values::int_array,
    )? {
        None => v,
        Some(idx) => flatten_indexed(&v, &idx, path, "primvars:displayOpacity:indices")?,
    };
    // Each authored value, before any mean over a curve hides it.
    for &o in &v {
        check_opacity(o, path, NAME, "")?;
    }
    let npoints: i64 = counts.iter().sum();
    // The mean of each curve's run of `lens` values.
    let per_curve = |lens: &mut dyn Iterator<Item = usize>| -> Vec<f32> {
        let mut start = 0usize;
        lens.map(|c| {
            let s = &v[start..start + c];
            start += c;
            if c == 0 {
                1.0
            } else {
                s.iter().sum::<f32>() / c as f32
            }
        })
        .collect()
    };
    // `varying` on a cubic curve has one value per segment end, not per
    // point: as many as usd-core's ComputeVaryingDataSize counts.
    let varying_lens = match interpolation.as_str() {
        "varying" | "faceVarying" => {
            let (ty, basis, wrap) = super::render_scene::curve_shape(r, prim, path)?;
            let lens: Vec<usize> = counts
                .iter()
                .map(|&c| crate::render::curves::usd_varying_data_size(ty, basis, wrap, c as usize))
                .collect();
            (lens.iter().sum::<usize>() == v.len()).then_some(lens)
        }
        _ => None,
    };
    let out = if let Some(lens) = varying_lens {
        per_curve(&mut lens.into_iter())
    } else if v.len() == 1 {
        vec![v[0]; ncurves]
    } else if v.len() == ncurves {
        v
    } else if v.len() as i64 == npoints {
        per_curve(&mut counts.iter().map(|&c| c as usize))
    } else {
        return Err(Error::attr(
            path,
            NAME,
            format!(
                "{} values fit neither 1, {ncurves} curves nor {npoints} points",
                v.len()
            ),
        ));
    };
    Ok(out)
}

impl StrokeLayer {
    /// The layer's local-to-world transform at `t`.
    pub fn local_to_world(&self, r: &StageReader, t: f64) -> Result<DMat4> {
        r.local_to_world(&self.prim, t)
    }

    /// `painterly:opacity` at `t` (it may be animated; fallback 1).
    /// `primvars:displayOpacity` per curve at `t` when it or its indices
    /// are time-sampled (an authored fade); `None` when the default value
    /// ([`StrokeLayer::display_opacity`]) holds at every time.
    pub fn display_opacity_at(&self, r: &StageReader, t: f64) -> Result<Option<Vec<f32>>> {
        if !self.display_varies {
            return Ok(None);
        }
        let counts: Vec<i64> = self.curve_counts.iter().map(|&c| i64::from(c)).collect();
        read_display_opacity(r, &self.prim, &self.path, &counts, Some(t))
            .map(Some)
            .map_err(|e| {
                Error {
                    message: format!("at time {t}: {}", e.message),
                    ..e
                }
                .or_rule(Rule::DisplayOpacity)
            })
    }

    /// Whether `painterly:opacity` has time samples (read per frame; its
    /// default, [`StrokeLayer::opacity`], is then not what any frame uses).
    pub fn opacity_is_sampled(&self) -> bool {
        self.opacity_sampled
    }

    pub fn opacity_at(&self, r: &StageReader, t: f64) -> Result<f32> {
        if let Some(o) = self.fixed_opacity.as_ref().and_then(|f| f.get()) {
            return Ok(*o);
        }
        let o = r
            .typed(&self.prim, "painterly:opacity", Some(t), "float", values::scalar)?
            .unwrap_or(1.0) as f32;
        check_opacity(o, &self.path, "painterly:opacity", &format!(" at time {t}"))?;
        if let Some(f) = &self.fixed_opacity {
            let _ = f.set(o);
        }
        Ok(o)
    }

    /// The largest `widths` value at `t` (0 when none), what the baked
    /// extent is padded by ([`crate::extent::curves_extent`]). Widths are
    /// not baked: they come from the input at every time, possibly
    /// time-sampled (read once, interpolated here as usd-core does).
    pub fn max_width_at(&self, t: f64) -> f32 {
        self.widths.max_at(t)
    }

    /// Number of points.
    pub fn num_points(&self) -> usize {
        self.rest_points.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::usd_io::testutil::stage_from_usda as stage;

    #[test]
    fn sampled_widths_interpolate_like_usd_core() {
        let w = Widths::Sampled(vec![
            (2.0, Some(vec![0.1, 0.2])),
            (4.0, Some(vec![0.3, 0.6])),
            (6.0, None),
            (8.0, Some(vec![1.0])),
            (10.0, Some(vec![2.0, 3.0])),
        ]);
        assert_eq!(w.max_at(0.0), 0.2); // held before the first sample
        assert_eq!(w.max_at(2.0), 0.2);
        assert_eq!(w.max_at(3.0), ((0.5 * 0.2f32 as f64) + 0.5 * 0.6f32 as f64) as f32);
        assert_eq!(w.max_at(4.0), 0.6);
        assert_eq!(w.max_at(5.0), 0.6); // the upper sample is a block: held
        assert_eq!(w.max_at(7.0), 0.0); // the lower sample is a block
        assert_eq!(w.max_at(9.0), 1.0); // sizes differ: held
        assert_eq!(w.max_at(11.0), 3.0); // held after the last sample
        assert_eq!(Widths::Constant(0.5).max_at(3.0), 0.5);
    }

    /// Two triangles over the unit square: 4 points, 6 face-vertex indices.
    const SQUARE: &str = "int[] faceVertexCounts = [3, 3]
        int[] faceVertexIndices = [0, 1, 2, 0, 2, 3]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]";

    /// One stroke of three points.
    const STROKE: &str = "int[] curveVertexCounts = [3]
            point3f[] points = [(0.2, 0.2, 0), (0.5, 0.5, 0), (0.8, 0.2, 0)]";

    /// A stage with the Mesh /World/Proxy (`mesh`: its body), the rig
    /// /World/Rig on it and the stroke layer /World/Rig/Strokes (`layer`:
    /// its body, children included).
    fn rig(mesh: &str, layer: &str) -> String {
        format!(
            r#"#usda 1.0
(
    startTimeCode = 1
    endTimeCode = 3
)
def Xform "World"
{{
    def Mesh "Proxy"
    {{
        {mesh}
    }}
    def Xform "Rig" (prepend apiSchemas = ["PainterlyRigAPI"])
    {{
        rel painterly:proxy = </World/Proxy>
        def BasisCurves "Strokes" (prepend apiSchemas = ["PainterlyStrokeLayerAPI"])
        {{
            {layer}
        }}
    }}
}}
"#
        )
    }

    #[test]
    fn a_character_inside_an_instance_is_named_once_per_instance() {
        let mut usda = rig(SQUARE, STROKE);
        usda.push_str(
            r#"
def Xform "Crowd1" (instanceable = true; references = </World>) {}
def Xform "Crowd2" (instanceable = true; references = </World>) {}
def Xform "Prop" (instanceable = true; references = </World/Proxy>) {}
def Xform "Plain" (references = </World/Proxy>) {}
"#,
        );
        let r = stage(&usda);
        let (scene, problems) = Scene::read_lenient(&r).unwrap();
        assert_eq!(
            scene.rigs.iter().map(|g| g.path.as_str()).collect::<Vec<_>>(),
            ["/World/Rig"]
        );
        let got: Vec<_> = problems
            .iter()
            .map(|e| (e.prim.as_deref().unwrap(), e.rule, e.message.as_str()))
            .collect();
        let message = |p: &str| {
            format!(
                "an instance (instanceable = true) holds painterly prims ({p}/Rig), which a bake cannot override: \
                 USD ignores opinions below an instance; set `instanceable = false` on {p} to bake it"
            )
        };
        let (m1, m2) = (message("/Crowd1"), message("/Crowd2"));
        assert_eq!(
            got,
            [
                ("/Crowd1", Some(Rule::Instanced), m1.as_str()),
                ("/Crowd2", Some(Rule::Instanced), m2.as_str())
            ]
        );
        assert!(Scene::read(&r).is_err());
    }

    #[test]
    fn an_instance_of_a_lone_stroke_layer_or_view_mesh_is_named() {
        // No rig inside: what an instance holds is found by its own API.
        let r = stage(&format!(
            r#"#usda 1.0
def Xform "Assets"
{{
    def Xform "Layers"
    {{
        def BasisCurves "Loose" (prepend apiSchemas = ["PainterlyStrokeLayerAPI"])
        {{
            {STROKE}
        }}
    }}
    def Xform "Faces"
    {{
        def Mesh "Face" (prepend apiSchemas = ["PainterlyViewDependentAPI"])
        {{
            {SQUARE}
        }}
    }}
}}
def Xform "A" (instanceable = true; references = </Assets/Layers/Loose>) {{}}
def Xform "B" (instanceable = true; references = </Assets/Layers>) {{}}
def Xform "V" (instanceable = true; references = </Assets/Faces>) {{}}
def Xform "Holder"
{{
    def Xform "C" (instanceable = true) {{
        def Xform "Inner" (references = </Assets/Faces/Face>) {{}}
    }}
}}
"#
        ));
        let found = instanced_characters(&r, &r.prim_paths().unwrap()).unwrap();
        let got: Vec<_> = found.iter().map(|e| (e.prim.as_deref().unwrap(), e.rule)).collect();
        // /A is itself the layer (a reference to it): the walk below it finds
        // nothing, and the layer-outside-rig rule names it instead. /Holder/C
        // has no arc, so it is no instance.
        assert_eq!(got, [("/B", Some(Rule::Instanced)), ("/V", Some(Rule::Instanced))]);
        assert!(found[0].message.contains("(/B/Loose)"), "{}", found[0].message);
        assert!(found[1].message.contains("(/V/Face)"), "{}", found[1].message);
    }

    /// The SQUARE proxy skinned to one joint that turns 90° about +Z from
    /// time 0 to 1, with `extra` in the Mesh (`influences`: whether it has
    /// joint influences at all).
    fn skinned_rig(extra: &str, influences: bool) -> String {
        let influences = if influences {
            r#"int[] primvars:skel:jointIndices = [0, 0, 0, 0] (interpolation = "vertex"; elementSize = 1)
        float[] primvars:skel:jointWeights = [1, 1, 1, 1] (interpolation = "vertex"; elementSize = 1)"#
        } else {
            ""
        };
        format!(
            r#"#usda 1.0
(
    startTimeCode = 0
    endTimeCode = 1
)
def SkelRoot "Char"
{{
    def Skeleton "Skel" (prepend apiSchemas = ["SkelBindingAPI"])
    {{
        uniform token[] joints = ["Root"]
        uniform matrix4d[] bindTransforms = [((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1))]
        uniform matrix4d[] restTransforms = [((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1))]
        rel skel:animationSource = </Char/Skel/Anim>
        def SkelAnimation "Anim"
        {{
            uniform token[] joints = ["Root"]
            float3[] translations = [(0, 0, 0)]
            quatf[] rotations.timeSamples = {{
                0: [(1, 0, 0, 0)],
                1: [(0.70710677, 0, 0, 0.70710677)],
            }}
            half3[] scales = [(1, 1, 1)]
        }}
    }}
    def Mesh "Proxy" (prepend apiSchemas = ["SkelBindingAPI"])
    {{
        {SQUARE}
        {influences}
        {extra}
        rel skel:skeleton = </Char/Skel>
    }}
    def Xform "Rig" (prepend apiSchemas = ["PainterlyRigAPI"])
    {{
        rel painterly:proxy = </Char/Proxy>
        def BasisCurves "Strokes" (prepend apiSchemas = ["PainterlyStrokeLayerAPI"])
        {{
            {STROKE}
        }}
    }}
}}
"#
        )
    }

    /// The prim, attribute and rule an error names.
    fn named(e: &Error) -> (&str, &str, Option<Rule>) {
        (
            e.prim.as_deref().unwrap_or(""),
            e.attribute.as_deref().unwrap_or(""),
            e.rule,
        )
    }

    fn near(a: &[Vec3], b: &[[f32; 3]]) -> bool {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(p, q)| (*p - Vec3::from(*q)).abs().max_element() < 1e-6)
    }

    #[test]
    fn sampled_widths_hold_and_interpolate_where_usd_core_does() {
        // Expected values are usd-core's `Get` of `widths` authored with
        // these samples (UsdAttribute::Get interpolates linearly).
        // Samples 5e-7 apart: usd-core holds the lower one (closer than 1e-6).
        let close = Widths::Sampled(vec![(1.0, Some(vec![1.0])), (1.0 + 5e-7, Some(vec![3.0]))]);
        assert_eq!(close.max_at(1.0 + 2.5e-7), 1.0);
        // Exactly 1e-6 apart usd-core interpolates ([1] at 0, [3] at 1e-6
        // give [2] at 5e-7); 9.9e-7 apart it holds.
        let edge = Widths::Sampled(vec![(0.0, Some(vec![1.0])), (1e-6, Some(vec![3.0]))]);
        assert_eq!(edge.max_at(5e-7), 2.0);
        let below = Widths::Sampled(vec![(0.0, Some(vec![1.0])), (9.9e-7, Some(vec![3.0]))]);
        assert_eq!(below.max_at(4.95e-7), 1.0);
        // α = (t − t0) / (t1 − t0), with t0 ≠ 2 and t1 ≠ 4 (t1 / t0 would do there).
        let w = Widths::Sampled(vec![(1.0, Some(vec![1.0])), (5.0, Some(vec![3.0]))]);
        assert_eq!(w.max_at(2.0), 1.5);
        // Samples on both sides of time 0 (t0 + t1 = 0).
        let w = Widths::Sampled(vec![(-1.0, Some(vec![1.0, 0.5])), (1.0, Some(vec![3.0, 0.5]))]);
        assert_eq!(w.max_at(0.5), 2.5);
    }

    #[test]
    fn is_descendant_needs_a_separator_after_the_ancestor() {
        assert!(is_descendant("/World/Rig/Strokes", "/World/Rig"));
        assert!(is_descendant("/World", "/"));
        // A sibling whose name starts with the ancestor's.
        assert!(!is_descendant("/World/RigB", "/World/Rig"));
        // A prim is not its own descendant, nor its parent's ancestor.
        assert!(!is_descendant("/World/Rig", "/World/Rig"));
        assert!(!is_descendant("/World", "/World/Rig"));
        // A separator where the ancestor would end, under another prim.
        assert!(!is_descendant("/Other/Rig", "/World"));
    }

    #[test]
    fn configuration_multiplies_each_layer_axis_value_by_its_scale() {
        let keys = LayerKeys {
            axes: vec![2, 0],
            scales: vec![0.5, 4.0],
            ..Default::default()
        };
        assert_eq!(keys.configuration(&[3.0, 7.0, 10.0]), [5.0, 12.0]);
        assert_eq!(LayerKeys::default().configuration(&[3.0]), [0.0]);
    }

    #[test]
    fn a_cached_binding_is_checked_entry_by_entry() {
        let w = [Vec3::new(0.2, 0.3, 0.5), Vec3::new(1.0, 0.0, 0.0)];
        let b = check_binding("/L", &[[0, 1, 2], [3, 2, 0]], &w, 2, 4).unwrap();
        assert_eq!(b.vertices, [[0, 1, 2], [3, 2, 0]]);
        assert_eq!(b.weights, [[0.2, 0.3, 0.5], [1.0, 0.0, 0.0]]);
        let bad = |verts: &[[i64; 3]], weights: &[Vec3]| {
            let e = check_binding("/L", verts, weights, 2, 4).unwrap_err();
            e.attribute.unwrap()
        };
        // A 4-point proxy has vertices 0..=3.
        assert_eq!(bad(&[[0, 1, 2], [3, 4, 0]], &w), "painterly:bindVertices");
        assert_eq!(bad(&[[0, 1, 2], [-1, 2, 0]], &w), "painterly:bindVertices");
        // One entry per point, finite weights.
        assert_eq!(bad(&[[0, 1, 2]], &w), "painterly:bindVertices");
        assert_eq!(bad(&[[0, 1, 2], [3, 2, 0]], &w[..1]), "painterly:bindWeights");
        let nan = [w[0], Vec3::new(f32::NAN, 0.0, 1.0)];
        assert_eq!(bad(&[[0, 1, 2], [3, 2, 0]], &nan), "painterly:bindWeights");
    }

    #[test]
    fn proxy_motion_is_named_as_inspect_documents_it() {
        // docs/schemas/inspect.schema.json: a rig's "animation" is one of these.
        let r = stage(&rig(SQUARE, STROKE));
        let scene = Scene::read(&r).unwrap();
        assert_eq!(scene.rigs[0].proxy.motion.describe(), "static points");
        assert!(!scene.rigs[0].proxy.is_skinned());

        let sampled = format!(
            "{SQUARE}
        point3f[] points.timeSamples = {{
            1: [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
            3: [(2, 0, 0), (3, 0, 0), (3, 1, 0), (2, 1, 0)],
        }}"
        );
        let r = stage(&rig(&sampled, STROKE));
        let scene = Scene::read(&r).unwrap();
        let proxy = &scene.rigs[0].proxy;
        assert_eq!(proxy.motion.describe(), "time-sampled points");
        assert!(!proxy.is_skinned());
        // Halfway between the samples: moved by (1, 0, 0).
        let half = [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [2.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        assert!(near(&proxy.posed_points_f32(&r, 2.0).unwrap(), &half));

        let r = stage(&skinned_rig("", true));
        let scene = Scene::read(&r).unwrap();
        assert_eq!(scene.rigs[0].proxy.motion.describe(), "UsdSkel");
        assert!(scene.rigs[0].proxy.is_skinned());
    }

    #[test]
    fn skinned_normals_are_deformed_where_bake_skinning_deforms_them() {
        // usd-core's UsdSkel.BakeSkinning of these stages writes normals
        // for the first two only; its values at time 1 are those below
        // (the joint's quarter turn about +Z takes x to y and y to −x).
        let vertex = r#"normal3f[] normals = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 0)] (interpolation = "vertex")"#;
        let face_varying = r#"normal3f[] normals = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 0), (0, 0, 1), (0, 1, 0)] (interpolation = "faceVarying")"#;
        let turned = |n: &[[f32; 3]]| -> Vec<[f32; 3]> { n.iter().map(|&[x, y, z]| [-y, x, z]).collect() };
        let vertex_rest = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]];
        let fv_rest = [
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 1.0, 0.0],
        ];
        for (extra, rest) in [(vertex, &vertex_rest[..]), (face_varying, &fv_rest[..])] {
            let r = stage(&skinned_rig(extra, true));
            let proxy = &Scene::read(&r).unwrap().rigs[0].proxy;
            assert!(proxy.has_deformed_normals(), "{extra}");
            assert!(
                near(&proxy.posed_normals(&r, 1.0).unwrap().unwrap(), &turned(rest)),
                "{extra}"
            );
            let points: Vec<Vec3> = proxy
                .posed_points(&r, 1.0)
                .unwrap()
                .iter()
                .map(|p| p.as_vec3())
                .collect();
            let square = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
            assert!(near(&points, &turned(&square)), "{extra}");
        }
        // Sized for the other interpolation (4 points, 6 face vertices), or
        // on a mesh nothing deforms: left alone.
        let vertex_sized_6 = face_varying.replace("faceVarying", "vertex");
        let face_varying_sized_4 = vertex.replace("vertex", "faceVarying");
        for (extra, influences) in [
            (vertex_sized_6.as_str(), true),
            (face_varying_sized_4.as_str(), true),
            (vertex, false),
        ] {
            let r = stage(&skinned_rig(extra, influences));
            let proxy = &Scene::read(&r).unwrap().rigs[0].proxy;
            assert!(!proxy.has_deformed_normals(), "{extra}");
            assert_eq!(proxy.posed_normals(&r, 1.0).unwrap(), None, "{extra}");
        }
    }

    #[test]
    fn proxy_topology_is_refused_where_usd_core_finds_it_invalid() {
        // UsdGeom.Mesh.ValidateTopology: counts must sum to the indices,
        // indices lie in [0, points); a face of no vertices is valid.
        let first = |mesh: &str| Scene::read(&stage(&rig(mesh, STROKE))).err();
        let mesh = |counts: &str, indices: &str| {
            format!(
                "int[] faceVertexCounts = {counts}
        int[] faceVertexIndices = {indices}
        point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]"
            )
        };
        let e = first(&mesh("[3, 4]", "[0, 1, 2, 0, 2, 3]")).unwrap();
        assert_eq!(named(&e), ("/World/Proxy", "faceVertexCounts", Some(Rule::Mesh)));
        for bad in ["[0, 1, 2, 0, 2, 4]", "[0, 1, 2, 0, 2, -1]"] {
            let e = first(&mesh("[3, 3]", bad)).unwrap();
            assert_eq!(
                named(&e),
                ("/World/Proxy", "faceVertexIndices", Some(Rule::Mesh)),
                "{bad}"
            );
        }
        assert!(first(&mesh("[3, 0, 3]", "[0, 1, 2, 0, 2, 3]")).is_none());
        // A negative count is named as such, even where the counts still
        // sum to the indices (7 - 1 = 6).
        let e = first(&mesh("[7, -1]", "[0, 1, 2, 0, 2, 3]")).unwrap();
        assert_eq!(named(&e), ("/World/Proxy", "faceVertexCounts", Some(Rule::Mesh)));
        assert!(e.to_string().contains("negative count -1"), "{e}");
        // No points at all: the points are what is missing.
        let empty = "int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = []";
        let e = first(empty).unwrap();
        assert_eq!(named(&e), ("/World/Proxy", "points", Some(Rule::Mesh)));
    }

    #[test]
    fn stroke_counts_are_refused_when_negative_or_over_the_limit() {
        let read = |layer: &str| Scene::read(&stage(&rig(SQUARE, layer)));
        let e = read(
            "int[] curveVertexCounts = [-1, 4]
            point3f[] points = [(0.2, 0.2, 0), (0.5, 0.5, 0), (0.8, 0.2, 0)]",
        )
        .err()
        .unwrap();
        assert_eq!(
            named(&e),
            ("/World/Rig/Strokes", "curveVertexCounts", Some(Rule::PointCounts))
        );
        // A curve of no points is an empty stroke.
        let scene = read(
            "int[] curveVertexCounts = [2, 0, 1]
            point3f[] points = [(0.2, 0.2, 0), (0.5, 0.5, 0), (0.8, 0.2, 0)]",
        )
        .unwrap();
        let layer = &scene.rigs[0].layers[0];
        assert_eq!(layer.curve_counts, [2, 0, 1]);
        assert_eq!(layer.num_points(), 3);
        // README, Limits: at most 20,000,000 stroke points, refused from the
        // counts before any point is read. At the limit the counts pass (and
        // the missing points are the problem).
        let e = read("int[] curveVertexCounts = [20000000]").err().unwrap();
        assert_eq!(
            named(&e),
            ("/World/Rig/Strokes", "points", Some(Rule::MissingRestPoints))
        );
        let e = read("int[] curveVertexCounts = [20000001]").err().unwrap();
        assert_eq!(
            named(&e),
            ("/World/Rig/Strokes", "curveVertexCounts", Some(Rule::PointCounts))
        );
        assert_eq!(
            e.message,
            "20000001 stroke points; painterly bakes at most 20000000 in one run (bake its stroke layers in several runs, deactivating the others in a layer over the input)"
        );
    }

    #[test]
    fn the_stroke_point_limit_sums_every_layers_counts_before_reading_points() {
        // Two layers of 10,000,001 and `second` points, neither over the
        // limit alone, no points authored: only the counts are read.
        let read = |second: u32| {
            let text = rig(SQUARE, "int[] curveVertexCounts = [10000001]").replacen(
                "def BasisCurves",
                &format!(
                    "def BasisCurves \"A\" (prepend apiSchemas = [\"PainterlyStrokeLayerAPI\"])
        {{
            int[] curveVertexCounts = [{second}]
        }}
        def BasisCurves"
                ),
                1,
            );
            Scene::read(&stage(&text)).err().unwrap()
        };
        // 20,000,002 > 20,000,000: named at the layer whose counts cross it.
        let e = read(10_000_001);
        assert_eq!(
            named(&e),
            ("/World/Rig/Strokes", "curveVertexCounts", Some(Rule::PointCounts))
        );
        assert!(e.message.starts_with("20000002 stroke points; "), "{e}");
        // Exactly at the limit the counts pass; the missing points fail.
        let e = read(9_999_999);
        assert_eq!(named(&e).1, "points");
    }

    #[test]
    fn non_finite_points_are_refused_naming_their_attribute() {
        let proxy = SQUARE.replace("(1, 1, 0)", "(1, inf, 0)");
        let e = Scene::read(&stage(&rig(&proxy, STROKE))).err().unwrap();
        assert_eq!(named(&e), ("/World/Proxy", "points", Some(Rule::NonFinite)));
        let layer = STROKE.replace("(0.5, 0.5, 0)", "(0.5, -inf, 0)");
        let e = Scene::read(&stage(&rig(SQUARE, &layer))).err().unwrap();
        assert_eq!(named(&e), ("/World/Rig/Strokes", "points", Some(Rule::NonFinite)));
        let rest =
            format!("{STROKE}\n            point3f[] painterly:restPoints = [(0, 0, 0), (inf, 0, 0), (1, 0, 0)]");
        let e = Scene::read(&stage(&rig(SQUARE, &rest))).err().unwrap();
        assert_eq!(
            named(&e),
            ("/World/Rig/Strokes", "painterly:restPoints", Some(Rule::NonFinite))
        );
    }

    #[test]
    fn animated_layer_opacity_is_read_at_each_time() {
        let r = stage(&rig(
            SQUARE,
            &format!("{STROKE}\n            float painterly:opacity.timeSamples = {{ 1: 0.2, 3: 0.6 }}"),
        ));
        let scene = Scene::read(&r).unwrap();
        let layer = &scene.rigs[0].layers[0];
        for (t, want) in [(1.0, 0.2), (2.0, 0.4), (3.0, 0.6)] {
            assert!((layer.opacity_at(&r, t).unwrap() - want).abs() < 1e-6, "t = {t}");
        }
    }

    #[test]
    fn vertex_display_opacity_is_the_mean_over_each_curve() {
        // docs/choices.md: vertex/varying displayOpacity is averaged over
        // each curve's points.
        let r = stage(&rig(
            SQUARE,
            r#"int[] curveVertexCounts = [2, 3]
            point3f[] points = [(0.2, 0.2, 0), (0.5, 0.5, 0), (0.8, 0.2, 0), (0.6, 0.2, 0), (0.4, 0.2, 0)]
            float[] primvars:displayOpacity = [0.5, 1, 0, 0.25, 0.5] (interpolation = "vertex")"#,
        ));
        let scene = Scene::read(&r).unwrap();
        assert_eq!(scene.rigs[0].layers[0].display_opacity, [0.75, 0.25]);
    }

    #[test]
    fn a_layer_outside_every_rig_is_a_problem_and_one_under_a_broken_rig_is_not() {
        let r = stage(&format!(
            r#"#usda 1.0
def Xform "World"
{{
    def BasisCurves "Loose" (prepend apiSchemas = ["PainterlyStrokeLayerAPI"])
    {{
        {STROKE}
    }}
    def Xform "Broken" (prepend apiSchemas = ["PainterlyRigAPI"])
    {{
        def BasisCurves "Strokes" (prepend apiSchemas = ["PainterlyStrokeLayerAPI"])
        {{
            {STROKE}
        }}
    }}
}}
"#
        ));
        let (scene, problems) = Scene::read_lenient(&r).unwrap();
        assert!(scene.rigs.is_empty());
        // The broken rig's layer is the rig's problem (no proxy), not another.
        let mut got: Vec<_> = problems.iter().map(|e| (e.prim.clone().unwrap(), e.rule)).collect();
        got.sort_by(|a, b| a.0.cmp(&b.0));
        assert_eq!(
            got,
            [
                ("/World/Broken".to_string(), Some(Rule::MissingProxy)),
                ("/World/Loose".to_string(), Some(Rule::LayerOutsideRig)),
            ]
        );
    }

    /// A pose key of the layer in [`rig`], with `body`.
    fn pose_key(name: &str, body: &str) -> String {
        format!("\n            def PainterlyPoseKey \"{name}\"\n            {{\n                {body}\n            }}")
    }

    const KEY_POINTS: &str = "point3f[] points = [(0.2, 0.3, 0), (0.5, 0.6, 0), (0.8, 0.3, 0)]";

    #[test]
    fn pose_keys_of_a_layer_without_axes() {
        let keys = |bodies: &[&str]| {
            let children: String = bodies
                .iter()
                .enumerate()
                .map(|(i, b)| {
                    pose_key(
                        &format!("k{i}"),
                        &format!("float[] coordinates = []\n                {b}"),
                    )
                })
                .collect();
            Scene::read(&stage(&rig(SQUARE, &format!("{STROKE}{children}"))))
                .map(|mut s| s.rigs[0].layers.remove(0).keys)
        };
        // One position key: a constant at the origin of a 1-D space.
        let one = keys(&[KEY_POINTS]).unwrap();
        assert!(one.axes.is_empty());
        assert_eq!(one.pose_points.as_ref().map(|c| c.values.len()), Some(1));
        assert!(one.uses_axes());
        // SPEC §4: two keys of a channel at one configuration are an error
        // naming both; without axes every key sits at the origin.
        for n in [2, 3] {
            let e = keys(&vec![KEY_POINTS; n]).err().unwrap();
            assert_eq!(
                named(&e),
                ("/World/Rig/Strokes/k0", "coordinates", Some(Rule::CoincidentKeys)),
                "{n} keys"
            );
            assert!(e.message.contains("/World/Rig/Strokes/k1"), "{e}");
        }
        // Only opacity keys still need the axes; keys carrying neither
        // points nor opacity do not.
        let fade = keys(&["float opacity = 0.5"]).unwrap();
        assert!(fade.pose_points.is_none() && fade.uses_axes());
        let bare = keys(&[""]).unwrap();
        assert!(bare.pose_points.is_none() && bare.pose_opacity.is_none());
        assert!(!bare.uses_axes());
    }

    /// A rig with one attribute axis of `scale` and a layer with two
    /// position keys at `a` and `b` (axis units).
    fn two_keys_on_a_scaled_axis(scale: f64, a: f64, b: f64) -> Error {
        let layer = format!(
            "{STROKE}{}{}",
            pose_key(
                "a",
                &format!("float[] coordinates = [{a}]\n                {KEY_POINTS}")
            ),
            pose_key(
                "b",
                &format!("float[] coordinates = [{b}]\n                {KEY_POINTS}")
            ),
        );
        let axis = format!(
            r#"def PainterlyAxis "knob"
        {{
            uniform token kind = "attribute"
            rel source = </Knob.value>
            float scale = {scale}
        }}
        def BasisCurves"#
        );
        let text = rig(SQUARE, &layer).replacen("def BasisCurves", &axis, 1)
            + "def Scope \"Knob\"\n{\n    double value = 0\n}\n";
        Scene::read(&stage(&text)).err().unwrap()
    }

    #[test]
    fn keys_that_meet_only_once_scaled_are_told_apart_from_equal_keys() {
        let equal = two_keys_on_a_scaled_axis(1.0, 0.5, 0.5);
        assert_eq!(
            named(&equal),
            ("/World/Rig/Strokes/a", "coordinates", Some(Rule::CoincidentKeys))
        );
        assert!(
            equal.message.contains("/World/Rig/Strokes/b") && !equal.message.contains("scale"),
            "{equal}"
        );
        // Apart in axis units, together once multiplied by scale 0: the
        // message says why.
        let scaled = two_keys_on_a_scaled_axis(0.0, 0.0, 1.0);
        assert_eq!(
            named(&scaled),
            ("/World/Rig/Strokes/a", "coordinates", Some(Rule::CoincidentKeys))
        );
        assert!(
            scaled.message.contains("/World/Rig/Strokes/b") && scaled.message.contains("scale"),
            "{scaled}"
        );
    }

    #[test]
    fn rbf_interpolation_needs_a_positive_radius() {
        let read = |radius: &str| {
            let layer = format!(
                "{STROKE}
            uniform token painterly:interpolation = \"rbf\"
            uniform float painterly:rbfRadius = {radius}"
            );
            Scene::read(&stage(&rig(SQUARE, &layer))).err()
        };
        for bad in ["0", "-1"] {
            let e = read(bad).unwrap();
            assert_eq!(
                named(&e),
                ("/World/Rig/Strokes", "painterly:rbfRadius", Some(Rule::Interpolation)),
                "{bad}"
            );
        }
        assert!(read("0.5").is_none());
    }

    #[test]
    fn a_non_finite_time_sample_is_an_authored_point_not_a_posed_one() {
        // A point cache read as a view-dependent mesh is: its bad value is
        // authored, so the error does not call it posed.
        let r = stage(
            "#usda 1.0
def Mesh \"Cache\"
{
    int[] faceVertexCounts = [3, 3]
    int[] faceVertexIndices = [0, 1, 2, 0, 2, 3]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    point3f[] points.timeSamples = {
        1: [(0, 0, 0), (inf, 0, 0), (1, 1, 0), (0, 1, 0)],
        2: [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
    }
}
",
        );
        let mesh = read_mesh(&r, r.require_prim("/Cache").unwrap(), None).unwrap();
        let e = mesh.posed_points_f32(&r, 1.0).unwrap_err();
        assert_eq!(named(&e), ("/Cache", "points", None));
        assert!(e.message.starts_with("point 1 ") && e.message.contains("time 1"), "{e}");
    }
}
