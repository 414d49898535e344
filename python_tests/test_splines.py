"""Attributes animated by a spline (USD 25.05's `.spline`, which usd-core
26.11 evaluates and openusd 0.8 reads past as if nothing were authored).

A bake that read past a spline would take the default, or nothing, where
usd-core's `Get(t)` evaluates the curve: a wrong bake with no word said (it
was: `painterly:opacity` baked as if 1, an axis source read at its default,
`inspect` saying "no problems found"; a camera's zoom rendered at its
default focal length). So wherever a spline gives an
attribute painterly reads its value, bake and inspect refuse it, naming the
prim, the attribute and the layer (rule `unreadable`), and the Python
package raises it. Which opinion gives the value is decided as usd-core
decides it, checked here against usd-core's own `GetResolveInfo`: a
stronger default, or time samples beside the spline, win over it, and then
the bake equals the bake of the same values authored without a spline. A
spline on an attribute painterly does not read changes nothing, and
`bind --in-place` keeps it. Value clips anchored in a stronger layer than
the spline's answer first and bake as usd-core reads them; a spline inside
a clip's own layer is not seen (README, Limits).
"""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from pxr import Sdf, Ts, Usd, UsdGeom

import authoring as Au
from conftest import REPO

FIXTURES = REPO / "fixtures"
HATCHING = "/Blowfish/Paint/BodyHatching"


def spline(type_name, knots):
    s = Ts.Spline(type_name)
    for t, v in knots:
        k = Ts.Knot(type_name)
        k.SetTime(t)
        k.SetValue(v)
        k.SetNextInterpolation(Ts.InterpLinear)
        s.SetKnot(k)
    return s


def fish(tmp_path, ext, edit, name="fish"):
    """The blowfish fixture saved by usd-core as `name.ext`, after `edit(stage)`."""
    path = tmp_path / f"{name}.{ext}"
    # Held in a name: a layer handle expires with the stage it came from.
    source = Sdf.Layer.FindOrOpen(str(FIXTURES / "blowfish.usda"))
    source.Export(str(path))
    stage = Usd.Stage.Open(str(path))
    edit(stage)
    stage.GetRootLayer().Save()
    return path


def on(prim, name, type_name, knots, default=None):
    def edit(stage):
        p = stage.GetPrimAtPath(prim)
        a = p.GetAttribute(name) or p.CreateAttribute(name, getattr(Sdf.ValueTypeNames, type_name.capitalize()))
        a.Clear()
        if default is not None:
            a.Set(default)
        a.SetSpline(spline(type_name, knots))
    return edit


# (prim, attribute, value type, knots): each one painterly reads.
READ = {
    "axis source": ("/Blowfish", "blink", "float", [(1, 0.0), (10, 1.0), (20, 0.0)]),
    "layer opacity": (HATCHING, "painterly:opacity", "float", [(1, 1.0), (12, 0.0)]),
    "rig transform": ("/Blowfish", "xformOp:rotateY", "float", [(1, 0.0), (48, 90.0)]),
}


@pytest.mark.parametrize("ext", ["usda", "usdc"])
@pytest.mark.parametrize("case", sorted(READ))
def test_a_spline_painterly_would_read_is_refused_by_bake_and_inspect(painterly, tmp_path, ext, case):
    prim, name, type_name, knots = READ[case]
    # A default beside the spline does not hide it: at a frame usd-core reads the curve.
    path = fish(tmp_path, ext, on(prim, name, type_name, knots, default=0.25))
    stage = Usd.Stage.Open(str(path))
    assert stage.GetPrimAtPath(prim).GetAttribute(name).GetResolveInfo(5).GetSource() == Usd.ResolveInfoSourceSpline
    before = Au.file_hash(path)
    out = tmp_path / "out" / "bake.usdc"
    out.parent.mkdir()
    proc = painterly("bake", path, "-o", out, "--frames", "1:12", check=False)
    assert proc.returncode == 1, proc.stderr
    line = f"error: {path}: {prim}.{name}: is animated by a spline (`.spline` in {path}), which painterly cannot evaluate"
    assert proc.stderr.startswith(line), proc.stderr
    assert "attr.Get(t) at each frame, attr.Clear(), then attr.Set(value, t)" in proc.stderr
    assert "panicked" not in proc.stderr
    assert list(out.parent.iterdir()) == [] and Au.file_hash(path) == before

    proc = painterly("inspect", path, "--json", check=False)
    assert proc.returncode == 1, proc.stderr
    problems = json.loads(proc.stdout)["problems"]
    mine = [p for p in problems if (p["prim"], p["attribute"]) == (prim, name)]
    assert len(mine) == 1, problems
    assert mine[0]["rule"] == "unreadable"
    assert mine[0]["message"].startswith(f"is animated by a spline (`.spline` in {path})")


