"""Authoring commands on bad input: every refusal exits 1 (2 for command-line
usage), names the file and the prim at fault, writes nothing (no edit layer,
no scratch file, an existing edit layer byte-identical, the input untouched)
and never panics.
"""

from __future__ import annotations

import json
import os
import shutil

import pytest
from pxr import Sdf, Usd, UsdGeom, Vt

import authoring as Au
from conftest import REPO

LAYER = "/World/Paint/Strokes"
GOOD_PATH = "0,0,0 1,2,0"


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    d = tmp_path_factory.mktemp("bad_author_base")
    rig = Au.build_skel_rig(d / "tube.usda", frames=(1, 12), n_strokes=4)
    st = Usd.Stage.Open(str(rig.path))
    cv = UsdGeom.BasisCurves.Define(st, "/World/OnePoint")
    cv.CreateCurveVertexCountsAttr(Vt.IntArray([1]))
    cv.CreatePointsAttr(Au.v3f([[0, 0, 0]]))
    k = st.DefinePrim(f"{LAYER}/nopts", "PainterlyPoseKey")  # an opacity-only key
    k.CreateAttribute("coordinates", Sdf.ValueTypeNames.FloatArray, False, Sdf.VariabilityUniform).Set(
        Vt.FloatArray([]))
    k.CreateAttribute("opacity", Sdf.ValueTypeNames.Float, False, Sdf.VariabilityUniform).Set(0.5)
    st.GetRootLayer().Save()
    return rig.path


@pytest.fixture
def case(base, tmp_path):
    """A fresh copy of the rig, and a checker for 'refused, nothing written'."""
    inp = tmp_path / "tube.usda"
    shutil.copy(base, inp)

    def refused(painterly, *args, code=1, names=(), edit_layer="e.usda", existing=False, file=None):
        e = tmp_path / edit_layer if edit_layer else None
        if existing and not e.exists():
            painterly("key", inp, "--layer", LAYER, "--time", 1, "--points", "--edit-layer", e, "--quiet")
        before_in = Au.file_hash(inp)
        before_e = Au.file_hash(e) if e and e.exists() else None
        listing = sorted(os.listdir(tmp_path))
        target = ["--edit-layer", e] if e else []
        p = painterly(*args, *target, check=False)
        msg = p.stderr
        assert p.returncode == code, f"exit {p.returncode}, expected {code}: {args}\n{msg}"
        assert "panicked" not in msg and "RUST_BACKTRACE" not in msg, msg
        assert msg.strip(), "no error message"
        if code == 1:
            files = [file.name] if file is not None else [inp.name] + ([e.name] if e is not None else [])
            assert any(f in msg for f in files), f"message does not name the file ({files}):\n{msg}"
        for n in names:
            assert str(n) in msg, f"message does not name {n!r}:\n{msg}"
        assert Au.file_hash(inp) == before_in, "a refused command modified its input"
        if before_e is not None:
            assert Au.file_hash(e) == before_e, "a refused command modified the existing edit layer"
        assert sorted(os.listdir(tmp_path)) == listing, \
            f"a refused command left files: {sorted(set(os.listdir(tmp_path)) - set(listing))}"
        return msg

    return inp, refused


def brush_args(inp, which="smudge", layer=LAYER, path=GOOD_PATH, radius="1", strength="0.1", extra=()):
    return [which, inp, "--layer", layer, "--path", path, f"--radius={radius}", f"--strength={strength}", *extra]


# ---------------------------------------------------------------------------
# bad input: exit 1


@pytest.mark.parametrize("existing", [False, True])
def test_unknown_layer(painterly, case, existing):
    inp, refused = case
    refused(painterly, "bind", inp, "--layer", "/World/Nope", names=["/World/Nope"], existing=existing)
    refused(painterly, "key", inp, "--layer", "/World/Nope", "--time", 3, names=["/World/Nope"], existing=existing)
    for which in ("smudge", "expand"):
        refused(painterly, *brush_args(inp, which, layer="/World/Nope"), names=["/World/Nope"], existing=existing)
    # a prim that exists but is not a stroke layer
    refused(painterly, *brush_args(inp, layer="/World/Character/Body"), names=["/World/Character/Body"])


