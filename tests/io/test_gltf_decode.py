"""glTF data that trimesh misreads, decoded by io/meshes/gltf_decode.py, checked on real files against a reference
(tests/data/models/LICENSES.md says where each comes from):

- KHR_mesh_quantization and EXT/KHR_meshopt_compression: gltfpack's output of BoxTextured (-c, -c -ce khr,
  -vpn -cc) against the float original, to within the quantization error the file's own grid allows; the
  gltfpack 0.14 pirate (the meshoptimizer demo's) against the same file decoded by gltfpack 1.3's own reader
  (-noq: meshoptimizer's C decoder and cgltf's dequantization), the reference library's output.
- EXT_mesh_gpu_instancing: glTF-Transform's many-cubes, 501 instances of one cube, packed by gltfpack -mi -c
  (instance rotations as normalized int16 under meshopt), against gltfpack -noq's one node an instance.
- KHR_materials_pbrSpecularGlossiness: glTF-Transform's BoxTextured in both workflows.
- A node matrix with a NaN and a corrupt Draco stream: one line each (issue 30 item 10).

Every test here fails on main, which refused the required extensions, or read them otherwise (noted per test).
"""

from __future__ import annotations

import json
import logging
import re
import shutil
import struct
import warnings
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import cKDTree

import raycast_phong as rp
from raycast_phong.errors import SceneError
from raycast_phong.io.meshes.source import read_mesh

MODELS = Path(__file__).resolve().parents[1] / "data" / "models"
SMALL = ["render.width=160", "render.height=120"]


def corners(mesh) -> np.ndarray:
    """(3F, 6): each face corner's position and unit normal, to match corners between two files whose vertex and
    face orders differ (gltfpack reorders both)."""
    normals = mesh.normals / np.linalg.norm(mesh.normals, axis=1)[:, None]
    return np.concatenate([mesh.vertices[mesh.faces].reshape(-1, 3), normals[mesh.faces].reshape(-1, 3)], axis=1)


def glb_document(path: Path) -> dict:
    data = path.read_bytes()
    return json.loads(data[20:20 + struct.unpack_from("<I", data, 12)[0]])


def write_glb(path: Path, tree: dict, binary: bytes) -> Path:
    """A .glb of `tree` and its binary chunk (glTF 2.0 §4.4), padded to 4 bytes."""
    text = json.dumps(tree).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(binary), 0x004E4942) + binary
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(chunks)) + chunks)
    return path


def differing(image: np.ndarray, reference: np.ndarray, atol: float) -> float:
    """The share of pixels covered in either image whose colour differs by more than `atol`."""
    covered = (image.max(axis=-1) > 0) | (reference.max(axis=-1) > 0)
    off = np.abs(image - reference).max(axis=-1) > atol
    return (off & covered).sum() / max(covered.sum(), 1)


@pytest.mark.parametrize("name", ["BoxTextured-meshopt.glb", "BoxTextured-khr-meshopt.glb",
                                  "BoxTextured-normalized.glb"])
def test_gltfpack_output_decodes_to_its_float_original_within_its_quantization(name):
    """Positions (14-bit, on the node's dequantizing scale and offset), normals (8-bit normalized int8) and
    texture coordinates (12-bit, normalized uint16 under KHR_texture_transform) each within half a step of their
    grid from the float original, and the rendered images alike within what that error can change."""
    packed, original = read_mesh(MODELS / name, "t"), read_mesh(MODELS / "BoxTextured.glb", "t")
    assert packed.faces.shape == original.faces.shape == (12, 3)
    distance, match = cKDTree(corners(original)).query(corners(packed))
    node = glb_document(MODELS / name)["nodes"][0]
    # Half a position step: gltfpack's scale maps one integer step (or 1/65535 when normalized) to scale × it.
    step = node["scale"][0] / (65535 if name == "BoxTextured-normalized.glb" else 1)
    assert distance.max() <= np.sqrt(3) * step / 2 + 1e-9, (distance.max(), step)
    # 12-bit texture coordinates over the file's UV range (u 0..6, v 0..1): within half a step.
    uv, reference_uv = packed.corner_uv.reshape(-1, 2), original.corner_uv.reshape(-1, 2)[match]
    half_step = (reference_uv.max(axis=0) - reference_uv.min(axis=0)) / (2**12 - 1) / 2
    uv_error = np.abs(uv - reference_uv).max(axis=0)
    assert (uv_error <= half_step + 1e-6).all(), (uv_error, half_step)
    # The images: a texel lookup moved by uv_error × 256 texels changes a colour by at most that fraction of the
    # map's largest step between neighbouring texels; only silhouette pixels (the framing moves by < 1e-4 of a
    # pixel) may flip. main refused these files.
    from PIL import Image
    with Image.open(MODELS / "BoxTextured-specgloss" / "CesiumLogoFlat.png") as opened:
        texels = np.asarray(opened.convert("RGB"), np.float64) / 255.0
    jump = max(np.abs(np.diff(texels, axis=0)).max(), np.abs(np.diff(texels, axis=1)).max())
    atol = float(uv_error.max() * 256 * jump) + 1e-4
    image, reference = (rp.render_file(MODELS / n, SMALL).image for n in (name, "BoxTextured.glb"))
    assert differing(image, reference, atol) < 0.005, atol


