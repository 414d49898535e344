"""Bad view-dependent input (SPEC section 6): `painterly bake` exits 1 with
`error: FILE: PRIM.ATTR: message` on stderr naming the offending prim and
attribute (both keys for a duplicate), writes no output file, leaves the
input untouched and never panics."""

import json

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

import authoring as Au
import reference_view as RV

OCTAHEDRON = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
MESH = "/World/Thing/Ball"


def key(st, name):
    return st.GetPrimAtPath(f"{MESH}/{name}")


def set_attr(prim, name, type_name, value, time=None):
    a = prim.GetAttribute(name) or prim.CreateAttribute(name, type_name, custom=False)
    if time is None:
        a.Set(value)
    else:
        a.Set(value, time)


def short_points(st):
    pts = key(st, "Key2").GetAttribute("points").Get()
    key(st, "Key2").GetAttribute("points").Set(pts[:-1])


def long_points(st):
    pts = list(key(st, "Key2").GetAttribute("points").Get())
    key(st, "Key2").GetAttribute("points").Set(pts + [Gf.Vec3f(0, 0, 0)])


def direction(value):
    return lambda st: key(st, "Key3").GetAttribute("direction").Set(Gf.Vec3f(*value))


def duplicate_untimed(st):
    key(st, "Key4").GetAttribute("direction").Set(Gf.Vec3f(2, 0, 0))  # same as Key0 once normalised


def duplicate_timed(st):
    for k in ("Key0", "Key4"):
        set_attr(key(st, k), "time", Sdf.ValueTypeNames.Double, 5.0)
    key(st, "Key4").GetAttribute("direction").Set(Gf.Vec3f(1, 0, 0))


def duplicate_token(st):
    for k in ("Key1", "Key5"):
        set_attr(key(st, k), "time", Sdf.ValueTypeNames.Double, 3.0)
        set_attr(key(st, k), "viewpoint", Sdf.ValueTypeNames.Token, "back")
    key(st, "Key5").GetAttribute("direction").Set(Gf.Vec3f(-1, 0, 0))


def sharpness(v):
    return lambda st: set_attr(st.GetPrimAtPath(MESH), "painterly:sharpness", Sdf.ValueTypeNames.Float, v)


def uncovered(tok):
    return lambda st: set_attr(st.GetPrimAtPath(MESH), "painterly:uncovered", Sdf.ValueTypeNames.Token, tok)


def no_camera_rel(st):
    st.GetPrimAtPath(MESH).RemoveProperty("painterly:camera")


def empty_camera_rel(st):
    st.GetPrimAtPath(MESH).GetRelationship("painterly:camera").ClearTargets(True)


def rel_to(path, make=None):
    def f(st):
        if make:
            make(st)
        st.GetPrimAtPath(MESH).GetRelationship("painterly:camera").SetTargets([Sdf.Path(path)])
    return f


def scope(st):
    UsdGeom.Scope.Define(st, "/World/Looks")


def material(st):
    UsdShade.Material.Define(st, "/World/Mat")


def mixed_timed(st):
    set_attr(key(st, "Key0"), "time", Sdf.ValueTypeNames.Double, 5.0)
    key(st, "Key4").GetAttribute("direction").Set(Gf.Vec3f(1, 0, 0))


def token_different_direction(st):
    for k in ("Key0", "Key1"):
        set_attr(key(st, k), "viewpoint", Sdf.ValueTypeNames.Token, "same")


