"""Bad axes and keys (SPEC sections 4-5): each case exits 1 with a message on
stderr of the form `error: FILE: PRIM.ATTR: message` naming the prim(s) and
attribute involved, leaves no output file behind, never panics and never
modifies the input. `painterly inspect` reports the same problems (exit 1).

Every case starts from a stage that bakes cleanly (test_good_stage_bakes)
and breaks exactly one thing.
"""

from __future__ import annotations

import json
import os
import re

import numpy as np
import pytest
from pxr import Sdf, Usd, Vt

import authoring as Au
import authoring_keys as AK

SKEL = "/World/Character/Skel"
ANIM = "/World/Character/Anim"
RIG = "/World/Paint"
LAYER = "/World/Paint/Keyed"
AXIS = "/World/Paint/bulge"


def good_stage(tmp_path, name="rig.usda"):
    """A skinned tube with a blend-shape axis, a keyed layer (two position
    keys, one opacity key, a sentinel and two time keys), a locator, a
    camera and a controls prim."""
    rig = Au.build_skel_rig(tmp_path / name, blend_shapes={"dense"}, n_strokes=3)
    stage = Usd.Stage.Open(str(rig.path))
    AK.add_controls(stage)
    AK.add_locator(stage)
    AK.add_orbit_camera(stage)
    AK.add_axis(stage, AXIS, "blendShape", source=ANIM, name="bulge")
    rng = np.random.default_rng(1)
    rest, _ = AK.add_layer(stage, rig, LAYER, rng, n_strokes=3)
    AK.set_layer_axes(stage, LAYER, [AXIS])
    AK.add_pose_key(stage, LAYER, "flat", [0.0], points=AK.displaced(rest, rng, 0.1))
    AK.add_pose_key(stage, LAYER, "puffed", [0.9], points=AK.displaced(rest, rng, 0.1), opacity=0.5)
    AK.add_pose_key(stage, LAYER, "dim", [0.4], opacity=0.2)
    AK.add_time_key(stage, LAYER, "s0", 3, sentinel=True)
    AK.add_time_key(stage, LAYER, "shock", 6, points=AK.displaced(rest, rng, 0.2), opacity=1.0)
    AK.add_time_key(stage, LAYER, "settle", 8, points=AK.displaced(rest, rng, 0.2))
    stage.GetRootLayer().Save()
    return rig, rest


def edit(path, fn):
    stage = Usd.Stage.Open(str(path))
    fn(stage)
    stage.GetRootLayer().Save()


def expect_failure(painterly, tmp_path, input_path, names=(), extra=()):
    """Run a bake that must fail; check the error contract. `names`: strings
    stderr must contain (prim paths, PRIM.ATTR, attribute names)."""
    out_dir = tmp_path / "out"
    out_dir.mkdir(exist_ok=True)
    out = out_dir / "bake.usdc"
    before = Au.file_hash(input_path)
    listing = sorted(os.listdir(tmp_path))
    proc = painterly("bake", input_path, "-o", out, *extra, check=False)
    err = proc.stderr
    assert proc.returncode == 1, f"exit {proc.returncode}, expected 1\nstderr:\n{err}\nstdout:\n{proc.stdout}"
    assert "panicked" not in err and "RUST_BACKTRACE" not in err, f"panic:\n{err}"
    assert re.search(r"^error: ", err, re.M), f"no line starting with 'error: ' on stderr:\n{err}"
    base = os.path.basename(str(input_path))
    assert base in err, f"error does not name the file {base}:\n{err}"
    for s in names:
        assert s in err, f"error does not mention {s!r}:\n{err}"
    assert not out.exists(), "failed bake left an output file"
    assert os.listdir(out_dir) == [], f"failed bake left files: {os.listdir(out_dir)}"
    assert sorted(os.listdir(tmp_path)) == listing, "failed bake left files next to the input"
    assert Au.file_hash(input_path) == before, "input modified"
    return err


# ---------------------------------------------------------------------------
# the bad cases: name -> (edit(stage, rig, rest), names that must appear,
# extra bake arguments)


def _set(prim_path, name, tname, value):
    def f(stage, rig, rest):
        prim = stage.GetPrimAtPath(prim_path)
        a = prim.GetAttribute(name) or prim.CreateAttribute(name, tname, False)
        a.Set(value)
    return f


def _retarget(prim_path, rel, targets):
    def f(stage, rig, rest):
        stage.GetPrimAtPath(prim_path).CreateRelationship(rel, False).SetTargets(
            [Sdf.Path(t) for t in targets])
    return f


