"""3MF (3D Manufacturing Format) read with its colours and textures: the core's meshes, components and build
items, and the Materials and Properties extension's base materials (`displaycolor`), colour groups, 2-D texture
groups and multiproperties, mapped onto the lecture's model (docs/meshes.md, "3MF").

trimesh's reader keeps only the geometry (every model grey) and refuses a document whose XML uses a namespace
prefix it never declares (two of the consortium's own three multiproperties samples: `ms:pbmetallic`). Here the
XML is read by lxml in recover mode, so such a prefix is kept as written (one note) while a document that is
not well-formed (cut short, bad syntax) is still refused in one line. Elements are matched by local name, so an
element in the wrong namespace (`<multi>` in the core's) is read too. lib3mf, the consortium's library, refuses
those files as well ("Could not get XML Namespace"), which is why it is not used.

Elements are cleared as they are read, so a document's tree is never held whole: the memory estimate's
ZIP_XML_READ_BYTES_PER_BYTE (below; measured on trimesh's reader) bounds this reader too.
"""

from __future__ import annotations

import io
import posixpath
import re
import zipfile
import zlib
from contextlib import suppress
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import FileProblem, SceneError
from ..encoding import srgb_encode
from ..files import open_regular
from ..textures import srgb_to_linear
from . import threemf_draft
from .format import Loaded, MeshFormat, Part, Reading
from .materials import FileMaterial, PartSurface, TextureSource, rgb
from .obj import UV_LIMIT

ROOT = "3D/3dmodel.model"  # the model part every producer writes (core §2.1); _rels/.rels may name another
MODEL_RELATION = "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"
MAX_DEPTH = 32      # components nested deeper than this are a cycle or a hostile file
TILE = {"wrap": "repeat", "mirror": "mirror", "clamp": "clamp", "none": "clamp"}  # m:texture2d tilestyleu/v
# What a base material or a triangle of a texture group without its own colour gets besides its colour: the
# .mtl defaults of a key it leaves out (k_s 0.5, f 32), no emission.
SPECULAR, SHININESS = (0.5, 0.5, 0.5), 32.0


@dataclass
class _Model:
    """One model part's resources, by id (ids are per part: a component's p:path names another part)."""
    name: str
    properties: dict = field(default_factory=dict)  # id → ("base", names, (n, 3)) | ("colour", (n, 3)) |
                                                    # ("uv", texture id, (n, 2)) | ("texture", member, s, t) |
                                                    # ("multi", pids, (n, k)) | ("other", tag)
    objects: dict = field(default_factory=dict)     # id → _Mesh | list of (part name, object id, (4, 4))
    build: list = field(default_factory=list)       # (part name, object id, (4, 4))


@dataclass
class _Mesh:
    vertices: np.ndarray      # (V, 3) float64
    faces: np.ndarray         # (F, 3) int64
    pid: np.ndarray           # (F,) int64 property group of each triangle, -1 for none
    p: np.ndarray             # (F, 3) int64 property index of each corner


def read_3mf(handle, path: Path, notes: list[str], sources: list[TextureSource]) -> list[tuple]:
    """The triangle meshes the 3MF at the open `handle` builds, placed: (vertices (V, 3) float64, faces (F, 3)
    int64, PartSurface) each, one per build instance and kind of surface. Colour maps are appended to `sources`
    (their materials index into it); what is not read is a note. SceneError, one line, for a file that is not
    a 3MF (not a zip, no model part, XML that is not well-formed, an index out of range)."""
    try:
        archive = zipfile.ZipFile(handle)
    except (zipfile.BadZipFile, ValueError, EOFError) as error:
        raise FileProblem(f"cannot read {str(path)!r} as 3MF: not a zip archive ({error})") from None
    try:
        with archive:
            return _read_archive(archive, path, notes, sources)
    except (RuntimeError, NotImplementedError, zipfile.BadZipFile, zlib.error, EOFError) as error:
        # zipfile's refusals of a member: encrypted, a compression method it lacks, a corrupt stream
        raise FileProblem(f"cannot read {str(path)!r} as 3MF: a part of its zip archive cannot be read "
                          f"({' '.join(str(error).split())[:160]}); allowed: a 3MF package whose parts are stored "
                          "or deflated, not encrypted") from None


def _read_archive(archive: zipfile.ZipFile, path: Path, notes: list[str], sources: list[TextureSource]) -> list:
    """read_3mf's model parts of the open archive, parsed and placed."""
    members, root = _root_part(archive)
    if root is None:
        raise FileProblem(f"cannot read {str(path)!r} as 3MF: it holds no model part ({ROOT}); allowed: a 3MF "
                          "package with a 3D model")
    models: dict[str, _Model] = {}
    _parse(archive, members, root, models, path, notes)
    # Components with a p:path name other parts (the Production extension): read each once.
    wanted = {part for model in list(models.values()) for kind in model.objects.values()
              if isinstance(kind, list) for part, _, _ in kind} | {part for part, _, _ in models[root].build}
    for part in sorted(wanted - set(models)):
        if part.lower() in members:
            _parse(archive, members, members[part.lower()], models, path, notes)
    return _placed(archive, members, models, root, path, notes, sources)


