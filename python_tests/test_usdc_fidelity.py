"""Every .usdc painterly writes survives usd-core (issue 9 §1).

What a TD does with a painterly file: open it in usd-core, add a prim, set
layer metadata, add a time sample, `Save()` in place, open it again in
usd-core and in painterly. Before painterly had its own crate writer, usd-core
failed that save (`_GetIndexForToken`: the pseudo-root's empty element token
was missing from the file's token table) and the half-written save damaged
the file. Here, for each kind of .usdc painterly writes — a bake (with and
without --bake-proxy), an edit layer from bind / key / smudge, and an
--in-place edit of a .usdc written by usd-core holding every construct —
the save must succeed and the file must reopen exactly as usd-core held it.

Also: the crate version is the lowest the content needs (what usd-core itself
would write: 0.8.0 for bakes), an in-place edit changes nothing but what it
edits, and bakes are no bigger than usd-core's own file of the same layer.
"""

from __future__ import annotations

import pathlib
import shutil

import numpy as np
import pytest
from pxr import Gf, Sdf, Ts, Usd, Vt

import authoring as Au
import crate_reps

T = Sdf.ValueTypeNames


# ---------------------------------------------------------------------------
# helpers


def crate_version(path) -> str:
    return str(Sdf.CrateInfo.Open(str(path)).GetFileVersion())


def open_for_edit(path):
    """The layer at `path` as on disk now (painterly rewrote it behind
    usd-core's layer cache)."""
    layer = Sdf.Layer.Find(str(path))
    if layer:
        layer.Reload(force=True)
        return layer
    return Sdf.Layer.FindOrOpen(str(path))


def on_disk(path) -> str:
    """The file as a fresh usd-core read sees it."""
    return Sdf.Layer.OpenAsAnonymous(str(path)).ExportToString()


def baked_samples(path) -> str:
    """A bake as usd-core reads it, without the input's stamp: the same edits
    read back give the same bake, though the input file was saved since."""
    text = on_disk(path)
    return "\n".join(line for line in text.splitlines() if "inputStamp" not in line)


def usd_core_touch(path, prim_path="/UsdCoreAdded") -> str:
    """Open in usd-core, add a prim, set layer metadata, add time samples (to
    a new and to an existing attribute), Save() in place. Returns what usd-core
    held when it saved."""
    layer = open_for_edit(path)
    layer.comment = "touched by usd-core"
    layer.customLayerData = dict(layer.customLayerData, touchedBy="usd-core")
    prim = Sdf.CreatePrimInLayer(layer, prim_path)
    prim.specifier = Sdf.SpecifierDef
    prim.typeName = "Xform"
    attr = Sdf.AttributeSpec(prim, "weight", T.Float)
    layer.SetTimeSample(attr.path, 3.0, 0.5)
    sampled = []
    layer.Traverse("/", lambda p: sampled.append(p) if p.IsPropertyPath() and layer.GetNumTimeSamplesForPath(p) else None)
    if sampled:
        p = sorted(sampled, key=str)[0]
        times = layer.ListTimeSamplesForPath(p)
        layer.SetTimeSample(p, max(times) + 0.5, layer.QueryTimeSample(p, times[0]))
    held = layer.ExportToString()
    assert layer.Save(), f"usd-core could not save {path} in place"
    return held


def contents(layer) -> dict:
    """Every spec of a layer as usd-core reads it: its kind, every field
    (ListInfoKeys/GetInfo) and its ordered children."""
    out = {}

    def visit(path):
        spec = layer.GetObjectAtPath(path)
        if spec is None:  # targets and connections Traverse lists
            return
        fields = {key: info(layer, spec, key) for key in spec.ListInfoKeys()}
        if isinstance(spec, (Sdf.PrimSpec, Sdf.PseudoRootSpec)):
            fields["<children>"] = [c.name for c in spec.nameChildren]
        if isinstance(spec, (Sdf.PrimSpec, Sdf.VariantSpec)):
            prim = spec if isinstance(spec, Sdf.PrimSpec) else spec.primSpec
            fields["<properties>"] = [p.name for p in prim.properties]
            fields["<variantSets>"] = list(prim.variantSets.keys())
        out[str(path)] = (type(spec).__name__, fields)

    layer.Traverse("/", visit)
    return out


def info(layer, spec, key):
    if key == "subLayerOffsets":  # a std::vector<SdfLayerOffset> has no Python converter
        return [(o.offset, o.scale) for o in layer.subLayerOffsets]
    return spec.GetInfo(key)


def differences(a: dict, b: dict) -> list:
    """(path, field) pairs where two contents() differ."""
    diffs = []
    for path in sorted(set(a) | set(b)):
        if path not in a or path not in b:
            diffs.append((path, "<spec>"))
            continue
        if a[path][0] != b[path][0]:
            diffs.append((path, "<kind>"))
        fa, fb = a[path][1], b[path][1]
        for key in sorted(set(fa) | set(fb)):
            if key not in fa or key not in fb or not same(fa[key], fb[key]):
                diffs.append((path, key))
    return diffs


def same(x, y) -> bool:
    eq = x == y
    # NaN != NaN: the same printed value is the same value.
    return (bool(eq) if isinstance(eq, bool) else bool(np.all(eq))) or str(x) == str(y)


