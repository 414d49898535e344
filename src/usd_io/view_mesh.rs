//! View-dependent meshes (SPEC §6, Rademacher 1999): a Mesh with
//! `PainterlyViewDependentAPI` and `PainterlyViewKey` children, read into
//! plain data: the base model, key viewpoints with their offsets from the
//! base, and the precomputed viewpoint hull.

use glam::Vec3;
use openusd::usd;

use super::scene::{read_mesh, read_rest_time, Proxy, VIEW_DEPENDENT_API};
use super::stage::StageReader;
use super::values;
use crate::error::{Error, Result};
use crate::rule::Rule;
use crate::view::{same_direction, NaturalCubicSpline, Uncovered, ViewBlender, ViewError};

/// One key viewpoint: a direction and its deformation offsets from the base,
/// either constant (keys without `time`) or at key times (animated base).
pub struct Viewpoint {
    /// Unit direction, mesh-local, from the base's bbox centre to the key camera.
    pub direction: [f64; 3],
    /// The key prims of this viewpoint, in time order.
    pub paths: Vec<String>,
    /// Offsets (key points − base) per key, in time order.
    pub offsets: Vec<Vec<Vec3>>,
    /// Spline over key times; None for a single untimed key.
    pub spline: Option<NaturalCubicSpline>,
}

/// The pure-math part of a view-dependent mesh: viewpoints and their hull.
pub struct ViewBlend {
    pub viewpoints: Vec<Viewpoint>,
    pub blender: ViewBlender,
}

/// A view-dependent mesh ready to bake.
pub struct ViewMesh {
    pub path: String,
    /// The base model (topology, rest pose, motion).
    pub mesh: Proxy,
    pub blend: ViewBlend,
    /// `painterly:camera`, if authored.
    pub camera: Option<String>,
    pub uncovered: Uncovered,
    pub sharpness: f64,
}

/// Raw key as authored.
struct KeyIn {
    path: String,
    points: Vec<Vec3>,
    direction: [f64; 3],
    time: Option<f64>,
    viewpoint: Option<String>,
}

fn view_error(keys: &[KeyIn], vp_paths: &[Vec<String>], mesh: &str, e: ViewError) -> Error {
    let first_of = |i: usize| {
        vp_paths
            .get(i)
            .and_then(|p| p.first())
            .cloned()
            .unwrap_or_else(|| mesh.to_string())
    };
    match e {
        ViewError::DuplicateDirection { first, second } => Error::attr(
            first_of(first),
            "direction",
            format!(
                "{} has the same direction: two key viewpoints cannot share a direction",
                first_of(second)
            ),
        )
        .rule(Rule::ViewKeyDirections),
        ViewError::ZeroDirection { index } | ViewError::NonFiniteDirection { index } => Error::attr(
            first_of(index),
            "direction",
            "direction must be a finite, non-zero vector",
        )
        .rule(Rule::ViewKeyDirections),
        ViewError::InvalidSharpness(s) => {
            Error::attr(mesh, "painterly:sharpness", format!("sharpness {s} must be positive")).rule(Rule::ViewMesh)
        }
        other => {
            let _ = keys;
            Error::prim(mesh, format!("cannot build the key viewpoint hull: {other}")).rule(Rule::ViewKeyDirections)
        }
    }
}

/// Finds and reads every view-dependent mesh in the stage; fails on the first problem.
pub fn read_view_meshes(r: &StageReader, paths: &[String]) -> Result<Vec<ViewMesh>> {
    let (meshes, mut problems) = read_view_meshes_lenient(r, paths)?;
    if problems.is_empty() {
        Ok(meshes)
    } else {
        Err(problems.swap_remove(0))
    }
}

