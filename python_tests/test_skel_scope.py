"""UsdSkel rules a review found painterly breaking, each checked against
usd-core's own `UsdSkel.BakeSkinning` of the same file (SPEC §2: the posed
proxy must match it):

- a mesh is skinned only under a SkelRoot, and binding properties are
  inherited from that SkelRoot down, not from above it;
- the animation comes from `skel:animationSource` on the Skeleton or its
  ancestors, never from the mesh;
- `skel:skinningMethod` (no `primvars:`) is not UsdSkel's name and does
  nothing; `rotations` must be `quatf[]`;
- joint influences, geomBindTransform and points stored as time samples
  are read (samples beat a default), and ones that change over time are
  refused rather than posed with a value usd-core does not use.

Also two axis rules from the same review: a `jointRotation` axis finds an
animation inherited from the SkelRoot, a `viewDirection` axis refuses a
camera at the proxy's centre up to rounding, and `component`/`element` on
a scalar source is refused.
"""

import json
import shutil

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

import authoring as Au

MESH = "/World/Character/Body"
SKEL = "/World/Character/Skel"
ANIM = "/World/Character/Anim"
IDX, WTS, GB = "primvars:skel:jointIndices", "primvars:skel:jointWeights", "primvars:skel:geomBindTransform"


def _rig(tmp_path, edit=None, **kw):
    d = tmp_path / "rig"
    shutil.rmtree(d, ignore_errors=True)
    d.mkdir()
    rig = Au.build_skel_rig(d / "rig.usda", **kw)
    if edit:
        stage = Usd.Stage.Open(str(rig.path))
        edit(stage)
        stage.GetRootLayer().Save()
    return rig


def _usd_core_points(rig):
    """usd-core's BakeSkinning of the rig into its session layer, per frame,
    in world space (the mesh at rest where usd-core does not skin it)."""
    stage = Usd.Stage.Open(str(rig.path))
    stage.SetEditTarget(stage.GetSessionLayer())
    UsdSkel.BakeSkinning(stage.Traverse(), Gf.Interval(min(rig.frames), max(rig.frames)))
    return {t: Au.world_points(stage, rig.mesh, t) for t in rig.frames}


def _assert_bake_matches_usd_core(painterly, rig, moves):
    out = rig.path.parent / "bake.usdc"
    painterly("bake", rig.path, "-o", out, "--bake-proxy", "--quiet")
    ref = _usd_core_points(rig)
    rest = Au.world_points(Usd.Stage.Open(str(rig.path)), rig.mesh, rig.frames[0])
    diag = max(Au.bbox_diag(p) for p in ref.values())
    # The case must tell skinned from still: usd-core moves the mesh or not.
    moved = max(np.abs(ref[t] - rest).max() for t in rig.frames) / diag
    assert (moved > 0.05) == moves, moved
    comp = Au.compose(rig.path, out)
    for t in rig.frames:
        err = np.abs(Au.world_points(comp, rig.mesh, t) - ref[t]).max() / diag
        assert err < 1e-5, (t, err)


def _notes(painterly, rig):
    report = json.loads(painterly("inspect", rig.path, "--json").stdout)
    return [n for r in report["rigs"] for n in r["notes"]]


# ---- SkelRoot scope -------------------------------------------------------


def _no_skel_root(stage):
    stage.GetPrimAtPath("/World/Character").SetTypeName("Xform")


def _skeleton_rel_above_root(stage):
    stage.GetPrimAtPath(MESH).RemoveProperty("skel:skeleton")
    UsdSkel.BindingAPI.Apply(stage.GetPrimAtPath("/World")).CreateSkeletonRel().SetTargets([SKEL])


def _geom_bind_above_root(stage):
    api = UsdSkel.BindingAPI.Apply(stage.GetPrimAtPath("/World"))
    api.CreateGeomBindTransformAttr(Gf.Matrix4d().SetTranslate(Gf.Vec3d(0.5, 0.2, 0)))


@pytest.mark.parametrize(
    "edit, moves",
    [(_no_skel_root, False), (_skeleton_rel_above_root, False), (_geom_bind_above_root, True)],
    ids=["no-skelroot", "skeleton-above-skelroot", "geombind-above-skelroot"],
)
def test_only_a_skel_roots_scope_binds_a_mesh(painterly, tmp_path, edit, moves):
    _assert_bake_matches_usd_core(painterly, _rig(tmp_path, edit), moves)


def test_a_binding_outside_any_skel_root_is_noted(painterly, tmp_path):
    rig = _rig(tmp_path, _no_skel_root)
    assert any(
        f"skel:skeleton on {MESH} binds {MESH} outside any SkelRoot's scope: usd-core does not skin it" in n
        for n in _notes(painterly, rig)
    ), _notes(painterly, rig)


def test_an_animation_source_on_the_mesh_drives_nothing(painterly, tmp_path):
    def edit(stage):
        stage.GetPrimAtPath(SKEL).RemoveProperty("skel:animationSource")
        UsdSkel.BindingAPI(stage.GetPrimAtPath(MESH)).CreateAnimationSourceRel().SetTargets([ANIM])

    _assert_bake_matches_usd_core(painterly, _rig(tmp_path, edit), moves=False)


# ---- names and types usd-core does not read -------------------------------


def test_a_bare_skinning_method_is_ignored_and_noted(painterly, tmp_path):
    def edit(stage):
        stage.GetPrimAtPath(MESH).CreateAttribute(
            "skel:skinningMethod", Sdf.ValueTypeNames.Token, False, Sdf.VariabilityUniform
        ).Set("dualQuaternion")

    rig = _rig(tmp_path, edit, twist=True)
    _assert_bake_matches_usd_core(painterly, rig, moves=True)
    assert any("authors skel:skinningMethod, which is not UsdSkel's name" in n for n in _notes(painterly, rig))


