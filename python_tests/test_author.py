"""Authoring commands (Bassett et al. 2013 sections 3.1-3.3): `painterly bind`
(strokes painted in any pose), `key` (pose keys, time keys, sentinels),
`smudge` and `expand`, and the edit layers they write.

Expected values come from reference_author.py (independent numpy, on top of
reference_skinning.py) fed with usd-core's own evaluation of the posed
proxy (UsdSkel.BakeSkinning or the points attribute). Positions must agree
within 1e-5 x the proxy's bbox diagonal.
"""

from __future__ import annotations

import json
import math
import os
import pathlib
import shutil
import subprocess
import sys

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

import authoring as Au
import reference_author as RA
import reference_skinning as RS

TOL = 1e-5
T = Sdf.ValueTypeNames


# ---------------------------------------------------------------------------
# helpers


def fresh(path):
    """Forget any cached copy of the file's layers (the CLI rewrites them)."""
    for lyr in Sdf.Layer.GetLoadedLayers():
        if lyr.realPath and not lyr.anonymous:
            lyr.Reload()


def open_stage(path):
    fresh(path)
    return Usd.Stage.Open(str(path))


def edit(painterly, cmd, inp, *args, layer=None, check=True):
    """Run an authoring command into the edit layer `layer` (or --in-place)."""
    target = ["--in-place"] if layer is None else ["--edit-layer", layer]
    p = painterly(cmd, inp, *args, *target, "--quiet", check=check)
    fresh(layer)
    return p


def posed_local(input_path, mesh, t):
    """usd-core's posed proxy at t, in the proxy's local space, and the world one."""
    pw = Au.usdcore_world_points(input_path, [mesh], [t])
    st = Usd.Stage.Open(str(input_path))
    m = RA.l2w(st, mesh, t)
    return RA.transform_points(np.linalg.inv(m), pw[mesh][t]), pw


def repaint(stage, layer_path, counts, pts):
    """Replace a stroke layer's strokes by `pts` (its `points`, stroke-local)
    and drop its rest points and binding: what a painting UI writes."""
    prim = stage.GetPrimAtPath(layer_path)
    c = UsdGeom.BasisCurves(prim)
    c.GetCurveVertexCountsAttr().Set(Vt.IntArray([int(x) for x in counts]))
    c.GetPointsAttr().Set(Au.v3f(pts))
    c.GetWidthsAttr().Set(Vt.FloatArray([0.01] * len(pts)))
    c.GetExtentAttr().Set(UsdGeom.PointBased.ComputeExtent(Au.v3f(pts)))
    for name in ("painterly:restPoints", "painterly:bindVertices", "painterly:bindWeights"):
        if prim.HasAttribute(name):
            prim.RemoveProperty(name)


def paint_in_pose(input_path, rig, layer_path, t, seed, n_strokes=8, offsets=(0.0, 0.01, 0.03)):
    """Paint strokes near the POSED proxy at t (in proxy space), store them as
    the layer's stroke-local `points`. Returns (painted stroke-local, posed_world)."""
    local, pw = posed_local(input_path, rig.mesh, t)
    st = Usd.Stage.Open(str(input_path))
    mesh = UsdGeom.Mesh(st.GetPrimAtPath(rig.mesh))
    counts = list(mesh.GetFaceVertexCountsAttr().Get())
    idx = list(mesh.GetFaceVertexIndicesAttr().Get())
    rng = np.random.default_rng(seed)
    sc, sp = Au.make_strokes(local, counts, idx, rng, n_strokes, offsets=offsets)
    to_stroke = np.linalg.inv(RA.l2w(st, layer_path, t)) @ RA.l2w(st, rig.mesh, t)
    stroke_pts = RA.transform_points(to_stroke, sp)
    repaint(st, layer_path, sc, stroke_pts)
    st.GetRootLayer().Save()
    return np.array(Au.v3f(stroke_pts), dtype=np.float64), pw


def attr_np(stage, prim_path, name, dtype=np.float64):
    a = stage.GetPrimAtPath(prim_path).GetAttribute(name)
    assert a and a.HasAuthoredValue(), f"{prim_path}.{name} is not authored"
    return np.array(a.Get(), dtype=dtype)


def binding_dicts(verts, weights):
    out = []
    for v, w in zip(np.asarray(verts), np.asarray(weights, dtype=np.float64)):
        d = {}
        for k in range(3):
            d[int(v[k])] = d.get(int(v[k]), 0.0) + float(w[k])
        out.append(d)
    return out


def assert_binding(verts, weights, exp_verts, exp_weights, what, tol=1e-4):
    assert len(verts) == len(exp_verts), f"{what}: {len(verts)} bound points, expected {len(exp_verts)}"
    ours, exp = binding_dicts(verts, weights), binding_dicts(exp_verts, exp_weights)
    for i, (a, b) in enumerate(zip(ours, exp)):
        keys = set(a) | set(b)
        err = sum(abs(a.get(k, 0.0) - b.get(k, 0.0)) for k in keys)
        assert err <= tol, f"{what}: point {i} bound to {a}, expected {b}"


def assert_close(ours, exp, scale, what, tol=TOL, mask=None):
    ours = np.asarray(ours, dtype=np.float64)
    exp = np.asarray(exp, dtype=np.float64)
    assert ours.shape == exp.shape, f"{what}: shape {ours.shape}, expected {exp.shape}"
    err = np.linalg.norm(ours - exp, axis=1) / scale
    if mask is not None:
        err = np.where(mask, err, 0.0)
    i = int(err.argmax())
    assert err[i] <= tol, (f"{what}: point {i} off by {err[i]:.3g} x bbox diagonal "
                           f"(ours {ours[i]}, expected {exp[i]})")


def rig_of(path, layer_path):
    stage, rigs = RS.describe(path)
    rig, layer = RA.find_rig(rigs, layer_path)
    return stage, rig, layer


def bake_at(painterly, path, t, tmp_path, name):
    out = tmp_path / name
    painterly("bake", path, "-o", out, "--frames", f"{t:g}:{t:g}", "--quiet")
    return Au.compose(path, out)


def brush_expected(path, layer_path, which, path_pts, radius, strength, kind="cubic", t=None,
                   posed_world=None, strokes=None, key=None):
    """Reference result for a brush applied to `path` (tie-safe at joints)."""
    stage, rig, layer = rig_of(path, layer_path)
    target = layer["rest"] if key is None else attr_np(stage, key, "points")
    res = []
    for tie in ("first", "last"):
        res.append(RA.brush(stage, rig, layer, which, target, path_pts, radius, strength, kind=kind, t=t,
                            posed_world=posed_world, strokes=strokes, tie=tie))
    scale = Au.bbox_diag(rig["topo"].rest)
    return res, scale, target


def check_brush(ours, res, scale, what):
    a, b = res[0][0], res[1][0]
    ea = np.linalg.norm(ours - a, axis=1)
    eb = np.linalg.norm(ours - b, axis=1)
    best = np.where(ea <= eb, a.T, b.T).T
    assert_close(ours, best, scale, what)


def safe_radius(d, radius, kind):
    """With falloff none the result jumps at d = R: keep points off it."""
    if kind != "none":
        return radius
    r = radius
    for _ in range(50):
        if np.all(np.abs(d - r) > 1e-4 * r):
            return r
        r *= 1.013
    raise AssertionError("no radius clear of the points")


# ---------------------------------------------------------------------------
# rigs


def skel_rig(tmp_path, name="tube.usda", **kw):
    kw.setdefault("world_xform", Au.xf_static(translate=(0.5, -1, 2), rotate=(0, 30, 0), scale=(1.5, 1.5, 1.5)))
    kw.setdefault("rig_xform", Au.xf_static(translate=(1, 0, 0), rotate=(10, 0, 0)))
    kw.setdefault("layer_xform", Au.xf_static(translate=(0, 0.3, -0.2), rotate=(0, 0, 25), scale=(1, 2, 1)))
    return Au.build_skel_rig(tmp_path / name, **kw)


def points_rig(tmp_path, name="pts.usda", **kw):
    kw.setdefault("proxy_xform", Au.xf_animated({
        1.0: ((0, 0, 0), (0, 0, 0), (1, 1, 1)),
        10.0: ((1, 0.5, -1), (20, 40, 0), (1.5, 0.8, 1.2)),
    }))
    kw.setdefault("layer_xform", Au.xf_animated({
        1.0: ((0.2, 0, 0), (0, 10, 0), (1, 1, 1)),
        10.0: ((0, 1, 0), (0, -20, 15), (1, 1.3, 1)),
    }))
    return Au.build_points_rig(tmp_path / name, **kw)


# ---------------------------------------------------------------------------
# (a) bind: strokes painted in any pose


def check_bind(painterly, rig, tmp_path, t, seed, extra_args=(), layer_path=None):
    layer_path = layer_path or rig.layers[0]
    painted, pw = paint_in_pose(rig.path, rig, layer_path, t, seed)
    before = Au.file_hash(rig.path)
    e = tmp_path / "edits.usda"
    edit(painterly, "bind", rig.path, "--time", t, *extra_args, layer=e)
    assert Au.file_hash(rig.path) == before, "bind modified its input"

    st = Usd.Stage.Open(str(e))
    _, rigs = RS.describe(e)
    rrig, _ = RA.find_rig(rigs, layer_path)
    exp_rest, exp_v, exp_w, _ = RA.bind_layer(st, rrig, layer_path, t, pw)
    scale = Au.bbox_diag(rrig["topo"].rest)
    rest = attr_np(st, layer_path, "painterly:restPoints")
    verts = attr_np(st, layer_path, "painterly:bindVertices", np.int64)
    weights = attr_np(st, layer_path, "painterly:bindWeights")
    assert_binding(verts, weights, exp_v, exp_w, f"{layer_path} binding (posed proxy at t={t})")
    assert np.all(weights >= 0) and np.allclose(weights.sum(axis=1), 1, atol=1e-5), "weights not clamped barycentrics"
    assert_close(rest, exp_rest, scale, f"{layer_path} restPoints after bind --time {t}")
    for name in ("painterly:restPoints", "painterly:bindVertices", "painterly:bindWeights"):
        a = st.GetPrimAtPath(layer_path).GetAttribute(name)
        assert a.GetVariability() == Sdf.VariabilityUniform, f"{name} is not uniform"

    # Baking the edited character at t gives back the painted strokes.
    comp = bake_at(painterly, e, t, tmp_path, "bake_t.usda")
    baked = Au.local_points(comp, layer_path, t)
    m = np.linalg.inv(RA.l2w(st, layer_path, t))
    sscale = Au.bbox_diag(RA.transform_points(m, pw[rig.mesh][t]))
    assert_close(baked, painted, sscale, f"{layer_path}: baked at t={t} vs as painted")
    return e, st


def test_bind_skel_tube_in_pose(painterly, tmp_path):
    rig = skel_rig(tmp_path, extra_layers=1)
    e, st = check_bind(painterly, rig, tmp_path, 8.0, seed=21, extra_args=("--layer", rig.layers[0]))
    # --layer: the other layer is untouched
    layer = Sdf.Layer.FindOrOpen(str(e))
    other = layer.GetPrimAtPath(rig.layers[1])
    assert other is None or not other.properties, f"bind --layer {rig.layers[0]} also wrote {rig.layers[1]}"


