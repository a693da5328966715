"""A glTF of float triangle primitives placed by nodes, with materials, texture coordinates and images, is read by
numpy views of its buffers (io/meshes/gltf_parts.py), without trimesh, into the very MeshFile trimesh's reader
gave; what it leaves (vertex colours, strips, cameras, ...) still goes to trimesh. The files are written here from
the glTF 2.0 specification (a GLB's JSON and BIN chunks, §4.4)."""

from __future__ import annotations

import base64
import json
import struct
from pathlib import Path

import numpy as np
import pytest
from test_obj_plain import assert_same_mesh_file

from raycast_phong.errors import SceneError
from raycast_phong.io.meshes import gltf_parts, trimesh_parts
from raycast_phong.io.meshes import read as mesh_file
from raycast_phong.io.meshes.source import mesh_source

pytestmark = pytest.mark.usefixtures("in_tmp_path")

RNG = np.random.default_rng(11)
POINTS = RNG.normal(size=(9, 3)).astype(np.float32)
NORMALS = (POINTS / np.linalg.norm(POINTS, axis=1, keepdims=True)).astype(np.float32)
FACES = np.array([[0, 1, 2], [2, 3, 4], [4, 5, 6], [6, 7, 8], [8, 0, 4]])


def document(index_type: int = 5125, normals: bool = True, interleaved: bool = False, **changes) -> tuple[dict, bytes]:
    """A glTF document of one node, one mesh, one primitive, and its binary buffer."""
    index_dtype = {5121: "<u1", 5123: "<u2", 5125: "<u4"}[index_type]
    indices = FACES.astype(index_dtype).tobytes()
    indices += bytes(-len(indices) % 4)
    if interleaved:
        vertex_bytes = np.hstack([POINTS, NORMALS]).astype("<f4").tobytes()
        views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(indices)},
                 {"buffer": 0, "byteOffset": len(indices), "byteLength": len(vertex_bytes), "byteStride": 24}]
        accessors = [{"bufferView": 1, "componentType": 5126, "type": "VEC3", "count": len(POINTS)},
                     {"bufferView": 1, "byteOffset": 12, "componentType": 5126, "type": "VEC3", "count": len(POINTS)}]
    else:
        vertex_bytes = POINTS.astype("<f4").tobytes() + NORMALS.astype("<f4").tobytes()
        views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(indices)},
                 {"buffer": 0, "byteOffset": len(indices), "byteLength": POINTS.nbytes},
                 {"buffer": 0, "byteOffset": len(indices) + POINTS.nbytes, "byteLength": NORMALS.nbytes}]
        accessors = [{"bufferView": 1, "componentType": 5126, "type": "VEC3", "count": len(POINTS)},
                     {"bufferView": 2, "componentType": 5126, "type": "VEC3", "count": len(POINTS)}]
    accessors[0] |= {"min": POINTS.min(axis=0).tolist(), "max": POINTS.max(axis=0).tolist()}
    accessors.append({"bufferView": 0, "componentType": index_type, "type": "SCALAR", "count": FACES.size})
    attributes = {"POSITION": 0, "NORMAL": 1} if normals else {"POSITION": 0}
    data = indices + vertex_bytes
    tree = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
            "nodes": [{"children": [1]}, {"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": attributes, "indices": 2, "mode": 4}]}],
            "accessors": accessors, "bufferViews": views, "buffers": [{"byteLength": len(data)}]}
    for key, value in changes.items():
        tree[key] = value(tree) if callable(value) else value
    return tree, data


def write_glb(path: Path, tree: dict, data: bytes) -> Path:
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    data += bytes(-len(data) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(data), 0x004E4942) + data
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(chunks)) + chunks)
    return path


