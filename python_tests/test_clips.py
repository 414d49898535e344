"""Chunked bakes as USD value clips (issue 10 §2).

`painterly bake IN -o shot.usda --chunk N` writes chunk layers plus a
clip-set layer. Composed over the input by usd-core, the clip set must give
exactly the single-file bake: at every baked frame (bit for bit) and at
fractional times between frames, across chunk boundaries too. A farm runs
the same chunks one per task (`--chunk-index K`) and assembles the clip set
last (`--assemble`), which refuses missing or stale chunks.
"""

import json
import os
import pathlib
import re
import shutil

import numpy as np
import pytest
from clip_compare import compare
from conftest import painterly_binary
from pxr import Sdf, Usd, Vt

FIXTURES = ["blowfish.usda", "tube.usda", "wave.usda", "static.usda", "apple.usda", "head.usda", "walk.usda", "building.usda"]


@pytest.mark.parametrize("fixture", FIXTURES)
def test_clip_set_composes_to_the_single_file_bake(painterly, tmp_path, repo_root, fixture):
    src = repo_root / "fixtures" / fixture
    single, shot = tmp_path / "single.usdc", tmp_path / "shot.usda"
    painterly("bake", src, "-o", single, "--quiet")
    painterly("bake", src, "-o", shot, "--chunk", "7", "--quiet")
    layer = Sdf.Layer.FindOrOpen(str(single))
    first, last = layer.startTimeCode, layer.endTimeCode
    frames = list(np.arange(first, last + 0.5))
    compare(single, shot, src, frames, exact=True)
    halves = [f + 0.5 for f in frames[:-1]]
    compare(single, shot, src, halves, exact=False)
    # The clip set carries the single-file bake's layer metadata.
    clip_layer = Sdf.Layer.FindOrOpen(str(shot))
    for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "framesPerSecond"):
        assert clip_layer.pseudoRoot.GetInfo(key) == layer.pseudoRoot.GetInfo(key), key
    stage = Usd.Stage.Open(str(shot))
    for key in ("upAxis", "metersPerUnit"):
        assert stage.GetMetadata(key) == Usd.Stage.Open(str(single)).GetMetadata(key), key


def test_fractional_steps_and_uneven_last_chunk(painterly, tmp_path, repo_root):
    src = repo_root / "fixtures" / "blowfish.usda"
    single, shot = tmp_path / "single.usda", tmp_path / "shot.usda"
    painterly("bake", src, "-o", single, "--frames", "10:14:0.25", "--quiet")
    out = painterly("bake", src, "-o", shot, "--frames", "10:14:0.25", "--chunk", "4", "--json")
    summary = json.loads(out.stdout)
    assert summary["frames"] == 17
    names = [pathlib.Path(c).name for c in summary["chunks"]]
    assert names == [
        "shot.0000.10-10.75.usdc",
        "shot.0001.11-11.75.usdc",
        "shot.0002.12-12.75.usdc",
        "shot.0003.13-13.75.usdc",
        "shot.0004.14-14.usdc",
    ]
    assert sorted(p.name for p in (tmp_path / "shot.clips").iterdir()) == sorted(
        names + ["shot.manifest.usda", "shot.binding.usdc", "shot.lock"]
    )
    times = [10 + 0.25 * k for k in range(17)]
    compare(single, shot, src, times, exact=True)
    compare(single, shot, src, [t + 0.125 for t in times[:-1]], exact=False)


def test_farm_tasks_and_assembly_match_a_local_chunked_bake(painterly, tmp_path, repo_root):
    src = repo_root / "fixtures" / "tube.usda"
    local, farm = tmp_path / "local" / "shot.usda", tmp_path / "farm" / "shot.usda"
    local.parent.mkdir()
    farm.parent.mkdir()
    painterly("bake", src, "-o", local, "--chunk", "5", "--quiet")
    for k in range(5):
        out = json.loads(painterly("bake", src, "-o", farm, "--chunk", "5", "--chunk-index", k, "--json").stdout)
        assert len(out["chunks"]) == 1 and out["frames"] == (5 if k < 4 else 4)
    assert not farm.exists(), "a chunk task must not write the clip set"
    text = painterly("bake", src, "-o", farm, "--chunk", "5", "--assemble").stdout
    # The tube: 2 layers, 50 strokes, 450 points; 24 frames in 5 chunks.
    assert re.fullmatch(
        rf"assembled 5 chunk layers: 2 layers, 50 strokes, 450 points, 0 view-dependent meshes -> {re.escape(str(farm))} in \d+\.\d\d s\n",
        text,
    ), text
    assembled = json.loads(painterly("bake", src, "-o", farm, "--chunk", "5", "--assemble", "--json").stdout)
    assert (assembled["frames"], len(assembled["chunks"])) == (0, 5)
    for f in sorted((local.parent / "shot.clips").iterdir()):
        g = farm.parent / "shot.clips" / f.name
        assert f.read_bytes() == g.read_bytes(), f.name
    assert local.read_text() == farm.read_text()


