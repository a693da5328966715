"""Read a mesh file (any format trimesh reads) with what it says about its surface: materials, colours, normals.

Everything the file says about materials is mapped onto the lecture's model (k_a, k_d, k_s, f, k_e);
docs/meshes.md has the table term by term. The formats' own parts have their modules: io/mtl.py (an OBJ's
.mtl files), io/gltf.py (a glTF's document and materials), io/obj.py (an OBJ's text for trimesh), io/stl.py
(binary STL), io/mesh_content.py (a file's bytes against its suffix); what the stages before this read learn
of the file is its io/mesh_source.MeshSource, made once and passed here. Problems with the file's side files
(a missing or broken .mtl, textures) are notes, one line each, and the render goes on with defaults; a file
that is not a mesh is a SceneError, one line.

A file read to frame a camera (scene.framing) is kept for the render that follows, so a 2M-triangle file is
read once: the hand-over is KEPT (io.files.VersionCache, one entry keyed on the MeshSource's identity: the
file's and its side files' versions), which the framing read fills and the geometry stage's read takes (not
copies); the bounds framing needs stay in BOUNDS, a small cache of their own.
"""

from __future__ import annotations

import io
import json
import math
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
import trimesh

from ..errors import SceneError, Where
from ..records import bounding_box
from ..tolerances import POSITION_LIMIT
from .collada import collada_text, collada_up
from .files import VersionCache, open_mesh_file, open_regular, shown_name
from .gltf import SPECULAR_GLOSSINESS, TRANSFORM, UNLIT, check_document, from_pbr, transform_uv, uri_file
from .gltf_decode import decode_gltf, needs_decoding
from .materials import FILE_CREASE_ANGLE, MAX_FILE_SHININESS, WIDE_LOBE, FileMaterial, PartSurface, TextureSource
from .mesh_content import READABLE, TEXT_FORMATS, check_content, check_file_content
from .mesh_source import MeshSource, mesh_source
from .mtl import MAX_SIDE_FILE
from .obj import UV_LIMIT, bom_decoded, load_obj, obj_problem, obj_text
from .obj_plain import plain_obj
from .ply import HEADER_LIMIT, ply_problem, resolved, texture_names, trimesh_quiet
from .stl import ascii_stl_problem, binary_stl_points
from .threemf import read_3mf

__all__ = ["FILE_CREASE_ANGLE", "MeshFile", "check_file_content", "mesh_bounds", "read_mesh"]

TRIMESH = Path(trimesh.__file__).resolve().parent  # an exception that passed through here: trimesh refused the file
# Up axes the formats' specifications state (glTF 2.0 §3.4: +Y up; 3MF core §3.4: +Z up); a COLLADA document
# states its own (io/collada.py, collada_up); others say nothing.
STATED_UP = {".gltf": (0.0, 1.0, 0.0), ".glb": (0.0, 1.0, 0.0), ".3mf": (0.0, 0.0, 1.0)}


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


def read_mesh(path: Path, where: Where, keep: bool = False, source: MeshSource | None = None) -> MeshFile:
    """The mesh file at `path`; `where` starts every error ("scene.toml: objects.0.path"); `source`: its
    MeshSource (made now when not given).

    keep=True (framing a camera) leaves the result for the next read of the same unchanged file, which
    takes it; so the render that follows a framing does not read the file again.
    """
    source = source or mesh_source(path)
    held = getattr(source, "held", None)  # a mesh given as arrays (scene.mesh_arrays): already checked, never read
    if held is not None:
        return held
    identity = source.identity if source.version is not None else None  # missing: the read words the error
    if identity is not None:
        found = KEPT.get(identity) if keep else KEPT.take(identity)
        if found is not None:
            return found
    found = _read(path, where, source, bounds=keep)
    if keep and identity is not None:
        KEPT.put(identity, found)
        _remember_bounds(identity, found)
    return found


