"""painterly's rules as usd-core UsdValidation validators (issue 14).

- `plugInfo.json` declares one validator per rule `painterly inspect`
  checks (`painterly.RULES`, from the Rust `Rule` list), keyword
  "painterly";
- every rule's validator fires on a bad input written with usd-core, names
  the prim and attribute, and agrees with `painterly inspect`; it stays
  quiet on every fixture;
- usd-core finds the plugin through PXR_PLUGINPATH_NAME (set before its
  registry starts) and imports it lazily; importing `painterly.validators`
  after the registry started registers the same validators explicitly;
- `painterly-validate FILE` exits 1 on errors, 0 without, 2 on bad usage.
"""

import json
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdValidation, Vt

import authoring as Au
import authoring_keys as AK
from conftest import PAINTERLY_PLUGIN, REPO, run_painterly

if os.environ.get("PAINTERLY_PYTHON_PACKAGE") == "required":
    import painterly
else:
    painterly = pytest.importorskip("painterly")

FIXTURES = REPO / "fixtures"
PLUGIN = "painterly.validators"
T = Sdf.ValueTypeNames
LAYER = "/World/Paint/Hair"
FACE = "/World/Face"


def good_stage(path):
    """A small correct character: a static proxy, an attribute axis, a stroke
    layer with two pose keys, a time key bounded by a sentinel, and a
    view-dependent mesh with one key."""
    stage = Usd.Stage.CreateNew(str(path))
    Au.set_stage_metadata(stage, 1, 11)
    knob = stage.DefinePrim("/World/Controls").CreateAttribute("knob", T.Double)
    knob.Set(0.0, 1)
    knob.Set(1.0, 11)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Proxy")
    mesh.CreateFaceVertexCountsAttr([4, 4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 4, 3, 1, 2, 5, 4])
    quad = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0]]
    mesh.CreatePointsAttr(Au.v3f(quad))
    Au.add_painterly_rig(stage, "/World/Paint", "/World/Proxy")
    AK.add_axis(stage, "/World/Paint/knob", "attribute", source="/World/Controls.knob")
    low = np.array([[0.2, 0.2, 0], [0.8, 0.5, 0], [1.5, 0.5, 0], [1.8, 0.8, 0]])
    Au.add_stroke_layer(stage, LAYER, [4], low)
    AK.add_pose_key(stage, LAYER, "low", [0], points=low)
    AK.add_pose_key(stage, LAYER, "high", [1], points=low + 0.1)
    AK.add_time_key(stage, LAYER, "shock", 6, points=low - 0.1)
    AK.add_time_key(stage, LAYER, "calm", 8, sentinel=True)
    face = UsdGeom.Mesh.Define(stage, FACE)
    face.CreateFaceVertexCountsAttr([4])
    face.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    face.CreatePointsAttr(Au.v3f(quad[:2] + [quad[4], quad[3]]))
    face.GetPrim().AddAppliedSchema("PainterlyViewDependentAPI")
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(1, 0.5, 5))
    face.GetPrim().CreateRelationship("painterly:camera").SetTargets([cam.GetPath()])
    key = stage.DefinePrim(f"{FACE}/front", "PainterlyViewKey")
    key.CreateAttribute("direction", T.Float3).Set(Gf.Vec3f(0, 0, 1))
    key.CreateAttribute("points", T.Point3fArray).Set(Au.v3f(np.array(quad[:2] + [quad[4], quad[3]]) + [0, 0, 0.2]))
    return stage


def prim(stage, path):
    return stage.GetPrimAtPath(path)


def _curves(stage, path, parent_api=True):
    c = UsdGeom.BasisCurves.Define(stage, path)
    c.GetPrim().AddAppliedSchema("PainterlyStrokeLayerAPI")
    c.CreateCurveVertexCountsAttr([2])
    return c


def _skinning(stage):
    # usd-core reads a binding only within a SkelRoot's scope.
    stage.GetPrimAtPath("/World").SetTypeName("SkelRoot")
    p = prim(stage, "/World/Proxy")
    p.AddAppliedSchema("SkelBindingAPI")
    p.CreateRelationship("skel:skeleton").SetTargets([Sdf.Path("/World/Controls")])
    return "/World/Proxy", "skel:skeleton"


def _layer_not_curves(stage):
    x = UsdGeom.Xform.Define(stage, "/World/Paint/NotCurves")
    x.GetPrim().AddAppliedSchema("PainterlyStrokeLayerAPI")
    return "/World/Paint/NotCurves", None


