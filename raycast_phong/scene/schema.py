"""Read a scene file (TOML, or JSON with the same structure) into a validated, frozen Scene.

The scene format is version 1; docs/scene-format.md lists every key with its default and allowed range.
Every problem becomes one SceneError naming the file, the key path and what is allowed, so the CLI can
print one line and exit 2.
"""

from __future__ import annotations

import difflib
import json
import math
import os
import stat
import tomllib
from enum import Enum
from pathlib import Path
from typing import Annotated, Any, BinaryIO, Literal, get_args, get_origin

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
    ValidationError,
    field_validator,
    model_validator,
)

MAX_SIZE = 16384          # pixels per side, from the format
MAX_SAMPLES = 16          # 16×16 = 256 rays per pixel is already a reference-quality render
MAX_PIXEL_RAYS = 2**31 - 1  # embree indexes rays with int32 per call; beyond this a frame is absurd anyway

# The float range a render stays inside (docs/scene-format.md, "Number ranges"). Shading runs in float32 by
# default (largest finite 3.4e38, smallest normal 1.2e-38) and Embree always does, so each bound keeps the
# numbers derived from a valid scene finite there, and their squares finite in float64.
POSITION_LIMIT = 1e18   # |coordinate| of a point, and the largest length: squared distances across the
                        # scene, (2√3 · 1e18)² ≈ 1.2e37, stay below float32's 3.4e38
MIN_EXTENT = 1e-12      # the scene's half-extent: the 1/d² floor, 1e-6 of it, squared is a normal float32,
                        # and the camera in Embree's unit frame stays within 3.5e18 / 1e-12 ≈ 3.5e30
DIRECTION_RANGE = (1e-150, 1e150)  # length of a direction: its square is a normal, finite float64, so
                                   # normalising it by sqrt(v·v) neither underflows to 0/0 nor overflows
INTENSITY_LIMIT = 1e38  # a bound on any channel of a pixel: below float32's 3.4e38 with room for the rounding
                        # of the kernel's sums


class SceneError(ValueError):
    """A scene the renderer refuses: the message is one line naming file, key and what is allowed."""


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


# ---------------------------------------------------------------- value types

def _shown(value: Any) -> str:
    """A value as the scene file spells it: the string '32', true, [1, 2]."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f"the string {value!r}"
    if isinstance(value, dict):
        return "a table"
    return repr(list(value)) if isinstance(value, (tuple, list)) else repr(value)


def _number(value: Any) -> Any:
    """TOML and JSON tell text and booleans from numbers, so "32" or true where a number belongs is a
    mistake in the file; pydantic's lax mode would quietly convert them."""
    if isinstance(value, (str, bool, dict, list, tuple)) or value is None:
        raise ValueError(f"must be a number, got {_shown(value)}")
    return value


def _whole(value: Any) -> Any:
    """As _number, for counts: width, height, samples, subdivisions, segments."""
    if isinstance(value, (str, bool, dict, list, tuple)) or value is None:
        raise ValueError(f"must be a whole number, got {_shown(value)}")
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
        raise ValueError(f"must be three numbers [a, b, c] (or one number for all three), got {count}{_shown(value)}")
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
    precision: Literal["float32", "float64"] = "float32"
    two_sided: Annotated[bool, Strict()] = True  # true or false, not "yes" or 1
    interpolation: Literal["perspective", "screen"] = "perspective"

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
        raise ValueError(f"allowed: {ATTENUATION_ALLOWED}; got {_shown(value)}")
    if len(sequence) != 3:
        raise ValueError(f"the attenuation list is [c, l, q], got {len(sequence)} numbers: {list(sequence)}")
    c, l, q = (float(_number(x)) for x in sequence)  # noqa: E741
    # min(1, 1/(c + l·d + q·d²)) is defined for every d ≥ 0 when no coefficient is negative: where the sum
    # is 0 (c = 0 at d = 0) the clamp gives 1. All zero would be "none" in disguise. The kernel's tables
    # are float32, so each coefficient must be finite there.
    if not all(0 <= x <= INTENSITY_LIMIT for x in (c, l, q)) or c == l == q == 0:
        raise ValueError(f"got [c, l, q] = {list(sequence)}; allowed: {ATTENUATION_ALLOWED}")
    return (c, l, q)


