"""PLY, read by trimesh, with what trimesh leaves out: triangle strips (a `tristrips` element), and texture
comments (MeshLab's `comment TextureFile NAME`, with per-face `texcoord` lists or per-vertex
`s t` / `texture_u texture_v`): the image beside the file becomes the k_d map of a white material, as a viewer
shows it. trimesh reads the first TextureFile and the coordinates, but hands the image on as a plain material
this package did not map, and logs a 10-line traceback when the image is missing (MeshLab writes `<this>` for
the PLY's own name, which trimesh looks for literally). Here `<this>` is the file's stem, a missing image is one
note, and a file naming several images (`texnumber` per face) uses the first (one note). A header trimesh cannot
read has its first bad line named (ply_problem), before trimesh is asked: its ASCII reader takes a property without
a name silently."""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np

from ...errors import FileProblem
from ..files import shown_name
from . import ply_lists
from .format import Loaded, MeshFormat, Part, Reading, weigh
from .materials import PartSurface

HEADER_LIMIT = 1 << 16  # a header is a few hundred bytes; the texture comments come before `end_header`


def texture_names(head: bytes) -> list[str]:
    """The TextureFile names of a PLY header (`head`: the file's first bytes), `<this>` not yet replaced."""
    end = head.find(b"end_header")
    header = head[:end if end >= 0 else len(head)].decode("latin-1")
    return [found.strip() for found in re.findall(r"^comment\s+TextureFile\s+(.+?)\s*$", header, re.M)]


PLY_TYPES = tuple(ply_lists.PLY_DTYPES)  # the PLY property types


def ply_problem(head: bytes) -> str | None:
    """What is wrong with a PLY header (`head`: the file's first bytes) trimesh could not read, in words naming
    the header line: a property whose type is not a PLY type (assimp's fuzzed crash-*.ply: binary bytes where
    the type goes), an element without a count, or no `end_header`; None when the header looks right."""
    lines = head.split(b"\n")
    for number, raw in enumerate(lines, 1):
        words = raw.decode("latin-1").split()
        if words == ["end_header"]:
            return None
        if words[:1] == ["property"]:
            listed = words[1:2] == ["list"]
            types = words[2:4] if listed else words[1:2]
            bad = next((kind for kind in types if kind not in PLY_TYPES), None)
            if bad is not None or len(words) != (5 if listed else 3):
                shown = repr(bad[:40]) if bad is not None else repr(" ".join(words)[:60])
                return (f"header line {number}: property type {shown} is not a PLY type, or the property has no "
                        f"name; allowed: property TYPE NAME or property list TYPE TYPE NAME, TYPE one of "
                        f"{', '.join(PLY_TYPES[:8])}")
        if words[:1] == ["element"] and (len(words) != 3 or not words[2].isdigit()):
            return (f"header line {number}: {' '.join(words)[:60]!r} is not an element; allowed: element NAME "
                    "COUNT, COUNT a whole number")
    return f"has no end_header line in its first {len(head)} bytes; allowed: a PLY header ending in end_header"


def resolved(name: str, path: Path) -> str:
    """A TextureFile name as MeshLab means it: `<this>` stands for the PLY's own name without its suffix."""
    return name.replace("<this>", path.stem)


def read(reading: Reading) -> Loaded:
    """A plain binary PLY by plain_part (no trimesh); any other through trimesh (its triangle strips made
    triangles where it read only the vertices), with the TextureFile names beside it."""
    data = line_feeds(reading.handle.read())  # read once: trimesh reads these bytes (or their rewrite), not again
    header = ply_lists.header(data)
    if header is None:  # a header that does not parse: its bad line named before trimesh, whose ASCII reader
        problem = ply_problem(data[:HEADER_LIMIT])  # takes a nameless property and reads the next in its column
        if problem:
            raise FileProblem(f"{str(reading.path)!r} {problem}")
    tried = header is not None and header.format == "ascii"  # plain_part has seen these bytes
    if tried:  # triangles alone: nothing to cut (ascii_cut's scan)
        plain = plain_part(data, header)
        if plain is not None:
            return Loaded([plain])
    cut = ply_lists.ascii_cut(data, header)  # an ASCII file's concave polygons, each made its triangles' lines
    if cut is not None:
        data, header = cut, ply_lists.header(cut)
    evened = ply_lists.evened(data, header, reading.notes)  # lists of uneven length (a quad, a triangle)
    _note_points(header, reading.path, reading.notes)
    if not tried or cut is not None or evened is not None:  # not the bytes plain_part refused above
        plain = plain_part(data if evened is None else evened,
                           header if evened is None else ply_lists.header(evened))
        if plain is not None:
            return Loaded([plain])
    from .trimesh_parts import RegularFiles, load, parts
    resolver = RegularFiles(reading.path)
    # `<this>` in a TextureFile name; trimesh asks for the last TextureFile, and the first is the one read (the
    # image of texnumber 0; _note_textures says so)
    names = [resolved(name, reading.path) for name in texture_names(data[:HEADER_LIMIT])]
    resolver.locate = lambda folder, name: folder / (names[0] if names else resolved(name, reading.path))
    loaded = load(reading, file_obj=io.BytesIO(data if evened is None else evened), resolver=resolver)
    _note_textures(reading.path, names, reading.notes)
    return Loaded(parts(loaded) or strip_parts(loaded))


