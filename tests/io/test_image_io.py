"""PNG and EXR output: encoding, layers, atomic replacement, permissions."""

import os
import stat
from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.io.encoding import srgb_encode, to_8bit


def test_png_is_clamped_8bit_without_gamma(tmp_path):
    image = np.array([[[0.0, 0.5, 1.0], [-0.2, 1.7, 0.25]]], np.float32)
    path = rp.write_image(tmp_path / "x.png", image)
    back, names = rp.read_image(path)
    assert names == ("R", "G", "B")
    expected = np.array([[[0, 128, 255], [0, 255, 64]]]) / 255  # round(0.5·255) = 128, round(0.25·255) = 64
    np.testing.assert_allclose(back, expected, atol=1e-6)


def test_linear_colour_encodes_a_png_with_the_srgb_curve(tmp_path):
    image = np.full((1, 2, 3), 0.5, np.float32)
    back, _ = rp.read_image(rp.write_image(tmp_path / "s.png", image, colour="linear"))
    # sRGB(0.5) = 1.055 · 0.5^(1/2.4) − 0.055 = 0.7354 → byte 188.
    assert srgb_encode(np.float32(0.5)) == pytest.approx(0.735357, abs=1e-5)
    np.testing.assert_allclose(back, 188 / 255, atol=1e-6)


def test_to_8bit_never_wraps_and_bands_agree_with_one_pass():
    rng = np.random.default_rng(1)
    image = rng.uniform(-2, 3, size=(600, 7, 3)).astype(np.float32)
    banded = to_8bit(image, rows_per_band=256)
    assert banded.dtype == np.uint8
    np.testing.assert_array_equal(banded, np.round(np.clip(image, 0, 1) * 255).astype(np.uint8))


def test_exr_keeps_values_unclamped_with_named_layers(tmp_path):
    image = np.array([[[0.0, 2.5, 1e4]]], np.float32)
    layers = {"depth": np.array([[[3.25]]], np.float32), "specular": np.array([[[0.1, 0.2, 0.3]]], np.float32)}
    path = rp.write_image(tmp_path / "x.exr", image, layers)
    np.testing.assert_array_equal(rp.read_layer(path), image)
    np.testing.assert_array_equal(rp.read_layer(path, "depth"), layers["depth"])
    np.testing.assert_array_equal(rp.read_layer(path, "specular"), layers["specular"])
    with pytest.raises(rp.ImageError, match="no layer 'normal'"):
        rp.read_layer(path, "normal")


def test_a_strided_array_writes_as_png(tmp_path):
    """A view with strides (such as a layer cut from a multi-channel EXR) still writes real pixels."""
    wide = np.linspace(0, 1, 4 * 5 * 6, dtype=np.float32).reshape(4, 5, 6)
    view = wide[:, :, ::2]
    back, _ = rp.read_image(rp.write_image(tmp_path / "v.png", view))
    np.testing.assert_allclose(back, np.round(view * 255) / 255, atol=1e-6)


def test_written_image_has_umask_permissions_and_no_temporary_left(tmp_path):
    old = os.umask(0o022)
    try:
        path = rp.write_image(tmp_path / "p.png", np.zeros((2, 2, 3), np.float32))
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.png"]


def test_failed_write_leaves_the_old_image(tmp_path):
    path = tmp_path / "keep.png"
    path.write_bytes(b"old image")
    with pytest.raises(rp.ImageError):
        rp.write_image(path, np.zeros((2, 2, 3), np.float32), {"depth": np.zeros((2, 2, 1), np.float32)})
    assert path.read_bytes() == b"old image"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.png"]


