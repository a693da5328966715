"""Compose the stages for one scene: plan → geometry → BVH → tiles (rays → hits → [shadow rays] → shading).

Tiles are bands of rows, each about TILE_RAYS rays, shaded on a thread pool: Embree and the numba
kernels release the GIL, so both cores work and memory stays flat whatever the image size. Every
tile writes only its own rows, so the image is bit-identical for any number of threads.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..geometry.build import build_geometry
from ..records import ImageBuffers, RenderPlan, RenderResult
from ..scene.load import load_scene
from ..scene.schema import Scene, SceneError
from .budget import check_memory
from .film import allocate_film, film_layers
from .intersect import Accelerator, unit_frame
from .kernels import embree
from .kernels.layout import COUNTS, MAX_LIGHTS, ShadingInputs, ShadowInputs
from .kernels.tile import render_band
from .pack import RayGenerator, camera_rig, film_rows, no_shadows, plan_flags, prepare_shading, prepare_shadows
from .plan import build_plan, diagnose

TILE_RAYS = 1 << 15  # 32k rays: large enough to amortise a call, small enough for ~10 MB per tile
NO_SHADOWS = no_shadows()  # local mode's shadow inputs for the tile kernel (read only in global mode)


def default_threads() -> int:
    return max(1, min(os.cpu_count() or 1, 8))


def render(scene: Scene, *, threads: int | None = None, plan: RenderPlan | None = None,
           progress: Callable[[int, int], None] | None = None, source: str = "<scene>",
           max_memory: int | str | None = None) -> RenderResult:
    """Render a validated scene.

    Parameters
    ----------
    threads: worker threads for the tiles (default: the machine's cores, at most 8).
    plan: the render plan; default build_plan(scene). build_plan(scene, optimize=False) keeps every stage.
    progress: called as progress(tiles_done, tiles_total) after each tile.
    (accuracy.measured adds RMSE, max, PSNR, … against the analytic or a self-convergence reference.)
    max_memory: the memory budget, bytes or a size such as "8G" (default: 3/4 of the memory available now);
        a scene whose estimate (memory.estimate_memory) exceeds it is refused with a SceneError before
        anything is built.

    Returns
    -------
    RenderResult with .image (H, W, 3) in the shading precision (float32, or float64), .aovs, .timings
    (seconds: geometry, build, rays, shadows (global mode), shade, frame; rays, shadows and shade are
    summed over the worker threads, frame is wall time).
    """
    timings: dict[str, float] = {}
    plan = plan or build_plan(scene)
    if plan.keeps("shadow_rays") and len(scene.lights) > MAX_LIGHTS:
        raise SceneError(f"{source}: lights: global mode handles at most {MAX_LIGHTS} lights, "
                         f"the scene has {len(scene.lights)}; use render.mode = \"local\" or fewer lights")
    width, height, samples = scene.render.width, scene.render.height, scene.render.samples
    rows_per_tile = max(1, TILE_RAYS // (width * samples * samples))
    threads = threads or default_threads()
    check_memory(scene, source, max_memory, smooth=plan.keeps("vertex_normals"),
                 float64=plan.keeps("float64_shading"),
                 shadow_lights=len(scene.lights) if plan.keeps("shadow_rays") else 0,
                 tile_rays=rows_per_tile * width * samples * samples, threads=min(threads, -(-height // rows_per_tile)))

    start = time.perf_counter()
    real = np.float64 if plan.keeps("float64_shading") else np.float32
    geometry = build_geometry(scene, source=source, vertex_normals=plan.keeps("vertex_normals"), normal_dtype=real)
    timings["geometry"] = time.perf_counter() - start
    plan = diagnose(plan, scene, geometry)
    start = time.perf_counter()
    frame = unit_frame(geometry.vertices)
    accelerator = Accelerator(geometry, frame)
    timings["build"] = time.perf_counter() - start

    rig = camera_rig(scene)
    tile = TileWork(
        rays=RayGenerator(rig, frame, width, height, samples, max_rays=rows_per_tile * width * samples * samples),
        accelerator=accelerator,
        shadows=prepare_shadows(scene, geometry, frame) if plan.keeps("shadow_rays") else None,
        shading=prepare_shading(scene, geometry, rig, frame, plan_flags(plan, scene), real),
        film=allocate_film(width, height, tuple(scene.output.aovs), real))
    bands = [(row, min(row + rows_per_tile, height)) for row in range(0, height, rows_per_tile)]
    counts = run_tiles(tile, bands, threads, progress, timings)
    return RenderResult(image=tile.film.rgb, aovs=film_layers(tile.film, tuple(scene.output.aovs)), timings=timings,
                        plan=plan, triangles=geometry.triangles, rays=width * height * samples * samples,
                        counts=dict(zip(COUNTS, counts.tolist())))


@dataclass(frozen=True, eq=False)
class TileWork:
    """What every tile of one frame needs: its rays, the BVH, the shadow and shading inputs, the film."""
    rays: RayGenerator
    accelerator: Accelerator
    shadows: ShadowInputs | None   # None in local mode
    shading: ShadingInputs
    film: ImageBuffers

    def __call__(self, band: tuple[int, int]) -> tuple[float, float, float, np.ndarray]:
        """Rays, closest hits, [shadow rays,] shading of rows [row0, row1) into the film, in one kernel
        (tile.render_band); seconds of each part and the kernel's counts."""
        row0, row1 = band
        film, seconds = film_rows(self.film.rows(row0, row1)), np.zeros(3)
        render_band(self.accelerator.embree_scene.scene, row0, row1, self.rays.params, self.rays.shared_origins,
                    self.shadows or NO_SHADOWS, self.shading, film, seconds)
        return seconds[0], seconds[1], seconds[2], film.counts


def run_tiles(tile: TileWork, bands: list[tuple[int, int]], threads: int,
              progress: Callable[[int, int], None] | None, timings: dict[str, float]) -> np.ndarray:
    """Run `tile` over the bands on a pool of `threads` (the kernels and Embree release the GIL); add
    frame (wall), rays, shade and, in global mode, shadows (summed over threads) to `timings`."""
    counts = np.zeros(len(COUNTS), np.int64)
    seconds = np.zeros(3)  # rays, shadows, shade
    start = time.perf_counter()
    if progress:
        progress(0, len(bands))
    with ThreadPoolExecutor(max_workers=threads) as pool:
        for done, (ray_s, shadow_s, shade_s, tile_counts) in enumerate(pool.map(tile, bands), start=1):
            seconds += (ray_s, shadow_s, shade_s)
            counts += tile_counts
            if progress:
                progress(done, len(bands))
    timings["frame"] = time.perf_counter() - start
    timings["rays"], timings["shade"] = float(seconds[0]), float(seconds[2])
    if tile.shadows is not None:
        timings["shadows"] = float(seconds[1])
    return counts


def tile_kernel() -> str:
    """The kernel a render runs its tiles in (for jit.compiled_before)."""
    return "render_band"


def warm_kernels(reals: tuple[type, ...] = (np.float32, np.float64), shadows: bool = True) -> None:
    """Load (or compile) the tile kernel (tile.render_band, which holds global mode's shadow rays too, so
    `shadows` changes nothing) in the `reals` precisions, without starting Embree: called on no rows, it
    reaches Embree only per chunk of rows.

    A process that forks workers afterwards hands them ready kernels (batch.py): each would otherwise
    spend ~0.15 s loading them from numba's cache, most of it numba's one-time set-up on a process's
    first dispatch. The kernel is typed by its arguments, so it is called through the real wrappers.
    """
    from ..scene.schema import validate_scene
    del shadows
    embree.library()  # binds the names the kernel links against (EmbreeError if it cannot be loaded)
    scene = validate_scene({"render": {"width": 2, "height": 2, "mode": "global"},
                            "lights": [{"type": "point", "position": [2, 2, 3]}],
                            "objects": [{"shape": "icosphere", "subdivisions": 0}]}, source="warm-up")
    plan = build_plan(scene)
    geometry = build_geometry(scene)
    frame, rig = unit_frame(geometry.vertices), camera_rig(scene)
    rays = RayGenerator(rig, frame, 2, 2, 1, 4)
    for real in reals:
        inputs = prepare_shading(scene, geometry, rig, frame, plan_flags(plan, scene), real)
        film = allocate_film(2, 2, (), real)
        render_band(0, 0, 0, rays.params, rays.shared_origins, NO_SHADOWS, inputs, film_rows(film.rows(0, 0)),
                    np.zeros(3))


def warm_kernels_for(plans: list[RenderPlan]) -> None:
    """warm_kernels with only what these plans need: their shading precisions, and the shadow-ray kernel
    if some plan casts shadow rays."""
    if plans:
        warm_kernels(tuple({np.float64 if plan.keeps("float64_shading") else np.float32 for plan in plans}),
                     shadows=any(plan.keeps("shadow_rays") for plan in plans))


def render_file(path: str | Path, overrides: list[str] | tuple[str, ...] = (), *, view: str | None = None,
                up: str | None = None, **options) -> RenderResult:
    """Load a scene file or a mesh file (with `key.path=value` overrides; `view` and `up` frame a mesh file,
    docs/meshes.md) and render it; timings include "load". `options` are render()'s."""
    start = time.perf_counter()
    scene = load_scene(path, overrides, view=view, up=up)
    loaded = time.perf_counter() - start
    result = render(scene, source=str(path), **options)
    result.timings["load"] = loaded
    return result
