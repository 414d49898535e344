"""`painterly preview` over plain HTTP: what it serves, what it refuses, that
it survives bad requests and never writes its input, and that the frames it
serves are `painterly bake`'s frames (read back with usd-core)."""

import hashlib
import io
import json
import os
import re
import shutil
import socket
import subprocess

import numpy as np
import pytest
from PIL import Image
from pxr import Gf, Sdf, Usd, UsdGeom, Vt

from conftest import REPO, painterly_binary, run_painterly
from preview_helpers import PreviewServer, WebSocket, WebSocketRefused, decode_frame

FISH = REPO / "fixtures" / "blowfish.usda"
HEAD = REPO / "fixtures" / "head.usda"


def sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def edited_fish(tmp_path, change, name="blowfish.usda"):
    """A copy of the fish under tmp_path, changed by `change(stage)` and
    saved with usd-core; returns its path and the open stage."""
    path = tmp_path / name
    shutil.copy(FISH, path)
    stage = Usd.Stage.Open(str(path))
    change(stage)
    stage.GetRootLayer().Save()
    return path, stage


def start_camera(view, near=0.1, far=10000):
    """The server's start view (`scene["view"]`) as a render camera."""
    return {"position": view["position"], "target": view["target"], "up": view["up"], "fov_y": view["fov_y"], "near": near, "far": far}


def render_rgba(server, frame, camera, width, height):
    """`POST /api/render`, decoded to RGBA as int16 so differences don't wrap."""
    status, _, body = server.request("api/render", body={"frame": frame, "camera": camera, "width": width, "height": height})
    assert status == 200, body
    return np.array(Image.open(io.BytesIO(body)).convert("RGBA"), dtype=np.int16)


@pytest.fixture(scope="module")
def fish_copy(tmp_path_factory):
    d = tmp_path_factory.mktemp("preview_fish")
    p = d / "blowfish.usda"
    shutil.copy(FISH, p)
    return p


@pytest.fixture(scope="module")
def fish(fish_copy):
    before = (sha(fish_copy), fish_copy.stat().st_mtime_ns)
    with PreviewServer(fish_copy) as s:
        yield s
        assert s.alive(), "the server must survive every test"
    # The input is never written.
    assert (sha(fish_copy), fish_copy.stat().st_mtime_ns) == before
    assert sorted(x.name for x in fish_copy.parent.iterdir()) == ["blowfish.usda"]


def test_listens_on_loopback_and_prints_the_port(fish):
    m = re.match(r"http://127\.0\.0\.1:(\d+)/$", fish.url)
    assert m and int(m.group(1)) > 0, fish.url


def test_serves_its_page(fish):
    for path, kind in [("", "text/html"), ("index.html", "text/html"), ("app.js", "text/javascript"), ("style.css", "text/css")]:
        status, headers, body = fish.request(path)
        assert status == 200, path
        assert headers["content-type"].startswith(kind), (path, headers)
        assert body
    status, headers, body = fish.request("")
    assert b'<script src="app.js">' in body
    assert "default-src 'self'" in headers["content-security-policy"]


@pytest.mark.parametrize(
    "path",
    [
        "fixtures/blowfish.usda",
        "blowfish.usda",
        "..%2f..%2fCargo.toml",
        "%2e%2e/%2e%2e/etc/passwd",
        "api/../Cargo.toml",
        "src/preview/page/app.js",
        "api/scene/extra",
        "api/nope",
    ],
)
def test_serves_nothing_else(fish, path):
    status, _, body = fish.request(path)
    assert status == 404, (path, status)
    assert b"Cargo" not in body and b"root:" not in body


def test_other_hosts_are_refused(fish):
    # A page elsewhere reaching the server by DNS rebinding sends its own Host.
    status, _, body = fish.request("api/scene", headers={"Host": "evil.example:80"})
    assert status == 403
    assert b"evil.example" in body
    port = fish.url.rsplit(":", 1)[1].strip("/")
    assert fish.request("api/scene", headers={"Host": f"localhost:{port}"})[0] == 200


def test_pages_elsewhere_are_refused(fish):
    # A page on another site, open in the same browser, sends the right Host
    # (127.0.0.1) but its own Origin: its websocket handshake and its POSTs
    # are refused, so it can neither read frames nor load the evaluator.
    own = fish.url.rstrip("/")
    port = own.rsplit(":", 1)[1]
    for origin in ["http://evil.example", "null", f"https://127.0.0.1:{port}", f"http://127.0.0.1:{int(port) + 1}", f"{own}.evil.example"]:
        with pytest.raises(WebSocketRefused) as refused:
            WebSocket(fish.url, origin=origin)
        assert refused.value.status == 403, origin
        status, _, body = fish.request("api/frame", body={"time": 1}, headers={"Origin": origin})
        assert status == 403, origin
        assert json.loads(body)["error"] == f"origin {json.dumps(origin)} is not this preview server's page"
        assert fish.request("api/scene", headers={"Origin": origin})[0] == 403
    # The page's own origin (what the browser sends from it), and no Origin
    # at all (curl, scripts), are served.
    for origin in [own, None]:
        ws = WebSocket(fish.url, origin=origin)
        ws.send(json.dumps({"id": 3, "time": 1}))
        opcode, payload = ws.recv()
        ws.close()
        assert opcode == 2 and payload[:4] == b"PTLY", origin
        headers = {"Origin": origin} if origin else {}
        assert fish.request("api/frame", body={"time": 1}, headers=headers)[0] == 200
    # The page opened as http://localhost:PORT (host names compare without case).
    local = {"Host": f"localhost:{port}", "Origin": f"http://LocalHost:{port}"}
    assert fish.request("api/frame", body={"time": 1}, headers=local)[0] == 200


@pytest.mark.parametrize(
    "raw,ctype,status",
    [
        (b"{not json", "application/json", 400),
        (b'{"time": "one"}', "application/json", 400),
        (b'{"time": 1, "bogus": 2}', "application/json", 400),
        (b'{"time": 1e999}', "application/json", 400),
        (b'{"time": 1, "eye": [0, 0]}', "application/json", 400),
        (b'{"time": 1, "overrides": {"/Blowfish/Nope": 1}}', "application/json", 400),
        (b'{"time": 1, "overrides": {"/Blowfish/Paint/blink": 1e999}}', "application/json", 400),
        (b'{"time": 1}', "text/plain", 415),
        (b"x" * (3 << 20), "application/json", 413),
        # A request is a JSON object, not the array of its fields in order.
        (b"[7, 12]", "application/json", 400),
        (b"12", "application/json", 400),
        # Only application/json, not a type that begins the same.
        (b'{"time": 1}', "application/jsonp", 415),
        (b'{"time": 1}', "application/json-seq", 415),
    ],
)
def test_bad_frame_requests_get_4xx(fish, raw, ctype, status):
    got, _, body = fish.request("api/frame", raw=raw, headers={"Content-Type": ctype}, method="POST")
    assert got == status, body[:200]
    assert fish.alive()


def test_a_request_is_a_json_object_of_media_type_application_json_in_any_case(fish):
    """docs/preview.md: a frame request is a JSON object, POSTed as
    application/json. A media type compares without case (RFC 9110) and
    takes parameters; an array of the fields in order ([id, time]) is 400
    on the route and on the websocket, for a render's frame and camera too."""
    for ctype in ["Application/JSON", "application/json; charset=utf-8", "APPLICATION/JSON;charset=UTF-8"]:
        status, _, body = fish.request("api/frame", raw=b'{"id": 3, "time": 2}', headers={"Content-Type": ctype},
                                       method="POST")
        assert status == 200, (ctype, body[:200])
        assert decode_frame(body)[0]["id"] == 3
    status, _, body = fish.request("api/frame", raw=b"[7, 12]", headers={"Content-Type": "application/json"},
                                   method="POST")
    assert (status, json.loads(body)) == (400, {"error": "bad request: expected a JSON object, found an array"})
    cam = {"position": [0, 0, 30], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40, "near": 0.1, "far": 1000}
    good = {"frame": {"time": 1}, "camera": cam, "width": 8, "height": 8}
    assert fish.request("api/render", body=good)[0] == 200
    for bad in [{**good, "frame": [0, 1]}, {**good, "camera": list(cam.values())}]:
        status, _, body = fish.request("api/render", body=bad)
        assert status == 400 and b"expected a JSON object, found an array" in body, (status, body[:200])
    ws = WebSocket(fish.url)
    try:
        ws.send("[7, 12]")
        op, body = ws.recv()
        assert (op, json.loads(body)) == (1, {"id": 0, "status": 400,
                                              "error": "bad request: expected a JSON object, found an array"})
        ws.send(json.dumps({"id": 7, "time": 12}))
        op, body = ws.recv()
        assert op == 2 and decode_frame(body)[0]["id"] == 7
    finally:
        ws.close()
    assert fish.alive()