def test_bind_points_rig_animated_transforms(painterly, tmp_path):
    # time-sampled proxy points between samples; animated proxy and layer transforms
    rig = points_rig(tmp_path)
    check_bind(painterly, rig, tmp_path, 7.0, seed=5)


def test_bind_real_asset(painterly, tmp_path, real_assets):
    rig = Au.wrap_real_asset(real_assets, "RiggedFigure", tmp_path,
                             rig_xform=Au.xf_static(translate=(0.2, 0, 0), rotate=(0, 15, 0)),
                             layer_xform=Au.xf_static(translate=(0, 0.1, 0), scale=(1.2, 1.2, 1.2)))
    check_bind(painterly, rig, tmp_path, 15.0, seed=9)


def test_bind_rest_pose(painterly, tmp_path):
    """No --time: the rest positions as the bake reads them are bound where
    they are. A layer without painterly:restPoints has its default `points`
    read as proxy-local rest positions (SPEC 3): bind used to read them as
    stroke-local and take them through the transforms at startTimeCode, which
    moved the strokes (static.usda: 1.81) wherever the proxy's and the layer's
    spaces differ (here both are animated between 1 and 10, start 3).
    Expected: restPoints = points, the numpy closest point on the rest proxy,
    and reference_skinning's bake of the input (bound on the fly)."""
    rig = points_rig(tmp_path, rest_time=None, frames=(3, 10))
    lp = rig.layers[0]
    st = Usd.Stage.Open(str(rig.path))
    t0 = st.GetStartTimeCode()
    _, rigs = RS.describe(rig.path)
    rest, tris = rigs[0]["topo"].rest, rigs[0]["topo"].tris
    rng = np.random.default_rng(4)
    mesh = UsdGeom.Mesh(st.GetPrimAtPath(rig.mesh))
    sc, sp = Au.make_strokes(rest, mesh.GetFaceVertexCountsAttr().Get(), mesh.GetFaceVertexIndicesAttr().Get(),
                             rng, 6, offsets=(0.0, 0.05))
    repaint(st, lp, sc, sp)  # proxy-local, no restPoints
    st.GetRootLayer().Save()
    to_stroke = np.linalg.inv(RA.l2w(st, lp, t0)) @ RA.l2w(st, rig.mesh, t0)
    assert np.abs(RA.transform_points(to_stroke, sp) - sp).max() > 0.1, "test setup: the spaces coincide"
    del st, mesh
    painted = np.array(Au.v3f(sp), dtype=np.float64)
    frames = [3.0, 7.0]
    expected = RS.expected_strokes(rig.path, frames)[lp]

    e = tmp_path / "e.usda"
    edit(painterly, "bind", rig.path, layer=e)
    out = tmp_path / "bake.usda"
    painterly("bake", e, "-o", out, "--frames", "3:7:4", "--quiet")
    comp = Au.compose(e, out)
    for t in frames:
        assert_close(Au.local_points(comp, lp, t), expected[t], Au.bbox_diag(rest), f"baked at {t:g} after bind")
    es = open_stage(e)
    assert np.array_equal(attr_np(es, lp, "painterly:restPoints"), painted), "bind moved the rest positions"
    exp_v, exp_w = RS.bind(rest, tris, painted)
    assert_binding(attr_np(es, lp, "painterly:bindVertices", np.int64), attr_np(es, lp, "painterly:bindWeights"),
                   exp_v, exp_w, "rest binding")


def test_bind_rest_pose_keeps_the_rest_points_a_brush_moved(painterly, tmp_path):
    """A layer with painterly:restPoints keeps them: a rest-pose bind after a
    smudge used to take the layer's `points` (as painted, not smudged) back
    to rest and threw the smudge away."""
    rig = skel_rig(tmp_path, n_strokes=8)
    lp = rig.layers[0]
    e = tmp_path / "e.usda"
    w = world_rest(rig.path, lp)
    run_brush(painterly, rig.path, lp, "smudge", tool_through(w, (1, 0.3, 0.2)), 0.3 * Au.bbox_diag(w), 0.2, e)
    smudged = attr_np(open_stage(e), lp, "painterly:restPoints")
    _, rrig, layer = rig_of(rig.path, lp)
    assert np.linalg.norm(smudged - layer["rest"], axis=1).max() > 1e-2, "test setup: the smudge moved nothing"
    edit(painterly, "bind", rig.path, layer=e)
    es = open_stage(e)
    assert np.array_equal(attr_np(es, lp, "painterly:restPoints"), smudged), "bind undid the smudge"
    exp_v, exp_w = RS.bind(rrig["topo"].rest, rrig["topo"].tris, smudged)
    assert_binding(attr_np(es, lp, "painterly:bindVertices", np.int64), attr_np(es, lp, "painterly:bindWeights"),
                   exp_v, exp_w, "rest binding of the smudged points")


# ---------------------------------------------------------------------------
# (b) key


def _set(prim, name, tname, value):
    a = prim.CreateAttribute(name, tname, False, Sdf.VariabilityUniform)
    a.Set(value)


def add_axis(stage, path, kind, source=None, name=None, element=None, component=None, scale=None):
    prim = stage.DefinePrim(path, "PainterlyAxis")
    _set(prim, "kind", T.Token, kind)
    if source is not None:
        prim.CreateRelationship("source", False).SetTargets([Sdf.Path(source)])
    if name is not None:
        _set(prim, "name", T.Token, name)
    if element is not None:
        _set(prim, "element", T.Int, element)
    if component is not None:
        _set(prim, "component", T.Int, component)
    if scale is not None:
        _set(prim, "scale", T.Float, scale)
    return prim


