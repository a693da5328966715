"""glTF 2.0 files (.gltf, .glb): the JSON document, read and parsed once per file version (its MeshSource keeps
it for every stage that asks: the memory estimate, batch's side files, the read's checks), what it requires, the
files and images it names, and its metallic-roughness materials on the lecture's model (docs/meshes.md). trimesh
reads the geometry (`read`), from the file itself or, for data it would misread, from the document rewritten by
io/meshes/gltf_decode.py.
"""

from __future__ import annotations

import io
import json
import math
import warnings
from collections import Counter
from contextlib import suppress
from pathlib import Path
from urllib.parse import unquote

import numpy as np

from ...codes import BLENDED_ALPHA, GLTF_WRAP
from ...errors import FileProblem
from ..files import open_regular, shown_name
from .format import TEXT_READ_BYTES_PER_BYTE, Loaded, MeshFormat, Reading, weigh
from .gltf_json import MESHOPT, Document, file_uris, read_document, uri_file
from .materials import MAX_FILE_SHININESS, WIDE_LOBE, FileMaterial, TextureSource, specular_lobe
from .materials import rgb as _rgb

# Required glTF extensions read here; any other one in extensionsRequired is refused (glTF 2.0 §3.12: a loader
# must not load a file whose required extensions it does not support). Draco needs DracoPy, meshopt the meshopt
# package; io/meshes/gltf_decode.py decodes the data ones before trimesh reads the file.
SUPPORTED_REQUIRED = ("KHR_draco_mesh_compression", "KHR_materials_unlit", "KHR_materials_emissive_strength",
                      "KHR_texture_transform", "KHR_mesh_quantization", "EXT_meshopt_compression",
                      "KHR_meshopt_compression", "EXT_mesh_gpu_instancing", "KHR_materials_pbrSpecularGlossiness",
                      "EXT_texture_webp", "KHR_lights_punctual")
WEBP, LIGHTS = "EXT_texture_webp", "KHR_lights_punctual"
# glTF 2.0 §3.7.2.1 primitive modes that draw no surface: points and lines.
NOT_SURFACES = {0: "points", 1: "lines", 2: "line loops", 3: "line strips"}
UNLIT, EMISSIVE_STRENGTH, TRANSFORM = "KHR_materials_unlit", "KHR_materials_emissive_strength", "KHR_texture_transform"
SPECULAR_GLOSSINESS = "KHR_materials_pbrSpecularGlossiness"
# Required material extensions that change only how a surface looks, not its geometry or the data read: the file
# is drawn in its base material (metallic-roughness, mapped as docs/meshes.md says), with a note naming each.
LOOK_ONLY = {"KHR_materials_transmission": "transmission", "KHR_materials_volume": "volume (thickness, attenuation)",
             "KHR_materials_clearcoat": "clear coat", "KHR_materials_sheen": "sheen", "KHR_materials_ior": "index of "
             "refraction", "KHR_materials_specular": "specular strength and colour",
             "KHR_materials_iridescence": "iridescence"}
# What an extension this renderer does not read asks of it, for the refusal (the file's need, in its words).
NEEDS = {"KHR_texture_basisu": "KTX2 (Basis Universal) textures"}


