"""Every `--json` output against its documented JSON Schema (docs/schemas/).

The schemas list every field as required with `additionalProperties: false`,
so a renamed, missing or extra field fails here. Values are then checked
against what usd-core (or the file system) says independently: the number
of prims with PainterlyRigAPI, the stroke and point counts read from the
BasisCurves, the frames of the range, the files written.
"""

import json
import math
import pathlib

import jsonschema
import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from conftest import REPO

SCHEMAS = REPO / "docs" / "schemas"
FIXTURES = REPO / "fixtures"


def schema(name):
    s = json.loads((SCHEMAS / f"{name}.schema.json").read_text())
    jsonschema.Draft202012Validator.check_schema(s)
    return s


def validate(name, doc):
    jsonschema.Draft202012Validator(schema(name)).validate(doc)
    return doc


def applied(stage, api):
    return [p for p in stage.Traverse() if api in p.GetAppliedSchemas()]


def usd_counts(path):
    """What usd-core counts in a painted file: rigs, view meshes, layers, strokes, points."""
    stage = Usd.Stage.Open(str(path))
    layers = applied(stage, "PainterlyStrokeLayerAPI")
    curves = [UsdGeom.BasisCurves(p) for p in layers]
    return {
        "rigs": len(applied(stage, "PainterlyRigAPI")),
        "view_meshes": len(applied(stage, "PainterlyViewDependentAPI")),
        "layers": len(layers),
        "strokes": sum(len(c.GetCurveVertexCountsAttr().Get()) for c in curves),
        "points": sum(len(c.GetPointsAttr().Get()) for c in curves),
        "stage": stage,
    }


def test_every_schema_is_strict():
    """Every object in every schema requires all its properties and allows no others."""
    names = sorted(p.name for p in SCHEMAS.glob("*.schema.json"))
    assert names == [
        f"{n}.schema.json" for n in ["author", "bake", "farm_status", "farm_submit", "inspect", "interpolate", "render", "view"]
    ]

    def walk(node, where):
        if isinstance(node, dict):
            if node.get("type") == "object" or "properties" in node:
                assert node.get("additionalProperties") is False, where
                assert sorted(node["required"]) == sorted(node["properties"]), where
                for k, v in node["properties"].items():
                    assert v.get("description") or v.get("anyOf"), f"{where}.{k} has no description"
            for k, v in node.items():
                walk(v, f"{where}/{k}")
        elif isinstance(node, list):
            for i, v in enumerate(node):
                walk(v, f"{where}[{i}]")

    for n in names:
        walk(schema(n.split(".")[0]), n)


def test_schema_rejects_renamed_missing_and_extra_fields():
    good = {
        "input": "a.usda", "output": "b.usdc", "frames": 1, "rigs": 1, "view_meshes": 0,
        "layers": 1, "strokes": 1, "points": 2, "seconds": 0.1, "chunks": [],
    }
    validate("bake", good)
    renamed = dict(good)
    renamed["rig"] = renamed.pop("rigs")
    missing = {k: v for k, v in good.items() if k != "points"}
    extra = dict(good, total=3)
    wrong_type = dict(good, frames="1")
    for bad in (renamed, missing, extra, wrong_type):
        with pytest.raises(jsonschema.ValidationError):
            validate("bake", bad)


@pytest.mark.parametrize(
    "fixture,frames,count",
    [("tube.usda", "1:24:0.5", 47), ("fig4.usda", None, 1), ("head.usda", "1:12", 12), ("building.usda", "5:9:2", 3)],
)
def test_bake_json(painterly, tmp_path, fixture, frames, count):
    out = tmp_path / "bake.usda"
    args = ["bake", FIXTURES / fixture, "-o", out, "--json"] + (["--frames", frames] if frames else [])
    proc = painterly(*args)
    assert proc.stderr == ""
    assert proc.stdout.count("\n") == 1
    doc = validate("bake", json.loads(proc.stdout))
    ref = usd_counts(FIXTURES / fixture)
    assert doc["input"] == str(FIXTURES / fixture)
    assert doc["output"] == str(out)
    assert doc["frames"] == count
    for k in ["rigs", "view_meshes", "layers", "strokes", "points"]:
        assert doc[k] == ref[k], k
    assert doc["chunks"] == []
    assert 0 <= doc["seconds"] < 600
    # Every baked prim has one points sample per frame reported.
    layer = Sdf.Layer.FindOrOpen(str(out))
    stage = ref["stage"]
    baked = applied(stage, "PainterlyStrokeLayerAPI") + applied(stage, "PainterlyViewDependentAPI")
    assert baked
    for prim in baked:
        assert len(layer.ListTimeSamplesForPath(prim.GetPath().AppendProperty("points"))) == count


