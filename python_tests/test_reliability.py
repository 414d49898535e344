"""Reliability (issue 11): inputs that used to crash, hang, allocate without
bound or bake silently wrong now fail fast with exit 1 (2 for usage) and a
message naming the file, prim and attribute; a run stopped by SIGTERM or
SIGINT while writing leaves no temporary file and the previous output
intact; temporaries of killed runs are removed by the next run.

Every case here failed before the fix: stack overflow (abort), exit 3, exit
0 with nothing baked, minutes of allocation, or a leftover temporary."""

import os
import pathlib
import re
import shutil
import signal
import stat
import subprocess
import time

import pytest
from pxr import Sdf, Usd, UsdGeom

from clip_compare import compare
from conftest import REPO, painterly_binary

BLOWFISH = REPO / "fixtures" / "blowfish.usda"
# Guard against hangs (the bad cases used to run for minutes); not a speed test.
HANG = 120


def run(*args, env=None):
    proc = subprocess.run(
        [str(painterly_binary()), *[str(a) for a in args]],
        capture_output=True,
        text=True,
        timeout=HANG,
        env=env,
    )
    err = proc.stderr
    assert "panicked" not in err and "overflowed its stack" not in err, err
    assert "internal error" not in err, err
    assert proc.returncode >= 0, f"killed by signal {-proc.returncode}:\n{err}"
    return proc


def expect_error(proc, code, *names):
    assert proc.returncode == code, f"exit {proc.returncode}, expected {code}\n{proc.stderr}"
    assert re.search(r"^error:", proc.stderr, re.M), proc.stderr
    for n in names:
        assert n in proc.stderr, f"{n!r} not named:\n{proc.stderr}"


def leftovers(folder):
    return [n for n in os.listdir(folder) if ".painterly-" in n]


def bake_fails(tmp_path, src, *names, code=1, extra=()):
    """A bake that must fail: input errors (exit 1) name the file, usage
    errors (exit 2) the option."""
    out = tmp_path / "out" / "bake.usdc"
    out.parent.mkdir(exist_ok=True)
    before = src.read_bytes()
    proc = run("bake", src, "-o", out, *extra)
    expect_error(proc, code, *([src.name] if code == 1 else []), *names)
    assert not out.exists()
    assert leftovers(out.parent) == []
    assert src.read_bytes() == before
    return proc


def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


# ---------------------------------------------------------------------------
# composition


CYCLE = """#usda 1.0
class "A" (inherits = </B>)
{
}
class "B" (inherits = </A>)
{
}
def Xform "C" (inherits = </A>)
{
}
"""


@pytest.mark.parametrize("command", ["bake", "inspect"])
def test_inherit_cycle_is_an_error_not_a_stack_overflow(tmp_path, command):
    src = write(tmp_path, "cycle.usda", CYCLE)
    # usd-core opens it and reports the cycle.
    assert Usd.Stage.Open(str(src)).GetCompositionErrors()
    args = ["-o", tmp_path / "o.usdc"] if command == "bake" else []
    expect_error(run(command, src, *args), 1, "cycle.usda", "cycle", "/A", "/B")


# usd-core composes this without error; openusd 0.8 overflows its stack on it
# (found by the random-hierarchy search in src/usd_io/compose_watch.rs).
OPENUSD_CRASH = """#usda 1.0
def "A"
{
    def "X" (
        inherits = [</C>]
    )
    {
        def "W"
        {
        }
    }
}
def "B"
{
    def "Y"
    {
    }
}
def "C" (
    inherits = [</B/Y>]
    specializes = [</B>]
)
{
    def "Z"
    {
    }
}
"""


@pytest.mark.parametrize("command", ["bake", "inspect"])
def test_openusd_composition_crash_is_an_error(tmp_path, command):
    src = write(tmp_path, "hier.usda", OPENUSD_CRASH)
    args = ["-o", tmp_path / "o.usdc"] if command == "bake" else []
    proc = run(command, src, *args)
    expect_error(proc, 1, "hier.usda", "openusd 0.8")
    # The README's Limits row, word for word (it did not name memory, which
    # a stage too large for `ulimit -v` ends in too).
    assert proc.stderr == (
        f"error: {src}: openusd 0.8 crashed composing this stage (stack overflow or aborted allocation). "
        "Its composition arcs are beyond what openusd can compose (e.g. recursive inherits, specializes or "
        "references, which usd-core reports as arc cycles), or composing it needs more memory than the process "
        "may use (ulimit -v).\n")
    assert leftovers(tmp_path) == []


def nested(depth, per_line=True):
    head = "".join(f'def "p{i}" {{\n' for i in range(depth))
    return "#usda 1.0\n" + head + "}\n" * depth


def test_deep_text_nesting_is_refused(tmp_path):
    src = write(tmp_path, "deep.usda", nested(10_000))
    proc = bake_fails(tmp_path, src, "10000 deep", "1000 levels")
    assert "line 10001" in proc.stderr


def test_deep_namespace_is_refused(tmp_path):
    src = write(tmp_path, "ns.usda", nested(300))
    bake_fails(tmp_path, src, "namespace 300 prims deep", "at most 256")
    # 256 levels compose (inspect of a stage with no character: exit 0).
    ok = write(tmp_path, "ok.usda", nested(256))
    assert run("inspect", ok).returncode == 0


# ---------------------------------------------------------------------------
# frame ranges


def with_metadata(tmp_path, **meta):
    dst = tmp_path / "rig.usda"
    shutil.copy(BLOWFISH, dst)
    layer = Sdf.Layer.FindOrOpen(str(dst))
    for k, v in meta.items():
        setattr(layer, k, v)
    layer.Save()
    return dst


@pytest.mark.parametrize("end", [1e19, 4294967296.0, 1e9, 1e7, 1e6])
def test_huge_stage_range_fails_fast(tmp_path, end):
    src = with_metadata(tmp_path, endTimeCode=end)
    bake_fails(tmp_path, src, "startTimeCode:endTimeCode", "at most 500000", "--frames")


@pytest.mark.parametrize(
    "meta,named",
    [
        ({"endTimeCode": float("inf")}, "endTimeCode"),
        ({"endTimeCode": 1e308}, "500000"),
        ({"startTimeCode": float("-inf")}, "startTimeCode"),
        ({"startTimeCode": float("nan")}, "startTimeCode"),
        ({"startTimeCode": 50.0}, "startTimeCode"),
        ({"framesPerSecond": float("nan")}, "framesPerSecond"),
        ({"timeCodesPerSecond": 0.0}, "timeCodesPerSecond"),
    ],
)
def test_invalid_stage_timing_is_named(tmp_path, meta, named):
    src = with_metadata(tmp_path, **meta)
    proc = bake_fails(tmp_path, src, named)
    assert "has no startTimeCode" not in proc.stderr
    # inspect reports what bake refuses.
    assert run("inspect", src).returncode == 1


# ---------------------------------------------------------------------------
# sizes (README "Limits")


def test_too_many_stroke_points_fail_before_the_points_are_read(tmp_path):
    """curveVertexCounts promising 20,000,001 points is refused from the
    counts alone (the limit is checked before points are decoded)."""
    src = tmp_path / "rig.usda"
    shutil.copy(REPO / "fixtures" / "static.usda", src)
    stage = Usd.Stage.Open(str(src))
    stage.GetPrimAtPath("/Static/Paint/Dabs").GetAttribute("curveVertexCounts").Set([20_000_001])
    stage.GetRootLayer().Save()
    bake_fails(tmp_path, src, "/Static/Paint/Dabs", "curveVertexCounts", "20000001 stroke points", "at most 20000000")
    proc = run("inspect", src)
    assert proc.returncode == 1 and "at most 20000000" in proc.stdout + proc.stderr


