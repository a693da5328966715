"""COLLADA (.dae) documents made readable by trimesh's reader (pycollada) where it would drop their geometry:
a skinned or morphed mesh (`<instance_controller>`) is instanced as its source mesh in its bind-shape pose, and
a material whose effect has no `<profile_COMMON>` (a GLSL or CG effect only, or a material the file does not
define) is left out, so its triangles render with the default material instead of vanishing ("holds no
triangles": pycollada drops a node whose material it cannot read), and numbers written with a decimal comma
(`0,5`, by exporters run under a comma locale; assimp reads them) get a decimal point, where pycollada would
drop every array and colour that holds one. Each change is one note. A document that needs none of these is
passed on byte for byte. `collada_up` reads the up axis the document states (`<asset><up_axis>`)."""

from __future__ import annotations

import io
import re
from dataclasses import dataclass, replace
from pathlib import Path, PurePosixPath
from urllib.parse import unquote, urlparse

import numpy as np

from ...errors import FileProblem, SceneError
from ..files import open_regular, shown_name
from .format import Loaded, MeshFormat, Reading, image_file_sizes
from .materials import FileMaterial, specular_lobe
from .mtl import MAX_SIDE_FILE

IDENTITY = " ".join(["1", "0", "0", "0", "0", "1", "0", "0", "0", "0", "1", "0", "0", "0", "0", "1"])
# Elements whose text is a whitespace-separated list of floats (COLLADA 1.4.1 schema), where a comma between
# two digits can only be a decimal comma.
FLOAT_LISTS = ("float_array", "float", "color", "translate", "rotate", "scale", "matrix", "lookat", "skew",
               "bind_shape_matrix")
DECIMAL_COMMA = re.compile(r"(?<=\d),(?=\d)")
# <asset><up_axis> (COLLADA 1.4.1 §5: X_UP, Y_UP (the default) or Z_UP); the asset comes first in a document.
UP_AXIS = re.compile(rb"<(?:\w+:)?up_axis>\s*([XYZ])_UP\s*</(?:\w+:)?up_axis>")
UP_VECTORS = {b"X": (1.0, 0.0, 0.0), b"Y": (0.0, 1.0, 0.0), b"Z": (0.0, 0.0, 1.0)}
ASSET_LIMIT = 1 << 16  # bytes searched for the up axis


def collada_up(data: bytes) -> tuple[float, float, float] | None:
    """The up axis the document's `<asset><up_axis>` states, as a unit vector; None when it states none (or is
    not UTF-8 or ASCII text: a UTF-16 document is read with +Y up, COLLADA's default)."""
    found = UP_AXIS.search(data, 0, ASSET_LIMIT)
    return UP_VECTORS[found.group(1)] if found else None


