"""A mesh file's materials on the lecture's model (k_a, k_d, k_s, f, k_e), shared by every format's reader
(mtl.py, gltf.py, read.py): the records and the one rule for a file's highlight. No trimesh."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

MAX_FILE_SHININESS = 1000.0  # the .mtl Ns range (0..1000); the glTF roughness map is capped to it too
# A file's specular lobe wider than the scene default's (f = 32) keeps at most that lobe's reflected energy:
# its k_s falls as (f + 2) / (WIDE_LOBE + 2) (specular_lobe says why), and f is at least MIN_FILE_SHININESS.
WIDE_LOBE = 32.0
MIN_FILE_SHININESS = 1.0
# The feature angle at which a file without normals is creased (VTK's vtkPolyDataNormals and Blender's
# auto-smooth both default to 30°): CAD faces keep their edges, a scan's small angles stay smooth.
FILE_CREASE_ANGLE = 30.0


class TextureSource(NamedTuple):
    """A colour map a file's material names, not yet decoded (geometry.textures decodes the ones faces use)."""
    source: object   # a Path (decoded with OpenImageIO) or the PIL image trimesh opened (a glTF's embedded one)
    wrap_s: str      # codes.WRAP_MODES
    wrap_t: str
    name: str        # for notes
    channel: str = "rgb"  # "alpha": the image's alpha channel, as a grey map (an alpha mask's)


@dataclass(frozen=True)
class FileMaterial:
    """A named material of the file, already on the lecture's model (each coefficient in [0, 1])."""
    name: str
    ka: tuple[float, float, float]
    kd: tuple[float, float, float]
    ks: tuple[float, float, float]
    ke: tuple[float, float, float]
    shininess: float
    ka_map: int = -1  # index into MeshFile.texture_sources of the map multiplying k_a (-1: none)
    kd_map: int = -1  # ... k_d (and k_a when ka_map is -1)
    ke_map: int = -1  # ... k_e
    alpha_cutoff: float = -1.0  # MASK: a point whose alpha is below this is cut away; codes.OPAQUE_ALPHA (-1),
                                # codes.BLENDED_ALPHA (-2): BLEND, drawn as coverage
    alpha: float = 1.0          # the alpha factor (glTF baseColorFactor's fourth value)
    alpha_map: int = -1         # texture source of the alpha (channel "alpha"), multiplying the factor

    def as_scene(self) -> dict:
        """The keys of a [materials.NAME] table with these values."""
        return {"ka": list(self.ka), "kd": list(self.kd), "ks": list(self.ks), "ke": list(self.ke),
                "shininess": self.shininess}


@dataclass(frozen=True, eq=False)
class PartSurface:
    """What colours one part of a file read by this package's own readers (threemf.py, ply.py) rather than
    through trimesh's visuals: its material and per-corner texture coordinates and colours."""
    material: FileMaterial | None = None         # None: the faces use the `default` material
    corner_uv: np.ndarray | None = None          # (F, 3, 2) float32, v up
    corner_colour: np.ndarray | None = None      # (F, 3, 3) float32 in [0, 1]: multiplies k_a, k_d (replaces
                                                 # them without a material)


def specular_lobe(ks, shininess: float) -> tuple[np.ndarray, float]:
    """A file's (k_s, f) made into a highlight the lecture's lobe shows faithfully (docs/meshes.md, "Highlights").

    The lecture's lobe max(v·r, 0)^f peaks at k_s whatever its width, so a wide lobe reflects far more light
    than a surface can: f = 0 (glTF roughness 1, .mtl Ns 0) is a second, view-independent diffuse term at
    full strength, which saturates the whole lit side. A normalised lobe's peak is (f + 2)/2π times the light
    it reflects, so a lobe wider than WIDE_LOBE (the scene default's f) has its peak lowered by
    (f + 2)/(WIDE_LOBE + 2): it reflects no more than a WIDE_LOBE lobe of the stated k_s, and a fully rough
    surface looks matte. Lobes at least as narrow keep the file's k_s; f is kept in [1, 1000].
    """
    shininess = min(max(float(shininess), MIN_FILE_SHININESS), MAX_FILE_SHININESS)
    return np.asarray(ks, np.float64) * min(1.0, (shininess + 2) / (WIDE_LOBE + 2)), shininess


def rgb(values) -> tuple[float, float, float]:
    return tuple(float(v) for v in values)  # type: ignore[return-value]

