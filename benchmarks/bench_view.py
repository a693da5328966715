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
"""

from __future__ import annotations

import argparse
import json
import math
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=None, help="scene file (default: the built-in figure)")
    parser.add_argument("--size", default="640x360", help="WIDTHxHEIGHT of the full frame")
    parser.add_argument("--steps", type=int, default=20, help="changes per quality in the step test")
    parser.add_argument("--rate", type=float, default=60.0, help="pointer events per second in the drag test")
    parser.add_argument("--seconds", type=float, default=3.0, help="length of the drag test")
    args = parser.parse_args()
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
                latencies, renders = [], []
                for k in range(args.steps):
                    started = time.perf_counter()
                    ask(quality, point(k, args.steps), reference)
                    header = frame()
                    latencies.append(time.perf_counter() - started)
                    renders.append(header["stats"]["a"]["frame"])
                name = f"{quality}{' + exact errors' if reference else ''}"
                print(summary(f"step, {name}: change→image", latencies))
                print(summary(f"step, {name}: render frame", renders))

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
