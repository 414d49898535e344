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
        let inv = 1.0 / area;
        // Edge functions e_i(p) = (v_j − v_i) × (p − v_i), weights for the opposite vertex.
        let edge = |u: Vec2, v: Vec2, p: Vec2| (v - u).perp_dot(p - u);
        // Top-left-like tie break: a centre exactly on a shared edge goes to
        // one triangle only (the one for which the edge's bias is zero).
        let bias = |u: Vec2, v: Vec2| {
            let e = (v - u) * area.signum();
            if (e.y < 0.0) || (e.y == 0.0 && e.x > 0.0) {
                0.0
            } else {
                -1e-7
            }
        };
        let (ba, bb, bc) = (bias(b, c), bias(c, a), bias(a, b));
        let inv_depth = [1.0 / self.depth[0], 1.0 / self.depth[1], 1.0 / self.depth[2]];
        for y in r.y0..r.y1 {
            let py = y as f32 + 0.5;
            for x in r.x0..r.x1 {
                let p = Vec2::new(x as f32 + 0.5, py);
                let w0 = edge(b, c, p) * inv;
                let w1 = edge(c, a, p) * inv;
                let w2 = edge(a, b, p) * inv;
                if w0 + ba < 0.0 || w1 + bb < 0.0 || w2 + bc < 0.0 {
                    continue;
                }
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
}
