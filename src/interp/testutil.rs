//! Test helpers: a seeded generator, key layouts and a C¹ detector.

/// Property-test settings: `cases` cases (or `$PROPTEST_CASES` for a soak
/// run), and no regression files written (they would land outside this
/// module's directory); the layouts come from an explicit `seed` argument,
/// so a failure message reproduces it.
pub(crate) fn proptest_config(cases: u32) -> proptest::test_runner::Config {
    let cases = std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(cases);
    proptest::test_runner::Config {
        cases,
        failure_persistence: None,
        ..proptest::test_runner::Config::default()
    }
}

/// Tiny 64-bit LCG (Knuth's MMIX constants), so layouts follow from a seed.
pub(crate) struct Lcg(u64);

impl Lcg {
    pub(crate) fn new(seed: u64) -> Self {
        let mut g = Lcg(seed ^ 0x9E37_79B9_7F4A_7C15);
        g.next_u64();
        g
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        self.0
    }

    /// Uniform in [0, 1).
    pub(crate) fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    pub(crate) fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Uniform integer in 0..n.
    pub(crate) fn below(&mut self, n: usize) -> usize {
        ((self.next_u64() >> 33) as usize) % n
    }
}

pub(crate) fn random_point(rng: &mut Lcg, d: usize, lo: f64, hi: f64) -> Vec<f64> {
    (0..d).map(|_| rng.uniform(lo, hi)).collect()
}

pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(p, q)| p * q).sum()
}

/// n keys in [0, 1]^d, pairwise at least 0.3·n^(−1/d) apart.
pub(crate) fn separated_keys(rng: &mut Lcg, n: usize, d: usize) -> Vec<f64> {
    let mut min_dist = 0.3 * (n as f64).powf(-1.0 / d as f64);
    let mut keys: Vec<f64> = Vec::with_capacity(n * d);
    let mut tries = 0;
    while keys.len() < n * d {
        let p = random_point(rng, d, 0.0, 1.0);
        let ok = keys.chunks(d).all(|k| {
            let d2: f64 = k.iter().zip(&p).map(|(a, b)| (a - b) * (a - b)).sum();
            d2 >= min_dist * min_dist
        });
        if ok {
            keys.extend_from_slice(&p);
        }
        tries += 1;
        if tries % 1000 == 0 {
            min_dist *= 0.8;
        }
    }
    keys
}

/// n keys on a random k-dimensional affine subspace of R^d (k < d), and a
/// unit vector orthogonal to that subspace.
pub(crate) fn keys_in_subspace(rng: &mut Lcg, n: usize, d: usize, k: usize) -> (Vec<f64>, Vec<f64>) {
    assert!(k < d);
    let origin = random_point(rng, d, -0.5, 0.5);
    // Orthonormal basis of a random k-plane plus one more vector (Gram–Schmidt).
    let mut basis: Vec<Vec<f64>> = Vec::new();
    while basis.len() < k + 1 {
        let mut v = random_point(rng, d, -1.0, 1.0);
        for _ in 0..2 {
            for b in &basis {
                let c = dot(&v, b);
                v.iter_mut().zip(b).for_each(|(x, y)| *x -= c * y);
            }
        }
        let len = dot(&v, &v).sqrt();
        if len > 1e-3 {
            basis.push(v.iter().map(|x| x / len).collect());
        }
    }
    let normal = basis.pop().unwrap();
    let coords = separated_keys(rng, n, k);
    let mut keys = Vec::with_capacity(n * d);
    for z in coords.chunks(k) {
        for c in 0..d {
            keys.push(origin[c] + (0..k).map(|m| z[m] * basis[m][c]).sum::<f64>());
        }
    }
    (keys, normal)
}

/// True when `f` on [0, 1] looks C¹: around the largest second differences,
/// refining the step does not make the second difference quotient blow up.
///
/// For a C¹ function with bounded (piecewise continuous) second derivative,
/// `|f(s+h) − 2f(s) + f(s−h)| / h²` converges as h shrinks; at a kink with
/// slope jump J it grows like J/h, so refining the step by 16 multiplies
/// the local maximum by at least ~8. Windows are kept inside [0, 1].
///
/// One refinement is not enough on its own: a smooth feature narrower than
/// the fine step (e.g. a segment that starts within 5e-5 of a smooth-step
/// joint, so only a sliver of a quadratic piece lies inside [0, 1]) is
/// undersampled at h/8 and only resolved at h/128, so the quotient grows
/// once and then stays put. A window is therefore rejected only if the
/// quotient grows again at h/2048: at a kink it keeps growing like 1/step,
/// for a bounded second derivative it has converged.
pub(crate) fn looks_c1(f: impl Fn(f64) -> f64) -> bool {
    let n = 1024usize;
    let h = 1.0 / n as f64;
    let vals: Vec<f64> = (0..=n).map(|k| f(k as f64 * h)).collect();
    let mut quot: Vec<(f64, usize)> = (1..n)
        .map(|k| ((vals[k + 1] - 2.0 * vals[k] + vals[k - 1]).abs() / (h * h), k))
        .collect();
    quot.sort_by(|a, b| b.0.total_cmp(&a.0));
    // Maximum second difference quotient with step `step` on [lo, hi].
    let local_max = |lo: f64, hi: f64, step: f64| -> f64 {
        let m = ((hi - lo) / step).round() as usize;
        let v: Vec<f64> = (0..=m).map(|j| f(lo + j as f64 * step)).collect();
        (1..m)
            .map(|j| (v[j + 1] - 2.0 * v[j] + v[j - 1]).abs() / (step * step))
            .fold(0.0, f64::max)
    };
    quot.iter().take(5).all(|&(_, k)| {
        let lo = (k as f64 - 3.0).max(0.0) * h;
        let hi = (k as f64 + 3.0).min(n as f64) * h;
        let grows = |coarse: f64, fine: f64| fine > 2.5 * coarse + 1e-3;
        let fine = local_max(lo, hi, h / 8.0);
        let finer = local_max(lo, hi, h / 128.0);
        !grows(fine, finer) || !grows(finer, local_max(lo, hi, h / 2048.0))
    })
}

/// Smallest distance between two keys.
pub(crate) fn min_spacing(keys: &[f64], d: usize) -> f64 {
    let n = keys.len() / d;
    let mut best = f64::INFINITY;
    for i in 0..n {
        for j in i + 1..n {
            let d2: f64 = (0..d).map(|c| (keys[i * d + c] - keys[j * d + c]).powi(2)).sum();
            best = best.min(d2.sqrt());
        }
    }
    best
}
