"""Build every object's triangles (trimesh), place them in the world, compute face and vertex normals.

Vertex normals are stored per face corner, so a crease split or normals read from a file need no
vertex duplication: corner (f, k) carries the normal that vertex faces[f, k] has *on face f*.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
import trimesh

from .records import Geometry
from .scene import (
    MIN_EXTENT,
    POSITION_LIMIT,
    Object,
    Scene,
    SceneError,
    ShadingModel,
    _dotted,
    brightness_problem,
    open_regular,
)
from .tolerances import MIN_DISTANCE, NO_DIRECTION

MODEL_CODE = {ShadingModel.FLAT: 0, ShadingModel.GOURAUD: 1, ShadingModel.PHONG: 2}
TRIMESH = Path(trimesh.__file__).resolve().parent  # an exception that passed through here: trimesh refused the file


def build_geometry(scene: Scene, source: str = "<scene>", vertex_normals: bool = True) -> Geometry:
    """Concatenate the scene's objects in world space.

    `vertex_normals=False` (the plan's choice for an all-flat scene) leaves corner_normals empty.
    """
    material_index = {name: i + 1 for i, name in enumerate(scene.materials)}  # 0 is the built-in default
    parts, notes = [], []
    for index, obj in enumerate(scene.objects):
        vertices, faces, file_normals = object_mesh(scene, obj, index, source)
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
        if not np.ptp(vertices, axis=0).any():
            raise SceneError(f"{source}: objects.{index}: placed, the object collapses to a single point (its scale "
                             f"{list(obj.scale)} is below float64's resolution at translate {list(obj.translate)}); "
                             "allowed: an object with some extent; raise scale or its size")
        unit, _ = face_normals(vertices, faces)
        model = MODEL_CODE[scene.shading_of(obj)]
        corners = None
        if vertex_normals:
            if exact is not None:
                corners = exact
            elif obj.normals == "file":
                corners = file_normals[faces]
                corners = _normalise_or(corners, np.repeat(unit[:, None, :], 3, axis=1))
            else:
                corners = compute_corner_normals(vertices, faces, obj.normals, obj.crease_angle)
        parts.append((vertices, faces, unit, corners, material_index.get(obj.material, 0), model))

    offset = np.cumsum([0] + [len(p[0]) for p in parts])
    geometry = Geometry(
        vertices=np.concatenate([p[0] for p in parts]),
        faces=np.concatenate([p[1] + o for p, o in zip(parts, offset)]).astype(np.int32),
        face_normals=np.concatenate([p[2] for p in parts]),
        corner_normals=(np.concatenate([p[3] for p in parts]) if vertex_normals
                        else np.zeros((0, 3, 3))),
        face_material=np.concatenate([np.full(len(p[1]), p[4], np.int32) for p in parts]),
        face_model=np.concatenate([np.full(len(p[1]), p[5], np.int8) for p in parts]),
        face_object=np.concatenate([np.full(len(p[1]), i, np.int32) for i, p in enumerate(parts)]),
        notes=tuple(notes),
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


def object_mesh(scene: Scene, obj: Object, index: int, source: str):
    """(vertices (V, 3), faces (F, 3), file vertex normals (V, 3) or None) in the object's own frame."""
    if obj.shape == "mesh":
        return _load_mesh(scene, obj, index, source)
    if obj.shape == "plane":
        return (*plane_mesh(obj.size or (2.0, 2.0), obj.segments or (1, 1)), None)
    # Build at unit size and scale after: trimesh merges vertices closer than an absolute 1e-8, which
    # would collapse (and divide by zero on) a sphere of radius 1e-20.
    lengths = {"icosphere": (obj.radius,), "uv_sphere": (obj.radius,), "box": obj.size or (2.0, 2.0, 2.0),
               "cylinder": (obj.radius, obj.height), "torus": (obj.major_radius, obj.minor_radius)}[obj.shape]
    unit = max(lengths)
    if obj.shape == "icosphere":
        mesh = trimesh.creation.icosphere(subdivisions=obj.subdivisions, radius=1.0)
    elif obj.shape == "uv_sphere":
        mesh = trimesh.creation.uv_sphere(radius=1.0, count=list(obj.segments or (32, 16)))
    elif obj.shape == "box":
        mesh = trimesh.creation.box(extents=[length / unit for length in lengths])
    elif obj.shape == "cylinder":
        mesh = trimesh.creation.cylinder(radius=obj.radius / unit, height=obj.height / unit,
                                         sections=(obj.segments or (32, 1))[0])
    else:
        major, minor = obj.segments or (32, 16)
        mesh = trimesh.creation.torus(major_radius=obj.major_radius / unit, minor_radius=obj.minor_radius / unit,
                                      major_sections=major, minor_sections=minor)
    if len(mesh.faces) == 0:
        raise SceneError(f"{source}: objects.{index}: a {obj.shape} with lengths {list(lengths)} has no triangles: "
                         "trimesh merges vertices closer than 1e-8 of the shape's size; allowed: the smaller "
                         "length a larger share of the larger one")
    return np.asarray(mesh.vertices, np.float64) * unit, np.asarray(mesh.faces, np.int64), None


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
    key = f"{source}: objects.{index}.path"
    try:
        handle = open_regular(path, key, "mesh file")  # never a FIFO, a device or a folder
    except FileNotFoundError:
        raise SceneError(f"{key}: no such mesh file {str(path)!r}") from None
    readable = "a mesh file trimesh reads (OBJ, PLY, STL, OFF, GLB)"
    try:
        # Load unprocessed: trimesh's cleaning would silently drop NaN vertices and their faces.
        with handle:
            loaded = trimesh.load(**_mesh_source(path, handle), process=False)
        if isinstance(loaded, trimesh.Scene):  # several parts: one mesh (force="mesh" would drop file normals)
            loaded = loaded.to_mesh() if loaded.geometry else None
    except Exception as error:
        if not _raised_in_trimesh(error):
            raise  # our own bug, not the file's: an internal error with its traceback
        raise SceneError(f"{key}: cannot read {str(path)!r} as {readable} ({type(error).__name__}: "
                         f"{error})") from None
    if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
        raise SceneError(f"{key}: {str(path)!r} holds no triangles; expected {readable}")
    used = np.unique(np.asarray(loaded.faces))
    coordinates = np.asarray(loaded.vertices, np.float64)[used]
    finite = np.isfinite(coordinates).all(axis=1)
    if not finite.all():
        raise SceneError(f"{key}: {str(path)!r} has {int((~finite).sum())} vertex(es) with NaN or infinite "
                         "coordinates; every vertex of a face must have finite coordinates")
    # Within ±POSITION_LIMIT, as every point of a scene: trimesh squares coordinates (lengths, cross products).
    huge = (np.abs(coordinates) > POSITION_LIMIT).any(axis=1)
    if huge.any():
        raise SceneError(f"{key}: {str(path)!r} has {int(huge.sum())} vertex(es) with a coordinate beyond "
                         f"±{POSITION_LIMIT:g} (largest {float(np.abs(coordinates).max()):.3g}); allowed: within "
                         f"±{POSITION_LIMIT:g}, so lengths squared stay finite")
    if obj.normals != "file":
        # Keep the file's vertex order when its normals are wanted; otherwise let trimesh merge and clean.
        loaded.process()
    vertices = np.asarray(loaded.vertices, np.float64)
    normals = None
    if obj.normals == "file":
        if "vertex_normals" not in loaded._cache:
            raise SceneError(f'{source}: objects.{index}.normals: "file" but {str(path)!r} stores no vertex '
                             'normals; use "mean", "area" or "angle"')
        normals = np.asarray(loaded.vertex_normals, np.float64)
    return vertices, np.asarray(loaded.faces, np.int64), normals


TEXT_FORMATS = (".obj", ".off")  # trimesh decodes these as text, guessing any non-UTF-8 encoding


def _raised_in_trimesh(error: BaseException) -> bool:
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


def _mesh_source(path, handle) -> dict:
    """trimesh.load arguments for the open file `handle` of `path`; a text format that is not UTF-8 is
    read as Latin-1. The file already opened is read (not the path again), and files it names (an OBJ's
    materials, a glTF's buffers) are found beside it.

    trimesh needs the optional charset_normalizer to guess an encoding, and fails without it, so
    decide here: every byte is a Latin-1 character, and the OBJ and OFF keywords are plain ASCII.
    """
    suffix = path.suffix.lower()
    source = {"file_obj": handle, "file_type": suffix[1:], "resolver": trimesh.resolvers.FilePathResolver(path)}
    if suffix in TEXT_FORMATS:
        data = handle.read()
        try:
            data.decode("utf-8")
        except UnicodeDecodeError:
            data = data.decode("latin-1").encode("utf-8")
        source["file_obj"] = io.BytesIO(data)
    return source


def rotation_of(obj: Object) -> np.ndarray:
    """3×3 rotation about x, then y, then z, by the object's angles in degrees."""
    rx, ry, rz = (math.radians(a) for a in obj.rotate)
    return (trimesh.transformations.rotation_matrix(rz, [0, 0, 1])
            @ trimesh.transformations.rotation_matrix(ry, [0, 1, 0])
            @ trimesh.transformations.rotation_matrix(rx, [1, 0, 0]))[:3, :3]


def place(obj: Object, vertices, faces, file_normals):
    """World = R (S v) + t; a mirroring scale reverses the winding so faces still point outward."""
    rotation, scale = rotation_of(obj), np.asarray(obj.scale)
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
