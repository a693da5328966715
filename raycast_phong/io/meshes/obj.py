"""Wavefront OBJ: a file of only `v` and `f` lines in one compiled pass (io/meshes/obj_plain.py), any other read
by trimesh from text prepared here: relative face indices made absolute and concave polygons cut
(io/meshes/obj_polygons.py), `v x y z r g b` colours kept beside materials, and each `usemtl` group tagged with
its material's name (the materials themselves are io/meshes/mtl.py's, parsed once per file version)."""

from __future__ import annotations

import io
import re
from contextlib import suppress
from pathlib import Path

import numpy as np

from ...errors import FileProblem, SceneError
from ..files import open_regular
from .content import is_number
from .format import Loaded, MeshFormat, Reading, image_file_sizes, weigh
from .mtl import mtllib_names, read_obj_materials, scan_mtllib, uncommented, utf8

BOMS = ((b"\xef\xbb\xbf", "utf-8"), (b"\xff\xfe", "utf-16-le"), (b"\xfe\xff", "utf-16-be"))


def bom_decoded(data: bytes, path: Path) -> bytes:
    """An OBJ's bytes as UTF-8 without its byte-order mark, when it starts with one (assimp's box_UTF16BE.obj:
    read as bytes, its keywords interleaved with NULs gave "holds no triangles"); else `data` itself. A file
    that its BOM says is UTF-16 but is not is a SceneError; after a UTF-8 mark, obj_text's Latin-1 fallback
    holds as without one."""
    for mark, encoding in BOMS:
        if data.startswith(mark):
            if encoding == "utf-8":
                return data[len(mark):]
            try:
                return data[len(mark):].decode(encoding).encode("utf-8")
            except UnicodeDecodeError as error:
                raise FileProblem(f"{str(path)!r} starts with a {encoding.upper()} byte-order mark but byte "
                                  f"{error.start + len(mark)} is not {encoding.upper()}; allowed: an OBJ in UTF-8, "
                                  "Latin-1, or UTF-16 with its byte-order mark") from None
    return data


NUMBER_RECORDS = re.compile(rb"^[ \t]*(v|vn|vt|vp)[ \t]+([^\r\n]*)", re.M)


def obj_problem(data: bytes) -> str | None:
    """What stops an OBJ (UTF-8 `data`) being read, in words naming its line, when trimesh could not read it: the
    first `v`, `vn`, `vt` or `vp` value that is not a number (tinyobjloader's test-nan.obj writes MSVC's
    `1.#IND`); None when none is found."""
    for found in NUMBER_RECORDS.finditer(data):
        for word in re.split(rb"(?:^|[ \t])#", found[2])[0].split():  # a comment, not `1.#IND`
            if not is_number(word):
                line = data.count(b"\n", 0, found.start()) + 1
                return (f"line {line}: {found[1].decode()} value {word.decode('latin-1')[:40]!r} is not a number; "
                        "allowed: decimal numbers (1.5, -2e-3, nan, inf)")
    return None


def obj_text(data: bytes, path: Path) -> io.BytesIO:
    """The OBJ's bytes as trimesh is given them: UTF-8 (a file that is not is read as Latin-1: every byte is a
    Latin-1 character, and the keywords are plain ASCII; trimesh would need the optional charset_normalizer to
    guess), relative face indices made absolute and concave polygons cut. An index 0 or one counting back past
    the file's start is a SceneError naming the line."""
    from .obj_polygons import absolute_indices, triangulate_concave
    data, problem = absolute_indices(utf8(data))  # trimesh counts -1 back from the file's end, not the line
    if problem:
        raise FileProblem(f"{str(path)!r} {problem}")
    data, _ = triangulate_concave(data)  # trimesh would fan a concave polygon over its hole
    return io.BytesIO(kept_hashes(data))


IN_NAME = "\ue000"  # stands for a `#` inside a material name while trimesh reads (it cuts every line at `#`)
USEMTL_HASH = re.compile(rb"^[ \t]*usemtl[ \t][^\n]*#[^\n]*", re.M)


