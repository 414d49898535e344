//! Reading what `painterly render` draws: the camera, every BasisCurves and
//! every renderable Mesh of a composed stage, per frame, as plain world-space
//! data ([`CurvesData`], [`MeshData`], [`CameraParams`]).
//!
//! Selection follows UsdGeomImageable: prims whose computed `purpose` is
//! `guide` or `proxy` are skipped (painterly's fixtures mark proxy meshes as
//! guides), and so are prims whose computed `visibility` is `invisible` at
//! the frame. Native instances are not expanded.
//!
//! Fallbacks: `widths` 1 (scene unit, object space, like Hydra's), colour
//! (0.5, 0.5, 0.5), opacity 1. `primvars:widths` wins over `widths` when
//! authored. A primvar holding exactly one value is read as constant whatever
//! its interpolation. Widths are scaled by the cube root of the prim's
//! local-to-world determinant (exact for uniform scale).

use std::path::Path;

use glam::{DMat4, DVec3, Vec3};
use openusd::sdf::Value;
use openusd::usd;

use super::scene::{read_face_topology, read_mesh, Proxy};
use super::skel::skeleton_binding;
use super::stage::{HeldQuery, StageReader};
use super::values;
use crate::error::{Error, Result};
use crate::render::camera::{CameraParams, Projection};
use crate::render::curves::{Basis, CurveType, CurvesData, Primvar, Wrap};
use crate::render::prepare::MeshData;

/// Grey, Hydra's fallback display colour.
pub const DEFAULT_COLOR: Vec3 = Vec3::new(0.5, 0.5, 0.5);
/// Fallback curve width (object-space units).
pub const DEFAULT_WIDTH: f32 = 1.0;

/// A primvar's attribute, its interpolation and optional indices.
struct PrimvarSource {
    name: String,
    query: HeldQuery,
    interpolation: String,
    /// `:indices`, read at each time with the values (they may be sampled).
    indices: Option<HeldQuery>,
}

impl PrimvarSource {
    /// None when the attribute has no authored value.
    fn open(r: &StageReader, prim: &usd::Prim, name: &str, default_interp: &str) -> Result<Option<Self>> {
        // (A constant primvar may be a scalar a spline animates: refused here.)
        if !r.has_authored(prim, name)? {
            return Ok(None);
        }
        let interpolation = r.primvar_interpolation(prim, name, default_interp)?;
        r.require_element_size_one(prim, name)?;
        let idx_name = format!("{name}:indices");
        let indices = if r.has_authored(prim, &idx_name)? {
            Some(HeldQuery::new(prim, &idx_name)?)
        } else {
            None
        };
        Ok(Some(PrimvarSource {
            name: name.to_string(),
            query: HeldQuery::new(prim, name)?,
            interpolation,
            indices,
        }))
    }

    fn value(&self, prim: &usd::Prim, t: f64) -> Result<Option<Value>> {
        self.query
            .get_at(t)
            .map_err(|e| Error::attr(prim.path(), &self.name, format!("cannot read: {e}")))
    }

    fn expand<T: Copy>(&self, prim: &usd::Prim, vals: Vec<T>, t: f64) -> Result<Vec<T>> {
        let idx_name = || format!("{}:indices", self.name);
        let indices = match &self.indices {
            None => None,
            Some(q) => match q.get_at(t) {
                Ok(v) => v
                    .map(|v| {
                        values::int_array(&v).ok_or_else(|| {
                            Error::attr(
                                prim.path(),
                                &idx_name(),
                                format!("expected int[], found {}", values::kind_name(&v)),
                            )
                        })
                    })
                    .transpose()?,
                Err(e) => return Err(Error::attr(prim.path(), &idx_name(), format!("cannot read: {e}"))),
            },
        };
        match indices {
            None => Ok(vals),
            Some(idx) => idx
                .iter()
                .map(|&i| usize::try_from(i).ok().and_then(|i| vals.get(i).copied()))
                .collect::<Option<Vec<T>>>()
                .ok_or_else(|| {
                    Error::attr(
                        prim.path(),
                        &format!("{}:indices", self.name),
                        format!("an index is out of range ({} values)", vals.len()),
                    )
                }),
        }
    }

