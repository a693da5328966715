"""Scene → the kernels' records: every table and column of kernels/layout.py is written here and only here.

The kernels read arrays and named layouts, never the scene schema; this module is where a Scene, its
Geometry, the unit Frame and the render plan become ShadingInputs, ShadowInputs, RayParams and FilmRows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..codes import OPAQUE_ALPHA, WRAP_CODE, StageName
from ..geometry.materials import rows_of
from ..records import Frame, Geometry, ImageBuffers, RenderPlan, Texture
from ..scene.schema import DEFAULT_MATERIAL, Scene, SpecularModel
from ..tolerances import MIN_DISTANCE
from .kernels.camera import fill_rows
from .kernels.layout import (
    ALPHA_CUTOFF,
    ATTENUATION_NONE,
    CLQ,
    COUNTS,
    DIRECTIONAL,
    F_ALPHA_MASK,
    F_AOV_GEOMETRY,
    F_AOV_TERMS,
    F_ATTENUATION,
    F_DIFFUSE,
    F_EMISSION,
    F_LIGHT_AMBIENT,
    F_SCENE_AMBIENT,
    F_SCREEN,
    F_SHADOWS,
    F_TEXTURES,
    F_TWO_SIDED,
    F_VERTEX_COLOURS,
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
    TEXTURE_COLUMNS,
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
        origins = np.empty((count, 3), np.float32) if self.rig.orthographic else self.shared_origins[:count]
        fill_rows(self.params, row0, row1, origins, directions)
        return origins, directions


def generate_rays(rig: CameraRig, frame: Frame, width: int, height: int, samples: int,
                  row0: int, row1: int) -> tuple[np.ndarray, np.ndarray]:
    """Rays of image rows [row0, row1) (one-off use; render() keeps a RayGenerator)."""
    count = (row1 - row0) * width * samples * samples
    return RayGenerator(rig, frame, width, height, samples, count).rows(row0, row1)


def plan_flags(plan: RenderPlan, scene: Scene) -> tuple[int, int]:
    """The shading kernel's flag bits and specular model for this plan."""
    bits = {F_ATTENUATION: StageName.ATTENUATION, F_LIGHT_AMBIENT: StageName.LIGHT_AMBIENT,
            F_EMISSION: StageName.EMISSION, F_SCENE_AMBIENT: StageName.SCENE_AMBIENT, F_DIFFUSE: StageName.DIFFUSE,
            F_VIEW_PER_POINT: StageName.VIEW_VECTOR_PER_POINT, F_TWO_SIDED: StageName.TWO_SIDED,
            F_SCREEN: StageName.SCREEN_INTERPOLATION, F_AOV_GEOMETRY: StageName.AOV_GEOMETRY,
            F_AOV_TERMS: StageName.AOV_TERMS, F_SHADOWS: StageName.SHADOW_RAYS, F_TEXTURES: StageName.TEXTURES,
            F_VERTEX_COLOURS: StageName.VERTEX_COLOURS}
    flags = sum(bit for bit, stage in bits.items() if plan.keeps(stage))
    specular = (SPECULAR_NONE if not plan.keeps(StageName.SPECULAR)
                else SPECULAR_PHONG if scene.render.specular == SpecularModel.PHONG else SPECULAR_BLINN)
    return flags, specular


def material_table(materials, real: type, more: np.ndarray | None = None,
                   maps: np.ndarray | None = None) -> np.ndarray:
    """(M, MATERIAL_COLUMNS) array of `real`: per material k_a, k_d, k_s, k_e (r, g, b each), f and its map
    rows (`maps`, (M, 3), Geometry.scene_maps; -1 without); then the rows `more` (material_rows: the
    materials read from mesh files)."""
    table = rows_of(materials, maps if maps is not None and len(maps) else None)
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


MIP_FLOOR = 1  # the last level of a pyramid is 1 texel on its shorter side


