#!/usr/bin/env python3
"""Redraw the interpolation figures of Bassett et al. 2013 with painterly's
own numbers, into docs/figures/.

    .venv/bin/pip install -r docs/requirements.txt
    .venv/bin/python docs/make_figures.py [--bin target/release/painterly] [--out docs/figures]

Every interpolated curve or basis function comes from the product: the
weights from `painterly interpolate` (smooth Voronoi, normalised Gaussian
RBF, Shepard 1/d^2), and the temporal-key figure from `painterly bake` of a
small scene this script writes. The one exception is the red curve of
Fig. 7 (smooth Voronoi's kernels phi used directly, without gradients),
which the product does not expose: it is computed here from equations 7-8
with the corrected step S of SPEC section 4.

Figures (see docs/figures/):
  fig06_rbf_radius.png       Fig. 6:  irregular 1-D keys, smooth Voronoi vs Gaussian RBF radii 1-5
  fig07_regular_keys.png     Fig. 7:  five regular keys, smooth Voronoi vs Shepard vs raw phi
  fig09_basis_2d.png         Fig. 9:  the five 2-D basis functions w_i
  fig12_non_monotone.png     Fig. 12: increasing key values, an interpolant that is not
  sentinel_blend.png         Fig. 5 / SPEC section 5: time keys and sentinels over a pose-keyed channel
"""

import argparse
import json
import os
import pathlib
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import TwoSlopeNorm  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent

SV_BLUE, SHEP_GREEN, RAW_RED, RBF_GREEN, RBF_RED = "#1f5fbf", "#2a9d3a", "#d62728", "#7fbf7f", "#d62728"
KEY_STYLE = dict(marker="o", color="black", ms=6, ls="none", zorder=5)


def style():
    plt.rcParams.update({
        "figure.dpi": 100, "savefig.dpi": 100, "font.size": 9, "axes.titlesize": 10,
        "axes.grid": True, "grid.alpha": 0.3, "legend.fontsize": 8, "legend.framealpha": 0.9,
    })


# --------------------------------------------------------------------------
# the product's interpolation
# --------------------------------------------------------------------------

class Painterly:
    def __init__(self, binary):
        self.bin = str(binary)

    def weights(self, method, keys, points, radius=None):
        """Basis weights (n_points x n_keys) from `painterly interpolate`."""
        keys = np.asarray(keys, dtype=np.float64)
        points = np.asarray(points, dtype=np.float64)
        if keys.ndim == 1:
            keys, points = keys[:, None], points[:, None]
        req = {"method": method, "keys": keys.tolist(), "points": points.tolist()}
        if radius is not None:
            req["radius"] = float(radius)
        proc = subprocess.run([self.bin, "interpolate"], input=json.dumps(req), capture_output=True,
                              text=True)
        if proc.returncode != 0:
            sys.exit(f"painterly interpolate failed: {proc.stderr.strip()}")
        return np.array(json.loads(proc.stdout)["weights"])

    def run(self, *args):
        proc = subprocess.run([self.bin, *map(str, args)], capture_output=True, text=True)
        if proc.returncode != 0:
            sys.exit(f"painterly {' '.join(map(str, args))} failed:\n{proc.stdout}{proc.stderr}")
        return proc.stdout


# --------------------------------------------------------------------------
# smooth Voronoi kernels (eqs 7-8), only for Fig. 7's "phi used directly"
# --------------------------------------------------------------------------

GAMMA = 0.2


def smooth_step(t, gamma=GAMMA):
    """S_gamma of eq. 7 with the SPEC section 4 erratum: the quadratic
    pieces divide by 2 gamma (1 - gamma), so S is C1."""
    t = np.asarray(t, dtype=np.float64)
    d = 2.0 * gamma * (1.0 - gamma)
    out = 0.5 + (t - 0.5) / (1.0 - gamma)
    out = np.where(t <= gamma, t * t / d, out)
    out = np.where(t > 1.0 - gamma, 1.0 - (1.0 - t) ** 2 / d, out)
    return np.clip(np.where(t <= 0.0, 0.0, np.where(t >= 1.0, 1.0, out)), 0.0, 1.0)


