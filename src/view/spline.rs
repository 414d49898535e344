//! Natural cubic spline over key times (Rademacher §4.2): each key
//! viewpoint of an animated base model has deformation offsets at a few key
//! times; they are interpolated over time and added to the animated base.
//!
//! The spline is linear in its data, so it is precomputed once for the key
//! times and evaluated as *weights over the key times*:
//! `value(t) = Σ c_k(t) · y_k`. One weight vector then blends a whole point
//! array of offsets ([`weighted_sum`]).

use glam::Vec3;

use super::ViewError;

/// A natural cubic spline through values at fixed key times.
///
/// * Interpolates: exact at every key time.
/// * Natural: second derivative zero at the first and last key time.
/// * Held: constant (first / last key value) before the first and after the
///   last key time.
/// * One key time: constant. Two: linear between them.
#[derive(Clone, Debug)]
pub struct NaturalCubicSpline {
    times: Vec<f64>,
    /// Row-major `n × n`: second derivative at knot `i` is
    /// `Σ_k second[i·n + k] · y_k` (zero rows at both ends).
    second: Vec<f64>,
}

impl NaturalCubicSpline {
    /// Precomputes the spline for `times`, which must be finite and strictly
    /// increasing (at least one).
    pub fn new(times: &[f64]) -> Result<Self, ViewError> {
        if times.is_empty() {
            return Err(ViewError::NoKeyTimes);
        }
        if let Some(index) = times.iter().position(|t| !t.is_finite()) {
            return Err(ViewError::NonFiniteTime { index });
        }
        if let Some(index) = (1..times.len()).find(|&i| times[i] <= times[i - 1]) {
            return Err(ViewError::TimesNotIncreasing { index });
        }
        let n = times.len();
        let mut second = vec![0.0; n * n];
        if n >= 3 {
            let h: Vec<f64> = times.windows(2).map(|w| w[1] - w[0]).collect();
            // Interior equations i = 1..n-2:
            // h[i-1]·M[i-1] + 2(h[i-1]+h[i])·M[i] + h[i]·M[i+1]
            //   = 6·((y[i+1]−y[i])/h[i] − (y[i]−y[i-1])/h[i-1]),  M[0] = M[n-1] = 0.
            let m = n - 2;
            let sub: Vec<f64> = (1..=m).map(|i| h[i - 1]).collect();
            let diag: Vec<f64> = (1..=m).map(|i| 2.0 * (h[i - 1] + h[i])).collect();
            let sup: Vec<f64> = (1..=m).map(|i| h[i]).collect();
            let mut rhs = vec![0.0; m];
            for k in 0..n {
                // Right-hand side for data y = unit vector e_k.
                let y = |j: usize| if j == k { 1.0 } else { 0.0 };
                for (r, i) in rhs.iter_mut().zip(1..=m) {
                    *r = 6.0 * ((y(i + 1) - y(i)) / h[i] - (y(i) - y(i - 1)) / h[i - 1]);
                }
                let sol = solve_tridiagonal(&sub, &diag, &sup, &rhs);
                for (i, v) in sol.into_iter().enumerate() {
                    second[(i + 1) * n + k] = v;
                }
            }
        }
        Ok(NaturalCubicSpline {
            times: times.to_vec(),
            second,
        })
    }

    /// Writes the weights `c_k(t)` over the key times into `out` (length =
    /// number of key times). They sum to one. Before the first / after the
    /// last key time they select that key alone; NaN is treated as before
    /// the first.
    ///
    /// # Panics
    /// If `out` has the wrong length.
    pub fn weights_into(&self, t: f64, out: &mut [f64]) {
        let n = self.times.len();
        assert_eq!(out.len(), n, "one weight per key time");
        out.fill(0.0);
        if t.is_nan() || t <= self.times[0] {
            out[0] = 1.0;
            return;
        }
        if t >= self.times[n - 1] {
            out[n - 1] = 1.0;
            return;
        }
        // Segment i with times[i] <= t < times[i+1].
        let i = self.times.partition_point(|&x| x <= t) - 1;
        let h = self.times[i + 1] - self.times[i];
        let b = (t - self.times[i]) / h;
        let a = 1.0 - b;
        out[i] += a;
        out[i + 1] += b;
        let ca = h * h / 6.0 * (a * a * a - a);
        let cb = h * h / 6.0 * (b * b * b - b);
        let row_i = &self.second[i * n..(i + 1) * n];
        let row_j = &self.second[(i + 1) * n..(i + 2) * n];
        for ((o, mi), mj) in out.iter_mut().zip(row_i).zip(row_j) {
            *o += ca * mi + cb * mj;
        }
    }

