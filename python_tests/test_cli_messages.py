"""What a new user reads (issue 13): errors that say what is wrong, counts
in words, a --verbose log of phases, no silent no-op edits."""

import json
import pathlib

import pytest


def test_key_on_a_missing_layer_says_it_does_not_exist(painterly, tmp_path, repo_root):
    proc = painterly(
        "key", repo_root / "fixtures" / "blowfish.usda", "--layer", "/Blowfish/Paint/Nope", "--time", "3",
        "--edit-layer", tmp_path / "e.usda", check=False,
    )
    assert proc.returncode == 1
    assert "/Blowfish/Paint/Nope: prim does not exist" in proc.stderr
    assert not (tmp_path / "e.usda").exists()


def test_key_on_a_prim_that_is_not_a_layer(painterly, tmp_path, repo_root):
    proc = painterly(
        "key", repo_root / "fixtures" / "blowfish.usda", "--layer", "/Blowfish/Paint", "--time", "3",
        "--edit-layer", tmp_path / "e.usda", check=False,
    )
    assert proc.returncode == 1
    assert "/Blowfish/Paint: is not a stroke layer" in proc.stderr


@pytest.mark.parametrize("brush", ["smudge", "expand"])
def test_a_brush_that_moves_nothing_writes_nothing(painterly, tmp_path, repo_root, brush):
    edit = tmp_path / "e.usda"
    proc = painterly(
        brush, repo_root / "fixtures" / "blowfish.usda", "--layer", "/Blowfish/Paint/Hair",
        "--path", "0,1,0 1,1.2,0", "--radius", "0.5", "--strength", "0.2", "--edit-layer", edit, check=False,
    )
    assert proc.returncode == 1
    assert "nothing changed, nothing written" in proc.stderr and "/Blowfish/Paint/Hair" in proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_counts_in_words(painterly, tmp_path, repo_root):
    out = painterly("bake", repo_root / "fixtures" / "tube.usda", "-o", tmp_path / "b.usdc", "--frames", "3")
    assert out.stdout.startswith("baked 1 frame: 2 layers, 50 strokes, 450 points, 0 view-dependent meshes -> ")


def test_verbose_logs_phases_on_stderr_only(painterly, tmp_path, repo_root):
    out = painterly("-v", "bake", repo_root / "fixtures" / "tube.usda", "-o", tmp_path / "b.usdc", "--json")
    json.loads(out.stdout)
    lines = out.stderr.splitlines()
    assert [l.split()[1] for l in lines] == ["opened", "read", "bound", "24"], lines
    assert "read 1 rig, 2 stroke layers, 0 view-dependent meshes in" in lines[1]
    assert "bound 450 stroke points (rest data of 194 proxy vertices) in" in lines[2]
    assert lines[3].startswith("painterly: 24 frames: read ") and "evaluate" in lines[3] and "write" in lines[3]
    quiet = painterly("bake", repo_root / "fixtures" / "tube.usda", "-o", tmp_path / "c.usdc", "--json")
    assert quiet.stderr == ""
    # The layer count is the stage's: a shot sublayering the tube and a
    # referenced prop has three (usd-core: len(stage.GetUsedLayers()) minus the session layer).
    (tmp_path / "tube.usda").write_bytes((repo_root / "fixtures" / "tube.usda").read_bytes())
    (tmp_path / "prop.usda").write_text('#usda 1.0\ndef Xform "Prop"\n{\n}\n')
    shot = tmp_path / "shot.usda"
    shot.write_text('#usda 1.0\n(\n    subLayers = [@./tube.usda@]\n)\n'
                    'def "Set" (references = @./prop.usda@</Prop>)\n{\n}\n')
    from pxr import Usd

    stage = Usd.Stage.Open(str(shot))
    used = [l for l in stage.GetUsedLayers() if not l.identifier.startswith("anon:")]
    assert len(used) == 3
    out = painterly("-v", "bake", shot, "-o", tmp_path / "d.usdc", "--frames", "1:2", "--quiet")
    assert f"opened {shot} (3 layers) in " in out.stderr.splitlines()[0]


def test_interpolate_is_listed_in_help(painterly):
    assert "interpolate" in painterly("--help").stdout


EDIT_FIELDS = {"command", "input", "written", "in_place", "layers", "points", "key", "message"}