def test_the_websocket_message_limit_closes_only_that_connection(fish):
    """README, Limits: 64 KiB a websocket message. One just under it is
    answered (a bad request, the padding is no field); one just over it
    closes that page's connection; the server and other pages go on."""
    ws = WebSocket(fish.url)
    try:
        msg = json.dumps({"id": 5, "time": 12, "pad": ""})
        ws.send(msg[:-2] + "x" * (65536 - len(msg)) + '"}')
        op, body = ws.recv()
        assert op == 1 and json.loads(body)["status"] == 400, body[:200]
        ws.send(msg[:-2] + "x" * (65537 - len(msg)) + '"}')
        with pytest.raises((EOFError, ConnectionError)):
            while True:
                op, body = ws.recv()
                if op == 8:  # a close frame, then the end
                    raise EOFError("closed")
    finally:
        ws.close()
    other = WebSocket(fish.url)
    try:
        other.send(json.dumps({"id": 8, "time": 12}))
        op, body = other.recv()
        assert op == 2 and decode_frame(body)[0]["id"] == 8
    finally:
        other.close()
    assert fish.alive()


def test_bad_render_requests_get_4xx(fish):
    cam = {"position": [0, 0, 30], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 40, "near": 0.1, "far": 1000}
    for width, c in [(0, cam), (100000, cam), (64, {**cam, "near": -1}), (64, {**cam, "fov_y": 0})]:
        status, _, body = fish.request("api/render", body={"frame": {"time": 1}, "camera": c, "width": width, "height": 64})
        assert status == 400, body
    assert fish.request("api/frame", method="GET")[0] == 405
    assert fish.alive()


def test_an_eye_at_the_proxy_centre_is_422_not_a_crash(tmp_path):
    """A viewDirection axis is the unit vector from the posed proxy's
    bounding-box centre to the eye (SPEC §4): an eye exactly there has no
    direction, a 422 naming it; anywhere else evaluates. The proxy has no
    transform, so the eye's world position is its local one, exactly."""
    import authoring as Au
    import authoring_keys as AK

    path = tmp_path / "quad.usda"
    stage = Usd.Stage.CreateNew(str(path))
    Au.set_stage_metadata(stage, 1, 2)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Proxy")
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    mesh.CreatePointsAttr(Au.v3f([[0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0]]))
    cam = UsdGeom.Camera.Define(stage, "/World/Cam")
    UsdGeom.Xformable(cam).AddTranslateOp().Set(Gf.Vec3d(1, 0.5, 5))
    Au.add_painterly_rig(stage, "/World/Paint", "/World/Proxy")
    AK.add_axis(stage, "/World/Paint/viewX", "viewDirection", source="/World/Cam", component=0)
    low = np.array([[0.2, 0.2, 0.1], [1.8, 0.8, 0.1]])
    Au.add_stroke_layer(stage, "/World/Paint/Hair", [2], low)
    AK.add_pose_key(stage, "/World/Paint/Hair", "left", [-1], points=low, opacity=1.0)
    AK.add_pose_key(stage, "/World/Paint/Hair", "right", [1], points=low + 0.1, opacity=0.5)
    stage.Save()
    with PreviewServer(path) as s:
        status, _, body = s.request("api/frame", body={"time": 1, "eye": [1, 0.5, 0]})
        assert (status, json.loads(body)["error"]) == (422, "/World/Paint/viewX: camera is at the proxy's centre at time 1")
        assert s.alive()
        header, _ = s.frame(time=1, eye=[3, 0.5, 0])
        assert header["configuration"] == {"/World/Paint/viewX": 1.0}


def test_scene_describes_the_character(fish):
    scene = fish.scene()
    stage = Usd.Stage.Open(str(FISH))
    assert scene["start"] == stage.GetStartTimeCode() and scene["end"] == stage.GetEndTimeCode()
    layers = {l["path"]: l for l in scene["layers"]}
    # Table I counts from the stage itself.
    for path, info in layers.items():
        curves = UsdGeom.BasisCurves(stage.GetPrimAtPath(path))
        counts = list(curves.GetCurveVertexCountsAttr().Get())
        assert info["strokes"] == len(counts) and info["points"] == sum(counts), path
        assert info["curve_counts"] == counts
    assert len(layers) == 14
    assert sum(l["strokes"] for l in layers.values()) == 2588
    axes = {a["path"]: a for a in scene["axes"]}
    assert set(axes) == {f"/Blowfish/Paint/{n}" for n in ["inflate", "eyeX", "eyeY", "blink"]}
    # Key marks: the Eyelids' opacity keys sit at blink 0 and 1.
    marks = sorted(k["coordinate"] for k in axes["/Blowfish/Paint/blink"]["keys"])
    assert marks == [0.0, 1.0]
    assert all(a["min"] < a["max"] for a in axes.values())
    assert scene["problems"] == []


def assert_strokes_come_from_the_stage(server, stage, never_drawn=()):
    """Widths and colours of every layer but `never_drawn` (guides, whose
    fallbacks are never seen) are the stage's."""
    status, _, data = server.request("api/strokes")
    assert status == 200
    _, arrays = decode_frame(data)
    scene = server.scene()
    for i, info in enumerate(scene["layers"]):
        if info["path"] in never_drawn:
            continue
        prim = stage.GetPrimAtPath(info["path"])
        curves = UsdGeom.BasisCurves(prim)
        widths = np.array(curves.GetWidthsAttr().Get(), dtype=np.float32)
        # In the layer's own space: the page scales them by each frame's
        # transform (docs/preview.md).
        got = arrays[f"layer/{i}/widths"]
        if len(widths) == len(got):
            np.testing.assert_allclose(got, widths, rtol=1e-6, err_msg=info["path"])
        colours = np.array(UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor").Get(), dtype=np.float32)
        per_point = np.repeat(colours, info["curve_counts"], axis=0)
        np.testing.assert_allclose(arrays[f"layer/{i}/colors"].reshape(-1, 3), per_point, rtol=1e-6, err_msg=info["path"])
    return scene


def test_stroke_widths_and_colours_come_from_the_stage(fish):
    assert_strokes_come_from_the_stage(fish, Usd.Stage.Open(str(FISH)))


def test_varying_primvars_of_pinned_cubic_curves_show_in_render_and_preview(tmp_path):
    """blowfish's Spots (60 curves of 7 points) made pinned Catmull-Rom,
    with varying widths, colours and opacities of usd-core's count (5 a
    curve: ComputeVaryingDataSize). render and preview refused them (they
    wanted the 7 span ends a pinned curve draws), and preview drew varying
    values of cubic curves at its default width 1 and grey (a review,
    2026-12-07). The pinned ends take the nearest value: control point
    k + 1 takes value k, points 0 and 6 those of points 1 and 5."""
    fish = tmp_path / "fish.usda"
    shutil.copy(FISH, fish)
    stage = Usd.Stage.Open(str(fish))
    curves = UsdGeom.BasisCurves(stage.GetPrimAtPath("/Blowfish/Paint/Spots"))
    counts = list(curves.GetCurveVertexCountsAttr().Get())
    curves.GetTypeAttr().Set(UsdGeom.Tokens.cubic)
    curves.GetBasisAttr().Set(UsdGeom.Tokens.catmullRom)
    curves.GetWrapAttr().Set(UsdGeom.Tokens.pinned)
    n = curves.ComputeVaryingDataSize(Usd.TimeCode.Default())
    assert n == 5 * len(counts) and set(counts) == {7}
    widths = np.linspace(0.01, 0.05, n).astype(np.float32)
    colours = np.random.default_rng(1).uniform(0, 1, (n, 3)).astype(np.float32)
    curves.GetWidthsAttr().Set(Vt.FloatArray(widths.tolist()))
    curves.SetWidthsInterpolation(UsdGeom.Tokens.varying)
    api = UsdGeom.PrimvarsAPI(curves)
    api.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.varying).Set(
        Vt.Vec3fArray.FromNumpy(colours))
    api.CreatePrimvar("displayOpacity", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.varying).Set(
        Vt.FloatArray([0.5] * n))
    stage.GetRootLayer().Save()
    assert curves.ComputeInterpolationForSize(n, Usd.TimeCode.Default()) == UsdGeom.Tokens.varying
    proc = run_painterly("render", fish, "--camera", "/Blowfish/Camera", "--frames", "1", "--size", "64x48",
                         "-o", tmp_path / "f.####.exr", "-q", check=False)
    assert (proc.returncode, proc.stderr) == (0, ""), proc.stderr
    pick = [0] + [k for k in range(5)] + [4]  # control point -> value, per curve
    with PreviewServer(fish) as server:
        status, _, data = server.request("api/strokes")
        assert status == 200
        _, arrays = decode_frame(data)
        i = [l["path"] for l in server.scene()["layers"]].index("/Blowfish/Paint/Spots")
        want = np.concatenate([widths[5 * c + np.array(pick)] for c in range(len(counts))])
        np.testing.assert_allclose(arrays[f"layer/{i}/widths"], want, rtol=1e-6)
        want = np.concatenate([colours[5 * c + np.array(pick)] for c in range(len(counts))])
        np.testing.assert_allclose(arrays[f"layer/{i}/colors"].reshape(-1, 3), want, rtol=1e-6)


