//! Closest-point binding timings (SPEC §3): BVH build and binding of every
//! stroke point, on the Dog bench character and on large synthetic proxies.
//! Run with `cargo bench --bench bind`; no harness, prints medians.
//!
//! Cases:
//! - `dog`: every stroke layer of `bench_out/dog.usdc` (161,520 points on a
//!   5,014-vertex proxy; `scripts/bench` writes the file, or set
//!   `PAINTERLY_BIND_DOG`); skipped when the file is missing;
//! - `grid`: a 1001 × 1001 height field (2,000,000 triangles), 100,000
//!   points scattered just off it;
//! - `soup`: 2,000,000 small triangles with their own vertices at random
//!   places in the unit cube, 100,000 random points;
//! - `bigsoup`: 800,000 triangles over 200,000 random shared vertices (each
//!   triangle spans the cube), 2,000 random points: the worst case for any
//!   bounding-volume hierarchy.
//!
//! Every case also checks a sample of points against brute force over all
//! triangles with the SPEC §3 tie rule ([`painterly::bind::bind_brute_force`]),
//! and times the binding painterly used before (parry's QBVH) on the same
//! points in the same run (`--no-parry` skips it; on `bigsoup` only 20
//! points, each query costing it about a quarter of a second).
//! Options: `--reps N`, `--cases dog,grid,soup,bigsoup`.

use glam::{DVec3, Vec3};
use painterly::bind::{bind_brute_force, ClosestPoint};
use painterly::mesh::fan_triangulate;
use std::time::{Duration, Instant};

/// Tiny LCG (Knuth's MMIX constants): reproducible inputs without a rand crate.
struct Lcg(u64);