def test_bake_json_chunks_are_the_files_written(painterly, tmp_path):
    out = tmp_path / "shot.usda"
    doc = validate("bake", json.loads(painterly("bake", FIXTURES / "tube.usda", "-o", out, "--chunk", 10, "--json").stdout))
    written = sorted(p.name for p in (tmp_path / "shot.clips").glob("*.usdc"))
    # The binding cache sits beside the chunks; it is not a chunk.
    assert written == ["shot.0000.1-10.usdc", "shot.0001.11-20.usdc", "shot.0002.21-24.usdc", "shot.binding.usdc"]
    written.remove("shot.binding.usdc")
    assert sorted(pathlib.Path(c).name for c in doc["chunks"]) == written
    assert all((tmp_path / c).exists() or pathlib.Path(c).exists() for c in doc["chunks"])
    assert doc["frames"] == 24


def test_inspect_json_matches_usd_core(painterly):
    for fixture in ["blowfish.usda", "fig4.usda", "head.usda", "building.usda", "wave.usda"]:
        proc = painterly("inspect", FIXTURES / fixture, "--json")
        doc = validate("inspect", json.loads(proc.stdout))
        ref = usd_counts(FIXTURES / fixture)
        stage = ref["stage"]
        assert doc["file"] == str(FIXTURES / fixture)
        assert doc["start_time_code"] == stage.GetStartTimeCode()
        assert doc["end_time_code"] == stage.GetEndTimeCode()
        assert doc["time_codes_per_second"] == stage.GetTimeCodesPerSecond()
        assert doc["up_axis"] == UsdGeom.GetStageUpAxis(stage)
        rigs = applied(stage, "PainterlyRigAPI")
        assert sorted(r["path"] for r in doc["rigs"]) == sorted(str(p.GetPath()) for p in rigs)
        for r in doc["rigs"]:
            prim = stage.GetPrimAtPath(r["path"])
            proxy = prim.GetRelationship("painterly:proxy").GetTargets()
            assert [r["proxy"]] == [str(t) for t in proxy]
            mesh = UsdGeom.Mesh(stage.GetPrimAtPath(proxy[0]))
            assert r["proxy_points"] == len(mesh.GetPointsAttr().Get())
            assert r["proxy_faces"] == len(mesh.GetFaceVertexCountsAttr().Get())
            layers = [p for p in Usd.PrimRange(prim) if "PainterlyStrokeLayerAPI" in p.GetAppliedSchemas()]
            assert sorted(x["path"] for x in r["layers"]) == sorted(str(p.GetPath()) for p in layers)
            for x in r["layers"]:
                layer = stage.GetPrimAtPath(x["path"])
                curves = UsdGeom.BasisCurves(layer)
                assert x["strokes"] == len(curves.GetCurveVertexCountsAttr().Get())
                assert x["points"] == len(curves.GetPointsAttr().Get())
                kids = list(layer.GetChildren())
                pose = [k for k in kids if k.GetTypeName() == "PainterlyPoseKey"]
                time = [k for k in kids if k.GetTypeName() == "PainterlyTimeKey"]
                assert x["pose_position_keys"] == sum(k.GetAttribute("points").HasAuthoredValue() for k in pose)
                assert x["pose_opacity_keys"] == sum(k.GetAttribute("opacity").HasAuthoredValue() for k in pose)
                sentinels = sum(bool(k.GetAttribute("sentinel").Get()) for k in time)
                assert x["sentinels"] == sentinels
                assert x["time_keys"] == len(time) - sentinels
                op = layer.GetAttribute("painterly:opacity")
                if op and op.GetNumTimeSamples() > 0:
                    assert x["opacity"] is None  # animated: read per frame
                else:
                    want = op.Get() if op and op.HasAuthoredValue() else 1.0
                    assert x["opacity"] == pytest.approx(want, abs=1e-6)
        axes = [p for p in stage.Traverse() if p.GetTypeName() == "PainterlyAxis"]
        assert sorted((a["path"], a["kind"]) for a in doc["axes"]) == sorted(
            (str(p.GetPath()), p.GetAttribute("kind").Get()) for p in axes
        )
        vms = applied(stage, "PainterlyViewDependentAPI")
        assert sorted(v["path"] for v in doc["view_dependent_meshes"]) == sorted(str(p.GetPath()) for p in vms)
        for v in doc["view_dependent_meshes"]:
            keys = [k for k in stage.GetPrimAtPath(v["path"]).GetChildren() if k.GetTypeName() == "PainterlyViewKey"]
            assert sorted(k for vp in v["key_viewpoints"] for k in vp["keys"]) == sorted(str(k.GetPath()) for k in keys)
            for vp in v["key_viewpoints"]:
                assert math.fsum(c * c for c in vp["direction"]) == pytest.approx(1.0, abs=1e-9)
                # The schema: the authored direction, mesh-local (SPEC section 6), normalised;
                # not turned by the mesh's transform (head.usda's face is rotated 15 degrees).
                authored = np.array(stage.GetPrimAtPath(vp["keys"][0]).GetAttribute("direction").Get(), float)
                assert np.allclose(vp["direction"], authored / np.linalg.norm(authored), atol=1e-6), vp
        assert doc["clip_set"] is None
        assert doc["unresolved_assets"] == []
        assert doc["problems"] == []
        assert proc.returncode == 0


