"""Renders checked for what users see, on scenes usd-core writes.

Expected colours come from what was authored (displayColor, displayOpacity)
and the formulas docs/render.md documents (premultiplied *over*;
Rademacher's warm/cool shading with its constants), evaluated here with
numpy; pixel positions from usd-core's own camera frustum. Nothing is
copied from painterly's output.
"""

import json
import os
import pathlib
import re
import resource
import shlex
import struct
import subprocess
import zlib

import numpy as np
import OpenEXR
import pytest
from PIL import Image
from pxr import Gf, Sdf, Usd, UsdGeom, Vt
from scipy.spatial import ConvexHull

from conftest import painterly_binary, run_on_pty

W, H = 200, 160
CAM_Z = 15.0

# docs/render.md, "Meshes": Rademacher §3.2.4 with the paper's constants.
K_A = 0.9
WARM = np.array([0.95, 0.62, 0.30])
COOL = np.array([0.18, 0.26, 0.55])
L_WARM = np.array([-0.5, 0.6, 0.62]) / np.linalg.norm([-0.5, 0.6, 0.62])
SILHOUETTE = np.array([0.02, 0.02, 0.03])


def warm_cool(base, n_cam):
    """Shaded colour of a surface of colour `base` whose camera-space normal is `n_cam`."""
    n = np.asarray(n_cam, float) / np.linalg.norm(n_cam)
    base = np.asarray(base, float)
    return K_A * base + max(0.0, L_WARM @ n) * (WARM - base) + max(0.0, -L_WARM @ n) * (COOL - base)


def read_exr(path):
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {k: np.array(v.pixels, dtype=np.float64) for k, v in f.channels().items()}


def new_stage(path, end=1):
    stage = Usd.Stage.CreateNew(str(path))
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(end)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.1, 100))
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, CAM_Z))
    return stage


def quad(stage, path, center, half, color, z=0.0):
    m = UsdGeom.Mesh.Define(stage, path)
    cx, cy = center
    m.CreatePointsAttr([Gf.Vec3f(cx - half, cy - half, z), Gf.Vec3f(cx + half, cy - half, z),
                        Gf.Vec3f(cx + half, cy + half, z), Gf.Vec3f(cx - half, cy + half, z)])
    m.CreateFaceVertexCountsAttr([4])
    m.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    m.CreateSubdivisionSchemeAttr("none")
    m.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([Gf.Vec3f(*color)])
    return m


def stroke(stage, path, a, b, color, opacity, width=0.6, z=0.5):
    c = UsdGeom.BasisCurves.Define(stage, path)
    c.CreateTypeAttr("linear")
    c.CreateCurveVertexCountsAttr([2])
    c.CreatePointsAttr([Gf.Vec3f(a[0], a[1], z), Gf.Vec3f(b[0], b[1], z)])
    c.CreateWidthsAttr([width])
    c.SetWidthsInterpolation(UsdGeom.Tokens.constant)
    c.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([Gf.Vec3f(*color)])
    c.CreateDisplayOpacityPrimvar(UsdGeom.Tokens.constant).Set([opacity])
    return c


def pixel(stage_path, world, time=1):
    """(column, row) of a world point, by usd-core's frustum (square pixels: keep the horizontal extent)."""
    stage = Usd.Stage.Open(str(stage_path))
    frustum = UsdGeom.Camera(stage.GetPrimAtPath("/Cam")).GetCamera(time).frustum
    win = frustum.window
    cy = 0.5 * (win.min[1] + win.max[1])
    half = 0.5 * (win.max[0] - win.min[0]) * H / W
    frustum.window = Gf.Range2d(Gf.Vec2d(win.min[0], cy - half), Gf.Vec2d(win.max[0], cy + half))
    ndc = (frustum.ComputeViewMatrix() * frustum.ComputeProjectionMatrix()).Transform(Gf.Vec3d(*world))
    return int((ndc[0] + 1) / 2 * W), int((1 - ndc[1]) / 2 * H)


def render(painterly, stage_path, out_dir, frames="1", *extra):
    painterly("render", stage_path, "--camera", "/Cam", "--frames", frames, "-o", out_dir / "f.####.exr",
              "--size", f"{W}x{H}", "--png", *extra)


# Four flat quads and two strokes: colours, opacity, visibility and purpose.
RED = (0.8, 0.1, 0.1)
GREEN = (0.1, 0.7, 0.2)
BLUE_STROKE = (0.1, 0.2, 0.9)
YELLOW_STROKE = (0.9, 0.8, 0.1)


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "scene.usda"
    stage = new_stage(path, end=2)
    quad(stage, "/Red", (-2.0, 1.0), 0.8, RED)
    quad(stage, "/Green", (2.0, 1.0), 0.8, GREEN)
    # Hidden: an invisible quad; a guide under a render-purpose-less Xform;
    # a stroke whose parent is invisible; a quad invisible only at frame 2.
    hidden = quad(stage, "/Hidden", (0.0, 1.0), 0.8, (1, 1, 1))
    hidden.CreateVisibilityAttr(UsdGeom.Tokens.invisible)
    UsdGeom.Xform.Define(stage, "/Guides").CreatePurposeAttr(UsdGeom.Tokens.guide)
    quad(stage, "/Guides/Quad", (0.0, -1.8), 0.6, (1, 1, 1))
    UsdGeom.Xform.Define(stage, "/Off").CreateVisibilityAttr(UsdGeom.Tokens.invisible)
    stroke(stage, "/Off/Stroke", (-3.0, -1.8), (-1.0, -1.8), (1, 1, 1), 1.0)
    blink = quad(stage, "/Blink", (2.0, -1.8), 0.6, GREEN)
    vis = blink.CreateVisibilityAttr()
    vis.Set(UsdGeom.Tokens.inherited, 1)
    vis.Set(UsdGeom.Tokens.invisible, 2)
    # A half-opaque blue stroke on nothing; a 40 % yellow stroke over the red quad.
    stroke(stage, "/Blue", (-3.0, -0.6), (3.0, -0.6), BLUE_STROKE, 0.5)
    stroke(stage, "/Yellow", (-2.6, 1.0), (-1.4, 1.0), YELLOW_STROKE, 0.4)
    stage.GetRootLayer().Save()
    return path


