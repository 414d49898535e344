"""SPEC sections 6-7: view-dependent geometry (Rademacher 1999 sections 3-4).

Every baked vertex is checked against reference_view.py (scipy ConvexHull,
numpy barycentrics, the section 3.3 cosine rule, scipy's natural cubic
spline) to within 1e-5 x the mesh's bounding-box diagonal:
- covered hulls: octahedron (6 keys), cube corners (8, square facets may be
  split either way), irregular random hulls (5-7 keys), alpha in {1, 3};
  eyes on an orbit that bobs across hull edges, exactly at key directions
  (the key deformation itself), at edge midpoints and face centroids;
- uncovered "cosine": a single key (SPEC 1.1's max(0,d)*deformed +
  (1 - max(0,d))*base, exactly the base for d < 0) and keys all on one side (an arc,
  a triangle, a cap of five) with the nearest-covered-direction rule;
- uncovered "base": invariants (keys reproduced, blend of at most three
  keys with weights in [0, 1], the base model opposite a single key,
  monotone fall-off, plain hull blend inside the covered region);
- continuity along fine camera paths;
- animated bases: time-sampled points (untimed keys offset from the rest
  pose, painterly:restTime), timed keys at 2-3 times (natural spline vs
  scipy, held outside the key times), a UsdSkel base (skel:skeleton blocked);
- --camera versus rel painterly:camera, time-sampled sharpness, the bake
  layer's points/extent samples, and the committed fixtures.
"""

import json
import pathlib

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdSkel
from scipy.interpolate import CubicSpline
from scipy.spatial import ConvexHull

import authoring as Au
import reference_view as RV

REPO = pathlib.Path(__file__).resolve().parent.parent
TOL = 1e-5  # x bbox diagonal

OCTAHEDRON = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
CUBE = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]


def irregular(n, seed):
    """n random directions whose hull encloses the centre with a margin."""
    rng = np.random.default_rng(seed)
    while True:
        d = rng.normal(size=(n, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        h = ConvexHull(d)
        if (-h.equations[:, 3]).min() > 0.08:
            return [tuple(map(float, x)) for x in d]


DIRECTION_SETS = {
    "octahedron": OCTAHEDRON,
    "cube": CUBE,
    "irregular5": irregular(5, 11),
    "irregular6": irregular(6, 12),
    "irregular7": irregular(7, 13),
}


def hull_probe_eyes(dirs):
    """Key directions, hull edge midpoints and face centroids."""
    u = np.array([RV.unit(RV.f32(d)) for d in dirs])
    h = ConvexHull(u)
    eyes = [x for x in u]
    edges = set()
    for s in h.simplices:
        eyes.append(RV.unit(u[s].mean(axis=0)))
        for a, b in ((s[0], s[1]), (s[1], s[2]), (s[0], s[2])):
            edges.add((min(a, b), max(a, b)))
    for a, b in sorted(edges):
        eyes.append(RV.unit(u[a] + u[b]))
    return eyes


# ---------------------------------------------------------------------------
# helpers


def bake(painterly, vs, tmp_path, *extra, name="bake.usda"):
    out = tmp_path / name
    painterly("bake", vs.path, "-o", out, "--quiet", *extra)
    return out


def baked_points(vs, out):
    stage = Au.compose(vs.path, out)
    return {t: Au.local_points(stage, vs.mesh, t) for t in vs.frames}


def assert_matches_reference(vs, out, camera=None, frames=None, diag=None):
    got = baked_points(vs, out)
    frames = frames or vs.frames
    ref = RV.reference_bake(vs.path, vs.mesh, frames, camera=camera)
    diag = diag or Au.bbox_diag(vs.rest)
    for t in frames:
        errs = [np.abs(got[t] - c).max() for c in ref[t]]
        assert min(errs) <= TOL * diag, (
            f"t={t}: baked points differ from the reference by {min(errs):.3g} "
            f"(> {TOL * diag:.3g}); candidates {len(errs)}")
    return got


def coefficients(vs, got, base=None):
    """Least-squares c with got - base = sum c_i offset_i (offsets are
    independent random fields) and the residual."""
    base = vs.rest if base is None else base
    A = np.stack([o.reshape(-1) for o in vs.offsets()], axis=1)
    c, *_ = np.linalg.lstsq(A, (got - base).reshape(-1), rcond=None)
    res = np.abs(A @ c - (got - base).reshape(-1)).max()
    return c, res


# ---------------------------------------------------------------------------
# covered hulls


@pytest.mark.parametrize("alpha", [1.0, 3.0])
@pytest.mark.parametrize("setname", list(DIRECTION_SETS))
def test_covered_hull_matches_reference(painterly, tmp_path, setname, alpha):
    dirs = DIRECTION_SETS[setname]
    eyes = RV.orbit_eyes(40, tilt=0.2, wobble=0.9) + hull_probe_eyes(dirs)
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in dirs],
                             eyes=eyes, sharpness=alpha)
    before = Au.file_hash(vs.path)
    out = bake(painterly, vs, tmp_path)
    got = assert_matches_reference(vs, out)
    assert Au.file_hash(vs.path) == before, "input modified"
    diag = Au.bbox_diag(vs.rest)
    # exactly the key deformation when the eye is a key direction
    for i, (name, d, pts, _, _) in enumerate(vs.keys):
        t = vs.frames[40 + i]
        assert np.abs(got[t] - pts).max() <= 1e-6 * diag, f"eye along {name}: not the key deformation"


