"""An independent numpy implementation of SPEC sections 4-5 (configuration
axes, pose keys, temporal keys), composed with reference_skinning.py (SPEC
section 3) into the expected result of `painterly bake`.

Axes are evaluated with usd-core directly (Usd.Attribute.Get(t) with USD's own
interpolation of time samples, the SkelAnimation's attributes, Xformable
local-to-world transforms); pose keys are blended with reference_interp.py
(smooth Voronoi, RBF, Shepard); temporal keys follow the rules of SPEC
section 5, written out here segment by segment.

The choices the SPEC leaves open, as painterly documents them:
- SPEC 1.1 section 4: axis values and key coordinates are in axis units
  (before scale); interpolation runs on both multiplied by the axes' scales;
- attribute: arrays pick `element` (0 when absent), vectors `component`
  (0 when absent), quaternions in (x, y, z, w) order, arrays of vectors by
  element then component; the relationship `source` targets the attribute;
- blendShape: the weight of `name` in the SkelAnimation's
  blendShapeWeights at t (0 when the animation does not list it);
- jointRotation: q = the joint's local rotation in the Skeleton's
  skel:animationSource at t (rest rotation when the joint is not animated),
  q_rest = rotation of restTransforms[j], q_rel = q_rest^-1 (x) q flipped to
  w >= 0, value = component of axis x angle (radians) of q_rel;
- position: the source's world-space origin mapped into the proxy's local
  space at t;
- viewDirection: unit vector, in proxy-local space, from the centre of the
  axis-aligned bounding box of the posed proxy (proxy-local, at t) to the
  camera's origin (proxy-local);
- layer axes: `painterly:axes` when authored, else every PainterlyAxis under
  the rig in namespace (depth-first) order;
- the layer's binding is computed from its rest points; keyed rest points
  are skinned with that binding;
- baked displayOpacity = authored displayOpacity (1 when absent) x
  painterly:opacity at t x keyed opacity.

Everything is float64 on top of the float32 values the stage holds.
"""

from __future__ import annotations

import math

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel

import reference_interp as RI
import reference_skinning as RS

AXIS_TYPE = "PainterlyAxis"
POSE_KEY_TYPE = "PainterlyPoseKey"
TIME_KEY_TYPE = "PainterlyTimeKey"

_QUAT_TYPES = (Gf.Quatf, Gf.Quatd, Gf.Quath)


# ---------------------------------------------------------------------------
# small utilities


def _m(gf):
    return np.array(gf, dtype=np.float64).reshape(4, 4)


def authored(prim, name, default=None):
    """The default-time value of an attribute when authored (no schema
    fallbacks are relied upon: painterly must work without the plugin)."""
    a = prim.GetAttribute(name)
    if a and a.HasAuthoredValue():
        v = a.Get()
        if v is not None:
            return v
    return default


def to_local(p_world, proxy_l2w):
    inv = np.linalg.inv(np.asarray(proxy_l2w, dtype=np.float64))
    p = np.asarray(p_world, dtype=np.float64)
    return p @ inv[:3, :3] + inv[3, :3]


def world_origin(prim, t):
    return _m(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t))[3, :3].copy()


def value_components(v):
    """A scalar, vector or quaternion value as a list of floats
    (quaternions as x, y, z, w)."""
    if isinstance(v, _QUAT_TYPES):
        im = v.GetImaginary()
        return [float(im[0]), float(im[1]), float(im[2]), float(v.GetReal())]
    if isinstance(v, (bool, int, float)):
        return [float(v)]
    try:
        return [float(x) for x in v]
    except TypeError:
        return [float(v)]


# ---------------------------------------------------------------------------
# quaternions, (w, x, y, z) numpy arrays


def quat_np(q):
    im = q.GetImaginary()
    return np.array([q.GetReal(), im[0], im[1], im[2]], dtype=np.float64)


