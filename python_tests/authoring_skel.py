"""Small UsdSkel rigs written by usd-core, for parity with `UsdSkel.BakeSkinning`
and for malformed-skeleton tests.

`skel_rig()` writes a tube bound to a Skeleton of any joints (a chain by
default), an animation, optional blend shapes (dense or sparse, inbetweens,
normal offsets only), authored normals, a geomBindTransform, a skinning
method and transforms above the mesh and the Skeleton. `edit(h)` receives the
stage and prim handles before the file is saved, so a test can break exactly
one thing. A painterly rig with a stroke layer sits on top.

`check_matches_usd_core()` bakes with `painterly bake --bake-proxy` and
compares every frame, in world space, with usd-core's BakeSkinning of the same
file (into the session layer; the file is not touched).
"""

from __future__ import annotations

import dataclasses
import math
import pathlib

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

import authoring as Au

CHAIN = ["a", "a/b", "a/b/c"]
SEG = 1.5  # joint spacing along +Y


@dataclasses.dataclass
class Handles:
    """What `edit` gets: the stage and the prims it may break."""
    stage: Usd.Stage
    root: UsdSkel.Root
    skel: UsdSkel.Skeleton
    anim: UsdSkel.Animation | None
    mesh: UsdGeom.Mesh
    binding: UsdSkel.BindingAPI
    shapes: dict
    key_times: list
    points: np.ndarray


def quat(axis, deg):
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    h = math.radians(deg) / 2
    return Gf.Quatf(math.cos(h), Gf.Vec3f(*(axis * math.sin(h))))


def bend_pose(j, name, u, rest_translation):
    """Default animation: every joint bends (and the root moves) with u in [0, 1]."""
    axes = [(1, 0, 0.3), (0, 0.2, 1), (0.5, 1, 0), (1, 1, 1)]
    angle = [35, -50, 65, 20][j % 4] * (u if j else math.sin(2 * u + 0.3))
    tr = Gf.Vec3f(*rest_translation)
    if j == 0:
        tr = tr + Gf.Vec3f(0.3 * u, 0.1 * math.sin(3 * u), -0.2 * u)
    return tr, quat(axes[j % 4], angle), Gf.Vec3h(1, 1, 1)


def twist_pose(j, name, u, rest_translation):
    """Large twists about the bone axis: DQS and LBS differ a lot."""
    return Gf.Vec3f(*rest_translation), quat((0, 1, 0), 110 * u if j else 0), Gf.Vec3h(1, 1, 1)


def spread_pose(j, name, u, rest_translation):
    """Root joints turning 0°, +130° and -130° about Y: the last two end on
    opposite quaternion hemispheres, so the DQS pivot joint matters."""
    # 130° rather than 120°: no sampled time lands where the two are exactly
    # 90° apart in quaternion space (DQS is discontinuous there).
    return Gf.Vec3f(*rest_translation), quat((0, 1, 0), [0, 130, -130][j % 3] * u), Gf.Vec3h(1, 1, 1)


def scale_pose(j, name, u, rest_translation):
    """bend_pose with a growing non-uniform scale on every other joint."""
    tr, q, _ = bend_pose(j, name, u, rest_translation)
    return tr, q, Gf.Vec3h(1 + 0.4 * u, 1, 1 - 0.2 * u) if j % 2 else Gf.Vec3h(1, 1, 1)


def mirror_pose(j, name, u, rest_translation):
    """The second joint mirrored in y (its bone axis: a negative determinant)
    and the joints below the root twisted 30°..140° about y. UsdSkel's DQS
    splits the mirror off the rotation; the rotation left (a twist plus a half
    turn about y) stays clear of the quaternion half-turn apart from the
    root's, where DQS blending is discontinuous."""
    scale = Gf.Vec3h(1, -1, 1) if j == 1 else Gf.Vec3h(1, 1, 1)
    return Gf.Vec3f(*rest_translation), quat((0, 1, 0), 30 + 110 * u if j else 0), scale


def joint_parent(names, i):
    name = names[i]
    if "/" not in name:
        return None
    parent = name.rsplit("/", 1)[0]
    return names.index(parent) if parent in names else None