/// Like [`read_view_meshes`], but skips broken meshes and returns every
/// problem (for `painterly inspect`).
pub fn read_view_meshes_lenient(r: &StageReader, paths: &[String]) -> Result<(Vec<ViewMesh>, Vec<Error>)> {
    let mut out = Vec::new();
    let mut problems = Vec::new();
    for p in paths {
        let prim = r.require_prim(p)?;
        if r.api_schemas(&prim)?.iter().any(|a| a == VIEW_DEPENDENT_API) {
            match read_view_mesh(r, prim) {
                Ok(m) => out.push(m),
                Err(e) => problems.push(e.or_rule(Rule::Unreadable)),
            }
        }
    }
    Ok((out, problems))
}

fn read_view_mesh(r: &StageReader, prim: usd::Prim) -> Result<ViewMesh> {
    let path = prim.path().as_str().to_string();
    let ty = r.type_name(&prim)?;
    if ty != "Mesh" {
        return Err(Error::prim(
            &path,
            format!("{VIEW_DEPENDENT_API} is applied to a {ty:?} prim, expected a Mesh"),
        )
        .rule(Rule::ViewMesh));
    }
    let sharpness = r
        .typed(&prim, "painterly:sharpness", None, "float", values::scalar)?
        .unwrap_or(1.0);
    if !(sharpness.is_finite() && sharpness > 0.0) {
        return Err(Error::attr(
            &path,
            "painterly:sharpness",
            format!("sharpness {sharpness} must be positive"),
        )
        .rule(Rule::ViewMesh));
    }
    let token = r
        .typed(&prim, "painterly:uncovered", None, "token", values::token)?
        .unwrap_or_else(|| "cosine".into());
    let uncovered = Uncovered::from_token(&token).ok_or_else(|| {
        Error::attr(
            &path,
            "painterly:uncovered",
            format!("unknown token {token:?} (expected cosine or base)"),
        )
        .rule(Rule::ViewMesh)
    })?;
    let camera = r
        .one_target(&prim, "painterly:camera")
        .map_err(|e| e.or_rule(Rule::ViewMesh))?;
    let rest_time = read_rest_time(r, &prim)?;
    let cache_time = point_cache_time(r, &prim, rest_time)?;
    // A point cache has no rest pose; its first sample only gives the
    // topology's point count (and keys must all have a time, below).
    let mesh = read_mesh(r, prim.clone(), rest_time.or(cache_time))?;
    let n = mesh.rest.len();

    let keys = read_view_keys(r, &prim, &path, n)?;
    let viewpoints = group_viewpoints(&keys)?
        .iter()
        .map(|g| viewpoint(r, &mesh, &keys, g, cache_time, &path))
        .collect::<Result<Vec<_>>>()?;
    let dirs: Vec<[f64; 3]> = viewpoints.iter().map(|v| v.direction).collect();
    let vp_paths: Vec<Vec<String>> = viewpoints.iter().map(|v| v.paths.clone()).collect();
    let blender = ViewBlender::new(&dirs, sharpness, uncovered).map_err(|e| view_error(&keys, &vp_paths, &path, e))?;
    Ok(ViewMesh {
        path,
        mesh,
        blend: ViewBlend { viewpoints, blender },
        camera,
        uncovered,
        sharpness,
    })
}