def collada_text(data: bytes, path: Path, notes: list[str]) -> bytes:
    """The document `data` with controller instances made geometry instances and unreadable material bindings
    dropped (module docstring); `data` itself when neither occurs or it is not XML lxml reads (trimesh words
    that)."""
    if (b"instance_controller" not in data and b"instance_material" not in data
            and re.search(rb"\d,\d", data) is None):
        return data
    from lxml import etree
    root = _tree(data)
    if root is None:
        return data
    namespace = root.tag[:root.tag.index("}") + 1] if root.tag.startswith("{") else ""
    by_id = {element.get("id"): element for element in root.iter() if element.get("id")}
    skinned = 0
    for instance in list(root.iter(f"{namespace}instance_controller")):
        controller = by_id.get((instance.get("url") or "").lstrip("#"))
        found = None if controller is None else next(
            (c for c in controller if isinstance(c.tag, str) and c.tag in (f"{namespace}skin", f"{namespace}morph")),
            None)
        source = None if found is None else (found.get("source") or "").lstrip("#")
        if source not in by_id or by_id[source].tag != f"{namespace}geometry":
            continue
        # The source mesh as bound: the skin's bind_shape_matrix (row-major, column vectors) under the instance.
        matrix = found.find(f"{namespace}bind_shape_matrix")
        geometry = etree.Element(f"{namespace}instance_geometry", url=f"#{source}")
        geometry.extend(child for child in list(instance) if child.tag == f"{namespace}bind_material")
        if matrix is not None and " ".join((matrix.text or "").split()) not in ("", IDENTITY) and _matrix(matrix.text):
            node = etree.Element(f"{namespace}node")
            etree.SubElement(node, f"{namespace}matrix").text = " ".join(matrix.text.split())
            node.append(geometry)
            geometry = node
        instance.getparent().replace(instance, geometry)
        skinned += 1
    if skinned:
        notes.append(f"{path}: {skinned} skinned or morphed mesh(es) (<instance_controller>) drawn in their "
                     "bind-shape pose; the skeleton and animations are not applied")
    commas = 0
    for element in root.iter(*(f"{namespace}{tag}" for tag in FLOAT_LISTS)):
        if element.text and "," in element.text:
            element.text, count = DECIMAL_COMMA.subn(".", element.text)
            commas += count
    if commas:
        notes.append(f"{path}: {commas} number(s) written with a decimal comma (as 0,5) read as decimal points")
    dropped = set()
    for binding in list(root.iter(f"{namespace}instance_material")):
        target = (binding.get("target") or "").lstrip("#")
        material = by_id.get(target)
        effect = None
        if material is not None:
            reference = material.find(f"{namespace}instance_effect")
            effect = by_id.get((reference.get("url") or "").lstrip("#")) if reference is not None else None
        if effect is None or effect.find(f"{namespace}profile_COMMON") is None:
            dropped.add(target or "?")
            binding.getparent().remove(binding)
    if dropped:
        notes.append(f"{path}: material(s) {', '.join(sorted(dropped))} not defined or without a profile_COMMON "
                     "effect (the only one read); their triangles use the default material")
    return etree.tostring(root, xml_declaration=True, encoding="utf-8") if skinned or commas or dropped else data


def _matrix(text: str) -> bool:
    try:
        values = np.array(text.split(), np.float64)
    except ValueError:
        return False
    return values.shape == (16,) and bool(np.isfinite(values).all())


def read(reading: Reading) -> Loaded:
    """A note for each image file it names that is missing, the values trimesh would take silently refused
    (check_values), then the document (made readable: collada_text) through trimesh, with the up axis it
    states."""
    from .trimesh_parts import RegularFiles, load, parts
    _check_images(reading.path, reading.handle, reading.notes)
    data = reading.handle.read()
    root = _tree(data)
    if root is not None:
        check_values(root, reading.path)
    text = io.BytesIO(collada_text(data, reading.path, reading.notes))
    effects = common_effects(root) if root is not None else []
    resolver = RegularFiles(reading.path)
    resolver.locate = image_file  # the images' references as files written on Windows mean them too
    return Loaded(parts(load(reading, text, resolver=resolver)), up=collada_up(data),
                  own_material=(lambda material, built: _as_effect(effects, material, built)) if effects else None)


@dataclass(frozen=True)
class CommonEffect:
    """A <profile_COMMON> technique's values (COLLADA 1.4.1 §8): the lecture's own model, which trimesh turns
    into metallic-roughness (specular and ambient dropped, shininess s made roughness √(2/(2 + s)))."""
    shading: str                                    # phong, blinn, lambert or constant
    emission: tuple[float, float, float] | None
    ambient: tuple[float, float, float] | None
    diffuse: tuple[float, float, float, float] | None  # None: a texture (or none)
    specular: tuple[float, float, float] | None
    shininess: float | None
    alpha: float                                    # trimesh's: the <transparent> colour's alpha, else diffuse's


TECHNIQUES = ("phong", "blinn", "lambert", "constant")


def common_effects(root) -> list[CommonEffect]:
    """The <profile_COMMON> technique of every <effect> a <material> instances, in document order."""
    by_id = {element.get("id"): element for element in root.iter() if element.get("id")}
    found = []
    for material in (element for element in root.iter() if _local(element.tag) == "material"):
        instance = next((child for child in material if _local(child.tag) == "instance_effect"), None)
        effect = by_id.get((instance.get("url") or "").lstrip("#")) if instance is not None else None
        technique = None if effect is None else next(
            (element for element in effect.iter() if _local(element.tag) in TECHNIQUES
             and _local(element.getparent().tag) == "technique"
             and _local(element.getparent().getparent().tag) == "profile_COMMON"), None)
        if technique is None:
            continue
        values = {_local(child.tag): _value(child) for child in technique}
        diffuse = values.get("diffuse")
        transparent = values.get("transparent")
        alpha = transparent[3] if transparent is not None and len(transparent) == 4 else \
            diffuse[3] if diffuse is not None and len(diffuse) == 4 else 1.0
        found.append(CommonEffect(_local(technique.tag), _rgb(values.get("emission")), _rgb(values.get("ambient")),
                                  None if diffuse is None else (*_rgb(diffuse), alpha),
                                  _rgb(values.get("specular")), (values.get("shininess") or (None,))[0], alpha))
    return found


