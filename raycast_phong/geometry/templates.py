"""A group's template: an object's triangles in its own frame (a built-in shape's from its kind, shapes/;
a mesh file's read by io/meshes/read.py, with its materials, colours and normals), its winding mended
(mesh_repair.py), its stored normals turned outward, and a built-in shape's UVs and exact corner normals.
Every object of a group is placed from it (placing.py).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .. import shapes
from ..errors import Problem, SceneError
from ..scene.schema import Object, Scene
from ..values.messages import Location
from .mesh_repair import WELD_SHARE, merge_duplicate_vertices, number_by_first_use, repair_winding, weld_soup
from .normals import PARALLEL_FACES, _normalise_or, face_normals

if TYPE_CHECKING:  # io.meshes.read imports trimesh: only a scene with a mesh file loads it
    from ..io.meshes.read import MeshFile

OBJECT_CHUNK_VERTICES = 1 << 20  # placed vertices per step of a group: ~25 MB of float64 temporaries
# A mesh file of this many faces or more whose merge kept every point as it is (an indexed PLY, OBJ or glTF) has its
# vertices numbered in the order its faces first use them (mesh_repair.number_by_first_use): the passes after
# then read neighbouring vertices together. Smaller meshes keep the file's order (their passes fit in the cache).
FIRST_USE_FACES = PARALLEL_FACES


class ObjectMesh(NamedTuple):
    """An object's triangles in its own frame, as object_mesh builds or reads them."""
    vertices: np.ndarray         # (V, 3) float64
    faces: np.ndarray            # (F, 3) int64
    normals: np.ndarray | None   # (V, 3) vertex normals a mesh file stores (used when normals is "file" or unset)
    file: MeshFile | None = None  # a mesh file's materials and colours, aligned with `faces`
    crease_angle: float | None = None  # a mesh file's crease angle when the object leaves it unset
    uv: np.ndarray | None = None  # (F, 3, 2) texture coordinates per face corner, aligned with `faces`


class Template(NamedTuple):
    """A group's mesh in the object frame, as every object of the group shares it, and what reading it said."""
    template: ObjectMesh         # mended: the winding repaired (and the corner arrays reordered with it)
    exact: np.ndarray | None     # (F, 3, 3) exact corner normals in the object frame (normals = "exact")
    read: MeshFile | None        # a mesh file as read, before the repair: its faces' material rows come from it
    notes: tuple[str, ...]       # the winding repair, for Geometry.notes
    file_notes: tuple[str, ...]  # what reading the file said, and turned-over normals, for Geometry.file_notes


def group_template(scene: Scene, index: int, wants_exact: bool, sources: dict | None = None) -> Template:
    """The template of the group whose first object is scene.objects[index]: a shape's triangles, or a mesh
    file read, its winding repaired and its stored normals turned outward if they point inward."""
    first = scene.objects[index]
    template = object_mesh(scene, index, sources)
    exact = exact_corner_normals_local(first, template.vertices, template.faces) if wants_exact else None
    read, notes, file_notes = template.file, [], []
    if template.file is not None:
        file_notes += template.file.notes
        faces, flipped, outward = repair_winding(template.vertices, template.faces)
        if flipped and template.uv is not None:  # the corner arrays follow each face's new corner order
            template = template._replace(uv=_follow_corners(template.faces, faces, template.uv))
        if flipped and template.file.corner_colour is not None:
            template = template._replace(file=dataclasses.replace(
                template.file, corner_colour=_follow_corners(template.faces, faces, template.file.corner_colour)))
        if flipped:
            notes.append(f"objects.{index}: the winding of {flipped} of {len(faces)} faces was repaired"
                         + (" (and turned outward: the mesh is closed)" if outward else ""))
        template = template._replace(faces=faces)
        if template.normals is not None:
            against = normals_against_winding(template.vertices, faces, template.normals)
            if against > 0.5:
                template = template._replace(normals=-template.normals)
                file_notes.append(f"objects.{index}: the vertex normals {first.path!r} stores point against "
                                  f"its faces' winding on {against:.0%} of its area; they were turned over")
    return Template(template, exact, read, tuple(notes), tuple(file_notes))


def object_mesh(scene: Scene, index: int, sources: dict | None = None) -> ObjectMesh:
    """Object `index`'s triangles in its own frame (a mesh file's with its materials, colours and normals; a
    built-in shape's from its kind, shapes/); its errors are placed at the object (file: objects.N)."""
    obj, where = scene.objects[index], scene.origin.at("objects", index)
    if shapes.from_file(obj):
        return _load_mesh(scene, obj, where, (sources or {}).get(scene.resolve(obj.path)))
    try:
        return ObjectMesh(*shapes.KINDS[obj.shape].template(obj), None)
    except Problem as problem:
        raise SceneError(problem.problem, where) from None


