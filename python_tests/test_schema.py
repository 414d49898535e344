"""The codeless painterly USD schema (schemas/painterly) against usd-core.

conftest.py puts schemas/painterly on PXR_PLUGINPATH_NAME before pxr.Usd is
imported, so in this process the plugin is loaded; the tests that need a USD
*without* the plugin run a child Python with that variable removed.
"""

import importlib.util
import json
import os
import pathlib
import subprocess
import sys

import pytest
from pxr import Plug, Sdf, Tf, Usd, UsdValidation

from conftest import REPO, SCHEMA_DIR

U = Sdf.VariabilityUniform
V = Sdf.VariabilityVarying
REL = "rel"
CONCRETE = Usd.SchemaKind.ConcreteTyped
SINGLE_API = Usd.SchemaKind.SingleApplyAPI

# type name -> (schema kind, can-only-apply-to,
#               {property: REL | (type name, variability, fallback, allowedTokens)})
EXPECTED = {
    "PainterlyRigAPI": (SINGLE_API, [], {
        "painterly:proxy": REL,
        "painterly:restTime": ("double", U, None, None),
    }),
    "PainterlyStrokeLayerAPI": (SINGLE_API, ["BasisCurves"], {
        "painterly:restPoints": ("point3f[]", U, None, None),
        "painterly:bindVertices": ("int3[]", U, None, None),
        "painterly:bindWeights": ("float3[]", U, None, None),
        "painterly:opacity": ("float", V, 1.0, None),
        "painterly:axes": REL,
        "painterly:interpolation": ("token", U, "smoothVoronoi", ["smoothVoronoi", "rbf", "shepard"]),
        "painterly:rbfRadius": ("float", U, 1.0, None),
    }),
    "PainterlyViewDependentAPI": (SINGLE_API, ["Mesh"], {
        "painterly:sharpness": ("float", V, 1.0, None),
        "painterly:uncovered": ("token", U, "cosine", ["cosine", "base"]),
        "painterly:camera": REL,
    }),
    "PainterlyAxis": (CONCRETE, [], {
        "kind": ("token", U, "attribute",
                 ["attribute", "blendShape", "jointRotation", "position", "viewDirection"]),
        "source": REL,
        "name": ("token", U, None, None),
        "element": ("int", U, 0, None),
        "component": ("int", U, 0, None),
        "scale": ("float", U, 1.0, None),
    }),
    "PainterlyPoseKey": (CONCRETE, [], {
        "coordinates": ("float[]", U, None, None),
        "points": ("point3f[]", U, None, None),
        "opacity": ("float", U, None, None),
    }),
    "PainterlyTimeKey": (CONCRETE, [], {
        "time": ("double", U, None, None),
        "sentinel": ("bool", U, False, None),
        "points": ("point3f[]", U, None, None),
        "opacity": ("float", U, None, None),
    }),
    "PainterlyViewKey": (CONCRETE, [], {
        "points": ("point3f[]", U, None, None),
        "direction": ("float3", U, None, None),
        "time": ("double", U, None, None),
        "viewpoint": ("token", U, None, None),
    }),
}
API_TYPES = [t for t, (kind, _, _) in EXPECTED.items() if kind == SINGLE_API]
TYPED_TYPES = [t for t, (kind, _, _) in EXPECTED.items() if kind == CONCRETE]


def _definition(type_name):
    reg = Usd.SchemaRegistry()
    if EXPECTED[type_name][0] == CONCRETE:
        return reg.FindConcretePrimDefinition(type_name)
    return reg.FindAppliedAPIPrimDefinition(type_name)