@pytest.fixture
def keyed_rig(tmp_path):
    rig = skel_rig(tmp_path, blend_shapes={"dense"}, extra_layers=1)
    st = Usd.Stage.Open(str(rig.path))
    ctl = st.DefinePrim("/World/Controls", "Scope")
    knob = ctl.CreateAttribute("knobs", T.Float3Array)
    for t in (1.0, 12.0):
        knob.Set(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0), Gf.Vec3f(1, 2, 0.1 * t * t)]), t)
    loc = UsdGeom.Xform.Define(st, "/World/Loc")
    op = loc.AddTranslateOp()
    op.Set(Gf.Vec3d(0, 0, 0), 1.0)
    op.Set(Gf.Vec3d(2, 3, -1), 12.0)
    cam = UsdGeom.Camera.Define(st, "/World/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(3, 2, 8))
    # namespace order (not alphabetical): zKnob, bulge, loc, bend, view
    add_axis(st, "/World/Paint/zKnob", "attribute", "/World/Controls.knobs", element=1, component=2, scale=2.0)
    add_axis(st, "/World/Paint/bulge", "blendShape", "/World/Character/Anim", name="bulge")
    add_axis(st, "/World/Paint/loc", "position", "/World/Loc", component=1)
    add_axis(st, "/World/Paint/bend", "jointRotation", "/World/Character/Skel", name="root/mid", component=0)
    add_axis(st, "/World/Paint/view", "viewDirection", component=2, scale=0.5)
    st.GetPrimAtPath(rig.layers[1]).CreateRelationship("painterly:axes", False).SetTargets(
        [Sdf.Path("/World/Paint/bulge"), Sdf.Path("/World/Paint/zKnob")])
    st.GetRootLayer().Save()
    return rig


def axis_values(rig, t):
    """Every axis of keyed_rig at t, computed with usd-core."""
    st = Usd.Stage.Open(str(rig.path))
    proxy = RA.l2w(st, rig.mesh, t)
    inv = np.linalg.inv(proxy)
    out = {}
    out["zKnob"] = float(st.GetPrimAtPath("/World/Controls").GetAttribute("knobs").Get(t)[1][2])
    anim = UsdSkel.Animation(st.GetPrimAtPath("/World/Character/Anim"))
    names = list(anim.GetBlendShapesAttr().Get())
    out["bulge"] = float(anim.GetBlendShapeWeightsAttr().Get(t)[names.index("bulge")])
    loc = RA.l2w(st, "/World/Loc", t)[:3, 3]
    out["loc"] = float(RA.transform_points(inv, loc)[0, 1])
    joints = list(anim.GetJointsAttr().Get())
    q = anim.GetRotationsAttr().Get(t)[joints.index("root/mid")]
    w, v = q.GetReal(), np.array(q.GetImaginary(), dtype=np.float64)
    if w < 0:
        w, v = -w, -v
    s = np.linalg.norm(v)
    rotvec = v / s * 2 * math.atan2(s, w) if s > 0 else np.zeros(3)
    out["bend"] = float(rotvec[0])  # the rig's rest rotations are identity
    local, _ = posed_local(rig.path, rig.mesh, t)
    centre = (local.min(axis=0) + local.max(axis=0)) / 2
    cam = RA.transform_points(inv, RA.l2w(st, "/World/Cam", t)[:3, 3])[0]
    d = cam - centre
    out["view"] = float(d[2] / np.linalg.norm(d))
    return out


def key_prim(stage, path):
    p = stage.GetPrimAtPath(path)
    assert p and p.IsValid(), f"no key prim {path}"
    return p


CAM = ("--camera", "/World/Cam")
ORDER0 = ["zKnob", "bulge", "loc", "bend", "view"]


def coords_of(stage, path):
    return np.array(key_prim(stage, path).GetAttribute("coordinates").Get(), dtype=np.float64)


def test_key_pose_keys(painterly, keyed_rig, tmp_path):
    rig = keyed_rig
    L0, L1 = rig.layers
    e = tmp_path / "keys.usda"
    t = 6.0
    vals = axis_values(rig, t)
    assert abs(vals["bend"]) > 1e-3 and abs(vals["bulge"]) > 1e-3 and abs(vals["loc"]) > 1e-3

    # default: a points key at the configuration at t (every axis, namespace order, in axis units: SPEC 1.1 section 4)
    edit(painterly, "key", rig.path, "--layer", L0, "--time", t, *CAM, layer=e)
    st = Usd.Stage.Open(str(e))
    k1 = key_prim(st, f"{L0}/key1")
    assert k1.GetTypeName() == "PainterlyPoseKey"
    coords = coords_of(st, f"{L0}/key1")
    exp = np.array([vals[n] for n in ORDER0])
    assert coords.shape == exp.shape, f"coordinates {coords} for axes {ORDER0}"
    assert np.allclose(coords, exp, rtol=1e-5, atol=1e-5), f"coordinates {coords}, expected {exp} ({ORDER0})"
    rest0 = attr_np(st, L0, "painterly:restPoints")
    assert np.array_equal(attr_np(st, f"{L0}/key1", "points"), rest0), "key points are not the layer's rest points"
    assert not k1.GetAttribute("opacity").HasAuthoredValue(), "a points-only key authored opacity"

    # an opacity key at the same configuration: another channel, no clash
    edit(painterly, "key", rig.path, "--layer", L0, "--time", t, "--opacity", 0.25, *CAM, layer=e)
    st = Usd.Stage.Open(str(e))
    k2 = key_prim(st, f"{L0}/key2")
    assert k2.GetTypeName() == "PainterlyPoseKey"
    assert k2.GetAttribute("opacity").Get() == pytest.approx(0.25)
    assert not k2.GetAttribute("points").HasAuthoredValue(), "--opacity alone keyed points"
    assert np.allclose(coords_of(st, f"{L0}/key2"), exp, rtol=1e-5, atol=1e-5)

    # a named key elsewhere; a layer with its own axes (painterly:axes order)
    edit(painterly, "key", rig.path, "--layer", L0, "--name", "smile", "--time", 12, "--points", *CAM, layer=e)
    edit(painterly, "key", rig.path, "--layer", L1, "--time", t, layer=e)
    st = Usd.Stage.Open(str(e))
    assert key_prim(st, f"{L0}/smile").GetTypeName() == "PainterlyPoseKey"
    v12 = axis_values(rig, 12.0)
    assert np.allclose(coords_of(st, f"{L0}/smile"), [v12[n] for n in ORDER0], rtol=1e-5, atol=1e-5)
    assert np.allclose(coords_of(st, f"{L1}/key1"), [vals["bulge"], vals["zKnob"]], rtol=1e-5, atol=1e-5), \
        "painterly:axes order not followed"
    rest_l1 = RS.describe(e)[1][0]["layers"][1]["rest"]
    assert np.allclose(attr_np(st, f"{L1}/key1", "points"), rest_l1)

    # the keys are valid input: the edited character bakes
    painterly("bake", e, "-o", tmp_path / "bake.usdc", "--frames", "1:12", "--camera", "/World/Cam", "--quiet")


def test_key_same_coordinates_refused_then_replaced(painterly, keyed_rig, tmp_path):
    rig = keyed_rig
    L0 = rig.layers[0]
    e = tmp_path / "keys.usda"
    t = 6.0
    edit(painterly, "key", rig.path, "--layer", L0, "--time", t, *CAM, layer=e)
    before = Au.file_hash(e)
    p = edit(painterly, "key", rig.path, "--layer", L0, "--time", t, "--points", *CAM, layer=e, check=False)
    assert p.returncode == 1, f"a second points key at the same coordinates was accepted (exit {p.returncode})"
    assert f"{L0}/key1" in p.stderr and "panicked" not in p.stderr, p.stderr
    assert Au.file_hash(e) == before

    # smudge the rest points, then --replace re-keys key1 with the new ones
    st = Usd.Stage.Open(str(e))
    rest0 = attr_np(st, L0, "painterly:restPoints")
    w = RA.transform_points(RA.l2w(st, rig.mesh, st.GetStartTimeCode()), rest0)
    c = w.mean(axis=0)
    edit(painterly, "smudge", rig.path, "--layer", L0, "--path", f"{c[0]},{c[1]},{c[2]} {c[0] + 1},{c[1]},{c[2]}",
         "--radius", 2.0, "--strength", 0.3, layer=e)
    edit(painterly, "key", rig.path, "--layer", L0, "--time", t, "--points", "--replace", *CAM, layer=e)
    st = Usd.Stage.Open(str(e))
    rest1 = attr_np(st, L0, "painterly:restPoints")
    assert not np.allclose(rest1, rest0), "smudge did not move anything (test setup)"
    assert np.array_equal(attr_np(st, f"{L0}/key1", "points"), rest1), "--replace did not re-capture the points"
    assert not st.GetPrimAtPath(f"{L0}/key2"), "--replace made a new key instead of rewriting key1"


# Found by `scripts/fuzz --edits` (seed 20261207, case 4419): `key` compared
# coordinates exactly, so a key 1e-33 from an existing one (a camera
# direction with rounding noise) was written, and then the bake refused the
# pair as one point. It now applies the bake's own rule: coordinates times
# the axes' scales, within the interpolation's duplicate tolerance. And
# `scripts/fuzz --keys` (seed 20261212, case 6445): a pose key that
# authors `sentinel = 1` (meaningless there; the bake reads a pose key) was
# left out of `key`'s check, so a key at its configuration was written.
@pytest.mark.parametrize("how", ["tolerance", "scale", "sentinel"])
def test_key_at_the_configuration_the_bake_calls_one_point_is_refused(painterly, repo_root, tmp_path, how):
    inp = tmp_path / "head.usda"
    shutil.copy(repo_root / "fixtures" / "head.usda", inp)
    brows = "/Head/Paint/Brows"
    st = Usd.Stage.Open(str(inp))
    front = st.GetPrimAtPath(f"{brows}/front").GetAttribute("coordinates")
    assert list(front.Get()) == [0.0, 1.0]  # where `key --time 1` puts a key (checked below)
    if how == "tolerance":
        # 1e-30 apart, against a layout 2 across: one point for the bake.
        front.Set(Vt.FloatArray([1e-30, 1.0]))
    elif how == "sentinel":
        # A sentinel is a time key's flag; the bake reads this pose key as one.
        st.GetPrimAtPath(f"{brows}/front").CreateAttribute("sentinel", Sdf.ValueTypeNames.Bool).Set(True)
    else:
        # Apart in axis units, one point once viewX is scaled by 0 (left
        # goes: it would meet right so).
        front.Set(Vt.FloatArray([0.7, 1.0]))
        st.GetPrimAtPath("/Head/Paint/viewX").CreateAttribute("scale", Sdf.ValueTypeNames.Float).Set(0.0)
        st.RemovePrim(f"{brows}/left")
    st.GetRootLayer().Save()
    del st, front  # the layer registry would hand the reopen below this copy
    problems = json.loads(painterly("inspect", inp, "--json", check=False).stdout)["problems"]
    # inspect names the misplaced flag (the bake ignores it); nothing else.
    want = [(f"{brows}/front", "sentinel", "sentinel-misuse")] if how == "sentinel" else []
    assert [(p["prim"], p["attribute"], p["rule"]) for p in problems] == want, "test setup"
    before = Au.file_hash(inp)

    p = painterly("key", inp, "--in-place", "--layer", brows, "--time", 1, "--points", check=False)
    assert p.returncode == 1, f"exit {p.returncode}: {p.stderr}"
    # Exactly front's coordinates (sentinel), or what the bake counts as them.
    place = "coordinates" if how == "sentinel" else "configuration"
    assert f"{brows}/front: already keys this layer at the same {place}" in p.stderr, p.stderr
    assert "pass --replace" in p.stderr and "panicked" not in p.stderr
    assert Au.file_hash(inp) == before, "a refused key changed its input"

    painterly("key", inp, "--in-place", "--layer", brows, "--time", 1, "--points", "--replace", "--quiet")
    st = Usd.Stage.Open(str(inp))
    keys = sorted(c.GetName() for c in st.GetPrimAtPath(brows).GetChildren())
    assert "key1" not in keys, keys
    assert list(st.GetPrimAtPath(f"{brows}/front").GetAttribute("coordinates").Get()) == [0.0, 1.0]
    # --replace rewrites the key: it holds only what the command sets, so a
    # stray flag goes too (blocked) and inspect finds nothing.
    problems = json.loads(painterly("inspect", inp, "--json", check=False).stdout)["problems"]
    assert problems == []
    assert not st.GetPrimAtPath(f"{brows}/front").GetAttribute("sentinel").HasAuthoredValue()
    painterly("bake", inp, "-o", tmp_path / "bake.usdc", "--frames", "1:3", "--quiet")


def test_pose_key_that_would_make_two_keys_meet_is_refused(painterly, repo_root, tmp_path):
    # head.usda's Brows keyed only at (0, 0) and (0, 1e-20): a layout 1e-20
    # across, whose keys are 1e-20 apart, so two points for the bake. A key
    # at time 1 lands at (0, 1) (the test above checks where): the layout
    # then spans about 1, its duplicate tolerance is 1e-12, and the first
    # two keys would count as one point.
    inp = tmp_path / "head.usda"
    shutil.copy(repo_root / "fixtures" / "head.usda", inp)
    brows = "/Head/Paint/Brows"
    st = Usd.Stage.Open(str(inp))
    for c in st.GetPrimAtPath(brows).GetChildren():
        if c.GetName() not in ("front", "left"):
            st.RemovePrim(c.GetPath())
    st.GetPrimAtPath(f"{brows}/front").GetAttribute("coordinates").Set(Vt.FloatArray([0.0, 0.0]))
    st.GetPrimAtPath(f"{brows}/left").GetAttribute("coordinates").Set(Vt.FloatArray([0.0, 1e-20]))
    st.GetRootLayer().Save()
    del st
    # The two keys are two points for the bake, which stops later: smooth
    # Voronoi over keys 1e-20 apart gives no finite blend (noted, not this
    # test's subject).
    first = painterly("inspect", inp, check=False)
    assert "same coordinates" not in first.stdout + first.stderr, first.stdout
    assert f"{brows}: baked point 0 is not finite" in first.stdout, first.stdout
    before = Au.file_hash(inp)
    p = painterly("key", inp, "--in-place", "--layer", brows, "--time", 1, "--points", check=False)
    assert p.returncode == 1, f"exit {p.returncode}: {p.stderr}"
    assert (f"{brows}: the new key {brows}/key1 would widen the layer's position keys so far that "
            f"{brows}/front and {brows}/left count as one") in p.stderr, p.stderr
    assert Au.file_hash(inp) == before, "a refused key changed its input"
    # Replacing front instead leaves left and the new key, 1 apart: written.
    painterly("key", inp, "--in-place", "--layer", brows, "--time", 1, "--points", "--name", "front", "--replace",
              "--quiet")
    st = Usd.Stage.Open(str(inp))
    assert list(st.GetPrimAtPath(f"{brows}/front").GetAttribute("coordinates").Get()) == [0.0, 1.0]
    assert sorted(c.GetName() for c in st.GetPrimAtPath(brows).GetChildren()) == ["front", "left"]
    del st


SPIKES = "/Blowfish/Paint/Spikes"


def spikes_times(path):
    """{key name: time} of blowfish.usda's Spikes layer (read by usd-core)."""
    st = Usd.Stage.Open(str(path))
    out = {c.GetName(): c.GetAttribute("time").Get() for c in st.GetPrimAtPath(SPIKES).GetChildren()
           if c.GetTypeName() == "PainterlyTimeKey"}
    del st
    return out


def test_a_key_past_the_interpolation_limit_is_refused(painterly, repo_root, tmp_path):
    """README, Limits: 300 keys per interpolation. A 301st time key was
    written (exit 0), and every command then refused the character (found
    by a review, 2026-12-07); `key` refuses it as it refuses a key the bake
    would count as another's, and writes nothing."""
    import authoring_keys as AK

    inp = tmp_path / "blowfish.usda"
    shutil.copy(repo_root / "fixtures" / "blowfish.usda", inp)
    hair = "/Blowfish/Paint/Hair"
    st = Usd.Stage.Open(str(inp))
    for i in range(300):
        AK.add_time_key(st, hair, f"t{i}", 1 + 0.15 * i, opacity=0.5)
    st.GetRootLayer().Save()
    del st

    def refused(*args, message):
        before = Au.file_hash(inp)
        p = painterly("key", inp, "--in-place", "--layer", hair, "--time-key", "--opacity", 0.5, *args, check=False)
        assert (p.returncode, p.stderr) == (1, f"error: {inp}: {hair}: {message}\n"), p.stderr
        assert Au.file_hash(inp) == before, "a refused key changed its input"

    refused("--time", 5, message=(
        f"the new key {hair}/time1 would make 301 opacity time keys with no sentinel between them; painterly "
        "interpolates at most 300 at once, and the bake would refuse the layer: split them over layers or sentinels"))
    # A sentinel splits the run instead: written, and a key after it too.
    painterly("key", inp, "--in-place", "--layer", hair, "--time", 20.1, "--sentinel", "--quiet")
    painterly("key", inp, "--in-place", "--layer", hair, "--time", 5, "--time-key", "--opacity", 0.5, "--quiet")
    st = Usd.Stage.Open(str(inp))
    assert len(st.GetPrimAtPath(hair).GetChildren()) == 302
    del st
    # Replacing that sentinel by a time key would join the runs again.
    refused("--time", 20.1, "--name", "sentinel1", "--replace", message=(
        f"replacing the sentinel {hair}/sentinel1 with a time key at time 20.1 would take away the split it makes "
        "and join runs of the layer's opacity keys into 302 keys, more than the 300 painterly interpolates at "
        "once, and the bake would refuse the layer"))


def test_time_key_at_a_time_the_bake_calls_the_same_is_refused(painterly, repo_root, tmp_path):
    # blowfish.usda's Spikes: time keys shock (40) and settle (44) between
    # the sentinels shockStart (36) and shockEnd (47). The bake interpolates
    # that run in time and counts two keys closer than 1e-12 of its span as
    # one time: with a key at 44 + 1e-12 the run spans 4 + 1e-12, so the
    # tolerance is about 4e-12.
    inp = tmp_path / "blowfish.usda"
    shutil.copy(repo_root / "fixtures" / "blowfish.usda", inp)
    assert spikes_times(inp) == {"shockStart": 36, "shock": 40, "settle": 44, "shockEnd": 47}
    before = Au.file_hash(inp)
    p = painterly("key", inp, "--in-place", "--layer", SPIKES, "--time", "44.000000000001", "--time-key",
                  "--points", check=False)
    assert p.returncode == 1, f"exit {p.returncode}: {p.stderr}"
    assert f"{SPIKES}/settle: already keys this layer at the same time (the times meet" in p.stderr, p.stderr
    assert "pass --replace" in p.stderr and "panicked" not in p.stderr
    assert Au.file_hash(inp) == before, "a refused key changed its input"

    # --replace rewrites settle at the new time.
    painterly("key", inp, "--in-place", "--layer", SPIKES, "--time", "44.000000000001", "--time-key", "--points",
              "--replace", "--quiet")
    assert spikes_times(inp) == {"shockStart": 36, "shock": 40, "settle": 44.000000000001, "shockEnd": 47}
    assert painterly("inspect", inp, check=False).returncode == 0


def test_time_key_at_a_pose_keys_coordinate_meets_no_key(painterly, repo_root, tmp_path):
    # Spikes also has pose keys on its one axis at 0, 0.5 and 1. A time key
    # at time 1 sits alone before the sentinel at 36: pose keys are not on
    # the timeline, whatever their coordinate.
    inp = tmp_path / "blowfish.usda"
    shutil.copy(repo_root / "fixtures" / "blowfish.usda", inp)
    st = Usd.Stage.Open(str(inp))
    assert [list(st.GetPrimAtPath(f"{SPIKES}/{k}").GetAttribute("coordinates").Get())
            for k in ("flat", "half", "out")] == [[0.0], [0.5], [1.0]]
    del st
    painterly("key", inp, "--in-place", "--layer", SPIKES, "--time", 1, "--time-key", "--points", "--quiet")
    assert spikes_times(inp) == {"shockStart": 36, "shock": 40, "settle": 44, "shockEnd": 47, "time1": 1}
    assert painterly("inspect", inp, check=False).returncode == 0


def test_time_key_that_would_make_two_keys_meet_is_refused(painterly, repo_root, tmp_path):
    inp = tmp_path / "blowfish.usda"
    shutil.copy(repo_root / "fixtures" / "blowfish.usda", inp)
    # 5e-12 after settle: the run 40 .. 44 + 5e-12 spans 4 + 5e-12, its
    # tolerance about 4e-12, so the three keys stay apart.
    painterly("key", inp, "--in-place", "--layer", SPIKES, "--time", "44.000000000005", "--time-key", "--points",
              "--quiet")
    assert spikes_times(inp)["time1"] == 44.000000000005
    assert painterly("inspect", inp, check=False).returncode == 0
    before = Au.file_hash(inp)
    # A key at 37 stretches the run to 7 + 5e-12 (tolerance about 7e-12):
    # settle and time1, 5e-12 apart, would become one time for the bake.
    # 38.5 (span 5.5, tolerance 5.5e-12) would too.
    for t in ("37", "38.5"):
        p = painterly("key", inp, "--in-place", "--layer", SPIKES, "--time", t, "--time-key", "--points", check=False)
        assert p.returncode == 1, f"--time {t}: exit {p.returncode}: {p.stderr}"
        assert (f"{SPIKES}: the new key {SPIKES}/time2 would widen the layer's position keys so far that "
                f"{SPIKES}/settle and {SPIKES}/time1 count as one") in p.stderr, p.stderr
        assert Au.file_hash(inp) == before, "a refused key changed its input"
    # 41 leaves the span at 4 + 5e-12: written, and the bake reads it.
    painterly("key", inp, "--in-place", "--layer", SPIKES, "--time", "41", "--time-key", "--points", "--quiet")
    assert spikes_times(inp)["time2"] == 41
    assert painterly("inspect", inp, check=False).returncode == 0
    painterly("bake", inp, "-o", tmp_path / "bake.usdc", "--frames", "36:48", "--quiet")


def test_a_time_key_replacing_a_sentinel_that_would_merge_meeting_keys_is_refused(painterly, repo_root, tmp_path):
    # Keys at 30 and 30 + 5e-12 alone before the sentinel shockStart (36): a
    # run 5e-12 across, so two times. A time key replacing shockStart joins
    # them to shock and settle (run 14 across, tolerance 1.4e-11): one time.
    inp = tmp_path / "blowfish.usda"
    shutil.copy(repo_root / "fixtures" / "blowfish.usda", inp)
    for t in ("30", "30.000000000005"):
        painterly("key", inp, "--in-place", "--layer", SPIKES, "--time", t, "--time-key", "--points", "--quiet")
    assert painterly("inspect", inp, check=False).returncode == 0
    before = Au.file_hash(inp)
    p = painterly("key", inp, "--in-place", "--layer", SPIKES, "--name", "shockStart", "--replace", "--time", 36,
                  "--time-key", "--points", check=False)
    assert p.returncode == 1, f"exit {p.returncode}: {p.stderr}"
    assert f"{SPIKES}/time1 and {SPIKES}/time2 count as one" in p.stderr, p.stderr
    assert Au.file_hash(inp) == before, "a refused key changed its input"


@pytest.mark.parametrize("new", ["sentinel", "opacity-time-key"])
def test_replacing_a_sentinel_that_would_merge_meeting_keys_of_either_channel_is_refused(painterly, repo_root,
                                                                                        tmp_path, new):
    """Moving a sentinel takes away the split where it was, for the points
    and the opacity keys alike: with position keys at 30 and 30 + 5e-12 (a
    run of their own before shockStart at 36), shockStart replaced by a
    sentinel at 20, or by a time key at 36 that keys only an opacity, joins
    them to shock and settle (a run 14 across, tolerance 1.4e-11): the bake
    counts them as one time. Both were written (exit 0) and inspect then
    failed; both are refused, the file untouched, and inspect stays clean."""
    inp = tmp_path / "blowfish.usda"
    shutil.copy(repo_root / "fixtures" / "blowfish.usda", inp)
    assert spikes_times(inp)["shockStart"] == 36.0, "test setup"
    for t in ("30", "30.000000000005"):
        painterly("key", inp, "--in-place", "--layer", SPIKES, "--time", t, "--time-key", "--points", "--quiet")
    assert painterly("inspect", inp, check=False).returncode == 0, "test setup"
    before = inp.read_bytes()
    how = ["--time", 20, "--sentinel"] if new == "sentinel" else ["--time", 36, "--time-key", "--opacity", 0.5]
    p = painterly("key", inp, "--in-place", "--layer", SPIKES, "--name", "shockStart", "--replace", *how,
                  check=False)
    assert p.returncode == 1, f"exit {p.returncode}: {p.stderr}"
    assert f"{SPIKES}/time1 and {SPIKES}/time2 count as one" in p.stderr, p.stderr
    assert "position keys" in p.stderr and "panicked" not in p.stderr, p.stderr
    assert inp.read_bytes() == before, "a refused key changed its input"
    p = painterly("inspect", inp, check=False)
    assert (p.returncode, p.stdout.strip().splitlines()[-1]) == (0, "no problems found"), p.stdout + p.stderr


def test_key_same_name_refused_then_replaced(painterly, keyed_rig, tmp_path):
    rig = keyed_rig
    L0 = rig.layers[0]
    e = tmp_path / "keys.usda"
    edit(painterly, "key", rig.path, "--layer", L0, "--name", "fade", "--time", 6, "--opacity", 0.25, *CAM, layer=e)
    before = Au.file_hash(e)
    p = edit(painterly, "key", rig.path, "--layer", L0, "--name", "fade", "--time", 10, "--opacity", 0.5, *CAM,
             layer=e, check=False)
    assert p.returncode == 1 and f"{L0}/fade" in p.stderr, p.stderr
    assert Au.file_hash(e) == before
    edit(painterly, "key", rig.path, "--layer", L0, "--name", "fade", "--time", 10, "--opacity", 0.5, "--replace",
         *CAM, layer=e)
    st = Usd.Stage.Open(str(e))
    v10 = axis_values(rig, 10.0)
    assert np.allclose(coords_of(st, f"{L0}/fade"), [v10[n] for n in ORDER0], rtol=1e-5, atol=1e-5)
    assert key_prim(st, f"{L0}/fade").GetAttribute("opacity").Get() == pytest.approx(0.5)
    assert len([c for c in st.GetPrimAtPath(L0).GetChildren()]) == 1


def key_attrs(path, key):
    """{name: value} of the key attributes with a value (usd-core: a blocked
    attribute has none)."""
    st = Usd.Stage.Open(str(path))
    k = st.GetPrimAtPath(key)
    out = {n: k.GetAttribute(n).Get() for n in ("coordinates", "time", "sentinel", "points", "opacity")
           if k.GetAttribute(n).HasAuthoredValue()}
    del st, k
    return out


@pytest.mark.parametrize("target", ["edit-layer", "in-place"])
def test_a_replaced_key_holds_only_what_the_command_sets(painterly, repo_root, tmp_path, target):
    """`key --name K --replace` kept K's other channel: `--name flat --opacity
    0.5 --time 30` left flat's folded shape keyed at inflate 1, beside `out`
    (inspect and bake refused two position keys there), and `--name shock
    --sentinel` left shock's points on a sentinel (inspect: a sentinel
    carries no points). The replaced key now holds only what the command
    sets; the rest is blocked, whatever layer held it. Expected: usd-core's
    reading of the key and reference_keys' bake of the edited stage."""
    spikes = "/Blowfish/Paint/Spikes"
    fish = fish_with_only(repo_root, tmp_path, spikes)
    e = tmp_path / "e.usda"
    where = ["--in-place"] if target == "in-place" else ["--edit-layer", e]
    out = fish if target == "in-place" else e
    assert set(key_attrs(fish, f"{spikes}/flat")) == {"coordinates", "points"}, "test setup"
    assert set(key_attrs(fish, f"{spikes}/shock")) == {"time", "points"}, "test setup"
    assert key_attrs(fish, f"{spikes}/shockStart")["sentinel"], "test setup"
    st = Usd.Stage.Open(str(fish))
    anim = UsdSkel.Animation(st.GetPrimAtPath("/Blowfish/Rig/Skel/Anim"))
    inflate30 = anim.GetBlendShapeWeightsAttr().Get(30)[list(anim.GetBlendShapesAttr().Get()).index("inflate")]
    rest = np.array(st.GetPrimAtPath(spikes).GetAttribute("painterly:restPoints").Get(), dtype=np.float64)
    del st, anim

    painterly("key", fish, "--layer", spikes, "--name", "flat", "--replace", "--time", 30, "--opacity", 0.5, *where,
              "--quiet")
    got = key_attrs(out, f"{spikes}/flat")
    assert set(got) == {"coordinates", "opacity"}, f"flat after an opacity --replace: {sorted(got)}"
    assert list(got["coordinates"]) == pytest.approx([inflate30]) and got["opacity"] == pytest.approx(0.5)

    painterly("key", fish, "--layer", spikes, "--name", "shock", "--replace", "--time", 40, "--sentinel", *where,
              "--quiet")
    got = key_attrs(out, f"{spikes}/shock")
    assert got == {"time": 40.0, "sentinel": True}, f"shock after a --sentinel --replace: {got}"

    # A sentinel replaced by a time key: sentinel 0 and the layer's rest points.
    painterly("key", fish, "--layer", spikes, "--name", "shockStart", "--replace", "--time", 36, "--time-key",
              "--points", *where, "--quiet")
    got = key_attrs(out, f"{spikes}/shockStart")
    assert set(got) == {"time", "sentinel", "points"} and got["sentinel"] is False, sorted(got)
    assert np.array_equal(np.array(got["points"], dtype=np.float64), rest)

    p = painterly("inspect", out, check=False)
    assert (p.returncode, p.stdout.strip().splitlines()[-1]) == (0, "no problems found"), p.stdout + p.stderr
    import reference_keys as RK
    frames = [16.0, 30.0, 38.0]
    expected, _ = RK.expected_bake(out, frames)
    baked = tmp_path / "bake.usda"
    painterly("bake", out, "-o", baked, "--frames", "16:38:2", "--quiet")
    comp = Au.compose(out, baked)
    scale = Au.bbox_diag(rest)
    for t in frames:
        assert_close(Au.local_points(comp, spikes, t), expected[spikes]["points"][t], scale, f"spikes at {t:g}")


def test_replacing_a_keys_opacity_where_it_is_keeps_its_points(painterly, repo_root, tmp_path):
    """`key --name flat --replace --opacity 0.5` at flat's own coordinates
    (inflate 0, frame 5) blocked flat's points, so a shape sculpted into the
    key (as `smudge --key` does) was lost for an opacity change. A key
    rewritten where it is keeps the channel the command does not set: its
    points read back unchanged (usd-core), its opacity is 0.5, and the bake
    at frame 5 is the sculpted shape. Expected: reference_keys' bake of the
    stage with only flat's opacity set by usd-core."""
    spikes = SPIKES
    fish = fish_with_only(repo_root, tmp_path, spikes)
    st = Usd.Stage.Open(str(fish))
    anim = UsdSkel.Animation(st.GetPrimAtPath("/Blowfish/Rig/Skel/Anim"))
    assert anim.GetBlendShapeWeightsAttr().Get(5) == Vt.FloatArray([0.0]), "test setup"
    flat = st.GetPrimAtPath(f"{spikes}/flat")
    assert list(flat.GetAttribute("coordinates").Get()) == [0.0], "test setup"
    # A sculpted shape: flat's points moved, as a brush on the key would.
    pts = np.array(flat.GetAttribute("points").Get(), dtype=np.float64)
    pts[:, 1] += 0.3 * np.sin(np.arange(len(pts)))
    flat.GetAttribute("points").Set(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
    st.GetRootLayer().Save()
    sculpted = np.array(flat.GetAttribute("points").Get(), dtype=np.float64)
    del st, anim, flat
    want = tmp_path / "want.usda"
    shutil.copy(fish, want)
    st = Usd.Stage.Open(str(want))
    st.GetPrimAtPath(f"{spikes}/flat").CreateAttribute("opacity", Sdf.ValueTypeNames.Float).Set(0.5)
    st.GetRootLayer().Save()
    del st

    painterly("key", fish, "--layer", spikes, "--name", "flat", "--replace", "--time", 5, "--opacity", 0.5,
              "--in-place", "--quiet")
    got = key_attrs(fish, f"{spikes}/flat")
    assert set(got) == {"coordinates", "points", "opacity"}, f"flat after an opacity --replace: {sorted(got)}"
    assert list(got["coordinates"]) == [0.0] and got["opacity"] == pytest.approx(0.5)
    assert np.array_equal(np.array(got["points"], dtype=np.float64), sculpted), "flat's points changed"
    p = painterly("inspect", fish, check=False)
    assert (p.returncode, p.stdout.strip().splitlines()[-1]) == (0, "no problems found"), p.stdout + p.stderr

    import reference_keys as RK
    expected, _ = RK.expected_bake(want, [5.0])
    baked = tmp_path / "bake.usda"
    painterly("bake", fish, "-o", baked, "--frames", "5:5", "--quiet")
    comp = Au.compose(fish, baked)
    assert_close(Au.local_points(comp, spikes, 5.0), expected[spikes]["points"][5.0], Au.bbox_diag(sculpted),
                 "spikes at 5 (flat's sculpted shape)")


def test_key_time_keys_and_sentinels(painterly, keyed_rig, tmp_path):
    rig = keyed_rig
    L0 = rig.layers[0]
    e = tmp_path / "tkeys.usda"
    edit(painterly, "key", rig.path, "--layer", L0, "--time", 4, "--time-key", layer=e)
    edit(painterly, "key", rig.path, "--layer", L0, "--time", 9, "--sentinel", layer=e)
    edit(painterly, "key", rig.path, "--layer", L0, "--time", 4, "--time-key", "--opacity", 0.3, layer=e)
    st = Usd.Stage.Open(str(e))
    k = key_prim(st, f"{L0}/time1")
    assert k.GetTypeName() == "PainterlyTimeKey"
    assert k.GetAttribute("time").Get() == 4.0
    assert not k.GetAttribute("sentinel").Get()
    assert np.array_equal(attr_np(st, f"{L0}/time1", "points"), RS.describe(e)[1][0]["layers"][0]["rest"])
    s = key_prim(st, f"{L0}/sentinel1")
    assert s.GetTypeName() == "PainterlyTimeKey"
    assert s.GetAttribute("time").Get() == 9.0 and s.GetAttribute("sentinel").Get() is True
    assert not s.GetAttribute("points").HasAuthoredValue() and not s.GetAttribute("opacity").HasAuthoredValue()
    o = key_prim(st, f"{L0}/time2")
    assert o.GetAttribute("opacity").Get() == pytest.approx(0.3) and not o.GetAttribute("points").HasAuthoredValue()

    for args, clash in ((("--time", 4, "--time-key"), "time1"), (("--time", 9, "--sentinel"), "sentinel1")):
        before = Au.file_hash(e)
        p = edit(painterly, "key", rig.path, "--layer", L0, *args, layer=e, check=False)
        assert p.returncode == 1 and f"{L0}/{clash}" in p.stderr, p.stderr
        assert Au.file_hash(e) == before
    del st, k, s, o  # a stage still open would hand the reopen below its stale layer
    edit(painterly, "key", rig.path, "--layer", L0, "--time", 4, "--time-key", "--replace", layer=e)
    st = Usd.Stage.Open(str(e))
    assert not st.GetPrimAtPath(f"{L0}/time3"), "--replace added a key"
    painterly("bake", e, "-o", tmp_path / "bake.usdc", "--frames", "1:12", "--camera", "/World/Cam", "--quiet")

    # Keys at other times meet none: a second sentinel, a time key at 6.
    del st
    edit(painterly, "key", rig.path, "--layer", L0, "--time", 11, "--sentinel", layer=e)
    edit(painterly, "key", rig.path, "--layer", L0, "--time", 6, "--time-key", layer=e)
    st = Usd.Stage.Open(str(e))
    assert key_prim(st, f"{L0}/sentinel2").GetAttribute("time").Get() == 11.0
    assert key_prim(st, f"{L0}/time3").GetAttribute("time").Get() == 6.0


# ---------------------------------------------------------------------------
# (c) smudge and expand


def world_rest(path, layer_path, t=None):
    """World positions of a layer's rest points skinned at t (for placing tools)."""
    stage, rig, layer = rig_of(path, layer_path)
    _, w, _ = RA.brush(stage, rig, layer, "smudge", layer["rest"], [[0, 0, 0], [1, 0, 0]], 1.0, 0.0, t=t,
                       posed_world=None if t is None else Au.usdcore_world_points(path, [rig["mesh"]], [t]))
    return w


def tool_through(w, direction, length=None):
    c = w.mean(axis=0)
    d = np.asarray(direction, dtype=np.float64)
    d /= np.linalg.norm(d)
    half = (length or Au.bbox_diag(w)) / 2
    return np.array([c - half * d, c + half * d])


def path_arg(pts):
    return " ".join(",".join(f"{x:.9g}" for x in p) for p in pts)


def run_brush(painterly, rig_path, layer_path, which, tool, radius, strength, e, kind="cubic", t=None,
              strokes=None, key=None, extra=()):
    args = ["--layer", layer_path, "--path", path_arg(tool), f"--radius={radius:.9g}",
            f"--strength={strength:.9g}", "--falloff", kind, *extra]
    if t is not None:
        args += ["--time", t]
    if strokes is not None:
        args += ["--strokes", strokes]
    if key is not None:
        args += ["--key", key]
    edit(painterly, which, rig_path, *args, layer=e)


def brush_case(painterly, rig, tmp_path, which, kind, t, strokes=None, strokes_list=None, name="b.usda",
               direction=(1, 0.3, 0.2), strength=0.15, frac=0.25, multi=False):
    """Apply one brush stroke via the CLI and compare with the reference."""
    src = rig.path
    lp = rig.layers[0]
    pw = None if t is None else Au.usdcore_world_points(src, [rig.mesh], [t])
    stage, rrig, layer = rig_of(src, lp)
    _, w, _ = RA.brush(stage, rrig, layer, "smudge", layer["rest"], [[0, 0, 0], [1, 0, 0]], 1.0, 0.0, t=t,
                       posed_world=pw)
    tool = tool_through(w, direction)
    if multi:
        mid = tool.mean(axis=0) + 0.2 * Au.bbox_diag(w) * np.array([0, 1, 0])
        tool = np.array([tool[0], mid, tool[1]])
    radius = frac * Au.bbox_diag(w)
    d, _ = RA.closest_on_path(tool, w)
    radius = safe_radius(d, radius, kind)
    e = tmp_path / name
    run_brush(painterly, rig.path, lp, which, tool, radius, strength, e, kind=kind, t=t, strokes=strokes)
    res, scale, target = brush_expected(src, lp, which, tool, radius, strength, kind=kind, t=t, posed_world=pw,
                                        strokes=strokes_list)
    st = Usd.Stage.Open(str(e))
    ours = attr_np(st, lp, "painterly:restPoints")
    check_brush(ours, res, scale, f"{which} {kind} t={t} strokes={strokes}")
    moved = np.linalg.norm(res[0][0] - target, axis=1) > 1e-6 * scale
    assert moved.sum() >= 3, f"test setup: only {moved.sum()} points within the tool radius"
    assert (~moved).sum() >= 3, "test setup: every point within the tool radius"
    # untouched points are bit-identical
    assert np.array_equal(ours[~moved].astype(np.float32), target[~moved].astype(np.float32)), \
        "points outside the tool's reach moved"
    return e


def test_smudge_rest_cubic(painterly, tmp_path):
    rig = skel_rig(tmp_path, n_strokes=10)
    brush_case(painterly, rig, tmp_path, "smudge", "cubic", None)


def test_smudge_pose_none_strokes_multisegment(painterly, tmp_path):
    rig = skel_rig(tmp_path, n_strokes=10)
    brush_case(painterly, rig, tmp_path, "smudge", "none", 8.0, strokes="0,2-5,9", strokes_list=[0, 2, 3, 4, 5, 9],
               multi=True, frac=0.3)


def test_expand_rest_and_pose_nonuniform_proxy(painterly, tmp_path):
    rig = points_rig(tmp_path, n_strokes=10)
    brush_case(painterly, rig, tmp_path, "expand", "cubic", None, name="rest.usda", frac=0.3)
    brush_case(painterly, rig, tmp_path, "expand", "none", 7.0, name="pose.usda", frac=0.3, strength=-0.1)


def test_brush_rest_pose_transforms_at_start(painterly, tmp_path):
    """No --time: transforms at startTimeCode (3; the proxy moves between 1 and 10)."""
    rig = points_rig(tmp_path, n_strokes=10, frames=(3, 10))
    brush_case(painterly, rig, tmp_path, "smudge", "cubic", None, frac=0.3)


def test_expand_skel_pose_strokes(painterly, tmp_path):
    rig = skel_rig(tmp_path, n_strokes=10)
    brush_case(painterly, rig, tmp_path, "expand", "cubic", 10.0, strokes="1-6", strokes_list=range(1, 7), frac=0.35)


def test_negative_strength_as_its_own_argument(painterly, tmp_path):
    """`--strength -0.1` (expand inwards) is a value, not an unknown flag."""
    rig = skel_rig(tmp_path, n_strokes=6)
    w = world_rest(rig.path, rig.layers[0])
    p = painterly("expand", rig.path, "--layer", rig.layers[0], "--path", path_arg(tool_through(w, (1, 0, 0))),
                  "--radius", "1", "--strength", "-0.1", "--edit-layer", tmp_path / "e.usda", check=False)
    assert p.returncode == 0, p.stderr


def test_expand_moves_out_of_a_left_handed_proxy(painterly, repo_root, tmp_path):
    """The static proxy written with every face's winding reversed and
    `orientation = "leftHanded"` is the same surface, facing the same way
    (usd-core's normals are the same), so expand moves the same way: it used
    the right-hand winding alone and pushed the dabs inwards. Expected: the
    numpy reference on the leftHanded file (its own binding: the fan order of
    a reversed face differs, and with it the lowest tied triangle) with its
    counter-clockwise normals turned round, which moves the dabs as the
    reference moves them on the rightHanded original."""
    fix = repo_root / "fixtures" / "static.usda"
    lp, proxy = "/Static/Paint/Dabs", "/Static/Rig/Proxy"
    st = Usd.Stage.Open(str(fix))
    mesh = UsdGeom.Mesh(st.GetPrimAtPath(proxy))
    assert mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.rightHanded, "test setup"
    counts, idx = list(mesh.GetFaceVertexCountsAttr().Get()), list(mesh.GetFaceVertexIndicesAttr().Get())
    reversed_idx, o = [], 0
    for n in counts:
        face = idx[o:o + n]
        reversed_idx += [face[0]] + face[1:][::-1]
        o += n
    mesh.GetFaceVertexIndicesAttr().Set(Vt.IntArray(reversed_idx))
    mesh.GetOrientationAttr().Set(UsdGeom.Tokens.leftHanded)
    lh = tmp_path / "left.usda"
    st.GetRootLayer().Export(str(lh))
    del st, mesh
    tool = np.array([[-3.0, 1.0, 0.0], [3.0, 1.0, 0.0]])
    e = tmp_path / "e.usda"
    run_brush(painterly, lh, lp, "expand", tool, 3.0, 0.2, e)
    ccw, scale, before = brush_expected(lh, lp, "expand", tool, 3.0, 0.2)
    # Turning the normals round turns each displacement round (x += A^-1 L^-1 d).
    res = [(2 * before - out, w, d) for out, w, d in ccw]
    right, _, _ = brush_expected(fix, lp, "expand", tool, 3.0, 0.2)
    moved = np.linalg.norm(res[0][0] - before, axis=1) > 1e-3
    assert moved.sum() >= 50, "test setup: the tool reaches too few dabs"
    assert np.abs(res[0][0] - right[0][0]).max() < 1e-3 * scale, "reference: not the rightHanded result"
    check_brush(attr_np(open_stage(e), lp, "painterly:restPoints"), res, scale, "expand on the leftHanded proxy")


def test_brush_key_points(painterly, tmp_path):
    """--key edits that key's points (in the pose at --time); restPoints stay."""
    rig = skel_rig(tmp_path, n_strokes=8)
    lp = rig.layers[0]
    st = Usd.Stage.Open(str(rig.path))
    rest = np.array(st.GetPrimAtPath(lp).GetAttribute("painterly:restPoints").Get(), dtype=np.float64)
    kp = st.DefinePrim(f"{lp}/wide", "PainterlyPoseKey")
    _set(kp, "coordinates", T.FloatArray, Vt.FloatArray([]))
    rng = np.random.default_rng(3)
    keypts = rest + rng.uniform(-0.03, 0.03, rest.shape)
    _set(kp, "points", T.Point3fArray, Au.v3f(keypts))
    st.GetRootLayer().Save()
    keypts = np.array(Au.v3f(keypts), dtype=np.float64)
    t = 9.0
    pw = Au.usdcore_world_points(rig.path, [rig.mesh], [t])
    stage, rrig, layer = rig_of(rig.path, lp)
    _, w, _ = RA.brush(stage, rrig, layer, "smudge", keypts, [[0, 0, 0], [1, 0, 0]], 1.0, 0.0, t=t, posed_world=pw)
    for which in ("smudge", "expand"):
        tool = tool_through(w, (0.2, 1, 0.1))
        radius = 0.3 * Au.bbox_diag(w)
        e = tmp_path / f"{which}_key.usda"
        run_brush(painterly, rig.path, lp, which, tool, radius, 0.2, e, t=t, key="wide")
        res, scale, target = brush_expected(rig.path, lp, which, tool, radius, 0.2, t=t, posed_world=pw,
                                            key=f"{lp}/wide")
        es = Usd.Stage.Open(str(e))
        check_brush(attr_np(es, f"{lp}/wide", "points"), res, scale, f"{which} --key")
        assert np.linalg.norm(res[0][0] - target, axis=1).max() > 1e-3, "test setup: nothing moved"
        assert not Sdf.Layer.FindOrOpen(str(e)).GetPropertyAtPath(f"{lp}.painterly:restPoints"), \
            f"{which} --key also wrote the layer's restPoints"


def test_brush_path_prim_and_cached_binding(painterly, tmp_path):
    """--path-prim (first curve, world space at --time) and a cached binding
    from `bind --time` (not the closest point on the rest proxy)."""
    rig = skel_rig(tmp_path, n_strokes=8)
    lp = rig.layers[0]
    t = 8.0
    painted, pw = paint_in_pose(rig.path, rig, lp, t, seed=33)
    e = tmp_path / "e.usda"
    edit(painterly, "bind", rig.path, "--time", t, layer=e)
    stage, rrig, layer = rig_of(e, lp)
    assert layer["cached"]
    rv, rw = RS.bind(rrig["topo"].rest, rrig["topo"].tris, layer["rest"])
    differs = [a != b for a, b in zip(binding_dicts(layer["verts"], layer["weights"]), binding_dicts(rv, rw))]
    assert sum(differs) >= 3, "test setup: the cached binding equals the rest-pose closest point"
    _, w, _ = RA.brush(stage, rrig, layer, "smudge", layer["rest"], [[0, 0, 0], [1, 0, 0]], 1.0, 0.0, t=t,
                       posed_world=pw)
    tool = tool_through(w, (0.5, 1, 0))
    # the tool path as a BasisCurves under a transformed parent: 2 curves, the first is the path
    st = Usd.Stage.Open(str(rig.path))
    holder = UsdGeom.Xform.Define(st, "/World/Tools")
    holder.AddTranslateOp().Set(Gf.Vec3d(0.3, -0.2, 0.1))
    holder.AddRotateYOp().Set(35.0)
    m = np.linalg.inv(RA.l2w(st, "/World/Tools", t))
    local = RA.transform_points(m, tool)
    mid = (local[0] + local[1]) / 2
    curve_pts = np.array([local[0], mid, local[1], local[1] + 5, local[1] + 6])
    cv = UsdGeom.BasisCurves.Define(st, "/World/Tools/Path")
    cv.CreateTypeAttr(UsdGeom.Tokens.linear)
    cv.CreateCurveVertexCountsAttr(Vt.IntArray([3, 2]))
    cv.CreatePointsAttr(Au.v3f(curve_pts))
    st.GetRootLayer().Save()
    es = Usd.Stage.Open(str(e))
    path_world = RA.path_from_curves(es, "/World/Tools/Path", t)
    radius = 0.3 * Au.bbox_diag(w)
    edit(painterly, "expand", rig.path, "--layer", lp, "--path-prim", "/World/Tools/Path", "--radius", radius,
         "--strength", 0.12, "--time", t, layer=e)
    scale = Au.bbox_diag(rrig["topo"].rest)
    before = layer["rest"]
    st2, rrig2, layer2 = rig_of(e, lp)
    exp = []
    for tie in ("first", "last"):
        exp.append(RA.brush(stage, rrig, layer, "expand", before, path_world, radius, 0.12, t=t, posed_world=pw,
                            tie=tie))
    check_brush(layer2["rest"], exp, scale, "expand --path-prim with a cached binding")
    assert np.linalg.norm(exp[0][0] - before, axis=1).max() > 1e-3, "test setup: nothing moved"
    # binding still cached, unchanged
    assert np.array_equal(layer2["verts"], layer["verts"])


FISH_HAIR = "/Blowfish/Paint/Hair"
# README's brush path on the hair, continued round the head.
HAIR_TOOL = np.array([[3.0, 6.0, -2.0], [6.0, 6.0, -1.5], [7.0, 5.0, 0.0]])


def fish_with_only(repo_root, tmp_path, keep):
    """fixtures/blowfish.usda with every stroke layer but `keep` removed (the
    references bind every layer by brute force: 14 of them take 30 s)."""
    fish = tmp_path / "blowfish.usda"
    st = Usd.Stage.Open(str(repo_root / "fixtures" / "blowfish.usda"))
    for p in list(st.GetPrimAtPath("/Blowfish/Paint").GetChildren()):
        if "PainterlyStrokeLayerAPI" in Au.applied_schemas(p) and str(p.GetPath()) != keep:
            st.RemovePrim(p.GetPath())
    st.GetRootLayer().Export(str(fish))
    return fish


def closest_of_two(ours, a, b):
    """Per point, whichever of two tie-breaking references is nearer `ours`."""
    near_a = np.linalg.norm(ours - a, axis=1) <= np.linalg.norm(ours - b, axis=1)
    return np.where(near_a[:, None], a, b)


def test_brush_in_a_pose_stores_the_binding_it_converted_through(painterly, repo_root, tmp_path):
    """A layer bound on the fly (no painterly:bindVertices) brushed in the pose
    at --time: each world displacement is taken back to rest space through the
    blend of the point's closest-point binding, so the edit stores that binding
    (else the bake binds the moved rest points again, to other triangles, and
    at --time shows another displacement: up to 0.12 off a requested 0.3 on
    the hair). Expected: numpy closest point on the rest proxy, usd-core's
    BakeSkinning pose, the eq. 1 blend, and the brush's world displacement."""
    fish = fish_with_only(repo_root, tmp_path, FISH_HAIR)
    t, radius, strength = 24.0, 1.5, 0.3
    stage, rrig, layer = rig_of(fish, FISH_HAIR)
    assert not layer["cached"], "test setup: the fixture's hair has a stored binding"
    pw = Au.usdcore_world_points(fish, [rrig["mesh"]], [t])
    for which in ("smudge", "expand"):
        e = tmp_path / f"{which}.usda"
        run_brush(painterly, fish, FISH_HAIR, which, HAIR_TOOL, radius, strength, e, t=t)
        res, scale, before = brush_expected(fish, FISH_HAIR, which, HAIR_TOOL, radius, strength, t=t,
                                            posed_world=pw)
        es = open_stage(e)
        rest = attr_np(es, FISH_HAIR, "painterly:restPoints")
        check_brush(rest, res, scale, f"{which} --time {t:g} rest points")
        moved = np.linalg.norm(res[0][0] - before, axis=1) > 1e-6 * scale
        assert moved.sum() >= 50, f"test setup: only {moved.sum()} points within reach"
        # Baked at --time, every point is where it was plus the brush's world displacement.
        comp = bake_at(painterly, e, t, tmp_path, f"{which}_bake.usda")
        baked = RA.transform_points(RA.l2w(comp, FISH_HAIR, t), Au.local_points(comp, FISH_HAIR, t))
        want = []
        for out, world, d in res:
            if which == "smudge":
                _, tangent = RA.closest_on_path(HAIR_TOOL, world)
                disp = tangent * (strength * RA.falloff(d / radius, "cubic") * (d <= radius))[:, None]
                want.append(world + disp)
            else:
                # The moved rest points skinned by the same blends (eq. 1).
                posed = RA.Pose(stage, rrig, t, pw)
                A, b = RA.blend(posed.R, posed.tr, layer["verts"], layer["weights"])
                want.append(RA.transform_points(posed.proxy_l2w, RA.apply_blend(A, b, out)))
        want = closest_of_two(baked, *want)
        assert np.linalg.norm(want - res[0][1], axis=1).max() > 0.2, "test setup: the brush moved too little"
        assert_close(baked, want, scale, f"{which} --time {t:g}: baked at {t:g} vs brushed")
        # The binding stored is the closest point of the rest points before the edit.
        assert_binding(attr_np(es, FISH_HAIR, "painterly:bindVertices", np.int64),
                       attr_np(es, FISH_HAIR, "painterly:bindWeights"), layer["verts"], layer["weights"],
                       f"{which}: the binding stored")


def test_brushing_a_keyed_layers_rest_points_leaves_its_keys_bound_as_they_were(painterly, repo_root, tmp_path):
    """The spikes' position keys are skinned with the layer's binding, which
    a bake computes from the rest points when none is stored: a brush that
    moves those rest points (in the rest pose or in a pose) stores the
    binding it used, so the keyed spikes are baked as before (they moved by
    up to 0.12 when the bake re-bound the moved rest points). Expected:
    reference_keys' bake of the unedited fixture (numpy closest-point binding,
    smooth Voronoi, SPEC 5 time keys, usd-core BakeSkinning)."""
    spikes = "/Blowfish/Paint/Spikes"
    fish = fish_with_only(repo_root, tmp_path, spikes)
    stage, rrig, layer = rig_of(fish, spikes)
    assert not layer["cached"], "test setup: the fixture's spikes have a stored binding"
    frames = [5.0, 40.0]
    import reference_keys as RK
    expected, _ = RK.expected_bake(fish, frames)
    scale = Au.bbox_diag(rrig["topo"].rest)
    for name, extra in (("rest", ()), ("posed", ("--time", 5))):
        e = tmp_path / f"{name}.usda"
        edit(painterly, "smudge", fish, "--layer", spikes, "--path", "0,6,-2 8,6,-1.5", "--radius", 3,
             "--strength", 0.3, *extra, layer=e)
        es = open_stage(e)
        rest = attr_np(es, spikes, "painterly:restPoints")
        assert np.linalg.norm(rest - layer["rest"], axis=1).max() > 0.05, "test setup: nothing moved"
        out = tmp_path / f"{name}_bake.usda"
        painterly("bake", e, "-o", out, "--frames", "5:40:35", "--quiet")
        comp = Au.compose(e, out)
        for t in frames:
            assert_close(Au.local_points(comp, spikes, t), expected[spikes]["points"][t], scale,
                         f"{name} smudge of the rest points: keyed spikes at {t:g}")
        assert_binding(attr_np(es, spikes, "painterly:bindVertices", np.int64),
                       attr_np(es, spikes, "painterly:bindWeights"), layer["verts"], layer["weights"],
                       f"{name} smudge: the binding stored")


# ---------------------------------------------------------------------------
# (d) edit layers


READ_ALL = r"""
import sys
from pxr import Usd
s = Usd.Stage.Open(sys.argv[1])
assert s, "cannot open"
n = 0
for p in s.TraverseAll():
    for a in p.GetAttributes():
        a.Get()
        for t in a.GetTimeSamples()[:3]:
            a.Get(t)
        n += 1
    for r in p.GetRelationships():
        r.GetTargets()
print(n)
"""


def open_quietly(path, plugin=True):
    env = dict(os.environ)
    if not plugin:
        env.pop("PXR_PLUGINPATH_NAME", None)
    p = subprocess.run([sys.executable, "-c", READ_ALL, str(path)], capture_output=True, text=True, env=env,
                       timeout=120)
    assert p.returncode == 0, p.stderr
    assert p.stderr.strip() == "", f"usd-core warnings opening {path} (plugin={plugin}):\n{p.stderr}"
    return int(p.stdout.strip())


def test_edit_layer_composes_and_appends(painterly, tmp_path):
    rig = skel_rig(tmp_path, n_strokes=6, extra_layers=1)
    lp = rig.layers[0]
    before = Au.file_hash(rig.path)
    e = tmp_path / "edits.usda"
    edit(painterly, "bind", rig.path, "--time", 6, "--layer", lp, layer=e)
    first = Sdf.Layer.FindOrOpen(str(e))
    assert list(first.subLayerPaths) == [f"./{rig.path.name}"], f"subLayers {list(first.subLayerPaths)}"
    w = world_rest(e, lp)
    tool = tool_through(w, (1, 0, 0))
    run_brush(painterly, rig.path, lp, "smudge", tool, 0.4 * Au.bbox_diag(w), 0.1, e)
    edit(painterly, "key", rig.path, "--layer", lp, "--time", 6, layer=e)
    assert Au.file_hash(rig.path) == before, "an edit-layer command modified its input"

    layer = Sdf.Layer.FindOrOpen(str(e))
    layer.Reload()
    assert list(layer.subLayerPaths) == [f"./{rig.path.name}"], "the sublayer list changed on append"
    specs = {str(s.path): s for s in Au.layer_prim_specs(layer)}
    # only edits: overs down to the layer, one new key prim
    for path, spec in specs.items():
        if path == f"{lp}/key1":
            assert spec.specifier == Sdf.SpecifierDef and spec.typeName == "PainterlyPoseKey"
        else:
            assert spec.specifier == Sdf.SpecifierOver, f"{path} is not an over in the edit layer"
            assert not spec.typeName, f"{path}: the edit layer re-types an input prim"
    props = {f"{p}.{name}" for p, s in specs.items() for name in s.properties.keys()}
    assert props == {f"{lp}.painterly:restPoints", f"{lp}.painterly:bindVertices", f"{lp}.painterly:bindWeights",
                     f"{lp}/key1.coordinates", f"{lp}/key1.points"}, sorted(props)
    assert open_quietly(e) > 0
    assert open_quietly(e, plugin=False) > 0
    # composed: input content intact, edits on top
    es, src = Usd.Stage.Open(str(e)), Usd.Stage.Open(str(rig.path))
    for path in (rig.mesh, "/World/Character/Anim"):
        for a in src.GetPrimAtPath(path).GetAttributes():
            b = es.GetPrimAtPath(path).GetAttribute(a.GetName())
            assert b.GetTimeSamples() == a.GetTimeSamples(), f"{a.GetPath()} samples differ through the edit layer"
            assert b.Get(Usd.TimeCode.Default()) == a.Get(Usd.TimeCode.Default())


def test_edit_layer_given_as_a_bare_file_name_is_in_the_working_folder(painterly, tmp_path):
    """`--edit-layer e.usda` (no folder) is the working folder, which exists:
    the layer is written there and sublayers the input beside it as ./name."""
    rig = skel_rig(tmp_path, n_strokes=4)
    lp = rig.layers[0]
    before = sorted(os.listdir(tmp_path))
    p = painterly("bind", rig.path.name, "--edit-layer", "e.usda", "--quiet", cwd=tmp_path, check=False)
    assert (p.returncode, p.stderr) == (0, ""), p.stderr
    assert sorted(os.listdir(tmp_path)) == sorted(before + ["e.usda"])
    fresh(tmp_path / "e.usda")
    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "e.usda"))
    assert list(layer.subLayerPaths) == [f"./{rig.path.name}"]
    assert layer.GetPropertyAtPath(f"{lp}.painterly:restPoints"), "the bind is not in the edit layer"