    fn wrap<T: Copy>(&self, prim: &usd::Prim, vals: Vec<T>, t: f64) -> Result<Option<Primvar<T>>> {
        let vals = self.expand(prim, vals, t)?;
        if vals.is_empty() {
            return Ok(None);
        }
        if vals.len() == 1 {
            return Ok(Some(Primvar::Constant(vals[0])));
        }
        Ok(Some(match self.interpolation.as_str() {
            "constant" => Primvar::Constant(vals[0]),
            "uniform" => Primvar::Uniform(vals),
            "vertex" => Primvar::Vertex(vals),
            "varying" => Primvar::Varying(vals),
            "faceVarying" => Primvar::FaceVarying(vals),
            other => {
                return Err(Error::attr(
                    prim.path(),
                    &self.name,
                    format!("unknown interpolation {other:?}"),
                ))
            }
        }))
    }

    fn colors(&self, prim: &usd::Prim, t: f64) -> Result<Option<Primvar<Vec3>>> {
        match self.value(prim, t)? {
            None => Ok(None),
            Some(v) => {
                let vals = values::vec3_array(&v)
                    .or_else(|| values::vec3(&v).map(|c| vec![Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32)]))
                    .ok_or_else(|| {
                        Error::attr(
                            prim.path(),
                            &self.name,
                            format!("expected color3f[], found {}", values::kind_name(&v)),
                        )
                    })?;
                self.wrap(prim, vals, t)
            }
        }
    }

    fn floats(&self, prim: &usd::Prim, t: f64) -> Result<Option<Primvar<f32>>> {
        match self.value(prim, t)? {
            None => Ok(None),
            Some(v) => {
                let vals = values::f32_array(&v)
                    .or_else(|| values::scalar(&v).map(|x| vec![x as f32]))
                    .ok_or_else(|| {
                        Error::attr(
                            prim.path(),
                            &self.name,
                            format!("expected float[], found {}", values::kind_name(&v)),
                        )
                    })?;
                self.wrap(prim, vals, t)
            }
        }
    }
}

/// The prim itself and its ancestors that author `visibility`.
fn visibility_chain(r: &StageReader, prim: &usd::Prim) -> Result<Vec<usd::Prim>> {
    let mut out = Vec::new();
    let mut p = Some(prim.clone());
    while let Some(q) = p {
        if q.path().as_str() == "/" {
            break;
        }
        if r.has_authored(&q, "visibility")? {
            out.push(q.clone());
        }
        p = q.parent();
    }
    Ok(out)
}

fn visible(r: &StageReader, chain: &[usd::Prim], t: f64) -> Result<bool> {
    for p in chain {
        if r.typed(p, "visibility", Some(t), "token", values::token)?.as_deref() == Some("invisible") {
            return Ok(false);
        }
    }
    Ok(true)
}

/// Computed purpose: the nearest authored `purpose` on the prim or an ancestor.
fn computed_purpose(r: &StageReader, prim: &usd::Prim) -> Result<String> {
    let mut p = Some(prim.clone());
    while let Some(q) = p {
        if q.path().as_str() == "/" {
            break;
        }
        if r.has_authored(&q, "purpose")? {
            return Ok(r
                .typed(&q, "purpose", None, "token", values::token)?
                .unwrap_or_else(|| "default".into()));
        }
        p = q.parent();
    }
    Ok("default".into())
}

fn width_scale(m: &DMat4) -> f32 {
    (glam::DMat3::from_mat4(*m).determinant().abs().cbrt()) as f32
}

struct CurvesSource {
    prim: usd::Prim,
    path: String,
    visibility: Vec<usd::Prim>,
    curve_type: CurveType,
    basis: Basis,
    wrap: Wrap,
    counts: HeldQuery,
    points: HeldQuery,
    widths: Option<PrimvarSource>,
    colors: Option<PrimvarSource>,
    opacities: Option<PrimvarSource>,
}

struct MeshSource {
    prim: usd::Prim,
    path: String,
    visibility: Vec<usd::Prim>,
    face_counts: Vec<u32>,
    face_indices: Vec<u32>,
    points: HeldQuery,
    skinned: Option<Proxy>,
    colors: Option<PrimvarSource>,
    left_handed: bool,
    double_sided: bool,
    smooth: bool,
}