def write_gltf(path: Path, tree: dict, data: bytes) -> Path:
    tree["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    path.write_text(json.dumps(tree))
    return path


def nested(key: str, value):
    """A change of one node's, mesh's or primitive's key (a path of keys and indices) to `value`."""
    def change(tree: dict):
        *parents, last = key
        at = tree
        for part in parents:
            at = at[part]
        at[last] = value
        return tree[key[0]]
    return change


def png_uri(colour: tuple[int, int, int]) -> str:
    """A 2 × 2 PNG of one colour as a data: URI."""
    import io

    from PIL import Image
    out = io.BytesIO()
    Image.new("RGB", (2, 2), colour).save(out, format="PNG")
    return "data:image/png;base64," + base64.b64encode(out.getvalue()).decode()


def with_uv(tree: dict) -> list:
    """TEXCOORD_0: the positions' first floats read as (u, v) pairs, a VEC2 accessor on their bufferView."""
    tree["accessors"].append({"bufferView": 1, "componentType": 5126, "type": "VEC2", "count": len(POINTS)})
    primitive = tree["meshes"][0]["primitives"][0]
    primitive["attributes"]["TEXCOORD_0"], primitive["material"] = len(tree["accessors"]) - 1, 0
    return tree["meshes"]


TEXTURED = {"meshes": with_uv,
            "materials": [{"name": "wood", "pbrMetallicRoughness": {
                "baseColorFactor": [0.8, 0.5, 0.2, 1], "metallicFactor": 0.1, "roughnessFactor": 0.7,
                "baseColorTexture": {"index": 0}}, "emissiveFactor": [0.1, 0, 0]}],
            "textures": [{"source": 0}], "images": [{"uri": png_uri((200, 120, 40))}]}
READ_HERE = {
    "uint32 indices": {},
    "uint16 indices": {"index_type": 5123},
    "uint8 indices": {"index_type": 5121},
    "no normals": {"normals": False},
    "interleaved": {"interleaved": True},
    "a material": {"meshes": nested(("meshes", 0, "primitives", 0, "material"), 0),
                   "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1]}}]},
    "a textured material": TEXTURED,
    "a translation": {"nodes": nested(("nodes", 0, "translation"), [1.0, 2.0, 3.0])},
    "a rotation on the mesh's node": {"nodes": nested(("nodes", 1, "rotation"), [0.0, 0.0, 0.6, 0.8])},
    # |q|² exactly 4 ε (2⁻⁵⁰), the least trimesh normalises (below it, no rotation): a half turn about x.
    "a rotation of the least length normalised": {"nodes": nested(("nodes", 1, "rotation"), [2.0 ** -25, 0, 0, 0])},
    "T, R and S under a matrix": {"nodes": [{"children": [1], "matrix": [2, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1, 2, 3,
                                                                          1]},
                                            {"mesh": 0, "translation": [0.5, 0, 0], "rotation": [0.6, 0, 0, 0.8],
                                             "scale": [1, -2, 1]}]},
    "two nodes place it": {"nodes": [{"children": [1, 2]}, {"mesh": 0}, {"mesh": 0, "translation": [3, 0, 0]}]},
    "two roots": {"nodes": [{"mesh": 0}, {"mesh": 0, "scale": [2, 2, 2]}], "scenes": [{"nodes": [1, 0]}]},
    "no indices": {"meshes": nested(("meshes", 0, "primitives", 0), {"attributes": {"POSITION": 0}})},
    # COLOR_0: the normals' floats, of either sign (clipped), as colours; 8 bits without a material, as trimesh
    "vertex colours": {"meshes": nested(("meshes", 0, "primitives", 0, "attributes", "COLOR_0"), 1)},
    "vertex colours beside a material": {"meshes": lambda tree: (nested(("meshes", 0, "primitives", 0, "attributes",
                                                                        "COLOR_0"), 1)(tree),
                                                                 nested(("meshes", 0, "primitives", 0, "material"),
                                                                        0)(tree))[1],
                                         "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1]}}]},
    # A camera on a node of its own (as Blender exports one): it places no triangle, and the file needs no trimesh
    # (whose import was 0.47 s of Duck.glb's 1.07 s process).
    "a camera beside the mesh": {"nodes": [{"children": [1]}, {"mesh": 0}, {"camera": 0, "translation": [0, 0, 5]}],
                                 "scenes": [{"nodes": [0, 2]}],
                                 "cameras": [{"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.1}}]},
    # The scene lists its root twice: trimesh's graph has one edge to it, so the mesh is placed once.
    "a root listed twice": {"scenes": [{"nodes": [0, 0]}]},
    # A quaternion of length 0 (below 4 ε) is no rotation, as trimesh reads it.
    "a zero rotation": {"nodes": nested(("nodes", 1, "rotation"), [0.0, 0.0, 0.0, 0.0])},
    # COLOR_0 of 8 values for 9 vertices: not one a vertex, so no colours (as trimesh drops them).
    "vertex colours of another count": {
        "meshes": nested(("meshes", 0, "primitives", 0, "attributes", "COLOR_0"), 3),
        "accessors": lambda tree: [*tree["accessors"], {"bufferView": 1, "componentType": 5126, "type": "VEC3",
                                                        "count": len(POINTS) - 1}]},
}
TRIMESH_READS = {
    "texture coordinates of three values": {"meshes": nested(("meshes", 0, "primitives", 0, "attributes",
                                                               "TEXCOORD_0"), 0)},
    "a triangle strip": {"meshes": nested(("meshes", 0, "primitives", 0, "mode"), 5)},
    "a texture's source in an extension": {**TEXTURED, "textures": [{"extensions": {"EXT_texture_webp": {
        "source": 0}}}]},
    # glTF 2.0 §3.5.3: a node has one parent at most; trimesh's graph keeps one of two.
    "a node under two parents": {"nodes": [{"children": [2]}, {"children": [2]}, {"mesh": 0}],
                                 "scenes": [{"nodes": [0, 1]}]},
    # trimesh converts specular-glossiness itself (a file that uses it without listing it in extensionsUsed)
    "a specular-glossiness material": {"materials": [{"extensions": {"KHR_materials_pbrSpecularGlossiness": {
        "diffuseFactor": [1, 0, 0, 1]}}}]},
    "a metallic factor that is not a number": {"materials": [{"pbrMetallicRoughness": {"metallicFactor": "0.5"}}]},
    "a base colour of three values": {"materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0]}}]},
    "a negative emissive factor": {"materials": [{"emissiveFactor": [0.5, -0.1, 0]}]},
    "an alpha mode glTF does not define": {"materials": [{"alphaMode": "CUTOUT"}]},
    "an image of neither a bufferView nor a URI": {**TEXTURED, "images": [{"uri": png_uri((1, 2, 3))},
                                                                          {"mimeType": "image/png"}]},
}


def no_trimesh(*arguments, **keywords):
    raise AssertionError("a glTF this package reads went to trimesh")


def read(path: Path, here: bool, monkeypatch) -> mesh_file.MeshFile:
    with monkeypatch.context() as patch:
        if not here:
            patch.setattr(gltf_parts, "gltf_parts", lambda *arguments: None)
        return mesh_file.read_file(mesh_source(path), bounds=True)


@pytest.mark.parametrize("container", ["glb", "gltf"])
@pytest.mark.parametrize("case", READ_HERE)
def test_a_gltf_reads_without_trimesh_as_trimesh_read_it(case, container, tmp_path, monkeypatch):
    """Bit for bit: vertices placed by the same products (a node's matrix, then T, R, S; a parent's before a
    child's), faces turned where a node mirrors, normals, v-up coordinates, materials and their images."""
    tree, data = document(**READ_HERE[case])
    path = (write_glb if container == "glb" else write_gltf)(tmp_path / f"here.{container}", tree, data)
    with monkeypatch.context() as patch:
        patch.setattr(trimesh_parts, "load", no_trimesh)
        here = mesh_file.read_file(mesh_source(path), bounds=True)
    assert_same_mesh_file(here, read(path, False, monkeypatch))
    if case in ("uint32 indices", "no normals"):
        np.testing.assert_array_equal(here.faces, FACES)
        np.testing.assert_array_equal(here.vertices, POINTS.astype(np.float64))
    if case == "a textured material":
        (material,) = here.materials
        assert material.name == "wood" and material.kd == (204 / 255, 128 / 255, 51 / 255)  # 8 bits, as trimesh
        assert here.texture_sources[material.kd_map].source.size == (2, 2)
        np.testing.assert_array_equal(here.corner_uv[:, :, 1], (1 - POINTS.reshape(-1)[:18].reshape(9, 2)[:, 1])[
            FACES].astype(np.float32))  # v up: 1 - v


@pytest.mark.parametrize("case", TRIMESH_READS)
def test_what_it_does_not_read_is_left_to_trimesh(case, tmp_path):
    tree, data = document(**TRIMESH_READS[case])
    assert gltf_parts.gltf_parts(tree, [data], tmp_path / "x.glb") is None


def test_a_mesh_under_a_camera_node_is_placed_by_it(tmp_path):
    """A node may hold a camera and children (glTF 2.0 §3.5: any node is a transform). trimesh's reader leaves a
    camera node out of its graph, so the mesh below it was lost and the file refused ('does not follow the GLB
    format'); read here, it is placed by the camera node's transform."""
    tree, data = document(nodes=[{"children": [1], "camera": 0, "translation": [0.0, 0.0, 5.0]}, {"mesh": 0}],
                          cameras=[{"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.1}}])
    found = mesh_file.read_file(mesh_source(write_glb(tmp_path / "rig.glb", tree, data)))
    np.testing.assert_array_equal(found.faces, FACES)
    np.testing.assert_array_equal(found.vertices, POINTS.astype(np.float64) + np.array([0.0, 0.0, 5.0]))


def test_vertex_colours_not_one_a_vertex_are_none(tmp_path):
    """COLOR_0 holds one colour a vertex (glTF 2.0 §3.7.2.1: every attribute has the vertices' count): 8 colours
    for 9 vertices colour nothing, not the first 8 vertices. 9 of them are the vertices' colours."""
    for count, kept in ((len(POINTS) - 1, False), (len(POINTS), True)):
        colours = {"bufferView": 1, "componentType": 5126, "type": "VEC3", "count": count}
        tree, data = document(**{**READ_HERE["vertex colours of another count"],
                                 "accessors": lambda tree, colours=colours: [*tree["accessors"], colours]})
        [part] = gltf_parts.gltf_parts(tree, [data], tmp_path / "x.glb")
        assert (part.colours is not None) == kept


def test_an_index_equal_to_the_vertex_count_is_one_line(tmp_path):
    """glTF's indices are read as stored: one naming vertex V of V vertices is refused by the read's one check
    (read.py: the face and the allowed range), not an IndexError later."""
    tree, data = document()
    faces = FACES.copy()
    faces[1, 2] = len(POINTS)  # 9, of vertices 0..8
    data = faces.astype("<u4").tobytes() + data[FACES.size * 4:]
    path = write_glb(tmp_path / "over.glb", tree, data)
    with pytest.raises(SceneError, match=r"has 1 face\(s\) with a vertex index outside 0\.\.8 \(first: \[2, 3, 9\]\)"):
        mesh_file.read_file(mesh_source(path))


def test_a_gltf_json_over_the_parse_limit_is_left_unparsed(tmp_path, monkeypatch):
    """read_document parses at most JSON_LIMIT bytes of a .gltf: a document of exactly the limit parses, one a
    byte longer is left alone (an empty tree, no problem: trimesh reads it), never parsed cut at the limit
    (which would refuse a good file as JSON that does not parse). The limit is made 64 bytes here."""
    from raycast_phong.io.meshes import gltf_json
    monkeypatch.setattr(gltf_json, "JSON_LIMIT", 64)
    text = '{"asset": {"version": "2.0"}, "extras": "'
    fits = text + "x" * (64 - len(text) - 2) + '"}'
    assert len(fits) == 64
    path = tmp_path / "m.gltf"
    path.write_text(fits)
    assert gltf_json.read_document(path).tree["asset"] == {"version": "2.0"}
    path.write_text(fits[:-2] + 'x"}')
    assert gltf_json.read_document(path) == gltf_json.Document({}, None, None)



def test_a_glb_json_chunk_over_the_parse_limit_is_left_unparsed(tmp_path, monkeypatch):
    """The same limit on a .glb's JSON chunk, by the length its header gives: a chunk of exactly JSON_LIMIT bytes
    parses (its binary chunk found after it), one 4 bytes longer (a chunk is padded to 4) is left alone. The limit
    is made 64 bytes here."""
    from raycast_phong.io.meshes import gltf_json
    monkeypatch.setattr(gltf_json, "JSON_LIMIT", 64)
    text = '{"asset": {"version": "2.0"}, "extras": "'
    path = tmp_path / "m.glb"
    for length, parsed in ((64, True), (68, False)):
        chunk = (text + "x" * (length - len(text) - 2) + '"}').encode()
        assert len(chunk) == length
        chunks = struct.pack("<I", length) + b"JSON" + chunk + struct.pack("<I", 4) + b"BIN\0" + bytes(4)
        path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks)
        found = gltf_json.read_document(path)
        if parsed:
            assert found.tree["asset"] == {"version": "2.0"} and found.binary == (20 + 64 + 8, 4)
        else:
            assert found == gltf_json.Document({}, None, None)


def test_a_gltf_of_64_mib_and_a_byte_is_not_parsed(tmp_path):
    """The limit itself, unpatched: a .gltf one byte over 64 MiB (a sparse file of zeros, which would not parse) is
    left unparsed, no problem said, never read whole. Catches JSON_LIMIT moved (the size is written here)."""
    from raycast_phong.io.meshes import gltf_json
    path = tmp_path / "huge.gltf"
    with path.open("wb") as handle:
        handle.truncate((64 << 20) + 1)
    assert gltf_json.read_document(path) == gltf_json.Document({}, None, None)

def _glb_with_one_texture(png: bytes, view_length: int) -> bytes:
    """A .glb of one material whose base colour map is the PNG `png`, the binary chunk's only content (padded
    to 4 bytes), its bufferView `view_length` bytes long."""
    binary = png + b"\0" * (-len(png) % 4)
    tree = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": len(binary)}],
            "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": view_length}],
            "images": [{"bufferView": 0, "mimeType": "image/png"}], "textures": [{"source": 0}],
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]}
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<I", len(text)) + b"JSON" + text + struct.pack("<I", len(binary)) + b"BIN\0" + binary
    return b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks


def test_an_embedded_image_whose_view_runs_past_the_binary_chunk_counts_nothing(tmp_path):
    """texture_sizes reads an embedded image's header from its bufferView's bytes within the .glb's binary
    chunk: a 3×2 PNG whose view fits gives (2, 3); the same file with the view 4 bytes longer than the chunk
    names bytes the file does not hold for it and counts nothing (the read words the broken view)."""
    import io

    from PIL import Image

    from raycast_phong.io.meshes import gltf
    from raycast_phong.io.meshes.gltf_json import read_document
    buffer = io.BytesIO()
    Image.new("RGB", (3, 2)).save(buffer, "PNG")
    png = buffer.getvalue()
    path = tmp_path / "m.glb"
    path.write_bytes(_glb_with_one_texture(png, len(png)))
    assert gltf.texture_sizes(path, read_document(path), lambda file: None) == [(2, 3)]
    path.write_bytes(_glb_with_one_texture(png, len(png) + (-len(png) % 4) + 4))
    assert gltf.texture_sizes(path, read_document(path), lambda file: None) == []


def test_data_uris_are_no_files_beside_a_gltf_and_a_file_uri_is_one(tmp_path):
    """glTF 2.0 §3.9.3: a buffer or image URI is a data: URI (the bytes inside the JSON) or a file's. Only files
    are side files, images the budget weighs, inputs of a batch and maps that may be missing: a .gltf whose
    buffer and first image are data: URIs and whose second image is map.png names map.png and nothing else."""
    from PIL import Image
    Image.new("RGB", (2, 2)).save(tmp_path / "map.png")
    tree, data = document(**TEXTURED)
    tree["images"].append({"uri": "map.png"})
    source = mesh_source(write_gltf(tmp_path / "embedded.gltf", tree, data))
    assert (source.side_files, source.images, source.files_read) == ((), (tmp_path / "map.png",),
                                                                      (tmp_path / "map.png",))
    assert not [note for note in mesh_file.read_file(source).notes if "missing" in note]


def test_a_flattening_node_scale_keeps_the_faces_winding(tmp_path):
    """A node scale of (1, 1, 0): its determinant is exactly 0, not a mirror, so the faces keep their winding as
    written (only a negative determinant turns them over) and the stored normals are dropped. Catches the mirror
    test taken as `determinant <= 0`."""
    tree, data = document(nodes=nested(("nodes", 1, "scale"), [1.0, 1.0, 0.0]))
    found = mesh_source(write_gltf(tmp_path / "flat.gltf", tree, data)).read()
    np.testing.assert_array_equal(found.faces, FACES)
    np.testing.assert_array_equal(found.vertices[:, 2], 0.0)
    assert found.normals is None


@pytest.mark.filterwarnings("error")
def test_an_infinite_vertex_under_a_node_transform_is_one_line_and_no_numpy_warning(tmp_path):
    """A node that moves its mesh multiplies every vertex, an infinite one too (assimp's BoxWithInfinites.glb):
    numpy's "invalid value encountered in matmul" must not reach the user, only the read's check of the values."""
    tree, data = document(nodes=nested(("nodes", 1, "translation"), [1.0, 2.0, 3.0]))
    points = POINTS.copy()
    points[4] = [np.inf, -np.inf, np.nan]
    start = FACES.size * 4
    data = data[:start] + points.astype("<f4").tobytes() + data[start + POINTS.nbytes:]
    path = write_glb(tmp_path / "infinite.glb", tree, data)
    with pytest.raises(SceneError, match=r"has 1 vertex\(es\) with NaN or infinite coordinates"):
        mesh_file.read_file(mesh_source(path))


@pytest.mark.parametrize(("version", "refused"), [("1.0", True), ("3.0", True), ("2.0", False), ("2.1", False)])
def test_only_major_version_2_is_read(version, refused, tmp_path):
    """glTF 2.0 §5.2: a loader reads the major version it knows and any later minor one. A glTF 1.0 file (shader
    techniques, assimp's test/models/glTF) was refused as 'does not follow the glTF format'; it is named now."""
    tree, data = document(asset={"version": version})
    path = write_gltf(tmp_path / "versioned.gltf", tree, data)
    if refused:
        with pytest.raises(SceneError, match=rf"its asset.version is '{version}'.*allowed: glTF 2\.0"):
            mesh_file.read_file(mesh_source(path))
    else:
        assert len(mesh_file.read_file(mesh_source(path)).faces) == len(FACES)


def test_a_glb_of_container_version_1_is_named_as_gltf_1(tmp_path):
    """A GLB's header holds its container version (§4.4.2: 2); glTF 1.0's KHR_binary_glTF wrote 1."""
    tree, data = document()
    path = write_glb(tmp_path / "old.glb", tree, data)
    raw = bytearray(path.read_bytes())
    raw[4:8] = (1).to_bytes(4, "little")
    path.write_bytes(bytes(raw))
    with pytest.raises(SceneError, match=r"its GLB header gives version 1 \(glTF 1\.0.*allowed: glTF 2\.0"):
        mesh_file.read_file(mesh_source(path))


@pytest.mark.filterwarnings("error")
def test_a_node_scale_past_float_range_is_one_line_and_no_numpy_warning(tmp_path):
    """A node scale of 1e300 on every axis: the placement's determinant overflows (1e900) and the vertices leave
    float range; the read's values check words it, without numpy's "overflow encountered in det" first."""
    tree, data = document(nodes=nested(("nodes", 1, "scale"), [1e300, 1e300, 1e300]))
    with pytest.raises(SceneError, match=r"vertex\(es\) with (a coordinate beyond|NaN or infinite)"):
        mesh_file.read_file(mesh_source(write_gltf(tmp_path / "far.gltf", tree, data)))


def uv_set_document(texcoords: dict, transform_set: int | None = None) -> tuple[dict, bytes]:
    """One triangle with the base colour map 'map.png' drawn with set `texcoords['base']` (and an emissive map
    with `texcoords['emissive']` when given), two sets stored: TEXCOORD_0 all zeros, TEXCOORD_1 the corners."""
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4")
    sets = [np.zeros((3, 2), "<f4"), np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], "<f4")]
    indices = np.array([0, 1, 2, 0], "<u2").tobytes()
    data = points.tobytes() + sets[0].tobytes() + sets[1].tobytes() + indices
    base = {"index": 0, "texCoord": texcoords["base"]}
    if transform_set is not None:  # KHR_texture_transform's texCoord overrides the texture info's
        base["extensions"] = {"KHR_texture_transform": {"texCoord": transform_set}}
    material = {"name": "m", "pbrMetallicRoughness": {"baseColorTexture": base}}
    if "emissive" in texcoords:
        material |= {"emissiveTexture": {"index": 0, "texCoord": texcoords["emissive"]}, "emissiveFactor": [1, 1, 1]}
    tree = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1, "TEXCOORD_1": 2},
                                        "indices": 3, "material": 0}]}],
            "materials": [material], "textures": [{"source": 0}], "images": [{"uri": "map.png"}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                           "min": [0, 0, 0], "max": [1, 1, 0]},
                          {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"},
                          {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2"},
                          {"bufferView": 3, "componentType": 5123, "count": 3, "type": "SCALAR"}],
            "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                            {"buffer": 0, "byteOffset": 36, "byteLength": 24},
                            {"buffer": 0, "byteOffset": 60, "byteLength": 24},
                            {"buffer": 0, "byteOffset": 84, "byteLength": 6}],
            "buffers": [{"byteLength": len(data)}]}
    if transform_set is not None:
        tree["extensionsUsed"] = ["KHR_texture_transform"]
    return tree, data


