"""Estimate a render's memory from the scene alone, before anything is built; refuse it above a budget.

The estimate counts each object's triangles from its keys (subdivisions, segments) or its mesh file's
header, and the image's pixels, layers and rays per tile; render() checks it before building geometry,
so a scene too large for the machine fails in milliseconds with one line instead of swapping until it
is killed. The budget is a share of the memory available now, or what the caller sets (--max-memory,
render(max_memory=...)).
"""

from __future__ import annotations

import json
import os
import re
import struct
from dataclasses import dataclass
from pathlib import Path

from ..scene.schema import Scene, SceneError, ShadingModel, open_regular

# Peak bytes per triangle above a warmed-up process's baseline (VmHWM after /proc/self/clear_refs; one
# object, 8×8 image, one thread; trimesh 4, numpy 2; measured 2026-11 on the project's x86-64 machine):
#   icosphere 8 (1.31M triangles) flat 251, phong 305, phong in float64 341, phong in global mode 345;
#   plane 1024×512 flat 186, phong with crease_angle 30 222; uv_sphere [8, 2048] with crease_angle 30
#   (two poles of 4096 faces) 572 on 49k triangles. The same icosphere (7) from a file, phong: PLY 281,
#   OBJ 331, GLB 347, STL 573, OFF 797 (flat the same but PLY 245, GLB 310: trimesh's own parse is the peak).
#   A noisy 1.31M-triangle PLY whose every vertex the crease splits, crease_angle 30: 692.
# The constants round these up; bench_mesh.py measures the whole render at 1000×1000 and 2M triangles.
FLAT_BYTES = 270       # vertices, faces, face normals, Embree's BVH, the shading copies, freed heap kept by malloc
SMOOTH_BYTES = 330     # + float32 corner normals (36 B) and their per-vertex sums
FLOAT64_NORMAL_BYTES = 40  # corner normals in float64 (float64 shading, or global mode's shadow copy)
CREASED_FILE_BYTES = 720   # a mesh file with a crease angle: at worst every corner takes the pairwise test
CREASE_CHUNK_BYTES = 64 << 20  # the pairwise test's temporaries, a chunk at a time (normals.PAIR_CHUNK)
# trimesh's load of a mesh file, above the render's own peak (the parse of a text or STL file is larger).
MESH_FILE_BYTES = {".ply": 30, ".obj": 80, ".glb": 70, ".gltf": 70, ".stl": 330, ".off": 550}
OTHER_MESH_FILE_BYTES = 550
# Per ray of a tile (origins, directions, hits, Embree's output): 8192 × 16² rays in one row took 117 MB.
RAY_BYTES = 64
BUDGET_SHARE = 0.75    # of the memory available now: the rest is for the OS and other programs
GB = 1 << 30


@dataclass(frozen=True)
class MemoryEstimate:
    """Bytes a render will need at its peak, in two parts, and the object that weighs most."""
    triangles: int
    geometry: int        # bytes: meshes, normals, BVH, the kernels' copies
    image: int           # bytes: film, layers, their float32 copies for writing, the tiles' rays
    largest: int | None  # index of the object with the most geometry bytes
    largest_bytes: int

    @property
    def total(self) -> int:
        return self.geometry + self.image


def shape_triangles(obj) -> int:
    """Triangles trimesh makes for a built-in shape (tests compare with the real meshes)."""
    if obj.shape == "icosphere":
        return 20 * 4 ** obj.subdivisions
    if obj.shape == "uv_sphere":
        # trimesh rounds both counts up to even and doubles the second; 2 triangles fewer per meridian at the poles.
        rings, sections = (c + c % 2 for c in (obj.segments or (32, 16)))
        return 2 * (rings - 2) * 2 * sections
    if obj.shape == "box":
        return 12
    if obj.shape == "cylinder":
        return 4 * (obj.segments or (32, 1))[0]  # side quads and two cap fans
    if obj.shape == "torus":
        major, minor = obj.segments or (32, 16)
        return 2 * major * minor
    nx, nz = obj.segments or (1, 1)  # plane
    return 2 * nx * nz


def size_key(obj) -> str:
    """The key that sets an object's triangle count."""
    return {"icosphere": "subdivisions", "mesh": "path", "box": "shape"}.get(obj.shape, "segments")


