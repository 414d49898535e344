"""Helpers for painterly's contract tests: author small rigs with usd-core,
add painterly rig / stroke-layer prims, compose a bake over its input, and
read usd-core's own evaluation of proxies (UsdSkel.BakeSkinning).

Everything here writes only into directories the caller passes (pytest's
tmp_path); real assets are copied before anything is written beside them.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import pathlib
import shutil

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

RIG_API = "PainterlyRigAPI"
LAYER_API = "PainterlyStrokeLayerAPI"


# ---------------------------------------------------------------------------
# small utilities


def file_hash(path) -> str:
    return hashlib.sha256(pathlib.Path(path).read_bytes()).hexdigest()


def frame_list(a, b, step=1.0):
    """Frames A, A+S, ... <= B (inclusive end when it lands on the step)."""
    out = []
    n = 0
    while True:
        t = a + n * step
        if t > b + 1e-9:
            break
        out.append(float(t))
        n += 1
    return out


def bbox_diag(points) -> float:
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))


def gf_to_np(m) -> np.ndarray:
    return np.array(m, dtype=np.float64).reshape(4, 4)


def apply_row(points, m) -> np.ndarray:
    """USD row-vector convention: p' = [p 1] @ M."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    m = np.asarray(m, dtype=np.float64)
    return p @ m[:3, :3] + m[3, :3]


def applied_schemas(prim) -> list:
    # Works with or without the painterly schema plugin registered.
    return list(prim.GetPrimTypeInfo().GetAppliedAPISchemas())


def set_stage_metadata(stage, start, end, tcps=24.0, fps=None, up="Y", mpu=1.0):
    stage.SetStartTimeCode(start)
    stage.SetEndTimeCode(end)
    stage.SetTimeCodesPerSecond(tcps)
    stage.SetFramesPerSecond(fps if fps is not None else tcps)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up == "Y" else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, mpu)


def v3f(points):
    return Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in np.asarray(points).reshape(-1, 3)])


# ---------------------------------------------------------------------------
# geometry


def tube_mesh(rings=9, seg=8, radius=0.5, length=4.0, tri_band=True, caps=True):
    """A closed, convex (in rest) tube along +Y.

    Body: quads, except the first band which is split into triangles (so the
    mesh mixes face sizes); caps: one `seg`-gon at each end (fan-triangulated
    by painterly). Winding gives outward normals (right-handed).
    Returns (points (N,3) float64, faceVertexCounts, faceVertexIndices).
    """
    pts = []
    for r in range(rings):
        y = length * r / (rings - 1)
        for s in range(seg):
            th = 2.0 * math.pi * s / seg
            pts.append((radius * math.cos(th), y, radius * math.sin(th)))
    counts, idx = [], []
    for r in range(rings - 1):
        for s in range(seg):
            a = r * seg + s
            b = r * seg + (s + 1) % seg
            c = (r + 1) * seg + (s + 1) % seg
            d = (r + 1) * seg + s
            # outward for this parametrisation: a, d, c, b
            if tri_band and r == 0:
                counts += [3, 3]
                idx += [a, d, c, a, c, b]
            else:
                counts.append(4)
                idx += [a, d, c, b]
    if caps:
        # bottom cap (y = 0) faces -Y, top cap faces +Y; start the fan at a
        # vertex that is not index 0 of the ring so the fan order matters.
        bottom = [(s + 3) % seg for s in range(seg)]
        counts.append(seg)
        idx += bottom
        top = [(rings - 1) * seg + (seg - 1 - ((s + 2) % seg)) for s in range(seg)]
        counts.append(seg)
        idx += top
    return np.array(pts, dtype=np.float64), counts, idx


