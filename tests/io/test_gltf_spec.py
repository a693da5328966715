"""Parts of the glTF 2.0 specification no sample file held (issue 45), each in a file written here from the
specification: the primitive modes (§3.7.2.1: fans and strips are triangles; points and lines draw no
surface), a required extension the read honours (EXT_texture_webp) or that adds nothing to the surface
(KHR_lights_punctual), and Draco data that decodes to another count than its accessor's."""

from __future__ import annotations

import base64
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.errors import SceneError
from raycast_phong.io.meshes.source import mesh_source, read_mesh

MODELS = Path(__file__).resolve().parents[1] / "data" / "models"
# A pentagon in the z = 0 plane, convex, counter-clockwise seen from +Z.
PENTAGON = np.array([[np.cos(a), np.sin(a), 0.0] for a in np.linspace(0, 2 * np.pi, 6)[:-1] + 0.3], np.float32)
AMBIENT = ["render.width=40", "render.height=30", "ambient=[1, 1, 1]", "lights=[]", "render.background=[0, 0, 0]"]


def write(path: Path, primitives: list[dict], points=PENTAGON, indices=None, uvs=None, **document) -> Path:
    """A glTF of one mesh whose primitives share POSITION (accessor 0), TEXCOORD_0 (1, when `uvs`) and indices
    (the last accessor, when `indices`), its buffer a data: URI."""
    blob = np.asarray(points, np.float32).tobytes()
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(blob)}]
    accessors = [{"bufferView": 0, "componentType": 5126, "count": len(points), "type": "VEC3",
                  "min": np.min(points, 0).tolist(), "max": np.max(points, 0).tolist()}]
    for values, kind, component, dtype in ((uvs, "VEC2", 5126, np.float32), (indices, "SCALAR", 5123, np.uint16)):
        if values is not None:
            data = np.asarray(values, dtype).tobytes()
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
            accessors.append({"bufferView": len(views) - 1, "componentType": component, "count": len(values),
                              "type": kind})
            blob += data + b"\0" * (-len(data) % 4)
    tree = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": primitives}], "accessors": accessors, "bufferViews": views,
            "buffers": [{"byteLength": len(blob),
                         "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
            **document}
    path.write_text(json.dumps(tree))
    return path


def triangles(read) -> set[tuple[int, ...]]:
    """The read's triangles, each from its smallest corner on, winding kept."""
    found = set()
    for face in read.faces.tolist():
        k = face.index(min(face))
        found.add(tuple(face[k:] + face[:k]))
    return found


def facing(read) -> np.ndarray:
    """Each triangle's normal's z: +1 where it is wound counter-clockwise seen from +Z."""
    corners = read.vertices[read.faces]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    return normal[:, 2] / np.linalg.norm(normal, axis=1)


@pytest.mark.parametrize("indexed", [False, True])
def test_a_triangle_fan_is_its_triangles(tmp_path, indexed):
    """§3.7.2.1: fan triangle i is (v_i+1, v_i+2, v_0); the pentagon's 5 vertices make 3 triangles, all facing +Z.
    Indexed, the fan runs through the indices (here the vertices in reverse: facing −Z)."""
    order = [4, 3, 2, 1, 0]
    primitive = {"attributes": {"POSITION": 0}, "mode": 6, **({"indices": 1} if indexed else {})}
    path = write(tmp_path / "fan.gltf", [primitive], indices=order if indexed else None)
    read = read_mesh(path, "t")
    v = order if indexed else list(range(5))
    expected = {tuple(np.roll(t, -int(np.argmin(t)))) for t in ([v[0], v[i], v[i + 1]] for i in range(1, 4))}
    assert triangles(read) == expected
    assert np.allclose(facing(read), -1.0 if indexed else 1.0)
    corners = read.vertices[read.faces]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1).sum()
    assert area == pytest.approx(2.5 * np.sin(2 * np.pi / 5), rel=1e-6)  # the regular pentagon's area


