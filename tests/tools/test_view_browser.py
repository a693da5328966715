"""`raycast-phong view` in a real browser: Playwright driving Debian's headless Chromium (/usr/bin/chromium,
installed by .ci/run with apt). The page's image is compared with render() of the same settings."""

from __future__ import annotations

import base64
import dataclasses
import http.server
import json
import math
import re
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

CHROMIUM = Path("/usr/bin/chromium")
pytestmark = pytest.mark.skipif(not CHROMIUM.exists(), reason=f"no Chromium at {CHROMIUM} (apt-get install chromium)")
playwright = pytest.importorskip("playwright.sync_api", reason="the browser tests need the [test] extra's playwright")
pytest.importorskip("starlette", reason="the view's server needs the [view] extra")

from conftest import write_tiny_scene

import raycast_phong as rp
from raycast_phong.io.encoding import to_8bit
from raycast_phong.tools.view import running
from raycast_phong.tools.view.server import session_render

# Headless, and nothing that reaches out: no updates, sync or first-run pages.
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
WIDTH, HEIGHT = 160, 120


@pytest.fixture(scope="module")
def browser():
    with playwright.sync_playwright() as driver:
        launched = driver.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        yield launched
        launched.close()


@pytest.fixture
def scene_path(tmp_path) -> Path:
    return write_tiny_scene(tmp_path, WIDTH, HEIGHT)


@pytest.fixture
def page(browser, scene_path):
    """The page of a view of the tiny scene, connected and showing its first full frame."""
    with opened(browser, scene_path) as tab:
        yield tab


@contextmanager
def opened(browser, path: Path, **options):
    """A tab on a view of `path`, showing its first full frame; no script error may occur meanwhile."""
    with running(path, **options) as url:
        context = browser.new_context(viewport={"width": 1000, "height": 800})  # its tabs share the cookie
        tab = context.new_page()
        errors: list[str] = []
        tab.on("pageerror", lambda error: errors.append(str(error)))
        tab.goto(url)
        wait_for_full_frame(tab)
        tab.url_with_token = url
        yield tab
        context.close()
        assert not errors, errors


def wait_for_full_frame(tab) -> None:
    """Wait until image A shows the full frame of the newest request sent (after any camera glide's end)."""
    tab.wait_for_function("() => !window.view.gliding", timeout=30_000)
    sent = tab.evaluate("window.view.nextId - 1")
    tab.wait_for_function("""(sent) => { const img = document.querySelector('#image-a');
        return img.dataset.quality === 'full' && Number(img.dataset.id) >= sent && img.complete; }""",
                          arg=sent, timeout=120_000)


def page_image(tab, selector: str = "#image-a") -> np.ndarray:
    """The pixels `selector`'s panel shows (its canvas: a frame from this machine comes as raw 8-bit RGBA rows,
    put there as they are), or the heat map's PNG (an <img>), as 8-bit (H, W, 3)."""
    if selector == "#heat":
        encoded = tab.evaluate("""async () => {
            const bytes = new Uint8Array(await (await fetch(window.view.urls.heat)).arrayBuffer());
            let text = ''; for (const b of bytes) text += String.fromCharCode(b); return btoa(text); }""")
        return decode_png(base64.b64decode(encoded))
    width, height, encoded = tab.evaluate("""(selector) => {
        const canvas = document.querySelector('#canvas-' + selector.slice('#image-'.length));
        const bytes = canvas.getContext('2d').getImageData(0, 0, canvas.width, canvas.height).data;
        let text = ''; for (const b of bytes) text += String.fromCharCode(b);
        return [canvas.width, canvas.height, btoa(text)]; }""", selector)
    return np.frombuffer(base64.b64decode(encoded), np.uint8).reshape(height, width, 4)[..., :3]


def decode_png(data: bytes) -> np.ndarray:
    import tempfile
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "image.png"
        path.write_bytes(data)
        return np.round(rp.read_image(path)[0] * 255).astype(np.uint8)  # read_image gives 8-bit values / 255


def shading(model: str) -> list[str]:
    """The page's shading switch sets render.shading and each object's own shading."""
    return [f'render.shading="{model}"', f'objects.0.shading="{model}"']


def test_switching_shading_shows_what_render_gives(page, scene_path):
    shown = {}
    for model in ("flat", "gouraud", "phong"):
        page.select_option("#shading", model)
        wait_for_full_frame(page)
        shown[model] = page_image(page)
        np.testing.assert_array_equal(shown[model], to_8bit(rp.render(rp.load_scene(scene_path, shading(model))).image))
    assert (shown["flat"] != shown["phong"]).any() and (shown["gouraud"] != shown["phong"]).any()
    assert page.text_content("#frame-time").startswith(("0.", "1", "2", "3", "4", "5", "6", "7", "8", "9"))
    assert "Mrays/s" not in page.text_content("#rays") and " M (" in page.text_content("#rays")


def turned(p, axis, angle: float) -> np.ndarray:
    """p turned by `angle` round the unit `axis` (Rodrigues), written here apart from the page's own."""
    p, axis = np.asarray(p, float), np.asarray(axis, float)
    return p * math.cos(angle) + np.cross(axis, p) * math.sin(angle) + axis * axis.dot(p) * (1 - math.cos(angle))


def drag(tab, selector: str, dx: float, dy: float, modifier: str | None = None) -> None:
    """Press in the middle of `selector`, move by (dx, dy) CSS pixels in 8 steps, release."""
    box = tab.locator(selector).bounding_box()
    x, y = round(box["x"] + box["width"] / 2), round(box["y"] + box["height"] / 2)
    if modifier:
        tab.keyboard.down(modifier)
    tab.mouse.move(x, y)
    tab.mouse.down()
    tab.mouse.move(x + dx, y + dy, steps=8)
    tab.wait_for_function("() => document.querySelector('#image-a').dataset.quality === 'draft'", timeout=60_000)
    tab.mouse.up()
    if modifier:
        tab.keyboard.up(modifier)


def test_the_light_gizmo_turns_the_light_round_the_look_at_point(page, scene_path):
    # Dragging across the gizmo's radius (74 px) is a quarter turn: 37 px right turns the light (2, 2, 3)
    # 45° round the camera's up axis (0, 1, 0) through the look-at point (the origin), at the same distance.
    drag(page, "#gizmo", 37, 0)
    wait_for_full_frame(page)
    position = page.evaluate("window.view.settings.a['lights.0.position']")
    np.testing.assert_allclose(position, turned([2, 2, 3], [0, 1, 0], math.pi / 4), atol=1e-4)
    moved = rp.load_scene(scene_path, [f"lights.0.position={position}"])
    np.testing.assert_array_equal(page_image(page), to_8bit(rp.render(moved).image))
    # Down by 74 px: a quarter turn round the camera's right axis (1, 0, 0), so the light drops below.
    drag(page, "#gizmo", 0, 74)
    wait_for_full_frame(page)
    lowered = page.evaluate("window.view.settings.a['lights.0.position']")
    np.testing.assert_allclose(lowered, turned(position, [1, 0, 0], math.pi / 2), atol=1e-4)
    assert lowered[1] < 0  # anywhere on the sphere of directions, not a patch in front of the camera
    # The wheel moves it 10 % further a notch, along the same direction.
    box = page.locator("#gizmo").bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.wheel(0, 100)
    wait_for_full_frame(page)
    further = page.evaluate("window.view.settings.a['lights.0.position']")
    np.testing.assert_allclose(further, 1.1 * np.asarray(lowered), atol=1e-5)
    assert float(page.input_value("#light-distance")) == pytest.approx(1.1 * math.sqrt(17), abs=1e-3)