/// The drawable content of a composed stage, with readers per frame.
///
/// Its attribute handles belong to the stage it was discovered on: every
/// per-frame read takes that stage's reader and refuses another one (whose
/// handles it would silently not read).
pub struct RenderScene {
    /// The stage the handles below belong to.
    stage: usd::Stage,
    /// None for a scene drawn through cameras given as numbers (the preview).
    camera: Option<usd::Prim>,
    camera_path: String,
    curves: Vec<CurvesSource>,
    meshes: Vec<MeshSource>,
}

fn token_attr(r: &StageReader, prim: &usd::Prim, name: &str, fallback: &str) -> Result<String> {
    Ok(r.typed(prim, name, None, "token", values::token)?
        .unwrap_or_else(|| fallback.to_string()))
}

/// A BasisCurves prim's `type`, `basis` and `wrap` (their fallbacks when
/// not authored).
pub fn curve_shape(r: &StageReader, prim: &usd::Prim, path: &str) -> Result<(CurveType, Basis, Wrap)> {
    let t = token_attr(r, prim, "type", "cubic")?;
    let curve_type =
        CurveType::from_token(&t).ok_or_else(|| Error::attr(path, "type", format!("unknown curve type {t:?}")))?;
    let b = token_attr(r, prim, "basis", "bezier")?;
    let basis = Basis::from_token(&b).ok_or_else(|| Error::attr(path, "basis", format!("unknown basis {b:?}")))?;
    let w = token_attr(r, prim, "wrap", "nonperiodic")?;
    let wrap = Wrap::from_token(&w).ok_or_else(|| Error::attr(path, "wrap", format!("unknown wrap {w:?}")))?;
    Ok((curve_type, basis, wrap))
}

impl RenderScene {
    /// Finds the camera (it must be a `Camera` prim) and everything drawable.
    pub fn discover(r: &StageReader, camera: &str) -> Result<RenderScene> {
        let cam = r
            .user_prim("--camera", camera)?
            .ok_or_else(|| Error::prim(camera, "camera prim does not exist (--camera)"))?;
        let ty = r.type_name(&cam)?;
        if ty != "Camera" {
            let what = if ty.is_empty() {
                "an untyped prim".to_string()
            } else {
                format!("a {ty} prim")
            };
            return Err(Error::prim(camera, format!("--camera names {what}, not a Camera")));
        }
        let mut scene = RenderScene::discover_drawables(r)?;
        scene.camera = Some(cam);
        scene.camera_path = camera.to_string();
        Ok(scene)
    }

    /// Finds everything drawable, without a camera prim ([`RenderScene::camera_at`]
    /// then fails): for views whose camera is given as numbers.
    pub fn discover_drawables(r: &StageReader) -> Result<RenderScene> {
        let mut scene = RenderScene {
            stage: r.stage.clone(),
            camera: None,
            camera_path: String::new(),
            curves: Vec::new(),
            meshes: Vec::new(),
        };
        for path in r.prim_paths()? {
            let prim = r.require_prim(&path)?;
            let ty = r.type_name(&prim)?;
            if ty != "BasisCurves" && ty != "Mesh" {
                continue;
            }
            let purpose = computed_purpose(r, &prim)?;
            if purpose == "guide" || purpose == "proxy" {
                continue;
            }
            let visibility = visibility_chain(r, &prim)?;
            if ty == "BasisCurves" {
                scene.curves.push(Self::curves_source(r, prim, path, visibility)?);
            } else {
                scene.meshes.push(Self::mesh_source(r, prim, path, visibility)?);
            }
        }
        Ok(scene)
    }

    fn curves_source(
        r: &StageReader,
        prim: usd::Prim,
        path: String,
        visibility: Vec<usd::Prim>,
    ) -> Result<CurvesSource> {
        let (curve_type, basis, wrap) = curve_shape(r, &prim, &path)?;
        let widths = match PrimvarSource::open(r, &prim, "primvars:widths", "vertex")? {
            Some(w) => Some(w),
            None => PrimvarSource::open(r, &prim, "widths", "vertex")?,
        };
        Ok(CurvesSource {
            counts: HeldQuery::new(&prim, "curveVertexCounts")?,
            points: HeldQuery::new(&prim, "points")?,
            widths,
            colors: PrimvarSource::open(r, &prim, "primvars:displayColor", "constant")?,
            opacities: PrimvarSource::open(r, &prim, "primvars:displayOpacity", "constant")?,
            prim,
            path,
            visibility,
            curve_type,
            basis,
            wrap,
        })
    }