def _remove(prim_path, prop):
    return lambda stage, rig, rest: stage.GetPrimAtPath(prim_path).RemoveProperty(prop)


def _new_axis(axis_name, kind, **kw):
    """Add an axis to the keyed layer (as its second axis) and give every pose
    key a second coordinate, so only the axis itself is wrong."""
    path = f"{RIG}/{axis_name}"

    def f(stage, rig, rest):
        AK.add_axis(stage, path, kind, **kw)
        AK.set_layer_axes(stage, LAYER, [AXIS, path])
        for c in stage.GetPrimAtPath(LAYER).GetChildren():
            if c.GetTypeName() == "PainterlyPoseKey":
                a = c.GetAttribute("coordinates")
                a.Set(Vt.FloatArray(list(a.Get()) + [0.25]))
    return path, f


def _both(*fns):
    def f(stage, rig, rest):
        for fn in fns:
            fn(stage, rig, rest)
    return f


def _dup_pose(channel):
    def f(stage, rig, rest):
        if channel == "points":
            AK.add_pose_key(stage, LAYER, "flat2", [0.0], points=rest + 0.05)
        else:
            AK.add_pose_key(stage, LAYER, "dim2", [0.4], opacity=0.6)
    return f


def _dup_time(channel):
    def f(stage, rig, rest):
        if channel == "points":
            AK.add_time_key(stage, LAYER, "shock2", 6, points=rest + 0.05)
        else:
            AK.add_time_key(stage, LAYER, "shock2", 6, opacity=0.3)
    return f


def _short_points(kind):
    def f(stage, rig, rest):
        if kind == "pose":
            AK.add_pose_key(stage, LAYER, "short", [0.5], points=rest[:-1])
        else:
            AK.add_time_key(stage, LAYER, "short", 10, points=rest[:-2])
    return f


def _samples_only(prim_path, name):
    """The attribute's default moved to a time sample at 1, as exporters that
    time-sample everything write it; the schema makes it uniform, so
    painterly (like usd-core's Get()) would read it as absent."""
    def f(stage, rig, rest):
        a = stage.GetPrimAtPath(prim_path).GetAttribute(name)
        v = a.Get()
        assert v is not None, f"{prim_path}.{name} has no default to move"
        a.Clear()
        a.Set(v, 1.0)
    return f


def _samples_beside_default(prim_path, name):
    """The attribute's default kept and a time sample at 1 added: usd-core's
    Get() reads the default, its Get(1) the sample."""
    def f(stage, rig, rest):
        a = stage.GetPrimAtPath(prim_path).GetAttribute(name)
        v = a.Get()
        assert v is not None, f"{prim_path}.{name} has no default"
        a.Set(v, 1.0)
    return f


_missing_src_path, _missing_src = _new_axis("noSource", "blendShape", name="bulge")
_ghost_path, _ghost = _new_axis("ghost", "position", source="/World/Nope", component=1)
_ghost_attr_path, _ghost_attr = _new_axis("ghostAttr", "attribute", source="/World/Controls.ctl:nope")
_kind_path, _kind = _new_axis("weird", "bogus", source="/World/Controls.ctl:scalar")
_joint_path, _joint = _new_axis("elbow", "jointRotation", source=SKEL, name="root/elbow", component=0)
_jc_path, _jc = _new_axis("jointC", "jointRotation", source=SKEL, name="root/mid", component=3)
_pc_path, _pc = _new_axis("posC", "position", source="/World/LocParent/Locator", component=3)
_vc_path, _vc = _new_axis("viewC", "viewDirection", source="/World/Orbit/Cam", component=-1)
_ac_path, _ac = _new_axis("vecC", "attribute", source="/World/Controls.ctl:vec", component=3)
_qc_path, _qc = _new_axis("quatC", "attribute", source="/World/Controls.ctl:quat", component=4)
# a pick on a scalar means the axis names the wrong attribute
_sc_path, _sc = _new_axis("scalarC", "attribute", source="/World/Controls.ctl:scalar", component=2)
_se_path, _se = _new_axis("scalarE", "attribute", source="/World/Controls.ctl:scalar", element=1)
_vn_path, _vn = _new_axis("viewNoCam", "viewDirection", component=0)
_vghost_path, _vghost = _new_axis("viewGhost", "viewDirection", source="/World/NoCam", component=0)

