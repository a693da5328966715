"""Build every object's triangles (shapes.py; mesh_file.py reads mesh files, mesh_repair.py mends them), place
them in the world, and give them face and vertex normals (normals.py): one world-space mesh, the Geometry.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..records import Geometry, bounding_box
from ..scene.schema import (
    DEFAULT_MATERIAL,
    MIN_EXTENT,
    POSITION_LIMIT,
    Object,
    Scene,
    SceneError,
    ShadingModel,
    _dotted,
    brightness_problem,
)
from ..tolerances import MIN_DISTANCE
from . import shapes
from .materials import material_rows
from .mesh_repair import merge_duplicate_vertices, repair_winding
from .normals import _normalise_or, compute_corner_normals, face_normals, file_corner_normals

if TYPE_CHECKING:  # mesh_file imports trimesh: only a scene with a mesh file loads it
    from ..io.mesh_file import MeshFile

MODEL_CODE = {ShadingModel.FLAT: 0, ShadingModel.GOURAUD: 1, ShadingModel.PHONG: 2}


class ObjectMesh(NamedTuple):
    """An object's triangles in its own frame, as object_mesh builds or reads them."""
    vertices: np.ndarray         # (V, 3) float64
    faces: np.ndarray            # (F, 3) int64
    normals: np.ndarray | None   # (V, 3) vertex normals a mesh file stores (used when normals is "file" or unset)
    file: MeshFile | None = None  # a mesh file's materials and colours, aligned with `faces`


def build_geometry(scene: Scene, source: str = "<scene>", vertex_normals: bool = True,
                   normal_dtype: type = np.float64) -> Geometry:
    """Concatenate the scene's objects in world space.

    `vertex_normals=False` (the plan's choice for an all-flat scene) leaves corner_normals empty;
    `normal_dtype` is the corner normals' dtype: render() asks for float32 when it shades in float32 (the
    kernel would round them so anyway), which halves the largest array of a smooth mesh.
    """
    material_index = {name: i + 1 for i, name in enumerate(scene.materials)}  # 0 is the built-in default
    parts, notes, file_notes, file_rows = [], [], [], FileRows(scene, material_index)
    for index, obj in enumerate(scene.objects):
        vertices, faces, file_normals, read = object_mesh(scene, obj, index, source)
        face_material = material_index.get(obj.material, 0)
        if read is not None:
            file_notes += read.notes
            if obj.material == "default":  # the file's own materials; any other name paints the whole mesh
                face_material = file_rows.faces(read)
        exact = exact_corner_normals(obj, vertices, faces) if vertex_normals and obj.normals == "exact" else None
        if obj.shape == "mesh":
            faces, flipped, outward = repair_winding(vertices, faces)
            if flipped:
                notes.append(f"objects.{index}: the winding of {flipped} of {len(faces)} faces was repaired"
                             + (" (and turned outward: the mesh is closed)" if outward else ""))
        vertices, faces, file_normals = place(obj, vertices, faces, file_normals)
        reach = float(np.abs(vertices).max())
        if not reach <= POSITION_LIMIT:  # NaN fails the comparison too
            raise SceneError(f"{source}: objects.{index}: placed (scale, rotate, translate), the object reaches a "
                             f"coordinate of {reach:.3g}; allowed: within ±{POSITION_LIMIT:g}, so distances squared "
                             "stay finite in float32; lower scale, its size or translate")
        low, high = bounding_box(vertices)
        if not (high - low).any():
            raise SceneError(f"{source}: objects.{index}: placed, the object collapses to a single point (its scale "
                             f"{list(obj.scale)} is below float64's resolution at translate {list(obj.translate)}); "
                             "allowed: an object with some extent; raise scale or its size")
        unit, doubled_area = face_normals(vertices, faces)
        model = MODEL_CODE[scene.shading_of(obj)]
        corners = None
        if vertex_normals:
            if exact is not None:
                corners = exact.astype(normal_dtype, copy=False)
            elif file_normals is not None:
                corners = file_corner_normals(file_normals, faces, unit, normal_dtype)
            else:
                corners = compute_corner_normals(vertices, faces, obj.normals or "mean", obj.crease_angle,
                                                 normal_dtype, normals=(unit, doubled_area))
        del doubled_area
        parts.append((vertices, faces, unit, corners, face_material, model))

    offset = np.cumsum([0] + [len(p[0]) for p in parts])
    faces = np.empty((sum(len(p[1]) for p in parts), 3), np.int32)  # filled part by part: no int64 copies
    for (_, part_faces, *_), start, first in zip(parts, np.cumsum([0] + [len(p[1]) for p in parts]), offset):
        np.add(part_faces, first, out=faces[start:start + len(part_faces)], casting="unsafe")
    geometry = Geometry(
        vertices=_joined([p[0] for p in parts]),
        faces=faces,
        face_normals=_joined([p[2] for p in parts]),
        corner_normals=(_joined([p[3] for p in parts]) if vertex_normals
                        else np.zeros((0, 3, 3), normal_dtype)),
        face_material=np.concatenate([np.broadcast_to(np.asarray(p[4], np.int32), len(p[1])) for p in parts]),
        face_model=np.concatenate([np.full(len(p[1]), p[5], np.int8) for p in parts]),
        face_object=np.concatenate([np.full(len(p[1]), i, np.int32) for i, p in enumerate(parts)]),
        notes=tuple(notes),
        file_materials=file_rows.table(),
        file_notes=tuple(dict.fromkeys(file_notes)),
    )
    check_float_range(scene, geometry.vertices, source)
    return geometry