def raw_kernels_1d(keys, x):
    """phi_i(x) of eq. 8 (product of steps towards every other key),
    normalised to sum to 1: (len(x), n)."""
    keys = np.asarray(keys, dtype=np.float64)
    phi = np.ones((len(x), len(keys)))
    for i, xi in enumerate(keys):
        for j, xj in enumerate(keys):
            if i != j:
                phi[:, i] *= smooth_step((x - xj) * (xi - xj) / (xi - xj) ** 2)
    return phi / phi.sum(axis=1, keepdims=True)


# --------------------------------------------------------------------------
# figures
# --------------------------------------------------------------------------

def fig06(p, out):
    """Irregularly spaced 1-D keys: no single RBF radius suits them."""
    kx = np.array([0.0, 1.0, 2.0, 8.0, 16.0])
    ky = np.array([0.0, 1.0, 2.0, 3.0, 5.0])
    x = np.linspace(-2.0, 18.0, 801)
    fig, ax = plt.subplots(figsize=(7.2, 3.6))
    for r in (1, 3, 4, 5):
        ax.plot(x, p.weights("rbf", kx, x, radius=r) @ ky, color=RBF_GREEN, lw=1.0,
                label="Gaussian RBF, radius 1, 3, 4, 5" if r == 1 else None)
    ax.plot(x, p.weights("rbf", kx, x, radius=2) @ ky, color=RBF_RED, lw=1.4, label="Gaussian RBF, radius 2")
    ax.plot(x, p.weights("smoothVoronoi", kx, x) @ ky, color=SV_BLUE, lw=2.2, label="smooth Voronoi")
    ax.plot(kx, ky, **KEY_STYLE, label="keys")
    ax.annotate("radius 2 overshoots after x = 2", xy=(4.4, 3.55), xytext=(4.2, 5.3), fontsize=8,
                arrowprops=dict(arrowstyle="->", lw=0.8))
    ax.annotate("and steps near x = 12", xy=(12.1, 4.0), xytext=(12.6, 2.1), fontsize=8,
                arrowprops=dict(arrowstyle="->", lw=0.8))
    ax.set(xlim=(-2, 18), ylim=(-1.2, 6.0), xlabel="configuration x", ylabel="interpolated value",
           title="Fig. 6: irregular keys, smooth Voronoi vs normalised Gaussian RBF")
    ax.legend(loc="lower right")
    save(fig, out / "fig06_rbf_radius.png")


def fig07(p, out):
    """Five regularly spaced keys: Shepard and raw phi stutter (zero slope
    at every key), smooth Voronoi does not."""
    kx = np.arange(5.0)
    ky = np.array([0.0, 0.8, 2.2, 2.8, 4.0])
    x = np.linspace(-0.5, 4.5, 1001)
    curves = [
        ("smooth Voronoi (painterly)", p.weights("smoothVoronoi", kx, x) @ ky, SV_BLUE, 2.2, "-"),
        ("Shepard 1/d² (painterly)", p.weights("shepard", kx, x) @ ky, SHEP_GREEN, 1.4, "-"),
        ("φ_i used directly, Σφ_i y_i\n(eqs 7–8, corrected S; computed here)", raw_kernels_1d(kx, x) @ ky,
         RAW_RED, 1.4, "--"),
    ]
    fig, (ax, ax2) = plt.subplots(2, 1, figsize=(7.2, 5.2), sharex=True,
                                  gridspec_kw=dict(height_ratios=[3, 2]))
    for label, y, c, lw, ls in curves:
        ax.plot(x, y, color=c, lw=lw, ls=ls, label=label)
        ax2.plot(x, np.gradient(y, x), color=c, lw=lw, ls=ls)
    ax.plot(kx, ky, **KEY_STYLE, label="keys")
    ax.set(ylabel="interpolated value", title="Fig. 7: five regularly spaced keys")
    ax.legend(loc="upper left")
    for k in kx:
        ax2.axvline(k, color="k", lw=0.5, alpha=0.4)
    ax2.set(xlabel="configuration x", ylabel="slope dy/dx", ylim=(-0.9, 3.6))
    ax2.text(0.5, 0.97, "Shepard and raw φ: zero slope at every key (stutter on playback);\n"
             "smooth Voronoi keeps moving through the inner keys", transform=ax2.transAxes,
             ha="center", va="top", fontsize=7.5)
    save(fig, out / "fig07_regular_keys.png")