/// The `PainterlyViewKey` children of the mesh at `path` (`n` points), each
/// checked alone (SPEC §6).
fn read_view_keys(r: &StageReader, prim: &usd::Prim, path: &str, n: usize) -> Result<Vec<KeyIn>> {
    let mut keys = Vec::new();
    for c in r.read_children(prim)? {
        if r.type_name(&c)? != "PainterlyViewKey" {
            continue;
        }
        let cp = c.path().as_str().to_string();
        let points = r
            .typed(&c, "points", None, "point3f[]", values::vec3_array)?
            .ok_or_else(|| {
                Error::attr(&cp, "points", "a view key needs `point3f[] points`").rule(Rule::ViewKeyCounts)
            })?;
        if points.len() != n {
            return Err(Error::attr(
                &cp,
                "points",
                format!("{} points, but the mesh {path} has {n}", points.len()),
            )
            .rule(Rule::ViewKeyCounts));
        }
        if let Some(i) = points.iter().position(|p| !p.is_finite()) {
            return Err(Error::attr(&cp, "points", format!("point {i} is not finite")).rule(Rule::NonFinite));
        }
        let d = r.typed(&c, "direction", None, "float3", values::vec3)?.ok_or_else(|| {
            Error::attr(&cp, "direction", "a view key needs `float3 direction`").rule(Rule::ViewKeyDirections)
        })?;
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if !(len.is_finite() && len > 0.0) {
            return Err(
                Error::attr(&cp, "direction", "direction must be a finite, non-zero vector")
                    .rule(Rule::ViewKeyDirections),
            );
        }
        let time = r.typed(&c, "time", None, "double", values::scalar)?;
        if let Some(t) = time {
            if !t.is_finite() {
                return Err(Error::attr(&cp, "time", "time is not finite").rule(Rule::NonFinite));
            }
        }
        let viewpoint = r.typed(&c, "viewpoint", None, "token", values::token)?;
        keys.push(KeyIn {
            path: cp,
            points,
            direction: [d[0] / len, d[1] / len, d[2] / len],
            time,
            viewpoint,
        });
    }

    Ok(keys)
}

/// Keys grouped into viewpoints (indices into `keys`): the same `viewpoint`
/// token, or else the same direction. Keys sharing a token must share the
/// direction too.
fn group_viewpoints(keys: &[KeyIn]) -> Result<Vec<Vec<usize>>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, k) in keys.iter().enumerate() {
        let found = groups.iter().position(|g| {
            let f = &keys[g[0]];
            match (&k.viewpoint, &f.viewpoint) {
                (Some(a), Some(b)) => a == b,
                _ => same_direction(k.direction, f.direction),
            }
        });
        match found {
            Some(g) => {
                let f = &keys[groups[g][0]];
                if !same_direction(k.direction, f.direction) {
                    return Err(Error::attr(
                        &k.path,
                        "direction",
                        format!(
                            "shares viewpoint {:?} with {} but not its direction",
                            k.viewpoint.as_deref().unwrap_or(""),
                            f.path
                        ),
                    )
                    .rule(Rule::ViewKeyDirections));
                }
                groups[g].push(i);
            }
            None => groups.push(vec![i]),
        }
    }
    Ok(groups)
}

