"""Issue 11 ("Trust between commands"): malformed skeletons and bindings.

Each case is a rig written by usd-core and then broken in one place. Where
usd-core cannot skin the mesh as authored (it warns and leaves the mesh, or
some frames, unskinned: checked here with its own BakeSkinning), `bake` and
`inspect` both exit 1 naming the prim and attribute. Where usd-core's UsdSkel
rules still give a complete result (duplicate or unknown names, animation
arrays it ignores at some times, restTransforms it does not need), the bake
matches it exactly, at integer and quarter frames, and `inspect` passes,
with a note where the result may surprise.
"""

import json

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdSkel, Vt

import authoring as Au
import authoring_skel as S

TOL = 1e-5
QUARTERS = ("1:6:0.25", Au.frame_list(1, 6, 0.25))
SKEL = "/World/Character/Skel"
ANIM = "/World/Character/Skel/Anim"
MESH = "/World/Character/Body"


# ---------------------------------------------------------------------------
# edits (each gets authoring_skel.Handles before the file is saved)


def short(attr, at=None, n=2):
    """Cut the animation's `attr` to n entries at time `at` (None: every sample)."""
    def edit(h):
        a = h.anim.GetPrim().GetAttribute(attr)
        for t in ([at] if at is not None else h.key_times):
            v = a.Get(t)
            a.Set(type(v)(list(v)[:n]), t)
    return edit


def remove(holder, attr):
    def edit(h):
        getattr(h, holder).GetPrim().RemoveProperty(attr)
    return edit


def matrices(attr, n):
    """Give the Skeleton's `attr` n matrices (cycling the authored ones)."""
    def edit(h):
        a = h.skel.GetPrim().GetAttribute(attr)
        v = list(a.Get())
        a.Set(Vt.Matrix4dArray((v * 4)[:n]))
    return edit


def children_before_parents(h):
    perm = [1, 0, 2]  # ["a/b", "a", "a/b/c"], arrays permuted to match
    for attr in ["joints", "bindTransforms", "restTransforms"]:
        a = h.skel.GetPrim().GetAttribute(attr)
        v = list(a.Get())
        a.Set(type(a.Get())([v[i] for i in perm]))
    ji = list(h.binding.GetJointIndicesAttr().Get())
    new = {old: k for k, old in enumerate(perm)}
    h.binding.GetJointIndicesAttr().Set(Vt.IntArray([new[i] for i in ji]))


def joints(names):
    def edit(h):
        h.skel.GetJointsAttr().Set(names)
    return edit


def joint_index(k, value):
    def edit(h):
        ji = list(h.binding.GetJointIndicesAttr().Get())
        ji[k] = value
        h.binding.GetJointIndicesAttr().Set(Vt.IntArray(ji))
    return edit


def mesh_joints(names):
    def edit(h):
        h.binding.CreateJointsAttr(names)
    return edit


def weights_element_size(h):
    h.binding.GetJointWeightsPrimvar().SetElementSize(1)


def influence_interpolation(interp):
    def edit(h):
        h.binding.GetJointIndicesPrimvar().SetInterpolation(interp)
        h.binding.GetJointWeightsPrimvar().SetInterpolation(interp)
    return edit


def zero_weights_point(h):
    w = list(h.binding.GetJointWeightsAttr().Get())
    w[0] = w[1] = 0.0
    h.binding.GetJointWeightsAttr().Set(Vt.FloatArray(w))


def short_shape_weights(h):
    a = h.anim.GetBlendShapeWeightsAttr()
    for t in h.key_times:
        a.Set(Vt.FloatArray(list(a.Get(t))[:1]), t)


SHAPES = [dict(name="s0"), dict(name="s1", inbetweens=[(0.5, True)], weight=lambda u: 1.5 * u)]

