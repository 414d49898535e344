"""SPEC section 2: the proxy mesh's evaluated points must match usd-core.

painterly's `--bake-proxy` output (composed over the input) is compared, in
world space, with usd-core's `UsdSkel.BakeSkinning` of the same mesh (baked
into the session layer, the input untouched) at every baked frame, within
1e-4 x the bbox diagonal. Rigs are authored with usd-core (authoring.py) or
are the real third-party assets.
"""

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdSkel

import authoring as Au

TOL = 1e-4


def _anim_world():
    return Au.xf_animated({1: ((0, 0, 0), (0, 0, 0), (1, 1, 1)),
                           12: ((1, 2, 3), (30, 40, 10), (1.5, 1.5, 1.5))})


SKEL_VARIANTS = {
    "lbs_1_influence": dict(influences=1),
    "lbs_2_influences": dict(influences=2),
    "lbs_4_influences": dict(influences=4),
    "rigid_constant_1": dict(interpolation="constant", influences=1),
    "rigid_constant_2": dict(interpolation="constant", influences=2),
    "geom_bind_transform": dict(geom_bind=True),
    "blend_shapes_dense_indexed_inbetween": dict(blend_shapes={"dense", "indexed", "inbetween"}),
    "blend_shape_weights_outside_0_1": dict(blend_shapes={"extrapolate"}),
    "blend_shape_negative_inbetween": dict(blend_shapes={"neg_inbetween"}),
    "transformed_xforms": dict(world_xform=_anim_world(),
                               root_xform=Au.xf_static((0.5, 0, 0), (0, 90, 0), (2, 1, 1)),
                               mesh_parent_xform=Au.xf_static((0, 1, 0), (10, 0, 0), (0.5, 0.5, 0.5))),
    "transformed_skeleton_prim": dict(skel_xform=Au.xf_animated({1: ((0, 0, 0), (0, 0, 0), (1, 1, 1)),
                                                                 12: ((0.5, 1, 0), (0, 0, 45), (1, 2, 1))})),
    "transformed_skeleton_rigid": dict(interpolation="constant", influences=2,
                                       skel_xform=Au.xf_static((1, 0, 0), (0, 30, 0), (1, 1, 1))),
    "anim_source_on_skelroot": dict(anim_on="skelroot"),
    "mesh_joint_subset": dict(mesh_joints_subset=True, influences=2),
    "sparse_reordered_animation": dict(sparse_anim=True),
    "inherited_skeleton_binding": dict(inherited_skeleton=True),
    "inherited_joint_influences": dict(interpolation="constant", influences=2, inherited_influences=True),
    "indexed_joint_influences": dict(indexed_influences=True),
    "unnormalized_weights": dict(unnormalized_weights=True),
    "joint_scale": dict(scale_joint=True),
    "usdc_input": dict(),
}


def bake_proxy(painterly, rig, tmp_path, frames_arg=None, out_name="bake.usdc"):
    out = tmp_path / out_name
    args = ["bake", rig.path, "-o", out, "--bake-proxy", "--quiet"]
    if frames_arg:
        args += ["--frames", frames_arg]
    painterly(*args)
    assert out.exists()
    return out


def check_proxy_matches_usd_core(rig, out, frames, tol=TOL):
    """World-space comparison at every frame + layer-level checks."""
    ref = Au.usdcore_world_points(rig.path, [rig.mesh], frames)[rig.mesh]
    comp = Au.compose(rig.path, out)
    diag = max(Au.bbox_diag(ref[t]) for t in frames)
    worst, worst_t = 0.0, None
    for t in frames:
        ours = Au.world_points(comp, rig.mesh, t)
        assert ours.shape == ref[t].shape, f"t={t}: {ours.shape} points, usd-core has {ref[t].shape}"
        assert np.all(np.isfinite(ours)), f"t={t}: non-finite proxy points"
        err = float(np.abs(ours - ref[t]).max()) / diag
        if err > worst:
            worst, worst_t = err, t
    assert worst <= tol, (f"{rig.mesh}: max error {worst:.3g} x bbox diagonal at t={worst_t} "
                          f"(tolerance {tol:g})")

    layer = Sdf.Layer.FindOrOpen(str(out))
    pts_path = Sdf.Path(rig.mesh).AppendProperty("points")
    ext_path = Sdf.Path(rig.mesh).AppendProperty("extent")
    assert layer.GetAttributeAtPath(pts_path), f"bake has no {pts_path}"
    assert sorted(layer.ListTimeSamplesForPath(pts_path)) == pytest.approx(sorted(frames))
    assert sorted(layer.ListTimeSamplesForPath(ext_path)) == pytest.approx(sorted(frames))
    for t in frames:
        pts = np.array(layer.QueryTimeSample(pts_path, t), dtype=np.float64)
        ext = np.array(layer.QueryTimeSample(ext_path, t), dtype=np.float64)
        np.testing.assert_allclose(ext, [pts.min(0), pts.max(0)], atol=1e-6 * diag + 1e-7,
                                   err_msg=f"proxy extent at t={t} is not min/max of the points")
    return comp, ref


