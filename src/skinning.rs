//! Stroke skinning (Bassett §3.2, SPEC §3).
//!
//! For every proxy vertex, the least-squares rigid motion (Procrustes) taking
//! its one-ring from the rest pose to the current pose serves as a "bone"; a
//! stroke point moves by the barycentric blend of the 3×4 motions of its bound
//! triangle's vertices (eq. 1). Rest data (one-rings, centroids, centred rest
//! positions) is cached once; per frame only the motions are recomputed.

use glam::{Affine3A, DAffine3, DMat3, DVec3, Mat3A, Vec3, Vec3A};
use nalgebra::Matrix3;
use rayon::prelude::*;

use crate::bind::Binding;
use crate::mesh::OneRings;

/// Relative threshold below which a one-ring is degenerate (SPEC §3): the
/// second singular value of its covariance < 1e-9 × the first.
pub const DEGENERATE_RATIO: f64 = 1e-9;

/// Everything about the rest pose that skinning needs, computed once.
#[derive(Debug, Clone)]
pub struct SkinningRest {
    rings: OneRings,
    /// Rest positions of the ring members, minus the ring centroid, in ring order.
    centred: Vec<DVec3>,
    offsets: Vec<usize>,
    centroids: Vec<DVec3>,
    /// Rings whose rest shape fixes no rotation (SPEC §3): their R is I.
    degenerate: Vec<bool>,
}

impl SkinningRest {
    /// Caches one-ring centroids and centred rest positions.
    pub fn new(rings: OneRings, rest: &[DVec3]) -> Self {
        let mut centred = Vec::new();
        let mut offsets = Vec::with_capacity(rings.len() + 1);
        let mut centroids = Vec::with_capacity(rings.len());
        let mut degenerate = Vec::with_capacity(rings.len());
        offsets.push(0);
        for v in 0..rings.len() {
            let ring = rings.ring(v);
            let c = centroid(ring.iter().map(|&i| rest[i as usize]), ring.len());
            centroids.push(c);
            let start = centred.len();
            centred.extend(ring.iter().map(|&i| rest[i as usize] - c));
            degenerate.push(rest_is_degenerate(&centred[start..]));
            offsets.push(centred.len());
        }
        SkinningRest {
            rings,
            centred,
            offsets,
            centroids,
            degenerate,
        }
    }

    /// Number of proxy vertices.
    pub fn vertex_count(&self) -> usize {
        self.centroids.len()
    }

    /// The rigid motion M_v(x) = R (x − c) + c' of every vertex for a pose.
    pub fn vertex_motions(&self, posed: &[DVec3]) -> Vec<DAffine3> {
        (0..self.vertex_count())
            .into_par_iter()
            .map(|v| self.vertex_motion(v, posed))
            .collect()
    }

    /// The rigid motion of one vertex's one-ring.
    pub fn vertex_motion(&self, v: usize, posed: &[DVec3]) -> DAffine3 {
        let (h, spread, c_posed) = self.cross_covariance(v, posed);
        let r = if self.degenerate[v] {
            DMat3::IDENTITY
        } else {
            crate::polar::fast_rotation(&h, spread).unwrap_or_else(|| svd_rotation(&h))
        };
        // x ↦ R (x − c) + c'
        DAffine3::from_mat3_translation(r, c_posed - r * self.centroids[v])
    }

    /// Vertex `v`'s Procrustes problem in `posed`: H = Σ p qᵀ over its
    /// centred (rest, posed) ring pairs, Σ |p|² + |q|², and the posed centroid.
    pub fn cross_covariance(&self, v: usize, posed: &[DVec3]) -> (DMat3, f64, DVec3) {
        let ring = self.rings.ring(v);
        let rest_centred = &self.centred[self.offsets[v]..self.offsets[v + 1]];
        let c_posed = centroid(ring.iter().map(|&i| posed[i as usize]), ring.len());
        let (h, spread) = cross_covariance(
            rest_centred
                .iter()
                .zip(ring)
                .map(|(&p, &i)| (p, posed[i as usize] - c_posed)),
        );
        (h, spread, c_posed)
    }
}

/// H = Σ p qᵀ and Σ |p|² + |q|² over pairs.
fn cross_covariance(pairs: impl Iterator<Item = (DVec3, DVec3)>) -> (DMat3, f64) {
    let mut h = DMat3::ZERO;
    let mut spread = 0.0;
    for (p, q) in pairs {
        // H_ij = Σ p_i q_j; column j is Σ p q_j.
        h.x_axis += p * q.x;
        h.y_axis += p * q.y;
        h.z_axis += p * q.z;
        spread += p.length_squared() + q.length_squared();
    }
    (h, spread)
}

