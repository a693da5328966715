"""The package's render functions: render(), render_file() and the kernels' warm-up, each through
prepare.prepare(), the one place the stages are sequenced (prepare.py).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .. import jit
from ..codes import StageName
from ..io.system import default_threads
from ..records import RenderPlan, RenderResult
from ..scene.load import load_scene
from ..scene.schema import Scene
from . import embree_library
from .by_address import cutter, shader, shadow_caster
from .film import allocate_film
from .fit import TILE_RAYS
from .kernels.tile import render_band
from .pack import film_rows
from .prepare import NO_SHADOWS, FrameCache, Renderer, prepare

__all__ = ["TILE_RAYS", "FrameCache", "Renderer", "default_threads", "render", "render_file", "warm_kernels",
           "warm_kernels_for"]


def render(scene: Scene, *, threads: int | None = None, plan: RenderPlan | None = None,
           progress: Callable[[int, int], None] | None = None, max_memory: int | str | None = None,
           cancelled: Callable[[], bool] | None = None) -> RenderResult:
    """Render a validated scene: Renderer(threads=threads, max_memory=max_memory).render(scene, plan, ...), a
    one-off session's render (an application rendering frame after frame keeps a Renderer). (accuracy.measured
    adds RMSE, max, PSNR, … against the analytic or a self-convergence reference.)

    Parameters
    ----------
    scene: a validated Scene (rp.load_scene, rp.validate_scene, Scene.replace, rp.mesh_scene).
    threads: worker threads for the bands (default: the machine's cores). plan: a RenderPlan (rp.build_plan's,
        default: made here). progress: progress(done, total), called as bands finish. max_memory: the memory
        budget in bytes or a size such as "8G" (default: 3/4 of the memory available). cancelled: asked before
        each band; True stops the frame with RenderCancelled.

    Returns
    -------
    RenderResult: .image (H, W, 3) linear display values, unclamped, float32 (float64 when the plan shades in
    float64); .aovs, .timings (seconds per stage), .plan, .colour, .triangles.

    Raises
    ------
    SceneError (one line) when the scene needs more memory than the budget, before anything is built, or when
    a mesh file it names cannot be read; ValueError for a budget of 0 or less.
    """
    return Renderer(threads=threads, max_memory=max_memory).render(scene, plan, progress=progress,
                                                                   cancelled=cancelled)


def warm_kernels(reals: tuple[type, ...] = (np.float32, np.float64), shadows: bool = True,
                 scene_kernels: Callable[[], None] | None = None, winding: bool = False) -> None:
    """Load (or compile) the tile kernel (tile.render_band) and the kernels it calls by address (by_address.py:
    the shading kernel, and global mode's shadow rays when `shadows`) in the `reals` precisions, without starting
    Embree: called on no rows, it reaches Embree only per chunk of rows. `scene_kernels` (a scene's own
    preparation kernels: a mesh file's merge, an OBJ's reader, the crease split) and, with `winding`, the mesh
    winding's kernels are made ready with the first precision: on a first compile the shading kernel, then the
    winding's, compile in a helper process meanwhile (split_compile.py).

    A process that forks workers afterwards hands them ready kernels (batch.py): each would otherwise
    spend ~0.15 s loading them from numba's cache, most of it numba's one-time set-up on a process's
    first dispatch. The kernel is typed by its arguments, so it is called on a prepared 2×2 scene.
    """
    from .split_compile import shading_compiled_aside, warm_scene
    embree_library.library()  # binds the names the kernel links against (EmbreeError if it cannot be loaded)
    for index, real in enumerate(reals):
        precision = "float64" if real == np.float64 else "float32"
        first = index == 0
        with shading_compiled_aside(precision, winding and first):  # on a cache miss, these compile aside
            jit.ready(shadow_caster(False))  # local mode's stand-in, then global mode's shadow rays (one kernel for
            if shadows and first:  # every precision: its inputs are float64), while the helper compiles
                jit.ready(shadow_caster(True))
            if scene_kernels is not None and first:
                scene_kernels()
            ready = prepare(warm_scene(precision))
            film = film_rows(allocate_film(2, 2, (), ready.real).rows(0, 0))
            render_band(0, 0, 0, ready.rays.params, ready.rays.shared_origins, NO_SHADOWS, ready.shading, film,
                        np.zeros(3), shader(ready.shading), shadow_caster(False), cutter(ready.rays.params,
                                                                                       ready.shading))
            if winding and first:  # the helper's second task: by now done, or waited for
                from ..geometry.mesh_repair import warm_up_winding
                warm_up_winding()


def warm_kernels_for(plans: list[RenderPlan], scene_kernels: Callable[[], None] | None = None,
                     winding: bool = False) -> None:
    """warm_kernels with only the shading precisions these plans need, and shadow rays if one is in global mode."""
    if plans:
        warm_kernels(tuple({plan.real for plan in plans}),
                     shadows=any(plan.keeps(StageName.SHADOW_RAYS) for plan in plans),
                     scene_kernels=scene_kernels, winding=winding)


def render_file(path: str | Path, overrides: list[str] | tuple[str, ...] = (), *, view: str | None = None,
                up: str | None = None, **options) -> RenderResult:
    """Load a scene file or a mesh file and render it; timings include "load".

    Parameters
    ----------
    path: a scene file (.toml, .json) or a mesh file (docs/meshes.md). overrides: `key.path=value` strings, as
        --set. view, up: how a mesh file is framed (three_quarter, front, side, top, iso; "+z", ...).
    options: render()'s keyword arguments (threads, progress, max_memory, ...).

    Returns the RenderResult (see render). Raises SceneError (one line naming the file, the key path and what
    is allowed) for a file that cannot be read or a value the format refuses.
    """
    start = time.perf_counter()
    scene = load_scene(path, overrides, view=view, up=up, max_memory=options.get("max_memory"))
    loaded = time.perf_counter() - start
    return render(scene, **options).with_timings(load=loaded)