@pytest.mark.parametrize("mode", ["edit-layer", "in-place"])
@pytest.mark.parametrize("t", ["0", "13", "nan"])
def test_time_outside_range(painterly, case, t, mode):
    inp, refused = case
    # NaN is a bad command-line value (exit 2); 0 and 13 lie outside the stage's range (exit 1).
    kw = dict(names=[t], code=2 if t == "nan" else 1)
    if mode == "in-place":
        kw["edit_layer"] = None
    extra = ["--in-place"] if mode == "in-place" else []
    refused(painterly, "bind", inp, "--time", t, *extra, **kw)
    refused(painterly, "key", inp, "--layer", LAYER, "--time", t, *extra, **kw)
    refused(painterly, *brush_args(inp, extra=("--time", t, *extra)), **kw)


@pytest.mark.parametrize("path", ["1,2,3", "1,2,3 1,2,3"])
def test_tool_path_too_short(painterly, case, path):
    inp, refused = case
    for which in ("smudge", "expand"):
        refused(painterly, *brush_args(inp, which, path=path), code=2, names=["--path"])


def test_tool_path_prim_too_short_or_missing(painterly, case):
    inp, refused = case
    args = ["smudge", inp, "--layer", LAYER, "--radius", "1", "--strength", "0.1"]
    refused(painterly, *args, "--path-prim", "/World/OnePoint", names=["path"])
    refused(painterly, *args, "--path-prim", "/World/NoCurve", names=["/World/NoCurve"])
    # The proxy mesh has points too, but is no path (walkthrough: its 2,550
    # points in index order moved 600 points).
    stage = Usd.Stage.Open(str(inp))
    mesh = next(str(p.GetPath()) for p in stage.Traverse() if p.GetTypeName() == "Mesh")
    for which in ("smudge", "expand"):
        args = [which, inp, "--layer", LAYER, "--radius", "1", "--strength", "0.1"]
        refused(painterly, *args, "--path-prim", mesh,
                names=[f"{mesh}: the tool path prim is a Mesh prim, not a BasisCurves (--path-prim takes a curve)"])


@pytest.mark.parametrize("radius", ["0", "-1", "inf"])
def test_radius_not_positive(painterly, case, radius):
    """A bad command-line value is a usage error: exit 2 (README, exit codes)."""
    inp, refused = case
    for which in ("smudge", "expand"):
        refused(painterly, *brush_args(inp, which, radius=radius), code=2,
                names=[f"--radius {radius} must be positive"])


@pytest.mark.parametrize("extra, why", [
    ({"path": "3,6,-2"}, "--path has 1 point(s); a tool path needs at least two"),
    ({"path": "3,6,-2 3,6,-2"}, "--path has no segment of non-zero length"),
    ({"path": "inf,0,0 1,0,0"}, '--path point "inf,0,0" is not finite'),
    ({"path": "1,nan,0 1,0,0"}, '--path point "1,nan,0" is not finite'),
    ({"strength": "nan"}, "--strength NaN is not finite"),
    # It was blamed on the radius (a review, 2026-12-07).
    ({"strength": "0"}, "--strength 0 moves nothing: give a non-zero strength"),
    ({"extra": ("--strokes", "12-7")}, '--strokes: range "12-7" ends before it starts'),
    ({"extra": ("--strokes", "x")}, '--strokes: "x" is not a stroke index'),
])
def test_bad_brush_values_are_usage_errors(painterly, case, extra, why):
    """Every bad brush option is a command-line value: exit 2, the option named."""
    inp, refused = case
    for which in ("smudge", "expand"):
        refused(painterly, *brush_args(inp, which, **extra), code=2, names=[why])


