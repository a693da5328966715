"""`--set KEY.PATH=VALUE`: one assignment applied to a parsed scene table, before validation.

The value is read as TOML (so 320, "flat", [1, 2, 3] and true mean what they mean in a scene file), else
kept as a plain string; list items are addressed by index. The same rule serves --set, --vary, sweep files
and the live view.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ..codes import ShadingModel
from ..errors import SceneError
from ..io.scene_file import syntax_limit
from .messages import dotted, shorten, shown

if TYPE_CHECKING:
    from .schema import Scene

# What `render --srgb` and `batch --srgb` stand for: they predate render.colour, and decoded the maps and encoded
# the PNG, which is what "linear" does.
SRGB_OVERRIDE = "render.colour=linear"


def apply_override(data: dict, assignment: str, source: str = "--set", option: str = "--set") -> None:
    """Set `key.path=value` in a parsed scene; the value is read as TOML, else as a plain string.

    List items are addressed by index: `lights.0.position=[1, 2, 3]`, `objects.1.shading=flat`.
    `option` names the command-line option the assignment came from in error messages (--set, --vary).
    """
    where = f"{source}: {option} {shorten(repr(assignment))}"
    if "=" not in assignment:
        raise SceneError(f"{where}: expected KEY.PATH=VALUE, e.g. render.width=320 or lights.0.position=[1, 2, 3]")
    key, text = (part.strip() for part in assignment.split("=", 1))
    key_parts(key, where)  # a bad key is said before a bad value
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        value = text
    except (RecursionError, ValueError) as error:
        raise SceneError(f"{where}: {syntax_limit(error)}") from None
    assign(data, key, value, where)


def key_parts(key: str, where: str) -> list[str]:
    """The names and indices of the key path `key`; SceneError "{where}: ..." when it is not one."""
    parts = key.split(".")
    if not all(parts):
        raise SceneError(f"{where}: {key!r} is not a key path; expected names and list indices joined by dots, "
                         "e.g. render.width")
    return parts


def assign(data: dict, key: str, value: Any, where: str) -> None:
    """Set the key path `key` (names and list indices joined by dots) of a parsed scene to `value`; SceneError
    "{where}: ..." for a path that is not one. Tables on the way are made; list items must exist."""
    parts = key_parts(key, where)
    node: Any = data
    for depth, part in enumerate(parts):
        node_path = ".".join(parts[:depth]) or "(top level)"
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                allowed = f"0 to {len(node) - 1}" if node else "none, the list is empty"
                raise SceneError(f"{where}: {dotted(parts[:depth + 1])}: {node_path} is a list of {len(node)} "
                                 f"item{'s' if len(node) != 1 else ''}; allowed indices: {allowed}")
            index: Any = int(part)
        elif isinstance(node, dict):
            index = part
        else:
            raise SceneError(f"{where}: {node_path} is the value {shown(node)}, not a table, so it has no key "
                             f"{part!r}")
        if depth == len(parts) - 1:
            node[index] = value
        elif isinstance(node, dict) and part not in node:
            node = node.setdefault(part, [] if parts[depth + 1].isdigit() else {})
        else:
            node = node[index]


def replaced(scene: Scene, changes: Mapping[str, Any], source: str = "Scene.replace") -> Scene:
    """`scene` with `changes` (key path → Python value) applied and validated again, in the scene's folder, so
    its relative files (meshes, maps) still resolve: Scene.replace."""
    from .schema import validate_scene
    data = scene.model_dump(mode="json", exclude={"folder"}, exclude_none=True)
    for key, value in changes.items():
        if not isinstance(key, str):
            raise SceneError(f"{source}: {shown(key)} is not a key path; expected a string such as 'render.width'")
        assign(data, key, value, f"{source}({key!r})")
    return validate_scene(data, source=source, folder=scene.folder)


def shaded(scene: Scene, model: ShadingModel) -> Scene:
    """The scene with every object in `model`: render.shading and each object's own `shading` (an object's
    own choice wins over render.shading, and the default figure gives each sphere its own). The lecture's
    flat | Gouraud | Phong figure renders these (notebooks' show(), the view's three-model page)."""
    objects = type(scene.objects)(obj.model_copy(update={"shading": model}) for obj in scene.objects)
    return scene.model_copy(update={"render": scene.render.model_copy(update={"shading": model}),
                                    "objects": objects})
