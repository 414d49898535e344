"""Contract tests for `painterly render` (preview EXR/PNG frames).

Pixel predictions come from usd-core's own camera math:
`UsdGeom.Camera(prim).GetCamera(t).frustum`, with the window conformed to
the image aspect by painterly's documented policy (keep the horizontal
extent, vertical = width / aspect around the same centre, CameraUtil's
MatchHorizontally), projected with `Gf.Frustum`'s view and projection
matrices. EXR files are read back with the OpenEXR bindings (an independent
reader), PNGs with Pillow.
"""

import json
import math

import numpy as np
import OpenEXR
import pytest
from PIL import Image
from pxr import Gf, Usd, UsdGeom

W, H = 320, 200


def read_exr(path):
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {k: np.array(v.pixels) for k, v in f.channels().items()}


def author(path, camera=None, strokes=(), meshes=(), camera_type="Camera", start=1, end=1):
    """A stage with a camera at /Cam and linear BasisCurves strokes at /S0, /S1, ..."""
    stage = Usd.Stage.CreateNew(str(path))
    stage.SetStartTimeCode(start)
    stage.SetEndTimeCode(end)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    if camera is not None:
        if camera_type == "Camera":
            cam = UsdGeom.Camera.Define(stage, "/Cam")
            for name, value in camera.get("attrs", {}).items():
                cam.GetPrim().GetAttribute(name).Set(value)
            xf = cam
        else:
            xf = UsdGeom.Xform.Define(stage, "/Cam")
        x = UsdGeom.Xformable(xf)
        x.AddTranslateOp().Set(Gf.Vec3d(*camera.get("translate", (0, 0, 0))))
        x.AddRotateXYZOp().Set(Gf.Vec3f(*camera.get("rotate", (0, 0, 0))))
    for i, s in enumerate(strokes):
        c = UsdGeom.BasisCurves.Define(stage, f"/S{i}")
        c.CreateTypeAttr("linear")
        pts = s["points"]
        c.CreateCurveVertexCountsAttr([len(pts)])
        c.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
        c.CreateWidthsAttr([s.get("width", 0.1)])
        c.SetWidthsInterpolation(UsdGeom.Tokens.constant)
        c.CreateDisplayColorPrimvar(UsdGeom.Tokens.constant).Set([Gf.Vec3f(*s.get("color", (1, 1, 1)))])
        c.CreateDisplayOpacityPrimvar(UsdGeom.Tokens.constant).Set([s.get("opacity", 1.0)])
    for i, m in enumerate(meshes):
        mesh = UsdGeom.Mesh.Define(stage, f"/M{i}")
        mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in m["points"]])
        mesh.CreateFaceVertexCountsAttr(m["counts"])
        mesh.CreateFaceVertexIndicesAttr(m["indices"])
        if "purpose" in m:
            mesh.CreatePurposeAttr(m["purpose"])
    stage.GetRootLayer().Save()
    return path


def predict(stage_path, world_point, time=1, size=(W, H)):
    """Pixel (x, y) and camera depth of a world point, by usd-core's frustum."""
    stage = Usd.Stage.Open(str(stage_path))
    gc = UsdGeom.Camera(stage.GetPrimAtPath("/Cam")).GetCamera(time)
    frustum = gc.frustum
    win = frustum.window
    aspect = size[0] / size[1]
    cy = 0.5 * (win.min[1] + win.max[1])
    half = 0.5 * (win.max[0] - win.min[0]) / aspect
    frustum.window = Gf.Range2d(Gf.Vec2d(win.min[0], cy - half), Gf.Vec2d(win.max[0], cy + half))
    m = frustum.ComputeViewMatrix() * frustum.ComputeProjectionMatrix()
    ndc = m.Transform(Gf.Vec3d(*world_point))
    cam_pt = frustum.ComputeViewMatrix().Transform(Gf.Vec3d(*world_point))
    return ((ndc[0] + 1) / 2 * size[0], (1 - ndc[1]) / 2 * size[1]), -cam_pt[2], gc


def render(painterly, stage, out_dir, *extra, frames="1", name="f.####.exr", size=(W, H), check=True):
    out = out_dir / name
    return painterly(
        "render", stage, "--camera", "/Cam", "--frames", frames, "-o", out, "--size", f"{size[0]}x{size[1]}", *extra,
        check=check,
    )


def centroid(alpha):
    ys, xs = np.mgrid[0 : alpha.shape[0], 0 : alpha.shape[1]]
    total = alpha.sum()
    assert total > 0, "nothing was drawn"
    return (xs + 0.5).ravel() @ alpha.ravel() / total, (ys + 0.5).ravel() @ alpha.ravel() / total


