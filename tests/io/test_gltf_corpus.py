"""glTF files of the public corpus (issue 33) that rendered wrong or were refused wrongly, each on a minimal file
written here after the real one (docs/figures/corpus.toml names them): COLOR_0 of normalized unsigned shorts
(glTF-Blender-IO's 22_vertex_color), accessors without a bufferView and a file without nodes (glTF-Validator's
mesh/valid.gltf and uv.gltf), required extensions that change only the look (15_transmission), an alpha mask,
and broken files refused in the renderer's words. Each test fails on the main branch before this change (noted
per test)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from test_gltf_extensions import quad_gltf

from raycast_phong.errors import SceneError
from raycast_phong.io.meshes.gltf import LOOK_ONLY
from raycast_phong.io.meshes.source import read_mesh


def with_colour(path: Path, colour: dict, data: bytes = b"") -> Path:
    """The quad of quad_gltf with a COLOR_0 accessor `colour` over `data` appended to its buffer (at byte 92)."""
    document = json.loads(path.read_text())
    binary = (path.parent / "quad.bin").read_bytes()  # 92 bytes: positions, uvs, indices
    if data:
        document["bufferViews"].append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(data)})
        colour = {**colour, "bufferView": len(document["bufferViews"]) - 1}
        (path.parent / "quad.bin").write_bytes(binary + data)
        document["buffers"][0]["byteLength"] = len(binary) + len(data)
    document["accessors"].append(colour)
    document["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = len(document["accessors"]) - 1
    path.write_text(json.dumps(document))
    return path


def test_normalized_unsigned_short_colours_read_as_their_fraction_of_65535(tmp_path):
    """22_vertex_color stores COLOR_0 as normalized uint16 VEC4 without KHR_mesh_quantization: each channel is
    c / 65535 (glTF 2.0 §3.11). main handed it to trimesh, which ignores `normalized` and scaled by 255 after
    a uint8 cast: pastel colours, the corners' green, blue and salmon lost."""
    stored = np.array([[0, 65535, 0, 65535], [0, 0, 65535, 65535], [65535, 32768, 16384, 65535],
                       [13107, 26214, 39321, 65535]], "<u2")
    path = with_colour(quad_gltf(tmp_path, {}),
                       {"componentType": 5123, "normalized": True, "count": 4, "type": "VEC4"}, stored.tobytes())
    document = json.loads(path.read_text())
    del document["meshes"][0]["primitives"][0]["material"]  # as in 22_vertex_color: colours alone
    path.write_text(json.dumps(document))
    read = read_mesh(path, "t")
    expected = (stored[:, :3] / 65535.0)[read.faces]
    np.testing.assert_allclose(read.corner_colour, expected, atol=0.5 / 255 + 1e-6)  # trimesh keeps 8 bits