fn centroid(points: impl Iterator<Item = DVec3>, n: usize) -> DVec3 {
    points.fold(DVec3::ZERO, |a, p| a + p) / n.max(1) as f64
}

/// The rotation R (det +1) minimising Σ |R p − q|² over centred pairs (p, q).
///
/// Kabsch: with H = Σ p qᵀ = U Σ Vᵀ, R = V diag(1, 1, sign det(V Uᵀ)) Uᵀ; the
/// sign term excludes reflections. Returns I when the rest set is degenerate
/// (SPEC §3: the second singular value of Σ p pᵀ < 1e-9 × the first), where
/// the rotation is not determined. The same rotation is found without an SVD
/// where that is well-conditioned ([`crate::polar`]); the SVD decides the rest.
pub fn procrustes_rotation(pairs: impl Iterator<Item = (DVec3, DVec3)>) -> DMat3 {
    let pairs: Vec<_> = pairs.collect();
    if rest_is_degenerate(&pairs.iter().map(|&(p, _)| p).collect::<Vec<_>>()) {
        return DMat3::IDENTITY;
    }
    let (h, spread) = cross_covariance(pairs.into_iter());
    crate::polar::fast_rotation(&h, spread).unwrap_or_else(|| svd_rotation(&h))
}

/// Whether centred rest points fix no rotation (SPEC §3): the second singular
/// value of their covariance C = Σ p pᵀ below 1e-9 × the first, C zero, or C
/// not finite. The rule looks at the rest shape only: a posed ring that
/// collapses (half-way through a linear-blend twist) still has a best
/// rotation, and a rest sliver gets none however it is posed.
pub fn rest_is_degenerate(centred: &[DVec3]) -> bool {
    let mut c = DMat3::ZERO;
    for &p in centred {
        c.x_axis += p * p.x;
        c.y_axis += p * p.y;
        c.z_axis += p * p.z;
    }
    // C's eigenvalues λ₁ ≥ λ₂ ≥ λ₃ ≥ 0 are its singular values. With
    // t = λ₁+λ₂+λ₃ and m = λ₁λ₂+λ₁λ₃+λ₂λ₃ ≤ 3 λ₁λ₂, λ₂/λ₁ ≥ m / (3 t²): most
    // rings are settled by that bound, the few near the threshold by an SVD.
    let t = c.x_axis.x + c.y_axis.y + c.z_axis.z;
    let m = c.x_axis.x * c.y_axis.y - c.y_axis.x * c.y_axis.x + c.x_axis.x * c.z_axis.z - c.z_axis.x * c.z_axis.x
        + c.y_axis.y * c.z_axis.z
        - c.z_axis.y * c.z_axis.y;
    if t.is_finite() && m.is_finite() && t > 0.0 && m >= 2.0 * DEGENERATE_RATIO * 3.0 * t * t {
        return false;
    }
    let svd = Matrix3::from_column_slice(&c.to_cols_array()).svd(false, false);
    let mut s = [svd.singular_values[0], svd.singular_values[1], svd.singular_values[2]];
    s.sort_by(|a, b| b.total_cmp(a));
    !(s[0].is_finite() && s[0] > 0.0 && s[1] >= DEGENERATE_RATIO * s[0])
}

/// [`procrustes_rotation`] of a cross-covariance H by its SVD: the reference,
/// and the fallback for ill-conditioned fits. A rank-deficient H (a posed set
/// collapsed onto a line) gets one of its minimisers; only a zero or
/// non-finite H, where every rotation fits alike or none does, gets I.
pub fn svd_rotation(h: &DMat3) -> DMat3 {
    let h = Matrix3::from_column_slice(&h.to_cols_array());
    let svd = h.svd(true, true);
    let mut s = [svd.singular_values[0], svd.singular_values[1], svd.singular_values[2]];
    s.sort_by(|a, b| b.total_cmp(a));
    if !s[0].is_finite() || s[0] <= 0.0 {
        return DMat3::IDENTITY;
    }
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return DMat3::IDENTITY;
    };
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&nalgebra::Vector3::new(1.0, 1.0, d)) * u.transpose();
    // nalgebra is column-major like glam.
    DMat3::from_cols_slice(r.as_slice())
}

/// Per-vertex motions in f32 for the hot loop.
pub fn to_f32(motions: &[DAffine3]) -> Vec<Affine3A> {
    motions
        .iter()
        .map(|m| Affine3A {
            matrix3: Mat3A::from_cols(
                m.matrix3.x_axis.as_vec3().into(),
                m.matrix3.y_axis.as_vec3().into(),
                m.matrix3.z_axis.as_vec3().into(),
            ),
            translation: m.translation.as_vec3().into(),
        })
        .collect()
}

