"""The `painterly` Python package (issue 14): bake, Character, interpolate,
inspect and errors, checked against the CLI and usd-core.

- `Character.evaluate(t)` / `.opacities(t)` equal, to the last bit, the
  points and displayOpacity that `painterly bake` writes for that frame,
  read back with usd-core;
- what-if configurations: overriding an axis to the value the stage gives
  it at another frame reproduces that frame (static proxy);
- `interpolate` equals the weights `painterly interpolate` prints, bit for
  bit, and blends values in key order;
- `bake` returns the `--json` summary; two bakes in two threads run at once
  (the GIL is released): each bake's progress callback waits at a barrier
  for the other, which only passes if both bakes are running together;
- inputs as `Sdf.Layer` (edited in memory, anonymous), errors as
  `painterly.Error` with `.file`, `.prim`, `.attribute`, `.rule`.

The package must be installed (`scripts/test` builds it into .venv); when it
is not, these tests skip unless PAINTERLY_PYTHON_PACKAGE=required.
"""

import json
import os
import shutil
import threading
import time

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, Vt

import authoring as Au
import authoring_keys as AK
from conftest import REPO, run_painterly

if os.environ.get("PAINTERLY_PYTHON_PACKAGE") == "required":
    import painterly
else:
    painterly = pytest.importorskip("painterly")

FIXTURES = REPO / "fixtures"


def baked(path, prim, attr, t):
    """A baked attribute's value at `t`, read with usd-core from the bake layer alone."""
    layer = Sdf.Layer.FindOrOpen(str(path))
    stage = Usd.Stage.Open(layer)
    return np.asarray(stage.GetPrimAtPath(prim).GetAttribute(attr).Get(Usd.TimeCode(t)))


# ---------------------------------------------------------------------------
# evaluate == bake, bit for bit


@pytest.mark.parametrize(
    "fixture,frames,times",
    [
        ("blowfish.usda", "1:48:6", [1.0, 13.0, 37.0, 43.0]),  # skinned, pose keys, time keys and sentinels
        ("apple.usda", "1:48:8", [1.0, 25.0, 41.0]),  # light-position axes
        ("head.usda", "1:48:12", [1.0, 25.0]),  # view-dependent mesh
        ("walk.usda", "1:40:12", [13.0, 37.0]),  # animated view-dependent base
    ],
)
def test_evaluate_equals_the_bake_bit_for_bit(tmp_path, fixture, frames, times):
    src = FIXTURES / fixture
    out = tmp_path / "bake.usdc"
    run_painterly("bake", src, "-o", out, "--frames", frames, "--quiet")
    ch = painterly.Character(str(src))
    assert len(ch.layers) + len(ch.view_meshes) > 0
    for t in times:
        points = ch.evaluate(t)
        assert sorted(points) == sorted(ch.layers + ch.view_meshes)
        for prim, got in points.items():
            assert got.dtype == np.float32 and got.ndim == 2 and got.shape[1] == 3
            expected = baked(out, prim, "points", t)
            assert np.array_equal(got, expected.astype(np.float32)), f"{prim} at {t}"
        opacities = ch.opacities(t)
        assert sorted(opacities) == sorted(ch.layers)
        for prim, got in opacities.items():
            assert got.dtype == np.float32
            assert np.array_equal(got, baked(out, prim, "primvars:displayOpacity", t)), f"{prim} at {t}"


def test_a_bake_from_python_writes_the_cli_bytes_and_its_summary(tmp_path):
    src = FIXTURES / "tube.usda"
    cli = tmp_path / "cli.usda"
    cli_summary = json.loads(run_painterly("bake", src, "-o", cli, "--frames", "1:12", "--json").stdout)
    py = tmp_path / "py.usda"
    summary = painterly.bake(str(src), str(py), frames="1:12")
    assert set(summary) == set(cli_summary)
    for k in summary:
        if k not in ("seconds", "output"):
            assert summary[k] == cli_summary[k], k
    assert summary["output"] == str(py)
    strip = lambda text: "\n".join(l for l in text.splitlines() if "seconds" not in l)  # noqa: E731
    assert strip(py.read_text()) == strip(cli.read_text())
    # frames as a tuple, and a bake in memory whose layer usd-core opens.
    mem = painterly.bake(src, frames=(1, 12))
    assert mem["output"] is None and mem["frames"] == 12
    layer = painterly.to_layer(mem["layer"])
    stage = Usd.Stage.Open(layer)
    ch = painterly.Character(src)
    for prim in ch.layers:
        got = np.asarray(stage.GetPrimAtPath(prim).GetAttribute("points").Get(Usd.TimeCode(7)))
        assert np.array_equal(got, ch.evaluate(7)[prim])


# ---------------------------------------------------------------------------
# what-if configurations


