//! Smooth Voronoi interpolation (Bassett et al. 2013 §4.2, eqs. 7–12).
//!
//! The interpolant is `ŷ(x̂) = Σ_i φ_i(x̂) (y_i + g_i · (x̂ − x_i))` (eq. 9):
//! normalised kernels φ_i (eq. 8) blending local linear fits whose gradients
//! g_i minimise eq. 10 plus ε‖g_i‖². Because g_i is linear in the y's, the
//! whole thing folds into basis weights `w(x̂) = Σ_i φ_i(x̂) (e_i + G_iᵀ (x̂ − x_i))`.
//!
//! # How it is made fast
//!
//! Everything is expressed through squared distances. With
//! `L_kl = ‖x_k − x_l‖²` (precomputed) and `r_k = ‖x̂ − x_k‖²` (n distances,
//! the only O(nd) work per query):
//! - eq. 8's projection parameter is
//!   `t_kl = (x̂ − x_l)·(x_k − x_l)/L_kl = (L_kl + r_l − r_k) / (2 L_kl)`, O(1);
//! - the local-fit offsets are `q_ij = (x_j − x_i)·(x̂ − x_i) = (r_i + L_ij − r_j)/2`;
//! - at eq. 11's sample point `m = α x_i + (1 − α) x_j`,
//!   `‖m − x_l‖² = α L_il + (1 − α) L_jl − α(1 − α) L_ij`, so every a_ij costs
//!   O(n²) without touching coordinates (O(n⁴) in all instead of O(n⁴d));
//! - cosines in eq. 12 and in the normal equations come from the polarisation
//!   identity `(x_j − x_i)·(x_k − x_i) = (L_ij + L_ik − L_jk)/2`.
//!
//! Kernels also use `t_lk = 1 − t_kl` and the symmetry `S(1 − t) = 1 − S(t)`,
//! so each unordered pair of keys costs one evaluation of S (evaluated with
//! selects, not branches, so the loop pipelines).
//!
//! This is the Gram-matrix trick in translation-invariant form: the squared
//! distance matrix carries the same information as `X Xᵀ` but is computed
//! directly from coordinate differences, so keys far from the origin lose
//! no precision, and a query sitting exactly on key k yields `t = 0` exactly
//! for every other kernel (exact interpolation, exact locality).
//!
//! ## Gradients in dual form
//!
//! For key i, with unit directions `u_j = (x_j − x_i)/ℓ_ij`, `A = diag(a_ij)`
//! and targets `ρ_j = b_ij (y_j − y_i)/ℓ_ij`, eq. 10 with the Tikhonov term is
//! `min_g ‖A(Uᵀg − ρ)‖² + ε‖g‖²`. Its d×d normal equations
//! `(U A² Uᵀ + εI) g = U A² ρ` are solved in their (n−1)×(n−1) dual form via
//! the push-through identity `(BBᵀ + εI)⁻¹ B = B (BᵀB + εI)⁻¹` with `B = UA`:
//! `g = U A M⁻¹ A ρ`, `M = A (UᵀU) A + εI`. `UᵀU` is the matrix of cosines
//! between the difference vectors, so M needs no coordinates either. M is
//! symmetric positive definite (eigenvalues ≥ ε), so a Cholesky solve gives
//! the same unique minimiser as the SVD the paper mentions ([`super::naive`]
//! does use an SVD, on the stacked d-dimensional system, and the tests check
//! both agree). Keys j with `a_ij = 0` drop out of M (their row and column
//! are just ε), and keys with `a_ij b_ij = 0` contribute no target, so each
//! M is only as large as key i's neighbourhood N_i.
//!
//! The query-dependent part is then `g_i · (x̂ − x_i) = Σ_j ρ_j v_j` with
//! `v = (b/ℓ) ⊙ A M⁻¹ A (q/ℓ)`: a precomputed matrix `Q_i` times the vector
//! `q_i` of the offsets above, O(|N_i|²) per key with a non-zero kernel.
//!
//! # Cost
//!
//! Precompute: O(n²d) for the distances, O(n⁴) for the a_ij (n²/2 sample
//! points × n²/2 pairs), O(n³) for the b_ij, O(Σ_i |N_i|³) for the
//! gradients. Weights: O(nd) distances, O(n²) kernels, then
//! O(Σ_{i: φ_i > 0} |N_i|²) for the gradient terms (at most O(n³), small in
//! practice: only keys near x̂ have a non-zero kernel, and keys at the
//! outside of the layout have no gradient at all).
//!
//! # Zero denominators
//!
//! `Σ_k φ'_k(x̂)` never vanishes, anywhere in R^d: for the key k* nearest to
//! x̂, `r_l ≥ r_k*` for every l, so `t_k*l ≥ 1/2` and every factor of
//! `φ'_k*` is at least S(1/2) = 1/2, giving `Σ_k φ'_k ≥ 2^{1−n}`. The same
//! holds at eq. 11's sample points. No fallback is needed.
//!
//! Far outside the keys the kernels settle on the outermost keys; the
//! blended local fits extrapolate linearly along any gradient those keys
//! have (b_ij forces it to zero only in directions where a key is extreme),
//! which is the paper's partial R6.
//!
//! # Two keys
//!
//! With n = 2 the minimum in eq. 12 runs over k = j only, whose cosine is 1,
//! so `b_ij = S(−β) = 0`: both gradients vanish (both keys are extreme) and
//! the interpolant is the smooth step S_γ along the line through the keys,
//! flat at both keys and constant across it.

