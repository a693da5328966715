"""An [[objects]] entry's keys: those every object has, each kind's own (declared in its module under
shapes/ and found through the registry, shapes.KINDS), and the union of one model per kind,
discriminated by `shape`, that the scene validates each object as.

A kind's model is its keys between the keys every object has: name, shape, the kind's own keys, then material,
shading, normals, crease_angle, translate, rotate, scale (the order a scene is written in and keys are listed).
A mesh file (shape = "mesh") is a kind too, the one read rather than built (ShapeKind.from_file).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, Union

from pydantic import AfterValidator, ConfigDict, Field, ValidationInfo, create_model

from ..codes import ShadingModel
from ..shapes import KINDS
from ..values.fields import Angles, KindKeys, Number, Position, Scale, Table

NormalsRule = Literal["mean", "area", "angle", "file", "exact"]  # how an object's vertex normals are made


def _normals_fit(value: str | None, info: ValidationInfo) -> str | None:
    """A mesh file's own normals need a mesh file; the closed form needs a built-in shape."""
    shape = info.data.get("shape")
    read = shape in KINDS and KINDS[shape].from_file
    if not read and value == "file":
        raise ValueError(f'normals = "file" needs a mesh file; shape = "{shape}" has no stored normals')
    if read and value == "exact":
        raise ValueError('normals = "exact" needs a built-in shape; a mesh file has no closed form (use "file", '
                         '"mean", "area" or "angle")')
    return value


def _object_schema(schema: dict, model: type) -> None:
    """A kind's JSON Schema says what its validators say: the normals rules it may use (_normals_fit), a mesh's
    path required (shapes.mesh.MeshKeys._named), and the keys of other kinds that a file written by an earlier
    version holds at their defaults (without_written_defaults), which are accepted, marked deprecated."""
    shape = model.model_fields["shape"].annotation.__args__[0]
    properties = schema["properties"]
    read = KINDS[shape].from_file
    refused = "exact" if read else "file"
    rules = properties["normals"]["anyOf"][0]
    rules["enum"] = [rule for rule in rules["enum"] if rule != refused]
    if read:
        schema["required"] = [*schema.get("required", ()), "path"]
        properties["path"] = {"type": "string", "minLength": 1, "description": properties["path"]["description"]}
    for key, defaults in sorted(_FOREIGN_DEFAULTS[shape].items()):
        properties[key] = {"enum": sorted({json_value(value) for value in defaults}, key=repr), "deprecated": True,
                           "description": "another shape's key, accepted at its default only (files written by "
                                          "earlier versions held every key of every shape)"}


def json_value(value: Any) -> Any:
    """A default as JSON writes it (a tuple as a list; hashable for the set above: a list as a tuple again)."""
    return tuple(value) if isinstance(value, (list, tuple)) else value


class ObjectHead(Table):
    """The keys every object starts with; each kind's model narrows `shape` to its own name."""
    model_config = ConfigDict(json_schema_extra=_object_schema)
    name: str | None = Field(None, description="a name for messages and the view; any text")
    shape: str = Field(description="the kind of object: a built-in shape, or mesh for a mesh file")


class ObjectKeys(Table):
    """The keys every object has after its kind's own: its material, shading and normals, and its placement."""
    material: str = Field("default", description=(
        'a material defined under [materials]; a mesh with "default" takes the file\'s own materials and colours'))
    shading: ShadingModel | None = Field(None, description="overrides render.shading for this object")
    # None: "file" if the mesh file stores vertex normals, else "mean"
    normals: Annotated[NormalsRule | None, AfterValidator(_normals_fit)] = Field(None, description=(
        "vertex normal = normalize(Σ w_f n_f) over the adjacent faces, w = 1 (mean), the face area or the corner "
        "angle; file: the mesh file's normals (mesh only); exact: the true surface normal of a built-in shape. "
        'Unset: "file" for a mesh file that stores normals, else "mean"'))
    crease_angle: Number = Field(180.0, ge=0.0, le=180.0, description=(
        "faces meeting at more than this many degrees keep their own vertex normals at the shared edge; "
        "180 = never split"))
    translate: Position = Field((0.0, 0.0, 0.0), description="placement: world = T · Rz · Ry · Rx · S · local")
    rotate: Angles = Field((0.0, 0.0, 0.0), description="degrees about x, then y, then z")
    scale: Scale = Field((1.0, 1.0, 1.0), description=(
        "a number or [sx, sy, sz], no zero factor; a negative product mirrors (the winding is reversed so faces "
        "still point outward)"))


def object_model(shape: str, keys: type[KindKeys], title: str) -> type[Table]:
    """The model of an object of one kind: name and shape (its name only), the kind's `keys`, then the keys of
    every object."""
    return create_model(title, __base__=(ObjectKeys, keys, ObjectHead), __module__=__name__,
                        __doc__=f'An object of shape = "{shape}".',
                        shape=(Literal[shape], Field(description=(keys.__doc__ or title).split("\n")[0])))


# One model per kind, in the registry's order, the kinds read from a file (a mesh) after those built.
OBJECT_MODELS: dict[str, type[Table]] = {name: object_model(name, kind.keys, type(kind).__name__)
                                         for name, kind in sorted(KINDS.items(), key=lambda item: item[1].from_file)}
globals().update({model.__name__: model for model in OBJECT_MODELS.values()})  # pickle finds a class by its name
Object = Annotated[Union[tuple(OBJECT_MODELS.values())], Field(discriminator="shape")]  # noqa: UP007

_COMMON = frozenset.intersection(*(frozenset(model.model_fields) for model in OBJECT_MODELS.values()))
OWN_KEYS = {shape: tuple(key for key in model.model_fields if key not in _COMMON)
            for shape, model in OBJECT_MODELS.items()}  # the keys each kind alone reads, in its order
# For each kind, the keys other kinds read, with the defaults they have there.
_FOREIGN_DEFAULTS = {shape: {key: tuple(other.model_fields[key].default for other in OBJECT_MODELS.values()
                                        if key in other.model_fields)
                             for key in frozenset().union(*map(OWN_KEYS.get, OBJECT_MODELS)) - set(OWN_KEYS[shape])}
                     for shape in OBJECT_MODELS}


def without_written_defaults(objects: Any) -> Any:
    """The object tables without the keys of other kinds that a scene file written by an earlier version holds
    at their defaults (it wrote every key of every shape): such a file still reads. A key another kind reads,
    set to anything else, stays, and is refused as not applying to the object's shape."""
    if type(objects) not in (list, tuple):
        return objects
    return [_trimmed(obj) if type(obj) is dict else obj for obj in objects]


def _trimmed(obj: dict) -> dict:
    shape = obj.get("shape")
    foreign = _FOREIGN_DEFAULTS.get(shape) if type(shape) is str else None
    if not foreign:
        return obj
    drop = [key for key, value in obj.items()  # at its default: not a bool (true == 1 in Python, not in a file)
            if key in foreign and not isinstance(value, bool) and json_value(value) in foreign[key]]
    return {key: value for key, value in obj.items() if key not in drop} if drop else obj
