"""A plain OBJ (only `v x y z` and `f a b c` lines, comments and blank lines: how scanners and trimesh write a
scan) read in one compiled pass, into what trimesh's reader gives for it.

trimesh's OBJ reader spends Python per face line (split, strip, a check of every line's width): 2.5 s of the
3 s bunny-1m's 1.1M faces took. Here one compiled scan (`_records`) proves the file plain, gathers the `v` lines'
text and reads the face indices (decimal integers: exact); the coordinates are converted by the very numpy call
trimesh's reader makes (np.fromstring of the `v` lines' text), so they carry its bits; the vertices no face
names are dropped and the faces renumbered as trimesh does. Any other record (`vt`, `vn`, `usemtl`, `o`, `g`,
`s`, polygons, `v/vt` corners, relative or zero indices, a coordinate that is not a plain number) leaves the
file to the full reader (io/meshes/obj.py), which words every problem.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...jit import kernel
from .decimals import POWERS, decimal, line_end, numeric, numpy_rows
from .format import Part

SPACE, TAB, HASH = 32, 9, 35
PLAIN_KERNELS = ("_records",)  # what reading a plain OBJ compiles (renderer/warmup.py loads it first)


@kernel()
def _records(data, mode, powers, points, vertex_text, faces):
    """One pass over OBJ text `data` (uint8). Returns (plain, vertices, faces, text bytes, exact): whether every
    line is blank, a comment (`#` first), `v` + a space + three words of `numeric` bytes, or `f` + a space + three
    decimal integers of at most 18 digits, words separated by spaces or tabs (lines end in LF or CRLF); the
    counts; and whether every coordinate was read exactly by decimals.decimal. mode 0 counts; 1 also reads each face's
    indices, less one, into faces (F, 3) int64 and the coordinates into points (V, 3) float64; 2 instead copies
    each `v` line's text after its `v` (its leading space included) into vertex_text, for numpy to read."""
    n = data.shape[0]
    vertices = count = written = 0
    exact = True
    at = 0
    while at < n:
        end, stop = line_end(data, at)
        if stop > at and data[at] != HASH:
            if stop - at < 2 or data[at + 1] != SPACE:
                return False, vertices, count, written, exact
            kind = data[at]
            if kind != 118 and kind != 102:  # neither "v" nor "f"
                return False, vertices, count, written, exact
            i, words = at + 2, 0
            while True:
                while i < stop and (data[i] == SPACE or data[i] == TAB):
                    i += 1
                if i == stop:
                    break
                start, value = i, 0
                while i < stop and data[i] != SPACE and data[i] != TAB:
                    c = data[i]
                    if kind == 118:
                        if not numeric(c):
                            return False, vertices, count, written, exact
                    elif c < 48 or c > 57 or i - start >= 18:
                        return False, vertices, count, written, exact
                    else:
                        value = 10 * value + (c - 48)
                    i += 1
                if words == 3:
                    return False, vertices, count, written, exact
                if kind == 102:
                    if value == 0:  # index 0 names nothing: the full reader refuses it in words
                        return False, vertices, count, written, exact
                    if mode == 1:
                        faces[count, words] = value - 1
                elif mode == 1 and exact:
                    number, exact = decimal(data, start, i, powers)
                    points[vertices, words] = number
                words += 1
            if words != 3:
                return False, vertices, count, written, exact
            if kind == 118:
                if mode == 2:
                    for k in range(stop - at - 1):  # a loop: a slice assignment compiles its error text
                        vertex_text[written + k] = data[at + 1 + k]
                written += stop - at - 1
                vertices += 1
            else:
                count += 1
        at = end + 1
    return True, vertices, count, written, exact


HEAD = 1 << 20  # bytes of a file's start the warm-up looks at (renderer/warmup.py)


def may_be_plain(data: bytes) -> bool:
    """False when `data` (a whole OBJ, or its start) continues a line or names a material (in a comment too:
    trimesh's reader acts on it): the full reader's file, with no compiled scan here."""
    return not (b"\\" in data or b"usemtl" in data or b"mtllib" in data)


def plain_obj(data: bytes, path: Path):
    """The one Part of a plain OBJ's bytes `data` (module docstring), as io/obj.load_obj gives it for the same
    file (which names no materials): no trimesh; None for any other OBJ (the full reader's)."""
    if b"f" not in data or not may_be_plain(data):
        return None
    text = np.frombuffer(data, np.uint8)
    no_points, no_text, no_faces = np.empty((0, 3)), np.empty(0, np.uint8), np.empty((0, 3), np.int64)
    plain, vertex_count, face_count, size, _ = _records(text, 0, POWERS, no_points, no_text, no_faces)
    if not plain or not face_count:
        return None
    points, faces = np.empty((vertex_count, 3)), np.empty((face_count, 3), np.int64)
    exact = _records(text, 1, POWERS, points, no_text, faces)[4]
    if not exact:  # a coordinate beyond the fast path: numpy reads them all, as trimesh's reader did
        points = _numpy_points(text, size, vertex_count)
        if points is None:
            return None
    if not faces.max() < vertex_count:
        return None
    used = np.zeros(vertex_count, dtype=bool)
    used[faces] = True
    inverse = np.zeros(vertex_count, dtype=np.int64)
    inverse[used] = np.arange(used.sum())
    return Part(points[used], inverse[faces], None, None)  # the vertices faces use, as trimesh's reader keeps them


def _numpy_points(text: np.ndarray, size: int, count: int) -> np.ndarray | None:
    """The `v` lines' coordinates (count, 3) by the numpy call trimesh's reader makes; None where that reader
    would read other numbers (it rewrites `+e` and `-e`) or numpy stops short of them."""
    vertex_text = np.empty(size, np.uint8)
    _records(text, 2, POWERS, np.empty((0, 3)), vertex_text, np.empty((0, 3), np.int64))
    vertex_text = vertex_text.tobytes()
    return None if b"+e" in vertex_text or b"-e" in vertex_text else numpy_rows(vertex_text, count, 3)


def warm_up() -> None:
    """Load (or compile) PLAIN_KERNELS: a plain triangle, counted and filled."""
    plain_obj(b"# a triangle\nv 0 0 0\nv 1 0 0\r\nv 0 1 0\n\nf 1 2 3\n", Path("warm-up.obj"))