def _points(path, prim):
    """A layer's rest points (painterly:restPoints, else points), as brushes edit them."""
    import numpy as np
    from pxr import Usd

    stage = Usd.Stage.Open(str(path))
    p = stage.GetPrimAtPath(prim)
    rest = p.GetAttribute("painterly:restPoints")
    return np.array((rest.Get() if rest.HasAuthoredValue() else None) or p.GetAttribute("points").Get(), dtype=float)


@pytest.mark.parametrize("brush", ["smudge", "expand"])
def test_brush_json_counts_the_points_usd_core_sees_moved(painterly, tmp_path, repo_root, brush):
    import numpy as np

    src, edit, hair = repo_root / "fixtures" / "blowfish.usda", tmp_path / "e.usda", "/Blowfish/Paint/Hair"
    proc = painterly(brush, src, "--layer", hair, "--path", "3,6,-2 6,6,-1.5", "--radius", "1",
                     "--strength", "0.2", "--edit-layer", edit, "--json")
    s = json.loads(proc.stdout)
    assert set(s) == EDIT_FIELDS and proc.stderr == ""
    moved = int(np.count_nonzero(np.any(_points(edit, hair) != _points(src, hair), axis=1)))
    assert moved > 0
    assert s == {"command": brush, "input": str(src), "written": str(edit), "in_place": False, "layers": [hair],
                 "points": moved, "key": None, "message": f"moved {moved} points of {hair} -> {edit}"}


def test_bind_and_key_json(painterly, tmp_path, repo_root):
    from pxr import Usd

    src, edit, hair = repo_root / "fixtures" / "blowfish.usda", tmp_path / "e.usda", "/Blowfish/Paint/Hair"
    s = json.loads(painterly("bind", src, "--layer", hair, "--time", "24", "--edit-layer", edit, "--json").stdout)
    n = len(_points(src, hair))
    assert s == {"command": "bind", "input": str(src), "written": str(edit), "in_place": False, "layers": [hair],
                 "points": n, "key": None, "message": f"bound {n} points in 1 layer -> {edit}"}
    s = json.loads(painterly("key", edit, "--layer", hair, "--time", "6", "--time-key", "--points", "--in-place",
                             "--json").stdout)
    assert set(s) == EDIT_FIELDS and s["in_place"] is True and s["written"] == str(edit)
    assert s["command"] == "key" and s["layers"] == [hair] and s["points"] == 0
    stage = Usd.Stage.Open(str(edit))
    key = stage.GetPrimAtPath(s["key"])
    assert key.IsValid() and key.GetParent().GetPath() == hair


def test_a_closed_pipe_ends_quietly(painterly, repo_root):
    import subprocess

    from conftest import painterly_binary

    # The reader closes the pipe after one byte; inspect --json has pages more to print.
    proc = subprocess.run(
        f"'{painterly_binary()}' inspect --json '{repo_root / 'fixtures' / 'blowfish.usda'}' | head -c 1 >/dev/null;"
        " echo ${PIPESTATUS[0]}",
        shell=True, executable="/bin/bash", capture_output=True, text=True, check=True,
    )
    assert proc.stderr == ""
    assert proc.stdout.strip() in {"0", "141"}


@pytest.mark.skipif(not pathlib.Path("/dev/full").exists(), reason="no /dev/full")
def test_a_full_stdout_is_a_failed_write(repo_root):
    """A write to stdout that fails (a full disk) exits 1 naming the stream
    and the reason, as the README's exit codes say, not 3 (a bug)."""
    import subprocess

    from conftest import painterly_binary

    with open("/dev/full", "w") as full:
        proc = subprocess.run([str(painterly_binary()), "inspect", "--json",
                               str(repo_root / "fixtures" / "blowfish.usda")],
                              stdout=full, stderr=subprocess.PIPE, text=True, timeout=60)
    assert proc.returncode == 1
    assert proc.stderr.startswith("error: failed printing to stdout: No space left on device"), proc.stderr
    assert "internal error" not in proc.stderr


