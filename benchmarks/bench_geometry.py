"""The geometry stage for built-in shapes (issue 12: "geometry in milliseconds"), optionally against an older
version of geometry/build.py, in one process.

Times build_geometry (shapes, placement, face and vertex normals, checks) on bench_frame's scene (icosphere of
6 subdivisions, 81,920 triangles, Phong), on the default scene (three 80-face icospheres) and on 1,000
80-face icospheres (the cost per object), and the
icosphere builder alone against trimesh.creation.icosphere. CPU time of this thread (time.thread_time),
minimum of --repeats, the versions interleaved: other jobs on the machine barely move it.

--before REV loads geometry/build.py as it was at git revision REV (beside today's stages) and times it too.
Usage: python benchmarks/bench_geometry.py [--repeats 15] [--before REV]
"""

from __future__ import annotations

import argparse
import importlib.util
import subprocess
import sys
import time
from pathlib import Path

from bench_frame import benchmark_scene

import raycast_phong as rp
from raycast_phong import shapes
from raycast_phong.geometry import build as geometry

ROOT = Path(__file__).resolve().parents[1]


def geometry_at(revision: str):
    """geometry/build.py as of `revision`, as a module of today's package (its relative imports resolve)."""
    source = subprocess.run(["git", "show", f"{revision}:raycast_phong/geometry/build.py"], cwd=ROOT,
                            capture_output=True, text=True, check=True).stdout
    name = f"raycast_phong.geometry._build_{revision}"
    module = importlib.util.module_from_spec(importlib.util.spec_from_loader(name, loader=None))
    module.__package__ = "raycast_phong.geometry"  # its relative imports: today's stages
    sys.modules[name] = module
    exec(compile(source, f"geometry.py@{revision}", "exec"), module.__dict__)
    return module


def best(function, repeats: int) -> float:
    """Minimum thread CPU seconds of `function()` over `repeats` calls."""
    times = []
    for _ in range(repeats):
        start = time.thread_time()
        function()
        times.append(time.thread_time() - start)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--before", help="a git revision whose geometry/build.py to time too")
    args = parser.parse_args()
    versions = {"now": geometry}
    if args.before:
        versions = {args.before: geometry_at(args.before), **versions}
    grid = [{"shape": "icosphere", "subdivisions": 1, "radius": 0.4, "translate": [i % 32, i // 32, 0]}
            for i in range(1000)]
    cases = {"icosphere 6 (81,920 faces)": benchmark_scene(1000),
             "default scene": rp.load_scene(rp.default_scene_path()),
             "1,000 icospheres of 80 faces": rp.validate_scene({"objects": grid}, source="grid")}
    for module in versions.values():
        for scene in cases.values():
            module.build_geometry(scene)  # first calls: imports, caches
    seconds = {(case, name): [] for case in cases for name in versions}
    for _ in range(args.repeats):
        for case, scene in cases.items():
            for name, module in versions.items():
                start = time.thread_time()
                module.build_geometry(scene)
                seconds[case, name].append(time.thread_time() - start)
    print(f"build_geometry, thread CPU time, min of {args.repeats}:")
    for case in cases:
        row = "   ".join(f"{name} {min(seconds[case, name]) * 1e3:7.2f} ms" for name in versions)
        ratio = (f"   now / {args.before} {min(seconds[case, 'now']) / min(seconds[case, args.before]):.2f}"
                 if args.before else "")
        print(f"  {case:30s} {row}{ratio}")
    import trimesh
    ours = best(lambda: shapes.icosphere(6), args.repeats)
    theirs = best(lambda: trimesh.creation.icosphere(6), args.repeats)
    print(f"icosphere(6) alone: shapes.py {ours * 1e3:.2f} ms, trimesh.creation {theirs * 1e3:.2f} ms "
          f"({ours / theirs:.2f}×)")


if __name__ == "__main__":
    main()