def test_exr_parts_keep_their_own_size_and_place(tmp_path):
    """Extra parts (multi-part EXR) of another size than the image, each at its (x, y) in the image."""
    image = np.zeros((4, 6, 3), np.float32)
    small = np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3)
    path = rp.write_image(tmp_path / "p.exr", image, parts={"left": (small, (1, 2)), "right": (small + 100, (3, 0))})
    np.testing.assert_array_equal(rp.read_layer(path), image)
    np.testing.assert_array_equal(rp.read_layer(path, "left"), small)
    np.testing.assert_array_equal(rp.read_layer(path, "right"), small + 100)
    assert rp.read_image(path, part=2)[1] == ("right.R", "right.G", "right.B")
    with pytest.raises(rp.ImageError, match=r"no layer 'middle'; channels are R, G, B, left.R, .*right.B"):
        rp.read_layer(path, "middle")
    with pytest.raises(rp.ImageError, match=r"need an \.exr output"):
        rp.write_image(tmp_path / "p.png", image, parts={"left": (small, (0, 0))})
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.exr"]


def test_text_coverage_is_one_line_of_text_or_none_without_a_font(monkeypatch):
    from raycast_phong.io import image_io
    wide, narrow = image_io.text_coverage("render.shading = flat", 12), image_io.text_coverage("flat", 12)
    assert wide.dtype == np.float32 and 0.0 <= wide.min() and wide.max() <= 1.0 and wide.max() > 0.9
    assert wide.shape[0] == narrow.shape[0]  # one line height for any text, so labels share a baseline
    assert wide.shape[1] > 3 * narrow.shape[1]
    monkeypatch.setattr(image_io, "LABEL_FONTS", ("NoSuchFont",))
    assert image_io.label_font() is None
    assert image_io.text_coverage("flat", 12) is None


@pytest.mark.parametrize("image, got", [
    (np.zeros((10, 10)), "an array of shape (10, 10) and dtype float64"),
    (np.zeros((4, 4, 4), np.float32), "an array of shape (4, 4, 4) and dtype float32"),
    (np.zeros((0, 5, 3)), "an array of shape (0, 5, 3)"),
    (np.zeros((2, 2, 3), complex), "dtype complex128"),
    ("pixels.png", "a str"),
])
def test_write_image_says_what_shape_it_wants(tmp_path, image, got):
    """Issue 34 item 4: rp.write_image("g.png", np.zeros((10, 10))) failed unpacking a shape; now one line says
    what it takes and what it got, and no file is written."""
    with pytest.raises(ValueError) as raised:
        rp.write_image(tmp_path / "g.png", image)
    assert str(raised.value).startswith("write_image: the image must be an (H, W, 3) array of real RGB values")
    assert got in str(raised.value) and not (tmp_path / "g.png").exists()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
@pytest.mark.parametrize("colour", ["display", "linear"])
def test_eight_bit_values_are_clamped_rounded_and_nan_is_zero(dtype, colour):
    """to_8bit (the live view's every frame) gives the bytes of the plain formula written here: clamp to [0, 1], a
    NaN 0, ±inf clamped, the sRGB curve for "linear", × 255 rounded to nearest even, in float32; ties included."""
    rng = np.random.default_rng(7)
    image = rng.normal(0.5, 0.6, (300, 257, 3)).astype(dtype)
    flat = image.reshape(-1)
    flat[::5] = (np.arange(flat.size)[::5] % 256 + 0.5) / 255  # halfway between two bytes
    flat[::97], flat[::101], flat[::103], flat[::107] = np.nan, np.inf, -np.inf, -0.0
    values = image.astype(np.float32)
    values = np.nan_to_num(np.clip(srgb_encode(values) if colour == "linear" else values, 0.0, 1.0), nan=0.0)
    np.testing.assert_array_equal(to_8bit(image, colour, rows_per_band=64), np.round(values * 255.0).astype(np.uint8))


