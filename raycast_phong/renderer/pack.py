"""Scene → the kernels' records: every table and column of kernels/layout.py is written here and only here.

The kernels read arrays and named layouts, never the scene schema; this module is where a Scene, its
Geometry, the unit Frame and the render plan become ShadingInputs, ShadowInputs, RayParams and FilmRows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..geometry.materials import material_rows
from ..records import Frame, Geometry, ImageBuffers, RenderPlan
from ..scene.schema import DEFAULT_MATERIAL, Scene, SpecularModel
from ..tolerances import MIN_DISTANCE
from .kernels.camera import fill_rows
from .kernels.layout import (
    ATTENUATION_NONE,
    CLQ,
    COUNTS,
    DIRECTIONAL,
    F_AOV_GEOMETRY,
    F_AOV_TERMS,
    F_ATTENUATION,
    F_DIFFUSE,
    F_EMISSION,
    F_LIGHT_AMBIENT,
    F_SCENE_AMBIENT,
    F_SCREEN,
    F_SHADOWS,
    F_TWO_SIDED,
    F_VIEW_PER_POINT,
    FLAT,
    INVERSE_SQUARE,
    L_ATT,
    L_ATT_KIND,
    L_IA,
    L_ID,
    L_IS,
    L_KIND,
    L_VEC,
    LIGHT_COLUMNS,
    POINT,
    SPECULAR_BLINN,
    SPECULAR_NONE,
    SPECULAR_PHONG,
    FilmRows,
    RayParams,
    ShadingInputs,
    ShadowInputs,
)


@dataclass(frozen=True, eq=False)
class CameraRig:
    """An orthonormal camera frame and the half-extent of the image plane at distance 1."""
    eye: np.ndarray        # (3,) float64, world
    right: np.ndarray      # (3,) unit
    up: np.ndarray         # (3,) unit, orthogonal to right and forward
    forward: np.ndarray    # (3,) unit, toward look_at
    half_height: float     # perspective: tan(fov / 2); orthographic: view_height / 2 (world units)
    half_width: float      # half_height × width / height
    orthographic: bool


def camera_rig(scene: Scene) -> CameraRig:
    camera, render = scene.camera, scene.render
    eye = np.asarray(camera.position, np.float64)
    forward = np.asarray(camera.look_at, np.float64) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(camera.up, np.float64))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    orthographic = camera.type == "orthographic"
    half_height = camera.view_height / 2 if orthographic else math.tan(math.radians(camera.fov) / 2)
    return CameraRig(eye, right, up, forward, half_height, half_height * render.width / render.height, orthographic)


class RayGenerator:
    """Primary rays of whole image rows, (N, 3) float32 origins and unit directions in the unit frame.

    A perspective camera's rays all start at the eye: one shared, read-only origins array (Embree
    never writes it) serves every tile, so only directions are computed per tile.
    """

    def __init__(self, rig: CameraRig, frame: Frame, width: int, height: int, samples: int, max_rays: int):
        self.rig, self.frame = rig, frame
        self.width, self.height, self.samples = width, height, samples
        self.params = RayParams(width, height, samples, rig.eye, rig.right, rig.up, rig.forward, rig.half_width,
                                rig.half_height, rig.orthographic, frame.center, 1.0 / frame.scale)
        # (0, 3) for an orthographic camera: kernels take the same argument types either way.
        self.shared_origins = np.zeros((0, 3), np.float32)
        if not rig.orthographic:
            eye = frame.to_unit(rig.eye).astype(np.float32)
            self.shared_origins = np.ascontiguousarray(np.broadcast_to(eye, (max_rays, 3)))

    def rows(self, row0: int, row1: int) -> tuple[np.ndarray, np.ndarray]:
        count = (row1 - row0) * self.width * self.samples * self.samples
        directions = np.empty((count, 3), np.float32)
        if self.rig.orthographic:
            origins = np.empty((count, 3), np.float32)
        else:
            origins = self.shared_origins[:count]
        fill_rows(self.params, row0, row1, origins, directions)
        return origins, directions


def generate_rays(rig: CameraRig, frame: Frame, width: int, height: int, samples: int,
                  row0: int, row1: int) -> tuple[np.ndarray, np.ndarray]:
    """Rays of image rows [row0, row1) (one-off use; render() keeps a RayGenerator)."""
    count = (row1 - row0) * width * samples * samples
    return RayGenerator(rig, frame, width, height, samples, count).rows(row0, row1)


def plan_flags(plan: RenderPlan, scene: Scene) -> tuple[int, int]:
    """The shading kernel's flag bits and specular model for this plan."""
    bits = {F_ATTENUATION: "attenuation", F_LIGHT_AMBIENT: "light_ambient", F_EMISSION: "emission",
            F_SCENE_AMBIENT: "scene_ambient", F_DIFFUSE: "diffuse", F_VIEW_PER_POINT: "view_vector_per_point",
            F_TWO_SIDED: "two_sided", F_SCREEN: "screen_interpolation", F_AOV_GEOMETRY: "aov_geometry",
            F_AOV_TERMS: "aov_terms", F_SHADOWS: "shadow_rays"}
    flags = sum(bit for bit, stage in bits.items() if plan.keeps(stage))
    if not plan.keeps("specular"):
        specular = SPECULAR_NONE
    else:
        specular = SPECULAR_PHONG if scene.render.specular == SpecularModel.PHONG else SPECULAR_BLINN
    return flags, specular


