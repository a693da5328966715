"""A binary PLY whose lists differ in length from row to row (a quad beside a triangle), made into one trimesh reads.

PLY lets every row of a list property hold its own count (Greg Turk's PLY format: "property list uchar int
vertex_indices", one polygon per face of any size). trimesh's binary reader takes the first row's count for
every row, so a mesh of quads and triangles is refused as "unexpected length" (or, where the sizes happen to
add up, misread). Here such a file is rewritten before trimesh reads it: one compiled walk (ply_rows.py) finds
every row's start and counts, then the `face` element becomes triangles, each polygon cut by polygons.cut (a
fan from its first corner, or ear clipping when concave), each triangle keeping its face's other properties and
its corners' entries of per-corner lists (`texcoord`: two per corner). A `tristrips` element becomes one strip
(its rows joined by the -1 that separates strips). Any other element with uneven lists is left out, noted.
Files whose lists are even (almost all) are not touched and compile nothing, unless they hold a concave
polygon (their polygons of four or more corners are tested: a few numpy passes)."""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass

import numpy as np

from .polygons import cut, fan, listed

# The PLY scalar types (Paul Bourke's PLY format, and the sized names rply and MeshLab write), as numpy kinds.
PLY_DTYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
PLY_SIZES = {name: np.dtype(kind).itemsize for name, kind in PLY_DTYPES.items()}
POLYGON = ("vertex_indices", "vertex_index")  # the face list the specification names (and its common variant)


@dataclass(frozen=True)
class Property:
    name: str
    type: str                  # a PLY_DTYPES key: the value's, or a list entry's
    count: str | None = None   # a list's count type; None for a scalar


@dataclass(frozen=True)
class Element:
    name: str
    rows: int
    properties: tuple[Property, ...]
    lines: tuple[bytes, ...]   # its header lines, as written


@dataclass(frozen=True)
class Header:
    format: str                # "ascii", "binary_little_endian" or "binary_big_endian"
    elements: tuple[Element, ...]
    before: bytes              # the header's lines before the first element (ply, format, comments)
    body: int                  # where the data starts


def header(data: bytes) -> Header | None:
    """The header of a PLY (`data`: the file, or its start), or None when it does not parse: ply_problem then
    names the bad line."""
    end = data.find(b"end_header")
    stop = data.find(b"\n", end)
    if end < 0 or stop < 0:
        return None
    form, before, elements = None, [], []
    for raw in data[:end].split(b"\n"):
        words = raw.decode("latin-1").split()
        if words[:1] == ["format"] and len(words) >= 2:
            form = words[1]
        if words[:1] == ["element"]:
            if len(words) != 3 or not words[2].isdigit():
                return None
            elements.append((words[1], int(words[2]), [], [raw]))
        elif words[:1] == ["property"] and elements:
            scalar = len(words) == 3 and words[1] in PLY_DTYPES
            listed = len(words) == 5 and words[1] == "list" and words[2] in PLY_DTYPES and words[3] in PLY_DTYPES
            if not (scalar or listed):
                return None
            elements[-1][2].append(Property(words[2], words[1]) if scalar else Property(words[4], words[3], words[2]))
            elements[-1][3].append(raw)
        elif not elements:
            before.append(raw)
    if form not in ("ascii", "binary_little_endian", "binary_big_endian"):
        return None
    return Header(form, tuple(Element(name, rows, tuple(props), tuple(lines)) for name, rows, props, lines in elements),
                  b"\n".join(before), stop + 1)


def _dtype(kind: str, big: bool) -> np.dtype:
    return np.dtype(PLY_DTYPES[kind]).newbyteorder(">" if big else "<")


