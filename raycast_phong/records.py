"""The pipeline's nouns: plain numpy arrays in small frozen records passed from stage to stage.

F faces, V vertices, K lights, H×W pixels. The Scene itself (validated keys, no arrays) is in scene.py.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from .codes import MATERIAL_TABLE_WIDTH, StageName

if TYPE_CHECKING:
    from numpy.typing import NDArray


@dataclass(frozen=True, eq=False)
class Texture:
    """A colour map decoded into float32 RGB (as render.colour asks), the full-resolution level of its mip pyramid."""
    pixels: np.ndarray   # (H, W, 3) float32 in [0, 1]; row 0 is the top of the image (v = 1)
    wrap_s: str          # codes.WRAP_MODES, along u
    wrap_t: str          # along v
    name: str            # where it came from, for notes


@dataclass(frozen=True, eq=False)
class Geometry:
    """Every object of the scene placed in the world and concatenated into one triangle mesh."""
    vertices: np.ndarray        # (V, 3) float64, world coordinates
    faces: np.ndarray           # (F, 3) int32, indices into vertices
    face_normals: np.ndarray    # (F, 3) float64, unit; zero for a degenerate face
    corner_normals: np.ndarray  # (F, 3, 3) unit vertex normal at each face corner (after crease split); float64,
                                # or float32 when render() shades in float32 (half the bytes, the same image);
                                # empty (0, 3, 3) when no object is smooth-shaded
    face_material: np.ndarray   # (F,) int32, index into the material table
    face_model: np.ndarray      # (F,) int8, 0 flat, 1 gouraud, 2 phong
    face_object: np.ndarray     # (F,) int32, index of the scene object the face belongs to
    notes: tuple[str, ...] = () # what loading changed, e.g. a repaired winding (shown by the plan)
    file_materials: np.ndarray = field(default_factory=lambda: np.zeros((0, MATERIAL_TABLE_WIDTH)))
                                # (M, 19) float64 material-table rows read from mesh files (their .mtl, glTF
                                # materials, colours); face_material counts them after the scene's materials
    file_notes: tuple[str, ...] = ()  # what the mesh files' materials left out (textures, transparency, ...)
    corner_uv: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 2), np.float32))
                                # (F, 3, 2) float32 texture coordinates at each face corner (v up: row 0 of a
                                # texture is v = 1), or empty when no material of the scene has a texture
    corner_colour: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3), np.float32))
                                # (F, 3, 3) float32 vertex colour at each face corner (1 where a face has none),
                                # or empty when no mesh file has vertex colours
    textures: tuple[Texture, ...] = ()  # the decoded textures the material table's map columns index
    scene_maps: np.ndarray = field(default_factory=lambda: np.full((0, 3), -1, np.int64))
                                # (1 + scene materials, 3) texture rows of the default's and the scene's
                                # materials' ka, kd, ke maps (-1: none); empty when none has a map

    @property
    def triangles(self) -> int:
        return len(self.faces)

    @cached_property
    def box(self) -> tuple[np.ndarray, np.ndarray]:
        """bounding_box(vertices), read only, computed once per Geometry: a live view's frames reuse one Geometry,
        and the float-range check and the behind-the-camera warning ask for its box on every frame (5-7 ms
        each on a 1.11M-triangle scan)."""
        low, high = bounding_box(self.vertices)
        low.flags.writeable = high.flags.writeable = False
        return low, high


def bounding_box(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest coordinate (3,) of (V, 3) vertices; NaN if any is NaN (as vertices.min(axis=0)).

    Column by column: numpy reduces a (V, 3) array along axis 0 15-25× slower than three strided columns
    (1M vertices: 85 ms against 3-6 ms, float32 and float64). The box the unit Frame is made from
    (intersect.unit_frame).
    """
    return (np.array([vertices[:, k].min() for k in range(3)]), np.array([vertices[:, k].max() for k in range(3)]))


@dataclass(frozen=True, eq=False)
class Frame:
    """The float32 frame Embree works in: world = unit * scale + center (float64 on both sides)."""
    center: np.ndarray  # (3,) float64, centre of the scene's bounding box
    scale: float        # half the largest extent of the box, so the scene spans about [-1, 1]

    def to_unit(self, points: np.ndarray) -> np.ndarray:
        unit = np.subtract(points, self.center, dtype=np.float64)
        unit /= self.scale  # in place: one (V, 3) array, not two
        return unit


@dataclass(frozen=True, eq=False)
class ImageBuffers:
    """The image and its layers, written in place by the shading kernel, tile by tile.

    A layer that was not asked for is an empty array, so the kernel's signature never changes.
    """
    rgb: np.ndarray     # (H, W, 3) shading precision, zeroed: the kernel adds each sample's share
    terms: np.ndarray   # (H, W, 4, 3) shading precision: ambient, diffuse, specular, emission; (0, 0, 4, 3) if not
    depth: np.ndarray   # (H, W) float32, world distance along the ray, inf on a miss; (0, 0) if not asked
    normal: np.ndarray  # (H, W, 3) float32 shading normal, 0 on a miss; (0, 0, 3) if not asked
    face: np.ndarray    # (H, W) float32 face index, -1 on a miss; (0, 0) if not asked

    def rows(self, row0: int, row1: int) -> ImageBuffers:
        """Views of rows [row0, row1) (an empty layer's slice is empty); C-contiguous because rows are whole."""
        return ImageBuffers(*(a[row0:row1] for a in (self.rgb, self.terms, self.depth, self.normal, self.face)))