def test_colours_opacity_visibility_and_purpose(painterly, tmp_path, scene):
    render(painterly, scene, tmp_path, "1:2")
    exr = read_exr(tmp_path / "f.0001.exr")
    rgb = np.stack([exr["R"], exr["G"], exr["B"]], axis=-1)
    a = exr["A"]
    facing = (0.0, 0.0, 1.0)  # every quad faces the camera

    def at(world):
        x, y = pixel(scene, world)
        return rgb[y, x], a[y, x]

    # Meshes: opaque, warm/cool shaded from their displayColor.
    for centre, colour in [((-2.0, 1.5), RED), ((2.0, 1.0), GREEN)]:
        c, alpha = at((*centre, 0.0))
        assert alpha == pytest.approx(1.0)
        np.testing.assert_allclose(c, warm_cool(colour, facing), atol=2e-3)
    # A stroke on nothing: premultiplied colour × opacity, alpha = opacity.
    c, alpha = at((0.0, -0.6, 0.5))
    assert alpha == pytest.approx(0.5, abs=2e-3)
    np.testing.assert_allclose(c, 0.5 * np.array(BLUE_STROKE), atol=2e-3)
    # A stroke over a mesh: α·c + (1 − α)·mesh.
    c, alpha = at((-2.0, 1.0, 0.5))
    assert alpha == pytest.approx(1.0)
    np.testing.assert_allclose(c, 0.4 * np.array(YELLOW_STROKE) + 0.6 * warm_cool(RED, facing), atol=2e-3)
    # Nothing hidden is drawn: invisible prims, guides, children of invisible prims.
    for hidden in [(0.0, 1.0, 0.0), (0.0, -1.8, 0.0), (-2.0, -1.8, 0.5)]:
        c, alpha = at(hidden)
        assert alpha == 0.0 and not c.any(), hidden
    # Time-sampled visibility: drawn at frame 1, gone at frame 2.
    assert at((2.0, -1.8, 0.0))[1] == pytest.approx(1.0)
    second = read_exr(tmp_path / "f.0002.exr")
    x, y = pixel(scene, (2.0, -1.8, 0.0), time=2)
    assert second["A"][y, x] == 0.0
    # The sRGB PNG says the same (straight alpha, sRGB transfer).
    png = np.asarray(Image.open(tmp_path / "f.0001.png").convert("RGBA"), dtype=float) / 255
    x, y = pixel(scene, (2.0, 1.0, 0.0))
    expected = warm_cool(GREEN, facing)
    srgb = np.where(expected <= 0.0031308, 12.92 * expected, 1.055 * expected ** (1 / 2.4) - 0.055)
    np.testing.assert_allclose(png[y, x, :3], srgb, atol=1.5 / 255)
    assert png[y, x, 3] == 1.0


def test_per_face_colours_and_widths_under_a_scaled_parent(painterly, tmp_path):
    """A uniform displayColor gives each face its own colour; a stroke's width scales with its transform."""
    path = tmp_path / "faces.usda"
    stage = new_stage(path)
    m = UsdGeom.Mesh.Define(stage, "/TwoFaces")
    m.CreatePointsAttr([Gf.Vec3f(x, y, 0) for x, y in [(-3, 0.5), (-2, 0.5), (-1, 0.5), (-3, 1.5), (-2, 1.5), (-1, 1.5)]])
    m.CreateFaceVertexCountsAttr([4, 4])
    m.CreateFaceVertexIndicesAttr([0, 1, 4, 3, 1, 2, 5, 4])
    m.CreateSubdivisionSchemeAttr("none")
    m.CreateDisplayColorPrimvar(UsdGeom.Tokens.uniform).Set([Gf.Vec3f(*RED), Gf.Vec3f(*GREEN)])
    # Width 0.3 under a parent scaled ×2: 0.6 wide in the world, as UsdGeom
    # widths are in the prim's own space.
    UsdGeom.Xform.Define(stage, "/Big").AddScaleOp().Set(Gf.Vec3f(2, 2, 2))
    stroke(stage, "/Big/Stroke", (0.25, -0.5), (1.5, -0.5), BLUE_STROKE, 1.0, width=0.3, z=0.0)
    stage.GetRootLayer().Save()
    render(painterly, path, tmp_path)
    exr = read_exr(tmp_path / "f.0001.exr")
    rgb = np.stack([exr["R"], exr["G"], exr["B"]], axis=-1)
    facing = (0.0, 0.0, 1.0)
    for centre, colour in [((-2.5, 1.0, 0.0), RED), ((-1.5, 1.0, 0.0), GREEN)]:
        x, y = pixel(path, centre)
        np.testing.assert_allclose(rgb[y, x], warm_cool(colour, facing), atol=2e-3)
    # The stroke runs along y = -1 from x = 0.5 to 3 (world); half its width is 0.3.
    # A pixel is about 0.03 units here.
    alpha = exr["A"]
    for off, covered in [(0.0, True), (0.2, True), (-0.2, True), (0.4, False), (-0.4, False)]:
        x, y = pixel(path, (1.75, -1.0 + off, 0.0))
        assert (alpha[y, x] > 0.5) == covered, (off, alpha[y, x])


@pytest.mark.parametrize(
    "field,value",
    [("timeCodesPerSecond", 0.0), ("framesPerSecond", -24.0), ("startTimeCode", float("inf")), ("endTimeCode", float("nan"))],
)
def test_a_scene_without_strokes_with_bad_timing_is_refused(painterly, tmp_path, field, value):
    """The render's root layer copies the input's timing: bad timing is named, not written."""
    path = tmp_path / "plain.usda"
    stage = new_stage(path)
    quad(stage, "/Red", (0.0, 0.0), 0.8, RED)
    stage.GetRootLayer().Save()
    layer = Sdf.Layer.FindOrOpen(str(path))
    # Authored, else timeCodesPerSecond falls back to framesPerSecond (USD's rule).
    layer.timeCodesPerSecond = 24.0
    setattr(layer, field, value)
    layer.Save()
    out = tmp_path / "out"
    out.mkdir()
    proc = painterly("render", path, "--camera", "/Cam", "--frames", "1", "-o", out / "f.####.exr",
                     "--size", "20x16", check=False)
    assert proc.returncode == 1, proc.stderr
    assert "plain.usda" in proc.stderr and field in proc.stderr, proc.stderr
    assert not any(out.iterdir())