def mesh_bounds(source: MeshSource, where: Where) -> MeshFile:
    """The file's centre, radius, up axis, materials and notes (its arrays may be empty): from the small
    cache when this unchanged file was read before, else read (and kept for the render)."""
    found = BOUNDS.get(source.identity) if source.version is not None else None
    return found if found is not None else read_mesh(source.path, where, keep=True, source=source)


def _remember_bounds(identity: tuple, found: MeshFile) -> None:
    empty = np.zeros((0, 3))
    BOUNDS.put(identity, MeshFile(empty, empty.astype(np.int64), None, np.zeros(0, np.int32), found.materials,
                                 found.up, found.notes, found.centre, found.radius, found.normals is not None))


# ---------------------------------------------------------------- reading

def _read(path: Path, where: Where, source: MeshSource, bounds: bool = True) -> MeshFile:
    handle = open_mesh_file(path, where)
    notes: list[str] = []
    suffix = path.suffix.lower()
    try:
        # Load unprocessed: trimesh's cleaning would silently drop NaN vertices and their faces.
        with handle:
            check_content(path, handle, where)
            samplers = check_document(source.document, path, where, notes) if source.document is not None else {}
            if suffix == ".dae":
                _check_collada_images(path, handle, notes)
            sources: list[TextureSource] = []
            textures: list[str] = []  # a PLY's TextureFile names, as found beside it
            points = binary_stl_points(handle) if suffix == ".stl" else None
            library = None
            up = STATED_UP.get(suffix)
            if points is None and suffix == ".obj":
                data = bom_decoded(handle.read(), path, where)  # a UTF-16 OBJ (its BOM) as UTF-8
                loaded = plain_obj(data, path)  # only v and f lines: one compiled pass (io/obj_plain.py)
                text = obj_text(data, path, where) if loaded is None else None
                library = source.materials.library
                notes += source.materials.notes
                sources += source.materials.sources
                if loaded is None:
                    loaded = load_obj(text, path, library, where, data)
            elif suffix == ".3mf":
                own = read_3mf(handle, path, where, notes, sources)
            elif points is None:
                # A PLY float property beyond float32 (5e38) is cast to inf with numpy's warning; the values check
                # below words it in one line.
                arguments = _trimesh_arguments(path, handle, source, where)
                if suffix == ".dae":  # skinned meshes, non-COMMON effects, decimal commas kept (io/collada.py)
                    data = handle.read()
                    up = collada_up(data)
                    arguments["file_obj"] = io.BytesIO(collada_text(data, path, notes))
                with np.errstate(over="ignore", invalid="ignore"), trimesh_quiet():
                    loaded = trimesh.load(**arguments, process=False)
                if suffix == ".ply":
                    textures = _ply_textures(path, handle, notes)
        if points is not None:  # the corners in file order, as trimesh's reader gives them (without its float64)
            parts = [_Part(points, np.arange(len(points), dtype=np.int64).reshape(-1, 3), None, None)]
        elif suffix == ".3mf":
            parts = [_Part(vertices, faces, None, surface) for vertices, faces, surface in own]
        else:
            parts = _parts(loaded) or _strip_parts(loaded)
    except SceneError:
        raise
    except Exception as error:
        if not _raised_in_trimesh(error):
            raise  # our own bug, not the file's: an internal error with its traceback
        problem = _explained(path, suffix, where)
        if problem:
            raise SceneError(f"{str(path)!r} {problem}", where) from None
        # The renderer's words, not the library's exception text (issue 33): a KeyError of three NUL bytes or
        # numpy's "could not be read to its end" says nothing a user can act on.
        name = path.suffix[1:].upper().replace("GLTF", "glTF").replace("DAE", "COLLADA") or "a mesh"
        raise SceneError(f"cannot read {str(path)!r} as {name}: its content does not follow the {name} format where "
                         f"the reader stopped (the file is corrupt, cut short, or another format); allowed: "
                         f"{READABLE}", where) from None
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
                                                                samplers, where, textures)
    centre, radius = np.full(3, np.nan), math.nan
    if bounds:  # only framing needs them: a render's own read skips the pass
        low, high = (side.astype(np.float64) for side in bounding_box(used))  # column by column (records says why)
        centre = (low + high) / 2
        radius = float(np.sqrt(((used - centre) ** 2).sum(axis=1).max()))
        hint = None if up is not None else up_hint(high - low, suffix)
        if hint:
            notes.append(f"{path}: {hint}")
    return MeshFile(vertices, faces, normals, face_group, materials, up,
                    tuple(dict.fromkeys(notes)), centre, radius, normals is not None, corner_uv, corner_colour,
                    tuple(sources))



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
            notes.append(f"{path}: texture {shown_name(name)} is missing")



