"""SPEC section 7: the layer `painterly bake` writes.

Only `over` specs plus copied layer metadata; samples exactly at the baked
frames; extent = usd-core's UsdGeom.Curves.ComputeExtent of each frame's
points and widths (test_extent.py checks it bit for bit); displayOpacity = authored
(1 when absent) x painterly:opacity per curve; input bytes unchanged; the
composed stage validates cleanly with UsdValidation; CLI reporting (--json,
--quiet); a bake of the committed fixture.
"""

import json
import pathlib
import shutil

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdValidation, Vt

import authoring as Au
import reference_skinning as R

ALLOWED_PROPERTIES = {"points", "extent", "primvars:displayOpacity", "skel:skeleton"}


def bake(painterly, rig_path, out, *extra):
    return painterly("bake", rig_path, "-o", out, *extra)


def test_only_over_specs_and_allowed_properties(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", extra_layers=1, opacity=0.5)
    out = tmp_path / "bake.usda"
    bake(painterly, rig.path, out, "--quiet", "--bake-proxy")
    layer = Sdf.Layer.FindOrOpen(str(out))
    src = Usd.Stage.Open(str(rig.path))
    specs = Au.layer_prim_specs(layer)
    assert specs, "bake layer holds no prim specs"
    for spec in specs:
        assert spec.specifier == Sdf.SpecifierOver, f"{spec.path} is {spec.specifier}, not over"
        assert src.GetPrimAtPath(spec.path).IsValid(), f"bake introduces a prim not in the input: {spec.path}"
        for prop in spec.properties:
            assert prop.name in ALLOWED_PROPERTIES, f"unexpected property in bake: {prop.path}"
    # every stroke layer and the proxy are there
    for lp in rig.layers + [rig.mesh]:
        assert layer.GetPrimAtPath(lp), f"bake has no spec for {lp}"
    assert not layer.subLayerPaths, "the bake layer must not sublayer the input itself"


def test_metadata_copied(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", frames=(2, 9), tcps=30.0, up="Z", mpu=0.01)
    out = tmp_path / "bake.usdc"
    bake(painterly, rig.path, out, "--quiet")
    layer = Sdf.Layer.FindOrOpen(str(out))
    src = Sdf.Layer.FindOrOpen(str(rig.path))
    assert layer.startTimeCode == 2 and layer.endTimeCode == 9
    assert layer.timeCodesPerSecond == 30
    stage = Usd.Stage.Open(layer)
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.01)
    assert src.timeCodesPerSecond == layer.timeCodesPerSecond


def test_units_and_up_axis_the_input_leaves_unauthored_are_not_written(painterly, tmp_path):
    """openusd answers its fallbacks (metersPerUnit 0.01, upAxis Y) for an
    input that authors neither, and the bake and the edit layer wrote them
    as if authored (a TD workflow review, 2026-12-06). They copy only what
    the input's root layer authors now, as for timeCodesPerSecond."""
    rig = Au.build_skel_rig(tmp_path / "rig.usda")
    src = Sdf.Layer.FindOrOpen(str(rig.path))
    for key in ("metersPerUnit", "upAxis"):
        src.pseudoRoot.ClearInfo(key)
    src.Save()
    bake(painterly, rig.path, tmp_path / "bake.usdc", "--quiet", "--frames", "1:2")
    painterly("key", rig.path, "--layer", rig.layers[0], "--time", "2", "--sentinel", "--edit-layer",
              tmp_path / "edit.usda", "-q")
    for name in ("bake.usdc", "edit.usda"):
        layer = Sdf.Layer.FindOrOpen(str(tmp_path / name))
        keys = layer.pseudoRoot.ListInfoKeys()
        assert "metersPerUnit" not in keys and "upAxis" not in keys, (name, keys)
    assert json.loads(painterly("inspect", rig.path, "--json").stdout)["up_axis"] is None


@pytest.mark.parametrize("frames_arg,frames", [(None, Au.frame_list(1, 12)), ("3:9:2", [3.0, 5.0, 7.0, 9.0])])
def test_samples_exactly_at_baked_frames_and_extent(painterly, tmp_path, frames_arg, frames):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", frames=(1, 12))
    out = tmp_path / "bake.usdc"
    extra = ["--quiet"] + (["--frames", frames_arg] if frames_arg else [])
    bake(painterly, rig.path, out, *extra)
    layer = Sdf.Layer.FindOrOpen(str(out))
    src = Usd.Stage.Open(str(rig.path))
    for lp in rig.layers:
        pp = Sdf.Path(lp).AppendProperty("points")
        ep = Sdf.Path(lp).AppendProperty("extent")
        assert list(layer.ListTimeSamplesForPath(pp)) == pytest.approx(frames)
        assert list(layer.ListTimeSamplesForPath(ep)) == pytest.approx(frames)
        dp = Sdf.Path(lp).AppendProperty("primvars:displayOpacity")
        if layer.GetAttributeAtPath(dp) and layer.GetNumTimeSamplesForPath(dp):
            assert list(layer.ListTimeSamplesForPath(dp)) == pytest.approx(frames)
        widths = UsdGeom.BasisCurves(src.GetPrimAtPath(lp)).GetWidthsAttr().Get()
        assert widths and max(widths) > 0
        for t in frames:
            pts = layer.QueryTimeSample(pp, t)
            ext = np.array(layer.QueryTimeSample(ep, t), dtype=np.float64)
            assert ext.shape == (2, 3)
            want = np.array(UsdGeom.Curves.ComputeExtent(pts, widths), dtype=np.float64)
            np.testing.assert_array_equal(ext, want, err_msg=f"{lp}.extent at t={t}")


@pytest.mark.parametrize("frames_arg,frames", [(None, Au.frame_list(-4, 4)), ("--frames=-3:1:2", [-3.0, -1.0, 1.0])])
def test_negative_time_codes(painterly, tmp_path, frames_arg, frames):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", frames=(-4, 4))
    out = tmp_path / "bake.usdc"
    bake(painterly, rig.path, out, "--quiet", *([frames_arg] if frames_arg else []))
    layer = Sdf.Layer.FindOrOpen(str(out))
    assert layer.startTimeCode == -4 and layer.endTimeCode == 4
    for lp in rig.layers:
        assert list(layer.ListTimeSamplesForPath(Sdf.Path(lp).AppendProperty("points"))) == pytest.approx(frames)


@pytest.mark.parametrize("authored,interp,opacity", [
    (None, None, None),            # 1 x 1
    (None, None, 0.25),            # fallback 1 x layer opacity
    ("uniform", "uniform", 0.5),   # per curve x layer opacity
    ("uniform", "uniform", None),
    ("constant", "constant", 0.4),
])
def test_display_opacity(painterly, tmp_path, authored, interp, opacity):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", opacity=opacity, n_strokes=5)
    st = Usd.Stage.Open(str(rig.path))
    prim = st.GetPrimAtPath(rig.layers[0])
    n = len(UsdGeom.BasisCurves(prim).GetCurveVertexCountsAttr().Get())
    if authored == "uniform":
        UsdGeom.PrimvarsAPI(prim).CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray,
                                                UsdGeom.Tokens.uniform).Set([0.1 + 0.2 * i for i in range(n)])
    elif authored == "constant":
        UsdGeom.PrimvarsAPI(prim).CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray,
                                                UsdGeom.Tokens.constant).Set([0.7])
    st.GetRootLayer().Save()
    expected = R.expected_display_opacity(Usd.Stage.Open(str(rig.path)), rig.layers[0])
    assert len(expected) == n
    out = tmp_path / "bake.usdc"
    bake(painterly, rig.path, out, "--quiet")
    comp = Au.compose(rig.path, out)
    pv = UsdGeom.PrimvarsAPI(comp.GetPrimAtPath(rig.layers[0])).GetPrimvar("displayOpacity")
    assert pv and pv.HasAuthoredValue(), "no primvars:displayOpacity in the composed result"
    for t in rig.frames:
        vals = np.array(pv.ComputeFlattened(t), dtype=np.float64)
        if pv.GetInterpolation() == UsdGeom.Tokens.constant:
            assert len(vals) == 1, f"constant displayOpacity with {len(vals)} values"
            vals = np.full(n, vals[0])
        else:
            assert pv.GetInterpolation() == UsdGeom.Tokens.uniform, pv.GetInterpolation()
        assert len(vals) == n
        np.testing.assert_allclose(vals, expected, atol=1e-6, err_msg=f"t={t}")