def _root_part(archive: zipfile.ZipFile) -> tuple[dict[str, str], str | None]:
    """The archive's members by their lower-case names, and its model part: the one _rels/.rels names (core
    §2.1), else 3D/3dmodel.model in any letter case (None: neither)."""
    members = {info.filename.lstrip("/").lower(): info.filename for info in archive.infolist()}
    rels = members.get("_rels/.rels")
    if rels is not None:
        from lxml import etree
        # a broken relationships part: fall back on the usual name
        with suppress(etree.XMLSyntaxError, ValueError, zipfile.BadZipFile, OSError, EOFError):
            # a file from anywhere: no entities, no network, no DTD (billion laughs, XXE)
            parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False)
            tree = etree.fromstring(archive.read(rels), parser)
            for relation in tree.iter("{*}Relationship"):
                target = relation.get("Target", "").lstrip("/").lower()
                if relation.get("Type") == MODEL_RELATION and target in members:
                    return members, members[target]
    return members, members.get(ROOT.lower())


def _local(tag) -> str:
    return tag.rsplit("}", 1)[-1].rsplit(":", 1)[-1] if isinstance(tag, str) else ""


BATCH = 8192  # vertices or triangles held as elements before they are dropped
YIELDED = ("vertex", "triangle", "object", "item", "basematerials", "colorgroup", "texture2d", "texture2dgroup",
           "multiproperties", "compositematerials", "beamlattice", "slicestack")
# The 3MF Consortium's extensions, told by a word of their namespace URI: those read (a triangle set only
# groups triangles), and what each other one adds, for the refusal of a file that requires it (core §2.3.1: a
# consumer must not read a file whose required extensions it does not support) or the note of one that uses it.
READ_EXTENSIONS = ("/core/", "/material/", "/production/", "/trianglesets/")
EXTENSIONS = {"/slice/": "Slice (the model as stacks of 2-D slices)", "/beamlattice/": "Beam Lattice (beams "
              "between vertices)", "/securecontent/": "Secure Content (encrypted parts)", "/volumetric/":
              "Volumetric", "/displacement/": "Displacement", "/implicit/": "Implicit", "/booleanoperations/":
              "Boolean Operations"}
MODEL_TAG = re.compile(r"<(?:[\w.-]+:)?model\b([^>]*)>")
ATTRIBUTE = re.compile(r"([\w.:-]+)\s*=\s*(?:\"([^\"]*)\"|'([^']*)')")


def _check_required(archive, part: str, path: Path) -> tuple[str, bool]:
    """Refuse a model part whose <model> requires an extension not read (naming it: core §2.3.1); returns its
    default namespace (the 2013/01 draft's is told apart) and whether it declares the Slice extension's."""
    with archive.open(part) as stream:
        head = stream.read(1 << 16).decode("utf-8", "replace")
    found = MODEL_TAG.search(head)
    if found is None:
        return "", False
    attributes = {match[1]: match[2] if match[2] is not None else match[3] for match in ATTRIBUTE.finditer(found[1])}
    missing = []
    for prefix in (attributes.get("requiredextensions") or "").split():
        uri = attributes.get(f"xmlns:{prefix}")
        if uri is None:
            missing.append(f"{prefix!r} (a prefix the model does not declare)")
        elif not any(word in uri for word in READ_EXTENSIONS):
            missing.append(next((name for word, name in EXTENSIONS.items() if word in uri), uri))
    if missing:
        raise FileProblem(f"{str(path)!r}: {part} requires the 3MF extension(s) {', '.join(missing)}, which this "
                          "renderer does not read; read: core, Materials and Properties, Production, Triangle "
                          "Sets")
    return attributes.get("xmlns", ""), any(SLICE in uri for uri in attributes.values())


