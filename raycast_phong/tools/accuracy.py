"""A render's error against a reference: the analytic oracle, or a finer render of the scene itself.

Tessellation levels (`refined`, `level_of`), the self-convergence reference for meshes
(`fine_reference`: the scene `levels` finer, rendered by the renderer itself), the coverage of the
render's own triangles (`mesh_coverage`), and `measured`, which attaches RMSE, max, PSNR, … to a
RenderResult (render --reference, study). A tool on top of the pipeline; reference.py, the oracle,
knows none of this.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np
import trimesh

from ..errors import SceneError
from ..geometry.templates import object_mesh
from ..records import MeasuredResult, RenderResult
from ..renderer.frame import render
from ..renderer.prepare import Prepared, prepare
from ..scene.schema import Object, Scene, validate_scene
from ..shapes import from_file, kind_of
from .metrics import measure
from .reference import ReferenceImage, analytic_reference


def refined(obj: Object, level: int) -> dict:
    """The keys that give an analytic object tessellation `level` (docs/accuracy.md, "Levels"; its kind's rule:
    icosphere subdivisions = L, uv_sphere and torus segments = [8·2^L, 4·2^L], cylinder [8·2^L, its own second
    value], plane [2^L, 2^L], box unchanged since 12 flat faces are exact); {} for a mesh file."""
    return kind_of(obj).refined(obj, level)


def level_of(obj: Object) -> int:
    """The level of an object as the scene gives it (the inverse of `refined`; 0 for a box or mesh)."""
    return kind_of(obj).level_of(obj)


def refine_entry(scene: Scene, index: int, entry: dict, level: int, iterations: int, folder: Path) -> None:
    """Set scene object `index`'s dict `entry` to tessellation `level` (analytic shapes), or, for a mesh,
    to its file Loop-subdivided `iterations` times (trimesh.remesh.subdivide_loop: it converges to a smooth
    limit surface, where midpoint subdivision would keep the same flat facets), written into `folder`."""
    obj = scene.objects[index]
    if not from_file(obj):
        entry.update(refined(obj, level))
    elif iterations > 0:
        target = folder / f"object{index}-loop{iterations}.ply"
        if not target.exists():
            vertices, faces, *_ = object_mesh(scene, index)
            vertices, faces = trimesh.remesh.subdivide_loop(vertices, faces, iterations=iterations)
            trimesh.Trimesh(vertices, faces, process=False).export(target)
        entry["path"] = str(target)
        if entry.get("normals") == "file":
            entry["normals"] = "mean"  # the subdivided mesh stores no normals


LOOP_BYTES = 400  # per triangle trimesh's subdivide_loop makes (peak 293 B measured at 82k) and its PLY round trip


def check_fine_memory(scene: Scene, data: dict, levels: int, max_memory: int | None) -> None:
    """Refuse (SceneError, one line) a fine reference whose refined scene would not fit in `max_memory` bytes
    (default: the render's budget), before a mesh is subdivided: the refined shapes' estimate
    (budget.estimate_memory of `data`, smooth, float64) and each mesh file's triangles × (4^levels − 1) more,
    at the render's bytes a triangle and the subdivision's."""
    from ..io.system import budget_of, count_text, format_bytes
    from ..renderer.budget import FLOAT64_NORMAL_BYTES, SMOOTH_BYTES, estimate_memory
    budget = budget_of(max_memory)
    if budget is None:
        return
    found = estimate_memory(validate_scene(data, source=scene.origin, folder=scene.folder), float64=True)
    sources = scene.current_mesh_sources()  # each mesh file's, made once for all its objects
    extra_triangles = (4 ** levels - 1) * sum(sources[path].triangles() for _, path in scene.mesh_objects())
    need = found.total + extra_triangles * (SMOOTH_BYTES + FLOAT64_NORMAL_BYTES + LOOP_BYTES)
    if need > budget:
        triangles = count_text(found.triangles + extra_triangles)
        raise SceneError(f"--fine {levels}: the refined scene has {triangles} triangles and needs ≈ "
                         f"{format_bytes(need)} of memory, above the {format_bytes(budget)} budget; use a smaller "
                         "--fine or raise the budget (--max-memory)", scene.origin)


def fine_reference(scene: Scene, levels: int, max_memory: int | None = None) -> ReferenceImage:
    """The scene refined `levels` times (refine_entry: meshes Loop-subdivided, analytic shapes `levels`
    tessellation levels up from their own), rendered with Phong shading in float64. Coverage comes from
    the same Embree cast as the render's. Refused (check_fine_memory) before anything is refined when it
    would need more than `max_memory` bytes (default: the render's budget)."""
    data = scene.data()
    data["render"].update(shading="phong", precision="float64")
    data["output"] = {"path": "reference.exr", "aovs": ["specular"]}
    targets = [min(level_of(obj) + levels, max_level(obj)) for obj in scene.objects]
    for index, obj in enumerate(scene.objects):
        data["objects"][index]["shading"] = "phong"
        if not from_file(obj):
            data["objects"][index].update(refined(obj, targets[index]))
    check_fine_memory(scene, data, levels, max_memory)
    with tempfile.TemporaryDirectory(prefix="raycast-phong-fine-") as folder:
        for index, target in enumerate(targets):  # the meshes now Loop-subdivided
            refine_entry(scene, index, data["objects"][index], target, levels, Path(folder))
        fine = validate_scene(data, source=scene.origin, folder=scene.folder)
        result = render(fine, max_memory=max_memory)
        coverage = mesh_coverage(fine)
    return ReferenceImage(result.image.astype(np.float64), result.aovs["specular"].astype(np.float64),
                          coverage, f"fine {levels}")


def max_level(obj: Object) -> int:
    """The finest level the scene format allows for the shape (subdivisions ≤ 8, segments ≤ 4096; a mesh: 9)."""
    return kind_of(obj).max_level


def reference_image(scene: Scene, fine: int | None = None, max_memory: int | None = None) -> ReferenceImage:
    """The analytic reference, or with `fine` the self-convergence one (the only choice for meshes), within
    `max_memory` bytes (default: the render's budget)."""
    if fine is not None:
        return fine_reference(scene, fine, max_memory)
    check_reference_memory(scene, max_memory)
    return analytic_reference(scene)


# The analytic reference holds float64 image, specular and coverage (56 bytes a pixel) and, written, a float32
# copy and the file's buffers: `reference` of the default scene peaked 320 MB at 1024² and 570 MB at 2048²,
# 81 bytes a pixel over ≈ 235 MB of interpreter, libraries and tiles (TILE_SAMPLES rays at a time).
REFERENCE_PIXEL_BYTES = 88


def check_reference_memory(scene: Scene, max_memory: int | None) -> None:
    """Refuse (SceneError, one line) an analytic reference whose image does not fit the budget: `max_memory`
    bytes, default the render's (io.system.default_budget)."""
    from ..io.system import budget_of, format_bytes
    budget = budget_of(max_memory)
    render = scene.render
    need = render.width * render.height * REFERENCE_PIXEL_BYTES
    if budget is not None and need > budget:
        raise SceneError(f"{scene.origin}: render.width × render.height: {render.width}×{render.height} pixels need ≈ "
                         f"{format_bytes(need)} of memory for the analytic reference, above the "
                         f"{format_bytes(budget)} budget; lower them or raise the budget (--max-memory)")


def mesh_coverage(scene: Scene | Prepared) -> np.ndarray:
    """(H, W) share of each pixel's samples whose ray hits the scene's triangles: the render's own rays and
    BVH (prepare, or a scene already prepared), cast band by band."""
    ready = scene if isinstance(scene, Prepared) else prepare(scene)
    scene = ready.scene
    accelerator = ready.build()
    width, n = scene.render.width, scene.render.samples
    coverage = np.zeros((scene.render.height, width))
    for row0, row1 in ready.bands:
        hits = accelerator.closest_hits(*ready.rays.rows(row0, row1), width * n * n)
        coverage[row0:row1] = (hits.face >= 0).reshape(row1 - row0, width, n * n).mean(axis=2)
    return coverage


def measured(scene: Scene, result: RenderResult, reference: str, fine: int = 2) -> MeasuredResult:
    """`result` with its errors against the "analytic" (or "fine": `fine` levels finer) reference."""
    if reference not in ("analytic", "fine"):
        raise ValueError(f"reference must be 'analytic' or 'fine', got {reference!r}")
    start = time.perf_counter()
    exact = reference_image(scene, fine=fine if reference == "fine" else None)
    errors = measure(result.image, mesh_coverage(scene), exact)
    fields = {name: getattr(result, name) for name in RenderResult.__dataclass_fields__}
    return MeasuredResult(**fields, errors=errors, reference_seconds=time.perf_counter() - start)
