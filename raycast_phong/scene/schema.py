"""The scene format as pydantic models, with its limits: a parsed scene table into a validated, frozen Scene.

The scene format is version 1; docs/scene-format.md lists every key with its default and allowed range.
Every problem becomes one SceneError naming the file, the key path and what is allowed (worded by
scene.messages), so the CLI can print one line and exit 2. Reading files is scene.load's (through
io.scene_file), `--set` is scene.overrides'.
"""

from __future__ import annotations

import difflib
import gc
import math
import operator
from itertools import chain, repeat
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

import annotated_types
import numpy as np
from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    Strict,
    ValidationError,
    field_validator,
    model_validator,
)

from ..codes import (
    IMAGE_SUFFIXES,
    LAYERS,
    MAP_COLUMNS,
    MATERIAL_DEFAULTS,
    OUTPUT_PATH,
    SHAPES,
    WRAP_MODES,
    LightKind,
    Mode,
    Precision,
    ShadingModel,
    SpecularModel,
    Viewer,
)
from ..errors import RaycastPhongError, SceneError
from ..io.encoding import COLOURS
from ..tolerances import DIRECTION_RANGE, INTENSITY_LIMIT, POSITION_LIMIT
from .kinds import object_kinds
from .messages import describe_error, dotted, shown

MAX_SIZE = 16384          # pixels per side, from the format
MAX_SAMPLES = 16          # 16×16 = 256 rays per pixel is already a reference-quality render
MAX_PIXEL_RAYS = 2**31 - 1  # embree indexes rays with int32 per call; beyond this a frame is absurd anyway

# ---------------------------------------------------------------- value types

def _number(value: Any) -> Any:
    """TOML and JSON tell text and booleans from numbers, so "32" or true where a number belongs is a
    mistake in the file; pydantic's lax mode would quietly convert them."""
    if isinstance(value, (str, bool, dict, list, tuple)) or value is None:
        raise ValueError(f"must be a number, got {shown(value)}")
    return value


def _whole(value: Any) -> Any:
    """As _number, for counts: width, height, samples, subdivisions, segments."""
    if isinstance(value, (str, bool, dict, list, tuple)) or value is None:
        raise ValueError(f"must be a whole number, got {shown(value)}")
    return value


Number = Annotated[float, BeforeValidator(_number)]
Whole = Annotated[int, BeforeValidator(_whole)]


