"""Extents as usd-core computes them (issue 9 section 5).

Renderers cull by `extent`, so every extent sample `painterly bake` writes
must be what usd-core computes for the composed result at that time:
`UsdGeom.Boundable.ComputeExtentFromPlugins`, which for BasisCurves is
`UsdGeom.Curves.ComputeExtent` (the points' box padded by half the largest
`widths` value, whatever its interpolation, read at that time) and for
meshes `UsdGeom.PointBased.ComputeExtent` (min/max of the points). Compared
bit for bit: both sides are float32 arithmetic on the same float32 points.
"""

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, Vt

import authoring as Au


def usd_core_extents(input_path, bake_path, prim_paths):
    """{prim: {t: (ours, usd-core's)}} over every extent sample of the bake."""
    stage = Au.compose(input_path, bake_path)
    layer = Sdf.Layer.FindOrOpen(str(bake_path))
    out = {}
    for p in prim_paths:
        ep = Sdf.Path(p).AppendProperty("extent")
        times = list(layer.ListTimeSamplesForPath(ep))
        assert times, f"{p}: no extent samples"
        b = UsdGeom.Boundable(stage.GetPrimAtPath(p))
        out[p] = {}
        for t in times:
            ours = np.array(layer.QueryTimeSample(ep, t), dtype=np.float32)
            want = np.array(UsdGeom.Boundable.ComputeExtentFromPlugins(b, Usd.TimeCode(t)), dtype=np.float32)
            out[p][t] = (ours, want)
    return out


def assert_usd_core_extents(input_path, bake_path, prim_paths):
    checks = usd_core_extents(input_path, bake_path, prim_paths)
    bad = [(p, t, o.tolist(), w.tolist()) for p, ts in checks.items() for t, (o, w) in ts.items()
           if not np.array_equal(o, w)]
    n = sum(len(ts) for ts in checks.values())
    assert not bad, f"{len(bad)} of {n} extents differ from usd-core's, e.g. {bad[:3]}"
    return n


def prims_with(stage, type_name, api=None):
    return [str(p.GetPath()) for p in stage.Traverse()
            if p.GetTypeName() == type_name and (api is None or api in p.GetAppliedSchemas())]


def test_blowfish_extents_match_usd_core(painterly, tmp_path, repo_root):
    """Every stroke layer of the blowfish at every frame, and its proxy
    (--bake-proxy), as issue 9 found them (84 of 90 sampled checks left
    the widths out)."""
    src = repo_root / "fixtures" / "blowfish.usda"
    out = tmp_path / "blowfish_bake.usdc"
    painterly("bake", src, "-o", out, "--bake-proxy", "--quiet")
    stage = Usd.Stage.Open(str(src))
    layers = prims_with(stage, "BasisCurves", "PainterlyStrokeLayerAPI")
    assert len(layers) >= 5
    widths = [UsdGeom.BasisCurves(stage.GetPrimAtPath(p)).GetWidthsAttr().Get() for p in layers]
    assert all(w is not None and max(w) > 0 for w in widths), "the test needs stroke widths"
    proxy = str(stage.GetPrimAtPath("/Blowfish/Paint").GetRelationship("painterly:proxy").GetTargets()[0])
    n = assert_usd_core_extents(src, out, layers + [proxy])
    assert n >= 48 * (len(layers) + 1)


def test_view_mesh_extents_match_usd_core(painterly, tmp_path, repo_root):
    src = repo_root / "fixtures" / "head.usda"
    out = tmp_path / "head_bake.usda"
    painterly("bake", src, "-o", out, "--quiet")
    meshes = prims_with(Usd.Stage.Open(str(src)), "Mesh", "PainterlyViewDependentAPI")
    assert meshes
    assert_usd_core_extents(src, out, meshes)


def set_widths(prim, values, interpolation, time=None):
    curves = UsdGeom.BasisCurves(prim)
    a = curves.GetWidthsAttr() or curves.CreateWidthsAttr()
    if time is None:
        a.Set(Vt.FloatArray([float(v) for v in values]))
    else:
        a.Set(Vt.FloatArray([float(v) for v in values]), float(time))
    curves.SetWidthsInterpolation(interpolation)


