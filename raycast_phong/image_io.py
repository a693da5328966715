"""The only OpenImageIO importer: write PNG (8-bit) and EXR (float32, with extra layers); read back.

Every write goes to a temporary file in the target folder and is renamed over the target only when
complete, so a failure never leaves a half-written image over a good one.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from .film import to_8bit

LAYER_CHANNELS = {"depth": ("Z",), "normal": ("X", "Y", "Z"), "face": ("id",)}


class ImageError(OSError):
    """An image that cannot be written or read; the message names the path."""


def check_output_path(path: str | Path) -> Path:
    """Refuse, before rendering, an output whose folder is missing or whose format is unknown."""
    path = Path(path)
    if path.suffix.lower() not in (".png", ".exr"):
        got = f"not {path.suffix!r}" if path.suffix else "it has no extension"
        raise ImageError(f"{path}: the output must end in .png (8-bit) or .exr (float32), {got}")
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ImageError(f"{path}: the output folder {str(folder)!r} does not exist; create it or choose an "
                         "existing folder")
    if not os.access(folder, os.W_OK):
        raise ImageError(f"{path}: the output folder {str(folder)!r} is not writable")
    return path


def write_image(path: str | Path, image: np.ndarray, aovs: dict[str, np.ndarray] | None = None,
                srgb: bool = False) -> Path:
    """Write an (H, W, 3) image: .png 8-bit clamped (sRGB-encoded if asked), .exr float32 unclamped.

    `aovs` (EXR only) adds layers as channels `name.R/G/B` (terms), `depth.Z`, `normal.X/Y/Z`, `face.id`.
    """
    path = check_output_path(path)
    aovs = aovs or {}
    if path.suffix.lower() == ".png":
        if aovs:
            raise ImageError(f"{path}: layers {sorted(aovs)} need an .exr output")
        # OpenImageIO's PNG writer needs C order; a strided view (e.g. from read_layer) writes no data.
        pixels, names, fmt = np.ascontiguousarray(to_8bit(image, srgb)), ["R", "G", "B"], oiio.UINT8
    else:
        planes, names = [np.asarray(image, np.float32)], ["R", "G", "B"]
        for name, layer in aovs.items():
            planes.append(np.asarray(layer, np.float32).reshape(image.shape[0], image.shape[1], -1))
            names += [f"{name}.{c}" for c in LAYER_CHANNELS.get(name, ("R", "G", "B"))]
        pixels, fmt = np.ascontiguousarray(np.concatenate(planes, axis=2)), oiio.FLOAT
    height, width, channels = pixels.shape
    spec = oiio.ImageSpec(width, height, channels, fmt)
    spec.channelnames = tuple(names)
    if path.suffix.lower() == ".exr":
        spec.attribute("compression", "zip")
    descriptor, temporary = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=path.suffix, dir=path.parent or ".")
    os.close(descriptor)
    try:
        output = oiio.ImageOutput.create(temporary)
        if output is None or not output.open(temporary, spec):
            raise ImageError(f"{path}: cannot write ({oiio.geterror() or 'no writer'})")
        ok = output.write_image(pixels)
        output.close()
        if not ok:
            raise ImageError(f"{path}: cannot write ({oiio.geterror()})")
        # mkstemp creates the file 0600; give the image the permissions a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)
        os.replace(temporary, path)
    finally:
        if os.path.exists(temporary):
            os.unlink(temporary)
    return path


def read_image(path: str | Path) -> tuple[np.ndarray, tuple[str, ...]]:
    """All channels of an image as (H, W, C) float32 (8-bit files scaled to [0, 1]) and their names."""
    buffer = oiio.ImageBuf(str(path))
    if buffer.has_error:
        raise ImageError(f"{path}: cannot read ({buffer.geterror()})")
    pixels = buffer.get_pixels(oiio.FLOAT)
    if pixels is None or pixels.size == 0:
        raise ImageError(f"{path}: cannot read ({buffer.geterror()})")
    return np.asarray(pixels, np.float32), tuple(buffer.spec().channelnames)


def read_layer(path: str | Path, layer: str | None = None) -> np.ndarray:
    """The RGB image (layer None) or one named layer of a file written by write_image."""
    pixels, names = read_image(path)
    if layer is None:
        wanted = ["R", "G", "B"]
    else:
        wanted = [n for n in names if n.startswith(layer + ".")]
    if not wanted or any(name not in names for name in wanted):
        raise ImageError(f"{path}: no layer {layer or 'RGB'!r}; channels are {', '.join(names)}")
    return pixels[:, :, [names.index(name) for name in wanted]]
