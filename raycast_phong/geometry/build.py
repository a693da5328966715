"""Build every object's triangles (shapes.py; mesh_file.py reads mesh files, mesh_repair.py mends them), place
them in the world, and give them face and vertex normals (normals.py): one world-space mesh, the Geometry.
"""

from __future__ import annotations

import dataclasses
import math
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from ..codes import MODEL_CODE
from ..errors import SceneError
from ..records import Geometry, Texture, bounding_box
from ..scene.kinds import object_kinds, placements
from ..scene.messages import Location, located
from ..scene.objects import OWN_KEYS
from ..scene.schema import DEFAULT_MATERIAL, Object, Scene, brightness_problem
from ..tolerances import MIN_DISTANCE, MIN_EXTENT, POSITION_LIMIT
from . import shapes
from .materials import material_rows
from .mesh_repair import merge_duplicate_vertices, repair_winding
from .normals import _normalise_or, compute_corner_normals, face_normals, file_corner_normals

if TYPE_CHECKING:  # mesh_file imports trimesh: only a scene with a mesh file loads it
    from ..io.mesh_file import MeshFile

class ObjectMesh(NamedTuple):
    """An object's triangles in its own frame, as object_mesh builds or reads them."""
    vertices: np.ndarray         # (V, 3) float64
    faces: np.ndarray            # (F, 3) int64
    normals: np.ndarray | None   # (V, 3) vertex normals a mesh file stores (used when normals is "file" or unset)
    file: MeshFile | None = None  # a mesh file's materials and colours, aligned with `faces`
    crease_angle: float | None = None  # a mesh file's crease angle when the object leaves it unset
    uv: np.ndarray | None = None  # (F, 3, 2) texture coordinates per face corner, aligned with `faces`


OBJECT_CHUNK_VERTICES = 1 << 20  # placed vertices per step of a group: ~25 MB of float64 temporaries


def build_geometry(scene: Scene, source: str | Location = "<scene>", vertex_normals: bool = True,
                   normal_dtype: type = np.float64, sources: dict | None = None,
                   memo: BuildMemo | None = None) -> Geometry:
    """Concatenate the scene's objects in world space, in the scene's order.

    Built-in objects that share a shape and its parameters (and normal rule) form one group: their mesh is
    built once and placed for all of them at once, so a scene of a million boxes costs a few numpy passes,
    not a million. A mesh file is a group of its own. Every per-object step is the same arithmetic in both
    cases (a batched matmul gives each object the bits of its own), so a group changes no pixel.
    `vertex_normals=False` (the plan's choice for an all-flat scene) leaves corner_normals empty;
    `normal_dtype` is the corner normals' dtype: render() asks for float32 when it shades in float32 (the
    kernel would round them so anyway), which halves the largest array of a smooth mesh. `sources`: the mesh
    files' io.mesh_source.MeshSource by resolved path (prepare() passes those the budget used; made here when
    not given).
    `memo` (a live view's frames of one changing scene) keeps what the last build made and gives back what this
    scene shares with it (BuildMemo); the Geometry is the one a build without it gives, array for array.
    """
    where = located(source)
    if sources is None and any(obj.shape == "mesh" for obj in scene.objects):
        from ..io.mesh_source import mesh_sources
        sources = mesh_sources(scene)
    if memo is None:
        return _build(scene, where, vertex_normals, normal_dtype, None, sources)
    whole = memo.begin(scene, where, vertex_normals, normal_dtype)
    kept = memo.geometry_for(whole)
    if kept is not None:
        check_float_range(scene, kept.vertices, where)  # the lights it checks may be new
        return kept
    try:
        geometry = _build(scene, where, vertex_normals, normal_dtype, memo, sources)
    except BaseException:
        memo.abandon()  # keep the last good build's pieces only, however often a scene is refused
        raise
    memo.keep(whole, geometry)
    return geometry