def quat_mul(a, b):
    """Hamilton product a (x) b."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    ])


def quat_inv(q):
    q = np.asarray(q, dtype=np.float64)
    return np.array([q[0], -q[1], -q[2], -q[3]]) / float(q @ q)


def rotation_vector(q):
    """axis x angle (radians) of a unit quaternion, taken with w >= 0."""
    q = np.asarray(q, dtype=np.float64)
    q = q / np.linalg.norm(q)
    if q[0] < 0:
        q = -q
    v = q[1:]
    s = np.linalg.norm(v)
    if s < 1e-300:
        return np.zeros(3)
    angle = 2.0 * math.atan2(s, q[0])
    return v / s * angle


def quat_axis_angle(axis, deg):
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    h = math.radians(deg) / 2
    return np.array([math.cos(h), *(axis * math.sin(h))])


def quat_to_row_matrix(q):
    """3x3 rotation in USD's row-vector convention (p' = p @ M)."""
    w, x, y, z = np.asarray(q, dtype=np.float64) / np.linalg.norm(q)
    col = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])
    return col.T


def row_matrix_to_quat(m3):
    """Unit quaternion (w, x, y, z) of a row-vector rotation matrix (Shepperd)."""
    r = np.asarray(m3, dtype=np.float64)[:3, :3].T  # column convention
    tr = np.trace(r)
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s]
    elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
        s = math.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2]) * 2
        q = [(r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s, (r[0, 2] + r[2, 0]) / s]
    elif r[1, 1] > r[2, 2]:
        s = math.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2]) * 2
        q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s, (r[1, 2] + r[2, 1]) / s]
    else:
        s = math.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1]) * 2
        q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s, 0.25 * s]
    q = np.array(q)
    return q / np.linalg.norm(q)


# ---------------------------------------------------------------------------
# axes (SPEC section 4)


class Frame:
    """What axes are measured against at one time: the proxy's
    local-to-world and its posed points (proxy-local), the bake's --camera."""

    def __init__(self, t, proxy_l2w, posed_local, camera=None):
        self.t = t
        self.proxy_l2w = np.asarray(proxy_l2w, dtype=np.float64)
        self.posed_local = np.asarray(posed_local, dtype=np.float64)
        self.camera = camera

    @property
    def centre(self):
        return 0.5 * (self.posed_local.min(axis=0) + self.posed_local.max(axis=0))


def _targets(prim, name="source"):
    rel = prim.GetRelationship(name)
    return list(rel.GetTargets()) if rel else []


def raw_axis_value(stage, axis_prim, frame):
    """The unscaled value of one PainterlyAxis at frame.t."""
    t = frame.t
    kind = authored(axis_prim, "kind", "attribute")
    element = int(authored(axis_prim, "element", 0))
    component = int(authored(axis_prim, "component", 0))
    targets = _targets(axis_prim)

    if kind == "attribute":
        attr = stage.GetAttributeAtPath(targets[0])
        v = attr.Get(t)
        if attr.GetTypeName().isArray:
            v = v[element]
        comps = value_components(v)
        return comps[component] if len(comps) > 1 else comps[0]

    if kind == "blendShape":
        anim = UsdSkel.Animation(stage.GetPrimAtPath(targets[0]))
        name = authored(axis_prim, "name")
        names = list(anim.GetBlendShapesAttr().Get() or [])
        if name not in names:
            return 0.0
        weights = anim.GetBlendShapeWeightsAttr().Get(t)
        return float(weights[names.index(name)])

    if kind == "jointRotation":
        skel_prim = stage.GetPrimAtPath(targets[0])
        skel = UsdSkel.Skeleton(skel_prim)
        name = authored(axis_prim, "name")
        joints = list(skel.GetJointsAttr().Get())
        j = joints.index(name)
        # usd-core's split of the rest transform (a mirroring one included)
        rest_rot = UsdSkel.DecomposeTransform(skel.GetRestTransformsAttr().Get()[j])[1]
        q_rest = np.array([rest_rot.GetReal(), *rest_rot.GetImaginary()])
        q = q_rest
        # usd-core's rule: on the Skeleton or inherited from any ancestor
        src = UsdSkel.BindingAPI(skel_prim).GetInheritedAnimationSource()
        if src:
            anim = UsdSkel.Animation(src)
            anim_joints = list(anim.GetJointsAttr().Get() or [])
            if name in anim_joints:
                q = quat_np(anim.GetRotationsAttr().Get(t)[anim_joints.index(name)])
        q_rel = quat_mul(quat_inv(q_rest), q / np.linalg.norm(q))
        return float(rotation_vector(q_rel)[component])

    if kind == "position":
        o = world_origin(stage.GetPrimAtPath(targets[0]), t)
        return float(to_local(o[None], frame.proxy_l2w)[0, component])

    if kind == "viewDirection":
        cam_path = targets[0] if targets else frame.camera
        cam = to_local(world_origin(stage.GetPrimAtPath(cam_path), t)[None], frame.proxy_l2w)[0]
        d = cam - frame.centre
        return float((d / np.linalg.norm(d))[component])

    raise ValueError(f"{axis_prim.GetPath()}: unknown axis kind {kind!r}")