def _triple(value: Any) -> Any:
    """A single number means the same value in all three channels (format: Conventions)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return (value, value, value)
    sequence = _sequence(value)
    if sequence is None or len(sequence) != 3:
        count = f"{len(sequence)} numbers: " if sequence is not None else ""
        raise ValueError(f"must be three numbers [a, b, c] (or one number for all three), got {count}{shown(value)}")
    return sequence


def _sequence(value: Any) -> tuple | None:
    """A list from the file, or any sized iterable from Python callers (a numpy array), as a tuple."""
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__") or not hasattr(value, "__iter__"):
        return None
    return tuple(value)


def _finite(values: tuple[float, ...]) -> tuple[float, ...]:
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"must be finite numbers, got {list(values)}")
    return values


def _position(values: tuple[float, ...]) -> tuple[float, ...]:
    """A point in the world: finite, each coordinate within ±POSITION_LIMIT."""
    _finite(values)
    if not all(abs(v) <= POSITION_LIMIT for v in values):
        raise ValueError(f"each coordinate must be within ±{POSITION_LIMIT:g} (so squared distances stay finite "
                         f"in float32), got {list(values)}")
    return values


def _direction(values: tuple[float, ...]) -> tuple[float, ...]:
    """A direction: finite, with a length in DIRECTION_RANGE (the zero vector is left to the owner's check,
    which says what the direction is for)."""
    _finite(values)
    length, (low, high) = math.hypot(*values), DIRECTION_RANGE
    if length != 0.0 and not low <= length <= high:
        raise ValueError(f"length {length:.3g}; allowed: {low:g} ≤ length ≤ {high:g} (its square must be a normal "
                         f"float64 to normalise it), got {list(values)}")
    return values


def _unit_range(values: tuple[float, ...]) -> tuple[float, ...]:
    _finite(values)
    if not all(0.0 <= v <= 1.0 for v in values):
        raise ValueError(f"each coefficient must be in [0, 1], got {list(values)}")
    return values


def _non_negative(values: tuple[float, ...]) -> tuple[float, ...]:
    _finite(values)
    if not all(0.0 <= v <= INTENSITY_LIMIT for v in values):
        raise ValueError(f"intensities must be in [0, {INTENSITY_LIMIT:g}] (a pixel must stay finite in float32), "
                         f"got {list(values)}")
    return values


Vec3 = Annotated[tuple[Number, Number, Number], BeforeValidator(_triple)]
Coefficient = Annotated[tuple[Number, Number, Number], BeforeValidator(_triple)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)


# ---------------------------------------------------------------- tables

class Render(_Strict):
    width: Whole = Field(640, ge=1, le=MAX_SIZE)
    height: Whole = Field(480, ge=1, le=MAX_SIZE)
    shading: ShadingModel = ShadingModel.PHONG
    specular: SpecularModel = SpecularModel.PHONG
    viewer: Viewer = Viewer.LOCAL
    mode: Mode = Mode.LOCAL
    terminator: Literal["none", "hanika"] = "hanika"
    samples: Whole = Field(1, ge=1, le=MAX_SAMPLES)
    background: Vec3 = (0.0, 0.0, 0.0)
    precision: Literal[tuple(p.value for p in Precision)] = "float32"  # type: ignore[valid-type]
    two_sided: Annotated[bool, Strict()] = True  # true or false, not "yes" or 1
    interpolation: Literal["perspective", "screen"] = "perspective"
    # "display" (fixed-function GL's): maps and colours as stored, the PNG written as it is; "linear" (glTF's):
    # 8-bit maps decoded from sRGB, the PNG through the sRGB curve. A mesh file rendered directly gets its
    # format's choice (scene.framing.mesh_colour); a scene file, this default.
    colour: Literal[COLOURS] = COLOURS[0]  # type: ignore[valid-type]

    _check_background = field_validator("background")(lambda v: _non_negative(v))


class Camera(_Strict):
    type: Literal["perspective", "orthographic"] = "perspective"
    position: Vec3 = (0.0, 0.0, 4.0)
    look_at: Vec3 = (0.0, 0.0, 0.0)
    up: Vec3 = (0.0, 1.0, 0.0)
    fov: Number = Field(40.0, gt=0.0, lt=180.0)
    view_height: Number = Field(2.0, gt=0.0, le=POSITION_LIMIT, allow_inf_nan=False)

    _check_position = field_validator("position", "look_at")(lambda v: _position(v))
    _check_up = field_validator("up")(lambda v: _direction(v))

    @model_validator(mode="after")
    def _frame(self) -> Camera:
        forward = [b - a for a, b in zip(self.position, self.look_at)]
        if math.hypot(*forward) == 0.0:
            raise _KeyError(("camera", "look_at"), f"{list(self.look_at)} is the camera position too, so the camera "
                            "has no viewing direction; look_at must differ from camera.position")
        if math.hypot(*forward) < DIRECTION_RANGE[0]:
            raise _KeyError(("camera", "look_at"), f"{list(self.look_at)} is only {math.hypot(*forward):.3g} from "
                            f"camera.position; allowed: at least {DIRECTION_RANGE[0]:g} (the viewing direction "
                            "look_at − position is normalised by sqrt(v·v))")
        if math.hypot(*self.up) == 0.0:
            raise _KeyError(("camera", "up"), "the zero vector; give any direction not parallel to look_at − position")
        cross = (forward[1] * self.up[2] - forward[2] * self.up[1],
                 forward[2] * self.up[0] - forward[0] * self.up[2],
                 forward[0] * self.up[1] - forward[1] * self.up[0])
        # Relative test: |f × up| / (|f| |up|) is the sine of the angle between them.
        if math.hypot(*cross) <= 1e-9 * math.hypot(*forward) * math.hypot(*self.up):
            raise _KeyError(("camera", "up"), f"{list(self.up)} is parallel to the viewing direction {forward}; "
                            "choose an up vector at an angle to look_at − position")
        return self


ATTENUATION_ALLOWED = (f'"none", "inverse_square" or [c, l, q] with 0 ≤ c, l, q ≤ {INTENSITY_LIMIT:g}, '
                       'not all zero')


def _attenuation(value: Any) -> Any:
    if isinstance(value, str):
        if value not in ("none", "inverse_square"):
            raise ValueError(f"allowed: {ATTENUATION_ALLOWED}; got {value!r}")
        return value
    sequence = _sequence(value)
    if sequence is None:
        raise ValueError(f"allowed: {ATTENUATION_ALLOWED}; got {shown(value)}")
    if len(sequence) != 3:
        raise ValueError(f"the attenuation list is [c, l, q], got {len(sequence)} numbers: {shown(sequence)}")
    c, l, q = (float(_number(x)) for x in sequence)  # noqa: E741
    # min(1, 1/(c + l·d + q·d²)) is defined for every d ≥ 0 when no coefficient is negative: where the sum
    # is 0 (c = 0 at d = 0) the clamp gives 1. All zero would be "none" in disguise. The kernel's tables
    # are float32, so each coefficient must be finite there.
    if not all(0 <= x <= INTENSITY_LIMIT for x in (c, l, q)) or c == l == q == 0:
        raise ValueError(f"got [c, l, q] = {list(sequence)}; allowed: {ATTENUATION_ALLOWED}")
    return (c, l, q)


class Light(_Strict):
    type: Literal[tuple(kind.value for kind in LightKind)] = "point"  # type: ignore[valid-type]
    position: Vec3 | None = None
    direction: Vec3 | None = None
    diffuse: Vec3 = (0.8, 0.8, 0.8)
    specular: Vec3 = (1.0, 1.0, 1.0)
    ambient: Vec3 = (0.0, 0.0, 0.0)
    attenuation: Annotated[Literal["none", "inverse_square"] | tuple[float, float, float],
                           BeforeValidator(_attenuation)] = "none"

    _check_position = field_validator("position")(lambda v: v if v is None else _position(v))
    _check_direction = field_validator("direction")(lambda v: v if v is None else _direction(v))
    _check_intensity = field_validator("diffuse", "specular", "ambient")(lambda v: _non_negative(v))

    @model_validator(mode="after")
    def _placement(self) -> Light:
        if self.type == "point" and self.position is None:
            raise ValueError("a point light needs position = [x, y, z]")
        if self.type == "directional":
            if self.direction is None:
                raise ValueError("a directional light needs direction = [x, y, z] (the way the light travels)")
            if math.hypot(*self.direction) == 0.0:
                raise ValueError("direction is the zero vector")
        return self


class TextureMap(_Strict):
    """A colour map: an image file relative to the scene file, and how it repeats outside [0, 1]."""
    path: str
    wrap: Literal[WRAP_MODES] = "repeat"  # type: ignore[valid-type]


def _map(value: Any) -> Any:
    return {"path": value} if isinstance(value, str) else value  # kd_map = "wood.png" is the short form


MapKey = Annotated[TextureMap, BeforeValidator(_map)] | None


class Material(_Strict):
    ka: Coefficient = MATERIAL_DEFAULTS["ka"]
    kd: Coefficient = MATERIAL_DEFAULTS["kd"]
    ks: Coefficient = MATERIAL_DEFAULTS["ks"]
    ke: Coefficient = MATERIAL_DEFAULTS["ke"]
    shininess: Number = MATERIAL_DEFAULTS["shininess"]
    ka_map: MapKey = None  # multiplies k_a (the kd_map does when this is not given)
    kd_map: MapKey = None  # multiplies k_d and k_a at the hit's texture coordinates
    ke_map: MapKey = None  # multiplies k_e

    _check_coefficients = field_validator("ka", "kd", "ks", "ke")(lambda v: _unit_range(v))

    @field_validator("shininess")
    @classmethod
    def _shininess(cls, value: float) -> float:
        # The material table is in the shading precision: a finite f must also be finite in float32. Beyond
        # 1e38, x^f is 0 for every x < 1 anyway, which is what inf (the mirror limit) says.
        if math.isnan(value) or value < 0 or INTENSITY_LIMIT < value < math.inf:
            raise ValueError(f"shininess must be ≥ 0 (inf allowed: the mirror limit) and, if finite, at most "
                             f"{INTENSITY_LIMIT:g}, got {value}")
        return value


# The keys only some shapes read; every other key of [[objects]] applies to all of them.
SHAPE_KEYS = {"icosphere": ("radius", "subdivisions"), "uv_sphere": ("radius", "segments"), "box": ("size",),
              "plane": ("size", "segments"), "cylinder": ("radius", "height", "segments"),
              "torus": ("major_radius", "minor_radius", "segments"), "mesh": ("path",)}


SEGMENTS = (3, 4096)  # each of an object's two segment counts, inclusive


def _pair(value: Any) -> Any:
    sequence = _sequence(value)
    if sequence is None or len(sequence) != 2:
        raise ValueError(f"must be two whole numbers [a, b] in [{SEGMENTS[0]}, {SEGMENTS[1]}], got {shown(value)}")
    return sequence


NormalsRule = Literal["mean", "area", "angle", "file", "exact"]  # how an object's vertex normals are made
SIZE_LENGTHS = {"box": 3, "plane": 2}  # how many numbers `size` has for the shapes that read it


class Object(_Strict):
    name: str | None = None
    shape: Literal[SHAPES]  # type: ignore[valid-type]
    subdivisions: Whole = Field(2, ge=0, le=8)
    segments: Annotated[tuple[Whole, Whole], BeforeValidator(_pair)] | None = None
    radius: Number = Field(1.0, gt=0.0, le=POSITION_LIMIT, allow_inf_nan=False)
    height: Number = Field(2.0, gt=0.0, le=POSITION_LIMIT, allow_inf_nan=False)      # cylinder: length along local z
    major_radius: Number = Field(1.0, gt=0.0, le=POSITION_LIMIT, allow_inf_nan=False)
    minor_radius: Number = Field(0.25, gt=0.0, le=POSITION_LIMIT, allow_inf_nan=False)
    size: tuple[Number, ...] | None = None
    path: str | None = None
    material: str = "default"
    shading: ShadingModel | None = None
    normals: NormalsRule | None = None  # None: "file" if the mesh file stores vertex normals, else "mean"
    crease_angle: Number = Field(180.0, ge=0.0, le=180.0)
    translate: Vec3 = (0.0, 0.0, 0.0)
    rotate: Vec3 = (0.0, 0.0, 0.0)
    scale: Vec3 = (1.0, 1.0, 1.0)

    _check_translate = field_validator("translate")(lambda v: _position(v))
    _check_rotate = field_validator("rotate")(lambda v: _finite(v))

    @field_validator("scale")
    @classmethod
    def _scale(cls, value: tuple[float, float, float]) -> tuple[float, float, float]:
        _finite(value)
        if any(v == 0 for v in value):
            raise ValueError(f"scale {list(value)} has a zero factor, which flattens the object")
        # A shape's lengths are at most POSITION_LIMIT, so the scaled coordinates stay finite in float64 and
        # the placed object's own bound (geometry.place) can be checked.
        if not all(abs(v) <= POSITION_LIMIT for v in value):
            raise ValueError(f"each factor must be within ±{POSITION_LIMIT:g}, got {list(value)}")
        return value

    @field_validator("segments")
    @classmethod
    def _segments(cls, value):
        if value is not None and not all(SEGMENTS[0] <= s <= SEGMENTS[1] for s in value):
            raise ValueError(f"segments must be two whole numbers in [{SEGMENTS[0]}, {SEGMENTS[1]}], got {list(value)}")
        return value

    @field_validator("size")
    @classmethod
    def _size(cls, value):
        if value is not None:
            _finite(value)
            if len(value) not in (2, 3) or not all(0 < v <= POSITION_LIMIT for v in value):
                raise ValueError(f"size must be 2 (plane) or 3 (box) numbers in (0, {POSITION_LIMIT:g}], "
                                 f"got {list(value)}")
        return value

    @model_validator(mode="after")
    def _shape_keys(self) -> Object:
        if self.shape == "mesh" and not self.path:
            raise ValueError('shape = "mesh" needs path = "file.obj" (any format trimesh reads)')
        if self.shape != "mesh" and self.normals == "file":
            raise ValueError(f'normals = "file" needs a mesh file; shape = "{self.shape}" has no stored normals')
        if self.shape == "mesh" and self.normals == "exact":
            raise ValueError('normals = "exact" needs a built-in shape; a mesh file has no closed form (use "file", '
                             '"mean", "area" or "angle")')
        if self.size is not None and self.shape in SIZE_LENGTHS and len(self.size) != SIZE_LENGTHS[self.shape]:
            raise ValueError("a box's size is [x, y, z]" if self.shape == "box" else "a plane's size is [width, depth]")
        return self


class Output(_Strict):
    path: str = "out.png"
    aovs: tuple[Literal[LAYERS], ...] = ()  # type: ignore[valid-type]

    @model_validator(mode="before")
    @classmethod
    def _default_path(cls, data: Any) -> Any:
        # Layers need EXR: with aovs and no path, default to out.exr rather than refuse out.png.
        if isinstance(data, dict) and data.get("aovs") and "path" not in data:
            return {**data, "path": "out.exr"}
        return data

    @model_validator(mode="after")
    def _format(self) -> Output:
        suffix = Path(self.path).suffix.lower()
        if suffix not in IMAGE_SUFFIXES:
            raise _KeyError(("output", "path"), f"{self.path!r} must end in .png or .exr")
        if self.aovs and suffix != ".exr":
            raise _KeyError(("output", "aovs"), f"{list(self.aovs)} need an .exr output, but output.path is "
                            f"{self.path!r} (a PNG holds only RGB)")
        return self

    def check_inside(self, source: str) -> None:
        """Refuse a path that leaves the scene's folder (absolute, ~ or '..'), before it is written to.

        A scene file is data, possibly someone else's: it may write beside itself or below, never over
        ~/.x.png or ../../x.png. An output elsewhere is the user's choice, made with -o (which the scene's
        path then does not matter to, so this is checked where the path is used, not while loading).
        """
        path = Path(self.path)
        if path.is_absolute() or self.path.startswith("~") or ".." in path.parts:
            raise SceneError(f"{source}: output.path: {self.path!r} leaves the scene's folder (an absolute path, ~ "
                             "or '..'); give a path inside that folder, or choose the output with -o")


DEFAULT_MATERIAL = Material()


class Scene(_Strict):
    """A validated scene: every key of the format with its value or default."""
    render: Render = Render()
    camera: Camera = Camera()
    ambient: Vec3 = (0.1, 0.1, 0.1)
    lights: tuple[Light, ...] = ()
    materials: dict[str, Material] = {}
    objects: tuple[Object, ...] = ()
    output: Output = Output()
    folder: str = Field(".", exclude=True)  # the scene file's folder: relative paths start here
    # The mesh files' io.mesh_source.MeshSource made while loading (framing a mesh file), by source_key: handed
    # with the scene to prepare(), which reads no file twice. What was read, not part of the scene's value.
    _mesh_sources: dict = PrivateAttr(default_factory=dict)

    _check_ambient = field_validator("ambient")(lambda v: _non_negative(v))

    @model_validator(mode="after")
    def _references(self) -> Scene:
        if not self.objects:
            raise _KeyError(("objects",), 'the scene has no [[objects]]; add at least one, e.g. '
                            '[[objects]] shape = "icosphere"')
        index = _first_misfit(self)
        if index is not None:
            obj = self.objects[index]
            # Like an unknown key, a key the shape does not read is a mistake the file should hear about. Only a
            # value other than the default counts, so a scene written back with every key (model_dump) still reads.
            foreign = sorted(key for key in _SHAPE_ONLY_KEYS - set(SHAPE_KEYS[obj.shape])
                             if getattr(obj, key) != Object.model_fields[key].default)
            if foreign:
                raise _KeyError(("objects", index, foreign[0]), f'does not apply to shape = "{obj.shape}"; '
                                f'a {obj.shape} reads {", ".join(SHAPE_KEYS[obj.shape])} besides the keys of '
                                "every object; remove it")
            close = difflib.get_close_matches(obj.material, list(self.materials), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            defined = ", ".join(sorted(self.materials)) or "none"
            raise _KeyError(("objects", index, "material"),
                            f"material {obj.material!r} is not defined{hint}; defined: {defined}")
        width, height, samples = self.render.width, self.render.height, self.render.samples
        if width * height * samples * samples > MAX_PIXEL_RAYS:
            raise _KeyError(("render", "samples"), f"{width}×{height} pixels × {samples}² samples is more "
                            f"than {MAX_PIXEL_RAYS} rays per frame")
        problem = brightness_problem(self)
        if problem:
            raise _KeyError(*problem)
        return self

    def __eq__(self, other) -> bool:
        """Equal keys (the mesh sources read while loading are not compared)."""
        if not isinstance(other, Scene):
            return NotImplemented
        return self.__dict__ == other.__dict__

    __hash__ = None  # as before this __eq__: a Scene holds dicts (materials), so it was never hashable

    @property
    def mesh_sources(self) -> dict:
        """The MeshSources (io/mesh_source.py) made while this scene was loaded, by source_key; {} when none
        were (a scene file: prepare() makes them)."""
        return self._mesh_sources

    def material_of(self, obj: Object) -> Material:
        return self.materials.get(obj.material, DEFAULT_MATERIAL)

    def shading_of(self, obj: Object) -> ShadingModel:
        return obj.shading or self.render.shading

    def resolve(self, path: str) -> Path:
        """A path from the scene file, relative to the file's folder."""
        return Path(self.folder) / Path(path).expanduser()

    def named_files(self) -> dict[tuple, str]:
        """Every file the scene names, as written, by the key path that names it (a tuple, as error locations
        are: messages.dotted words it): ("objects", N, "path") for meshes, ("materials", M, "kd_map", "path")
        (and ka_map, ke_map) for textures, and OUTPUT_PATH. A caller that must not let its client choose files
        (the view's page) compares these before anything is opened."""
        named: dict[tuple, str] = {("objects", index, "path"): obj.path
                                   for index, obj in enumerate(self.objects) if obj.path}
        named.update({("materials", name, key, "path"): getattr(material, key).path
                      for name, material in self.materials.items() for key in MAP_COLUMNS
                      if getattr(material, key) is not None})
        named[OUTPUT_PATH] = self.output.path
        return named


