"""Read a mesh file (any format trimesh reads) with what it says about its surface: materials, colours, normals.

Everything the file says about materials is mapped here onto the lecture's model (k_a, k_d, k_s, f, k_e);
docs/meshes.md has the table term by term. Problems with the file's side files (a missing or broken .mtl,
textures) are notes, one line each, and the render goes on with defaults; a file that is not a mesh is a
SceneError, one line.

A file read to frame a camera (scene.framing) is kept for the render that follows, so a 2M-triangle file is
read once: the hand-over is the file-version cache KEPT (io.files.VersionCache, one entry keyed on the
file's and its side files' versions), which the framing read fills and the geometry stage's read takes (not
copies); the bounds framing needs stay in BOUNDS, a small cache of their own.
"""

from __future__ import annotations

import io
import math
import os
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
import trimesh

from ..codes import GLTF_WRAP, MATERIAL_DEFAULTS
from ..errors import SceneError, Where
from ..records import bounding_box
from ..tolerances import POSITION_LIMIT
from .files import VersionCache, file_version, open_mesh_file, open_regular
from .mesh_header import gltf_buffer_files

TRIMESH = Path(trimesh.__file__).resolve().parent  # an exception that passed through here: trimesh refused the file
TEXT_FORMATS = (".obj", ".off")  # trimesh decodes these as text, guessing any non-UTF-8 encoding
MAX_SIDE_FILE = 16 << 20  # an .mtl is text of a few kB; refuse to read more than a scene file may be
READABLE = "a mesh file trimesh reads (OBJ, PLY, STL, OFF, GLB)"
# Up axes the formats' specifications state (glTF 2.0 §3.4: +Y up; 3MF core §3.4: +Z up); others say nothing.
STATED_UP = {".gltf": (0.0, 1.0, 0.0), ".glb": (0.0, 1.0, 0.0), ".3mf": (0.0, 0.0, 1.0)}
MAX_FILE_SHININESS = 1000.0  # the .mtl Ns range (0..1000); the glTF roughness map is capped to it too
# A file's specular lobe wider than the scene default's (f = 32) keeps at most that lobe's reflected energy:
# its k_s falls as (f + 2) / (WIDE_LOBE + 2) (specular_lobe says why), and f is at least MIN_FILE_SHININESS.
WIDE_LOBE = 32.0
MIN_FILE_SHININESS = 1.0
# The feature angle at which a file without normals is creased (VTK's vtkPolyDataNormals and Blender's
# auto-smooth both default to 30°): CAD faces keep their edges, a scan's small angles stay smooth.
FILE_CREASE_ANGLE = 30.0


class TextureSource(NamedTuple):
    """A colour map a file's material names, not yet decoded (geometry.build decodes the ones faces use)."""
    source: object   # a Path (decoded with OpenImageIO) or the PIL image trimesh opened (a glTF's embedded one)
    wrap_s: str      # codes.WRAP_MODES
    wrap_t: str
    name: str        # for notes


@dataclass(frozen=True)
class FileMaterial:
    """A named material of the file, already on the lecture's model (each coefficient in [0, 1])."""
    name: str
    ka: tuple[float, float, float]
    kd: tuple[float, float, float]
    ks: tuple[float, float, float]
    ke: tuple[float, float, float]
    shininess: float
    ka_map: int = -1  # index into MeshFile.texture_sources of the map multiplying k_a (-1: none)
    kd_map: int = -1  # ... k_d (and k_a when ka_map is -1)
    ke_map: int = -1  # ... k_e

    def as_scene(self) -> dict:
        """The keys of a [materials.NAME] table with these values."""
        return {"ka": list(self.ka), "kd": list(self.kd), "ks": list(self.ks), "ke": list(self.ke),
                "shininess": self.shininess}


@dataclass(frozen=True, eq=False)
class MeshFile:
    """A mesh file as read: one triangle mesh in the file's frame, and its surface description."""
    vertices: np.ndarray            # (V, 3) float64 (float32 as a binary STL stores them), every used vertex finite
                                    # and within ±POSITION_LIMIT
    faces: np.ndarray               # (F, 3) int64
    normals: np.ndarray | None      # (V, 3) float64 vertex normals the file stores, else None
    face_group: np.ndarray          # (F,) int32: index into `materials`, -1 for a face without a material
    materials: tuple[FileMaterial, ...]
    up: tuple[float, float, float] | None  # the up axis the format states, or None
    notes: tuple[str, ...]          # one line each: side files missing or broken, what is ignored
    centre: np.ndarray              # (3,) float64 centre of the used vertices' bounding box (NaN unless read
                                    # for framing: read_mesh(keep=True))
    radius: float                   # largest distance of a used vertex from `centre`
    stores_normals: bool = False    # whether the file stores vertex normals (kept in the bounds cache too)
    corner_uv: np.ndarray | None = None      # (F, 3, 2) texture coordinates per face corner (v up), taken before
                                             # any merge of repeated points so UV seams stay; None without UVs
    corner_colour: np.ndarray | None = None  # (F, 3, 3) float32 linear vertex colour per face corner in [0, 1],
                                             # -1 on faces of a part without colours; None without colours
    texture_sources: tuple[TextureSource, ...] = ()


# ---------------------------------------------------------------- the cache

KEPT: VersionCache[MeshFile] = VersionCache(1)     # identity → the file read for framing, waiting for its render
BOUNDS: VersionCache[MeshFile] = VersionCache(64)  # identity → a file stripped of its arrays (centre, radius, ...)
SIDE_FILES: VersionCache[tuple[Path, ...]] = VersionCache(64)  # a mesh file's version → the files it names


def mesh_identity(path: Path) -> tuple:
    """The file as it is now: resolved path, mtime, size, inode (a rewrite changes at least one), and the same
    of its side files (an .mtl edited alone changes the materials)."""
    def stamp(file: Path) -> tuple:
        try:
            return file_version(file)
        except OSError:
            return (str(file), None)
    os.stat(path)  # a missing mesh file: no identity (the read words the error)
    return (stamp(path), *(stamp(side) for side in side_files(path)))


