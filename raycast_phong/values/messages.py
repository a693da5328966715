"""The scene's error messages: one line per problem, in the scene file's words (file, key path, what is
allowed), from pydantic's errors; how a value or key path is spelled in them; and where a problem is
(`Location`, the record every SceneError carries, worded here alone).

Nothing here knows the scene's tables: describe_error walks whatever model it is given, so an edit to a
message touches neither the schema nor anything that imports it.
"""

from __future__ import annotations

import dataclasses
import difflib
import re
from dataclasses import dataclass
from numbers import Integral  # an index from numpy (int64) as well
from typing import Annotated, Any, Literal, get_args, get_origin

from pydantic import BaseModel, ValidationError

SHOWN_CHARACTERS = 80  # a value echoed in a message: enough to recognise it, never a megabyte of it


def shorten(text: str, limit: int = SHOWN_CHARACTERS) -> str:
    """`text` cut to `limit` characters with how much was left out: a message stays one short line."""
    return text if len(text) <= limit else f"{text[:limit]}… ({len(text) - limit:,} more characters)"


def shown(value: Any) -> str:
    """A value as the scene file spells it, cut to SHOWN_CHARACTERS: the string '32', true, [1, 2]."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f"the string {shorten(repr(value))}"
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, (tuple, list)):
        head = repr(list(value[:SHOWN_CHARACTERS // 2]))
        return shorten(head if len(value) <= SHOWN_CHARACTERS // 2 else f"{head[:-1]}, …]")
    return shorten(repr(value))


def dotted(loc: tuple) -> str:
    """("lights", 0, "position") → lights.0.position; a key with a control character, a dot or a space is
    quoted with its escapes shown (a bell or a newline in a key must not reach the terminal raw)."""
    return ".".join(str(part) if isinstance(part, Integral) or _plain(part) else shorten(repr(part)) for part in loc)


@dataclass(frozen=True)
class Location:
    """Where a problem is, as each message starts: the file (a scene or mesh file, "<scene>", "stdin"), what in it
    when that is no key (a --set assignment, a line), and the key path. A SceneError carries it (errors.py) and
    words it with str(), so a line is put together here alone: `scene.toml: objects.3.radius: ...`."""
    file: str
    key: tuple = ()
    part: str = ""  # "--set 'render.width=x'", "line 3": said between the file and the key path

    def at(self, *key: str | int) -> Location:
        """The location of a key below this one."""
        return dataclasses.replace(self, key=(*self.key, *key))

    def __str__(self) -> str:
        return ": ".join(text for text in (self.file, self.part, dotted(self.key)) if text)


def located(source: str | Location) -> Location:
    """`source` as a Location: a file's name (or "<scene>") from a caller, or a location already."""
    return source if isinstance(source, Location) else Location(str(source))


def _plain(key: str) -> bool:
    return key.isprintable() and "." not in key and " " not in key and len(key) <= SHOWN_CHARACTERS


@dataclass(frozen=True)
class _Union:
    """A list of tables of several kinds, each kind one model, told apart by the value of one key (pydantic's
    discriminated union: [[objects]] by `shape`)."""
    noun: str                              # what one table is: "object" for [[objects]]
    key: str                               # the key whose value names the kind: "shape"
    models: dict[str, type[BaseModel]]     # kind → its model, in the schema's order


@dataclass(frozen=True)
class _Place:
    """Where a pydantic error location leads in the models: its key path in the file's words (pydantic's union
    tags left out), the model holding its last key, and the union and kind that model is one of."""
    loc: tuple
    owner: type[BaseModel] | None
    union: _Union | None = None
    kind: str | None = None

    @property
    def field(self) -> Any:
        return self.owner.model_fields.get(str(self.loc[-1])) if self.owner is not None and self.loc else None


