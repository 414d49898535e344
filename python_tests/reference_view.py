"""An independent numpy/scipy implementation of SPEC section 6
(view-dependent geometry, Rademacher 1999 sections 3-4), used to check what
`painterly bake` writes for a PainterlyViewDependentAPI mesh.

Pieces (all float64 on top of the float32 values the stage holds):

- key directions are normalised onto the unit sphere; keys sharing a
  `viewpoint` token or a direction are one key viewpoint;
- covered case (the hull of the viewpoint directions strictly encloses the
  centre): the face of `scipy.spatial.ConvexHull` hit by the ray from the
  centre along the eye direction, barycentric weights b of the hit point
  (the cone coordinates of the eye over the face's three vertices,
  normalised to sum 1), w = b^a / sum b^a;
- coplanar hull facets with four vertices (cube corners) can be split along
  either diagonal; Rademacher leaves that to the hull algorithm, so the
  reference returns every valid triangulation's answer and tests accept any;
- uncovered, "cosine": the covered region is the cone spanned by the keys;
  its cells are the faces of hull(keys + centre) not touching the centre
  (the hull faces facing away from the centre). p = the covered direction
  nearest to the eye: the eye itself inside a cell, otherwise the best of the
  keys and the nearest points of the arcs between pairs of keys (the maximum
  of a linear function over a convex spherical region lies on its boundary,
  and every boundary arc is an arc between two keys); d = eye . p;
  result = base + max(0,d) * sum w_i(p) offset_i; with one key, exactly
  max(0,d) * deformed + (1 - max(0,d)) * base (SPEC 1.1; 1.0 printed
  max(0,1-d) for the base coefficient), so d <= 0 gives the base model;
- uncovered, "base": not reproduced (the placement of the virtual keys is an
  implementation choice); tests check its invariants instead;
- time: untimed key offset = key points - rest points (rest = default points,
  or the points at painterly:restTime); timed keys: offset_k = key points -
  base(t_k), natural cubic spline (scipy CubicSpline bc_type='natural') over
  the key times, held constant outside them, one key = constant;
- base(t): the mesh's points at t as usd-core evaluates them (time samples
  interpolated linearly) or, for a skinned mesh, usd-core's
  UsdSkel.BakeSkinning brought back into the mesh's local space;
- eye: camera origin (local-to-world translation) mapped into mesh-local
  space at t, minus the centre of the axis-aligned bounding box of base(t).
"""

from __future__ import annotations

import itertools

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt
from scipy.interpolate import CubicSpline
from scipy.spatial import ConvexHull

VIEW_API = "PainterlyViewDependentAPI"
VIEW_KEY = "PainterlyViewKey"

# Same-direction tolerance for grouping keys into viewpoints (radians).
SAME_DIR = 1e-6
# The centre counts as enclosed only if farther than this from every face plane.
ENCLOSE_EPS = 1e-9
# Cone-coordinate slack when testing whether a direction lies in a cell.
INSIDE_EPS = 1e-10


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def sharpen(b, alpha):
    b = np.clip(np.asarray(b, dtype=np.float64), 0.0, None)
    w = b ** float(alpha)
    return w / w.sum()


# ---------------------------------------------------------------------------
# hulls and cells


def _facets(points, extra_origin=False):
    """Facets of the convex hull of `points` (plus the origin when
    `extra_origin`), as (vertex index tuple, outward normal, offset h with
    n.x = h on the plane). Coplanar scipy simplices are merged into one
    facet (vertices in angular order). Vertex index len(points) is the origin.
    """
    pts = np.asarray(points, dtype=np.float64)
    if extra_origin:
        pts = np.vstack([pts, np.zeros(3)])
    hull = ConvexHull(pts)
    groups = []  # [(normal, h, set(vertices))]
    for simplex, eq in zip(hull.simplices, hull.equations):
        n, h = eq[:3], -eq[3]
        for g in groups:
            if np.dot(g[0], n) > 1 - 1e-9 and abs(g[1] - h) < 1e-9:
                g[2].update(int(i) for i in simplex)
                break
        else:
            groups.append((n, h, set(int(i) for i in simplex)))
    out = []
    for n, h, vs in groups:
        vs = sorted(vs)
        c = pts[vs].mean(axis=0)
        u = pts[vs[0]] - c
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        ang = [np.arctan2(np.dot(pts[i] - c, v), np.dot(pts[i] - c, u)) for i in vs]
        order = tuple(vs[i] for i in np.argsort(ang))
        out.append((order, n, h))
    return out