def shape_offsets(pts, k, kind):
    """Deterministic, distinct offsets per shape k (kind "a": radial, "b": along x)."""
    y = pts[:, 1:2]
    radial = pts.copy()
    radial[:, 1] = 0
    if kind == "a":
        return radial * 0.3 * np.sin(y * (0.7 + 0.2 * k)) + np.array([0, 0.05 * k, 0])
    off = np.zeros_like(pts)
    off[:, (k + 1) % 3] = 0.4 * np.cos(y[:, 0] * (1.1 + 0.3 * k))
    return off


def skel_rig(out_path, *, joints=CHAIN, joint_y=None, bind=True, rest=True, anim=True,
             anim_joints=None, pose=bend_pose, frames=(1, 6), key_times=(1, 3, 6), tcps=24.0,
             influences=2, interpolation="vertex", unnormalized=False, geom_bind=None,
             method=None, shapes=(), normals=None, root_xform=None, skel_xform=None,
             parent_xform=None, mesh_xform=None, reverse_influences=False, rest_bend=0.0, edit=None,
             n_strokes=4, seed=5):
    """Writes the rig and returns an `authoring.Rig`.

    joints: Skeleton `joints` (None: not authored). joint_y: each joint's
    bind height (default index × SEG). influences: per point (0 or
    interpolation=None: no joint influences at all), largest weight first
    unless reverse_influences. shapes: list of dicts
    {name, offsets: "dense"|"sparse"|None, normal_offsets: bool,
    inbetweens: [(weight, with_offsets)], weight: f(u)} in mesh order.
    normals: None, "vertex" or "faceVarying" authored normals. rest_bend:
    degrees about Z added to every child joint's restTransforms, so the rest
    pose differs from the bind pose.
    """
    out_path = pathlib.Path(out_path)
    stage = Usd.Stage.CreateNew(str(out_path))
    a, b = frames
    Au.set_stage_metadata(stage, a, b, tcps=tcps)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    root = UsdSkel.Root.Define(stage, "/World/Character")
    if root_xform:
        root_xform(root)

    names = list(joints or [])
    nj = len(names)
    joint_y = list(joint_y) if joint_y is not None else [SEG * i for i in range(nj)]
    length = max(SEG * max(nj, 1), 2.0)
    pts, counts, idx = Au.tube_mesh(rings=7, seg=6, length=length)

    skel = UsdSkel.Skeleton.Define(stage, "/World/Character/Skel")
    if skel_xform:
        skel_xform(skel)
    bind_m = [Gf.Matrix4d().SetTranslate(Gf.Vec3d(0, y, 0)) for y in joint_y]
    rest_m = []
    for i in range(nj):
        p = joint_parent(names, i)
        local = bind_m[i] if p is None else bind_m[i] * bind_m[p].GetInverse()
        if p is not None and rest_bend:
            local = Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(0, 0, 1), rest_bend)) * local
        rest_m.append(local)
    if joints is not None:
        skel.CreateJointsAttr(names)
    if bind and nj:
        skel.CreateBindTransformsAttr(Vt.Matrix4dArray(bind_m))
    if rest and nj:
        skel.CreateRestTransformsAttr(Vt.Matrix4dArray(rest_m))

    anim_prim = None
    key_times = [float(t) for t in key_times]
    if anim:
        anim_prim = UsdSkel.Animation.Define(stage, "/World/Character/Skel/Anim")
        UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim_prim.GetPath()])
        aj = names if anim_joints is None else list(anim_joints)
        if aj:
            anim_prim.CreateJointsAttr(aj)
            tr_attr = anim_prim.CreateTranslationsAttr()
            rot_attr = anim_prim.CreateRotationsAttr()
            sc_attr = anim_prim.CreateScalesAttr()
            for t in key_times:
                u = (t - a) / max(b - a, 1)
                per = []
                for n in aj:
                    j = names.index(n) if n in names else len(per)
                    rt = rest_m[j].ExtractTranslation() if j < nj else Gf.Vec3d(0, SEG, 0)
                    per.append(pose(j, n, u, rt))
                tr_attr.Set(Vt.Vec3fArray([p[0] for p in per]), t)
                rot_attr.Set(Vt.QuatfArray([p[1] for p in per]), t)
                sc_attr.Set(Vt.Vec3hArray([p[2] for p in per]), t)

    mesh_parent = "/World/Character"
    if parent_xform:
        geo = UsdGeom.Xform.Define(stage, "/World/Character/Geo")
        parent_xform(geo)
        mesh_parent = "/World/Character/Geo"
    mesh = UsdGeom.Mesh.Define(stage, mesh_parent + "/Body")
    if mesh_xform:
        mesh_xform(mesh)
    mesh_pts = pts
    if geom_bind is not None:
        # authored so that points * geomBind is the skel-space bind pose
        mesh_pts = Au.apply_row(pts, Au.gf_to_np(geom_bind.GetInverse()))
    mesh.CreatePointsAttr(Au.v3f(mesh_pts))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray(counts))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(idx))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(Au.v3f(mesh_pts)))
    if normals == "vertex":
        n = pts.copy()
        n[:, 1] = 0.2
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        mesh.CreateNormalsAttr(Au.v3f(n))
        mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    elif normals == "faceVarying":
        n = pts[np.asarray(idx)].copy()
        n[:, 1] = 0.1
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        mesh.CreateNormalsAttr(Au.v3f(n))
        mesh.SetNormalsInterpolation(UsdGeom.Tokens.faceVarying)

    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    if geom_bind is not None:
        binding.CreateGeomBindTransformAttr(geom_bind)
    if method:
        binding.CreateSkinningMethodAttr(method)
    if influences and interpolation and nj:
        k = min(influences, nj)
        ji, jw = Au._joint_weights(pts, np.asarray(joint_y), k) if nj > 1 else (
            np.zeros((len(pts), 1), int), np.ones((len(pts), 1)))
        if unnormalized:
            jw = jw * np.linspace(0.6, 1.3, len(jw))[:, None]
        if reverse_influences:
            ji, jw = ji[:, ::-1], jw[:, ::-1]
        if interpolation == "constant":
            # the most evenly blended point's influences, for the whole mesh
            row = int(np.argmin(jw.max(axis=1)))
            ci, cw = [int(x) for x in ji[row]], [float(x) for x in jw[row]]
            binding.CreateJointIndicesPrimvar(True, len(ci)).Set(Vt.IntArray(ci))
            binding.CreateJointWeightsPrimvar(True, len(cw)).Set(Vt.FloatArray(cw))
        else:
            binding.CreateJointIndicesPrimvar(False, ji.shape[1]).Set(Vt.IntArray([int(x) for x in ji.reshape(-1)]))
            binding.CreateJointWeightsPrimvar(False, jw.shape[1]).Set(
                Vt.FloatArray([float(x) for x in jw.reshape(-1)]))

    handles_shapes = {}
    if shapes:
        _add_shapes(stage, mesh, binding, anim_prim, shapes, pts, key_times, a, b, handles_shapes)

    h = Handles(stage, root, skel, anim_prim, mesh, binding, handles_shapes, key_times, pts)
    if edit:
        edit(h)

    rest_pts = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
    rng = np.random.default_rng(seed)
    Au.add_painterly_rig(stage, "/World/Paint", mesh.GetPath())
    sc, sp = Au.make_strokes(rest_pts, counts, idx, rng, n_strokes, offsets=(0.0, 0.02))
    Au.add_stroke_layer(stage, "/World/Paint/Strokes", sc, sp)
    stage.GetRootLayer().Save()
    return Au.Rig(out_path, str(mesh.GetPath()), "/World/Paint", ["/World/Paint/Strokes"],
                  Au.frame_list(a, b), rest_pts)


