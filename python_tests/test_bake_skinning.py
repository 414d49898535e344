"""SPEC section 3: baked stroke points vs an independent reference.

Expected stroke points come from reference_skinning.py (fan triangulation,
closest-point binding, one-ring Procrustes, barycentric blend of 3x4
matrices, proxy local-to-world then stroke world-to-local) fed with
usd-core's own evaluation of the proxy (UsdSkel.BakeSkinning, or the points
attribute). Every baked point at every baked frame must agree within
1e-5 x the proxy's bbox diagonal (measured in the stroke layer's space).
"""

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom

import authoring as Au
import reference_skinning as R

TOL = 1e-5


def run_bake(painterly, rig, tmp_path, out_name="bake.usdc", frames_arg=None, extra=()):
    out = tmp_path / out_name
    args = ["bake", rig.path, "-o", out, "--quiet", *extra]
    if frames_arg:
        args += ["--frames", frames_arg]
    before = Au.file_hash(rig.path)
    painterly(*args)
    assert out.exists(), "bake reported success but wrote no file"
    assert Au.file_hash(rig.path) == before, "bake modified its input"
    return out


def stroke_scale(rig_path, posed_world, layer_path, mesh, t):
    """bbox diagonal of the posed proxy, expressed in the stroke layer's space."""
    st = Usd.Stage.Open(str(rig_path))
    m = np.linalg.inv(Au.gf_to_np(UsdGeom.Xformable(st.GetPrimAtPath(layer_path)).ComputeLocalToWorldTransform(t)))
    return Au.bbox_diag(Au.apply_row(posed_world[mesh][t], m))


def check_strokes(rig, out, frames, tol=TOL, override_binding=None, expected=None, posed=None):
    if posed is None:
        posed = Au.usdcore_world_points(rig.path, [rig.mesh], frames)
    if expected is None:
        expected = R.expected_strokes(rig.path, frames, posed_world=posed, override_binding=override_binding)
    comp = Au.compose(rig.path, out)
    layer = Sdf.Layer.FindOrOpen(str(out))
    for lp in rig.layers:
        pts_path = Sdf.Path(lp).AppendProperty("points")
        assert sorted(layer.ListTimeSamplesForPath(pts_path)) == pytest.approx(sorted(frames)), \
            f"{lp}.points time samples are not exactly the baked frames"
        worst, worst_t, worst_i = 0.0, None, None
        for t in frames:
            ours = Au.local_points(comp, lp, t)
            exp = expected[lp][t]
            assert ours.shape == exp.shape, f"{lp} t={t}: {ours.shape} vs expected {exp.shape}"
            scale = stroke_scale(rig.path, posed, lp, rig.mesh, t)
            err = np.linalg.norm(ours - exp, axis=1) / scale
            if err.max() > worst:
                worst, worst_t, worst_i = float(err.max()), t, int(err.argmax())
        assert worst <= tol, (f"{lp}: point {worst_i} off by {worst:.3g} x bbox diagonal at t={worst_t} "
                              f"(tolerance {tol:g})")
    return expected


SKEL_CASES = {
    "lbs": dict(),
    "rigid_constant": dict(interpolation="constant", influences=2),
    "geom_bind_transform": dict(geom_bind=True),
    "blend_shapes": dict(blend_shapes={"dense", "indexed", "inbetween"}),
    "sparse_animation": dict(sparse_anim=True),
    "transformed_skeleton_prim": dict(skel_xform=Au.xf_static((0.5, 1, 0), (0, 0, 45), (1, 2, 1)),
                                      mesh_parent_xform=Au.xf_static((0, 0, 1), (0, 20, 0), (1, 1, 1))),
    "two_layers": dict(extra_layers=1),
    "rest_from_points": dict(write_rest=False),
}


@pytest.mark.parametrize("case", list(SKEL_CASES))
def test_skinned_strokes_match_reference(painterly, tmp_path, case):
    # strokes on the surface, slightly above it, and far from it (the rest
    # tube is convex, so even far points have an unambiguous closest point)
    rig = Au.build_skel_rig(tmp_path / "rig.usda", offsets=(0.0, 0.01, 0.5), n_strokes=9,
                            **SKEL_CASES[case])
    out = run_bake(painterly, rig, tmp_path)
    check_strokes(rig, out, rig.frames)


