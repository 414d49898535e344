"""Bad input: every case exits 1 (2 allowed for malformed --frames), prints a
message on stderr starting with `error:` that names the file, the prim path
and the attribute involved, leaves no output file (nor temporary files)
behind, never panics, and never modifies the input."""

import math
import os
import pathlib
import re
import struct

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

import authoring as Au


# ---------------------------------------------------------------------------
# helpers


def good_static(tmp_path, name="rig.usda", **kw):
    return Au.build_points_rig(tmp_path / name, mode="static", **kw)


def good_skel(tmp_path, name="rig.usda", **kw):
    return Au.build_skel_rig(tmp_path / name, **kw)


def edit(path, fn):
    stage = Usd.Stage.Open(str(path))
    fn(stage)
    stage.GetRootLayer().Save()


def expect_failure(painterly, tmp_path, input_path, *, names=(), extra=(), codes=(1,),
                   name_file=True, out=None):
    """Run a bake expected to fail and check the contract. `names`: strings
    that must appear in stderr (prim paths, attribute names)."""
    out_dir = tmp_path / "out"
    out_dir.mkdir(exist_ok=True)
    out = out if out is not None else out_dir / "bake.usdc"
    before = Au.file_hash(input_path) if os.path.isfile(input_path) else None
    listing = sorted(os.listdir(tmp_path))
    out_listing = sorted(os.listdir(out_dir))
    proc = painterly("bake", input_path, "-o", out, *extra, check=False)
    err = proc.stderr
    assert proc.returncode in codes, f"exit {proc.returncode}, expected {codes}\nstderr:\n{err}\nstdout:\n{proc.stdout}"
    assert "panicked" not in err and "RUST_BACKTRACE" not in err, f"panic:\n{err}"
    assert "Traceback" not in err
    assert re.search(r"^error:", err, re.M), f"no line starting with 'error:' on stderr:\n{err}"
    if name_file:
        base = os.path.basename(str(input_path).rstrip("/"))
        assert base in err, f"error does not name the file {base}:\n{err}"
    for s in names:
        assert s in err, f"error does not mention {s!r}:\n{err}"
    assert not os.path.exists(out), "failed bake left an output file"
    assert sorted(os.listdir(out_dir)) == out_listing, f"failed bake left files: {os.listdir(out_dir)}"
    assert sorted(os.listdir(tmp_path)) == listing, f"failed bake left files: {os.listdir(tmp_path)}"
    if before is not None:
        assert Au.file_hash(input_path) == before, "input modified"
    return err


# ---------------------------------------------------------------------------
# the rig and its proxy


def test_missing_proxy_relationship(painterly, tmp_path):
    rig = good_static(tmp_path)
    edit(rig.path, lambda st: st.GetPrimAtPath(rig.rig).RemoveProperty("painterly:proxy"))
    expect_failure(painterly, tmp_path, rig.path, names=[rig.rig, "painterly:proxy"])


def test_proxy_targets_non_mesh(painterly, tmp_path):
    rig = good_static(tmp_path)
    edit(rig.path, lambda st: st.GetPrimAtPath(rig.rig).GetRelationship("painterly:proxy")
         .SetTargets([Sdf.Path("/World/ProxyXf")]))
    expect_failure(painterly, tmp_path, rig.path, names=["/World/ProxyXf", "painterly:proxy"])


def test_proxy_targets_missing_prim(painterly, tmp_path):
    rig = good_static(tmp_path)
    edit(rig.path, lambda st: st.GetPrimAtPath(rig.rig).GetRelationship("painterly:proxy")
         .SetTargets([Sdf.Path("/World/NoSuchMesh")]))
    expect_failure(painterly, tmp_path, rig.path, names=["/World/NoSuchMesh", "painterly:proxy"])


def test_proxy_without_points(painterly, tmp_path):
    rig = good_static(tmp_path)
    edit(rig.path, lambda st: st.GetPrimAtPath(rig.mesh).RemoveProperty("points"))
    expect_failure(painterly, tmp_path, rig.path, names=[rig.mesh, "points"])


def test_proxy_with_empty_points(painterly, tmp_path):
    rig = good_static(tmp_path)
    edit(rig.path, lambda st: UsdGeom.Mesh(st.GetPrimAtPath(rig.mesh)).GetPointsAttr().Set(Vt.Vec3fArray()))
    expect_failure(painterly, tmp_path, rig.path, names=[rig.mesh, "points"])


