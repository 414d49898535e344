//! The rotation of a 3×3 Procrustes fit without an SVD (Horn 1987).
//!
//! For a cross-covariance H = Σ p qᵀ of centred pairs, the proper rotation R
//! maximising Σ qᵀ R p is the unit quaternion of the largest eigenvalue of
//! Horn's symmetric, traceless 4×4 matrix N(H). Its largest eigenvalue is
//! found by Newton's method on the characteristic quartic (Theobald 2005,
//! "QCP"), started above the root so that it descends monotonically; the
//! eigenvector is the best-scaled column of adj(N − λI). This costs a few
//! hundred flops against an SVD's thousands.
//!
//! The eigenvector is accurate when λ is well separated from N's second
//! eigenvalue: the gap is 2(σ₂ + sign(det H) σ₃), small for near-collinear
//! rings and for reflected rings with σ₂ ≈ σ₃. [`fast_rotation`] declines
//! those (`None`) and the caller falls back to the SVD, so degenerate rings
//! are decided exactly as before.

use glam::{DMat3, DQuat, DVec4};

/// Below this conditioning estimate (|tr adj(N − λI)| / ‖H‖³, a lower bound
/// on the eigen-gap product), the fast path declines. Chosen so that the
/// eigenvector's rounding error stays under about 1e-12.
const MIN_CONDITIONING: f64 = 0.02;

/// The optimal proper rotation for cross-covariance `h` (H = Σ p qᵀ,
/// so R p ≈ q), or `None` when the fit is too ill-conditioned for this
/// method (degenerate, near-collinear or near-symmetric reflected rings).
///
/// `spread` is Σ |p|² + Σ |q|² when known (it gives Newton a close start for
/// near-rigid motion), else `f64::INFINITY`.
pub fn fast_rotation(h: &DMat3, spread: f64) -> Option<DMat3> {
    let f2 = h.x_axis.length_squared() + h.y_axis.length_squared() + h.z_axis.length_squared();
    let f = f2.sqrt();
    if !(f.is_finite() && f > f64::MIN_POSITIVE) {
        return None;
    }
    // Scale to ‖S‖ = 1: the rotation is unchanged and all terms stay O(1).
    let s = *h * (1.0 / f);
    // S_ab = Σ p_a q_b = column b, row a (glam is column-major).
    let (sxx, sxy, sxz) = (s.x_axis.x, s.y_axis.x, s.z_axis.x);
    let (syx, syy, syz) = (s.x_axis.y, s.y_axis.y, s.z_axis.y);
    let (szx, szy, szz) = (s.x_axis.z, s.y_axis.z, s.z_axis.z);
    let n = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    // det(λI − N) = λ⁴ + c2 λ² + c1 λ + c0 (N is traceless).
    let c2 = -2.0; // −2 ‖S‖²
    let c1 = -8.0 * s.determinant();
    let c0 = det4(&n);
    // Upper bounds on λmax: σ₁+σ₂+σ₃ ≤ √3 ‖S‖, and (Σ|p|²+Σ|q|²)/2 since
    // Σ|Rp − q|² ≥ 0. Newton from above a polynomial's largest real root
    // decreases monotonically to it.
    let mut lambda = (0.5 * spread / f).min(3f64.sqrt());
    for _ in 0..64 {
        let l2 = lambda * lambda;
        let p = (l2 + c2) * l2 + c1 * lambda + c0;
        let dp = (4.0 * l2 + 2.0 * c2) * lambda + c1;
        if dp.is_nan() || dp <= 0.0 {
            break;
        }
        let next = lambda - p / dp;
        if next.is_nan() || next >= lambda {
            break; // converged to rounding noise
        }
        let step = lambda - next;
        lambda = next;
        if step <= 1e-15 * lambda.abs().max(1.0) {
            break;
        }
    }
    let mut m = n;
    for (i, row) in m.iter_mut().enumerate() {
        row[i] -= lambda;
    }
    // adj(M) = Π_{j≠1}(λ_j − λ₁) v vᵀ: its diagonal gives the best column.
    let diag = [0, 1, 2, 3].map(|j| cofactor(&m, j, j));
    let trace: f64 = diag.iter().sum();
    // −trace = g₂ g₃ g₄ (the gaps to the other eigenvalues, each ≤ 4).
    if trace.is_nan() || -trace < MIN_CONDITIONING {
        return None;
    }
    let j = (0..4)
        .max_by(|&a, &b| diag[a].abs().total_cmp(&diag[b].abs()))
        .unwrap_or(0);
    let v = DVec4::from_array([0, 1, 2, 3].map(|i| cofactor(&m, j, i)));
    let len = v.length();
    if !(len.is_finite() && len > 0.0) {
        return None;
    }
    let v = v / len;
    // Horn's quaternion is (w, x, y, z).
    let q = DQuat::from_xyzw(v.y, v.z, v.w, v.x);
    Some(DMat3::from_quat(q))
}