def test_a_strength_below_float_precision_moves_nothing_and_says_so(painterly, case):
    # It reported "moved 269 points" and wrote a layer that changed none
    # (a review, 2026-12-07).
    inp, refused = case
    for which in ("smudge", "expand"):
        refused(painterly, *brush_args(inp, which, strength="1e-12"),
                names=[LAYER, "the brush moves ", " by less than a float's precision (--strength is too small): nothing changed"])


def test_bad_key_values_are_usage_errors(painterly, case):
    inp, refused = case
    refused(painterly, "key", inp, "--layer", LAYER, "--time", "nan", "--points", code=2,
            names=["--time NaN is not a finite number"])
    refused(painterly, "key", inp, "--layer", LAYER, "--time", 1, "--opacity", "inf", code=2,
            names=["--opacity inf is not finite"])


def test_key_name_exists(painterly, case):
    inp, refused = case
    # 'e.usda' already holds key1 (from `existing`)
    refused(painterly, "key", inp, "--layer", LAYER, "--time", 5, "--name", "key1", "--points",
            names=[f"{LAYER}/key1", "--replace"], existing=True)
    # the rig has no axes: every pose key sits at coordinates [], so a second points key clashes
    refused(painterly, "key", inp, "--layer", LAYER, "--time", 7, "--points", names=[f"{LAYER}/key1"])
    # --replace of `nopts` by name, whose points would also replace key1: two keys, refused
    refused(painterly, "key", inp, "--layer", LAYER, "--time", 7, "--name", "nopts", "--points", "--opacity", 0.3,
            "--replace", names=[f"{LAYER}/key1", "--replace would overwrite two different keys"], existing=True)


@pytest.mark.parametrize("camera, why", [
    ("/Nope", "the camera named by --camera does not exist"),
    ("/World", "--camera names a Xform prim, not a Camera"),
])
def test_key_camera_must_name_a_camera(painterly, case, camera, why):
    inp, refused = case
    refused(painterly, "key", inp, "--layer", LAYER, "--time", 5, "--points", "--camera", camera,
            names=[camera, why])


def test_edit_layer_is_the_input(painterly, case):
    inp, refused = case
    refused(painterly, "bind", inp, names=["--in-place"], edit_layer="tube.usda")
    refused(painterly, *brush_args(inp), names=["--in-place"], edit_layer="tube.usda")


def test_edit_layer_over_another_input(painterly, case, tmp_path):
    """An existing edit layer made over one input is not reused for another:
    the edits would be computed from the first and land on it."""
    inp, refused = case
    other = tmp_path / "other.usda"
    shutil.copy(inp, other)
    why = f"this edit layer does not sublayer {other} (it was made over another input)"
    refused(painterly, "bind", other, names=[why], existing=True)
    refused(painterly, "key", other, "--layer", LAYER, "--time", 5, "--sentinel", names=[why], existing=True)
    refused(painterly, *brush_args(other), names=[why], existing=True)
    # The same input by another name (a symlink) is the same input.
    alias = tmp_path / "alias.usda"
    alias.symlink_to(inp)
    painterly("key", alias, "--layer", LAYER, "--time", 5, "--sentinel", "--edit-layer", tmp_path / "e.usda", "--quiet")
    assert Usd.Stage.Open(str(tmp_path / "e.usda")).GetPrimAtPath(f"{LAYER}/sentinel1")


def test_nothing_to_bind(painterly, case, tmp_path):
    """A stage without stroke layers (a character before painting) is an
    error, as for bake, not an empty edit layer and "bound 0 points"."""
    _, refused = case
    empty = tmp_path / "unpainted.usda"
    stage = Usd.Stage.CreateNew(str(empty))
    UsdGeom.Xform.Define(stage, "/World")
    stage.GetRootLayer().Save()
    why = "nothing to bind: no stroke layer (PainterlyStrokeLayerAPI under a prim with PainterlyRigAPI)"
    for target in ("e.usda", None):
        refused(painterly, "bind", empty, *([] if target else ["--in-place"]), names=[why], file=empty,
                edit_layer=target)


