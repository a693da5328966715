"""What a render settles before anything is built: its plan, its tiles and threads, and whether it fits the
memory budget. Nothing here compiles or imports numba, so a scene that is refused (over the budget, too many
lights for global mode) is refused before the renderer's stages load (`raycast-phong render` checks here first:
a refused input costs its validation, not numba's import and the kernels)."""

from __future__ import annotations

from typing import NamedTuple

from ..codes import StageName
from ..errors import SceneError
from ..io.system import default_threads
from ..records import RenderPlan
from ..scene.schema import Scene
from .budget import MemoryEstimate, check_memory
from .kernels.layout import MAX_LIGHTS
from .plan import build_plan

TILE_RAYS = 1 << 15  # 32k rays: large enough to amortise a call, small enough for ~10 MB per tile


class Fitted(NamedTuple):
    """What prepare() settles before anything is built."""
    plan: RenderPlan
    bands: tuple[tuple[int, int], ...]  # rows [row0, row1) of each tile
    threads: int
    tile_rays: int                      # the rays of a full tile
    sources: dict | None                # each mesh file's MeshSource (None: the scene has none)
    memory: MemoryEstimate


def fitted(scene: Scene, plan: RenderPlan | None = None, threads: int | None = None,
           max_memory: int | str | None = None) -> Fitted:
    """The plan (`plan`, else the scene's), the bands of rows, the threads (`threads`, else the cores) and the
    memory check against `max_memory` (a SceneError, one line, over the budget or past MAX_LIGHTS in global mode)."""
    plan = plan or build_plan(scene)
    if plan.keeps(StageName.SHADOW_RAYS) and len(scene.lights) > MAX_LIGHTS:
        raise SceneError(f"global mode handles at most {MAX_LIGHTS} lights, the scene has {len(scene.lights)}; "
                         'use render.mode = "local" or fewer lights', scene.origin.at("lights"))
    width, height, samples = scene.render.width, scene.render.height, scene.render.samples
    rows_per_tile = max(1, TILE_RAYS // (width * samples * samples))
    bands = tuple((row, min(row + rows_per_tile, height)) for row in range(0, height, rows_per_tile))
    threads = threads or default_threads()
    tile_rays = rows_per_tile * width * samples * samples
    sources = scene.current_mesh_sources()  # each mesh file's MeshSource, read once (the scene's)
    memory = check_memory(scene, max_memory, sources=sources, smooth=plan.keeps(StageName.VERTEX_NORMALS),
                          float64=plan.keeps(StageName.FLOAT64_SHADING),
                          shadow_lights=len(scene.lights) if plan.keeps(StageName.SHADOW_RAYS) else 0,
                          tile_rays=tile_rays, threads=min(threads, len(bands)))
    return Fitted(plan, bands, threads, tile_rays, sources, memory)
