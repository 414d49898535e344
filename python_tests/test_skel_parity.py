"""Issue 9 §2 / SPEC §2: a UsdSkel proxy evaluates as usd-core's
`UsdSkel.BakeSkinning` of the same mesh.

Every rig is written by usd-core (authoring_skel.skel_rig), baked with
`painterly bake --bake-proxy`, and compared in world space with usd-core's
BakeSkinning of the same file (into its session layer) at integer frames and
at quarter frames (the reference then runs at a 4x time-code rate, see
authoring.usdcore_world_points), within 1e-5 of the bbox diagonal. Each rig
also has to deform visibly in usd-core, so a comparison cannot pass by both
sides doing nothing.
"""

import json

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdSkel

import authoring as Au
import authoring_skel as S

TOL = 1e-5
QUARTERS = ("1:6:0.25", Au.frame_list(1, 6, 0.25))

# Transforms on every level: a blend-shape-only mesh stays in its own space,
# a skinned one goes through the Skeleton prim's transform.
XF = dict(root_xform=Au.xf_static((1, 0, 0), (0, 30, 0), (1, 1, 1)),
          skel_xform=Au.xf_static((0, 0.5, 0), (10, 0, 0), (1, 2, 1)),
          parent_xform=Au.xf_static((0, 1, 0), (0, 0, 20), (0.5, 0.5, 0.5)),
          mesh_xform=Au.xf_animated({1: ((0, 0, 0), (0, 0, 0), (1, 1, 1)),
                                     6: ((1, 2, 0), (0, 40, 0), (1, 1.5, 1))}))
GEOM_BIND = Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(1, 1, 0), 30)) * Gf.Matrix4d().SetTranslate(
    Gf.Vec3d(0.4, -0.3, 0.25))

# Weights below 0 and above 1, inbetweens at negative weights, several
# inbetweens per shape, a sparse (pointIndices) shape.
INBETWEENS = [
    dict(name="s0", inbetweens=[(0.5, True), (-0.5, True)], weight=lambda u: -1.2 + 3 * u),
    dict(name="s1", offsets="sparse", inbetweens=[(0.25, True), (1.5, True)], weight=lambda u: 2 * u - 0.3),
    dict(name="s2", weight=lambda u: 1.7 - 2 * u),
]

CASES = {
    # --- meshes driven only by blend shapes
    "skeleton_without_joints": dict(joints=[], shapes=INBETWEENS, geom_bind=GEOM_BIND, **XF),
    "skeleton_joints_not_authored": dict(joints=None, shapes=INBETWEENS, geom_bind=GEOM_BIND, **XF),
    "mesh_without_joint_indices": dict(influences=0, shapes=INBETWEENS, geom_bind=GEOM_BIND, **XF),
    # --- blend shapes
    "inbetweens_negative_and_beyond_one": dict(shapes=INBETWEENS, **XF),
    "shape_with_only_normal_offsets": dict(
        shapes=[dict(name="n0", offsets=None, normal_offsets=True), dict(name="s1", weight=lambda u: 1.5 * u)],
        **XF),
    "only_normal_offsets_no_joints": dict(
        joints=[], shapes=[dict(name="n0", offsets=None, normal_offsets=True),
                           dict(name="s1", inbetweens=[(0.5, True)], weight=lambda u: 1.5 * u)]),
    "inbetween_without_offsets": dict(
        shapes=[dict(name="s0", inbetweens=[(0.5, False), (-0.5, True)], weight=lambda u: -1 + 2.5 * u)]),
    "inbetweens_at_0_and_1_are_ignored": dict(
        shapes=[dict(name="s0", inbetweens=[(1.0, True), (1e-7, True), (0.6, True)],
                     weight=lambda u: -1 + 2.5 * u)]),
    # GfIsClose is strict and the query's EPS a float: an inbetween authored
    # at 1e-6 lies 1e-6 from 0, not closer, so usd-core keeps it.
    "inbetween_at_float_eps_is_kept": dict(
        shapes=[dict(name="s0", inbetweens=[(1e-6, True), (0.6, True)], weight=lambda u: -0.2 + 1.2 * u)]),
    # --- authored normals (points must not care)
    "vertex_normals": dict(normals="vertex", shapes=INBETWEENS, **XF),
    "face_varying_normals": dict(normals="faceVarying", **XF),
    # --- linear blend and dual-quaternion skinning
    "lbs_geom_bind_transform": dict(geom_bind=GEOM_BIND, influences=3, **XF),
    "dqs_geom_bind_transform": dict(geom_bind=GEOM_BIND, influences=3, method="dualQuaternion",
                                    pose=S.twist_pose, **XF),
    "dqs_unnormalized_weights": dict(influences=3, method="dualQuaternion", pose=S.twist_pose,
                                     unnormalized=True),
    "dqs_pivot_is_largest_weight": dict(joints=["r0", "r1", "r2"], influences=3, method="dualQuaternion",
                                        pose=S.spread_pose, reverse_influences=True),
    "dqs_joint_scale": dict(influences=3, method="dualQuaternion", pose=S.scale_pose, geom_bind=GEOM_BIND),
    "dqs_mirrored_joint": dict(influences=3, method="dualQuaternion", pose=S.mirror_pose),
    "dqs_rigid": dict(influences=2, interpolation="constant", method="dualQuaternion", pose=S.twist_pose,
                      **XF),
    "dqs_with_blend_shapes": dict(influences=2, method="dualQuaternion", pose=S.twist_pose,
                                  shapes=INBETWEENS),
}


