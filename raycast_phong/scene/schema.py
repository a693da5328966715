"""The scene format as pydantic models, with its limits: a parsed scene table into a validated, frozen Scene.

The scene format is version 1; docs/scene-format.md lists every key with its default and allowed range.
Every problem becomes one SceneError naming the file, the key path and what is allowed (worded by
values.messages), so the CLI can print one line and exit 2. An object's keys are its kind's (scene.objects, from
the registry of kinds), many objects are checked in bulk first (scene.bulk). Reading files is scene.load's
(through io.scene_file), `--set` is scene.overrides'.
"""

from __future__ import annotations

import math
import operator
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    Strict,
    ValidationError,
    WithJsonSchema,
    field_validator,
    model_validator,
)

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
from ..shapes import from_file
from ..tolerances import DIRECTION_RANGE, INTENSITY_LIMIT, POSITION_LIMIT
from ..values.fields import (
    Coefficient,
    Direction,
    Intensity,
    Number,
    Position,
    Table,
    Whole,
    check_number,
    number_schema,
    sequence_of,
)
from ..values.messages import Location, describe_error, did_you_mean, located, shown
from .alike import alike
from .bulk import objects_in_bulk
from .objects import Object, ObjectHead, without_written_defaults

MAX_SIZE = 16384          # pixels per side, from the format
MAX_SAMPLES = 16          # 16×16 = 256 rays per pixel is already a reference-quality render
MAX_PIXEL_RAYS = 2**31 - 1  # embree indexes rays with int32 per call; beyond this a frame is absurd anyway

# ---------------------------------------------------------------- tables

class Render(Table):
    """How the image is made: its size, the shading and specular models, the mode, sampling and precision."""
    width: Whole = Field(640, ge=1, le=MAX_SIZE, description="image width in pixels")
    height: Whole = Field(480, ge=1, le=MAX_SIZE, description="image height in pixels")
    shading: ShadingModel = Field(ShadingModel.PHONG, description=(
        "where the model is evaluated: flat at each face's centroid with its face normal, gouraud at the corners "
        "with their vertex normals and mixed, phong at the hit with the mixed, renormalised normal"))
    specular: SpecularModel = Field(SpecularModel.PHONG, description=(
        "the specular term: phong max(v·r, 0)^f, or blinn max(n·h, 0)^f with h = normalize(l + v)"))
    viewer: Viewer = Field(Viewer.LOCAL, description=(
        "local: v toward the eye at each point; infinite: v = −forward everywhere"))
    mode: Mode = Field(Mode.LOCAL, description=(
        "global: a shadow ray from every hit to every light (at most 63 lights); see docs/global.md"))
    terminator: Literal["none", "hanika"] = Field("hanika", description=(
        "global mode, Gouraud/Phong faces: start shadow rays on the smooth surface of the vertex normals "
        "(Hanika 2021), or at the hit point"))
    samples: Whole = Field(1, ge=1, le=MAX_SAMPLES, description=(
        "n: n×n rays per pixel on the centres of an n×n grid, equal weights"))
    background: Intensity = Field((0.0, 0.0, 0.0), description="the colour of pixels that see nothing")
    precision: Literal[tuple(p.value for p in Precision)] = Field(  # type: ignore[valid-type]
        "float32", description="the arithmetic of the shading kernel")
    two_sided: Annotated[bool, Strict()] = Field(True, description=(  # true or false, not "yes" or 1
        "shade a back-facing hit with its normals flipped toward the viewer"))
    interpolation: Literal["perspective", "screen"] = Field("perspective", description=(
        "barycentric weights: the true point on the triangle (Embree's), or linear in the image plane like the "
        "lecture's scanline formulas"))
    # "display" (fixed-function GL's): maps and colours as stored, the PNG written as it is; "linear" (glTF's):
    # 8-bit maps decoded from sRGB, the PNG through the sRGB curve. A mesh file rendered directly gets its
    # format's choice (scene.framing.mesh_colour); a scene file, this default.
    colour: Literal[COLOURS] = Field(COLOURS[0], description=(  # type: ignore[valid-type]
        "how colour values are taken and shown: display uses 8-bit maps as stored and writes the PNG as it is; "
        "linear decodes 8-bit maps from sRGB and writes the PNG through the sRGB curve (a glTF file rendered "
        "directly defaults to linear)"))


