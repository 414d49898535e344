#!/usr/bin/env python3
"""Draw the viewing sphere of fixtures/head.usda (Rademacher 1999, Fig. 4)
into docs/figures/view_sphere.png.

    .venv/bin/pip install -r docs/requirements.txt   # matplotlib (scipy: python_tests/requirements.txt)
    .venv/bin/python docs/make_view_figure.py [--bin target/release/painterly] [--frame 20] [--out docs/figures]

Left: the key viewpoint directions of /Head/Face on the unit sphere, the
edges of their convex hull, and the eye direction of /Head/Camera over the
whole shot (camera origin in the mesh's local space minus the centre of the
base model's bounding box, normalised, SPEC section 6). At --frame the hull
face hit by the ray towards the camera is filled green and its three keys
are red. Right: the head at --frame as `painterly bake` shapes it, seen
from a fixed viewpoint (Fig. 6, bottom row), over the grey base model.
"""

import argparse
import pathlib
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection  # noqa: E402
from pxr import Sdf, Usd, UsdGeom  # noqa: E402
from scipy.spatial import ConvexHull  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent
MESH, CAMERA = "/Head/Face", "/Head/Camera"


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def matrix(prim, t):
    return np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t), dtype=np.float64).reshape(4, 4)


def read_head(path):
    stage = Usd.Stage.Open(str(path))
    mesh = stage.GetPrimAtPath(MESH)
    base = np.array(UsdGeom.Mesh(mesh).GetPointsAttr().Get(), dtype=np.float64)
    keys = []
    for c in mesh.GetChildren():
        if c.GetTypeName() == "PainterlyViewKey":
            keys.append((c.GetName(), unit(np.array(c.GetAttribute("direction").Get(), dtype=np.float64))))
    frames = np.arange(stage.GetStartTimeCode(), stage.GetEndTimeCode() + 1)
    centre = 0.5 * (base.min(axis=0) + base.max(axis=0))
    cam = stage.GetPrimAtPath(CAMERA)
    eyes = []
    for t in frames:
        inv = np.linalg.inv(matrix(mesh, t))
        c = matrix(cam, t)[3, :3] @ inv[:3, :3] + inv[3, :3]
        eyes.append(unit(c - centre))
    counts = list(UsdGeom.Mesh(mesh).GetFaceVertexCountsAttr().Get())
    indices = list(UsdGeom.Mesh(mesh).GetFaceVertexIndicesAttr().Get())
    faces, o = [], 0
    for n in counts:
        faces.append(indices[o:o + n])
        o += n
    return base, keys, frames, np.array(eyes), faces


def hit_face(dirs, hull, eye):
    for s in hull.simplices:
        lam = np.linalg.solve(dirs[s].T, eye)
        if lam.min() >= -1e-12:
            return s, lam / lam.sum()
    raise RuntimeError("no hull face hit: the keys do not enclose the centre")


def baked_head(binary, path, frame):
    with tempfile.TemporaryDirectory() as tmp:
        out = pathlib.Path(tmp) / "head_bake.usdc"
        subprocess.run([str(binary), "bake", str(path), "-o", str(out), "--quiet",
                        "--frames", f"{frame}:{frame}"], check=True)
        layer = Sdf.Layer.FindOrOpen(str(out))
        pts = layer.QueryTimeSample(Sdf.Path(MESH).AppendProperty("points"), float(frame))
        return np.array(pts, dtype=np.float64)


def yup(p):
    """Mesh-local (Y up) to matplotlib's (x, y, z) with z up."""
    p = np.asarray(p)
    return p[..., [0, 2, 1]] * np.array([1, -1, 1])


