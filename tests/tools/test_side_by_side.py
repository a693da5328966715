"""`raycast-phong side-by-side`: one scene rendered per value of a key, composed, measured, and written.

Each variant is also rendered on its own here, so the tests check the composed image against the
renderer, not against the comparison code: panel pixels, heat-map zeros, the printed statistics and
the EXR parts are compared value for value.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import write_tiny_scene
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app
from raycast_phong.io import image_io
from raycast_phong.io.encoding import to_8bit
from raycast_phong.tools import compare, difference

runner = CliRunner()

SHADINGS = ["flat", "gouraud", "phong"]
# The Layout docstring for 3 panels of 48×32: f = clamp(round(32 / 10), 10, 32) = 10, g = 5, s = 15, b = 10.
COLUMNS = [5, 58, 111]  # g + i·(W + g)
ROWS = {"labels": 5, "variants": 20, "difference_labels": 57, "differences": 72, "bar": 109, "scale": 119}
SIZE = (3 * 48 + 4 * 5, 2 * 32 + 3 * 15 + 10 + 4 * 5)  # (n·W + (n + 1)·g, 2H + 3s + b + 4g) = (164, 139)
BACKDROP8 = round(compare.BACKDROP * 255)  # the grey between panels, as a PNG byte: 46


pytestmark = pytest.mark.usefixtures("in_tmp_path")


@pytest.fixture
def tiny_scene(tmp_path) -> Path:
    return write_tiny_scene(tmp_path, 48, 32)


def render_alone(scene: Path, *overrides: str) -> np.ndarray:
    """One variant rendered on its own: (H, W, 3) float32 linear."""
    return rp.render(rp.load_scene(scene, list(overrides))).image


def run(*args: str):
    result = runner.invoke(app, ["side-by-side", *args])
    assert result.exit_code == 0, result.output
    return result


def panel(image: np.ndarray, row: str, index: int, width: int = 48, height: int = 32) -> np.ndarray:
    y, x = ROWS[row], COLUMNS[index]
    return image[y:y + height, x:x + width]


def png_bytes(path: Path) -> np.ndarray:
    """An 8-bit image as its (H, W, 3) uint8 values."""
    return np.round(rp.read_image(path)[0] * 255).astype(np.uint8)


# ---------------------------------------------------------------- layout and panels

def test_layout_places_every_band_as_documented():
    grid = compare.layout(3, 48, 32)
    assert (grid.font, grid.gap, grid.strip, grid.bar) == (10, 5, 15, 10)
    assert (grid.image_width, grid.image_height) == SIZE
    assert [grid.column(i) for i in range(3)] == COLUMNS
    assert grid.rows == ROWS
    # A large panel: f = round(360 / 10) = 36, capped at 32; g = 16, s = 48, b = 32.
    big = compare.layout(2, 960, 360)
    assert (big.font, big.gap, big.strip, big.bar) == (32, 16, 48, 32)
    assert (big.image_width, big.image_height) == (2 * 960 + 3 * 16, 2 * 360 + 3 * 48 + 32 + 4 * 16)


def test_png_panels_are_the_variants_in_order(tiny_scene, tmp_path):
    run(str(tiny_scene), "--vary", "render.shading=flat,gouraud,phong", "-o", "cmp.png")
    composed = png_bytes(tmp_path / "cmp.png")
    assert composed.shape == (SIZE[1], SIZE[0], 3)
    variants = [render_alone(tiny_scene, f"render.shading={model}") for model in SHADINGS]
    assert not np.array_equal(variants[0], variants[1]) and not np.array_equal(variants[1], variants[2])
    for index, variant in enumerate(variants):
        np.testing.assert_array_equal(panel(composed, "variants", index), to_8bit(variant))
    # The gap left of the first panel and between panels is backdrop, untouched by any panel.
    np.testing.assert_array_equal(composed[ROWS["variants"]:ROWS["variants"] + 32, [0, 4, 53, 57, 106, 110]],
                                  BACKDROP8)


def test_exr_output_holds_the_exact_variants_as_parts(tiny_scene, tmp_path):
    result = run(str(tiny_scene), "--vary", "render.shading=flat,gouraud,phong", "-o", "cmp.exr")
    path = tmp_path / "cmp.exr"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cmp.exr", "tiny.toml"]  # no sibling, no temporaries
    assert f"exact variants in {Path('cmp.exr')}" in result.stdout
    composed = rp.read_layer(path)
    assert composed.shape == (SIZE[1], SIZE[0], 3)
    for index, model in enumerate(SHADINGS):
        variant = render_alone(tiny_scene, f"render.shading={model}")
        np.testing.assert_array_equal(rp.read_layer(path, f"variant{index}"), variant)
        np.testing.assert_array_equal(panel(composed, "variants", index), variant)  # linear, unclamped
        _pixels, names = rp.read_image(path, part=index + 1)
        assert names == (f"variant{index}.R", f"variant{index}.G", f"variant{index}.B")
        # Each part's data window sits over its panel in the composed image's display window.
        spec = oiio.ImageBuf(str(path), index + 1, 0).spec()
        assert (spec.x, spec.y, spec.width, spec.height) == (COLUMNS[index], ROWS["variants"], 48, 32)
        assert (spec.full_width, spec.full_height) == SIZE


def test_a_png_gets_the_variants_in_a_sibling_exr(tiny_scene, tmp_path):
    run(str(tiny_scene), "--vary", "render.shading=flat,phong", "--width", "20", "--height", "10", "-o", "c.png")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c-variants.exr", "c.png", "tiny.toml"]
    sibling = tmp_path / "c-variants.exr"
    for index, model in enumerate(["flat", "phong"]):
        variant = render_alone(tiny_scene, "render.width=20", "render.height=10", f"render.shading={model}")
        assert variant.shape == (10, 20, 3)  # --width/--height reached every variant
        np.testing.assert_array_equal(rp.read_layer(sibling, f"variant{index}"), variant)
    # The sibling's main image is the composed image, unclamped: its bytes are the PNG's.
    np.testing.assert_array_equal(to_8bit(rp.read_layer(sibling)), png_bytes(tmp_path / "c.png"))


# ---------------------------------------------------------------- labels

def label_strip(image: np.ndarray, row: str, index: int) -> np.ndarray:
    y, x = ROWS[row], COLUMNS[index]
    return image[y:y + 15, x:x + 48]


def test_labels_are_drawn_in_their_strips(tiny_scene, tmp_path):
    run(str(tiny_scene), "--vary", "render.shading=flat,gouraud,phong", "-o", "cmp.png")
    composed = png_bytes(tmp_path / "cmp.png")
    for row in ("labels", "difference_labels"):
        for index in range(3):
            strip = label_strip(composed, row, index)
            assert strip.max() > 200 and strip.min() == BACKDROP8, (row, index)  # white text on the backdrop
    # The scale strip: "0" at the left end, the maximum at the right end.
    scale = composed[ROWS["scale"]:ROWS["scale"] + 15, 5:159]
    assert scale[:, :10].max() > 200 and scale[:, -10:].max() > 200
    # Different values give different labels (48 px panels: the short wording, the value alone).
    assert not np.array_equal(label_strip(composed, "labels", 0), label_strip(composed, "labels", 1))


def test_without_a_font_the_image_has_blank_label_strips_and_a_warning(tiny_scene, tmp_path, monkeypatch):
    """What a machine without OpenImageIO's fonts gets (seen for real with the font folders hidden)."""
    monkeypatch.setattr(image_io, "LABEL_FONTS", ("NoSuchFont",))
    result = run(str(tiny_scene), "--vary", "render.shading=flat,phong", "-o", "cmp.png")
    assert "warning: the image has no labels" in result.output
    composed = png_bytes(tmp_path / "cmp.png")
    for row in ("labels", "difference_labels"):
        np.testing.assert_array_equal(label_strip(composed, row, 0), BACKDROP8)
    np.testing.assert_array_equal(composed[ROWS["scale"]:ROWS["scale"] + 15], BACKDROP8)