# A small painted character using every type and every property (SPEC §1).
# Some schema-uniform attributes are declared without `uniform`, as in the
# SPEC's example: USD takes variability from the schema and does not complain.
SCENE_USDA = """#usda 1.0
(
    defaultPrim = "Fish"
    metersPerUnit = 0.01
    upAxis = "Y"
    startTimeCode = 1
    endTimeCode = 48
)

def Xform "Fish" (
    kind = "component"
)
{
    def Scope "Rig"
    {
        def Mesh "Proxy"
        {
            int[] faceVertexCounts = [4]
            int[] faceVertexIndices = [0, 1, 2, 3]
            point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
            point3f[] points.timeSamples = {
                1: [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
                48: [(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
            }
            float3[] extent = [(0, 0, 0), (1, 1, 0)]
        }
    }

    def Xform "EyeTarget"
    {
        double3 xformOp:translate = (0, 0, 5)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }

    def Camera "Cam"
    {
        double3 xformOp:translate = (0, 0, 10)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }

    def Xform "Paint" (
        prepend apiSchemas = ["PainterlyRigAPI"]
    )
    {
        rel painterly:proxy = </Fish/Rig/Proxy>
        uniform double painterly:restTime = 1

        def PainterlyAxis "eyeX"
        {
            uniform token kind = "position"
            rel source = </Fish/EyeTarget>
            uniform int component = 0
            uniform float scale = 2
        }

        def PainterlyAxis "view"
        {
            uniform token kind = "viewDirection"
            rel source = </Fish/Cam>
            uniform int component = 2
        }

        def PainterlyAxis "open"
        {
            token kind = "attribute"
            rel source = </Fish/Rig/Proxy.extent>
            token name = "open"
            int element = 1
        }

        def BasisCurves "Spikes" (
            prepend apiSchemas = ["PainterlyStrokeLayerAPI"]
        )
        {
            uniform token type = "linear"
            int[] curveVertexCounts = [2]
            point3f[] points = [(0.2, 0.2, 0), (0.2, 0.2, 0.5)]
            float3[] extent = [(0.2, 0.2, 0), (0.2, 0.2, 0.5)]
            float[] widths = [0.01, 0.01] (
                interpolation = "vertex"
            )
            color3f[] primvars:displayColor = [(1, 0, 0)] (
                interpolation = "uniform"
            )
            float[] primvars:displayOpacity = [1] (
                interpolation = "uniform"
            )
            uniform point3f[] painterly:restPoints = [(0.2, 0.2, 0), (0.2, 0.2, 0.5)]
            uniform int3[] painterly:bindVertices = [(0, 1, 2), (0, 1, 2)]
            uniform float3[] painterly:bindWeights = [(0.6, 0, 0.4), (0.6, 0, 0.4)]
            float painterly:opacity = 0.5
            float painterly:opacity.timeSamples = {
                1: 0.5,
                48: 1,
            }
            rel painterly:axes = [
                </Fish/Paint/eyeX>,
                </Fish/Paint/view>,
            ]
            uniform token painterly:interpolation = "rbf"
            uniform float painterly:rbfRadius = 0.25

            def PainterlyPoseKey "flat"
            {
                float[] coordinates = [0, 0]
                point3f[] points = [(0.2, 0.2, 0), (0.2, 0.2, 0.5)]
            }

            def PainterlyPoseKey "puffed"
            {
                uniform float[] coordinates = [1, 0.5]
                uniform point3f[] points = [(0.2, 0.2, 0), (0.3, 0.2, 0.7)]
                uniform float opacity = 0.75
            }

            def PainterlyTimeKey "s1"
            {
                double time = 40
                bool sentinel = 1
            }

            def PainterlyTimeKey "shock"
            {
                uniform double time = 48
                uniform point3f[] points = [(0.2, 0.2, 0), (0.2, 0.2, 0.9)]
                uniform float opacity = 0.25
            }
        }
    }

    def Mesh "Head" (
        prepend apiSchemas = ["PainterlyViewDependentAPI"]
    )
    {
        int[] faceVertexCounts = [3]
        int[] faceVertexIndices = [0, 1, 2]
        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
        float3[] extent = [(0, 0, 0), (1, 1, 0)]
        float painterly:sharpness = 2
        uniform token painterly:uncovered = "base"
        rel painterly:camera = </Fish/Cam>

        def PainterlyViewKey "front"
        {
            uniform float3 direction = (0, 0, 1)
            uniform point3f[] points = [(0, 0, 0.1), (1, 0, 0), (0, 1, 0)]
            uniform double time = 10
            uniform token viewpoint = "front"
        }
    }
}
"""

