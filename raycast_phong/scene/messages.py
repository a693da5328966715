"""The scene's error messages: one line per problem, in the scene file's words (file, key path, what is
allowed), from pydantic's errors; and how a value or key path is spelled in them.

Nothing here knows the scene's tables: describe_error walks whatever model it is given, so an edit to a
message touches neither the schema nor anything that imports it.
"""

from __future__ import annotations

import difflib
from typing import Any, Literal, get_args, get_origin

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
    return ".".join(str(part) if isinstance(part, int) or _plain(part) else shorten(repr(part)) for part in loc)


def _plain(key: str) -> bool:
    return key.isprintable() and "." not in key and " " not in key and len(key) <= SHOWN_CHARACTERS


def _model_of(annotation: Any) -> tuple[type[BaseModel] | None, bool]:
    """The pydantic model a field's values are, through `X | None`, `tuple[X, ...]`, `Annotated` and
    `dict[str, X]`; and whether a dict key (a material's name) comes before it in a key path."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation, False
    if get_origin(annotation) is dict:
        return _model_of(get_args(annotation)[1])[0], True
    for argument in get_args(annotation):
        found = _model_of(argument)
        if found[0] is not None:
            return found
    return None, False


def _model_at(root: type[BaseModel], loc: tuple) -> type[BaseModel] | None:
    """The pydantic model that holds the key at `loc` below `root` (for suggesting a close valid key)."""
    model: type[BaseModel] | None = root
    keyed = False
    for part in (p for p in loc if not isinstance(p, int)):
        if keyed:  # the name of a [materials.NAME] table
            keyed = False
            continue
        field = model.model_fields.get(str(part)) if model is not None else None
        if field is None:
            return None
        model, keyed = _model_of(field.annotation)
    return None if keyed else model


def describe_error(error: ValidationError, data: dict, source: str, root: type[BaseModel]) -> str:
    """One line for the first problem pydantic found validating `root`: file, key path, what is wrong, what is
    allowed."""
    first = error.errors()[0]
    loc = tuple(part for part in first["loc"] if not (isinstance(part, str) and "[" in part))
    # pydantic names union branches and validator functions in loc; keep only real keys.
    loc = tuple(p for p in loc if isinstance(p, int) or not p.startswith(("function-", "tuple[", "literal[")))
    key = dotted(loc) or "(top level)"
    kind = first["type"]
    if kind == "extra_forbidden":
        owner = _model_at(root, loc[:-1])
        valid = [name for name in (owner.model_fields if owner else {}) if name != "folder"]
        close = difflib.get_close_matches(str(loc[-1]), valid, n=1, cutoff=0.6)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        return f"{source}: {key}: unknown key{hint}; valid keys here: {', '.join(valid)}"
    message = first["msg"]
    if message.startswith("Value error, "):
        message = message[len("Value error, "):]
    # Say pydantic's type errors in the scene file's words (table, list, true/false).
    if kind in ("greater_than_equal", "less_than_equal", "greater_than", "less_than"):
        message = f"out of range; allowed: {_allowed_range(root, loc)}"
    elif message.startswith(("must be a number", "must be a whole number")) and _bounded(root, loc):
        message = f"{message}; allowed: {_allowed_range(root, loc)}"
    elif kind == "int_from_float":
        message = "must be a whole number" + (f"; allowed: {_allowed_range(root, loc)}" if _bounded(root, loc) else "")
    elif kind == "missing":
        choices = _choices(root, loc)
        message = "this key is required" + (f"; allowed: {', '.join(map(repr, choices))}" if choices else "")
    elif kind in ("model_type", "dict_type"):
        message = "must be a table of keys"
    elif kind in ("tuple_type", "list_type"):
        message = (f"must be an array of tables, [[{loc[-1]}]]" if loc and loc[-1] in ("lights", "objects")
                   else "must be a list")
    elif kind == "bool_type":
        message = "must be true or false"
    value = first.get("input")
    got = "" if kind == "missing" or isinstance(value, dict) or "got " in message else f" (got {shown(value)})"
    return f"{source}: {key}: {message}{got}"


def _bounded(root: type[BaseModel], loc: tuple) -> bool:
    return _allowed_range(root, loc) != str(loc[-1])


def _choices(root: type[BaseModel], loc: tuple) -> tuple:
    """The values a Literal key allows ('icosphere', 'box', ...), or () for other keys."""
    owner = _model_at(root, loc[:-1]) if loc else None
    field = owner.model_fields.get(str(loc[-1])) if owner else None
    if field is None or get_origin(field.annotation) is not Literal:
        return ()
    return get_args(field.annotation)


def _allowed_range(root: type[BaseModel], loc: tuple) -> str:
    """'1 ≤ width ≤ 16384' from the field's constraints ('width' alone if it has none)."""
    if not loc:
        return ""
    owner = _model_at(root, loc[:-1])
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
