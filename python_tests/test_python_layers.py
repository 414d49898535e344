"""The `painterly` Python package's inputs and Ctrl-C (review of issue 14):

- a saved `Sdf.Layer` (clean, its realPath a regular file) is read from its
  file, exactly as its path would be: the bake is the CLI's, byte for byte,
  for .usda, .usdc and .usd, even when the file was replaced after the
  layer was opened; a layer that is not its own file (inside a .usdz
  package) is read through its text and marked unsaved;
- unsaved edits (or anonymous layers) in what an input composes are refused
  with `painterly.Error` naming the layer, not silently read from disk;
- a `Usd.Stage` is a TypeError with a hint;
- errors about a layer read through its text name its identifier, never
  the made-up path its text was served at;
- Ctrl-C stops a bake: KeyboardInterrupt comes promptly, the previous
  output is untouched and no temporary file is left.

Expected values come from the CLI and usd-core, never from the binding.
"""

import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdUtils

from conftest import REPO, run_painterly

if os.environ.get("PAINTERLY_PYTHON_PACKAGE") == "required":
    import painterly
else:
    painterly = pytest.importorskip("painterly")

TUBE = REPO / "fixtures" / "tube.usda"
RINGS = "/Tube/Paint/Rings"


def no_seconds(path):
    """A .usda bake without the line that records how long it took."""
    return "\n".join(l for l in path.read_text().splitlines() if "seconds" not in l)


def view_warnings(src, bake, tmp_path):
    out = run_painterly("view", src, "--bake", bake, "-o", tmp_path / "view.usda", "--json").stdout
    return json.loads(out)["warnings"]


def opacity(bake, prim, t):
    """A baked prim's displayOpacity at `t`, read with usd-core."""
    stage = Usd.Stage.Open(str(bake))
    return np.asarray(UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(prim)).GetPrimvar("displayOpacity").Get(t))


# ---------------------------------------------------------------------------
# a saved layer is its file


def test_a_saved_layer_is_read_from_its_file(tmp_path):
    """Before, every layer was read through ExportToString() and served at
    `realPath + ".usda"`: a .usdc layer's bake recorded `tube.usdc.usda` and
    the stamp of no file, so `view` over the file refused it."""
    for ext, args in [("usda", {}), ("usdc", {}), ("usd", {"format": "usda"})]:
        d = tmp_path / ext
        d.mkdir()
        src = d / f"tube.{ext}"
        assert Sdf.Layer.FindOrOpen(str(TUBE)).Export(str(src), args=args)
        layer = Sdf.Layer.FindOrOpen(str(src))
        assert not layer.dirty and layer.realPath == str(src)
        cli, py = d / "cli.usda", d / "py.usda"
        run_painterly("bake", src, "-o", cli, "--frames", "1:4")
        summary = painterly.bake(layer, py, frames="1:4")
        assert summary["input"] == str(src), ext
        assert no_seconds(py) == no_seconds(cli), ext
        assert view_warnings(src, py, d) == [], ext
        # A chunked bake (matched to the file by its stamp) works from the layer too.
        clips = d / "clips.usda"
        painterly.bake(layer, clips, frames="1:4", chunk=2)
        assert view_warnings(src, clips, d) == [], ext


def test_a_saved_layer_replaced_on_disk_is_read_from_the_new_file(tmp_path):
    """A session holds a clean layer while another process publishes a new
    file in its place: the bake is what a farm would bake from the file
    (before: the layer's old text, stamped with the new file's stamp)."""
    src = tmp_path / "tube.usda"
    shutil.copy(TUBE, src)
    held = Sdf.Layer.FindOrOpen(str(src))
    new = Sdf.Layer.OpenAsAnonymous(str(src))
    publish = Usd.Stage.Open(new)
    publish.GetPrimAtPath(RINGS).CreateAttribute("painterly:opacity", Sdf.ValueTypeNames.Float).Set(0.3)
    assert new.Export(str(tmp_path / "publish.usda"))
    os.replace(tmp_path / "publish.usda", src)
    assert not held.dirty and not held.GetPropertyAtPath(f"{RINGS}.painterly:opacity")  # usd-core: still the old content
    cli, py = tmp_path / "cli.usda", tmp_path / "py.usda"
    run_painterly("bake", src, "-o", cli, "--frames", "1:2")
    painterly.bake(held, py, frames="1:2")
    assert no_seconds(py) == no_seconds(cli)
    old = tmp_path / "old.usda"
    run_painterly("bake", TUBE, "-o", old, "--frames", "1:2")
    assert np.allclose(opacity(py, RINGS, 1), np.float32(0.3) * opacity(old, RINGS, 1))