@dataclass(frozen=True)
class Stage:
    """One line of a render plan: a stage or term, whether it runs, and why. `name` is one of codes.StageName
    (kept as its plain string, which is what the CLI, the view and JSON show); another name raises ValueError."""
    name: str
    kept: bool
    reason: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", StageName(self.name).value)


@dataclass(frozen=True)
class RenderPlan:
    """What this scene needs, decided before any ray is cast; shading reads its flags.

    `warnings` and `notes` are found once the geometry is known (diagnosis.diagnose). A warning is a result the user
    may not want (printed even under -q); a note is information: what a mesh file's materials left out or
    approximated, or what an object's own choice of Gouraud shading misses.
    """
    stages: tuple[Stage, ...]
    warnings: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    colour: str = "display"         # the scene's render.colour: how maps are decoded and the PNG encoded
    colour_reason: str = ""         # why: the scene files' default, a mesh format's, or set (plan.colour_reason)

    def keeps(self, name: StageName) -> bool:
        for stage in self.stages:
            if stage.name == name:
                return stage.kept
        raise KeyError(name)

    @property
    def real(self) -> type:
        """The shading precision's numpy type: np.float64 where the plan keeps float64 shading, else np.float32."""
        return np.float64 if self.keeps(StageName.FLOAT64_SHADING) else np.float32

    def describe(self) -> str:
        width = max(len(stage.name) for stage in self.stages)
        lines = [f"{'kept' if s.kept else 'left out':8}  {s.name:{width}}  {s.reason}" for s in self.stages]
        lines.append(f"{'colour':8}  {self.colour:{width}}  {self.colour_reason}")
        return "\n".join(lines + [f"warning   {warning}" for warning in self.warnings]
                         + [f"note      {note}" for note in self.notes])


@dataclass(frozen=True, eq=False)
class RenderResult:
    """What render() returns: the image, its layers, and where the time went."""
    image: NDArray[np.float32] | NDArray[np.float64]  # (H, W, 3) the model's values (in render.colour),
                                      # unclamped; float32, or float64 when the plan shades in float64
    aovs: dict[str, np.ndarray]       # layer name -> (H, W, C) float32, only those the scene asks for
    timings: Mapping[str, float]      # seconds per stage: load, geometry, build, rays, shade, frame (and write);
                                      # read-only: with_timings gives a result with more stages
    plan: RenderPlan
    triangles: int
    rays: int
    counts: dict[str, int] = field(default_factory=dict)  # the kernel's term evaluations, and shadow_rays cast

    def __post_init__(self) -> None:
        object.__setattr__(self, "timings", MappingProxyType(dict(self.timings)))

    def with_timings(self, **seconds: float) -> RenderResult:
        """This result with more stages timed (load, write, compile, kernels: what its caller did around the
        render), as a new record of the same type; this one, frozen, keeps its own."""
        return replace(self, timings={**self.timings, **seconds})

    @property
    def colour(self) -> str:
        """The render.colour the image is in: what write_image(..., colour=) needs to encode it."""
        return self.plan.colour

    @property
    def rays_per_second(self) -> float:
        return self.rays / max(self.timings.get("frame", 0.0), 1e-12)

    def _repr_html_(self) -> str:
        """Jupyter shows a render as its image with a small table of its timings and plan. The drawing lives
        in tools/notebook.py (it encodes PNGs); this base record reaches it by the package's public name,
        as a notebook would, so importing records loads nothing."""
        import raycast_phong
        return raycast_phong.show(self)._repr_html_()

    def _repr_png_(self) -> bytes:
        """The image's 8-bit values as `raycast-phong render -o x.png` writes them, for front ends that show PNGs
        only; drawn by tools/notebook.py, reached by the package's public name as _repr_html_ does."""
        import raycast_phong
        return raycast_phong.show(self)._repr_png_()

    def __repr__(self) -> str:
        """One line: size, precision, where the time went, the work done, and the errors when measured (not
        the arrays: a million numbers help no one at a prompt)."""
        height, width = self.image.shape[:2]
        errors = getattr(self, "errors", None)
        measured = "" if errors is None else f", RMSE {errors.rmse:.4g} ({errors.reference})"
        return (f"<{type(self).__name__} {width}×{height} {self.image.dtype}, frame "
                f"{1000 * self.timings.get('frame', 0.0):.1f} ms, {self.rays:,} rays, {self.triangles:,} triangles"
                f"{measured}>")


@dataclass(frozen=True)
class ImageErrors:
    """A render measured against a reference (metrics.measure); errors in linear display values."""
    rmse: float              # root mean square over the RGB values of the pixels both images cover
    max_error: float         # largest |render − reference| over those values
    psnr: float              # 20 log10(1 / rmse), dB; inf for identical images
    mae: float               # mean |render − reference| over those values
    silhouette_pixels: int   # pixels whose coverage differs: covered by one and not (or less) the other
    highlight_loss: float    # share of the reference's specular peak the render misses, 0..1; nan without one
    compared_pixels: int     # pixels both cover fully (the set rmse, max_error, mae are taken over)
    reference: str = "analytic"  # "analytic" or "fine N"


@dataclass(frozen=True, eq=False, repr=False)  # RenderResult's one-line repr, with the errors
class MeasuredResult(RenderResult):
    """A RenderResult that also carries its errors against a reference (accuracy.measured)."""
    errors: ImageErrors | None = None
    reference_seconds: float = 0.0   # time to compute the reference (not part of timings)