    /// The weights `c_k(t)` over the key times, as a new vector.
    pub fn weights(&self, t: f64) -> Vec<f64> {
        let mut w = vec![0.0; self.times.len()];
        self.weights_into(t, &mut w);
        w
    }

    /// The spline through scalar values `ys` (one per key time) at `t`.
    ///
    /// # Panics
    /// If `ys` has the wrong length.
    pub fn value(&self, t: f64, ys: &[f64]) -> f64 {
        assert_eq!(ys.len(), self.times.len(), "one value per key time");
        self.weights(t).iter().zip(ys).map(|(w, y)| w * y).sum()
    }

    /// Interpolates whole point arrays (one per key time, e.g. a key
    /// viewpoint's offsets from the base) at `t` into `out`.
    ///
    /// # Panics
    /// If the number of arrays differs from the number of key times, or an
    /// array's length differs from `out`'s.
    pub fn evaluate(&self, t: f64, values: &[&[Vec3]], out: &mut [Vec3]) {
        let w = self.weights(t);
        weighted_sum(&w, values, out);
    }
}

/// `out[p] = Σ_k weights[k] · arrays[k][p]`, in `f32` (the hot loop);
/// arrays with zero weight are not read.
///
/// # Panics
/// If `weights` and `arrays` differ in length, or an array's length differs
/// from `out`'s.
pub fn weighted_sum(weights: &[f64], arrays: &[&[Vec3]], out: &mut [Vec3]) {
    assert_eq!(weights.len(), arrays.len(), "one weight per array");
    let terms: Vec<(f64, &[Vec3])> = weights.iter().copied().zip(arrays.iter().copied()).collect();
    crate::mesh::weighted_sum(out, &terms);
}