def test_time_sampled_proxy_without_rest_pose(painterly, tmp_path):
    """Only time samples, no default value and no painterly:restTime: no rest pose."""
    rig = Au.build_points_rig(tmp_path / "rig.usda", mode="sampled", default_points=False, rest_time=None)
    expect_failure(painterly, tmp_path, rig.path, names=[rig.mesh])


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_proxy_points(painterly, tmp_path, bad):
    rig = good_static(tmp_path)

    def f(st):
        a = UsdGeom.Mesh(st.GetPrimAtPath(rig.mesh)).GetPointsAttr()
        pts = list(a.Get())
        pts[5] = Gf.Vec3f(0.0, bad, 0.0)
        a.Set(Vt.Vec3fArray(pts))
    edit(rig.path, f)
    expect_failure(painterly, tmp_path, rig.path, names=[rig.mesh, "points"])


def test_non_finite_proxy_time_sample(painterly, tmp_path):
    rig = Au.build_points_rig(tmp_path / "rig.usda", mode="sampled")

    def f(st):
        a = UsdGeom.Mesh(st.GetPrimAtPath(rig.mesh)).GetPointsAttr()
        t = a.GetTimeSamples()[-1]
        pts = list(a.Get(t))
        pts[3] = Gf.Vec3f(math.nan, 0.0, 0.0)
        a.Set(Vt.Vec3fArray(pts), t)
    edit(rig.path, f)
    expect_failure(painterly, tmp_path, rig.path, names=[rig.mesh, "points"])


def test_non_finite_skinned_proxy_points(painterly, tmp_path):
    rig = good_skel(tmp_path)

    def f(st):
        a = UsdGeom.Mesh(st.GetPrimAtPath(rig.mesh)).GetPointsAttr()
        pts = list(a.Get())
        pts[0] = Gf.Vec3f(math.inf, 0.0, 0.0)
        a.Set(Vt.Vec3fArray(pts))
    edit(rig.path, f)
    expect_failure(painterly, tmp_path, rig.path, names=[rig.mesh, "points"])


def test_non_finite_joint_translation_is_named_not_the_proxy_points(painterly, tmp_path):
    """An animation value that is not finite made the posed points so, and
    the error blamed the proxy's authored (finite) points (an error-message
    review, 2026-12-07)."""
    from pxr import UsdSkel

    rig = good_skel(tmp_path)
    found = {}

    def f(st):
        anim = next(p for p in st.Traverse() if p.IsA(UsdSkel.Animation))
        a = UsdSkel.Animation(anim).GetTranslationsAttr()
        # The first sample: every earlier frame holds it, and later ones
        # interpolate from it (usd-core's inf · (1 − s) is inf too).
        t = a.GetTimeSamples()[0]
        assert t <= rig.frames[0]
        v = list(a.Get(t))
        v[1] = Gf.Vec3f(math.inf, 0.0, 0.0)
        a.Set(Vt.Vec3fArray(v), t)
        found.update(path=str(anim.GetPath()), time=t)
    edit(rig.path, f)
    err = expect_failure(painterly, tmp_path, rig.path,
                         names=[f"{found['path']}.translations: joint 1's value is not finite at time {found['time']:g}"])
    assert ".points" not in err


# ---------------------------------------------------------------------------
# stroke layers


def test_curve_vertex_counts_do_not_sum_to_points(painterly, tmp_path):
    rig = good_static(tmp_path)

    def f(st):
        a = UsdGeom.BasisCurves(st.GetPrimAtPath(rig.layers[0])).GetCurveVertexCountsAttr()
        c = list(a.Get())
        c[0] += 1
        a.Set(Vt.IntArray(c))
    edit(rig.path, f)
    expect_failure(painterly, tmp_path, rig.path, names=[rig.layers[0], "curveVertexCounts"])


def test_rest_points_count_differs_from_points(painterly, tmp_path):
    rig = good_static(tmp_path)

    def f(st):
        a = st.GetPrimAtPath(rig.layers[0]).GetAttribute("painterly:restPoints")
        a.Set(Vt.Vec3fArray(list(a.Get())[:-2]))
    edit(rig.path, f)
    expect_failure(painterly, tmp_path, rig.path, names=[rig.layers[0], "painterly:restPoints"])


