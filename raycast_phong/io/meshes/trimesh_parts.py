"""trimesh's side of reading a mesh file: its load, kept to the file already opened and to regular side files,
and what it loaded as placed parts (Part). The formats that read through trimesh call `load`; the others
(binary STL, a plain OBJ, 3MF) make their Parts themselves."""

from __future__ import annotations

import logging
import warnings
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import trimesh
from PIL.Image import DecompressionBombWarning

from ..files import open_regular
from .format import Part, Reading, placed

TRIMESH = Path(trimesh.__file__).resolve().parent  # an exception that passed through here: trimesh refused the file


class RegularFiles(trimesh.resolvers.FilePathResolver):
    """trimesh's resolver for the files a mesh names (.mtl, textures, glTF buffers), but only regular files:
    a FIFO named by `mtllib` would block the read forever. `locate`: the file a name means beside the mesh (a
    format's own rule: a glTF's URIs are percent-encoded, a PLY's `<this>` is its own name)."""

    decoded: dict[str, bytes] | None = None  # gltf_decode's buffers, by the names its rewritten document gives

    @staticmethod
    def locate(folder: Path, name: str) -> Path:
        return folder / name

    def get(self, name):
        if self.decoded and name in self.decoded:
            return self.decoded[name]
        path = self.locate(Path(self.parent), name)
        with open_regular(path, str(path), "file") as handle:
            return handle.read()


@contextmanager
def trimesh_quiet():
    """trimesh's logger silenced while it reads (it logs a traceback for an image it cannot open; the read says
    one note instead)."""
    logger = logging.getLogger("trimesh")
    before = logger.disabled
    logger.disabled = True
    try:
        yield
    finally:
        logger.disabled = before


def load(reading: Reading, file_obj=None, file_type: str | None = None, resolver: RegularFiles | None = None):
    """trimesh.load of the open file (not the path again: `file_obj`, when given, stands for its content),
    unprocessed: trimesh's cleaning would silently drop NaN vertices and their faces. Files it names are found
    beside it (`resolver`). A PLY float property beyond float32 (5e38) is cast to inf with numpy's warning;
    the read's values check words it in one line."""
    resolver = resolver or RegularFiles(reading.path)
    file_type = file_type or reading.path.suffix.lower()[1:]
    with np.errstate(over="ignore", invalid="ignore"), trimesh_quiet(), warnings.catch_warnings():
        warnings.simplefilter("ignore", DecompressionBombWarning)  # an embedded map's size is weighed before
        return trimesh.load(file_obj=reading.handle if file_obj is None else file_obj, file_type=file_type,
                            resolver=resolver, process=False)


def parts(loaded) -> list[Part]:
    """The triangle meshes of what trimesh loaded, in world placement (a glTF's node transforms applied).

    Not Scene.dump(): its copies forget the vertex normals the file stored. A node transform past float range
    (a COLLADA scale of 1e300) is carried without numpy's warnings from trimesh's graph: the values check words it."""
    if isinstance(loaded, trimesh.Trimesh):
        instances = [(np.eye(4), loaded)]
    elif isinstance(loaded, trimesh.Scene):
        with np.errstate(over="ignore", invalid="ignore"):
            instances = [(np.asarray(loaded.graph[node][0], np.float64), loaded.geometry[loaded.graph[node][1]])
                         for node in loaded.graph.nodes_geometry]
        if not instances:  # a glTF without nodes (a library of meshes, glTF 2.0 §3.5.1): each mesh once, unplaced
            instances = [(np.eye(4), mesh) for mesh in loaded.geometry.values()]
    else:
        instances = []
    found = []
    for transform, mesh in instances:
        if not isinstance(mesh, trimesh.Trimesh) or not len(mesh.faces):
            continue
        # The raw dict, not `in mesh._cache`: that re-hashes the arrays to validate the cache (slow without xxhash).
        normals = mesh._cache.cache.get("vertex_normals")
        vertices, faces, normals = placed(np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64),
                                          None if normals is None else np.asarray(normals, np.float64), transform)
        colours = None if isinstance(mesh.visual, trimesh.visual.ColorVisuals) else mesh.vertex_attributes.get("color")
        found.append(Part(vertices, faces, normals, mesh.visual, colours))
    return found


def raised_in_trimesh(error: BaseException) -> bool:
    """Whether `error` came out of trimesh's own code, i.e. trimesh could not read the file.

    A corrupt file makes trimesh raise almost anything (750 corrupted OBJ, PLY, STL, OFF and GLB files gave
    ValueError, KeyError, IndexError, TypeError, NotImplementedError and, from a bug of its own on a bad PLY
    header, UnboundLocalError), so the type says little; where it was raised says whose problem it is.
    Running out of memory is never the file's fault.
    """
    if isinstance(error, MemoryError):
        return False
    frame = error.__traceback__
    while frame is not None:
        if Path(frame.tb_frame.f_code.co_filename).resolve().is_relative_to(TRIMESH):
            return True
        frame = frame.tb_next
    return False
