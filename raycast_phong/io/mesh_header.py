"""A mesh file's size before it is read: its triangle count from the header (PLY, OFF, binary STL, glTF) or
a cheap scan (OBJ's face lines), and whether reading it could fit in memory at all.

Counts are kept per file version (io.files.VersionCache): framing's check and the render's estimate both ask.
"""

from __future__ import annotations

import json
import os
import re
import struct
from pathlib import Path

from ..errors import SceneError
from .files import VersionCache, file_version, open_regular
from .system import available_memory, count_text, format_bytes

# trimesh's load of a mesh file, above the render's own peak (the parse of a text or STL file is larger).
MESH_FILE_BYTES = {".ply": 30, ".obj": 80, ".glb": 70, ".gltf": 70, ".stl": 330, ".off": 550}
OTHER_MESH_FILE_BYTES = 550
# Bytes per triangle of reading a mesh file and holding it for a flat render: renderer.budget.FLAT_BYTES, the
# measured figure (a test keeps the two equal; here so framing, below the renderer, can check a read).
MESH_READ_BYTES = 270


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
        # An OBJ is counted line by line (0.37 s for 78 MB): once per version; framing and the render both ask.
        return COUNTS.setdefault(file_version(path, info),
                                 lambda: _count_triangles(handle, path.suffix.lower(), info.st_size))


COUNTS: VersionCache[int] = VersionCache(64)  # file version → triangles


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


def check_mesh_read(path: Path, source: str) -> None:
    """Refuse (SceneError, one line) to read a mesh file for framing (scene.framing, before any render and
    so before renderer.budget.check_memory) when the read alone could not fit in the memory available now: its triangles
    (from the header, mesh_file_triangles) × the flat render's bytes per triangle and the format's parse.
    Against the whole available memory, not the budget: --max-memory only reaches the render."""
    available = available_memory()
    triangles = mesh_file_triangles(path, source)
    need = triangles * (MESH_READ_BYTES + MESH_FILE_BYTES.get(path.suffix.lower(), OTHER_MESH_FILE_BYTES))
    if available is not None and need > available:
        raise SceneError(f"{source}: reading its {count_text(triangles)} triangles needs ≈ {format_bytes(need)} of "
                         f"memory, more than the {format_bytes(available)} available; allowed: a mesh whose "
                         "triangles fit, so decimate it or free memory")
