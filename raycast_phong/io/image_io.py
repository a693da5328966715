"""The only OpenImageIO importer: write PNG (8-bit) and EXR (float32, with extra layers and parts); read
back; compare two image files (ImageBufAlgo.compare); rasterise a line of label text.

Every write goes through atomic.replaced_atomically: a temporary file in the target folder, every
OpenImageIO result and error state checked, fsync, then rename. A failure raises WriteError and never
leaves a half-written image over a good one.
"""

from __future__ import annotations

import math
import os
import stat
import struct
import tempfile
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

from ..errors import ImageError
from .atomic import os_reason, replaced_atomically
from .encoding import COLOURS, DISPLAY, LINEAR, to_8bit
from .files import FILE_KINDS, check_output_path, image_suffix_mismatch, native_errors_kept
from .system import budget_of, format_bytes

LAYER_CHANNELS = {"depth": ("Z",), "normal": ("X", "Y", "Z"), "face": ("id",)}


# An EXR says what its values are, for a reader that does not know this renderer: the colour setting itself,
# and the colour space in OpenImageIO's attribute, named by the ASWF colour interop IDs that OpenImageIO 3
# gives its own reads (a PNG reads as "srgb_rec709_scene"). "display" values are what an sRGB display shows
# as they are, so they are sRGB-encoded values; "linear" values are linear Rec.709 (sRGB primaries).
EXR_COLOUR_ATTRIBUTE = "raycast_phong:colour"
EXR_COLOR_SPACES = {DISPLAY: "srgb_rec709_scene", LINEAR: "lin_rec709_scene"}


def image_array(image) -> np.ndarray:
    """`image` as an (H, W, 3) array of real numbers, H, W ≥ 1 (a render's image, float32 or float64); else
    ValueError saying what was given, before any file is touched."""
    array = np.asarray(image) if isinstance(image, np.ndarray | list | tuple) else None
    if array is None or array.dtype.kind not in "biuf" or array.ndim != 3 or array.shape[2] != 3 or 0 in array.shape:
        got = (f"an array of shape {array.shape} and dtype {array.dtype}" if array is not None
               else f"a {type(image).__name__}")
        raise ValueError(f"write_image: the image must be an (H, W, 3) array of real RGB values with H, W ≥ 1, "
                         f"as render() returns; got {got}")
    return array


def write_image(path: str | Path, image: np.ndarray, aovs: dict[str, np.ndarray] | None = None,
                colour: str = DISPLAY, parts: dict[str, tuple[np.ndarray, tuple[int, int]]] | None = None) -> Path:
    """Write an (H, W, 3) image rendered in `colour` (the scene's render.colour, io.encoding): .png 8-bit
    clamped (through the sRGB curve for "linear"), .exr float32 unclamped and unencoded, its header saying which
    (EXR_COLOUR_ATTRIBUTE and OpenImageIO's "oiio:ColorSpace", EXR_COLOR_SPACES).

    `aovs` (EXR only) adds layers as channels `name.R/G/B` (terms), `depth.Z`, `normal.X/Y/Z`, `face.id`.
    `parts` (EXR only) maps name → ((h, w, 3) image, (x, y)): each becomes one more part of a multi-part
    EXR, with channels `name.R/G/B` and its data window at (x, y) in the main image's H×W display window
    (OpenEXR requires one display window for all parts; the data windows may differ in size).

    Parameters: `path` (.png or .exr), `image` (H, W, 3) real values, `aovs`, `colour` ("display" or "linear"),
    `parts`, as above. Returns the Path written. Raises ValueError for an image that is not (H, W, 3) real values
    or an unknown colour; ImageError for an output path that cannot be written (a folder, an input); WriteError
    when the write fails (the old file is kept).
    """
    if colour not in COLOURS:
        raise ValueError(f"colour {colour!r}; allowed: {', '.join(COLOURS)}")
    image = image_array(image)
    path = check_output_path(path)
    aovs = aovs or {}
    parts = parts or {}
    if path.suffix.lower() == ".png":
        if aovs or parts:
            raise ImageError(f"{path}: layers {sorted(aovs) + sorted(parts)} need an .exr output")
        # OpenImageIO's PNG writer needs C order; a strided view (e.g. from read_layer) writes no data.
        pixels, names, fmt = np.ascontiguousarray(to_8bit(image, colour)), ["R", "G", "B"], oiio.UINT8
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
        spec.attribute(EXR_COLOUR_ATTRIBUTE, colour)
        spec.attribute("oiio:ColorSpace", EXR_COLOR_SPACES[colour])
    extra = [_part(name, layer, origin, spec) for name, (layer, origin) in parts.items()]
    if extra:
        spec.attribute("name", "image")  # every part of a multi-part EXR needs a unique name
    with replaced_atomically(path, prefix=f".{path.stem}-") as temporary_path:
        specs = [spec, *(part_spec for part_spec, _ in extra)] if extra else spec
        _write_oiio(str(temporary_path), specs, pixels, extra)
    return path