def kept_hashes(data: bytes) -> bytes:
    """`usemtl` lines holding `#` as mtl.uncommented reads them: a trailing comment dropped (trimesh kept the
    space before it in the name, and lost the material), each `#` inside a word as IN_NAME, so trimesh's
    comment cut leaves the name whole. Files without such a line are returned as they are."""
    if not USEMTL_HASH.search(data):
        return data
    marker = IN_NAME.encode()
    return USEMTL_HASH.sub(lambda line: b" ".join(uncommented(line[0].split())).replace(b"#", marker), data)


def hashed(name: str) -> str:
    """A material name as trimesh is given it (kept_hashes)."""
    return name.replace("#", IN_NAME)


def material_names(path: Path, names):
    """The resolver trimesh is given for an OBJ: whatever .mtl it asks for, a `newmtl` line per material read by
    io/meshes/mtl.py, so trimesh tags each `usemtl` group with its material's name. trimesh reads only the first
    `mtllib` line, as one file name; the materials themselves (and their maps) are read there."""
    import trimesh

    class MaterialNames(trimesh.resolvers.FilePathResolver):
        def get(self, name):
            return self.text

    resolver = MaterialNames(path)
    resolver.text = "".join(f"newmtl {hashed(name)}\n" for name in names).encode("utf-8")
    return resolver


def load_obj(text: io.BytesIO, path: Path, names, data: bytes = b""):
    """What trimesh.load gives for the OBJ `text` (obj_text) of `path` whose materials are `names`, but
    `v x y z r g b` colours are kept beside a material or texture coordinates: trimesh's reader hands them to
    a Trimesh whose TextureVisuals replaces them. They move to the visual's `color` vertex attribute (where
    trimesh keeps glTF's COLOR_0 beside a material, which io/meshes/read.py reads), 8-bit as trimesh's
    ColorVisuals keeps them when there is no material. A texture coordinate beyond float32's range (kept so
    per corner) is a SceneError naming its line in `data`, the file's bytes as read."""
    import trimesh
    kwargs = trimesh.exchange.obj.load_obj(text, resolver=material_names(path, names), process=False)
    for mesh in (kwargs.get("geometry") or {}).values():
        if mesh.get("vertex_colors") is not None and mesh.get("visual") is not None:
            mesh["visual"].vertex_attributes["color"] = trimesh.visual.color.to_rgba(mesh.pop("vertex_colors"))
        uv = getattr(mesh.get("visual"), "uv", None)
        if uv is not None and (np.abs(np.asarray(uv, np.float64)) > UV_LIMIT).any():  # NaN passes, as in read.py
            _refuse_texture_coordinate(data or text.getvalue(), path)
    return trimesh.load_scene(kwargs)


UV_LIMIT = float(np.finfo(np.float32).max)  # texture coordinates are kept as float32 per face corner


def _refuse_texture_coordinate(data: bytes, path: Path) -> None:
    """The SceneError for the first `vt` line of `data` with a value beyond ±UV_LIMIT (NaN is not beyond)."""
    for found in re.finditer(rb"^[ \t]*vt[ \t]+([^\r\n]*)", data, re.M):
        for word in found[1].split():
            try:
                value = float(word)
            except ValueError:
                continue
            if abs(value) > UV_LIMIT:
                line = data.count(b"\n", 0, found.start()) + 1
                raise FileProblem(f"{str(path)!r} line {line}: texture coordinate {word.decode('latin-1')[:40]} "
                                  f"is beyond float32's range; allowed: -{UV_LIMIT:.4g} .. {UV_LIMIT:.4g}")
    raise FileProblem(f"{str(path)!r} has a texture coordinate beyond float32's range; allowed: "
                      f"-{UV_LIMIT:.4g} .. {UV_LIMIT:.4g}")


