//! World-space curves and meshes → a pixel-space [`FrameScene`].
//!
//! **Strokes.** Every curve of every BasisCurves prim is one stroke. Its
//! polyline is clipped to the camera's clipping range, projected, and drawn
//! as a camera-facing ribbon: at each point the ribbon is `width` scene units
//! wide perpendicular to the view direction, i.e. `width × pixels_per_unit(depth)`
//! pixels on screen. Strokes are sorted back to front by the mean camera
//! depth of their points (ties keep stage order: later prims and curves on
//! top).
//!
//! **Meshes.** Faces are fan-triangulated from their first vertex; shading
//! normals are the area-weighted sums of the triangle normals at each vertex
//! for subdivision surfaces (`subdivisionScheme` ≠ `none`, smooth as a
//! subdivided surface would look), the polygon's own normal for
//! `subdivisionScheme = "none"` (faceted); authored `normals` are ignored; triangles crossing the near plane are
//! clipped; back faces are culled unless `doubleSided`. A silhouette edge is
//! an edge shared by a front-facing and a back-facing polygon (Rademacher
//! §3.2.4 after Raskar & Cohen), facing judged from the polygon's Newell
//! normal and the eye; silhouettes are drawn as dark round-capped lines.

use std::collections::HashMap;

use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;

use super::camera::Projector;
use super::composite::{FrameScene, StrokeRibbon};
use super::curves::{CurvesData, Polyline, Primvar};
use super::raster::{RibbonVertex, ScreenTriangle};
use super::shade::WarmCool;

/// One Mesh prim at one time, in world space.
#[derive(Debug, Clone)]
pub struct MeshData {
    pub path: String,
    pub face_counts: Vec<u32>,
    pub face_indices: Vec<u32>,
    /// World-space points.
    pub points: Vec<DVec3>,
    /// Linear display colour.
    pub colors: Primvar<Vec3>,
    /// Clockwise polygons face outwards (`orientation = "leftHanded"`, or a
    /// mirroring transform).
    pub left_handed: bool,
    pub double_sided: bool,
    /// Smooth vertex normals (`subdivisionScheme` other than `none`);
    /// faceted otherwise.
    pub smooth: bool,
}

impl MeshData {
    /// Checks the colour primvar's length against the topology.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let want = match &self.colors {
            Primvar::Constant(_) => return Ok(()),
            Primvar::Uniform(_) => self.face_counts.len(),
            Primvar::Vertex(_) | Primvar::Varying(_) => self.points.len(),
            Primvar::FaceVarying(_) => self.face_indices.len(),
        };
        if self.colors.len() != want {
            return Err((
                "primvars:displayColor",
                format!(
                    "{} values with {} interpolation, expected {want}",
                    self.colors.len(),
                    self.colors.interpolation()
                ),
            ));
        }
        Ok(())
    }

    fn color(&self, face: usize, corner: usize, point: usize) -> Vec3 {
        match &self.colors {
            Primvar::Constant(c) => *c,
            Primvar::Uniform(v) => v[face],
            Primvar::Vertex(v) | Primvar::Varying(v) => v[point],
            Primvar::FaceVarying(v) => v[corner],
        }
    }
}

/// Look of the preview.
#[derive(Debug, Clone, Copy)]
pub struct Style {
    /// Silhouette line width in pixels.
    pub line_width: f32,
    /// Silhouette line colour (linear).
    pub line_color: Vec3,
    pub shading: WarmCool,
}

impl Default for Style {
    fn default() -> Self {
        Style {
            line_width: 1.5,
            line_color: Vec3::new(0.02, 0.02, 0.03),
            shading: WarmCool::default(),
        }
    }
}

/// A point in camera space with the attributes that ride along.
#[derive(Debug, Clone, Copy)]
struct CamPoint {
    p: DVec3,
    width: f32,
    color: Vec3,
    opacity: f32,
}

impl CamPoint {
    fn lerp(&self, o: &CamPoint, t: f64) -> CamPoint {
        let tf = t as f32;
        CamPoint {
            p: self.p + (o.p - self.p) * t,
            width: self.width + (o.width - self.width) * tf,
            color: self.color + (o.color - self.color) * tf,
            opacity: self.opacity + (o.opacity - self.opacity) * tf,
        }
    }
}

/// The parameter interval of segment depth `d0 → d1` inside `[near, far]`.
fn clip_interval(d0: f64, d1: f64, near: f64, far: f64) -> Option<(f64, f64)> {
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (lo, hi) in [(near, f64::INFINITY), (f64::NEG_INFINITY, far)] {
        // Keep lo ≤ d(t) ≤ hi, d(t) = d0 + t (d1 − d0).
        let dd = d1 - d0;
        if dd.abs() < 1e-300 {
            if d0 < lo || d0 > hi {
                return None;
            }
            continue;
        }
        let (a, b) = ((lo - d0) / dd, (hi - d0) / dd);
        let (a, b) = if a < b { (a, b) } else { (b, a) };
        t0 = t0.max(a);
        t1 = t1.min(b);
    }
    (t0 <= t1).then_some((t0, t1))
}

/// Splits a camera-space polyline into the runs inside the clipping range.
fn clip_polyline(pts: &[CamPoint], near: f64, far: f64) -> Vec<Vec<CamPoint>> {
    let depth = |c: &CamPoint| -c.p.z;
    let inside = |c: &CamPoint| depth(c) >= near && depth(c) <= far;
    if pts.len() == 1 {
        return if inside(&pts[0]) { vec![pts.to_vec()] } else { vec![] };
    }
    let mut pieces = Vec::new();
    let mut cur: Vec<CamPoint> = Vec::new();
    for w in pts.windows(2) {
        let Some((t0, t1)) = clip_interval(depth(&w[0]), depth(&w[1]), near, far) else {
            if !cur.is_empty() {
                pieces.push(std::mem::take(&mut cur));
            }
            continue;
        };
        if cur.is_empty() || t0 > 0.0 {
            if !cur.is_empty() {
                pieces.push(std::mem::take(&mut cur));
            }
            cur.push(w[0].lerp(&w[1], t0));
        }
        cur.push(w[0].lerp(&w[1], t1));
        if t1 < 1.0 {
            pieces.push(std::mem::take(&mut cur));
        }
    }
    if !cur.is_empty() {
        pieces.push(cur);
    }
    pieces
}