@pytest.mark.parametrize("alpha", [1.0, 3.0])
def test_edge_midpoints_blend_the_two_edge_keys(painterly, tmp_path, alpha):
    """On a hull edge only its two keys take part, half and half (any alpha)."""
    dirs = DIRECTION_SETS["irregular6"]
    u = np.array([RV.unit(RV.f32(d)) for d in dirs])
    edges = sorted({(min(a, b), max(a, b)) for s in ConvexHull(u).simplices
                    for a, b in ((s[0], s[1]), (s[1], s[2]), (s[0], s[2]))})
    eyes = [RV.unit(u[a] + u[b]) for a, b in edges]
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in dirs],
                             eyes=eyes, sharpness=alpha)
    got = baked_points(vs, bake(painterly, vs, tmp_path))
    offs = vs.offsets()
    diag = Au.bbox_diag(vs.rest)
    for t, (a, b) in zip(vs.frames, edges):
        want = vs.rest + 0.5 * offs[a] + 0.5 * offs[b]
        assert np.abs(got[t] - want).max() <= TOL * diag, f"edge {a}-{b}: not the mean of its keys"


def test_cube_square_facets_split_consistently(painterly, tmp_path):
    """Cube corners: at the centre of a square facet the result is the mean
    of one of its two diagonals (either split is a valid hull)."""
    u = np.array([RV.unit(d) for d in CUBE])
    eyes = [np.array(a, dtype=float) for a in OCTAHEDRON]  # square facet centres
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in CUBE], eyes=eyes)
    got = baked_points(vs, bake(painterly, vs, tmp_path))
    offs = vs.offsets()
    diag = Au.bbox_diag(vs.rest)
    for t, e in zip(vs.frames, eyes):
        face = [i for i in range(8) if u[i] @ e > 0.5]
        assert len(face) == 4
        cands = []
        for a in face:
            for b in face:
                if a < b and u[a] @ u[b] < 0:  # diagonal
                    cands.append(vs.rest + 0.5 * offs[a] + 0.5 * offs[b])
        assert len(cands) == 2
        assert min(np.abs(got[t] - c).max() for c in cands) <= TOL * diag, \
            f"eye {e}: not the mean of a diagonal of the square facet"


@pytest.mark.parametrize("setname,alpha,uncovered", [
    ("irregular7", 1.0, None), ("cube", 3.0, None), ("hemi3", 1.0, "cosine"),
    ("hemi3", 2.0, "base"), ("single", 1.0, "cosine"), ("single", 1.0, "base")])
def test_continuity_along_fine_camera_paths(painterly, tmp_path, setname, alpha, uncovered):
    """Small camera moves give small changes: a 400-step path (0.9 degrees a
    step) bobbing over the whole sphere, crossing vertices and edges."""
    dirs = {"hemi3": HEMI3, "single": [(0.2, 0.3, 1.0)]}.get(setname) or DIRECTION_SETS[setname]
    eyes = RV.orbit_eyes(400, turns=1.0, tilt=0.1, wobble=1.2)
    steps = [np.arccos(np.clip(a @ b, -1, 1)) for a, b in zip(eyes, eyes[1:])]
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in dirs],
                             eyes=eyes, sharpness=alpha, uncovered=uncovered)
    got = baked_points(vs, bake(painterly, vs, tmp_path, name="bake.usdc"))
    max_off = max(np.abs(o).max() for o in vs.offsets())
    base_scale = max(np.abs(vs.rest).max(), max_off)
    for (t0, t1), step in zip(zip(vs.frames, vs.frames[1:]), steps):
        jump = np.abs(got[t1] - got[t0]).max()
        assert jump <= 12.0 * base_scale * step + 1e-6, (
            f"t={t0}->{t1}: points jump {jump:.3g} for a {np.degrees(step):.2f} degree camera move")


# ---------------------------------------------------------------------------
# uncovered regions: cosine