# name: (skel_rig kwargs, edit, prim, attribute)
REJECTED = {
    "children_before_parents": (dict(), children_before_parents, SKEL, "joints"),
    "parent_duplicated_after_child": (dict(), joints(["a", "a/b", "a"]), SKEL, "joints"),
    "short_rotations_without_rest_pose": (dict(rest=False), short("rotations", 3.0), ANIM, "rotations"),
    "short_translations_without_rest_pose": (dict(rest=False), short("translations"), ANIM, "translations"),
    "short_scales_without_rest_pose": (dict(rest=False), short("scales", 6.0), ANIM, "scales"),
    "no_scales_without_rest_pose": (dict(rest=False), remove("anim", "scales"), ANIM, "scales"),
    "bind_transforms_too_short": (dict(), matrices("bindTransforms", 2), SKEL, "bindTransforms"),
    "bind_transforms_too_long": (dict(), matrices("bindTransforms", 4), SKEL, "bindTransforms"),
    "bind_transforms_missing": (dict(bind=False), None, SKEL, "bindTransforms"),
    "rest_transforms_wrong_length_sparse_animation": (
        dict(anim_joints=["a/b/c", "a"]), matrices("restTransforms", 4), SKEL, "restTransforms"),
    "rest_transforms_missing_sparse_animation": (
        dict(rest=False, anim_joints=["a/b/c", "a"]), None, SKEL, "restTransforms"),
    "rest_transforms_wrong_length_no_animation": (
        dict(anim=False), matrices("restTransforms", 2), SKEL, "restTransforms"),
    "joint_index_out_of_range": (dict(), joint_index(5, 7), MESH, "primvars:skel:jointIndices"),
    "joint_index_negative": (dict(), joint_index(5, -1), MESH, "primvars:skel:jointIndices"),
    "joint_index_beyond_mesh_joints": (
        dict(), lambda h: (mesh_joints(["a/b", "a"])(h), joint_index(9, 2)(h)), MESH,
        "primvars:skel:jointIndices"),
    "empty_mesh_joints": (dict(), mesh_joints([]), MESH, "skel:joints"),
    "influence_element_sizes_differ": (dict(), weights_element_size, MESH, "primvars:skel:jointWeights"),
    "varying_influences": (dict(), influence_interpolation("varying"), MESH, "primvars:skel:jointIndices"),
    "uniform_influences": (dict(), influence_interpolation("uniform"), MESH, "primvars:skel:jointIndices"),
}


@pytest.mark.parametrize("case", list(REJECTED))
def test_rejected_like_usd_core(painterly, tmp_path, case):
    kw, edit, prim, attr = REJECTED[case]
    rig = S.skel_rig(tmp_path / "rig.usda", edit=edit, **kw)
    assert not S.usd_core_skins_every_frame(rig), "usd-core skins this rig: the case tests nothing"
    before = Au.file_hash(rig.path)

    out, proc = S.bake_proxy(painterly, rig, tmp_path, check=False)
    assert proc.returncode == 1, f"exit {proc.returncode}\n{proc.stderr}"
    err = proc.stderr
    assert "panicked" not in err and "internal error" not in err, err
    assert str(rig.path) in err, f"error does not name the file:\n{err}"
    assert f"{prim}.{attr}" in err, f"error does not name {prim}.{attr}:\n{err}"
    assert not out.exists(), "failed bake left an output"
    assert Au.file_hash(rig.path) == before, "input modified"

    # inspect reports the same problem and fails.
    proc = painterly("inspect", rig.path, check=False)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert f"{prim}.{attr}" in proc.stdout, proc.stdout
    proc = painterly("inspect", rig.path, "--json", check=False)
    assert proc.returncode == 1
    problems = json.loads(proc.stdout)["problems"]
    assert any(p["prim"] == prim and p["attribute"] == attr for p in problems), problems


@pytest.mark.parametrize("names", [["a/b", "a", "a/b/c"], ["a", "a/b", "a"]])
def test_usd_core_topology_rejects_these_orders(names):
    ok, _why = UsdSkel.Topology(names).Validate()
    assert not ok


