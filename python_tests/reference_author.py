"""An independent numpy implementation of painterly's authoring commands
(`bind`, `smudge`, `expand`; Bassett et al. 2013 sections 3.1-3.3 on top of
SPEC section 3), used as the expected value in test_author.py.

Definitions implemented here (the contract of the commands):

bind --time T
    p   = each point of the layer's default `points` (stroke-local, as
          painted) taken to the proxy's local space in the pose at T:
          inverse(proxy L2W(T)) . stroke L2W(T);
    binding = closest point of the POSED proxy (fan triangles, clamped
          barycentrics);
    M   = sum_i w_i M_i, M_i the per-vertex Procrustes motions rest -> pose T;
    rest = M^-1 p.
    Without --time: the rest pose (M = I, posed = rest proxy), transforms
    read at the stage's startTimeCode.

smudge / expand
    w   = proxy L2W(T) . M . x  (x = a rest point or a key point, M from the
          layer's binding: the cached one, else the closest point on the
          rest proxy);
    d   = distance from w to the tool path (a world-space polyline);
    if d <= R: delta_world = S f(d / R) u, f(r) = 2r^3 - 3r^2 + 1 (cubic) or
          1 (none), u = the unit tangent of the path segment holding the
          closest path point (smudge), or the unit world-space surface normal
          at the bound position (expand): the barycentric blend, with the
          binding's weights, of the posed proxy's area-weighted unit vertex
          normals, mapped by the normal matrix of the proxy's L2W and then
          normalised;
    x  += A^-1 (L^-1 delta_world), A = the linear part of M, L = the
          linear part of the proxy's L2W.

Row-vector matrices (USD) are converted to column-vector numpy matrices
right away: for a USD row matrix m, the column-convention linear part is
m[:3, :3].T and the translation m[3, :3].
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom

import reference_skinning as RS


# ---------------------------------------------------------------------------
# small linear algebra


def usd_matrix(gf) -> np.ndarray:
    """A USD (row-vector) Gf matrix as a column-vector 4x4 numpy matrix."""
    return np.array(gf, dtype=np.float64).reshape(4, 4).T


def transform_points(m_col, pts) -> np.ndarray:
    p = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
    return p @ m_col[:3, :3].T + m_col[:3, 3]


def l2w(stage, path, t) -> np.ndarray:
    return usd_matrix(UsdGeom.Xformable(stage.GetPrimAtPath(path)).ComputeLocalToWorldTransform(t))


def blend(R, tr, verts, weights):
    """Per point (A (N,3,3), b (N,3)): M = sum_k w_k M_{v_k} (Bassett eq. 1)."""
    verts = np.asarray(verts, dtype=np.int64)
    w = np.asarray(weights, dtype=np.float64)
    A = np.einsum("nk,nkij->nij", w, R[verts])
    b = np.einsum("nk,nki->ni", w, tr[verts])
    return A, b


def apply_blend(A, b, x):
    return np.einsum("nij,nj->ni", A, np.asarray(x, dtype=np.float64)) + b


def inverse_blend(A, b, p):
    return np.linalg.solve(A, (np.asarray(p, dtype=np.float64) - b)[..., None])[..., 0]


def identity_motions(n):
    return np.repeat(np.eye(3)[None], n, axis=0), np.zeros((n, 3))


# ---------------------------------------------------------------------------
# the pose a command works in


class Pose:
    """The rig of `mesh_path` in the pose at `t` (None: the rest pose).

    posed_world: {mesh: {t: (N,3) world points}} from usd-core
    (authoring.usdcore_world_points); only needed when t is not None.
    start: the time transforms are read at in the rest pose (default: the
    stage's startTimeCode; pass the input's when `stage` is an edit layer
    that does not repeat it).
    """

    def __init__(self, stage, rig, t, posed_world=None, start=None):
        self.stage = stage
        self.rig = rig
        topo = rig["topo"]
        self.topo = topo
        if start is None:
            start = stage.GetStartTimeCode()
        self.time = float(start) if t is None else float(t)
        self.proxy_l2w = l2w(stage, rig["mesh"], self.time)
        if t is None:
            self.posed = topo.rest.copy()
            self.R, self.tr = identity_motions(topo.n)
        else:
            pw = posed_world[rig["mesh"]][t]
            self.posed = transform_points(np.linalg.inv(self.proxy_l2w), pw)
            self.R, self.tr = topo.motions(self.posed)

    def vertex_normals(self):
        """Area-weighted unit vertex normals of the posed proxy (proxy-local)."""
        P = self.posed
        tris = self.topo.tris
        f = np.cross(P[tris[:, 1]] - P[tris[:, 0]], P[tris[:, 2]] - P[tris[:, 0]])
        n = np.zeros_like(P)
        for k in range(3):
            np.add.at(n, tris[:, k], f)
        ln = np.linalg.norm(n, axis=1, keepdims=True)
        return np.where(ln > 0, n / np.where(ln > 0, ln, 1), 0.0)


def find_rig(rigs, layer_path):
    for rig in rigs:
        for layer in rig["layers"]:
            if layer["path"] == layer_path:
                return rig, layer
    raise KeyError(layer_path)


# ---------------------------------------------------------------------------
# bind


def bind_layer(stage, rig, layer_path, t=None, posed_world=None, start=None):
    """Expected (restPoints, bindVertices, bindWeights) of `painterly bind`.

    Reads the layer's default `points` (as painted) from `stage`.
    """
    pose = Pose(stage, rig, t, posed_world, start)
    prim = stage.GetPrimAtPath(layer_path)
    painted = np.array(UsdGeom.BasisCurves(prim).GetPointsAttr().Get(Usd.TimeCode.Default()), dtype=np.float64)
    to_proxy = np.linalg.inv(pose.proxy_l2w) @ l2w(stage, layer_path, pose.time)
    p = transform_points(to_proxy, painted)
    verts, weights = RS.bind(pose.posed, pose.topo.tris, p)
    A, b = blend(pose.R, pose.tr, verts, weights)
    return inverse_blend(A, b, p), verts, weights, p


# ---------------------------------------------------------------------------
# tool paths and brushes


def closest_on_path(path, pts, tie="first"):
    """(distance (N,), unit tangent (N,3)) of the closest path point.

    Zero-length segments are skipped. tie="first" keeps the earliest of
    equally close segments, "last" the latest (the two ends of the range a
    correct implementation may land in at a polyline joint).
    """
    path = np.asarray(path, dtype=np.float64)
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
    best_d = np.full(len(pts), np.inf)
    best_u = np.zeros((len(pts), 3))
    for a, b in zip(path[:-1], path[1:]):
        d = b - a
        l2 = d @ d
        if l2 <= 0:
            continue
        s = np.clip((pts - a) @ d / l2, 0.0, 1.0)
        dist = np.linalg.norm(a + s[:, None] * d - pts, axis=1)
        better = dist < best_d - 1e-12 if tie == "first" else dist <= best_d + 1e-12
        best_d = np.where(better, dist, best_d)
        best_u = np.where(better[:, None], d / np.sqrt(l2), best_u)
    return best_d, best_u


def falloff(r, kind):
    r = np.asarray(r, dtype=np.float64)
    inside = (r >= 0) & (r <= 1)
    if kind == "cubic":
        f = 2 * r ** 3 - 3 * r ** 2 + 1
    elif kind == "none":
        f = np.ones_like(r)
    else:
        raise ValueError(kind)
    return np.where(inside, f, 0.0)


def stroke_mask(counts, strokes, n):
    if strokes is None:
        return np.ones(n, dtype=bool)
    starts = np.concatenate([[0], np.cumsum(counts)])
    m = np.zeros(n, dtype=bool)
    for s in strokes:
        m[starts[s]:starts[s + 1]] = True
    return m


def brush(stage, rig, layer, which, target, path, radius, strength, kind="cubic", t=None,
          posed_world=None, strokes=None, tie="first", start=None):
    """Expected edited points (N,3) of `painterly smudge|expand`.

    `layer` is a reference_skinning.describe() layer dict (its binding is the
    cached one when authored, else the closest point on the rest proxy);
    `target` the points being edited (rest points or a key's points).
    Returns (new points, world positions, distances to the path).
    """
    pose = Pose(stage, rig, t, posed_world, start)
    x = np.asarray(target, dtype=np.float64).reshape(-1, 3)
    verts, weights = layer["verts"], layer["weights"]
    A, b = blend(pose.R, pose.tr, verts, weights)
    world = transform_points(pose.proxy_l2w, apply_blend(A, b, x))
    d, tangent = closest_on_path(path, world, tie=tie)
    mag = strength * falloff(d / radius, kind) * (d <= radius)
    L = pose.proxy_l2w[:3, :3]
    if which == "smudge":
        u = tangent
    elif which == "expand":
        vn = pose.vertex_normals()
        n_local = np.einsum("nk,nki->ni", np.asarray(weights, dtype=np.float64), vn[np.asarray(verts)])
        n_world = n_local @ np.linalg.inv(L)  # (L^-T n) as rows
        ln = np.linalg.norm(n_world, axis=1, keepdims=True)
        u = np.where(ln > 0, n_world / np.where(ln > 0, ln, 1), 0.0)
    else:
        raise ValueError(which)
    dw = u * mag[:, None]
    dl = dw @ np.linalg.inv(L).T
    dr = np.linalg.solve(A, dl[..., None])[..., 0]
    mask = stroke_mask(layer["counts"], strokes, len(x))
    out = x + np.where(mask[:, None], dr, 0.0)
    return out, world, d


def path_from_curves(stage, path, t=None):
    """World-space points of a BasisCurves prim's first curve (default value
    of points; transforms at t, or at the stage's start when t is None)."""
    prim = stage.GetPrimAtPath(path)
    curves = UsdGeom.BasisCurves(prim)
    tc = Usd.TimeCode.Default() if t is None else t
    pts = np.array(curves.GetPointsAttr().Get(tc), dtype=np.float64)
    counts = curves.GetCurveVertexCountsAttr().Get()
    if counts:
        pts = pts[: int(counts[0])]
    return transform_points(l2w(stage, path, stage.GetStartTimeCode() if t is None else t), pts)
