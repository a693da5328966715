"""Many objects validated a key at a time: the same objects pydantic would give, a column's numbers at once.

pydantic costs about 12 µs an object, 12 s for a million boxes. Objects of one kind with the same keys are
checked here a key at a time instead: a structural check of the column (each value's type, with
set(map(type, ...))), then numpy for the numbers. What each column allows is read from the kind's model (its
fields' types, their Field(gt=, ge=, le=) bounds and their validators, values.fields), never restated: a bound
changed there changes both. A row that passes becomes its kind's model with exactly the values pydantic would
give it; a row that does not (or a key whose rules are not read here, a mesh file, an array from Python) is left
to pydantic, so every message stays pydantic's, naming the object's index and key. Scene._references then checks
all objects in vectorised passes.
"""

from __future__ import annotations

import enum
import gc
import math
import operator
import types
from collections.abc import Callable
from itertools import chain
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import annotated_types
import numpy as np
from pydantic import AfterValidator, BeforeValidator
from pydantic.fields import FieldInfo

from ..shapes import KINDS
from ..tolerances import POSITION_LIMIT
from ..values import fields
from .objects import OBJECT_MODELS, _normals_fit

_NUMBER = frozenset({int, float})                 # exact types: a bool or a str is pydantic's to refuse
_SEQUENCE = frozenset({list, tuple})
_NONE = type(None)
_ROWS = 1 << 16  # objects checked at once: the columns' temporaries stay a few MB however many there are
# Values a validator refuses for every built-in kind (bulk never sees a mesh file): its own stored normals.
_REFUSED = {_normals_fit: frozenset({"file"})}
# Keys of a built-in kind that bulk checking leaves to pydantic (an object with one is validated alone); the
# test holds this to what the fields' rules say.
LEFT_TO_PYDANTIC: dict[str, frozenset] = {}

Check = Callable[[list], tuple[np.ndarray, list]]  # a column → (rows pydantic accepts, the values it gives them)


def bounds(metadata: list) -> tuple[float, bool, float, bool]:
    """(lowest, whether the lowest itself is allowed, highest, whether inf and NaN are allowed) of a number from
    its Field(gt= or ge=, le=, allow_inf_nan=): the one statement of the bound, which bulk checking uses too."""
    low, allowed, high, special = -math.inf, True, math.inf, True
    for constraint in metadata:
        if isinstance(constraint, annotated_types.Gt):
            low, allowed = constraint.gt, False
        elif isinstance(constraint, annotated_types.Ge):
            low, allowed = constraint.ge, True
        elif isinstance(constraint, annotated_types.Le):
            high = constraint.le
        elif getattr(constraint, "allow_inf_nan", None) is False:
            special = False
    return low, allowed, high, special


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


# ---------------------------------------------------------------- column checks, one per value type

def _choice(allowed: dict) -> Check:
    """One of the `allowed` values (file value → what pydantic gives: the value, or its enum member)."""
    members = any(key is not value for key, value in allowed.items())

    def check(column):
        good = _typed(column, frozenset({str, _NONE}))
        good &= np.fromiter((value in allowed if ok else False for value, ok in zip(column, good)), bool, len(column))
        if members:
            column = [allowed[value] if ok else value for value, ok in zip(column, good.tolist())]
        return good, column
    return check


def _text(allowed: frozenset) -> Check:
    return lambda column: (_typed(column, allowed), column)


def _whole(low: float, allowed: bool, high: float) -> Check:
    return lambda column: (np.fromiter((type(v) is int and (low <= v if allowed else low < v) and v <= high
                                        for v in column), bool, len(column)), column)


def _number(low: float, allowed: bool, high: float, special: bool) -> Check:
    def check(column):
        good = _typed(column, _NUMBER)
        values = _numbers(column, good, 1.0)
        good &= ((values >= low) if allowed else (values > low)) & (values <= high)
        if not special:
            good &= np.isfinite(values)
        return good, column if set(map(type, column)) == {float} else values.tolist()
    return check


_VECTOR_RULES = {  # an object's triples (values.fields) and what their validators allow, per row
    fields.position: lambda values: np.all(np.abs(values) <= POSITION_LIMIT, axis=1),
    fields.finite: lambda values: np.all(np.isfinite(values), axis=1),
    fields.scale_factors: lambda values: np.all(np.isfinite(values) & (values != 0)
                                                & (np.abs(values) <= POSITION_LIMIT), axis=1),
}


def _vector(rule: Callable) -> Check:
    def check(column):
        made, good, values = _sequences(column, 3, scalar=True)
        return good & rule(values), made
    return check


def _segments(column):
    low, high = fields.SEGMENTS
    good = np.fromiter((type(value) in _SEQUENCE and len(value) == 2 and all(type(v) is int and low <= v <= high
                                                                              for v in value) for value in column),
                       bool, len(column))
    return good, [tuple(value) if ok else value for value, ok in zip(column, good.tolist())]


def _lengths(count: int) -> Check:
    def check(column):
        made, good, values = _sequences(column, count)
        return good & np.all((values > 0) & (values <= POSITION_LIMIT), axis=1), made
    return check


def _nullable(check: Check) -> Check:
    """`check`, with None accepted as itself (a key whose default is None, given as null in JSON)."""
    def nullable(column):
        if _NONE not in set(map(type, column)):
            return check(column)
        rows = [index for index, value in enumerate(column) if value is not None]
        good, values = np.ones(len(column), bool), list(column)
        passed, made = check([column[index] for index in rows])
        good[rows] = passed
        for index, value in zip(rows, made):
            values[index] = value
        return good, values
    return nullable


