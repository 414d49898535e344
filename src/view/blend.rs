//! Blend weights from an eye direction (Rademacher §3.2.2, §3.3) and the
//! per-point blend of key offsets.

use glam::Vec3;
use nalgebra::Vector3;

use super::hull::{self, Cover};
use super::ViewError;

/// Eye directions this close (chord length) to a key direction give exactly
/// that key, so the key deformation is reproduced bit for bit.
const SNAP: f64 = 1e-12;

/// A point counts as inside a cell when `min λ / Σ|λ| ≥ −INSIDE_SLACK`.
const INSIDE_SLACK: f64 = 1e-12;

/// What happens where the key viewpoints do not surround the model
/// (`painterly:uncovered`, SPEC §6; Rademacher §3.3).
///
/// The covered region is the part of the viewing sphere spanned by the key
/// directions: the whole sphere when their hull strictly encloses the
/// centre, otherwise the cone they span (a spherical polygon, an arc, or a
/// single direction). Inside it both modes are the plain hull blend.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Uncovered {
    /// Fall off towards the base model with the cosine of the angle to the
    /// covered region (token `"cosine"`, the default).
    ///
    /// Let `p` be the covered direction nearest to the eye `e` and
    /// `d = cos∠(e, p)`: `d` is the largest `e·q` over covered unit
    /// directions `q` (so `d = 1` inside the covered region). The result is
    /// `max(0,d)·blend(p) + (1 − max(0,d))·base`, where `blend(p)` is the
    /// hull blend at `p` (barycentric weights on the covered border,
    /// sharpened by α). With one key, `p` is the key and this is exactly
    /// SPEC 1.1 §6's `max(0,d)·deformed + (1 − max(0,d))·base` with
    /// `d = key·eye`. It is continuous in the eye direction: `d` is a cosine
    /// of a distance, and the nearest covered direction is unique wherever
    /// `d > 0` because the covered region is convex.
    ///
    /// The weights always sum to one: the base model is reached 90° from
    /// the covered region and held beyond it (`d ≤ 0` gives exactly the
    /// base). SPEC 1.0 printed the base coefficient as `max(0,1−d)`, which
    /// scaled the base model by up to 2 behind the keys.
    #[default]
    Cosine,
    /// Close the hull with copies of the base model (token `"base"`):
    /// virtual viewpoints with zero deformation are added until the hull
    /// strictly encloses the centre, then every eye direction gets the plain
    /// hull blend, and the weights of virtual viewpoints go to the base.
    /// Weights always sum to one.
    ///
    /// Virtual viewpoints are placed on the uncovered side, each at least
    /// 90° from every real key, so they never intrude on the covered
    /// region:
    /// * one key `k`: an octahedron (`−k` and four directions perpendicular
    ///   to `k`);
    /// * keys on one great circle (normal `n`): `n` and `−n`, plus the
    ///   mid-direction of any gap of half a turn or more between
    ///   neighbouring keys (two keys 90° apart get both poles and the
    ///   direction opposite their bisector);
    /// * keys on one small circle around `n`: `−n`, the apex of a pyramid
    ///   over the key polygon;
    /// * otherwise, one at a time, the outward normal of the hull face
    ///   nearest to (or beyond) the centre, until the centre is enclosed;
    ///   keys spread over a cap around `c` typically get one virtual key,
    ///   `−c`.
    ///
    /// Between the edge of the covered region and a virtual key the
    /// deformation fades linearly along the hull face, which is Rademacher's
    /// "insert dummy deformations" variant of the cosine falloff.
    Base,
}

impl Uncovered {
    /// Parses the `painterly:uncovered` token (`"cosine"` or `"base"`).
    pub fn from_token(token: &str) -> Option<Self> {
        match token {
            "cosine" => Some(Uncovered::Cosine),
            "base" => Some(Uncovered::Base),
            _ => None,
        }
    }

    /// The `painterly:uncovered` token for this mode.
    pub fn token(self) -> &'static str {
        match self {
            Uncovered::Cosine => "cosine",
            Uncovered::Base => "base",
        }
    }
}

/// Blend weights for one eye direction: at most three `(key index, weight)`
/// pairs plus the coefficient of the base model.
///
/// The blended shape is `base · base_model + Σ w_k · key_points_k`, which in
/// offsets (`offset_k = key_points_k − base_model`) is
/// `base_scale() · base_model + Σ w_k · offset_k`. The weights sum to one
/// in every mode, so `base_scale() == 1` and the result is
/// `base_model + Σ w_k · offset_k`. Only keys with non-zero weight are
/// listed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewWeights {
    entries: [(usize, f64); 3],
    len: usize,
    base: f64,
}

impl ViewWeights {
    /// The base model alone (no keys, or a degenerate eye direction).
    pub fn base_only() -> Self {
        ViewWeights {
            entries: [(0, 0.0); 3],
            len: 0,
            base: 1.0,
        }
    }

    /// The key deformations taking part, with their weights.
    pub fn keys(&self) -> &[(usize, f64)] {
        &self.entries[..self.len]
    }

    /// Weight of key `key` (zero when it takes no part).
    pub fn weight_of(&self, key: usize) -> f64 {
        self.keys().iter().filter(|(k, _)| *k == key).map(|(_, w)| w).sum()
    }

    /// Coefficient of the base model in `base · base_model + Σ w_k · key_k`.
    pub fn base(&self) -> f64 {
        self.base
    }

    /// Coefficient of the base model when blending offsets:
    /// `base() + Σ w_k`, one in every mode (weights are a partition of
    /// unity), up to rounding.
    pub fn base_scale(&self) -> f64 {
        self.base + self.keys().iter().map(|(_, w)| w).sum::<f64>()
    }

    fn push(&mut self, key: usize, w: f64) {
        if w > 0.0 {
            self.entries[self.len] = (key, w);
            self.len += 1;
        }
    }
}

/// The view-dependent blender for one mesh: key directions, sharpness and
/// uncovered mode, with the hull precomputed once (`new`) and queried per
/// frame (`weights`).
#[derive(Clone, Debug)]
pub struct ViewBlender {
    /// Real key directions (unit).
    keys: Vec<Vector3<f64>>,
    /// Key directions the hull was built on: the real keys, then any virtual
    /// base viewpoints (`Base` mode).
    all: Vec<Vector3<f64>>,
    cover: Cover,
    sharpness: f64,
    mode: Uncovered,
}