def _parse(archive, members, part: str, models: dict, path: Path, notes: list[str]) -> None:
    """Read one model part's resources, objects and build into models[part]."""
    from lxml import etree
    namespace, slices = _check_required(archive, part, path)
    model = models[part] = _Model(part)
    draft = threemf_draft.Draft(path) if namespace == threemf_draft.NAMESPACE else None
    tags = [f"{{*}}{name}" for name in YIELDED]
    if draft is not None:  # the draft's colours, materials, textures and texture vertices (threemf_draft.py)
        tags += [f"{{{threemf_draft.NAMESPACE}}}{name}" for name in threemf_draft.TAGS]
    vertices: list = []
    triangles: list = []
    held = 0
    stream = archive.open(part)
    # Only the elements read yield (libxml2 filters the rest in C): every vertex and triangle is one Python step.
    context = etree.iterparse(stream, events=("end",), tag=tags, recover=True,
                              resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False)
    try:
        for _, element in context:
            name = element.tag.rsplit("}", 1)[-1]
            attrib = element.attrib
            if slices and name == "vertex" and SLICE in element.tag:  # a slice's 2-D vertex (x, y), not the mesh's
                continue
            if name == "vertex" or name == "triangle" or name == "texturevertex":
                if name == "vertex":
                    vertices.append((attrib.get("x"), attrib.get("y"), attrib.get("z")))
                elif name == "texturevertex":
                    draft.texture_vertex(attrib)  # yielded only for a draft part
                else:
                    triangles.append((attrib.get("v1"), attrib.get("v2"), attrib.get("v3"),
                                      *(draft.triangle(attrib) if draft is not None else
                                        (attrib.get("pid"), attrib.get("p1"), attrib.get("p2"), attrib.get("p3")))))
                held += 1
                if held == BATCH:  # drop the ones read in one step: per element, the deletes cost 2× the read
                    # Those before this one only: the parser may have read siblings ahead (not yet yielded), and
                    # one dropped with them would be read detached (no parent) at the next drop.
                    parent = element.getparent()
                    if parent is not None:
                        del parent[:parent.index(element)]
                    held = 0
                continue
            if name == "object":
                found = dict(attrib) if draft is None else draft.object_end(model.properties, dict(attrib), _numbers)
                _object(model, found, vertices, triangles, element, path)
                vertices, triangles = [], []
            elif name in ("beamlattice", "slicestack"):
                _unread_geometry(name, element, part, path, notes)
            elif draft is not None and name in threemf_draft.TAGS:
                draft.resource(model.properties, name, attrib, _colour)
            elif name == "item":
                model.build.append((_path_of(attrib, part), attrib.get("objectid"), _transform(attrib, path)))
            else:
                _resource(model, name, element, path, notes)
            element.clear()  # read: dropped with the siblings before it, so the tree is never held whole
            parent = element.getparent()
            while element.getprevious() is not None:
                del parent[0]
    except etree.XMLSyntaxError as error:
        raise FileProblem(f"cannot read {str(path)!r} as 3MF: {part} is not well-formed XML ({error})") \
            from None
    except (zipfile.BadZipFile, EOFError, OSError) as error:  # a member whose data is corrupt
        raise FileProblem(f"cannot read {str(path)!r} as 3MF: {part}: {error}") from None
    fatal = [entry for entry in context.error_log if entry.level >= 3]  # libxml2's FATAL: cut short, bad syntax
    if fatal:
        raise FileProblem(f"cannot read {str(path)!r} as 3MF: {part} is not well-formed XML ({fatal[0].message.strip()}"
                          f", line {fatal[0].line})")
    undeclared = [entry for entry in context.error_log if entry.domain_name == "NAMESPACE"]
    if undeclared:
        notes.append(f"{path}: {part} uses a namespace prefix it does not declare ({undeclared[0].message.strip()}, "
                     f"line {undeclared[0].line}); read as written")


SLICE = "/slice/"  # the Slice extension's namespace word: its <s:vertex> elements are 2-D


def _unread_geometry(name: str, element, part: str, path: Path, notes: list[str]) -> None:
    """A note for a beam lattice (its beams are not drawn) or a slice stack (its slices are not: the mesh is)."""
    if name == "beamlattice":
        beams = sum(1 for child in element.iter() if isinstance(child.tag, str) and _local(child.tag) == "beam")
        notes.append(f"{path}: {part} holds a beam lattice of {beams} beam(s) (the Beam Lattice extension), which is "
                     "not drawn: only its mesh's triangles are")
    else:
        notes.append(f"{path}: {part} holds a slice stack (the Slice extension), which is not read: its objects' "
                     "meshes are drawn")


def _path_of(attrib, part: str) -> str:
    """The model part a component or build item's p:path names (the Production extension), else its own."""
    return next((posixpath.normpath(value.lstrip("/")) for key, value in attrib.items() if _local(key) == "path"
                 and value), part)


def _transform(attrib, path: Path) -> np.ndarray:
    """(4, 4) of a `transform` attribute: 12 numbers, the 3 × 3 matrix by rows then the translation, for row
    vectors (core §3.4.1: p' = p · M), so the column-vector matrix is its transpose."""
    matrix = np.eye(4)
    text = attrib.get("transform")
    if text is None:
        return matrix
    values = np.zeros(0)  # a word that is not a number: refused as not 12 numbers
    with suppress(ValueError):
        values = np.array(text.split(), np.float64)
    if values.shape != (12,) or not np.isfinite(values).all():
        raise FileProblem(f"{str(path)!r}: transform {text[:80]!r} is not 12 finite numbers; allowed: "
                          "'m00 m01 m02 m10 m11 m12 m20 m21 m22 m30 m31 m32'")
    matrix[:3, :4] = values.reshape(4, 3).T
    return matrix


