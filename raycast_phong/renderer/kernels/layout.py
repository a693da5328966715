"""Every table, column, flag and record that crosses into the compiled kernels, named in one place.

The kernels see arrays and these names only, never the scene schema: renderer/pack.py is the one writer
(Scene → these records), the kernels the readers. So an edit to the scene's schema or its messages changes
no kernel module and recompiles nothing (jit.kernel_keys: each kernel module's key covers it and what it imports).
The role of pbrt-v4's wavefront/workitems.h. Imports numpy and the shared codes (codes.py: the model, light
and material-column numbers that the geometry stage writes too, named there once).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...codes import ALPHA as ALPHA
from ...codes import ALPHA_CUTOFF as ALPHA_CUTOFF
from ...codes import ALPHA_MAP as ALPHA_MAP
from ...codes import BLENDED_ALPHA as BLENDED_ALPHA
from ...codes import KA as KA  # the material columns, re-exported for the kernels (`X as X`: on purpose)
from ...codes import KA_MAP as KA_MAP
from ...codes import KD as KD
from ...codes import KD_MAP as KD_MAP
from ...codes import KE as KE
from ...codes import KE_MAP as KE_MAP
from ...codes import KS as KS
from ...codes import LIGHT_CODE, MATERIAL_TABLE_WIDTH, MODEL_CODE, WRAP_CODE, LightKind, ShadingModel
from ...codes import SHININESS as SHININESS

# Bits of the `flags` integer that the render plan fills in (pack.plan_flags; the specular model travels apart).
F_ATTENUATION = 1 << 0     # some point light attenuates
F_LIGHT_AMBIENT = 1 << 1   # some light has its own ambient intensity
F_EMISSION = 1 << 2        # some material emits
F_SCENE_AMBIENT = 1 << 3   # I_a k_a is non-zero somewhere
F_DIFFUSE = 1 << 4         # some light and material have a diffuse part
F_VIEW_PER_POINT = 1 << 5  # local viewer with a perspective camera: v = normalize(eye − p) per point
F_TWO_SIDED = 1 << 6       # flip the shading normal of a back-facing hit toward the viewer
F_SCREEN = 1 << 7          # interpolate with screen-space weights instead of perspective-correct ones
F_AOV_GEOMETRY = 1 << 8    # write depth, normal and face layers
F_AOV_TERMS = 1 << 9       # write the per-term layers
F_SHADOWS = 1 << 10        # global mode: per-ray light visibility masks are given
F_TEXTURES = 1 << 11       # some material has a colour map: sample it at the hit's UV (texture.sample)
F_VERTEX_COLOURS = 1 << 12 # some face has vertex colours: they multiply k_a and k_d per corner
F_ALPHA_MASK = 1 << 13     # some material cuts away where its alpha is below a cutoff (ray_queries.cut_masked)
SPECULAR_NONE, SPECULAR_PHONG, SPECULAR_BLINN = 0, 1, 2     # ShadingInputs.specular

# Shading model codes of ShadingInputs.face_model (geometry.scene_mesh writes codes.MODEL_CODE).
FLAT, GOURAUD, PHONG = (MODEL_CODE[m] for m in (ShadingModel.FLAT, ShadingModel.GOURAUD, ShadingModel.PHONG))

# Columns of the material table (M, 19): k_a, k_d, k_s, k_e (r, g, b each), f, then the texture-table rows of the
# k_a, k_d and k_e maps (KA_MAP, KD_MAP, KE_MAP; -1 none), then the alpha mask's cutoff (-1: opaque), alpha factor
# and alpha map (ALPHA_CUTOFF, ALPHA, ALPHA_MAP), as codes.py names them.
# geometry.materials.material_rows writes rows, pack.material_table the table, shading._shade_rays reads it.
MATERIAL_COLUMNS = MATERIAL_TABLE_WIDTH
# Columns of the texture table (T, 6) int64, written by pack.pack_textures: where a texture's mip pyramid starts
# in the flat texel array (level 0, then each half-size level after it), its level-0 width and height, its
# number of levels, and its wrap modes along u and v (WRAP_REPEAT, WRAP_CLAMP, WRAP_MIRROR).
T_OFFSET, T_WIDTH, T_HEIGHT, T_LEVELS, T_WRAP_S, T_WRAP_T, TEXTURE_COLUMNS = 0, 1, 2, 3, 4, 5, 6
WRAP_REPEAT, WRAP_CLAMP, WRAP_MIRROR = WRAP_CODE["repeat"], WRAP_CODE["clamp"], WRAP_CODE["mirror"]
# Columns of the light table (K, 17), written by pack.light_table.
L_KIND, L_VEC, L_ID, L_IS, L_IA, L_ATT_KIND, L_ATT, LIGHT_COLUMNS = 0, 1, 4, 7, 10, 13, 14, 17
POINT, DIRECTIONAL = LIGHT_CODE[LightKind.POINT], LIGHT_CODE[LightKind.DIRECTIONAL]  # L_KIND, ShadowInputs
ATTENUATION_NONE, INVERSE_SQUARE, CLQ = 0, 1, 2              # L_ATT_KIND
MAX_LIGHTS = 63  # global mode: visibility travels as bits of one int64 per ray

# ShadingInputs.viewing (10,): I_a (r, g, b), the eye, the fixed view vector (−forward: an infinite viewer or
# an orthographic camera), and the smallest d² that 1/d² attenuation divides by.
V_AMBIENT, V_EYE, V_VIEW, V_FLOOR, VIEWING_SIZE = 0, 3, 6, 9, 10
# ShadingInputs.camera (10,): right, up, forward, then 1 for an orthographic camera (0 perspective).
CAM_RIGHT, CAM_UP, CAM_FORWARD, CAM_ORTHOGRAPHIC, CAMERA_SIZE = 0, 3, 6, 9, 10

# Indices into the tile kernel's counts: how many shading points evaluated each optional term, then how many
# shadow rays were cast (global mode's stage, counted where it runs).
COUNTED_TERMS = ("specular", "attenuation", "light_ambient", "emission", "scene_ambient", "diffuse",
                 "view_vector")
C_SPECULAR, C_ATTENUATION, C_LIGHT_AMBIENT, C_EMISSION, C_SCENE_AMBIENT, C_DIFFUSE, C_VIEW = range(7)
TERMS = len(COUNTED_TERMS)
COUNTS = (*COUNTED_TERMS, "shadow_rays")
C_SHADOW_RAYS = TERMS


# The shading engine's scratch lanes (shading._shade_rays shades PACKET rays at a time). A group's hits give up to
# CORNERS × PACKET evaluation points, where the model is evaluated: a flat hit its centroid, a Phong hit the hit point,
# a Gouraud hit its three corners; corner c of ray j is lane j of block c (one block where no hit is Gouraud). Rows of
# the per-point array (CORNERS blocks, POINT_LANES, PACKET): the side the ray sees (±1), the normal held unless
# renormalised (the face normal; a Gouraud corner's vertex normal), the point, the mixed vertex normal and whether to
# renormalise it (1: Phong; 0 else), and the unit shading normal.
CORNERS = 3
(E_SIDE, E_GX, E_GY, E_GZ, E_PX, E_PY, E_PZ, E_SX, E_SY, E_SZ, E_RENORMALISE, E_NX, E_NY, E_NZ,
 POINT_LANES) = range(15)
# Rows of the per-light array (lights, CORNERS blocks, LIGHT_LANES, PACKET): f_att, n·l and the highlight's cosine.
E_FALL, E_N_DOT_L, E_COSINE, LIGHT_LANES = range(4)
# Rows of the per-ray array (RAY_LANES, PACKET): the hit's interpolation weights (screen ones with F_SCREEN).
R_B0, R_B1, R_B2, RAY_LANES = range(4)


class Material(NamedTuple):
    """One row of the material table as scalars, read by name in shading._shade_rays and illumination's helpers:
    scalars, not a row view of the table, since every array argument costs an atomic reference count per call."""
    ka_r: float
    ka_g: float
    ka_b: float
    kd_r: float
    kd_g: float
    kd_b: float
    ks_r: float
    ks_g: float
    ks_b: float
    ke_r: float
    ke_g: float
    ke_b: float
    shininess: float


class ShadingInputs(NamedTuple):
    """Everything the shading kernel reads, in the scene's precision, centred on the scene (pack.prepare_shading).

    A NamedTuple, not a dataclass: numba takes it as one argument and reads its fields by name (a field
    may not be called `view`: numba reads `x.view` as ndarray.view).
    """
    vertices: np.ndarray        # (V, 3)
    faces: np.ndarray           # (F, 3) int32
    face_normals: np.ndarray    # (F, 3)
    corner_normals: np.ndarray  # (F, 3, 3), or (1, 3, 3) of zeros when no face is smooth-shaded
    face_material: np.ndarray   # (F,) int32, row of the material table
    face_model: np.ndarray      # (F,) int8, FLAT, GOURAUD or PHONG
    materials: np.ndarray       # (M, MATERIAL_COLUMNS); row 0 the built-in default
    lights: np.ndarray          # (K, LIGHT_COLUMNS)
    viewing: np.ndarray         # (VIEWING_SIZE,) at V_AMBIENT, V_EYE, V_VIEW, V_FLOOR
    camera: np.ndarray          # (CAMERA_SIZE,) at CAM_RIGHT, CAM_UP, CAM_FORWARD, CAM_ORTHOGRAPHIC
    background: np.ndarray      # (3,) linear RGB of a pixel sample that hits nothing
    flags: int                  # F_* bits from the render plan
    specular: int               # SPECULAR_NONE, SPECULAR_PHONG or SPECULAR_BLINN
    frame_scale: float          # Embree's unit-frame t × frame_scale = world distance
    zero: np.floating           # 0, 1 and 2 in the shading precision: Python literals would widen float32
    one: np.floating
    two: np.floating
    texels: np.ndarray          # (N, 3) float32 linear RGB: every texture's mip pyramid, rows top to bottom
    texture_table: np.ndarray   # (T, TEXTURE_COLUMNS) int64; (0, 6) without textures
    corner_uv: np.ndarray       # (F, 3, 2) float32 per-corner UVs, or (1, 3, 2) without textures
    uv_density: np.ndarray      # (F,) float32 sqrt(UV area / world area) of each face, or (1,) without textures
    corner_colour: np.ndarray   # (F, 3, 3) float32 vertex colours per corner, or (1, 3, 3) without any
    pixel_spread: float         # world footprint of one sample per unit distance (perspective: angle of a
                                # sample, t × spread), or the sample's world size (orthographic)


class TileRays(NamedTuple):
    """A tile's rays and their closest hits, as the kernel reads them (ray k is sample k % n² of pixel k // n²)."""
    face: np.ndarray        # (N,) int32, -1 on a miss
    u: np.ndarray           # (N,) float32, weight of corner 1
    v: np.ndarray           # (N,) float32, weight of corner 2
    t: np.ndarray           # (N,) float32, unit-frame distance
    directions: np.ndarray  # (N, 3) float32, unit
    visible: np.ndarray     # (N,) int64 light bits (global mode), or empty in local mode
    samples: int            # n: n × n samples per pixel