def camera_axes(gc):
    m = gc.transform
    right = Gf.Vec3d(m.GetRow3(0)).GetNormalized()
    up = Gf.Vec3d(m.GetRow3(1)).GetNormalized()
    return right, up


CAMERAS = {
    "perspective_offset": {
        "translate": (1.5, -0.5, 12.0),
        "rotate": (4.0, 6.0, 3.0),
        "attrs": {
            "focalLength": 42.0,
            "horizontalAperture": 24.0,
            "verticalAperture": 20.0,  # aspect 1.2, image 1.6: conform applies
            "horizontalApertureOffset": 1.3,
            "verticalApertureOffset": -0.8,
            "clippingRange": Gf.Vec2f(0.5, 500.0),
        },
    },
    "orthographic": {
        "translate": (0.3, 0.2, 20.0),
        "rotate": (2.0, 3.0, 0.0),
        "attrs": {
            "projection": "orthographic",
            "horizontalAperture": 100.0,
            "verticalAperture": 40.0,
            "verticalApertureOffset": 2.0,
            "clippingRange": Gf.Vec2f(0.1, 100.0),
        },
    },
}


@pytest.mark.parametrize("cam_name", sorted(CAMERAS))
@pytest.mark.parametrize("target", [(0.4, 0.3, 0.0), (-1.2, 0.9, -2.0)])
def test_point_lands_where_usd_core_projects_it(painterly, tmp_path, cam_name, target):
    cam = CAMERAS[cam_name]
    probe = author(tmp_path / "probe.usda", camera=cam)
    (px, py), depth, gc = predict(probe, target)
    assert 20 < px < W - 20 and 20 < py < H - 20, "test point must be well inside the frame"
    right, _ = camera_axes(gc)
    # A short stroke across the view, centred on the target, at one depth.
    d = 0.02 * depth if cam_name != "orthographic" else 0.05
    a = Gf.Vec3d(*target) - right * d
    b = Gf.Vec3d(*target) + right * d
    stage = author(tmp_path / "s.usda", camera=cam, strokes=[{"points": [tuple(a), tuple(b)], "width": d}])
    render(painterly, stage, tmp_path)
    exr = read_exr(tmp_path / "f.0001.exr")
    cx, cy = centroid(exr["A"])
    assert abs(cx - px) < 0.15 and abs(cy - py) < 0.15, f"centroid {(cx, cy)} vs usd-core {(px, py)}"
    # Z holds the camera depth of the stroke.
    iy, ix = int(py), int(px)
    assert exr["Z"][iy, ix] == pytest.approx(depth, rel=1e-4)
    assert math.isinf(exr["Z"][0, 0])


def test_stroke_covers_width_times_length(painterly, tmp_path):
    cam = {"translate": (0, 0, 10), "attrs": {"focalLength": 35.0, "clippingRange": Gf.Vec2f(0.1, 100)}}
    width, opacity = 0.15, 0.8
    a, b = (-1.6, -0.7, 0.0), (1.4, 0.9, 0.0)
    stage = author(tmp_path / "s.usda", camera=cam, strokes=[{"points": [a, b], "width": width, "opacity": opacity}])
    (pa, _, _), (pb, _, _) = predict(stage, a), predict(stage, b)
    length_px = math.dist(pa, pb)
    world_len = math.dist(a, b)
    width_px = width * length_px / world_len  # both ends at the same depth
    render(painterly, stage, tmp_path)
    alpha = read_exr(tmp_path / "f.0001.exr")["A"]
    area = alpha.sum() / opacity
    expected = width_px * length_px
    assert width_px > 5 and abs(area - expected) / expected < 0.02, (area, expected)
    assert alpha.max() == pytest.approx(opacity, abs=1e-5)


def conformed_view_projection(stage_path, size, time=1):
    """usd-core's frustum for /Cam, conformed as predict() does: the view
    matrix and the world-to-pixel function."""
    stage = Usd.Stage.Open(str(stage_path))
    return conformed_view_projection_of(UsdGeom.Camera(stage.GetPrimAtPath("/Cam")).GetCamera(time).frustum, size)