def fig09(p, out):
    """The 2-D basis functions w_i of the paper's five keys."""
    keys = np.array([[0.2, 0.2], [0.8, 0.8], [0.2, 0.8], [0.8, 0.2], [0.3, 0.4]])
    g = np.linspace(0.0, 1.0, 101)
    gx, gy = np.meshgrid(g, g)
    w = p.weights("smoothVoronoi", keys, np.c_[gx.ravel(), gy.ravel()])
    lo = min(-0.05, float(w.min()))
    norm = TwoSlopeNorm(vmin=lo, vcenter=0.0, vmax=1.0)
    fig, axs = plt.subplots(1, 5, figsize=(12.5, 3.0), constrained_layout=True)
    for i, ax in enumerate(axs):
        wi = w[:, i].reshape(gx.shape)
        im = ax.imshow(wi, origin="lower", extent=(-0.005, 1.005, -0.005, 1.005), cmap="RdBu_r", norm=norm,
                       interpolation="nearest")
        ax.contour(gx, gy, wi, levels=[0.1, 0.3, 0.5, 0.7, 0.9], colors="k", linewidths=0.5, alpha=0.6)
        ax.contour(gx, gy, wi, levels=[0.0], colors="k", linewidths=0.8, linestyles="--")
        ax.plot(keys[:, 0], keys[:, 1], "o", color="white", mec="black", ms=4)
        ax.plot(*keys[i], "o", color="gold", mec="black", ms=7)
        ax.set_title(f"w_{i + 1}, key ({keys[i, 0]:g}, {keys[i, 1]:g})")
        ax.set(xlabel="x₁", xticks=[0, 0.5, 1], yticks=[0, 0.5, 1])
        ax.grid(False)
        if i == 0:
            ax.set_ylabel("x₂")
    fig.colorbar(im, ax=axs, shrink=0.85, label="weight w_i", ticks=[lo, 0.0, 0.25, 0.5, 0.75, 1.0],
                 format="%.2f")
    fig.suptitle("Fig. 9: smooth Voronoi basis functions w_i in 2-D (painterly interpolate)\n"
                 "keys: dots, the function's own key in gold; contours at 0.1, 0.3, 0.5, 0.7, 0.9, dashed: w = 0; "
                 f"min w = {w.min():.2f}, max |Σw − 1| = {np.abs(w.sum(1) - 1).max():.0e}", fontsize=9.5)
    save(fig, out / "fig09_basis_2d.png")


