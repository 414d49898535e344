"""SPEC 1.1 section 3: ties in the closest-point binding go to the lowest
triangle index (issue 9 section 3).

Meshes converted from glTF/FBX split their vertices along texture seams:
both sides of a seam sit at the same positions under different indices, so
a stroke point on or above the seam is equally close to triangles of both
sides. The input here is written by usd-core: a sheet split down a seam
column, its faces in shuffled order (so the lowest triangle is sometimes on
one side, sometimes on the other), animated non-rigidly (the two sides'
one-rings differ, so the side a point binds to shows in the bake). The
binding `painterly bind` caches and the bake (binding on the fly) are
compared with reference_skinning.py, which implements the tie rule; the
other tie choice (highest index) is shown to give different vertices and a
different bake, so the test can tell the rules apart.
"""

import numpy as np
from pxr import Usd, UsdGeom, Vt

import authoring as Au
import reference_skinning as RS
from test_bake_skinning import check_strokes, run_bake

N, SIZE, SEAM = 8, 4.0, 4  # grid cells per side, side length, seam column
FRAMES = Au.frame_list(1, 8, 0.5)


def seam_sheet(rng):
    """An N x N quad grid in the XZ plane; the vertices of column SEAM are
    duplicated and the faces right of the seam use the copies. Returns
    (points, counts, indices, copies: {original: copy})."""
    w = N + 1
    pts = [(SIZE * i / N, 0.0, SIZE * j / N) for j in range(w) for i in range(w)]
    copies = {}
    for j in range(w):
        copies[j * w + SEAM] = len(pts)
        pts.append(pts[j * w + SEAM])
    faces = []
    for j in range(N):
        for i in range(N):
            quad = [j * w + i, j * w + i + 1, (j + 1) * w + i + 1, (j + 1) * w + i]
            if i >= SEAM:
                quad = [copies.get(v, v) for v in quad]
            faces.append(quad)
    faces = [faces[k] for k in rng.permutation(len(faces))]
    return np.array(pts, dtype=np.float64), [4] * len(faces), [v for f in faces for v in f], copies


def seam_strokes(rng):
    """Strokes along the seam (x = SIZE/2) on, above and below the sheet,
    some through grid vertices, and a few random ones across the sheet."""
    x = SIZE * SEAM / N
    strokes = []
    for off in (0.0, 0.04, -0.07, 0.3):
        for z0 in rng.uniform(0.1, SIZE - 0.6, size=3):
            strokes.append([(x, off, z0 + 0.15 * k) for k in range(4)])
        strokes.append([(x, off, SIZE * j / N) for j in (1, 3, 5)])  # through seam vertices
    for _ in range(4):
        p0 = rng.uniform(0.2, SIZE - 0.2, size=2)
        strokes.append([(p0[0] + 0.1 * k, rng.uniform(-0.05, 0.05), p0[1] + 0.05 * k) for k in range(3)])
    return [len(s) for s in strokes], np.array([p for s in strokes for p in s], dtype=np.float64)


def build_seam_rig(path, seed=4):
    rng = np.random.default_rng(seed)
    stage = Usd.Stage.CreateNew(str(path))
    Au.set_stage_metadata(stage, 1, 8)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    pts, counts, idx, copies = seam_sheet(rng)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Sheet")
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray(counts))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray(idx))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    pa = mesh.CreatePointsAttr()
    pa.Set(Au.v3f(pts))
    for t in (1.0, 4.5, 8.0):
        pa.Set(Au.v3f(Au.sheet_deform(pts, (t - 1) / 7)), t)
    sc, sp = seam_strokes(rng)
    Au.add_painterly_rig(stage, "/World/Paint", mesh.GetPath())
    Au.add_stroke_layer(stage, "/World/Paint/Strokes", sc, sp)
    stage.GetRootLayer().Save()
    rest = np.array(Au.v3f(pts), dtype=np.float64)
    rig = Au.Rig(path, str(mesh.GetPath()), "/World/Paint", ["/World/Paint/Strokes"], FRAMES, rest)
    return rig, copies