class Camera(Table):
    """The eye: where it is, where it looks, and its lens."""
    type: Literal["perspective", "orthographic"] = Field("perspective", description="the projection")
    position: Position = Field((0.0, 0.0, 4.0), description="the eye")
    look_at: Position = Field((0.0, 0.0, 0.0), description=(
        f"the point the camera looks at; at least {DIRECTION_RANGE[0]:g} from position"))
    up: Direction = Field((0.0, 1.0, 0.0), description=(
        f"the image's up direction; length in [{DIRECTION_RANGE[0]:g}, {DIRECTION_RANGE[1]:g}], not parallel to "
        "look_at − position"))
    fov: Number = Field(40.0, gt=0.0, lt=180.0, description="perspective: the vertical field of view, degrees")
    view_height: Number = Field(2.0, gt=0.0, le=POSITION_LIMIT, allow_inf_nan=False, description=(
        "orthographic: the height of the view in world units"))

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


ATTENUATION_SCHEMA = WithJsonSchema({"anyOf": [
    {"enum": ["none", "inverse_square"]},
    {"type": "array", "items": number_schema(0.0, INTENSITY_LIMIT), "minItems": 3, "maxItems": 3,
     "not": {"const": [0, 0, 0]}}]})


class Light(Table):
    """A point or directional light and its intensities."""
    model_config = ConfigDict(json_schema_extra={  # _placement below: a light needs where it is, or its way
        "if": {"properties": {"type": {"const": "directional"}}, "required": ["type"]},
        "then": {"required": ["direction"], "properties": {"direction": {"not": {"type": "null"}}}},
        "else": {"required": ["position"], "properties": {"position": {"not": {"type": "null"}}}}})
    type: Literal[tuple(kind.value for kind in LightKind)] = Field(  # type: ignore[valid-type]
        "point", description="point: at a position; directional: from a direction, at infinity")
    position: Position | None = Field(None, description="where a point light is (required for a point light)")
    direction: Direction | None = Field(None, description=(
        f"the direction a directional light travels (required for one); length in [{DIRECTION_RANGE[0]:g}, "
        f"{DIRECTION_RANGE[1]:g}]"))
    diffuse: Intensity = Field((0.8, 0.8, 0.8), description="I_d, the diffuse intensity")
    specular: Intensity = Field((1.0, 1.0, 1.0), description="I_s, the specular intensity")
    ambient: Intensity = Field((0.0, 0.0, 0.0), description="the light's own ambient, added to I_a (times f_att)")
    attenuation: Annotated[Literal["none", "inverse_square"] | tuple[float, float, float],
                           BeforeValidator(_attenuation), ATTENUATION_SCHEMA] = Field("none", description=(
                               "f_att = 1, 1/d², or min(1, 1/(c + l·d + q·d²)) for [c, l, q] (not all zero); "
                               "always 1 for a directional light"))

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
    path: str = Field(description="the image file, relative to the scene file's folder")
    wrap: Literal[WRAP_MODES] = Field("repeat", description=(  # type: ignore[valid-type]
        "how texture coordinates outside [0, 1] are brought back"))


def _map(value: Any) -> Any:
    """kd_map = "wood.png" is the short form of { path = "wood.png" }; a number or a list is neither (not a file
    named '5')."""
    if isinstance(value, str):
        return {"path": value}
    if value is not None and not isinstance(value, dict):
        raise ValueError('must be an image file name or a table { path = "...", wrap = "clamp" }')
    return value


# "wood.png" or { path = "wood.png", wrap = "clamp" }, as the file may write it.
MapKey = Annotated[TextureMap, BeforeValidator(_map, json_schema_input_type=str | TextureMap)] | None