def image_colour(path: str | Path) -> str | None:
    """The render.colour an EXR of write_image says its values are in (EXR_COLOUR_ATTRIBUTE), or None for a file
    that does not say (a PNG: its values are display values already; an EXR from elsewhere)."""
    spec = header_spec(path)
    found = spec.get_string_attribute(EXR_COLOUR_ATTRIBUTE) if spec is not None else None
    return found if found in COLOURS else None


def _write_oiio(temporary: str, specs, pixels: np.ndarray, extra: list) -> None:
    """Write every part into `temporary`, checking each bool and the writer's error state after close.

    OpenImageIO's PNG writer reports a short write (a full disk, a file-size limit) only through
    has_error: write_image and close both return True. Raises OSError with the OS reason.
    """
    output = oiio.ImageOutput.create(temporary)
    if output is None:
        raise OSError(f"no image writer ({oiio.geterror() or 'unknown format'})")
    ok = output.open(temporary, specs) and output.write_image(pixels)
    # Later parts follow the first: reopen for each with AppendSubimage, then write its pixels.
    for part_spec, part_pixels in extra:
        ok = ok and output.open(temporary, part_spec, "AppendSubimage") and output.write_image(part_pixels)
    closed = output.close()
    if not (ok and closed) or output.has_error:
        message = output.geterror() or oiio.geterror() or ""
        raise os_reason(temporary, message.replace(temporary, "the temporary file"))
    if not _complete(temporary, 1 + len(extra)):
        raise os_reason(temporary, "the image file is incomplete after the writer closed it")


# The last chunk of every PNG (length 0, type IEND, its CRC): the PNG writer writes it last, so a file
# that ends in it was written to the end.
PNG_END = b"\x00\x00\x00\x00IEND\xaeB`\x82"


def _complete(temporary: str, parts: int) -> bool:
    """Whether the file OpenImageIO closed is whole. Its writers ignore an error in the final flush at close
    (measured under RLIMIT_FSIZE: a PNG or EXR a few bytes over the limit is cut short while open, write_image,
    close and has_error all report success), so look at the end of the file, which a lost flush always takes:
    a PNG must end in its IEND chunk; the last scanline of every EXR part must read back (its chunk is the
    last of the part, and OpenEXR notices a chunk missing even one byte). Reading one line per part instead
    of the whole image: 1 ms instead of 60 for a 1920×1080 EXR."""
    if temporary.lower().endswith(".png"):
        with open(temporary, "rb") as handle:
            handle.seek(0, os.SEEK_END)
            if handle.tell() < len(PNG_END):
                return False
            handle.seek(-len(PNG_END), os.SEEK_END)
            return handle.read() == PNG_END
    source = oiio.ImageInput.open(temporary)  # not an ImageBuf: the image cache would keep the file open
    if source is None:
        oiio.geterror()  # clear it: the caller reports the OS reason instead
        return False
    whole = True
    for part in range(parts):
        whole = whole and source.seek_subimage(part, 0)
        if whole:
            spec = source.spec()
            whole = source.read_scanline(spec.y + spec.height - 1, 0, oiio.FLOAT) is not None
    whole = whole and not source.has_error
    source.geterror()
    source.close()
    return whole


