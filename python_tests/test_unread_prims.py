"""Key prims a composed stage does not hold are not read (USD semantics, as
usd-core's `GetChildren()` lists a prim's children): a deactivated key
(`active = false`, the way a shot drops an asset's key it cannot delete),
an `over` that no layer defines, and a `class`. The expected bake is the
bake of the same stage with those prims removed, so the reference is
USD's own rule, not painterly's output.
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from pxr import Sdf, Usd

from conftest import REPO

FISH = "/Blowfish/Paint/Spikes"
FACE = "/Head/Face"


def shot_over(tmp_path, fixture, edit):
    """A shot layer that sublayers a copy of `fixture` and holds `edit`'s
    opinions; returns (shot, copy)."""
    asset = tmp_path / fixture
    shutil.copy(REPO / "fixtures" / fixture, asset)
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.subLayerPaths.append(f"./{fixture}")
    src = Sdf.Layer.FindOrOpen(str(asset))
    for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "upAxis", "metersPerUnit"):
        if src.pseudoRoot.HasInfo(key):
            shot.pseudoRoot.SetInfo(key, src.pseudoRoot.GetInfo(key))
    stage = Usd.Stage.Open(shot)
    stage.SetEditTarget(shot)
    edit(stage)
    shot.Save()
    return tmp_path / "shot.usda", asset


def removed(tmp_path, fixture, paths):
    """A copy of `fixture` without the prims at `paths`."""
    out = tmp_path / f"removed_{fixture}"
    shutil.copy(REPO / "fixtures" / fixture, out)
    layer = Sdf.Layer.FindOrOpen(str(out))
    for p in paths:
        parent = layer.GetPrimAtPath(Sdf.Path(p).GetParentPath())
        del parent.nameChildren[Sdf.Path(p).name]
    layer.Save()
    return out


def baked_points(painterly, tmp_path, inp, prim, name, frames="1:48:4"):
    out = tmp_path / f"bake_{name}.usdc"
    painterly("bake", inp, "-o", out, "--frames", frames, "--quiet")
    stage = Usd.Stage.Open(str(out))
    attr = stage.GetPrimAtPath(prim).GetAttribute("points")
    return {t: np.array(attr.Get(t)) for t in attr.GetTimeSamples()}


def layer_report(painterly, inp, layer):
    rep = json.loads(painterly("inspect", inp, "--json").stdout)
    assert rep["problems"] == []
    return next(lay for lay in rep["rigs"][0]["layers"] if lay["path"] == layer)


def deactivate(*paths):
    def edit(stage):
        for p in paths:
            stage.OverridePrim(p).SetActive(False)
    return edit


@pytest.mark.parametrize("keys", [
    [f"{FISH}/shock"],                     # a time key
    [f"{FISH}/half"],                      # a pose key
    [f"{FISH}/half", f"{FISH}/shockStart"],  # a pose key and a sentinel
])
def test_a_deactivated_key_is_not_read(painterly, tmp_path, keys):
    shot, _ = shot_over(tmp_path, "blowfish.usda", deactivate(*keys))
    want_input = removed(tmp_path, "blowfish.usda", keys)
    got = baked_points(painterly, tmp_path, shot, FISH, "shot")
    want = baked_points(painterly, tmp_path, want_input, FISH, "removed")
    full = baked_points(painterly, tmp_path, REPO / "fixtures" / "blowfish.usda", FISH, "full")
    assert sorted(got) == sorted(want) and len(got) == 12
    assert all(np.array_equal(got[t], want[t]) for t in got)
    # The key did something: without it the bake differs.
    assert any(not np.array_equal(got[t], full[t]) for t in got)
    assert layer_report(painterly, shot, FISH) == layer_report(painterly, want_input, FISH)


def test_an_over_or_a_class_is_not_a_key(painterly, tmp_path):
    """A stronger layer's `over` with a key's type but no `def` anywhere,
    and a `class` key, hold no key a bake reads."""
    def edit(stage):
        layer = stage.GetEditTarget().GetLayer()
        for name, spec in (("ghost", Sdf.SpecifierOver), ("abstract", Sdf.SpecifierClass)):
            parent = Sdf.CreatePrimInLayer(layer, FISH)
            prim = Sdf.PrimSpec(parent, name, spec, "PainterlyTimeKey")
            Sdf.AttributeSpec(prim, "time", Sdf.ValueTypeNames.Double).default = 20.0
            pts = stage.GetPrimAtPath(f"{FISH}/shock").GetAttribute("points").Get()
            Sdf.AttributeSpec(prim, "points", Sdf.ValueTypeNames.Point3fArray).default = pts
    shot, _ = shot_over(tmp_path, "blowfish.usda", edit)
    # usd-core's own view: the shot lists the asset's keys and no others.
    shot_stage, asset_stage = (Usd.Stage.Open(str(p)) for p in (shot, REPO / "fixtures" / "blowfish.usda"))
    names = [[c.GetName() for c in st.GetPrimAtPath(FISH).GetChildren()] for st in (shot_stage, asset_stage)]
    assert names[0] == names[1] and "ghost" not in names[0]
    assert shot_stage.GetPrimAtPath(f"{FISH}/abstract").IsAbstract()
    got = baked_points(painterly, tmp_path, shot, FISH, "shot")
    want = baked_points(painterly, tmp_path, REPO / "fixtures" / "blowfish.usda", FISH, "full")
    assert all(np.array_equal(got[t], want[t]) for t in want)
    assert layer_report(painterly, shot, FISH) == layer_report(painterly, REPO / "fixtures" / "blowfish.usda", FISH)


def test_a_deactivated_view_key_is_not_read(painterly, tmp_path):
    key = f"{FACE}/Left"
    shot, _ = shot_over(tmp_path, "head.usda", deactivate(key))
    want_input = removed(tmp_path, "head.usda", [key])
    got = baked_points(painterly, tmp_path, shot, FACE, "shot", "1:96:8")
    want = baked_points(painterly, tmp_path, want_input, FACE, "removed", "1:96:8")
    full = baked_points(painterly, tmp_path, REPO / "fixtures" / "head.usda", FACE, "full", "1:96:8")
    assert sorted(got) == sorted(want) and len(got) == 12
    assert all(np.array_equal(got[t], want[t]) for t in got)
    assert any(not np.array_equal(got[t], full[t]) for t in got)


def test_key_does_not_reuse_a_deactivated_keys_name(painterly, tmp_path):
    """`key --name` of a deactivated key is refused (a key written there
    would stay inactive); an unnamed key takes a free name, and a
    deactivated key at the same time does not count as a clash."""
    shot, _ = shot_over(tmp_path, "blowfish.usda", deactivate(f"{FISH}/shock"))
    before = shot.read_bytes()
    asset = Usd.Stage.Open(str(REPO / "fixtures" / "blowfish.usda"))
    time = asset.GetPrimAtPath(f"{FISH}/shock").GetAttribute("time").Get()
    proc = painterly("key", shot, "--layer", FISH, "--time-key", "--time", str(time), "--points",
                     "--name", "shock", "--replace", "--in-place", check=False)
    assert proc.returncode == 1
    assert proc.stderr == (
        f"error: {shot}: {FISH}/shock: a prim of this name exists but is deactivated (active = false), "
        "so a bake would not read a key there: pick another --name\n")
    assert shot.read_bytes() == before
    painterly("key", shot, "--layer", FISH, "--time-key", "--time", str(time), "--points", "--in-place", "--quiet")
    stage = Usd.Stage.Open(str(shot))
    names = [c.GetName() for c in stage.GetPrimAtPath(FISH).GetChildren()]
    assert "shock" not in names and "time1" in names
    assert stage.GetPrimAtPath(f"{FISH}/time1").GetAttribute("time").Get() == time


def crowd(tmp_path, hero2_instanced=True):
    """A shot referencing the blowfish twice (/Hero1 plain, /Hero2 maybe
    instanceable) and a prop, instanceable, with nothing painterly in it."""
    shutil.copy(REPO / "fixtures" / "blowfish.usda", tmp_path / "blowfish.usda")
    stage = Usd.Stage.CreateNew(str(tmp_path / "shot.usda"))
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(48)
    for name, target, instanced in (("Hero1", "/Blowfish", False), ("Hero2", "/Blowfish", hero2_instanced),
                                     ("Prop", "/Blowfish/EyeTarget", True)):
        p = stage.DefinePrim(f"/{name}", "Xform")
        p.GetReferences().AddReference("./blowfish.usda", target)
        p.SetInstanceable(instanced)
    stage.GetRootLayer().Save()
    assert stage.GetPrimAtPath("/Hero2").IsInstance() == hero2_instanced and stage.GetPrimAtPath("/Prop").IsInstance()
    return tmp_path / "shot.usda"


def test_a_character_inside_an_instance_is_refused_by_name(painterly, tmp_path):
    """USD ignores opinions below an instance, so no bake layer can move an
    instanced character's strokes: inspect names the instance under the
    `instanced` rule, bake and key refuse the stage, an instanced prop with
    nothing painterly in it is fine."""
    shot = crowd(tmp_path)
    message = ("an instance (instanceable = true) holds painterly prims (/Hero2/Paint), which a bake "
               "cannot override: USD ignores opinions below an instance; set `instanceable = false` on /Hero2 to bake it")
    proc = painterly("inspect", shot, "--json", check=False)
    assert proc.returncode == 1
    report = json.loads(proc.stdout)
    assert [(p["prim"], p["attribute"], p["rule"], p["message"]) for p in report["problems"]] == [
        ("/Hero2", None, "instanced", message)]
    message = f"/Hero2: {message}"
    assert [r["path"] for r in report["rigs"]] == ["/Hero1/Paint"]
    out = tmp_path / "bake.usdc"
    proc = painterly("bake", shot, "-o", out, "--frames", "1:48:8", check=False)
    assert (proc.returncode, proc.stderr) == (1, f"error: {shot}: {message}\n")
    assert not out.exists()
    proc = painterly("key", shot, "--layer", "/Hero1/Paint/Spikes", "--time", "9", "--points", "--in-place", check=False)
    assert (proc.returncode, proc.stderr) == (1, f"error: {shot}: {message}\n")


def test_a_character_no_longer_instanced_bakes_like_its_twin(painterly, tmp_path):
    """The fix the message gives: with `instanceable = false` both heroes
    bake, and (same asset, same animation) to the same local points."""
    shot = crowd(tmp_path, hero2_instanced=False)
    out = tmp_path / "bake.usdc"
    painterly("bake", shot, "-o", out, "--frames", "1:48:8", "--quiet")
    stage = Usd.Stage.Open(str(out))
    for layer in ("Spikes", "BodyHatching"):
        a, b = (stage.GetPrimAtPath(f"/{h}/Paint/{layer}").GetAttribute("points") for h in ("Hero1", "Hero2"))
        assert a.GetTimeSamples() == b.GetTimeSamples() == [1.0, 9.0, 17.0, 25.0, 33.0, 41.0]
        assert all(np.array_equal(np.array(a.Get(t)), np.array(b.Get(t))) for t in a.GetTimeSamples())


def test_a_layer_targeting_a_deactivated_axis_is_refused(painterly, tmp_path):
    """usd-core still reads a deactivated prim's attributes, but an axis a
    shot switched off must not go on shaping the layers that name it in
    `painterly:axes`: the axis is one problem (rule `axis`, however many
    layers meet it) naming those layers, and the bake stops."""
    axis = "/Blowfish/Paint/inflate"
    shot, _ = shot_over(tmp_path, "blowfish.usda", deactivate(axis))
    stage = Usd.Stage.Open(str(shot))
    assert stage.GetPrimAtPath(axis).GetAttribute("kind").Get() == "blendShape"  # usd-core reads it
    proc = painterly("inspect", shot, "--json", check=False)
    assert proc.returncode == 1
    problems = json.loads(proc.stdout)["problems"]
    layers = [str(p.GetPath()) for p in stage.Traverse()
              if axis in p.GetRelationship("painterly:axes").GetTargets()]
    assert FISH in layers and len(layers) == 3
    message = (f"the axis is deactivated (active = false), but 3 stroke layers target it in `painterly:axes` "
               f"({', '.join(layers)}): it would go on shaping them unseen")
    assert [(p["prim"], p["attribute"], p["rule"], p["message"]) for p in problems] == [(axis, None, "axis", message)]
    out = tmp_path / "bake.usdc"
    proc = painterly("bake", shot, "-o", out, check=False)
    assert (proc.returncode, proc.stderr) == (1, f"error: {shot}: {axis}: {message}\n")
    assert not out.exists()