def _missing_rest_points(stage):
    _curves(stage, "/World/Paint/Empty")
    return "/World/Paint/Empty", "points"


def _layer_outside_rig(stage):
    c = _curves(stage, "/World/Loose")
    c.CreatePointsAttr(Au.v3f([[0, 0, 0], [1, 0, 0]]))
    return "/World/Loose", None


def _set(path, name, tname, value):
    def make(stage):
        prim(stage, path).CreateAttribute(name, tname).Set(value)
        return path, name

    return make


def _time_key_without_time(stage):
    stage.DefinePrim(f"{LAYER}/untimed", "PainterlyTimeKey")
    return f"{LAYER}/untimed", "time"


def _sentinel_with_points(stage):
    prim(stage, f"{LAYER}/calm").CreateAttribute("points", T.Point3fArray).Set(Au.v3f(np.zeros((4, 3))))
    return f"{LAYER}/calm", "points"


def _binding_half(stage):
    prim(stage, LAYER).CreateAttribute("painterly:bindVertices", T.Int3Array).Set(Vt.Vec3iArray([Gf.Vec3i(0, 1, 4)] * 4))
    return LAYER, "painterly:bindWeights"


def _second_untimed_view_key(stage):
    key = stage.DefinePrim(f"{FACE}/front2", "PainterlyViewKey")
    key.CreateAttribute("direction", T.Float3).Set(Gf.Vec3f(0, 0, 2))
    key.CreateAttribute("points", T.Point3fArray).Set(prim(stage, f"{FACE}/front").GetAttribute("points").Get())
    # Neither key has a time: the second one's direction is what repeats.
    return f"{FACE}/front2", "direction"


def _instanced(stage):
    """The good character again, as an instance: its prims are instance
    proxies that no bake can override."""
    crowd = stage.DefinePrim("/Crowd")
    crowd.GetReferences().AddInternalReference("/World")
    crowd.SetInstanceable(True)
    return "/Crowd", None


def _missing_proxy(stage):
    prim(stage, "/World/Paint").GetRelationship("painterly:proxy").ClearTargets(True)
    return "/World/Paint", "painterly:proxy"


def _spec_with_type(stage, path, name, tname, value):
    """An attribute spec of the wrong type, written at the Sdf level (the
    schema plugin makes usd-core refuse it through Usd)."""
    spec = Sdf.AttributeSpec(stage.GetRootLayer().GetPrimAtPath(path), name, tname)
    spec.default = value
    return path, name


NAN = float("nan")

# rule id → a function that breaks a good stage and returns the (prim, attribute) the error must name.
BREAK = {
    "missing-proxy": _missing_proxy,
    "mesh": _set("/World/Proxy", "faceVertexIndices", T.IntArray, Vt.IntArray([0, 1, 4, 3, 1, 2, 5, 9])),
    "skinning": _skinning,
    "layer-outside-rig": _layer_outside_rig,
    "layer-not-curves": _layer_not_curves,
    "point-counts": _set(LAYER, "curveVertexCounts", T.IntArray, Vt.IntArray([5])),
    "missing-rest-points": _missing_rest_points,
    "binding": _binding_half,
    "display-opacity": _set(LAYER, "primvars:displayOpacity", T.FloatArray, Vt.FloatArray([1, 1, 1])),
    "axis": _set("/World/Paint/knob", "kind", T.Token, "bogus"),
    "key-point-counts": _set(f"{LAYER}/high", "points", T.Point3fArray, Au.v3f(np.zeros((3, 3)))),
    "key-coordinates": _set(f"{LAYER}/high", "coordinates", T.FloatArray, Vt.FloatArray([1, 2])),
    "key-time": _time_key_without_time,
    "coincident-keys": lambda s: (_set(f"{LAYER}/high", "coordinates", T.FloatArray, Vt.FloatArray([0]))(s), (f"{LAYER}/low", "coordinates"))[1],
    "sentinel-misuse": _sentinel_with_points,
    "interpolation": _set(LAYER, "painterly:interpolation", T.Token, "linear"),
    "view-mesh": _set(FACE, "painterly:uncovered", T.Token, "sideways"),
    "view-key-counts": _set(f"{FACE}/front", "points", T.Point3fArray, Au.v3f(np.zeros((3, 3)))),
    "view-key-directions": _set(f"{FACE}/front", "direction", T.Float3, Gf.Vec3f(0, 0, 0)),
    "view-key-times": _second_untimed_view_key,
    "non-finite": _set(LAYER, "painterly:restPoints", T.Point3fArray, Au.v3f([[0, 0, 0], [NAN, 0, 0], [1, 0, 0], [1, 1, 0]])),
    "attribute-type": lambda s: _spec_with_type(s, LAYER, "painterly:opacity", T.String, "half"),
    "instanced": _instanced,
}
# Rules whose bad input is not a stage edit: tested on their own below.
SEPARATE = {"chunks", "unreadable"}


