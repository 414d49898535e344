"""SPEC sections 4-5: configuration axes, pose keys and temporal keys.

A third party authors stages with usd-core whose stroke layers are keyed on
axes of every kind, drives the configuration along paths through time
samples, bakes (whole and fractional frames), and compares every baked
point (1e-5 x the posed proxy's bbox diagonal) and every baked per-curve
displayOpacity (1e-5) with its own implementation (reference_keys.py:
axes with usd-core, pose-key blending with reference_interp.py, temporal
keys per SPEC section 5, skinning with reference_skinning.py).

Keys are placed where the configuration actually goes: the reference
evaluates each axis over the baked frames first, and keys sit at fractions
of the observed range. Nothing expected is read back from painterly.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom

import authoring as Au
import authoring_keys as AK
import reference_interp as RI
import reference_keys as RK
from conftest import REPO, run_painterly

POINT_TOL = 1e-5      # x bbox diagonal of the posed proxy (stroke space)
OPACITY_TOL = 1e-5

FRAMES_ARG = "1:12:0.25"
FRAMES = Au.frame_list(1, 12, 0.25)

SKEL = "/World/Character/Skel"
ANIM = "/World/Character/Anim"

# an animated, non-uniformly scaled world transform above the proxy, so that
# "proxy-local" differs from world space at every frame
WORLD_XF = Au.xf_animated({1: ((0.0, 0.0, 0.0), (0, 0, 0), (1.0, 1.0, 1.0)),
                           6: ((0.5, 0.3, -0.2), (10, 20, 0), (1.1, 1.0, 1.05)),
                           12: ((1.0, 0.5, 0.0), (0, 35, 10), (1.2, 1.0, 1.1))})


# ---------------------------------------------------------------------------
# comparison


def _stroke_scale(stage, posed, mesh, layer_path, t):
    m = np.linalg.inv(Au.gf_to_np(UsdGeom.Xformable(stage.GetPrimAtPath(layer_path))
                                  .ComputeLocalToWorldTransform(t)))
    return Au.bbox_diag(Au.apply_row(posed[mesh][t], m))


def compare(case, layers=None):
    """Every point and per-curve opacity of `layers` at every frame; returns
    a list of failure descriptions (worst point per layer, first opacity)."""
    rig, out, expected, posed, frames = case["rig"], case["out"], case["expected"], case["posed"], case["frames"]
    layers = layers if layers is not None else list(expected)
    comp = Au.compose(rig.path, out)
    src = Usd.Stage.Open(str(rig.path))
    bake_layer = Sdf.Layer.FindOrOpen(str(out))
    problems = []
    for lp in layers:
        pp = Sdf.Path(lp).AppendProperty("points")
        got_times = sorted(bake_layer.ListTimeSamplesForPath(pp))
        if len(got_times) != len(frames) or not np.allclose(got_times, frames):
            problems.append(f"{lp}.points: time samples {got_times} are not the baked frames")
            continue
        worst = (0.0, None, None)
        for t in frames:
            ours = Au.local_points(comp, lp, t)
            exp = expected[lp]["points"][t]
            if ours.shape != exp.shape:
                problems.append(f"{lp} t={t}: {ours.shape} points, expected {exp.shape}")
                break
            err = np.linalg.norm(ours - exp, axis=1) / _stroke_scale(src, posed, rig.mesh, lp, t)
            if err.max() > worst[0]:
                worst = (float(err.max()), t, int(err.argmax()))
        if worst[0] > POINT_TOL:
            t = worst[1]
            problems.append(f"{lp}: point {worst[2]} off by {worst[0]:.3g} x bbox diagonal at t={t} "
                            f"(config {expected[lp]['config'][t]}, keyed opacity "
                            f"{expected[lp]['keyed_opacity'][t]:.6g})")
        pv = UsdGeom.PrimvarsAPI(comp.GetPrimAtPath(lp)).GetPrimvar("displayOpacity")
        if not (pv and pv.HasAuthoredValue()):
            problems.append(f"{lp}: no primvars:displayOpacity in the composed result")
            continue
        for t in frames:
            exp = expected[lp]["opacity"][t]
            vals = np.array(pv.ComputeFlattened(t), dtype=np.float64)
            if pv.GetInterpolation() == UsdGeom.Tokens.constant and len(vals) == 1:
                vals = np.full(len(exp), vals[0])
            if vals.shape != exp.shape or np.abs(vals - exp).max() > OPACITY_TOL:
                problems.append(f"{lp}: displayOpacity at t={t} is {vals}, expected {exp} "
                                f"(keyed opacity {expected[lp]['keyed_opacity'][t]:.6g}, "
                                f"config {expected[lp]['config'][t]})")
                break
    return problems


def bake_and_expect(rig, d, frames_arg=FRAMES_ARG, frames=FRAMES, camera=None, name="bake.usdc"):
    out = d / name
    args = ["bake", rig.path, "-o", out, "--quiet", "--frames", frames_arg]
    if camera:
        args += ["--camera", camera]
    before = Au.file_hash(rig.path)
    run_painterly(*args)
    assert out.exists(), "bake reported success but wrote no file"
    assert Au.file_hash(rig.path) == before, "bake modified its input"
    expected, posed = RK.expected_bake(rig.path, frames, camera=camera)
    return dict(rig=rig, out=out, expected=expected, posed=posed, frames=frames, camera=camera)


def _check(case, layers):
    problems = compare(case, layers)
    assert not problems, "\n".join(problems)


def _pose_keys_on_axis(stage, lp, rest, values, rng, op_values=(0.2, 0.9), amp=0.15):
    """3 position keys and 2 opacity keys on a layer keyed to one axis."""
    for i, c in enumerate(AK.key_positions(values, (0.1, 0.55, 0.95))):
        AK.add_pose_key(stage, lp, f"pos{i}", [c], points=AK.displaced(rest, rng, amp))
    for i, (c, o) in enumerate(zip(AK.key_positions(values, (0.3, 0.8)), op_values)):
        AK.add_pose_key(stage, lp, f"op{i}", [c], opacity=o)


# ---------------------------------------------------------------------------
# one layer per axis kind


def _attr(short):
    return lambda ctl, loc, cam: ctl[short]


AXIS_SPECS = {
    # attribute: scalar (double, float), array element, vector component,
    # quaternion components (x and w), array of vectors (element, component)
    "scalar": dict(kind="attribute", source=_attr("scalar")),
    "floatScaled": dict(kind="attribute", source=_attr("float"), scale=2.0),
    "arrayElem": dict(kind="attribute", source=_attr("array"), element=2),
    "vecComp": dict(kind="attribute", source=_attr("vec"), component=1),
    "quatX": dict(kind="attribute", source=_attr("quat"), component=0),
    "quatW": dict(kind="attribute", source=_attr("quat"), component=3),
    "vecArray": dict(kind="attribute", source=_attr("vecArray"), element=1, component=2),
    # blendShape (the name is not listed first in the animation) and one
    # the animation does not list (value 0)
    "bsPinch": dict(kind="blendShape", source=lambda *a: ANIM, name="pinch"),
    "bsMissing": dict(kind="blendShape", source=lambda *a: ANIM, name="nope"),
    # jointRotation: animated joints (reordered sparse animation) with a
    # rotated rest transform, and an unanimated joint (rest: value 0)
    "jointTip1": dict(kind="jointRotation", source=lambda *a: SKEL, name="root/mid/tip", component=1),
    "jointTip2": dict(kind="jointRotation", source=lambda *a: SKEL, name="root/mid/tip", component=2,
                      scale=2.5),
    "jointEnd1": dict(kind="jointRotation", source=lambda *a: SKEL, name="root/mid/tip/end", component=1),
    "jointRoot2": dict(kind="jointRotation", source=lambda *a: SKEL, name="root", component=2),
    "jointRestOnly": dict(kind="jointRotation", source=lambda *a: SKEL, name="root/mid", component=1),
    # position of an animated locator under an animated parent
    "posY": dict(kind="position", source=lambda ctl, loc, cam: loc, component=1),
    "posXScaled": dict(kind="position", source=lambda ctl, loc, cam: loc, component=0, scale=0.5),
    # viewDirection: an orbiting camera by relationship, and --camera
    "viewSrcX": dict(kind="viewDirection", source=lambda ctl, loc, cam: cam, component=0),
    "viewSrcZ": dict(kind="viewDirection", source=lambda ctl, loc, cam: cam, component=2),
    "viewCamY": dict(kind="viewDirection", source=None, component=1),
    "viewCamZ": dict(kind="viewDirection", source=None, component=2),
}


@pytest.fixture(scope="module")
def axes_case(tmp_path_factory):
    d = tmp_path_factory.mktemp("axes")
    rig = Au.build_skel_rig(d / "axes.usda", blend_shapes={"dense", "indexed"}, sparse_anim=True,
                            world_xform=WORLD_XF, n_strokes=3)
    stage = Usd.Stage.Open(str(rig.path))
    ctl = AK.add_controls(stage)
    loc = AK.add_locator(stage)
    cam = AK.add_orbit_camera(stage)
    camb = AK.add_moving_camera(stage)
    AK.set_rest_rotation(stage, SKEL, "root/mid", (0, 1, 1), 25)        # unanimated joint
    AK.set_rest_rotation(stage, SKEL, "root/mid/tip", (1, 0, 0.5), 40)  # animated joint
    axis_paths = {}
    for name, spec in AXIS_SPECS.items():
        src = spec["source"](ctl, loc, cam) if spec["source"] else None
        kw = {k: v for k, v in spec.items() if k not in ("kind", "source")}
        axis_paths[name] = str(AK.add_axis(stage, f"{rig.rig}/{name}", spec["kind"], source=src, **kw).GetPath())
    stage.GetRootLayer().Save()

    values = RK.axis_values_over(rig.path, list(axis_paths.values()), FRAMES, camera=camb)
    rng = np.random.default_rng(20)
    stage = Usd.Stage.Open(str(rig.path))
    layers = {}
    for i, (name, ap) in enumerate(axis_paths.items()):
        lp = f"{rig.rig}/L_{name}"
        extra = {}
        if i % 3 == 1:
            extra["display_opacity"] = [0.5 + 0.1 * k for k in range(3)]
        rest, _ = AK.add_layer(stage, rig, lp, rng, n_strokes=3, **extra)
        AK.set_layer_axes(stage, lp, [ap])
        _pose_keys_on_axis(stage, lp, rest, values[ap], rng)
        layers[name] = lp
    # a time-sampled layer opacity on one layer
    stage.GetPrimAtPath(layers["scalar"]).CreateAttribute(
        "painterly:opacity", Sdf.ValueTypeNames.Float, False).Set(0.4, 1)
    stage.GetPrimAtPath(layers["scalar"]).GetAttribute("painterly:opacity").Set(1.0, 12)
    stage.GetRootLayer().Save()
    rig.layers = list(rig.layers) + list(layers.values())
    case = bake_and_expect(rig, d, camera=camb)
    case.update(layers=layers, values=values, axis_paths=axis_paths)
    return case


def test_axis_layers_move(axes_case):
    """Sanity of the fixture itself: every axis moves (or, for the two
    constant ones, sits strictly between keys), so every layer's keyed
    points actually change with the configuration."""
    for name, ap in axes_case["axis_paths"].items():
        v = axes_case["values"][ap]
        if name in ("bsMissing", "jointRestOnly"):
            assert np.allclose(v, 0.0, atol=1e-6), f"{name}: expected constant 0, reference says {v}"
        else:
            assert np.ptp(v) > 0.05, f"{name}: the axis barely moves ({np.ptp(v):.3g}); test would be weak"
        lp = axes_case["layers"][name]
        rests = axes_case["expected"][lp]["rest"]
        spread = max(np.abs(rests[t] - rests[FRAMES[0]]).max() for t in FRAMES)
        if name not in ("bsMissing", "jointRestOnly"):
            assert spread > 0.01, f"{name}: keyed rest points do not move"


@pytest.mark.parametrize("name", list(AXIS_SPECS))
def test_single_axis_layer(axes_case, name):
    _check(axes_case, [axes_case["layers"][name]])


def test_unkeyed_layer_is_pure_skinning(axes_case):
    """The rig's original layer has no keys: rest points skinned, opacity 1."""
    _check(axes_case, ["/World/Paint/Strokes"])