def read_mesh(path: Path, where: Where, keep: bool = False) -> MeshFile:
    """The mesh file at `path`; `where` starts every error ("scene.toml: objects.0.path").

    keep=True (framing a camera) leaves the result for the next read of the same unchanged file, which
    takes it; so the render that follows a framing does not read the file again.
    """
    try:
        identity = mesh_identity(path)
    except OSError:
        identity = None  # let the read word the error
    if identity is not None:
        found = KEPT.get(identity) if keep else KEPT.take(identity)
        if found is not None:
            return found
    found = _read(path, where, bounds=keep)
    if keep and identity is not None:
        KEPT.put(identity, found)
        _remember_bounds(identity, found)
    return found


def mesh_bounds(path: Path, where: Where) -> MeshFile:
    """The file's centre, radius, up axis, materials and notes (its arrays may be empty): from the small
    cache when this unchanged file was read before, else read (and kept for the render)."""
    try:
        identity = mesh_identity(path)
    except OSError:
        identity = None
    found = BOUNDS.get(identity) if identity is not None else None
    return found if found is not None else read_mesh(path, where, keep=True)


def _remember_bounds(identity: tuple, found: MeshFile) -> None:
    empty = np.zeros((0, 3))
    BOUNDS.put(identity, MeshFile(empty, empty.astype(np.int64), None, np.zeros(0, np.int32), found.materials,
                                 found.up, found.notes, found.centre, found.radius, found.normals is not None))


def side_files(path: Path) -> list[Path]:
    """The files a mesh file names that change its image: an OBJ's .mtl files (every one its `mtllib` lines
    name, as read), a .gltf's external buffers. For `batch`'s up-to-date rule and the read cache's identity.
    The OBJ is read whole (`mtllib` may come anywhere, and more than once), so the answer is kept per version
    of the file (path, mtime, size, inode): framing, the render's read and batch scan it once."""
    try:
        version = file_version(path)
    except OSError:
        return []  # the render reports a missing file
    return list(SIDE_FILES.setdefault((str(path), *version), lambda: _side_files(Path(path))))


def _side_files(path: Path) -> tuple[Path, ...]:
    """side_files of the file as it is now."""
    suffix = path.suffix.lower()
    try:
        if suffix == ".obj":
            with open_regular(path, str(path), "mesh file") as handle:
                lines, carry = [], b""
                for block in iter(lambda: handle.read(1 << 20), b""):
                    block = carry + block
                    cut = block.rfind(b"\n") + 1  # whole lines only: a line split between two blocks waits
                    if b"mtllib" in block[:cut]:  # find() at memory speed; the pattern only where it can match
                        lines += MTLLIB.findall(block[:cut])
                    carry = block[cut:][-4096:]  # an mtllib line is short: a longer remainder is no mtllib
                lines += MTLLIB.findall(carry)
            return tuple(path.parent / name for name in mtllib_names(lines, path.parent))
        elif suffix == ".gltf":
            return gltf_buffer_files(path)
    except (OSError, SceneError, ValueError, RecursionError, TypeError, AttributeError):
        pass  # the render reports an unreadable file (JSON nested too deep, buffers that are not a list, ...)
    return ()


# ---------------------------------------------------------------- reading

def _read(path: Path, where: Where, bounds: bool = True) -> MeshFile:
    handle = open_mesh_file(path, where)
    notes: list[str] = []
    suffix = path.suffix.lower()
    try:
        # Load unprocessed: trimesh's cleaning would silently drop NaN vertices and their faces.
        with handle:
            check_content(path, handle, where)
            samplers = _check_gltf(path, handle, where, notes) if suffix in (".gltf", ".glb") else {}
            if suffix == ".dae":
                _check_collada_images(path, handle, notes)
            sources: list[TextureSource] = []
            points = _binary_stl_points(handle) if suffix == ".stl" else None
            if points is None:
                source = _mesh_source(path, handle, where)
                library = _obj_materials(path, source["file_obj"], notes, sources) if suffix == ".obj" else None
                if library is not None:
                    source["resolver"] = _MaterialNames(path, library)
                loaded = _load_obj(source) if suffix == ".obj" else trimesh.load(**source, process=False)
        if points is not None:  # the corners in file order, as trimesh's reader gives them (without its float64)
            library, parts = None, [_Part(points, np.arange(len(points), dtype=np.int64).reshape(-1, 3), None, None)]
        else:
            parts = _parts(loaded) or _strip_parts(loaded)
    except SceneError:
        raise
    except Exception as error:
        if not _raised_in_trimesh(error):
            raise  # our own bug, not the file's: an internal error with its traceback
        raise SceneError(f"cannot read {str(path)!r} as {READABLE} ({type(error).__name__}: "
                         f"{error})", where) from None
    if not parts:
        raise SceneError(f"{str(path)!r} holds no triangles; expected {READABLE}", where)
    vertices, faces, normals = _concatenate(parts)
    if vertices.ndim != 2 or vertices.shape[1] != 3:  # an OBJ `v x y`, a glTF POSITION of VEC2
        given = vertices.shape[1] if vertices.ndim == 2 else vertices.ndim
        raise SceneError(f"{str(path)!r} gives its vertices {given} coordinate(s) each; allowed: 3 (x, y, z)", where)
    if faces.size and not (0 <= faces.min() and faces.max() < len(vertices)):
        bad = int(((faces < 0) | (faces >= len(vertices))).any(axis=1).sum())
        raise SceneError(f"{str(path)!r} has {bad} face(s) with a vertex index outside 0..{len(vertices) - 1} "
                         f"(first: {faces[((faces < 0) | (faces >= len(vertices))).any(axis=1)][0].tolist()}); "
                         "allowed: indices of the file's own vertices", where)
    mask = np.zeros(len(vertices), bool)
    mask[faces.ravel()] = True  # the vertices faces use: O(F), where np.unique would sort
    used = vertices if mask.all() else vertices[mask]
    _check_values(used, path, where)
    face_group, materials, corner_uv, corner_colour = _surfaces(parts, library, path, notes, sources,
                                                                            samplers)
    centre, radius = np.full(3, np.nan), math.nan
    if bounds:  # only framing needs them: a render's own read skips the pass
        low, high = (side.astype(np.float64) for side in bounding_box(used))  # column by column (records says why)
        centre = (low + high) / 2
        radius = float(np.sqrt(((used - centre) ** 2).sum(axis=1).max()))
        hint = up_hint(high - low, suffix)
        if hint:
            notes.append(f"{path}: {hint}")
    return MeshFile(vertices, faces, normals, face_group, materials, STATED_UP.get(suffix),
                    tuple(dict.fromkeys(notes)), centre, radius, normals is not None, corner_uv, corner_colour,
                    tuple(sources))