@pytest.mark.parametrize("times", ["integer", "quarter"])
@pytest.mark.parametrize("case", list(CASES))
def test_proxy_matches_usd_core(painterly, tmp_path, case, times):
    rig = S.skel_rig(tmp_path / "rig.usda", **CASES[case])
    if times == "integer":
        S.check_matches_usd_core(painterly, rig, tmp_path, tol=TOL)
    else:
        S.check_matches_usd_core(painterly, rig, tmp_path, *QUARTERS, tol=TOL)


# ---------------------------------------------------------------------------
# authored normals: BakeSkinning rewrites vertex, varying and faceVarying
# normals; the bake must too, or the composed proxy keeps rest-pose normals

SCALED_BIND = GEOM_BIND * Gf.Matrix4d().SetScale(Gf.Vec3d(1, 1.3, 0.8))
NORMAL_SHAPES = [dict(name="n0", normal_offsets=True, inbetweens=[(0.5, True)], weight=lambda u: 1.6 * u - 0.3),
                 dict(name="s1", normal_offsets=True, offsets="sparse")]
NORMAL_CASES = {
    "lbs_vertex": dict(normals="vertex", geom_bind=SCALED_BIND, influences=3, **XF),
    "lbs_vertex_joint_scale": dict(normals="vertex", influences=3, pose=S.scale_pose),
    "lbs_face_varying": dict(normals="faceVarying", geom_bind=SCALED_BIND, influences=3, **XF),
    "dqs_vertex": dict(normals="vertex", geom_bind=SCALED_BIND, influences=3, method="dualQuaternion",
                       pose=S.twist_pose, **XF),
    "dqs_vertex_joint_scale": dict(normals="vertex", influences=3, method="dualQuaternion", pose=S.scale_pose),
    "dqs_vertex_mirrored_joint": dict(normals="vertex", influences=3, method="dualQuaternion", pose=S.mirror_pose),
    "dqs_face_varying": dict(normals="faceVarying", influences=3, method="dualQuaternion", pose=S.twist_pose,
                             **XF),
    "rigid": dict(normals="vertex", interpolation="constant", geom_bind=SCALED_BIND, **XF),
    "rigid_dqs": dict(normals="vertex", interpolation="constant", method="dualQuaternion", pose=S.twist_pose,
                      **XF),
    "normal_offsets_skinned": dict(normals="vertex", shapes=NORMAL_SHAPES, **XF),
    "normal_offsets_without_joints": dict(normals="vertex", joints=[], shapes=NORMAL_SHAPES, **XF),
    "face_varying_with_normal_offsets": dict(normals="faceVarying", shapes=NORMAL_SHAPES, **XF),
}


@pytest.mark.parametrize("times", ["integer", "quarter"])
@pytest.mark.parametrize("case", list(NORMAL_CASES))
def test_normals_match_usd_core(painterly, tmp_path, case, times):
    rig = S.skel_rig(tmp_path / "rig.usda", **NORMAL_CASES[case])
    if times == "integer":
        S.check_normals_match_usd_core(painterly, rig, tmp_path, tol=TOL)
    else:
        S.check_normals_match_usd_core(painterly, rig, tmp_path, *QUARTERS, tol=TOL)
    # ...and the normals do turn: a bake leaving rest normals would fail.
    src = Usd.Stage.Open(str(rig.path))
    turned = max(float(np.abs(S.world_normals(src, rig.mesh, t) - S.world_normals(
        Au.compose(rig.path, tmp_path / "proxy_bake.usdc"), rig.mesh, t)).max()) for t in rig.frames)
    assert turned > 0.01, f"normals barely change ({turned:.3g}): the case tests nothing"