def test_strokes_follow_transforms_between_proxy_and_strokes(painterly, tmp_path):
    """Proxy under animated/scaled Xforms, stroke layer under an animated rig
    Xform and with its own transform: points are written in stroke space."""
    rig = Au.build_skel_rig(
        tmp_path / "rig.usda", offsets=(0.0, 0.01, 0.4),
        world_xform=Au.xf_animated({1: ((0, 0, 0), (0, 0, 0), (1, 1, 1)),
                                    12: ((2, -1, 0.5), (20, -30, 45), (1.3, 1.3, 1.3))}),
        root_xform=Au.xf_static((0.5, 0, 0), (0, 90, 0), (2, 1, 1)),
        mesh_parent_xform=Au.xf_static((0, 1, 0), (10, 0, 0), (0.5, 0.5, 0.5)),
        rig_xform=Au.xf_animated({1: ((0, 1, 0), (0, 0, 0), (1, 1, 1)),
                                  6: ((3, 0, 0), (0, 60, 0), (1, 1, 1)),
                                  12: ((0, 0, -2), (45, 0, 0), (0.5, 0.5, 0.5))}),
        layer_xform=Au.xf_static((0.3, -0.2, 0.1), (5, 10, 15), (1, 2, 0.5)))
    out = run_bake(painterly, rig, tmp_path)
    check_strokes(rig, out, rig.frames)
    # sanity: the proxy-to-stroke transform is not the identity and changes
    # over time, so a bake that ignored either transform would fail above
    st = Usd.Stage.Open(str(rig.path))

    def proxy_to_stroke(t):
        pm = Au.gf_to_np(UsdGeom.Xformable(st.GetPrimAtPath(rig.mesh)).ComputeLocalToWorldTransform(t))
        sm = Au.gf_to_np(UsdGeom.Xformable(st.GetPrimAtPath(rig.layers[0])).ComputeLocalToWorldTransform(t))
        return pm @ np.linalg.inv(sm)
    assert not np.allclose(proxy_to_stroke(1), np.eye(4), atol=1e-3)
    assert not np.allclose(proxy_to_stroke(1), proxy_to_stroke(9), atol=1e-3)


def test_deep_layer_with_own_transform(painterly, tmp_path):
    """A stroke layer any depth under the rig, under its own Xforms."""
    rig = Au.build_skel_rig(tmp_path / "rig.usda")
    st = Usd.Stage.Open(str(rig.path))
    g = UsdGeom.Xform.Define(st, "/World/Paint/Group")
    Au.xf_animated({1: ((0, 0, 0), (0, 0, 0), (1, 1, 1)), 12: ((1, 1, 1), (0, 0, 90), (2, 2, 2))})(g)
    UsdGeom.Xform.Define(st, "/World/Paint/Group/Deep")
    rest = np.array(UsdGeom.Mesh(st.GetPrimAtPath(rig.mesh)).GetPointsAttr().Get(), dtype=np.float64)
    mesh = UsdGeom.Mesh(st.GetPrimAtPath(rig.mesh))
    sc, sp = Au.make_strokes(rest, list(mesh.GetFaceVertexCountsAttr().Get()),
                             list(mesh.GetFaceVertexIndicesAttr().Get()), np.random.default_rng(5), 5,
                             offsets=(0.0, 0.05))
    Au.add_stroke_layer(st, "/World/Paint/Group/Deep/Strokes", sc, sp,
                        xform=Au.xf_static((0, 0, 1), (30, 0, 0), (1, 1, 1)))
    st.GetRootLayer().Save()
    rig.layers.append("/World/Paint/Group/Deep/Strokes")
    out = run_bake(painterly, rig, tmp_path)
    check_strokes(rig, out, rig.frames)


