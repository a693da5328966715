"""The scene format's value types: what a key's value may be (a number, a whole number, a triple, lengths, a
segment pair), each with its check and its one-line wording, and `KindKeys`, the base of a kind's own keys.

They sit below the kinds of object (shapes/), which declare their keys with them, and below the schema,
which gathers those keys from the registry; they know no table of the scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, Field, WithJsonSchema

from ..tolerances import DIRECTION_RANGE, INTENSITY_LIMIT, POSITION_LIMIT
from .messages import shown


class Table(BaseModel):
    """A table of the scene format: unknown keys are an error, a validated table never changes."""
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)


def check_number(value: Any, *, what: str = "a number") -> Any:
    """TOML and JSON tell text and booleans from numbers, so "32" or true where a number belongs is a
    mistake in the file; pydantic's lax mode would quietly convert them."""
    if isinstance(value, (str, bool, dict, list, tuple)) or value is None:
        raise ValueError(f"must be {what}, got {shown(value)}")
    return value


def check_whole(value: Any) -> Any:
    """As check_number, for counts: width, height, samples, subdivisions, segments."""
    return check_number(value, what="a whole number")


Number = Annotated[float, BeforeValidator(check_number)]
Whole = Annotated[int, BeforeValidator(check_whole)]
# ---------------------------------------------------------------- the JSON Schema of each value type
# Each type below states its JSON Schema beside its check, from the same constants: `raycast-phong schema` is
# generated from these models (scene.schema.scene_json_schema) and accepts what they accept. JSON has no inf or
# NaN, so a JSON number is finite; what no JSON Schema can say (a vector's length, one key against another) is
# listed in scene.schema.BEYOND_THE_SCHEMA.

def number_schema(low: float | None = None, high: float | None = None, above: bool = False,
                  non_zero: bool = False) -> dict:
    """A number's JSON Schema: at least `low` (more than it when `above`), at most `high`, never 0 if `non_zero`."""
    node: dict = {"type": "number"}
    if low is not None:
        node["exclusiveMinimum" if above else "minimum"] = low
    if high is not None:
        node["maximum"] = high
    if non_zero:
        node["not"] = {"const": 0}
    return node


def triple_schema(item: dict) -> WithJsonSchema:
    """Three numbers [a, b, c], each as `item` says, or one such number meaning all three (check_triple)."""
    return WithJsonSchema({"anyOf": [item, {"type": "array", "items": item, "minItems": 3, "maxItems": 3}]})


def list_schema(item: dict, count: int) -> WithJsonSchema:
    """Exactly `count` values, each as `item` says."""
    return WithJsonSchema({"type": "array", "items": item, "minItems": count, "maxItems": count})


def check_triple(value: Any) -> Any:
    """A single number means the same value in all three channels (format: Conventions)."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return (value, value, value)
    sequence = sequence_of(value)
    if sequence is None or len(sequence) != 3:
        count = f"{len(sequence)} numbers: " if sequence is not None else ""
        raise ValueError(f"must be three numbers [a, b, c] (or one number for all three), got {count}{shown(value)}")
    return sequence


def sequence_of(value: Any) -> tuple | None:
    """A list from the file, or any sized iterable from Python callers (a numpy array), as a tuple."""
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__") or not hasattr(value, "__iter__"):
        return None
    return tuple(value)


def finite(values: tuple[float, ...]) -> tuple[float, ...]:
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"must be finite numbers, got {list(values)}")
    return values


def position(values: tuple[float, ...]) -> tuple[float, ...]:
    """A point in the world: finite, each coordinate within ±POSITION_LIMIT."""
    finite(values)
    if not all(abs(v) <= POSITION_LIMIT for v in values):
        raise ValueError(f"each coordinate must be within ±{POSITION_LIMIT:g} (so squared distances stay finite "
                         f"in float32), got {list(values)}")
    return values


def direction(values: tuple[float, ...]) -> tuple[float, ...]:
    """A direction: finite, with a length in DIRECTION_RANGE (the zero vector is left to the owner's check,
    which says what the direction is for)."""
    finite(values)
    length, (low, high) = math.hypot(*values), DIRECTION_RANGE
    if length != 0.0 and not low <= length <= high:
        raise ValueError(f"length {length:.3g}; allowed: {low:g} ≤ length ≤ {high:g} (its square must be a normal "
                         f"float64 to normalise it), got {list(values)}")
    return values


def unit_range(values: tuple[float, ...]) -> tuple[float, ...]:
    finite(values)
    if not all(0.0 <= v <= 1.0 for v in values):
        raise ValueError(f"each coefficient must be in [0, 1], got {list(values)}")
    return values


def non_negative(values: tuple[float, ...]) -> tuple[float, ...]:
    finite(values)
    if not all(0.0 <= v <= INTENSITY_LIMIT for v in values):
        raise ValueError(f"intensities must be in [0, {INTENSITY_LIMIT:g}] (a pixel must stay finite in float32), "
                         f"got {list(values)}")
    return values


def scale_factors(values: tuple[float, float, float]) -> tuple[float, float, float]:
    """An object's scale: finite, no zero factor (it would flatten the object), each within ±POSITION_LIMIT (a
    shape's lengths are at most POSITION_LIMIT, so the scaled coordinates stay finite in float64 and the placed
    object's own bound, geometry.place, can be checked)."""
    finite(values)
    if any(v == 0 for v in values):
        raise ValueError(f"scale {list(values)} has a zero factor, which flattens the object")
    if not all(abs(v) <= POSITION_LIMIT for v in values):
        raise ValueError(f"each factor must be within ±{POSITION_LIMIT:g}, got {list(values)}")
    return values