def brightness_problem(scene: Scene, inverse_square: dict[int, float] | None = None, why: str = "") -> tuple | None:
    """(key path, message) if the lights could make a pixel channel exceed INTENSITY_LIMIT, else None.

    Every coefficient, cosine and S is at most 1, so a pixel channel is at most
    1 + I_a + Σ_k g_k (I_a,k + I_d,k + I_s,k), with g_k ≥ f_att of light k: 1 without attenuation,
    min(1, 1/c) for [c, l, q], and for a 1/d² light the bound `inverse_square[k]` that only the geometry
    can give (geometry.check_float_range; 0 until then). Supersampling only averages.
    """
    inverse_square = inverse_square or {}
    gains = []
    for k, light in enumerate(scene.lights):
        if light.type == "directional" or light.attenuation == "none":
            gains.append(1.0)
        elif light.attenuation == "inverse_square":
            gains.append(inverse_square.get(k, 0.0))
        else:
            gains.append(min(1.0, 1.0 / light.attenuation[0]) if light.attenuation[0] > 0 else 1.0)
    terms = [[g * (a + d + s) for a, d, s in zip(light.ambient, light.diffuse, light.specular)]
             for g, light in zip(gains, scene.lights)]
    total = max(1.0 + scene.ambient[c] + sum(term[c] for term in terms) for c in range(3))
    if not total <= INTENSITY_LIMIT and terms:  # without lights the total is at most 1 + 1e38
        k = max(range(len(terms)), key=lambda i: max(terms[i]))
        return (("lights", k), f"{why}a pixel channel could reach {total:.3g} = 1 + ambient + Σ f_att × "
                        f"(ambient + diffuse + specular) over the lights; allowed: at most {INTENSITY_LIMIT:g}, so "
                        "the image stays finite in float32; lower this light's intensities")
    return None