def test_a_layer_shaped_like_another_keeps_its_own_colours(tmp_path):
    # A copy of Spikes after it, green: the same curve and point counts, so
    # only its path tells the copy's widths and colours from the original's.
    def add_copy(stage):
        layer = stage.GetRootLayer()
        assert Sdf.CopySpec(layer, "/Blowfish/Paint/Spikes", layer, "/Blowfish/Paint/SpikesCopy")
        copy = UsdGeom.BasisCurves(stage.GetPrimAtPath("/Blowfish/Paint/SpikesCopy"))
        n = len(copy.GetCurveVertexCountsAttr().Get())
        UsdGeom.PrimvarsAPI(copy).GetPrimvar("displayColor").Set([(0.1, 0.9, 0.2)] * n)
        copy.GetWidthsAttr().Set([2 * w for w in copy.GetWidthsAttr().Get()])

    path, stage = edited_fish(tmp_path, add_copy)
    with PreviewServer(path) as s:
        scene = assert_strokes_come_from_the_stage(s, stage)
    # The copy is drawn after the original (traversal order), so a match by
    # counts alone would find the original first.
    paths = [l["path"] for l in scene["layers"]]
    assert paths.index("/Blowfish/Paint/Spikes") < paths.index("/Blowfish/Paint/SpikesCopy")


def test_scene_and_frame_headers_hold_exactly_the_documented_keys(tmp_path):
    # docs/preview.md lists them; a client is written from that list.
    bake = tmp_path / "fish_bake.usdc"
    subprocess.run([str(painterly_binary()), "bake", str(FISH), "-o", str(bake), "--frames", "1:2", "--quiet"], check=True)
    with PreviewServer(FISH, "--bake", bake) as s:
        scene = s.scene()
        assert set(scene) == {
            "file", "start", "end", "frames_per_second", "up_axis", "layers", "axes",
            "proxies", "views", "problems", "view", "bounds", "bake",
        }
        assert set(scene["view"]) == {"position", "target", "up", "fov_y", "aspect", "camera"}
        live, _ = s.frame(id=5, time=1)
        assert set(live) == {"id", "time", "eye", "configuration", "weights", "hidden", "stale", "timing", "arrays"}
        assert live["stale"] is None
        assert set(live["timing"]) == {"read_ms", "evaluate_ms", "encode_ms", "total_ms"}
        baked, _ = s.frame(id=6, time=1, bake=True)
        assert set(baked) == {"id", "time", "source", "hidden", "stale", "timing", "arrays"}
        assert baked["stale"] is None
        assert (baked["id"], baked["source"], set(baked["timing"])) == (6, "bake", {"total_ms"})


def test_layers_render_would_not_draw_are_hidden_per_frame(tmp_path):
    # Spikes invisible, Hair invisible at frames 1 and 2 only (the fish's
    # `Paint` scope stays visible), GapFill a guide: `render` draws none of
    # them at frame 1 and only Hair again at frame 10. The preview says so
    # per frame, and still reads the invisible layers' own widths and
    # colours (not the grey, width-1 fallbacks of an undrawn prim) for the
    # frames they show; a guide is never drawn.
    def hide(stage):
        UsdGeom.Imageable(stage.GetPrimAtPath("/Blowfish/Paint/Spikes")).GetVisibilityAttr().Set("invisible")
        vis = UsdGeom.Imageable(stage.GetPrimAtPath("/Blowfish/Paint/Hair")).GetVisibilityAttr()
        vis.Set("invisible", 1)
        vis.Set("invisible", 2)
        vis.Set("inherited", 3)
        UsdGeom.Imageable(stage.GetPrimAtPath("/Blowfish/Paint/GapFill")).GetPurposeAttr().Set("guide")

    path, stage = edited_fish(tmp_path, hide)
    bake = tmp_path / "fish_bake.usdc"
    subprocess.run([str(painterly_binary()), "bake", str(path), "-o", str(bake), "--frames", "1:10", "--quiet"], check=True)
    with PreviewServer(path, "--bake", bake) as s:
        scene = assert_strokes_come_from_the_stage(s, stage, never_drawn=["/Blowfish/Paint/GapFill"])
        index = {l["path"]: i for i, l in enumerate(scene["layers"])}
        spikes, hair, gap = (index[f"/Blowfish/Paint/{n}"] for n in ["Spikes", "Hair", "GapFill"])
        for t, want in [(1, [spikes, hair, gap]), (2, [spikes, hair, gap]), (10, [spikes, gap])]:
            for bake_frame_ in [False, True]:
                header, arrays = s.frame(time=t, bake=bake_frame_)
                assert header["hidden"] == {"layers": sorted(want), "views": []}, (t, bake_frame_)
                # Hidden layers are still evaluated: the page needs their
                # points the moment they show.
                assert len(arrays[f"layer/{hair}/points"]) == 3 * scene["layers"][hair]["points"]
    # Nothing hidden in the fixture itself.
    with PreviewServer(FISH) as s:
        assert s.frame(time=1)[0]["hidden"] == {"layers": [], "views": []}


def test_a_hidden_view_mesh_keeps_its_colour_and_is_hidden(tmp_path):
    # The head's view-dependent mesh made invisible: its colour in the scene
    # is still its displayColor, and every frame lists it as hidden.
    path = tmp_path / "head.usda"
    shutil.copy(HEAD, path)
    stage = Usd.Stage.Open(str(path))
    with PreviewServer(HEAD) as s:
        shown = s.scene()["views"]
    assert len(shown) == 1
    UsdGeom.Imageable(stage.GetPrimAtPath(shown[0]["path"])).GetVisibilityAttr().Set("invisible")
    stage.GetRootLayer().Save()
    with PreviewServer(path) as s:
        views = s.scene()["views"]
        assert views == shown
        assert s.frame(time=1)[0]["hidden"] == {"layers": [], "views": [0]}


