"""A Dog-size synthetic painted character for `scripts/bench`.

Sized like the Dog of Bassett et al. 2013, Table I: 10,095 strokes of 16
points (161,520 points) in 42 stroke layers on a ~5,000-vertex closed proxy
mesh skinned to a 30-joint UsdSkel rig whose every joint rotates over 48
frames. `write_peer` writes the usd-core comparison: one skinned Mesh whose
161,520 points are the strokes' rest points, on the same skeleton and
animation.

    from bench_character import build_character, write_character, write_peer
    dog = build_character()                       # numpy data, seeded
    write_character(dog, "dog.usdc", keys=False)  # the painted character
    write_peer(dog, "peer.usdc")                  # the usd-core mesh

`keys=True` also authors configuration-space pose keys (SPEC section 4):
43 position keys and 19 opacity keys spread over 18 layers, on
`PainterlyAxis` prims of kind "jointRotation" that measure joint rotations
the animation actually reaches.

Everything is deterministic: each part draws from its own seeded numpy
Generator. Only numpy and usd-core are used. The painterly schema is
codeless and need not be loaded: API schemas are applied by name and
schema attributes are created with custom=False and the schema's types and
variability (as fixtures/make_fixtures.py does).

Design space = skeleton space = proxy-local space = stroke-local space (no
transforms anywhere): the dog faces +X, up is +Y, its left side is +Z.
"""

import pathlib

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

N_STROKES = 10_095
POINTS_PER_STROKE = 16
N_LAYERS = 42
FRAMES = (1, 48)
FPS = 24.0
N_POSITION_KEYS = 43
N_OPACITY_KEYS = 19

T = Sdf.ValueTypeNames
UNIFORM = Sdf.VariabilityUniform

CHAR_ROOT = "/Dog"
SKEL_ROOT = "/Dog/Rig"
SKEL_PATH = "/Dog/Rig/Skel"
ANIM_PATH = "/Dog/Rig/Skel/Anim"
PROXY_PATH = "/Dog/Rig/Proxy"
PAINT_PATH = "/Dog/Paint"
PEER_ROOT = "/Peer"
PEER_MESH = "/Peer/Rig/StrokeMesh"


# --------------------------------------------------------------------------
# small helpers
# --------------------------------------------------------------------------

def normalize(v):
    v = np.asarray(v, dtype=np.float64)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0.0, n, 1.0)


def vec3f_array(a):
    return Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32).reshape(-1, 3))


def float_array(a):
    return Vt.FloatArray.FromNumpy(np.ascontiguousarray(a, dtype=np.float32).reshape(-1))


def int_array(a):
    return Vt.IntArray.FromNumpy(np.ascontiguousarray(a, dtype=np.int32).reshape(-1))


def translate_matrix(t):
    return Gf.Matrix4d(1.0).SetTranslate(Gf.Vec3d(*[float(c) for c in t]))


def quat_axis_angle(axis, angle):
    """(w, x, y, z) of the rotation by `angle` (radians) about unit `axis`."""
    axis = normalize(axis)
    return np.array([np.cos(angle / 2.0), *(axis * np.sin(angle / 2.0))])


def quat_mul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw])


def quat_rotvec(q):
    """Rotation vector (axis x angle, radians) of a unit quaternion (w, x, y, z)."""
    q = np.asarray(q, dtype=np.float64)
    if q[0] < 0.0:
        q = -q
    v = q[1:]
    s = np.linalg.norm(v)
    if s < 1e-12:
        return 2.0 * v
    return v / s * (2.0 * np.arctan2(s, q[0]))


# --------------------------------------------------------------------------
# skeleton: 30 joints, rest rotations identity (so a joint's rotation
# relative to its rest rotation is its animated rotation)
# --------------------------------------------------------------------------

X, Y, Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
# name, parent, rest translation in the parent's space, rotation terms
# (axis, amplitude deg, cycles per 48 frames, phase rad, bias deg); a joint's
# rotation is the product of its terms' rotations, first term outermost.
_LEG = {
    # upper, lower, paw: swing about Z (walk cycle: 2 cycles in 48 frames)
    "Front": [(22.0, 0.0), (28.0, -0.9), (24.0, -1.6)],
    "Hind": [(20.0, np.pi), (26.0, np.pi - 0.9), (22.0, np.pi - 1.6)],
}