def test_the_meshopt_decoder_agrees_with_the_reference_implementation():
    """pirate.glb (gltfpack 0.14: 14-bit uint16 positions, 8-bit octahedral-filtered normals, meshopt-compressed
    indices) against pirate-float.glb, the same file decoded and written as floats by gltfpack 1.3 itself:
    the same 5,010 triangles, every corner where the reference puts it (float32 rounding), its normal within one
    step of the 8-bit grid (1/127: gltfpack warns that repacking quantized input may move them; 0.6% of corners
    differ, by at most 0.0058) and the same image.
    Against the original pirate.obj (not kept: 369 kB) every decoded vertex lay within 9.6e-5 of one, under half
    the 14-bit grid's diagonal step (1.0e-4)."""
    packed, reference = read_mesh(MODELS / "pirate.glb", "t"), read_mesh(MODELS / "pirate-float.glb", "t")
    assert len(packed.faces) == len(reference.faces) == 5010
    found, expected = corners(packed), corners(reference)
    _, match = cKDTree(expected).query(found)
    assert np.abs(found[:, :3] - expected[match, :3]).max() < 1e-6  # float32 rounding of the same positions
    assert np.abs(found[:, 3:] - expected[match, 3:]).max() < 1 / 127
    # A normal moved by up to 1/127 changes k_d (N·L) by as much (white, one light of 1, its faint lobe f = 1
    # included); silhouettes do not move (positions agree to 1e-6).
    image, expected = (rp.render_file(MODELS / n, SMALL).image for n in ("pirate.glb", "pirate-float.glb"))
    np.testing.assert_allclose(image, expected, atol=1 / 127)


def test_instances_are_each_placed_and_counted_before_the_read(tmp_path):
    """501 cube instances of one node (EXT_mesh_gpu_instancing; ROTATION as normalized int16 under meshopt's
    filters) land where gltfpack -noq's 501 nodes put them: main drew one cube and counted 12 triangles.
    Rotations are 16-bit: a corner moves at most 2 × 4 components × ½/32767 × its distance from the instance's
    centre (√3 × scale ≤ 2 here), 1e-3 with the 14-bit cube besides."""
    from raycast_phong.io.meshes.size import check_mesh_read
    from raycast_phong.io.meshes.source import mesh_source
    packed = read_mesh(MODELS / "many-cubes-instanced.glb", "t")
    reference = read_mesh(MODELS / "many-cubes-float.glb", "t")
    assert len(packed.faces) == len(reference.faces) == 501 * 12
    distance, _ = cKDTree(reference.vertices).query(packed.vertices[packed.faces].reshape(-1, 3))
    assert distance.max() < 1e-3, distance.max()
    # The estimate counts every instance's triangles (and vertices) before any data is decoded.
    counted = mesh_source(MODELS / "many-cubes-instanced.glb").triangles()
    assert counted == mesh_source(MODELS / "many-cubes-float.glb").triangles() >= 501 * 12
    with pytest.raises(SceneError, match="triangles needs"):  # 12 triangles' worth fits; 501 × 12 do not
        check_mesh_read(mesh_source(MODELS / "many-cubes-instanced.glb", "t"), max_memory=1 << 20)
    image, expected = (rp.render_file(MODELS / n, SMALL).image
                       for n in ("many-cubes-instanced.glb", "many-cubes-float.glb"))
    assert differing(image, expected, 0.02) < 0.005