def test_no_normals_written_for_meshes_without_them(painterly, tmp_path):
    rig = S.skel_rig(tmp_path / "rig.usda", shapes=INBETWEENS)
    out, _ = S.bake_proxy(painterly, rig, tmp_path)
    layer = Sdf.Layer.FindOrOpen(str(out))
    assert layer.GetAttributeAtPath(Sdf.Path(rig.mesh).AppendProperty("normals")) is None


def _dq_vs_lbs(tmp_path, case):
    rig = S.skel_rig(tmp_path / "rig.usda", **CASES[case])
    frames = rig.frames
    dq = S.usd_core_world(rig, frames)
    lbs = S.usd_core_world(rig, frames, lambda st: UsdSkel.BindingAPI(st.GetPrimAtPath(rig.mesh))
                           .CreateSkinningMethodAttr().Set("classicLinear"))
    diag = max(Au.bbox_diag(dq[t]) for t in frames)
    return max(float(np.abs(dq[t] - lbs[t]).max()) for t in frames) / diag


@pytest.mark.parametrize("case", ["dqs_geom_bind_transform", "dqs_pivot_is_largest_weight",
                                  "dqs_unnormalized_weights", "dqs_joint_scale", "dqs_rigid"])
def test_dqs_rigs_tell_dqs_from_lbs(tmp_path, case):
    """The DQS rigs prove DQS only if usd-core's linear-blend result is far
    from its DQS result: then a refused or silently linear bake fails them."""
    assert _dq_vs_lbs(tmp_path, case) > 100 * TOL


def test_blend_shape_without_offsets_is_a_note_not_a_problem(painterly, tmp_path):
    rig = S.skel_rig(tmp_path / "rig.usda", **CASES["shape_with_only_normal_offsets"])
    shape = rig.mesh + "/n0"
    proc = painterly("inspect", rig.path)
    assert proc.returncode == 0
    notes = [l for l in proc.stdout.splitlines() if l.strip().startswith("note:")]
    assert any(shape in l and "normalOffsets" in l and "no point" in l for l in notes), proc.stdout
    assert "no problems found" in proc.stdout
    rep = json.loads(painterly("inspect", rig.path, "--json").stdout)
    assert rep["problems"] == []
    (r,) = rep["rigs"]
    assert set(r) == {"path", "proxy", "proxy_points", "proxy_faces", "animation", "skeleton",
                      "animation_source", "layers", "notes"}
    assert r["animation"] == "UsdSkel" and r["skeleton"] == "/World/Character/Skel"
    assert any(shape in n and "normalOffsets" in n for n in r["notes"]), r["notes"]


def test_blend_shape_only_mesh_is_noted(painterly, tmp_path):
    rig = S.skel_rig(tmp_path / "rig.usda", **CASES["mesh_without_joint_indices"])
    rep = json.loads(painterly("inspect", rig.path, "--json").stdout)
    assert rep["problems"] == []
    notes = rep["rigs"][0]["notes"]
    assert any(rig.mesh in n and "primvars:skel:jointIndices" in n for n in notes), notes


def test_plain_rig_has_no_notes(painterly, tmp_path):
    rig = S.skel_rig(tmp_path / "rig.usda", shapes=INBETWEENS)
    rep = json.loads(painterly("inspect", rig.path, "--json").stdout)
    assert rep["problems"] == [] and rep["rigs"][0]["notes"] == []
    assert "note:" not in painterly("inspect", rig.path).stdout


# ---------------------------------------------------------------------------
# duplicated attribute specs: usd-core keeps the last spec of a prim's
# attribute in a .usda file, and the strongest layer's opinion


def _block_end(lines, i):
    """Index of the line closing the `{`-block opened on line i."""
    depth = 0
    for k in range(i, len(lines)):
        depth += lines[k].count("{") - lines[k].count("}")
        if depth == 0:
            return k
    raise ValueError("unbalanced block")