def make_strokes(rest_points, counts, indices, rng, n_strokes, pts_per_stroke=4,
                 offsets=(0.0,), scale=None, avoid_ambiguous=True):
    """Strokes near a mesh, in the mesh's (proxy-local) space.

    Each stroke runs along a straight segment inside one fan triangle
    (barycentric weights >= 0.1) pushed out along that triangle's normal by
    an offset (a multiple of `scale`, default the bbox diagonal). Offsets
    cycle over `offsets` per stroke. Strokes whose points have an ambiguous
    closest point (two different closest features within a margin) are
    dropped and re-drawn when `avoid_ambiguous`.
    Returns (curveVertexCounts, points (M,3) float64).
    """
    from reference_skinning import binding_is_ambiguous, fan_triangles  # local import

    P = np.asarray(rest_points, dtype=np.float64)
    tris = fan_triangles(counts, indices)
    area = np.linalg.norm(np.cross(P[tris[:, 1]] - P[tris[:, 0]], P[tris[:, 2]] - P[tris[:, 0]]), axis=1)
    good = np.nonzero(area > 1e-8 * max(area.max(), 1e-30))[0]
    diag = bbox_diag(P) if scale is None else scale
    out_counts, out_pts = [], []
    attempts = 0
    while len(out_counts) < n_strokes:
        attempts += 1
        if attempts > 50 * n_strokes + 100:
            raise RuntimeError("could not place unambiguous strokes")
        ti = good[rng.integers(len(good))]
        a, b, c = P[tris[ti]]
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n)
        off = offsets[len(out_counts) % len(offsets)] * diag

        def rb():
            w = rng.uniform(0.1, 1.0, 3)
            w = w / w.sum()
            w = np.maximum(w, 0.1)
            return w / w.sum()

        w0, w1 = rb(), rb()
        stroke = []
        for k in range(pts_per_stroke):
            s = k / max(pts_per_stroke - 1, 1)
            w = (1 - s) * w0 + s * w1
            stroke.append(w[0] * a + w[1] * b + w[2] * c + off * n)
        stroke = np.array(stroke)
        if avoid_ambiguous and binding_is_ambiguous(P, tris, stroke, margin=1e-4 * bbox_diag(P)):
            continue
        out_counts.append(pts_per_stroke)
        out_pts.append(stroke)
    return out_counts, np.concatenate(out_pts, axis=0)


# ---------------------------------------------------------------------------
# painterly prims


def add_painterly_rig(stage, rig_path, proxy_path, rest_time=None, xform=None):
    """An Xform with PainterlyRigAPI and `rel painterly:proxy`."""
    rig = UsdGeom.Xform.Define(stage, rig_path)
    prim = rig.GetPrim()
    prim.AddAppliedSchema(RIG_API)
    if proxy_path is not None:
        prim.CreateRelationship("painterly:proxy", custom=False).SetTargets([Sdf.Path(proxy_path)])
    if rest_time is not None:
        prim.CreateAttribute("painterly:restTime", Sdf.ValueTypeNames.Double, custom=False).Set(float(rest_time))
    if xform is not None:
        xform(rig)
    return prim


def add_stroke_layer(stage, path, counts, rest_points, *, points=None, write_rest=True,
                     opacity=None, display_opacity=None, display_opacity_interp="uniform",
                     bind_vertices=None, bind_weights=None, xform=None, widths=True):
    """A BasisCurves stroke layer. `rest_points` are proxy-local rest positions.

    write_rest=True authors painterly:restPoints = rest_points and `points`
    (default) = `points` if given, else rest_points. write_rest=False authors
    only `points` = rest_points (the rest pose then comes from points).
    """
    curves = UsdGeom.BasisCurves.Define(stage, path)
    prim = curves.GetPrim()
    prim.AddAppliedSchema(LAYER_API)
    curves.CreateTypeAttr(UsdGeom.Tokens.linear)
    curves.CreateCurveVertexCountsAttr(Vt.IntArray([int(c) for c in counts]))
    rest_points = np.asarray(rest_points, dtype=np.float64).reshape(-1, 3)
    if write_rest:
        prim.CreateAttribute("painterly:restPoints", Sdf.ValueTypeNames.Point3fArray, custom=False).Set(v3f(rest_points))
        curves.CreatePointsAttr(v3f(rest_points if points is None else points))
    else:
        curves.CreatePointsAttr(v3f(rest_points))
    if widths:
        curves.CreateWidthsAttr(Vt.FloatArray([0.01] * len(rest_points)))
        curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
    if opacity is not None:
        prim.CreateAttribute("painterly:opacity", Sdf.ValueTypeNames.Float, custom=False).Set(float(opacity))
    if display_opacity is not None:
        pv = UsdGeom.PrimvarsAPI(prim).CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray,
                                                     display_opacity_interp)
        pv.Set(Vt.FloatArray([float(x) for x in display_opacity]))
    if bind_vertices is not None:
        prim.CreateAttribute("painterly:bindVertices", Sdf.ValueTypeNames.Int3Array, custom=False).Set(
            Vt.Vec3iArray([Gf.Vec3i(*map(int, v)) for v in bind_vertices]))
    if bind_weights is not None:
        prim.CreateAttribute("painterly:bindWeights", Sdf.ValueTypeNames.Float3Array, custom=False).Set(
            Vt.Vec3fArray([Gf.Vec3f(*map(float, v)) for v in bind_weights]))
    ext = UsdGeom.Boundable.ComputeExtentFromPlugins(curves, Usd.TimeCode.Default())
    if ext:
        curves.CreateExtentAttr(ext)
    if xform is not None:
        xform(curves)
    return prim


def xf_static(translate=(0, 0, 0), rotate=(0, 0, 0), scale=(1, 1, 1)):
    def f(xformable):
        xformable.AddTranslateOp().Set(Gf.Vec3d(*translate))
        xformable.AddRotateXYZOp().Set(Gf.Vec3f(*rotate))
        xformable.AddScaleOp().Set(Gf.Vec3f(*scale))
    return f