def composed(layer_path, input_path, out):
    """A stage file sublayering `layer_path` over `input_path`."""
    out.write_text(f'#usda 1.0\n(\n    subLayers = [@{layer_path.name}@, @{input_path.name}@]\n)\n')
    return out


def stroke_points(path, prim, frames):
    st = Usd.Stage.Open(str(path))
    a = st.GetPrimAtPath(prim).GetAttribute("points")
    return [np.array(a.Get(t)) for t in frames]


def skel_rig(tmp_path, name="rig.usda", **kw):
    kw.setdefault("world_xform", Au.xf_static(translate=(0.5, -1, 2), rotate=(0, 30, 0)))
    kw.setdefault("n_strokes", 6)
    return Au.build_skel_rig(tmp_path / name, **kw)


# ---------------------------------------------------------------------------
# bakes


@pytest.mark.parametrize("proxy", [False, True], ids=["strokes", "bake-proxy"])
def test_bake_survives_usd_core_save(painterly, tmp_path, proxy):
    rig = skel_rig(tmp_path)
    bake = tmp_path / "bake.usdc"
    painterly("bake", rig.path, "-o", bake, "--quiet", *(["--bake-proxy"] if proxy else []))
    shot = composed(bake, rig.path, tmp_path / "shot.usda")
    before = stroke_points(shot, rig.layers[0], rig.frames)
    original = contents(Sdf.Layer.OpenAsAnonymous(str(bake)))

    held = usd_core_touch(bake)
    assert on_disk(bake) == held, "the file usd-core saved does not reopen as usd-core held it"
    assert crate_version(bake) == "0.8.0", "a bake needs nothing newer than what usd-core writes"
    # Everything painterly wrote is still there, unchanged.
    after = contents(Sdf.Layer.OpenAsAnonymous(str(bake)))
    lost = [d for d in differences(original, after) if not d[0].startswith("/UsdCoreAdded") and d[0] != "/"]
    assert not [d for d in lost if d[1] != "timeSamples"], lost
    # ...and usd-core composes the same strokes through it.
    for a, b in zip(before, stroke_points(shot, rig.layers[0], rig.frames)):
        assert np.array_equal(a, b)
    # painterly reads the saved file: on its own and over the input.
    painterly("inspect", bake)
    # The composing layer has no time range of its own: give the bake's.
    out = painterly("inspect", shot, "--frames", f"{rig.frames[0]}:{rig.frames[-1]}")
    assert rig.layers[0] in out.stdout


# ---------------------------------------------------------------------------
# edit layers


def smudge_args(rig):
    st = Usd.Stage.Open(str(rig.path))
    from pxr import UsdGeom

    cache = UsdGeom.BBoxCache(Usd.TimeCode.Default(), ["default", "render"])
    box = cache.ComputeWorldBound(st.GetPrimAtPath(rig.layers[0])).ComputeAlignedRange()
    lo, hi = np.array(box.GetMin()), np.array(box.GetMax())
    c, size = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
    a, b = c - [size / 2, 0, 0], c + [size / 2, 0, 0]
    path = " ".join(",".join(f"{x:.9g}" for x in p) for p in (a, b))
    return ["--layer", rig.layers[0], "--path", path, f"--radius={size / 2:.9g}", "--strength=0.05"]


EDITS = {
    "bind": lambda rig: ["--time", 5],
    "key": lambda rig: ["--layer", rig.layers[0], "--time", 6],
    "smudge": smudge_args,
}


@pytest.mark.parametrize("cmd", sorted(EDITS))
def test_edit_layer_survives_usd_core_save(painterly, tmp_path, cmd):
    rig = skel_rig(tmp_path)
    e = tmp_path / "edits.usdc"
    painterly(cmd, rig.path, *EDITS[cmd](rig), "--edit-layer", e, "--quiet")
    version = crate_version(e)
    baked = tmp_path / "b1.usdc"
    painterly("bake", e, "-o", baked, "--quiet")
    before = baked_samples(baked)

    held = usd_core_touch(e)
    assert on_disk(e) == held
    assert version == "0.8.0"
    # painterly reads the edits back as they were: the same bake.
    again = tmp_path / "b2.usdc"
    painterly("bake", e, "-o", again, "--quiet")
    assert baked_samples(again) == before
    # and appends to the layer usd-core saved, which usd-core saves again.
    # (A rest-pose bind: `bind --time` refuses the layer the `key` case keyed.)
    painterly("bind", rig.path, "--edit-layer", e, "--quiet")
    assert Sdf.Layer.OpenAsAnonymous(str(e)).GetPrimAtPath("/UsdCoreAdded"), "painterly dropped usd-core's prim"
    held = usd_core_touch(e, "/UsdCoreAddedAgain")
    assert on_disk(e) == held


# ---------------------------------------------------------------------------
# --in-place on a .usdc usd-core wrote, holding every construct