def _not_a_number(what: str, path: Path) -> FileProblem:
    return FileProblem(f"{str(path)!r}: a {what} that is not a number (or is missing); allowed: numbers as the 3MF "
                       "core specification writes them")


def _numbers(values, dtype, what: str, path: Path) -> np.ndarray:
    try:
        return np.array(values, dtype)
    except (TypeError, ValueError):
        raise _not_a_number(what, path) from None


def _column(words, dtype, what: str, path: Path, default: str | None = None) -> np.ndarray:
    """A flat array of attribute strings (None: `default`, else missing), parsed in one pass of numpy's text
    reader: a million tuples of strings through np.array took 3× trimesh's whole read."""
    if default is not None:
        if all(word is None for word in words):
            return np.full(len(words), int(default), dtype)
        words = [default if word is None else word for word in words]
    try:
        text = " ".join(words)
    except TypeError:  # a None: a required attribute is missing (np.array would make it a float NaN)
        raise _not_a_number(what, path) from None
    if dtype is np.float64 or ("." not in text and "e" not in text.lower()):
        try:
            values = np.fromstring(text, dtype=dtype, sep=" ") if text else np.zeros(0, dtype)
        except ValueError:  # numpy 2: a word that is not a number stops it; _numbers words it
            values = None
        if values is not None and len(values) == len(words):
            return values
    return _numbers(list(words), dtype, what, path)  # words its error


def _object(model: _Model, attrib: dict, vertices: list, triangles: list, element, path: Path) -> None:
    """An <object>: a mesh (its vertices and triangles, each triangle's property group and indices, the
    object's pid and pindex filling in) or components."""
    identity = attrib.get("id")
    components = [(_path_of(c.attrib, model.name), c.get("objectid"), _transform(c.attrib, path))
                  for c in element.iter() if isinstance(c.tag, str) and c.tag.endswith("component")]
    if components and not triangles:
        model.objects[identity] = components
        return
    points = _column([word for vertex in vertices for word in vertex], np.float64, "vertex coordinate",
                     path).reshape(-1, 3)
    columns = list(zip(*triangles)) or [()] * 7
    faces = _column([word for row in triangles for word in row[:3]], np.int64, "triangle's vertex index",
                    path).reshape(-1, 3)
    if faces.size and (faces.min() < 0 or faces.max() >= len(points)):
        raise FileProblem(f"{str(path)!r}: object {identity} has a triangle with a vertex index outside "
                          f"0..{len(points) - 1}; allowed: indices of the object's own vertices")
    pid = _column(list(columns[3]), np.int64, "property id", path, attrib.get("pid") or "-1")
    pindex = attrib.get("pindex") if attrib.get("pid") is not None else None
    first = _column(list(columns[4]), np.int64, "property index", path, pindex or "-1")
    first = np.where((first < 0) & (pid >= 0), 0, first)  # a group without an index: its first entry
    p = np.column_stack([first, _column(list(columns[5]), np.int64, "property index", path, "-1"),
                         _column(list(columns[6]), np.int64, "property index", path, "-1")])
    p[:, 1:] = np.where(p[:, 1:] < 0, first[:, None], p[:, 1:])  # p2, p3 default to p1 (materials §4.1)
    model.objects[identity] = _Mesh(points, faces, pid, p)


