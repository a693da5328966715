"""A scene table's key paths (`render.width`, `lights.0.position`): names and list indices joined by dots, as
`--set`, `--vary`, sweep files, the live view and Scene.replace address a key. One walk for all of them."""

from __future__ import annotations

from typing import Any

from ..errors import SceneError
from ..values.messages import Location, shown


def key_parts(key: str, where: Location) -> list[str]:
    """The names and indices of the key path `key`; SceneError at `where` when it is not one."""
    parts = key.split(".")
    if not all(parts):
        raise SceneError(f"{key!r} is not a key path; expected names and list indices joined by dots, "
                         "e.g. render.width", where)
    return parts


def assign(data: dict, key: str, value: Any, where: Location) -> None:
    """Set the key path `key` (names and list indices joined by dots) of a parsed scene to `value`; SceneError
    at `where` (or the key below it) for a path that is not one. Tables on the way are made; list items must
    exist."""
    parts = key_parts(key, where)
    node: Any = data
    for depth, part in enumerate(parts):
        node_path = ".".join(parts[:depth]) or "(top level)"
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                allowed = f"0 to {len(node) - 1}" if node else "none, the list is empty"
                raise SceneError(f"{node_path} is a list of {len(node)} item{'s' if len(node) != 1 else ''}; "
                                 f"allowed indices: {allowed}", where.at(*parts[:depth + 1]))
            index: Any = int(part)
        elif isinstance(node, dict):
            index = part
        else:
            raise SceneError(f"{node_path} is the value {shown(node)}, not a table, so it has no key "
                             f"{part!r}", where)
        if depth == len(parts) - 1:
            node[index] = value
        elif isinstance(node, dict) and part not in node:
            node = node.setdefault(part, [] if parts[depth + 1].isdigit() else {})
        else:
            node = node[index]