/// A stroke ready to sort: its sort depth and its projected pieces.
struct PreparedStroke {
    depth: f64,
    pieces: Vec<(Vec<RibbonVertex>, f32)>,
}

fn prepare_stroke(proj: &Projector, line: &Polyline) -> Option<PreparedStroke> {
    if line.points.is_empty() {
        return None;
    }
    let cam: Vec<CamPoint> = (0..line.points.len())
        .map(|i| CamPoint {
            p: proj.to_camera(line.points[i]),
            width: line.widths[i],
            color: line.colors[i],
            opacity: line.opacities[i],
        })
        .collect();
    let depth = cam.iter().map(|c| -c.p.z).sum::<f64>() / cam.len() as f64;
    let pieces: Vec<(Vec<RibbonVertex>, f32)> = clip_polyline(&cam, proj.near, proj.far)
        .into_iter()
        .map(|piece| {
            let mut arc = 0.0f32;
            let mut prev: Option<Vec2> = None;
            let verts: Vec<RibbonVertex> = piece
                .iter()
                .map(|c| {
                    let d = -c.p.z;
                    let pos = proj.camera_to_pixel(c.p).as_vec2();
                    if let Some(q) = prev {
                        arc += (pos - q).length();
                    }
                    prev = Some(pos);
                    RibbonVertex {
                        pos,
                        radius: (0.5 * c.width as f64 * proj.pixels_per_unit(d)) as f32,
                        depth: d as f32,
                        color: c.color,
                        opacity: c.opacity,
                        arc,
                    }
                })
                .collect();
            (verts, arc)
        })
        .filter(|(v, _)| v.iter().all(|r| r.pos.is_finite() && r.radius.is_finite()))
        .collect();
    (!pieces.is_empty()).then_some(PreparedStroke { depth, pieces })
}

/// Newell normal of a polygon (length = twice its area).
fn newell(points: &[DVec3], idx: &[u32]) -> DVec3 {
    let mut n = DVec3::ZERO;
    for k in 0..idx.len() {
        let a = points[idx[k] as usize];
        let b = points[idx[(k + 1) % idx.len()] as usize];
        n += DVec3::new(
            (a.y - b.y) * (a.z + b.z),
            (a.z - b.z) * (a.x + b.x),
            (a.x - b.x) * (a.y + b.y),
        );
    }
    n
}

/// Whether a camera-space surface with normal `n` at `p` faces the eye.
fn faces_eye(proj: &Projector, n: DVec3, p: DVec3) -> bool {
    if proj.is_perspective() {
        n.dot(-p) > 0.0
    } else {
        n.z > 0.0
    }
}

/// A mesh vertex in camera space with its shading inputs.
#[derive(Debug, Clone, Copy)]
struct MeshVertex {
    p: DVec3,
    n: Vec3,
    c: Vec3,
}

fn clip_triangle_near(tri: [MeshVertex; 3], near: f64) -> Vec<MeshVertex> {
    let inside = |v: &MeshVertex| -v.p.z >= near;
    let mut out = Vec::with_capacity(4);
    for k in 0..3 {
        let (a, b) = (tri[k], tri[(k + 1) % 3]);
        if inside(&a) {
            out.push(a);
        }
        if inside(&a) != inside(&b) {
            // Cut from the inside end: the neighbour across this edge runs
            // it the other way and must get the same point, bit for bit,
            // or a crack opens along the clipped edge.
            let (i, o) = if inside(&a) { (a, b) } else { (b, a) };
            let (di, dout) = (-i.p.z, -o.p.z);
            let t = (near - di) / (dout - di);
            let tf = t as f32;
            out.push(MeshVertex {
                p: i.p + (o.p - i.p) * t,
                n: i.n + (o.n - i.n) * tf,
                c: i.c + (o.c - i.c) * tf,
            });
        }
    }
    out
}

fn prepare_mesh(proj: &Projector, m: &MeshData, style: &Style) -> (Vec<ScreenTriangle>, Vec<[RibbonVertex; 2]>) {
    let cam: Vec<DVec3> = m.points.iter().map(|&p| proj.to_camera(p)).collect();
    let shading = Shading::new(proj, m, &cam);
    let tris = mesh_triangles(proj, m, &cam, &shading);
    let lines = silhouette_lines(proj, m, &cam, &shading, style);
    (tris, lines)
}

/// What every face and vertex of a mesh shares, in camera space.
struct Shading {
    /// Where each face's indices start in `face_indices`.
    offsets: Vec<usize>,
    /// Smooth vertex normals: the sum of the fan triangles' area normals.
    normals: Vec<Vec3>,
    /// Whether each face (Newell normal at its centroid) faces the eye.
    front: Vec<bool>,
    /// -1 for a left-handed mesh, whose faces wind the other way.
    sign: f64,
}

impl Shading {
    fn new(proj: &Projector, m: &MeshData, cam: &[DVec3]) -> Shading {
        let sign = if m.left_handed { -1.0 } else { 1.0 };
        let mut offsets = Vec::with_capacity(m.face_counts.len());
        let mut o = 0usize;
        for &c in &m.face_counts {
            offsets.push(o);
            o += c as usize;
        }
        let mut normals = vec![DVec3::ZERO; cam.len()];
        let mut front = vec![false; m.face_counts.len()];
        for (f, &c) in m.face_counts.iter().enumerate() {
            let idx = &m.face_indices[offsets[f]..offsets[f] + c as usize];
            if idx.len() < 3 {
                continue;
            }
            let n = newell(cam, idx) * sign;
            let centroid = idx.iter().map(|&i| cam[i as usize]).sum::<DVec3>() / idx.len() as f64;
            front[f] = faces_eye(proj, n, centroid);
            for k in 1..idx.len() - 1 {
                let (a, b, cc) = (cam[idx[0] as usize], cam[idx[k] as usize], cam[idx[k + 1] as usize]);
                let tn = (b - a).cross(cc - a) * sign;
                for &i in [idx[0], idx[k], idx[k + 1]].iter() {
                    normals[i as usize] += tn;
                }
            }
        }
        let normals: Vec<Vec3> = normals.iter().map(|n| n.normalize_or_zero().as_vec3()).collect();
        Shading {
            offsets,
            normals,
            front,
            sign,
        }
    }
}