def _resource(model: _Model, name: str, element, path: Path, notes: list[str]) -> None:
    """A property resource of the Materials and Properties extension, kept by id."""
    identity = element.get("id")
    children = [child for child in element if isinstance(child.tag, str)]
    if name == "basematerials":
        bases = [child for child in children if _local(child.tag) == "base"]
        colours = np.array([_colour(b.get("displaycolor", "#FFFFFF"), path) for b in bases]).reshape(-1, 3)
        model.properties[identity] = ("base", [b.get("name") or f"base {identity}.{k}" for k, b in enumerate(bases)],
                                      colours)
    elif name == "colorgroup":
        colours = [_colour(child.get("color", "#FFFFFF"), path) for child in children
                   if _local(child.tag) == "color"]
        model.properties[identity] = ("colour", np.array(colours, np.float64).reshape(-1, 3))
    elif name == "texture2d":
        if element.get("filter") == "nearest":
            notes.append(f"{path}: texture2d {identity} asks for the nearest filter; textures are sampled bilinearly")
        model.properties[identity] = ("texture", posixpath.normpath((element.get("path") or "").lstrip("/")),
                                      TILE.get(element.get("tilestyleu", "wrap"), "repeat"),
                                      TILE.get(element.get("tilestylev", "wrap"), "repeat"))
    elif name == "texture2dgroup":
        uv = [(child.get("u"), child.get("v")) for child in children if _local(child.tag) == "tex2coord"]
        uv = _numbers(uv, np.float64, "tex2coord", path).reshape(-1, 2)
        if not (np.abs(uv) <= UV_LIMIT).all():  # kept as float32 per corner; NaN passes (the kernel reads 0)
            raise FileProblem(f"{str(path)!r}: texture2dgroup {identity} has a tex2coord beyond float32's range; "
                              f"allowed: -{UV_LIMIT:.4g} .. {UV_LIMIT:.4g}")
        # Materials §3.1: u runs right and v up from the texture's lower left corner, as the renderer's v does:
        # read as written (lib3mf's smiley box, ladybug and lettered cube stand upright only so).
        model.properties[identity] = ("uv", element.get("texid"), uv)
    elif name == "compositematerials":
        indices = _numbers((element.get("matindices") or "").split(), np.int64, "matindices", path)
        rows = [(child.get("values") or "").split() for child in children if _local(child.tag) == "composite"]
        values = np.zeros((len(rows), len(indices)))  # a value not given is 0; extra ones are ignored (§4.1)
        for k, row in enumerate(rows):
            values[k, :min(len(row), len(indices))] = _numbers(row[:len(indices)], np.float64, "composite values",
                                                                path)
        if not (np.isfinite(values) & (values >= 0) & (values <= 1)).all():
            raise FileProblem(f"{str(path)!r}: compositematerials {identity} has a composite value outside 0..1; "
                              "allowed: fractions 0 to 1 (materials §4.1)")
        model.properties[identity] = ("composite", element.get("matid"), indices, values)
    elif name == "multiproperties":
        layers = (element.get("pids") or "").split()
        rows = [(child.get("pindices") or "").split() for child in children if _local(child.tag) == "multi"]
        indices = np.zeros((len(rows), len(layers)), np.int64)  # a missing index is the layer's first entry
        for k, row in enumerate(rows):
            indices[k, :min(len(row), len(layers))] = _numbers(row[:len(layers)], np.int64, "pindices", path)
        model.properties[identity] = ("multi", layers, indices)
    else:
        model.properties[identity] = ("other", name)


def _colour(text: str, path: Path) -> tuple[float, float, float]:
    """An sRGB colour #RRGGBB or #RRGGBBAA (materials §2.1) as three values in [0, 1]; alpha is not read."""
    digits = text.strip().lstrip("#")
    try:
        if len(digits) not in (6, 8):
            raise ValueError
        return tuple(int(digits[k:k + 2], 16) / 255.0 for k in (0, 2, 4))  # type: ignore[return-value]
    except ValueError:
        raise FileProblem(f"{str(path)!r}: colour {text[:40]!r} is not #RRGGBB or #RRGGBBAA; allowed: hexadecimal "
                          "sRGB as the 3MF materials extension writes it") from None


# ---------------------------------------------------------------- the build, placed and coloured

def _placed(archive, members, models: dict, root: str, path: Path, notes: list[str],
            sources: list[TextureSource]) -> list[tuple]:
    """Every build item's meshes (through its components), placed, split by what colours them."""
    textures: dict[tuple, int] = {}     # (part, texture id) → index into sources
    materials: dict[tuple, FileMaterial] = {}
    parts: list[tuple] = []
    skipped: set[str] = set()

    def visit(part: str, identity: str, transform: np.ndarray, depth: int) -> None:
        model = models.get(part)
        found = model.objects.get(identity) if model is not None else None
        if found is None:
            raise FileProblem(f"{str(path)!r}: the build names object {identity} of {part}, which it does not "
                              "define; allowed: the id of an <object> of that part")
        if depth > MAX_DEPTH:
            raise FileProblem(f"{str(path)!r}: components nest deeper than {MAX_DEPTH} (a component that contains "
                              "itself?); allowed: a tree of components")
        if isinstance(found, list):
            for child_part, child, local in found:
                visit(child_part, child, transform @ local, depth + 1)
            return
        with np.errstate(invalid="ignore", over="ignore"):  # an infinite vertex: read.py's values check words it
            vertices = found.vertices @ transform[:3, :3].T + transform[:3, 3]
            kept = not np.linalg.det(transform[:3, :3]) < 0  # a mirror turns the faces over, to keep them outward
        faces = found.faces if kept else found.faces[:, ::-1]
        p = found.p if kept else found.p[:, ::-1]
        for pid in np.unique(found.pid).tolist():
            chosen = found.pid == pid
            parts.extend(_surfaces(model, str(pid), vertices, faces[chosen], p[chosen], path, textures,
                                   materials, sources, skipped, archive, members))

    for part, identity, transform in models[root].build:
        visit(part, identity, transform, 0)
    if skipped:
        notes.append(f"{path}: not read: {'; '.join(sorted(skipped))}")
    return parts