def _joint_table():
    J = [
        ("Root", None, (0.0, 5.0, 0.0), [(Z, 4.0, 2, 0.0, 0.0), (Y, 5.0, 1, 0.3, 0.0)]),
        ("Spine1", "Root", (1.0, 0.15, 0.0), [(Y, 4.0, 2, 0.5, 0.0), (Z, 3.0, 2, 1.0, 0.0)]),
        ("Spine2", "Spine1", (1.0, 0.1, 0.0), [(Y, 5.0, 2, 1.0, 0.0), (Z, 3.0, 2, 1.5, 0.0)]),
        ("Spine3", "Spine2", (1.0, 0.0, 0.0), [(Y, 5.0, 2, 1.5, 0.0), (Z, 3.0, 2, 2.0, 0.0)]),
        ("Chest", "Spine3", (0.9, 0.0, 0.0), [(Y, 4.0, 2, 2.0, 0.0), (Z, 4.0, 2, 2.5, 0.0),
                                               (X, 3.0, 2, 0.0, 0.0)]),
        ("Neck1", "Chest", (0.7, 0.6, 0.0), [(Z, 8.0, 1, 0.0, 0.0), (Y, 10.0, 1, 0.8, 0.0)]),
        ("Neck2", "Neck1", (0.5, 0.6, 0.0), [(Z, 8.0, 1, 0.4, 0.0), (Y, 10.0, 1, 1.2, 0.0)]),
        ("Head", "Neck2", (0.4, 0.4, 0.0), [(Z, 12.0, 1, 0.8, 0.0), (Y, 15.0, 1, 1.6, 0.0),
                                             (X, 8.0, 2, 0.3, 0.0)]),
        ("Jaw", "Head", (0.35, -0.35, 0.0), [(Z, 10.0, 3, 0.0, -10.0)]),
        ("EarL", "Head", (-0.25, 0.45, 0.4), [(X, 20.0, 3, 0.0, 0.0), (Z, 10.0, 2, 0.5, 0.0)]),
        ("EarR", "Head", (-0.25, 0.45, -0.4), [(X, 20.0, 3, 1.0, 0.0), (Z, 10.0, 2, 1.5, 0.0)]),
        ("Tail1", "Root", (-0.7, 0.35, 0.0), [(Y, 15.0, 2, 0.0, 0.0), (Z, 10.0, 1, 0.0, 15.0)]),
    ]
    for k in range(2, 8):
        J.append((f"Tail{k}", f"Tail{k - 1}", (-0.4, 0.1, 0.0),
                  [(Y, 12.0 + 2.0 * k, 2, -0.6 * k, 0.0), (Z, 5.0, 1, -0.4 * k, 0.0)]))
    for part, parent, root in (("Front", "Chest", (0.1, -0.7, 0.65)),
                               ("Hind", "Root", (-0.1, -0.6, 0.7))):
        offsets = {"Front": [(0.0, -1.7, 0.0), (0.05, -1.6, 0.0)],
                   "Hind": [(0.35, -1.8, 0.0), (-0.3, -1.6, 0.0)]}[part]
        for side, sz, ph in (("L", 1.0, 0.0), ("R", -1.0, np.pi)):
            names = [f"{part}Upper{side}", f"{part}Lower{side}", f"{part}Paw{side}"]
            trans = [(root[0], root[1], root[2] * sz)] + offsets
            parents = [parent] + names[:2]
            for name, par, tr, (amp, phase) in zip(names, parents, trans, _LEG[part]):
                terms = [(Z, amp, 2, phase + ph, 0.0)]
                if "Upper" in name:
                    terms.append((X, 4.0 * sz, 2, phase + ph + 0.5, 0.0))
                J.append((name, par, tr, terms))
    return J


JOINT_TABLE = _joint_table()
JOINT_NAMES = [j[0] for j in JOINT_TABLE]
assert len(JOINT_NAMES) == 30


def joint_paths():
    """Joint path tokens (`Root/Spine1/...`), parents before children."""
    paths = {}
    for name, parent, _, _ in JOINT_TABLE:
        paths[name] = name if parent is None else paths[parent] + "/" + name
    return [paths[n] for n in JOINT_NAMES]


def rest_world_positions():
    pos = {}
    for name, parent, tr, _ in JOINT_TABLE:
        pos[name] = np.array(tr, dtype=np.float64) + (0.0 if parent is None else pos[parent])
    return pos


def joint_rotations(frame):
    """(30, 4) local rotation quaternions (w, x, y, z) at `frame`, w >= 0."""
    out = []
    u = 2.0 * np.pi * (frame - FRAMES[0]) / 48.0
    for _, _, _, terms in JOINT_TABLE:
        qj = np.array([1.0, 0.0, 0.0, 0.0])
        for axis, amp, cycles, phase, bias in terms:
            ang = np.radians(bias + amp * np.sin(cycles * u + phase))
            qj = quat_mul(qj, quat_axis_angle(axis, ang))
        if qj[0] < 0.0:
            qj = -qj
        out.append(qj / np.linalg.norm(qj))
    return np.array(out)


def root_translation(frame):
    u = 2.0 * np.pi * (frame - FRAMES[0]) / 48.0
    tr = np.array(JOINT_TABLE[0][2], dtype=np.float64)
    return tr + np.array([0.15 * np.sin(u), 0.12 * np.sin(2 * u + 0.4), 0.0])


def axis_value(rotations, joint, component):
    """Value of a jointRotation axis (rest rotations are identity)."""
    return float(quat_rotvec(rotations[JOINT_NAMES.index(joint)])[component])


# --------------------------------------------------------------------------
# proxy: closed tubes around joint chains (trunk, tail, 4 legs, 2 ears, jaw)
# --------------------------------------------------------------------------

def latlong_topology(n_rings, n_around):
    """Pole 0, n_rings rings of n_around vertices, last pole."""
    last = 1 + n_rings * n_around
    ring = lambda r, j: 1 + r * n_around + (j % n_around)
    counts, idx = [], []
    for j in range(n_around):
        counts.append(3)
        idx += [0, ring(0, j + 1), ring(0, j)]
    for r in range(n_rings - 1):
        for j in range(n_around):
            counts.append(4)
            idx += [ring(r, j), ring(r, j + 1), ring(r + 1, j + 1), ring(r + 1, j)]
    for j in range(n_around):
        counts.append(3)
        idx += [last, ring(n_rings - 1, j), ring(n_rings - 1, j + 1)]
    return np.array(counts, dtype=np.int32), np.array(idx, dtype=np.int32)


def fan_triangles(counts, indices):
    tris, start = [], 0
    for c in counts:
        f = indices[start:start + c]
        tris += [(f[0], f[k], f[k + 1]) for k in range(1, c - 1)]
        start += c
    return np.array(tris, dtype=np.int64)


def orient_outward(points, counts, indices):
    """Reverse every face (keeping its first vertex) when the signed volume
    of the closed component is negative."""
    t = fan_triangles(counts, indices)
    vol = np.einsum("ij,ij->i", points[t[:, 0]], np.cross(points[t[:, 1]], points[t[:, 2]])).sum()
    if vol >= 0.0:
        return indices
    out, start = [], 0
    for c in counts:
        f = list(indices[start:start + c])
        out += [f[0]] + f[1:][::-1]
        start += c
    return np.array(out, dtype=np.int32)


