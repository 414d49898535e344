"""Farm bakes (issue 10 §3-5): `painterly farm submit` / `farm status`.

The Slurm tests run on a real single-host cluster: the one `scripts/test`
starts (it exports PAINTERLY_SLURM_CONF), or else one this module starts
with `scripts/slurm_local` when Slurm is installed (and stops at the end).
They skip when Slurm is not installed, unless PAINTERLY_REQUIRE_SLURM=1
(set by scripts/test), where they fail instead. A user's own cluster
(plain SLURM_CONF) is never used.

The Open Job Description tests run the written template with `openjd run`
(openjd-cli, pinned in requirements.txt).
"""

import json
import os
import pathlib
import shutil
import subprocess
import sys
import tempfile
import time

import pytest
from clip_compare import compare
from conftest import REPO, painterly_binary
from pxr import Sdf

BLOWFISH = REPO / "fixtures" / "blowfish.usda"
SUBMIT_FIELDS = {
    "scheduler", "input", "output", "plan", "chunk_size", "chunks", "submitted", "skipped",
    "job", "tasks", "assemble_job", "files", "next",
}
STATUS_FIELDS = {
    "output", "plan", "input", "scheduler", "submitted_at", "scheduler_queried", "input_changed",
    "chunk_size", "job", "chunks", "counts", "assembly", "assembled", "complete",
}
CHUNK_FIELDS = {"index", "name", "path", "frames", "state", "task", "scheduler_state", "detail"}
PLAN_FIELDS = {
    "format", "scheduler", "input", "output", "input_hash", "painterly", "version", "frames",
    "frame_range", "frame_count", "chunk_size", "camera", "bake_proxy", "submitted_at", "job",
    "assemble_job", "assemble_command", "submit_commands", "files", "chunks",
}
PLAN_CHUNK_FIELDS = {"index", "name", "frames", "state_at_submit", "submitted", "task", "command"}


# --------------------------------------------------------------------------
# the cluster
# --------------------------------------------------------------------------

def sbin_path():
    return os.environ.get("PATH", "") + ":/usr/sbin:/sbin"


def cluster_idle(env):
    try:
        out = subprocess.run(["sinfo", "-h", "-N", "-o", "%T"], env=env, capture_output=True, text=True, timeout=20)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return out.returncode == 0 and "idle" in out.stdout


@pytest.fixture(scope="module")
def slurm():
    """Environment for painterly and Slurm's commands on a running test cluster."""
    required = os.environ.get("PAINTERLY_REQUIRE_SLURM") == "1"

    def unavailable(msg):
        if required:
            pytest.fail(msg + " (PAINTERLY_REQUIRE_SLURM=1)")
        pytest.skip(msg)

    env = dict(os.environ)
    conf = os.environ.get("PAINTERLY_SLURM_CONF")
    if conf:
        env["SLURM_CONF"] = conf
        if not cluster_idle(env):
            unavailable(f"PAINTERLY_SLURM_CONF={conf}: no idle node answers")
        yield env
        return
    if not (shutil.which("slurmctld", path=sbin_path()) and shutil.which("sbatch")):
        unavailable("Slurm is not installed (scripts/slurm_local install, as root; scripts/test does it)")
    tmp = tempfile.mkdtemp(prefix="painterly-slurm-")
    helper = REPO / "scripts" / "slurm_local"
    proc = subprocess.run([str(helper), "start", tmp], capture_output=True, text=True, timeout=180)
    if proc.returncode != 0:
        shutil.rmtree(tmp, ignore_errors=True)
        unavailable(f"could not start a local Slurm cluster: {proc.stderr.strip()[-2000:]}")
    env["SLURM_CONF"] = f"{tmp}/slurm.conf"
    try:
        yield env
    finally:
        subprocess.run([str(helper), "stop", tmp], capture_output=True, text=True, timeout=120)
        shutil.rmtree(tmp, ignore_errors=True)


def slurm_cmd(env, *args, check=True):
    proc = subprocess.run([str(a) for a in args], env=env, capture_output=True, text=True, timeout=60)
    if check and proc.returncode != 0:
        raise AssertionError(f"{' '.join(map(str, args))} exited {proc.returncode}: {proc.stderr}")
    return proc


def live_tasks(env, jobs):
    """Task ids of `jobs` that wait or run (squeue's default states)."""
    proc = slurm_cmd(env, "squeue", "-h", "-r", f"--jobs={','.join(jobs)}", "-o", "%i|%T", check=False)
    if proc.returncode != 0:
        assert "Invalid job id" in proc.stderr, proc.stderr
        return {}
    return dict(line.split("|") for line in proc.stdout.split())


def wait_until_done(env, jobs, timeout=300):
    deadline = time.monotonic() + timeout
    while live_tasks(env, jobs):
        assert time.monotonic() < deadline, f"jobs {jobs} still running after {timeout} s: {live_tasks(env, jobs)}"
        time.sleep(0.2)


def stat_key(path):
    st = pathlib.Path(path).stat()
    return st.st_ino, st.st_mtime_ns, st.st_size


# --------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------

def submit(painterly, env, src, shot, *args, check=True):
    proc = painterly("farm", "submit", src, "-o", shot, *args, "--json", env=env, check=check)
    return (json.loads(proc.stdout) if proc.returncode == 0 else None), proc


def status(painterly, env, shot):
    proc = painterly("farm", "status", shot, "--json", env=env, check=False)
    assert proc.returncode in (0, 1), proc.stderr
    st = json.loads(proc.stdout)
    assert set(st) == STATUS_FIELDS
    assert all(set(c) == CHUNK_FIELDS for c in st["chunks"])
    assert st["complete"] == (proc.returncode == 0)
    return st


def states(st):
    return [c["state"] for c in st["chunks"]]


def chunk_names(shot):
    """Chunk layers in the clips folder (not the binding cache beside them)."""
    clips = shot.parent / f"{shot.stem}.clips"
    return sorted(p.name for p in clips.glob("*.usdc") if p.name != f"{shot.stem}.binding.usdc")


def openjd_exe():
    exe = pathlib.Path(sys.executable).parent / "openjd"
    if not exe.exists():
        pytest.fail(f"openjd-cli is not installed in {sys.prefix} (pip install -r python_tests/requirements.txt)")
    return exe


# --------------------------------------------------------------------------
# Slurm
# --------------------------------------------------------------------------

