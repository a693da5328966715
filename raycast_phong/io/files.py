"""Files, safely: open_regular opens only a regular file (never a FIFO, a device or a folder) of at most a given
size; file_version names a version of a file, (resolved path, mtime, size, inode): a rewrite changes at least one,
so what was learnt of one version is never taken for another's; check_output_path refuses, before anything
renders, an image output that could not be written or would replace an input (no codec is loaded for it).
"""

from __future__ import annotations

import os
import re
import stat
import sys
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import BinaryIO

from ..codes import IMAGE_SUFFIXES
from ..errors import ImageError, SceneError, Where, shortened

FILE_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISCHR, "a device"),
              (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def shown_name(name: str | Path) -> str:
    """`name` quoted for a one-line message, a long one shortened (errors.shortened): its start and its end."""
    return shortened(repr(str(name)))


def open_regular(path: Path, where: Where, what: str, limit: int | None = None) -> BinaryIO:
    """Open `path` for binary reading if it is a regular file of at most `limit` bytes; else SceneError at
    `where` naming `what` (a scene file, a mesh file). A missing file raises FileNotFoundError,
    for the caller to word.

    A FIFO would block the read forever and /dev/zero never ends, so the kind is checked with stat before
    opening (opening some devices acts on them), and again with fstat after an O_NONBLOCK open, in case
    the path was swapped in between (a FIFO opens at once without blocking then).
    """
    def refuse_kind(mode: int) -> None:
        if not stat.S_ISREG(mode):
            kind = next((f"{name}, not a regular file" for test, name in FILE_KINDS if test(mode)),
                        "not a regular file")
            raise SceneError(f"{shown_name(path)} is {kind}; give a {what}", where)

    try:
        refuse_kind(os.stat(path).st_mode)
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except SceneError:  # refuse_kind's (a ValueError too)
        raise
    except (NotADirectoryError, ValueError):  # ValueError: a NUL byte, which no file's name holds
        raise FileNotFoundError(path) from None
    except FileNotFoundError:
        raise
    except OSError as error:
        raise SceneError(f"cannot read the {what} {shown_name(path)} ({error.strerror})", where) from None
    try:
        info = os.fstat(descriptor)
        refuse_kind(info.st_mode)
        if limit is not None and info.st_size > limit:
            raise SceneError(f"the {what} is {info.st_size:,} bytes, more than the {limit:,} "
                             f"({limit >> 20} MiB) allowed", where)
        os.set_blocking(descriptor, True)
        return os.fdopen(descriptor, "rb")
    except BaseException:
        os.close(descriptor)
        raise


# An image's first bytes, by the suffixes that promise its format: a file whose bytes are not its suffix's is
# refused at once (OpenImageIO would try every reader it has on it, minutes for a 3 GiB file of something else).
IMAGE_MAGIC = {".png": ("PNG", (b"\x89PNG\r\n\x1a\n",)), ".jpg": ("JPEG", (b"\xff\xd8\xff",)),
               ".jpeg": ("JPEG", (b"\xff\xd8\xff",)), ".exr": ("OpenEXR", (b"\x76\x2f\x31\x01",)),
               ".tif": ("TIFF", (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")),
               ".tiff": ("TIFF", (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+")), ".bmp": ("BMP", (b"BM",)),
               ".gif": ("GIF", (b"GIF87a", b"GIF89a")), ".hdr": ("Radiance HDR", (b"#?",))}


def image_suffix_mismatch(path: str | Path) -> str | None:
    """What is wrong when a file whose suffix promises an image format starts with no image signature at all
    ("not a PNG file: it starts with b'hello'"), else None. A misnamed image (a JPEG called .png, as exporters
    write) passes: OpenImageIO reads it by its bytes. A suffix without a known signature, or a file that cannot
    be read, is left to the reader."""
    known = IMAGE_MAGIC.get(Path(path).suffix.lower())
    if known is None:
        return None
    try:
        with open(path, "rb") as handle:  # the caller checked it is a regular file
            start = handle.read(8)
    except OSError:
        return None
    if any(start.startswith(signature) for _, signatures in IMAGE_MAGIC.values() for signature in signatures):
        return None
    return f"not a {known[0]} file: it starts with {start!r}"


def open_mesh_file(path: Path, where: Where) -> BinaryIO:
    """open_regular for a mesh file, with a missing one worded: "WHERE: no such mesh file 'PATH'"."""
    try:
        return open_regular(path, where, "mesh file")  # never a FIFO, a device or a folder
    except FileNotFoundError:
        raise SceneError(f"no such mesh file {str(path)!r}", where) from None


def file_version(path: str | Path) -> tuple:
    """(resolved path, mtime, size, inode) of the file as it is now; OSError for a missing one."""
    info = os.stat(path)
    return (str(Path(path).resolve()), info.st_mtime_ns, info.st_size, info.st_ino)


def present_version(path: str | Path) -> tuple | None:
    """file_version of `path`; None for a file that is not there (deleted, moved, or an editor's save halfway)."""
    try:
        return file_version(path)
    except OSError:
        return None


# Lines a native image library prints on the process's own stderr (fd 2) while it fails: libpng's default
# error handler writes "libpng error: IDAT: Read error: ..." before OpenImageIO reports the same error, which
# the caller then words in its one line.
NATIVE_ERROR_LINE = re.compile(r"^libpng (error|warning): ")


@contextmanager
def native_errors_kept():
    """Run the block with fd 2 captured; afterwards give back to stderr what it printed, less the native image
    libraries' own error lines (NATIVE_ERROR_LINE), so that a failing read says one line, the caller's."""
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):  # no fd 2 (closed, or a stream without one): nothing to keep
        yield
        return
    import tempfile  # here, not at start-up: 7 ms of imports (random, shutil) that only this needs
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            kept = [line for line in sink.read().decode("utf-8", "replace").splitlines(keepends=True)
                    if not NATIVE_ERROR_LINE.match(line)]
            if kept:
                sys.stderr.write("".join(kept))


# ---------------------------------------------------------------- where an image may be written

def check_output_path(path: str | Path, inputs: tuple[str | Path, ...] = ()) -> Path:
    """Refuse, before rendering, an output whose folder is missing, whose format is unknown, that is a
    folder, or that is one of the command's `inputs` (writing it would destroy what is being read)."""
    path = Path(path)
    if os.path.isdir(path):  # before the suffix: a folder has none, and "no extension" would not say why
        check_output_file(path, inputs)  # which says it is a folder
    if path.suffix.lower() not in IMAGE_SUFFIXES:
        got = f"not {path.suffix!r}" if path.suffix else "it has no extension"
        raise ImageError(f"{path}: the output must end in .png (8-bit) or .exr (float32), {got}")
    check_output_file(path, inputs)
    return path


def check_output_file(path: Path, inputs: tuple[str | Path, ...] = ()) -> None:
    """Refuse an output file in a missing or read-only folder, a folder itself, or one of `inputs`."""
    folder = path.parent if str(path.parent) else Path(".")
    _check_name_length(path, folder)
    if not folder.is_dir():
        raise ImageError(f"{path}: the output folder {str(folder)!r} does not exist; create it or choose an "
                         "existing folder")
    if path.is_dir():
        raise ImageError(f"{path}: the output is a folder; give a file name in it, e.g. {path / 'render.png'}")
    for given in inputs:
        if _same_file(path, Path(given)):
            raise ImageError(f"{path}: the output is the input {given}; writing it would replace what is read")
    if not os.access(folder, os.W_OK):
        raise ImageError(f"{path}: the output folder {str(folder)!r} is not writable")


def _check_name_length(path: Path, folder: Path) -> None:
    """Refuse a file name or path longer than the file system allows (ENAMETOOLONG from any later call)."""
    name, whole = len(os.fsencode(path.name)), len(os.fsencode(str(path)))
    name_max, path_max = 255, 4096  # where the file system does not say
    with suppress(OSError, ValueError):
        where = folder if folder.is_dir() else "."
        name_max, path_max = os.pathconf(where, "PC_NAME_MAX"), os.pathconf(where, "PC_PATH_MAX")
    if name > name_max or whole >= path_max:
        what, size, limit = ("file name", name, name_max) if name > name_max else ("path", whole, path_max)
        shown = f"{str(path)[:60]}…" if len(str(path)) > 60 else str(path)
        raise ImageError(f"{shown}: the output's {what} is {size:,} bytes, longer than the {limit:,} the file system "
                         "allows; choose a shorter name")


def _same_file(a: Path, b: Path) -> bool:
    """One file under two spellings (relative, `..`, a symbolic or hard link), or one path not yet written. A
    path no file can have (a NUL byte) is no other: the input's own check words it."""
    try:
        try:
            return os.path.samefile(a, b)
        except OSError:  # one of them does not exist: compare the spelled-out paths
            return a.resolve() == b.resolve()
    except ValueError:
        return False