def check_document(document: Document, path: Path, notes: list[str]) -> dict:
    """Refuse a document the read cannot take (nested too deep) or whose required extensions are not supported,
    naming them (a required material extension that changes only the look, LOOK_ONLY, is a note); a note for
    each image file it names that is missing. Returns the wrap modes of each material's
    colour maps (gltf_samplers; trimesh drops them)."""
    if document.problem:
        raise FileProblem(f"{str(path)!r}: {document.problem}")
    tree = document.tree
    required = [e for e in tree.get("extensionsRequired", []) if isinstance(e, str)] \
        if isinstance(tree.get("extensionsRequired", []), list) else []
    missing = [e for e in required if e not in SUPPORTED_REQUIRED and e not in LOOK_ONLY]
    used = tree.get("extensionsUsed") if isinstance(tree.get("extensionsUsed"), list) else []
    for e in dict.fromkeys([*required, *(e for e in used if isinstance(e, str))]):
        if e in LOOK_ONLY:
            notes.append(f"{path}: {'requires' if e in required else 'uses'} {e}; its {LOOK_ONLY[e]} is not "
                         "drawn: its materials are drawn in their base colour, metallic and roughness")
    if "KHR_draco_mesh_compression" in required:
        try:
            import DracoPy  # noqa: F401  (trimesh decodes Draco with it)
        except ImportError:
            missing.insert(0, "KHR_draco_mesh_compression (Draco compression: pip install DracoPy)")
    for name in MESHOPT:
        if name in required:
            try:
                import meshopt  # noqa: F401  (io/meshes/gltf_decode.py decodes meshopt with it)
            except ImportError:
                missing.insert(0, f"{name} (meshoptimizer compression: pip install meshopt)")
    check_node_transforms(tree, path)
    check_references(tree, path)
    if missing:
        named = [f"{e} ({NEEDS[e]})" if e in NEEDS else e for e in missing]
        raise FileProblem(f"{str(path)!r} requires the glTF extension(s) {', '.join(named)}, which this "
                          f"renderer does not support; supported: {', '.join(SUPPORTED_REQUIRED)} (and, drawn in "
                          f"the base material: {', '.join(LOOK_ONLY)})")
    _note_unread(tree, path, notes)
    notes.extend(f"{path}: texture {shown_name(unquote(uri))} is missing" for uri in file_uris(tree, "images")
                 if not uri_file(path.parent, uri).is_file())
    return gltf_samplers(tree)


def _note_unread(tree: dict, path: Path, notes: list[str]) -> None:
    """A note for what the file holds that is not drawn: its point and line primitives (only triangles are
    surfaces), its own lights (KHR_lights_punctual: the scene's lights light it) and cameras (the framing's is
    used)."""
    try:
        modes = Counter(NOT_SURFACES[mode] for mesh in tree.get("meshes", [])
                        for primitive in mesh.get("primitives", [])
                        if (mode := primitive.get("mode", 4)) in NOT_SURFACES)
        lights = ((tree.get("extensions") or {}).get(LIGHTS) or {}).get("lights") or []
        cameras = tree.get("cameras") or []
    except (AttributeError, TypeError):
        return  # a malformed document: the read words it
    if modes:
        said = ", ".join(f"{count} primitive(s) of {kind}" for kind, count in modes.items())
        notes.append(f"{path}: not drawn, as only triangles are surfaces: {said}")
    if isinstance(lights, list) and lights:
        notes.append(f"{path}: its {len(lights)} light(s) ({LIGHTS}) are not used: the scene's lights light it")
    if isinstance(cameras, list) and cameras:
        notes.append(f"{path}: its {len(cameras)} camera(s) are not used: the framing camera (or the scene's) is")


def texture_sizes(path: Path, document: Document, file_size, embedded: bool = False) -> list[tuple[int, int]]:
    """(height, width) of each colour map (baseColorTexture, emissiveTexture, a specular-glossiness material's
    diffuseTexture) the glTF's materials use, and of each alpha map (a MASK or BLEND material's baseColorTexture
    again: its alpha channel is decoded apart), from
    image headers only: an external file's (`file_size`, io.textures), a .glb's embedded image's from its own
    bytes alone (the rest of the binary chunk is not read); what cannot be read counts nothing. `embedded`:
    only the images in the file's own buffers (trimesh decodes those whole: floor counts them)."""
    tree = document.tree
    images = set()  # (image, channel): a MASK or BLEND material decodes its base colour map's alpha apart too
    try:
        for material in tree.get("materials", []):
            glossy = (material.get("extensions") or {}).get(SPECULAR_GLOSSINESS) or {}
            base = (material.get("pbrMetallicRoughness") or {}).get("baseColorTexture")
            for slot in (base, material.get("emissiveTexture"), glossy.get("diffuseTexture")):
                if isinstance(slot, dict) and "index" in slot:
                    texture = tree["textures"][slot["index"]]
                    source = ((texture.get("extensions") or {}).get(WEBP) or {}).get("source", texture.get("source"))
                    if source is not None:
                        images.add((source, "rgb"))
                        if slot is base and material.get("alphaMode") in ("MASK", "BLEND"):
                            images.add((source, "alpha"))
    except (AttributeError, IndexError, KeyError, TypeError):
        return []
    if not images:
        return []  # no map: no PIL (9 ms of an untextured GLB's start-up)
    from PIL import Image
    sizes = []
    for index, _ in sorted(images):
        with suppress(Exception):  # a broken image counts nothing; the read words it
            image = tree["images"][index]
            if "bufferView" in image:
                if document.binary is None:
                    continue
                view = tree["bufferViews"][image["bufferView"]]
                start, length = view.get("byteOffset", 0), view["byteLength"]
                if start + length > document.binary[1]:
                    continue
                with open_regular(path, str(path), "mesh file") as handle:
                    handle.seek(document.binary[0] + start)
                    blob = io.BytesIO(handle.read(length))
                with warnings.catch_warnings():  # a header past PIL's bomb warning: the memory check weighs it
                    warnings.simplefilter("ignore", Image.DecompressionBombWarning)
                    with Image.open(blob) as opened:
                        sizes.append((opened.height, opened.width))
            elif embedded:
                continue
            elif isinstance(image.get("uri"), str) and not image["uri"].startswith("data:"):
                size = file_size(uri_file(path.parent, image["uri"]))
                if size:
                    sizes.append(size)
    return sizes