def test_slurm_bake_of_four_chunks_composes_to_the_single_file_bake(slurm, painterly, tmp_path):
    shot, single = tmp_path / "out" / "shot.usda", tmp_path / "single.usdc"
    shot.parent.mkdir()
    sub, _ = submit(painterly, slurm, BLOWFISH, shot, "--chunk", "12", "--scheduler", "slurm")
    assert set(sub) == SUBMIT_FIELDS
    job, asm = sub["job"], sub["assemble_job"]
    assert job.isdigit() and asm.isdigit() and job != asm
    clips = shot.parent / "shot.clips"
    assert sub == {
        "scheduler": "slurm", "input": str(BLOWFISH), "output": str(shot),
        "plan": str(clips / "farm" / "plan.json"), "chunk_size": 12, "chunks": 4,
        "submitted": [0, 1, 2, 3], "skipped": [], "job": job,
        "tasks": [{"chunk": k, "task": f"{job}_{k}"} for k in range(4)], "assemble_job": asm,
        "files": [str(clips / "farm" / "bake.sh"), str(clips / "farm" / "assemble.sh")], "next": None,
    }
    # The plan says exactly what every task runs, with this binary.
    plan = json.loads((clips / "farm" / "plan.json").read_text())
    assert set(plan) == PLAN_FIELDS and all(set(c) == PLAN_CHUNK_FIELDS for c in plan["chunks"])
    exe = str(painterly_binary().resolve())
    base = [exe, "bake", str(BLOWFISH), "-o", str(shot), "--chunk", "12"]
    assert [c["command"] for c in plan["chunks"]] == [base + ["--chunk-index", str(k)] for k in range(4)]
    assert plan["assemble_command"] == base + ["--assemble"]
    assert (plan["painterly"], plan["frames"], plan["frame_range"], plan["frame_count"]) == (exe, None, "1:48:1", 48)
    assert [c["frames"] for c in plan["chunks"]] == ["1:12:1", "13:24:1", "25:36:1", "37:48:1"]
    assert [c["task"] for c in plan["chunks"]] == [f"{job}_{k}" for k in range(4)]
    assert plan["submit_commands"][0][0] == "sbatch" and "--array=0-3" in plan["submit_commands"][0]
    assert f"--dependency=afterok:{job}" in plan["submit_commands"][1]
    assert plan["submitted_at"].endswith("Z") and len(plan["submitted_at"]) == 20

    wait_until_done(slurm, [job, asm])
    st = status(painterly, slurm, shot)
    assert st["complete"] and st["assembled"] and st["scheduler_queried"]
    assert states(st) == ["done"] * 4
    assert st["counts"] == {"done": 4, "running": 0, "pending": 0, "failed": 0, "missing": 0, "stale": 0}
    assert st["assembly"]["state"] == "done" and st["assembly"]["job"] == asm
    logs = sorted(p.name for p in (clips / "farm" / "logs").iterdir())
    assert logs == [f"assemble.{asm}.log"] + [f"bake.{job}_{k}.log" for k in range(4)]

    painterly("bake", BLOWFISH, "-o", single, "--quiet")
    compare(single, shot, BLOWFISH, list(range(1, 49)), exact=True)
    compare(single, shot, BLOWFISH, [f + 0.5 for f in range(1, 48)], exact=False)
    assert "4 done, 0 missing, 0 stale" in painterly("inspect", shot).stdout

    # Without Slurm's commands on PATH, status answers from the files.
    bare = dict(slurm, PATH=str(tmp_path))
    st = status(painterly, bare, shot)
    assert (st["complete"], st["scheduler_queried"]) == (True, False)
    (clips / "shot.0002.25-36.usdc").unlink()
    st = status(painterly, bare, shot)
    assert states(st) == ["done", "done", "missing", "done"]
    assert (st["complete"], st["assembled"], st["assembly"]["state"]) == (False, False, "missing")
    # With Slurm, the chunk's task is known to have ended: failed.
    st = status(painterly, slurm, shot)
    assert states(st) == ["done", "done", "failed", "done"]
    assert st["chunks"][2]["scheduler_state"] == "COMPLETED"
    assert st["chunks"][2]["detail"] == f"task {job}_2 ended COMPLETED and the chunk is missing"


def gate_first_chunk(tmp_path):
    """A bash start-up file that holds array task 1 of a job while it runs.

    Tasks are bash scripts and sbatch exports the submitting environment, so
    `BASH_ENV` runs this before the task's first line: task 1 says it started,
    then waits (up to 10 minutes) for a file nobody writes. Cancelling it
    therefore always meets a running task, however fast the bake is.
    """
    started = tmp_path / "task1.started"
    hook = tmp_path / "hold_task1.sh"
    hook.write_text(
        'if [ "${SLURM_ARRAY_TASK_ID:-}" = 1 ]; then\n'
        f'  touch {started}\n'
        '  for _ in $(seq 6000); do sleep 0.1; done\n'
        "fi\n"
    )
    return hook, started