def _cached_binding(rig, vertices=None, weights=None):
    """An edit writing a binding on the first layer: (0, 1, 2) and
    (0.2, 0.3, 0.5) for every point, then `vertices(list, proxy points)` and
    `weights(list)` change them."""
    def f(st):
        prim = st.GetPrimAtPath(rig.layers[0])
        n = len(prim.GetAttribute("painterly:restPoints").Get())
        nv = len(UsdGeom.Mesh(st.GetPrimAtPath(rig.mesh)).GetPointsAttr().Get())
        v = [Gf.Vec3i(0, 1, 2)] * n
        w = [Gf.Vec3f(0.2, 0.3, 0.5)] * n
        v = vertices(v, nv) if vertices else v
        w = weights(w) if weights else w
        prim.CreateAttribute("painterly:bindVertices", Sdf.ValueTypeNames.Int3Array, custom=False).Set(
            Vt.Vec3iArray(v))
        prim.CreateAttribute("painterly:bindWeights", Sdf.ValueTypeNames.Float3Array, custom=False).Set(
            Vt.Vec3fArray(w))
    return f


def _set_item(i, value):
    """Item `i` (None: the middle one) of a list set to `value`."""
    def f(items, *_):
        items = list(items)
        items[len(items) // 2 if i is None else i] = value
        return items
    return f


def test_cached_binding_out_of_range(painterly, tmp_path):
    rig = good_static(tmp_path)
    edit(rig.path, _cached_binding(rig, vertices=lambda v, nv: _set_item(1, Gf.Vec3i(0, nv + 10, 2))(v)))
    expect_failure(painterly, tmp_path, rig.path, names=[rig.layers[0], "painterly:bindVertices"])


def test_cached_binding_negative_index(painterly, tmp_path):
    rig = good_static(tmp_path)
    edit(rig.path, _cached_binding(rig, vertices=_set_item(0, Gf.Vec3i(-1, 1, 2))))
    expect_failure(painterly, tmp_path, rig.path, names=[rig.layers[0], "painterly:bindVertices"])


def test_cached_binding_weights_count_mismatch(painterly, tmp_path):
    rig = good_static(tmp_path)
    edit(rig.path, _cached_binding(rig, weights=lambda w: w[:-1]))
    expect_failure(painterly, tmp_path, rig.path, names=[rig.layers[0], "painterly:bindWeights"])


@pytest.mark.parametrize("weights", [(0.5, 0.5, 0.5), (1.5, -0.25, -0.25)], ids=["sum_1.5", "negative"])
def test_cached_binding_weights_that_are_not_barycentric(painterly, tmp_path, weights):
    """SPEC §3: bindWeights are the barycentric weights of the closest point
    (each in [0, 1], summing to 1). On a static proxy every binding leaves
    a stroke at rest, but (0.5, 0.5, 0.5) scales it by 1.5: refused."""
    rig = good_static(tmp_path)
    edit(rig.path, _cached_binding(rig, weights=_set_item(None, Gf.Vec3f(*weights))))
    err = expect_failure(painterly, tmp_path, rig.path, names=[rig.layers[0], "painterly:bindWeights"])
    assert "barycentric" in err


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_rest_time(painterly, tmp_path, bad):
    """usd-core reads no points at a NaN time (Get(nan) is None): no rest pose."""
    rig = Au.build_points_rig(tmp_path / "rig.usda", mode="sampled", default_points=False, rest_time=2.0)
    edit(rig.path, lambda st: st.GetPrimAtPath(rig.rig).GetAttribute("painterly:restTime").Set(bad))
    expect_failure(painterly, tmp_path, rig.path, names=[f"{rig.rig}.painterly:restTime", "not finite"])


@pytest.mark.parametrize("values", [[1.5], [0.5, -0.1]], ids=["constant", "vertex"])
def test_display_opacity_outside_unit_range(painterly, tmp_path, values):
    rig = good_static(tmp_path)

    def f(st):
        prim = st.GetPrimAtPath(rig.layers[0])
        curves = UsdGeom.BasisCurves(prim)
        if len(values) > 1:
            n = len(prim.GetAttribute("painterly:restPoints").Get())
            vals = [values[0]] * n
            vals[n - 1] = values[1]  # one point's value; the curve's mean stays in range
            interp = UsdGeom.Tokens.vertex
        else:
            vals, interp = values, UsdGeom.Tokens.constant
        pv = UsdGeom.PrimvarsAPI(curves).CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray, interp)
        pv.Set(Vt.FloatArray(vals))
    edit(rig.path, f)
    expect_failure(painterly, tmp_path, rig.path,
                   names=[f"{rig.layers[0]}.primvars:displayOpacity", "outside [0, 1]"])


