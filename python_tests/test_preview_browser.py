"""`painterly preview` in a real browser: Debian's chromium (headless,
SwiftShader WebGL2) driven by playwright-core (browser_tests/driver.mjs).

The page must load without a console error, draw, follow its sliders and
timeline with `painterly bake`'s frames (read back with usd-core), and
change a view-dependent mesh while orbiting with "view drives" on.
Screenshots of three fixtures are taken (scripts/preview_figures makes the
committed ones in docs/figures/).
"""

import contextlib
import shutil
import subprocess

import numpy as np
import pytest
from pxr import Usd

from conftest import REPO, painterly_binary
from preview_helpers import Browser, PreviewServer, browser_available

FISH = REPO / "fixtures" / "blowfish.usda"
HEAD = REPO / "fixtures" / "head.usda"
APPLE = REPO / "fixtures" / "apple.usda"


@pytest.fixture(scope="module")
def browser():
    why = browser_available()
    if why:
        pytest.fail(f"cannot run the browser tests: {why}")
    b = Browser()
    yield b
    b.close()


def open_page(browser, server):
    browser.call("goto", url=server.url)
    browser.settle(0)
    return browser


def canvas_pixels(browser, tmp_path, name):
    from PIL import Image

    path = tmp_path / f"{name}.png"
    browser.call("screenshot", selector="#live", path=str(path))
    return np.asarray(Image.open(path).convert("RGB"), dtype=np.int16)


def set_slider(browser, selector, value):
    """What a drag does: the range input's value changes, `input` fires."""
    browser.eval(
        f"""(() => {{ const e = document.querySelector({selector!r});
        e.value = {value!r}; e.dispatchEvent(new Event('input', {{bubbles: true}})); return e.value; }})()"""
    )


def bake(tmp_path, src, t):
    out = tmp_path / f"{src.stem}_bake_{t}.usdc"
    subprocess.run([str(painterly_binary()), "bake", str(src), "-o", str(out), "--frames", str(t), "--quiet"], check=True)
    return Usd.Stage.Open(str(out))


def test_page_loads_and_draws_without_console_errors(browser, tmp_path):
    with PreviewServer(FISH) as s:
        open_page(browser, s)
        assert browser.call("console")["errors"] == []
        assert browser.eval("window.painterly.errors") == []
        assert browser.eval("document.querySelectorAll('#layers tbody tr').length") == 14
        assert browser.eval("document.querySelectorAll('#axes input[type=range]').length") == 4
        # Key marks on the inflate slider: the Spikes' keys.
        assert browser.eval("document.querySelectorAll('#axes .mark').length") >= 4
        assert browser.eval("document.querySelector('#problems').textContent") == "none found"
        px = canvas_pixels(browser, tmp_path, "fish")
        paper = np.array([241, 237, 228])
        painted = np.abs(px - paper).sum(axis=2) > 30
        assert painted.mean() > 0.01, "strokes are drawn"
        assert browser.eval("window.painterly.framesDrawn") >= 1


def test_moving_a_slider_changes_pixels_and_serves_the_bakes_points(browser, tmp_path):
    # Pinning "blink" to 0.8 at frame 5 (eyes open there) must show what a
    # bake of a copy whose blink attribute is authored to 0.8 holds (an
    # independent stage, read back by usd-core): the eyelids' opacity keys.
    t = 5
    copy = tmp_path / "blink.usda"
    shutil.copy(FISH, copy)
    stage = Usd.Stage.Open(str(copy))
    attr = stage.GetPrimAtPath("/Blowfish").GetAttribute("blink")
    attr.Clear()
    attr.Set(0.8)
    stage.Save()
    baked = bake(tmp_path, copy, t)
    with PreviewServer(FISH) as s:
        open_page(browser, s)
        n = browser.eval("window.painterly.framesDrawn")
        set_slider(browser, "#time", t)
        browser.settle(n)
        before = canvas_pixels(browser, tmp_path, "before")
        n = browser.eval("window.painterly.framesDrawn")
        set_slider(browser, 'input[data-axis="/Blowfish/Paint/blink"]', 0.8)
        browser.settle(n)
        assert browser.eval("window.painterly.state.overrides") == {"/Blowfish/Paint/blink": 0.8}
        after = canvas_pixels(browser, tmp_path, "after")
        changed = (np.abs(after - before).sum(axis=2) > 30).sum()
        assert changed > 50, f"only {changed} pixels changed when the eyelids closed"
        scene = browser.eval("window.painterly.scene")
        for i, info in enumerate(scene["layers"]):
            prim = baked.GetPrimAtPath(info["path"])
            want = np.array(prim.GetAttribute("points").Get(t), dtype=np.float32).ravel()
            got = np.array(browser.eval(f"window.painterly.layerPoints({i})"), dtype=np.float32)
            np.testing.assert_array_equal(got, want, err_msg=info["path"])
            want = np.array(prim.GetAttribute("primvars:displayOpacity").Get(t), dtype=np.float32)
            got = np.array(browser.eval(f"window.painterly.layerOpacity({i})"), dtype=np.float32)
            np.testing.assert_allclose(got, want, atol=1e-6, err_msg=info["path"])
        assert browser.call("console")["errors"] == []


