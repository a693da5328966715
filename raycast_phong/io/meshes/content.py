"""What a mesh file's bytes are, before any reader sees them: a file whose content is not the format its suffix
says (an OBJ named .stl), an archive or a compressed file is refused in one line. No trimesh."""

from __future__ import annotations

import os
import re
from pathlib import Path

from ...errors import SceneError, Where
from ..files import open_regular

SIGNATURES = ((b"ply", "PLY"), (b"glTF", "GLB"), (b"PK\x03\x04", "a zip archive"), (b"BZh", "bzip2-compressed"),
              (b"\x1f\x8b", "gzip-compressed"), (b"\xfd7zXZ", "xz-compressed"), (b"<?xml", "XML"),
              (b"<COLLADA", "COLLADA (XML)"), (b"{", "JSON"))
# A file a repository keeps in Git LFS, cloned without it: a few lines naming the real file's hash and size.
LFS_POINTER = b"version https://git-lfs.github.com/spec/"
# Formats not read here that share a suffix with one that is, by their first line: refused naming them, where the
# format they were taken for found nothing (an MNI surface .obj was a Wavefront OBJ that "holds no triangles").
NUMBER = rb"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?"
FOREIGN = ((re.compile(rb"\AP" + rb"[ \t]+" + (NUMBER + rb"[ \t]+") * 5 + rb"\d+[ \t]*\r?\n"),
            "an MNI (BIC) surface object (a first line 'P' with surface properties and a point count)"),)
# Suffixes of containers, not mesh formats (trimesh opens some): refused with what to do instead.
CONTAINERS = {".zip": "a zip archive", ".bz2": "bzip2-compressed", ".gz": "gzip-compressed", ".xz": "xz-compressed",
              ".tar": "a tar archive", ".7z": "a 7z archive"}


def sniff(head: bytes) -> str | None:
    """The format a file's first bytes announce, or None (text formats without a signature: OBJ, OFF)."""
    head = head.removeprefix(b"\xef\xbb\xbf")  # a UTF-8 byte-order mark before a text format's first word
    stripped = head.lstrip()
    for signature, name in SIGNATURES:
        if head.startswith(signature) or (name in ("JSON", "XML", "COLLADA (XML)") and stripped.startswith(signature)):
            return name
    if re.match(rb"(\s*(#[^\n]*)?\n)*\s*(v|vn|vt|f|o|g|mtllib|usemtl)\s", head):
        return "OBJ"
    if re.match(rb"(\s*(#[^\n]*)?\n)*\s*(ST)?C?N?4?n?OFF\b", head):  # Geomview's [ST][C][N][4][n]OFF
        return "OFF"
    return "ASCII STL" if stripped[:5].lower() == b"solid" else None


def check_file_content(path: Path, kind, where: Where) -> None:
    """check_content on the file at `path` (framing calls it before the memory check reads a binary STL's
    triangle count from a header that may be an OBJ's first line). A file that cannot be opened is left to
    the read, which words it."""
    try:
        handle = open_regular(path, where, "mesh file")
    except (OSError, SceneError):
        return
    with handle:
        check_content(path, handle, kind, where)


def check_content(path: Path, handle, kind, where: Where) -> None:
    """Refuse, in one line, a file whose content is not the format its suffix says (an OBJ named .stl was read
    as a binary STL of 433 GB: `kind`, its MeshFormat, says what fits), an archive or compressed file (decompress
    it first)."""
    suffix = path.suffix.lower()
    if suffix in CONTAINERS:
        raise SceneError(f"{str(path)!r} is {CONTAINERS[suffix]}; extract or decompress it and render the "
                         "model file inside (OBJ, PLY, STL, OFF, GLB/glTF, ...)", where)
    head = handle.read(512)
    handle.seek(0)
    name = kind.name(suffix)
    if not head:
        raise SceneError(f"{str(path)!r} is empty (0 bytes); expected a {name} file", where)
    if head.startswith(LFS_POINTER):  # read as an OBJ of no faces, or a binary STL of a billion triangles
        size = re.search(rb"\nsize (\d+)", head)
        real = f"the {int(size[1]):,} bytes of " if size else ""
        raise SceneError(f"cannot read {str(path)!r} as {name}: it is a Git LFS pointer to {real}the real file, "
                         "not the file; fetch it (`git lfs pull` in its repository)", where)
    for pattern, foreign in FOREIGN:
        if pattern.match(head):
            raise SceneError(f"cannot read {str(path)!r} as {name}: its content is {foreign}, which shares the "
                             f"{suffix} suffix and is not read here; convert it to a mesh file read here ({name}, "
                             "PLY, STL, ...)", where)
    found = sniff(head)
    if kind.content(head, found, os.fstat(handle.fileno()).st_size, suffix):
        return
    said = (f"its content is {found}; rename it to that format's suffix" if found
            else f"its content does not start as a {name} file does")
    raise SceneError(f"cannot read {str(path)!r} as {name}: {said}", where)


def is_number(word: str | bytes) -> bool:
    """Whether a word of a text mesh file (OBJ, MTL, ASCII STL) reads as a number, as Python's float() does
    (1.5, -2e-3, nan, inf); MSVC's `1.#IND` and a control byte do not."""
    try:
        float(word)
    except ValueError:
        return False
    return True