# ---------------------------------------------------------------- differences and statistics

def test_difference_panels_are_zero_exactly_where_the_variants_agree(tiny_scene, tmp_path):
    run(str(tiny_scene), "--vary", "render.shading=flat,gouraud,phong", "-o", "cmp.exr")
    composed = rp.read_layer(tmp_path / "cmp.exr")
    flat, phong = (render_alone(tiny_scene, f"render.shading={m}") for m in ("flat", "phong"))
    changed = np.abs(flat - phong).max(axis=2) > 0
    assert 0.05 < changed.mean() < 0.6  # the sphere's pixels differ; the background does not
    black = difference.colour_map(0.0)
    heat = panel(composed, "differences", 0)
    np.testing.assert_array_equal(heat[~changed], np.broadcast_to(black, heat[~changed].shape))
    assert (np.abs(heat[changed] - black).max(axis=1) > 0).all()
    # The reference compared with itself: all zero.
    np.testing.assert_array_equal(panel(composed, "differences", 2), np.broadcast_to(black, (32, 48, 3)))


def test_a_key_that_changes_nothing_gives_zero_statistics_and_a_note(tiny_scene, tmp_path):
    result = run(str(tiny_scene), "--vary", "render.two_sided=true,true", "-o", "same.exr")
    lines = result.stdout.splitlines()
    assert lines[0] == ("render.two_sided = true    0.00% of pixels changed (> 1e-06), mean 0, max 0 "
                        "against render.two_sided = true")
    assert lines[1] == "render.two_sided = true    0.00% of pixels changed (> 1e-06), mean 0, max 0 (the reference)"
    assert "note: all 2 variants are identical: render.two_sided changes nothing" in result.output
    composed = rp.read_layer(tmp_path / "same.exr")
    for index in range(2):
        np.testing.assert_array_equal(panel(composed, "differences", index),
                                      np.broadcast_to(difference.colour_map(0.0), (32, 48, 3)))