def test_single_key_cosine_formula(painterly, tmp_path):
    """One key: max(0,d)*deformed + (1 - max(0,d))*base, d = key.eye
    (SPEC 1.1 section 6): behind the key (d < 0) exactly the base model,
    bit for bit (SPEC 1.0's max(0,1-d) scaled it up to 2x)."""
    k = RV.unit((0.3, -0.2, 1.0))
    eyes = RV.orbit_eyes(36, turns=1.0, tilt=0.1, wobble=0.5) + [k, -k, RV.unit(np.cross(k, (0, 1, 0)))]
    eyes = [RV.unit(e) for e in eyes]
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(k, None, None, None)], eyes=eyes, uncovered="cosine")
    out = bake(painterly, vs, tmp_path)
    got = assert_matches_reference(vs, out)
    key = vs.keys[0][2]
    kd = vs.keys[0][1]
    diag = Au.bbox_diag(vs.rest)
    seen_negative = False
    for t, e in zip(vs.frames, vs.eyes):
        d = float(kd @ e)
        seen_negative |= d < -0.5
        want = max(0.0, d) * key + (1.0 - max(0.0, d)) * vs.rest
        assert np.abs(got[t] - want).max() <= TOL * diag, f"t={t} d={d:.3f}: not the SPEC 1.1 cosine rule"
        if d < 0:
            assert np.array_equal(got[t], vs.rest.astype(np.float32)), f"t={t} d={d:.3f}: not exactly the base"
    assert seen_negative
    # the three special eyes: the key, its antipode (base), perpendicular (base)
    n = len(vs.frames)
    assert np.abs(got[vs.frames[n - 3]] - key).max() <= 1e-6 * diag
    assert np.array_equal(got[vs.frames[n - 2]], vs.rest.astype(np.float32))
    assert np.abs(got[vs.frames[n - 1]] - vs.rest).max() <= TOL * diag


HEMI2 = [(0.0, 0.2, 1.0), (0.9, 0.1, 0.6)]
HEMI3 = [(0.0, 0.2, 1.0), (0.9, 0.1, 0.6), (0.3, 0.9, 0.5)]
HEMI5 = [(0.0, 0.1, 1.0), (0.8, 0.0, 0.7), (0.3, 0.8, 0.6), (-0.5, 0.5, 0.8), (0.2, 0.25, 1.0)]
HEMIS = {"arc2": HEMI2, "tri3": HEMI3, "cap5": HEMI5}


def one_sided_eyes(dirs):
    """Eyes inside the covered region, just outside each arc and each key,
    and all round the sphere."""
    u = [RV.unit(RV.f32(d)) for d in dirs]
    c = RV.unit(np.sum(u, axis=0))
    eyes = list(RV.orbit_eyes(30, tilt=0.3, wobble=0.8))
    eyes += u + [c, -c]
    for i, a in enumerate(u):
        eyes.append(RV.unit(a + 0.3 * (a - c)))  # beyond a key
        for b in u[i + 1:]:
            m = RV.unit(a + b)
            eyes.append(RV.unit(m + 0.25 * (m - c)))  # beyond an arc
            eyes.append(RV.unit(m + 1.5 * (m - c)))
    return eyes


@pytest.mark.parametrize("alpha", [1.0, 3.0])
@pytest.mark.parametrize("hemi", list(HEMIS))
def test_one_sided_keys_cosine(painterly, tmp_path, hemi, alpha):
    dirs = HEMIS[hemi]
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in dirs],
                             eyes=one_sided_eyes(dirs), sharpness=alpha, uncovered="cosine")
    got = assert_matches_reference(vs, bake(painterly, vs, tmp_path))
    diag = Au.bbox_diag(vs.rest)
    for i, (name, d, pts, _, _) in enumerate(vs.keys):
        t = vs.frames[30 + i]
        assert np.abs(got[t] - pts).max() <= 1e-6 * diag, f"eye along {name}: not the key deformation"
    # the path exercises every case of the nearest-covered-direction rule
    sphere = RV.Sphere([k[1] for k in vs.keys])
    kinds = {RV.classify_eye(sphere, e) for e in vs.eyes}
    want = {"inside", "key", "arc", "behind"} if hemi != "arc2" else {"key", "arc", "behind"}
    assert want <= kinds, f"eye path misses cases: {want - kinds}"


def test_cosine_is_the_default_mode(painterly, tmp_path):
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in HEMI3],
                             eyes=one_sided_eyes(HEMI3))
    assert_matches_reference(vs, bake(painterly, vs, tmp_path))


# ---------------------------------------------------------------------------
# uncovered regions: base (invariants)


