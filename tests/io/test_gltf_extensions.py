"""glTF files that are valid and were refused (issue 33, "Valid files refused"), each on a minimal file written
here: a percent-encoded buffer and image URI, KHR_materials_unlit (the lecture's emission-only material),
KHR_materials_emissive_strength, KHR_texture_transform; and the refusal of an extension still unsupported,
in the renderer's words."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.errors import SceneError
from raycast_phong.io.meshes.source import read_mesh

# Ambient light only, white: a surface shows k_a (and k_e); lights would add its diffuse and specular terms.
AMBIENT = ["render.width=40", "render.height=30", "ambient=[1, 1, 1]", "lights=[]", "render.background=[0, 0, 0]"]
LIT = ["render.width=40", "render.height=30", "ambient=[0, 0, 0]", "render.background=[0, 0, 0]"]


def quad_gltf(folder: Path, material: dict, buffer: str = "quad.bin", uri: str | None = None,
              images: list | None = None, required: tuple[str, ...] = ()) -> Path:
    """A square of two triangles facing +Z (the framing's front), texture coordinates over the whole image,
    its data in the external file `buffer` named by `uri` (default: the name as written)."""
    positions = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)  # glTF: v down from the image's top
    indices = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    data = positions.tobytes() + uvs.tobytes() + indices.tobytes()
    (folder / buffer).write_bytes(data)
    document = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2, "material": 0}]}],
        "materials": [material],
        "buffers": [{"uri": uri or buffer, "byteLength": len(data)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 32},
                        {"buffer": 0, "byteOffset": 80, "byteLength": 12}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -1, 0],
                       "max": [1, 1, 0]},
                      {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
                      {"bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR"}],
    }
    if images:
        document["images"] = images
        document["textures"] = [{"source": i} for i in range(len(images))]
    used = sorted({*required, *(material.get("extensions") or {})})
    if used:
        document["extensionsUsed"] = used
    if required:
        document["extensionsRequired"] = list(required)
    path = folder / "quad.gltf"
    path.write_text(json.dumps(document), encoding="utf-8")
    return path


def covered(image: np.ndarray) -> np.ndarray:
    return image[image.max(axis=-1) > 0]


def solid_png(path: Path, rgb: tuple[int, int, int]) -> None:
    from PIL import Image
    Image.new("RGB", (4, 4), rgb).save(path)


def test_percent_encoded_buffer_and_image_uris_are_decoded(tmp_path):
    """glTF 2.0 §3.3.3: a URI is RFC 3986, so `a%20buffer.bin` names "a buffer.bin" (main: refused with trimesh's
    FileNotFoundError). The map (pure red, as stored) colours the square; batch's inputs name the real files."""
    solid_png(tmp_path / "the map.png", (255, 0, 0))
    path = quad_gltf(tmp_path, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}},
                     buffer="a buffer.bin", uri="a%20buffer.bin", images=[{"uri": "the%20map.png"}])
    image = covered(rp.render_file(path, AMBIENT).image)
    assert len(image) > 100
    np.testing.assert_allclose(image, np.broadcast_to([1.0, 0.0, 0.0], image.shape), atol=1e-6)
    from raycast_phong.io.meshes.source import mesh_source
    source = mesh_source(path)
    assert source.side_files == (tmp_path / "a buffer.bin",) and source.images == (tmp_path / "the map.png",)


def test_an_unlit_material_is_emission_only_and_required_unlit_renders(tmp_path):
    """KHR_materials_unlit (required here; main refused the file): k_e = base colour, k_a = k_d = k_s = 0, so
    the square shows its colour whatever the lights (a light and no ambient here) — the lecture's emission."""
    colour = [0.2, 0.6, 0.4, 1.0]
    path = quad_gltf(tmp_path, {"pbrMetallicRoughness": {"baseColorFactor": colour},
                                "extensions": {"KHR_materials_unlit": {}}}, required=("KHR_materials_unlit",))
    [material] = read_mesh(path, "t").materials
    assert material.ka == material.kd == material.ks == (0.0, 0.0, 0.0)
    np.testing.assert_allclose(material.ke, colour[:3], atol=0.5 / 255)  # trimesh keeps the factor in 8 bits
    image = covered(rp.render_file(path, LIT).image)
    assert len(image) > 100
    np.testing.assert_allclose(image, np.broadcast_to(material.ke, image.shape), atol=1e-6)


