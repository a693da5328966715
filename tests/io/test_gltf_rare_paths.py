"""The rare paths of io/meshes/gltf_decode.py, each on a document written here after the glTF 2.0 specification and
its extensions (EXT_meshopt_compression, KHR_draco_mesh_compression, EXT_mesh_gpu_instancing, skins): the refusals,
each in its own words with the key it names and what is allowed, and the values decoded, computed by hand. A
coverage run found no test reaching these lines; each test here fails with a plausible bug planted on its line."""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from test_gltf_decode import MODELS, glb_document, skinned_quad, with_accessor, write_glb
from test_gltf_extensions import quad_gltf

from raycast_phong.errors import SceneError
from raycast_phong.io.meshes.gltf_decode import _Decoder, node_globals
from raycast_phong.io.meshes.source import read_mesh

MESHOPT_NAME = "EXT_meshopt_compression"


def decoder(tree: dict, *buffers: bytes) -> _Decoder:
    return _Decoder(tree, list(buffers), Path("t.glb"), [])


def refused(call, words: str) -> str:
    """The message of the SceneError `call()` raises, which must hold `words` and be one line."""
    with pytest.raises(SceneError) as caught:
        call()
    message = str(caught.value)
    assert words in message and "\n" not in message, message
    return message


# ------------------------------------------------------------ bufferViews and accessors


def test_a_buffer_view_the_file_lacks_or_one_without_its_byte_length_is_refused_naming_it():
    """bufferView.byteLength is required (glTF 2.0 §5.11); a view index past the list names no view. Each refused
    with the key that named it, not a KeyError or IndexError."""
    tree = {"bufferViews": [{"buffer": 0, "byteOffset": 0}]}
    found = decoder(tree, bytes(16))
    for index in (0, 3):
        refused(lambda index=index: found.view_bytes(index, "accessors[2]"),
                f"'t.glb': accessors[2]: names bufferView {index}, which is not a bufferView of the file with a "
                "buffer, a byteOffset and a byteLength")


@pytest.mark.parametrize(("offset", "length", "outside"), [(8, 8, False), (8, 9, True), (-4, 4, True)])
def test_a_buffer_view_reaching_past_its_buffer_is_refused(offset, length, outside):
    """glTF 2.0 §5.11: a bufferView's bytes lie within its buffer. Bytes 8..16 of a 16-byte buffer are its last
    eight; 8..17 run one byte past it and a negative byteOffset before it, both refused naming the bytes."""
    tree = {"bufferViews": [{"buffer": 0, "byteOffset": offset, "byteLength": length}]}
    data = bytes(range(16))
    if not outside:
        assert bytes(decoder(tree, data).view_bytes(0, "k")) == data[8:]
        return
    refused(lambda: decoder(tree, data).view_bytes(0, "k"),
            f"'t.glb': bufferViews[0]: bytes {offset}..{offset + length} lie outside its buffer 0 of 16 bytes; "
            "allowed: within the buffer")


def test_an_accessor_with_a_negative_count_is_refused():
    """accessor.count is at least 1 (glTF 2.0 §5.1); a negative one is refused naming it (this reader lets 0 be
    an empty accessor)."""
    tree = {"accessors": [{"componentType": 5126, "count": -1, "type": "VEC3"}]}
    refused(lambda: decoder(tree).read_accessor(0, "k"), "'t.glb': accessors[0].count: is -1; allowed: 0 or more")


@pytest.mark.parametrize(("offset", "overrun"), [(0, False), (4, True)])
def test_an_accessor_overrunning_its_buffer_view_is_refused(offset, overrun):
    """glTF 2.0 §3.6.2.4: byteOffset + stride × (count − 1) + element size ≤ the bufferView's byteLength. Three
    float VEC3 (12 bytes each) fill a 36-byte view exactly from byte 0; from byte 4 they end at 40."""
    values = np.arange(9, dtype="<f4")
    tree = {"bufferViews": [{"buffer": 0, "byteLength": 36}],
            "accessors": [{"bufferView": 0, "byteOffset": offset, "componentType": 5126, "count": 3, "type": "VEC3"}]}
    found = decoder(tree, values.tobytes() + bytes(4))
    if not overrun:
        np.testing.assert_array_equal(found.read_accessor(0, "k"), values.reshape(3, 3))
        return
    refused(lambda: found.read_accessor(0, "k"),
            "'t.glb': accessors[0]: its 3 element(s) of 12 bytes every 12 from byte 4 overrun its bufferView of 36 "
            "bytes; allowed: within the bufferView")