def _joined(arrays: list[np.ndarray]) -> np.ndarray:
    """np.concatenate, but a lone array as it is: a one-mesh scene makes no copy of its largest arrays."""
    return arrays[0] if len(arrays) == 1 else np.concatenate(arrays)


def check_float_range(scene: Scene, vertices: np.ndarray, source: str = "<scene>") -> None:
    """Refuse a scene whose placed extent or 1/d² lights would leave float32's range (SceneError).

    The half-extent must be at least MIN_EXTENT; a 1/d² light's f_att is at most 1/max(d, floor)², d its
    distance to the scene's bounding box and floor tolerances.MIN_DISTANCE × the half-extent, and the lights
    must keep every pixel channel below INTENSITY_LIMIT with that gain (scene.brightness_problem).
    """
    low, high = bounding_box(vertices)
    extent = float((high - low).max()) / 2  # as intersect.unit_frame measures it
    if extent < MIN_EXTENT:
        raise SceneError(f"{source}: objects: the whole scene spans only {2 * extent:.3g} (its largest bounding-box "
                         f"side); allowed: at least {2 * MIN_EXTENT:g}, so the 1/d² floor and Embree's unit frame "
                         "stay in float32's range; raise the objects' scale or size")
    floor = MIN_DISTANCE * extent
    gains = {}
    for k, light in enumerate(scene.lights):
        if light.type == "point" and light.attenuation == "inverse_square":
            position = np.asarray(light.position)
            d = float(np.linalg.norm(np.maximum(np.maximum(low - position, position - high), 0.0)))
            gains[k] = 1.0 / max(d, floor) ** 2
    problem = brightness_problem(scene, gains, why="with 1/d² attenuation up to "
                                 f"{max(gains.values(), default=1.0):.3g} (the light at or near the scene), ")
    if problem:
        raise SceneError(f"{source}: {_dotted(problem[0])}: {problem[1]}")


def behind_camera(scene: Scene, vertices: np.ndarray) -> str | None:
    """A one-line warning if every placed vertex lies behind the camera (or on its plane), else None:
    no ray can hit anything, so the image is only background."""
    eye = np.asarray(scene.camera.position)
    forward = np.asarray(scene.camera.look_at) - eye
    if ((vertices - eye) @ forward).max() > 0:
        return None
    return (f"every object is behind the camera (camera.position {list(scene.camera.position)} looks toward "
            f"look_at {list(scene.camera.look_at)}); the image will be only background")


THIN = 2.0 ** -23  # float32's resolution: a tube thinner than this share of the shape collapses in Embree's frame


class FileRows:
    """The material table's rows after the scene's own: one per distinct (file material, colour) of the mesh
    files' faces. A file material the scene defines by name ([materials.NAME]) uses the scene's row instead."""

    def __init__(self, scene: Scene, material_index: dict[str, int]):
        self.scene, self.material_index = scene, material_index
        self.rows: list[np.ndarray] = []
        self.first = 1 + len(scene.materials)  # row of the first file material: after the default and the scene's

    def faces(self, read: MeshFile) -> np.ndarray:
        """(F,) int32 material rows for the faces of one mesh file."""
        default = self.scene.materials.get("default", DEFAULT_MATERIAL)
        named = [self.scene.materials.get(m.name, m) for m in read.materials] + [default]  # -1: no material
        group = np.where(read.face_group < 0, len(named) - 1, read.face_group)
        if read.face_colour is None:  # one row per material: no sort of the faces
            self.rows.append(self._rows(named, np.arange(len(named)), np.zeros(len(named), np.int64)))
            return (self.first + sum(len(r) for r in self.rows[:-1]) + group).astype(np.int32)
        # Colours replace k_d and k_a (docs/meshes.md); -1 marks faces of a part without colours.
        sums = read.face_colour.astype(np.int64)
        colour_code = np.where(sums[:, 0] < 0, 0, 1 + (sums[:, 0] << 20 | sums[:, 1] << 10 | sums[:, 2]))
        keys, inverse = np.unique(group.astype(np.int64) << 31 | colour_code, return_inverse=True)
        rows = self._rows(named, keys >> 31, keys & ((1 << 31) - 1))
        self.rows.append(rows)
        return (self.first + sum(len(r) for r in self.rows[:-1]) + inverse.reshape(-1)).astype(np.int32)

    @staticmethod
    def _rows(named: list, groups: np.ndarray, codes: np.ndarray) -> np.ndarray:
        def column(key: str) -> np.ndarray:  # one row per key: a colour mesh may have a million of them
            return np.array([getattr(m, key) for m in named], np.float64).reshape(len(named), -1)[groups]
        ka, kd = column("ka"), column("kd")
        coloured = codes > 0
        if coloured.any():
            code = codes[coloured] - 1
            colour = np.column_stack([code >> 20, (code >> 10) & 1023, code & 1023]) / 765.0  # mean of 3 × 8 bit
            ka[coloured] = kd[coloured] = colour
        return material_rows(ka, kd, column("ks"), column("ke"), column("shininess")[:, 0])

    def table(self) -> np.ndarray:
        return np.concatenate(self.rows) if self.rows else material_rows(*(np.zeros((0, 3)),) * 4, np.zeros(0))


