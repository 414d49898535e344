//! A bake is a function of its input alone: the bytes written do not depend
//! on how many threads evaluated the frames (issue 12).

use std::path::{Path, PathBuf};
use std::process::Command;

fn bake(input: &str, threads: usize, dir: &Path) -> Vec<u8> {
    let dir = dir.join(format!("threads{threads}"));
    std::fs::create_dir_all(&dir).unwrap();
    let out: PathBuf = dir.join("bake.usdc");
    let status = Command::new(env!("CARGO_BIN_EXE_painterly"))
        .args(["bake", input, "-o"])
        .arg(&out)
        .arg("--quiet")
        .env("RAYON_NUM_THREADS", threads.to_string())
        .status()
        .expect("painterly runs");
    assert!(status.success(), "bake of {input} with {threads} threads failed");
    std::fs::read(&out).unwrap()
}

#[test]
fn one_and_two_threads_write_identical_bytes() {
    let dir = std::env::temp_dir().join(format!("painterly_threads_{}", std::process::id()));
    // Skinned strokes (walk), pose keys (blowfish), view-dependent meshes
    // (building, head).
    for fixture in ["walk", "blowfish", "building", "head"] {
        let input = format!("fixtures/{fixture}.usda");
        let one = bake(&input, 1, &dir);
        let two = bake(&input, 2, &dir);
        assert!(one.len() > 1000, "{fixture}: a real bake");
        assert!(one == two, "{fixture}: 1 and 2 threads differ");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
