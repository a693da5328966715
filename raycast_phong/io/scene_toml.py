"""The scene writer: a validated Scene as a TOML scene file (`raycast-phong scene`, the view's "Save scene"),
and one value as TOML text for a `--set KEY=VALUE` override (sweeps, the view's settings).

The file is written by tomli-w and reads as a hand-written scene does: the header's comment lines,
`ambient`, [render], [camera], one [[lights]] per light, [materials.NAME], one [[objects]] per object,
[output]. Every file the scene names (Scene.named_files: meshes and texture maps) is rebased to the folder
the file is written to; output.path is the render's output relative to the scene file, wherever that is,
and is written as it is.
"""

from __future__ import annotations

import os
import re
from contextlib import suppress
from pathlib import Path
from typing import Any

import tomli_w

from ..codes import OUTPUT_PATH

VIEW_HEADER = "# Saved by `raycast-phong view`; render it with `raycast-phong render THIS.toml`."
SECTIONS = ("ambient", "render", "camera", "lights", "materials", "objects", "output")  # in the file's order


def toml_value(value: Any) -> str:
    """A value as one line of TOML text, as apply_override reads it: "flat", 8, 0.5, true, [1, 0, 0],
    {path = "a.png", wrap = "clamp"}. A sweep's file names are made from this text, so it stays one line.

    tomli-w writes it, as the item of an array in an array (where a table is written inline, not as [[v]]); its
    line breaks all fall between items (a string's own newlines are escaped), so joining them gives the same
    value on one line."""
    text = tomli_w.dumps({"v": [[value]]}, indent=0)[len("v = [\n[\n"):-len(",\n],\n]\n")]
    return text.replace("[\n", "[").replace(",\n]", "]").replace(",\n", ", ")


def _without_none(value: Any) -> Any:
    """An unset key (None: "decide from the file", such as a mesh's normals) is not written; TOML has no null."""
    if isinstance(value, dict):
        return {k: _without_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_without_none(item) for item in value]
    return value


def rebased(path: Path, relative_to: Path | None) -> str:
    """An absolute file path written relative to the folder `relative_to` (absolute when that is None, or
    when no relative path leads there, as across Windows drives)."""
    if relative_to is not None:
        with suppress(ValueError):
            return os.path.relpath(path, relative_to.resolve())
    return str(path)


def scene_data(scene, relative_to: Path | None = None) -> dict:
    """The scene as the data of its TOML file: every key with its value (defaults too, so the file does not
    depend on later defaults; an unset key stays unset) and every named file rebased to `relative_to`."""
    data = scene.data(mode="json")
    for key, path in scene.named_files().items():
        if key != OUTPUT_PATH:  # relative to the scene file's own folder, wherever the file goes
            container = data
            for part in key[:-1]:  # the key path walks the dumped tables and lists as it walked the scene's
                container = container[part]
            container[key[-1]] = rebased(scene.resolve(path).resolve(), relative_to)
    return _without_none(data)


# tomli-w writes every non-empty array one item a line. An array of plain items (numbers, booleans, strings: a
# string never holds a raw newline here, tomli-w escapes it) is put back on one line, as a scene is written by
# hand: `position = [0.0, 0.0, 4.0]`. Only whitespace inside the brackets changes, which TOML ignores.
_ITEM = r'(?:[\w.+-]+|"(?:[^"\\\n]|\\.)*")'
_PLAIN_ARRAY = re.compile(rf"\[\n((?: +{_ITEM},\n)+) *\]")


def _one_line(match: re.Match) -> str:
    return "[" + ", ".join(item.strip().removesuffix(",") for item in match.group(1).splitlines()) + "]"


def scene_toml(scene, header: str = VIEW_HEADER, relative_to: Path | None = None) -> str:
    """The validated scene as a scene file that load_scene reads back to the same Scene.

    Every key is written with its value (defaults too; an unset key that means "decide from the file", such as
    a mesh's `normals`, stays unset). Every file the scene names (meshes, texture maps) is written relative to
    the folder `relative_to` the file goes to, or absolute when that is not known. tomli-w lays the tables out:
    `ambient`, [render], [camera], [[lights]], [materials.NAME] (a texture map as [materials.NAME.kd_map]),
    [[objects]], [output]; the header's lines come first as comments.
    """
    data = scene_data(scene, relative_to)
    ordered = {key: data.pop(key) for key in SECTIONS if key in data} | data
    body = _PLAIN_ARRAY.sub(_one_line, tomli_w.dumps(ordered))
    comment = "".join(line if line.startswith("#") else f"# {line}" for line in header.splitlines(keepends=True))
    return (comment.rstrip("\n") + "\n\n" if comment else "") + body
