"""Frame time against the raw embreex cast of the same rays, in one run (issue 12's speed targets).

Scene: icosphere of 6 subdivisions (81,920 triangles, radius 1), camera at distance 4, fov 40°, one
point light, Phong shading and specular, 1000×1000. Reports the median of --repeats runs:
  raw cast  the same rays, generated beforehand, cast through embreex's one-ray API (EmbreeScene.run) in
            the same tiles on the same thread pool: the fixed yardstick of issues 2, 3 and 12
  C cast    the same, through Embree's C API (rtcIntersect16 packets, embree.py): Embree's own limit
  frame     render() wall time minus the BVH build (ray generation + cast + shading + film)
and the ratio frame / raw cast (issue 12's targets: ≤ 0.6 in local mode, ≤ 1.2 in global mode, where
every hit also casts a shadow ray), rays/s, and the per-stage split. Wall-clock ratios move by ±20 % on a
machine other jobs share, so the same ratio is also given in CPU time on one thread (time.thread_time, min
of --repeats, every tile of the frame run in turn in this thread): that one hardly moves.
Usage: python benchmarks/bench_frame.py [--size 1000] [--repeats 5] [--threads 2] [--mode global]
"""

from __future__ import annotations

import argparse
import statistics
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import raycast_phong as rp
from raycast_phong.geometry.build import build_geometry
from raycast_phong.renderer.film import allocate_film
from raycast_phong.renderer.intersect import Accelerator, unit_frame
from raycast_phong.renderer.kernels.shadows import shadow_rays
from raycast_phong.renderer.pack import (
    camera_rig,
    generate_rays,
    prepare_shadows,
)
from raycast_phong.renderer.prepare import TILE_RAYS, TileWork, prepare


def benchmark_scene(size: int, subdivisions: int = 6, mode: str = "local") -> rp.Scene:
    return rp.validate_scene({
        "render": {"width": size, "height": size, "shading": "phong", "specular": "phong", "mode": mode},
        "camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "fov": 40},
        "lights": [{"type": "point", "position": [2, 2, 3]}],
        "materials": {"m": {"ka": 1, "kd": 0.7, "ks": 0.5, "shininess": 32}},
        "objects": [{"shape": "icosphere", "subdivisions": subdivisions, "radius": 1.0, "material": "m"}],
    }, source="benchmark")


class Embreex:
    """embreex's one-ray API on the render's unit-frame mesh: the yardstick (the renderer itself uses only
    Embree's C API)."""

    def __init__(self, geometry, frame):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
        self.scene = rtcore_scene.EmbreeScene(robust=True)
        TriangleMesh(self.scene, frame.to_unit(geometry.vertices).astype(np.float32),
                     np.ascontiguousarray(geometry.faces, np.int32))
        self.scene.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32))  # commits the BVH

    def cast_only(self, origins, directions) -> None:
        self.scene.run(origins, directions, output=1)

    def occluded(self, origins, directions, t_max) -> np.ndarray:
        return self.scene.run(origins, directions, dists=t_max, query="OCCLUDED") == 0


