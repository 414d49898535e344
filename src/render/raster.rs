//! Rasterisation in pixel space: antialiased ribbon coverage for strokes and
//! silhouette lines, and z-buffered triangles.
//!
//! Pixel (i, j) covers `[i, i+1) × [j, j+1)` and is sampled at its centre.
//!
//! **Ribbon coverage** is analytic for a box filter, separably: a pixel at
//! signed distance `d` from a ribbon's centre line, where the ribbon is `r`
//! pixels from the centre line to its edge, is covered by the fraction of
//! `[d − s/2, d + s/2]` inside `[−r, r]`; at a butt cap the same fraction is
//! taken along the ribbon against `[0, L]`. The filter width
//! `s = max(|cos θ|, |sin θ|)` (θ the segment's direction) is the spacing at
//! which the pixel centres of one row or column sample that distance, which
//! makes the coverage summed over the pixels of a straight ribbon of width
//! `w` and length `L` exactly `w × L`, for any `w` (even below a pixel) and
//! any direction. Segments meet with round joins (distance to the nearer
//! segment end); a stroke's two ends get butt caps, so a stroke covers its
//! width times its length.
//!
//! **Triangles** cover the pixels whose centres they contain, watertight:
//! every edge function is computed from its endpoints in (x, y) order
//! ([`edge_function`]), so the two triangles of a shared edge agree on every
//! centre's side bit for bit, and the top-left rule gives a centre exactly
//! on the edge to one of them.

use glam::{Vec2, Vec3};

/// One projected point of a ribbon (a stroke or a line), in pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RibbonVertex {
    /// Pixel position.
    pub pos: Vec2,
    /// Half the ribbon's width here, in pixels.
    pub radius: f32,
    /// Camera depth (distance along the view axis).
    pub depth: f32,
    /// Linear colour.
    pub color: Vec3,
    /// Opacity in [0, 1].
    pub opacity: f32,
    /// Pixel arc length from the ribbon's first point.
    pub arc: f32,
}

/// What a ribbon segment leaves on one pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fragment {
    /// Coverage in [0, 1].
    pub coverage: f32,
    /// Position along the segment in [0, 1] (for attribute interpolation).
    pub t: f32,
    /// Signed position across the ribbon, −1 at one edge, 1 at the other.
    pub across: f32,
}

/// Fraction of `[c − s/2, c + s/2]` inside `[lo, hi]`.
#[inline]
pub fn box_overlap(c: f32, lo: f32, hi: f32, s: f32) -> f32 {
    (((c + 0.5 * s).min(hi) - (c - 0.5 * s).max(lo)) / s).clamp(0.0, 1.0)
}

/// Coverage of the pixel centred at `p` by the segment `a`–`b` of a ribbon.
/// `cap_a` / `cap_b`: the segment starts / ends the ribbon (butt cap there;
/// otherwise a round join).
#[inline]
pub fn segment_fragment(p: Vec2, a: &RibbonVertex, b: &RibbonVertex, cap_a: bool, cap_b: bool) -> Option<Fragment> {
    let d = b.pos - a.pos;
    let len2 = d.length_squared();
    let ap = p - a.pos;
    if len2 < 1e-12 {
        // A dot: a disc of the larger radius.
        let r = a.radius.max(b.radius);
        let dist = ap.length();
        let c = box_overlap(dist, -r, r, 1.0);
        return (c > 0.0).then_some(Fragment {
            coverage: c,
            t: 0.0,
            across: if r > 0.0 { (ap.x / r).clamp(-1.0, 1.0) } else { 0.0 },
        });
    }
    let len = len2.sqrt();
    let dir = d / len;
    // Pixel centres sample a distance measured along a unit normal `n` with
    // spacing max(|n.x|, |n.y|) per row or column; a box of that width sums
    // exactly to the covered area.
    let s = dir.x.abs().max(dir.y.abs());
    let along = ap.dot(dir);
    let perp = dir.perp_dot(ap);
    let mut cap = 1.0;
    let (t, dist) = if along < 0.0 {
        if cap_a {
            (0.0, perp.abs())
        } else {
            (0.0, ap.length())
        }
    } else if along > len {
        if cap_b {
            (1.0, perp.abs())
        } else {
            (1.0, (p - b.pos).length())
        }
    } else {
        (along / len, perp.abs())
    };
    if cap_a {
        cap *= box_overlap(along, 0.0, f32::INFINITY, s);
    }
    if cap_b {
        cap *= box_overlap(along, f32::NEG_INFINITY, len, s);
    }
    let r = a.radius + (b.radius - a.radius) * t;
    let c = box_overlap(dist, -r, r, s) * cap;
    if c <= 0.0 {
        return None;
    }
    Some(Fragment {
        coverage: c,
        t,
        across: if r > 0.0 { (perp / r).clamp(-1.0, 1.0) } else { 0.0 },
    })
}

/// Integer pixel bounds `[x0, x1) × [y0, y1)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelRect {
    pub x0: i32,
    pub y0: i32,
    pub x1: i32,
    pub y1: i32,
}