def object_mesh(scene: Scene, obj: Object, index: int, source: str) -> ObjectMesh:
    """The object's triangles in its own frame (a mesh file's with its materials, colours and normals)."""
    if obj.shape == "mesh":
        return _load_mesh(scene, obj, index, source)
    if obj.shape == "plane":
        return ObjectMesh(*plane_mesh(obj.size or (2.0, 2.0), obj.segments or (1, 1)), None)
    # Build at unit size and scale after, so a shape of radius 1e-20 or 1e15 has the same well-scaled triangles.
    lengths = {"icosphere": (obj.radius,), "uv_sphere": (obj.radius,), "box": obj.size or (2.0, 2.0, 2.0),
               "cylinder": (obj.radius, obj.height), "torus": (obj.major_radius, obj.minor_radius)}[obj.shape]
    unit = max(lengths)
    # A tube thinner than float32's resolution of the whole (Embree's precision) has nothing to hit.
    thin = {"cylinder": obj.radius, "torus": obj.minor_radius}.get(obj.shape, unit)
    if thin < THIN * unit:
        raise SceneError(f"{source}: objects.{index}: a {obj.shape} with lengths {list(lengths)} has no triangles "
                         f"Embree can hit: its {'radius' if obj.shape == 'cylinder' else 'minor_radius'} is below "
                         f"float32's resolution of its size; allowed: at least {THIN:.3g} of the larger length")
    if obj.shape == "icosphere":
        vertices, faces = shapes.icosphere(obj.subdivisions)
    elif obj.shape == "uv_sphere":
        vertices, faces = shapes.uv_sphere(obj.segments or (32, 16))
    elif obj.shape == "box":
        vertices, faces = shapes.box([length / unit for length in lengths])
    elif obj.shape == "cylinder":
        vertices, faces = shapes.cylinder(obj.radius / unit, obj.height / unit, (obj.segments or (32, 1))[0])
    else:
        major, minor = obj.segments or (32, 16)
        vertices, faces = shapes.torus(obj.major_radius / unit, obj.minor_radius / unit, major, minor)
    return ObjectMesh(vertices * unit, faces, None)


def plane_mesh(size, segments) -> tuple[np.ndarray, np.ndarray]:
    """A width × depth grid in the local x–z plane, centred, wound so its normal is +y."""
    nx, nz = segments
    xs = np.linspace(-size[0] / 2, size[0] / 2, nx + 1)
    zs = np.linspace(-size[1] / 2, size[1] / 2, nz + 1)
    x, z = np.meshgrid(xs, zs, indexing="ij")
    vertices = np.column_stack([x.ravel(), np.zeros(x.size), z.ravel()])
    i, k = np.meshgrid(np.arange(nx), np.arange(nz), indexing="ij")
    a = (i * (nz + 1) + k).ravel()
    b, c, d = a + (nz + 1), a + (nz + 1) + 1, a + 1  # (x+1, z), (x+1, z+1), (x, z+1)
    # (a, d, c) and (a, c, b): counter-clockwise seen from +y, so the cross product points up.
    faces = np.concatenate([np.column_stack([a, d, c]), np.column_stack([a, c, b])])
    return vertices, faces