def test_timeline_shows_the_bakes_frame(browser, tmp_path):
    t = 30
    baked = bake(tmp_path, FISH, t)
    with PreviewServer(FISH) as s:
        open_page(browser, s)
        n = browser.eval("window.painterly.framesDrawn")
        set_slider(browser, "#time", t)
        browser.settle(n)
        assert browser.eval("document.querySelector('#time-value').textContent") == str(t)
        assert browser.eval("window.painterly.lastHeader.time") == t
        scene = browser.eval("window.painterly.scene")
        for i, info in enumerate(scene["layers"]):
            want = np.array(baked.GetPrimAtPath(info["path"]).GetAttribute("points").Get(t), dtype=np.float32).ravel()
            got = np.array(browser.eval(f"window.painterly.layerPoints({i})"), dtype=np.float32)
            np.testing.assert_array_equal(got, want, err_msg=info["path"])
        # The sliders follow the timeline: inflate is held at 1 at frame 30.
        assert float(browser.eval("document.querySelector('input[data-axis=\"/Blowfish/Paint/inflate\"]').value")) == 1.0
        # Play advances frames.
        n = browser.eval("window.painterly.framesDrawn")
        browser.call("click", selector="#play")
        browser.wait(f"window.painterly.framesDrawn > {n + 2}")
        browser.call("click", selector="#play")
        browser.settle()
        assert browser.eval("window.painterly.state.time") != t
        assert browser.call("console")["errors"] == []


@contextlib.contextmanager
def apple_on_the_same_port(browser, url, why):
    """A preview of the apple on the port of `url`, whose server (the fish)
    has stopped: moving the open page's timeline draws nothing and the
    status says `why` and to reload. Yields with the apple's server up."""
    drawn = browser.eval("window.painterly.framesDrawn")
    other = PreviewServer(APPLE)
    other.args[other.args.index("--port") + 1] = url.rstrip("/").rsplit(":", 1)[1]
    with other:
        assert other.url == url
        set_slider(browser, "#time", 5)
        status = browser.eval("document.querySelector('#status').textContent")
        assert status == f"{why}: reload this page once painterly preview runs again", status
        assert browser.eval("window.painterly.framesDrawn") == drawn
        yield other


def test_a_page_whose_server_restarted_asks_for_a_reload(browser, tmp_path):
    """The page drew a restarted server's frames against its old scene
    (another file on the same port: every layer vanished) with a normal
    status line (a review, 2026-12-07). Once its websocket closes it asks
    for no more frames and says to reload."""
    with PreviewServer(FISH) as s:
        open_page(browser, s)
        url = s.url
    browser.wait("window.painterly.lost === true")
    with apple_on_the_same_port(browser, url, "the preview server closed the connection"):
        # A reload shows the new server's scene.
        browser.call("goto", url=url)
        browser.settle(0)
        assert browser.eval("window.painterly.lost") is False
        assert browser.eval("window.painterly.scene.layers.length") > 0
        assert "apple.usda" in browser.eval("document.title")
    assert browser.call("console")["errors"] == []


def test_a_page_without_a_websocket_whose_server_restarted_asks_for_a_reload(browser, tmp_path):
    """The same on the page's HTTP fallback (a browser whose websocket cannot
    connect; a verification, 2026-12-07): a request that reaches no server
    stops the page, which does not draw the next server's frames."""
    no_socket = ("window.WebSocket = class { constructor() { setTimeout(() => { "
                 "if (this.onerror) this.onerror(); if (this.onclose) this.onclose(); }, 0); } "
                 "send() {} close() {} };")
    with PreviewServer(FISH) as s:
        browser.call("goto", url=s.url, init=no_socket)
        browser.settle(0)
        assert browser.eval("window.painterly.lost") is False
        url = s.url
    set_slider(browser, "#time", 3)
    browser.wait("window.painterly.lost === true")
    with apple_on_the_same_port(browser, url, "the preview server cannot be reached"):
        pass
    # The requests that found no server are the only errors (and are
    # forgotten, so that later tests start clean).
    errors = browser.call("console", clear=True)["errors"]
    assert errors and all(("/api/frame " in e and e.startswith("request failed: "))
                          or e == "console: Failed to load resource: net::ERR_CONNECTION_REFUSED"
                          for e in errors), errors