def sparse_tree(sparse: dict) -> tuple[dict, bytes]:
    """Three uint16 values 10, 20, 30 (view 0) with `sparse`; view 1 holds the index 2, view 2 the value 99."""
    data = np.array([10, 20, 30, 0, 2, 0, 99, 0], "<u2").tobytes()
    tree = {"bufferViews": [{"buffer": 0, "byteLength": 6}, {"buffer": 0, "byteOffset": 8, "byteLength": 2},
                            {"buffer": 0, "byteOffset": 12, "byteLength": 2}],
            "accessors": [{"bufferView": 0, "componentType": 5123, "count": 3, "type": "SCALAR", "sparse": sparse}]}
    return tree, data


@pytest.mark.parametrize(("sparse", "words"), [
    ({"count": 1, "indices": {"bufferView": 1, "componentType": 5123}},
     "accessors[0].sparse: needs count, indices (bufferView, componentType) and values (bufferView) within their "
     "bufferViews"),
    ({"count": 2, "indices": {"bufferView": 1, "componentType": 5123}, "values": {"bufferView": 2}},
     "accessors[0].sparse: needs count, indices"),  # two indices of 2 bytes each in a 2-byte view
    ({"count": 1, "indices": {"bufferView": 7, "componentType": 5123}, "values": {"bufferView": 2}},
     "accessors[0].sparse: names bufferView 7, which is not a bufferView of the file"),
])
def test_sparse_substitutions_without_their_parts_are_refused_naming_the_sparse_key(sparse, words):
    """glTF 2.0 §5.1.1: sparse needs count, indices and values, each within its bufferView. A missing part or a
    count its views cannot hold says what sparse needs; a view the file lacks keeps the view's own words."""
    tree, data = sparse_tree(sparse)
    refused(lambda: decoder(tree, data).read_accessor(0, "k"), f"'t.glb': {words}")


# ------------------------------------------------------------ EXT_meshopt_compression


POSITIONS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], "<f4")