def gltf_samplers(document: dict) -> dict:
    """What the document says of each material that trimesh drops, by (material name, key): the wrap modes
    (wrap_s, wrap_t) of its colour maps (key: the slot) from the glTF's samplers (10497 repeat, 33071 clamp,
    33648 mirror; a texture without a sampler repeats, glTF 2.0 §5.26); True for (name, UNLIT) when it is
    unlit; its emissive strength for (name, EMISSIVE_STRENGTH); a colour map's KHR_texture_transform for
    (name, TRANSFORM, slot): (offset, rotation, scale) (transform_uv); for a KHR_materials_pbrSpecularGlossiness
    material, (name, SPECULAR_GLOSSINESS): (specular factor (3,), glossiness factor), and its diffuseTexture is
    the baseColorTexture slot (io/meshes/gltf_decode.py hands it to trimesh so)."""
    found = {}
    # a malformed table: the maps read before it keep their modes, the rest repeat
    with suppress(AttributeError, IndexError, TypeError, ValueError):
        textures, samplers = document.get("textures", []), document.get("samplers", [])
        for material in document.get("materials", []):
            name, extensions = material.get("name"), material.get("extensions")
            extensions = extensions if isinstance(extensions, dict) else {}
            if UNLIT in extensions:
                found.setdefault((name, UNLIT), True)
            strength = (extensions.get(EMISSIVE_STRENGTH) or {}).get("emissiveStrength", 1.0)
            if isinstance(strength, (int, float)) and not isinstance(strength, bool) and strength != 1.0:
                found.setdefault((name, EMISSIVE_STRENGTH), float(strength))
            slots = {"baseColorTexture": (material.get("pbrMetallicRoughness") or {}).get("baseColorTexture"),
                     "emissiveTexture": material.get("emissiveTexture")}
            glossy = extensions.get(SPECULAR_GLOSSINESS)
            if isinstance(glossy, dict):
                specular = np.clip(np.asarray(glossy.get("specularFactor", (1.0, 1.0, 1.0)), np.float64)[:3], 0, 1)
                found.setdefault((name, SPECULAR_GLOSSINESS),
                                 (specular, min(max(float(glossy.get("glossinessFactor", 1.0)), 0.0), 1.0),
                                  "specularGlossinessTexture" in glossy))
                slots["baseColorTexture"] = glossy.get("diffuseTexture")
            for slot, info in slots.items():
                if not isinstance(info, dict) or not isinstance(info.get("index"), int):
                    continue
                transform = (info.get("extensions") or {}).get(TRANSFORM)
                if isinstance(transform, dict):
                    found.setdefault((name, TRANSFORM, slot), (
                        tuple(float(x) for x in transform.get("offset", (0.0, 0.0)))[:2],
                        float(transform.get("rotation", 0.0)),
                        tuple(float(x) for x in transform.get("scale", (1.0, 1.0)))[:2]))
                sampler = textures[info["index"]].get("sampler")
                modes = samplers[sampler] if isinstance(sampler, int) else {}
                found.setdefault((name, slot), (GLTF_WRAP.get(modes.get("wrapS"), "repeat"),
                                                GLTF_WRAP.get(modes.get("wrapT"), "repeat")))
    return found


