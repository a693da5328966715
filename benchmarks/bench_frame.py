"""The frame against Embree's own limit on the same rays, in one run, on whatever CPU runs it (issue 22).

Scene: icosphere of 6 subdivisions (81,920 triangles, radius 1), camera at distance 4, fov 40°, one point
light, Phong shading and specular, 1000×1000; or, with --scan, cached real scans (make_scans.py) framed by the
mesh loader, in local and global mode. Reports the median of --repeats runs of:
  limit     Embree's rtcIntersect16 on coherent 4×4 packets of the frame's rays, prepared beforehand in the
            render's bands (intersect.packed_rays), on the same thread pool, no shading: what Embree's own
            code needs for these rays on this CPU, so frame / limit means the same on any machine
  frame     the render's tiles (run_tiles, as render() times it: rays + cast + [shadow rays] + shading + film)
  raw cast  the same rays through embreex's one-ray API (EmbreeScene.run): the yardstick of issues 2, 3, 12
and, since wall-clock ratios move by ±20 % on a machine other jobs share, the same ratio in CPU time on one
thread (time.thread_time, min of --repeats, every band run in turn on this thread), with the frame's stages
(the kernel's own clock) and ray generation alone (camera.fill_rows), each against the limit. The first line
names the CPU (model, AVX2/AVX-512) and the ISA Embree picked (its verbose device report).
Usage: python benchmarks/bench_frame.py [--size 1000] [--repeats 5] [--threads 2] [--mode global] [--set KEY=VALUE ...]
       python benchmarks/bench_frame.py --scan bunny-1m bunny-4m [--no-embreex]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import raycast_phong as rp
from raycast_phong.renderer.embree_library import device_report, library, picked_target
from raycast_phong.renderer.film import allocate_film
from raycast_phong.renderer.intersect import packed_rays
from raycast_phong.renderer.kernels.camera import fill_rows
from raycast_phong.renderer.kernels.shadows import shadow_rays
from raycast_phong.renderer.pack import camera_rig, generate_rays
from raycast_phong.renderer.prepare import TileWork, prepare, run_tiles
from raycast_phong.scene.overrides import apply_override


def benchmark_scene(size: int, subdivisions: int = 6, mode: str = "local",
                    overrides: tuple[str, ...] = ()) -> rp.Scene:
    """The icosphere scene; `overrides`: --set assignments (e.g. render.shading=gouraud), applied before validation."""
    data = {
        "render": {"width": size, "height": size, "shading": "phong", "specular": "phong", "mode": mode},
        "camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "fov": 40},
        "lights": [{"type": "point", "position": [2, 2, 3]}],
        "materials": {"m": {"ka": 1, "kd": 0.7, "ks": 0.5, "shininess": 32}},
        "objects": [{"shape": "icosphere", "subdivisions": subdivisions, "radius": 1.0, "material": "m"}],
    }
    for assignment in overrides:
        apply_override(data, assignment)
    return rp.validate_scene(data, source="benchmark")


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


def raw_cast_seconds(limit: Limit, embreex: Embreex, threads: int) -> float:
    """Cast the frame's rays, generated beforehand in the render's bands, through embreex on `threads` threads."""
    with ThreadPoolExecutor(threads) as pool:
        start = time.perf_counter()
        list(pool.map(lambda tile: embreex.cast_only(*tile), limit.tiles))
        return time.perf_counter() - start


def raw_shadow_cast_seconds(limit: Limit, embreex: Embreex, threads: int) -> float:
    """Occlusion queries of the render's shadow rays, built beforehand per band, through embreex, on
    `threads` threads."""
    inputs = limit.ready.shadows
    batches = []
    for origins, directions in limit.tiles:
        hits = limit.accelerator.closest_hits(origins, directions)
        hit_rays = np.flatnonzero(hits.face >= 0)
        count = len(hit_rays) * len(inputs.light_kind)
        batch = (np.empty((count, 3), np.float32), np.empty((count, 3), np.float32), np.empty(count, np.float32))
        shadow_rays(inputs, hit_rays, hits.face, hits.u, hits.v, directions, *batch)
        batches.append(batch)
    with ThreadPoolExecutor(threads) as pool:
        start = time.perf_counter()
        list(pool.map(lambda batch: embreex.occluded(batch[0], batch[1], batch[2].copy()), batches))
        return time.perf_counter() - start


def cpu() -> str:
    """The CPU's model and vector flags (/proc/cpuinfo) and the ISA Embree picked (its verbose report)."""
    model, flags = "unknown CPU", set()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "model name" and model == "unknown CPU":
                model = value.strip()
            elif key.strip() == "flags":
                flags = set(value.split())
    except OSError:
        pass
    vector = "/".join(flag for flag in ("avx2", "avx512f") if flag in flags) or "no avx2"
    picked = picked_target(device_report(library())) or "unknown"
    return f"{model} ({vector}, {os.cpu_count()} CPUs), Embree {picked}"