def axis_value(stage, axis_prim, frame):
    """Axis value in axis units (what key coordinates store)."""
    return raw_axis_value(stage, axis_prim, frame)


def axis_scales(axes):
    """The axes' `scale`s: interpolation multiplies key coordinates and the
    configuration by them."""
    return np.array([float(authored(a, "scale", 1.0)) for a in axes], dtype=np.float64)


def rig_axes(rig_prim):
    """Every PainterlyAxis under the rig, namespace (depth-first) order."""
    return [p for p in Usd.PrimRange(rig_prim) if p != rig_prim and p.GetTypeName() == AXIS_TYPE]


def layer_axes(stage, rig_prim, layer_prim):
    rel = layer_prim.GetRelationship("painterly:axes")
    if rel and rel.HasAuthoredTargets():
        return [stage.GetPrimAtPath(p) for p in rel.GetTargets()]
    return rig_axes(rig_prim)


# ---------------------------------------------------------------------------
# pose keys (SPEC section 4)


def pose_keys(layer_prim):
    """(position keys, opacity keys): lists of (path, coordinates, value)."""
    pos, op = [], []
    for c in layer_prim.GetChildren():
        if c.GetTypeName() != POSE_KEY_TYPE:
            continue
        coords = np.array(authored(c, "coordinates", []), dtype=np.float64)
        pts = authored(c, "points")
        if pts is not None:
            pos.append((str(c.GetPath()), coords, np.array(pts, dtype=np.float64)))
        o = authored(c, "opacity")
        if o is not None:
            op.append((str(c.GetPath()), coords, float(o)))
    return pos, op


def interpolation(layer_prim):
    return (str(authored(layer_prim, "painterly:interpolation", "smoothVoronoi")),
            float(authored(layer_prim, "painterly:rbfRadius", 1.0)))


def blend_weights(method, radius, key_coords, configs, scales):
    """(m, n) weights of n keys at m configurations, both in axis units,
    interpolated over scaled coordinates."""
    keys = np.asarray(key_coords, dtype=np.float64).reshape(len(key_coords), -1)
    x = np.asarray(configs, dtype=np.float64).reshape(len(configs), keys.shape[1])
    s = np.asarray(scales, dtype=np.float64).reshape(1, keys.shape[1])
    return RI.weights(method, keys * s, x * s, radius)


# ---------------------------------------------------------------------------
# temporal keys (SPEC section 5)


def time_keys(layer_prim):
    """(sentinel times, normal position keys, normal opacity keys), keys as
    sorted lists of (time, value)."""
    sentinels, pos, op = [], [], []
    for c in layer_prim.GetChildren():
        if c.GetTypeName() != TIME_KEY_TYPE:
            continue
        t = float(authored(c, "time"))
        if bool(authored(c, "sentinel", False)):
            sentinels.append(t)
            continue
        pts = authored(c, "points")
        if pts is not None:
            pos.append((t, np.array(pts, dtype=np.float64)))
        o = authored(c, "opacity")
        if o is not None:
            op.append((t, float(o)))
    return sorted(sentinels), sorted(pos, key=lambda k: k[0]), sorted(op, key=lambda k: k[0])