def test_edit_layer_keeps_time_metadata(painterly, tmp_path):
    """Opened on its own, the edit layer shows the input's animation as authored:
    same time range and timeCodesPerSecond (else usd-core retimes the input)."""
    rig = points_rig(tmp_path, tcps=30.0)
    e = tmp_path / "e.usda"
    edit(painterly, "bind", rig.path, layer=e)
    src, es = Usd.Stage.Open(str(rig.path)), Usd.Stage.Open(str(e))
    a, b = src.GetPrimAtPath(rig.mesh).GetAttribute("points"), es.GetPrimAtPath(rig.mesh).GetAttribute("points")
    assert b.GetTimeSamples() == a.GetTimeSamples(), \
        f"input retimed through the edit layer: samples {a.GetTimeSamples()} -> {b.GetTimeSamples()}"
    assert es.GetTimeCodesPerSecond() == src.GetTimeCodesPerSecond()
    assert (es.GetStartTimeCode(), es.GetEndTimeCode()) == (src.GetStartTimeCode(), src.GetEndTimeCode())
    # and the product itself bakes it without being told the frames
    painterly("bake", e, "-o", tmp_path / "bake.usda", "--quiet")


def test_edit_layer_elsewhere_and_usdc(painterly, tmp_path):
    rig = skel_rig(tmp_path, n_strokes=6)
    lp = rig.layers[0]
    sub = tmp_path / "sub"
    sub.mkdir()
    ea = sub / "e.usda"
    ec = tmp_path / "e.usdc"
    for e in (ea, ec):
        edit(painterly, "bind", rig.path, "--time", 5, layer=e)
    la = Sdf.Layer.FindOrOpen(str(ea))
    assert pathlib.Path(la.subLayerPaths[0]).resolve() == rig.path.resolve()
    assert ec.read_bytes()[:8] == b"PXR-USDC", "a .usdc edit layer is not a crate file"
    lc = Sdf.Layer.FindOrOpen(str(ec))
    assert lc and list(lc.subLayerPaths) == [f"./{rig.path.name}"]
    open_quietly(ec)
    sa, sc = Usd.Stage.Open(str(ea)), Usd.Stage.Open(str(ec))
    for name in ("painterly:restPoints", "painterly:bindWeights"):
        assert np.array_equal(attr_np(sa, lp, name), attr_np(sc, lp, name)), f"{name}: usda and usdc differ"
    # appending to a .usdc edit layer
    w = world_rest(ec, lp)
    run_brush(painterly, rig.path, lp, "expand", tool_through(w, (0, 1, 0)), 0.3 * Au.bbox_diag(w), 0.1, ec)
    assert Sdf.Layer.FindOrOpen(str(ec)).GetPropertyAtPath(f"{lp}.painterly:bindWeights"), "append lost edits"