use super::step::Step;
use super::{sq_dists_to, ALPHA, BETA, EPSILON, GAMMA};

/// The four constants of the method. The public API always uses the
/// paper's values; tests build variants (e.g. γ = 0, a C⁰ control).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Params {
    pub(crate) alpha: f64,
    pub(crate) beta: f64,
    pub(crate) gamma: f64,
    pub(crate) epsilon: f64,
}

impl Params {
    /// α = 0.5, β = 5, γ = 0.2, ε = 0.2, as used for all the paper's results.
    pub(crate) const PAPER: Params = Params {
        alpha: ALPHA,
        beta: BETA,
        gamma: GAMMA,
        epsilon: EPSILON,
    };
}

/// Precomputed smooth Voronoi interpolant for n ≥ 2 keys.
#[derive(Clone, Debug)]
pub(crate) struct SmoothVoronoi {
    n: usize,
    step: Step,
    /// `L_kl = ‖x_k − x_l‖²`, n×n row-major, zero diagonal.
    sq: Vec<f64>,
    /// `1 / (2 L_kl)`, n×n row-major (diagonal unused).
    half_inv: Vec<f64>,
    /// eq. 11 weights a_ij (n×n, row i = key i's fit).
    a: Vec<f64>,
    /// eq. 12 weights b_ij (n×n).
    b: Vec<f64>,
    /// Per key, the dual-form gradient operator.
    grads: Vec<Gradient>,
}

/// Dual-form operator mapping offsets q_i to coefficients on y.
#[derive(Clone, Debug, Default)]
struct Gradient {
    /// Keys j with `a_ij b_ij > 0`: those whose value enters g_i.
    rows: Vec<usize>,
    /// Keys k with `a_ik > 0`: those whose offset q_ik enters g_i.
    cols: Vec<usize>,
    /// `rows.len() × cols.len()`, row-major:
    /// `Q[j][k] = (b_ij a_ij / ℓ_ij) (M⁻¹)_jk (a_ik / ℓ_ik)`.
    q: Vec<f64>,
}

/// Product of a slice with four independent accumulators (lets the
/// multiplications pipeline instead of forming one long dependency chain).
#[inline]
fn product(v: &[f64]) -> f64 {
    let mut acc = [1.0f64; 4];
    let chunks = v.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for (a, x) in acc.iter_mut().zip(c) {
            *a *= x;
        }
    }
    let mut p = (acc[0] * acc[1]) * (acc[2] * acc[3]);
    for x in rest {
        p *= x;
    }
    p
}

/// In-place Cholesky factorisation `M = L Lᵀ` of a c×c row-major SPD
/// matrix; the lower triangle is overwritten with L. False if a pivot is
/// not positive.
fn cholesky_in_place(m: &mut [f64], c: usize) -> bool {
    for j in 0..c {
        let (done, rest) = m.split_at_mut(j * c);
        let row_j = &mut rest[..c];
        // Entries L_jk for k < j, using rows already factorised.
        for k in 0..j {
            let row_k = &done[k * c..k * c + k];
            let s: f64 = row_j[..k].iter().zip(row_k).map(|(a, b)| a * b).sum();
            row_j[k] = (row_j[k] - s) / done[k * c + k];
        }
        let s: f64 = row_j[..j].iter().map(|v| v * v).sum();
        let pivot = row_j[j] - s;
        if pivot <= 0.0 || !pivot.is_finite() {
            return false;
        }
        row_j[j] = pivot.sqrt();
    }
    true
}