def test_inspect_json_problems_and_clip_set(painterly, tmp_path):
    broken = tmp_path / "broken.usda"
    text = (FIXTURES / "tube.usda").read_text()
    # Point the rig's proxy at nothing: the missing-proxy rule.
    stage = Usd.Stage.Open(str(FIXTURES / "tube.usda"))
    rig = applied(stage, "PainterlyRigAPI")[0]
    proxy = str(rig.GetRelationship("painterly:proxy").GetTargets()[0])
    broken.write_text(text.replace(f"<{proxy}>", "</Nowhere>"))
    proc = painterly("inspect", broken, "--json", check=False)
    assert proc.returncode == 1
    doc = validate("inspect", json.loads(proc.stdout))
    assert [(p["rule"], p["prim"], p["attribute"]) for p in doc["problems"]] == [
        ("missing-proxy", str(rig.GetPath()), "painterly:proxy")
    ]

    out = tmp_path / "shot.usda"
    painterly("bake", FIXTURES / "tube.usda", "-o", out, "--chunk", 12, "-q")
    # Every chunk on disk: a done chunk is no problem.
    proc = painterly("inspect", out, "--json", check=False)
    doc = validate("inspect", json.loads(proc.stdout))
    assert [c["state"] for c in doc["clip_set"]["chunks"]] == ["done", "done"]
    assert (doc["problems"], proc.returncode) == ([], 0)
    missing = tmp_path / "shot.clips" / "shot.0001.13-24.usdc"
    missing.unlink()
    proc = painterly("inspect", out, "--json", check=False)
    doc = validate("inspect", json.loads(proc.stdout))
    assert doc["clip_set"]["chunk_size"] == 12
    assert [(pathlib.Path(c["path"]).name, c["state"]) for c in doc["clip_set"]["chunks"]] == [
        ("shot.0000.1-12.usdc", "done"),
        ("shot.0001.13-24.usdc", "missing"),
    ]
    assert [(p["rule"], p["message"]) for p in doc["problems"]] == [("chunks", f"chunk {missing} is missing")]
    assert proc.returncode == 1