# shininess = inf (the mirror limit) as validators see a TOML inf: a number above the largest finite float where
# numbers are doubles (Python's tomllib and json, JavaScript), null in taplo (Even Better TOML), whose serde_json
# has no inf and turns it into null; TOML has no null, so there null is inf (or nan). A "maximum" alone refuses both.
SHININESS_SCHEMA = WithJsonSchema({"anyOf": [number_schema(0.0, INTENSITY_LIMIT),
                                             {"type": "number", "exclusiveMinimum": sys.float_info.max},
                                             {"type": "null"}]})


class Material(Table):
    """The Phong model's coefficients of a surface, and its colour maps."""
    ka: Coefficient = Field(MATERIAL_DEFAULTS["ka"], description="k_a, the ambient reflection")
    kd: Coefficient = Field(MATERIAL_DEFAULTS["kd"], description="k_d, the diffuse reflection")
    ks: Coefficient = Field(MATERIAL_DEFAULTS["ks"], description="k_s, the specular reflection")
    ke: Coefficient = Field(MATERIAL_DEFAULTS["ke"], description="k_e, the emission")
    shininess: Annotated[Number, SHININESS_SCHEMA] = Field(
        MATERIAL_DEFAULTS["shininess"], description=(
            "the exponent f; 0 is the limit f → 0⁺; a TOML file may write inf, the mirror limit"))
    ka_map: MapKey = Field(None, description=(  # multiplies k_a (the kd_map does when this is not given)
        "a colour map multiplying k_a instead of the kd_map"))
    kd_map: MapKey = Field(None, description=(  # multiplies k_d and k_a at the hit's texture coordinates
        "a colour map: its colour at the hit's texture coordinates multiplies k_d and k_a (the specular term is "
        'never textured); an image file name, or a table { path = "...", wrap = "clamp" }'))
    ke_map: MapKey = Field(None, description="a colour map multiplying k_e")

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
    """The file `render` writes when no -o is given, and its extra layers."""
    model_config = ConfigDict(json_schema_extra={  # the layers need an EXR (_format below)
        "if": {"properties": {"aovs": {"minItems": 1}}, "required": ["aovs", "path"]},
        "then": {"properties": {"path": {"pattern": r"\.[eE][xX][rR]$"}}}})
    path: str = Field("out.png", json_schema_extra={"pattern": r"\.([pP][nN][gG]|[eE][xX][rR])$"}, description=(
        '.png (8-bit) or .exr (float32), inside the scene\'s folder (no absolute path, ~ or ".."); "out.exr" '
        "when aovs are asked for"))
    aovs: tuple[Literal[LAYERS], ...] = Field((), description=(  # type: ignore[valid-type]
        "extra EXR layers (an .exr path is required)"))

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
            raise _KeyError(OUTPUT_PATH, f"{self.path!r} must end in .png or .exr")
        if self.aovs and suffix != ".exr":
            raise _KeyError(("output", "aovs"), f"{list(self.aovs)} need an .exr output, but output.path is "
                            f"{self.path!r} (a PNG holds only RGB)")
        return self


DEFAULT_MATERIAL = Material()