@pytest.mark.parametrize("case", ["element_size", "interpolation"])
def test_display_opacity_painterly_cannot_read_as_usd_core_does(painterly, tmp_path, case):
    """elementSize above 1 (6 values, constant, elementSize 6 on 6 curves:
    usd-core reads one element of 6 values for every curve; the bake read
    one value per curve, exit 0) and an interpolation usd-core does
    not know (`faceConstant`: the bake guessed from the count; render
    refused it) are refused, naming what (a review, 2026-12-07). The
    same primvars of render and preview refuse elementSize too."""
    rig = good_static(tmp_path)
    interp = UsdGeom.Tokens.constant if case == "element_size" else "faceConstant"
    assert not UsdGeom.Primvar.IsValidInterpolation("faceConstant")

    def f(st):
        curves = UsdGeom.BasisCurves(st.GetPrimAtPath(rig.layers[0]))
        n = len(curves.GetCurveVertexCountsAttr().Get())
        assert n == 6
        pv = UsdGeom.PrimvarsAPI(curves).CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray)
        pv.Set(Vt.FloatArray([0.2 + 0.1 * i for i in range(n)]))
        pv.GetAttr().SetMetadata("interpolation", interp)
        if case == "element_size":
            pv.SetElementSize(n)
    edit(rig.path, f)
    message = ("elementSize 6: painterly reads one value per element of this primvar (elementSize 1)"
               if case == "element_size" else 'unknown interpolation "faceConstant"')
    err = expect_failure(painterly, tmp_path, rig.path, names=[f"{rig.layers[0]}.primvars:displayOpacity"])
    assert err.endswith(f": {message}\n"), err


def test_an_opacity_a_float_step_above_1_is_accepted(painterly, tmp_path):
    """float32 sums of weights that should be 1 give 1.0000001 (4 % of them
    in a review's numpy run): rounding, not a fault."""
    rig = good_static(tmp_path)
    above = float(np.nextafter(np.float32(1.0), np.float32(2.0)))

    def f(st):
        pv = UsdGeom.PrimvarsAPI(UsdGeom.BasisCurves(st.GetPrimAtPath(rig.layers[0]))).CreatePrimvar(
            "displayOpacity", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.constant)
        pv.Set(Vt.FloatArray([above]))
    edit(rig.path, f)
    proc = painterly("bake", rig.path, "-o", tmp_path / "b.usdc", "--quiet", check=False)
    assert proc.returncode == 0, proc.stderr


def test_animated_layer_opacity_outside_unit_range(painterly, tmp_path):
    """Read per frame, linearly between samples as usd-core does: the first
    frame whose value passes 1 (0.5 + 0.75·s > 1, s = (t − t0)/(t1 − t0) >
    2/3) is refused, and named."""
    rig = good_static(tmp_path)
    t0, t1 = rig.frames[0], rig.frames[-1]

    def f(st):
        a = st.GetPrimAtPath(rig.layers[0]).CreateAttribute("painterly:opacity", Sdf.ValueTypeNames.Float)
        a.Set(0.5, t0)
        a.Set(1.25, t1)
    edit(rig.path, f)
    first = next(t for t in rig.frames if 0.5 + 0.75 * (t - t0) / (t1 - t0) > 1.0)
    assert t0 < first < t1
    expect_failure(painterly, tmp_path, rig.path,
                   names=[f"{rig.layers[0]}.painterly:opacity", "outside [0, 1]", f"at time {first:g} "])


