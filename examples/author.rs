//! Authoring with the library API (Bassett et al. 2013 §3.1–3.3): bind, brush
//! and key the strokes of `fixtures/tube.usda`, collecting the edits in an
//! edit layer that sublayers the input.
//!
//! ```sh
//! cargo run --release --ignore-rust-version --example author
//! ```
//!
//! Writes `tube_edits.usda` (and a copy of the input beside it) into a fresh
//! temporary folder, prints what each step did, and leaves the folder for
//! inspection (`usdview <dir>/tube_edits.usda`). The input is never modified.

use std::path::{Path, PathBuf};

use glam::DVec3;
use painterly::author::{self, BindOptions, Brush, BrushOptions, KeyKind, KeyOptions};
use painterly::tools::Falloff;
use painterly::usd_io::edit::{EditSession, EditTarget};

const RINGS: &str = "/Tube/Paint/Rings";

/// Opens the edit layer (created by the first step, appended to by the others).
fn session(input: &Path, edits: &Path) -> painterly::Result<EditSession> {
    EditSession::open(input, &EditTarget::Layer(edits.to_path_buf()))
}

fn out_dir() -> std::io::Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("painterly-author-example-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    Ok(dir)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/tube.usda");
    let dir = out_dir()?;
    // Work on a copy so the edit layer can sublayer it as `./tube.usda`.
    let input = dir.join("tube.usda");
    std::fs::copy(fixture, &input)?;
    let edits = dir.join("tube_edits.usda");

    // 1. Bind the rings in the rest pose: caches painterly:restPoints and the
    //    closest-point binding. (With `time: Some(t)`, strokes painted in the
    //    pose at t are taken back to the rest pose.)
    let s = session(&input, &edits)?;
    let report = author::bind(
        &s,
        &BindOptions {
            layers: vec![RINGS.into()],
            time: None,
        },
    )?;
    s.save()?;
    for (layer, n) in &report {
        println!("bind: {n} points of {layer}");
    }

    // 2. Smudge the rings in the pose at frame 12 (the tube bends most there):
    //    a world-space tool path up the side of the tube, cubic falloff.
    let s = session(&input, &edits)?;
    let moved = author::brush(
        &s,
        Brush::Smudge,
        &BrushOptions {
            layer: RINGS.into(),
            path: vec![
                DVec3::new(1.5, 0.5, 0.0),
                DVec3::new(1.3, 2.0, 0.2),
                DVec3::new(0.8, 3.5, 0.3),
            ],
            radius: 0.6,
            strength: 0.15,
            falloff: Falloff::Cubic,
            time: Some(12.0),
            key: None,
            strokes: None,
        },
    )?;
    s.save()?;
    println!("smudge: moved {moved} points at frame 12");

    // 3. Expand strokes 0-4 of the rings away from the surface, in the rest pose.
    let s = session(&input, &edits)?;
    let moved = author::brush(
        &s,
        Brush::Expand,
        &BrushOptions {
            layer: RINGS.into(),
            path: vec![DVec3::new(1.0, 0.0, 0.5), DVec3::new(1.0, 1.0, 0.5)],
            radius: 0.8,
            strength: 0.1,
            falloff: Falloff::None,
            time: None,
            key: None,
            strokes: Some(vec![(0, 4)]),
        },
    )?;
    s.save()?;
    println!("expand: moved {moved} points");

    // 4. Key the result: a pose key holding the current rest points, and an
    //    opacity time key with sentinels around it.
    let keys = [
        (KeyKind::Pose, 12.0, None, true),
        (KeyKind::Sentinel, 4.0, None, false),
        (KeyKind::Time, 8.0, Some(0.2), false),
        (KeyKind::Sentinel, 16.0, None, false),
    ];
    for (kind, time, opacity, points) in keys {
        let s = session(&input, &edits)?;
        let path = author::key(
            &s,
            &KeyOptions {
                layer: RINGS.into(),
                time,
                kind,
                name: None,
                points,
                opacity,
                replace: false,
                camera: None,
            },
        )?;
        s.save()?;
        println!("key: {path} ({kind:?} at {time})");
    }

    println!("edits in {} (over {})", edits.display(), input.display());
    Ok(())
}