def _add_shapes(stage, mesh, binding, anim, shapes, pts, key_times, a, b, out):
    n = len(pts)
    names, targets = [], []
    for k, s in enumerate(shapes):
        name = s["name"]
        bs = UsdSkel.BlendShape.Define(stage, mesh.GetPath().AppendChild(name))
        sel = None
        if s.get("offsets") == "sparse" or s.get("sparse"):
            sel = [i for i in range(n) if pts[i, 1] > pts[:, 1].max() * 0.4]
            bs.CreatePointIndicesAttr(Vt.IntArray(sel))
        rows = pts if sel is None else pts[sel]
        if s.get("offsets", "dense"):
            bs.CreateOffsetsAttr(Au.v3f(shape_offsets(rows, k, "a")))
        if s.get("normal_offsets"):
            bs.CreateNormalOffsetsAttr(Au.v3f(0.1 * shape_offsets(rows, k, "b")))
        for m, (w, with_offsets) in enumerate(s.get("inbetweens", [])):
            ib = bs.CreateInbetween(f"ib{m}")
            ib.SetWeight(float(w))
            if with_offsets:
                ib.SetOffsets(Au.v3f(shape_offsets(rows, k + 3 + m, "b")))
        names.append(name)
        targets.append(bs.GetPath())
        out[name] = bs
    binding.CreateBlendShapesAttr(names)
    binding.CreateBlendShapeTargetsRel().SetTargets(targets)
    if anim is None:
        return
    # The animation lists its shapes in another order than the mesh.
    anim_names = list(reversed(names))
    anim.CreateBlendShapesAttr(anim_names)
    wattr = anim.CreateBlendShapeWeightsAttr()
    by_name = {s["name"]: s for s in shapes}
    for t in key_times:
        u = (t - a) / max(b - a, 1)
        wattr.Set(Vt.FloatArray([float(by_name[nm].get("weight", lambda u: u)(u)) for nm in anim_names]), t)