/// Solves `L Lᵀ x = e_p` with the factor from [`cholesky_in_place`]: column
/// p of M⁻¹.
fn solve_unit(l: &[f64], c: usize, p: usize, x: &mut [f64]) {
    x.fill(0.0);
    x[p] = 1.0;
    // Forward: L y = e_p (y_i = 0 for i < p).
    for i in p..c {
        let row = &l[i * c..i * c + i];
        let s: f64 = row[p..].iter().zip(&x[p..i]).map(|(a, b)| a * b).sum();
        x[i] = (x[i] - s) / l[i * c + i];
    }
    // Backward: Lᵀ x = y, column-oriented so rows of L are read contiguously.
    for i in (0..c).rev() {
        x[i] /= l[i * c + i];
        let xi = x[i];
        for (xk, lik) in x[..i].iter_mut().zip(&l[i * c..i * c + i]) {
            *xk -= lik * xi;
        }
    }
}

impl SmoothVoronoi {
    /// Precomputes kernels' tables, a_ij, b_ij and the gradient operators
    /// from the squared distance matrix of n ≥ 2 distinct keys.
    pub(crate) fn new(n: usize, sq: Vec<f64>, params: Params) -> Self {
        debug_assert!(n >= 2 && sq.len() == n * n);
        let half_inv = sq.iter().map(|&v| if v > 0.0 { 0.5 / v } else { 0.0 }).collect();
        let mut sv = SmoothVoronoi {
            n,
            step: Step::new(params.gamma),
            sq,
            half_inv,
            a: Vec::new(),
            b: Vec::new(),
            grads: Vec::new(),
        };
        sv.a = sv.compute_a(params.alpha);
        sv.b = sv.compute_b(params.beta);
        let mut scratch = Vec::new();
        sv.grads = (0..n).map(|i| sv.gradient(i, params.epsilon, &mut scratch)).collect();
        sv
    }

    /// Unnormalised kernels φ'_k (eq. 8) at a point given by its squared
    /// distances `r` to the keys; returns their sum (> 0, see module docs).
    ///
    /// Each unordered pair {k, l} is visited once: `t_lk = 1 − t_kl`, so the
    /// factor of kernel l is `1 − S(t_kl)` (S is symmetric). Both parameters
    /// are still formed so that a factor that must be exactly 0 (a query on
    /// a key, exact locality) or exactly 1 is. `buf` is scratch of length n.
    #[inline]
    fn kernels(&self, r: &[f64], phi: &mut [f64], buf: &mut [f64]) -> f64 {
        let n = self.n;
        phi.fill(1.0);
        for k in 0..n {
            let rk = r[k];
            let row = k * n + k + 1..(k + 1) * n;
            let (head, tail) = phi.split_at_mut(k + 1);
            let factors = &mut buf[..n - k - 1];
            for ((((f, pl), &l2), &h), &rl) in factors
                .iter_mut()
                .zip(tail.iter_mut())
                .zip(&self.sq[row.clone()])
                .zip(&self.half_inv[row])
                .zip(&r[k + 1..])
            {
                let t_kl = (l2 + rl - rk) * h;
                let t_lk = (l2 + rk - rl) * h;
                let s = self.step.eval_select(t_kl);
                *f = s;
                *pl *= if t_lk <= 0.0 {
                    0.0
                } else if t_lk >= 1.0 {
                    1.0
                } else {
                    1.0 - s
                };
            }
            head[k] *= product(factors);
        }
        phi.iter().sum()
    }

    /// a_ij = φ_i(α x_i + (1 − α) x_j) for all i ≠ j (eq. 11). O(n⁴).
    fn compute_a(&self, alpha: f64) -> Vec<f64> {
        let n = self.n;
        let sq = &self.sq;
        let mut a = vec![0.0; n * n];
        let mut r = vec![0.0; n];
        let mut phi = vec![0.0; n];
        let mut buf = vec![0.0; n];
        // With α = ½ the sample point of (i, j) is also that of (j, i).
        let symmetric = alpha == 0.5;
        let beta_ = 1.0 - alpha;
        for i in 0..n {
            for j in 0..n {
                if i == j || (symmetric && j < i) {
                    continue;
                }
                let lij = sq[i * n + j];
                for (l, rl) in r.iter_mut().enumerate() {
                    *rl = alpha * sq[i * n + l] + beta_ * sq[j * n + l] - alpha * beta_ * lij;
                }
                let sum = self.kernels(&r, &mut phi, &mut buf);
                a[i * n + j] = phi[i] / sum;
                if symmetric {
                    a[j * n + i] = phi[j] / sum;
                }
            }
        }
        a
    }