def estimate_memory(scene: Scene, source: str = "<scene>", *, smooth: bool = True, float64: bool = False,
                    shadow_lights: int = 0, tile_rays: int = 1 << 15, threads: int = 1) -> MemoryEstimate:
    """The peak memory of rendering `scene`, from its keys and mesh-file headers only.

    smooth: the plan keeps vertex normals; float64: it shades in float64; shadow_lights: lights that
    cast shadow rays (global mode); tile_rays × threads rays are in flight at once.
    """
    files: dict[Path, int] = {}
    geometry, triangles, largest, largest_bytes = 0, 0, None, -1
    wide_normals = FLOAT64_NORMAL_BYTES if float64 or shadow_lights else 0
    for index, obj in enumerate(scene.objects):
        mesh_file = obj.shape == "mesh"
        if mesh_file:
            path = scene.resolve(obj.path)
            if path not in files:
                files[path] = mesh_file_triangles(path, f"{source}: objects.{index}.path")
            count, extra = files[path], MESH_FILE_BYTES.get(path.suffix.lower(), OTHER_MESH_FILE_BYTES)
        else:
            count, extra = shape_triangles(obj), 0
        smooth_here = smooth and scene.shading_of(obj) != ShadingModel.FLAT
        per, chunk = FLAT_BYTES, 0
        if smooth_here:
            per = SMOOTH_BYTES + wide_normals
            if obj.crease_angle < 180:
                # A built-in shape is smooth but for a few edges and poles; a file may be noise everywhere.
                per, chunk = (max(per, CREASED_FILE_BYTES) if mesh_file else per), CREASE_CHUNK_BYTES
        size = count * (per + extra) + chunk
        triangles += count
        geometry += size
        if size > largest_bytes:
            largest, largest_bytes = index, size
    render = scene.render
    pixels = render.width * render.height
    real = 8 if float64 else 4
    aovs = set(scene.output.aovs)
    terms = bool(aovs & {"ambient", "diffuse", "specular", "emission"})
    layers = bool(aovs & {"depth", "normal", "face"})
    film = pixels * (3 * real + (12 * real if terms else 0) + (20 if layers else 0))
    # Writing makes one float32 copy of every channel written (PNG: of RGB before the 8-bit conversion).
    written = pixels * 4 * (3 + 3 * len(aovs & {"ambient", "diffuse", "specular", "emission", "normal"})
                            + len(aovs & {"depth", "face"}))
    rays = tile_rays * threads * (1 + shadow_lights) * RAY_BYTES
    return MemoryEstimate(triangles, geometry, film + written + rays, largest, max(largest_bytes, 0))


def mesh_file_triangles(path: Path, key: str) -> int:
    """Triangles in a mesh file, read cheaply: PLY and OFF headers, binary STL's count, OBJ's face lines,
    glTF's accessor counts; other formats by file size (at least 6 bytes per triangle). 0 for a missing
    file (the loader reports it); a FIFO, device or folder is refused here (SceneError)."""
    try:
        handle = open_regular(path, key, "mesh file")
    except FileNotFoundError:
        return 0
    with handle:
        info = os.fstat(handle.fileno())
        version = (str(path), info.st_mtime_ns, info.st_size, info.st_ino)
        if version not in _counted:  # an OBJ is counted line by line (0.37 s for 78 MB): once per version
            if len(_counted) >= MAX_COUNTED:
                _counted.pop(next(iter(_counted)))
            _counted[version] = _count_triangles(handle, path.suffix.lower(), info.st_size)
        return _counted[version]


_counted: dict[tuple, int] = {}  # (path, mtime, size, inode) → triangles: framing and the render both ask
MAX_COUNTED = 64


def _count_triangles(handle, suffix: str, size: int) -> int:
    """mesh_file_triangles of the open file `handle` of `size` bytes."""
    head = handle.read(4096)
    try:
        if suffix == ".ply":
            match = re.search(rb"^element\s+face\s+(\d+)", head, re.M)
            if match:
                return int(match[1])
        elif suffix == ".stl":
            if not head.lstrip().startswith(b"solid") or size == 84 + 50 * struct.unpack_from("<I", head, 80)[0]:
                return struct.unpack_from("<I", head, 80)[0]
            return size // 86  # the shortest ASCII facet ("facet normal 0 0 0\nouter loop\n…") is 86 bytes
        elif suffix == ".off":
            numbers = [line.split() for line in head.splitlines()[1:] if line.strip() and not line.startswith(b"#")]
            if numbers and len(numbers[0]) >= 2:
                return int(numbers[0][1])
        elif suffix == ".obj":
            handle.seek(0)
            # A polygon of k corners becomes k − 2 triangles; 0.09 s for a 12.8 MB file (7% of its load).
            return sum(len(line.split()) - 3 for line in handle if line[:2] in (b"f ", b"f\t"))
        elif suffix == ".glb" and head[:4] == b"glTF":
            length = struct.unpack_from("<I", head, 12)[0]
            handle.seek(20)
            return _gltf_triangles(json.loads(handle.read(length)))
        elif suffix == ".gltf":
            handle.seek(0)
            return _gltf_triangles(json.loads(handle.read()))
    except (ValueError, KeyError, IndexError, TypeError, struct.error, OSError):
        pass  # a malformed header: fall back to the size bound; the loader reports the real problem
    return size // 6


def _gltf_triangles(document: dict) -> int:
    """Triangles over every node's mesh (each instance counts), from the accessors' counts."""
    accessors, meshes = document.get("accessors", []), document.get("meshes", [])
    uses = [node["mesh"] for node in document.get("nodes", []) if "mesh" in node] or range(len(meshes))
    total = 0
    for mesh in uses:
        for primitive in meshes[mesh].get("primitives", []):
            indexed = primitive.get("indices", primitive.get("attributes", {}).get("POSITION"))
            total += accessors[indexed]["count"] // 3
    return total