_opened = []  # stages stay alive while their errors' sites are looked at


def validate(path_or_stage):
    stage = path_or_stage if isinstance(path_or_stage, Usd.Stage) else Usd.Stage.Open(str(path_or_stage))
    _opened[:] = [stage]
    context = UsdValidation.ValidationContext(keywords=["painterly"])
    return [e for e in context.Validate(stage) if not e.HasNoError()]


def by_validator(errors):
    out = {}
    for e in errors:
        out.setdefault(e.GetValidator().GetMetadata().name, []).append(e)
    return out


def test_plugin_info_declares_one_validator_per_rule():
    with open(pathlib.Path(painterly.plugin_path()) / "plugInfo.json") as f:
        info = json.load(f)
    import painterly.validators as V

    assert info == V.plugin_info()
    declared = info["Plugins"][0]["Info"]["Validators"]
    assert declared.pop("keywords") == ["painterly"]
    assert sorted(declared) == sorted(r["validator"] for r in painterly.RULES)
    # Every rule is broken by a test below.
    assert sorted(BREAK.keys() | SEPARATE) == sorted(r["id"] for r in painterly.RULES)


def test_usd_core_loaded_the_plugin_from_the_plugin_path():
    registry = UsdValidation.ValidationRegistry()
    for r in painterly.RULES:
        meta = registry.GetValidatorMetadata(f"{PLUGIN}:{r['validator']}")
        assert meta is not None and meta.plugin is not None, r
        assert list(meta.GetKeywords()) == ["painterly"] and meta.doc == r["doc"]


@pytest.mark.parametrize("rule", sorted(BREAK))
def test_each_rule_fires_on_a_bad_input_and_names_prim_and_attribute(tmp_path, rule):
    path = tmp_path / f"{rule}.usda"
    stage = good_stage(path)
    stage.Save()
    assert validate(path) == []
    where_prim, where_attr = BREAK[rule](stage)
    stage.Save()
    validator = next(r["validator"] for r in painterly.RULES if r["id"] == rule)
    found = by_validator(validate(path))
    assert f"{PLUGIN}:{validator}" in found, {k: [e.GetMessage() for e in v] for k, v in found.items()}
    errors = found[f"{PLUGIN}:{validator}"]
    where = where_prim + (f".{where_attr}" if where_attr else "")
    assert any(e.GetMessage().startswith(f"{where}: ") for e in errors), [e.GetMessage() for e in errors]
    for e in errors:
        assert e.GetType() == UsdValidation.ValidationErrorType.Error
        # Printed as "(painterly.validators:PointCounts.point-counts)": the
        # error's name is the rule id, not the validator's name again.
        assert e.GetName() == rule
        assert e.GetIdentifier() == f"{PLUGIN}:{validator}.{rule}"
    sites = [s for e in errors for s in e.GetSites()]
    assert all(s.IsValid() for s in sites)
    on = [s.GetProperty().GetPrimPath() if s.IsProperty() else s.GetPrim().GetPath() for s in sites]
    assert Sdf.Path(where_prim) in on, on
    if where_attr:  # the site is the property itself whenever the stage has it
        has = bool(stage.GetPrimAtPath(where_prim)) and bool(stage.GetPrimAtPath(where_prim).GetProperty(where_attr))
        assert has == any(s.IsProperty() and s.GetProperty().GetName() == where_attr for s in sites)
    # The same finding as `painterly inspect`, under the same rule.
    report = painterly.inspect(path)
    assert any(p["rule"] == rule and p["prim"] == where_prim and p["attribute"] == where_attr for p in report["problems"])
    # And nothing else fires.
    assert set(found) == {f"{PLUGIN}:{validator}"}, sorted(found)


def test_unsaved_edits_are_validated(tmp_path):
    stage = good_stage(tmp_path / "edit.usda")
    stage.Save()
    assert validate(stage) == []
    _missing_proxy(stage)  # not saved
    assert stage.GetRootLayer().dirty
    found = by_validator(validate(stage))
    assert list(found) == [f"{PLUGIN}:MissingProxy"]
    stage.GetRootLayer().Reload()
    assert validate(stage) == []