def highest_index_binding(rest, tris, points):
    """The binding with the other tie rule: the highest tied triangle."""
    A, B, C = rest[tris[:, 0]], rest[tris[:, 1]], rest[tris[:, 2]]
    d2, bary = RS.closest_on_triangles(points, A, B, C)
    d = np.sqrt(np.maximum(d2, 0.0))
    tied = d <= d.min(axis=1, keepdims=True) + RS.tie_tolerance(rest)
    best = tied.shape[1] - 1 - np.argmax(tied[:, ::-1], axis=1)
    return tris[best], bary[np.arange(len(best)), best]


def reference(rig):
    stage, rigs = RS.describe(rig.path)
    layer = rigs[0]["layers"][0]
    tris = rigs[0]["topo"].tris
    return layer, tris, highest_index_binding(rig.rest, tris, layer["rest"])


def test_the_rig_has_seam_ties_both_ways(tmp_path):
    """Sanity of the input: many points tie across the seam, and the lowest
    tied triangle lies on either side for different points."""
    rig, copies = build_seam_rig(tmp_path / "seam.usda")
    layer, _, (hv, _) = reference(rig)
    lv = layer["verts"]
    differ = (lv != hv).any(axis=1)
    assert differ.sum() >= 20, f"only {differ.sum()} points tie across the seam"
    dup = set(copies.values())
    low_on_copies = np.array([any(v in dup for v in row) for row in lv])
    assert (differ & low_on_copies).any() and (differ & ~low_on_copies).any(), \
        "the lowest tied triangle is always on the same side of the seam"


def test_bind_caches_the_lowest_tied_triangle(painterly, tmp_path):
    rig, _ = build_seam_rig(tmp_path / "seam.usda")
    layer, _, (hv, _) = reference(rig)
    edits = tmp_path / "edits.usda"
    painterly("bind", rig.path, "--edit-layer", edits, "--quiet")
    st = Usd.Stage.Open(str(edits))
    prim = st.GetPrimAtPath(rig.layers[0])
    verts = np.array(prim.GetAttribute("painterly:bindVertices").Get(), dtype=np.int64)
    weights = np.array(prim.GetAttribute("painterly:bindWeights").Get(), dtype=np.float64)
    bad = np.nonzero((verts != layer["verts"]).any(axis=1))[0]
    assert len(bad) == 0, (f"{len(bad)} of {len(verts)} points bound to other triangles than the lowest tied one, "
                           f"e.g. point {bad[0]}: {verts[bad[0]].tolist()} vs {layer['verts'][bad[0]].tolist()} "
                           f"(highest: {hv[bad[0]].tolist()})")
    np.testing.assert_allclose(weights, layer["weights"], atol=1e-6)


def test_bake_binds_seam_points_to_the_lowest_tied_triangle(painterly, tmp_path):
    """The bake, binding on the fly, follows the tie rule; the other rule's
    binding would move the seam points measurably differently."""
    rig, _ = build_seam_rig(tmp_path / "seam.usda")
    out = run_bake(painterly, rig, tmp_path, frames_arg="1:8:0.5")
    posed = Au.usdcore_world_points(rig.path, [rig.mesh], FRAMES)
    check_strokes(rig, out, FRAMES, posed=posed)

    _, _, other = reference(rig)
    want = RS.expected_strokes(rig.path, FRAMES, posed_world=posed)[rig.layers[0]]
    wrong = RS.expected_strokes(rig.path, FRAMES, posed_world=posed,
                                override_binding={rig.layers[0]: other})[rig.layers[0]]
    diag = Au.bbox_diag(rig.rest)
    gap = max(float(np.linalg.norm(want[t] - wrong[t], axis=1).max()) for t in FRAMES) / diag
    assert gap > 1e-3, f"the two tie rules bake within {gap:.3g} x diagonal: the test cannot tell them apart"