@pytest.mark.parametrize("hemi", ["single", "arc2", "tri3", "cap5"])
def test_one_sided_keys_base_mode_invariants(painterly, tmp_path, hemi):
    dirs = [(0.2, 0.3, 1.0)] if hemi == "single" else HEMIS[hemi]
    eyes = one_sided_eyes(dirs)
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in dirs],
                             eyes=eyes, uncovered="base", sharpness=1.5)
    got = baked_points(vs, bake(painterly, vs, tmp_path))
    diag = Au.bbox_diag(vs.rest)
    sphere = RV.Sphere([k[1] for k in vs.keys])
    n_inside = 0
    for t, e in zip(vs.frames, vs.eyes):
        c, res = coefficients(vs, got[t])
        # a blend of at most three keys with the base: weights in [0, 1]
        assert res <= TOL * diag, f"t={t}: result is not base + a blend of key offsets"
        assert c.min() >= -1e-6 and c.max() <= 1 + 1e-6 and c.sum() <= 1 + 1e-6, f"t={t}: weights {c}"
        assert (np.abs(c) > 1e-6).sum() <= 3, f"t={t}: more than three keys blended: {c}"
        # inside the covered region: the plain hull blend
        inside = sphere.cell_weights(e) if sphere.cells else []
        if inside:
            n_inside += 1
            cands = [RV.sharpen(b, 1.5) for b in inside]
            assert min(np.abs(c - w).max() for w in cands) <= 1e-5, f"t={t}: covered eye, weights {c}"
    assert n_inside >= (3 if hemi in ("tri3", "cap5") else 0)
    for i, (name, d, pts, _, _) in enumerate(vs.keys):
        t = vs.frames[30 + i]
        assert np.abs(got[t] - pts).max() <= 1e-6 * diag, f"eye along {name}: not the key deformation"
    if hemi == "single":
        t = vs.frames[32]  # -c = the antipode of the key
        assert np.abs(got[t] - vs.rest).max() <= 1e-6 * diag, "antipode of the single key is not the base"


def test_single_key_base_mode_falls_off_monotonically(painterly, tmp_path):
    """One key, "base": along meridians from the key to its antipode the key's
    weight goes 1 -> 0 without rising, and is 0 once the eye is 90 degrees away."""
    k = RV.unit((0.0, 0.0, 1.0))
    eyes, meridians = [], []
    for az in np.radians([0, 35, 80, 125, 200, 290]):
        side = np.array([np.cos(az), np.sin(az), 0.0])
        ids = []
        for th in np.linspace(0, np.pi, 19):
            ids.append(len(eyes))
            eyes.append(np.cos(th) * k + np.sin(th) * side)
        meridians.append((ids, np.linspace(0, np.pi, 19)))
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(k, None, None, None)], eyes=eyes, uncovered="base")
    got = baked_points(vs, bake(painterly, vs, tmp_path))
    for ids, ths in meridians:
        w = [coefficients(vs, got[vs.frames[i]])[0][0] for i in ids]
        assert w[0] == pytest.approx(1.0, abs=1e-6)
        assert all(b <= a + 1e-6 for a, b in zip(w, w[1:])), f"weight rises along a meridian: {w}"
        for wi, th in zip(w, ths):
            assert -1e-6 <= wi <= 1 + 1e-6
            if th >= np.pi / 2 - 1e-9:
                assert abs(wi) <= 1e-6, f"key weight {wi} at {np.degrees(th):.0f} degrees from the key"


# ---------------------------------------------------------------------------
# camera choice, sharpness over time, the bake layer


def test_bake_camera_overrides_rel(painterly, tmp_path):
    dirs = DIRECTION_SETS["irregular6"]
    eyes_a = RV.orbit_eyes(20, wobble=0.5)
    eyes_b = RV.orbit_eyes(20, tilt=-0.4, phase=2.0, wobble=0.3)
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in dirs], eyes=eyes_a,
                             cameras=("/World/Camera", "/World/Other/CamB"),
                             camera_eyes={"/World/Other/CamB": eyes_b})
    out_rel = bake(painterly, vs, tmp_path, name="rel.usda")
    assert_matches_reference(vs, out_rel)
    out_b = bake(painterly, vs, tmp_path, "--camera", "/World/Other/CamB", name="camb.usda")
    got_b = assert_matches_reference(vs, out_b, camera="/World/Other/CamB")
    got_a = baked_points(vs, out_rel)
    assert max(np.abs(got_a[t] - got_b[t]).max() for t in vs.frames) > 0.01 * Au.bbox_diag(vs.rest)


def test_camera_from_command_line_without_rel(painterly, tmp_path):
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in OCTAHEDRON],
                             eyes=RV.orbit_eyes(12, wobble=0.4), camera_rel=None)
    out = bake(painterly, vs, tmp_path, "--camera", "/World/Camera")
    assert_matches_reference(vs, out, camera="/World/Camera")


def test_time_sampled_sharpness(painterly, tmp_path):
    eyes = RV.orbit_eyes(16, wobble=0.7)
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in OCTAHEDRON],
                             eyes=eyes, sharpness={1: 1.0, 16: 5.0})
    assert_matches_reference(vs, bake(painterly, vs, tmp_path))


