"""Colour maps read from files (issue 20, items 1 and 7): wrap modes from .mtl options and glTF samplers,
UV seams kept through the merge of repeated points, unused maps never decoded, and the memory term."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.geometry.build import build_geometry
from raycast_phong.io.meshes.gltf import gltf_samplers
from raycast_phong.io.meshes.mtl import parse_mtl
from raycast_phong.io.meshes.source import read_mesh

MODELS = Path(__file__).resolve().parents[1] / "data" / "models"


def test_mtl_maps_register_their_file_and_clamp_option(tmp_path):
    (tmp_path / "a.png").write_bytes(b"x")
    sources: list = []
    notes: list[str] = []
    found = parse_mtl("newmtl m\nmap_Kd -clamp on a.png\nmap_Ke a.png\nmap_Ks a.png\n", tmp_path / "m.mtl",
                      notes, sources)
    m = found["m"]
    assert [(s.source.name, s.wrap_s, s.wrap_t) for s in sources] == [("a.png", "clamp", "clamp"),
                                                                      ("a.png", "repeat", "repeat")]
    assert (m.ka_map, m.kd_map, m.ke_map) == (-1, 0, 1)
    assert any("not applied: map_ks a.png" in n for n in notes), notes


def test_gltf_sampler_codes_become_wrap_modes():
    document = {"samplers": [{"wrapS": 33071, "wrapT": 33648}, {}],
                "textures": [{"sampler": 0, "source": 0}, {"sampler": 1, "source": 0}, {"source": 0}],
                "materials": [{"name": "a", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
                               "emissiveTexture": {"index": 1}},
                              {"name": "b", "pbrMetallicRoughness": {"baseColorTexture": {"index": 2}}}]}
    assert gltf_samplers(document) == {("a", "baseColorTexture"): ("clamp", "mirror"),
                                        ("a", "emissiveTexture"): ("repeat", "repeat"),
                                        ("b", "baseColorTexture"): ("repeat", "repeat")}


def test_uv_seams_survive_the_merge_of_repeated_points(tmp_path):
    """normals = "mean" merges the file's repeated points; the UVs are per corner, taken before, so a seam
    (one point, two UVs) keeps both."""
    for name in ("fuze.obj", "fuze.obj.mtl", "fuze uv.jpg"):
        shutil.copy(MODELS / name, tmp_path / name)
    read = read_mesh(tmp_path / "fuze.obj", "x")
    scene = rp.load_scene(tmp_path / "fuze.obj", ["objects.0.normals=\"mean\""])
    geometry = build_geometry(scene)
    assert len(geometry.vertices) < 3 * len(geometry.faces)  # merged
    np.testing.assert_array_equal(geometry.corner_uv, read.corner_uv)
    # Some merged vertex has corners with different UVs: a seam.
    flat_uv = geometry.corner_uv.reshape(-1, 2)
    vertex = geometry.faces.reshape(-1)
    order = np.lexsort((flat_uv[:, 1], flat_uv[:, 0], vertex))
    same_vertex = vertex[order][1:] == vertex[order][:-1]
    differs = (flat_uv[order][1:] != flat_uv[order][:-1]).any(axis=1)
    assert (same_vertex & differs).any()


def test_a_mesh_painted_by_a_scene_material_decodes_none_of_its_maps(tmp_path, monkeypatch):
    import raycast_phong.io.textures as textures
    calls = []
    monkeypatch.setattr(textures, "decode_pil",
                        lambda image, colour, channel="rgb": calls.append(image) or np.zeros((1, 1, 3), np.float32))
    (tmp_path / "s.toml").write_text(f'[materials.plain]\nkd = [0.5, 0.5, 0.5]\n[[objects]]\nshape = "mesh"\n'
                                     f'path = "{MODELS / "BoxTextured.glb"}"\nmaterial = "plain"\n')
    geometry = build_geometry(rp.load_scene(tmp_path / "s.toml"))
    assert calls == [] and geometry.textures == ()
    build_geometry(rp.load_scene(MODELS / "BoxTextured.glb"))
    assert len(calls) == 1


def test_the_memory_estimate_counts_the_maps_a_file_names():
    from raycast_phong.io.textures import TEXTURE_BYTES_PER_TEXEL
    from raycast_phong.renderer.budget import estimate_memory
    assert estimate_memory(rp.load_scene(MODELS / "fuze.obj")).textures == TEXTURE_BYTES_PER_TEXEL * 1024 * 1024
    assert estimate_memory(rp.load_scene("scenes/default.toml" if Path("scenes/default.toml").is_file()
                                         else MODELS.parents[2] / "scenes" / "default.toml")).textures == 0


def test_gltf_color_0_beside_a_material_multiplies_its_factor(tmp_path):
    """glTF: baseColor = factor × texture × COLOR_0. A factor (0.5, 1, 1) with random COLOR_0 per vertex, lit
    by ambient only (k_a = base colour): the red channel never exceeds 0.5 while green reaches near 1, and the
    corner colours are COLOR_0 at each face's corners (on main: a note, and the factor alone)."""
    import trimesh
    mesh = trimesh.creation.icosphere(subdivisions=2)
    mesh.visual = trimesh.visual.TextureVisuals(material=trimesh.visual.material.PBRMaterial(
        name="half", baseColorFactor=[128, 255, 255, 255], metallicFactor=0.0, roughnessFactor=1.0))
    colours = np.random.default_rng(0).integers(0, 256, (len(mesh.vertices), 4)).astype(np.uint8)
    mesh.visual.vertex_attributes["color"] = colours
    mesh.export(tmp_path / "painted.glb")
    read = read_mesh(tmp_path / "painted.glb", "x")
    np.testing.assert_allclose(read.corner_colour, colours[:, :3][mesh.faces] / 255, atol=1e-6)
    image = rp.render_file(tmp_path / "painted.glb", ["render.width=120", "render.height=90", "ambient=[1, 1, 1]",
                                                      "lights=[]"]).image
    covered = image.max(axis=-1) > 0
    assert image[covered][:, 0].max() <= 128 / 255 + 1e-6 and image[covered][:, 1].max() > 0.8


