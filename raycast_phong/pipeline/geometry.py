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


def bounding_box(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest coordinate (3,) of (V, 3) vertices; NaN if any is NaN (as vertices.min(axis=0)).

    Column by column: numpy reduces a (V, 3) array along axis 0 some 10× slower than three strided columns.
    """
    return (np.array([vertices[:, k].min() for k in range(3)]), np.array([vertices[:, k].max() for k in range(3)]))


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
    """Make a mesh file's winding consistent, and outward if the mesh is closed.

    Inconsistent winding makes face normals of neighbours cancel in the vertex-normal mean. Returns
    the faces, how many were flipped, and whether the mesh is closed (every edge in exactly two faces:
    then it is turned outward, by its signed volume). A consistent mesh, the common case, costs one
    sort of its 3F half-edges (and a closed one its signed volume, taken over the whole mesh as trimesh's
    fix_inversion did: a consistent mesh whose pieces disagree is left to its majority by volume); only an
    inconsistent one pays for the face graph (`_orient_faces`), which also orients each piece by its own volume.
    """
    keys = _half_edge_keys(faces, len(vertices))
    keys.sort()
    # Closed: the sorted undirected edges come in pairs, each pair unlike its neighbours.
    closed = (len(keys) % 2 == 0 and bool(((keys[0::2] >> 1) == (keys[1::2] >> 1)).all())
              and not ((keys[1:-1:2] >> 1) == (keys[2::2] >> 1)).any())
    # Consistent: no half-edge is traversed twice in the same direction (by two faces or a duplicate face).
    if not (keys[1:] == keys[:-1]).any():
        del keys
        if closed and _signed_volumes(vertices, faces)[0] < 0:
            return faces[:, ::-1], len(faces), True
        return faces, 0, closed
    del keys
    flip = _orient_faces(vertices, faces, closed)
    repaired = faces.copy()
    repaired[flip] = faces[flip, ::-1]
    return repaired, int(flip.sum()), closed


def _orient_faces(vertices: np.ndarray, faces: np.ndarray, closed: bool) -> np.ndarray:
    """Which faces to flip (F,) bool so that every edge shared by exactly two faces is traversed in
    opposite directions; per connected piece the orientation that flips fewer faces, or, if the mesh is
    closed, the one with positive signed volume. A non-orientable piece (a Möbius strip) is left as it is.

    Orientation is a two-colouring: face f as it is is node f, flipped node f + F; an edge whose two faces
    agree joins (f, g) and (f + F, g + F), one where they disagree (f, g + F) and (f + F, g). The graph's
    connected components (scipy.sparse.csgraph, linear) then give every face's orientation relative to
    its piece at once; a piece whose f and f + F fall in one component cannot be oriented.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    count = len(faces)
    keys = _half_edge_keys(faces, len(vertices))
    order = np.argsort(keys, kind="stable")
    keys, face = keys[order], order // 3
    edge = keys >> 1
    first = np.flatnonzero(np.r_[True, edge[1:] != edge[:-1]])
    runs = np.diff(np.r_[first, len(edge)])
    shared = first[runs == 2]  # manifold edges only: a third face makes orientation ambiguous there
    f, g = face[shared], face[shared + 1]
    agree = (keys[shared] & 1) != (keys[shared + 1] & 1)
    rows = np.concatenate([f, f + count])
    cols = np.concatenate([np.where(agree, g, g + count), np.where(agree, g + count, g)])
    graph = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(2 * count, 2 * count))
    _, label = connected_components(graph, directed=False)
    as_is, flipped = label[:count], label[count:]
    piece = np.minimum(as_is, flipped)  # one name per piece, whichever node carries it
    orientable = as_is != flipped
    # Keep the side of each piece that most faces already have; a closed mesh: the side of positive volume.
    votes = np.bincount(piece, np.where(as_is == piece, 1.0, -1.0), minlength=2 * count)
    flip = orientable & ((as_is == piece) != (votes[piece] >= 0))
    if closed:
        sign = np.where(flip, -1.0, 1.0)
        inward = _signed_volumes(vertices, faces, piece, 2 * count, sign) < 0
        flip ^= orientable & inward[piece]
    return flip


def _half_edge_keys(faces: np.ndarray, vertex_count: int) -> np.ndarray:
    """(3F,) int64, one per half-edge (start → end) of face f's corner k at 3f + k: the undirected edge
    (low · V + high), shifted left one bit for its direction (1 where start > end). Built in place: the
    3F half-edges are the largest arrays of mesh preparation."""
    start = np.ascontiguousarray(faces, np.int64).ravel()
    end = np.roll(faces, -1, axis=1).astype(np.int64).ravel()
    keys = np.minimum(start, end)
    keys *= vertex_count
    np.maximum(start, end, out=end)
    keys += end
    del end
    keys <<= 1
    keys += np.roll(faces, -1, axis=1).ravel() < start  # start > end
    return keys