Z_UP_RATIO = 1.5  # a model this many times longer along Z than along Y (and longest along Z) looks Z-up
# A model whose Y extent is at most this share of its largest is flat in X-Z (float32 noise on a plane is
# about 1e-7 of its size): a floor as +Y up shows it, or a drawing seen from the front as +Z up would; its
# extents cannot tell, so no hint (a ratio to a zero extent read "2e+300× longer").
FLAT_SHARE = 1e-6


def up_hint(extent: np.ndarray, suffix: str) -> str | None:
    """A one-line hint when a format that states no up axis holds a model that looks Z-up: longest along Z
    and at least Z_UP_RATIO times longer along Z than along Y (a scanned statue, a standing figure from a
    Z-up tool), which the default +Y up shows lying on its back. None otherwise, and for a model flat in
    X-Z (FLAT_SHARE), which either axis shows right side up (docs/meshes.md, "Up")."""
    if suffix in STATED_UP or not extent[2] > 0 or extent[1] <= FLAT_SHARE * extent.max():
        return None
    if extent[2] >= extent.max() and extent[2] >= Z_UP_RATIO * extent[1]:
        return (f"the model is {extent[2] / extent[1]:.3g}× longer along Z than along Y, as models "
                "made Z-up are; the view takes +Y as up (the format states none), so if it lies on its back, "
                "add --up z")
    return None


class _Part(NamedTuple):
    """One placed triangle mesh of what trimesh loaded."""
    vertices: np.ndarray          # (V, 3) float64, placed by its node's transform
    faces: np.ndarray             # (F, 3) int64
    normals: np.ndarray | None    # (V, 3) the normals the file stores, transformed with the vertices
    visual: object                # trimesh's visual: its material, its colours
    colours: np.ndarray | None = None  # (V, 3|4) vertex colours kept on the mesh beside a material (a COLLADA
                                       # COLOR input: trimesh stores them there, not on the visual)