def test_each_instance_counts_its_mesh_s_triangles_where_they_outnumber_its_vertices(tmp_path):
    """The estimate's count is instances × triangles, and where vertices are fewer than triangles (shared, as in
    any closed mesh) it is the triangles that decide: a mesh of 4 vertices and 100 triangles (its two indexed
    over and over) placed 1,000 times by EXT_mesh_gpu_instancing counts 100,000. Catches the instances left off
    the triangles (the vertices' 3,998 would win)."""
    import base64

    from raycast_phong.io.meshes.source import mesh_source
    from tests.io.test_gltf_extensions import quad_gltf
    path = quad_gltf(tmp_path, {})
    document = json.loads(path.read_text())
    indices = np.tile(np.array([0, 1, 2, 0, 2, 3], "<u2"), 50)
    document["meshes"][0]["primitives"][0]["indices"] = len(document["accessors"])
    data = indices.tobytes()
    document["buffers"].append({"uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode(),
                                "byteLength": len(data)})
    document["bufferViews"].append({"buffer": len(document["buffers"]) - 1, "byteLength": len(data)})
    document["accessors"].append({"bufferView": len(document["bufferViews"]) - 1, "componentType": 5123,
                                  "count": len(indices), "type": "SCALAR"})
    places = {"TRANSLATION": with_accessor(document, np.zeros((1000, 3)))}
    document["nodes"][0]["extensions"] = {"EXT_mesh_gpu_instancing": {"attributes": places}}
    document["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]
    path.write_text(json.dumps(document))
    assert mesh_source(path).triangles() == 1000 * 100


def test_specular_glossiness_maps_diffuse_specular_and_glossiness_onto_the_lecture_s_model():
    """The same box in both workflows (glTF-Transform's test files): k_d = k_a and the map are the diffuse
    ones, as the metallic-roughness box's base colour; k_s = specularFactor 0.2 and glossiness 1 the sharpest
    lobe (f = 1000). Lit by ambient light alone the two images are the same; lit, the specular-glossiness one
    lacks at most the rough one's faint lobe. main took trimesh's conversion: k_s 0.088, f = 1."""
    glossy = read_mesh(MODELS / "BoxTextured-specgloss" / "BoxTextured.gltf", "t")
    rough = read_mesh(MODELS / "BoxTextured.glb", "t")
    [material], [base] = glossy.materials, rough.materials
    assert (material.kd, material.ka, material.kd_map >= 0) == (base.kd, base.ka, True)
    np.testing.assert_allclose(material.ks, (0.2, 0.2, 0.2), rtol=1e-6)
    assert material.shininess == 1000.0
    ambient = [*SMALL, "ambient=[1, 1, 1]", "lights=[]"]
    a, b = (rp.render_file(p, ambient).image for p in (MODELS / "BoxTextured-specgloss" / "BoxTextured.gltf",
                                                         MODELS / "BoxTextured.glb"))
    np.testing.assert_allclose(a, b, atol=1e-5)
    a, b = (rp.render_file(p, SMALL).image for p in (MODELS / "BoxTextured-specgloss" / "BoxTextured.gltf",
                                                     MODELS / "BoxTextured.glb"))
    # The rough box's own lobe (k_s 0.0035, f = 1) is all the glossy one may lack (its own lobe is a point here).
    assert (a >= b - base.ks[0] - 1e-5).all()


def test_a_meshopt_filter_it_cannot_decode_and_corrupt_data_are_one_line(tmp_path):
    """An unknown filter is refused naming the bufferView, the filter and those supported; compressed bytes
    that do not decode say so. main refused both files for requiring EXT_meshopt_compression."""
    data = (MODELS / "BoxMeshopt.glb").read_bytes()
    length = struct.unpack_from("<I", data, 12)[0]
    document = json.loads(data[20:20 + length])
    view = next(v for v in document["bufferViews"] if v["extensions"]["EXT_meshopt_compression"]["mode"]
                == "ATTRIBUTES")
    index = document["bufferViews"].index(view)

    def write(name: str, tree: dict, binary: bytes) -> Path:
        return write_glb(tmp_path / name, tree, binary)

    binary = data[20 + length + 8:]
    view["extensions"]["EXT_meshopt_compression"]["filter"] = "FANCY"
    with pytest.raises(SceneError) as caught:
        read_mesh(write("filter.glb", document, binary), "t")
    assert (f"bufferViews[{index}].extensions.EXT_meshopt_compression.filter: is 'FANCY', which this renderer "
            "cannot decode; supported: NONE, OCTAHEDRAL, QUATERNION, EXPONENTIAL") in str(caught.value)
    view["extensions"]["EXT_meshopt_compression"].pop("filter")
    start = view["extensions"]["EXT_meshopt_compression"].get("byteOffset", 0)
    broken = bytearray(binary)
    broken[start:start + 8] = b"\xff" * 8  # the vertex codec's header byte and first blocks
    with pytest.raises(SceneError) as caught:
        read_mesh(write("corrupt.glb", document, bytes(broken)), "t")
    message = str(caught.value)
    assert "could not be decoded" in message and "\n" not in message, message


def nan_quad(folder: Path, field: str, value) -> Path:
    from tests.io.test_gltf_extensions import quad_gltf
    path = quad_gltf(folder, {})
    document = json.loads(path.read_text())
    document["nodes"][0][field] = value
    path.write_text(json.dumps(document))  # json writes NaN and Infinity, and reads them back as floats
    return path


@pytest.mark.parametrize(("field", "value"), [("matrix", [1, 0, 0, 0, 0, float("nan"), 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]),
                                              ("translation", [0, float("inf"), 0]), ("scale", [1, 1])])
def test_a_non_finite_node_transform_is_one_line_naming_the_node(tmp_path, field, value):
    """main: numpy RuntimeWarnings, then "every vertex lies within 0" or a blank image."""
    path = nan_quad(tmp_path, field, value)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a numpy RuntimeWarning fails the test
        with pytest.raises(SceneError) as caught:
            rp.render_file(path, SMALL)
    message = str(caught.value)
    length = {"matrix": 16, "translation": 3, "scale": 3}[field]
    assert f"nodes[0].{field} is " in message and f"allowed: {length} finite numbers" in message, message


@pytest.mark.parametrize(("written", "shown"), [("x" * 78, "'" + "x" * 78 + "'"), ("x" * 79, "'" + "x" * 76 + "...")])
def test_a_bad_node_value_is_shown_whole_up_to_80_characters(tmp_path, written, shown):
    """A bad node field's value is quoted whole while its repr is at most 80 characters (78 letters and their
    quotes), else cut to 77 and `...`. Catches the cut made at 80 itself."""
    from raycast_phong.io.meshes.source import mesh_source
    with pytest.raises(SceneError) as caught:
        mesh_source(nan_quad(tmp_path, "translation", written)).read()
    assert f"nodes[0].translation is {shown}; allowed: 3 finite numbers" in str(caught.value), str(caught.value)


def test_corrupt_draco_data_is_one_line_naming_the_file(tmp_path, caplog):
    """main: trimesh's two warnings, then "every vertex of the model lies within 0". The intact file renders."""
    shutil.copytree(MODELS / "BoxDraco", tmp_path / "box")
    intact = read_mesh(tmp_path / "box" / "BoxDraco.gltf", "t")
    assert len(intact.faces) == 12 and np.ptp(intact.vertices, axis=0).min() > 0.5
    data = bytearray((tmp_path / "box" / "0.bin").read_bytes())
    data[10:] = bytes(b ^ 0x5A for b in data[10:])
    (tmp_path / "box" / "0.bin").write_bytes(bytes(data))
    (tmp_path / "box" / "BoxDraco.gltf").touch()  # a new version: not the read kept above
    with caplog.at_level(logging.WARNING), pytest.raises(SceneError) as caught:
        rp.render_file(tmp_path / "box" / "BoxDraco.gltf", SMALL)
    message = str(caught.value)
    assert "BoxDraco.gltf" in message and "Draco-compressed data could not be decoded" in message, message
    assert "within 0" not in message and not caplog.records, [r.getMessage() for r in caplog.records]


@pytest.mark.parametrize(("component", "normalized", "stored", "expected"), [
    (5120, True, [-128, -127, -1, 0, 127], [-1.0, -1.0, -1 / 127, 0.0, 1.0]),  # max(c / 127, −1)
    (5121, True, [0, 1, 255], [0.0, 1 / 255, 1.0]),
    (5122, True, [-32768, -32767, 16384, 32767], [-1.0, -1.0, 16384 / 32767, 1.0]),
    (5123, True, [0, 65535, 1], [0.0, 1.0, 1 / 65535]),
    (5123, False, [0, 7, 16383], [0.0, 7.0, 16383.0]),  # KHR_mesh_quantization: not normalized is the value
    (5120, False, [-128, 5], [-128.0, 5.0])])
def test_integer_accessors_decode_as_the_gltf_specification_says(component, normalized, stored, expected):
    """glTF 2.0 §3.11 (and KHR_mesh_quantization): hand-computed values for each component type, with a
    byteStride wider than the element (as gltfpack pads int8 VEC3 to 4 bytes) and a sparse substitution."""
    from raycast_phong.io.meshes.gltf_decode import DTYPES, _Decoder
    dtype = np.dtype(DTYPES[component]).newbyteorder("<")
    stride = 4 * ((dtype.itemsize + 3) // 4)
    data = bytearray(stride * len(stored))
    for i, value in enumerate(stored):  # each element at the start of its stride, the rest padding (0xEE)
        data[i * stride:(i + 1) * stride] = np.array([value], dtype).tobytes().ljust(stride, b"\xee")
    sparse_at = np.array([len(stored) - 1], "<u2").tobytes() + b"\0\0"
    sparse_value = np.array([stored[0]], dtype).tobytes().ljust(4, b"\0")
    offset = len(data)
    data += sparse_at + sparse_value
    tree = {"buffers": [{"byteLength": len(data)}],
            "bufferViews": [{"buffer": 0, "byteLength": offset, "byteStride": stride},
                            {"buffer": 0, "byteOffset": offset, "byteLength": 4},
                            {"buffer": 0, "byteOffset": offset + 4, "byteLength": 4}],
            "accessors": [{"bufferView": 0, "componentType": component, "normalized": normalized,
                           "count": len(stored), "type": "SCALAR"},
                          {"bufferView": 0, "componentType": component, "normalized": normalized,
                           "count": len(stored), "type": "SCALAR",
                           "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5123},
                                      "values": {"bufferView": 2}}}]}
    decoder = _Decoder(tree, [bytes(data)], Path("t.glb"), [])
    np.testing.assert_array_equal(decoder.float_accessor(0, "k")[:, 0], expected)
    np.testing.assert_array_equal(decoder.float_accessor(1, "k")[:, 0], [*expected[:-1], expected[0]])


def test_an_instance_matrix_is_translation_rotation_scale_in_that_order():
    """EXT_mesh_gpu_instancing: a point goes through S, then R, then T (hand-computed: x̂ scaled by 2 along x,
    turned 90° about z by the quaternion (0, 0, sin 45°, cos 45°), moved by (1, 2, 3): (1, 4, 3); the other
    order gives (1, 3, 3)); no rotation accessor is no rotation."""
    from raycast_phong.io.meshes.gltf_decode import instance_matrices
    half = np.sqrt(0.5)
    [matrix] = instance_matrices(np.array([[1.0, 2.0, 3.0]]), np.array([[0.0, 0.0, half, half]]),
                                 np.array([[2.0, 1.0, 1.0]]), 1)
    np.testing.assert_allclose(matrix @ [1.0, 0.0, 0.0, 1.0], [1.0, 4.0, 3.0, 1.0], atol=1e-12)
    [plain] = instance_matrices(np.array([[1.0, 2.0, 3.0]]), None, None, 1)
    np.testing.assert_allclose(plain @ [1.0, 0.0, 0.0, 1.0], [2.0, 2.0, 3.0, 1.0], atol=1e-12)


def test_the_cli_says_a_nan_node_and_a_missing_meshopt_package_in_one_line_exit_2(tmp_path, monkeypatch):
    """Through `raycast-phong render`: exit 2, one line on stderr (no RuntimeWarning lines); a meshopt file
    without the meshopt package names the extension and the package to install."""
    import sys

    from typer.testing import CliRunner

    from raycast_phong.cli import app
    runner = CliRunner()
    path = nan_quad(tmp_path, "rotation", [0, 0, float("nan"), 1])
    done = runner.invoke(app, ["render", str(path), "-o", str(tmp_path / "x.png"), "--set", "render.width=40",
                               "--set", "render.height=30"])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert "nodes[0].rotation is [0, 0, NaN, 1]; allowed: 4 finite numbers" in line, line
    monkeypatch.setitem(sys.modules, "meshopt", None)  # import meshopt raises ImportError
    done = runner.invoke(app, ["render", str(MODELS / "pirate.glb"), "-o", str(tmp_path / "y.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert "EXT_meshopt_compression (meshoptimizer compression: pip install meshopt)" in line, line


def with_accessor(document: dict, values: np.ndarray) -> int:
    """A float32 accessor of `values` (count, width) in a new data: URI buffer of `document`."""
    import base64
    data = np.ascontiguousarray(values, "<f4").tobytes()
    document["buffers"].append({"uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode(),
                                "byteLength": len(data)})
    document["bufferViews"].append({"buffer": len(document["buffers"]) - 1, "byteLength": len(data)})
    document["accessors"].append({"bufferView": len(document["bufferViews"]) - 1, "componentType": 5126,
                                  "count": len(values), "type": f"VEC{values.shape[1]}"})
    return len(document["accessors"]) - 1


def test_instances_keep_their_faces_outward_and_their_normals_perpendicular(tmp_path):
    """A square in the plane y = z with its normals (0, −1, 1)/√2, instanced twice: once stretched and turned
    (scale (1, 3, 1), then 45° about x), once mirrored (scale (−1, 1, 1)). Each instance's stored normals stay
    perpendicular to its placed faces (the inverse transpose, not the matrix itself) and agree in sign with the
    faces' winding (a mirrored instance's faces turned over), as one node with one child per instance would."""
    from tests.io.test_gltf_extensions import quad_gltf
    path = quad_gltf(tmp_path, {})
    document = json.loads(path.read_text())
    primitive = document["meshes"][0]["primitives"][0]
    tilted = np.array([[-1.0, -1.0, -1.0], [1.0, -1.0, -1.0], [1.0, 1.0, 1.0], [-1.0, 1.0, 1.0]])
    primitive["attributes"]["POSITION"] = with_accessor(document, tilted)
    primitive["attributes"]["NORMAL"] = with_accessor(document, np.tile([0.0, -np.sqrt(0.5), np.sqrt(0.5)], (4, 1)))
    turn = np.sin(np.pi / 8), np.cos(np.pi / 8)
    attributes = {"ROTATION": with_accessor(document, np.array([[turn[0], 0, 0, turn[1]], [0, 0, 0, 1]])),
                  "SCALE": with_accessor(document, np.array([[1.0, 3.0, 1.0], [-1.0, 1.0, 1.0]]))}
    document["nodes"][0]["extensions"] = {"EXT_mesh_gpu_instancing": {"attributes": attributes}}
    document["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]
    path.write_text(json.dumps(document))
    read = read_mesh(path, "t")
    assert read.faces.shape == (4, 3)
    corners_ = read.vertices[read.faces]
    winding = np.cross(corners_[:, 1] - corners_[:, 0], corners_[:, 2] - corners_[:, 0])
    normals = read.normals[read.faces[:, 0]]
    cosine = np.einsum("ij,ij->i", winding, normals) / np.linalg.norm(winding, axis=1) / np.linalg.norm(normals,
                                                                                                         axis=1)
    np.testing.assert_allclose(cosine, 1.0, atol=1e-12)


def test_khr_meshopt_colour_filter_and_version_1_vertex_codec_decode_vertex_colours(tmp_path):
    """KHR_meshopt_compression's COLOR filter (YCoCg, 8 bits) over the version 1 vertex codec, written here by
    meshoptimizer's own encoder (the meshopt package) since no public file has one: the square's COLOR_0 reads
    back within the filter's rounding (1.5/255 a channel) of the colours encoded."""
    import meshopt
    colours = np.array([[0.1, 0.5, 0.9, 1.0], [1.0, 0.0, 0.0, 1.0], [0.25, 0.75, 0.5, 1.0], [0.0, 0.0, 1.0, 1.0]],
                       np.float32)
    packed = meshopt.encode_gltf_buffer(meshopt.encode_filter_color(colours, 4, 8), "ATTRIBUTES", version=1)
    positions = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], "<f4").tobytes()
    indices = np.array([0, 1, 2, 0, 2, 3, 0, 0], "<u2").tobytes()  # padded to 16 bytes
    binary = positions + indices + packed
    compressed = {"buffer": 0, "byteOffset": 64, "byteLength": len(packed), "byteStride": 4, "count": 4,
                  "mode": "ATTRIBUTES", "filter": "COLOR"}
    tree = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "COLOR_0": 2}, "indices": 1}]}],
            "buffers": [{"byteLength": len(binary) + (-len(binary) % 4)},
                        {"byteLength": 16, "extensions": {"KHR_meshopt_compression": {"fallback": True}}}],
            "bufferViews": [{"buffer": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 16},
                            {"buffer": 1, "byteLength": 16, "byteStride": 4,
                             "extensions": {"KHR_meshopt_compression": compressed}}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                           "min": [-1, -1, 0], "max": [1, 1, 0]},
                          {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
                          {"bufferView": 2, "componentType": 5121, "normalized": True, "count": 4, "type": "VEC4"}],
            "extensionsUsed": ["KHR_meshopt_compression"], "extensionsRequired": ["KHR_meshopt_compression"]}
    read = read_mesh(write_glb(tmp_path / "colours.glb", tree, binary), "t")
    found = read.corner_colour.reshape(-1, 3)
    expected = colours[read.faces.reshape(-1), :3]
    np.testing.assert_allclose(found, expected, atol=1.5 / 255)