def meshopt_tree(stored: np.ndarray = POSITIONS, **changes) -> tuple[dict, list[bytes]]:
    """A float VEC3 accessor of POSITIONS (48 bytes) on bufferView 0, compressed by meshopt in buffer 0 as the
    rows of `stored` (the extension's `changes` applied); buffer 1 the fallback the view names."""
    import meshopt
    packed = meshopt.encode_gltf_buffer(stored, "ATTRIBUTES")
    spec = {"buffer": 0, "byteOffset": 0, "byteLength": len(packed), "byteStride": 12, "count": 4,
            "mode": "ATTRIBUTES", **changes}
    spec = {k: v for k, v in spec.items() if v is not None}
    tree = {"bufferViews": [{"buffer": 1, "byteLength": 48, "extensions": {MESHOPT_NAME: spec}}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"}]}
    return tree, [packed, b""]


KEY = f"'t.glb': bufferViews[0].extensions.{MESHOPT_NAME}"


@pytest.mark.parametrize(("changes", "words"), [
    ({"byteStride": None}, f"{KEY}: needs buffer, byteLength, byteStride, count and mode"),
    ({"mode": "POINTS"}, f"{KEY}.mode: is 'POINTS'; allowed: ATTRIBUTES, TRIANGLES, INDICES"),
    ({"byteStride": 6, "count": 8}, f"{KEY}.byteStride: is 6; allowed for ATTRIBUTES: 4 to 256, a multiple of 4"),
    ({"byteStride": 260}, f"{KEY}.byteStride: is 260; allowed for ATTRIBUTES: 4 to 256, a multiple of 4"),
    ({"mode": "TRIANGLES", "byteStride": 3, "count": 16}, f"{KEY}.byteStride: is 3; allowed for TRIANGLES: 2 or 4"),
    ({"mode": "INDICES", "byteStride": 8, "count": 6}, f"{KEY}.byteStride: is 8; allowed for INDICES: 2 or 4"),
    ({"mode": "TRIANGLES", "byteStride": 4, "count": 12}, None),  # 12 indices: a multiple of 3, checked further
    ({"mode": "TRIANGLES", "byteStride": 2, "count": 24}, None),
    ({"mode": "TRIANGLES", "byteStride": 4, "count": 10}, f"{KEY}.count: is 10; allowed: 0 or more, a multiple of 3"),
    ({"count": -4}, f"{KEY}.count: is -4; allowed: 0 or more"),
    ({"count": 3}, f"{KEY}: decodes to 3 × 12 bytes, but the bufferView's byteLength is 48; allowed: equal"),
    ({"buffer": 5}, f"{KEY}.buffer: is 5, not a buffer of the file"),
    ({"byteOffset": 4}, f"{KEY}: bytes 4..{{end}} lie outside buffer 0 of {{size}} bytes; allowed: within the buffer"),
])
def test_a_meshopt_view_breaking_the_extension_s_rules_is_refused_naming_the_field(changes, words):
    """EXT_meshopt_compression: buffer, byteLength, byteStride, count and mode are required; mode is ATTRIBUTES,
    TRIANGLES or INDICES; ATTRIBUTES' byteStride divisible by 4 and at most 256, TRIANGLES' and INDICES' 2 or 4;
    TRIANGLES' count divisible by 3; the parent view's byteLength is byteStride × count; the compressed bytes lie
    in their buffer. A TRIANGLES view of 12 or 24 indices passes these checks (then fails to decode: the bytes
    are vertex data)."""
    tree, buffers = meshopt_tree(**changes)
    if words is None:
        message = refused(lambda: decoder(tree, *buffers).decode_meshopt(), "could not be decoded")
        assert ".count" not in message and ".byteStride" not in message, message
        return
    size = len(buffers[0])
    refused(lambda: decoder(tree, *buffers).decode_meshopt(), words.format(end=4 + size, size=size))


def test_a_meshopt_view_decodes_its_data_keeps_other_extensions_and_one_nothing_reads_is_left_empty():
    """The compressed view becomes its decoded bytes (the positions exactly, the attribute codec is lossless) at
    its own byteStride, keeping any other extension it has; a compressed view no accessor reads is emptied,
    not decoded (its count × byteStride may be any size: only what is read is weighed)."""
    tree, buffers = meshopt_tree()
    tree["bufferViews"][0]["extensions"]["EXT_other"] = {"kept": True}
    tree["bufferViews"].append(json.loads(json.dumps(tree["bufferViews"][0])))
    tree["bufferViews"][1]["extensions"].pop("EXT_other")
    found = decoder(tree, *buffers)
    found.decode_meshopt()
    np.testing.assert_array_equal(found.read_accessor(0, "k"), POSITIONS)
    first, unread = tree["bufferViews"]
    assert first["extensions"] == {"EXT_other": {"kept": True}} and first["byteStride"] == 12
    assert unread["byteLength"] == 0 and "extensions" not in unread


def test_meshopt_views_that_only_sparse_substitutions_read_are_decoded():
    """An accessor's sparse indices and values may lie in compressed views (the extension compresses any view):
    a uint32 index (2) and a float value (99.5), each its own ATTRIBUTES view of stride 4, replace the last of
    three floats. Left undecoded they would read as empty views."""
    import meshopt
    index = meshopt.encode_gltf_buffer(np.array([[2]], "<u4"), "ATTRIBUTES")
    value = meshopt.encode_gltf_buffer(np.array([[99.5]], "<f4"), "ATTRIBUTES")
    plain = np.array([1.0, 2.0, 3.0], "<f4").tobytes()

    def compressed(data: bytes, offset: int) -> dict:
        return {"buffer": 1, "byteLength": 4, "extensions": {MESHOPT_NAME: {
            "buffer": 0, "byteOffset": offset, "byteLength": len(data), "byteStride": 4, "count": 1,
            "mode": "ATTRIBUTES"}}}
    tree = {"bufferViews": [{"buffer": 2, "byteLength": 12}, compressed(index, 0), compressed(value, len(index))],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "SCALAR",
                           "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5125},
                                      "values": {"bufferView": 2}}}]}
    found = decoder(tree, index + value, b"", plain)
    found.decode_meshopt()
    np.testing.assert_array_equal(found.read_accessor(0, "k")[:, 0], [1.0, 2.0, 99.5])


