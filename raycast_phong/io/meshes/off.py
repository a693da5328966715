"""OFF, Geomview's Object File Format, read here from its specification (geomview.org, "OFF Files"):

    [ST][C][N][4][n]OFF [BINARY]     the header keyword (optional in text: a file may start at its counts)
    [Ndim]                           only for nOFF
    NVertices NFaces NEdges
    x y z [nx ny nz] [r g b [a]] [s t]        a vertex line, in that order for the N, C and ST prefixes
    Nv v[0] ... v[Nv-1] [colorspec]           a face line: a polygon of any size; colorspec to the end of the line
                                              is none, a colormap index, or 3-4 numbers (0..255, or 0..1 floats)

A face is cut as a fan from its first corner, or by ear clipping when concave (polygons.py). Vertex colours
(C) and face colours (3 or 4 numbers) become the file's colours; normals (N) are kept. `BINARY`: the same
records as big-endian int32 and float32, a face's colour as a count then that many floats, or the
little-endian dialect without the colour count (byte_order). A 4OFF or nOFF file (vertices in 4 or n
dimensions) and texture coordinates without a texture are read without what they add, with a note.
trimesh's reader read only `OFF` and `COFF` (not the header-less form, NOFF's normals, colours or
`OFF BINARY`) at about 9 µs a triangle.
"""

from __future__ import annotations

import re
import warnings

import numpy as np

from ...errors import SceneError
from .content import is_number
from .format import Loaded, MeshFormat, Part, Reading, weigh
from .materials import PartSurface
from .polygons import cut, listed

HEADER = re.compile(rb"(ST)?(C)?(N)?(4)?(n)?OFF")
COMMENT = re.compile(rb"#[^\n]*")
NUMBER = re.compile(rb"[-+]?(\d|\.\d)")


def _start(data: bytes) -> int:
    """Where the first word that is not a comment starts (comments run from # to the line's end)."""
    at = 0
    while True:
        at = len(data) - len(data[at:].lstrip()) if at < len(data) else at
        if data[at:at + 1] != b"#":
            return at
        end = data.find(b"\n", at)
        if end < 0:
            return len(data)
        at = end + 1


def _keyword(data: bytes) -> tuple[re.Match | None, int, bool]:
    """The header keyword (None for a text file that starts at its counts), where what follows it starts, and
    whether that is `BINARY` (the rest of the keyword's line)."""
    at = _start(data)
    found = HEADER.match(data, at)
    at = found.end() if found else at
    return found, at, found is not None and data[at:at + 80].split(b"\n", 1)[0].split()[:1] == [b"BINARY"]


def read(reading: Reading) -> Loaded:
    data = reading.handle.read()
    try:
        vertices, faces, normals, colours, per_face = parse(data, reading.notes, str(reading.path))
    except SceneError as refused:  # the problem alone (parse knows no path): worded here with the file
        raise SceneError(f"{str(reading.path)!r} {refused.problem}", reading.where) from None
    return Loaded([Part(vertices, faces, normals, _visual(colours, per_face, faces))])


def _visual(colours: np.ndarray | None, per_face: bool, faces: np.ndarray) -> PartSurface | None:
    """The colours as every reader gives them: RGB in [0, 1] at each face corner (8-bit / 255)."""
    if colours is None:
        return None
    rgb = colours[:, :3].astype(np.float32) / 255.0
    return PartSurface(corner_colour=np.repeat(rgb[:, None, :], 3, axis=1) if per_face else rgb[faces])