def test_int_attribute_axis_holds_between_samples(tmp_path):
    """An int attribute is not interpolated by USD (held values)."""
    rig = Au.build_skel_rig(tmp_path / "int.usda", n_strokes=3)
    stage = Usd.Stage.Open(str(rig.path))
    ctl = AK.add_controls(stage)
    ax = AK.add_axis(stage, f"{rig.rig}/step", "attribute", source=ctl["int"])
    rng = np.random.default_rng(4)
    lp = f"{rig.rig}/L_step"
    rest, _ = AK.add_layer(stage, rig, lp, rng, n_strokes=3)
    AK.set_layer_axes(stage, lp, [ax.GetPath()])
    for i, c in enumerate((0.0, 1.0, 2.0)):
        AK.add_pose_key(stage, lp, f"pos{i}", [c], points=AK.displaced(rest, rng, 0.2), opacity=0.3 + 0.3 * i)
    stage.GetRootLayer().Save()
    rig.layers = list(rig.layers) + [lp]
    case = bake_and_expect(rig, tmp_path)
    _check(case, [lp])


def test_joint_axis_reads_an_animation_inherited_from_the_skel_root(tmp_path):
    """`skel:animationSource` on the SkelRoot, not on the Skeleton: usd-core
    (GetInheritedAnimationSource) animates the joints, and so must the axis."""
    from pxr import UsdSkel

    rig = Au.build_skel_rig(tmp_path / "inherited.usda", n_strokes=3)
    stage = Usd.Stage.Open(str(rig.path))
    skel = stage.GetPrimAtPath(SKEL)
    anim = UsdSkel.BindingAPI(skel).GetAnimationSourceRel().GetTargets()
    skel.RemoveProperty("skel:animationSource")
    UsdSkel.BindingAPI.Apply(skel.GetParent()).CreateAnimationSourceRel().SetTargets(anim)
    ap = str(AK.add_axis(stage, f"{rig.rig}/tip", "jointRotation", source=SKEL, name="root/mid/tip",
                         component=2).GetPath())
    stage.GetRootLayer().Save()
    values = RK.axis_values_over(rig.path, [ap], FRAMES)
    assert np.ptp(values[ap]) > 0.05, "the joint does not turn: the test would be weak"
    rng = np.random.default_rng(5)
    stage = Usd.Stage.Open(str(rig.path))
    lp = f"{rig.rig}/L_tip"
    rest, _ = AK.add_layer(stage, rig, lp, rng, n_strokes=3)
    AK.set_layer_axes(stage, lp, [ap])
    _pose_keys_on_axis(stage, lp, rest, values[ap], rng)
    stage.GetRootLayer().Save()
    rig.layers = list(rig.layers) + [lp]
    _check(bake_and_expect(rig, tmp_path), [lp])