/// One viewpoint from its keys (`group`, indices into `keys`): all timed
/// or one untimed key, no two at one time; each key's offset from the rest
/// pose, or from the posed mesh at its time, and the spline through the times.
fn viewpoint(
    r: &StageReader,
    mesh: &Proxy,
    keys: &[KeyIn],
    group: &[usize],
    cache_time: Option<f64>,
    path: &str,
) -> Result<Viewpoint> {
    let mut g = group.to_vec();
    let timed = g.iter().filter(|&&i| keys[i].time.is_some()).count();
    if timed != 0 && timed != g.len() {
        let a = g.iter().find(|&&i| keys[i].time.is_some()).expect("a timed key");
        let b = g.iter().find(|&&i| keys[i].time.is_none()).expect("an untimed key");
        return Err(Error::attr(
            &keys[*b].path,
            "time",
            format!(
                "is one key viewpoint with {}, which has a time: give every key of a viewpoint a time, or none",
                keys[*a].path
            ),
        )
        .rule(Rule::ViewKeyTimes));
    }
    if timed == 0 && g.len() > 1 {
        return Err(Error::attr(
            &keys[g[1]].path,
            "direction",
            format!(
                "{} has the same direction and neither has a time: one viewpoint needs one key, or keys at different times",
                keys[g[0]].path
            ),
        )
        .rule(Rule::ViewKeyTimes));
    }
    g.sort_by(|&a, &b| keys[a].time.unwrap_or(0.0).total_cmp(&keys[b].time.unwrap_or(0.0)));
    for w in g.windows(2) {
        if keys[w[0]].time == keys[w[1]].time {
            return Err(Error::attr(
                &keys[w[0]].path,
                "time",
                format!("{} has the same direction and time", keys[w[1]].path),
            )
            .rule(Rule::ViewKeyTimes));
        }
    }
    let mut offsets = Vec::with_capacity(g.len());
    for &i in &g {
        let base: Vec<Vec3> = match keys[i].time {
            None if cache_time.is_some() => {
                return Err(Error::attr(
                    &keys[i].path,
                    "time",
                    format!(
                        "a key without `time` is an offset from the rest pose, but {path} has only \
                         time-sampled points (a point cache) and no rest pose: give this key a `time` \
                         (its offset is then taken from the base at that time), or author a default \
                         `points` or `painterly:restTime` on {path}"
                    ),
                ))
            }
            None => mesh.rest.iter().map(|p| p.as_vec3()).collect(),
            Some(t) => mesh.posed_points(r, t)?.iter().map(|p| p.as_vec3()).collect(),
        };
        offsets.push(keys[i].points.iter().zip(&base).map(|(k, b)| *k - *b).collect());
    }
    let spline = if timed > 0 {
        let times: Vec<f64> = g.iter().map(|&i| keys[i].time.expect("timed")).collect();
        Some(
            NaturalCubicSpline::new(&times)
                .map_err(|e| Error::prim(&keys[g[0]].path, format!("{e}")).rule(Rule::ViewKeyTimes))?,
        )
    } else {
        None
    };
    Ok(Viewpoint {
        direction: keys[g[0]].direction,
        paths: g.iter().map(|&i| keys[i].path.clone()).collect(),
        offsets,
        spline,
    })
}

/// For a point cache (a mesh that is not skinned, whose `points` are only
/// time samples, without `painterly:restTime`): its first sample time.
/// Such a mesh has no rest pose, and SPEC §6 needs none when every key has
/// a time (offsets from the base at each key's time).
fn point_cache_time(r: &StageReader, prim: &usd::Prim, rest_time: Option<f64>) -> Result<Option<f64>> {
    if rest_time.is_some() || r.value(prim, "points", None)?.is_some() {
        return Ok(None);
    }
    if super::skel::skeleton_binding(r, prim)?.is_some() {
        return Ok(None);
    }
    // A point cache read from its crate file lists its times without decoding them.
    match r.crate_samples(prim, "points") {
        Some(s) => Ok(s.stage_times().first().copied()),
        None => Ok(r.sample_times(prim, "points")?.first().copied()),
    }
}

/// Checks that the `painterly:camera` of the view-dependent mesh `mesh`
/// targets an existing prim with a transform (only its position is used, so
/// any Xformable serves, as for a `position` axis). Errors name the mesh and
/// the relationship, where the fault is authored.
pub fn check_camera(r: &StageReader, path: &str, mesh: &str) -> Result<()> {
    let fault = |why: String| Error::attr(mesh, "painterly:camera", why).rule(Rule::ViewMesh);
    let p = r
        .prim(path)?
        .ok_or_else(|| fault(format!("targets {path}, which does not exist")))?;
    let ty = r.type_name(&p)?;
    if NOT_XFORMABLE.contains(&ty.as_str()) {
        return Err(fault(format!(
            "targets {path}, {}, which has no transform (expected a Camera or another Xformable)",
            crate::words::prim_of_type(&ty)
        )));
    }
    Ok(())
}

impl ViewMesh {
    /// The camera for this mesh: the bake's `--camera`, else `painterly:camera`.
    pub fn camera_for<'a>(&'a self, bake_camera: Option<&'a str>) -> Result<&'a str> {
        bake_camera.or(self.camera.as_deref()).ok_or_else(|| {
            Error::attr(
                &self.path,
                "painterly:camera",
                "no camera: pass `--camera PRIM` or author `rel painterly:camera`",
            )
        })
    }
}