def conformed_view_projection_of(frustum, size):
    """conformed_view_projection() of a Gf.Frustum."""
    frustum = Gf.Frustum(frustum)
    win = frustum.window
    cy = 0.5 * (win.min[1] + win.max[1])
    half = 0.5 * (win.max[0] - win.min[0]) / (size[0] / size[1])
    frustum.window = Gf.Range2d(Gf.Vec2d(win.min[0], cy - half), Gf.Vec2d(win.max[0], cy + half))
    view = frustum.ComputeViewMatrix()
    m = view * frustum.ComputeProjectionMatrix()

    def pixel(p):
        ndc = m.Transform(Gf.Vec3d(*p))
        return (ndc[0] + 1) / 2 * size[0], (1 - ndc[1]) / 2 * size[1]

    return view, pixel


def test_a_receding_stroke_is_interpolated_perspective_correctly(painterly, tmp_path):
    """A stroke from 5 to 100 units in front of a perspective camera, in
    front of a wall 20 units away, red at its near end and green at its far
    end. Each pixel column sees the point of the stroke where the ray
    through its centre meets it (found with usd-core's frustum, by
    bisection along the segment): the stroke is drawn over the wall exactly
    where that point is nearer than 20, Z is its depth, and its colour is
    the mix at that point of the segment. Depth interpolated linearly on
    screen put the stroke behind the wall where it is 6 to 18 units away."""
    size = (256, 191)  # odd height: the centre row's centres lie on y = 0
    row = size[1] // 2
    near_end, far_end = (0.5, 0.0, -5.0), (0.5, 0.0, -100.0)
    wall = {"points": [(-20, -20, -20), (20, -20, -20), (20, 20, -20), (-20, 20, -20)],
            "counts": [4], "indices": [0, 1, 2, 3]}
    cam = {"translate": (0, 0, 0), "attrs": {"clippingRange": Gf.Vec2f(1, 1000)}}
    path = author(tmp_path / "s.usda", camera=cam, meshes=[wall])
    stage = Usd.Stage.Open(str(path))
    c = UsdGeom.BasisCurves.Define(stage, "/Receding")
    c.CreateTypeAttr("linear")
    c.CreateCurveVertexCountsAttr([2])
    c.CreatePointsAttr([Gf.Vec3f(*near_end), Gf.Vec3f(*far_end)])
    c.CreateWidthsAttr([0.2])
    c.SetWidthsInterpolation(UsdGeom.Tokens.constant)
    c.CreateDisplayColorPrimvar(UsdGeom.Tokens.vertex).Set([Gf.Vec3f(1, 0, 0), Gf.Vec3f(0, 1, 0)])
    stage.GetRootLayer().Save()
    render(painterly, path, tmp_path, size=size)
    exr = read_exr(tmp_path / "f.0001.exr")

    view, pixel = conformed_view_projection(path, size)
    at = lambda s: tuple(a + s * (b - a) for a, b in zip(near_end, far_end))  # noqa: E731
    depth_at = lambda s: -view.Transform(Gf.Vec3d(*at(s)))[2]  # noqa: E731
    x_near, x_far = pixel(near_end)[0], pixel(far_end)[0]
    assert x_far < x_near
    checked = {"stroke": 0, "wall": 0}
    for col in range(math.ceil(x_far) + 2, math.floor(x_near) - 2):
        lo, hi = 0.0, 1.0  # x falls from x_near at s = 0 to x_far at s = 1
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if pixel(at(mid))[0] > col + 0.5 else (lo, mid)
        s = 0.5 * (lo + hi)
        depth = depth_at(s)
        if 19.0 < depth < 21.5:
            continue  # where the stroke passes through the wall (depth-test bias)
        z, rgb = exr["Z"][row, col], np.array([exr[k][row, col] for k in "RGB"])
        if depth < 20:
            checked["stroke"] += 1
            assert z == pytest.approx(depth, rel=1e-3), f"column {col}: Z {z}, the stroke is {depth:.3f} away"
            assert np.allclose(rgb, [1 - s, s, 0], atol=5e-3), f"column {col}: {rgb} vs the mix at s = {s:.4f}"
        else:
            checked["wall"] += 1
            assert z == pytest.approx(20.0, rel=1e-4), f"column {col}: Z {z}, the wall is 20 away"
    assert checked["stroke"] > 30 and checked["wall"] > 5, checked


