//! Assembling a frame from projected primitives: z-buffered meshes, their
//! silhouette lines, then strokes composited back to front.
//!
//! The image is cut into 32 × 32 tiles; every primitive is binned to the
//! tiles its bounds touch (keeping draw order), and rows of tiles render in
//! parallel (rayon), each tile with its own z-buffer and scratch buffers.
//! Results do not depend on the thread count.
//!
//! Per tile:
//! 1. mesh triangles, z-buffered, shaded with [`WarmCool`] at every pixel
//!    that wins the depth test (opaque; not antialiased: silhouette lines
//!    cover the outer edges);
//! 2. silhouette lines, max-combined into one coverage mask (so joins do not
//!    darken), depth-tested against the meshes with a slope-scaled bias
//!    (the line lies on the very surface it outlines, which is seen edge-on
//!    there), composited over;
//! 3. strokes in the given order (back to front). Within one stroke, the
//!    alpha of overlapping segments is max-combined, so a stroke never
//!    blends over itself; each stroke is then composited with the
//!    premultiplied *over* operator. Stroke fragments behind the mesh
//!    z-buffer (beyond the same kind of bias) are hidden.
//!
//! Depth bias: a fragment at depth `d` over a mesh pixel at depth `z`
//! whose triangle's depth changes by `s` per pixel is visible when
//! `d ≤ z·(1 + tolerance) + s·(reach + 1)`, `reach` the fragment's distance
//! in pixels from the surface it lies on (a line's half width).
//!
//! Along a stroke or line segment, depth, colour and opacity vary linearly
//! in the scene, so on screen they are interpolated perspective-correctly
//! (1/depth linear in screen space) under a perspective camera, linearly
//! under an orthographic one ([`along_segment`]); the brush's arc length is
//! measured on screen.
//!
//! Colours are linear and premultiplied. Z is the camera depth of the
//! nearest mesh pixel or stroke fragment (alpha > 0), +∞ where empty.

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::raster::{segment_fragment, segment_rect, PixelRect, RibbonVertex, ScreenTriangle};
use super::shade::WarmCool;

/// Tile edge in pixels.
pub const TILE: usize = 32;
/// Lines and strokes pass the depth test up to this fraction behind a mesh
/// surface (plus the slope-scaled bias).
pub const DEPTH_TOLERANCE: f32 = 0.01;

/// A stroke: a run of ribbon vertices.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StrokeRibbon {
    /// Range into [`FrameScene::verts`].
    pub start: u32,
    pub end: u32,
    /// Pixel arc length of the whole stroke.
    pub length: f32,
}

/// Everything to draw in one frame, in pixel space.
#[derive(Debug, Clone, Default)]
pub struct FrameScene {
    pub width: usize,
    pub height: usize,
    /// Perspective projection (depth interpolates as 1/z).
    pub perspective: bool,
    /// Opaque mesh triangles (already back-face culled).
    pub triangles: Vec<ScreenTriangle>,
    /// Silhouette segments (round caps).
    pub lines: Vec<[RibbonVertex; 2]>,
    /// Colour of silhouette lines (linear).
    pub line_color: Vec3,
    /// Stroke vertices.
    pub verts: Vec<RibbonVertex>,
    /// Strokes in drawing order (back to front).
    pub strokes: Vec<StrokeRibbon>,
    pub shading: Option<WarmCool>,
}

/// A grayscale footprint texture, values in [0, 1].
#[derive(Debug, Clone, PartialEq)]
pub struct Brush {
    pub width: usize,
    pub height: usize,
    pub values: Vec<f32>,
}

impl Brush {
    /// Bilinear sample; `u` across the stroke, `v` along it, both in [0, 1].
    pub fn sample(&self, u: f32, v: f32) -> f32 {
        let x = (u.clamp(0.0, 1.0) * self.width as f32 - 0.5).clamp(0.0, (self.width - 1) as f32);
        let y = (v.clamp(0.0, 1.0) * self.height as f32 - 0.5).clamp(0.0, (self.height - 1) as f32);
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let at = |x: usize, y: usize| self.values[y * self.width + x];
        let top = at(x0, y0) * (1.0 - fx) + at(x1, y0) * fx;
        let bottom = at(x0, y1) * (1.0 - fx) + at(x1, y1) * fx;
        top * (1.0 - fy) + bottom * fy
    }
}

/// A rendered frame: premultiplied linear RGBA and depth, row-major, top row first.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    pub width: usize,
    pub height: usize,
    pub rgba: Vec<[f32; 4]>,
    pub z: Vec<f32>,
}

/// Premultiplied *over*: `dst = color·alpha + (1 − alpha)·dst`.
#[inline]
pub fn over(dst: &mut [f32; 4], color: Vec3, alpha: f32) {
    let k = 1.0 - alpha;
    dst[0] = color.x * alpha + k * dst[0];
    dst[1] = color.y * alpha + k * dst[1];
    dst[2] = color.z * alpha + k * dst[2];
    dst[3] = alpha + k * dst[3];
}