def test_chunks(tmp_path):
    src = tmp_path / "shot.usda"
    good_stage(src).Save()
    clips = tmp_path / "bake.usda"
    painterly.bake(src, clips, chunk=4)
    assert validate(clips) == []
    chunk = sorted((tmp_path / "bake.clips").iterdir())[1]
    chunk.unlink()
    found = by_validator(validate(clips))
    assert list(found) == [f"{PLUGIN}:Chunks"]
    assert chunk.name in found[f"{PLUGIN}:Chunks"][0].GetMessage()


def test_chunks_of_a_changed_input(tmp_path):
    """The chunks of a clip set whose input changed since are stale, as in
    `painterly inspect` (both judged them against the hash the clip set
    recorded, not the input's, and found nothing)."""
    src = tmp_path / "shot.usda"
    stage = good_stage(src)
    stage.Save()
    clips = tmp_path / "bake.usda"
    painterly.bake(src, clips, chunk=4)
    assert validate(clips) == []
    prim(stage, "/World/Controls").GetAttribute("knob").Set(0.5, 1)
    stage.Save()
    found = by_validator(validate(clips))
    assert list(found) == [f"{PLUGIN}:Chunks"]
    messages = [e.GetMessage() for e in found[f"{PLUGIN}:Chunks"]]
    assert f"{src} changed since this clip set was assembled" in messages[0]
    assert sum("is stale (baked from a different input)" in m for m in messages) == 3, messages


def test_a_clip_set_validated_again_after_its_input_changed(tmp_path):
    """One Usd.Stage of a clip set, validated, then validated again after its
    input (or a layer the input reads) changed: the second run judges the
    input as it is now, not the first run's remembered answer."""
    shot = tmp_path / "shot.usda"
    stage = good_stage(shot)
    stage.Save()
    top = Sdf.Layer.CreateNew(str(tmp_path / "top.usda"))
    top.subLayerPaths.append(shot.name)
    top.startTimeCode, top.endTimeCode = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    top.Save()
    clips = tmp_path / "bake.usda"
    painterly.bake(tmp_path / "top.usda", clips, chunk=4)
    opened = Usd.Stage.Open(str(clips))
    assert validate(opened) == []
    # A layer under the input, not the input's own file, changes.
    prim(stage, "/World/Controls").GetAttribute("knob").Set(0.5, 1)
    stage.Save()
    found = by_validator(validate(opened))
    assert list(found) == [f"{PLUGIN}:Chunks"], found


def test_unreadable(tmp_path):
    """A stage painterly cannot read is reported, not skipped: here its file
    went away after usd-core opened it (openusd reads every layer usd-core
    reads, so a file is the way to get there)."""
    path = tmp_path / "shot.usda"
    good_stage(path).Save()
    stage = Usd.Stage.Open(str(path))
    assert validate(stage) == []
    os.rename(path, tmp_path / "moved.usda")
    found = by_validator(validate(stage))
    assert list(found) == [f"{PLUGIN}:Unreadable"], found
    assert "shot.usda" in found[f"{PLUGIN}:Unreadable"][0].GetMessage()


def shot_with_a_wip_layer_and_a_payload(tmp_path):
    """shot.usda: /Good references a good character, with wip.usda sublayered
    over it breaking its key coordinates; /Bad is a payload of a character
    without a proxy."""
    good_stage(tmp_path / "good.usda").Save()
    bad = good_stage(tmp_path / "bad.usda")
    _missing_proxy(bad)
    bad.Save()
    wip = Usd.Stage.CreateNew(str(tmp_path / "wip.usda"))
    wip.OverridePrim("/Good/Paint/Hair/high").CreateAttribute("coordinates", T.FloatArray).Set(Vt.FloatArray([1, 2]))
    wip.Save()
    shot = Usd.Stage.CreateNew(str(tmp_path / "shot.usda"))
    Au.set_stage_metadata(shot, 1, 11)
    shot.GetRootLayer().subLayerPaths.append("./wip.usda")
    shot.DefinePrim("/Good").GetReferences().AddReference("./good.usda", "/World")
    shot.DefinePrim("/Bad").GetPayloads().AddPayload("./bad.usda", "/World")
    shot.Save()
    return tmp_path / "shot.usda", wip.GetRootLayer().identifier