def _part(name: str, layer: np.ndarray, origin: tuple[int, int],
          main: oiio.ImageSpec) -> tuple[oiio.ImageSpec, np.ndarray]:
    """The spec and C-ordered float32 (h, w, C) pixels of one extra EXR part at `origin` = (x, y)."""
    pixels = np.ascontiguousarray(layer, np.float32)
    height, width, channels = pixels.shape
    spec = oiio.ImageSpec(width, height, channels, oiio.FLOAT)
    spec.channelnames = tuple(f"{name}.{c}" for c in LAYER_CHANNELS.get(name, ("R", "G", "B")))
    spec.x, spec.y = origin
    spec.full_x, spec.full_y, spec.full_width, spec.full_height = 0, 0, main.width, main.height
    spec.attribute("name", name)
    spec.attribute("compression", "zip")
    return spec, pixels


def refuse_non_regular(path: str | Path) -> None:
    """ImageError (one line) for an image path that is a FIFO, a device or a folder (OpenImageIO would wait on a
    pipe for ever, or read a device without end), or whose first bytes are not its suffix's format (OpenImageIO
    would try every reader on it). A missing or unreadable file is left to the read's own words."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return
    if not stat.S_ISREG(mode):
        kind = next((name for test, name in FILE_KINDS if test(mode)), "not a regular file")
        raise ImageError(f"{path}: is {kind}, not a regular file; give an image file (PNG, EXR, ...)")
    mismatch = image_suffix_mismatch(path)
    if mismatch:
        raise ImageError(f"{path}: {mismatch}; give an image file (PNG, EXR, ...)")


def colour_as_stored() -> oiio.ImageSpec:
    """The configuration an image is opened with so its colour reads as stored: OpenImageIO would multiply a
    PNG's (or TIFF's) colour by its alpha, darkening a cut-out's edge texels, where PIL and the file keep it
    straight."""
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    return config


def read_image(path: str | Path, part: int = 0,
               max_memory: int | str | None = None) -> tuple[np.ndarray, tuple[str, ...]]:
    """All channels of one part of an image as (H, W, C) float32 (8-bit files scaled to [0, 1]) and their names.

    A part is read over its own data window: an extra part of write_image comes back at its own size. Its size
    is checked from the header before a pixel is decoded: a 1 MB PNG may hold 20000² pixels (6.4 GB as float32).

    Parameters: `path`, an image file OpenImageIO reads; `part`, the part of a multi-part EXR (0: the first);
    `max_memory`, the bytes the read may use (or '8G'; default: the commands' budget, a share of the memory
    available, and no more than BOMB_RATIO times the file's size once past BOMB_FLOOR). Returns (pixels (H, W, C)
    float32, channel names). Raises ImageError (one line) for a file that cannot be read or would exceed the
    budget.
    """
    refuse_non_regular(path)
    budget = budget_of(max_memory)
    buffer = oiio.ImageBuf(str(path), part, 0, colour_as_stored())
    spec = buffer.spec()  # the header alone: ImageBuf decodes the pixels when they are asked for
    if buffer.has_error:
        raise _cannot_read(path, buffer.geterror())
    needed = _read_bytes(spec)
    if budget is not None and needed > budget:
        raise ImageError(f"{path}: a {spec.width}×{spec.height} image of {spec.nchannels} channel(s) needs about "
                         f"{format_bytes(needed)} to read, over the budget of {format_bytes(budget)}; allowed: "
                         "read_image(..., max_memory=...) above it")
    size = os.stat(path).st_size
    if max_memory is None and needed > BOMB_FLOOR and needed > BOMB_RATIO * size:
        raise ImageError(f"{path}: a {spec.width}×{spec.height} image of {spec.nchannels} channel(s) in a file of "
                         f"{format_bytes(size)} needs about {format_bytes(needed)} to read, over {BOMB_RATIO:,}× its "
                         "size, as a decompression bomb's does; allowed: read_image(..., max_memory=...) to read "
                         "it anyway")
    pixels = buffer.get_pixels(oiio.FLOAT)
    if pixels is None or pixels.size == 0:
        raise _cannot_read(path, buffer.geterror())
    return np.asarray(pixels, np.float32), tuple(buffer.spec().channelnames)


# An image that decodes to more than BOMB_RATIO × its file's bytes, past BOMB_FLOOR, is read only when the caller
# gives a budget: a 1 MB PNG of 20000² pixels needs 10 GB (PIL's own guard refuses 179M pixels and more). A PNG of
# one flat colour compresses about 1000×, so a large flat mask passes only with max_memory; photographs and
# renders compress 2-20×.
BOMB_RATIO = 1000
BOMB_FLOOR = 256 << 20


def _read_bytes(spec) -> int:
    """Peak bytes of reading a part whole: the file's pixels decoded, ImageBuf's float copy and the array handed
    back (a 20000² RGB PNG: 10.6 GB at peak, 8.8 bytes a value; this says 9)."""
    values = max(spec.width, 0) * max(spec.height, 0) * max(spec.depth, 1) * max(spec.nchannels, 0)
    return values * (2 * 4 + max(spec.format.size(), 1))


def read_layer(path: str | Path, layer: str | None = None, max_memory: int | str | None = None) -> np.ndarray:
    """The RGB image (layer None) or one named layer, in any part, of a file written by write_image.

    Parameters: `path`, an image file; `layer`, a layer name (depth, normal, face, ambient, diffuse, specular,
    emission, or an extra part's name) or None for R, G, B; `max_memory`, as read_image's. Returns (H, W, C)
    float32. Raises ImageError for a file that cannot be read or has no such layer (naming the channels it has).
    """
    seen: list[str] = []
    for part in range(_part_count(path) if layer is not None else 1):
        pixels, names = read_image(path, part, max_memory)
        seen += names
        wanted = ["R", "G", "B"] if layer is None else [n for n in names if n.startswith(layer + ".")]
        if wanted and all(name in names for name in wanted):
            return pixels[:, :, [names.index(name) for name in wanted]]
    raise ImageError(f"{path}: no layer {layer or 'RGB'!r}; channels are {', '.join(seen)}")


def _part_count(path: str | Path) -> int:
    refuse_non_regular(path)
    buffer = oiio.ImageBuf(str(path))
    count = buffer.nsubimages
    buffer.geterror()  # a missing file reports through read_image; drop the error here, unread
    return max(count, 1)


# ---------------------------------------------------------------- label text

# "" is OpenImageIO's default font, the DroidSans its wheel ships in OpenImageIO/share/fonts; a build
# without it may still find DejaVuSans in a folder named by $OPENIMAGEIO_FONTS.
LABEL_FONTS = ("", "DejaVuSans")
LINE_GLYPHS = "Ag[]|()"  # the tallest capital, a descender and the brackets that reach above and below both
NO_FONT = ("OpenImageIO found no font (tried its own DroidSans and DejaVuSans); set OPENIMAGEIO_FONTS to "
           "a folder holding DejaVuSans.ttf")


def label_font() -> str | None:
    """The first of LABEL_FONTS that OpenImageIO can load, or None on a machine without them."""
    return next((name for name in LABEL_FONTS if oiio.ImageBufAlgo.text_size("Ag", 12, name).defined), None)


def text_coverage(text: str, size: int) -> np.ndarray | None:
    """One line of text as (h, w) float32 coverage in [0, 1], or None when no font is found.

    h is the font's line height at `size` pixels (the extent of LINE_GLYPHS, the same for any text, so
    labels drawn side by side share a baseline); w is the text's width.
    """
    font = label_font()
    if font is None:
        return None
    line = oiio.ImageBufAlgo.text_size(LINE_GLYPHS, size, font)
    extent = oiio.ImageBufAlgo.text_size(text, size, font)
    width = max(extent.xend - min(extent.xbegin, 0), 1) if extent.defined else 1  # "" or blanks have no extent
    buffer = oiio.ImageBuf(oiio.ImageSpec(width, line.yend - line.ybegin, 1, oiio.FLOAT))
    # x, y is the baseline's left end: shift so that the ascent and any left overhang land inside.
    if not oiio.ImageBufAlgo.render_text(buffer, -min(extent.xbegin, 0), -line.ybegin, text, size, font, (1.0,)):
        buffer.geterror()
        return None
    return np.asarray(buffer.get_pixels(oiio.FLOAT), np.float32)[:, :, 0]


# ---------------------------------------------------------------- comparison


@dataclass(frozen=True, eq=False)
class ImageComparison:
    """OpenImageIO's comparison of two images of one size (ImageBufAlgo.compare), and their pixels."""
    mean: float                  # mean |a − b| over every pixel and channel
    rms: float                   # root mean square of a − b
    psnr: float                  # 20·log10(1 / rms) dB; inf for identical images
    max: float                   # largest |a − b|
    max_at: tuple[int, int]      # (x, y) of that pixel
    max_channel: int             # and its channel
    warned: int                  # pixels with some channel above the warn threshold
    failed: int                  # pixels with some channel above the fail threshold
    pixels: int                  # width × height
    nan: tuple[int, int]         # pixels of a and of b with a NaN channel
    inf: tuple[int, int]         # pixels of a and of b with an infinite channel
    a: np.ndarray                # (H, W, C) float32
    b: np.ndarray                # (H, W, C) float32