    /// b_ij = S(−β min_{k≠i} cos∠(x_k − x_i, x_j − x_i)) (eq. 12). O(n³).
    fn compute_b(&self, beta: f64) -> Vec<f64> {
        let n = self.n;
        let sq = &self.sq;
        let len: Vec<f64> = sq.iter().map(|v| v.sqrt()).collect();
        let mut b = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                if i == j {
                    continue;
                }
                let mut min_cos = f64::INFINITY;
                for k in 0..n {
                    if k == i {
                        continue;
                    }
                    let dot = 0.5 * (sq[i * n + k] + sq[i * n + j] - sq[j * n + k]);
                    min_cos = min_cos.min(dot / (len[i * n + k] * len[i * n + j]));
                }
                b[i * n + j] = self.step.eval(-beta * min_cos);
            }
        }
        b
    }

    /// The dual-form operator for key i's gradient (module docs).
    fn gradient(&self, i: usize, epsilon: f64, scratch: &mut Vec<f64>) -> Gradient {
        let n = self.n;
        let sq = &self.sq;
        let a_i = &self.a[i * n..(i + 1) * n];
        let b_i = &self.b[i * n..(i + 1) * n];
        let cols: Vec<usize> = (0..n).filter(|&k| k != i && a_i[k] > 0.0).collect();
        let rows: Vec<usize> = cols.iter().copied().filter(|&j| b_i[j] > 0.0).collect();
        if rows.is_empty() {
            return Gradient::default();
        }
        let c = cols.len();
        let len: Vec<f64> = cols.iter().map(|&k| sq[i * n + k].sqrt()).collect();
        // M = A (UᵀU) A + εI on the keys with a_ik > 0; UᵀU holds the cosines
        // (x_p − x_i)·(x_q − x_i) / (ℓ_ip ℓ_iq) from the polarisation identity.
        scratch.clear();
        scratch.resize(c * c + c, 0.0);
        let (m, x) = scratch.split_at_mut(c * c);
        for p in 0..c {
            let kp = cols[p];
            for q in 0..=p {
                let kq = cols[q];
                let cos = if p == q {
                    1.0
                } else {
                    0.5 * (sq[i * n + kp] + sq[i * n + kq] - sq[kp * n + kq]) / (len[p] * len[q])
                };
                let v = a_i[kp] * a_i[kq] * cos;
                m[p * c + q] = if p == q { v + epsilon } else { v };
            }
        }
        // M ⪰ εI, so this cannot fail for finite input; if rounding ever made
        // it, falling back to the ε-only fit keeps the result finite.
        let factored = cholesky_in_place(m, c);
        let mut q = Vec::with_capacity(rows.len() * c);
        for &j in &rows {
            let p = cols.iter().position(|&k| k == j).expect("rows ⊆ cols");
            if factored {
                solve_unit(m, c, p, x);
            } else {
                x.fill(0.0);
                x[p] = 1.0 / epsilon;
            }
            let row_scale = b_i[j] * a_i[j] / len[p];
            for (k, &xk) in x.iter().enumerate() {
                q.push(row_scale * xk * a_i[cols[k]] / len[k]);
            }
        }
        Gradient { rows, cols, q }
    }

    /// Basis weights at `x` (see [`crate::interp::Interpolator::weights`]).
    pub(crate) fn weights(&self, keys: &[f64], dim: usize, x: &[f64], out: &mut [f64]) {
        let n = self.n;
        // One allocation for all scratch: distances, kernels, pair factors, offsets.
        let mut scratch = vec![0.0; 4 * n];
        let (r, rest) = scratch.split_at_mut(n);
        let (phi, rest) = rest.split_at_mut(n);
        let (buf, qv) = rest.split_at_mut(n);
        sq_dists_to(keys, dim, x, r);
        let sum = self.kernels(r, phi, buf);
        let inv = 1.0 / sum;
        for (o, p) in out.iter_mut().zip(phi.iter_mut()) {
            *p *= inv;
            *o = *p;
        }
        for (i, g) in self.grads.iter().enumerate() {
            let phi_i = phi[i];
            if phi_i == 0.0 || g.rows.is_empty() {
                continue;
            }
            let sq_i = &self.sq[i * n..(i + 1) * n];
            let ri = r[i];
            let c = g.cols.len();
            for (qp, &k) in qv.iter_mut().zip(&g.cols) {
                *qp = 0.5 * (ri + sq_i[k] - r[k]);
            }
            let qv = &qv[..c];
            let mut total = 0.0;
            for (row, &j) in g.q.chunks_exact(c).zip(&g.rows) {
                let v: f64 = row.iter().zip(qv).map(|(a, b)| a * b).sum();
                out[j] += phi_i * v;
                total += v;
            }
            out[i] -= phi_i * total;
        }
    }

    /// Normalised kernels φ_k(x) (eq. 8 normalised), for tests.
    #[cfg(test)]
    pub(crate) fn normalized_kernels(&self, keys: &[f64], dim: usize, x: &[f64]) -> Vec<f64> {
        let mut r = vec![0.0; self.n];
        sq_dists_to(keys, dim, x, &mut r);
        let mut phi = vec![0.0; self.n];
        let mut buf = vec![0.0; self.n];
        let sum = self.kernels(&r, &mut phi, &mut buf);
        phi.iter().map(|p| p / sum).collect()
    }

    /// a_ij (eq. 11), for tests.
    #[cfg(test)]
    pub(crate) fn a(&self, i: usize, j: usize) -> f64 {
        self.a[i * self.n + j]
    }

    /// b_ij (eq. 12), for tests.
    #[cfg(test)]
    pub(crate) fn b(&self, i: usize, j: usize) -> f64 {
        self.b[i * self.n + j]
    }
}