@pytest.mark.parametrize("target", [(0.3, 0.2, 0.0), (-1.0, -0.6, 1.0)])
def test_a_camera_under_a_non_uniform_scale_projects_as_usd_core(painterly, tmp_path, target):
    """A camera under a rig rotated and scaled (2, 0.5, 1.5): its matrix is
    neither orthogonal nor a rotation times a uniform scale. usd-core's
    GetCamera(t).frustum keeps the rotation GfMatrix4d::Orthonormalize gives
    (not the closest rotation); a small dot drawn at the target lands where
    that frustum projects it."""
    path = tmp_path / "s.usda"
    stage = Usd.Stage.CreateNew(str(path))
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(1)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    rig = UsdGeom.Xform.Define(stage, "/Rig")
    rig.AddRotateXYZOp().Set(Gf.Vec3f(5, 10, 0))
    rig.AddScaleOp().Set(Gf.Vec3f(2.0, 0.5, 1.5))
    cam = UsdGeom.Camera.Define(stage, "/Rig/Cam")
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.1, 1000))
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 8))
    cam.AddRotateXYZOp().Set(Gf.Vec3f(3, -4, 7))
    frustum = cam.GetCamera(1).frustum
    view, pixel = conformed_view_projection_of(frustum, (W, H))
    px, py = pixel(target)
    assert 20 < px < W - 20 and 20 < py < H - 20, "the target must be well inside the frame"
    depth = -view.Transform(Gf.Vec3d(*target))[2]
    right = frustum.ComputeViewInverse().TransformDir(Gf.Vec3d(1, 0, 0)).GetNormalized()
    d = 0.01 * depth  # a dot about 2 % of the depth across: a few pixels
    c = UsdGeom.BasisCurves.Define(stage, "/Dot")
    c.CreateTypeAttr("linear")
    c.CreateCurveVertexCountsAttr([2])
    c.CreatePointsAttr([Gf.Vec3f(*(Gf.Vec3d(*target) - right * d)), Gf.Vec3f(*(Gf.Vec3d(*target) + right * d))])
    c.CreateWidthsAttr([2 * d])
    c.SetWidthsInterpolation(UsdGeom.Tokens.constant)
    stage.GetRootLayer().Save()
    painterly("render", path, "--camera", "/Rig/Cam", "--frames", "1", "-o", tmp_path / "f.####.exr",
              "--size", f"{W}x{H}")
    cx, cy = centroid(read_exr(tmp_path / "f.0001.exr")["A"])
    assert math.hypot(cx - px, cy - py) < 0.5, f"dot at {(cx, cy)}, usd-core's frustum puts it at {(px, py)}"


@pytest.mark.parametrize("red_nearer", [True, False])
@pytest.mark.parametrize("authored_red_first", [True, False])
def test_compositing_order_follows_depth(painterly, tmp_path, red_nearer, authored_red_first):
    cam = {"translate": (0, 0, 10), "attrs": {"clippingRange": Gf.Vec2f(0.1, 100)}}
    zr, zb = (1.0, -1.0) if red_nearer else (-1.0, 1.0)
    red = {"points": [(-1, 0, zr), (1, 0, zr)], "width": 0.4, "color": (1, 0, 0), "opacity": 0.5}
    blue = {"points": [(0, -1, zb), (0, 1, zb)], "width": 0.4, "color": (0, 0, 1), "opacity": 0.5}
    strokes = [red, blue] if authored_red_first else [blue, red]
    stage = author(tmp_path / "s.usda", camera=cam, strokes=strokes)
    render(painterly, stage, tmp_path)
    exr = read_exr(tmp_path / "f.0001.exr")
    y, x = H // 2, W // 2
    near, far = ("R", "B") if red_nearer else ("B", "R")
    # near·0.5 over far·0.5 (premultiplied): near 0.5, far 0.25, alpha 0.75.
    assert exr[near][y, x] == pytest.approx(0.5, abs=1e-4)
    assert exr[far][y, x] == pytest.approx(0.25, abs=1e-4)
    assert exr["A"][y, x] == pytest.approx(0.75, abs=1e-4)
    assert exr["Z"][y, x] == pytest.approx(10 - max(zr, zb), rel=1e-4)