def xf_animated(keys):
    """keys: {time: (translate, rotateXYZ degrees, scale)}"""
    def f(xformable):
        t_op = xformable.AddTranslateOp()
        r_op = xformable.AddRotateXYZOp()
        s_op = xformable.AddScaleOp()
        for t, (tr, rot, sc) in keys.items():
            t_op.Set(Gf.Vec3d(*tr), t)
            r_op.Set(Gf.Vec3f(*rot), t)
            s_op.Set(Gf.Vec3f(*sc), t)
    return f


# ---------------------------------------------------------------------------
# synthetic rigs


@dataclasses.dataclass
class Rig:
    path: pathlib.Path           # the input .usda/.usdc
    mesh: str                    # proxy mesh path
    rig: str                     # painterly rig prim path
    layers: list                 # stroke layer paths
    frames: list                 # default frames (stage start..end)
    rest: np.ndarray = None      # proxy rest points (mesh-local)


def _quat_axis_angle(axis, deg):
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    h = math.radians(deg) / 2
    return Gf.Quatf(math.cos(h), Gf.Vec3f(*(axis * math.sin(h))))


def _joint_weights(points, joint_y, k):
    """Per-point top-k influences from distance to each joint's segment centre."""
    if k > len(joint_y):
        raise ValueError("more influences than joints")
    seg = np.diff(np.append(joint_y, joint_y[-1] + (joint_y[-1] - joint_y[-2] if len(joint_y) > 1 else 1)))
    centres = np.asarray(joint_y) + seg / 2
    d = np.abs(points[:, 1:2] - centres[None, :])
    w = np.exp(-(d / (seg.mean() * 0.6)) ** 2) + 1e-3
    order = np.argsort(-w, axis=1)[:, :k]
    idx = order
    ww = np.take_along_axis(w, order, axis=1)
    ww = ww / ww.sum(axis=1, keepdims=True)
    return idx.astype(int), ww