def test_a_decoded_view_whose_stride_is_shorter_than_its_accessors_elements_is_refused():
    """The extension's byteStride lays out the decoded view (the file's own view states none here, so the read's
    first check cannot see it): float VEC3 elements of 12 bytes every 4 would overlap (§3.6.2.4)."""
    tree, buffers = meshopt_tree(POSITIONS.reshape(12, 1), byteStride=4, count=12)
    found = decoder(tree, *buffers)
    found.decode_meshopt()
    refused(lambda: found.read_accessor(0, "k"), "'t.glb': bufferViews[0].byteStride is 4, less than the 12 bytes of "
                                                 "accessors[0]'s elements; allowed: 12 or more")


def without_required(source: Path, target: Path) -> Path:
    """The .glb `source` written to `target` with no extensionsRequired (its extensions only used)."""
    data = source.read_bytes()
    tree = glb_document(source)
    tree.pop("extensionsRequired", None)
    start = 20 + int.from_bytes(data[12:16], "little")
    return write_glb(target, tree, data[start + 8:start + 8 + int.from_bytes(data[start:start + 4], "little")])


def test_a_used_compression_without_its_decoder_package_is_refused_naming_the_package(tmp_path, monkeypatch):
    """A file that uses (not requires) meshopt or Draco compression passes the required-extension check; its
    compressed data is then refused, naming the package that decodes it (main: trimesh's own errors)."""
    path = without_required(MODELS / "BoxMeshopt.glb", tmp_path / "box.glb")
    shutil.copytree(MODELS / "BoxDraco", tmp_path / "draco")
    monkeypatch.setitem(sys.modules, "meshopt", None)  # import meshopt raises ImportError
    monkeypatch.setitem(sys.modules, "DracoPy", None)
    refused(lambda: read_mesh(path, "t"), f"bufferViews[0].extensions.{MESHOPT_NAME}: decoding "
                                          "meshoptimizer-compressed data needs the meshopt package: pip install "
                                          "meshopt")
    refused(lambda: read_mesh(tmp_path / "draco" / "BoxDraco.gltf", "t"),
            "BoxDraco.gltf': decoding its Draco-compressed meshes needs DracoPy: pip install DracoPy")


# ------------------------------------------------------------ KHR_draco_mesh_compression


def draco_box(folder: Path, change) -> Path:
    """BoxDraco in `folder`, its primitive's Draco extension changed by `change`."""
    shutil.copytree(MODELS / "BoxDraco", folder)
    path = folder / "BoxDraco.gltf"
    tree = json.loads(path.read_text())
    change(tree["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"])
    path.write_text(json.dumps(tree))
    return path


DRACO_KEY = "meshes[0].primitives[0].extensions.KHR_draco_mesh_compression"


def test_a_draco_extension_without_its_buffer_view_or_attributes_is_refused(tmp_path):
    """KHR_draco_mesh_compression requires bufferView and attributes: a view the file lacks is refused in the
    view's own words, a missing attributes map says what the extension needs."""
    pytest.importorskip("DracoPy")
    path = draco_box(tmp_path / "a", lambda spec: spec.update(bufferView=9))
    refused(lambda: read_mesh(path, "t"), f"{DRACO_KEY}: names bufferView 9, which is not a bufferView of the file")
    path = draco_box(tmp_path / "b", lambda spec: spec.pop("attributes"))
    refused(lambda: read_mesh(path, "t"), f"{DRACO_KEY}: needs a bufferView and attributes")


