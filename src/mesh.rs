//! Proxy mesh topology: fan triangulation, one-rings, bounds.
//!
//! Pure functions over plain arrays (libigl style), shared by binding,
//! skinning and the view-dependent code.

use glam::{DVec3, Vec3};

/// Fan-triangulates polygons from their first vertex: (v0, vk, vk+1).
///
/// SPEC §3 pins this order so that independent implementations bind to the
/// same triangles. Faces with fewer than 3 vertices contribute nothing.
pub fn fan_triangulate(face_counts: &[u32], face_indices: &[u32]) -> Vec<[u32; 3]> {
    let mut tris = Vec::with_capacity(face_indices.len());
    let mut start = 0usize;
    for &n in face_counts {
        let n = n as usize;
        let face = &face_indices[start..start + n];
        for k in 1..n.saturating_sub(1) {
            tris.push([face[0], face[k], face[k + 1]]);
        }
        start += n;
    }
    tris
}

/// One-rings in compressed rows: `ring(v)` = v itself plus every vertex that
/// shares an edge of an authored polygon with v (SPEC §3), sorted, unique.
#[derive(Debug, Clone, PartialEq)]
pub struct OneRings {
    offsets: Vec<u32>,
    members: Vec<u32>,
}

impl OneRings {
    /// Builds one-rings from the authored polygons (not the triangulation:
    /// fan diagonals are not edges of the surface the artist modelled).
    pub fn new(num_vertices: usize, face_counts: &[u32], face_indices: &[u32]) -> Self {
        let mut adj: Vec<Vec<u32>> = (0..num_vertices).map(|v| vec![v as u32]).collect();
        let mut start = 0usize;
        for &n in face_counts {
            let n = n as usize;
            let face = &face_indices[start..start + n];
            for k in 0..n {
                let a = face[k];
                let b = face[(k + 1) % n];
                if a != b {
                    adj[a as usize].push(b);
                    adj[b as usize].push(a);
                }
            }
            start += n;
        }
        let mut offsets = Vec::with_capacity(num_vertices + 1);
        let mut members = Vec::new();
        offsets.push(0);
        for mut ring in adj {
            ring.sort_unstable();
            ring.dedup();
            members.extend_from_slice(&ring);
            offsets.push(members.len() as u32);
        }
        OneRings { offsets, members }
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    /// True when the mesh has no vertices.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The one-ring of vertex `v`, including `v`.
    pub fn ring(&self, v: usize) -> &[u32] {
        &self.members[self.offsets[v] as usize..self.offsets[v + 1] as usize]
    }
}

/// Axis-aligned bounds `[min, max]` of points; None when empty.
pub fn bounds(points: &[Vec3]) -> Option<[Vec3; 2]> {
    let first = *points.first()?;
    let (mut lo, mut hi) = (first, first);
    for &p in &points[1..] {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    Some([lo, hi])
}

/// Bounds of f64 points.
pub fn bounds_f64(points: &[DVec3]) -> Option<[DVec3; 2]> {
    let first = *points.first()?;
    let (mut lo, mut hi) = (first, first);
    for &p in &points[1..] {
        lo = lo.min(p);
        hi = hi.max(p);
    }
    Some([lo, hi])
}

/// `out[p] = Σ_k w_k · arrays_k[p]` over whole point arrays, in f32 (the hot
/// loop), parallel over points. Terms with weight 0 are not read, so their
/// arrays may be empty.
///
/// One weight vector blends a whole layer or mesh: pose and time keys,
/// view-dependent offsets and spline coefficients all come down to this.
///
/// # Panics
/// If a weighted array's length differs from `out`'s.
pub fn weighted_sum(out: &mut [Vec3], terms: &[(f64, &[Vec3])]) {
    use rayon::prelude::*;
    let terms = f32_terms(terms, out.len());
    out.par_chunks_mut(4096).enumerate().for_each(|(c, chunk)| {
        let start = c * 4096;
        for (i, o) in chunk.iter_mut().enumerate() {
            let mut acc = Vec3::ZERO;
            for (w, a) in &terms {
                acc += a[start + i] * *w;
            }
            *o = acc;
        }
    });
}

/// The terms of a [`weighted_sum`] as it computes them: zero weights
/// dropped, the rest in f32.
///
/// # Panics
/// If a weighted array's length differs from `len`.
pub fn f32_terms<'a>(terms: &[(f64, &'a [Vec3])], len: usize) -> Vec<(f32, &'a [Vec3])> {
    let terms: Vec<(f32, &[Vec3])> = terms
        .iter()
        .filter(|(w, _)| *w != 0.0)
        .map(|&(w, a)| (w as f32, a))
        .collect();
    for (k, (_, a)) in terms.iter().enumerate() {
        assert_eq!(a.len(), len, "term {k}: length differs from output");
    }
    terms
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fan_triangulation_starts_at_first_vertex() {
        let tris = fan_triangulate(&[4, 3], &[0, 1, 2, 3, 3, 2, 4]);
        assert_eq!(tris, vec![[0, 1, 2], [0, 2, 3], [3, 2, 4]]);
    }

    #[test]
    fn one_ring_uses_polygon_edges_not_fan_diagonals() {
        // A quad 0-1-2-3: 0 and 2 share no edge although the fan makes one.
        let rings = OneRings::new(4, &[4], &[0, 1, 2, 3]);
        assert_eq!(rings.ring(0), &[0, 1, 3]);
        assert_eq!(rings.ring(2), &[1, 2, 3]);
    }

    #[test]
    fn weighted_sum_blends_and_skips_zero_weights() {
        let a = vec![Vec3::X; 5000];
        let b = vec![Vec3::Y; 5000];
        let mut out = vec![Vec3::ZERO; 5000];
        // The zero-weight term's array is empty and must not be read.
        weighted_sum(&mut out, &[(0.25, &a), (0.75, &b), (0.0, &[])]);
        assert!(out.iter().all(|p| (*p - Vec3::new(0.25, 0.75, 0.0)).length() < 1e-7));
    }

    #[test]
    fn weighted_sum_keeps_each_point_in_place_across_chunks() {
        // More points than one 4096-point parallel chunk, each different, so
        // a point read from the wrong index shows.
        let n = 4096 + 10;
        let a: Vec<Vec3> = (0..n).map(|p| Vec3::new(p as f32, 1.0, 0.0)).collect();
        let mut out = vec![Vec3::ZERO; n];
        weighted_sum(&mut out, &[(2.0, &a)]);
        for (p, o) in out.iter().enumerate() {
            assert_eq!(*o, Vec3::new(2.0 * p as f32, 2.0, 0.0), "point {p}");
        }
    }

    #[test]
    fn one_rings_count_vertices() {
        let none = OneRings::new(0, &[], &[]);
        assert_eq!(none.len(), 0);
        assert!(none.is_empty());
        // Vertex 3 is in no face: counted, and its ring is itself.
        let tri = OneRings::new(4, &[3], &[0, 1, 2]);
        assert_eq!(tri.len(), 4);
        assert!(!tri.is_empty());
        assert_eq!(tri.ring(3), &[3]);
    }

    #[test]
    fn bounds_of_points() {
        let b = bounds(&[Vec3::new(1.0, -2.0, 0.0), Vec3::new(-1.0, 3.0, 0.5)]).unwrap();
        assert_eq!(b, [Vec3::new(-1.0, -2.0, 0.0), Vec3::new(1.0, 3.0, 0.5)]);
        assert!(bounds(&[]).is_none());
    }
}