def knob_stage(path=None):
    """A static quad proxy and one stroke keyed to a knob animated 0 → 1
    over frames 1..11 (pose keys at 0 and 1): a static proxy means the
    frame's pose does not matter, only the knob."""
    stage = Usd.Stage.CreateNew(str(path)) if path else Usd.Stage.CreateInMemory()
    Au.set_stage_metadata(stage, 1, 11)
    ctl = stage.DefinePrim("/World/Controls")
    knob = ctl.CreateAttribute("knob", Sdf.ValueTypeNames.Double)
    knob.Set(0.0, 1)
    knob.Set(1.0, 11)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Proxy")
    mesh.CreateFaceVertexCountsAttr([4, 4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 4, 3, 1, 2, 5, 4])
    mesh.CreatePointsAttr(Au.v3f([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [2, 1, 0]]))
    Au.add_painterly_rig(stage, "/World/Paint", "/World/Proxy")
    AK.add_axis(stage, "/World/Paint/knob", "attribute", source="/World/Controls.knob")
    low = np.array([[0.2, 0.2, 0], [0.8, 0.5, 0], [1.5, 0.5, 0], [1.8, 0.8, 0]])
    high = low + np.array([[0, 0.1, 0.3], [0, 0.2, 0.1], [0, -0.1, 0.2], [0, 0.1, -0.2]])
    Au.add_stroke_layer(stage, "/World/Paint/Hair", [4], low)
    AK.add_pose_key(stage, "/World/Paint/Hair", "low", [0], points=low, opacity=1.0)
    AK.add_pose_key(stage, "/World/Paint/Hair", "high", [1], points=high, opacity=0.25)
    return stage, low, high


def test_configuration_overrides_reproduce_the_frame_with_that_value(tmp_path):
    stage, low, high = knob_stage(tmp_path / "knob.usda")
    stage.Save()
    ch = painterly.Character(tmp_path / "knob.usda")
    assert ch.axes == ["/World/Paint/knob"]
    assert ch.configuration(6) == {"/World/Paint/knob": 0.5}
    hair = "/World/Paint/Hair"
    # The stage's own values change nothing.
    assert np.array_equal(ch.evaluate(6, ch.configuration(6))[hair], ch.evaluate(6)[hair])
    # At frame 1 the knob reads 0; set to 1 it shows frame 11, bit for bit,
    # which is the "high" key (smooth Voronoi interpolates its keys).
    what_if = ch.evaluate(1, {"/World/Paint/knob": 1.0})[hair]
    assert np.array_equal(what_if, ch.evaluate(11)[hair])
    assert np.allclose(what_if, high, atol=1e-6)
    assert np.allclose(ch.evaluate(1)[hair], low, atol=1e-6)
    assert np.array_equal(ch.opacities(1, {"/World/Paint/knob": 1.0})[hair], np.float32([0.25]))
    assert np.array_equal(ch.opacities(1)[hair], np.float32([1.0]))
    with pytest.raises(painterly.Error) as e:
        ch.evaluate(1, {"/World/Paint/nope": 1.0})
    assert e.value.prim == "/World/Paint/nope" and "not an axis" in e.value.message


# ---------------------------------------------------------------------------
# Sdf.Layer inputs


def test_layers_are_read_with_their_unsaved_edits(tmp_path):
    stage, low, high = knob_stage()
    anon = stage.GetRootLayer()
    ch = painterly.Character(anon)  # an anonymous layer, never on disk
    assert np.allclose(ch.evaluate(11)["/World/Paint/Hair"], high, atol=1e-6)
    assert painterly.inspect(anon)["problems"] == []

    # A file layer edited in memory: the edit is what painterly sees.
    path = tmp_path / "knob.usda"
    knob_stage(path)[0].Save()
    layer = Sdf.Layer.FindOrOpen(str(path))
    on_disk = painterly.Character(layer).opacities(1)["/World/Paint/Hair"]
    edit = Usd.Stage.Open(layer)
    edit.GetPrimAtPath("/World/Paint/Hair").CreateAttribute("painterly:opacity", Sdf.ValueTypeNames.Float).Set(0.5)
    assert layer.dirty
    assert np.array_equal(painterly.Character(layer).opacities(1)["/World/Paint/Hair"], on_disk * np.float32(0.5))
    # A problem introduced in memory: errors name the layer, the prim and the attribute.
    edit.GetPrimAtPath("/World/Paint/Hair/high").GetAttribute("coordinates").Set(Vt.FloatArray([0.0]))
    problems = painterly.inspect(layer)["problems"]
    assert [(p["prim"], p["attribute"], p["rule"]) for p in problems] == [
        ("/World/Paint/Hair/low", "coordinates", "coincident-keys")
    ]
    with pytest.raises(painterly.Error) as e:
        painterly.Character(layer)
    assert (e.value.file, e.value.prim, e.value.attribute, e.value.rule) == (
        layer.identifier,
        "/World/Paint/Hair/low",
        "coordinates",
        "coincident-keys",
    )