def expected_problems(stage):
    """What usd-core composes of the two breakages: (validator, prim) each."""
    out = set()
    coords = stage.GetPrimAtPath("/Good/Paint/Hair/high").GetAttribute("coordinates").Get()
    if len(coords) != 1:  # one axis: one coordinate per key
        out.add((f"{PLUGIN}:KeyCoordinates", "/Good/Paint/Hair/high"))
    rig = stage.GetPrimAtPath("/Bad/Paint")
    if rig and not rig.GetRelationship("painterly:proxy").GetTargets():
        out.add((f"{PLUGIN}:MissingProxy", "/Bad/Paint"))
    return out


def found_problems(stage):
    out = set()
    for e in validate(stage):
        site = e.GetSites()[0]
        prim = site.GetProperty().GetPrimPath() if site.IsProperty() else site.GetPrim().GetPath()
        out.add((e.GetValidator().GetMetadata().name, str(prim)))
    return out


def test_validators_judge_the_stage_as_opened_not_its_file(tmp_path):
    """A muted layer, a population mask and load rules leave content out of
    the stage: the validators judge what the stage composes (before, they
    inspected the file, so muting wip.usda or unloading /Bad changed nothing)."""
    shot, wip = shot_with_a_wip_layer_and_a_payload(tmp_path)
    stage = Usd.Stage.Open(str(shot))
    assert expected_problems(stage) == {(f"{PLUGIN}:KeyCoordinates", "/Good/Paint/Hair/high"), (f"{PLUGIN}:MissingProxy", "/Bad/Paint")}
    assert found_problems(stage) == expected_problems(stage)
    # The same stage, changed in place: what it composes changes each time.
    stage.MuteLayer(wip)
    assert found_problems(stage) == expected_problems(stage) == {(f"{PLUGIN}:MissingProxy", "/Bad/Paint")}
    stage.Unload("/Bad")
    assert found_problems(stage) == expected_problems(stage) == set()
    stage.UnmuteLayer(wip)
    stage.Load("/Bad")
    assert found_problems(stage) == expected_problems(stage) and len(expected_problems(stage)) == 2
    # Opened without payloads, or masked to /Good.
    unloaded = Usd.Stage.Open(str(shot), load=Usd.Stage.LoadNone)
    assert found_problems(unloaded) == expected_problems(unloaded) == {(f"{PLUGIN}:KeyCoordinates", "/Good/Paint/Hair/high")}
    masked = Usd.Stage.OpenMasked(str(shot), Usd.StagePopulationMask(["/Good"]))
    masked.MuteLayer(wip)
    assert found_problems(masked) == expected_problems(masked) == set()


def test_validators_take_the_time_range_they_are_given(tmp_path):
    """An asset without startTimeCode/endTimeCode is unreadable for inspect
    without frames; a validation with a finite time range gives them (before,
    the range was ignored and the validators said "pass --frames A:B")."""
    path = tmp_path / "asset.usda"
    stage = good_stage(path)
    stage.GetRootLayer().ClearStartTimeCode()
    stage.GetRootLayer().ClearEndTimeCode()
    stage.Save()
    stage = Usd.Stage.Open(str(path))
    context = UsdValidation.ValidationContext(keywords=["painterly"])
    cli = json.loads(run_painterly("inspect", path, "--json", check=False).stdout)["problems"]
    assert [p["rule"] for p in cli] == ["unreadable"]
    assert [e.GetName() for e in context.Validate(stage)] == ["unreadable"]
    cli = json.loads(run_painterly("inspect", path, "--json", "--frames", "1:2").stdout)["problems"]
    assert cli == []
    ranged = UsdValidation.ValidationTimeRange(Gf.Interval(1, 2))
    assert [e.GetName() for e in context.Validate(stage, ranged)] == []
    # The inspection is cached per stage state and range: without it, unreadable again.
    assert [e.GetName() for e in context.Validate(stage)] == ["unreadable"]


