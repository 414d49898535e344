"""The ledger of the full mutation run (scripts/mutants_ledger.py, issue 16):
a finished unit is recorded with its counts and misses, stands while its
file's mutable code (the text without its trailing test module) is
unchanged since its commit, a recheck's catches close misses, written
reasons close the rest, and it is all reported per file."""

import json
import os
import subprocess
import sys
from pathlib import Path

LEDGER_PY = Path(__file__).resolve().parent.parent / "scripts" / "mutants_ledger.py"


def git(repo, *args):
    return subprocess.run(["git", *args], cwd=repo, check=True, capture_output=True, text=True).stdout.strip()


def ledger(repo, *args):
    return subprocess.run(
        [sys.executable, str(LEDGER_PY), *args], cwd=repo, check=True, capture_output=True, text=True
    ).stdout


def unit(repo, name, file, k, n, caught, unviable, missed, timeout):
    d = repo / "out" / name
    (d / "mutants.out").mkdir(parents=True)
    (d / "unit").write_text(f"{file} {k} {n}\n")
    (d / "commit").write_text(git(repo, "rev-parse", "HEAD") + "\n")
    (d / "pytest").write_text("python_tests/test_a.py python_tests/test_b.py\n")
    outcomes = {"caught": caught, "unviable": unviable, "missed": len(missed), "timeout": len(timeout)}
    (d / "mutants.out" / "outcomes.json").write_text(json.dumps(outcomes))
    (d / "mutants.out" / "missed.txt").write_text("".join(m + "\n" for m in missed))
    (d / "mutants.out" / "timeout.txt").write_text("".join(m + "\n" for m in timeout))
    return d


def new_repo(repo):
    """An empty git repository with src/ and docs/ folders."""
    git(repo, "init", "-q")
    git(repo, "config", "user.email", "t@example.com")
    git(repo, "config", "user.name", "t")
    (repo / "src").mkdir()
    (repo / "docs").mkdir()
    return repo


def test_a_unit_stands_until_its_file_changes(tmp_path):
    repo = new_repo(tmp_path)
    (repo / "src" / "a.rs").write_text("fn a() {}\n")
    (repo / "src" / "b.rs").write_text("fn b() {}\n")
    git(repo, "add", "src")
    git(repo, "commit", "-qm", "one")
    head = git(repo, "rev-parse", "HEAD")

    missed = ["src/a.rs:1:1: replace a with ()", "src/a.rs:2:3: replace + with -"]
    first = unit(repo, "a1", "src/a.rs", 0, 2, 3, 0, [], [])
    ledger(repo, "record", str(first))
    again = unit(repo, "a1-again", "src/a.rs", 0, 2, 5, 1, missed, ["src/a.rs:4:1: delete !"])
    ledger(repo, "record", str(again))

    lines = (repo / "docs" / "mutants_ledger.jsonl").read_text().splitlines()
    assert len(lines) == 2
    entry = json.loads(lines[1])
    assert entry["file"] == "src/a.rs" and entry["k"] == 0 and entry["n"] == 2
    assert entry["commit"] == head
    assert entry["caught"] == 5 and entry["unviable"] == 1
    assert entry["missed"] == missed and entry["timeout"] == ["src/a.rs:4:1: delete !"]
    assert entry["pytest"] == ["python_tests/test_a.py", "python_tests/test_b.py"]

    # The last line of a unit wins; only the recorded unit stands.
    assert ledger(repo, "standing") == f"src/a.rs 0 2 {head[:12]}\n"

    plan = repo / "plan"
    plan.write_text("src/a.rs 0 2 17\nsrc/a.rs 1 2 17\nsrc/b.rs 0 1 4\n")
    report = ledger(repo, "report", str(plan)).splitlines()
    assert "| `src/a.rs` | 17 | 1/2 | 5 | 2 | 1 | 1 | 0 | 0 |" in report
    assert "| `src/b.rs` | 4 | 0/1 | 0 | 0 | 0 | 0 | 0 | 0 |" in report
    assert "| **all** | 21 | 1/3 | 5 | 2 | 1 | 1 | 0 | 0 |" in report
    assert f"9 of 21 mutants tested; commits: {head[:12]}." in report
    assert "  " + missed[0] in report and "  " + missed[1] in report
    assert "  src/a.rs:4:1: delete !" in report

    # Another file's change leaves it standing; its own file's change does not.
    (repo / "src" / "b.rs").write_text("fn b() { 1; }\n")
    assert ledger(repo, "standing") == f"src/a.rs 0 2 {head[:12]}\n"
    (repo / "src" / "a.rs").write_text("fn a() { 2; }\n")
    assert ledger(repo, "standing") == ""
    report = ledger(repo, "report", str(plan)).splitlines()
    assert "| **all** | 21 | 0/3 | 0 | 0 | 0 | 0 | 0 | 0 |" in report
    assert f"  src/a.rs 1/2 at {head[:12]}: 9 tested, 5 caught, 2 missed, 1 timeouts, 1 unviable" in report