def test_orbiting_with_view_drives_changes_the_view_dependent_mesh(browser, tmp_path):
    with PreviewServer(HEAD) as s:
        open_page(browser, s)
        before = np.array(browser.eval("window.painterly.viewPoints(0)"))
        # Without "view drives" the head follows its USD camera: orbiting
        # changes only the picture.
        n = browser.eval("window.painterly.framesDrawn")
        browser.call("drag", selector="#live", dx=160, dy=0)
        browser.settle()
        assert browser.eval("window.painterly.framesDrawn") == n
        browser.call("click", selector="#view-drives")
        browser.settle(n)
        first = np.array(browser.eval("window.painterly.viewPoints(0)"))
        eye = browser.eval("window.painterly.lastHeader.eye")
        pose = browser.eval("window.painterly.cameraPose().position")
        np.testing.assert_allclose(eye, pose, rtol=1e-9)
        px1 = canvas_pixels(browser, tmp_path, "head1")
        n = browser.eval("window.painterly.framesDrawn")
        browser.call("drag", selector="#live", dx=-260, dy=40)
        browser.settle(n)
        second = np.array(browser.eval("window.painterly.viewPoints(0)"))
        assert np.abs(second - first).max() > 1e-3, "the head's shape follows the orbit camera"
        assert np.abs(first - before).max() > 1e-3
        px2 = canvas_pixels(browser, tmp_path, "head2")
        assert (np.abs(px2 - px1).sum(axis=2) > 30).sum() > 100
        # The viewDirection axes measure the orbit camera too.
        conf = browser.eval("window.painterly.lastHeader.configuration")
        assert set(conf) == {"/Head/Paint/viewX", "/Head/Paint/viewZ"}
        assert browser.call("console")["errors"] == []


def test_render_button_shows_painterly_render_beside(browser):
    size = "[document.querySelector('#live').clientWidth, document.querySelector('#live').clientHeight]"
    with PreviewServer(APPLE) as s:
        open_page(browser, s)
        alone = browser.eval(size)
        browser.call("click", selector="#render-button")
        browser.wait("window.painterly.rendered === 1", timeout=60000)
        browser.wait("document.querySelector('#render').complete && document.querySelector('#render').naturalWidth > 0")
        assert not browser.eval("document.querySelector('#render-figure').hidden")
        # The render is made at the live view's size beside it (the live view
        # was wider alone), so both show the same framing.
        beside = browser.eval(size)
        assert beside[0] < alone[0] * 0.75, (alone, beside)
        natural = browser.eval("[document.querySelector('#render').naturalWidth, document.querySelector('#render').naturalHeight]")
        assert natural == [min(1280, beside[0]), min(1280, beside[1])], (natural, beside)
        assert browser.call("console")["errors"] == []


def test_render_with_show_bake_renders_the_bake(browser, tmp_path):
    """With "show bake" ticked the render button asks for the bake, which
    the server draws as `render --bake` does (test_preview_server checks
    the pixels); the caption says so."""
    bake = tmp_path / "apple_bake.usdc"
    subprocess.run([str(painterly_binary()), "bake", str(APPLE), "-o", str(bake), "--frames", "1:48", "--quiet"], check=True)
    with PreviewServer(APPLE, "--bake", bake) as s:
        open_page(browser, s)
        browser.eval(
            """(() => { window.renderBodies = []; const f = window.fetch;
            window.fetch = (u, o) => { if (String(u).includes('api/render')) window.renderBodies.push(JSON.parse(o.body)); return f(u, o); };
            })()"""
        )
        n = browser.eval("window.painterly.framesDrawn")
        browser.call("click", selector="#show-bake")
        browser.settle(n)
        assert browser.eval("window.painterly.lastHeader.source") == "bake"
        browser.call("click", selector="#render-button")
        browser.wait("window.painterly.rendered === 1", timeout=60000)
        assert browser.eval("window.renderBodies.map(b => b.frame.bake)") == [True]
        assert browser.eval("document.querySelector('#render-caption').textContent").startswith("painterly render · bake · t=")
        assert browser.call("console")["errors"] == []