COLOURS = ("red", "green", "blue")
UV_NAMES = {"texture_u", "texture_v", "u", "v", "s", "t"}  # the per-vertex coordinates trimesh reads as UVs


def plain_part(data: bytes, header: ply_lists.Header | None) -> Part | None:
    """The Part trimesh's reader gives for a PLY of a `vertex` element (float x, y, z; optionally nx, ny, nz and
    8-bit red, green, blue, alpha; other scalars ignored, as trimesh keeps them aside) and a `face` element of
    one list of three indices per row, read by numpy views of the bytes (binary) or one parse of each section
    (ASCII, ply_lists.ascii_rows); None for any other PLY (texture coordinates or files, face properties,
    polygons, strips, other elements, short data), which trimesh reads. Same arrays, same dtypes: vertices and
    normals float64, faces int64, colours as every reader gives them (8-bit / 255 at each corner)."""
    if header is None or texture_names(data[:HEADER_LIMIT]):
        return None
    if [element.name for element in header.elements] not in (["vertex", "face"], ["face", "vertex"]):
        return None
    if header.format == "ascii":
        rows = ply_lists.ascii_rows(data, header)
        if rows is None:
            return None
    else:
        big, view, at, rows = header.format == "binary_big_endian", memoryview(data), header.body, {}
        for element in header.elements:
            even = ply_lists._even(element, view, at, big)
            if even is None or not element.rows:
                return None
            rows[element.name], at = even
    vertex, face = (next(e for e in header.elements if e.name == name) for name in ("vertex", "face"))
    names = {prop.name: f"p{k}" for k, prop in enumerate(vertex.properties) if prop.count is None}
    if (len(face.properties) != 1 or face.properties[0].name not in ply_lists.POLYGON
            or rows["face"]["p0"].shape[1:] != (3,) or not {"x", "y", "z"} <= names.keys() or UV_NAMES & names.keys()
            or any(prop.count is not None for prop in vertex.properties)
            or any(prop.type[0] not in "fd" for prop in vertex.properties if prop.name in "xyz")):
        return None
    coloured = [name for name in (*COLOURS, "alpha") if name in names]
    if coloured and (not set(COLOURS) <= set(coloured)
                     or any(next(p for p in vertex.properties if p.name == name).type not in ("uchar", "uint8")
                            for name in coloured)):
        return None
    table = rows["vertex"]
    vertices, normals = ply_lists._points(vertex, table), ply_lists._points(vertex, table, ("nx", "ny", "nz"))
    faces = rows["face"]["p0"].astype(np.int64)
    surface = None
    if coloured:
        rgb = np.column_stack([table[names[name]] for name in COLOURS]).astype(np.float32) / 255.0
        surface = PartSurface(corner_colour=rgb[faces])
    return Part(vertices, faces, normals, surface)


def _note_points(header: ply_lists.Header | None, path: Path, notes: list[str]) -> None:
    """A note for a PLY of points and no faces (a scan's point cloud, a Gaussian splat file): nothing of it
    is a surface, which the no-triangles refusal then says."""
    if header is None or any(element.name in ("face", "tristrips") and element.rows for element in header.elements):
        return  # an empty face element (`element face 0`, as point-cloud writers put it) holds no surface either
    vertex = next((element for element in header.elements if element.name == "vertex"), None)
    if vertex is not None:
        names = {prop.name for prop in vertex.properties}
        kind = "Gaussian splats" if {"f_dc_0", "opacity"} <= names else "points"
        notes.append(f"{path}: a point cloud of {vertex.rows:,} {kind}, no faces: only surfaces are drawn")


def strip_parts(loaded) -> list:
    """A PLY that stores triangle strips (a `tristrips` element, -1 between strips) as triangles: trimesh
    reads only its vertices. Strip triangle i is (s_i, s_i+1, s_i+2), every other one reversed to keep the
    winding; triangles that repeat a vertex (the strips' joins) are dropped."""
    raw = getattr(loaded, "metadata", {}).get("_ply_raw") if hasattr(loaded, "metadata") else None
    if not raw or "tristrips" not in raw or "vertex" not in raw:
        return []
    data, vertex = raw["tristrips"]["data"], raw["vertex"]["data"]
    try:
        field = data["vertex_indices"]
        rows = field["f1"] if field.dtype.names else field
        strips = np.concatenate([np.append(np.asarray(row, np.int64).ravel(), -1) for row in np.atleast_1d(rows)])
        vertices = np.column_stack([np.asarray(vertex[k], np.float64).ravel() for k in ("x", "y", "z")])
    except (KeyError, ValueError, TypeError, IndexError):
        return []
    if len(strips) < 3:
        return []
    windows = np.lib.stride_tricks.sliding_window_view(strips, 3)
    restart = np.flatnonzero(strips < 0)
    start = np.zeros(len(strips), np.int64)  # where each position's strip starts
    start[restart[restart + 1 < len(strips)] + 1] = restart[restart + 1 < len(strips)] + 1
    start = np.maximum.accumulate(start)[: len(windows)]
    odd = (np.arange(len(windows)) - start) % 2 == 1
    keep = ((windows >= 0).all(axis=1) & (windows[:, 0] != windows[:, 1]) & (windows[:, 1] != windows[:, 2])
            & (windows[:, 0] != windows[:, 2]))
    faces = np.where(odd[:, None], windows[:, [1, 0, 2]], windows)[keep]
    return [Part(vertices, faces, None, None)] if len(faces) else []