def _even(element: Element, body: memoryview, at: int, big: bool) -> tuple[np.ndarray, int] | None:
    """The element's rows as trimesh would read them (every list as long as its first row's), with where it
    ends, when every row's counts are indeed the first row's; None when they differ, a list is empty (rewritten
    by evened) or the data is short."""
    fields, offset = [], 0
    for k, prop in enumerate(element.properties):
        if prop.count is None:
            fields.append((f"p{k}", _dtype(prop.type, big)))
            offset += fields[-1][1].itemsize
            continue
        size = PLY_SIZES[prop.count]
        if at + offset + size > len(body):
            return None
        first = int(np.frombuffer(body, _dtype(prop.count, big), 1, at + offset)[0])
        if first <= 0:  # negative, or empty: trimesh's reader refuses a list of length 0, the row walk drops it
            return None
        fields += [(f"c{k}", _dtype(prop.count, big)), (f"p{k}", _dtype(prop.type, big), (first,))]
        offset += size + first * fields[-1][1].itemsize
    row = np.dtype(fields)
    if at + element.rows * row.itemsize > len(body):
        return None
    rows = np.frombuffer(body, row, element.rows, at)
    if any(name.startswith("c") and not (rows[name] == rows[name][:1]).all() for name in row.names):
        return None
    return rows, at + element.rows * row.itemsize


def element_rows(element: Element, data: np.ndarray, at: int, big: bool):
    """The element's row starts and list counts, by ply_rows.walk_rows; None when its rows do not fit the data."""
    props = element.properties
    sizes = np.array([PLY_SIZES[p.type] if p.count is None else 0 for p in props], np.int64)
    counts = np.array([0 if p.count is None else PLY_SIZES[p.count] for p in props], np.int64)
    entries = np.array([PLY_SIZES[p.type] for p in props], np.int64)
    signed = np.array([p.count is not None and PLY_DTYPES[p.count][0] == "i" for p in props], np.bool_)
    starts = np.empty(element.rows + 1, np.int64)
    found = np.zeros((element.rows, max(1, int((counts > 0).sum()))), np.int64)
    from .ply_rows import walk_rows  # compiled: imported only for a file that needs it (numba's import is slow)
    if not walk_rows(data, at, element.rows, sizes, counts, entries, signed, big, starts, found):
        return None
    return starts, found


def _gather(data: np.ndarray, starts: np.ndarray, width: int) -> np.ndarray:
    """`width` bytes from each of `starts` (rows × width uint8)."""
    return data[starts[:, None] + np.arange(width)]


FACE_CHUNK = 1 << 18  # faces rewritten at a time: the gathers' int64 index arrays stay tens of MB


