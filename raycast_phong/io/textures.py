"""Colour maps decoded into float32 RGB, as the scene's render.colour asks, and their sizes read from headers
for the memory estimate.

A texture file (an .mtl's map_Kd, a scene's kd_map) is decoded with OpenImageIO; a glTF's embedded image
arrives as the PIL image trimesh opened lazily (not yet decoded) and is decoded here, only when a material
of a face uses it. An 8-bit colour map holds sRGB-encoded values (glTF 2.0 §3.9.2 says so for baseColor and
emissive textures; .mtl colour maps and PNGs are so by convention): render.colour = "display" uses them as
stored (value / 255, as fixed-function GL does), "linear" decodes them to linear values (glTF's pipeline).
Float images (EXR, HDR) hold linear values and are used as stored in both (clamped to [0, 1]). A map larger
than MAX_TEXTURE_SIZE on a side is shrunk to it (a box filter): no picture of this renderer shows more texels
than that, and the memory stays bounded.
"""

from __future__ import annotations

import warnings
from contextlib import suppress
from pathlib import Path

import numpy as np

from ..errors import SceneError, Where
from .encoding import LINEAR
from .files import image_suffix_mismatch, native_errors_kept, open_regular, shown_name

MAX_TEXTURE_SIZE = 2048
# Bytes per texel of level 0 while a texture is in use: the decoded float32 RGB kept in the Geometry (12), the
# mip pyramid's float32 texels (12 × 4/3 = 16), and the float64 2 × 2 block means of one level as it is made (24).
TEXTURE_BYTES_PER_TEXEL = 52


def srgb_to_linear(values: np.ndarray) -> np.ndarray:
    """The sRGB transfer function's inverse (IEC 61966-2-1) on values in [0, 1]: 188/255 → 0.5029."""
    values = np.asarray(values, np.float64)
    return np.where(values <= 0.04045, values / 12.92, ((values + 0.055) / 1.055) ** 2.4)


def capped(height: int, width: int) -> tuple[int, int]:
    """The size a map is decoded at: its own, or shrunk (aspect kept) to MAX_TEXTURE_SIZE on its longer side."""
    longest = max(height, width)
    if longest <= MAX_TEXTURE_SIZE:
        return height, width
    scale = MAX_TEXTURE_SIZE / longest
    return max(1, round(height * scale)), max(1, round(width * scale))


def _rgb(pixels: np.ndarray, channel: str = "rgb") -> np.ndarray:
    """(H, W, C) → (H, W, 3): grey repeated, alpha dropped; for channel "alpha" the alpha channel repeated (the
    last of 2 or 4 channels; 1 where the image has none)."""
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if channel == "alpha":
        alpha = pixels[:, :, -1:] if pixels.shape[2] in (2, 4) else np.ones_like(pixels[:, :, :1])
        return np.repeat(alpha, 3, axis=2)
    if pixels.shape[2] < 3:
        pixels = np.repeat(pixels[:, :, :1], 3, axis=2)
    return pixels[:, :, :3]


DECODE_BAND_BYTES = 32 << 20  # a larger map is read and shrunk a band of rows at a time: its peak stays this


