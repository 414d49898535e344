"""Authoring helpers for painterly's key tests (SPEC sections 4-5): axes,
pose keys, time keys, and the scene objects axes measure (controls with
time-sampled attributes, an animated locator, cameras), written with
usd-core. Built on authoring.py; writes only where the caller says.
"""

from __future__ import annotations

import math

import numpy as np
from pxr import Gf, Sdf, UsdGeom, UsdSkel, Vt

import authoring as Au

AXIS = "PainterlyAxis"
POSE_KEY = "PainterlyPoseKey"
TIME_KEY = "PainterlyTimeKey"

T = Sdf.ValueTypeNames


def _set(prim, name, tname, value, uniform=True):
    a = prim.CreateAttribute(name, tname, False, Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying)
    a.Set(value)
    return a


def add_axis(stage, path, kind, source=None, name=None, element=None, component=None, scale=None):
    """A PainterlyAxis prim. `source`: a path (prim or attribute) or a list."""
    prim = stage.DefinePrim(path, AXIS)
    if kind is not None:
        _set(prim, "kind", T.Token, kind)
    if source is not None:
        srcs = source if isinstance(source, (list, tuple)) else [source]
        prim.CreateRelationship("source", False).SetTargets([Sdf.Path(str(s)) for s in srcs])
    if name is not None:
        _set(prim, "name", T.Token, name)
    if element is not None:
        _set(prim, "element", T.Int, int(element))
    if component is not None:
        _set(prim, "component", T.Int, int(component))
    if scale is not None:
        _set(prim, "scale", T.Float, float(scale))
    return prim


def add_pose_key(stage, layer_path, name, coordinates, points=None, opacity=None):
    prim = stage.DefinePrim(Sdf.Path(layer_path).AppendChild(name), POSE_KEY)
    _set(prim, "coordinates", T.FloatArray, Vt.FloatArray([float(c) for c in coordinates]))
    if points is not None:
        _set(prim, "points", T.Point3fArray, Au.v3f(points))
    if opacity is not None:
        _set(prim, "opacity", T.Float, float(opacity))
    return prim


def add_time_key(stage, layer_path, name, time, sentinel=None, points=None, opacity=None):
    prim = stage.DefinePrim(Sdf.Path(layer_path).AppendChild(name), TIME_KEY)
    _set(prim, "time", T.Double, float(time))
    if sentinel is not None:
        _set(prim, "sentinel", T.Bool, bool(sentinel))
    if points is not None:
        _set(prim, "points", T.Point3fArray, Au.v3f(points))
    if opacity is not None:
        _set(prim, "opacity", T.Float, float(opacity))
    return prim


def set_layer_axes(stage, layer_path, axis_paths):
    prim = stage.GetPrimAtPath(layer_path)
    prim.CreateRelationship("painterly:axes", False).SetTargets([Sdf.Path(str(p)) for p in axis_paths])


def set_interpolation(stage, layer_path, method, radius=None):
    prim = stage.GetPrimAtPath(layer_path)
    _set(prim, "painterly:interpolation", T.Token, method)
    if radius is not None:
        _set(prim, "painterly:rbfRadius", T.Float, float(radius))


def proxy_topology(stage, mesh_path):
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(mesh_path))
    return (np.array(mesh.GetPointsAttr().Get(), dtype=np.float64),
            list(mesh.GetFaceVertexCountsAttr().Get()), list(mesh.GetFaceVertexIndicesAttr().Get()))


def add_layer(stage, rig, path, rng, n_strokes=4, offsets=(0.0, 0.03), **kw):
    """A new stroke layer with strokes near the rig's rest proxy; returns its
    rest points (float32 round trip)."""
    rest, counts, idx = proxy_topology(stage, rig.mesh)
    sc, sp = Au.make_strokes(rest, counts, idx, rng, n_strokes, offsets=offsets)
    Au.add_stroke_layer(stage, path, sc, sp, **kw)
    return np.array(Au.v3f(sp), dtype=np.float64), sc


def layer_rest(stage, layer_path):
    prim = stage.GetPrimAtPath(layer_path)
    a = prim.GetAttribute("painterly:restPoints")
    if a and a.HasAuthoredValue():
        return np.array(a.Get(), dtype=np.float64)
    return np.array(UsdGeom.BasisCurves(prim).GetPointsAttr().Get(), dtype=np.float64)


def displaced(points, rng, amp):
    """Key points: the rest points moved by a random field of size ~amp
    (each stroke translated and its points jittered)."""
    p = np.asarray(points, dtype=np.float64)
    return p + rng.uniform(-amp, amp, size=(1, 3)) + rng.uniform(-0.4 * amp, 0.4 * amp, size=p.shape)


# ---------------------------------------------------------------------------
# what axes measure