def check_not_skinned_twice(rig, out, frames):
    """skel:skeleton is blocked in the bake, so usd-core's own bake of the
    composed stage must leave the baked points where they are."""
    comp = Au.compose(rig.path, out)
    rel = comp.GetPrimAtPath(rig.mesh).GetRelationship("skel:skeleton")
    assert rel, "no skel:skeleton relationship on the composed proxy"
    assert rel.GetTargets() == [], f"skel:skeleton still targets {rel.GetTargets()}"
    layer = Sdf.Layer.FindOrOpen(str(out))
    rspec = layer.GetRelationshipAtPath(Sdf.Path(rig.mesh).AppendProperty("skel:skeleton"))
    assert rspec is not None, "bake does not author (block) skel:skeleton on the proxy"
    before = {t: Au.world_points(comp, rig.mesh, t) for t in frames}
    comp.SetEditTarget(comp.GetSessionLayer())
    UsdSkel.BakeSkinning(comp.Traverse(), Gf.Interval(min(frames), max(frames)))
    for t in frames:
        after = Au.world_points(comp, rig.mesh, t)
        assert np.abs(after - before[t]).max() <= 1e-6 * Au.bbox_diag(before[t]), \
            f"usd-core still deforms the baked proxy at t={t} (skinned twice)"


@pytest.mark.parametrize("variant", list(SKEL_VARIANTS))
def test_skinned_proxy_matches_usd_core(painterly, tmp_path, variant):
    ext = "usdc" if variant == "usdc_input" else "usda"
    rig = Au.build_skel_rig(tmp_path / f"rig.{ext}", **SKEL_VARIANTS[variant])
    before = Au.file_hash(rig.path)
    out = bake_proxy(painterly, rig, tmp_path)
    check_proxy_matches_usd_core(rig, out, rig.frames)
    check_not_skinned_twice(rig, out, rig.frames)
    assert Au.file_hash(rig.path) == before, "input modified"