def test_assemble_refuses_missing_and_stale_chunks(painterly, tmp_path, repo_root):
    src = tmp_path / "tube.usda"
    shutil.copy(repo_root / "fixtures" / "tube.usda", src)
    shot = tmp_path / "shot.usda"
    for k in (0, 2, 3, 4):
        painterly("bake", src, "-o", shot, "--chunk", "5", "--chunk-index", k, "--quiet")
    proc = painterly("bake", src, "-o", shot, "--chunk", "5", "--assemble", check=False)
    assert proc.returncode == 1
    assert "1 of 5 chunks missing: shot.0001.6-10.usdc" in proc.stderr
    assert not shot.exists()
    # Change the input: every chunk baked from the old one is stale.
    text = src.read_text().replace("timeCodesPerSecond = 24", "timeCodesPerSecond = 24.0")
    assert text != src.read_text()
    src.write_text(text)
    painterly("bake", src, "-o", shot, "--chunk", "5", "--chunk-index", 1, "--quiet")
    proc = painterly("bake", src, "-o", shot, "--chunk", "5", "--assemble", check=False)
    assert proc.returncode == 1
    assert "4 stale" in proc.stderr and "baked from a different input" in proc.stderr
    assert not shot.exists()


def test_chunks_baked_with_other_options_are_stale(painterly, tmp_path, repo_root):
    """`--bake-proxy` and `--camera` change what a chunk holds, so a chunk
    baked without them is stale for a shot baked with them: a re-submit
    bakes it again and the assembly refuses it (both took the old chunks
    as done, and the composed proxy had its skeleton blocked and no points;
    found by a farm review, 2026-12-06)."""
    src = repo_root / "fixtures" / "tube.usda"
    shot = tmp_path / "shot.usda"
    painterly("bake", src, "-o", shot, "--chunk", "5", "--quiet")
    proc = painterly("bake", src, "-o", shot, "--chunk", "5", "--bake-proxy", "--assemble", check=False)
    assert proc.returncode == 1
    assert "5 stale" in proc.stderr and "baked with no options, expected `--bake-proxy`" in proc.stderr
    sub = json.loads(painterly("farm", "submit", src, "-o", shot, "--chunk", "5", "--scheduler", "openjd",
                               "--bake-proxy", "--json").stdout)
    assert (sub["submitted"], sub["skipped"]) == ([0, 1, 2, 3, 4], [])
    status = painterly("farm", "status", shot, "--json", check=False)
    assert status.returncode == 1 and json.loads(status.stdout)["assembled"] is False
    for k in range(5):
        painterly("bake", src, "-o", shot, "--chunk", "5", "--chunk-index", k, "--bake-proxy", "--quiet")
    painterly("bake", src, "-o", shot, "--chunk", "5", "--bake-proxy", "--assemble", "--quiet")
    # Now the shot is the --bake-proxy bake: the proxy has points at every frame (usd-core).
    root = Sdf.Layer.CreateAnonymous(".usda")
    root.subLayerPaths = [str(shot), str(src)]
    composed = Usd.Stage.Open(root)
    proxy = composed.GetPrimAtPath("/Tube/Rig/Proxy")
    assert proxy.GetRelationship("skel:skeleton").GetTargets() == []
    assert all(proxy.GetAttribute("points").Get(t) is not None for t in (1, 12, 24))
    # And the other way: chunks with an option are stale for a bake without it.
    proc = painterly("bake", src, "-o", shot, "--chunk", "5", "--assemble", check=False)
    assert proc.returncode == 1 and "baked with `--bake-proxy`, expected no options" in proc.stderr