def _parts(loaded) -> list[_Part]:
    """The triangle meshes of what trimesh loaded, in world placement (a glTF's node transforms applied).

    Not Scene.dump(): its copies forget the vertex normals the file stored."""
    if isinstance(loaded, trimesh.Trimesh):
        instances = [(np.eye(4), loaded)]
    elif isinstance(loaded, trimesh.Scene):
        instances = [(np.asarray(loaded.graph[node][0], np.float64), loaded.geometry[loaded.graph[node][1]])
                     for node in loaded.graph.nodes_geometry]
        if not instances:  # a glTF without nodes (a library of meshes, glTF 2.0 §3.5.1): each mesh once, unplaced
            instances = [(np.eye(4), mesh) for mesh in loaded.geometry.values()]
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
        colours = None
        if not isinstance(mesh.visual, trimesh.visual.ColorVisuals):
            colours = mesh.vertex_attributes.get("color")
        parts.append(_Part(vertices, faces, normals, mesh.visual, colours))
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
              sources: list[TextureSource], samplers: dict, where: Where = "", textures: list[str] = ()):
    """Per face: its material (an index into the returned tuple, -1 for none); per corner: the texture
    coordinates (None unless some used material has a map) and the vertex colours (None unless some part
    has colours)."""
    materials: list[FileMaterial] = []
    index: dict[str, int] = {}
    groups, corners, uvs, any_colour, gltf = [], [], [], False, False
    for part in parts:
        own = part.visual if isinstance(part.visual, PartSurface) else None  # read by io/threemf.py, io/ply.py
        material = None if own is not None else getattr(part.visual, "material", None)
        found = None if own is None else own.material
        if isinstance(material, trimesh.visual.material.PBRMaterial):
            found = from_pbr(material, path, notes, sources, samplers)
            # An unlit material is the lecture's own (no approximation); a specular-glossiness one says its own.
            gltf |= not samplers.get((material.name, UNLIT)) and (material.name, SPECULAR_GLOSSINESS) not in samplers
        elif material is not None and library is not None:
            found = library.get(getattr(material, "name", None) or "")
        elif textures and getattr(material, "image", None) is not None:  # a PLY's TextureFile (io/ply.py)
            sources.append(TextureSource(material.image, "repeat", "repeat", textures[0]))
            white = (1.0, 1.0, 1.0)
            found = FileMaterial(Path(textures[0]).stem, white, white, (0.5, 0.5, 0.5), (0.0, 0.0, 0.0), 32.0,
                                 kd_map=len(sources) - 1)
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
        uv = None if uv is None or len(uv) != len(part.vertices) else np.asarray(uv, np.float64)[:, :2]
        if uv is not None and isinstance(material, trimesh.visual.material.PBRMaterial):
            uv = _transformed_uv(uv, material, samplers, path, notes)
        if uv is not None and not (np.abs(uv) <= UV_LIMIT).all():  # NaN passes: the kernel reads it as 0
            raise SceneError(f"{str(path)!r} has a texture coordinate beyond float32's range (largest "
                             f"{float(np.nanmax(np.abs(uv))):.4g}); allowed: -{UV_LIMIT:.4g} .. {UV_LIMIT:.4g}",
                             where)
        uvs.append(None if uv is None else uv[part.faces].astype(np.float32))
        if own is not None:
            uvs[-1] = own.corner_uv
        corner = _corner_colours(part) if own is None else own.corner_colour
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


def _transformed_uv(uv: np.ndarray, material, samplers: dict, path: Path, notes: list[str]) -> np.ndarray:
    """A glTF part's texture coordinates through its colour maps' KHR_texture_transform (io.gltf.transform_uv):
    the base colour map's, else the emissive map's. The renderer keeps one set of coordinates per corner, so
    an emissive map transformed otherwise than the base colour map reads the base colour's (one note)."""
    base = samplers.get((material.name, TRANSFORM, "baseColorTexture"))
    emissive = samplers.get((material.name, TRANSFORM, "emissiveTexture"))
    has_base = getattr(material, "baseColorTexture", None) is not None
    has_emissive = getattr(material, "emissiveTexture", None) is not None
    chosen = base if has_base else emissive
    if has_base and has_emissive and (base or IDENTITY) != (emissive or IDENTITY):
        notes.append(f"{path}: material {material.name!r}: its emissiveTexture's KHR_texture_transform differs "
                     "from its baseColorTexture's; the base colour's texture coordinates are used for both")
    return uv if chosen is None else transform_uv(uv, chosen)


IDENTITY = ((0.0, 0.0), 0.0, (1.0, 1.0))  # KHR_texture_transform's defaults: no change