def _triangles(element: Element, data: np.ndarray, starts: np.ndarray, found: np.ndarray, big: bool,
               notes: list[str], points: np.ndarray | None) -> tuple[tuple[bytes, ...], bytes] | None:
    """The face element as triangles: each polygon cut by polygons.cut (a fan, or ear-clipped when concave and
    the vertex `points` are known); None when it has no polygon
    list. Scalars are repeated per triangle; a list of one or two entries per corner keeps its triangle's
    corners'; any other list is left out, noted. FACE_CHUNK faces at a time."""
    props = element.properties
    lists = [k for k, p in enumerate(props) if p.count is not None]
    polygon = next((k for k in lists if props[k].name in POLYGON), None)
    if polygon is None:
        return None
    corners = found[:, lists.index(polygon)]
    kept = []
    for k, prop in enumerate(props):
        length = found[:, lists.index(k)] if prop.count is not None else None
        each = int(length[0] // max(int(corners[0]), 1)) if length is not None and len(length) else 1
        if prop.count is None or (each in (1, 2) and (length == each * corners).all()):
            kept.append(k)
        else:
            notes.append(f"its face list {prop.name!r} is not one or two entries a corner; it is left out")
    chunks = [_fan_rows(props, kept, lists, data, starts[:-1][rows], found[rows], corners[rows], big, points)
              for rows in (slice(first, first + FACE_CHUNK) for first in range(0, len(corners), FACE_CHUNK))]
    triangles = int(np.maximum(corners - 2, 0).sum())
    lines = (f"element {element.name} {triangles}".encode(), *(element.lines[1 + k] for k in kept))
    return lines, b"".join(chunks)


def _fan_rows(props, kept: list[int], lists: list[int], data: np.ndarray, starts: np.ndarray, found: np.ndarray,
              corners: np.ndarray, big: bool, points: np.ndarray | None) -> bytes:
    """The bytes of the triangles of some faces (their row `starts`, list counts `found` and `corners`): each
    kept property of each face, for each of its triangles (_triangles)."""
    polygon = next(k for k in lists if props[k].name in POLYGON)
    at = starts.copy()  # where the polygon list starts in each row
    for k, prop in enumerate(props[:polygon]):
        size = PLY_SIZES[prop.type]
        at += size if prop.count is None else PLY_SIZES[prop.count] + found[:, lists.index(k)] * size
    at += PLY_SIZES[props[polygon].count]
    entry = _dtype(props[polygon].type, big)

    def vertex_of(faces: np.ndarray, k: int) -> np.ndarray:
        return _gather(data, at[faces] + k * entry.itemsize, entry.itemsize).view(entry)[:, 0].astype(np.int64)

    row, picks = cut(corners, vertex_of, points)
    offsets = starts.copy()  # where each row's next property starts
    columns = []
    for k, prop in enumerate(props):
        entry = PLY_SIZES[prop.type]
        if prop.count is None:
            if k in kept:
                columns.append(_gather(data, offsets[row], entry))
            offsets += entry
            continue
        width = PLY_SIZES[prop.count]
        length = found[:, lists.index(k)]
        if k in kept:
            each = int(length[0] // max(int(corners[0]), 1)) if len(length) else 1
            count = np.array(3 * each, _dtype(prop.count, big)).tobytes()
            at = (offsets[row] + width)[:, None, None] + (picks * each * entry)[:, :, None] + np.arange(each * entry)
            columns += [np.frombuffer(count * len(row), np.uint8).reshape(len(row), width),
                        data[at.reshape(len(row), -1)]]
        offsets += width + length * entry
    return (np.concatenate(columns, axis=1) if columns else np.zeros((len(row), 0), np.uint8)).tobytes()


def _points(element: Element, rows: np.ndarray, axes=("x", "y", "z")) -> np.ndarray | None:
    """(V, 3) float64 x, y, z (or other `axes`: nx, ny, nz) of an even vertex element's rows, or None when it has
    no such scalars."""
    names = {prop.name: f"p{k}" for k, prop in enumerate(element.properties) if prop.count is None}
    if not set(axes) <= names.keys():
        return None
    return np.column_stack([rows[names[axis]] for axis in axes]).astype(np.float64)


def _concave(element: Element, rows: np.ndarray, points: np.ndarray | None) -> bool:
    """Whether an even face element (its `rows`) holds a concave polygon of 4 or more corners."""
    polygon = next((k for k, p in enumerate(element.properties) if p.count is not None and p.name in POLYGON), None)
    if points is None or polygon is None or rows[f"p{polygon}"].ndim < 2 or rows[f"p{polygon}"].shape[1] < 4:
        return False
    corners = rows[f"p{polygon}"]
    sizes = np.full(len(corners), corners.shape[1])
    _, picks = cut(sizes, lambda faces, k: corners[faces, k].astype(np.int64), points)
    return bool((picks != fan(sizes)[1]).any())


def _strip(element: Element, data: np.ndarray, starts: np.ndarray, found: np.ndarray,
           big: bool) -> tuple[tuple[bytes, ...], bytes] | None:
    """A tristrips element of uneven rows as one row: the strips joined by -1 (the specification's separator),
    its count an int. None when it is not one list of indices."""
    if len(element.properties) != 1 or element.properties[0].count is None or not element.rows:
        return None
    prop = element.properties[0]
    entry = _dtype(prop.type, big)
    width = PLY_SIZES[prop.count]
    pieces = []
    for row in range(element.rows):  # a strips element has a few rows (one, usually)
        values = np.frombuffer(data, entry, int(found[row, 0]), int(starts[row]) + width).astype(np.int64)
        pieces += [values, np.array([-1], np.int64)]
    joined = np.concatenate(pieces[:-1]).astype(_dtype("int", big))
    lines = (f"element {element.name} 1".encode(), f"property list int int {prop.name}".encode())
    return lines, np.array(len(joined), _dtype("int", big)).tobytes() + joined.tobytes()


def ascii_rows(data: bytes, found: Header) -> dict[str, dict[str, np.ndarray]] | None:
    """An ASCII PLY's `vertex` element (scalars, one row a line) and `face` element (one list of three indices a
    row, nothing else), in that order, as _even gives a binary one's columns: {"vertex": {"p0": ..., ...},
    "face": {"p0": (rows, 3)}}, each column in its declared type. The numbers are read as trimesh reads them
    (float64, then the declared type), by _rows; None for any other layout (a polygon, a comment or a short
    line, CR-only line ends), which trimesh reads."""
    if [element.name for element in found.elements] != ["vertex", "face"]:
        return None
    vertex, face = found.elements
    if not vertex.rows or not face.rows or any(prop.count is not None for prop in vertex.properties) \
            or len(face.properties) != 1 or face.properties[0].count is None:
        return None
    read = _rows(data, found.body, vertex.rows, len(vertex.properties), face.rows)
    if read is None:
        return None
    points, faces = read
    if not (faces[:, 0] == 3).all() or not np.isfinite(faces).all():
        return None
    # Indices as int64, not their declared type: one past that type's range is then refused as out of range by
    # the read's check, not wrapped round to another vertex as trimesh's cast does.
    corners = faces[:, 1:].astype(np.int64)
    with np.errstate(over="ignore", invalid="ignore"):  # 5e38 as a float is inf, as trimesh casts it: the read
        return {"vertex": {f"p{k}": points[:, k].astype(PLY_DTYPES[prop.type])  # check then says so, no warning
                           for k, prop in enumerate(vertex.properties)}, "face": {"p0": corners}}


def _rows(data: bytes, start: int, rows: int, width: int, faces: int) -> tuple[np.ndarray, np.ndarray] | None:
    """(points (rows × width), faces (faces × 4)) float64 of an ASCII PLY's two sections from byte `start`, one
    row a line: one compiled pass (decimals.lines_of_numbers) finds the lines and reads every word on the exact
    path, the bits numpy's parse gives; a section holding any other word is parsed by numpy, as trimesh parses
    it. None when a line holds another count of words (or the file is too short for the rows: nothing allocated)."""
    if 2 * max(width, 1) * rows + 8 * faces - 1 > len(data) - start:
        return None
    from .decimals import lines_of_numbers, numpy_rows  # compiled: only for an ASCII PLY (numba's import is slow)
    text = np.frombuffer(data, np.uint8)
    sections, at = [], start
    for count, each in ((rows, width), (faces, 4)):
        read = lines_of_numbers(text, at, count, False, count * each, False)
        if read is None or (read[0] != each).any():
            return None
        values = read[1].reshape(count, each) if read[1] is not None else numpy_rows(data[at:read[2]], count, each)
        if values is None:
            return None
        sections.append(values)
        at = read[2]
    return sections[0], sections[1]


def warm_up() -> None:
    """Load (or compile) decimals.number_lines: a two-line section read."""
    _rows(b"0 1\n3 0 0 0\n", 0, 1, 2, 1)


def evened(data: bytes, found: Header | None, notes: list[str]) -> bytes | None:
    """`data`, a binary PLY (its parsed `found` header), rewritten so every list of an element has one length
    and every concave polygon is ear-clipped (polygons.cut, with the vertex positions when the vertex element
    comes first and is even) (module docstring); None when it needs no rewriting (ASCII, no lists, even
    convex lists) or its rows do not fit its size (the reader then says so). Notes name what was left out."""
    if found is None or found.format == "ascii" or not any(p.count for e in found.elements for p in e.properties):
        return None
    big = found.format == "binary_big_endian"
    view, raw = memoryview(data), np.frombuffer(data, np.uint8)
    at, uneven, parts, points = found.body, False, [], None
    for element in found.elements:
        even = _even(element, view, at, big)
        if even is not None and not (element.name == "face" and _concave(element, even[0], points)):
            parts.append((element.lines, data[at:even[1]]))
            at = even[1]
            points = _points(element, even[0]) if element.name == "vertex" else points
            continue
        walked = element_rows(element, raw, at, big)
        if walked is None:
            return None
        uneven, (starts, counts) = True, walked
        made = (_triangles(element, raw, starts, counts, big, notes, points) if element.name == "face"
                else _strip(element, raw, starts, counts, big) if element.name == "tristrips" else None)
        if made is None:
            notes.append(f"its element {element.name!r} has lists of uneven length; it is left out")
        else:
            parts.append(made)
        at = int(starts[-1])
    if not uneven:
        return None
    lines = [found.before, *(line for element_lines, _ in parts for line in element_lines), b"end_header", b""]
    return b"\n".join(lines) + b"".join(body for _, body in parts)


def ascii_cut(data: bytes, found: Header | None) -> bytes | None:
    """`data`, an ASCII PLY (its parsed `found` header), with each concave polygon's line replaced by one line
    per triangle (polygons.cut), the face count raised to match; None when there is none or the file is not
    the plain form this reads (a vertex element of scalars with x, y, z, then a face element whose first
    property is the polygon list and the rest scalars, one row a line). trimesh reads the rest, fanning the
    convex polygons as polygons.cut would."""
    if found is None or found.format != "ascii" or [e.name for e in found.elements][:2] != ["vertex", "face"]:
        return None
    vertex, face = found.elements[:2]
    props = face.properties
    if (any(p.count for p in vertex.properties) or not props or props[0].count is None
            or props[0].name not in POLYGON or any(p.count for p in props[1:]) or not vertex.rows or not face.rows):
        return None
    body = data[found.body:]
    feeds = np.flatnonzero(np.frombuffer(body, np.uint8) == 10)
    if len(feeds) < vertex.rows:
        return None
    start = int(feeds[vertex.rows - 1]) + 1
    stop = int(feeds[vertex.rows + face.rows - 1]) if len(feeds) >= vertex.rows + face.rows else len(body)
    section = body[start:stop]
    if not re.search(rb"(?m)^[ \t]*(?!3[ \t\r]|3$)\d", section):
        return None  # triangles only: nothing to cut (a text scan, no parse)
    names = [p.name for p in vertex.properties]
    if not {"x", "y", "z"} <= set(names):
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a word that is not a number: left to trimesh, which says so
        try:
            table = np.fromstring(body[:start], sep=" ")
            values = np.fromstring(section, sep=" ")
        except ValueError:  # numpy 2 refuses the word where numpy 1 warned
            return None
    lines = section.split(b"\n")
    words = np.array([len(line.split()) for line in lines], np.int64)
    if table.size != vertex.rows * len(names) or values.size != words.sum() or len(lines) != face.rows:
        return None
    points = table.reshape(vertex.rows, len(names))[:, [names.index(axis) for axis in "xyz"]]
    first = np.cumsum(words) - words
    corners = values[first].astype(np.int64)
    if (corners < 0).any() or (corners + 1 > words).any() or not np.isfinite(values).all():
        return None
    row, picks = cut(corners, listed(values, first + 1, points), points)
    concave = np.unique(row[(picks != fan(corners)[1]).any(axis=1)])
    if not len(concave):
        return None
    for polygon in concave.tolist()[::-1]:
        tokens = lines[polygon].split()
        corner, rest = tokens[1:1 + corners[polygon]], b" ".join(tokens[1 + corners[polygon]:])
        lines[polygon] = b"\n".join(b" ".join([b"3", *(corner[c] for c in triangle), rest]).rstrip()
                                    for triangle in picks[row == polygon].tolist())
    added = int((corners[concave] - 3).sum())
    head = data[:found.body].replace(face.lines[0], f"element face {face.rows + added}".encode(), 1)
    return head + body[:start] + b"\n".join(lines) + body[stop:]