def test_tests_added_to_a_file_keep_its_units_and_rechecks_and_reasons_close_misses(tmp_path):
    repo = new_repo(tmp_path)
    code = "pub fn a(x: i32) -> i32 {\n    x + 1\n}\n"
    tests = "\n#[cfg(test)]\nmod tests {\n    #[test]\n    fn one() {\n        assert_eq!(super::a(1), 2);\n    }\n}\n"
    (repo / "src" / "a.rs").write_text(code + tests)
    git(repo, "add", "src")
    git(repo, "commit", "-qm", "one")
    head = git(repo, "rev-parse", "HEAD")
    missed = ["src/a.rs:2:7: replace + with -", "src/a.rs:2:7: replace + with *", "src/a.rs:1:1: replace a -> i32 with 0"]
    ledger(repo, "record", str(unit(repo, "a", "src/a.rs", 0, 1, 4, 0, missed, [])))

    # A test added inside the trailing test module: the unit stands.
    more = tests.replace("    }\n}\n", "    }\n    #[test]\n    fn two() {}\n}\n")
    (repo / "src" / "a.rs").write_text(code + more)
    assert ledger(repo, "standing") == f"src/a.rs 0 1 {head[:12]}\n"
    assert ledger(repo, "missed", "src/a.rs").splitlines() == missed

    # A recheck at a later commit caught two of the three.
    git(repo, "commit", "-qam", "tests")
    d = unit(repo, "re", "src/a.rs", 0, 1, 0, 0, [missed[1]], [])
    (d / "mutants.out" / "caught.txt").write_text(missed[0] + "\n" + missed[2] + "\n")
    ledger(repo, "recheck", str(d))
    assert ledger(repo, "missed", "src/a.rs").splitlines() == [missed[1]]
    # Rechecks are not units: standing lists the unit alone.
    assert ledger(repo, "standing") == f"src/a.rs 0 1 {head[:12]}\n"

    plan = repo / "plan"
    plan.write_text("src/a.rs 0 1 7\n")
    report = ledger(repo, "report", str(plan)).splitlines()
    assert "| `src/a.rs` | 7 | 1/1 | 4 | 3 | 0 | 0 | 2 | 0 |" in report
    at = report.index("Missed or timed out, with neither a test that kills it nor a reason:")
    assert report[at + 1 :] == ["  " + missed[1]]

    # A written reason closes the last; a reason for no miss is listed as stale.
    (repo / "docs" / "mutants_reasons.txt").write_text(
        "# comment\n" + missed[1] + "\n    equivalent: x * 1 = x + 1 nowhere,\n    but say why.\n"
        "src/a.rs:9:9: replace gone with ()\n    old.\n"
    )
    report = ledger(repo, "report", str(plan)).splitlines()
    assert "| `src/a.rs` | 7 | 1/1 | 4 | 3 | 0 | 0 | 2 | 1 |" in report
    assert "Missed or timed out, with neither a test that kills it nor a reason:" not in report
    at = report.index("Reasons in docs/mutants_reasons.txt for no standing miss (stale):")
    assert report[at + 1 :] == ["  src/a.rs:9:9: replace gone with ()"]
    # A recheck would run none of them again.
    assert ledger(repo, "missed", "src/a.rs") == ""

    # A reason with no text is refused.
    (repo / "docs" / "mutants_reasons.txt").write_text(missed[1] + "\n")
    bad = subprocess.run([sys.executable, str(LEDGER_PY), "report", str(plan)], cwd=repo, capture_output=True, text=True)
    assert bad.returncode == 1 and f"no reason under {missed[1]}" in bad.stderr
    (repo / "docs" / "mutants_reasons.txt").unlink()

    # A change to the code itself (not its tests): the unit and the recheck are stale.
    (repo / "src" / "a.rs").write_text(code.replace("x + 1", "x + 2") + more)
    assert ledger(repo, "standing") == ""
    assert ledger(repo, "missed", "src/a.rs") == ""