def test_points_samples_must_match_the_curves_and_be_finite(tmp_path):
    """Bake reads only rest points, but usdview and preview draw a `points`
    time sample: one of another length than the curves is a point-counts
    problem, for the validator and for `painterly inspect` (exit 1); one with
    a NaN is a non-finite problem."""
    path = tmp_path / "sampled.usda"
    stage = good_stage(path)
    points = stage.GetPrimAtPath(LAYER).GetAttribute("points")
    points.Set(Au.v3f(np.ones((4, 3))), 2)
    stage.Save()
    assert validate(path) == []
    points.Set(Au.v3f(np.ones((3, 3))), 6)
    stage.Save()
    found = by_validator(validate(path))
    assert list(found) == [f"{PLUGIN}:PointCounts"], sorted(found)
    message = (f"{LAYER}.points: time samples disagreeing with curveVertexCounts (sum 4): 1 of 2, "
               "the first at time 6 with 3 points")
    assert [e.GetMessage() for e in found[f"{PLUGIN}:PointCounts"]] == [message]
    proc = run_painterly("inspect", path, "--json", check=False)
    assert proc.returncode == 1, proc.stderr
    assert json.loads(proc.stdout)["problems"] == [
        {"prim": LAYER, "attribute": "points", "message": message.split(": ", 1)[1], "rule": "point-counts"}
    ]
    # The right count, but a point that is not a number: non-finite.
    points.Set(Au.v3f([[0, 0, 0], [1, NAN, 0], [2, 0, 0], [3, 0, 0]]), 6)
    stage.Save()
    found = by_validator(validate(path))
    assert list(found) == [f"{PLUGIN}:NonFinite"], sorted(found)
    assert [e.GetMessage() for e in found[f"{PLUGIN}:NonFinite"]] == [
        f"{LAYER}.points: point 1 of the sample at time 6 is not finite ([1, NaN, 0])"
    ]


@pytest.mark.parametrize("fixture", sorted(p.name for p in FIXTURES.glob("*.usda")))
def test_quiet_on_every_fixture(fixture):
    assert validate(FIXTURES / fixture) == []


# ---------------------------------------------------------------------------
# discovery and the command line


def run_python(code, env_extra=None):
    env = {k: v for k, v in os.environ.items() if k != "PXR_PLUGINPATH_NAME"}
    env.update(env_extra or {})
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)


def test_plugin_route_imports_the_validators_lazily(tmp_path):
    path = tmp_path / "bad.usda"
    stage = good_stage(path)
    _missing_proxy(stage)
    stage.Save()
    code = f"""
import sys
from pxr import Usd, UsdValidation
meta = UsdValidation.ValidationRegistry().GetValidatorMetadata("{PLUGIN}:MissingProxy")
assert meta is not None and meta.plugin is not None
assert "painterly.validators" not in sys.modules
errors = UsdValidation.ValidationContext(keywords=["painterly"]).Validate(Usd.Stage.Open({str(path)!r}))
assert "painterly.validators" in sys.modules
print([e.GetValidator().GetMetadata().name for e in errors])
"""
    proc = run_python(code, {"PXR_PLUGINPATH_NAME": PAINTERLY_PLUGIN})
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"['{PLUGIN}:MissingProxy']"


def test_a_late_import_registers_the_validators_explicitly(tmp_path):
    path = tmp_path / "bad.usda"
    stage = good_stage(path)
    _missing_proxy(stage)
    stage.Save()
    code = f"""
from pxr import Usd, UsdValidation
assert UsdValidation.ValidationRegistry().GetValidatorMetadata("{PLUGIN}:MissingProxy") is None
import painterly.validators
errors = UsdValidation.ValidationContext(keywords=["painterly"]).Validate(Usd.Stage.Open({str(path)!r}))
print([e.GetValidator().GetMetadata().name for e in errors])
"""
    proc = run_python(code)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"['{PLUGIN}:MissingProxy']"


def painterly_validate(*args):
    exe = pathlib.Path(sys.executable).parent / "painterly-validate"
    env = {k: v for k, v in os.environ.items() if k != "PXR_PLUGINPATH_NAME"}
    return subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True, env=env, timeout=300)


def test_painterly_validate_exit_codes(tmp_path):
    bad = tmp_path / "bad.usda"
    stage = good_stage(bad)
    _missing_proxy(stage)
    stage.Save()
    proc = painterly_validate(bad)
    assert proc.returncode == 1, proc.stderr
    assert f"{PLUGIN}:MissingProxy" in proc.stdout and "/World/Paint.painterly:proxy: not authored" in proc.stdout
    proc = painterly_validate(FIXTURES / "blowfish.usda", FIXTURES / "head.usda")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.count("no problems found") == 2
    proc = painterly_validate()
    assert proc.returncode == 2
    proc = painterly_validate(tmp_path / "missing.usda")
    assert proc.returncode == 1 and "missing.usda" in proc.stderr