class FilmRows(NamedTuple):
    """Views of whole image rows that the kernel adds into (ImageBuffers.rows), and its counters."""
    rgb: np.ndarray
    terms: np.ndarray
    depth: np.ndarray
    normal: np.ndarray
    face: np.ndarray
    counts: np.ndarray      # (len(COUNTS),) int64: shading points that evaluated each term, shadow rays


class RayParams(NamedTuple):
    """What ray generation needs besides the rows, as one argument for kernels (camera.fill_rows)."""
    width: int
    height: int
    samples: int
    eye: np.ndarray         # (3,) float64, world
    right: np.ndarray
    up: np.ndarray
    forward: np.ndarray
    half_width: float
    half_height: float
    orthographic: bool      # then every ray has its own origin (written); else all start at the eye
    center: np.ndarray      # (3,) the unit frame: unit = (world − center) × inv_scale
    inv_scale: float


class ShadowInputs(NamedTuple):
    """Geometry and lights in Embree's unit frame (float64), for building shadow rays (pack.prepare_shadows)."""
    vertices: np.ndarray        # (V, 3) float64, unit frame
    faces: np.ndarray           # (F, 3) int32
    face_normals: np.ndarray    # (F, 3) float64
    corner_normals: np.ndarray  # (F, 3, 3) float64, or (1, 3, 3) when no face is smooth
    smooth: np.ndarray          # (F,) bool: move the origin to the smooth surface (Hanika) on this face
    light_kind: np.ndarray      # (K,) int64, POINT or DIRECTIONAL
    light_vec: np.ndarray       # (K, 3) float64: unit-frame position, or unit vector toward the light
    two_sided: bool
    offset_scale: float = 1.0   # 1: the Wächter–Binder offset; 0: none (only to show what acne looks like)