def test_proxy_face_index_out_of_range(painterly, tmp_path):
    rig = good_static(tmp_path)

    def f(st):
        a = UsdGeom.Mesh(st.GetPrimAtPath(rig.mesh)).GetFaceVertexIndicesAttr()
        idx = list(a.Get())
        idx[7] = 10_000
        a.Set(Vt.IntArray(idx))
    edit(rig.path, f)
    expect_failure(painterly, tmp_path, rig.path, names=[rig.mesh, "faceVertexIndices"])


def test_proxy_face_counts_do_not_match_indices(painterly, tmp_path):
    rig = good_static(tmp_path)

    def f(st):
        a = UsdGeom.Mesh(st.GetPrimAtPath(rig.mesh)).GetFaceVertexCountsAttr()
        c = list(a.Get())
        c[-1] += 3
        a.Set(Vt.IntArray(c))
    edit(rig.path, f)
    expect_failure(painterly, tmp_path, rig.path, names=[rig.mesh, "faceVertexCounts"])


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_stroke_points(painterly, tmp_path, bad):
    """No restPoints: `points` is the rest pose, and it holds a NaN / inf."""
    rig = good_static(tmp_path, write_rest=False)

    def f(st):
        a = UsdGeom.BasisCurves(st.GetPrimAtPath(rig.layers[0])).GetPointsAttr()
        pts = list(a.Get())
        pts[2] = Gf.Vec3f(0.0, 0.0, bad)
        a.Set(Vt.Vec3fArray(pts))
    edit(rig.path, f)
    expect_failure(painterly, tmp_path, rig.path, names=[rig.layers[0], "points"])


@pytest.mark.parametrize("bad", [math.nan, -math.inf])
def test_non_finite_rest_points(painterly, tmp_path, bad):
    rig = good_static(tmp_path)

    def f(st):
        a = st.GetPrimAtPath(rig.layers[0]).GetAttribute("painterly:restPoints")
        pts = list(a.Get())
        pts[1] = Gf.Vec3f(bad, 0.0, 0.0)
        a.Set(Vt.Vec3fArray(pts))
    edit(rig.path, f)
    expect_failure(painterly, tmp_path, rig.path, names=[rig.layers[0], "painterly:restPoints"])


# ---------------------------------------------------------------------------
# files


def test_input_is_a_directory(painterly, tmp_path):
    d = tmp_path / "looks_like.usda"
    d.mkdir()
    expect_failure(painterly, tmp_path, d)


@pytest.mark.parametrize("ext", ["usda", "usdc", "usd"])
def test_garbage_file(painterly, tmp_path, ext):
    p = tmp_path / f"garbage.{ext}"
    p.write_bytes(bytes(np.random.default_rng(0).integers(0, 256, 4096, dtype=np.uint8)))
    expect_failure(painterly, tmp_path, p)


def test_garbage_usda_text(painterly, tmp_path):
    p = tmp_path / "broken.usda"
    p.write_text('#usda 1.0\n\ndef Xform "World" {\n    double3 xformOp:translate = (1, 2\n')
    expect_failure(painterly, tmp_path, p)


@pytest.mark.parametrize("fraction", [0.5, 0.9, 0.02])
def test_truncated_usdc(painterly, tmp_path, fraction):
    rig = good_skel(tmp_path)
    usdc = tmp_path / "rig_binary.usdc"
    assert Sdf.Layer.FindOrOpen(str(rig.path)).Export(str(usdc))
    data = usdc.read_bytes()
    usdc.write_bytes(data[: max(16, int(len(data) * fraction))])
    expect_failure(painterly, tmp_path, usdc)


def stored_package(path, entries):
    """A .usdz as usd-core writes one: stored (uncompressed) files, in the
    order given, each one's bytes 64-byte aligned by padding in its local
    header's extra field."""
    import zipfile

    with zipfile.ZipFile(path, "w", zipfile.ZIP_STORED) as z:
        for name, data in entries:
            info = zipfile.ZipInfo(name, date_time=(2024, 1, 1, 0, 0, 0))
            header = z.fp.tell() + 30 + len(name.encode()) + 4
            info.extra = b"\x86\x19" + struct.pack("<H", -header % 64) + bytes(-header % 64)
            z.writestr(info, data)
    with zipfile.ZipFile(path) as z:
        raw = path.read_bytes()
        for info in z.infolist():
            n, x = struct.unpack_from("<HH", raw, info.header_offset + 26)
            assert (info.header_offset + 30 + n + x) % 64 == 0
        assert [i.filename for i in z.infolist()] == [name for name, _ in entries]
    return path