impl PixelRect {
    /// The pixels whose centres may lie within `margin` of the points' hull.
    pub fn around(points: impl Iterator<Item = (Vec2, f32)>) -> Option<PixelRect> {
        let mut lo = Vec2::splat(f32::INFINITY);
        let mut hi = Vec2::splat(f32::NEG_INFINITY);
        for (p, margin) in points {
            lo = lo.min(p - Vec2::splat(margin));
            hi = hi.max(p + Vec2::splat(margin));
        }
        if !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        // Clamp before converting so huge coordinates cannot overflow.
        let c = |v: f32| v.clamp(-1e8, 1e8);
        Some(PixelRect {
            x0: c(lo.x - 1.0).floor() as i32,
            y0: c(lo.y - 1.0).floor() as i32,
            x1: c(hi.x + 1.0).ceil() as i32 + 1,
            y1: c(hi.y + 1.0).ceil() as i32 + 1,
        })
    }

    /// The intersection, or None when empty.
    pub fn intersect(&self, o: &PixelRect) -> Option<PixelRect> {
        let r = PixelRect {
            x0: self.x0.max(o.x0),
            y0: self.y0.max(o.y0),
            x1: self.x1.min(o.x1),
            y1: self.y1.min(o.y1),
        };
        (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
    }
}

/// Pixel bounds of a ribbon segment (including its antialiased fringe).
pub fn segment_rect(a: &RibbonVertex, b: &RibbonVertex) -> Option<PixelRect> {
    PixelRect::around([(a.pos, a.radius + 0.5), (b.pos, b.radius + 0.5)].into_iter())
}

/// The edge function `(v − u) × (p − u)` of the directed edge `u → v`,
/// always computed from the endpoint that is smaller in (x, y) order and
/// negated for the other direction: the two triangles sharing an edge (which
/// run it in opposite directions) get bit-identical magnitudes, so rounding
/// cannot leave a centre on it outside both.
#[inline]
pub fn edge_function(u: Vec2, v: Vec2, p: Vec2) -> f32 {
    if u.x < v.x || (u.x == v.x && u.y <= v.y) {
        (v - u).perp_dot(p - u)
    } else {
        -(u - v).perp_dot(p - v)
    }
}

/// A projected triangle with per-corner shading inputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScreenTriangle {
    /// Pixel positions.
    pub pos: [Vec2; 3],
    /// Camera depths (> 0).
    pub depth: [f32; 3],
    /// Camera-space normals (unnormalised is fine).
    pub normal: [Vec3; 3],
    /// Linear base colours.
    pub color: [Vec3; 3],
}

/// One covered pixel of a triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleSample {
    pub x: i32,
    pub y: i32,
    pub depth: f32,
    /// Perspective-correct barycentric weights.
    pub weights: [f32; 3],
}

impl ScreenTriangle {
    /// How fast depth changes across a pixel: `|∂z/∂x| + |∂z/∂y|` of the
    /// plane through the corners (in screen space). Huge for triangles seen
    /// edge-on; used as a slope-scaled depth bias.
    pub fn depth_slope(&self) -> f32 {
        let [a, b, c] = self.pos;
        let [za, zb, zc] = self.depth;
        let area = (b - a).perp_dot(c - a);
        if area.abs() < 1e-12 {
            return f32::INFINITY;
        }
        let dzdx = ((zb - za) * (c.y - a.y) - (zc - za) * (b.y - a.y)) / area;
        let dzdy = ((zc - za) * (b.x - a.x) - (zb - za) * (c.x - a.x)) / area;
        dzdx.abs() + dzdy.abs()
    }

    /// Pixel bounds.
    pub fn rect(&self) -> Option<PixelRect> {
        PixelRect::around(self.pos.iter().map(|&p| (p, 0.0)))
    }