/// Per-tile lists of primitive indices, in input order.
struct Bins {
    tiles_x: usize,
    lists: Vec<Vec<u32>>,
}

impl Bins {
    fn new(tiles_x: usize, tiles_y: usize) -> Bins {
        Bins {
            tiles_x,
            lists: vec![Vec::new(); tiles_x * tiles_y],
        }
    }

    fn add(&mut self, index: usize, rect: &PixelRect, image: &PixelRect) {
        let Some(r) = rect.intersect(image) else {
            return;
        };
        let t = TILE as i32;
        for ty in (r.y0 / t)..=((r.y1 - 1) / t) {
            for tx in (r.x0 / t)..=((r.x1 - 1) / t) {
                self.lists[ty as usize * self.tiles_x + tx as usize].push(index as u32);
            }
        }
    }
}

/// Scratch buffers of one tile.
struct TileBuffers {
    color: Vec<[f32; 4]>,
    zmesh: Vec<f32>,
    /// Depth change per pixel of the mesh triangle seen at each pixel.
    zslope: Vec<f32>,
    zout: Vec<f32>,
    /// Per-stroke (or silhouette) alpha and colour, max-combined.
    alpha: Vec<f32>,
    tint: Vec<Vec3>,
    depth: Vec<f32>,
}

impl TileBuffers {
    fn new() -> Self {
        let n = TILE * TILE;
        TileBuffers {
            color: vec![[0.0; 4]; n],
            zmesh: vec![f32::INFINITY; n],
            zslope: vec![0.0; n],
            zout: vec![f32::INFINITY; n],
            alpha: vec![0.0; n],
            tint: vec![Vec3::ZERO; n],
            depth: vec![f32::INFINITY; n],
        }
    }

    fn reset(&mut self) {
        self.color.fill([0.0; 4]);
        self.zmesh.fill(f32::INFINITY);
        self.zslope.fill(0.0);
        self.zout.fill(f32::INFINITY);
    }

    /// Whether a fragment at `depth`, `reach` pixels from its surface, is in
    /// front of the meshes at pixel `i`.
    #[inline]
    fn visible(&self, i: usize, depth: f32, reach: f32) -> bool {
        let z = self.zmesh[i];
        z == f32::INFINITY || depth <= z * (1.0 + DEPTH_TOLERANCE) + self.zslope[i] * (reach + 1.0)
    }

    fn clear_scratch(&mut self, r: &PixelRect, tile: &PixelRect) {
        for y in r.y0..r.y1 {
            let row = (y - tile.y0) as usize * TILE;
            for x in r.x0..r.x1 {
                let i = row + (x - tile.x0) as usize;
                self.alpha[i] = 0.0;
                self.depth[i] = f32::INFINITY;
            }
        }
    }

    /// Composites the scratch layer over the tile within `r`.
    fn flush_scratch(&mut self, r: &PixelRect, tile: &PixelRect) {
        for y in r.y0..r.y1 {
            let row = (y - tile.y0) as usize * TILE;
            for x in r.x0..r.x1 {
                let i = row + (x - tile.x0) as usize;
                let a = self.alpha[i];
                if a > 0.0 {
                    over(&mut self.color[i], self.tint[i], a);
                    self.zout[i] = self.zout[i].min(self.depth[i]);
                }
            }
        }
    }
}

/// Renders a frame.
pub fn render(scene: &FrameScene, brush: Option<&Brush>) -> Frame {
    let (w, h) = (scene.width, scene.height);
    let tiles_x = w.div_ceil(TILE);
    let tiles_y = h.div_ceil(TILE);
    let image = PixelRect {
        x0: 0,
        y0: 0,
        x1: w as i32,
        y1: h as i32,
    };
    let mut tri_bins = Bins::new(tiles_x, tiles_y);
    for (i, t) in scene.triangles.iter().enumerate() {
        if let Some(r) = t.rect() {
            tri_bins.add(i, &r, &image);
        }
    }
    let mut line_bins = Bins::new(tiles_x, tiles_y);
    for (i, [a, b]) in scene.lines.iter().enumerate() {
        if let Some(r) = segment_rect(a, b) {
            line_bins.add(i, &r, &image);
        }
    }
    let mut stroke_bins = Bins::new(tiles_x, tiles_y);
    for (i, s) in scene.strokes.iter().enumerate() {
        let vs = &scene.verts[s.start as usize..s.end as usize];
        if let Some(r) = PixelRect::around(vs.iter().map(|v| (v.pos, v.radius + 0.5))) {
            stroke_bins.add(i, &r, &image);
        }
    }

    let mut rgba = vec![[0.0f32; 4]; w * h];
    let mut z = vec![f32::INFINITY; w * h];
    rgba.par_chunks_mut(TILE * w)
        .zip(z.par_chunks_mut(TILE * w))
        .enumerate()
        .for_each_init(TileBuffers::new, |buf, (ty, (rgba_band, z_band))| {
            for tx in 0..tiles_x {
                let tile = PixelRect {
                    x0: (tx * TILE) as i32,
                    y0: (ty * TILE) as i32,
                    x1: ((tx + 1) * TILE).min(w) as i32,
                    y1: ((ty + 1) * TILE).min(h) as i32,
                };
                let bin = ty * tiles_x + tx;
                buf.reset();
                draw_meshes(scene, &tri_bins.lists[bin], &tile, buf);
                draw_lines(scene, &line_bins.lists[bin], &tile, buf);
                draw_strokes(scene, &stroke_bins.lists[bin], &tile, buf, brush);
                for y in tile.y0..tile.y1 {
                    let src = (y - tile.y0) as usize * TILE;
                    let dst = (y as usize - ty * TILE) * w + tile.x0 as usize;
                    let n = (tile.x1 - tile.x0) as usize;
                    rgba_band[dst..dst + n].copy_from_slice(&buf.color[src..src + n]);
                    for k in 0..n {
                        z_band[dst + k] = buf.zout[src + k].min(buf.zmesh[src + k]);
                    }
                }
            }
        });
    Frame {
        width: w,
        height: h,
        rgba,
        z,
    }
}

