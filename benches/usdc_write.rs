//! Crate (`.usdc`) writer timings: painterly's writer (`usd_io::usdc`)
//! against openusd 0.8's `CrateWriter`, on the same layer held in memory.
//!
//!     cargo bench --ignore-rust-version --bench usdc_write -- [LAYER.usdc] [--runs N]
//!
//! With a layer (`scripts/bench_usdc` passes the Dog-size bake), it is read
//! with openusd and copied into an `sdf::Data`; without one, a synthetic layer
//! of the Dog bake's shape is built (42 stroke layers, 161,520 points, 48
//! frames of points, extent and displayOpacity). Each writer then writes it to
//! a file in the system temp dir, alternately, `--runs` times (default 5):
//!
//! - openusd: `CrateWriter::write` into a `Vec`, then one file write (what
//!   painterly did before, see `../shared/notes/openusd.md`);
//! - painterly: `usdc::write_layer_file`, streaming through a `BufWriter`.
//!
//! Prints each file's size and the median wall time. Under `cargo test
//! --benches` (no `--bench` flag) only a small smoke run is done.

use std::io::Cursor;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use openusd::gf;
use openusd::sdf::{self, AbstractData, SpecType, Value};
use painterly::usd_io::usdc;

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v[v.len() / 2]
}

/// A layer shaped like a painterly bake of the Dog: over specs, points
/// (`point3f[]`), extent and per-curve displayOpacity sampled every frame.
fn synthetic(layers: usize, points: usize, frames: usize) -> sdf::Data {
    let mut data = sdf::Data::new();
    let names: Vec<openusd::tf::Token> = (0..layers).map(|i| format!("Layer{i:02}").into()).collect();
    let root = data.create_spec(sdf::Path::abs_root(), SpecType::PseudoRoot);
    root.add("startTimeCode", Value::Double(1.0));
    root.add("endTimeCode", Value::Double(frames as f64));
    root.add("primChildren", Value::TokenVec(vec!["Dog".into()]));
    let dog = data.create_spec(sdf::Path::new("/Dog").unwrap(), SpecType::Prim);
    dog.add("specifier", Value::Specifier(sdf::Specifier::Over));
    dog.add("primChildren", Value::TokenVec(names.clone()));
    let per_layer = points / layers;
    for (li, name) in names.iter().enumerate() {
        let prim = format!("/Dog/{}", name.as_str());
        let spec = data.create_spec(sdf::Path::new(&prim).unwrap(), SpecType::Prim);
        spec.add("specifier", Value::Specifier(sdf::Specifier::Over));
        spec.add(
            "propertyChildren",
            Value::TokenVec(vec!["points".into(), "extent".into(), "primvars:displayOpacity".into()]),
        );
        let mut pts = Vec::new();
        let mut ext = Vec::new();
        let mut opa = Vec::new();
        for f in 0..frames {
            let t = 1.0 + f as f64;
            let p: Vec<gf::Vec3f> = (0..per_layer)
                .map(|i| {
                    let s = (i * 7 + li * 13 + f * 3) as f32;
                    gf::vec3f((s * 0.37).sin(), (s * 0.11).cos() + f as f32 * 0.01, s * 1e-4)
                })
                .collect();
            pts.push((t, Value::Vec3fVec(p)));
            ext.push((
                t,
                Value::Vec3fVec(vec![gf::vec3f(-1.0, -1.0, 0.0), gf::vec3f(1.0, 2.0, 1.0)]),
            ));
            opa.push((t, Value::FloatVec(vec![1.0; per_layer / 16])));
        }
        for (attr, ty, samples) in [
            ("points", "point3f[]", pts),
            ("extent", "float3[]", ext),
            ("primvars:displayOpacity", "float[]", opa),
        ] {
            let a = data.create_spec(sdf::Path::new(&format!("{prim}.{attr}")).unwrap(), SpecType::Attribute);
            a.add("typeName", Value::Token(ty.into()));
            a.add("timeSamples", Value::TimeSamples(samples));
        }
    }
    data
}

/// A crate layer read with openusd, copied into memory so neither writer
/// pays for decoding.
fn load(path: &str) -> sdf::Data {
    let bytes = std::fs::read(path).expect("read the layer");
    let src = openusd::usdc::CrateData::open(bytes, true).expect("a crate file");
    let mut data = sdf::Data::new();
    for p in src.spec_paths() {
        let ty = src.spec_type(&p).unwrap();
        let fields: Vec<(String, Value)> = src
            .list_fields(&p)
            .unwrap_or_default()
            .into_iter()
            .map(|f| {
                let v = src.get_field(&p, &f).unwrap().into_owned();
                (f, v)
            })
            .collect();
        let spec = data.create_spec(p, ty);
        for (f, v) in fields {
            spec.add(f, v);
        }
    }
    data
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = !args.iter().any(|a| a == "--bench");
    let runs = args
        .iter()
        .position(|a| a == "--runs")
        .and_then(|i| args.get(i + 1))
        .and_then(|n| n.parse().ok())
        .unwrap_or(if quick { 1 } else { 5 });
    let layer = args.iter().find(|a| a.ends_with(".usdc") || a.ends_with(".usd"));
    let data = match (layer, quick) {
        (Some(p), _) => load(p),
        (None, true) => synthetic(4, 4_000, 3),
        (None, false) => synthetic(42, 161_520, 48),
    };
    let dir = std::env::temp_dir();
    let old_path: PathBuf = dir.join(format!("painterly-bench-openusd-{}.usdc", std::process::id()));
    let new_path: PathBuf = dir.join(format!("painterly-bench-usdc-{}.usdc", std::process::id()));
    let (mut old_t, mut new_t) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        let t = Instant::now();
        let mut buf = Cursor::new(Vec::new());
        openusd::usdc::CrateWriter::write(&data, &mut buf).expect("openusd writes");
        std::fs::write(&old_path, buf.into_inner()).expect("write");
        old_t.push(t.elapsed());

        let t = Instant::now();
        usdc::write_layer_file(&new_path, &data).expect("painterly writes");
        new_t.push(t.elapsed());
    }
    let size = |p: &PathBuf| std::fs::metadata(p).map(|m| m.len()).unwrap_or(0);
    println!(
        "layer: {}",
        layer.map(String::as_str).unwrap_or(if quick {
            "synthetic (smoke)"
        } else {
            "synthetic Dog-size bake"
        })
    );
    println!(
        "openusd CrateWriter  {:>12} bytes  median {:8.3} s over {runs} runs",
        size(&old_path),
        median(old_t).as_secs_f64()
    );
    println!(
        "painterly usdc       {:>12} bytes  median {:8.3} s over {runs} runs",
        size(&new_path),
        median(new_t).as_secs_f64()
    );
    // Both read back (openusd) with the same specs.
    let back = openusd::usdc::CrateData::open(std::fs::read(&new_path).unwrap(), true).expect("readable");
    assert_eq!(back.spec_paths(), data.spec_paths());
    let _ = std::fs::remove_file(&old_path);
    let _ = std::fs::remove_file(&new_path);
}