def column_check(field: FieldInfo) -> Check | None:
    """How a column of this field's values is checked in bulk, read from its type, bounds and validators;
    None when they include anything not read here (then pydantic checks every object with the key)."""
    annotation, metadata = field.annotation, list(field.metadata)
    nullable = False
    while True:
        if get_origin(annotation) is Annotated:
            annotation, *extra = get_args(annotation)
            metadata = [*extra, *metadata]
        elif get_origin(annotation) in (Union, types.UnionType) and _NONE in get_args(annotation):
            rest = [arg for arg in get_args(annotation) if arg is not _NONE]
            if len(rest) != 1:
                return None
            annotation, nullable = rest[0], True
        else:
            break
    before = [item.func for item in metadata if isinstance(item, BeforeValidator)]
    after = [item.func for item in metadata if isinstance(item, AfterValidator)]
    check = _column_of(annotation, before, after, metadata, nullable)
    if check is None:
        return None
    # A choice or a text takes None as one of its values; other checks are given the rows that are not None.
    takes_none = get_origin(annotation) is Literal or (isinstance(annotation, type) and issubclass(annotation, str))
    return _nullable(check) if nullable and not takes_none else check


def _column_of(annotation, before: list, after: list, metadata: list, nullable: bool) -> Check | None:
    if get_origin(annotation) is Literal or (isinstance(annotation, type) and issubclass(annotation, enum.Enum)):
        if before or any(rule not in _REFUSED for rule in after):
            return None
        values = get_args(annotation) if get_origin(annotation) is Literal else tuple(annotation)
        allowed = {getattr(value, "value", value): value for value in values}
        for rule in after:
            allowed = {key: value for key, value in allowed.items() if key not in _REFUSED[rule]}
        return _choice(allowed | ({None: None} if nullable else {}))
    if annotation is str and not before and not after:
        return _text(frozenset({str, _NONE} if nullable else {str}))
    if annotation is float and before == [fields.check_number] and not after:
        return _number(*bounds(metadata))
    if annotation is int and before == [fields.check_whole] and not after:
        return _whole(*bounds(metadata)[:3])
    if annotation == tuple[fields.Number, fields.Number, fields.Number] and before == [fields.check_triple] \
            and len(after) == 1 and after[0] in _VECTOR_RULES:
        return _vector(_VECTOR_RULES[after[0]])
    if annotation == tuple[fields.Whole, fields.Whole] and before == [fields.check_pair] \
            and after == [fields.segment_range]:
        return _segments
    if annotation == tuple[fields.Number, ...] and not before and len(after) == 1 \
            and isinstance(after[0], fields.Lengths):
        return _lengths(after[0].count)
    return None


def _plan(model) -> dict[str, Check]:
    """The bulk check of each key of a kind's model whose rules are read here (see column_check)."""
    if model.__pydantic_decorators__.model_validators:  # a whole-object rule: pydantic's, an object at a time
        return {}
    plan = {key: check for key, field in model.model_fields.items() if (check := column_check(field)) is not None}
    plan["shape"] = lambda column: (np.ones(len(column), bool), column)  # the group's own shape
    return plan


# Plans for the built kinds; an object read from a file (a mesh) is validated by pydantic's own model.
PLANS = {shape: _plan(model) for shape, model in OBJECT_MODELS.items() if not KINDS[shape].from_file}
_DEFAULTS = {shape: {key: field.default for key, field in OBJECT_MODELS[shape].model_fields.items()}
             for shape in PLANS}


def _build_group(shape: str, keys: tuple, rows: list) -> list:
    """An object of `shape`'s model for each row pydantic would accept (with pydantic's values), None for the
    others."""
    plan, good, values = PLANS[shape], np.ones(len(rows), bool), []
    for key in keys:
        try:
            passed, column = plan[key](list(map(operator.itemgetter(key), rows)))
        except (OverflowError, ValueError, TypeError):  # an int beyond float64, a ragged list: pydantic's
            return [None] * len(rows)
        good &= passed
        values.append(column)
    model, fields_set, defaults = OBJECT_MODELS[shape], set(keys), _DEFAULTS[shape]
    made, new, attribute = [None] * len(rows), model.__new__, object.__setattr__
    chosen = np.flatnonzero(good).tolist()
    columns = values if len(chosen) == len(rows) else [[column[i] for i in chosen] for column in values]
    for index, row in zip(chosen, zip(*columns)):
        values_of = dict(defaults)  # in the fields' order, as pydantic keeps them
        values_of.update(zip(keys, row))
        obj = made[index] = new(model)
        attribute(obj, "__dict__", values_of)
        attribute(obj, "__pydantic_fields_set__", fields_set.copy())
        attribute(obj, "__pydantic_extra__", None)
        attribute(obj, "__pydantic_private__", None)
    return made


def objects_in_bulk(objects: Any) -> Any:
    """`objects` with each object that pydantic would accept already its kind's model (see above); the others,
    and anything that is not a list of tables, as they were, for pydantic to validate and word."""
    if type(objects) not in _SEQUENCE:
        return objects
    groups: dict[tuple, list[int]] = {}
    for index, obj in enumerate(objects):
        if type(obj) is dict and type(shape := obj.get("shape")) is str:
            groups.setdefault((shape, tuple(obj)), []).append(index)
    result = list(objects)
    collecting = gc.isenabled()
    gc.disable()  # a million new objects would start as many collections of a growing heap
    try:
        for (shape, keys), members in groups.items():
            if shape not in PLANS or not PLANS[shape].keys() >= set(keys):
                continue
            for start in range(0, len(members), _ROWS):
                chunk = members[start:start + _ROWS]
                for index, obj in zip(chunk, _build_group(shape, keys, [objects[i] for i in chunk])):
                    if obj is not None:
                        result[index] = obj
    finally:
        if collecting:
            gc.enable()
    return result