def _proxy_animated_by_a_clip(repo_root, tmp_path):
    """The wave fixture with its proxy's `points`/`extent` samples moved into
    a value clip `wave_anim.usda` on /Wave/Rig (as point-cache pipelines
    deliver animation); returns the root layer's path and the clip's."""
    src = Sdf.Layer.FindOrOpen(str(repo_root / "fixtures" / "wave.usda"))
    root = Sdf.Layer.CreateNew(str(tmp_path / "wave_clipped.usda"))
    root.TransferContent(src)
    clip = Sdf.Layer.CreateNew(str(tmp_path / "wave_anim.usda"))
    proxy = Sdf.Path("/Wave/Rig/Proxy")
    Sdf.CreatePrimInLayer(clip, proxy)
    for name in ("points", "extent"):
        ap = proxy.AppendProperty(name)
        spec = root.GetAttributeAtPath(ap)
        Sdf.AttributeSpec(clip.GetPrimAtPath(proxy), name, spec.typeName)
        times = list(root.ListTimeSamplesForPath(ap))
        for t in times:
            clip.SetTimeSample(ap, t, root.QueryTimeSample(ap, t))
            root.EraseTimeSample(ap, t)
        spec.ClearDefaultValue()  # the rest pose too comes from the clip
    clip.Save()
    root.Save()
    stage = Usd.Stage.Open(root)
    api = Usd.ClipsAPI(stage.GetPrimAtPath("/Wave/Rig"))
    api.SetClipAssetPaths([Sdf.AssetPath("./wave_anim.usda")], "anim")
    api.SetClipPrimPath("/Wave/Rig", "anim")
    api.SetClipActive([(times[0], 0)], "anim")
    api.SetClipTimes([(times[0], times[0]), (times[-1], times[-1])], "anim")
    root.Save()
    del stage
    fresh = Usd.Stage.Open(root.realPath)
    assert len(times) > 2 and fresh.GetAttributeAtPath(proxy.AppendProperty("points")).GetNumTimeSamples() == len(times)
    return pathlib.Path(root.realPath), pathlib.Path(clip.realPath)