def test_draco_positions_under_an_id_the_stream_lacks_are_the_stream_s_points(tmp_path):
    """The stream's points are its positions: where the extension maps POSITION to an attribute id the stream
    does not hold (99), the box is still read from them, exactly as the intact file (not zeros)."""
    pytest.importorskip("DracoPy")
    intact = read_mesh(MODELS / "BoxDraco" / "BoxDraco.gltf", "t")
    path = draco_box(tmp_path / "box", lambda spec: spec["attributes"].update(POSITION=99))
    found = read_mesh(path, "t")
    np.testing.assert_array_equal(found.faces, intact.faces)
    np.testing.assert_allclose(found.vertices, intact.vertices, atol=0)
    assert np.ptp(found.vertices, axis=0).min() == 1.0  # the box's unit extent


# ------------------------------------------------------------ skins


def test_a_node_naming_a_skin_the_file_lacks_is_refused(tmp_path):
    path = skinned_quad(tmp_path, [0, 1], 1)
    document = json.loads(path.read_text())
    document["nodes"][0]["skin"] = 3
    path.write_text(json.dumps(document))
    refused(lambda: read_mesh(path, "t"), "nodes[0].skin: names a skin with joints and a mesh the file does not define")


def test_a_skinned_normal_turns_by_the_inverse_transpose_of_its_joint_s_matrix(tmp_path):
    """§3.7.3: a skinned vertex moves by its joint matrix L, its normal by L⁻ᵀ (kept perpendicular to the surface).
    The quad's every vertex follows joint 1, a node scaled (2, 1, 1): positions double in x, and the normal
    (1, 1, 0)/√2 becomes diag(½, 1, 1) of it, the direction (1, 2, 0)/√5 (L itself gives (2, 1, 0)/√5)."""
    path = skinned_quad(tmp_path, [0, 1], 1)
    document = json.loads(path.read_text())
    document["nodes"][1] = {"scale": [2, 1, 1]}
    attributes = document["meshes"][0]["primitives"][0]["attributes"]
    attributes["NORMAL"] = with_accessor(document, np.tile([np.sqrt(0.5), np.sqrt(0.5), 0.0], (4, 1)))
    path.write_text(json.dumps(document))
    found = read_mesh(path, "t")
    np.testing.assert_allclose(np.sort(found.vertices[:, 0]), [-2, -2, 2, 2], atol=1e-6)
    normals = found.normals / np.linalg.norm(found.normals, axis=1, keepdims=True)
    np.testing.assert_allclose(normals, np.tile([1 / np.sqrt(5), 2 / np.sqrt(5), 0.0], (len(normals), 1)), atol=1e-6)


def test_node_globals_are_each_parent_s_transform_times_its_own_a_matrix_read_by_columns():
    """A node's global transform is its parent's times its own (§3.5.3); a `matrix` is stored column by column
    (§3.5.2): node 1's matrix scales x by 3 and moves by (0, 2, 0); under node 0's translation (1, 0, 0) the
    point (1, 0, 0) lands at (4, 2, 0). A node that is not an object places nothing (the identity)."""
    nodes = [{"children": [1], "translation": [1, 0, 0]},
             {"matrix": [3, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 2, 0, 1]}, 5]
    placed = node_globals(nodes)
    np.testing.assert_allclose(placed[1] @ [1, 0, 0, 1], [4, 2, 0, 1], atol=1e-12)
    np.testing.assert_allclose(placed[0] @ [1, 0, 0, 1], [2, 0, 0, 1], atol=1e-12)
    np.testing.assert_array_equal(placed[2], np.eye(4))


# ------------------------------------------------------------ EXT_mesh_gpu_instancing


INSTANCING_KEY = "nodes[0].extensions.EXT_mesh_gpu_instancing.attributes"