def far_tilted_sheet(path):
    """A flat 2 x 2 sheet of 800 triangles turned off every axis, and
    stroke points 1e2 to 1e3 units off it along its normal, above and
    below. So far off, several triangles around the foot of each point tie
    within the tolerance (distances differ by x^2 / 2r for an offset x
    along the sheet). Returns (rest points, stroke points)."""
    n = 20
    grid = np.array([(0.1 * i, 0.1 * j, 0.0) for j in range(n + 1) for i in range(n + 1)])
    axis = np.array([0.63, 0.45, 0.52])
    axis /= np.linalg.norm(axis)
    angle = 1.09
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rot = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * (k @ k)  # Rodrigues
    rest = grid @ rot.T
    normal = rot[:, 2]
    feet = [rot @ np.array([0.05 + 0.15 * i, 0.07 + 0.12 * i, 0.0]) for i in range(12)]
    strokes = [[f + s * r * normal for f in feet[i::3]] for i in range(3)
               for r in (1e2, 5e2, 1e3) for s in (1.0, -1.0)]
    stage = Usd.Stage.CreateNew(str(path))
    Au.set_stage_metadata(stage, 1, 1)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    mesh = UsdGeom.Mesh.Define(stage, "/World/Sheet")
    quads = [[j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i]
             for j in range(n) for i in range(n)]
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([4] * len(quads)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray([v for q in quads for v in q]))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreatePointsAttr().Set(Au.v3f(rest))
    Au.add_painterly_rig(stage, "/World/Paint", mesh.GetPath())
    pts = np.array([p for s in strokes for p in s])
    Au.add_stroke_layer(stage, "/World/Paint/Strokes", [len(s) for s in strokes], pts)
    stage.GetRootLayer().Save()
    # What USD stores (f32), as both sides read it.
    return np.array(Au.v3f(rest), dtype=np.float64), np.array(Au.v3f(pts), dtype=np.float64)


def test_bind_far_from_a_tilted_sheet_keeps_the_lowest_tie(painterly, tmp_path):
    """Points far from their proxy still bind by the tie rule. Rounding a
    plane to f32 moves its value at a point in proportion to the point's
    distance from the origin; the search once pruned lower-indexed ties
    there (14 of these 72 points bound to another triangle)."""
    path = tmp_path / "far.usda"
    rest, pts = far_tilted_sheet(path)
    stage, rigs = RS.describe(str(path))
    tris = rigs[0]["topo"].tris
    want_v, want_w = RS.bind(rest, tris, pts)
    # Sanity: real ties (several triangles within the tolerance), none of
    # them near its edge, where rounding could decide either way.
    A, B, C = rest[tris[:, 0]], rest[tris[:, 1]], rest[tris[:, 2]]
    d = np.sqrt(np.maximum(RS.closest_on_triangles(pts, A, B, C)[0], 0.0))
    edge = d.min(axis=1, keepdims=True) + RS.tie_tolerance(rest)
    assert ((d <= edge).sum(axis=1) >= 2).sum() >= 24, "too few points with tied triangles"
    assert (np.abs(d - edge) > 1e-12 * np.linalg.norm(pts, axis=1, keepdims=True)).all()

    edits = tmp_path / "edits.usda"
    painterly("bind", path, "--edit-layer", edits, "--quiet")
    edited = Usd.Stage.Open(str(edits))
    prim = edited.GetPrimAtPath("/World/Paint/Strokes")
    verts = np.array(prim.GetAttribute("painterly:bindVertices").Get(), dtype=np.int64)
    weights = np.array(prim.GetAttribute("painterly:bindWeights").Get(), dtype=np.float64)
    bad = np.nonzero((verts != want_v).any(axis=1))[0]
    assert len(bad) == 0, (f"{len(bad)} of {len(pts)} points bound to another triangle than the lowest tied one, "
                           f"e.g. point {bad[0]}: {verts[bad[0]].tolist()} vs {want_v[bad[0]].tolist()}")
    np.testing.assert_allclose(weights, want_w, atol=1e-6)