impl ViewBlender {
    /// Precomputes the key viewpoint hull.
    ///
    /// `directions[k]` is key viewpoint `k`'s direction in the mesh's local
    /// space, from the centre of the base model's bounding box towards the
    /// key camera; it is normalised here. `sharpness` is the exponent α
    /// applied to barycentric weights (α > 1 snaps towards the nearest key,
    /// α < 1 blends more gradually).
    ///
    /// Errors: a zero or non-finite direction, two directions within
    /// [`super::SAME_DIRECTION_TOLERANCE`] of each other (naming both
    /// indices), α not finite or ≤ 0, or a hull that cannot be built
    /// reliably. An empty key list is allowed and always yields the base
    /// model.
    pub fn new(directions: &[[f64; 3]], sharpness: f64, mode: Uncovered) -> Result<Self, ViewError> {
        if !(sharpness.is_finite() && sharpness > 0.0) {
            return Err(ViewError::InvalidSharpness(sharpness));
        }
        let keys = hull::unit_directions(directions)?;
        let shape = hull::shape(&keys)?;
        let mut all = keys.clone();
        let mut cover = Cover::new(&keys, &shape);
        if mode == Uncovered::Base && !cover.encloses && !keys.is_empty() {
            let (extended, tris) = hull::enclose(&keys)?;
            cover = Cover::enclosing(&extended, &tris);
            all = extended;
        }
        Ok(ViewBlender {
            keys,
            all,
            cover,
            sharpness,
            mode,
        })
    }

    /// Number of (real) key viewpoints.
    pub fn key_count(&self) -> usize {
        self.keys.len()
    }

    /// The sharpness exponent α.
    pub fn sharpness(&self) -> f64 {
        self.sharpness
    }

    /// The uncovered-region mode.
    pub fn mode(&self) -> Uncovered {
        self.mode
    }

    /// Whether the key directions alone strictly enclose the centre, so
    /// that the uncovered mode never applies.
    pub fn encloses(&self) -> bool {
        self.cover.encloses && self.all.len() == self.keys.len()
    }

    /// The virtual base viewpoints added in `Base` mode (empty otherwise),
    /// for diagnostics.
    pub fn virtual_directions(&self) -> Vec<[f64; 3]> {
        self.all[self.keys.len()..].iter().map(|v| [v.x, v.y, v.z]).collect()
    }

    /// Blend weights for the eye direction `eye` (mesh local space, from the
    /// centre of the base model's bounding box towards the camera; it is
    /// normalised here).
    ///
    /// Covered directions: the hull face hit by the ray from the centre
    /// along `eye`, the barycentric weights `b_i` of the hit point, then
    /// `b_i^α / Σ b_j^α`. At a key direction the result is exactly that
    /// key; along a hull edge both faces give the same weights, so the
    /// blend is continuous (Lipschitz for α ≥ 1; for α < 1 the power makes
    /// it steeper, though still continuous, next to edges and keys).
    /// Elsewhere see [`Uncovered`]. A zero or non-finite `eye` (camera at
    /// the centre) yields the base model.
    pub fn weights(&self, eye: [f64; 3]) -> ViewWeights {
        let Some(e) = hull::unit(eye) else {
            return ViewWeights::base_only();
        };
        if self.keys.is_empty() {
            return ViewWeights::base_only();
        }
        if let Some(i) = self.keys.iter().position(|k| (k - e).norm() <= SNAP) {
            let mut w = ViewWeights::base_only();
            w.base = 0.0;
            w.push(i, 1.0);
            return w;
        }
        if let Some((cell, score)) = self.best_cell(&e) {
            if self.cover.encloses || score >= -INSIDE_SLACK {
                let c = &self.cover.cells[cell];
                return self.finish(&c.keys, c.coefficients(&e), 1.0, 0.0);
            }
        }
        // Cosine mode outside the covered region.
        self.cosine_falloff(&e)
    }

    /// The cell the ray along `e` is deepest inside, with its score.
    fn best_cell(&self, e: &Vector3<f64>) -> Option<(usize, f64)> {
        self.cover
            .cells
            .iter()
            .map(|c| c.score(e))
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Nearest covered direction `p` over all arcs and keys, `d = cos∠(e,p)`,
    /// then `max(0,d)·blend(p)` and base `1 − max(0,d)`.
    fn cosine_falloff(&self, e: &Vector3<f64>) -> ViewWeights {
        // Candidates are ranked by their angle to e, atan2(|e×p|, e·p), not
        // by the cosine: within about 1.5e-8 rad of a key every cosine
        // rounds to 1, and an arc through the key would lose to it there,
        // snapping the blend to the key (a jump of (1.5e-8)^α for α < 1).
        let angle = |p: &Vector3<f64>| e.cross(p).norm().atan2(e.dot(p));
        // Best candidate: (d, keys, coefficients).
        let mut best_d = f64::NEG_INFINITY;
        let mut best_angle = f64::INFINITY;
        let mut best: ([usize; 2], [f64; 2], usize) = ([0, 0], [0.0, 0.0], 0);
        for (i, k) in self.keys.iter().enumerate() {
            let a = angle(k);
            if a < best_angle {
                best_angle = a;
                best_d = k.dot(e);
                best = ([i, i], [1.0, 0.0], 1);
            }
        }
        for &[i, j] in &self.cover.edges {
            let (a, b) = (&self.keys[i], &self.keys[j]);
            let (ea, eb, g) = (e.dot(a), e.dot(b), a.dot(b));
            let det = 1.0 - g * g;
            if det <= 0.0 {
                continue;
            }
            // Projection of e onto the plane of a and b: μa·a + μb·b.
            let ma = (ea - g * eb) / det;
            let mb = (eb - g * ea) / det;
            if ma > 0.0 && mb > 0.0 {
                let to_arc = angle(&(a * ma + b * mb));
                if to_arc < best_angle {
                    best_angle = to_arc;
                    // |q|² = q·e for an orthogonal projection q.
                    best_d = (ma * ea + mb * eb).max(0.0).sqrt().min(1.0);
                    best = ([i, j], [ma, mb], 2);
                }
            }
        }
        let d = best_d;
        let (keys, coef, n) = best;
        if n == 1 {
            // A single key: exactly max(0,d)·key + (1 − max(0,d))·base.
            let mut w = ViewWeights::base_only();
            w.base = 1.0 - d.max(0.0);
            w.push(keys[0], d.max(0.0));
            return w;
        }
        self.finish(&keys[..n], [coef[0], coef[1], 0.0], d.max(0.0), 1.0 - d.max(0.0))
    }

    /// Turns cone coefficients into sharpened barycentric weights, scales
    /// them by `scale`, sends virtual keys to the base and adds `base`.
    fn finish(&self, keys: &[usize], coef: [f64; 3], scale: f64, base: f64) -> ViewWeights {
        let n = keys.len();
        let mut b = [0.0f64; 3];
        for (bi, c) in b.iter_mut().zip(coef).take(n) {
            *bi = c.max(0.0);
        }
        let sum: f64 = b.iter().sum();
        if sum <= 0.0 {
            // Unreachable for a ray inside a cell; fall back to the base.
            return ViewWeights::base_only();
        }
        for bi in &mut b {
            *bi /= sum;
        }
        if self.sharpness != 1.0 {
            for bi in &mut b {
                *bi = bi.powf(self.sharpness);
            }
            let s: f64 = b.iter().sum();
            for bi in &mut b {
                *bi /= s;
            }
        }
        let mut w = ViewWeights::base_only();
        w.base = base;
        let real = self.keys.len();
        for (&k, &bk) in keys.iter().zip(&b) {
            let bk = bk * scale;
            if k < real {
                w.push(k, bk);
            } else {
                w.base += bk;
            }
        }
        w
    }
}

/// Applies view weights to point arrays:
/// `out[p] = base_scale·base[p] + Σ w_k · offsets[k][p]`, where
/// `offsets[k][p] = key_points_k[p] − base[p]` (the key deformation as an
/// offset from the base, possibly interpolated over time for an animated
/// base, Rademacher §4.2) and `base_scale` is
/// [`ViewWeights::base_scale`] (one: the weights sum to one in every mode).
/// Blending offsets is then identical to blending absolute key shapes, and
/// the cosine fallback `max(0,d)·deformed + (1 − max(0,d))·base` is
/// `base + max(0,d)·offset`.
///
/// `offsets` is indexed by key index; keys with zero weight are not read.
///
/// # Panics
/// If `out` and `base` differ in length, or a weighted key's offsets do.
pub fn blend_offsets(base: &[Vec3], offsets: &[&[Vec3]], weights: &ViewWeights, out: &mut [Vec3]) {
    assert_eq!(base.len(), out.len(), "base and output point counts differ");
    let mut terms: Vec<(f64, &[Vec3])> = vec![(weights.base_scale(), base)];
    terms.extend(weights.keys().iter().map(|&(k, w)| (w, offsets[k])));
    crate::mesh::weighted_sum(out, &terms);
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const EPS: f64 = 1e-12;

    fn norm(v: [f64; 3]) -> [f64; 3] {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / n, v[1] / n, v[2] / n]
    }