# Bytes per pixel channel that compare_files holds for each image: OpenImageIO's buffer (read as float),
# its float32 copy, and the comparison's float32 temporaries (the NaN and inf tests, the heat map).
COMPARE_BYTES_PER_SAMPLE = 16


def _cannot_read(path: str | Path, said: str) -> ImageError:
    """The one line for an image OpenImageIO could not read: "no such file" for a missing one (its own words
    repeat themselves: 'Could not open file: Could not open file "x.png"'), else the first line of what it said."""
    first = next((line.strip() for line in str(said).splitlines() if line.strip()), "unknown reason")
    reason = f"cannot read ({first})" if os.path.lexists(path) else "no such file"
    return ImageError(f"{path}: {reason}")


def header_spec(path: str | Path):
    """The OpenImageIO ImageSpec of an image's first part, from its header alone, or None if it cannot be
    opened (the read reports why)."""
    refuse_non_regular(path)
    source = oiio.ImageInput.open(str(path))
    if source is None:
        oiio.geterror()
        return None
    try:
        return source.spec()
    finally:
        source.close()


def image_header(path: str | Path) -> tuple[int, int, int] | None:
    """(width, height, channels) of an image's first part from its header alone (header_spec), or None."""
    spec = header_spec(path)
    return None if spec is None else (spec.width, spec.height, spec.nchannels)