@pytest.mark.parametrize("camera, what", [
    ("/Cam.focalLength", "is a property path, not a prim path"),
    ("/Cam.no:such:attr", "is a property path, not a prim path"),
    ("/Cam{v=x}", "is a variant selection path, not a prim path"),
    ("Cam", "is a relative path, not an absolute prim path"),
])
def test_a_camera_path_that_is_not_a_prim_path_is_a_usage_error(painterly, tmp_path, scene, repo_root, camera, what):
    """usd-core's GetPrimAtPath finds no prim at a property, variant or
    relative path: --camera there is refused (exit 2), not read as /Cam. The
    scene without a rig is rendered without a bake; blowfish is baked first."""
    stage = Usd.Stage.Open(str(scene))
    assert stage.GetPrimAtPath("/Cam") and not stage.GetPrimAtPath(camera)
    for path, cam in [(scene, camera), (repo_root / "fixtures" / "blowfish.usda", camera.replace("Cam", "Blowfish/Camera", 1))]:
        out = tmp_path / "out"
        out.mkdir(exist_ok=True)
        proc = painterly("render", path, "--camera", cam, "--frames", "1", "-o", out / "f.####.exr",
                         "--size", "20x16", check=False)
        assert proc.returncode == 2, proc.stderr
        assert f"--camera {cam} {what}" in proc.stderr, proc.stderr
        assert not any(out.iterdir())


def test_a_sheet_of_more_than_2000_frames_is_refused_up_front(painterly, tmp_path, scene):
    """README, Limits: the sheet holds every thumbnail until it is written, so its frames are capped."""
    out = tmp_path / "out"
    out.mkdir()
    proc = painterly("render", scene, "--camera", "/Cam", "--frames", "1:2001", "-o", out / "f.####.exr",
                     "--sheet", check=False)
    assert proc.returncode == 2
    assert proc.stderr == ("error: --sheet lays out at most 2000 frames, not 2001: use a coarser --frames step, "
                           "or render without --sheet\n")
    assert proc.stdout == "" and not any(out.iterdir())
    # Without --sheet the same range is not refused for its length (here it
    # fails later, on the one-frame output name, which shows the check passed).
    proc = painterly("render", scene, "--camera", "/Cam", "--frames", "1:2001", "-o", out / "f.exr", check=False)
    assert proc.returncode == 2 and "2001 frames would all write one file" in proc.stderr


def test_frames_that_would_share_a_file_name_are_refused(painterly, tmp_path, scene):
    """Frame names keep three decimals (README, render): 1.0004 would be
    written as frame 1 and replace it."""
    out = tmp_path / "out"
    out.mkdir()
    proc = painterly("render", scene, "--camera", "/Cam", "--frames", "1:1.0012:0.0004", "-o",
                     out / "f.####.exr", check=False)
    assert proc.returncode == 2
    assert proc.stderr == (f"error: frames 1 and 1.0004 would both write {out / 'f.0001.exr'}: frame names keep "
                           "three decimals, use a coarser --frames step\n")
    assert proc.stdout == "" and not any(out.iterdir())
    # A millisecond apart is two names.
    proc = painterly("render", scene, "--camera", "/Cam", "--frames", "1:1.002:0.001", "-o",
                     out / "f.####.exr", "--size", "32x24", "--quiet")
    assert sorted(p.name for p in out.iterdir()) == ["f.0001.001.exr", "f.0001.002.exr", "f.0001.exr"]