def _triangulations(poly):
    """All triangulations of a convex polygon given as a vertex tuple
    (only 3 and 4 vertices are expected here)."""
    if len(poly) == 3:
        return [[tuple(poly)]]
    if len(poly) == 4:
        a, b, c, d = poly
        return [[(a, b, c), (a, c, d)], [(b, c, d), (b, d, a)]]
    raise ValueError(f"coplanar facet with {len(poly)} vertices: ambiguous triangulation not supported")


def _cone_coords(dirs, tri, e):
    m = np.stack([dirs[i] for i in tri], axis=1)
    try:
        return np.linalg.solve(m, e)
    except np.linalg.LinAlgError:
        return None


class Sphere:
    """Key viewpoint directions and the pieces of the viewing sphere they cover.

    `cells` is a list of facets; each facet is a list of alternative
    triangulations (one for a triangle, two for a square facet)."""

    def __init__(self, directions):
        self.dirs = np.array([unit(d) for d in directions])
        n = len(self.dirs)
        self.enclosed = False
        self.cells = []
        if n >= 4 and np.linalg.matrix_rank(self.dirs - self.dirs[0], tol=1e-9) == 3:
            facets = _facets(self.dirs)
            self.enclosed = all(h > ENCLOSE_EPS for _, _, h in facets)
        if self.enclosed:
            self.cells = [_triangulations(f) for f, _, _ in facets]
        elif n >= 3:
            m = np.vstack([self.dirs, np.zeros(3)])
            if np.linalg.matrix_rank(m - m[-1], tol=1e-9) == 3:
                facets = _facets(self.dirs, extra_origin=True)
                self.cells = [_triangulations(f) for f, _, _ in facets if n not in f]

    # -- weights inside the covered region ---------------------------------

    def cell_weights(self, e):
        """Every distinct barycentric weight vector (len n) for a covered
        direction e (one per triangulation choice of the facet hit), or []
        when e is in no cell."""
        e = unit(e)
        found = []
        for alts in self.cells:
            for tris in alts:
                for tri in tris:
                    lam = _cone_coords(self.dirs, tri, e)
                    if lam is None or lam.min() < -INSIDE_EPS * np.abs(lam).sum() or lam.sum() <= 0:
                        continue
                    b = np.zeros(len(self.dirs))
                    b[list(tri)] = np.clip(lam, 0, None) / np.clip(lam, 0, None).sum()
                    if not any(np.allclose(b, f, atol=1e-12) for f in found):
                        found.append(b)
                    break  # one triangle per triangulation
        return found

    def arc_weights(self, i, j, p):
        """Barycentric weights of a direction p on the arc between keys i, j."""
        m = np.stack([self.dirs[i], self.dirs[j]], axis=1)
        lam, *_ = np.linalg.lstsq(m, p, rcond=None)
        lam = np.clip(lam, 0, None)
        b = np.zeros(len(self.dirs))
        b[[i, j]] = lam / lam.sum()
        return b

    # -- nearest covered direction -----------------------------------------

    def nearest_covered(self, e):
        """(p, d, [barycentric weight vectors at p]) for eye direction e."""
        e = unit(e)
        if self.enclosed:
            return e, 1.0, self.cell_weights(e)
        inside = self.cell_weights(e)
        if inside:
            return e, 1.0, inside
        n = len(self.dirs)
        cands = []  # (dot, p, weights)
        for i in range(n):
            b = np.zeros(n)
            b[i] = 1.0
            cands.append((float(self.dirs[i] @ e), self.dirs[i], [b]))
        for i, j in itertools.combinations(range(n), 2):
            a, c = self.dirs[i], self.dirs[j]
            nrm = np.cross(a, c)
            if np.linalg.norm(nrm) < 1e-12:
                continue
            nrm /= np.linalg.norm(nrm)
            q = e - (e @ nrm) * nrm
            if np.linalg.norm(q) < 1e-12:
                continue
            q /= np.linalg.norm(q)
            lam, *_ = np.linalg.lstsq(np.stack([a, c], axis=1), q, rcond=None)
            if lam.min() >= 0:
                cands.append((float(q @ e), q, [self.arc_weights(i, j, q)]))
        best = max(c[0] for c in cands)
        # every candidate attaining the best dot gives the same p when d > 0
        top = [c for c in cands if c[0] >= best - 1e-12]
        dot, p, ws = top[0]
        if len(self.cells):
            # p on a cell's boundary: weights from the cells (same values)
            cw = self.cell_weights(p)
            if cw:
                ws = cw
        return p, float(np.clip(dot, -1.0, 1.0)), ws