# name: (mutation, extra bake args, substrings stderr must contain)
CASES = {
    "points_short": (short_points, [], [f"{MESH}/Key2.points"]),
    "points_long": (long_points, [], [f"{MESH}/Key2.points"]),
    "direction_zero": (direction((0, 0, 0)), [], [f"{MESH}/Key3.direction"]),
    "direction_nan": (direction((float("nan"), 0, 1)), [], [f"{MESH}/Key3.direction"]),
    "direction_inf": (direction((0, float("inf"), 1)), [], [f"{MESH}/Key3.direction"]),
    "duplicate_untimed": (duplicate_untimed, [], [f"{MESH}/Key4.direction", f"{MESH}/Key0", "neither has a time"]),
    "duplicate_timed": (duplicate_timed, [], [f"{MESH}/Key0.time", f"{MESH}/Key4", "same direction and time"]),
    "duplicate_token": (duplicate_token, [], [f"{MESH}/Key1", f"{MESH}/Key5"]),
    "mixed_timed_untimed": (mixed_timed, [], [f"{MESH}/Key0", f"{MESH}/Key4", ".time"]),
    "token_different_direction": (token_different_direction, [], [f"{MESH}/Key0", f"{MESH}/Key1"]),
    "camera_arg_missing": (None, ["--camera", "/World/Nope"], ["/World/Nope", "--camera"]),
    "camera_arg_scope": (scope, ["--camera", "/World/Looks"], ["/World/Looks", "--camera"]),
    "camera_arg_material": (material, ["--camera", "/World/Mat"], ["/World/Mat", "--camera"]),
    "camera_rel_missing": (rel_to("/World/Nope"), [], ["/World/Nope", f"{MESH}.painterly:camera"]),
    "camera_rel_scope": (rel_to("/World/Looks", scope), [], ["/World/Looks", f"{MESH}.painterly:camera"]),
    "camera_rel_material": (rel_to("/World/Mat", material), [], ["/World/Mat", f"{MESH}.painterly:camera"]),
    "sharpness_zero": (sharpness(0.0), [], [f"{MESH}.painterly:sharpness"]),
    "sharpness_negative": (sharpness(-2.0), [], [f"{MESH}.painterly:sharpness"]),
    "sharpness_nan": (sharpness(float("nan")), [], [f"{MESH}.painterly:sharpness"]),
    "uncovered_unknown": (uncovered("bogus"), [], [f"{MESH}.painterly:uncovered", "bogus"]),
    "no_camera": (no_camera_rel, [], [f"{MESH}.painterly:camera", "--camera"]),
    "camera_rel_empty": (empty_camera_rel, [], [f"{MESH}.painterly:camera"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_bad_view_input(painterly, tmp_path, case):
    mutate, extra, needles = CASES[case]
    path = tmp_path / "bad.usda"
    RV.build_view_stage(path, keys=[(d, None, None, None) for d in OCTAHEDRON], eyes=RV.orbit_eyes(4))
    if mutate:
        st = Usd.Stage.Open(str(path))
        mutate(st)
        st.GetRootLayer().Save()
        del st
    before = Au.file_hash(path)
    out = tmp_path / "out.usda"
    r = painterly("bake", path, "-o", out, *extra, check=False)
    assert r.returncode == 1, f"exit {r.returncode}\nstdout:\n{r.stdout}\nstderr:\n{r.stderr}"
    err = r.stderr
    assert "panicked" not in err and "RUST_BACKTRACE" not in err, err
    first = err.strip().splitlines()[0] if err.strip() else ""
    assert first.startswith(f"error: {path}: "), f"not `error: FILE: ...`: {err!r}"
    for n in needles:
        assert n in err, f"stderr does not name {n!r}: {err!r}"
    assert "Some(" not in err and "None)" not in err, f"debug formatting leaks into the message: {err!r}"
    assert not out.exists(), "a failed bake left an output file"
    assert not list(tmp_path.glob("out*")), "a failed bake left a partial file"
    assert Au.file_hash(path) == before, "input modified"


def test_bad_key_in_one_mesh_fails_the_whole_bake(painterly, tmp_path):
    """A good view mesh next to a bad one: nothing is written."""
    path = tmp_path / "bad.usda"
    RV.build_view_stage(path, keys=[(d, None, None, None) for d in OCTAHEDRON], eyes=RV.orbit_eyes(4))
    st = Usd.Stage.Open(str(path))
    src = st.GetPrimAtPath(MESH)
    copy = UsdGeom.Mesh.Define(st, "/World/Other")
    for name in ("points", "faceVertexCounts", "faceVertexIndices"):
        copy.GetPrim().CreateAttribute(name, src.GetAttribute(name).GetTypeName()).Set(src.GetAttribute(name).Get())
    RV.apply_view_api(copy.GetPrim(), camera="/World/Camera")
    pts = np.array(src.GetAttribute("points").Get(), dtype=np.float64)
    RV.add_view_key(st, "/World/Other", "Only", pts[:-3], (0, 0, 1))
    st.GetRootLayer().Save()
    del st
    out = tmp_path / "out.usdc"
    r = painterly("bake", path, "-o", out, check=False)
    assert r.returncode == 1 and "/World/Other/Only.points" in r.stderr, r.stderr
    assert not out.exists()


@pytest.mark.parametrize("target, make, why", [
    ("/World/Nope", None, "targets /World/Nope, which does not exist"),
    ("/World/Looks", scope, "targets /World/Looks, a Scope prim, which has no transform"),
])
def test_a_bad_camera_relationship_is_a_problem_of_the_mesh(painterly, tmp_path, target, make, why):
    """The fault is authored on the mesh's `painterly:camera`, so that is the
    prim and attribute `inspect --json` and the bake name (a validator keys on
    them), under the view-mesh rule; the target is named in the message."""
    path = tmp_path / "bad.usda"
    RV.build_view_stage(path, keys=[(d, None, None, None) for d in OCTAHEDRON], eyes=RV.orbit_eyes(4))
    st = Usd.Stage.Open(str(path))
    rel_to(target, make)(st)
    st.GetRootLayer().Save()
    del st
    r = painterly("inspect", path, "--json", check=False)
    assert r.returncode == 1, r.stderr
    problems = json.loads(r.stdout)["problems"]
    assert [(p["prim"], p["attribute"], p["rule"]) for p in problems] == [(MESH, "painterly:camera", "view-mesh")], problems
    assert why in problems[0]["message"], problems
    r = painterly("bake", path, "-o", tmp_path / "out.usdc", check=False)
    assert r.returncode == 1
    assert r.stderr.splitlines()[0].startswith(f"error: {path}: {MESH}.painterly:camera: {why}"), r.stderr


def test_a_camera_relationship_with_two_targets_is_refused(painterly, tmp_path):
    """The first of two targets was used silently (a review, 2026-12-07)."""
    path = tmp_path / "bad.usda"
    RV.build_view_stage(path, keys=[(d, None, None, None) for d in OCTAHEDRON], eyes=RV.orbit_eyes(4))
    st = Usd.Stage.Open(str(path))
    rel = st.GetPrimAtPath(MESH).GetRelationship("painterly:camera")
    first = rel.GetTargets()[0]
    rel.SetTargets([first, "/World"])
    st.GetRootLayer().Save()
    del st
    why = f"has 2 targets ({first}, /World); painterly reads one"
    r = painterly("inspect", path, "--json", check=False)
    assert r.returncode == 1, r.stderr
    problems = json.loads(r.stdout)["problems"]
    assert [(p["prim"], p["attribute"], p["rule"], p["message"]) for p in problems] == [
        (MESH, "painterly:camera", "view-mesh", why)], problems
    r = painterly("bake", path, "-o", tmp_path / "out.usdc", check=False)
    assert (r.returncode, r.stderr) == (1, f"error: {path}: {MESH}.painterly:camera: {why}\n")


def test_no_camera_names_the_option_every_command_takes(painterly, tmp_path):
    """The message said "pass `painterly bake --camera PRIM`" in inspect,
    farm and the preview too: each of them takes `--camera`."""
    path = tmp_path / "bad.usda"
    RV.build_view_stage(path, keys=[(d, None, None, None) for d in OCTAHEDRON], eyes=RV.orbit_eyes(4))
    st = Usd.Stage.Open(str(path))
    no_camera_rel(st)
    st.GetRootLayer().Save()
    del st
    why = "no camera: pass `--camera PRIM` or author `rel painterly:camera`"
    r = painterly("bake", path, "-o", tmp_path / "out.usda", check=False)
    assert (r.returncode, r.stderr) == (1, f"error: {path}: {MESH}.painterly:camera: {why}\n")
    r = painterly("inspect", path, "--json", check=False)
    problems = json.loads(r.stdout)["problems"]
    assert [(p["prim"], p["attribute"], p["message"]) for p in problems] == [(MESH, "painterly:camera", why)], problems