def transform_uv(uv: np.ndarray, transform: tuple) -> np.ndarray:
    """(N, 2) texture coordinates as trimesh gives them (v up: 1 − glTF's v) through a KHR_texture_transform
    (offset, rotation, scale), in glTF's own coordinates (v down) as the extension defines it: uv' = T R S uv,
    R turning the UVs counter-clockwise by `rotation` radians as seen in UV space, whose v points down:
    u' = u cos r + v sin r, v' = −u sin r + v cos r. The spec's GLSL listing reads as the opposite sign
    (glTF issue #1563); its own example (offset (0, 1), rotation π/2, scale 0.5: the lower left quadrant),
    the TextureTransformTest sample's green marker and three.js, Babylon.js and Blender take this one.
    Returned v up again."""
    (ox, oy), rotation, (sx, sy) = transform
    u, v = uv[:, 0] * sx, (1.0 - uv[:, 1]) * sy
    c, s = math.cos(rotation), math.sin(rotation)
    return np.column_stack([c * u + s * v + ox, 1.0 - (-s * u + c * v + oy)])


def from_pbr(material, path: Path, notes: list[str], sources: list[TextureSource], samplers: dict) -> FileMaterial:
    """glTF 2.0 metallic-roughness → Phong: a stated approximation (docs/meshes.md).

    k_d = k_a = base colour; k_s = F0 of the metallic workflow, lerp(0.04, base colour, metallic) (glTF
    2.0 Appendix B); f = 2/α² − 2 with α = roughness², the Blinn-Phong exponent of the same lobe width
    (Walter et al. 2007); both through specular_lobe, so roughness 1 is matte; k_e = emissive factor.
    A baseColorTexture is the k_d map (and k_a's), an emissiveTexture the k_e map, each with its sampler's
    wrap modes (decoded later, only if a face uses the material). glTF's defaults: base colour 1, metallic 1,
    roughness 1, emissive 0. KHR_materials_emissive_strength multiplies the emissive factor (k_e is clamped
    to 1, and said); KHR_materials_unlit is the lecture's emission-only material: k_e = base colour (its
    baseColorTexture the k_e map), k_a = k_d = k_s = 0.

    KHR_materials_pbrSpecularGlossiness states the same lobe in other terms, mapped the same way: k_d = k_a =
    diffuse factor (its diffuseTexture the k_d map, given here as the base colour), k_s = specular factor (the F0
    the metallic workflow computes), roughness = 1 − glossiness, so f = 2/(1 − glossiness)⁴ − 2; through
    specular_lobe too. Its defaults: diffuse 1, specular 1, glossiness 1.
    """
    base = material.baseColorFactor
    base = np.ones(4) if base is None else np.asarray(base, np.float64) / 255.0
    metallic = 1.0 if material.metallicFactor is None else float(material.metallicFactor)
    roughness = 1.0 if material.roughnessFactor is None else float(material.roughnessFactor)
    emissive = np.zeros(3) if material.emissiveFactor is None else np.asarray(material.emissiveFactor, np.float64)
    rgb = np.clip(base[:3], 0, 1)
    metallic, roughness = min(max(metallic, 0.0), 1.0), min(max(roughness, 0.0), 1.0)
    glossy = samplers.get((material.name, SPECULAR_GLOSSINESS))
    if glossy is not None:
        roughness = 1.0 - glossy[1]
    alpha = roughness * roughness
    shininess = MAX_FILE_SHININESS if alpha == 0 else 2 / alpha**2 - 2
    name = material.name or f"{path.stem}-material"

    def source(key: str, said: str, channel: str = "rgb") -> int:
        """The material's map `key` as a texture source with its sampler's wrap modes: its index in `sources`."""
        wrap_s, wrap_t = samplers.get((material.name, key), ("repeat", "repeat"))
        sources.append(TextureSource(getattr(material, key), wrap_s, wrap_t, f"{path}: material {name!r}: its {said}",
                                     channel))
        return len(sources) - 1
    mode = getattr(material, "alphaMode", None)
    mask = {}
    if mode in ("MASK", "BLEND"):  # glTF 2.0 §3.9.4: alpha = factor × the base colour map's alpha
        cutoff = getattr(material, "alphaCutoff", None)
        cutoff = 0.5 if cutoff is None else max(float(cutoff), 0.0)
        mask = {"alpha_cutoff": BLENDED_ALPHA if mode == "BLEND" else cutoff, "alpha": float(base[3])}
        if getattr(material, "baseColorTexture", None) is not None:
            mask["alpha_map"] = source("baseColorTexture", "baseColorTexture's alpha", "alpha")
        # MASK cuts away (ray_queries.cut_masked); BLEND is screen-door coverage: seen with probability alpha
        said = (f"alphaMode MASK cuts the surface away where alpha < {mask['alpha_cutoff']:.3g}" if mode == "MASK" else
                "alphaMode BLEND is drawn as coverage: each ray sample sees the surface with probability alpha "
                "(render.samples = 4 or more averages it to a blend)")
        notes.append(f"{path}: material {name!r}: {said}; a shadow ray (global mode) still sees the whole surface")
    maps = {key: source(key, key) for key in ("baseColorTexture", "emissiveTexture")
            if getattr(material, key, None) is not None}
    ignored = [key for key in ("metallicRoughnessTexture", "normalTexture", "occlusionTexture")
               if getattr(material, key, None) is not None]
    if glossy is not None:
        notes.append(f"{path}: specular-glossiness materials are mapped onto the Phong model: k_d = k_a = diffuse, "
                     f"k_s = specular × min(1, (f + 2)/{WIDE_LOBE + 2:g}), f = 2/(1 − glossiness)⁴ − 2 in [1, "
                     f"{MAX_FILE_SHININESS:g}], k_e = emissive (docs/meshes.md)")
        if glossy[2]:
            notes.append(f"{path}: material {name!r}: specularGlossinessTexture not applied; its factors are used")
    if ignored:
        notes.append(f"{path}: material {name!r}: {', '.join(ignored)} not applied; its factors are used")
    if samplers.get((material.name, UNLIT)):
        black = (0.0, 0.0, 0.0)
        return FileMaterial(name, black, black, black, _rgb(rgb), MAX_FILE_SHININESS,
                            ke_map=maps.get("baseColorTexture", -1), **mask)
    emissive = emissive[:3] * samplers.get((material.name, EMISSIVE_STRENGTH), 1.0)
    if emissive.max(initial=0.0) > 1:
        notes.append(f"{path}: material {name!r}: emissive factor × strength {emissive.max():.3g} is clamped to 1, "
                     "the lecture's largest k_e")
    f0 = glossy[0] if glossy is not None else 0.04 + (rgb - 0.04) * metallic  # the lobe's peak (F0)
    ks, shininess = specular_lobe(f0, shininess)
    return FileMaterial(name, _rgb(rgb), _rgb(rgb), _rgb(ks), _rgb(np.clip(emissive, 0, 1)), float(shininess),
                        kd_map=maps.get("baseColorTexture", -1), ke_map=maps.get("emissiveTexture", -1), **mask)