def test_a_triangle_fan_of_three_vertices_is_one_triangle(tmp_path):
    """The smallest fan, 3 indices (0, 2, 3 of the pentagon), is its one triangle, facing +Z; catches the fan
    needing more than 3 vertices."""
    primitive = {"attributes": {"POSITION": 0}, "mode": 6, "indices": 1}
    read = read_mesh(write(tmp_path / "fan.gltf", [primitive], indices=[0, 2, 3]), "t")
    assert triangles(read) == {(0, 2, 3)} and np.allclose(facing(read), 1.0)


def test_a_triangle_strip_alternates_its_winding_to_keep_facing(tmp_path):
    """§3.7.2.1: strip triangle i is (v_i, v_i+1+i%2, v_i+2−i%2): every one faces the same way."""
    points = [[0, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [2, 0, 0], [2, 1, 0]]
    read = read_mesh(write(tmp_path / "strip.gltf", [{"attributes": {"POSITION": 0}, "mode": 5}], points=points), "t")
    assert len(read.faces) == 4 and np.allclose(facing(read), facing(read)[0])


def test_points_and_lines_are_noted_and_a_file_of_only_them_says_why_it_holds_no_triangles(tmp_path):
    mixed = write(tmp_path / "mixed.gltf", [{"attributes": {"POSITION": 0}, "mode": 6},
                                            {"attributes": {"POSITION": 0}, "mode": 0},
                                            {"attributes": {"POSITION": 0}, "mode": 3}])
    read = read_mesh(mixed, "t")
    assert len(read.faces) == 3
    assert any("1 primitive(s) of points, 1 primitive(s) of line strips" in note for note in read.notes), read.notes
    only = write(tmp_path / "only.gltf", [{"attributes": {"POSITION": 0}, "mode": 1}])
    with pytest.raises(SceneError) as caught:
        read_mesh(only, "t")
    assert "holds no triangles" in str(caught.value) and "1 primitive(s) of lines" in str(caught.value)


def test_required_lights_render_with_a_note_naming_them(tmp_path):
    """KHR_lights_punctual adds lights, no surface: a file that requires it renders (it was refused); its lights
    and cameras are named in a note."""
    lights = {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 5.0}, {"type": "directional"}]}}
    path = write(tmp_path / "lit.gltf", [{"attributes": {"POSITION": 0}, "mode": 6}], extensions=lights,
                 extensionsUsed=["KHR_lights_punctual"], extensionsRequired=["KHR_lights_punctual"],
                 cameras=[{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}])
    read = read_mesh(path, "t")
    assert len(read.faces) == 3 and any("2 light(s) (KHR_lights_punctual)" in note for note in read.notes)
    assert any("1 camera(s) are not used" in note for note in read.notes), read.notes


def test_a_required_webp_texture_is_read(tmp_path):
    """EXT_texture_webp: the texture's image is the extension's `source` (here the only one)."""
    from PIL import Image
    Image.new("RGB", (8, 8), (30, 200, 40)).save(tmp_path / "green.webp", lossless=True)
    square = [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]
    webp = {"extensionsUsed": ["EXT_texture_webp"], "extensionsRequired": ["EXT_texture_webp"],
            "images": [{"uri": "green.webp"}],
            "textures": [{"extensions": {"EXT_texture_webp": {"source": 0}}}],
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}]}
    path = write(tmp_path / "webp.gltf", [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2,
                                           "material": 0}],
                 points=square, uvs=[[0, 1], [1, 1], [1, 0], [0, 0]], indices=[0, 1, 2, 0, 2, 3], **webp)
    source = mesh_source(path)
    assert source.format.texture_sizes(source) == ((8, 8),)  # the memory estimate counts the WebP map
    image = rp.render_file(path, AMBIENT).image
    seen = image[image.max(axis=-1) > 0]
    assert len(seen) > 100 and (seen[:, 1] > 3 * seen[:, 0]).all() and (seen[:, 1] > 3 * seen[:, 2]).all()