def test_usd_core_skeleton_query_has_no_bind_pose_for_wrong_lengths(tmp_path):
    rig = S.skel_rig(tmp_path / "rig.usda", edit=matrices("bindTransforms", 2))
    stage = Usd.Stage.Open(str(rig.path))
    query = UsdSkel.Cache().GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath(SKEL)))
    assert query and not query.HasBindPose()


# name: (skel_rig kwargs, edit, text a note must contain or None, deforms)
ACCEPTED = {
    "duplicate_joint_name": (dict(joints=["a", "a/b", "a/b"]), None, '"a/b" more than once', True),
    "duplicate_joint_name_sparse_animation": (
        dict(joints=["a", "a/b", "a/b"], anim_joints=["a/b", "a"]), None, "more than once", True),
    "joint_parent_is_a_grandparent_path": (dict(joints=["a", "a/x/b", "a/x/b/c"]), None, None, True),
    "ill_formed_joint_paths_are_roots": (dict(joints=["a", "a/b.1", "a/b.1/c"]), None, None, True),
    "short_rotations_at_one_time": (dict(rest_bend=25), short("rotations", 3.0), "at time 3", True),
    "short_rotations_everywhere": (dict(rest_bend=25), short("rotations"), "at every time", True),
    "short_translations_at_one_time": (dict(rest_bend=25), short("translations", 3.0), "translations", True),
    "long_scales_at_one_time": (dict(rest_bend=25), short("scales", 6.0, n=2), "scales", True),
    "short_rotations_sparse_animation": (
        dict(rest_bend=25, anim_joints=["a/b/c", "a"]), short("rotations", 3.0, n=1), "rotations", True),
    "animation_without_scales": (dict(rest_bend=25), remove("anim", "scales"), "scales is not authored", True),
    "rest_transforms_wrong_length_full_animation": (
        dict(), matrices("restTransforms", 2), "restTransforms", True),
    "no_animation_no_rest_transforms": (
        dict(anim=False, rest=False, skel_xform=Au.xf_static((0, 1, 0), (0, 0, 30)),
             geom_bind=S.Gf.Matrix4d().SetTranslate(S.Gf.Vec3d(1, 0, 0))),
        None, "does not skin", False),
    "no_animation_rest_pose": (dict(anim=False, rest_bend=25), None, None, True),
    "mesh_joints_name_unknown_joints": (dict(), mesh_joints(["a", "zz", "a/b/c"]), '"zz"', True),
    "mesh_joints_duplicated": (dict(), mesh_joints(["a/b", "a/b", "a/b/c"]), "more than once", True),
    "short_blend_shape_weights": (dict(shapes=SHAPES), short_shape_weights, None, True),
    "dqs_point_with_only_zero_weights": (dict(method="dualQuaternion"), zero_weights_point, None, True),
    "joint_indices_without_weights": (
        dict(shapes=SHAPES), remove("binding", "primvars:skel:jointWeights"), "jointWeights", True),
}


@pytest.mark.parametrize("times", ["integer", "quarter"])
@pytest.mark.parametrize("case", list(ACCEPTED))
def test_accepted_like_usd_core(painterly, tmp_path, case, times):
    kw, edit, note, deforms = ACCEPTED[case]
    rig = S.skel_rig(tmp_path / "rig.usda", edit=edit, **kw)
    moves = 0.01 if deforms else None
    if times == "integer":
        S.check_matches_usd_core(painterly, rig, tmp_path, tol=TOL, moves=moves)
    else:
        S.check_matches_usd_core(painterly, rig, tmp_path, *QUARTERS, tol=TOL, moves=moves)
        return
    proc = painterly("inspect", rig.path, "--json")
    rep = json.loads(proc.stdout)
    assert rep["problems"] == []
    notes = rep["rigs"][0]["notes"]
    if note:
        assert any(note in n for n in notes), notes