def test_render_json(painterly, tmp_path):
    out = tmp_path / "fr" / "apple.####.exr"
    out.parent.mkdir()
    proc = painterly(
        "render", FIXTURES / "apple.usda", "--camera", "/Apple/Camera", "--frames", "1:9:4", "-o", out,
        "--size", "64x40", "--png", "--sheet", "--json",
    )
    doc = validate("render", json.loads(proc.stdout))
    ref = usd_counts(FIXTURES / "apple.usda")
    assert doc["input"] == str(FIXTURES / "apple.usda")
    assert doc["output"] == str(out)
    assert (doc["frames"], doc["width"], doc["height"]) == (3, 64, 40)
    assert sorted(p.name for p in out.parent.glob("*.exr")) == ["apple.0001.exr", "apple.0005.exr", "apple.0009.exr"]
    assert pathlib.Path(doc["sheet"]).exists() and doc["sheet"].endswith(".png")
    # The apple's only curves are its stroke layers; its meshes are guides.
    assert doc["curves"] == ref["layers"]
    assert doc["strokes"] == ref["strokes"]
    assert (doc["meshes"], doc["triangles"]) == (0, 0)
    assert doc["empty_frames"] == [] and doc["warnings"] == []
    assert 0 < doc["median_frame_seconds"] <= doc["seconds"]
    no_sheet = validate("render", json.loads(painterly(
        "render", FIXTURES / "apple.usda", "--camera", "/Apple/Camera", "--frames", "1", "-o", tmp_path / "x.####.exr",
        "--size", "16x16", "--json").stdout))
    assert no_sheet["sheet"] is None


def test_view_json(painterly, tmp_path):
    bake = tmp_path / "b.usdc"
    painterly("bake", FIXTURES / "tube.usda", "-o", bake, "--frames", "3:9", "-q")
    out = tmp_path / "v.usda"
    doc = validate("view", json.loads(painterly("view", FIXTURES / "tube.usda", "--bake", bake, "-o", out, "--json").stdout))
    written = Usd.Stage.Open(str(out))
    assert (doc["input"], doc["bake"], doc["output"]) == (str(FIXTURES / "tube.usda"), str(bake), str(out))
    assert (doc["start_time_code"], doc["end_time_code"]) == (3.0, 9.0)
    assert (written.GetStartTimeCode(), written.GetEndTimeCode()) == (3.0, 9.0)
    assert doc["default_prim"] == Usd.Stage.Open(str(FIXTURES / "tube.usda")).GetDefaultPrim().GetName()
    assert doc["default_prim"] == written.GetDefaultPrim().GetName()
    assert doc["warnings"] == []


def test_farm_submit_and_status_json(painterly, tmp_path):
    out = tmp_path / "shot.usda"
    proc = painterly("farm", "submit", FIXTURES / "tube.usda", "-o", out, "--chunk", 10, "--scheduler", "openjd", "--json")
    sub = validate("farm_submit", json.loads(proc.stdout))
    assert sub["scheduler"] == "openjd"
    assert (sub["input"], sub["output"]) == (str(FIXTURES / "tube.usda"), str(out))
    assert pathlib.Path(sub["plan"]) == tmp_path / "shot.clips" / "farm" / "plan.json"
    assert pathlib.Path(sub["plan"]).exists()
    assert (sub["chunk_size"], sub["chunks"]) == (10, math.ceil(24 / 10))
    assert (sub["submitted"], sub["skipped"], sub["job"]) == ([0, 1, 2], [], None)
    assert sub["tasks"] == [{"chunk": k, "task": f"BakeChunks[Chunk={k}]"} for k in range(3)]
    assert sub["assemble_job"] == "Assemble"
    assert all(pathlib.Path(f).is_file() for f in sub["files"]) and len(sub["files"]) == 2
    assert sub["next"].startswith("openjd run ")

    proc = painterly("farm", "status", out, "--json", check=False)
    assert proc.returncode == 1
    st = validate("farm_status", json.loads(proc.stdout))
    assert (st["scheduler"], st["scheduler_queried"], st["input_changed"]) == ("openjd", False, False)
    assert [c["state"] for c in st["chunks"]] == ["missing"] * 3
    assert [c["frames"] for c in st["chunks"]] == ["1:10:1", "11:20:1", "21:24:1"]
    assert st["counts"] == {"done": 0, "running": 0, "pending": 0, "failed": 0, "missing": 3, "stale": 0}
    assert (st["assembly"]["state"], st["assembled"], st["complete"]) == ("missing", False, False)

    # Run the tasks as the template would: every chunk, then the assembly.
    for k in range(3):
        painterly("bake", FIXTURES / "tube.usda", "-o", out, "--chunk", 10, "--chunk-index", k, "-q")
    painterly("bake", FIXTURES / "tube.usda", "-o", out, "--chunk", 10, "--assemble", "-q")
    proc = painterly("farm", "status", out, "--json")
    st = validate("farm_status", json.loads(proc.stdout))
    assert [c["state"] for c in st["chunks"]] == ["done"] * 3
    assert all(pathlib.Path(c["path"]).exists() for c in st["chunks"])
    assert st["counts"]["done"] == 3
    assert (st["assembly"]["state"], st["assembled"], st["complete"]) == ("done", True, True)

    # Re-submitting skips what is done.
    sub = validate("farm_submit", json.loads(painterly(
        "farm", "submit", FIXTURES / "tube.usda", "-o", out, "--chunk", 10, "--scheduler", "openjd", "--json").stdout))
    assert (sub["submitted"], sub["skipped"], sub["tasks"]) == ([], [0, 1, 2], [])


