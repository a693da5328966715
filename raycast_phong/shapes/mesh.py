"""mesh: an object read from a mesh file rather than built: its triangles, normals and materials are the file's
(io/meshes/, through the scene's MeshSource), so it has no closed form, no tessellation levels and no UVs of its
own; each mesh object is a set of alike objects of its own (scene/alike.py)."""

from __future__ import annotations

from pydantic import Field, model_validator

from ..values.fields import KindKeys
from .kind import ShapeKind


class MeshKeys(KindKeys):
    """A mesh file's key: the file, relative to the scene file's folder (any format trimesh reads)."""
    path: str | None = Field(None, description=(
        "the mesh file (any format trimesh reads: OBJ, PLY, STL, OFF, glTF/GLB), relative to the scene file"))

    @model_validator(mode="after")
    def _named(self) -> MeshKeys:
        if not self.path:
            raise ValueError('shape = "mesh" needs path = "file.obj" (any format trimesh reads)')
        if "\0" in self.path:  # every later stat and open would raise ValueError, not say the file is missing
            raise ValueError(f"no such mesh file {self.path[:60]!r}: a file name cannot hold a NUL byte")
        return self


class Mesh(ShapeKind):
    name = "mesh"
    keys = MeshKeys
    size_key = "path"
    from_file = True  # curved: a file's surface may be (ShapeKind.curved's default)

    def template(self, obj):
        raise TypeError("a mesh object is read from its file (geometry.templates), not built")

    def triangles(self, obj):
        raise TypeError("a mesh file's triangles are counted by its MeshSource")

    def uv(self, obj, vertices, faces):
        return None  # the file's own, per corner
