"""One object per mesh file: everything the stages want from it, read and parsed once, and kept with the scene.

A MeshSource is made (mesh_source) when a scene is loaded: framing makes the one of a mesh file rendered
directly, and load_scene hands it on with the scene (Scene.mesh_sources); prepare() takes the scene's sources
(mesh_sources: a file changed since is made again) and passes them to the memory estimate (triangles, read
floor, texture sizes) and to the geometry stage's read. Batch's up-to-date rule asks the same object for the
side files and images. What it learns it keeps (its memo): the triangle count, the bounds framing read, and the
read itself until the render takes it, so a file framed and rendered is read once. No module-level cache: a
source is found only through the scene that carries it. No trimesh: a scene without mesh files, and the memory
estimate, stay light.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ...errors import Where
from ..files import present_version
from . import format_of
from .format import MeshFormat
from .gltf_json import Document
from .mtl import ObjMaterials

if TYPE_CHECKING:
    from .read import MeshFile


@dataclass(frozen=True, eq=False)
class MeshSource:
    """A mesh file as it is now, before its geometry is read. What the file names beside it is read when first
    asked (its format's `describe`), so a file refused from its size alone is never scanned (a 3 GiB OBJ's
    `mtllib` scan reads all of it)."""
    path: Path
    format: MeshFormat
    version: tuple | None              # io.files.file_version; None for a missing file (the read words it)
    where: Where = ""                  # where its errors point: the first object naming it (scene.toml:
                                       # objects.2.path), else the file itself
    _memo: dict[str, Any] = field(default_factory=dict, repr=False)  # what was read: triangles, bounds, read

    @cached_property
    def _described(self) -> dict[str, Any]:
        described = self.format.describe(self.path) if self.version is not None else {}
        return {**described, "side_versions": _stamps(described.get("side_files", ()))}

    @property
    def side_files(self) -> tuple[Path, ...]:
        """The files it names that change its image: an OBJ's .mtl files (every one its `mtllib` lines name, in
        order), a .gltf's external buffers."""
        return self._described.get("side_files", ())

    @property
    def document(self) -> Document | None:
        """A glTF's JSON, parsed (io/meshes/gltf_json.py); None for other formats."""
        return self._described.get("document")

    @property
    def materials(self) -> ObjMaterials | None:
        """An OBJ's .mtl files, read and parsed (io/meshes/mtl.py); None otherwise."""
        return self._described.get("materials")

    @property
    def images(self) -> tuple[Path, ...]:
        """Image files outside it that its materials read (an OBJ's colour maps that exist, a glTF's image URIs)."""
        return self._described.get("images", ())

    @property
    def files_read(self) -> tuple[Path, ...]:
        """What reading it opens beside the file itself: its side files, then its images."""
        return (*self.side_files, *self.images)

    @property
    def side_versions(self) -> tuple:
        """Each side file's version when it was described."""
        return self._described["side_versions"]

    @property
    def identity(self) -> tuple:
        """The file and its side files as they were when this was made (an .mtl edited alone changes the
        materials): what the live view's memo keys a read on (geometry/memo.py)."""
        return (self.version, *self.side_versions)

    def current(self) -> bool:
        """Whether the file and its side files are still as they were (a batch renders long after it loads)."""
        return present_version(self.path) == self.version and _stamps(self.side_files) == self.side_versions

    @cached_property
    def texture_sizes(self) -> tuple[tuple[int, int], ...]:
        """(height, width) of each colour map its materials name, from image headers only (io.textures), for
        the memory estimate."""
        return self.format.texture_sizes(self)

    def triangles(self) -> int:
        """Its triangles, counted cheaply once (io/meshes/size.py): framing's check and the render's estimate ask."""
        if "triangles" not in self._memo:
            from .size import count_triangles
            self._memo["triangles"] = count_triangles(self)
        return self._memo["triangles"]

    def read_floor(self) -> int:
        """The least memory its read takes, from its size (io/meshes/size.py)."""
        from .size import read_floor
        return read_floor(self)

    def bounds(self) -> MeshFile:
        """Its centre, radius, up axis, materials and notes (the arrays empty), for framing: read once, and the
        whole read kept for the render that follows (`read` takes it), so a framed file is read once."""
        if "bounds" not in self._memo:
            from .read import read_file
            found = read_file(self, bounds=True)
            if self.version is not None:
                self._memo["read"] = found
            self._memo["bounds"] = replace(found, vertices=found.vertices[:0], faces=found.faces[:0], normals=None,
                                           face_group=found.face_group[:0], corner_uv=None, corner_colour=None)
        return self._memo["bounds"]

    def read(self) -> MeshFile:
        """The file's geometry and surfaces (io/meshes/read.py): the read framing kept, taken (the caller owns
        it now), else read now."""
        found = self._memo.pop("read", None)
        if found is not None:
            return found
        from .read import read_file
        return read_file(self, bounds=False)

    def holds_read(self) -> bool:
        """Whether a read waits here for its render (framing read the file in this process)."""
        return "read" in self._memo


def mesh_source(path: Path, where: Where | None = None) -> MeshSource:
    """The MeshSource of the file at `path` as it is now (its version; what it names beside it is read when
    asked); `where` starts its errors (default: the file). A file that cannot be read gives a source with what
    could be (the read words the error)."""
    path = Path(path)
    return MeshSource(path, format_of(path), present_version(path), str(path) if where is None else where)


def read_mesh(path: Path, where: Where | None = None) -> MeshFile:
    """The mesh file at `path`, read now (its MeshSource made now); `where` starts every error."""
    return mesh_source(path, where).read()


def _stamps(files) -> tuple:
    return tuple(present_version(file) or (str(file), None) for file in files)


def mesh_sources(scene, given: dict | None = None) -> dict[Path, MeshSource]:
    """A MeshSource for each mesh file `scene` reads, keyed by its resolved path (as scene.resolve gives it):
    those `given` (or the scene's own, Scene.mesh_sources) that are still current, the others made now."""
    given = scene.mesh_sources if given is None else given
    found: dict[Path, MeshSource] = {}
    for index, path in scene.mesh_objects():
        if path in found:
            continue
        source = given.get(source_key(path))
        where = scene.origin.at("objects", index, "path")
        found[path] = source if source is not None and source.current() else mesh_source(path, where)
    return found


def source_key(path: Path) -> str:
    """The key a MeshSource is found under whatever the path's spelling (relative, absolute, via a link)."""
    try:
        return os.path.realpath(path)
    except (OSError, ValueError):
        return str(path)