def test_a_layer_inside_a_package_is_read_through_its_text_as_unsaved(tmp_path):
    """A clean layer whose realPath is no regular file (a layer inside a
    .usdz) cannot be read as a file: its text is baked, and the bake says
    it is not the file (before: stamped as if it were)."""
    crate = tmp_path / "tube.usdc"
    assert Sdf.Layer.FindOrOpen(str(TUBE)).Export(str(crate))
    pkg = tmp_path / "tube.usdz"
    assert UsdUtils.CreateNewUsdzPackage(str(crate), str(pkg))
    layer = Sdf.Layer.FindOrOpen(f"{pkg}[tube.usdc]")
    assert not layer.dirty and not os.path.isfile(layer.realPath)
    py, cli = tmp_path / "py.usdc", tmp_path / "cli.usdc"
    summary = painterly.bake(layer, py, frames="1:3")
    assert summary["input"] == layer.identifier
    assert Sdf.Layer.FindOrOpen(str(py)).customLayerData["painterly"]["inputStamp"].startswith("unsaved:")
    run_painterly("bake", crate, "-o", cli, "--frames", "1:3")
    a, b = Usd.Stage.Open(str(py)), Usd.Stage.Open(str(cli))
    for t in (1, 2, 3):
        pa = np.asarray(a.GetPrimAtPath(RINGS).GetAttribute("points").Get(t))
        pb = np.asarray(b.GetPrimAtPath(RINGS).GetAttribute("points").Get(t))
        assert np.array_equal(pa, pb)


def test_a_package_layer_that_composes_a_sibling_is_refused_not_resolved_beside_the_package(tmp_path):
    """`pkg.usdz[root.usda]` referencing `./base.usda` (inside the package
    for usd-core) was served as text beside the package, so an older
    base.usda on disk there was baked instead, 1 unit off (a Python review,
    2026-12-07). Refused, naming the layer and what it composes; the
    package's path still bakes what usd-core composes."""
    build = tmp_path / "build"
    build.mkdir()
    shutil.copy(TUBE, build / "base.usda")
    root = Sdf.Layer.CreateNew(str(build / "root.usda"))
    root.startTimeCode, root.endTimeCode = 1, 24
    Sdf.CreatePrimInLayer(root, "/Shot").specifier = Sdf.SpecifierDef
    fish = Sdf.CreatePrimInLayer(root, "/Shot/Tube")
    fish.specifier = Sdf.SpecifierDef
    fish.referenceList.Prepend(Sdf.Reference("./base.usda", "/Tube"))
    root.Save()
    pkg = tmp_path / "pkg.usdz"
    assert UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(str(build / "root.usda")), str(pkg))
    shutil.copy(TUBE, tmp_path / "base.usda")  # a decoy beside the package
    inner = Sdf.Layer.FindOrOpen(f"{pkg}[root.usda]")
    edited = Usd.Stage.Open(str(pkg))
    edited.GetPrimAtPath("/Shot").SetMetadata("comment", "tweak")
    for layer in (inner, edited.GetRootLayer()):
        with pytest.raises(painterly.Error) as e:
            painterly.Character(layer)
        assert str(e.value).startswith(f"{layer.identifier} is a layer of a package with unsaved edits or read "
                                       "from inside it, and it composes ./base.usda: "), str(e.value)
        with pytest.raises(painterly.Error):
            painterly.bake(layer, frames="1:1")
    # The package by path: read inside it, as usd-core composes it.
    got = painterly.Character(str(pkg)).evaluate(1)["/Shot/Tube/Paint/Rings"]
    want = painterly.Character(str(build / "root.usda")).evaluate(1)["/Shot/Tube/Paint/Rings"]
    assert np.array_equal(got, want)


# ---------------------------------------------------------------------------
# unsaved edits in what an input composes


def shot_over_tube(tmp_path):
    """shot.usda sublayers asset.usda, which references tube.usda inside a
    variant: a dependency two arcs down, one of them in a variant."""
    shutil.copy(TUBE, tmp_path / "tube.usda")
    asset = Usd.Stage.CreateNew(str(tmp_path / "asset.usda"))
    prim = asset.DefinePrim("/Tube")
    look = prim.GetVariantSets().AddVariantSet("look")
    look.AddVariant("painted")
    look.SetVariantSelection("painted")
    with look.GetVariantEditContext():
        prim.GetReferences().AddReference("./tube.usda", "/Tube")
    asset.GetRootLayer().Save()
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.subLayerPaths.append("./asset.usda")
    shot.startTimeCode, shot.endTimeCode = 1, 24
    shot.Save()
    return Usd.Stage.Open(str(tmp_path / "shot.usda"))