class Light(_Strict):
    type: Literal["point", "directional"] = "point"
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


class Material(_Strict):
    ka: Coefficient = (0.2, 0.2, 0.2)
    kd: Coefficient = (0.8, 0.8, 0.8)
    ks: Coefficient = (0.5, 0.5, 0.5)
    ke: Coefficient = (0.0, 0.0, 0.0)
    shininess: Number = 32.0

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


SHAPES = ("icosphere", "uv_sphere", "box", "plane", "cylinder", "torus", "mesh")
# The keys only some shapes read; every other key of [[objects]] applies to all of them.
SHAPE_KEYS = {"icosphere": ("radius", "subdivisions"), "uv_sphere": ("radius", "segments"), "box": ("size",),
              "plane": ("size", "segments"), "cylinder": ("radius", "height", "segments"),
              "torus": ("major_radius", "minor_radius", "segments"), "mesh": ("path",)}


def _pair(value: Any) -> Any:
    sequence = _sequence(value)
    if sequence is None or len(sequence) != 2:
        raise ValueError(f"must be two whole numbers [a, b] in [3, 4096], got {_shown(value)}")
    return sequence


NormalsRule = Literal["mean", "area", "angle", "file", "exact"]  # how an object's vertex normals are made


class Object(_Strict):
    name: str | None = None
    shape: Literal["icosphere", "uv_sphere", "box", "plane", "cylinder", "torus", "mesh"]
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
        if value is not None and not all(3 <= s <= 4096 for s in value):
            raise ValueError(f"segments must be two whole numbers in [3, 4096], got {list(value)}")
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
        if self.size is not None and self.shape == "box" and len(self.size) != 3:
            raise ValueError("a box's size is [x, y, z]")
        if self.size is not None and self.shape == "plane" and len(self.size) != 2:
            raise ValueError("a plane's size is [width, depth]")
        return self


AOVS = ("depth", "normal", "face", "ambient", "diffuse", "specular", "emission")


class Output(_Strict):
    path: str = "out.png"
    aovs: tuple[Literal["depth", "normal", "face", "ambient", "diffuse", "specular", "emission"], ...] = ()

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
        if suffix not in (".png", ".exr"):
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

    _check_ambient = field_validator("ambient")(lambda v: _non_negative(v))

    @model_validator(mode="after")
    def _references(self) -> Scene:
        if not self.objects:
            raise _KeyError(("objects",), 'the scene has no [[objects]]; add at least one, e.g. '
                            '[[objects]] shape = "icosphere"')
        for index, obj in enumerate(self.objects):
            # Like an unknown key, a key the shape does not read is a mistake the file should hear about. Only a
            # value other than the default counts, so a scene written back with every key (model_dump) still reads.
            foreign = sorted(key for key in set().union(*SHAPE_KEYS.values()) - set(SHAPE_KEYS[obj.shape])
                             if getattr(obj, key) != Object.model_fields[key].default)
            if foreign:
                raise _KeyError(("objects", index, foreign[0]), f'does not apply to shape = "{obj.shape}"; '
                                f'a {obj.shape} reads {", ".join(SHAPE_KEYS[obj.shape])} besides the keys of '
                                "every object; remove it")
            if obj.material != "default" and obj.material not in self.materials:
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

    def material_of(self, obj: Object) -> Material:
        return self.materials.get(obj.material, DEFAULT_MATERIAL)

    def shading_of(self, obj: Object) -> ShadingModel:
        return obj.shading or self.render.shading

    def resolve(self, path: str) -> Path:
        """A path from the scene file, relative to the file's folder."""
        return Path(self.folder) / Path(path).expanduser()


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