def _surfaces(model: _Model, pid: str, vertices, faces, p, path: Path, textures: dict,
              materials: dict, sources: list, skipped: set, archive, members) -> list[tuple]:
    """The parts of one mesh's triangles of property group `pid` ("-1": none): (vertices, faces, PartSurface)."""
    if pid == "-1":
        return [(vertices, faces, PartSurface())]
    found = model.properties.get(pid)
    if found is None:
        raise FileProblem(f"{str(path)!r}: a triangle names property group {pid}, which {model.name} does not "
                          "define; allowed: the id of a basematerials, colorgroup, texture2dgroup or multiproperties")
    kind = found[0]
    if kind == "base":  # one material per base, the whole triangle its p1's (materials §4.1)
        out = []
        for index in np.unique(p[:, 0]).tolist():
            _check_index(index, len(found[2]), pid, path)
            chosen = p[:, 0] == index
            out.append((vertices, faces[chosen], PartSurface(material=_base(found, index, pid, model, materials))))
        return out
    if kind in ("colour", "composite"):
        table = _colours(model, found, pid, path)
        _check_index(p, len(table), pid, path)
        return [(vertices, faces, PartSurface(corner_colour=table[p].astype(np.float32)))]
    if kind == "uv":
        _check_index(p, len(found[2]), pid, path)
        material = _textured(model, found[1], path, textures, materials, sources, skipped, archive, members)
        return [(vertices, faces, PartSurface(material=material, corner_uv=found[2][p].astype(np.float32)))]
    if kind == "multi":
        return [_multi(model, found, pid, vertices, faces, p, path, textures, materials, sources, skipped,
                       archive, members)]
    # a texture2d (kind "texture", found[1] its image's path) is no property group (materials §3.1: a
    # texture2dgroup's texid names it): its triangles are drawn in the default material
    skipped.add(f"{'texture2d' if kind == 'texture' else found[1]} resources named as a triangle's property group "
                "(their triangles use the default material)")
    return [(vertices, faces, PartSurface())]


def _colours(model: _Model, found: tuple, pid: str, path: Path) -> np.ndarray:
    """(N, 3) sRGB colours of a property group that colours: a colorgroup's colours, a basematerials group's
    displaycolors, or a compositematerials group's mixtures of its base group's displaycolors (materials §4: in
    the composite's proportions, each row divided by its sum, equal shares where it is 0; mixed in linear RGB, as
    §5 says blending is done, so 50 % red and 50 % blue is (0.735, 0, 0.735), not (0.5, 0, 0.5))."""
    if found[0] == "colour":
        return found[1]
    if found[0] == "base":
        return found[2]
    base = model.properties.get(found[1])
    if base is None or base[0] != "base":
        raise FileProblem(f"{str(path)!r}: compositematerials {pid} names matid {found[1]}, which is not a "
                          "basematerials group; allowed: the id of a <basematerials> (materials §4)")
    indices, count = found[2], len(base[2])
    if not indices.size or indices.min() < 0 or indices.max() >= count:
        raise FileProblem(f"{str(path)!r}: compositematerials {pid} has matindices "
                          f"{' '.join(str(k) for k in indices.tolist())[:60]!r}; allowed: one or more indices of "
                          f"basematerials {found[1]}'s bases, 0..{count - 1} (materials §4)")
    total = found[3].sum(axis=1, keepdims=True)
    shares = np.where(total > 0, found[3] / np.where(total > 0, total, 1), 1 / max(found[3].shape[1], 1))
    return srgb_encode(shares @ srgb_to_linear(base[2][found[2]]))


def _check_index(index, count: int, pid: str, path: Path) -> None:
    """Refuse property indices outside group `pid`'s 0..count - 1, naming the lowest if it is negative, else the
    highest."""
    index = np.asarray(index)
    if index.size and (index.min() < 0 or index.max() >= count):
        bad = int(index.min()) if index.min() < 0 else int(index.max())
        raise FileProblem(f"{str(path)!r}: a triangle's property index {bad} is outside property group "
                          f"{pid}'s 0..{count - 1}; allowed: an index of the group's entries")


def _base(found, index: int, pid: str, model: _Model, materials: dict) -> FileMaterial:
    """The file material of base `index` of basematerials `pid`: its displaycolor as k_a and k_d."""
    key = (model.name, pid, index)
    if key not in materials:
        colour = rgb(found[2][index])
        materials[key] = FileMaterial(found[1][index], colour, colour, SPECULAR, (0.0, 0.0, 0.0), SHININESS)
    return materials[key]


