//! The quadratic–linear–quadratic smooth step S_γ (Bassett et al. 2013, eq. 7,
//! with the SPEC's erratum applied).
//!
//! As printed, eq. 7 divides its quadratic pieces by 2γ − γ², which makes the
//! step jump at t = γ (0.111 against the linear piece's 0.125 for γ = 0.2).
//! The step whose linear middle piece has slope 1/(1 − γ) and which is C¹
//! divides by 2γ(1 − γ) instead; that is the one used everywhere here
//! (kernels, b_ij, sentinel blends).

/// Evaluates the corrected smooth step S_γ(t).
///
/// S is 0 for t ≤ 0, 1 for t ≥ 1, t²/(2γ(1−γ)) on (0, γ],
/// 1 − (1−t)²/(2γ(1−γ)) on (1−γ, 1) and 0.5 + (t − 0.5)/(1 − γ) in between.
/// It is C¹, monotone, S(0.5) = 0.5 and S(1 − t) = 1 − S(t).
/// `gamma` is clamped to [0, 0.5] (beyond ½ the pieces would overlap);
/// γ = 0 degenerates to the C⁰ clamp of t to [0, 1].
pub fn smooth_step(t: f64, gamma: f64) -> f64 {
    Step::new(gamma).eval(t)
}

/// Evaluates dS_γ/dt, the derivative of [`smooth_step`].
///
/// Continuous everywhere (that is what makes the kernels C¹); its maximum,
/// 1/(1 − γ), is reached on the linear piece.
pub fn smooth_step_derivative(t: f64, gamma: f64) -> f64 {
    Step::new(gamma).derivative(t)
}

/// S_γ with its constants folded, for inner loops.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Step {
    gamma: f64,
    /// 1 − γ.
    one_minus_gamma: f64,
    /// 1 / (1 − γ): slope of the linear piece.
    slope: f64,
    /// 1 / (2γ(1 − γ)): curvature factor of the quadratic pieces.
    quad: f64,
}

impl Step {
    /// Precomputes the constants of S_γ.
    pub(crate) fn new(gamma: f64) -> Self {
        let gamma = gamma.clamp(0.0, 0.5);
        let one_minus_gamma = 1.0 - gamma;
        let quad = if gamma > 0.0 {
            1.0 / (2.0 * gamma * one_minus_gamma)
        } else {
            0.0 // the quadratic pieces are empty when γ = 0
        };
        Step {
            gamma,
            one_minus_gamma,
            slope: 1.0 / one_minus_gamma,
            quad,
        }
    }

    /// S_γ(t). Exactly 0 for t ≤ 0 and exactly 1 for t ≥ 1 (the kernels'
    /// locality relies on the exact zero).
    #[inline(always)]
    pub(crate) fn eval(&self, t: f64) -> f64 {
        if t <= 0.0 {
            0.0
        } else if t >= 1.0 {
            1.0
        } else if t <= self.gamma {
            t * t * self.quad
        } else if t > self.one_minus_gamma {
            let u = 1.0 - t;
            1.0 - u * u * self.quad
        } else {
            0.5 + (t - 0.5) * self.slope
        }
    }

    /// S_γ(t) written with selects instead of branches, so loops over many
    /// parameters vectorise and do not mispredict. Bitwise equal to
    /// [`Step::eval`].
    #[inline(always)]
    pub(crate) fn eval_select(&self, t: f64) -> f64 {
        let lin = 0.5 + (t - 0.5) * self.slope;
        let low = t * t * self.quad;
        let u = 1.0 - t;
        let high = 1.0 - u * u * self.quad;
        let inner = if t <= self.gamma {
            low
        } else if t > self.one_minus_gamma {
            high
        } else {
            lin
        };
        if t <= 0.0 {
            0.0
        } else if t >= 1.0 {
            1.0
        } else {
            inner
        }
    }

