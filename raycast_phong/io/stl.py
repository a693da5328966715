"""Binary STL, read here rather than by trimesh: its records straight into float32 corner points. An ASCII STL
trimesh cannot read has its first bad `vertex` line named (ascii_stl_problem)."""

from __future__ import annotations

import os
import re

import numpy as np

from .mesh_content import is_number

STL_RECORD = np.dtype([("normal", "<f4", 3), ("points", "<f4", (3, 3)), ("attribute", "<u2")])  # 50 bytes


def binary_stl_points(handle) -> np.ndarray | None:
    """A binary STL's corner points (3F, 3) float32 in file order (corner k of triangle f at row 3f + k), or None
    if the file is not one (an ASCII STL: its size does not match the header's count) or holds no triangle.

    The values trimesh's reader gives, without its float64 (3F, 3) copy (72 bytes a triangle) and the hashing
    its Trimesh does to validate the file's face normals (0.25 s at 1M triangles); the normals (the renderer
    computes its own), the attribute bytes and the 80-byte header are not kept, as trimesh keeps none of them
    for shading. The records are read into one array (50 bytes a triangle), their points copied out (36)."""
    handle.seek(0)
    head = handle.read(84)
    size = os.fstat(handle.fileno()).st_size
    count = int.from_bytes(head[80:84], "little") if len(head) == 84 else 0
    if count == 0 or size != 84 + STL_RECORD.itemsize * count:
        handle.seek(0)
        return None
    records = np.empty(count, STL_RECORD)
    if handle.readinto(records.view(np.uint8)) != count * STL_RECORD.itemsize:
        handle.seek(0)
        return None  # the file shrank under us: let trimesh word it
    return np.ascontiguousarray(records["points"], np.float32).reshape(-1, 3)



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

