"""Build every object's triangles (shapes.py; trimesh reads mesh files), place them in the world, compute
face and vertex normals.

Vertex normals are stored per face corner, so a crease split or normals read from a file need no
vertex duplication: corner (f, k) carries the normal that vertex faces[f, k] has *on face f*.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from . import shapes
from .illumination import material_rows
from .lazy import OnFirstUse
from .records import Geometry
from .scene import (
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
from .tolerances import MIN_DISTANCE, NO_DIRECTION

if TYPE_CHECKING:  # mesh_file imports trimesh: only a scene with a mesh file loads it
    from .mesh_file import MeshFile

MODEL_CODE = {ShadingModel.FLAT: 0, ShadingModel.GOURAUD: 1, ShadingModel.PHONG: 2}


class ObjectMesh(NamedTuple):
    """An object's triangles in its own frame, as object_mesh builds or reads them."""
    vertices: np.ndarray         # (V, 3) float64
    faces: np.ndarray            # (F, 3) int64
    normals: np.ndarray | None   # (V, 3) vertex normals a mesh file stores (used when normals is "file" or unset)
    file: MeshFile | None = None  # a mesh file's materials and colours, aligned with `faces`


trimesh = OnFirstUse("trimesh")  # for mesh files only (0.2–0.3 s to import): the built-in shapes are numpy


def build_geometry(scene: Scene, source: str = "<scene>", vertex_normals: bool = True) -> Geometry:
    """Concatenate the scene's objects in world space.

    `vertex_normals=False` (the plan's choice for an all-flat scene) leaves corner_normals empty.
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
        if not np.ptp(vertices, axis=0).any():
            raise SceneError(f"{source}: objects.{index}: placed, the object collapses to a single point (its scale "
                             f"{list(obj.scale)} is below float64's resolution at translate {list(obj.translate)}); "
                             "allowed: an object with some extent; raise scale or its size")
        unit, _ = face_normals(vertices, faces)
        model = MODEL_CODE[scene.shading_of(obj)]
        corners = None
        if vertex_normals:
            if file_normals is not None:
                corners = file_normals[faces]
                corners = _normalise_or(corners, np.repeat(unit[:, None, :], 3, axis=1))
            else:
                corners = compute_corner_normals(vertices, faces, obj.normals or "mean", obj.crease_angle)
        parts.append((vertices, faces, unit, corners, face_material, model))

    offset = np.cumsum([0] + [len(p[0]) for p in parts])
    geometry = Geometry(
        vertices=np.concatenate([p[0] for p in parts]),
        faces=np.concatenate([p[1] + o for p, o in zip(parts, offset)]).astype(np.int32),
        face_normals=np.concatenate([p[2] for p in parts]),
        corner_normals=(np.concatenate([p[3] for p in parts]) if vertex_normals
                        else np.zeros((0, 3, 3))),
        face_material=np.concatenate([np.broadcast_to(np.asarray(p[4], np.int32), len(p[1])) for p in parts]),
        face_model=np.concatenate([np.full(len(p[1]), p[5], np.int8) for p in parts]),
        face_object=np.concatenate([np.full(len(p[1]), i, np.int32) for i, p in enumerate(parts)]),
        notes=tuple(notes),
        file_materials=file_rows.table(),
        file_notes=tuple(dict.fromkeys(file_notes)),
    )
    check_float_range(scene, geometry.vertices, source)
    return geometry


def check_float_range(scene: Scene, vertices: np.ndarray, source: str = "<scene>") -> None:
    """Refuse a scene whose placed extent or 1/d² lights would leave float32's range (SceneError).

    The half-extent must be at least MIN_EXTENT; a 1/d² light's f_att is at most 1/max(d, floor)², d its
    distance to the scene's bounding box and floor tolerances.MIN_DISTANCE × the half-extent, and the lights
    must keep every pixel channel below INTENSITY_LIMIT with that gain (scene.brightness_problem).
    """
    low, high = vertices.min(axis=0), vertices.max(axis=0)
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


def repair_winding(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, int, bool]:
    """Make a mesh file's winding consistent (trimesh.repair), and outward if the mesh is closed.

    Inconsistent winding makes face normals of neighbours cancel in the vertex-normal mean. Returns
    the faces, how many were flipped, and whether the orientation was decided by closedness.
    """
    mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False, validate=False)
    trimesh.repair.fix_winding(mesh)
    closed = mesh.is_watertight
    if closed:
        trimesh.repair.fix_inversion(mesh)
    repaired = np.asarray(mesh.faces, np.int64)
    # A face counts as flipped when its corners no longer come in the same cyclic order.
    same = np.zeros(len(faces), bool)
    for shift in range(3):
        same |= (np.roll(repaired, shift, axis=1) == faces).all(axis=1)
    return repaired, int((~same).sum()), closed


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
    from .mesh_file import read_mesh  # imports trimesh (0.2–0.3 s): only for mesh files

    read = read_mesh(path, f"{source}: objects.{index}.path")
    normals = read.normals if obj.normals in (None, "file") else None  # unset: the file's, if it has them
    if obj.normals == "file" and normals is None:
        raise SceneError(f'{source}: objects.{index}.normals: "file" but {str(path)!r} stores no vertex '
                         'normals; use "mean", "area" or "angle"')
    if normals is not None:  # keep the file's vertex order: its normals are per vertex
        return ObjectMesh(read.vertices, read.faces, normals, read)
    # Otherwise let trimesh merge and clean (merging keeps the faces and their order, so the per-face
    # materials still line up).
    loaded = trimesh.Trimesh(vertices=read.vertices, faces=read.faces, process=False, validate=False)
    loaded.process()
    return ObjectMesh(np.asarray(loaded.vertices, np.float64), np.asarray(loaded.faces, np.int64), None, read)


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
    placed = (vertices * scale) @ rotation.T + np.asarray(obj.translate)
    if file_normals is not None:
        # Normals transform with the inverse transpose: (R S)^-T = R S^-1, which stretches by at most 1/min|s|.
        reach = np.linalg.norm(file_normals, axis=-1, keepdims=True) / np.abs(scale).min()
        file_normals = (file_normals / scale) @ rotation.T
        file_normals = _normalise_or(file_normals, np.zeros_like(file_normals), reach)  # none: the face normal later
    if np.prod(scale) < 0:
        faces = faces[:, ::-1]
    return placed, faces, file_normals


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals (F, 3) (zero for a degenerate face) and twice the areas (F,)."""
    corners = vertices[faces]
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    doubled_area = np.linalg.norm(cross, axis=1)
    unit = np.divide(cross, doubled_area[:, None], out=np.zeros_like(cross), where=doubled_area[:, None] > 0)
    return unit, doubled_area