def test_a_spline_on_a_view_camera_is_refused(painterly, tmp_path):
    # head.usda's view-dependent mesh follows /Head/Camera; a rotateY op
    # appended to the camera's ops turns it by a curve.
    path = tmp_path / "head.usda"
    shutil.copy(FIXTURES / "head.usda", path)
    stage = Usd.Stage.Open(str(path))
    cam = stage.GetPrimAtPath("/Head/Camera")
    op = UsdGeom.Xformable(cam).AddRotateYOp(opSuffix="turn")
    op.GetAttr().SetSpline(spline("float", [(1, -20.0), (24, 20.0)]))
    stage.GetRootLayer().Save()
    proc = painterly("bake", path, "-o", tmp_path / "bake.usdc", "--frames", "1:4", check=False)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.startswith(f"error: {path}: /Head/Camera.xformOp:rotateY:turn: is animated by a spline"), proc.stderr
    assert not (tmp_path / "bake.usdc").exists()


def test_a_zoom_by_a_spline_is_refused_by_render(painterly, tmp_path):
    path = tmp_path / "head.usda"
    shutil.copy(FIXTURES / "head.usda", path)
    stage = Usd.Stage.Open(str(path))
    stage.GetPrimAtPath("/Head/Camera").GetAttribute("focalLength").SetSpline(spline("float", [(1, 35.0), (24, 80.0)]))
    stage.GetRootLayer().Save()
    out = tmp_path / "frames" / "head.####.exr"
    out.parent.mkdir()
    proc = painterly("render", path, "--camera", "/Head/Camera", "--frames", "1:2", "-o", out, check=False)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.startswith(f"error: {path}: /Head/Camera.focalLength: is animated by a spline"), proc.stderr
    assert list(out.parent.iterdir()) == []


def test_a_constant_primvar_animated_by_a_spline_is_refused_by_render(painterly, tmp_path):
    # A constant primvar may be authored as a scalar, which a spline can
    # animate: render read the widths at their default (found by review).
    path = tmp_path / "head.usda"
    shutil.copy(FIXTURES / "head.usda", path)
    stage = Usd.Stage.Open(str(path))
    curves = UsdGeom.BasisCurves.Define(stage, "/Head/Extra")
    curves.CreateTypeAttr("linear")
    curves.CreatePointsAttr([(-30, 0, 0), (30, 0, 0)])
    curves.CreateCurveVertexCountsAttr([2])
    widths = curves.GetPrim().CreateAttribute("primvars:widths", Sdf.ValueTypeNames.Float)
    widths.SetMetadata("interpolation", "constant")
    widths.Set(0.5)
    widths.SetSpline(spline("float", [(1, 0.5), (24, 8.0)]))
    stage.GetRootLayer().Save()
    assert widths.GetResolveInfo(20).GetSource() == Usd.ResolveInfoSourceSpline
    out = tmp_path / "frames" / "head.####.exr"
    out.parent.mkdir()
    proc = painterly("render", path, "--camera", "/Head/Camera", "--frames", "20:20", "-o", out, check=False)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.startswith(f"error: {path}: /Head/Extra.primvars:widths: is animated by a spline"), proc.stderr


def test_the_python_package_raises_the_same_error(tmp_path):
    painterly_py = pytest.importorskip("painterly")
    prim, name, type_name, knots = READ["layer opacity"]
    path = fish(tmp_path, "usdc", on(prim, name, type_name, knots))
    with pytest.raises(painterly_py.Error) as e:
        painterly_py.bake(str(path), str(tmp_path / "bake.usdc"), frames="1:12")
    assert (e.value.prim, e.value.attribute, e.value.rule) == (prim, name, "unreadable")
    assert "is animated by a spline" in e.value.message


def baked_opacity(painterly, path, out, t):
    painterly("bake", path, "-o", out, "--frames", "1:12")
    stage = Usd.Stage.Open(str(out))
    return np.array(stage.GetPrimAtPath(HATCHING).GetAttribute("primvars:displayOpacity").Get(t))


def two_layers(tmp_path, name, weak_edit, strong_edit):
    """`name`.usda over a weaker sublayer (the fixture, edited by `weak_edit`)."""
    weak = fish(tmp_path, "usda", weak_edit, name=f"{name}_weak")
    strong = Sdf.Layer.CreateNew(str(tmp_path / f"{name}.usda"))
    strong.subLayerPaths.append(weak.name)
    strong.Save()
    stage = Usd.Stage.Open(strong)
    strong_edit(stage)
    stage.GetRootLayer().Save()
    return tmp_path / f"{name}.usda"