def check_references(tree: dict, path: Path) -> None:
    """Refuse, in one line, a bufferView naming a buffer the file does not have, an accessor naming a bufferView it
    does not have, an external buffer file that is missing (trimesh raised IndexError or FileNotFoundError), and a
    byteStride shorter than an accessor's elements (read overlapping, silently)."""
    def table(key: str) -> list:
        value = tree.get(key, [])
        return value if isinstance(value, list) else []
    buffers, views = table("buffers"), table("bufferViews")
    for b, buffer in enumerate(buffers):
        uri = buffer.get("uri") if isinstance(buffer, dict) else None
        if isinstance(uri, str) and not uri.startswith("data:") and not uri_file(path.parent, uri).is_file():
            raise FileProblem(f"{str(path)!r}: buffers[{b}].uri names {unquote(uri)!r}, which is missing; allowed: "
                              f"a file in {str(path.parent)!r}")
    for kind, rows, field, size in (("bufferViews", views, "buffer", len(buffers)),
                                    ("accessors", table("accessors"), "bufferView", len(views)),
                                    ("images", table("images"), "bufferView", len(views))):
        for n, row in enumerate(rows):
            if not isinstance(row, dict) or field not in row:
                continue
            value = row[field]
            if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value < size:
                allowed = f"0..{size - 1}" if size else f"none: the file has no {field}s"
                raise FileProblem(f"{str(path)!r}: {kind}[{n}].{field} is {_short(value)}; allowed: {allowed}")
    from .gltf_decode import DTYPES, WIDTHS, short_stride
    for n, accessor in enumerate(table("accessors")):  # an element fits its stride (§3.6.2.4); trimesh overlapped them
        try:
            stride = views[accessor["bufferView"]].get("byteStride")
            element = DTYPES[accessor["componentType"]]().itemsize * WIDTHS[accessor["type"]]
        except (AttributeError, KeyError, TypeError):
            continue  # no bufferView, or a malformed accessor: the read words it
        if isinstance(stride, int) and not isinstance(stride, bool) and stride < element:
            raise FileProblem(f"{str(path)!r}: {short_stride(accessor['bufferView'], stride, n, element)}")


