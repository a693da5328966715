"""Texture mapping (issue 20, item 1): wrap modes, sRGB decoding, mip pyramids and level choice, the
modulation of k_a and k_d (specular untextured), and a textured plane held to its closed form."""

from __future__ import annotations

import numpy as np
import OpenImageIO as oiio
import pytest

import raycast_phong as rp
from raycast_phong.errors import SceneError
from raycast_phong.io.textures import decode_file, srgb_to_linear
from raycast_phong.records import Texture
from raycast_phong.renderer.kernels.layout import WRAP_CLAMP, WRAP_MIRROR, WRAP_REPEAT
from raycast_phong.renderer.kernels.texture import sample, wrap
from raycast_phong.renderer.pack import mip_pyramid, pack_textures
from raycast_phong.tools.reference import ramp, textured_plane_colour


def write_png(path, rgb8: np.ndarray) -> None:
    h, w = rgb8.shape[:2]
    buffer = oiio.ImageBuf(oiio.ImageSpec(w, h, 3, oiio.UINT8))
    buffer.set_pixels(oiio.ROI(0, w, 0, h, 0, 1, 0, 3), np.ascontiguousarray(rgb8, np.uint8))
    assert buffer.write(str(path))


def row_texture(values, mode: str):
    """A 4 × 1 texture whose red channel is `values`, packed as the kernel reads it."""
    pixels = np.zeros((1, len(values), 3), np.float32)
    pixels[0, :, 0] = values
    return pack_textures((Texture(pixels, mode, mode, "row"),))


@pytest.mark.parametrize("mode, expected", [("repeat", (10 + 20) / 2), ("clamp", 40.0), ("mirror", (40 + 30) / 2)])
def test_wrap_modes_at_u_1_25_hand_computed(mode, expected):
    """u = 1.25 on 4 texels: x = 1.25·4 − 0.5 = 4.5, halfway between texels 4 and 5. Repeat reads texels 0
    and 1, clamp texel 3 twice, mirror texels 3 and 2 (the reversed copy)."""
    texels, table = row_texture([10.0, 20.0, 30.0, 40.0], mode)
    r, _, _ = sample(texels, table, 0, 1.25, 0.5, 1.0)
    assert r == pytest.approx(expected, abs=1e-4)


def test_wrap_function_by_hand():
    assert [wrap(i, 4, WRAP_REPEAT) for i in (-1, 4, 5)] == [3, 0, 1]
    assert [wrap(i, 4, WRAP_CLAMP) for i in (-1, 4, 5)] == [0, 3, 3]
    assert [wrap(i, 4, WRAP_MIRROR) for i in (-1, 4, 5, 8)] == [0, 3, 2, 0]


def test_an_srgb_texel_of_188_decodes_to_half_in_linear_colour_and_stays_188_in_display(tmp_path):
    assert float(srgb_to_linear(188 / 255)) == pytest.approx(0.5029, abs=1e-4)
    write_png(tmp_path / "t.png", np.full((2, 2, 3), 188, np.uint8))
    np.testing.assert_allclose(decode_file(tmp_path / "t.png", "linear"), 0.5029, atol=1e-4)
    np.testing.assert_array_equal(decode_file(tmp_path / "t.png", "display"), np.float32(188 / 255))


def test_every_mip_level_of_a_linear_ramp_is_the_same_function_of_uv():
    """A 2 × 2 box mean of a linear function is its value at the block's centre, so sampling a ramp at
    (u, v) gives the same value on every level (away from the wrap seam)."""
    n = 16
    y, x = np.mgrid[0:n, 0:n]
    u, v = (x + 0.5) / n, 1 - (y + 0.5) / n
    pixels = np.stack([0.2 + 0.6 * u, 0.1 + 0.5 * v, 0.3 + 0.2 * u + 0.3 * v], axis=-1).astype(np.float32)
    levels = mip_pyramid(pixels)
    assert [level.shape[0] for level in levels] == [16, 8, 4, 2, 1]
    texels, table = pack_textures((Texture(pixels, "clamp", "clamp", "ramp"),))
    for footprint in (1.0, 2.0, 3.0, 4.0, 6.0):
        got = sample(texels, table, 0, 0.4, 0.6, footprint)
        np.testing.assert_allclose(got, [0.2 + 0.6 * 0.4, 0.1 + 0.5 * 0.6, 0.3 + 0.2 * 0.4 + 0.3 * 0.6], atol=1e-5)