class _KeyError(RaycastPhongError):
    """Raised inside a validator when the error belongs to a key other than the one validated; validate_scene
    turns it into a SceneError, so it is never seen outside.

    Not a ValueError, so pydantic lets it through instead of blaming the whole table."""

    def __init__(self, loc: tuple, message: str):
        super().__init__(message)
        self.loc = loc
        self.message = message


# ---------------------------------------------------------------- many objects at once
#
# pydantic costs about 12 µs an object, 12 s for a million boxes. Objects with the same keys are checked here
# a key at a time instead: a structural check of the column (each value's type, with set(map(type, ...))),
# then numpy for the numbers, with the bounds of Object's fields. A row that passes is made into an Object
# with exactly the values pydantic would give it; a row that does not (or a key this does not know, a mesh,
# normals = "file", an array from Python) is left to pydantic, so every message stays pydantic's, naming the
# object's index and key. Scene._references then checks all objects in vectorised passes.

def _bounds(model: type[BaseModel], key: str) -> tuple[float, bool, float]:
    """(lowest, whether the lowest itself is allowed, highest) of a numeric field, read from its own
    Field(gt= or ge=, le=): the one statement of the bound, which bulk checking uses too."""
    low, allowed, high = -math.inf, True, math.inf
    for constraint in model.model_fields[key].metadata:
        if isinstance(constraint, annotated_types.Gt):
            low, allowed = constraint.gt, False
        elif isinstance(constraint, annotated_types.Ge):
            low, allowed = constraint.ge, True
        elif isinstance(constraint, annotated_types.Le):
            high = constraint.le
    return low, allowed, high