def png_claiming(path, width, height):
    """A valid 1-bit grayscale PNG of `width` × `height`, all white. Its
    rows compress to almost nothing, so the file stays small whatever size
    its header says (PNG spec: signature, IHDR, IDAT, IEND; each chunk is
    length, type, data, CRC-32 of type and data)."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    row = b"\x00" + b"\xff" * ((width + 7) // 8)  # filter type 0, then the row's bits
    z = zlib.compressobj(9)
    data = b"".join(z.compress(row) for _ in range(height)) + z.flush()
    ihdr = struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0)  # 1 bit, grayscale
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", data) + chunk(b"IEND", b""))
    return path


def limit_memory(nbytes):
    """preexec_fn: caps the child's address space, so a regression that
    decodes a huge brush fails to allocate instead of taking the machine."""
    return lambda: resource.setrlimit(resource.RLIMIT_AS, (nbytes, nbytes))


def test_a_brush_larger_than_the_limit_is_refused_before_decoding(tmp_path, scene):
    """README, Limits: a brush PNG is at most 4096 x 4096. An 80 KB file
    whose header says 20000 x 20000 (decoded, 1.6 GB as floats) is refused
    from its header, exit 1, naming the file, its size and the limit; one
    at the limit renders."""
    out = tmp_path / "out"
    out.mkdir()
    huge = png_claiming(tmp_path / "huge.png", 20000, 20000)
    assert huge.stat().st_size < 200_000
    args = [str(painterly_binary()), "render", str(scene), "--camera", "/Cam", "--frames", "1", "-o",
            str(out / "f.####.exr"), "--size", "32x24"]
    proc = subprocess.run([*args, "--brush", str(huge)], capture_output=True, text=True, timeout=120,
                          preexec_fn=limit_memory(1 << 30))
    assert proc.returncode == 1, proc.stderr[-2000:]
    assert proc.stderr == (f"error: {huge}: brush PNG is 20000 x 20000 pixels; painterly reads brushes of at most "
                           "4096 x 4096 (scale the footprint down)\n")
    assert proc.stdout == "" and not any(out.iterdir())
    # At the limit (4096 on a side): read, and the frame is drawn.
    edge = png_claiming(tmp_path / "edge.png", 4096, 16)
    proc = subprocess.run([*args, "--brush", str(edge), "--quiet"], capture_output=True, text=True, timeout=120,
                          preexec_fn=limit_memory(1 << 30))
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(p.name for p in out.iterdir()) == ["f.0001.exr"]


def test_a_frame_number_a_file_name_cannot_hold_exactly_is_refused(painterly, tmp_path, scene):
    """A frame's whole number is written into its file name (and sheet
    label) as a 64-bit integer: 1e19 was written as
    f.9223372036854775807.exr, the largest such integer, with exit 0. It is
    refused as a usage error, as the other --frames checks are; the largest
    double below 2^63 is still named digit for digit."""
    out = tmp_path / "out"
    out.mkdir()
    for frame, shown in [("1e19", "10000000000000000000"), ("-9223372036854775808", "-9223372036854775808")]:
        proc = painterly("render", scene, "--camera", "/Cam", "--frames", frame, "-o", out / "f.####.exr",
                         "--size", "32x24", check=False)
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr == (f"error: frame {shown} cannot be written in a file name: painterly numbers frames "
                               "from -9223372036854775807 to 9223372036854775807\n")
        assert proc.stdout == "" and not any(out.iterdir())
    top = 2**63 - 1024  # the largest double below 2^63, an integer
    painterly("render", scene, "--camera", "/Cam", "--frames", str(top), "-o", out / "f.####.exr",
              "--size", "32x24", "--quiet")
    assert [p.name for p in out.iterdir()] == [f"f.{top}.exr"]


def test_a_scene_at_48_time_codes_per_second_renders_its_own_times(painterly, tmp_path):
    """The render's root layer must keep the input's timeCodesPerSecond, or
    USD retimes the input (a sublayer's times scale by the rates' ratio)."""
    path = tmp_path / "fast.usda"
    stage = new_stage(path, end=20)
    stage.SetTimeCodesPerSecond(48)
    stage.SetFramesPerSecond(48)
    q = quad(stage, "/Mover", (0.0, 0.0), 0.5, GREEN)
    op = q.AddTranslateOp()
    for t, x in [(1, -2.0), (10, 2.0), (20, -2.0)]:
        op.Set(Gf.Vec3d(x, 0, 0), t)
    stage.GetRootLayer().Save()
    render(painterly, path, tmp_path, "10")
    alpha = read_exr(tmp_path / "f.0010.exr")["A"]
    # At time 10 the quad sits at x = 2; retimed by ×2 or ×½ it would be at
    # x = -2 (time 20) or near x = -0.2 (time 5).
    at = lambda x: alpha[pixel(path, (x, 0.0, 0.0), time=10)[::-1]]  # noqa: E731
    assert at(2.0) == pytest.approx(1.0)
    assert at(-2.0) == 0.0 and at(-0.2) == 0.0


def test_render_json_counts_prims_and_drawn_elements(painterly, tmp_path, scene):
    """curves/meshes count the prims found (guides excluded, visibility is per
    frame); strokes/triangles the most drawn in one frame."""
    proc = painterly("render", scene, "--camera", "/Cam", "--frames", "1:2", "-o", tmp_path / "j.####.exr",
                     "--size", "40x32", "--json")
    summary = json.loads(proc.stdout)
    # BasisCurves /Off/Stroke, /Blue, /Yellow; Mesh /Red, /Green, /Hidden, /Blink.
    assert (summary["curves"], summary["meshes"]) == (3, 4)
    # Frame 1 draws /Blue and /Yellow, and the quads /Red, /Green, /Blink (2 triangles each).
    assert (summary["strokes"], summary["triangles"]) == (2, 6)


def flat_or_smooth_book(path, scheme):
    """Two quads meeting at x = 0: A flat in z = 0, B turned 45° about y."""
    stage = new_stage(path)
    m = UsdGeom.Mesh.Define(stage, "/Book")
    m.CreatePointsAttr([Gf.Vec3f(*p) for p in [(-2, -1, 0), (0, -1, 0), (0, 1, 0), (-2, 1, 0), (1.4, -1, 1.4), (1.4, 1, 1.4)]])
    m.CreateFaceVertexCountsAttr([4, 4])
    m.CreateFaceVertexIndicesAttr([0, 1, 2, 3, 1, 4, 5, 2])
    if scheme is not None:
        m.CreateSubdivisionSchemeAttr(scheme)
    m.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([Gf.Vec3f(0.6, 0.6, 0.6)])
    stage.GetRootLayer().Save()


def test_subdivision_scheme_none_is_faceted_and_the_fallback_smooth(painterly, tmp_path):
    for scheme in ["none", None]:  # None: unauthored, catmullClark
        path = tmp_path / f"book_{scheme}.usda"
        flat_or_smooth_book(path, scheme)
        out = tmp_path / f"out_{scheme}"
        out.mkdir()
        render(painterly, path, out)
        exr = read_exr(out / "f.0001.exr")
        rgb = np.stack([exr["R"], exr["G"], exr["B"]], axis=-1)
        at = lambda p: rgb[pixel(path, p)[::-1]]  # noqa: E731
        far_a, near_crease_a, b = at((-1.8, 0.0, 0.0)), at((-0.15, 0.0, 0.0)), at((0.7, 0.0, 0.7))
        if scheme == "none":
            np.testing.assert_allclose(far_a, warm_cool((0.6,) * 3, (0, 0, 1)), atol=2e-3)
            np.testing.assert_allclose(near_crease_a, far_a, atol=1e-4)
            np.testing.assert_allclose(b, warm_cool((0.6,) * 3, (-1, 0, 1)), atol=2e-3)
        else:
            # Smooth: the crease's vertex normals lean A's shading towards B's.
            assert np.abs(near_crease_a - far_a).max() > 0.01, (near_crease_a, far_a)


@pytest.mark.parametrize(
    "counts,indices,message",
    [
        ([4], [0, 1, 2], "counts sum to 4, but there are 3 faceVertexIndices"),
        ([-1, 5], [0, 1, 2, 3], "faceVertexCounts: negative count -1"),
        ([4], [0, 1, -2, 3], "negative index -2"),
    ],
)
def test_bad_mesh_topology_is_named(painterly, tmp_path, counts, indices, message):
    path = tmp_path / "bad.usda"
    stage = new_stage(path)
    m = quad(stage, "/Bad", (0.0, 0.0), 0.8, RED)
    m.GetFaceVertexCountsAttr().Set(counts)
    m.GetFaceVertexIndicesAttr().Set(indices)
    stage.GetRootLayer().Save()
    out = tmp_path / "out"
    out.mkdir()
    proc = painterly("render", path, "--camera", "/Cam", "--frames", "1", "-o", out / "f.####.exr",
                     "--size", "20x16", check=False)
    assert proc.returncode == 1, proc.stderr
    assert "bad.usda" in proc.stderr and "/Bad" in proc.stderr and message in proc.stderr, proc.stderr
    assert not any(out.iterdir())


def test_empty_faces_and_curves_are_skipped(painterly, tmp_path):
    """A face of 0 vertices and a curve of 0 points are legal and draw nothing;
    a negative curve count is named."""
    path = tmp_path / "empty.usda"
    stage = new_stage(path)
    m = quad(stage, "/Quad", (0.0, 0.0), 0.8, RED)
    m.GetFaceVertexCountsAttr().Set([0, 4])
    c = stroke(stage, "/Stroke", (-1.0, -1.5), (1.0, -1.5), BLUE_STROKE, 1.0)
    c.GetCurveVertexCountsAttr().Set([0, 2])
    stage.GetRootLayer().Save()
    render(painterly, path, tmp_path)
    alpha = read_exr(tmp_path / "f.0001.exr")["A"]
    assert alpha[pixel(path, (0.0, 0.0, 0.0))[::-1]] == pytest.approx(1.0)
    assert alpha[pixel(path, (0.0, -1.5, 0.5))[::-1]] == pytest.approx(1.0)
    c.GetCurveVertexCountsAttr().Set([-1, 3])
    stage.GetRootLayer().Save()
    proc = painterly("render", path, "--camera", "/Cam", "--frames", "1", "-o", tmp_path / "g.####.exr",
                     "--size", "20x16", check=False)
    assert proc.returncode == 1
    assert "/Stroke" in proc.stderr and "curveVertexCounts" in proc.stderr and "negative count -1" in proc.stderr


@pytest.mark.parametrize("value_type", ["double2", "half2"])
def test_a_clipping_range_of_another_precision_is_honoured(painterly, tmp_path, value_type):
    """clippingRange is float2 in the schema; double2 and half2 opinions are read too."""
    path = tmp_path / "clip.usda"
    stage = new_stage(path)
    UsdGeom.Camera(stage.GetPrimAtPath("/Cam")).GetClippingRangeAttr().Set(Gf.Vec2f(0.5, 14.5))
    quad(stage, "/Near", (-1.5, 0.0), 0.8, RED, z=1.0)  # depth 14: inside
    quad(stage, "/Far", (1.5, 0.0), 0.8, GREEN, z=-1.0)  # depth 16: beyond far
    stage.GetRootLayer().Save()
    # usd-core authors the schema's float2 whatever type is asked for: edit the text.
    text = path.read_text()
    assert text.count("float2 clippingRange = (0.5, 14.5)") == 1
    path.write_text(text.replace("float2 clippingRange", f"{value_type} clippingRange"))
    render(painterly, path, tmp_path)
    alpha = read_exr(tmp_path / "f.0001.exr")["A"]
    assert alpha[pixel(path, (-1.5, 0.0, 1.0))[::-1]] == pytest.approx(1.0)
    assert alpha[pixel(path, (1.5, 0.0, -1.0))[::-1]] == 0.0


@pytest.mark.parametrize("double_sided", [True, False, None])
def test_back_faces_are_drawn_only_when_double_sided(painterly, tmp_path, double_sided):
    path = tmp_path / "back.usda"
    stage = new_stage(path)
    m = quad(stage, "/Away", (0.0, 0.0), 0.8, RED)
    m.GetFaceVertexIndicesAttr().Set([0, 3, 2, 1])  # clockwise as seen: facing away
    if double_sided is not None:
        m.CreateDoubleSidedAttr(double_sided)
    stage.GetRootLayer().Save()
    render(painterly, path, tmp_path)
    alpha = read_exr(tmp_path / "f.0001.exr")["A"]
    assert alpha[pixel(path, (0.0, 0.0, 0.0))[::-1]] == (1.0 if double_sided else 0.0)


@pytest.mark.parametrize("scale", [(-1, 1, 1), (1, 1, 0)])
def test_mirrored_and_flattened_transforms_keep_front_faces(painterly, tmp_path, scale):
    """A mirroring transform (det < 0) flips the winding, so the quad still
    faces the camera; a flattening one (det = 0) does not flip it."""
    path = tmp_path / "mirror.usda"
    stage = new_stage(path)
    UsdGeom.Xform.Define(stage, "/M").AddScaleOp().Set(Gf.Vec3f(*scale))
    quad(stage, "/M/Quad", (1.5, 0.0), 0.8, RED)
    stage.GetRootLayer().Save()
    render(painterly, path, tmp_path)
    alpha = read_exr(tmp_path / "f.0001.exr")["A"]
    x = 1.5 * scale[0]
    assert alpha[pixel(path, (x, 0.0, 0.0))[::-1]] == pytest.approx(1.0)
    assert alpha[pixel(path, (-x, 0.0, 0.0))[::-1]] == 0.0


def rotation(rx, ry):
    return Gf.Matrix3d(Gf.Rotation(Gf.Vec3d(1, 0, 0), rx)) * Gf.Matrix3d(Gf.Rotation(Gf.Vec3d(0, 1, 0), ry))


def test_warm_cool_faces_and_silhouette_of_a_cube(painterly, tmp_path):
    """A rotated cube: each visible face shaded by its own normal; its outline drawn dark."""
    path = tmp_path / "cube.usda"
    stage = new_stage(path)
    base = (0.6, 0.6, 0.6)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    faces = {  # outward normal -> corner indices, counter-clockwise seen from outside
        (1, 0, 0): [4, 6, 7, 5], (-1, 0, 0): [0, 1, 3, 2], (0, 1, 0): [2, 3, 7, 6],
        (0, -1, 0): [0, 4, 5, 1], (0, 0, 1): [1, 5, 7, 3], (0, 0, -1): [0, 2, 6, 4],
    }
    m = UsdGeom.Mesh.Define(stage, "/Cube")
    m.CreatePointsAttr(Vt.Vec3fArray([Gf.Vec3f(*c) for c in corners]))
    m.CreateFaceVertexCountsAttr([4] * 6)
    m.CreateFaceVertexIndicesAttr([i for f in faces.values() for i in f])
    m.CreateSubdivisionSchemeAttr("none")
    m.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([Gf.Vec3f(*base)])
    rot = m.AddRotateXYZOp()
    rot.Set(Gf.Vec3f(25, 35, 0))
    stage.GetRootLayer().Save()
    render(painterly, path, tmp_path)
    exr = read_exr(tmp_path / "f.0001.exr")
    rgb = np.stack([exr["R"], exr["G"], exr["B"]], axis=-1)
    xf = np.array(UsdGeom.Xformable(m).ComputeLocalToWorldTransform(1))  # row vectors: p' = p @ M
    world = corners @ xf[:3, :3] + xf[3, :3]
    seen = 0
    for normal, idx in faces.items():
        n = np.array(normal, float) @ xf[:3, :3]
        centre = world[idx].mean(axis=0)
        to_eye = np.array([0, 0, CAM_Z]) - centre
        if n @ to_eye <= 0.2 * np.linalg.norm(to_eye):
            continue  # back-facing or nearly edge-on
        seen += 1
        x, y = pixel(path, centre)
        # The camera only translates: camera space has world's axes.
        np.testing.assert_allclose(rgb[y, x], warm_cool(base, n), atol=3e-3, err_msg=str(normal))
    assert seen == 3
    # Silhouette: the hull of the projected corners; the middle of each hull
    # edge is dark, a few pixels inside it is not.
    px = np.array([pixel(path, p) for p in world], float)
    hull = ConvexHull(px)
    inside = px[hull.vertices].mean(axis=0)
    alpha = exr["A"]
    for i, j in hull.simplices:
        mid = 0.5 * (px[i] + px[j])
        rows = slice(int(mid[1]) - 1, int(mid[1]) + 2)
        cols = slice(int(mid[0]) - 1, int(mid[0]) + 2)
        a, c = alpha[rows, cols], rgb[rows, cols]
        # Un-premultiplied brightness of the well-covered pixels: the line's
        # (0.07) where it is drawn, a face's (at least 0.8 here) where not.
        straight = c.sum(axis=-1)[a > 0.5] / a[a > 0.5]
        assert straight.size and straight.min() < 0.6, (mid, c, a)
        probe = mid + 6 * (inside - mid) / np.linalg.norm(inside - mid)
        assert rgb[int(probe[1]), int(probe[0])].sum() > 0.8


def test_contact_sheet_grid_and_labels(painterly, tmp_path):
    """Each frame appears once in the sheet, on a grid in frame order, a label under each."""
    path = tmp_path / "sweep.usda"
    frames = 7
    stage = new_stage(path, end=frames)
    c = stroke(stage, "/Sweep", (-3.0, 0.0), (-1.0, 0.0), BLUE_STROKE, 1.0, width=0.8, z=0.0)
    op = UsdGeom.Xformable(c).AddTranslateOp()
    for t in range(1, frames + 1):
        op.Set(Gf.Vec3d(0.6 * (t - 1), 0.4 * ((t - 1) % 3 - 1), 0), t)
    stage.GetRootLayer().Save()
    bg = "#ffffff"
    render(painterly, path, tmp_path, f"1:{frames}", "--sheet", "--background", bg)
    sheet = np.asarray(Image.open(tmp_path / "f.sheet.png").convert("RGB"), dtype=np.int32)
    tiles = [np.asarray(Image.open(tmp_path / f"f.{t:04d}.png").convert("RGB"), dtype=np.int32) for t in range(1, frames + 1)]
    # At this size no reduction applies: each frame is in the sheet pixel for
    # pixel (within one 8-bit step: the sheet and the PNG round separately).
    sh, sw, _ = sheet.shape
    positions = []
    for tile in tiles:
        # Anchor on the tile's first pixel that is not background (a stroke edge).
        ay, ax = np.argwhere((tile < 250).any(axis=-1))[0]
        window = sheet[ay: sh - H + 1 + ay, ax: sw - W + 1 + ax]
        cand = np.argwhere((np.abs(window - tile[ay, ax]) <= 1).all(axis=-1))
        hits = [(int(y), int(x)) for y, x in cand if np.abs(sheet[y: y + H, x: x + W] - tile).max() <= 1]
        assert len(hits) == 1, f"a frame appears {len(hits)} times in the sheet"
        positions.append(hits[0])
    ys = sorted({y for y, _ in positions})
    xs = sorted({x for _, x in positions})
    cols = len(xs)
    assert len(ys) == -(-frames // cols)  # rows
    # Reading order: left to right, then top to bottom, equal spacing.
    assert positions == [(ys[k // cols], xs[k % cols]) for k in range(frames)]
    assert len({b - a for a, b in zip(xs, xs[1:])}) <= 1 and len({b - a for a, b in zip(ys, ys[1:])}) <= 1
    # About 16:10 (docs/render.md): the whole sheet, label bands, gaps and
    # margins included, is the closest to it a column count gives (with 7
    # frames of 200 × 160 no count reduces them). The layout is read off this
    # sheet: the margin before the first frame, the gap between columns, the
    # pitch of the rows (frame, label band, gap).
    assert len(xs) > 1 and len(ys) > 1
    margin, gap, pitch = xs[0], xs[1] - xs[0] - W, ys[1] - ys[0]
    assert ys[0] == margin

    def sheet_size(n):
        return 2 * margin + n * W + (n - 1) * gap, 2 * margin + -(-frames // n) * pitch - gap

    assert sheet_size(cols) == (sw, sh)
    off = {n: abs(np.log(sheet_size(n)[0] / sheet_size(n)[1] / 1.6)) for n in range(1, frames + 1)}
    assert off[cols] <= min(off.values()) + 1e-9, off
    # A label under each frame: ink in the strip below the tile, within its width,
    # and different numbers look different.
    step_y = ys[1] - ys[0] if len(ys) > 1 else sh - ys[0]
    labels = []
    for y, x in positions:
        strip = sheet[y + H: y + step_y, x: x + W]
        ink = (np.abs(strip - 255).sum(axis=-1) > 60)
        assert ink.any(), "no label under a frame"
        labels.append(ink)
    assert len({lab.tobytes() for lab in labels}) == frames



def test_json_reports_a_positive_median_frame_time(painterly, tmp_path, scene):
    """One frame: its own time is the median, so neither 0 nor above the run's total."""
    proc = painterly("render", scene, "--camera", "/Cam", "--frames", "1", "-o", tmp_path / "m.####.exr",
                     "--size", "40x32", "--json")
    summary = json.loads(proc.stdout)
    assert summary["frames"] == 1
    assert 0 < summary["median_frame_seconds"] <= summary["seconds"], summary