def temporal_value(t, config, normals, sentinels):
    """SPEC section 5 for one channel at time t.

    config: the configuration-space value at t; normals: sorted (time, value)
    normal keys of this channel; sentinels: sorted sentinel times.
    """
    if not normals:
        return config
    for tk, v in normals:
        if t == tk:
            return v
    if any(t == s for s in sentinels):
        return config  # at a sentinel every blend weight is 0
    prev_n = max((k for k in normals if k[0] < t), default=None, key=lambda k: k[0])
    next_n = min((k for k in normals if k[0] > t), default=None, key=lambda k: k[0])
    prev_s = max((s for s in sentinels if s < t), default=None)
    next_s = min((s for s in sentinels if s > t), default=None)
    # the neighbouring events on the channel's timeline (keys + sentinels)
    prev_is_key = prev_n is not None and (prev_s is None or prev_n[0] > prev_s)
    next_is_key = next_n is not None and (next_s is None or next_n[0] < next_s)
    S = lambda u: float(RI.smooth_step(u))  # noqa: E731  corrected S_0.2

    if prev_is_key and next_is_key:
        lo = -math.inf if prev_s is None else prev_s
        hi = math.inf if next_s is None else next_s
        group = [k for k in normals if lo < k[0] < hi]
        w = RI.smooth_voronoi_weights(np.array([[k[0]] for k in group]), np.array([[t]]))[0]
        return sum(wi * k[1] for wi, k in zip(w, group))
    if next_is_key:  # previous event: a sentinel or the start of time
        if prev_s is None:
            return next_n[1]
        u = (t - prev_s) / (next_n[0] - prev_s)
        return (1.0 - S(u)) * config + S(u) * next_n[1]
    if prev_is_key:  # next event: a sentinel or the end of time
        if next_s is None:
            return prev_n[1]
        u = (next_s - t) / (next_s - prev_n[0])
        return (1.0 - S(u)) * config + S(u) * prev_n[1]
    return config  # between two sentinels, or a sentinel and an end of time


# ---------------------------------------------------------------------------
# whole bake


def base_display_opacity(prim):
    """Per-curve authored displayOpacity (1 when absent)."""
    ncurves = len(UsdGeom.BasisCurves(prim).GetCurveVertexCountsAttr().Get())
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayOpacity")
    if not (pv and pv.HasAuthoredValue()):
        return np.ones(ncurves)
    vals = np.array(pv.ComputeFlattened(Usd.TimeCode.Default()), dtype=np.float64)
    interp = pv.GetInterpolation()
    if interp == UsdGeom.Tokens.constant:
        return np.full(ncurves, vals[0])
    if interp == UsdGeom.Tokens.uniform:
        return vals
    raise ValueError(f"reference does not model displayOpacity interpolation {interp}")


def layer_opacity(prim, t):
    a = prim.GetAttribute("painterly:opacity")
    if a and a.HasAuthoredValue():
        return float(a.Get(t))
    return 1.0