def test_joint_axis_reads_zero_for_a_mirrored_joint_held_at_rest(tmp_path):
    """A mirrored rest transform (scale -1 on x, as mirrored limbs export)
    whose animation holds UsdSkel.DecomposeTransform of it: usd-core poses
    the joint exactly at rest, so the axis reads 0 (SPEC §4). glam split the
    rest as scale (-1, 1, 1) and no rotation, the animation as a half turn
    with scale (-1, -1, -1), and the axis read pi (a keys review, 2026-12-06)."""
    from pxr import Gf, UsdSkel, Vt

    rig = Au.build_skel_rig(tmp_path / "mirror.usda", n_strokes=3)
    stage = Usd.Stage.Open(str(rig.path))
    skel = UsdSkel.Skeleton(stage.GetPrimAtPath(SKEL))
    joints = list(skel.GetJointsAttr().Get())
    joint = "root/mid/tip"
    rest = list(skel.GetRestTransformsAttr().Get())
    mirrored = Gf.Matrix4d().SetScale(Gf.Vec3d(-1, 1, 1)) * rest[joints.index(joint)]
    rest[joints.index(joint)] = mirrored
    skel.GetRestTransformsAttr().Set(rest)
    tr, rot, sc = UsdSkel.DecomposeTransform(mirrored)
    anim = UsdSkel.Animation(stage.GetPrimAtPath(ANIM))
    k = list(anim.GetJointsAttr().Get()).index(joint)
    for name, value in (("translations", Gf.Vec3f(tr)), ("rotations", Gf.Quatf(rot)), ("scales", Gf.Vec3h(sc))):
        attr = anim.GetPrim().GetAttribute(name)
        for t in attr.GetTimeSamples() or [Usd.TimeCode.Default()]:
            v = list(attr.Get(t))
            v[k] = value
            attr.Set(type(attr.Get(t))(v), t)
    ap = str(AK.add_axis(stage, f"{rig.rig}/tip", "jointRotation", source=SKEL, name=joint, component=0).GetPath())
    rng = np.random.default_rng(6)
    lp = f"{rig.rig}/L_tip"
    AK.add_layer(stage, rig, lp, rng, n_strokes=3)
    AK.set_layer_axes(stage, lp, [ap])
    AK.add_pose_key(stage, lp, "atRest", [0.0], opacity=1.0)
    AK.add_pose_key(stage, lp, "halfTurn", [math.pi], opacity=0.0)
    stage.GetRootLayer().Save()
    cache = UsdSkel.Cache()
    stage = Usd.Stage.Open(str(rig.path))
    cache.Populate(UsdSkel.Root(stage.GetPrimAtPath("/World/Character")), Usd.PrimDefaultPredicate)
    query = cache.GetSkelQuery(UsdSkel.Skeleton(stage.GetPrimAtPath(SKEL)))
    assert Gf.IsClose(Gf.Matrix4d(query.ComputeJointLocalTransforms(5.0)[joints.index(joint)]), mirrored, 1e-5)
    assert np.allclose(RK.axis_values_over(rig.path, [ap], [1.0, 5.0, 12.0])[ap], 0.0, atol=1e-6)
    out = tmp_path / "bake.usdc"
    run_painterly("bake", rig.path, "-o", out, "--frames", "1:12", "--quiet")
    comp = Au.compose(rig.path, out)
    for t in (1.0, 5.0, 12.0):
        op = UsdGeom.PrimvarsAPI(comp.GetPrimAtPath(lp)).GetPrimvar("displayOpacity").Get(t)
        assert np.allclose(np.asarray(op), 1.0, atol=1e-6), (t, op)