@pytest.mark.skipif(not pathlib.Path("/dev/full").exists(), reason="no /dev/full")
@pytest.mark.parametrize("command", [
    ["bind", "{src}", "--in-place", "--json"],
    ["bake", "{src}", "-o", "{out}", "--frames", "1:2"],
    ["render", "{src}", "--camera", "/Blowfish/Camera", "-o", "{frames}", "--frames", "1:2", "--size", "64x36"],
])
def test_a_full_stdout_after_the_write_says_the_file_was_written(repo_root, tmp_path, command):
    """The report fails after the work is saved: exit 1 as before, and the
    message now says the file was written, so a TD does not redo an
    in-place edit that is there (an I/O review's finding, 2026-12-07)."""
    import shutil
    import subprocess

    from conftest import painterly_binary

    src, out, frames = tmp_path / "fish.usda", tmp_path / "fish_bake.usdc", tmp_path / "f.####.exr"
    shutil.copy(repo_root / "fixtures" / "blowfish.usda", src)
    written = {"bind": [src], "bake": [out], "render": [tmp_path / "f.0001.exr", tmp_path / "f.0002.exr"]}[command[0]]
    with open("/dev/full", "w") as full:
        proc = subprocess.run([str(painterly_binary()), *(a.format(src=src, out=out, frames=frames) for a in command)],
                              stdout=full, stderr=subprocess.PIPE, text=True, timeout=120)
    assert proc.returncode == 1
    # The render's own bake, in a temporary folder, is not counted.
    said = (f"({written[0]} was written before it)" if len(written) == 1
            else f"(2 files were written before it, the first {written[0]})")
    assert proc.stderr == f"error: failed printing to stdout: No space left on device (os error 28) {said}\n", proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted({src.name, *(w.name for w in written)})


def test_verbose_times_each_stage_of_the_bake(painterly, repo_root, tmp_path):
    """--verbose's per-stage line: every stage timed, none negative, the
    writer's time not above the whole bake's (it runs inside it)."""
    import re

    proc = painterly("bake", repo_root / "fixtures" / "blowfish.usda", "-o", tmp_path / "b.usdc", "--verbose")
    m = re.search(r"painterly: 48 frames: read ([0-9.]+) s, evaluate ([0-9.]+) s \(summed over threads\), "
                  r"write ([0-9.]+) s; ([0-9.]+) s wall\n", proc.stderr)
    assert m, proc.stderr
    read, evaluate, write, wall = map(float, m.groups())
    total = float(re.search(r"-> .*b\.usdc in ([0-9.]+) s", proc.stdout + proc.stderr).group(1))
    # Writing 48 frames of 17,940 points takes milliseconds, never 0.000 s.
    assert read >= 0 and evaluate > 0 and write > 0 and wall > 0
    assert write <= total + 0.01 and wall <= total + 0.01


def test_bake_refuses_to_write_over_its_input(painterly, tmp_path, repo_root):
    """The input is never modified: an output naming the input (directly or
    through a symlink) is refused before any work, and the input's bytes stay."""
    src = tmp_path / "tube.usda"
    src.write_bytes((repo_root / "fixtures" / "tube.usda").read_bytes())
    link = tmp_path / "link.usda"
    link.symlink_to(src)
    before = src.read_bytes()
    for out in (src, link, tmp_path / "." / "tube.usda"):
        proc = painterly("bake", src, "-o", out, "--frames", "1:2", check=False)
        assert proc.returncode == 1, proc.stderr
        assert proc.stderr.strip() == f"error: {out}: output would overwrite the input; inputs are never modified"
        assert src.read_bytes() == before
        assert sorted(p.name for p in tmp_path.iterdir()) == ["link.usda", "tube.usda"]


