"""`raycast-phong view` in a real browser: Playwright driving Debian's headless Chromium (/usr/bin/chromium,
installed by .ci/run with apt). The page's image is compared with render() of the same settings."""

from __future__ import annotations

import base64
import http.server
import math
import threading
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
    with running(scene_path) as url:
        tab = browser.new_page(viewport={"width": 1000, "height": 700})
        errors: list[str] = []
        tab.on("pageerror", lambda error: errors.append(str(error)))
        tab.goto(url)
        wait_for_full_frame(tab)
        tab.url_with_token = url
        yield tab
        tab.close()
        assert not errors, errors


def wait_for_full_frame(tab) -> None:
    """Wait until image A shows the full frame of the newest request sent."""
    sent = tab.evaluate("window.view.nextId - 1")
    tab.wait_for_function("""(sent) => { const img = document.querySelector('#image-a');
        return img.dataset.quality === 'full' && Number(img.dataset.id) >= sent && img.complete; }""",
                          arg=sent, timeout=120_000)


def page_image(tab, selector: str = "#image-a") -> np.ndarray:
    """The PNG the page shows in `selector`, as 8-bit (H, W, 3)."""
    encoded = tab.evaluate("""async (selector) => {
        const bytes = new Uint8Array(await (await fetch(document.querySelector(selector).src)).arrayBuffer());
        let text = ''; for (const b of bytes) text += String.fromCharCode(b); return btoa(text); }""", selector)
    return decode_png(base64.b64decode(encoded))


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


def test_dragging_moves_the_light_and_refines_when_released(page, scene_path):
    box = page.locator("#image-a").bounding_box()
    start = (box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    end = (box["x"] + 0.8 * box["width"], box["y"] + 0.25 * box["height"])
    page.mouse.move(*start)
    page.mouse.down()
    page.mouse.move(*end, steps=8)
    page.wait_for_function("document.querySelector('#image-a').dataset.quality === 'draft'", timeout=60_000)
    page.mouse.up()
    wait_for_full_frame(page)
    position = page.evaluate("window.view.settings.a['lights.0.position']")
    # Camera at z = 4 looking down −z, fov 40°, 4:3; the light (2, 2, 3) is 1 in front of the eye, so it moves
    # in the plane z = 3: image point (u, v) puts it at ((2u − 1) tan 20° · 4/3, (1 − 2v) tan 20°, 3).
    u, v = (end[0] - box["x"]) / box["width"], (end[1] - box["y"]) / box["height"]
    t = math.tan(math.radians(20))
    expected = [(2 * u - 1) * t * WIDTH / HEIGHT, (1 - 2 * v) * t, 3.0]
    np.testing.assert_allclose(position, expected, atol=1e-5)  # the server rounds to 6 decimals
    moved = rp.load_scene(scene_path, [f"lights.0.position={position}"])
    np.testing.assert_array_equal(page_image(page), to_8bit(rp.render(moved).image))


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
    assert saved.name == "tiny-view.toml"
    assert rp.load_scene(saved).materials["red"].shininess == 31.6
    result = CliRunner().invoke(app, ["render", str(saved), "-o", str(tmp_path / "cli.png"), "--quiet"])
    assert result.exit_code == 0, result.output
    rendered = np.round(rp.read_image(tmp_path / "cli.png")[0] * 255).astype(np.uint8)
    np.testing.assert_array_equal(rendered, page_image(page))


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


@contextmanager
def other_origin():
    """An empty page at http://127.0.0.1:<another port>/."""
    class Blank(http.server.BaseHTTPRequestHandler):
        def do_GET(self):
            body = b"<!doctype html><title>another origin</title>"
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