/// The mesh's triangles in pixels: fans of its faces, culled when one-sided
/// and facing away, clipped at the near plane.
fn mesh_triangles(proj: &Projector, m: &MeshData, cam: &[DVec3], s: &Shading) -> Vec<ScreenTriangle> {
    let mut tris = Vec::new();
    for (f, &c) in m.face_counts.iter().enumerate() {
        let off = s.offsets[f];
        let idx = &m.face_indices[off..off + c as usize];
        if idx.len() < 3 {
            continue;
        }
        let flat = (!m.smooth).then(|| (newell(cam, idx) * s.sign).normalize_or_zero().as_vec3());
        let vert = |k: usize| {
            let i = idx[k] as usize;
            MeshVertex {
                p: cam[i],
                n: flat.unwrap_or(s.normals[i]),
                c: m.color(f, off + k, i),
            }
        };
        for k in 1..idx.len() - 1 {
            let tri = [vert(0), vert(k), vert(k + 1)];
            let tn = (tri[1].p - tri[0].p).cross(tri[2].p - tri[0].p) * s.sign;
            let centre = (tri[0].p + tri[1].p + tri[2].p) / 3.0;
            if !m.double_sided && !faces_eye(proj, tn, centre) {
                continue;
            }
            let depths = tri.map(|v| -v.p.z);
            if depths.iter().all(|&d| d > proj.far) || depths.iter().all(|&d| d < proj.near) {
                continue;
            }
            let poly = if depths.iter().all(|&d| d >= proj.near) {
                tri.to_vec()
            } else {
                clip_triangle_near(tri, proj.near)
            };
            for j in 1..poly.len().saturating_sub(1) {
                let t = [poly[0], poly[j], poly[j + 1]];
                let st = ScreenTriangle {
                    pos: t.map(|v| proj.camera_to_pixel(v.p).as_vec2()),
                    depth: t.map(|v| (-v.p.z) as f32),
                    normal: t.map(|v| v.n),
                    color: t.map(|v| v.c),
                };
                if st.pos.iter().all(|p| p.is_finite()) {
                    tris.push(st);
                }
            }
        }
    }
    tris
}