/// The blended motion M = Σ w_i M_i of one bound point (eq. 1).
#[inline]
pub fn blended_motion(motions: &[Affine3A], vertices: [u32; 3], weights: [f32; 3]) -> Affine3A {
    let [a, b, c] = vertices.map(|i| &motions[i as usize]);
    let [wa, wb, wc] = weights;
    Affine3A {
        matrix3: a.matrix3 * wa + b.matrix3 * wb + c.matrix3 * wc,
        translation: a.translation * wa + b.translation * wb + c.translation * wc,
    }
}

/// What [`skin_points`] saw of its output in the same pass: the points' box
/// ([`crate::extent::point_based_extent`]: usd-core's empty box for none)
/// and whether every coordinate is finite. A bake needs both per layer per
/// frame; gathering them while the points are in registers saves two more
/// passes over them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SkinnedBox {
    pub extent: [Vec3; 2],
    pub finite: bool,
}

/// Points per parallel task.
const SKIN_CHUNK: usize = 4096;

/// Skins rest points: out[k] = frame · (Σ w M_v) · rest[k].
///
/// `frame` maps skinned proxy-local positions into the output space (proxy
/// local-to-world, then the stroke prim's world-to-local); the identity
/// (strokes under the proxy's own transform) is skipped.
pub fn skin_points(
    binding: &Binding,
    motions: &[Affine3A],
    frame: &Affine3A,
    rest: &[Vec3],
    out: &mut [Vec3],
) -> SkinnedBox {
    skin_with(binding, motions, frame, out, |start, _| Some(&rest[start..]))
}

/// [`skin_points`] of keyed rest points Σ w_k a_k (a layer's key blend),
/// blended a block at a time inside the skinning pass rather than into a
/// whole array first.
/// Terms of weight 0 are skipped; the sum runs in f32, in term order, from
/// zero (as [`crate::mesh::weighted_sum`] does).
///
/// # Panics
/// When a term's length differs from `out`'s.
pub fn skin_blended_points(
    binding: &Binding,
    motions: &[Affine3A],
    frame: &Affine3A,
    terms: &[(f64, &[Vec3])],
    out: &mut [Vec3],
) -> SkinnedBox {
    let terms = crate::mesh::f32_terms(terms, out.len());
    match terms[..] {
        [(1.0, a)] => skin_with(binding, motions, frame, out, |start, _| Some(&a[start..])),
        _ => skin_with(binding, motions, frame, out, |start, buf| {
            // Term by term over a block that stays in L1: one vectorisable
            // loop per key array, no per-frame array of blended points.
            buf.fill(Vec3::ZERO);
            for &(w, a) in &terms {
                for (b, &x) in buf.iter_mut().zip(&a[start..]) {
                    *b += x * w;
                }
            }
            None
        }),
    }
}

/// Turns a layer's rest normals with its strokes: out[k] is along
/// frame⁻ᵀ · (Σ w R_v) · rest[k] with rest[k]'s length (zero stays zero).
///
/// Σ w R_v is the linear part of the point's blended motion (eq. 1); the
/// vertex motions are rigid, so each R_v is its own inverse transpose and
/// the sum is the linear-blend normal skinning UsdSkel gives a mesh's
/// normals. Keyed shapes do not turn them (keys hold no normals): a normal
/// follows the rig, not a sculpt.
pub fn skin_normals(binding: &Binding, motions: &[Affine3A], frame: &Affine3A, rest: &[Vec3]) -> Vec<Vec3> {
    // The inverse transpose of the frame's linear part (the identity when
    // it is singular: a normal matrix has nothing better to offer).
    let f = frame.matrix3;
    let f = if f.determinant() != 0.0 {
        f.inverse().transpose()
    } else {
        Mat3A::IDENTITY
    };
    let mut out = vec![Vec3::ZERO; rest.len()];
    out.par_chunks_mut(SKIN_CHUNK).enumerate().for_each(|(chunk, out)| {
        let start = chunk * SKIN_CHUNK;
        for (k, o) in out.iter_mut().enumerate() {
            let i = start + k;
            let n = Vec3A::from(rest[i]);
            let m = blended_motion(motions, binding.vertices[i], binding.weights[i]);
            let v = f * (m.matrix3 * n);
            let len = v.length();
            *o = if len > 0.0 {
                (v * (n.length() / len)).into()
            } else {
                Vec3::ZERO
            };
        }
    });
    out
}