@pytest.mark.parametrize("background,dark_ink", [("#ffffff", True), ("#000000", False)])
def test_sheet_labels_are_dark_on_light_backgrounds_and_light_on_dark(painterly, tmp_path, background, dark_ink):
    """Nothing in view: every pixel of the sheet that is not background is label ink."""
    path = tmp_path / "nothing.usda"
    stage = new_stage(path, end=2)
    stage.GetRootLayer().Save()
    painterly("render", path, "--camera", "/Cam", "--frames", "1:2", "-o", tmp_path / "f.####.exr",
              "--size", "64x40", "--sheet", "--background", background)
    sheet = np.asarray(Image.open(tmp_path / "f.sheet.png").convert("L"), dtype=int)
    bg = 255 if dark_ink else 0
    ink = sheet[sheet != bg]
    assert ink.size > 0, "no label drawn"
    if dark_ink:
        assert ink.min() < 100, ink.min()
    else:
        assert ink.max() > 150, ink.max()


CYCLE = 'def "A" (inherits = </B>) {}\ndef "B" (inherits = </A>) {}\n'


def render_over_bake(painterly, tmp_path, input_prims, bake_prims):
    """`render --bake` of a one-frame scene with camera /Cam: the input holds
    `input_prims`, the bake layer `bake_prims` under the provenance
    `painterly bake` records (customLayerData["painterly"])."""
    path = tmp_path / "scene.usda"
    path.write_text('#usda 1.0\n(\n    startTimeCode = 1\n    endTimeCode = 1\n)\n\ndef Camera "Cam" {}\n' + input_prims)
    bake = tmp_path / "bake.usda"
    bake.write_text('#usda 1.0\n(\n    customLayerData = {\n        dictionary painterly = {\n'
                    f'            string frames = "1:1:1"\n            string input = "{path.resolve()}"\n'
                    '        }\n    }\n)\n\n' + bake_prims)
    proc = painterly("render", path, "--bake", bake, "--camera", "/Cam", "--frames", "1", "-o",
                     tmp_path / "f.####.exr", "--size", "20x16", check=False)
    return path, bake, proc


