"""`--set KEY.PATH=VALUE`: one assignment applied to a parsed scene table, before validation.

The value is read as TOML (so 320, "flat", [1, 2, 3] and true mean what they mean in a scene file), else
kept as a plain string; list items are addressed by index. The same rule serves --set, --vary, sweep files
and the live view.
"""

from __future__ import annotations

import dataclasses
import tomllib
from typing import TYPE_CHECKING

from ..codes import ShadingModel
from ..errors import SceneError
from ..io.scene_file import syntax_limit
from ..values.messages import Location, located, shorten
from .keypaths import assign, key_parts

if TYPE_CHECKING:
    from .schema import Scene


# What `render --srgb` and `batch --srgb` stand for: maps decoded from sRGB and the PNG encoded, as "linear" does.
SRGB_OVERRIDE = "render.colour=linear"
# An assignment without its '=' (`--set render.width 320`: the shell's space is not one), said by apply_override
# and, while the command line is parsed, before the 320 is taken for the scene file, by the CLI.
NO_EQUALS = ("expected KEY.PATH=VALUE, e.g. render.width=320 or lights.0.position=[1, 2, 3] (the value after '=', "
             "not after a space)")


def apply_override(data: dict, assignment: str, source: str | Location = "--set", option: str = "--set") -> None:
    """Set `key.path=value` in a parsed scene; the value is read as TOML, else as a plain string.

    List items are addressed by index: `lights.0.position=[1, 2, 3]`, `objects.1.shading=flat`.
    `option` names the command-line option the assignment came from in error messages (--set, --vary).
    """
    where = dataclasses.replace(located(source), part=f"{option} {shorten(repr(assignment))}")
    if "=" not in assignment:
        raise SceneError(NO_EQUALS, where)
    key, text = (part.strip() for part in assignment.split("=", 1))
    key_parts(key, where)  # a bad key is said before a bad value
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        value = text
    except (RecursionError, ValueError) as error:
        raise SceneError(syntax_limit(error), where) from None
    assign(data, key, value, where)


def shaded(scene: Scene, model: ShadingModel) -> Scene:
    """The scene with every object in `model`: render.shading and each object's own `shading` (an object's
    own choice wins over render.shading, and the default figure gives each sphere its own). The lecture's
    flat | Gouraud | Phong figure renders these (notebooks' show(), the view's three-model page)."""
    objects = type(scene.objects)(obj.model_copy(update={"shading": model}) for obj in scene.objects)
    return scene.model_copy(update={"render": scene.render.model_copy(update={"shading": model}),
                                    "objects": objects})
