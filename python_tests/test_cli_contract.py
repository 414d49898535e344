"""The CLI contract pinned exactly: exit codes, --quiet, the progress bar, --help examples.

README (Commands): exit 0 success, 1 bad input or a failed write, 2 bad
command-line usage, 3 an internal error (a bug). Every case below expects
one exact code, never "non-zero".
"""

import json
import os
import pathlib
import re
import shlex
import shutil
import subprocess
import urllib.request

import pytest

from conftest import REPO, painterly_binary, run_on_pty

FIX = REPO / "fixtures"
TUBE = FIX / "tube.usda"
FISH = FIX / "blowfish.usda"
APPLE = FIX / "apple.usda"


def cases(tmp):
    """(id, args, stdin, exit code): every command, every class of outcome."""
    bake = tmp / "tube_bake.usdc"
    missing = tmp / "nope.usda"
    garbage = tmp / "garbage.usda"  # test_exit_code writes it
    edit = ["--edit-layer", tmp / "e.usda"]
    brush = ["--layer", "/Blowfish/Paint/Hair", "--path", "3,6,-2 6,6,-1.5", "--radius", "1", "--strength", "0.1"]
    frames_out = tmp / "f.####.exr"
    return [
        # bake
        ("bake-ok", ["bake", TUBE, "-o", bake, "--frames", "1:3", "-q"], None, 0),
        ("bake-missing-input", ["bake", missing, "-o", tmp / "b.usdc"], None, 1),
        ("bake-unparsable-input", ["bake", garbage, "-o", tmp / "b.usdc"], None, 1),
        ("bake-output-folder-missing", ["bake", TUBE, "-o", tmp / "no" / "b.usdc"], None, 1),
        ("bake-output-bad-extension", ["bake", TUBE, "-o", tmp / "b.txt"], None, 2),  # a name that cannot work: usage
        ("bake-frames-outside-stage", ["bake", TUBE, "-o", tmp / "b.usdc", "--frames", "0:1000"], None, 1),
        ("bake-camera-missing", ["bake", TUBE, "-o", tmp / "b.usdc", "--camera", "/NoCam"], None, 1),
        ("bake-no-output", ["bake", TUBE], None, 2),
        ("bake-unknown-flag", ["bake", TUBE, "-o", tmp / "b.usdc", "--fast"], None, 2),
        ("bake-chunk-index-without-chunk", ["bake", TUBE, "-o", tmp / "b.usda", "--chunk-index", "0"], None, 2),
        ("bake-chunk-zero", ["bake", TUBE, "-o", tmp / "b.usda", "--chunk", "0"], None, 2),
        *[
            (f"bake-frames-{i}", ["bake", TUBE, "-o", tmp / "b.usdc", "--frames", f], None, 2)
            for i, f in enumerate(["abc", "1:", "5:1", "1:10:0", "1:10:-1", "nan", "1:2:3:4", "", "1:24:1e-9", "0:1e300"])
        ],
        # inspect
        ("inspect-clean", ["inspect", TUBE], None, 0),
        ("inspect-missing-input", ["inspect", missing], None, 1),
        ("inspect-unparsable-input", ["inspect", garbage], None, 1),
        ("inspect-no-input", ["inspect"], None, 2),
        # authoring
        ("bind-ok", ["bind", FISH, "--layer", "/Blowfish/Paint/Hair", "--time", "24", *edit, "-q"], None, 0),
        ("bind-layer-missing", ["bind", FISH, "--layer", "/Blowfish/Paint/Nope", "--time", "24", *edit], None, 1),
        ("bind-both-targets", ["bind", FISH, "--time", "24", *edit, "--in-place"], None, 2),
        ("bind-no-target", ["bind", FISH, "--time", "24"], None, 2),
        ("key-ok", ["key", FISH, "--layer", "/Blowfish/Paint/Spikes", "--time", "15", "--points", *edit, "-q"], None, 0),
        ("key-time-outside", ["key", FISH, "--layer", "/Blowfish/Paint/Nope", "--time", "15", *edit], None, 1),
        ("key-no-layer", ["key", FISH, "--time", "15", *edit], None, 2),
        ("key-time-not-number", ["key", FISH, "--layer", "/Blowfish/Paint/Spikes", "--time", "x", *edit], None, 2),
        ("smudge-ok", ["smudge", FISH, *brush, *edit, "-q"], None, 0),
        ("smudge-misses-everything", ["smudge", FISH, *brush[:3], "100,100,100 101,100,100", *brush[4:], *edit], None, 1),
        ("smudge-bad-path-point", ["smudge", FISH, *brush[:3], "1,2 3,4", *brush[4:], *edit], None, 2),
        ("smudge-no-radius", ["smudge", FISH, *brush[:4], *brush[6:], *edit], None, 2),
        ("expand-ok", ["expand", FISH, *brush, *edit, "-q"], None, 0),
        ("expand-bad-strokes", ["expand", FISH, *brush, "--strokes", "x-y", *edit], None, 2),
        ("expand-bad-falloff", ["expand", FISH, *brush, "--falloff", "linear", *edit], None, 2),
        # render
        ("render-ok", ["render", APPLE, "--camera", "/Apple/Camera", "--frames", "1", "-o", frames_out, "--size", "16x16", "-q"], None, 0),
        ("render-camera-missing", ["render", APPLE, "--camera", "/Nope", "--frames", "1", "-o", frames_out], None, 1),
        ("render-output-folder-missing", ["render", APPLE, "--camera", "/Apple/Camera", "--frames", "1", "-o", tmp / "no" / "f.####.exr"], None, 1),
        ("render-bad-frames", ["render", APPLE, "--camera", "/Apple/Camera", "--frames", "1:x", "-o", frames_out], None, 2),
        ("render-bad-size", ["render", APPLE, "--camera", "/Apple/Camera", "--frames", "1", "-o", frames_out, "--size", "0x10"], None, 2),
        ("render-no-camera", ["render", APPLE, "--frames", "1", "-o", frames_out], None, 2),
        # view
        ("view-bake-missing", ["view", TUBE, "--bake", tmp / "none.usdc", "-o", tmp / "v.usda"], None, 1),
        ("view-not-usda", ["view", TUBE, "--bake", tmp / "none.usdc", "-o", tmp / "v.usdc"], None, 2),
        ("view-no-bake", ["view", TUBE, "-o", tmp / "v.usda"], None, 2),
        # interpolate
        ("interpolate-ok", ["interpolate"], '{"method": "shepard", "keys": [[0], [1]], "points": [[0.5]]}', 0),
        ("interpolate-bad-json", ["interpolate"], "{", 1),
        ("interpolate-unknown-method", ["interpolate"], '{"method": "nearest", "keys": [[0]], "points": [[0]]}', 1),
        ("interpolate-unknown-flag", ["interpolate", "--radius", "2"], "{}", 2),
        # farm
        ("farm-submit-openjd", ["farm", "submit", TUBE, "-o", tmp / "shot.usda", "--chunk", "12", "--scheduler", "openjd"], None, 0),
        ("farm-submit-missing-input", ["farm", "submit", missing, "-o", tmp / "s2.usda", "--chunk", "12", "--scheduler", "openjd"], None, 1),
        ("farm-submit-partition-openjd", ["farm", "submit", TUBE, "-o", tmp / "s3.usda", "--chunk", "12", "--scheduler", "openjd", "--partition", "p"], None, 2),
        ("farm-submit-unknown-scheduler", ["farm", "submit", TUBE, "-o", tmp / "s4.usda", "--chunk", "12", "--scheduler", "cue"], None, 2),
        ("farm-status-no-plan", ["farm", "status", tmp / "never.usda"], None, 1),
        ("farm-status-no-output", ["farm", "status"], None, 2),
        # preview: bad input is found before the server starts
        ("preview-missing-input", ["preview", missing, "--port", "0"], None, 1),
        ("preview-bad-port", ["preview", TUBE, "--port", "http"], None, 2),
        # the tool itself
        ("no-command", [], None, 2),
        ("unknown-command", ["paint"], None, 2),
        ("version", ["--version"], None, 0),
        ("help", ["--help"], None, 0),
    ]