def build_skel_rig(out_path, *, influences=4, interpolation="vertex", geom_bind=False,
                   blend_shapes=None, skinning_method=None, world_xform=None, root_xform=None,
                   mesh_parent_xform=None, anim_on="skeleton", mesh_joints_subset=False,
                   sparse_anim=False, inherited_skeleton=False, inherited_influences=False,
                   indexed_influences=False, twist=False, frames=(1, 12), key_times=None,
                   tcps=24.0, n_strokes=6, offsets=(0.0, 0.02), rig_xform=None,
                   layer_xform=None, seed=1, extra_layers=0, write_rest=True,
                   bind_cache=None, opacity=None, display_opacity=None, up="Y", mpu=1.0,
                   unnormalized_weights=False, scale_joint=False, skel_xform=None):
    """A UsdSkel tube with a 4-joint chain, an animation, a painterly rig and
    stroke layer(s). Returns a Rig.

    blend_shapes: None or a set of {"dense", "indexed", "inbetween",
    "extrapolate", "neg_inbetween"}.
    """
    out_path = pathlib.Path(out_path)
    stage = Usd.Stage.CreateNew(str(out_path))
    a, b = frames
    set_stage_metadata(stage, a, b, tcps=tcps, up=up, mpu=mpu)
    key_times = key_times or sorted({float(a), float((a + b) // 2), float(b), float(a + 2)})

    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    if world_xform:
        world_xform(world)
    root = UsdSkel.Root.Define(stage, "/World/Character")
    if root_xform:
        root_xform(root)

    L = 4.0
    pts, counts, idx = tube_mesh(length=L)
    joint_names = ["root", "root/mid", "root/mid/tip", "root/mid/tip/end"]
    seg_len = L / 4
    joint_y = np.array([0.0, seg_len, 2 * seg_len, 3 * seg_len])

    skel = UsdSkel.Skeleton.Define(stage, "/World/Character/Skel")
    if skel_xform:
        skel_xform(skel)  # skel space -> world goes through the Skeleton prim's own transform
    skel.CreateJointsAttr(joint_names)
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray(
        [Gf.Matrix4d().SetTranslate(Gf.Vec3d(0, y, 0)) for y in joint_y]))
    rest_local = [Gf.Matrix4d().SetTranslate(Gf.Vec3d(0, 0, 0))] + [
        Gf.Matrix4d().SetTranslate(Gf.Vec3d(0, seg_len, 0)) for _ in joint_y[1:]]
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray(rest_local))

    anim = UsdSkel.Animation.Define(stage, "/World/Character/Anim")
    anim_joints = list(joint_names)
    if sparse_anim:
        # reordered subset; "root/mid" falls back to its rest transform
        anim_joints = ["root/mid/tip/end", "root/mid/tip", "root"]
    anim.CreateJointsAttr(anim_joints)
    tr_attr = anim.CreateTranslationsAttr()
    rot_attr = anim.CreateRotationsAttr()
    sc_attr = anim.CreateScalesAttr()
    one = Gf.Vec3h(1, 1, 1)
    down = Gf.Vec3f(0, seg_len, 0)
    for i, t in enumerate(key_times):
        u = (t - a) / max(b - a, 1)
        per = {}
        per["root"] = (Gf.Vec3f(0.3 * u, 0.1 * math.sin(3 * u), -0.2 * u),
                       _quat_axis_angle((0, 0, 1), 25 * math.sin(2.0 * u + 0.3)), one)
        if twist:
            for j in joint_names[1:]:
                per[j] = (down, _quat_axis_angle((0, 1, 0), 110 * u), one)
        else:
            per["root/mid"] = (down, _quat_axis_angle((1, 0, 0.3), 50 * u),
                               Gf.Vec3h(1.2, 1, 1) if scale_joint else one)
            per["root/mid/tip"] = (down, _quat_axis_angle((0, 0.2, 1), -60 * u * (1 - 0.5 * u)), one)
            per["root/mid/tip/end"] = (down, _quat_axis_angle((0.5, 1, 0), 70 * u), one)
        tr_attr.Set(Vt.Vec3fArray([per[j][0] for j in anim_joints]), t)
        rot_attr.Set(Vt.QuatfArray([per[j][1] for j in anim_joints]), t)
        sc_attr.Set(Vt.Vec3hArray([per[j][2] for j in anim_joints]), t)

    if anim_on == "skeleton":
        UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    elif anim_on == "skelroot":
        UsdSkel.BindingAPI.Apply(root.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    else:
        raise ValueError(anim_on)

    mesh_parent = "/World/Character"
    if mesh_parent_xform:
        geo = UsdGeom.Xform.Define(stage, "/World/Character/Geo")
        mesh_parent_xform(geo)
        mesh_parent = "/World/Character/Geo"
    mesh_path = mesh_parent + "/Body"
    mesh = UsdGeom.Mesh.Define(stage, mesh_path)

    G = None
    mesh_pts = pts
    if geom_bind:
        G = (Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(1, 1, 0), 30))
             * Gf.Matrix4d().SetTranslate(Gf.Vec3d(0.4, -0.3, 0.25)))
        # mesh points authored so that points * G is the skel-space bind pose
        mesh_pts = apply_row(pts, gf_to_np(G.GetInverse()))
    mesh.CreatePointsAttr(v3f(mesh_pts))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray(counts))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(idx))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(v3f(mesh_pts)))

    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    if inherited_skeleton:
        UsdSkel.BindingAPI.Apply(root.GetPrim()).CreateSkeletonRel().SetTargets([skel.GetPath()])
    else:
        binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    if G is not None:
        binding.CreateGeomBindTransformAttr(G)
    if skinning_method:
        binding.CreateSkinningMethodAttr(skinning_method)

    if mesh_joints_subset:
        # the mesh only sees two joints, in its own order
        binding.CreateJointsAttr(["root/mid/tip", "root/mid"])
        sub_y = np.array([joint_y[1], joint_y[2]])
        ji, jw = _joint_weights(pts, sub_y, min(influences, 2))
        ji = 1 - ji  # [mid, tip] order from _joint_weights onto the mesh's [tip, mid]
    else:
        ji, jw = _joint_weights(pts, joint_y, influences)
    if unnormalized_weights:
        jw = jw * np.linspace(0.7, 1.2, len(jw))[:, None]

    if interpolation == "constant":
        # rigid: one set of influences for the whole mesh
        ci = Vt.IntArray([0, 1][:influences] if influences <= 2 else [0, 1, 2][:influences])
        cw = Vt.FloatArray(([0.7, 0.3] if influences == 2 else [1.0] if influences == 1 else [0.5, 0.3, 0.2][:influences]))
        holder = binding
        if inherited_influences:
            holder = UsdSkel.BindingAPI.Apply(root.GetPrim())
        holder.CreateJointIndicesPrimvar(True, len(ci)).Set(ci)
        holder.CreateJointWeightsPrimvar(True, len(cw)).Set(cw)
    else:
        k = ji.shape[1]
        ipv = binding.CreateJointIndicesPrimvar(False, k)
        wpv = binding.CreateJointWeightsPrimvar(False, k)
        if indexed_influences:
            # indexed primvar: unique k-tuples, one index per point
            uniq, inv = np.unique(ji, axis=0, return_inverse=True)
            ipv.Set(Vt.IntArray([int(x) for x in uniq.reshape(-1)]))
            ipv.SetIndices(Vt.IntArray([int(x) for x in np.asarray(inv).reshape(-1)]))
        else:
            ipv.Set(Vt.IntArray([int(x) for x in ji.reshape(-1)]))
        wpv.Set(Vt.FloatArray([float(x) for x in jw.reshape(-1)]))

    if blend_shapes:
        _add_blend_shapes(stage, mesh, binding, anim, blend_shapes, pts, key_times, a, b)

    rest = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
    rng = np.random.default_rng(seed)
    rig_prim = add_painterly_rig(stage, "/World/Paint", mesh_path, xform=rig_xform)
    layers = []
    for li in range(1 + extra_layers):
        sc, sp = make_strokes(rest, counts, idx, rng, n_strokes, offsets=offsets)
        lp = f"/World/Paint/Strokes{li if li else ''}"
        bv = bw = None
        if bind_cache is not None:
            bv, bw = bind_cache(rest, counts, idx, sp)
        add_stroke_layer(stage, lp, sc, sp, write_rest=write_rest, xform=layer_xform if li == 0 else None,
                         bind_vertices=bv, bind_weights=bw, opacity=opacity,
                         display_opacity=display_opacity(len(sc)) if callable(display_opacity) else display_opacity)
        layers.append(lp)
    stage.GetRootLayer().Save()
    return Rig(out_path, mesh_path, str(rig_prim.GetPath()), layers, frame_list(a, b), rest)


