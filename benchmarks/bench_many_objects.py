"""A scene of many small objects (issue 21, item 8): time and peak memory of each stage of a render.

N boxes (or icospheres of 80 faces) of 0.1 spread in a cube, rotated, a 320×240 image: the scene table is
made in Python (a file of 10⁶ objects is over the 16 MiB scene-file cap), then timed through
validate_scene, the memory estimate, build_geometry and the whole render(). Each stage's peak is VmHWM
reset before it (/proc/self/clear_refs), above the resident size at its start; run each N in a fresh
process (the default), as malloc keeps what a previous stage freed.

Usage: python benchmarks/bench_many_objects.py [--count 100000] [--shape box|icosphere|plane]
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np

import raycast_phong as rp
from raycast_phong.geometry.build import build_geometry
from raycast_phong.renderer.budget import estimate_memory


def scene_table(count: int, shape: str) -> dict:
    """`count` objects of one shape in a cube of side ≈ count^(1/3), each turned differently."""
    generator = np.random.default_rng(1)
    side = max(1.0, count ** (1 / 3))
    where = (generator.random((count, 3)) * side).round(3).tolist()
    turn = (generator.random((count, 3)) * 360).round(1).tolist()
    keys = {"box": {"size": [0.1, 0.1, 0.1]}, "icosphere": {"radius": 0.05, "subdivisions": 1},
            "plane": {"size": [0.1, 0.1]}}[shape]
    objects = [{"shape": shape, **keys, "translate": t, "rotate": r} for t, r in zip(where, turn)]
    centre = side / 2
    return {"render": {"width": 320, "height": 240},
            "camera": {"position": [centre, centre, 3 * side], "look_at": [centre, centre, centre]},
            "lights": [{"type": "point", "position": [centre, 2 * side, 2 * side]}],
            "objects": objects}


def _status(field: str) -> int:
    with open("/proc/self/status") as status:
        return next(int(line.split()[1]) << 10 for line in status if line.startswith(field))


CPU = [0.0, 0.0]  # user and system CPU seconds of the last measurement


def _cpu() -> tuple[float, float]:
    used = resource.getrusage(resource.RUSAGE_SELF)
    return used.ru_utime, used.ru_stime


def measured(function):
    """(result, seconds, bytes of peak above the resident size at the start); CPU is set to the user and
    system CPU seconds (all threads), which another job on the machine moves less than the wall-clock time.
    On a virtual machine the system time is mostly first touches of memory the host must back."""
    with open("/proc/self/clear_refs", "w") as refs:
        refs.write("5")  # reset VmHWM to the resident size now
    start_rss, start, (user, system) = _status("VmRSS:"), time.perf_counter(), _cpu()
    result = function()
    CPU[:] = [_cpu()[0] - user, _cpu()[1] - system]
    return result, time.perf_counter() - start, _status("VmHWM:") - start_rss


def cpu_text() -> str:
    return f"CPU {CPU[0]:.2f} s user + {CPU[1]:.2f} s system"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=100_000)
    parser.add_argument("--shape", choices=("box", "icosphere", "plane"), default="box")
    args = parser.parse_args()
    rp.render(rp.validate_scene(scene_table(8, args.shape)), max_memory="4G")  # kernels loaded, caches warm
    table = scene_table(args.count, args.shape)
    scene, seconds, peak = measured(lambda: rp.validate_scene(table, source="bench"))
    print(f"{args.count} objects ({args.shape})  validate {seconds:6.2f} s ({cpu_text()}) "
          f"{peak / 2**20:7.0f} MB", flush=True)
    estimate, seconds, peak = measured(lambda: estimate_memory(scene))
    print(f"  estimate {seconds:6.2f} s  total {estimate.total / 2**20:7.0f} MB", flush=True)
    _, seconds, peak = measured(lambda: build_geometry(scene))
    print(f"  geometry {seconds:6.2f} s ({cpu_text()}) {peak / 2**20:7.0f} MB", flush=True)
    _, seconds, peak = measured(lambda: rp.render(scene, max_memory="16G"))
    print(f"  render() {seconds:6.2f} s ({cpu_text()}) {peak / 2**20:7.0f} MB (from the validated scene)",
          flush=True)
    scene = None  # its memory is free for the next measurement
    _, seconds, peak = measured(lambda: rp.render(rp.validate_scene(table, source="bench"), max_memory="16G"))
    print(f"  validate and render {seconds:6.2f} s ({cpu_text()}) {peak / 2**20:7.0f} MB, "
          f"estimate {estimate.total / 2**20:7.0f} MB ({(peak - estimate.total) / args.count:+.0f} B an object)",
          flush=True)


if __name__ == "__main__":
    main()