CASE_IDS = [c[0] for c in cases(pathlib.Path("/nonexistent"))]


def run(args, stdin=None, env=None, cwd=None, timeout=300):
    return subprocess.run(
        [str(painterly_binary()), *map(str, args)], input=stdin, capture_output=True, text=True,
        env=env, cwd=cwd, timeout=timeout,
    )


@pytest.mark.parametrize("case", CASE_IDS)
def test_exit_code(tmp_path, case):
    (name, args, stdin, code), = [c for c in cases(tmp_path) if c[0] == case]
    (tmp_path / "garbage.usda").write_text("#usda 1.0\n(\n  this is not usda\n")
    proc = run(args, stdin)
    assert proc.returncode == code, f"{name}: exit {proc.returncode}, not {code}\n{proc.stderr}"
    assert "panicked" not in proc.stderr and "error: internal error" not in proc.stderr
    if code == 1:
        assert proc.stderr.startswith("error: "), proc.stderr
    if code == 2 and args:
        assert "error" in proc.stderr or "Usage" in proc.stderr


@pytest.mark.parametrize("args", [["inspect", TUBE], ["bake", TUBE, "-o", "/nonexistent/x.usdc"], ["interpolate"]])
def test_internal_error_exits_3_with_a_bug_report(args):
    env = dict(os.environ, PAINTERLY_TEST_INTERNAL_ERROR="1")
    proc = run(args, "{}", env=env)
    assert proc.returncode == 3
    assert proc.stdout == ""
    assert proc.stderr.startswith("error: internal error at ")
    assert "this is a bug in painterly" in proc.stderr