def _textured(model: _Model, texture: str, path: Path, textures: dict, materials: dict, sources: list,
              skipped: set, archive, members) -> FileMaterial | None:
    """The white material whose k_d map is texture2d `texture` (its image a PIL image of the zip member,
    decoded only if used); None (one note) when the texture or its image is missing."""
    key = (model.name, texture)
    if key in materials:
        return materials[key]
    found = model.properties.get(texture)
    member = members.get(found[1].lower()) if found is not None and found[0] == "texture" else None
    material = None
    if member is not None:
        from PIL import Image
        try:
            image = Image.open(io.BytesIO(archive.read(member)))  # lazy: decoded by io.textures if a face uses it
        except Exception:  # noqa: BLE001 - not an image PIL reads
            image = None
        if image is not None:
            textures[key] = len(sources)
            sources.append(TextureSource(image, found[2], found[3], f"{path.name}:{member}"))
            white = (1.0, 1.0, 1.0)
            material = FileMaterial(f"texture {posixpath.basename(member)}", white, white, SPECULAR, (0.0, 0.0, 0.0),
                                    SHININESS, kd_map=textures[key])
    if material is None:
        name = found[1] if found is not None and found[0] == "texture" else f"texture2d {texture}"
        skipped.add(f"{name!r}, missing or not an image (its triangles use the default material)")
    materials[key] = material
    return material


def _multi(model: _Model, found, pid: str, vertices, faces, p, path: Path, textures: dict,
           materials: dict, sources: list, skipped: set, archive, members) -> tuple:
    """Triangles of a multiproperties group: the colour layers (base materials' displaycolor, colour groups)
    multiplied per corner, and the first texture layer's coordinates and map; other layers not read."""
    layers, indices = found[1], found[2]
    _check_index(p, len(indices), pid, path)
    entry = indices[p]                                  # (F, 3, layers)
    colour = None
    material = uv = None
    for k, layer in enumerate(layers):
        resource = model.properties.get(layer)
        kind = resource[0] if resource is not None else None
        if kind in ("base", "colour", "composite"):
            table = _colours(model, resource, layer, path)
            _check_index(entry[:, :, k], len(table), layer, path)
            colour = table[entry[:, :, k]] if colour is None else colour * table[entry[:, :, k]]
        elif kind == "uv" and uv is None:
            _check_index(entry[:, :, k], len(resource[2]), layer, path)
            textured = _textured(model, resource[1], path, textures, materials, sources, skipped, archive, members)
            if textured is not None and _has_alpha(sources[textured.kd_map].source):
                skipped.add("multiproperties' texture layers with an alpha channel (a map here multiplies its "
                            "colour; mixing layers by alpha is not modelled)")
                continue
            uv, material = resource[2][entry[:, :, k]].astype(np.float32), textured
        elif kind == "uv":
            skipped.add("multiproperties' texture layers after the first")
        else:
            named = {"texture": "texture2d", "multi": "multiproperties"}.get(kind, "undefined")
            skipped.add(f"multiproperties' {resource[1] if kind == 'other' else named} layers")
    return (vertices, faces, PartSurface(material=material, corner_uv=uv if material is not None else None,
                                         corner_colour=None if colour is None else colour.astype(np.float32)))


def _has_alpha(image) -> bool:
    """Whether a PIL image (header read, not decoded) has an alpha channel or a transparent colour."""
    return "A" in image.mode or "transparency" in image.info


def texture_sizes(mesh) -> tuple[tuple[int, int], ...]:
    """(height, width) of each image in the 3MF's zip (its textures), from the image headers, for the memory
    estimate; () when it cannot be read (the read words it)."""
    from PIL import Image
    path = mesh.path
    sizes = []
    try:
        with open_regular(path, str(path), "mesh file") as handle, zipfile.ZipFile(handle) as archive:
            for info in archive.infolist():
                name = info.filename.lower()
                # an image by its suffix, or any member of a texture folder (the 0.93 samples' "0000.texture")
                if (name.endswith((".png", ".jpg", ".jpeg")) or "/texture/" in name) and "thumbnail" not in name:
                    with suppress(Exception):  # not an image: the read notes it
                        with archive.open(info) as member, Image.open(member) as image:
                            sizes.append((image.height, image.width))
    except (OSError, SceneError, zipfile.BadZipFile, ValueError, EOFError):
        return ()
    return tuple(sizes)


def read(reading: Reading) -> Loaded:
    own = read_3mf(reading.handle, reading.path, reading.notes, reading.textures)
    return Loaded([Part(vertices, faces, None, surface) for vertices, faces, surface in own])


# A 3MF's XML, parsed into a tree and lists: a 178 kB 3MF of 56.5 MB XML (500k triangles) peaked 1.95 GB
# resident, 34.5 bytes a byte of XML.
ZIP_XML_READ_BYTES_PER_BYTE = 36