def test_points_proxy_position_and_view_axes(tmp_path):
    """A proxy with time-sampled points under an animated transform (not
    skinned): position and viewDirection measured in its local space, bbox
    centre of its posed points."""
    rig = Au.build_points_rig(tmp_path / "pts.usda", mode="sampled", frames=(1, 12), n_strokes=3,
                              proxy_xform=Au.xf_animated({1: ((0, 0, 0), (0, 0, 0), (1, 1, 1)),
                                                          12: ((1, -1, 0.5), (20, 0, 30), (1.3, 0.9, 1.0))}))
    stage = Usd.Stage.Open(str(rig.path))
    loc = AK.add_locator(stage)
    cam = AK.add_orbit_camera(stage, degrees=(-40, 200))
    axes = [str(AK.add_axis(stage, f"{rig.rig}/view", "viewDirection", source=cam, component=0).GetPath()),
            str(AK.add_axis(stage, f"{rig.rig}/locZ", "position", source=loc, component=2, scale=0.7).GetPath())]
    stage.GetRootLayer().Save()
    values = RK.axis_values_over(rig.path, axes, FRAMES)
    rng = np.random.default_rng(9)
    stage = Usd.Stage.Open(str(rig.path))
    layers = []
    for ap in axes:
        lp = f"{rig.rig}/L_{Sdf.Path(ap).name}"
        rest, _ = AK.add_layer(stage, rig, lp, rng, n_strokes=3)
        AK.set_layer_axes(stage, lp, [ap])
        _pose_keys_on_axis(stage, lp, rest, values[ap], rng)
        layers.append(lp)
    stage.GetRootLayer().Save()
    rig.layers = list(rig.layers) + layers
    case = bake_and_expect(rig, tmp_path)
    _check(case, rig.layers)


# ---------------------------------------------------------------------------
# several axes of mixed kinds, default / subset / reordered axes, rbf, shepard