def test_a_cancelled_task_is_redone_alone_on_resubmit(slurm, painterly, tmp_path):
    shot = tmp_path / "shot.usda"
    args = ("--chunk", "12", "--scheduler", "slurm")
    hook, started = gate_first_chunk(tmp_path)
    gated = dict(slurm, BASH_ENV=str(hook))
    # Held: every task waits, deterministically.
    sub, _ = submit(painterly, gated, BLOWFISH, shot, *args, "--sbatch-arg", "--hold")
    job, asm = sub["job"], sub["assemble_job"]
    st = status(painterly, slurm, shot)
    assert states(st) == ["pending"] * 4
    assert [c["detail"] for c in st["chunks"]] == ["JobHeldUser"] * 4
    assert st["assembly"]["state"] == "pending"
    # Re-submitting while tasks wait is refused: they would bake the same chunks.
    _, proc = submit(painterly, slurm, BLOWFISH, shot, *args, check=False)
    assert proc.returncode == 1
    assert "tasks of the previous submission still wait or run" in proc.stderr and f"scancel {job}" in proc.stderr
    assert json.loads((shot.parent / "shot.clips" / "farm" / "plan.json").read_text())["job"] == job

    slurm_cmd(slurm, "scontrol", "release", job)
    slurm_cmd(slurm, "scontrol", "release", asm)
    victim = f"{job}_1"
    deadline = time.monotonic() + 120
    while not started.exists():
        assert time.monotonic() < deadline, "chunk 1's task never ran"
        time.sleep(0.05)
    assert live_tasks(slurm, [job]).get(victim) == "RUNNING"
    st = status(painterly, slurm, shot)
    assert st["chunks"][1]["state"] == "running" and st["chunks"][1]["task"] == victim
    slurm_cmd(slurm, "scancel", victim)
    wait_until_done(slurm, [job, asm])

    st = status(painterly, slurm, shot)
    names = [c["name"] for c in st["chunks"]]
    assert not (shot.parent / "shot.clips" / names[1]).exists()
    assert states(st) == ["done", "failed", "done", "done"]
    assert st["chunks"][1]["scheduler_state"] == "CANCELLED"
    assert st["assembly"]["state"] == "failed" and st["assembly"]["scheduler_state"] == "CANCELLED"
    assert (st["complete"], st["assembled"]) == (False, False)
    assert not shot.exists()
    # Nothing half-written under a chunk's final name: only finished chunks are there.
    assert chunk_names(shot) == sorted([names[0], names[2], names[3]])
    before = {n: stat_key(shot.parent / "shot.clips" / n) for n in (names[0], names[2], names[3])}

    sub2, _ = submit(painterly, slurm, BLOWFISH, shot, *args)
    assert (sub2["submitted"], sub2["skipped"]) == ([1], [0, 2, 3])
    assert sub2["tasks"] == [{"chunk": 1, "task": f"{sub2['job']}_0"}]
    st = status(painterly, slurm, shot)
    assert states(st)[0::2] == ["done", "done"] and states(st)[3] == "done"
    assert st["chunks"][1]["state"] in ("pending", "running")
    wait_until_done(slurm, [sub2["job"], sub2["assemble_job"]])
    st = status(painterly, slurm, shot)
    assert st["complete"] and states(st) == ["done"] * 4
    assert {n: stat_key(shot.parent / "shot.clips" / n) for n in before} == before
    # The re-baked chunk is the one a local task writes, byte for byte.
    local = tmp_path / "local" / "shot.usda"
    local.parent.mkdir()
    painterly("bake", BLOWFISH, "-o", local, "--chunk", "12", "--chunk-index", "1", "--quiet")
    assert (local.parent / "shot.clips" / names[1]).read_bytes() == (shot.parent / "shot.clips" / names[1]).read_bytes()
    layer = Sdf.Layer.FindOrOpen(str(shot))
    assert (layer.startTimeCode, layer.endTimeCode) == (1, 48)


def test_sbatch_rejections_are_reported_and_nothing_is_planned(slurm, painterly, tmp_path):
    shot = tmp_path / "shot.usda"
    _, proc = submit(painterly, slurm, BLOWFISH, shot, "--chunk", "12", "--scheduler", "slurm",
                     "--partition", "nosuch", check=False)
    assert proc.returncode == 1
    assert "sbatch refused the chunk tasks" in proc.stderr and "invalid partition specified: nosuch" in proc.stderr
    assert "--partition=nosuch" in proc.stderr
    assert not (tmp_path / "shot.clips" / "farm" / "plan.json").exists()
    proc = painterly("farm", "status", shot, env=slurm, check=False)
    assert proc.returncode == 1 and "no farm plan at" in proc.stderr
    _, proc = submit(painterly, slurm, BLOWFISH, shot, "--chunk", "12", "--scheduler", "slurm",
                     "--sbatch-arg=--no-such-option", check=False)
    assert proc.returncode == 1 and "unrecognized option '--no-such-option'" in proc.stderr


# --------------------------------------------------------------------------
# errors without a cluster
# --------------------------------------------------------------------------

def test_submit_without_sbatch_on_path(painterly, tmp_path):
    env = dict(os.environ, PATH=str(tmp_path))
    proc = painterly("farm", "submit", BLOWFISH, "-o", tmp_path / "shot.usda", "--chunk", "12",
                     "--scheduler", "slurm", env=env, check=False)
    assert proc.returncode == 1
    assert "sbatch not found on PATH" in proc.stderr
    assert not (tmp_path / "shot.clips").exists()


def stand_ins(bin_dir, scripts):
    """Writes each `name: body` as an executable /bin/sh script in `bin_dir`
    and returns an environment whose PATH is that folder alone: stand-ins
    for Slurm's commands, for what a real cluster cannot show on cue."""
    bin_dir.mkdir()
    for name, body in scripts.items():
        (bin_dir / name).write_text("#!/bin/sh\n" + body)
        (bin_dir / name).chmod(0o755)
    return dict(os.environ, PATH=str(bin_dir))


def submit_with_a_refused_assembly(painterly, tmp_path, scancel):
    """`farm submit --scheduler slurm` of the fish into tmp_path/out with a
    stand-in sbatch that accepts the job array (4242) and refuses the
    assembly job, and `scancel` as the body of the stand-in scancel (both
    in tmp_path/bin). Returns (the process, the output folder)."""
    bin_dir = tmp_path / "bin"
    env = stand_ins(bin_dir, {
        "sbatch": f"if [ -e {bin_dir}/once ]; then echo 'sbatch: error: Batch job submission failed: "
                  f"QOSMaxSubmitJobPerUserLimit' >&2; exit 1; fi\n: > {bin_dir}/once; echo '4242;cluster'\n",
        "scancel": scancel,
    })
    out = tmp_path / "out"
    out.mkdir()
    proc = painterly("farm", "submit", BLOWFISH, "-o", out / "shot.usda", "--chunk", "12", "--scheduler", "slurm",
                     env=env, check=False)
    return proc, out


def test_a_refused_assembly_takes_the_chunk_tasks_back(painterly, tmp_path):
    # A stand-in sbatch that accepts the job array and refuses the assembly
    # job: the one failure the real cluster cannot be made to produce on cue.
    bin_dir = tmp_path / "bin"
    proc, out = submit_with_a_refused_assembly(painterly, tmp_path, f"echo \"$@\" > {bin_dir}/cancelled\n")
    assert proc.returncode == 1
    assert "sbatch refused the assembly job: sbatch: error: Batch job submission failed: QOSMaxSubmitJobPerUserLimit" in proc.stderr
    assert "the chunk tasks (job 4242) were cancelled" in proc.stderr
    assert (bin_dir / "cancelled").read_text() == "4242\n"
    assert not (out / "shot.clips" / "farm" / "plan.json").exists()