def checker_scene(tmp_path, distance: float, **material) -> dict:
    n = 256
    y, x = np.mgrid[0:n, 0:n]
    checker = np.where(((x + y) % 2)[..., None] == 1, 255, 0).astype(np.uint8).repeat(3, axis=2)
    write_png(tmp_path / "checker.png", checker)
    return {"ambient": [0, 0, 0], "render": {"width": 64, "height": 64, "shading": "flat", "specular": "phong"},
            "camera": {"position": [0, distance, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "fov": 20},
            "lights": [{"type": "directional", "direction": [0, -1, 0], "diffuse": [1, 1, 1], "specular": [0, 0, 0]}],
            "materials": {"c": {"kd": [1, 1, 1], "ks": [0, 0, 0], "kd_map": "checker.png", **material}},
            "objects": [{"shape": "plane", "size": [1, 1], "material": "c"}]}


def test_a_far_checker_averages_to_its_mean_instead_of_aliasing(tmp_path):
    """A 256² one-texel checker on a plane seen at 64 pixels: every pixel covers many texels, so the coarse
    mip level answers the checker's mean (linear 0.5), not a pattern of 0s and 1s."""
    image = rp.render(rp.validate_scene(checker_scene(tmp_path, 10.0), folder=tmp_path)).image
    covered = image[..., 0] > 0.01
    values = image[covered][:, 0]
    assert covered.sum() > 20
    assert values.std() < 0.05 and values.mean() == pytest.approx(0.5, abs=0.05)


def test_the_texture_modulates_ambient_and_diffuse_not_specular(tmp_path):
    """A black texture (0 everywhere): ambient and diffuse vanish, the white highlight stays."""
    write_png(tmp_path / "black.png", np.zeros((4, 4, 3), np.uint8))
    scene = rp.validate_scene({
        "ambient": [0.3, 0.3, 0.3], "output": {"aovs": ["ambient", "diffuse", "specular"]},
        "render": {"width": 48, "height": 48, "shading": "phong"},
        "camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov": 40},
        "lights": [{"type": "point", "position": [0, 0, 5]}],
        "materials": {"m": {"kd_map": "black.png", "ks": [1, 1, 1]}},
        "objects": [{"shape": "uv_sphere", "material": "m"}]}, folder=tmp_path)
    result = rp.render(scene)
    assert result.aovs["ambient"].max() == 0 and result.aovs["diffuse"].max() == 0
    assert result.aovs["specular"].max() > 0.5


@pytest.mark.parametrize("shading", ["flat", "gouraud", "phong"])
def test_a_textured_plane_matches_its_closed_form(tmp_path, shading):
    """An orthographic camera straight above a plane lit head-on: every model gives k_d·ramp(u, v)·I_d + I_a
    k_a·ramp(u, v) at every pixel (the normal is constant), with the ramp a linear function of the texel
    centres, which bilinear filtering and every mip level reproduce. tools/reference.py has the closed form;
    the tolerance is float32 rounding of the texel values (8-bit sRGB is avoided: the texture is an EXR)."""
    n = 32
    y, x = np.mgrid[0:n, 0:n]
    u, v = (x + 0.5) / n, 1 - (y + 0.5) / n
    pixels = ramp(u, v).astype(np.float32)
    buffer = oiio.ImageBuf(oiio.ImageSpec(n, n, 3, oiio.FLOAT))
    buffer.set_pixels(oiio.ROI(0, n, 0, n, 0, 1, 0, 3), np.ascontiguousarray(pixels))
    assert buffer.write(str(tmp_path / "ramp.exr"))
    size = 64
    scene = rp.validate_scene({
        "ambient": [0.2, 0.2, 0.2], "render": {"width": size, "height": size, "shading": shading,
                                               "specular": "phong"},
        "camera": {"type": "orthographic", "position": [0, 5, 0], "look_at": [0, 0, 0], "up": [0, 0, -1],
                   "view_height": 1.0},
        "lights": [{"type": "directional", "direction": [0, -1, 0], "diffuse": [1, 1, 1], "specular": [0, 0, 0]}],
        "materials": {"r": {"ka": [0.5, 0.5, 0.5], "kd": [0.8, 0.7, 0.6], "ks": [0, 0, 0],
                            "kd_map": {"path": "ramp.exr", "wrap": "clamp"}}},
        "objects": [{"shape": "plane", "size": [1, 1], "material": "r"}]}, folder=tmp_path)
    image = rp.render(scene).image
    centre = (np.arange(size) + 0.5) / size
    pu, pv = np.meshgrid(centre, 1 - centre)  # image column → u (x right), image row → v (−z up)
    expected = textured_plane_colour(pu, pv, kd=(0.8, 0.7, 0.6), ka=(0.5, 0.5, 0.5), ambient=0.2, diffuse=1.0)
    inner = slice(2, -2)  # away from the plane's edge pixels
    np.testing.assert_allclose(image[inner, inner], expected[inner, inner], atol=2e-5)