def load_ledger_module():
    import importlib.util

    spec = importlib.util.spec_from_file_location("mutants_ledger", LEDGER_PY)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_trailing_test_module_is_found_past_strings_and_comments():
    code = "fn a() -> u32 {\n    1\n}\n"
    tricky = (
        "\n#[cfg(test)]\nmod tests {\n    const T: &str = r#\"\ndef X {\n}\n\"#;\n"
        "    // a } in a comment\n    /* and { here /* nested } */ */\n"
        "    fn f<'a>(x: &'a str) -> char { let _ = \"}\\\"\"; '}' }\n}\n"
    )
    ledger_mod = load_ledger_module()
    assert ledger_mod.mutable_code(code + tricky) == code
    # An item after the module is code: the text is kept whole.
    after = code + tricky + "\nfn b() {}\n"
    assert ledger_mod.mutable_code(after) == after
    # A module that is not a test module, or an unclosed one, is kept too.
    plain = code + "\nmod inner {\n}\n"
    assert ledger_mod.mutable_code(plain) == plain
    unclosed = code + "\n#[cfg(test)]\nmod tests {\n    fn f() {}\n"
    assert ledger_mod.mutable_code(unclosed) == unclosed


def test_every_pytest_file_the_map_names_exists():
    root = LEDGER_PY.parent.parent
    rules = [
        line.split()
        for line in (root / "scripts" / "mutants_pytest_map").read_text().splitlines()
        if line.strip() and not line.startswith("#")
    ]
    assert rules[-1][0] == "*", "the last rule catches every other source file"
    for glob, *files in rules:
        assert files, f"rule {glob} names no pytest file"
        for f in files:
            assert (root / "python_tests" / f).is_file(), f"rule {glob}: no python_tests/{f}"


MUTANTS_CHANGE = Path(__file__).resolve().parent.parent / "scripts" / "mutants_change"


def change_repo(tmp_path):
    """A git repository holding scripts/mutants_change (and the line of
    scripts/mutants it reads), with one commit of library source."""
    repo = tmp_path / "repo"
    (repo / "scripts").mkdir(parents=True)
    (repo / "src").mkdir()
    (repo / "docs").mkdir()
    (repo / "scripts" / "mutants_change").write_text(MUTANTS_CHANGE.read_text())
    (repo / "scripts" / "mutants_change").chmod(0o755)
    (repo / "scripts" / "mutants").write_text("MUTANTS_VERSION=27.1.0\n")
    (repo / "src" / "lib.rs").write_text("pub fn one() -> i32 {\n    1\n}\n")
    git(repo, "init", "-q")
    git(repo, "add", "-A")
    git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "first")
    return repo


def run_change(repo, **env):
    return subprocess.run([str(repo / "scripts" / "mutants_change")], cwd=repo, capture_output=True, text=True,
                          env={**os.environ, **env})


def test_mutants_of_a_change_without_library_source_cost_nothing(tmp_path):
    repo = change_repo(tmp_path)
    # The first commit has no parent: nothing to compare, not an error.
    r = run_change(repo)
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("mutants of the last commit: it has no parent here"), r.stdout
    (repo / "docs" / "notes.md").write_text("words\n")
    git(repo, "add", "-A")
    git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "docs")
    # cargo-mutants is never asked: a PATH without cargo still passes.
    r = run_change(repo, PATH="/usr/bin:/bin")
    assert r.returncode == 0, r.stderr
    head = git(repo, "rev-parse", "--short", "HEAD")
    base = git(repo, "rev-parse", "--short", "HEAD~1")
    assert r.stdout == f"mutants of {base}..{head}: the change touches no library source\n"


def test_mutants_of_a_change_refuse_a_bad_base_or_budget(tmp_path):
    repo = change_repo(tmp_path)
    r = run_change(repo, PAINTERLY_MUTANTS_CHANGE_BASE="no-such-commit")
    assert (r.returncode, r.stdout) == (2, "")
    assert r.stderr == "error: PAINTERLY_MUTANTS_CHANGE_BASE=no-such-commit is not a commit\n"
    r = run_change(repo, PAINTERLY_MUTANTS_CHANGE_BASE="HEAD", PAINTERLY_MUTANTS_CHANGE_MAX="0")
    assert (r.returncode, r.stdout) == (2, "")
    assert r.stderr == "error: PAINTERLY_MUTANTS_CHANGE_MAX must be a positive number, not '0'\n"
