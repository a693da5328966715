"""Wavefront OBJ, read by trimesh from text prepared here: relative face indices made absolute and concave
polygons cut (io/obj_polygons.py), `v x y z r g b` colours kept beside materials, and each `usemtl` group
tagged with its material's name (the materials themselves are io/mtl.py's, parsed once per file version)."""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np
import trimesh

from ..errors import SceneError, Where
from .mesh_content import is_number

BOMS = ((b"\xef\xbb\xbf", "utf-8"), (b"\xff\xfe", "utf-16-le"), (b"\xfe\xff", "utf-16-be"))


def bom_decoded(data: bytes, path: Path, where: Where) -> bytes:
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
                raise SceneError(f"{str(path)!r} starts with a {encoding.upper()} byte-order mark but byte "
                                 f"{error.start + len(mark)} is not {encoding.upper()}; allowed: an OBJ in UTF-8, "
                                 "Latin-1, or UTF-16 with its byte-order mark", where) from None
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


def obj_text(data: bytes, path: Path, where: Where) -> io.BytesIO:
    """The OBJ's bytes as trimesh is given them: UTF-8 (a file that is not is read as Latin-1: every byte is a
    Latin-1 character, and the keywords are plain ASCII; trimesh would need the optional charset_normalizer to
    guess), relative face indices made absolute and concave polygons cut. An index 0 or one counting back past
    the file's start is a SceneError naming the line."""
    try:
        data.decode("utf-8")
    except UnicodeDecodeError:
        data = data.decode("latin-1").encode("utf-8")
    from .obj_polygons import absolute_indices, triangulate_concave
    data, problem = absolute_indices(data)  # trimesh counts -1 back from the file's end, not the line
    if problem:
        raise SceneError(f"{str(path)!r} {problem}", where)
    data, _ = triangulate_concave(data)  # trimesh would fan a concave polygon over its hole
    return io.BytesIO(data)


class MaterialNames(trimesh.resolvers.FilePathResolver):
    """The .mtl trimesh is given for an OBJ, whatever name it asks for: a `newmtl` line per material read
    by io/mtl.py, so trimesh tags each `usemtl` group with its material's name. trimesh reads only the first
    `mtllib` line, as one file name; the materials themselves (and their maps) are read there."""

    def __init__(self, path: Path, names):
        super().__init__(path)
        self.text = "".join(f"newmtl {name}\n" for name in names).encode("utf-8")

    def get(self, name):
        return self.text


def load_obj(text: io.BytesIO, path: Path, names, where: Where = "", data: bytes = b""):
    """What trimesh.load gives for the OBJ `text` (obj_text) of `path` whose materials are `names`, but
    `v x y z r g b` colours are kept beside a material or texture coordinates: trimesh's reader hands them to
    a Trimesh whose TextureVisuals replaces them. They move to the visual's `color` vertex attribute (where
    trimesh keeps glTF's COLOR_0 beside a material, which io/mesh_file.py reads), 8-bit as trimesh's
    ColorVisuals keeps them when there is no material. A texture coordinate beyond float32's range (kept so
    per corner) is a SceneError naming its line in `data`, the file's bytes as read."""
    kwargs = trimesh.exchange.obj.load_obj(text, resolver=MaterialNames(path, names), process=False)
    for mesh in (kwargs.get("geometry") or {}).values():
        if mesh.get("vertex_colors") is not None and mesh.get("visual") is not None:
            mesh["visual"].vertex_attributes["color"] = trimesh.visual.color.to_rgba(mesh.pop("vertex_colors"))
        uv = getattr(mesh.get("visual"), "uv", None)
        if uv is not None and not (np.abs(np.asarray(uv, np.float64)) <= UV_LIMIT).all():
            _refuse_texture_coordinate(data or text.getvalue(), path, where)
    return trimesh.load_scene(kwargs)


UV_LIMIT = float(np.finfo(np.float32).max)  # texture coordinates are kept as float32 per face corner


def _refuse_texture_coordinate(data: bytes, path: Path, where: Where) -> None:
    """The SceneError for the first `vt` line of `data` with a value beyond ±UV_LIMIT (NaN is not beyond)."""
    for found in re.finditer(rb"^[ \t]*vt[ \t]+([^\r\n]*)", data, re.M):
        for word in found[1].split():
            try:
                value = float(word)
            except ValueError:
                continue
            if abs(value) > UV_LIMIT:
                line = data.count(b"\n", 0, found.start()) + 1
                raise SceneError(f"{str(path)!r} line {line}: texture coordinate {word.decode('latin-1')[:40]} "
                                 f"is beyond float32's range; allowed: -{UV_LIMIT:.4g} .. {UV_LIMIT:.4g}", where)
    raise SceneError(f"{str(path)!r} has a texture coordinate beyond float32's range; allowed: "
                     f"-{UV_LIMIT:.4g} .. {UV_LIMIT:.4g}", where)