def add_every_construct(layer, tmp_path):
    """Author, with usd-core's Sdf API, one of everything a layer can hold
    (beside the painterly character already in it)."""
    ref = tmp_path / "ref.usda"
    ref_layer = Sdf.Layer.CreateNew(str(ref))
    r = Sdf.CreatePrimInLayer(ref_layer, "/R")
    r.specifier = Sdf.SpecifierDef
    Sdf.CreatePrimInLayer(ref_layer, "/R/Child").specifier = Sdf.SpecifierDef
    ref_layer.Save()
    sub = tmp_path / "sub.usda"
    Sdf.Layer.CreateNew(str(sub)).Save()

    layer.subLayerPaths.append("./sub.usda")
    layer.subLayerOffsets[0] = Sdf.LayerOffset(2.0, 0.5)
    layer.customLayerData = {"studio": "painterly tests", "nested": {"n": 1, "tags": Vt.StringArray(["a", "b"])}}
    layer.documentation = "every construct"
    layer.relocates = [(Sdf.Path("/Extras/Referenced/Child"), Sdf.Path("/Extras/Referenced/Renamed"))]

    x = Sdf.CreatePrimInLayer(layer, "/Extras")
    x.specifier = Sdf.SpecifierDef
    x.typeName = "Xform"
    x.documentation = "a prim with everything"
    x.kind = "component"
    x.customData = {"int": 3, "double": 0.25, "token": Sdf.AssetPath("@tex.png@"), "dict": {"s": "deep"}}
    x.assetInfo = {"identifier": Sdf.AssetPath("./asset.usd"), "version": "1"}
    x.SetInfo("apiSchemas", Sdf.TokenListOp.Create(prependedItems=["CollectionAPI:set"]))
    x.SetInfo("instanceable", False)
    x.hidden = True
    x.active = True

    cls = Sdf.CreatePrimInLayer(layer, "/Extras_Class")
    cls.specifier = Sdf.SpecifierClass
    x.inheritPathList.Prepend("/Extras_Class")
    x.specializesList.Append("/Extras_Class")

    refd = Sdf.CreatePrimInLayer(layer, "/Extras/Referenced")
    refd.specifier = Sdf.SpecifierDef
    refd.referenceList.Prepend(Sdf.Reference("./ref.usda", "/R", Sdf.LayerOffset(1.0, 2.0), {"note": "hi"}))
    payd = Sdf.CreatePrimInLayer(layer, "/Extras/Payloaded")
    payd.specifier = Sdf.SpecifierDef
    payd.payloadList.explicitItems = [Sdf.Payload("./ref.usda", "/R", Sdf.LayerOffset(-3.0, 1.0))]
    dflt = Sdf.CreatePrimInLayer(layer, "/Extras/DefaultRef")
    dflt.specifier = Sdf.SpecifierOver
    dflt.referenceList.Append(Sdf.Reference("./ref.usda"))

    vs = Sdf.VariantSetSpec(x, "shape")
    for name, value in (("round", 1.0), ("square", 2.0)):
        v = Sdf.VariantSpec(vs, name)
        inner = Sdf.PrimSpec(v.primSpec, "Inner", Sdf.SpecifierDef, "Xform")
        a = Sdf.AttributeSpec(inner, "size", T.Double)
        a.default = value
        Sdf.AttributeSpec(v.primSpec, "variantAttr", T.Token).default = name
    x.variantSelections["shape"] = "round"
    x.SetInfo("variantSetNames", Sdf.StringListOp.Create(prependedItems=["shape"]))

    values = [
        ("b", T.Bool, True), ("uc", T.UChar, 200), ("i", T.Int, -7), ("u", T.UInt, 4000000000),
        ("i64", T.Int64, 5), ("i64big", T.Int64, -(2**40)), ("u64", T.UInt64, 2**63),
        ("h", T.Half, 0.5), ("f", T.Float, -1.25), ("d", T.Double, 0.1),
        ("s", T.String, "h\u00e9 \"q\"\nline"), ("t", T.Token, "tok"), ("a", T.Asset, Sdf.AssetPath("./tex/a.png")),
        ("m4", T.Matrix4d, Gf.Matrix4d(1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16)),
        ("m3", T.Matrix3d, Gf.Matrix3d(1)), ("q", T.Quatf, Gf.Quatf(0.5, 0.5, -0.5, 0.5)),
        ("qh", T.Quath, Gf.Quath(1, 0, 0, 0)), ("v3d", T.Double3, Gf.Vec3d(1e10, -2, 3)),
        ("v2h", T.Half2, Gf.Vec2h(1, 2)), ("v4i", T.Int4, Gf.Vec4i(1, -2, 3, 400)),
        ("tc", T.TimeCode, Sdf.TimeCode(12.5)), ("tcs", T.TimeCodeArray, Sdf.TimeCodeArray([1, 2.5])),
        ("expr", T.PathExpression, Sdf.PathExpression("/World//Mesh* - /World/Hidden")),
        ("ints", T.IntArray, Vt.IntArray(list(range(0, 300, 7)))),
        ("floats", T.FloatArray, Vt.FloatArray([0.5, -0.0, 1.0] * 10)),
        ("halves", T.HalfArray, Vt.HalfArray([1, 2, 3, 4] * 5)),
        ("doubles", T.DoubleArray, Vt.DoubleArray([i / 7 for i in range(20)])),
        ("strs", T.StringArray, Vt.StringArray(["a", "", "b"])),
        ("toks", T.TokenArray, Vt.TokenArray(["x", "y"])),
        ("assets", T.AssetArray, Sdf.AssetPathArray([Sdf.AssetPath("a.usd"), Sdf.AssetPath("b.usd")])),
        ("bools", T.BoolArray, Vt.BoolArray([True, False])),
        ("quats", T.QuatdArray, Vt.QuatdArray([Gf.Quatd(1, 2, 3, 4)])),
        ("mats", T.Matrix4dArray, Vt.Matrix4dArray([Gf.Matrix4d(2)])),
        ("i64s", T.Int64Array, Vt.Int64Array([-(2**62), 2**62, 0] * 6)),
        ("empty", T.Point3fArray, Vt.Vec3fArray()),
    ]
    for name, tn, value in values:
        a = Sdf.AttributeSpec(x, name, tn)
        a.default = value
    held = Sdf.AttributeSpec(x, "held", T.Float, Sdf.VariabilityUniform)
    held.default = Sdf.ValueBlock()
    held.custom = True
    anim = Sdf.AttributeSpec(x, "anim", T.Float3Array)
    anim.SetInfo("interpolation", "vertex")
    anim.displayName = "Animated"
    anim.documentation = "samples with a block"
    for t, v in ((1.0, Vt.Vec3fArray([(1, 2, 3)])), (2.0, Sdf.ValueBlock()), (3.5, Vt.Vec3fArray([(0, 0, 1)]))):
        layer.SetTimeSample(anim.path, t, v)
    tok = Sdf.AttributeSpec(x, "choice", T.Token, Sdf.VariabilityUniform)
    tok.allowedTokens = ["a", "b"]
    tok.default = "a"
    rel = Sdf.RelationshipSpec(x, "targets")
    rel.targetPathList.explicitItems = ["/Extras/Referenced", "/World"]
    rel2 = Sdf.RelationshipSpec(x, "edits", custom=True)
    rel2.targetPathList.Prepend("/Extras/Payloaded")
    rel2.targetPathList.deletedItems.append("/Gone")
    con = Sdf.AttributeSpec(x, "connected", T.Float)
    con.connectionPathList.Append("/Extras.f")
    clip = tmp_path / "clip.usda"
    Sdf.Layer.CreateNew(str(clip)).Save()
    c = Sdf.CreatePrimInLayer(layer, "/Extras/Clipped")
    c.specifier = Sdf.SpecifierDef
    c.SetInfo("clips", {"default": {
        "assetPaths": Sdf.AssetPathArray([Sdf.AssetPath("./clip.usda")]),
        "primPath": "/R", "active": Vt.Vec2dArray([(1, 0)]), "times": Vt.Vec2dArray([(1, 1), (2, 2)])}})
    c.SetInfo("clipSets", Sdf.StringListOp.CreateExplicit(["default"]))


