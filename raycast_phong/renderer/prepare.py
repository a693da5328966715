"""The one place the stages are sequenced: Renderer.prepare() = plan → memory check → geometry → diagnosis →
packing; Prepared.render() = BVH → tiles (rays → hits → [shadow rays] → shading, in one kernel per band) → film.

A Renderer is a session: what stays the same from one render to the next (threads, the memory budget, the
pool the bands run on, and for the frames of one changing scene a FrameCache), given once, as an httpx
Client or Open3D's RaycastingScene is. render(), render_file(), warm_kernels, the `plan` command,
accuracy.mesh_coverage, the study, batches and the live view all go through Renderer.prepare(), so they
agree on the plan, on whether a scene fits its memory budget (one check, with the same arguments for all)
and on what the kernels get. Tiles are bands of rows, about TILE_RAYS rays each, shaded on a thread pool:
Embree and the kernels release the GIL, so both cores work and memory stays flat whatever the image size.
Every band writes only its own rows: the image is bit-identical for any number of threads.

A FrameCache (a live view's page keeps one in its Renderer) carries the geometry and its committed BVH from
one frame to the next, so that a frame rebuilds only what its change touched; `cancelled` stops a frame
between bands.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from concurrent.futures import Executor, ThreadPoolExecutor, wait
from dataclasses import dataclass, field

import numpy as np

from ..codes import StageName
from ..errors import RenderCancelled
from ..geometry.build import build_geometry
from ..geometry.memo import FRESH
from ..geometry.normals import PARALLEL_FACES, prep_threads
from ..records import Frame, Geometry, ImageBuffers, RenderPlan, RenderResult
from ..scene.schema import Scene
from .budget import MemoryEstimate
from .by_address import cutter, shader, shadow_caster
from .diagnosis import ObjectFigures, diagnose
from .film import allocate_film, film_layers
from .fit import fitted
from .intersect import Accelerator, frame_of_box, unit_frame
from .kernels.layout import COUNTS, ShadingInputs, ShadowInputs
from .kernels.tile import render_band
from .pack import RayGenerator, camera_rig, film_rows, no_shadows, plan_flags, prepare_shading, prepare_shadows
from .reuse import FrameCache

# A mesh of at least this many faces, rendered on 2 threads or more, has its BVH built on a thread of its own from the
# moment its vertices and faces are final (BuildAhead), while its normals, diagnosis and packing go on: neither keeps
# both cores busy alone (bunny-1m, 1.1M triangles: Embree's Morton build 0.095 s of CPU in 0.05 s of wall with two free
# cores; the normals' passes wait on their slowest thread), together they do. Below it (every built-in scene) the BVH
# is built in render(), after the preparation.
BUILD_AHEAD_FACES = PARALLEL_FACES
NO_SHADOWS = no_shadows()  # local mode's shadow inputs for the tile kernel (read only in global mode)


@dataclass(frozen=True, eq=False)
class Prepared:
    """Everything a render of one scene needs before its BVH and tiles: the plan, the memory estimate that
    let it through, the geometry, the unit frame and the kernels' packed inputs. `.render()` runs the rest."""
    scene: Scene
    plan: RenderPlan                 # diagnosed: with the geometry's warnings and notes
    memory: MemoryEstimate
    geometry: Geometry
    frame: Frame                     # Embree's unit frame
    rays: RayGenerator
    shading: ShadingInputs
    shadows: ShadowInputs | None     # None in local mode
    bands: tuple[tuple[int, int], ...]  # the tiles: image rows [row0, row1)
    threads: int                     # the session's, or the machine's cores
    session: Renderer                # its cache gives the BVH (and keeps it); its pool runs the bands
    progress: Callable[[int, int], None] | None = None
    timings: dict[str, float] = field(default_factory=dict)  # geometry so far; render() adds the rest
    cancelled: Callable[[], bool] | None = None  # asked before each band; True: stop (RenderCancelled)
    ahead: BuildAhead | None = None  # the BVH, building since the geometry's positions were final

    @property
    def real(self) -> type:
        """The shading precision."""
        return self.plan.real

    def build(self) -> Accelerator:
        """The BVH (starts Embree; committed before any thread uses it): the one built ahead (waited for), or the
        cache's if it is this one."""
        if self.ahead is not None and self.ahead.started:
            built = self.ahead.take()
            if built is not None:
                return built
        if self.session.cache is not None:
            return self.session.cache.accelerator(self.geometry, self.frame)
        return Accelerator(self.geometry, self.frame)

    def render(self) -> RenderResult:
        """BVH, then every band on the thread pool into a fresh film.

        Returns a RenderResult with .image (H, W, 3) in the shading precision, .aovs, .timings (seconds:
        geometry, build, rays, shadows (global mode), shade, frame; rays, shadows and shade are summed over
        the worker threads, frame is wall time; build is the wait for a BVH built ahead, whose work overlapped the
        geometry's) and .counts (terms evaluated, shadow rays cast).
        RenderCancelled if `cancelled()` turned True before the last band started.
        """
        timings = dict(self.timings)
        start = time.perf_counter()
        accelerator = self.build()
        timings["build"] = time.perf_counter() - start
        render = self.scene.render
        aovs = tuple(self.scene.output.aovs)
        tile = TileWork(self.rays, accelerator, self.shadows, self.shading,
                        allocate_film(render.width, render.height, aovs, self.real))
        counts = run_tiles(tile, list(self.bands), self.threads, self.progress, timings, self.cancelled,
                           self.session.pool)
        return RenderResult(image=tile.film.rgb, aovs=film_layers(tile.film, aovs), timings=timings, plan=self.plan,
                            triangles=self.geometry.triangles, rays=render.width * render.height * render.samples ** 2,
                            counts=dict(zip(COUNTS, counts.tolist())))


