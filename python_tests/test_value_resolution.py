"""Values resolved as usd-core resolves them (found by a value-resolution
review, 2026-12-06):

- a time sample holds up to a value block after it (usd-core: samples 1 at
  t=1 and a block at t=3 read 1 at t=2; openusd 0.8 read no value there,
  which put joints at rest, blend shapes at 0 and failed a points proxy);
- SPEC §4 axes read the same (blendShape, jointRotation, position);
- a time-sampled `primvars:displayOpacity` (a fade) is baked per frame
  (the bake wrote its default, or 1, at every frame).

Every expected value comes from usd-core: UsdSkel.BakeSkinning for the
proxy, `Get(t)` for the primvar.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

import authoring as Au
import authoring_keys as AK


def blocked_skel_rig(tmp_path):
    """A skinned tube with a blend shape, animated at 1, 4, 8 and 12, whose
    weights are blocked at 6 and joint rotations at 10; returns the rig and
    its opened stage (for more edits; save it)."""
    rig = Au.build_skel_rig(tmp_path / "in.usda", blend_shapes={"dense"}, frames=(1, 12),
                            key_times=[1.0, 4.0, 8.0, 12.0])
    st = Usd.Stage.Open(str(rig.path))
    anim = st.GetPrimAtPath("/World/Character/Anim")
    anim.GetAttribute("blendShapeWeights").Set(Sdf.ValueBlock(), 6.0)
    anim.GetAttribute("rotations").Set(Sdf.ValueBlock(), 10.0)
    return rig, st


def test_a_skel_animation_holds_its_sample_up_to_a_block(painterly, tmp_path):
    rig, st = blocked_skel_rig(tmp_path)
    st.GetRootLayer().Save()
    del st
    times = [4.0, 5.0, 5.5, 8.0, 9.0, 9.5]  # 5, 5.5: before the weights' block; 9, 9.5: before the rotations'
    out = tmp_path / "bake.usda"
    painterly("bake", rig.path, "-o", out, "--frames", "1:12:0.5", "--bake-proxy", "--quiet")
    want = Au.usdcore_world_points(rig.path, [rig.mesh], times)[rig.mesh]
    composed = Au.compose(rig.path, out)
    for t in times:
        got = Au.world_points(composed, rig.mesh, t)
        assert np.abs(got - want[t]).max() < 1e-5, t
    # The blocks bite: the weights at 5 are the held sample at 4, not 0.
    src = Usd.Stage.Open(str(rig.path))
    weights = src.GetPrimAtPath("/World/Character/Anim").GetAttribute("blendShapeWeights")
    assert list(weights.Get(5.0)) == list(weights.Get(4.0)) and max(weights.Get(4.0)) > 0


def test_a_points_proxy_holds_its_sample_up_to_a_block(painterly, tmp_path):
    """A proxy animated by `points` samples at 1, 4 and 10 with a block
    added at 3: at 1.5 and 2 the proxy is the sample at 1 (usd-core), so
    the strokes are where they are at 1."""
    rig = Au.build_points_rig(tmp_path / "in.usda", frames=(1, 10))
    st = Usd.Stage.Open(str(rig.path))
    st.GetPrimAtPath(rig.mesh).GetAttribute("points").Set(Sdf.ValueBlock(), 3.0)
    st.GetRootLayer().Save()
    del st
    src = Usd.Stage.Open(str(rig.path))
    check = src.GetPrimAtPath(rig.mesh).GetAttribute("points")
    assert np.array_equal(np.array(check.Get(2.0)), np.array(check.Get(1.0))) and check.Get(3.0) is None
    out = tmp_path / "bake.usda"
    painterly("bake", rig.path, "-o", out, "--frames", "1:2:0.5", "--quiet")
    bake_stage = Usd.Stage.Open(str(out))
    baked = bake_stage.GetPrimAtPath(rig.layers[0]).GetAttribute("points")
    at1 = np.array(baked.Get(1.0))
    for t in (1.5, 2.0):
        assert np.array_equal(np.array(baked.Get(t)), at1), t
    # At the block there is no proxy: the bake says so.
    proc = painterly("bake", rig.path, "-o", tmp_path / "at3.usda", "--frames", "3", check=False)
    assert proc.returncode == 1 and f"{rig.mesh}.points" in proc.stderr


def test_a_display_opacity_fade_is_baked_per_frame(painterly, tmp_path):
    """`primvars:displayOpacity` samples (with and without a default): the
    bake's per-curve opacity at each frame is usd-core's value at that frame
    times `painterly:opacity` (0.5 here)."""
    for default in (None, 0.25):
        d = tmp_path / f"default_{default}"
        d.mkdir()
        rig = Au.build_skel_rig(d / "in.usda", frames=(1, 10))
        st = Usd.Stage.Open(str(rig.path))
        layer = st.GetPrimAtPath(rig.layers[0])
        n = len(layer.GetAttribute("curveVertexCounts").Get())
        dop = layer.CreateAttribute("primvars:displayOpacity", Sdf.ValueTypeNames.FloatArray)
        dop.SetMetadata("interpolation", "uniform")
        if default is not None:
            dop.Set(Vt.FloatArray([default] * n))
        dop.Set(Vt.FloatArray([0.0] * n), 1.0)
        dop.Set(Vt.FloatArray(list(np.linspace(0.5, 1.0, n))), 10.0)
        layer.CreateAttribute("painterly:opacity", Sdf.ValueTypeNames.Float).Set(0.5)
        st.GetRootLayer().Save()
        del st, layer, dop
        src_stage = Usd.Stage.Open(str(rig.path))
        src = src_stage.GetPrimAtPath(rig.layers[0]).GetAttribute("primvars:displayOpacity")
        out = d / "bake.usda"
        painterly("bake", rig.path, "-o", out, "--frames", "1:10:1.5", "--quiet")
        bake_stage = Usd.Stage.Open(str(out))
        baked = bake_stage.GetPrimAtPath(rig.layers[0]).GetAttribute("primvars:displayOpacity")
        times = baked.GetTimeSamples()
        assert times == [1.0, 2.5, 4.0, 5.5, 7.0, 8.5, 10.0]
        for t in times:
            want = np.array(src.Get(t), dtype=np.float32) * np.float32(0.5)
            assert np.allclose(np.array(baked.Get(t)), want, rtol=0, atol=1e-7), (default, t)


def _rotation_vector(q):
    """Axis × angle (radians) of a Gf.Quatd, the shorter way round."""
    w, v = q.GetReal(), np.array(q.GetImaginary())
    if w < 0:
        w, v = -w, -v
    n = np.linalg.norm(v)
    return np.zeros(3) if n == 0 else v / n * 2 * np.arctan2(n, w)


def test_axes_read_a_sample_held_up_to_a_block(tmp_path):
    """blendShape, jointRotation and position axes (SPEC §4) between a
    sample and a block after it read the sample, as usd-core does (they read
    0, the rest pose and the identity before)."""
    painterly = pytest.importorskip("painterly")
    rig, st = blocked_skel_rig(tmp_path)
    anim = st.GetPrimAtPath("/World/Character/Anim")
    loc = UsdGeom.Xform.Define(st, "/World/Loc")
    op = loc.AddTranslateOp()
    op.Set(Gf.Vec3d(1, 2, 3), 1)
    op.Set(Sdf.ValueBlock(), 6)
    op.Set(Gf.Vec3d(3, 2, 1), 12)
    shape = list(anim.GetAttribute("blendShapes").Get())[0]
    AK.add_axis(st, "/World/Paint/bs", "blendShape", source="/World/Character/Anim", name=shape)
    AK.add_axis(st, "/World/Paint/jr", "jointRotation", source="/World/Character/Skel", name="root/mid", component=0)
    AK.add_axis(st, "/World/Paint/pos", "position", source="/World/Loc", component=0)
    AK.add_pose_key(st, rig.layers[0], "k0", [0.0] * 3, opacity=1.0)
    AK.add_pose_key(st, rig.layers[0], "k1", [1.0] * 3, opacity=0.5)
    st.GetRootLayer().Save()
    del st, anim, loc, op
    st = Usd.Stage.Open(str(rig.path))
    skel = UsdSkel.Skeleton(st.GetPrimAtPath("/World/Character/Skel"))
    joint = list(skel.GetJointsAttr().Get()).index("root/mid")
    rest = Gf.Matrix4d(skel.GetRestTransformsAttr().Get()[joint]).ExtractRotationQuat()
    query = UsdSkel.Cache().GetSkelQuery(skel)
    weights = st.GetAttributeAtPath("/World/Character/Anim.blendShapeWeights")
    names = list(st.GetAttributeAtPath("/World/Character/Anim.blendShapes").Get())
    proxy = UsdGeom.Xformable(st.GetPrimAtPath(rig.mesh))
    loc = UsdGeom.Xformable(st.GetPrimAtPath("/World/Loc"))
    character = painterly.Character(str(rig.path))
    for t in (5.0, 5.5, 9.0, 9.5):
        got = character.configuration(t)
        world = loc.ComputeLocalToWorldTransform(t).ExtractTranslation()
        local = proxy.ComputeLocalToWorldTransform(t).GetInverse().Transform(world)
        q = Gf.Matrix4d(query.ComputeJointLocalTransforms(t)[joint]).ExtractRotationQuat()
        want = {
            "/World/Paint/bs": weights.Get(t)[names.index(shape)],
            "/World/Paint/jr": _rotation_vector(rest.GetInverse() * q)[0],
            "/World/Paint/pos": local[0],
        }
        for axis, value in want.items():
            assert abs(got[axis] - value) < 1e-5, (t, axis, got[axis], value)
    # The blocks bite at these times.
    assert weights.Get(5.0) == weights.Get(4.0) and max(weights.Get(4.0)) > 0
    assert loc.ComputeLocalToWorldTransform(5.0).ExtractTranslation()[0] == 1.0


def test_indices_authored_only_as_samples_are_read_per_frame(painterly, tmp_path):
    """`primvars:displayOpacity:indices` with one time sample and no
    default: usd-core reads no indices at the default time but flattens
    them at every frame, and so does the bake (it refused the layer: 2
    values for 4 curves)."""
    rig = Au.build_points_rig(tmp_path / "in.usda", mode="static", frames=(1, 3), n_strokes=4)
    st = Usd.Stage.Open(str(rig.path))
    pv = UsdGeom.PrimvarsAPI(st.GetPrimAtPath(rig.layers[0])).CreatePrimvar(
        "displayOpacity", Sdf.ValueTypeNames.FloatArray, "uniform")
    pv.Set(Vt.FloatArray([0.2, 0.9]))
    pv.SetIndices(Vt.IntArray([0, 1, 1, 0]), 1.0)
    st.GetRootLayer().Export(str(tmp_path / "both.usda"))
    st.GetRootLayer().Save()
    del st, pv
    # The same with the values sampled too (a fade of an indexed primvar).
    both = Usd.Stage.Open(str(tmp_path / "both.usda"))
    values = both.GetPrimAtPath(rig.layers[0]).GetAttribute("primvars:displayOpacity")
    values.Set(Vt.FloatArray([0.1, 0.5]), 1.0)
    values.Set(Vt.FloatArray([0.3, 0.7]), 3.0)
    both.GetRootLayer().Save()
    del both, values
    for path, name in ((tmp_path / "both.usda", "both"),):
        src_stage = Usd.Stage.Open(str(path))
        src = UsdGeom.PrimvarsAPI(src_stage.GetPrimAtPath(rig.layers[0])).GetPrimvar("displayOpacity")
        out = tmp_path / f"bake_{name}.usda"
        painterly("bake", path, "-o", out, "--quiet")
        bake_stage = Usd.Stage.Open(str(out))
        baked = bake_stage.GetPrimAtPath(rig.layers[0]).GetAttribute("primvars:displayOpacity")
        for t in (1.0, 2.0, 3.0):
            want = np.array(src.ComputeFlattened(t), dtype=np.float32)
            # openusd and usd-core round the interpolated float apart by an ulp.
            got = np.array(baked.Get(t), dtype=np.float32)
            assert want.shape == (4,) and np.allclose(got, want, rtol=0, atol=1e-7), (name, t)
        assert not np.array_equal(np.array(baked.Get(1.0)), np.array(baked.Get(3.0)))
    src_stage = Usd.Stage.Open(str(rig.path))
    src = UsdGeom.PrimvarsAPI(src_stage.GetPrimAtPath(rig.layers[0])).GetPrimvar("displayOpacity")
    out = tmp_path / "bake.usda"
    painterly("bake", rig.path, "-o", out, "--quiet")
    bake_stage = Usd.Stage.Open(str(out))
    baked = bake_stage.GetPrimAtPath(rig.layers[0]).GetAttribute("primvars:displayOpacity")
    for t in (1.0, 2.0, 3.0):
        want = np.array(src.ComputeFlattened(t), dtype=np.float32)
        assert want.shape == (4,) and np.array_equal(np.array(baked.Get(t), dtype=np.float32), want), t


def test_render_reads_sampled_color_indices_per_frame(painterly, tmp_path):
    """`primvars:displayColor:indices` sampled at 1 (all red) and 3 (all
    blue): render drew frame 1 red and frame 3 blue, as usd-core's
    ComputeFlattened gives (it refused the primvar at every frame)."""
    rig = Au.build_points_rig(tmp_path / "in.usda", mode="static", frames=(1, 3), n_strokes=4)
    st = Usd.Stage.Open(str(rig.path))
    UsdGeom.Camera.Define(st, "/World/Cam").AddTranslateOp().Set(Gf.Vec3d(0, 2, 9))
    pv = UsdGeom.PrimvarsAPI(st.GetPrimAtPath(rig.layers[0])).CreatePrimvar(
        "displayColor", Sdf.ValueTypeNames.Color3fArray, "uniform")
    pv.Set(Vt.Vec3fArray([(1, 0, 0), (0, 0, 1)]))
    pv.SetIndices(Vt.IntArray([0, 0, 0, 0]), 1.0)
    pv.SetIndices(Vt.IntArray([1, 1, 1, 1]), 3.0)
    st.GetPrimAtPath(rig.mesh).GetAttribute("visibility").Set("invisible")  # strokes only
    st.GetRootLayer().Save()
    del st, pv
    painterly("render", rig.path, "--camera", "/World/Cam", "--frames", "1:3:2", "-o", tmp_path / "f.####.exr",
              "--size", "64x40", "--quiet")
    import OpenEXR
    for frame, (strong, weak) in ((1, ("R", "B")), (3, ("B", "R"))):
        with OpenEXR.File(str(tmp_path / f"f.{frame:04d}.exr"), separate_channels=True) as f:
            ch = {k: np.array(v.pixels, dtype=np.float64) for k, v in f.channels().items()}
        drawn = ch["A"] > 0
        assert drawn.any(), frame
        assert (ch[strong][drawn] > 0).all() and (ch[weak][drawn] == 0).all(), frame


def test_a_sampled_display_opacity_that_does_not_fit_names_its_time(painterly, tmp_path):
    """A fade whose sample at 2 has 3 values for 4 curves: the bake stops
    there, naming the attribute and the time."""
    rig = Au.build_points_rig(tmp_path / "in.usda", mode="static", frames=(1, 3), n_strokes=4)
    st = Usd.Stage.Open(str(rig.path))
    layer = st.GetPrimAtPath(rig.layers[0])
    counts = list(layer.GetAttribute("curveVertexCounts").Get())
    dop = layer.CreateAttribute("primvars:displayOpacity", Sdf.ValueTypeNames.FloatArray)
    dop.Set(Vt.FloatArray([0.5] * len(counts)), 1.0)
    dop.Set(Vt.FloatArray([0.5] * 3), 2.0)
    st.GetRootLayer().Save()
    del st, layer, dop
    out = tmp_path / "bake.usda"
    proc = painterly("bake", rig.path, "-o", out, "--frames", "1:2", check=False)
    assert proc.returncode == 1 and not out.exists()
    assert proc.stderr == (
        f"error: {rig.path}: {rig.layers[0]}.primvars:displayOpacity: at time 2: 3 values fit neither 1, "
        f"{len(counts)} curves nor {sum(counts)} points\n")


def test_render_draws_points_held_up_to_a_block(painterly, tmp_path):
    """Plain curves and a mesh (no painterly rig: render draws their own
    `points`) with a points sample at 1 and a block at 3: at 2 usd-core holds
    the sample, so render draws them there as at 1 (it drew nothing: openusd
    gave no points), and at 3 draws nothing."""
    stage = Usd.Stage.CreateNew(str(tmp_path / "in.usda"))
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(3)
    UsdGeom.Camera.Define(stage, "/Cam").AddTranslateOp().Set(Gf.Vec3d(0, 0, 5))
    curves = UsdGeom.BasisCurves.Define(stage, "/Curves")
    curves.CreateTypeAttr("linear")
    curves.CreateCurveVertexCountsAttr([2])
    curves.CreateWidthsAttr([0.2])
    mesh = UsdGeom.Mesh.Define(stage, "/Quad")
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    for attr, pts in ((curves.GetPointsAttr(), [(-1, 0.5, 0), (1, 0.5, 0)]),
                      (mesh.GetPointsAttr(), [(-1, -1, 0), (0, -1, 0), (0, -0.2, 0), (-1, -0.2, 0)])):
        attr.Set(Vt.Vec3fArray(pts), 1.0)
        attr.Set(Sdf.ValueBlock(), 3.0)
        assert attr.Get(2.0) is not None and attr.Get(3.0) is None
    stage.GetRootLayer().Save()
    del stage, curves, mesh
    painterly("render", tmp_path / "in.usda", "--camera", "/Cam", "--frames", "1:3", "-o", tmp_path / "f.####.exr",
              "--size", "64x40", "--quiet")
    import OpenEXR
    alpha = {}
    for frame in (1, 2, 3):
        with OpenEXR.File(str(tmp_path / f"f.{frame:04d}.exr"), separate_channels=True) as f:
            alpha[frame] = np.array(f.channels()["A"].pixels, dtype=np.float64)
    assert (alpha[1] > 0).any() and np.array_equal(alpha[2], alpha[1])
    assert not (alpha[3] > 0).any()


@pytest.mark.parametrize("indices_at", [None, 1.0], ids=["default-indices", "sampled-indices"])
def test_an_indexed_display_opacity_composes_as_the_input_flattened(painterly, tmp_path, indices_at):
    """An indexed `primvars:displayOpacity` on the input: the bake writes one
    value per curve, so over the input (bake stronger) the composed primvar
    must flatten to the input's flattened values times `painterly:opacity`
    (usd-core). The bake left the input's indices in force, re-indexing its
    per-curve values (found by a farm review, 2026-12-06)."""
    rig = Au.build_points_rig(tmp_path / "in.usda", mode="static", frames=(1, 3), n_strokes=4)
    st = Usd.Stage.Open(str(rig.path))
    prim = st.GetPrimAtPath(rig.layers[0])
    pv = UsdGeom.PrimvarsAPI(prim).CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray, "uniform")
    pv.Set(Vt.FloatArray([0.2, 0.9]))
    if indices_at is None:
        pv.SetIndices(Vt.IntArray([1, 0, 1, 1]))
    else:
        pv.SetIndices(Vt.IntArray([1, 0, 1, 1]), indices_at)
    prim.CreateAttribute("painterly:opacity", Sdf.ValueTypeNames.Float).Set(0.8)
    st.GetRootLayer().Save()
    del st, pv, prim
    src = Usd.Stage.Open(str(rig.path))
    src_pv = UsdGeom.PrimvarsAPI(src.GetPrimAtPath(rig.layers[0])).GetPrimvar("displayOpacity")
    for out, extra in ((tmp_path / "bake.usdc", ()), (tmp_path / "bake.usda", ()),
                       (tmp_path / "shot.usda", ("--chunk", "2"))):
        painterly("bake", rig.path, "-o", out, "--quiet", *extra)
        composed = Au.compose(rig.path, out)
        got_pv = UsdGeom.PrimvarsAPI(composed.GetPrimAtPath(rig.layers[0])).GetPrimvar("displayOpacity")
        for t in (1.0, 2.0, 3.0):
            want = np.array(src_pv.ComputeFlattened(t), dtype=np.float64) * np.float32(0.8)
            assert list(want) != sorted(want)  # the indices reorder: a re-indexing shows
            got = np.array(got_pv.ComputeFlattened(t), dtype=np.float64)
            assert got.shape == (4,) and np.allclose(got, want, rtol=0, atol=1e-6), (out.name, t, got, want)
