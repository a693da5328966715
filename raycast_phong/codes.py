"""The shared vocabularies, each named once: shading and specular models, viewer and mode, light kinds, mesh
views, precisions, shapes, plan stages, AOV layer names, file suffixes, and the numbers compiled code uses
for them.

The scene schema, the plan, the memory estimate, the film, the geometry stage, the CLI and the kernels'
layout all derive from these, so a new model or layer is added here and nowhere else is a second list to
forget. The integer codes follow each enum's order (flat 0, gouraud 1, phong 2), so they are stated once.
"""

from __future__ import annotations

from enum import Enum


class ShadingModel(str, Enum):
    FLAT = "flat"
    GOURAUD = "gouraud"
    PHONG = "phong"


class SpecularModel(str, Enum):
    PHONG = "phong"
    BLINN = "blinn"


class Viewer(str, Enum):
    LOCAL = "local"
    INFINITE = "infinite"


class Mode(str, Enum):
    LOCAL = "local"
    GLOBAL = "global"


class LightKind(str, Enum):
    POINT = "point"
    DIRECTIONAL = "directional"


class View(str, Enum):
    """Where a mesh file's framing camera looks from (scene.framing)."""
    THREE_QUARTER = "three-quarter"  # the default: 30° round from the front, 20° up
    FRONT = "front"
    SIDE = "side"
    TOP = "top"
    ISO = "iso"


class Precision(str, Enum):
    FLOAT32 = "float32"
    FLOAT64 = "float64"


class StageName(str, Enum):
    """The stages and terms a render plan keeps or leaves out (renderer/plan.py decides each, with its reason)."""
    VERTEX_NORMALS = "vertex_normals"
    CREASE_SPLIT = "crease_split"
    EMISSION = "emission"
    SCENE_AMBIENT = "scene_ambient"
    LIGHT_AMBIENT = "light_ambient"
    DIFFUSE = "diffuse"
    SPECULAR = "specular"
    ATTENUATION = "attenuation"
    VIEW_VECTOR_PER_POINT = "view_vector_per_point"
    SUPERSAMPLING = "supersampling"
    SCREEN_INTERPOLATION = "screen_interpolation"
    TWO_SIDED = "two_sided"
    SHADOW_RAYS = "shadow_rays"
    TERMINATOR_FIX = "terminator_fix"
    AOV_GEOMETRY = "aov_geometry"
    AOV_TERMS = "aov_terms"
    SHADING_MODELS = "shading_models"
    FLOAT64_SHADING = "float64_shading"
    WINDING_REPAIR = "winding_repair"   # known once the geometry is (diagnosis.diagnose)
    TEXTURES = "textures"               # likewise
    VERTEX_COLOURS = "vertex_colours"   # likewise


def codes_of(enum: type[Enum]) -> dict:
    """member → its integer code, the member's position in the enum (what compiled code compares)."""
    return {member: index for index, member in enumerate(enum)}


MODEL_CODE = codes_of(ShadingModel)          # flat 0, gouraud 1, phong 2
LIGHT_CODE = codes_of(LightKind)             # point 0, directional 1

# AOV layers (output.aovs): per-pixel geometry, and the model's terms (the film stores them in this order).
GEOMETRY_LAYERS = ("depth", "normal", "face")
TERM_LAYERS = ("ambient", "diffuse", "specular", "emission")
LAYERS = GEOMETRY_LAYERS + TERM_LAYERS

SCENE_SUFFIXES = (".toml", ".json")   # a scene file; any other suffix trimesh reads is a mesh file
OUTPUT_PATH = ("output", "path")  # the key path of the one file a scene names that it writes (Scene.named_files)
IMAGE_SUFFIXES = (".png", ".exr")     # what the renderer writes: 8-bit PNG, float32 EXR with layers

# The default material (the scene format's [materials] defaults; a mesh file's .mtl omits keys to these).
MATERIAL_DEFAULTS = {"ka": (0.2, 0.2, 0.2), "kd": (0.8, 0.8, 0.8), "ks": (0.5, 0.5, 0.5), "ke": (0.0, 0.0, 0.0),
                     "shininess": 32.0}

# A material-table row: ka (3), kd (3), ks (3), ke (3), shininess; the first column of each and the width.
MATERIAL_COLUMNS = ("ka", "kd", "ks", "ke", "shininess")
KA, KD, KS, KE, SHININESS, MATERIAL_WIDTH = 0, 3, 6, 9, 12, 13
# After those, the row of the texture table each colour map uses (-1: none): the map that multiplies k_a, the
# one that multiplies k_d, the one that multiplies k_e; the kernels read them only when the scene has textures.
MAP_COLUMNS = ("ka_map", "kd_map", "ke_map")
KA_MAP, KD_MAP, KE_MAP = 13, 14, 15
# Then alpha as glTF's alphaMode cuts with it (ray_queries.cut_masked): the cutoff (MASK: 0 or more; OPAQUE_ALPHA:
# nothing is cut; BLENDED_ALPHA: each ray sample is cut with probability 1 − alpha), the alpha factor, and the
# texture row of its alpha map (an image's alpha channel; -1: none).
ALPHA_CUTOFF, ALPHA, ALPHA_MAP, MATERIAL_TABLE_WIDTH = 16, 17, 18, 19
OPAQUE_ALPHA, BLENDED_ALPHA = -1.0, -2.0
# Texture wrap modes (glTF sampler codes 10497, 33071, 33648 and OBJ "-clamp on" map onto them).
WRAP_MODES = ("repeat", "clamp", "mirror")
WRAP_CODE = {name: index for index, name in enumerate(WRAP_MODES)}
GLTF_WRAP = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
