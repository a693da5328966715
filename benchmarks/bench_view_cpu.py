"""The view server's CPU a frame (issue 35): `raycast-phong view` as a process of its own, driven over its socket one
change at a time as the page drives it (drafts asked as raw RGBA, full frames as PNG), its CPU (user + system, every
thread) read from /proc/PID/stat before and after N frames. A figure that holds on a shared machine better than a
latency does; interleave runs of two checkouts to compare them (--command names the other's `raycast-phong`).

Usage: python benchmarks/bench_view_cpu.py [SCENE] [--frames 150] [--command PATH] [--size 640x360]
Prints, per kind of change (a light moved: draft, full; the camera orbited: draft), the server's CPU a frame and
the median wall time of its frame() (JSON header `seconds`), with the load average. Linux only (/proc).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import shutil
import statistics
import subprocess
import sys
from pathlib import Path

from websockets.sync.client import connect

from raycast_phong.tools.view.server import unpack


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=None)
    parser.add_argument("--frames", type=int, default=150, help="frames of each kind")
    beside = Path(sys.executable).parent / "raycast-phong"  # this environment's command, on PATH or not
    parser.add_argument("--command", default=str(beside) if beside.exists() else shutil.which("raycast-phong"),
                        help="the raycast-phong executable to serve with (another checkout's venv, to compare)")
    parser.add_argument("--size", default="640x360")
    args = parser.parse_args()
    width, height = (int(x) for x in args.size.lower().split("x"))
    server = subprocess.Popen([args.command, "view", "--port", "0", "--no-browser", "-q",
                               *([args.scene] if args.scene else [])], stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True)
    url = next((m.group(0) for line in server.stdout if (m := re.search(r"http://\S+token=\S+", line))), None)
    tick = os.sysconf("SC_CLK_TCK")

    def cpu() -> float:
        fields = open(f"/proc/{server.pid}/stat").read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / tick

    try:
        origin = url.split("/?", 1)[0]
        address = origin.replace("http://", "ws://") + "/socket?token=" + url.split("token=", 1)[1]
        with connect(address, origin=origin, max_size=None) as ws:
            json.loads(ws.recv())  # hello
            asked = 0

            def frame(kind: str, k: int) -> dict:
                nonlocal asked
                asked += 1
                turn = 2 * math.pi * k / 50
                settings = {"render.width": width, "render.height": height}
                if kind == "orbit":  # the camera round the look_at point, as the page's orbit
                    settings["camera.position"] = [round(10 * math.sin(turn / 5), 6), 0.0,
                                                   round(10 * math.cos(turn / 5), 6)]
                else:
                    settings["lights.0.position"] = [round(5 * math.cos(turn), 6), round(5 * math.sin(turn), 6), 4.0]
                quality = "full" if kind == "full" else "draft"
                ws.send(json.dumps({"type": "render", "id": asked, "quality": quality, "settings": settings,
                                    "pixels": "rgba"}))
                while True:
                    message = ws.recv()
                    if isinstance(message, bytes):
                        header = unpack(message)[0]
                        if header["type"] == "frame" and header["id"] == asked:
                            return header
                    elif json.loads(message)["type"] == "error":
                        raise SystemExit(json.loads(message)["message"])

            for k in range(5):  # warm: the kernels, the geometry and the BVH
                for kind in ("full", "draft", "orbit"):
                    frame(kind, k)
            print(f"view of {args.scene or 'the default scene'} at {width}×{height}, served by {args.command}")
            for kind in ("draft", "full", "orbit"):
                used, walls = cpu(), []
                for k in range(args.frames):
                    walls.append(frame(kind, k)["seconds"])
                used = cpu() - used
                name = {"draft": "light moved, draft", "full": "light moved, full", "orbit": "orbit, draft"}[kind]
                print(f"{name:20} server CPU {1000 * used / args.frames:6.2f} ms a frame   frame() wall median "
                      f"{1000 * statistics.median(walls):6.1f} ms   (n = {args.frames}, load {os.getloadavg()[0]:.1f})")
    finally:
        server.terminate()
        server.wait(10)


if __name__ == "__main__":
    main()
