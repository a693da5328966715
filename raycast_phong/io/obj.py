"""Wavefront OBJ, read by trimesh from text prepared here: relative face indices made absolute and concave
polygons cut (io/obj_polygons.py), `v x y z r g b` colours kept beside materials, and each `usemtl` group
tagged with its material's name (the materials themselves are io/mtl.py's, parsed once per file version)."""

from __future__ import annotations

import io
from pathlib import Path

import trimesh

from ..errors import SceneError, Where


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


def load_obj(text: io.BytesIO, path: Path, names):
    """What trimesh.load gives for the OBJ `text` (obj_text) of `path` whose materials are `names`, but
    `v x y z r g b` colours are kept beside a material or texture coordinates: trimesh's reader hands them to
    a Trimesh whose TextureVisuals replaces them. They move to the visual's `color` vertex attribute (where
    trimesh keeps glTF's COLOR_0 beside a material, which io/mesh_file.py reads), 8-bit as trimesh's
    ColorVisuals keeps them when there is no material."""
    kwargs = trimesh.exchange.obj.load_obj(text, resolver=MaterialNames(path, names), process=False)
    for mesh in (kwargs.get("geometry") or {}).values():
        if mesh.get("vertex_colors") is not None and mesh.get("visual") is not None:
            mesh["visual"].vertex_attributes["color"] = trimesh.visual.color.to_rgba(mesh.pop("vertex_colors"))
    return trimesh.load_scene(kwargs)