def test_input_bytes_unchanged(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda")
    before = Au.file_hash(rig.path)
    mtime = rig.path.stat().st_mtime_ns
    bake(painterly, rig.path, tmp_path / "bake.usdc", "--quiet", "--bake-proxy")
    bake(painterly, rig.path, tmp_path / "bake.usda", "--quiet")
    assert Au.file_hash(rig.path) == before
    assert rig.path.stat().st_mtime_ns == mtime
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bake.usda", "bake.usdc", "rig.usda"]


def _validation_errors(stage):
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    errs = ctx.Validate(stage)
    return [f"{e.GetName()}: {e.GetMessage()}" for e in errs
            if e.GetType() == UsdValidation.ValidationErrorType.Error]


@pytest.mark.parametrize("bake_proxy", [False, True])
def test_validation_clean(painterly, tmp_path, bake_proxy):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", blend_shapes={"dense"}, opacity=0.5,
                            display_opacity=lambda n: [0.5] * n)
    src_errors = _validation_errors(Usd.Stage.Open(str(rig.path)))
    assert src_errors == [], f"test input itself fails validation: {src_errors}"
    out = tmp_path / "bake.usdc"
    bake(painterly, rig.path, out, "--quiet", *(["--bake-proxy"] if bake_proxy else []))
    errors = _validation_errors(Au.compose(rig.path, out))
    assert errors == [], "\n".join(errors)
    # and the bake layer alone opens as a stage (an override layer need not
    # name a defaultPrim, so only opening is checked)
    assert Usd.Stage.Open(str(out))