def test_errors_composing_the_input_name_the_input_not_the_root_layer(painterly, tmp_path):
    """With --bake the input is first composed under the render's temporary
    root layer; an error there names the input."""
    path, _, proc = render_over_bake(painterly, tmp_path, CYCLE, "")
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.startswith(f"error: {path}: ") and "cycle" in proc.stderr, proc.stderr
    assert "render_root" not in proc.stderr


def test_errors_in_the_bake_layer_name_the_bake_not_the_input(painterly, tmp_path):
    """Only errors of the temporary root (or of no file) become the input's:
    a cycle in the `--bake` layer is the bake's to fix, and named so."""
    _, bake, proc = render_over_bake(painterly, tmp_path, "", CYCLE)
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr.startswith(f"error: {bake.resolve()}: ") and "cycle" in proc.stderr, proc.stderr


CURVE = ('def BasisCurves "C" {\n    int[] curveVertexCounts = [2]\n'
         '    point3f[] points = [(0, 0, -5), (1, 0, -5)]\n    uniform token type = "linear"\n}\n')
NAN_POINTS = 'point3f[] points.timeSamples = { 1: [(0, 0, -5), (nan, 0, -5)] }'


def test_a_bad_value_the_bake_layer_gives_names_the_bake(painterly, tmp_path):
    """A value read from the `--bake` layer (its opinion is the strongest at
    that time) is the bake's to fix: the error names the bake's file."""
    _, bake, proc = render_over_bake(painterly, tmp_path, CURVE, f'over "C" {{\n    {NAN_POINTS}\n}}\n')
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr == f"error: {bake.resolve()}: /C.points: point 1 is not finite at time 1\n"