impl ViewBlend {
    /// The view-dependent points at `t` for a camera at `camera_local`
    /// (mesh-local), given the base model's points at `t` and the sharpness
    /// α at `t` (`painterly:sharpness` may be animated).
    pub fn evaluate(&self, t: f64, base: &[Vec3], camera_local: glam::DVec3, sharpness: f64) -> Result<Vec<Vec3>> {
        let [lo, hi] = crate::mesh::bounds(base).unwrap_or([Vec3::ZERO; 2]);
        let centre = ((lo + hi) * 0.5).as_dvec3();
        let eye = camera_local - centre;
        let rebuilt;
        let blender = if sharpness == self.blender.sharpness() {
            &self.blender
        } else {
            let dirs: Vec<[f64; 3]> = self.viewpoints.iter().map(|v| v.direction).collect();
            rebuilt = ViewBlender::new(&dirs, sharpness, self.blender.mode())
                .map_err(|e| Error::msg(format!("sharpness {sharpness} at time {t}: {e}")))?;
            &rebuilt
        };
        // A camera at the centre, up to rounding, has no direction: it sees the base.
        let at_centre = crate::view::eye_at_centre(eye, (hi - lo).length() as f64, centre);
        let weights = if !at_centre && eye.is_finite() {
            blender.weights(eye.normalize().to_array())
        } else {
            crate::view::ViewWeights::base_only()
        };
        // Fold each viewpoint's spline coefficients at t into its view
        // weight, so the output is one pass over at most 3 × (key times)
        // offset arrays: out = s·base + Σ_k w_k Σ_j c_kj(t) offset_kj.
        let mut terms: Vec<(f64, &[Vec3])> = vec![(weights.base_scale(), base)];
        for &(k, w) in weights.keys() {
            let vp = &self.viewpoints[k];
            match &vp.spline {
                None => terms.push((w, &vp.offsets[0])),
                Some(s) => terms.extend(
                    s.weights(t)
                        .into_iter()
                        .zip(&vp.offsets)
                        .map(|(c, off)| (w * c, off.as_slice())),
                ),
            }
        }
        let mut out = vec![Vec3::ZERO; base.len()];
        crate::mesh::weighted_sum(&mut out, &terms);
        Ok(out)
    }
}

/// `painterly:sharpness` of the mesh at `path` at `t`, checked positive.
pub fn sharpness_at(r: &StageReader, path: &str, t: f64) -> Result<f64> {
    let prim = r.require_prim(path)?;
    let s = r
        .typed(&prim, "painterly:sharpness", Some(t), "float", values::scalar)?
        .unwrap_or(1.0);
    if !(s.is_finite() && s > 0.0) {
        return Err(Error::attr(
            path,
            "painterly:sharpness",
            format!("sharpness {s} at time {t} must be positive"),
        ));
    }
    Ok(s)
}