def srgb(x):
    x = np.clip(x, 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def test_exr_channels_match_png(painterly, tmp_path):
    cam = {"translate": (0, 0, 10), "attrs": {"clippingRange": Gf.Vec2f(0.1, 100)}}
    strokes = [
        {"points": [(-2, -1, 0), (2, 1, 0)], "width": 0.5, "color": (0.9, 0.4, 0.1), "opacity": 0.7},
        {"points": [(-2, 1, 1), (2, -1, 1)], "width": 0.3, "color": (0.1, 0.5, 0.8), "opacity": 0.9},
    ]
    stage = author(tmp_path / "s.usda", camera=cam, strokes=strokes)
    render(painterly, stage, tmp_path, "--png")
    exr = read_exr(tmp_path / "f.0001.exr")
    assert sorted(exr) == ["A", "B", "G", "R", "Z"]
    assert all(v.dtype == np.float32 and v.shape == (H, W) for v in exr.values())
    png = Image.open(tmp_path / "f.0001.png")
    assert png.mode == "RGBA" and png.size == (W, H)
    p = np.asarray(png).astype(int)
    a = exr["A"]
    assert np.abs(p[..., 3] - np.round(a * 255)).max() <= 1
    mask = a > 0.02
    for k, c in enumerate("RGB"):
        want = np.round(srgb(exr[c][mask] / a[mask]) * 255)
        assert np.abs(p[..., k][mask] - want).max() <= 1, c
    # Flattened over a background: RGB = srgb(C + (1 − A)·bg).
    render(painterly, stage, tmp_path, "--png", "--background", "#336699", name="g.####.exr")
    flat = np.asarray(Image.open(tmp_path / "g.0001.png")).astype(int)
    bg = [((v / 255 + 0.055) / 1.055) ** 2.4 for v in (0x33, 0x66, 0x99)]
    for k, c in enumerate("RGB"):
        want = np.round(srgb(exr[c] + (1 - a) * bg[k]) * 255)
        assert np.abs(flat[..., k] - want).max() <= 1, c


def test_bake_layer_option_matches_baking_on_the_fly(painterly, tmp_path, repo_root):
    fish = repo_root / "fixtures" / "blowfish.usda"
    wrapper = tmp_path / "fish_cam.usda"
    stage = Usd.Stage.CreateNew(str(wrapper))
    stage.GetRootLayer().subLayerPaths.append(str(fish))
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(48)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.CreateFocalLengthAttr(35.0)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.1, 1000))
    UsdGeom.Xformable(cam).AddTranslateOp().Set(Gf.Vec3d(-0.9, 4.2, 40))
    stage.GetRootLayer().Save()
    painterly("bake", wrapper, "-o", tmp_path / "bake.usdc", "--frames", "24:25")
    render(painterly, wrapper, tmp_path, "--bake", tmp_path / "bake.usdc", frames="24:25", name="a.####.exr")
    out = render(painterly, wrapper, tmp_path, "--sheet", frames="24:25", name="b.####.exr")
    assert "2 frames" in out.stdout and "strokes" in out.stdout
    for f in (24, 25):
        a = read_exr(tmp_path / f"a.{f:04d}.exr")
        b = read_exr(tmp_path / f"b.{f:04d}.exr")
        assert a["A"].sum() > 1000, "the fish is in view"
        for c in "RGBAZ":
            np.testing.assert_array_equal(a[c], b[c])
    sheet = Image.open(tmp_path / "b.sheet.png")
    assert sheet.mode == "RGB" and sheet.size[0] > 100


def test_meshes_are_shaded_guides_are_not(painterly, tmp_path):
    cam = {"translate": (0, 0, 10), "attrs": {"clippingRange": Gf.Vec2f(0.1, 100)}}
    quad = {"points": [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], "counts": [4], "indices": [0, 1, 2, 3]}
    stage = author(tmp_path / "m.usda", camera=cam, meshes=[quad])
    render(painterly, stage, tmp_path)
    exr = read_exr(tmp_path / "f.0001.exr")
    assert exr["A"][H // 2, W // 2] == 1.0
    assert exr["Z"][H // 2, W // 2] == pytest.approx(10.0, rel=1e-5)
    guide = author(tmp_path / "g.usda", camera=cam, meshes=[dict(quad, purpose="guide")])
    render(painterly, guide, tmp_path, name="g.####.exr")
    assert read_exr(tmp_path / "g.0001.exr")["A"].max() == 0.0



@pytest.mark.parametrize("size", [(360, 240), (720, 480)])
# Fanned from corner 0 or from corner 2: the diagonal 0–2 either way, its
# triangles' corners in different orders (the old rasteriser cracked on both).
@pytest.mark.parametrize("indices", [[0, 1, 2, 3], [2, 3, 0, 1]], ids=["fan_from_0", "fan_from_2"])
def test_a_quads_diagonal_through_pixel_centres_leaves_no_crack(painterly, tmp_path, size, indices):
    """A quad's two triangles share a diagonal; at these sizes it runs exactly
    through pixel centres (x ± y is whole there). Every centre inside the quad
    is drawn: none is left to the transparent background."""
    path = tmp_path / "plain.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateHorizontalApertureAttr(36.0)
    cam.CreateVerticalApertureAttr(24.0)
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 10))
    mesh = UsdGeom.Mesh.Define(stage, "/World/Quad")
    corners = [(-1, -1, -2), (1, -1, -2), (1, 1, -2), (-1, 1, -2)]
    mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in corners])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr(indices)
    mesh.CreateSubdivisionSchemeAttr("none")
    stage.GetRootLayer().Save()
    painterly("render", path, "--camera", "/World/Cam", "--frames", "1", "-o", tmp_path / "plain.exr",
              "--png", "--size", f"{size[0]}x{size[1]}")
    alpha = read_exr(tmp_path / "plain.exr")["A"]
    # The quad by hand: 12 units in front, a 50 mm lens over a 36 mm
    # aperture: x = W/2 ± (1/12)(50/36) W, y = H/2 ± the same (square pixels).
    half = (1 / 12) * (50 / 36) * size[0]
    x0, x1 = size[0] / 2 - half, size[0] / 2 + half
    y0, y1 = size[1] / 2 - half, size[1] / 2 + half
    ys, xs = np.mgrid[0 : size[1], 0 : size[0]] + 0.5
    # Centres inside by more than half a pixel: the mesh covers them all.
    inside = (xs > x0 + 0.5) & (xs < x1 - 0.5) & (ys > y0 + 0.5) & (ys < y1 - 0.5)
    assert inside.sum() > 0.9 * (2 * half) ** 2
    holes = np.argwhere(inside & (alpha == 0))
    assert holes.size == 0, f"{len(holes)} transparent pixels inside the quad, e.g. (y, x) {holes[:5].tolist()}"
    assert (alpha[inside] == 1).all()
    # And nothing well outside it.
    outside = (xs < x0 - 0.5) | (xs > x1 + 0.5) | (ys < y0 - 0.5) | (ys > y1 + 0.5)
    assert (alpha[outside] == 0).all()