def test_bake_layer_points_and_extent(painterly, tmp_path):
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in OCTAHEDRON],
                             eyes=RV.orbit_eyes(10, wobble=0.4))
    out = bake(painterly, vs, tmp_path, "--frames", "2:8:2")
    layer = Sdf.Layer.FindOrOpen(str(out))
    pp = Sdf.Path(vs.mesh).AppendProperty("points")
    ep = Sdf.Path(vs.mesh).AppendProperty("extent")
    assert list(layer.ListTimeSamplesForPath(pp)) == [2.0, 4.0, 6.0, 8.0]
    assert list(layer.ListTimeSamplesForPath(ep)) == [2.0, 4.0, 6.0, 8.0]
    assert layer.GetPrimAtPath(vs.mesh).specifier == Sdf.SpecifierOver
    ref = RV.reference_bake(vs.path, vs.mesh, [2.0, 4.0, 6.0, 8.0])
    diag = Au.bbox_diag(vs.rest)
    for t in (2.0, 4.0, 6.0, 8.0):
        pts = np.array(layer.QueryTimeSample(pp, t), dtype=np.float64)
        ext = np.array(layer.QueryTimeSample(ep, t), dtype=np.float64)
        np.testing.assert_allclose(ext, [pts.min(0), pts.max(0)], atol=1e-6 * diag)
        assert min(np.abs(pts - c).max() for c in ref[t]) <= TOL * diag
    # a static mesh is not skinned: no skel:skeleton opinion
    assert layer.GetRelationshipAtPath(Sdf.Path(vs.mesh).AppendProperty("skel:skeleton")) is None


# ---------------------------------------------------------------------------
# animated base models (Rademacher section 4)


def wobble_points(rest, u):
    p = rest.copy()
    p[:, 0] *= 1 + 0.3 * u
    p[:, 1] += 0.4 * u * np.sin(2 * p[:, 0])
    p[:, 2] += 0.5 * u * p[:, 1] ** 2
    return RV.f32(p)


def sampled_base(sampled, t):
    """USD's linear interpolation of time-sampled points (held outside)."""
    ts = sorted(sampled)
    if t <= ts[0]:
        return sampled[ts[0]]
    if t >= ts[-1]:
        return sampled[ts[-1]]
    for a, b in zip(ts, ts[1:]):
        if a <= t <= b:
            u = (t - a) / (b - a)
            return (1 - u) * sampled[a] + u * sampled[b]


def test_time_sampled_base_untimed_keys(painterly, tmp_path):
    """Untimed keys: offsets from the default points, added to base(t)."""
    rest, _, _ = RV.ball_mesh()
    rest = RV.f32(rest)
    sampled = {1: wobble_points(rest, 0.2), 7: wobble_points(rest, 1.0), 14: wobble_points(rest, -0.5)}
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in DIRECTION_SETS["irregular6"]],
                             eyes=RV.orbit_eyes(16, wobble=0.6), sampled=sampled, sharpness=2.0)
    got = assert_matches_reference(vs, bake(painterly, vs, tmp_path))
    stage = Usd.Stage.Open(str(vs.path))
    pa = UsdGeom.Mesh(stage.GetPrimAtPath(vs.mesh)).GetPointsAttr()
    c, res = coefficients(vs, got[4.0], base=np.array(pa.Get(4.0), dtype=np.float64))
    assert res <= TOL * Au.bbox_diag(vs.rest) and abs(c.sum() - 1) < 1e-5


def test_rest_time_picks_the_rest_pose(painterly, tmp_path):
    """painterly:restTime: untimed offsets are taken from the points at that
    time, not from the (different) default points."""
    rest, _, _ = RV.ball_mesh()
    rest = RV.f32(rest)
    sampled = {1: wobble_points(rest, 0.5), 10: wobble_points(rest, -0.6)}
    keys = [(d, wobble_points(rest, 0.5) + RV.smooth_offsets(rest, np.random.default_rng(i)), None, None)
            for i, d in enumerate(OCTAHEDRON)]
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=keys, eyes=RV.orbit_eyes(10, wobble=0.5),
                             sampled=sampled, rest_time=1.0)
    assert_matches_reference(vs, bake(painterly, vs, tmp_path))
    # and the default-points answer would be far off
    wrong_offsets = [k[2] - vs.rest for k in vs.keys]
    right_offsets = [k[2] - sampled[1] for k in vs.keys]
    diff = max(np.abs(a - b).max() for a, b in zip(wrong_offsets, right_offsets))
    assert diff > 0.05 * Au.bbox_diag(vs.rest)


def point_cache(rest, frames):
    """A usd-core point cache: time samples at every frame, no default."""
    return {t: wobble_points(rest, np.sin(0.4 * t)) + 0.05 * t for t in frames}