def classify_eye(sphere, e):
    """Which case of the cosine rule an eye direction falls in: "inside" the
    covered region, nearest covered direction a "key" or a point inside an
    "arc", or "behind" (d <= 0: exactly the base model)."""
    p, d, _ = sphere.nearest_covered(e)
    if d <= 0:
        return "behind"
    if d >= 1 - 1e-12:
        return "inside"
    if min(np.linalg.norm(p - k) for k in sphere.dirs) < 1e-9:
        return "key"
    return "arc"


def cosine_blend(sphere, eye, alpha, base, offsets):
    """Every candidate result (one per triangulation choice) of the cosine
    rule: max(0,d)*blend(p) + (1-max(0,d))*base = base + max(0,d)*sum w_i offset_i."""
    p, d, ws = sphere.nearest_covered(eye)
    out = []
    for b in ws:
        w = sharpen(b, alpha)
        acc = base.copy()
        for i, wi in enumerate(w):
            if wi > 0:
                acc = acc + max(0.0, d) * wi * offsets[i]
        out.append(acc)
    return out


def covered_weights(sphere, eye, alpha):
    """Sharpened weights (list of alternatives) for an enclosed sphere."""
    return [sharpen(b, alpha) for b in sphere.cell_weights(eye)]


# ---------------------------------------------------------------------------
# time


def spline_offsets(times, offsets, t):
    """Natural cubic spline through (times, offsets) at t, held constant
    outside [times[0], times[-1]]; one time = constant."""
    times = np.asarray(times, dtype=np.float64)
    offs = np.asarray(offsets, dtype=np.float64)
    order = np.argsort(times)
    times, offs = times[order], offs[order]
    if len(times) == 1:
        return offs[0]
    tc = min(max(t, times[0]), times[-1])
    cs = CubicSpline(times, offs.reshape(len(times), -1), bc_type="natural", axis=0)
    return cs(tc).reshape(offs.shape[1:])


# ---------------------------------------------------------------------------
# reading the stage


def gf_np(m):
    return np.array(m, dtype=np.float64).reshape(4, 4)


def _is_skinned(mesh_prim):
    b = UsdSkel.BindingAPI(mesh_prim)
    if not b.GetSkeletonRel().GetTargets():
        # inherited binding
        p = mesh_prim.GetParent()
        while p and not p.IsPseudoRoot():
            if UsdSkel.BindingAPI(p).GetSkeletonRel().GetTargets():
                return True
            p = p.GetParent()
        return False
    return True


class BaseModel:
    """base(t) of a mesh in its local space, as usd-core evaluates it."""

    def __init__(self, path, mesh_path, frames):
        self.stage = Usd.Stage.Open(str(path))
        self.prim = self.stage.GetPrimAtPath(mesh_path)
        self.mesh = UsdGeom.Mesh(self.prim)
        self.skinned = _is_skinned(self.prim)
        self.cache = {}
        if self.skinned:
            import authoring as Au
            extra = sorted(set(float(f) for f in frames))
            world = Au.usdcore_world_points(path, [mesh_path], extra)[mesh_path]
            for t, w in world.items():
                m = gf_np(UsdGeom.Xformable(self.prim).ComputeLocalToWorldTransform(t))
                inv = np.linalg.inv(m)
                self.cache[t] = w @ inv[:3, :3] + inv[3, :3]

    def at(self, t):
        t = float(t)
        if t in self.cache:
            return self.cache[t]
        if self.skinned:
            raise KeyError(f"skinned base not evaluated at {t}; pass it in frames")
        return np.array(self.mesh.GetPointsAttr().Get(t), dtype=np.float64)

    def rest(self):
        rt = self.prim.GetAttribute("painterly:restTime")
        if rt and rt.HasAuthoredValue():
            return np.array(self.mesh.GetPointsAttr().Get(rt.Get()), dtype=np.float64)
        return np.array(self.mesh.GetPointsAttr().Get(Usd.TimeCode.Default()), dtype=np.float64)