#[cfg(test)]
mod tests {
    use super::super::naive::NaiveSmoothVoronoi;
    use super::super::testutil::*;
    use super::super::{Interpolator, Method};
    use super::*;
    use proptest::prelude::*;

    fn build(dim: usize, keys: &[f64]) -> Interpolator {
        Interpolator::new(Method::SmoothVoronoi, dim, keys).unwrap()
    }

    fn weights(it: &Interpolator, x: &[f64]) -> Vec<f64> {
        it.weights_vec(x)
    }

    /// A random layout's interpolation of random values `y` at its keys,
    /// along three random segments a → b (all drawn from `seed`).
    struct Segments {
        it: Interpolator,
        y: Vec<f64>,
        ends: Vec<(Vec<f64>, Vec<f64>)>,
    }

    impl Segments {
        fn new(d: usize, n: usize, seed: u64) -> Segments {
            let mut rng = Lcg::new(seed);
            let keys = separated_keys(&mut rng, n, d);
            let it = build(d, &keys);
            let y = (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect();
            let ends = (0..3)
                .map(|_| {
                    let a = random_point(&mut rng, d, -0.2, 1.2);
                    (a, random_point(&mut rng, d, -0.2, 1.2))
                })
                .collect();
            Segments { it, y, ends }
        }

        /// The interpolated value at `s` ∈ [0, 1] along segment `k`.
        fn at(&self, k: usize, s: f64) -> f64 {
            let (a, b) = &self.ends[k];
            let x: Vec<f64> = a.iter().zip(b).map(|(p, q)| p + s * (q - p)).collect();
            dot(&weights(&self.it, &x), &self.y)
        }
    }

    /// Layout strategy: dimension, key count, seed.
    fn layouts() -> impl Strategy<Value = (usize, usize, u64)> {
        (prop::sample::select(vec![1usize, 2, 3, 5]), 1usize..=8, any::<u64>())
    }