STL_RECORD = np.dtype([("normal", "<f4", 3), ("points", "<f4", (3, 3)), ("attribute", "<u2")])  # 50 bytes


def _binary_stl_points(handle) -> np.ndarray | None:
    """A binary STL's corner points (3F, 3) float32 in file order (corner k of triangle f at row 3f + k), or None
    if the file is not one (an ASCII STL: its size does not match the header's count) or holds no triangle.

    The values trimesh's reader gives, without its float64 (3F, 3) copy (72 bytes a triangle) and the hashing
    its Trimesh does to validate the file's face normals (0.25 s at 1M triangles); the normals (the renderer
    computes its own), the attribute bytes and the 80-byte header are not kept, as trimesh keeps none of them
    for shading. The records are read into one array (50 bytes a triangle), their points copied out (36)."""
    handle.seek(0)
    head = handle.read(84)
    size = os.fstat(handle.fileno()).st_size
    count = int.from_bytes(head[80:84], "little") if len(head) == 84 else 0
    if count == 0 or size != 84 + STL_RECORD.itemsize * count:
        handle.seek(0)
        return None
    records = np.empty(count, STL_RECORD)
    if handle.readinto(records.view(np.uint8)) != count * STL_RECORD.itemsize:
        handle.seek(0)
        return None  # the file shrank under us: let trimesh word it
    return np.ascontiguousarray(records["points"], np.float32).reshape(-1, 3)


# ---------------------------------------------------------------- what the content is

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


# Required glTF extensions read here; any other one in extensionsRequired is refused (glTF 2.0 §3.12: a loader
# must not load a file whose required extensions it does not support). Draco needs DracoPy.
SUPPORTED_REQUIRED = ("KHR_draco_mesh_compression",)


def _check_gltf(path: Path, handle, where: Where, notes: list[str]) -> dict:
    """The glTF's JSON (a .glb's first chunk): refuse required extensions that are not supported, naming them;
    a note for each image file it names that is missing. Returns the wrap modes of each material's colour
    maps: {(material name, "baseColorTexture" or "emissiveTexture"): (wrap_s, wrap_t)} (trimesh drops them)."""
    import json
    try:
        if path.suffix.lower() == ".glb":
            header = handle.read(20)
            length = int.from_bytes(header[12:16], "little")
            text = handle.read(min(length, MAX_SIDE_FILE)) if header[16:20] == b"JSON" else b"{}"
        else:
            text = handle.read(MAX_SIDE_FILE)
        document = json.loads(text)
    except (ValueError, UnicodeDecodeError):
        document = {}  # trimesh words what is wrong with the file
    except RecursionError:  # Python's parser recurses per level: no glTF is nested a thousand deep
        raise SceneError(f"{str(path)!r}: its JSON is nested deeper than Python's parser reads; allowed: "
                         "a glTF document (a few levels of objects and lists)", where) from None
    finally:
        handle.seek(0)
    if not isinstance(document, dict):
        return {}
    required = [e for e in document.get("extensionsRequired", []) if isinstance(e, str)]
    missing = [e for e in required if e not in SUPPORTED_REQUIRED]
    if "KHR_draco_mesh_compression" in required:
        try:
            import DracoPy  # noqa: F401  (trimesh decodes Draco with it)
        except ImportError:
            missing.insert(0, "KHR_draco_mesh_compression (Draco compression: pip install DracoPy)")
    if missing:
        raise SceneError(f"{str(path)!r} requires the glTF extension(s) {', '.join(missing)}, which this "
                         f"renderer does not support; supported: {', '.join(SUPPORTED_REQUIRED)}", where)
    from urllib.parse import unquote
    for image in document.get("images", []):
        uri = image.get("uri") if isinstance(image, dict) else None
        if isinstance(uri, str) and not uri.startswith("data:") and not (path.parent / unquote(uri)).is_file():
            notes.append(f"{path}: texture {unquote(uri)!r} is missing")
    return _gltf_samplers(document)


def _check_collada_images(path: Path, handle, notes: list[str]) -> None:
    """A note for each image file a COLLADA file's <library_images> names that is missing: trimesh's reader
    drops such a map without a word, and the model renders in its factors alone (white for the duck).

    Read from the file's first MAX_SIDE_FILE bytes (exporters write the images before the geometry); the
    path is <init_from> (1.4) or its <ref> (1.5), a URI relative to the file."""
    from pathlib import PurePosixPath
    from urllib.parse import unquote, urlparse
    try:
        text = handle.read(MAX_SIDE_FILE).decode("utf-8", errors="replace")
    finally:
        handle.seek(0)
    for image in re.findall(r"<image\b[^>]*>(.*?)</image>", text, re.S):
        found = re.search(r"<init_from>\s*(?:<ref>)?\s*([^<]+?)\s*<", image)
        if found is None or found[1].startswith("data:"):
            continue
        uri = urlparse(found[1])
        name = str(PurePosixPath(unquote(uri.path))) if uri.scheme in ("", "file") else found[1]
        if uri.scheme in ("", "file") and not (path.parent / name).is_file():
            notes.append(f"{path}: texture {name!r} is missing")