def test_a_bake_of_unsaved_edits_says_so_when_shown(tmp_path):
    """A bake records its input's stamp, which `view`, `render --bake` and
    `preview --bake` check against the file. A layer edited in memory is
    not the file: its bake says so, and the check warns (before, the stamp
    was the untouched file's, and the bake passed for current). A clean
    layer's bake is the file's."""
    src = tmp_path / "tube.usda"
    Sdf.Layer.FindOrOpen(str(FIXTURES / "tube.usda")).Export(str(src))
    layer = Sdf.Layer.FindOrOpen(str(src))
    clean, dirty = tmp_path / "clean.usda", tmp_path / "dirty.usda"
    painterly.bake(layer, clean, frames="1:4")
    edit = Usd.Stage.Open(layer)
    edit.GetPrimAtPath("/Tube").SetMetadata("comment", "edited in memory")
    assert layer.dirty
    painterly.bake(layer, dirty, frames="1:4")

    def view(bake):
        out = run_painterly("view", src, "--bake", bake, "-o", tmp_path / "v.usda", "--json").stdout
        return json.loads(out)["warnings"]

    assert view(clean) == []
    assert view(dirty) == [
        f"{dirty} was baked from unsaved edits of {src} (a layer edited in memory), not from the file: "
        f"strokes may not match it; save the layer and bake again (painterly bake {src} -o {dirty} --frames 1:4:1)"
    ]
    stamp = Sdf.Layer.FindOrOpen(str(dirty)).customLayerData["painterly"]["inputStamp"]
    assert stamp.startswith("unsaved:")
    # Chunks and their binding cache are matched to the file by its content
    # hash: a chunked bake of unsaved edits is refused, and writes nothing.
    before = sorted(os.listdir(tmp_path))
    with pytest.raises(painterly.Error) as e:
        painterly.bake(layer, tmp_path / "clips.usda", frames="1:4", chunk=2)
    assert e.value.message == (
        "a chunked bake needs the input saved: its chunks and binding cache are matched to the file, "
        "and this layer has unsaved edits (save it, or bake without chunks)"
    )
    assert sorted(os.listdir(tmp_path)) == before


def test_a_layer_with_relative_sublayers_resolves_them_where_it_lives(tmp_path):
    knob_stage(tmp_path / "character.usda")[0].Save()
    shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
    shot.subLayerPaths.append("./character.usda")
    shot.Save()
    layer = Sdf.Layer.FindOrOpen(str(tmp_path / "shot.usda"))
    edit = Usd.Stage.Open(layer)
    edit.OverridePrim("/World/Paint/Hair").CreateAttribute("painterly:opacity", Sdf.ValueTypeNames.Float).Set(0.5)
    ch = painterly.Character(layer)
    assert ch.opacities(1)["/World/Paint/Hair"].tolist() == [0.5]


# ---------------------------------------------------------------------------
# interpolate == `painterly interpolate`


def cli_weights(painterly_cli, method, keys, points, radius=None):
    payload = {"method": method, "keys": np.asarray(keys).tolist(), "points": np.asarray(points).tolist()}
    if radius is not None:
        payload["radius"] = radius
    out = painterly_cli("interpolate", input=json.dumps(payload)).stdout
    return np.array(json.loads(out)["weights"])


@pytest.mark.parametrize("method,token,radius", [("smooth_voronoi", "smoothVoronoi", None), ("rbf", "rbf", 0.7), ("shepard", "shepard", None)])
def test_interpolate_matches_the_cli_bit_for_bit(method, token, radius):
    rng = np.random.default_rng(14)
    keys = rng.uniform(-1, 1, (6, 2))
    queries = np.vstack([rng.uniform(-1.2, 1.2, (20, 2)), keys[:2]])
    w = cli_weights(run_painterly, token, keys, queries, radius)
    kw = {"radius": radius} if radius is not None else {}
    # Identity values give the weights themselves.
    assert np.array_equal(painterly.interpolate(keys, np.eye(6), queries, method=method, **kw), w)
    # Any values are blended in key order: sum_i w_i * v_i.
    values = rng.normal(size=(6, 4, 3))
    got = painterly.interpolate(keys, values, queries, method=method, **kw)
    assert got.shape == (len(queries), 4, 3)
    expected = np.zeros((len(queries), 12))
    for q in range(len(queries)):
        for j in range(12):
            s = 0.0
            for i in range(6):
                s += float(w[q, i]) * float(values.reshape(6, 12)[i, j])
            expected[q, j] = s
    assert np.array_equal(got.reshape(len(queries), 12), expected)
    # The USD token the CLI's JSON takes is the same method.
    assert np.array_equal(painterly.interpolate(keys, np.eye(6), queries, method=token, **kw), w)


def test_interpolate_in_one_dimension_and_its_errors():
    keys = [0.0, 0.3, 1.0]
    w = cli_weights(run_painterly, "smoothVoronoi", [[k] for k in keys], [[0.1], [0.65]])
    got = painterly.interpolate(keys, [10.0, 20.0, 40.0], [0.1, 0.65])
    assert got.shape == (2,)
    assert np.array_equal(got, [sum(float(wi) * v for wi, v in zip(row, [10.0, 20.0, 40.0])) for row in w])
    assert np.array_equal(painterly.interpolate(keys, [10.0, 20.0, 40.0], keys), [10.0, 20.0, 40.0])
    with pytest.raises(painterly.Error, match="keys 0 and 1"):
        painterly.interpolate([0.0, 0.0], [1.0, 2.0], [0.5])
    with pytest.raises(painterly.Error, match="unknown method"):
        painterly.interpolate(keys, [1.0, 2.0, 3.0], [0.5], method="linear")
    with pytest.raises(painterly.Error, match="one value per key"):
        painterly.interpolate(keys, [1.0, 2.0], [0.5])
    with pytest.raises(painterly.Error, match="^no keys: interpolation needs at least one key$"):
        painterly.interpolate([], [], [[0.5]])


