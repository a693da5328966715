"""A glTF with materials and images read into placed Parts without trimesh, whose import alone is about half of a
small textured file's process to PNG. It gives what trimesh's reader gave for the same document (the Parts
io/meshes/trimesh_parts.parts made of it: its nodes in trimesh's order, each placed by its matrix and T · R · S,
each triangle primitive a part with its normals, its v-up texture coordinates and its material as trimesh's
PBRMaterial holds it), so the rest of the read (read._surfaces, gltf.from_pbr) is the same code either way. A
camera's node is a transform like any other (trimesh left it out of its graph, and a mesh below it with it).

None for what it leaves to trimesh: strips, fans, points and lines, sparse or integer attributes,
morph targets, a node or primitive with extensions, a texture without a plain image source, an image PIL
cannot open, a buffer or image file that is not there. Material extensions trimesh has no reader for are read
from the document by gltf.gltf_samplers (unlit, emissive strength) or noted (LOOK_ONLY), the same either way.
"""

from __future__ import annotations

import base64
import io
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..files import open_regular
from .format import Part, placed
from .gltf_decode import INDEX_TYPES, _Decoder

# The one material extension trimesh reads into its material (the document goes to gltf_decode first anyway).
TRIMESH_READS = "KHR_materials_pbrSpecularGlossiness"
ATTRIBUTES = {"POSITION": ("VEC3",), "NORMAL": ("VEC3",), "TEXCOORD_0": ("VEC2",), "COLOR_0": ("VEC3", "VEC4")}


class GltfMaterial(NamedTuple):
    """A glTF material as trimesh's PBRMaterial holds it, for gltf.from_pbr: the base colour factor in 8 bits
    (round(255 x), as trimesh stores it), the other factors as given, each texture's image (PIL) or None."""
    name: str | None
    baseColorFactor: np.ndarray | None
    metallicFactor: float | None
    roughnessFactor: float | None
    emissiveFactor: np.ndarray | None
    alphaMode: str | None
    alphaCutoff: float | None
    baseColorTexture: object
    emissiveTexture: object
    metallicRoughnessTexture: object
    normalTexture: object
    occlusionTexture: object


class GltfVisual(NamedTuple):
    """A part's texture coordinates (v up, as trimesh flips them) and material, where trimesh had its visual."""
    uv: np.ndarray | None
    material: GltfMaterial


def gltf_parts(tree: dict, buffers: list[bytes], path: Path) -> list[Part] | None:
    """The placed Parts of the document `tree` whose buffers are `buffers`, or None (trimesh reads it). Data that
    breaks the specification is refused in the decoder's words (FileProblem: the accessor and what is wrong)."""
    try:
        return _parts(tree, buffers, path)
    except NotImplementedError:  # raised here for what this reader leaves to trimesh
        return None
    except (AttributeError, IndexError, KeyError, TypeError, ValueError, OSError):
        return None  # a malformed document or a missing file: trimesh reads it, and words what is wrong


def _parts(tree: dict, buffers: list[bytes], path: Path) -> list[Part]:
    nodes = tree.get("nodes", [])
    if tree.get("skins") or any("extensions" in node for node in nodes):  # a camera places no triangle
        raise NotImplementedError
    decoder = _Decoder(tree, buffers, path, [])
    images = _images(tree, decoder, path)
    materials = [_material(material, tree, images) for material in tree.get("materials", [])]
    meshes = [[_primitive(primitive, decoder, materials) for primitive in mesh["primitives"]]
              for mesh in tree.get("meshes", [])]
    return [Part(*placed(vertices, faces, normals, matrix), visual, colours) for matrix, mesh in _placed(tree)
            for vertices, faces, normals, visual, colours in meshes[mesh] if len(faces)]