def test_unsaved_edits_in_a_composed_layer_are_refused(tmp_path):
    """Before, they were silently ignored: painterly read tube.usda from disk."""
    stage = shot_over_tube(tmp_path)
    tube = Sdf.Layer.Find(str(tmp_path / "tube.usda"))
    fix = Usd.Stage.Open(tube)  # an asset-level fix, not saved yet
    fix.GetPrimAtPath(RINGS).CreateAttribute("painterly:opacity", Sdf.ValueTypeNames.Float).Set(0.25)
    root = stage.GetRootLayer()
    assert tube.dirty and not root.dirty
    assert stage.GetPrimAtPath(RINGS).GetAttribute("painterly:opacity").Get() == 0.25  # usd-core composes the edit
    before = sorted(os.listdir(tmp_path))
    for call in (
        lambda: painterly.bake(root, tmp_path / "bake.usda", frames="1:2"),
        lambda: painterly.bake(root, frames="1:2"),
        lambda: painterly.Character(root),
        lambda: painterly.inspect(root),
    ):
        with pytest.raises(painterly.Error) as e:
            call()
        assert e.value.file == tube.identifier
        assert str(e.value).startswith(f"{tube.identifier}: a layer with unsaved edits that {root.identifier} composes")
        assert "save it, or pass stage.Flatten()" in e.value.message
    assert sorted(os.listdir(tmp_path)) == before
    # What the message offers works: the flattened stage bakes the edit.
    flat = painterly.bake(stage.Flatten(), frames="5")
    old = tmp_path / "old.usda"
    run_painterly("bake", TUBE, "-o", old, "--frames", "5")
    got = Usd.Stage.Open(painterly.to_layer(flat["layer"]))
    got = np.asarray(UsdGeom.PrimvarsAPI(got.GetPrimAtPath(RINGS)).GetPrimvar("displayOpacity").Get(5))
    assert np.allclose(got, np.float32(0.25) * opacity(old, RINGS, 5))
    # And once saved, the layer is the file again.
    tube.Save()
    assert painterly.inspect(root)["problems"] == []


def test_an_anonymous_composed_layer_is_refused_naming_it(tmp_path):
    """Before: "missing asset ... (in /cwd/anonymous.usda)", a path that does not exist."""
    inner = Sdf.Layer.CreateAnonymous("inner.usda")
    inner.TransferContent(Sdf.Layer.FindOrOpen(str(TUBE)))
    top = Sdf.Layer.CreateAnonymous("top.usda")
    top.subLayerPaths.append(inner.identifier)
    with pytest.raises(painterly.Error) as e:
        painterly.Character(top)
    assert e.value.file == inner.identifier
    assert e.value.message.startswith(f"an anonymous layer (only in memory) that {top.identifier} composes")
    assert "anonymous.usda" not in str(e.value)


def test_a_stage_is_a_type_error_with_a_hint():
    stage = Usd.Stage.Open(str(TUBE))
    for call in (painterly.bake, painterly.inspect, painterly.Character):
        with pytest.raises(TypeError) as e:
            call(stage)
        assert str(e.value) == (
            "expected a file path or an Sdf.Layer, got Stage: pass stage.GetRootLayer() (read as saved), "
            "or stage.Flatten() to include unsaved edits across its layers"
        )


def test_errors_about_a_layer_read_through_its_text_name_its_identifier(tmp_path, monkeypatch):
    """An anonymous layer's text is served as `anonymous.usda` in the working
    directory (so relative paths resolve from there): no message may name
    that path, which does not exist."""
    monkeypatch.chdir(tmp_path)
    top = Sdf.Layer.CreateAnonymous("top.usda")
    top.subLayerPaths.append("./nowhere.usda")
    served = str(tmp_path / "anonymous.usda")
    with pytest.raises(painterly.Error) as e:
        painterly.Character(top)
    assert e.value.file == top.identifier
    assert served not in str(e.value) and f"(in {top.identifier})" in e.value.message
    report = painterly.inspect(top)
    assert [a["layer"] for a in report["unresolved_assets"]] == [top.identifier]
    assert report["problems"] and all(served not in p["message"] for p in report["problems"])
    assert served not in json.dumps(report)


# ---------------------------------------------------------------------------
# Ctrl-C