def test_draco_data_that_decodes_to_another_count_is_drawn_with_a_note(tmp_path):
    """A known quirk of published samples: the accessor's count is not the decoded stream's. f3d draws the
    decoded data; so does the read, saying so."""
    pytest.importorskip("DracoPy")
    shutil.copytree(MODELS / "BoxDraco", tmp_path / "box")
    path = tmp_path / "box" / "BoxDraco.gltf"
    intact = read_mesh(path, "t")
    tree = json.loads(path.read_text())
    position = tree["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
    tree["accessors"][position]["count"] += 5
    path.write_text(json.dumps(tree))
    read = read_mesh(path, "t")
    assert np.array_equal(read.faces, intact.faces) and np.allclose(read.vertices, intact.vertices)
    assert any("decodes to" in note and "the decoded values are drawn" in note for note in read.notes), read.notes


def test_a_skinned_mesh_is_drawn_in_the_pose_its_joints_hold(tmp_path):
    """§3.7.3: v' = Σ_k w_k (G(joint_k) · IBM_k) v, the skinned node's own transform ignored. A square: its
    bottom corners follow joint 0 (bound at y = 1, now at y = 2: +1 in y), its top corners joint 1 (bound at the
    origin, now turned 90° about z: (x, y) → (−y, x)); the mesh node's translation (100, 0, 0) is not applied.
    trimesh drew the bind pose (the square as stored)."""
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    joints = np.array([[0, 0, 0, 0], [0, 0, 0, 0], [1, 0, 0, 0], [1, 0, 0, 0]], np.uint16)
    weights = np.array([[1, 0, 0, 0]] * 4, np.float32)
    bind = np.eye(4)
    bind[1, 3] = -1.0  # the inverse of joint 0's bind transform, a translation by (0, 1, 0)
    inverse = np.stack([bind, np.eye(4)]).transpose(0, 2, 1).astype(np.float32)  # column by column
    blob = b"".join(a.tobytes() for a in (square, joints, weights, inverse))
    sizes = [square.nbytes, joints.nbytes, weights.nbytes, inverse.nbytes]
    offsets = np.concatenate([[0], np.cumsum(sizes)[:-1]]).tolist()
    tree = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
            "nodes": [{"mesh": 0, "skin": 0, "translation": [100, 0, 0]},
                      {"translation": [0, 2, 0]},
                      {"rotation": [0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)]}],
            "skins": [{"joints": [1, 2], "inverseBindMatrices": 3}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "JOINTS_0": 1, "WEIGHTS_0": 2},
                                        "indices": 4}]}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                           "min": [0, 0, 0], "max": [1, 1, 0]},
                          {"bufferView": 1, "componentType": 5123, "count": 4, "type": "VEC4"},
                          {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC4"},
                          {"bufferView": 3, "componentType": 5126, "count": 2, "type": "MAT4"},
                          {"bufferView": 4, "componentType": 5123, "count": 6, "type": "SCALAR"}],
            "bufferViews": [{"buffer": 0, "byteOffset": o, "byteLength": n} for o, n in zip(offsets, sizes)]
            + [{"buffer": 0, "byteOffset": len(blob), "byteLength": 12}]}
    blob += np.array([0, 1, 2, 0, 2, 3], np.uint16).tobytes()
    tree["buffers"] = [{"byteLength": len(blob),
                        "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}]
    path = tmp_path / "skinned.gltf"
    path.write_text(json.dumps(tree))
    read = read_mesh(path, "t")
    expected = {(0.0, 1.0, 0.0), (1.0, 1.0, 0.0), (-1.0, 1.0, 0.0), (-1.0, 0.0, 0.0)}
    found = {tuple(np.round(v, 6) + 0.0) for v in read.vertices[np.unique(read.faces)]}
    assert found == expected, found


def masked_quads(folder: Path, alpha_pixels, factor: float = 1.0, cutoff=0.5, layers: int = 1) -> Path:
    """`layers` unit squares at z = 0.5, 0.25, ... with alphaMode MASK over a red wall at z = -0.5, all facing
    the camera. The squares' map is 2 × 2 green texels with the given alphas (row by row, top first)."""
    from PIL import Image
    image = Image.new("RGBA", (2, 2))
    image.putdata([(0, 200, 0, a) for a in alpha_pixels])
    image.save(folder / "mask.png")
    squares = [np.array([[-1, -1, z], [1, -1, z], [1, 1, z], [-1, 1, z]], np.float32)
               for z in (0.5 - 0.25 * k for k in range(layers))]
    wall = np.array([[-2, -2, -0.5], [2, -2, -0.5], [2, 2, -0.5], [-2, 2, -0.5]], np.float32)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    indices = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    parts = [*squares, wall, uv, indices]
    blob, views = b"", []
    for part in parts:
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": part.nbytes})
        blob += part.tobytes()
    n = len(squares)
    accessors = [{"bufferView": k, "componentType": 5126, "count": 4, "type": "VEC3",
                  "min": part.min(0).tolist(), "max": part.max(0).tolist()} for k, part in enumerate([*squares, wall])]
    accessors += [{"bufferView": n + 1, "componentType": 5126, "count": 4, "type": "VEC2"},
                  {"bufferView": n + 2, "componentType": 5123, "count": 6, "type": "SCALAR"}]
    leaf = {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "baseColorFactor": [1, 1, 1, factor],
                                     "metallicFactor": 0}, "alphaMode": "MASK", "name": "leaf"}
    if cutoff is not None:
        leaf["alphaCutoff"] = cutoff
    meshes = [{"primitives": [{"attributes": {"POSITION": k, "TEXCOORD_0": n + 1}, "indices": n + 2, "material": 0}]}
              for k in range(n)]
    meshes.append({"primitives": [{"attributes": {"POSITION": n}, "indices": n + 2, "material": 1}]})
    tree = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": list(range(n + 1))}],
            "nodes": [{"mesh": k} for k in range(n + 1)], "meshes": meshes,
            "materials": [leaf, {"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1], "metallicFactor": 0},
                                 "name": "wall"}],
            "textures": [{"source": 0, "sampler": 0}], "samplers": [{"magFilter": 9728, "minFilter": 9728}],
            "images": [{"uri": "mask.png"}], "accessors": accessors, "bufferViews": views,
            "buffers": [{"byteLength": len(blob),
                         "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}]}
    path = folder / "masked.gltf"
    path.write_text(json.dumps(tree))
    return path


FLAT_LIGHT = ["render.width=64", "render.height=64", "camera.position=[0,0,6]", "camera.look_at=[0,0,0]",
              "camera.fov=30", "lights=[]", "ambient=[1,1,1]"]
QUARTERS = {"top left": (20, 20), "top right": (20, 44), "bottom left": (44, 20), "bottom right": (44, 44)}


def seen(path: Path, *extra: str) -> dict:
    """Which surface each quarter of the square shows: "leaf" (green), "wall" (red) or "none"."""
    image = rp.render_file(path, [*FLAT_LIGHT, *extra]).image
    return {name: "leaf" if image[y, x, 1] > 0.3 else "wall" if image[y, x, 0] > 0.5 else "none"
            for name, (y, x) in QUARTERS.items()}


@pytest.mark.parametrize("mode", ["local", "global"])
def test_alpha_mask_cuts_the_texels_below_its_cutoff_away(tmp_path, mode):
    """§3.9.4: MASK draws a point where alpha ≥ alphaCutoff and nothing elsewhere; the wall behind shows through
    the two texels of alpha 0 (nearest filtering: each texel a quarter of the square)."""
    path = masked_quads(tmp_path, [0, 255, 255, 0])
    assert seen(path, f"render.mode={mode}") == {"top left": "wall", "top right": "leaf", "bottom left": "leaf",
                                                  "bottom right": "wall"}
    assert any("alphaMode MASK cuts" in note for note in read_mesh(path, "t").notes)


def test_alpha_mask_multiplies_the_factor_and_defaults_its_cutoff_to_a_half(tmp_path):
    """alpha = factor × texel: 0.7 × 200/255 = 0.55 is kept under the default cutoff 0.5, 0.7 × 100/255 cut."""
    path = masked_quads(tmp_path, [200, 100, 100, 200], factor=0.7, cutoff=None)
    assert seen(path) == {"top left": "leaf", "top right": "wall", "bottom left": "wall", "bottom right": "leaf"}


def test_a_ray_passes_through_every_cut_away_layer(tmp_path):
    """Three masked squares, one behind the other: the cut quarters show the wall through all three."""
    path = masked_quads(tmp_path, [0, 255, 255, 0], layers=3)
    assert seen(path)["top left"] == "wall" and seen(path)["top right"] == "leaf"


def test_a_cutoff_above_1_cuts_everything_and_0_nothing(tmp_path):
    """Alpha is at most 1: a cutoff of 1.1 leaves nothing of the masked surface (the Asset Generator's
    Material_AlphaMask_03), a cutoff of 0 keeps all of it."""
    everything = masked_quads(tmp_path, [0, 255, 255, 0], cutoff=1.1)
    assert set(seen(everything).values()) == {"wall"}
    nothing = masked_quads(tmp_path, [0, 255, 255, 0], cutoff=0.0)
    assert set(seen(nothing).values()) == {"leaf"}


def test_alpha_blend_covers_a_share_alpha_of_a_pixel_s_samples(tmp_path):
    """BLEND, drawn as coverage (screen-door): with 8 × 8 samples a pixel of a square of alpha 0.3 over the red
    wall is 0.3 of the square's colour and 0.7 of the wall's, within the sampling's spread (64 samples: ±3σ =
    ±0.17 of the share). Opaque before (the square's colour alone)."""
    path = masked_quads(tmp_path, [255, 255, 255, 255], factor=0.3)
    tree = json.loads(path.read_text())
    tree["materials"][0]["alphaMode"] = "BLEND"
    path.write_text(json.dumps(tree))
    image = rp.render_file(path, [*FLAT_LIGHT, "render.samples=8"]).image
    leaf = np.array([0.0, 200 / 255, 0.0]) ** 2.2  # roughly, ambient 1: the leaf's k_a (sRGB decoded)
    centre = image[24:40, 24:40].reshape(-1, 3)
    green_share = centre[:, 1] / max(float(leaf[1]), 1e-6)
    red_share = centre[:, 0]
    assert abs(float(np.median(red_share)) - 0.7) < 0.17 and abs(float(np.median(green_share)) - 0.3) < 0.17
    assert any("alphaMode BLEND is drawn as coverage" in note for note in read_mesh(path, "t").notes)


def test_blend_at_one_sample_a_pixel_warns_with_the_samples_it_needs(tmp_path):
    """Coverage reads as a blend only with several samples a pixel: at 1 the plan says so, at 4 it is quiet."""
    path = masked_quads(tmp_path, [255, 255, 255, 255], factor=0.3)
    tree = json.loads(path.read_text())
    tree["materials"][0]["alphaMode"] = "BLEND"
    path.write_text(json.dumps(tree))
    one = rp.render_file(path, FLAT_LIGHT)
    assert any("use render.samples = 4 or more" in warning for warning in one.plan.warnings), one.plan.warnings
    four = rp.render_file(path, [*FLAT_LIGHT, "render.samples=4"])
    assert not any("alphaMode BLEND" in warning for warning in four.plan.warnings)


def test_the_memory_estimate_counts_an_alpha_map_apart_from_its_colour(tmp_path):
    """MASK and BLEND decode the base colour map's alpha channel as a texture of its own: the estimate counts
    the image twice; an opaque material once."""
    path = masked_quads(tmp_path, [0, 255, 255, 0])
    source = mesh_source(path)
    assert source.format.texture_sizes(source) == ((2, 2), (2, 2))
    tree = json.loads(path.read_text())
    tree["materials"][0]["alphaMode"] = "OPAQUE"
    path.write_text(json.dumps(tree))
    source = mesh_source(path)
    assert source.format.texture_sizes(source) == ((2, 2),)