def _gltf_samplers(document: dict) -> dict:
    """{(material name, slot): (wrap_s, wrap_t)} from the glTF's samplers (10497 repeat, 33071 clamp, 33648
    mirror; a texture without a sampler repeats, glTF 2.0 §5.26)."""
    found = {}
    try:
        textures, samplers = document.get("textures", []), document.get("samplers", [])
        for material in document.get("materials", []):
            slots = {"baseColorTexture": (material.get("pbrMetallicRoughness") or {}).get("baseColorTexture"),
                     "emissiveTexture": material.get("emissiveTexture")}
            for slot, info in slots.items():
                if not isinstance(info, dict) or not isinstance(info.get("index"), int):
                    continue
                sampler = textures[info["index"]].get("sampler")
                modes = samplers[sampler] if isinstance(sampler, int) else {}
                found.setdefault((material.get("name"), slot), (GLTF_WRAP.get(modes.get("wrapS"), "repeat"),
                                                                GLTF_WRAP.get(modes.get("wrapT"), "repeat")))
    except (AttributeError, IndexError, TypeError):
        pass  # a malformed table: every map repeats
    return found


Z_UP_RATIO = 1.5  # a model this many times longer along Z than along Y (and longest along Z) looks Z-up


def up_hint(extent: np.ndarray, suffix: str) -> str | None:
    """A one-line hint when a format that states no up axis holds a model that looks Z-up: longest along Z
    and at least Z_UP_RATIO times longer along Z than along Y (a scanned statue, a standing figure from a
    Z-up tool), which the default +Y up shows lying on its back. None otherwise (docs/meshes.md, "Up")."""
    if suffix in STATED_UP or not extent[2] > 0:
        return None
    if extent[2] >= extent.max() and extent[2] >= Z_UP_RATIO * extent[1]:
        return (f"the model is {extent[2] / max(extent[1], 1e-300):.3g}× longer along Z than along Y, as models "
                "made Z-up are; the view takes +Y as up (the format states none), so if it lies on its back, "
                "add --up z")
    return None


class _Part(NamedTuple):
    """One placed triangle mesh of what trimesh loaded."""
    vertices: np.ndarray          # (V, 3) float64, placed by its node's transform
    faces: np.ndarray             # (F, 3) int64
    normals: np.ndarray | None    # (V, 3) the normals the file stores, transformed with the vertices
    visual: object                # trimesh's visual: its material, its colours


def _parts(loaded) -> list[_Part]:
    """The triangle meshes of what trimesh loaded, in world placement (a glTF's node transforms applied).

    Not Scene.dump(): its copies forget the vertex normals the file stored."""
    if isinstance(loaded, trimesh.Trimesh):
        instances = [(np.eye(4), loaded)]
    elif isinstance(loaded, trimesh.Scene):
        instances = [(np.asarray(loaded.graph[node][0], np.float64), loaded.geometry[loaded.graph[node][1]])
                     for node in loaded.graph.nodes_geometry]
    else:
        instances = []
    parts = []
    for transform, mesh in instances:
        if not isinstance(mesh, trimesh.Trimesh) or not len(mesh.faces):
            continue
        linear, faces = transform[:3, :3], np.asarray(mesh.faces, np.int64)
        vertices = np.asarray(mesh.vertices, np.float64)
        # The raw dict, not `in mesh._cache`: that re-hashes the arrays to validate the cache (slow without xxhash).
        normals = mesh._cache.cache.get("vertex_normals")
        normals = None if normals is None else np.asarray(normals, np.float64)
        if not np.array_equal(transform, np.eye(4)):  # most files: one part, placed as it is
            vertices = vertices @ linear.T + transform[:3, 3]
            # Normals transform with the inverse transpose; their length is set by the geometry stage.
            normals = None if normals is None or np.linalg.det(linear) == 0 else normals @ np.linalg.inv(linear)
            if np.linalg.det(linear) < 0:
                faces = faces[:, ::-1]  # a mirroring node keeps the faces outward
        parts.append(_Part(vertices, faces, normals, mesh.visual))
    return parts


def _strip_parts(loaded) -> list[_Part]:
    """A PLY that stores triangle strips (a `tristrips` element, -1 between strips) as triangles: trimesh
    reads only its vertices. Strip triangle i is (s_i, s_i+1, s_i+2), every other one reversed to keep the
    winding; triangles that repeat a vertex (the strips' joins) are dropped."""
    raw = getattr(loaded, "metadata", {}).get("_ply_raw") if hasattr(loaded, "metadata") else None
    if not raw or "tristrips" not in raw or "vertex" not in raw:
        return []
    data = raw["tristrips"]["data"]
    try:
        field = data["vertex_indices"]
        rows = field["f1"] if field.dtype.names else field
        strips = np.concatenate([np.append(np.asarray(row, np.int64).ravel(), -1) for row in np.atleast_1d(rows)])
    except (KeyError, ValueError, TypeError, IndexError):
        return []
    vertex = raw["vertex"]["data"]
    try:
        vertices = np.column_stack([np.asarray(vertex[k], np.float64).ravel() for k in ("x", "y", "z")])
    except (KeyError, ValueError, TypeError, IndexError):
        return []
    if len(strips) < 3:
        return []
    windows = np.lib.stride_tricks.sliding_window_view(strips, 3)
    restart = np.flatnonzero(strips < 0)
    start = np.zeros(len(strips), np.int64)  # where each position's strip starts
    start[restart[restart + 1 < len(strips)] + 1] = restart[restart + 1 < len(strips)] + 1
    start = np.maximum.accumulate(start)[: len(windows)]
    odd = (np.arange(len(windows)) - start) % 2 == 1
    keep = ((windows >= 0).all(axis=1) & (windows[:, 0] != windows[:, 1]) & (windows[:, 1] != windows[:, 2])
            & (windows[:, 0] != windows[:, 2]))
    faces = np.where(odd[:, None], windows[:, [1, 0, 2]], windows)[keep]
    if not len(faces):
        return []
    return [_Part(vertices, faces, None, trimesh.visual.ColorVisuals())]


def _concatenate(parts: list[_Part]) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """One vertex and face array; vertex normals only if every part stores them."""
    if len(parts) == 1:
        return parts[0].vertices, parts[0].faces, parts[0].normals
    offsets = np.cumsum([0] + [len(part.vertices) for part in parts])
    vertices = np.concatenate([part.vertices for part in parts])
    faces = np.concatenate([part.faces + o for part, o in zip(parts, offsets)])
    stored = all(part.normals is not None for part in parts)
    normals = np.concatenate([part.normals for part in parts]) if stored else None
    return vertices, faces, normals