_SHAPE_ONLY_KEYS = frozenset().union(*SHAPE_KEYS.values())
_OBJECT_DEFAULTS = {key: field.default for key, field in Object.model_fields.items()}
_NUMBER = frozenset({int, float})                 # exact types: a bool or a str is pydantic's to refuse
_SEQUENCE = frozenset({list, tuple})
# The values bulk accepts for a choice: the field's own, but for a mesh and normals = "file" (pydantic's).
_CHOICES = {"shape": frozenset(SHAPES) - {"mesh"}, "normals": frozenset(get_args(NormalsRule)) - {"file"} | {None},
            "shading": {model.value: model for model in ShadingModel} | {None: None}}
_TEXT = {"name": frozenset({str, type(None)}), "material": frozenset({str})}
_WHOLE = {"subdivisions": _bounds(Object, "subdivisions")}
_LENGTHS = {key: _bounds(Object, key) for key in ("radius", "height", "major_radius", "minor_radius", "crease_angle")}
_VECTORS = ("translate", "rotate", "scale")
_BULK_ROWS = 1 << 16  # objects checked at once: the columns' temporaries stay a few MB however many there are
_BULK_KEYS = frozenset({"shape", "segments", "size", *_CHOICES, *_TEXT, *_WHOLE, *_LENGTHS, *_VECTORS})
# Every other key of Object is left to pydantic (an object with it is validated one at a time): a mesh's path.
LEFT_TO_PYDANTIC = frozenset({"path"})