    fn mesh_source(r: &StageReader, prim: usd::Prim, path: String, visibility: Vec<usd::Prim>) -> Result<MeshSource> {
        let (face_counts, face_indices) = read_face_topology(r, &prim, &path)?;
        let skinned = if skeleton_binding(r, &prim)?.is_some() {
            Some(read_mesh(r, prim.clone(), None)?)
        } else {
            None
        };
        let double_sided = r
            .typed(&prim, "doubleSided", None, "bool", values::scalar)?
            .is_some_and(|v| v != 0.0);
        let smooth = token_attr(r, &prim, "subdivisionScheme", "catmullClark")? != "none";
        Ok(MeshSource {
            smooth,
            face_counts,
            face_indices,
            points: HeldQuery::new(&prim, "points")?,
            skinned,
            colors: PrimvarSource::open(r, &prim, "primvars:displayColor", "constant")?,
            left_handed: r.left_handed(&prim)?,
            double_sided,
            prim,
            path,
            visibility,
        })
    }

    /// Number of (curves prims, meshes) found.
    pub fn counts(&self) -> (usize, usize) {
        (self.curves.len(), self.meshes.len())
    }

    /// Refuses a reader of another stage than the one discovered on.
    fn same_stage(&self, r: &StageReader) -> Result<()> {
        if r.stage == self.stage {
            Ok(())
        } else {
            Err(Error::msg(
                "internal error: drawables read through another stage than the one they were found on",
            ))
        }
    }

    /// The camera's parameters at `t` (validated).
    pub fn camera_at(&self, r: &StageReader, t: f64) -> Result<CameraParams> {
        self.same_stage(r)?;
        let p = self
            .camera
            .as_ref()
            .ok_or_else(|| Error::msg("this scene was discovered without a camera"))?;
        let d = CameraParams::default();
        let f = |name: &str, fallback: f64| -> Result<f64> {
            Ok(r.typed(p, name, Some(t), "float", values::scalar)?.unwrap_or(fallback))
        };
        let clip = r
            .typed(p, "clippingRange", Some(t), "float2", |v| match v {
                Value::Vec2f(c) => Some((c.x as f64, c.y as f64)),
                Value::Vec2d(c) => Some((c.x, c.y)),
                Value::Vec2h(c) => Some((c.x.to_f64(), c.y.to_f64())),
                _ => None,
            })?
            .unwrap_or((d.near, d.far));
        let projection = match r
            .typed(p, "projection", Some(t), "token", values::token)?
            .as_deref()
            .unwrap_or("perspective")
        {
            "perspective" => Projection::Perspective,
            "orthographic" => Projection::Orthographic,
            other => {
                return Err(Error::attr(
                    &self.camera_path,
                    "projection",
                    format!("unknown projection {other:?} (expected perspective or orthographic)"),
                ))
            }
        };
        let cam = CameraParams {
            focal_length: f("focalLength", d.focal_length)?,
            horizontal_aperture: f("horizontalAperture", d.horizontal_aperture)?,
            vertical_aperture: f("verticalAperture", d.vertical_aperture)?,
            horizontal_aperture_offset: f("horizontalApertureOffset", 0.0)?,
            vertical_aperture_offset: f("verticalApertureOffset", 0.0)?,
            near: clip.0,
            far: clip.1,
            projection,
            camera_to_world: r.local_to_world(p, t)?,
        };
        cam.validate()
            .map_err(|e| Error::attr(&self.camera_path, e.attribute, format!("at time {t}: {}", e.message)))?;
        Ok(cam)
    }

    /// Every visible curves prim at `t`, in world space.
    pub fn curves_at(&self, r: &StageReader, t: f64) -> Result<Vec<CurvesData>> {
        self.read_curves(r, t, true, true)
    }

    /// Every selected curves prim at `t`, invisible ones too, with widths in
    /// each prim's own space: the preview reads widths and colours once, for
    /// layers hidden only at that time, and scales the widths by each
    /// frame's transform (an animated scale changes them).
    pub fn curves_at_any_visibility(&self, r: &StageReader, t: f64) -> Result<Vec<CurvesData>> {
        self.read_curves(r, t, false, false)
    }