def test_one_sample_values_hold_at_every_frame(painterly, tmp_path):
    """A transform op and painterly:opacity with one time sample beside a
    different default are the sample at every frame, as usd-core resolves
    them, though a bake reads a value that cannot vary only once. The first
    layer resets the transform stack under an animated rig Xform (its
    transform is fixed), the second inherits the animation."""
    rig = Au.build_skel_rig(
        tmp_path / "rig.usda", extra_layers=1, offsets=(0.0, 0.05),
        rig_xform=Au.xf_animated({1: ((0, 0, 0), (0, 0, 0), (1, 1, 1)), 12: ((1, 2, 0), (0, 45, 0), (1, 1, 1))}))
    st = Usd.Stage.Open(str(rig.path))
    for i, path in enumerate(rig.layers[:2]):
        prim = st.GetPrimAtPath(path)
        x = UsdGeom.Xformable(prim)
        x.SetResetXformStack(i == 0)
        op = x.AddTranslateOp(opSuffix="held")
        op.Set(Gf.Vec3d(0, 0, 0))
        op.Set(Gf.Vec3d(0.5, -0.25, 1.0 + i), 6)
    opacity = st.GetPrimAtPath(rig.layers[0]).CreateAttribute("painterly:opacity", Sdf.ValueTypeNames.Float, False)
    opacity.Set(0.9)
    opacity.Set(0.3, 6)
    st.GetRootLayer().Save()
    out = run_bake(painterly, rig, tmp_path)
    check_strokes(rig, out, rig.frames)
    comp = Au.compose(rig.path, out)
    pv = UsdGeom.PrimvarsAPI(comp.GetPrimAtPath(rig.layers[0])).GetPrimvar("displayOpacity")
    for t in rig.frames:
        np.testing.assert_allclose(np.array(pv.ComputeFlattened(t)), 0.3, rtol=1e-7, err_msg=f"t={t}")


def test_a_baked_point_beyond_float_range_is_named(painterly, tmp_path):
    """Finite inputs whose baked point leaves float's range (a stroke layer
    scaled far down, so stroke-local points are far out): exit 1, nothing
    written, and the error names the layer and the first such point."""
    f32_max = float(np.finfo(np.float32).max)
    rig = Au.build_skel_rig(tmp_path / "rig.usda", offsets=(0.0, 0.05))
    t0 = rig.frames[0]
    layer = rig.layers[0]
    # Without a layer transform, stroke-local = proxy-local: pick the scale
    # so that some points, but not the first, land beyond f32's largest
    # value, with a clear gap on both sides of it.
    m = np.abs(R.expected_strokes(rig.path, [t0])[layer][t0]).max(axis=1)
    above = np.unique(m[m > m[0]])
    gaps = above[1:] / above[:-1]
    k = int(np.argmax(gaps))
    assert gaps[k] > 1.001, "no clear gap between point sizes"
    scale = float(np.sqrt(above[k] * above[k + 1])) / f32_max
    st = Usd.Stage.Open(str(rig.path))
    UsdGeom.Xformable(st.GetPrimAtPath(layer)).AddScaleOp(UsdGeom.XformOp.PrecisionDouble).Set(
        Gf.Vec3d(scale, scale, scale))
    st.GetRootLayer().Save()
    size = np.abs(R.expected_strokes(rig.path, [t0])[layer][t0]).max(axis=1)
    first = int(np.argmax(size > f32_max))
    assert first > 0 and size[first] > f32_max and size[0] < f32_max
    out = tmp_path / "bake.usdc"
    proc = painterly("bake", rig.path, "-o", out, "--frames", f"{t0:g}:{t0:g}", check=False)
    assert proc.returncode == 1, proc.stderr
    assert f"{layer}: baked point {first} is not finite at time {t0:g}" in proc.stderr, proc.stderr
    assert not out.exists()