def test_errors_raised_by_the_python_side_carry_the_documented_attributes():
    """`painterly.Error` raised in Python (not by the native module) had no
    `.message`, `.file`, ...; ragged keys raised numpy's ValueError and bad
    text usd-core's Tf.ErrorException (an error-message review, 2026-12-07)."""
    cases = [
        (lambda: painterly.interpolate([], [], [[0.5]]), "^no keys"),
        (lambda: painterly.interpolate([[0.0, 1.0], [2.0]], [1.0, 2.0], [[0.5, 0.5]]),
         "^keys must be numbers in a rectangular array: "),
        (lambda: painterly.interpolate([0.0, 1.0], [1.0, 2.0], [["a"]]), "^queries must be numbers"),
        (lambda: painterly.to_layer("#usda 1.0\ndef X \"a\" {\n"), "^usd-core could not read the layer text"),
        (lambda: painterly.to_layer(None), "^to_layer takes usda text"),
        (lambda: painterly.interpolate([0.0, 1.0], [1.0, 2.0], [0.5], method="rbf", radius="x"),
         "^radius must be a number"),
    ]
    for call, message in cases:
        with pytest.raises(painterly.Error, match=message) as info:
            call()
        e = info.value
        assert e.message == str(e)
        assert (e.file, e.prim, e.attribute, e.rule) == (None, None, None, None)


# ---------------------------------------------------------------------------
# inspect, errors


def test_inspect_is_the_cli_report():
    for name in ("blowfish.usda", "head.usda"):
        path = FIXTURES / name
        assert painterly.inspect(path) == json.loads(run_painterly("inspect", path, "--json").stdout)


def without_messages(report):
    """An inspect report with its problems' messages left out: Python's
    name options as Python spells them (`frames=(A, B)`, not `--frames A:B`)."""
    return {**report, "problems": [{k: v for k, v in p.items() if k != "message"} for p in report["problems"]]}


def test_inspect_takes_the_frames_of_the_bake(tmp_path):
    """A stage without a time range needs frames for inspect, as for bake;
    the report is the CLI's with the same --frames."""
    src = tmp_path / "tube.usda"
    Sdf.Layer.FindOrOpen(str(FIXTURES / "tube.usda")).Export(str(src))
    layer = Sdf.Layer.FindOrOpen(str(src))
    layer.ClearStartTimeCode()
    layer.ClearEndTimeCode()
    layer.Save()
    without = painterly.inspect(src)
    assert [p["message"] for p in without["problems"]] == [
        "the stage has no startTimeCode/endTimeCode: pass frames=(A, B)"]
    cli = json.loads(run_painterly("inspect", src, "--json", check=False).stdout)
    assert [p["message"] for p in cli["problems"]] == [
        "the stage has no startTimeCode/endTimeCode: pass --frames A:B"]
    assert without_messages(without) == without_messages(cli)
    for frames, cli in [((1, 12), "1:12"), ("1:12:2", "1:12:2"), (5, "5")]:
        report = painterly.inspect(src, frames=frames)
        assert report["problems"] == []
        assert report == json.loads(run_painterly("inspect", src, "--json", "--frames", cli).stdout)


def test_inspect_vouches_for_the_bake_with_its_camera(tmp_path):
    """Without `painterly:camera` the view-dependent mesh needs the bake's
    --camera: inspect reports that unless given the same camera, as the CLI."""
    src = tmp_path / "building.usda"
    layer = Sdf.Layer.FindOrOpen(str(FIXTURES / "building.usda"))
    layer.Export(str(src))
    stage = Usd.Stage.Open(str(src))
    stage.GetPrimAtPath("/Building/Box").GetRelationship("painterly:camera").ClearTargets(True)
    stage.GetRootLayer().Save()
    report = painterly.inspect(src)
    assert [p["prim"] for p in report["problems"]] == ["/Building/Box"], report["problems"]
    assert report["problems"][0]["message"] == "no camera: pass `camera=PRIM` or author `rel painterly:camera`"
    cli = json.loads(run_painterly("inspect", src, "--json", check=False).stdout)
    assert "--camera" in cli["problems"][0]["message"]
    assert without_messages(report) == without_messages(cli)
    with_camera = painterly.inspect(src, camera="/Building/Camera")
    assert with_camera["problems"] == []
    cli = json.loads(run_painterly("inspect", src, "--json", "--camera", "/Building/Camera").stdout)
    assert with_camera == cli


def test_a_file_is_read_as_the_cli_reads_it(tmp_path):
    """The file whose camera samples once failed only the mapped read (see
    test_reliability): inspect's report is the CLI's, and bake writes the
    CLI's points."""
    from clip_compare import compare
    from test_reliability import undecodable_camera_samples

    src, ref = undecodable_camera_samples(tmp_path)
    report = painterly.inspect(src)
    assert report["problems"] == []
    assert report == json.loads(run_painterly("inspect", src, "--json").stdout)
    cli, api = tmp_path / "cli.usdc", tmp_path / "api.usdc"
    run_painterly("bake", src, "-o", cli)
    painterly.bake(src, api)
    assert len(Sdf.Layer.FindOrOpen(str(cli)).ListTimeSamplesForPath("/Building/Box.points")) == 48
    compare(cli, api, ref, range(1, 49), exact=True)