def _first_misfit(scene: Scene) -> int | None:
    """The first object with a key its shape does not read (set to other than the default) or an undefined
    material; None if there is none. Decided once per kind (scene.kinds), in passes over the kinds' first
    objects: a kind's first object is the first of its objects to go wrong, and kinds are numbered in the
    order of their first objects."""
    kinds = object_kinds(scene)
    firsts, objects = kinds.first, kinds.firsts(scene.objects)
    count = len(objects)
    shapes = np.array(list(map(operator.attrgetter("shape"), objects)))
    wrong = np.zeros(count, bool)
    for key in sorted(_SHAPE_ONLY_KEYS):
        differs = np.fromiter(map(operator.ne, map(operator.attrgetter(key), objects),
                                  repeat(_OBJECT_DEFAULTS[key])), bool, count)
        wrong |= differs & ~np.isin(shapes, [shape for shape, keys in SHAPE_KEYS.items() if key in keys])
    names = list(map(operator.attrgetter("material"), objects))
    undefined = {name for name in set(names) if name != "default" and name not in scene.materials}
    if undefined:
        wrong |= np.fromiter(map(undefined.__contains__, names), bool, count)
    return int(firsts[np.argmax(wrong)]) if wrong.any() else None


def _typed(column: list, allowed: frozenset) -> np.ndarray:
    """Rows whose value's type is one of `allowed` (one pass in C when all are)."""
    if set(map(type, column)) <= allowed:
        return np.ones(len(column), bool)
    return np.fromiter((type(value) in allowed for value in column), bool, len(column))