def _add_blend_shapes(stage, mesh, binding, anim, kinds, pts, key_times, a, b):
    n = len(pts)
    names, targets = [], []
    weights_per_time = {t: [] for t in key_times}
    center = pts.mean(axis=0)
    radial = pts - center
    radial[:, 1] = 0
    if "dense" in kinds:
        bs = UsdSkel.BlendShape.Define(stage, mesh.GetPath().AppendChild("bulge"))
        off = radial * 0.3 * np.sin(pts[:, 1:2] * 0.8)
        bs.CreateOffsetsAttr(v3f(off))
        names.append("bulge")
        targets.append(bs.GetPath())
        for t in key_times:
            u = (t - a) / max(b - a, 1)
            weights_per_time[t].append(0.9 * u)
    if "indexed" in kinds:
        bs = UsdSkel.BlendShape.Define(stage, mesh.GetPath().AppendChild("pinch"))
        sel = [i for i in range(n) if pts[i, 1] > 2.5]
        bs.CreatePointIndicesAttr(Vt.IntArray(sel))
        bs.CreateOffsetsAttr(v3f(-0.4 * radial[sel] + np.array([0, 0.2, 0])))
        names.append("pinch")
        targets.append(bs.GetPath())
        for t in key_times:
            u = (t - a) / max(b - a, 1)
            weights_per_time[t].append(1.0 - u)
    if "inbetween" in kinds or "neg_inbetween" in kinds:
        bs = UsdSkel.BlendShape.Define(stage, mesh.GetPath().AppendChild("wave"))
        full = np.zeros_like(pts)
        full[:, 0] = 0.5 * np.sin(pts[:, 1] * 1.3)
        bs.CreateOffsetsAttr(v3f(full))
        if "inbetween" in kinds:
            ib = bs.CreateInbetween("half")
            ib.SetWeight(0.5)
            mid = np.zeros_like(pts)
            mid[:, 2] = 0.3 * np.cos(pts[:, 1])
            ib.SetOffsets(v3f(mid))
        if "neg_inbetween" in kinds:
            ib = bs.CreateInbetween("neg")
            ib.SetWeight(-0.5)
            neg = np.zeros_like(pts)
            neg[:, 1] = 0.2 * np.cos(pts[:, 0] * 3)
            ib.SetOffsets(v3f(neg))
        names.append("wave")
        targets.append(bs.GetPath())
        for t in key_times:
            u = (t - a) / max(b - a, 1)
            if "neg_inbetween" in kinds:
                weights_per_time[t].append(-0.8 + 1.6 * u)
            else:
                weights_per_time[t].append(u)
    if "extrapolate" in kinds:
        bs = UsdSkel.BlendShape.Define(stage, mesh.GetPath().AppendChild("stretch"))
        off = np.zeros_like(pts)
        off[:, 1] = 0.1 * pts[:, 1]
        bs.CreateOffsetsAttr(v3f(off))
        ib = bs.CreateInbetween("halfway")
        ib.SetWeight(0.5)
        mid = np.zeros_like(pts)
        mid[:, 0] = 0.2 * np.sin(pts[:, 1])
        ib.SetOffsets(v3f(mid))
        names.append("stretch")
        targets.append(bs.GetPath())
        for t in key_times:
            u = (t - a) / max(b - a, 1)
            weights_per_time[t].append(-0.5 + 2.0 * u)  # from -0.5 to 1.5
    binding.CreateBlendShapesAttr(names)
    binding.CreateBlendShapeTargetsRel().SetTargets(targets)
    anim.CreateBlendShapesAttr(names)
    wattr = anim.CreateBlendShapeWeightsAttr()
    for t in key_times:
        wattr.Set(Vt.FloatArray(weights_per_time[t]), t)