def _build(scene: Scene, where: Location, vertex_normals: bool, normal_dtype: type, memo: BuildMemo | None,
           sources: dict | None) -> Geometry:
    """build_geometry's work, each group's template and part from `memo` when it has them."""
    material_index = {name: i + 1 for i, name in enumerate(scene.materials)}  # 0 is the built-in default
    groups = _groups(scene)
    bank = TextureBank(scene, where, memo)
    notes, file_notes, file_rows = [], [], FileRows(scene, material_index, bank)
    built = []  # (members, template, exact corner normals in the object frame, a mesh file's material rows)
    for members in groups:
        first = scene.objects[members[0]]
        wants_exact = vertex_normals and first.normals == "exact"
        if memo is None:
            group = _group_template(scene, first, int(members[0]), where, wants_exact, sources)
        else:
            group = memo.template(_template_key(scene, first, int(members[0]), where, wants_exact, sources),
                                  partial(_group_template, scene, first, int(members[0]), where, wants_exact,
                                          sources))
        file_notes += group.file_notes
        notes += group.notes
        rows = None
        if group.read is not None and first.material == "default":  # the file's own materials; any other name
            rows = file_rows.faces(group.read)                      # paints the whole mesh
        built.append((members, group.template, group.exact, rows))
    mesh = _Mesh.allocate(scene, built, vertex_normals, normal_dtype, material_index)
    for members, template, exact, rows in built:
        step = max(1, OBJECT_CHUNK_VERTICES // max(1, len(template.vertices)))
        for at in range(0, len(members), step):
            chunk = members[at:at + step]
            if memo is None:
                part = _group_part(scene, chunk, template, exact, vertex_normals, normal_dtype, where)
            else:
                part = memo.part(scene, chunk, template, vertex_normals, normal_dtype,
                                 partial(_group_part, scene, chunk, template, exact, normal_dtype=normal_dtype,
                                         where=where))
            mesh.write(part, rows)
    scene_maps = bank.scene_maps([o.material for o in object_kinds(scene).firsts(scene.objects)])
    textured = bank.textures and (len(scene_maps) or file_rows.mapped)
    corner_uv = _corner_uvs(scene, built, mesh) if textured else np.zeros((0, 3, 2), np.float32)
    corner_colour = _corner_colours(scene, built, mesh, in_place=memo is None)
    geometry = mesh.geometry(tuple(notes), file_rows.table(), tuple(dict.fromkeys(file_notes + bank.notes)))
    geometry = dataclasses.replace(geometry, corner_uv=corner_uv, corner_colour=corner_colour,
                                   textures=tuple(bank.textures) if textured else (),
                                   scene_maps=scene_maps if textured else np.full((0, 3), -1, np.int64))
    check_float_range(scene, geometry.vertices, where)
    return geometry


class _Template(NamedTuple):
    """A group's mesh in the object frame, as every object of the group shares it, and what reading it said."""
    template: ObjectMesh         # mended: the winding repaired (and the corner arrays reordered with it)
    exact: np.ndarray | None     # (F, 3, 3) exact corner normals in the object frame (normals = "exact")
    read: MeshFile | None        # a mesh file as read, before the repair: its faces' material rows come from it
    notes: tuple[str, ...]       # the winding repair, for Geometry.notes
    file_notes: tuple[str, ...]  # what reading the file said, and turned-over normals, for Geometry.file_notes


def _group_template(scene: Scene, first: Object, index: int, where: Location, wants_exact: bool,
                    sources: dict | None = None) -> _Template:
    """The template of the group whose first object is `first` (scene.objects[index]): a shape's triangles, or
    a mesh file read, its winding repaired and its stored normals turned outward if they point inward."""
    template = object_mesh(scene, first, where.at("objects", index), sources)
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
    return _Template(template, exact, read, tuple(notes), tuple(file_notes))


def _template_key(scene: Scene, first: Object, index: int, where: Location, wants_exact: bool,
                  sources: dict | None = None) -> tuple:
    """What _group_template reads: a shape's keys; a mesh file's object, its file as it is now (its version and
    its side files', MeshSource.identity) and the object's number and location, which its notes name."""
    if first.shape != "mesh":
        return ("shape", *_group_key(first, index), wants_exact)
    return ("mesh", index, where, _mesh_stamp(scene.resolve(first.path), sources), first.normals, first.crease_angle,
            "crease_angle" in first.model_fields_set, wants_exact)


def _mesh_stamp(path: Path, sources: dict | None = None) -> tuple:
    """A mesh file's identity now (its version and its side files': its MeshSource, the one prepare() made when
    given), or (path, None) when it cannot be read: then no key matches and the read words the error."""
    from ..io.mesh_source import mesh_source
    source = (sources or {}).get(path) or mesh_source(path)
    return source.identity if source.version is not None else (str(path), None)


def _file_stamp(path: Path) -> tuple:
    """A file's version now (io.files.file_version), or (path, None) when it cannot be stat'ed."""
    from ..io.files import file_version
    try:
        return file_version(path)
    except OSError:
        return (str(path), None)


class BuildMemo:
    """What build_geometry keeps between builds of one changing scene (a live view's frames of one page), so
    that a frame rebuilds only what its change touched:

    - the last Geometry, with the key of everything it was built from (begin) and the versions of the
      texture files it decoded: a scene that differs only in lights, camera or render settings other than
      shading and colour gets that Geometry back (the same object);
    - each group's template (a shape's triangles, or a mesh file read, merged and mended), keyed by what it
      reads, the mesh file's version among it: a material or shading change, or a new placement, reads nothing;
    - each group's placed part (world vertices, face and corner normals), keyed by its template and its objects'
      placements: a new tessellation or placement of one kind rebuilds that kind's part only;
    - the textures decoded, keyed by the file's version (or the image object a mesh file holds) and the
      render.colour they were decoded for.

    Only what the last build used is kept (one scene's worth of geometry, and its parts: as much again for a
    scene of several objects, the parts' arrays being copied into one mesh). Not for two threads at once.
    """

    def __init__(self):
        self._whole: tuple | None = None            # whole_key of `_geometry`
        self._geometry: Geometry | None = None
        self._texture_stamps: dict[str, tuple] = {}  # texture files `_geometry` decoded → their versions then
        self._templates: dict[tuple, _Template] = {}
        self._parts: dict[tuple, _Part] = {}
        self._textures: dict[tuple, tuple[object, np.ndarray]] = {}  # (TextureBank key, colour) → (stamp, pixels)
        self._used: tuple[set, set, set] = (set(), set(), set())  # templates, parts and textures of this build
        self._kept: tuple[set, set, set] = (set(), set(), set())  # those of the last build that succeeded

    def begin(self, scene: Scene, where: Location, vertex_normals: bool, normal_dtype: type) -> tuple:
        """Start a build: the key of everything build_geometry reads from `scene` and the disk: every object's
        keys but placement (once per kind) and the placements' bits, the materials, the default shading, the
        colour the maps are decoded in (render.colour), the folder, the mesh files and maps as they are now; not
        the lights (check_float_range runs on every build), the camera or the other render settings."""
        self._used = (set(), set(), set())
        kinds = object_kinds(scene)
        files = tuple(_mesh_stamp(scene.resolve(o.path)) for o in scene.objects if o.shape == "mesh")
        files += tuple(_file_stamp(scene.resolve(getattr(m, key).path)) for m in scene.materials.values()
                       for key in ("ka_map", "kd_map", "ke_map") if getattr(m, key) is not None)
        placed = tuple(array.tobytes() for array in placements(scene.objects))  # bits: -0.0 is not 0.0
        return (where, scene.folder, vertex_normals, np.dtype(normal_dtype).str, scene.render.shading,
                scene.render.colour, tuple(scene.materials.items()), tuple(kinds.firsts(scene.objects)),
                kinds.kind.tobytes(), placed, files)

    def geometry_for(self, whole: tuple) -> Geometry | None:
        """The last Geometry if `whole` is its key and the texture files it decoded are unchanged; else None."""
        if self._geometry is None or whole != self._whole:
            return None
        if any(_file_stamp(Path(path)) != stamp for path, stamp in self._texture_stamps.items()):
            return None
        return self._geometry

    def template(self, key: tuple, make) -> _Template:
        found = self._templates.get(key)
        if found is None:
            found = self._templates[key] = make()
        self._used[0].add(key)
        return found

    def part(self, scene: Scene, members: np.ndarray, template: ObjectMesh, vertex_normals: bool,
             normal_dtype: type, make) -> _Part:
        """The placed part of `members` sharing `template`: kept if the same template was placed the same way
        (a part made with corner normals serves a build without them), else made by make(vertex_normals)."""
        first = scene.objects[int(members[0])]
        where = tuple(array.tobytes() for array in placements(scene.objects, members))
        key = (id(template.vertices), id(template.faces), members.tobytes(), where, first.normals,
               first.crease_angle, np.dtype(normal_dtype).str)
        for normals in ((True, False) if not vertex_normals else (True,)):
            found = self._parts.get((*key, normals))
            if found is not None and found.template is template:
                self._used[1].add((*key, normals))
                return found.part if vertex_normals or found.part.corners is None else found.part._replace(corners=None)
        part = make(vertex_normals)
        self._parts[(*key, vertex_normals)] = _KeptPart(template, part)
        self._used[1].add((*key, vertex_normals))
        return part

    def texture(self, key: tuple, stamp: object, decode) -> np.ndarray:
        """The pixels of texture `key`, decoded again only when its stamp (a file's version, or the image object
        a mesh file holds) is another."""
        found = self._textures.get(key)
        # A file's version is compared; an image object a mesh file holds must be the same object.
        if found is None or not (found[0] is stamp or (isinstance(stamp, tuple) and found[0] == stamp)):
            found = self._textures[key] = (stamp, decode())
        self._used[2].add(key)
        return found[1]

    def keep(self, whole: tuple, geometry: Geometry) -> None:
        """Remember this build's Geometry, and drop every template, part and texture it did not use."""
        self._kept, self._used = self._used, (set(), set(), set())
        self._prune()
        self._texture_stamps = {key[0]: stamp for key, (stamp, _) in self._textures.items()
                                if isinstance(stamp, tuple)}
        self._whole, self._geometry = whole, geometry

    def abandon(self) -> None:
        """A build failed (a refused scene): drop what it made, keep what the last good build used."""
        self._used = (set(), set(), set())
        self._prune()

    def _prune(self) -> None:
        templates, parts, textures = self._kept
        self._templates = {k: v for k, v in self._templates.items() if k in templates}
        self._parts = {k: v for k, v in self._parts.items() if k in parts}
        self._textures = {k: v for k, v in self._textures.items() if k in textures}


class _KeptPart(NamedTuple):
    template: ObjectMesh  # the template it was placed from (the key holds its arrays' ids: this keeps them alive)
    part: _Part


class _Part(NamedTuple):
    """Objects of one group, placed: K objects of n vertices and m faces each."""
    members: np.ndarray         # (K,) their indices in scene.objects, ascending
    vertices: np.ndarray        # (K, n, 3) float64, world
    faces: np.ndarray           # (K, m, 3) int64, each object's own vertex numbers (0..n-1), mirrored reversed
    unit: np.ndarray            # (K, m, 3) unit face normals
    corners: np.ndarray | None  # (K, m, 3, 3) corner normals in normal_dtype, or None


def _groups(scene: Scene) -> list[np.ndarray]:
    """The objects (ascending indices) of each group of objects sharing one build (_group_key), groups in the
    order of their first object. Decided once per kind of object (scene.kinds), then spread to the objects."""
    kinds = object_kinds(scene)
    numbers: dict[tuple, int] = {}
    kind_group = np.array([numbers.setdefault(_group_key(scene.objects[i], i), len(numbers))
                           for i in kinds.first.tolist()], np.int64)
    return kinds.grouped(kind_group)


def _group_key(obj: Object, index: int) -> tuple:
    """What makes two objects' meshes (and normals) the same before placement: equal keys share one build.
    A mesh file is never shared (its reading notes and materials belong to its object)."""
    if obj.shape == "mesh":
        return ("mesh", index)
    return (obj.shape, *(getattr(obj, key) for key in OWN_KEYS[obj.shape]), obj.normals, obj.crease_angle)


def _group_part(scene: Scene, members: np.ndarray, template: ObjectMesh, exact: np.ndarray | None,
                vertex_normals: bool, normal_dtype: type, where: Location) -> _Part:
    """Place K objects that share `template` (its vertices and faces in the object frame) and give them face
    and corner normals: the per-object steps of the scene format, done for all K at once."""
    scale, rotate, translate = placements(scene.objects, members)
    rotation = rotations_of(rotate)
    vertices = place_vertices(template.vertices, scale, rotation, translate, (rotate != 0).any(axis=1))
    mirrored = np.prod(scale, axis=1) < 0  # a mirroring scale reverses the winding so faces still point outward
    faces = np.broadcast_to(template.faces, (len(members), *template.faces.shape)).copy()
    faces[mirrored] = faces[mirrored][:, :, ::-1]
    reach = np.abs(vertices).max(axis=(1, 2))
    for k in np.flatnonzero(~(reach <= POSITION_LIMIT)):  # NaN fails the comparison too
        raise SceneError(f"placed (scale, rotate, translate), the object reaches a coordinate of {reach[k]:.3g}; "
                         f"allowed: within ±{POSITION_LIMIT:g}, so distances squared stay finite in float32; lower "
                         "scale, its size or translate", where.at("objects", int(members[k])))
    extent = vertices.max(axis=1) - vertices.min(axis=1)
    for k in np.flatnonzero(~(extent != 0).any(axis=1)):
        obj = scene.objects[members[k]]
        raise SceneError(f"placed, the object collapses to a single point (its scale {list(obj.scale)} is below "
                         f"float64's resolution at translate {list(obj.translate)}); allowed: an object with some "
                         "extent; raise scale or its size", where.at("objects", int(members[k])))
    count, n = len(members), len(template.vertices)
    flat_vertices = vertices.reshape(-1, 3)
    flat_faces = (faces + (np.arange(count) * n)[:, None, None]).reshape(-1, 3)
    unit, doubled_area = face_normals(flat_vertices, flat_faces)
    corners = None
    if vertex_normals:
        first = scene.objects[members[0]]
        if exact is not None:
            corners = place_normals(exact.reshape(-1, 3), scale, rotation).reshape(count, -1, 3, 3)
            corners[mirrored] = corners[mirrored][:, :, ::-1]  # as place() reversed the mirrored winding
            corners = corners.astype(normal_dtype, copy=False)
        elif template.normals is not None:
            placed = place_normals(template.normals, scale, rotation).reshape(-1, 3)
            corners = file_corner_normals(placed, flat_faces, unit, normal_dtype)
        else:
            crease = first.crease_angle if template.crease_angle is None else template.crease_angle
            corners = compute_corner_normals(flat_vertices, flat_faces, first.normals or "mean", crease,
                                             normal_dtype, normals=(unit, doubled_area))
        corners = corners.reshape(count, -1, 3, 3)
    del doubled_area
    return _Part(members, vertices, faces, unit.reshape(count, -1, 3), corners)


class _Mesh:
    """The scene's one mesh, allocated once its objects' sizes are known and written part by part in the
    scene's order (face numbers and material rows follow the objects as the scene lists them)."""

    @classmethod
    def allocate(cls, scene: Scene, built: list, vertex_normals: bool, normal_dtype: type,
                 material_index: dict[str, int]) -> _Mesh:
        mesh = cls()
        objects = len(scene.objects)
        mesh.vertex_count, mesh.face_count = np.zeros(objects, np.int64), np.zeros(objects, np.int64)
        for members, template, *_ in built:
            mesh.vertex_count[members] = len(template.vertices)
            mesh.face_count[members] = len(template.faces)
        mesh.vertex_start = np.cumsum(mesh.vertex_count) - mesh.vertex_count
        mesh.face_start = np.cumsum(mesh.face_count) - mesh.face_count
        # One object (a large mesh file) keeps its part's arrays: no copies.
        mesh.single = objects == 1
        vertices, faces = int(mesh.vertex_count.sum()), int(mesh.face_count.sum())
        if not mesh.single:
            mesh.vertices, mesh.unit = np.empty((vertices, 3)), np.empty((faces, 3))
            mesh.faces = np.empty((faces, 3), np.int32)  # filled part by part: no int64 copies
            mesh.corners = np.empty((faces if vertex_normals else 0, 3, 3), normal_dtype)
        else:
            mesh.corners = np.zeros((0, 3, 3), normal_dtype)
        mesh.face_object = np.repeat(np.arange(objects, dtype=np.int32), mesh.face_count)
        kinds = object_kinds(scene)  # material and shading are decided per kind of object
        firsts = kinds.firsts(scene.objects)
        object_material = np.array([material_index.get(o.material, 0) for o in firsts], np.int32)[kinds.kind]
        mesh.face_material = object_material[mesh.face_object]
        object_model = np.array([MODEL_CODE[scene.shading_of(o)] for o in firsts], np.int8)[kinds.kind]
        mesh.face_model = object_model[mesh.face_object]
        return mesh

    def write(self, part: _Part, rows: np.ndarray | None) -> None:
        """Copy a part's objects into their places; `rows`: a mesh file's own material rows for its faces."""
        members = part.members
        if rows is not None:
            start = self.face_start[members[0]]
            self.face_material[start:start + len(rows)] = rows
        if self.single:
            self.vertices, self.unit = part.vertices[0], part.unit[0]
            self.faces = part.faces[0].astype(np.int32)
            if part.corners is not None:
                self.corners = part.corners[0]
            return
        if members[-1] - members[0] + 1 == len(members):  # consecutive objects (the usual case): one slice each
            at_vertex = slice(self.vertex_start[members[0]], self.vertex_start[members[-1]] + part.vertices.shape[1])
            at_face = slice(self.face_start[members[0]], self.face_start[members[-1]] + part.faces.shape[1])
        else:
            at_vertex = (self.vertex_start[members][:, None] + np.arange(part.vertices.shape[1])).ravel()
            at_face = (self.face_start[members][:, None] + np.arange(part.faces.shape[1])).ravel()
        self.vertices[at_vertex] = part.vertices.reshape(-1, 3)
        self.faces[at_face] = (part.faces + self.vertex_start[members][:, None, None]).reshape(-1, 3)
        self.unit[at_face] = part.unit.reshape(-1, 3)
        if part.corners is not None:
            self.corners[at_face] = part.corners.reshape(-1, 3, 3)

    def geometry(self, notes: tuple, file_materials: np.ndarray, file_notes: tuple) -> Geometry:
        return Geometry(vertices=self.vertices, faces=self.faces, face_normals=self.unit,
                        corner_normals=self.corners, face_material=self.face_material, face_model=self.face_model,
                        face_object=self.face_object, notes=notes, file_materials=file_materials,
                        file_notes=file_notes)


def check_float_range(scene: Scene, vertices: np.ndarray, source: str | Location = "<scene>") -> None:
    """Refuse a scene whose placed extent or 1/d² lights would leave float32's range (SceneError).

    The half-extent must be at least MIN_EXTENT; a 1/d² light's f_att is at most 1/max(d, floor)², d its
    distance to the scene's bounding box and floor tolerances.MIN_DISTANCE × the half-extent, and the lights
    must keep every pixel channel below INTENSITY_LIMIT with that gain (scene.brightness_problem).
    """
    low, high = bounding_box(vertices)
    extent = float((high - low).max()) / 2  # as intersect.unit_frame measures it
    if extent < MIN_EXTENT:
        raise SceneError(f"the whole scene spans only {2 * extent:.3g} (its largest bounding-box side); allowed: at "
                         f"least {2 * MIN_EXTENT:g}, so the 1/d² floor and Embree's unit frame stay in float32's "
                         "range; raise the objects' scale or size", located(source).at("objects"))
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
        raise SceneError(problem[1], located(source).at(*problem[0]))


def behind_camera(scene: Scene, vertices: np.ndarray) -> str | None:
    """A one-line warning if every placed vertex lies behind the camera (or on its plane), else None:
    no ray can hit anything, so the image is only background."""
    eye = np.asarray(scene.camera.position)
    forward = np.asarray(scene.camera.look_at) - eye
    if (vertices @ forward).max() > eye @ forward:  # (v - eye)·forward > 0, without a (V, 3) temporary
        return None
    return (f"every object is behind the camera (camera.position {list(scene.camera.position)} looks toward "
            f"look_at {list(scene.camera.look_at)}); the image will be only background")


class TextureBank:
    """The scene's decoded textures, each decoded once and only when a face's material uses it (a file's
    unused maps are never decoded), as the scene's render.colour asks (io.textures: as stored, or decoded from
    sRGB to linear values); a map that cannot be decoded is a note and its factor stands alone."""

    def __init__(self, scene: Scene, where: Location, memo: BuildMemo | None = None):
        self.scene, self.where, self.memo = scene, where, memo
        self.textures: list[Texture] = []
        self.notes: list[str] = []
        self.found: dict = {}

    def add(self, key, decode, wrap_s: str, wrap_t: str, name: str, stamp: object = None) -> int:
        """The texture row of `key`, decoded by `decode()` the first time; -1 (and a note) if it cannot be.
        `stamp` (a file's version, or the image object a mesh file holds) lets a memo keep the pixels."""
        if key not in self.found:
            try:
                pixels = (decode() if self.memo is None else
                          self.memo.texture((*key, self.scene.render.colour), stamp, decode))
            except SceneError:
                raise  # a scene's own map: the scene is wrong (one line, exit 2)
            except ValueError as error:
                self.notes.append(f"{name} cannot be decoded as an image ({error}); its factor is used")
                self.found[key] = -1
            else:
                self.found[key] = len(self.textures)
                self.textures.append(Texture(pixels, wrap_s, wrap_t, name))
        return self.found[key]

    def file_map(self, read: MeshFile, index: int) -> int:
        """The texture row of a mesh file's map `index` (into read.texture_sources), -1 for none."""
        if index < 0:
            return -1
        from ..io.textures import decode_file, decode_pil
        found = read.texture_sources[index]
        colour = self.scene.render.colour
        if isinstance(found.source, Path):
            key, decode = (str(found.source), found.wrap_s, found.wrap_t), lambda: decode_file(found.source, colour)
            stamp = _file_stamp(found.source) if self.memo is not None else None
        else:
            key, decode = (id(found.source), found.wrap_s, found.wrap_t), lambda: decode_pil(found.source, colour)
            stamp = found.source
        return self.add(key, decode, found.wrap_s, found.wrap_t, found.name, stamp)

    def scene_map(self, name: str, key: str) -> int:
        """The texture row of a scene material's map (its `kd_map`, ...), -1 for none; SceneError (one line)
        when the file is missing or not an image."""
        material = self.scene.materials.get(name)
        value = getattr(material, key, None) if material is not None else None
        if value is None:
            return -1
        from ..io.textures import decode_scene_map
        path, wrap = self.scene.resolve(value.path), value.wrap
        where = self.where.at("materials", name, key)
        stamp = _file_stamp(path) if self.memo is not None else None
        return self.add((str(path), wrap, wrap), lambda: decode_scene_map(path, where, self.scene.render.colour),
                        wrap, wrap, str(path), stamp)

    def maps_of(self, material, read: MeshFile | None = None) -> tuple[int, int, int]:
        """(ka, kd, ke) texture rows of a material: a FileMaterial of `read`, or a scene material by name;
        the k_a map is the k_d map unless a k_a map of its own is given (the texture modulates both)."""
        if read is not None:
            ka, kd, ke = (self.file_map(read, i) for i in (material.ka_map, material.kd_map, material.ke_map))
        else:
            name = next((n for n, m in self.scene.materials.items() if m is material), None)
            if name is None:
                return -1, -1, -1
            ka, kd, ke = (self.scene_map(name, k) for k in ("ka_map", "kd_map", "ke_map"))
        return (kd if ka < 0 else ka), kd, ke

    def scene_maps(self, used: list[str]) -> np.ndarray:
        """(1 + scene materials, 3) texture rows of the default's and the scene's materials; decoded only for
        the materials some object uses; empty when none has a map."""
        rows = np.full((1 + len(self.scene.materials), 3), -1, np.int64)
        used = set(used)
        for i, (name, material) in enumerate(self.scene.materials.items()):
            if name in used or name == "default":
                rows[1 + i] = self.maps_of(material)
        return rows if (rows >= 0).any() else np.full((0, 3), -1, np.int64)


class FileRows:
    """The material table's rows after the scene's own: one per file material of the mesh files' faces, and
    for faces with vertex colours but no material one whose k_a = k_d = 1 (the colours, which multiply k_a
    and k_d per corner in the kernel, then replace them). A file material the scene defines by name
    ([materials.NAME]) uses the scene's factors instead, and the file's maps unless it gives its own."""

    def __init__(self, scene: Scene, material_index: dict[str, int], bank: TextureBank | None = None):
        self.scene, self.material_index = scene, material_index
        self.bank = bank if bank is not None else TextureBank(scene, Location("<scene>"))
        self.rows: list[np.ndarray] = []
        self.mapped = False
        self.first = 1 + len(scene.materials)  # row of the first file material: after the default and the scene's

    def faces(self, read: MeshFile) -> np.ndarray:
        """(F,) int32 material rows for the faces of one mesh file."""
        default = self.scene.materials.get("default", DEFAULT_MATERIAL)
        named = [self.scene.materials.get(m.name, m) for m in read.materials] + [default]  # -1: no material
        group = np.where(read.face_group < 0, len(named) - 1, read.face_group)
        # A scene material of the file material's name (framing writes them so) gives the factors; the file's
        # maps stay unless it names maps of its own.
        maps = []
        for own, used in zip(read.materials, named):
            given = self.bank.maps_of(used) if used is not own else (-1, -1, -1)
            maps.append(given if max(given) >= 0 else self.bank.maps_of(own, read))
        maps.append(self.bank.maps_of(default))
        if read.corner_colour is not None:  # colours with no material replace k_a and k_d: a white row
            named.append(default.model_copy(update={"ka": (1.0, 1.0, 1.0), "kd": (1.0, 1.0, 1.0)}))
            maps.append(maps[-1])
            coloured = (read.face_group < 0) & (read.corner_colour[:, 0, 0] >= 0)
            group = np.where(coloured, len(named) - 1, group)
        self.mapped |= any(r >= 0 for m in maps for r in m)
        self.rows.append(self._rows(named, np.asarray(maps, np.int64).reshape(-1, 3)))
        return (self.first + sum(len(r) for r in self.rows[:-1]) + group).astype(np.int32)

    @staticmethod
    def _rows(named: list, maps: np.ndarray) -> np.ndarray:
        def column(key: str) -> np.ndarray:
            return np.array([getattr(m, key) for m in named], np.float64).reshape(len(named), -1)
        return material_rows(column("ka"), column("kd"), column("ks"), column("ke"), column("shininess")[:, 0], maps)

    def table(self) -> np.ndarray:
        return np.concatenate(self.rows) if self.rows else material_rows(*(np.zeros((0, 3)),) * 4, np.zeros(0))


def _follow_corners(before: np.ndarray, after: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Per-corner values (F, 3, ...) reordered as each face's corners were (repair_winding reverses some):
    corner j of `after` takes the value of the corner of `before` with the same vertex."""
    order = (before[:, None, :] == after[:, :, None]).argmax(axis=2)  # (F, 3): where after's corner was
    return np.take_along_axis(values, order.reshape(*order.shape, *([1] * (values.ndim - 2))), axis=1)


def _object_corners(scene: Scene, built: list, mesh, per_object, width: int, fill: float) -> np.ndarray:
    """(F, 3, width) float32 per-corner values of every face in the scene's order: `per_object(members,
    template)` gives a template's (m, 3, width) array or None (then `fill`); mirrored objects reversed."""
    if len(scene.objects) == 1:  # one object (a large mesh file): its own array, no copy
        members, template = built[0][0], built[0][1]
        values = per_object(members, template)
        if values is not None and np.prod(scene.objects[0].scale) >= 0:
            return np.ascontiguousarray(values, np.float32)
    out = np.full((int(mesh.face_count.sum()), 3, width), fill, np.float32)
    for members, template, *_ in built:
        values = per_object(members, template)
        if values is None:
            continue
        step = max(1, OBJECT_CHUNK_VERTICES // max(1, len(values)))
        for at in range(0, len(members), step):
            chunk = members[at:at + step]
            (scale,) = placements(scene.objects, chunk, ("scale",))
            mirrored = np.prod(scale, axis=1) < 0
            for objects, placed in ((chunk[~mirrored], values), (chunk[mirrored], values[:, ::-1])):
                rows = (mesh.face_start[objects][:, None] + np.arange(len(values))).ravel()
                out[rows] = np.broadcast_to(placed, (len(objects), *placed.shape)).reshape(-1, 3, width)
    return out


def _corner_uvs(scene: Scene, built: list, mesh) -> np.ndarray:
    """(F, 3, 2) texture coordinates of every face: a mesh file's, or a built-in shape's (shape_uv)."""
    def uvs(members, template):
        if template.uv is not None or template.file is not None:
            return template.uv
        return shape_uv(scene.objects[members[0]], template.vertices, template.faces)
    return _object_corners(scene, built, mesh, uvs, 2, 0.0)


def _corner_colours(scene: Scene, built: list, mesh, in_place: bool = True) -> np.ndarray:
    """(F, 3, 3) vertex colours per corner (1 where a face has none), or empty when no used file has any.
    `in_place`: the file's own array is changed (no copy); not when a memo keeps the file for the next build,
    whose material rows still tell the faces without colours by their -1."""
    def colours(members, template):
        read = template.file
        if read is None or read.corner_colour is None or scene.objects[members[0]].material != "default":
            return None
        colours = read.corner_colour  # the file's own array: -1 (a part without colours) becomes 1
        if not in_place:
            return np.where(colours < 0, np.float32(1), colours).astype(colours.dtype, copy=False)
        colours[colours < 0] = 1
        return colours
    if not any(t.file is not None and t.file.corner_colour is not None
               and scene.objects[m[0]].material == "default" for m, t, *_ in built):
        return np.zeros((0, 3, 3), np.float32)
    return _object_corners(scene, built, mesh, colours, 3, 1.0)


def object_mesh(scene: Scene, obj: Object, where: Location, sources: dict | None = None) -> ObjectMesh:
    """The object's triangles in its own frame (a mesh file's with its materials, colours and normals; a built-in
    shape's from its kind, geometry/shapes/); `where` is the object's location (file: objects.N)."""
    if obj.shape == "mesh":
        return _load_mesh(scene, obj, where, (sources or {}).get(scene.resolve(obj.path)))
    return ObjectMesh(*shapes.KINDS[obj.shape].template(obj, where), None)


def shape_uv(obj: Object, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray | None:
    """(F, 3, 2) texture coordinates of a built-in shape's template (object_mesh's vertices and faces), made
    only when the scene has textures (a textured scene's geometry stage calls it); None for a mesh file."""
    kind = shapes.kind_of(obj)
    return None if kind is None else kind.uv(obj, vertices, faces)


def _load_mesh(scene: Scene, obj: Object, where: Location, mesh=None):
    path = scene.resolve(obj.path)
    from ..io.mesh_file import read_mesh  # imports trimesh (0.2–0.3 s): only for mesh files

    read = read_mesh(path, where.at("path"), source=mesh)
    normals = read.normals if obj.normals in (None, "file") else None  # unset: the file's, if it has them
    if obj.normals == "file" and normals is None:
        raise SceneError(f'"file" but {str(path)!r} stores no vertex normals; use "mean", "area" or "angle"',
                         where.at("normals"))
    if normals is not None:  # keep the file's vertex order: its normals are per vertex
        return ObjectMesh(read.vertices, read.faces, normals, read, uv=read.corner_uv)
    # Otherwise merge what the file repeats (the faces and their order stay, so the per-face materials line up).
    # The scene named a rule, so the file's normals neither shade nor keep its points apart.
    vertices, faces = merge_duplicate_vertices(read.vertices, read.faces)
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
    from ..io.materials import FILE_CREASE_ANGLE
    return FILE_CREASE_ANGLE


def rotations_of(angles: list) -> np.ndarray:
    """(K, 3, 3) rotations about x, then y, then z, by K objects' angles in degrees. cos and sin come from the
    math module (the C library), whose bits numpy's vectorised ones need not share."""
    angles = np.asarray(angles, np.float64).reshape(-1, 3)
    distinct, inverse = np.unique(angles, return_inverse=True)
    cos = np.array([math.cos(math.radians(a)) for a in distinct.tolist()])[inverse].reshape(angles.shape)
    sin = np.array([math.sin(math.radians(a)) for a in distinct.tolist()])[inverse].reshape(angles.shape)
    turns = []
    for axis in range(3):
        i, j = (axis + 1) % 3, (axis + 2) % 3  # the plane it turns: y→z about x, z→x about y, x→y about z
        turn = np.broadcast_to(np.eye(3), (len(angles), 3, 3)).copy()
        turn[:, i, i] = turn[:, j, j] = cos[:, axis]
        turn[:, j, i], turn[:, i, j] = sin[:, axis], -sin[:, axis]
        turns.append(turn)
    return turns[2] @ turns[1] @ turns[0]


def place_vertices(vertices: np.ndarray, scale: np.ndarray, rotation: np.ndarray, translate: np.ndarray,
                   rotated: list[bool]) -> np.ndarray:
    """World = R (S v) + t for K objects sharing object-frame vertices (n, 3): (K, n, 3). An object neither
    turned nor scaled is only moved: the same numbers, and (n, 3) @ (3, 3) is slow for a large mesh. numpy's
    stacked matmul multiplies each object's pair as its own 2-D product does, so the bits do not depend on K."""
    placed = np.empty((len(scale), *vertices.shape))
    moved = ~np.asarray(rotated, bool) & (scale == 1).all(axis=1)
    if moved.any():
        placed[moved] = vertices[None] + translate[moved][:, None, :]
    if not moved.all():
        turned = ~moved
        placed[turned] = (np.matmul(vertices[None] * scale[turned][:, None, :], rotation[turned].transpose(0, 2, 1))
                          + translate[turned][:, None, :])
    return placed


def place_normals(normals: np.ndarray, scale: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """Object-frame normals (N, 3) → unit world normals (K, N, 3) for K objects; zero where one has no
    direction (the caller's fallback then applies). Normals transform with the inverse transpose:
    (R S)^-T = R S^-1, which stretches by at most 1/min|s|."""
    reach = (np.linalg.norm(normals, axis=-1, keepdims=True)[None]
             / np.abs(scale).min(axis=1)[:, None, None])
    # (n / s) @ R^T as three scaled columns of R: numpy's matmul with a 3-wide inner dimension took 95 ms for
    # 245,760 corners on a busy 2-core machine, this 4 ms.
    placed = sum(normals[None, :, k:k + 1] * (rotation[:, None, :, k] / scale[:, None, k:k + 1]) for k in range(3))
    return _normalise_or(placed, np.zeros_like(placed), reach)


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


