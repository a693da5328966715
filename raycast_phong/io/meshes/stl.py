"""STL: a binary STL is read here rather than by trimesh, its records straight into float32 corner points; an
ASCII STL in the form exporters write by one compiled scan (stl_ascii.py), any other by trimesh, and one trimesh
cannot read has its first bad `vertex` line named (ascii_stl_problem)."""

from __future__ import annotations

import os
import re
import struct
from contextlib import suppress

import numpy as np

from ...errors import SceneError
from .content import is_number
from .format import TEXT_READ_BYTES_PER_BYTE, Loaded, MeshFormat, Part, Reading

STL_RECORD = np.dtype([("normal", "<f4", 3), ("points", "<f4", (3, 3)), ("attribute", "<u2")])  # 50 bytes
RECORDS_READ = 1 << 16  # records a read of a binary STL takes at a time (3.2 MB)


def binary_stl_points(handle) -> np.ndarray | None:
    """A binary STL's corner points (3F, 3) float32 in file order (corner k of triangle f at row 3f + k), or None
    if the file is not one (an ASCII STL: its size does not match the header's count) or holds no triangle.

    The values trimesh's reader gives, without its float64 (3F, 3) copy (72 bytes a triangle) and the hashing
    its Trimesh does to validate the file's face normals (0.25 s at 1M triangles); the normals (the renderer
    computes its own), the attribute bytes and the 80-byte header are not kept, as trimesh keeps none of them
    for shading. The records are read RECORDS_READ at a time into one small buffer, their points copied out (36
    bytes a triangle), so no buffer of the whole file (50 bytes a triangle) is touched."""
    handle.seek(0)
    head = handle.read(84)
    count = int.from_bytes(head[80:84], "little")
    if count == 0 or not is_binary(head, os.fstat(handle.fileno()).st_size):
        handle.seek(0)
        return None
    points = np.empty((count, 3, 3), np.float32)
    records = np.empty(min(count, RECORDS_READ), STL_RECORD)
    for start in range(0, count, RECORDS_READ):
        some = records[:min(RECORDS_READ, count - start)]
        if handle.readinto(some.view(np.uint8)) != some.nbytes:
            handle.seek(0)
            return None  # the file shrank under us: let trimesh word it
        points[start:start + len(some)] = some["points"]
    return points.reshape(-1, 3)


VERTEX_LINES = re.compile(rb"^[ \t]*vertex(?![^ \t\r\n])([^\n]*)", re.M | re.I)


def ascii_stl_problem(data: bytes) -> str | None:
    """What stops an ASCII STL being read, in words naming its line, when trimesh could not read it: the first
    `vertex` line that is not three numbers (openscad's invalidvertex.stl: `vertex 0 0 blah`; unparseable.stl: a
    control byte among them); None when every vertex line is three numbers."""
    for found in VERTEX_LINES.finditer(data):
        words = found[1].split()
        bad = next((word for word in words if not is_number(word)), None)
        if bad is not None or len(words) != 3:
            line = data.count(b"\n", 0, found.start()) + 1
            given = (f"{bad.decode('latin-1')[:40]!r} is not a number" if bad is not None
                     else f"it gives {len(words)} number(s)")
            return f"line {line}: a vertex needs three numbers (x y z), and {given}"
    return None


def read(reading: Reading) -> Loaded:
    """A binary STL's corners in file order, as trimesh's reader gives them (without its float64); a plain ASCII
    STL by one compiled pass (stl_ascii.py), the same; any other through trimesh."""
    points = binary_stl_points(reading.handle)
    if points is None:
        from .stl_ascii import plain_stl  # compiled: imported only for an ASCII STL (numba's import is slow)
        plain = plain_stl(reading.handle.read())
        if plain is not None:
            return Loaded([plain])
        reading.handle.seek(0)
        from .trimesh_parts import load, parts
        return Loaded(parts(load(reading)))
    return Loaded([Part(points, np.arange(len(points), dtype=np.int64).reshape(-1, 3), None, None)])


def is_binary(head: bytes, size: int) -> bool:
    """Whether an STL of `size` bytes starting with `head` is binary: its size is 84 + 50 × its header's count."""
    return len(head) >= 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little")


def count(handle, size: int, mesh) -> int:
    """A binary STL's header count (a size that does not match it is refused: corrupt or cut short), or an
    ASCII STL's most facets: the shortest ("facet normal 0 0 0\nouter loop\n…") is 86 bytes."""
    head = handle.read(4096)
    if size >= 84 and (not head.lstrip().startswith(b"solid") or is_binary(head, size)):
        triangles = struct.unpack_from("<I", head, 80)[0]
        if size != 84 + 50 * triangles:
            raise SceneError(f"a binary STL whose header counts {triangles:,} triangles ({84 + 50 * triangles:,} "
                             f"bytes) but which has {size:,} bytes: the file is corrupt or cut short; allowed: "
                             "84 + 50 × its count bytes", mesh.where)
        return triangles
    return size // 86


# A binary STL's records (its size) and the points and faces copied out of them (72% and 48% of it).
BINARY_STL_READ_BYTES_PER_BYTE = 3


def floor(path, size: int, mesh) -> int:
    from ..files import open_regular
    head = b""
    with suppress(OSError, SceneError), open_regular(path, str(path), "mesh file") as handle:
        head = handle.read(84)
    return size * (BINARY_STL_READ_BYTES_PER_BYTE if is_binary(head, size) else TEXT_READ_BYTES_PER_BYTE)


def warm_up(handle) -> tuple:
    """The ASCII scan's kernel for a text STL; none for a binary one (read by numpy)."""
    from . import stl_ascii
    head = handle.read(84)
    return () if is_binary(head, os.fstat(handle.fileno()).st_size) else (stl_ascii.warm_up,)


FORMAT = MeshFormat(
    names=("STL",), suffixes=(".stl",), read=read, count=count, floor=floor, warm_up=warm_up,
    explain=lambda handle, mesh: ascii_stl_problem(handle.read()),
    # A binary STL is told by its size; any text may be an ASCII STL ("solid") or unrecognised.
    content=lambda head, found, size, suffix: is_binary(head, size) or found in ("ASCII STL", None),
    # Binary: 50-byte records, then 36 + 24 bytes a triangle of points and faces, below the render's peak
    # (bunny-1m phong 279 B/triangle against the PLY's 287, flat 215 against 270, 8×8, one thread).
    parse_bytes=30)