    /// Calls `f` for every pixel of `clip` whose centre lies inside the
    /// triangle. `perspective`: interpolate depth as 1/z (perspective
    /// projection) rather than linearly (orthographic).
    pub fn raster(&self, clip: &PixelRect, perspective: bool, mut f: impl FnMut(TriangleSample)) {
        let Some(r) = self.rect().and_then(|r| r.intersect(clip)) else {
            return;
        };
        let [a, b, c] = self.pos;
        let area = (b - a).perp_dot(c - a);
        if area.abs() < 1e-12 || !area.is_finite() {
            return;
        }
        let sign = area.signum();
        // Barycentric weight = oriented edge value / |twice the area|.
        let inv = 1.0 / area.abs();
        // Watertight: a shared edge is evaluated with its endpoints in one
        // canonical order (see `edge_function`), so its two triangles get the
        // same value, negated, and a centre on it is never missed by both.
        // Oriented so inside is positive, whatever the winding.
        let edge = |u: Vec2, v: Vec2, p: Vec2| edge_function(u, v, p) * sign;
        // Top-left rule for exact zeros: a centre exactly on an edge belongs
        // to the triangle for which that edge is a left edge (or a top edge,
        // when horizontal), so one of the two triangles draws it, not both.
        let top_left = |u: Vec2, v: Vec2| {
            let e = (v - u) * sign;
            e.y < 0.0 || (e.y == 0.0 && e.x > 0.0)
        };
        let inside = |e: f32, tl: bool| e > 0.0 || (e == 0.0 && tl);
        let (tl0, tl1, tl2) = (top_left(b, c), top_left(c, a), top_left(a, b));
        let inv_depth = [1.0 / self.depth[0], 1.0 / self.depth[1], 1.0 / self.depth[2]];
        for y in r.y0..r.y1 {
            let py = y as f32 + 0.5;
            for x in r.x0..r.x1 {
                let p = Vec2::new(x as f32 + 0.5, py);
                let (e0, e1, e2) = (edge(b, c, p), edge(c, a, p), edge(a, b, p));
                if !(inside(e0, tl0) && inside(e1, tl1) && inside(e2, tl2)) {
                    continue;
                }
                let (w0, w1, w2) = (e0 * inv, e1 * inv, e2 * inv);
                let (depth, weights) = if perspective {
                    let q = [w0 * inv_depth[0], w1 * inv_depth[1], w2 * inv_depth[2]];
                    let s = q[0] + q[1] + q[2];
                    (1.0 / s, [q[0] / s, q[1] / s, q[2] / s])
                } else {
                    (
                        w0 * self.depth[0] + w1 * self.depth[1] + w2 * self.depth[2],
                        [w0, w1, w2],
                    )
                };
                f(TriangleSample { x, y, depth, weights });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn v(x: f32, y: f32, r: f32) -> RibbonVertex {
        RibbonVertex {
            pos: Vec2::new(x, y),
            radius: r,
            depth: 1.0,
            color: Vec3::ONE,
            opacity: 1.0,
            arc: 0.0,
        }
    }

    /// Sums the max-combined coverage of a polyline ribbon over a grid.
    fn ribbon_area(pts: &[RibbonVertex], size: i32) -> f32 {
        let mut total = 0.0;
        for y in 0..size {
            for x in 0..size {
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let n = pts.len() - 1;
                let c = (0..n)
                    .filter_map(|i| segment_fragment(p, &pts[i], &pts[i + 1], i == 0, i + 1 == n))
                    .map(|f| f.coverage)
                    .fold(0.0, f32::max);
                total += c;
            }
        }
        total
    }

    #[test]
    fn straight_ribbon_covers_width_times_length() {
        // Width 6 px (radius 3), length 80 px, at an odd angle.
        let dir = Vec2::new(0.8, 0.6);
        let a = Vec2::new(20.3, 17.9);
        let b = a + dir * 80.0;
        let area = ribbon_area(&[v(a.x, a.y, 3.0), v(b.x, b.y, 3.0)], 128);
        assert!((area - 480.0).abs() / 480.0 < 0.01, "{area}");
        // The same line split into 4 collinear segments: joins add nothing.
        let pts: Vec<_> = (0..=4)
            .map(|k| {
                let p = a + dir * (20.0 * k as f32);
                v(p.x, p.y, 3.0)
            })
            .collect();
        let area4 = ribbon_area(&pts, 128);
        assert!((area4 - area).abs() < 0.5, "{area4} vs {area}");
        // Sub-pixel width: still width × length.
        let thin = ribbon_area(&[v(10.0, 10.2, 0.15), v(90.0, 50.2, 0.15)], 128);
        let want = 0.3 * (80.0f32 * 80.0 + 40.0 * 40.0).sqrt();
        assert!((thin - want).abs() / want < 0.03, "{thin} vs {want}");
    }

    #[test]
    fn fragment_interpolates_along_and_across() {
        let a = v(0.0, 0.0, 2.0);
        let b = v(10.0, 0.0, 4.0);
        let f = segment_fragment(Vec2::new(5.0, 0.0), &a, &b, true, true).unwrap();
        assert!((f.t - 0.5).abs() < 1e-6 && f.coverage == 1.0 && f.across.abs() < 1e-6);
        let f = segment_fragment(Vec2::new(5.0, 1.5), &a, &b, true, true).unwrap();
        assert!((f.across - 0.5).abs() < 1e-6);
        // Beyond a butt cap: nothing; beyond a round join: covered.
        assert!(segment_fragment(Vec2::new(-1.5, 0.0), &a, &b, true, true).is_none());
        assert!(segment_fragment(Vec2::new(-1.5, 0.0), &a, &b, false, true).is_some());
    }

    #[test]
    fn triangle_pixels_and_shared_edges() {
        let t = |p: [Vec2; 3]| ScreenTriangle {
            pos: p,
            depth: [1.0, 2.0, 3.0],
            normal: [Vec3::Z; 3],
            color: [Vec3::ONE; 3],
        };
        let (a, b, c, d) = (
            Vec2::new(0.0, 0.0),
            Vec2::new(16.0, 0.0),
            Vec2::new(16.0, 16.0),
            Vec2::new(0.0, 16.0),
        );
        let clip = PixelRect {
            x0: 0,
            y0: 0,
            x1: 32,
            y1: 32,
        };
        let mut count = vec![0u8; 32 * 32];
        for tri in [t([a, b, c]), t([a, c, d])] {
            tri.raster(&clip, true, |s| count[(s.y * 32 + s.x) as usize] += 1);
        }
        // A 16 × 16 square: every pixel exactly once.
        assert_eq!(count.iter().filter(|&&c| c == 1).count(), 256);
        assert!(count.iter().all(|&c| c <= 1));
        // Perspective depth at a corner-ish pixel lies between the corner depths.
        let mut seen = None;
        t([a, b, c]).raster(&clip, true, |s| {
            if s.x == 15 && s.y == 1 {
                seen = Some(s);
            }
        });
        let s = seen.unwrap();
        assert!(s.depth > 1.0 && s.depth < 3.0);
        // Depth 1 → 2 over 16 px in x, 2 → 3 over 16 px in y.
        assert!((t([a, b, c]).depth_slope() - 2.0 / 16.0).abs() < 1e-6);
        assert!((s.weights.iter().sum::<f32>() - 1.0).abs() < 1e-5);
    }

    // Exact values derived by hand from the module's formulas, and the
    // triangle rasteriser against an independent f64 inside test.

    #[test]
    fn box_overlap_is_the_covered_fraction() {
        assert_eq!(box_overlap(0.0, -1.0, 1.0, 1.0), 1.0);
        assert_eq!(box_overlap(1.0, -1.0, 1.0, 1.0), 0.5);
        assert_eq!(box_overlap(1.25, -1.0, 1.0, 1.0), 0.25);
        assert_eq!(box_overlap(-1.25, -1.0, 1.0, 1.0), 0.25);
        assert_eq!(box_overlap(2.0, -1.0, 1.0, 1.0), 0.0);
        // A box of width 0.5 centred at 0.9: [0.65, 1.15] ∩ [−1, 1] = 0.35 long.
        assert!((box_overlap(0.9, -1.0, 1.0, 0.5) - 0.7).abs() < 1e-6);
        // Wider than the interval: at most the interval's share.
        assert_eq!(box_overlap(0.0, -0.25, 0.25, 1.0), 0.5);
    }

    #[test]
    fn a_dot_is_a_disc_of_the_larger_radius() {
        let (a, b) = (v(10.0, 10.0, 1.0), v(10.0, 10.0, 2.5));
        let at = |x: f32, y: f32| segment_fragment(Vec2::new(x, y), &a, &b, true, true);
        // Distance 2: the box [1.5, 2.5] lies inside the radius.
        let f = at(12.0, 10.0).unwrap();
        assert_eq!((f.coverage, f.t, f.across), (1.0, 0.0, 0.8));
        // Distance 2.5 (on the rim, left of the centre): half.
        let f = at(10.0 - 1.5, 10.0 + 2.0).unwrap();
        assert_eq!((f.coverage, f.across), (0.5, -0.6));
        assert!(at(13.1, 10.0).is_none());
        // Radius 0: an interval of length 0 covers nothing.
        let z = v(10.0, 10.0, 0.0);
        assert!(segment_fragment(Vec2::new(10.25, 10.0), &z, &z, true, true).is_none());
    }

    #[test]
    fn segments_shorter_than_a_millionth_of_a_pixel_are_dots() {
        // 1e-6 is exact enough in f32 that its square is the threshold 1e-12:
        // from there on the capped segment covers its length (nothing here),
        // below it a dot covers its disc.
        let a = v(0.0, 0.0, 2.0);
        assert_eq!(1e-6f32 * 1e-6f32, 1e-12f32);
        let at = |len: f32| segment_fragment(Vec2::new(1.0, 0.0), &a, &v(len, 0.0, 2.0), true, true);
        assert_eq!(at(1e-6), None);
        assert_eq!(at(0.99e-6).map(|f| f.coverage), Some(1.0));
    }

    #[test]
    fn a_segment_covers_by_distance_with_caps_and_joins() {
        // Horizontal, from x = 0 to 10, radius 2 → 4: r(t) = 2 + 2t.
        let (a, b) = (v(0.0, 0.0, 2.0), v(10.0, 0.0, 4.0));
        let at = |x: f32, y: f32, ca: bool, cb: bool| segment_fragment(Vec2::new(x, y), &a, &b, ca, cb);
        // Middle, r = 3: a pixel centred 3 off is half covered; across = ±1.
        let f = at(5.0, 3.0, true, true).unwrap();
        assert_eq!((f.coverage, f.t, f.across), (0.5, 0.5, 1.0));
        let f = at(5.0, -2.25, true, true).unwrap();
        assert_eq!((f.coverage, f.across), (1.0, -0.75));
        let f = at(2.5, 2.0, true, true).unwrap();
        assert_eq!((f.coverage, f.t, f.across), (1.0, 0.25, 0.8));
        // Butt cap at a: a pixel centred 0.25 before it is a quarter covered.
        let f = at(-0.25, 1.0, true, true).unwrap();
        assert_eq!((f.coverage, f.t), (0.25, 0.0));
        // A round join instead: distance to a itself, √(0.25² + 1²) < 2.
        let f = at(-0.25, 1.0, false, true).unwrap();
        assert_eq!((f.coverage, f.t), (1.0, 0.0));
        let f = at(-1.5, 1.5, false, true).unwrap();
        let d = (1.5f32 * 1.5 * 2.0).sqrt();
        // r = 2 at a: the box [d − 0.5, d + 0.5] overlaps [−2, 2] by 2 − (d − 0.5).
        assert!((f.coverage - (2.0 - (d - 0.5))).abs() < 1e-6, "{f:?}");
        // Butt cap at b: 0.25 past it.
        let f = at(10.25, -1.0, true, true).unwrap();
        assert_eq!((f.coverage, f.t), (0.25, 1.0));
        let f = at(11.0, 0.0, true, false).unwrap();
        assert_eq!((f.coverage, f.t), (1.0, 1.0));
        assert!(at(11.0, 0.0, true, true).is_none());
        assert!(at(5.0, 3.6, true, true).is_none());
        // Direction (0.8, 0.6): rows sample the distance every 0.8, the box
        // is 0.8 wide; a centre 2.9 from the line with r = 3 is
        // (3 − 2.5) / 0.8 covered.
        let (c, d) = (v(0.0, 0.0, 3.0), v(40.0, 30.0, 3.0));
        let n = Vec2::new(-0.6, 0.8);
        let p = Vec2::new(20.0, 15.0) + n * 2.9;
        let f = segment_fragment(p, &c, &d, true, true).unwrap();
        assert!((f.coverage - 0.625).abs() < 1e-5, "{f:?}");
        assert!((f.across - 2.9 / 3.0).abs() < 1e-5 && (f.t - 0.5).abs() < 1e-6);
        // Its cap: 0.2 before c along the line, 0.2 / 0.8 of the box.
        let p = Vec2::new(0.8, 0.6) * -0.2;
        let f = segment_fragment(p, &c, &d, true, true).unwrap();
        assert!((f.coverage - 0.25).abs() < 1e-5, "{f:?}");
        let p = Vec2::new(40.0, 30.0) + Vec2::new(0.8, 0.6) * 0.2;
        let f = segment_fragment(p, &c, &d, true, true).unwrap();
        assert!((f.coverage - 0.25).abs() < 1e-5, "{f:?}");
    }

    #[test]
    fn pixel_rects_round_outwards_and_intersect() {
        let r = PixelRect::around([(Vec2::new(10.2, 20.7), 1.0), (Vec2::new(15.5, 22.1), 0.5)].into_iter());
        // Hull with margins: [9.2, 16.0] × [19.7, 22.6], one more pixel each way.
        let want = PixelRect {
            x0: 8,
            y0: 18,
            x1: 18,
            y1: 25,
        };
        assert_eq!(r, Some(want));
        assert_eq!(PixelRect::around([(Vec2::new(f32::NAN, 0.0), 1.0)].into_iter()), None);
        assert_eq!(PixelRect::around(std::iter::empty()), None);
        // One end finite, the other not: still no rect.
        let half = [(Vec2::ZERO, 1.0), (Vec2::new(f32::INFINITY, 0.0), 1.0)];
        assert_eq!(PixelRect::around(half.into_iter()), None);
        let huge = PixelRect::around([(Vec2::new(-1e30, 1e30), 0.0)].into_iter()).unwrap();
        // Clamped to ±1e8 (exact in f32) before the floor and ceil.
        assert_eq!((huge.x0, huge.y1), (-100_000_000, 100_000_001));
        let seg = segment_rect(&v(10.2, 20.7, 0.5), &v(15.5, 22.1, 0.0)).unwrap();
        assert_eq!(seg, want);
        // Each end's own radius (+ half a pixel of fringe): b reaches 4.5 px.
        let seg = segment_rect(&v(10.2, 20.7, 0.5), &v(15.5, 22.1, 4.0)).unwrap();
        assert_eq!((seg.x0, seg.y0, seg.x1, seg.y1), (8, 16, 22, 29));
        let o = PixelRect {
            x0: 12,
            y0: 0,
            x1: 40,
            y1: 20,
        };
        let both = PixelRect {
            x0: 12,
            y0: 18,
            x1: 18,
            y1: 20,
        };
        assert_eq!(want.intersect(&o), Some(both));
        assert_eq!(o.intersect(&want), Some(both));
        let touching = PixelRect { x0: 18, ..o };
        assert_eq!(want.intersect(&touching), None);
        let below = PixelRect { y1: 18, ..o };
        assert_eq!(want.intersect(&below), None);
    }

    fn tri(pos: [Vec2; 3], depth: [f32; 3]) -> ScreenTriangle {
        ScreenTriangle {
            pos,
            depth,
            normal: [Vec3::Z; 3],
            color: [Vec3::ONE; 3],
        }
    }

    #[test]
    fn depth_slope_is_the_planes_gradient() {
        // z = 0.5 + 0.25 x − 0.125 y at three general corners.
        let z = |p: Vec2| 0.5 + 0.25 * p.x - 0.125 * p.y;
        let pos = [Vec2::new(1.0, 2.0), Vec2::new(7.0, 3.0), Vec2::new(2.0, 9.0)];
        assert!((tri(pos, pos.map(z)).depth_slope() - 0.375).abs() < 1e-6);
        let z = |p: Vec2| 4.0 - 0.5 * p.x + 0.75 * p.y;
        let rev = [pos[0], pos[2], pos[1]];
        assert!((tri(rev, rev.map(z)).depth_slope() - 1.25).abs() < 1e-6);
        let flat = [Vec2::ZERO, Vec2::ONE, Vec2::splat(2.0)];
        assert_eq!(tri(flat, [1.0; 3]).depth_slope(), f32::INFINITY);
        // Twice-area exactly 1e-12 (1e-6 squared in f32) is not degenerate yet:
        // depth 0 → 1e-6 over 1e-6 px in x, 0 in y.
        let tiny = [Vec2::ZERO, Vec2::new(1e-6, 0.0), Vec2::new(0.0, 1e-6)];
        assert!((tri(tiny, [0.0, 1e-6, 0.0]).depth_slope() - 1.0).abs() < 1e-3);
    }

    #[test]
    fn triangles_cover_the_pixel_centres_inside_them() {
        use crate::interp::testutil::Lcg;
        let mut rng = Lcg::new(7);
        let clip = PixelRect {
            x0: 0,
            y0: 0,
            x1: 40,
            y1: 30,
        };
        for case in 0..200 {
            let pos: [Vec2; 3] =
                std::array::from_fn(|_| Vec2::new(rng.uniform(-10.0, 50.0) as f32, rng.uniform(-10.0, 40.0) as f32));
            let depth: [f32; 3] = std::array::from_fn(|_| rng.uniform(1.0, 20.0) as f32);
            let t = tri(pos, depth);
            // Independent: f64 edge functions, sign-normalised.
            let [a, b, c] = pos.map(|p| p.as_dvec2());
            let area = (b - a).perp_dot(c - a);
            if area.abs() < 1.0 {
                continue;
            }
            let inside = |x: i32, y: i32| -> Option<bool> {
                let p = glam::DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                let e = [(b, c), (c, a), (a, b)].map(|(u, w)| (w - u).perp_dot(p - u) / area);
                if e.iter().any(|v| v.abs() < 1e-4) {
                    return None; // on an edge: either answer
                }
                Some(e.iter().all(|&v| v > 0.0))
            };
            for perspective in [false, true] {
                let mut got = vec![None; 40 * 30];
                t.raster(&clip, perspective, |s| {
                    assert!(s.x >= 0 && s.x < 40 && s.y >= 0 && s.y < 30, "{s:?} outside the clip");
                    assert!(got[(s.y * 40 + s.x) as usize].is_none(), "a pixel twice");
                    got[(s.y * 40 + s.x) as usize] = Some(s);
                });
                for y in 0..30 {
                    for x in 0..40 {
                        let s = got[(y * 40 + x) as usize];
                        match inside(x, y) {
                            Some(want) => assert_eq!(s.is_some(), want, "case {case} pixel {x},{y}"),
                            None => continue,
                        }
                        let Some(s) = s else { continue };
                        // Screen barycentrics of the centre, then the depth and
                        // weights each projection implies.
                        let p = glam::DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                        let w = [(b, c), (c, a), (a, b)].map(|(u, v)| (v - u).perp_dot(p - u) / area);
                        let z = depth.map(f64::from);
                        let (want_depth, want_w) = if perspective {
                            let q = [w[0] / z[0], w[1] / z[1], w[2] / z[2]];
                            let sum = q[0] + q[1] + q[2];
                            (1.0 / sum, q.map(|v| v / sum))
                        } else {
                            (w[0] * z[0] + w[1] * z[1] + w[2] * z[2], w)
                        };
                        assert!(
                            (s.depth as f64 - want_depth).abs() < 1e-3,
                            "case {case}: {} vs {want_depth}",
                            s.depth
                        );
                        for k in 0..3 {
                            assert!(
                                (s.weights[k] as f64 - want_w[k]).abs() < 1e-4,
                                "case {case}: {s:?} vs {want_w:?}"
                            );
                        }
                    }
                }
            }
        }
    }

    /// Where `p` lies against the simple polygon `outline` (f64, independent
    /// of the rasteriser): Some(true) strictly inside, Some(false) strictly
    /// outside, None within 1e-3 px of its boundary (either answer).
    fn against_outline(p: glam::DVec2, outline: &[glam::DVec2]) -> Option<bool> {
        let n = outline.len();
        let mut inside = false;
        for k in 0..n {
            let (u, v) = (outline[k], outline[(k + 1) % n]);
            let d = v - u;
            let t = ((p - u).dot(d) / d.length_squared()).clamp(0.0, 1.0);
            if (u + d * t - p).length() < 1e-3 {
                return None;
            }
            // Crossing number along +x.
            if (u.y > p.y) != (v.y > p.y) && p.x < u.x + (p.y - u.y) / (v.y - u.y) * d.x {
                inside = !inside;
            }
        }
        Some(inside)
    }

    /// Rasterises `tris` with each triangle in the winding and first corner
    /// `order(index)` gives, and checks every pixel centre of `clip` against
    /// the union's `outline`: covered exactly once strictly inside, never
    /// strictly outside, at most once on the boundary.
    fn assert_union_covered_once(
        tris: &[[Vec2; 3]],
        outline: &[glam::DVec2],
        clip: PixelRect,
        order: impl Fn(usize) -> (bool, usize),
        what: &str,
    ) {
        let w = (clip.x1 - clip.x0) as usize;
        let mut count = vec![0u8; w * (clip.y1 - clip.y0) as usize];
        for (k, &corners) in tris.iter().enumerate() {
            let (clockwise, first) = order(k);
            let mut c = corners;
            if clockwise {
                c.swap(1, 2);
            }
            c.rotate_left(first);
            tri(c, [1.0; 3]).raster(&clip, false, |s| {
                count[(s.y - clip.y0) as usize * w + (s.x - clip.x0) as usize] += 1;
            });
        }
        for y in clip.y0..clip.y1 {
            for x in clip.x0..clip.x1 {
                let n = count[(y - clip.y0) as usize * w + (x - clip.x0) as usize];
                let p = glam::DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                match against_outline(p, outline) {
                    Some(true) => assert_eq!(n, 1, "{what}: pixel {x},{y} inside the union"),
                    Some(false) => assert_eq!(n, 0, "{what}: pixel {x},{y} outside the union"),
                    None => assert!(n <= 1, "{what}: pixel {x},{y} on the boundary drawn {n} times"),
                }
            }
        }
    }

    #[test]
    fn shared_edges_through_pixel_centres_leave_no_cracks() {
        use crate::interp::testutil::Lcg;
        let all_orders: Vec<(bool, usize)> = [false, true]
            .into_iter()
            .flat_map(|cw| (0..3).map(move |first| (cw, first)))
            .collect();
        let f32s = |p: glam::DVec2| p.as_vec2();

        // The bug report's quad: corners (±1, ±1) at depth 12 through a
        // 50 mm lens on a 36 × 24 aperture, i.e. the window x ∈ ±0.36,
        // y ∈ ±0.24 one unit out, W / 0.72 pixels per unit on a W × 2W/3
        // image. Its centre (W/2, W/3) has x ± y whole, so both diagonals
        // run through pixel centres.
        for width in [360u32, 480, 720, 1200] {
            let scale = width as f64 / 0.72;
            let px = |x: f64, y: f64| glam::DVec2::new((x / 12.0 + 0.36) * scale, (0.24 - y / 12.0) * scale);
            let quad = [px(-1.0, -1.0), px(1.0, -1.0), px(1.0, 1.0), px(-1.0, 1.0)];
            // The quad's pixels and a margin (the rest of the image is empty).
            let q = quad.map(f32s);
            let clip = PixelRect::around(q.iter().map(|&p| (p, 2.0))).unwrap();
            for (diagonal, tris) in [
                ("0-2", [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]),
                ("1-3", [[q[1], q[2], q[3]], [q[1], q[3], q[0]]]),
            ] {
                for &o0 in &all_orders {
                    for &o1 in &all_orders {
                        let what = format!("quad at {width} px, diagonal {diagonal}, orders {o0:?} {o1:?}");
                        let order = |k: usize| if k == 0 { o0 } else { o1 };
                        assert_union_covered_once(&tris, &quad, clip, order, &what);
                    }
                }
            }
        }

        // Random pairs: the shared edge A–B lies on a line of pixel centres
        // c + j·(p, q), its ends at fractional steps along it (so they round
        // in f32), C and D on either side of it.
        let mut rng = Lcg::new(11);
        let clip = PixelRect {
            x0: -4,
            y0: -4,
            x1: 68,
            y1: 68,
        };
        for case in 0..300 {
            let c = glam::DVec2::new(rng.below(24) as f64 + 20.5, rng.below(24) as f64 + 20.5);
            let dir = loop {
                let d = glam::DVec2::new(rng.below(7) as f64 - 3.0, rng.below(7) as f64 - 3.0);
                if d != glam::DVec2::ZERO {
                    break d;
                }
            };
            let (a, b) = (c + dir * rng.uniform(-6.0, -0.5), c + dir * rng.uniform(0.5, 6.0));
            let mid = (a + b) * 0.5;
            let n = dir.perp().normalize();
            let along = (b - a).normalize();
            let side = |rng: &mut Lcg, s: f64| mid + n * (s * rng.uniform(2.0, 15.0)) + along * rng.uniform(-8.0, 8.0);
            let (cc, d) = (side(&mut rng, 1.0), side(&mut rng, -1.0));
            let outline = [a, cc, b, d];
            let tris = [[a, b, cc].map(f32s), [b, a, d].map(f32s)];
            let (o0, o1) = (all_orders[rng.below(6)], all_orders[rng.below(6)]);
            let order = |k: usize| if k == 0 { o0 } else { o1 };
            assert_union_covered_once(&tris, &outline, clip, order, &format!("pair {case}"));
        }

        // Random fans round a vertex on a pixel centre: every spoke runs
        // through pixel centres, the vertex itself is on all of them.
        let dirs = [
            (1.0, 0.0),
            (3.0, 1.0),
            (2.0, 1.0),
            (1.0, 1.0),
            (1.0, 2.0),
            (0.0, 1.0),
            (-1.0, 3.0),
            (-1.0, 1.0),
            (-2.0, 1.0),
            (-1.0, 0.0),
            (-3.0, -2.0),
            (-1.0, -1.0),
            (-1.0, -3.0),
            (0.0, -1.0),
            (1.0, -2.0),
            (1.0, -1.0),
            (2.0, -1.0),
        ];
        for case in 0..200 {
            let v = glam::DVec2::new(rng.below(8) as f64 + 28.5, rng.below(8) as f64 + 28.5);
            // A random subset of the directions, no two consecutive more
            // than half a turn apart (every fourth kept at least).
            let mut ring = Vec::new();
            for (k, &(x, y)) in dirs.iter().enumerate() {
                if k % 4 == 0 || rng.below(2) == 0 {
                    let d = glam::DVec2::new(x, y);
                    ring.push(v + d * (rng.uniform(6.0, 20.0) / d.length()));
                }
            }
            let tris: Vec<[Vec2; 3]> = (0..ring.len())
                .map(|k| [v, ring[k], ring[(k + 1) % ring.len()]].map(f32s))
                .collect();
            let orders: Vec<(bool, usize)> = tris.iter().map(|_| all_orders[rng.below(6)]).collect();
            assert_union_covered_once(&tris, &ring, clip, |k| orders[k], &format!("fan {case}"));
        }
    }

    #[test]
    fn edges_through_pixel_centres_go_to_one_triangle_either_winding() {
        // A 16 × 12 rectangle cut at x = 8.5 and y = 6.5 (lines of pixel
        // centres) into four quads, each split by a diagonal, in both
        // windings and with each corner first (so every edge is once the
        // b–c, c–a and a–b of its triangle): every pixel exactly once.
        let xs = [0.0, 8.5, 16.0];
        let ys = [0.0, 6.5, 12.0];
        let clip = PixelRect {
            x0: -2,
            y0: -2,
            x1: 20,
            y1: 16,
        };
        // Each triangle in both windings and with each corner first.
        let orders = || {
            [false, true]
                .into_iter()
                .flat_map(|cw| (0..3).map(move |first| (cw, first)))
        };
        let reorder = |mut corners: [Vec2; 3], clockwise: bool, first: usize| {
            if clockwise {
                corners.swap(1, 2);
            }
            corners.rotate_left(first);
            corners
        };
        for (clockwise, first) in orders() {
            let mut count = vec![0u8; 22 * 18];
            for i in 0..2 {
                for j in 0..2 {
                    let (p00, p10) = (Vec2::new(xs[i], ys[j]), Vec2::new(xs[i + 1], ys[j]));
                    let (p11, p01) = (Vec2::new(xs[i + 1], ys[j + 1]), Vec2::new(xs[i], ys[j + 1]));
                    for corners in [[p00, p10, p11], [p00, p11, p01]] {
                        tri(reorder(corners, clockwise, first), [1.0; 3]).raster(&clip, false, |s| {
                            count[((s.y + 2) * 22 + s.x + 2) as usize] += 1;
                        });
                    }
                }
            }
            for y in -2..16 {
                for x in -2..20 {
                    let want = u8::from((0..16).contains(&x) && (0..12).contains(&y));
                    assert_eq!(
                        count[((y + 2) * 22 + x + 2) as usize],
                        want,
                        "pixel {x},{y} clockwise {clockwise} first corner {first}"
                    );
                }
            }
        }
        // Which triangle gets a shared edge's centres is the top-left rule
        // (y down): a vertical edge goes to the triangle right of it (its
        // left edge), a horizontal one to the triangle below it (its top
        // edge), whatever the winding and first corner.
        let owner = |left_or_top: [Vec2; 3], right_or_bottom: [Vec2; 3], on_edge: &dyn Fn(i32, i32) -> bool| {
            let mut seen = [0usize; 2];
            for (clockwise, first) in orders() {
                for (side, corners) in [left_or_top, right_or_bottom].into_iter().enumerate() {
                    tri(reorder(corners, clockwise, first), [1.0; 3]).raster(&clip, false, |s| {
                        if on_edge(s.x, s.y) {
                            seen[side] += 1;
                        }
                    });
                }
            }
            seen
        };
        let (top, bottom) = (Vec2::new(8.5, 0.0), Vec2::new(8.5, 12.0));
        let seen = owner(
            [Vec2::new(0.0, 0.0), top, bottom],
            [top, Vec2::new(16.0, 0.0), bottom],
            &|x, _| x == 8,
        );
        assert_eq!(seen, [0, 6 * 12], "centres on x = 8.5 (left, right)");
        let (left, right) = (Vec2::new(0.0, 6.5), Vec2::new(16.0, 6.5));
        let seen = owner(
            [Vec2::new(0.0, 0.0), right, left],
            [left, right, Vec2::new(0.0, 13.0)],
            &|_, y| y == 6,
        );
        // The edge runs from x = 0 to 16: all 16 centres of the row, 6 times.
        assert_eq!(seen, [0, 6 * 16], "centres on y = 6.5 (above, below)");
        // Degenerate and non-finite triangles draw nothing.
        let mut n = 0;
        tri([Vec2::ZERO, Vec2::splat(5.0), Vec2::splat(10.0)], [1.0; 3]).raster(&clip, true, |_| n += 1);
        tri([Vec2::ZERO, Vec2::new(f32::INFINITY, 0.0), Vec2::splat(10.0)], [1.0; 3]).raster(&clip, true, |_| n += 1);
        assert_eq!(n, 0);
    }
}