def test_printed_statistics_for_a_background_change(tiny_scene):
    """Background 0 against 0.25: exactly the background pixels change, each by 0.25 in every channel."""
    result = run(str(tiny_scene), "--vary", "render.background=0,0.25", "-o", "bg.png")
    image = render_alone(tiny_scene)  # black background; the sphere is lit (ambient 0.1), so never exactly 0
    background = (image == 0).all(axis=2).mean()
    assert 0.3 < background < 0.9
    first, last, summary = result.stdout.splitlines()
    assert first == (f"render.background = 0     {background:7.2%} of pixels changed (> 1e-06), "
                     f"mean {0.25 * background:.4g}, max 0.25 against render.background = 0.25")
    assert last == "render.background = 0.25    0.00% of pixels changed (> 1e-06), mean 0, max 0 (the reference)"
    # Two panels: 2·48 + 3·5 = 111 wide, as tall as three (139).
    assert summary == f"{Path('bg.png')}: 2 variants of 48×32 and their differences, 111×139; exact variants in " \
                      f"{Path('bg-variants.exr')}"


def test_statistics_of_one_difference():
    a = np.zeros((2, 2, 3), np.float32)
    b = a.copy()
    b[0, 0] = [0.1, -0.4, 0.2]  # max over RGB of |a − b| = 0.4
    b[1, 1, 2] = 5e-7           # below the threshold: not "changed", still in the mean
    diff = difference.difference(a, b)
    np.testing.assert_allclose(diff, [[0.4, 0], [0, 5e-7]], rtol=1e-6)
    stats = compare.measure(diff)
    assert stats.changed == 0.25
    assert stats.mean == pytest.approx((0.4 + 5e-7) / 4, rel=1e-6)
    assert stats.max == pytest.approx(0.4, rel=1e-6)


def test_difference_keeps_float64_renders_in_float64():
    a = np.zeros((1, 1, 3))
    b = a + 1e-9  # lost in float32 next to a value of 1, kept in float64
    assert difference.difference(a + 1, b + 1).dtype == np.float64
    assert difference.difference(a + 1, b + 1)[0, 0] == pytest.approx(1e-9, rel=1e-6)
    assert difference.difference(a.astype(np.float32), b.astype(np.float32)).dtype == np.float32


def test_colour_map_runs_from_black_to_pale_yellow_with_rising_lightness():
    t = np.linspace(0, 1, 256)
    colours = difference.colour_map(t)
    np.testing.assert_allclose(colours[0], difference.INFERNO[0])
    np.testing.assert_allclose(colours[-1], difference.INFERNO[-1])
    luma = colours @ np.array([0.2126, 0.7152, 0.0722], np.float32)  # Rec. 709 weights
    assert (np.diff(luma) > 0).all()
    np.testing.assert_array_equal(difference.colour_map(np.array([-1.0, 2.0])), difference.INFERNO[[0, -1]])  # clamped


# ---------------------------------------------------------------- --vary

@pytest.mark.parametrize(("text", "key", "values"), [
    ("render.shading=flat,gouraud,phong", "render.shading", ["flat", "gouraud", "phong"]),
    ("materials.clay.shininess=8, 64, 512", "materials.clay.shininess", ["8", "64", "512"]),
    ("lights.0.position=[1,2,3],[3,2,1]", "lights.0.position", ["[1,2,3]", "[3,2,1]"]),
    ('lights.0.attenuation="none",[1, 0.5, 0.25]', "lights.0.attenuation", ['"none"', "[1, 0.5, 0.25]"]),
    ('objects.0.name="a,b",c', "objects.0.name", ['"a,b"', "c"]),
    ("objects.0.name='a,b',c", "objects.0.name", ["'a,b'", "c"]),  # a TOML literal string quotes its comma too
])
def test_vary_splits_at_top_level_commas(text, key, values):
    assert compare.parse_vary(text) == (key, values)