def _placed(tree: dict) -> list[tuple[np.ndarray, int]]:
    """(world matrix, mesh index) of each node that places a mesh, in the order trimesh's scene graph lists them:
    its traversal takes the scene's roots and each node's children from a stack (the last first)."""
    nodes = tree.get("nodes", [])
    scenes = tree.get("scenes")
    if not scenes:
        raise NotImplementedError  # trimesh: each mesh once, unplaced
    stack = [(None, root) for root in scenes[tree.get("scene", 0)].get("nodes", [])]
    world: dict[int, np.ndarray] = {}
    placed, seen = [], set()
    while stack:
        parent, at = stack.pop()
        if (parent, at) in seen:
            continue
        if at in world:
            raise NotImplementedError  # a node under two parents: trimesh's graph keeps one
        seen.add((parent, at))
        node = nodes[at]
        stack.extend((at, child) for child in node.get("children", []))
        world[at] = (np.eye(4) if parent is None else world[parent]) @ _local(node)
        if "mesh" in node:
            placed.append((world[at], node["mesh"]))
    return placed


def _local(node: dict) -> np.ndarray:
    """A node's matrix, then its translation, rotation and scale, multiplied as trimesh multiplies them."""
    matrix = np.array(node["matrix"], np.float64).reshape(4, 4).T if "matrix" in node else np.eye(4)
    if "translation" in node:
        moved = np.eye(4)
        moved[:3, 3] = np.asarray(node["translation"], np.float64)[:3]
        matrix = matrix @ moved
    if "rotation" in node:
        matrix = matrix @ _rotation(np.asarray(node["rotation"], np.float64).reshape(4))
    if "scale" in node:
        matrix = matrix @ np.diag(np.concatenate((np.asarray(node["scale"], np.float64).reshape(3), [1.0])))
    return matrix


def _rotation(xyzw: np.ndarray) -> np.ndarray:
    """The homogeneous rotation of a quaternion (x, y, z, w), normalised as it is read: q scaled by √(2/|q|²)
    so that the products q_i q_j are the rotation's terms (2 q_i q_j of a unit q)."""
    q = xyzw[[3, 0, 1, 2]]  # w, x, y, z
    n = float(q @ q)
    matrix = np.eye(4)
    if n < np.finfo(float).eps * 4.0:
        return matrix
    q = q * np.sqrt(2.0 / n)
    p = np.outer(q, q)
    matrix[:3, :3] = [[1.0 - p[2, 2] - p[3, 3], p[1, 2] - p[3, 0], p[1, 3] + p[2, 0]],
                      [p[1, 2] + p[3, 0], 1.0 - p[1, 1] - p[3, 3], p[2, 3] - p[1, 0]],
                      [p[1, 3] - p[2, 0], p[2, 3] + p[1, 0], 1.0 - p[1, 1] - p[2, 2]]]
    return matrix


def _primitive(primitive: dict, decoder: _Decoder, materials: list[GltfMaterial]):
    """(vertices float64, faces int64, normals or None, visual or None, colours or None) of one triangle
    primitive, as trimesh's reader and trimesh_parts.parts gave them."""
    attributes = primitive["attributes"]
    if primitive.get("mode", 4) != 4 or set(primitive) - {"attributes", "indices", "mode", "material", "extras"} \
            or not {"POSITION"} <= set(attributes) <= set(ATTRIBUTES):
        raise NotImplementedError
    for name, index in (*attributes.items(), *((("indices", primitive["indices"]),) if "indices" in primitive
                                              else ())):
        accessor = decoder.tree["accessors"][index]
        plain = (accessor.get("componentType") in INDEX_TYPES and accessor.get("type") == "SCALAR"
                 if name == "indices" else accessor.get("componentType") == 5126 and accessor.get("type") in
                 ATTRIBUTES[name])
        if not plain or "sparse" in accessor or "bufferView" not in accessor or accessor.get("normalized"):
            raise NotImplementedError
    vertices = decoder.read_accessor(attributes["POSITION"], "POSITION").astype(np.float64)
    if "indices" in primitive:
        faces = decoder.read_accessor(primitive["indices"], "indices").reshape(-1, 3).astype(np.int64)
    else:
        faces = np.arange(len(vertices), dtype=np.int64).reshape(-1, 3)
    normals = decoder.read_accessor(attributes["NORMAL"], "NORMAL").astype(np.float64) \
        if "NORMAL" in attributes else None
    visual = colours = None
    if "material" in primitive:
        uv = None
        if "TEXCOORD_0" in attributes:
            uv = decoder.read_accessor(attributes["TEXCOORD_0"], "TEXCOORD_0").copy()
            uv[:, 1] = 1.0 - uv[:, 1]  # glTF's v runs down the image; trimesh's and ours up
        visual = GltfVisual(uv, materials[primitive["material"]])
    if "COLOR_0" in attributes:  # float colours (integer ones go through gltf_decode), one a vertex, else none
        colours = decoder.read_accessor(attributes["COLOR_0"], "COLOR_0")
        if len(colours) != len(vertices):
            colours = None
        elif visual is None:  # trimesh kept them as its vertex colours, in 8 bits
            colours = _eight_bits(colours)
    return vertices, faces, normals, visual, colours