def _value(element) -> tuple[float, ...] | None:
    """The numbers of a <color> or <float> child (None for a <texture> or a <param> reference)."""
    child = next((c for c in element if _local(c.tag) in ("color", "float")), None)
    try:
        values = tuple(float(word) for word in (child.text or "").split()) if child is not None else None
    except ValueError:
        return None
    return values if values and all(np.isfinite(values)) else None


def _rgb(values) -> tuple[float, float, float] | None:
    return None if values is None or len(values) < 3 else tuple(min(max(v, 0.0), 1.0) for v in values[:3])


def _as_effect(effects: list[CommonEffect], material, built: FileMaterial) -> FileMaterial | None:
    """`built` (the glTF rule's reading of trimesh's material: its k_d, maps and alpha) with the values of the
    effect trimesh made `material` from: k_a = ambient (k_d where none), k_s and f = specular and shininess
    through specular_lobe (lambert: no specular; constant: emission only), k_e = emission. None when no effect
    makes this material (it keeps the glTF rule, noted)."""
    effect = next((e for e in effects if _makes(e, material)), None)
    if effect is None:
        return None
    black = (0.0, 0.0, 0.0)
    emission = effect.emission or black
    if effect.shading == "constant":
        return replace(built, ka=black, kd=black, ks=black, ke=emission, ka_map=-1, kd_map=-1)
    ka = effect.ambient if effect.ambient is not None else built.kd
    if effect.shading == "lambert" or effect.specular is None:
        return replace(built, ka=ka, ks=black, ke=emission)
    ks, shininess = specular_lobe(effect.specular, effect.shininess if effect.shininess is not None else 0.0)
    return replace(built, ka=ka, ks=tuple(float(v) for v in ks), shininess=shininess, ke=emission)


def _makes(effect: CommonEffect, material) -> bool:
    """Whether trimesh's reader (exchange/dae.py _parse_material) makes `material` from `effect`: base colour =
    diffuse (white under a texture) with the alpha above, emissive = emission, roughness = √(2/(2 + s))."""
    base = np.asarray(material.baseColorFactor if material.baseColorFactor is not None else [255] * 4, np.float64)
    wanted = np.array(effect.diffuse if effect.diffuse is not None else (1.0, 1.0, 1.0, effect.alpha)) * 255
    emissive = np.asarray(material.emissiveFactor if material.emissiveFactor is not None else np.zeros(3), np.float64)
    roughness = 1.0 if effect.shininess is None or 2 + effect.shininess <= 0 else np.sqrt(2 / (2 + effect.shininess))
    return (base.shape == (4,) and bool(np.all(np.abs(base - wanted) <= 1.0))
            and np.allclose(emissive, effect.emission or (0.0, 0.0, 0.0), atol=1e-6)
            and abs(float(material.roughnessFactor if material.roughnessFactor is not None else 1.0) - roughness)
            <= 1e-6)


def _check_images(path: Path, handle, notes: list[str]) -> None:
    """A note for each image file a COLLADA file's <library_images> names that is missing: trimesh's reader
    drops such a map without a word, and the model renders in its factors alone (white for the duck)."""
    try:
        references = image_references(handle.read(MAX_SIDE_FILE))
    finally:
        handle.seek(0)
    notes.extend(f"{path}: texture {shown_name(_spelled(reference))} is missing" for reference in references
                 if is_local(reference) and not image_file(path.parent, reference).is_file())


def image_references(data: bytes) -> list[str]:
    """The image references of a COLLADA document's <library_images> (<init_from>, 1.4, or its <ref>, 1.5), read
    from its first bytes (exporters write the images before the geometry); embedded data: URIs left out."""
    text = data.decode("utf-8", errors="replace")
    found = (re.search(r"<init_from>\s*(?:<ref>)?\s*([^<]+?)\s*<", image)
             for image in re.findall(r"<image\b[^>]*>(.*?)</image>", text, re.S))
    return [match[1] for match in found if match is not None and not match[1].startswith("data:")]