def catmull_rom(nodes, per_segment=200):
    """Dense samples of a Catmull-Rom spline through `nodes`, and the
    sample index of every node."""
    P = np.asarray(nodes, dtype=np.float64)
    ext = np.concatenate([[2 * P[0] - P[1]], P, [2 * P[-1] - P[-2]]])
    out = []
    for i in range(len(P) - 1):
        p0, p1, p2, p3 = ext[i:i + 4]
        t = np.linspace(0.0, 1.0, per_segment, endpoint=False)[:, None]
        out.append(0.5 * ((2 * p1) + (-p0 + p2) * t + (2 * p0 - 5 * p1 + 4 * p2 - p3) * t ** 2
                          + (-p0 + 3 * p1 - 3 * p2 + p3) * t ** 3))
    out.append(P[-1:])
    return np.concatenate(out), np.arange(len(P)) * per_segment


class Tube:
    """A closed tube around a smooth centreline: circular (or flattened)
    sections with hemispherical end caps. Surface parameters: arc length s
    along the centreline and angle th around it (th = 0 along the transported
    normal N, +90 deg along B = T x N)."""

    def __init__(self, name, nodes, radii, n_rings, n_around, joints, bones,
                 ref=(0.0, 1.0, 0.0), flatten=1.0):
        self.name, self.n_rings, self.n_around = name, n_rings, n_around
        self.joints = joints        # candidate skinning joints
        self.bones = bones          # (joint, segment start, segment end) for weights
        self.flatten = flatten
        c, node_idx = catmull_rom(nodes)
        seg = np.linalg.norm(np.diff(c, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        self.c, self.s, self.length = c, s, float(s[-1])
        self.r_nodes = (s[node_idx], np.asarray(radii, dtype=np.float64))
        tan = normalize(np.gradient(c, axis=0))
        ref = np.asarray(ref, dtype=np.float64)
        n = [normalize(ref - tan[0] * np.dot(ref, tan[0]))]
        for i in range(1, len(c)):        # parallel transport
            v = n[-1] - tan[i] * np.dot(n[-1], tan[i])
            n.append(normalize(v))
        self.T, self.N = tan, np.array(n)
        self.B = np.cross(self.T, self.N)
        self.cap0, self.cap1 = float(radii[0]), float(radii[-1])

    def _interp(self, s, arr):
        s = np.clip(s, 0.0, self.length)
        return np.stack([np.interp(s, self.s, arr[:, k]) for k in range(arr.shape[1])], axis=-1)

    def radius(self, s):
        s = np.asarray(s, dtype=np.float64)
        r = np.interp(s, *self.r_nodes)
        d0 = np.clip(s / self.cap0, 0.0, 1.0)
        d1 = np.clip((self.length - s) / self.cap1, 0.0, 1.0)
        return r * np.sqrt(1.0 - (1.0 - d0) ** 2) * np.sqrt(1.0 - (1.0 - d1) ** 2)

    def frame(self, s, th):
        """Surface point and approximate outward normal at (s, th)."""
        s, th = np.broadcast_arrays(np.asarray(s, dtype=np.float64), np.asarray(th, dtype=np.float64))
        c = self._interp(s, self.c)
        N = normalize(self._interp(s, self.N))
        B = normalize(self._interp(s, self.B))
        r = self.radius(s)[..., None]
        cs, sn = np.cos(th)[..., None], np.sin(th)[..., None]
        p = c + r * (cs * N + sn * self.flatten * B)
        nrm = normalize(cs * self.flatten * N + sn * B)
        return p, nrm

    def point(self, s, th, lift=0.0):
        p, n = self.frame(s, th)
        return p + n * np.asarray(lift, dtype=np.float64)[..., None]

    def mesh(self):
        s = self.length * np.arange(1, self.n_rings + 1) / (self.n_rings + 1)
        th = np.linspace(0.0, 2 * np.pi, self.n_around, endpoint=False)
        ring, _ = self.frame(s[:, None], th[None, :])
        pts = np.concatenate([self.c[:1], ring.reshape(-1, 3), self.c[-1:]])
        counts, idx = latlong_topology(self.n_rings, self.n_around)
        return pts, counts, orient_outward(pts, counts, idx)


def build_tubes():
    P = rest_world_positions()
    nose = P["Head"] + np.array([1.3, -0.25, 0.0])
    tubes = []
    trunk_nodes = [P["Root"] + np.array([-0.8, -0.1, 0.0]), P["Root"], P["Spine1"], P["Spine2"],
                   P["Spine3"], P["Chest"], P["Neck1"], P["Neck2"], P["Head"],
                   P["Head"] + np.array([0.7, -0.15, 0.0]), nose]
    trunk_j = ["Root", "Spine1", "Spine2", "Spine3", "Chest", "Neck1", "Neck2", "Head"]
    ends = {"Root": P["Spine1"], "Spine1": P["Spine2"], "Spine2": P["Spine3"],
            "Spine3": P["Chest"], "Chest": P["Neck1"], "Neck1": P["Neck2"],
            "Neck2": P["Head"], "Head": nose}
    tubes.append(Tube("Trunk", trunk_nodes, [0.85, 1.05, 1.15, 1.15, 1.15, 1.2, 0.75, 0.6, 0.65,
                                             0.4, 0.25], 68, 36, trunk_j,
                      [(j, P[j] if j != "Root" else P["Root"] + np.array([-0.8, 0.0, 0.0]), ends[j])
                       for j in trunk_j]))
    tail_j = [f"Tail{k}" for k in range(1, 8)]
    tip = P["Tail7"] + np.array([-0.4, 0.1, 0.0])
    tail_nodes = [P["Root"] + np.array([-0.4, 0.3, 0.0])] + [P[j] for j in tail_j] + [tip]
    tail_ends = [P[j] for j in tail_j[1:]] + [tip]
    tubes.append(Tube("Tail", tail_nodes, [0.3, 0.32, 0.3, 0.27, 0.24, 0.21, 0.18, 0.14, 0.08],
                      32, 14, ["Root"] + tail_j,
                      [("Root", P["Root"], P["Tail1"])] + list(zip(tail_j, [P[j] for j in tail_j],
                                                                   tail_ends))))
    for part, parent in (("Front", "Chest"), ("Hind", "Root")):
        for side in ("L", "R"):
            u, lo, paw = (f"{part}{k}{side}" for k in ("Upper", "Lower", "Paw"))
            toe = P[paw] + np.array([0.55, -0.45, 0.0])
            nodes = [P[u] + np.array([0.0, 0.6, 0.0]), P[u], P[lo], P[paw], toe]
            bones = [(parent, P[u] + np.array([0.0, 0.8, 0.0]), P[u]), (u, P[u], P[lo]),
                     (lo, P[lo], P[paw]), (paw, P[paw], toe)]
            tubes.append(Tube(f"{part}Leg{side}", nodes, [0.45, 0.42, 0.28, 0.22, 0.2], 26, 16,
                              [parent, u, lo, paw], bones, ref=(1.0, 0.0, 0.0)))
    for side, sz in (("L", 1.0), ("R", -1.0)):
        e = f"Ear{side}"
        tip = P[e] + np.array([-0.15, 0.8, 0.25 * sz])
        nodes = [P[e] - np.array([0.0, 0.15, 0.0]), P[e], 0.5 * (P[e] + tip), tip]
        tubes.append(Tube(e, nodes, [0.22, 0.3, 0.25, 0.08], 10, 12, ["Head", e],
                          [("Head", P["Head"], P[e]), (e, P[e], tip)], ref=(0.0, 0.0, 1.0),
                          flatten=0.35))
    jaw_tip = P["Jaw"] + np.array([0.95, -0.2, 0.0])
    tubes.append(Tube("Jaw", [P["Jaw"], P["Jaw"] + np.array([0.5, -0.15, 0.0]), jaw_tip],
                      [0.3, 0.25, 0.15], 14, 14, ["Head", "Jaw"],
                      [("Head", P["Head"], nose), ("Jaw", P["Jaw"], jaw_tip)]))
    return tubes


def segment_distance(p, a, b):
    ab = b - a
    t = np.clip(((p - a) @ ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def skin_weights(tube, points, es=4):
    """Smooth 4-influence weights: inverse 4th power of the distance to each
    candidate bone segment, strongest 4 kept, normalised."""
    names = [b[0] for b in tube.bones]
    d = np.stack([segment_distance(points, a, b) for _, a, b in tube.bones], axis=1)
    w = 1.0 / (d * d + 0.05) ** 2
    order = np.argsort(-w, axis=1, kind="stable")[:, :es]
    wt = np.take_along_axis(w, order, axis=1)
    wt /= wt.sum(axis=1, keepdims=True)
    ji = np.array([JOINT_NAMES.index(n) for n in names])[order]
    pad = es - ji.shape[1]          # fewer candidates than influences: zero weights
    ji = np.pad(ji, ((0, 0), (0, pad)))
    wt = np.pad(wt, ((0, 0), (0, pad)))
    return ji.astype(np.int32), wt.astype(np.float32)


# --------------------------------------------------------------------------
# stroke layers
# --------------------------------------------------------------------------

# name, tube, s range (fractions of the tube length), th window (centre deg,
# half width deg; None = all around), style, relative stroke count,
# base colour, drivers [(joint, rotation-vector component)] for --keys
LAYER_SPECS = [
    ("BackCoat", "Trunk", (0.08, 0.62), (0, 60), "coat", 5.0, (0.45, 0.3, 0.15), [("Spine2", 1), ("Spine2", 2)]),
    ("BackFur", "Trunk", (0.08, 0.62), (0, 50), "fur", 4.0, (0.4, 0.27, 0.13), [("Spine2", 1)]),
    ("BackHighlights", "Trunk", (0.15, 0.55), (0, 25), "coat", 1.5, (0.7, 0.55, 0.35), [("Spine3", 1)]),
    ("FlankCoatL", "Trunk", (0.08, 0.6), (90, 40), "coat", 4.0, (0.55, 0.38, 0.2), [("Spine1", 1), ("Spine1", 2)]),
    ("FlankCoatR", "Trunk", (0.08, 0.6), (-90, 40), "coat", 4.0, (0.55, 0.38, 0.2), [("Spine1", 1), ("Spine1", 2)]),
    ("FlankFurL", "Trunk", (0.1, 0.58), (80, 35), "fur", 2.5, (0.5, 0.35, 0.18), [("Spine2", 1)]),
    ("FlankFurR", "Trunk", (0.1, 0.58), (-80, 35), "fur", 2.5, (0.5, 0.35, 0.18), [("Spine2", 1)]),
    ("Belly", "Trunk", (0.1, 0.55), (180, 45), "coat", 3.0, (0.85, 0.78, 0.62), [("Spine2", 2)]),
    ("BellyFur", "Trunk", (0.12, 0.5), (180, 35), "fur", 1.5, (0.9, 0.82, 0.68), [("Spine3", 2)]),
    ("RibHatching", "Trunk", (0.35, 0.58), (0, 150), "ring", 2.0, (0.35, 0.22, 0.1), [("Spine3", 1), ("Chest", 2)]),
    ("Spots", "Trunk", (0.1, 0.6), (0, 110), "dab", 1.0, (0.2, 0.12, 0.06), [("Spine2", 1)]),
    ("Hips", "Trunk", (0.0, 0.15), None, "coat", 2.0, (0.5, 0.33, 0.17), [("Root", 1), ("Root", 2)]),
    ("ChestCoat", "Trunk", (0.55, 0.68), None, "coat", 3.0, (0.6, 0.42, 0.22), [("Chest", 1), ("Chest", 2)]),
    ("ChestRuff", "Trunk", (0.58, 0.7), (180, 80), "fur", 2.0, (0.88, 0.8, 0.65), [("Chest", 2)]),
    ("NeckCoat", "Trunk", (0.66, 0.8), None, "coat", 3.0, (0.55, 0.38, 0.2), [("Neck1", 1), ("Neck1", 2)]),
    ("NeckFur", "Trunk", (0.66, 0.8), (0, 90), "fur", 1.5, (0.48, 0.32, 0.16), [("Neck2", 2)]),
    ("Collar", "Trunk", (0.7, 0.74), None, "ring", 0.8, (0.7, 0.1, 0.1), [("Neck1", 2)]),
    ("HeadCoat", "Trunk", (0.8, 0.9), None, "coat", 2.5, (0.58, 0.4, 0.21), [("Head", 1), ("Head", 2)]),
    ("Brow", "Trunk", (0.84, 0.9), (0, 50), "ring", 0.8, (0.3, 0.2, 0.1), [("Head", 2), ("Head", 0)]),
    ("Cheeks", "Trunk", (0.85, 0.92), (180, 100), "fur", 1.0, (0.8, 0.7, 0.55), [("Jaw", 2)]),
    ("Snout", "Trunk", (0.9, 0.985), None, "coat", 1.5, (0.5, 0.35, 0.2), [("Head", 2)]),
    ("Nose", "Trunk", (0.97, 0.995), None, "dab", 0.4, (0.08, 0.06, 0.05), [("Head", 1)]),
    ("TailCoat", "Tail", (0.05, 0.95), None, "coat", 2.5, (0.45, 0.3, 0.15), [("Tail3", 1), ("Tail5", 1)]),
    ("TailFur", "Tail", (0.2, 0.98), None, "fur", 2.0, (0.5, 0.34, 0.17), [("Tail5", 1), ("Tail6", 2)]),
    ("TailRings", "Tail", (0.1, 0.9), None, "ring", 0.8, (0.3, 0.2, 0.1), [("Tail4", 1)]),
    ("FrontUpperL", "FrontLegL", (0.05, 0.45), None, "coat", 1.5, (0.55, 0.38, 0.2), [("FrontUpperL", 2)]),
    ("FrontLowerL", "FrontLegL", (0.45, 0.8), None, "coat", 1.2, (0.6, 0.42, 0.22), [("FrontLowerL", 2)]),
    ("FrontPawL", "FrontLegL", (0.8, 0.99), None, "fur", 0.8, (0.85, 0.78, 0.62), [("FrontPawL", 2)]),
    ("FrontUpperR", "FrontLegR", (0.05, 0.45), None, "coat", 1.5, (0.55, 0.38, 0.2), [("FrontUpperR", 2)]),
    ("FrontLowerR", "FrontLegR", (0.45, 0.8), None, "coat", 1.2, (0.6, 0.42, 0.22), [("FrontLowerR", 2)]),
    ("FrontPawR", "FrontLegR", (0.8, 0.99), None, "fur", 0.8, (0.85, 0.78, 0.62), [("FrontPawR", 2)]),
    ("HindUpperL", "HindLegL", (0.05, 0.45), None, "fur", 1.8, (0.5, 0.34, 0.17), [("HindUpperL", 2)]),
    ("HindLowerL", "HindLegL", (0.45, 0.8), None, "coat", 1.2, (0.6, 0.42, 0.22), [("HindLowerL", 2)]),
    ("HindPawL", "HindLegL", (0.8, 0.99), None, "fur", 0.8, (0.85, 0.78, 0.62), [("HindPawL", 2)]),
    ("HindUpperR", "HindLegR", (0.05, 0.45), None, "fur", 1.8, (0.5, 0.34, 0.17), [("HindUpperR", 2)]),
    ("HindLowerR", "HindLegR", (0.45, 0.8), None, "coat", 1.2, (0.6, 0.42, 0.22), [("HindLowerR", 2)]),
    ("HindPawR", "HindLegR", (0.8, 0.99), None, "fur", 0.8, (0.85, 0.78, 0.62), [("HindPawR", 2)]),
    ("EarOuterL", "EarL", (0.1, 0.95), (90, 80), "coat", 0.6, (0.3, 0.2, 0.1), [("EarL", 0), ("EarL", 2)]),
    ("EarInnerL", "EarL", (0.1, 0.9), (-90, 80), "fur", 0.5, (0.85, 0.6, 0.55), [("EarL", 0)]),
    ("EarOuterR", "EarR", (0.1, 0.95), (-90, 80), "coat", 0.6, (0.3, 0.2, 0.1), [("EarR", 0), ("EarR", 2)]),
    ("EarInnerR", "EarR", (0.1, 0.9), (90, 80), "fur", 0.5, (0.85, 0.6, 0.55), [("EarR", 0)]),
    ("Jaw", "Jaw", (0.05, 0.95), None, "coat", 0.7, (0.8, 0.7, 0.55), [("Jaw", 2)]),
]
assert len(LAYER_SPECS) == N_LAYERS


def stroke_counts():
    """Strokes per layer: proportional to the specs' weights, summing to
    N_STROKES exactly (largest remainder)."""
    w = np.array([s[5] for s in LAYER_SPECS], dtype=np.float64)
    raw = w / w.sum() * N_STROKES
    n = np.floor(raw).astype(int)
    rest = N_STROKES - n.sum()
    n[np.argsort(-(raw - n), kind="stable")[:rest]] += 1
    return n


def sample_sites(tube, rng, count, s_range, th_window):
    """Area-weighted surface parameters (s, th) inside a region."""
    lo, hi = s_range[0] * tube.length, s_range[1] * tube.length
    rmax = float(tube.radius(np.linspace(lo, hi, 200)).max())
    out_s, out_t = [], []
    while len(out_s) < count:
        s = rng.uniform(lo, hi, 4096)
        if th_window is None:
            th = rng.uniform(-np.pi, np.pi, 4096)
        else:
            th = np.radians(th_window[0] + rng.uniform(-th_window[1], th_window[1], 4096))
        keep = rng.uniform(0.0, 1.0, 4096) < tube.radius(s) / rmax
        out_s += list(s[keep])
        out_t += list(th[keep])
    return np.array(out_s[:count]), np.array(out_t[:count])


def make_strokes(tube, rng, style, s0, th0):
    """(count, 16, 3) stroke points for sites (s0, th0) in one style: on the
    surface ("coat", "ring", "dab") or leaving it ("fur")."""
    n, k = len(s0), POINTS_PER_STROKE
    t = np.linspace(0.0, 1.0, k)[None, :]
    r = np.maximum(tube.radius(s0), 0.05)[:, None]
    margin = 0.01 * tube.length
    if style == "coat":
        length = rng.uniform(0.5, 1.1, n)[:, None]
        drift = rng.normal(0.0, 0.25, n)[:, None]
        wob = 0.04 * np.sin(t * np.pi * 2 + rng.uniform(0, 6.3, n)[:, None])
        s = s0[:, None] - length * t
        th = th0[:, None] + (drift * length * t + wob) / r
        lift = np.full_like(s, 0.015) + 0.01 * rng.uniform(0, 1, n)[:, None]
    elif style == "fur":
        length = rng.uniform(0.2, 0.45, n)[:, None]
        s = s0[:, None] - length * t
        th = th0[:, None] + rng.normal(0.0, 0.15, n)[:, None] * t / r
        lift = rng.uniform(0.12, 0.3, n)[:, None] * t ** 1.5
    elif style == "ring":
        arc = rng.uniform(0.6, 1.2, n)[:, None]
        s = s0[:, None] + 0.05 * np.sin(np.pi * t) * rng.normal(0, 1, n)[:, None]
        th = th0[:, None] + arc * (t - 0.5) / r
        lift = np.full_like(s, 0.02)
    elif style == "dab":
        rad = rng.uniform(0.04, 0.09, n)[:, None]
        a = rng.uniform(0, 2 * np.pi, n)[:, None] + t * 2.2 * np.pi
        s = s0[:, None] + rad * (0.3 + 0.7 * t) * np.cos(a)
        th = th0[:, None] + rad * (0.3 + 0.7 * t) * np.sin(a) / r
        lift = np.full_like(s, 0.03)
    else:
        raise ValueError(style)
    s = np.clip(s, margin, tube.length - margin)
    return tube.point(s, th, lift)


def stroke_widths(style, n):
    t = np.linspace(0.0, 1.0, POINTS_PER_STROKE)
    w0 = {"coat": 0.09, "fur": 0.05, "ring": 0.06, "dab": 0.05}[style]
    prof = (1.0 - 0.85 * t) if style == "fur" else (0.35 + 0.65 * np.sin(np.pi * t) ** 0.7)
    return np.broadcast_to(w0 * prof, (n, POINTS_PER_STROKE))


class Character:
    """All arrays of the character (numpy), independent of USD."""


def build_character(seed=2013):
    dog = Character()
    dog.tubes = build_tubes()
    tube_by_name = {t.name: t for t in dog.tubes}
    # proxy mesh: all tubes, one mesh
    pts, counts, idx, ji, jw, first = [], [], [], [], [], 0
    for tube in dog.tubes:
        p, c, i = tube.mesh()
        a, b = skin_weights(tube, p)
        pts.append(p)
        counts.append(c)
        idx.append(i + first)
        ji.append(a)
        jw.append(b)
        first += len(p)
    dog.mesh_points = np.concatenate(pts)
    dog.mesh_counts = np.concatenate(counts)
    dog.mesh_indices = np.concatenate(idx)
    dog.joint_indices = np.concatenate(ji)
    dog.joint_weights = np.concatenate(jw)
    # skeleton and animation
    dog.joints = joint_paths()
    P = rest_world_positions()
    dog.rest_world = [P[n] for n in JOINT_NAMES]
    dog.rest_local = [np.array(j[2], dtype=np.float64) for j in JOINT_TABLE]
    dog.frames = list(range(FRAMES[0], FRAMES[1] + 1))
    dog.rotations = [joint_rotations(f) for f in dog.frames]
    dog.root_translations = [root_translation(f) for f in dog.frames]
    # stroke layers
    dog.layers = []
    for li, (spec, n) in enumerate(zip(LAYER_SPECS, stroke_counts())):
        name, tname, s_range, th_window, style, _, color, drivers = spec
        tube = tube_by_name[tname]
        rng = np.random.default_rng([seed, li])
        s0, th0 = sample_sites(tube, rng, int(n), s_range, th_window)
        strokes = make_strokes(tube, rng, style, s0, th0)
        layer = Character()
        layer.name, layer.tube, layer.style, layer.drivers = name, tube, style, drivers
        layer.points = strokes.reshape(-1, 3)
        layer.counts = np.full(len(strokes), POINTS_PER_STROKE, dtype=np.int32)
        layer.widths = stroke_widths(style, len(strokes)).reshape(-1)
        layer.colors = np.clip(np.asarray(color) + rng.normal(0.0, 0.04, (len(strokes), 3)), 0, 1)
        layer.opacities = rng.uniform(0.75, 1.0, len(strokes))
        dog.layers.append(layer)
    assert sum(len(l.counts) for l in dog.layers) == N_STROKES
    return dog


# --------------------------------------------------------------------------
# configuration-space keys (--keys)
# --------------------------------------------------------------------------

# position keys per keyed layer (sum 43) and opacity keys (sum 19)
POSITION_KEY_COUNTS = [4, 3, 3, 2, 3, 4, 2, 3, 3, 2, 4, 3, 3, 2, 2]
OPACITY_KEY_COUNTS = [3, 3, 2, 3, 3, 2, 3]
assert sum(POSITION_KEY_COUNTS) == N_POSITION_KEYS and sum(OPACITY_KEY_COUNTS) == N_OPACITY_KEYS


def key_plan():
    """{layer index: [position keys, opacity keys]}: position keys on 15
    layers spread evenly, opacity keys on 7 layers, 4 of them also carrying
    position keys (18 keyed layers)."""
    plan = {}
    pos_layers = [int(round(x)) for x in np.linspace(0, N_LAYERS - 1, len(POSITION_KEY_COUNTS))]
    for li, n in zip(pos_layers, POSITION_KEY_COUNTS):
        plan[li] = [n, 0]
    opa_layers = [0, 6, 9, 16, 21, 29, 40]
    for li, n in zip(opa_layers, OPACITY_KEY_COUNTS):
        plan.setdefault(li, [0, 0])[1] = n
    return plan


def axis_values(dog, drivers):
    """(frames, axes) values of a layer's jointRotation axes over the animation."""
    return np.array([[axis_value(rot, j, c) for j, c in drivers] for rot in dog.rotations])


def pick_key_frames(values, n):
    """n frame indices whose axis values are spread out (farthest-point
    sampling, starting nearest the rest pose)."""
    chosen = [int(np.argmin(np.linalg.norm(values, axis=1)))]
    while len(chosen) < n:
        d = np.min(np.linalg.norm(values[:, None, :] - values[None, chosen, :], axis=2), axis=1)
        chosen.append(int(np.argmax(d)))
    return chosen


def key_frames(dog, li):
    """Per key of layer li (pose0, pose1, ...), the frame whose axis values
    are its coordinates (rounded to 4 decimals); [] for a layer without keys.
    A bake at that frame shows that key alone."""
    plan = key_plan()
    if li not in plan:
        return []
    vals = axis_values(dog, dog.layers[li].drivers)
    return [dog.frames[f] for f in pick_key_frames(vals, max(plan[li]))]


def key_coordinates(dog, li):
    vals = axis_values(dog, dog.layers[li].drivers)
    return np.round(vals[[f - dog.frames[0] for f in key_frames(dog, li)]], 4)


def smooth_offsets(rng, points, amplitude):
    """A smooth displacement field sampled at `points`."""
    w = rng.normal(0.0, 1.2, (3, 3))
    ph = rng.uniform(0.0, 2 * np.pi, 3)
    return amplitude * np.sin(points @ w.T + ph)


def author_keys(stage, dog, layer_prims, seed=43):
    axis_paths = {}

    def axis(joint, comp):
        if (joint, comp) not in axis_paths:
            path = Sdf.Path(PAINT_PATH).AppendChild(f"{joint}_r{'xyz'[comp]}")
            prim = stage.DefinePrim(path, "PainterlyAxis")
            prim.CreateAttribute("kind", T.Token, custom=False, variability=UNIFORM).Set("jointRotation")
            prim.CreateRelationship("source", custom=False).SetTargets([Sdf.Path(SKEL_PATH)])
            prim.CreateAttribute("name", T.Token, custom=False, variability=UNIFORM).Set(
                dog.joints[JOINT_NAMES.index(joint)])
            prim.CreateAttribute("component", T.Int, custom=False, variability=UNIFORM).Set(comp)
            axis_paths[(joint, comp)] = path
        return axis_paths[(joint, comp)]

    summary = []
    for li, (n_pos, n_opa) in sorted(key_plan().items()):
        layer, prim = dog.layers[li], layer_prims[li]
        rng = np.random.default_rng([seed, li])
        vals = axis_values(dog, layer.drivers)
        spread = vals.max(axis=0) - vals.min(axis=0)
        assert spread.min() > 0.02, (layer.name, spread)
        prim.CreateRelationship("painterly:axes", custom=False).SetTargets(
            [axis(j, c) for j, c in layer.drivers])
        n_keys = max(n_pos, n_opa)
        frames = pick_key_frames(vals, n_keys)
        coords = key_coordinates(dog, li)
        for a in range(n_keys):
            for b in range(a):
                assert np.abs(coords[a] - coords[b]).max() > 1e-3, (layer.name, a, b)
        for k in range(n_keys):
            key = stage.DefinePrim(prim.GetPath().AppendChild(f"pose{k}"), "PainterlyPoseKey")
            key.CreateAttribute("coordinates", T.FloatArray, custom=False,
                                variability=UNIFORM).Set(float_array(coords[k]))
            if k < n_pos:
                amp = 0.03 if k == 0 else 0.06 + 0.02 * k
                pts = layer.points + smooth_offsets(rng, layer.points, amp)
                key.CreateAttribute("points", T.Point3fArray, custom=False,
                                    variability=UNIFORM).Set(vec3f_array(pts))
            if k < n_opa:
                op = 1.0 if k == 0 else float(np.round(rng.uniform(0.15, 0.9), 3))
                key.CreateAttribute("opacity", T.Float, custom=False, variability=UNIFORM).Set(op)
        summary.append((layer.name, n_pos, n_opa, [f"{j}.{'xyz'[c]}" for j, c in layer.drivers],
                        [dog.frames[f] for f in frames]))
    return summary


# --------------------------------------------------------------------------
# USD writers
# --------------------------------------------------------------------------

def _new_stage(path, root):
    path = pathlib.Path(path)
    if path.exists():
        path.unlink()
    layer = Sdf.Layer.CreateNew(str(path))
    stage = Usd.Stage.Open(layer)
    stage.SetStartTimeCode(FRAMES[0])
    stage.SetEndTimeCode(FRAMES[1])
    stage.SetTimeCodesPerSecond(FPS)
    stage.SetFramesPerSecond(FPS)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 0.1)
    layer.documentation = "painterly benchmark character, generated by scripts/bench_character.py"
    xf = UsdGeom.Xform.Define(stage, root)
    stage.SetDefaultPrim(xf.GetPrim())
    return stage


def _write_skeleton(stage, dog, rig_path):
    UsdSkel.Root.Define(stage, rig_path)
    skel_path, anim_path = f"{rig_path}/Skel", f"{rig_path}/Skel/Anim"
    skel = UsdSkel.Skeleton.Define(stage, skel_path)
    skel.CreateJointsAttr(Vt.TokenArray(dog.joints))
    skel.CreateJointNamesAttr(Vt.TokenArray(JOINT_NAMES))
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray([translate_matrix(p) for p in dog.rest_world]))
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray([translate_matrix(p) for p in dog.rest_local]))
    anim = UsdSkel.Animation.Define(stage, anim_path)
    anim.CreateJointsAttr(Vt.TokenArray(dog.joints))
    tr_attr, rot_attr, sc_attr = (anim.CreateTranslationsAttr(), anim.CreateRotationsAttr(),
                                  anim.CreateScalesAttr())
    ones = Vt.Vec3hArray([Gf.Vec3h(1.0, 1.0, 1.0)] * len(dog.joints))
    sc_attr.Set(ones)
    for f, rots, root_t in zip(dog.frames, dog.rotations, dog.root_translations):
        tr = np.array(dog.rest_local)
        tr[0] = root_t
        tr_attr.Set(vec3f_array(tr), Usd.TimeCode(f))
        rot_attr.Set(Vt.QuatfArray([Gf.Quatf(float(r[0]), Gf.Vec3f(*[float(c) for c in r[1:]]))
                                    for r in rots]), Usd.TimeCode(f))
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets(
        [Sdf.Path(anim_path)])
    return skel_path


def _define_skinned_mesh(stage, path, points, counts, indices, skel_path, ji, jw):
    mesh = UsdGeom.Mesh.Define(stage, path)
    pts = vec3f_array(points)
    mesh.CreatePointsAttr(pts)
    mesh.CreateFaceVertexCountsAttr(int_array(counts))
    mesh.CreateFaceVertexIndicesAttr(int_array(indices))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(pts))
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([Sdf.Path(skel_path)])
    binding.CreateJointIndicesPrimvar(False, ji.shape[1]).Set(int_array(ji))
    binding.CreateJointWeightsPrimvar(False, jw.shape[1]).Set(float_array(jw))
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
    return mesh