def test_the_stroke_point_limits_advice_can_be_followed(tmp_path):
    """Two layers over the limit together: the message says to bake them in
    several runs, deactivating the others in a layer over the input, and a
    shot layer that deactivates one takes the other under the limit."""
    src = tmp_path / "rig.usda"
    shutil.copy(REPO / "fixtures" / "static.usda", src)
    stage = Usd.Stage.Open(str(src))
    dabs = stage.GetPrimAtPath("/Static/Paint/Dabs")
    Sdf.CopySpec(stage.GetRootLayer(), dabs.GetPath(), stage.GetRootLayer(), "/Static/Paint/Dabs2")
    for p in ("/Static/Paint/Dabs", "/Static/Paint/Dabs2"):
        stage.GetPrimAtPath(p).GetAttribute("curveVertexCounts").Set([10_000_001])
    stage.GetRootLayer().Save()
    bake_fails(tmp_path, src, "at most 20000000",
               "bake its stroke layers in several runs, deactivating the others in a layer over the input")
    shot = Sdf.Layer.CreateNew(str(tmp_path / "part.usda"))
    shot.subLayerPaths.append(src.name)
    over = Sdf.CreatePrimInLayer(shot, "/Static/Paint/Dabs2")
    over.specifier = Sdf.SpecifierOver
    over.active = False
    shot.Save()
    proc = run("inspect", tmp_path / "part.usda")
    # Under the limit now: the remaining layer's own 10,000,001 counts
    # against its 60 points is what is left to fix.
    assert "at most 20000000" not in proc.stdout + proc.stderr, proc.stdout + proc.stderr
    assert "/Static/Paint/Dabs" in proc.stdout + proc.stderr


def test_a_proxy_over_the_point_limit_is_refused(tmp_path):
    """A 10,000,001-point proxy (a 120 MB crate file from usd-core) fails
    fast naming the proxy instead of binding for minutes."""
    import numpy as np
    from pxr import Vt

    src = tmp_path / "rig.usdc"
    layer = Sdf.Layer.FindOrOpen(str(REPO / "fixtures" / "static.usda"))
    layer.Export(str(src))
    stage = Usd.Stage.Open(str(src))
    pts = np.zeros((10_000_001, 3), dtype=np.float32)
    pts[:, 0] = np.arange(pts.shape[0], dtype=np.float32) * 1e-3
    stage.GetPrimAtPath("/Static/Rig/Proxy").GetAttribute("points").Set(Vt.Vec3fArray.FromNumpy(pts))
    stage.GetRootLayer().Save()
    del stage, pts
    started = time.monotonic()
    bake_fails(tmp_path, src, "/Static/Rig/Proxy", "10000001 points", "at most 10000000")
    assert time.monotonic() - started < 20


@pytest.mark.parametrize("frames", ["1:12:1e-18", "1:12:1e-9", "1:12:0.00001", "1:12:1e-19"])
def test_tiny_frame_step_is_a_usage_error(tmp_path, frames):
    proc = bake_fails(tmp_path, BLOWFISH, "at most 500000", code=2, extra=["--frames", frames])
    assert "--frames" in proc.stderr
    # The advice is one the CLI can follow: --chunk does not lift the limit.
    assert "bake the range in parts, each with its own --frames A:B" in proc.stderr
    assert "chunk" not in proc.stderr


# ---------------------------------------------------------------------------
# trust between commands


def test_missing_reference_fails_bake_and_is_listed_by_inspect(tmp_path):
    src = tmp_path / "rig.usda"
    shutil.copy(BLOWFISH, src)
    stage = Usd.Stage.Open(str(src))
    stage.GetPrimAtPath("/Blowfish").GetReferences().AddReference("./missing_rig.usda")
    stage.GetRootLayer().Save()
    bake_fails(tmp_path, src, "missing_rig.usda", "/Blowfish")
    proc = run("inspect", src, "--json")
    assert proc.returncode == 1
    import json

    report = json.loads(proc.stdout)
    assets = report["unresolved_assets"]
    assert len(assets) == 1 and assets[0]["asset"].endswith("missing_rig.usda"), assets
    assert assets[0]["prim"] == "/Blowfish" and assets[0]["arc"] == "reference", assets
    assert any("missing_rig.usda" in p["message"] for p in report["problems"])


def non_finite_at_a_frame(tmp_path, fixture, prim, attr, good, bad):
    """`fixture` with `prim`.`attr` sampled `good` at frame 1 and `bad` (not
    finite) from frame 6 on, written by usd-core: every static check passes,
    only evaluating frame 6 finds it."""
    src = tmp_path / fixture
    shutil.copy(REPO / "fixtures" / fixture, src)
    stage = Usd.Stage.Open(str(src))
    a = stage.GetPrimAtPath(prim).GetAttribute(attr)
    assert a.IsValid(), (prim, attr)
    a.Set(good, 1.0)
    a.Set(bad, 6.0)
    stage.GetRootLayer().Save()
    return src


@pytest.mark.parametrize(
    "fixture, prim, attr, good, bad",
    [
        # A camera that leaves the world at frame 6: view-dependent blending
        # and the camera axis cannot be evaluated there.
        ("building.usda", "/Building/Camera", "xformOp:translate", (0, 0, 50), (float("nan"), 0, 0)),
        # A proxy whose transform is not finite from frame 6.
        ("static.usda", "/Static/Rig/Proxy", "xformOp:translate", (0.5, 1, 0), (float("inf"), 1, 0)),
    ],
)
def test_inspect_evaluates_every_frame_bake_would(tmp_path, fixture, prim, attr, good, bad):
    """inspect exit 0 means the default bake succeeds: it evaluates each
    frame (writing nothing) and reports what bake would fail on."""
    src = non_finite_at_a_frame(tmp_path, fixture, prim, attr, good, bad)
    proc = bake_fails(tmp_path, src, prim)
    assert "not finite" in proc.stderr, proc.stderr
    proc = run("inspect", src, "--json")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    import json

    problems = json.loads(proc.stdout)["problems"]
    assert len(problems) == 1, problems
    assert problems[0]["prim"] == prim and "not finite" in problems[0]["message"], problems
    # The untouched fixture passes both.
    assert run("inspect", REPO / "fixtures" / fixture).returncode == 0


def test_inspect_checks_the_frames_bake_will_get(tmp_path):
    """inspect takes bake's --frames: a stage without a time range (a paint
    layer over a published asset) fails inspect as it fails bake, and
    passes both with the same --frames; --frames that avoid a bad frame
    pass, frames that reach it fail, as the bakes do (walkthrough: inspect
    passed a stage without a range that bake then refused)."""
    import json

    src = non_finite_at_a_frame(tmp_path, "static.usda", "/Static/Rig/Proxy", "xformOp:translate",
                                (0.5, 1, 0), (float("inf"), 1, 0))
    layer = Sdf.Layer.FindOrOpen(str(src))
    layer.ClearStartTimeCode()
    layer.ClearEndTimeCode()
    layer.Save()
    why = "the stage has no startTimeCode/endTimeCode: pass --frames A:B"
    bake_fails(tmp_path, src, why)
    proc = run("inspect", src, "--json")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert json.loads(proc.stdout)["problems"] == [{"prim": None, "attribute": None, "message": why, "rule": "unreadable"}]
    out = tmp_path / "ok.usdc"
    # The translate is held before its good sample at 1 and interpolates
    # towards inf after it: frames up to 1 evaluate, later ones do not. A
    # pre-roll's negative frames are values, not options.
    for frames, code in [("1", 0), ("-2:1:0.5", 0), ("1:2", 1), ("6", 1)]:
        inspected = run("inspect", src, "--frames", frames)
        baked = run("bake", src, "-o", out, "--frames", frames, "-q")
        assert (inspected.returncode, baked.returncode) == (code, code), (frames, inspected.stdout, baked.stderr)
        if code:
            assert "/Static/Rig/Proxy" in inspected.stdout and "not finite" in inspected.stdout, inspected.stdout
    # A stage with a range: --frames must lie inside it, as for bake.
    fixture = REPO / "fixtures" / "static.usda"
    proc = run("inspect", fixture, "--frames", "0:100", "--json")
    assert proc.returncode == 1
    assert [p["message"] for p in json.loads(proc.stdout)["problems"]] == [
        "--frames 0:100 is outside the stage's time range 1:12 (startTimeCode:endTimeCode)"]
    expect_error(run("inspect", fixture, "--frames", "1:2:0"), 2, "--frames")