def test_emissive_strength_multiplies_the_emissive_factor_and_is_clamped_to_1(tmp_path):
    material = {"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0},
                "emissiveFactor": [0.1, 0.2, 0.05],
                "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}}
    path = quad_gltf(tmp_path, material)
    np.testing.assert_allclose(read_mesh(path, "t").materials[0].ke, (0.4, 0.8, 0.2), atol=1e-12)
    material["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] = 10.0
    other = tmp_path / "other"
    other.mkdir()
    read = read_mesh(quad_gltf(other, material), "t")
    np.testing.assert_allclose(read.materials[0].ke, (1.0, 1.0, 0.5), atol=1e-12)
    assert any("clamped to 1" in note for note in read.notes), read.notes


@pytest.mark.parametrize("strength", [None, 5.0])
def test_an_emissive_factor_of_exactly_1_is_not_said_to_be_clamped(tmp_path, strength):
    """k_e's largest is 1: an emissive factor reaching exactly 1 (1 alone, or 0.2 × strength 5) is within it, read
    as it is with no note. Catches the clamp note taken at 1 rather than above it."""
    material = {"pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0},
                "emissiveFactor": [1.0, 0.5, 0.0] if strength is None else [0.2, 0.1, 0.0]}
    if strength is not None:
        material["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": strength}}
    read = read_mesh(quad_gltf(tmp_path, material), "t")
    np.testing.assert_allclose(read.materials[0].ke, (1.0, 0.5, 0.0), atol=1e-12)
    assert not any("clamped" in note for note in read.notes), read.notes


@pytest.mark.parametrize("before", [(), ("KHR_materials_unlit",)])  # the unread one first, or after one it reads
@pytest.mark.parametrize(("extension", "words"), [("KHR_texture_basisu", "KTX2 (Basis Universal) textures")])
def test_an_unsupported_required_extension_is_refused_in_the_renderer_s_words(tmp_path, extension, words, before):
    path = quad_gltf(tmp_path, {}, required=(*before, extension))
    with pytest.raises(SceneError) as caught:
        rp.render_file(path, AMBIENT)
    message = str(caught.value)
    assert f"requires the glTF extension(s) {extension} ({words})" in message and "Error" not in message, message


def quadrants_png(path: Path) -> None:
    """64×64, a colour per quadrant: top-left red, top-right green, bottom-left blue, bottom-right white."""
    from PIL import Image
    pixels = np.zeros((64, 64, 3), np.uint8)
    pixels[:32, :32], pixels[:32, 32:], pixels[32:, :32], pixels[32:, 32:] = (255, 0, 0), (0, 255, 0), (0, 0, 255), 255
    Image.fromarray(pixels).save(path)


@pytest.mark.parametrize("rotation", [0.0, math.pi / 2])
def test_a_texture_transform_moves_the_uvs_of_its_map(tmp_path, rotation):
    """KHR_texture_transform on the base colour map: scale ½ and an offset put the whole square in the map's
    top-right quadrant (glTF's v runs down from the top). Without rotation the offset is (½, 0); turned by 90°
    counter-clockwise in UV space, whose v runs down, (u, v) → (v, −u), so the offset (½, ½) does it. The wrong
    turn, (u, v) → (−v, u) as the spec's GLSL listing reads, lands in the bottom-left (blue) quadrant; no
    transform shows all four: the square is green."""
    quadrants_png(tmp_path / "quadrants.png")
    transform = {"offset": [0.5, 0.0] if rotation == 0 else [0.5, 0.5], "rotation": rotation, "scale": [0.5, 0.5]}
    info = {"index": 0, "extensions": {"KHR_texture_transform": transform}}
    path = quad_gltf(tmp_path, {"pbrMetallicRoughness": {"baseColorTexture": info, "metallicFactor": 0.0}},
                     images=[{"uri": "quadrants.png"}], required=("KHR_texture_transform",))
    read = read_mesh(path, "t")
    # Corner (u, v) of glTF's [0, 1]² → ½(u, v) turned and offset: within u ∈ [½, 1], v ∈ [0, ½] (glTF's, v down).
    glTF = 1.0 - read.corner_uv[..., 1]
    assert read.corner_uv[..., 0].min() >= 0.5 - 1e-6 and read.corner_uv[..., 0].max() <= 1 + 1e-6
    assert glTF.min() >= -1e-6 and glTF.max() <= 0.5 + 1e-6
    image = covered(rp.render_file(path, AMBIENT).image)
    # The map's quadrants meet at the square's edges (texels blend there, as the outline's pixels do): most of
    # the square is green, and none of it the other quadrants' colours.
    green = (image[:, 1] > 0.9) & (image[:, 0] < 0.1) & (image[:, 2] < 0.1)
    others = (image[:, 0] > 0.5) | (image[:, 2] > 0.5)
    assert len(image) > 100 and green.mean() > 0.8 and not others.any(), (green.mean(), others.mean())


@pytest.mark.parametrize("maps, u_range, noted", [
    ({"emissiveTexture": (0.5, 0.25)}, (0.5, 0.75), False),  # an emissive map alone: its own transform
    ({"baseColorTexture": (0.5, 0.25), "emissiveTexture": (0.0, 0.5)}, (0.5, 0.75), True),  # the base colour's
    ({"baseColorTexture": (0.5, 0.25), "emissiveTexture": (0.5, 0.25)}, (0.5, 0.75), False),  # alike: no note
    ({"baseColorTexture": (0.5, 0.25)}, (0.5, 0.75), False),  # no emissive map: nothing differs
    ({"baseColorTexture": (0.0, 1.0), "emissiveTexture": None}, (0.0, 1.0), False),  # the identity, given or not
])
def test_one_set_of_uvs_follows_the_base_colour_maps_transform_else_the_emissive_maps(tmp_path, maps, u_range,
                                                                                      noted):
    """The renderer keeps one set of texture coordinates a corner: they follow the base colour map's
    KHR_texture_transform, or the emissive map's when it is the only map; two maps transformed apart read the
    base colour's, with one note saying so (none when the other map is absent, or its transform is the identity
    given or left out). Each transform here is (offset u, scale): u' = offset + scale u, so u over [0, 1] lands
    in [offset, offset + scale]; None: no transform."""
    quadrants_png(tmp_path / "quadrants.png")
    material = {"pbrMetallicRoughness": {"metallicFactor": 0.0}, "emissiveFactor": [1, 1, 1]}
    for key, transform in maps.items():
        info = {"index": 0}
        if transform is not None:
            offset, scale = transform
            info["extensions"] = {"KHR_texture_transform": {"offset": [offset, 0], "scale": [scale, 1]}}
        (material["pbrMetallicRoughness"] if key == "baseColorTexture" else material)[key] = info
    read = read_mesh(quad_gltf(tmp_path, material, images=[{"uri": "quadrants.png"}]), "t")
    u = read.corner_uv[..., 0]
    assert (u.min(), u.max()) == pytest.approx(u_range, abs=1e-6)
    said = [note for note in read.notes if "KHR_texture_transform differs" in note]
    assert len(said) == int(noted), read.notes
    if noted:
        assert "base colour's texture coordinates are used for both" in said[0]


@pytest.mark.parametrize("transform, gltf_uv, expected", [
    # The extension's own example: offset (0, 1), rotation π/2, scale ½ reads the image's lower left quadrant.
    (((0.0, 1.0), math.pi / 2, (0.5, 0.5)), [(0, 0), (1, 0), (1, 1), (0, 1)],
     [(0, 1), (0, 0.5), (0.5, 0.5), (0.5, 1)]),
    # 09_texture_transform's 0.3 rad alone: (1, 0) → (cos 0.3, −sin 0.3), (0, 1) → (sin 0.3, cos 0.3).
    (((0.0, 0.0), 0.3, (1.0, 1.0)), [(1, 0), (0, 1)],
     [(0.955336489, -0.295520207), (0.295520207, 0.955336489)]),
    # T · R · S: scale (2, 1) first, then the turn, then the offset: (1, 0) → (2, 0) → (0, −2) → (0.25, −1.75).
    (((0.25, 0.25), math.pi / 2, (2.0, 1.0)), [(1, 0)], [(0.25, -1.75)]),
])
def test_texture_transform_turns_uvs_as_the_extensions_example_and_sample_do(transform, gltf_uv, expected):
    """KHR_texture_transform by hand, in glTF's UV coordinates (v down): u' = u cos r + v sin r, v' = −u sin r +
    v cos r, after the scale and before the offset (glTF issue #1563: the GLSL listing's sign is the wrong one,
    its example JSON and the TextureTransformTest sample the right one). transform_uv takes and gives v up."""
    from raycast_phong.io.meshes.gltf import transform_uv
    given = np.array(gltf_uv, np.float64)
    found = transform_uv(np.column_stack([given[:, 0], 1.0 - given[:, 1]]), transform)
    np.testing.assert_allclose(np.column_stack([found[:, 0], 1.0 - found[:, 1]]), expected, atol=1e-9)


def test_maps_the_phong_model_has_no_place_for_are_said_not_applied(tmp_path):
    """A normalTexture and an occlusionTexture change no Phong term: the material is drawn in its factors and a
    note names both maps and the material (the base colour map, read, is not named)."""
    solid_png(tmp_path / "map.png", (128, 128, 255))
    material = {"name": "bumpy", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
                "normalTexture": {"index": 0}, "occlusionTexture": {"index": 0}}
    found = read_mesh(quad_gltf(tmp_path, material, images=[{"uri": "map.png"}]), "t")
    said = [note for note in found.notes if "not applied" in note]
    assert len(said) == 1 and said[0].endswith("material 'bumpy': normalTexture, occlusionTexture not applied; its "
                                               "factors are used"), found.notes


def test_one_image_file_gives_a_mask_its_alpha_and_the_surface_its_colour(tmp_path):
    """alphaMode MASK with a base colour map in an image file beside the .gltf: the same file is decoded twice,
    its colour for the surface and its alpha for the mask, each kept apart (a texture bank keyed without the
    channel gave the mask the colour, cutting nothing away, or the surface the alpha). The map: red everywhere,
    alpha 0 on its left half. About half the square is drawn, all of it red."""
    from PIL import Image
    pixels = np.zeros((8, 8, 4), np.uint8)
    pixels[..., 0], pixels[:, 4:, 3] = 255, 255
    Image.fromarray(pixels, "RGBA").save(tmp_path / "half.png")
    sizes = {}
    for mode in ("OPAQUE", "MASK"):
        material = {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0},
                    "alphaMode": mode}
        image = covered(rp.render_file(quad_gltf(tmp_path, material, images=[{"uri": "half.png"}]), AMBIENT).image)
        red = (image[:, 0] > 0.5) & (image[:, 1] < 0.1) & (image[:, 2] < 0.1)
        assert red.mean() > 0.95, (mode, red.mean())
        sizes[mode] = len(image)
    assert 0.35 < sizes["MASK"] / sizes["OPAQUE"] < 0.65, sizes


