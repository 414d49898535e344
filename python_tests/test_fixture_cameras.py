"""Every fixture camera frames its subject (issue 13): a render from it over
the fixture's whole frame range has paint or geometry in at least 90% of
frames. Cameras are found with usd-core; alpha is read back from the EXRs
with the OpenEXR bindings, not taken from painterly's own summary."""

import pathlib

import OpenEXR
import pytest
from pxr import Usd, UsdGeom

FIXTURES = pathlib.Path(__file__).resolve().parent.parent / "fixtures"


def cameras():
    out = []
    for f in sorted(FIXTURES.glob("*.usda")):
        stage = Usd.Stage.Open(str(f))
        out += [(f.name, str(p.GetPath())) for p in stage.Traverse() if p.IsA(UsdGeom.Camera)]
    return out


def test_the_fixtures_that_need_cameras_have_them():
    names = {f for f, _ in cameras()}
    assert {"blowfish.usda", "head.usda", "building.usda", "walk.usda"} <= names


@pytest.mark.parametrize("fixture,camera", cameras())
def test_camera_frames_its_subject(painterly, tmp_path, fixture, camera):
    stage = Usd.Stage.Open(str(FIXTURES / fixture))
    start, end = int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode())
    step = max(1, (end - start) // 16)
    painterly("render", FIXTURES / fixture, "--camera", camera, "--frames", f"{start}:{end}:{step}",
              "-o", tmp_path / "f.####.exr", "--size", "96x64", "--quiet")
    frames = sorted(tmp_path.glob("f.*.exr"))
    assert len(frames) == len(range(start, end + 1, step))
    covered = 0
    for path in frames:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            covered += bool((f.channels()["A"].pixels > 0).any())
    assert covered >= 0.9 * len(frames), f"{camera}: {len(frames) - covered} of {len(frames)} frames empty"