def test_point_cache_with_timed_keys(painterly, tmp_path):
    """issue 9 section 4: a base with only time-sampled points (no default,
    no restTime: an Alembic-converted cache) needs no rest pose when every
    key has a time (SPEC section 6: offsets from the base at each key's
    time). It bakes, and matches the reference at every frame."""
    rest, _, _ = RV.ball_mesh()
    rest = RV.f32(rest)
    frames = list(range(1, 17))
    cache = point_cache(rest, frames)
    rng = np.random.default_rng(11)
    keys = [(d, sampled_base(cache, t) + RV.smooth_offsets(rest, rng, 0.3), t, None)
            for d in OCTAHEDRON for t in (4.0, 12.0)]
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=keys, eyes=RV.orbit_eyes(16, wobble=0.5),
                             sampled=cache, default_points=False)
    st = Usd.Stage.Open(str(vs.path))
    assert UsdGeom.Mesh(st.GetPrimAtPath(vs.mesh)).GetPointsAttr().Get(Usd.TimeCode.Default()) is None
    got = assert_matches_reference(vs, bake(painterly, vs, tmp_path))
    assert sorted(got) == [float(t) for t in frames]


def test_point_cache_untimed_key_is_named(painterly, tmp_path):
    """A key without `time` on a point cache would be an offset from a rest
    pose the mesh does not have: an error naming that key (not a proxy or a
    rig the user never made)."""
    rest, _, _ = RV.ball_mesh()
    rest = RV.f32(rest)
    cache = point_cache(rest, range(1, 9))
    keys = [(d, None, 5.0, None) for d in OCTAHEDRON]
    keys[3] = (OCTAHEDRON[3], None, None, None)
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=keys, eyes=RV.orbit_eyes(8),
                             sampled=cache, default_points=False)
    out = tmp_path / "bake.usda"
    proc = painterly("bake", vs.path, "-o", out, "--quiet", check=False)
    assert proc.returncode == 1, proc.stderr
    assert f"{vs.mesh}/Key3.time" in proc.stderr, proc.stderr
    assert "point cache" in proc.stderr and "proxy" not in proc.stderr and "on the rig" not in proc.stderr
    assert not out.exists()


@pytest.mark.parametrize("n_times", [1, 2, 3])
def test_timed_keys_natural_spline(painterly, tmp_path, n_times):
    """Camera fixed on viewpoint A's direction: result = base(t) + offset_A(t)
    with offset_A the natural cubic spline through the key offsets (scipy),
    held outside the key times. Keys are grouped by token (A) and by equal
    direction (B, C, D ... without token)."""
    rest, _, _ = RV.ball_mesh()
    rest = RV.f32(rest)
    sampled = {1: wobble_points(rest, 0.0), 9: wobble_points(rest, 1.0), 20: wobble_points(rest, -0.4)}
    key_times = [5.0, 9.0, 16.0][:n_times] if n_times != 2 else [6.0, 15.0]
    rng = np.random.default_rng(5)
    keys = []
    for vi, d in enumerate(OCTAHEDRON):
        for t in key_times:
            # key points: base(t) + a per-time offset
            keys.append((d, sampled_base(sampled, t) + RV.smooth_offsets(rest, rng, 0.3), t,
                         "A" if vi == 0 else None))
    k0 = RV.unit(OCTAHEDRON[0])
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=keys, eyes=[k0] * 20, sampled=sampled)
    got = assert_matches_reference(vs, bake(painterly, vs, tmp_path))
    stage = Usd.Stage.Open(str(vs.path))
    pa = UsdGeom.Mesh(stage.GetPrimAtPath(vs.mesh)).GetPointsAttr()
    a_keys = [k for k in vs.keys if k[4] == "A"]
    times = np.array([k[3] for k in a_keys])
    offs = np.stack([k[2] - np.array(pa.Get(k[3]), dtype=np.float64) for k in a_keys])
    diag = Au.bbox_diag(vs.rest)
    for t in vs.frames:
        base = np.array(pa.Get(t), dtype=np.float64)
        if len(times) == 1:
            want = offs[0]
        else:
            cs = CubicSpline(times, offs.reshape(len(times), -1), bc_type="natural")
            want = cs(min(max(t, times[0]), times[-1])).reshape(-1, 3)
        assert np.abs((got[t] - base) - want).max() <= TOL * diag, f"t={t}: offset is not the natural spline"
        if t in times:
            k = a_keys[list(times).index(t)]
            assert np.abs(got[t] - k[2]).max() <= TOL * diag, f"t={t}: key time does not give the key"
    if n_times == 3:
        # a cubic, not piecewise linear: differs from linear interpolation mid-segment
        lin = offs[0] + (offs[1] - offs[0]) * (7.0 - times[0]) / (times[1] - times[0])
        base7 = np.array(pa.Get(7.0), dtype=np.float64)
        assert np.abs((got[7.0] - base7) - lin).max() > 1e-3 * diag