# Counts what the page does, independently of its own code: render requests on the socket, URL writes, redraws of
# the light's gizmo, and the pointer moves the gizmo received.
COUNTING = """() => {
    const counts = window.counted = { sends: 0, urls: 0, redraws: 0, moves: 0 };
    const send = WebSocket.prototype.send;
    WebSocket.prototype.send = function (data) {
        if (String(data).includes('"type":"render"')) counts.sends += 1;
        return send.call(this, data);
    };
    const replace = history.replaceState;
    history.replaceState = function (...args) { counts.urls += 1; return replace.apply(this, args); };
    const gizmo = document.querySelector('#gizmo'), context = gizmo.getContext('2d'), clear = context.clearRect;
    context.clearRect = function (...args) { counts.redraws += 1; return clear.apply(this, args); };
    gizmo.addEventListener('pointermove', () => { counts.moves += 1; }, { capture: true });
}"""

# 60 pointer moves of half a pixel each, dispatched in one go (a hand's events, queued while the page was busy).
BURST = """([x, y]) => {
    const gizmo = document.querySelector('#gizmo');
    for (let k = 1; k <= 60; k++) {
        gizmo.dispatchEvent(new PointerEvent('pointermove', { pointerId: 1, pointerType: 'mouse', isPrimary: true,
                                                              bubbles: true, buttons: 1, clientX: x + 1 + k / 2,
                                                              clientY: y }));
    }
}"""
ANSWERED = "() => window.view.asked && window.view.answered >= window.view.asked.id"  # every request answered


def test_a_burst_of_pointer_events_makes_a_few_requests_and_one_url_write(page, scene_path):
    """A drag's burst of 60 pointer moves: the page folds them into the newest state, sent once a display frame
    with one request in flight; the gizmo is redrawn once a display frame, the URL written once, when the drag
    ends. Every move counts: the light turns by the whole drag, and the image is render()'s of that light."""
    page.evaluate(COUNTING)
    box = page.locator("#gizmo").bounding_box()
    x, y = round(box["x"] + box["width"] / 2), round(box["y"] + box["height"] / 2)
    page.mouse.move(x, y)
    page.mouse.down()
    page.mouse.move(x + 1, y)  # a real move first: the gizmo has the pointer captured
    page.wait_for_function(ANSWERED, timeout=60_000)
    before = page.evaluate("({ ...window.counted })")
    page.evaluate(BURST, [x, y])
    page.wait_for_timeout(200)  # room for what the burst sends
    page.wait_for_function(ANSWERED, timeout=60_000)
    during = page.evaluate("({ ...window.counted })")
    page.mouse.up()
    wait_for_full_frame(page)
    after = page.evaluate("({ ...window.counted })")
    assert before["sends"] == 1 and during["moves"] - before["moves"] == 60
    assert during["sends"] - before["sends"] <= 2, during  # one a display frame (one in flight), not 60
    assert during["redraws"] - before["redraws"] <= 2, during
    assert during["urls"] == 0 and after["urls"] == 1, (during, after)  # written when the drag ends
    assert after["sends"] == during["sends"] + 1  # the full frame of the release
    # 1 + 60 × 0.5 = 31 pixels to the right: 31/74 of a quarter turn round the camera's up axis.
    position = page.evaluate("window.view.settings.a['lights.0.position']")
    np.testing.assert_allclose(position, turned([2, 2, 3], [0, 1, 0], 31 / 74 * math.pi / 2), atol=1e-4)
    moved = rp.load_scene(scene_path, [f"lights.0.position={position}"])
    np.testing.assert_array_equal(page_image(page), to_8bit(rp.render(moved).image))


def held_draft():
    """(holding, release, render): once `holding` is set, the next draft the server renders waits for `release`."""
    holding, release = threading.Event(), threading.Event()

    def held(session, scene, **options):
        if holding.is_set() and scene.render.width == WIDTH // 2:  # a draft
            holding.clear()
            release.wait(60)
        return session_render(session, scene, **options)

    return holding, release, held


def gizmo_centre(tab) -> tuple[int, int]:
    box = tab.locator("#gizmo").bounding_box()
    return round(box["x"] + box["width"] / 2), round(box["y"] + box["height"] / 2)


def test_one_request_is_in_flight_while_a_draft_renders(browser, scene_path):
    """While a draft is rendering, moves over many display frames send nothing; its answer lets the newest state
    go, once."""
    holding, release, held = held_draft()
    with opened(browser, scene_path, render=held) as tab:
        tab.evaluate(COUNTING)
        x, y = gizmo_centre(tab)
        tab.mouse.move(x, y)
        tab.mouse.down()
        holding.set()
        tab.mouse.move(x + 1, y)  # its draft is held in the server
        tab.wait_for_function("() => window.counted.sends === 1", timeout=30_000)
        for _ in range(3):  # three bursts, each several display frames apart
            tab.evaluate(BURST, [x, y])
            tab.wait_for_timeout(150)
        waiting = tab.evaluate("({ ...window.counted })")
        release.set()
        tab.wait_for_function(ANSWERED, timeout=60_000)
        tab.wait_for_timeout(200)
        answered = tab.evaluate("({ ...window.counted })")
        tab.mouse.up()
        wait_for_full_frame(tab)
    assert waiting["sends"] == 1 and waiting["moves"] >= 181, waiting
    assert answered["sends"] == 2, answered


def test_every_release_is_painted_even_when_the_next_stroke_starts_at_once(browser, scene_path):
    """Strokes back to back (issue 35): a release while a draft renders, and the next stroke at once. The release's
    full frame is sent at once, not folded into the next stroke's draft; the server renders it before that draft,
    and the page paints it before the draft replaces it."""
    holding, release, held = held_draft()
    with opened(browser, scene_path, render=held) as tab:
        tab.evaluate(COUNTING)
        x, y = gizmo_centre(tab)
        tab.evaluate("window.view.painted.length = 0")
        tab.mouse.move(x, y)
        tab.mouse.down()
        holding.set()
        tab.mouse.move(x + 1, y)  # its draft is held in the server
        tab.wait_for_function("() => window.counted.sends === 1", timeout=30_000)
        tab.mouse.up()
        released = tab.evaluate("window.view.asked")
        tab.mouse.down()  # the next stroke, at once
        tab.mouse.move(x + 9, y)
        tab.mouse.move(x + 17, y)
        release.set()
        tab.wait_for_function("(id) => window.view.painted.some((p) => p.quality === 'draft' && p.id > id)",
                              arg=released["id"], timeout=60_000)
        painted = tab.evaluate("window.view.painted.map((p) => [p.id, p.quality])")
        tab.mouse.up()
        wait_for_full_frame(tab)
    assert released["quality"] == "full"
    assert [released["id"], "full"] in painted, painted
    assert [frame_id for frame_id, _ in painted] == sorted(frame_id for frame_id, _ in painted), painted  # in turn


def test_light_fields_place_the_light_its_marker_shows_it_and_reset_brings_it_back(page, scene_path):
    original = page_image(page)
    assert page.is_hidden("#marker-a")  # the scene's light (2, 2, 3) is outside the 40° view
    for axis, value in enumerate(("0.5", "0.3", "2")):
        page.fill(f"#light-xyz input[data-axis='{axis}']", value)
        page.dispatch_event(f"#light-xyz input[data-axis='{axis}']", "change")
    wait_for_full_frame(page)
    assert page.evaluate("window.view.settings.a['lights.0.position']") == [0.5, 0.3, 2]
    moved = rp.load_scene(scene_path, ["lights.0.position=[0.5, 0.3, 2]"])
    np.testing.assert_array_equal(page_image(page), to_8bit(rp.render(moved).image))
    # Eye at z = 4, fov 40°, 4:3: the light at depth 2 is seen at x = 0.5 / (2 tan 20° · 4/3), y = 0.3 / (2 tan 20°).
    t = math.tan(math.radians(20))
    u, v = (1 + 0.5 / (2 * t * WIDTH / HEIGHT)) / 2, (1 - 0.3 / (2 * t)) / 2
    image, marker = page.locator("#image-a").bounding_box(), page.locator("#marker-a").bounding_box()
    centre = (marker["x"] + marker["width"] / 2, marker["y"] + marker["height"] / 2)
    assert centre[0] == pytest.approx(image["x"] + u * image["width"], abs=1.5)
    assert centre[1] == pytest.approx(image["y"] + v * image["height"], abs=1.5)
    page.click("#light-reset")
    wait_for_full_frame(page)
    assert page.evaluate("Object.keys(window.view.settings.a)") == []
    np.testing.assert_array_equal(page_image(page), original)
    assert page.input_value("#light-xyz input[data-axis='0']") == "2"


