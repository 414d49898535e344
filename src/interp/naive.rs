//! Direct O(n⁴d) transcription of smooth Voronoi interpolation (Bassett et
//! al. 2013, eqs. 7–12), the reference the fast [`crate::interp::Interpolator`]
//! is tested and benchmarked against.
//!
//! Nothing clever: every kernel is evaluated from coordinates with d-long
//! dot products each time it is needed, a_ij evaluates all n kernels at the
//! midpoint (O(n²d) each, O(n⁴d) in all, the paper's stated bottleneck), and
//! each gradient fit is solved with an SVD, as the paper says, on the stacked
//! least-squares system `[A Uᵀ; √ε I] g = [A ρ; 0]`. It shares no code with
//! the fast path except the smooth step and key validation.

use super::step::Step;
use super::{validate_keys, InterpError, ALPHA, BETA, EPSILON, GAMMA};
use nalgebra::DMatrix;

/// Reference smooth Voronoi interpolant: slow, simple, obviously the paper.
#[derive(Clone, Debug)]
pub struct NaiveSmoothVoronoi {
    dim: usize,
    n: usize,
    keys: Vec<f64>,
    step: Step,
    /// Per key i, the d×n matrix G_i with g_i = G_i y.
    grads: Vec<DMatrix<f64>>,
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(p, q)| p * q).sum()
}

fn sub(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(p, q)| p - q).collect()
}

impl NaiveSmoothVoronoi {
    /// Precomputes all gradients (O(n⁴d) for the a_ij, n SVDs). Same
    /// validation and errors as [`crate::interp::Interpolator::new`].
    pub fn new(dim: usize, keys: &[f64]) -> Result<Self, InterpError> {
        let (n, _) = validate_keys(dim, keys)?;
        let mut me = NaiveSmoothVoronoi {
            dim,
            n,
            keys: keys.to_vec(),
            step: Step::new(GAMMA),
            grads: Vec::new(),
        };
        me.grads = (0..n).map(|i| me.gradient_matrix(i)).collect();
        Ok(me)
    }

    fn key(&self, i: usize) -> &[f64] {
        &self.keys[i * self.dim..(i + 1) * self.dim]
    }

    /// Normalised kernels φ_i(x) (eq. 8 and its normalisation), O(n²d).
    pub fn kernels(&self, x: &[f64]) -> Vec<f64> {
        let mut phi = vec![0.0; self.n];
        for (i, p) in phi.iter_mut().enumerate() {
            let xi = self.key(i);
            let mut prod = 1.0;
            for j in 0..self.n {
                if j == i {
                    continue;
                }
                let xj = self.key(j);
                let dir = sub(xi, xj);
                let t = dot(&sub(x, xj), &dir) / dot(&dir, &dir);
                prod *= self.step.eval(t);
            }
            *p = prod;
        }
        let sum: f64 = phi.iter().sum();
        phi.iter().map(|p| p / sum).collect()
    }

    /// a_ij = φ_i(α x_i + (1 − α) x_j) (eq. 11).
    fn a(&self, i: usize, j: usize) -> f64 {
        let m: Vec<f64> = self
            .key(i)
            .iter()
            .zip(self.key(j))
            .map(|(p, q)| ALPHA * p + (1.0 - ALPHA) * q)
            .collect();
        self.kernels(&m)[i]
    }

    /// b_ij (eq. 12).
    fn b(&self, i: usize, j: usize) -> f64 {
        let dj = sub(self.key(j), self.key(i));
        let mut min_cos = f64::INFINITY;
        for k in 0..self.n {
            if k == i {
                continue;
            }
            let dk = sub(self.key(k), self.key(i));
            let cos = dot(&dk, &dj) / (dot(&dk, &dk).sqrt() * dot(&dj, &dj).sqrt());
            min_cos = min_cos.min(cos);
        }
        self.step.eval(-BETA * min_cos)
    }

    /// G_i (d×n): minimiser of eq. 10 + ε‖g‖² for every unit y at once,
    /// via SVD of the stacked system.
    fn gradient_matrix(&self, i: usize) -> DMatrix<f64> {
        let (n, d) = (self.n, self.dim);
        let others: Vec<usize> = (0..n).filter(|&j| j != i).collect();
        let rows = others.len() + d;
        let mut lhs = DMatrix::zeros(rows, d);
        let mut rhs = DMatrix::zeros(rows, n);
        for (r, &j) in others.iter().enumerate() {
            let diff = sub(self.key(j), self.key(i));
            let len = dot(&diff, &diff).sqrt();
            let a = self.a(i, j);
            let b = self.b(i, j);
            for c in 0..d {
                lhs[(r, c)] = a * diff[c] / len;
            }
            // a_ij b_ij (y_j − y_i) / ‖x_j − x_i‖ as a row acting on y.
            rhs[(r, j)] += a * b / len;
            rhs[(r, i)] -= a * b / len;
        }
        for c in 0..d {
            lhs[(others.len() + c, c)] = EPSILON.sqrt();
        }
        lhs.svd(true, true)
            .solve(&rhs, 0.0)
            .expect("SVD was computed with both U and Vᵀ")
    }

    /// Basis weights `w(x) = Σ_i φ_i(x) (e_i + G_iᵀ (x − x_i))` (eq. 9).
    ///
    /// # Panics
    /// If `x` is not a point of the keys' dimension or `out` is not one weight per key.
    pub fn weights(&self, x: &[f64], out: &mut [f64]) {
        assert_eq!(x.len(), self.dim, "query has the wrong dimension");
        assert_eq!(out.len(), self.n, "output has the wrong length");
        if self.n == 1 {
            out[0] = 1.0;
            return;
        }
        let phi = self.kernels(x);
        out.fill(0.0);
        for i in 0..self.n {
            out[i] += phi[i];
            let off = sub(x, self.key(i));
            let g = &self.grads[i];
            for (k, o) in out.iter_mut().enumerate() {
                let along: f64 = (0..self.dim).map(|c| g[(c, k)] * off[c]).sum();
                *o += phi[i] * along;
            }
        }
    }
}