# ---------------------------------------------------------------- the budget


def available_memory() -> int | None:
    """Bytes the machine can give now: MemAvailable (Linux), capped by a cgroup limit; else free pages."""
    found = None
    try:
        with open("/proc/meminfo", "rb") as meminfo:
            for line in meminfo:
                if line.startswith(b"MemAvailable:"):
                    found = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    if found is None:
        try:
            found = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            return None
    try:  # a container's limit (cgroup v2) can be far below the host's free memory
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = int(Path("/sys/fs/cgroup/memory.current").read_text())
        if limit != "max":
            found = min(found, max(int(limit) - used, 0))
    except (OSError, ValueError):
        pass
    return found


def default_budget() -> int | None:
    """BUDGET_SHARE of the available memory; None (no limit) where the platform tells nothing."""
    available = available_memory()
    return None if available is None else int(available * BUDGET_SHARE)


UNITS = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


def parse_size(text: str) -> int:
    """'8G', '500M', '1.5GiB', '2048' (bytes) → bytes; K, M, G, T are powers of 1024. ValueError otherwise."""
    match = re.fullmatch(r"\s*(\d+(?:\.\d*)?|\.\d+)\s*([kmgt]?)(?:i?b)?\s*", str(text), re.I)
    if not match or float(match[1]) <= 0:
        raise ValueError(f"expected a size such as 8G, 500M or 1.5GiB (K, M, G, T: powers of 1024), got {text!r}")
    return int(float(match[1]) * UNITS[match[2].lower()])


def check_mesh_read(path: Path, source: str) -> None:
    """Refuse (SceneError, one line) to read a mesh file for framing (mesh_scene.py, before any render and
    so before check_memory) when the read alone could not fit in the memory available now: its triangles
    (from the header, mesh_file_triangles) × the flat render's bytes per triangle and the format's parse.
    Against the whole available memory, not the budget: --max-memory only reaches the render."""
    available = available_memory()
    triangles = mesh_file_triangles(path, source)
    need = triangles * (FLAT_BYTES + MESH_FILE_BYTES.get(path.suffix.lower(), OTHER_MESH_FILE_BYTES))
    if available is not None and need > available:
        raise SceneError(f"{source}: reading its {_count(triangles)} triangles needs ≈ {format_bytes(need)} of "
                         f"memory, more than the {format_bytes(available)} available; allowed: a mesh whose "
                         "triangles fit, so decimate it or free memory")


def format_bytes(count: float) -> str:
    """3.4 GB, 512 MB, 20 kB: binary units, written the way people say them."""
    for unit, size in (("TB", 1 << 40), ("GB", 1 << 30), ("MB", 1 << 20), ("kB", 1 << 10)):
        if count >= size:
            return f"{count / size:.3g} {unit}"
    return f"{int(count)} bytes"


def check_memory(scene: Scene, source: str, max_memory: int | str | None, **options) -> MemoryEstimate:
    """Refuse (SceneError, one line) a scene whose estimate exceeds the budget: max_memory in bytes (or
    '8G'), default default_budget(). `options` go to estimate_memory. Returns the estimate."""
    budget = parse_size(max_memory) if isinstance(max_memory, str) else max_memory
    if budget is None:
        budget = default_budget()
    found = estimate_memory(scene, source, **options)
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
        amount = f"≈ {need} of memory for geometry ({_count(found.triangles)} triangles{others})"
        if found.largest_bytes * 2 >= found.geometry:  # one object is most of it: name its key
            what = f"objects.{index}.{key}: {shown} needs {amount}"
        else:
            what = (f"objects: {len(scene.objects):,} objects need {amount}, the largest objects.{index}.{key} = "
                    f"{shown} {format_bytes(found.largest_bytes)}")
            raise_it = "use fewer or coarser objects or raise the budget (--max-memory, render(max_memory=...))"
        raise SceneError(f"{source}: {what}, above the {limit} budget; {raise_it}")
    render = scene.render
    layers = f" and {len(scene.output.aovs)} layer(s) (output.aovs)" if scene.output.aovs else ""
    samples = f", {render.samples}² samples" if render.samples > 1 else ""
    raise SceneError(f"{source}: render.width × render.height: {render.width}×{render.height} pixels{samples}"
                     f"{layers} need ≈ {need} of memory, above the {limit} budget; lower them or raise the "
                     "budget (--max-memory, render(max_memory=...))")


def _count(n: int) -> str:
    """335M, 1.3M, 40,000: a triangle count at a glance."""
    if n >= 10_000_000:
        return f"{n / 1e6:.0f}M"
    if n >= 1_000_000:
        return f"{n / 1e6:.1f}M"
    return f"{n:,}"