# ---------------------------------------------------------------------------
# comparison with usd-core


def bake_proxy(painterly, rig, tmp_path, frames_arg=None, check=True):
    out = pathlib.Path(tmp_path) / "proxy_bake.usdc"
    args = ["bake", rig.path, "-o", out, "--bake-proxy", "--quiet"]
    if frames_arg:
        args += ["--frames", frames_arg]
    proc = painterly(*args, check=check)
    return out, proc


def check_matches_usd_core(painterly, rig, tmp_path, frames_arg=None, frames=None, tol=1e-5, moves=0.01):
    """Bake with painterly and compare with usd-core at every frame (world
    space, max error over the bbox diagonal). Unless `moves` is None,
    usd-core's result must also differ from the unskinned mesh by that much
    somewhere (so the comparison tests the deformation). Returns the worst
    error."""
    frames = frames or rig.frames
    before = Au.file_hash(rig.path)
    out, _ = bake_proxy(painterly, rig, tmp_path, frames_arg)
    assert Au.file_hash(rig.path) == before, "input modified"
    ref = usd_core_reference(rig, frames)
    comp = Au.compose(rig.path, out)
    diag = max(Au.bbox_diag(ref[t]) for t in frames)
    worst, worst_t = 0.0, None
    for t in frames:
        ours = Au.world_points(comp, rig.mesh, t)
        assert ours.shape == ref[t].shape, f"t={t}: {ours.shape} points, usd-core has {ref[t].shape}"
        err = float(np.abs(ours - ref[t]).max()) / diag
        if err > worst:
            worst, worst_t = err, t
    assert worst <= tol, f"{rig.mesh}: max error {worst:.3g} x bbox diagonal at t={worst_t} (tolerance {tol:g})"
    if moves is not None:
        src = Usd.Stage.Open(str(rig.path))
        moved = max(float(np.abs(ref[t] - Au.world_points(src, rig.mesh, t)).max()) for t in frames) / diag
        assert moved > moves, f"usd-core barely deforms {rig.mesh} ({moved:.3g} x diagonal): the rig tests nothing"
    return worst