# A length of a shape: positive, and at most POSITION_LIMIT so the shape's coordinates stay finite in float64.
# (Bounds behind a BeforeValidator reach the JSON Schema as pydantic's raw gt/le: the schema is stated here.)
Length = Annotated[Number, Field(gt=0.0, le=POSITION_LIMIT, allow_inf_nan=False),
                   WithJsonSchema(number_schema(0.0, POSITION_LIMIT, above=True))]
Vec3 = Annotated[tuple[Number, Number, Number], BeforeValidator(check_triple), triple_schema(number_schema())]
Coefficient = Annotated[tuple[Number, Number, Number], BeforeValidator(check_triple), AfterValidator(unit_range),
                        triple_schema(number_schema(0.0, 1.0))]
Intensity = Annotated[Vec3, AfterValidator(non_negative), triple_schema(number_schema(0.0, INTENSITY_LIMIT))]
Position = Annotated[Vec3, AfterValidator(position), triple_schema(number_schema(-POSITION_LIMIT, POSITION_LIMIT))]
# Its length is checked (DIRECTION_RANGE), which no JSON Schema can say: scene.schema.BEYOND_THE_SCHEMA.
Direction = Annotated[Vec3, AfterValidator(direction)]
Angles = Annotated[Vec3, AfterValidator(finite)]
Scale = Annotated[Vec3, AfterValidator(scale_factors),
                  triple_schema(number_schema(-POSITION_LIMIT, POSITION_LIMIT, non_zero=True))]


SEGMENTS = (3, 4096)  # each of an object's two segment counts, inclusive


def check_pair(value: Any) -> Any:
    sequence = sequence_of(value)
    if sequence is None or len(sequence) != 2:
        raise ValueError(f"must be two whole numbers [a, b] in [{SEGMENTS[0]}, {SEGMENTS[1]}], got {shown(value)}")
    return sequence


def segment_range(value: tuple[int, int]) -> tuple[int, int]:
    if not all(SEGMENTS[0] <= s <= SEGMENTS[1] for s in value):
        raise ValueError(f"segments must be two whole numbers in [{SEGMENTS[0]}, {SEGMENTS[1]}], got {list(value)}")
    return value


# Two counts of segments (their meaning is the kind's: around and along, x and z cells, ...).
Segments = Annotated[tuple[Whole, Whole], BeforeValidator(check_pair), AfterValidator(segment_range),
                     list_schema({"type": "integer", "minimum": SEGMENTS[0], "maximum": SEGMENTS[1]}, 2)]


@dataclass(frozen=True)
class Lengths:
    """The check of `count` lengths, each in (0, POSITION_LIMIT]: a box's [x, y, z], a plane's [width, depth].
    A class, not a closure, so the bulk check reads its count."""
    count: int
    spelled: str  # how the file writes them, "[x, y, z]"

    def __call__(self, values: tuple[float, ...]) -> tuple[float, ...]:
        if len(values) != self.count or not all(0 < v <= POSITION_LIMIT for v in values):  # NaN fails too
            raise ValueError(f"must be {self.count} numbers {self.spelled}, each in (0, {POSITION_LIMIT:g}], "
                             f"got {list(values)}")
        return values


def lengths(count: int, spelled: str) -> Any:
    """The type of a key of `count` lengths, written `spelled` ("[x, y, z]")."""
    return Annotated[tuple[Number, ...], AfterValidator(Lengths(count, spelled)),
                     list_schema(number_schema(0.0, POSITION_LIMIT, above=True), count)]


class KindKeys(Table):
    """A kind of object's own keys, each with its default and bounds, declared in the kind's module
    (shapes/<kind>.py) with the types above. The schema adds `shape` and the keys every object has
    (scene.objects), so a kind writes only what it alone reads."""