def is_local(reference: str) -> bool:
    """Whether an image reference names a file (a relative path or a file: URI), not a web address."""
    scheme = urlparse(reference.replace("\\", "/")).scheme
    return scheme in ("", "file") or len(scheme) == 1  # C:/... is a Windows drive, not a scheme


def _spelled(reference: str) -> str:
    """An image reference as a path, for messages: the file: scheme dropped, percent-escapes decoded."""
    text = re.sub(r"(?i)^file:(//(?=/))?(//)?", "", unquote(reference.replace("\\", "/")))
    return str(PurePosixPath(text)) if text else text


def image_file(folder: Path, reference: str) -> Path:
    """The file a COLLADA image reference names, for a document in `folder`. A URI relative to the document by
    the specification; files written on Windows are read as they were meant: backslashes are folder separators,
    `file://..\\x.jpg` and `\\..\\x.jpg` are relative to the document, and a name found in no folder it could
    mean is looked for beside the document (an absolute path from the exporter's machine), then by its name in
    any case (Windows' file names ignore it: `EarthCylindric.jpg` for `earthCylindric.jpg`)."""
    spelled = _spelled(reference)
    candidates = [Path(spelled)] if Path(spelled).is_absolute() and not re.match(r"^/?[A-Za-z]:/", spelled) else []
    candidates += [folder / spelled.lstrip("/"), folder / PurePosixPath(spelled).name]
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    for candidate in candidates[-2:]:  # the same name, another case, in the folder it names
        try:
            matches = [entry for entry in candidate.parent.iterdir() if entry.name.lower() == candidate.name.lower()]
        except OSError:
            continue
        if len(matches) == 1 and matches[0].is_file():
            return matches[0]
    return candidates[-2]


def describe(path: Path) -> dict:
    """The image files its <library_images> names that exist (io.meshes.source: a batch's inputs, what no output
    may replace, what the memory estimate weighs)."""
    try:
        with open_regular(path, str(path), "mesh file") as handle:
            references = image_references(handle.read(MAX_SIDE_FILE))
    except (OSError, SceneError):
        return {}
    images = (image_file(path.parent, reference) for reference in references if is_local(reference))
    return {"images": tuple(dict.fromkeys(image for image in images if image.is_file()))}


# ---------------------------------------------------------------- what the document builds, before it is read

NOT_FINITE = re.compile(r"(?i)\b(nan|inf|infinity)\b")
INDEX_LISTS = ("p", "v", "vcount")


def _tree(data: bytes):
    """The document's element tree (lxml, no entities, no network, no DTD), or None when lxml cannot parse it
    (trimesh words that)."""
    from lxml import etree
    try:
        return etree.fromstring(data, etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False,
                                                      huge_tree=False))
    except (etree.XMLSyntaxError, ValueError):
        return None


def _local(tag) -> str:
    return tag.rpartition("}")[2] if isinstance(tag, str) else ""


def check_values(root, path: Path) -> None:
    """Refuse what pycollada reads silently wrong: a position that is NaN or infinite (read as 0), a negative
    vertex index (numpy wraps -1 to the last vertex) and one past the positions (trimesh drops that geometry
    without a word: a file of one said "holds no triangles")."""
    by_id = {element.get("id"): element for element in root.iter() if element.get("id")}
    for element in root.iter():
        name = _local(element.tag)
        if name in INDEX_LISTS and element.text and "-" in element.text:
            raise FileProblem(f"{str(path)!r}: a <{name}> list holds a negative index "
                              f"({next(w for w in element.text.split() if w.startswith('-'))[:20]}); allowed: "
                              "indices 0 or more")
        if name == "p" and element.text:
            _check_vertex_indices(element, by_id, path)
        if name == "input" and element.get("semantic") == "POSITION":
            source = by_id.get((element.get("source") or "").lstrip("#"))
            values = None if source is None else next(
                (child for child in source if _local(child.tag) == "float_array"), None)
            if values is not None and values.text and NOT_FINITE.search(values.text):
                raise FileProblem(f"{str(path)!r}: positions {values.get('id') or ''} hold NaN or infinite "
                                  "numbers; every vertex must have finite coordinates")