def test_a_byte_stride_shorter_than_its_elements_is_refused_naming_the_buffer_view(tmp_path):
    """glTF 2.0 §3.6.2.4: an element must fit in the stride. A float VEC3 (12 bytes) every 4 bytes would read
    overlapping positions, inside the bufferView's 48 bytes (trimesh did, silently): refused in one line naming
    the bufferView."""
    from tests.io.test_gltf_extensions import quad_gltf
    path = quad_gltf(tmp_path, {})
    document = json.loads(path.read_text())
    document["bufferViews"][0]["byteStride"] = 4
    path.write_text(json.dumps(document))
    with pytest.raises(SceneError, match=re.escape("bufferViews[0].byteStride is 4, less than the 12 bytes of "
                                                   "accessors[0]'s elements; allowed: 12 or more")):
        read_mesh(path, "t")
    document["bufferViews"][0]["byteStride"] = 12
    path.write_text(json.dumps(document))
    assert len(read_mesh(path, "t").faces) == 2


def test_instances_times_vertices_beyond_32_bits_are_refused_before_placing_them(tmp_path):
    """65,536 instances of a primitive of 65,536 vertices place 2³² vertices (96 GiB as float64): refused
    before the placement allocates. Accessors without a bufferView hold zeros (glTF 2.0 §3.6.2.3), so the
    file stays a few hundred bytes."""
    from tests.io.test_gltf_extensions import quad_gltf
    path = quad_gltf(tmp_path, {})
    document = json.loads(path.read_text())
    document["accessors"][0] = {"componentType": 5126, "count": 65_536, "type": "VEC3"}
    document["accessors"].append({"componentType": 5126, "count": 65_536, "type": "VEC3"})
    document["nodes"][0]["extensions"] = {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": 3}}}
    document["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]
    path.write_text(json.dumps(document))
    with pytest.raises(SceneError, match=re.escape("places 65,536 × 65,536 vertices; allowed: fewer than 2³²")):
        read_mesh(path, "t")


def test_a_compressed_view_decoding_to_more_than_its_accessors_read_is_refused_before_decoding(tmp_path):
    """A meshopt bufferView's count × byteStride is what its decode allocates: a 2 kB file may claim gigabytes.
    BoxMeshopt's vertex view claims twice what its accessors read: refused, naming both, before the decoder runs."""
    path = MODELS / "BoxMeshopt.glb"
    data = path.read_bytes()
    tree = glb_document(path)
    start = 20 + struct.unpack_from("<I", data, 12)[0]
    binary = data[start + 8:start + 8 + struct.unpack_from("<I", data, start)[0]]
    index, view = next((k, v) for k, v in enumerate(tree["bufferViews"])
                       if (v.get("extensions") or {}).get("EXT_meshopt_compression", {}).get("mode") == "ATTRIBUTES")
    spec = view["extensions"]["EXT_meshopt_compression"]
    spec["count"] *= 2
    view["byteLength"] = spec["count"] * spec["byteStride"]
    bloated = write_glb(tmp_path / "bloated.glb", tree, binary)
    with pytest.raises(SceneError, match=re.escape(f"bufferViews[{index}].extensions.EXT_meshopt_compression: decodes "
                                                   f"to {spec['count']} × {spec['byteStride']} bytes, of which its "
                                                   "accessors read")):
        read_mesh(bloated, "t")


@pytest.mark.parametrize(("index", "refused"), [(2, False), (3, True)])
def test_a_sparse_index_equal_to_the_accessors_count_is_refused_in_words(index, refused):
    """An integer accessor of 3 elements with one sparse substitute: at index 2 (its last) it replaces that element,
    at index 3 (the count) it is refused naming `sparse.indices` and the count, not an IndexError."""
    from raycast_phong.io.meshes.gltf_decode import _Decoder
    data = np.array([10, 20, 30], "<u2").tobytes() + b"\0\0" + np.array([index], "<u2").tobytes() + b"\0\0"
    data += np.array([99], "<u2").tobytes() + b"\0\0"
    tree = {"buffers": [{"byteLength": len(data)}],
            "bufferViews": [{"buffer": 0, "byteLength": 6}, {"buffer": 0, "byteOffset": 8, "byteLength": 2},
                            {"buffer": 0, "byteOffset": 12, "byteLength": 2}],
            "accessors": [{"bufferView": 0, "componentType": 5123, "count": 3, "type": "SCALAR",
                           "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5123},
                                      "values": {"bufferView": 2}}}]}
    decoder = _Decoder(tree, [bytes(data)], Path("t.glb"), [])
    if not refused:
        np.testing.assert_array_equal(decoder.float_accessor(0, "k")[:, 0], [10, 20, 99])
        return
    with pytest.raises(SceneError) as caught:
        decoder.float_accessor(0, "k")
    assert "sparse.indices" in str(caught.value) and "below the accessor's count 3" in str(caught.value)


def skinned_quad(tmp_path, joints: list[int], joint: int) -> Path:
    """The quad skinned: its skin lists the nodes `joints` (node 0 the quad's own, node 1 translated by +5 in x)
    and every vertex names joint number `joint` of them with weight 1."""
    from tests.io.test_gltf_extensions import quad_gltf
    path = quad_gltf(tmp_path, {})
    document = json.loads(path.read_text())
    document["nodes"] = [{"mesh": 0, "skin": 0}, {"translation": [5, 0, 0]}]
    document["skins"] = [{"joints": joints}]
    attributes = document["meshes"][0]["primitives"][0]["attributes"]
    attributes["JOINTS_0"] = with_accessor(document, np.tile([joint, 0, 0, 0], (4, 1)))
    attributes["WEIGHTS_0"] = with_accessor(document, np.tile([1, 0, 0, 0], (4, 1)))
    path.write_text(json.dumps(document))
    return path


@pytest.mark.parametrize(("joints", "joint", "refused"), [
    ([0, 1], 1, None),
    ([0, 2], 1, r"skins\[0\]\.joints: allowed: node indices 0\.\.1"),  # a joint node equal to the node count
    ([0, 1], 2, r"JOINTS_0: allowed: one row per vertex of joint numbers 0\.\.1"),  # a joint number at the count
])
def test_a_skin_s_joint_at_the_count_is_refused_naming_the_field(tmp_path, joints, joint, refused):
    """A skinned quad posed by joint 1 (node 1, +5 in x) moves by it, node 0 being a joint too; a skin joint
    naming node 2 of 2 nodes, or a vertex naming joint 2 of 2, is refused in one line naming the field, not read
    past the end (an IndexError worded as a malformed document)."""
    path = skinned_quad(tmp_path, joints, joint)
    if refused is None:
        found = read_mesh(path, "t")
        np.testing.assert_allclose(np.sort(found.vertices[:, 0]), [4, 4, 6, 6], atol=1e-6)
        return
    with pytest.raises(SceneError, match=refused):
        read_mesh(path, "t")


def test_an_instance_scaled_flat_keeps_its_faces_winding(tmp_path):
    """The quad (in z = 0, facing +z) instanced once with scale (1, 1, 0): the determinant is exactly 0, not a
    mirror, so its faces keep their winding, facing +z as written; only a negative determinant turns them over.
    Catches the mirror test taken as `determinant <= 0`."""
    from tests.io.test_gltf_extensions import quad_gltf
    path = quad_gltf(tmp_path, {})
    document = json.loads(path.read_text())
    attributes = {"SCALE": with_accessor(document, np.array([[1.0, 1.0, 0.0]]))}
    document["nodes"][0]["extensions"] = {"EXT_mesh_gpu_instancing": {"attributes": attributes}}
    document["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]
    path.write_text(json.dumps(document))
    read = read_mesh(path, "t")
    corners_ = read.vertices[read.faces]
    winding = np.cross(corners_[:, 1] - corners_[:, 0], corners_[:, 2] - corners_[:, 0])
    assert read.faces.shape == (2, 3) and (winding[:, 2] > 0).all(), winding