# Run in this process (plugin loaded) and in a child without the plugin: a
# JSON snapshot of everything *authored* on the stage.
SNAPSHOT_CODE = r'''
def _plain(value):
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, Sdf.AssetPath):
        return value.path
    try:
        return [_plain(v) for v in value]
    except TypeError:
        return str(value)


def _listop(op):
    return None if op is None else list(op.GetAddedOrExplicitItems())


def snapshot(stage):
    prims = {}
    for prim in stage.TraverseAll():
        props = {}
        for attr in prim.GetAuthoredAttributes():
            samples = {str(t): _plain(attr.Get(t)) for t in attr.GetTimeSamples()}
            props[attr.GetName()] = {
                "type": str(attr.GetTypeName()),
                "default": _plain(attr.Get(Usd.TimeCode.Default())),
                "samples": samples,
            }
        for rel in prim.GetAuthoredRelationships():
            props[rel.GetName()] = {"targets": [str(t) for t in rel.GetTargets()]}
        prims[str(prim.GetPath())] = {
            "typeName": prim.GetTypeName(),
            "apiSchemas": _listop(prim.GetMetadata("apiSchemas")),
            "typeInfoAPISchemas": list(prim.GetPrimTypeInfo().GetAppliedAPISchemas()),
            "props": props,
        }
    return prims
'''
exec(SNAPSHOT_CODE)  # defines snapshot() here, with this module's Sdf/Usd


CHILD_CODE = r'''
import json, sys
from pxr import Plug, Sdf, Usd
''' + SNAPSHOT_CODE + r'''
stage = Usd.Stage.Open(sys.argv[1])
paint = stage.GetPrimAtPath("/Fish/Paint")
axis = stage.GetPrimAtPath("/Fish/Paint/eyeX")
shock = stage.GetPrimAtPath("/Fish/Paint/Spikes/shock")
print(json.dumps({
    "plugin": Plug.Registry().GetPluginWithName("painterly") is not None,
    "axisDefinition": Usd.SchemaRegistry().FindConcretePrimDefinition("PainterlyAxis") is not None,
    "hasRigAPI": paint.HasAPI("PainterlyRigAPI"),
    "rigAppliedSchemas": list(paint.GetAppliedSchemas()),
    "unauthoredSentinel": shock.GetAttribute("sentinel").IsValid(),
    "axisHasPrimDefinitionProps": list(axis.GetPrimDefinition().GetPropertyNames()),
    "snapshot": snapshot(stage),
}))
'''


def _env_without_plugin():
    env = dict(os.environ)
    for key in ("PXR_PLUGINPATH_NAME", "TF_DEBUG"):
        env.pop(key, None)
    return env


def _write_scene(directory, ext):
    path = directory / f"scene.{ext}"
    if ext == "usda":
        path.write_text(SCENE_USDA)
    else:
        layer = Sdf.Layer.CreateAnonymous(".usda")
        assert layer.ImportFromString(SCENE_USDA)
        assert layer.Export(str(path))
    return path


# ---------------------------------------------------------------- plugin ----

def test_plugin_is_a_resource_plugin_with_generated_schema():
    plugin = Plug.Registry().GetPluginWithName("painterly")
    assert plugin is not None, "PXR_PLUGINPATH_NAME did not register plugin 'painterly'"
    assert plugin.isResource
    assert not plugin.isPythonModule
    assert pathlib.Path(plugin.path).resolve() == SCHEMA_DIR.resolve()
    assert pathlib.Path(plugin.resourcePath).resolve() == SCHEMA_DIR.resolve()
    found = plugin.FindPluginResource("generatedSchema.usda")
    assert found and pathlib.Path(found).resolve() == (SCHEMA_DIR / "generatedSchema.usda").resolve()
    assert pathlib.Path(found).is_file()
    assert plugin.metadata.get("Types", {}).keys() == EXPECTED.keys()
    text = (SCHEMA_DIR / "plugInfo.json").read_text()
    assert "@PLUG_INFO_" not in text