def undecodable_camera_samples(tmp_path):
    """Found by `scripts/fuzz --seed 20261205` (case 11453): usd-core's
    crate export of building.usda with two bytes changed, so that the
    camera's translate samples cannot be decoded and sit under an op name
    no transform op has ("xformOp:traNslate"), which the camera's transform
    skips. Returns that file, and the same export with the translate op
    left out of xformOpOrder: the transform the first one has."""
    ref = tmp_path / "building_no_translate.usdc"
    Sdf.Layer.FindOrOpen(str(REPO / "fixtures" / "building.usda")).Export(str(ref))
    src = tmp_path / "building.usdc"
    data = bytearray(ref.read_bytes())
    # The fuzzer's two bytes, in usd-core's (pinned) export: the third byte
    # of the offset in one sample's value rep (a Vec3d, type 0x17), and the
    # "n" of the shared token "translate" (an LZ4 literal).
    assert data[6840:6848] == b"\x18\x15\x00\x00\x00\x00\x17\x00", "usd-core's export changed"
    assert data[7178:7187] == b"translate", "usd-core's export changed"
    data[6842] = 0xA9
    data[7181] = ord("N")
    src.write_bytes(bytes(data))
    stage = Usd.Stage.Open(str(ref))
    camera = UsdGeom.Xformable(stage.GetPrimAtPath("/Building/Camera"))
    ops = camera.GetOrderedXformOps()
    assert [op.GetOpName() for op in ops] == ["xformOp:translate", "xformOp:orient"]
    camera.SetXformOpOrder(ops[1:])
    stage.Save()
    return src, ref


def test_samples_a_transform_skips_fail_neither_inspect_nor_bake(tmp_path):
    """bake reads the stage mapped, and its mapped reader asked openusd
    whether the camera may move (to keep a fixed transform), which decodes
    the skipped op's samples and failed: bake exited 1 while inspect (then
    unmapped) passed. That question now only decides what is kept, so both
    pass, inspect reading as bake does, and the bake is the bake of the
    file without that op."""
    src, ref = undecodable_camera_samples(tmp_path)
    import json

    proc = run("inspect", src, "--json")
    assert proc.returncode == 0 and json.loads(proc.stdout)["problems"] == [], proc.stdout + proc.stderr
    baked = []
    for name, path in (("corrupt", src), ("reference", ref)):
        out = tmp_path / f"{name}_bake.usdc"
        proc = run("bake", path, "-o", out)
        assert proc.returncode == 0, proc.stderr
        baked.append(out)
    assert len(Sdf.Layer.FindOrOpen(str(baked[0])).ListTimeSamplesForPath("/Building/Box.points")) == 48
    compare(baked[0], baked[1], ref, range(1, 49), exact=True)


def test_camera_naming_a_mesh_is_refused(tmp_path):
    src = tmp_path / "rig.usda"
    shutil.copy(BLOWFISH, src)
    stage = Usd.Stage.Open(str(src))
    mesh = next(p for p in stage.Traverse() if p.GetTypeName() == "Mesh")
    path = str(mesh.GetPath())
    bake_fails(tmp_path, src, path, "--camera", "Mesh", extra=["--camera", path])


def test_wrong_output_extension_is_a_usage_error(tmp_path):
    out = tmp_path / "bake.txt"
    proc = run("bake", BLOWFISH, "-o", out)
    expect_error(proc, 2, ".usdc")
    assert not out.exists()


# ---------------------------------------------------------------------------
# interrupted writes


def host():
    raw = pathlib.Path("/proc/sys/kernel/hostname").read_text().strip()
    return "".join(c if c.isascii() and (c.isalnum() or c == ".") else "_" for c in raw) or "localhost"


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
@pytest.mark.parametrize("ext", ["usdc", "usda"])
def test_signal_during_write_leaves_no_temporary_and_the_old_output(tmp_path, sig, ext):
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    out = out_dir / f"bake.{ext}"
    old = b"previous output, must survive\n"
    out.write_bytes(old)
    # --bake-proxy over the whole range keeps the write going for a while.
    proc = subprocess.Popen(
        [str(painterly_binary()), "bake", str(BLOWFISH), "-o", str(out), "--bake-proxy", "-q"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + HANG
    while not leftovers(out_dir) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.001)
    seen = leftovers(out_dir)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=HANG)
    if not seen or proc.returncode == 0:
        pytest.skip(f"the bake finished before the signal (exit {proc.returncode})")
    assert proc.returncode == 128 + sig, f"exit {proc.returncode}\n{err}"
    assert "temporary files removed" in err
    assert leftovers(out_dir) == []
    # The old output, or (signal just after the rename) the complete new one.
    assert out.read_bytes() == old or Usd.Stage.Open(str(out)), err


def test_a_signal_blocked_in_the_mask_painterly_inherits_still_stops_it(tmp_path):
    """A job runner that starts painterly from a thread with SIGTERM
    blocked passes that mask on through exec: the signal then never
    arrived, so the cleanup never ran, and the bus-error report (which
    goes through it) waited for ever (found by a review, 2026-12-07).
    painterly unblocks SIGTERM, SIGINT and SIGHUP as it starts."""
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    out = out_dir / "bake.usdc"
    proc = subprocess.Popen(
        [str(painterly_binary()), "bake", str(BLOWFISH), "-o", str(out), "--bake-proxy", "-q"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=lambda: signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM}),
    )
    deadline = time.monotonic() + HANG
    while not leftovers(out_dir) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.001)
    seen = leftovers(out_dir)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=HANG)
    if not seen:
        pytest.skip(f"the bake finished before its temporary was seen (exit {proc.returncode})")
    assert (proc.returncode, err) == (128 + signal.SIGTERM, "painterly: stopped by signal 15; temporary files removed\n")
    assert leftovers(out_dir) == []