def fish_text():
    return (pathlib.Path(__file__).resolve().parent.parent / "fixtures" / "blowfish.usda").read_bytes()


@pytest.mark.parametrize("first", ["blowfish.usda", "blowfish.usd", "Blowfish.USDA", "sub/blowfish.usda"])
def test_a_package_whose_first_file_is_a_usd_layer_is_read(painterly, tmp_path, first):
    pkg = stored_package(tmp_path / "fish.usdz", [(first, fish_text()), ("tex.png", b"\x89PNG\r\n\x1a\n")])
    assert Usd.Stage.Open(str(pkg)).GetPrimAtPath("/Blowfish/Paint/Hair")
    assert painterly("inspect", pkg).stdout.rstrip().endswith("no problems found")


@pytest.mark.parametrize("first, why", [
    ("tex.png", "the package's first file is tex.png, not a USD layer; usd-core opens the first file as "
                "the package's root layer"),
    ("notes/", "the package's first file is notes/, not a USD layer; usd-core opens the first file as "
               "the package's root layer"),
])
def test_a_package_whose_first_file_is_not_a_usd_layer_is_refused(painterly, tmp_path, first, why):
    """usd-core opens a package's first file as its root layer: with an
    image (or a folder) first it opens nothing, where painterly read the
    first USD layer inside. The same files with the layer first are read
    (test above): only the order differs."""
    pkg = stored_package(tmp_path / "fish.usdz", [(first, b"\x89PNG\r\n\x1a\n" if first.endswith("png") else b""),
                                                  ("blowfish.usda", fish_text())])
    assert Sdf.Layer.FindOrOpen(str(pkg)) is None
    with pytest.raises(Exception):
        Usd.Stage.Open(str(pkg))
    proc = painterly("inspect", pkg, check=False)
    assert (proc.returncode, proc.stdout, proc.stderr) == (1, "", f"error: {pkg}: {why}\n")
    expect_failure(painterly, tmp_path, pkg, names=[why])
    # Sublayered or referenced by its bare path, the package is refused too
    # (usd-core composes nothing from it; openusd would read its first layer).
    for arc in ("subLayers", "references"):
        shot = tmp_path / f"shot_{arc}.usda"
        shot.write_text('#usda 1.0\n(\n    subLayers = [@./fish.usdz@]\n)\n' if arc == "subLayers" else
                        '#usda 1.0\ndef Xform "Fish" (\n    references = @./fish.usdz@</Blowfish>\n)\n{\n}\n')
        expect_failure(painterly, tmp_path, shot, name_file=False, names=[f"fish.usdz: {why}"])


def test_a_package_whose_first_file_is_a_package_is_refused(painterly, tmp_path):
    """usd-core opens the first file of a package that is a package's first
    file; openusd would read the outer package's first layer instead (here
    /Other, where usd-core reads /Blowfish). Refused, naming the inner package."""
    inner = stored_package(tmp_path / "inner.usdz", [("blowfish.usda", fish_text())])
    other = b'#usda 1.0\ndef Xform "Other"\n{\n}\n'
    pkg = stored_package(tmp_path / "outer.usdz", [("inner.usdz", inner.read_bytes()), ("other.usda", other)])
    inner.unlink()
    stage = Usd.Stage.Open(str(pkg))
    assert stage.GetPrimAtPath("/Blowfish") and not stage.GetPrimAtPath("/Other")
    expect_failure(painterly, tmp_path, pkg, names=["the package's first file is inner.usdz, another package"])


def test_nonexistent_input(painterly, tmp_path):
    expect_failure(painterly, tmp_path, tmp_path / "does_not_exist.usda")


def test_output_in_missing_directory(painterly, tmp_path):
    rig = good_static(tmp_path)
    out = tmp_path / "no_such_dir" / "bake.usdc"
    err = expect_failure(painterly, tmp_path, rig.path, out=out, name_file=False)
    assert "no_such_dir" in err, f"error does not name the output path:\n{err}"
    assert not (tmp_path / "no_such_dir").exists()