def check_image_reads(paths: tuple[str | Path, ...], budget: int | None, per_sample: int) -> None:
    """Refuse (ImageError, one line) to read images whose headers claim more pixels than the budget holds at
    `per_sample` bytes per pixel channel: a 100-byte PNG may claim 20000 × 20000 pixels."""
    if budget is None:
        return
    sizes = {path: image_header(path) for path in paths}
    need = sum(w * h * c for w, h, c in filter(None, sizes.values())) * per_sample
    if need > budget:
        path, (w, h, c) = max(((p, s) for p, s in sizes.items() if s), key=lambda item: math.prod(item[1]))
        raise ImageError(f"{path}: its header says {w}×{h} pixels with {c} channels; reading "
                         f"{'them' if len(paths) == 1 else 'the images'} needs ≈ {format_bytes(need)} of memory, "
                         f"above the {format_bytes(budget)} budget; raise the budget (--max-memory)")


def compare_files(a: str | Path, b: str | Path, fail: float, warn: float,
                  budget: int | None = None) -> ImageComparison:
    """Compare two image files as idiff does (8-bit files scaled to [0, 1]).

    Raises ImageError for an unreadable file, a different size or channel count, or images whose headers
    claim more pixels than `budget` bytes hold (checked before any pixel is read).
    """
    check_image_reads((a, b), budget, COMPARE_BYTES_PER_SAMPLE)
    buffers = []
    for path in (a, b):
        with native_errors_kept():  # libpng prints "libpng error: …" on stderr itself; our line says it
            buffer = oiio.ImageBuf(str(path))
            unread = buffer.has_error or not buffer.read()
        if unread:
            raise _cannot_read(path, buffer.geterror() or oiio.geterror())
        buffers.append(buffer)
    specs = [buffer.spec() for buffer in buffers]
    shapes = [(spec.width, spec.height, spec.nchannels) for spec in specs]
    if shapes[0] != shapes[1]:
        (wa, ha, ca), (wb, hb, cb) = shapes
        raise ImageError(f"{b}: {wb}×{hb} with {cb} channels, but {a} is {wa}×{ha} with {ca}; only images of one "
                         "size and channel count can be compared")
    # CompareResults.error is set whenever a pixel fails (OpenImageIO 3.2), so it says nothing about the call.
    found = oiio.ImageBufAlgo.compare(buffers[0], buffers[1], fail, warn)
    pixels_a, pixels_b = (np.asarray(buffer.get_pixels(oiio.FLOAT), np.float32) for buffer in buffers)
    # ImageBufAlgo.compare counts a NaN as no difference: an image of NaN passes against itself.
    nan = tuple(int(np.isnan(p).any(axis=2).sum()) for p in (pixels_a, pixels_b))
    inf = tuple(int(np.isinf(p).any(axis=2).sum()) for p in (pixels_a, pixels_b))
    return ImageComparison(mean=found.meanerror, rms=found.rms_error, psnr=found.PSNR, max=found.maxerror,
                           max_at=(found.maxx, found.maxy), max_channel=found.maxc, warned=found.nwarn,
                           failed=found.nfail, pixels=specs[0].width * specs[0].height, nan=nan, inf=inf,
                           a=pixels_a, b=pixels_b)