TRS = (("matrix", 16), ("translation", 3), ("rotation", 4), ("scale", 3))


def check_node_transforms(tree: dict, path: Path) -> None:
    """Refuse, in one line, a node whose matrix or translation, rotation or scale is not a list of finite numbers of
    its length (a NaN matrix gave numpy's RuntimeWarnings and a blank image)."""
    nodes = tree.get("nodes", [])
    if not isinstance(nodes, list):
        return  # trimesh words it
    for n, node in enumerate(nodes):
        if not isinstance(node, dict):
            continue
        for field, length in TRS:
            if field not in node:
                continue
            value = node[field]
            good = isinstance(value, list) and len(value) == length and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in value)
            if not good:
                raise FileProblem(f"{str(path)!r}: nodes[{n}].{field} is {_short(value)}; allowed: {length} finite "
                                  "numbers")


def _short(value) -> str:
    text = repr(value).replace("nan", "NaN").replace("inf", "Infinity")
    return text if len(text) <= 80 else text[:77] + "..."


def read(reading: Reading) -> Loaded:
    """The document checked (what it requires, the images it names), then the geometry: by numpy views of its
    buffers where it holds what io/meshes/gltf_parts.py reads (most files: trimesh's import is half a small file's
    process), else through trimesh, given the document rewritten as plain glTF where it would misread the data
    (compressed, quantized or instanced data, specular-glossiness materials: io/meshes/gltf_decode.py)."""
    from .gltf_decode import decode_gltf, needs_decoding, read_buffers
    from .gltf_parts import gltf_parts
    path, document = reading.path, reading.source.document
    samplers = check_document(document, path, reading.notes)
    if not needs_decoding(document.tree):
        found = gltf_parts(document.tree, read_buffers(document.tree, path, document, reading.where), path)
        if found is not None:
            return Loaded(found, samplers=samplers)
    from .trimesh_parts import RegularFiles, load, parts
    resolver = RegularFiles(path)
    resolver.locate = uri_file  # names are URIs, percent-encoded
    if needs_decoding(document.tree):
        tree, resolver.decoded = decode_gltf(path, document, reading.where, reading.notes)
        loaded = load(reading, io.BytesIO(json.dumps(tree).encode()), "gltf", resolver)
    else:
        loaded = load(reading, resolver=resolver)
    return Loaded(parts(loaded), samplers=samplers)


