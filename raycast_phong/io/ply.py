"""PLY texture comments (MeshLab's `comment TextureFile NAME`, with per-face `texcoord` lists or per-vertex
`s t` / `texture_u texture_v`): the image beside the file becomes the k_d map of a white material, as a viewer
shows it. trimesh reads the first TextureFile and the coordinates, but hands the image on as a plain material
this package did not map, and logs a 10-line traceback when the image is missing (MeshLab writes `<this>` for
the PLY's own name, which trimesh looks for literally). Here `<this>` is the file's stem, a missing image is one
note, and a file naming several images (`texnumber` per face) uses the first (one note). A header trimesh cannot
read has its first bad line named (ply_problem)."""

from __future__ import annotations

import logging
import re
from contextlib import contextmanager
from pathlib import Path

HEADER_LIMIT = 1 << 16  # a header is a few hundred bytes; the texture comments come before `end_header`


def texture_names(head: bytes) -> list[str]:
    """The TextureFile names of a PLY header (`head`: the file's first bytes), `<this>` not yet replaced."""
    end = head.find(b"end_header")
    header = head[:end if end >= 0 else len(head)].decode("latin-1")
    return [found.strip() for found in re.findall(r"^comment\s+TextureFile\s+(.+?)\s*$", header, re.M)]


# The PLY property types (Paul Bourke's PLY format, and the sized names rply and MeshLab write).
PLY_TYPES = ("char", "uchar", "short", "ushort", "int", "uint", "float", "double", "int8", "uint8", "int16",
             "uint16", "int32", "uint32", "float32", "float64")


def ply_problem(head: bytes) -> str | None:
    """What is wrong with a PLY header (`head`: the file's first bytes) trimesh could not read, in words naming
    the header line: a property whose type is not a PLY type (assimp's fuzzed crash-*.ply: binary bytes where
    the type goes), an element without a count, or no `end_header`; None when the header looks right."""
    lines = head.split(b"\n")
    for number, raw in enumerate(lines, 1):
        words = raw.decode("latin-1").split()
        if words == ["end_header"]:
            return None
        if words[:1] == ["property"]:
            types = words[2:4] if words[1:2] == ["list"] else words[1:2]
            wanted = 4 if words[1:2] == ["list"] else 2
            bad = next((kind for kind in types if kind not in PLY_TYPES), None)
            if bad is not None or len(types) < wanted - 1 or len(words) < wanted + 1:
                shown = repr(bad[:40]) if bad is not None else repr(" ".join(words)[:60])
                return (f"header line {number}: property type {shown} is not a PLY type, or the property has no "
                        f"name; allowed: property TYPE NAME or property list TYPE TYPE NAME, TYPE one of "
                        f"{', '.join(PLY_TYPES[:8])}")
        if words[:1] == ["element"] and (len(words) != 3 or not words[2].isdigit()):
            return (f"header line {number}: {' '.join(words)[:60]!r} is not an element; allowed: element NAME "
                    "COUNT, COUNT a whole number")
    return f"has no end_header line in its first {len(head)} bytes; allowed: a PLY header ending in end_header"


def resolved(name: str, path: Path) -> str:
    """A TextureFile name as MeshLab means it: `<this>` stands for the PLY's own name without its suffix."""
    return name.replace("<this>", path.stem)


@contextmanager
def trimesh_quiet():
    """trimesh's logger silenced while it reads (it logs a traceback for an image it cannot open; the read says
    one note instead)."""
    logger = logging.getLogger("trimesh")
    before = logger.disabled
    logger.disabled = True
    try:
        yield
    finally:
        logger.disabled = before