/// Rest points per block of [`skin_with`].
const REST_BLOCK: usize = 256;

/// [`skin_points`] with the rest points of a block from `rest(start, buf)`:
/// those of indices `start..start + buf.len()`, either as a slice of some
/// array (at least `buf.len()` long) or, when it returns `None`, in `buf`.
fn skin_with<'a, R>(binding: &Binding, motions: &[Affine3A], frame: &Affine3A, out: &mut [Vec3], rest: R) -> SkinnedBox
where
    R: Fn(usize, &mut [Vec3]) -> Option<&'a [Vec3]> + Sync,
{
    let framed = *frame != Affine3A::IDENTITY;
    let empty = (Vec3A::splat(f32::MAX), Vec3A::splat(-f32::MAX), Vec3A::ZERO);
    let (lo, hi, nan) = out
        .par_chunks_mut(SKIN_CHUNK)
        .enumerate()
        .map(|(chunk, out)| {
            let (mut lo, mut hi, mut nan) = empty;
            let mut buf = [Vec3::ZERO; REST_BLOCK];
            for (block, out) in out.chunks_mut(REST_BLOCK).enumerate() {
                let start = chunk * SKIN_CHUNK + block * REST_BLOCK;
                let block = &mut buf[..out.len()];
                let rest = match rest(start, block) {
                    Some(points) => points,
                    None => block,
                };
                for (k, (o, &p)) in out.iter_mut().zip(rest).enumerate() {
                    let i = start + k;
                    let m = blended_motion(motions, binding.vertices[i], binding.weights[i]);
                    let mut q = m.transform_point3a(Vec3A::from(p));
                    if framed {
                        q = frame.transform_point3a(q);
                    }
                    lo = lo.min(q);
                    hi = hi.max(q);
                    // q × 0 is ±0 for a finite coordinate, NaN for an infinite or NaN one.
                    nan += q * 0.0;
                    *o = q.into();
                }
            }
            (lo, hi, nan)
        })
        .reduce(|| empty, |a, b| (a.0.min(b.0), a.1.max(b.1), a.2 + b.2));
    SkinnedBox {
        extent: [lo.into(), hi.into()],
        finite: nan == Vec3A::ZERO,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn square_rings() -> (OneRings, Vec<DVec3>) {
        // A small non-planar patch: a pyramid of 5 vertices, 4 triangles.
        let pts = vec![
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(0.0, -1.0, 0.0),
        ];
        let idx = [0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 1];
        (OneRings::new(5, &[3, 3, 3, 3], &idx), pts)
    }

    #[test]
    fn rigid_pose_is_recovered_exactly() {
        let (rings, rest) = square_rings();
        let q = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 0.9);
        let t = DVec3::new(3.0, -1.0, 2.0);
        let posed: Vec<_> = rest.iter().map(|&p| q * p + t).collect();
        let sk = SkinningRest::new(rings, &rest);
        for (v, m) in sk.vertex_motions(&posed).iter().enumerate() {
            assert!((m.transform_point3(rest[v]) - posed[v]).length() < 1e-12);
            assert!((m.matrix3.determinant() - 1.0).abs() < 1e-12);
            // Any point of space moves rigidly with the patch.
            let x = DVec3::new(0.3, 0.7, 2.0);
            assert!((m.transform_point3(x) - (q * x + t)).length() < 1e-12);
        }
    }

    #[test]
    fn the_svd_fit_recovers_a_rotation_and_excludes_a_reflection() {
        // `svd_rotation` is the fast fit's reference and fallback, so it is
        // checked on its own (the fast path answers the other tests).
        // Points ±3x, ±2y, ±1z: centred, with Σ p pᵀ = diag(18, 8, 2).
        let pts = [3.0 * DVec3::X, 2.0 * DVec3::Y, DVec3::Z]
            .into_iter()
            .flat_map(|p| [p, -p]);
        let q = DMat3::from_quat(DQuat::from_axis_angle(DVec3::new(1.0, -2.0, 0.7).normalize(), 2.3));
        let (h, _) = cross_covariance(pts.clone().map(|p| (p, q * p)));
        let r = svd_rotation(&h);
        assert!((r - q).to_cols_array().iter().all(|d| d.abs() < 1e-12), "{r} vs {q}");
        // Mirrored in z: H = diag(18, 8, −2). Every proper rotation moves
        // the x and y points too; the identity errs only on the two z points
        // (Σ |R p − q|² = 8), the least, so the fit is I and not the mirror.
        let mirror = DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0));
        let (h, _) = cross_covariance(pts.map(|p| (p, mirror * p)));
        let r = svd_rotation(&h);
        assert!(
            (r - DMat3::IDENTITY).to_cols_array().iter().all(|d| d.abs() < 1e-12),
            "{r}"
        );
    }

    #[test]
    fn the_svd_fit_of_a_rank_deficient_h_is_a_minimiser() {
        // Σ |R p − q|² = Σ|p|² + Σ|q|² − 2 tr(R H), and the largest tr(R H)
        // over proper rotations is σ₁ + σ₂ + sign·σ₃ (von Neumann), here
        // σ₁ + σ₂ for H = k Q diag(1, ε, 0): any R reaching it is a minimiser.
        let q = DMat3::from_quat(DQuat::from_axis_angle(DVec3::new(0.3, 1.0, -0.4).normalize(), 1.1));
        for eps in [0.0, 1e-10, 1e-8] {
            for k in [1e-3, 1.0, 1e3] {
                let h = q * DMat3::from_diagonal(DVec3::new(1.0, eps, 0.0)) * k;
                let r = svd_rotation(&h);
                let tr = (r * h).to_cols_array().iter().step_by(4).sum::<f64>();
                assert!((tr - k * (1.0 + eps)).abs() <= 1e-12 * k, "ε {eps}, k {k}: tr(RH) {tr}");
                assert!((r.determinant() - 1.0).abs() < 1e-12);
            }
        }
        // Every rotation fits a zero H alike, none a non-finite one: I.
        assert_eq!(svd_rotation(&DMat3::ZERO), DMat3::IDENTITY);
        for bad in [f64::NAN, f64::INFINITY] {
            let mut h = q;
            h.y_axis.z = bad;
            assert_eq!(svd_rotation(&h), DMat3::IDENTITY, "H with {bad}");
        }
    }

    /// An isolated triangle of rest height `height` under a unit base, its
    /// apex lifted by 0.01 in z in the pose: the rings of all three vertices
    /// are the whole triangle.
    fn sliver(height: f64) -> (SkinningRest, Vec<DVec3>) {
        let rest = vec![
            DVec3::new(14.0, 0.0, 0.0),
            DVec3::new(15.0, 0.0, 0.0),
            DVec3::new(14.5, height, 0.0),
        ];
        let mut posed = rest.clone();
        posed[2] = DVec3::new(14.5, 0.0, 0.01);
        (SkinningRest::new(OneRings::new(3, &[3], &[0, 1, 2]), &rest), posed)
    }

    #[test]
    fn a_rest_sliver_gets_the_identity_however_it_is_posed() {
        // SPEC §3 judges the REST ring: centred, the sliver's covariance is
        // diag(1/2, h²·2/3, 0) (x: ±1/2 twice; y: −h/3 twice, 2h/3 once), so
        // σ₂/σ₁ = 4h²/3: 1.3e-12 at h = 1e-6, degenerate, and R = I. The
        // cross-covariance H = Σ p qᵀ mixes in the pose (its σ₂/σ₁ is about
        // 1e-8 here), and the old rule, on H, fitted a quarter turn whose
        // sense followed the sign of h: a stroke 0.3 above went sideways.
        for h in [1e-6, -1e-6] {
            let (sk, posed) = sliver(h);
            for (v, m) in sk.vertex_motions(&posed).iter().enumerate() {
                assert_eq!(m.matrix3, DMat3::IDENTITY, "h {h}, vertex {v}");
                // x ↦ x − c + c': the centroid moves up 0.01/3.
                let c_shift = DVec3::new(0.0, -h / 3.0, 0.01 / 3.0);
                let x = DVec3::new(14.5, 0.0, 0.3);
                assert!((m.transform_point3(x) - (x + c_shift)).length() < 1e-12);
            }
        }
        // 4h²/3 = 1.3e-8 at h = 1e-4: above the ratio, a rotation is fitted.
        let (sk, posed) = sliver(1e-4);
        assert!(sk.vertex_motions(&posed).iter().all(|m| m.matrix3 != DMat3::IDENTITY));
    }

    #[test]
    fn the_degenerate_rule_is_the_ratio_of_the_rest_covariance() {
        // Points ±a x, ±b y: C = diag(2a², 2b², 0), σ₂/σ₁ = b²/a².
        let ring = |b: f64| [DVec3::X, -DVec3::X, DVec3::Y * b, -DVec3::Y * b];
        for scale in [1e-3, 1.0, 1e3] {
            let at = |b: f64| rest_is_degenerate(&ring(b).map(|p| p * scale));
            assert!(at(3e-5), "b²/a² = 9e-10 at scale {scale}");
            assert!(!at(3.2e-5), "b²/a² = 1.02e-9 at scale {scale}");
            assert!(!at(1.0));
        }
        assert!(rest_is_degenerate(&[]));
        assert!(rest_is_degenerate(&[DVec3::ZERO; 3]));
        assert!(rest_is_degenerate(&[DVec3::X, DVec3::NAN, DVec3::Y]));
        assert!(rest_is_degenerate(&[DVec3::X * 2.0, DVec3::X * -1.0, DVec3::X * -1.0]));
    }

    #[test]
    fn a_ring_posed_onto_a_line_gets_a_best_rotation_not_the_identity() {
        // The pyramid's rings, every posed point moved onto the x axis (a
        // linear-blend twist half-way round): H has rank 1, so the fit is a
        // rotation reaching tr(R H) = σ₁ (a minimiser), where I reached less.
        let (rings, rest) = square_rings();
        let posed: Vec<_> = rest
            .iter()
            .map(|p| DVec3::new(p.x + 2.0 * p.y - p.z, 0.0, 0.0))
            .collect();
        let sk = SkinningRest::new(rings, &rest);
        let mut better = 0;
        for (v, m) in sk.vertex_motions(&posed).iter().enumerate() {
            let (h, _, _) = sk.cross_covariance(v, &posed);
            let s = Matrix3::from_column_slice(&h.to_cols_array()).singular_values();
            let sigma1 = s.max();
            let tr = |r: DMat3| (r * h).to_cols_array().iter().step_by(4).sum::<f64>();
            assert!((tr(m.matrix3) - sigma1).abs() <= 1e-12 * sigma1, "vertex {v}");
            assert!((m.matrix3.determinant() - 1.0).abs() < 1e-12);
            if tr(DMat3::IDENTITY) < sigma1 - 1e-9 {
                better += 1;
            }
        }
        assert!(better > 0, "I was a minimiser everywhere: the case tests nothing");
    }

    #[test]
    fn reflection_is_excluded() {
        // A mirrored pose: the best proper rotation is not the mirror.
        let rest = [DVec3::X, DVec3::Y, DVec3::Z, DVec3::ZERO];
        let c = rest.iter().sum::<DVec3>() / 4.0;
        let pairs = rest
            .iter()
            .map(|&p| (p - c, DVec3::new(-(p - c).x, (p - c).y, (p - c).z)));
        let r = procrustes_rotation(pairs);
        assert!((r.determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn degenerate_ring_gives_identity_rotation() {
        // Collinear ring: the second singular value is zero.
        let pairs = [DVec3::X, -DVec3::X].map(|p| (p, DVec3::Y * p.x));
        assert_eq!(procrustes_rotation(pairs.into_iter()), DMat3::IDENTITY);
        // A single point: nothing to fit.
        assert_eq!(
            procrustes_rotation([(DVec3::ZERO, DVec3::ZERO)].into_iter()),
            DMat3::IDENTITY
        );
    }

    #[test]
    fn least_squares_rotation_matches_closed_form_in_2d() {
        // Planar pairs rotated by θ with noise symmetric about the fit: the
        // optimum of Σ|R p − q|² for rotations about z is atan2(Σ p×q, Σ p·q).
        let p = [
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
            DVec3::new(-1.0, -1.0, 0.0),
        ];
        let q = [
            DVec3::new(0.8, 0.7, 0.0),
            DVec3::new(-1.5, 1.2, 0.0),
            DVec3::new(0.3, -1.4, 0.0),
        ];
        let pc = p.iter().sum::<DVec3>() / 3.0;
        let qc = q.iter().sum::<DVec3>() / 3.0;
        let pairs: Vec<_> = p.iter().zip(&q).map(|(&a, &b)| (a - pc, b - qc)).collect();
        let (mut s, mut c) = (0.0, 0.0);
        for (a, b) in &pairs {
            s += a.x * b.y - a.y * b.x;
            c += a.x * b.x + a.y * b.y;
        }
        let theta = s.atan2(c);
        let r = procrustes_rotation(pairs.into_iter());
        let expected = DMat3::from_rotation_z(theta);
        assert!((r - expected).to_cols_array().iter().all(|x| x.abs() < 1e-10));
    }

    #[test]
    fn blend_and_frame_apply_in_order() {
        let motions = vec![
            Affine3A::from_translation(Vec3::X),
            Affine3A::from_translation(Vec3::Y),
            Affine3A::from_translation(Vec3::Z),
        ];
        let binding = Binding {
            vertices: vec![[0, 1, 2]],
            weights: vec![[0.5, 0.25, 0.25]],
        };
        let frame = Affine3A::from_scale(Vec3::splat(2.0));
        let mut out = vec![Vec3::ZERO];
        skin_points(&binding, &motions, &frame, &[Vec3::ONE], &mut out);
        assert!((out[0] - Vec3::new(3.0, 2.5, 2.5)).length() < 1e-6);
    }

    #[test]
    fn blended_rest_points_skin_as_their_weighted_sum() {
        let motions = vec![
            Affine3A::from_translation(Vec3::X),
            Affine3A::from_rotation_z(0.3),
            Affine3A::from_scale(Vec3::splat(2.0)),
        ];
        let binding = Binding {
            vertices: vec![[0, 1, 2]; 3],
            weights: vec![[0.5, 0.25, 0.25]; 3],
        };
        let a = [Vec3::ONE, Vec3::new(-1.0, 2.0, 0.5), Vec3::Z];
        let b = [Vec3::X, Vec3::Y, Vec3::new(3.0, -2.0, 1.0)];
        let terms: [(f64, &[Vec3]); 3] = [(0.25, &a), (0.0, &[]), (0.75, &b)];
        let mut summed = vec![Vec3::ZERO; 3];
        crate::mesh::weighted_sum(&mut summed, &terms);
        let frame = Affine3A::from_translation(Vec3::new(0.0, 1.0, -1.0));
        let (mut want, mut got) = (vec![Vec3::ZERO; 3], vec![Vec3::ZERO; 3]);
        let want_box = skin_points(&binding, &motions, &frame, &summed, &mut want);
        assert_eq!(
            skin_blended_points(&binding, &motions, &frame, &terms, &mut got),
            want_box
        );
        assert_eq!(got, want);
        // One term of weight 1 is that array itself.
        skin_points(&binding, &motions, &frame, &b, &mut want);
        skin_blended_points(&binding, &motions, &frame, &[(1.0, &b)], &mut got);
        assert_eq!(got, want);
    }

    #[test]
    fn every_block_of_every_chunk_skins_its_own_points() {
        // Points spanning two parallel chunks and several rest blocks each,
        // every one with its own binding and rest point, against eq. 1 per
        // point: Σ w_j M_j p (the blended matrix applied, up to rounding).
        let mut rng = crate::interp::testutil::Lcg::new(4);
        let mut v = || Vec3::new(rng.unit() as f32, rng.unit() as f32, rng.unit() as f32) * 2.0 - 1.0;
        let motions: Vec<Affine3A> = (0..11)
            .map(|_| Affine3A::from_scale_rotation_translation(Vec3::ONE, glam::Quat::from_rotation_y(v().x), v()))
            .collect();
        let n = SKIN_CHUNK + 3 * REST_BLOCK + 5;
        let binding = Binding {
            vertices: (0..n)
                .map(|i| [i % 11, (i / 11) % 11, (i / 121) % 11].map(|x| x as u32))
                .collect(),
            weights: (0..n)
                .map(|i| {
                    let a = (i % 7) as f32 / 10.0;
                    [a, 0.8 - a, 0.2]
                })
                .collect(),
        };
        let (a, b): (Vec<Vec3>, Vec<Vec3>) = (0..n).map(|_| (v(), v())).unzip();
        let frame = Affine3A::from_translation(Vec3::new(0.5, 0.0, -0.25));
        let eq1 = |i: usize, p: Vec3| {
            let q: Vec3 = (0..3)
                .map(|j| motions[binding.vertices[i][j] as usize].transform_point3(p) * binding.weights[i][j])
                .sum();
            frame.transform_point3(q)
        };
        let mut out = vec![Vec3::ZERO; n];
        skin_points(&binding, &motions, &frame, &a, &mut out);
        for (i, (o, &p)) in out.iter().zip(&a).enumerate() {
            assert!((*o - eq1(i, p)).length() < 1e-5, "point {i}: {o} vs {}", eq1(i, p));
        }
        skin_blended_points(&binding, &motions, &frame, &[(0.25, &a), (0.75, &b)], &mut out);
        for (i, o) in out.iter().enumerate() {
            let want = eq1(i, a[i] * 0.25 + b[i] * 0.75);
            assert!((*o - want).length() < 1e-5, "blended point {i}: {o} vs {want}");
        }
    }

    #[test]
    fn skinned_box_is_the_extent_and_finiteness_of_the_output() {
        use crate::extent::point_based_extent;
        let mut rng = crate::interp::testutil::Lcg::new(9);
        let mut v = || Vec3::new(rng.unit() as f32, rng.unit() as f32, rng.unit() as f32) * 4.0 - 2.0;
        let motions: Vec<Affine3A> = (0..7)
            .map(|_| {
                Affine3A::from_scale_rotation_translation(v().abs() + 0.5, glam::Quat::from_rotation_z(v().x), v())
            })
            .collect();
        // More points than one parallel chunk, so chunks are reduced.
        let n = 2 * SKIN_CHUNK + 17;
        let binding = Binding {
            vertices: (0..n)
                .map(|i| [i % 7, (i + 3) % 7, (i + 5) % 7].map(|x| x as u32))
                .collect(),
            weights: vec![[0.5, 0.3, 0.2]; n],
        };
        let rest: Vec<Vec3> = (0..n).map(|_| v()).collect();
        let mut out = vec![Vec3::ZERO; n];
        for frame in [
            Affine3A::IDENTITY,
            Affine3A::from_translation(Vec3::new(1.0, -2.0, 0.5)),
        ] {
            let got = skin_points(&binding, &motions, &frame, &rest, &mut out);
            assert_eq!(
                got,
                SkinnedBox {
                    extent: point_based_extent(&out),
                    finite: true
                }
            );
        }
        // No points: usd-core's empty box.
        let none = skin_points(&Binding::default(), &motions, &Affine3A::IDENTITY, &[], &mut []);
        assert_eq!(none.extent, point_based_extent(&[]));
        assert!(none.finite);
        // One infinite or NaN coordinate anywhere is seen.
        for bad in [f32::INFINITY, f32::NEG_INFINITY, f32::NAN] {
            let mut rest = rest.clone();
            rest[n - 3].y = bad;
            assert!(
                !skin_points(&binding, &motions, &Affine3A::IDENTITY, &rest, &mut out).finite,
                "{bad}"
            );
        }
    }

    #[test]
    fn normals_turn_by_the_blended_rotation_then_the_frames_inverse_transpose() {
        // Two vertex motions: a quarter turn about z and the identity; a
        // point weighted 1 to the turn, one 1/2 each, one at a zero normal.
        let turn = Affine3A::from_rotation_z(std::f32::consts::FRAC_PI_2);
        let motions = [turn, Affine3A::IDENTITY];
        let binding = Binding {
            vertices: vec![[0, 1, 1], [0, 1, 1], [0, 1, 1]],
            weights: vec![[1.0, 0.0, 0.0], [0.5, 0.5, 0.0], [1.0, 0.0, 0.0]],
        };
        // A frame that stretches y by 2 (and moves: translation is no part
        // of a normal's turn): normals scale by its inverse transpose, 1/2 in y.
        let frame = Affine3A::from_scale_rotation_translation(
            Vec3::new(1.0, 2.0, 1.0),
            glam::Quat::IDENTITY,
            Vec3::new(5.0, 6.0, 7.0),
        );
        let rest = [Vec3::new(3.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0), Vec3::ZERO];
        let out = skin_normals(&binding, &motions, &frame, &rest);
        // x turned to y, then halved in y: along y, rest length 3.
        assert!((out[0] - Vec3::new(0.0, 3.0, 0.0)).length() < 1e-6, "{}", out[0]);
        // z is fixed by both motions and by the frame: unchanged.
        assert!((out[1] - Vec3::new(0.0, 0.0, 2.0)).length() < 1e-6, "{}", out[1]);
        assert_eq!(out[2], Vec3::ZERO);
        // A blend of the turn and the identity on x: (1/2, 1/2, 0), then
        // (1/2, 1/4, 0) through the frame, rescaled to length 1.
        let out = skin_normals(&binding, &motions, &frame, &[Vec3::X, Vec3::X, Vec3::X]);
        let want = Vec3::new(0.5, 0.25, 0.0).normalize();
        assert!((out[1] - want).length() < 1e-6, "{}", out[1]);
        // A singular frame leaves the turn alone.
        let flat = Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0));
        let out = skin_normals(&binding, &motions, &flat, &[Vec3::X, Vec3::X, Vec3::X]);
        assert!((out[0] - Vec3::Y).length() < 1e-6, "{}", out[0]);
        // Past the first parallel chunk each point still gets its own
        // normal (a missed mutant: chunk / SKIN_CHUNK as the start).
        let n = 2 * SKIN_CHUNK + 7;
        let still = Binding {
            vertices: vec![[1, 1, 1]; n],
            weights: vec![[1.0, 0.0, 0.0]; n],
        };
        let rest: Vec<Vec3> = (0..n).map(|i| Vec3::new(1.0, i as f32, 0.5)).collect();
        let out = skin_normals(&still, &motions, &Affine3A::IDENTITY, &rest);
        assert_eq!(out, rest);
    }
}
