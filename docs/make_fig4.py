#!/usr/bin/env python3
"""Redraw Fig. 4 of Bassett et al. 2013 (the smudge and expand tools) with
painterly's own results, into docs/figures/.

    .venv/bin/pip install -r docs/requirements.txt
    .venv/bin/python docs/make_fig4.py [--bin target/release/painterly] [--out docs/figures]

The scene is fixtures/fig4.usda (written by fixtures/fig4_fixture.py). The
script applies the product's tools with the CLI, into an edit layer in a
temporary folder (the fixture is not modified):

    painterly smudge fixtures/fig4.usda --layer /Fig4/SmudgeAfter/Paint/Strokes \
        --path-prim /Fig4/SmudgeAfter/Tool --radius 0.35 --strength 0.3 --edit-layer edits.usda
    painterly expand fixtures/fig4.usda --layer /Fig4/ExpandAfter/Paint/Grid \
        --path-prim /Fig4/ExpandAfter/Tool --radius 0.4 --strength 0.3 --edit-layer edits.usda
    painterly bake edits.usda -o bake.usda --frames 1:1

and plots the baked strokes (what a viewer draws), before and after:

  fig4_smudge.png   three straight strokes on a flat canvas, smudged along an arc
  fig4_expand.png   a grid of strokes on a sphere, expanded along a diagonal path
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

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent

SMUDGE = dict(layer="/Fig4/SmudgeAfter/Paint/Strokes", tool="/Fig4/SmudgeAfter/Tool", radius=0.35, strength=0.3)
EXPAND = dict(layer="/Fig4/ExpandAfter/Paint/Grid", tool="/Fig4/ExpandAfter/Tool", radius=0.4, strength=0.3)


def run(binary, *args):
    proc = subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"painterly {' '.join(map(str, args))} failed:\n{proc.stdout}{proc.stderr}")
    return proc.stdout


def apply_tools(binary, fixture, tmp):
    """The product's smudge and expand into an edit layer, baked at frame 1.
    Returns a usd-core stage composing the bake over the edit layer."""
    from pxr import Sdf, Usd

    edits = tmp / "edits.usda"
    for cmd, p in (("smudge", SMUDGE), ("expand", EXPAND)):
        run(binary, cmd, fixture, "--layer", p["layer"], "--path-prim", p["tool"], "--radius", p["radius"],
            "--strength", p["strength"], "--edit-layer", edits)
    bake = tmp / "bake.usda"
    run(binary, "bake", edits, "-o", bake, "--frames", "1:1", "--quiet")
    root = Sdf.Layer.CreateAnonymous(".usda")
    root.subLayerPaths.append(str(bake))
    root.subLayerPaths.append(str(edits))
    return Usd.Stage.Open(root)


def world(stage, path, t=1.0):
    """World-space points of a point-based prim, split into its curves when it has curveVertexCounts."""
    from pxr import UsdGeom

    prim = stage.GetPrimAtPath(path)
    pts = np.array(UsdGeom.PointBased(prim).GetPointsAttr().Get(t), dtype=np.float64)
    m = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t), dtype=np.float64)
    w = pts @ m[:3, :3] + m[3, :3]
    counts = prim.GetAttribute("curveVertexCounts")
    if not counts or not counts.HasAuthoredValue():
        return w
    out, o = [], 0
    for n in counts.Get():
        out.append(w[o:o + n])
        o += n
    return out


def colors(stage, path):
    from pxr import UsdGeom

    pv = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(path)).GetPrimvar("displayColor")
    return [tuple(c) for c in pv.Get()]


def mesh_edges(stage, path):
    """World-space segments of a mesh's authored polygon edges."""
    from pxr import UsdGeom

    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(path))
    p = world(stage, path)
    segs, o = [], 0
    idx = list(mesh.GetFaceVertexIndicesAttr().Get())
    for n in mesh.GetFaceVertexCountsAttr().Get():
        f = idx[o:o + n]
        segs += [(p[f[k]], p[f[(k + 1) % n]]) for k in range(n)]
        o += n
    return segs


def distance_to_path(pts, path):
    """Distance from each point to a polyline (any dimension)."""
    best = np.full(len(pts), np.inf)
    for a, b in zip(path[:-1], path[1:]):
        d = b - a
        s = np.clip((pts - a) @ d / (d @ d), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(a + s[:, None] * d - pts, axis=1))
    return best