def test_no_output_overwrites_a_file_the_input_reads(painterly, tmp_path, repo_root):
    """`bake -o` and `view -o` naming a sublayer or a referenced layer of
    the input, or `view -o` naming the input or the bake, are refused (exit
    1) and every file keeps its bytes; they replaced the layer (exit 0)
    before (found by an edit-fidelity review, 2026-12-06)."""
    (tmp_path / "char.usda").write_bytes((repo_root / "fixtures" / "tube.usda").read_bytes())
    (tmp_path / "prop.usda").write_text('#usda 1.0\n(\n    defaultPrim = "Prop"\n)\ndef Xform "Prop"\n{\n}\n')
    shot = tmp_path / "shot.usda"
    shot.write_text('#usda 1.0\n(\n    subLayers = [@./char.usda@]\n    startTimeCode = 1\n    endTimeCode = 24\n'
                    '    defaultPrim = "Tube"\n)\nover "Tube"\n{\n    def "Prop" (references = @./prop.usda@)\n    {\n    }\n}\n')
    bake = tmp_path / "bake.usdc"
    painterly("bake", shot, "-o", bake, "--frames", "1:2", "--quiet")
    files = sorted(tmp_path.iterdir())
    before = {f: f.read_bytes() for f in files}
    cases = [
        (("bake", shot, "-o", tmp_path / "char.usda"), f"{tmp_path / 'char.usda'}, a file the input reads"),
        (("bake", shot, "-o", tmp_path / "prop.usda"), f"{tmp_path / 'prop.usda'}, a file the input reads"),
        (("view", shot, "--bake", bake, "-o", tmp_path / "char.usda"), f"{tmp_path / 'char.usda'}, a file the input reads"),
        (("view", shot, "--bake", bake, "-o", shot), "the input"),
    ]
    for args, what in cases:
        proc = painterly(*args, check=False)
        assert proc.returncode == 1, (args, proc.stderr)
        assert proc.stderr.strip() == f"error: {args[-1]}: output would overwrite {what}; inputs are never modified"
    # The bake itself, as view's output (view layers are .usda: a .usda bake).
    bake_a = tmp_path / "bake.usda"
    painterly("bake", shot, "-o", bake_a, "--frames", "1:2", "--quiet")
    bake_bytes = bake_a.read_bytes()
    proc = painterly("view", shot, "--bake", bake_a, "-o", bake_a, check=False)
    assert proc.returncode == 1
    assert proc.stderr.strip() == f"error: {bake_a}: output would overwrite the bake layer; the view layer is a new file"
    assert bake_a.read_bytes() == bake_bytes
    assert {f: f.read_bytes() for f in files} == before
    assert sorted(tmp_path.iterdir()) == sorted(files + [bake_a])


def test_a_chunked_output_through_a_symbolic_link_is_refused(painterly, tmp_path, repo_root):
    """Writes go through a link to the file it names, but a clip set's
    chunks sit beside the name given: opened from the linked file, its
    relative clip paths would miss them, so the link is refused."""
    real = tmp_path / "real" / "shot.usda"
    real.parent.mkdir()
    real.write_text("#usda 1.0\n")
    link = tmp_path / "shot.usda"
    link.symlink_to(real)
    proc = painterly("bake", repo_root / "fixtures" / "tube.usda", "-o", link, "--chunk", "5", check=False)
    assert proc.returncode == 1
    assert proc.stderr.strip() == (f"error: {link}: with --chunk the output (the clip-set layer) must not be a "
                                   "symbolic link: name the file it links to")
    assert real.read_text() == "#usda 1.0\n" and sorted(p.name for p in tmp_path.iterdir()) == ["real", "shot.usda"]
    # The file itself is a fine output; and without --chunk the link is written through.
    painterly("bake", repo_root / "fixtures" / "tube.usda", "-o", real, "--chunk", "12", "--quiet")
    assert (real.parent / "shot.clips").is_dir()
    plain = tmp_path / "plain.usda"
    (real.parent / "plain.usda").write_text("#usda 1.0\n")
    plain.symlink_to(real.parent / "plain.usda")
    painterly("bake", repo_root / "fixtures" / "tube.usda", "-o", plain, "--frames", "1:2", "--quiet")
    from pxr import Sdf

    assert plain.is_symlink() and Sdf.Layer.FindOrOpen(str(real.parent / "plain.usda")).customLayerData["painterly"]


def test_bake_names_a_missing_output_folder(painterly, tmp_path, repo_root):
    out = tmp_path / "no" / "such" / "bake.usdc"
    proc = painterly("bake", repo_root / "fixtures" / "tube.usda", "-o", out, check=False)
    assert proc.returncode == 1
    assert proc.stderr.strip() == f"error: {out}: output directory {out.parent} does not exist"
    assert not (tmp_path / "no").exists()


def test_bake_to_a_bare_file_name_writes_in_the_working_folder(painterly, tmp_path, repo_root):
    """`-o bake.usdc` (no folder) is the working folder, which exists."""
    proc = painterly("bake", repo_root / "fixtures" / "tube.usda", "-o", "bake.usdc", "--frames", "1:2", "-q",
                     cwd=tmp_path, check=False)
    assert (proc.returncode, proc.stderr) == (0, "")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bake.usdc"]