BAD_CAMERAS = [
    ("missing", None, "Camera", "does not exist"),
    ("xform", {"translate": (0, 0, 10)}, "Xform", "not a Camera"),
    ("zero_aperture", {"attrs": {"horizontalAperture": 0.0}}, "Camera", "horizontalAperture"),
    ("zero_focal", {"attrs": {"focalLength": 0.0}}, "Camera", "focalLength"),
    ("bad_clip", {"attrs": {"clippingRange": Gf.Vec2f(5, 1)}}, "Camera", "clippingRange"),
]


@pytest.mark.parametrize("name,camera,ctype,needle", BAD_CAMERAS, ids=[b[0] for b in BAD_CAMERAS])
def test_bad_cameras_exit_1_naming_file_and_prim(painterly, tmp_path, name, camera, ctype, needle):
    stage = author(tmp_path / "s.usda", camera=camera, camera_type=ctype, strokes=[{"points": [(0, 0, 0), (1, 0, 0)]}])
    p = render(painterly, stage, tmp_path, check=False)
    assert p.returncode == 1, p.stderr
    assert "/Cam" in p.stderr and needle in p.stderr and "s.usda" in p.stderr, p.stderr
    assert "internal error" not in p.stderr and "panicked" not in p.stderr


@pytest.mark.parametrize(
    "args,code,needle",
    [
        (["--frames", "a:b"], 2, "frames"),
        (["--frames", "5:1"], 2, "before start"),
        (["--frames", "1:3:0"], 2, "step"),
        (["--size", "0x10"], 2, "size"),
        (["--background", "#12"], 2, "colour"),
    ],
)
def test_bad_usage_exits_2(painterly, tmp_path, args, code, needle):
    stage = author(tmp_path / "s.usda", camera={"translate": (0, 0, 10)})
    base = ["render", stage, "--camera", "/Cam", "-o", tmp_path / "f.####.exr"]
    if "--frames" not in args:
        base += ["--frames", "1"]
    p = painterly(*base, *args, check=False)
    assert p.returncode == code and needle in p.stderr, p.stderr


def test_bad_outputs_and_inputs_exit_1(painterly, tmp_path):
    stage = author(tmp_path / "s.usda", camera={"translate": (0, 0, 10)})

    def run(output, *extra, input=stage, frames="1", code=1):
        p = painterly("render", input, "--camera", "/Cam", "--frames", frames, "-o", output, *extra, check=False)
        assert p.returncode == code and "internal error" not in p.stderr, p.stderr
        return p.stderr

    err = run(tmp_path / "nope" / "f.####.exr")
    assert "nope" in err and "does not exist" in err
    # An output name that cannot work is a usage error (issue 11).
    assert "####" in run(tmp_path / "f.exr", frames="1:3", code=2)
    assert ".exr" in run(tmp_path / "f.png", code=2)
    assert "absent.usda" in run(tmp_path / "f.exr", input=tmp_path / "absent.usda")
    assert "b.png" in run(tmp_path / "f.exr", "--brush", tmp_path / "b.png")
    assert "bake.usdc" in run(tmp_path / "f.exr", "--bake", tmp_path / "bake.usdc")


