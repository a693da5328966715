"""Estimate a render's memory from the scene alone, before anything is built; refuse it above a budget.

The estimate counts each object's triangles from its keys (subdivisions, segments) or its mesh file's
header, and the image's pixels, layers and rays per tile; render() checks it before building geometry,
so a scene too large for the machine fails in milliseconds with one line instead of swapping until it
is killed. The budget is a share of the memory available now, or what the caller sets (--max-memory,
render(max_memory=...)).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..codes import GEOMETRY_LAYERS, MAP_COLUMNS, TERM_LAYERS, ShadingModel
from ..errors import SceneError
from ..io.system import budget_of, count_text, format_bytes
from ..scene.alike import alike
from ..scene.schema import Scene
from ..shapes import KINDS, from_file
from ..values.messages import dotted

# Peak bytes per triangle above a warmed-up process's baseline (VmHWM after /proc/self/clear_refs; one
# object, 8×8 image, one thread; trimesh 4, numpy 2; measured 2026-11 on the project's x86-64 machine):
#   icosphere 8 (1.31M triangles) flat 251, phong 305, phong in float64 341, phong in global mode 345;
#   plane 1024×512 flat 186, phong with crease_angle 30 222; uv_sphere [8, 2048] with crease_angle 30
#   (two poles of 4096 faces) 572 on 49k triangles. The same icosphere (7) from a file, phong: PLY 281,
#   OBJ 331, GLB 347, STL 573, OFF 797 (flat the same but PLY 245, GLB 310: trimesh's own parse is the peak).
#   A noisy 1.31M-triangle PLY whose every vertex the crease splits, crease_angle 30: 692 (232 on the 327,680
#   triangles of icosphere 7 since the crease split is a compiled pass, 2026-12).
# On two threads a large mesh's BVH is built while its normals are made (prepare.BuildAhead), so both peaks overlap:
#   the 1.11M-triangle bunny, 8×8, phong with the files' crease angle 30: PLY 306 (254 on one thread), GLB 276 (237),
#   OBJ 260 (124), STL 238 (131); estimated 350, 384, 490, 344 (2026-12).
# The constants round these up; bench_mesh.py measures the whole render at 1000×1000 and 2M triangles.
FLAT_BYTES = 270       # vertices, faces, face normals, Embree's BVH, the shading copies, freed heap kept by malloc
SMOOTH_BYTES = 330     # + float32 corner normals (36 B) and their per-vertex sums
FLOAT64_NORMAL_BYTES = 40  # corner normals in float64 (float64 shading, or global mode's shadow copy)
# A mesh file with a crease angle: at worst every corner takes the pairwise test, whose compiled pass buckets the
# corners by vertex (8 bytes a corner): the noisy icosphere-7 PLY whose every vertex it splits, 232 B/triangle.
CREASED_FILE_BYTES = 360
# From embree_library.MORTON_FACES triangles in all, Embree builds the BVH by its Morton builder on the compact
# layout: less BVH and fewer build temporaries. icosphere 7 as a PLY (327,680 triangles), 8×8, one thread: phong
# 206 B/triangle (281 with the SAH build), flat 176; as STL, OBJ, GLB 194-254. The per-triangle figures above less:
MORTON_SAVING_BYTES = 50
# Per object, whatever its triangles: its validated object (its kind's model: a dict of 10 to 12 values, under
# 1 KB, and the column temporaries of scene.bulk.objects_in_bulk) and the per-object rows of the geometry
# (placement, material, model, group). Validating and rendering planes of 2 triangles, peak above a warmed-up
# process: 30,000 at 64×48 2.15 KB an object in all (tests/renderer/test_budget.py), 100,000 at 320×240
# (bench_many_objects.py) 985 B above what the triangles and the image were estimated; validation alone peaks at
# 1.3 KB an object (measured with the one model of every shape's keys; a kind's own model is smaller).
OBJECT_BYTES = 2000
# Per ray of a tile (origins, directions, hits, Embree's output): 8192 × 16² rays in one row took 117 MB.
RAY_BYTES = 64


@dataclass(frozen=True)
class MemoryEstimate:
    """Bytes a render will need at its peak, in two parts, and the object that weighs most."""
    triangles: int
    geometry: int        # bytes: meshes, normals, BVH, the kernels' copies
    image: int           # bytes: film, layers, their float32 copies for writing, the tiles' rays
    largest: int | None  # index of the object with the most geometry bytes
    largest_bytes: int
    textures: int = 0    # bytes: decoded colour maps and their mip pyramids (io.textures.texture_bytes)

    @property
    def total(self) -> int:
        return self.geometry + self.image + self.textures


def shape_triangles(obj) -> int:
    """Triangles a built-in shape makes (its kind's count; tests compare it with the built meshes)."""
    return KINDS[obj.shape].triangles(obj)


def size_key(obj) -> str:
    """The key that sets an object's triangle count."""
    return KINDS[obj.shape].size_key


def estimate_memory(scene: Scene, *, smooth: bool = True, float64: bool = False,
                    shadow_lights: int = 0, tile_rays: int = 1 << 15, threads: int = 1,
                    sources: dict | None = None) -> MemoryEstimate:
    """The peak memory of rendering `scene`, from its keys and mesh-file headers only.

    smooth: the plan keeps vertex normals; float64: it shades in float64; shadow_lights: lights that
    cast shadow rays (global mode); tile_rays × threads rays are in flight at once; sources: the mesh files'
    io.meshes.source.MeshSource by resolved path (made here when not given).
    """
    sources = scene.current_mesh_sources() if sources is None else sources
    files: dict[Path, int] = {}
    geometry, triangles, largest, largest_bytes = 0, 0, None, -1
    wide_normals = FLOAT64_NORMAL_BYTES if float64 or shadow_lights else 0
    sets = alike(scene)  # objects that differ only in placement cost the same: one estimate a set
    costs = []  # per set: (first object, objects, triangles, bytes a triangle, the least its read takes)
    for index, objects in zip(sets.first.tolist(), sets.count.tolist()):
        obj = scene.objects[index]
        mesh_file, floor = from_file(obj), 0
        if mesh_file:
            path = scene.resolve(obj.path)
            mesh = sources[path]
            if path not in files:
                files[path] = mesh.triangles()
            count, extra = files[path], mesh.format.parse_bytes
            floor = mesh.read_floor()  # a large file that claims few triangles still costs its read (a one-line OBJ)
        else:
            count, extra = shape_triangles(obj), 0
        smooth_here = smooth and scene.shading_of(obj) != ShadingModel.FLAT
        per = FLAT_BYTES
        if smooth_here:
            per = SMOOTH_BYTES + wide_normals
            if obj.crease_angle < 180 and mesh_file:
                # A built-in shape is smooth but for a few edges and poles; a file may be noise everywhere.
                per = max(per, CREASED_FILE_BYTES)
        costs.append((index, objects, count, per + extra, floor))
        triangles += count * objects
    from .embree_library import MORTON_FACES  # (ctypes: only when a scene is estimated; no numba, no LLVM)
    saving = MORTON_SAVING_BYTES if triangles >= MORTON_FACES else 0
    for index, objects, count, per, floor in costs:
        size = max(count * (per - saving), floor)
        geometry += size * objects
        if size > largest_bytes:  # the first object of the largest set is the first of the largest objects
            largest, largest_bytes = index, size
    geometry += len(scene.objects) * OBJECT_BYTES
    render = scene.render
    pixels = render.width * render.height
    real = 8 if float64 else 4
    aovs = set(scene.output.aovs)
    terms = bool(aovs & set(TERM_LAYERS))
    layers = bool(aovs & set(GEOMETRY_LAYERS))
    film = pixels * (3 * real + (12 * real if terms else 0) + (20 if layers else 0))
    # Writing makes one float32 copy of every channel written (PNG: of RGB before the 8-bit conversion).
    written = pixels * 4 * (3 + 3 * len(aovs & {*TERM_LAYERS, "normal"})
                            + len(aovs & {"depth", "face"}))
    rays = tile_rays * threads * (1 + shadow_lights) * RAY_BYTES
    return MemoryEstimate(triangles, geometry, film + written + rays, largest, max(largest_bytes, 0),
                          texture_estimate(scene, [sources[path] for path in files]))


def texture_estimate(scene: Scene, meshes) -> int:
    """The texture term: every colour map a used scene material names and every map the mesh files'
    materials name (`meshes`: their MeshSources), at the size it is decoded at, from image headers only
    (io.textures; a mesh file's sizes are its MeshSource's)."""
    used = {obj.material for obj in alike(scene).firsts(scene.objects)}
    maps = {scene.resolve(getattr(material, key).path): scene.origin.at("materials", name, key)
            for name, material in scene.materials.items() if name in used or name == "default"
            for key in MAP_COLUMNS if getattr(material, key) is not None}
    sizes = [size for mesh in meshes for size in mesh.texture_sizes]
    if not maps and not sizes:
        return 0
    from ..io.textures import check_map_file, file_size, texture_bytes
    for path, where in maps.items():
        check_map_file(path, where)  # a file no reader should probe is refused before any does
    return texture_bytes([size for size in map(file_size, maps) if size] + sizes)


# ---------------------------------------------------------------- the budget


def check_memory(scene: Scene, max_memory: int | str | None, **options) -> MemoryEstimate:
    """Refuse (SceneError, one line) a scene whose estimate exceeds the budget: max_memory in bytes (or
    '8G'), default default_budget(). `options` go to estimate_memory. Returns the estimate."""
    budget = budget_of(max_memory)
    found = estimate_memory(scene, **options)
    if budget is None or found.total <= budget:
        return found
    need, limit = format_bytes(found.total), format_bytes(budget)
    raise_it = "lower it or raise the budget (--max-memory, render(max_memory=...))"
    if found.geometry >= found.image:
        index = found.largest
        obj = scene.objects[index]
        key = size_key(obj)
        value = getattr(obj, key)
        shown = repr(value) if isinstance(value, str) else str(list(value) if isinstance(value, tuple) else value)
        others = f", and {format_bytes(found.image)} for the image" if found.image * 20 > found.total else ""
        amount = f"≈ {need} of memory for geometry ({count_text(found.triangles)} triangles{others})"
        if found.largest_bytes * 2 >= found.geometry:  # one object is most of it: name its key
            at, what = scene.origin.at("objects", index, key), f"{shown} needs {amount}"
        else:
            at = scene.origin.at("objects")
            what = (f"{len(scene.objects):,} objects need {amount}, the largest {dotted(('objects', index, key))} = "
                    f"{shown} {format_bytes(found.largest_bytes)}")
            raise_it = "use fewer or coarser objects or raise the budget (--max-memory, render(max_memory=...))"
        raise SceneError(f"{what}, above the {limit} budget; {raise_it}", at)
    render = scene.render
    layers = f" and {len(scene.output.aovs)} layer(s) (output.aovs)" if scene.output.aovs else ""
    samples = f", {render.samples}² samples" if render.samples > 1 else ""
    raise SceneError(f"render.width × render.height: {render.width}×{render.height} pixels{samples}{layers} need "
                     f"≈ {need} of memory, above the {limit} budget; lower them or raise the budget (--max-memory, "
                     "render(max_memory=...))", scene.origin)
