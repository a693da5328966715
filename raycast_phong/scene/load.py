"""Any scene file into a Scene: a TOML or JSON scene, or a mesh file (any suffix trimesh reads) made into one.

read_scene_dict gives the table (the file's syntax from io.scene_file, or a mesh file framed by
scene.framing) with the `--set` overrides applied; load_scene validates it. These are the only two.
"""

from __future__ import annotations

from pathlib import Path

from ..codes import SCENE_SUFFIXES
from ..errors import SceneError
from ..io.scene_file import is_stdin, read_scene_file
from .framing import mesh_scene_dict
from .messages import Location
from .overrides import apply_override
from .schema import Scene, validate_scene


def is_mesh_file(path: str | Path) -> bool:
    """Whether `path` names a mesh file rather than a scene file, by its suffix: one trimesh reads (.obj,
    .ply, .stl, .off, .glb, .gltf, ...). Any other is a scene file: TOML, or JSON for .json."""
    suffix = Path(path).suffix.lower()
    if suffix in SCENE_SUFFIXES or not suffix:
        return False  # the common case answers without importing trimesh
    import trimesh
    return suffix[1:] in trimesh.available_formats()


def read_scene_dict(path: str | Path, overrides: list[str] | tuple[str, ...] = (), view: str | None = None,
                    up: str | None = None, max_memory: int | None = None, sources: dict | None = None) -> dict:
    """The table of a scene file, or of a mesh file made into a scene, with `overrides` applied; reading a
    mesh file to frame it keeps to `max_memory` bytes (a command's --max-memory; None: what the machine has).
    A mesh file's io.mesh_source.MeshSource is put in `sources`, if given."""
    path = Path(path)
    if not is_mesh_file(path):
        if view is not None or up is not None:
            raise SceneError("--view and --up frame a mesh file; a scene file has its own [camera]",
                             Location(str(path)))
        data = read_scene_file(path)
        for assignment in overrides:
            apply_override(data, assignment, source=str(path))
        return data
    return mesh_scene_dict(path, overrides, view, up, max_memory, sources)


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
