"""The scene format as pydantic models, with its limits: a parsed scene table into a validated, frozen Scene.

The scene format is version 1; docs/scene-format.md lists every key with its default and allowed range.
Every problem becomes one SceneError naming the file, the key path and what is allowed (worded by
scene.messages), so the CLI can print one line and exit 2. An object's keys are its kind's (scene.objects, from
the registry of kinds), many objects are checked in bulk first (scene.bulk). Reading files is scene.load's
(through io.scene_file), `--set` is scene.overrides'.
"""

from __future__ import annotations

import difflib
import math
import operator
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BeforeValidator, Field, PrivateAttr, Strict, ValidationError, field_validator, model_validator

from ..codes import (
    IMAGE_SUFFIXES,
    LAYERS,
    MAP_COLUMNS,
    MATERIAL_DEFAULTS,
    OUTPUT_PATH,
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
from .bulk import objects_in_bulk
from .fields import (
    Coefficient,
    Number,
    Table,
    Vec3,
    Whole,
    check_number,
    direction,
    non_negative,
    position,
    sequence_of,
    unit_range,
)
from .kinds import object_kinds
from .messages import Location, describe_error, located, shown
from .objects import MESH, Object, without_written_defaults

MAX_SIZE = 16384          # pixels per side, from the format
MAX_SAMPLES = 16          # 16×16 = 256 rays per pixel is already a reference-quality render
MAX_PIXEL_RAYS = 2**31 - 1  # embree indexes rays with int32 per call; beyond this a frame is absurd anyway

# ---------------------------------------------------------------- tables

class Render(Table):
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

    _check_background = field_validator("background")(lambda v: non_negative(v))


class Camera(Table):
    type: Literal["perspective", "orthographic"] = "perspective"
    position: Vec3 = (0.0, 0.0, 4.0)
    look_at: Vec3 = (0.0, 0.0, 0.0)
    up: Vec3 = (0.0, 1.0, 0.0)
    fov: Number = Field(40.0, gt=0.0, lt=180.0)
    view_height: Number = Field(2.0, gt=0.0, le=POSITION_LIMIT, allow_inf_nan=False)

    _check_position = field_validator("position", "look_at")(lambda v: position(v))
    _check_up = field_validator("up")(lambda v: direction(v))

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
    sequence = sequence_of(value)
    if sequence is None:
        raise ValueError(f"allowed: {ATTENUATION_ALLOWED}; got {shown(value)}")
    if len(sequence) != 3:
        raise ValueError(f"the attenuation list is [c, l, q], got {len(sequence)} numbers: {shown(sequence)}")
    c, l, q = (float(check_number(x)) for x in sequence)  # noqa: E741
    # min(1, 1/(c + l·d + q·d²)) is defined for every d ≥ 0 when no coefficient is negative: where the sum
    # is 0 (c = 0 at d = 0) the clamp gives 1. All zero would be "none" in disguise. The kernel's tables
    # are float32, so each coefficient must be finite there.
    if not all(0 <= x <= INTENSITY_LIMIT for x in (c, l, q)) or c == l == q == 0:
        raise ValueError(f"got [c, l, q] = {list(sequence)}; allowed: {ATTENUATION_ALLOWED}")
    return (c, l, q)


class Light(Table):
    type: Literal[tuple(kind.value for kind in LightKind)] = "point"  # type: ignore[valid-type]
    position: Vec3 | None = None
    direction: Vec3 | None = None
    diffuse: Vec3 = (0.8, 0.8, 0.8)
    specular: Vec3 = (1.0, 1.0, 1.0)
    ambient: Vec3 = (0.0, 0.0, 0.0)
    attenuation: Annotated[Literal["none", "inverse_square"] | tuple[float, float, float],
                           BeforeValidator(_attenuation)] = "none"

    _check_position = field_validator("position")(lambda v: v if v is None else position(v))
    _check_direction = field_validator("direction")(lambda v: v if v is None else direction(v))
    _check_intensity = field_validator("diffuse", "specular", "ambient")(lambda v: non_negative(v))

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


class TextureMap(Table):
    """A colour map: an image file relative to the scene file, and how it repeats outside [0, 1]."""
    path: str
    wrap: Literal[WRAP_MODES] = "repeat"  # type: ignore[valid-type]


def _map(value: Any) -> Any:
    """kd_map = "wood.png" is the short form of { path = "wood.png" }; a number or a list is neither (a file
    named '5' was once looked for)."""
    if isinstance(value, str):
        return {"path": value}
    if value is not None and not isinstance(value, dict):
        raise ValueError('must be an image file name or a table { path = "...", wrap = "clamp" }')
    return value


MapKey = Annotated[TextureMap, BeforeValidator(_map)] | None


class Material(Table):
    ka: Coefficient = MATERIAL_DEFAULTS["ka"]
    kd: Coefficient = MATERIAL_DEFAULTS["kd"]
    ks: Coefficient = MATERIAL_DEFAULTS["ks"]
    ke: Coefficient = MATERIAL_DEFAULTS["ke"]
    shininess: Number = MATERIAL_DEFAULTS["shininess"]
    ka_map: MapKey = None  # multiplies k_a (the kd_map does when this is not given)
    kd_map: MapKey = None  # multiplies k_d and k_a at the hit's texture coordinates
    ke_map: MapKey = None  # multiplies k_e

    _check_coefficients = field_validator("ka", "kd", "ks", "ke")(lambda v: unit_range(v))

    @field_validator("shininess")
    @classmethod
    def _shininess(cls, value: float) -> float:
        # The material table is in the shading precision: a finite f must also be finite in float32. Beyond
        # 1e38, x^f is 0 for every x < 1 anyway, which is what inf (the mirror limit) says.
        if math.isnan(value) or value < 0 or INTENSITY_LIMIT < value < math.inf:
            raise ValueError(f"shininess must be ≥ 0 (inf allowed: the mirror limit) and, if finite, at most "
                             f"{INTENSITY_LIMIT:g}, got {value}")
        return value


class Output(Table):
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

    def check_inside(self, source: str | Location) -> None:
        """Refuse a path that leaves the scene's folder (absolute, ~ or '..'), before it is written to.

        A scene file is data, possibly someone else's: it may write beside itself or below, never over
        ~/.x.png or ../../x.png. An output elsewhere is the user's choice, made with -o (which the scene's
        path then does not matter to, so this is checked where the path is used, not while loading).
        """
        path = Path(self.path)
        if path.is_absolute() or self.path.startswith("~") or ".." in path.parts:
            raise SceneError(f"{self.path!r} leaves the scene's folder (an absolute path, ~ or '..'); give a path "
                             "inside that folder, or choose the output with -o", located(source).at("output", "path"))


DEFAULT_MATERIAL = Material()


class Scene(Table):
    """A validated scene: every key of the format with its value or default."""
    render: Render = Render()
    camera: Camera = Camera()
    ambient: Vec3 = (0.1, 0.1, 0.1)
    lights: tuple[Light, ...] = ()
    materials: dict[str, Material] = {}  # noqa: RUF012 - pydantic copies a default, not shares it
    objects: Annotated[tuple[Object, ...], BeforeValidator(without_written_defaults)] = ()
    output: Output = Output()
    folder: str = Field(".", exclude=True)  # the scene file's folder: relative paths start here
    # The mesh files' io.mesh_source.MeshSource made while loading (framing a mesh file), by source_key: handed
    # with the scene to prepare(), which reads no file twice. What was read, not part of the scene's value.
    _mesh_sources: dict = PrivateAttr(default_factory=dict)

    _check_ambient = field_validator("ambient")(lambda v: non_negative(v))

    @model_validator(mode="after")
    def _references(self) -> Scene:
        if not self.objects:
            raise _KeyError(("objects",), 'the scene has no [[objects]]; add at least one, e.g. '
                            '[[objects]] shape = "icosphere"')
        index = _undefined_material(self)
        if index is not None:
            name = self.objects[index].material
            close = difflib.get_close_matches(name, list(self.materials), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            defined = ", ".join(sorted(self.materials)) or "none"
            raise _KeyError(("objects", index, "material"),
                            f"material {name!r} is not defined{hint}; defined: {defined}")
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

    def replace(self, changes: Mapping[str, Any], /) -> Scene:
        """A new scene with `changes` applied, validated as a scene file is, in this scene's folder (its meshes
        and maps still resolve). Keys are the paths `--set` takes, values are Python values:

            scene.replace({"render.width": 320, "lights.0.position": [1, 2, 3], "materials.red.kd": [1, 0, 0]})

        Raises SceneError (one line naming the key path and what is allowed) for a change the format refuses.
        A Scene is frozen; `model_copy(update=...)` would skip validation."""
        from .keypaths import assign
        where = located("Scene.replace")
        data = self.model_dump(mode="json", exclude={"folder"}, exclude_none=True)
        for key, value in changes.items():
            if not isinstance(key, str):
                raise SceneError(f"{shown(key)} is not a key path; expected a string such as 'render.width'", where)
            assign(data, key, value, where)
        return validate_scene(data, source=str(where), folder=self.folder)

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
                                   for index, obj in enumerate(self.objects) if obj.shape == MESH}
        named.update({("materials", name, key, "path"): getattr(material, key).path
                      for name, material in self.materials.items() for key in MAP_COLUMNS
                      if getattr(material, key) is not None})
        named[OUTPUT_PATH] = self.output.path
        return named


def _undefined_material(scene: Scene) -> int | None:
    """The first object whose material is neither "default" nor defined; None if there is none. Decided once per
    kind of object (scene.kinds): a kind's first object is the first of its objects to go wrong."""
    kinds = object_kinds(scene)
    names = list(map(operator.attrgetter("material"), kinds.firsts(scene.objects)))
    undefined = {name for name in set(names) if name != "default" and name not in scene.materials}
    if not undefined:
        return None
    return int(kinds.first[next(k for k, name in enumerate(names) if name in undefined)])


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


def validate_scene(data: dict, source: str | Location = "<scene>", folder: str | Path = ".") -> Scene:
    """Validate a parsed scene dictionary; errors name `source` (the file) and the key path."""
    where = located(source)
    data = dict(data)
    if "folder" in data:
        raise SceneError("unknown key", where.at("folder"))
    try:
        objects = {"objects": objects_in_bulk(data["objects"])} if "objects" in data else {}
        return Scene.model_validate({**data, **objects, "folder": str(folder)})
    except ValidationError as error:
        at, problem = describe_error(error, where, Scene)
        raise SceneError(problem, at) from None
    except _KeyError as error:
        raise SceneError(error.message, where.at(*error.loc)) from None


def default_scene_path() -> Path:
    """The built-in default scene: the lecture's figure, one sphere in flat, Gouraud and Phong shading."""
    return Path(__file__).parents[1] / "data" / "default.toml"  # raycast_phong/data


def scene_json_schema() -> dict:
    """The JSON Schema of the scene format, published as docs/scene.schema.json."""
    schema = Scene.model_json_schema(mode="validation")
    schema["properties"].pop("folder", None)
    schema["title"] = "raycast-phong scene, format version 1"
    return schema