def test_skinned_proxy_frame_subset(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", blend_shapes={"dense"})
    out = bake_proxy(painterly, rig, tmp_path, frames_arg="2:11:3")
    check_proxy_matches_usd_core(rig, out, [2.0, 5.0, 8.0, 11.0])


def test_skinned_proxy_fractional_frames(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", blend_shapes={"dense", "inbetween"}, key_times=[1, 5, 12])
    out = bake_proxy(painterly, rig, tmp_path, frames_arg="2:4:0.25")
    check_proxy_matches_usd_core(rig, out, Au.frame_list(2, 4, 0.25))


@pytest.mark.parametrize("name", ["RiggedSimple", "RiggedFigure", "CesiumMan"])
def test_real_asset_proxy_matches_usd_core(painterly, tmp_path, real_assets, name):
    rig = Au.wrap_real_asset(real_assets, name, tmp_path)
    src_hash = Au.file_hash(real_assets / name / f"{name}.usdz")
    out = bake_proxy(painterly, rig, tmp_path)
    check_proxy_matches_usd_core(rig, out, rig.frames)
    check_not_skinned_twice(rig, out, rig.frames)
    assert Au.file_hash(real_assets / name / f"{name}.usdz") == src_hash


@pytest.mark.parametrize("name", ["RiggedSimple", "CesiumMan"])
def test_real_asset_proxy_fractional_frames(painterly, tmp_path, real_assets, name):
    rig = Au.wrap_real_asset(real_assets, name, tmp_path)
    out = bake_proxy(painterly, rig, tmp_path, frames_arg="10:13:0.25")
    check_proxy_matches_usd_core(rig, out, Au.frame_list(10, 13, 0.25))


def test_dual_quaternion_matches_usd_core(painterly, tmp_path):
    """skel:skinningMethod = "dualQuaternion" (README: the proxy may be
    skinned "linear or dual-quaternion"): usd-core's DQS result, never a
    refusal and never a silent linear-blend result."""
    rig = Au.build_skel_rig(tmp_path / "dq.usda", skinning_method="dualQuaternion", twist=True)
    frames = rig.frames
    dq = Au.usdcore_world_points(rig.path, [rig.mesh], frames)[rig.mesh]
    lbs = Au.skinning_method_override(rig.path, rig.mesh, "classicLinear", frames)
    diag = max(Au.bbox_diag(dq[t]) for t in frames)
    # the rig must tell the two methods apart, or this test proves nothing
    assert max(np.abs(dq[t] - lbs[t]).max() for t in frames) > 100 * TOL * diag

    out = tmp_path / "dq_bake.usdc"
    before = Au.file_hash(rig.path)
    proc = painterly("bake", rig.path, "-o", out, "--bake-proxy", "--quiet", check=False)
    assert Au.file_hash(rig.path) == before
    assert (proc.returncode, proc.stdout, proc.stderr) == (0, "", ""), "a dualQuaternion proxy was refused"
    comp = Au.compose(rig.path, out)
    err_dq = max(np.abs(Au.world_points(comp, rig.mesh, t) - dq[t]).max() for t in frames) / diag
    err_lbs = max(np.abs(Au.world_points(comp, rig.mesh, t) - lbs[t]).max() for t in frames) / diag
    assert err_lbs > TOL or err_dq <= TOL, "dualQuaternion proxy silently skinned with linear blending"
    assert err_dq <= TOL, f"dualQuaternion proxy differs from usd-core by {err_dq:.3g} x diagonal"


@pytest.mark.parametrize("rest_time", [None, 4.0])
def test_time_sampled_proxy_is_its_points(painterly, tmp_path, rest_time):
    rig = Au.build_points_rig(tmp_path / "sampled.usda", mode="sampled", rest_time=rest_time,
                              proxy_xform=Au.xf_animated({1: ((0, 0, 0), (0, 0, 0), (1, 1, 1)),
                                                          10: ((1, -1, 2), (0, 45, 0), (1, 2, 1))}))
    out = bake_proxy(painterly, rig, tmp_path)
    comp, _ = check_proxy_matches_usd_core(rig, out, rig.frames, tol=1e-6)
    src = Usd.Stage.Open(str(rig.path))
    for t in rig.frames:
        np.testing.assert_allclose(Au.local_points(comp, rig.mesh, t), Au.local_points(src, rig.mesh, t),
                                   atol=1e-6, err_msg=f"t={t}")


def test_time_sampled_proxy_fractional_frames(painterly, tmp_path):
    rig = Au.build_points_rig(tmp_path / "sampled.usda", mode="sampled")
    out = bake_proxy(painterly, rig, tmp_path, frames_arg="1:3:0.5")
    check_proxy_matches_usd_core(rig, out, Au.frame_list(1, 3, 0.5), tol=1e-6)


@pytest.mark.parametrize("default_points", [True, False])
def test_point_cache_in_a_crate_sublayer_reads_as_usd_core_does(painterly, tmp_path, default_points):
    """Time-sampled proxy points in a usd-core-written .usdc sublayer with a
    layer offset (offset 2, scale 1.5) are read one sample at a time from the
    crate file (src/usd_io/crate_samples.rs), not through openusd's reader.
    The --bake-proxy points match usd-core at frames and fractional frames
    in stage time, and are bit-identical to the bake of the same stage whose
    sublayer is the .usda text (which openusd reads). Without default points
    it is a point cache whose rest pose is its first sample, in stage time."""
    from types import SimpleNamespace
    rig = Au.build_points_rig(tmp_path / "rig.usda", mode="sampled", default_points=default_points,
                              rest_time=None if default_points else 1.0)
    Sdf.Layer.FindOrOpen(str(rig.path)).Export(str(tmp_path / "rig.usdc"))
    frames = Au.frame_list(3.0, 2.0 + 1.5 * 10, 0.25)
    points = {}
    for ext in ("usdc", "usda"):
        root = tmp_path / f"root_{ext}.usda"
        root.write_text(f"#usda 1.0\n(\n    subLayers = [@./rig.{ext}@ (offset = 2; scale = 1.5)]\n)\n")
        if not default_points:
            # painterly:restTime is in the rig's own time: frame 1 is stage time 3.5.
            st = Usd.Stage.Open(str(root))
            assert st.GetPrimAtPath(rig.mesh).GetAttribute("points").Get(Usd.TimeCode.Default()) is None
        staged = SimpleNamespace(path=root, mesh=rig.mesh, frames=frames)
        out = bake_proxy(painterly, staged, tmp_path, frames_arg=f"{frames[0]}:{frames[-1]}:0.25",
                         out_name=f"bake_{ext}.usdc")
        check_proxy_matches_usd_core(staged, out, frames, tol=1e-6)
        layer = Sdf.Layer.FindOrOpen(str(out))
        pts = Sdf.Path(rig.mesh).AppendProperty("points")
        points[ext] = {t: np.array(layer.QueryTimeSample(pts, t), dtype=np.float32) for t in frames}
    for t in frames:
        assert np.array_equal(points["usdc"][t], points["usda"][t]), f"t={t}: crate and text reads differ"


def test_static_proxy_is_its_points(painterly, tmp_path):
    rig = Au.build_points_rig(tmp_path / "static.usda", mode="static",
                              proxy_xform=Au.xf_static((1, 2, 3), (10, 20, 30), (2, 2, 2)))
    out = bake_proxy(painterly, rig, tmp_path)
    comp, _ = check_proxy_matches_usd_core(rig, out, rig.frames, tol=1e-6)
    for t in rig.frames:
        np.testing.assert_allclose(Au.local_points(comp, rig.mesh, t), rig.rest, atol=1e-6)