def test_errors_are_painterly_errors_naming_where(tmp_path):
    with pytest.raises(painterly.Error) as e:
        painterly.Character(tmp_path / "missing.usda")
    assert e.value.file == str(tmp_path / "missing.usda") and e.value.prim is None
    stage, _, _ = knob_stage(tmp_path / "bad.usda")
    stage.GetPrimAtPath("/World/Paint").GetRelationship("painterly:proxy").ClearTargets(True)
    stage.Save()
    for call in (lambda: painterly.Character(tmp_path / "bad.usda"), lambda: painterly.bake(tmp_path / "bad.usda")):
        with pytest.raises(painterly.Error) as e:
            call()
        err = e.value
        assert (err.file, err.prim, err.attribute, err.rule) == (
            str(tmp_path / "bad.usda"),
            "/World/Paint",
            "painterly:proxy",
            "missing-proxy",
        )
        assert str(err).startswith(f"{tmp_path / 'bad.usda'}: /World/Paint.painterly:proxy: ")
    with pytest.raises(painterly.Error, match="step"):
        painterly.bake(FIXTURES / "tube.usda", frames="1:12:0")
    with pytest.raises(painterly.Error, match="outside the stage's time range"):
        painterly.bake(FIXTURES / "tube.usda", frames=(0, 1000))
    with pytest.raises(TypeError):
        painterly.Character(42)
    assert not list(tmp_path.glob("*.usdc"))


def test_errors_name_options_as_python_spells_them(tmp_path):
    """The library's messages name the CLI's options; from Python they name
    the keyword arguments instead (the CLI's words are in test_cli_messages)."""
    tube = FIXTURES / "tube.usda"
    no_range = tmp_path / "no_range.usda"
    Sdf.Layer.FindOrOpen(str(tube)).Export(str(no_range))
    layer = Sdf.Layer.FindOrOpen(str(no_range))
    layer.ClearStartTimeCode()
    layer.ClearEndTimeCode()
    layer.Save()
    no_camera = tmp_path / "building.usda"
    Sdf.Layer.FindOrOpen(str(FIXTURES / "building.usda")).Export(str(no_camera))
    stage = Usd.Stage.Open(str(no_camera))
    stage.GetPrimAtPath("/Building/Box").GetRelationship("painterly:camera").ClearTargets(True)
    stage.GetRootLayer().Save()
    cases = [
        (lambda: painterly.bake(tube, frames=(0, 1000)),
         "frames 0:1000 is outside the stage's time range 1:24 (startTimeCode:endTimeCode)"),
        (lambda: painterly.bake(no_range), "the stage has no startTimeCode/endTimeCode: pass frames=(A, B)"),
        (lambda: painterly.Character(FIXTURES / "blowfish.usda", camera="/Blowfish"),
         "`camera` names a Xform prim, not a Camera"),
        (lambda: painterly.bake(FIXTURES / "blowfish.usda", camera="/Blowfish"),
         "`camera` names a Xform prim, not a Camera"),
        (lambda: painterly.Character(no_camera),
         "no camera: pass `camera=PRIM` or author `rel painterly:camera`"),
        (lambda: painterly.bake(tube, output=tmp_path / "shot.usdc", chunk=2),
         "with `chunk` the output is the clip-set layer: name it .usda"),
    ]
    for call, message in cases:
        with pytest.raises(painterly.Error) as e:
            call()
        assert e.value.message == message
        assert str(e.value).endswith(": " + message)
    # inspect's problems too (they said --frames A:B; a review, 2026-12-07).
    report = painterly.inspect(no_range)
    assert [p["message"] for p in report["problems"]] == [
        "the stage has no startTimeCode/endTimeCode: pass frames=(A, B)"]
    # Options checked before any file is read name no file.
    for call, message in [
        (lambda: painterly.bake(tube, output=tmp_path / "shot.usda", chunk=0), "`chunk` must be at least 1"),
        # Negative too, not an OverflowError (a review, 2026-12-07).
        (lambda: painterly.bake(tube, output=tmp_path / "shot.usda", chunk=-1), "`chunk` must be at least 1"),
        (lambda: painterly.bake(tube, chunk=2), "a chunked bake writes files: give an output path"),
    ]:
        with pytest.raises(painterly.Error) as e:
            call()
        assert (e.value.message, str(e.value), e.value.file) == (message, message, None)
    assert not list(tmp_path.glob("shot*"))


def test_errors_survive_pickling_with_their_fields(tmp_path):
    # A ProcessPoolExecutor job that raises sends its exception back by
    # pickle: the class must be importable as painterly.Error, and the
    # fields must come back.
    import pickle

    stage, _, _ = knob_stage(tmp_path / "bad.usda")
    stage.GetPrimAtPath("/World/Paint").GetRelationship("painterly:proxy").ClearTargets(True)
    stage.Save()
    with pytest.raises(painterly.Error) as e:
        painterly.Character(tmp_path / "bad.usda")
    assert painterly.Error.__module__ == "painterly"
    back = pickle.loads(pickle.dumps(e.value))
    assert type(back) is painterly.Error
    assert str(back) == str(e.value)
    fields = ("message", "file", "prim", "attribute", "rule")
    assert [getattr(back, f) for f in fields] == [getattr(e.value, f) for f in fields]
    assert back.rule == "missing-proxy"