class _KeyError(Exception):
    """Raised inside a validator when the error belongs to a key other than the one validated.

    Not a ValueError, so pydantic lets it through instead of blaming the whole table."""

    def __init__(self, loc: tuple, message: str):
        super().__init__(message)
        self.loc = loc
        self.message = message


# ---------------------------------------------------------------- reading

MAX_SCENE_BYTES = 16 << 20  # 16 MiB: a scene is keys and numbers; 40,000 objects take about 3.5 MiB of TOML

FILE_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISCHR, "a device"),
              (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def open_regular(path: Path, where: str, what: str, limit: int | None = None) -> BinaryIO:
    """Open `path` for binary reading if it is a regular file of at most `limit` bytes; else SceneError
    "{where}: ..." naming `what` (a scene file, a mesh file). A missing file raises FileNotFoundError,
    for the caller to word.

    A FIFO would block the read forever and /dev/zero never ends, so the kind is checked with stat before
    opening (opening some devices acts on them), and again with fstat after an O_NONBLOCK open, in case
    the path was swapped in between (a FIFO opens at once without blocking then).
    """
    def refuse_kind(mode: int) -> None:
        if not stat.S_ISREG(mode):
            kind = next((f"{name}, not a regular file" for test, name in FILE_KINDS if test(mode)),
                        "not a regular file")
            raise SceneError(f"{where}: {str(path)!r} is {kind}; give a {what}")

    try:
        refuse_kind(os.stat(path).st_mode)
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except NotADirectoryError:
        raise FileNotFoundError(path) from None
    except FileNotFoundError:
        raise
    except OSError as error:
        raise SceneError(f"{where}: cannot read the {what} {str(path)!r} ({error.strerror})") from None
    try:
        info = os.fstat(descriptor)
        refuse_kind(info.st_mode)
        if limit is not None and info.st_size > limit:
            raise SceneError(f"{where}: the {what} is {info.st_size:,} bytes, more than the {limit:,} "
                             f"({limit >> 20} MiB) allowed")
        os.set_blocking(descriptor, True)
        return os.fdopen(descriptor, "rb")
    except BaseException:
        os.close(descriptor)
        raise


def read_scene_dict(path: Path) -> dict:
    """Parse the file's syntax only (TOML, or JSON for .json), with a one-line error on failure.

    Only a regular file of at most MAX_SCENE_BYTES is read (open_regular)."""
    try:
        with open_regular(path, str(path), "scene file", MAX_SCENE_BYTES) as handle:
            # One byte over the cap tells a file that grew after fstat from one that fits.
            data = handle.read(MAX_SCENE_BYTES + 1)
        if len(data) > MAX_SCENE_BYTES:
            raise SceneError(f"{path}: the scene file grew past the {MAX_SCENE_BYTES >> 20} MiB allowed while read")
        text = data.decode("utf-8")
    except FileNotFoundError:
        raise SceneError(f"{path}: no such scene file") from None
    except (OSError, UnicodeDecodeError) as error:
        raise SceneError(f"{path}: cannot read the scene file ({error})") from None
    text = text.removeprefix("\ufeff")  # a byte-order mark, as some Windows editors write, is no syntax error
    try:
        if path.suffix.lower() == ".json":
            data = json.loads(text, object_pairs_hook=_JSONObject)
            twice = _duplicate_key(data)
            if twice:
                raise SceneError(f"{path}: {_dotted(twice)}: the key is given twice in one object (JSON would keep "
                                 "the last silently); allowed: each key once")
        else:
            data = tomllib.loads(text)
    except json.JSONDecodeError as error:
        where = f"line {error.lineno}, column {error.colno}"
        raise SceneError(f"{path}: JSON syntax error at {where}: {error.msg}") from None
    except tomllib.TOMLDecodeError as error:
        raise SceneError(f"{path}: TOML syntax error: {error}") from None
    if not isinstance(data, dict):
        raise SceneError(f"{path}: the top level must be a table of keys")
    return data


class _JSONObject(dict):
    """A JSON object (json's object_pairs_hook) that remembers the keys it was given more than once."""

    def __init__(self, pairs: list[tuple[str, Any]]):
        super().__init__(pairs)
        self.repeated = []
        if len(self) < len(pairs):
            seen: set[str] = set()
            self.repeated = [key for key, _ in pairs if key in seen or seen.add(key)]


def _duplicate_key(data: Any) -> tuple | None:
    """The key path of the first key given twice in a JSON object, or None (a walk with a stack, not
    recursion, so a nesting as deep as json accepts cannot overflow Python's stack here)."""
    stack = [((), data)]
    while stack:
        loc, node = stack.pop()
        if isinstance(node, _JSONObject) and node.repeated:
            return (*loc, node.repeated[0])
        children = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
        stack.extend(reversed([((*loc, key), child) for key, child in children]))
    return None


def load_scene(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> Scene:
    """Read, override (`key.path=value`, as `--set`), and validate a scene file."""
    path = Path(path)
    data = read_scene_dict(path)
    for assignment in overrides:
        apply_override(data, assignment, source=str(path))
    return validate_scene(data, source=str(path), folder=path.parent)


def validate_scene(data: dict, source: str = "<scene>", folder: str | Path = ".") -> Scene:
    """Validate a parsed scene dictionary; errors name `source` and the key path."""
    data = dict(data)
    if "folder" in data:
        raise SceneError(f"{source}: folder: unknown key")
    try:
        return Scene.model_validate({**data, "folder": str(folder)})
    except ValidationError as error:
        raise SceneError(describe_error(error, data, source)) from None
    except _KeyError as error:
        raise SceneError(f"{source}: {_dotted(error.loc)}: {error.message}") from None


def _dotted(loc: tuple) -> str:
    return ".".join(str(part) for part in loc)


def _model_at(loc: tuple) -> type[BaseModel] | None:
    """The pydantic model that holds the key at `loc` (for suggesting a close valid key)."""
    nested = {"render": Render, "camera": Camera, "lights": Light, "objects": Object, "output": Output}
    model: Any = Scene
    for part in (p for p in loc if not isinstance(p, int)):
        if model is Scene and part == "materials":
            model = "materials"
        elif model == "materials":
            model = Material
        elif model is Scene and part in nested:
            model = nested[part]
        else:
            return None
    return model if isinstance(model, type) else None


def describe_error(error: ValidationError, data: dict, source: str) -> str:
    """One line for the first problem pydantic found: file, key path, what is wrong, what is allowed."""
    first = error.errors()[0]
    loc = tuple(part for part in first["loc"] if not (isinstance(part, str) and "[" in part))
    # pydantic names union branches and validator functions in loc; keep only real keys.
    loc = tuple(p for p in loc if isinstance(p, int) or not p.startswith(("function-", "tuple[", "literal[")))
    key = _dotted(loc) or "(top level)"
    kind = first["type"]
    if kind == "extra_forbidden":
        owner = _model_at(loc[:-1])
        valid = [name for name in (owner.model_fields if owner else {}) if name != "folder"]
        close = difflib.get_close_matches(str(loc[-1]), valid, n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        return f"{source}: {key}: unknown key{hint}; valid keys here: {', '.join(valid)}"
    message = first["msg"]
    if message.startswith("Value error, "):
        message = message[len("Value error, "):]
    # Say pydantic's type errors in the scene file's words (table, list, true/false).
    if kind in ("greater_than_equal", "less_than_equal", "greater_than", "less_than"):
        message = f"out of range; allowed: {_allowed_range(loc)}"
    elif message.startswith(("must be a number", "must be a whole number")) and _bounded(loc):
        message = f"{message}; allowed: {_allowed_range(loc)}"
    elif kind == "int_from_float":
        message = "must be a whole number" + (f"; allowed: {_allowed_range(loc)}" if _bounded(loc) else "")
    elif kind == "missing":
        choices = _choices(loc)
        message = "this key is required" + (f"; allowed: {', '.join(map(repr, choices))}" if choices else "")
    elif kind in ("model_type", "dict_type"):
        message = "must be a table of keys"
    elif kind in ("tuple_type", "list_type"):
        message = (f"must be an array of tables, [[{loc[-1]}]]" if loc and loc[-1] in ("lights", "objects")
                   else "must be a list")
    elif kind == "bool_type":
        message = "must be true or false"
    value = first.get("input")
    shown = "" if kind == "missing" or isinstance(value, dict) or "got " in message else f" (got {_shown(value)})"
    return f"{source}: {key}: {message}{shown}"


def _bounded(loc: tuple) -> bool:
    return _allowed_range(loc) != str(loc[-1])


def _choices(loc: tuple) -> tuple:
    """The values a Literal key allows ('icosphere', 'box', ...), or () for other keys."""
    owner = _model_at(loc[:-1]) if loc else None
    field = owner.model_fields.get(str(loc[-1])) if owner else None
    if field is None or get_origin(field.annotation) is not Literal:
        return ()
    return get_args(field.annotation)


def _allowed_range(loc: tuple) -> str:
    """'1 ≤ width ≤ 16384' from the field's constraints ('width' alone if it has none)."""
    if not loc:
        return ""
    owner = _model_at(loc[:-1])
    field = owner.model_fields.get(str(loc[-1])) if owner else None
    low = high = None
    for item in (field.metadata if field else ()):
        for name, symbol in (("ge", "≤"), ("gt", "<")):
            if getattr(item, name, None) is not None:
                low = f"{getattr(item, name)} {symbol} "
        for name, symbol in (("le", "≤"), ("lt", "<")):
            if getattr(item, name, None) is not None:
                high = f" {symbol} {getattr(item, name)}"
    return f"{low or ''}{loc[-1]}{high or ''}"


def apply_override(data: dict, assignment: str, source: str = "--set", option: str = "--set") -> None:
    """Set `key.path=value` in a parsed scene; the value is read as TOML, else as a plain string.

    List items are addressed by index: `lights.0.position=[1, 2, 3]`, `objects.1.shading=flat`.
    `option` names the command-line option the assignment came from in error messages (--set, --vary).
    """
    where = f"{source}: {option} {assignment!r}"
    if "=" not in assignment:
        raise SceneError(f"{where}: expected KEY.PATH=VALUE, e.g. render.width=320 or lights.0.position=[1, 2, 3]")
    key, text = (part.strip() for part in assignment.split("=", 1))
    parts = key.split(".")
    if not all(parts):
        raise SceneError(f"{where}: {key!r} is not a key path; expected names and list indices joined by dots, "
                         "e.g. render.width")
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        value = text
    node: Any = data
    for depth, part in enumerate(parts):
        node_path = ".".join(parts[:depth]) or "(top level)"
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                allowed = f"0 to {len(node) - 1}" if node else "none, the list is empty"
                raise SceneError(f"{where}: {_dotted(parts[:depth + 1])}: {node_path} is a list of {len(node)} "
                                 f"item{'s' if len(node) != 1 else ''}; allowed indices: {allowed}")
            index: Any = int(part)
        elif isinstance(node, dict):
            index = part
        else:
            raise SceneError(f"{where}: {node_path} is the value {_shown(node)}, not a table, so it has no key "
                             f"{part!r}")
        if depth == len(parts) - 1:
            node[index] = value
        elif isinstance(node, dict) and part not in node:
            node = node.setdefault(part, [] if parts[depth + 1].isdigit() else {})
        else:
            node = node[index]


def default_scene_path() -> Path:
    """The built-in default scene: the lecture's figure, one sphere in flat, Gouraud and Phong shading."""
    return Path(__file__).parents[1] / "data" / "default.toml"  # raycast_phong/data


def scene_json_schema() -> dict:
    """The JSON Schema of the scene format, published as docs/scene.schema.json."""
    schema = Scene.model_json_schema(mode="validation")
    schema["properties"].pop("folder", None)
    schema["title"] = "raycast-phong scene, format version 1"
    return schema
