"""`painterly view`: an assembly layer that shows a bake over its input in
usdview at the baked frames, with nothing for UsdValidation to report."""

import json
import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdValidation


def validation_errors(stage):
    registry = UsdValidation.ValidationRegistry()
    ctx = UsdValidation.ValidationContext(registry.GetOrLoadAllValidators())
    return [e.GetMessage() for e in ctx.Validate(stage)]


def test_view_layer_shows_the_bake_at_its_frames(painterly, tmp_path, repo_root):
    src = repo_root / "fixtures" / "blowfish.usda"
    shot = tmp_path / "shot"
    shot.mkdir()
    bake = shot / "fish_bake.usdc"
    painterly("bake", src, "-o", bake, "--frames", "5:20")
    view = shot / "fish_view.usda"
    out = json.loads(painterly("view", src, "--bake", bake, "-o", view, "--json").stdout)
    assert out == {
        "input": str(src),
        "bake": str(bake),
        "output": str(view),
        "start_time_code": 5.0,
        "end_time_code": 20.0,
        "default_prim": "Blowfish",
        "warnings": [],
    }
    layer = Sdf.Layer.FindOrOpen(str(view))
    assert list(layer.subLayerPaths)[0] == "./fish_bake.usdc"
    stage = Usd.Stage.Open(str(view))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (5, 20)
    assert stage.GetTimeCodesPerSecond() == 24 and stage.GetFramesPerSecond() == 24
    assert UsdGeom.GetStageUpAxis(stage) == "Y" and UsdGeom.GetStageMetersPerUnit(stage) == 0.01
    assert stage.GetDefaultPrim().GetPath() == "/Blowfish"
    assert validation_errors(stage) == []
    baked = Sdf.Layer.FindOrOpen(str(bake))
    path = "/Blowfish/Paint/Spikes.points"
    for t in (5, 12, 20):
        np.testing.assert_array_equal(
            np.array(stage.GetAttributeAtPath(path).Get(t)), np.array(baked.QueryTimeSample(path, t))
        )
    # Moving the shot folder keeps the bake (relative path).
    moved = tmp_path / "moved"
    shot.rename(moved)
    stage = Usd.Stage.Open(str(moved / "fish_view.usda"))
    assert len(stage.GetAttributeAtPath(path).Get(12)) == 780


def test_view_refuses_a_bake_of_another_input(painterly, tmp_path, repo_root):
    bake = tmp_path / "apple.usdc"
    painterly("bake", repo_root / "fixtures" / "apple.usda", "-o", bake, "--frames", "1:2")
    proc = painterly("view", repo_root / "fixtures" / "blowfish.usda", "--bake", bake, "-o", tmp_path / "v.usda", check=False)
    assert proc.returncode == 1
    assert "was made from" in proc.stderr and "apple.usda" in proc.stderr
    assert not (tmp_path / "v.usda").exists()


def layers_digest(files, content):
    """SHA-256 over the layer files, sorted by resolved path: for each, the
    path's bytes and a NUL, then the file's bytes (`inputHash`) or its size
    and modification time in ns (`inputStamp`), as docs/render.md defines."""
    import hashlib

    h = hashlib.sha256()
    for f in sorted(str(Path(f).resolve()) for f in files):
        h.update(f.encode() + b"\0")
        st = Path(f).stat()
        h.update(Path(f).read_bytes() if content else f"{st.st_size} {st.st_mtime_ns}\n".encode())
    return h.hexdigest()


@pytest.mark.parametrize("chunk", [None, "5"])
def test_a_stale_bake_is_shown_with_a_warning(painterly, tmp_path, repo_root, chunk):
    """A bake records the hash of its input's layers; when the input or one
    of its sublayers changed since, view, render and preview still show the
    bake (it may be what the TD wants) but say it is stale."""
    shutil.copyfile(repo_root / "fixtures" / "apple.usda", tmp_path / "body.usda")
    src = tmp_path / "apple.usda"
    stage = Usd.Stage.CreateNew(str(src))
    stage.GetRootLayer().subLayerPaths.append("./body.usda")
    stage.GetRootLayer().defaultPrim = "Apple"
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(10)
    stage.Save()
    bake = tmp_path / ("bake.usda" if chunk else "bake.usdc")
    painterly("bake", src, "-o", bake, *(["--chunk", chunk] if chunk else []))
    recorded = Sdf.Layer.FindOrOpen(str(bake)).customLayerData["painterly"]
    files = [src, tmp_path / "body.usda"]
    assert recorded["inputStamp"] == layers_digest(files, content=False)
    # A chunked bake also records the content hash, which its chunks are checked by.
    assert recorded.get("inputHash") == (layers_digest(files, content=True) if chunk else None)
    field = "inputHash" if chunk else "inputStamp"
    view = tmp_path / "v.usda"
    args = ("view", src, "--bake", bake, "-o", view, "--json")
    assert json.loads(painterly(*args).stdout)["warnings"] == []
    # An edit to the sublayer, saved by usd-core.
    body = Usd.Stage.Open(str(tmp_path / "body.usda"))
    rest = body.GetPrimAtPath("/Apple/Paint/Skin").GetAttribute("painterly:restPoints")
    rest.Set([p * 1.5 for p in rest.Get()])
    body.Save()
    warning = (
        f"{src} changed since this bake was made (its layers differ from the bake's {field}): "
        f"strokes show the old bake; bake again (painterly bake {src} -o {bake} --frames {recorded['frames']}"
        + (f" --chunk {chunk})" if chunk else ")")
    )
    proc = painterly(*args)
    assert json.loads(proc.stdout)["warnings"] == [warning]
    assert proc.stderr == f"warning: {warning}\n"
    assert view.exists()
    cam = ["--camera", "/Apple/Camera", "--frames", "1", "--size", "32x18", "--json"]
    rendered = painterly("render", src, "--bake", bake, "-o", tmp_path / "f.####.exr", *cam)
    assert json.loads(rendered.stdout)["warnings"] == [warning]
    # Saved again unchanged: a chunked bake checks the bytes, a single
    # file the modification time.
    painterly("bake", src, "-o", bake, *(["--chunk", chunk] if chunk else []))
    os.utime(tmp_path / "body.usda", ns=(0, 1_000_000_000))
    assert json.loads(painterly(*args).stdout)["warnings"] == ([] if chunk else [warning])
    # Baked again, the warning is gone.
    painterly("bake", src, "-o", bake, *(["--chunk", chunk] if chunk else []))
    assert json.loads(painterly(*args).stdout)["warnings"] == []