@pytest.mark.parametrize("type_name", list(EXPECTED))
def test_type_is_registered_with_its_schema_kind(type_name):
    kind, can_only_apply_to, _ = EXPECTED[type_name]
    assert Usd.SchemaRegistry.GetSchemaKind(type_name) == kind
    tf_type = Usd.SchemaRegistry.GetTypeFromSchemaTypeName(type_name)
    assert tf_type == Tf.Type.FindByName(type_name) and not tf_type.isUnknown
    assert Usd.SchemaRegistry.GetSchemaTypeName(tf_type) == type_name
    if kind == CONCRETE:
        assert tf_type.IsA(Usd.Typed)
        assert Usd.SchemaRegistry.IsTyped(tf_type)
        assert Usd.SchemaRegistry.IsConcrete(type_name)
        assert not Usd.SchemaRegistry.IsAppliedAPISchema(type_name)
        assert not tf_type.IsA(Usd.APISchemaBase)
    else:
        assert tf_type.IsA(Usd.APISchemaBase)
        assert Usd.SchemaRegistry.IsAppliedAPISchema(type_name)
        assert not Usd.SchemaRegistry.IsMultipleApplyAPISchema(type_name)
        assert not Usd.SchemaRegistry.IsConcrete(type_name)
        assert list(Usd.SchemaRegistry.GetAPISchemaCanOnlyApplyToTypeNames(type_name)) \
            == can_only_apply_to


@pytest.mark.parametrize("type_name", list(EXPECTED))
def test_definition_has_every_property_with_type_and_fallback(type_name):
    definition = _definition(type_name)
    assert definition is not None
    expected = EXPECTED[type_name][2]
    assert sorted(definition.GetPropertyNames()) == sorted(expected)
    for name, spec in expected.items():
        if spec == REL:
            assert definition.GetRelationshipDefinition(name), name
            assert not definition.GetAttributeDefinition(name), name
            continue
        type_token, variability, fallback, allowed = spec
        attr = definition.GetAttributeDefinition(name)
        assert attr, name
        assert attr.GetTypeName() == Sdf.ValueTypeNames.Find(type_token), name
        assert str(attr.GetTypeNameToken()) == type_token, name
        assert attr.GetVariability() == variability, name
        assert definition.GetAttributeFallbackValue(name) == fallback, name
        assert attr.GetFallbackValue() == fallback, name
        tokens = definition.GetPropertyMetadata(name, "allowedTokens")
        if allowed is None:
            assert tokens is None, name
        else:
            assert list(tokens) == allowed, name
            assert fallback in allowed


def test_every_class_and_property_is_documented_in_the_source():
    layer = Sdf.Layer.FindOrOpen(str(SCHEMA_DIR / "schema.usda"))
    assert layer
    glob = layer.GetPrimAtPath("/GLOBAL")
    assert dict(glob.customData) == {
        "libraryName": "painterly", "libraryPath": ".", "skipCodeGeneration": True}
    classes = [p for p in layer.rootPrims if p.name != "GLOBAL"]
    assert sorted(p.name for p in classes) == sorted(EXPECTED)
    for cls in classes:
        assert cls.specifier == Sdf.SpecifierClass
        assert cls.documentation.strip(), cls.name
        assert "className" in cls.customData, cls.name
        assert cls.customData["className"] == cls.name[len("Painterly"):]
        assert sorted(p.name for p in cls.properties) == sorted(EXPECTED[cls.name][2])
        for prop in cls.properties:
            assert prop.documentation.strip(), f"{cls.name}.{prop.name}"

    # usdGenSchema drops `doc` from generatedSchema.usda and keeps the first
    # sentence of each as customData userDocBrief (what usdview shows).
    generated = Sdf.Layer.FindOrOpen(str(SCHEMA_DIR / "generatedSchema.usda"))
    assert sorted(p.name for p in generated.rootPrims) == sorted(EXPECTED)
    for cls in generated.rootPrims:
        assert cls.customData.get("userDocBrief", "").endswith("."), cls.name
        for prop in cls.properties:
            brief = prop.customData.get("userDocBrief", "")
            assert brief.endswith(".") and len(brief) > 20, f"{cls.name}.{prop.name}"