def test_light_intensity_is_apart_from_its_colour_and_attenuation_keeps_the_brightness(page, scene_path):
    assert page.input_value("#light-diffuse-colour") == "#ffffff"  # the scene's (0.8, 0.8, 0.8): white × 0.8
    assert page.input_value("#light-diffuse-intensity") == "0.8"
    page.fill("#light-diffuse-intensity", "2.5")  # above 1: a colour picker alone would clip it
    page.dispatch_event("#light-diffuse-intensity", "change")
    wait_for_full_frame(page)
    assert page.evaluate("window.view.settings.a['lights.0.diffuse']") == [2.5, 2.5, 2.5]
    page.fill("#light-diffuse-colour", "#ffffff")  # picking the same colour again changes nothing …
    page.dispatch_event("#light-diffuse-colour", "input")
    assert page.evaluate("window.view.settings.a['lights.0.diffuse']") == [2.5, 2.5, 2.5]
    assert "lights.0.specular" not in page.evaluate("window.view.settings.a")  # … and leaves the specular alone
    # 1/d² with the light √17 from the look-at point: both intensities × 17, so that point stays as bright.
    page.select_option("#attenuation", "inverse_square")
    wait_for_full_frame(page)
    settings = page.evaluate("window.view.settings.a")
    assert settings["lights.0.attenuation"] == "inverse_square"
    np.testing.assert_allclose(settings["lights.0.diffuse"], [42.5] * 3, rtol=1e-5)
    np.testing.assert_allclose(settings["lights.0.specular"], [17] * 3, rtol=1e-5)
    # [c, l, q] = [1, 0, 1]: 1/(1 + 17) instead of 1/17, so × 18/17 more.
    page.select_option("#attenuation", "clq")
    wait_for_full_frame(page)
    settings = page.evaluate("window.view.settings.a")
    assert settings["lights.0.attenuation"] == [1, 0, 1] and page.is_visible("#attenuation-clq")
    np.testing.assert_allclose(settings["lights.0.diffuse"], [45.0] * 3, rtol=1e-5)
    overrides = [f"lights.0.{key}={settings[f'lights.0.{key}']}" for key in ("diffuse", "specular", "attenuation")]
    np.testing.assert_array_equal(page_image(page), to_8bit(rp.render(rp.load_scene(scene_path, overrides)).image))


def test_every_light_of_the_scene_can_be_chosen_and_moved(browser, tmp_path):
    path = write_tiny_scene(tmp_path, WIDTH, HEIGHT, '[[lights]]\ntype = "directional"\ndirection = [1, 0, -1]\n')
    with opened(browser, path) as tab:
        assert tab.locator("#light option").all_text_contents() == ["1: point", "2: directional"]
        tab.select_option("#light", "1")
        assert tab.text_content("#light-xyz-name") == "direction" and tab.is_disabled("#light-distance")
        drag(tab, "#gizmo", 37, 0)
        wait_for_full_frame(tab)
        settings = tab.evaluate("window.view.settings.a")
        assert list(settings) == ["lights.1.direction"]  # the first light stays where the scene put it
        # The direction the light travels turns with the direction towards it: 45° round (0, 1, 0).
        expected = turned(np.array([1, 0, -1]) / math.sqrt(2), [0, 1, 0], math.pi / 4)
        np.testing.assert_allclose(settings["lights.1.direction"], expected, atol=1e-4)
        moved = rp.load_scene(path, [f"lights.1.direction={settings['lights.1.direction']}"])
        np.testing.assert_array_equal(page_image(tab), to_8bit(rp.render(moved).image))


def test_the_camera_orbits_pans_zooms_and_resets(page, scene_path, tmp_path):
    original = page_image(page)
    height = page.locator("#image-a").bounding_box()["height"]
    # Dragging across the image's height is half a turn: 1/4 of it to the right turns the eye (0, 0, 4)
    # by −45° round the scene's up axis (0, 1, 0), about look_at, so the sphere seems to turn right.
    drag(page, "#image-a", height / 4, 0)
    wait_for_full_frame(page)
    position = page.evaluate("window.view.settings.a['camera.position']")
    np.testing.assert_allclose(position, turned([0, 0, 4], [0, 1, 0], -math.pi / 4), atol=1e-4)
    orbited = rp.load_scene(scene_path, [f"camera.position={position}"])
    np.testing.assert_array_equal(page_image(page), to_8bit(rp.render(orbited).image))
    # The wheel moves the eye 10 % further a notch along its view axis.
    page.mouse.wheel(0, 100)
    wait_for_full_frame(page)
    np.testing.assert_allclose(page.evaluate("window.view.settings.a['camera.position']"),
                               1.1 * np.asarray(position), atol=1e-5)
    # A key press on the image orbits 5°, and R resets the view.
    page.focus("#stage")
    page.keyboard.press("r")
    wait_for_full_frame(page)
    assert page.evaluate("Object.keys(window.view.settings.a)") == []
    np.testing.assert_array_equal(page_image(page), original)
    page.keyboard.press("ArrowLeft")
    wait_for_full_frame(page)
    np.testing.assert_allclose(page.evaluate("window.view.settings.a['camera.position']"),
                               turned([0, 0, 4], [0, 1, 0], math.pi / 36), atol=1e-5)
    page.click("#camera-reset")
    wait_for_full_frame(page)  # the camera glides back
    # Shift-drag pans: eye and look_at move together; 1/8 of the height right moves them left by
    # 1/8 of the view's height at the look_at point's depth, 2 · 4 · tan 20°.
    drag(page, "#image-a", height / 8, 0, modifier="Shift")
    wait_for_full_frame(page)
    shift = -2 * 4 * math.tan(math.radians(20)) / 8
    settings = page.evaluate("window.view.settings.a")
    np.testing.assert_allclose(settings["camera.look_at"], [shift, 0, 0], atol=1e-5)
    np.testing.assert_allclose(settings["camera.position"], [shift, 0, 4], atol=1e-5)
    # The camera is saved with the settings: the scene file renders the image shown.
    with page.expect_download() as download:
        page.click("[data-save=toml]")
    saved = tmp_path / "saved.toml"
    download.value.save_as(saved)
    np.testing.assert_allclose(rp.load_scene(saved).camera.look_at, [shift, 0, 0], atol=1e-5)
    np.testing.assert_array_equal(page_image(page), to_8bit(rp.render(rp.load_scene(saved)).image))


def test_a_lost_server_turns_the_page_off_and_it_reconnects_to_the_restarted_one(browser, scene_path):
    token = "kept-" + "x" * 40  # serve() keeps its token between runs (remembered_token); so do we here
    tab = browser.new_page(viewport={"width": 1000, "height": 800})
    try:
        with running(scene_path, token=token) as url:
            port = int(url.split(":")[2].split("/")[0])
            tab.goto(url)
            wait_for_full_frame(tab)
            tab.select_option("#shading", "flat")
            wait_for_full_frame(tab)
            assert tab.is_hidden("#lost") and tab.is_enabled("#shading")
        tab.wait_for_selector("#lost:not([hidden])", timeout=30_000)
        assert "not answering" in tab.text_content("#lost")
        assert tab.is_disabled("#shading") and tab.is_disabled("#gizmo-box ~ label input")
        assert tab.text_content("#connection") == "disconnected"
        with running(scene_path, port=port, token=token):
            tab.wait_for_selector("#lost", state="hidden", timeout=30_000)
            wait_for_full_frame(tab)
            assert tab.is_enabled("#shading") and tab.input_value("#shading") == "flat"
            flat = rp.load_scene(scene_path, shading("flat"))
            np.testing.assert_array_equal(page_image(tab), to_8bit(rp.render(flat).image))
            assert tab.reload().status == 200  # the cookie and the URL's token are still good
            wait_for_full_frame(tab)
    finally:
        tab.close()