def expected_bake(input_path, frames, camera=None, posed_world=None):
    """Expected bake of every stroke layer at every frame.

    Returns {layer_path: {"points": {t: (N,3) stroke-local},
    "opacity": {t: (ncurves,)}, "config": {t: (d,)}, "rest": {t: (N,3)},
    "keyed_opacity": {t: float}}} and the posed proxies used
    ({mesh: {t: world points}}).
    """
    from authoring import usdcore_world_points

    frames = [float(t) for t in frames]
    stage, rigs = RS.describe(input_path)
    if posed_world is None:
        posed_world = usdcore_world_points(input_path, sorted({r["mesh"] for r in rigs}), frames)
    out = {}
    for rig in rigs:
        rig_prim = stage.GetPrimAtPath(rig["path"])
        mesh_prim = stage.GetPrimAtPath(rig["mesh"])
        topo = rig["topo"]
        fr = {}
        for t in frames:
            l2w = _m(UsdGeom.Xformable(mesh_prim).ComputeLocalToWorldTransform(t))
            fr[t] = Frame(t, l2w, to_local(posed_world[rig["mesh"]][t], l2w), camera)
        axis_cache = {}

        def av(axis_prim, t):
            key = (str(axis_prim.GetPath()), t)
            if key not in axis_cache:
                axis_cache[key] = axis_value(stage, axis_prim, fr[t])
            return axis_cache[key]

        per_layer = {}
        for layer in rig["layers"]:
            lp = stage.GetPrimAtPath(layer["path"])
            pos, op = pose_keys(lp)
            method, radius = interpolation(lp)
            cfg, scales = {}, None
            if pos or op:
                axes = layer_axes(stage, rig_prim, lp)
                scales = axis_scales(axes)
                cfg = {t: np.array([av(a, t) for a in axes]) for t in frames}
            rest_cfg = {t: layer["rest"] for t in frames}
            op_cfg = {t: 1.0 for t in frames}
            if pos:
                W = blend_weights(method, radius, [k[1] for k in pos], [cfg[t] for t in frames], scales)
                for row, t in zip(W, frames):
                    rest_cfg[t] = sum(w * k[2] for w, k in zip(row, pos))
            if op:
                W = blend_weights(method, radius, [k[1] for k in op], [cfg[t] for t in frames], scales)
                for row, t in zip(W, frames):
                    op_cfg[t] = float(sum(w * k[2] for w, k in zip(row, op)))
            sentinels, tpos, top = time_keys(lp)
            rest_t = {t: temporal_value(t, rest_cfg[t], tpos, sentinels) for t in frames}
            op_t = {t: float(temporal_value(t, op_cfg[t], top, sentinels)) for t in frames}
            per_layer[layer["path"]] = (layer, lp, cfg, rest_t, op_t)

        for t in frames:
            R, tr = topo.motions(fr[t].posed_local)
            for path, (layer, lp, cfg, rest_t, op_t) in per_layer.items():
                sk = RS.skin_points(rest_t[t], layer["verts"], layer["weights"], R, tr)
                stroke_l2w = _m(UsdGeom.Xformable(lp).ComputeLocalToWorldTransform(t))
                d = out.setdefault(path, {"points": {}, "opacity": {}, "config": {}, "rest": {},
                                          "keyed_opacity": {}})
                d["points"][t] = RS.to_stroke_space(sk, fr[t].proxy_l2w, stroke_l2w)
                d["opacity"][t] = base_display_opacity(lp) * layer_opacity(lp, t) * op_t[t]
                d["config"][t] = cfg.get(t)
                d["rest"][t] = rest_t[t]
                d["keyed_opacity"][t] = op_t[t]
    return out, posed_world


def axis_values_over(input_path, axis_paths, frames, camera=None, posed_world=None):
    """{axis path: [value in axis units at each frame]} for the first rig of the input
    (used to place keys where the configuration actually goes)."""
    from authoring import usdcore_world_points

    frames = [float(t) for t in frames]
    stage, rigs = RS.describe(input_path)
    rig = rigs[0]
    if posed_world is None:
        posed_world = usdcore_world_points(input_path, [rig["mesh"]], frames)
    mesh_prim = stage.GetPrimAtPath(rig["mesh"])
    out = {p: [] for p in axis_paths}
    for t in frames:
        l2w = _m(UsdGeom.Xformable(mesh_prim).ComputeLocalToWorldTransform(t))
        f = Frame(t, l2w, to_local(posed_world[rig["mesh"]][t], l2w), camera)
        for p in axis_paths:
            out[p].append(axis_value(stage, stage.GetPrimAtPath(Sdf.Path(p)), f))
    return {p: np.array(v) for p, v in out.items()}