@pytest.fixture(scope="module")
def multi_case(tmp_path_factory):
    d = tmp_path_factory.mktemp("multi")
    rig = Au.build_skel_rig(d / "multi.usda", blend_shapes={"dense", "indexed"}, world_xform=WORLD_XF,
                            n_strokes=3)
    stage = Usd.Stage.Open(str(rig.path))
    loc = AK.add_locator(stage)
    # namespace (depth-first) order zeta, alpha, mid -- neither alphabetical,
    # nor path-sorted, nor breadth-first
    zeta = AK.add_axis(stage, f"{rig.rig}/zeta", "blendShape", source=ANIM, name="bulge", scale=2.0)
    UsdGeom.Xform.Define(stage, f"{rig.rig}/Group")
    alpha = AK.add_axis(stage, f"{rig.rig}/Group/alpha", "jointRotation", source=SKEL, name="root/mid",
                        component=0)
    mid = AK.add_axis(stage, f"{rig.rig}/mid", "position", source=loc, component=1, scale=0.5)
    axes = [str(a.GetPath()) for a in (zeta, alpha, mid)]
    stage.GetRootLayer().Save()

    vals = RK.axis_values_over(rig.path, axes, FRAMES)
    X = np.stack([vals[a] for a in axes], axis=1)          # configuration path, DFS order
    span = np.ptp(X, axis=0)
    assert np.all(span > 0.05), f"axes barely move: {span}"
    fi = {t: i for i, t in enumerate(FRAMES)}
    rng = np.random.default_rng(31)

    def near(ts, cols):
        P = X[[fi[float(t)] for t in ts]][:, cols]
        return P + rng.normal(0.0, 0.08, P.shape) * span[cols]

    stage = Usd.Stage.Open(str(rig.path))
    layers = {}

    # L_mixed: 5 position keys, 3 opacity keys; key 0 carries both channels;
    # an opacity-only key sits at position key 2's coordinates (other channel)
    lp = f"{rig.rig}/L_mixed"
    rest, _ = AK.add_layer(stage, rig, lp, rng, n_strokes=3, display_opacity=[0.9, 0.6, 0.3])
    AK.set_layer_axes(stage, lp, axes)
    pos_c = near([1, 4, 7, 10, 12], [0, 1, 2])
    for i, c in enumerate(pos_c):
        AK.add_pose_key(stage, lp, f"pos{i}", c, points=AK.displaced(rest, rng, 0.15),
                        opacity=0.25 if i == 0 else None)
    op_c = near([6, 11], [0, 1, 2])
    AK.add_pose_key(stage, lp, "op0", op_c[0], opacity=0.8)
    AK.add_pose_key(stage, lp, "op1", pos_c[2], opacity=0.55)
    AK.add_pose_key(stage, lp, "op2", op_c[1], opacity=1.0)
    op = stage.GetPrimAtPath(lp).CreateAttribute("painterly:opacity", Sdf.ValueTypeNames.Float, False)
    op.Set(1.0, 1)
    op.Set(0.5, 7)
    layers["mixed"] = lp

    # L_default: no painterly:axes -> every axis under the rig, DFS order
    lp = f"{rig.rig}/L_default"
    rest, _ = AK.add_layer(stage, rig, lp, rng, n_strokes=3)
    for i, c in enumerate(near([1, 5, 9, 12], [0, 1, 2])):
        AK.add_pose_key(stage, lp, f"pos{i}", c, points=AK.displaced(rest, rng, 0.15))
    for i, c in enumerate(near([3, 10], [0, 1, 2])):
        AK.add_pose_key(stage, lp, f"op{i}", c, opacity=0.3 + 0.5 * i)
    layers["default"] = lp

    # L_subset: painterly:axes = [mid, zeta] (a reordered subset)
    lp = f"{rig.rig}/L_subset"
    rest, _ = AK.add_layer(stage, rig, lp, rng, n_strokes=3)
    AK.set_layer_axes(stage, lp, [axes[2], axes[0]])
    for i, c in enumerate(near([2, 6, 9, 12], [2, 0])):
        AK.add_pose_key(stage, lp, f"pos{i}", c, points=AK.displaced(rest, rng, 0.15))
    for i, c in enumerate(near([4, 11], [2, 0])):
        AK.add_pose_key(stage, lp, f"op{i}", c, opacity=0.9 - 0.6 * i)
    layers["subset"] = lp

    # L_rbf / L_shepard: L_mixed's key coordinates, other interpolation
    dists = [np.linalg.norm(a - b) for i, a in enumerate(pos_c) for b in pos_c[i + 1:]]
    for method in ("rbf", "shepard"):
        lp = f"{rig.rig}/L_{method}"
        rest, _ = AK.add_layer(stage, rig, lp, rng, n_strokes=3)
        AK.set_layer_axes(stage, lp, axes)
        AK.set_interpolation(stage, lp, method, radius=float(np.median(dists)) if method == "rbf" else None)
        for i, c in enumerate(pos_c):
            AK.add_pose_key(stage, lp, f"pos{i}", c, points=AK.displaced(rest, rng, 0.15))
        for i, c in enumerate(op_c):
            AK.add_pose_key(stage, lp, f"op{i}", c, opacity=0.2 + 0.6 * i)
        layers[method] = lp

    # L_single: smoothVoronoi authored explicitly, a single position+opacity key (holds everywhere)
    lp = f"{rig.rig}/L_single"
    rest, _ = AK.add_layer(stage, rig, lp, rng, n_strokes=2)
    AK.set_interpolation(stage, lp, "smoothVoronoi")
    AK.add_pose_key(stage, lp, "only", near([5], [0, 1, 2])[0], points=AK.displaced(rest, rng, 0.2),
                    opacity=0.35)
    layers["single"] = lp
    stage.GetRootLayer().Save()
    rig.layers = list(rig.layers) + list(layers.values())
    case = bake_and_expect(rig, d)
    case.update(layers=layers, axes=axes)
    return case