def test_a_change_in_an_input_value_clip_makes_its_chunks_stale(painterly, tmp_path, repo_root):
    """The input's value clips are part of its hash: a chunk baked before
    its clip file changed is stale, and the binding cache of the old input
    is not reused (both missed it, and the re-bake reused the old binding;
    found by a farm review, 2026-12-06)."""
    src, clip_path = _proxy_animated_by_a_clip(repo_root, tmp_path)
    shot = tmp_path / "out" / "shot.usda"
    shot.parent.mkdir()
    painterly("bake", src, "-o", shot, "--chunk", "10", "--chunk-index", "0", "--quiet")
    # The clip's animation moves by +1 in y: a new delivery of the cache.
    clip = Sdf.Layer.FindOrOpen(str(clip_path))
    ap = Sdf.Path("/Wave/Rig/Proxy.points")
    for t in clip.ListTimeSamplesForPath(ap):
        pts = np.array(clip.QueryTimeSample(ap, t))
        pts[:, 1] += 1.0
        clip.SetTimeSample(ap, t, Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
    clip.Save()
    for k in (1, 2, 3):
        painterly("bake", src, "-o", shot, "--chunk", "10", "--chunk-index", k, "--quiet")
    proc = painterly("bake", src, "-o", shot, "--chunk", "10", "--assemble", check=False)
    assert proc.returncode == 1
    assert "1 stale: shot.0000.0-9.usdc (baked from a different input)" in proc.stderr
    # A full re-bake in the same folder equals a single bake of the new input.
    single = tmp_path / "single.usdc"
    painterly("bake", src, "-o", single, "--quiet")
    painterly("bake", src, "-o", shot, "--chunk", "10", "--quiet")
    compare(single, shot, src, [float(t) for t in range(0, 31)], exact=True)


@pytest.mark.parametrize("damage", ["truncated", "empty", "text"])
def test_a_damaged_chunk_is_stale_and_baked_again(painterly, tmp_path, repo_root, damage):
    """A chunk file that cannot be read (a full disk, a copy cut short) is
    stale, named with why: status lists it, a re-submit bakes it again, the
    assembly refuses it. All three failed whole on it, naming no chunk
    (found by a farm review, 2026-12-06)."""
    src = repo_root / "fixtures" / "tube.usda"
    shot = tmp_path / "shot.usda"
    painterly("bake", src, "-o", shot, "--chunk", "5", "--quiet")
    painterly("farm", "submit", src, "-o", shot, "--chunk", "5", "--scheduler", "openjd", "--quiet")
    chunk = tmp_path / "shot.clips" / "shot.0001.6-10.usdc"
    data = chunk.read_bytes()
    chunk.write_bytes({"truncated": data[: len(data) // 2], "empty": b"", "text": b"not usd"}[damage])
    status = painterly("farm", "status", shot, "--json", check=False)
    assert status.returncode == 1, status.stderr
    states = {c["name"]: (c["state"], c["detail"]) for c in json.loads(status.stdout)["chunks"]}
    assert states["shot.0001.6-10.usdc"][0] == "stale" and "unreadable" in states["shot.0001.6-10.usdc"][1]
    assert [st for name, (st, _) in states.items() if name != "shot.0001.6-10.usdc"] == ["done"] * 4
    proc = painterly("bake", src, "-o", shot, "--chunk", "5", "--assemble", check=False)
    assert proc.returncode == 1 and "1 stale: shot.0001.6-10.usdc (unreadable: " in proc.stderr
    sub = json.loads(painterly("farm", "submit", src, "-o", shot, "--chunk", "5", "--scheduler", "openjd",
                               "--json").stdout)
    assert (sub["submitted"], sub["skipped"]) == ([1], [0, 2, 3, 4])
    painterly("bake", src, "-o", shot, "--chunk", "5", "--chunk-index", "1", "--quiet")
    painterly("bake", src, "-o", shot, "--chunk", "5", "--assemble", "--quiet")
    single = tmp_path / "single.usdc"
    painterly("bake", src, "-o", single, "--quiet")
    compare(single, shot, src, [float(t) for t in range(1, 25)], exact=True)


def test_a_failed_rebake_leaves_the_published_clip_set_whole(painterly, tmp_path, repo_root):
    """A chunked re-bake writes every chunk under a temporary name and puts
    them in place only once all are written: one that fails part way (here
    at frame 20, where the new input's opacity is not finite) leaves the
    published clip set and its chunks byte for byte as they were, and no
    temporary. It replaced the chunks it had finished, so the published
    shot mixed two inputs (found by a farm review, 2026-12-06)."""
    src = tmp_path / "tube.usda"
    text = (repo_root / "fixtures" / "tube.usda").read_text()
    src.write_text(text)
    shot = tmp_path / "shot.usda"
    painterly("bake", src, "-o", shot, "--chunk", "5", "--quiet")
    published = {p: p.read_bytes() for p in sorted(tmp_path.rglob("*")) if p.is_file() and p != src}
    v2 = text.replace("float painterly:opacity = 0.8",
                      "float painterly:opacity.timeSamples = {1: 0.5, 19: 0.5, 20: nan}", 1)
    assert v2 != text
    src.write_text(v2)
    proc = painterly("bake", src, "-o", shot, "--chunk", "5", check=False)
    assert proc.returncode == 1 and "not finite" in proc.stderr, proc.stderr
    after = {p: p.read_bytes() for p in sorted(tmp_path.rglob("*")) if p.is_file() and p != src}
    assert sorted(after) == sorted(published)
    # Only the binding cache is new: it is stamped with the input it binds.
    assert [p.name for p in published if after[p] != published[p]] == ["shot.binding.usdc"]


def _files(root):
    return {p: p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_chunk_names_too_long_for_the_file_system_are_refused_before_any_write(painterly, tmp_path, repo_root):
    """A 241-byte stem: chunk 0 (`<stem>.0000.1-5.usdc`, 255 bytes) fits,
    chunk 1 (`<stem>.0001.6-10.usdc`, 256) does not. The re-bake once wrote
    every chunk through one cut temporary name and replaced the published
    chunk 0 with frames 6-10 before failing (a shot-scale review,
    2026-12-07); now nothing is written and the cause is named."""
    src = repo_root / "fixtures" / "tube.usda"
    shot = tmp_path / ("s" * 241 + ".usda")
    painterly("bake", src, "-o", shot, "--chunk", "5", "--frames", "1:5", "--quiet")
    published = _files(tmp_path)
    proc = painterly("bake", src, "-o", shot, "--chunk", "5", "--frames", "1:10", check=False)
    long = "s" * 241 + ".0001.6-10.usdc"
    assert (proc.returncode, proc.stderr) == (1, (
        f"error: {shot}: its chunks' file names would be up to 256 bytes ({long}), over the 255 a file name "
        "may have: shorten the output's name (or give --frames simpler times)\n"))
    assert _files(tmp_path) == published


@pytest.mark.skipif(os.geteuid() != 0 or not shutil.which("setpriv"), reason="needs root to run as another user")
def test_a_rebake_whose_clip_set_is_read_only_publishes_no_chunk(request, painterly, repo_root):
    """The pipeline locked the published clip-set layer (mode 444); a
    re-bake by another user must fail before it replaces a chunk, or the
    old set would show new chunks for some frames and old for others."""
    import subprocess
    import tempfile

    shared = pathlib.Path(tempfile.mkdtemp(prefix="painterly-shared-"))
    request.addfinalizer(lambda: shutil.rmtree(shared, ignore_errors=True))
    shared.chmod(0o777)
    src = shared / "tube.usda"
    text = (repo_root / "fixtures" / "tube.usda").read_text()
    src.write_text(text)
    shot = shared / "shot.usda"
    nobody = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"]
    first = subprocess.run([*nobody, str(painterly_binary()), "bake", str(src), "-o", str(shot), "--chunk", "5",
                            "--frames", "1:10", "--quiet"], capture_output=True, text=True, timeout=120)
    assert first.returncode == 0, first.stderr
    shot.chmod(0o444)
    published = _files(shared)
    src.write_text(text.replace("float painterly:opacity = 0.8", "float painterly:opacity = 0.6", 1))
    proc = subprocess.run([*nobody, str(painterly_binary()), "bake", str(src), "-o", str(shot), "--chunk", "5",
                           "--frames", "1:7"], capture_output=True, text=True, timeout=120)
    assert (proc.returncode, proc.stderr) == (1, (
        f"error: {shot}: cannot replace a file this user may not write (mode 444): change its permissions first\n"))
    # A farm task is refused too: its chunk, published when it ends, could
    # never be assembled into the locked set.
    task = subprocess.run([*nobody, str(painterly_binary()), "bake", str(src), "-o", str(shot), "--chunk", "5",
                           "--frames", "1:10", "--chunk-index", "0"], capture_output=True, text=True, timeout=120)
    assert (task.returncode, task.stderr) == (1, proc.stderr)
    # Refused before its clips folder is made: nothing is left behind.
    fresh = shared / "fresh.usda"
    fresh.write_text("#usda 1.0\n")
    fresh.chmod(0o444)
    first = subprocess.run([*nobody, str(painterly_binary()), "bake", str(src), "-o", str(fresh), "--chunk", "5",
                            "--frames", "1:10"], capture_output=True, text=True, timeout=120)
    assert first.returncode == 1 and "may not write (mode 444)" in first.stderr, first.stderr
    assert not (shared / "fresh.clips").exists()
    fresh.unlink()
    after = _files(shared)
    assert {p for p in after if p != src} == {p for p in published if p != src}
    assert [p.name for p in published if p != src and after[p] != published[p]] == []


def test_a_chunked_bake_of_an_input_holding_a_painterly_clip_set_is_refused(painterly, tmp_path, repo_root):
    """`clips` merges key by key: a second set named "painterly" on the root prim
    replaced every entry of the first, and the proxy the first set animated
    froze at rest (a shot-scale review, 2026-12-07). A single-file bake over
    the same input keeps the old set, as usd-core composes it."""
    src = repo_root / "fixtures" / "tube.usda"
    first, view = tmp_path / "first.usda", tmp_path / "layered.usda"
    painterly("bake", src, "-o", first, "--chunk", "6", "--bake-proxy", "--quiet")
    painterly("view", src, "--bake", first, "-o", view)
    out = tmp_path / "again.usda"
    proc = painterly("bake", view, "-o", out, "--chunk", "6", check=False)
    assert proc.returncode == 1
    assert proc.stderr.startswith(f"error: {view}: /Tube.clips: the input already holds a value-clip set named "
                                  '"painterly" here'), proc.stderr
    assert not out.exists() and not (tmp_path / "again.clips").exists()
    painterly("bake", view, "-o", tmp_path / "single.usdc", "--quiet")
    # The same set reaching the root prim through a reference (a shot that
    # references the layered character) is refused as well.
    shot = tmp_path / "shot.usda"
    shot.write_text(f'#usda 1.0\n(\n    defaultPrim = "Tube"\n)\n\ndef Xform "Tube" (\n'
                    f'    references = @{view}@</Tube>\n)\n{{\n}}\n')
    stage = Usd.Stage.Open(str(shot))
    assert "painterly" in stage.GetPrimAtPath("/Tube").GetMetadata("clips")  # usd-core sees the set
    proc = painterly("bake", shot, "-o", tmp_path / "again2.usda", "--chunk", "6", "--frames", "1:12", check=False)
    assert proc.returncode == 1 and '/Tube.clips: the input already holds a value-clip set named "painterly"' in proc.stderr, proc.stderr


def test_one_process_at_a_time_writes_a_shot_and_tasks_share_it(painterly, tmp_path, repo_root):
    """A whole chunked bake and an assembly take the clips folder's lock
    alone, chunk tasks together (flock on shot.clips/shot.lock): two local
    bakes into one output mixed their inputs' chunks under one clip set
    with exit 0 (found by a farm review, 2026-12-06). The lock is held here
    by this test, as another process would."""
    import fcntl

    src = repo_root / "fixtures" / "tube.usda"
    shot = tmp_path / "shot.usda"
    painterly("bake", src, "-o", shot, "--chunk", "5", "--quiet")
    before = {p: p.read_bytes() for p in sorted(tmp_path.rglob("*")) if p.is_file()}
    busy = f"error: {tmp_path / 'shot.clips'}: another painterly process is writing this shot's chunks or clip set"
    with open(tmp_path / "shot.clips" / "shot.lock", "a") as held:
        fcntl.flock(held, fcntl.LOCK_SH)  # a running chunk task
        for args in (("--chunk", "5"), ("--chunk", "5", "--assemble")):
            proc = painterly("bake", src, "-o", shot, *args, check=False)
            assert proc.returncode == 1 and proc.stderr.startswith(busy), proc.stderr
        painterly("bake", src, "-o", shot, "--chunk", "5", "--chunk-index", "2", "--quiet")
        fcntl.flock(held, fcntl.LOCK_EX)  # a running whole bake
        proc = painterly("bake", src, "-o", shot, "--chunk", "5", "--chunk-index", "2", check=False)
        assert proc.returncode == 1 and proc.stderr.startswith(busy), proc.stderr
    after = {p: p.read_bytes() for p in sorted(tmp_path.rglob("*")) if p.is_file()}
    assert after == before  # the task's chunk 2 is the same bake again
    painterly("bake", src, "-o", shot, "--chunk", "5", "--assemble", "--quiet")


@pytest.mark.parametrize(
    "args,code,message",
    [
        (["--chunk", "0"], 2, "not a whole number of at least 1"),
        (["--chunk", "5", "--chunk-index", "9"], 1,
         "--chunk-index 9 is out of range: 24 frames in chunks of 5 make 5 chunks, numbered 0 to 4"),
        (["--chunk", "24", "--chunk-index", "1"], 1,
         "--chunk-index 1 is out of range: 24 frames in chunks of 24 make 1 chunk, numbered 0 to 0"),
        (["--chunk", "99999999999999999999"], 2, '"99999999999999999999" is too large (at most 18446744073709551615)'),
        (["--chunk-index", "1"], 2, "--chunk"),
        (["--assemble"], 2, "--chunk"),
    ],
)
def test_bad_chunk_arguments(painterly, tmp_path, repo_root, args, code, message):
    proc = painterly("bake", repo_root / "fixtures" / "tube.usda", "-o", tmp_path / "shot.usda", *args, check=False)
    assert proc.returncode == code, proc.stderr
    assert message in proc.stderr
    assert not (tmp_path / "shot.usda").exists()


def test_chunked_output_must_be_usda(painterly, tmp_path, repo_root):
    proc = painterly("bake", repo_root / "fixtures" / "tube.usda", "-o", tmp_path / "shot.usdc", "--chunk", "5", check=False)
    # A wrong output extension is a command-line mistake, as for a plain bake.
    assert proc.returncode == 2, proc.stderr
    assert "name it .usda" in proc.stderr
    assert list(tmp_path.iterdir()) == []


def test_inspect_reports_chunks(painterly, tmp_path, repo_root):
    src = tmp_path / "tube.usda"
    shutil.copy(repo_root / "fixtures" / "tube.usda", src)
    shot = tmp_path / "shot.usda"
    painterly("bake", src, "-o", shot, "--chunk", "10", "--quiet")
    proc = painterly("inspect", shot)
    assert "clip set: 3 chunks of 10 frames: 3 done, 0 missing, 0 stale" in proc.stdout
    report = json.loads(painterly("inspect", shot, "--json").stdout)
    assert report["clip_set"]["chunk_size"] == 10
    assert [c["state"] for c in report["clip_set"]["chunks"]] == ["done"] * 3
    (tmp_path / "shot.clips" / "shot.0001.11-20.usdc").unlink()
    # The input changes and one chunk is baked again from it: the chunks
    # are judged against the input as it is now, as the assembly judges
    # them, so the old ones are stale and the new one done.
    text = src.read_text().replace("timeCodesPerSecond = 24", "timeCodesPerSecond = 24.0")
    src.write_text(text)
    painterly("bake", src, "-o", shot, "--chunk", "10", "--chunk-index", "2", "--quiet")
    proc = painterly("inspect", shot, "--json", check=False)
    assert proc.returncode == 1
    chunks = json.loads(proc.stdout)["clip_set"]["chunks"]
    assert [(pathlib.Path(c["path"]).name, c["state"]) for c in chunks] == [
        ("shot.0000.1-10.usdc", "stale"),
        ("shot.0001.11-20.usdc", "missing"),
        ("shot.0002.21-24.usdc", "done"),
    ]
    assert chunks[0]["detail"] == "baked from a different input"
    text = painterly("inspect", shot, check=False).stdout
    assert "1 done, 1 missing, 1 stale" in text and "shot.0001.11-20.usdc is missing" in text
    assert f"{src} changed since this clip set was assembled" in text


def _move_the_tube(src):
    """Moves the tube fixture's root transform, with usd-core, and saves."""
    stage = Usd.Stage.Open(str(src))
    op = stage.GetPrimAtPath("/Tube").GetAttribute("xformOp:translate")
    assert op.Get() == (1, 0, 0)
    op.Set((2, 0, 0))
    stage.Save()


def test_inspect_judges_chunks_against_the_current_input(painterly, tmp_path, repo_root):
    """A chunked bake whose input changed since is stale: inspect names its
    chunks stale as farm status and the assembly do (it compared each
    chunk's stamp with the hash the clip set recorded, never with the
    input's, and called the bake current; found by a review, 2026-12-07)."""
    src, shot = tmp_path / "in.usda", tmp_path / "shot.usda"
    shutil.copy(repo_root / "fixtures" / "tube.usda", src)
    painterly("bake", src, "-o", shot, "--chunk", "8", "--quiet")
    report = json.loads(painterly("inspect", shot, "--json").stdout)
    assert report["problems"] == []
    assert "3 done, 0 missing, 0 stale" in painterly("inspect", shot).stdout
    _move_the_tube(src)
    proc = painterly("inspect", shot, "--json", check=False)
    assert proc.returncode == 1, proc.stderr
    report = json.loads(proc.stdout)
    assert [(c["state"], c["detail"]) for c in report["clip_set"]["chunks"]] == [
        ("stale", "baked from a different input")
    ] * 3
    messages = [p["message"] for p in report["problems"] if p["rule"] == "chunks"]
    assert len(messages) == len(report["problems"]) == 4, report["problems"]
    assert f"{src} changed since this clip set was assembled" in messages[0]
    for name in ("shot.0000.1-8.usdc", "shot.0001.9-16.usdc", "shot.0002.17-24.usdc"):
        assert any(name in m and "is stale (baked from a different input)" in m for m in messages), name
    proc = painterly("inspect", shot, check=False)
    assert proc.returncode == 1
    assert "clip set: 3 chunks of 8 frames: 0 done, 0 missing, 3 stale" in proc.stdout
    # The assembly agrees.
    proc = painterly("bake", src, "-o", shot, "--chunk", "8", "--assemble", check=False)
    assert proc.returncode == 1 and "3 stale" in proc.stderr
    # Baked again from the changed input, the shot is current again.
    painterly("bake", src, "-o", shot, "--chunk", "8", "--quiet")
    assert json.loads(painterly("inspect", shot, "--json").stdout)["problems"] == []


@pytest.mark.parametrize("damage", ["deleted", "not usd"])
def test_inspect_names_the_input_of_a_clip_set_it_cannot_read(painterly, tmp_path, repo_root, damage):
    """Without its input, a clip set's chunks cannot be checked against it:
    inspect says so, naming the input, instead of calling them current."""
    src, shot = tmp_path / "in.usda", tmp_path / "shot.usda"
    shutil.copy(repo_root / "fixtures" / "tube.usda", src)
    painterly("bake", src, "-o", shot, "--chunk", "8", "--quiet")
    if damage == "deleted":
        src.unlink()
    else:
        src.write_text("not usd\n")
    proc = painterly("inspect", shot, "--json", check=False)
    assert proc.returncode == 1, proc.stderr
    problems = json.loads(proc.stdout)["problems"]
    assert len(problems) == 1 and problems[0]["rule"] == "chunks", problems
    assert problems[0]["message"].startswith(f"the clip set's input {src} cannot be read"), problems
    assert str(src) in painterly("inspect", shot, check=False).stdout


@pytest.mark.parametrize("ext", ["usdc", "usda"])
def test_a_long_bake_spilling_its_sample_index_matches_unspilled_chunks(painterly, tmp_path, repo_root, ext):
    """Past 1,024 frames a single-file bake keeps its per-frame sample
    handles (offsets for .usda) in a scratch file, not in memory (flat memory,
    issue 10); chunks of 1,000 frames never do. Both must compose to the
    same values, around the 1,024-frame block edges too, and the scratch
    file must be gone."""
    src = repo_root / "fixtures" / "static.usda"
    single, shot = tmp_path / f"single.{ext}", tmp_path / "shot.usda"
    frames = "1:12:0.005"  # 2,201 frames: two full blocks and a partial one
    painterly("bake", src, "-o", single, "--frames", frames, "--quiet")
    painterly("bake", src, "-o", shot, "--frames", frames, "--chunk", "1000", "--quiet")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([single.name, "shot.usda", "shot.clips"])
    times = [1 + 0.005 * k for k in range(2201)]
    assert Sdf.Layer.FindOrOpen(str(single)).ListAllTimeSamples() == pytest.approx(times, abs=1e-9)
    picked = sorted({0, 1, 999, 1000, 1023, 1024, 1025, 2047, 2048, 2049, 2200, *range(0, 2201, 97)})
    compare(single, shot, src, [times[k] for k in picked], exact=True)


def _chunk_task(painterly, src, shot, k, *extra):
    return painterly("bake", src, "-o", shot, "--chunk", "5", "--chunk-index", k, "-v", *extra).stderr


def test_tasks_of_a_shot_bind_once_through_the_binding_cache(painterly, tmp_path, repo_root):
    """The first chunked process binds and leaves the binding in
    <stem>.clips/<stem>.binding.usdc; later tasks and the assembly take it
    from there, and what they write is byte-identical to a task that bound
    by itself."""
    src = repo_root / "fixtures" / "tube.usda"
    shot, fresh = tmp_path / "a" / "shot.usda", tmp_path / "b" / "shot.usda"
    shot.parent.mkdir(), fresh.parent.mkdir()
    first = _chunk_task(painterly, src, shot, 0)
    cache = shot.parent / "shot.clips" / "shot.binding.usdc"
    assert cache.is_file() and "from the binding cache" not in first
    info = Sdf.Layer.FindOrOpen(str(cache)).customLayerData["painterly"]
    assert info["version"] and len(info["inputHash"]) == 64
    assert info["input"] == str(src)  # the root layer's path as given
    # usd-core reads the cache as an override layer of bindings, one per point.
    stage = Usd.Stage.Open(str(cache))
    layers = [p for p in stage.TraverseAll() if p.HasAttribute("painterly:bindVertices")]
    strokes = Usd.Stage.Open(str(src))
    assert layers and all(
        len(p.GetAttribute("painterly:bindVertices").Get())
        == len(strokes.GetPrimAtPath(p.GetPath()).GetAttribute("points").Get())
        for p in layers
    )
    second = _chunk_task(painterly, src, shot, 3)
    assert f"took the binding of {len(layers)} stroke layer" in second
    _chunk_task(painterly, src, fresh, 3)  # no cache there yet: binds itself
    name = "shot.0003.16-20.usdc"
    assert (shot.parent / "shot.clips" / name).read_bytes() == (fresh.parent / "shot.clips" / name).read_bytes()
    for k in (1, 2, 4):
        _chunk_task(painterly, src, shot, k)
    assemble = painterly("bake", src, "-o", shot, "--chunk", "5", "--assemble", "-v").stderr
    assert "from the binding cache" in assemble


@pytest.mark.parametrize("damage", ["other input", "garbage", "out of range", "wrong length"])
def test_a_stale_or_broken_binding_cache_is_ignored(painterly, tmp_path, repo_root, damage):
    """A cache never fails a bake nor changes it: a cache of another input,
    an unreadable one, or one whose entries fail the checks an authored
    binding gets is ignored and the binding computed."""
    src = tmp_path / "tube.usda"
    shutil.copy(repo_root / "fixtures" / "tube.usda", src)
    shot, fresh = tmp_path / "a" / "shot.usda", tmp_path / "b" / "shot.usda"
    shot.parent.mkdir(), fresh.parent.mkdir()
    _chunk_task(painterly, src, shot, 0)
    cache = shot.parent / "shot.clips" / "shot.binding.usdc"
    if damage == "other input":
        src.write_text(src.read_text().replace("timeCodesPerSecond = 24", "timeCodesPerSecond = 24.0"))
    elif damage == "garbage":
        cache.write_bytes(b"PXR-USDC" + bytes(range(256)) * 8)
    else:
        layer = Sdf.Layer.FindOrOpen(str(cache))
        attr = layer.GetAttributeAtPath("/Tube/Paint/Rings.painterly:bindVertices")
        verts = list(attr.default)
        if damage == "out of range":
            verts[0] = (10**6, 0, 0)
        else:
            verts = verts[:-1]
        attr.default = verts
        layer.Save()
    log = _chunk_task(painterly, src, shot, 2)
    if damage in ("other input", "garbage"):
        assert "from the binding cache" not in log and "binding cache" in log and "ignored" in log
    else:  # only the damaged layer's entry is refused; the other layer's is used
        assert "binding cache entry ignored: " in log and "/Tube/Paint/Rings" in log
        assert "took the binding of 1 stroke layer from the binding cache" in log
    _chunk_task(painterly, src, fresh, 2)
    name = "shot.0002.11-15.usdc"
    assert (shot.parent / "shot.clips" / name).read_bytes() == (fresh.parent / "shot.clips" / name).read_bytes()


def test_a_chunk_from_another_painterly_version_is_stale(painterly, tmp_path, repo_root):
    """Same input, other version stamp: inspect reports the chunk stale
    (not done) and the assembly refuses it."""
    src, shot = repo_root / "fixtures" / "tube.usda", tmp_path / "shot.usda"
    painterly("bake", src, "-o", shot, "--chunk", "10", "--quiet")
    chunk = tmp_path / "shot.clips" / "shot.0001.11-20.usdc"
    layer = Sdf.Layer.FindOrOpen(str(chunk))
    data = dict(layer.customLayerData)
    info = dict(data["painterly"])
    assert info["version"] != "0.0.1-other"
    info["version"] = "0.0.1-other"
    data["painterly"] = info
    layer.customLayerData = data
    layer.Save()
    proc = painterly("inspect", shot, "--json", check=False)
    chunks = json.loads(proc.stdout)["clip_set"]["chunks"]
    assert [c["state"] for c in chunks] == ["done", "stale", "done"]
    assert chunks[1]["detail"] == "baked by painterly 0.0.1-other"
    proc = painterly("bake", src, "-o", shot, "--chunk", "10", "--assemble", check=False)
    assert proc.returncode == 1
    assert "1 stale: shot.0001.11-20.usdc (baked by painterly 0.0.1-other)" in proc.stderr