def _duplicate_spec(text, header, replacement, before):
    """Insert `replacement` (a whole attribute spec) just before or after the
    first spec whose line contains `header`."""
    lines = text.splitlines()
    i = next(k for k, l in enumerate(lines) if header in l)
    end = _block_end(lines, i) if lines[i].rstrip().endswith("{") else i
    indent = lines[i][: len(lines[i]) - len(lines[i].lstrip())]
    block = [indent + l for l in replacement.strip().splitlines()]
    at = i if before else end + 1
    return "\n".join(lines[:at] + block + lines[at:]) + "\n"


def test_duplicated_attribute_specs_match_usd_core(painterly, tmp_path):
    rig = S.skel_rig(tmp_path / "rig.usda", shapes=INBETWEENS[:1], **XF)
    text = rig.path.read_text()
    n = len(rig.rest)
    # Later specs win: these replace the animation...
    text = _duplicate_spec(text, "quatf[] rotations.timeSamples", """
quatf[] rotations.timeSamples = {
    1: [(1, 0, 0, 0), (0.9, 0.1, 0.2, 0), (1, 0, 0, 0)],
    6: [(0.95, 0, 0.3, 0.1), (0.8, 0.3, 0, 0.1), (0.9, 0.2, 0.1, 0)],
}""", before=False)
    text = _duplicate_spec(text, "float[] blendShapeWeights.timeSamples", """
float[] blendShapeWeights.timeSamples = {
    2: [1.4],
    5: [-0.7],
}""", before=False)
    # ...and these earlier ones lose to the specs usd-core wrote.
    text = _duplicate_spec(text, "uniform token[] joints = [\"a\", \"a/b\", \"a/b/c\"]",
                           'uniform token[] joints = ["q", "q/r", "q/r/s"]', before=True)
    text = _duplicate_spec(text, "int[] primvars:skel:jointIndices", "int[] primvars:skel:jointIndices = ["
                           + ", ".join(["7"] * (2 * n)) + "]", before=True)
    dup = tmp_path / "dup.usda"
    dup.write_text(text)
    stage = Usd.Stage.Open(str(dup))
    anim = stage.GetPrimAtPath("/World/Character/Skel/Anim")
    assert anim.GetAttribute("rotations").GetTimeSamples() == [1.0, 6.0]
    assert anim.GetAttribute("blendShapeWeights").GetTimeSamples() == [2.0, 5.0]
    rig = Au.Rig(dup, rig.mesh, rig.rig, rig.layers, rig.frames, rig.rest)
    S.check_matches_usd_core(painterly, rig, tmp_path, tol=TOL)
    S.check_matches_usd_core(painterly, rig, tmp_path, *QUARTERS, tol=TOL)


def test_stronger_layer_opinions_match_usd_core(painterly, tmp_path):
    """An override layer re-authors the animation at other times: only its
    samples count, as in usd-core."""
    base = S.skel_rig(tmp_path / "base.usda", shapes=INBETWEENS[:1], **XF)
    over = Sdf.Layer.CreateNew(str(tmp_path / "over.usda"))
    stage = Usd.Stage.Open(over)
    anim = stage.OverridePrim("/World/Character/Skel/Anim")
    rot = anim.CreateAttribute("rotations", Sdf.ValueTypeNames.QuatfArray)
    for t, deg in [(2.0, 20), (5.0, -45)]:
        rot.Set([S.quat((1, 0, 0), deg), S.quat((0, 0, 1), deg), S.quat((0, 1, 1), -deg)], t)
    anim.CreateAttribute("blendShapeWeights", Sdf.ValueTypeNames.FloatArray).Set([1.3], 4.0)
    over.Save()
    root = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    root.subLayerPaths.append("./over.usda")
    root.subLayerPaths.append("./base.usda")
    src = Sdf.Layer.FindOrOpen(str(base.path))
    root.startTimeCode, root.endTimeCode = src.startTimeCode, src.endTimeCode
    root.timeCodesPerSecond, root.framesPerSecond = src.timeCodesPerSecond, src.framesPerSecond
    root.defaultPrim = src.defaultPrim
    root.Save()
    rig = Au.Rig(tmp_path / "shot.usda", base.mesh, base.rig, base.layers, base.frames, base.rest)
    S.check_matches_usd_core(painterly, rig, tmp_path, tol=TOL)
    S.check_matches_usd_core(painterly, rig, tmp_path, *QUARTERS, tol=TOL)