def test_brush_bad_key_and_strokes(painterly, case):
    inp, refused = case
    refused(painterly, *brush_args(inp, extra=("--key", "nokey")), names=[f"{LAYER}/nokey"])
    refused(painterly, *brush_args(inp, extra=("--key", "nopts")), names=[f"{LAYER}/nopts"])
    refused(painterly, *brush_args(inp, extra=("--strokes", "2,40")), names=[LAYER, "40"])
    # A range past any layer is refused as such, at once: it aborted
    # allocating 2^64 indices, or took 400 MB for 0-50000000 (a review, 2026-12-07).
    for big in ("0-18446744073709551615", "0-1000000000000", "3-50000000,1"):
        refused(painterly, *brush_args(inp, extra=("--strokes", big)),
                names=[LAYER, "out of range (the layer has"])


def test_bad_path_text(painterly, case):
    inp, refused = case
    for bad in ("1,2 3,4,5", "a,b,c 1,2,3"):
        msg = refused(painterly, *brush_args(inp, path=bad), code=2)
        assert "--path" in msg


def test_in_place_usdz_and_missing_dir(painterly, case, tmp_path):
    inp, refused = case
    z = tmp_path / "x.usdz"
    shutil.copy(Au.pathlib.Path(inp), tmp_path / "copy.usda")
    from pxr import UsdUtils
    assert UsdUtils.CreateNewUsdzPackage(str(tmp_path / "copy.usda"), str(z))
    os.remove(tmp_path / "copy.usda")
    before = Au.file_hash(z)
    refused(painterly, "bind", z, "--in-place", edit_layer=None, file=z)
    assert Au.file_hash(z) == before
    refused(painterly, "bind", inp, edit_layer="nodir/e.usda", names=["nodir"])


def test_missing_input(painterly, case, tmp_path):
    inp, refused = case
    p = painterly("bind", tmp_path / "missing.usda", "--edit-layer", tmp_path / "e.usda", check=False)
    assert p.returncode == 1 and "missing.usda" in p.stderr and "panicked" not in p.stderr
    assert not (tmp_path / "e.usda").exists()


def scale_proxy(inp, scale):
    """Gives the proxy of the rig in `inp` a double-precision scale op
    (appended to its ops); returns the proxy's path."""
    st = Usd.Stage.Open(str(inp))
    proxy = next(p for p in st.Traverse() if p.IsA(UsdGeom.Mesh))
    UsdGeom.Xformable(proxy).AddScaleOp(UsdGeom.XformOp.PrecisionDouble, "fuzz").Set(scale)
    st.GetRootLayer().Save()
    return str(proxy.GetPath())


# Found by `scripts/fuzz --edits` (seed 7, case 86): a proxy scaled by 0 on
# one axis made `bind` panic, its world transform's inverse carrying NaN
# into the binding; a brush would have written NaN rest points.
@pytest.mark.parametrize("mode", ["--in-place", "edit-layer"])
def test_a_proxy_flattened_to_nothing_is_refused(painterly, case, mode):
    inp, refused = case
    proxy = scale_proxy(inp, (1.0, 1.0, 0.0))
    extra, where = (["--in-place"], {"edit_layer": None}) if mode == "--in-place" else ([], {})
    for args in (brush_args(inp), brush_args(inp, "expand")):
        msg = refused(painterly, *args, *extra, names=[proxy, "has no inverse", "determinant 0"], **where)
        assert msg.count("\n") == 1, msg
    # Posed, the skinning of the flattened proxy fails first, as a bake's does.
    # (A rest-pose bind binds the rest positions where they are, in the
    # proxy's space: it takes nothing through the transform.)
    refused(painterly, "bind", inp, "--time", 6, *extra, names=[proxy, "not finite at time 6"], **where)