/// Prim types that have no transform: a camera must not be one of these.
const NOT_XFORMABLE: &[&str] = &[
    "",
    "Scope",
    "Material",
    "Shader",
    "NodeGraph",
    "GeomSubset",
    "SkelAnimation",
    "BlendShape",
    "PainterlyAxis",
    "PainterlyPoseKey",
    "PainterlyTimeKey",
    "PainterlyViewKey",
];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::usd_io::testutil::stage_from_usda as stage;

    const MESH: &str = "/World/Ball";

    /// A tetrahedron Mesh /World/Ball with PainterlyViewDependentAPI:
    /// `attrs` are more of its properties, `keys` its children.
    fn view_stage(attrs: &str, keys: &str) -> String {
        format!(
            r#"#usda 1.0
(
    startTimeCode = 1
    endTimeCode = 6
)
def Xform "World"
{{
    def Mesh "Ball" (prepend apiSchemas = ["PainterlyViewDependentAPI"])
    {{
        int[] faceVertexCounts = [3, 3, 3, 3]
        int[] faceVertexIndices = [0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
        {attrs}
        {keys}
    }}
}}
"#
        )
    }

    /// A key with 4 points (the mesh's count) or 3 (one too few).
    fn key(name: &str, direction: &str, four_points: bool) -> String {
        let points = if four_points {
            "(0, 0, 0.5), (1, 0, 0), (0, 1, 0), (0, 0, 1)"
        } else {
            "(0, 0, 0.5), (1, 0, 0), (0, 1, 0)"
        };
        format!(
            r#"def PainterlyViewKey "{name}"
        {{
            uniform float3 direction = {direction}
            uniform point3f[] points = [{points}]
        }}
        "#
        )
    }

    fn read_err(usda: &str) -> Error {
        let r = stage(usda);
        match read_view_meshes(&r, &r.prim_paths().unwrap()) {
            Ok(m) => panic!("read {} view meshes, expected an error", m.len()),
            Err(e) => e,
        }
    }

    #[test]
    fn sharpness_is_read_at_each_time_and_refused_where_it_is_not_positive() {
        // Default 2 (what the bake's hull is built with); samples 2, 4, 0
        // at 1, 3, 5, linearly interpolated (USD) and held after the last.
        let attrs = "float painterly:sharpness = 2
        float painterly:sharpness.timeSamples = { 1: 2, 3: 4, 5: 0 }";
        let r = stage(&view_stage(attrs, &key("Front", "(0, 0, 1)", true)));
        let meshes = read_view_meshes(&r, &r.prim_paths().unwrap()).unwrap();
        assert_eq!(meshes.len(), 1);
        let vm = &meshes[0];
        assert_eq!(vm.path, MESH);
        assert_eq!(vm.sharpness, 2.0);
        assert_eq!(sharpness_at(&r, MESH, 2.0).unwrap(), 3.0);
        assert_eq!(sharpness_at(&r, MESH, 3.0).unwrap(), 4.0);
        assert_eq!(sharpness_at(&r, MESH, 4.0).unwrap(), 2.0);
        for t in [5.0, 6.0] {
            let e = sharpness_at(&r, MESH, t).unwrap_err();
            assert_eq!(e.prim.as_deref(), Some(MESH), "t={t}: {e}");
            assert_eq!(e.attribute.as_deref(), Some("painterly:sharpness"), "t={t}: {e}");
        }
    }

    #[test]
    fn a_zero_sharpness_is_named_before_a_broken_key() {
        // The mesh's own attribute is checked before its keys are read.
        let usda = view_stage("float painterly:sharpness = 0", &key("Short", "(0, 0, 1)", false));
        let e = read_err(&usda);
        assert_eq!(e.prim.as_deref(), Some(MESH), "{e}");
        assert_eq!(e.attribute.as_deref(), Some("painterly:sharpness"), "{e}");
        assert_eq!(e.rule, Some(Rule::ViewMesh), "{e}");
    }

    #[test]
    fn a_zero_or_infinite_direction_is_named_before_a_later_broken_key() {
        for bad in ["(0, 0, 0)", "(inf, 0, 0)", "(0, -inf, 1)"] {
            let keys = key("Bad", bad, true) + &key("Short", "(0, 0, 1)", false);
            let e = read_err(&view_stage("", &keys));
            assert_eq!(e.prim.as_deref(), Some("/World/Ball/Bad"), "{bad}: {e}");
            assert_eq!(e.attribute.as_deref(), Some("direction"), "{bad}: {e}");
            assert_eq!(e.rule, Some(Rule::ViewKeyDirections), "{bad}: {e}");
        }
        // Each alone is named too (the broken key after a good one).
        let keys = key("Good", "(0, 0, 1)", true) + &key("Short", "(1, 0, 0)", false);
        let e = read_err(&view_stage("", &keys));
        assert_eq!(e.prim.as_deref(), Some("/World/Ball/Short"), "{e}");
        assert_eq!(e.attribute.as_deref(), Some("points"), "{e}");
    }
}