def test_in_place(painterly, tmp_path):
    rig = skel_rig(tmp_path, n_strokes=6)
    lp = rig.layers[0]
    ref = tmp_path / "ref"
    ref.mkdir()
    copy = ref / rig.path.name
    shutil.copy(rig.path, copy)
    # same edit as an edit layer, for comparison
    t = 7.0
    e = ref / "e.usda"
    edit(painterly, "bind", copy, "--time", t, layer=e)
    listing = sorted(os.listdir(tmp_path))
    edit(painterly, "bind", rig.path, "--time", t)
    assert sorted(os.listdir(tmp_path)) == listing, "--in-place left files behind"
    st, se = Usd.Stage.Open(str(rig.path)), Usd.Stage.Open(str(e))
    for name in ("painterly:restPoints", "painterly:bindVertices", "painterly:bindWeights"):
        assert np.array_equal(attr_np(st, lp, name), attr_np(se, lp, name)), f"in place {name} differs"
    _, rigs = RS.describe(rig.path)
    pw = Au.usdcore_world_points(copy, [rig.mesh], [t])
    exp_rest, _, _, _ = RA.bind_layer(st, rigs[0], lp, t, pw)
    assert_close(attr_np(st, lp, "painterly:restPoints"), exp_rest, Au.bbox_diag(rig.rest), "in place bind")
    # everything else is as it was
    orig = Usd.Stage.Open(str(copy))
    for prim in orig.TraverseAll():
        q = st.GetPrimAtPath(prim.GetPath())
        assert q and q.GetTypeName() == prim.GetTypeName(), f"{prim.GetPath()} lost"
        for a in prim.GetAttributes():
            if str(a.GetPath()).startswith(lp + "."):
                continue
            b = q.GetAttribute(a.GetName())
            assert b.GetTimeSamples() == a.GetTimeSamples(), f"{a.GetPath()} samples changed"
            assert b.Get() == a.Get(), f"{a.GetPath()} changed"
    for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "upAxis", "metersPerUnit", "defaultPrim"):
        assert st.GetRootLayer().pseudoRoot.GetInfo(key) == orig.GetRootLayer().pseudoRoot.GetInfo(key), key
    open_quietly(rig.path)