def _model_of(annotation: Any, name: str = "") -> tuple[type[BaseModel] | _Union | None, bool]:
    """The pydantic model (or union of models) a field's values are, through `X | None`, `tuple[X, ...]`,
    `Annotated` and `dict[str, X]`; and whether a dict key (a material's name) comes before it in a key path."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation, False
    if get_origin(annotation) is dict:
        return _model_of(get_args(annotation)[1], name)[0], True
    if get_origin(annotation) is Annotated:
        key = next((getattr(item, "discriminator", None) for item in get_args(annotation)[1:]
                    if isinstance(getattr(item, "discriminator", None), str)), None)
        if key is not None:
            models = get_args(get_args(annotation)[0])
            return _Union(name.removesuffix("s"), key, {get_args(model.model_fields[key].annotation)[0]: model
                                                         for model in models}), False
    for argument in get_args(annotation):
        found = _model_of(argument, name)
        if found[0] is not None:
            return found
    return None, False


def _place(root: type[BaseModel], loc: tuple) -> _Place:
    """Follow `loc` from `root` through the models (see _Place)."""
    path: list = []
    model: type[BaseModel] | _Union | None = root
    owner, keyed = None, False
    branch: tuple = (None, None)  # the union and kind `model` is one of
    owner_branch: tuple = (None, None)
    for part in loc:
        if isinstance(part, int) or keyed:  # a list index, or the name of a [materials.NAME] table
            keyed = False
            path.append(part)
            continue
        if isinstance(model, _Union):
            if part in model.models:  # the kind pydantic puts in the path after the index: not a key of the file
                branch, model = (model, part), model.models[part]
                continue
            model = None
        owner, owner_branch = model, branch
        path.append(part)
        field = model.model_fields.get(str(part)) if model is not None else None
        model, keyed = _model_of(field.annotation, str(part)) if field is not None else (None, False)
        branch = (None, None)
    if isinstance(model, _Union):  # the path ends at a table of the union: its kind could not be told
        return _Place(tuple(path), None, model, None)
    return _Place(tuple(path), owner, *owner_branch)


def describe_error(error: ValidationError, where: Location, root: type[BaseModel]) -> tuple[Location, str]:
    """Where the first problem pydantic found validating `root` is (below `where`, the file) and what it is: what
    is wrong, what is allowed."""
    first = error.errors()[0]
    # An unknown key ends its loc as the file spells it, brackets and all ("a[0]" is a valid quoted TOML key):
    # kept, not taken for one of the names pydantic gives union branches (an empty loc has no last key).
    raw = tuple(first["loc"])
    unknown = raw[-1:] if first["type"] == "extra_forbidden" else ()
    loc = tuple(part for part in raw[:len(raw) - len(unknown)] if not (isinstance(part, str) and "[" in part))
    # pydantic names union branches and validator functions in loc; keep only real keys.
    loc = tuple(p for p in loc if isinstance(p, int) or not p.startswith(("function-", "tuple[", "literal[")))
    loc += unknown
    place = _place(root, loc)
    kind = first["type"]
    value = first.get("input")
    if kind in ("union_tag_not_found", "union_tag_invalid") and place.union is not None:
        return where.at(*place.loc, place.union.key), _kind_error(place, kind, value)
    at = where.at(*place.loc) if place.loc else dataclasses.replace(where, part="(top level)")
    if kind == "extra_forbidden":
        valid = [name for name in (place.owner.model_fields if place.owner else {}) if name != "folder"]
        foreign = _foreign(place, str(loc[-1])) if loc else None
        if foreign:
            return at, foreign
        return at, f"unknown key{did_you_mean(str(loc[-1]), valid)}; valid keys here: {', '.join(valid)}"
    message = first["msg"].removeprefix("Value error, ")
    # Say pydantic's type errors in the scene file's words (table, list, true/false).
    if kind in ("greater_than_equal", "less_than_equal", "greater_than", "less_than"):
        message = f"out of range; allowed: {_allowed_range(place)}"
    elif message.startswith(("must be a number", "must be a whole number")) and _bounded(place):
        message = f"{message}; allowed: {_allowed_range(place)}"
    elif kind == "int_from_float":
        message = "must be a whole number" + (f"; allowed: {_allowed_range(place)}" if _bounded(place) else "")
    elif kind == "missing":
        choices = _choices(place)
        message = "this key is required" + (f"; allowed: {', '.join(map(repr, choices))}" if choices else "")
    elif kind in ("model_type", "dict_type", "model_attributes_type"):
        message = "must be a table of keys"
    elif kind in ("tuple_type", "list_type"):
        message = (f"must be an array of tables, [[{loc[-1]}]]" if loc and loc[-1] in ("lights", "objects")
                   else "must be a list")
    elif kind == "bool_type":
        message = "must be true or false"
    guess = ""
    if kind in ("enum", "literal_error") and isinstance(value, str):  # a mistyped choice: the closest offered
        guess = did_you_mean(value, re.findall(r"'([^']*)'", str((first.get("ctx") or {}).get("expected", ""))))
    said = "got " in message or (isinstance(value, str) and f'"{value}"' in message)  # the value is in the message
    got = "" if kind == "missing" or isinstance(value, dict) or said else f" (got {shown(value)})"
    return at, f"{message}{got}{guess}"


def _kind_error(place: _Place, kind: str, value: Any) -> str:
    """A table of a union whose kind key is missing or names no kind: what that key allows."""
    union = place.union
    if kind == "union_tag_not_found" or not isinstance(value, dict) or union.key not in value:
        return f"this key is required; allowed: {', '.join(map(repr, union.models))}"
    *rest, last = map(repr, union.models)
    return f"Input should be {', '.join(rest)} or {last} (got {shown(value[union.key])})"


def _foreign(place: _Place, key: str) -> str | None:
    """For a key the table's own kind does not read but another kind does: what it is wrong about."""
    union, kind = place.union, place.kind
    if union is None or key in union.models[kind].model_fields:
        return None
    readers = [name for name, model in union.models.items() if key in model.model_fields]
    if not readers:
        return None
    common = set.intersection(*(set(model.model_fields) for model in union.models.values()))  # every kind's keys
    own = [key for key in union.models[kind].model_fields if key not in common]  # the keys `kind` alone reads
    reads = f"reads {', '.join(own)} besides the keys" if own else "reads only the keys"
    article = "an" if kind[:1] in "aeiou" else "a"
    return (f'does not apply to {union.key} = "{kind}" ({key} is a key of {_listed(readers)}); {article} {kind} '
            f"{reads} of every {union.noun}; remove it")