def count(handle, size: int, mesh) -> int | None:
    """Triangles over every node's mesh (each node counts, and each instance of an EXT_mesh_gpu_instancing node:
    instances × the mesh's triangles), from the accessors' counts in the parsed document; or their vertices
    (less 2) where more (format.weigh: a compressed bufferView decodes to what its accessors read,
    io/meshes/gltf_decode.py). None for a document too large to parse here."""
    document = mesh.document.tree
    if not document:
        return None
    try:
        accessors, meshes = document.get("accessors", []), document.get("meshes", [])
        placed = [node for node in document.get("nodes", []) if "mesh" in node]
        uses = [(node["mesh"], _instances(node, accessors)) for node in placed] or [(m, 1) for m in range(len(meshes))]
        total = vertices = 0
        for mesh, copies in uses:
            for primitive in meshes[mesh].get("primitives", []):
                indexed = primitive.get("indices", primitive.get("attributes", {}).get("POSITION"))
                total += copies * (accessors[indexed]["count"] // 3)
                vertices += copies * int(accessors[primitive.get("attributes", {}).get("POSITION", indexed)]["count"])
    except (AttributeError, IndexError, KeyError, TypeError, ValueError):
        return None  # a malformed document (a primitive that is a number): the size bound stands; the read words it
    return weigh(total, vertices)


def _instances(node: dict, accessors: list) -> int:
    """How many times a node places its mesh: its EXT_mesh_gpu_instancing accessors' count (the largest, if they
    disagree: the read refuses that), else 1."""
    extensions = node.get("extensions")
    found = extensions.get("EXT_mesh_gpu_instancing") if isinstance(extensions, dict) else None
    attributes = found.get("attributes") if isinstance(found, dict) else None
    if not isinstance(attributes, dict):
        return 1  # not instanced, or malformed: the read words it
    return max((int(accessors[index]["count"]) for index in attributes.values()), default=1)


GLB_READ_BYTES_PER_BYTE = 2  # a .glb's binary chunks are read as they are
# A .gltf's external buffer is read whole into bytes (trimesh's resolver): a 600 MB buffer of which the accessors
# use 36 bytes peaked 734 MB (interpreter included).
BUFFER_READ_BYTES_PER_BYTE = 1


def held(path: Path, mesh) -> tuple[int, int]:
    """A .gltf's external buffers, read whole whatever its accessors claim to use of them."""
    return sum(_size(buffer) for buffer in mesh.side_files), 0


def _size(path: Path) -> int:
    with suppress(OSError):
        return path.stat().st_size
    return 0  # the read reports a missing buffer


# An image in a .glb's buffer is decoded whole by trimesh (PIL: 4 bytes a texel as RGBA) before it is shrunk to
# the map's size (a copy of as much): a 12000² PNG peaked 999 MB under a 300 MB budget.
EMBEDDED_IMAGE_BYTES_PER_TEXEL = 8


def floor(path: Path, size: int, mesh) -> int:
    """The file's bytes as read, a .gltf's buffers, and its embedded images decoded whole."""
    from ..textures import file_size
    per_byte = GLB_READ_BYTES_PER_BYTE if path.suffix.lower() == ".glb" else TEXT_READ_BYTES_PER_BYTE
    images = sum(h * w for h, w in texture_sizes(path, mesh.document, file_size, embedded=True))
    return size * per_byte + held(path, mesh)[0] * BUFFER_READ_BYTES_PER_BYTE + \
        images * EMBEDDED_IMAGE_BYTES_PER_TEXEL


def describe(path: Path) -> dict:
    """Its JSON document, parsed (at most JSON_LIMIT), a .gltf's external buffer files (side files) and the image
    files its URIs name."""
    document = read_document(path)
    buffers = () if path.suffix.lower() == ".glb" else file_uris(document.tree, "buffers")
    return {"document": document, "side_files": tuple(uri_file(path.parent, uri) for uri in buffers),
            "images": tuple(uri_file(path.parent, uri) for uri in file_uris(document.tree, "images"))}


def _texture_sizes(mesh) -> tuple[tuple[int, int], ...]:
    from ..textures import file_size
    return tuple(texture_sizes(mesh.path, mesh.document, file_size))


FORMAT = MeshFormat(
    names=("glTF", "GLB"), suffixes=(".gltf", ".glb"), read=read, count=count, floor=floor, held=held,
    describe=describe, texture_sizes=_texture_sizes, parse_bytes=70,
    content=lambda head, found, size, suffix: found == ("GLB" if suffix == ".glb" else "JSON"),
    up=(0.0, 1.0, 0.0),  # glTF 2.0 §3.4: +Y up
    # glTF 2.0 §3.9.2: colour textures are sRGB-encoded, factors and COLOR_0 linear, lit in linear values
    linear="glTF 2.0", pbr="glTF metallic-roughness")