def bake_frame(tmp_path, src, t):
    out = tmp_path / f"bake_{t}.usdc"
    subprocess.run([str(painterly_binary()), "bake", str(src), "-o", str(out), "--frames", str(t), "--quiet"], check=True)
    return Usd.Stage.Open(str(out))


def test_timeline_frames_are_the_bakes_frames(fish, tmp_path):
    scene = fish.scene()
    for t in [1, 30]:
        bake = bake_frame(tmp_path, FISH, t)
        header, arrays = fish.frame(time=t)
        assert header["time"] == t
        for i, info in enumerate(scene["layers"]):
            prim = bake.GetPrimAtPath(info["path"])
            pts = np.array(prim.GetAttribute("points").Get(t), dtype=np.float32).ravel()
            np.testing.assert_array_equal(arrays[f"layer/{i}/points"], pts, err_msg=f"{info['path']} at {t}")
            op = np.array(prim.GetAttribute("primvars:displayOpacity").Get(t), dtype=np.float32)
            np.testing.assert_array_equal(arrays[f"layer/{i}/opacity"], op)
        timing = header["timing"]
        assert 0 <= timing["read_ms"] <= timing["total_ms"]


def test_pinned_axes_give_the_bake_of_a_stage_authored_that_way(fish, tmp_path):
    # A copy whose blink and eye target hold still: its bake at frame 5 is
    # what the original must show with those axes pinned (pose mode).
    t = 5

    def hold_still(stage):
        blink = stage.GetPrimAtPath("/Blowfish").GetAttribute("blink")
        blink.Clear()
        blink.Set(0.7)
        target = UsdGeom.Xformable(stage.GetPrimAtPath("/Blowfish/EyeTarget"))
        op = target.GetOrderedXformOps()[0]
        held = Gf.Vec3d(op.Get(t)) + Gf.Vec3d(0.4, -0.3, 0.2)
        op.GetAttr().Clear()
        op.Set(held)

    copy, _ = edited_fish(tmp_path, hold_still, "still.usda")
    # The eye axes, derived here with usd-core: the target's world origin
    # in the proxy's local space, times `scale` where the server's
    # unpinned values at this frame say the axes are scaled.
    s2 = Usd.Stage.Open(str(copy))
    proxy = UsdGeom.Xformable(s2.GetPrimAtPath("/Blowfish/Rig/Proxy")).ComputeLocalToWorldTransform(t)
    world = UsdGeom.Xformable(s2.GetPrimAtPath("/Blowfish/EyeTarget")).ComputeLocalToWorldTransform(t).ExtractTranslation()
    local = proxy.GetInverse().Transform(world)
    conf = fish.frame(time=t)[0]["configuration"]
    s1 = Usd.Stage.Open(str(FISH))
    p1 = UsdGeom.Xformable(s1.GetPrimAtPath("/Blowfish/Rig/Proxy")).ComputeLocalToWorldTransform(t)
    w1 = UsdGeom.Xformable(s1.GetPrimAtPath("/Blowfish/EyeTarget")).ComputeLocalToWorldTransform(t).ExtractTranslation()
    raw_x = p1.GetInverse().Transform(w1)[0]
    scale = 0.5 if abs(conf["/Blowfish/Paint/eyeX"] - 0.5 * raw_x) < 1e-6 else 1.0
    assert abs(conf["/Blowfish/Paint/eyeX"] - scale * raw_x) < 1e-6
    overrides = {
        "/Blowfish/Paint/blink": 0.7,
        "/Blowfish/Paint/eyeX": scale * local[0],
        "/Blowfish/Paint/eyeY": scale * local[1],
    }
    header, arrays = fish.frame(time=t, overrides=overrides)
    for k, v in overrides.items():
        assert header["configuration"][k] == pytest.approx(v, abs=1e-12)
    bake = bake_frame(tmp_path, copy, t)
    changed = 0
    plain = fish.frame(time=t)[1]
    for i, info in enumerate(fish.scene()["layers"]):
        prim = bake.GetPrimAtPath(info["path"])
        pts = np.array(prim.GetAttribute("points").Get(t), dtype=np.float32).ravel()
        np.testing.assert_allclose(arrays[f"layer/{i}/points"], pts, atol=2e-5, err_msg=info["path"])
        op = np.array(prim.GetAttribute("primvars:displayOpacity").Get(t), dtype=np.float32)
        np.testing.assert_allclose(arrays[f"layer/{i}/opacity"], op, atol=2e-6, err_msg=info["path"])
        changed += not np.array_equal(arrays[f"layer/{i}/points"], plain[f"layer/{i}/points"])
        changed += not np.array_equal(arrays[f"layer/{i}/opacity"], plain[f"layer/{i}/opacity"])
    assert changed >= 2, "pinning blink and the eye must change the pupils and the eyelids"
    weights = header["weights"]["/Blowfish/Paint/Eyelids"]["opacity"]
    ws = {(k or "/rest").rsplit("/", 1)[1]: w for k, w in weights}
    assert abs(sum(ws.values()) - 1) < 1e-9, ws
    assert ws.get("shut", 0) > ws.get("open", 0), ws


def test_render_returns_a_png_of_the_asked_size(fish):
    cam = start_camera(fish.scene()["view"])
    status, headers, body = fish.request("api/render", body={"frame": {"time": 24}, "camera": cam, "width": 96, "height": 64})
    assert status == 200, body
    assert headers["content-type"] == "image/png"
    img = Image.open(io.BytesIO(body))
    assert img.size == (96, 64)
    alpha = np.array(img.convert("RGBA"))[..., 3]
    assert alpha.max() > 0, "the fish is in view"