def _check_vertex_indices(p, by_id: dict, path: Path) -> None:
    """Refuse a <p> list whose VERTEX index (at its input's offset, every `stride` values: the primitive's largest
    offset + 1) is past the count of the positions its <vertices> reads (their accessor's count)."""
    primitive = p.getparent()
    inputs = [child for child in primitive if _local(child.tag) == "input"]
    offsets = [int(child.get("offset", "0")) for child in inputs if (child.get("offset") or "0").isdigit()]
    vertex = next((child for child in inputs if child.get("semantic") == "VERTEX"), None)
    vertices = by_id.get((vertex.get("source") or "").lstrip("#")) if vertex is not None else None
    position = next((child for child in vertices if _local(child.tag) == "input"
                     and child.get("semantic") == "POSITION"), None) if vertices is not None else None
    source = by_id.get((position.get("source") or "").lstrip("#")) if position is not None else None
    accessor = next((child for child in source.iter() if _local(child.tag) == "accessor"), None) \
        if source is not None else None
    count = accessor.get("count") if accessor is not None else None
    if not (count or "").isdigit() or not offsets or not (vertex.get("offset") or "0").isdigit():
        return  # a document this check cannot follow: pycollada words what is wrong with it
    words = p.text.split()[int(vertex.get("offset") or "0")::max(offsets) + 1]
    largest = max((int(word) for word in words if word.isdigit()), default=-1)
    if largest >= int(count):
        raise FileProblem(f"{str(path)!r}: a <p> list of <{_local(primitive.tag)}> names vertex {largest} of the "
                          f"{int(count):,} its positions {source.get('id') or ''} hold; allowed: 0..{int(count) - 1}")


def count(handle, size: int, mesh) -> int | None:
    """The triangles the document builds: each geometry's triangles (a polylist's from its vcount) times the
    times its scene places it, through <instance_node> (a 2 kB document can place one box 10^8 times: this
    count is what the memory check weighs, before trimesh expands it). None for a document lxml cannot parse."""
    root = _tree(handle.read())
    if root is None:
        return None
    by_id = {element.get("id"): element for element in root.iter() if element.get("id")}
    totals: dict[int, int] = {}

    def geometry(element) -> int:
        total = 0
        for primitive in element.iter():
            name = _local(primitive.tag)
            if name == "polylist":
                vcount = next((c for c in primitive if _local(c.tag) == "vcount"), None)
                sides = np.fromstring(vcount.text or "", dtype=np.int64, sep=" ") if vcount is not None else []
                total += int(np.maximum(np.asarray(sides) - 2, 0).sum())
            elif name in ("triangles", "polygons", "trifans", "tristrips"):
                total += int(primitive.get("count") or 0)
        return total

    def node(element) -> int:
        key = id(element)
        if key not in totals:
            totals[key] = 0  # meanwhile: a node that instances itself adds nothing (the read refuses it)
            total = 0
            for child in element:
                name = _local(child.tag)
                target = by_id.get((child.get("url") or "").lstrip("#"))
                if name == "instance_controller" and target is not None:  # drawn as its skin's or morph's mesh
                    found = next((c for c in target if _local(c.tag) in ("skin", "morph")), None)
                    target = None if found is None else by_id.get((found.get("source") or "").lstrip("#"))
                    name = "instance_geometry"
                if name == "instance_geometry" and target is not None:
                    total += geometry(target)
                elif name == "instance_node" and target is not None:
                    total += node(target)
                elif name == "node":
                    total += node(child)
            totals[key] = total
        return totals[key]

    scenes = [by_id.get((e.get("url") or "").lstrip("#")) for e in root.iter()
              if _local(e.tag) == "instance_visual_scene"]
    scenes = [s for s in scenes if s is not None] or [e for e in root.iter() if _local(e.tag) == "visual_scene"]
    return sum(node(scene) for scene in scenes)


FORMAT = MeshFormat(names=("COLLADA",), suffixes=(".dae",), read=read, count=count, describe=describe,
                    texture_sizes=image_file_sizes,
                    # trimesh turns every effect (phong, blinn, lambert) into metallic-roughness; the note says so
                    pbr="COLLADA (phong, blinn and lambert effects, which trimesh reads as metallic-roughness: their "
                        "specular and ambient colours are not kept)")