def _check_values(coordinates: np.ndarray, path: Path, where: Where) -> None:
    """Every vertex of a face (`coordinates`, (U, 3)) finite and within ±POSITION_LIMIT (trimesh squares
    coordinates)."""
    if (np.abs(coordinates) <= np.float64(POSITION_LIMIT)).all():  # one pass (float32 compared in float64); NaN fails
        return
    finite = np.isfinite(coordinates).all(axis=1)
    if not finite.all():
        raise SceneError(f"{str(path)!r} has {int((~finite).sum())} vertex(es) with NaN or infinite "
                         "coordinates; every vertex of a face must have finite coordinates", where)
    huge = (np.abs(coordinates) > POSITION_LIMIT).any(axis=1)
    if huge.any():
        raise SceneError(f"{str(path)!r} has {int(huge.sum())} vertex(es) with a coordinate beyond "
                         f"±{POSITION_LIMIT:g} (largest {float(np.abs(coordinates).max()):.3g}); allowed: within "
                         f"±{POSITION_LIMIT:g}, so lengths squared stay finite", where)


# ---------------------------------------------------------------- materials and colours

def _surfaces(parts, library: dict[str, FileMaterial] | None, path: Path, notes: list[str],
              sources: list[TextureSource], samplers: dict):
    """Per face: its material (an index into the returned tuple, -1 for none); per corner: the texture
    coordinates (None unless some used material has a map) and the vertex colours (None unless some part
    has colours)."""
    materials: list[FileMaterial] = []
    index: dict[str, int] = {}
    groups, corners, uvs, any_colour, gltf = [], [], [], False, False
    for part in parts:
        material = getattr(part.visual, "material", None)
        found = None
        if isinstance(material, trimesh.visual.material.PBRMaterial):
            found, gltf = _from_pbr(material, path, notes, sources, samplers), True
        elif material is not None and library is not None:
            found = library.get(getattr(material, "name", None) or "")
        if found is not None:
            # Two different materials under one name (glTF names are optional) each keep their own values.
            name, copy = found.name, 1
            while name in index and materials[index[name]] != replace(found, name=name):
                copy += 1
                name = f"{found.name}-{copy}"
            found = replace(found, name=name)
            if name not in index:
                index[name] = len(materials)
                materials.append(found)
        groups.append(np.full(len(part.faces), index[found.name] if found is not None else -1, np.int32))
        uv = getattr(part.visual, "uv", None)
        uvs.append(None if uv is None or len(uv) != len(part.vertices)
                   else np.asarray(uv, np.float64)[:, :2][part.faces].astype(np.float32))
        corner = _corner_colours(part)
        any_colour |= corner is not None
        corners.append(corner)
    if gltf:  # glTF's own materials, or a file whose materials trimesh reads as metallic-roughness (COLLADA)
        kind = "glTF metallic-roughness" if path.suffix.lower() in (".gltf", ".glb") else "metallic-roughness (PBR)"
        notes.append(f"{path}: {kind} materials are approximated on the Phong model: k_d = k_a = "
                     "base colour, F0 = 0.04 + (base colour − 0.04) × metallic, f = 2/roughness⁴ − 2 in [1, "
                     f"{MAX_FILE_SHININESS:g}], k_s = F0 × min(1, (f + 2)/{WIDE_LOBE + 2:g}), k_e = emissive "
                     "(docs/meshes.md)")
    corner_colour = corner_uv = None
    if any_colour:
        # A part without colours keeps its material's own k_d: mark it with -1 to tell it apart.
        corner_colour = np.concatenate([c if c is not None else np.full((len(p.faces), 3, 3), -1, np.float32)
                                        for c, p in zip(corners, parts)])
    mapped = any(m.ka_map >= 0 or m.kd_map >= 0 or m.ke_map >= 0 for m in materials)
    if mapped:  # a part without texture coordinates reads its maps at (0, 0), as GL reads a missing attribute
        if any(u is None for u, g in zip(uvs, groups) if len(g) and g[0] >= 0
               and max(materials[g[0]].ka_map, materials[g[0]].kd_map, materials[g[0]].ke_map) >= 0):
            notes.append(f"{path}: a textured part has no texture coordinates; its maps are read at (0, 0)")
        corner_uv = np.concatenate([u if u is not None else np.zeros((len(p.faces), 3, 2), np.float32)
                                    for u, p in zip(uvs, parts)])
    return np.concatenate(groups), tuple(materials), corner_uv, corner_colour


def _corner_colours(part: _Part) -> np.ndarray | None:
    """(F, 3, 3) float32 colour in [0, 1] at each face corner: vertex colours (8-bit /255), a face's colour
    at its three corners, or glTF's COLOR_0 beside a material (trimesh keeps it as a vertex attribute);
    None when the part has none. Taken as stored (glTF's COLOR_0 is linear; PLY and OFF colours say nothing,
    and are read as linear too, as before)."""
    visual = part.visual
    kind = getattr(visual, "kind", None)
    if isinstance(visual, trimesh.visual.ColorVisuals) and kind == "vertex":
        rgb = np.asarray(visual.vertex_colors)[:, :3].astype(np.float32) / 255.0
        return rgb[part.faces]
    if isinstance(visual, trimesh.visual.ColorVisuals) and kind == "face":
        rgb = np.asarray(visual.face_colors)[:, :3].astype(np.float32) / 255.0
        return np.repeat(rgb[:, None, :], 3, axis=1)
    attributes = getattr(visual, "vertex_attributes", None) or {}
    raw = attributes.get("color") if hasattr(attributes, "get") else None
    if raw is None or len(raw) != len(part.vertices):
        return None
    raw = np.asarray(raw)
    scale = 1.0 if raw.dtype.kind == "f" else float(np.iinfo(raw.dtype).max)
    rgb = np.clip(np.asarray(raw, np.float64).reshape(len(raw), -1)[:, :3] / scale, 0, 1).astype(np.float32)
    if rgb.shape[1] < 3:
        return None
    return rgb[part.faces]