@pytest.mark.parametrize("dropped, message", [
    (("startTimeCode", "endTimeCode"), "the stage has no startTimeCode/endTimeCode: pass --frames A:B"),
    (("endTimeCode",), "the stage has a startTimeCode but no endTimeCode: pass --frames A:B"),
    (("startTimeCode",), "the stage has an endTimeCode but no startTimeCode: pass --frames A:B"),
])
def test_a_stage_without_a_frame_range_needs_frames_to_inspect_and_bake(painterly, tmp_path, repo_root,
                                                                       dropped, message):
    """No startTimeCode/endTimeCode, or half a range: inspect and bake
    without --frames both say what to pass (exit 1); with --frames both
    work. (inspect once passed a stage without any range, which bake then
    refused: exit 0 must mean the same bake succeeds.)"""
    text = (repo_root / "fixtures" / "tube.usda").read_text()
    text = "\n".join(l for l in text.splitlines() if not any(f"{d} = " in l for d in dropped)) + "\n"
    src = tmp_path / "norange.usda"
    src.write_text(text)
    assert all(d not in text for d in dropped)
    proc = painterly("inspect", src, "--json", check=False)
    problems = json.loads(proc.stdout)["problems"]
    assert (proc.returncode, proc.stderr) == (1, "")
    assert [p["message"] for p in problems] == [message]
    proc = painterly("inspect", src, "--json", "--frames", "1:3", check=False)
    assert (proc.returncode, proc.stderr, json.loads(proc.stdout)["problems"]) == (0, "", [])
    proc = painterly("bake", src, "-o", tmp_path / "a.usdc", check=False)
    assert proc.returncode == 1
    assert proc.stderr.strip() == f"error: {src}: {message}"
    proc = painterly("bake", src, "-o", tmp_path / "b.usdc", "--frames", "1:3", "-q", check=False)
    assert (proc.returncode, proc.stderr) == (0, "")


def test_verbose_phase_times_add_up(painterly, tmp_path, repo_root):
    """The -v frame line: read, evaluate (summed over threads), write and
    wall seconds; reading and writing are serial, so each lies within the wall."""
    src = repo_root / "fixtures" / "tube.usda"
    proc = painterly("bake", src, "-o", tmp_path / "b.usdc", "-v")
    import re
    assert re.search(rf"^painterly: opened {re.escape(str(src))} \(1 layer\) in [\d.]+ s$", proc.stderr, re.M), \
        proc.stderr
    m = re.search(r"(\d+) frames: read ([\d.]+) s, evaluate ([\d.]+) s \(summed over threads\), "
                  r"write ([\d.]+) s; ([\d.]+) s wall", proc.stderr)
    assert m, proc.stderr
    frames, read, evaluate, write, wall = int(m[1]), *map(float, m.group(2, 3, 4, 5))
    assert frames == 24
    assert 0 <= read <= wall + 0.001 and 0 <= write <= wall + 0.001 and evaluate >= 0


def test_key_captures_points_by_default_and_not_with_opacity_alone(painterly, tmp_path, repo_root):
    """docs/choices.md: `key` captures the layer's rest points for --points,
    the default when neither --points nor --opacity is given; an --opacity
    key alone sets the opacity and no points."""
    import numpy as np
    from pxr import Usd

    fish = repo_root / "fixtures" / "blowfish.usda"
    spikes = "/Blowfish/Paint/Spikes"
    rest = _points(fish, spikes)
    for extra, want_points, want_opacity in (([], True, None), (["--opacity", "0.5"], False, 0.5)):
        edit = tmp_path / f"key{len(extra)}.usda"
        s = json.loads(painterly("key", fish, "--layer", spikes, "--time", "15", *extra, "--edit-layer", edit,
                                 "--json").stdout)
        stage = Usd.Stage.Open(str(edit))
        key = stage.GetPrimAtPath(s["key"])
        assert key.IsValid() and key.GetTypeName() == "PainterlyPoseKey", (extra, s)
        points, opacity = key.GetAttribute("points"), key.GetAttribute("opacity")
        assert points.HasAuthoredValue() == want_points, extra
        if want_points:
            assert np.array_equal(np.array(points.Get(), dtype=float), rest.astype(np.float32).astype(float))
        assert opacity.HasAuthoredValue() == (want_opacity is not None), extra
        if want_opacity is not None:
            assert opacity.Get() == pytest.approx(want_opacity)