def test_a_non_executable_sbatch_on_path_is_not_sbatch(painterly, tmp_path):
    # PATH search as POSIX execvp and shutil.which do it: only an executable
    # regular file is the program; a plain file or a folder of that name is not.
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    (bin_dir / "sbatch").write_text("#!/bin/sh\necho 4242\n")
    (bin_dir / "sbatch").chmod(0o644)
    (tmp_path / "dir" / "sbatch").mkdir(parents=True)
    path = f"{bin_dir}:{tmp_path / 'dir'}"
    assert shutil.which("sbatch", path=path) is None
    out = tmp_path / "out"
    out.mkdir()
    proc = painterly("farm", "submit", BLOWFISH, "-o", out / "shot.usda", "--chunk", "12",
                     "--scheduler", "slurm", env=dict(os.environ, PATH=path), check=False)
    assert proc.returncode == 1
    assert "sbatch not found on PATH" in proc.stderr
    assert list(out.iterdir()) == []


def test_submit_leaves_the_binding_for_the_tasks(painterly, tmp_path):
    # README "Bind once per shot": farm submit, the first process of the
    # shot to bind, leaves shot.clips/shot.binding.usdc (an override layer
    # of painterly:bindVertices/bindWeights) before any task runs.
    shot = tmp_path / "shot.usda"
    sub, _ = submit(painterly, None, BLOWFISH, shot, "--chunk", "12", "--scheduler", "openjd")
    assert sub["submitted"] == [0, 1, 2, 3]
    cache = tmp_path / "shot.clips" / "shot.binding.usdc"
    assert cache.is_file()
    layer = Sdf.Layer.FindOrOpen(str(cache))
    names = set()
    layer.Traverse(layer.pseudoRoot.path, lambda p: names.add(p.name) if p.IsPropertyPath() else None)
    assert {"painterly:bindVertices", "painterly:bindWeights"} <= names
    assert chunk_names(shot) == []


@pytest.mark.parametrize(
    "args,code,message",
    [
        (["--chunk", "0", "--scheduler", "openjd"], 2, "not a whole number of at least 1"),
        (["--chunk", "4"], 2, "--scheduler"),
        (["--chunk", "4", "--scheduler", "tractor"], 2, "invalid value 'tractor'"),
        (["--chunk", "4", "--scheduler", "openjd", "--partition", "p"], 2, "--partition and --sbatch-arg are for --scheduler slurm"),
        (["--chunk", "4", "--scheduler", "openjd", "--frames", "1:99"], 1, "outside the stage's time range"),
        (["--chunk", "4", "--scheduler", "openjd", "--camera", "/Nope"], 1, "/Nope"),
    ],
)
def test_bad_submit_arguments(painterly, tmp_path, args, code, message):
    proc = painterly("farm", "submit", BLOWFISH, "-o", tmp_path / "shot.usda", *args, check=False)
    assert proc.returncode == code, proc.stderr
    assert message in proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_bad_inputs_and_outputs(painterly, tmp_path):
    for src, out, message, code in [
        (tmp_path / "nope.usda", tmp_path / "shot.usda", "cannot open input", 1),
        (BLOWFISH, tmp_path / "shot.usdc", "name it .usda", 2),
        (BLOWFISH, tmp_path / "no" / "shot.usda", "does not exist", 1),
    ]:
        proc = painterly("farm", "submit", src, "-o", out, "--chunk", "4", "--scheduler", "openjd", check=False)
        assert proc.returncode == code, proc.stderr
        assert message in proc.stderr
    assert list(tmp_path.iterdir()) == []
    # A stage every frame of which fails to bake (viewDirection axes with no
    # source and no --camera) is refused before anything is planned or
    # submitted (it was submitted, and every task failed; a review,
    # 2026-12-07); with --camera it is submitted.
    head = (REPO / "fixtures" / "head.usda").read_text()
    no_source = tmp_path / "in" / "head.usda"
    no_source.parent.mkdir()
    no_source.write_text(head.replace("rel source = </Head/Camera>", ""))
    proc = painterly("farm", "submit", no_source, "-o", tmp_path / "shot.usda", "--chunk", "4",
                     "--scheduler", "openjd", check=False)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr == (f"error: {no_source}: /Head/Paint/viewX.source: "
                           "a viewDirection axis needs `rel source` or `--camera`\n"), proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in"]
    painterly("farm", "submit", no_source, "-o", tmp_path / "shot.usda", "--chunk", "4",
              "--scheduler", "openjd", "--camera", "/Head/Camera", "--quiet")
    assert (tmp_path / "shot.clips").is_dir()
    shutil.rmtree(tmp_path / "shot.clips")
    shutil.rmtree(tmp_path / "in")
    bad = tmp_path / "shot.clips" / "farm"
    bad.mkdir(parents=True)
    (bad / "plan.json").write_text("{not json")
    proc = painterly("farm", "status", tmp_path / "shot.usda", check=False)
    assert proc.returncode == 1 and "not a painterly farm plan" in proc.stderr