def draw_sphere(ax, keys, eyes, frame_index):
    dirs = np.array([d for _, d in keys])
    hull = ConvexHull(dirs)
    face, bary = hit_face(dirs, hull, eyes[frame_index])
    # faint sphere
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 37), np.linspace(0, np.pi, 19))
    sx, sy, sz = np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v)
    ax.plot_wireframe(sx, sy, sz, color="#c8c8c8", linewidth=0.3, alpha=0.6)
    # hull edges
    edges = {tuple(sorted((s[a], s[b]))) for s in hull.simplices for a, b in ((0, 1), (1, 2), (0, 2))}
    ax.add_collection3d(Line3DCollection([yup(dirs[[a, b]]) for a, b in sorted(edges)],
                                         colors="#555555", linewidths=0.9))
    # the face hit at the chosen frame
    ax.add_collection3d(Poly3DCollection([yup(dirs[face])], facecolor="#2a9d3a", alpha=0.45,
                                         edgecolor="#1b6e27", linewidths=1.5))
    # camera path on the sphere, coloured by time
    pe = yup(eyes)
    cmap = plt.get_cmap("viridis")
    segs = [pe[i:i + 2] for i in range(len(pe) - 1)]
    ax.add_collection3d(Line3DCollection(segs, colors=[cmap(i / len(segs)) for i in range(len(segs))],
                                         linewidths=1.6))
    ax.plot(*yup(eyes[frame_index])[:, None], marker="*", color="#1f5fbf", ms=14, ls="none", zorder=10,
            label="eye at the shown frame")
    # keys
    for i, (name, d) in enumerate(keys):
        hit = i in face
        ax.plot(*yup(d)[:, None], marker="o", ms=8 if hit else 6, ls="none",
                color="#d62728" if hit else "black", zorder=9)
        ax.text(*(yup(d) * 1.2), name, fontsize=7, ha="center", va="center")
    ax.set_box_aspect((1, 1, 1))
    for set_lim in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
        set_lim(-1.05, 1.05)
    ax.set_xticks([]), ax.set_yticks([]), ax.set_zticks([])
    ax.view_init(elev=18, azim=-62)
    return face, bary


def draw_head(ax, base, baked, faces):
    edges = {tuple(sorted((f[i], f[(i + 1) % len(f)]))) for f in faces for i in range(len(f))}
    ax.add_collection3d(Line3DCollection([yup(base[[a, b]]) for a, b in sorted(edges)],
                                         colors="#a0a0a0", linewidths=0.3))
    moved = np.linalg.norm(baked - base, axis=1)
    shade = np.array([moved[f].mean() for f in faces]) / max(moved.max(), 1e-12)
    cmap = plt.get_cmap("Oranges")
    ax.add_collection3d(Poly3DCollection([yup(baked[f]) for f in faces],
                                         facecolors=[cmap(0.15 + 0.75 * x) for x in shade], alpha=0.8,
                                         edgecolor="#7a4a2a", linewidths=0.2))
    allp = yup(np.vstack([base, baked]))
    c = 0.5 * (allp.min(0) + allp.max(0))
    r = 0.55 * (allp.max(0) - allp.min(0)).max()
    ax.set_xlim(c[0] - r, c[0] + r), ax.set_ylim(c[1] - r, c[1] + r), ax.set_zlim(c[2] - r, c[2] + r)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xticks([]), ax.set_yticks([]), ax.set_zticks([])
    ax.view_init(elev=12, azim=-30)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=str(REPO / "target" / "release" / "painterly"))
    ap.add_argument("--input", default=str(REPO / "fixtures" / "head.usda"))
    ap.add_argument("--frame", type=int, default=20)
    ap.add_argument("--out", default=str(HERE / "figures"))
    args = ap.parse_args()
    base, keys, frames, eyes, faces = read_head(args.input)
    fi = int(np.nonzero(frames == args.frame)[0][0])
    baked = baked_head(args.bin, args.input, args.frame)

    plt.rcParams.update({"figure.dpi": 100, "savefig.dpi": 100, "font.size": 9, "axes.titlesize": 10})
    fig = plt.figure(figsize=(11, 5.4))
    ax = fig.add_subplot(1, 2, 1, projection="3d")
    face, bary = draw_sphere(ax, keys, eyes, fi)
    names = ", ".join(f"{keys[i][0]} {w:.2f}" for i, w in zip(face, bary))
    ax.set_title(f"{MESH}: key viewpoints, their convex hull, camera path\n"
                 f"frame {args.frame}: hull face hit by the eye ray (green)\n"
                 f"barycentric weights {names}")
    ax2 = fig.add_subplot(1, 2, 2, projection="3d")
    draw_head(ax2, base, baked, faces)
    ax2.set_title(f"painterly bake at frame {args.frame}, seen from a fixed viewpoint\n"
                  "filled: view-dependent shape (darker = moved more)\n"
                  "grey wireframe: base model")
    sm = plt.cm.ScalarMappable(cmap="viridis", norm=plt.Normalize(frames[0], frames[-1]))
    cb = fig.colorbar(sm, ax=ax, shrink=0.55, pad=0.02)
    cb.set_label("camera path (frame)")
    fig.subplots_adjust(left=0.0, right=0.98, top=0.86, bottom=0.02, wspace=0.05)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fig.savefig(out / "view_sphere.png")
    print(out / "view_sphere.png")
    return 0


if __name__ == "__main__":
    sys.exit(main())