class Scene(Table):
    """A validated scene: every key of the format with its value or default."""
    model_config = ConfigDict(json_schema_extra={"required": ["objects"]})  # _references refuses a scene without
    render: Render = Render()
    camera: Camera = Camera()
    ambient: Intensity = Field((0.1, 0.1, 0.1), description="I_a, the scene's ambient intensity")
    lights: tuple[Light, ...] = Field((), description="the lights, any number")
    materials: dict[str, Material] = Field({}, description=(  # pydantic copies a default, not shares it
        'materials by name; an object without one uses the defaults (the material named "default")'))
    objects: Annotated[tuple[Object, ...], BeforeValidator(without_written_defaults)] = Field(
        (), json_schema_extra={"minItems": 1}, description="the objects, at least one")
    output: Output = Output()
    folder: str = Field(".", exclude=True)  # the scene file's folder: relative paths start here
    # The mesh files' io.meshes.source.MeshSource made while loading (framing a mesh file), by source_key: handed
    # with the scene to prepare(), which reads no file twice. What was read, not part of the scene's value.
    _mesh_sources: dict = PrivateAttr(default_factory=dict)
    # Where the scene came from (the file, "mesh_scene", "<scene>"): every later stage's message starts there.
    _origin: Location = PrivateAttr(default_factory=lambda: Location("<scene>"))

    @model_validator(mode="after")
    def _references(self) -> Scene:
        if not self.objects:
            raise _KeyError(("objects",), 'the scene has no [[objects]]; add at least one, e.g. '
                            '[[objects]] shape = "icosphere"')
        index = _undefined_material(self)
        if index is not None:
            name = self.objects[index].material
            defined = ", ".join(sorted(self.materials)) or "none"
            raise _KeyError(("objects", index, "material"),
                            f"material {name!r} is not defined{did_you_mean(name, self.materials)}; defined: "
                            f"{defined}")
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

    __hash__ = None  # a Scene holds dicts (materials): not hashable

    @property
    def origin(self) -> Location:
        """Where the scene came from (validate_scene's `source`: the file): a stage's error about the scene is
        located from it (`scene.origin.at("objects", 3, "path")`), so no stage is told it again."""
        return self._origin

    @property
    def mesh_sources(self) -> dict:
        """The MeshSources (io/meshes/source.py) made while this scene was loaded, by source_key; {} when none
        were (a scene file: prepare() makes them)."""
        return self._mesh_sources

    def current_mesh_sources(self) -> dict | None:
        """Each mesh file's MeshSource by resolved path (io.meshes.source.mesh_sources: the kept ones still
        current, the others made now); None when no object is read from a file, its modules left unimported."""
        if any(map(from_file, self.objects)):
            from ..io.meshes.source import mesh_sources
            return mesh_sources(self)
        return None

    def data(self, mode: str = "python", exclude_none: bool = False) -> dict:
        """The scene's keys as a dict that validates back to this scene (model_dump without the folder), a key
        left unset that means "decide from the file" kept unset: an object's crease_angle, unset, creases a mesh
        file without normals at 30° (geometry.templates.file_crease_angle); dumped, it would read 180."""
        data = self.model_dump(mode=mode, exclude={"folder"}, exclude_none=exclude_none)
        for obj, dumped in zip(self.objects, data["objects"]):
            if "crease_angle" not in obj.model_fields_set:
                dumped.pop("crease_angle", None)
        return data

    def replace(self, changes: Mapping[str, Any], /) -> Scene:
        """A new scene with `changes` applied, validated as a scene file is, in this scene's folder (its meshes
        and maps still resolve). Keys are the paths `--set` takes, values are Python values:

            scene.replace({"render.width": 320, "lights.0.position": [1, 2, 3], "materials.red.kd": [1, 0, 0]})

        Raises SceneError (one line naming the key path and what is allowed) for a change the format refuses.
        A Scene is frozen; `model_copy(update=...)` would skip validation. The mesh sources read while loading
        (and a mesh given as arrays, rp.mesh_scene) go with the new scene."""
        from .keypaths import assign
        where = located("Scene.replace")
        data = self.data(mode="json", exclude_none=True)
        for key, value in changes.items():
            if not isinstance(key, str):
                raise SceneError(f"{shown(key)} is not a key path; expected a string such as 'render.width'", where)
            assign(data, key, value, where)
        changed = validate_scene(data, source=str(where), folder=self.folder)
        changed.mesh_sources.update(self.mesh_sources)
        changed._origin = self._origin  # the same file, changed: later stages still name it
        return changed

    def material_of(self, obj: Object) -> Material:
        return self.materials.get(obj.material, DEFAULT_MATERIAL)

    def shading_of(self, obj: Object) -> ShadingModel:
        return obj.shading or self.render.shading

    def resolve(self, path: str) -> Path:
        """A path from the scene file, relative to the file's folder."""
        return Path(self.folder) / Path(path).expanduser()

    def mesh_objects(self) -> list[tuple[int, Path]]:
        """(index, file) of each object read from a file (a mesh), the file resolved, in the objects' order."""
        return [(index, self.resolve(obj.path)) for index, obj in enumerate(self.objects)
                if from_file(obj) and obj.path]

    def mesh_paths(self) -> list[Path]:
        """The file each object read from a file (a mesh) names, resolved, in the objects' order."""
        return [path for _, path in self.mesh_objects()]

    def files_read(self) -> list[Path]:
        """Every file rendering this scene reads, resolved: the colour maps its materials name, its mesh files,
        then what those open beside them (an .obj's .mtl files and maps, a .gltf's buffers and images), as each
        mesh file's MeshSource finds them (the scene's own where it has them: a mesh file loaded as a scene). An
        output may be none of these; a batch's up-to-date rule covers exactly these and the scene file."""
        maps = [self.resolve(path) for key, path in self.named_files().items() if key[0] == "materials"]
        found = self.current_mesh_sources()  # not kept: a batch sends scenes to its workers, sources stay here
        if found is None:
            return maps
        return [*maps, *self.mesh_paths(), *(file for source in found.values() for file in source.files_read)]

    def named_files(self) -> dict[tuple, str]:
        """Every file the scene names, as written, by the key path that names it (a tuple, as error locations
        are: messages.dotted words it): ("objects", N, "path") for meshes, ("materials", M, "kd_map", "path")
        (and ka_map, ke_map) for textures, and OUTPUT_PATH. A caller that must not let its client choose files
        (the view's page) compares these before anything is opened."""
        named: dict[tuple, str] = {("objects", index, "path"): obj.path
                                   for index, obj in enumerate(self.objects) if from_file(obj)}
        named.update({("materials", name, key, "path"): getattr(material, key).path
                      for name, material in self.materials.items() for key in MAP_COLUMNS
                      if getattr(material, key) is not None})
        named[OUTPUT_PATH] = self.output.path
        return named


