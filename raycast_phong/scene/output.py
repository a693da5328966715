"""Where `render` writes its image: the policy, checked before anything renders.

-o wins; otherwise the scene's output.path, resolved against the scene's folder and never leaving it (a
scene file is data: it may write beside itself or below); the built-in default scene writes its file name
into the working folder. The output must be a writable .png or .exr that is not the input, and layers
(output.aovs) need an .exr.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import ImageError, SceneError
from .schema import Scene


def render_output(scene: Scene, source: Path, given: Path | None, builtin: bool) -> Path | str:
    """The image `render` writes for `scene` read from `source` (`builtin`: the default scene), -o `given` or
    None. Raises SceneError or ImageError, one line naming the source and where the path came from."""
    from ..io.image_io import check_output_path  # OpenImageIO: only once a render is on its way
    option = "--output" if given is not None else "output.path"
    if given is None and not builtin:
        scene.output.check_inside(str(source))  # a scene writes inside its folder; elsewhere only with -o
    output = given if given is not None else (Path(scene.output.path).name if builtin
                                              else scene.resolve(scene.output.path))
    try:
        check_output_path(output, inputs=(source,))
    except ImageError as error:
        raise ImageError(f"{source}: {option}: {error}") from None  # where the path came from: option or scene
    if scene.output.aovs and Path(output).suffix.lower() != ".exr":
        raise SceneError(f"{source}: output.aovs: {list(scene.output.aovs)} need an .exr output, but -o {output} is "
                         "a PNG (a PNG holds only RGB)")
    return output