def parse(data: bytes, notes: list[str], name: str):
    """(vertices (V, 3), faces (F, 3), normals (V, 3) or None, colours (V|F, 4) uint8 or None, whether the
    colours are per face) of an OFF file's bytes (module docstring)."""
    found, at, binary = _keyword(data)
    texture, coloured, normals, four, dimensions = (bool(found and found[k]) for k in range(1, 6))
    if binary:
        return _binary(data[at + data[at:].index(b"\n") + 1:], normals, coloured, texture, four, notes, name)
    lines, body = _content_lines(data, at, 2 if dimensions else 1)
    width = 3
    if dimensions:
        if not lines:
            raise SceneError("is cut short before its dimension line; allowed: nOFF, then Ndim")
        width = _integers(lines.pop(0), "the dimension line (nOFF's Ndim)", 1)[0]
        notes.append(f"{name}: is {'4' if four else ''}nOFF ({width}-dimensional vertices); the first three "
                     "coordinates are drawn")
    elif four:
        notes.append(f"{name}: is 4OFF (homogeneous 4-D vertices); x, y, z are drawn without the fourth")
    width += 1 if four else 0
    if not lines:
        raise SceneError("has no counts line; allowed: NVertices NFaces NEdges after the header")
    counts = _integers(lines[0], "the counts line", 2)
    vertex_count, face_count = counts[0], counts[1]
    read = _compiled_body(data, body, vertex_count, face_count)
    if read is not None:
        block, face_words, face_values = read
    else:  # a word off the compiled pass's exact path, or a file cut short: numpy's parse, which words each problem
        lines = [line for line in COMMENT.sub(b"", data[body:]).split(b"\n") if line.strip()]
        if len(lines) < vertex_count + face_count:
            raise SceneError(f"holds {len(lines):,} vertex and face lines where its counts line says "
                             f"{vertex_count:,} + {face_count:,}; the file is cut short")
        block = _numbers(lines[:vertex_count], "a vertex line")
        face_lines = lines[vertex_count:vertex_count + face_count]
        face_words = np.array([len(line.split()) for line in face_lines], np.int64)
        face_values = _numbers(face_lines, "a face line")
        if face_values.size != face_words.sum():
            raise SceneError("has a face line numpy reads differently from its words; allowed: decimal numbers")
    per_line = block.size // max(vertex_count, 1)
    wanted = width + 3 * normals + 2 * texture
    if block.size != per_line * vertex_count or per_line < wanted:
        raise SceneError(f"has vertex lines of {per_line if block.size == per_line * vertex_count else 'differing'} "
                       f"numbers; allowed: the same count on every line, at least {wanted} for its header "
                       f"({found[0].decode() if found else 'OFF'})")
    block = block.reshape(vertex_count, per_line)
    vertices = block[:, :3].copy()
    normal = block[:, width:width + 3].copy() if normals else None
    colours, per_face = None, False
    if coloured:
        spare = per_line - wanted
        colours = _colours(block[:, width + 3 * normals:width + 3 * normals + min(spare, 4)], name, notes)
    if texture:
        notes.append(f"{name}: its texture coordinates (ST) are not used: OFF names no texture image")
    faces, face_colours = _text_faces(face_words, face_values, vertices)
    if colours is None and face_colours is not None:
        colours, per_face = _colours(face_colours[0], name, notes), True
        colours = colours[face_colours[1]] if colours is not None else None
    return vertices, faces, normal, colours, per_face


def _content_lines(data: bytes, at: int, count: int) -> tuple[list[bytes], int]:
    """The first `count` lines from byte `at` that hold a word once their comments are cut, and where the line
    after the last of them starts (the vertex lines, after the counts line)."""
    lines = []
    while len(lines) < count and at < len(data):
        end = data.find(b"\n", at)
        end = len(data) if end < 0 else end
        line = COMMENT.sub(b"", data[at:end])
        if line.strip():
            lines.append(line)
        at = end + 1
    return lines, min(at, len(data))


def _compiled_body(data: bytes, at: int, vertex_count: int, face_count: int):
    """(vertex numbers in order, each face line's count of words, face numbers in order) of the lines from byte
    `at`, read in one compiled pass each (decimals.lines_of_numbers: the bits numpy's parse gives); None when a
    word is off its exact path or the file is cut short, for the numpy parse that words the problem."""
    if 2 * (vertex_count + face_count) > len(data) - at:  # each line needs a word and its line feed
        return None
    from .decimals import lines_of_numbers  # compiled: imported only for a text OFF (numba's import is slow)
    text = np.frombuffer(data, np.uint8)
    vertices = lines_of_numbers(text, at, vertex_count, True, 3 * vertex_count, True)
    if vertices is None or vertices[1] is None:
        return None
    faces = lines_of_numbers(text, vertices[2], face_count, True, 4 * face_count, True)
    return None if faces is None or faces[1] is None else (vertices[1], faces[0], faces[1])


def warm_up(handle) -> tuple:
    """The compiled lines' kernel for a text OFF (not `OFF BINARY`: its header line says so)."""
    return () if _keyword(handle.read(4096))[2] else (_warm_lines,)


def _warm_lines() -> None:
    """Load (or compile) decimals.number_lines as a text OFF calls it."""
    _compiled_body(b"0 0 0\n3 0 0 0\n", 0, 1, 1)


def _integers(line: bytes, what: str, least: int) -> list[int]:
    words = line.split()
    try:
        values = [int(word) for word in words]
    except ValueError:
        raise SceneError(f"has {what} {line[:60].decode('latin-1')!r}, which is not whole numbers") from None
    if len(values) < least or min(values) < 0:
        raise SceneError(f"has {what} {line[:60].decode('latin-1')!r}; allowed: {least} or more whole numbers ≥ 0")
    return values