def test_read_image_checks_its_budget_from_the_header_before_decoding(tmp_path, monkeypatch):
    """A 1 MB PNG may hold 20000² pixels: the read weighs width × height × channels × (two float32 copies and
    the file's own values, 9 bytes for 8-bit) first. 2000 × 1000 RGB 8-bit: 54 MB."""
    from raycast_phong.io import system
    path = tmp_path / "wide.png"
    rp.write_image(path, np.zeros((1000, 2000, 3), np.float32))
    refusal = r"2000×1000 image of 3 channel.*over the budget.*max_memory"
    with pytest.raises(rp.errors.ImageError, match=refusal) as refused:
        rp.read_image(path, max_memory=50_000_000)
    assert "\n" not in str(refused.value)
    pixels, names = rp.read_image(path, max_memory=60_000_000)
    assert pixels.shape == (1000, 2000, 3) and names == ("R", "G", "B")
    monkeypatch.setattr(system, "default_budget", lambda: 50_000_000)  # no max_memory: the commands' budget
    with pytest.raises(rp.errors.ImageError, match="over the budget"):
        rp.read_image(path)


def test_read_image_without_a_budget_refuses_what_decodes_to_over_1000_times_its_file(tmp_path, monkeypatch):
    """A decompression bomb (a 1 MB PNG of 20000² pixels: 10 GB; issue 50) is refused from its header when the
    caller gives no budget, though the commands' budget (a share of the machine) would allow it. The floor is
    lowered here to 1 MB so that 1000 × 2000 pixels stand for it: of zeros (the file is a few kB, over 1000×) it
    is refused, and read with max_memory; of noise (a file of 6 MB, 9×) it is read."""
    from raycast_phong.io import image_io
    monkeypatch.setattr(image_io, "BOMB_FLOOR", 1 << 20)
    flat = rp.write_image(tmp_path / "flat.png", np.zeros((1000, 2000, 3), np.float32))
    with pytest.raises(rp.errors.ImageError, match=r"over 1,000× its size, as a decompression bomb's.*max_memory"):
        rp.read_image(flat)
    assert rp.read_image(flat, max_memory="1G")[0].shape == (1000, 2000, 3)
    with pytest.raises(rp.errors.ImageError, match="decompression bomb"):
        rp.read_layer(flat)
    assert rp.read_layer(flat, max_memory="1G").shape == (1000, 2000, 3)  # read_layer passes its budget on
    noise = np.random.default_rng(3).random((1000, 2000, 3)).astype(np.float32)
    assert rp.read_image(rp.write_image(tmp_path / "noise.png", noise))[0].shape == (1000, 2000, 3)


def test_a_read_whose_need_is_exactly_the_budget_is_made(tmp_path):
    """The budget is the most the read may use: 100 × 50 RGB 8-bit needs 100 × 50 × 3 × 9 = 135,000 bytes, read
    under a budget of exactly that, refused one byte under it."""
    path = rp.write_image(tmp_path / "small.png", np.zeros((50, 100, 3), np.float32))
    pixels, _ = rp.read_image(path, max_memory=135_000)
    assert pixels.shape == (50, 100, 3)
    with pytest.raises(rp.errors.ImageError, match="needs about 132 kB to read, over the budget"):
        rp.read_image(path, max_memory=134_999)


def test_an_output_path_as_long_as_path_max_is_refused_and_one_byte_shorter_is_not(tmp_path):
    """PATH_MAX counts the terminating NUL (POSIX), so a path of exactly PATH_MAX bytes is one open() refuses
    with ENAMETOOLONG: the check refuses it before rendering, and lets one byte less through."""
    from raycast_phong.errors import ImageError
    from raycast_phong.io.files import _check_name_length
    limit = os.pathconf(tmp_path, "PC_PATH_MAX")

    def path_of(length: int) -> Path:
        """ "/ddd…" folders of 200 bytes, then the rest, then "/x.png": `length` bytes in all."""
        folders, rest = divmod(length - len("/x.png"), 200)
        assert rest >= 2, rest  # a last folder of one byte or more after its "/"
        return Path(("/" + "d" * 199) * folders + "/" + "d" * (rest - 1) + "/x.png")

    assert len(os.fsencode(str(path_of(limit)))) == limit
    with pytest.raises(ImageError, match=f"path is {limit:,} bytes, longer than the {limit:,}"):
        _check_name_length(path_of(limit), tmp_path)
    _check_name_length(path_of(limit - 1), tmp_path)