def test_widths_of_every_interpolation_and_time_samples(painterly, tmp_path):
    """A usd-core-written rig whose layers author widths constant, uniform,
    vertex (with a negative value), time-sampled (interpolated between
    samples, held outside and before a value block, nothing after it), only
    as primvars:widths (which usd-core's extent ignores), none, and all
    negative (usd-core pads by the largest value, shrinking the box)."""
    rig = Au.build_skel_rig(tmp_path / "rig.usda", frames=(1, 12), extra_layers=6)
    stage = Usd.Stage.Open(str(rig.path))
    prims = [stage.GetPrimAtPath(p) for p in rig.layers]
    counts = [list(UsdGeom.BasisCurves(p).GetCurveVertexCountsAttr().Get()) for p in prims]
    npts = [sum(c) for c in counts]
    set_widths(prims[0], [0.25], UsdGeom.Tokens.constant)
    set_widths(prims[1], np.linspace(0.05, 0.4, len(counts[1])), UsdGeom.Tokens.uniform)
    set_widths(prims[2], np.r_[[-1.0], np.linspace(0.01, 0.3, npts[2] - 1)], UsdGeom.Tokens.vertex)
    UsdGeom.BasisCurves(prims[3]).GetWidthsAttr().Clear()
    set_widths(prims[3], np.full(npts[3], 0.1), UsdGeom.Tokens.vertex, time=3)
    set_widths(prims[3], np.linspace(0.1, 0.9, npts[3]), UsdGeom.Tokens.vertex, time=9)
    UsdGeom.BasisCurves(prims[3]).GetWidthsAttr().Set(Sdf.ValueBlock(), 11.0)
    UsdGeom.BasisCurves(prims[4]).GetWidthsAttr().Clear()
    pv = UsdGeom.PrimvarsAPI(prims[4]).CreatePrimvar("widths", Sdf.ValueTypeNames.FloatArray,
                                                     UsdGeom.Tokens.vertex)
    pv.Set(Vt.FloatArray([2.0] * npts[4]))
    UsdGeom.BasisCurves(prims[5]).GetWidthsAttr().Clear()
    set_widths(prims[6], [-0.2], UsdGeom.Tokens.constant)
    stage.GetRootLayer().Save()

    out = tmp_path / "bake.usda"
    painterly("bake", rig.path, "-o", out, "--quiet")
    checks = usd_core_extents(rig.path, out, rig.layers)
    for p in rig.layers:
        for t, (ours, want) in checks[p].items():
            assert np.array_equal(ours, want), f"{p} t={t}: {ours.tolist()} vs usd-core {want.tolist()}"
    # the padding really differs between layers and over time
    comp = Au.compose(rig.path, out)

    def pad(p, t):
        pts = np.array(UsdGeom.BasisCurves(comp.GetPrimAtPath(p)).GetPointsAttr().Get(t), dtype=np.float32)
        return float(pts.min(0)[0] - checks[p][t][0][0][0])

    L = rig.layers
    assert pad(L[0], 6.0) == pytest.approx(0.125)
    assert pad(L[1], 6.0) == pytest.approx(0.2)
    assert pad(L[2], 6.0) == pytest.approx(0.15)
    assert pad(L[3], 6.0) == pytest.approx(0.5 * (0.1 + (0.9 - 0.1) * 0.5))  # max width at t=6
    assert pad(L[3], 1.0) == pytest.approx(0.05)  # held before the first sample
    assert pad(L[3], 10.0) == pytest.approx(0.45)  # held before the block
    assert pad(L[3], 12.0) == 0.0  # blocked
    assert pad(L[4], 6.0) == 0.0 and pad(L[5], 6.0) == 0.0
    assert pad(L[6], 6.0) == pytest.approx(-0.1)


def test_non_finite_width_is_an_error(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", frames=(1, 4))
    stage = Usd.Stage.Open(str(rig.path))
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath(rig.layers[0]))
    w = list(curves.GetWidthsAttr().Get())
    w[3] = float("nan")
    curves.GetWidthsAttr().Set(Vt.FloatArray(w))
    stage.GetRootLayer().Save()
    out = tmp_path / "bake.usda"
    proc = painterly("bake", rig.path, "-o", out, check=False)
    assert proc.returncode == 1, proc.stderr
    assert f"{rig.layers[0]}.widths" in proc.stderr and "width 3 is not finite" in proc.stderr, proc.stderr
    assert not out.exists()


@pytest.mark.parametrize("name", ["tube", "walk", "wave", "apple", "building", "static", "fig4"])
def test_fixture_extents_match_usd_core(painterly, tmp_path, repo_root, name):
    """Every extent sample of a --bake-proxy bake of each committed fixture
    (stroke layers, proxies, view-dependent meshes, whatever it holds)."""
    src = repo_root / "fixtures" / f"{name}.usda"
    out = tmp_path / f"{name}_bake.usdc"
    painterly("bake", src, "-o", out, "--bake-proxy", "--quiet")
    layer = Sdf.Layer.FindOrOpen(str(out))
    prims = []
    layer.Traverse(Sdf.Path.absoluteRootPath,
                   lambda p: prims.append(str(p.GetPrimPath())) if p.IsPropertyPath() and p.name == "extent" else None)
    assert prims, f"{name}: the bake wrote no extent"
    assert_usd_core_extents(src, out, sorted(set(prims)))  # every sample of every prim


def test_point_cache_view_mesh_extents_match_usd_core(painterly, tmp_path):
    """A usd-core view-dependent mesh whose base is a point cache (only time
    samples): its baked extent follows the blended points at every frame."""
    import reference_view as RV
    from test_view_dependent import OCTAHEDRON, point_cache, sampled_base

    rest = RV.f32(RV.ball_mesh()[0])
    frames = list(range(1, 13))
    cache = point_cache(rest, frames)
    rng = np.random.default_rng(3)
    keys = [(d, sampled_base(cache, t) + RV.smooth_offsets(rest, rng, 0.3), t, None)
            for d in OCTAHEDRON for t in (3.0, 9.0)]
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=keys, eyes=RV.orbit_eyes(12, wobble=0.5),
                             sampled=cache, default_points=False)
    out = tmp_path / "bake.usdc"
    painterly("bake", vs.path, "-o", out, "--quiet")
    assert assert_usd_core_extents(vs.path, out, [vs.mesh]) == len(frames)