def test_an_invisible_layer_is_not_drawn(browser, tmp_path):
    # Spikes made invisible with usd-core: `render` leaves it out, and so
    # must the live view. Unchecking it changes nothing on the canvas (it
    # was not drawn), while unchecking a visible layer (Hair) does.
    from pxr import UsdGeom

    path = tmp_path / "blowfish.usda"
    shutil.copy(FISH, path)
    stage = Usd.Stage.Open(str(path))
    UsdGeom.Imageable(stage.GetPrimAtPath("/Blowfish/Paint/Spikes")).GetVisibilityAttr().Set("invisible")
    stage.GetRootLayer().Save()
    with PreviewServer(path) as s:
        index = {l["path"]: i for i, l in enumerate(s.scene()["layers"])}
        open_page(browser, s)
        struck = browser.eval("Array.from(document.querySelectorAll('#layers tr.hidden-now')).map(r => r.title)")
        assert len(struck) == 1 and struck[0].startswith("/Blowfish/Paint/Spikes: invisible at this time"), struck
        shown = canvas_pixels(browser, tmp_path, "shown")
        for name, changes in [("Spikes", False), ("Hair", True)]:
            n = browser.eval("window.painterly.framesDrawn")
            browser.call("click", selector=f"input[data-layer='{index['/Blowfish/Paint/' + name]}']")
            browser.eval("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
            px = canvas_pixels(browser, tmp_path, name)
            assert (np.abs(px - shown).max() > 0) == changes, name
            assert browser.eval("window.painterly.framesDrawn") == n
        assert browser.call("console")["errors"] == []


@pytest.mark.parametrize("path", [HEAD, FISH], ids=["head camera", "bounds"])
def test_a_narrow_pane_keeps_the_start_frame_whole(browser, path):
    # The start frame (the head's USD camera, 20.955 x 15.2908 apertures; the
    # blowfish's square around its bounds) must stay whole in any pane: when
    # the pane is narrower than the frame, the vertical field of view widens
    # so the horizontal one is the frame's (tan(h/2) = tan(v/2) * aspect).
    with PreviewServer(path) as s:
        view = s.scene()["view"]
        expected_aspect = 20.955 / 15.2908 if path == HEAD else 1.0
        assert view["aspect"] == pytest.approx(expected_aspect, rel=1e-6)
        open_page(browser, s)
        tan_v = np.tan(np.radians(view["fov_y"]) / 2)
        state = "[window.painterly.cameraPose().fov_y, document.querySelector('#live').clientWidth, document.querySelector('#live').clientHeight]"
        seen = []
        for opened in [False, True]:
            if opened:
                browser.call("click", selector="#render-button")
                browser.wait("window.painterly.rendered === 1", timeout=60000)
            fov, w, h = browser.eval(state)
            pane = w / h
            tan_h_wanted = tan_v * view["aspect"]
            assert np.tan(np.radians(fov) / 2) == pytest.approx(tan_v * max(1.0, view["aspect"] / pane), rel=1e-6), (opened, fov, w, h)
            # The frame's full width is in view; its height too.
            assert np.tan(np.radians(fov) / 2) * pane >= tan_h_wanted * (1 - 1e-9)
            assert fov >= view["fov_y"] - 1e-9
            seen.append((pane, fov))
        # Beside the render the pane is narrower than both frames here, so
        # the field of view did widen.
        assert seen[1][0] < min(1.0, view["aspect"]) and seen[1][1] > view["fov_y"] + 1, seen
        assert browser.call("console")["errors"] == []


@pytest.mark.parametrize(
    "name,path,setup",
    [
        ("blowfish", FISH, ["window.painterly.setTime(26)", "window.painterly.pin('/Blowfish/Paint/blink', 0.0)"]),
        ("head", HEAD, ["document.querySelector('#view-drives').click()"]),
        ("apple", APPLE, ["window.painterly.setTime(20)"]),
    ],
)
def test_screenshots(browser, tmp_path, name, path, setup):
    from PIL import Image

    with PreviewServer(path) as s:
        open_page(browser, s)
        n = browser.eval("window.painterly.framesDrawn")
        for js in setup:
            browser.eval(js)
        browser.settle(n)
        shot = tmp_path / f"preview_{name}.png"
        browser.call("screenshot", selector="body", path=str(shot))
        img = Image.open(shot)
        assert img.size[0] > 600 and img.size[1] > 400
        assert browser.call("console")["errors"] == []