def test_the_page_shows_that_it_is_rendering_and_how_far(browser, scene_path):
    holding, release = threading.Event(), threading.Event()

    def held(session, scene, **options):
        """Once `holding` is set, a full frame reports a quarter of its tiles done and waits for `release`."""
        if holding.is_set() and options.get("progress") is not None:
            options["progress"](1, 4)
            release.wait(60)
        return session_render(session, scene, **options)

    with opened(browser, scene_path, render=held) as tab:
        assert tab.is_hidden("#busy")
        holding.set()
        tab.select_option("#shading", "flat")
        tab.wait_for_selector("#busy:not([hidden])", timeout=30_000)
        tab.wait_for_function("() => document.querySelector('#busy-bar').value === 0.25", timeout=30_000)
        assert tab.text_content("#busy-text").startswith("rendering the full frame…")
        assert "stale" in tab.get_attribute("#stage", "class")
        release.set()
        wait_for_full_frame(tab)
        assert tab.is_hidden("#busy") and "stale" not in tab.get_attribute("#stage", "class")


def test_the_url_is_a_permalink_of_the_settings(page, scene_path):
    page.select_option("#shading", "flat")
    page.fill("#light-xyz input[data-axis='0']", "-1.5")
    page.dispatch_event("#light-xyz input[data-axis='0']", "change")
    wait_for_full_frame(page)
    page.select_option("#compare", "side")
    wait_for_full_frame(page)
    settings = page.evaluate("window.view.settings")
    link = page.url
    assert "#view=" in link and page.get_attribute("#permalink", "href") in link
    shown_a, shown_b = page_image(page), page_image(page, "#image-b")
    other = page.context.new_page()  # a bookmark opened later in this browser: only the URL is shared
    try:
        other.goto(link)
        wait_for_full_frame(other)
        assert other.evaluate("window.view.settings") == settings
        assert other.input_value("#shading") == "flat" and other.input_value("#compare") == "side"
        assert other.input_value("#light-xyz input[data-axis='0']") == "-1.5"
        np.testing.assert_array_equal(page_image(other), shown_a)
        np.testing.assert_array_equal(page_image(other, "#image-b"), shown_b)
        moved = rp.load_scene(scene_path, [*shading("flat"), "lights.0.position=[-1.5, 2, 3]"])
        np.testing.assert_array_equal(shown_a, to_8bit(rp.render(moved).image))
    finally:
        other.close()
    damaged = page.context.new_page()  # a damaged link: the scene as it is
    try:
        damaged.goto(link.split("#")[0] + "#view=%7Bnot-json")
        wait_for_full_frame(damaged)
        assert damaged.evaluate("Object.keys(window.view.settings.a)") == []
    finally:
        damaged.close()


def test_a_saved_scene_renders_from_the_cli_to_the_image_shown(page, tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    monkeypatch.delenv("RAYCAST_PHONG_DEBUG", raising=False)
    page.select_option("#shading", "flat")
    page.select_option("[data-key='render.specular']", "blinn")
    page.fill("#shininess", "1.5")  # 10^1.5 ≈ 31.6 on the log slider
    page.dispatch_event("#shininess", "change")
    wait_for_full_frame(page)
    with page.expect_download() as download:
        page.click("[data-save=toml]")
    saved = tmp_path / download.value.suggested_filename
    download.value.save_as(saved)
    assert saved.name == "tiny-view-A.toml"  # which setting it is
    assert rp.load_scene(saved).materials["red"].shininess == 31.6
    result = CliRunner().invoke(app, ["render", str(saved), "-o", str(tmp_path / "cli.png"), "--quiet"])
    assert result.exit_code == 0, result.output
    rendered = np.round(rp.read_image(tmp_path / "cli.png")[0] * 255).astype(np.uint8)
    np.testing.assert_array_equal(rendered, page_image(page))


def test_a_saved_scene_file_opens_back_on_the_page(page, scene_path, tmp_path):
    page.select_option("#shading", "gouraud")
    page.fill("#light-xyz input[data-axis='1']", "-1")
    page.dispatch_event("#light-xyz input[data-axis='1']", "change")
    wait_for_full_frame(page)
    with page.expect_download() as download:
        page.click("[data-save=toml]")
    saved = tmp_path / "saved.toml"
    download.value.save_as(saved)
    shown = page_image(page)
    page.click("#light-reset")
    page.select_option("#shading", "phong")
    wait_for_full_frame(page)
    assert (page_image(page) != shown).any()
    page.set_input_files("#load", str(saved))
    page.wait_for_function("() => window.view.settings.a['render.shading'] === 'gouraud'", timeout=30_000)
    wait_for_full_frame(page)
    assert page.input_value("#shading") == "gouraud" and page.input_value("#light-xyz input[data-axis='1']") == "-1"
    np.testing.assert_array_equal(page_image(page), shown)
    np.testing.assert_array_equal(shown, to_8bit(rp.render(rp.load_scene(saved)).image))


def test_a_file_or_message_larger_than_the_server_takes_is_one_line_on_the_page(page, tmp_path):
    """The page checks the sizes hello gives (a scene file it opens, a message) before sending: a larger one is
    its one-line message, the socket is not closed under it, and the page goes on."""
    big = tmp_path / "big.toml"
    big.write_text("# note\n" * 9000)  # 63,000 bytes
    page.set_input_files("#load", str(big))
    page.wait_for_selector("#error:not([hidden])", timeout=30_000)
    assert page.text_content("#error") == "big.toml: 63,000 bytes; a scene file the page opens is at most 60,000 bytes"
    page.evaluate("window.view.settings.a['materials.red.name'] = 'x'.repeat(600000)")
    page.select_option("#shading", "flat")
    page.wait_for_function("() => document.querySelector('#error').textContent.startsWith('message of ')",
                           timeout=30_000)
    assert re.fullmatch(r"message of [\d,]+ bytes; allowed: at most 524,288", page.text_content("#error"))
    page.evaluate("delete window.view.settings.a['materials.red.name']")
    page.select_option("#shading", "gouraud")
    wait_for_full_frame(page)
    assert page.is_hidden("#error")


def test_a_bad_value_shows_the_one_line_message(page):
    page.evaluate("window.view.settings.a['render.samples'] = 99")
    page.select_option("[data-key='render.mode']", "global")
    page.wait_for_selector("#error:not([hidden])", timeout=60_000)
    assert "render.samples: out of range; allowed: 1 ≤ samples ≤ 16 (got 99)" in page.text_content("#error")


def test_the_page_and_socket_refuse_a_request_without_the_token(page, browser):
    url = page.url_with_token
    bare = url.split("?", 1)[0]
    stranger = browser.new_context()  # no cookie from having opened the page with its token
    try:
        tab = stranger.new_page()
        assert tab.goto(bare).status == 403 and tab.goto(f"{bare}?token=wrong").status == 403
        assert tab.goto(f"{bare}static/view.js").status == 403
        assert "token" in tab.text_content("body")
    finally:
        stranger.close()
    assert page.request.get(f"{bare}?token=wrong").status == 403  # a wrong token counts even with the cookie
    outcome = """(address) => new Promise((done) => { const ws = new WebSocket(address);
        ws.onopen = () => done('open'); ws.onclose = () => done('closed'); })"""
    socket = bare.replace("http://", "ws://") + "socket"
    token = url.split("token=", 1)[1]
    assert page.evaluate(outcome, f"{socket}?token=wrong") == "closed"
    assert page.evaluate(outcome, f"{socket}?token={token}") == "open"
    # A page of another origin that knows the token is still refused. It is served on loopback too (another
    # port): Chromium itself already blocks a public site's socket to 127.0.0.1, which would test nothing here.
    with other_origin() as other:
        page.goto(other)
        assert page.evaluate(outcome, f"{socket}?token={token}") == "closed"


def test_flat_gouraud_and_phong_side_by_side_in_one_view(page, scene_path):
    page.select_option("[data-key='render.specular']", "blinn")  # the three panels are A's, with its settings
    page.select_option("#compare", "models")
    wait_for_full_frame(page)
    assert [page.text_content(f"#tag-{p}") for p in "abc"] == ["flat", "Gouraud", "Phong"]
    assert page.is_hidden("#heat-box") and page.is_hidden("#editing-label")
    left = []
    for panel, model in zip("abc", ("flat", "gouraud", "phong")):
        expected = rp.render(rp.load_scene(scene_path, [*shading(model), 'render.specular="blinn"']))
        np.testing.assert_array_equal(page_image(page, f"#image-{panel}"), to_8bit(expected.image))
        left.append(", ".join(s.name for s in expected.plan.stages if not s.kept) or "nothing")
    assert page.evaluate("window.view.lastFrame.stats.c.width") == WIDTH
    # Each model's plan leaves out its own stages: said panel by panel (it was the flat panel's alone).
    assert len(set(left)) > 1, left
    assert page.text_content("#left-out") == "; ".join(f"{tag}: {stages}" for tag, stages in
                                                       zip(("flat", "Gouraud", "Phong"), left))
    page.select_option("#compare", "side")
    wait_for_full_frame(page)
    assert [page.text_content(f"#tag-{p}") for p in "ab"] == ["A", "B"] and page.is_hidden("#panel-c")
    assert page.text_content("#heat-box .tag") == "|A − B|" and page.text_content("#exact-label") == "exact error of A"
    page.select_option("#editing", "b")
    with page.expect_download() as download:
        page.click("[data-save=toml]")
    assert download.value.suggested_filename == "tiny-view-B.toml"


def test_an_edited_scene_file_shows_on_the_page_with_its_settings_kept(page, scene_path):
    page.select_option("#shading", "flat")
    wait_for_full_frame(page)
    shown = page.evaluate("window.view.nextId")
    scene_path.write_text(scene_path.read_text().replace("ambient = [0.1, 0.1, 0.1]", "ambient = [0.4, 0.4, 0.6]"))
    page.wait_for_function("(shown) => window.view.nextId > shown", arg=shown, timeout=30_000)  # asked anew
    wait_for_full_frame(page)
    assert "(reloaded" in page.text_content("#source") and page.input_value("#shading") == "flat"
    edited = rp.load_scene(scene_path, shading("flat"))
    np.testing.assert_array_equal(page_image(page), to_8bit(rp.render(edited).image))


@contextmanager
def other_origin(body: bytes = b"<!doctype html><title>another origin</title>"):
    """A page (empty by default) at http://127.0.0.1:<another port>/."""
    class Blank(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Blank)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


def test_compare_shows_b_beside_a_with_the_heat_map(page, scene_path):
    page.select_option("[data-key='render.specular']", "blinn")  # A changed before B exists: B starts from it
    wait_for_full_frame(page)
    page.select_option("#compare", "side")
    wait_for_full_frame(page)
    assert page.is_visible("#image-b") and page.is_visible("#heat") and not page.is_visible("#wipe")
    b = rp.load_scene(scene_path, [*shading("gouraud"), 'render.specular="blinn"'])
    np.testing.assert_array_equal(page_image(page, "#image-b"), to_8bit(rp.render(b).image))
    assert page_image(page, "#heat").shape == (HEIGHT, WIDTH, 3)
    assert "pale yellow" in page.text_content("#heat-caption")
    page.select_option("#compare", "wipe")
    wait_for_full_frame(page)
    assert page.is_visible("#wipe") and page.is_visible("#wipe-line")
    page.fill("#wipe", "30")
    page.dispatch_event("#wipe", "input")
    assert page.evaluate("document.querySelector('#image-b').style.clipPath") == "inset(0px 0px 0px 30%)"


def test_the_live_view_can_be_framed_by_a_notebook_on_another_port(browser, scene_path):
    from raycast_phong.tools.notebook import live
    view = live(scene_path, height=600)
    try:
        cell = f"<!doctype html><title>a notebook</title>{view._repr_html_()}".encode()
        with other_origin(cell) as notebook:  # Jupyter's page: another origin on loopback
            stranger = browser.new_context()  # no cookie: the framed page's own files come by their token
            try:
                tab = stranger.new_page()
                tab.goto(notebook)
                framed = tab.frame_locator("iframe")
                framed.locator("#image-a[data-quality='full']").wait_for(timeout=120_000)
                assert framed.locator("#connection").text_content() == "connected"
            finally:
                stranger.close()
    finally:
        view.stop()


def test_the_browser_benchmark_runs_in_a_reduced_form():
    """bench_view.py --browser is not a timed test; this keeps it working (one step a size, short drags)."""
    import subprocess
    import sys
    root = Path(__file__).resolve().parents[2]
    done = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_view.py"), "--browser", "--steps", "1",
                           "--seconds", "0.6", "--rate", "20"], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    for line in ("rest 640×360                 full", "rest 1280×720                full",
                 "dragging 640×360             draft"):
        assert line in done.stdout, done.stdout
    unpaced = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_view.py"), "--browser", "--unpaced",
                              "--strokes", "2", "--stroke", "0.3"], capture_output=True, text=True, timeout=600)
    assert unpaced.returncode == 0, unpaced.stderr
    for line in ("light  drafts while dragging: input→paint median", "orbit  full frame after a release:",
                 "load average after:"):
        assert line in unpaced.stdout, unpaced.stdout