def test_in_place_on_usd_core_usdc_changes_only_the_edit(painterly, tmp_path):
    rig = skel_rig(tmp_path, name="authored.usda")
    src = Sdf.Layer.FindOrOpen(str(rig.path))
    add_every_construct(src, tmp_path)
    inp = tmp_path / "input.usdc"
    src.Export(str(inp))
    version = crate_version(inp)
    assert version == "0.11.0", "test setup: layer relocates need 0.11.0 in usd-core"
    original = contents(Sdf.Layer.OpenAsAnonymous(str(inp)))
    assert len(original) > 40, "test setup"

    painterly("bind", inp, "--time", 5, "--in-place", "--quiet")
    edited = contents(Sdf.Layer.OpenAsAnonymous(str(inp)))
    lp = rig.layers[0]
    bind_attrs = {f"{lp}.painterly:{n}" for n in ("restPoints", "bindVertices", "bindWeights")}
    unexpected = [d for d in differences(original, edited)
                  if d[0] not in bind_attrs and d != (lp, "<properties>")]
    assert not unexpected, f"--in-place changed more than the bind: {unexpected}"
    assert {d[0] for d in differences(original, edited)} & bind_attrs, "test setup: bind changed nothing"
    assert crate_version(inp) == version, "not the lowest version the content needs (usd-core's)"

    baked = tmp_path / "b1.usdc"
    painterly("bake", inp, "-o", baked, "--quiet")
    held = usd_core_touch(inp)
    assert on_disk(inp) == held
    again = tmp_path / "b2.usdc"
    painterly("bake", inp, "-o", again, "--quiet")
    assert baked_samples(again) == baked_samples(baked)


def test_in_place_plain_usdc_stays_0_8(painterly, tmp_path):
    rig = skel_rig(tmp_path, name="plain.usdc")
    assert crate_version(rig.path) == "0.8.0"
    painterly("bind", rig.path, "--time", 5, "--in-place", "--quiet")
    assert crate_version(rig.path) == "0.8.0"
    held = usd_core_touch(rig.path)
    assert on_disk(rig.path) == held


# Valid usd-core values that openusd 0.8's crate reader cannot read (an error)
# or reads wrong (silently): an --in-place edit takes them from the file's
# bytes (src/usd_io/usdc/recover.rs) and must keep each one as usd-core wrote it.
def _spline(custom_data=None):
    s = Ts.Spline()
    for t, v in ((1.0, 0.0), (4.0, 2.5)):
        k = Ts.Knot()
        k.SetTime(t)
        k.SetValue(v)
        if custom_data:
            k.SetCustomData(custom_data)
        s.SetKnot(k)
    return s


