"""A mesh given as arrays (numpy, or a trimesh.Trimesh) instead of a file: the same object a file becomes.

`held_mesh` checks the arrays as a mesh file's read checks its vertices (finite, within ±POSITION_LIMIT) and its
faces (whole numbers indexing the vertices), and holds them as the io.meshes.read.MeshFile a read would give, in an
`ArraySource`: a io.meshes.source.MeshSource whose file is never read. A scene names it with a placeholder path
(`<arrays N>`) and carries it in Scene.mesh_sources, as it carries a framed file's; prepare() passes it on, the
memory estimate asks it its triangles (renderer.budget), and the geometry stage's read gets the held MeshFile
from it. So the arrays go through the same validation, estimate and renderer as a file, and nothing is written.
`mesh_scene` (rp.mesh_scene) frames one, as `render model.obj` frames a file.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..errors import SceneError
from ..io.meshes import format_of
from ..io.meshes.source import MeshSource
from ..shapes import MESH
from ..tolerances import POSITION_LIMIT
from ..values.messages import Location, located

if TYPE_CHECKING:
    from .schema import Scene  # imported when a scene is made (mesh_scene), not with this module

_NUMBERS = itertools.count(1)  # each held mesh's own version: its identity, never a file's


@dataclass(frozen=True, eq=False)
class ArraySource(MeshSource):
    """The MeshSource of a mesh given as arrays: its MeshFile, held. Always current (arrays do not change under
    a scene: they were checked and copied when held); its read costs nothing beyond the arrays counted."""
    held: Any = None  # io.meshes.read.MeshFile

    def current(self) -> bool:
        return True

    @property
    def texture_sizes(self) -> tuple:
        """(height, width) of each image a Trimesh's material holds (a PIL image's size is (width, height))."""
        return tuple((size[1], size[0]) for size in (getattr(t.source, "size", None) for t in
                                                     self.held.texture_sources) if size is not None)

    def triangles(self) -> int:
        return len(self.held.faces)

    def read_floor(self) -> int:
        return 0

    def bounds(self):
        return self.held

    def read(self):
        return self.held

    def holds_read(self) -> bool:
        return True


def placeholder(number: int) -> str:
    """The path a scene names a held mesh by: not a file name a scene could mean (load refuses no such path, but
    no file is ever looked for under it while the scene carries the mesh)."""
    return f"<arrays {number}>"


def held_mesh(vertices: Any, faces: Any = None, normals: Any = None, where: str | Location = "mesh_scene",
              folder: str | Path = ".") -> tuple[str, ArraySource]:
    """(the placeholder path, its ArraySource) for `vertices` (V, 3) and `faces` (F, 3), or a trimesh.Trimesh as
    `vertices` (its vertices, faces and, when it has them cached or given, vertex normals); `normals`: (V, 3)
    vertex normals to shade with (normals = "file" then uses them).

    Raises ValueError for arrays of the wrong shape or kind (the message says which and what is wanted), and
    SceneError (one line at `where`) for values a mesh file would be refused for: a NaN, infinite or too large
    coordinate, a face naming a vertex that does not exist, no face at all.
    """
    from ..io.meshes.read import MeshFile  # imports trimesh: only when a mesh is held
    where = located(where)
    visual = None
    if faces is None and hasattr(vertices, "faces") and hasattr(vertices, "vertices"):  # a trimesh.Trimesh
        mesh = vertices
        faces, visual = mesh.faces, getattr(mesh, "visual", None)
        if normals is None and "vertex_normals" in getattr(mesh, "_cache", {}):
            normals = mesh.vertex_normals
        vertices = mesh.vertices
    points = _array(vertices, "vertices", (None, 3), np.floating, np.integer)
    corners = _array(faces, "faces", (None, 3), np.integer)
    if not len(corners):
        raise SceneError("the mesh has no faces; give at least one triangle (faces: (F, 3) vertex indices)", where)
    if corners.min() < 0 or corners.max() >= len(points):
        raise SceneError(f"faces name vertex {int(corners.min() if corners.min() < 0 else corners.max())}, but the "
                         f"mesh has {len(points)} vertices; allowed: 0 ≤ index < {len(points)}", where.at("faces"))
    points = np.array(points, np.float64)  # a copy: the caller's arrays may change after this
    used = points[np.unique(corners)]
    if not (np.abs(used) <= POSITION_LIMIT).all():  # NaN fails too
        bad = int((~(np.abs(used) <= POSITION_LIMIT).all(axis=1)).sum())
        raise SceneError(f"{bad} vertex(es) of a face with NaN, infinite or beyond ±{POSITION_LIMIT:g} coordinates; "
                         f"allowed: finite, within ±{POSITION_LIMIT:g}", where.at("vertices"))
    stored = None
    if normals is not None:
        stored = np.array(_array(normals, "normals", (len(points), 3), np.floating, np.integer), np.float64)
        if not np.isfinite(stored).all():
            raise SceneError("normals hold NaN or infinite values; allowed: finite (V, 3)", where.at("normals"))
    low, high = used.min(axis=0), used.max(axis=0)
    centre = (low + high) / 2
    radius = float(np.linalg.norm(used - centre, axis=1).max())
    number = next(_NUMBERS)
    path = placeholder(number)
    corners = np.array(corners, np.int64)
    surface: tuple = (np.full(len(corners), -1, np.int32), (), None, None, (), ())
    if visual is not None and getattr(visual, "kind", None) is not None:  # colours, a material, UVs
        from ..io.meshes.format import Part
        from ..io.meshes.read import held_surfaces
        surface = held_surfaces(Part(points, corners, stored, visual), Path(str(where)))
    group, materials, corner_uv, corner_colour, textures, notes = surface
    held = MeshFile(points, corners, stored, group, materials, None, notes, centre, radius, stored is not None,
                    corner_uv, corner_colour, textures)
    return path, ArraySource(Path(folder) / path, format_of(path), ("arrays", number), held=held)


def _array(value: Any, name: str, shape: tuple, *kinds) -> np.ndarray:
    """`value` as an array of `shape` (None: any length) whose dtype is one of `kinds`; ValueError otherwise."""
    try:
        array = np.asarray(value)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} must be an array of shape {_shape(shape)}, got {type(value).__name__} ({error})") \
            from None
    fits = array.ndim == len(shape) and all(want is None or got == want for got, want in zip(array.shape, shape))
    if not fits or not any(np.issubdtype(array.dtype, kind) for kind in kinds):
        kind = "whole numbers" if kinds == (np.integer,) else "real numbers"
        raise ValueError(f"{name} must be an array of shape {_shape(shape)} of {kind}, got shape {array.shape} "
                         f"of {array.dtype}")
    return array


def _shape(shape: tuple) -> str:
    return "(" + ", ".join("N" if size is None else str(size) for size in shape) + ")"


def mesh_scene(vertices: Any, faces: Any = None, *, normals: Any = None, name: str = MESH.name,
               view: str | None = None, up: str | None = None, overrides: list[str] | tuple[str, ...] = (),
               folder: str | Path = ".") -> Scene:
    """A Scene showing a mesh given as arrays, framed as `raycast-phong render model.obj` frames a file: one
    `mesh` object, a camera on its bounding sphere from `view` (three_quarter, front, side, top, iso), a key light,
    the default material; then `overrides` (`key.path=value`, as --set). Nothing is written.

    Parameters
    ----------
    vertices: (V, 3) real numbers, or a trimesh.Trimesh (then `faces` stays None; its colours, material and
        texture coordinates are kept, read as a file's are).
    faces: (F, 3) whole numbers, each a vertex index, counter-clockwise seen from outside.
    normals: (V, 3) vertex normals to shade with (used as a mesh file's own normals: normals = "file").
    name: the object's name (and the stem of output.path).
    up: the model's up axis ("+z", "-y", ...; default +y). folder: where the scene's other relative paths start.

    Returns the validated Scene (scene.replace() keeps the mesh; rp.render renders it).

    Raises ValueError for arrays of the wrong shape or kind, SceneError (one line) for a NaN, infinite or too
    large coordinate, a face index out of range, no faces, a model of no size, or an override the format refuses.
    """
    from ..io.encoding import DISPLAY
    from ..io.meshes.source import source_key
    from .framing import check_view, framed_dict
    from .schema import validate_scene
    where = Location("mesh_scene")
    check_view(view, where)
    path, source = held_mesh(vertices, faces, normals, where, folder)
    data = framed_dict(source.bounds(), path, name, DISPLAY, overrides, view, up, where)
    scene = validate_scene(data, source=where, folder=folder)
    scene.mesh_sources[source_key(scene.resolve(path))] = source
    return scene