    proptest! {
        #![proptest_config(proptest_config(48))]

        #[test]
        fn r1_exact_at_keys_and_partition_of_unity((d, n, seed) in layouts()) {
            let mut rng = Lcg::new(seed);
            let keys = separated_keys(&mut rng, n, d);
            let it = build(d, &keys);
            for j in 0..n {
                let w = weights(&it, &keys[j * d..(j + 1) * d]);
                for (i, wi) in w.iter().enumerate() {
                    let target = if i == j { 1.0 } else { 0.0 };
                    prop_assert!((wi - target).abs() < 1e-9, "w_{}(x_{}) = {}", i, j, wi);
                }
            }
            for _ in 0..20 {
                let x = random_point(&mut rng, d, -0.5, 1.5);
                let s: f64 = weights(&it, &x).iter().sum();
                prop_assert!((s - 1.0).abs() < 1e-12, "sum = {}", s);
            }
        }

        #[test]
        fn fast_equals_naive((d, n, seed) in layouts()) {
            let mut rng = Lcg::new(seed);
            let keys = separated_keys(&mut rng, n, d);
            let fast = build(d, &keys);
            let naive = NaiveSmoothVoronoi::new(d, &keys).unwrap();
            let mut wn = vec![0.0; n];
            for _ in 0..25 {
                let x = random_point(&mut rng, d, -0.3, 1.3);
                let wf = weights(&fast, &x);
                naive.weights(&x, &mut wn);
                for i in 0..n {
                    prop_assert!((wf[i] - wn[i]).abs() < 1e-9, "w_{}: fast {} naive {}", i, wf[i], wn[i]);
                }
            }
        }

        #[test]
        fn r2_c1_along_random_segments((d, n, seed) in layouts()) {
            let case = Segments::new(d, n, seed);
            for k in 0..case.ends.len() {
                prop_assert!(looks_c1(|s| case.at(k, s)), "kink along a segment");
            }
        }

        #[test]
        fn r3_orthogonal_moves_change_nothing((d, n, seed) in (prop::sample::select(vec![2usize, 3, 5]), 2usize..=8, any::<u64>())) {
            let mut rng = Lcg::new(seed);
            // Keys spanning a k-dimensional affine subspace, k < d.
            let k = rng.below(d.min(n)).max(1).min(d - 1);
            let (keys, normal) = keys_in_subspace(&mut rng, n, d, k);
            let it = build(d, &keys);
            for _ in 0..10 {
                let x = random_point(&mut rng, d, -0.3, 1.3);
                let s = rng.uniform(-2.0, 2.0);
                let moved: Vec<f64> = x.iter().zip(&normal).map(|(p, v)| p + s * v).collect();
                let (w0, w1) = (weights(&it, &x), weights(&it, &moved));
                for i in 0..n {
                    prop_assert!((w0[i] - w1[i]).abs() < 1e-9, "w_{} {} vs {}", i, w0[i], w1[i]);
                }
            }
        }

        #[test]
        fn r5_scale_and_translation_invariance((d, n, seed) in layouts()) {
            let mut rng = Lcg::new(seed);
            let keys = separated_keys(&mut rng, n, d);
            let s = rng.uniform(1e-3, 1e3);
            let shift = random_point(&mut rng, d, -10.0, 10.0);
            let map = |p: &[f64]| -> Vec<f64> { p.iter().enumerate().map(|(c, v)| s * v + shift[c]).collect() };
            let moved_keys: Vec<f64> = keys.chunks(d).flat_map(map).collect();
            let (it0, it1) = (build(d, &keys), build(d, &moved_keys));
            for _ in 0..10 {
                let x = random_point(&mut rng, d, -0.3, 1.3);
                let (w0, w1) = (weights(&it0, &x), weights(&it1, &map(&x)));
                for i in 0..n {
                    prop_assert!((w0[i] - w1[i]).abs() < 1e-8, "w_{} {} vs {}", i, w0[i], w1[i]);
                }
            }
        }

        #[test]
        fn r7_values_far_away_have_no_influence((d, n, seed) in (prop::sample::select(vec![1usize, 2, 3]), 3usize..=8, any::<u64>())) {
            let mut rng = Lcg::new(seed);
            let keys = separated_keys(&mut rng, n, d);
            let it = build(d, &keys);
            let sv = it.smooth_voronoi().unwrap();
            for _ in 0..60 {
                let x = random_point(&mut rng, d, -0.2, 1.2);
                let phi = sv.normalized_kernels(&keys, d, &x);
                let w = weights(&it, &x);
                for i in 0..n {
                    // y_i enters only through φ_i, or through the gradient of a
                    // key k with φ_k > 0 that fits y_i (a_ki b_ki > 0).
                    let remote = phi[i] == 0.0
                        && (0..n).all(|k| k == i || phi[k] == 0.0 || sv.a(k, i) * sv.b(k, i) == 0.0);
                    if remote {
                        prop_assert_eq!(w[i], 0.0);
                    }
                }
            }
        }
    }

    #[test]
    fn cholesky_inverse_matches_nalgebra() {
        let mut rng = Lcg::new(7);
        for c in [1usize, 2, 5, 13] {
            let b = nalgebra::DMatrix::from_fn(c, c, |_, _| rng.uniform(-1.0, 1.0));
            let m = &b * b.transpose() + nalgebra::DMatrix::identity(c, c) * 0.2;
            let mut flat: Vec<f64> = (0..c * c).map(|k| m[(k / c, k % c)]).collect();
            assert!(cholesky_in_place(&mut flat, c));
            let inv = m.clone().try_inverse().unwrap();
            let mut x = vec![0.0; c];
            for p in 0..c {
                solve_unit(&flat, c, p, &mut x);
                for k in 0..c {
                    assert!((x[k] - inv[(k, p)]).abs() < 1e-10);
                }
            }
        }
        let mut not_spd = vec![1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_in_place(&mut not_spd, 2));
    }