def fig12(p, out):
    """Key values that increase while the interpolant goes down."""
    kx = np.array([0.0, 2.0, 7.5, 8.0])
    ky = np.array([0.0, 1.0, 2.0, 3.0])
    x = np.linspace(-1.0, 9.0, 1001)
    y = p.weights("smoothVoronoi", kx, x) @ ky
    fig, ax = plt.subplots(figsize=(7.2, 3.4))
    falling = np.gradient(y, x) < 0
    ax.fill_between(x, -0.5, 3.5, where=falling, color="orange", alpha=0.25, lw=0,
                    label="interpolant decreasing")
    ax.plot(x, p.weights("shepard", kx, x) @ ky, color=SHEP_GREEN, lw=1.0, ls=":", label="Shepard 1/d² (for reference)")
    ax.plot(x, y, color=SV_BLUE, lw=2.2, label="smooth Voronoi (painterly)")
    ax.plot(kx, ky, **KEY_STYLE, label="keys: values 0 < 1 < 2 < 3")
    i_max = np.argmax(np.where((x > 2) & (x < 5), y, -np.inf))
    i_min = np.argmin(np.where((x > 3) & (x < 7.5), y, np.inf))
    ax.annotate(f"local max {y[i_max]:.2f}", xy=(x[i_max], y[i_max]), xytext=(x[i_max] - 1.2, 2.0),
                fontsize=8, arrowprops=dict(arrowstyle="->", lw=0.8))
    ax.annotate(f"local min {y[i_min]:.2f}", xy=(x[i_min], y[i_min]), xytext=(x[i_min] + 0.5, 0.35),
                fontsize=8, arrowprops=dict(arrowstyle="->", lw=0.8))
    ax.set(xlim=(-1, 9), ylim=(-0.5, 3.5), xlabel="configuration x", ylabel="interpolated value",
           title="Fig. 12: monotone key values, non-monotone interpolant")
    ax.text(0.01, 0.03, "keys at x = 0, 2, 7.5, 8: the key at 7.5 takes a steep gradient from its close neighbour\n"
            "at 8, and its linear fit y = 2 + g·(x − 7.5) pulls the curve down between 2 and 7.5",
            transform=ax.transAxes, fontsize=7.5, va="bottom")
    ax.legend(loc="upper left")
    save(fig, out / "fig12_non_monotone.png")


# --------------------------------------------------------------------------
# temporal keys: bake a tiny scene and plot what painterly wrote
# --------------------------------------------------------------------------

SENT_FRAMES = (1, 60)
SENTINELS = (14.0, 46.0)
TIME_KEYS = ((22.0, 1.0), (36.0, 0.1))      # (time, opacity)
POSE_KEYS = ((0.0, 0.2), (1.0, 0.7))        # (drive, opacity)


def drive_value(f):
    """The attribute the opacity is pose-keyed to: a slow wave."""
    return 0.5 + 0.5 * np.sin(2.0 * np.pi * (f - 1.0) / 40.0)


def write_sentinel_scene(path, with_time_keys):
    sys.path.insert(0, str(REPO / "fixtures"))
    import make_fixtures as mf                              # the fixtures' authoring helpers
    from pxr import Usd, UsdGeom

    start, end = SENT_FRAMES
    stage, root = mf.new_stage(path, "Demo", start, end)
    drive = root.GetPrim().CreateAttribute("drive", mf.T.Float, custom=True)
    for f in range(start, end + 1):
        drive.Set(float(round(drive_value(f), 5)), Usd.TimeCode(f))
    UsdGeom.Xform.Define(stage, "/Demo/Rig")
    quad = np.array([[-1.0, 0.0, -1.0], [1.0, 0.0, -1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, 1.0]])
    mf.define_mesh(stage, "/Demo/Rig/Proxy", quad, [4], [0, 3, 2, 1])
    paint = mf.define_rig(stage, "/Demo/Paint", "/Demo/Rig/Proxy")
    axis = mf.define_axis(stage, paint.GetPath(), "drive", "attribute", "/Demo.drive")
    L = mf.Layer("Dab")
    L.add([[-0.5, 0.01, 0.0], [0.5, 0.01, 0.0]], [0.1, 0.1], (0.2, 0.3, 0.8), 1.0)
    curves = mf.write_layer(stage, paint.GetPath(), L)
    mf.set_layer_axes(curves, [axis])
    for k, (d, o) in enumerate(POSE_KEYS):
        mf.add_pose_key(curves, f"pose{k}", [d], opacity=o)
    if with_time_keys:
        mf.add_time_key(curves, "sentinelIn", SENTINELS[0], sentinel=True)
        for k, (t, o) in enumerate(TIME_KEYS):
            mf.add_time_key(curves, f"key{k}", t, opacity=o)
        mf.add_time_key(curves, "sentinelOut", SENTINELS[1], sentinel=True)
    stage.GetRootLayer().Save()


