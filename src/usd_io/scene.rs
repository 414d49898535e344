//! Reads a painted character from a composed stage into plain data.
//!
//! A rig is a prim with `PainterlyRigAPI`; its `painterly:proxy` names the
//! proxy Mesh; its stroke layers are the `BasisCurves` with
//! `PainterlyStrokeLayerAPI` beneath it (SPEC §1–3). API schemas are read from
//! `apiSchemas` metadata and fallbacks are applied here, so painterly never
//! depends on the schema plugin being registered.

use glam::{DMat4, DVec3, Vec3};
use openusd::usd;

use super::skel::{skeleton_binding, SkelProxy};
use super::stage::StageReader;
use super::values;
use crate::bind::Binding;
use crate::error::{Error, Result};

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
    prim: usd::Prim,
}

/// One stroke layer (a BasisCurves prim).
pub struct StrokeLayer {
    pub path: String,
    /// Points per stroke (`curveVertexCounts`).
    pub curve_counts: Vec<u32>,
    /// Rest positions, proxy-local.
    pub rest_points: Vec<Vec3>,
    /// `painterly:bindVertices`/`bindWeights` when authored.
    pub cached_binding: Option<Binding>,
    /// `painterly:opacity` (fallback 1).
    pub opacity: f32,
    /// Authored `primvars:displayOpacity` per curve (1 when absent).
    pub display_opacity: Vec<f32>,
    prim: usd::Prim,
}

/// A rig: its proxy and stroke layers.
pub struct Rig {
    pub path: String,
    pub proxy: Proxy,
    pub layers: Vec<StrokeLayer>,
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
        let mut rigs = Vec::new();
        for rp in &rig_paths {
            let prim = r.require_prim(rp)?;
            match read_proxy(r, &prim) {
                Ok(proxy) => rigs.push(Rig {
                    path: rp.clone(),
                    proxy,
                    layers: Vec::new(),
                }),
                Err(e) => problems.push(e),
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
                    problems.push(Error::prim(
                        lp,
                        format!("stroke layer ({STROKE_LAYER_API}) is not under a prim with {RIG_API}"),
                    ));
                }
                continue;
            };
            match read_layer(r, lp, owner.proxy.rest.len()) {
                Ok(layer) => owner.layers.push(layer),
                Err(e) => problems.push(e),
            }
        }
        Ok((Scene { rigs }, problems))
    }
}

fn is_descendant(path: &str, ancestor: &str) -> bool {
    path.len() > ancestor.len()
        && path.starts_with(ancestor)
        && (ancestor == "/" || path.as_bytes()[ancestor.len()] == b'/')
}