@pytest.mark.parametrize("value", ["abc", "0", "-1", "inf", ""])
def test_a_compose_timeout_that_is_no_number_of_seconds_is_a_usage_error(tmp_path, value):
    """README "Limits": PAINTERLY_COMPOSE_TIMEOUT=SECONDS. A value that is
    no positive number would silently leave the 30 s default in force."""
    env = dict(os.environ, PAINTERLY_COMPOSE_TIMEOUT=value)
    proc = run(["bake", TUBE, "-o", tmp_path / "b.usdc", "--frames", "1:2"], env=env)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr == f"error: PAINTERLY_COMPOSE_TIMEOUT={value!r} is not a positive number of seconds\n".replace(
        f"={value!r}", '="' + value + '"'), proc.stderr
    assert not (tmp_path / "b.usdc").exists()
    env["PAINTERLY_COMPOSE_TIMEOUT"] = " 2.5 "
    assert run(["bake", TUBE, "-o", tmp_path / "b.usdc", "--frames", "1:2", "-q"], env=env).returncode == 0


def test_frames_too_many_time_codes_is_usage_not_a_crash(tmp_path):
    proc = run(["bake", TUBE, "-o", tmp_path / "b.usdc", "--frames", "1:24:0.000000001"], timeout=60)
    assert proc.returncode == 2
    assert "at most" in proc.stderr and "time codes" in proc.stderr
    assert not (tmp_path / "b.usdc").exists()


def quiet_cases(tmp):
    edit = ["--edit-layer", tmp / "q.usda"]
    brush = ["--layer", "/Blowfish/Paint/Hair", "--path", "3,6,-2 6,6,-1.5", "--radius", "1", "--strength", "0.1"]
    # The render is pointed away from everything: it would warn about empty frames.
    return {
        "bake": ["bake", TUBE, "-o", tmp / "b.usdc", "--frames", "1:4", "-q"],
        "bake-chunks": ["bake", TUBE, "-o", tmp / "shot.usda", "--chunk", "12", "--quiet"],
        "bind": ["bind", FISH, "--layer", "/Blowfish/Paint/Hair", "--time", "24", *edit, "-q"],
        "key": ["key", FISH, "--layer", "/Blowfish/Paint/Spikes", "--time", "15", "--points", *edit, "-q"],
        "smudge": ["smudge", FISH, *brush, *edit, "-q"],
        "expand": ["expand", FISH, *brush, *edit, "--quiet"],
        "render": ["render", APPLE, "--camera", "/Apple/Camera", "--frames", "1:3", "-o", tmp / "r.####.exr", "--size", "16x16", "--sheet", "--png", "-q"],
    }