@pytest.mark.parametrize("name", ["mixed", "default", "subset", "rbf", "shepard", "single"])
def test_multi_axis_layer(multi_case, name):
    _check(multi_case, [multi_case["layers"][name]])


def test_reference_axis_order_matters(multi_case):
    """The fixture can tell axis orders apart: feeding L_default's keys with
    alphabetical order instead of namespace order changes the reference."""
    exp = multi_case["expected"][multi_case["layers"]["default"]]
    stage = Usd.Stage.Open(str(multi_case["rig"].path))
    lp = stage.GetPrimAtPath(multi_case["layers"]["default"])
    pos, _ = RK.pose_keys(lp)
    K = np.array([k[1] for k in pos])
    X = np.array([exp["config"][t] for t in FRAMES])
    perm = [1, 2, 0]  # alpha, mid, zeta
    W = RI.smooth_voronoi_weights(K, X)
    W2 = RI.smooth_voronoi_weights(K, X[:, perm])
    assert np.abs(W - W2).max() > 0.05


def _scaled_axes_rig(path, scales):
    """A usd-core rig whose one layer is keyed on two attribute axes with
    the given scales; the keys sit exactly at the axis values (in axis
    units) of frames 2, 6 and 10."""
    rig = Au.build_skel_rig(path, frames=(1, 12), n_strokes=4)
    stage = Usd.Stage.Open(str(rig.path))
    knobs = stage.DefinePrim("/World/Knobs", "Scope")
    a_vals = {t: float(t - 1) for t in range(1, 13)}
    b_vals = dict(zip(range(1, 13), [0, 1.5, 3, 2, 0.5, -1, -2.5, -1, 0.5, 2, 3, 1]))
    for name, vals in (("a", a_vals), ("b", b_vals)):
        attr = knobs.CreateAttribute(name, Sdf.ValueTypeNames.Double, True)
        for t, v in vals.items():
            attr.Set(float(v), float(t))
    axes = [AK.add_axis(stage, f"{rig.rig}/{n}", "attribute", source=f"/World/Knobs.{n}", scale=sc).GetPath()
            for n, sc in zip("ab", scales)]
    lp = rig.layers[0]
    AK.set_layer_axes(stage, lp, axes)
    rest = AK.layer_rest(stage, lp)
    rng = np.random.default_rng(5)
    for t in (2, 6, 10):
        AK.add_pose_key(stage, lp, f"k{t}", [a_vals[t], b_vals[t]], points=AK.displaced(rest, rng, 0.2))
    stage.GetRootLayer().Save()
    rig.layers = [lp]
    return rig


def test_rescaling_an_axis_never_moves_its_keys(tmp_path):
    """SPEC 1.1 section 4: key coordinates are in axis units, interpolation
    runs on scaled coordinates. The same keys under scales (1, 1) and
    (8, 0.25): both bakes match the reference; at the keys' frames both
    show the keys (a key stored in scaled units would be missed by the
    re-scaled one); between keys the scale reshapes the blend."""
    cases = {}
    for name, scales in (("unit", (1.0, 1.0)), ("scaled", (8.0, 0.25))):
        d = tmp_path / name
        d.mkdir()
        cases[name] = bake_and_expect(_scaled_axes_rig(d / "rig.usda", scales), d, frames_arg="1:12:0.5",
                                      frames=Au.frame_list(1, 12, 0.5))
        _check(cases[name], None)
    lp = cases["unit"]["rig"].layers[0]
    comp = {n: Au.compose(c["rig"].path, c["out"]) for n, c in cases.items()}
    diag = Au.bbox_diag(Au.local_points(comp["unit"], lp, 1.0))
    diff = {t: float(np.abs(Au.local_points(comp["unit"], lp, t) - Au.local_points(comp["scaled"], lp, t)).max())
            for t in Au.frame_list(1, 12, 0.5)}
    for t in (2.0, 6.0, 10.0):
        assert diff[t] <= 1e-6 * diag, f"the key at t={t} moved by {diff[t]} when the axes were re-scaled"
    assert max(diff.values()) > 1e-3 * diag, "re-scaling the axes did not change the blend between keys"


# ---------------------------------------------------------------------------
# temporal keys