def usd_core_reference(rig, frames):
    """usd-core's world points of the mesh at `frames`: authoring.usdcore_world_points,
    except that a bake usd-core writes as a default value only (a skeleton
    posed at rest, nothing animated) is accepted as its result."""
    stage = Usd.Stage.Open(str(rig.path))
    stage.SetEditTarget(stage.GetSessionLayer())
    UsdSkel.BakeSkinning(stage.Traverse(), Gf.Interval(min(frames), max(frames)))
    sl = stage.GetSessionLayer()
    spec = sl.GetAttributeAtPath(Sdf.Path(rig.mesh).AppendProperty("points"))
    if spec is not None and spec.HasDefaultValue() and not sl.ListTimeSamplesForPath(spec.path):
        return {t: Au.world_points(stage, rig.mesh, t) for t in frames}
    return Au.usdcore_world_points(rig.path, [rig.mesh], frames)[rig.mesh]


def world_normals(stage, path, t):
    """A mesh's `normals` at t as world-space unit directions (inverse
    transpose of its local-to-world), or None when it has none."""
    prim = stage.GetPrimAtPath(path)
    n = UsdGeom.PointBased(prim).GetNormalsAttr().Get(t)
    if n is None:
        return None
    m = Au.gf_to_np(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t))[:3, :3]
    w = np.asarray(n, dtype=np.float64) @ np.linalg.inv(m).T
    return w / np.linalg.norm(w, axis=1, keepdims=True)


def check_normals_match_usd_core(painterly, rig, tmp_path, frames_arg=None, frames=None, tol=1e-5):
    """The bake's normals (composed over the input) point where usd-core's
    BakeSkinning puts them, in world space, at every frame; returns the
    worst difference of unit vectors."""
    frames = frames or rig.frames
    out, _ = bake_proxy(painterly, rig, tmp_path, frames_arg)
    stage = Usd.Stage.Open(str(rig.path))
    k = Au._multiplier(frames)
    sl = stage.GetSessionLayer()
    if k != 1:
        sl.timeCodesPerSecond = stage.GetTimeCodesPerSecond() * k
        sl.framesPerSecond = stage.GetFramesPerSecond() * k
    sl.startTimeCode, sl.endTimeCode = min(frames) * k, max(frames) * k
    stage.SetEditTarget(sl)
    UsdSkel.BakeSkinning(stage.Traverse(), Gf.Interval(min(frames) * k, max(frames) * k))
    comp = Au.compose(rig.path, out)
    worst = 0.0
    for t in frames:
        ref, ours = world_normals(stage, rig.mesh, k * t), world_normals(comp, rig.mesh, t)
        assert ref is not None and ours is not None and ours.shape == ref.shape
        worst = max(worst, float(np.abs(ours - ref).max()))
    assert worst <= tol, f"{rig.mesh}: normals differ from usd-core's by {worst:.3g} (tolerance {tol:g})"
    return worst


def usd_core_skins_every_frame(rig):
    """Whether usd-core's BakeSkinning writes finite points for the mesh at
    every frame of the stage (False: it warned and left the mesh, or some
    frames, unskinned)."""
    stage = Usd.Stage.Open(str(rig.path))
    sl = stage.GetSessionLayer()
    stage.SetEditTarget(sl)
    UsdSkel.BakeSkinning(stage.Traverse(), Gf.Interval(min(rig.frames), max(rig.frames)))
    path = Sdf.Path(rig.mesh).AppendProperty("points")
    spec = sl.GetAttributeAtPath(path)
    if not spec:
        return False
    baked = set(sl.ListTimeSamplesForPath(path))
    if not baked and spec.HasDefaultValue():
        return bool(np.all(np.isfinite(np.array(spec.default, dtype=float))))
    return all(t in baked and np.all(np.isfinite(np.array(sl.QueryTimeSample(path, t), dtype=float)))
               for t in rig.frames)


def usd_core_world(rig, frames, edit_session=None):
    """usd-core's world points after an optional session-layer edit (a what-if)."""
    stage = Usd.Stage.Open(str(rig.path))
    sl = stage.GetSessionLayer()
    stage.SetEditTarget(sl)
    if edit_session:
        edit_session(stage)
    UsdSkel.BakeSkinning(stage.Traverse(), Gf.Interval(min(frames), max(frames)))
    return {t: Au.world_points(stage, rig.mesh, t) for t in frames}


def sdf_path(p):
    return Sdf.Path(p)