CASES = {
    # coordinates: one per layer axis
    "coordinates_too_many": (_set(f"{LAYER}/flat", "coordinates", Sdf.ValueTypeNames.FloatArray,
                                  Vt.FloatArray([0.0, 1.0])), [f"{LAYER}/flat.coordinates"], ()),
    "coordinates_empty": (_set(f"{LAYER}/dim", "coordinates", Sdf.ValueTypeNames.FloatArray,
                               Vt.FloatArray([])), [f"{LAYER}/dim.coordinates"], ()),
    "coordinates_default_axes": (  # no painterly:axes: every axis under the rig (two of them)
        _both(_remove(LAYER, "painterly:axes"),
              lambda st, rig, rest: AK.add_axis(st, f"{RIG}/extra", "blendShape", source=ANIM, name="bulge")),
        [f"{LAYER}/flat.coordinates"], ()),
    # key points: all of the layer's points
    "pose_points_count": (_short_points("pose"), [f"{LAYER}/short.points"], ()),
    "time_points_count": (_short_points("time"), [f"{LAYER}/short.points"], ()),
    # duplicates within one channel name both keys
    "pose_duplicate_position": (_dup_pose("points"), [f"{LAYER}/flat", f"{LAYER}/flat2"], ()),
    "pose_duplicate_opacity": (_dup_pose("opacity"), [f"{LAYER}/dim", f"{LAYER}/dim2"], ()),
    "time_duplicate_points": (_dup_time("points"), [f"{LAYER}/shock", f"{LAYER}/shock2"], ()),
    "time_duplicate_opacity": (_dup_time("opacity"), [f"{LAYER}/shock", f"{LAYER}/shock2"], ()),
    # axis sources
    "axis_source_not_authored": (_missing_src, [f"{_missing_src_path}.source"], ()),
    "axis_source_missing_prim": (_ghost, [f"{_ghost_path}.source"], ()),
    "axis_source_missing_attribute": (_ghost_attr, [f"{_ghost_attr_path}.source"], ()),
    "axis_source_empty_targets": (_retarget(AXIS, "source", []), [f"{AXIS}.source"], ()),
    "axis_source_two_targets": (_retarget(AXIS, "source", [ANIM, "/World/Controls"]),
                                [f"{AXIS}.source", "has 2 targets", "painterly reads one"], ()),
    # the layer's relationship is named, not only the prim it targets
    "axes_target_not_an_axis": (_retarget(LAYER, "painterly:axes", ["/World/Controls"]),
                                [f"{LAYER}.painterly:axes", "targets /World/Controls", "not a PainterlyAxis"], ()),
    "view_source_missing_prim_with_camera": (_vghost, [f"{_vghost_path}.source"],
                                             ("--camera", "/World/Orbit/Cam")),
    # axis kind, interpolation, radius
    "unknown_axis_kind": (_kind, [f"{_kind_path}.kind"], ()),
    "unknown_interpolation": (_set(LAYER, "painterly:interpolation", Sdf.ValueTypeNames.Token, "linear"),
                              [f"{LAYER}.painterly:interpolation"], ()),
    "rbf_radius_zero": (_both(_set(LAYER, "painterly:interpolation", Sdf.ValueTypeNames.Token, "rbf"),
                              _set(LAYER, "painterly:rbfRadius", Sdf.ValueTypeNames.Float, 0.0)),
                        [f"{LAYER}.painterly:rbfRadius"], ()),
    "rbf_radius_negative": (_both(_set(LAYER, "painterly:interpolation", Sdf.ValueTypeNames.Token, "rbf"),
                                  _set(LAYER, "painterly:rbfRadius", Sdf.ValueTypeNames.Float, -1.0)),
                            [f"{LAYER}.painterly:rbfRadius"], ()),
    # joints and components
    "joint_name_not_in_joints": (_joint, [f"{_joint_path}.name"], ()),
    "joint_component_3": (_jc, [f"{_jc_path}.component"], ()),
    "position_component_3": (_pc, [f"{_pc_path}.component"], ()),
    "view_component_negative": (_vc, [f"{_vc_path}.component"], ()),
    "vector_component_3": (_ac, [f"{_ac_path}.component"], ()),
    "quaternion_component_4": (_qc, [f"{_qc_path}.component"], ()),
    "scalar_component_2": (_sc, [f"{_sc_path}.component", "picks from a scalar"], ()),
    "scalar_element_1": (_se, [f"{_se_path}.element", "picks from a scalar"], ()),
    # a viewDirection axis with neither a source nor --camera
    "view_without_source_or_camera": (_vn, [f"{_vn_path}.source: a viewDirection axis needs `rel source` or `--camera`"], ()),
    # authored opacities lie in [0, 1], as `key --opacity` takes them
    "pose_key_opacity_above_1": (_set(f"{LAYER}/dim", "opacity", Sdf.ValueTypeNames.Float, 1.7),
                                 [f"{LAYER}/dim.opacity", "outside [0, 1]"], ()),
    "time_key_opacity_negative": (_set(f"{LAYER}/shock", "opacity", Sdf.ValueTypeNames.Float, -0.5),
                                  [f"{LAYER}/shock.opacity", "outside [0, 1]"], ()),
    "layer_opacity_negative": (_set(LAYER, "painterly:opacity", Sdf.ValueTypeNames.Float, -0.5),
                               [f"{LAYER}.painterly:opacity", "outside [0, 1]"], ()),
    # the time-key limit and overflow, per run between sentinels (crashed before)
    "time_keys_over_the_limit": (lambda st, rig, rest: [AK.add_time_key(st, LAYER, f"many{i}", 1000 + i, opacity=0.5)
                                                         for i in range(300)],
                                 ["301 keys", "at most 300"], ()),
    "time_keys_too_far_apart": (lambda st, rig, rest: AK.add_time_key(st, LAYER, "far", 1e160, opacity=0.5),
                                [f"{LAYER}/far", f"{LAYER}/shock.time", "too far"], ()),
    # uniform attributes authored only as time samples
    **{f"samples_only_{n.split(':')[-1]}_{p.rsplit('/', 1)[1]}": (_samples_only(p, n), [f"{p}.{n}", "only as time samples"], ())
       for p, n in [(f"{LAYER}/flat", "points"), (f"{LAYER}/puffed", "coordinates"), (f"{LAYER}/dim", "opacity"),
                    (f"{LAYER}/shock", "time"), (f"{LAYER}/s0", "sentinel"), (AXIS, "name"), (AXIS, "kind"),
                    (LAYER, "painterly:restPoints")]},
    # and beside a default (usd-core's Get at a frame reads the samples)
    **{f"samples_beside_default_{n.split(':')[-1]}_{p.rsplit('/', 1)[1]}": (
        _samples_beside_default(p, n), [f"{p}.{n}", "time samples (1 sample, first at 1) beside its default"], ())
       for p, n in [(f"{LAYER}/flat", "points"), (f"{LAYER}/puffed", "coordinates"), (f"{LAYER}/dim", "opacity"),
                    (f"{LAYER}/shock", "time"), (f"{LAYER}/s0", "sentinel"), (AXIS, "name"), (AXIS, "kind"),
                    (LAYER, "painterly:restPoints")]},
}


