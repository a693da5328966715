"""Have a scene's kernels ready before its render, so a frame's time (and the Mrays/s printed from it) holds
neither compilation nor loading from numba's cache."""

from __future__ import annotations

import time
from collections.abc import Callable

from ..scene.schema import Scene

# The geometry stage's kernels every render loads: warm_kernels prepares a smooth icosphere, which calls them.
GEOMETRY_KERNELS = ("face_normals_into", "vertex_normal_sums", "normalise_sums", "gather_corners")


def ready_kernels(scene: Scene, announce: Callable[[str], None] | None = None,
                  source: str = "scene") -> tuple[str, float]:
    """("compile", seconds) when the cache does not hold this scene's kernels (the first render after an install
    or an edit; `announce` is told first, as it takes 10-40 s), else ("kernels", seconds) for loading them
    from the cache (≈ 0.15 s, most of it numba's one-time set-up in a process). The kernels are the frame's, the
    geometry stage's and, for a scene with a mesh file, its preparation's (merge, winding: mesh_repair.warm_up;
    an OBJ's polygon scan: obj_polygons.warm_up), and the crease split's where an object may be creased
    (normals.warm_up_creases).
    A mesh file that cannot be opened is refused first (one line, naming `source`): before 10-40 s of compiling."""
    import numpy as np

    from ..geometry.mesh_repair import MESH_FILE_KERNELS, warm_up
    from ..geometry.normals import CREASE_KERNELS, warm_up_creases
    from ..jit import compiled_before
    from .frame import tile_kernel, warm_kernels_for
    from .plan import build_plan
    plan = build_plan(scene)
    from ..io.files import open_mesh_file
    from ..scene.kinds import object_kinds
    kinds = [(index, scene.objects[index]) for index in object_kinds(scene).first.tolist()]  # a mesh: its own kind
    meshes = objs = False
    for index, obj in kinds:
        if obj.shape == "mesh":
            open_mesh_file(scene.resolve(obj.path), f"{source}: objects.{index}.path").close()
            meshes = True
            objs = objs or str(obj.path).lower().endswith(".obj")
    creases = plan.keeps("vertex_normals") and (meshes or any(obj.crease_angle < 180 for _, obj in kinds))
    names = (tile_kernel(), *GEOMETRY_KERNELS, *(MESH_FILE_KERNELS if meshes else ()),
             *(CREASE_KERNELS if creases else ()))
    if objs:
        from ..io import obj_polygons
        names += obj_polygons.OBJ_KERNELS
    cached = all(compiled_before(name) for name in names)
    if not cached and announce is not None:
        announce("compiling the shading kernels (and the mesh preparation's), once after an install or an edit "
                 "(about 10-40 s)...")
    started = time.perf_counter()
    warm_kernels_for([plan])
    if meshes:
        warm_up()
    if objs:
        obj_polygons.warm_up()
    if creases:  # in the corner normals' dtype: the shading precision (render() asks build_geometry for it)
        warm_up_creases(np.float64 if plan.keeps("float64_shading") else np.float32)
    return ("kernels" if cached else "compile"), time.perf_counter() - started