def test_view_warns_and_reports_unless_quiet(painterly, tmp_path, repo_root):
    """`view` of an input without a defaultPrim warns on stderr that it uses
    the first root prim, and prints its line; with --quiet it prints nothing
    on either stream and still writes the layer."""
    from pxr import Sdf, Usd

    src = tmp_path / "tube.usda"
    src.write_bytes((repo_root / "fixtures" / "tube.usda").read_bytes())
    layer = Sdf.Layer.FindOrOpen(str(src))
    layer.ClearDefaultPrim()
    layer.Save()
    stage = Usd.Stage.Open(str(src))
    first = stage.GetPseudoRoot().GetChildren()[0].GetName()
    bake = tmp_path / "b.usdc"
    painterly("bake", src, "-o", bake, "--frames", "1:2", "-q")
    out = tmp_path / "v.usda"
    loud = painterly("view", src, "--bake", bake, "-o", out)
    warnings = loud.stderr.splitlines()
    assert len(warnings) == 1 and warnings[0].startswith("warning: "), loud.stderr
    assert "defaultPrim" in warnings[0] and f"/{first}" in warnings[0], loud.stderr
    lines = loud.stdout.splitlines()
    assert len(lines) == 1 and str(out) in lines[0], loud.stdout
    assert "frames 1:2" in lines[0] and f"defaultPrim {first}" in lines[0], loud.stdout
    view = Usd.Stage.Open(str(out))
    assert (view.GetStartTimeCode(), view.GetEndTimeCode()) == (1.0, 2.0)
    assert view.GetDefaultPrim().GetName() == first
    out.unlink()
    quiet = painterly("view", src, "--bake", bake, "-o", out, "-q", check=False)
    assert (quiet.returncode, quiet.stdout, quiet.stderr) == (0, "", "")
    view = Usd.Stage.Open(str(out))
    assert view.GetDefaultPrim().GetName() == first


@pytest.mark.parametrize("kind,why", [("folder", "it is a folder, not a USD file"), ("missing", "no such file")])
def test_an_input_that_is_not_a_file_is_named_before_any_work(painterly, tmp_path, repo_root, kind, why):
    """Every command that reads an input or a bake layer says which one is
    missing or a folder (a TD who passed the shot folder by mistake), exit 1,
    and writes nothing."""
    bad = tmp_path / ("shot" if kind == "folder" else "missing.usda")
    if kind == "folder":
        bad.mkdir()
    apple = repo_root / "fixtures" / "apple.usda"
    out = tmp_path / "out"
    out.mkdir()
    cases = [
        (["bake", bad, "-o", out / "b.usdc"], "input"),
        (["inspect", bad], "input"),
        (["bind", bad, "--in-place"], "input"),
        (["render", bad, "--camera", "/Apple/Camera", "--frames", "1", "-o", out / "f.####.exr"], "input"),
        (["render", apple, "--camera", "/Apple/Camera", "--frames", "1", "-o", out / "f.####.exr", "--bake", bad], "bake layer"),
        (["view", bad, "--bake", apple, "-o", out / "v.usda"], "input"),
        (["view", apple, "--bake", bad, "-o", out / "v.usda"], "bake layer"),
        (["preview", bad, "--port", "0"], "input"),
    ]
    for args, what in cases:
        proc = painterly(*args, check=False)
        assert (proc.returncode, proc.stderr) == (1, f"error: {bad}: cannot open {what}: {why}\n"), args
    assert list(out.iterdir()) == []


def test_an_input_that_is_a_device_or_under_a_file_gets_the_system_s_words(painterly, tmp_path, repo_root):
    """Not a folder and not missing: /dev/null is not a regular file, and a
    path through a file is the system's own error, not "no such file"."""
    under = repo_root / "fixtures" / "apple.usda" / "x.usda"
    for bad, why in [("/dev/null", "not a regular file (a FIFO, device or socket)"), (under, "Not a directory (os error 20)")]:
        for args in (["inspect", bad], ["render", bad, "--camera", "/C", "--frames", "1", "-o", tmp_path / "f.####.exr"]):
            proc = painterly(*args, check=False)
            assert (proc.returncode, proc.stderr) == (1, f"error: {bad}: cannot open input: {why}\n"), args