def shape_uv(obj: Object, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray | None:
    """(F, 3, 2) texture coordinates of a built-in shape's template (object_mesh's vertices and faces), made
    only when the scene has textures (a textured scene's geometry stage calls it); None for a mesh file."""
    return shapes.kind_of(obj).uv(obj, vertices, faces)


def _load_mesh(scene: Scene, obj: Object, where: Location, mesh=None):
    path = scene.resolve(obj.path)
    if mesh is None:
        from ..io.meshes.source import mesh_source
        mesh = mesh_source(path, where.at("path"))
    read = mesh.read()  # imports trimesh (0.2–0.3 s): only for mesh files; errors at the object naming the file
    normals = read.normals if obj.normals in (None, "file") else None  # unset: the file's, if it has them
    if obj.normals == "file" and normals is None:
        raise SceneError(f'"file" but {str(path)!r} stores no vertex normals; use "mean", "area" or "angle"',
                         where.at("normals"))
    if normals is not None:  # keep the file's vertex order: its normals are per vertex
        return ObjectMesh(read.vertices, read.faces, normals, read, uv=read.corner_uv)
    # Otherwise merge what the file repeats (the faces and their order stay, so the per-face materials line up).
    # The scene named a rule, so the file's normals neither shade nor keep its points apart.
    vertices, faces = merge_duplicate_vertices(read.vertices, read.faces)
    vertices, faces, welded = weld_soup(vertices, faces)  # a soup's copies of a point, rounded apart
    if welded:
        read = dataclasses.replace(read, notes=(*read.notes, f"{path}: a triangle soup: {welded:,} copies of "
                                                f"points within {WELD_SHARE:g} of the model's size welded, so "
                                                "its faces share their corners (smooth normals, one winding)"))
    elif len(vertices) == len(read.vertices) and len(faces) >= FIRST_USE_FACES:  # nothing merged or dropped
        vertices, faces = number_by_first_use(vertices, faces)
    # The merged arrays replace the file's: an STL's raw (3F, 3) points need not live through the normals.
    crease = file_crease_angle(obj, read.stores_normals)
    read = dataclasses.replace(read, vertices=read.vertices[:0].copy(), faces=read.faces[:0].copy())  # no views: freed
    return ObjectMesh(vertices, faces, None, read, crease, read.corner_uv)


def normals_against_winding(vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray) -> float:
    """The share of the surface's area (0..1) whose file normals (the mean of a face's three) point against
    the face's winding: most of it means the file's normals are inward (an exporter's flipped `vn`), which
    shades the lit side black."""
    total = against = 0.0
    for at in range(0, len(faces), OBJECT_CHUNK_VERTICES):  # bounded temporaries on a large scan
        part = faces[at:at + OBJECT_CHUNK_VERTICES]
        cross = np.cross(vertices[part[:, 1]] - vertices[part[:, 0]], vertices[part[:, 2]] - vertices[part[:, 0]])
        area = np.linalg.norm(cross, axis=1)
        facing = np.einsum("ij,ij->i", cross, normals[part].sum(axis=1))
        total, against = total + float(area.sum()), against + float(area[facing < 0].sum())
    return against / total if total > 0 else 0.0


def file_crease_angle(obj: Object, stores_normals: bool) -> float | None:
    """The crease angle of a mesh object that leaves crease_angle and normals unset, reading a file that
    stores no normals: FILE_CREASE_ANGLE (a CAD part's edges stay sharp); None otherwise (the object's own)."""
    if stores_normals or obj.normals is not None or "crease_angle" in obj.model_fields_set:
        return None
    from ..io.meshes.materials import FILE_CREASE_ANGLE
    return FILE_CREASE_ANGLE


def exact_corner_normals_local(obj: Object, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """`normals = "exact"`: the true surface normal of the built-in shape at every face corner (F, 3, 3),
    in the corner order of place()'s faces, from the kind's closed form in its own frame (ShapeKind.exact_normals:
    sphere p/|p|, torus and cylinder their own, flat faces the face normal). The error of a vertex normal then
    comes from the interpolation alone, so the shading orders are the textbook's.
    """
    corners = vertices[faces]  # (F, 3, 3)
    unit, _ = face_normals(vertices, faces)
    flat = np.repeat(unit[:, None, :], 3, axis=1)
    local = shapes.KINDS[obj.shape].exact_normals(obj, corners, flat)
    return _normalise_or(local, flat, np.linalg.norm(local, axis=-1, keepdims=True).max())


def _follow_corners(before: np.ndarray, after: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Per-corner values (F, 3, ...) reordered as each face's corners were (repair_winding reverses some):
    corner j of `after` takes the value of the corner of `before` with the same vertex."""
    order = (before[:, None, :] == after[:, :, None]).argmax(axis=2)  # (F, 3): where after's corner was
    return np.take_along_axis(values, order.reshape(*order.shape, *([1] * (values.ndim - 2))), axis=1)
