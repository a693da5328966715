"""Mesh files: one module per format behind one interface (format.MeshFormat), and the registry of them.

Adding a format is one module that fills a MeshFormat and one line in FORMATS. A suffix no module claims but
trimesh reads is read by trimesh with the defaults (`format_of`). Around the formats: content.py (a file's
first bytes against its suffix), source.py (MeshSource: one object per file, what every stage wants of it,
read once), size.py (the memory a read costs, before it), read.py (the read, finished into a MeshFile the same
way for every format), trimesh_parts.py (trimesh's side). No trimesh here: the registry stays light.
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

from . import collada, gltf, obj, off, ply, stl, threemf
from .format import MeshFormat

FORMATS: tuple[MeshFormat, ...] = (obj.FORMAT, ply.FORMAT, stl.FORMAT, off.FORMAT, gltf.FORMAT, threemf.FORMAT,
                                   collada.FORMAT)
BY_SUFFIX = {suffix: kind for kind in FORMATS for suffix in kind.suffixes}


def format_of(path: str | Path) -> MeshFormat:
    """The format of the mesh file at `path`, by its suffix: a registered one, else trimesh's own reader of
    that suffix with the defaults (named after the suffix)."""
    suffix = Path(path).suffix.lower()
    return BY_SUFFIX.get(suffix) or _trimesh_format(suffix)


@cache
def _trimesh_format(suffix: str) -> MeshFormat:
    from .format import Loaded

    def read(reading):
        from .trimesh_parts import load, parts
        return Loaded(parts(load(reading)))
    return MeshFormat(names=(suffix[1:].upper() or "a mesh",), suffixes=(suffix,), read=read)


def is_mesh_file(path: str | Path) -> bool:
    """Whether `path` names a mesh file by its suffix: a registered format's, or one trimesh reads (trimesh is
    imported only for a suffix no format claims)."""
    suffix = Path(path).suffix.lower()
    if suffix in BY_SUFFIX:
        return True
    if not suffix:
        return False
    import trimesh
    return suffix[1:] in trimesh.available_formats()