def _undefined_material(scene: Scene) -> int | None:
    """The first object whose material is neither "default" nor defined; None if there is none. Decided once per
    set of alike objects (scene/alike.py): a set's first object is the first of its objects to go wrong."""
    sets = alike(scene)
    names = list(map(operator.attrgetter("material"), sets.firsts(scene.objects)))
    undefined = {name for name in set(names) if name != "default" and name not in scene.materials}
    return int(sets.first[next(k for k, name in enumerate(names) if name in undefined)]) if undefined else None


def brightness_problem(scene: Scene, inverse_square: dict[int, float] | None = None, why: str = "") -> tuple | None:
    """(key path, message) if the lights could make a pixel channel exceed INTENSITY_LIMIT, else None.

    Every coefficient, cosine and S is at most 1, so a pixel channel is at most
    1 + I_a + Σ_k g_k (I_a,k + I_d,k + I_s,k), with g_k ≥ f_att of light k: 1 without attenuation,
    min(1, 1/c) for [c, l, q], and for a 1/d² light the bound `inverse_square[k]` that only the geometry
    can give (geometry.check_float_range; 0 until then). Supersampling only averages.
    """
    inverse_square = inverse_square or {}
    gains = [1.0 if light.type == "directional" or light.attenuation == "none"
             else inverse_square.get(k, 0.0) if light.attenuation == "inverse_square"
             else min(1.0, 1.0 / light.attenuation[0]) if light.attenuation[0] > 0 else 1.0
             for k, light in enumerate(scene.lights)]
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
    """Validate a parsed scene table (a dict, as TOML or JSON gives it) into a Scene.

    Parameters
    ----------
    data: the scene's keys (docs/scene-format.md); Python sequences and numpy arrays are taken where lists are.
    source: the name each error starts with (the file). folder: where the scene's relative paths start.

    Returns the validated, frozen Scene. Raises SceneError, one line naming `source`, the key path and what is
    allowed.
    """
    where = located(source)
    data = dict(data)
    if "folder" in data:
        raise SceneError("unknown key", where.at("folder"))
    try:
        objects = {"objects": objects_in_bulk(data["objects"])} if "objects" in data else {}
        scene = Scene.model_validate({**data, **objects, "folder": str(folder)})
        scene._origin = where
        return scene
    except ValidationError as error:
        at, problem = describe_error(error, where, Scene)
        raise SceneError(problem, at) from None
    except _KeyError as error:
        raise SceneError(error.message, where.at(*error.loc)) from None


