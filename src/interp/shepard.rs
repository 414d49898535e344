//! Shepard interpolation with 1/d² weights (Bassett et al. 2013 §4.1,
//! eq. 5 with φ(r) = 1/r²), kept for comparison with smooth Voronoi.
//!
//! `w_i(x) = ‖x − x_i‖⁻² / Σ_j ‖x − x_j‖⁻²`, and exactly `δ_ij` at key j.
//! Exact at keys, scale-invariant and smooth away from the keys, but its
//! gradient vanishes at every key (stutter on playback, Bassett Fig. 7), and
//! it violates R3 and R7.

use super::sq_dists_to;

/// Basis weights at `x`. Computed relative to the nearest key's squared
/// distance so that neither overflow near a key nor underflow far away occurs.
pub(crate) fn weights(keys: &[f64], dim: usize, x: &[f64], out: &mut [f64]) {
    sq_dists_to(keys, dim, x, out);
    let (nearest, dmin) =
        out.iter().copied().enumerate().fold(
            (0, f64::INFINITY),
            |best, (k, r)| if r < best.1 { (k, r) } else { best },
        );
    if dmin == 0.0 {
        out.fill(0.0);
        out[nearest] = 1.0;
        return;
    }
    let mut sum = 0.0;
    for r in out.iter_mut() {
        *r = dmin / *r;
        sum += *r;
    }
    out.iter_mut().for_each(|w| *w /= sum);
}

#[cfg(test)]
mod tests {
    use super::super::testutil::*;
    use super::super::{Interpolator, Method};
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(proptest_config(32))]

        #[test]
        fn exact_at_keys_partition_of_unity_and_scale_invariant(
            d in prop::sample::select(vec![1usize, 2, 3, 5]),
            n in 1usize..=8,
            seed in any::<u64>(),
        ) {
            let mut rng = Lcg::new(seed);
            let keys = separated_keys(&mut rng, n, d);
            let it = Interpolator::new(Method::Shepard, d, &keys).unwrap();
            for j in 0..n {
                let w = it.weights_vec(&keys[j * d..(j + 1) * d]);
                for (i, wi) in w.iter().enumerate() {
                    prop_assert_eq!(*wi, if i == j { 1.0 } else { 0.0 });
                }
            }
            let s = rng.uniform(0.01, 100.0);
            let scaled: Vec<f64> = keys.iter().map(|v| v * s).collect();
            let it2 = Interpolator::new(Method::Shepard, d, &scaled).unwrap();
            for _ in 0..10 {
                let x = random_point(&mut rng, d, -0.5, 1.5);
                let w = it.weights_vec(&x);
                prop_assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
                prop_assert!(w.iter().all(|&v| (0.0..=1.0).contains(&v)));
                let xs: Vec<f64> = x.iter().map(|v| v * s).collect();
                let w2 = it2.weights_vec(&xs);
                for i in 0..n {
                    prop_assert!((w[i] - w2[i]).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn close_to_a_key_tends_to_it() {
        let it = Interpolator::new(Method::Shepard, 2, &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0]).unwrap();
        let w = it.weights_vec(&[1e-200, 0.0]);
        assert!((w[0] - 1.0).abs() < 1e-15);
    }
}