def test_brush_footprint_modulates_alpha(painterly, tmp_path):
    cam = {"translate": (0, 0, 10), "attrs": {"clippingRange": Gf.Vec2f(0.1, 100)}}
    stage = author(tmp_path / "s.usda", camera=cam, strokes=[{"points": [(-1, 0, 0), (1, 0, 0)], "width": 0.4}])
    # Left half of the footprint (one side of the stroke) transparent.
    brush = np.zeros((8, 16), dtype=np.uint8)
    brush[:, 8:] = 255
    Image.fromarray(brush, mode="L").save(tmp_path / "brush.png")
    render(painterly, stage, tmp_path, name="plain.####.exr")
    render(painterly, stage, tmp_path, "--brush", tmp_path / "brush.png", name="brushed.####.exr")
    plain = read_exr(tmp_path / "plain.0001.exr")["A"]
    brushed = read_exr(tmp_path / "brushed.0001.exr")["A"]
    ratio = brushed.sum() / plain.sum()
    assert 0.4 < ratio < 0.6, ratio
    # One side of the stroke is kept, the other cleared.
    rows = np.nonzero(brushed.sum(axis=1) > 0)[0]
    assert plain.sum(axis=1)[rows].sum() > 0
    top, bottom = brushed[: H // 2].sum(), brushed[H // 2 :].sum()
    assert min(top, bottom) < 0.1 * max(top, bottom)


def fish_with_camera(tmp_path, repo_root, name="fish_cam.usda"):
    """The blowfish under a camera that frames it (frames 1-48)."""
    wrapper = tmp_path / name
    stage = Usd.Stage.CreateNew(str(wrapper))
    stage.GetRootLayer().subLayerPaths.append(str(repo_root / "fixtures" / "blowfish.usda"))
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(48)
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.CreateFocalLengthAttr(35.0)
    cam.CreateClippingRangeAttr(Gf.Vec2f(0.1, 1000))
    UsdGeom.Xformable(cam).AddTranslateOp().Set(Gf.Vec3d(-0.9, 4.2, 40))
    stage.GetRootLayer().Save()
    return wrapper


def test_bake_of_another_input_is_refused(painterly, tmp_path, repo_root):
    wrapper = fish_with_camera(tmp_path, repo_root)
    other = tmp_path / "apple_bake.usdc"
    painterly("bake", repo_root / "fixtures" / "apple.usda", "-o", other, "--frames", "1:2")
    proc = render(painterly, wrapper, tmp_path, "--bake", other, frames="1:2", check=False)
    assert proc.returncode == 1
    assert "was made from" in proc.stderr and "apple.usda" in proc.stderr and str(other) in proc.stderr
    assert not list(tmp_path.glob("f.*.exr"))


def test_frames_outside_the_bake_are_warned_about(painterly, tmp_path, repo_root):
    wrapper = fish_with_camera(tmp_path, repo_root)
    bake = tmp_path / "bake.usdc"
    painterly("bake", wrapper, "-o", bake, "--frames", "1:5")
    proc = render(painterly, wrapper, tmp_path, "--bake", bake, "--json", frames="4:7")
    summary = json.loads(proc.stdout)
    assert summary["frames"] == 4
    assert summary["warnings"] == [
        "2 frames outside the bake's frames 1:5 (6, 7): strokes there show their authored points"
    ]
    assert "warning: 2 frames outside the bake's frames 1:5 (6, 7)" in proc.stderr
    quiet = render(painterly, wrapper, tmp_path, "--bake", bake, "--quiet", frames="4:7")
    assert quiet.stdout == "" and quiet.stderr == ""


def test_empty_frames_are_warned_about_and_listed(painterly, tmp_path):
    # A stroke in view at frame 1 only: the camera turns away afterwards.
    stage = author(
        tmp_path / "s.usda",
        camera={"translate": (0, 0, 10)},
        strokes=[{"points": [(-1, 0, 0), (1, 0, 0)], "width": 0.3}],
        end=3,
    )
    s = Usd.Stage.Open(str(stage))
    rot = UsdGeom.Xformable(s.GetPrimAtPath("/Cam")).GetOrderedXformOps()[1]
    rot.Set(Gf.Vec3f(0, 0, 0), 1)
    rot.Set(Gf.Vec3f(0, 180, 0), 2)
    s.GetRootLayer().Save()
    proc = render(painterly, stage, tmp_path, "--json", frames="1:3")
    summary = json.loads(proc.stdout)
    assert summary["empty_frames"] == [2, 3]
    assert summary["warnings"] == ["2 frames of 3 empty: nothing in front of /Cam at 2, 3"]
    assert "warning: 2 frames of 3 empty" in proc.stderr
    assert set(summary) == {
        "input", "output", "frames", "width", "height", "curves", "strokes", "meshes", "triangles",
        "sheet", "empty_frames", "warnings", "seconds", "median_frame_seconds",
    }


def test_summary_line_counts_in_words(painterly, tmp_path):
    stage = author(tmp_path / "s.usda", camera={"translate": (0, 0, 10)}, strokes=[{"points": [(-1, 0, 0), (1, 0, 0)]}])
    out = render(painterly, stage, tmp_path)
    assert out.stdout.startswith(f"rendered 1 frame at {W}x{H}: 1 curves prim (1 stroke), 0 meshes (0 triangles) -> ")


def add_curves(stage_path, path, points, counts=None, width=0.3, curve_type="linear", basis=None):
    """Adds a BasisCurves prim with usd-core; `counts` None leaves
    curveVertexCounts unauthored."""
    s = Usd.Stage.Open(str(stage_path))
    c = UsdGeom.BasisCurves.Define(s, path)
    c.CreateTypeAttr(curve_type)
    if basis:
        c.CreateBasisAttr(basis)
    c.CreatePointsAttr([Gf.Vec3f(*p) for p in points])
    if counts is not None:
        c.CreateCurveVertexCountsAttr(counts)
    c.CreateWidthsAttr([width])
    c.SetWidthsInterpolation(UsdGeom.Tokens.constant)
    s.GetRootLayer().Save()


def test_curves_that_draw_nothing_are_named(painterly, tmp_path):
    """A cubic B-spline of three points (one span needs four) and a curve
    of negative width draw nothing; the render says which and why, and
    its pixels are those of the one drawable stroke alone."""
    stroke = {"points": [(-1, 0, 0), (1, 0, 0)], "width": 0.3}
    alone = author(tmp_path / "alone.usda", camera={"translate": (0, 0, 10)}, strokes=[stroke], end=2)
    stage = author(tmp_path / "s.usda", camera={"translate": (0, 0, 10)}, strokes=[stroke], end=2)
    add_curves(stage, "/Short", [(-1, 1, 0), (0, 1.5, 0), (1, 1, 0)], [3], curve_type="cubic", basis="bspline")
    add_curves(stage, "/Thin", [(-1, -1, 0), (1, -1, 0)], [2], width=-0.2)
    proc = render(painterly, stage, tmp_path, "--json", frames="1:2")
    summary = json.loads(proc.stdout)
    assert summary["warnings"] == [
        "/Short: 1 of 1 curve draw nothing (1 with too few points for one span) at frames 1, 2",
        "/Thin: 1 of 1 curve draw nothing (1 without a positive width) at frames 1, 2",
    ]
    assert summary["curves"] == 3 and summary["empty_frames"] == []
    assert "warning: /Short: 1 of 1 curve draw nothing" in proc.stderr
    (tmp_path / "alone").mkdir()
    render(painterly, alone, tmp_path / "alone", frames="1:2")
    for f in ("f.0001.exr", "f.0002.exr"):
        got, want = read_exr(tmp_path / f), read_exr(tmp_path / "alone" / f)
        assert set(got) == set(want) and all(np.array_equal(got[k], want[k]) for k in got), f
        assert got["A"].max() > 0, f


def test_curves_without_vertex_counts_are_refused(painterly, tmp_path):
    """USD has no fallback for curveVertexCounts but the empty array, which
    does not add up to the points: refused like any other mismatch, naming
    the file, prim and attribute (it was once drawn as one stroke)."""
    stage = author(tmp_path / "s.usda", camera={"translate": (0, 0, 10)})
    add_curves(stage, "/NoCounts", [(-1, 0, 0), (0, 1, 0), (1, 0, 0)])
    proc = render(painterly, stage, tmp_path, check=False)
    assert proc.returncode == 1
    assert proc.stderr == (f"error: {stage}: /NoCounts.curveVertexCounts: at time 1: "
                           "counts sum to 0, but there are 3 points\n")
    assert not list(tmp_path.glob("f.*"))