def test_an_empty_or_cut_short_input_says_what_is_wrong_with_its_bytes(painterly, tmp_path):
    """An empty input (a failed copy, a `touch`) said `failed to read pod
    openusd::usdc::layout::Bootstrap`, and a crate file shorter than its
    header said the same: the step openusd failed at, not what was wrong
    (found in the twenty-third session). usd-core's words, for comparison:
    "is not a valid usda layer", "File too small to contain bootstrap
    structure"."""
    (tmp_path / "empty.usdc").write_bytes(b"")
    (tmp_path / "empty.usda").write_bytes(b"")
    # The first 8 bytes of a crate file: its magic number. The header is 88
    # bytes, of which openusd reads 32 first (magic, version, table offset).
    (tmp_path / "short.usdc").write_bytes(b"PXR-USDC")
    said = {
        "empty.usdc": "the file is empty (0 bytes)",
        "empty.usda": "the file is empty (0 bytes)",
        "short.usdc": "failed to read pod openusd::usdc::layout::Bootstrap: corrupt crate data: 32 bytes at "
                      "offset 0 reach past the 8-byte stream",
    }
    for name, why in said.items():
        bad = tmp_path / name
        for args in (["inspect", bad], ["bake", bad, "-o", tmp_path / "out.usdc"]):
            proc = painterly(*args, check=False)
            assert (proc.returncode, proc.stderr) == (1, f"error: {bad}: cannot read USD file: {why}\n"), args
    # Empty layers the input names say so too (a review found them still
    # in openusd's words).
    top = tmp_path / "top.usda"
    top.write_text('#usda 1.0\n(\n    subLayers = [@./empty.usda@, @./short.usdc@]\n)\n'
                   'def "A" (references = @./empty.usdc@)\n{\n}\n')
    proc = painterly("bake", top, "-o", tmp_path / "out.usdc", check=False)
    empty = "cannot be read: the file is empty (0 bytes)"
    # A layer that is not empty keeps openusd's words.
    assert (proc.returncode, proc.stderr) == (
        1, f"error: {top}: 3 missing assets: sublayer @{tmp_path / 'empty.usda'}@ (in {top}): {empty}; "
           f"sublayer @{tmp_path / 'short.usdc'}@ (in {top}): cannot be read: {said['short.usdc']}; "
           f"reference @{tmp_path / 'empty.usdc'}@ on /A (in {top}): {empty}\n")
    assert not (tmp_path / "out.usdc").exists()


@pytest.mark.parametrize("args, named", [
    (["bake", "{head}", "--camera", "/Head/Camera.focalLength", "--frames", "1:2", "-o", "{out}/b.usdc"],
     "--camera /Head/Camera.focalLength is a property path, not a prim path"),
    (["bake", "{fish}", "--camera", "/Blowfish/Camera{v=x}", "--frames", "1", "-o", "{out}/b.usdc"],
     "--camera /Blowfish/Camera{v=x} is a variant selection path, not a prim path"),
    (["key", "{fish}", "--layer", "/Blowfish/Paint/Spikes", "--time", "15", "--points", "--camera",
      "/Blowfish/Camera.focalLength", "--edit-layer", "{out}/e.usda"],
     "--camera /Blowfish/Camera.focalLength is a property path, not a prim path"),
    (["key", "{fish}", "--layer", "/Blowfish/Paint/Spikes.points", "--time", "15", "--points",
      "--edit-layer", "{out}/e.usda"],
     "--layer /Blowfish/Paint/Spikes.points is a property path, not a prim path"),
    (["bind", "{fish}", "--layer", "Blowfish/Paint/Hair", "--edit-layer", "{out}/e.usda"],
     "--layer Blowfish/Paint/Hair is a relative path, not an absolute prim path"),
    (["smudge", "{fish}", "--layer", "/Blowfish/Paint/Hair", "--path-prim", "/Blowfish/Paint/Hair.points",
      "--radius", "1", "--strength", "0.2", "--edit-layer", "{out}/e.usda"],
     "--path-prim /Blowfish/Paint/Hair.points is a property path, not a prim path"),
])
def test_an_option_naming_a_prim_refuses_a_path_that_is_not_a_prim_path(painterly, tmp_path, repo_root, args,
                                                                         named):
    """usd-core's GetPrimAtPath finds no prim at a property path, a variant
    selection or a relative path: an option naming a prim refuses them as a
    usage error (exit 2) naming the option and the path, and writes nothing,
    where the prim the path ends in (/Head/Camera) was silently used."""
    from pxr import Usd

    fish, head = repo_root / "fixtures" / "blowfish.usda", repo_root / "fixtures" / "head.usda"
    stage = Usd.Stage.Open(str(head))
    assert stage.GetPrimAtPath("/Head/Camera") and not stage.GetPrimAtPath("/Head/Camera.focalLength")
    out = tmp_path / "out"
    out.mkdir()
    given = {"{fish}": str(fish), "{head}": str(head)}
    proc = painterly(*[given.get(a, a.replace("{out}", str(out))) for a in args], check=False)
    assert proc.returncode == 2, proc.stderr
    assert named in proc.stderr, proc.stderr
    assert list(out.iterdir()) == []