/// Solves a diagonally dominant tridiagonal system (Thomas algorithm).
/// `sub[0]` and `sup[m-1]` are unused.
fn solve_tridiagonal(sub: &[f64], diag: &[f64], sup: &[f64], rhs: &[f64]) -> Vec<f64> {
    let m = diag.len();
    let mut c = vec![0.0; m];
    let mut d = vec![0.0; m];
    for i in 0..m {
        let denom = diag[i] - if i > 0 { sub[i] * c[i - 1] } else { 0.0 };
        c[i] = sup[i] / denom;
        d[i] = (rhs[i] - if i > 0 { sub[i] * d[i - 1] } else { 0.0 }) / denom;
    }
    let mut x = vec![0.0; m];
    for i in (0..m).rev() {
        x[i] = d[i] - if i + 1 < m { c[i] * x[i + 1] } else { 0.0 };
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};
    use proptest::prelude::*;

    #[test]
    fn rejects_bad_times() {
        assert_eq!(NaturalCubicSpline::new(&[]).unwrap_err(), ViewError::NoKeyTimes);
        assert_eq!(
            NaturalCubicSpline::new(&[0.0, f64::NAN]).unwrap_err(),
            ViewError::NonFiniteTime { index: 1 }
        );
        assert_eq!(
            NaturalCubicSpline::new(&[0.0, 2.0, 2.0]).unwrap_err(),
            ViewError::TimesNotIncreasing { index: 2 }
        );
        assert_eq!(
            NaturalCubicSpline::new(&[3.0, 1.0]).unwrap_err(),
            ViewError::TimesNotIncreasing { index: 1 }
        );
    }

    #[test]
    fn one_and_two_knots() {
        let s = NaturalCubicSpline::new(&[5.0]).unwrap();
        for t in [-1e9, 0.0, 5.0, 7.0, f64::NAN] {
            assert_eq!(s.weights(t), vec![1.0]);
        }
        let s = NaturalCubicSpline::new(&[10.0, 30.0]).unwrap();
        assert_eq!(s.value(15.0, &[2.0, 6.0]), 3.0);
        assert_eq!(s.value(25.0, &[2.0, 6.0]), 5.0);
        assert_eq!(s.value(0.0, &[2.0, 6.0]), 2.0);
        assert_eq!(s.value(40.0, &[2.0, 6.0]), 6.0);
    }

    #[test]
    fn three_knots_by_hand() {
        // Knots 0,1,2 with values 0,1,0. The single interior equation is
        // 1·0 + 2·(1+1)·M1 + 1·0 = 6·((0−1)/1 − (1−0)/1) = −12, so M1 = −3.
        // On [0,1] with S(0)=0, S''(0)=0: S = a·t + b·t³, S''(1) = 6b = −3
        // → b = −1/2, and S(1) = 1 → a = 3/2. By symmetry S(2−t) = S(t).
        let s = NaturalCubicSpline::new(&[0.0, 1.0, 2.0]).unwrap();
        let ys = [0.0, 1.0, 0.0];
        for t in [0.25, 0.5, 0.75] {
            let want = 1.5 * t - 0.5 * t * t * t;
            assert!((s.value(t, &ys) - want).abs() < 1e-14);
            assert!((s.value(2.0 - t, &ys) - want).abs() < 1e-14);
        }
        assert!((s.value(0.5, &ys) - 0.6875).abs() < 1e-15);
    }

    #[test]
    fn exact_at_knots_and_held_outside() {
        let times = [0.0, 0.7, 2.0, 2.5, 6.0];
        let ys = [1.0, -2.0, 0.5, 3.0, -1.0];
        let s = NaturalCubicSpline::new(&times).unwrap();
        for (k, &t) in times.iter().enumerate() {
            let w = s.weights(t);
            for (j, wj) in w.iter().enumerate() {
                assert_eq!(*wj, if j == k { 1.0 } else { 0.0 });
            }
        }
        assert_eq!(s.value(-3.0, &ys), 1.0);
        assert_eq!(s.value(100.0, &ys), -1.0);
        assert_eq!(s.value(f64::NEG_INFINITY, &ys), 1.0);
        assert_eq!(s.value(f64::INFINITY, &ys), -1.0);
        // Weights always sum to one (constants are reproduced).
        for i in 0..=60 {
            let t = i as f64 * 0.1;
            let total: f64 = s.weights(t).iter().sum();
            assert!((total - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn natural_end_conditions() {
        let times = [0.0, 1.0, 1.5, 3.0];
        let ys = [0.0, 2.0, -1.0, 1.0];
        let s = NaturalCubicSpline::new(&times).unwrap();
        let f = |t: f64| s.value(t, &ys);
        let h = 1e-4;
        // One-sided second differences inside the range.
        let start = (f(0.0) - 2.0 * f(h) + f(2.0 * h)) / (h * h);
        let end = (f(3.0) - 2.0 * f(3.0 - h) + f(3.0 - 2.0 * h)) / (h * h);
        assert!(start.abs() < 1e-2, "{start}");
        assert!(end.abs() < 1e-2, "{end}");
        // ...while the interior curvature is far from zero.
        let mid = (f(1.0 - h) - 2.0 * f(1.0) + f(1.0 + h)) / (h * h);
        assert!(mid.abs() > 1.0, "{mid}");
    }

    /// Independent reference: solve for the piecewise cubic coefficients
    /// a_i + b_i s + c_i s² + d_i s³ (s = t − t_i) directly from the
    /// interpolation, C¹, C² and natural end conditions as one dense system.
    fn reference(times: &[f64], ys: &[f64], t: f64) -> f64 {
        let n = times.len();
        let segs = n - 1;
        let mut m = DMatrix::<f64>::zeros(4 * segs, 4 * segs);
        let mut r = DVector::<f64>::zeros(4 * segs);
        let mut row = 0;
        for i in 0..segs {
            let h = times[i + 1] - times[i];
            let c = 4 * i;
            m[(row, c)] = 1.0;
            r[row] = ys[i];
            row += 1;
            m[(row, c)] = 1.0;
            m[(row, c + 1)] = h;
            m[(row, c + 2)] = h * h;
            m[(row, c + 3)] = h * h * h;
            r[row] = ys[i + 1];
            row += 1;
            if i + 1 < segs {
                // First derivatives match at t_{i+1}.
                m[(row, c + 1)] = 1.0;
                m[(row, c + 2)] = 2.0 * h;
                m[(row, c + 3)] = 3.0 * h * h;
                m[(row, c + 5)] = -1.0;
                row += 1;
                // Second derivatives match.
                m[(row, c + 2)] = 2.0;
                m[(row, c + 3)] = 6.0 * h;
                m[(row, c + 6)] = -2.0;
                row += 1;
            }
        }
        m[(row, 2)] = 2.0; // S''(t_0) = 0
        row += 1;
        let h = times[n - 1] - times[n - 2];
        m[(row, 4 * (segs - 1) + 2)] = 2.0;
        m[(row, 4 * (segs - 1) + 3)] = 6.0 * h;
        row += 1;
        assert_eq!(row, 4 * segs);
        let coef = m.lu().solve(&r).expect("solvable");
        let i = (0..segs).rev().find(|&i| t >= times[i]).unwrap_or(0);
        let s = t - times[i];
        coef[4 * i] + coef[4 * i + 1] * s + coef[4 * i + 2] * s * s + coef[4 * i + 3] * s * s * s
    }

    #[test]
    fn matches_dense_reference() {
        let times = [0.0, 0.3, 1.1, 1.2, 4.0, 4.5];
        let ys = [0.5, -1.0, 2.0, 2.2, 0.0, 1.0];
        let s = NaturalCubicSpline::new(&times).unwrap();
        for i in 0..=450 {
            let t = i as f64 * 0.01;
            assert!((s.value(t, &ys) - reference(&times, &ys, t)).abs() < 1e-10, "{t}");
        }
    }

    #[test]
    fn point_arrays() {
        let s = NaturalCubicSpline::new(&[0.0, 1.0, 2.0]).unwrap();
        let a = [Vec3::new(0.0, 1.0, 2.0)];
        let b = [Vec3::new(1.0, 1.0, 0.0)];
        let c = [Vec3::new(0.0, 1.0, 4.0)];
        let mut out = [Vec3::ZERO];
        // Each component is its own spline: x through (0,1,0) → 0.6875 at
        // 0.5 (hand value above), y constant, z through (2,0,4).
        s.evaluate(0.5, &[&a, &b, &c], &mut out);
        assert!((out[0].x - 0.6875).abs() < 1e-6);
        assert!((out[0].y - 1.0).abs() < 1e-6);
        let z = s.value(0.5, &[2.0, 0.0, 4.0]);
        assert!((out[0].z as f64 - z).abs() < 1e-6);
        s.evaluate(2.0, &[&a, &b, &c], &mut out);
        assert_eq!(out[0], c[0]);
    }

    proptest! {
        #[test]
        fn prop_matches_reference(
            gaps in prop::collection::vec(0.05f64..3.0, 1..8),
            start in -10.0f64..10.0,
            seed in prop::collection::vec(-5.0f64..5.0, 9),
            frac in 0.0f64..1.0,
        ) {
            let mut times = vec![start];
            for g in &gaps {
                times.push(times.last().unwrap() + g);
            }
            let ys = &seed[..times.len()];
            let s = NaturalCubicSpline::new(&times).unwrap();
            let t = times[0] + frac * (times[times.len() - 1] - times[0]);
            if times.len() >= 2 {
                prop_assert!((s.value(t, ys) - reference(&times, ys, t)).abs() < 1e-8);
            }
            for (k, &tk) in times.iter().enumerate() {
                prop_assert_eq!(s.value(tk, ys), ys[k]);
            }
        }
    }
}
