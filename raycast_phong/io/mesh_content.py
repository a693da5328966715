"""What a mesh file's bytes are, before any reader sees them: a file whose content is not the format its suffix
says (an OBJ named .stl), an archive or a compressed file is refused in one line. No trimesh."""

from __future__ import annotations

import os
import re
from pathlib import Path

from ..errors import SceneError, Where
from .files import open_regular

TEXT_FORMATS = (".obj", ".off")  # trimesh decodes these as text, guessing any non-UTF-8 encoding
READABLE = "a mesh file trimesh reads (OBJ, PLY, STL, OFF, GLB)"

SIGNATURES = ((b"ply", "PLY"), (b"glTF", "GLB"), (b"PK\x03\x04", "a zip archive"), (b"BZh", "bzip2-compressed"),
              (b"\x1f\x8b", "gzip-compressed"), (b"\xfd7zXZ", "xz-compressed"), (b"<?xml", "XML"),
              (b"<COLLADA", "COLLADA (XML)"), (b"{", "JSON"))
# What a suffix's content starts with (a binary STL is told by its size instead); formats not listed are
# left to trimesh.
EXPECTED = {".ply": ("PLY",), ".glb": ("GLB",), ".gltf": ("JSON",), ".3mf": ("a zip archive",)}
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
    if re.match(rb"\s*[CN]?[ST]?OFF\b", head):
        return "OFF"
    if stripped[:5].lower() == b"solid":
        return "ASCII STL"
    return None


def check_file_content(path: Path, where: Where) -> None:
    """check_content on the file at `path` (framing calls it before the memory check reads a binary STL's
    triangle count from a header that may be an OBJ's first line). A file that cannot be opened is left to
    the read, which words it. Text formats are left to the read: their header count cannot be fooled so."""
    if path.suffix.lower() in TEXT_FORMATS:
        return
    try:
        handle = open_regular(path, where, "mesh file")
    except (OSError, SceneError):
        return
    with handle:
        check_content(path, handle, where)


def check_content(path: Path, handle, where: Where) -> None:
    """Refuse, in one line, a file whose content is not the format its suffix says (an OBJ named .stl was read
    as a binary STL of 433 GB), an archive or compressed file (decompress it first), or a glTF's sibling."""
    suffix = path.suffix.lower()
    if suffix in CONTAINERS:
        raise SceneError(f"{str(path)!r} is {CONTAINERS[suffix]}; extract or decompress it and render the "
                         "model file inside (OBJ, PLY, STL, OFF, GLB/glTF, ...)", where)
    head = handle.read(512)
    handle.seek(0)
    if not head:
        raise SceneError(f"{str(path)!r} is empty (0 bytes); expected {READABLE}", where)
    found = sniff(head)
    if suffix == ".stl":
        size = os.fstat(handle.fileno()).st_size
        if (size >= 84 and size == 84 + 50 * int.from_bytes(head[80:84], "little")) or found in ("ASCII STL", None):
            return
    elif suffix in (".obj", ".off"):
        if found in (None, "OBJ", "OFF", "ASCII STL"):
            return  # text formats whose first lines may look like each other's
    elif suffix not in EXPECTED or found in EXPECTED[suffix]:
        return
    name = suffix[1:].upper().replace("GLTF", "glTF")
    said = (f"its content is {found}; rename it to that format's suffix" if found
            else f"its content does not start as a {name} file does; expected {READABLE}")
    raise SceneError(f"cannot read {str(path)!r} as {name}: {said}", where)


def is_number(word: str | bytes) -> bool:
    """Whether a word of a text mesh file (OBJ, MTL, ASCII STL) reads as a number, as Python's float() does
    (1.5, -2e-3, nan, inf); MSVC's `1.#IND` and a control byte do not."""
    try:
        float(word)
    except ValueError:
        return False
    return True