def test_inspect_says_when_there_is_nothing_painterly(painterly, tmp_path, repo_root):
    """A plain UsdSkel character has nothing wrong with it (exit 0), but bake
    has nothing to bake: inspect says so rather than only "no problems
    found", which reads as "bake will work" (README, inspect)."""
    from pxr import Usd, UsdGeom

    plain = tmp_path / "plain.usda"
    stage = Usd.Stage.CreateNew(str(plain))
    UsdGeom.Mesh.Define(stage, "/Thing")
    stage.GetRootLayer().Save()
    line = "nothing painterly: no rig (PainterlyRigAPI) and no view-dependent mesh, so bake has nothing to bake"
    proc = painterly("inspect", plain)
    assert proc.returncode == 0 and line in proc.stdout.splitlines(), proc.stdout
    bake = painterly("bake", plain, "-o", tmp_path / "b.usdc", check=False)
    assert bake.returncode == 1 and "nothing to bake" in bake.stderr
    for fixture in ("blowfish.usda", "head.usda"):  # a rig; a view-dependent mesh alone
        proc = painterly("inspect", repo_root / "fixtures" / fixture)
        assert "nothing painterly" not in proc.stdout, proc.stdout


def test_inspect_says_when_a_rig_has_nothing_to_bake_or_could_not_be_read(painterly, tmp_path, repo_root):
    """A rig whose stroke layers are all deactivated passed as "no problems
    found" while bake said "nothing to bake"; a rig inspect could not read
    was reported as "no rig" though its problem named it (two reviews,
    2026-12-07)."""
    from pxr import Usd

    idle = tmp_path / "idle.usda"
    stage = Usd.Stage.Open(str(repo_root / "fixtures" / "tube.usda"))
    stage.Export(str(idle))
    stage = Usd.Stage.Open(str(idle))
    for p in stage.Traverse():
        if "PainterlyStrokeLayerAPI" in p.GetAppliedSchemas():
            p.SetActive(False)
    stage.GetRootLayer().Save()
    proc = painterly("inspect", idle)
    assert proc.returncode == 0
    assert ("nothing to bake: no rig has an active stroke layer (PainterlyStrokeLayerAPI) and there is no "
            "view-dependent mesh") in proc.stdout.splitlines(), proc.stdout
    bake = painterly("bake", idle, "-o", tmp_path / "b.usdc", check=False)
    assert bake.returncode == 1 and "nothing to bake" in bake.stderr

    broken = tmp_path / "broken.usda"
    stage = Usd.Stage.Open(str(repo_root / "fixtures" / "tube.usda"))
    stage.Export(str(broken))
    stage = Usd.Stage.Open(str(broken))
    rig = next(p for p in stage.Traverse() if "PainterlyRigAPI" in p.GetAppliedSchemas())
    rig.GetRelationship("painterly:proxy").SetTargets(["/Nowhere"])
    stage.GetRootLayer().Save()
    proc = painterly("inspect", broken, check=False)
    assert proc.returncode == 1
    lines = proc.stdout.splitlines()
    assert "nothing painterly could be listed (the problems below say why), so bake has nothing to bake" in lines
    assert not any(line.startswith("nothing painterly: no rig") for line in lines), proc.stdout


def test_inspect_refuses_a_camera_that_is_no_prim_path(painterly, repo_root):
    """As bake does (exit 2): a property path is a bad option, not a
    problem of the stage (inspect listed it as one, exit 1)."""
    proc = painterly("inspect", repo_root / "fixtures" / "head.usda", "--camera", "/Head/Camera.focalLength", check=False)
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert "--camera /Head/Camera.focalLength is a property path, not a prim path" in proc.stderr
    assert proc.stdout == ""