@dataclass
class Limit:
    """One prepared scene with its BVH and the frame's rays as Embree packets, band by band."""
    ready: object
    accelerator: object
    tiles: list    # (origins, directions) of each band
    packets: list  # (packets, valid) of each band

    @classmethod
    def of(cls, scene: rp.Scene) -> Limit:
        ready = prepare(scene)
        accelerator = ready.build()
        width, height, samples = scene.render.width, scene.render.height, scene.render.samples
        rig = camera_rig(scene)
        tiles = [generate_rays(rig, ready.frame, width, height, samples, *band) for band in ready.bands]
        packets = [packed_rays(*tile, width * samples * samples) for tile in tiles]
        return cls(ready, accelerator, tiles, packets)

    def work(self) -> TileWork:
        scene = self.ready.scene
        return TileWork(self.ready.rays, self.accelerator, self.ready.shadows, self.ready.shading,
                        allocate_film(scene.render.width, scene.render.height, (), self.ready.real))

    def cast(self, band: int) -> None:
        self.accelerator.cast_packets(*self.packets[band])

    def generate(self) -> None:
        """The frame's rays alone (camera.fill_rows into reused arrays), band by band."""
        params = self.ready.rays.params
        for row0, row1 in self.ready.bands:
            count = (row1 - row0) * params.width * params.samples ** 2
            fill_rows(params, row0, row1, self._origins[:count], self._directions[:count])

    def __post_init__(self):
        params = self.ready.rays.params
        most = max(b - a for a, b in self.ready.bands) * params.width * params.samples ** 2
        self._directions = np.empty((most, 3), np.float32)
        self._origins = np.empty((most, 3), np.float32)


def one_thread(limit: Limit, repeats: int) -> dict[str, float]:
    """CPU time on this one thread (min of `repeats`): Embree's limit (every band's packets), the frame (every
    band through render's TileWork, a fresh film each time) and its stages (the kernel's own clock), and ray
    generation alone."""
    bands = range(len(limit.packets))
    best = {"limit": np.inf, "frame": np.inf, "generation": np.inf}
    stages = {}
    for _ in range(repeats):
        start = time.thread_time()
        for band in bands:
            limit.cast(band)
        best["limit"] = min(best["limit"], time.thread_time() - start)
        work, split = limit.work(), np.zeros(3)
        start = time.thread_time()
        for band in limit.ready.bands:
            split += work(band)[:3]
        frame = time.thread_time() - start
        if frame < best["frame"]:
            best["frame"] = frame
            stages = {"rays": split[0], "shadows": split[1], "shade": split[2]}
        start = time.thread_time()
        limit.generate()
        best["generation"] = min(best["generation"], time.thread_time() - start)
    return best | stages


def threads_wall(limit: Limit, threads: int) -> tuple[float, float]:
    """Wall time on `threads` threads of Embree's limit (the bands' packets) and of the frame (run_tiles, as
    render() times it)."""
    with ThreadPoolExecutor(threads) as pool:
        start = time.perf_counter()
        list(pool.map(limit.cast, range(len(limit.packets))))
        cast = time.perf_counter() - start
    timings = {}
    run_tiles(limit.work(), list(limit.ready.bands), threads, None, timings)
    return cast, timings["frame"]