def write_character(dog, path, keys=False):
    """Author the painted character to `path` (.usdc or .usda). Returns the
    key summary when keys=True, else []."""
    stage = _new_stage(path, CHAR_ROOT)
    skel_path = _write_skeleton(stage, dog, SKEL_ROOT)
    mesh = _define_skinned_mesh(stage, PROXY_PATH, dog.mesh_points, dog.mesh_counts,
                                dog.mesh_indices, skel_path, dog.joint_indices, dog.joint_weights)
    mesh.CreatePurposeAttr(UsdGeom.Tokens.guide)
    mesh.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set(Vt.Vec3fArray([Gf.Vec3f(0.6, 0.5, 0.4)]))

    paint = UsdGeom.Xform.Define(stage, PAINT_PATH).GetPrim()
    paint.AddAppliedSchema("PainterlyRigAPI")
    paint.CreateRelationship("painterly:proxy", custom=False).SetTargets([Sdf.Path(PROXY_PATH)])
    prims = []
    for layer in dog.layers:
        curves = UsdGeom.BasisCurves.Define(stage, f"{PAINT_PATH}/{layer.name}")
        prim = curves.GetPrim()
        prim.AddAppliedSchema("PainterlyStrokeLayerAPI")
        curves.CreateTypeAttr(UsdGeom.Tokens.linear)
        curves.CreateWrapAttr(UsdGeom.Tokens.nonperiodic)
        curves.CreateCurveVertexCountsAttr(int_array(layer.counts))
        pts, widths = vec3f_array(layer.points), float_array(layer.widths)
        curves.CreatePointsAttr(pts)
        curves.CreateWidthsAttr(widths)
        curves.SetWidthsInterpolation(UsdGeom.Tokens.vertex)
        curves.CreateExtentAttr(UsdGeom.Curves.ComputeExtent(pts, widths))
        curves.CreateDisplayColorPrimvar(UsdGeom.Tokens.uniform).Set(vec3f_array(layer.colors))
        curves.CreateDisplayOpacityPrimvar(UsdGeom.Tokens.uniform).Set(float_array(layer.opacities))
        # proxy-local rest pose (= points here: no transforms in between)
        prim.CreateAttribute("painterly:restPoints", T.Point3fArray, custom=False,
                             variability=UNIFORM).Set(pts)
        prims.append(prim)
    summary = author_keys(stage, dog, prims) if keys else []
    stage.GetRootLayer().Save()
    return summary