# ----------------------------------------------------------------- stage ----

def test_applied_and_typed_prims_report_schemas_and_fallbacks():
    stage = Usd.Stage.CreateInMemory()
    rig = stage.DefinePrim("/Fish/Paint", "Xform")
    strokes = stage.DefinePrim("/Fish/Paint/Spikes", "BasisCurves")
    head = stage.DefinePrim("/Fish/Head", "Mesh")

    assert rig.CanApplyAPI("PainterlyRigAPI")
    assert rig.ApplyAPI("PainterlyRigAPI")
    assert strokes.CanApplyAPI("PainterlyStrokeLayerAPI")
    assert strokes.AddAppliedSchema("PainterlyStrokeLayerAPI")
    assert head.CanApplyAPI("PainterlyViewDependentAPI")
    assert head.ApplyAPI("PainterlyViewDependentAPI")
    # apiSchemaCanOnlyApplyTo is advisory: CanApplyAPI says no (with a reason).
    why = rig.CanApplyAPI("PainterlyStrokeLayerAPI")
    assert not why and "BasisCurves" in why.whyNot
    assert not strokes.CanApplyAPI("PainterlyViewDependentAPI")

    for prim, api in ((rig, "PainterlyRigAPI"), (strokes, "PainterlyStrokeLayerAPI"),
                      (head, "PainterlyViewDependentAPI")):
        assert prim.HasAPI(api)
        assert prim.HasAPI(Tf.Type.FindByName(api))
        assert list(prim.GetAppliedSchemas()) == [api]
        assert prim.GetMetadata("apiSchemas").GetAddedOrExplicitItems() == [api]
        for name, spec in EXPECTED[api][2].items():
            if spec == REL:
                rel = prim.GetRelationship(name)
                assert rel and not rel.IsCustom() and rel.GetTargets() == []
                continue
            attr = prim.GetAttribute(name)
            assert attr and not attr.IsCustom() and not attr.HasAuthoredValue(), name
            assert attr.Get() == spec[2], name
            assert str(attr.GetTypeName()) == spec[0], name
            assert attr.GetVariability() == spec[1], name
            if spec[3]:
                assert list(attr.GetMetadata("allowedTokens")) == spec[3]
    assert not rig.HasAPI("PainterlyStrokeLayerAPI")

    for type_name in TYPED_TYPES:
        prim = stage.DefinePrim(f"/Fish/Paint/Spikes/{type_name}", type_name)
        assert prim.IsA(type_name)
        assert prim.IsA(Usd.Typed)
        assert prim.IsA(Tf.Type.FindByName(type_name))
        for name, spec in EXPECTED[type_name][2].items():
            if spec == REL:
                assert prim.GetRelationship(name), name
                continue
            attr = prim.GetAttribute(name)
            assert attr and not attr.IsCustom(), name
            assert attr.Get() == spec[2], name
            if spec[3]:
                assert list(attr.GetMetadata("allowedTokens")) == spec[3]

    # Authored values win over fallbacks, time samples on varying attributes.
    strokes.GetAttribute("painterly:interpolation").Set("shepard")
    strokes.GetAttribute("painterly:opacity").Set(0.25, Usd.TimeCode(10))
    assert strokes.GetAttribute("painterly:interpolation").Get() == "shepard"
    assert strokes.GetAttribute("painterly:opacity").Get(10) == 0.25
    axis = stage.GetPrimAtPath("/Fish/Paint/Spikes/PainterlyAxis")
    axis.GetAttribute("kind").Set("jointRotation")
    assert axis.GetAttribute("kind").Get() == "jointRotation"