def test_a_missing_or_broken_scene_texture_is_one_line(tmp_path):
    (tmp_path / "notimage.png").write_text("hello")
    (tmp_path / "truncated.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 10)  # its format's bytes, then nothing
    for name, words in (("gone.png", "no such texture file"), ("notimage.png", "is not a PNG file: it starts with"),
                        ("truncated.png", "cannot be read as an image")):
        scene = rp.validate_scene({"materials": {"m": {"kd_map": name}},
                                   "objects": [{"shape": "plane", "material": "m"}]}, folder=tmp_path)
        with pytest.raises(SceneError) as error:
            rp.render(scene)
        assert words in str(error.value) and "materials.m.kd_map" in str(error.value)
        assert "\n" not in str(error.value)


def test_a_texture_that_is_a_fifo_device_or_folder_is_refused_without_waiting(tmp_path):
    """A FIFO as kd_map blocked in the memory estimate's header read (PIL.Image.open) before the decode's
    is_file check, which then called a FIFO, a device or a folder "no such texture file". Now the estimate
    skips it and the decode refuses it by its kind, in one line; a subprocess with a timeout, as a FIFO
    that blocks would hang the test itself."""
    import os
    import subprocess
    import sys
    os.mkfifo(tmp_path / "pipe.png")
    (tmp_path / "folder.png").mkdir()
    for name, kind in (("pipe.png", "a named pipe (FIFO)"), ("/dev/zero", "a device"), ("folder.png", "a folder")):
        scene = tmp_path / "s.toml"
        scene.write_text(f'[materials.m]\nkd_map = "{name}"\n[[objects]]\nshape = "plane"\nmaterial = "m"\n')
        done = subprocess.run([sys.executable, "-m", "raycast_phong.cli", "render", str(scene), "-o",
                               str(tmp_path / "out.png"), "--width", "8", "--height", "8"], capture_output=True,
                              text=True, timeout=120, stdin=subprocess.DEVNULL)
        assert done.returncode == 2, done.stderr
        assert done.stderr.count("\n") == 1 and "materials.m.kd_map" in done.stderr, done.stderr
        assert f"is {kind}, not a regular file" in done.stderr and "no such texture" not in done.stderr
    assert not (tmp_path / "out.png").exists()


def test_a_float_map_with_nan_inf_or_negative_texels_gives_a_finite_non_negative_image(tmp_path):
    """An EXR map's NaN, ±inf and negative texels (through a scene's kd_map) made NaN, inf and negative pixels.
    A map multiplies a coefficient in [0, 1]: its texels are clamped to [0, 1] (NaN and −inf to 0, +inf to 1)."""
    texels = np.array([[np.nan, np.inf], [-np.inf, -3.0]], np.float32)[:, :, None].repeat(3, axis=2)
    buffer = oiio.ImageBuf(oiio.ImageSpec(2, 2, 3, oiio.FLOAT))
    buffer.set_pixels(oiio.ROI(0, 2, 0, 2, 0, 1, 0, 3), np.ascontiguousarray(texels))
    assert buffer.write(str(tmp_path / "bad.exr"))
    for colour in ("display", "linear"):  # a float map's values are linear, used as stored in both
        np.testing.assert_array_equal(decode_file(tmp_path / "bad.exr", colour)[:, :, 0], [[0, 1], [0, 0]])
    scene = rp.validate_scene({"render": {"width": 16, "height": 16}, "camera": {"position": [0, 3, 0.5]},
                               "lights": [{"position": [0, 3, 1]}],
                               "materials": {"m": {"kd_map": "bad.exr"}},
                               "objects": [{"shape": "plane", "material": "m"}]}, folder=tmp_path)
    image = rp.render(scene).image
    assert np.isfinite(image).all() and image.min() >= 0 and image.max() > 0


def ramp_exr(path, n: int = 64) -> None:
    y, x = np.mgrid[0:n, 0:n]
    pixels = ramp((x + 0.5) / n, 1 - (y + 0.5) / n).astype(np.float32)
    buffer = oiio.ImageBuf(oiio.ImageSpec(n, n, 3, oiio.FLOAT))
    buffer.set_pixels(oiio.ROI(0, n, 0, n, 0, 1, 0, 3), np.ascontiguousarray(pixels))
    assert buffer.write(str(path))


def test_a_textured_sphere_matches_the_analytic_reference(tmp_path):
    """A uv_sphere of 256 × 128 segments with a ramp k_a map, ambient light only, against
    reference.textured_ambient_reference (the exact sphere hit, u = longitude/2π, v = latitude). The
    renderer interpolates UVs linearly over flat triangles: within one triangle u and v are off by at most
    one segment step (1/512 in u, 1/128 in v), so the colour by at most 0.6/512 + 0.5/128 (the ramp's
    slopes) ≈ 0.005; float32 adds nothing comparable. Away from the seam (u within 0.02 of 0 or 1), the
    poles (v beyond 0.1 of them) and the texture's clamped edge texels."""
    from raycast_phong.tools.reference import exact_uv, textured_ambient_reference
    ramp_exr(tmp_path / "ramp.exr")
    ka = (0.9, 0.8, 0.7)
    scene = rp.validate_scene({
        "ambient": [1, 1, 1], "render": {"width": 96, "height": 96, "shading": "phong", "specular": "phong"},
        "camera": {"position": [0, -4, 0.5], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov": 35},
        "materials": {"r": {"ka": list(ka), "kd": [0, 0, 0], "ks": [0, 0, 0],
                            "ka_map": {"path": "ramp.exr", "wrap": "clamp"}}},
        "objects": [{"shape": "uv_sphere", "segments": [128, 256], "material": "r"}]}, folder=tmp_path)
    image = rp.render(scene).image
    expected, u = textured_ambient_reference(scene, ka)
    inside = np.isfinite(u) & (u > 0.02) & (u < 0.98)
    # Keep whole pixels of the sphere only (the silhouette's pixels may hit one and not the other).
    inside[[0, -1], :] = inside[:, [0, -1]] = False
    inside &= np.roll(inside, 1, 0) & np.roll(inside, -1, 0) & np.roll(inside, 1, 1) & np.roll(inside, -1, 1)
    assert inside.sum() > 2000
    np.testing.assert_allclose(image[inside], expected[inside], atol=0.6 / 512 + 0.5 / 128)
    assert exact_uv("sphere", np.array([[0.0, 1.0, 0.0]]))[0] == pytest.approx([0.25, 0.5])


def test_supersampling_filters_a_texture_as_the_finer_image_does(tmp_path):
    """render.samples = 2 casts the rays of a render at twice the size, and each sample's texture footprint is that
    render's pixel (the mip level follows the samples' spacing, not the pixel's): the image is the mean of the 2×2
    blocks of the 2× render, on a noise texture whose every mip level differs. Catches a footprint of the whole
    pixel (a level too coarse with supersampling)."""
    rng = np.random.default_rng(5)
    write_png(tmp_path / "noise.png", rng.integers(0, 256, (256, 256, 3), dtype=np.uint8))
    scene = checker_scene(tmp_path, 2.5)
    scene["materials"]["c"]["kd_map"] = "noise.png"

    def render(size, samples):
        return rp.render(rp.validate_scene({**scene, "render": {**scene["render"], "width": size, "height": size,
                                                                 "samples": samples}}, folder=tmp_path)).image
    coarse, fine = render(32, 2), render(64, 1)
    np.testing.assert_allclose(coarse, fine.reshape(32, 2, 32, 2, 3).mean(axis=(1, 3)), atol=1e-6)