def _int64s(n, seed, lo=-2**62, hi=2**62):
    return [int(x) for x in np.random.default_rng(seed).integers(lo, hi, n, dtype=np.int64)]


def _attr(prim, type_name, default=None, **info):
    a = Sdf.AttributeSpec(prim, "v", type_name)
    if default is not None:
        a.default = default  # cast to type_name (SetInfo would keep a Python int an int)
    for key, value in info.items():
        a.SetInfo(key, value)
    return a


def _samples(prim, type_name, values):
    a = Sdf.AttributeSpec(prim, "v", type_name)
    for t, v in enumerate(values):
        prim.layer.SetTimeSample(a.path, float(t + 1), v)


OPENUSD_READER_GAPS = {
    # Stored as payload 0, which openusd reads as a file offset.
    "empty string[]": lambda x: _attr(x, T.StringArray, default=Vt.StringArray()),
    "empty asset[]": lambda x: _attr(x, T.AssetArray, default=Sdf.AssetPathArray()),
    # 64-bit differences: openusd's decompression buffer is sized for 32-bit ones.
    "int64[] (1040 random)": lambda x: _attr(x, T.Int64Array, default=Vt.Int64Array(_int64s(1040, 1))),
    "uint64[] (20 random)": lambda x: _attr(x, T.UInt64Array, default=Vt.UInt64Array(
        [v + 2**62 for v in _int64s(20, 2)])),
    # Inlined as 32 bits; openusd zero-extends them (no error).
    "negative int64": lambda x: _attr(x, T.Int64, default=-5),
    # Types openusd does not know: copied as the file holds them.
    "animation block": lambda x: _attr(x, T.Double, default=Sdf.AnimationBlock()),
    "spline": lambda x: _attr(x, T.Double, spline=_spline()),
    # The same inside time samples and dictionaries.
    "int64[] and int64 time samples": lambda x: _samples(x, T.Int64Array, [
        Vt.Int64Array(_int64s(300, 3)), Vt.Int64Array(), Vt.Int64Array([-7])]),
    "negative int64 time samples": lambda x: _samples(x, T.Int64, [-1, 5, -(2**31)]),
    "customData": lambda x: _attr(x, T.Float, default=1.5, customData={
        "empty": Vt.StringArray(), "big": Vt.Int64Array(_int64s(64, 4)), "neg": Vt.Int64Array([-3]),
        "nested": {"n": Vt.Int64(-9), "assets": Sdf.AssetPathArray()}}),
}


def _gap_file(tmp_path, make, name="gap.usdc"):
    """fixtures/tube.usda with /Tube/Extra holding one value, as a usd-core crate file."""
    src = Sdf.Layer.OpenAsAnonymous(str(pathlib.Path(__file__).parent.parent / "fixtures" / "tube.usda"))
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.TransferContent(src)
    x = Sdf.CreatePrimInLayer(layer, "/Tube/Extra")
    x.specifier = Sdf.SpecifierDef
    make(x)
    inp = tmp_path / name
    layer.Export(str(inp))
    return inp


@pytest.mark.parametrize("case", sorted(OPENUSD_READER_GAPS))
def test_in_place_keeps_values_openusds_reader_cannot_read(painterly, tmp_path, case):
    inp = _gap_file(tmp_path, OPENUSD_READER_GAPS[case])
    version = crate_version(inp)
    original = contents(Sdf.Layer.OpenAsAnonymous(str(inp)))
    assert "/Tube/Extra.v" in original, "test setup"

    painterly("key", inp, "--layer", "/Tube/Paint/Rings", "--time", 3, "--sentinel", "--in-place", "--quiet")
    edited = contents(Sdf.Layer.OpenAsAnonymous(str(inp)))
    key = "/Tube/Paint/Rings/sentinel1"
    # The edit as usd-core reads it: a sentinel key at time 3.
    assert edited[key][1]["typeName"] == "PainterlyTimeKey"
    assert edited[f"{key}.time"][1]["default"] == 3.0
    assert edited[f"{key}.sentinel"][1]["default"] is True
    # Everything else, spec by spec and field by field, as usd-core wrote it.
    unexpected = [d for d in differences(original, edited)
                  if not d[0].startswith(key) and d != ("/Tube/Paint/Rings", "<children>")]
    assert not unexpected, f"--in-place changed more than the key: {unexpected}"
    assert crate_version(inp) == version, "not the version usd-core gave the content"
    # usd-core edits and saves it in place, and reads back what it held.
    held = usd_core_touch(inp)
    assert on_disk(inp) == held


def test_in_place_refuses_a_spline_with_knot_custom_data(painterly, tmp_path):
    """Knot custom data refers to the file's string table: not copied, refused
    naming the file, the attribute, the field and why; the file is unchanged."""
    inp = _gap_file(tmp_path, lambda x: _attr(x, T.Double, spline=_spline({"note": "keep me"})))
    before = inp.read_bytes()
    p = painterly("key", inp, "--layer", "/Tube/Paint/Rings", "--time", 3, "--sentinel", "--in-place",
                  check=False)
    assert p.returncode == 1, p.stderr
    assert str(inp) in p.stderr and "/Tube/Extra.v" in p.stderr and "`spline`" in p.stderr, p.stderr
    assert "a spline whose knots hold custom data cannot be kept" in p.stderr, p.stderr
    assert inp.read_bytes() == before