FACE_CHUNK = 1 << 18  # faces per step of a per-face computation: ~25 MB of temporaries, whatever the mesh


def _signed_volumes(vertices: np.ndarray, faces: np.ndarray, piece: np.ndarray | None = None, pieces: int = 1,
                    sign: np.ndarray | float = 1.0) -> np.ndarray:
    """Six times the signed volume enclosed by each piece's faces (divergence theorem: Σ v0 · (v1 × v2)),
    (pieces,) float64; piece (F,) numbers each face's piece (None: one piece), `sign` (F,) −1 for a face
    taken flipped. Measured from the bounding-box centre, so a mesh far from the origin keeps its digits."""
    low, high = bounding_box(vertices)
    centred = vertices - (low + high) / 2
    sign = np.broadcast_to(sign, len(faces))
    total = np.zeros(pieces)
    for at in range(0, len(faces), FACE_CHUNK):
        part = faces[at:at + FACE_CHUNK]
        v0, v1, v2 = (centred[part[:, k]] for k in range(3))
        six = np.einsum("ij,ij->i", v0, cross_rows(v1, v2)) * sign[at:at + FACE_CHUNK]
        total += six.sum() if piece is None else np.bincount(piece[at:at + FACE_CHUNK], six, minlength=pieces)
    return total


