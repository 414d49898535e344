"""`double` times read through a layer offset (SPEC §5–6, USD value
resolution): a reference or sublayer with an offset retimes the time
samples of the layers it brings in, but USD never retimes a `double`, so a
time key's or view key's `time` and a `painterly:restTime` keep the value
written. painterly reads them as usd-core does, and `inspect` notes each
such time with the time the offset would have given (offset + scale × t,
the rule of Sdf.LayerOffset, worked out here from usd-core's own values).
"""

from __future__ import annotations

import json
import shutil

import pytest
from pxr import Sdf, Usd

from conftest import REPO


def shot(tmp_path, fixture, root, offset, scale, how="reference"):
    """A shot that brings `fixture` in under /Hero (a reference to `root`)
    or as a sublayer, with the layer offset (offset, scale)."""
    asset = tmp_path / fixture
    shutil.copy(REPO / "fixtures" / fixture, asset)
    stage = Usd.Stage.CreateNew(str(tmp_path / "shot.usda"))
    src = Usd.Stage.Open(str(asset))
    stage.SetStartTimeCode(offset + scale * src.GetStartTimeCode())
    stage.SetEndTimeCode(offset + scale * src.GetEndTimeCode())
    stage.SetTimeCodesPerSecond(src.GetTimeCodesPerSecond())
    layer_offset = Sdf.LayerOffset(offset, scale)
    if how == "reference":
        stage.DefinePrim("/Hero", "Xform").GetReferences().AddReference(
            Sdf.Reference(f"./{fixture}", root, layer_offset))
    else:
        stage.GetRootLayer().subLayerPaths.append(f"./{fixture}")
        stage.GetRootLayer().subLayerOffsets[0] = layer_offset
    stage.GetRootLayer().Save()
    return tmp_path / "shot.usda", asset, src


def report(painterly, path):
    proc = painterly("inspect", path, "--json")
    rep = json.loads(proc.stdout)
    assert rep["problems"] == []
    return rep


def listed(times, offset, scale):
    return ", ".join(f"{label}{t:g} (not {offset + scale * t:g})" for label, t in times)


def test_time_keys_through_a_reference_offset_are_noted(painterly, tmp_path):
    path, asset, src = shot(tmp_path, "blowfish.usda", "/Blowfish", 10, 2)
    layer = src.GetPrimAtPath("/Blowfish/Paint/Spikes")
    keys = [(f"{c.GetName()} at ", c.GetAttribute("time").Get()) for c in layer.GetChildren()
            if c.GetTypeName() == "PainterlyTimeKey"]
    assert [t for _, t in keys] == [36, 40, 44, 47]
    rig = report(painterly, path)["rigs"][0]
    assert rig["path"] == "/Hero/Paint"
    assert [n for n in rig["notes"] if "layer offset" in n] == [
        f"/Hero/Paint/Spikes: 4 time keys' `double time` come from {asset} through a layer offset "
        "(offset 10, scale 2); USD retimes that layer's time samples but never a double, so the stage reads "
        f"the times written: {listed(keys, 10, 2)}"]
    # usd-core reads the same: the composed time is the value written.
    composed = Usd.Stage.Open(str(path))
    assert composed.GetPrimAtPath("/Hero/Paint/Spikes/shock").GetAttribute("time").Get() == 40


def test_rest_time_and_view_key_times_through_a_sublayer_offset_are_noted(painterly, tmp_path):
    path, asset, src = shot(tmp_path, "walk.usda", "/Walk", -5, 0.5, how="sublayer")
    mesh = "/Walk/Character/Body"
    keys = [(f"{c.GetName()} at ", c.GetAttribute("time").Get())
            for c in src.GetPrimAtPath(mesh).GetChildren() if c.GetTypeName() == "PainterlyViewKey"]
    assert len(keys) == 4
    rep = report(painterly, path)
    (view,) = rep["view_dependent_meshes"]
    # The report lists keys by viewpoint (Front, then Side), each in time order.
    order = [k.rsplit("/", 1)[1] for vp in view["key_viewpoints"] for k in vp["keys"]]
    keys = sorted(keys, key=lambda k: order.index(k[0][:-len(" at ")]))
    assert view["notes"] == [
        f"{mesh}: 4 view keys' `double time` come from {asset} through a layer offset (offset -5, scale 0.5); "
        "USD retimes that layer's time samples but never a double, so the stage reads the times written: "
        f"{listed(keys, -5, 0.5)}"]
    (tmp_path / "wave").mkdir()
    wave, wave_asset, wave_src = shot(tmp_path / "wave", "wave.usda", "/Wave", 100, 1)
    rest = wave_src.GetPrimAtPath("/Wave/Paint").GetAttribute("painterly:restTime").Get()
    rig = report(painterly, wave)["rigs"][0]
    assert [n for n in rig["notes"] if "layer offset" in n] == [
        f"/Hero/Paint: its `double painterly:restTime` comes from {wave_asset} through a layer offset "
        "(offset 100, scale 1); USD retimes that layer's time samples but never a double, so the stage reads "
        f"the times written: {rest:g} (not {100 + rest:g})"]


@pytest.mark.parametrize("fixture,root", [("blowfish.usda", "/Blowfish"), ("walk.usda", "/Walk")])
def test_no_note_without_an_offset(painterly, tmp_path, fixture, root):
    for how in ("reference", "sublayer"):
        (tmp_path / how).mkdir()
        path, _, _ = shot(tmp_path / how, fixture, root, 0, 1, how=how)
        rep = report(painterly, path)
        notes = [n for r in rep["rigs"] for n in r["notes"]] + [n for m in rep["view_dependent_meshes"] for n in m["notes"]]
        assert not [n for n in notes if "layer offset" in n], notes


@pytest.mark.parametrize("extra,more", [(1, ""), (3, " and 2 more")])
def test_a_long_list_of_offset_times_names_five(painterly, tmp_path, extra, more):
    """The note lists five times at most, then how many more."""
    src_path = tmp_path / "blowfish.usda"
    shutil.copy(REPO / "fixtures" / "blowfish.usda", src_path)
    layer = "/Blowfish/Paint/Spikes"
    asset = Usd.Stage.Open(str(src_path))
    for i in range(extra):
        key = asset.DefinePrim(f"{layer}/extra{i}", "PainterlyTimeKey")
        key.CreateAttribute("time", Sdf.ValueTypeNames.Double).Set(10.0 + i)
        key.CreateAttribute("sentinel", Sdf.ValueTypeNames.Bool).Set(True)
    asset.GetRootLayer().Save()
    keys = [(f"{c.GetName()} at ", c.GetAttribute("time").Get()) for c in asset.GetPrimAtPath(layer).GetChildren()
            if c.GetTypeName() == "PainterlyTimeKey"]
    assert len(keys) == 4 + extra
    stage = Usd.Stage.CreateNew(str(tmp_path / "shot.usda"))
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(48)
    stage.DefinePrim("/Hero", "Xform").GetReferences().AddReference(
        Sdf.Reference("./blowfish.usda", "/Blowfish", Sdf.LayerOffset(3, 1)))
    stage.GetRootLayer().Save()
    rig = report(painterly, tmp_path / "shot.usda")["rigs"][0]
    assert [n for n in rig["notes"] if "layer offset" in n] == [
        f"/Hero/Paint/Spikes: {len(keys)} time keys' `double time` come from {src_path} through a layer offset "
        "(offset 3, scale 1); USD retimes that layer's time samples but never a double, so the stage reads "
        f"the times written: {listed(keys[:5], 3, 1)}{more}"]