@dataclass(frozen=True, eq=False)
class Renderer:
    """A renderer session: what stays the same from one render to the next, given once.

    threads: worker threads for the bands (default: the machine's cores, at most 8). max_memory: the budget,
    bytes or a size such as "8G" (default: 3/4 of the memory available at each render); a scene whose estimate
    (budget.estimate_memory) exceeds it is refused with a SceneError before anything is built. pool: an
    executor the caller owns and keeps, to run the bands on (a live view's band threads: a new pool waited 1-2
    ms for its threads to start, on a default draft of ~6 ms); default: `threads` threads made and shut down
    by each render. cache: a FrameCache for the frames of one changing scene (a live view's page): each reuses
    the geometry and BVH of the one before where its change left them, and keeps its own for the next.
    """
    threads: int | None = None
    max_memory: int | str | None = None
    pool: Executor | None = None
    cache: FrameCache | None = None

    def render(self, scene: Scene, plan: RenderPlan | None = None, *,
               progress: Callable[[int, int], None] | None = None,
               cancelled: Callable[[], bool] | None = None) -> RenderResult:
        """prepare(...).render(), the BVH of a large mesh built ahead (BuildAhead)."""
        return self.prepare(scene, plan, progress=progress, cancelled=cancelled, build_ahead=True).render()

    def prepare(self, scene: Scene, plan: RenderPlan | None = None, *,
                progress: Callable[[int, int], None] | None = None,
                cancelled: Callable[[], bool] | None = None, build_ahead: bool = False) -> Prepared:
        """Plan the render, check it fits the memory budget, build the geometry and pack the kernels' inputs.

        plan: the render plan; default build_plan(scene) (build_plan(scene, optimize=False) keeps every stage).
        progress: called as progress(tiles_done, tiles_total) by render(). cancelled: asked before each band by
        render(); when it answers True, the bands not yet started are skipped and render() raises
        RenderCancelled. build_ahead: a mesh of BUILD_AHEAD_FACES or more has its BVH built on a thread of its
        own while the normals are made, on 2 threads or more and without a cache (render() asks for it; a
        prepare() that is not rendered starts no Embree).
        """
        plan, bands, threads, tile_rays, sources, memory = fitted(scene, plan, self.threads, self.max_memory)
        width, height, samples = scene.render.width, scene.render.height, scene.render.samples
        start = time.perf_counter()
        real, cache = plan.real, self.cache
        ahead = BuildAhead() if build_ahead and cache is None and threads > 1 else None
        with prep_threads(threads):  # a large mesh's preparation uses as many threads as its tiles
            with cache.lock if cache is not None else contextlib.nullcontext():
                geometry = build_geometry(scene, vertex_normals=plan.keeps(StageName.VERTEX_NORMALS),
                                          normal_dtype=real, sources=sources, positions=ahead,
                                          memo=cache.memo if cache is not None else FRESH)
        timings = {"geometry": time.perf_counter() - start}
        derived = cache.derived(geometry) if cache is not None else None
        start = time.perf_counter()
        plan = diagnose(plan, scene, geometry, ObjectFigures(geometry, len(scene.objects), derived))
        timings["diagnosis"] = time.perf_counter() - start  # the plan's Gouraud and highlight checks: ms at 10^5 faces
        if ahead is not None and ahead.started:
            frame = ahead.frame  # unit_frame of the same vertices
        elif derived is None:
            frame = frame_of_box(*geometry.box)  # the box the geometry's checks measured
        else:
            frame = derived.get("frame", ("vertices",), lambda: frame_of_box(*geometry.box))
        rig = camera_rig(scene)
        return Prepared(
            scene=scene, plan=plan, memory=memory, geometry=geometry, frame=frame,
            rays=RayGenerator(rig, frame, width, height, samples, max_rays=tile_rays),
            shading=prepare_shading(scene, geometry, rig, frame, plan_flags(plan, scene), real, kept=derived),
            shadows=prepare_shadows(scene, geometry, frame) if plan.keeps(StageName.SHADOW_RAYS) else None,
            bands=bands, threads=threads, session=self, progress=progress, timings=timings, cancelled=cancelled,
            ahead=ahead)

    def check_fits(self, scene: Scene) -> MemoryEstimate:
        """prepare()'s plan and memory check alone, building nothing: a SceneError if the scene is over the
        budget (the study checks every level before it measures; `render` calls fit.fitted itself, before this
        module loads)."""
        return fitted(scene, None, self.threads, self.max_memory).memory