def baked_opacity(p, scene, tmp, name):
    from pxr import Usd
    out = pathlib.Path(tmp) / f"{name}_bake.usda"
    p.run("bake", scene, "-o", out, "--frames", f"{SENT_FRAMES[0]}:{SENT_FRAMES[1]}:0.25", "--quiet")
    stage = Usd.Stage.Open(str(scene))
    stage.GetSessionLayer().subLayerPaths.append(str(out))
    attr = stage.GetPrimAtPath("/Demo/Paint/Dab").GetAttribute("primvars:displayOpacity")
    times = np.array(attr.GetTimeSamples())
    return times, np.array([attr.Get(t)[0] for t in times])


def fig_sentinel(p, out):
    with tempfile.TemporaryDirectory() as tmp:
        keyed, plain = pathlib.Path(tmp) / "keyed.usda", pathlib.Path(tmp) / "plain.usda"
        write_sentinel_scene(keyed, True)
        write_sentinel_scene(plain, False)
        t, y = baked_opacity(p, keyed, tmp, "keyed")
        tc, yc = baked_opacity(p, plain, tmp, "plain")
    s0, s1 = SENTINELS
    (k0, o0), (k1, o1) = TIME_KEYS
    fig, ax = plt.subplots(figsize=(7.2, 3.8))
    spans = [((SENT_FRAMES[0], s0), "#eeeeee", "inactive: configuration space"),
             ((s0, k0), "#fde3c8", r"blend to the key with weight $S_{0.2}(u)$"),
             ((k0, k1), "#d5e8f7", "1-D smooth Voronoi over time keys"),
             ((k1, s1), "#fde3c8", None),
             ((s1, SENT_FRAMES[1]), "#eeeeee", None)]
    for (a, b), c, label in spans:
        ax.axvspan(a, b, color=c, lw=0, label=label)
    ax.plot(tc, yc, color="0.45", lw=1.4, ls="--", label="configuration-space value (pose keys on `drive`)")
    ax.plot(t, y, color=SV_BLUE, lw=2.2, label="baked primvars:displayOpacity")
    for s in SENTINELS:
        ax.axvline(s, color="k", lw=1.0, ls=":")
        ax.text(s, 1.07, f"sentinel\nt={s:g}", ha="center", va="bottom", fontsize=7.5)
    ax.plot([k0, k1], [o0, o1], "D", color="black", ms=6, zorder=5, label="time keys (opacity)")
    ax.set(xlim=SENT_FRAMES, ylim=(-0.05, 1.25), xlabel="time code", ylabel="opacity",
           yticks=[0, 0.25, 0.5, 0.75, 1.0])
    ax.set_title("Temporal keys (SPEC §5, Bassett Fig. 5): painterly bake of a one-stroke layer", pad=22)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), fontsize=7.5, ncol=2, frameon=False)
    save(fig, out / "sentinel_blend.png")


def save(fig, path):
    fig.savefig(path, metadata={"Software": None}, bbox_inches="tight", pad_inches=0.08)
    plt.close(fig)
    kb = path.stat().st_size / 1024
    print(f"wrote {path.relative_to(REPO) if path.is_relative_to(REPO) else path} ({kb:.0f} KB)")
    if kb > 150:
        print(f"warning: {path.name} is over 150 KB", file=sys.stderr)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.environ.get("PAINTERLY_BIN", str(REPO / "target" / "release" / "painterly")),
                    help="the painterly binary (default: $PAINTERLY_BIN or target/release/painterly)")
    ap.add_argument("--out", default=str(HERE / "figures"), help="output folder (default: docs/figures)")
    args = ap.parse_args()
    if not pathlib.Path(args.bin).exists():
        sys.exit(f"no painterly binary at {args.bin}: build it with cargo build --release")
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    style()
    p = Painterly(args.bin)
    fig06(p, out)
    fig07(p, out)
    fig09(p, out)
    fig12(p, out)
    fig_sentinel(p, out)


if __name__ == "__main__":
    main()