def specular_lobe(ks, shininess: float) -> tuple[np.ndarray, float]:
    """A file's (k_s, f) made into a highlight the lecture's lobe shows faithfully (docs/meshes.md, "Highlights").

    The lecture's lobe max(v·r, 0)^f peaks at k_s whatever its width, so a wide lobe reflects far more light
    than a surface can: f = 0 (glTF roughness 1, .mtl Ns 0) is a second, view-independent diffuse term at
    full strength, which saturates the whole lit side. A normalised lobe's peak is (f + 2)/2π times the light
    it reflects, so a lobe wider than WIDE_LOBE (the scene default's f) has its peak lowered by
    (f + 2)/(WIDE_LOBE + 2): it reflects no more than a WIDE_LOBE lobe of the stated k_s, and a fully rough
    surface looks matte. Lobes at least as narrow keep the file's k_s; f is kept in [1, 1000].
    """
    shininess = min(max(float(shininess), MIN_FILE_SHININESS), MAX_FILE_SHININESS)
    return np.asarray(ks, np.float64) * min(1.0, (shininess + 2) / (WIDE_LOBE + 2)), shininess


def _from_pbr(material, path: Path, notes: list[str], sources: list[TextureSource], samplers: dict) -> FileMaterial:
    """glTF 2.0 metallic-roughness → Phong: a stated approximation (docs/meshes.md).

    k_d = k_a = base colour; k_s = F0 of the metallic workflow, lerp(0.04, base colour, metallic) (glTF
    2.0 Appendix B); f = 2/α² − 2 with α = roughness², the Blinn-Phong exponent of the same lobe width
    (Walter et al. 2007); both through specular_lobe, so roughness 1 is matte; k_e = emissive factor.
    A baseColorTexture is the k_d map (and k_a's), an emissiveTexture the k_e map, each with its sampler's
    wrap modes (decoded later, only if a face uses the material). glTF's defaults: base colour 1, metallic 1,
    roughness 1, emissive 0.
    """
    base = material.baseColorFactor
    base = np.ones(4) if base is None else np.asarray(base, np.float64) / 255.0
    metallic = 1.0 if material.metallicFactor is None else float(material.metallicFactor)
    roughness = 1.0 if material.roughnessFactor is None else float(material.roughnessFactor)
    emissive = np.zeros(3) if material.emissiveFactor is None else np.asarray(material.emissiveFactor, np.float64)
    rgb = np.clip(base[:3], 0, 1)
    metallic, roughness = min(max(metallic, 0.0), 1.0), min(max(roughness, 0.0), 1.0)
    alpha = roughness * roughness
    shininess = MAX_FILE_SHININESS if alpha == 0 else 2 / alpha**2 - 2
    name = material.name or f"{path.stem}-material"
    if base[3] < 1 or getattr(material, "alphaMode", None) in ("BLEND", "MASK"):
        notes.append(f"{path}: material {name!r}: transparency (alpha {base[3]:.3g}) is ignored: surfaces are opaque")
    maps = {}
    for key in ("baseColorTexture", "emissiveTexture"):
        image = getattr(material, key, None)
        if image is None:
            continue
        wrap_s, wrap_t = samplers.get((material.name, key), ("repeat", "repeat"))
        maps[key] = len(sources)
        sources.append(TextureSource(image, wrap_s, wrap_t, f"{path}: material {name!r}: its {key}"))
    ignored = [key for key in ("metallicRoughnessTexture", "normalTexture", "occlusionTexture")
               if getattr(material, key, None) is not None]
    if ignored:
        notes.append(f"{path}: material {name!r}: {', '.join(ignored)} not applied; its factors are used")
    ks, shininess = specular_lobe(0.04 + (rgb - 0.04) * metallic, shininess)
    return FileMaterial(name, _rgb(rgb), _rgb(rgb), _rgb(ks), _rgb(np.clip(emissive[:3], 0, 1)), float(shininess),
                        kd_map=maps.get("baseColorTexture", -1), ke_map=maps.get("emissiveTexture", -1))


def _rgb(values) -> tuple[float, float, float]:
    return tuple(float(v) for v in values)  # type: ignore[return-value]


# ---------------------------------------------------------------- .mtl files

TEXTURE_KEYS = ("map_", "bump", "disp", "decal", "refl", "norm")


MTLLIB = re.compile(rb"^[ \t]*mtllib[ \t]+([^\r\n]+)", re.MULTILINE)  # an OBJ's mtllib statement: its names


def mtllib_names(lines: list[bytes], folder: Path) -> list[str]:
    """The .mtl files named by an OBJ's `mtllib` statements (`lines`: each statement's text after `mtllib`),
    in order, each once. The OBJ specification lets one statement name several files: they are separated by
    blanks, a backslash escapes a space (`b\\ c.mtl` is "b c.mtl"), and a `#` word starts a comment. A
    statement whose whole text names a file beside the OBJ is that one file (`mtllib my model.mtl`, which
    exporters write unescaped and which was read so before)."""
    names = []
    for line in lines:
        text = line.decode("utf-8", "replace").strip()
        words = [word.replace("\\ ", " ") for word in re.split(r"(?<!\\)[ \t]+", text)]
        words = words[:next((i for i, word in enumerate(words) if word.startswith("#")), len(words))]
        whole = text.replace("\\ ", " ")
        try:
            if len(words) > 1 and (folder / whole).is_file():
                words = [whole]
        except OSError:
            pass  # a name too long to be one file: the words
        names += words
    return list(dict.fromkeys(name for name in names if name))


def _obj_materials(path: Path, text: io.BytesIO, notes: list[str],
                   sources: list[TextureSource] | None = None) -> dict[str, FileMaterial]:
    """The materials of every .mtl an OBJ's `mtllib` lines name (mtllib_names), by name: a name defined by
    several files keeps the first file's (the OBJ specification searches them in order). A missing or
    unreadable file is a note, and the others still count; {} when there are none."""
    data = text.getvalue()
    text.seek(0)
    # The pattern tries every byte of a file without one (0.19 s at 40 MB); find() looks at memory speed first.
    lines = MTLLIB.findall(data) if b"mtllib" in data else []
    library: dict[str, FileMaterial] = {}
    for name in mtllib_names(lines, path.parent):
        mtl = path.parent / name
        try:
            with open_regular(mtl, f"{path}: mtllib", "material file", MAX_SIDE_FILE) as handle:
                content = handle.read(MAX_SIDE_FILE + 1).decode("utf-8", "replace")
        except FileNotFoundError:
            notes.append(f"{path}: its material file {name!r} is missing; the default material is used")
            continue
        except (SceneError, OSError) as error:
            notes.append(f"{path}: its material file {name!r} cannot be read ({error}); the default material is "
                         "used")
            continue
        for key, material in parse_mtl(content, mtl, notes, sources).items():
            library.setdefault(key, material)
    return library