def _material(material: dict, tree: dict, images: list) -> GltfMaterial:
    if TRIMESH_READS in (material.get("extensions") or {}):
        raise NotImplementedError
    rough = material.get("pbrMetallicRoughness") or {}

    def number(table: dict, key: str) -> float | None:
        value = table.get(key)
        if value is None:
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise NotImplementedError
        return float(value)

    def image(table: dict, key: str):
        info = table.get(key)
        if info is None:
            return None
        texture = tree["textures"][info["index"]]
        if texture.get("extensions") or not isinstance(texture.get("source"), int):
            raise NotImplementedError
        return images[texture["source"]]

    base = rough.get("baseColorFactor")
    if base is not None:
        base = np.asarray(base, np.float64)
        if base.shape != (4,):
            raise NotImplementedError
        base = _eight_bits(base)
    emissive = material.get("emissiveFactor")
    if emissive is not None:
        emissive = np.asarray(emissive, np.float64).reshape(3)
        if emissive.min() < 0:
            raise NotImplementedError
    mode = material.get("alphaMode")
    if mode is not None and mode not in ("OPAQUE", "MASK", "BLEND"):
        raise NotImplementedError
    return GltfMaterial(material.get("name"), base, number(rough, "metallicFactor"), number(rough, "roughnessFactor"),
                        emissive, mode, number(material, "alphaCutoff"), image(rough, "baseColorTexture"),
                        image(material, "emissiveTexture"), image(rough, "metallicRoughnessTexture"),
                        image(material, "normalTexture"), image(material, "occlusionTexture"))


def _eight_bits(values: np.ndarray) -> np.ndarray:
    """Colour values in [0, 1] as trimesh stores a material's factor and vertex colours (its to_rgba): uint8,
    round(255 x) clipped to 0..255, a NaN or infinite value 0."""
    return np.clip(np.where(np.isfinite(values), values, 0.0) * 255, 0, 255).round().astype(np.uint8)


def _images(tree: dict, decoder: _Decoder, path: Path) -> list:
    """Each image of the document opened by PIL (decoded later, and only if a face uses it), as trimesh did; an
    image file larger than the decoded size (io.textures.MAX_TEXTURE_SIZE) is given as its path instead, so it
    is shrunk a band at a time as it is read (decode_file: the memory estimate counts it so), where PIL would
    decode it whole first (a 12000² PNG: 430 MB of pixels) or refuse it past its bomb limit."""
    if not tree.get("images"):
        return []
    import PIL.Image

    from ..textures import MAX_TEXTURE_SIZE, file_size
    from .gltf_json import uri_file
    opened = []
    for entry in tree["images"]:
        if "bufferView" in entry:
            data = bytes(decoder.view_bytes(entry["bufferView"], "image"))
        elif isinstance(entry.get("uri"), str) and entry["uri"].startswith("data:"):
            data = base64.b64decode(entry["uri"].split(",", 1)[1])
        elif isinstance(entry.get("uri"), str):
            file = uri_file(path.parent, entry["uri"])
            size = file_size(file)  # its header only (None: not a regular file, or no image: opened below)
            if size is not None and max(size) > MAX_TEXTURE_SIZE:
                opened.append(file)
                continue
            with open_regular(file, str(file), "image file") as handle:  # not a FIFO, not a device
                data = handle.read()
        else:
            raise NotImplementedError
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", PIL.Image.DecompressionBombWarning)  # its size is weighed before
                opened.append(PIL.Image.open(io.BytesIO(data)))
        except Exception as error:  # any image PIL cannot open: trimesh notes it its own way
            raise NotImplementedError from error
    return opened