def test_a_proxy_scaled_past_the_float_range_is_refused(painterly, case):
    """A scale of 1e-100 has an inverse, but 1e100 takes the painted points
    and the brush's displacements past f32: refused, naming what would
    have been written."""
    inp, refused = case
    scale_proxy(inp, (1e-100, 1e-100, 1e-100))
    msg = refused(painterly, "bind", inp, "--time", 6, names=[LAYER, "points", "point 0", "not finite"])
    assert "past the float range" in msg
    for which in ("smudge", "expand"):
        refused(painterly, *brush_args(inp, which), names=[LAYER, "painterly:restPoints", "past the float range"])


@pytest.mark.parametrize("kind", ["PainterlyPoseKey", "PainterlyTimeKey"])
def test_bind_in_a_pose_refuses_a_layer_with_position_keys(painterly, case, tmp_path, kind):
    """`bind --time T` promises that baking at T gives back the painted
    points. On a layer with position keys the keys, not the rest points,
    shape the bake (blowfish's Pupils, bound at 24 as baked there, came back
    0.025 off and moved 0.009 at frame 40), and the new binding re-skins
    every key: refused, naming the layer
    and its position keys and what to do instead. An opacity key
    (the rig's `nopts`) keys no position: that layer still binds."""
    inp, refused = case
    e = tmp_path / "ok.usda"
    painterly("bind", inp, "--time", 6, "--edit-layer", e, "--quiet")
    assert Usd.Stage.Open(str(e)).GetPrimAtPath(LAYER).GetAttribute("painterly:bindVertices").HasAuthoredValue()
    os.remove(e)
    st = Usd.Stage.Open(str(inp))
    rest = st.GetPrimAtPath(LAYER).GetAttribute("painterly:restPoints").Get()
    k = st.DefinePrim(f"{LAYER}/wide", kind)
    where = ("coordinates", Sdf.ValueTypeNames.FloatArray, Vt.FloatArray([])) if kind == "PainterlyPoseKey" \
        else ("time", Sdf.ValueTypeNames.Double, 8.0)
    for name, ty, v in (where, ("points", Sdf.ValueTypeNames.Point3fArray, rest)):
        k.CreateAttribute(name, ty, False, Sdf.VariabilityUniform).Set(v)
    st.GetRootLayer().Save()
    del st, k
    for extra, kw in (((), {}), (("--layer", LAYER), {}), (("--in-place",), {"edit_layer": None})):
        msg = refused(painterly, "bind", inp, "--time", 6, *extra,
                      names=[f"{LAYER}: has position keys ({LAYER}/wide)", "bind --time 6",
                             "would not give back the painted points", "smudge --key"], **kw)
        assert f"{LAYER}/nopts" not in msg, msg


def test_brush_key_must_be_a_key_of_the_layer(painterly, case):
    """`smudge --key` edited any prim with as many points: `--key` naming the
    layer itself moved its stroke-local `points` as if they were rest-space
    key points (exit 0, and no bake changed). Only a PainterlyPoseKey or
    PainterlyTimeKey child of the layer that a bake reads for its points is
    a key to edit."""
    inp, refused = case
    st = Usd.Stage.Open(str(inp))
    rest = st.GetPrimAtPath(LAYER).GetAttribute("painterly:restPoints").Get()

    def key_like(path, ty, active=True, **attrs):
        k = st.DefinePrim(path, ty)
        for name, (vt, v) in {"points": (Sdf.ValueTypeNames.Point3fArray, rest), **attrs}.items():
            k.CreateAttribute(name, vt, False, Sdf.VariabilityUniform).Set(v)
        k.SetActive(active)

    key_like("/World/Paint/Stray", "PainterlyPoseKey", coordinates=(Sdf.ValueTypeNames.FloatArray, Vt.FloatArray()))
    key_like(f"{LAYER}/Copy", "BasisCurves")
    key_like(f"{LAYER}/stop", "PainterlyTimeKey", time=(Sdf.ValueTypeNames.Double, 5.0),
             sentinel=(Sdf.ValueTypeNames.Bool, True))
    key_like(f"{LAYER}/off", "PainterlyTimeKey", active=False, time=(Sdf.ValueTypeNames.Double, 6.0))
    st.GetRootLayer().Save()
    del st
    cases = [
        (LAYER, [f"{LAYER}: is the stroke layer itself (a BasisCurves prim), not a key of {LAYER}"]),
        ("/World/Paint/Stray", ["/World/Paint/Stray: is a PainterlyPoseKey prim, not a key of"]),
        ("Copy", [f"{LAYER}/Copy: is a BasisCurves prim, not a key of {LAYER}"]),
        ("stop", [f"{LAYER}/stop: is a sentinel"]),
        ("off", [f"{LAYER}/off: is deactivated"]),
    ]
    for key, names in cases:
        for which in ("smudge", "expand"):
            refused(painterly, *brush_args(inp, which, extra=("--key", key)), names=names)