def test_validation_real_asset_adds_no_errors(painterly, tmp_path, real_assets):
    rig = Au.wrap_real_asset(real_assets, "CesiumMan", tmp_path)
    before = _validation_errors(Usd.Stage.Open(str(rig.path)))
    out = tmp_path / "bake.usdc"
    bake(painterly, rig.path, out, "--quiet", "--bake-proxy")
    after = _validation_errors(Au.compose(rig.path, out))
    # compare by error name and message minus the (anonymous) root layer name
    def key(e):
        return e.split(" with root layer ")[0]
    new = sorted(set(map(key, after)) - set(map(key, before)))
    assert not new, f"new validation errors: {new}"


def test_json_summary(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda", extra_layers=1, n_strokes=5)
    out = tmp_path / "bake.usdc"
    proc = bake(painterly, rig.path, out, "--json", "--frames", "2:10:2")
    lines = [l for l in proc.stdout.splitlines() if l.strip()]
    assert len(lines) == 1, f"--json must print one JSON object on stdout, got:\n{proc.stdout}"
    info = json.loads(lines[0])
    for key in ("input", "output", "frames", "layers", "strokes", "points", "seconds"):
        assert key in info, f"--json output lacks {key!r}: {info}"
    assert pathlib.Path(info["input"]).resolve() == rig.path.resolve()
    assert pathlib.Path(info["output"]).resolve() == out.resolve()
    frames = [2.0, 4.0, 6.0, 8.0, 10.0]
    if isinstance(info["frames"], list):
        assert info["frames"] == pytest.approx(frames)
    else:
        assert info["frames"] == len(frames)
    n_layers = len(rig.layers)
    assert (info["layers"] if isinstance(info["layers"], int) else len(info["layers"])) == n_layers
    st = Usd.Stage.Open(str(rig.path))
    n_curves = sum(len(UsdGeom.BasisCurves(st.GetPrimAtPath(lp)).GetCurveVertexCountsAttr().Get())
                   for lp in rig.layers)
    n_points = sum(len(UsdGeom.BasisCurves(st.GetPrimAtPath(lp)).GetPointsAttr().Get()) for lp in rig.layers)
    assert info["strokes"] == n_curves
    assert info["points"] in (n_points, n_points * len(frames))
    assert isinstance(info["seconds"], (int, float)) and info["seconds"] >= 0


def test_quiet_prints_nothing(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda")
    proc = bake(painterly, rig.path, tmp_path / "bake.usdc", "--quiet")
    assert proc.stdout == ""
    assert "error" not in proc.stderr.lower()


def test_default_output_reports_something(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda")
    proc = bake(painterly, rig.path, tmp_path / "bake.usdc")
    assert proc.stdout.strip() or proc.stderr.strip(), "a normal bake should print a summary"


def test_overwrites_existing_output(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda")
    out = tmp_path / "bake.usdc"
    out.write_bytes(b"old contents")
    bake(painterly, rig.path, out, "--quiet")
    assert out.read_bytes().startswith(b"PXR-USDC")


def test_inspect_good_file(painterly, tmp_path):
    rig = Au.build_skel_rig(tmp_path / "rig.usda")
    proc = painterly("inspect", rig.path)
    assert proc.returncode == 0
    assert rig.mesh in proc.stdout and rig.layers[0] in proc.stdout, proc.stdout
    proc = painterly("inspect", rig.path, "--json")
    json.loads(proc.stdout)


def _fixture(repo_root, name):
    p = pathlib.Path(repo_root) / "fixtures" / name
    if not p.exists():
        pytest.skip(f"fixture {p} not present")
    return p


def test_fixture_tube_bake(painterly, tmp_path, repo_root):
    src = _fixture(repo_root, "tube.usda")
    before = Au.file_hash(src)
    out = tmp_path / "tube_bake.usdc"
    painterly("bake", src, "-o", out, "--quiet")
    assert Au.file_hash(src) == before
    layer = Sdf.Layer.FindOrOpen(str(out))
    for spec in Au.layer_prim_specs(layer):
        assert spec.specifier == Sdf.SpecifierOver, spec.path
    stage, rigs = R.describe(src)
    frames = Au.frame_list(stage.GetStartTimeCode(), stage.GetEndTimeCode())
    layers = [l["path"] for r in rigs for l in r["layers"]]
    assert layers, "fixture has no stroke layers"
    comp = Au.compose(src, out)
    for lp in layers:
        for t in frames:
            pts = Au.local_points(comp, lp, t)
            assert np.all(np.isfinite(pts))
    # Without pose/time keys or axes the bake is pure skinning: compare with the reference.
    keyed = any(p.GetTypeName() in ("PainterlyPoseKey", "PainterlyTimeKey", "PainterlyAxis")
                for p in stage.Traverse())
    if keyed:
        return
    posed = Au.usdcore_world_points(src, sorted({r["mesh"] for r in rigs}), frames)
    exp = R.expected_strokes(src, frames, posed_world=posed)
    for r in rigs:
        for l in r["layers"]:
            for t in frames:
                diag = Au.bbox_diag(posed[r["mesh"]][t])
                err = np.abs(Au.local_points(comp, l["path"], t) - exp[l["path"]][t]).max() / diag
                assert err <= 1e-5, f"{l['path']} t={t}: {err:.3g} x diagonal"


def all_samples(layer):
    """{(attribute path, time): value} for every time sample in `layer`."""
    out = {}

    def visit(path):
        if path.IsPropertyPath():
            for t in layer.ListTimeSamplesForPath(path):
                out[(str(path), t)] = np.array(layer.QueryTimeSample(path, t))

    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return out


@pytest.mark.parametrize("fixture", ["blowfish.usda", "head.usda"])
def test_usda_and_usdc_bakes_hold_the_same_samples(painterly, tmp_path, repo_root, fixture):
    """The two writers (streamed text, crate) must agree bit for bit."""
    src = repo_root / "fixtures" / fixture
    a, c = tmp_path / "b.usda", tmp_path / "b.usdc"
    bake(painterly, src, a, "--frames", "1:6:0.5", "--bake-proxy", "--quiet")
    bake(painterly, src, c, "--frames", "1:6:0.5", "--bake-proxy", "--quiet")
    sa, sc = all_samples(Sdf.Layer.FindOrOpen(str(a))), all_samples(Sdf.Layer.FindOrOpen(str(c)))
    assert sa.keys() == sc.keys() and len(sa) > 0
    assert {t for _, t in sa} == {1 + 0.5 * k for k in range(11)}
    for k in sa:
        assert sa[k].dtype == sc[k].dtype and np.array_equal(sa[k], sc[k]), k
    la, lc = Sdf.Layer.FindOrOpen(str(a)), Sdf.Layer.FindOrOpen(str(c))
    for attr in ("primvars:displayOpacity",):
        for path in {p for p, _ in sa if p.endswith("." + attr)}:
            assert la.GetAttributeAtPath(path).GetInfo("interpolation") == "uniform"
            assert lc.GetAttributeAtPath(path).GetInfo("interpolation") == "uniform"


@pytest.mark.parametrize("ext", ["usda", "usdc"])
def test_provenance_in_custom_layer_data(painterly, tmp_path, repo_root, ext):
    src = repo_root / "fixtures" / "tube.usda"
    out = tmp_path / f"b.{ext}"
    bake(painterly, src, out, "--frames", "2:10:2", "--quiet")
    data = Sdf.Layer.FindOrOpen(str(out)).customLayerData["painterly"]
    assert data["input"] == str(src.resolve())
    assert data["frames"] == "2:10:2"
    cargo = (repo_root / "Cargo.toml").read_text()
    assert f'version = "{data["version"]}"' in cargo


def test_stage_with_nothing_to_bake_exits_1_and_writes_nothing(painterly, tmp_path):
    src = tmp_path / "plain.usda"
    stage = Usd.Stage.CreateNew(str(src))
    UsdGeom.Mesh.Define(stage, "/World/Mesh")
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(4)
    stage.Save()
    out = tmp_path / "b.usdc"
    proc = painterly("bake", src, "-o", out, check=False)
    assert proc.returncode == 1
    assert "nothing to bake" in proc.stderr and str(src) in proc.stderr
    assert not out.exists()
    assert list(tmp_path.iterdir()) == [src]


def test_a_rig_without_stroke_layers_bakes_only_with_bake_proxy(painterly, tmp_path, repo_root):
    """A rig whose stroke layers are gone has nothing to bake (exit 1, no
    file), unless --bake-proxy asks for its proxy, which is then written."""
    src = tmp_path / "bare_rig.usda"
    shutil.copyfile(repo_root / "fixtures" / "tube.usda", src)
    stage = Usd.Stage.Open(str(src))
    for name in ("Rings", "Stripes"):
        assert stage.RemovePrim(f"/Tube/Paint/{name}")
    stage.Save()
    out = tmp_path / "b.usdc"
    proc = painterly("bake", src, "-o", out, "--frames", "1:3", check=False)
    assert proc.returncode == 1
    assert "nothing to bake" in proc.stderr and str(src) in proc.stderr
    assert not out.exists()
    proc = painterly("bake", src, "-o", out, "--frames", "1:3", "--bake-proxy", "--json")
    assert json.loads(proc.stdout)["layers"] == 0
    layer = Sdf.Layer.FindOrOpen(str(out))
    assert layer.ListTimeSamplesForPath("/Tube/Rig/Proxy.points") == [1.0, 2.0, 3.0]


def test_bake_proxy_writes_each_rig_proxy_once(painterly, tmp_path, repo_root):
    """--bake-proxy over three rigs: two share the tube's proxy, the third
    has a copy of the whole SkelRoot as its own. Each proxy mesh is written
    (the shared one once, equal to a one-rig bake's), and the copy's points
    equal the original's, since it is the same rig."""
    one = tmp_path / "one.usda"
    shutil.copyfile(repo_root / "fixtures" / "tube.usda", one)
    src = tmp_path / "three.usda"
    layer = Sdf.Layer.FindOrOpen(str(one))
    assert Sdf.CopySpec(layer, "/Tube/Paint", layer, "/Tube/PaintShared")
    assert Sdf.CopySpec(layer, "/Tube/Rig", layer, "/Tube/Rig2")
    assert Sdf.CopySpec(layer, "/Tube/Paint", layer, "/Tube/Paint2")
    layer.GetRelationshipAtPath("/Tube/Paint2.painterly:proxy").targetPathList.explicitItems = ["/Tube/Rig2/Proxy"]
    layer.Export(str(src))
    layer.Reload(True)
    outs = {}
    for name, path, rigs in (("one", one, 1), ("three", src, 3)):
        outs[name] = tmp_path / f"{name}_bake.usdc"
        proc = painterly("bake", path, "-o", outs[name], "--frames", "1:3", "--bake-proxy", "--json")
        assert json.loads(proc.stdout)["rigs"] == rigs
    got = Sdf.Layer.FindOrOpen(str(outs["three"]))
    want = Sdf.Layer.FindOrOpen(str(outs["one"]))
    for mesh in ("/Tube/Rig/Proxy", "/Tube/Rig2/Proxy"):
        pts = Sdf.Path(mesh).AppendProperty("points")
        assert got.ListTimeSamplesForPath(pts) == [1.0, 2.0, 3.0], mesh
        for t in (1.0, 2.0, 3.0):
            assert np.array_equal(np.array(got.QueryTimeSample(pts, t)),
                                  np.array(want.QueryTimeSample("/Tube/Rig/Proxy.points", t))), (mesh, t)


def test_bake_proxy_beside_a_view_dependent_mesh(painterly, tmp_path, repo_root):
    """A rig's proxy that is not the stage's view-dependent mesh is written
    by --bake-proxy next to that mesh."""
    fix = repo_root / "fixtures"
    root = tmp_path / "both.usda"
    root.write_text(f"#usda 1.0\n(\n    subLayers = [@{fix / 'tube.usda'}@, @{fix / 'building.usda'}@]\n)\n")
    out = tmp_path / "b.usdc"
    painterly("bake", root, "-o", out, "--frames", "1:3", "--bake-proxy", "-q")
    layer = Sdf.Layer.FindOrOpen(str(out))
    for mesh in ("/Tube/Rig/Proxy", "/Building/Box"):
        assert layer.ListTimeSamplesForPath(f"{mesh}.points") == [1.0, 2.0, 3.0], mesh


def test_skeleton_blocked_only_on_meshes_the_bake_writes(painterly, tmp_path, repo_root):
    """skel:skeleton is blocked on a skinned proxy only when --bake-proxy
    writes its points: otherwise viewers must go on skinning it."""
    src = repo_root / "fixtures" / "tube.usda"
    rel = Sdf.Path("/Tube/Rig/Proxy").AppendProperty("skel:skeleton")
    for flags, blocked in (([], False), (["--bake-proxy"], True)):
        out = tmp_path / f"b{len(flags)}.usda"
        painterly("bake", src, "-o", out, "--frames", "1:2", "-q", *flags)
        assert (Sdf.Layer.FindOrOpen(str(out)).GetRelationshipAtPath(rel) is not None) == blocked, flags
        comp = Au.compose(src, out)
        targets = comp.GetPrimAtPath("/Tube/Rig/Proxy").GetRelationship("skel:skeleton").GetTargets()
        assert (targets == []) == blocked, (flags, targets)


def _usd_varying_len(basis, wrap, n):
    """Values of a `varying` primvar on one cubic curve of n vertices, as
    usd-core counts them (ComputeVaryingDataSize on a curve of its own)."""
    stage = Usd.Stage.CreateInMemory()
    c = UsdGeom.BasisCurves.Define(stage, "/c")
    c.GetCurveVertexCountsAttr().Set([n])
    c.GetTypeAttr().Set(UsdGeom.Tokens.cubic)
    c.GetBasisAttr().Set(basis)
    c.GetWrapAttr().Set(wrap)
    return c.ComputeVaryingDataSize(Usd.TimeCode.Default())


@pytest.mark.parametrize("basis,wrap", [("bezier", "nonperiodic"), ("bezier", "periodic"),
                                        ("catmullRom", "pinned"), ("bspline", "nonperiodic")])
@pytest.mark.parametrize("interp", ["varying", "faceVarying"])
def test_varying_display_opacity_on_cubic_curves(painterly, tmp_path, basis, wrap, interp):
    """A cubic curve's varying primvar has one value per span end, not per
    vertex: 4-vertex bezier curves take 2 values each. It was refused
    ("fit neither 1, N curves nor M points"; a SPEC review, 2026-12-07);
    the bake's per-curve opacity is the mean of each curve's values."""
    rig = Au.build_points_rig(tmp_path / "rig.usda", mode="static")
    st = Usd.Stage.Open(str(rig.path))
    curves = UsdGeom.BasisCurves(st.GetPrimAtPath(rig.layers[0]))
    counts = list(curves.GetCurveVertexCountsAttr().Get())
    curves.GetTypeAttr().Set(UsdGeom.Tokens.cubic)
    curves.GetBasisAttr().Set(basis)
    curves.GetWrapAttr().Set(wrap)
    lens = [_usd_varying_len(basis, wrap, n) for n in counts]
    assert sum(lens) == curves.ComputeVaryingDataSize(Usd.TimeCode.Default())
    assert sum(lens) != sum(counts)
    rng = np.random.default_rng(3)
    values = rng.uniform(0.1, 0.9, sum(lens))
    UsdGeom.PrimvarsAPI(curves).CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray,
                                              interp).Set(Vt.FloatArray(values.tolist()))
    st.GetRootLayer().Save()
    values = np.array(Vt.FloatArray(values.tolist()), dtype=np.float64)  # as stored, f32
    expected = [values[s:s + k].mean() for s, k in zip(np.cumsum([0] + lens[:-1]), lens)]
    out = tmp_path / "bake.usdc"
    bake(painterly, rig.path, out, "--quiet")
    comp = Au.compose(rig.path, out)  # kept: the prim dies with its stage
    pv = UsdGeom.PrimvarsAPI(comp.GetPrimAtPath(rig.layers[0])).GetPrimvar("displayOpacity")
    assert pv.GetInterpolation() == UsdGeom.Tokens.uniform
    np.testing.assert_allclose(np.array(pv.ComputeFlattened(rig.frames[0])), expected, atol=1e-6)