@pytest.fixture(scope="module")
def time_case(tmp_path_factory):
    d = tmp_path_factory.mktemp("time")
    rig = Au.build_skel_rig(d / "time.usda", blend_shapes={"dense"}, world_xform=WORLD_XF, n_strokes=3)
    stage = Usd.Stage.Open(str(rig.path))
    bulge = AK.add_axis(stage, f"{rig.rig}/bulge", "blendShape", source=ANIM, name="bulge")
    stage.GetRootLayer().Save()
    vals = RK.axis_values_over(rig.path, [str(bulge.GetPath())], FRAMES)[str(bulge.GetPath())]
    rng = np.random.default_rng(77)
    stage = Usd.Stage.Open(str(rig.path))
    layers = {}

    def layer(name, **kw):
        lp = f"{rig.rig}/{name}"
        rest, _ = AK.add_layer(stage, rig, lp, rng, n_strokes=3, **kw)
        layers[name] = lp
        return lp, rest

    def pts(rest):
        return AK.displaced(rest, rng, 0.2)

    # the "shock": sentinel, key, key, sentinel; the opacity channel has its
    # own keys (5 and 6), the position channel 5 and 7
    lp, rest = layer("T_shock")
    AK.add_time_key(stage, lp, "s0", 3, sentinel=True)
    AK.add_time_key(stage, lp, "k5", 5, points=pts(rest), opacity=0.2)
    AK.add_time_key(stage, lp, "k6op", 6, opacity=0.7)
    AK.add_time_key(stage, lp, "k7", 7.5, points=pts(rest))
    AK.add_time_key(stage, lp, "s1", 9, sentinel=True)

    # keys only, no sentinel: hold before the first and after the last key
    lp, rest = layer("T_keysOnly")
    AK.add_time_key(stage, lp, "a", 4, points=pts(rest), opacity=0.3)
    AK.add_time_key(stage, lp, "b", 8, points=pts(rest), opacity=0.9)
    AK.add_time_key(stage, lp, "c", 10.5, points=pts(rest))

    # a sentinel at the start, then one key that holds to the end
    lp, rest = layer("T_startSentinel", display_opacity=[0.5, 1.0, 0.8])
    AK.add_time_key(stage, lp, "s", 2, sentinel=True)
    AK.add_time_key(stage, lp, "k", 6, points=pts(rest), opacity=0.4)

    # two groups split by a sentinel; a points-only and an opacity-only key
    # share a time (different channels: allowed)
    lp, rest = layer("T_groups")
    AK.add_time_key(stage, lp, "k2", 2, points=pts(rest), opacity=0.6)
    AK.add_time_key(stage, lp, "k4", 4, points=pts(rest))
    AK.add_time_key(stage, lp, "s6", 6, sentinel=True)
    AK.add_time_key(stage, lp, "k8", 8, points=pts(rest))
    AK.add_time_key(stage, lp, "k9p", 9, points=pts(rest))
    AK.add_time_key(stage, lp, "k9o", 9, opacity=0.1)
    AK.add_time_key(stage, lp, "k11", 11, points=pts(rest), opacity=0.75)

    # pose keys (on the blend shape) and time keys together: the sentinel
    # blends start from the moving configuration-space value
    lp, rest = layer("T_poseAndTime")
    for i, c in enumerate(AK.key_positions(vals, (0.05, 0.5, 0.95))):
        AK.add_pose_key(stage, lp, f"pos{i}", [c], points=pts(rest))
    for i, c in enumerate(AK.key_positions(vals, (0.2, 0.9))):
        AK.add_pose_key(stage, lp, f"op{i}", [c], opacity=0.3 + 0.6 * i)
    AK.add_time_key(stage, lp, "s0", 3.5, sentinel=True)
    AK.add_time_key(stage, lp, "k", 6, points=pts(rest), opacity=0.05)
    AK.add_time_key(stage, lp, "k2", 7, points=pts(rest))
    AK.add_time_key(stage, lp, "s1", 10, sentinel=True)

    # sentinels only: inactive everywhere
    lp, rest = layer("T_sentinelsOnly")
    AK.add_pose_key(stage, lp, "pos0", [float(vals.min())], points=pts(rest), opacity=0.5)
    AK.add_pose_key(stage, lp, "pos1", [float(vals.max())], points=pts(rest), opacity=1.0)
    AK.add_time_key(stage, lp, "s0", 4, sentinel=True)
    AK.add_time_key(stage, lp, "s1", 8, sentinel=True)
    stage.GetRootLayer().Save()
    rig.layers = list(rig.layers) + list(layers.values())
    case = bake_and_expect(rig, d)
    case.update(layers=layers)
    return case


@pytest.mark.parametrize("name", ["T_shock", "T_keysOnly", "T_startSentinel", "T_groups", "T_poseAndTime",
                                  "T_sentinelsOnly"])
def test_time_keyed_layer(time_case, name):
    _check(time_case, [time_case["layers"][name]])


def test_time_keys_at_whole_frames_only(tmp_path):
    """The same timeline baked on whole frames only (no fractional
    interpolation of the proxy involved)."""
    rig = Au.build_skel_rig(tmp_path / "t.usda", n_strokes=3)
    stage = Usd.Stage.Open(str(rig.path))
    rng = np.random.default_rng(3)
    lp = f"{rig.rig}/L"
    rest, _ = AK.add_layer(stage, rig, lp, rng, n_strokes=3)
    AK.add_time_key(stage, lp, "s0", 2, sentinel=True)
    AK.add_time_key(stage, lp, "a", 5, points=AK.displaced(rest, rng, 0.2), opacity=0.25)
    AK.add_time_key(stage, lp, "b", 6, points=AK.displaced(rest, rng, 0.2), opacity=0.5)
    AK.add_time_key(stage, lp, "c", 8, points=AK.displaced(rest, rng, 0.2), opacity=0.75)
    AK.add_time_key(stage, lp, "s1", 11, sentinel=True)
    stage.GetRootLayer().Save()
    rig.layers = list(rig.layers) + [lp]
    case = bake_and_expect(rig, tmp_path, frames_arg="1:12", frames=Au.frame_list(1, 12))
    _check(case, [lp])