OBJECT = re.compile(rb"<(?:[\w.-]+:)?object\b([^>]*)>")
COMPONENT = re.compile(rb"<(?:[\w.-]+:)?(?:component|item)\b([^>]*)>")
SCANNED_ATTRIBUTE = re.compile(rb"([\w.:-]+)\s*=\s*(?:\"([^\"]*)\"|'([^']*)')")


def count(handle, size: int, mesh) -> int | None:
    """The triangles the 3MF builds: each object's <triangle> elements times the times the build places it,
    through its components (10 components each, 8 levels deep, make a 2 kB file of 10^8 boxes: this count is
    what the memory check weighs, before any is read). A scan of the model parts' bytes, not an XML parse;
    None for a file that is not a 3MF package (the read words it)."""
    try:
        with zipfile.ZipFile(handle) as archive:
            return _built_triangles(archive)
    except (zipfile.BadZipFile, ValueError, EOFError, RuntimeError, NotImplementedError, zlib.error):
        return None  # not a zip, or a part zipfile cannot read (encrypted): the read words it


def _built_triangles(archive: zipfile.ZipFile) -> int | None:
    """count's sum over the build of the archive's root part."""
    members, root = _root_part(archive)
    if root is None:
        return None
    parts: dict[str, dict] = {}  # part → object id → its triangles, or its components [(part, id)]

    def objects(part: str) -> dict:
        if part not in parts:
            name = members.get(part.lower())
            parts[part] = {} if name is None else _scanned_objects(archive.read(name), part)
        return parts[part]

    totals: dict[tuple[str, str], int] = {}

    def placed(part: str, identity: str, depth: int) -> int:
        key = (part, identity)
        if key not in totals:
            totals[key] = 0  # meanwhile: a component that contains itself adds nothing (the read refuses it)
            found = objects(part).get(identity, 0)
            totals[key] = 0 if depth > MAX_DEPTH else found if isinstance(found, int) else \
                sum(placed(child_part, child, depth + 1) for child_part, child in found)
        return totals[key]

    return sum(placed(part, identity, 0) for part, identity in objects(root).get(None, []))


def _scanned_objects(data: bytes, part: str) -> dict:
    """Object id → its triangles (a mesh) or its components [(part, object id)]; None → the build's items."""
    found: dict = {}
    starts = [(match.start(), _attributes(match[1])) for match in OBJECT.finditer(data)]
    for k, (start, attributes) in enumerate(starts):
        end = starts[k + 1][0] if k + 1 < len(starts) else len(data)
        build = data.find(b"build", start, end)
        end = build if build >= 0 else end
        components = [_target(match[1], part) for match in COMPONENT.finditer(data, start, end)]
        triangles = (data.count(b"<triangle", start, end) + data.count(b":triangle", start, end)
                     - data.count(b"<triangles", start, end) - data.count(b":triangles", start, end))
        found[attributes.get("id")] = components or triangles
    build = max(data.rfind(b"<build"), data.rfind(b":build"))
    found[None] = [_target(match[1], part) for match in COMPONENT.finditer(data, build)] if build >= 0 else []
    return found


def _attributes(text: bytes) -> dict[str, str]:
    return {key.decode("latin-1").rpartition(":")[2] if key.endswith(b"path") else key.decode("latin-1"):
            (double if double is not None else single).decode("latin-1") for key, double, single in
            ((m[1], m[2], m[3]) for m in SCANNED_ATTRIBUTE.finditer(text))}


def _target(text: bytes, part: str) -> tuple[str, str]:
    """(part, object id) a component or build item names (its p:path, else its own part)."""
    attributes = _attributes(text)
    path = attributes.get("path")
    return (posixpath.normpath(path.lstrip("/")) if path else part), attributes.get("objectid")


def _unzipped(path: Path) -> int:
    """The sum of the sizes a zip's directory gives its members, uncompressed. Python's zipfile (read_3mf uses
    it) stops a member at its stated size (a longer stream fails its check), so the sum bounds what a
    read decompresses. 0 for a file that is not a zip (the read reports it)."""
    try:
        with open_regular(path, str(path), "mesh file") as handle, zipfile.ZipFile(handle) as archive:
            return sum(info.file_size for info in archive.infolist())
    except (OSError, SceneError, zipfile.BadZipFile, ValueError, EOFError):
        return 0


FORMAT = MeshFormat(
    names=("3MF",), suffixes=(".3mf",), read=read, count=count, texture_sizes=texture_sizes,
    floor=lambda path, size, source: size + _unzipped(path) * ZIP_XML_READ_BYTES_PER_BYTE,
    held=lambda path, source: (0, _unzipped(path)),  # an 800 MB XML zips to 2 MB
    content=lambda head, found, size, suffix: found == "a zip archive",
    up=(0.0, 0.0, 1.0))  # 3MF core §3.4: +Z up
