"""Any scene file into a Scene: a TOML or JSON scene, or a mesh file (any suffix trimesh reads) made into one.

read_scene_dict gives the table (the file's syntax from io.scene_file, or a mesh file framed by
scene.framing) with the `--set` overrides applied; load_scene validates it. These are the only two.
"""

from __future__ import annotations

from pathlib import Path

from ..codes import SCENE_SUFFIXES
from ..errors import SceneError
from ..io.scene_file import is_stdin, read_scene_file
from ..io.system import count_text, format_bytes, memory_allowed
from ..values.messages import Location
from .framing import mesh_scene_dict
from .overrides import apply_override
from .schema import Scene, validate_scene

# Memory validation takes an object, light or material, the most measured (a box with size, translate, rotate,
# scale, material and shading: 1.25 kB; a point light with its material 0.9 kB each; a bare box 0.7 kB).
VALIDATED_ITEM_BYTES = 1536


def is_mesh_file(path: str | Path) -> bool:
    """Whether `path` names a mesh file rather than a scene file, by its suffix (io.meshes.is_mesh_file). Any
    other is a scene file: TOML, or JSON for .json."""
    suffix = Path(path).suffix.lower()
    if suffix in SCENE_SUFFIXES or not suffix:
        return False  # the common cases (and a name with no suffix, "-", "warm-up") answer without the formats
    from ..io.meshes import is_mesh_file as mesh_suffix
    return mesh_suffix(path)


def read_scene_dict(path: str | Path, overrides: list[str] | tuple[str, ...] = (), view: str | None = None,
                    up: str | None = None, max_memory: int | None = None, sources: dict | None = None) -> dict:
    """The table of a scene file, or of a mesh file made into a scene, with `overrides` applied; reading a
    mesh file to frame it keeps to `max_memory` bytes (a command's --max-memory; None: what the machine has).
    A mesh file's io.meshes.source.MeshSource is put in `sources`, if given."""
    path = Path(path)
    if not is_mesh_file(path):
        if path.suffix.lower() not in SCENE_SUFFIXES:  # a .toml or .json is read as one: no format registry
            from ..io.meshes import unread
            reason = unread(path)
            if reason is not None:  # an FBX, a Blender file: not a scene file to read as TOML
                raise SceneError(reason, Location(str(path)))
        if view is not None or up is not None:
            raise SceneError("--view and --up frame a mesh file; a scene file has its own [camera]",
                             Location(str(path)))
        data = read_scene_file(path, max_memory)
        for assignment in overrides:
            apply_override(data, assignment, source=str(path))
        check_validation_memory(data, path, max_memory)
        return data
    return mesh_scene_dict(path, overrides, view, up, max_memory, sources)


def check_validation_memory(data: dict, path: str | Path, max_memory: int | None) -> None:
    """Refuse (SceneError, one line) a scene table whose validation alone would not fit: VALIDATED_ITEM_BYTES
    for each of its objects, lights and materials, against io.system.memory_allowed(max_memory). Checked before
    validation, which would otherwise grow to its full size before the render's own estimate refuses."""
    items = {key: len(data[key]) for key, kind in (("objects", list), ("lights", list), ("materials", dict))
             if isinstance(data.get(key), kind)}
    need, allowed = sum(items.values()) * VALIDATED_ITEM_BYTES, memory_allowed(max_memory)
    if allowed is not None and need > allowed:
        counted = ", ".join(f"{count_text(count)} {key if count > 1 else key[:-1]}"
                            for key, count in items.items() if count)
        raise SceneError(f"validating its {counted} needs ≈ {format_bytes(need)} of memory, more than the "
                         f"{format_bytes(allowed)} available; allowed: a scene whose objects fit, so use fewer "
                         "or raise the budget (--max-memory)", Location(str(path)))


def load_scene(path: str | Path, overrides: list[str] | tuple[str, ...] = (), view: str | None = None,
               up: str | None = None, max_memory: int | None = None) -> Scene:
    """Read, override and validate a scene file or a mesh file. The scene carries the MeshSource framing made
    (Scene.mesh_sources), which prepare() passes on: the file is not read again.

    Parameters
    ----------
    path: a scene file (.toml, or .json of the same structure), "-" for standard input, or a mesh file (any
        format trimesh reads: one `mesh` object, a framing camera and a key light, docs/meshes.md).
    overrides: `key.path=value` strings, applied before validation as --set applies them.
    view, up: how a mesh file is framed (three_quarter, front, side, top, iso; its up axis "+z", "-y", ...).
    max_memory: bytes (or "8G") a mesh file's framing read may need (render() checks the render's own).

    Returns the validated, frozen Scene. Raises SceneError (one line naming the file, the key path and what is
    allowed) for a file that cannot be read, a value the format refuses or an unknown key.
    """
    path = Path(path)
    folder = Path(".") if is_stdin(path) else path.parent  # a piped scene's paths are the working folder's
    sources: dict = {}
    scene = validate_scene(read_scene_dict(path, overrides, view, up, max_memory, sources), source=str(path),
                           folder=folder)
    scene.mesh_sources.update(sources)
    return scene