/// Silhouettes: edges between a front- and a back-facing polygon.
fn silhouette_lines(
    proj: &Projector,
    m: &MeshData,
    cam: &[DVec3],
    s: &Shading,
    style: &Style,
) -> Vec<[RibbonVertex; 2]> {
    let mut edges: HashMap<(u32, u32), (usize, Option<usize>)> = HashMap::new();
    for (f, &c) in m.face_counts.iter().enumerate() {
        if c < 3 {
            continue;
        }
        let idx = &m.face_indices[s.offsets[f]..s.offsets[f] + c as usize];
        for k in 0..idx.len() {
            let (a, b) = (idx[k], idx[(k + 1) % idx.len()]);
            let key = (a.min(b), a.max(b));
            edges
                .entry(key)
                .and_modify(|e| {
                    if e.1.is_none() && e.0 != f {
                        e.1 = Some(f);
                    }
                })
                .or_insert((f, None));
        }
    }
    let mut lines = Vec::new();
    let r = 0.5 * style.line_width;
    for (&(a, b), &(f0, f1)) in &edges {
        let Some(f1) = f1 else { continue };
        if s.front[f0] == s.front[f1] {
            continue;
        }
        let pa = CamPoint {
            p: cam[a as usize],
            width: 0.0,
            color: style.line_color,
            opacity: 1.0,
        };
        let pb = CamPoint {
            p: cam[b as usize],
            ..pa
        };
        for piece in clip_polyline(&[pa, pb], proj.near, proj.far) {
            if piece.len() == 2 {
                let v = |c: &CamPoint| RibbonVertex {
                    pos: proj.camera_to_pixel(c.p).as_vec2(),
                    radius: r,
                    depth: (-c.p.z) as f32,
                    color: style.line_color,
                    opacity: 1.0,
                    arc: 0.0,
                };
                let seg = [v(&piece[0]), v(&piece[1])];
                if seg.iter().all(|s| s.pos.is_finite()) {
                    lines.push(seg);
                }
            }
        }
    }
    // HashMap order is random: sort for reproducible output.
    lines.sort_by(|x, y| {
        (x[0].pos.x, x[0].pos.y, x[1].pos.x, x[1].pos.y)
            .partial_cmp(&(y[0].pos.x, y[0].pos.y, y[1].pos.x, y[1].pos.y))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    lines
}

/// Projects everything into a frame's pixel space.
pub fn build_scene(proj: &Projector, curves: &[CurvesData], meshes: &[MeshData], style: &Style) -> FrameScene {
    let lines: Vec<Polyline> = curves.par_iter().flat_map_iter(|c| c.polylines()).collect();
    build_scene_of_lines(proj, &lines, meshes, style)
}

/// [`build_scene`] from the curves' polylines, evaluated already (every
/// curve's, in stage order).
pub fn build_scene_of_lines(proj: &Projector, lines: &[Polyline], meshes: &[MeshData], style: &Style) -> FrameScene {
    let mut strokes: Vec<(usize, PreparedStroke)> = lines
        .par_iter()
        .enumerate()
        .filter_map(|(i, l)| prepare_stroke(proj, l).map(|s| (i, s)))
        .collect();
    // Back to front; equal depths keep stage order (later on top).
    strokes.sort_by(|a, b| b.1.depth.total_cmp(&a.1.depth).then(a.0.cmp(&b.0)));

    let mut scene = FrameScene {
        width: proj.width,
        height: proj.height,
        perspective: proj.is_perspective(),
        line_color: style.line_color,
        shading: Some(style.shading),
        ..Default::default()
    };
    for (_, s) in strokes {
        for (verts, length) in s.pieces {
            let start = scene.verts.len() as u32;
            scene.verts.extend(verts);
            scene.strokes.push(StrokeRibbon {
                start,
                end: scene.verts.len() as u32,
                length,
            });
        }
    }
    let prepared: Vec<_> = meshes.par_iter().map(|m| prepare_mesh(proj, m, style)).collect();
    for (t, l) in prepared {
        scene.triangles.extend(t);
        scene.lines.extend(l);
    }
    scene
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::camera::{CameraParams, Projection};
    use crate::render::composite::render;
    use crate::render::curves::{Basis, CurveType, Wrap};
    use glam::{DMat4, DVec2};

    fn projector() -> Projector {
        // 100 px wide window of 2 units at depth 10: 50 px per unit there.
        let cam = CameraParams {
            focal_length: 50.0,
            horizontal_aperture: 10.0,
            vertical_aperture: 10.0,
            camera_to_world: DMat4::from_translation(DVec3::new(0.0, 0.0, 10.0)),
            ..Default::default()
        };
        Projector::new(&cam, 100, 100)
    }

    fn stroke(z: f64, x0: f64, x1: f64, width: f32, color: Vec3) -> CurvesData {
        CurvesData {
            path: "/S".into(),
            curve_type: CurveType::Linear,
            basis: Basis::Bezier,
            wrap: Wrap::Nonperiodic,
            counts: vec![2],
            points: vec![DVec3::new(x0, 0.0, z), DVec3::new(x1, 0.0, z)],
            widths: Primvar::Constant(width),
            colors: Primvar::Constant(color),
            opacities: Primvar::Constant(0.5),
        }
    }

    #[test]
    fn ribbon_width_is_world_width_at_its_depth() {
        let p = projector();
        let s = build_scene(&p, &[stroke(0.0, -0.5, 0.5, 0.2, Vec3::ONE)], &[], &Style::default());
        // 0.2 units at depth 10 → 10 px wide, 1 unit long → 50 px.
        assert_eq!(s.strokes.len(), 1);
        assert!((s.verts[0].radius - 5.0).abs() < 1e-4);
        assert!((s.strokes[0].length - 50.0).abs() < 1e-3);
        let f = render(&s, None);
        let area: f32 = f.rgba.iter().map(|p| p[3]).sum::<f32>() / 0.5;
        assert!((area - 500.0).abs() / 500.0 < 0.01, "{area}");
    }

    #[test]
    fn strokes_sort_back_to_front_whatever_the_stage_order() {
        let p = projector();
        let red = Vec3::X;
        let blue = Vec3::Z;
        // Red is nearer (z = 1 is closer to the camera at z = 10).
        for order in [[0, 1], [1, 0]] {
            let c = [stroke(1.0, -0.5, 0.5, 0.2, red), stroke(-1.0, -0.5, 0.5, 0.2, blue)];
            let cs: Vec<CurvesData> = order.iter().map(|&i| c[i].clone()).collect();
            let f = render(&build_scene(&p, &cs, &[], &Style::default()), None);
            let px = f.rgba[50 * 100 + 50];
            // red·0.5 over blue·0.5: R = 0.5, B = 0.25.
            assert!((px[0] - 0.5).abs() < 1e-4 && (px[2] - 0.25).abs() < 1e-4, "{px:?}");
        }
    }

    #[test]
    fn near_plane_clips_strokes_and_triangles() {
        let p = projector();
        // From depth 5 to depth 15 through the camera (at z = 10): depth 0..1
        // is before the near plane (1).
        let c = CurvesData {
            points: vec![DVec3::new(0.0, 0.0, 5.0), DVec3::new(0.0, 0.0, 9.5)],
            ..stroke(0.0, 0.0, 0.0, 0.1, Vec3::ONE)
        };
        let s = build_scene(&p, &[c], &[], &Style::default());
        assert_eq!(s.strokes.len(), 1);
        let last = s.verts[s.strokes[0].end as usize - 1];
        assert!((last.depth - 1.0).abs() < 1e-5);
        let (a, b) = clip_interval(0.5, 2.0, 1.0, 100.0).unwrap();
        assert!((a - 1.0 / 3.0).abs() < 1e-12 && b == 1.0);
        assert!(clip_interval(0.0, 0.5, 1.0, 100.0).is_none());
    }

    fn cube() -> MeshData {
        let mut points = Vec::new();
        for z in [-1.0, 1.0] {
            for y in [-1.0, 1.0] {
                for x in [-1.0, 1.0] {
                    points.push(DVec3::new(x, y, z));
                }
            }
        }
        // Outward, counter-clockwise faces.
        let faces = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        MeshData {
            path: "/Cube".into(),
            face_counts: vec![4; 6],
            face_indices: faces.iter().flatten().copied().collect(),
            points,
            colors: Primvar::Constant(Vec3::splat(0.5)),
            left_handed: false,
            double_sided: false,
            smooth: false,
        }
    }

    #[test]
    fn cube_front_faces_and_silhouette() {
        let p = projector();
        let (tris, lines) = prepare_mesh(&p, &cube(), &Style::default());
        // Seen straight on, only the +Z face faces the eye.
        assert_eq!(tris.len(), 2);
        // The 4 edges around it border side faces that face away.
        assert_eq!(lines.len(), 4);
        let f = render(&build_scene(&p, &[], &[cube()], &Style::default()), None);
        // Centre: the +Z face, depth 9, lit by the warm light only.
        let c = f.rgba[50 * 100 + 50];
        let want = WarmCool::default().shade(Vec3::splat(0.5), Vec3::Z);
        assert!((c[0] - want.x).abs() < 1e-4 && c[3] == 1.0);
        assert!((f.z[50 * 100 + 50] - 9.0).abs() < 1e-4);
        // The face spans ±1 unit at depth 9: x from 50 − 55.6 to 50 + 55.6,
        // beyond the image; a smaller cube shows its silhouette as dark lines.
        let small = MeshData {
            points: cube().points.iter().map(|q| *q * 0.5).collect(),
            ..cube()
        };
        let f = render(&build_scene(&p, &[], &[small], &Style::default()), None);
        // The right edge at x = 0.5 at depth 9.5: pixel 50 + 0.5 / 9.5 · 500 = 76.3.
        let edge = f.rgba[50 * 100 + 76];
        assert!(edge[0] < 0.2 && edge[3] > 0.9, "{edge:?}");
    }

    // What follows pins each step against values derived by hand, or
    // against an independent rule (a triangle faces the eye exactly when
    // its projection winds counter-clockwise as seen).

    #[test]
    fn validate_counts_colours_per_interpolation() {
        let with = |colors| MeshData { colors, ..cube() };
        let v = |n| vec![Vec3::ONE; n];
        assert_eq!(with(Primvar::Constant(Vec3::ONE)).validate(), Ok(()));
        assert_eq!(with(Primvar::Uniform(v(6))).validate(), Ok(()));
        assert_eq!(with(Primvar::Vertex(v(8))).validate(), Ok(()));
        assert_eq!(with(Primvar::Varying(v(8))).validate(), Ok(()));
        assert_eq!(with(Primvar::FaceVarying(v(24))).validate(), Ok(()));
        let err = |n: usize, how: &str, want: usize| {
            Err((
                "primvars:displayColor",
                format!("{n} values with {how} interpolation, expected {want}"),
            ))
        };
        assert_eq!(with(Primvar::Uniform(v(8))).validate(), err(8, "uniform", 6));
        assert_eq!(with(Primvar::Vertex(v(6))).validate(), err(6, "vertex", 8));
        assert_eq!(with(Primvar::Varying(v(24))).validate(), err(24, "varying", 8));
        assert_eq!(with(Primvar::FaceVarying(v(8))).validate(), err(8, "faceVarying", 24));
    }

    #[test]
    fn lerp_carries_every_attribute() {
        let a = CamPoint {
            p: DVec3::new(1.0, 2.0, -4.0),
            width: 2.0,
            color: Vec3::new(0.0, 1.0, 0.5),
            opacity: 1.0,
        };
        let b = CamPoint {
            p: DVec3::new(5.0, -2.0, -8.0),
            width: 6.0,
            color: Vec3::new(1.0, 0.0, 0.5),
            opacity: 0.0,
        };
        let c = a.lerp(&b, 0.25);
        assert_eq!(c.p, DVec3::new(2.0, 1.0, -5.0));
        assert_eq!(c.width, 3.0);
        assert_eq!(c.color, Vec3::new(0.25, 0.75, 0.5));
        assert_eq!(c.opacity, 0.75);
    }

    #[test]
    fn clip_interval_keeps_the_closed_range() {
        // Constant depth: kept whole when inside, bounds included.
        assert_eq!(clip_interval(1.0, 1.0, 1.0, 100.0), Some((0.0, 1.0)));
        assert_eq!(clip_interval(100.0, 100.0, 1.0, 100.0), Some((0.0, 1.0)));
        assert_eq!(clip_interval(50.0, 50.0, 1.0, 100.0), Some((0.0, 1.0)));
        assert_eq!(clip_interval(0.5, 0.5, 1.0, 100.0), None);
        assert_eq!(clip_interval(101.0, 101.0, 1.0, 100.0), None);
        // d(t) = 150 − 100 t comes inside the far plane at t = 1/2.
        assert_eq!(clip_interval(150.0, 50.0, 1.0, 100.0), Some((0.5, 1.0)));
        // d(t) = 200 t crosses near at t = 1/200 and far at t = 1/2.
        assert_eq!(clip_interval(0.0, 200.0, 1.0, 100.0), Some((1.0 / 200.0, 0.5)));
        assert_eq!(clip_interval(101.0, 300.0, 1.0, 100.0), None);
        assert_eq!(clip_interval(0.0, 0.5, 1.0, 100.0), None);
        // A step of exactly 1e-300 is still a slope: d(t) = 1e-300 t
        // reaches near = 1e-300 at t = 1.
        assert_eq!(clip_interval(0.0, 1e-300, 1e-300, 1.0), Some((1.0, 1.0)));
    }

    /// Points at these depths (x = depth, so pieces can be told apart).
    fn at_depths(depths: &[f64]) -> Vec<CamPoint> {
        let point = |d: f64| CamPoint {
            p: DVec3::new(d, 0.0, -d),
            width: 1.0,
            color: Vec3::ONE,
            opacity: 1.0,
        };
        depths.iter().map(|&d| point(d)).collect()
    }

    /// The depths of each clipped piece, rounded to 1e-9.
    fn piece_depths(depths: &[f64]) -> Vec<Vec<f64>> {
        clip_polyline(&at_depths(depths), 1.0, 10.0)
            .iter()
            .map(|piece| piece.iter().map(|c| (-c.p.z * 1e9).round() / 1e9).collect())
            .collect()
    }

    #[test]
    fn clip_polyline_splits_into_the_runs_inside() {
        let none: Vec<Vec<f64>> = vec![];
        // Single points: kept inside the closed range [1, 10] only.
        assert_eq!(piece_depths(&[1.0]), [[1.0]]);
        assert_eq!(piece_depths(&[10.0]), [[10.0]]);
        assert_eq!(piece_depths(&[5.0]), [[5.0]]);
        assert_eq!(piece_depths(&[0.5]), none);
        assert_eq!(piece_depths(&[11.0]), none);
        // Inside throughout: one run of every point.
        assert_eq!(piece_depths(&[2.0, 3.0, 4.0]), [[2.0, 3.0, 4.0]]);
        // Starting behind the near plane: the run starts on it.
        assert_eq!(piece_depths(&[0.5, 0.6, 2.0]), [[1.0, 2.0]]);
        // Leaving through near and coming back: two runs.
        assert_eq!(
            piece_depths(&[0.5, 2.0, 3.0, 0.5, 2.0]),
            [vec![1.0, 2.0, 3.0, 1.0], vec![1.0, 2.0]]
        );
        // Leaving through far and coming back.
        assert_eq!(piece_depths(&[2.0, 12.0, 3.0]), [[2.0, 10.0], [10.0, 3.0]]);
        assert_eq!(piece_depths(&[0.5, 0.7]), none);
    }

    #[test]
    fn strokes_sort_by_their_mean_depth() {
        let p = projector();
        // Eight points at depth 5 against two at depth 6: the mean puts the
        // two-point stroke behind (a sum would not).
        let line = |z: f64, n: usize, color: Vec3| CurvesData {
            counts: vec![n],
            points: (0..n).map(|i| DVec3::new(-0.5 + i as f64 / n as f64, 0.0, z)).collect(),
            ..stroke(z, 0.0, 0.0, 0.2, color)
        };
        for order in [[0, 1], [1, 0]] {
            let c = [line(5.0, 8, Vec3::X), line(4.0, 2, Vec3::Z)];
            let cs: Vec<CurvesData> = order.iter().map(|&i| c[i].clone()).collect();
            let s = build_scene(&p, &cs, &[], &Style::default());
            let first = s.verts[s.strokes[0].start as usize];
            assert_eq!((first.depth, first.color), (6.0, Vec3::Z), "{order:?}");
        }
        // A piece whose radius is not finite is dropped.
        let wide = stroke(0.0, -0.5, 0.5, f32::INFINITY, Vec3::ONE);
        assert!(build_scene(&p, &[wide], &[], &Style::default()).strokes.is_empty());
    }

    #[test]
    fn newell_normal_is_twice_the_area_along_the_normal() {
        let tri = [
            DVec3::new(3.0, -1.0, 2.0),
            DVec3::new(5.0, 0.0, 1.0),
            DVec3::new(2.0, 2.0, 4.0),
        ];
        let cross = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
        assert!((newell(&tri, &[0, 1, 2]) - cross).length() < 1e-12);
        assert!((newell(&tri, &[0, 2, 1]) + cross).length() < 1e-12);
        // A 2 × 3 rectangle in the plane z = 7.
        let quad = [(0.0, 0.0), (2.0, 0.0), (2.0, 3.0), (0.0, 3.0)].map(|(x, y)| DVec3::new(x, y, 7.0));
        assert_eq!(newell(&quad, &[0, 1, 2, 3]), DVec3::new(0.0, 0.0, 12.0));
    }

    fn ortho_projector() -> Projector {
        let cam = CameraParams {
            projection: Projection::Orthographic,
            horizontal_aperture: 100.0,
            vertical_aperture: 100.0,
            camera_to_world: DMat4::from_translation(DVec3::new(0.0, 0.0, 10.0)),
            ..Default::default()
        };
        Projector::new(&cam, 100, 100)
    }

    #[test]
    fn facing_is_strict_in_both_projections() {
        let persp = projector();
        let p = DVec3::new(0.0, 0.0, -5.0);
        assert!(faces_eye(&persp, DVec3::Z, p));
        assert!(!faces_eye(&persp, -DVec3::Z, p));
        assert!(!faces_eye(&persp, DVec3::X, p), "edge-on");
        // Orthographic: the normal's z alone decides, wherever the point is.
        let ortho = ortho_projector();
        let off = DVec3::new(30.0, 0.0, -5.0);
        assert!(faces_eye(&ortho, DVec3::new(1.0, 0.0, 0.01), off));
        assert!(!faces_eye(&ortho, DVec3::new(-1.0, 0.0, 0.0), off), "edge-on");
        assert!(!faces_eye(&ortho, DVec3::new(-1.0, 0.0, -0.01), off));
        assert!(
            faces_eye(&persp, DVec3::new(-1.0, 0.0, 0.0), off),
            "the eye's direction counts in perspective"
        );
    }

    fn mesh_vertex(p: [f64; 3], n: [f32; 3], c: [f32; 3]) -> MeshVertex {
        MeshVertex {
            p: DVec3::from(p),
            n: Vec3::from(n),
            c: Vec3::from(c),
        }
    }

    fn pncs(vs: &[MeshVertex]) -> Vec<(DVec3, Vec3, Vec3)> {
        vs.iter().map(|v| (v.p, v.n, v.c)).collect()
    }

    #[test]
    fn near_clip_of_a_triangle_cuts_on_the_plane() {
        // near = 2; depths 5, 5, 1: b→c crosses at t = (2 − 5)/(1 − 5) = 3/4,
        // c→a at t = (2 − 1)/(5 − 1) = 1/4.
        let a = mesh_vertex([0.0, 0.0, -5.0], [1.0, 0.0, 0.0], [0.5, 0.0, 0.0]);
        let b = mesh_vertex([4.0, 0.0, -5.0], [0.0, 1.0, 0.0], [0.0, 0.5, 0.0]);
        let c = mesh_vertex([0.0, 4.0, -1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.5]);
        let bc = (
            DVec3::new(1.0, 3.0, -2.0),
            Vec3::new(0.0, 0.25, 0.75),
            Vec3::new(0.0, 0.125, 0.375),
        );
        let ca = (
            DVec3::new(0.0, 3.0, -2.0),
            Vec3::new(0.25, 0.0, 0.75),
            Vec3::new(0.125, 0.0, 0.375),
        );
        let (pa, pb) = ((a.p, a.n, a.c), (b.p, b.n, b.c));
        assert_eq!(pncs(&clip_triangle_near([a, b, c], 2.0)), [pa, pb, bc, ca]);
        // Two corners behind: a triangle, a→b′ cut at 3/4.
        let b2 = mesh_vertex([4.0, 0.0, -1.0], [0.0, 1.0, 0.0], [0.0, 0.5, 0.0]);
        let ab = (
            DVec3::new(3.0, 0.0, -2.0),
            Vec3::new(0.25, 0.75, 0.0),
            Vec3::new(0.125, 0.375, 0.0),
        );
        assert_eq!(pncs(&clip_triangle_near([a, b2, c], 2.0)), [pa, ab, ca]);
        // A corner on the plane is inside: nothing changes.
        let on = mesh_vertex([0.0, 4.0, -2.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.5]);
        assert_eq!(pncs(&clip_triangle_near([a, b, on], 2.0)), pncs(&[a, b, on]));
    }

    #[test]
    fn near_clip_cuts_a_shared_edge_at_one_point_from_either_side() {
        // Two triangles sharing the edge p–q (p in front of the plane, q
        // behind), each running it its own way: the cut point must be the
        // same bits in both, or the rasteriser sees two different edges.
        use crate::interp::testutil::Lcg;
        let mut rng = Lcg::new(5);
        let near = 0.37;
        let mut pt = |d: (f64, f64)| {
            let v = [rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0), -rng.uniform(d.0, d.1)];
            let mut f3 = || std::array::from_fn(|_| rng.uniform(0.0, 1.0) as f32);
            let (n, c) = (f3(), f3());
            mesh_vertex(v, n, c)
        };
        for case in 0..200 {
            let (p, q) = (pt((0.5, 4.0)), pt((0.01, 0.3)));
            let (r, s) = (pt((0.5, 4.0)), pt((0.5, 4.0)));
            // [p, q, r] → p, cut(p–q), cut(q–r), r; [q, p, s] → cut(q–p), p, s, cut(s–q).
            let one = clip_triangle_near([p, q, r], near);
            let other = clip_triangle_near([q, p, s], near);
            assert_eq!((one.len(), other.len()), (4, 4));
            assert_eq!(pncs(&one[1..2]), pncs(&other[0..1]), "case {case}");
            assert!((one[1].p.z + near).abs() < 1e-12, "case {case}: on the plane");
        }
    }

    /// A mesh of separate faces over `points`.
    fn mesh(points: Vec<DVec3>, faces: &[&[u32]]) -> MeshData {
        MeshData {
            path: "/M".into(),
            face_counts: faces.iter().map(|f| f.len() as u32).collect(),
            face_indices: faces.iter().flat_map(|f| f.iter().copied()).collect(),
            points,
            colors: Primvar::Constant(Vec3::splat(0.5)),
            left_handed: false,
            double_sided: false,
            smooth: false,
        }
    }

    /// Twice the signed area of a projected triangle, positive when it winds
    /// counter-clockwise as seen (pixel y points down).
    fn seen_area(pos: [Vec2; 3]) -> f64 {
        let [a, b, c] = pos.map(|p| p.as_dvec2());
        -(b - a).perp_dot(c - a)
    }

    fn pixel(proj: &Projector, p: DVec3) -> Vec2 {
        proj.camera_to_pixel(proj.to_camera(p)).as_vec2()
    }

    #[test]
    fn culling_keeps_the_triangles_that_wind_counter_clockwise_on_screen() {
        use crate::interp::testutil::Lcg;
        let mut rng = Lcg::new(16);
        for proj in [projector(), ortho_projector()] {
            // 300 triangles 5–15 units in front of the camera, none nearly edge-on.
            let mut points = Vec::new();
            let mut faces: Vec<[u32; 3]> = Vec::new();
            let mut tries = 0;
            while faces.len() < 300 {
                // Bounded: a projection that shrinks every triangle below a
                // pixel fails here rather than looping for ever.
                tries += 1;
                assert!(tries < 100_000, "only {} triangles a pixel wide", faces.len());
                let tri: [DVec3; 3] = std::array::from_fn(|_| {
                    DVec3::new(rng.uniform(-3.0, 3.0), rng.uniform(-3.0, 3.0), rng.uniform(-5.0, 5.0))
                });
                if seen_area(tri.map(|p| pixel(&proj, p))).abs() < 1.0 {
                    continue;
                }
                let i = points.len() as u32;
                points.extend(tri);
                faces.push([i, i + 1, i + 2]);
            }
            let face_refs: Vec<&[u32]> = faces.iter().map(|f| &f[..]).collect();
            let m = mesh(points.clone(), &face_refs);
            let seen = |f: &[u32; 3]| f.map(|i| pixel(&proj, points[i as usize]));
            let want = |ccw: bool| -> Vec<[Vec2; 3]> {
                faces
                    .iter()
                    .map(seen)
                    .filter(|&s| (seen_area(s) > 0.0) == ccw)
                    .collect()
            };
            let got = |m: &MeshData| -> Vec<[Vec2; 3]> {
                prepare_mesh(&proj, m, &Style::default())
                    .0
                    .iter()
                    .map(|t| t.pos)
                    .collect()
            };
            let front = want(true);
            assert!(front.len() > 100 && front.len() < 200, "{}", front.len());
            assert_eq!(got(&m), front);
            // Left-handed: clockwise polygons face outwards.
            assert_eq!(
                got(&MeshData {
                    left_handed: true,
                    ..m.clone()
                }),
                want(false)
            );
            assert_eq!(
                got(&MeshData {
                    double_sided: true,
                    ..m.clone()
                })
                .len(),
                300
            );
        }
    }

    #[test]
    fn silhouettes_are_the_edges_between_front_and_back_faces() {
        use crate::interp::testutil::Lcg;
        let mut rng = Lcg::new(3);
        // A 3 × 2 × 1.4 box off the origin, outward counter-clockwise quads,
        // seen by perspective cameras all around it.
        let (lo, hi) = (DVec3::new(-1.0, 0.5, -0.2), DVec3::new(2.0, 2.5, 1.2));
        let mut box_mesh = cube();
        box_mesh.points = box_mesh
            .points
            .iter()
            .map(|q| lo + (hi - lo) * (*q + DVec3::ONE) * 0.5)
            .collect();
        let centre = (lo + hi) * 0.5;
        let style = Style {
            line_width: 3.0,
            ..Style::default()
        };
        for _ in 0..40 {
            let dir = DVec3::new(rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
            if dir.length() < 0.2 {
                continue;
            }
            let eye = centre + dir.normalize() * rng.uniform(6.0, 12.0);
            let up = if dir.normalize().y.abs() > 0.9 {
                DVec3::X
            } else {
                DVec3::Y
            };
            let cam = CameraParams {
                focal_length: 35.0,
                camera_to_world: DMat4::look_at_rh(eye, centre, up).inverse(),
                ..Default::default()
            };
            let proj = Projector::new(&cam, 200, 150);
            let faces: Vec<&[u32]> = box_mesh.face_indices.chunks(4).collect();
            // Facing from the projected outline alone (shoelace area).
            let seen: Vec<bool> = faces
                .iter()
                .map(|f| {
                    let q: Vec<DVec2> = f
                        .iter()
                        .map(|&i| pixel(&proj, box_mesh.points[i as usize]).as_dvec2())
                        .collect();
                    let twice_area: f64 = (0..4).map(|k| q[k].perp_dot(q[(k + 1) % 4])).sum();
                    -twice_area > 0.0
                })
                .collect();
            let mut want = Vec::new();
            for (f, face) in faces.iter().enumerate() {
                for (g, other) in faces.iter().enumerate().skip(f + 1) {
                    let shared: Vec<u32> = face.iter().copied().filter(|i| other.contains(i)).collect();
                    if shared.len() == 2 && seen[f] != seen[g] {
                        want.push((shared[0].min(shared[1]), shared[0].max(shared[1])));
                    }
                }
            }
            want.sort();
            let (_, lines) = prepare_mesh(&proj, &box_mesh, &style);
            let vertex_at = |v: &RibbonVertex| -> u32 {
                let i = (0..8)
                    .min_by(|&a, &b| {
                        let d = |i: usize| (pixel(&proj, box_mesh.points[i]) - v.pos).length();
                        d(a).total_cmp(&d(b))
                    })
                    .unwrap();
                let depth = -proj.to_camera(box_mesh.points[i]).z;
                assert!((v.depth as f64 - depth).abs() < 1e-5, "{} {depth}", v.depth);
                assert_eq!(v.radius, 1.5);
                assert_eq!(v.pos, pixel(&proj, box_mesh.points[i]));
                i as u32
            };
            let mut got: Vec<(u32, u32)> = lines
                .iter()
                .map(|[a, b]| {
                    let (a, b) = (vertex_at(a), vertex_at(b));
                    (a.min(b), a.max(b))
                })
                .collect();
            got.sort();
            assert!(want.len() == 4 || want.len() == 6, "{want:?}");
            assert_eq!(got, want, "eye {eye}");
        }
    }

    #[test]
    fn smooth_normals_are_area_weighted_and_flat_ones_per_face() {
        // Two faces at O: t1 (normal +Z, twice-area 1) and t2 (cross
        // (1, 0, 1), twice-area √2); O and Y get (0, 0, 1) + (1, 0, 1).
        let pts = vec![
            DVec3::ZERO,
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(-1.0, 0.0, 1.0),
        ];
        let m = MeshData {
            smooth: true,
            ..mesh(pts, &[&[0, 1, 2], &[0, 2, 3]])
        };
        let shared = Vec3::new(1.0, 0.0, 2.0) / 5f32.sqrt();
        let side = Vec3::new(1.0, 0.0, 1.0) / 2f32.sqrt();
        let normals = |m: &MeshData| -> Vec<[Vec3; 3]> {
            prepare_mesh(&projector(), m, &Style::default())
                .0
                .iter()
                .map(|t| t.normal)
                .collect()
        };
        let close = |got: Vec<[Vec3; 3]>, want: [[Vec3; 3]; 2]| {
            assert_eq!(got.len(), 2);
            for (g, w) in got.iter().flatten().zip(want.iter().flatten()) {
                assert!((*g - *w).length() < 1e-6, "{got:?}");
            }
        };
        close(normals(&m), [[shared, Vec3::Z, shared], [shared, shared, side]]);
        close(
            normals(&MeshData {
                smooth: false,
                ..m.clone()
            }),
            [[Vec3::Z; 3], [side; 3]],
        );
        // Left-handed: every normal turns (both faces are then back faces).
        close(
            normals(&MeshData {
                left_handed: true,
                double_sided: true,
                ..m.clone()
            }),
            [[-shared, -Vec3::Z, -shared], [-shared, -shared, -side]],
        );
    }

    #[test]
    fn mesh_colours_follow_their_interpolation() {
        let pts = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
        ];
        let m = mesh(pts, &[&[0, 1, 2, 3], &[1, 4, 2]]);
        let c = |i: usize| Vec3::new(i as f32 / 8.0, 1.0 - i as f32 / 8.0, 0.25);
        let colours = |colors| -> Vec<[Vec3; 3]> {
            let m = MeshData { colors, ..m.clone() };
            prepare_mesh(&projector(), &m, &Style::default())
                .0
                .iter()
                .map(|t| t.color)
                .collect()
        };
        // The quad fans into (0 1 2) and (0 2 3).
        let corners = Primvar::FaceVarying((0..7).map(c).collect());
        assert_eq!(
            colours(corners),
            [[c(0), c(1), c(2)], [c(0), c(2), c(3)], [c(4), c(5), c(6)]]
        );
        let per_point = Primvar::Vertex((0..5).map(c).collect());
        assert_eq!(
            colours(per_point),
            [[c(0), c(1), c(2)], [c(0), c(2), c(3)], [c(1), c(4), c(2)]]
        );
        let per_face = Primvar::Uniform(vec![c(5), c(6)]);
        assert_eq!(colours(per_face), [[c(5); 3], [c(5); 3], [c(6); 3]]);
    }

    #[test]
    fn triangles_at_the_clipping_planes() {
        // near 1, far 100, camera at z = 10: depth d is world z = 10 − d.
        let cam = CameraParams {
            far: 100.0,
            ..Default::default()
        };
        let cam = CameraParams {
            camera_to_world: DMat4::from_translation(DVec3::new(0.0, 0.0, 10.0)),
            ..cam
        };
        let p = Projector::new(&cam, 100, 100);
        let at = |depths: [f64; 3]| {
            let pts = vec![
                DVec3::new(0.0, 0.0, 10.0 - depths[0]),
                DVec3::new(0.1, 0.0, 10.0 - depths[1]),
                DVec3::new(0.0, 0.1, 10.0 - depths[2]),
            ];
            let (tris, _) = prepare_mesh(&p, &mesh(pts, &[&[0, 1, 2]]), &Style::default());
            tris.iter().map(|t| t.depth).collect::<Vec<_>>()
        };
        assert_eq!(p.to_camera(DVec3::new(0.0, 0.0, -90.0)).z, -100.0);
        assert_eq!(at([100.0; 3]), [[100.0; 3]], "on the far plane");
        assert_eq!(at([105.0; 3]), Vec::<[f32; 3]>::new(), "beyond it");
        assert_eq!(at([105.0, 105.0, 50.0]), [[105.0, 105.0, 50.0]], "only part beyond");
        assert_eq!(at([1.0; 3]), [[1.0; 3]], "on the near plane");
        assert_eq!(at([0.5; 3]), Vec::<[f32; 3]>::new(), "before it");
    }

    #[test]
    fn an_edge_of_three_faces_pairs_its_first_two() {
        // Faces 0 (front), 1 (back) and 2 (front) share edge 0–1; the
        // silhouette test pairs the first two.
        let pts = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.5, 1.0, 0.0),
            DVec3::new(0.5, -1.0, 0.0),
            DVec3::new(0.5, -1.0, 0.1),
        ];
        let m = mesh(pts.clone(), &[&[0, 1, 2], &[0, 1, 3], &[1, 0, 4]]);
        let p = projector();
        let (_, lines) = prepare_mesh(&p, &m, &Style::default());
        let ends: Vec<[Vec2; 2]> = lines.iter().map(|l| [l[0].pos, l[1].pos]).collect();
        let edge = [pixel(&p, pts[0]), pixel(&p, pts[1])];
        assert!(ends == [edge] || ends == [[edge[1], edge[0]]], "{ends:?}");
    }

    #[test]
    fn the_scene_carries_the_projection_and_style() {
        let style = Style {
            line_color: Vec3::new(0.1, 0.2, 0.3),
            ..Style::default()
        };
        let s = build_scene(&projector(), &[], &[], &style);
        assert!(s.perspective);
        assert_eq!(s.line_color, style.line_color);
        assert_eq!(s.shading, Some(style.shading));
        assert_eq!((s.width, s.height), (100, 100));
        assert!(!build_scene(&ortho_projector(), &[], &[], &style).perspective);
    }
}
