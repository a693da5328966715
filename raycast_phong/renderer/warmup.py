"""Have a scene's kernels ready before its render, so a frame's time (and the Mrays/s printed from it) holds
neither compilation nor loading from numba's cache."""

from __future__ import annotations

import time
from collections.abc import Callable

from ..codes import StageName
from ..scene.schema import Scene


def ready_kernels(scene: Scene, announce: Callable[[str], None] | None = None) -> tuple[str, float]:
    """("compile", seconds) when any kernel this scene's render calls is not in the cache for the signature the
    scene gives it (the first render after an install or an edit, or of a new precision: float64 after
    float32 is a compile too), else ("kernels", seconds) for loading them from the cache (≈ 0.1 s, most of it
    numba's one-time set-up in a process). `announce` is told once, when numba is about to compile the first
    of them (compiles.told hears the cache miss), so no compile is ever silent. The kernels are the
    frame's in the scene's precision, the geometry stage's and, for a scene with a mesh file, its
    preparation's (mesh_repair.warm_up_merge, and warm_up_winding, which a helper may compile meanwhile; the
    kernels its format's reader will run (MeshFormat.warm_up: an OBJ's scans), none for a file already read in
    this process and waiting for its render, as a mesh file given on the command line is, whose read compiled
    what it needed: its render does not read it again), and the crease split's where an object may be creased
    (normals.warm_up_creases).
    A mesh file that cannot be opened is refused first (one line, naming the scene's file): before any compile."""
    import numpy as np

    from ..compiles import part, told
    from ..geometry.mesh_repair import WINDING_KERNELS, warm_up_merge, winding_signatures
    from ..geometry.normals import warm_up_creases
    from ..io.files import open_mesh_file
    from ..scene.alike import alike
    from ..shapes import from_file
    from .frame import warm_kernels_for
    from .plan import build_plan
    plan = build_plan(scene)
    firsts = [(index, scene.objects[index]) for index in alike(scene).first.tolist()]  # a mesh: a set of its own
    meshes, readers = False, {}
    for index, obj in firsts:
        if from_file(obj):
            from ..io.meshes import format_of  # the format registry: only for a scene with a mesh file
            from ..io.meshes.source import source_key
            path = scene.resolve(obj.path)
            handle = open_mesh_file(path, scene.origin.at("objects", index, "path"))
            waiting = scene.mesh_sources.get(source_key(path))
            warm_up = format_of(path).warm_up
            with handle:
                if warm_up is not None and not (waiting is not None and waiting.holds_read()):
                    readers.update(dict.fromkeys(warm_up(handle)))
            meshes = True
    creases = plan.keeps(StageName.VERTEX_NORMALS) and (meshes or any(obj.crease_angle < 180 for _, obj in firsts))
    real = plan.real

    def tell(name: str, signature: str) -> None:
        """Said once, before the first compile: what compiles, named by its first kernel, and how long it takes."""
        if announce is None:
            return
        smaller = part(name)
        if smaller is None:
            precision = np.dtype(real).name
            announce(f"compiling the {precision} shading kernels, the first time a scene needs {precision} after "
                     "an install or an edit (about 13-18 s of CPU shared by two processes: 6-9 s on an idle 2-core "
                     "machine)...")
            return
        # The shadow rays' kernels compile before the shading kernels, which may follow.
        also, shading = ((", and the shading kernels if they are not compiled yet",
                          ", 13-18 s of CPU with the shading kernels") if "shadows" in name else ("", ""))
        announce(f"compiling {smaller}{also}, the first time a scene needs them after an install or an edit (a few "
                 f"seconds{shading})...")

    def scene_kernels() -> None:  # this scene's own preparation: compiled here while a helper compiles the rest
        if meshes:
            warm_up_merge()
            for kernel, signature in winding_signatures().items():  # a helper may be compiling the others
                if kernel not in WINDING_KERNELS:
                    kernel.compile(signature)
        for warm in readers:
            warm()
        if creases:  # in the corner normals' dtype: the shading precision (render() asks build_geometry for it)
            warm_up_creases(real)

    started = time.perf_counter()
    with told(tell) as compiled:
        warm_kernels_for([plan], scene_kernels, winding=meshes)
    return ("compile" if compiled else "kernels"), time.perf_counter() - started