def test_inspect_and_bake_agree_on_every_case(painterly, tmp_path):
    """inspect exit 0 ⇔ bake exit 0, over every case in this file."""
    cases = [(k, v[0], v[1]) for k, v in REJECTED.items()] + [(k, v[0], v[1]) for k, v in ACCEPTED.items()]
    for name, kw, edit in cases:
        d = tmp_path / name
        d.mkdir()
        rig = S.skel_rig(d / "rig.usda", edit=edit, **kw)
        ins = painterly("inspect", rig.path, check=False).returncode
        bake = S.bake_proxy(painterly, rig, d, check=False)[1].returncode
        assert (ins == 0) == (bake == 0), f"{name}: inspect exit {ins}, bake exit {bake}"
        assert ins in (0, 1) and bake in (0, 1), name


def test_layered_restTransforms_block_is_missing(painterly, tmp_path):
    """A stronger layer that blocks restTransforms leaves a sparse animation
    without a rest pose: rejected, like a file that never had one."""
    base = S.skel_rig(tmp_path / "base.usda", anim_joints=["a/b/c", "a"])
    root = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    root.subLayerPaths.append("./base.usda")
    src = Sdf.Layer.FindOrOpen(str(base.path))
    root.startTimeCode, root.endTimeCode = src.startTimeCode, src.endTimeCode
    root.defaultPrim = src.defaultPrim
    root.Save()
    stage = Usd.Stage.Open(root)
    stage.GetPrimAtPath(SKEL).GetAttribute("restTransforms").Block()
    root.Save()
    rig = Au.Rig(tmp_path / "shot.usda", base.mesh, base.rig, base.layers, base.frames, base.rest)
    assert not S.usd_core_skins_every_frame(rig)
    _, proc = S.bake_proxy(painterly, rig, tmp_path, check=False)
    assert proc.returncode == 1 and f"{SKEL}.restTransforms" in proc.stderr, proc.stderr


# ---------------------------------------------------------------------------
# blend shapes that do not fit their mesh: usd-core warns and then skins the
# mesh without any of its blend shapes (README: painterly refuses instead)


def short_offsets(h):
    a = h.shapes["s0"].GetOffsetsAttr()
    a.Set(a.Get()[:-1])


def point_index_out_of_range(h):
    a = h.shapes["s1"].GetPointIndicesAttr()
    idx = list(a.Get())
    idx[0] = len(h.points) + 3
    a.Set(Vt.IntArray(idx))


BAD_SHAPES = [dict(name="s0", weight=lambda u: u), dict(name="s1", offsets="sparse", weight=lambda u: 1.5 * u)]


@pytest.mark.parametrize("case,edit,attr", [("short_offsets", short_offsets, "offsets"),
                                            ("point_index_out_of_range", point_index_out_of_range,
                                             "pointIndices")])
def test_blend_shapes_that_do_not_fit_are_refused(painterly, tmp_path, case, edit, attr):
    rig = S.skel_rig(tmp_path / "rig.usda", shapes=BAD_SHAPES, edit=edit)
    frames = list(rig.frames)

    def without_blend_shapes(stage):
        UsdSkel.BindingAPI(stage.GetPrimAtPath(MESH)).GetBlendShapeTargetsRel().SetTargets([])

    ref = S.usd_core_world(rig, frames)
    bare = S.usd_core_world(rig, frames, without_blend_shapes)
    assert all(np.array_equal(ref[t], bare[t]) for t in frames), \
        "usd-core applied a blend shape: the case tests nothing"

    out, proc = S.bake_proxy(painterly, rig, tmp_path, check=False)
    assert proc.returncode == 1, f"exit {proc.returncode}\n{proc.stderr}"
    shape = {"offsets": f"{MESH}/s0", "pointIndices": f"{MESH}/s1"}[attr]
    assert f"{shape}.{attr}" in proc.stderr, proc.stderr
    assert "panicked" not in proc.stderr
    assert not out.exists()
    proc = painterly("inspect", rig.path, "--json", check=False)
    assert proc.returncode == 1
    problems = json.loads(proc.stdout)["problems"]
    assert any(p["prim"] == shape and p["attribute"] == attr for p in problems), problems