def _numbers(lines: list[bytes], what: str) -> np.ndarray:
    """Every number of `lines`, in order (numpy's C parser); a word that is not a number is refused naming it."""
    joined = b" ".join(lines)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            return np.fromstring(joined, sep=" ") if joined.strip() else np.zeros(0)
        except (DeprecationWarning, ValueError):
            bad = next((word for line in lines for word in line.split() if not is_number(word)), None)
            if bad is not None:
                raise SceneError(f"has {what} with {bad[:40].decode('latin-1')!r}, which is not a number; "
                                 "allowed: decimal numbers") from None
            raise SceneError(f"has {what} numpy cannot read; allowed: decimal numbers") from None


def _text_faces(words: np.ndarray, values: np.ndarray, points: np.ndarray
                ) -> tuple[np.ndarray, tuple[np.ndarray, np.ndarray] | None]:
    """The face lines' triangles (_polygons), from each line's count of `words` and every line's numbers in order
    (`values`), and their colorspecs (the distinct numbers, each triangle's row) if any face has one of 3 or 4."""
    start = np.cumsum(words) - words
    corners = values[start].astype(np.int64) if len(words) else np.zeros(0, np.int64)
    if (corners < 0).any() or (corners + 1 > words).any():
        bad = int(np.flatnonzero((corners < 0) | (corners + 1 > words))[0])
        raise SceneError(f"has face {bad} (line {bad + 1} of the faces) of {words[bad] - 1} indices where it counts "
                       f"{corners[bad]}; allowed: Nv then Nv vertex indices")
    faces, row = _polygons(values, start + 1, corners, points)
    spec = words - 1 - corners
    if not (spec >= 3).any():
        return faces, None
    rows = np.flatnonzero(spec >= 3)
    table = np.full((len(words), 4), np.nan)
    for k in (0, 1, 2, 3):
        has = spec[rows] > k
        table[rows[has], k] = values[start[rows[has]] + 1 + corners[rows[has]] + k]
    return faces, (table, row)