def instanced_quad(folder: Path, attributes, **primitive) -> Path:
    """The quad (quad_gltf) placed by EXT_mesh_gpu_instancing: `attributes` maps each name to float values
    ((count, width) arrays), or is a callable given the document; `primitive` changes its primitive."""
    path = quad_gltf(folder, {})
    document = json.loads(path.read_text())
    document["meshes"][0]["primitives"][0].update(primitive)
    places = attributes(document) if callable(attributes) else {
        name: with_accessor(document, np.asarray(values, np.float64)) for name, values in attributes.items()}
    document["nodes"][0]["extensions"] = {"EXT_mesh_gpu_instancing": {"attributes": places}}
    document["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]
    path.write_text(json.dumps(document))
    return path


@pytest.mark.parametrize(("attributes", "words"), [
    ({"TRANSLATION": [[1, 2, 3, 4]]}, f"{INSTANCING_KEY}.TRANSLATION: has 4 components; allowed: 3"),
    ({"ROTATION": [[0, 0, 1]]}, f"{INSTANCING_KEY}.ROTATION: has 3 components; allowed: 4"),
    ({"SCALE": [[1, float("nan"), 1]]}, f"{INSTANCING_KEY}.SCALE: holds a NaN or infinite value; allowed: finite "
                                         "numbers"),
    ({"TRANSLATION": [[0, 0, 0], [1, 0, 0]], "SCALE": [[1, 1, 1]] * 3},
     f"{INSTANCING_KEY}: its accessors count [2, 3] instances; allowed: one count, the same for TRANSLATION, "
     "ROTATION and SCALE"),
    ({}, f"{INSTANCING_KEY}: names none of TRANSLATION, ROTATION, SCALE"),
])
def test_instance_attributes_breaking_the_extension_are_refused_naming_them(tmp_path, attributes, words):
    """EXT_mesh_gpu_instancing: TRANSLATION and SCALE are VEC3, ROTATION VEC4; every attribute accessor of a node
    has the same count. NaN, a count that disagrees and no attribute at all are refused naming the key."""
    refused(lambda: read_mesh(instanced_quad(tmp_path, attributes), "t"), words)


def test_an_instanced_node_naming_a_mesh_the_file_lacks_is_refused(tmp_path):
    path = instanced_quad(tmp_path, {"TRANSLATION": [[0, 0, 0]]})
    document = json.loads(path.read_text())
    document["nodes"][0]["mesh"] = 7
    path.write_text(json.dumps(document))
    refused(lambda: read_mesh(path, "t"), "nodes[0].mesh: is 7, not a mesh of the file with primitives")


def test_instanced_indices_past_the_vertices_are_refused(tmp_path):
    """Indices name vertices 0..count − 1 (§3.7.2.1): the quad's index 3 made 4 is refused before instances are
    built from it."""
    path = instanced_quad(tmp_path, {"TRANSLATION": [[0, 0, 0]]})
    data = bytearray((tmp_path / "quad.bin").read_bytes())
    data[80:92] = np.array([0, 1, 2, 0, 2, 4], "<u2").tobytes()
    (tmp_path / "quad.bin").write_bytes(bytes(data))
    refused(lambda: read_mesh(path, "t"), "meshes[0].primitives[0].indices: reach 4; allowed: 0..3")


def corner_points(found) -> set[tuple[float, ...]]:
    return {tuple(np.round(p, 6) + 0.0) for p in found.vertices[found.faces].reshape(-1, 3)}


def test_instances_of_triangles_without_indices_are_each_three_vertices_in_turn():
    """A primitive without indices draws vertices 0, 1, 2, then 3, 4, 5, ... (§3.7.2.1); a seventh vertex with no
    third pair draws nothing. Two instances (moved by 0 and by 10 in z) merge into one primitive of 14 vertices
    whose indices are each instance's two triangles, the second's from vertex 7 on."""
    from raycast_phong.io.meshes.gltf_decode import instance_matrices
    points = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0], [2, 1, 0], [9, 9, 9]], np.float64)
    tree = {"meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "bufferViews": [{"buffer": 0, "byteLength": 84}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 7, "type": "VEC3"}]}
    found = decoder(tree, points.astype("<f4").tobytes())
    shifts = np.array([[0, 0, 0], [0, 0, 10]], np.float64)
    merged = found.merged_instances(0, instance_matrices(shifts, None, None, 2), "nodes[0]")
    [primitive] = tree["meshes"][merged]["primitives"]
    np.testing.assert_array_equal(found.read_accessor(primitive["indices"], "k")[:, 0],
                                  [0, 1, 2, 3, 4, 5, 7, 8, 9, 10, 11, 12])
    np.testing.assert_array_equal(found.float_accessor(primitive["attributes"]["POSITION"], "k"),
                                  np.concatenate([points, points + np.array([0.0, 0.0, 10.0])]))


def test_instances_of_a_strip_are_child_nodes_each_placed_by_its_instance(tmp_path):
    """A primitive that is not triangles (a TRIANGLE_STRIP, mode 5) cannot be merged: each instance becomes a
    child node whose matrix (stored column by column, §3.5.2) is the instance's. The quad's four vertices as a
    strip, at x + 0 and x + 10: two triangles at each place."""
    path = instanced_quad(tmp_path, {"TRANSLATION": [[0, 0, 0], [10, 0, 0]]}, mode=5)
    document = json.loads(path.read_text())
    del document["meshes"][0]["primitives"][0]["indices"]
    path.write_text(json.dumps(document))
    found = read_mesh(path, "t")
    assert len(found.faces) == 4
    quad = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
    assert corner_points(found) == {(float(x + dx), float(y), 0.0) for x, y, _ in quad for dx in (0, 10)}


# ------------------------------------------------------------ the document


def test_a_data_uri_that_is_not_base64_is_refused_naming_the_buffer(tmp_path):
    """A buffer's data: URI holds base64 (glTF 2.0 §3.6.1.1); three characters cannot be (base64 comes in fours)."""
    path = quad_gltf(tmp_path, {})
    document = json.loads(path.read_text())
    document["buffers"][0]["uri"] = "data:application/octet-stream;base64,AAA"
    path.write_text(json.dumps(document))
    refused(lambda: read_mesh(path, "t"), "quad.gltf': buffers[0].uri is a data: URI that is not base64")


def test_a_document_too_malformed_to_decode_is_one_line_naming_what_is_wrong(tmp_path):
    """A mesh that is a number, in a file the decoder rewrites (it uses specular-glossiness): one line naming the
    problem's type and what is allowed, not a traceback."""
    path = quad_gltf(tmp_path, {"extensions": {"KHR_materials_pbrSpecularGlossiness": {}}})
    document = json.loads(path.read_text())
    document["meshes"].append(5)
    path.write_text(json.dumps(document))
    message = refused(lambda: read_mesh(path, "t"), "quad.gltf': its document is malformed where its compressed, "
                                                    "quantized or instanced data is described (AttributeError: ")
    assert message.endswith("allowed: a glTF 2.0 document"), message


def test_a_primitive_naming_an_accessor_the_file_lacks_is_left_to_trimesh_s_words(tmp_path):
    """The decoder's dequantization passes over an attribute naming no accessor, so the read's own check of the
    document says what is wrong; the decoder itself does not stop on it."""
    tree = {"accessors": [{"bufferView": 0, "componentType": 5126, "count": 1, "type": "VEC3"}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 4}}]}]}
    before = json.loads(json.dumps(tree))
    decoder(tree).dequantize()
    assert tree == before


def test_a_specular_glossiness_diffuse_factor_is_the_diffuse_colour_and_its_texture_is_said_unused(tmp_path):
    """KHR_materials_pbrSpecularGlossiness: diffuseFactor is k_d (and k_a), in trimesh's 8 bits; a
    specularGlossinessTexture is not applied, said in a note naming the material (its factors are used)."""
    from test_gltf_extensions import solid_png
    solid_png(tmp_path / "gloss.png", (255, 255, 255))
    glossy = {"diffuseFactor": [0.2, 0.4, 0.6, 1.0], "specularFactor": [0.1, 0.1, 0.1],
              "specularGlossinessTexture": {"index": 0}}
    path = quad_gltf(tmp_path, {"name": "shiny", "extensions": {"KHR_materials_pbrSpecularGlossiness": glossy}},
                     images=[{"uri": "gloss.png"}])
    found = read_mesh(path, "t")
    [material] = found.materials
    np.testing.assert_allclose(material.kd, (0.2, 0.4, 0.6), atol=0.5 / 255)
    assert material.ka == material.kd
    assert any("material 'shiny': specularGlossinessTexture not applied; its factors are used" in note
               for note in found.notes), found.notes