def _load_mesh(scene: Scene, obj: Object, index: int, source: str):
    path = scene.resolve(obj.path)
    from ..io.mesh_file import read_mesh  # imports trimesh (0.2–0.3 s): only for mesh files

    read = read_mesh(path, f"{source}: objects.{index}.path")
    normals = read.normals if obj.normals in (None, "file") else None  # unset: the file's, if it has them
    if obj.normals == "file" and normals is None:
        raise SceneError(f'{source}: objects.{index}.normals: "file" but {str(path)!r} stores no vertex '
                         'normals; use "mean", "area" or "angle"')
    if normals is not None:  # keep the file's vertex order: its normals are per vertex
        return ObjectMesh(read.vertices, read.faces, normals, read)
    # Otherwise merge what the file repeats (the faces and their order stay, so the per-face materials line up).
    # The scene named a rule, so the file's normals neither shade nor keep its points apart.
    vertices, faces = merge_duplicate_vertices(read.vertices, read.faces)
    return ObjectMesh(vertices, faces, None, read)


def rotation_of(obj: Object) -> np.ndarray:
    """3×3 rotation about x, then y, then z, by the object's angles in degrees."""
    turns = []
    for axis, degrees in enumerate(obj.rotate):
        cos, sin = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
        i, j = (axis + 1) % 3, (axis + 2) % 3  # the plane it turns: y→z about x, z→x about y, x→y about z
        turn = np.eye(3)
        turn[i, i] = turn[j, j] = cos
        turn[j, i], turn[i, j] = sin, -sin
        turns.append(turn)
    return turns[2] @ turns[1] @ turns[0]


def place(obj: Object, vertices, faces, file_normals):
    """World = R (S v) + t; a mirroring scale reverses the winding so faces still point outward."""
    rotation, scale = rotation_of(obj), np.asarray(obj.scale)
    if not any(obj.rotate) and (scale == 1).all():
        placed = vertices + np.asarray(obj.translate)  # the same numbers; a (V, 3) @ (3, 3) is slow for large V
    else:
        placed = (vertices * scale) @ rotation.T + np.asarray(obj.translate)
    if file_normals is not None:
        file_normals = place_normals(obj, file_normals)
    if np.prod(scale) < 0:
        faces = faces[:, ::-1]
    return placed, faces, file_normals


def place_normals(obj: Object, normals: np.ndarray) -> np.ndarray:
    """Object-frame normals (..., 3) → unit world normals; zero where one has no direction (the caller's
    fallback then applies). Normals transform with the inverse transpose: (R S)^-T = R S^-1, which stretches
    by at most 1/min|s|."""
    rotation, scale = rotation_of(obj), np.asarray(obj.scale)
    reach = np.linalg.norm(normals, axis=-1, keepdims=True) / np.abs(scale).min()
    # (n / s) @ R^T as three scaled columns of R: numpy's matmul with a 3-wide inner dimension took 95 ms for
    # 245,760 corners on a busy 2-core machine, this 4 ms.
    placed = sum(normals[..., k:k + 1] * (rotation[:, k] / scale[k]) for k in range(3))
    return _normalise_or(placed, np.zeros_like(normals), reach)


def exact_corner_normals(obj: Object, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """`normals = "exact"`: the true surface normal of the built-in shape at every face corner (F, 3, 3),
    placed in the world and in the corner order of place()'s faces.

    From the shape's parameters in its own frame (vertices, faces as object_mesh gives them): sphere p/|p|;
    torus p minus the nearest point of the tube's centre circle (radius major_radius in the x–y plane);
    cylinder radial (x, y, 0) on the side faces and ±z on the caps, decided per face by its face normal (the
    rim vertices are shared by both); box and plane the face normal, which is exact. The error of a vertex
    normal then comes from the interpolation alone, so the shading orders are the textbook's.
    """
    corners = vertices[faces]  # (F, 3, 3)
    unit, _ = face_normals(vertices, faces)
    flat = np.repeat(unit[:, None, :], 3, axis=1)
    if obj.shape in ("icosphere", "uv_sphere"):
        local = corners
    elif obj.shape == "torus":
        ring = np.hypot(corners[..., 0], corners[..., 1])
        centre = obj.major_radius * corners[..., :2] / np.where(ring > 0, ring, 1.0)[..., None]
        local = np.concatenate([corners[..., :2] - centre, corners[..., 2:]], axis=-1)
    elif obj.shape == "cylinder":
        radial = np.concatenate([corners[..., :2], np.zeros_like(corners[..., 2:])], axis=-1)
        cap = np.abs(unit[:, 2]) > 0.5  # a cap face's normal is ±z, a side face's lies in the x–y plane
        local = np.where(cap[:, None, None], np.sign(unit[:, None, 2:3]) * np.array([0.0, 0.0, 1.0]), radial)
    else:  # box, plane: flat faces
        local = flat
    local = _normalise_or(local, flat, np.linalg.norm(local, axis=-1, keepdims=True).max())
    placed = place_normals(obj, local.reshape(-1, 3)).reshape(-1, 3, 3)
    return placed[:, ::-1] if np.prod(obj.scale) < 0 else placed  # place() reversed the mirrored winding