# ---------------------------------------------------------------- access: settings apart from the token (issue 35)

def test_the_token_leaves_the_address_bar_and_a_shared_permalink_opens_nothing(page, browser):
    page.select_option("#shading", "flat")
    wait_for_full_frame(page)
    link = page.url
    assert "#view=" in link and "token" not in link and "token" not in page.get_attribute("#permalink", "href")
    again = page.context.new_page()  # this browser (it holds the cookie): the permalink reopens the view
    try:
        again.goto(link)
        wait_for_full_frame(again)
        assert again.input_value("#shading") == "flat"
    finally:
        again.close()
    stranger = browser.new_context()  # someone the link was sent to
    try:
        assert stranger.new_page().goto(link).status == 403
    finally:
        stranger.close()


def test_another_page_on_loopback_cannot_frame_the_view(page):
    """127.0.0.1 on another port is the same site, so it would send the cookie: a page loaded by its cookie
    refuses every frame (frame-ancestors 'none')."""
    bare = page.url.split("#", 1)[0]
    framing = (f"<!doctype html><title>framing</title><iframe src='{bare}' "
               "onload=\"document.title = 'loaded'\"></iframe>").encode()
    with other_origin(framing) as other:
        tab = page.context.new_page()  # the cookie is in this context
        try:
            tab.goto(other)
            tab.wait_for_function("document.title === 'loaded'", timeout=30_000)
            tab.wait_for_timeout(500)
            framed = [frame for frame in tab.frames if frame != tab.main_frame]
            assert framed and all(frame.locator("#controls").count() == 0 for frame in framed)
        finally:
            tab.close()


def test_a_restarted_server_with_another_token_says_the_token_is_refused(browser, scene_path):
    tab = browser.new_page(viewport={"width": 1000, "height": 800})
    try:
        with running(scene_path, token="first-" + "x" * 40) as url:
            port = int(url.split(":")[2].split("/")[0])
            tab.goto(url)
            wait_for_full_frame(tab)
        with running(scene_path, port=port, token="second-" + "y" * 40):
            tab.wait_for_function("() => document.querySelector('#lost').textContent.includes('refused')",
                                  timeout=30_000)
            assert tab.is_visible("#lost") and "printed" in tab.text_content("#lost")
    finally:
        tab.close()


# ---------------------------------------------------------------- robust to the file (issue 35 item 6)

SECOND_SPHERE = '\n[[objects]]\nshape = "icosphere"\nsubdivisions = 1\nradius = 0.4\nmaterial = "red"\n' \
                'translate = [1.2, 0, 0]\n'