@pytest.mark.parametrize("name", ["v.usdc", "v.usd"])
def test_a_view_layer_not_named_usda_is_a_usage_error(painterly, tmp_path, repo_root, name):
    """The view layer is text; any other output name is a command-line
    mistake (exit 2), as a bake's wrong extension is."""
    bake = tmp_path / "tube.usdc"
    painterly("bake", repo_root / "fixtures" / "tube.usda", "-o", bake, "--frames", "1:2")
    out = tmp_path / name
    proc = painterly("view", repo_root / "fixtures" / "tube.usda", "--bake", bake, "-o", out, check=False)
    assert (proc.returncode, proc.stderr) == (2, f"error: {out}: the view layer is text: name it .usda\n")
    assert not out.exists()


def test_view_of_a_clip_set_bake(painterly, tmp_path, repo_root):
    src = repo_root / "fixtures" / "tube.usda"
    painterly("bake", src, "-o", tmp_path / "shot.usda", "--chunk", "10")
    painterly("view", src, "--bake", tmp_path / "shot.usda", "-o", tmp_path / "view.usda")
    stage = Usd.Stage.Open(str(tmp_path / "view.usda"))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (1, 24)
    single = tmp_path / "single.usdc"
    painterly("bake", src, "-o", single)
    path = "/Tube/Paint/Rings.points"
    reference = Usd.Stage.Open(str(single))
    for t in (3, 11, 12.5, 24):
        np.testing.assert_allclose(
            np.array(stage.GetAttributeAtPath(path).Get(t)),
            np.array(reference.GetAttributeAtPath(path).Get(t)),
            rtol=0, atol=1e-6,
        )
    assert validation_errors(stage) == []


def test_view_layer_paths_are_relative_to_its_own_folder(painterly, tmp_path, repo_root):
    """Sublayer paths are relative to the view layer's folder, as USD
    resolves them: `./` beside it, `../` up to a sibling folder (no `./`
    before it), also when -o is a bare file name (the current folder)."""
    assets, shot = tmp_path / "assets", tmp_path / "shot"
    assets.mkdir(), shot.mkdir()
    src = assets / "tube.usda"
    shutil.copy(repo_root / "fixtures" / "tube.usda", src)
    painterly("bake", src, "-o", shot / "bake.usdc", "--frames", "1:3")
    painterly("view", src, "--bake", "bake.usdc", "-o", "view.usda", cwd=shot)
    layer = Sdf.Layer.FindOrOpen(str(shot / "view.usda"))
    assert list(layer.subLayerPaths) == ["./bake.usdc", "../assets/tube.usda"]
    stage = Usd.Stage.Open(str(shot / "view.usda"))
    assert [l.realPath for l in stage.GetLayerStack(includeSessionLayers=False)[1:]] == [
        str(shot / "bake.usdc"), str(src)]
    assert stage.GetPrimAtPath("/Tube/Paint/Rings").IsValid()


def test_a_view_written_through_a_linked_folder_opens_from_both_paths(painterly, tmp_path, repo_root):
    """usd-core anchors a relative sublayer path to the path the view was
    opened by, as text: a view written into `views`, a link to a deeper
    folder, named its sublayers between real paths (`../../../../proj/...`)
    and composed nothing when opened through the link (found by a review,
    2026-12-07). Its sublayers now resolve from the link and from the real
    folder; the bake beside it stays `./`."""
    proj, deep = tmp_path / "proj", tmp_path / "scratch" / "user" / "a" / "b" / "views"
    proj.mkdir(), deep.mkdir(parents=True)
    (tmp_path / "views").symlink_to(deep)
    src = proj / "tube.usda"
    shutil.copy(repo_root / "fixtures" / "tube.usda", src)
    bake = tmp_path / "views" / "bake.usdc"
    painterly("bake", src, "-o", bake, "--frames", "1:3")
    painterly("view", src, "--bake", bake, "-o", tmp_path / "views" / "view.usda")
    layer = Sdf.Layer.FindOrOpen(str(deep / "view.usda"))
    assert list(layer.subLayerPaths) == ["./bake.usdc", str(src)]
    # And from a shell that went into the link (`cd views`: $PWD is the
    # link's path, the process's working folder the real one).
    painterly("view", src, "--bake", "bake.usdc", "-o", "shell.usda", cwd=tmp_path / "views",
              env={**os.environ, "PWD": str(tmp_path / "views")})
    layer = Sdf.Layer.FindOrOpen(str(deep / "shell.usda"))
    assert list(layer.subLayerPaths) == ["./bake.usdc", str(src)]
    for opened in (tmp_path / "views" / "view.usda", deep / "view.usda", tmp_path / "views" / "shell.usda"):
        stage = Usd.Stage.Open(str(opened))
        assert len(stage.GetLayerStack(includeSessionLayers=False)) == 3, opened
        assert len(stage.GetAttributeAtPath("/Tube/Paint/Rings.points").Get(2)) > 0, opened