def test_an_opinion_that_wins_over_a_spline_is_read_as_usd_core_reads_it(painterly, tmp_path):
    prim, name, _, knots = READ["layer opacity"]

    def opacity(stage):
        return stage.GetPrimAtPath(prim).GetAttribute(name)

    def set_default(v):
        return lambda stage: opacity(stage).Set(v)

    # A stronger layer's default over a weaker spline: usd-core reads the default.
    over = two_layers(tmp_path, "over", on(prim, name, "float", knots), set_default(0.5))
    plain = two_layers(tmp_path, "plain", lambda stage: None, set_default(0.5))
    over_stage = Usd.Stage.Open(str(over))
    assert opacity(over_stage).GetResolveInfo(6).GetSource() == Usd.ResolveInfoSourceDefault
    assert np.array_equal(baked_opacity(painterly, over, tmp_path / "over_bake.usdc", 6),
                          baked_opacity(painterly, plain, tmp_path / "plain_bake.usdc", 6))

    # Time samples beside a spline in one spec: usd-core reads the samples.
    # (Writing samples over a spline drops it, so the spline comes second.)
    def samples(stage):
        stage.GetPrimAtPath(prim).CreateAttribute(name, Sdf.ValueTypeNames.Float)
        layer = stage.GetRootLayer()
        for t, v in ((1, 0.2), (12, 0.8)):
            layer.SetTimeSample(Sdf.Path(f"{prim}.{name}"), t, v)

    def samples_and_spline(stage):
        samples(stage)
        opacity(stage).SetSpline(spline("float", knots))

    both = fish(tmp_path, "usdc", samples_and_spline, name="both")
    only = fish(tmp_path, "usdc", samples, name="only")
    both_stage = Usd.Stage.Open(str(both))
    a = opacity(both_stage)
    spec = both_stage.GetRootLayer().GetAttributeAtPath(a.GetPath())
    assert {"spline", "timeSamples"} <= set(spec.ListInfoKeys())
    assert a.GetResolveInfo(6).GetSource() == Usd.ResolveInfoSourceTimeSamples
    got = baked_opacity(painterly, both, tmp_path / "both_bake.usdc", 6)
    assert np.array_equal(got, baked_opacity(painterly, only, tmp_path / "only_bake.usdc", 6))
    # ... and the samples were read: at frame 6 the opacity is 0.2 + 5/11 * 0.6, not 1.
    authored = np.array(both_stage.GetPrimAtPath(prim).GetAttribute("primvars:displayOpacity").Get(6))
    assert np.allclose(got, authored * (0.2 + 5 / 11 * 0.6), atol=1e-6)


def test_value_clips_over_a_weaker_spline_are_read_as_usd_core_reads_them(painterly, tmp_path):
    # Clips anchored in the stronger layer answer before a weaker layer's
    # spline: usd-core reads the clip's samples, and so does the bake (a
    # first version of the refusal refused this; found by review).
    prim, name, _, knots = READ["layer opacity"]
    clip = Sdf.Layer.CreateNew(str(tmp_path / "clip.usda"))
    clip_stage = Usd.Stage.Open(clip)
    a = clip_stage.OverridePrim(prim).CreateAttribute(name, Sdf.ValueTypeNames.Float)
    a.Set(0.2, 1)
    a.Set(0.8, 12)
    clip.Save()

    def clips(stage):
        api = Usd.ClipsAPI(stage.OverridePrim(prim))
        api.SetClipAssetPaths([Sdf.AssetPath("./clip.usda")])
        api.SetClipPrimPath(prim)
        api.SetClipActive([(1, 0)])
        api.SetClipTimes([(1, 1), (12, 12)])

    over = two_layers(tmp_path, "over", on(prim, name, "float", knots, default=0.9), clips)
    over_stage = Usd.Stage.Open(str(over))
    attr = over_stage.GetPrimAtPath(prim).GetAttribute(name)
    assert attr.GetResolveInfo(6).GetSource() == Usd.ResolveInfoSourceValueClips
    got = baked_opacity(painterly, over, tmp_path / "over_bake.usdc", 6)
    assert attr.Get(6) == pytest.approx(0.2 + 5 / 11 * 0.6)
    authored = np.array(over_stage.GetPrimAtPath(prim).GetAttribute("primvars:displayOpacity").Get(6))
    assert np.allclose(got, authored * attr.Get(6), atol=1e-6)


def test_a_spline_painterly_does_not_read_changes_nothing_and_bind_keeps_it(painterly, tmp_path):
    edit = on("/Blowfish", "unread", "double", [(1, 0.0), (10, 2.0)])
    for ext in ("usda", "usdc"):
        path = fish(tmp_path, ext, edit)
        plain = fish(tmp_path, ext, lambda stage: None, name="plain")
        assert np.array_equal(baked_opacity(painterly, path, tmp_path / f"a_{ext}.usdc", 6),
                              baked_opacity(painterly, plain, tmp_path / f"b_{ext}.usdc", 6))
        painterly("bind", path, "--in-place")
        stage = Usd.Stage.Open(str(path))
        a = stage.GetPrimAtPath("/Blowfish").GetAttribute("unread")
        assert a.HasSpline() and len(a.GetSpline().GetKnots()) == 2
        assert a.Get(5.5) == pytest.approx(1.0)
        assert stage.GetPrimAtPath(HATCHING).GetAttribute("painterly:bindVertices").HasAuthoredValue()