impl Lcg {
    fn unit(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn vec(&mut self) -> DVec3 {
        DVec3::new(self.unit(), self.unit(), self.unit())
    }
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

/// This process's CPU time (user + system, all threads) from
/// /proc/self/stat, in clock ticks of 10 ms: on a shared machine it shows
/// the work done where wall time also shows the wait for a core.
fn cpu_time() -> Duration {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map_or("", |(_, a)| a);
    // Fields 14 and 15 (utime, stime) are the 12th and 13th after ")".
    let f: Vec<&str> = after.split_whitespace().collect();
    let field = |i: usize| f.get(i).and_then(|x| x.parse::<u64>().ok()).unwrap_or(0);
    let ticks = field(11) + field(12);
    Duration::from_millis(10 * ticks)
}

/// (wall, CPU) time of `f`.
fn timed<T>(f: impl FnOnce() -> T) -> (T, [Duration; 2]) {
    let (w, c) = (Instant::now(), cpu_time());
    let out = f();
    (out, [w.elapsed(), cpu_time().saturating_sub(c)])
}

fn median2(v: &[[Duration; 2]]) -> [Duration; 2] {
    [
        median(v.iter().map(|x| x[0]).collect()),
        median(v.iter().map(|x| x[1]).collect()),
    ]
}

struct Case {
    name: &'static str,
    points: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    /// Point sets bound one after another with one BVH (a rig's layers).
    queries: Vec<Vec<Vec3>>,
}

fn grid(n: usize, rng: &mut Lcg, npts: usize) -> Case {
    let h = |x: f64, y: f64| 0.05 * (7.0 * x).sin() * (5.0 * y).cos();
    let mut points = Vec::with_capacity(n * n);
    for j in 0..n {
        for i in 0..n {
            let (x, y) = (i as f64 / (n - 1) as f64, j as f64 / (n - 1) as f64);
            points.push(DVec3::new(x, y, h(x, y)));
        }
    }
    let mut counts = Vec::new();
    let mut idx = Vec::new();
    for j in 0..n - 1 {
        for i in 0..n - 1 {
            let v = (j * n + i) as u32;
            counts.push(4);
            idx.extend_from_slice(&[v, v + 1, v + 1 + n as u32, v + n as u32]);
        }
    }
    let q = (0..npts)
        .map(|_| {
            let (x, y) = (rng.unit(), rng.unit());
            Vec3::new(x as f32, y as f32, (h(x, y) + 0.02 * (rng.unit() - 0.5)) as f32)
        })
        .collect();
    Case {
        name: "grid",
        points,
        triangles: fan_triangulate(&counts, &idx),
        queries: vec![q],
    }
}

fn soup(ntris: usize, rng: &mut Lcg, npts: usize) -> Case {
    let size = 2.0 / (ntris as f64).cbrt();
    let mut points = Vec::with_capacity(3 * ntris);
    let mut triangles = Vec::with_capacity(ntris);
    for t in 0..ntris {
        let c = rng.vec();
        for _ in 0..3 {
            points.push(c + (rng.vec() - 0.5) * size);
        }
        let v = 3 * t as u32;
        triangles.push([v, v + 1, v + 2]);
    }
    let q = (0..npts).map(|_| rng.vec().as_vec3()).collect();
    Case {
        name: "soup",
        points,
        triangles,
        queries: vec![q],
    }
}

fn big_soup(ntris: usize, nverts: usize, rng: &mut Lcg, npts: usize) -> Case {
    let points: Vec<DVec3> = (0..nverts).map(|_| rng.vec()).collect();
    let mut pick = || ((rng.unit() * nverts as f64) as u32).min(nverts as u32 - 1);
    let triangles = (0..ntris).map(|_| [pick(), pick(), pick()]).collect();
    let q = (0..npts).map(|_| rng.vec().as_vec3()).collect();
    Case {
        name: "bigsoup",
        points,
        triangles,
        queries: vec![q],
    }
}

fn dog() -> Option<Case> {
    use painterly::usd_io::scene::Scene;
    use painterly::usd_io::stage::StageReader;
    let path = std::env::var("PAINTERLY_BIND_DOG").unwrap_or_else(|_| "bench_out/dog.usdc".into());
    if !std::path::Path::new(&path).exists() {
        println!("dog: {path} not found (run scripts/bench once); skipped");
        return None;
    }
    let r = StageReader::open(std::path::Path::new(&path)).expect("open the Dog");
    let scene = Scene::read(&r).expect("read the Dog");
    let rig = &scene.rigs[0];
    Some(Case {
        name: "dog",
        points: rig.proxy.rest.clone(),
        triangles: fan_triangulate(&rig.proxy.face_counts, &rig.proxy.face_indices),
        queries: rig.layers.iter().map(|l| l.rest_points.clone()).collect(),
    })
}

/// The binding painterly used before (parry's QBVH picks a closest
/// triangle, barycentrics recomputed in f64; ties by traversal order),
/// timed in the same run for a before/after ratio: (build, bind).
fn parry_times(case: &Case, queries: &[Vec3]) -> [[Duration; 2]; 2] {
    use parry3d_f64::math::Point;
    use parry3d_f64::query::PointQueryWithLocation;
    use parry3d_f64::shape::TriMesh;
    use rayon::prelude::*;
    let (mesh, build) = timed(|| {
        let verts = case.points.iter().map(|p| Point::new(p.x, p.y, p.z)).collect();
        TriMesh::new(verts, case.triangles.clone())
    });
    let (n, bind) = timed(|| {
        queries
            .par_iter()
            .map(|p| {
                let p = p.as_dvec3();
                let (_, (tri, _)) = mesh.project_local_point_and_get_location(&Point::new(p.x, p.y, p.z), false);
                let [a, b, c] = case.triangles[tri as usize].map(|v| case.points[v as usize]);
                let w = painterly::bind::closest_point_barycentric(p, a, b, c);
                (w[0] > 0.5) as usize
            })
            .sum::<usize>()
    });
    std::hint::black_box(n);
    [build, bind]
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn run(case: &Case, reps: usize, check: usize, parry_points: usize) {
    let npts: usize = case.queries.iter().map(Vec::len).sum();
    let flat: Vec<Vec3> = case.queries.iter().flatten().copied().collect();
    let parry_q = &flat[..parry_points.min(flat.len())];
    let (mut build, mut bind, mut pbuild, mut pbind) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut result = Vec::new();
    for _ in 0..reps {
        // Alternate the two sides.
        if !parry_q.is_empty() {
            let [b, q] = parry_times(case, parry_q);
            pbuild.push(b);
            pbind.push(q);
        }
        let (cp, b) = timed(|| ClosestPoint::new(&case.points, &case.triangles));
        let (r, q) = timed(|| case.queries.iter().map(|q| cp.bind(q)).collect::<Vec<_>>());
        build.push(b);
        bind.push(q);
        result = r;
    }
    // Exactness on a sample (brute force is O(points × triangles)).
    let got: Vec<_> = result
        .iter()
        .flat_map(|b| b.vertices.iter().copied().zip(b.weights.iter().copied()))
        .collect();
    let stride = (flat.len() / check.max(1)).max(1);
    let sample: Vec<usize> = (0..flat.len()).step_by(stride).take(check).collect();
    let pts: Vec<Vec3> = sample.iter().map(|&i| flat[i]).collect();
    let want = bind_brute_force(&case.points, &case.triangles, &pts);
    let mismatches = sample
        .iter()
        .enumerate()
        .filter(|&(k, &i)| got[i] != (want.vertices[k], want.weights[k]))
        .count();
    let ([bw, bc], [qw, qc]) = (median2(&build), median2(&bind));
    let per = |d: Duration, n: usize| d.as_secs_f64() * 1e6 / n as f64;
    println!(
        "{:>8} {:>8} tris {:>6} points | build {:>7.1} ms (cpu {:>7.1}) | bind {:>8.1} ms (cpu {:>8.1}) {:>6.2} µs/point (cpu {:>6.2}) | brute force: {}/{} differ",
        case.name,
        case.triangles.len(),
        npts,
        ms(bw),
        ms(bc),
        ms(qw),
        ms(qc),
        per(qw, npts),
        per(qc, npts),
        mismatches,
        sample.len()
    );
    if !pbuild.is_empty() {
        let ([pbw, pbc], [pqw, pqc]) = (median2(&pbuild), median2(&pbind));
        let n = parry_q.len();
        println!(
            "{:>8} parry before, {:>6} points | build {:>7.1} ms (cpu {:>7.1}) | bind {:>6.2} µs/point (cpu {:>6.2}) | now faster: build ×{:.2} (cpu ×{:.2}), bind ×{:.2} (cpu ×{:.2})",
            "",
            n,
            ms(pbw),
            ms(pbc),
            per(pqw, n),
            per(pqc, n),
            pbw.as_secs_f64() / bw.as_secs_f64(),
            pbc.as_secs_f64() / bc.as_secs_f64().max(1e-9),
            per(pqw, n) / per(qw, npts),
            per(pqc, n) / per(qc, npts).max(1e-9),
        );
    }
    assert_eq!(mismatches, 0, "{}: the BVH binding differs from brute force", case.name);
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = !args.iter().any(|a| a == "--bench") || args.iter().any(|a| a == "--quick");
    let threads = rayon::current_num_threads();
    println!("closest-point binding (medians; {threads} rayon threads)");
    // `--reps N`, `--cases dog,grid,soup,bigsoup`.
    let arg = |name: &str| args.iter().position(|a| a == name).and_then(|i| args.get(i + 1));
    let (reps, scale) = if quick { (1, 20) } else { (5, 1) };
    let reps = arg("--reps").and_then(|r| r.parse().ok()).unwrap_or(reps);
    let cases = arg("--cases").map_or("dog,grid,soup,bigsoup", |c| c.as_str());
    let on = |c: &str| cases.split(',').any(|x| x == c);
    let big = |n: usize| n / scale;
    let mut rng = Lcg(0x5eed);
    // parry (the binding before) on the same points, fewer on the soup
    // where a query costs it a quarter of a second.
    let parry = !args.iter().any(|a| a == "--no-parry");
    let pp = |n: usize| if parry { n } else { 0 };
    if on("dog") {
        if let Some(d) = dog() {
            run(&d, reps, if quick { 200 } else { 2000 }, pp(usize::MAX));
        }
    }
    if on("grid") {
        let n = ((1001 * 1001 / scale) as f64).sqrt() as usize;
        run(&grid(n, &mut rng, big(100_000)), reps, 200, pp(usize::MAX));
    }
    if on("soup") {
        run(&soup(big(2_000_000), &mut rng, big(100_000)), reps, 200, pp(usize::MAX));
    }
    if on("bigsoup") {
        let c = big_soup(big(800_000), big(200_000), &mut rng, big(2_000));
        run(&c, reps.min(3), 50, pp(if quick { 5 } else { 20 }));
    }
}