def prepare(scene: Scene, plan: RenderPlan | None = None) -> Prepared:
    """A default session's prepare() (the plan command's, the warm-up's): Renderer().prepare(scene, plan)."""
    return Renderer().prepare(scene, plan)


class BuildAhead:
    """The BVH of a large mesh built on a thread of its own (build_geometry's `positions`: called with the Geometry's
    final vertices and faces) while the preparation goes on; take() waits for it. A mesh below BUILD_AHEAD_FACES
    starts nothing (`started` stays False). An error of the build (EmbreeError) is raised by take()."""

    def __init__(self):
        self.frame: Frame | None = None  # unit_frame of the vertices, once started
        self._thread: threading.Thread | None = None
        self._built: Accelerator | Exception | None = None

    @property
    def started(self) -> bool:
        return self._thread is not None

    def __call__(self, vertices: np.ndarray, faces: np.ndarray) -> None:
        if len(faces) < BUILD_AHEAD_FACES or self.started:
            return
        self.frame = unit_frame(vertices)
        self._thread = threading.Thread(target=self._build, args=(vertices, faces, self.frame), name="bvh-ahead")
        self._thread.start()

    def _build(self, vertices: np.ndarray, faces: np.ndarray, frame: Frame) -> None:
        try:
            self._built = Accelerator.of_mesh(vertices, faces, frame)
        except Exception as error:  # noqa: BLE001 — raised again by take(), on the thread that renders
            self._built = error

    def take(self) -> Accelerator | None:
        """The BVH, once built (waits); given once (None after: the caller keeps it only as long as it renders)."""
        self._thread.join()
        built, self._built = self._built, None
        if isinstance(built, Exception):
            raise built
        return built