def test_a_scene_file_that_loses_an_object_keeps_the_page_and_its_old_links_working(browser, tmp_path):
    path = write_tiny_scene(tmp_path, WIDTH, HEIGHT, SECOND_SPHERE)
    with opened(browser, path) as tab:
        tab.select_option("#shading", "flat")  # sets objects.0.shading and objects.1.shading
        wait_for_full_frame(tab)
        old_link = tab.url
        assert "objects.1.shading" in tab.evaluate("Object.keys(window.view.settings.a).join()")
        path.write_text(path.read_text().replace(SECOND_SPHERE, ""))
        tab.wait_for_selector("#note:not([hidden])", timeout=30_000)
        assert "objects.1.shading" in tab.text_content("#note")
        wait_for_full_frame(tab)
        one = rp.load_scene(path, shading("flat"))
        np.testing.assert_array_equal(page_image(tab), to_8bit(rp.render(one).image))
        assert tab.is_hidden("#error")
        fresh = tab.context.new_page()  # the link made before the edit still opens the view
        try:
            fresh.goto(old_link)
            wait_for_full_frame(fresh)
            assert fresh.is_visible("#note") and fresh.is_hidden("#error")
            np.testing.assert_array_equal(page_image(fresh), to_8bit(rp.render(one).image))
        finally:
            fresh.close()


def test_a_message_about_an_invalid_file_stays_until_the_file_is_fixed(page, scene_path):
    good = scene_path.read_text()
    scene_path.write_text(good.replace("subdivisions = 1", "subdivisions = -4"))
    page.wait_for_selector("#file-error:not([hidden])", timeout=30_000)
    assert "subdivisions" in page.text_content("#file-error")
    page.select_option("#shading", "flat")  # a new frame of the scene as it was
    wait_for_full_frame(page)
    assert page.is_visible("#file-error") and "subdivisions" in page.text_content("#file-error")
    scene_path.write_text(good.replace("ambient = [0.1, 0.1, 0.1]", "ambient = [0.2, 0.2, 0.2]"))
    page.wait_for_selector("#file-error", state="hidden", timeout=30_000)


# ---------------------------------------------------------------- gestures (issue 35 item 4)

def wheel(tab, **init) -> None:
    """A wheel event on image A, as a browser makes it (Playwright's mouse.wheel has no deltaMode or ctrlKey)."""
    tab.evaluate("""(init) => { const img = document.querySelector('#image-a'); const box = img.getBoundingClientRect();
        img.dispatchEvent(new WheelEvent('wheel', { bubbles: true, cancelable: true, clientX: box.x + box.width / 2,
                                                    clientY: box.y + box.height / 2, ...init })); }""", init)


def eye_distance(tab) -> float:
    position = tab.evaluate("window.view.settings.a['camera.position'] || window.view.hello.scene.camera.position")
    look_at = tab.evaluate("window.view.settings.a['camera.look_at'] || window.view.hello.scene.camera.look_at")
    return float(np.linalg.norm(np.subtract(position, look_at)))


def test_the_wheel_zooms_in_proportion_pinch_zooms_and_two_fingers_pan(page):
    start = eye_distance(page)  # 4: the tiny scene's camera
    wheel(page, deltaY=10)  # a trackpad's small step: a tenth of a notch
    assert eye_distance(page) == pytest.approx(start * 1.1 ** 0.1, rel=1e-5)
    wheel(page, deltaY=90)
    assert eye_distance(page) == pytest.approx(start * 1.1, rel=1e-5)
    wheel(page, deltaY=-3, deltaMode=1)  # Firefox counts lines: 3 lines are a notch
    assert eye_distance(page) == pytest.approx(start * 1.1 * 1.1 ** -0.99, rel=1e-5)
    before = eye_distance(page)
    wheel(page, deltaY=-20, ctrlKey=True)  # a pinch: the fingers spread, the view comes closer
    assert eye_distance(page) == pytest.approx(before * math.exp(-0.2), rel=1e-5)
    look_at = page.evaluate("window.view.settings.a['camera.look_at'] || [0, 0, 0]")
    before = eye_distance(page)
    wheel(page, deltaX=30)  # two fingers sideways: a pan; the distance stays
    moved = page.evaluate("window.view.settings.a['camera.look_at']")
    assert moved[0] > look_at[0] + 1e-3 and eye_distance(page) == pytest.approx(before, rel=1e-6)
    wait_for_full_frame(page)


def test_zoom_stops_outside_the_object(page):
    wait_for_full_frame(page)
    radius = page.evaluate("window.view.lastFrame.spheres[0][3]")
    assert 0.9 < radius <= 1.0 + 1e-6  # the unit icosphere's bounding sphere
    for _ in range(60):
        wheel(page, deltaY=-400)
    assert radius * 1.04 < eye_distance(page) < radius * 1.06  # the sphere is centred on look_at
    wait_for_full_frame(page)


def test_keys_glide_the_camera_through_drafts_to_the_exact_step(page):
    page.focus("#stage")
    sent = page.evaluate("window.view.nextId")
    page.keyboard.press("+")
    wait_for_full_frame(page)
    assert page.evaluate("window.view.nextId") - sent > 3  # drafts on the way, then the full frame
    assert eye_distance(page) == pytest.approx(4 / 1.1, rel=1e-5)


# ---------------------------------------------------------------- layout (issue 35 item 5)

def test_the_page_fits_a_phone_and_the_image_takes_the_room_there_is(browser, scene_path):
    with running(scene_path) as url:
        for width, height in ((390, 844), (1000, 800)):
            context = browser.new_context(viewport={"width": width, "height": height})
            try:
                tab = context.new_page()
                tab.goto(url)
                wait_for_full_frame(tab)
                box = tab.locator("#image-a").bounding_box()
                assert box["x"] >= 0 and box["x"] + box["width"] <= width + 0.5
                if width == 390:  # a phone: the image across the screen, above the controls
                    assert box["width"] >= 350 and box["y"] < tab.locator("#controls").bounding_box()["y"]
                else:  # the room beside the controls (the scene file's 160 pixels are not a limit)
                    assert box["width"] > 2 * WIDTH and box["height"] <= height
                smoothing = "getComputedStyle(document.querySelector('#image-a')).imageRendering"
                assert tab.evaluate(smoothing) != "pixelated"
                tab.focus("#stage")
                tab.keyboard.press("p")  # pixel peeping
                assert tab.evaluate(smoothing) == "pixelated"
            finally:
                context.close()


def test_the_image_is_an_early_tab_stop(page):
    page.evaluate("document.activeElement.blur()")
    stops = []
    while len(stops) < 3 and "stage" not in stops:  # the stage within the first three Tab stops
        page.keyboard.press("Tab")
        stops.append(page.evaluate("document.activeElement.id"))
    assert "stage" in stops, stops


def test_the_busy_bar_never_moves_the_image(browser, scene_path):
    holding, release = threading.Event(), threading.Event()

    def held(session, scene, **options):
        if holding.is_set() and options.get("progress") is not None:
            release.wait(60)
        return session_render(session, scene, **options)

    with opened(browser, scene_path, render=held) as tab:
        before = tab.locator("#image-a").bounding_box()
        holding.set()
        tab.select_option("#shading", "flat")
        tab.wait_for_selector("#busy:not([hidden])", timeout=30_000)
        assert tab.locator("#image-a").bounding_box() == before
        release.set()
        wait_for_full_frame(tab)


# ---------------------------------------------------------------- what viewers people like have (item 8)

def test_standard_views_fit_and_the_turntable(page):
    page.click("[data-view=top]")
    wait_for_full_frame(page)
    position = np.asarray(page.evaluate("window.view.settings.a['camera.position']"))
    assert np.linalg.norm(position) == pytest.approx(4, rel=1e-5)  # the distance kept, look_at at the origin
    assert math.degrees(math.acos(position[1] / 4)) == pytest.approx(1, abs=1e-3)  # a degree off straight down
    page.click("[data-view=front]")
    wait_for_full_frame(page)
    np.testing.assert_allclose(page.evaluate("window.view.settings.a['camera.position']"), [0, 0, 4], atol=1e-5)
    page.focus("#stage")
    for _ in range(5):
        page.keyboard.press("-")
        wait_for_full_frame(page)
    radius = page.evaluate("window.view.lastFrame.spheres[0][3]")
    page.keyboard.press("f")  # the sphere round the scene fills the narrower side (the height) with 10 % spare
    wait_for_full_frame(page)
    half = math.tan(math.radians(20))
    assert eye_distance(page) == pytest.approx(1.1 * radius / math.sin(math.atan(half)), rel=1e-4)
    answered = page.evaluate("window.view.answered")
    page.check("#turntable")  # it turns on by itself: eight more frames answered with no input
    page.wait_for_function("(before) => window.view.answered > before + 8", arg=answered, timeout=30_000)
    page.uncheck("#turntable")
    wait_for_full_frame(page)
    x, _, z = page.evaluate("window.view.settings.a['camera.position']")
    assert abs(x) > 1e-3 and math.hypot(x, z) == pytest.approx(eye_distance(page), rel=1e-5)  # turned round up