def material_table(materials, real: type, more: np.ndarray | None = None) -> np.ndarray:
    """(M, MATERIAL_COLUMNS) array of `real`: per material k_a, k_d, k_s, k_e (r, g, b each) and f; then the
    rows `more` (material_rows: the materials read from mesh files)."""
    table = material_rows(*(np.array([getattr(m, key) for m in materials], np.float64).reshape(len(materials), -1)
                            for key in ("ka", "kd", "ks", "ke", "shininess")))
    if more is not None:
        table = np.concatenate([table, more])
    return np.ascontiguousarray(table, real)


def light_table(lights, center: np.ndarray, attenuate: bool, real: type) -> np.ndarray:
    """(K, LIGHT_COLUMNS) array of `real`: per light its kind, a point light's position − `center` or a
    directional light's unit vector toward it, I_d, I_s, I_a, and its attenuation kind with c, l, q.

    f_att = 1 for directional lights, whatever the file says. When some light attenuates (`attenuate`),
    "none" is written as min(1, 1/(1 + 0 d + 0 d²)) = 1, so that every light takes the same branch.
    """
    table = np.zeros((len(lights), LIGHT_COLUMNS))
    for row, light in zip(table, lights):
        if light.type == "point":
            row[L_KIND], row[L_VEC:L_VEC + 3] = POINT, np.asarray(light.position) - center
        else:
            toward = -np.asarray(light.direction, np.float64)
            row[L_KIND], row[L_VEC:L_VEC + 3] = DIRECTIONAL, toward / np.linalg.norm(toward)
        row[L_ID:L_ID + 3], row[L_IS:L_IS + 3], row[L_IA:L_IA + 3] = light.diffuse, light.specular, light.ambient
        if light.type == "directional" or light.attenuation == "none":
            row[L_ATT_KIND], row[L_ATT:L_ATT + 3] = (CLQ if attenuate else ATTENUATION_NONE), (1.0, 0.0, 0.0)
        elif light.attenuation == "inverse_square":
            row[L_ATT_KIND], row[L_ATT:L_ATT + 3] = INVERSE_SQUARE, (0.0, 0.0, 1.0)
        else:
            row[L_ATT_KIND], row[L_ATT:L_ATT + 3] = CLQ, light.attenuation
    return np.ascontiguousarray(table, real)