@pytest.mark.parametrize("default_points", [True, False])
def test_time_sampled_proxy_with_rest_time(painterly, tmp_path, default_points):
    """painterly:restTime picks the rest pose from the time-sampled points
    (even when a different default value exists)."""
    rig = Au.build_points_rig(tmp_path / "sampled.usda", mode="sampled", rest_time=4.0,
                              default_points=default_points)
    out = run_bake(painterly, rig, tmp_path)
    exp = check_strokes(rig, out, rig.frames)
    # At the rest time the strokes are back at their rest positions.
    np.testing.assert_allclose(exp[rig.layers[0]][4.0], R.describe(rig.path)[1][0]["layers"][0]["rest"],
                               atol=1e-5)
    if default_points:
        # the wrong rest pose (the default value) gives a measurably different bake
        stage, rigs = R.describe(rig.path)
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(rig.mesh))
        default = np.array(mesh.GetPointsAttr().Get(Usd.TimeCode.Default()), dtype=np.float64)
        assert np.abs(default - rigs[0]["topo"].rest).max() > 0.05


def test_time_sampled_proxy_default_rest(painterly, tmp_path):
    rig = Au.build_points_rig(tmp_path / "sampled.usda", mode="sampled", rest_time=None)
    out = run_bake(painterly, rig, tmp_path)
    check_strokes(rig, out, rig.frames)


def test_static_proxy_strokes_unchanged_modulo_transforms(painterly, tmp_path):
    rig = Au.build_points_rig(
        tmp_path / "static.usda", mode="static",
        proxy_xform=Au.xf_animated({1: ((0, 0, 0), (0, 0, 0), (1, 1, 1)), 10: ((1, 2, 3), (0, 90, 0), (2, 2, 2))}),
        rig_xform=Au.xf_static((0, -1, 0), (0, 0, 30), (1, 1, 1)),
        layer_xform=Au.xf_static((0.5, 0, 0), (0, 0, 0), (3, 3, 3)))
    out = run_bake(painterly, rig, tmp_path)
    st = Usd.Stage.Open(str(rig.path))
    rest = np.array(st.GetPrimAtPath(rig.layers[0]).GetAttribute("painterly:restPoints").Get(), dtype=np.float64)
    comp = Au.compose(rig.path, out)
    for t in rig.frames:
        pm = Au.gf_to_np(UsdGeom.Xformable(st.GetPrimAtPath(rig.mesh)).ComputeLocalToWorldTransform(t))
        sm = Au.gf_to_np(UsdGeom.Xformable(st.GetPrimAtPath(rig.layers[0])).ComputeLocalToWorldTransform(t))
        exp = R.to_stroke_space(rest, pm, sm)
        ours = Au.local_points(comp, rig.layers[0], t)
        np.testing.assert_allclose(ours, exp, atol=TOL * Au.bbox_diag(exp) * 10 + 1e-6,
                                   err_msg=f"static proxy, t={t}")
    check_strokes(rig, out, rig.frames)


def _other_binding(rest, counts, idx, pts):
    """A valid binding that is deliberately not the closest-point one: the
    triangle 7 further on in fan order, fixed weights."""
    tris = R.fan_triangles(counts, idx)
    verts, _ = R.bind(rest, tris, pts)
    out_v, out_w = [], []
    for v in verts:
        # find this triangle, take another one
        ti = int(np.nonzero((tris == v).all(axis=1))[0][0])
        other = tris[(ti + 7) % len(tris)]
        out_v.append(other)
        out_w.append((0.2, 0.3, 0.5))
    return np.array(out_v), np.array(out_w)