def test_status_of_a_relative_output_gives_absolute_paths(painterly, tmp_path):
    """`farm status shot.usda` run in the output's folder: `output` was
    absolute and `plan` as typed (`shot.clips/farm/plan.json`), unusable
    from another folder."""
    shot = tmp_path / "shot.usda"
    submit(painterly, None, BLOWFISH, shot, "--chunk", "12", "--scheduler", "openjd")
    proc = subprocess.run([str(painterly_binary()), "farm", "status", "shot.usda", "--json"],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 1, proc.stderr
    st = json.loads(proc.stdout)
    assert (st["output"], st["plan"], st["input"]) == (
        str(shot), str(tmp_path / "shot.clips" / "farm" / "plan.json"), str(BLOWFISH))


# --------------------------------------------------------------------------
# Open Job Description
# --------------------------------------------------------------------------

def test_openjd_template_runs_locally_and_resubmits_only_missing_chunks(painterly, tmp_path):
    openjd = openjd_exe()
    shot, single = tmp_path / "shot.usda", tmp_path / "single.usdc"
    sub, _ = submit(painterly, None, BLOWFISH, shot, "--chunk", "12", "--scheduler", "openjd")
    folder = tmp_path / "shot.clips" / "farm" / "openjd"
    template, params = folder / "template.json", folder / "parameters.json"
    assert sub == {
        "scheduler": "openjd", "input": str(BLOWFISH), "output": str(shot),
        "plan": str(tmp_path / "shot.clips" / "farm" / "plan.json"), "chunk_size": 12, "chunks": 4,
        "submitted": [0, 1, 2, 3], "skipped": [], "job": None,
        "tasks": [{"chunk": k, "task": f"BakeChunks[Chunk={k}]"} for k in range(4)], "assemble_job": "Assemble",
        "files": [str(template), str(params)], "next": f"openjd run {template} -p file://{params}",
    }
    doc = json.loads(template.read_text())
    assert [s["name"] for s in doc["steps"]] == ["BakeChunks", "Assemble"]
    assert doc["steps"][0]["parameterSpace"]["taskParameterDefinitions"] == [{"name": "Chunk", "type": "INT", "range": "0-3"}]
    assert doc["steps"][1]["dependencies"] == [{"dependsOn": "BakeChunks"}]
    assert json.loads(params.read_text()) == {
        "Painterly": str(painterly_binary().resolve()), "Input": str(BLOWFISH), "Output": str(shot),
    }
    check = subprocess.run([str(openjd), "check", str(template)], capture_output=True, text=True, timeout=120)
    assert check.returncode == 0, check.stdout + check.stderr
    st = status(painterly, None, shot)
    assert states(st) == ["missing"] * 4 and not st["scheduler_queried"]
    assert st["counts"] == counts(missing=4)
    # Not asked (openjd keeps no state) and nothing assembled: the assembly
    # step is missing, not failed, and no clip set is there to explain.
    assert st["assembly"] == {"job": "Assemble", "state": "missing", "scheduler_state": None, "detail": None}
    assert (st["assembled"], st["input_changed"]) == (False, False)

    def run():
        proc = subprocess.run([str(openjd), "run", str(template), "-p", f"file://{params}"],
                              capture_output=True, text=True, timeout=600, cwd=tmp_path)
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
        return proc.stdout

    run()
    st = status(painterly, None, shot)
    assert st["complete"] and states(st) == ["done"] * 4 and st["assembly"]["state"] == "done"
    assert st["counts"] == counts(done=4) and (st["assembled"], st["input_changed"]) == (True, False)
    painterly("bake", BLOWFISH, "-o", single, "--quiet")
    compare(single, shot, BLOWFISH, list(range(1, 49)), exact=True)
    compare(single, shot, BLOWFISH, [11.5, 12.5, 24.5, 36.5], exact=False)

    # One chunk lost: the next template bakes only that one.
    names = chunk_names(shot)
    before = {n: stat_key(tmp_path / "shot.clips" / n) for n in names if ".0002." not in n}
    (tmp_path / "shot.clips" / names[2]).unlink()
    sub, _ = submit(painterly, None, BLOWFISH, shot, "--chunk", "12", "--scheduler", "openjd")
    assert (sub["submitted"], sub["skipped"]) == ([2], [0, 1, 3])
    doc = json.loads(template.read_text())
    assert doc["steps"][0]["parameterSpace"]["taskParameterDefinitions"][0]["range"] == "2"
    run()
    assert status(painterly, None, shot)["complete"]
    assert {n: stat_key(tmp_path / "shot.clips" / n) for n in before} == before

    # Everything done: only the assembly step is left.
    sub, _ = submit(painterly, None, BLOWFISH, shot, "--chunk", "12", "--scheduler", "openjd")
    assert (sub["submitted"], sub["tasks"]) == ([], [])
    doc = json.loads(template.read_text())
    assert [s["name"] for s in doc["steps"]] == ["Assemble"] and "dependencies" not in doc["steps"][0]
    run()
    assert status(painterly, None, shot)["complete"]

    assert_status_reads_the_files_of_a_complete_bake(painterly, tmp_path, shot)


def counts(**n):
    return {k: n.get(k, 0) for k in ("done", "running", "pending", "failed", "missing", "stale")}


NOT_CURRENT = "the clip set on disk is not current: missing or stale chunks, or another input"


def assert_status_reads_the_files_of_a_complete_bake(painterly, tmp_path, shot):
    """Status of an assembled bake whose files are then changed one at a time
    (each change undone before the next, the lost chunk last)."""
    plan_path = tmp_path / "shot.clips" / "farm" / "plan.json"
    plan_text = plan_path.read_text()
    plan = json.loads(plan_text)

    # Every chunk done but no clip set: not complete (exit 1).
    shot.rename(tmp_path / "away.usda")
    st = status(painterly, None, shot)
    assert states(st) == ["done"] * 4 and st["counts"] == counts(done=4)
    assert (st["assembled"], st["complete"]) == (False, False)
    assert (st["assembly"]["state"], st["assembly"]["detail"]) == ("missing", None)
    (tmp_path / "away.usda").rename(shot)
    assert status(painterly, None, shot)["complete"]

    # The plan's input changed (a copy with one more comment byte): every
    # chunk and the clip set were baked from another input.
    changed = tmp_path / "changed.usda"
    changed.write_text(BLOWFISH.read_text() + "\n# changed\n")
    plan_path.write_text(json.dumps(dict(plan, input=str(changed))))
    st = status(painterly, None, shot)
    assert states(st) == ["stale"] * 4 and st["counts"] == counts(stale=4)
    assert st["chunks"][0]["detail"] == "baked from a different input"
    assert (st["input_changed"], st["assembled"], st["complete"]) == (True, False, False)
    assert (st["assembly"]["state"], st["assembly"]["detail"]) == ("missing", NOT_CURRENT)

    # A plan that lost its last chunk does not match its frames.
    plan_path.write_text(json.dumps(dict(plan, chunks=plan["chunks"][:3])))
    proc = painterly("farm", "status", shot, "--json", check=False)
    assert proc.returncode == 1 and proc.stdout == ""
    assert "the plan's chunks do not match its frames and chunk size" in proc.stderr
    plan_path.write_text(plan_text)

    # A chunk lost after the assembly: the clip set is no longer assembled.
    (tmp_path / "shot.clips" / chunk_names(shot)[1]).unlink()
    st = status(painterly, None, shot)
    assert states(st) == ["done", "missing", "done", "done"] and st["counts"] == counts(done=3, missing=1)
    assert (st["assembled"], st["complete"]) == (False, False)
    assert (st["assembly"]["state"], st["assembly"]["detail"]) == ("missing", NOT_CURRENT)


def test_a_clip_set_of_another_chunk_size_is_not_assembled(painterly, tmp_path):
    # Frames 1:3 in one chunk have the same chunk name at --chunk 3 and 4;
    # the clip set records its chunk size, and a plan of another size does
    # not count it as assembled even though its one chunk is done.
    shot = tmp_path / "shot.usda"
    submit(painterly, None, BLOWFISH, shot, "--chunk", "3", "--frames", "1:3", "--scheduler", "openjd")
    painterly("bake", BLOWFISH, "-o", shot, "--chunk", "3", "--frames", "1:3", "--quiet")
    assert status(painterly, None, shot)["complete"]
    plan_path = tmp_path / "shot.clips" / "farm" / "plan.json"
    plan_path.write_text(json.dumps(dict(json.loads(plan_path.read_text()), chunk_size=4)))
    st = status(painterly, None, shot)
    assert states(st) == ["done"] and st["counts"] == counts(done=1)
    assert (st["assembled"], st["complete"]) == (False, False)
    assert (st["assembly"]["state"], st["assembly"]["detail"]) == ("missing", NOT_CURRENT)


def test_status_asks_slurm_about_every_task(painterly, tmp_path):
    # Stand-ins for sbatch (array job 4242, assembly 4243) and squeue (one
    # task of each kind; 4242_3 no longer known): what a real cluster cannot
    # be made to show at once, and it runs without Slurm.
    bin_dir = tmp_path / "bin"
    env = stand_ins(bin_dir, {
        "sbatch": f"if [ -e {bin_dir}/once ]; then echo 4243; exit 0; fi\n: > {bin_dir}/once; echo '4242;cluster'\n",
        "squeue": 'case "$*" in *--jobs=4242,4243\\ *) ;; *) echo "squeue: error: Invalid job id specified" >&2; '
                  'exit 1;; esac\n'
                  "printf '%s\\n' '4242_0|PENDING|Priority' '4242_1|RUNNING|None' '4242_2|FAILED|NonZeroExitCode' "
                  "'4243|PENDING|Dependency'\n",
    })
    shot = tmp_path / "shot.usda"
    sub, _ = submit(painterly, env, BLOWFISH, shot, "--chunk", "12", "--scheduler", "slurm")
    assert (sub["job"], sub["assemble_job"]) == ("4242", "4243")
    st = status(painterly, env, shot)
    assert st["scheduler_queried"] and not st["complete"]
    assert states(st) == ["pending", "running", "failed", "failed"]
    assert st["counts"] == counts(pending=1, running=1, failed=2)
    assert [(c["task"], c["scheduler_state"], c["detail"]) for c in st["chunks"]] == [
        ("4242_0", "PENDING", "Priority"),
        ("4242_1", "RUNNING", None),
        ("4242_2", "FAILED", "task 4242_2 ended FAILED (NonZeroExitCode) and the chunk is missing"),
        ("4242_3", None, "task 4242_3 is no longer known to the scheduler and the chunk is missing"),
    ]
    assert st["assembly"] == {"job": "4243", "state": "pending", "scheduler_state": "PENDING", "detail": "Dependency"}


# --------------------------------------------------------------------------
# Slurm's answers a real cluster cannot give on cue (stand-ins)
# --------------------------------------------------------------------------

TWO_JOBS_SBATCH = "if [ -e {d}/once ]; then echo 4243; exit 0; fi\n: > {d}/once; echo '4242;cluster'\n"


def only_jobs(jobs, body):
    """A stand-in body that answers `body` when asked about exactly `jobs`
    (`--jobs=...` followed by more options), and otherwise fails as squeue
    and sacct do for a job they do not know."""
    return (f'case "$*" in *--jobs={jobs}\\ *) ;; *) echo "slurm_load_jobs error: Invalid job id specified" >&2; '
            f"exit 1;; esac\n{body}")


def test_two_submits_of_one_shot_at_once_take_turns(tmp_path):
    """Two `farm submit`s of one shot started together: both passed the
    live-task check, shared the job scripts, and the later plan hid the
    other's tasks, so status said complete while they waited and then
    rewrote the shot from another input (a review on a real cluster,
    2026-12-07). One submission at a time now holds `farm/submit.lock`: the
    second waits, finds the first's tasks waiting, and is refused; sbatch is
    called twice in all (array and assembly), not four times."""
    bin_dir = tmp_path / "bin"
    env = stand_ins(bin_dir, {
        "sbatch": f"echo x >> {bin_dir}/calls; /bin/sleep 0.5\n" + TWO_JOBS_SBATCH.format(d=bin_dir),
        "squeue": only_jobs("4242,4243", "printf '%s\\n' '4242_0|PENDING|Priority' '4242_1|PENDING|Priority' "
                                         "'4243|PENDING|Dependency'\n"),
    })
    shot = tmp_path / "shot.usda"
    cmd = [str(painterly_binary()), "farm", "submit", str(BLOWFISH), "-o", str(shot), "--chunk", "24",
           "--scheduler", "slurm", "--json"]
    procs = [subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for _ in range(2)]
    outs = [p.communicate(timeout=120) for p in procs]
    codes = sorted(p.returncode for p in procs)
    assert codes == [0, 1], outs
    refused = next(err for p, (_, err) in zip(procs, outs) if p.returncode == 1)
    assert "still wait or run" in refused, refused
    assert (bin_dir / "calls").read_text() == "x\nx\n"


def test_a_submit_lock_that_is_a_symbolic_link_is_refused_saying_so(painterly, tmp_path):
    """`farm/submit.lock` is never followed through a link (a leftover could
    name any file); the refusal said only `Too many levels of symbolic
    links` (noticed in the twenty-second session)."""
    bin_dir = tmp_path / "bin"
    env = stand_ins(bin_dir, {"sbatch": f"echo x >> {bin_dir}/calls\n"})
    shot = tmp_path / "shot.usda"
    farm = tmp_path / "shot.clips" / "farm"
    farm.mkdir(parents=True)
    target = tmp_path / "elsewhere.txt"
    target.write_text("kept\n")
    (farm / "submit.lock").symlink_to(target)
    proc = painterly("farm", "submit", BLOWFISH, "-o", shot, "--chunk", "24", "--scheduler", "slurm",
                     env=env, check=False)
    lock = farm / "submit.lock"
    assert (proc.returncode, proc.stderr) == (
        1, f"error: {lock}: cannot lock: it is a symbolic link, and a lock is never taken through one "
           "(remove the link)\n")
    assert target.read_text() == "kept\n" and not (bin_dir / "calls").exists()


def test_a_shot_is_not_complete_while_its_tasks_still_wait(painterly, tmp_path):
    """A local bake finished the shot while its farm tasks still wait in the
    queue: they will write the chunks and the clip set again, so status says
    pending, not done and complete (it said complete, exit 0; a review,
    2026-12-07), as submit's live-task check says."""
    bin_dir = tmp_path / "bin"
    env = stand_ins(bin_dir, {
        "sbatch": TWO_JOBS_SBATCH.format(d=bin_dir),
        "squeue": only_jobs("4242,4243", "printf '%s\\n' '4242_0|PENDING|JobHeldUser' '4242_1|PENDING|JobHeldUser' "
                                         "'4243|PENDING|Dependency'\n"),
    })
    shot = tmp_path / "shot.usda"
    submit(painterly, env, BLOWFISH, shot, "--chunk", "24", "--scheduler", "slurm")
    painterly("bake", BLOWFISH, "-o", shot, "--chunk", "24", "--quiet")
    st = status(painterly, env, shot)
    assert (st["assembled"], st["complete"]) == (True, False)
    assert states(st) == ["pending", "pending"] and st["counts"] == counts(pending=2)
    assert st["assembly"]["state"] == "pending"
    # The assembly task has ended (sacct: COMPLETED) while a chunk task
    # still waits: the assembly is done, the shot is still not complete.
    (bin_dir / "squeue").write_text("#!/bin/sh\n" + only_jobs("4242,4243", "printf '%s\\n' '4242_1|PENDING|JobHeldUser'\n"))
    (bin_dir / "sacct").write_text("#!/bin/sh\n" + only_jobs("4242,4243", "printf '%s\\n' '4242_0|COMPLETED|None' "
                                                                        "'4243|COMPLETED|None'\n"))
    (bin_dir / "sacct").chmod(0o755)
    st = status(painterly, env, shot)
    assert st["assembly"]["state"] == "done" and st["assembled"]
    assert states(st) == ["done", "pending"]
    assert not st["complete"]


@pytest.mark.parametrize("printed", ["", "Submitted batch job 4242"])
def test_sbatch_that_prints_no_job_id_is_refused(painterly, tmp_path, printed):
    # sbatch exits 0 without the --parsable "ID[;CLUSTER]" line: nothing at
    # all, or its default "Submitted batch job N" (sbatch(1) without
    # --parsable, e.g. from a wrapper). No task id can be recorded.
    bin_dir = tmp_path / "bin"
    env = stand_ins(bin_dir, {"sbatch": f"echo '{printed}'\n" if printed else "exit 0\n"})
    out = tmp_path / "out"
    out.mkdir()
    proc = painterly("farm", "submit", BLOWFISH, "-o", out / "shot.usda", "--chunk", "12", "--scheduler", "slurm",
                     env=env, check=False)
    assert proc.returncode == 1, proc.stdout
    assert "sbatch printed no job id for the chunk tasks" in proc.stderr
    assert f'(stdout "{printed}")' in proc.stderr
    assert not (out / "shot.clips" / "farm" / "plan.json").exists()


def test_a_refused_assembly_whose_scancel_fails_says_what_to_run(painterly, tmp_path):
    # As test_a_refused_assembly_takes_the_chunk_tasks_back, but scancel
    # fails too (exit 1, as scancel does when it may not cancel the job).
    proc, out = submit_with_a_refused_assembly(
        painterly, tmp_path, "echo 'scancel: error: Kill job error on job id 4242: Access/permission denied' >&2; exit 1\n")
    assert proc.returncode == 1
    assert "sbatch refused the assembly job" in proc.stderr
    assert "cancelling the chunk tasks failed: run scancel 4242" in proc.stderr
    assert "were cancelled" not in proc.stderr
    assert not (out / "shot.clips" / "farm" / "plan.json").exists()


@pytest.mark.parametrize("purged", [False, True])
def test_status_when_squeue_fails(painterly, tmp_path, purged):
    # squeue exits 1 in two ways: the controller does not answer (then
    # nothing is known and the files alone answer), or every job asked
    # about has left the controller's memory ("Invalid job id specified",
    # after MinJobAge): then Slurm was asked, and no task waits or runs.
    bin_dir = tmp_path / "bin"
    message = ("slurm_load_jobs error: Invalid job id specified" if purged
               else "slurm_load_jobs error: Unable to contact slurm controller (connect failure)")
    env = stand_ins(bin_dir, {
        "sbatch": TWO_JOBS_SBATCH.format(d=bin_dir),
        "squeue": f"echo '{message}' >&2; exit 1\n",
    })
    shot = tmp_path / "shot.usda"
    sub, _ = submit(painterly, env, BLOWFISH, shot, "--chunk", "12", "--scheduler", "slurm")
    assert (sub["job"], sub["assemble_job"]) == ("4242", "4243")
    st = status(painterly, env, shot)
    assert not st["complete"]
    assert st["scheduler_queried"] is purged
    if purged:
        assert states(st) == ["failed"] * 4 and st["counts"] == counts(failed=4)
        assert [c["detail"] for c in st["chunks"]] == [
            f"task 4242_{k} is no longer known to the scheduler and the chunk is missing" for k in range(4)
        ]
        assert (st["assembly"]["state"], st["assembly"]["scheduler_state"]) == ("failed", None)
    else:
        assert states(st) == ["missing"] * 4 and st["counts"] == counts(missing=4)
        assert [c["detail"] for c in st["chunks"]] == [None] * 4
        assert st["assembly"] == {"job": "4243", "state": "missing", "scheduler_state": None, "detail": None}


def test_status_reads_sacct_for_tasks_squeue_forgot(painterly, tmp_path):
    # With accounting, sacct (-n -P -X: "JobID|State|Reason") still knows
    # tasks that ended before the controller's MinJobAge, which squeue no
    # longer lists; squeue's live view wins where both answer (4242_3:
    # sacct's record is older). sacct prints "CANCELLED by UID".
    bin_dir = tmp_path / "bin"
    env = stand_ins(bin_dir, {
        "sbatch": TWO_JOBS_SBATCH.format(d=bin_dir),
        "sacct": only_jobs("4242,4243", "printf '%s\\n' '4242_0|COMPLETED|None' '4242_1|CANCELLED by 1000|None' "
                                        "'4242_2|TIMEOUT|None' '4242_3|PENDING|Priority' '4243|PENDING|Dependency'\n"),
        "squeue": only_jobs("4242,4243", "printf '%s\\n' '4242_3|RUNNING|None' '4243|PENDING|Dependency'\n"),
    })
    shot = tmp_path / "shot.usda"
    submit(painterly, env, BLOWFISH, shot, "--chunk", "12", "--scheduler", "slurm")
    st = status(painterly, env, shot)
    assert st["scheduler_queried"] and not st["complete"]
    assert states(st) == ["failed", "failed", "failed", "running"]
    assert st["counts"] == counts(running=1, failed=3)
    assert [c["scheduler_state"] for c in st["chunks"]] == ["COMPLETED", "CANCELLED", "TIMEOUT", "RUNNING"]
    assert st["chunks"][1]["detail"] == "task 4242_1 ended CANCELLED and the chunk is missing"
    assert st["chunks"][3]["detail"] is None
    assert st["assembly"] == {"job": "4243", "state": "pending", "scheduler_state": "PENDING", "detail": "Dependency"}
    # A task still runs and the assembly waits: a new submission is refused,
    # naming how to cancel each job (scancel JOBID).
    _, proc = submit(painterly, env, BLOWFISH, shot, "--chunk", "12", "--scheduler", "slurm", check=False)
    assert proc.returncode == 1
    assert "tasks of the previous submission still wait or run (4242_3, 4243)" in proc.stderr
    assert "(scancel 4242; scancel 4243)" in proc.stderr


def test_a_plan_without_task_ids_asks_no_scheduler(painterly, tmp_path):
    # A plan that records no task id (edited by hand, or kept from a
    # submission whose ids were lost) has nothing to ask Slurm about: squeue
    # and sacct are not run, and the files alone answer.
    bin_dir = tmp_path / "bin"
    asked = "echo \"$0 $*\" >> " + str(bin_dir / "asked") + "\n"
    env = stand_ins(bin_dir, {
        "sbatch": TWO_JOBS_SBATCH.format(d=bin_dir),
        "squeue": asked + "exit 0\n",
        "sacct": asked + "exit 0\n",
    })
    shot = tmp_path / "shot.usda"
    submit(painterly, env, BLOWFISH, shot, "--chunk", "12", "--scheduler", "slurm")
    plan_path = tmp_path / "shot.clips" / "farm" / "plan.json"
    plan = json.loads(plan_path.read_text())
    plan.update(job=None, assemble_job=None, chunks=[dict(c, task=None) for c in plan["chunks"]])
    plan_path.write_text(json.dumps(plan))
    st = status(painterly, env, shot)
    assert not st["scheduler_queried"]
    assert states(st) == ["missing"] * 4
    assert not (bin_dir / "asked").exists()


def test_quiet_submit_and_status_print_nothing_and_keep_their_exit_codes(painterly, tmp_path):
    """`-q` as for bake: a farm script that reads only exit codes gets them,
    and nothing on stdout or stderr."""
    shot = tmp_path / "shot.usda"
    sub = painterly("farm", "submit", BLOWFISH, "-o", shot, "--chunk", "24", "--scheduler", "openjd", "-q", check=False)
    assert (sub.returncode, sub.stdout, sub.stderr) == (0, "", "")
    assert (tmp_path / "shot.clips" / "farm" / "plan.json").is_file()
    st = painterly("farm", "status", shot, "--quiet", check=False)
    assert (st.returncode, st.stdout, st.stderr) == (1, "", "")
    # With --json too, only the JSON, as for bake (they were refused, exit 2,
    # while `-q` said "as for bake"; a review, 2026-12-07).
    both = painterly("farm", "status", shot, "--quiet", "--json", check=False)
    assert (both.returncode, both.stderr) == (1, "")
    assert json.loads(both.stdout)["complete"] is False
    again = painterly("farm", "submit", BLOWFISH, "-o", shot, "--chunk", "24", "--scheduler", "openjd", "-q",
                      "--json", check=False)
    assert (again.returncode, again.stderr) == (0, "")
    assert json.loads(again.stdout)["scheduler"] == "openjd"
    bake = painterly("bake", BLOWFISH, "-o", tmp_path / "one.usdc", "--frames", "1:2", "-q", "--json")
    assert (bake.stderr, json.loads(bake.stdout)["frames"]) == ("", 2)


def test_slurm_scripts_and_log_patterns_hold_any_output_folder(painterly, tmp_path):
    """An output folder with a newline put a live shell line into the
    comment of bake.sh and assemble.sh, and a `%` in it was taken by sbatch
    as a replacement symbol in --output (found by a files-and-signals
    review, 2026-12-06). The comment now quotes the path with escapes, and
    `%` is passed as `%%`. The scripts run here with a stand-in painterly
    that records its arguments."""
    bin_dir = tmp_path / "bin"
    env = stand_ins(bin_dir, {"sbatch": f"for a in \"$@\"; do printf '%s\\n' \"$a\"; done >> {bin_dir}/argv\necho 4242\n"})
    folder = tmp_path / "shots\ntouch INJECTED\n#%j"
    folder.mkdir()
    shutil.copy(BLOWFISH, folder / "fish.usda")
    painterly("farm", "submit", folder / "fish.usda", "-o", folder / "shot.usda", "--chunk", "24", "--frames", "1:48",
              "--scheduler", "slurm", env=env, cwd=tmp_path)
    argv = (bin_dir / "argv").read_text()
    logs = str(folder / "shot.clips" / "farm" / "logs").replace("%", "%%")
    assert f"--output={logs}/bake.%A_%a.log\n" in argv and f"--output={logs}/assemble.%j.log\n" in argv
    fake = tmp_path / "fake-painterly"
    fake.write_text("#!/bin/sh\nexit 0\n")
    fake.chmod(0o755)
    for name in ("bake.sh", "assemble.sh"):
        script = folder / "shot.clips" / "farm" / name
        text = script.read_text()
        # Run the script's lines with painterly replaced by the stand-in.
        text = text.replace(str(painterly_binary().resolve()), str(fake)).replace(str(painterly_binary()), str(fake))
        proc = subprocess.run(["bash", "-c", text], cwd=tmp_path, capture_output=True, text=True, timeout=60,
                              env=dict(os.environ, SLURM_ARRAY_TASK_ID="0", SLURM_ARRAY_JOB_ID="1"))
        assert proc.returncode == 0, (name, proc.stderr)
        assert not (tmp_path / "INJECTED").exists(), f"{name} ran a line from the folder's name:\n{text}"