def parse_mtl(content: str, mtl: Path, notes: list[str],
              sources: list[TextureSource] | None = None) -> dict[str, FileMaterial]:
    """Wavefront .mtl → materials on the lecture's model (docs/meshes.md, "Materials").

    Ka → k_a, Kd → k_d, Ks → k_s, Ke → k_e, Ns → f; a key the material omits takes the scene default's
    value; illum 0 is colour only (k_e = Kd + Ke, the other terms 0), 1 has no specular term (k_s = 0),
    2 and above are Phong (reflection and refraction are out of scope). map_Kd, map_Ka and map_Ke are colour
    maps (appended to `sources`, found as _texture_path finds them, "-clamp on" clamps them, else they
    repeat); other maps (map_Ks, bump, ...) and d < 1 or Tr > 0 (transparency) are ignored, each said once.
    Coefficients outside [0, 1] are clamped, and said.
    """
    raw: dict[str, dict[str, list[str]]] = {}
    current = None
    for line in content.splitlines():
        words = line.split("#", 1)[0].split()
        if len(words) < 2:
            continue
        key = words[0].lower()
        if key == "newmtl":
            current = raw.setdefault(" ".join(words[1:]), {})
        elif current is not None:
            current[key] = words[1:]
    materials, bad, clamped, textures, transparent, illums = {}, [], [], [], [], set()
    sources = [] if sources is None else sources
    registered: dict[tuple, int] = {}
    for name, keys in raw.items():
        values = {}
        for key in ("ka", "kd", "ks", "ke", "ns", "d", "tr", "illum"):
            if key not in keys:
                continue
            try:
                numbers = [float(word) for word in keys[key][:3]]
                if not all(math.isfinite(x) for x in numbers):
                    raise ValueError
            except ValueError:
                bad.append(f"{name}: {key.capitalize()} {' '.join(keys[key])}")
                continue
            values[key] = numbers
        textures += [(name, key, _map_file(words)) for key, words in keys.items() if key.startswith(TEXTURE_KEYS)]
        if values.get("d", [1.0])[0] < 1 or values.get("tr", [0.0])[0] > 0:
            transparent.append(name)
        illum = int(values.get("illum", [2])[0])
        coefficients = {}
        for key in ("ka", "kd", "ks", "ke"):
            default = MATERIAL_DEFAULTS[key]
            given = values.get(key)
            rgb = default if given is None else (given * 3)[:3] if len(given) == 1 else given
            if any(not 0 <= x <= 1 for x in rgb):
                clamped.append(f"{name}: {key.capitalize()}")
            coefficients[key] = _rgb(np.clip(rgb, 0, 1))
        rows = {}
        for key in ("map_kd", "map_ka", "map_ke"):
            file = _map_file(keys[key]) if key in keys else ""
            found = _texture_path(mtl.parent, file) if file else None
            if found is None:
                continue  # missing: a note below, and the coefficient alone
            clamp = "clamp" if _map_clamps(keys[key]) else "repeat"
            if (found, clamp) not in registered:
                registered[(found, clamp)] = len(sources)
                sources.append(TextureSource(found, clamp, clamp, f"{mtl}: texture {file!r}"))
            rows[key] = registered[(found, clamp)]
        ks, shininess = specular_lobe(coefficients["ks"],
                                      values.get("ns", [MATERIAL_DEFAULTS["shininess"]])[0])
        coefficients["ks"] = _rgb(ks)
        if illum == 0:
            colour = np.clip(np.add(coefficients["kd"], coefficients["ke"]), 0, 1)
            coefficients = {"ka": (0.0,) * 3, "kd": (0.0,) * 3, "ks": (0.0,) * 3, "ke": _rgb(colour)}
        elif illum == 1:
            coefficients["ks"] = (0.0, 0.0, 0.0)
        elif illum > 2:
            illums.add(illum)
        kd_map = rows.get("map_kd", -1)
        ke_map = kd_map if illum == 0 else rows.get("map_ke", -1)  # colour only: the k_d map colours k_e
        materials[name] = FileMaterial(name, coefficients["ka"], coefficients["kd"], coefficients["ks"],
                                       coefficients["ke"], float(shininess), rows.get("map_ka", -1), kd_map, ke_map)
    if bad:
        notes.append(f"{mtl}: {len(bad)} value(s) are not numbers and keep their defaults (first: {bad[0]})")
    if clamped:
        notes.append(f"{mtl}: {len(clamped)} coefficient(s) outside [0, 1] are clamped to it (first: {clamped[0]})")
    if transparent:
        notes.append(f"{mtl}: transparency (d < 1 or Tr > 0) is ignored: {', '.join(transparent)} render opaque")
    if illums:
        notes.append(f"{mtl}: illum {', '.join(map(str, sorted(illums)))} render as illum 2 (Phong); reflection "
                     "and refraction are out of scope")
    if textures:
        missing = sorted({file for _, _, file in textures if file and _texture_path(mtl.parent, file) is None})
        for file in missing:
            notes.append(f"{mtl}: texture {file!r} is missing")
        others = [f"{key} {file}" for _, key, file in textures if key not in ("map_kd", "map_ka", "map_ke")]
        if others:
            shown = ", ".join(others[:3]) + (", ..." if len(others) > 3 else "")
            notes.append(f"{mtl}: only colour maps (map_Kd, map_Ka, map_Ke) are applied; not applied: {shown}")
    return materials


# Options of a map statement and how many values each takes (the .mtl specification, "Texture map options").
MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
               "-mm": 2, "-o": 3, "-s": 3, "-t": 3, "-texres": 1, "-type": 1}


