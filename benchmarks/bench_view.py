"""Latency of `raycast-phong view` from a change to its image, through the real server and socket (issue 15).

Serves the view (uvicorn, on a background thread) and talks to it as the page does, over a websocket:
  step      one change at a time (the light dragged to a new point), waiting for each frame: the time from
            sending the change to having the PNG, for draft frames (a quarter of the pixels) and full ones, and
            full ones whose exact errors (analytic scenes) are computed meanwhile on the reference thread
  drag      a pointer moving at --rate Hz for --seconds, sent without waiting, as a browser does: how many
            requests were dropped (latest wins), the age of each frame on arrival, and the time from the
            last move to its frame (no queue builds up if it stays near one frame's time)
Target: a draft frame within 100 ms at 640×360. Reports medians and 90th percentiles; asserts nothing.
Usage: python benchmarks/bench_view.py [SCENE] [--size 640x360] [--steps 20] [--rate 60] [--seconds 3]

--browser: the latency a user feels, in Playwright driving Debian's Chromium (issue 23's targets: draft ≤ 50 ms
and full ≤ 100 ms at 640×360 while dragging, full ≤ 250 ms at 1280×720). The page records, for each frame it
shows, the time from the input event it answers to the first animation frame after the image decoded
(window.view.painted). Three runs: `rest` (640×360 and 1280×720: press on the light gizmo, one move, wait for
the draft on screen, release, wait for the full frame and its exact errors), and `dragging` at 640×360 (drags
of --seconds / 3 at --rate Hz, each released into the next with no pause, so a release's exact-error job runs
while the next drag's drafts are rendered). Median and 95th percentile.

--browser --unpaced: strokes as a hand makes them, not paced to the page (Playwright's mouse waits for the page
to take each event, so a busy page slows the input down and hides its own lag): --strokes strokes back to back
(each released into the next), of --stroke seconds at --rate Hz, sent through the DevTools protocol without
waiting for the page, over the light gizmo (`light`) and over the image (`orbit`). Reports input → paint of the
drafts while dragging (from the oldest pointer event a frame answers to the first animation frame after it
decoded), the frames painted per second while dragging, and the releases answered by a full frame (release →
paint). The load average is printed beside the figures.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import math
import os
import statistics
import time

from websockets.sync.client import connect

from raycast_phong.tools.view import running
from raycast_phong.tools.view.server import unpack


def quantile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, math.ceil(q * len(ordered)) - 1)]


def summary(name: str, seconds: list[float]) -> str:
    ms = [1000 * s for s in seconds]
    return (f"{name:42} median {statistics.median(ms):7.1f} ms   p90 {quantile(ms, 0.9):7.1f} ms   "
            f"max {max(ms):7.1f} ms   (n = {len(ms)})")


def point(k: int, n: int) -> list[float]:
    """The k-th of n light positions on a circle of radius 5 round the view axis at z = 4 (the page's gizmo
    turning the light round the look-at point)."""
    angle = 2 * math.pi * k / max(n, 1)
    return [round(5 * math.cos(angle), 6), round(5 * math.sin(angle), 6), 4.0]


CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]


def p95(values: list[float]) -> float:
    return quantile(values, 0.95)


def browser_benchmark(scene: str | None, steps: int, rate: float, seconds: float) -> None:
    """The `--browser` runs (see the module docstring); prints one line per run and quality."""
    from urllib.parse import quote

    from playwright.sync_api import sync_playwright

    def opened(page, url: str, width: int, height: int) -> None:
        kept = {"a": {"render.width": width, "render.height": height}, "compare": "off"}
        page.goto("about:blank")  # else a new fragment alone would not load the page again
        page.goto(f"{url}#view={quote(json.dumps(kept))}")  # the permalink sets the size
        page.wait_for_function("() => window.view.painted.some((p) => p.quality === 'full')", timeout=180_000)
        assert page.evaluate("window.view.lastFrame.stats.a.width") == width
        page.evaluate("window.view.painted.length = 0")

    def painted(page, quality: str) -> list[float]:
        return page.evaluate("(q) => window.view.painted.filter((p) => p.quality === q).map((p) => p.ms)", quality)

    def report(name: str, page) -> None:
        for quality in ("draft", "full"):
            ms = painted(page, quality)
            if ms:
                print(f"{name:28} {quality:5}  median {statistics.median(ms):6.1f} ms   p95 {p95(ms):6.1f} ms   "
                      f"(n = {len(ms)})")

    with sync_playwright() as driver:
        browser = driver.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        page = browser.new_page(viewport={"width": 1700, "height": 1100})
        with running(scene) as url:
            for width, height in ((640, 360), (1280, 720)):
                opened(page, url, width, height)
                box = page.locator("#gizmo").bounding_box()
                x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
                for k in range(steps):
                    count = len(page.evaluate("window.view.painted"))
                    page.mouse.move(x, y)
                    page.mouse.down()
                    page.mouse.move(x + (3 if k % 2 else -3), y)
                    page.wait_for_function("(n) => window.view.painted.length > n", arg=count, timeout=60_000)
                    page.mouse.up()
                    page.wait_for_function("(n) => window.view.painted.length > n + 1", arg=count, timeout=60_000)
                    if page.evaluate("window.view.hello.analytic"):  # at rest: its exact errors are done too
                        page.wait_for_function("() => document.querySelector('#exact').textContent.startsWith("
                                               "'RMSE')", timeout=120_000)
                report(f"rest {width}×{height}", page)
            opened(page, url, 640, 360)
            box = page.locator("#gizmo").bounding_box()
            x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
            moves = max(1, int(rate * seconds / 3))
            for drag in range(3):
                page.mouse.move(x, y)
                page.mouse.down()
                started = time.perf_counter()
                for k in range(moves):
                    time.sleep(max(0.0, started + k / rate - time.perf_counter()))
                    page.mouse.move(x + 40 * math.sin(2 * math.pi * k / moves), y + 10 * math.sin(drag + k / 9))
                page.mouse.up()
            page.wait_for_function("() => window.view.painted.at(-1).quality === 'full'", timeout=60_000)
            report("dragging 640×360", page)
        browser.close()


def unpaced_benchmark(scene: str | None, size: str, rate: float, strokes: int, stroke: float) -> None:
    """The `--browser --unpaced` runs (see the module docstring); prints one line per measure and target."""
    width, height = (int(x) for x in size.lower().split("x"))
    from raycast_phong.tools.view.server import draft_of, open_scene, scene_with
    shaped = draft_of(scene_with(open_scene(scene), {"render.width": width, "render.height": height})).render
    draft = f"{shaped.width}×{shaped.height}"
    print(f"view of {scene or 'the default scene'} at {width}×{height} (drafts {draft}); "
          f"{strokes} strokes of {stroke:g} s at {rate:g} Hz, back to back, not paced to the page; "
          f"load average {os.getloadavg()[0]:.1f}")
    with running(scene) as url:
        results = asyncio.run(_unpaced(url, width, height, rate, strokes, stroke))
    for target, found in results.items():
        drafts, fulls, seconds = found["drafts"], found["fulls"], found["seconds"]
        shown = (f"median {statistics.median(drafts):6.1f} ms   p95 {p95(drafts):6.1f} ms" if drafts else "none")
        print(f"{target:6} drafts while dragging: input→paint {shown}   {len(drafts) / seconds:5.1f} frames/s "
              f"painted (n = {len(drafts)})")
        answered = (f"median {statistics.median(fulls):6.1f} ms   p95 {p95(fulls):6.1f} ms   "
                    f"worst {max(fulls):6.1f} ms, {sum(ms > 100 for ms in fulls)} over 100 ms" if fulls else "none")
        print(f"{target:6} full frame after a release: {len(fulls)} of {strokes} releases, release→paint {answered}")
    print(f"load average after: {os.getloadavg()[0]:.1f}")


async def _unpaced(url: str, width: int, height: int, rate: float, strokes: int, stroke: float) -> dict:
    from urllib.parse import quote

    from playwright.async_api import TimeoutError as PlaywrightTimeout
    from playwright.async_api import async_playwright

    results = {}
    async with async_playwright() as driver:
        browser = await driver.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        page = await browser.new_page(viewport={"width": 1700, "height": 1100})
        kept = {"a": {"render.width": width, "render.height": height}, "compare": "off"}
        await page.goto(f"{url}#view={quote(json.dumps(kept))}")  # the permalink sets the size
        await page.wait_for_function("() => window.view.painted.some((p) => p.quality === 'full')", timeout=180_000)
        protocol = await page.context.new_cdp_session(page)
        loop = asyncio.get_running_loop()

        def mouse(kind: str, x: float, y: float) -> asyncio.Task:
            """One mouse event sent without waiting for the page to take it (as the OS queues a hand's)."""
            event = {"type": kind, "x": x, "y": y, "button": "left", "buttons": 0 if kind == "mouseReleased" else 1,
                     "clickCount": 1 if kind != "mouseMoved" else 0}
            return asyncio.ensure_future(protocol.send("Input.dispatchMouseEvent", event))

        for target, selector in (("light", "#gizmo"), ("orbit", "#image-a")):
            box = await page.locator(selector).bounding_box()
            x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
            reach = min(box["width"], box["height"]) / 4
            await page.mouse.move(x, y)
            await page.evaluate("window.view.painted.length = 0")
            sent, moves = [], max(1, round(rate * stroke))
            started = loop.time()
            for k in range(strokes * moves):
                await asyncio.sleep(max(0.0, started + k / rate - loop.time()))
                turn = 2 * math.pi * (k % moves) / moves
                point = (x + reach * math.sin(turn), y + reach / 3 * math.sin(2 * turn + k // moves))
                if k % moves == 0:
                    sent.append(mouse("mousePressed", *point))
                sent.append(mouse("mouseMoved", *point))
                if k % moves == moves - 1:
                    sent.append(mouse("mouseReleased", *point))
            seconds = loop.time() - started
            await asyncio.gather(*sent)
            await page.wait_for_function("() => window.view.asked && window.view.answered >= window.view.asked.id",
                                         timeout=120_000)
            # ... and painted: the last release's frame is answered when it arrives, painted a display frame later
            with contextlib.suppress(PlaywrightTimeout):  # a page that never paints it: counted as not answered
                await page.wait_for_function("() => window.view.painted.some((p) => p.id === window.view.asked.id)",
                                             timeout=10_000)
            painted = await page.evaluate("window.view.painted")
            results[target] = {"drafts": [p["ms"] for p in painted if p["quality"] == "draft"],
                               "fulls": [p["ms"] for p in painted if p["quality"] == "full"], "seconds": seconds}
        await browser.close()
    return results


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=None, help="scene file (default: the built-in figure)")
    parser.add_argument("--size", default="640x360", help="WIDTHxHEIGHT of the full frame")
    parser.add_argument("--steps", type=int, default=20, help="changes per quality in the step test")
    parser.add_argument("--rate", type=float, default=60.0, help="pointer events per second in the drag test")
    parser.add_argument("--seconds", type=float, default=3.0, help="length of the drag test")
    parser.add_argument("--browser", action="store_true", help="the latency felt in Chromium instead (Playwright)")
    parser.add_argument("--unpaced", action="store_true",
                        help="with --browser: strokes not paced to the page, input → paint (see above)")
    parser.add_argument("--strokes", type=int, default=10, help="strokes in each --unpaced run")
    parser.add_argument("--stroke", type=float, default=0.5, help="seconds each --unpaced stroke lasts")
    args = parser.parse_args()
    if args.browser and args.unpaced:
        return unpaced_benchmark(args.scene, args.size, args.rate, args.strokes, args.stroke)
    if args.browser:
        return browser_benchmark(args.scene, args.steps, args.rate, args.seconds)
    width, height = (int(x) for x in args.size.lower().split("x"))
    settings = {"render.width": width, "render.height": height}

    with running(args.scene) as url:
        origin = url.split("/?", 1)[0]
        address = origin.replace("http://", "ws://") + "/socket?token=" + url.split("token=", 1)[1]
        with connect(address, origin=origin, max_size=None) as ws:
            json.loads(ws.recv())  # hello
            request_id = 0

            def ask(quality: str, position: list[float], reference: bool = False) -> int:
                nonlocal request_id
                request_id += 1
                moved = {**settings, "lights.0.position": position}
                ws.send(json.dumps({"type": "render", "id": request_id, "quality": quality, "settings": moved,
                                    "reference": reference}))
                return request_id

            def frame() -> dict:
                while True:
                    message = ws.recv()
                    if isinstance(message, bytes):
                        header = unpack(message)[0]
                        if header["type"] == "frame":
                            return header
                    elif json.loads(message)["type"] == "error":
                        raise SystemExit(json.loads(message)["message"])

            ask("full", point(0, 1))  # warm: the kernels load and the BVH code runs once
            frame()
            print(f"view of {args.scene or 'the default scene'} at {width}×{height} "
                  f"(draft {(width + 1) // 2}×{(height + 1) // 2}), served at {origin}")
            for quality, reference in (("draft", False), ("full", False), ("full", True)):
                latencies, renders, cpu = [], [], []
                for k in range(args.steps):
                    started, used = time.perf_counter(), time.process_time()
                    ask(quality, point(k, args.steps), reference)
                    header = frame()
                    latencies.append(time.perf_counter() - started)
                    cpu.append(time.process_time() - used)  # this process's CPU: the server runs on its threads
                    renders.append(header["stats"]["a"]["frame"])
                name = f"{quality}{' + exact errors' if reference else ''}"
                print(summary(f"step, {name}: change→image", latencies))
                print(summary(f"step, {name}: render frame", renders))
                print(summary(f"step, {name}: CPU (all threads)", cpu))

            # Drag: send at the pointer's rate without waiting; the server keeps only the newest waiting request.
            sent_at: dict[int, float] = {}
            ages, count = [], int(args.rate * args.seconds)
            started = time.perf_counter()
            for k in range(count):
                due = started + k / args.rate
                while True:  # read whatever has arrived until the next pointer event is due
                    ws_timeout = due - time.perf_counter()
                    if ws_timeout <= 0:
                        break
                    try:
                        message = ws.recv(timeout=ws_timeout)
                    except TimeoutError:
                        break
                    if isinstance(message, bytes):
                        header = unpack(message)[0]
                        ages.append(time.perf_counter() - sent_at[header["id"]])
                sent_at[ask("draft", point(k, 120))] = time.perf_counter()
            last = request_id
            while True:
                message = ws.recv()
                if isinstance(message, bytes):
                    header = unpack(message)[0]
                    ages.append(time.perf_counter() - sent_at[header["id"]])
                    if header["id"] == last:
                        break
            tail = time.perf_counter() - sent_at[last]
            print(summary("drag: frame age on arrival", ages))
            print(f"drag: {count} moves at {args.rate:g} Hz, {len(ages)} frames shown, {count - len(ages)} dropped; "
                  f"last move → its frame {1000 * tail:.1f} ms")


if __name__ == "__main__":
    main()