def test_a_file_without_buffers_reads_its_accessors_as_zeros(tmp_path):
    """glTF 2.0 §3.6.2.1: an accessor without a bufferView holds zeros; glTF-Validator's mesh/valid.gltf and
    uv.gltf have no buffers at all. Read here: indices, positions and colours all zero (the render then refuses
    the model for its zero size, in its own words). main: trimesh raised UnboundLocalError (it builds its
    accessors only when the file has buffers), shown as the refusal."""
    path = quad_gltf(tmp_path, {})
    document = json.loads(path.read_text())
    for key in ("buffers", "bufferViews"):
        document.pop(key)
    document["accessors"] = [{"componentType": 5126, "count": 4, "type": "VEC3"},
                             {"componentType": 5126, "count": 4, "type": "VEC2"},
                             {"componentType": 5123, "count": 3, "type": "SCALAR"},
                             {"componentType": 5121, "normalized": True, "count": 4, "type": "VEC4"}]
    document["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = 3
    path.write_text(json.dumps(document))
    read = read_mesh(path, "t")
    np.testing.assert_array_equal(read.faces, [[0, 0, 0]])
    np.testing.assert_array_equal(read.vertices, np.zeros((4, 3)))
    np.testing.assert_array_equal(read.corner_colour, np.zeros((1, 3, 3)))


def test_a_file_without_nodes_shows_each_mesh_once(tmp_path):
    """A file with meshes but no scene or nodes (glTF 2.0 §3.5.1: a library of meshes, as glTF-Validator's
    valid.gltf and uv.gltf) shows each mesh once, unplaced. main: 'holds no triangles'."""
    path = quad_gltf(tmp_path, {})
    document = json.loads(path.read_text())
    for key in ("scene", "scenes", "nodes"):
        document.pop(key)
    path.write_text(json.dumps(document))
    read = read_mesh(path, "t")
    assert read.faces.shape == (2, 3)
    np.testing.assert_array_equal(read.vertices, [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])


@pytest.mark.parametrize("required", [True, False])
@pytest.mark.parametrize("extension", sorted(LOOK_ONLY))
def test_an_extension_that_changes_only_the_look_is_a_note(tmp_path, extension, required):
    """15_transmission requires KHR_materials_transmission: the spec lets a viewer refuse, but drawing the base
    material with a note is friendlier; so for each extension that changes only the look, required or only
    used (issue 45: a used one was dropped with no note)."""
    material = {"pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.4, 0.6, 1.0], "metallicFactor": 0.0},
                "extensions": {extension: {}}}
    read = read_mesh(quad_gltf(tmp_path, material, required=(extension,) if required else ()), "t")
    assert read.materials[0].kd == pytest.approx((0.2, 0.4, 0.6))
    said = f"{'requires' if required else 'uses'} {extension}"
    assert any(said in note and "base colour" in note for note in read.notes), read.notes


def test_a_required_extension_that_changes_the_data_is_still_refused(tmp_path):
    """KHR_texture_basisu stores textures this renderer cannot decode: refused, naming it and what it needs."""
    with pytest.raises(SceneError, match=r"KHR_texture_basisu \(KTX2"):
        read_mesh(quad_gltf(tmp_path, {}, required=("KHR_texture_basisu",)), "t")


def test_broken_files_are_refused_in_the_renderers_words(tmp_path):
    """The corpus's broken glTF files whose refusal carried trimesh's exception text: invalid JSON
    (glTF-Validator's json/invalid_syntax.gltf: FileNotFoundError of a file trimesh then looked for), a missing
    buffer file (buffer/not_found.gltf: FileNotFoundError), a bufferView naming a buffer the file lacks
    (tinygltf's BoundsChecking/invalid-buffer-index.gltf: IndexError). Each now names the file, the key path and
    what is allowed, and no exception type. main: each message named the exception type."""
    broken = tmp_path / "syntax.gltf"
    broken.write_text("{]")
    cases = [(broken, r"its JSON does not parse \(line 1, column 2")]
    path = quad_gltf(tmp_path, {}, buffer="gone.bin")
    (tmp_path / "gone.bin").unlink()
    cases.append((path, r"buffers\[0\]\.uri names 'gone\.bin', which is missing"))

    def edited(folder: str, key: str, index: int, field: str, value: int) -> Path:
        """The quad's glTF in its own folder, with document[key][index][field] = value."""
        (tmp_path / folder).mkdir()
        path = quad_gltf(tmp_path / folder, {})
        document = json.loads(path.read_text())
        document[key][index][field] = value
        path.write_text(json.dumps(document))
        return path

    cases.append((edited("second", "bufferViews", 1, "buffer", 1), r"bufferViews\[1\]\.buffer is 1; allowed: 0\.\.0"))
    cases.append((edited("third", "accessors", 2, "bufferView", 7),
                  r"accessors\[2\]\.bufferView is 7; allowed: 0\.\.2"))
    for path, words in cases:
        with pytest.raises(SceneError, match=words) as raised:
            read_mesh(path, "t")
        assert "Error" not in str(raised.value), str(raised.value)


def test_alpha_mask_and_blend_are_said_with_their_cutoff_and_coverage(tmp_path):
    """01_alpha_mask: alphaMode MASK cuts away (tests/io/test_gltf_spec.py draws it); the note names the mask and
    its cutoff, not a transparency of alpha 1. BLEND is drawn as coverage, said so; OPAQUE ignores alpha."""
    from raycast_phong.codes import BLENDED_ALPHA, OPAQUE_ALPHA
    read = read_mesh(quad_gltf(tmp_path, {"alphaMode": "MASK", "alphaCutoff": 0.3}), "t")
    assert any("alphaMode MASK cuts the surface away where alpha < 0.3" in note for note in read.notes), read.notes
    assert read.materials[0].alpha_cutoff == 0.3
    for mode, cutoff in (("BLEND", BLENDED_ALPHA), ("OPAQUE", OPAQUE_ALPHA)):
        folder = tmp_path / mode
        folder.mkdir()
        read = read_mesh(quad_gltf(folder, {"alphaMode": mode, "pbrMetallicRoughness": {
            "baseColorFactor": [1, 1, 1, 0.4]}}), "t")
        assert read.materials[0].alpha_cutoff == cutoff
        assert any("alphaMode BLEND is drawn as coverage" in note for note in read.notes) == (mode == "BLEND")


def test_a_reader_that_stops_on_a_corrupt_file_is_refused_without_its_exception_text(tmp_path):
    """A PLY header whose property type is three NUL bytes (the assimp fuzzer's crash file): trimesh raised
    KeyError('\\x00\\x00\\x00'), an ASCII STL with a vertex line that does not parse gave numpy's ValueError text
    (openscad's invalidvertex.stl). Now the renderer's words: the line and what it should hold where the reader
    can tell (io.meshes.read._explained), else the format and what the file may be. main: the exception's type and
    text."""
    (tmp_path / "crash.ply").write_bytes(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty \0\0\0 x\nend_header\n1\n")
    (tmp_path / "bad.stl").write_text("solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 x\nvertex 1 0 0\n"
                                      "vertex 0 1 0\nendloop\nendfacet\nendsolid s\n")
    for name, format in (("crash.ply", "PLY"), ("bad.stl", "STL")):
        words = rf"'.*{name}' (header )?line \d+: |cannot read '.*{name}' as {format}: its content does not follow"
        with pytest.raises(SceneError, match=words) as raised:
            read_mesh(tmp_path / name, "t")
        assert "Error" not in str(raised.value), str(raised.value)


def test_a_material_naming_a_texture_the_file_lacks_counts_no_map_in_the_memory_estimate(tmp_path):
    """texture_sizes weighs each colour map from its image's header before the read; a baseColorTexture whose
    index names no texture (the file has none) counts nothing rather than stopping the estimate (the read words
    the broken reference). The same material naming a texture of a 4 × 4 image counts it."""
    from test_gltf_extensions import solid_png

    from raycast_phong.io.meshes.source import mesh_source
    solid_png(tmp_path / "map.png", (255, 0, 0))
    path = quad_gltf(tmp_path, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                     images=[{"uri": "map.png"}])
    source = mesh_source(path)
    assert source.format.texture_sizes(source) == ((4, 4),)
    document = json.loads(path.read_text())
    document["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["index"] = 3
    path.write_text(json.dumps(document))
    source = mesh_source(path)
    assert source.format.texture_sizes(source) == ()


def test_wrap_modes_read_before_a_sampler_the_file_lacks_are_kept_and_the_rest_repeat():
    """glTF 2.0 §5.26: wrapS and wrapT 33071 clamp, 33648 mirror (10497, repeat, the default). Material a's map
    clamps in s and mirrors in t; material b's texture names sampler 5 of 1: the table is malformed from there
    on, so b's map (and any after it) repeats, without stopping the read."""
    from raycast_phong.io.meshes.gltf import gltf_samplers
    document = {"materials": [{"name": "a", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                              {"name": "b", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1}}}],
                "textures": [{"source": 0, "sampler": 0}, {"source": 0, "sampler": 5}],
                "samplers": [{"wrapS": 33071, "wrapT": 33648}]}
    assert gltf_samplers(document) == {("a", "baseColorTexture"): ("clamp", "mirror")}


def test_node_transforms_are_checked_past_a_node_that_is_not_an_object(tmp_path):
    """check_node_transforms refuses a node's scale of 2 numbers (3 are needed) though a node before it is a
    number (not an object: trimesh words that), and leaves a `nodes` that is not a list to trimesh."""
    from raycast_phong.io.meshes.gltf import check_node_transforms
    with pytest.raises(SceneError, match=r"'m\.gltf': nodes\[1\]\.scale is \[1, 1\]; allowed: 3 finite numbers"):
        check_node_transforms({"nodes": [5, {"scale": [1, 1]}]}, Path("m.gltf"))
    assert check_node_transforms({"nodes": 5}, Path("m.gltf")) is None


def test_a_missing_buffer_file_weighs_nothing_in_the_memory_estimate(tmp_path):
    """held() counts a .gltf's external buffers as read whole (the quad's is 92 bytes); a buffer file that is
    missing counts 0 (the read then refuses it, naming the file), not an error of the estimate."""
    from raycast_phong.io.meshes import gltf
    from raycast_phong.io.meshes.source import mesh_source
    path = quad_gltf(tmp_path, {})
    source = mesh_source(path)
    assert gltf.held(path, source) == (92, 0)
    (tmp_path / "quad.bin").unlink()
    assert gltf.held(path, source) == (0, 0)