def peer_topology():
    """Each stroke as a zig-zag ribbon of 7 quads over its 16 points."""
    k = POINTS_PER_STROKE
    base = np.arange(0, k - 2, 2)
    quad = np.stack([base, base + 1, base + 3, base + 2], axis=1).reshape(-1)
    starts = np.arange(N_STROKES) * k
    idx = (starts[:, None] + quad[None, :]).reshape(-1)
    counts = np.full(N_STROKES * len(base), 4, dtype=np.int32)
    return counts, idx.astype(np.int32)


def stroke_points(dog):
    """All stroke rest points, layers in order (= the peer mesh's points)."""
    return np.concatenate([l.points for l in dog.layers])


def write_peer(dog, path):
    """usd-core's side: one Mesh with every stroke point as a vertex, skinned
    (4 influences, the same weight rule as the proxy) to the same skeleton
    and animation."""
    stage = _new_stage(path, PEER_ROOT)
    skel_path = _write_skeleton(stage, dog, f"{PEER_ROOT}/Rig")
    ji, jw = zip(*[skin_weights(l.tube, l.points) for l in dog.layers])
    counts, idx = peer_topology()
    _define_skinned_mesh(stage, PEER_MESH, stroke_points(dog), counts, idx, skel_path,
                         np.concatenate(ji), np.concatenate(jw))
    stage.GetRootLayer().Save()


def describe(dog):
    n_pts = sum(len(l.points) for l in dog.layers)
    return (f"proxy {len(dog.mesh_points)} vertices / {len(dog.mesh_counts)} faces, "
            f"{len(dog.joints)} joints, {len(dog.frames)} frames, {len(dog.layers)} layers, "
            f"{sum(len(l.counts) for l in dog.layers)} strokes x {POINTS_PER_STROKE} = {n_pts} points")


if __name__ == "__main__":
    import argparse
    import time
    ap = argparse.ArgumentParser(description="Write the benchmark character and its usd-core peer.")
    ap.add_argument("out_dir")
    ap.add_argument("--keys", action="store_true", help="also author pose keys (SPEC section 4)")
    a = ap.parse_args()
    out = pathlib.Path(a.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    d = build_character()
    print(describe(d))
    write_character(d, out / ("dog_keys.usdc" if a.keys else "dog.usdc"), keys=a.keys)
    write_peer(d, out / "peer.usdc")
    print(f"written to {out} in {time.perf_counter() - t0:.1f} s")