def mip_pyramid(pixels: np.ndarray) -> list[np.ndarray]:
    """Level 0 (H, W, 3) and each level after it at half the size (floor, at least 1): every texel the mean
    of the 2 × 2 texels it covers (a box filter; an odd last row or column joins no texel), down to 1 texel
    on the shorter side. The mean of a linear function over a 2 × 2 block is its value at the block's
    centre, so a linear ramp is the same function of (u, v) on every level."""
    levels = [np.ascontiguousarray(pixels, np.float32)]
    while min(levels[-1].shape[:2]) > MIP_FLOOR:
        last = levels[-1]
        h, w = max(1, last.shape[0] // 2), max(1, last.shape[1] // 2)
        rows = last[:2 * h] if last.shape[0] > 1 else np.concatenate([last, last])
        both = rows[:, :2 * w] if last.shape[1] > 1 else np.concatenate([rows, rows], axis=1)
        block = both.reshape(h, 2, w, 2, 3).astype(np.float64)
        levels.append(block.mean(axis=(1, 3)).astype(np.float32))
    return levels


def pack_textures(textures: tuple[Texture, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Every texture's mip pyramid in one flat (N, 3) float32 texel array, and the (T, TEXTURE_COLUMNS) int64
    table of layout.py: offset, width, height, levels, wrap_s, wrap_t (texture.sample reads them)."""
    table = np.zeros((len(textures), TEXTURE_COLUMNS), np.int64)
    parts, offset = [], 0
    for row, texture in zip(table, textures):
        levels = mip_pyramid(texture.pixels)
        h, w = texture.pixels.shape[:2]
        row[:] = offset, w, h, len(levels), WRAP_CODE[texture.wrap_s], WRAP_CODE[texture.wrap_t]
        parts += [level.reshape(-1, 3) for level in levels]
        offset += sum(len(level.reshape(-1, 3)) for level in levels)
    texels = np.concatenate(parts) if parts else np.zeros((1, 3), np.float32)
    return np.ascontiguousarray(texels, np.float32), table


def uv_density(geometry: Geometry) -> np.ndarray:
    """(F,) float32 sqrt(UV area / world area) per face: texels per world length divided by sqrt(w h)
    (0 on a face of no world area)."""
    corners = geometry.vertices[geometry.faces]
    world = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    uv = geometry.corner_uv.astype(np.float64)
    e1, e2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    area = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        density = np.where(world > 0, np.sqrt(area / np.where(world > 0, world, 1.0)), 0.0)
    return density.astype(np.float32)


def prepare_shading(scene: Scene, geometry: Geometry, rig: CameraRig, frame: Frame,
                    flags: tuple[int, int], real: type = np.float32, kept: dict | None = None) -> ShadingInputs:
    """Pack the scene's numbers into tables of the shading precision `real` for the kernel.

    viewing[V_FLOOR] is the smallest distance 1/d² attenuation divides by, squared: MIN_DISTANCE of the
    scene's half-extent, so a light on the surface gives a large but finite f_att (≤ 1e12 / scale²).
    `kept` (a FrameCache's reuse.Derived of this geometry) keeps the tables made from the geometry alone (its
    vertices, normals, texels), so that the next frame of the same arrays packs only the lights and camera.
    """
    center = frame.center
    corner = geometry.corner_normals if len(geometry.corner_normals) else np.zeros((1, 3, 3))

    def table(values):
        return np.ascontiguousarray(np.asarray(values, np.float64), dtype=real)

    def of_geometry(name: str, fields: tuple[str, ...], make):
        """make(), computed from the Geometry `fields` alone (and the frame, made from its vertices), or what
        it gave before for the same bits."""
        return make() if kept is None else kept.get(("shading", name, np.dtype(real).str), fields, make)

    materials = material_table([DEFAULT_MATERIAL, *scene.materials.values()], real, geometry.file_materials,
                               geometry.scene_maps)
    bits = int(flags[0])
    if (materials[:, ALPHA_CUTOFF] != OPAQUE_ALPHA).any():  # a material's alpha cuts (MASK) or covers (BLEND)
        bits |= F_ALPHA_MASK
    if bits & F_TEXTURES:  # the plan's "textures" stage (diagnosis.surface_maps) decided it
        texels, texture_table = of_geometry("textures", ("textures",), lambda: pack_textures(geometry.textures))
        corner_uv = np.ascontiguousarray(geometry.corner_uv, np.float32)
        density = of_geometry("uv_density", ("vertices", "faces", "corner_uv"), lambda: uv_density(geometry))
    else:
        texels, texture_table = np.zeros((1, 3), np.float32), np.zeros((0, TEXTURE_COLUMNS), np.int64)
        corner_uv, density = np.zeros((1, 3, 2), np.float32), np.zeros(1, np.float32)
    colours = (np.ascontiguousarray(geometry.corner_colour, np.float32) if bits & F_VERTEX_COLOURS
               else np.ones((1, 3, 3), np.float32))
    # One sample's spread: its angle (perspective, at the image centre) or its world size (orthographic).
    spread = 2.0 * rig.half_height / (scene.render.height * scene.render.samples)

    return ShadingInputs(
        vertices=of_geometry("vertices", ("vertices",), lambda: table(geometry.vertices - center)),
        faces=np.ascontiguousarray(geometry.faces, np.int32),
        face_normals=of_geometry("face_normals", ("face_normals",), lambda: table(geometry.face_normals)),
        corner_normals=np.ascontiguousarray(corner, real),  # no copy when geometry made them in `real`
        face_material=np.ascontiguousarray(geometry.face_material, np.int32),
        face_model=np.ascontiguousarray(geometry.face_model, np.int8),
        materials=materials,
        lights=light_table(scene.lights, center, bool(flags[0] & F_ATTENUATION), real),
        # In layout's order: V_AMBIENT, V_EYE, V_VIEW, V_FLOOR and CAM_RIGHT, CAM_UP, CAM_FORWARD, CAM_ORTHOGRAPHIC.
        viewing=table([*scene.ambient, *(rig.eye - center), *(-rig.forward), (MIN_DISTANCE * frame.scale) ** 2]),
        camera=table([*rig.right, *rig.up, *rig.forward, float(rig.orthographic)]),
        background=table(scene.render.background),
        flags=bits, specular=int(flags[1]), frame_scale=float(frame.scale),
        zero=real(0), one=real(1), two=real(2),
        texels=texels, texture_table=texture_table, corner_uv=corner_uv, uv_density=density,
        corner_colour=colours, pixel_spread=float(spread),
    )


def prepare_shadows(scene: Scene, geometry: Geometry, frame: Frame, offset_scale: float = 1.0) -> ShadowInputs:
    """Geometry and lights in Embree's unit frame for the shadow-ray kernel (shadows.cast_shadows)."""
    kinds = [POINT if light.type == "point" else DIRECTIONAL for light in scene.lights]
    vectors = [frame.to_unit(np.asarray(light.position, np.float64)) if light.type == "point"
               else -np.asarray(light.direction, np.float64) / np.linalg.norm(light.direction)
               for light in scene.lights]
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


def film_rows(out: ImageBuffers) -> FilmRows:
    """The kernel's FilmRows of image rows `out` (ImageBuffers.rows), with fresh counters."""
    return FilmRows(out.rgb, out.terms, out.depth, out.normal, out.face, np.zeros(len(COUNTS), np.int64))