# ---------------------------------------------------------------------------
# (e) in-place edits of usda text keep what usd-core wrote


from test_usdc_fidelity import contents, differences  # noqa: E402

TUBE = pathlib.Path(__file__).parent.parent / "fixtures" / "tube.usda"
RINGS = "/Tube/Paint/Rings"


def tube_copy(make=None):
    """fixtures/tube.usda as usd-core writes it, after `make(layer)`."""
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.TransferContent(Sdf.Layer.OpenAsAnonymous(str(TUBE)))
    if make:
        make(layer)
    return layer


def test_in_place_bind_keeps_a_connection_usd_core_wrote_without_a_declaration(painterly, tmp_path):
    """usd-core writes a connection-only attribute as one `name.connect` statement.
    Adding properties to its prim (bind) splices them after it; openusd 0.8
    lists such a property after all declared ones, which made the check refuse.
    The result is what usd-core makes of the same edit: the original properties
    in their order, then the new ones, nothing else changed."""
    def connect(layer):
        a = Sdf.AttributeSpec(layer.GetPrimAtPath(RINGS), "inputs:c", T.Float)
        a.connectionPathList.explicitItems = ["/Tube.outputs:out"]

    inp = tmp_path / "t.usda"
    tube_copy(connect).Export(str(inp))
    text = inp.read_text()
    assert "float inputs:c.connect = </Tube.outputs:out>" in text and "float inputs:c\n" not in text, "test setup"
    original = Sdf.Layer.OpenAsAnonymous(str(inp))

    p = painterly("bind", inp, "--layer", RINGS, "--in-place", "--quiet", check=False)
    assert (p.returncode, p.stderr) == (0, ""), p.stderr
    edited = Sdf.Layer.OpenAsAnonymous(str(inp))

    # usd-core's own edit: set the bind's values (painterly's numbers, which
    # test_in_place checks) on a copy of the original; new attributes append.
    expected = Sdf.Layer.CreateAnonymous(".usda")
    expected.TransferContent(original)
    prim = expected.GetPrimAtPath(RINGS)
    added = [n for n in edited.GetPrimAtPath(RINGS).properties.keys()
             if n not in original.GetPrimAtPath(RINGS).properties.keys()]
    assert added == ["painterly:bindVertices", "painterly:bindWeights"], added
    for name in ("painterly:restPoints", *added):
        src = edited.GetAttributeAtPath(f"{RINGS}.{name}")
        a = prim.properties.get(name) or Sdf.AttributeSpec(prim, name, src.typeName, Sdf.VariabilityUniform)
        a.default = src.default
    assert differences(contents(expected), contents(edited)) == []
    assert list(edited.GetPrimAtPath(RINGS).properties.keys()) == list(prim.properties.keys())
    assert edited.GetAttributeAtPath(f"{RINGS}.inputs:c").connectionPathList.explicitItems == \
        [Sdf.Path("/Tube.outputs:out")]
    # Everything before the edit is still byte for byte in the text.
    assert text.split("inputs:c.connect")[0] in inp.read_text()
    assert open_quietly(inp) > 0