    /// Whether `render` draws the curves or mesh prim at `path` at `t`:
    /// selected (not a guide or proxy purpose) and visible.
    pub fn draws(&self, r: &StageReader, path: &str, t: f64) -> Result<bool> {
        self.same_stage(r)?;
        let chain = self
            .curves
            .iter()
            .find(|c| c.path == path)
            .map(|c| &c.visibility)
            .or_else(|| self.meshes.iter().find(|m| m.path == path).map(|m| &m.visibility));
        match chain {
            Some(chain) => visible(r, chain, t),
            None => Ok(false),
        }
    }

    fn read_curves(&self, r: &StageReader, t: f64, visible_only: bool, world_widths: bool) -> Result<Vec<CurvesData>> {
        self.same_stage(r)?;
        let mut out = Vec::with_capacity(self.curves.len());
        for c in &self.curves {
            if visible_only && !visible(r, &c.visibility, t)? {
                continue;
            }
            let read = |q: &HeldQuery, name: &str| -> Result<Option<Value>> {
                q.get_at(t)
                    .map_err(|e| Error::attr(&c.path, name, format!("cannot read: {e}")))
            };
            let Some(pv) = read(&c.points, "points")? else {
                continue;
            };
            let local = values::vec3_array(&pv).ok_or_else(|| {
                Error::attr(
                    &c.path,
                    "points",
                    format!("expected point3f[], found {}", values::kind_name(&pv)),
                )
            })?;
            let counts = match read(&c.counts, "curveVertexCounts")? {
                Some(v) => values::int_array(&v).ok_or_else(|| {
                    Error::attr(
                        &c.path,
                        "curveVertexCounts",
                        format!("expected int[], found {}", values::kind_name(&v)),
                    )
                })?,
                // USD's fallback is an empty array: counts that sum to 0
                // against the points, refused below as any other mismatch.
                None => Vec::new(),
            };
            if let Some(bad) = counts.iter().find(|&&n| n < 0) {
                return Err(Error::attr(
                    &c.path,
                    "curveVertexCounts",
                    format!("negative count {bad}"),
                ));
            }
            let m = r.local_to_world(&c.prim, t)?;
            let ws = if world_widths { width_scale(&m) } else { 1.0 };
            let points: Vec<DVec3> = local.iter().map(|p| m.transform_point3(p.as_dvec3())).collect();
            if let Some(i) = points.iter().position(|p| !p.is_finite()) {
                return Err(Error::attr(
                    &c.path,
                    "points",
                    format!("point {i} is not finite at time {t}"),
                ));
            }
            let widths = match &c.widths {
                Some(s) => s.floats(&c.prim, t)?,
                None => None,
            }
            .unwrap_or(Primvar::Constant(DEFAULT_WIDTH))
            .map(|w| if w.is_finite() { w.max(0.0) * ws } else { 0.0 });
            let colors = match &c.colors {
                Some(s) => s.colors(&c.prim, t)?,
                None => None,
            }
            .unwrap_or(Primvar::Constant(DEFAULT_COLOR));
            let opacities = match &c.opacities {
                Some(s) => s.floats(&c.prim, t)?,
                None => None,
            }
            .unwrap_or(Primvar::Constant(1.0))
            .map(|o| if o.is_finite() { o.clamp(0.0, 1.0) } else { 0.0 });
            let mut data = CurvesData {
                path: c.path.clone(),
                curve_type: c.curve_type,
                basis: c.basis,
                wrap: c.wrap,
                counts: counts.iter().map(|&n| n as usize).collect(),
                points,
                widths,
                colors,
                opacities,
            };
            data.adopt_usd_varying();
            data.validate()
                .map_err(|(attr, msg)| Error::attr(&c.path, attr, format!("at time {t}: {msg}")))?;
            out.push(data);
        }
        Ok(out)
    }

    /// Every visible mesh at `t`, in world space.
    pub fn meshes_at(&self, r: &StageReader, t: f64) -> Result<Vec<MeshData>> {
        self.read_meshes(r, t, true)
    }

    /// Every selected mesh at `t`, invisible ones too (see
    /// [`RenderScene::curves_at_any_visibility`]).
    pub fn meshes_at_any_visibility(&self, r: &StageReader, t: f64) -> Result<Vec<MeshData>> {
        self.read_meshes(r, t, false)
    }