@pytest.mark.parametrize("kind", ["quath", "quatd"])
def test_rotations_not_quatf_leave_the_skeleton_at_rest(painterly, tmp_path, kind):
    type_name, array, quat = {
        "quath": (Sdf.ValueTypeNames.QuathArray, Vt.QuathArray, Gf.Quath),
        "quatd": (Sdf.ValueTypeNames.QuatdArray, Vt.QuatdArray, Gf.Quatd),
    }[kind]

    def edit(stage):
        layer = stage.GetRootLayer()
        path = Sdf.Path(ANIM).AppendProperty("rotations")
        samples = [(t, layer.QueryTimeSample(path, t)) for t in layer.ListTimeSamplesForPath(path)]
        spec = layer.GetPrimAtPath(ANIM)
        spec.RemoveProperty(spec.properties["rotations"])
        Sdf.AttributeSpec(spec, "rotations", type_name)
        for t, v in samples:
            layer.SetTimeSample(path, t, array([quat(q) for q in v]))

    rig = _rig(tmp_path, edit)
    _assert_bake_matches_usd_core(painterly, rig, moves=False)
    assert any(f"rotations is {kind}[], expected quatf[]" in n for n in _notes(painterly, rig))


# ---- skinning inputs stored as time samples -------------------------------


def _as_one_sample(names):
    def edit(stage):
        prim = stage.GetPrimAtPath(MESH)
        for n in names:
            a = prim.GetAttribute(n)
            v = a.Get()
            a.Clear()
            a.Set(v, 1.0)

    return edit


def _weights_sample_beats_default(stage):
    # The default is never used by usd-core once a sample exists.
    a = stage.GetPrimAtPath(MESH).GetAttribute(WTS)
    v = np.array(a.Get()).reshape(-1, 4)
    a.Set(Vt.FloatArray([float(x) for x in v[:, [1, 0, 2, 3]].ravel()]), 5.0)


@pytest.mark.parametrize(
    "edit, kw",
    [
        (_as_one_sample([IDX, WTS]), {}),
        (_as_one_sample([GB]), {"geom_bind": True}),
        (_as_one_sample(["points"]), {}),
        (_weights_sample_beats_default, {}),
    ],
    ids=["influences", "geombind", "points", "weights-sample-and-default"],
)
def test_skinning_inputs_stored_as_samples_are_read(painterly, tmp_path, edit, kw):
    _assert_bake_matches_usd_core(painterly, _rig(tmp_path, edit, **kw), moves=True)


def test_skinning_inputs_that_change_over_time_are_refused(painterly, tmp_path):
    def edit(stage):
        a = UsdGeom.Mesh(stage.GetPrimAtPath(MESH)).GetPointsAttr()
        v = np.array(a.Get(), dtype=np.float32)
        a.Set(Vt.Vec3fArray.FromNumpy(v), 1.0)
        a.Set(Vt.Vec3fArray.FromNumpy(v * np.float32(1.3)), 12.0)

    rig = _rig(tmp_path, edit)
    r = painterly("bake", rig.path, "-o", tmp_path / "out.usdc", check=False)
    assert r.returncode == 1, r.stderr
    assert f"{MESH}.points: changes over time (its samples at 1 and 12 differ)" in r.stderr
    assert not (tmp_path / "out.usdc").exists()


# ---- rotations between samples --------------------------------------------


def _assert_quarter_frames_match_usd_core(painterly, rig):
    """The proxy baked at quarter frames (most of them between samples)
    against usd-core's evaluation there."""
    frames = [1 + 0.25 * i for i in range(45)]
    out = rig.path.parent / "bake.usdc"
    painterly("bake", rig.path, "-o", out, "--bake-proxy", "--frames", "1:12:0.25", "--quiet")
    ref = Au.usdcore_world_points(rig.path, [rig.mesh], frames)[rig.mesh]
    diag = max(Au.bbox_diag(p) for p in ref.values())
    comp = Au.compose(rig.path, out)
    worst = max(np.abs(Au.world_points(comp, rig.mesh, t) - ref[t]).max() for t in frames) / diag
    assert worst < 1e-5, worst


def test_rotations_not_of_unit_length_interpolate_as_gf_slerp(painterly, tmp_path):
    """Exporters write quaternions a little off unit length. usd-core
    interpolates them with GfSlerp, which never normalises; openusd
    normalised a nearly parallel pair, 0.047 of the character off at
    |q| = 1.05 between samples (a UsdSkel review, 2026-12-06). Quarter
    frames put most times between samples."""
    def edit(stage):
        a = UsdSkel.Animation(stage.GetPrimAtPath(ANIM)).GetRotationsAttr()
        for t in a.GetTimeSamples():
            a.Set(Vt.QuatfArray([q * 1.05 for q in a.Get(t)]), t)

    _assert_quarter_frames_match_usd_core(painterly, _rig(tmp_path, edit))


def test_rotations_whose_samples_flip_sign_take_the_shorter_way(painterly, tmp_path):
    """q and -q are one rotation; exporters flip signs between samples.
    GfSlerp goes the shorter way (it negates the second quaternion when
    their dot is negative), as the bake must between samples."""
    def edit(stage):
        a = UsdSkel.Animation(stage.GetPrimAtPath(ANIM)).GetRotationsAttr()
        for i, t in enumerate(a.GetTimeSamples()):
            if i % 2:
                a.Set(Vt.QuatfArray([-q for q in a.Get(t)]), t)

    _assert_quarter_frames_match_usd_core(painterly, _rig(tmp_path, edit))