def merge_duplicate_vertices(vertices: np.ndarray, faces: np.ndarray,
                             normals: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices at exactly the same position and drop those no face uses; the first of each kept, in file order.

    What trimesh's process() did that matters for shading: a file that repeats a point for every face
    around it (STL always, OBJ and PLY often) must share it, or the vertex-normal mean sees one face
    and the surface shades faceted. As process(), vertices whose file normals (V, 3) differ (rounded to
    0.01) stay apart: a hard edge the file draws stays hard. Unlike process(): positions are compared
    exactly (−0 = +0), not rounded to trimesh's 1e-8 grid, and UV coordinates do not keep two vertices
    apart (the renderer reads no textures: a texture seam is no edge of the surface). Rows are hashed
    to one uint64 and the hashes sorted (V log V, numpy's vectorised sort); equal hashes are then
    checked value by value.
    """
    used = np.zeros(len(vertices), bool)
    used[faces] = True
    index = np.flatnonzero(used)
    rows = vertices[index] if normals is None else np.column_stack([vertices[index], np.round(normals[index] * 100)])
    rows += 0.0  # −0.0 + 0.0 is +0.0: the two zeros are one value
    key = _row_hashes(rows)
    order = np.argsort(key)
    key = key[order]
    starts = np.r_[True, key[1:] != key[:-1]]
    del key
    if starts.all():
        if len(index) == len(vertices):
            return vertices, faces  # nothing to merge or drop: no copies
        first = np.arange(len(index))
    else:
        # The first row (in file order) of each run of equal keys stands for the run.
        first_sorted = np.minimum.reduceat(order, np.flatnonzero(starts))[np.cumsum(starts) - 1]
        # A run holds one row unless two rows collided in the hash (about 2^-64 per pair): then fall back
        # to numpy's exact (and slower) row comparison.
        if (rows[first_sorted] == rows[order]).all():
            first = np.empty_like(order)
            first[order] = first_sorted  # from sorted positions back to the rows' order
        else:
            _, first_seen, inverse = np.unique(rows, axis=0, return_index=True, return_inverse=True)
            first = first_seen[inverse.ravel()]
    # first[i]: the first vertex (in `index` order) at point i's position; number the firsts in order.
    keep = first == np.arange(len(first))
    number = np.cumsum(keep) - 1
    new_of_old = np.full(len(vertices), -1, np.int64)
    new_of_old[index] = number[first]
    return vertices[index[keep]], new_of_old[faces]


def _row_hashes(rows: np.ndarray) -> np.ndarray:
    """One uint64 per row of a float64 array (N, C): splitmix64's mixer over the columns in turn, so every
    input bit reaches every output bit (float32 data in float64 leaves the low 29 mantissa bits zero)."""
    bits = rows.view(np.uint64)
    key = np.zeros(len(rows), np.uint64)
    for column in range(bits.shape[1]):
        key ^= bits[:, column]
        key ^= key >> np.uint64(30)
        key *= np.uint64(0xBF58476D1CE4E5B9)
        key ^= key >> np.uint64(27)
        key *= np.uint64(0x94D049BB133111EB)
        key ^= key >> np.uint64(31)
    return key


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


def face_normals(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit face normals (F, 3) (zero for a degenerate face) and twice the areas (F,)."""
    unit, doubled_area = np.zeros((len(faces), 3)), np.empty(len(faces))
    for at in range(0, len(faces), FACE_CHUNK):  # in chunks: the outputs are the only (F, ·) arrays
        part = faces[at:at + FACE_CHUNK]
        first = vertices[part[:, 0]]
        cross = cross_rows(vertices[part[:, 1]] - first, vertices[part[:, 2]] - first)
        area = np.sqrt(cross[:, 0] * cross[:, 0] + cross[:, 1] * cross[:, 1] + cross[:, 2] * cross[:, 2])
        np.divide(cross, area[:, None], out=unit[at:at + FACE_CHUNK], where=area[:, None] > 0)
        doubled_area[at:at + FACE_CHUNK] = area
    return unit, doubled_area


def cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a × b row by row, (N, 3): np.cross's arithmetic (so its bits) without its (N, 3) temporaries."""
    cross = np.empty_like(a)
    for k in range(3):
        i, j = (k + 1) % 3, (k + 2) % 3
        np.subtract(a[:, i] * b[:, j], a[:, j] * b[:, i], out=cross[:, k])
    return cross


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
                           crease_angle: float = 180.0, dtype: type = np.float64,
                           normals: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Vertex normal at every face corner (F, 3, 3), unit, in `dtype`.

    n_v = normalize(Σ_f w_f n_f) over the faces f around v, with w = 1 ("mean", the lecture's rule),
    the face area ("area") or the corner angle ("angle"); degenerate faces weigh 0. With a crease
    angle below 180°, corner (f, v) only gathers faces g whose normal is within that angle of n_f.
    A vertex whose sum vanishes falls back to the face normal. `normals`: face_normals(vertices, faces)
    if the caller has them. The sums are per vertex, (V, 4) float64, and only the result is per corner
    (36 bytes a triangle in float32, 72 in float64); only corners at a vertex a crease may split pay
    for the pairwise test (_creased_vertices).
    """
    unit, doubled_area = normals if normals is not None else face_normals(vertices, faces)
    if weighting == "mean":
        weights = None
    elif weighting == "area":
        weights = np.repeat(doubled_area[:, None], 3, axis=1)
    elif weighting == "angle":
        weights = corner_angles(vertices, faces)
    else:
        raise ValueError(f"unknown normal weighting {weighting!r}")
    # w |n_f|: the length the sum would have if every normal agreed (|n_f| is 1, or 0 for a degenerate face).
    length = np.linalg.norm(unit, axis=1)
    reach = (np.repeat(length, 3) if weights is None else (weights * length[:, None]).ravel())
    # Sum per vertex, in the corners' order (the order of the additions fixes the last bits).
    corner_vertex = faces.ravel()
    summed = np.column_stack([np.bincount(corner_vertex, _corner_terms(unit, weights, i), minlength=len(vertices))
                              for i in range(3)] + [np.bincount(corner_vertex, reach, minlength=len(vertices))])
    size = np.linalg.norm(summed[:, :3], axis=1, keepdims=True)
    vague = (size <= NO_DIRECTION * summed[:, 3:]).ravel()  # no direction: the face normal (as _normalise_or)
    vertex_normal = summed[:, :3] / np.where(vague[:, None], 1.0, size)
    del summed, size
    split = _creased_vertices(unit, corner_vertex, vertex_normal, vague, crease_angle)
    corners = _corners_of(vertex_normal, vague, faces, unit, dtype)
    if split.any():
        # Corners at a vertex with a crease: each gathers only the faces within the angle of its own.
        picked = np.flatnonzero(split[corner_vertex])
        face = picked // 3
        contribution = np.column_stack([_corner_terms(unit, weights, i)[picked] for i in range(3)] + [reach[picked]])
        sums = _creased_sums(corner_vertex[picked], contribution, unit[face], crease_angle)
        corners.reshape(-1, 3)[picked] = _normalise_or(sums[:, :3], unit[face], sums[:, 3:])
    return corners


def _creased_vertices(unit, corner_vertex, vertex_normal, vague, crease_angle) -> np.ndarray:
    """(V,) bool: vertices whose faces do not all lie within `crease_angle` of each other, so a crease
    may split them. A vertex whose face normals all lie within half the angle of its mean normal is
    not: any two are then within the angle (triangle inequality on the sphere), and every corner there
    gathers every face, which is the uncreased sum, bit for bit (the same additions in the same order).
    Only the others pay for the (corner, neighbour) pairs of _creased_sums."""
    if crease_angle >= 180.0:
        return np.zeros(len(vertex_normal), bool)
    cosine = np.zeros(len(corner_vertex))
    for i in range(3):
        cosine += np.repeat(unit[:, i], 3) * vertex_normal[corner_vertex, i]
    least = np.full(len(vertex_normal), np.inf)
    np.minimum.at(least, corner_vertex, cosine)
    # The margin sends a vertex at the bound through the exact pairwise test instead.
    return vague | ~(least >= math.cos(math.radians(crease_angle) / 2) + 1e-9)


def file_corner_normals(file_normals: np.ndarray, faces: np.ndarray, unit: np.ndarray,
                        dtype: type = np.float64) -> np.ndarray:
    """Corner normals (F, 3, 3) from a file's vertex normals (V, 3), placed (geometry.place): each unit
    length, and a vertex normal without direction (≤ NO_DIRECTION, as _normalise_or) gives way to the face
    normal `unit` (F, 3). Normalised per vertex, then gathered: no (F, 3, 3) float64 temporaries."""
    length = np.linalg.norm(file_normals, axis=1, keepdims=True)
    vague = (length <= NO_DIRECTION).ravel()
    return _corners_of(file_normals / np.where(vague[:, None], 1.0, length), vague, faces, unit, dtype)


def _corners_of(vertex_normal: np.ndarray, vague: np.ndarray, faces: np.ndarray, unit: np.ndarray,
                dtype: type) -> np.ndarray:
    """(F, 3, 3) in `dtype`: each corner its vertex's normal (V, 3), or its face's `unit` normal where the
    vertex is `vague` (V,) bool (its normal has no direction)."""
    corners = vertex_normal.astype(dtype, copy=False)[faces]
    face, corner = np.nonzero(vague[faces])
    corners[face, corner] = unit[face]
    return corners


def _corner_terms(unit: np.ndarray, weights: np.ndarray | None, axis: int) -> np.ndarray:
    """(3F,) w n_f[axis] for every corner, in corner order; weights (F, 3), or None for all ones."""
    if weights is None:
        return np.repeat(unit[:, axis], 3)
    return (weights * unit[:, axis, None]).ravel()


PAIR_CHUNK = 1 << 20  # (corner, neighbour) pairs per step of _creased_sums: ~60 MB of temporaries


def _creased_sums(corner_vertex, contribution, corner_face_normal, crease_angle):
    """For each corner, the sum of contributions of the corners at the same vertex whose faces are
    within `crease_angle` of its own face. corner_face_normal (C, 3) is indexed like the corners.

    A vertex of valence s makes s² (corner, neighbour) pairs, so they are made PAIR_CHUNK at a time
    (whole corners per step: each corner's sum is added in the same order whatever the chunking).
    """
    order = np.argsort(corner_vertex, kind="stable")
    sorted_vertex = corner_vertex[order]
    start = np.searchsorted(sorted_vertex, sorted_vertex, side="left")
    count = np.searchsorted(sorted_vertex, sorted_vertex, side="right") - start
    del sorted_vertex
    # The small slack keeps a face and its exact coplanar neighbour together despite rounding.
    least = math.cos(math.radians(crease_angle)) - 1e-12
    sums = np.zeros((len(order), contribution.shape[1]))
    pairs_before = np.cumsum(count) - count
    cuts = np.searchsorted(pairs_before, np.arange(0, pairs_before[-1] + count[-1], PAIR_CHUNK)) if len(order) else []
    for first, last in zip(cuts, [*cuts[1:], len(order)]):
        if first == last:
            continue
        # Every (corner, neighbour corner) pair that shares a vertex, in sorted positions.
        here = count[first:last]
        mine = np.repeat(np.arange(first, last), here)
        neighbour = start[mine] + (np.arange(len(mine)) - np.repeat(pairs_before[first:last] - pairs_before[first],
                                                                    here))
        neighbour = order[neighbour]
        cosine = np.einsum("ij,ij->i", corner_face_normal[order[mine]], corner_face_normal[neighbour])
        smooth = cosine >= least
        mine, neighbour = mine[smooth] - first, neighbour[smooth]  # mine: row within this chunk
        rows = order[first:last]
        for i in range(contribution.shape[1]):
            sums[rows, i] = np.bincount(mine, contribution[neighbour, i], minlength=last - first)
    return sums


def _normalise_or(vectors: np.ndarray, fallback: np.ndarray, reach: np.ndarray | float = 1.0) -> np.ndarray:
    """Unit vectors; the fallback where a vector has no direction: a length at most NO_DIRECTION × `reach`,
    the length it would have if its parts agreed (a sum of unit normals that nearly cancels points
    wherever rounding sends it). The shading kernel applies the same tolerance to its mixed normals."""
    length = np.linalg.norm(vectors, axis=-1, keepdims=True)
    tiny = length <= NO_DIRECTION * np.asarray(reach)
    return np.where(tiny, fallback, vectors / np.where(tiny, 1.0, length))