@pytest.mark.parametrize("stderr_kind", ["full disk", "closed pipe"])
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_ends_the_run_when_stderr_cannot_be_written(tmp_path, stderr_kind, sig):
    """A farm task killed while its log disk is full or its log reader is
    gone: the signal's cleanup still ends the process, 128 + signal (it
    deadlocked: the signal thread held the temporaries' list when its
    message failed, and the panic hook waited for the list; found by a
    review, 2026-12-07)."""
    if stderr_kind == "full disk":
        err = open("/dev/full", "w")
        closer = err.close
    else:
        r, w = os.pipe()
        os.close(r)
        err = w
        closer = lambda: os.close(w)  # noqa: E731
    proc = subprocess.Popen([str(painterly_binary()), "preview", str(BLOWFISH), "--port", "0"],
                            stdout=subprocess.PIPE, stderr=err, text=True)
    closer()
    try:
        line = proc.stdout.readline()  # the URL: the server is up
        assert "http://" in line, line
        proc.send_signal(sig)
        code = proc.wait(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert code == 128 + sig


@pytest.mark.parametrize("mode", [0o600, 0o664, 0o444])
def test_a_replaced_file_keeps_its_permission_bits(tmp_path, mode):
    """An in-place edit and a bake over an existing output replace the file
    by a rename; the new file keeps the old one's mode, as usd-core's Save
    does (a private file must not become world-readable)."""
    src = tmp_path / "fish.usda"
    shutil.copy(BLOWFISH, src)
    src.chmod(mode)
    out = tmp_path / "bake.usdc"
    out.write_bytes(b"old")
    out.chmod(mode)
    edit = run("key", src, "--layer", "/Blowfish/Paint/Hair", "--time", "5", "--sentinel", "--in-place", "-q")
    bake = run("bake", src, "-o", out, "--frames", "1:2", "-q")
    # root may write a read-only file, as it may with usd-core.
    assert (edit.returncode, bake.returncode) == (0, 0), edit.stderr + bake.stderr
    assert Usd.Stage.Open(str(src)).GetPrimAtPath("/Blowfish/Paint/Hair/sentinel1")
    assert (src.stat().st_mode & 0o7777, out.stat().st_mode & 0o7777) == (mode, mode)


def test_a_write_through_a_symlink_replaces_the_file_it_names(tmp_path):
    """`--in-place` (and a bake's -o) through a symbolic
    link edits the file the link names and keeps the link, as usd-core's
    `Layer.Save()` through a link does; it replaced the link by a regular
    file beside it and left the real file unedited (found by an
    edit-fidelity review, 2026-12-06). The edit's bytes equal the same
    edit made on the file directly."""
    versions = tmp_path / "versions"
    versions.mkdir()
    real = versions / "fish_v003.usda"
    shutil.copy(BLOWFISH, real)
    direct = tmp_path / "direct.usda"
    shutil.copy(BLOWFISH, direct)
    link = tmp_path / "fish_latest.usda"
    link.symlink_to("versions/fish_v003.usda")
    key = ("--layer", "/Blowfish/Paint/Hair", "--time", "5", "--sentinel", "-q")
    for target, args in ((link, ("--in-place",)), (direct, ("--in-place",))):
        proc = run("key", target, *key, *args)
        assert proc.returncode == 0, proc.stderr
    assert link.is_symlink() and os.readlink(link) == "versions/fish_v003.usda"
    assert real.read_bytes() == direct.read_bytes() != BLOWFISH.read_bytes()
    # A bake's output reached through a link: written through it too.
    out_real, out_link = versions / "bake.usdc", tmp_path / "bake.usdc"
    out_real.write_bytes(b"old")
    out_link.symlink_to(out_real)
    bake = run("bake", direct, "-o", out_link, "--frames", "1:2", "-q")
    assert bake.returncode == 0, bake.stderr
    assert out_link.is_symlink()
    assert Usd.Stage.Open(str(out_real)).GetPrimAtPath("/Blowfish/Paint/Hair").GetAttribute("points").GetNumTimeSamples() == 2
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bake.usdc", "direct.usda", "fish_latest.usda", "versions"]


@pytest.mark.skipif(os.geteuid() != 0 or not shutil.which("setpriv"), reason="needs root to run as another user")
def test_a_file_the_user_may_not_write_is_not_replaced(request):
    """In a folder anyone may write, a rename could replace another user's
    read-only file; painterly refuses, naming the file, and leaves it as
    it was (usd-core's Save refuses it too)."""
    import tempfile

    # pytest's own folders are private to root; this one is reachable.
    shared = pathlib.Path(tempfile.mkdtemp(prefix="painterly-shared-"))
    request.addfinalizer(lambda: shutil.rmtree(shared, ignore_errors=True))
    shared.chmod(0o777)
    locked = shared / "fish.usda"
    shutil.copy(BLOWFISH, locked)
    locked.chmod(0o444)
    out = shared / "bake.usdc"
    out.write_bytes(b"root's")
    out.chmod(0o444)
    before = locked.read_bytes()
    nobody = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", str(painterly_binary())]

    def as_nobody(*args):
        proc = subprocess.run([*nobody, *map(str, args)], capture_output=True, text=True, timeout=HANG)
        assert "panicked" not in proc.stderr, proc.stderr
        return proc

    why = "cannot replace a file this user may not write (mode 444): change its permissions first"
    edit = as_nobody("key", locked, "--layer", "/Blowfish/Paint/Hair", "--time", "5", "--sentinel", "--in-place")
    assert (edit.returncode, edit.stderr) == (1, f"error: {locked}: {why}\n")
    bake = as_nobody("bake", locked, "-o", out, "--frames", "1:2", "-q")
    assert (bake.returncode, bake.stderr) == (1, f"error: {out}: {why}\n")
    assert locked.read_bytes() == before and out.read_bytes() == b"root's"
    assert (locked.stat().st_uid, out.stat().st_uid) == (0, 0)
    assert leftovers(shared) == []


def test_next_run_removes_temporaries_of_killed_runs(tmp_path):
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    dead = subprocess.Popen(["true"])
    dead.wait()
    stale = out_dir / f".bake.usdc.painterly-{host()}-{dead.pid}.tmp"
    stale.write_bytes(b"x" * 1000)
    # A live process's temporary and another host's are kept.
    live = out_dir / f".other.usdc.painterly-{host()}-{os.getpid()}.tmp"
    live.write_bytes(b"y")
    remote = out_dir / f".bake.usdc.painterly-otherhost-{dead.pid}.tmp"
    remote.write_bytes(b"z")
    proc = run("bake", BLOWFISH, "-o", out_dir / "bake.usdc", "--frames", "1:2", "-q")
    assert proc.returncode == 0, proc.stderr
    assert not stale.exists()
    assert live.exists() and remote.exists()


def test_host_name_in_temporaries_keeps_letters_digits_and_dots(tmp_path):
    """On a farm host "render-07.farm" temporaries say "render_07.farm": '-'
    becomes '_', '.' stays; the sweep must match that name. The host name is
    set in a UTS namespace of its own (unshare -ru), skipped where none can be made."""
    name = "render-07.farm"
    probe = subprocess.run(["unshare", "-ru", "hostname", name], capture_output=True)
    if probe.returncode != 0:
        pytest.skip(f"cannot set a host name in a namespace: {probe.stderr!r}")
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    dead = subprocess.Popen(["true"])
    dead.wait()
    stale = out_dir / f".bake.usdc.painterly-render_07.farm-{dead.pid}.tmp"
    stale.write_bytes(b"x")
    proc = subprocess.run(
        ["unshare", "-ru", "sh", "-c", f'hostname {name} && exec "$@"', "sh", str(painterly_binary()),
         "bake", str(BLOWFISH), "-o", str(out_dir / "bake.usdc"), "--frames", "1:2", "-q"],
        capture_output=True, text=True, timeout=HANG,
    )
    assert proc.returncode == 0, proc.stderr
    assert not stale.exists()


@pytest.mark.parametrize("derived, command", [
    ("shot.clips/shot.0000.1-2.usdc", ("bake", "fish.usda", "-o", "shot.usda", "--frames", "1:4", "--chunk", "2")),
    ("shot.clips/shot.manifest.usda", ("bake", "fish.usda", "-o", "shot.usda", "--frames", "1:4", "--chunk", "2")),
    ("shot.clips/shot.0001.3-4.usdc", ("bake", "fish.usda", "-o", "shot.usda", "--frames", "1:4", "--chunk", "2",
                                       "--chunk-index", "1")),
    ("fr/f.0001.exr", ("render", "fish.usda", "--camera", "/Blowfish/Camera", "--frames", "1:1",
                       "-o", "fr/f.####.exr", "--size", "32x20")),
], ids=["chunk", "manifest", "chunk-task", "render-frame"])
def test_a_file_painterly_names_itself_never_overwrites_the_input_through_a_link(tmp_path, derived, command):
    """A chunk, the manifest or a rendered frame whose name is a link to the
    input was written through the link: the input became a crate file,
    exit 0 (found by a files-and-signals review, 2026-12-06). Such a write
    is refused now, naming the file it would overwrite."""
    src = tmp_path / "fish.usda"
    shutil.copy(BLOWFISH, src)
    link = tmp_path / derived
    link.parent.mkdir()
    link.symlink_to(os.path.relpath(src, link.parent))
    proc = subprocess.run([str(painterly_binary()), *command, "-q"], capture_output=True, text=True,
                          timeout=HANG, cwd=tmp_path)
    expect_error(proc, 1, f"would overwrite {src.resolve()}, a file the input reads")
    assert src.read_bytes() == BLOWFISH.read_bytes()
    assert leftovers(tmp_path) == [] and leftovers(link.parent) == []


def test_a_signal_while_a_chunked_rebake_publishes_leaves_no_mix_of_old_and_new_chunks(tmp_path):
    """SIGTERM as soon as the first new chunk is renamed into place: the
    renames went on one by one until the signal thread exited between two,
    leaving 22 to 44 of 471 chunks new under the old clip set (found by a
    files-and-signals review, 2026-12-06). Now every target is checked
    before the first rename and the signal waits for the last one and the
    clip set: all chunks are new, and the clip set is the new one."""
    src = tmp_path / "fish.usda"
    shutil.copy(BLOWFISH, src)
    args = [str(painterly_binary()), "bake", str(src), "-o", str(tmp_path / "shot.usda"), "--frames", "1:48:0.1",
            "--chunk", "1", "-q"]
    assert subprocess.run(args, timeout=HANG).returncode == 0
    clips = tmp_path / "shot.clips"

    def chunks():
        return {e.name: e.inode() for e in os.scandir(clips) if re.match(r"shot\.\d{4}\..*\.usdc$", e.name)}

    layer = Sdf.Layer.FindOrOpen(str(src))
    layer.customLayerData = {"rev": 1}  # the input changes: every chunk is re-baked
    layer.Save()
    old = chunks()
    proc = subprocess.Popen(args, stderr=subprocess.PIPE, text=True)
    signalled = False
    deadline = time.monotonic() + HANG
    while proc.poll() is None and time.monotonic() < deadline:
        if any(e.inode() != old.get(e.name) for e in os.scandir(clips) if e.name in old):
            proc.send_signal(signal.SIGTERM)
            signalled = True
            break
    err = proc.communicate(timeout=HANG)[1]
    now = chunks()
    replaced = sum(now[k] != v for k, v in old.items())
    assert replaced in (0, len(old)), f"{replaced} of {len(old)} chunks new (exit {proc.returncode}): {err}"
    if signalled:
        assert proc.returncode in (0, 143), err
        assert replaced == len(old)
        clip_set = Sdf.Layer.OpenAsAnonymous(str(tmp_path / "shot.usda")).customLayerData["painterly"]
        first = Sdf.Layer.OpenAsAnonymous(str(clips / sorted(now)[0])).customLayerData["painterly"]
        assert clip_set["inputHash"] == first["inputHash"]
    assert leftovers(tmp_path) == [] and leftovers(clips) == []


@pytest.mark.parametrize("name", ["tab\tshot", "nl\nshot", "at@shot"])
def test_a_path_usd_cannot_hold_as_an_asset_path_is_refused(tmp_path, name):
    """A tab or newline in a file's name went verbatim into the edit
    layer's subLayers, the view layer's subLayers and the clip set's
    assetPaths: exit 0, and usd-core could not open any of them (found by a
    files-and-signals review, 2026-12-06). '@' was refused by the edit and
    view layers only. All three writers refuse all three now; a plain bake,
    which writes no asset path, still works with such names."""
    src = tmp_path / f"{name}.usda"
    shutil.copy(BLOWFISH, src)
    bake = tmp_path / f"{name}.usdc"
    assert run("bake", src, "-o", bake, "--frames", "1:2", "-q").returncode == 0
    for args, out in [
        (("key", src, "--layer", "/Blowfish/Paint/Hair", "--time", "2", "--sentinel", "--edit-layer",
          tmp_path / "e.usda"), tmp_path / "e.usda"),
        (("view", src, "--bake", bake, "-o", tmp_path / "v.usda"), tmp_path / "v.usda"),
        (("bake", tmp_path / "ok.usda", "-o", tmp_path / f"{name}_shot.usda", "--frames", "1:4", "--chunk", "2"),
         tmp_path / f"{name}_shot.usda"),
    ]:
        shutil.copy(BLOWFISH, tmp_path / "ok.usda")
        proc = run(*args, "-q")
        expect_error(proc, 1, "which a USD asset path cannot hold")
        assert not out.exists()
    assert src.read_bytes() == BLOWFISH.read_bytes()
    assert leftovers(tmp_path) == []


def test_an_edit_layer_that_is_a_fifo_is_refused_not_waited_on(tmp_path):
    """`key --edit-layer FIFO` read the FIFO before looking at what it was
    and hung for ever (found by a files-and-signals review, 2026-12-06);
    the same FIFO as the input was refused at once."""
    src = tmp_path / "fish.usda"
    shutil.copy(BLOWFISH, src)
    fifo = tmp_path / "e.usda"
    os.mkfifo(fifo)
    proc = run("key", src, "--layer", "/Blowfish/Paint/Hair", "--time", "2", "--sentinel", "--edit-layer", fifo, "-q")
    expect_error(proc, 1, "cannot open the layer: not a regular file", "e.usda")
    assert src.read_bytes() == BLOWFISH.read_bytes()


def test_a_layer_the_stage_names_that_is_a_fifo_fails_instead_of_hanging(tmp_path):
    """A sublayer or reference naming a FIFO hung every command that opened
    the stage (openusd opens each layer with a plain blocking `open`; found
    in the twenty-second session). Layers are now opened without blocking and
    refused unless regular files, in the CLI and the Python API alike."""
    import sys
    shutil.copy(BLOWFISH, tmp_path / "fish.usda")
    os.mkfifo(tmp_path / "pipe.usda")
    (tmp_path / "sub.usda").write_text('#usda 1.0\n(\n    subLayers = [@./pipe.usda@, @./fish.usda@]\n)\n')
    (tmp_path / "ref.usda").write_text(
        '#usda 1.0\n(\n    subLayers = [@./fish.usda@]\n)\ndef "Extra" (references = @./pipe.usda@)\n{\n}\n')
    # An entry of a package that is a FIFO: the lookup of the entry opened it.
    os.mkfifo(tmp_path / "pipe.usdz")
    (tmp_path / "pkg.usda").write_text('#usda 1.0\n(\n    subLayers = [@./pipe.usdz[a.usda]@, @./fish.usda@]\n)\n')
    # A package that is a folder keeps its own words.
    (tmp_path / "dir.usdz").mkdir()
    (tmp_path / "dirpkg.usda").write_text('#usda 1.0\n(\n    subLayers = [@./dir.usdz[a.usda]@, @./fish.usda@]\n)\n')
    proc = subprocess.run([str(painterly_binary()), "bake", "dirpkg.usda", "-o", "out.usdc"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=30)
    assert (proc.returncode, proc.stderr) == (1, f"error: dirpkg.usda: missing asset: sublayer @./dir.usdz[a.usda]@ "
                                                 f"(in {tmp_path / 'dirpkg.usda'}): cannot be read: it is a folder, not a file\n")
    pipe = f"@{tmp_path / 'pipe.usda'}@"
    why = "cannot be read: not a regular file (a FIFO, device or socket)"
    run_in = {"cwd": tmp_path, "capture_output": True, "text": True, "timeout": 30}
    for top, listed, said in [
        ("sub.usda", f"sublayer {pipe} (in {tmp_path / 'sub.usda'}): {why}",
         f"sublayer {pipe} (in {tmp_path / 'sub.usda'}): {why}"),
        ("ref.usda", f"/Extra: missing asset: reference {pipe} (in {tmp_path / 'ref.usda'}): {why}",
         f"reference {pipe} on /Extra (in {tmp_path / 'ref.usda'}): {why}"),
        ("pkg.usda", f"sublayer @./pipe.usdz[a.usda]@ (in {tmp_path / 'pkg.usda'}): {why}",
         f"sublayer @./pipe.usdz[a.usda]@ (in {tmp_path / 'pkg.usda'}): {why}"),
    ]:
        # inspect lists a stage's problems on stdout, and exits 1.
        proc = subprocess.run([str(painterly_binary()), "inspect", top], **run_in)
        assert proc.returncode == 1 and f"{listed}\n" in proc.stdout, proc
        proc = subprocess.run([str(painterly_binary()), "bake", top, "-o", "out.usdc", "--frames", "1"], **run_in)
        assert (proc.returncode, proc.stderr) == (1, f"error: {top}: missing asset: {said}\n")
        code = f"import painterly\npainterly.Character({str(tmp_path / top)!r})"
        proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=30)
        assert proc.returncode == 1 and said in proc.stderr, proc.stderr
    assert not (tmp_path / "out.usdc").exists()
    assert (tmp_path / "fish.usda").read_bytes() == BLOWFISH.read_bytes()


def rewrite_in_place(src, stop):
    """Rewrites the file `src` in place until `stop` is set, as `cp` over it
    does: truncated, then written again 4 KiB at a time."""
    data = open(src, "rb").read()
    while not stop.is_set():
        with open(src, "r+b") as f:
            f.truncate(0)
            for i in range(0, len(data), 4096):
                f.write(data[i:i + 4096])
                f.flush()
        time.sleep(0.001)


def test_an_input_cut_short_while_a_bake_reads_it_is_an_error_not_a_bus_error(tmp_path):
    """A program rewriting a `.usdc` input in place (truncate, then write,
    as `cp` does) while bakes read it: 59 of 100 bakes died of SIGBUS (a
    read past the new end of the mapped file) and 29 said "openusd 0.8
    crashed composing this stage" (found in the twenty-second session).
    Each now ends with exit 0 or 1 and a message that says the file
    changed, naming it, and leaves no temporary."""
    import threading
    src = tmp_path / "in.usdc"
    Usd.Stage.Open(str(BLOWFISH)).Export(str(src))
    stop = threading.Event()
    writer = threading.Thread(target=rewrite_in_place, args=(src, stop))
    writer.start()
    outcomes = []
    try:
        for _ in range(100):
            proc = subprocess.run([str(painterly_binary()), "bake", src, "-o", tmp_path / "out.usdc",
                                   "--frames", "1", "-q"], capture_output=True, text=True, timeout=HANG)
            outcomes.append((proc.returncode, proc.stderr))
    finally:
        stop.set()
        writer.join()
    said = {
        f"error: {src}: was cut short while painterly read it (rewritten in place during this run?): what "
        "was read is not what the file now holds; run again once it is saved\n",
        f"error: {src}: changed while painterly read it (saved during this run?): what was read is not what "
        "the file now holds; run again once it is saved",
        # Read while empty or nearly: a damaged file, for all anyone can see.
        f"error: {src}: cannot read USD file: ",
    }
    for code, err in outcomes:
        assert code == 0 and err == "" or code == 1 and any(err.startswith(m) for m in said), (code, err)
    assert leftovers(tmp_path) == []


CUT_SHORT_IN_PYTHON = """
import sys, threading, time
import painterly
src, out = sys.argv[1], sys.argv[2]
stop = threading.Event()
writer = threading.Thread(target=rewrite_in_place, args=(src, stop))
writer.start()
try:
    for i in range(int(sys.argv[3])):
        for call in (lambda: painterly.bake(src, out, frames=(1, 1)), lambda: painterly.inspect(src)):
            try:
                call()
                print("ok")
            except painterly.Error as e:
                print("error:", str(e).replace(chr(10), " "))
finally:
    stop.set()
    writer.join()
"""


def test_an_input_cut_short_under_a_python_bake_is_an_error_not_the_end_of_python(tmp_path):
    """The Python package's bake and inspect read a file as the CLI does,
    which mapped it: a program rewriting the file in place under them cut
    the mapping short and the bus error ended the Python process (no
    handler of painterly's runs there; found in the twenty-third session).
    Files are now read whole in Python: each call succeeds or raises
    painterly.Error saying what is wrong with the file."""
    import sys
    src = tmp_path / "in.usdc"
    Usd.Stage.Open(str(BLOWFISH)).Export(str(src))
    import inspect
    child = inspect.getsource(rewrite_in_place) + CUT_SHORT_IN_PYTHON
    proc = subprocess.run([sys.executable, "-c", child, src, tmp_path / "out.usdc", "50"],
                          capture_output=True, text=True, timeout=HANG)
    assert proc.returncode == 0, (proc.returncode, proc.stderr[-2000:])
    said = ("ok", f"error: {src}: changed while painterly read it (saved during this run?)",
            f"error: {src}: cannot read USD file: ")
    lines = proc.stdout.splitlines()
    assert len(lines) == 100 and all(line.startswith(said) for line in lines), lines
    assert leftovers(tmp_path) == []


def test_a_clips_lock_that_is_a_fifo_is_refused_not_waited_on(tmp_path):
    """A FIFO at a chunked bake's lock (`shot.clips/shot.lock`) hung the
    bake (opened for writing, blocking; found by a review, 2026-12-07)."""
    (tmp_path / "shot.clips").mkdir()
    lock = tmp_path / "shot.clips" / "shot.lock"
    os.mkfifo(lock)
    for extra in ([], ["--chunk-index", "0"]):
        proc = subprocess.run([str(painterly_binary()), "bake", BLOWFISH, "-o", tmp_path / "shot.usda",
                               "--chunk", "12", *extra, "-q"], capture_output=True, text=True, timeout=30)
        assert (proc.returncode, proc.stderr) == (
            1, f"error: {lock}: cannot open the clips folder's lock: not a regular file (a FIFO, device or socket)\n")


def test_a_fifo_swapped_in_for_the_edit_layer_never_blocks_the_edit(tmp_path):
    """Another process swaps the existing edit layer between a regular file
    and a FIFO (atomic renames) while `key --edit-layer` runs: 16 of 40 edits
    hung, each at one of the opens that followed a check of the file's type
    (found by a review, 2026-12-07). Every open of an input is now
    non-blocking and checks the opened file: each edit ends, exit 0 or 1."""
    import multiprocessing
    tube = REPO / "fixtures" / "tube.usda"
    shutil.copy(tube, tmp_path / "in.usda")
    base = ["key", tmp_path / "in.usda", "--layer", "/Tube/Paint/Rings", "--time-key", "-q"]
    assert run(*base, "--time", "2", "--name", "t0", "--edit-layer", tmp_path / "R.usda").returncode == 0

    def swap(folder):
        i = 0
        while True:
            i += 1
            os.link(folder / "R.usda", folder / f"r{i}.tmp")
            os.rename(folder / f"r{i}.tmp", folder / "E.usda")
            os.mkfifo(folder / f"f{i}.tmp")
            os.rename(folder / f"f{i}.tmp", folder / "E.usda")

    swapper = multiprocessing.get_context("fork").Process(target=swap, args=(tmp_path,), daemon=True)
    swapper.start()
    codes, hung = [], 0
    try:
        for n in range(30):
            cmd = [str(painterly_binary()), *map(str, base), "--time", "3", "--name", f"k{n}",
                   "--edit-layer", str(tmp_path / "E.usda")]
            p = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
            try:
                err = p.communicate(timeout=20)[1]
            except subprocess.TimeoutExpired:
                hung += 1
                p.kill()
                p.communicate()
                continue
            assert "panicked" not in err, err
            codes.append(p.returncode)
    finally:
        swapper.kill()
        swapper.join()
    assert hung == 0, f"{hung} of 30 edits hung"
    assert set(codes) <= {0, 1}, codes
    assert (tmp_path / "in.usda").read_bytes() == tube.read_bytes()


@pytest.mark.parametrize("ext", ["usda", "usdc"])
def test_two_in_place_edits_at_once_never_lose_one(tmp_path, ext):
    """Two `key --in-place` runs on one file at once both exited 0 and the
    later rename threw the other's sentinel away, in 10 of 10 runs (found by
    a files-and-signals review, 2026-12-06). An edit now locks the file it
    replaces and checks, just before writing, that it is the version it
    read: either both edits land, or one is refused with exit 1."""
    src = tmp_path / f"fish.{ext}"
    for _ in range(5):
        Sdf.Layer.FindOrOpen(str(BLOWFISH)).Export(str(src))
        procs = [subprocess.Popen([str(painterly_binary()), "key", str(src), "--layer", layer, "--time", t,
                                   "--sentinel", "--in-place", "-q"], stderr=subprocess.PIPE, text=True)
                 for layer, t in (("/Blowfish/Paint/Hair", "5"), ("/Blowfish/Paint/Spikes", "9"))]
        results = [(p.wait(timeout=HANG), p.stderr.read()) for p in procs]
        stage = Usd.Stage.Open(Sdf.Layer.OpenAsAnonymous(str(src)))
        for (code, err), prim in zip(results, ("/Blowfish/Paint/Hair/sentinel1", "/Blowfish/Paint/Spikes/sentinel1")):
            if code == 0:
                assert stage.GetPrimAtPath(prim).IsValid(), f"{prim}: its edit exited 0 and was lost"
            else:
                assert code == 1 and ("another painterly edit of this file is running" in err
                                      or "the file changed" in err), err
        assert leftovers(tmp_path) == []


@pytest.mark.parametrize("ext", ["usda", "usdc"])
def test_two_edits_creating_one_edit_layer_at_once_never_lose_one(tmp_path, ext):
    """Two `key --edit-layer E` runs with E not there yet both exited 0
    and E held one of the two keys (25 of 30 tries; a concurrency review,
    2026-12-07): a new layer had no lock, and the later rename replaced
    the first. A new layer now takes its place only if nothing is there:
    either both edits land, or one is refused with exit 1."""
    src, edit = tmp_path / "fish.usda", tmp_path / f"E.{ext}"
    shutil.copy(BLOWFISH, src)
    for _ in range(8):
        edit.unlink(missing_ok=True)
        procs = [subprocess.Popen([str(painterly_binary()), "key", str(src), "--layer", "/Blowfish/Paint/Hair",
                                   "--time", t, "--time-key", "--name", name, "--edit-layer", str(edit), "-q"],
                                  stderr=subprocess.PIPE, text=True)
                 for name, t in (("ta", "2"), ("tb", "3"))]
        results = [(p.wait(timeout=HANG), p.stderr.read()) for p in procs]
        layer = Sdf.Layer.OpenAsAnonymous(str(edit))
        for (code, err), name in zip(results, ("ta", "tb")):
            if code == 0:
                assert layer.GetPrimAtPath(f"/Blowfish/Paint/Hair/{name}"), f"{name}: its edit exited 0 and was lost"
            else:
                assert code == 1 and err in (
                    f"error: {edit}: another process created this file while this edit ran; nothing was written: "
                    "run the edit again to add it to that file\n",
                    f"error: {edit}: another painterly edit of this file is running: "
                    "run this one when it has finished\n"), err
        assert src.read_bytes() == BLOWFISH.read_bytes()
        assert leftovers(tmp_path) == []


def test_an_edit_layer_created_while_an_edit_reads_its_input_is_locked_and_checked(tmp_path):
    """usd-core creates the edit layer while `key --edit-layer E` reads its
    input (E was not there when it started), then saves into it. The edit
    found E, had neither lock nor check (both were decided before the
    input was read) and replaced usd-core's save with exit 0 (26 of 100
    tries; the verification of a concurrency fix, 2026-12-07). E is now
    locked and identified when it is found."""
    import random

    src, edit = tmp_path / "in.usda", tmp_path / "E.usda"
    shutil.copy(BLOWFISH, src)
    lost = []
    rng = random.Random(7)
    for i in range(20):
        edit.unlink(missing_ok=True)
        made = Sdf.Layer.CreateAnonymous(".usda")
        made.subLayerPaths.append("./in.usda")
        Sdf.CreatePrimInLayer(made, "/U1")
        proc = subprocess.Popen([str(painterly_binary()), "key", str(src), "--layer", "/Blowfish/Paint/Hair",
                                 "--time", "2", "--time-key", "--name", "ta", "--edit-layer", str(edit), "-q"],
                                stderr=subprocess.PIPE, text=True)
        time.sleep(rng.uniform(0.005, 0.045))
        assert made.Export(str(edit))
        time.sleep(rng.uniform(0.005, 0.05))
        layer = Sdf.Layer.FindOrOpen(str(edit))
        layer.Reload(True)
        Sdf.CreatePrimInLayer(layer, "/U2")
        assert layer.Save()
        del layer
        code, err = proc.wait(timeout=HANG), proc.stderr.read()
        after = Sdf.Layer.OpenAsAnonymous(str(edit))
        if code == 0 and after.GetPrimAtPath("/Blowfish/Paint/Hair/ta") and not (
                after.GetPrimAtPath("/U1") and after.GetPrimAtPath("/U2")):
            lost.append(i)
        elif code != 0:
            assert code == 1, err
        assert leftovers(tmp_path) == []
    assert lost == [], f"tries {lost}: the edit exited 0 over a save it never read"


def test_a_new_edit_layer_named_through_a_dangling_link_replaces_the_link(tmp_path):
    """`latest.usda -> v003/E.usda` before v003/E.usda exists: the edit
    writes latest.usda as a file, as usd-core's save does. The first
    no-replace publish saw the link's name as taken and refused every time,
    blaming another process."""
    src = tmp_path / "in.usda"
    shutil.copy(BLOWFISH, src)
    (tmp_path / "v003").mkdir()
    link = tmp_path / "latest.usda"
    link.symlink_to("v003/E.usda")
    proc = run("key", src, "--layer", "/Blowfish/Paint/Hair", "--time", "2", "--time-key", "--name", "ta",
               "--edit-layer", link, "-q")
    assert (proc.returncode, proc.stderr) == (0, "")
    assert not link.is_symlink()
    assert Sdf.Layer.OpenAsAnonymous(str(link)).GetPrimAtPath("/Blowfish/Paint/Hair/ta")
    assert leftovers(tmp_path) == []


def test_an_in_place_edit_never_replaces_a_save_made_while_it_ran(tmp_path):
    """usd-core saves the file while `key --in-place` runs. The edit
    checked the file before splicing and writing, about 40 ms before its
    rename: a save in that gap was replaced with exit 0 (23 of 60 tries; a
    concurrency review, 2026-12-07). The check now runs again just before
    the rename: whenever the edit exits 0, the save it read over is in the
    file or came after it."""
    import random

    src = tmp_path / "fish.usda"
    lost = []
    for i in range(16):
        for p in tmp_path.iterdir():
            p.unlink()
        shutil.copy(BLOWFISH, src)
        layer = Sdf.Layer.FindOrOpen(str(src))
        layer.Reload(True)
        Sdf.CreatePrimInLayer(layer, "/UsdCoreEdit")
        proc = subprocess.Popen([str(painterly_binary()), "key", str(src), "--layer", "/Blowfish/Paint/Hair",
                                 "--time", "2", "--time-key", "--name", "ta", "--in-place", "-q"],
                                stderr=subprocess.PIPE, text=True)
        time.sleep(random.Random(i).uniform(0.0, 0.15))
        assert layer.Save()
        code, err = proc.wait(timeout=HANG), proc.stderr.read()
        del layer
        after = Sdf.Layer.OpenAsAnonymous(str(src))
        if code == 0 and not after.GetPrimAtPath("/UsdCoreEdit"):
            # The edit's rename came after the save: it replaced a version
            # it never read, unless usd-core's save came after the rename
            # (then the key is what is missing: usd-core's own lost update).
            if after.GetPrimAtPath("/Blowfish/Paint/Hair/ta"):
                lost.append(i)
        elif code != 0:
            assert code == 1 and "the file changed since this edit read it" in err, err
        assert leftovers(tmp_path) == []
    assert lost == [], f"tries {lost}: the edit exited 0 over a save it never read"


def test_a_render_stops_when_a_file_it_reads_is_saved_while_it_runs(tmp_path):
    """README Limits: a file saved while a render reads it ends the run
    with `changed while painterly read it`. The render checked its input
    once, before its first frame: an input saved mid-render gave exit 0
    with frames of both versions (a concurrency review, 2026-12-07)."""
    src = tmp_path / "fish.usda"
    shutil.copy(BLOWFISH, src)
    out = tmp_path / "frames"
    out.mkdir()
    proc = subprocess.Popen([str(painterly_binary()), "render", str(src), "--camera", "/Blowfish/Camera",
                             "-o", str(out / "f.####.exr"), "--frames", "1:48", "--size", "640x360", "-q"],
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + HANG
    while not list(out.glob("*.exr")) and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    layer = Sdf.Layer.FindOrOpen(str(src))
    layer.customLayerData = {"saved": "mid-render"}
    assert layer.Save()
    code, err = proc.wait(timeout=HANG), proc.stderr.read()
    assert (code, err) == (1, (
        f"error: {src}: changed while painterly read it (saved during this run?): what was read is not what "
        "the file now holds; run again once it is saved\n"))
    assert len(list(out.glob("*.exr"))) < 48


def test_an_edit_of_a_file_another_edit_holds_is_refused(tmp_path):
    import fcntl

    src = tmp_path / "fish.usda"
    shutil.copy(BLOWFISH, src)
    with open(src) as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        proc = run("key", src, "--layer", "/Blowfish/Paint/Hair", "--time", "5", "--sentinel", "--in-place", "-q")
        expect_error(proc, 1, "another painterly edit of this file is running: run this one when it has finished")
    assert src.read_bytes() == BLOWFISH.read_bytes()
    assert run("key", src, "--layer", "/Blowfish/Paint/Hair", "--time", "5", "--sentinel", "--in-place",
               "-q").returncode == 0


def test_an_edit_layer_in_a_folder_whose_name_is_not_utf8_is_named(tmp_path):
    """The error named the scratch file beside the edit layer
    (`.e.usda.painterly-….scratch.usda`), a file the user never named (an
    error-message review, 2026-12-07)."""
    folder = tmp_path / os.fsdecode(b"dir\xfd")
    folder.mkdir()
    edit = folder / "e.usda"
    proc = run("smudge", BLOWFISH, "--layer", "/Blowfish/Paint/Hair", "--path", "3,6,-2 6,6,-1.5",
               "--radius", "1", "--strength", "0.2", "--edit-layer", edit)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.startswith("error: ") and proc.stderr.rstrip().endswith(
        "e.usda: the edit layer's path is not valid UTF-8 (USD reads layers by UTF-8 paths): name it another way"), proc.stderr
    assert "scratch" not in proc.stderr
    assert list(folder.iterdir()) == []


@pytest.mark.parametrize("through_link", [False, True])
def test_an_output_that_is_no_regular_file_is_refused_not_replaced(tmp_path, through_link):
    """An output that was a FIFO or a device (or a link to one) was replaced
    by a regular file: `-o null.usda` linked to /dev/null replaced /dev/null
    itself (an I/O review, 2026-12-07). A FIFO stands in for the device."""
    fifo = tmp_path / "pipe.usda"
    os.mkfifo(fifo)
    target = fifo
    if through_link:
        target = tmp_path / "out.usda"
        target.symlink_to(fifo)
    proc = run("bake", BLOWFISH, "-o", target, "--frames", "1:2", "-q")
    assert (proc.returncode, proc.stderr) == (1, (
        f"error: {fifo}: cannot write over something that is not a regular file (a device, FIFO or socket): "
        "name a file to write\n"))
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted({"pipe.usda", target.name})


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
def test_a_full_stderr_ends_in_exit_1_not_an_abort(tmp_path):
    """With stderr on a full device, the first `-v` line or error panicked,
    and the panic hook's own eprintln! panicked again: SIGABRT, exit 134,
    no message anywhere (an I/O review, 2026-12-07)."""
    with open("/dev/full", "w") as full:
        proc = subprocess.run([str(painterly_binary()), "bake", str(BLOWFISH), "-o", str(tmp_path / "b.usdc"),
                               "--frames", "1:2", "-v"], stdout=subprocess.PIPE, stderr=full, timeout=HANG)
        assert proc.returncode == 1
        proc = subprocess.run([str(painterly_binary()), "inspect", str(tmp_path / "missing.usda")],
                              stdout=subprocess.PIPE, stderr=full, timeout=HANG)
        assert proc.returncode == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == []


def test_json_refuses_a_file_name_that_is_not_utf8_before_any_work(tmp_path):
    """`bake -o $'\\xfc.usda' --json` baked, then printed an empty line and
    exited 0 (JSON strings cannot hold the name). Refused up front, exit 2;
    without --json the same bake runs."""
    out = os.path.join(os.fsencode(tmp_path), b"\xfc.usda")
    exe = os.fsencode(painterly_binary())
    proc = subprocess.run([exe, b"bake", os.fsencode(BLOWFISH), b"-o", out, b"--frames", b"1:2", b"--json"],
                          capture_output=True, timeout=HANG)
    assert (proc.returncode, proc.stdout) == (2, b"")
    assert proc.stderr == (b"error: --json names files in UTF-8, and " + os.fsencode(tmp_path) +
                           "/\ufffd.usda is not: rename it, or run without --json\n".encode())
    assert os.listdir(tmp_path) == []
    proc = subprocess.run([exe, b"bake", os.fsencode(BLOWFISH), b"-o", out, b"--frames", b"1:2", b"-q"],
                          capture_output=True, timeout=HANG)
    assert proc.returncode == 0 and os.listdir(os.fsencode(tmp_path)) == [b"\xfc.usda"]


@pytest.mark.skipif(os.geteuid() != 0, reason="mounting a file system needs root")
def test_a_read_only_file_system_is_named_not_blamed_on_permissions(tmp_path):
    """On a read-only mount, `--in-place` said "cannot replace a file this
    user may not write (mode 644): change its permissions first", advice
    that cannot help (an I/O review, 2026-12-07)."""
    mnt = tmp_path / "ro"
    mnt.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=4m", "tmpfs", str(mnt)]).returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:
        rig = mnt / "fish.usda"
        shutil.copy(BLOWFISH, rig)
        assert subprocess.run(["mount", "-o", "remount,ro", str(mnt)]).returncode == 0
        proc = run("key", rig, "--layer", "/Blowfish/Paint/Hair", "--time", "5", "--sentinel", "--in-place", "-q")
        assert (proc.returncode, proc.stderr) == (
            1, f"error: {rig}: cannot replace the file: Read-only file system (os error 30)\n")
        assert rig.read_bytes() == BLOWFISH.read_bytes()
    finally:
        subprocess.run(["umount", str(mnt)])


def test_a_folder_with_a_bracket_in_its_name_is_a_folder(tmp_path):
    """`take[2]/shot.usda` was read as a layer inside a package `take`: the
    list of files the input reads came out empty, so `-o` over its sublayer
    replaced it with exit 0, and no saved file was ever noticed (a
    verification review, 2026-12-07). usd-core's Ar.IsPackageRelativePath
    is false there."""
    take = tmp_path / "take[2]"
    take.mkdir()
    shutil.copy(BLOWFISH, take / "body.usda")
    (take / "shot.usda").write_text("#usda 1.0\n(\n    subLayers = [@./body.usda@]\n)\n")
    before = (take / "body.usda").read_bytes()
    proc = run("bake", take / "shot.usda", "-o", take / "body.usda", "--frames", "1:2", "-q")
    assert (proc.returncode, proc.stderr) == (1, (
        f"error: {take / 'body.usda'}: output would overwrite {take / 'body.usda'}, a file the input reads; "
        "inputs are never modified\n"))
    assert (take / "body.usda").read_bytes() == before
    # The bake records a stamp of the file it read: view finds it unchanged.
    assert run("bake", take / "shot.usda", "-o", tmp_path / "b.usda", "--frames", "1:2", "-q").returncode == 0
    view = run("view", take / "shot.usda", "--bake", tmp_path / "b.usda", "-o", tmp_path / "v.usda")
    assert view.returncode == 0 and "changed since" not in view.stderr, view.stderr
    (take / "body.usda").write_bytes(before + b"\n")
    view = run("view", take / "shot.usda", "--bake", tmp_path / "b.usda", "-o", tmp_path / "v2.usda")
    assert view.returncode == 0 and "changed since this bake was made" in view.stderr, view.stderr