def test_bad_inputs_exit_1_without_serving(tmp_path):
    missing = tmp_path / "missing.usda"
    r = subprocess.run([str(painterly_binary()), "preview", str(missing), "--port", "0"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1
    assert str(missing) in r.stderr
    bad = tmp_path / "bad.usda"
    bad.write_text("#usda 1.0\ndef Xform \"A\" {\n")
    r = subprocess.run([str(painterly_binary()), "preview", str(bad), "--port", "0"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and "bad.usda" in r.stderr


@pytest.mark.parametrize("camera, what", [
    ("/Head/Camera.focalLength", "is a property path, not a prim path"),
    ("/Head/Camera{v=x}", "is a variant selection path, not a prim path"),
    ("Head/Camera", "is a relative path, not an absolute prim path"),
])
def test_a_camera_that_is_not_a_prim_path_is_a_usage_error_without_serving(camera, what):
    """usd-core's GetPrimAtPath finds no prim there: --camera refuses it
    (exit 2, as bake and render do) instead of starting at /Head/Camera."""
    args = [str(painterly_binary()), "preview", str(HEAD), "--port", "0", "--camera", camera]
    try:
        r = subprocess.run(args, capture_output=True, text=True, timeout=30)
    except subprocess.TimeoutExpired as e:  # run() killed the server it started
        pytest.fail(f"preview served with --camera {camera}: {e.stdout!r}")
    assert r.returncode == 2, r.stderr
    assert f"--camera {camera} {what}" in r.stderr and r.stdout == ""


def test_a_busy_port_is_a_clear_error(fish):
    port = int(fish.url.rsplit(":", 1)[1].strip("/"))
    r = subprocess.run([str(painterly_binary()), "preview", str(FISH), "--port", str(port)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 1
    assert f"127.0.0.1:{port}" in r.stderr


def test_a_render_of_the_bake_draws_the_bake_even_when_stale(tmp_path):
    """`/api/render` with `"bake": true` draws the `--bake` layer over the
    input (the page's "show bake"), as `/api/frame` serves it: after the
    input changed, the bake still shows the strokes as they were baked,
    the live render the new ones, and the scene says the bake is stale.
    Without `--bake` the request is refused, as `/api/frame`'s is."""
    path = tmp_path / "blowfish.usda"
    shutil.copy(FISH, path)
    bake = tmp_path / "fish_bake.usdc"
    subprocess.run([str(painterly_binary()), "bake", str(path), "-o", str(bake), "--frames", "1:48", "--quiet"], check=True)
    frame = {"time": 12}
    with PreviewServer(path, "--bake", bake) as s:
        cam = start_camera(s.scene()["view"])
        live_before = render_rgba(s, frame, cam, 96, 64)
        assert np.array_equal(render_rgba(s, {**frame, "bake": True}, cam, 96, 64), live_before)
    stage = Usd.Stage.Open(str(path))
    rest = stage.GetPrimAtPath("/Blowfish/Paint/Spikes").GetAttribute("painterly:restPoints")
    rest.Set([p * 1.3 for p in rest.Get()])
    stage.GetRootLayer().Save()
    with PreviewServer(path, "--bake", bake) as s:
        messages = [p["message"] for p in s.scene()["problems"]]
        assert messages == [
            f"{path} changed since this bake was made (its layers differ from the bake's inputStamp): "
            f"strokes show the old bake; bake again (painterly bake {path} -o {bake} --frames 1:48:1)"
        ]
        baked = render_rgba(s, {**frame, "bake": True}, cam, 96, 64)
        live = render_rgba(s, frame, cam, 96, 64)
    assert np.array_equal(baked, live_before)
    assert np.abs(live - live_before).max() > 0
    with PreviewServer(path) as s:
        status, _, body = s.request("api/render", body={"frame": {**frame, "bake": True}, "camera": cam, "width": 96, "height": 64})
        assert (status, json.loads(body)["error"]) == (422, "no --bake layer was given to painterly preview")


def test_bake_layer_frames_are_served_as_baked(tmp_path):
    bake = tmp_path / "fish_bake.usdc"
    subprocess.run([str(painterly_binary()), "bake", str(FISH), "-o", str(bake), "--frames", "10:12", "--quiet"], check=True)
    before = sha(bake)
    with PreviewServer(FISH, "--bake", bake) as s:
        scene = s.scene()
        assert scene["bake"] == str(bake)
        # The stage runs 1:48; the preview's timeline ends are outside the
        # bake's 10:12, and it says so as `render --bake` does.
        assert scene["problems"] == [
            {
                "prim": None,
                "attribute": None,
                "message": "2 frames outside the bake's frames 10:12 (1, 48): strokes there show their authored points",
            }
        ]
        stage = Usd.Stage.Open(str(bake))
        header, arrays = s.frame(time=11, bake=True)
        assert header["source"] == "bake"
        live = s.frame(time=11)[1]
        for i, info in enumerate(scene["layers"]):
            pts = np.array(stage.GetPrimAtPath(info["path"]).GetAttribute("points").Get(11), dtype=np.float32).ravel()
            np.testing.assert_array_equal(arrays[f"layer/{i}/points"], pts)
            np.testing.assert_array_equal(live[f"layer/{i}/points"], pts)
    assert sha(bake) == before
    # A bake of another input is refused.
    other = tmp_path / "head_bake.usdc"
    subprocess.run([str(painterly_binary()), "bake", str(HEAD), "-o", str(other), "--frames", "1", "--quiet"], check=True)
    r = subprocess.run(
        [str(painterly_binary()), "preview", str(FISH), "--bake", str(other), "--port", "0"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 1 and "not from the input" in r.stderr


def test_scene_lists_the_stages_problems_as_inspect_does(tmp_path):
    # A sentinel that carries an opacity: the bake ignores it, inspect flags
    # it, and the preview (which still opens) shows the same problem.
    def add_sentinel(stage):
        layer = next(p for p in stage.Traverse() if p.GetTypeName() == "BasisCurves")
        key = stage.DefinePrim(layer.GetPath().AppendChild("badSentinel"), "PainterlyTimeKey")
        key.CreateAttribute("time", Sdf.ValueTypeNames.Double).Set(20.0)
        key.CreateAttribute("sentinel", Sdf.ValueTypeNames.Bool).Set(True)
        key.CreateAttribute("opacity", Sdf.ValueTypeNames.Float).Set(0.5)

    src, stage = edited_fish(tmp_path, add_sentinel)
    key = next(p for p in stage.Traverse() if p.GetName() == "badSentinel")
    want = {
        "prim": str(key.GetPath()),
        "attribute": "opacity",
        "message": "a sentinel carries no opacity: it would be ignored (set `sentinel = 0` for a time key)",
    }
    proc = subprocess.run([str(painterly_binary()), "inspect", str(src), "--json"], capture_output=True, text=True)
    assert proc.returncode == 1, proc.stderr
    assert [{k: p[k] for k in want} for p in json.loads(proc.stdout)["problems"]] == [want]
    with PreviewServer(src) as s:
        assert s.scene()["problems"] == [want]


def test_weights_cover_every_keyed_layer_time_keys_alone_included(tmp_path):
    # The Mouth gets position time keys only (no axes, no opacity keys):
    # sentinel at 10, a key at 20, sentinel at 30 (SPEC 1.1 §5).
    def add_time_keys(stage):
        mouth = stage.GetPrimAtPath("/Blowfish/Paint/Mouth")
        rest = mouth.GetAttribute("points").Get()
        for name, t, sentinel in [("open", 10, True), ("gape", 20, False), ("close", 30, True)]:
            k = stage.DefinePrim(mouth.GetPath().AppendChild(name), "PainterlyTimeKey")
            k.CreateAttribute("time", Sdf.ValueTypeNames.Double).Set(float(t))
            if sentinel:
                k.CreateAttribute("sentinel", Sdf.ValueTypeNames.Bool).Set(True)
            else:
                k.CreateAttribute("points", Sdf.ValueTypeNames.Point3fArray).Set(rest)

    src, stage = edited_fish(tmp_path, add_time_keys)
    keyed = {
        str(l.GetPath())
        for l in stage.GetPrimAtPath("/Blowfish/Paint").GetChildren()
        if any(c.GetTypeName() in ("PainterlyPoseKey", "PainterlyTimeKey") for c in l.GetChildren())
    }
    assert "/Blowfish/Paint/Mouth" in keyed and len(keyed) == 6
    # Weight of the key between a sentinel and it: S_0.2(u), u the way from
    # the sentinel; S(u) = u^2 / 0.32 up to u = 0.2 (0.125 there), then
    # slope 1.25. Outside the sentinels only the rest value counts.
    gape = "/Blowfish/Paint/Mouth/gape"
    want = {
        5: [[None, 1.0]],
        11: [[None, 1 - 0.03125], [gape, 0.03125]],
        12.5: [[None, 1 - 0.1875], [gape, 0.1875]],
        20: [[gape, 1.0]],
        35: [[None, 1.0]],
    }
    with PreviewServer(src) as s:
        for t, position in want.items():
            weights = s.frame(time=t)[0]["weights"]
            assert set(weights) == keyed, t
            got = weights["/Blowfish/Paint/Mouth"]
            assert got["opacity"] == [[None, 1.0]], t
            assert [k for k, _ in got["position"]] == [k for k, _ in position], (t, got)
            np.testing.assert_allclose([w for _, w in got["position"]], [w for _, w in position], atol=1e-12, err_msg=str(t))


def test_mesh_infos_are_the_drawn_meshes_own():
    # The head's one Mesh is its proxy and its view-dependent mesh: both
    # entries carry its topology, its displayColor and its subdivision
    # scheme ("none": not smooth), read here with usd-core.
    stage = Usd.Stage.Open(str(HEAD))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Head/Face"))
    counts = list(mesh.GetFaceVertexCountsAttr().Get())
    indices = list(mesh.GetFaceVertexIndicesAttr().Get())
    color = list(mesh.GetDisplayColorAttr().Get()[0])
    smooth = mesh.GetSubdivisionSchemeAttr().Get() != "none"
    assert not smooth
    with PreviewServer(HEAD) as s:
        scene = s.scene()
    infos = scene["proxies"] + scene["views"]
    assert [i["path"] for i in infos] == ["/Head/Face", "/Head/Face"]
    for info in infos:
        assert info["face_counts"] == counts and info["face_indices"] == indices
        np.testing.assert_allclose(info["color"], color, rtol=0, atol=1e-7)
        assert info["smooth"] == smooth


def test_render_keeps_an_authored_curve_shaped_unlike_its_layer(tmp_path):
    # At frame 5 the Mouth's authored curves have another shape (a point
    # fewer in the first stroke) and sit far off screen. The evaluated
    # strokes cannot be drawn on that shape, so the render shows the
    # authored curves: the frame looks as if the Mouth were invisible.
    def reshaped(stage):
        # Frame 1 keeps the authored values; frame 5 drops the first point.
        mouth = stage.GetPrimAtPath("/Blowfish/Paint/Mouth")
        counts, points, widths = (mouth.GetAttribute(n) for n in ["curveVertexCounts", "points", "widths"])
        c, p, w = list(counts.Get()), list(points.Get()), list(widths.Get())
        for attr in (counts, points, widths):
            attr.Set(attr.Get(), 1.0)
        counts.Set(Vt.IntArray([c[0] - 1] + c[1:]), 5.0)
        points.Set(Vt.Vec3fArray([Gf.Vec3f(x) + Gf.Vec3f(1000, 0, 0) for x in p[1:]]), 5.0)
        widths.Set(Vt.FloatArray(w[1:]), 5.0)

    def hidden(stage):
        UsdGeom.Imageable(stage.GetPrimAtPath("/Blowfish/Paint/Mouth")).MakeInvisible()

    images = []
    for path in [FISH, edited_fish(tmp_path, reshaped, "reshaped.usda")[0], edited_fish(tmp_path, hidden, "hidden.usda")[0]]:
        with PreviewServer(path) as s:
            images.append(render_rgba(s, {"time": 5}, start_camera(s.scene()["view"]), 192, 128))
    plain, reshaped_img, hidden_img = images
    assert np.abs(plain - hidden_img).max() > 0, "the Mouth is in view"
    np.testing.assert_array_equal(reshaped_img, hidden_img)


def gf_flat(m):
    """A GfMatrix4d as the frame format's 16 floats: Gf's rows (row vectors) are glam's columns."""
    return np.array(m, dtype=np.float64).ravel()


def test_frame_xforms_are_usd_local_to_world(fish):
    t = 12
    scene = fish.scene()
    stage = Usd.Stage.Open(str(FISH))
    header, arrays = fish.frame(time=t, proxy=True)
    paths = [(f"layer/{i}", l["path"]) for i, l in enumerate(scene["layers"])]
    paths += [(f"proxy/{i}", p["path"]) for i, p in enumerate(scene["proxies"])]
    assert any(k.startswith("proxy/") and f"{k}/xform" in arrays for k, _ in paths)
    for key, path in paths:
        if f"{key}/xform" not in arrays:
            continue
        want = gf_flat(UsdGeom.Xformable(stage.GetPrimAtPath(path)).ComputeLocalToWorldTransform(t))
        np.testing.assert_allclose(arrays[f"{key}/xform"], want, atol=1e-5, err_msg=path)


def test_layer_time_keys_and_axis_kinds_come_from_the_stage(fish):
    scene = fish.scene()
    stage = Usd.Stage.Open(str(FISH))
    for info in scene["layers"]:
        # Sentinels (hold markers, no pose) are counted apart.
        keys = [c for c in stage.GetPrimAtPath(info["path"]).GetChildren() if c.GetTypeName() == "PainterlyTimeKey"]
        assert info["time_keys"] == sum(not k.GetAttribute("sentinel").Get() for k in keys), info["path"]
    assert {l["path"].rsplit("/", 1)[1]: l["time_keys"] for l in scene["layers"]}["Spikes"] == 2
    for a in scene["axes"]:
        assert a["kind"] == stage.GetPrimAtPath(a["path"]).GetAttribute("kind").Get(), a["path"]


def fish_axis_values(stage, path, t):
    """An attribute or blend-shape axis's value at `t`, read with usd-core."""
    axis = stage.GetPrimAtPath(path)
    kind = axis.GetAttribute("kind").Get()
    if kind == "attribute":
        return stage.GetAttributeAtPath("/Blowfish.blink").Get(t)
    if kind == "blendShape":
        anim = stage.GetPrimAtPath("/Blowfish/Rig/Skel/Anim")
        names = list(anim.GetAttribute("blendShapes").Get())
        return anim.GetAttribute("blendShapeWeights").Get(t)[names.index(axis.GetAttribute("name").Get())]
    raise AssertionError(f"{path}: kind {kind}")


def assert_axis_ranges(scene, stage, frames):
    """Slider range: the hull of the axis's key coordinates and its values
    at `frames`, padded by 10 %. The eye axes' values are the rig's own
    measure; blink and inflate are read straight from their sources."""
    for a in scene["axes"]:
        if a["kind"] not in ("attribute", "blendShape"):
            continue
        values = [fish_axis_values(stage, a["path"], t) for t in frames]
        for layer in stage.GetPrimAtPath("/Blowfish/Paint").GetChildren():
            axes = [str(p) for p in layer.GetRelationship("painterly:axes").GetTargets()] if layer.HasRelationship("painterly:axes") else []
            if a["path"] not in axes:
                continue
            j = axes.index(a["path"])
            for key in layer.GetChildren():
                if key.GetTypeName() == "PainterlyPoseKey":
                    values.append(key.GetAttribute("coordinates").Get()[j])
        lo, hi = min(values), max(values)
        pad = 0.1 * (hi - lo) if hi - lo > 1e-9 else 1.0
        assert a["min"] == pytest.approx(lo - pad, abs=1e-6), a["path"]
        assert a["max"] == pytest.approx(hi + pad, abs=1e-6), a["path"]


def test_axis_ranges_pad_the_key_marks_and_the_timeline_by_a_tenth(fish):
    # 48 frames: the timeline is sampled at every integer frame.
    assert_axis_ranges(fish.scene(), Usd.Stage.Open(str(FISH)), range(1, 49))


def test_axis_ranges_cover_the_animation_beyond_the_keys(tmp_path):
    # The fish's blink stays inside its keys' [0, 1], so its range test sees
    # no sample of the timeline. Here blink leaves the keys both ways: 2 at
    # the first frame (2, not 1, so a start that multiplies is not a start
    # that adds) and a one-frame dip to -5 at frame 17, which only a sample
    # on that integer frame sees (linear interpolation between samples).
    # The hull's ends sum to less than zero: the pad depends on hi - lo only.
    def wander(stage):
        stage.SetStartTimeCode(2)
        blink = stage.GetAttributeAtPath("/Blowfish.blink")
        blink.Clear()
        for t, v in {2: 2.0, 16: 0.0, 17: -5.0, 18: 0.0, 48: 0.5}.items():
            blink.Set(v, t)

    path, stage = edited_fish(tmp_path, wander)
    with PreviewServer(path) as s:
        scene = s.scene()
    assert (scene["start"], scene["end"]) == (2, 48)
    blink_axis = next(a for a in scene["axes"] if a["path"] == "/Blowfish/Paint/blink")
    # By hand: the hull is [-5, 2] (keys within [0, 1]), padded by 0.7.
    assert (blink_axis["min"], blink_axis["max"]) == (pytest.approx(-5.7, abs=1e-6), pytest.approx(2.7, abs=1e-6))
    assert_axis_ranges(scene, stage, range(2, 49))


def test_scene_bounds_are_the_start_frames_world_box(fish, tmp_path):
    # Every layer's points as baked, and the posed proxy, in world space.
    scene = fish.scene()
    t = scene["start"]
    bake = bake_frame(tmp_path, FISH, int(t))
    stage = Usd.Stage.Open(str(FISH))
    _, arrays = fish.frame(time=t, proxy=True)
    pts = []
    for info in scene["layers"]:
        p = np.array(bake.GetPrimAtPath(info["path"]).GetAttribute("points").Get(t), dtype=np.float64)
        pts.append((p, info["path"]))
    for i, p in enumerate(scene["proxies"]):
        if f"proxy/{i}/points" in arrays:
            pts.append((arrays[f"proxy/{i}/points"].reshape(-1, 3).astype(np.float64), p["path"]))
    world = []
    for p, path in pts:
        m = np.array(UsdGeom.Xformable(stage.GetPrimAtPath(path)).ComputeLocalToWorldTransform(t))
        world.append(p @ m[:3, :3] + m[3, :3])
    world = np.concatenate(world)
    np.testing.assert_allclose(scene["bounds"], [world.min(axis=0), world.max(axis=0)], atol=1e-4)


def test_render_shows_the_evaluated_pose_not_the_authored_curves(fish):
    # Inflating changes the spikes and cheeks: two renders must differ.
    cam = start_camera(fish.scene()["view"])
    imgs = [render_rgba(fish, {"time": 1, "overrides": {"/Blowfish/Paint/inflate": w}}, cam, 96, 64) for w in [0.0, 1.0]]
    assert np.abs(imgs[0] - imgs[1]).max() > 0


def test_the_orbit_starts_at_the_view_meshes_camera():
    stage = Usd.Stage.Open(str(HEAD))
    t = stage.GetStartTimeCode()
    prim = stage.GetPrimAtPath("/Head/Camera")
    m = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t)
    cam = UsdGeom.Camera(prim).GetCamera(t)
    fov = 2 * np.degrees(np.arctan(0.5 * cam.verticalAperture / cam.focalLength))
    up = np.array(m.TransformDir(Gf.Vec3d(0, 1, 0)).GetNormalized())
    with PreviewServer(HEAD) as s:
        v = s.scene()["view"]
    assert v["camera"] == "/Head/Camera"
    np.testing.assert_allclose(v["position"], np.array(m.ExtractTranslation()), atol=1e-6)
    np.testing.assert_allclose(v["up"], up, atol=1e-6)
    assert v["fov_y"] == pytest.approx(fov, abs=1e-4)
    assert v["aspect"] == pytest.approx(cam.horizontalAperture / cam.verticalAperture, rel=1e-6)


def test_render_shows_the_view_mesh_the_eye_drives(tmp_path):
    # The building's one view key (cosine mode): seen from the key's own
    # direction the box is the key's points, from the opposite side the
    # base model (SPEC §6), 85 units apart. The render camera stays put, so
    # the two renders differ only if the evaluated mesh replaces the
    # authored one.
    path = REPO / "fixtures" / "building.usda"
    stage = Usd.Stage.Open(str(path))
    box = stage.GetPrimAtPath("/Building/Box")
    pts = np.array(box.GetAttribute("points").Get(1), dtype=np.float64)
    centre = (pts.min(axis=0) + pts.max(axis=0)) / 2
    d = np.array(stage.GetPrimAtPath("/Building/Box/Front").GetAttribute("direction").Get(), dtype=np.float64)
    d /= np.linalg.norm(d)
    m = np.array(UsdGeom.Xformable(box).ComputeLocalToWorldTransform(1))
    imgs = []
    with PreviewServer(path) as s:
        cam = start_camera(s.scene()["view"], near=1, far=100000)
        for side in [1.0, -1.0]:
            eye = np.append(centre + side * 2000 * d, 1.0) @ m
            imgs.append(render_rgba(s, {"time": 1, "eye": eye[:3].tolist()}, cam, 96, 64))
    assert imgs[0][..., 3].max() > 0, "the building is in view"
    assert np.abs(imgs[0] - imgs[1]).max() > 0


def test_the_slider_stream_answers_like_the_frame_route(fish):
    """`GET /api/ws` (docs/preview.md): each text message is a frame request,
    answered by the bytes `POST /api/frame` gives for it, or by a text
    {"id", "status", "error"}; a request of a few KiB is fine."""
    axis = fish.scene()["axes"][0]["path"]
    req = {"id": 7, "time": 12, "overrides": {axis: 0.25}}
    status, _, http = fish.request("api/frame", body=req)
    assert status == 200
    want_header, want_arrays = decode_frame(http)
    del want_header["timing"]  # how long each stage took, per request

    def same_frame(message):
        op, body = message
        header, arrays = decode_frame(body)
        del header["timing"]
        assert op == 2 and header == want_header and header["id"] == 7
        assert arrays.keys() == want_arrays.keys()
        for name, values in arrays.items():
            np.testing.assert_array_equal(values, want_arrays[name], err_msg=name)

    ws = WebSocket(fish.url)
    try:
        ws.send(json.dumps(req))
        same_frame(ws.recv())
        # Padded to 3 KiB with JSON whitespace: still one frame request.
        ws.send(json.dumps(req) + " " * 3000)
        same_frame(ws.recv())
        ws.send("{not json")
        op, body = ws.recv()
        reply = json.loads(body)
        assert op == 1 and (reply["id"], reply["status"]) == (0, 400) and reply["error"].startswith("bad request: ")
        # JSON with a readable id but an unknown field: the error carries the id.
        ws.send(json.dumps({"id": 9, "time": 1, "bogus": 2}))
        reply = json.loads(ws.recv()[1])
        assert (reply["id"], reply["status"]) == (9, 400) and "unknown field `bogus`" in reply["error"]
        ws.send(json.dumps({"id": -1, "time": 1, "bogus": 2}))
        assert json.loads(ws.recv()[1])["id"] == 0
        ws.send(json.dumps({"id": 3, "time": 1, "overrides": {"/Blowfish/Nope": 1}}))
        assert json.loads(ws.recv()[1]) == {
            "id": 3, "status": 400, "error": "/Blowfish/Nope is not an axis of this character"}
        ws.send(b"\x00\x01", opcode=2)
        assert json.loads(ws.recv()[1]) == {"id": 0, "status": 400, "error": "send frame requests as JSON text"}
    finally:
        ws.close()


def test_the_slider_stream_closes_on_a_message_over_64_kib(fish):
    """A frame request is a few hundred bytes; the stream refuses anything
    over 64 KiB by closing, and the server goes on serving."""
    ws = WebSocket(fish.url)
    try:
        ws.send(json.dumps({"id": 1, "time": 1}) + " " * (64 * 1024))
        try:
            op, _ = ws.recv()
            assert op == 8, op  # a close frame (1009, message too big)
        except (EOFError, ConnectionResetError):
            pass
    finally:
        ws.close()
    assert fish.frame(time=1)[0]["time"] == 1


EVERY = "(serving every address of this machine; Ctrl-C stops)"


@pytest.mark.parametrize("host,shown,serving", [
    ("localhost", "127.0.0.1", "(serving 127.0.0.1 only; Ctrl-C stops)"),
    ("127.0.0.2", "127.0.0.2", "(serving 127.0.0.2 only; Ctrl-C stops)"),
    ("0.0.0.0", "127.0.0.1", EVERY),
    ("::1", "[::1]", "(serving ::1 only; Ctrl-C stops)"),
    ("::", "[::1]", EVERY),
])
def test_host_takes_localhost_and_every_address_prints_an_openable_url(host, shown, serving):
    """The URL printed is one a browser on this machine opens: the address
    served, or the loopback when every address is served."""
    with PreviewServer(FISH, "--host", host) as s:
        assert re.fullmatch(re.escape(f"http://{shown}:") + r"\d+/", s.url), s.url
        assert s.proc.stdout.readline() == serving + "\n"
        assert s.scene()["file"] == str(FISH)
    r = subprocess.run([str(painterly_binary()), "preview", str(FISH), "--host", "example.com"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "\"example.com\" is not an IP address (or localhost)" in r.stderr


def test_stroke_widths_follow_an_animated_scale(tmp_path):
    """Widths were sent in world units at the start frame and drawn so at
    every frame: with /Blowfish scaled 1 → 3 over the shot, a Spots stroke
    drew 0.105 wide at frame 48 where render draws 0.315 (a preview review,
    2026-12-06). They are sent in the layer's own space now, and the page
    scales them by each frame's layer transform, as render does: the two
    together give usd-core's widths times the world scale at that frame."""
    src = tmp_path / "fish.usda"
    shutil.copy(FISH, src)
    stage = Usd.Stage.Open(str(src))
    op = UsdGeom.Xformable(stage.GetPrimAtPath("/Blowfish")).AddScaleOp(opSuffix="grow")
    op.Set(Gf.Vec3f(1, 1, 1), 1)
    op.Set(Gf.Vec3f(3, 3, 3), 48)
    stage.GetRootLayer().Save()
    with PreviewServer(src) as server:
        scene = server.scene()
        _, statics = decode_frame(server.request("api/strokes")[2])
        _, arrays = server.frame(time=48)
        for i, info in enumerate(scene["layers"]):
            prim = stage.GetPrimAtPath(info["path"])
            widths = np.array(UsdGeom.BasisCurves(prim).GetWidthsAttr().Get(), dtype=np.float64)
            world = np.array(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(48))[:3, :3]
            want = widths * np.cbrt(abs(np.linalg.det(world)))
            xform = np.asarray(arrays[f"layer/{i}/xform"], dtype=np.float64).reshape(4, 4)[:3, :3]
            drawn = np.asarray(statics[f"layer/{i}/widths"]) * np.cbrt(abs(np.linalg.det(xform)))
            if len(widths) == len(drawn):
                np.testing.assert_allclose(drawn, want, rtol=1e-5, err_msg=info["path"])


# ---------------------------------------------------------------------------
# found by a preview review (2026-12-06)


def test_a_guide_proxy_with_only_time_sampled_points_and_a_rest_time_is_served(tmp_path):
    """bake and inspect accept it (SPEC §2: the rest pose is read at
    painterly:restTime); preview refused to start, asking for the restTime
    that is there, because it read the guide proxy's points for its faces."""
    src = tmp_path / "wave.usda"
    shutil.copy(REPO / "fixtures" / "wave.usda", src)
    stage = Usd.Stage.Open(str(src))
    proxy = stage.GetPrimAtPath("/Wave/Rig/Proxy")
    assert proxy.GetAttribute("purpose").Get() == "guide"
    proxy.GetAttribute("points").ClearDefault()
    stage.GetRootLayer().Save()
    with PreviewServer(src) as server:
        scene = server.scene()
        counts = UsdGeom.Mesh(proxy).GetFaceVertexCountsAttr().Get()
        assert [p["face_counts"] for p in scene["proxies"]] == [list(counts)]


def test_the_start_view_looks_where_the_camera_looks(tmp_path):
    """docs/preview.md: the orbit starts at --camera, its pose and field of
    view. It kept the position but aimed at the scene's centre, 12.7° off a
    camera aimed past the fish."""
    src = tmp_path / "fish.usda"
    shutil.copy(FISH, src)
    stage = Usd.Stage.Open(str(src))
    cam = UsdGeom.Camera.Define(stage, "/Cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(4, 6, 22))
    cam.AddRotateXYZOp().Set(Gf.Vec3f(-8, 25, 0))
    stage.GetRootLayer().Save()
    forward = np.array(UsdGeom.Xformable(stage.GetPrimAtPath("/Cam")).ComputeLocalToWorldTransform(1)
                       .TransformDir(Gf.Vec3d(0, 0, -1)))
    with PreviewServer(src, "--camera", "/Cam") as server:
        view = server.scene()["view"]
    aim = np.array(view["target"]) - np.array(view["position"])
    np.testing.assert_allclose(view["position"], [4, 6, 22], atol=1e-9)
    np.testing.assert_allclose(aim / np.linalg.norm(aim), forward / np.linalg.norm(forward), atol=1e-9)


@pytest.mark.parametrize("method, path, body, status, needle", [
    ("GET", "api/frame", None, 405, "this address does not take that method"),
    ("POST", "api/scene", {}, 405, "this address does not take that method"),
    ("POST", "api/frame", {"time": 1, "pad": "x" * 3_000_000}, 413, "the request body is over the 2 MB limit"),
])
def test_errors_axum_answers_itself_are_json_too(fish, method, path, body, status, needle):
    """They were plain text (413) or empty (405), unlike every other error."""
    got, headers, data = fish.request(path, body=body, method=method)
    assert got == status
    assert json.loads(data) == {"error": needle} or needle in json.loads(data)["error"]


def test_a_character_preview_cannot_open_names_its_file(tmp_path):
    """An error after the character opened (an axis needing a camera) named
    no file."""
    src = tmp_path / "head.usda"
    shutil.copy(REPO / "fixtures" / "head.usda", src)
    stage = Usd.Stage.Open(str(src))
    stage.GetPrimAtPath("/Head/Paint/viewX").GetRelationship("source").SetTargets([])
    stage.GetRootLayer().Save()
    proc = subprocess.run([str(painterly_binary()), "preview", str(src), "--port", "0"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 1
    assert proc.stderr.startswith(f"error: {src}: /Head/Paint/viewX.source:"), proc.stderr


def test_a_closed_stdout_leaves_no_temporary_folder(tmp_path):
    """With --bake, preview makes a folder in TMPDIR before it prints its
    URL; a stdout whose reader had gone ended the run at that print (exit
    141) and left the folder."""
    bake = tmp_path / "bake.usdc"
    run_painterly("bake", FISH, "-o", bake, "--quiet")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    r, w = os.pipe()
    os.close(r)
    proc = subprocess.Popen([str(painterly_binary()), "preview", str(FISH), "--port", "0", "--bake", str(bake)],
                            stdout=w, stderr=subprocess.PIPE, env=dict(os.environ, TMPDIR=str(tmp)))
    os.close(w)
    try:
        code = proc.wait(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert code == 141, proc.stderr.read()
    assert list(tmp.iterdir()) == []


def test_a_frame_says_when_the_input_changed_on_disk(tmp_path):
    """The server reads the input once: an edit saved while it runs was not
    shown, and nothing said so (a preview review, 2026-12-06). Every live
    frame now carries `stale`, a message once a file the input reads has
    changed."""
    src = tmp_path / "fish.usda"
    shutil.copy(FISH, src)
    with PreviewServer(src) as server:
        header, _ = server.frame(time=24)
        assert header["stale"] is None
        layer = Sdf.Layer.FindOrOpen(str(src))
        layer.customLayerData = {"edited": True}
        layer.Save()
        header, _ = server.frame(time=24)
        assert header["stale"] == ("the input changed on disk since this preview opened it: "
                                   "restart `painterly preview` to see the edits")


@pytest.mark.parametrize("changed", ["bake", "input"])
def test_a_bake_frame_says_when_the_bake_or_the_input_changed_on_disk(tmp_path, changed):
    """`--bake` frames come from the files as the preview opened them, and,
    unlike live frames, carried no `stale`: a bake layer re-baked (or an
    input saved) while the preview ran went on showing the old frames with
    nothing said."""
    src = tmp_path / "fish.usda"
    shutil.copy(FISH, src)
    bake = tmp_path / "fish_bake.usdc"
    subprocess.run([str(painterly_binary()), "bake", str(src), "-o", str(bake), "--frames", "1:2", "--quiet"], check=True)
    with PreviewServer(src, "--bake", bake) as server:
        assert server.frame(time=1, bake=True)[0]["stale"] is None
        layer = Sdf.Layer.FindOrOpen(str(bake if changed == "bake" else src))
        layer.customLayerData = dict(layer.customLayerData, edited=True)
        layer.Save()
        header, _ = server.frame(time=1, bake=True)
        assert header["stale"] == ("the bake layer or the input changed on disk since this preview opened them: "
                                   "restart `painterly preview` to see the new files")
        assert (server.frame(time=1)[0]["stale"] is None) == (changed == "bake")
