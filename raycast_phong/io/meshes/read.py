"""Read a mesh file into a MeshFile, the same way for every format: the format's `read` gives placed parts
(io/meshes/<format>.py), and here they become one triangle mesh with what the file says about its surface:
materials, colours, normals, texture coordinates.

Everything the file says about materials is mapped onto the lecture's model (k_a, k_d, k_s, f, k_e);
docs/meshes.md has the table term by term. Problems with the file's side files (a missing or broken .mtl,
textures) are notes, one line each, and the render goes on with defaults; a file that is not a mesh is a
SceneError, one line. The file's MeshSource calls read_file, and keeps a read made for framing for the render.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ...errors import FileProblem, SceneError
from ...records import bounding_box
from ...tolerances import POSITION_LIMIT
from ..files import open_mesh_file
from . import read_names
from .content import check_content
from .format import Loaded, Part, Reading
from .gltf import SPECULAR_GLOSSINESS, TRANSFORM, UNLIT, from_pbr, transform_uv
from .gltf_parts import GltfMaterial
from .materials import FILE_CREASE_ANGLE, MAX_FILE_SHININESS, WIDE_LOBE, FileMaterial, PartSurface, TextureSource
from .materials import rgb as _rgb
from .obj import UV_LIMIT

__all__ = ["FILE_CREASE_ANGLE", "MeshFile", "read_file"]


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


READABLE = f"a mesh file of a format read here ({read_names()})"


def read_file(mesh, bounds: bool = True) -> MeshFile:
    """The file of `mesh` (its MeshSource), read by its format and finished here; its `where` starts every
    error ("scene.toml: objects.0.path"): the readers' FileProblems get it here, their one boundary. bounds: also
    measure the centre and radius framing needs (a render's own read skips the pass)."""
    try:
        return _read_file(mesh, bounds)
    except FileProblem as problem:
        raise SceneError(problem.problem, mesh.where) from None


def _read_file(mesh, bounds: bool) -> MeshFile:
    path, kind, where = mesh.path, mesh.format, mesh.where
    handle = open_mesh_file(path, where)
    notes: list[str] = []
    textures: list[TextureSource] = []
    try:
        with handle:
            check_content(path, handle, kind, where)
            loaded = kind.read(Reading(handle, mesh, notes, textures))
    except SceneError:
        raise
    except Exception as error:
        if not _raised_in_trimesh(error):
            raise  # our own bug, not the file's: an internal error with its traceback
        with open_mesh_file(path, where) as handle:
            problem = kind.explain(handle, mesh)
        if problem:
            raise SceneError(f"{str(path)!r} {problem}", where) from None
        # The renderer's words, not the library's exception text: a KeyError of three NUL bytes or numpy's "could
        # not be read to its end" says nothing a user can act on.
        name = kind.name(path.suffix.lower())
        raise SceneError(f"cannot read {str(path)!r} as {name}: its content does not follow the {name} format where "
                         f"the reader stopped (the file is corrupt, cut short, or another format); allowed: "
                         f"{READABLE}", where) from None
    parts = loaded.parts
    if not parts:
        why = "; ".join(note.removeprefix(f"{path}: ") for note in notes)  # what the read left out, if anything
        raise SceneError(f"{str(path)!r} holds no triangles{f' ({why})' if why else ''}; expected {READABLE}",
                         where)
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
    low, high = (side.astype(np.float64) for side in bounding_box(used))  # column by column (records says why)
    _check_values(used, path, low, high)
    face_group, materials, corner_uv, corner_colour = _surfaces(parts, loaded, kind.pbr, path, notes, textures)
    up = loaded.up or kind.up
    centre, radius = np.full(3, np.nan), math.nan
    if bounds:
        centre = (low + high) / 2
        radius = _radius(used, centre)
        hint = None if up is not None else up_hint(high - low)
        if hint:
            notes.append(f"{path}: {hint}")
    return MeshFile(vertices, faces, normals, face_group, materials, up,
                    tuple(dict.fromkeys(notes)), centre, radius, normals is not None, corner_uv, corner_colour,
                    tuple(textures))


Z_UP_RATIO = 1.5  # a model this many times longer along Z than along Y (and longest along Z) looks Z-up
# A model whose Y extent is at most this share of its largest is flat in X-Z (float32 noise on a plane is
# about 1e-7 of its size): a floor as +Y up shows it, or a drawing seen from the front as +Z up would; its
# extents cannot tell, so no hint (a ratio to a zero extent read "2e+300× longer").
FLAT_SHARE = 1e-6


RADIUS_ROWS = 1 << 16  # points a block of _radius: its float64 temporaries 1.5 MB, not 80 MB for a 3.3M-corner STL


def _radius(points: np.ndarray, centre: np.ndarray) -> float:
    """max |p − centre| over `points`, |d|² as (dx² + dy²) + dz² in float64, in blocks of RADIUS_ROWS: column by
    column (numpy's sum along rows of three is 7× slower than three column passes), with no (n, 3) float64
    temporaries; the sums in the order numpy's row sum adds them, so its bits."""
    largest = 0.0
    for start in range(0, len(points), RADIUS_ROWS):
        block = points[start:start + RADIUS_ROWS]
        squared = np.square(block[:, 0] - centre[0])  # float64, as centre is
        squared += np.square(block[:, 1] - centre[1])
        squared += np.square(block[:, 2] - centre[2])
        largest = max(largest, float(squared.max()))
    return math.sqrt(largest)


def up_hint(extent: np.ndarray) -> str | None:
    """A one-line hint when a format that states no up axis holds a model that looks Z-up: longest along Z
    and at least Z_UP_RATIO times longer along Z than along Y (a scanned statue, a standing figure from a
    Z-up tool), which the default +Y up shows lying on its back. None otherwise, and for a model flat in
    X-Z (FLAT_SHARE), which either axis shows right side up (docs/meshes.md, "Up")."""
    if not extent[2] > 0 or extent[1] <= FLAT_SHARE * extent.max():
        return None
    if extent[2] >= extent.max() and extent[2] >= Z_UP_RATIO * extent[1]:
        return (f"the model is {extent[2] / extent[1]:.3g}× longer along Z than along Y, as models "
                "made Z-up are; the view takes +Y as up (the format states none), so if it lies on its back, "
                "add --up z")
    return None


def _concatenate(parts: list[Part]) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """One vertex and face array; vertex normals only if every part stores them."""
    if len(parts) == 1:
        return parts[0].vertices, parts[0].faces, parts[0].normals
    offsets = np.cumsum([0] + [len(part.vertices) for part in parts])
    vertices = np.concatenate([part.vertices for part in parts])
    faces = np.concatenate([part.faces + o for part, o in zip(parts, offsets)])
    stored = all(part.normals is not None for part in parts)
    return vertices, faces, np.concatenate([part.normals for part in parts]) if stored else None


def _check_values(coordinates: np.ndarray, path: Path, low: np.ndarray, high: np.ndarray) -> None:
    """Every vertex of a face (`coordinates`, (U, 3)) finite and within ±POSITION_LIMIT (trimesh squares
    coordinates). `low`, `high`: their bounding box in float64, within the limits exactly when every coordinate is
    (NaN where one is NaN, and a comparison with NaN fails): no pass of its own over the coordinates."""
    if (low >= -POSITION_LIMIT).all() and (high <= POSITION_LIMIT).all():
        return
    finite = np.isfinite(coordinates).all(axis=1)
    if not finite.all():
        raise FileProblem(f"{str(path)!r} has {int((~finite).sum())} vertex(es) with NaN or infinite "
                          "coordinates; every vertex of a face must have finite coordinates")
    huge = (np.abs(coordinates) > POSITION_LIMIT).any(axis=1)
    if huge.any():
        raise FileProblem(f"{str(path)!r} has {int(huge.sum())} vertex(es) with a coordinate beyond "
                          f"±{POSITION_LIMIT:g} (largest {float(np.abs(coordinates).max()):.3g}); allowed: within "
                          f"±{POSITION_LIMIT:g}, so lengths squared stay finite")


# ---------------------------------------------------------------- materials and colours

def _surfaces(parts, loaded, pbr: str, path: Path, notes: list[str], sources: list[TextureSource]):
    """Per face: its material (an index into the returned tuple, -1 for none); per corner: the texture
    coordinates (None unless some used material has a map) and the vertex colours (None unless some part
    has colours). `loaded`: the format's Loaded (an OBJ's library, a glTF's samplers, a PLY's images); `pbr`:
    how the note on approximated PBR materials names them."""
    library, samplers = loaded.library, loaded.samplers
    materials: list[FileMaterial] = []
    index: dict[str, int] = {}
    groups, corners, uvs, any_colour, gltf = [], [], [], False, False
    for part in parts:
        own = part.visual if isinstance(part.visual, PartSurface) else None  # read by io/meshes/threemf.py
        material = None if own is not None else getattr(part.visual, "material", None)
        found = None if own is None else own.material
        if _is_pbr(material):
            found = from_pbr(material, path, notes, sources, samplers)
            read_so = loaded.own_material(material, found) if loaded.own_material is not None else None
            # An unlit material is the lecture's own (no approximation); a specular-glossiness one says its own;
            # a format's own reading (COLLADA's effects) is no approximation either.
            gltf |= (read_so is None and not samplers.get((material.name, UNLIT))
                     and (material.name, SPECULAR_GLOSSINESS) not in samplers)
            found = read_so if read_so is not None else found
        elif material is not None and library is not None:
            found = library.get(getattr(material, "name", None) or "")
        elif _is_trimesh(material, "SimpleMaterial"):
            found = from_simple(material, path, sources)  # rp.mesh_scene's, a trimesh-only file's, a PLY's TextureFile
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
        if uv is not None and _is_pbr(material):
            uv = _transformed_uv(uv, material, samplers, path, notes)
        if uv is not None and (np.abs(uv) > UV_LIMIT).any():  # NaN passes: the kernel reads it as 0
            raise FileProblem(f"{str(path)!r} has a texture coordinate beyond float32's range (largest "
                              f"{float(np.nanmax(np.abs(uv))):.4g}); allowed: -{UV_LIMIT:.4g} .. {UV_LIMIT:.4g}")
        uvs.append(own.corner_uv if own is not None else None if uv is None else uv[part.faces].astype(np.float32))
        corner = _corner_colours(part) if own is None else own.corner_colour
        any_colour |= corner is not None
        corners.append(corner)
    if gltf:  # glTF's own materials, or a file whose materials trimesh reads as metallic-roughness (COLLADA)
        notes.append(f"{path}: {pbr} materials are approximated on the Phong model: k_d = k_a = "
                     "base colour, F0 = 0.04 + (base colour − 0.04) × metallic, f = 2/roughness⁴ − 2 in [1, "
                     f"{MAX_FILE_SHININESS:g}], k_s = F0 × min(1, (f + 2)/{WIDE_LOBE + 2:g}), k_e = emissive "
                     "(docs/meshes.md)")
    corner_colour = corner_uv = None
    if any_colour:
        # A part without colours keeps its material's own k_d: mark it with -1 to tell it apart.
        corner_colour = np.concatenate([c if c is not None else np.full((len(p.faces), 3, 3), -1, np.float32)
                                        for c, p in zip(corners, parts)])
    mapped = {k for k, m in enumerate(materials) if max(m.ka_map, m.kd_map, m.ke_map) >= 0}  # materials with a map
    if mapped:  # a part without texture coordinates reads its maps at (0, 0), as GL reads a missing attribute
        if any(u is None for u, g in zip(uvs, groups) if len(g) and g[0] in mapped):
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


def held_surfaces(part: Part, path: Path) -> tuple:
    """(face_group, materials, corner_uv, corner_colour, texture sources, notes) of a mesh given as a
    trimesh.Trimesh (rp.mesh_scene; `part` holds its visual), read by the rule a file's parts are read by, so its
    colours, material and texture coordinates colour it as they would in a file; notes start with `path`."""
    notes: list[str] = []
    sources: list[TextureSource] = []
    found = _surfaces([part], Loaded([part]), "the Trimesh's metallic-roughness (PBR)", path, notes, sources)
    return (*found, tuple(sources), tuple(dict.fromkeys(notes)))


def from_simple(material, path: Path, sources: list[TextureSource]) -> FileMaterial:
    """trimesh's SimpleMaterial (the .mtl's terms, 8-bit) on the lecture's model as an .mtl is read
    (io/meshes/mtl.py): k_a = ambient, k_d = diffuse, k_s = specular through specular_lobe, f = glossiness (its
    Ns); its image the k_d map, repeating."""
    from .materials import specular_lobe

    def colour(value) -> tuple[float, float, float]:
        return _rgb(np.clip(np.asarray(value, np.float64).ravel()[:3] / 255.0, 0, 1))
    name = getattr(material, "name", None) or f"{path.stem}-material"
    glossiness = getattr(material, "glossiness", None)
    ks, shininess = specular_lobe(colour(material.specular), 32.0 if glossiness is None else float(glossiness))
    kd_map = -1
    if getattr(material, "image", None) is not None:
        kd_map = len(sources)
        sources.append(TextureSource(material.image, "repeat", "repeat", f"{path}: material {name!r}: its image"))
    return FileMaterial(name, colour(material.ambient), colour(material.diffuse), _rgb(ks), (0.0, 0.0, 0.0),
                        float(shininess), kd_map=kd_map)


def _is_trimesh(material, kind: str) -> bool:
    """Whether a part's material is trimesh's `kind` (SimpleMaterial, PBRMaterial), without importing trimesh to
    ask (a file read without it has none)."""
    trimesh = sys.modules.get("trimesh")
    return trimesh is not None and isinstance(material, getattr(trimesh.visual.material, kind))


def _is_pbr(material) -> bool:
    """Whether a part's material is a glTF's metallic-roughness one: read here (gltf_parts.GltfMaterial) or
    trimesh's PBRMaterial (a glTF's, a COLLADA's)."""
    return isinstance(material, GltfMaterial) or _is_trimesh(material, "PBRMaterial")


def _raised_in_trimesh(error: BaseException) -> bool:
    """trimesh_parts.raised_in_trimesh, without importing trimesh for a file read without it."""
    if "trimesh" not in sys.modules:
        return False
    from .trimesh_parts import raised_in_trimesh
    return raised_in_trimesh(error)


def _corner_colours(part: Part) -> np.ndarray | None:
    """(F, 3, 3) float32 colour in [0, 1] at each face corner: vertex colours (8-bit /255), a face's colour
    at its three corners, or glTF's COLOR_0 or COLLADA's COLOR beside a material (trimesh keeps them as vertex
    attributes); None when the part has none. Taken as stored (glTF's COLOR_0 is linear; PLY and OFF colours say
    nothing, and are read as linear too)."""
    visual, trimesh = part.visual, sys.modules.get("trimesh")  # a trimesh visual only where trimesh read the file
    if part.colours is None and (visual is None or trimesh is None):  # read here, without colours
        return None
    kind = getattr(visual, "kind", None)
    colour_visual = trimesh is not None and isinstance(visual, trimesh.visual.ColorVisuals)
    if colour_visual and kind == "vertex":
        rgb = np.asarray(visual.vertex_colors)[:, :3].astype(np.float32) / 255.0
        return rgb[part.faces]
    if colour_visual and kind == "face":
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
    return rgb[part.faces] if rgb.shape[1] >= 3 else None