def build_points_rig(out_path, *, mode="sampled", rest_time=None, default_points=True,
                     frames=(1, 10), proxy_xform=None, rig_xform=None, layer_xform=None,
                     n_strokes=6, offsets=(0.0, 0.02, 0.6), seed=3, write_rest=True, tcps=24.0):
    """A non-skinned tube proxy: mode "sampled" (time-sampled points at a few
    key times) or "static" (default points only)."""
    out_path = pathlib.Path(out_path)
    stage = Usd.Stage.CreateNew(str(out_path))
    a, b = frames
    set_stage_metadata(stage, a, b, tcps=tcps)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    holder = UsdGeom.Xform.Define(stage, "/World/ProxyXf")
    if proxy_xform:
        proxy_xform(holder)
    pts, counts, idx = tube_mesh()
    mesh = UsdGeom.Mesh.Define(stage, "/World/ProxyXf/Proxy")
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray(counts))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(idx))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    pa = mesh.CreatePointsAttr()
    if default_points:
        pa.Set(v3f(pts))
    rest = pts
    if mode == "sampled":
        keys = [float(a), float(a + (b - a) // 3), float(b)]
        for i, t in enumerate(keys):
            u = (t - a) / max(b - a, 1)
            d = deform(pts, u)
            pa.Set(v3f(d), t)
            if rest_time is not None and abs(t - rest_time) < 1e-12:
                rest = d
        if rest_time is not None and all(abs(t - rest_time) > 1e-12 for t in keys):
            rest = np.array(pa.Get(rest_time), dtype=np.float64)
    rest = np.array(v3f(rest), dtype=np.float64)  # float32 round trip
    rng = np.random.default_rng(seed)
    add_painterly_rig(stage, "/World/Paint", mesh.GetPath(), rest_time=rest_time, xform=rig_xform)
    sc, sp = make_strokes(rest, counts, idx, rng, n_strokes, offsets=offsets)
    add_stroke_layer(stage, "/World/Paint/Strokes", sc, sp, write_rest=write_rest, xform=layer_xform)
    stage.GetRootLayer().Save()
    return Rig(out_path, str(mesh.GetPath()), "/World/Paint", ["/World/Paint/Strokes"], frame_list(a, b), rest)


def deform(pts, u):
    """A smooth non-rigid deformation of the tube (bend + twist + bulge)."""
    p = np.array(pts, dtype=np.float64)
    y = p[:, 1]
    ang = 0.35 * u * y
    x, z = p[:, 0], p[:, 2]
    xr = x * np.cos(ang) - z * np.sin(ang)
    zr = x * np.sin(ang) + z * np.cos(ang)
    bulge = 1 + 0.25 * u * np.sin(y)
    bend = 0.15 * u * y ** 2
    return np.stack([xr * bulge + bend, y + 0.1 * u * np.sin(2 * x), zr * bulge], axis=1)


# ---------------------------------------------------------------------------
# real assets


REAL_MESHES = {
    "RiggedSimple": "/RiggedSimple/Geom/Z_UP/Armature/Bone_3/Cylinder_2",
    "RiggedFigure": "/RiggedFigure/Geom/Z_UP/Armature/torso_joint_1_2/Proxy_1",
    "CesiumMan": "/CesiumMan/Geom/Z_UP/Armature/Skeleton_torso_joint_1_3/Cesium_Man_2",
}


def wrap_real_asset(real_assets, name, tmp_path, *, n_strokes=8, offsets=(0.0, 0.002), seed=7,
                    layer_xform=None, rig_xform=None):
    """Copy the asset into tmp_path and write tmp_path/<name>_painted.usda, which
    sublayers it and adds /PainterlyRig (proxy = the asset's only mesh) with
    one stroke layer of strokes on / just above the surface."""
    src = pathlib.Path(real_assets) / name / f"{name}.usdz"
    dst = pathlib.Path(tmp_path) / f"{name}.usdz"
    shutil.copy(src, dst)
    asset = Usd.Stage.Open(str(dst))
    mesh_path = REAL_MESHES[name]
    mesh = UsdGeom.Mesh(asset.GetPrimAtPath(mesh_path))
    assert mesh, f"{name}: no mesh at {mesh_path}"
    rest = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
    counts = list(mesh.GetFaceVertexCountsAttr().Get())
    idx = list(mesh.GetFaceVertexIndicesAttr().Get())

    out = pathlib.Path(tmp_path) / f"{name}_painted.usda"
    stage = Usd.Stage.CreateNew(str(out))
    stage.GetRootLayer().subLayerPaths.append(f"./{name}.usdz")
    set_stage_metadata(stage, asset.GetStartTimeCode(), asset.GetEndTimeCode(),
                       tcps=asset.GetTimeCodesPerSecond(), fps=asset.GetFramesPerSecond(),
                       up=UsdGeom.GetStageUpAxis(asset), mpu=UsdGeom.GetStageMetersPerUnit(asset))
    if asset.GetDefaultPrim():
        stage.GetRootLayer().defaultPrim = asset.GetDefaultPrim().GetName()
    rng = np.random.default_rng(seed)
    add_painterly_rig(stage, "/PainterlyRig", mesh_path, xform=rig_xform)
    sc, sp = make_strokes(rest, counts, idx, rng, n_strokes, offsets=offsets)
    add_stroke_layer(stage, "/PainterlyRig/Strokes", sc, sp, xform=layer_xform)
    stage.GetRootLayer().Save()
    frames = frame_list(asset.GetStartTimeCode(), asset.GetEndTimeCode())
    return Rig(out, mesh_path, "/PainterlyRig", ["/PainterlyRig/Strokes"], frames, rest)


# ---------------------------------------------------------------------------
# reading bakes


def compose(input_path, bake_path):
    """A stage whose root layer sublayers [bake, input] (bake stronger), with
    the input's time metadata so no time scaling is introduced."""
    src = Sdf.Layer.FindOrOpen(str(input_path))
    root = Sdf.Layer.CreateAnonymous(".usda")
    for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond", "framesPerSecond",
                "upAxis", "metersPerUnit", "defaultPrim"):
        if src.pseudoRoot.HasInfo(key):
            root.pseudoRoot.SetInfo(key, src.pseudoRoot.GetInfo(key))
    root.subLayerPaths.append(str(bake_path))
    root.subLayerPaths.append(str(input_path))
    return Usd.Stage.Open(root)


def world_points(stage, path, t):
    prim = stage.GetPrimAtPath(path)
    pts = np.array(UsdGeom.PointBased(prim).GetPointsAttr().Get(t), dtype=np.float64)
    m = gf_to_np(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t))
    return apply_row(pts, m)