@pytest.mark.parametrize("container", ["glb", "gltf"])
@pytest.mark.parametrize(("texcoords", "transform_set", "drawn"), [
    ({"base": 1}, None, 1), ({"base": 0}, None, 0), ({"base": 0}, 1, 1), ({"base": 1, "emissive": 0}, None, 1)])
def test_a_colour_map_is_drawn_with_the_texture_coordinate_set_it_names(tmp_path, container, texcoords,
                                                                          transform_set, drawn):
    """glTF 2.0 §5.22: a texture info's texCoord names the TEXCOORD_n set it maps with (KHR_texture_transform's
    own texCoord overrides it). Both readers used TEXCOORD_0 whatever it said (draco's testdata
    TexCoord0InvalidTexCoord1Valid.gltf drew 'Multiple UVs not supported in this viewer'). A material whose maps
    name two sets draws them with its base colour map's, and says so."""
    import raycast_phong as rp
    rp.write_image(tmp_path / "map.png", np.full((2, 2, 3), 0.5, np.float32))
    tree, data = uv_set_document(texcoords, transform_set)
    path = (write_glb if container == "glb" else write_gltf)(tmp_path / f"sets.{container}", tree, data)
    found = mesh_file.read_file(mesh_source(path))
    expected = [[0.0, 1.0], [1.0, 1.0], [0.0, 0.0]] if drawn else [[0.0, 1.0]] * 3  # v up: 1 − glTF's v
    np.testing.assert_array_equal(found.corner_uv[0], expected)
    moved = [note for note in found.notes if "emissiveTexture is drawn with its baseColorTexture's" in note]
    assert len(moved) == ("emissive" in texcoords)
