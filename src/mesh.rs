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
    fn bounds_of_points() {
        let b = bounds(&[Vec3::new(1.0, -2.0, 0.0), Vec3::new(-1.0, 3.0, 0.5)]).unwrap();
        assert_eq!(b, [Vec3::new(-1.0, -2.0, 0.0), Vec3::new(1.0, 3.0, 0.5)]);
        assert!(bounds(&[]).is_none());
    }
}