def test_a_bad_value_the_input_gives_names_the_input_under_a_bake(painterly, tmp_path):
    """The same bad value in the input, under a bake with no opinion on it,
    is the input's."""
    curve = CURVE.replace('point3f[] points = [(0, 0, -5), (1, 0, -5)]', NAN_POINTS)
    path, _, proc = render_over_bake(painterly, tmp_path, curve, 'over "D" {}\n')
    assert proc.returncode == 1, proc.stderr
    assert proc.stderr == f"error: {path}: /C.points: point 1 is not finite at time 1\n"


def test_a_scene_without_a_time_range_is_baked_for_the_frames_asked(painterly, tmp_path, repo_root):
    """No startTimeCode/endTimeCode: the bake on the fly takes --frames, and
    matches a bake given the same frames."""
    wrapper = tmp_path / "fish_untimed.usda"
    stage = Usd.Stage.CreateNew(str(wrapper))
    stage.GetRootLayer().subLayerPaths.append(str(repo_root / "fixtures" / "blowfish.usda"))
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.CreateFocalLengthAttr(35.0)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.1, 1000))
    UsdGeom.Xformable(cam).AddTranslateOp().Set(Gf.Vec3d(-0.9, 4.2, 40))
    stage.GetRootLayer().Save()
    assert not Sdf.Layer.FindOrOpen(str(wrapper)).HasStartTimeCode()
    a_dir, b_dir = tmp_path / "a", tmp_path / "b"
    a_dir.mkdir()
    b_dir.mkdir()
    render(painterly, wrapper, a_dir, "24")
    painterly("bake", wrapper, "-o", tmp_path / "bake.usdc", "--frames", "24")
    render(painterly, wrapper, b_dir, "24", "--bake", tmp_path / "bake.usdc")
    a, b = read_exr(a_dir / "f.0024.exr"), read_exr(b_dir / "f.0024.exr")
    assert a["A"].sum() > 50, "the fish is in view"
    for c in "RGBAZ":
        np.testing.assert_array_equal(a[c], b[c])