def _key_in_place_keeps_the_rest(painterly, inp):
    """Keys /Tube/Paint/Rings in place; every other spec and field must read
    in usd-core as it did before. Returns (before, after) contents()."""
    original = contents(Sdf.Layer.OpenAsAnonymous(str(inp)))
    painterly("key", inp, "--layer", "/Tube/Paint/Rings", "--time", 3, "--sentinel", "--in-place", "--quiet")
    edited = contents(Sdf.Layer.OpenAsAnonymous(str(inp)))
    key = "/Tube/Paint/Rings/sentinel1"
    assert edited[key][1]["typeName"] == "PainterlyTimeKey"
    unexpected = [d for d in differences(original, edited)
                  if not d[0].startswith(key) and d != ("/Tube/Paint/Rings", "<children>")]
    assert not unexpected, f"--in-place changed more than the key: {unexpected}"
    return original, edited


def test_in_place_keeps_a_negative_int64_in_a_dictionary_holding_a_nan(painterly, tmp_path):
    """openusd reads an inlined negative int64 zero-extended; the field is
    taken from the file unless the edit changed it, which NaN != NaN made
    every dictionary with a NaN look like (review t5: -12 became 4294967284)."""
    def make(x):
        x.customData = {"neg": Vt.Int64(-5), "nan": float("nan"), "inner": {"n": Vt.Int64(-7), "f": float("nan")}}
        x.layer.customLayerData = {"frame": Vt.Int64(-12), "nan": float("nan")}
        y = Sdf.CreatePrimInLayer(x.layer, "/Tube/Extra2")
        y.specifier = Sdf.SpecifierDef
        y.customData = {"neg": Vt.Int64(-5)}
        _attr(x, T.Float, default=1.0, customData={"i": Vt.Int64(-3), "nan": float("nan")})

    inp = _gap_file(tmp_path, make)
    original, edited = _key_in_place_keeps_the_rest(painterly, inp)
    assert repr(edited["/"][1]["customLayerData"]) == repr(original["/"][1]["customLayerData"])
    assert edited["/"][1]["customLayerData"]["frame"] == -12
    assert edited["/Tube/Extra"][1]["customData"]["neg"] == -5
    assert edited["/Tube/Extra"][1]["customData"]["inner"]["n"] == -7
    assert edited["/Tube/Extra.v"][1]["customData"]["i"] == -3


def test_in_place_keeps_negative_int64s_in_references_custom_data(painterly, tmp_path):
    """A reference's customData is a dictionary inside the reference list
    op, where openusd zero-extends a negative int64 too (review t6: -2 became
    4294967294); payloads and their layer offsets beside it are kept."""
    def make(x):
        src = Sdf.CreatePrimInLayer(x.layer, "/Src")
        src.specifier = Sdf.SpecifierDef
        refs = x.referenceList
        refs.prependedItems = [
            Sdf.Reference("", "/Src", Sdf.LayerOffset(2, 0.5), {"k": Vt.Int64(-2), "nan": float("nan")}),
            Sdf.Reference("", "/Src"),
        ]
        refs.appendedItems = [Sdf.Reference("", "/Src", Sdf.LayerOffset(-3, 2),
                                            {"nested": {"m": Vt.Int64(-(2**31))}})]
        refs.deletedItems = [Sdf.Reference("", "/Gone", customData={"d": Vt.Int64(-9)})]
        x.payloadList.appendedItems = [Sdf.Payload("", "/Src", Sdf.LayerOffset(-3, 2))]
        y = Sdf.CreatePrimInLayer(x.layer, "/Tube/Extra2")
        y.specifier = Sdf.SpecifierDef
        y.referenceList.explicitItems = [Sdf.Reference("", "/Src", customData={"k": Vt.Int64(-1)})]

    inp = _gap_file(tmp_path, make)
    original, edited = _key_in_place_keeps_the_rest(painterly, inp)
    refs = edited["/Tube/Extra"][1]["references"]
    assert refs.prependedItems[0].customData["k"] == -2
    assert refs.appendedItems[0].customData["nested"]["m"] == -(2**31)
    assert refs.deletedItems[0].customData["d"] == -9
    assert edited["/Tube/Extra2"][1]["references"].explicitItems[0].customData["k"] == -1


def _hostile_dictionary(tmp_path, patch):
    """/Tube/Extra's customData {"e": empty string[]} (which openusd cannot
    read, so the edit reads it from the file), its bytes then changed by
    `patch(data, at)`, `at` the dictionary's offset."""
    import struct

    inp = _gap_file(tmp_path, lambda x: setattr(x, "customData", {"e": Vt.StringArray()}))
    data = bytearray(inp.read_bytes())
    # The dictionary: a count of 1, a key, a recursive offset of 8, the rep
    # of an empty string[] (type 10, array, payload 0).
    rep = struct.pack("<Q", (1 << 63) | (10 << 48))
    hits = [i for i in range(0, len(data) - 28)
            if data[i:i + 8] == struct.pack("<Q", 1) and data[i + 12:i + 20] == struct.pack("<q", 8)
            and data[i + 20:i + 28] == rep]
    assert len(hits) == 1, f"test setup: {hits}"
    patch(data, hits[0])
    inp.write_bytes(bytes(data))
    return inp