def test_timed_keys_orbit_matches_reference(painterly, tmp_path):
    """Timed keys (2-3 times, token or shared direction) on a time-sampled
    base seen from an orbiting camera, with some untimed viewpoints mixed in."""
    rest, _, _ = RV.ball_mesh()
    rest = RV.f32(rest)
    sampled = {1: wobble_points(rest, 0.0), 12: wobble_points(rest, 1.0), 24: wobble_points(rest, -0.4)}
    rng = np.random.default_rng(9)
    keys = []
    for vi, d in enumerate(DIRECTION_SETS["irregular7"]):
        if vi % 3 == 0:
            keys.append((d, rest + RV.smooth_offsets(rest, rng), None, None))
        else:
            for t in ([4.0, 13.0, 20.0] if vi % 3 == 1 else [8.0, 18.0]):
                keys.append((d, wobble_points(rest, 0.5) + RV.smooth_offsets(rest, rng), t,
                             f"vp{vi}" if vi % 2 else None))
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=keys, eyes=RV.orbit_eyes(24, wobble=0.8),
                             sampled=sampled, sharpness=1.5)
    assert_matches_reference(vs, bake(painterly, vs, tmp_path))


def test_skinned_base(painterly, tmp_path):
    """A UsdSkel base (authoring.build_skel_rig): untimed and timed keys,
    compared with usd-core's skinning plus the reference blend;
    skel:skeleton is blocked so viewers do not skin the result again."""
    rig = Au.build_skel_rig(tmp_path / "rig.usda", frames=(1, 12), n_strokes=2)
    stage = Usd.Stage.Open(str(rig.path))
    mesh = stage.GetPrimAtPath(rig.mesh)
    rest = np.array(UsdGeom.Mesh(mesh).GetPointsAttr().Get(), dtype=np.float64)
    RV.apply_view_api(mesh, uncovered="cosine", camera="/World/Camera", sharpness=2.0)
    rng = np.random.default_rng(3)
    dirs = DIRECTION_SETS["irregular5"]
    for i, d in enumerate(dirs):
        if i < 2:
            RV.add_view_key(stage, rig.mesh, f"Key{i}", rest + RV.smooth_offsets(rest, rng, 0.4), d)
        else:
            for t in (3.0, 7.0, 11.0)[: 1 + i % 3]:
                RV.add_view_key(stage, rig.mesh, f"Key{i}_{int(t)}", rest + RV.smooth_offsets(rest, rng, 0.4), d,
                                time=t, viewpoint=f"v{i}")
    frames = Au.frame_list(1, 12)
    m = RV.gf_np(UsdGeom.Xformable(mesh).ComputeLocalToWorldTransform(0))
    centre = np.array([0.0, 2.0, 0.0])
    pos = [(centre + 15.0 * e) @ m[:3, :3] + m[3, :3] for e in RV.orbit_eyes(12, wobble=0.9)]
    RV.define_camera(stage, "/World/Camera", pos, frames)
    stage.GetRootLayer().Save()
    del stage
    out = tmp_path / "bake.usda"
    painterly("bake", rig.path, "-o", out, "--quiet")
    comp = Au.compose(rig.path, out)
    ref = RV.reference_bake(rig.path, rig.mesh, frames)
    diag = Au.bbox_diag(rest)
    for t in frames:
        got = Au.local_points(comp, rig.mesh, t)
        assert min(np.abs(got - c).max() for c in ref[t]) <= TOL * diag, f"t={t}: skinned view mesh differs"
    rel = comp.GetPrimAtPath(rig.mesh).GetRelationship("skel:skeleton")
    assert rel and rel.GetTargets() == [], "skel:skeleton is not blocked on the baked view mesh"
    layer = Sdf.Layer.FindOrOpen(str(out))
    assert layer.GetRelationshipAtPath(Sdf.Path(rig.mesh).AppendProperty("skel:skeleton")) is not None
    # usd-core no longer deforms it
    before = {t: Au.world_points(comp, rig.mesh, t) for t in frames}
    comp.SetEditTarget(comp.GetSessionLayer())
    from pxr import Gf
    UsdSkel.BakeSkinning(comp.Traverse(), Gf.Interval(1, 12))
    for t in frames:
        assert np.abs(Au.world_points(comp, rig.mesh, t) - before[t]).max() <= 1e-6 * diag
    # The view mesh is also the rig's proxy: with --bake-proxy its baked
    # points are still the view-dependent ones, written once.
    assert Usd.Stage.Open(str(rig.path)).GetPrimAtPath(rig.rig).GetRelationship(
        "painterly:proxy").GetTargets() == [Sdf.Path(rig.mesh)]
    out2 = tmp_path / "bake_proxy.usda"
    painterly("bake", rig.path, "-o", out2, "--quiet", "--bake-proxy")
    with_proxy = Sdf.Layer.FindOrOpen(str(out2))
    pts = Sdf.Path(rig.mesh).AppendProperty("points")
    assert with_proxy.ListTimeSamplesForPath(pts) == layer.ListTimeSamplesForPath(pts)
    for t in frames:
        assert np.array_equal(np.array(with_proxy.QueryTimeSample(pts, t)), np.array(layer.QueryTimeSample(pts, t)))
    # Nor are its authored normals baked: skinned, they would contradict
    # the view-dependent points (a proxy that is a view mesh is not baked).
    stage = Usd.Stage.Open(str(rig.path))
    normals = UsdGeom.Mesh(stage.GetPrimAtPath(rig.mesh)).CreateNormalsAttr([(0.0, 1.0, 0.0)] * len(rest))
    normals.SetMetadata("interpolation", UsdGeom.Tokens.vertex)
    stage.GetRootLayer().Save()
    del stage
    out3 = tmp_path / "bake_proxy_normals.usda"
    painterly("bake", rig.path, "-o", out3, "--quiet", "--bake-proxy")
    with_normals = Sdf.Layer.FindOrOpen(str(out3))
    assert with_normals.GetAttributeAtPath(Sdf.Path(rig.mesh).AppendProperty("normals")) is None
    for t in frames:
        assert np.array_equal(np.array(with_normals.QueryTimeSample(pts, t)), np.array(layer.QueryTimeSample(pts, t)))


