//! The Python contract tests, run from `cargo test` against this build's
//! binary, so that cargo-mutants (scripts/mutants) sees what only they check
//! (renders, `--json` fields, exit codes). Ignored in ordinary runs, where
//! scripts/test runs the whole pytest suite itself; scripts/mutants runs it
//! with `--include-ignored` and the files in `PAINTERLY_MUTANTS_PYTEST`.

use std::path::Path;
use std::process::Command;

#[test]
#[ignore = "mutation testing only: scripts/mutants runs it"]
fn python_contract_tests_pass_against_this_build() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files = std::env::var("PAINTERLY_MUTANTS_PYTEST")
        .expect("PAINTERLY_MUTANTS_PYTEST: the pytest files to run (scripts/mutants sets it)");
    let python = std::env::var("PAINTERLY_MUTANTS_PYTHON")
        .unwrap_or_else(|_| root.join(".venv/bin/python").display().to_string());
    let status = Command::new(&python)
        .args(["-m", "pytest", "-q", "-x", "-p", "no:cacheprovider"])
        .args(files.split_whitespace())
        .current_dir(root)
        .env("PAINTERLY_BIN", env!("CARGO_BIN_EXE_painterly"))
        .status()
        .unwrap_or_else(|e| panic!("cannot run {python}: {e}"));
    assert!(
        status.success(),
        "pytest {files} failed against {}",
        env!("CARGO_BIN_EXE_painterly")
    );
}