def corner_angles(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Interior angle at each corner (F, 3), radians; 0 at a degenerate corner."""
    corners = vertices[faces]
    angles = np.zeros(faces.shape)
    for k in range(3):
        a = corners[:, (k + 1) % 3] - corners[:, k]
        b = corners[:, (k + 2) % 3] - corners[:, k]
        # atan2(|a×b|, a·b) is accurate at every angle, unlike acos of a normalised dot.
        angles[:, k] = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), np.einsum("ij,ij->i", a, b))
    return angles


def compute_corner_normals(vertices: np.ndarray, faces: np.ndarray, weighting: str = "mean",
                           crease_angle: float = 180.0) -> np.ndarray:
    """Vertex normal at every face corner (F, 3, 3), unit.

    n_v = normalize(Σ_f w_f n_f) over the faces f around v, with w = 1 ("mean", the lecture's rule),
    the face area ("area") or the corner angle ("angle"); degenerate faces weigh 0. With a crease
    angle below 180°, corner (f, v) only gathers faces g whose normal is within that angle of n_f.
    A vertex whose sum vanishes falls back to the face normal.
    """
    unit, doubled_area = face_normals(vertices, faces)
    if weighting == "mean":
        weights = np.ones(faces.shape)
    elif weighting == "area":
        weights = np.repeat(doubled_area[:, None], 3, axis=1)
    elif weighting == "angle":
        weights = corner_angles(vertices, faces)
    else:
        raise ValueError(f"unknown normal weighting {weighting!r}")
    # (3F, 4), one row per corner: w n_f, and w |n_f| (the length the sum would have if every normal agreed).
    reach = weights * np.linalg.norm(unit, axis=1)[:, None]
    contribution = np.concatenate([weights[:, :, None] * unit[:, None, :], reach[:, :, None]], axis=2).reshape(-1, 4)
    corner_vertex = faces.ravel()
    if crease_angle >= 180.0:
        summed = np.column_stack([np.bincount(corner_vertex, contribution[:, i], minlength=len(vertices))
                                  for i in range(4)])[corner_vertex]
    else:
        summed = _creased_sums(corner_vertex, contribution, np.repeat(unit, 3, axis=0), crease_angle)
    fallback = np.repeat(unit, 3, axis=0)
    return _normalise_or(summed[:, :3], fallback, summed[:, 3:]).reshape(-1, 3, 3)


def _creased_sums(corner_vertex, contribution, corner_face_normal, crease_angle):
    """For each corner, the sum of contributions of the corners at the same vertex whose faces are
    within `crease_angle` of its own face."""
    order = np.argsort(corner_vertex, kind="stable")
    sorted_vertex = corner_vertex[order]
    start = np.searchsorted(sorted_vertex, sorted_vertex, side="left")
    count = np.searchsorted(sorted_vertex, sorted_vertex, side="right") - start
    # Every (corner, neighbour corner) pair that shares a vertex, in sorted positions.
    mine = np.repeat(np.arange(len(order)), count)
    neighbour = start[mine] + (np.arange(len(mine)) - np.repeat(np.cumsum(count) - count, count))
    mine, neighbour = order[mine], order[neighbour]
    # The small slack keeps a face and its exact coplanar neighbour together despite rounding.
    cosine = np.einsum("ij,ij->i", corner_face_normal[mine], corner_face_normal[neighbour])
    smooth = cosine >= math.cos(math.radians(crease_angle)) - 1e-12
    return np.column_stack([np.bincount(mine[smooth], contribution[neighbour[smooth], i], minlength=len(order))
                            for i in range(contribution.shape[1])])


def _normalise_or(vectors: np.ndarray, fallback: np.ndarray, reach: np.ndarray | float = 1.0) -> np.ndarray:
    """Unit vectors; the fallback where a vector has no direction: a length at most NO_DIRECTION × `reach`,
    the length it would have if its parts agreed (a sum of unit normals that nearly cancels points
    wherever rounding sends it). The shading kernel applies the same tolerance to its mixed normals."""
    length = np.linalg.norm(vectors, axis=-1, keepdims=True)
    tiny = length <= NO_DIRECTION * np.asarray(reach)
    return np.where(tiny, fallback, vectors / np.where(tiny, 1.0, length))