/// Where the fragment a fraction `t` of the way along a projected segment
/// (on screen, from the end at depth `da` to the end at depth `db`) lies on
/// the segment in the scene: its camera depth and the fraction `s` of the
/// way in the scene, by which attributes that vary linearly along the scene
/// segment (colour, opacity) are interpolated.
///
/// Orthographic projection keeps ratios along a segment: `s = t`, and depth
/// is linear. Perspective projection does not: `1/depth` is what varies
/// linearly on screen, `1/d = (1 − t)/da + t/db`, and `s = (t/db)·d`, so the
/// near half of a receding segment takes more than half of its pixels.
/// (The pixel radius needs no such care: it is proportional to
/// width/depth, itself linear on screen, so its endpoints' values
/// interpolate linearly in `t`.)
#[inline]
fn along_segment(da: f32, db: f32, t: f32, perspective: bool) -> (f32, f32) {
    if !perspective || da == db {
        return (da + (db - da) * t, t);
    }
    let (ia, ib) = (1.0 / da, 1.0 / db);
    let inv = ia + (ib - ia) * t;
    let d = 1.0 / inv;
    (d, (t * ib * d).clamp(0.0, 1.0))
}

fn draw_meshes(scene: &FrameScene, list: &[u32], tile: &PixelRect, buf: &mut TileBuffers) {
    let shading = scene.shading.unwrap_or_default();
    for &ti in list {
        let t = &scene.triangles[ti as usize];
        let slope = t.depth_slope();
        t.raster(tile, scene.perspective, |s| {
            let i = (s.y - tile.y0) as usize * TILE + (s.x - tile.x0) as usize;
            if s.depth >= buf.zmesh[i] {
                return;
            }
            buf.zmesh[i] = s.depth;
            buf.zslope[i] = slope;
            let [a, b, c] = s.weights;
            let mut n = (t.normal[0] * a + t.normal[1] * b + t.normal[2] * c).normalize_or_zero();
            if n.z < 0.0 {
                // Seen from behind (double-sided or grazing): light the side we see.
                n = -n;
            }
            let base = t.color[0] * a + t.color[1] * b + t.color[2] * c;
            let col = shading.shade(base, n);
            buf.color[i] = [col.x, col.y, col.z, 1.0];
        });
    }
}

fn draw_lines(scene: &FrameScene, list: &[u32], tile: &PixelRect, buf: &mut TileBuffers) {
    if list.is_empty() {
        return;
    }
    buf.clear_scratch(tile, tile);
    let mut touched: Option<PixelRect> = None;
    for &li in list {
        let [a, b] = &scene.lines[li as usize];
        let Some(r) = segment_rect(a, b).and_then(|r| r.intersect(tile)) else {
            continue;
        };
        touched = Some(match touched {
            None => r,
            Some(t) => PixelRect {
                x0: t.x0.min(r.x0),
                y0: t.y0.min(r.y0),
                x1: t.x1.max(r.x1),
                y1: t.y1.max(r.y1),
            },
        });
        for y in r.y0..r.y1 {
            for x in r.x0..r.x1 {
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let Some(f) = segment_fragment(p, a, b, false, false) else {
                    continue;
                };
                let i = (y - tile.y0) as usize * TILE + (x - tile.x0) as usize;
                let (depth, _) = along_segment(a.depth, b.depth, f.t, scene.perspective);
                if !buf.visible(i, depth, a.radius) {
                    continue;
                }
                let alpha = f.coverage * a.opacity;
                if alpha > buf.alpha[i] {
                    buf.alpha[i] = alpha;
                    buf.tint[i] = scene.line_color;
                    buf.depth[i] = depth;
                }
            }
        }
    }
    if let Some(r) = touched {
        buf.flush_scratch(&r, tile);
    }
}