def test_assembly_says_assembled_and_is_quiet_with_quiet(tmp_path):
    # The tube's 24 frames in 2 chunks of 12; the assembly bakes nothing.
    out = tmp_path / "shot.usda"
    for k in (0, 1):
        assert run(["bake", TUBE, "-o", out, "--chunk", "12", "--chunk-index", k, "-q"]).returncode == 0
    quiet = run(["bake", TUBE, "-o", out, "--chunk", "12", "--assemble", "--quiet"])
    assert (quiet.returncode, quiet.stdout, quiet.stderr) == (0, "", "")
    loud = run(["bake", TUBE, "-o", out, "--chunk", "12", "--assemble"])
    assert loud.returncode == 0 and loud.stderr == ""
    assert re.fullmatch(
        rf"assembled 2 chunk layers: 2 layers, 50 strokes, 450 points, 0 view-dependent meshes -> {re.escape(str(out))} in \d+\.\d\d s\n",
        loud.stdout,
    ), loud.stdout


@pytest.mark.parametrize("name", list(quiet_cases(pathlib.Path("/x"))))
def test_quiet_is_silent_on_both_streams(tmp_path, name):
    args = quiet_cases(tmp_path)[name]
    proc = run(args)
    assert (proc.returncode, proc.stdout, proc.stderr) == (0, "", "")
    again = tmp_path / "loud"
    again.mkdir()
    loud = run([a for a in quiet_cases(again)[name] if a not in ("-q", "--quiet")])
    assert loud.returncode == 0 and loud.stdout.strip(), "without --quiet the command reports"


def test_quiet_render_hides_warnings_it_would_print(tmp_path):
    bake = tmp_path / "b.usdc"
    run(["bake", APPLE, "-o", bake, "--frames", "1:4", "-q"])
    # Frames outside the bake warn (test_render pins the warning itself).
    args = ["render", APPLE, "--bake", bake, "--camera", "/Apple/Camera", "--frames", "1:8:7", "-o", tmp_path / "w.####.exr", "--size", "16x16"]
    loud = run(args)
    assert loud.returncode == 0 and "warning:" in loud.stderr
    quiet = run([*args, "-q"])
    assert (quiet.returncode, quiet.stdout, quiet.stderr) == (0, "", "")


@pytest.mark.parametrize("command", ["bake", "render", "inspect"])
def test_progress_bar_on_a_terminal_only(tmp_path, command):
    if command == "bake":
        args = ["bake", FISH, "-o", tmp_path / "b.usdc", "--frames", "1:48"]
        word = "baking frame"
    elif command == "inspect":
        # inspect evaluates every frame of the stage's range (blowfish: 1..48).
        args = ["inspect", FISH]
        word = "checking frame"
    else:
        args = ["render", APPLE, "--camera", "/Apple/Camera", "--frames", "1:48", "-o", tmp_path / "r.####.exr", "--size", "64x40"]
        word = "rendering"
    code, seen = run_on_pty(args)
    assert code == 0
    assert word in seen, seen[:500]
    assert re.search(r"\d+/48", seen), seen[:500]
    # Off a terminal: no bar, nothing on stderr.
    proc = run(args)
    assert proc.returncode == 0
    assert word not in proc.stderr and proc.stderr == ""
    if command == "inspect":
        # inspect has no --quiet; --json on a terminal prints the report alone.
        code, seen = run_on_pty([*args, "--json"])
        assert code == 0 and word not in seen
        assert json.loads(seen)["problems"] == []
        return
    # --quiet on a terminal: nothing at all.
    code, seen = run_on_pty([*args, "-q"])
    assert (code, seen) == (0, "")