def _numbers(rows: list, good: np.ndarray, filler) -> np.ndarray:
    """float64 of the good rows (numbers, or sequences of one length), `filler` in the others."""
    if not good.all():
        rows = [row if ok else filler for row, ok in zip(rows, good)]
    return np.array(rows, np.float64)  # OverflowError for an int beyond float64: the caller leaves it to pydantic


def _sequences(column: list, length: int, scalar: bool = False) -> tuple[list, np.ndarray, np.ndarray]:
    """(the values as pydantic gives them: tuples of floats, good, float64 (n, length)) for a key of `length`
    numbers; `scalar`: one number means all three (Vec3). Where every number is a float already, the tuples
    hold the file's own float objects, as pydantic's do (new ones from numpy: 200 MB more for 10⁶ objects)."""
    rows = [(value, value, value) if type(value) in _NUMBER else value for value in column] if scalar else column
    shaped = set(map(type, rows)) <= _SEQUENCE and set(map(len, rows)) == {length}
    kinds = set(map(type, chain.from_iterable(rows))) if shaped else set()
    floats = shaped and kinds == {float}
    if shaped and kinds <= _NUMBER:
        good = np.ones(len(rows), bool)
    else:
        good = np.fromiter((type(row) in _SEQUENCE and len(row) == length and all(type(v) in _NUMBER for v in row)
                            for row in rows), bool, len(rows))
    values = _numbers(rows, good, (1.0,) * length).reshape(len(rows), length)
    return list(map(tuple, rows if floats else values.tolist())), good, values


def _check_column(key: str, column: list, shapes: list) -> tuple[np.ndarray, list]:
    """(rows pydantic would accept with the same value, the values it would give them) for one key."""
    count = len(column)
    if key in _CHOICES:
        choices = _CHOICES[key]
        good = _typed(column, frozenset({str, type(None)}))
        good &= np.fromiter((value in choices if ok else False for value, ok in zip(column, good)), bool, count)
        if key == "shading":  # pydantic gives the enum member
            column = [choices[value] if ok else value for value, ok in zip(column, good.tolist())]
        return good, column
    if key in _TEXT:
        return _typed(column, _TEXT[key]), column
    if key in _WHOLE:
        low, allowed, high = _WHOLE[key]
        return np.fromiter((type(v) is int and (low <= v if allowed else low < v) and v <= high for v in column),
                           bool, count), column
    if key in _LENGTHS:
        low, allowed, high = _LENGTHS[key]
        good = _typed(column, _NUMBER)
        values = _numbers(column, good, 1.0)
        good &= ((values >= low) if allowed else (values > low)) & (values <= high)
        return good, column if set(map(type, column)) == {float} else values.tolist()
    if key == "segments":
        good = np.fromiter((value is None or (type(value) in _SEQUENCE and len(value) == 2 and all(
            type(v) is int and SEGMENTS[0] <= v <= SEGMENTS[1] for v in value)) for value in column), bool, count)
        return good, [tuple(value) if ok and value is not None else value for value, ok in zip(column, good.tolist())]
    if key == "size":  # a box's three lengths or a plane's two; None or any other shape: pydantic's
        good, sizes = np.zeros(count, bool), list(column)
        for shape, length in SIZE_LENGTHS.items():
            rows = [index for index, name in enumerate(shapes) if name == shape]
            if rows:
                made, passed, values = _sequences([column[index] for index in rows], length)
                good[rows] = passed & np.all((values > 0) & (values <= POSITION_LIMIT), axis=1)
                for index, value in zip(rows, made):
                    sizes[index] = value
        return good, sizes
    made, good, values = _sequences(column, 3, scalar=True)  # translate, rotate, scale
    finite = np.all(np.isfinite(values), axis=1)
    if key == "translate":
        good &= np.all(np.abs(values) <= POSITION_LIMIT, axis=1)
    elif key == "rotate":
        good &= finite
    else:
        good &= finite & np.all(values != 0, axis=1) & np.all(np.abs(values) <= POSITION_LIMIT, axis=1)
    return good, made