def test_good_stage_bakes(painterly, tmp_path):
    """The starting point is valid (so every failure below is the edit's)."""
    rig, _ = good_stage(tmp_path)
    out = tmp_path / "bake.usdc"
    proc = painterly("bake", rig.path, "-o", out, "--quiet")
    assert proc.returncode == 0 and out.exists()
    assert "panicked" not in proc.stderr
    # and the view axis without a source is fine once --camera is given
    edit(rig.path, lambda st: _vn(st, rig, None))
    out2 = tmp_path / "bake2.usdc"
    painterly("bake", rig.path, "-o", out2, "--quiet", "--camera", "/World/Orbit/Cam")
    assert out2.exists()


@pytest.mark.parametrize("case", list(CASES))
def test_bad_key(painterly, tmp_path, case):
    fn, names, extra = CASES[case]
    rig, rest = good_stage(tmp_path)
    edit(rig.path, lambda st: fn(st, rig, rest))
    expect_failure(painterly, tmp_path, rig.path, names=names, extra=extra)


INSPECT_CASES = [c for c in CASES if c not in ("view_without_source_or_camera",
                                               "view_source_missing_prim_with_camera")]


@pytest.mark.parametrize("case", INSPECT_CASES)
def test_inspect_reports_bad_key(painterly, tmp_path, case):
    fn, names, _ = CASES[case]
    rig, rest = good_stage(tmp_path)
    edit(rig.path, lambda st: fn(st, rig, rest))
    before = Au.file_hash(rig.path)
    proc = painterly("inspect", rig.path, check=False)
    assert proc.returncode == 1, f"inspect exit {proc.returncode}\n{proc.stdout}\n{proc.stderr}"
    assert "panicked" not in proc.stderr
    text = proc.stdout + proc.stderr
    prims = {n.split(".")[0] for n in names}
    for p in prims:
        assert p in text, f"inspect does not mention {p}:\n{text}"
    assert Au.file_hash(rig.path) == before