class Viewpoint:
    def __init__(self, direction):
        self.direction = unit(direction)
        self.keys = []  # (time or None, points)

    def offset(self, base, t):
        timed = [k for k in self.keys if k[0] is not None]
        if not timed:
            return self.keys[0][1] - base.rest()
        times = [k[0] for k in timed]
        offs = [k[1] - base.at(k[0]) for k in timed]
        return spline_offsets(times, offs, t)


def read_viewpoints(stage, mesh_path):
    prim = stage.GetPrimAtPath(mesh_path)
    vps = []
    by_token = {}
    for c in prim.GetChildren():
        if c.GetTypeName() != VIEW_KEY:
            continue
        d = np.array(c.GetAttribute("direction").Get(), dtype=np.float64)
        pts = np.array(c.GetAttribute("points").Get(), dtype=np.float64)
        ta = c.GetAttribute("time")
        t = float(ta.Get()) if ta and ta.HasAuthoredValue() else None
        va = c.GetAttribute("viewpoint")
        tok = va.Get() if va and va.HasAuthoredValue() else None
        target = None
        if tok is not None and tok in by_token:
            target = by_token[tok]
        else:
            for vp in vps:
                if np.arccos(np.clip(vp.direction @ unit(d), -1, 1)) < SAME_DIR:
                    target = vp
                    break
        if target is None:
            target = Viewpoint(d)
            vps.append(target)
        if tok is not None:
            by_token[tok] = target
        target.keys.append((t, pts))
    return vps


def camera_local(stage, mesh_prim, camera_path, t):
    cam = stage.GetPrimAtPath(camera_path)
    cw = gf_np(UsdGeom.Xformable(cam).ComputeLocalToWorldTransform(t))[3, :3]
    m = gf_np(UsdGeom.Xformable(mesh_prim).ComputeLocalToWorldTransform(t))
    inv = np.linalg.inv(m)
    return cw @ inv[:3, :3] + inv[3, :3]


def eye_direction(stage, mesh_prim, camera_path, base_pts, t):
    centre = 0.5 * (base_pts.min(axis=0) + base_pts.max(axis=0))
    return unit(camera_local(stage, mesh_prim, camera_path, t) - centre)


def reference_bake(path, mesh_path, frames, camera=None):
    """{t: [candidate mesh-local points]} for a view-dependent mesh; more
    than one candidate only where a square hull facet may be split either
    way. Raises NotImplementedError for uncovered "base" mode at uncovered
    eye directions."""
    base = BaseModel(path, mesh_path, list(frames) + _key_times(path, mesh_path))
    stage = base.stage
    prim = base.prim
    vps = read_viewpoints(stage, mesh_path)
    sphere = Sphere([vp.direction for vp in vps])
    unc = prim.GetAttribute("painterly:uncovered")
    mode = unc.Get() if unc and unc.HasAuthoredValue() else "cosine"
    if camera is None:
        camera = str(prim.GetRelationship("painterly:camera").GetTargets()[0])
    out = {}
    for t in frames:
        sa = prim.GetAttribute("painterly:sharpness")
        alpha = float(sa.Get(t)) if sa and sa.HasAuthoredValue() else 1.0
        b = base.at(t)
        e = eye_direction(stage, prim, camera, b, t)
        offs = [vp.offset(base, t) for vp in vps]
        if sphere.enclosed:
            out[t] = [b + sum(w[i] * offs[i] for i in range(len(vps)) if w[i] > 0)
                      for w in covered_weights(sphere, e, alpha)]
        elif mode == "cosine":
            out[t] = cosine_blend(sphere, e, alpha, b, offs)
        else:
            inside = sphere.cell_weights(e) if sphere.cells else []
            if not inside:
                raise NotImplementedError("uncovered 'base' mode outside the covered region")
            out[t] = [b + sum(w[i] * offs[i] for i in range(len(vps)) if w[i] > 0)
                      for w in (sharpen(x, alpha) for x in inside)]
    return out


def _key_times(path, mesh_path):
    stage = Usd.Stage.Open(str(path))
    prim = stage.GetPrimAtPath(mesh_path)
    ts = []
    for c in prim.GetChildren():
        if c.GetTypeName() == VIEW_KEY:
            ta = c.GetAttribute("time")
            if ta and ta.HasAuthoredValue():
                ts.append(float(ta.Get()))
    return ts


def view_meshes(stage):
    return [p for p in stage.Traverse() if VIEW_API in p.GetPrimTypeInfo().GetAppliedAPISchemas()]