def _note_textures(path: Path, names: list[str], notes: list[str]) -> None:
    """A note for a PLY's missing TextureFile image (`names`: `<this>` replaced) and for images after the first
    (one map per file is read: trimesh's, as a SimpleMaterial's image)."""
    if names and not (path.parent / names[0]).is_file():
        notes.append(f"{path}: texture {shown_name(names[0])} is missing")
    if len(names) > 1:
        notes.append(f"{path}: names {len(names)} TextureFile images (a texture number per face); only the first, "
                     f"{names[0]!r}, is read, for every face")


def line_feeds(data: bytes) -> bytes:
    """A PLY whose lines end in a carriage return alone (Rhino 6, classic Mac; the PLY description says
    "carriage-return terminated lines") with its header's CRs made line feeds, and an ASCII body's too; the same
    length, so a binary body starts where it did. Any other file unchanged."""
    if not data.startswith(b"ply\r") or data.startswith(b"ply\r\n"):
        return data
    end = data.find(b"end_header\r")
    if end < 0:
        return re.sub(rb"\r(?!\n)", b"\n", data)  # the start of a file (explain, count): its header only
    stop = end + len(b"end_header\r") + (data[end + 11:end + 12] == b"\n")  # Rhino ends it `\r\n`
    head = re.sub(rb"\r(?!\n)", b"\n", data[:stop])
    return head + (re.sub(rb"\r(?!\n)", b"\n", data[stop:]) if _ascii(head) else data[stop:])


def count(handle, size: int, mesh) -> int | None:
    """The header's face count, or the most triangles its lists can make from the file's size (binary), or its
    vertices less 2 where more (format.weigh); None for a header without faces or lists."""
    head = line_feeds(handle.read(4096))
    faces = re.search(rb"^element\s+face\s+(\d+)", head, re.M)
    points = re.search(rb"^element\s+vertex\s+(\d+)", head, re.M)
    listed = _list_triangles(head, size)
    if faces or listed is not None:
        return weigh(max(int(faces[1]) if faces else 0, listed or 0), int(points[1]) if points else 0)
    return None


def _list_triangles(head: bytes, size: int) -> int | None:
    """The most triangles a binary PLY's lists (faces, strips) can make, from its size and its header's
    types, whatever its counts claim: the bytes past the fixed-size properties hold at most that many list
    entries of the smallest index type, and n entries of a polygon or strip make n − 2 triangles. Exact for
    a file of triangles (a face of 3 M corners, header "1 face", is 3 M triangles). None for an ASCII PLY, a
    header longer than `head`, or no list; ValueError for a header that does not parse (the size bound then
    stands, size.count_triangles)."""
    end = head.find(b"end_header")
    if end < 0 or head.find(b"\n", end) < 0 or _ascii(head):
        return None
    found = ply_lists.header(head)
    if found is None:
        raise ValueError("a PLY header that does not parse")
    elements = []  # (count, bytes of its fixed properties and list counts, smallest list entry or 0)
    for element in found.elements:
        fixed = sum(ply_lists.PLY_SIZES[p.count if p.count else p.type] for p in element.properties)
        smallest = min((ply_lists.PLY_SIZES[p.type] for p in element.properties if p.count), default=0)
        elements.append((element.rows, fixed, smallest))
    lists = [(count, entry) for count, _, entry in elements if entry]
    if not lists:
        return None
    body = size - found.body
    entries = max(0, body - sum(count * fixed for count, fixed, _ in elements)) // min(e for _, e in lists)
    return max(0, entries - 2 * sum(count for count, _ in lists))


def warm_up(handle) -> tuple:
    """The ASCII rows' kernel for an ASCII PLY (its header says so); none for a binary one, read by numpy views
    (its uneven lists' walk, rare, compiles when read)."""
    return (ply_lists.warm_up,) if _ascii(line_feeds(handle.read(HEADER_LIMIT))) else ()


def _ascii(head: bytes) -> bool:
    """Whether the header at the start of `head` says `format ascii`."""
    end = head.find(b"end_header")
    return end >= 0 and re.search(rb"^format\s+ascii", head[:end], re.M) is not None


FORMAT = MeshFormat(names=("PLY",), suffixes=(".ply",), read=read, count=count, parse_bytes=30, warm_up=warm_up,
                    content=lambda head, found, size, suffix: found == "PLY")