def test_a_uniform_attribute_with_only_time_samples_is_named(painterly, tmp_path):
    """The whole message and the inspect problem's rule."""
    rig, rest = good_stage(tmp_path)
    edit(rig.path, lambda st: _samples_only(LAYER, "painterly:restPoints")(st, rig, rest))
    err = expect_failure(painterly, tmp_path, rig.path)
    assert err == (
        f"error: {rig.path}: {LAYER}.painterly:restPoints: authored only as time samples (1 sample, first at 1), "
        "but the schema makes it uniform: painterly reads its default value; author it without a time\n"
    )
    report = json.loads(painterly("inspect", rig.path, "--json", check=False).stdout)
    assert [(p["prim"], p["attribute"], p["rule"]) for p in report["problems"]] == [
        (LAYER, "painterly:restPoints", "attribute-type")]


def test_a_uniform_attribute_with_time_samples_beside_its_default_is_named(painterly, tmp_path):
    """usd-core's Get() reads the default but Get(frame) the samples (a
    review's chain: bind --in-place, then usd-core keyed the rest points and
    the bake used the default, 0.5 off what usd-core reads at a frame, with
    inspect silent): refused like samples alone, by bake and inspect."""
    rig, rest = good_stage(tmp_path)

    def default_and_samples(stage):
        a = stage.GetPrimAtPath(LAYER).GetAttribute("painterly:restPoints")
        a.Set(Vt.Vec3fArray([tuple(p) for p in rest]))
        a.Set(Vt.Vec3fArray([tuple(p + 1.0) for p in rest]), 2.0)
        a.Set(Vt.Vec3fArray([tuple(p + 1.0) for p in rest]), 5.0)
    edit(rig.path, default_and_samples)
    st = Usd.Stage.Open(str(rig.path))
    a = st.GetPrimAtPath(LAYER).GetAttribute("painterly:restPoints")
    assert np.allclose(np.array(a.Get(2.0)) - np.array(a.Get()), 1.0)  # the two readings differ
    err = expect_failure(painterly, tmp_path, rig.path)
    assert err == (
        f"error: {rig.path}: {LAYER}.painterly:restPoints: has time samples (2 samples, first at 2) beside its "
        "default, but the schema makes it uniform: painterly reads only the default, where usd-core's Get at a "
        "frame reads the samples; remove the samples or the default\n"
    )
    report = json.loads(painterly("inspect", rig.path, "--json", check=False).stdout)
    assert [(p["prim"], p["attribute"], p["rule"]) for p in report["problems"]] == [
        (LAYER, "painterly:restPoints", "attribute-type")]


def test_a_blend_shape_axis_the_animation_does_not_animate_gets_a_note(painterly, tmp_path):
    """SPEC §4: such an axis reads 0 (not a problem: bake succeeds), but a
    misspelt name reads 0 too, so inspect notes it on the rig, naming what
    the animation animates (walkthrough: `puf` for `puff` passed silently)."""
    rig, rest = good_stage(tmp_path)
    notes = lambda: json.loads(painterly("inspect", rig.path, "--json").stdout)["rigs"][0]["notes"]
    assert not [n for n in notes() if AXIS in n]
    edit(rig.path, lambda st: st.GetAttributeAtPath(f"{AXIS}.name").Set("bulgee"))
    stage = Usd.Stage.Open(str(rig.path))
    animated = ", ".join(stage.GetPrimAtPath(ANIM).GetAttribute("blendShapes").Get())
    assert "bulge" in animated.split(", ")
    assert [n for n in notes() if AXIS in n] == [
        f'axis {AXIS} reads 0 at every frame: {ANIM} does not animate blend shape "bulgee" (it animates: {animated})']
    text = painterly("inspect", rig.path).stdout
    assert f'  note: axis {AXIS} reads 0 at every frame: {ANIM} does not animate blend shape "bulgee"' in text
    painterly("bake", rig.path, "-o", tmp_path / "bake.usdc", "--quiet")