def test_scene_file_reads_with_plugin(tmp_path):
    stage = Usd.Stage.Open(str(_write_scene(tmp_path, "usda")))
    spikes = stage.GetPrimAtPath("/Fish/Paint/Spikes")
    assert spikes.HasAPI("PainterlyStrokeLayerAPI")
    assert spikes.GetAttribute("painterly:opacity").Get(48) == 1.0
    assert spikes.GetRelationship("painterly:axes").GetTargets() == [
        Sdf.Path("/Fish/Paint/eyeX"), Sdf.Path("/Fish/Paint/view")]
    sentinel = stage.GetPrimAtPath("/Fish/Paint/Spikes/s1")
    assert sentinel.IsA("PainterlyTimeKey")
    assert sentinel.GetAttribute("sentinel").Get() is True
    assert not sentinel.GetAttribute("points").HasAuthoredValue()
    assert sentinel.GetAttribute("points").Get() is None
    flat = stage.GetPrimAtPath("/Fish/Paint/Spikes/flat")
    assert not flat.GetAttribute("opacity").HasAuthoredValue()
    head = stage.GetPrimAtPath("/Fish/Head")
    assert head.HasAPI("PainterlyViewDependentAPI")
    view = stage.GetPrimAtPath("/Fish/Paint/view")
    assert view.GetAttribute("scale").Get() == 1.0  # fallback
    assert view.GetAttribute("element").Get() == 0


# ----------------------------------------------------- without the plugin ----