    fn read_meshes(&self, r: &StageReader, t: f64, visible_only: bool) -> Result<Vec<MeshData>> {
        self.same_stage(r)?;
        let mut out = Vec::with_capacity(self.meshes.len());
        for m in &self.meshes {
            if visible_only && !visible(r, &m.visibility, t)? {
                continue;
            }
            let local: Vec<DVec3> = match &m.skinned {
                Some(proxy) => proxy.posed_points(r, t)?,
                None => {
                    let v = m
                        .points
                        .get_at(t)
                        .map_err(|e| Error::attr(&m.path, "points", format!("cannot read: {e}")))?;
                    let Some(v) = v else { continue };
                    values::vec3_array(&v)
                        .ok_or_else(|| {
                            Error::attr(
                                &m.path,
                                "points",
                                format!("expected point3f[], found {}", values::kind_name(&v)),
                            )
                        })?
                        .iter()
                        .map(|p| p.as_dvec3())
                        .collect()
                }
            };
            if let Some(&bad) = m.face_indices.iter().find(|&&i| i as usize >= local.len()) {
                return Err(Error::attr(
                    &m.path,
                    "faceVertexIndices",
                    format!("index {bad} is out of range ({} points at time {t})", local.len()),
                ));
            }
            let xf = r.local_to_world(&m.prim, t)?;
            let points: Vec<DVec3> = local.iter().map(|p| xf.transform_point3(*p)).collect();
            if let Some(i) = points.iter().position(|p| !p.is_finite()) {
                return Err(Error::attr(
                    &m.path,
                    "points",
                    format!("point {i} is not finite at time {t}"),
                ));
            }
            let colors = match &m.colors {
                Some(s) => s.colors(&m.prim, t)?,
                None => None,
            }
            .unwrap_or(Primvar::Constant(DEFAULT_COLOR));
            let data = MeshData {
                path: m.path.clone(),
                face_counts: m.face_counts.clone(),
                face_indices: m.face_indices.clone(),
                points,
                colors,
                // A negative-determinant transform flips the winding.
                left_handed: m.left_handed != (glam::DMat3::from_mat4(xf).determinant() < 0.0),
                double_sided: m.double_sided,
                smooth: m.smooth,
            };
            data.validate()
                .map_err(|(attr, msg)| Error::attr(&m.path, attr, format!("at time {t}: {msg}")))?;
            out.push(data);
        }
        Ok(out)
    }
}

