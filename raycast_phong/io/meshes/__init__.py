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
from .format import Loaded, MeshFormat

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
    def read(reading):
        from .trimesh_parts import load, parts
        return Loaded(parts(load(reading)))
    return MeshFormat(names=(suffix[1:].upper() or "a mesh",), suffixes=(suffix,), read=read)


# Model formats people bring that no reader here reads, by suffix: refused in one line naming the format, what is
# read, and how to convert, instead of being read as a scene file (an FBX gave a TOML syntax error).
UNREAD = {".fbx": "FBX", ".blend": "Blender", ".3ds": "3D Studio", ".max": "3ds Max", ".c4d": "Cinema 4D",
          ".ma": "Maya", ".mb": "Maya", ".lwo": "LightWave", ".lws": "LightWave", ".skp": "SketchUp", ".abc": "Alembic",
          ".usd": "USD", ".usda": "USD", ".usdc": "USD", ".usdz": "USD", ".x3d": "X3D", ".wrl": "VRML",
          ".vrml": "VRML", ".step": "STEP", ".stp": "STEP", ".iges": "IGES", ".igs": "IGES", ".ifc": "IFC",
          ".md2": "Quake MD2", ".md5mesh": "Doom 3 MD5", ".x": "DirectX", ".ac": "AC3D", ".ase": "3ds Max ASCII",
          ".mtl": "a material library (the .obj that names it is the model)"}
# What a file's first bytes say it is, for a file that is neither a scene nor a mesh format read here.
CONTENT = ((b"Kaydara FBX Binary", "FBX"), (b"BLENDER", "Blender"), (b"\x89PNG", "a PNG image"),
           (b"\xff\xd8\xff", "a JPEG image"), (b"GIF8", "a GIF image"), (b"%PDF", "a PDF document"),
           (b"PK\x03\x04", "a zip archive"), (b"\x1f\x8b", "gzip-compressed data"))


def read_names() -> str:
    """The formats read here, for a message: "OBJ, PLY, STL, OFF, glTF/GLB, 3MF, COLLADA"."""
    return ", ".join("/".join(kind.names) for kind in FORMATS)


def unread(path: str | Path, head: bytes = b"") -> str | None:
    """Why the file at `path` (its first bytes `head`, when read) is a model format not read here, in one line with
    what is and how to convert; None when it is not one (a scene file, a mesh file read here, anything else)."""
    suffix = Path(path).suffix.lower()
    name = UNREAD.get(suffix) or next((what for magic, what in CONTENT if head.startswith(magic)), None)
    if name is None:
        return None
    how = ("; convert it to glTF (GLB) or OBJ, e.g. in Blender (File > Import, then File > Export > glTF 2.0) or "
           f"with assimp (assimp export model{suffix or ''} model.glb)") if name in UNREAD.values() else ""
    return f"its format is {name}, which this renderer does not read; it reads scene files (TOML, JSON) and " \
           f"mesh files ({read_names()}){how}"


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
