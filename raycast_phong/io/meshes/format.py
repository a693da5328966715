"""The one interface every mesh file format fills: a MeshFormat record, made once in the format's own module
(io/meshes/obj.py, ply.py, ...) and listed in the registry (io/meshes/__init__.py). Nothing outside io/meshes/
names a suffix: a stage asks the file's format (MeshSource.format) what it wants to know.

No trimesh: the registry, the memory estimate and framing's checks stay light; a format's `read` imports what
it reads with.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO, NamedTuple

import numpy as np

from ...errors import Where

MeshSource = Any  # io/meshes/source.py's, which imports the registry: named here without importing it

# Reading a file that may be text costs this many bytes a byte of it at least, whatever its header claims: the
# text, its decoded str and its split tokens (trimesh 4, peak RSS over the interpreter's: an icosphere-7 OBJ of
# 12.8 MB 93 MB; a 100 MB OBJ of vertex lines 1.0 GB, of one line 1.9 GB, of face lines 2.0 GB).
TEXT_READ_BYTES_PER_BYTE = 12
# trimesh's load of a file of a format with no measured figure, above the render's own peak, a triangle.
OTHER_PARSE_BYTES = 550


class Part(NamedTuple):
    """One placed triangle mesh of a file."""
    vertices: np.ndarray          # (V, 3) float64, placed by its node's transform
    faces: np.ndarray             # (F, 3) int64
    normals: np.ndarray | None    # (V, 3) the normals the file stores, transformed with the vertices
    visual: object                # trimesh's visual (its material, its colours), a materials.PartSurface
                                  # (the formats read here), or None (no colours, no material)
    colours: np.ndarray | None = None  # (V, 3|4) vertex colours kept on the mesh beside a material (a COLLADA
                                       # COLOR input: trimesh stores them there, not on the visual)


def placed(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray | None,
           matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """A part's (vertices, faces, normals) placed by a node's (4, 4) matrix: vertices by it, normals by its
    inverse transpose (dropped if it is singular: their length is set by the geometry stage), faces turned over
    where it mirrors, so they stay outward. The identity leaves the arrays as they are (most files). A NaN or
    infinite coordinate is carried through without numpy's warning: the read's values check words it."""
    if np.array_equal(matrix, np.eye(4)):
        return vertices, faces, normals
    linear = matrix[:3, :3]
    with np.errstate(invalid="ignore", over="ignore"):
        determinant = np.linalg.det(linear)
        vertices = vertices @ linear.T + matrix[:3, 3]
        normals = None if normals is None or determinant == 0 else normals @ np.linalg.inv(linear)
    return vertices, faces[:, ::-1] if determinant < 0 else faces, normals


class Reading(NamedTuple):
    """What a format's `read` is given: the file open at its start, what was learnt of the file before (its
    MeshSource: its path, where errors point), and the lists its notes and texture sources are added to."""
    handle: BinaryIO
    source: MeshSource
    notes: list[str]
    textures: list                 # materials.TextureSource each

    @property
    def path(self) -> Path:
        return self.source.path

    @property
    def where(self) -> Where:
        return self.source.where


@dataclass(frozen=True)
class Loaded:
    """What a format's `read` gives io/meshes/read.py to finish into a MeshFile."""
    parts: list                                    # trimesh_parts.Part each: one placed triangle mesh
    up: tuple[float, float, float] | None = None   # the up axis the file itself states (COLLADA's <up_axis>)
    library: dict | None = None                    # an OBJ's materials by name (its .mtl files)
    samplers: dict = field(default_factory=dict)   # a glTF's material extensions and samplers (io.meshes.gltf)
    # The format's own reading of a metallic-roughness material trimesh made from it (COLLADA's effects), given
    # that material and the glTF rule's reading of it; None (or a None result): the glTF rule, noted.
    own_material: Callable[[Any, Any], Any] | None = None


def weigh(triangles: int, vertices: int) -> int:
    """Triangles, or the vertices less 2 where those are more: a closed surface has T/2 + 2 vertices and an
    open one a few more, so only vertices far beyond what the faces need (millions unused) raise the count.
    A vertex read costs about 130 bytes (7.5M vertex lines of OBJ: 1.0 GB), a triangle's worth more."""
    return max(triangles, vertices - 2)


def _any_content(head: bytes, found: str | None, size: int, suffix: str) -> bool:
    return True


def _none(*_: object) -> None:
    return None


def _text_floor(path: Path, size: int, mesh: MeshSource) -> int:
    return size * TEXT_READ_BYTES_PER_BYTE


def _no_held(path: Path, mesh: MeshSource) -> tuple[int, int]:
    return 0, 0


def _described(path: Path) -> dict[str, Any]:
    return {}


def _no_sizes(mesh: MeshSource) -> tuple[tuple[int, int], ...]:
    return ()


def image_file_sizes(mesh: MeshSource) -> tuple[tuple[int, int], ...]:
    """(height, width) of each image file the mesh's description names (MeshSource.images), from its header;
    a file that is no image is left out (its read says why): the texture_sizes of a format whose maps are files."""
    from ..textures import file_size
    return tuple(size for size in map(file_size, mesh.images) if size)


@dataclass(frozen=True)
class MeshFormat:
    """Everything the renderer does that depends on a mesh file's format, in one record.

    Only `names`, `suffixes` and `read` are required; the defaults are those of a text file read whole by
    trimesh with nothing beside it."""
    names: tuple[str, ...]             # how messages name it, one per suffix ("glTF", "GLB")
    suffixes: tuple[str, ...]          # lower case, with the dot
    read: Callable[[Reading], Loaded]  # the open file into placed parts
    # Whether a file's first bytes (`head`) fit this format: `found` is what content.sniff calls them, `size`
    # the file's size, `suffix` its suffix; a file that does not fit is refused in one line before any reader.
    content: Callable[[bytes, str | None, int, str], bool] = _any_content
    # Triangles from the header or a cheap scan (size.count_triangles weighs them); None: the size bound.
    count: Callable[[BinaryIO, int, MeshSource], int | None] = _none
    # The least memory reading the file costs, from its size (and side files' sizes) alone.
    floor: Callable[[Path, int, MeshSource], int] = _text_floor
    # What a read decodes besides the file's bytes, for the refusal's words: (external buffers, unzipped bytes).
    held: Callable[[Path, MeshSource], tuple[int, int]] = _no_held
    parse_bytes: int = OTHER_PARSE_BYTES  # a read's bytes a triangle above the render's own peak
    # What is wrong with a file its reader refused, in the renderer's words naming the line (the file open at
    # its start, its MeshSource); None to word the reader's refusal.
    explain: Callable[[BinaryIO, MeshSource], str | None] = _none
    # What the file names beside it, made into MeshSource fields (side_files, document, materials, images).
    describe: Callable[[Path], dict[str, Any]] = _described
    texture_sizes: Callable[[MeshSource], tuple[tuple[int, int], ...]] = _no_sizes  # (height, width) of each map
    up: tuple[float, float, float] | None = None  # the up axis its specification states
    linear: str | None = None          # the specification that says its colours are linear (render.colour)
    pbr: str = "metallic-roughness (PBR)"  # how the note on approximated PBR materials names them
    # Kernels a read of this file will compile, from its first bytes (renderer/warmup.py runs them first).
    warm_up: Callable[[BinaryIO], tuple[Callable[[], None], ...]] | None = None

    def name(self, suffix: str) -> str:
        """How messages name the format of a file with `suffix`."""
        return self.names[self.suffixes.index(suffix)] if suffix in self.suffixes else self.names[0]