def test_inspect_lists_a_bad_attribute_pick_beside_another_problem(painterly, tmp_path):
    """An attribute axis's element and component are checked when the axis
    is read, not only when a frame is evaluated: inspect evaluates frames
    only when it found nothing else, so a stage with a second, unrelated
    problem (a stroke layer outside any rig) must still list the axis's."""
    rig, rest = good_stage(tmp_path)

    def both(stage):
        _ac(stage, rig, rest)
        loose = stage.DefinePrim("/World/Loose", "BasisCurves")
        loose.AddAppliedSchema(Au.LAYER_API)
        loose.CreateAttribute("curveVertexCounts", Sdf.ValueTypeNames.IntArray).Set(Vt.IntArray([2]))
        loose.CreateAttribute("points", Sdf.ValueTypeNames.Point3fArray).Set(Au.v3f([[0, 0, 0], [1, 0, 0]]))

    edit(rig.path, both)
    proc = painterly("inspect", rig.path, "--json", check=False)
    assert proc.returncode == 1, proc.stderr
    got = sorted((p["prim"], p["attribute"]) for p in json.loads(proc.stdout)["problems"])
    assert got == [("/World/Loose", None), (_ac_path, "component")], got


BLOWFISH_SPIKES = "/Blowfish/Paint/Spikes"


def test_bake_refuses_time_keys_it_counts_as_one_time(painterly, repo_root, tmp_path):
    # Written by usd-core: a third key at 37 in the run between the
    # sentinels, and settle moved to 40 + 2e-12, 2e-12 after shock in a run
    # spanning 3 + 2e-12 (tolerance about 3e-12). The bake used to panic here.
    inp = tmp_path / "blowfish.usda"
    inp.write_bytes((repo_root / "fixtures" / "blowfish.usda").read_bytes())
    st = Usd.Stage.Open(str(inp))
    shock = st.GetPrimAtPath(f"{BLOWFISH_SPIKES}/shock")
    early = st.DefinePrim(f"{BLOWFISH_SPIKES}/early", "PainterlyTimeKey")
    early.CreateAttribute("time", Sdf.ValueTypeNames.Double, custom=False).Set(37.0)
    early.CreateAttribute("points", Sdf.ValueTypeNames.Point3fArray, custom=False).Set(
        shock.GetAttribute("points").Get())
    st.GetPrimAtPath(f"{BLOWFISH_SPIKES}/settle").GetAttribute("time").Set(40.000000000002)
    st.GetRootLayer().Save()
    del st, shock, early
    for cmd in (["inspect", inp], ["bake", inp, "-o", tmp_path / "bake.usdc", "-q"]):
        p = painterly(*cmd, check=False)
        assert p.returncode == 1, f"{cmd[0]}: exit {p.returncode}: {p.stderr}"
        assert "panicked" not in p.stderr and "internal error" not in p.stderr, p.stderr
        assert (f"{BLOWFISH_SPIKES}/shock.time: {BLOWFISH_SPIKES}/settle is within 1e-12 of the span of the time "
                "keys between their sentinels: the time interpolation counts the two as one time"
                ) in p.stderr + p.stdout, p.stderr
    assert not (tmp_path / "bake.usdc").exists()


def test_a_property_of_the_other_key_type_is_named_and_ignored(painterly, tmp_path):
    """SPEC §4–5: a pose key has coordinates, a time key a time and a
    sentinel flag. The other type's property on a key (a retyped prim, a
    copy-paste) is never read: inspect names each one under the rule of
    what it would have set (exit 1), and the bake ignores it (its points
    equal the clean stage's)."""
    rig, rest = good_stage(tmp_path)
    pose, timed = f"{LAYER}/flat", f"{LAYER}/shock"

    def misplace(stage):
        flat = stage.GetPrimAtPath(pose)
        flat.CreateAttribute("sentinel", Sdf.ValueTypeNames.Bool).Set(True)
        flat.CreateAttribute("time", Sdf.ValueTypeNames.Double).Set(5.0)
        stage.GetPrimAtPath(timed).CreateAttribute("coordinates", Sdf.ValueTypeNames.FloatArray).Set(Vt.FloatArray([0.9]))
    edit(rig.path, misplace)
    proc = painterly("inspect", rig.path, "--json", check=False)
    assert proc.returncode == 1, proc.stderr
    problems = [(p["prim"], p["attribute"], p["rule"], p["message"]) for p in json.loads(proc.stdout)["problems"]]
    assert problems == [
        (pose, "sentinel", "sentinel-misuse",
         "a pose key has no sentinel: it would be ignored (only a PainterlyTimeKey's sentinel is read; "
         "a pose key keys its coordinates)"),
        (pose, "time", "key-time",
         "a pose key has no time: it would be ignored (only a PainterlyTimeKey's time is read; "
         "a pose key keys its coordinates)"),
        (timed, "coordinates", "key-coordinates",
         "a time key has no coordinates: they would be ignored (only a PainterlyPoseKey's coordinates "
         "are read; a time key keys its time)"),
    ]
    out = tmp_path / "bake.usda"
    painterly("bake", rig.path, "-o", out, "--frames", "1:9", "--quiet")
    clean, _ = good_stage(tmp_path / "clean")
    painterly("bake", clean.path, "-o", tmp_path / "clean.usda", "--frames", "1:9", "--quiet")
    baked = [Usd.Stage.Open(str(p)) for p in (out, tmp_path / "clean.usda")]
    for t in range(1, 10):
        got, want = (np.array(st.GetPrimAtPath(LAYER).GetAttribute("points").Get(t)) for st in baked)
        assert got.shape == (len(rest), 3) and np.array_equal(got, want), t