def _listed(names: list[str]) -> str:
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


def _bounded(place: _Place) -> bool:
    return _allowed_range(place) != str(place.loc[-1])


def _choices(place: _Place) -> tuple:
    """The values a Literal key allows ('perspective', 'orthographic'), or () for other keys."""
    field = place.field
    if field is None or get_origin(field.annotation) is not Literal:
        return ()
    return get_args(field.annotation)


def _allowed_range(place: _Place) -> str:
    """'1 ≤ width ≤ 16384' from the field's constraints ('width' alone if it has none)."""
    if not place.loc:
        return ""
    field = place.field
    low = high = None
    for item in (field.metadata if field else ()):
        for name, symbol in (("ge", "≤"), ("gt", "<")):
            if getattr(item, name, None) is not None:
                low = f"{getattr(item, name)} {symbol} "
        for name, symbol in (("le", "≤"), ("lt", "<")):
            if getattr(item, name, None) is not None:
                high = f" {symbol} {getattr(item, name)}"
    return f"{low or ''}{place.loc[-1]}{high or ''}"


def did_you_mean(given: str, choices, cutoff: float = 0.6) -> str:
    """" (did you mean 'NAME'?)" for the choice closest to `given` (difflib, at least `cutoff` alike), else ""."""
    close = difflib.get_close_matches(given, list(choices), n=1, cutoff=cutoff)
    return f" (did you mean {close[0]!r}?)" if close else ""