# ---------------------------------------------------------------------------
# command-line usage: exit 2


USAGE = [
    ["bind", "{inp}"],                                                     # neither --edit-layer nor --in-place
    ["bind", "{inp}", "--in-place", "--edit-layer", "{e}"],                # both
    ["key", "{inp}", "--layer", LAYER, "--edit-layer", "{e}"],             # no --time
    ["key", "{inp}", "--time", "3", "--edit-layer", "{e}"],                # no --layer
    ["key", "{inp}", "--layer", LAYER, "--time", "3", "--time-key", "--sentinel", "--edit-layer", "{e}"],
    ["key", "{inp}", "--layer", LAYER, "--time", "x", "--edit-layer", "{e}"],
    # A sentinel holds no data: its data options were silently dropped.
    ["key", "{inp}", "--layer", LAYER, "--time", "3", "--sentinel", "--points", "--edit-layer", "{e}"],
    ["key", "{inp}", "--layer", LAYER, "--time", "3", "--sentinel", "--opacity", "0.3", "--edit-layer", "{e}"],
    ["smudge", "{inp}", "--layer", LAYER, "--radius", "1", "--strength", "1", "--edit-layer", "{e}"],  # no path
    ["smudge", "{inp}", "--layer", LAYER, "--path", GOOD_PATH, "--path-prim", "/World/OnePoint",
     "--radius", "1", "--strength", "1", "--edit-layer", "{e}"],
    ["expand", "{inp}", "--layer", LAYER, "--path", GOOD_PATH, "--strength", "1", "--edit-layer", "{e}"],
    ["expand", "{inp}", "--layer", LAYER, "--path", GOOD_PATH, "--radius", "1", "--strength", "1",
     "--falloff", "gauss", "--edit-layer", "{e}"],
    ["smudge", "{inp}", "--layer", LAYER, "--path", GOOD_PATH, "--radius", "r", "--strength", "1",
     "--edit-layer", "{e}"],
]


@pytest.mark.parametrize("argv", USAGE, ids=[" ".join(a[:1] + a[2:6]) for a in USAGE])
def test_usage_errors(painterly, case, tmp_path, argv):
    inp, refused = case
    args = [str(a).format(inp=inp, e=tmp_path / "e.usda") for a in argv]
    refused(painterly, *args, code=2, edit_layer=None)


@pytest.mark.parametrize("value", ["1.7", "-0.5", "1.0000001", "-0.000001", "inf", "nan"])
def test_a_key_opacity_is_in_0_1(painterly, case, tmp_path, value):
    """An opacity is a value between 0 and 1 (Bassett 3.3): `--opacity 1.7`
    was keyed and baked as displayOpacity 1.52. Refused as a usage error;
    0 and 1 themselves are opacities."""
    inp, refused = case
    for kind in ([], ["--time-key"]):
        msg = refused(painterly, "key", inp, "--layer", LAYER, "--time", 3, *kind, "--opacity", value, code=2,
                      names=["--opacity"])
        assert "panicked" not in msg
    e = tmp_path / "ok.usda"
    for t, v in ((4, "0"), (5, "1")):
        painterly("key", inp, "--layer", LAYER, "--time", t, "--time-key", "--opacity", v, "--edit-layer", e, "--quiet")
    st = Usd.Stage.Open(str(e))
    assert [st.GetPrimAtPath(f"{LAYER}/time{i}").GetAttribute("opacity").Get() for i in (1, 2)] == [0.0, 1.0]