def plot_smudge(stage, out):
    fig, axes = plt.subplots(1, 2, figsize=(8.4, 4.7), sharey=True)
    for ax, name in zip(axes, ("SmudgeBefore", "SmudgeAfter")):
        base = f"/Fig4/{name}"
        off = world(stage, f"{base}/Canvas").mean(axis=0)
        for a, b in mesh_edges(stage, f"{base}/Canvas"):
            ax.plot([a[0] - off[0], b[0] - off[0]], [a[1] - off[1], b[1] - off[1]], color="0.85", lw=0.6,
                    zorder=1)
        if name == "SmudgeAfter":
            tool = world(stage, f"{base}/Tool")[0] - off
            # the tool's reach: every point within the radius of the path
            gx, gy = np.meshgrid(np.linspace(-1.3, 1.3, 261), np.linspace(-1.3, 1.3, 261))
            d = distance_to_path(np.c_[gx.ravel(), gy.ravel()], tool[:, :2]).reshape(gx.shape)
            ax.contourf(gx, gy, d, levels=[0, SMUDGE["radius"]], colors=["#f6caca"], alpha=0.5, zorder=2)
            ax.plot(tool[:, 0], tool[:, 1], "--", color="#c0392b", lw=1.2, zorder=3)
            ax.annotate("", xy=tool[-1, :2], xytext=tool[-2, :2],
                        arrowprops=dict(arrowstyle="-|>", color="#c0392b", lw=1.2), zorder=3)
        layer = f"{base}/Paint/Strokes"
        for s, c in zip(world(stage, layer), colors(stage, layer)):
            ax.plot(s[:, 0] - off[0], s[:, 1] - off[1], color=c, lw=3.2, solid_capstyle="round", zorder=4)
        ax.set_aspect("equal")
        ax.set_xlim(-1.25, 1.25)
        ax.set_ylim(-1.25, 1.25)
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title("before: three straight strokes" if name == "SmudgeBefore" else
                     f"after painterly smudge\n(radius {SMUDGE['radius']}, strength {SMUDGE['strength']}, cubic falloff)")
    fig.suptitle("Fig. 4 (top): the smudge tool moves strokes along the tool path (red)", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.94))
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_expand(stage, out):
    fig = plt.figure(figsize=(9.6, 4.6))
    view = dict(elev=14, azim=-62)
    for k, name in enumerate(("ExpandBefore", "ExpandAfter")):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        base = f"/Fig4/{name}"
        centre = world(stage, f"{base}/Sphere").mean(axis=0)
        # matplotlib's 3-D axes are Z-up: plot (x, -z, y) so USD's +Y is up and +Z faces the viewer
        def P(a):
            a = np.asarray(a) - centre
            return a[..., 0], -a[..., 2], a[..., 1]
        for a, b in mesh_edges(stage, f"{base}/Sphere"):
            x, y, z = P(np.array([a, b]))
            ax.plot(x, y, z, color="0.8", lw=0.4)
        layer = f"{base}/Paint/Grid"
        for s, c in zip(world(stage, layer), colors(stage, layer)):
            x, y, z = P(s)
            ax.plot(x, y, z, color=c, lw=2.0)
        if name == "ExpandAfter":
            x, y, z = P(world(stage, f"{base}/Tool")[0])
            ax.plot(x, y, z, "--", color="#c0392b", lw=1.6)
        ax.view_init(**view)
        ax.set_box_aspect((1, 1, 1), zoom=1.45)
        for setl in (ax.set_xlim, ax.set_ylim, ax.set_zlim):
            setl(-1.15, 1.15)
        ax.set_axis_off()
        ax.set_title("before: a grid painted on the sphere" if name == "ExpandBefore" else
                     f"after painterly expand\n(radius {EXPAND['radius']}, strength {EXPAND['strength']}, cubic falloff)")
    fig.suptitle("Fig. 4 (bottom): the expand tool moves strokes along the surface normal near the tool path (red)",
                 fontsize=11)
    fig.subplots_adjust(left=0.0, right=1.0, bottom=0.0, top=0.84, wspace=0.0)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--bin", default=REPO / "target" / "release" / "painterly", type=pathlib.Path)
    ap.add_argument("--fixture", default=REPO / "fixtures" / "fig4.usda", type=pathlib.Path)
    ap.add_argument("--out", default=HERE / "figures", type=pathlib.Path)
    a = ap.parse_args()
    if not a.bin.exists():
        sys.exit(f"{a.bin} not found: cargo build --release --ignore-rust-version")
    a.out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        stage = apply_tools(a.bin, a.fixture.resolve(), pathlib.Path(tmp))
        plot_smudge(stage, a.out / "fig4_smudge.png")
        plot_expand(stage, a.out / "fig4_expand.png")
    for n in ("fig4_smudge.png", "fig4_expand.png"):
        print(a.out / n)


if __name__ == "__main__":
    main()