@dataclass(frozen=True, eq=False)
class TileWork:
    """What every tile of one frame needs: its rays, the BVH, the shadow and shading inputs, the film."""
    rays: RayGenerator
    accelerator: Accelerator
    shadows: ShadowInputs | None   # None in local mode
    shading: ShadingInputs
    film: ImageBuffers
    shade: object = field(init=False)  # shading._shade_rays for these inputs, by address (by_address.py)
    cast: object = field(init=False)   # shadows.cast_shadows in global mode, else no_shadow_rays, by address
    cut: object = field(init=False)    # ray_queries.cut_masked with alpha masks, else no_cut, by address

    def __post_init__(self) -> None:
        object.__setattr__(self, "shade", shader(self.shading))
        object.__setattr__(self, "cast", shadow_caster(self.shadows is not None))
        object.__setattr__(self, "cut", cutter(self.rays.params, self.shading))

    def __call__(self, band: tuple[int, int]) -> tuple[float, float, float, np.ndarray]:
        """Rays, closest hits, [shadow rays,] shading of rows [row0, row1) into the film, in one kernel
        (tile.render_band); seconds of each part and the kernel's counts."""
        row0, row1 = band
        film, seconds = film_rows(self.film.rows(row0, row1)), np.zeros(3)
        render_band(self.accelerator.embree_scene.scene, row0, row1, self.rays.params, self.rays.shared_origins,
                    self.shadows or NO_SHADOWS, self.shading, film, seconds, self.shade, self.cast, self.cut)
        return seconds[0], seconds[1], seconds[2], film.counts


def run_tiles(tile: TileWork, bands: list[tuple[int, int]], threads: int,
              progress: Callable[[int, int], None] | None, timings: dict[str, float],
              cancelled: Callable[[], bool] | None = None, pool: Executor | None = None) -> np.ndarray:
    """Run `tile` over the bands on `pool` (default: a pool of `threads` made for this frame; the kernels and
    Embree release the GIL); add frame (wall), rays, shade and, in global mode, shadows (summed over threads) to
    `timings`. `cancelled()` is asked as each band starts: once it is True, the bands not started are skipped,
    and RenderCancelled (with the bands done) is raised after the running ones end. On any exception (an
    interrupt included) the bands not started are dropped and the running ones waited for, so no band outlives
    the frame's film and BVH."""
    if pool is None:
        with ThreadPoolExecutor(max_workers=threads) as own:
            return run_tiles(tile, bands, threads, progress, timings, cancelled, own)
    counts = np.zeros(len(COUNTS), np.int64)
    seconds = np.zeros(3)  # rays, shadows, shade
    start = time.perf_counter()
    progress = progress or (lambda done, total: None)
    progress(0, len(bands))

    def band_unless_cancelled(band: tuple[int, int]):
        return None if cancelled is not None and cancelled() else tile(band)

    done = 0
    futures = [pool.submit(band_unless_cancelled, band) for band in bands]
    try:
        for future in futures:
            result = future.result()
            if result is None:
                continue
            ray_s, shadow_s, shade_s, tile_counts = result
            done += 1
            seconds += (ray_s, shadow_s, shade_s)
            counts += tile_counts
            progress(done, len(bands))
    except BaseException:
        for future in futures:
            future.cancel()
        wait(futures)
        raise
    if done < len(bands):
        raise RenderCancelled(done, len(bands))
    timings["frame"] = time.perf_counter() - start
    timings["rays"], timings["shade"] = float(seconds[0]), float(seconds[2])
    if tile.shadows is not None:
        timings["shadows"] = float(seconds[1])
    return counts
