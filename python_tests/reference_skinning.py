"""An independent numpy implementation of SPEC section 3 (stroke skinning),
used as the expected value in painterly's contract tests.

Pinned details (SPEC section 3):
- faces fan-triangulated from their first vertex: (v0, vk, vk+1);
- binding: closest point on the rest-pose triangle set (exact point-triangle
  distance, region-based closest point, barycentrics clamped to the
  triangle), that triangle's three vertices and barycentric weights; ties
  (SPEC 1.1): among triangles whose closest points lie within 1e-6 x the
  rest bounding-box diagonal of the smallest distance, the lowest triangle
  index in fan order;
- one-ring of v: v plus every vertex sharing an authored polygon edge;
- per-vertex rigid motion M_v(x) = R (x - c) + c' (Procrustes / Kabsch,
  det R = +1, R = I when the rest one-ring's covariance has second singular
  value < 1e-9 x the first);
- stroke point x -> sum_i w_i M_{v_i}(x) (blend of 3x4 matrices);
- then the proxy's local-to-world at t, then the stroke prim's world-to-local.

Everything is float64; inputs are whatever float32 values the stage holds.
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom, UsdSkel

RIG_API = "PainterlyRigAPI"
LAYER_API = "PainterlyStrokeLayerAPI"


# ---------------------------------------------------------------------------
# topology


def fan_triangles(counts, indices):
    counts = np.asarray(counts, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    tris = []
    o = 0
    for n in counts:
        f = indices[o:o + n]
        for k in range(1, n - 1):
            tris.append((f[0], f[k], f[k + 1]))
        o += n
    return np.array(tris, dtype=np.int64).reshape(-1, 3)


def one_rings(counts, indices, n_points):
    """CSR one-rings: (owner, member) pairs; every vertex's ring contains itself
    plus the vertices sharing an authored polygon edge with it."""
    nbrs = [set([v]) for v in range(n_points)]
    o = 0
    for n in counts:
        f = list(indices[o:o + n])
        for k in range(n):
            a, b = int(f[k]), int(f[(k + 1) % n])
            if a != b:
                nbrs[a].add(b)
                nbrs[b].add(a)
        o += n
    owner, member = [], []
    for v, s in enumerate(nbrs):
        for u in sorted(s):
            owner.append(v)
            member.append(u)
    return np.array(owner, dtype=np.int64), np.array(member, dtype=np.int64)


# ---------------------------------------------------------------------------
# closest point on triangles


def closest_on_triangles(p, A, B, C):
    """Closest points from points p (N,3) to triangles (A,B,C each (T,3)).

    Region-based (Voronoi regions of vertices, edges, face) closest point.
    Returns (dist2 (N,T), bary (N,T,3)) with bary in [0,1], summing to 1.
    """
    p = np.asarray(p, dtype=np.float64)[:, None, :]
    A = A[None]
    B = B[None]
    C = C[None]
    ab = B - A
    ac = C - A
    ap = p - A
    d1 = np.sum(ab * ap, -1)
    d2 = np.sum(ac * ap, -1)
    bp = p - B
    d3 = np.sum(ab * bp, -1)
    d4 = np.sum(ac * bp, -1)
    cp = p - C
    d5 = np.sum(ab * cp, -1)
    d6 = np.sum(ac * cp, -1)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    shape = d1.shape
    u = np.zeros(shape)
    v = np.zeros(shape)
    w = np.zeros(shape)
    with np.errstate(divide="ignore", invalid="ignore"):
        # interior (default)
        den = va + vb + vc
        iv = vb / den
        iw = vc / den
        u, v, w = 1 - iv - iw, iv, iw
        done = np.zeros(shape, dtype=bool)

        def put(mask, uu, vv, ww):
            nonlocal u, v, w, done
            m = mask & ~done
            u = np.where(m, uu, u)
            v = np.where(m, vv, v)
            w = np.where(m, ww, w)
            done |= m

        one = np.ones(shape)
        zero = np.zeros(shape)
        put((d1 <= 0) & (d2 <= 0), one, zero, zero)                       # vertex A
        put((d3 >= 0) & (d4 <= d3), zero, one, zero)                      # vertex B
        t_ab = d1 / (d1 - d3)
        put((vc <= 0) & (d1 >= 0) & (d3 <= 0), 1 - t_ab, t_ab, zero)      # edge AB
        put((d6 >= 0) & (d5 <= d6), zero, zero, one)                      # vertex C
        t_ac = d2 / (d2 - d6)
        put((vb <= 0) & (d2 >= 0) & (d6 <= 0), 1 - t_ac, zero, t_ac)      # edge AC
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        put((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), zero, 1 - t_bc, t_bc)  # edge BC
    bary = np.stack([u, v, w], axis=-1)
    bad = ~np.all(np.isfinite(bary), axis=-1)
    if bad.any():
        # degenerate triangle: closest over its three edges as segments
        bary = _degenerate_fix(p, A, B, C, bary, bad)
    bary = np.clip(bary, 0.0, 1.0)
    bary = bary / bary.sum(-1, keepdims=True)
    q = bary[..., 0:1] * A + bary[..., 1:2] * B + bary[..., 2:3] * C
    dist2 = np.sum((p - q) ** 2, -1)
    return dist2, bary


def _degenerate_fix(p, A, B, C, bary, bad):
    out = bary.copy()
    ns, ts = np.nonzero(bad)
    for n, t in zip(ns, ts):
        best = None
        pts = [A[0, t], B[0, t], C[0, t]]
        for i, j in ((0, 1), (0, 2), (1, 2)):
            a, b = pts[i], pts[j]
            d = b - a
            dd = d @ d
            s = 0.0 if dd == 0 else float(np.clip((p[n, 0] - a) @ d / dd, 0, 1))
            q = a + s * d
            e = np.sum((p[n, 0] - q) ** 2)
            if best is None or e < best[0]:
                wv = np.zeros(3)
                wv[i] += 1 - s
                wv[j] += s
                best = (e, wv)
        out[n, t] = best[1]
    return out


def tie_tolerance(rest_proxy):
    """SPEC 1.1 section 3: 1e-6 x the rest bounding-box diagonal."""
    P = np.asarray(rest_proxy, dtype=np.float64)
    return 1e-6 * float(np.linalg.norm(P.max(0) - P.min(0))) if len(P) else 0.0


def bind(rest_proxy, tris, points, chunk=128):
    """Closest-point binding with the SPEC 1.1 tie rule (lowest triangle
    index within tie_tolerance of the smallest distance).
    Returns (vertices (N,3) int, weights (N,3))."""
    P = np.asarray(rest_proxy, dtype=np.float64)
    A, B, C = P[tris[:, 0]], P[tris[:, 1]], P[tris[:, 2]]
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    verts = np.zeros((len(pts), 3), dtype=np.int64)
    weights = np.zeros((len(pts), 3))
    tol = tie_tolerance(P)
    for s in range(0, len(pts), chunk):
        d2, bary = closest_on_triangles(pts[s:s + chunk], A, B, C)
        d = np.sqrt(np.maximum(d2, 0.0))
        # first index (argmax of a boolean) among the tied triangles
        best = np.argmax(d <= d.min(axis=1, keepdims=True) + tol, axis=1)
        verts[s:s + chunk] = tris[best]
        weights[s:s + chunk] = bary[np.arange(len(best)), best]
    return verts, weights


def binding_is_ambiguous(rest_proxy, tris, points, margin, tol=1e-3):
    """True when some point has another triangle within `margin` of its
    closest distance whose closest point puts different weights on the
    vertices (a tie painterly could break differently, e.g. at a UV seam
    with split vertices, or on the medial axis of a concave region)."""
    P = np.asarray(rest_proxy, dtype=np.float64)
    A, B, C = P[tris[:, 0]], P[tris[:, 1]], P[tris[:, 2]]
    d2, bary = closest_on_triangles(np.asarray(points, dtype=np.float64).reshape(-1, 3), A, B, C)
    d = np.sqrt(np.maximum(d2, 0))
    for i in range(d.shape[0]):
        b = int(np.argmin(d[i]))
        ref = {}
        for k in range(3):
            ref[int(tris[b, k])] = ref.get(int(tris[b, k]), 0.0) + bary[i, b, k]
        for j in np.nonzero(d[i] <= d[i, b] + margin)[0]:
            if j == b:
                continue
            other = {}
            for k in range(3):
                other[int(tris[j, k])] = other.get(int(tris[j, k]), 0.0) + bary[i, j, k]
            keys = set(ref) | set(other)
            if sum(abs(ref.get(x, 0.0) - other.get(x, 0.0)) for x in keys) > tol:
                return True
    return False


# ---------------------------------------------------------------------------
# rigid motions and skinning


class ProxyTopology:
    def __init__(self, counts, indices, rest_points):
        self.rest = np.asarray(rest_points, dtype=np.float64)
        self.n = len(self.rest)
        self.tris = fan_triangles(counts, indices)
        self.owner, self.member = one_rings(counts, indices, self.n)
        cnt = np.bincount(self.owner, minlength=self.n).astype(np.float64)
        self.cnt = cnt
        c = np.zeros((self.n, 3))
        np.add.at(c, self.owner, self.rest[self.member])
        self.c = c / cnt[:, None]
        self.Prel = self.rest[self.member] - self.c[self.owner]
        cov = np.zeros((self.n, 3, 3))
        np.add.at(cov, self.owner, self.Prel[:, :, None] * self.Prel[:, None, :])
        s = np.linalg.svd(cov, compute_uv=False)
        self.degenerate = (s[:, 1] < 1e-9 * s[:, 0]) | (s[:, 0] <= 0)

    def motions(self, posed):
        """Per-vertex (R (n,3,3), t (n,3)) with M_v(x) = R x + t."""
        Q = np.asarray(posed, dtype=np.float64)
        c2 = np.zeros((self.n, 3))
        np.add.at(c2, self.owner, Q[self.member])
        c2 /= self.cnt[:, None]
        Qrel = Q[self.member] - c2[self.owner]
        H = np.zeros((self.n, 3, 3))
        np.add.at(H, self.owner, self.Prel[:, :, None] * Qrel[:, None, :])
        U, _, Vt = np.linalg.svd(H)
        V = np.transpose(Vt, (0, 2, 1))
        Ut = np.transpose(U, (0, 2, 1))
        d = np.sign(np.linalg.det(V @ Ut))
        d[d == 0] = 1.0
        D = np.zeros((self.n, 3, 3))
        D[:, 0, 0] = 1
        D[:, 1, 1] = 1
        D[:, 2, 2] = d
        R = V @ D @ Ut
        R[self.degenerate] = np.eye(3)
        t = c2 - np.einsum("nij,nj->ni", R, self.c)
        return R, t


def skin_points(points, verts, weights, R, t):
    x = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    out = np.zeros_like(x)
    for k in range(3):
        v = verts[:, k]
        w = weights[:, k][:, None]
        out += w * (np.einsum("nij,nj->ni", R[v], x) + t[v])
    return out


def to_stroke_space(points_proxy_local, proxy_l2w, stroke_l2w):
    p = np.asarray(points_proxy_local, dtype=np.float64)
    M = np.asarray(proxy_l2w) @ np.linalg.inv(np.asarray(stroke_l2w))
    return p @ M[:3, :3] + M[3, :3]


# ---------------------------------------------------------------------------
# whole-stage expectation


def applied(prim):
    return list(prim.GetPrimTypeInfo().GetAppliedAPISchemas())


def _np(v):
    return np.array(v, dtype=np.float64)


def _m(gf):
    return np.array(gf, dtype=np.float64).reshape(4, 4)


def is_skinned(stage, mesh_prim):
    cache = UsdSkel.Cache()
    for prim in stage.Traverse():
        if prim.IsA(UsdSkel.Root):
            cache.Populate(UsdSkel.Root(prim), Usd.PrimDefaultPredicate)
    q = cache.GetSkinningQuery(mesh_prim)
    return q is not None and bool(q)


def describe(input_path):
    """Rigs, proxies, rest poses and stroke layers of an input, read with usd-core."""
    stage = Usd.Stage.Open(str(input_path))
    rigs = []
    for prim in stage.Traverse():
        if RIG_API not in applied(prim):
            continue
        targets = prim.GetRelationship("painterly:proxy").GetTargets()
        mesh_prim = stage.GetPrimAtPath(targets[0])
        mesh = UsdGeom.Mesh(mesh_prim)
        skinned = is_skinned(stage, mesh_prim)
        pa = mesh.GetPointsAttr()
        rt = prim.GetAttribute("painterly:restTime")
        if skinned:
            rest = _np(pa.Get(Usd.TimeCode.Default()))
        elif rt and rt.HasAuthoredValue():
            rest = _np(pa.Get(rt.Get()))
        else:
            rest = _np(pa.Get(Usd.TimeCode.Default()))
        topo = ProxyTopology(mesh.GetFaceVertexCountsAttr().Get(), mesh.GetFaceVertexIndicesAttr().Get(), rest)
        layers = []
        for d in Usd.PrimRange(prim):
            if d == prim or LAYER_API not in applied(d):
                continue
            curves = UsdGeom.BasisCurves(d)
            rp = d.GetAttribute("painterly:restPoints")
            if rp and rp.HasAuthoredValue():
                spts = _np(rp.Get())
            else:
                spts = _np(curves.GetPointsAttr().Get(Usd.TimeCode.Default()))
            bv = d.GetAttribute("painterly:bindVertices")
            bw = d.GetAttribute("painterly:bindWeights")
            if bv and bv.HasAuthoredValue() and bw and bw.HasAuthoredValue():
                verts = np.array(bv.Get(), dtype=np.int64)
                weights = _np(bw.Get())
                cached = True
            else:
                verts, weights = bind(rest, topo.tris, spts)
                cached = False
            layers.append(dict(path=str(d.GetPath()), rest=spts, verts=verts, weights=weights,
                               cached=cached, counts=list(curves.GetCurveVertexCountsAttr().Get())))
        rigs.append(dict(path=str(prim.GetPath()), mesh=str(mesh_prim.GetPath()), skinned=skinned,
                         topo=topo, layers=layers))
    return stage, rigs


def expected_strokes(input_path, frames, posed_world=None, override_binding=None):
    """Expected baked stroke points {layer_path: {t: (N,3) stroke-local}}.

    The posed proxy comes from usd-core (BakeSkinning for skinned meshes,
    the points attribute otherwise), via authoring.usdcore_world_points,
    unless `posed_world` ({mesh: {t: world points}}) is given.
    override_binding: {layer_path: (verts, weights)} to force a binding.
    """
    from authoring import usdcore_world_points

    stage, rigs = describe(input_path)
    if posed_world is None:
        posed_world = usdcore_world_points(input_path, sorted({r["mesh"] for r in rigs}), frames)
    out = {}
    for rig in rigs:
        mesh_prim = stage.GetPrimAtPath(rig["mesh"])
        topo = rig["topo"]
        for t in frames:
            proxy_l2w = _m(UsdGeom.Xformable(mesh_prim).ComputeLocalToWorldTransform(t))
            pw = posed_world[rig["mesh"]][t]
            inv = np.linalg.inv(proxy_l2w)
            posed_local = pw @ inv[:3, :3] + inv[3, :3]
            R, tr = topo.motions(posed_local)
            for layer in rig["layers"]:
                verts, weights = layer["verts"], layer["weights"]
                if override_binding and layer["path"] in override_binding:
                    verts, weights = override_binding[layer["path"]]
                sk = skin_points(layer["rest"], verts, weights, R, tr)
                stroke_l2w = _m(UsdGeom.Xformable(stage.GetPrimAtPath(layer["path"])).ComputeLocalToWorldTransform(t))
                out.setdefault(layer["path"], {})[t] = to_stroke_space(sk, proxy_l2w, stroke_l2w)
    return out


def expected_display_opacity(stage, layer_path):
    """Per-curve authored displayOpacity (1 when absent) x painterly:opacity (1 when absent)."""
    prim = stage.GetPrimAtPath(layer_path)
    ncurves = len(UsdGeom.BasisCurves(prim).GetCurveVertexCountsAttr().Get())
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayOpacity")
    base = np.ones(ncurves)
    if pv and pv.HasAuthoredValue():
        vals = _np(pv.ComputeFlattened(Usd.TimeCode.Default()))
        interp = pv.GetInterpolation()
        if interp == UsdGeom.Tokens.constant:
            base = np.full(ncurves, vals[0])
        elif interp == UsdGeom.Tokens.uniform:
            base = vals
        else:
            raise ValueError(f"test does not model displayOpacity interpolation {interp}")
    op = prim.GetAttribute("painterly:opacity")
    o = float(op.Get()) if op and op.HasAuthoredValue() else 1.0
    return base * o