def local_points(stage, path, t):
    prim = stage.GetPrimAtPath(path)
    return np.array(UsdGeom.PointBased(prim).GetPointsAttr().Get(t), dtype=np.float64)


def _multiplier(frames):
    for k in range(1, 65):
        if all(abs(k * t - round(k * t)) < 1e-9 for t in frames):
            return k
    raise ValueError(f"frames too fine for the usd-core comparison: {frames}")


def usdcore_world_points(input_path, mesh_paths, frames):
    """usd-core's evaluation of each mesh at each frame, in world space:
    UsdSkel.BakeSkinning into the session layer (the input is not touched),
    then points x local-to-world. Fractional frames: the session layer's
    timeCodesPerSecond/framesPerSecond are raised k-fold (which rescales the
    root layer's time by k) so every requested frame is a whole baked frame.
    Returns {mesh_path: {t: (N,3)}}."""
    stage = Usd.Stage.Open(str(input_path))
    k = _multiplier(frames)
    sl = stage.GetSessionLayer()
    if k != 1:
        sl.timeCodesPerSecond = stage.GetTimeCodesPerSecond() * k
        sl.framesPerSecond = stage.GetFramesPerSecond() * k
    start = min(stage.GetStartTimeCode(), min(frames))
    end = max(stage.GetEndTimeCode(), max(frames))
    sl.startTimeCode = start * k
    sl.endTimeCode = end * k
    stage.SetEditTarget(sl)
    # Bake the whole range: given a sub-interval, BakeSkinning only bakes
    # between the authored animation samples that fall inside it.
    ok = UsdSkel.BakeSkinning(stage.Traverse(), Gf.Interval(k * start, k * end))
    assert ok, "usd-core BakeSkinning failed"
    out = {p: {} for p in mesh_paths}
    for p in mesh_paths:
        spec = sl.GetAttributeAtPath(Sdf.Path(p).AppendProperty("points"))
        if spec is not None:
            baked = set(sl.ListTimeSamplesForPath(spec.path))
            missing = [t for t in frames if float(k * t) not in baked]
            assert not missing, f"usd-core did not bake {p} at {missing} (k={k})"
        for t in frames:
            out[p][t] = world_points(stage, p, k * t)
    return out