# ---------------------------------------------------------------------------
# committed fixtures


FIXTURES = {
    "building.usda": ("/Building/Box", 1),
    "head.usda": ("/Head/Face", 8),
    "walk.usda": ("/Walk/Character/Body", 4),
}


@pytest.mark.parametrize("name", list(FIXTURES))
def test_committed_fixture_bakes_and_matches_reference(painterly, tmp_path, name):
    path = REPO / "fixtures" / name
    mesh, n_keys = FIXTURES[name]
    before = Au.file_hash(path)
    rep = painterly("inspect", path, "--json")
    meshes = {m["path"]: m for m in json.loads(rep.stdout)["view_dependent_meshes"]}
    keys = [k for vp in meshes[mesh]["key_viewpoints"] for k in vp["keys"]]
    assert len(keys) == n_keys, f"inspect does not list the {n_keys} keys of {mesh}:\n{rep.stdout}"
    assert all(k.startswith(mesh + "/") for k in keys)
    out = tmp_path / "bake.usdc"
    painterly("bake", path, "-o", out, "--quiet")
    assert Au.file_hash(path) == before, "fixture modified"
    comp = Au.compose(path, out)
    frames = Au.frame_list(comp.GetStartTimeCode(), comp.GetEndTimeCode())
    ref = RV.reference_bake(path, mesh, frames)
    base = RV.BaseModel(path, mesh, frames)
    diag = Au.bbox_diag(base.at(frames[0]))
    moved = 0.0
    for t in frames:
        got = Au.local_points(comp, mesh, t)
        assert min(np.abs(got - c).max() for c in ref[t]) <= TOL * diag, f"{name} t={t}: differs from reference"
        moved = max(moved, np.abs(got - base.at(t)).max())
    assert moved > 0.02 * diag, f"{name}: the view-dependent shape never leaves the base model"
    if name == "walk.usda":
        rel = comp.GetPrimAtPath(mesh).GetRelationship("skel:skeleton")
        assert rel.GetTargets() == []


def test_fixture_generator_is_deterministic(tmp_path):
    import importlib.util
    spec = importlib.util.spec_from_file_location("view_fixtures", REPO / "fixtures" / "view_fixtures.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    mod.write_all(tmp_path / "a")
    for name in FIXTURES:
        assert (tmp_path / "a" / name).read_bytes() == (REPO / "fixtures" / name).read_bytes(), \
            f"fixtures/{name} is stale: rerun fixtures/view_fixtures.py"


def test_a_camera_at_the_centre_sees_the_base_model(painterly, tmp_path):
    """A camera placed at the base's bounding-box centre through the mesh's
    own transform (scale, rotation, translation) lands there only up to the
    rounding of M·M⁻¹: its eye direction is noise, and it must see the base
    model, as a camera exactly at the centre does (docs/choices.md), not a
    key picked by that noise."""
    vs = RV.build_view_stage(tmp_path / "v.usda", keys=[(d, None, None, None) for d in OCTAHEDRON],
                             eyes=[(1.0, 0.0, 0.0), (0.0, 0.6, 0.8)], radius=0.0)
    stage = Usd.Stage.Open(str(vs.path))
    for t in vs.frames:
        local = RV.camera_local(stage, stage.GetPrimAtPath(vs.mesh), "/World/Camera", t)
        c = 0.5 * (vs.rest.min(axis=0) + vs.rest.max(axis=0))
        assert np.linalg.norm(local - c) < 1e-12 * Au.bbox_diag(vs.rest)
    got = baked_points(vs, bake(painterly, vs, tmp_path))
    for t in vs.frames:
        assert np.abs(got[t] - vs.rest).max() < 1e-6, t