def decode_file(path: Path, colour: str, channel: str = "rgb") -> np.ndarray:
    """(H, W, 3) float32 RGB in [0, 1] of an image file for a render in `colour` (an 8-bit image decoded from
    sRGB for "linear", as stored for "display"; a float image as stored); ValueError when it is not an image
    OpenImageIO reads. A map multiplies a coefficient in [0, 1], so a float image's texels are clamped to
    [0, 1] too (NaN and −inf to 0, +inf to 1): a NaN, infinite or negative texel would otherwise make such
    pixels of the image.

    A map larger than MAX_TEXTURE_SIZE is shrunk while it is read, a band of rows at a time (each texel of the
    result the mean of the source texels it covers), so decoding a 12000² PNG costs a band, not the 1.7 GB of
    its float texels at full size: the memory estimate counts the shrunk map only."""
    import OpenImageIO as oiio

    from .image_io import colour_as_stored
    with native_errors_kept():  # libpng prints its own "libpng error: ..." line; the caller words one line
        found = oiio.ImageInput.open(str(path), colour_as_stored())  # as PIL decodes the same image in a GLB
        if found is None:
            raise ValueError(oiio.geterror() or "not an image")
        try:
            spec = found.spec()
            if spec.width <= 0 or spec.height <= 0 or spec.nchannels <= 0:
                raise ValueError("not an image")
            height, width = capped(spec.height, spec.width)
            pixels = _read_shrunk(found, spec, height, width)
        finally:
            found.close()
    pixels = _rgb(pixels, channel)
    floats = spec.format.basetype in (oiio.HALF, oiio.FLOAT, oiio.DOUBLE) or channel == "alpha"  # alpha is linear
    out = np.empty(pixels.shape, np.float32)
    step = max(1, (DECODE_BAND_BYTES >> 6) // max(1, pixels.shape[1] * 3))  # float64 temporaries of a band
    for row in range(0, len(pixels), step):  # a band at a time: the curve's float64 temporaries stay small
        band = pixels[row:row + step]
        if floats:
            out[row:row + step] = np.clip(np.nan_to_num(band, nan=0.0, posinf=1.0, neginf=0.0), 0, 1)
        else:
            out[row:row + step] = srgb_to_linear(np.clip(band, 0, 1)) if colour == LINEAR else np.clip(band, 0, 1)
    return out


def _read_shrunk(found, spec, height: int, width: int) -> np.ndarray:
    """(height, width, channels) float32 of an open image: read whole if that is its size, else a band of source
    rows at a time, each band averaged into the result's rows and columns it covers (box filter)."""
    import OpenImageIO as oiio

    eight_bit = spec.format.basetype == oiio.UINT8  # read as stored: a band of bytes is a quarter of its floats
    scale = 1.0 / 255.0 if eight_bit else 1.0

    def rows(begin: int, end: int) -> np.ndarray:
        band = found.read_scanlines(0, 0, begin, end, 0, 0, spec.nchannels, oiio.UINT8 if eight_bit else oiio.FLOAT)
        if band is None or found.has_error:
            raise ValueError(found.geterror() or "cannot decode")
        return np.asarray(band).reshape(end - begin, spec.width, spec.nchannels)

    if (height, width) == (spec.height, spec.width):
        return rows(0, spec.height).astype(np.float32) * np.float32(scale)

    row_edges = np.linspace(0, spec.height, height + 1).round().astype(np.int64)
    column_edges = np.linspace(0, spec.width, width + 1).round().astype(np.int64)
    columns = np.diff(column_edges)
    per_row = max(1, int(np.diff(row_edges).max()))
    band_rows = max(1, DECODE_BAND_BYTES // (8 * spec.width * spec.nchannels * per_row))  # result rows a band
    out = np.empty((height, width, spec.nchannels), np.float32)
    for first in range(0, height, band_rows):
        last = min(height, first + band_rows)
        band = rows(int(row_edges[first]), int(row_edges[last]))
        # The rows first, each result row the sum of its source rows taken whole (8-bit sums exact in uint32), then
        # the columns of the fewer rows: the columns first summed across the rows' stride, and numpy's reduceat
        # over rows converts element by element; this is 9x less CPU (a 12000² PNG shrunk to 2048²: 1.8 s of 3.4).
        edges = row_edges[first:last + 1] - row_edges[first]
        down = np.empty((last - first, spec.width, spec.nchannels), np.uint32 if eight_bit else np.float64)
        for k in range(last - first):
            np.sum(band[edges[k]:edges[k + 1]], axis=0, dtype=down.dtype, out=down[k])
        sums = np.add.reduceat(down, column_edges[:-1], axis=1, dtype=np.float64)
        counts = np.diff(edges)[:, None, None] * columns[None, :, None]
        out[first:last] = sums * (scale / counts)
    return out


def decode_pil(image, colour: str, channel: str = "rgb") -> np.ndarray:
    """(H, W, 3) float32 RGB of a PIL image (an 8-bit sRGB colour map) for a render in `colour`: decoded to
    linear values for "linear", as stored for "display"; for channel "alpha" its alpha (linear), repeated;
    ValueError when it cannot be decoded. A large image is
    shrunk in place first (thumbnail: a JPEG decodes at the smaller scale)."""
    try:
        height, width = capped(image.height, image.width)
        if (height, width) != (image.height, image.width):
            image.thumbnail((width, height))
        with warnings.catch_warnings():  # PIL's advice on a palette's transparency (two lines on stderr): the
            warnings.simplefilter("ignore", UserWarning)  # colour is what is read; alpha is not drawn
            if channel == "alpha":  # linear, as stored: 1 where the image has no alpha
                pixels = np.asarray(image.convert("RGBA"), np.float64)[:, :, 3:] / 255.0
                return np.ascontiguousarray(np.repeat(pixels, 3, axis=2), np.float32)
            pixels = np.asarray(image.convert("RGB"), np.float64) / 255.0
    except Exception as error:  # noqa: BLE001 - PIL raises many types on a corrupt image
        raise ValueError(f"{type(error).__name__}: {error}") from None
    return np.ascontiguousarray(srgb_to_linear(pixels) if colour == LINEAR else pixels, np.float32)


def check_map_file(path: Path, where: Where) -> None:
    """A scene material's map file refused in one line (SceneError) when missing, not a regular file (a FIFO, a
    device, a folder: refused before any open that could block) or not the image its suffix promises (a 3 GiB
    file of zeros named .png: OpenImageIO would try every reader on it). The memory estimate checks it so,
    before anything is compiled or decoded."""
    try:
        open_regular(path, where, "texture file (PNG, JPEG, EXR, ...)").close()
    except FileNotFoundError:
        raise SceneError(f"no such texture file {shown_name(path)}; give an image file (PNG, JPEG, EXR, ...) "
                         "relative to the scene file", where) from None
    mismatch = image_suffix_mismatch(path)
    if mismatch:
        raise SceneError(f"{shown_name(path)} is {mismatch}; give a PNG, JPEG, EXR or another image file", where)


def decode_scene_map(path: Path, where: Where, colour: str) -> np.ndarray:
    """A scene material's map (kd_map, ...), checked (check_map_file) and decoded; one line, SceneError, when it
    is not an image."""
    check_map_file(path, where)
    try:
        return decode_file(path, colour)
    except Exception as error:  # noqa: BLE001 - any decoder failure is the file's
        reason = " ".join(str(error).split()) or "unknown"
        raise SceneError(f"{str(path)!r} cannot be read as an image ({reason[:200]}); "
                         "give a PNG, JPEG, EXR or another format OpenImageIO reads", where) from None


# ---------------------------------------------------------------- sizes for the memory estimate

def file_size(path: Path) -> tuple[int, int] | None:
    """(height, width) of an image file from its header, or None when it is not one (nor a regular file: a FIFO
    is never opened by a reader that would wait on it; the decode refuses it in its own words)."""
    try:
        handle = open_regular(path, str(path), "texture file")
    except (SceneError, OSError):
        return None
    if image_suffix_mismatch(path):  # no image's signature where its suffix promises one: no reader probes it
        handle.close()
        return None
    with handle, suppress(Exception):  # not an image PIL reads (an EXR), or past PIL's bomb limit: OIIO's header
        from PIL import Image
        with warnings.catch_warnings():  # a header only: the decode shrinks a large map in bands (decode_file)
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(handle) as image:
                return image.height, image.width
    try:
        import OpenImageIO as oiio
        with native_errors_kept():  # libpng's own "IHDR: Read error" line: the decode words one line
            found = oiio.ImageInput.open(str(path))
        if found is None:
            oiio.geterror()  # retrieved, so OpenImageIO does not print it at exit
            return None
        spec = found.spec()
        found.close()
        return spec.height, spec.width
    except Exception:  # noqa: BLE001
        return None


def texture_bytes(sizes) -> int:
    """The memory estimate's texture term: TEXTURE_BYTES_PER_TEXEL per level-0 texel at the decoded size."""
    return sum(TEXTURE_BYTES_PER_TEXEL * h * w for h, w in (capped(height, width) for height, width in sizes))