def _build_group(keys: tuple, rows: list) -> list:
    """An Object for each row pydantic would accept (with pydantic's values), None for the others."""
    columns = {key: list(map(operator.itemgetter(key), rows)) for key in keys}
    shapes = columns["shape"]
    good = np.ones(len(rows), bool)
    values = []
    for key in keys:
        try:
            passed, column = _check_column(key, columns[key], shapes)
        except (OverflowError, ValueError, TypeError):  # an int beyond float64, a ragged list: pydantic's
            return [None] * len(rows)
        good &= passed
        values.append(column)
    made, fields, defaults, new, attribute = [None] * len(rows), set(keys), _OBJECT_DEFAULTS, Object.__new__, \
        object.__setattr__
    chosen = np.flatnonzero(good).tolist()
    columns = values if len(chosen) == len(rows) else [[column[i] for i in chosen] for column in values]
    for index, row in zip(chosen, zip(*columns)):
        values_of = dict(defaults)  # in the fields' order, as pydantic keeps them
        values_of.update(zip(keys, row))
        obj = made[index] = new(Object)
        attribute(obj, "__dict__", values_of)
        attribute(obj, "__pydantic_fields_set__", fields.copy())
        attribute(obj, "__pydantic_extra__", None)
        attribute(obj, "__pydantic_private__", None)
    return made


def objects_in_bulk(objects: Any) -> Any:
    """`objects` with each object that pydantic would accept already an Object (see above); the others, and
    anything that is not a list of tables, as they were, for pydantic to validate and word."""
    if type(objects) not in _SEQUENCE:
        return objects
    groups: dict[tuple, list[int]] = {}
    for index, obj in enumerate(objects):
        if type(obj) is dict:
            groups.setdefault(tuple(obj), []).append(index)
    result = list(objects)
    collecting = gc.isenabled()
    gc.disable()  # a million new objects would start as many collections of a growing heap
    try:
        for keys, members in groups.items():
            if "shape" not in keys or not _BULK_KEYS.issuperset(keys):
                continue
            for start in range(0, len(members), _BULK_ROWS):
                chunk = members[start:start + _BULK_ROWS]
                for index, obj in zip(chunk, _build_group(keys, [objects[i] for i in chunk])):
                    if obj is not None:
                        result[index] = obj
    finally:
        if collecting:
            gc.enable()
    return result


def validate_scene(data: dict, source: str = "<scene>", folder: str | Path = ".") -> Scene:
    """Validate a parsed scene dictionary; errors name `source` and the key path."""
    data = dict(data)
    if "folder" in data:
        raise SceneError(f"{source}: folder: unknown key")
    try:
        objects = {"objects": objects_in_bulk(data["objects"])} if "objects" in data else {}
        return Scene.model_validate({**data, **objects, "folder": str(folder)})
    except ValidationError as error:
        raise SceneError(describe_error(error, data, source, Scene)) from None
    except _KeyError as error:
        raise SceneError(f"{source}: {dotted(error.loc)}: {error.message}") from None


def default_scene_path() -> Path:
    """The built-in default scene: the lecture's figure, one sphere in flat, Gouraud and Phong shading."""
    return Path(__file__).parents[1] / "data" / "default.toml"  # raycast_phong/data


def scene_json_schema() -> dict:
    """The JSON Schema of the scene format, published as docs/scene.schema.json."""
    schema = Scene.model_json_schema(mode="validation")
    schema["properties"].pop("folder", None)
    schema["title"] = "raycast-phong scene, format version 1"
    return schema