def read(reading: Reading) -> Loaded:
    """The OBJ's geometry (a UTF-16 OBJ, told by its byte-order mark, as UTF-8), with its .mtl materials as its
    MeshSource read them (their notes and maps added to the reading's)."""
    from .obj_plain import plain_obj
    path, materials = reading.path, reading.source.materials
    data = bom_decoded(reading.handle.read(), path)
    plain = plain_obj(data, path)  # only v and f lines: one compiled pass
    reading.notes.extend(materials.notes)
    reading.textures.extend(materials.sources)
    library = materials.library and {hashed(name): material for name, material in materials.library.items()}
    if plain is not None:
        return Loaded([plain], library=library)
    from .trimesh_parts import parts
    return Loaded(parts(load_obj(obj_text(data, path), path, materials.library, data)), library=library)


CHUNK = 1 << 20  # an OBJ is scanned this many bytes at a time (about 20 MB of index arrays), never a whole line


def count(handle, size: int, mesh) -> int:
    """An OBJ's triangles (a face of k corners is k − 2), or its vertices where more (format.weigh), scanned in
    CHUNK-byte pieces with numpy: a line is never held whole, so a one-line 1 GB file costs about 20 MB here.

    Each piece is seen with the stream's two bytes before it, so a line that starts at a piece's edge is
    classified (its first two bytes: `f ` or `v `) exactly once, and a token start (a non-blank byte after a
    blank one) is counted in the line it belongs to."""
    triangles = vertices = open_tokens = 0
    before, in_face = b"\n\n", False
    while True:
        chunk = handle.read(CHUNK)
        buffer = np.frombuffer(before + (chunk or b"\n"), np.uint8)
        # Positions 1 .. len − 2 of the buffer are this piece's (each stream byte once over the pieces).
        starts = np.flatnonzero(buffer[:-2] == 10) + 1
        blank = buffer <= 32
        first, second = buffer[starts], buffer[starts + 1]
        gap = (second == 32) | (second == 9)
        face = np.concatenate(([in_face], (first == ord("f")) & gap))  # 0: the line carried from before
        vertices += int(np.count_nonzero((first == ord("v")) & gap))
        begins = np.flatnonzero(~blank[1:-1] & blank[:-2]) + 1
        line = np.searchsorted(starts, begins, side="right")
        tokens = np.bincount(line[face[line]], minlength=len(face))  # per line: `f` and its corners
        tokens[0] += open_tokens
        closed = tokens if not chunk else tokens[:-1]  # the last line may go on in the next piece
        triangles += int(np.maximum(closed - 3, 0).sum())
        if not chunk:
            break
        open_tokens, in_face = int(tokens[-1]), bool(face[-1])
        before = buffer[-2:].tobytes()
    return weigh(triangles, vertices)


def describe(path: Path) -> dict:
    """Its .mtl files (every one its `mtllib` lines name, in order: side files), read and parsed, and the colour
    maps they name that exist. The OBJ is scanned for `mtllib` in 1 MB blocks; an .mtl is at most 16 MiB."""
    lines = []  # unreadable: the read words it
    with suppress(OSError, SceneError), open_regular(path, str(path), "mesh file") as handle:
        lines = scan_mtllib(handle)
    names = mtllib_names(lines, path.parent)
    materials = read_obj_materials(path, names)
    images = tuple(dict.fromkeys(texture.source for texture in materials.sources))
    return {"side_files": tuple(path.parent / name for name in names), "materials": materials, "images": images}


def warm_up(handle) -> tuple:
    """The polygon scan's kernels, and the plain reader's unless the file's first MB names a material library
    (then the plain reader's scan never runs)."""
    from . import obj_plain, obj_polygons
    plain = obj_plain.may_be_plain(handle.read(obj_plain.HEAD))
    return (obj_plain.warm_up, obj_polygons.warm_up) if plain else (obj_polygons.warm_up,)


FORMAT = MeshFormat(
    names=("OBJ",), suffixes=(".obj",), read=read, count=count, describe=describe,
    texture_sizes=image_file_sizes, warm_up=warm_up, parse_bytes=80,
    explain=lambda handle, mesh: obj_problem(bom_decoded(handle.read(), mesh.path)),
    content=lambda head, found, size, suffix: found in (None, "OBJ", "OFF", "ASCII STL"))  # text formats look alike