BLOWFISH_AXIS = "/Blowfish/Paint/inflate"


def _blowfish_with_axis_fault(repo_root, tmp_path, fault):
    """fixtures/blowfish.usda with one fault on the inflate axis, which the
    Spikes, Cheeks and GapFill layers' keys use: a bad `kind` or `source`
    authored in a copy, or the axis deactivated by a shot that sublayers it."""
    asset = tmp_path / "blowfish.usda"
    asset.write_bytes((repo_root / "fixtures" / "blowfish.usda").read_bytes())
    if fault == "deactivated":
        src = Sdf.Layer.FindOrOpen(str(asset))
        shot = Sdf.Layer.CreateNew(str(tmp_path / "shot.usda"))
        shot.subLayerPaths.append("./blowfish.usda")
        shot.startTimeCode, shot.endTimeCode = src.startTimeCode, src.endTimeCode
        stage = Usd.Stage.Open(shot)
        stage.SetEditTarget(shot)
        stage.OverridePrim(BLOWFISH_AXIS).SetActive(False)
        shot.Save()
        return tmp_path / "shot.usda"
    stage = Usd.Stage.Open(str(asset))
    axis = stage.GetPrimAtPath(BLOWFISH_AXIS)
    if fault == "kind":
        axis.GetAttribute("kind").Set("blendShap")
    else:
        axis.GetRelationship("source").SetTargets([Sdf.Path("/Blowfish/Rig/Skel/NoAnim")])
    stage.GetRootLayer().Save()
    return asset


def _stroke_layers(stage):
    """usd-core's count: {path: (strokes, points)} of every BasisCurves with
    PainterlyStrokeLayerAPI under a prim with PainterlyRigAPI."""
    rigs = [p.GetPath() for p in stage.Traverse() if "PainterlyRigAPI" in p.GetAppliedSchemas()]
    out = {}
    for p in stage.Traverse():
        if (p.GetTypeName() == "BasisCurves" and "PainterlyStrokeLayerAPI" in p.GetAppliedSchemas()
                and any(p.GetPath().HasPrefix(r) for r in rigs)):
            counts = list(p.GetAttribute("curveVertexCounts").Get())
            out[str(p.GetPath())] = (len(counts), sum(counts))
    return out


@pytest.mark.parametrize("fault", ["kind", "source", "deactivated"])
def test_inspect_lists_the_layers_of_a_broken_axis_and_names_it_once(painterly, repo_root, tmp_path, fault):
    """README: inspect lists each stroke layer, and a cause several layers
    meet (an axis their keys share) is one problem, named once. The layers
    whose keys use a broken axis used to vanish from the listing (11 of the
    blowfish's 14), and a deactivated axis was one problem per layer; now
    every layer is listed with its strokes and points and the axis is one
    problem on the axis (rule axis), as a bad kind or source already was."""
    shot = _blowfish_with_axis_fault(repo_root, tmp_path, fault)
    stage = Usd.Stage.Open(str(shot))
    layers = _stroke_layers(stage)
    users = [p for p in layers if Sdf.Path(BLOWFISH_AXIS) in
             stage.GetPrimAtPath(p).GetRelationship("painterly:axes").GetTargets()]
    assert len(users) == 3, users  # the fault is shared
    strokes = sum(s for s, _ in layers.values())
    points = sum(n for _, n in layers.values())

    proc = painterly("inspect", shot, "--json", check=False)
    assert proc.returncode == 1, proc.stderr
    report = json.loads(proc.stdout)
    [rig] = report["rigs"]
    got = {lay["path"]: (lay["strokes"], lay["points"]) for lay in rig["layers"]}
    assert len(rig["layers"]) == len(layers) and got == layers
    problems = [(p["prim"], p["attribute"], p["rule"]) for p in report["problems"]]
    attribute = {"kind": "kind", "source": "source", "deactivated": None}[fault]
    assert problems == [(BLOWFISH_AXIS, attribute, "axis")], report["problems"]
    if fault == "deactivated":
        message = report["problems"][0]["message"]
        assert message.startswith("the axis is deactivated (active = false)"), message
        assert f"({', '.join(users)})" in message, message

    proc = painterly("inspect", shot, check=False)
    assert proc.returncode == 1, proc.stderr
    assert f"  total: {len(layers)} layers, {strokes} strokes, {points} points\n" in proc.stdout, proc.stdout
    assert "1 problem(s):\n" in proc.stdout, proc.stdout
    # bake still refuses the stage, naming the axis
    out = tmp_path / "bake.usdc"
    proc = painterly("bake", shot, "-o", out, check=False)
    assert proc.returncode == 1 and f": {BLOWFISH_AXIS}" in proc.stderr, proc.stderr
    assert not out.exists()