/// Timing metadata of one layer file, for a root layer that sublayers it
/// without rescaling time: (timeCodesPerSecond, framesPerSecond, start, end).
pub fn layer_timing(path: &Path) -> Result<(f64, f64, Option<f64>, Option<f64>)> {
    let layer = super::guard::open_layer(path)?;
    let timing = (
        layer.time_codes_per_second(),
        layer.frames_per_second(),
        layer.has_start_time_code().then(|| layer.start_time_code()),
        layer.has_end_time_code().then(|| layer.end_time_code()),
    );
    // Written into the render's root layer: usd-core and openusd refuse nan.
    super::stage::StageMetadata {
        time_codes_per_second: Some(timing.0),
        frames_per_second: Some(timing.1),
        start_time_code: timing.2,
        end_time_code: timing.3,
        ..Default::default()
    }
    .validate()
    .map_err(|e| e.in_file(path))?;
    Ok(timing)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Four curves prims and two meshes: `Shown`; `Hidden` invisible at
    /// frames 1–2 only (its parent stays visible); `UnderHidden` under an
    /// invisible Xform; `Guide` a guide; a visible and an invisible mesh.
    const STAGE: &str = r#"#usda 1.0
def Xform "W" {
    def BasisCurves "Shown" { int[] curveVertexCounts = [2] point3f[] points = [(0, 0, 0), (1, 0, 0)] float[] widths = [0.5, 0.5] (interpolation = "vertex") }
    def BasisCurves "Hidden" {
        int[] curveVertexCounts = [2] point3f[] points = [(0, 1, 0), (1, 1, 0)] float[] widths = [0.25, 0.25] (interpolation = "vertex")
        token visibility.timeSamples = { 1: "invisible", 3: "inherited" }
    }
    def Xform "Off" {
        token visibility = "invisible"
        def BasisCurves "UnderHidden" { int[] curveVertexCounts = [2] point3f[] points = [(0, 2, 0), (1, 2, 0)] }
    }
    def BasisCurves "Guide" { uniform token purpose = "guide" int[] curveVertexCounts = [2] point3f[] points = [(0, 3, 0), (1, 3, 0)] }
    def Mesh "Box" { int[] faceVertexCounts = [3] int[] faceVertexIndices = [0, 1, 2] point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)] }
    def Mesh "OffBox" { token visibility = "invisible" int[] faceVertexCounts = [3] int[] faceVertexIndices = [0, 1, 2] point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)] }
}
"#;

    fn paths_of<T>(items: &[T], path: impl Fn(&T) -> &str) -> Vec<String> {
        items.iter().map(|i| path(i).to_string()).collect()
    }

    #[test]
    fn a_reader_of_another_stage_is_refused() {
        // The same file opened twice is two stages: the handles found on
        // the first do not read the second's values, so every read refuses
        // it instead of answering from the first.
        let dir = crate::test_dir::ScratchDir::new("render-scene-other-stage");
        let file = dir.join("s.usda");
        std::fs::write(&file, STAGE).unwrap();
        let (r, other) = (StageReader::open(&file).unwrap(), StageReader::open(&file).unwrap());
        let scene = RenderScene::discover_drawables(&r).unwrap();
        assert_eq!(scene.curves_at(&r, 1.0).unwrap().len(), 1);
        let refused = |e: Error| assert!(e.to_string().contains("another stage"), "{e}");
        refused(scene.curves_at(&other, 1.0).unwrap_err());
        refused(scene.curves_at_any_visibility(&other, 1.0).unwrap_err());
        refused(scene.meshes_at(&other, 1.0).unwrap_err());
        refused(scene.meshes_at_any_visibility(&other, 1.0).unwrap_err());
        refused(scene.draws(&other, "/W/Shown", 1.0).unwrap_err());
        refused(scene.camera_at(&other, 1.0).unwrap_err());
    }

    #[test]
    fn visibility_selects_per_frame_and_the_any_visibility_reads_keep_hidden_prims() {
        let dir = crate::test_dir::ScratchDir::new("render-scene-visibility");
        let file = dir.join("s.usda");
        std::fs::write(&file, STAGE).unwrap();
        let r = StageReader::open(&file).unwrap();
        let scene = RenderScene::discover_drawables(&r).unwrap();
        let curves = |t: f64, any: bool| {
            let c = if any {
                scene.curves_at_any_visibility(&r, t).unwrap()
            } else {
                scene.curves_at(&r, t).unwrap()
            };
            paths_of(&c, |c| &c.path)
        };
        // The guide is never selected; visibility is read at each time.
        assert_eq!(curves(1.0, false), ["/W/Shown"]);
        assert_eq!(curves(3.0, false), ["/W/Shown", "/W/Hidden"]);
        for t in [1.0, 3.0] {
            assert_eq!(curves(t, true), ["/W/Shown", "/W/Hidden", "/W/Off/UnderHidden"]);
        }
        // A hidden prim's data is its own, not a fallback.
        let all = scene.curves_at_any_visibility(&r, 1.0).unwrap();
        assert_eq!(all[1].widths, Primvar::Vertex(vec![0.25, 0.25]));
        let meshes = |any: bool| {
            let m = if any {
                scene.meshes_at_any_visibility(&r, 1.0).unwrap()
            } else {
                scene.meshes_at(&r, 1.0).unwrap()
            };
            paths_of(&m, |m| &m.path)
        };
        assert_eq!(meshes(false), ["/W/Box"]);
        assert_eq!(meshes(true), ["/W/Box", "/W/OffBox"]);
        // `draws`: what `render` draws at that time; unknown prims are not drawn.
        let draws = |p: &str, t: f64| scene.draws(&r, p, t).unwrap();
        assert!(draws("/W/Shown", 1.0) && draws("/W/Box", 1.0));
        assert!(!draws("/W/Hidden", 1.0) && !draws("/W/Hidden", 2.0) && draws("/W/Hidden", 3.0));
        assert!(!draws("/W/Off/UnderHidden", 3.0) && !draws("/W/Guide", 1.0) && !draws("/W/OffBox", 1.0));
        assert!(!draws("/W/Nothing", 1.0));
    }
}