@pytest.mark.parametrize("name", ["a/b", "../up", "bad name", "1st", "", "k.x"])
def test_a_key_name_is_one_prim_name(painterly, case, name):
    """`--name a/b` used to write `over "a" { def ... "b" }` outside the
    layer, where no bake looks for keys, and report success."""
    inp, refused = case
    msg = refused(painterly, "key", inp, "--layer", LAYER, "--time", 3, "--name", name, "--sentinel", code=2)
    why = "is not a prim name: letters, digits and _, not starting with a digit"
    assert msg == f"error: {inp}: --name {json.dumps(name)} {why}\n"


def test_a_key_name_may_be_any_identifier(painterly, case, tmp_path):
    inp, _ = case
    e = tmp_path / "e.usda"
    for t, name in [(3, "_k9"), (4, "ключ")]:
        painterly("key", inp, "--layer", LAYER, "--time", t, "--name", name, "--sentinel", "--edit-layer", e, "--quiet")
        assert Usd.Stage.Open(str(e)).GetPrimAtPath(f"{LAYER}/{name}").GetTypeName() == "PainterlyTimeKey"


def test_in_place_usdz_with_an_upper_case_extension(painterly, case, tmp_path):
    """usd-core finds file formats by extension whatever its case, so
    `X.USDZ` is a package like `x.usdz`, and editing it in place must be
    refused the same way (else the package is overwritten by a bare crate
    layer that usd-core can no longer open)."""
    inp, refused = case
    shutil.copy(inp, tmp_path / "copy.usda")
    from pxr import UsdUtils
    assert UsdUtils.CreateNewUsdzPackage(str(tmp_path / "copy.usda"), str(tmp_path / "lower.usdz"))
    os.remove(tmp_path / "copy.usda")
    z = tmp_path / "X.USDZ"
    os.rename(tmp_path / "lower.usdz", z)
    assert Sdf.FileFormat.FindByExtension(str(z)).formatId == "usdz"
    assert Usd.Stage.Open(str(z)), "test setup: usd-core does not open the package"
    before = Au.file_hash(z)
    refused(painterly, "bind", z, "--in-place", edit_layer=None, file=z)
    assert Au.file_hash(z) == before


def test_a_second_pose_key_on_a_layer_without_axes_names_the_empty_axes(painterly, tmp_path):
    """With `painterly:axes = []` every pose key sits at the one empty
    configuration: the second was refused as "already keys this layer at
    the same coordinates: pass --replace", which hid the cause and offered
    an overwrite (a TD workflow review, 2026-12-06)."""
    src = tmp_path / "fish.usda"
    shutil.copy(REPO / "fixtures" / "blowfish.usda", src)
    stage = Usd.Stage.Open(str(src))
    stage.GetPrimAtPath("/Blowfish/Paint/Hair").CreateRelationship("painterly:axes").SetTargets([])
    stage.GetRootLayer().Save()
    painterly("key", src, "--layer", "/Blowfish/Paint/Hair", "--time", "5", "--in-place", "-q")
    proc = painterly("key", src, "--layer", "/Blowfish/Paint/Hair", "--time", "25", "--in-place", check=False)
    assert proc.returncode == 1
    assert proc.stderr == (
        f"error: {src}: /Blowfish/Paint/Hair.painterly:axes: the layer has no axes, so a pose key at any time "
        "meets /Blowfish/Paint/Hair/key1: give the layer axes, or key the timeline with --time-key\n")