@pytest.mark.parametrize("ext", ["usda", "usdc"])
def test_files_open_without_the_plugin(tmp_path, ext):
    path = _write_scene(tmp_path, ext)
    proc = subprocess.run(
        [sys.executable, "-c", CHILD_CODE, str(path)],
        capture_output=True, text=True, env=_env_without_plugin(), cwd=str(tmp_path),
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == "", f"USD printed diagnostics without the plugin:\n{proc.stderr}"
    child = json.loads(proc.stdout)

    # The child really ran without the schema...
    assert child["plugin"] is False
    assert child["axisDefinition"] is False
    assert child["hasRigAPI"] is False
    assert child["rigAppliedSchemas"] == []  # GetAppliedSchemas drops unknown schemas
    assert child["unauthoredSentinel"] is False
    assert child["axisHasPrimDefinitionProps"] == []

    # ...and still sees exactly what this process (with the plugin) sees as authored.
    expected = snapshot(Usd.Stage.Open(str(path)))
    assert child["snapshot"] == expected

    prims = child["snapshot"]
    type_names = {p: v["typeName"] for p, v in prims.items()}
    for path_str, type_name in {
        "/Fish/Paint/eyeX": "PainterlyAxis",
        "/Fish/Paint/Spikes/flat": "PainterlyPoseKey",
        "/Fish/Paint/Spikes/s1": "PainterlyTimeKey",
        "/Fish/Head/front": "PainterlyViewKey",
        "/Fish/Paint/Spikes": "BasisCurves",
    }.items():
        assert type_names[path_str] == type_name
    for path_str, api in (("/Fish/Paint", "PainterlyRigAPI"),
                          ("/Fish/Paint/Spikes", "PainterlyStrokeLayerAPI"),
                          ("/Fish/Head", "PainterlyViewDependentAPI")):
        # Composed apiSchemas metadata, and the prim type info, keep the name.
        assert prims[path_str]["apiSchemas"] == [api]
        assert prims[path_str]["typeInfoAPISchemas"] == [api]
    spikes = prims["/Fish/Paint/Spikes"]["props"]
    assert spikes["painterly:interpolation"]["default"] == "rbf"
    assert spikes["painterly:bindVertices"]["default"] == [[0, 1, 2], [0, 1, 2]]
    assert spikes["painterly:opacity"]["samples"] == {"1.0": 0.5, "48.0": 1.0}
    assert spikes["painterly:axes"]["targets"] == ["/Fish/Paint/eyeX", "/Fish/Paint/view"]
    puffed = prims["/Fish/Paint/Spikes/puffed"]["props"]
    assert puffed["coordinates"]["default"] == [1.0, 0.5]
    assert puffed["opacity"]["default"] == 0.75
    assert prims["/Fish/Paint/Spikes/s1"]["props"]["sentinel"]["default"] is True
    assert prims["/Fish/Paint/eyeX"]["props"]["kind"]["default"] == "position"
    assert prims["/Fish/Paint/eyeX"]["props"]["source"]["targets"] == ["/Fish/EyeTarget"]
    front = prims["/Fish/Head/front"]["props"]
    assert front["direction"]["default"] == [0.0, 0.0, 1.0]
    assert front["viewpoint"]["default"] == "front"


# ------------------------------------------------------------- generator ----

def _usdgenschema_unavailable():
    if importlib.util.find_spec("jinja2") is None:
        return "jinja2 is not installed"
    pxr_dir = pathlib.Path(importlib.util.find_spec("pxr").origin).parent
    if not (pxr_dir / "Usd" / "usdGenSchema.py").is_file():
        return f"usd-core at {pxr_dir} does not ship usdGenSchema"
    return None


def test_generated_files_match_schema_source():
    reason = _usdgenschema_unavailable()
    if reason:
        pytest.skip(reason)
    proc = subprocess.run(
        [sys.executable, str(REPO / "scripts" / "gen_schema.py"), "--check"],
        capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, (
        "schemas/painterly is out of date with schema.usda; run scripts/gen_schema.py\n"
        f"{proc.stdout}\n{proc.stderr}")


# ------------------------------------------------------------ validation ----

def _validate(stage):
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    assert validators
    return UsdValidation.ValidationContext(validators).Validate(stage)


def _describe(errors):
    return "\n".join(f"{e.GetType()} {e.GetIdentifier()}: {e.GetMessage()}" for e in errors)


def test_validation_of_a_stage_using_every_type(tmp_path):
    stage = Usd.Stage.Open(str(_write_scene(tmp_path, "usda")))
    used = {p.GetTypeName() for p in stage.Traverse()}
    used |= {api for p in stage.Traverse() for api in p.GetAppliedSchemas()}
    assert set(EXPECTED) <= used
    errors = [e for e in _validate(stage) if not e.HasNoError()]
    assert errors == [], _describe(errors)


BAD_TYPES_USDA = """#usda 1.0
(
    defaultPrim = "Curves"
    metersPerUnit = 1
    upAxis = "Y"
)

def BasisCurves "Curves" (
    prepend apiSchemas = ["PainterlyStrokeLayerAPI"]
)
{
    double painterly:opacity = 0.5

    def PainterlyPoseKey "key"
    {
        double[] coordinates = [1]
        float3[] points = [(0, 0, 0)]
    }
}
"""


def test_validation_reports_type_mismatches_against_the_schema():
    """Control: the validators above really check against painterly's schema
    (a role mismatch, float3[] for point3f[], counts too). Types must be
    authored in the layer: UsdPrim.CreateAttribute on a schema attribute
    silently uses the schema's type instead."""
    layer = Sdf.Layer.CreateAnonymous(".usda")
    assert layer.ImportFromString(BAD_TYPES_USDA)
    stage = Usd.Stage.Open(layer)
    errors = [e for e in _validate(stage) if not e.HasNoError()]
    mismatches = sorted(str(site.GetPropertySpec().path)  # sites are layer specs
                        for e in errors if e.GetName() == "AttributeTypeMismatch"
                        for site in e.GetSites())
    assert mismatches == ["/Curves.painterly:opacity", "/Curves/key.coordinates",
                          "/Curves/key.points"], _describe(errors)