def _map_file(words: list[str]) -> str:
    """The file a map statement names: its options skipped (-o, -s and -t take up to 3 numbers), the rest,
    spaces kept ("fuze uv.jpg"), backslashes read as folder separators (files written on Windows). Options
    come before the name (the .mtl specification), but some exporters write one after it (`wood.png -bm
    0.5`): words from an option to the end that are all options with their values are not part of the name."""
    at = 0
    while at < len(words) and words[at].lower() in MAP_OPTIONS:
        count = MAP_OPTIONS[words[at].lower()]
        at += 1
        taken = 0
        while taken < count and at < len(words) - 1:
            if count == 1 or _is_number(words[at]):
                at, taken = at + 1, taken + 1
            else:
                break
    end = next((i for i in range(at + 1, len(words)) if _only_options(words[i:])), len(words))
    return " ".join(words[at:end]).replace("\\", "/")


def _only_options(words: list[str]) -> bool:
    """Whether `words` are map options to the end, each with its values: one word for a one-value option
    (`-clamp on`, `-bm 0.5`), 1 to 3 numbers for -o, -s, -t, 1 or 2 for -mm."""
    at = 0
    while at < len(words):
        count = MAP_OPTIONS.get(words[at].lower())
        if count is None:
            return False
        at += 1
        taken = 0
        while taken < count and at < len(words) and (count == 1 or _is_number(words[at])):
            at, taken = at + 1, taken + 1
        if taken == 0:
            return False
    return True


def _is_number(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def _texture_path(folder: Path, file: str) -> Path | None:
    """The texture a material names, relative to its .mtl: as written, else by its file name alone beside
    the .mtl (exporters often keep the absolute path of the machine they ran on); None when neither exists."""
    for candidate in (folder / file, folder / Path(file).name):
        try:
            if candidate.is_file():
                return candidate
        except OSError:
            pass
    return None


def _map_clamps(words: list[str]) -> bool:
    """Whether a map statement says "-clamp on" (the .mtl specification: texels outside [0, 1] clamp)."""
    lowered = [w.lower() for w in words]
    return any(w == "-clamp" and i + 1 < len(lowered) and lowered[i + 1] == "on" for i, w in enumerate(lowered))


# ---------------------------------------------------------------- trimesh's side of reading

def _raised_in_trimesh(error: BaseException) -> bool:
    """Whether `error` came out of trimesh's own code, i.e. trimesh could not read the file.

    A corrupt file makes trimesh raise almost anything (750 corrupted OBJ, PLY, STL, OFF and GLB files gave
    ValueError, KeyError, IndexError, TypeError, NotImplementedError and, from a bug of its own on a bad PLY
    header, UnboundLocalError), so the type says little; where it was raised says whose problem it is.
    Running out of memory is never the file's fault.
    """
    if isinstance(error, MemoryError):
        return False
    frame = error.__traceback__
    while frame is not None:
        if Path(frame.tb_frame.f_code.co_filename).resolve().is_relative_to(TRIMESH):
            return True
        frame = frame.tb_next
    return False


class _RegularFiles(trimesh.resolvers.FilePathResolver):
    """trimesh's resolver for the files a mesh names (.mtl, textures, glTF buffers), but only regular files:
    a FIFO named by `mtllib` would block the read forever."""

    def get(self, name):
        path = Path(self.parent) / name
        with open_regular(path, str(path), "file") as handle:
            return handle.read()


class _MaterialNames(_RegularFiles):
    """The .mtl trimesh is given for an OBJ, whatever name it asks for: a `newmtl` line per material read
    here (_obj_materials), so trimesh tags each `usemtl` group with its material's name. trimesh reads only
    the first `mtllib` line, as one file name; the materials themselves (and their maps) are read here."""

    def __init__(self, path: Path, names):
        super().__init__(path)
        self.text = "".join(f"newmtl {name}\n" for name in names).encode("utf-8")

    def get(self, name):
        return self.text


def _load_obj(source: dict):
    """What trimesh.load gives for an OBJ, but `v x y z r g b` colours are kept beside a material or texture
    coordinates: trimesh's reader hands them to a Trimesh whose TextureVisuals replaces them. They move to
    the visual's `color` vertex attribute (where trimesh keeps glTF's COLOR_0 beside a material, which
    _corner_colours reads), 8-bit as trimesh's ColorVisuals keeps them when there is no material."""
    kwargs = trimesh.exchange.obj.load_obj(source["file_obj"], resolver=source["resolver"], process=False)
    for mesh in (kwargs.get("geometry") or {}).values():
        if mesh.get("vertex_colors") is not None and mesh.get("visual") is not None:
            mesh["visual"].vertex_attributes["color"] = trimesh.visual.color.to_rgba(mesh.pop("vertex_colors"))
    return trimesh.load_scene(kwargs)


def _mesh_source(path, handle, where: Where) -> dict:
    """trimesh.load arguments for the open file `handle` of `path`; a text format that is not UTF-8 is
    read as Latin-1. The file already opened is read (not the path again), and files it names (an OBJ's
    materials, a glTF's buffers) are found beside it. An OBJ's relative face indices are made absolute
    and its concave polygons cut (io/obj_polygons.py); an index 0 or one counting back past the file's
    start is a SceneError naming the line.

    trimesh needs the optional charset_normalizer to guess an encoding, and fails without it, so
    decide here: every byte is a Latin-1 character, and the OBJ and OFF keywords are plain ASCII.
    """
    suffix = path.suffix.lower()
    source = {"file_obj": handle, "file_type": suffix[1:], "resolver": _RegularFiles(path)}
    if suffix in TEXT_FORMATS:
        data = handle.read()
        try:
            data.decode("utf-8")
        except UnicodeDecodeError:
            data = data.decode("latin-1").encode("utf-8")
        if suffix == ".obj":
            from .obj_polygons import absolute_indices, triangulate_concave
            data, problem = absolute_indices(data)  # trimesh counts -1 back from the file's end, not the line
            if problem:
                raise SceneError(f"{str(path)!r} {problem}", where)
            data, _ = triangulate_concave(data)  # trimesh would fan a concave polygon over its hole
        source["file_obj"] = io.BytesIO(data)
    return source
