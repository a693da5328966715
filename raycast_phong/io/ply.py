"""PLY texture comments (MeshLab's `comment TextureFile NAME`, with per-face `texcoord` lists or per-vertex
`s t` / `texture_u texture_v`): the image beside the file becomes the k_d map of a white material, as a viewer
shows it. trimesh reads the first TextureFile and the coordinates, but hands the image on as a plain material
this package did not map, and logs a 10-line traceback when the image is missing (MeshLab writes `<this>` for
the PLY's own name, which trimesh looks for literally). Here `<this>` is the file's stem, a missing image is one
note, and a file naming several images (`texnumber` per face) uses the first (one note)."""

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