def test_a_large_map_is_shrunk_while_it_is_read_so_its_decode_stays_in_the_estimate(tmp_path):
    """A 420 kB PNG of 12000² peaked at 1 GB while decoded at full size and shrunk after (issue 30, item 3; 871 MB
    above the imports measured here). Now it is read a band of rows at a time, box-filtered to MAX_TEXTURE_SIZE,
    and put through the sRGB curve a band at a time: here an 8000² PNG (a left half 64/255, a right half 255) in
    a process of its own peaks within the memory estimate's term for it plus one band (the old code: ~770 MB of
    float texels at full size), and the result is the box filter's: the halves' colours."""
    import subprocess
    import sys

    import OpenImageIO as oiio
    import pytest

    from raycast_phong.io.textures import DECODE_BAND_BYTES, srgb_to_linear, texture_bytes
    if not Path("/proc/self/clear_refs").exists():
        pytest.skip("measures the peak with Linux's /proc/self/clear_refs and VmHWM")
    path, side = tmp_path / "big.png", 8000
    output = oiio.ImageOutput.create(str(path))
    assert output.open(str(path), oiio.ImageSpec(side, side, 3, oiio.UINT8))
    row = np.zeros((side, 3), np.uint8)
    row[: side // 2], row[side // 2:] = 64, 255
    for y in range(side):
        assert output.write_scanline(y, 0, row)
    assert output.close()
    probe = ("import sys, numpy as np; from pathlib import Path; from raycast_phong.io.textures import decode_file; "
             "import OpenImageIO\n"
             "def kb(name):\n"
             "    return next(int(line.split()[1]) for line in open('/proc/self/status') if line.startswith(name))\n"
             "open('/proc/self/clear_refs', 'w').write('5'); before = kb('VmRSS')\n"
             "t = decode_file(Path(sys.argv[1]), 'linear'); np.save(sys.argv[2], t)\n"
             "print((kb('VmHWM') - before) * 1024)\n")
    done = subprocess.run([sys.executable, "-c", probe, str(path), str(tmp_path / "t.npy")], capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    texels = np.load(tmp_path / "t.npy")
    assert texels.shape == (2048, 2048, 3)
    assert int(done.stdout) < texture_bytes([(side, side)]) + DECODE_BAND_BYTES, int(done.stdout) >> 20
    np.testing.assert_allclose(texels[:, :1023], srgb_to_linear(64 / 255), rtol=1e-6)
    np.testing.assert_allclose(texels[:, 1025:], 1.0, rtol=1e-6)


def test_a_large_maps_header_is_read_without_pils_bomb_warning(tmp_path, monkeypatch, recwarn):
    """The memory estimate reads a map's header with PIL, which warned (a multi-line DecompressionBombWarning on
    stderr) for a map of more than 89M pixels; the decode shrinks such a map in bands, so the header read says
    nothing. PIL's limit is lowered here to stand for a 12000² map."""
    from PIL import Image

    from raycast_phong.io.textures import file_size
    monkeypatch.setattr(Image, "MAX_IMAGE_PIXELS", 1000)
    rp.write_image(tmp_path / "m.png", np.zeros((40, 50, 3), np.float32))  # 2000 pixels: past the limit, not 2×
    assert file_size(tmp_path / "m.png") == (40, 50)
    assert not [w for w in recwarn if issubclass(w.category, Image.DecompressionBombWarning)]


def test_a_long_map_name_is_shown_by_its_start_and_end_in_one_short_line(tmp_path):
    """Issue 30 item 10: a 4,000-character map name (a note for an MTL's map_Kd, an error for a scene's kd_map)
    was echoed whole (a 5,047-character line); now its first and last 50 characters and the count left out. The
    name is 3,227 characters, so under a deep temporary folder the whole path stays below PATH_MAX (4,096): with
    4,011 it failed as "too long" in the mutation script's folder, not as the missing file it is."""
    import pytest

    from raycast_phong.errors import SceneError
    name = "d" * 200 + "/" + ("e" * 200 + "/") * 15 + "missing.png"
    (tmp_path / "l.mtl").write_text(f"newmtl m\nmap_Kd {name}\n")
    (tmp_path / "l.obj").write_text("mtllib l.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl m\n"
                                    "f 1/1 2/2 3/3\n")
    notes = read_mesh(tmp_path / "l.obj", "l.obj").notes
    [note] = [n for n in notes if "missing.png" in n]
    assert len(note) < 300 and "'dddd" in note and "/missing.png' is missing" in note, note
    assert f"{len(repr(name)) - 100:,} characters" in note
    (tmp_path / "l.toml").write_text(f'[materials.m]\nkd_map = "{name}"\n[[objects]]\nshape = "plane"\n'
                                     'material = "m"\n')
    with pytest.raises(SceneError) as refused:
        rp.render(rp.load_scene(tmp_path / "l.toml", ["render.width=8", "render.height=8"]))
    said = str(refused.value)  # it starts with the scene file's path, as long as the temporary folder's
    assert len(said) - len(str(tmp_path)) < 300 and "/missing.png'" in said, said


def test_a_palette_map_with_byte_transparency_decodes_without_pil_s_warning(tmp_path, recwarn):
    """PIL warns in two lines on stderr that such an image 'should be converted to RGBA' (issue 45): the colour
    is what is read, so the advice is not passed on."""
    from PIL import Image

    from raycast_phong.io.textures import decode_pil
    image = Image.new("P", (4, 4))
    image.putpalette([255, 0, 0] * 256)
    image.save(tmp_path / "p.png", transparency=bytes([0, 128, 255]))
    with Image.open(tmp_path / "p.png") as opened:
        pixels = decode_pil(opened, "display")
    assert np.allclose(pixels, [1, 0, 0]) and not [w for w in recwarn if "Palette" in str(w.message)]


def _write(path: Path, pixels: np.ndarray, kind) -> Path:
    """An image file of `pixels` (H, W, C) written by OpenImageIO as `kind` (oiio.UINT8, oiio.FLOAT)."""
    import OpenImageIO as oiio
    output = oiio.ImageOutput.create(str(path))
    assert output.open(str(path), oiio.ImageSpec(pixels.shape[1], pixels.shape[0], pixels.shape[2], kind))
    assert output.write_image(pixels) and output.close()
    return path


def test_a_float_map_is_linear_already_and_an_8_bit_map_is_decoded_from_srgb(tmp_path):
    """render.colour = "linear": an 8-bit PNG of 188, 64, 255 becomes 0.5029, 0.0513, 1 (IEC 61966-2-1,
    ((c + 0.055) / 1.055)^2.4 by hand), a float EXR of 0.5, 0.2, 0.04 stays so; "display" keeps both as stored
    (188 / 255 = 0.7373). Catches the float map put through the sRGB curve too (0.5 → 0.214) and the curve applied
    under the wrong mode."""
    import OpenImageIO as oiio
    png = _write(tmp_path / "m.png", np.array([[[188, 64, 255]]] * 2, np.uint8), oiio.UINT8)
    exr = _write(tmp_path / "m.exr", np.array([[[0.5, 0.2, 0.04]]] * 2, np.float32), oiio.FLOAT)
    expected = {("linear", "png"): [0.5029, 0.0513, 1.0], ("linear", "exr"): [0.5, 0.2, 0.04],
                ("display", "png"): [188 / 255, 64 / 255, 1.0], ("display", "exr"): [0.5, 0.2, 0.04]}
    for colour in ("linear", "display"):
        (tmp_path / "s.toml").write_text(
            f'[render]\ncolour = "{colour}"\n[materials.a]\nkd_map = "{png.name}"\n[materials.b]\nkd_map = '
            f'"{exr.name}"\n[[objects]]\nshape = "plane"\nmaterial = "a"\n[[objects]]\nshape = "plane"\n'
            'material = "b"\ntranslate = [3, 0, 0]\n')
        textures = build_geometry(rp.load_scene(tmp_path / "s.toml")).textures
        found = {Path(texture.name).suffix[1:]: texture.pixels for texture in textures}
        for kind in ("png", "exr"):
            np.testing.assert_allclose(found[kind], np.broadcast_to(expected[colour, kind], (2, 1, 3)), atol=1e-4,
                                       err_msg=f"{kind} under {colour}")


def test_a_long_map_is_shrunk_to_2048_on_its_longer_side_keeping_its_shape(tmp_path):
    """An 8192 × 1024 map (an embedded image, opened lazily as a glTF's or 3MF's is; and a file) is decoded at
    2048 × 256, a quarter on each side, as the memory estimate weighs it (52 B a texel); a box or thumbnail filter
    keeps a uniform colour. Catches a shrink rule that goes too far (or not at all) on a non-square map."""
    import io

    import OpenImageIO as oiio
    from PIL import Image

    from raycast_phong.io.textures import decode_file, decode_pil, texture_bytes
    pixels = np.full((1024, 8192, 3), (200, 100, 50), np.uint8)
    embedded = io.BytesIO()
    Image.fromarray(pixels).save(embedded, "PNG")
    with Image.open(io.BytesIO(embedded.getvalue())) as image:
        shrunk = decode_pil(image, "display")
    assert shrunk.shape == (256, 2048, 3)
    np.testing.assert_allclose(shrunk, np.broadcast_to([200 / 255, 100 / 255, 50 / 255], shrunk.shape), atol=1e-6)
    read = decode_file(_write(tmp_path / "long.png", pixels, oiio.UINT8), "display")
    assert read.shape == (256, 2048, 3)
    np.testing.assert_allclose(read, np.broadcast_to([200 / 255, 100 / 255, 50 / 255], read.shape), atol=1e-6)
    assert texture_bytes([(1024, 8192)]) == 256 * 2048 * 52


def test_the_memory_estimate_skips_a_map_that_is_missing_or_unreadable(tmp_path):
    """file_size gives None (no size to weigh; the decode words the problem) for a map that is missing, a
    folder, or a file it may not open, instead of raising from the memory estimate."""
    import os

    from raycast_phong.io.textures import file_size
    assert file_size(tmp_path / "missing.png") is None
    assert file_size(tmp_path) is None
    rp.write_image(tmp_path / "shut.png", np.zeros((4, 6, 3), np.float32))
    assert file_size(tmp_path / "shut.png") == (4, 6)
    if os.geteuid() != 0:  # root opens anything
        (tmp_path / "shut.png").chmod(0)
        assert file_size(tmp_path / "shut.png") is None


def test_an_alpha_map_is_the_last_channel_of_a_grey_and_alpha_image_as_of_an_rgba_one(tmp_path):
    """A map's alpha (glTF's baseColorTexture for MASK and BLEND, an OBJ's map_d) is its last channel when the
    image has one: RGBA and grey + alpha (LA) alike; an RGB or grey image has none (alpha 1). Values by hand:
    alpha 0, 128 and 255 of an 8-bit image, as PIL and OpenImageIO store them."""
    from PIL import Image

    from raycast_phong.io.textures import decode_file, decode_pil
    alpha = np.array([[0, 128, 255]], np.uint8)
    grey = np.full_like(alpha, 200)
    images = {"LA": np.stack([grey, alpha], axis=2), "RGBA": np.stack([grey, grey, grey, alpha], axis=2),
              "L": grey, "RGB": np.stack([grey] * 3, axis=2)}
    for mode, pixels in images.items():
        image = Image.fromarray(pixels, mode)
        image.save(tmp_path / f"{mode}.png")
        expected = alpha / 255 if mode in ("LA", "RGBA") else np.ones(alpha.shape)
        for decoded in (decode_file(tmp_path / f"{mode}.png", "display", "alpha"),
                        decode_pil(image, "display", "alpha")):
            np.testing.assert_allclose(decoded[..., 0], expected, atol=1e-6, err_msg=mode)
            assert (decoded[..., 0] == decoded[..., 2]).all()


def test_a_half_float_map_is_linear_already_like_any_float_map(tmp_path):
    """A half-float EXR holds linear values as a float EXR does: under render.colour = linear its texels are used
    as stored (0.5 stays 0.5, not the sRGB decode's 0.2140), and clamped to [0, 1] with NaN and -inf made 0 and
    +inf 1. Read as 8-bit, the NaN would be kept and 0.5 decoded from sRGB: a wrong map and NaN pixels."""
    import OpenImageIO as oiio

    from raycast_phong.io.textures import decode_file
    path = tmp_path / "half.exr"
    pixels = np.array([[[0.5, 0.5, 0.5], [2.0, 0.25, -1.0], [np.nan, -np.inf, np.inf]]], np.float32)
    output = oiio.ImageOutput.create(str(path))
    assert output.open(str(path), oiio.ImageSpec(3, 1, 3, oiio.HALF))
    assert output.write_image(pixels) and output.close()
    expected = np.array([[[0.5, 0.5, 0.5], [1.0, 0.25, 0.0], [0.0, 0.0, 1.0]]], np.float32)  # 0.5, 0.25 exact in half
    for colour in ("linear", "display"):
        np.testing.assert_array_equal(decode_file(path, colour), expected)


def test_the_memory_estimate_checks_and_counts_every_map_key_of_a_material(tmp_path):
    """texture_estimate weighs ka_map, kd_map and ke_map alike: a material whose only map is an emission map of
    64 × 32 texels costs TEXTURE_BYTES_PER_TEXEL × 64 × 32 = 106,496 bytes, and a missing ke_map file is refused
    by the estimate, before anything is decoded, as a missing kd_map is."""
    from raycast_phong.errors import SceneError
    from raycast_phong.io.textures import TEXTURE_BYTES_PER_TEXEL
    from raycast_phong.renderer.budget import estimate_memory
    rp.write_image(tmp_path / "glow.png", np.zeros((32, 64, 3), np.float32))
    scene = tmp_path / "glow.toml"
    for name in ("glow.png", "missing.png"):
        scene.write_text(f'[materials.glow]\nke_map = "{name}"\n\n[[objects]]\nshape = "box"\nmaterial = "glow"\n')
        if name == "glow.png":
            assert TEXTURE_BYTES_PER_TEXEL * 64 * 32 == 106_496
            assert estimate_memory(rp.load_scene(scene)).textures == 106_496
        else:
            with pytest.raises(SceneError, match=r"materials\.glow\.ke_map.*no such texture file 'missing\.png'|"
                                                 r"no such texture file .*missing\.png"):
                estimate_memory(rp.load_scene(scene))


def test_a_maps_colour_is_read_as_stored_beside_any_alpha(tmp_path):
    """A grey (L), grey + alpha (LA) or RGBA PNG as a colour map: the grey is red, green and blue alike, and the
    colour is the stored one whatever the alpha (PNG's alpha is straight; a cut-out's edge texels keep their
    colour), as PIL decodes the same image embedded in a GLB. 200 decoded from sRGB by hand:
    ((200/255 + 0.055) / 1.055)^2.4 = 0.5776; as stored, 200/255 = 0.7843. Catches OpenImageIO's default of
    multiplying the colour by the alpha (40/255: 0.1216), grey left in red only, or LA read as two colours."""
    from PIL import Image

    from raycast_phong.io.textures import decode_file, decode_pil
    grey, alpha = np.full((2, 3), 200, np.uint8), np.full((2, 3), 40, np.uint8)
    images = {"L": grey, "LA": np.stack([grey, alpha], axis=2), "RGBA": np.stack([grey, grey, grey, alpha], axis=2)}
    for mode, pixels in images.items():
        Image.fromarray(pixels, mode).save(tmp_path / f"{mode}.png")
        for colour, value in (("linear", 0.5776), ("display", 200 / 255)):
            with Image.open(tmp_path / f"{mode}.png") as image:
                for decoded in (decode_file(tmp_path / f"{mode}.png", colour), decode_pil(image, colour)):
                    assert decoded.shape == (2, 3, 3)
                    np.testing.assert_allclose(decoded, value, atol=1e-4, err_msg=f"{mode} under {colour}")