def _corner_colours(part: _Part) -> np.ndarray | None:
    """(F, 3, 3) float32 colour in [0, 1] at each face corner: vertex colours (8-bit /255), a face's colour
    at its three corners, or glTF's COLOR_0 or COLLADA's COLOR beside a material (trimesh keeps them as vertex
    attributes);
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
    raw = part.colours if raw is None else raw
    if raw is None or len(raw) != len(part.vertices):
        return None
    raw = np.asarray(raw)
    scale = 1.0 if raw.dtype.kind == "f" else float(np.iinfo(raw.dtype).max)
    rgb = np.clip(np.asarray(raw, np.float64).reshape(len(raw), -1)[:, :3] / scale, 0, 1).astype(np.float32)
    if rgb.shape[1] < 3:
        return None
    return rgb[part.faces]



# ---------------------------------------------------------------- trimesh's side of reading

def _ply_textures(path: Path, handle, notes: list[str]) -> list[str]:
    """A PLY's TextureFile names (io/ply.py), `<this>` replaced; a note for each missing image and for images
    after the first (one map per file is read)."""
    handle.seek(0)
    names = [resolved(name, path) for name in texture_names(handle.read(HEADER_LIMIT))]
    if not names:
        return []
    for name in names[:1]:
        if not (path.parent / name).is_file():
            notes.append(f"{path}: texture {shown_name(name)} is missing")
    if len(names) > 1:
        notes.append(f"{path}: names {len(names)} TextureFile images (a texture number per face); only the first, "
                     f"{names[0]!r}, is read, for every face")
    return names


def _explained(path: Path, suffix: str, where: Where) -> str | None:
    """What is wrong with a file trimesh could not read, in the renderer's words, when a check of the format's
    own finds it (a line, a header line); None to word trimesh's exception instead."""
    with open_mesh_file(path, where) as handle:
        if suffix == ".obj":
            return obj_problem(bom_decoded(handle.read(), path, where))
        if suffix == ".stl":
            return ascii_stl_problem(handle.read())
        if suffix == ".ply":
            return ply_problem(handle.read(HEADER_LIMIT))
    return None


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
    a FIFO named by `mtllib` would block the read forever. `uris`: the names are a glTF's URIs, percent-encoded."""

    uris = False
    decoded: dict[str, bytes] | None = None  # io.gltf_decode's buffers, by the names its rewritten document gives
    file: Path | None = None  # a PLY: its own path, for `<this>` in a TextureFile name

    def get(self, name):
        if self.decoded and name in self.decoded:
            return self.decoded[name]
        name = resolved(name, self.file) if self.file is not None else name  # MeshLab's `<this>` in a PLY
        path = uri_file(Path(self.parent), name) if self.uris else Path(self.parent) / name
        with open_regular(path, str(path), "file") as handle:
            return handle.read()



def _trimesh_arguments(path: Path, handle, source: MeshSource, where: Where) -> dict:
    """trimesh.load arguments for the open file `handle` of `path` (any format but OBJ, io/obj.py's, and binary
    STL, io/stl.py's): the file already opened is read (not the path again), and files it names (a glTF's
    buffers) are found beside it. An OFF that is not UTF-8 is read as Latin-1: trimesh needs the optional
    charset_normalizer to guess an encoding, and fails without it; every byte is a Latin-1 character, and the
    keywords are plain ASCII. A glTF whose data trimesh would misread is given it rewritten as plain glTF
    (io/gltf_decode.py: compressed, quantized or instanced data, specular-glossiness materials)."""
    suffix = path.suffix.lower()
    resolver = _RegularFiles(path)
    resolver.uris = suffix in (".gltf", ".glb")  # names are URIs, percent-encoded (io.gltf.uri_file)
    resolver.file = path if suffix == ".ply" else None
    arguments = {"file_obj": handle, "file_type": suffix[1:], "resolver": resolver}
    if source.document is not None and needs_decoding(source.document.tree):
        tree, resolver.decoded = decode_gltf(path, source.document, where)
        arguments.update(file_obj=io.BytesIO(json.dumps(tree).encode()), file_type="gltf")
    if suffix in TEXT_FORMATS:
        data = handle.read()
        try:
            data.decode("utf-8")
        except UnicodeDecodeError:
            data = data.decode("latin-1").encode("utf-8")
        arguments["file_obj"] = io.BytesIO(data)
    return arguments