def test_cached_binding_is_honoured(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", bind_cache=_other_binding, offsets=(0.0, 0.02))
    posed = Au.usdcore_world_points(rig.path, [rig.mesh], rig.frames)
    stage, rigs = R.describe(rig.path)
    layer = rigs[0]["layers"][0]
    assert layer["cached"]
    # what a recomputed binding would give -- must differ, or the test is void
    fresh = R.bind(rigs[0]["topo"].rest, rigs[0]["topo"].tris, layer["rest"])
    with_fresh = R.expected_strokes(rig.path, rig.frames, posed_world=posed,
                                    override_binding={layer["path"]: fresh})
    with_cached = R.expected_strokes(rig.path, rig.frames, posed_world=posed)
    diff = max(np.abs(with_fresh[layer["path"]][t] - with_cached[layer["path"]][t]).max() for t in rig.frames)
    assert diff > 1e-2 * Au.bbox_diag(rig.rest)
    out = run_bake(painterly, rig, tmp_path)
    check_strokes(rig, out, rig.frames, expected=with_cached, posed=posed)


def test_cached_binding_between_fresh_layers(painterly, tmp_path):
    """The middle one of three layers has a cached binding; the other two are
    bound fresh (in one batch), each to its own points."""
    calls = []

    def middle_only(rest, counts, idx, pts):
        calls.append(len(pts))
        return _other_binding(rest, counts, idx, pts) if len(calls) == 2 else (None, None)

    rig = Au.build_skel_rig(tmp_path / "rig.usda", bind_cache=middle_only, extra_layers=2,
                            n_strokes=5, offsets=(0.0, 0.02))
    stage, rigs = R.describe(rig.path)
    assert [layer["cached"] for layer in rigs[0]["layers"]] == [False, True, False]
    out = run_bake(painterly, rig, tmp_path)
    check_strokes(rig, out, rig.frames)


@pytest.mark.parametrize("name", ["RiggedFigure", "CesiumMan"])
def test_real_asset_strokes(painterly, tmp_path, real_assets, name):
    rig = Au.wrap_real_asset(real_assets, name, tmp_path, n_strokes=12,
                             layer_xform=Au.xf_static((0.1, 0, 0), (0, 0, 10), (1, 1, 1)))
    out = run_bake(painterly, rig, tmp_path)
    check_strokes(rig, out, rig.frames)


@pytest.mark.parametrize("ext", ["usda", "usdc"])
def test_output_formats(painterly, tmp_path, ext):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", blend_shapes={"dense"})
    out = run_bake(painterly, rig, tmp_path, out_name=f"bake.{ext}")
    head = out.read_bytes()[:16]
    if ext == "usda":
        assert head.startswith(b"#usda 1.0"), head
    else:
        assert head.startswith(b"PXR-USDC"), head
    check_strokes(rig, out, rig.frames)


@pytest.mark.parametrize("frames_arg,frames", [
    ("2:11:3", [2.0, 5.0, 8.0, 11.0]),
    ("3:9:2", [3.0, 5.0, 7.0, 9.0]),
    ("4:10:4", [4.0, 8.0]),
    ("7:7", [7.0]),
    ("5", [5.0]),
])
def test_frame_subsets(painterly, tmp_path, frames_arg, frames):
    rig = Au.build_skel_rig(tmp_path / "rig.usda")
    out = run_bake(painterly, rig, tmp_path, frames_arg=frames_arg)
    check_strokes(rig, out, frames)


def test_fractional_frames(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", key_times=[1, 5, 12], blend_shapes={"dense"})
    frames = Au.frame_list(2, 4, 0.25)
    out = run_bake(painterly, rig, tmp_path, frames_arg="2:4:0.25")
    check_strokes(rig, out, frames)


def test_fractional_frames_real_asset(painterly, tmp_path, real_assets):
    rig = Au.wrap_real_asset(real_assets, "RiggedFigure", tmp_path)
    frames = Au.frame_list(10, 12, 0.5)
    out = run_bake(painterly, rig, tmp_path, frames_arg="10:12:0.5")
    check_strokes(rig, out, frames)


def test_flat_sheet_planar_and_collinear_one_rings(painterly, tmp_path):
    """A flat rest sheet: every one-ring is planar (the rotation must still be
    a proper rotation, det +1); one boundary vertex's one-ring is collinear
    (degenerate: R = I) while its fan triangles are not."""
    rig = Au.build_sheet_rig(tmp_path / "sheet.usda")
    stage, rigs = R.describe(rig.path)
    topo = rigs[0]["topo"]
    v = topo.n - 1
    assert topo.degenerate[v] and topo.degenerate.sum() == 1
    assert (rigs[0]["layers"][0]["verts"] == v).any(), "no stroke bound to the degenerate vertex"
    out = run_bake(painterly, rig, tmp_path)
    check_strokes(rig, out, rig.frames)