def test_a_view_axis_refuses_a_camera_at_the_proxys_centre_up_to_rounding(painterly, tmp_path):
    """The camera is put at the centre of the proxy's box through the proxy's
    transforms, where usd-core leaves a residue of about 1e-17: a direction
    made of that noise would give the keys arbitrary weights, so the bake
    refuses it as it refuses an exact zero."""
    from pxr import Gf, UsdGeom

    rig = Au.build_points_rig(tmp_path / "rig.usda", mode="static", n_strokes=3,
                              proxy_xform=Au.xf_static((0.3, -1.7, 2.9), (31, -47, 12), (1.3, 0.7, 2.1)))
    stage = Usd.Stage.Open(str(rig.path))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(rig.mesh))
    pts = np.array(mesh.GetPointsAttr().Get(), dtype=np.float64)
    centre = (pts.min(axis=0) + pts.max(axis=0)) / 2
    world = mesh.ComputeLocalToWorldTransform(1.0).Transform(Gf.Vec3d(*centre))
    cam = UsdGeom.Camera.Define(stage, "/World/CentreCam")
    cam.AddTranslateOp().Set(world)
    back = np.array(mesh.ComputeLocalToWorldTransform(1.0).GetInverse().Transform(world))
    assert np.linalg.norm(back - centre) < 1e-12
    axis = f"{rig.rig}/view"
    AK.add_axis(stage, axis, "viewDirection", source="/World/CentreCam", component=0)
    rng = np.random.default_rng(2)
    lp = f"{rig.rig}/L_view"
    AK.add_layer(stage, rig, lp, rng, n_strokes=3)
    AK.set_layer_axes(stage, lp, [axis])
    AK.add_pose_key(stage, lp, "left", [-1.0], opacity=0.0)
    AK.add_pose_key(stage, lp, "right", [1.0], opacity=1.0)
    stage.GetRootLayer().Save()
    err = expect_failure(painterly, tmp_path, rig.path, names=["/World/CentreCam"])
    assert "camera is at the proxy's centre at time 1" in err, err


def test_inspect_checks_an_axis_no_keyed_layer_reads_yet(painterly, tmp_path):
    """An axis was read only by layers with pose keys: a wrong joint name
    passed inspect (exit 0) and surfaced at the first `painterly key` (a TD
    workflow review on CesiumMan, 2026-12-06). inspect checks every axis
    now; a name that ends exactly one joint's path is offered as the fix.
    The bake, which reads no such axis, still succeeds."""
    rig, _ = good_stage(tmp_path)
    edit(rig.path, lambda st: AK.add_axis(st, f"{RIG}/spare", "jointRotation", source=SKEL, name="tip", component=0))
    proc = painterly("inspect", rig.path, "--json", check=False)
    assert proc.returncode == 1, proc.stdout
    problems = json.loads(proc.stdout)["problems"]
    assert [(p["prim"], p["attribute"], p["rule"]) for p in problems] == [(f"{RIG}/spare", "name", "axis")]
    assert problems[0]["message"] == (
        f'joint "tip" is not in {SKEL}.joints (joints are named by their path: "root/mid/tip"?)')
    painterly("bake", rig.path, "-o", tmp_path / "bake.usdc", "--quiet")
