//! Normalized Gaussian radial basis functions (Bassett et al. 2013 §4.1,
//! eq. 3), kept for comparison with smooth Voronoi.
//!
//! With Gaussian kernels `φ_i(x) = exp(−‖x − x_i‖² / radius²)` (the paper's
//! example kernel at radius 1) and their normalisation
//! `ψ_i(x) = φ_i(x) / Σ_j φ_j(x)`, the interpolant is
//! `ŷ(x) = Σ_i c_i ψ_i(x)`, with coefficients chosen "to guarantee
//! interpolation": `Σ_i c_i ψ_i(x_j) = y_j` for every key j, i.e. `N c = y`
//! with `N_ji = ψ_i(x_j)`. Hence the basis weights `w(x) = N⁻ᵀ ψ(x)`.
//!
//! Because each row of N sums to 1, `N 1 = 1`, so constants are reproduced
//! and the weights sum to 1. The method is exact at keys, C^∞, and
//! satisfies R3, but not R5: the radius must suit the key spacing, and a
//! wide radius makes N ill-conditioned (large, oscillating weights).

use super::{sq_dists_to, InterpError};
use nalgebra::DMatrix;

/// Rejects radii outside [`super::MIN_RADIUS`, `super::MAX_RADIUS`] (NaN
/// included): beyond them 1/radius² overflows or loses its precision.
pub(crate) fn check_radius(radius: f64) -> Result<(), InterpError> {
    if (super::MIN_RADIUS..=super::MAX_RADIUS).contains(&radius) {
        Ok(())
    } else {
        Err(InterpError::InvalidRadius { radius })
    }
}

/// Precomputed normalized Gaussian RBF interpolant for n ≥ 2 keys.
#[derive(Clone, Debug)]
pub(crate) struct Rbf {
    n: usize,
    /// 1 / radius².
    inv_r2: f64,
    /// N⁻¹, n×n row-major: `w_k(x) = Σ_i ψ_i(x) ninv[i*n + k]`.
    ninv: Vec<f64>,
}

/// Normalised Gaussian kernels from squared distances, computed relative to
/// the nearest key so that nothing underflows far away from all keys.
fn normalized_gaussians(r: &[f64], inv_r2: f64, psi: &mut [f64]) {
    let nearest = r.iter().copied().fold(f64::INFINITY, f64::min);
    let mut sum = 0.0;
    for (p, &rk) in psi.iter_mut().zip(r) {
        *p = (-(rk - nearest) * inv_r2).exp();
        sum += *p;
    }
    psi.iter_mut().for_each(|p| *p /= sum);
}

/// Largest entry of N·N⁻¹ − I accepted: weights then match δ_ij at the
/// keys, and sum to 1, to about this much.
const SOLVE_TOLERANCE: f64 = 1e-9;

impl Rbf {
    /// Builds N from the squared key distances `sq` (n×n) and inverts it.
    pub(crate) fn new(n: usize, sq: &[f64], radius: f64) -> Result<Self, InterpError> {
        check_radius(radius)?;
        let inv_r2 = 1.0 / (radius * radius);
        let mut nmat = DMatrix::zeros(n, n);
        let mut psi = vec![0.0; n];
        for j in 0..n {
            normalized_gaussians(&sq[j * n..(j + 1) * n], inv_r2, &mut psi);
            for i in 0..n {
                nmat[(j, i)] = psi[i];
            }
        }
        let inv = nmat.clone().try_inverse().ok_or(InterpError::SingularSystem)?;
        if inv.iter().any(|v| !v.is_finite()) {
            return Err(InterpError::SingularSystem);
        }
        // An inverse found but wrong (a wide radius makes N nearly singular,
        // cond 1e16 at 100× the spacing) gives weights that neither sum to 1
        // nor equal δ_ij at the keys: refuse it rather than bake with it.
        let residual = (&nmat * &inv - DMatrix::<f64>::identity(n, n)).amax();
        if residual.is_nan() || residual > SOLVE_TOLERANCE {
            return Err(InterpError::SingularSystem);
        }
        let mut ninv = vec![0.0; n * n];
        for i in 0..n {
            for k in 0..n {
                ninv[i * n + k] = inv[(i, k)];
            }
        }
        Ok(Rbf { n, inv_r2, ninv })
    }