def _polygons(values: np.ndarray, first: np.ndarray, corners: np.ndarray, points: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of polygons whose corner indices start at values[first] (`corners` each), each polygon a
    fan or, when concave, ear-clipped (polygons.cut), and each triangle's polygon; an index that is not a whole
    number, or names no vertex of `points`, refused."""
    row, picks = cut(corners, listed(values, first, points), points)
    faces = values[first[row][:, None] + picks]  # every corner is in some triangle, whichever the cut
    if faces.size and not (faces == np.round(faces)).all():
        raise SceneError("has a face index that is not a whole number; allowed: vertex indices 0, 1, ...")
    faces = faces.astype(np.int64).reshape(-1, 3)
    if faces.size and (faces.min() < 0 or faces.max() >= len(points)):
        raise SceneError(f"has a face index outside 0..{len(points) - 1}; allowed: indices of its own vertices")
    return faces, row


def _colours(values: np.ndarray, name: str, notes: list[str]) -> np.ndarray | None:
    """RGBA 0..255 of colour rows of 3 or 4 numbers (NaN where a row has none: drawn white): floats in 0..1 as
    they are, else 0..255 (the specification's two forms). A colormap index (one number) is not read."""
    if values.shape[1] < 3:
        notes.append(f"{name}: its colours are colormap indices, which are not read")
        return None
    rgba = np.ones((len(values), 4))
    rgba[:, :values.shape[1]] = values[:, :4]
    floats = not (rgba[:, :3] > 1).any()  # NaN > 1 is False: a row without a colour does not decide the form
    rgba[np.isnan(rgba)] = 1.0 if floats else 255.0  # full, in the form the other rows are written in
    return np.clip(np.round(rgba * (255 if floats else 1)), 0, 255).astype(np.uint8)


def byte_order(counts: bytes, width: int, size: int) -> tuple[bool, int, int] | None:
    """(big-endian, vertices, faces) of a binary body whose first 12 bytes are `counts`, `size` bytes long,
    `width` floats a vertex: Geomview's big-endian form when its counts fit the size, else the little-endian
    dialect pmp-library and OpenMesh write (told apart the way pmp's reader does: by the size); None when
    neither fits (cut short, or a wrong header)."""
    for big in (True, False):
        vertices, faces, _ = (int(v) for v in np.frombuffer(counts, ">i4" if big else "<i4", 3))
        if vertices >= 0 and faces >= 0 and 12 + 4 * width * vertices + 4 * faces <= size:
            return big, vertices, faces
    return None


def _binary(body: bytes, normals: bool, coloured: bool, texture: bool, four: bool, notes: list[str], name: str):
    """OFF BINARY: int32 counts, float32 vertex records, then per face int32 Nv and Nv int32 indices; in
    Geomview's big-endian form then int32 Nc and Nc float32 colour values, in the little-endian dialect
    (byte_order) nothing more."""
    from .ply_lists import Element, Property, element_rows  # a binary face record is a PLY row of lists
    if len(body) < 12:
        raise SceneError("is cut short before its binary counts; allowed: three big-endian int32 counts")
    width = (4 if four else 3) + 3 * normals + 4 * coloured + 2 * texture
    order = byte_order(body[:12], width, len(body))
    if order is None:
        vertex_count, face_count, _ = (int(v) for v in np.frombuffer(body, ">i4", 3))
        raise SceneError(f"counts {vertex_count:,} vertices and {face_count:,} faces, more than its "
                         f"{len(body):,} bytes hold; the file is cut short or its header is wrong")
    big, vertex_count, face_count = order
    word = ">" if big else "<"
    block = np.frombuffer(body, word + "f4", width * vertex_count, 12).reshape(vertex_count, width).astype(np.float64)
    at = 12 + 4 * width * vertex_count
    lists = (Property("vertex_indices", "int", "int"), Property("colour", "float", "int"))
    element = Element("face", face_count, lists if big else lists[:1], ())  # a PLY element of one or two lists
    walked = element_rows(element, np.frombuffer(body, np.uint8), at, big)
    if walked is None:
        raise SceneError(f"has {face_count:,} binary face records that run past its end or count below 0; the file "
                       "is cut short")
    starts, found = walked
    whole = np.frombuffer(body[: len(body) - len(body) % 4], word + "i4")
    first = (starts[:-1] + 4) // 4  # the word of each face's first index
    faces, row = _polygons(whole.astype(np.float64), first, found[:, 0], block[:, :3])
    colours, per_face = None, False
    base = (4 if four else 3) + 3 * normals
    if coloured:
        colours = _colours(block[:, base:base + 4], name, notes)
    elif big and (found[:, 1] >= 3).any():
        floats = np.frombuffer(body[: len(body) - len(body) % 4], ">f4").astype(np.float64)
        table = np.full((face_count, 4), np.nan)
        offset = (starts[:-1] + 8) // 4 + found[:, 0]  # the word after the face's count of colours
        for k in range(4):
            has = found[:, 1] > k
            table[has, k] = floats[offset[has] + k]
        made = _colours(table, name, notes)
        colours, per_face = (made[row] if made is not None else None), True
    if four:
        notes.append(f"{name}: is 4OFF (homogeneous 4-D vertices); x, y, z are drawn without the fourth")
    return block[:, :3].copy(), faces, block[:, base - 3:base].copy() if normals else None, colours, per_face


def count(handle, size: int, mesh) -> int | None:
    """The faces and vertices of the counts line (the first line after the header that is not a comment; a
    binary file's three int32), or None where they claim more than the file's `size` can hold."""
    head = handle.read(4096)
    found, at, binary = _keyword(head)
    if binary:
        start = at + head[at:].find(b"\n") + 1
        if len(head) < start + 12:
            return None
        width = (4 if found[4] else 3) + 3 * bool(found[3]) + 4 * bool(found[2]) + 2 * bool(found[1])
        order = byte_order(head[start:start + 12], width, size - start)
        return None if order is None else weigh(order[2], order[1])  # None: the reader says what is wrong
    lines = [line.split() for line in COMMENT.sub(b"", head[at:]).splitlines() if line.strip()]
    if found and found[5] and lines:
        lines = lines[1:]  # nOFF's dimension line
    if lines and len(lines[0]) >= 2 and all(word.isdigit() for word in lines[0][:2]):
        vertices, faces = int(lines[0][0]), int(lines[0][1])
        if 6 * vertices + 8 * faces <= size:  # "0 0 0" and "3 0 1 2", each with its line feed, at the least
            return weigh(faces, vertices)
    return None  # counts more than the file holds: the reader says it is cut short


def is_off(head: bytes, found, size: int, suffix: str) -> bool:
    """An OFF header keyword, or (the keyword is optional) text starting with its counts."""
    at = _start(head)
    return bool(HEADER.match(head, at)) or (found in (None, "OBJ") and bool(NUMBER.match(head, at)))


FORMAT = MeshFormat(names=("OFF",), suffixes=(".off",), read=read, count=count, parse_bytes=550, content=is_off,
                    warm_up=warm_up)