def examples_folder() -> Path:
    """The example scenes, their meshes and textures: in a wheel raycast_phong/data/scenes (setup.py copies them
    there), in a source checkout the top-level scenes/, their one home."""
    packaged = Path(__file__).parents[1] / "data" / "scenes"
    return packaged if packaged.is_dir() else Path(__file__).parents[2] / "scenes"


def example_names() -> list[str]:
    """The example scenes by name (`raycast-phong scene --example NAME`): each .toml of examples_folder()."""
    return sorted(path.stem for path in examples_folder().glob("*.toml"))


def default_scene_path() -> Path:
    """The built-in default scene: the lecture's figure, one sphere in flat, Gouraud and Phong shading.

    Parameters: none. Returns the Path of the example scene default.toml (examples_folder). Raises nothing."""
    return examples_folder() / "default.toml"


# What the loader checks and no JSON Schema can say: a vector's length, one key against another, the scene as a
# whole, and the files a scene names. The schema accepts these scenes; the loader refuses them with one line.
BEYOND_THE_SCHEMA = (
    f"camera.up and a light's direction: a length in [{DIRECTION_RANGE[0]:g}, {DIRECTION_RANGE[1]:g}], not zero",
    "camera.look_at at least 1e-150 from camera.position; camera.up not parallel to look_at − position",
    "an object's material: defined under [materials] (or \"default\")",
    "render: width × height × samples² at most 2³¹ − 1 rays",
    "the lights together: 1 + ambient + Σ f_att (ambient + diffuse + specular) at most 1e38 in each channel",
    "files: mesh files and maps exist and read; output.path stays inside the scene's folder; every placed "
    "vertex within ±1e18 and the scene's half-extent at least 1e-12 (docs/scene-format.md, \"Number ranges\")",
    "TOML's inf and nan, which JSON cannot write: only shininess = inf is accepted",
    "a material's shininess = null in a JSON file, which the schema lets through as taplo's reading of TOML's inf",
)


def scene_json_schema() -> dict:
    """The JSON Schema (draft 2020-12) of the scene format, published as docs/scene.schema.json.

    Generated from the models above, so it accepts what the loader accepts, shorthands included (one number for
    a triple, a map's file name alone), an [[objects]] entry keyed on its shape (_objects_by_shape); what it cannot
    say is BEYOND_THE_SCHEMA, written into its $comment."""
    schema = Scene.model_json_schema(mode="validation")
    schema["properties"].pop("folder", None)
    objects = schema["properties"]["objects"]
    objects["items"] = _objects_by_shape(objects["items"])
    return {"$schema": "https://json-schema.org/draft/2020-12/schema",
            "title": "raycast-phong scene, format version 1",
            "description": "A scene file of raycast-phong (TOML, or JSON of the same structure); docs/scene-format.md "
                           "is its reference.",
            "$comment": "Checked by the loader, not by this schema: " + "; ".join(BEYOND_THE_SCHEMA) + ".",
            **{key: value for key, value in schema.items() if key not in ("title", "description")}}


def _objects_by_shape(union: dict) -> dict:
    """An [[objects]] entry as one `if`/`then` per kind keyed on `shape`, in place of pydantic's `oneOf` of the
    kinds with a discriminator: validators ignore the discriminator, so under `oneOf` a sphere's wrong radius would
    be "not valid under any of the given schemas" at the whole object. Here the kind's table applies as such and an
    editor marks the key; a shape no kind has is marked at `shape`. Same meaning: `shape` required, one of the
    kinds, and the object that kind's table (each `if` asks for a table too, or anything else would meet every
    `then` and be refused once per kind)."""
    shape_of = {ref: shape for shape, ref in union["discriminator"]["mapping"].items()}
    kinds = [(shape_of[option["$ref"]], option["$ref"]) for option in union["oneOf"]]  # the registry's order
    return {"type": "object", "required": ["shape"],
            "properties": {"shape": {"enum": [shape for shape, _ in kinds],
                                     "description": ObjectHead.model_fields["shape"].description}},
            "allOf": [{"if": {"type": "object", "properties": {"shape": {"const": shape}}, "required": ["shape"]},
                       "then": {"$ref": ref}} for shape, ref in kinds]}