def _doubling_chain(data, at):
    """Appends 30 dictionaries, each of two entries that are both the next
    one (the last holds the empty string[]), and makes the entry the first:
    2^30 values within the nesting limit, from 1.5 KB."""
    import struct

    key = bytes(data[at + 8:at + 12])
    leaf = bytes(data[at + 20:at + 28])
    start = len(data)
    size = 8 + 2 * 20
    for i in range(30):
        nxt = struct.pack("<Q", (31 << 48) | (start + (i + 1) * size))
        data += struct.pack("<Q", 2) + (key + struct.pack("<q", 8) + nxt) * 2
    data += struct.pack("<Q", 1) + key + struct.pack("<q", 8) + leaf
    data[at + 20:at + 28] = struct.pack("<Q", (31 << 48) | start)


HOSTILE_DICTIONARIES = {
    # A count of 2^64-1 and an offset of -12 back onto the entry itself (review t8).
    "endless entries": lambda data, at: (data.__setitem__(slice(at, at + 8), (2**64 - 1).to_bytes(8, "little")),
                                         data.__setitem__(slice(at + 12, at + 20), (-12).to_bytes(8, "little", signed=True))),
    # Values shared: a few bytes describe exponentially many.
    "doubling chain": _doubling_chain,
}


@pytest.mark.parametrize("case", sorted(HOSTILE_DICTIONARIES))
def test_in_place_refuses_a_hostile_dictionary(tmp_path, case):
    """Counts bounded by the bytes left, offsets that must move forward, a
    cap on nesting and on values: a clear error and exit 1, under a memory
    limit and in bounded time, the file unchanged."""
    import resource
    import subprocess

    from conftest import painterly_binary

    inp = _hostile_dictionary(tmp_path, HOSTILE_DICTIONARIES[case])
    before = inp.read_bytes()

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))

    p = subprocess.run([str(painterly_binary()), "key", str(inp), "--layer", "/Tube/Paint/Rings", "--time", "3",
                        "--sentinel", "--in-place"], capture_output=True, text=True, timeout=60,
                       preexec_fn=limit)
    assert p.returncode == 1, (p.returncode, p.stderr[-2000:])
    assert str(inp) in p.stderr and "/Tube/Extra" in p.stderr and "`customData`" in p.stderr, p.stderr
    assert "panicked" not in p.stderr, p.stderr
    assert inp.read_bytes() == before


# ---------------------------------------------------------------------------
# value layout


def rep_panel():
    """Values on each side of usd-core's encoding rules (crateFile.cpp):
    inlined when a double is exactly a float, when vector components and a
    diagonal matrix's entries are 8-bit integers, and for an empty
    dictionary; int arrays compressed from 16 elements; float arrays from 16
    when integral or with at most n/4 distinct values; raw non-int arrays
    8-byte aligned; equal values stored once. (-0.0 vector components are
    left out: usd-core inlines them as +0.0, painterly keeps the sign.)"""
    frac = [0.1, 0.35, 0.6, 0.85, 1.1]
    return [
        ("d_half", T.Double, 0.5),
        ("d_tenth", T.Double, 0.1),
        ("d_negzero", T.Double, -0.0),
        ("d_huge", T.Double, 1e300),
        ("f_tenth", T.Float, 0.1),
        ("v3h_frac", T.Half3, Gf.Vec3h(0.5, 0, 1)),  # 6 bytes: leaves the next write unaligned
        ("v3f_ints", T.Float3, Gf.Vec3f(1, 2, -3)),
        ("v3f_frac", T.Float3, Gf.Vec3f(0.5, 1, 2)),
        ("v3f_big", T.Float3, Gf.Vec3f(1, 200, 3)),
        ("v3d_ints", T.Double3, Gf.Vec3d(1, -128, 127)),
        ("v3h_ints", T.Half3, Gf.Vec3h(1, 0, -3)),
        ("m4_identity", T.Matrix4d, Gf.Matrix4d(1)),
        ("m4_diag", T.Matrix4d, Gf.Matrix4d(2, 0, 0, 0, 0, 3, 0, 0, 0, 0, -4, 0, 0, 0, 0, 1)),
        ("m4_translate", T.Matrix4d, Gf.Matrix4d().SetTranslate(Gf.Vec3d(0, 0, 1))),
        ("m4_frac_diag", T.Matrix4d, Gf.Matrix4d(0.5)),
        ("m2_upper", T.Matrix2d, Gf.Matrix2d(1, 1, 0, 1)),
        ("m2_lower", T.Matrix2d, Gf.Matrix2d(1, 0, 1, 1)),
        ("m3_corner", T.Matrix3d, Gf.Matrix3d(1, 0, 0, 0, 1, 0, 2, 0, 1)),
        ("i15", T.IntArray, Vt.IntArray(list(range(15)))),
        ("i16", T.IntArray, Vt.IntArray(list(range(16)))),
        ("i64_16", T.Int64Array, Vt.Int64Array([3 * k for k in range(16)])),
        ("u16", T.UIntArray, Vt.UIntArray(list(range(16)))),
        ("f15_int", T.FloatArray, Vt.FloatArray([float(k) for k in range(15)])),
        ("f16_int", T.FloatArray, Vt.FloatArray([float(k) - 8 for k in range(16)])),
        ("f16_half", T.FloatArray, Vt.FloatArray([k + 0.5 for k in range(16)])),
        ("f16_lut4", T.FloatArray, Vt.FloatArray([frac[k % 4] for k in range(16)])),
        ("f16_lut5", T.FloatArray, Vt.FloatArray([frac[k % 5] for k in range(16)])),
        ("d20_lut5", T.DoubleArray, Vt.DoubleArray([frac[k % 5] for k in range(20)])),
        ("d19_lut5", T.DoubleArray, Vt.DoubleArray([frac[k % 5] for k in range(19)])),
        ("d16_int", T.DoubleArray, Vt.DoubleArray([float(-k) for k in range(16)])),
        ("h16_int", T.HalfArray, Vt.HalfArray([float(k) for k in range(16)])),
        ("p3", T.Point3fArray, Vt.Vec3fArray([(0.5, 1, 2)] * 3)),
        ("arr_a", T.FloatArray, Vt.FloatArray([0.5, 0.7, 0.9])),
        ("arr_b", T.FloatArray, Vt.FloatArray([0.5, 0.7, 0.9])),
        # Dictionaries, as customData: an empty one nested, two equal ones.
        # (Equal dictionaries holding stored values, such as arrays, are
        # shared by usd-core, which dedups by value, but not by painterly,
        # which dedups bytes: the second one's nested reps point elsewhere.)
        ("dict_empty", None, {"e": {}}),
        ("dict_a", None, {"x": 0.5, "y": "s", "i": 3}),
        ("dict_b", None, {"x": 0.5, "y": "s", "i": 3}),
    ]