fn draw_strokes(scene: &FrameScene, list: &[u32], tile: &PixelRect, buf: &mut TileBuffers, brush: Option<&Brush>) {
    for &si in list {
        let s = &scene.strokes[si as usize];
        let vs = &scene.verts[s.start as usize..s.end as usize];
        let Some(r) = PixelRect::around(vs.iter().map(|v| (v.pos, v.radius + 0.5))).and_then(|r| r.intersect(tile))
        else {
            continue;
        };
        buf.clear_scratch(&r, tile);
        let nseg = vs.len().saturating_sub(1);
        // A single point is drawn as a dot (a zero-length segment).
        let count = nseg.max(1);
        for k in 0..count {
            let (ia, ib) = if nseg == 0 { (0, 0) } else { (k, k + 1) };
            let (a, b) = (&vs[ia], &vs[ib]);
            let Some(sr) = segment_rect(a, b).and_then(|q| q.intersect(&r)) else {
                continue;
            };
            let (cap_a, cap_b) = (k == 0 && nseg > 0, k + 1 == count && nseg > 0);
            for y in sr.y0..sr.y1 {
                for x in sr.x0..sr.x1 {
                    let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                    let Some(f) = segment_fragment(p, a, b, cap_a, cap_b) else {
                        continue;
                    };
                    let i = (y - tile.y0) as usize * TILE + (x - tile.x0) as usize;
                    let (depth, scene_t) = along_segment(a.depth, b.depth, f.t, scene.perspective);
                    if !buf.visible(i, depth, 0.0) {
                        continue;
                    }
                    let mut alpha = f.coverage * (a.opacity + (b.opacity - a.opacity) * scene_t);
                    if let Some(brush) = brush {
                        // The brush runs along the screen-space arc length.
                        let arc = a.arc + (b.arc - a.arc) * f.t;
                        let v = if s.length > 0.0 { arc / s.length } else { 0.5 };
                        alpha *= brush.sample(0.5 * (f.across + 1.0), v);
                    }
                    if alpha > buf.alpha[i] {
                        buf.alpha[i] = alpha;
                        buf.tint[i] = a.color + (b.color - a.color) * scene_t;
                        buf.depth[i] = depth;
                    }
                }
            }
        }
        buf.flush_scratch(&r, tile);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stroke_verts(y: f32, color: Vec3, opacity: f32) -> Vec<RibbonVertex> {
        [10.0f32, 54.0]
            .iter()
            .enumerate()
            .map(|(k, &x)| RibbonVertex {
                pos: Vec2::new(x, y),
                radius: 6.0,
                depth: 5.0,
                color,
                opacity,
                arc: 44.0 * k as f32,
            })
            .collect()
    }

    fn scene_with(strokes: &[Vec<RibbonVertex>]) -> FrameScene {
        let mut s = FrameScene {
            width: 64,
            height: 40,
            perspective: true,
            ..Default::default()
        };
        for v in strokes {
            let start = s.verts.len() as u32;
            s.verts.extend_from_slice(v);
            s.strokes.push(StrokeRibbon {
                start,
                end: s.verts.len() as u32,
                length: 44.0,
            });
        }
        s
    }

    #[test]
    fn later_strokes_go_over_earlier_ones() {
        let red = Vec3::new(1.0, 0.0, 0.0);
        let blue = Vec3::new(0.0, 0.0, 1.0);
        let px = |f: &Frame| f.rgba[20 * 64 + 32];
        // Red (opacity 0.5) drawn last, over opaque blue.
        let f = render(
            &scene_with(&[stroke_verts(20.0, blue, 1.0), stroke_verts(20.0, red, 0.5)]),
            None,
        );
        let c = px(&f);
        assert!((c[0] - 0.5).abs() < 1e-5 && (c[2] - 0.5).abs() < 1e-5 && (c[3] - 1.0).abs() < 1e-5);
        // Blue (opacity 0.5) over opaque red.
        let f = render(
            &scene_with(&[stroke_verts(20.0, red, 1.0), stroke_verts(20.0, blue, 0.5)]),
            None,
        );
        let c = px(&f);
        assert!((c[0] - 0.5).abs() < 1e-5 && (c[2] - 0.5).abs() < 1e-5);
        // Two half-transparent strokes: the top one's colour dominates.
        let f = render(
            &scene_with(&[stroke_verts(20.0, blue, 0.5), stroke_verts(20.0, red, 0.5)]),
            None,
        );
        let c = px(&f);
        assert!((c[0] - 0.5).abs() < 1e-5 && (c[2] - 0.25).abs() < 1e-5 && (c[3] - 0.75).abs() < 1e-5);
        assert_eq!(f.z[20 * 64 + 32], 5.0);
        assert_eq!(f.z[0], f32::INFINITY);
    }

    #[test]
    fn a_stroke_does_not_blend_over_itself() {
        // A stroke doubling back on itself: opacity 0.5 everywhere, not 0.75.
        let mut v = stroke_verts(20.0, Vec3::ONE, 0.5);
        let mut back = v[0];
        back.arc = 88.0;
        v.push(back);
        let f = render(&scene_with(&[v]), None);
        assert!((f.rgba[20 * 64 + 32][3] - 0.5).abs() < 1e-5);
    }

    #[test]
    fn coverage_area_survives_tiling_and_brush_modulates() {
        // A stroke crossing tile borders: total alpha = width × length.
        let f = render(&scene_with(&[stroke_verts(31.7, Vec3::ONE, 1.0)]), None);
        let area: f32 = f.rgba.iter().map(|p| p[3]).sum();
        assert!((area - 12.0 * 44.0).abs() < 1.0, "{area}");
        // A brush that is 0 on one half of the width halves the area.
        let b = Brush {
            width: 4,
            height: 1,
            values: vec![0.0, 0.0, 1.0, 1.0],
        };
        let f = render(&scene_with(&[stroke_verts(20.0, Vec3::ONE, 1.0)]), Some(&b));
        let area: f32 = f.rgba.iter().map(|p| p[3]).sum();
        assert!((area - 6.0 * 44.0).abs() < 12.0, "{area}");
    }

    /// A brush with distinct texels: 3 across (u), 4 along (v), row-major by v.
    fn brush_3x4() -> Brush {
        Brush {
            width: 3,
            height: 4,
            values: vec![0.9, 0.5, 0.3, 0.7, 1.0, 0.2, 0.4, 0.8, 0.6, 1.0, 0.3, 0.5],
        }
    }

    /// Bilinear filtering written as tent weights over texel centres
    /// ((i + ½)/w, (j + ½)/h), the lookup clamped to the edge texels.
    fn tent_sample(b: &Brush, u: f32, v: f32) -> f32 {
        let x = (u.clamp(0.0, 1.0) * b.width as f32 - 0.5).clamp(0.0, b.width as f32 - 1.0);
        let y = (v.clamp(0.0, 1.0) * b.height as f32 - 0.5).clamp(0.0, b.height as f32 - 1.0);
        let mut sum = 0.0;
        for j in 0..b.height {
            for i in 0..b.width {
                let w = (1.0 - (x - i as f32).abs()).max(0.0) * (1.0 - (y - j as f32).abs()).max(0.0);
                sum += w * b.values[j * b.width + i];
            }
        }
        sum
    }

    #[test]
    fn brush_samples_texel_centres_and_blends_between_them() {
        let b = brush_3x4();
        // At a texel centre: that texel.
        assert!((b.sample(0.5 / 3.0, 0.5 / 4.0) - 0.9).abs() < 1e-6);
        assert!((b.sample(1.5 / 3.0, 2.5 / 4.0) - 0.8).abs() < 1e-6);
        // Halfway between two centres along u, then along v: their mean.
        assert!((b.sample(1.0 / 3.0, 0.5 / 4.0) - 0.7).abs() < 1e-6);
        assert!((b.sample(2.5 / 3.0, 2.0 / 4.0) - 0.4).abs() < 1e-6);
        // Beyond the outer centres: the edge texel.
        assert!((b.sample(0.0, 0.0) - 0.9).abs() < 1e-6);
        assert!((b.sample(1.0, 1.0) - 0.5).abs() < 1e-6);
        // Anywhere: the tent-weight form.
        for (u, v) in [(0.23, 0.61), (0.77, 0.05), (0.41, 0.93), (0.6, 0.3)] {
            assert!((b.sample(u, v) - tent_sample(&b, u, v)).abs() < 1e-6, "({u}, {v})");
        }
    }

    /// Where the pixel column `x` sees the scene segment whose ends project
    /// to columns `xa`, `xb` at depths `da`, `db`, by a pinhole (column =
    /// X / depth, any scale and centre give the same answer): the ray through
    /// `x` meets the segment `(X, Z)(s) = (xa·da, da) + s·(xb·db − xa·da, db − da)`
    /// where `X(s) = x·Z(s)`. Returns (s, depth there).
    fn ray_meets_segment(xa: f64, da: f64, xb: f64, db: f64, x: f64) -> (f64, f64) {
        let (pa, pb) = (xa * da, xb * db);
        let s = (x * da - pa) / ((pb - pa) - x * (db - da));
        (s, da + s * (db - da))
    }

    #[test]
    fn stroke_attributes_follow_the_segment_and_the_brush() {
        // One segment from (10, 20) to (54, 20), radius 6: depth, opacity,
        // colour and arc length all change along it. The scene is
        // perspective: depth, opacity and colour vary linearly along the
        // segment in the scene, so on screen they follow the ray through
        // each pixel ([`ray_meets_segment`]); the brush follows the
        // screen-space arc length.
        let (red, blue) = (Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0));
        let end = |x: f32, depth: f32, opacity: f32, color: Vec3, arc: f32| RibbonVertex {
            pos: Vec2::new(x, 20.0),
            radius: 6.0,
            depth,
            color,
            opacity,
            arc,
        };
        // The segment starts 10 pixels into a 54-pixel stroke.
        let mut scene = scene_with(&[vec![end(10.0, 4.0, 0.2, red, 10.0), end(54.0, 8.0, 1.0, blue, 54.0)]]);
        scene.strokes[0].length = 54.0;
        let brush = brush_3x4();
        let plain = render(&scene, None);
        let brushed = render(&scene, Some(&brush));
        for x in [14usize, 25, 40, 49] {
            for y in [17usize, 20, 23] {
                // Pixel centre (x + ½, y + ½): inside the ribbon, away from
                // its caps, so fully covered.
                let t = (x as f32 + 0.5 - 10.0) / 44.0;
                let (s, depth) = ray_meets_segment(10.0, 4.0, 54.0, 8.0, x as f64 + 0.5);
                let (s, depth) = (s as f32, depth as f32);
                // Receding: the near end takes more than its share of pixels.
                assert!(s < t, "{s} {t}");
                let across = (y as f32 + 0.5 - 20.0) / 6.0;
                let opacity = 0.2 + 0.8 * s;
                let color = red * (1.0 - s) + blue * s;
                let i = y * 64 + x;
                for (frame, alpha) in [
                    (&plain, opacity),
                    (
                        &brushed,
                        opacity * tent_sample(&brush, 0.5 * (across + 1.0), (10.0 + 44.0 * t) / 54.0),
                    ),
                ] {
                    let c = frame.rgba[i];
                    let want = [color.x * alpha, color.y * alpha, color.z * alpha, alpha];
                    for k in 0..4 {
                        assert!((c[k] - want[k]).abs() < 1e-5, "({x}, {y}): {c:?} vs {want:?}");
                    }
                    assert!((frame.z[i] - depth).abs() < 1e-5, "({x}, {y}) z {}", frame.z[i]);
                }
            }
        }
        // Orthographic: everything linear on screen.
        scene.perspective = false;
        let f = render(&scene, None);
        for x in [14usize, 25, 40, 49] {
            let t = (x as f32 + 0.5 - 10.0) / 44.0;
            let i = 20 * 64 + x;
            let opacity = 0.2 + 0.8 * t;
            assert!((f.rgba[i][3] - opacity).abs() < 1e-5, "({x}, 20): {:?}", f.rgba[i]);
            assert!((f.rgba[i][2] - t * opacity).abs() < 1e-5, "({x}, 20): {:?}", f.rgba[i]);
            assert!((f.z[i] - (4.0 + 4.0 * t)).abs() < 1e-5, "({x}, 20) z {}", f.z[i]);
        }
    }

    #[test]
    fn a_dot_with_a_brush_samples_the_middle_of_its_length() {
        // A one-point stroke has no length: the brush is read at v = ½.
        let mut dot = stroke_verts(20.0, Vec3::ONE, 1.0);
        dot.truncate(1);
        let mut scene = scene_with(&[dot]);
        scene.strokes[0].length = 0.0;
        let brush = brush_3x4();
        let f = render(&scene, Some(&brush));
        // Pixel (10, 20): centre (10.5, 20.5), across = 0.5 / 6, fully covered.
        let want = tent_sample(&brush, 0.5 * (0.5 / 6.0 + 1.0), 0.5);
        assert!(
            (f.rgba[20 * 64 + 10][3] - want).abs() < 1e-5,
            "{:?} vs {want}",
            f.rgba[20 * 64 + 10]
        );
    }

    #[test]
    fn joins_are_round_and_alpha_ties_keep_the_earlier_segment() {
        // Three collinear points joined at a pixel centre (32.5, 20.5): the
        // join is round, so the pixel there is fully covered.
        let mut v = stroke_verts(20.5, Vec3::ONE, 1.0);
        v.insert(
            1,
            RibbonVertex {
                pos: Vec2::new(32.5, 20.5),
                arc: 22.5,
                ..v[0]
            },
        );
        let f = render(&scene_with(&[v]), None);
        assert!(
            (f.rgba[20 * 64 + 32][3] - 1.0).abs() < 1e-6,
            "{:?}",
            f.rgba[20 * 64 + 32]
        );
        // Doubling back: both segments give (32, 20) alpha 0.5; the first
        // (red, depth 5) keeps the pixel, not the way back (red to blue, depth 5 to 7).
        let mut v = stroke_verts(20.0, Vec3::X, 0.5);
        v.push(RibbonVertex {
            color: Vec3::Z,
            depth: 7.0,
            arc: 88.0,
            ..v[0]
        });
        let f = render(&scene_with(&[v]), None);
        let c = f.rgba[20 * 64 + 32];
        assert!(
            (c[0] - 0.5).abs() < 1e-6 && c[2].abs() < 1e-6 && (c[3] - 0.5).abs() < 1e-6,
            "{c:?}"
        );
        assert_eq!(f.z[20 * 64 + 32], 5.0);
    }

    #[test]
    fn a_bend_is_the_union_of_both_segments_round_ends() {
        // At a 45° bend, a pixel centre 4√2 from the join vertex lies in both
        // segments' round ends. Each filters with its own box width
        // (1 along a horizontal segment, 1/√2 along a diagonal), and the
        // larger coverage, the diagonal's, wins:
        // (6 − (4√2 − ½·(1/√2))) / (1/√2) ≈ 0.98528 against 6 − (4√2 − ½) ≈ 0.84315.
        let diagonal = (6.0 - (4.0 * 2f32.sqrt() - 0.5 / 2f32.sqrt())) * 2f32.sqrt();
        let at = |x: f32, y: f32, arc: f32| RibbonVertex {
            pos: Vec2::new(x, y),
            radius: 6.0,
            depth: 5.0,
            color: Vec3::ONE,
            opacity: 1.0,
            arc,
        };
        // Horizontal, then diagonal: the second segment's round start counts.
        let first = vec![at(10.0, 20.5, 0.0), at(32.5, 20.5, 22.5), at(50.0, 38.0, 47.2)];
        // Diagonal, then horizontal: the first segment's round end counts.
        let second = vec![at(15.0, 3.0, 0.0), at(32.5, 20.5, 24.7), at(55.0, 20.5, 47.2)];
        for (stroke, (x, y)) in [(first, (36, 16)), (second, (28, 24))] {
            let f = render(&scene_with(&[stroke]), None);
            let a = f.rgba[y * 64 + x][3];
            assert!((a - diagonal).abs() < 1e-4, "({x}, {y}): {a} vs {diagonal}");
        }
    }

    #[test]
    fn silhouette_lines_interpolate_depth_and_cover_their_rows() {
        // A horizontal line through pixel centres of row 20, radius 1,
        // opacity 0.5, depth 4 to 8 (perspective: 1/depth is linear on
        // screen); the same line again at depth 9 ties everywhere and
        // changes nothing.
        let end = |x: f32, depth: f32| RibbonVertex {
            pos: Vec2::new(x, 20.5),
            radius: 1.0,
            depth,
            color: Vec3::ZERO,
            opacity: 0.5,
            arc: 0.0,
        };
        let mut s = scene_with(&[]);
        s.line_color = Vec3::new(0.2, 0.4, 0.6);
        s.lines.push([end(4.0, 4.0), end(44.0, 8.0)]);
        s.lines.push([end(4.0, 9.0), end(44.0, 9.0)]);
        let f = render(&s, None);
        for x in [10usize, 24, 37] {
            let (_, depth) = ray_meets_segment(4.0, 4.0, 44.0, 8.0, x as f64 + 0.5);
            // Row 20 is fully covered, rows 19 and 21 half (box filter), 22 not.
            for (y, coverage) in [(19usize, 0.5), (20, 1.0), (21, 0.5), (22, 0.0)] {
                let c = f.rgba[y * 64 + x];
                let a = 0.5 * coverage;
                let want = [0.2 * a, 0.4 * a, 0.6 * a, a];
                for k in 0..4 {
                    assert!((c[k] - want[k]).abs() < 1e-5, "({x}, {y}): {c:?} vs {want:?}");
                }
            }
            assert!(
                (f.z[20 * 64 + x] - depth as f32).abs() < 1e-5,
                "z at {x}: {} vs {depth}",
                f.z[20 * 64 + x]
            );
        }
    }

    #[test]
    fn the_depth_test_allows_the_documented_bias() {
        // An orthographic mesh whose depth is 5 + 0.1·x (slope 0.1 per
        // pixel). At pixel (12, 20) it is 6.25, so a stroke passes up to
        // 6.25·1.01 + 0.1·(0 + 1) = 6.4125 and a silhouette line of radius
        // 1.5 up to 6.3125 + 0.1·(1.5 + 1) = 6.5625.
        let mesh = ScreenTriangle {
            pos: [Vec2::new(0.0, 0.0), Vec2::new(0.0, 40.0), Vec2::new(40.0, 0.0)],
            depth: [5.0, 5.0, 9.0],
            normal: [Vec3::Z; 3],
            color: [Vec3::splat(0.5); 3],
        };
        let alpha_at = |stroke_depth: Option<f32>, line_depth: Option<f32>| {
            let mut s = scene_with(&[]);
            s.perspective = false;
            s.triangles.push(mesh);
            s.shading = Some(WarmCool {
                k_a: 0.0,
                k1: 0.0,
                k3: 0.0,
                warm: Vec3::ZERO,
                cool: Vec3::ZERO,
                ..WarmCool::default()
            });
            let at = |depth: f32, radius: f32| {
                [2.0, 30.0].map(|x| RibbonVertex {
                    pos: Vec2::new(x, 20.5),
                    radius,
                    depth,
                    color: Vec3::ONE,
                    opacity: 1.0,
                    arc: x - 2.0,
                })
            };
            if let Some(d) = stroke_depth {
                s.verts.extend(at(d, 3.0));
                s.strokes.push(StrokeRibbon {
                    start: 0,
                    end: 2,
                    length: 28.0,
                });
            }
            if let Some(d) = line_depth {
                s.line_color = Vec3::ONE;
                s.lines.push(at(d, 1.5));
            }
            // The shading is black, so what shows is the stroke or line.
            render(&s, None).rgba[20 * 64 + 12][0]
        };
        assert_eq!(alpha_at(None, None), 0.0);
        assert!(alpha_at(Some(6.40), None) > 0.99);
        assert_eq!(alpha_at(Some(6.43), None), 0.0);
        assert!(alpha_at(None, Some(6.55)) > 0.99);
        assert_eq!(alpha_at(None, Some(6.575)), 0.0);
    }

    #[test]
    fn mesh_colour_and_normal_interpolate_and_back_faces_light_their_seen_side() {
        // Orthographic, so the weights at a pixel centre are its plain
        // barycentrics (area ratios).
        let pos = [Vec2::new(2.0, 2.0), Vec2::new(2.0, 38.0), Vec2::new(60.0, 2.0)];
        let color = [
            Vec3::new(0.9, 0.1, 0.1),
            Vec3::new(0.1, 0.8, 0.2),
            Vec3::new(0.2, 0.3, 0.9),
        ];
        let weights = |p: Vec2| {
            let area = |a: Vec2, b: Vec2, c: Vec2| (b - a).perp_dot(c - a);
            let whole = area(pos[0], pos[1], pos[2]);
            [
                area(p, pos[1], pos[2]) / whole,
                area(pos[0], p, pos[2]) / whole,
                area(pos[0], pos[1], p) / whole,
            ]
        };
        let shading = WarmCool::default();
        for normal in [
            // Facing the camera, tilted differently at each corner.
            [
                Vec3::new(0.3, 0.1, 1.0),
                Vec3::new(-0.2, 0.5, 0.8),
                Vec3::new(0.1, -0.4, 0.9),
            ],
            // Seen from behind: lit as its other side.
            [
                Vec3::new(0.3, 0.1, -1.0),
                Vec3::new(-0.2, 0.5, -0.8),
                Vec3::new(0.1, -0.4, -0.9),
            ],
            // Edge-on (z = 0): lit as it is, not flipped.
            [
                Vec3::new(1.0, 0.2, 0.0),
                Vec3::new(0.8, -0.3, 0.0),
                Vec3::new(0.9, 0.1, 0.0),
            ],
        ] {
            let mut s = scene_with(&[]);
            s.perspective = false;
            s.triangles.push(ScreenTriangle {
                pos,
                depth: [5.0; 3],
                normal,
                color,
            });
            let f = render(&s, None);
            for (x, y) in [(5usize, 5usize), (20, 10), (8, 30), (40, 4)] {
                let w = weights(Vec2::new(x as f32 + 0.5, y as f32 + 0.5));
                let n = (normal[0] * w[0] + normal[1] * w[1] + normal[2] * w[2]).normalize();
                let n = if n.z < 0.0 { -n } else { n };
                let want = shading.shade(color[0] * w[0] + color[1] * w[1] + color[2] * w[2], n);
                let c = f.rgba[y * 64 + x];
                assert!(
                    (Vec3::new(c[0], c[1], c[2]) - want).abs().max_element() < 1e-5,
                    "({x}, {y}): {c:?} vs {want}"
                );
            }
        }
    }

    #[test]
    fn a_stroke_on_the_last_row_of_a_whole_tile_image() {
        // 64 × 64: the stroke's box ends at the image's bottom edge, which is
        // also a tile edge; it is binned to the tiles that exist.
        let mut s = scene_with(&[stroke_verts(60.0, Vec3::ONE, 1.0)]);
        s.height = 64;
        let f = render(&s, None);
        assert!((f.rgba[63 * 64 + 32][3] - 1.0).abs() < 1e-6);
    }

    #[test]
    fn meshes_hide_strokes_behind_them() {
        let mut s = scene_with(&[stroke_verts(20.0, Vec3::X, 1.0)]);
        s.verts.iter_mut().for_each(|v| v.depth = 10.0);
        s.triangles.push(ScreenTriangle {
            pos: [Vec2::new(0.0, 0.0), Vec2::new(0.0, 40.0), Vec2::new(40.0, 0.0)],
            depth: [5.0; 3],
            normal: [Vec3::Z; 3],
            color: [Vec3::splat(0.5); 3],
        });
        let f = render(&s, None);
        // Left of the triangle's hypotenuse: the mesh (ambient 0.9·0.5 + warm term).
        let c = f.rgba[20 * 64 + 12];
        let want = WarmCool::default().shade(Vec3::splat(0.5), Vec3::Z);
        assert!((c[0] - want.x).abs() < 1e-5 && c[3] == 1.0);
        assert_eq!(f.z[20 * 64 + 12], 5.0);
        // Right of it: the stroke.
        let c = f.rgba[20 * 64 + 50];
        assert!(c[0] > 0.99 && c[1] < 1e-6);
    }
}