def test_times_and_frames_are_checked_before_use():
    fish = painterly.Character(FIXTURES / "blowfish.usda")
    for t in [float("nan"), float("inf"), float("-inf")]:
        for call in (fish.evaluate, fish.opacities, fish.configuration):
            with pytest.raises(painterly.Error, match=r"^time (NaN|inf|-inf) is not a finite number$"):
                call(t)
    # A list is (start, end[, step]) like a tuple, never a list of frames.
    assert painterly.bake(FIXTURES / "tube.usda", frames=[1, 3])["frames"] == 3
    assert painterly.bake(FIXTURES / "tube.usda", frames=[1, 5, 2])["frames"] == 3
    # A bad range is named as it was written, in Python.
    for frames, written in [((5, 1), "(5, 1)"), ("5:1", "'5:1'"), ([5, 1], "[5, 1]")]:
        with pytest.raises(painterly.Error) as e:
            painterly.bake(FIXTURES / "tube.usda", frames=frames)
        assert str(e.value) == f"frames={written}: end 1 is before start 5"
    for frames in ([1], [1, 2, 3, 4]):
        with pytest.raises(painterly.Error, match=rf"^frames: a sequence is \(start, end\) or \(start, end, step\), not {len(frames)} numbers"):
            painterly.bake(FIXTURES / "tube.usda", frames=frames)


# ---------------------------------------------------------------------------
# progress and the GIL


def test_progress_reports_every_frame_and_its_exceptions_surface(tmp_path):
    calls = []
    painterly.bake(FIXTURES / "tube.usda", tmp_path / "a.usdc", frames="1:10", progress=lambda d, n: calls.append((d, n)))
    assert calls == [(i, 10) for i in range(1, 11)]

    def boom(done, total):
        raise RuntimeError(f"stop at {done}")

    with pytest.raises(RuntimeError, match="stop at 1"):
        painterly.bake(FIXTURES / "tube.usda", tmp_path / "b.usdc", frames="1:4", progress=boom)


def test_a_bake_in_memory_uses_a_temporary_folder_and_removes_it(tmp_path, monkeypatch):
    """Without an output the bake is written under TMPDIR, in a folder of
    its own while it runs, and nothing is left after it, failed or not."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    monkeypatch.setenv("TMPDIR", str(tmp))
    seen = []
    painterly.bake(FIXTURES / "tube.usda", frames="1:3", progress=lambda d, n: seen.append(sorted(p.name for p in tmp.iterdir())))
    assert len(seen) == 3 and all(len(names) == 1 and names == seen[0] for names in seen), seen
    assert seen[0][0].startswith("painterly-render-")
    assert list(tmp.iterdir()) == []
    with pytest.raises(painterly.Error, match="outside the stage's time range"):
        painterly.bake(FIXTURES / "tube.usda", frames=(0, 1000))
    assert list(tmp.iterdir()) == []


def test_two_bakes_in_threads_run_at_once(tmp_path):
    """Each bake's first progress call waits at a two-party barrier: it only
    passes when the other bake is running too, which needs the GIL released
    while baking. The [first, last] progress intervals then overlap."""
    barrier = threading.Barrier(2, timeout=120)
    spans = {}
    errors = []

    def run(name):
        def progress(done, total):
            now = time.monotonic()
            if done == 1:
                barrier.wait()
                spans[name] = [now, now]
            spans[name][1] = now

        try:
            painterly.bake(FIXTURES / "blowfish.usda", tmp_path / f"{name}.usdc", frames="1:8", progress=progress)
        except BaseException as e:  # noqa: BLE001  (reported below)
            errors.append(e)

    threads = [threading.Thread(target=run, args=(n,)) for n in ("a", "b")]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    (a0, a1), (b0, b1) = spans["a"], spans["b"]
    assert max(a0, b0) <= min(a1, b1), spans
    assert (tmp_path / "a.usdc").exists() and (tmp_path / "b.usdc").exists()


def test_the_readme_example_runs():
    """The README's "From Python" example, as written, from the repository root."""
    import re
    import subprocess
    import sys

    section = (REPO / "README.md").read_text().split("## From Python", 1)[1].split("\n## ", 1)[0]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    env = {k: v for k, v in os.environ.items() if k != "PXR_PLUGINPATH_NAME"}
    proc = subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "24 frames, 17940 points" in proc.stdout


def test_a_progress_that_cannot_be_called_is_refused_before_the_bake(tmp_path):
    """`progress=5` baked the whole output, then raised TypeError when the
    first report came (a Python API review, 2026-12-06)."""
    out = tmp_path / "bake.usdc"
    with pytest.raises(TypeError, match="progress must be callable"):
        painterly.bake(FIXTURES / "blowfish.usda", out, frames="1:2", progress=5)
    assert not out.exists()