@pytest.mark.parametrize(("vary", "expected"), [
    ("render.shadng=flat,phong", ["render.shadng: unknown key", "did you mean 'shading'"]),
    ("render.shading=flat,blurry", ["render.shading:", "blurry"]),
    ("render.shading=flat", ["--vary render.shading: needs at least 2 values"]),
    ("render.shading", ["--vary 'render.shading': expected KEY.PATH=V1,V2"]),
    ("=flat,phong", ["--vary '=flat,phong': expected KEY.PATH=V1,V2"]),
    ("render.shading=flat,,phong", ["--vary render.shading: value 2 of 3 is empty"]),
    ("lights.0.position=[1,2,3],[3,2", ["--vary lights.0.position: cannot split", "unclosed bracket"]),
    ("objects.5.subdivisions=1,2", ["--vary 'objects.5.subdivisions=1'", "objects.5", "allowed indices: 0"]),
    ("render.width=32,48", ["--vary render.width: the variants must share one image size", "32 → 32×32"]),
])
def test_bad_vary_exits_2_with_one_line_naming_the_key(tiny_scene, tmp_path, vary, expected):
    output = tmp_path / "cmp.png"
    output.write_bytes(b"an earlier image")
    result = runner.invoke(app, ["side-by-side", str(tiny_scene), "--vary", vary, "-o", str(output)])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    for part in expected:
        assert part in lines[0], lines[0]
    assert output.read_bytes() == b"an earlier image"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cmp.png", "tiny.toml"]


def test_bad_set_and_bad_output_exit_2(tiny_scene):
    bad_set = runner.invoke(app, ["side-by-side", str(tiny_scene), "--vary", "render.shading=flat,phong",
                                  "--set", "render.samples=0"])
    assert bad_set.exit_code == 2 and "render.samples: out of range" in bad_set.output, bad_set.output
    bad_output = runner.invoke(app, ["side-by-side", str(tiny_scene), "--vary", "render.shading=flat,phong",
                                     "-o", "cmp.jpg"])
    assert bad_output.exit_code == 2 and "must end in .png" in bad_output.output, bad_output.output


def test_internal_error_exits_1_with_one_line(tiny_scene, tmp_path, monkeypatch):
    def broken_render(*args, **kwargs):
        raise RuntimeError("kernel exploded")
    monkeypatch.setattr(rp.Renderer, "render", broken_render)  # the command's session renders its variants
    result = runner.invoke(app, ["side-by-side", str(tiny_scene), "--vary", "render.shading=flat,phong"])
    assert result.exit_code == 1, result.output
    [line] = result.output.strip().splitlines()
    assert line.startswith("error: internal error: RuntimeError: kernel exploded (traceback in ")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tiny.toml"]


def test_help_has_examples():
    result = runner.invoke(app, ["side-by-side", "--help"])
    assert result.exit_code == 0, result.output
    assert "Examples" in result.output
    assert "raycast-phong side-by-side scenes/specular.toml --vary" in result.output
    assert "NAME-variants.exr" in result.output  # where a PNG's exact variants go


def test_variants_held_at_the_budget_are_refused_at_the_scene_one_byte_under_it_they_fit(tiny_scene):
    """render_budget: N variants of W×H pixels hold N·W·H·HELD_BYTES_PER_PIXEL bytes; a budget of exactly that
    leaves nothing for the renders and is refused in one line starting with the scene's file, a byte more
    leaves that byte to each render."""
    scenes = [rp.load_scene(tiny_scene, [f"render.shading={model}"]) for model in ("flat", "phong", "gouraud")]
    render = scenes[0].render
    held = 3 * render.width * render.height * compare.HELD_BYTES_PER_PIXEL
    assert compare.render_budget(scenes, held + 1) == 1
    assert compare.render_budget(scenes, None) is None
    with pytest.raises(rp.SceneError) as refused:
        compare.render_budget(scenes, held)
    assert str(refused.value).startswith(f"{tiny_scene}: --vary: 3 variants of {render.width}×{render.height} ")


def test_a_difference_map_is_scaled_to_the_largest_finite_difference_and_draws_a_nan_at_the_top():
    """difference_map (compare --diff, docs/batch.md): black for 0 to pale yellow for the largest finite
    difference (1.0 here, so 0.5 is the middle of the scale, inferno's sixth stop), and a pixel whose difference
    is NaN (inf − inf) pale yellow too, not black."""
    a = np.zeros((1, 4, 3), np.float32)
    b = np.zeros((1, 4, 3), np.float32)
    b[0, 1, 2], b[0, 2, 0] = 0.5, 1.0
    a[0, 3], b[0, 3] = np.inf, np.inf
    shown = difference.difference_map(a, b)
    np.testing.assert_allclose(shown[0, 0], difference.INFERNO[0], atol=1e-6)
    np.testing.assert_allclose(shown[0, 1], difference.INFERNO[5], atol=1e-6)
    np.testing.assert_allclose(shown[0, 2], difference.INFERNO[-1], atol=1e-6)
    np.testing.assert_allclose(shown[0, 3], difference.INFERNO[-1], atol=1e-6)