def test_capture_gives_the_image_on_screen_and_its_scene(page, tmp_path):
    page.select_option("#shading", "flat")
    wait_for_full_frame(page)
    downloads = []
    page.on("download", lambda download: downloads.append(download))
    page.click("#capture")  # one click, two files
    for _ in range(200):
        if len(downloads) >= 2:
            break
        page.wait_for_timeout(50)
    files = {download.suggested_filename: download for download in downloads}
    assert sorted(files) == ["tiny-view-A.png", "tiny-view-A.toml"]
    files["tiny-view-A.png"].save_as(tmp_path / "shown.png")
    files["tiny-view-A.toml"].save_as(tmp_path / "shown.toml")
    shown = np.round(rp.read_image(tmp_path / "shown.png")[0] * 255).astype(np.uint8)
    np.testing.assert_array_equal(shown, page_image(page))
    np.testing.assert_array_equal(shown, to_8bit(rp.render(rp.load_scene(tmp_path / "shown.toml")).image))


def test_a_full_frame_from_this_machine_comes_raw_and_nothing_is_decoded(page):
    """From a server on this machine a full frame comes as raw pixels, put into the canvas as they are (a PNG's
    encoding and createImageBitmap's decoding were 28-39 ms of a release), so no PNG is kept (capture asks the
    server for one); the transparent <img> under the canvas gets no src, which made Chromium decode every full
    frame a second time."""
    page.select_option("#shading", "flat")
    wait_for_full_frame(page)
    assert page.evaluate("window.view.painted.at(-1).quality") == "full"
    assert page.evaluate("window.view.urls['image-a']") is None and page.get_attribute("#image-a", "src") is None
    assert page.locator("#image-a").bounding_box()["height"] > 10  # the panel keeps its box (--aspect)


def test_undo_and_the_keys_list(page):
    page.select_option("#shading", "flat")
    wait_for_full_frame(page)
    page.select_option("[data-key='render.specular']", "blinn")
    wait_for_full_frame(page)
    page.focus("#stage")
    page.keyboard.press("Control+z")
    wait_for_full_frame(page)
    settings = page.evaluate("window.view.settings.a")
    assert "render.specular" not in settings and settings["render.shading"] == "flat"
    page.keyboard.press("Control+z")
    wait_for_full_frame(page)
    assert page.evaluate("window.view.settings.a") == {} and page.input_value("#shading") == ""
    assert page.is_disabled("#undo")
    page.keyboard.press("?")
    assert page.is_visible("#help") and "turntable" in page.text_content("#help")
    page.keyboard.press("Escape")
    assert page.is_hidden("#help")


def test_compared_both_figures_show_and_a_mesh_promises_no_exact_error(page, browser, tmp_path):
    page.select_option("#compare", "side")
    wait_for_full_frame(page)
    assert page.text_content("#frame-time").startswith("A: ") and "; B: " in page.text_content("#frame-time")
    assert "; B: " in page.text_content("#rays")
    assert page.is_visible("#exact-row")
    mesh = tmp_path / "tri.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with opened(browser, mesh) as tab:
        assert tab.is_disabled("#level") and "no curved shapes" in tab.get_attribute("#level", "title")
        assert tab.is_hidden("#exact-row")


def test_show_lays_the_three_models_side_by_side_in_a_narrow_cell(browser, tmp_path):
    """rp.show() in a JupyterLab-wide output (about 900 px): the three models in one row, their figures under
    their images, where the wide table of timings used to push each onto its own line."""
    path = write_tiny_scene(tmp_path, 200, 150)
    html = rp.show(path)._repr_html_()
    context = browser.new_context(viewport={"width": 900, "height": 800})
    try:
        tab = context.new_page()
        tab.set_content(f"<!doctype html><body style='margin:0;width:860px'>{html}</body>")
        boxes = [tab.locator("img").nth(k).bounding_box() for k in range(3)]
        assert len({round(box["y"]) for box in boxes}) == 1 and boxes[0]["x"] < boxes[1]["x"] < boxes[2]["x"]
    finally:
        context.close()


def test_a_drag_rewrites_no_unchanged_readout_and_the_times_four_times_a_second(page):
    """Each readout whose text changes is laid out and painted again, on the page's main thread, beside 30+ drafts a
    second: the plan's warnings and what it left out are written only when they change, the frame's times at most
    every READOUT_MS (250 ms) while drafts come (issue 35: drafts 39-52 against 45-75 ms input → paint, three
    interleaved pairs). Counted with a MutationObserver while the turntable turns (drafts, no input)."""
    wait_for_full_frame(page)
    page.evaluate("""() => {
        window.rewrites = {};
        for (const id of ["warnings", "left-out", "frame-time", "rays"]) {
            window.rewrites[id] = 0;
            new MutationObserver((changes) => { window.rewrites[id] += changes.length; })
                .observe(document.getElementById(id), { childList: true, characterData: true, subtree: true });
        }
        window.turnStarted = performance.now();
    }""")
    answered = page.evaluate("window.view.answered")
    page.check("#turntable")
    page.wait_for_function("(before) => window.view.answered > before + 20", arg=answered, timeout=60_000)
    counted = page.evaluate("() => ({ ...window.rewrites, ms: performance.now() - window.turnStarted })")
    page.uncheck("#turntable")
    wait_for_full_frame(page)
    assert counted["warnings"] == 0 and counted["left-out"] == 0, counted
    # Each write of a text is one mutation (its child replaced); 20 drafts or more were shown meanwhile.
    for readout in ("frame-time", "rays"):
        assert counted[readout] <= counted["ms"] / 250 + 2, counted


def test_a_phone_lays_the_page_out_at_its_own_width(browser, scene_path):
    """Issue 49: without a viewport tag a phone laid the page out 980 px wide at 0.4× (5.6 px text) and the narrow
    layout never applied. Emulated as a phone is (is_mobile: the browser then honours or ignores the tag)."""
    with running(scene_path) as url:
        context = browser.new_context(viewport={"width": 390, "height": 844}, device_scale_factor=3, is_mobile=True,
                                      has_touch=True)
        try:
            tab = context.new_page()
            tab.goto(url)
            wait_for_full_frame(tab)
            assert tab.evaluate("document.documentElement.clientWidth") == 390
            assert tab.evaluate("getComputedStyle(document.querySelector('main')).flexDirection") == "column"
            assert tab.evaluate("parseFloat(getComputedStyle(document.body).fontSize)") >= 12
        finally:
            context.close()


def test_a_trackpad_scroll_with_sideways_jitter_zooms_and_does_not_pan(page):
    """Issue 49: any deltaX ≠ 0 took the pan branch, so a trackpad's vertical scroll (±1 px sideways) crept the
    view. Ten events of 12 px up and 1 px sideways zoom in by 1.1^(-120/100), along the view axis."""
    box = page.locator("#image-a").bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    for k in range(10):
        page.mouse.wheel(1 if k % 2 else -1, -12)
    wait_for_full_frame(page)
    settings = page.evaluate("window.view.settings.a")
    assert "camera.look_at" not in settings or settings["camera.look_at"] == [0, 0, 0], settings
    np.testing.assert_allclose(settings["camera.position"], [0, 0, 4 * 1.1 ** -1.2], atol=1e-4)