def test_a_file_name_is_measured_in_bytes_not_characters(tmp_path):
    """NAME_MAX is bytes: 200 "é" and ".png" are 404 bytes in UTF-8, over the 255 most file systems allow,
    though only 204 characters; 125 "é" (254 bytes with ".png") pass, and the file system takes them."""
    from raycast_phong.errors import ImageError
    from raycast_phong.io.files import _check_name_length
    with pytest.raises(ImageError, match="file name is 404 bytes, longer than the"):
        _check_name_length(tmp_path / ("é" * 200 + ".png"), tmp_path)
    _check_name_length(tmp_path / ("é" * 125 + ".png"), tmp_path)
    assert len(os.fsencode("é" * 125 + ".png")) == 254 and len(("é" * 200 + ".png").encode()) == 404
    assert os.pathconf(tmp_path, "PC_NAME_MAX") < 404
    (tmp_path / ("é" * 125 + ".png")).write_bytes(b"")


def test_a_file_name_of_exactly_name_max_bytes_is_allowed_and_one_more_is_not(tmp_path):
    """NAME_MAX is the longest name the file system takes: a name of exactly that many bytes passes (and is
    written), one byte more is refused naming the file name; in a path also too long, the path is named, since
    the name is within its limit."""
    from raycast_phong.errors import ImageError
    from raycast_phong.io.files import _check_name_length
    limit = os.pathconf(tmp_path, "PC_NAME_MAX")
    name = "n" * (limit - 4) + ".png"
    _check_name_length(tmp_path / name, tmp_path)
    (tmp_path / name).write_bytes(b"")
    with pytest.raises(ImageError, match=f"file name is {limit + 1:,} bytes, longer than the {limit:,}"):
        _check_name_length(tmp_path / ("n" + name), tmp_path)
    too_long = Path(("/" + "d" * 199) * (os.pathconf(tmp_path, "PC_PATH_MAX") // 200)) / name
    with pytest.raises(ImageError, match="the output's path is"):
        _check_name_length(too_long, tmp_path)


def test_images_read_together_are_weighed_together(tmp_path):
    """compare reads both images: each alone fits the budget, the two together do not, so it is refused
    (10 × 10 × 3 samples at 4 bytes: 1,200 bytes each, 2,400 both, against 2,000)."""
    from raycast_phong.errors import ImageError
    from raycast_phong.io.image_io import check_image_reads
    a, b = (rp.write_image(tmp_path / f"{name}.png", np.zeros((10, 10, 3), np.float32)) for name in "ab")
    check_image_reads((a,), 2_000, 4)
    check_image_reads((b,), 2_000, 4)
    with pytest.raises(ImageError, match=r"reading the images needs ≈ 2\.34 kB"):
        check_image_reads((a, b), 2_000, 4)
    check_image_reads((a, b), 2_400, 4)


def test_a_multi_part_exr_cut_short_in_its_last_part_is_not_whole(tmp_path):
    """The writer's close can lose its last flush without saying so (see io.image_io._complete): every part's
    last scanline is read back, so a file whose last part lost its last bytes is not taken as written, though
    its first part reads whole."""
    import OpenImageIO as oiio

    from raycast_phong.io.image_io import _complete
    image = np.random.default_rng(2).uniform(size=(32, 48, 3)).astype(np.float32)
    part = np.random.default_rng(3).uniform(size=(16, 16, 3)).astype(np.float32)
    path = rp.write_image(tmp_path / "p.exr", image, parts={"extra": (part, (0, 0))})
    assert _complete(str(path), 2)
    data = path.read_bytes()
    path.write_bytes(data[:-8])
    first = oiio.ImageInput.open(str(path))
    spec = first.spec()
    assert first.read_scanline(spec.y + spec.height - 1, 0, oiio.FLOAT) is not None  # part 0 still reads
    first.close()
    assert not _complete(str(path), 2)


def test_a_missing_image_is_said_to_be_missing_once(tmp_path):
    """OpenImageIO says 'Could not open file: Could not open file "x.png"'; a missing image is "no such file",
    from read_image and from compare (both files checked by the same rule)."""
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    from raycast_phong.errors import ImageError
    missing = tmp_path / "missing.png"
    with pytest.raises(ImageError) as refused:
        rp.read_image(missing)
    assert str(refused.value) == f"{missing}: no such file"
    present = rp.write_image(tmp_path / "present.png", np.zeros((2, 2, 3), np.float32))
    for args in ([missing, present], [present, missing]):
        done = CliRunner().invoke(app, ["compare", *map(str, args)])
        assert done.exit_code == 2 and done.output.strip() == f"error: {missing}: no such file", done.output


def test_images_over_the_read_budget_are_refused_naming_the_largest(tmp_path):
    """check_image_reads refuses images whose headers need more than the budget, in one line naming the
    image that needs the most (the one to shrink): of a 2×2 and a 6×4 PNG, the 6×4 one."""
    from raycast_phong.errors import ImageError
    from raycast_phong.io.image_io import check_image_reads, write_image
    small, large = tmp_path / "small.png", tmp_path / "large.png"
    write_image(small, np.zeros((2, 2, 3), np.float32))
    write_image(large, np.zeros((4, 6, 3), np.float32))
    with pytest.raises(ImageError) as caught:
        check_image_reads((small, large), budget=1, per_sample=4)
    assert str(caught.value).startswith(f"{large}: its header says 6×4 pixels with 3 channels")


def test_a_label_exactly_as_wide_as_its_room_fits_at_its_size_and_at_the_least_size():
    """fitting_size keeps a size at which the text is at most the width: text drawn exactly as wide as the room
    keeps that size, including at MIN_FONT, the least it tries; a pixel less room at MIN_FONT fits nothing."""
    from raycast_phong.io.labels import MIN_FONT, fitting_size, text_coverage
    text = "shading=flat"
    assert MIN_FONT == 8
    if text_coverage(text, 20) is None:
        pytest.skip("no font to draw labels with")
    wide = text_coverage(text, 20).shape[1]
    assert fitting_size(text, 20, wide) == 20
    least = text_coverage(text, MIN_FONT).shape[1]
    assert fitting_size(text, MIN_FONT, least) == MIN_FONT
    assert fitting_size(text, MIN_FONT, least - 1) is None


def test_an_rgba_png_is_read_as_stored_by_the_api_and_by_the_oracle(tmp_path):
    """A PNG's alpha is straight: rp.read_image gives the colour bytes / 255 beside the alpha, and the analytic
    reference's own map reading (tools/reference.read_map) the same colour, as the renderer's map decode does.
    OpenImageIO's default multiplies the colour by the alpha: 200 with alpha 40 read as 0.1216, not 0.7843."""
    from PIL import Image

    from raycast_phong.tools.reference import read_map
    pixels = np.zeros((2, 3, 4), np.uint8)
    pixels[...] = (200, 100, 50, 40)
    Image.fromarray(pixels, "RGBA").save(tmp_path / "a.png")
    read, names = rp.read_image(tmp_path / "a.png")
    assert names == ("R", "G", "B", "A")
    np.testing.assert_allclose(read[0, 0], np.array([200, 100, 50, 40]) / 255, atol=1e-6)
    np.testing.assert_allclose(read_map(tmp_path / "a.png", "display")[0, 0], np.array([200, 100, 50]) / 255,
                               atol=1e-6)