def test_a_character_names_its_file_in_evaluation_errors():
    """Errors from an override or an evaluation had `.file = None`, though
    the character knows its file."""
    fish = FIXTURES / "blowfish.usda"
    ch = painterly.Character(str(fish))
    with pytest.raises(painterly.Error) as e:
        ch.evaluate(1, configuration={"/Nope": 1.0})
    assert e.value.file == str(fish)


# ---------------------------------------------------------------------------
# adversarial arguments (a review of the package, 2026-12-07)


def test_two_bakes_of_one_output_in_one_process_each_publish_a_whole_file(tmp_path):
    """Both bakes used `.<name>.painterly-<host>-<pid>.tmp`: the second
    truncated the first's temporary, the inner call returned having
    published nothing of its own and the outer raised ENOENT. Now each
    write has its own temporary and the last rename wins, whole."""
    fish = FIXTURES / "blowfish.usda"
    outer_alone, inner_alone, out = tmp_path / "outer.usdc", tmp_path / "inner.usdc", tmp_path / "shot.usdc"
    painterly.bake(fish, outer_alone, frames="1:4")
    painterly.bake(fish, inner_alone, frames="10:11")
    inner = []

    def progress(done, total):
        if done == 1:  # a hook that bakes a preview of the same shot
            inner.append(painterly.bake(fish, out, frames="10:11"))
            inner.append(out.read_bytes())

    summary = painterly.bake(fish, out, frames="1:4", progress=progress)
    assert inner[0]["frames"] == 2 and summary["frames"] == 4
    assert inner[1] == inner_alone.read_bytes()
    assert out.read_bytes() == outer_alone.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["inner.usdc", "outer.usdc", "shot.usdc"]


def test_frames_given_as_bytes_are_refused():
    """b"12" extracted as the sequence (49, 50): frames 49:50 baked."""
    for frames in (b"12", bytearray(b"1:4")):
        with pytest.raises(TypeError, match=r"not bytes \(decode them first\)$"):
            painterly.bake(FIXTURES / "tube.usda", frames=frames)


def test_interpolate_refuses_what_a_float_conversion_would_drop():
    """Complex values lost their imaginary part (numpy only warned) and a
    masked array's hidden values were interpolated."""
    keys = [[0.0], [1.0]]
    with pytest.raises(painterly.Error, match=r"^values must be real numbers, not complex$"):
        painterly.interpolate(keys, np.array([1 + 5j, 2]), [[0.5]])
    with pytest.raises(painterly.Error, match=r"^queries must be real numbers, not complex$"):
        painterly.interpolate(keys, [1.0, 2.0], [[0.5 + 1j]])
    masked = np.ma.masked_array([1.0, 999.0], mask=[False, True])
    with pytest.raises(painterly.Error, match=r"^values is a masked array"):
        painterly.interpolate(keys, masked, [[0.5]])
    # The real values still interpolate: Shepard at 0.25 weighs 0.9 and 0.1.
    got = painterly.interpolate(keys, [1.0, 2.0], [[0.25]], method="shepard")
    assert np.allclose(got, [1.1], rtol=1e-15, atol=0)


def test_interpolate_that_cannot_allocate_its_answer_is_a_memory_error():
    """10⁶ queries × 10⁶ values per key is 8 TB: it aborted the interpreter
    ("memory allocation failed", SIGABRT); numpy raises MemoryError."""
    keys = np.zeros((1, 1))
    values = np.broadcast_to(np.zeros(1), (1, 1_000_000))
    queries = np.broadcast_to(np.zeros(1), (1_000_000, 1))
    with pytest.raises(MemoryError, match=r"cannot allocate the answer: 1000000 queries × 1000000 values per key"):
        painterly.interpolate(keys, values, queries)


def test_a_bake_to_a_name_that_is_not_utf8_is_refused_before_writing(tmp_path):
    """The summary names the output as a str: the bake was written, then
    "cannot encode the result" raised without the file."""
    out = os.fsdecode(os.path.join(os.fsencode(tmp_path), b"\xff.usda"))
    with pytest.raises(painterly.Error) as e:
        painterly.bake(FIXTURES / "tube.usda", out, frames="1:2")
    assert e.value.message == "the output's name is not UTF-8, and the summary names it as text: rename it"
    assert e.value.file == f"{tmp_path}/\ufffd.usda"  # as text, the byte shown as U+FFFD
    assert os.listdir(tmp_path) == []


def test_an_input_saved_during_a_bake_fails_it_naming_the_file(tmp_path):
    """A save of the input while a bake ran left a bake holding the old
    data with the new file's stamp (render, view and the farm's assembly
    then vouched for it). The bake now fails before replacing its output,
    naming the file; the CLI and chunked bakes share the check (an I/O
    review, 2026-12-07)."""
    fish = tmp_path / "fish.usda"
    shutil.copy(FIXTURES / "blowfish.usda", fish)
    out = tmp_path / "bake.usdc"
    out.write_bytes(b"previous")

    def progress(done, total):
        if done == 2:
            stage = Usd.Stage.Open(str(fish))
            stage.GetRootLayer().customLayerData = {"note": "saved mid-bake"}
            stage.GetRootLayer().Save()

    with pytest.raises(painterly.Error) as e:
        painterly.bake(fish, out, frames="1:6", progress=progress)
    assert e.value.file == str(fish)
    assert e.value.message.startswith("changed while painterly read it (saved during this run?)")
    assert out.read_bytes() == b"previous"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bake.usdc", "fish.usda"]
    # Unchanged since: the same bake goes through.
    assert painterly.bake(fish, out, frames="1:6")["frames"] == 6