def test_small_wheel_steps_move_the_light_as_little_as_they_turn(page):
    """Issue 49: the gizmo moved the light 10 % an event whatever its size, so 30 trackpad steps of 3 px put it
    inside the object. Now 90 px in all: 1.1^(-0.9) of its distance."""
    box = page.locator("#gizmo").bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    for _ in range(30):
        page.mouse.wheel(0, -3)
    wait_for_full_frame(page)
    position = page.evaluate("window.view.settings.a['lights.0.position']")
    np.testing.assert_allclose(position, 1.1 ** -0.9 * np.array([2, 2, 3]), atol=1e-4)


def test_a_light_distance_of_0_is_said_and_the_light_stays(page):
    """Issue 49: a distance of 0 (or less) was ignored silently; now one line on the page, the field restored."""
    before = page.evaluate("window.view.settings.a['lights.0.position'] ?? null")
    page.fill("#light-distance", "0")
    page.dispatch_event("#light-distance", "change")
    assert page.is_visible("#error") and "greater than 0" in page.text_content("#error")
    assert page.evaluate("window.view.settings.a['lights.0.position'] ?? null") == before
    assert float(page.input_value("#light-distance")) == pytest.approx(math.sqrt(17), abs=1e-3)


def this_machines_address() -> str | None:
    """An address of this machine other than loopback (the one its default route leaves from), or None."""
    import socket
    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.connect(("192.0.2.1", 9))  # TEST-NET-1: nothing is sent, the kernel only picks a route
            address = probe.getsockname()[0]
    except OSError:
        return None
    return None if address.startswith("127.") or address == "0.0.0.0" else address


def test_a_page_from_another_machine_gets_full_frames_as_png(browser, scene_path):
    """Reached by an address other than loopback (`--host 0.0.0.0`), the page asks for full frames as PNGs (640×360
    raw is 0.9 MB): the PNG is decoded into the canvas and kept for capture, and what the canvas shows is render's
    8-bit image; drafts stay raw."""
    address = this_machines_address()
    if address is None:
        pytest.skip("this machine has no address but loopback")
    with running(scene_path, host="0.0.0.0") as url:
        context = browser.new_context(viewport={"width": 1000, "height": 800})
        try:
            tab = context.new_page()
            errors: list[str] = []
            tab.on("pageerror", lambda error: errors.append(str(error)))
            tab.goto(url.replace("127.0.0.1", address))
            wait_for_full_frame(tab)
            assert tab.evaluate("window.view.urls['image-a']").startswith("blob:")
            expected = to_8bit(rp.render(rp.load_scene(scene_path)).image)
            assert np.abs(page_image(tab).astype(int) - expected).max() <= 1  # through the PNG decoder's colour path
            assert not errors, errors
        finally:
            context.close()


def test_a_frame_over_its_share_of_the_servers_budget_is_said_on_the_page(browser, scene_path):
    """`view --max-memory`: the page's first frame fits its share (half the server's budget: two frames render
    at once); the tessellation slider at level 6 asks for a sphere whose frame does not, and the page says the
    memory line render gives, while the last frame stays on screen."""
    from raycast_phong.tools.view.server import frame_of, open_scene, scene_with
    source = open_scene(scene_path)
    small = rp.Renderer().check_fits(frame_of(scene_with(source, {}))).total
    large = rp.Renderer().check_fits(frame_of(scene_with(source, {"objects.0.subdivisions": 6}))).total
    assert large > small
    with opened(browser, scene_path, max_memory=small + large) as tab:  # a share of (small + large) / 2
        tab.fill("#level", "6")
        tab.dispatch_event("#level", "change")
        tab.wait_for_selector("#error:not([hidden])", timeout=30_000)
        said = tab.text_content("#error")
        assert "objects.0.subdivisions" in said and "budget" in said, said
        assert tab.evaluate("document.querySelector('#image-a').dataset.quality") == "full"


FLOODING_PAGES = 12  # other pages, each keeping a large full frame asked for all the time


def test_a_page_s_draft_is_not_held_behind_other_pages_full_frames(browser, scene_path, monkeypatch):
    """Twelve other pages (sockets) each keep a 1280×720 full frame asked for; this page's drag asks a draft. The
    frame threads take by turns the cheapest and the oldest work (tools/view/frame_queue.py), and a draft is the
    cheapest (other pages' checks of their steps come after it), so while it waits at most one of the other
    pages' frames is taken before it (the oldest's turn), however many wait; first come, first served took every
    frame queued before it. Counted in the server's own order of taking, not in time, so it holds on any machine
    and at any load."""
    from websockets.sync.client import connect as socket_to

    from raycast_phong.tools.view import frame_queue
    large = {"render.width": 1280, "render.height": 720, "render.samples": 2}
    finished, stop, errors, events = [], threading.Event(), [], []
    take, submit_at, making = frame_queue.FrameQueue._take, frame_queue.FrameQueue.submit_at, threading.local()

    def tagged(queue, cost, fn, /, *args, **kwargs):  # what the work is: a frame's step, or the steps' check
        making.what = (getattr(fn, "__name__", ""), args[-1] if args else None)
        return submit_at(queue, cost, fn, *args, **kwargs)

    @dataclasses.dataclass(order=True)
    class Logged(frame_queue._Work):  # made by submit_at, the queue's lock held
        def __post_init__(self):
            self.what = making.what
            events.append(("queued", self))

    def taken(queue):
        work = take(queue)
        events.append(("taken", work))  # the queue's lock is held here too
        return work
    monkeypatch.setattr(frame_queue.FrameQueue, "submit_at", tagged)
    monkeypatch.setattr(frame_queue, "_Work", Logged)
    monkeypatch.setattr(frame_queue.FrameQueue, "_take", taken)

    def flood(address: str, origin: str, page: int) -> None:
        try:
            with socket_to(address, origin=origin, max_size=None) as ws:
                ws.recv(timeout=60)
                for request in range(1, 10_000):
                    if stop.is_set():
                        return
                    ws.send(json.dumps({"type": "render", "id": request, "quality": "full", "settings": {
                        **large, "lights.0.position": [page + request * 1e-3, 2, 3]}}))  # never a cached frame
                    while not isinstance(ws.recv(timeout=120), bytes):
                        pass
                    finished.append(page)
        except Exception as error:  # noqa: BLE001 - said by the test's assertion, not lost in a thread
            if not stop.is_set():
                errors.append(repr(error))

    with opened(browser, scene_path) as tab:
        origin = tab.url_with_token.split("/?", 1)[0]
        address = origin.replace("http://", "ws://") + "/socket?token=" + tab.url_with_token.split("token=", 1)[1]
        threads = [threading.Thread(target=flood, args=(address, origin, page), daemon=True)
                   for page in range(FLOODING_PAGES)]
        for thread in threads:
            thread.start()
        try:
            deadline = time.monotonic() + 120
            while len(finished) < 2 * FLOODING_PAGES and not errors and time.monotonic() < deadline:
                time.sleep(0.05)  # every page has had a frame: each now keeps one waiting or running
            assert len(finished) >= 2 * FLOODING_PAGES, errors
            flooded = len(events)
            drag(tab, "#image-a", 40, 10)
        finally:
            stop.set()
            for thread in threads:
                thread.join(120)
    assert not errors, errors
    later = events[flooded:]
    # The page's draft: a frame's draft step (the other pages ask full frames only: a preview or a full step,
    # each after a check of its steps at a draft's cost).
    draft = next(work for event, work in later if event == "queued" and work.what == ("frame", "draft"))
    queued_at = events.index(("queued", draft))
    frames = {work.number for event, work in events[:queued_at]
              if event == "queued" and work.what[0] == "frame" and work.what[1] != "draft"}
    waiting = frames - {work.number for event, work in events[:queued_at] if event == "taken"}
    assert len(waiting) >= 3, waiting  # the other pages kept frames waiting: the draft had a queue to jump
    ahead = [work for event, work in events[queued_at:events.index(("taken", draft))]
             if event == "taken" and work.number in waiting]
    assert len(ahead) <= 1, f"{len(ahead)} of the {len(waiting)} frames waiting were taken before the page's draft"
