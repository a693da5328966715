"""What reading a mesh file costs, before it is read: its triangles from the header or a cheap scan (the
format's `count`; else the size bound), the least its read takes from its size and format (the format's
`floor`), and whether reading it could fit in memory at all. No trimesh.
"""

from __future__ import annotations

import os
import struct

from ...errors import SceneError
from ..files import open_regular
from ..system import count_text, format_bytes, memory_allowed

# Bytes per triangle of reading a mesh file and holding it for a flat render: renderer.budget.FLAT_BYTES, the
# measured figure (a test keeps the two equal; here so framing, below the renderer, can check a read).
MESH_READ_BYTES = 270
SMALLEST_TRIANGLE = 6  # bytes a triangle takes at least in any format: the size bound of a file not counted


def count_triangles(mesh) -> int:
    """Triangles in the mesh file of `mesh` (a MeshSource), read cheaply by its format (PLY and OFF headers,
    binary STL's count, OBJ's face corners, glTF's accessor counts), else by file size (SMALLEST_TRIANGLE);
    where the file's vertices outnumber its triangles, its vertices (less 2): unused vertices cost memory too.
    0 for a missing file (the read reports it); a FIFO, device or folder is refused here, and so is a binary
    STL whose size does not match its header's count (SceneError)."""
    try:
        handle = open_regular(mesh.path, mesh.where, "mesh file")
    except FileNotFoundError:
        return 0
    with handle:
        size = os.fstat(handle.fileno()).st_size
        try:
            found = mesh.format.count(handle, size, mesh)
        except SceneError:
            raise
        except (ValueError, KeyError, IndexError, TypeError, struct.error, OSError, RecursionError):
            found = None  # a malformed header: the size bound; the read reports the real problem
    return size // SMALLEST_TRIANGLE if found is None else found


def read_floor(mesh) -> int:
    """The least memory reading the file costs, from its size and format alone (0 if it is not there): the
    floor under the triangle count's estimate for a file that claims little and is large."""
    try:
        size = mesh.path.stat().st_size
    except OSError:
        return 0
    return mesh.format.floor(mesh.path, size, mesh)


def check_mesh_read(mesh, max_memory: int | None = None) -> None:
    """Refuse (SceneError, one line) to read a mesh file (`mesh`: its MeshSource) for framing (scene.framing,
    before any render and so before renderer.budget.check_memory) when the read alone could not fit in the
    memory available now (io.system.available_memory: cgroup and `ulimit -v`; and `max_memory`, the command's
    --max-memory): the file's size × its parse (read_floor, checked first, so a huge file is never scanned), or
    its triangles (from the header) × the flat render's bytes per triangle and the format's parse."""
    available = memory_allowed(max_memory)
    floor = read_floor(mesh)  # from the size alone: a huge file is refused before any byte is read
    triangles = 0 if available is not None and floor > available else mesh.triangles()
    need = max(triangles * (MESH_READ_BYTES + mesh.format.parse_bytes), floor)
    if available is not None and need > available:
        external, unzipped = mesh.format.held(mesh.path, mesh)  # said only when refused
        what = (f"{count_text(triangles)} triangles" if triangles else f"{format_bytes(mesh.path.stat().st_size)}"
                + (f" and {format_bytes(external)} of buffers" if external else "")
                + (f" ({format_bytes(unzipped)} unzipped)" if unzipped else ""))
        raise SceneError(f"reading its {what} needs ≈ {format_bytes(need)} of memory, more than the "
                         f"{format_bytes(available)} available; allowed: a mesh whose size and triangles fit, "
                         "so decimate it or free memory", mesh.where)