    /// dS_γ/dt.
    #[inline]
    pub(crate) fn derivative(&self, t: f64) -> f64 {
        if t <= 0.0 || t >= 1.0 {
            0.0
        } else if t <= self.gamma {
            2.0 * t * self.quad
        } else if t > self.one_minus_gamma {
            2.0 * (1.0 - t) * self.quad
        } else {
            self.slope
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GAMMAS: [f64; 5] = [0.05, 0.1, 0.2, 0.35, 0.5];

    #[test]
    fn continuous_and_c1_at_the_joints() {
        for &g in &GAMMAS {
            for &joint in &[0.0, g, 1.0 - g, 1.0] {
                let h = 1e-9;
                let below = smooth_step(joint - h, g);
                let above = smooth_step(joint + h, g);
                assert!((below - above).abs() < 1e-8, "S jumps at {joint} for γ={g}");
                let d_below = smooth_step_derivative(joint - h, g);
                let d_above = smooth_step_derivative(joint + h, g);
                assert!(
                    (d_below - d_above).abs() < 1e-7,
                    "S' jumps at {joint} for γ={g}: {d_below} vs {d_above}"
                );
            }
        }
    }

    #[test]
    fn erratum_value_at_gamma() {
        // Corrected: both pieces give γ/(2(1−γ)) = 0.125 at γ = 0.2.
        assert!((smooth_step(0.2, 0.2) - 0.125).abs() < 1e-15);
        let linear_side = 0.5 + (0.2 + 1e-12 - 0.5) / 0.8;
        assert!((smooth_step(0.2 + 1e-12, 0.2) - linear_side).abs() < 1e-15);
        // The printed 2γ − γ² would give 0.04 / 0.36 = 0.111.
        assert!((smooth_step(0.2, 0.2) - 0.04 / 0.36).abs() > 0.01);
    }

    #[test]
    fn half_and_symmetry() {
        for &g in &GAMMAS {
            assert!((smooth_step(0.5, g) - 0.5).abs() < 1e-15);
            for k in 0..=200 {
                let t = -0.5 + 2.0 * k as f64 / 200.0;
                let s = smooth_step(t, g);
                let mirrored = smooth_step(1.0 - t, g);
                assert!((s + mirrored - 1.0).abs() < 1e-14, "γ={g} t={t}");
                assert!((0.0..=1.0).contains(&s));
            }
        }
    }

    #[test]
    fn derivative_matches_finite_differences_and_is_monotone() {
        for &g in &GAMMAS {
            let mut prev = smooth_step(-0.1, g);
            for k in 0..=1000 {
                let t = -0.1 + 1.2 * k as f64 / 1000.0;
                let h = 1e-6;
                let fd = (smooth_step(t + h, g) - smooth_step(t - h, g)) / (2.0 * h);
                assert!((fd - smooth_step_derivative(t, g)).abs() < 1e-5, "γ={g} t={t}");
                let s = smooth_step(t, g);
                assert!(s >= prev);
                prev = s;
            }
            let max_slope = 1.0 / (1.0 - g);
            assert!((smooth_step_derivative(0.5, g) - max_slope).abs() < 1e-12);
        }
    }

    #[test]
    fn select_form_is_bitwise_equal() {
        for &g in &GAMMAS {
            let step = Step::new(g);
            for k in 0..=2000 {
                let t = -0.2 + 1.4 * k as f64 / 2000.0;
                assert_eq!(step.eval(t).to_bits(), step.eval_select(t).to_bits(), "γ={g} t={t}");
            }
            for t in [0.0, g, 1.0 - g, 1.0, f64::MIN_POSITIVE, 1.0 - f64::EPSILON] {
                assert_eq!(step.eval(t).to_bits(), step.eval_select(t).to_bits());
            }
        }
    }

    #[test]
    fn exact_ends_and_zero_gamma_is_a_clamp() {
        assert_eq!(smooth_step(0.0, 0.2), 0.0);
        assert_eq!(smooth_step(-3.0, 0.2), 0.0);
        assert_eq!(smooth_step(1.0, 0.2), 1.0);
        assert_eq!(smooth_step(7.0, 0.2), 1.0);
        for &t in &[-1.0, 0.0, 0.25, 0.5, 0.9, 1.0, 2.0] {
            assert!((smooth_step(t, 0.0) - f64::clamp(t, 0.0, 1.0)).abs() < 1e-15);
        }
    }

    #[test]
    fn t_at_one_minus_gamma_is_on_the_linear_piece() {
        // The upper quadratic covers (1 − γ, 1), open at 1 − γ, as documented:
        // there S' is the linear piece's slope exactly. The quadratic's
        // 2(1 − t)/(2γ(1 − γ)) is the same number in exact arithmetic but
        // rounds differently for these γ (e.g. 1.25 − 2⁻⁵² at γ = 0.2).
        for g in [0.05, 0.1, 0.2, 0.35] {
            assert_eq!(smooth_step_derivative(1.0 - g, g), 1.0 / (1.0 - g), "γ={g}");
        }
    }
}