    #[test]
    fn r2_control_c0_kernels_fail_the_c1_check() {
        // γ = 0 turns S into a clamp: the kernels (and so the interpolant)
        // are only C⁰. The same check must reject them.
        let keys = [0.0, 0.3, 1.0];
        let (_, sq) = super::super::validate_keys(1, &keys).unwrap();
        let c0 = SmoothVoronoi::new(
            3,
            sq,
            Params {
                gamma: 0.0,
                ..Params::PAPER
            },
        );
        let y = [0.0, 1.0, 0.2];
        let f = |s: f64| {
            let mut w = [0.0; 3];
            c0.weights(&keys, 1, &[s], &mut w);
            dot(&w, &y)
        };
        assert!(!looks_c1(|s| f(-0.5 + 2.0 * s)));
        // A plain kink is rejected too, a smooth function accepted.
        assert!(!looks_c1(|s| (s - 0.4321).abs()));
        assert!(looks_c1(|s| (3.0 * s).sin()));
        // A small kink (slope jump 2e-3) on a smooth function is still
        // rejected, also at a grid point, and near the ends of [0, 1]. (The
        // base is gentle: only the 5 largest coarse quotients are looked at,
        // so the kink must outrank the smooth curvature there.)
        for p in [0.3, 0.5, 0.0003, 0.9999] {
            assert!(!looks_c1(|s| (0.5 * s).sin() + 1e-3 * (s - p).abs()), "kink at {p}");
        }
    }

    #[test]
    fn r2_segment_clipping_a_sliver_of_a_quadratic_piece_is_c1() {
        // Proptest case (d, n, seed) = (3, 2, 15099038323540161588). Two keys:
        // f = y_1 + (y_0 − y_1) S_γ(t) along the line through them. The third
        // segment starts at t = 1 − 2e-5, so only s ∈ [0, 5.4e-5] lies on
        // S_γ's upper quadratic piece (f'' ≈ −0.289 there, 0 after): C¹ with
        // a jump in f'' narrower than the h/8 step, which the first
        // refinement undersamples (max quotient 0.028 at h/8, 0.289 at h/128).
        let case = Segments::new(3, 2, 15099038323540161588);
        for seg in 0..case.ends.len() {
            let f = |s: f64| case.at(seg, s);
            assert!(looks_c1(f), "segment {seg}");
            if seg == 2 {
                // Really C¹ at the joint (s ≈ 5.4e-5): the one-sided slopes
                // differ by ≈ f''·e, shrinking with e (no kink).
                let s0 = 5.4e-5;
                for e in [1e-5, 1e-6, 1e-7] {
                    let jump = (f(s0 + e) - f(s0)) / e - (f(s0) - f(s0 - e)) / e;
                    assert!(jump.abs() < 0.5 * e, "e {e}: {jump}");
                }
            }
        }
    }

    /// Keys of Bassett Fig. 9.
    const FIG9: [f64; 10] = [0.2, 0.2, 0.8, 0.8, 0.2, 0.8, 0.8, 0.2, 0.3, 0.4];