    /// Basis weights at `x`.
    pub(crate) fn weights(&self, keys: &[f64], dim: usize, x: &[f64], out: &mut [f64]) {
        let n = self.n;
        let mut r = vec![0.0; n];
        sq_dists_to(keys, dim, x, &mut r);
        let mut psi = vec![0.0; n];
        normalized_gaussians(&r, self.inv_r2, &mut psi);
        out.fill(0.0);
        for (i, &p) in psi.iter().enumerate() {
            for (o, v) in out.iter_mut().zip(&self.ninv[i * n..(i + 1) * n]) {
                *o += p * v;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::super::{Interpolator, Method};
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(proptest_config(32))]

        #[test]
        fn exact_at_keys_sums_to_one_and_r3(
            d in prop::sample::select(vec![2usize, 3, 5]),
            n in 2usize..=8,
            seed in any::<u64>(),
        ) {
            let mut rng = Lcg::new(seed);
            let k = rng.below(d.min(n)).max(1).min(d - 1);
            let (keys, normal) = keys_in_subspace(&mut rng, n, d, k);
            // A radius suited to the spacing keeps N well conditioned.
            let radius = 0.5 * min_spacing(&keys, d);
            let it = Interpolator::new(Method::Rbf { radius }, d, &keys).unwrap();
            for j in 0..n {
                let w = it.weights_vec(&keys[j * d..(j + 1) * d]);
                for (i, wi) in w.iter().enumerate() {
                    let target = if i == j { 1.0 } else { 0.0 };
                    prop_assert!((wi - target).abs() < 1e-9, "w_{}(x_{}) = {}", i, j, wi);
                }
            }
            for _ in 0..10 {
                let x = random_point(&mut rng, d, -1.0, 1.0);
                let w = it.weights_vec(&x);
                prop_assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-9);
                // Gaussian kernels satisfy R3 (Bassett §4.1).
                let moved: Vec<f64> = x.iter().zip(&normal).map(|(p, v)| p + 0.7 * v).collect();
                let w2 = it.weights_vec(&moved);
                for i in 0..n {
                    prop_assert!((w[i] - w2[i]).abs() < 1e-9, "w_{} {} vs {}", i, w[i], w2[i]);
                }
            }
        }
    }

    #[test]
    fn far_away_follows_the_nearest_key_and_wide_radius_is_rejected_or_wild() {
        let keys = [0.0, 1.0, 2.0, 4.0];
        let it = Interpolator::new(Method::Rbf { radius: 0.5 }, 1, &keys).unwrap();
        let w = it.weights_vec(&[1e4]);
        assert!(w.iter().all(|v| v.is_finite()));
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        // Wide kernels: poor conditioning shows up as large weights.
        match Interpolator::new(Method::Rbf { radius: 50.0 }, 1, &keys) {
            Ok(wide) => {
                let w = wide.weights_vec(&[3.0]);
                assert!(w.iter().any(|&v| v < -0.3), "{w:?}");
            }
            Err(e) => assert_eq!(e, super::InterpError::SingularSystem),
        }
    }

    #[test]
    fn a_radius_too_wide_to_solve_accurately_is_refused() {
        // Five keys a quarter apart, radius 100: N's condition number is
        // about 4e16, and the inverse nalgebra finds gave weights at key 1
        // summing to 0.48 (a review, 2026-12-06).
        let keys = [0.0, 0.25, 0.5, 0.75, 1.0];
        assert_eq!(
            Interpolator::new(Method::Rbf { radius: 100.0 }, 1, &keys).err(),
            Some(super::super::InterpError::SingularSystem)
        );
        let ok = Interpolator::new(Method::Rbf { radius: 0.25 }, 1, &keys).unwrap();
        let w = ok.weights_vec(&[0.25]);
        assert!(
            (w[1] - 1.0).abs() < 1e-9 && (w.iter().sum::<f64>() - 1.0).abs() < 1e-9,
            "{w:?}"
        );
    }

    #[test]
    fn weights_are_the_papers_normalized_gaussians() {
        // Bassett eq. 3 with φ_i = exp(−‖x − x_i‖² / r²), solved by numpy
        // (np.linalg.solve(N.T, ψ(x))) without the nearest-key shift. The
        // properties above hold for any kernel of ‖x − x_i‖²; these pin
        // the Gaussian and its radius.
        let keys = [0.0, 1.0, 2.0, 4.0];
        for (radius, x, want) in [
            (
                0.5,
                3.0,
                [
                    1.7080289505111982e-4,
                    -9.496437538839617e-3,
                    0.5093271707110429,
                    0.4999984639327456,
                ],
            ),
            (
                1.5,
                2.7,
                [
                    0.2399226690614408,
                    -0.7955323286355852,
                    1.3311525235625499,
                    0.2244571360115943,
                ],
            ),
        ] {
            let it = Interpolator::new(Method::Rbf { radius }, 1, &keys).unwrap();
            let w = it.weights_vec(&[x]);
            for (g, e) in w.iter().zip(want) {
                assert!((g - e).abs() < 1e-9, "radius {radius}, x {x}: {w:?}");
            }
        }
    }
}