# ---------------------------------------------------------------------------
# --frames


@pytest.mark.parametrize("frames", ["0:5", "5:20", "-3:2", "13", "11:13"])
def test_frames_outside_stage_range(painterly, tmp_path, frames):
    rig = good_skel(tmp_path, frames=(1, 12))
    # --frames=VALUE so that a leading '-' is not taken for an option
    err = expect_failure(painterly, tmp_path, rig.path, extra=[f"--frames={frames}"])
    assert "frame" in err.lower()


@pytest.mark.parametrize("frames", ["1:", "a:b", "5:1", "1:10:0", "1:10:-1", ":5", "1:2:3:4", "nan:3", ""])
def test_malformed_frames(painterly, tmp_path, frames):
    rig = good_skel(tmp_path, frames=(1, 12))
    err = expect_failure(painterly, tmp_path, rig.path, extra=["--frames", frames], codes=(1, 2),
                         name_file=False)
    assert "frames" in err.lower() or (frames and frames in err), err


# ---------------------------------------------------------------------------
# inspect


def test_inspect_reports_problem_with_prim_path(painterly, tmp_path):
    rig = good_static(tmp_path)
    edit(rig.path, lambda st: st.GetPrimAtPath(rig.rig).GetRelationship("painterly:proxy")
         .SetTargets([Sdf.Path("/World/NoSuchMesh")]))
    before = Au.file_hash(rig.path)
    proc = painterly("inspect", rig.path, check=False)
    text = proc.stdout + proc.stderr
    assert "panicked" not in text
    assert "/World/NoSuchMesh" in text or rig.rig in text, text
    assert Au.file_hash(rig.path) == before


def test_inspect_nonexistent_file(painterly, tmp_path):
    proc = painterly("inspect", tmp_path / "nope.usda", check=False)
    assert proc.returncode != 0
    assert "nope.usda" in proc.stderr and "panicked" not in proc.stderr


# ---------------------------------------------------------------------------
# command-line usage


@pytest.mark.parametrize("args", [
    ["bake"],                                   # no input, no -o
    ["bake", "{input}"],                        # no -o
    ["bake", "{input}", "-o", "{out}", "--no-such-flag"],
    ["frobnicate", "{input}"],
])
def test_usage_errors_exit_2(painterly, tmp_path, args):
    rig = good_static(tmp_path)
    out = tmp_path / "usage_out.usdc"
    before = Au.file_hash(rig.path)
    argv = [a.format(input=rig.path, out=out) for a in args]
    proc = painterly(*argv, check=False)
    assert proc.returncode == 2, f"exit {proc.returncode}\n{proc.stderr}"
    assert "error" in proc.stderr.lower() and "panicked" not in proc.stderr
    assert not out.exists()
    assert Au.file_hash(rig.path) == before


def test_curve_vertex_counts_only_as_time_samples_are_named(painterly, tmp_path):
    """usd-core reads time-sampled counts at each frame; painterly reads the
    default, and said "counts sum to 0, but the layer has N points" (an
    inspect review, 2026-12-07)."""
    rig = good_static(tmp_path)

    def f(st):
        a = UsdGeom.BasisCurves(st.GetPrimAtPath(rig.layers[0])).GetCurveVertexCountsAttr()
        counts = a.Get()
        a.Clear()
        a.Set(counts, rig.frames[0])
    edit(rig.path, f)
    err = expect_failure(painterly, tmp_path, rig.path,
                         names=[f"{rig.layers[0]}.curveVertexCounts: authored only as time samples"])
    assert "sum to 0" not in err


def test_curve_vertex_counts_never_authored_is_a_count_mismatch(painterly, tmp_path):
    """With no curveVertexCounts at all (neither default nor samples) the
    counts are empty, so the message is the plain mismatch, not the
    samples-only one: the guard must look at the samples."""
    rig = good_static(tmp_path)

    def f(st):
        UsdGeom.BasisCurves(st.GetPrimAtPath(rig.layers[0])).GetCurveVertexCountsAttr().Clear()
    edit(rig.path, f)
    err = expect_failure(painterly, tmp_path, rig.path,
                         names=[f"{rig.layers[0]}.curveVertexCounts: counts sum to 0, but the layer has "])
    assert "time samples" not in err