def png_bytes(image: np.ndarray, colour: str = DISPLAY) -> bytes:
    """An (H, W, 3) image rendered in `colour` as a PNG in memory, with the 8-bit values `raycast-phong render
    -o x.png` stores (encoding.to_8bit: clamped, the sRGB curve for "linear", rounded). Written here, not by
    OpenImageIO, which writes only files (a scratch file, fsynced, read back): the to_8bit pass and a zlib pass
    at level 1 (speed over size: the bytes cross a local socket).

    PNG: signature, IHDR (8-bit RGB), one IDAT of zlib rows each led by filter 0, IEND (RFC 2083).
    """
    rgb8 = to_8bit(image, colour)
    height, width = rgb8.shape[:2]
    rows = np.zeros((height, 1 + 3 * width), np.uint8)  # column 0: each row's filter type, 0 = none
    rows[:, 1:] = rgb8.reshape(height, 3 * width)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)  # depth 8, colour type 2 (RGB), no interlace
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(rows.tobytes(), 1))
            + chunk(b"IEND", b""))


def image_bytes(image, suffix: str = ".png", aovs: dict | None = None, colour: str = DISPLAY) -> bytes:
    """An image rendered in `colour` as a file's bytes: a PNG with the pixels `raycast-phong render -o x.png`
    stores (png_bytes), or the EXR it would write, layers and all (image_io writes only files: a scratch folder,
    removed at once). The view's frames and saves use it too."""
    if suffix == ".png" and not aovs:
        return png_bytes(image, colour)
    with tempfile.TemporaryDirectory(prefix="raycast-phong-image-") as folder:
        path = Path(folder) / f"image{suffix}"
        write_image(path, image, aovs, colour)
        return path.read_bytes()