# ---------------------------------------------------------------------------
# inspect


@pytest.mark.parametrize("which", ["multi", "time", "axes"])
def test_inspect_counts(request, which):
    case = request.getfixturevalue(f"{which}_case")
    rig = case["rig"]
    # inspect vouches for the bake with the same --camera (a viewDirection
    # axis without a source needs one).
    camera = ["--camera", case["camera"]] if case["camera"] else []
    proc = run_painterly("inspect", rig.path, "--json", *camera)
    report = json.loads(proc.stdout)
    got = {l["path"]: l for r in report["rigs"] for l in r["layers"]}
    stage = Usd.Stage.Open(str(rig.path))
    problems = []
    for lp in rig.layers:
        prim = stage.GetPrimAtPath(lp)
        pos, op = RK.pose_keys(prim)
        sentinels, tpos, top = RK.time_keys(prim)
        normal = sum(1 for c in prim.GetChildren() if c.GetTypeName() == "PainterlyTimeKey"
                     and not RK.authored(c, "sentinel", False))
        want = dict(pose_position_keys=len(pos), pose_opacity_keys=len(op), time_keys=normal,
                    sentinels=len(sentinels))
        if lp not in got:
            problems.append(f"{lp} missing from inspect --json")
            continue
        for k, v in want.items():
            if got[lp].get(k) != v:
                problems.append(f"{lp}: {k} = {got[lp].get(k)}, expected {v}")
    assert not problems, "\n".join(problems)
    assert report.get("problems", []) == [], report.get("problems")


# ---------------------------------------------------------------------------
# the reference checks itself (so a wrong reference cannot pass silently)


def test_reference_quaternion_helpers():
    rng = np.random.default_rng(0)
    for _ in range(20):
        axis = rng.normal(size=3)
        deg = rng.uniform(-170, 170)
        a = RK.quat_axis_angle(axis, deg)
        b = RK.quat_axis_angle(rng.normal(size=3), rng.uniform(-170, 170))
        ga = Gf.Quatd(a[0], Gf.Vec3d(*a[1:]))
        gb = Gf.Quatd(b[0], Gf.Vec3d(*b[1:]))
        np.testing.assert_allclose(RK.quat_mul(a, b), RK.quat_np(ga * gb), atol=1e-12)
        m = Gf.Matrix4d().SetRotate(ga)
        q = RK.row_matrix_to_quat(Au.gf_to_np(m))
        assert min(np.abs(q - a).max(), np.abs(q + a).max()) < 1e-9
        np.testing.assert_allclose(RK.quat_to_row_matrix(a), Au.gf_to_np(m)[:3, :3], atol=1e-12)
        want = axis / np.linalg.norm(axis) * math.radians(deg)
        np.testing.assert_allclose(RK.rotation_vector(a), want, atol=1e-12)
        np.testing.assert_allclose(RK.rotation_vector(-a), want, atol=1e-12)
        np.testing.assert_allclose(RK.quat_mul(RK.quat_inv(a), a), [1, 0, 0, 0], atol=1e-12)


def test_reference_temporal_rules():
    S = lambda u: float(RI.smooth_step(u))  # noqa: E731
    normals = [(5.0, 1.0), (7.0, 3.0)]
    sentinels = [3.0, 9.0]
    cfg = 10.0
    f = lambda t: RK.temporal_value(t, cfg, normals, sentinels)  # noqa: E731
    assert f(1.0) == cfg and f(3.0) == cfg and f(9.0) == cfg and f(11.0) == cfg
    assert f(5.0) == 1.0 and f(7.0) == 3.0
    assert f(4.0) == pytest.approx((1 - S(0.5)) * cfg + S(0.5) * 1.0)
    assert f(8.5) == pytest.approx((1 - S(0.25)) * cfg + S(0.25) * 3.0)
    # continuity around every event
    for t0 in (3.0, 5.0, 7.0, 9.0):
        assert abs(f(t0 - 1e-7) - f(t0 + 1e-7)) < 1e-4
    # no sentinel beyond: hold
    assert RK.temporal_value(0.0, cfg, normals, []) == 1.0
    assert RK.temporal_value(20.0, cfg, normals, []) == 3.0
    # groups are split by sentinels
    g = [(1.0, 0.0), (2.0, 1.0), (4.0, 5.0), (5.0, 2.0)]
    v1 = RK.temporal_value(1.5, cfg, g, [3.0])
    v2 = RK.temporal_value(1.5, cfg, g[:2], [])
    assert v1 == pytest.approx(v2)


def test_every_axis_kind_the_schema_allows_is_baked_here():
    """README lists axes of every kind; test_single_axis_layer bakes one layer
    per kind (a refused kind fails it). A kind added to the schema without a
    case here fails this test."""
    layer = Sdf.Layer.FindOrOpen(str(REPO / "schemas" / "painterly" / "schema.usda"))
    allowed = set(layer.GetPropertyAtPath("/PainterlyAxis.kind").GetInfo("allowedTokens"))
    assert allowed == {"attribute", "blendShape", "jointRotation", "position", "viewDirection"}
    assert {spec["kind"] for spec in AXIS_SPECS.values()} == allowed