def test_interpolate_json(painterly):
    req = {"method": "smoothVoronoi", "keys": [[0.0], [1.0], [3.0]], "points": [[0.0], [0.5], [2.0], [3.0]]}
    doc = validate("interpolate", json.loads(painterly("interpolate", input=json.dumps(req)).stdout))
    assert len(doc["weights"]) == 4 and all(len(w) == 3 for w in doc["weights"])
    for w in doc["weights"]:
        assert math.fsum(w) == pytest.approx(1.0, abs=1e-9)
    # At a key, that key alone (Bassett eq. 7's interpolation property).
    assert doc["weights"][0] == pytest.approx([1, 0, 0], abs=1e-12)
    assert doc["weights"][3] == pytest.approx([0, 0, 1], abs=1e-12)


def test_readme_lists_every_bake_and_inspect_field():
    """README's documented field lists are the schemas' property lists."""
    readme = (REPO / "README.md").read_text()
    for name in ["bake", "inspect"]:
        props = list(schema(name)["properties"])
        listing = "{" + ",".join(f'"{p}"' for p in props) + "}"
        assert listing in readme, f"README does not list {name} --json fields as {listing}"
    rig = list(schema("inspect")["properties"]["rigs"]["items"]["properties"])
    assert "{" + ",".join(f'"{p}"' for p in rig) + "}" in readme


def rest_points(path, layer):
    stage = Usd.Stage.Open(str(path))
    return np.array(stage.GetPrimAtPath(layer).GetAttribute("painterly:restPoints").Get(), dtype=float)


def test_author_json(painterly, tmp_path):
    fish = FIXTURES / "blowfish.usda"
    hair, spikes = "/Blowfish/Paint/Hair", "/Blowfish/Paint/Spikes"
    brush = ["--layer", hair, "--path", "3,6,-2 6,6,-1.5", "--radius", "1"]
    bind = tmp_path / "bind.usda"
    doc = validate("author", json.loads(painterly("bind", fish, "--layer", hair, "--time", 24, "--edit-layer", bind, "--json").stdout))
    fish_stage = Usd.Stage.Open(str(fish))
    hair_points = len(UsdGeom.BasisCurves(fish_stage.GetPrimAtPath(hair)).GetPointsAttr().Get())
    assert (doc["command"], doc["input"], doc["written"], doc["in_place"]) == ("bind", str(fish), str(bind), False)
    assert (doc["layers"], doc["points"], doc["key"]) == ([hair], hair_points, None)
    assert doc["message"].startswith("bound ")

    key = tmp_path / "key.usda"
    doc = validate("author", json.loads(painterly("key", fish, "--layer", spikes, "--time", 15, "--points", "--edit-layer", key, "--json").stdout))
    assert (doc["command"], doc["layers"], doc["points"]) == ("key", [spikes], 0)
    key_stage = Usd.Stage.Open(str(key))
    prim = key_stage.GetPrimAtPath(doc["key"])
    assert prim and prim.GetTypeName() == "PainterlyPoseKey" and str(prim.GetParent().GetPath()) == spikes

    for command, strength in [("smudge", "0.2"), ("expand", "0.1")]:
        out = tmp_path / f"{command}.usda"
        doc = validate("author", json.loads(painterly(command, fish, *brush, "--strength", strength, "--edit-layer", out, "--json").stdout))
        moved = np.abs(rest_points(out, hair) - rest_points(fish, hair)).max(axis=1) > 0
        assert (doc["command"], doc["layers"], doc["written"]) == (command, [hair], str(out))
        assert doc["points"] == int(moved.sum()) > 0