def test_key_replace_keeps_the_key_prims_metadata_properties_and_children_in_usda(painterly, tmp_path):
    """`key --replace` of a key prim with prim metadata re-types its header and
    sets its attributes; the metadata, other properties and children stay, as
    they do for the same file as .usdc (the .usda edit was refused). The
    key's points, which the replacing opacity key does not set, stay: the
    key is rewritten where it is (the same coordinates)."""
    inp = tmp_path / "t.usda"
    tube_copy().Export(str(inp))
    painterly("key", inp, "--layer", RINGS, "--time", 12, "--name", "k", "--in-place", "--quiet")
    layer = Sdf.Layer.FindOrOpen(str(inp))
    layer.Reload(force=True)
    k = layer.GetPrimAtPath(f"{RINGS}/k")
    k.documentation = "approved by lead"
    k.customData = {"reviewed": True}
    Sdf.AttributeSpec(k, "note", T.String).default = "keep"
    Sdf.CreatePrimInLayer(layer, f"{RINGS}/k/Child").specifier = Sdf.SpecifierDef
    assert layer.Save()
    crate = tmp_path / "t.usdc"
    layer.Export(str(crate))
    for f in (inp, crate):
        # (usd-core writes a usda prim's properties sorted, a crate's in order)
        original = contents(Sdf.Layer.OpenAsAnonymous(str(f)))
        p = painterly("key", f, "--layer", RINGS, "--time", 12, "--name", "k", "--opacity", 0.25, "--replace",
                      "--in-place", "--quiet", check=False)
        assert (p.returncode, p.stderr) == (0, ""), f"{f.suffix}: {p.stderr}"
        edited = contents(Sdf.Layer.OpenAsAnonymous(str(f)))
        # Only the key's new opacity, which usd-core appends to its properties
        # (its points stay: the key does not move).
        assert differences(original, edited) == [(f"{RINGS}/k", "<properties>"), (f"{RINGS}/k.opacity", "<spec>")]
        assert edited[f"{RINGS}/k"][1]["<properties>"] == [*original[f"{RINGS}/k"][1]["<properties>"], "opacity"]
        assert edited[f"{RINGS}/k.opacity"][1]["default"] == 0.25
        spec = edited[f"{RINGS}/k"][1]
        assert spec["documentation"] == "approved by lead" and dict(spec["customData"]) == {"reviewed": True}
        assert spec["<children>"] == ["Child"] and "note" in spec["<properties>"]