fn check_finite(points: &[Vec3], prim: &str, attr: &str) -> Result<()> {
    match points.iter().position(|p| !p.is_finite()) {
        None => Ok(()),
        Some(i) => Err(Error::attr(
            prim,
            attr,
            format!("point {i} is not finite ({})", points[i]),
        )),
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
            ))
        }
        [p] => p.clone(),
        many => {
            return Err(Error::attr(
                rig_path,
                "painterly:proxy",
                format!("has {} targets, expected exactly one Mesh", many.len()),
            ))
        }
    };
    let prim = r.prim(&proxy_path)?.ok_or_else(|| {
        Error::attr(
            rig_path,
            "painterly:proxy",
            format!("targets {proxy_path}, which does not exist"),
        )
    })?;
    let ty = r.type_name(&prim)?;
    if ty != "Mesh" {
        return Err(Error::attr(
            rig_path,
            "painterly:proxy",
            format!("targets {proxy_path}, a {:?} prim, expected a Mesh", ty),
        ));
    }
    let counts = r
        .typed(&prim, "faceVertexCounts", None, "int[]", values::int_array)?
        .ok_or_else(|| Error::attr(&proxy_path, "faceVertexCounts", "proxy mesh has no faces"))?;
    let indices = r
        .typed(&prim, "faceVertexIndices", None, "int[]", values::int_array)?
        .ok_or_else(|| Error::attr(&proxy_path, "faceVertexIndices", "proxy mesh has no faces"))?;
    if counts.iter().any(|&c| c < 0) || counts.iter().sum::<i64>() != indices.len() as i64 {
        return Err(Error::attr(
            &proxy_path,
            "faceVertexCounts",
            format!(
                "counts sum to {}, but there are {} faceVertexIndices",
                counts.iter().sum::<i64>(),
                indices.len()
            ),
        ));
    }
    if !counts.iter().any(|&c| c >= 3) {
        return Err(Error::attr(
            &proxy_path,
            "faceVertexCounts",
            "proxy mesh has no polygon with 3 or more vertices",
        ));
    }

    // Rest pose and motion kind (SPEC §2).
    let skeleton = skeleton_binding(r, &prim)?;
    let has_samples = !r.sample_times(&prim, "points")?.is_empty();
    let rest_time = r.typed(rig, "painterly:restTime", None, "double", values::scalar)?;
    let rest_pts = if skeleton.is_some() {
        r.typed(&prim, "points", None, "point3f[]", values::vec3_array)?
    } else if let Some(t) = rest_time {
        r.typed(&prim, "points", Some(t), "point3f[]", values::vec3_array)?
    } else {
        r.typed(&prim, "points", None, "point3f[]", values::vec3_array)?
    };
    let rest_pts = match rest_pts {
        Some(p) if !p.is_empty() => p,
        _ => {
            let why = if skeleton.is_some() {
                "skinned proxy has no default `points` (its bind pose)"
            } else if has_samples {
                "proxy has only time-sampled points: author a default value or `double painterly:restTime` on the rig"
            } else {
                "proxy mesh has no points"
            };
            return Err(Error::attr(&proxy_path, "points", why));
        }
    };
    check_finite(&rest_pts, &proxy_path, "points")?;
    let n = rest_pts.len();
    if let Some(bad) = indices.iter().find(|&&i| i < 0 || i as usize >= n) {
        return Err(Error::attr(
            &proxy_path,
            "faceVertexIndices",
            format!("index {bad} is out of range ({n} points)"),
        ));
    }
    let rest: Vec<DVec3> = rest_pts.iter().map(|p| p.as_dvec3()).collect();
    let motion = match skeleton {
        Some(s) => ProxyMotion::Skel(Box::new(SkelProxy::read(r, &prim, &s, &rest)?)),
        None if has_samples => ProxyMotion::Sampled,
        None => ProxyMotion::Static,
    };
    Ok(Proxy {
        path: proxy_path,
        face_counts: counts.iter().map(|&c| c as u32).collect(),
        face_indices: indices.iter().map(|&i| i as u32).collect(),
        rest,
        motion,
        prim,
    })
}

impl Proxy {
    /// Posed points in the proxy's local space at time `t`.
    pub fn posed_points(&self, r: &StageReader, t: f64) -> Result<Vec<DVec3>> {
        let pts = match &self.motion {
            ProxyMotion::Static => return Ok(self.rest.clone()),
            ProxyMotion::Sampled => {
                let p = r
                    .typed(&self.prim, "points", Some(t), "point3f[]", values::vec3_array)?
                    .unwrap_or_default();
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
                p.iter().map(|p| p.as_dvec3()).collect::<Vec<_>>()
            }
            ProxyMotion::Skel(s) => {
                let (skinning, weights) = s.pose(t)?;
                let skel_pts = s.deformer.deform(&skinning, &weights);
                let skel_prim = r.require_prim(&s.skeleton)?;
                let to_local = self.local_to_world(r, t)?.inverse() * r.local_to_world(&skel_prim, t)?;
                skel_pts.iter().map(|p| to_local.transform_point3(*p)).collect()
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

    /// The proxy's local-to-world transform at `t`.
    pub fn local_to_world(&self, r: &StageReader, t: f64) -> Result<DMat4> {
        r.local_to_world(&self.prim, t)
    }

    /// Whether the proxy is skinned (a bake that writes it must block `skel:skeleton`).
    pub fn is_skinned(&self) -> bool {
        matches!(self.motion, ProxyMotion::Skel(_))
    }
}

fn read_layer(r: &StageReader, path: &str, proxy_points: usize) -> Result<StrokeLayer> {
    let prim = r.require_prim(path)?;
    let ty = r.type_name(&prim)?;
    if ty != "BasisCurves" {
        return Err(Error::prim(
            path,
            format!("{STROKE_LAYER_API} is applied to a {ty:?} prim; stroke layers must be BasisCurves"),
        ));
    }
    let counts = r
        .typed(&prim, "curveVertexCounts", None, "int[]", values::int_array)?
        .unwrap_or_default();
    if let Some(bad) = counts.iter().find(|&&c| c < 0) {
        return Err(Error::attr(path, "curveVertexCounts", format!("negative count {bad}")));
    }
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
            ));
        }
    }
    let rest_points = match (rest, points) {
        (Some(rest), points) => {
            check_finite(&rest, path, "painterly:restPoints")?;
            if let Some(p) = points {
                if p.len() != rest.len() {
                    return Err(Error::attr(
                        path,
                        "painterly:restPoints",
                        format!("{} rest points, but the layer has {} points", rest.len(), p.len()),
                    ));
                }
            }
            if rest.len() as i64 != total {
                return Err(Error::attr(
                    path,
                    "painterly:restPoints",
                    format!("{} rest points, but curveVertexCounts sum to {total}", rest.len()),
                ));
            }
            rest
        }
        (None, Some(p)) => p,
        (None, None) => {
            return Err(Error::attr(
                path,
                "points",
                "stroke layer has neither painterly:restPoints nor a default value of points",
            ))
        }
    };

    let cached_binding = read_cached_binding(r, &prim, path, rest_points.len(), proxy_points)?;
    let opacity = r
        .typed(&prim, "painterly:opacity", None, "float", values::scalar)?
        .unwrap_or(1.0) as f32;
    if !opacity.is_finite() {
        return Err(Error::attr(path, "painterly:opacity", "opacity is not finite"));
    }
    let display_opacity = read_display_opacity(r, &prim, path, &counts)?;
    Ok(StrokeLayer {
        path: path.to_string(),
        curve_counts: counts.iter().map(|&c| c as u32).collect(),
        rest_points,
        cached_binding,
        opacity,
        display_opacity,
        prim,
    })
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
    check_finite(&weights, path, "painterly:bindWeights")?;
    Ok(Some(Binding {
        vertices: verts.iter().map(|v| v.map(|x| x as u32)).collect(),
        weights: weights.iter().map(|w| [w.x, w.y, w.z]).collect(),
    }))
}