@pytest.mark.parametrize("wrap_s, wrap_t", [("clamp", "repeat"), ("repeat", "clamp")])
def test_a_samplers_wrap_modes_act_each_along_its_own_axis(tmp_path, wrap_s, wrap_t):
    """glTF 2.0 §5.26: wrapS acts along u, wrapT along v. A texture transform (scale 2, offset −½) spreads the
    square's UVs over [−½, 3⁄2]²; the map's red rises with its column (0 at the left), its green with its row.
    Clamped along u, the square's left quarter (u < 0) shows the first column: no red at all; repeated, it shows
    the map's right half: red. The same of green along v in the square's top and bottom quarters: clamped, one
    row (each band's green constant down it); repeated, the rows wrap (green changes down the band). Seen head
    on, the square is square in the image and its UVs run straight along its rows and columns."""
    from PIL import Image
    ramp = np.array([0, 80, 160, 240], np.uint8)
    pixels = np.full((4, 4, 3), 255, np.uint8)  # blue throughout: the square is seen where red and green are 0
    pixels[..., 0], pixels[..., 1] = ramp[None, :], ramp[:, None]
    Image.fromarray(pixels).save(tmp_path / "ramp.png")
    transform = {"offset": [-0.5, -0.5], "scale": [2.0, 2.0]}
    info = {"index": 0, "extensions": {"KHR_texture_transform": transform}}
    path = quad_gltf(tmp_path, {"pbrMetallicRoughness": {"baseColorTexture": info, "metallicFactor": 0.0}},
                     images=[{"uri": "ramp.png"}], required=("KHR_texture_transform",))
    document = json.loads(path.read_text(encoding="utf-8"))
    codes = {"clamp": 33071, "repeat": 10497}
    document["samplers"] = [{"wrapS": codes[wrap_s], "wrapT": codes[wrap_t]}]
    document["textures"][0]["sampler"] = 0
    path.write_text(json.dumps(document), encoding="utf-8")
    head_on = ["camera.position=[0, 0, 6]", "camera.look_at=[0, 0, 0]", "camera.fov=30"]
    image = rp.render_file(path, [*AMBIENT, *head_on, "render.width=160", "render.height=120"]).image
    rows, columns = np.nonzero(image[..., 2] > 0.5)
    square = image[rows.min():rows.max() + 1, columns.min():columns.max() + 1]
    n = len(square)
    assert n > 40 and abs(square.shape[1] - n) <= 2, square.shape
    inner = slice(n * 3 // 10, n * 7 // 10)  # away from the other axis's bands
    band = slice(n // 20, n // 5)            # well inside u < 0 (columns) or v < 0 / v > 1 (rows)
    left_red = square[inner, band, 0]
    if wrap_s == "clamp":
        assert left_red.max() < 1e-6, left_red.max()
    else:
        assert left_red.min() > 0.2, left_red.min()
    for rows_of_band in (square[band, inner, 1], square[-band.stop:-band.start, inner, 1]):
        change = np.ptp(rows_of_band, axis=0).min()  # down the band, in each column
        assert change < 1e-6 if wrap_t == "clamp" else change > 0.02, (wrap_t, change)