def prepare_shading(scene: Scene, geometry: Geometry, rig: CameraRig, frame: Frame,
                    flags: tuple[int, int], real: type = np.float32) -> ShadingInputs:
    """Pack the scene's numbers into tables of the shading precision `real` for the kernel.

    viewing[V_FLOOR] is the smallest distance 1/d² attenuation divides by, squared: MIN_DISTANCE of the
    scene's half-extent, so a light on the surface gives a large but finite f_att (≤ 1e12 / scale²).
    """
    center = frame.center
    corner = geometry.corner_normals if len(geometry.corner_normals) else np.zeros((1, 3, 3))

    def table(values):
        return np.ascontiguousarray(np.asarray(values, np.float64), dtype=real)

    return ShadingInputs(
        vertices=table(geometry.vertices - center),
        faces=np.ascontiguousarray(geometry.faces, np.int32),
        face_normals=table(geometry.face_normals),
        corner_normals=np.ascontiguousarray(corner, real),  # no copy when geometry made them in `real`
        face_material=np.ascontiguousarray(geometry.face_material, np.int32),
        face_model=np.ascontiguousarray(geometry.face_model, np.int8),
        materials=material_table([DEFAULT_MATERIAL, *scene.materials.values()], real, geometry.file_materials),
        lights=light_table(scene.lights, center, bool(flags[0] & F_ATTENUATION), real),
        # In layout's order: V_AMBIENT, V_EYE, V_VIEW, V_FLOOR and CAM_RIGHT, CAM_UP, CAM_FORWARD, CAM_ORTHOGRAPHIC.
        viewing=table([*scene.ambient, *(rig.eye - center), *(-rig.forward), (MIN_DISTANCE * frame.scale) ** 2]),
        camera=table([*rig.right, *rig.up, *rig.forward, float(rig.orthographic)]),
        background=table(scene.render.background),
        flags=int(flags[0]), specular=int(flags[1]), frame_scale=float(frame.scale),
        zero=real(0), one=real(1), two=real(2),
    )


def prepare_shadows(scene: Scene, geometry: Geometry, frame: Frame, offset_scale: float = 1.0) -> ShadowInputs:
    """Geometry and lights in Embree's unit frame for the shadow-ray kernel (shadows.cast_shadows)."""
    kinds, vectors = [], []
    for light in scene.lights:
        if light.type == "point":
            kinds.append(POINT), vectors.append(frame.to_unit(np.asarray(light.position, np.float64)))
        else:
            toward = -np.asarray(light.direction, np.float64)
            kinds.append(DIRECTIONAL), vectors.append(toward / np.linalg.norm(toward))
    hanika = scene.render.terminator == "hanika" and len(geometry.corner_normals) > 0
    corner = geometry.corner_normals if len(geometry.corner_normals) else np.zeros((1, 3, 3))
    return ShadowInputs(
        vertices=frame.to_unit(geometry.vertices),
        faces=np.ascontiguousarray(geometry.faces, np.int32),
        face_normals=np.ascontiguousarray(geometry.face_normals, np.float64),
        corner_normals=np.ascontiguousarray(corner, np.float64),
        smooth=(geometry.face_model != FLAT) & hanika,
        light_kind=np.asarray(kinds, np.int64).reshape(-1),
        light_vec=np.asarray(vectors, np.float64).reshape(-1, 3),
        two_sided=bool(scene.render.two_sided),
        offset_scale=float(offset_scale),
    )


def no_shadows() -> ShadowInputs:
    """Local mode's stand-in (no lights, nothing to build from): the tile kernel's arguments keep one type."""
    return ShadowInputs(np.zeros((0, 3)), np.zeros((0, 3), np.int32), np.zeros((0, 3)), np.zeros((1, 3, 3)),
                        np.zeros(0, np.bool_), np.zeros(0, np.int64), np.zeros((0, 3)), False)


def film_rows(out: ImageBuffers, counts: np.ndarray | None = None) -> FilmRows:
    """The kernel's FilmRows of image rows `out` (ImageBuffers.rows), with fresh counters unless given."""
    counts = np.zeros(len(COUNTS), np.int64) if counts is None else counts
    return FilmRows(out.rgb, out.terms, out.depth, out.normal, out.face, counts)