def report(scene: rp.Scene, repeats: int, threads: int, embreex: bool) -> None:
    """The frame against Embree's limit (and embreex's one-ray cast) in one run, wall and CPU time."""
    limit = Limit.of(scene)
    work = limit.work()
    for band in limit.ready.bands[:2]:  # load the kernels
        work(band)
    limit.cast(0)
    walls = [threads_wall(limit, threads) for _ in range(repeats)]
    peer = Embreex(limit.ready.geometry, limit.ready.frame) if embreex else None
    casts = [raw_cast_seconds(limit, peer, threads) for _ in range(repeats)] if peer else []
    shadow_casts = ([raw_shadow_cast_seconds(limit, peer, threads) for _ in range(repeats)]
                    if peer and limit.ready.shadows is not None else [])
    cast, frame = statistics.median(w[0] for w in walls), statistics.median(w[1] for w in walls)
    r = scene.render
    rays = r.width * r.height * r.samples ** 2
    print(f"{r.width}×{r.height}, {len(limit.ready.geometry.faces):,} triangles, {r.mode.value} mode, "
          f"{threads} threads, "
          f"median of {repeats}; CPU: {cpu()}")
    print(f"limit      {cast * 1e3:7.1f} ms  {rays / cast / 1e6:5.1f} Mrays/s  (Embree's rtcIntersect16 on 4×4 "
          "packets of the same rays, prepared beforehand)")
    print(f"frame      {frame * 1e3:7.1f} ms  {rays / frame / 1e6:5.1f} Mrays/s  (rays + cast + "
          f"{'shadow rays + ' if r.mode == 'global' else ''}shading + film)")
    print(f"ratio      {frame / cast:7.2f}    (frame / limit, wall; target ≤ 1.5, issue 31)")
    if casts:
        raw = statistics.median(casts)
        print(f"raw cast   {raw * 1e3:7.1f} ms  {rays / raw / 1e6:5.1f} Mrays/s  (embreex's one-ray API); "
              f"frame / raw cast {frame / raw:.2f}")
    if shadow_casts:
        shadow = statistics.median(shadow_casts)
        print(f"shadow     {shadow * 1e3:7.1f} ms  (embreex's occlusion queries of the shadow rays alone)")
    one = one_thread(limit, repeats)
    print(f"CPU        {one['frame'] / one['limit']:7.2f}    (frame {one['frame'] * 1e3:.1f} ms / limit "
          f"{one['limit'] * 1e3:.1f} ms, CPU time on one thread, min of {repeats})")
    print(f"stages     generation {one['generation'] * 1e3:.1f} ms (fill_rows alone), rays {one['rays'] * 1e3:.1f} ms "
          f"(generation + cast in the frame: {one['rays'] / one['limit']:.2f} × limit), "
          + (f"shadow rays {one['shadows'] * 1e3:.1f} ms, " if r.mode == "global" else "")
          + f"shading {one['shade'] * 1e3:.1f} ms ({one['shade'] / one['limit']:.2f} × limit); the rest "
          f"{(one['frame'] - one['rays'] - one['shadows'] - one['shade']) * 1e3:.1f} ms")


def scan_scene(name: str, size: int, mode: str) -> rp.Scene:
    """A cached real scan (benchmarks/make_scans.py) framed by the mesh loader, at size × size."""
    path = Path(os.environ.get("RAYCAST_PHONG_SCANS") or Path.home() / ".cache" / "raycast-phong" / "scans")
    return rp.load_scene(path / f"{name}.ply", [f"render.width={size}", f"render.height={size}",
                                                 f"render.mode={mode}", "render.shading=phong"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--mode", choices=["local", "global"], default="local",
                        help="global: also shadow rays to the light; reports their raw cast too")
    parser.add_argument("--scan", nargs="*", metavar="NAME",
                        help="render cached real scans instead (e.g. bunny-1m bunny-4m: make_scans.py), in local "
                             "and global mode (or --mode only if given)")
    parser.add_argument("--no-embreex", action="store_true", help="skip embreex's one-ray cast")
    parser.add_argument("--set", nargs="*", default=[], metavar="KEY=VALUE",
                        help="change the icosphere scene as the CLI's --set does, e.g. render.shading=gouraud "
                             "render.specular=blinn lights.0.type=directional lights.0.direction=[-1,-1,-1]")
    args = parser.parse_args()
    rp.render(benchmark_scene(64, mode="global"), threads=args.threads)  # compile or load the kernels first
    if args.scan is None:
        report(benchmark_scene(args.size, mode=args.mode, overrides=tuple(args.set)), args.repeats, args.threads,
               not args.no_embreex)
        return
    modes = ("local", "global") if "--mode" not in sys.argv else (args.mode,)
    for name in args.scan or ["bunny-1m", "bunny-4m"]:
        for mode in modes:
            report(scan_scene(name, args.size, mode), args.repeats, args.threads, not args.no_embreex)
            print()


if __name__ == "__main__":
    main()
