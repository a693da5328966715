"""One object per mesh file: everything the stages before the geometry want from it, read and parsed once.

A MeshSource is made (mesh_source) when a scene is loaded: framing makes the one of a mesh file rendered
directly, and load_scene hands it on with the scene (Scene.mesh_sources); prepare() takes the scene's sources
(mesh_sources: a file changed since is made again) and passes them to the memory estimate (header counts,
texture sizes) and to the geometry stage's read (the parsed .mtl materials, the glTF document, the side files
that identify the read kept from framing). Batch's up-to-date rule asks the same object for the side files and
images. So a .gltf's JSON is parsed once here (trimesh parses it again to read the geometry) and an .mtl is
read and parsed once, where each stage used to read the file again. No trimesh: a scene without mesh files,
and the memory estimate, stay light.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

from ..errors import SceneError
from .files import file_version, open_regular
from .gltf import Document, buffer_files, image_uris, read_document, uri_file
from .mtl import ObjMaterials, mtllib_names, read_obj_materials, scan_mtllib


@dataclass(frozen=True, eq=False)
class MeshSource:
    """A mesh file as it is now, before its geometry is read."""
    path: Path
    suffix: str                        # lower case, with the dot
    version: tuple | None              # io.files.file_version; None for a missing file (the read words it)
    side_files: tuple[Path, ...] = ()  # the files it names that change its image: an OBJ's .mtl files (every one
                                       # its `mtllib` lines name, in order), a .gltf's external buffers
    document: Document | None = None   # a glTF's JSON, parsed (io/gltf.py); None for other formats
    materials: ObjMaterials | None = None  # an OBJ's .mtl files, read and parsed (io/mtl.py); None otherwise
    images: tuple[Path, ...] = ()      # image files outside it that its materials read (an OBJ's colour maps that
                                       # exist, a glTF's image URIs)
    side_versions: tuple = field(default=(), repr=False)  # each side file's version when this was made

    @property
    def identity(self) -> tuple:
        """The file and its side files as they were when this was made (an .mtl edited alone changes the
        materials): the key of the read framing keeps for the render (io/mesh_file.py)."""
        return (self.version, *self.side_versions)

    def current(self) -> bool:
        """Whether the file and its side files are still as they were (a batch renders long after it loads)."""
        try:
            now = file_version(self.path)
        except OSError:
            now = None
        return now == self.version and _stamps(self.side_files) == self.side_versions

    @cached_property
    def texture_sizes(self) -> tuple[tuple[int, int], ...]:
        """(height, width) of each colour map its materials name, from image headers only (io.textures), for
        the memory estimate: an OBJ's maps, a glTF's baseColor and emissive textures."""
        from .textures import file_size
        if self.materials is not None:
            return tuple(size for size in map(file_size, self.images) if size)
        if self.document is not None:
            from .gltf import texture_sizes
            return tuple(texture_sizes(self.path, self.document, file_size))
        if self.suffix == ".3mf":  # its images, in its zip
            from .threemf import texture_sizes
            return texture_sizes(self.path)
        return ()


def mesh_source(path: Path) -> MeshSource:
    """The MeshSource of the file at `path` as it is now. Reads only what is small: an OBJ is scanned for its
    `mtllib` lines in 1 MB blocks and its .mtl files (at most 16 MiB each) parsed; a glTF's JSON (at most
    io.gltf.JSON_LIMIT) parsed, not a .glb's binary chunk. A file that cannot be read gives a source with what
    could be (the read words the error)."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        version = file_version(path)
    except OSError:
        return MeshSource(path, suffix, None)
    if suffix == ".obj":
        try:
            with open_regular(path, str(path), "mesh file") as handle:
                lines = scan_mtllib(handle)
        except (OSError, SceneError):
            lines = []  # the read words it
        names = mtllib_names(lines, path.parent)
        materials = read_obj_materials(path, names)
        images = tuple(dict.fromkeys(texture.source for texture in materials.sources))
        side = tuple(path.parent / name for name in names)
        return MeshSource(path, suffix, version, side, None, materials, images, _stamps(side))
    if suffix in (".gltf", ".glb"):
        document = read_document(path)
        side = buffer_files(document.tree, path.parent) if suffix == ".gltf" else ()
        images = tuple(uri_file(path.parent, uri) for uri in image_uris(document.tree))
        return MeshSource(path, suffix, version, side, document, None, images, _stamps(side))
    return MeshSource(path, suffix, version)


def _stamps(files) -> tuple:
    def stamp(file: Path) -> tuple:
        try:
            return file_version(file)
        except OSError:
            return (str(file), None)
    return tuple(stamp(file) for file in files)


def mesh_sources(scene, given: dict | None = None) -> dict[Path, MeshSource]:
    """A MeshSource for each mesh file `scene` reads, keyed by its resolved path (as scene.resolve gives it):
    those `given` (or the scene's own, Scene.mesh_sources) that are still current, the others made now."""
    given = scene.mesh_sources if given is None else given
    found: dict[Path, MeshSource] = {}
    for obj in scene.objects:
        if obj.shape != "mesh" or not obj.path:
            continue
        path = scene.resolve(obj.path)
        if path in found:
            continue
        source = given.get(source_key(path))
        found[path] = source if source is not None and source.current() else mesh_source(path)
    return found


def source_key(path: Path) -> str:
    """The key a MeshSource is found under whatever the path's spelling (relative, absolute, via a link)."""
    try:
        return os.path.realpath(path)
    except (OSError, ValueError):
        return str(path)