/// Authored displayOpacity as one value per curve.
///
/// constant → repeated; uniform → as is; vertex/varying → mean over each
/// curve's points (the bake writes uniform opacity, SPEC §7).
fn read_display_opacity(r: &StageReader, prim: &usd::Prim, path: &str, counts: &[i64]) -> Result<Vec<f32>> {
    const NAME: &str = "primvars:displayOpacity";
    let ncurves = counts.len();
    let Some(v) = r.typed(prim, NAME, None, "float[]", values::f32_array)? else {
        return Ok(vec![1.0; ncurves]);
    };
    let v = match r.typed(
        prim,
        "primvars:displayOpacity:indices",
        None,
        "int[]",
        values::int_array,
    )? {
        None => v,
        Some(idx) => idx
            .iter()
            .map(|&i| usize::try_from(i).ok().and_then(|i| v.get(i).copied()))
            .collect::<Option<Vec<_>>>()
            .ok_or_else(|| Error::attr(path, "primvars:displayOpacity:indices", "index out of range"))?,
    };
    let npoints: i64 = counts.iter().sum();
    let out = if v.len() == 1 {
        vec![v[0]; ncurves]
    } else if v.len() == ncurves {
        v
    } else if v.len() as i64 == npoints {
        let mut start = 0usize;
        counts
            .iter()
            .map(|&c| {
                let c = c as usize;
                let s = &v[start..start + c];
                start += c;
                if c == 0 {
                    1.0
                } else {
                    s.iter().sum::<f32>() / c as f32
                }
            })
            .collect()
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
    if out.iter().any(|x| !x.is_finite()) {
        return Err(Error::attr(path, NAME, "opacity is not finite"));
    }
    Ok(out)
}

impl StrokeLayer {
    /// The layer's local-to-world transform at `t`.
    pub fn local_to_world(&self, r: &StageReader, t: f64) -> Result<DMat4> {
        r.local_to_world(&self.prim, t)
    }

    /// `painterly:opacity` at `t` (it may be animated; fallback 1).
    pub fn opacity_at(&self, r: &StageReader, t: f64) -> Result<f32> {
        let o = r
            .typed(&self.prim, "painterly:opacity", Some(t), "float", values::scalar)?
            .unwrap_or(1.0) as f32;
        if !o.is_finite() {
            return Err(Error::attr(
                &self.path,
                "painterly:opacity",
                format!("opacity is not finite at time {t}"),
            ));
        }
        Ok(o)
    }

    /// Number of points.
    pub fn num_points(&self) -> usize {
        self.rest_points.len()
    }
}