CHILD = """
import signal, sys, time, painterly
# A shell's background job starts with SIGINT ignored, and Python then
# installs no KeyboardInterrupt handler: install it, as an interactive run has.
signal.signal(signal.SIGINT, signal.default_int_handler)
seen = [0, 0]
def progress(done, total):
    if done == 1:
        print("started", flush=True)
    seen[:] = [done, total]
try:
    painterly.bake(sys.argv[1], sys.argv[2], frames="1:24:0.0005", progress=progress)
    print("finished", flush=True)
except KeyboardInterrupt:
    print("interrupted", seen[0], seen[1], time.monotonic(), flush=True)
"""


def test_ctrl_c_stops_a_bake_and_keeps_the_previous_output(tmp_path):
    """Before, the bake ran to its end, replaced the output, and only then
    raised KeyboardInterrupt."""
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    out = out_dir / "bake.usdc"
    run_painterly("bake", TUBE, "-o", out, "--frames", "1:2")
    previous = out.read_bytes()
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(TUBE), str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout.readline().strip() == "started"
        time.sleep(0.3)
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        stdout, stderr = child.communicate(timeout=120)
    finally:
        if child.poll() is None:
            child.kill()
    words = stdout.split()
    assert words[:1] == ["interrupted"], (stdout, stderr)
    done, total, at = int(words[1]), int(words[2]), float(words[3])
    assert done < total
    assert at - sent < 2.0  # prompt: within a few frames, not at the bake's end
    assert out.read_bytes() == previous
    assert sorted(os.listdir(out_dir)) == ["bake.usdc"]


# ---------------------------------------------------------------------------
# an edited crate layer, and edits behind a layer not open (a review, 2026-12-06)


def test_an_edited_crate_layer_is_never_baked_over_its_own_file(tmp_path):
    """An edited `.usdc` layer is read from its text, served as
    `tube.usdc.usda`; the output check compared the output with that made-up
    name, so `bake(layer, "tube.usdc")` replaced the input with the bake.
    The CLI refuses the same command."""
    crate = tmp_path / "tube.usdc"
    Sdf.Layer.FindOrOpen(str(TUBE)).Export(str(crate))
    before = crate.read_bytes()
    layer = Sdf.Layer.FindOrOpen(str(crate))
    layer.customLayerData = {"note": "an unsaved edit"}
    with pytest.raises(painterly.Error, match="output would overwrite the input; inputs are never modified"):
        painterly.bake(layer, str(crate), frames="1:2")
    assert crate.read_bytes() == before


def test_a_bake_of_an_edited_crate_layer_records_its_file(tmp_path):
    """It recorded the made-up `tube.usdc.usda` as its input, so `view`
    refused the bake as made from another file; it records `tube.usdc` now,
    and view warns that it was baked from unsaved edits, as for a `.usda`."""
    crate = tmp_path / "tube.usdc"
    Sdf.Layer.FindOrOpen(str(TUBE)).Export(str(crate))
    layer = Sdf.Layer.FindOrOpen(str(crate))
    layer.customLayerData = {"note": "an unsaved edit"}
    bake = tmp_path / "bake.usdc"
    painterly.bake(layer, str(bake), frames="1:2")
    recorded = Sdf.Layer.FindOrOpen(str(bake)).customLayerData["painterly"]["input"]
    assert recorded == str(crate.resolve())
    assert any("baked from unsaved edits" in w for w in view_warnings(crate, bake, tmp_path))


def test_unsaved_edits_behind_a_layer_not_open_are_refused(tmp_path):
    """root (passed, saved) → mid (not open in the session) → leaf (open,
    edited): the walk over open layers stopped at mid and the edit was
    silently left out (Rings baked at opacity 1, usd-core composes 0.25)."""
    leaf_path = tmp_path / "leaf.usda"
    Sdf.Layer.FindOrOpen(str(TUBE)).Export(str(leaf_path))
    mid = Sdf.Layer.CreateNew(str(tmp_path / "mid.usda"))
    mid.subLayerPaths.append("leaf.usda")
    mid.Save()
    root = Sdf.Layer.CreateNew(str(tmp_path / "root.usda"))
    root.subLayerPaths.append("mid.usda")
    root.Save()
    del mid
    leaf = Sdf.Layer.FindOrOpen(str(leaf_path))
    Sdf.AttributeSpec(leaf.GetPrimAtPath(RINGS), "painterly:opacity", Sdf.ValueTypeNames.Float).default = 0.25
    assert Sdf.Layer.Find(str(tmp_path / "mid.usda")) is None
    with pytest.raises(painterly.Error, match="a layer with unsaved edits that .*root.usda composes") as e:
        painterly.bake(root, frames="1")
    assert e.value.file == str(leaf_path)
    leaf.Save()
    assert painterly.bake(root, frames="1")["frames"] == 1