# ---------------------------------------------------------------------------
# authoring small view-dependent stages for the tests (usd-core)


def ball_mesh(n_rings=6, n_around=8, radius=1.0, squash=(1.0, 0.8, 0.9)):
    """A closed lat-long ball: poles plus rings of quads, triangle fans at
    the poles. Returns (points (N,3), counts, indices)."""
    pts = [(0.0, radius * squash[1], 0.0)]
    for r in range(1, n_rings):
        th = np.pi * r / n_rings
        for s in range(n_around):
            ph = 2 * np.pi * s / n_around
            pts.append((radius * squash[0] * np.sin(th) * np.cos(ph),
                        radius * squash[1] * np.cos(th),
                        radius * squash[2] * np.sin(th) * np.sin(ph)))
    pts.append((0.0, -radius * squash[1], 0.0))
    last = len(pts) - 1
    counts, idx = [], []

    def ring(r, s):
        return 1 + (r - 1) * n_around + (s % n_around)
    for s in range(n_around):
        counts.append(3)
        idx += [0, ring(1, s + 1), ring(1, s)]
    for r in range(1, n_rings - 1):
        for s in range(n_around):
            counts.append(4)
            idx += [ring(r, s), ring(r, s + 1), ring(r + 1, s + 1), ring(r + 1, s)]
    for s in range(n_around):
        counts.append(3)
        idx += [last, ring(n_rings - 1, s), ring(n_rings - 1, s + 1)]
    return np.array(pts, dtype=np.float64), counts, idx


def smooth_offsets(points, rng, scale=0.25):
    """A smooth random offset field over the points (a few Gaussian bumps)."""
    p = np.asarray(points, dtype=np.float64)
    out = np.zeros_like(p)
    for _ in range(3):
        c = p[rng.integers(len(p))]
        v = rng.normal(size=3)
        v *= scale / np.linalg.norm(v)
        w = np.exp(-np.sum((p - c) ** 2, axis=1) / 0.5)
        out += w[:, None] * v
    return out


def orbit_eyes(n, *, turns=1.0, tilt=0.0, wobble=0.0, phase=0.0):
    """n unit eye directions going round the Y axis, with an optional tilt
    (radians) and an up/down wobble (radians amplitude, 3 cycles a turn)."""
    out = []
    for i in range(n):
        u = i / max(n - 1, 1)
        az = phase + 2 * np.pi * turns * u
        el = tilt + wobble * np.sin(6 * np.pi * turns * u)
        out.append(np.array([np.cos(el) * np.cos(az), np.sin(el), np.cos(el) * np.sin(az)]))
    return out


def define_camera(stage, path, world_positions, frames):
    """A UsdGeom.Camera whose translate is sampled at the given frames."""
    cam = UsdGeom.Camera.Define(stage, path)
    op = cam.AddTranslateOp()
    for t, p in zip(frames, world_positions):
        op.Set(Gf.Vec3d(*map(float, p)), float(t))
    return cam


def apply_view_api(prim, *, sharpness=None, uncovered=None, camera=None, rest_time=None):
    prim.AddAppliedSchema(VIEW_API)
    if sharpness is not None:
        a = prim.CreateAttribute("painterly:sharpness", Sdf.ValueTypeNames.Float, custom=False)
        if isinstance(sharpness, dict):
            for t, v in sharpness.items():
                a.Set(float(v), float(t))
        else:
            a.Set(float(sharpness))
    if uncovered is not None:
        prim.CreateAttribute("painterly:uncovered", Sdf.ValueTypeNames.Token, custom=False,
                             variability=Sdf.VariabilityUniform).Set(uncovered)
    if camera is not None:
        prim.CreateRelationship("painterly:camera", custom=False).SetTargets([Sdf.Path(camera)])
    if rest_time is not None:
        prim.CreateAttribute("painterly:restTime", Sdf.ValueTypeNames.Double, custom=False,
                             variability=Sdf.VariabilityUniform).Set(float(rest_time))