def skinning_method_override(input_path, mesh_path, method, frames):
    """usd-core's world points of one mesh with skel:skinningMethod overridden
    (in the session layer) -- used to tell LBS and DQS results apart."""
    stage = Usd.Stage.Open(str(input_path))
    sl = stage.GetSessionLayer()
    stage.SetEditTarget(sl)
    UsdSkel.BindingAPI(stage.GetPrimAtPath(mesh_path)).CreateSkinningMethodAttr().Set(method)
    UsdSkel.BakeSkinning(stage.Traverse(), Gf.Interval(min(stage.GetStartTimeCode(), min(frames)),
                                                       max(stage.GetEndTimeCode(), max(frames))))
    return {t: world_points(stage, mesh_path, t) for t in frames}


def layer_prim_specs(layer):
    specs = []

    def visit(path):
        if path.IsPrimPath():
            specs.append(layer.GetPrimAtPath(path))
    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return specs


def sheet_mesh(n=6, size=3.0):
    """A flat n x n quad grid in the XZ plane (every rest one-ring planar),
    whose corner quad is a pentagon (v, p1, p2, p3, p0) with v the midpoint
    of the boundary side p0-p1: v's one-ring {p0, v, p1} is collinear (a
    degenerate rest one-ring, R = I), while v's fan triangles are not."""
    pts = [(size * i / n, 0.0, size * j / n) for j in range(n + 1) for i in range(n + 1)]
    counts, idx = [], []
    w = n + 1
    for j in range(n):
        for i in range(n):
            a, b, c, d = j * w + i, j * w + i + 1, (j + 1) * w + i + 1, (j + 1) * w + i
            if i == 0 and j == 0:
                v = len(pts)
                pts.append(((pts[a][0] + pts[b][0]) / 2, 0.0, (pts[a][2] + pts[b][2]) / 2))
                counts.append(5)
                idx += [v, b, c, d, a]
            else:
                counts.append(4)
                idx += [a, b, c, d]
    return np.array(pts, dtype=np.float64), counts, idx


def sheet_deform(pts, u):
    """Roll the sheet up around the X axis and twist it: non-rigid, smooth."""
    p = np.array(pts, dtype=np.float64)
    x, z = p[:, 0], p[:, 2]
    k = 0.6 * u + 1e-9  # curvature of the roll
    y = (1 - np.cos(k * z)) / k + 0.2 * u * x * z
    zz = np.sin(k * z) / k
    rolled = np.stack([x + 0.1 * u * z, y, zz], axis=1)
    # plus a growing rigid turn, so per-vertex rotations are far from I
    ay, az = math.radians(50 * u), math.radians(30 * u)
    ry = np.array([[math.cos(ay), 0, math.sin(ay)], [0, 1, 0], [-math.sin(ay), 0, math.cos(ay)]])
    rz = np.array([[math.cos(az), -math.sin(az), 0], [math.sin(az), math.cos(az), 0], [0, 0, 1]])
    return rolled @ (rz @ ry).T


def build_sheet_rig(out_path, frames=(1, 8), n_strokes=8, seed=11):
    out_path = pathlib.Path(out_path)
    stage = Usd.Stage.CreateNew(str(out_path))
    a, b = frames
    set_stage_metadata(stage, a, b)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    pts, counts, idx = sheet_mesh()
    mesh = UsdGeom.Mesh.Define(stage, "/World/Sheet")
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray(counts))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(idx))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    pa = mesh.CreatePointsAttr()
    pa.Set(v3f(pts))
    for t in (a, (a + b) / 2, b):
        pa.Set(v3f(sheet_deform(pts, (t - a) / (b - a))), t)
    rest = np.array(v3f(pts), dtype=np.float64)
    from reference_skinning import fan_triangles
    tris = fan_triangles(counts, idx)
    v = len(pts) - 1
    # strokes on / above the pentagon's fan triangles (they all use v) ...
    special = []
    for ti in np.nonzero((tris == v).any(axis=1))[0]:
        A, B, C = rest[tris[ti]]
        for off in (0.0, 0.05):
            special.append(np.array([w0 * A + w1 * B + w2 * C + (0, off, 0)
                                     for w0, w1, w2 in ((0.6, 0.2, 0.2), (0.3, 0.4, 0.3), (0.2, 0.2, 0.6))]))
    # ... and random strokes elsewhere, on, above and far above the sheet
    rng = np.random.default_rng(seed)
    sc, sp = make_strokes(rest, counts, idx, rng, n_strokes, offsets=(0.0, 0.02, 0.3))
    all_pts = np.concatenate(special + [sp])
    all_counts = [3] * len(special) + list(sc)
    add_painterly_rig(stage, "/World/Paint", mesh.GetPath())
    add_stroke_layer(stage, "/World/Paint/Strokes", all_counts, all_pts)
    stage.GetRootLayer().Save()
    return Rig(out_path, str(mesh.GetPath()), "/World/Paint", ["/World/Paint/Strokes"], frame_list(a, b), rest)