def add_controls(stage, path="/World/Controls"):
    """Time-sampled attributes of several types on one prim. Returns the
    attribute paths by short name."""
    prim = stage.DefinePrim(path, "Scope")
    out = {}

    def mk(short, name, tname, samples):
        a = prim.CreateAttribute(name, tname, True)
        for t, v in samples.items():
            a.Set(v, t)
        out[short] = f"{path}.{name}"

    mk("scalar", "ctl:scalar", T.Double, {1: -0.5, 5: 0.8, 9: 0.1, 12: 1.0})
    mk("float", "ctl:gain", T.Float, {2: 0.25, 7: -0.75, 11: 0.5})
    mk("array", "ctl:array", T.FloatArray, {
        1: Vt.FloatArray([0.0, 1.0, -1.0, 3.0]),
        7: Vt.FloatArray([0.5, 1.0, 2.0, 3.0]),
        12: Vt.FloatArray([0.0, 1.0, 0.5, 3.0])})
    mk("vec", "ctl:vec", T.Float3, {
        1: Gf.Vec3f(0.0, -1.0, 2.0), 4: Gf.Vec3f(1.0, 1.5, 0.0), 12: Gf.Vec3f(-1.0, 0.2, 1.0)})

    def q(axis, deg):
        a = np.asarray(axis, dtype=float)
        a = a / np.linalg.norm(a) * math.sin(math.radians(deg) / 2)
        return Gf.Quatf(math.cos(math.radians(deg) / 2), Gf.Vec3f(*a))

    # large angles between samples: slerp, nlerp and component lerp differ
    mk("quat", "ctl:quat", T.Quatf, {1: q((1, 0, 0), 10), 6: q((1, 1, 0), 100), 12: q((0, 1, 1), 150)})
    mk("vecArray", "ctl:vecArray", T.Double3Array, {
        1: Vt.Vec3dArray([Gf.Vec3d(9, 9, 9), Gf.Vec3d(0.1, 0.2, -0.6)]),
        5: Vt.Vec3dArray([Gf.Vec3d(9, 9, 9), Gf.Vec3d(0.3, 0.2, 0.9)]),
        12: Vt.Vec3dArray([Gf.Vec3d(9, 9, 9), Gf.Vec3d(0.0, 0.4, 0.2)])})
    mk("int", "ctl:step", T.Int, {1: 0, 5: 2, 9: 1})
    return out


def add_locator(stage, parent="/World/LocParent", name="Locator"):
    """An animated locator under an animated, rotated parent."""
    par = UsdGeom.Xform.Define(stage, parent)
    Au.xf_animated({1: ((0.5, 0.0, 0.0), (0, 0, 0), (1, 1, 1)),
                    6: ((0.0, 1.0, 0.5), (0, 40, 10), (1, 1, 1)),
                    12: ((-0.5, 2.0, 1.0), (0, 90, 0), (1.5, 1.5, 1.5))})(par)
    loc = UsdGeom.Xform.Define(stage, f"{parent}/{name}")
    op = loc.AddTranslateOp()
    for t, v in {1: (1.0, 0.0, 0.0), 4: (1.0, 1.5, 0.0), 9: (0.0, 3.0, 1.0), 12: (0.5, 2.0, 2.0)}.items():
        op.Set(Gf.Vec3d(*v), t)
    return str(loc.GetPath())


def add_orbit_camera(stage, path="/World/Orbit", degrees=(0, 300), frames=(1, 12), radius=8.0, height=2.0):
    """A camera orbiting the origin about +Y (animated parent rotation)."""
    orbit = UsdGeom.Xform.Define(stage, path)
    rop = orbit.AddRotateYOp()
    rop.Set(float(degrees[0]), frames[0])
    rop.Set(float(degrees[1]), frames[1])
    cam = UsdGeom.Camera.Define(stage, f"{path}/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0.0, height, radius))
    return str(cam.GetPath())


def add_moving_camera(stage, path="/World/CamB"):
    cam = UsdGeom.Camera.Define(stage, path)
    op = cam.AddTranslateOp()
    for t, v in {1: (6.0, 1.0, 2.0), 6: (0.5, 5.0, -6.0), 12: (-3.0, 4.0, 7.0)}.items():
        op.Set(Gf.Vec3d(*v), t)
    return path


def set_rest_rotation(stage, skel_path, joint, axis, deg):
    """Give a joint's rest transform a rotation (its translation is kept)."""
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath(skel_path))
    joints = list(skel.GetJointsAttr().Get())
    rest = list(skel.GetRestTransformsAttr().Get())
    j = joints.index(joint)
    tr = rest[j].ExtractTranslation()
    m = Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(*map(float, axis)), float(deg)))
    m.SetTranslateOnly(tr)
    rest[j] = m
    skel.GetRestTransformsAttr().Set(Vt.Matrix4dArray(rest))


def key_positions(values, fractions):
    """Places along the observed range [min, max] of an axis; when the axis
    does not move, spread around its value."""
    v = np.asarray(values, dtype=np.float64)
    lo, hi = float(v.min()), float(v.max())
    if hi - lo < 1e-6:
        lo, hi = lo - 0.5, hi + 0.5
    return [lo + f * (hi - lo) for f in fractions]
