"""Screenshots of `raycast-phong view` for docs/view.md, taken with Playwright in Debian's headless Chromium.

Usage: python docs/figures/make_view_screenshots.py   (writes docs/images/view-*.png and view-drag.gif)
"""

from __future__ import annotations

import os
from pathlib import Path

from playwright.sync_api import sync_playwright

from raycast_phong.tools.view import running

ROOT = Path(__file__).resolve().parents[2]
IMAGES = ROOT / "docs" / "images"
ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run"]


def settle(page, errors: bool = False) -> None:
    """Wait for the full frame of the newest request (and, if asked, its exact errors)."""
    sent = page.evaluate("window.view.nextId - 1")
    page.wait_for_function("""(sent) => { const img = document.querySelector('#image-a');
        return img.dataset.quality === 'full' && Number(img.dataset.id) >= sent && img.complete; }""",
                           arg=sent, timeout=120_000)
    if errors:
        page.wait_for_function("() => document.querySelector('#exact').textContent.startsWith('RMSE')", timeout=120_000)
    # The frame is painted into the panel's canvas after it decodes (createImageBitmap), over the <img>: two
    # display frames later it is on screen.
    page.evaluate("() => new Promise(done => requestAnimationFrame(() => requestAnimationFrame(done)))")


def animation(page, path: Path) -> None:
    """docs/images/view-drag.gif: the light turned with the gizmo round the spheres, then the camera orbited,
    each step a screenshot of the page after its full frame, assembled by Pillow (optimised palette GIF)."""
    from io import BytesIO

    from PIL import Image
    frames = []

    def shot() -> None:
        settle(page)
        image = Image.open(BytesIO(page.screenshot(clip={"x": 0, "y": 0, "width": 1180, "height": 780})))
        frames.append(image.convert("RGB").resize((826, 546), Image.LANCZOS))

    def step(selector: str, dx: float, dy: float) -> None:
        box = page.locator(selector).bounding_box()
        x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        page.mouse.move(x, y)
        page.mouse.down()
        page.mouse.move(x + dx, y + dy, steps=3)
        page.mouse.up()
        shot()

    shot()
    for dx, dy in [(-6, 0)] * 11 + [(0, 5)] * 4:  # the light across the front to the left (80°), then down
        step("#gizmo", dx, dy)
    for dx, dy in [(10, 0)] * 8 + [(0, 8)] * 3:  # the camera round the spheres, then a little from above
        step("#image-a", dx, dy)
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=220, loop=0, optimize=True)


def main() -> None:
    with sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path="/usr/bin/chromium", args=ARGS)
        page = browser.new_page(viewport={"width": 1320, "height": 860})

        os.chdir(ROOT)  # the page names the scene as given: a short relative path
        with running(Path("scenes/default.toml")) as url:  # the default figure: flat, Gouraud, Phong spheres
            page.goto(url)
            settle(page)
            page.evaluate("window.view.request('full')")  # a second frame: the kernels are loaded by now
            settle(page, errors=True)
            page.screenshot(path=IMAGES / "view-overview.png")
            page.select_option("#compare", "side")
            settle(page, errors=True)
            page.screenshot(path=IMAGES / "view-compare.png")

        with running(Path("scenes/specular.toml")) as url:
            page.goto(url)
            settle(page)
            page.select_option("#compare", "wipe")
            page.select_option("#editing", "b")
            page.select_option("#shading", "phong")  # B: Phong shading (not the page's Gouraud start) …
            page.select_option("[data-key='render.specular']", "blinn")  # … with Blinn's specular term
            settle(page)
            page.fill("#wipe", "45")
            page.dispatch_event("#wipe", "input")
            page.locator("#viewer").screenshot(path=IMAGES / "view-wipe.png")

        with running(Path("scenes/default.toml")) as url:  # the light over the three spheres, by its fields
            page.goto(url)
            settle(page)
            # In the plane z = 6, 4 in front of the eye: over a vertex of the Gouraud sphere, between vertices,
            # further left and down.
            for index, position in enumerate([(0, 0.255068, 6), (-0.906908, 0, 6), (-1.587089, -0.34009, 6)], 1):
                for axis, value in enumerate(position):
                    page.fill(f"#light-xyz input[data-axis='{axis}']", str(value))
                    page.dispatch_event(f"#light-xyz input[data-axis='{axis}']", "change")
                settle(page)
                page.locator("#stage").screenshot(path=IMAGES / f"view-drag-{index}.png")
            page.evaluate("window.view.settings.a['materials.clay.shininess'] = -1")
            page.select_option("[data-key='render.specular']", "blinn")
            page.wait_for_selector("#error:not([hidden])")
            page.screenshot(path=IMAGES / "view-error.png", clip={"x": 0, "y": 0, "width": 1320, "height": 260})
        with running(Path("scenes/default.toml")) as url:  # the animation, from the scene's own light and camera
            page.set_viewport_size({"width": 1180, "height": 860})
            page.goto(url)
            settle(page)
            animation(page, IMAGES / "view-drag.gif")
        browser.close()


if __name__ == "__main__":
    main()
