"""Where `render` writes its image: the policy, checked before anything renders.

-o wins; otherwise the scene's output.path, resolved against the scene's folder and never leaving it (a
scene file is data: it may write beside itself or below); the built-in default scene writes its file name
into the working folder. The output must be a writable .png or .exr that is no file the scene reads (the scene
file, a colour map, a mesh file, a mesh's .mtl or images: Scene.files_read), and layers
(output.aovs) need an .exr. Symbolic links: output.path is checked where it really leads (a linked subfolder
that leaves the scene's folder is refused); `-o LINK` writes the file LINK names and keeps the link.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import ImageError, SceneError
from .schema import Scene


def _check_inside(scene: Scene) -> None:
    """Refuse an output.path that leaves the scene's folder (absolute, ~ or '..'), before it is written to: a
    scene file is data, possibly someone else's; it may write beside itself or below, never over ~/.x.png or
    ../../x.png. An output elsewhere is the user's choice, made with -o."""
    path = Path(scene.output.path)
    if path.is_absolute() or scene.output.path.startswith("~") or ".." in path.parts:
        raise SceneError(f"{scene.output.path!r} leaves the scene's folder (an absolute path, ~ or '..'); give a "
                         "path inside that folder, or choose the output with -o", scene.origin.at("output", "path"))


def _check_real_path(scene: Scene, output: Path) -> None:
    """Refuse an output.path whose real location (every symbolic link followed: a linked subfolder, a
    linked file) leaves the scene's folder, as _check_inside refuses one spelled with '..'."""
    folder = Path(os.path.realpath(scene.folder))
    real = Path(os.path.realpath(output))
    if real != folder and folder not in real.parents:
        raise SceneError(f"{scene.output.path!r} leaves the scene's folder through a symbolic link (it is "
                         f"{str(real)!r}); give a path inside that folder, or choose the output with -o",
                         scene.origin.at("output", "path"))


def render_output(scene: Scene, scene_path: Path, given: Path | None, builtin: bool) -> Path | str:
    """The image `render` writes for `scene` read from `scene_path` (`builtin`: the default scene), -o `given` or
    None; never the scene file itself. Raises SceneError or ImageError, one line naming the scene and where the
    path came from."""
    from ..io.files import check_output_path
    option = "--output" if given is not None else "output.path"
    if given is None and not builtin:
        _check_inside(scene)  # a scene writes inside its folder; elsewhere only with -o
    output = given if given is not None else (Path(scene.output.path).name if builtin
                                              else scene.resolve(scene.output.path))
    if given is None and not builtin:
        _check_real_path(scene, Path(output))
    if scene.mesh_objects():  # each mesh file described once: kept with the scene, prepare() reads them there
        from ..io.meshes.source import mesh_sources, source_key
        for path, source in mesh_sources(scene).items():
            scene.mesh_sources.setdefault(source_key(path), source)
    inputs = (scene_path, *scene.files_read())  # the scene file, its maps, its meshes and what they open
    try:
        check_output_path(output, inputs=inputs)
        if given is not None and Path(given).is_symlink():
            # -o LINK writes the file the link names, as `cp x LINK` or `> LINK` would, and keeps the link
            # (the atomic rename would otherwise replace the link itself with a file).
            output = check_output_path(Path(os.path.realpath(given)), inputs=inputs)
    except ImageError as error:
        raise ImageError(f"{scene.origin}: {option}: {error}") from None  # where the path came from
    if scene.output.aovs and Path(output).suffix.lower() != ".exr":
        raise SceneError(f"{list(scene.output.aovs)} need an .exr output, but -o {output} is a PNG (a PNG holds "
                         "only RGB)", scene.origin.at("output", "aovs"))
    return output