def test_values_are_laid_out_as_usd_core_lays_them(painterly, tmp_path):
    rig = skel_rig(tmp_path, name="panel.usda")
    src = Sdf.Layer.FindOrOpen(str(rig.path))
    prim = Sdf.CreatePrimInLayer(src, "/Values")
    prim.specifier = Sdf.SpecifierDef
    for name, ty, v in rep_panel():
        if ty is None:
            Sdf.AttributeSpec(prim, name, T.Int).customData = v
        else:
            Sdf.AttributeSpec(prim, name, ty).default = v
    theirs = tmp_path / "usd_core.usdc"
    src.Export(str(theirs))
    ours = tmp_path / "painterly.usdc"
    shutil.copy(theirs, ours)
    painterly("bind", ours, "--time", 5, "--in-place", "--quiet")
    assert contents(Sdf.Layer.OpenAsAnonymous(str(ours)))["/Values"] == contents(
        Sdf.Layer.OpenAsAnonymous(str(theirs)))["/Values"], "test setup: values changed"

    def layout(crate, name, ty):
        rep = crate.rep(f"/Values.{name}", "customData" if ty is None else "default")
        reps = crate.dictionary_reps(rep) if ty is None else [rep]
        # The payload is an offset, which differs between files, unless inlined.
        return [(r.type, r.array, r.inlined, r.compressed, r.payload if r.inlined else None) for r in reps]

    u, p = crate_reps.Crate(theirs), crate_reps.Crate(ours)
    differ = [(name, layout(u, name, ty), layout(p, name, ty))
              for name, ty, _ in rep_panel() if layout(u, name, ty) != layout(p, name, ty)]
    assert not differ, f"(value, usd-core's rep, painterly's): {differ}"

    def rep(crate, name):
        return crate.rep(f"/Values.{name}", "customData" if name.startswith("dict") else "default")

    for crate, who in ((u, "usd-core"), (p, "painterly")):
        for name in ("f15_int", "f16_lut5", "p3", "arr_a", "m4_translate"):
            assert rep(crate, name).payload % 8 == 0, f"{who}: {name} not 8-byte aligned"
        assert rep(crate, "dict_a") == rep(crate, "dict_b"), f"{who}: equal dictionaries stored twice"
        assert rep(crate, "arr_a") == rep(crate, "arr_b"), f"{who}: equal arrays stored twice"


# ---------------------------------------------------------------------------
# size


def test_bake_is_no_bigger_than_usd_cores_file(painterly, tmp_path):
    rig = skel_rig(tmp_path, frames=(1, 48), n_strokes=40)
    bake = tmp_path / "bake.usdc"
    painterly("bake", rig.path, "-o", bake, "--quiet", "--bake-proxy")
    theirs = tmp_path / "usd_core.usdc"
    Sdf.Layer.OpenAsAnonymous(str(bake)).Export(str(theirs))
    assert on_disk(theirs) == on_disk(bake)
    ours, ref = bake.stat().st_size, theirs.stat().st_size
    print(f"bake: painterly {ours} bytes, usd-core {ref} bytes ({ours / ref:.3f}x)")
    assert ours <= 1.02 * ref, f"painterly {ours} bytes vs usd-core {ref}"