def test_progress_bar_on_a_terminal_unless_quiet(tmp_path, scene):
    args = ["render", scene, "--camera", "/Cam", "--frames", "1:2", "-o", tmp_path / "f.####.exr", "--size", "64x40"]
    code, seen = run_on_pty(args)
    assert code == 0 and "rendering" in seen and re.search(r"\d/2 frames", seen), seen[:500]
    code, seen = run_on_pty([*args, "--quiet"])
    assert (code, seen) == (0, "")


def test_the_bake_on_the_fly_takes_the_render_camera(painterly, tmp_path, repo_root):
    """`render --help`: without --bake the input is baked first with the same
    camera. The building's view-dependent box follows --camera over its own
    painterly:camera: seen from the side (90 degrees from its one key, so the
    base model), not as its own camera (near the key) would show it."""
    wrapper = tmp_path / "building_side.usda"
    stage = Usd.Stage.CreateNew(str(wrapper))
    stage.GetRootLayer().subLayerPaths.append(str(repo_root / "fixtures" / "building.usda"))
    # The box's local +x axis, 3000 units out from its centre, in world space.
    box = UsdGeom.Xformable(stage.GetPrimAtPath("/Building/Box")).ComputeLocalToWorldTransform(1)
    eye, centre = box.Transform(Gf.Vec3d(3000, 500, 0)), box.Transform(Gf.Vec3d(0, 500, 0))
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.CreateFocalLengthAttr(20.0)
    cam.CreateClippingRangeAttr(Gf.Vec2f(1, 100000))
    UsdGeom.Xformable(cam).AddTransformOp().Set(Gf.Matrix4d().SetLookAt(eye, centre, Gf.Vec3d(0, 1, 0)).GetInverse())
    stage.GetRootLayer().Save()
    dirs = {name: tmp_path / name for name in ["fly", "cam", "own"]}
    for d in dirs.values():
        d.mkdir()
    render(painterly, wrapper, dirs["fly"])
    painterly("bake", wrapper, "-o", tmp_path / "cam.usdc", "--frames", "1", "--camera", "/Cam")
    render(painterly, wrapper, dirs["cam"], "1", "--bake", tmp_path / "cam.usdc")
    painterly("bake", wrapper, "-o", tmp_path / "own.usdc", "--frames", "1")
    render(painterly, wrapper, dirs["own"], "1", "--bake", tmp_path / "own.usdc")
    fly, cam_bake, own = (read_exr(dirs[n] / "f.0001.exr") for n in ["fly", "cam", "own"])
    assert fly["A"].sum() > 50, "the building is in view"
    for c in "RGBAZ":
        np.testing.assert_array_equal(fly[c], cam_bake[c])
    # Baked for the box's own camera, the box has another outline.
    assert np.abs(fly["A"] - own["A"]).sum() > 50


def readme_sheet_commands():
    """The `painterly render` lines of the README's sh block that follows
    "The contact sheets below are these commands'"."""
    text = (pathlib.Path(__file__).resolve().parent.parent / "README.md").read_text()
    after = text.split("The contact sheets below are these commands'", 1)[1]
    block = after.split("```sh\n", 1)[1].split("```", 1)[0]
    return [line for line in block.splitlines() if line.startswith("painterly render ")]


README_SHEETS = readme_sheet_commands()


@pytest.mark.parametrize("line", README_SHEETS, ids=[shlex.split(s)[2].split("/")[-1] for s in README_SHEETS])
def test_a_committed_contact_sheet_is_what_the_readme_command_renders(painterly, tmp_path, repo_root, line):
    """The README shows docs/figures/render_<name>_sheet.png as the sheet of
    the command above it; a change to what the bake or render gives must
    come with new figures (scripts/render_figures). The apple's had gone
    stale: its Shading layer at frame 33 (light exactly at key light270,
    opacity 1) drew far lighter than that key gives."""
    assert len(README_SHEETS) == 3
    args = [a.replace("/tmp/frames/", f"{tmp_path}/") for a in shlex.split(line)[1:]]
    painterly(*args, "--quiet", cwd=repo_root)
    name = pathlib.Path(args[1]).stem
    got = np.asarray(Image.open(tmp_path / f"{name}.sheet.png").convert("RGB"))
    want = np.asarray(Image.open(repo_root / "docs" / "figures" / f"render_{name}_sheet.png").convert("RGB"))
    assert got.shape == want.shape, f"render_{name}_sheet.png is {want.shape}, the command renders {got.shape}"
    differ = int((got != want).any(axis=2).sum())
    assert differ == 0, f"docs/figures/render_{name}_sheet.png: {differ} pixels differ from today's render (run scripts/render_figures)"


def test_a_brush_that_is_a_fifo_is_refused_not_waited_on(tmp_path, scene):
    """`--brush` on a FIFO blocked in open() until a writer came (an I/O
    review, 2026-12-07); every other file option refuses what is not a
    regular file."""
    fifo = tmp_path / "brush.png"
    os.mkfifo(fifo)
    out = tmp_path / "out"
    out.mkdir()
    proc = subprocess.run([str(painterly_binary()), "render", str(scene), "--camera", "/Cam", "--frames", "1",
                           "-o", str(out / "f.####.exr"), "--size", "32x24", "--brush", str(fifo)],
                          capture_output=True, text=True, timeout=30)
    assert (proc.returncode, proc.stderr) == (1, f"error: {fifo}: cannot open brush: not a regular file (a FIFO, device or socket)\n")
    assert not any(out.iterdir())