def _in_child(what, path):
    """Runs in a forked child: one painterly call, its result in plain data."""
    if what == "bake":
        return painterly.bake(path)["points"]
    if what == "inspect":
        return len(painterly.inspect(path)["problems"])
    c = painterly.Character(path)
    return {k: v.tolist() for k, v in c.evaluate(12).items()}


def test_a_child_forked_after_painterly_calls_works(tmp_path):
    """multiprocessing's default start method on Linux forks. A child forked
    after any painterly call in the parent waited forever on the parent's
    thread pool, which the child does not have (a review, 2026-12-07); it
    now gets its own pool, and the same answers."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    tube = str(FIXTURES / "tube.usda")
    here = {w: _in_child(w, tube) for w in ("bake", "inspect", "evaluate")}
    ex = ProcessPoolExecutor(2, mp_context=multiprocessing.get_context("fork"))
    try:
        futures = {w: ex.submit(_in_child, w, tube) for w in here}
        there = {w: f.result(timeout=120) for w, f in futures.items()}
    finally:
        # A hung child would keep the executor's shutdown waiting: kill it.
        for proc in list(ex._processes.values()):
            proc.kill()
        ex.shutdown(wait=False, cancel_futures=True)
    assert there == here
    assert here["bake"] > 0 and here["inspect"] == 0


def test_interpreter_exit_during_a_bake_in_a_daemon_thread(tmp_path):
    """A bake with a progress callback still running in a daemon thread when
    the script ends: the process aborted at exit (SIGABRT, 4 and 10 times in
    12; a review, 2026-12-07). An atexit hook now cancels it and waits for
    it to leave its call: exit 0, and no output and no temporary left."""
    import subprocess
    import sys

    out = tmp_path / "out"
    out.mkdir()
    script = (
        "import threading, time, painterly\n"
        "def cb(d, t): time.sleep(0.02)\n"
        f"def run(): painterly.bake({str(FIXTURES / 'blowfish.usda')!r}, {str(out / 'o.usdc')!r}, progress=cb)\n"
        "threading.Thread(target=run, daemon=True).start()\n"
        "time.sleep(0.3)\n"
    )
    for _ in range(8):
        p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
        assert p.returncode == 0, p.stderr[-2000:]
        assert list(out.iterdir()) == []


def test_a_write_onto_another_threads_input_names_that_cause(tmp_path):
    """Thread A bakes a shot that sublayers tube_bake.usdc; thread B bakes
    the tube to tube_bake.usdc meanwhile. B is refused (inputs are never
    modified), and the message said B's input read the file through a link,
    which it did not (a review, 2026-12-07): it now names the other cause."""
    tube = tmp_path / "tube.usda"
    shutil.copy(FIXTURES / "tube.usda", tube)
    painterly.bake(tube, tmp_path / "tube_bake.usdc", frames=(1, 2))
    shot = tmp_path / "shot.usda"
    shot.write_text('#usda 1.0\n(\n    subLayers = [@./tube_bake.usdc@, @./tube.usda@]\n)\n')
    started, release = threading.Event(), threading.Event()

    def hold(done, total):
        started.set()
        release.wait(60)

    a = threading.Thread(target=lambda: painterly.bake(shot, tmp_path / "shot_bake.usdc", frames=(1, 2), progress=hold))
    a.start()
    try:
        assert started.wait(60)
        before = (tmp_path / "tube_bake.usdc").read_bytes()
        with pytest.raises(painterly.Error) as e:
            painterly.bake(tube, tmp_path / "tube_bake.usdc")
        assert e.value.message == (
            f"would overwrite {(tmp_path / 'tube_bake.usdc').resolve()}, a file the input reads (through a link of "
            "that name?), or the input of other painterly work running in this process (another Python thread's); "
            "inputs are never modified: remove the link or write elsewhere")
        assert (tmp_path / "tube_bake.usdc").read_bytes() == before
    finally:
        release.set()
        a.join()
    assert (tmp_path / "shot_bake.usdc").is_file()


def test_a_child_forked_while_a_bake_runs_exits_at_once(tmp_path):
    """A child forked while a bake runs in another thread of the parent
    inherited the list of running bakes, and its exit waited the whole 30 s
    for a bake that runs only in the parent (a review, 2026-12-07)."""
    import subprocess
    import sys

    script = (
        "import os, sys, threading, time, painterly\n"
        "started = threading.Event()\n"
        "def cb(d, t): started.set(); time.sleep(0.3)\n"
        f"threading.Thread(target=lambda: painterly.bake({str(FIXTURES / 'tube.usda')!r}, progress=cb), daemon=True).start()\n"
        "started.wait(30)\n"
        "pid = os.fork()\n"
        "if pid == 0:\n"
        "    sys.exit(0)\n"
        "t = time.monotonic(); os.waitpid(pid, 0); print(time.monotonic() - t)\n"
    )
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr[-2000:]
    assert float(p.stdout) < 10, p.stdout
