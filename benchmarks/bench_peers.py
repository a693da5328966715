"""render_file of a 1M-triangle scan against the peers people would pick: Open3D's whole path and f3d (issue 33).

    .venv/bin/python benchmarks/bench_peers.py [--scan stanford-bunny-1m] [--formats ply stl glb obj]
        [--repeats 3] [--width 640] [--height 480] [--threads 2]

The scan is make_scans.py's (the full-resolution Stanford bunny of alecjacobson/common-3d-test-models, midpoint-
subdivided to 1,111,216 triangles, written as binary PLY, binary STL, GLB and OBJ). For each format a fresh process
times, in turn within each round (so a change of the machine's load hits all three alike):
  ours     rp.render_file(FILE) at WIDTH × HEIGHT with the defaults (read, checks, normals, BVH, the framed
           picture), `--threads` threads
  open3d   Open3D's whole path to the same rays: read_triangle_mesh, compute_vertex_normals, RaycastingScene
           (its BVH) and cast_rays of our camera's WIDTH × HEIGHT pinhole rays, `--threads` threads
  f3d      f3d's time to the same image: scene.add(FILE), our camera, render_to_image at WIDTH × HEIGHT (an
           offscreen EGL engine made once before, as our kernels are loaded once: its set-up is printed apart)
Each round is preceded by one untimed warm-up of each. A line per format gives each one's least wall seconds and
least CPU seconds (time.process_time: every thread of the process; f3d's includes its software GL's threads) over
the rounds, the median of the per-round ratios ours/open3d and ours/f3d, the load average before and after, and the
CPU. Targets: ours/open3d ≤ 0.7, ours/f3d ≤ 1.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_mesh import cpu  # the CPU line every benchmark prints
from make_scans import scan


def timed(step) -> tuple[float, float]:
    """Wall and CPU seconds of step()."""
    wall, used = time.perf_counter(), time.process_time()
    step()
    return time.perf_counter() - wall, time.process_time() - used


def measure(path: Path, repeats: int, width: int, height: int, threads: int) -> dict:
    """The three timings of `path`, interleaved by round, in this process."""
    import f3d
    import numpy as np
    import open3d as o3d

    import raycast_phong as rp

    size = [f"render.width={width}", f"render.height={height}"]
    camera = rp.load_scene(path, size).camera

    def ours() -> None:
        rp.render_file(path, size, threads=threads)

    def open3d() -> None:
        mesh = o3d.io.read_triangle_mesh(str(path))
        mesh.compute_vertex_normals()
        caster = o3d.t.geometry.RaycastingScene(nthreads=threads)
        caster.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)),
                             o3d.core.Tensor(np.asarray(mesh.triangles, np.uint32)))
        # Open3D's fov_deg is the horizontal angle: ours (vertical) widened by the aspect ratio.
        horizontal = 2 * np.degrees(np.arctan(np.tan(np.radians(camera.fov) / 2) * width / height))
        rays = caster.create_rays_pinhole(fov_deg=horizontal, center=list(camera.look_at), eye=list(camera.position),
                                          up=list(camera.up), width_px=width, height_px=height)
        caster.cast_rays(rays, nthreads=threads)["t_hit"].numpy()

    f3d.Log.set_verbose_level(f3d.Log.VerboseLevel.QUIET)
    start = time.perf_counter()
    engine = f3d.Engine.create(True)
    engine.window.size = (width, height)
    engine_setup = time.perf_counter() - start

    def f3d_image() -> None:
        engine.scene.clear()
        engine.scene.add(str(path))
        view = engine.window.camera
        view.position, view.focal_point = tuple(camera.position), tuple(camera.look_at)
        view.view_up, view.view_angle = tuple(camera.up), float(camera.fov)
        engine.window.render_to_image()

    steps = {"ours": ours, "open3d": open3d, "f3d": f3d_image}
    for step in steps.values():
        step()  # warm-up: kernels loaded, lazy imports done, each library's first-call set-up
    rounds = {name: [] for name in steps}
    load_before = os.getloadavg()[0]
    for _ in range(repeats):
        for name, step in steps.items():
            rounds[name].append(timed(step))
    found = {"file": path.name, "engine_setup_f3d": engine_setup, "load_before": load_before,
             "load_after": os.getloadavg()[0]}
    for name, times in rounds.items():
        found[name] = min(wall for wall, _ in times)
        found[name + "_cpu"] = min(used for _, used in times)
    for peer in ("open3d", "f3d"):
        found["ours/" + peer] = statistics.median(a[0] / b[0] for a, b in zip(rounds["ours"], rounds[peer]))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scan", default="stanford-bunny-1m")
    parser.add_argument("--formats", nargs="+", default=["ply", "stl", "glb", "obj"])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--one", type=Path, help=argparse.SUPPRESS)  # the child process: measure this file
    args = parser.parse_args()
    if args.one:
        print(json.dumps(measure(args.one, args.repeats, args.width, args.height, args.threads)))
        return
    print(f"# {cpu()}; {args.scan}, {args.width}×{args.height}, {args.threads} threads, best of {args.repeats} "
          "interleaved rounds", flush=True)
    for fmt in args.formats:
        path = scan(args.scan, fmt)
        done = subprocess.run([sys.executable, __file__, "--one", str(path), "--repeats", str(args.repeats),
                               "--width", str(args.width), "--height", str(args.height),
                               "--threads", str(args.threads)], capture_output=True, text=True)
        if done.returncode:
            print(f"{fmt}: failed: {done.stderr.strip().splitlines()[-1:]}", flush=True)
            continue
        row = json.loads(done.stdout.strip().splitlines()[-1])
        print(f"{fmt:4} ours {row['ours']:.2f} s (CPU {row['ours_cpu']:.2f})  open3d {row['open3d']:.2f} s "
              f"(CPU {row['open3d_cpu']:.2f})  f3d {row['f3d']:.2f} s (CPU {row['f3d_cpu']:.2f}; engine "
              f"{row['engine_setup_f3d']:.2f} s apart)  ours/open3d {row['ours/open3d']:.2f}  "
              f"ours/f3d {row['ours/f3d']:.2f}  [load {row['load_before']:.1f} → {row['load_after']:.1f}]",
              flush=True)


if __name__ == "__main__":
    main()