# --help examples ---------------------------------------------------------

HELP_COMMANDS = [[], ["bake"], ["inspect"], ["bind"], ["key"], ["smudge"], ["expand"], ["render"], ["preview"],
                 ["view"], ["farm"], ["farm", "submit"], ["farm", "status"], ["interpolate"]]


def help_examples():
    """Every `Example:` line of every --help, in command order."""
    found = []
    for cmd in HELP_COMMANDS:
        text = run([*cmd, "--help"]).stdout
        found += [(" ".join(cmd) or "painterly", m) for m in re.findall(r"^Example: (.+)$", text, re.M)]
    return found


def test_every_subcommand_has_an_example():
    have = {c for c, _ in help_examples()}
    assert have == {" ".join(c) for c in HELP_COMMANDS if c}


def slurm_env():
    conf = os.environ.get("PAINTERLY_SLURM_CONF")
    return dict(os.environ, SLURM_CONF=conf) if conf and shutil.which("sbatch") else None


def test_every_help_example_runs(tmp_path):
    """Run from a scratch folder with fixtures/ beside it; /tmp/ paths go to the scratch folder."""
    (tmp_path / "fixtures").symlink_to(FIX)
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    ran = []
    for cmd, example in help_examples():
        line = example.replace("/tmp/", f"{scratch}/")
        if cmd == "preview":
            words = shlex.split(line)
            proc = subprocess.Popen([str(painterly_binary()), *words[1:]], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            try:
                line_out = proc.stdout.readline()
                url = re.search(r"http://127\.0\.0\.1:\d+/", line_out)
                assert url, line_out
                with urllib.request.urlopen(url.group(0), timeout=60) as r:
                    assert r.status == 200 and b"<html" in r.read(4096).lower()
            finally:
                proc.terminate()
                proc.wait(timeout=30)
            ran.append(cmd)
            continue
        env = None
        if "--scheduler slurm" in line:
            env = slurm_env()
            if env is None:
                continue  # test_farm.py runs the Slurm path on a local cluster
        # `echo ... | painterly ...`: the shell runs it, with our binary first on PATH.
        path_dir = tmp_path / "bin"
        path_dir.mkdir(exist_ok=True)
        if not (path_dir / "painterly").exists():
            (path_dir / "painterly").symlink_to(painterly_binary())
        env = dict(env or os.environ)
        env["PATH"] = f"{path_dir}{os.pathsep}{env['PATH']}"
        proc = subprocess.run(line, shell=True, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
        if "--scheduler slurm" in line and proc.returncode == 0:
            # Leave nothing queued on the test cluster once this test's folder is gone.
            words = shlex.split(line)
            out = pathlib.Path(words[words.index("-o") + 1])
            plan = json.loads((out.parent / f"{out.stem}.clips" / "farm" / "plan.json").read_text())
            jobs = [j for j in (plan["job"], plan["assemble_job"]) if j]
            subprocess.run(["scancel", *jobs], env=env, check=False)
        expected = 0
        if cmd == "farm status":
            # Exit 0 only once every chunk is done and assembled (README): right after a submit, 1.
            expected = 0 if json.loads(proc.stdout)["complete"] else 1
        assert proc.returncode == expected, f"{example}\n{proc.stdout}\n{proc.stderr}"
        ran.append(cmd)
    assert {"bake", "inspect", "bind", "key", "smudge", "expand", "render", "preview", "view", "farm", "farm status",
            "interpolate"} <= set(ran)
    # What the examples promise to have written.
    assert (scratch / "blowfish_bake.usdc").exists() and (scratch / "fish_view.usda").exists()
    assert len(list(scratch.glob("apple.*.exr"))) == 12 and (scratch / "apple.sheet.png").exists()
    assert all((tmp_path / f).exists() for f in ["fish_edits.usda", "edits.usda", "brush.usda"])
    assert (scratch / "shot.clips" / "farm" / "openjd" / "template.json").exists()
