//! Smooth Voronoi timings against the paper's (Bassett et al. 2013 §4.2,
//! "Complexity": one Core i7 930 thread, d = 100: 35 ms / 120 µs at n = 20,
//! 540 ms / 470 µs at n = 40 for precompute / weights) and against the
//! direct O(n⁴d) reference in `painterly::interp::naive`, timed in the same
//! run. Run with `cargo bench --bench interp`; no harness, prints medians.
//!
//! Two key layouts, both with a fixed seed:
//! - `uniform`: keys uniform in [0, 1]^100. Every key is then a vertex of the
//!   keys' simplex, so every b_ij is 0 and no gradient is fitted (cheap).
//! - `plane3`: keys uniform in a random 3-D affine subspace of R^100 (a rig
//!   where three controls matter), so interior keys fit gradients.

use painterly::interp::naive::NaiveSmoothVoronoi;
use painterly::interp::{Interpolator, Method};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// Tiny LCG (Knuth's MMIX constants): reproducible keys without a rand crate.
struct Lcg(u64);

impl Lcg {
    fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn uniform_keys(rng: &mut Lcg, n: usize, d: usize) -> Vec<f64> {
    (0..n * d).map(|_| rng.unit()).collect()
}

fn plane_keys(rng: &mut Lcg, n: usize, d: usize, k: usize) -> Vec<f64> {
    let origin: Vec<f64> = (0..d).map(|_| rng.unit()).collect();
    let basis: Vec<Vec<f64>> = (0..k).map(|_| (0..d).map(|_| rng.unit() - 0.5).collect()).collect();
    let mut keys = Vec::with_capacity(n * d);
    for _ in 0..n {
        let z: Vec<f64> = (0..k).map(|_| rng.unit()).collect();
        for c in 0..d {
            keys.push(origin[c] + (0..k).map(|m| z[m] * basis[m][c]).sum::<f64>());
        }
    }
    keys
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

/// Median over `reps` runs of `f`.
fn time_median(reps: usize, mut f: impl FnMut()) -> Duration {
    median(
        (0..reps)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed()
            })
            .collect(),
    )
}

fn fmt(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s >= 1e-3 {
        format!("{:9.3} ms", s * 1e3)
    } else {
        format!("{:9.2} µs", s * 1e6)
    }
}

fn main() {
    // `cargo bench` passes `--bench`; under `cargo test --all-targets` (or
    // with `--quick`) only a smoke run with a few repetitions is done.
    let args: Vec<String> = std::env::args().collect();
    let quick = !args.iter().any(|a| a == "--bench") || args.iter().any(|a| a == "--quick");
    let d = 100;
    println!("smooth Voronoi, d = {d} (medians; paper: one Core i7 930 thread)");
    println!(
        "{:>7} {:>3} {:>12} {:>12} {:>12} {:>9} {:>9} {:>12} {:>12} {:>12} {:>9} {:>9}",
        "layout",
        "n",
        "precompute",
        "paper",
        "naive",
        "paper/x",
        "naive/x",
        "weights",
        "paper",
        "naive",
        "paper/x",
        "naive/x"
    );
    for &(n, paper_pre, paper_w) in &[(20usize, 35e-3, 120e-6), (40usize, 540e-3, 470e-6)] {
        for layout in ["uniform", "plane3"] {
            let mut rng = Lcg(0x5eed ^ (n as u64) << 8);
            let keys = match layout {
                "uniform" => uniform_keys(&mut rng, n, d),
                _ => plane_keys(&mut rng, n, d, 3),
            };
            let queries: Vec<Vec<f64>> = (0..64)
                .map(|q| {
                    // Half near keys, half anywhere in the keys' box.
                    let base = &keys[(q % n) * d..(q % n + 1) * d];
                    (0..d)
                        .map(|c| {
                            if q % 2 == 0 {
                                base[c] + 0.05 * (rng.unit() - 0.5)
                            } else {
                                rng.unit()
                            }
                        })
                        .collect()
                })
                .collect();

            let reps = if quick {
                3
            } else if n <= 20 {
                300
            } else {
                60
            };
            let pre = time_median(reps, || {
                black_box(Interpolator::new(Method::SmoothVoronoi, d, black_box(&keys)).unwrap());
            });
            let interp = Interpolator::new(Method::SmoothVoronoi, d, &keys).unwrap();
            let mut out = vec![0.0; n];
            let batches = if quick { 3 } else { 200 };
            let per_batch = queries.len();
            let w = time_median(batches, || {
                for q in &queries {
                    interp.weights(black_box(q), &mut out);
                    black_box(&out);
                }
            }) / per_batch as u32;

            let naive_reps = if quick || n > 20 { 1 } else { 3 };
            let naive_pre = time_median(naive_reps, || {
                black_box(NaiveSmoothVoronoi::new(d, black_box(&keys)).unwrap());
            });
            let naive = NaiveSmoothVoronoi::new(d, &keys).unwrap();
            let naive_w = time_median(if quick { 1 } else { 15 }, || {
                for q in &queries {
                    naive.weights(black_box(q), &mut out);
                    black_box(&out);
                }
            }) / per_batch as u32;

            // Sanity: both agree on this layout.
            let mut wf = vec![0.0; n];
            let mut max_diff = 0.0f64;
            for q in &queries {
                interp.weights(q, &mut wf);
                naive.weights(q, &mut out);
                for i in 0..n {
                    max_diff = max_diff.max((wf[i] - out[i]).abs());
                }
            }
            assert!(max_diff < 1e-9, "fast and naive disagree by {max_diff}");

            println!(
                "{:>7} {:>3} {} {} {} {:>9.0} {:>9.0} {} {} {} {:>9.1} {:>9.1}",
                layout,
                n,
                fmt(pre),
                fmt(Duration::from_secs_f64(paper_pre)),
                fmt(naive_pre),
                paper_pre / pre.as_secs_f64(),
                naive_pre.as_secs_f64() / pre.as_secs_f64(),
                fmt(w),
                fmt(Duration::from_secs_f64(paper_w)),
                fmt(naive_w),
                paper_w / w.as_secs_f64(),
                naive_w.as_secs_f64() / w.as_secs_f64(),
            );
        }
    }
    println!("targets: precompute ≤ 0.35 ms (n=20) / 5 ms (n=40); weights ≤ 12 µs / 47 µs");
}