def add_view_key(stage, mesh_path, name, points, direction, time=None, viewpoint=None):
    prim = stage.DefinePrim(f"{mesh_path}/{name}", VIEW_KEY)
    U = Sdf.VariabilityUniform
    prim.CreateAttribute("points", Sdf.ValueTypeNames.Point3fArray, custom=False, variability=U).Set(
        Vt.Vec3fArray([Gf.Vec3f(*map(float, p)) for p in np.asarray(points).reshape(-1, 3)]))
    prim.CreateAttribute("direction", Sdf.ValueTypeNames.Float3, custom=False, variability=U).Set(
        Gf.Vec3f(*map(float, direction)))
    if time is not None:
        prim.CreateAttribute("time", Sdf.ValueTypeNames.Double, custom=False, variability=U).Set(float(time))
    if viewpoint is not None:
        prim.CreateAttribute("viewpoint", Sdf.ValueTypeNames.Token, custom=False, variability=U).Set(viewpoint)
    return prim


def f32(a):
    return np.asarray(a, dtype=np.float32).astype(np.float64)


class ViewStage:
    """What build_view_stage wrote: file, mesh path, frames, base (rest)
    points, keys [(name, unit direction, points, time, token)], mesh
    local-to-world (static), camera path(s)."""

    def __init__(self, **kw):
        self.__dict__.update(kw)

    def offsets(self):
        return [k[2] - self.rest for k in self.keys]


def build_view_stage(path, *, keys, eyes, base_points=None, sampled=None, default_points=True,
                     sharpness=None, uncovered=None, rest_time=None, camera_rel="/World/Camera",
                     cameras=("/World/Camera",), camera_eyes=None, radius=6.0, mesh_xform=True,
                     seed=0, key_scale=0.25, start=1):
    """A ball Mesh /World/Thing/Ball (under a transformed Xform) with
    PainterlyViewDependentAPI and keys, plus camera(s) whose translate at
    frame start+i puts the camera at centre(t) + radius * eyes[i] in the
    mesh's local space (centre = bbox centre of the points at t).

    keys: list of (direction, points-or-None, time-or-None, token-or-None);
    None points get base + a smooth random offset. sampled: {t: points}
    authors time samples on the mesh points. camera_eyes: {camera path:
    eyes} for extra cameras (default: every camera uses `eyes`)."""
    import authoring as Au
    stage = Usd.Stage.CreateNew(str(path))
    frames = [float(start + i) for i in range(len(eyes))]
    Au.set_stage_metadata(stage, frames[0], frames[-1])
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    thing = UsdGeom.Xform.Define(stage, "/World/Thing")
    if mesh_xform:
        Au.xf_static((1.0, 2.0, -0.5), (10.0, 30.0, -5.0), (1.5, 1.2, 1.5))(thing)
    if base_points is None:
        base_points, counts, idx = ball_mesh()
    else:
        _, counts, idx = ball_mesh()
    base_points = f32(base_points)
    mesh_path = "/World/Thing/Ball"
    mesh = UsdGeom.Mesh.Define(stage, mesh_path)
    mesh.CreateFaceVertexCountsAttr(counts)
    mesh.CreateFaceVertexIndicesAttr(idx)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    pa = mesh.CreatePointsAttr()
    if default_points:
        pa.Set(Au.v3f(base_points))
    for t, p in (sampled or {}).items():
        pa.Set(Au.v3f(p), float(t))
    apply_view_api(mesh.GetPrim(), sharpness=sharpness, uncovered=uncovered, camera=camera_rel,
                   rest_time=rest_time)
    rng = np.random.default_rng(seed)
    written = []
    for i, (d, pts, t, tok) in enumerate(keys):
        if pts is None:
            pts = base_points + smooth_offsets(base_points, rng, key_scale)
        pts = f32(pts)
        name = f"Key{i}"
        add_view_key(stage, mesh_path, name, pts, d, time=t, viewpoint=tok)
        written.append((name, unit(f32(d)), pts, t, tok))
    m = gf_np(UsdGeom.Xformable(mesh.GetPrim()).ComputeLocalToWorldTransform(0))
    camera_eyes = camera_eyes or {}
    for cam in cameras:
        es = camera_eyes.get(cam, eyes)
        pos = []
        for t, e in zip(frames, es):
            pts_t = np.array(pa.Get(t), dtype=np.float64)
            c = 0.5 * (pts_t.min(axis=0) + pts_t.max(axis=0))
            local = c + radius * unit(e)
            pos.append(local @ m[:3, :3] + m[3, :3])
        define_camera(stage, cam, pos, frames)
    stage.GetRootLayer().Save()
    return ViewStage(path=path, mesh=mesh_path, frames=frames, rest=base_points, keys=written,
                     m=m, eyes=[unit(e) for e in eyes], counts=counts, indices=idx)
