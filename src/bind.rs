//! Binding stroke points to the proxy: closest point on the rest triangles.
//!
//! Bassett §3.2: "simply associating each stroke with the closest geometric
//! primitive of the mesh has proven to be sufficient"; the barycentric
//! coordinates of the closest point are the skinning weights. A BVH
//! (parry's `TriMesh`) finds the closest triangle; the barycentrics are then
//! recomputed here in f64 with clamping so degenerate triangles cannot produce
//! NaNs.

use glam::{DVec3, Vec3};
use parry3d_f64::math::Point;
use parry3d_f64::query::PointQueryWithLocation;
use parry3d_f64::shape::TriMesh;

/// Per stroke point: its triangle's three proxy vertices and weights.
///
/// This is the flat "stencil table" of the bake: computed once, applied to the
/// per-vertex motions of every frame.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Binding {
    /// The three proxy vertex indices of each point's bound triangle.
    pub vertices: Vec<[u32; 3]>,
    /// Barycentric weights (non-negative, summing to 1) of each point.
    pub weights: Vec<[f32; 3]>,
}

impl Binding {
    /// Number of bound points.
    pub fn len(&self) -> usize {
        self.vertices.len()
    }

    /// True when no points are bound.
    pub fn is_empty(&self) -> bool {
        self.vertices.is_empty()
    }
}

/// A BVH over the rest-pose triangles, built once per proxy.
pub struct ClosestPoint {
    mesh: TriMesh,
    points: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
}

impl ClosestPoint {
    /// Builds the BVH. `triangles` must be non-empty and index into `points`
    /// (callers validate: parry asserts on an empty mesh).
    pub fn new(points: &[DVec3], triangles: &[[u32; 3]]) -> Self {
        let verts = points.iter().map(|p| Point::new(p.x, p.y, p.z)).collect();
        ClosestPoint {
            mesh: TriMesh::new(verts, triangles.to_vec()),
            points: points.to_vec(),
            triangles: triangles.to_vec(),
        }
    }

    /// Closest point on the triangle set: (triangle index, clamped barycentrics).
    pub fn query(&self, p: DVec3) -> (usize, [f64; 3]) {
        let (_, (tri, _)) = self
            .mesh
            .project_local_point_and_get_location(&Point::new(p.x, p.y, p.z), false);
        let [a, b, c] = self.triangles[tri as usize];
        let w = closest_point_barycentric(
            p,
            self.points[a as usize],
            self.points[b as usize],
            self.points[c as usize],
        );
        (tri as usize, w)
    }

    /// Binds every point (must be finite) to its closest triangle.
    pub fn bind(&self, points: &[Vec3]) -> Binding {
        use rayon::prelude::*;
        let (vertices, weights) = points
            .par_iter()
            .map(|p| {
                let (tri, w) = self.query(p.as_dvec3());
                (self.triangles[tri], [w[0] as f32, w[1] as f32, w[2] as f32])
            })
            .unzip();
        Binding { vertices, weights }
    }
}

/// Barycentric coordinates of the point of triangle (a, b, c) closest to `p`.
///
/// Region-based closest point (vertex, edge or face region), so the result is
/// clamped to the triangle. A degenerate triangle falls back to its closest
/// edge or vertex.
pub fn closest_point_barycentric(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> [f64; 3] {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return [0.0, 1.0, 0.0];
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return [1.0 - v, v, 0.0];
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return [0.0, 0.0, 1.0];
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return [1.0 - w, 0.0, w];
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return [0.0, 1.0 - w, w];
    }
    let denom = va + vb + vc;
    if denom.abs() <= f64::MIN_POSITIVE || !denom.is_finite() {
        // Degenerate (collinear) triangle: best of its three edges.
        return degenerate_barycentric(p, a, b, c);
    }
    let v = vb / denom;
    let w = vc / denom;
    [1.0 - v - w, v, w]
}

fn degenerate_barycentric(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> [f64; 3] {
    let seg = |x: DVec3, y: DVec3| {
        let d = y - x;
        let len2 = d.length_squared();
        let t = if len2 > 0.0 {
            ((p - x).dot(d) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (t, (x + d * t - p).length_squared())
    };
    let (t0, e0) = seg(a, b);
    let (t1, e1) = seg(b, c);
    let (t2, e2) = seg(a, c);
    if e0 <= e1 && e0 <= e2 {
        [1.0 - t0, t0, 0.0]
    } else if e1 <= e2 {
        [0.0, 1.0 - t1, t1]
    } else {
        [1.0 - t2, 0.0, t2]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> (DVec3, DVec3, DVec3) {
        (DVec3::ZERO, DVec3::X, DVec3::Y)
    }

    #[test]
    fn interior_point_projects_to_its_barycentrics() {
        let (a, b, c) = tri();
        let w = closest_point_barycentric(DVec3::new(0.25, 0.5, 3.0), a, b, c);
        assert!((w[0] - 0.25).abs() < 1e-12 && (w[1] - 0.25).abs() < 1e-12 && (w[2] - 0.5).abs() < 1e-12);
    }

    #[test]
    fn outside_points_clamp_to_edges_and_vertices() {
        let (a, b, c) = tri();
        assert_eq!(
            closest_point_barycentric(DVec3::new(-1.0, -1.0, 0.0), a, b, c),
            [1.0, 0.0, 0.0]
        );
        assert_eq!(
            closest_point_barycentric(DVec3::new(2.0, -0.5, 0.0), a, b, c),
            [0.0, 1.0, 0.0]
        );
        let w = closest_point_barycentric(DVec3::new(0.5, -1.0, 1.0), a, b, c);
        assert_eq!(w, [0.5, 0.5, 0.0]);
        // Beyond the hypotenuse: its midpoint.
        let w = closest_point_barycentric(DVec3::new(1.0, 1.0, 0.0), a, b, c);
        assert!((w[1] - 0.5).abs() < 1e-12 && (w[2] - 0.5).abs() < 1e-12 && w[0].abs() < 1e-12);
    }

    #[test]
    fn degenerate_triangle_gives_finite_weights() {
        let w = closest_point_barycentric(DVec3::new(0.5, 1.0, 0.0), DVec3::ZERO, DVec3::X, DVec3::X * 2.0);
        assert!(w.iter().all(|x| x.is_finite()));
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bvh_query_matches_brute_force() {
        // Two triangles of a folded quad; compare with brute force over both.
        let pts = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.5),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let tris = [[0, 1, 2], [0, 2, 3]];
        let cp = ClosestPoint::new(&pts, &tris);
        for q in [
            DVec3::new(0.9, 0.2, 1.0),
            DVec3::new(0.1, 0.8, -1.0),
            DVec3::new(0.5, 0.5, 2.0),
        ] {
            let (t, w) = cp.query(q);
            let at = |t: usize, w: [f64; 3]| {
                let [a, b, c] = tris[t];
                pts[a as usize] * w[0] + pts[b as usize] * w[1] + pts[c as usize] * w[2]
            };
            let got = (at(t, w) - q).length();
            let best = (0..2)
                .map(|i| {
                    let [a, b, c] = tris[i];
                    let w = closest_point_barycentric(q, pts[a as usize], pts[b as usize], pts[c as usize]);
                    (at(i, w) - q).length()
                })
                .fold(f64::INFINITY, f64::min);
            assert!((got - best).abs() < 1e-9, "{got} vs {best}");
        }
    }
}