    #[test]
    fn fig9_layout() {
        let it = build(2, &FIG9);
        for j in 0..5 {
            let w = weights(&it, &FIG9[2 * j..2 * j + 2]);
            for (i, wi) in w.iter().enumerate() {
                assert_eq!(*wi, if i == j { 1.0 } else { 0.0 }, "w_{i}(x_{j})");
            }
        }
        let mut remote_points = 0;
        let sv = it.smooth_voronoi().unwrap();
        for gx in 0..=40 {
            for gy in 0..=40 {
                let x = [gx as f64 / 40.0, gy as f64 / 40.0];
                let w = weights(&it, &x);
                let s: f64 = w.iter().sum();
                assert!((s - 1.0).abs() < 1e-12);
                // The weights stay close to [0, 1] (mild overshoot only).
                assert!(w.iter().all(|&v| (-0.25..=1.25).contains(&v)), "{w:?} at {x:?}");
                let phi = sv.normalized_kernels(&FIG9, 2, &x);
                if phi[4] == 0.0 && w[4] == 0.0 {
                    remote_points += 1;
                }
            }
        }
        // The inner key (0.3, 0.4) has no say in a good part of the square.
        assert!(remote_points > 100, "{remote_points}");
        let naive = NaiveSmoothVoronoi::new(2, &FIG9).unwrap();
        let mut wn = [0.0; 5];
        for x in [[0.5, 0.5], [0.25, 0.3], [0.9, 0.1], [0.6, 0.35]] {
            naive.weights(&x, &mut wn);
            let wf = weights(&it, &x);
            for i in 0..5 {
                assert!((wf[i] - wn[i]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn a_is_the_normalised_kernel_at_its_sample_point_for_any_alpha() {
        // Eq. 11 with the kernels evaluated at y = α x_i + (1 − α) x_j from
        // its plain distances, not compute_a's expansion; α ≠ ½ has no
        // (i, j)/(j, i) symmetry to share.
        let (_, sq) = super::super::validate_keys(2, &FIG9).unwrap();
        for alpha in [0.3, 0.5, 0.8] {
            let sv = SmoothVoronoi::new(5, sq.clone(), Params { alpha, ..Params::PAPER });
            let mut spread = 0.0f64;
            for i in 0..5 {
                for j in (0..5).filter(|&j| j != i) {
                    let y = [0, 1].map(|k| alpha * FIG9[2 * i + k] + (1.0 - alpha) * FIG9[2 * j + k]);
                    let want = sv.normalized_kernels(&FIG9, 2, &y)[i];
                    assert!(
                        (sv.a(i, j) - want).abs() < 1e-12,
                        "α {alpha}: a_{i}{j} {} vs {want}",
                        sv.a(i, j)
                    );
                    spread = spread.max((sv.a(i, j) - sv.a(j, i)).abs());
                }
            }
            // The test needs a_ij ≠ a_ji somewhere, or it could not see a swap.
            assert!(spread > 0.1, "α {alpha}: {spread}");
        }
    }

    #[test]
    fn two_keys_give_the_smooth_step_along_the_line() {
        let keys = [1.0, 2.0, 0.0, 3.0, 4.0, 2.0];
        let it = build(3, &keys);
        let sv = it.smooth_voronoi().unwrap();
        assert_eq!(sv.b(0, 1), 0.0);
        assert_eq!(sv.b(1, 0), 0.0);
        for k in 0..=20 {
            let t = -0.2 + 1.4 * k as f64 / 20.0;
            // Point at parameter t from key 0 to key 1, pushed sideways.
            let x = [1.0 + 2.0 * t + 0.5, 2.0 + 2.0 * t - 0.1, 2.0 * t - 0.4];
            let w = weights(&it, &x);
            let expected = super::super::smooth_step(t, GAMMA);
            assert!((w[1] - expected).abs() < 1e-12, "t={t}: {} vs {expected}", w[1]);
            assert!((w[0] + w[1] - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn one_dimensional_extremes_are_flat_and_interior_keys_have_slope() {
        // Regularly spaced keys (Bassett Fig. 7): the end keys are extreme so
        // their gradient is forced to zero; interior keys get a gradient, so
        // a linear ramp is followed closely instead of stair-stepping.
        let keys = [0.0, 1.0, 2.0, 3.0, 4.0];
        let it = build(1, &keys);
        let y = [0.0, 1.0, 2.0, 3.0, 4.0];
        let f = |s: f64| dot(&weights(&it, &[s]), &y);
        let h = 1e-6;
        let slope_at = |s: f64| (f(s + h) - f(s - h)) / (2.0 * h);
        assert!(slope_at(0.0).abs() < 1e-6);
        assert!(slope_at(4.0).abs() < 1e-6);
        for s in [1.0, 2.0, 3.0] {
            assert!(slope_at(s) > 0.5, "slope at {s}: {}", slope_at(s));
        }
        // Monotone along the ramp (no stutter steps going backwards).
        let mut prev = f(0.0);
        for k in 1..=400 {
            let v = f(4.0 * k as f64 / 400.0);
            assert!(v >= prev - 1e-12);
            prev = v;
        }
    }

    #[test]
    fn kernel_denominator_is_bounded_below_far_away() {
        let keys = [0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 1.0];
        let it = build(2, &keys);
        for x in [[1e6, -3e5], [-40.0, 7.0], [0.5, 1e4]] {
            let w = weights(&it, &x);
            assert!(w.iter().all(|v| v.is_finite()));
            assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        }
        let w = weights(&it, &[f64::NAN, 0.0]);
        assert!(w.iter().all(|v| v.is_nan()));
    }
}