@pytest.mark.parametrize("kind", ["int", "bogus"])
def test_an_axis_kind_that_cannot_be_read_is_a_problem_in_a_whole_report(painterly, tmp_path, kind):
    """An axis `kind` authored as an int made `inspect --json` print nothing
    (exit 1, the error naming no file); an unknown token broke the schema's
    enum. Both are now one problem in a report that validates, with the
    axis's kind null (an inspect review, 2026-12-07)."""
    src = tmp_path / "fish.usda"
    stage = Usd.Stage.Open(str(FIXTURES / "blowfish.usda"))
    stage.Export(str(src))
    stage = Usd.Stage.Open(str(src))
    axis = stage.DefinePrim("/Blowfish/Loose", "PainterlyAxis")
    if kind == "int":
        # At the Sdf level: the schema plugin makes usd-core refuse it through Usd.
        spec = Sdf.AttributeSpec(stage.GetRootLayer().GetPrimAtPath("/Blowfish/Loose"), "kind",
                                 Sdf.ValueTypeNames.Int)
        spec.default = 3
    else:
        axis.GetAttribute("kind").Set("bogus")
    stage.GetRootLayer().Save()
    proc = painterly("inspect", src, "--json", check=False)
    assert proc.returncode == 1, proc.stderr
    doc = validate("inspect", json.loads(proc.stdout))
    assert {"path": "/Blowfish/Loose", "kind": None, "source": None} in doc["axes"]
    assert [(p["prim"], p["attribute"]) for p in doc["problems"]] == [("/Blowfish/Loose", "kind")]


def test_an_animated_layer_opacity_is_null_not_its_default(painterly, tmp_path):
    """Time-sampled painterly:opacity (0.2 → 0.4) was reported as 1, a
    value no frame uses (an inspect review, 2026-12-07)."""
    src = tmp_path / "fish.usda"
    Usd.Stage.Open(str(FIXTURES / "blowfish.usda")).Export(str(src))
    stage = Usd.Stage.Open(str(src))
    a = stage.GetPrimAtPath("/Blowfish/Paint/Hair").GetAttribute("painterly:opacity")
    a.Set(0.2, 1)
    a.Set(0.4, 48)
    stage.GetRootLayer().Save()
    doc = validate("inspect", json.loads(painterly("inspect", src, "--json").stdout))
    layers = {x["path"]: x for r in doc["rigs"] for x in r["layers"]}
    assert layers["/Blowfish/Paint/Hair"]["opacity"] is None
    assert layers["/Blowfish/Paint/Spots"]["opacity"] == 1.0
    text = painterly("inspect", src).stdout
    assert any(line.split()[0] == "/Blowfish/Paint/Hair" and line.split()[-1] == "animated"
               for line in text.splitlines() if line.strip()), text


def test_unresolved_assets_name_the_layer_that_authors_them_anchored(painterly, tmp_path):
    """A reference authored in a sublayer was said to be "in" the root
    layer, a missing defaultPrim's in no layer ("(in )"), and a relative
    sublayer path was left unanchored (two reviews, 2026-12-07). Expected
    layers and paths are usd-core's (prim stack, ComputeAbsolutePath)."""
    work = tmp_path / "work"
    work.mkdir()
    (work / "nodefault.usda").write_text('#usda 1.0\n\ndef "X"\n{\n}\n')
    (work / "sub.usda").write_text(
        '#usda 1.0\n\ndef "A" (\n    references = @./missing_ref.usda@\n)\n{\n}\n\n'
        'def "B" (\n    references = @./nodefault.usda@\n)\n{\n}\n')
    root = work / "root.usda"
    root.write_text('#usda 1.0\n(\n    subLayers = [@./sub.usda@, @./gone/../missing_sub.usda@]\n)\n')
    stage = Usd.Stage.Open(str(root))
    for prim in ("/A", "/B"):
        authored_in = [s.layer.realPath for s in stage.GetPrimAtPath(prim).GetPrimStack()
                       if s.referenceList.GetAddedOrExplicitItems()]
        assert authored_in == [str(work / "sub.usda")], authored_in
    proc = painterly("inspect", root, "--json", check=False)
    assert proc.returncode == 1
    doc = validate("inspect", json.loads(proc.stdout))
    got = sorted((u["arc"], u["prim"], u["layer"], u["asset"]) for u in doc["unresolved_assets"])
    layer = Sdf.Layer.FindOrOpen(str(root))
    assert got == sorted([
        ("reference", "/A", str(work / "sub.usda"),
         Sdf.Layer.FindOrOpen(str(work / "sub.usda")).ComputeAbsolutePath("./missing_ref.usda")),
        ("reference", "/B", str(work / "sub.usda"), str(work / "nodefault.usda")),
        ("sublayer", None, str(root), layer.ComputeAbsolutePath("./gone/../missing_sub.usda")),
    ])