def raw_cast_seconds(scene: rp.Scene, threads: int, use_c_api: bool = False) -> float:
    """Cast the render's rays, pre-generated in the render's tiles, on `threads` threads (through embreex,
    or Embree's C API)."""
    geometry = build_geometry(scene)
    frame = unit_frame(geometry.vertices)
    accelerator = Accelerator(geometry, frame) if use_c_api else Embreex(geometry, frame)
    rig = camera_rig(scene)
    width, height = scene.render.width, scene.render.height
    rows = max(1, TILE_RAYS // width)
    tiles = [generate_rays(rig, frame, width, height, 1, r, min(r + rows, height)) for r in range(0, height, rows)]
    with ThreadPoolExecutor(threads) as pool:
        start = time.perf_counter()
        if use_c_api:
            list(pool.map(lambda tile: accelerator.closest_hits(*tile), tiles))
        else:
            list(pool.map(lambda tile: accelerator.cast_only(*tile), tiles))
        return time.perf_counter() - start


def raw_shadow_cast_seconds(scene: rp.Scene, threads: int) -> float:
    """Occlusion queries of the render's shadow rays, built beforehand per tile, through embreex, on
    `threads` threads."""
    geometry = build_geometry(scene)
    frame = unit_frame(geometry.vertices)
    accelerator, embreex = Accelerator(geometry, frame), Embreex(geometry, frame)
    rig = camera_rig(scene)
    inputs = prepare_shadows(scene, geometry, frame)
    width, height = scene.render.width, scene.render.height
    rows = max(1, TILE_RAYS // width)
    batches = []
    for r in range(0, height, rows):
        origins, directions = generate_rays(rig, frame, width, height, 1, r, min(r + rows, height))
        hits = accelerator.closest_hits(origins, directions)
        hit_rays = np.flatnonzero(hits.face >= 0)
        count = len(hit_rays) * len(inputs.light_kind)
        batch = (np.empty((count, 3), np.float32), np.empty((count, 3), np.float32), np.empty(count, np.float32))
        shadow_rays(inputs, hit_rays, hits.face, hits.u, hits.v, directions, *batch)
        batches.append(batch)
    with ThreadPoolExecutor(threads) as pool:
        start = time.perf_counter()
        list(pool.map(lambda batch: embreex.occluded(batch[0], batch[1], batch[2].copy()), batches))
        return time.perf_counter() - start


def cpu_seconds(scene: rp.Scene, repeats: int) -> tuple[float, float]:
    """CPU time on this one thread (min of `repeats`) of the raw embreex cast and of the frame's tiles, run
    in turn here through render's own prepare and TileWork (a fresh film each time)."""
    ready = prepare(scene)
    accelerator, embreex = ready.build(), Embreex(ready.geometry, ready.frame)
    width, height = scene.render.width, scene.render.height
    bands = ready.bands
    tiles = [generate_rays(camera_rig(scene), ready.frame, width, height, 1, *band) for band in bands]
    casts, frames = [], []
    for _ in range(repeats):
        work = TileWork(ready.rays, accelerator, ready.shadows, ready.shading,
                        allocate_film(width, height, (), np.float32))
        start = time.thread_time()
        for band in bands:
            work(band)
        frames.append(time.thread_time() - start)
        start = time.thread_time()
        for origins, directions in tiles:
            embreex.cast_only(origins, directions)
        casts.append(time.thread_time() - start)
    return min(casts), min(frames)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--mode", choices=["local", "global"], default="local",
                        help="global: also shadow rays to the light; reports their raw cast too")
    args = parser.parse_args()
    scene = benchmark_scene(args.size, mode=args.mode)
    rp.render(benchmark_scene(64, mode=args.mode), threads=args.threads)  # compile or load the kernels first
    casts, c_casts, shadow_casts, frames, splits = [], [], [], [], []
    for _ in range(args.repeats):
        casts.append(raw_cast_seconds(scene, args.threads))
        c_casts.append(raw_cast_seconds(scene, args.threads, use_c_api=True))
        if args.mode == "global":
            shadow_casts.append(raw_shadow_cast_seconds(scene, args.threads))
        result = rp.render(scene, threads=args.threads)
        frames.append(result.timings["frame"])
        splits.append(result.timings)
    cast, frame = statistics.median(casts), statistics.median(frames)
    rays = args.size * args.size
    stages = ("geometry", "build", "rays", *(("shadows",) if args.mode == "global" else ()), "shade")
    median_split = {key: statistics.median(s[key] for s in splits) for key in stages}
    print(f"{args.size}×{args.size}, {result.triangles:,} triangles, {args.threads} threads, median of {args.repeats}")
    c_cast = statistics.median(c_casts)
    print(f"raw cast   {cast * 1e3:7.1f} ms  {rays / cast / 1e6:5.1f} Mrays/s  (embreex)")
    print(f"C cast     {c_cast * 1e3:7.1f} ms  {rays / c_cast / 1e6:5.1f} Mrays/s  ({c_cast / cast:.2f} × raw cast: "
          "Embree's C API, rtcIntersect16)")
    if shadow_casts:
        shadow = statistics.median(shadow_casts)
        print(f"shadow     {shadow * 1e3:7.1f} ms  ({shadow / cast:.2f} × the primary cast): "
              "embreex's occlusion queries alone, same tiles")
    print(f"frame      {frame * 1e3:7.1f} ms  {rays / frame / 1e6:5.1f} Mrays/s")
    target = 1.2 if args.mode == "global" else 0.6
    print(f"ratio      {frame / cast:7.2f}    (frame / raw cast; target ≤ {target})")
    cpu_cast, cpu_frame = cpu_seconds(scene, args.repeats)
    print(f"CPU        {cpu_frame / cpu_cast:7.2f}    (frame {cpu_frame * 1e3:.1f} ms / raw cast "
          f"{cpu_cast * 1e3:.1f} ms, CPU time on one thread)")
    print("stages     " + ", ".join(f"{k} {v * 1e3:.1f} ms" for k, v in median_split.items())
          + "  (rays = generation + cast; summed over threads)")


if __name__ == "__main__":
    main()