    fn octahedron() -> Vec<[f64; 3]> {
        vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ]
    }

    fn cube() -> Vec<[f64; 3]> {
        let mut d = Vec::new();
        for sx in [-1.0, 1.0] {
            for sy in [-1.0, 1.0] {
                for sz in [-1.0, 1.0] {
                    d.push([sx, sy, sz]);
                }
            }
        }
        d
    }

    /// Dense weight vector: one entry per real key, then the base.
    fn dense(w: &ViewWeights, n: usize) -> Vec<f64> {
        let mut v: Vec<f64> = (0..n).map(|k| w.weight_of(k)).collect();
        v.push(w.base());
        v
    }

    fn max_diff(a: &[f64], b: &[f64]) -> f64 {
        a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
    }

    fn sum(w: &ViewWeights) -> f64 {
        w.base_scale()
    }

    #[test]
    fn rejects_bad_sharpness() {
        for s in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                ViewBlender::new(&octahedron(), s, Uncovered::Cosine),
                Err(ViewError::InvalidSharpness(_))
            ));
        }
        assert_eq!(
            ViewBlender::new(&[[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], 1.0, Uncovered::Base).unwrap_err(),
            ViewError::DuplicateDirection { first: 0, second: 1 }
        );
    }

    #[test]
    fn tokens() {
        assert_eq!(Uncovered::from_token("cosine"), Some(Uncovered::Cosine));
        assert_eq!(Uncovered::from_token("base"), Some(Uncovered::Base));
        assert_eq!(Uncovered::from_token("Base"), None);
        assert_eq!(Uncovered::Base.token(), "base");
        assert_eq!(Uncovered::default(), Uncovered::Cosine);
    }

    #[test]
    fn exact_key_at_key_direction() {
        for dirs in [octahedron(), cube()] {
            for mode in [Uncovered::Cosine, Uncovered::Base] {
                for alpha in [0.5, 1.0, 4.0] {
                    let vb = ViewBlender::new(&dirs, alpha, mode).unwrap();
                    for (k, d) in dirs.iter().enumerate() {
                        // Scaled directions are the same viewpoint.
                        let w = vb.weights([d[0] * 3.0, d[1] * 3.0, d[2] * 3.0]);
                        assert_eq!(w.keys(), &[(k, 1.0)]);
                        assert_eq!(w.base(), 0.0);
                    }
                }
            }
        }
    }

    #[test]
    fn octahedron_closed_form() {
        // Face x+y+z=1 (first octant): the ray along e hits e/(ex+ey+ez),
        // whose barycentric coordinates on (+x,+y,+z) are e_i/Σe.
        let vb1 = ViewBlender::new(&octahedron(), 1.0, Uncovered::Cosine).unwrap();
        let vb4 = ViewBlender::new(&octahedron(), 4.0, Uncovered::Cosine).unwrap();
        assert!(vb1.encloses());
        for e in [[1.0, 2.0, 3.0], [0.2, 0.3, 0.9], [1.0, 1.0, 1.0], [5.0, 0.1, 0.2]] {
            let s = e[0] + e[1] + e[2];
            let w = vb1.weights(e);
            for (i, key) in [0usize, 2, 4].into_iter().enumerate() {
                assert!((w.weight_of(key) - e[i] / s).abs() < EPS);
            }
            assert!((sum(&w) - 1.0).abs() < EPS);
            assert_eq!(w.base(), 0.0);
            let s4: f64 = e.iter().map(|x| x.powi(4)).sum();
            let w = vb4.weights(e);
            for (i, key) in [0usize, 2, 4].into_iter().enumerate() {
                assert!((w.weight_of(key) - e[i].powi(4) / s4).abs() < EPS);
            }
        }
        // Negative octant (−x, −y, +z).
        let w = vb1.weights([-1.0, -2.0, 1.0]);
        assert!((w.weight_of(1) - 0.25).abs() < EPS);
        assert!((w.weight_of(3) - 0.5).abs() < EPS);
        assert!((w.weight_of(4) - 0.25).abs() < EPS);
    }

    #[test]
    fn cube_corners() {
        let dirs = cube();
        let vb = ViewBlender::new(&dirs, 1.0, Uncovered::Cosine).unwrap();
        assert!(vb.encloses());
        // Along the cube edge from (1,1,-1) (index 6) to (1,1,1) (index 7):
        // e = (1,1,z) hits the edge at parameter (1+z)/2.
        for z in [-0.5, 0.0, 0.3, 0.9] {
            let w = vb.weights([1.0, 1.0, z]);
            assert!((w.weight_of(7) - (1.0 + z) / 2.0).abs() < EPS, "{w:?}");
            assert!((w.weight_of(6) - (1.0 - z) / 2.0).abs() < EPS);
        }
        // Face centre +x: on the diagonal splitting the square face, half
        // each to two opposite corners of that face (either diagonal).
        let w = vb.weights([1.0, 0.0, 0.0]);
        let ks: Vec<usize> = w.keys().iter().map(|k| k.0).collect();
        assert_eq!(ks.len(), 2);
        for &(k, wk) in w.keys() {
            assert!(dirs[k][0] > 0.0);
            assert!((wk - 0.5).abs() < EPS);
        }
        let (a, b) = (dirs[ks[0]], dirs[ks[1]]);
        assert_eq!((a[1] + b[1], a[2] + b[2]), (0.0, 0.0));
        // Inside a face, weights stay continuous across the diagonal.
        for dy in [1e-7, -1e-7] {
            for dz in [1e-7, -1e-7] {
                let w2 = vb.weights([1.0, dy, dz]);
                assert!(max_diff(&dense(&w, 8), &dense(&w2, 8)) < 1e-6);
            }
        }
    }

    #[test]
    fn edge_ties_agree_between_faces() {
        // Directly compare the two cells sharing an octahedron edge.
        let vb = ViewBlender::new(&octahedron(), 2.5, Uncovered::Cosine).unwrap();
        let e = Vector3::new(1.0, 1.0, 0.0).normalize();
        let cells: Vec<_> = vb.cover.cells.iter().filter(|c| c.score(&e) >= -1e-15).collect();
        assert_eq!(cells.len(), 2);
        let w: Vec<ViewWeights> = cells
            .iter()
            .map(|c| vb.finish(&c.keys, c.coefficients(&e), 1.0, 0.0))
            .collect();
        assert!(max_diff(&dense(&w[0], 6), &dense(&w[1], 6)) < EPS);
        assert!((w[0].weight_of(0) - 0.5).abs() < EPS);
    }

    #[test]
    fn continuity_near_edges_and_vertices() {
        let dirs = cube();
        for mode in [Uncovered::Cosine, Uncovered::Base] {
            let vb = ViewBlender::new(&dirs, 1.0, mode).unwrap();
            let probes = [
                norm([1.0, 1.0, 1.0]), // vertex
                norm([1.0, 1.0, 0.2]), // edge
                norm([1.0, 0.3, 0.3]), // face diagonal
                norm([1.0, 0.0, 0.0]), // face centre
            ];
            for p in probes {
                let w0 = dense(&vb.weights(p), 8);
                for h in [1e-6, 1e-8] {
                    for dir in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 1.0]] {
                        let q = [p[0] + h * dir[0], p[1] + h * dir[1], p[2] + h * dir[2]];
                        let w1 = dense(&vb.weights(q), 8);
                        assert!(max_diff(&w0, &w1) < 10.0 * h, "{p:?} {q:?} {w0:?} {w1:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn cosine_mode_follows_an_arc_right_up_to_its_key() {
        // Keys +x and +y, eye (1, t, 0) on the arc between them: the nearest
        // covered direction is the eye itself (d = 1), with cone coefficients
        // in the ratio 1 : t, so w_y = t^α / (1 + t^α). For α = 1/4 that is
        // about 0.0099 at t = 1e-8, where cosines can no longer tell the eye
        // from +x; only the snap (1e-12) may take the key.
        let vb = ViewBlender::new(&[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], 0.25, Uncovered::Cosine).unwrap();
        for t in [1e-11f64, 1e-9, 1e-8, 2e-8, 1e-3] {
            let w = vb.weights([1.0, t, 0.0]);
            let want = t.powf(0.25) / (1.0 + t.powf(0.25));
            assert!((w.weight_of(1) - want).abs() < 1e-12, "t = {t}: {w:?}");
            assert!(
                (w.weight_of(0) - (1.0 - want)).abs() < 1e-12 && w.base().abs() < 1e-12,
                "t = {t}: {w:?}"
            );
        }
    }

    #[test]
    fn one_key_cosine_formula() {
        let key = norm([0.3, -0.2, 0.9]);
        let vb = ViewBlender::new(&[[0.6, -0.4, 1.8]], 3.0, Uncovered::Cosine).unwrap();
        for e in [
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 0.0],
            [-0.3, 0.2, -0.9],
            [0.5, 0.5, 0.1],
            [0.0, 1.0, 0.0],
        ] {
            let en = norm(e);
            let d = key[0] * en[0] + key[1] * en[1] + key[2] * en[2];
            let w = vb.weights(e);
            assert!((w.weight_of(0) - d.max(0.0)).abs() < 1e-15);
            assert!((w.base() - (1.0 - d.max(0.0))).abs() < 1e-15);
        }
        // Behind the key (d < 0) exactly the base model (SPEC 1.1 §6; 1.0
        // scaled it by 1 − d, up to 2).
        for e in [[-0.3, 0.2, -0.9], [-0.2, 0.1, -0.1], [0.0, 1.0, 0.2]] {
            let w = vb.weights(e);
            assert_eq!(w.base(), 1.0, "{e:?}");
            assert!(w.keys().is_empty());
            assert_eq!(w.base_scale(), 1.0);
        }
    }

    #[test]
    fn one_key_base_mode_is_octahedral() {
        // Key +z closed by five base copies at the other octahedron
        // vertices (their in-plane orientation is an implementation detail,
        // so check frame-free facts).
        let vb = ViewBlender::new(&[[0.0, 0.0, 1.0]], 1.0, Uncovered::Base).unwrap();
        assert_eq!(vb.virtual_directions().len(), 5);
        for e in [[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.3, -0.9, -0.1]] {
            let w = vb.weights(e);
            assert!(w.keys().is_empty(), "{e:?} {w:?}");
            assert!((w.base() - 1.0).abs() < EPS);
        }
        let w = vb.weights([0.1, 0.2, 1.0]);
        assert!((sum(&w) - 1.0).abs() < EPS);
        assert!(w.weight_of(0) > 0.5 && w.weight_of(0) < 1.0);
        // Along the axis of any virtual key adjacent to +z (a 90° neighbour
        // v), the weight on the arc between is the barycentric split.
        for v in vb.virtual_directions() {
            if v[2].abs() > 0.5 {
                continue;
            }
            // Midpoint of the octahedron edge from v to +z: half each.
            let e = [v[0], v[1], v[2] + 1.0];
            let w = vb.weights(e);
            assert!((w.weight_of(0) - 0.5).abs() < 1e-9, "{w:?}");
            assert!((w.base() - 0.5).abs() < 1e-9);
        }
    }

    /// Keys strictly inside the upper hemisphere: four at 45° from +z plus
    /// +z itself.
    fn cap() -> Vec<[f64; 3]> {
        let s = std::f64::consts::FRAC_1_SQRT_2;
        vec![[s, 0.0, s], [0.0, s, s], [-s, 0.0, s], [0.0, -s, s], [0.0, 0.0, 1.0]]
    }

    #[test]
    fn hemisphere_keys_cosine() {
        let dirs = cap();
        let vb = ViewBlender::new(&dirs, 1.0, Uncovered::Cosine).unwrap();
        assert!(!vb.encloses());
        // Inside the cap: plain hull blend, summing to one.
        let w = vb.weights([0.1, 0.2, 1.0]);
        assert_eq!(w.base(), 0.0);
        assert!((sum(&w) - 1.0).abs() < EPS);
        // Straight out from the key at 45°: nearest covered direction is
        // that key, at angle θ−45° for a direction at polar angle θ.
        for deg in [60.0f64, 90.0, 120.0, 135.0, 150.0, 180.0] {
            let t = deg.to_radians();
            let w = vb.weights([t.sin(), 0.0, t.cos()]);
            let d = (t - std::f64::consts::FRAC_PI_4).cos();
            assert!((w.weight_of(0) - d.max(0.0)).abs() < 1e-12, "{deg} {w:?}");
            assert!((w.base() - (1.0 - d.max(0.0))).abs() < 1e-12);
            assert!((w.base_scale() - 1.0).abs() < 1e-15);
        }
        // Between two rim keys (azimuth 45°), out of the cap: the nearest
        // covered direction is on the rim arc between keys 0 and 1 (in the
        // plane x = y at the same angle from the arc), half each.
        let t = 100f64.to_radians();
        let e = [t.sin() / 2f64.sqrt(), t.sin() / 2f64.sqrt(), t.cos()];
        let w = vb.weights(e);
        // The plane of keys 0 and 1 (through the centre) has unit normal
        // n = (1,1,−1)/√3; d = |e − (e·n)n| = √(1 − (e·n)²).
        let n = norm([1.0, 1.0, -1.0]);
        let en = e[0] * n[0] + e[1] * n[1] + e[2] * n[2];
        let d = (1.0 - en * en).sqrt();
        assert!(en > 0.0); // e is on the far side from +z: outside the cap
        assert!((w.weight_of(0) - d / 2.0).abs() < 1e-12, "{w:?} {d}");
        assert!((w.weight_of(1) - d / 2.0).abs() < 1e-12);
        assert!((w.base() - (1.0 - d)).abs() < 1e-12);
        // Continuity along a path leaving the cap.
        let path = |t: f64| [t.cos() + 0.2, 0.3, t.sin() - t.cos()];
        let mut prev = dense(&vb.weights(path(0.0)), 5);
        for i in 1..=2000 {
            let t = i as f64 / 2000.0 * std::f64::consts::PI;
            let cur = dense(&vb.weights(path(t)), 5);
            assert!(max_diff(&prev, &cur) < 0.02, "{i} {prev:?} {cur:?}");
            prev = cur;
        }
    }

    #[test]
    fn hemisphere_keys_base() {
        let dirs = cap();
        let vb = ViewBlender::new(&dirs, 1.0, Uncovered::Base).unwrap();
        assert!(!vb.encloses());
        let v = vb.virtual_directions();
        assert_eq!(v.len(), 1);
        assert!(max_diff(&v[0], &[0.0, 0.0, -1.0]) < EPS);
        // Straight down: all base.
        let w = vb.weights([0.0, 0.0, -1.0]);
        assert!(w.keys().is_empty());
        assert_eq!(w.base(), 1.0);
        // On the meridian through key 0 the ray hits the chord from key 0
        // (s, 0, s) to (0, 0, −1): at polar angle θ the hit point
        // (1−t)(s,0,s) + t(0,0,−1) satisfies x/z = tan θ.
        let s = std::f64::consts::FRAC_1_SQRT_2;
        for deg in [60.0f64, 90.0, 120.0, 170.0] {
            let th = deg.to_radians();
            let w = vb.weights([th.sin(), 0.0, th.cos()]);
            // (1−t)s·cosθ = ((1−t)s − t)·sinθ  ⇒  t = s(sinθ − cosθ)/(s(sinθ − cosθ) + sinθ)
            let a = s * (th.sin() - th.cos());
            let t = a / (a + th.sin());
            assert!((w.weight_of(0) - (1.0 - t)).abs() < 1e-12, "{deg} {w:?}");
            assert!((w.base() - t).abs() < 1e-12);
            assert!((sum(&w) - 1.0).abs() < EPS);
        }
    }

    #[test]
    fn equator_and_pole_cosine_leaves_south_uncovered() {
        let dirs = vec![
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
        ];
        let vb = ViewBlender::new(&dirs, 1.0, Uncovered::Cosine).unwrap();
        // Below the equator at azimuth 0: nearest covered is key 0.
        let t = 0.4f64;
        let w = vb.weights([t.cos(), 0.0, -t.sin()]);
        assert!((w.weight_of(0) - t.cos()).abs() < 1e-12);
        assert!((w.base() - (1.0 - t.cos())).abs() < 1e-12);
        // Straight down: 90° from every covered direction.
        let w = vb.weights([0.0, 0.0, -1.0]);
        assert!(w.keys().is_empty());
        assert!((w.base() - 1.0).abs() < 1e-12);
        // Base mode closes it with −z: octahedron.
        let vb = ViewBlender::new(&dirs, 1.0, Uncovered::Base).unwrap();
        assert_eq!(vb.virtual_directions().len(), 1);
        let w = vb.weights([1.0, 2.0, -1.0]);
        assert!((w.weight_of(0) - 0.25).abs() < EPS);
        assert!((w.weight_of(1) - 0.5).abs() < EPS);
        assert!((w.base() - 0.25).abs() < EPS);
    }

    #[test]
    fn two_keys() {
        // Keys +x and +y: the covered region is the quarter arc between.
        let vb = ViewBlender::new(&[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], 1.0, Uncovered::Cosine).unwrap();
        // On the arc: the chord hit point's barycentrics.
        let w = vb.weights([1.0, 3.0, 0.0]);
        assert!((w.weight_of(0) - 0.25).abs() < EPS);
        assert!((w.weight_of(1) - 0.75).abs() < EPS);
        assert!(w.base() < EPS);
        // Lifted off the arc by angle φ: nearest point is the same arc
        // point, d = cos φ.
        let phi = 0.3f64;
        let r = phi.cos() / 10f64.sqrt();
        let e = [r, 3.0 * r, phi.sin()];
        let w = vb.weights(e);
        assert!((w.weight_of(0) - 0.25 * phi.cos()).abs() < 1e-12, "{w:?}");
        assert!((w.weight_of(1) - 0.75 * phi.cos()).abs() < 1e-12);
        assert!((w.base() - (1.0 - phi.cos())).abs() < 1e-12);
        // Beyond the end of the arc: nearest is the key itself.
        let w = vb.weights([1.0, -1.0, 0.0]);
        assert!((w.weight_of(0) - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
        assert_eq!(w.weight_of(1), 0.0);
        // Antipodal keys: no arc, each key on its own.
        let vb = ViewBlender::new(&[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]], 1.0, Uncovered::Cosine).unwrap();
        let w = vb.weights([0.0, 1.0, 0.0]);
        assert!(w.keys().is_empty());
        assert!((w.base() - 1.0).abs() < EPS);
        let w = vb.weights([-1.0, 1.0, 0.0]);
        assert!((w.weight_of(1) - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
        // Base mode with two keys sums to one everywhere.
        let vb = ViewBlender::new(&[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], 1.0, Uncovered::Base).unwrap();
        for e in [[1.0, 3.0, 0.0], [0.0, 0.0, 1.0], [-1.0, -1.0, -1.0], [0.3, 0.1, -0.2]] {
            assert!((sum(&vb.weights(e)) - 1.0).abs() < EPS);
        }
        // On the arc between the two keys the base takes nothing.
        let w = vb.weights([1.0, 3.0, 0.0]);
        assert!((w.weight_of(0) - 0.25).abs() < EPS);
        assert!((w.weight_of(1) - 0.75).abs() < EPS);
    }

    #[test]
    fn three_keys() {
        // +x, +y, +z: the covered region is the first octant; inside, the
        // barycentric weights on the face x+y+z=1 are e_i/Σe.
        let dirs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        for mode in [Uncovered::Cosine, Uncovered::Base] {
            let vb = ViewBlender::new(&dirs, 1.0, mode).unwrap();
            let w = vb.weights([1.0, 2.0, 3.0]);
            for i in 0..3 {
                assert!((w.weight_of(i) - (i + 1) as f64 / 6.0).abs() < EPS);
            }
            assert_eq!(w.base(), 0.0);
        }
        let vb = ViewBlender::new(&dirs, 1.0, Uncovered::Cosine).unwrap();
        // Below the x-y plane: nearest covered point is on the arc between
        // +x and +y, the projection of e onto the plane.
        let e = norm([1.0, 3.0, -0.5]);
        let q = (e[0] * e[0] + e[1] * e[1]).sqrt();
        let w = vb.weights(e);
        assert!((w.weight_of(0) - q * 0.25).abs() < 1e-12);
        assert!((w.weight_of(1) - q * 0.75).abs() < 1e-12);
        assert!((w.base() - (1.0 - q)).abs() < 1e-12);
        // Opposite octant: 90°+ from everything; d = max_k e·k.
        let e = norm([-1.0, -2.0, -2.0]);
        let w = vb.weights(e);
        assert!(w.keys().is_empty());
        // SPEC 1.1: 1 − max(0, d), exactly the base (v1's 1 − d gave 4/3).
        assert_eq!(w.base(), 1.0);
        // Three keys on a great circle, 120° apart: every in-plane
        // direction is covered, the poles are 90° away.
        let third = 2.0 * std::f64::consts::PI / 3.0;
        let ring: Vec<[f64; 3]> = (0..3)
            .map(|i| [(i as f64 * third).cos(), (i as f64 * third).sin(), 0.0])
            .collect();
        let vb = ViewBlender::new(&ring, 1.0, Uncovered::Cosine).unwrap();
        let w = vb.weights([0.0, 0.0, 1.0]);
        assert!(w.keys().is_empty());
        assert!((w.base() - 1.0).abs() < 1e-12);
        // Midway between keys 0 and 1 in the plane: half each.
        let w = vb.weights([(third / 2.0).cos(), (third / 2.0).sin(), 0.0]);
        assert!((w.weight_of(0) - 0.5).abs() < 1e-12);
        assert!((w.weight_of(1) - 0.5).abs() < 1e-12);
        // Base mode adds both poles: a triangular bipyramid.
        let vb = ViewBlender::new(&ring, 1.0, Uncovered::Base).unwrap();
        assert_eq!(vb.virtual_directions().len(), 2);
        assert!((vb.weights([0.0, 0.0, 1.0]).base() - 1.0).abs() < EPS);
    }

    #[test]
    fn sharpness_pulls_to_nearest_key() {
        let vb1 = ViewBlender::new(&octahedron(), 1.0, Uncovered::Cosine).unwrap();
        let vb4 = ViewBlender::new(&octahedron(), 4.0, Uncovered::Cosine).unwrap();
        let vb50 = ViewBlender::new(&octahedron(), 50.0, Uncovered::Cosine).unwrap();
        let e = [0.6, 0.3, 0.1];
        let (w1, w4, w50) = (vb1.weights(e), vb4.weights(e), vb50.weights(e));
        assert!((w1.weight_of(0) - 0.6).abs() < EPS);
        assert!(w4.weight_of(0) > w1.weight_of(0));
        assert!(w50.weight_of(0) > 1.0 - 1e-12);
        // α < 1 flattens towards equal weights.
        let vbh = ViewBlender::new(&octahedron(), 0.25, Uncovered::Cosine).unwrap();
        let wh = vbh.weights(e);
        assert!(wh.weight_of(0) < w1.weight_of(0) && wh.weight_of(4) > w1.weight_of(4));
        for w in [w1, w4, w50, wh] {
            assert!((sum(&w) - 1.0).abs() < EPS);
        }
    }

    #[test]
    fn empty_and_degenerate_eye() {
        let vb = ViewBlender::new(&[], 1.0, Uncovered::Cosine).unwrap();
        assert_eq!(vb.weights([0.0, 0.0, 1.0]), ViewWeights::base_only());
        let vb = ViewBlender::new(&octahedron(), 1.0, Uncovered::Cosine).unwrap();
        assert_eq!(vb.weights([0.0, 0.0, 0.0]), ViewWeights::base_only());
        assert_eq!(vb.weights([f64::NAN, 0.0, 0.0]), ViewWeights::base_only());
    }

    #[test]
    fn blend_offsets_applies_weights() {
        let base = [Vec3::new(1.0, 2.0, 3.0), Vec3::new(-1.0, 0.0, 1.0)];
        let o0 = [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0)];
        let o1 = [Vec3::new(0.0, 0.0, 4.0), Vec3::new(2.0, 2.0, 2.0)];
        let offsets: [&[Vec3]; 2] = [&o0, &o1];
        let mut w = ViewWeights::base_only();
        w.base = 0.0;
        w.push(0, 0.25);
        w.push(1, 0.75);
        let mut out = [Vec3::ZERO; 2];
        blend_offsets(&base, &offsets, &w, &mut out);
        assert_eq!(out[0], Vec3::new(1.25, 2.0, 6.0));
        assert_eq!(out[1], Vec3::new(0.5, 2.0, 2.5));
        // One key, eye behind it: SPEC 1.1's (1 − max(0,d))·base is
        // exactly the base (v1's (1−d)·base doubled it).
        let vb = ViewBlender::new(&[[0.0, 0.0, 1.0]], 1.0, Uncovered::Cosine).unwrap();
        let w = vb.weights([0.0, 0.0, -1.0]);
        blend_offsets(&base, &offsets, &w, &mut out);
        assert_eq!(out, base);
        // d = 0.6: 0.6·(base + o0) + 0.4·base.
        let w = vb.weights([0.8, 0.0, 0.6]);
        blend_offsets(&base, &offsets, &w, &mut out);
        let want = (base[0] + o0[0]) * 0.6 + base[0] * 0.4;
        assert!((out[0] - want).length() < 1e-6);
    }

    #[test]
    fn accessors_report_what_new_was_given() {
        // Base mode adds −z to the cap; key_count counts the real keys only.
        let vb = ViewBlender::new(&cap(), 2.5, Uncovered::Base).unwrap();
        assert_eq!(vb.virtual_directions().len(), 1);
        assert_eq!((vb.key_count(), vb.sharpness(), vb.mode()), (5, 2.5, Uncovered::Base));
        let vb = ViewBlender::new(&octahedron(), 0.5, Uncovered::Cosine).unwrap();
        assert_eq!((vb.key_count(), vb.sharpness(), vb.mode()), (6, 0.5, Uncovered::Cosine));
    }

    #[test]
    fn base_scale_is_base_plus_key_weights() {
        // Hand-built weights that do not sum to one show the formula.
        let mut w = ViewWeights::base_only();
        w.base = 0.5;
        w.push(0, 0.125);
        w.push(2, 0.25);
        assert_eq!(w.base_scale(), 0.875);
    }

    #[test]
    fn covered_border_is_the_plain_hull_blend() {
        // Cosine mode, eyes on the arcs bounding the cap's cells (its rim
        // and the arcs to +z): covered, so exactly the chord point's
        // barycentric split with no base, not the falloff formula.
        let dirs = cap();
        let vb = ViewBlender::new(&dirs, 1.0, Uncovered::Cosine).unwrap();
        for (i, j) in [(0, 1), (1, 2), (2, 3), (3, 0), (0, 4), (1, 4), (2, 4), (3, 4)] {
            for t in [0.5, 0.25, 0.1] {
                let (a, b) = (dirs[i], dirs[j]);
                let w = vb.weights([0, 1, 2].map(|c| (1.0 - t) * a[c] + t * b[c]));
                assert_eq!(w.base(), 0.0, "{i} {j} {t} {w:?}");
                assert!((w.weight_of(i) - (1.0 - t)).abs() < EPS && (w.weight_of(j) - t).abs() < EPS);
            }
        }
    }

    /// Random sets of unit directions, pairwise at least ~3° apart.
    fn direction_sets() -> impl Strategy<Value = Vec<[f64; 3]>> {
        prop::collection::vec(
            (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0)
                .prop_filter("non-zero", |(x, y, z)| x * x + y * y + z * z > 1e-2)
                .prop_map(|(x, y, z)| norm([x, y, z])),
            1..12,
        )
        .prop_map(|v| {
            let mut out: Vec<[f64; 3]> = Vec::new();
            for d in v {
                if out.iter().all(|o| o[0] * d[0] + o[1] * d[1] + o[2] * d[2] < 0.9986) {
                    out.push(d);
                }
            }
            out
        })
    }

    fn eye() -> impl Strategy<Value = [f64; 3]> {
        (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0)
            .prop_filter("non-zero", |(x, y, z)| x * x + y * y + z * z > 1e-2)
            .prop_map(|(x, y, z)| norm([x, y, z]))
    }

    /// Optionally restrict a set to one hemisphere (uncovered cases).
    fn maybe_hemisphere(dirs: Vec<[f64; 3]>, hemi: bool) -> Vec<[f64; 3]> {
        if hemi {
            dirs.into_iter()
                .map(|d| [d[0], d[1], d[2].abs() + 0.05])
                .map(norm)
                .collect::<Vec<_>>()
        } else {
            dirs
        }
    }

    /// Directions with small integer components: exactly coplanar sets,
    /// closed hemispheres, antipodal pairs and great circles are common.
    fn lattice_sets() -> impl Strategy<Value = Vec<[f64; 3]>> {
        prop::collection::vec((-2i32..=2, -2i32..=2, -2i32..=2), 1..10).prop_map(|v| {
            let mut out: Vec<[f64; 3]> = Vec::new();
            for (x, y, z) in v {
                let d = [x as f64, y as f64, z as f64];
                if (x, y, z) != (0, 0, 0) && !out.iter().any(|o| hull::same_direction(*o, d)) {
                    out.push(d);
                }
            }
            out
        })
    }

    /// Largest weight change when stepping from `p` by `h` along `step`.
    fn jump(vb: &ViewBlender, n: usize, p: [f64; 3], step: [f64; 3], h: f64) -> f64 {
        let q = [p[0] + h * step[0], p[1] + h * step[1], p[2] + h * step[2]];
        max_diff(&dense(&vb.weights(p), n), &dense(&vb.weights(q), n))
    }

    /// Continuity at `p`: a step of length `h` changes no weight by more
    /// than `bound`, or, where near-degenerate hull faces make the weights
    /// steep, a step a thousand times shorter changes them at least five
    /// times less (a jump would not shrink).
    fn assert_continuous(
        vb: &ViewBlender,
        dirs: &[[f64; 3]],
        p: [f64; 3],
        step: [f64; 3],
        h: f64,
        bound: f64,
    ) -> Result<(), TestCaseError> {
        let d1 = jump(vb, dirs.len(), p, step, h);
        if d1 >= bound {
            let d2 = jump(vb, dirs.len(), p, step, h / 1000.0);
            prop_assert!(
                d2 <= d1 / 5.0,
                "{:?} {:?} at {:?}: {} then {}",
                vb.mode(),
                dirs,
                p,
                d1,
                d2
            );
        }
        Ok(())
    }

    /// Continuity where hull pieces meet: near every key (hull vertices)
    /// and at every chord midpoint (hull edges, covered borders).
    fn check_probes(
        vb: &ViewBlender,
        dirs: &[[f64; 3]],
        step: [f64; 3],
        h: f64,
        bound: f64,
    ) -> Result<(), TestCaseError> {
        let mut probes: Vec<[f64; 3]> = dirs.iter().map(|d| norm(*d)).collect();
        let keys = probes.clone();
        for (i, a) in keys.iter().enumerate() {
            for b in &keys[i + 1..] {
                let m = [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
                if m.iter().map(|c| c * c).sum::<f64>() > 1e-6 {
                    probes.push(norm(m));
                }
            }
        }
        for p in probes {
            assert_continuous(vb, dirs, p, step, h, bound)?;
        }
        Ok(())
    }

    /// Nearly degenerate sets: keys on a great circle or in a small cap,
    /// jittered off it by `noise`.
    fn near_degenerate_sets() -> impl Strategy<Value = Vec<[f64; 3]>> {
        (
            prop::collection::vec((0.0f64..std::f64::consts::TAU, -1.0f64..1.0), 3..10),
            prop::sample::select(vec![0.0f64, 1e-9, 1e-7, 1e-6, 1e-5, 1e-3]),
            prop::sample::select(vec![0.0f64, 0.3, 0.99]),
            any::<bool>(),
        )
            .prop_map(|(pts, noise, lift, cap)| {
                let mut out: Vec<[f64; 3]> = Vec::new();
                for (a, j) in pts {
                    let d = if cap {
                        // Small cap around +z of radius 0.05 rad.
                        let r = 0.05 * (j.abs() + 0.1);
                        [r.sin() * a.cos(), r.sin() * a.sin(), r.cos()]
                    } else {
                        let r = (1.0 - lift * lift).sqrt();
                        [r * a.cos(), r * a.sin(), lift + noise * j]
                    };
                    if !out.iter().any(|o| hull::same_direction(*o, d)) {
                        out.push(d);
                    }
                }
                out
            })
    }

    proptest! {
        #[test]
        fn prop_near_degenerate(dirs in near_degenerate_sets(), e in eye(), step in eye()) {
            for mode in [Uncovered::Cosine, Uncovered::Base] {
                let vb = match ViewBlender::new(&dirs, 1.0, mode) {
                    Ok(vb) => vb,
                    Err(ViewError::Hull(msg)) => {
                        // Acceptable only at the limit of f32 precision.
                        eprintln!("hull refused: {msg}");
                        continue;
                    }
                    Err(e) => return Err(TestCaseError::fail(format!("{e}"))),
                };
                let w = vb.weights(e);
                for &(k, wk) in w.keys() {
                    prop_assert!(k < dirs.len() && wk > 0.0 && wk <= 1.0 + 1e-12);
                }
                prop_assert!(w.base().is_finite() && w.base() >= 0.0);
                if mode == Uncovered::Base {
                    prop_assert!((sum(&w) - 1.0).abs() < 1e-9);
                }
                for (k, d) in dirs.iter().enumerate() {
                    let wk = vb.weights(*d);
                    prop_assert_eq!(wk.keys(), &[(k, 1.0)][..]);
                }
                let _ = step;
            }
        }

        #[test]
        fn prop_lattice_sets(dirs in lattice_sets(), e in eye(), step in eye(), alpha in 0.3f64..5.0) {
            let h = 1e-9f64;
            // Weights are Lipschitz for α ≥ 1; for α < 1, b^α makes them
            // Hölder continuous with exponent α near a vertex or edge.
            let bound = 2.0 * (1e5 * h).powf(alpha.min(1.0));
            for mode in [Uncovered::Cosine, Uncovered::Base] {
                let vb = ViewBlender::new(&dirs, alpha, mode).unwrap();
                let w = vb.weights(e);
                // Every mode: a partition of unity (SPEC 1.1 §6).
                prop_assert!((sum(&w) - 1.0).abs() < 1e-9, "{:?}", w);
                assert_continuous(&vb, &dirs, e, step, h, bound)?;
                for (k, d) in dirs.iter().enumerate() {
                    let wk = vb.weights(*d);
                    prop_assert_eq!(wk.keys(), &[(k, 1.0)][..]);
                }
                check_probes(&vb, &dirs, step, h, bound)?;
            }
        }

        #[test]
        fn prop_weights_well_formed(dirs in direction_sets(), hemi in any::<bool>(), e in eye(), alpha in 0.3f64..5.0) {
            let dirs = maybe_hemisphere(dirs, hemi);
            // The hemisphere squash can merge directions; skip those sets.
            prop_assume!(hull::unit_directions(&dirs).is_ok());
            for mode in [Uncovered::Cosine, Uncovered::Base] {
                let vb = ViewBlender::new(&dirs, alpha, mode).unwrap();
                let w = vb.weights(e);
                prop_assert!(w.keys().len() <= 3);
                for &(k, wk) in w.keys() {
                    prop_assert!(k < dirs.len());
                    prop_assert!(wk > 0.0 && wk <= 1.0 + 1e-12);
                }
                prop_assert!(w.base() >= 0.0 && w.base() <= 1.0 + 1e-12);
                // Every mode: a partition of unity (cosine: keys sum to
                // max(0,d), base 1 − max(0,d)).
                prop_assert!((sum(&w) - 1.0).abs() < 1e-9, "{:?}", w);
                // Exact at every key direction.
                for (k, d) in dirs.iter().enumerate() {
                    let wk = vb.weights(*d);
                    prop_assert_eq!(wk.keys(), &[(k, 1.0)][..]);
                    prop_assert_eq!(wk.base(), 0.0);
                }
            }
        }

        #[test]
        fn prop_continuous(dirs in direction_sets(), hemi in any::<bool>(), e in eye(), step in eye()) {
            let dirs = maybe_hemisphere(dirs, hemi);
            prop_assume!(hull::unit_directions(&dirs).is_ok());
            let h = 1e-9;
            for mode in [Uncovered::Cosine, Uncovered::Base] {
                for alpha in [1.0, 3.0] {
                    let vb = ViewBlender::new(&dirs, alpha, mode).unwrap();
                    assert_continuous(&vb, &dirs, e, step, h, 1e-4)?;
                    check_probes(&vb, &dirs, step, h, 1e-4)?;
                }
            }
        }

        #[test]
        fn prop_matches_octahedron_under_rotation(angles in (0.0f64..6.3, 0.0f64..6.3, 0.0f64..6.3), e in eye()) {
            // A rotated octahedron: weights are |e'_i| / Σ|e'_j| in the
            // rotated frame (closed form), whatever the triangulation.
            let r = nalgebra::Rotation3::from_euler_angles(angles.0, angles.1, angles.2);
            let axes: Vec<[f64; 3]> = octahedron()
                .iter()
                .map(|d| { let v = r * Vector3::from(*d); [v.x, v.y, v.z] })
                .collect();
            let vb = ViewBlender::new(&axes, 1.0, Uncovered::Cosine).unwrap();
            let local = r.inverse() * Vector3::from(e);
            let l1 = local.x.abs() + local.y.abs() + local.z.abs();
            let w = vb.weights(e);
            for (axis, c) in [local.x, local.y, local.z].into_iter().enumerate() {
                let k = 2 * axis + usize::from(c < 0.0);
                prop_assert!((w.weight_of(k) - c.abs() / l1).abs() < 1e-9, "{:?}", w);
            }
        }
    }
}