def test_an_up_axis_other_than_y_or_z_is_a_problem_bake_refuses(painterly, tmp_path):
    """upAxis = "X" passed inspect and was copied into the bake (UsdGeom
    knows only Y and Z); --json broke its own schema (an inspect review,
    2026-12-07)."""
    src = tmp_path / "fish.usda"
    Usd.Stage.Open(str(FIXTURES / "blowfish.usda")).Export(str(src))
    layer = Sdf.Layer.FindOrOpen(str(src))
    layer.pseudoRoot.SetInfo("upAxis", "X")
    layer.Save()
    why = 'the stage\'s upAxis is "X"; it must be "Y" or "Z"'
    proc = painterly("inspect", src, "--json", check=False)
    assert proc.returncode == 1
    doc = validate("inspect", json.loads(proc.stdout))
    assert doc["up_axis"] == "X"
    assert [(p["prim"], p["message"]) for p in doc["problems"]] == [(None, why)]
    out = tmp_path / "b.usdc"
    bake = painterly("bake", src, "-o", out, check=False)
    assert (bake.returncode, bake.stderr) == (1, f"error: {src}: {why}\n")
    assert not out.exists()


@pytest.mark.parametrize("default,samples", [(0.9, {5: 0.3}), (5.0, {1: 0.5, 48: 0.7})])
def test_a_sampled_layer_opacity_ignores_its_default(painterly, tmp_path, default, samples):
    """With time samples usd-core never resolves the default at a frame: a
    default of 0.9 over one sample of 0.3 was reported as 0.9, and a default
    of 5 over samples in range was refused (a verification review,
    2026-12-07). The baked opacity is usd-core's Get(t) at each frame."""
    src = tmp_path / "fish.usda"
    Usd.Stage.Open(str(FIXTURES / "blowfish.usda")).Export(str(src))
    stage = Usd.Stage.Open(str(src))
    a = stage.GetPrimAtPath("/Blowfish/Paint/Hair").GetAttribute("painterly:opacity")
    a.Set(default)
    for t, v in samples.items():
        a.Set(v, t)
    stage.GetRootLayer().Save()
    doc = validate("inspect", json.loads(painterly("inspect", src, "--json").stdout))
    layers = {x["path"]: x for r in doc["rigs"] for x in r["layers"]}
    assert layers["/Blowfish/Paint/Hair"]["opacity"] is None
    out = tmp_path / "b.usdc"
    painterly("bake", src, "-o", out, "--frames", "1:48:11", "--quiet")
    import authoring as Au

    comp = Au.compose(src, out)  # the bake over the input, as a shot layers it
    prim = comp.GetPrimAtPath("/Blowfish/Paint/Hair")
    plain = Usd.Stage.Open(str(src))  # kept: a prim dies with its stage
    authored = plain.GetPrimAtPath("/Blowfish/Paint/Hair")
    for t in (1, 12, 23, 34, 45):
        want = authored.GetAttribute("painterly:opacity").Get(t)
        display = authored.GetAttribute("primvars:displayOpacity").Get(t)
        scale = 1.0 if display is None else np.array(display, dtype=np.float64)
        got = np.array(UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayOpacity").ComputeFlattened(t), dtype=np.float64)
        np.testing.assert_allclose(got, want * scale, atol=1e-6, err_msg=f"t={t}")