/// (−1)^{r+c} det of `m` without row `r` and column `c`.
fn cofactor(m: &[[f64; 4]; 4], r: usize, c: usize) -> f64 {
    let rows = others(r);
    let cols = others(c);
    let a = |i: usize, k: usize| m[rows[i]][cols[k]];
    let d = a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) - a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0))
        + a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
    if (r + c).is_multiple_of(2) {
        d
    } else {
        -d
    }
}

fn others(i: usize) -> [usize; 3] {
    match i {
        0 => [1, 2, 3],
        1 => [0, 2, 3],
        2 => [0, 1, 3],
        _ => [0, 1, 2],
    }
}

fn det4(m: &[[f64; 4]; 4]) -> f64 {
    // Laplace expansion by 2×2 minors of the first two rows.
    let s0 = m[0][0] * m[1][1] - m[1][0] * m[0][1];
    let s1 = m[0][0] * m[1][2] - m[1][0] * m[0][2];
    let s2 = m[0][0] * m[1][3] - m[1][0] * m[0][3];
    let s3 = m[0][1] * m[1][2] - m[1][1] * m[0][2];
    let s4 = m[0][1] * m[1][3] - m[1][1] * m[0][3];
    let s5 = m[0][2] * m[1][3] - m[1][2] * m[0][3];
    let c5 = m[2][2] * m[3][3] - m[3][2] * m[2][3];
    let c4 = m[2][1] * m[3][3] - m[3][1] * m[2][3];
    let c3 = m[2][1] * m[3][2] - m[3][1] * m[2][2];
    let c2 = m[2][0] * m[3][3] - m[3][0] * m[2][3];
    let c1 = m[2][0] * m[3][2] - m[3][0] * m[2][2];
    let c0 = m[2][0] * m[3][1] - m[3][0] * m[2][1];
    s0 * c5 - s1 * c4 + s2 * c3 + s3 * c2 - s4 * c1 + s5 * c0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skinning::{procrustes_rotation, svd_rotation};
    use glam::DVec3;
    use proptest::prelude::*;

    fn cross_covariance(pairs: &[(DVec3, DVec3)]) -> (DMat3, f64) {
        let mut h = DMat3::ZERO;
        let mut spread = 0.0;
        for &(p, q) in pairs {
            h.x_axis += p * q.x;
            h.y_axis += p * q.y;
            h.z_axis += p * q.z;
            spread += p.length_squared() + q.length_squared();
        }
        (h, spread)
    }

    /// An optimality certificate for rotation `r` of cross-covariance `h`,
    /// independent of any SVD: at the optimum A = R H is symmetric and its
    /// eigenvalues a₁ ≥ a₂ ≥ a₃ have a₂ + a₃ ≥ 0 (turning in any plane
    /// lowers tr A). Returns ‖A − Aᵀ‖ / (a₂ + a₃), about the angle by which
    /// `r` misses the optimum, or infinity when the optimum is not unique.
    fn distance_from_optimum(r: &DMat3, h: &DMat3) -> f64 {
        let scale = h.to_cols_array().iter().map(|x| x * x).sum::<f64>().sqrt();
        let a = *r * *h * (1.0 / scale);
        let asym = (a - a.transpose())
            .to_cols_array()
            .iter()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        let sym = (a + a.transpose()) * 0.5;
        let m = nalgebra::Matrix3::from_column_slice(&sym.to_cols_array());
        let mut e: Vec<f64> = m.symmetric_eigenvalues().iter().copied().collect();
        e.sort_by(|x, y| y.total_cmp(x));
        let gap = e[1] + e[2];
        if gap > 0.0 {
            asym / gap
        } else {
            f64::INFINITY
        }
    }

    fn max_diff(a: &DMat3, b: &DMat3) -> f64 {
        (*a - *b).to_cols_array().iter().fold(0.0, |m, x| m.max(x.abs()))
    }

    fn centred(points: Vec<DVec3>) -> Vec<DVec3> {
        let c = points.iter().sum::<DVec3>() / points.len() as f64;
        points.into_iter().map(|p| p - c).collect()
    }

    fn vec3() -> impl Strategy<Value = DVec3> {
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(x, y, z)| DVec3::new(x, y, z))
    }

    fn rotation() -> impl Strategy<Value = glam::DQuat> {
        (vec3(), 0.0..std::f64::consts::PI).prop_map(|(axis, angle)| {
            let axis = if axis.length() > 1e-3 {
                axis.normalize()
            } else {
                DVec3::Z
            };
            glam::DQuat::from_axis_angle(axis, angle)
        })
    }

    /// Checks the fit of `pairs` against the SVD. Returns whether the fast
    /// path answered.
    fn check(pairs: &[(DVec3, DVec3)]) -> Result<bool, TestCaseError> {
        let (h, spread) = cross_covariance(pairs);
        let fast = fast_rotation(&h, spread);
        let r = procrustes_rotation(pairs.iter().copied());
        let rest: Vec<DVec3> = pairs.iter().map(|&(p, _)| p).collect();
        if crate::skinning::rest_is_degenerate(&rest) {
            // SPEC §3: no rotation is fitted to a degenerate rest ring.
            prop_assert_eq!(r, DMat3::IDENTITY);
            return Ok(fast.is_some());
        }
        match fast {
            Some(f) => {
                prop_assert!(
                    distance_from_optimum(&f, &h) < 1e-10,
                    "fast {f} is not optimal for H = {h}"
                );
                // Wherever the SVD is accurate itself, the two agree.
                let svd = svd_rotation(&h);
                if distance_from_optimum(&svd, &h) < 1e-12 {
                    prop_assert!(max_diff(&f, &svd) < 1e-9, "fast {f} vs svd {svd} for H = {h}");
                }
                prop_assert!((f.determinant() - 1.0).abs() < 1e-12);
                prop_assert!(max_diff(&(f * f.transpose()), &DMat3::IDENTITY) < 1e-12);
                prop_assert_eq!(r, f);
            }
            // Ill-conditioned: decided by the SVD exactly as before.
            None => prop_assert_eq!(r, svd_rotation(&h)),
        }
        Ok(fast.is_some())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        #[test]
        fn rigid_and_noisy_rings_match_the_svd(
            points in prop::collection::vec(vec3(), 3..12),
            q in rotation(),
            noise in prop::collection::vec(vec3(), 12),
            amount in 0.0..0.5f64,
            scale in -6i32..6,
        ) {
            let k = 10f64.powi(scale);
            let p = centred(points.iter().map(|&p| p * k).collect());
            let posed = centred(p.iter().zip(&noise).map(|(&x, &n)| q * x + n * amount * k).collect());
            let pairs: Vec<_> = p.into_iter().zip(posed).collect();
            check(&pairs)?;
        }

        #[test]
        fn random_covariances_match_the_svd(cols in prop::collection::vec(vec3(), 3), scale in -30i32..30) {
            let k = 10f64.powi(scale);
            let h = DMat3::from_cols(cols[0] * k, cols[1] * k, cols[2] * k);
            if let Some(r) = fast_rotation(&h, f64::INFINITY) {
                prop_assert!(distance_from_optimum(&r, &h) < 1e-10, "fast {r} is not optimal for H = {h}");
                let svd = svd_rotation(&h);
                if distance_from_optimum(&svd, &h) < 1e-12 {
                    prop_assert!(max_diff(&r, &svd) < 1e-9, "fast {r} vs svd {svd} for H = {h}");
                }
            }
        }

        #[test]
        fn covariances_of_known_svd_give_their_rotation(
            u in rotation(),
            v in rotation(),
            s1 in 0.0..1.0f64,
            s2 in -1.0..1.0f64,
            scale in -8i32..8,
        ) {
            // H = U diag(1, σ₂, σ₃) Vᵀ with U, V rotations and |σ₃| ≤ σ₂ ≤ 1
            // (σ₃ < 0: a reflected ring). The best rotation is V Uᵀ, unique
            // when σ₂ + σ₃ > 0; the fast path must find it or decline.
            let s2 = s2 * s1;
            let (u, v) = (DMat3::from_quat(u), DMat3::from_quat(v));
            let h = u * DMat3::from_diagonal(DVec3::new(1.0, s1, s2)) * v.transpose() * 10f64.powi(scale);
            let expected = v * u.transpose();
            match fast_rotation(&h, f64::INFINITY) {
                Some(r) => prop_assert!(max_diff(&r, &expected) < 1e-9, "fast {r} vs {expected} for σ = 1, {s1}, {s2}"),
                None => prop_assert!(s1 + s2 < 0.1, "declined a conditioned fit: σ = 1, {s1}, {s2}"),
            }
        }

        #[test]
        fn reflected_rings_match_the_svd(
            points in prop::collection::vec(vec3(), 4..10),
            q in rotation(),
            mirror in 0usize..3,
            noise in prop::collection::vec(vec3(), 10),
            amount in 0.0..0.2f64,
        ) {
            let p = centred(points);
            let posed = centred(p.iter().zip(&noise).map(|(&x, &n)| {
                let mut y = q * x;
                y[mirror] = -y[mirror];
                y + n * amount
            }).collect());
            let pairs: Vec<_> = p.into_iter().zip(posed).collect();
            check(&pairs)?;
        }

        #[test]
        fn near_degenerate_rings_match_the_svd(
            points in prop::collection::vec(vec3(), 3..10),
            q in rotation(),
            flat in -14i32..0,
            thin in -14i32..1,
            noise in prop::collection::vec(vec3(), 10),
            amount in -14i32..-1,
        ) {
            // Squash the rest ring towards a plane (flat) and a line (thin):
            // rank-1 and rank-2 covariances and everything near them.
            let squash = DVec3::new(1.0, 10f64.powi(thin), 10f64.powi(flat));
            let p = centred(points.iter().map(|&x| x * squash).collect());
            let e = 10f64.powi(amount);
            let posed = centred(p.iter().zip(&noise).map(|(&x, &n)| q * x + n * e).collect());
            let pairs: Vec<_> = p.into_iter().zip(posed).collect();
            check(&pairs)?;
        }
    }

    #[test]
    fn nearly_equal_singular_values_are_fitted_accurately() {
        // H of a Dog bench proxy vertex (σ = 0.96390, 0.96387, 0.0279), where
        // `svd_rotation` (nalgebra's HᵀH-based 3×3 SVD) is off by 7.7e-5.
        // Expected: numpy's LAPACK SVD.
        let h = DMat3::from_cols_array(&[
            0.9329430781584718,
            0.005213665936192357,
            -0.16472254723352833,
            -0.1757733849864087,
            0.027409085500019213,
            0.025859534026756822,
            0.16664712612301977,
            0.0007339476398934129,
            0.9493713334289814,
        ]);
        let expected = DMat3::from_cols_array(&[
            0.967877602339356,
            -0.18253479528688457,
            0.1728988010351576,
            0.1843237635438115,
            0.9828485221834622,
            0.005790736985047076,
            -0.17099034207482286,
            0.026264633090147708,
            0.9849225715586862,
        ]);
        let r = fast_rotation(&h, f64::INFINITY).expect("fast path");
        assert!(max_diff(&r, &expected) < 1e-12, "{}", max_diff(&r, &expected));
        assert!(distance_from_optimum(&r, &h) < 1e-12);
    }

    #[test]
    fn well_conditioned_fits_take_the_fast_path() {
        // A non-planar ring in a rigid pose: no SVD needed.
        let p = centred(vec![DVec3::X, DVec3::Y, DVec3::Z, DVec3::new(-1.0, -0.5, 0.2)]);
        let q = glam::DQuat::from_axis_angle(DVec3::new(1.0, -2.0, 0.3).normalize(), 2.5);
        let pairs: Vec<_> = p.iter().map(|&x| (x, q * x)).collect();
        let (h, spread) = cross_covariance(&pairs);
        let r = fast_rotation(&h, spread).expect("fast path");
        assert!(max_diff(&r, &DMat3::from_quat(q)) < 1e-13);
        // A planar ring too (rank-2 covariance).
        let p = centred(vec![DVec3::X, DVec3::Y, -DVec3::X, DVec3::new(0.3, -1.0, 0.0)]);
        let pairs: Vec<_> = p.iter().map(|&x| (x, q * x)).collect();
        let (h, spread) = cross_covariance(&pairs);
        let r = fast_rotation(&h, spread).expect("fast path");
        assert!(max_diff(&r, &DMat3::from_quat(q)) < 1e-13);
    }

    #[test]
    fn degenerate_and_non_finite_fits_decline() {
        // Collinear ring (rank 1), empty, NaN: the SVD decides (identity).
        let pairs = [DVec3::X, -DVec3::X].map(|p| (p, DVec3::Y * p.x));
        let (h, spread) = cross_covariance(&pairs);
        assert_eq!(fast_rotation(&h, spread), None);
        assert_eq!(fast_rotation(&DMat3::ZERO, 0.0), None);
        assert_eq!(fast_rotation(&DMat3::from_diagonal(DVec3::splat(f64::NAN)), 1.0), None);
        // Finite entries whose squares overflow: ‖H‖ is infinite, and
        // scaling by 1/‖H‖ would erase H (the SVD decides instead).
        let huge = DMat3::from_quat(glam::DQuat::from_rotation_z(0.7)) * 1e200;
        assert!(huge.is_finite());
        assert_eq!(fast_rotation(&huge, f64::INFINITY), None);
        // A ring as wide along y as along z, mirrored in z: H = diag(4, 1, −1),
        // every rotation about x is optimal (σ₂ = σ₃ with det H < 0), so the
        // fit is left to the SVD.
        let p = [
            2.0 * DVec3::X,
            -2.0 * DVec3::X,
            DVec3::Y,
            -DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
        ]
        .to_vec();
        let pairs: Vec<_> = p.iter().map(|&x| (x, DVec3::new(x.x, x.y, -x.z))).collect();
        let (h, spread) = cross_covariance(&pairs);
        assert_eq!(fast_rotation(&h, spread), None);
    }
}
