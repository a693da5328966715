"""render.colour (issue 33, "Colour by default"): one setting decides how 8-bit colour maps are decoded and
how a PNG is encoded. "display" (the scene files' default) shows a map at its own brightness times the
lighting; "linear" (glTF's, the default of a glTF file rendered directly) decodes the map from sRGB and encodes
the PNG with the sRGB curve, which round-trips to the same brightness. An EXR holds the values unencoded and
says which setting they are in; a scene without maps renders the same values in both.

Every expected value is computed here from the IEC 61966-2-1 formulas, not with the renderer's own code. The
scenes put each pixel centre on one texel centre (an orthographic camera straight above a plane exactly as
large as the view, as many pixels as texels), so a pixel is its texel times the lighting factor.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app

runner = CliRunner()
SCENES = Path(__file__).resolve().parents[2] / "scenes"
N = 32           # texels and pixels a side
BYTE = 1 / 255   # one 8-bit step


def decode(values: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] to linear ones (IEC 61966-2-1)."""
    return np.where(values <= 0.04045, values / 12.92, ((values + 0.055) / 1.055) ** 2.4)


def encode(values: np.ndarray) -> np.ndarray:
    """Linear values to sRGB-encoded ones in [0, 1] (IEC 61966-2-1)."""
    values = np.clip(values, 0.0, 1.0)
    return np.where(values <= 0.0031308, 12.92 * values, 1.055 * values ** (1 / 2.4) - 0.055)


def texels() -> np.ndarray:
    """(N, N, 3) uint8: every byte value, mid-greys included (where display and linear differ most)."""
    return np.random.default_rng(33).integers(0, 256, size=(N, N, 3), dtype=np.uint8)


def write_png(path: Path, rgb8: np.ndarray) -> Path:
    buffer = oiio.ImageBuf(oiio.ImageSpec(rgb8.shape[1], rgb8.shape[0], 3, oiio.UINT8))
    buffer.set_pixels(oiio.ROI(0, rgb8.shape[1], 0, rgb8.shape[0], 0, 1, 0, 3), np.ascontiguousarray(rgb8))
    assert buffer.write(str(path))
    return path


def plane_scene(folder: Path, ambient: float, diffuse: float, render: dict | None = None) -> Path:
    """A 2 × 2 plane with k_a = k_d = 1 and a map `map.png`, filling an N × N orthographic view from straight
    above, lit by I_a = `ambient` and a directional light straight down (n·l = 1) with I_d = `diffuse` and no
    highlight: each pixel is (I_a + I_d) × its texel, in the values render.colour gives the texel."""
    data = {"ambient": ambient, "render": {"width": N, "height": N, **(render or {})},
            "camera": {"type": "orthographic", "position": [0, 5, 0], "look_at": [0, 0, 0], "up": [0, 0, -1],
                       "view_height": 2.0},
            "lights": [{"type": "directional", "direction": [0, -1, 0], "diffuse": diffuse, "specular": 0}],
            "materials": {"m": {"ka": 1, "kd": 1, "ks": 0, "kd_map": "map.png"}},
            "objects": [{"shape": "plane", "size": [2, 2], "material": "m"}]}
    path = folder / "plane.json"
    path.write_text(json.dumps(data))
    return path


def rendered_png(scene: Path, output: Path, *options: str) -> np.ndarray:
    """`raycast-phong render SCENE -o OUTPUT OPTIONS`: the PNG's bytes as (H, W, 3) uint8."""
    done = runner.invoke(app, ["render", str(scene), "-o", str(output), "-q", *options])
    assert done.exit_code == 0, done.output
    return np.round(rp.read_image(output)[0] * 255).astype(np.uint8)


def bytes_apart(a: np.ndarray, b: np.ndarray) -> int:
    return int(np.abs(a.astype(np.int64) - b.astype(np.int64)).max())


@pytest.mark.parametrize("ambient, diffuse", [(0.2, 0.6), (0.25, 0.75)])
def test_display_colour_shows_a_map_at_its_own_brightness_times_the_lighting(tmp_path, ambient, diffuse):
    """A scene file's default: the map's bytes used as stored and the PNG written as it is, so the PNG is the
    texture times I_a k_a + I_d k_d n·l (0.8, then 1: the texture itself). Before, the map was decoded to
    linear values and written with no curve: the PNG's mean was 0.50 of the texture's here, not 0.8."""
    t = texels()
    write_png(tmp_path / "map.png", t)
    factor = ambient + diffuse
    png = rendered_png(plane_scene(tmp_path, ambient, diffuse), tmp_path / "out.png")
    assert abs(png.mean() / 255 - factor * t.mean() / 255) <= BYTE
    assert bytes_apart(png, np.round(factor * t.astype(np.float64))) <= 1  # and pixel by pixel
    if factor == 1:
        assert bytes_apart(png, t) <= 1


@pytest.mark.parametrize("ambient, diffuse", [(0.2, 0.6), (0.25, 0.75)])
def test_linear_colour_decodes_the_map_and_encodes_the_png_so_its_brightness_round_trips(
        tmp_path, ambient, diffuse):
    """glTF's pipeline: texels decoded from sRGB, lit in linear values (× 0.8, then × 1), the PNG encoded with
    the sRGB curve: encode(factor × decode(texel)); with a factor of 1, the texture's own bytes again."""
    t = texels()
    write_png(tmp_path / "map.png", t)
    factor = ambient + diffuse
    png = rendered_png(plane_scene(tmp_path, ambient, diffuse, {"colour": "linear"}), tmp_path / "out.png")
    expected = 255 * encode(factor * decode(t / 255))
    assert abs(png.mean() - expected.mean()) <= 1
    assert bytes_apart(png, np.round(expected)) <= 1
    if factor == 1:
        assert bytes_apart(png, t) <= 1 and abs(png.mean() - t.mean()) <= 1


def test_srgb_is_the_shorthand_for_linear_colour_and_a_set_colour_wins(tmp_path):
    """`render --srgb` (which decoded the maps and encoded the PNG before render.colour existed) gives the bytes of
    `--set render.colour=linear`; a --set of render.colour wins over it."""
    write_png(tmp_path / "map.png", texels())
    scene = plane_scene(tmp_path, 0.2, 0.6)
    shorthand = rendered_png(scene, tmp_path / "a.png", "--srgb")
    np.testing.assert_array_equal(shorthand, rendered_png(scene, tmp_path / "b.png", "--set", "render.colour=linear"))
    assert bytes_apart(shorthand, rendered_png(scene, tmp_path / "c.png")) > 10  # not display's
    np.testing.assert_array_equal(rendered_png(scene, tmp_path / "d.png", "--srgb", "--set", "render.colour=display"),
                                  rendered_png(scene, tmp_path / "e.png"))


@pytest.mark.parametrize("colour, space", [("display", "srgb_rec709_scene"), ("linear", "lin_rec709_scene")])
def test_an_exr_holds_the_unencoded_values_and_its_header_says_the_colour(tmp_path, colour, space):
    """The EXR has the values the PNG is made from, before the curve and the 8-bit rounding (display: the same
    values as the PNG's; linear: the linear ones the PNG encodes), and says which in its header: the setting
    (raycast_phong:colour) and OpenImageIO's colour space (oiio:ColorSpace)."""
    t = texels()
    write_png(tmp_path / "map.png", t)
    scene = plane_scene(tmp_path, 0.2, 0.6, {"colour": colour})
    png = rendered_png(scene, tmp_path / "out.png")
    assert runner.invoke(app, ["render", str(scene), "-o", str(tmp_path / "out.exr"), "-q"]).exit_code == 0
    spec = oiio.ImageInput.open(str(tmp_path / "out.exr")).spec()
    assert spec.get_string_attribute("raycast_phong:colour") == colour
    assert spec.get_string_attribute("oiio:ColorSpace") == space
    values = rp.read_image(tmp_path / "out.exr")[0]
    shown = values if colour == "display" else encode(values)
    np.testing.assert_array_equal(np.round(np.clip(shown, 0, 1) * 255), png)
    texel = t / 255 if colour == "display" else decode(t / 255)
    np.testing.assert_allclose(values, 0.8 * texel, atol=1e-6)


def textured_quad_glb(path: Path, rgb8: np.ndarray) -> Path:
    """A 2 × 2 quad in the x–y plane (normal +z) whose glTF material's baseColorTexture is `rgb8` over UVs
    [0, 1]²; metallic 0, roughness 1 (k_a = k_d = the texture; docs/meshes.md)."""
    import trimesh
    from PIL import Image
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    material = trimesh.visual.material.PBRMaterial(name="paint", baseColorTexture=Image.fromarray(rgb8),
                                                   metallicFactor=0.0, roughnessFactor=1.0)
    quad = trimesh.Trimesh(np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float), [[0, 1, 2], [0, 2, 3]],
                           visual=trimesh.visual.TextureVisuals(uv=uv, material=material), process=False)
    quad.export(path)
    return path


# The quad framed exactly and lit head-on by I_d = 0.5 alone: each pixel is 0.5 × its texel.
QUAD_VIEW = [f"render.width={N}", f"render.height={N}", "camera.type=orthographic", "camera.position=[0, 0, 5]",
             "camera.look_at=[0, 0, 0]", "camera.up=[0, 1, 0]", "camera.view_height=2", "ambient=0",
             'lights=[{type = "directional", direction = [0, 0, -1], diffuse = 0.5, specular = 0}]']


def test_a_gltf_rendered_directly_is_in_linear_colour_and_says_why(tmp_path):
    """glTF specifies sRGB colour maps lit in linear values: `render model.glb` decodes the map and encodes the
    PNG (0.5 × a texel → encode(0.5 · decode(texel))); `plan` says so and why; `scene` writes the key, so the
    scene file it makes renders the same; --set render.colour=display wins (0.5 × the texel's byte)."""
    t = texels()
    glb = textured_quad_glb(tmp_path / "quad.glb", t)
    sets = [arg for override in QUAD_VIEW for arg in ("--set", override)]
    png = rendered_png(glb, tmp_path / "quad.png", *sets)
    assert bytes_apart(png, np.round(255 * encode(0.5 * decode(t / 255)))) <= 1
    display = rendered_png(glb, tmp_path / "display.png", *sets, "--set", "render.colour=display")
    assert bytes_apart(display, np.round(0.5 * t.astype(np.float64))) <= 1
    planned = runner.invoke(app, ["plan", str(glb)])
    assert re.search(r"^colour\s+linear\s+the default for a glTF file rendered directly", planned.output, re.M), \
        planned.output
    assert re.search(r"^colour\s+display\s+render.colour is set",
                     runner.invoke(app, ["plan", str(glb), "--set", "render.colour=display"]).output, re.M)
    written = runner.invoke(app, ["scene", str(glb)])
    assert 'colour = "linear"' in written.output, written.output
    assert rp.render_file(glb, QUAD_VIEW).colour == "linear"  # the Python API's default too


def test_an_obj_rendered_directly_is_in_display_colour():
    """No other format names a colour space; fixed-function viewers show OBJ, PLY and STL colours as stored."""
    for path in (SCENES / "meshes" / "dice.obj", SCENES / "meshes" / "painted_knot.ply"):
        scene = rp.load_scene(path)
        assert scene.render.colour == "display"
        assert rp.build_plan(scene).colour_reason.startswith(  # the scene knows its file (Scene.origin)
            f"the default for a {path.suffix} file rendered directly")


UNTEXTURED = [path for path in sorted(SCENES.glob("*.toml")) if "kd_map" not in path.read_text()] + [
    SCENES / "meshes" / name for name in ("dice.obj", "painted_knot.ply", "still_life.glb")]


@pytest.mark.parametrize("path", UNTEXTURED, ids=lambda path: path.name)
def test_a_scene_without_maps_renders_the_same_values_in_both_colours(path):
    """render.colour decides only how maps are decoded and how the PNG is encoded: without maps, the model's
    values are bit for bit the same in both (so the lecture's scenes, in display colour, are unchanged)."""
    small = ["render.width=32", "render.height=24"]
    display = rp.render_file(path, [*small, "render.colour=display"])
    linear = rp.render_file(path, [*small, "render.colour=linear"])
    assert (display.colour, linear.colour) == ("display", "linear")
    np.testing.assert_array_equal(display.image, linear.image)


def test_batch_srgb_renders_in_linear_colour_and_a_sweeps_exr_cells_show_as_their_pngs(tmp_path, monkeypatch):
    """`batch --srgb` is the same shorthand: its PNG is the linear render's, and switching it re-renders (the
    colour is in each job's hash). A contact sheet shows an EXR cell as its PNG would (its header's colour)."""
    write_png(tmp_path / "map.png", texels())
    scene = plane_scene(tmp_path, 0.2, 0.6)
    linear = rendered_png(scene, tmp_path / "linear.png", "--set", "render.colour=linear")
    display = rendered_png(scene, tmp_path / "display.png")
    out = tmp_path / "out"
    hashes = []
    for extra, expected in (([], display), (["--srgb"], linear)):
        done = runner.invoke(app, ["batch", str(scene), "--out", str(out), "--jobs", "1", "-q", *extra])
        assert done.exit_code == 0, done.output
        np.testing.assert_array_equal(np.round(rp.read_image(out / "plane.png")[0] * 255), expected)
        entry = json.loads((out / "manifest.json").read_text())["scenes"]["plane"]
        assert entry["status"] == "rendered"  # not "up to date": --srgb changes the image
        hashes.append(entry["hash"])
    assert hashes[0] != hashes[1]

    from raycast_phong.tools import sweep
    shown = []
    compose = sweep.compose_sheet
    monkeypatch.setattr(sweep, "compose_sheet", lambda cells, images: shown.extend(images) or compose(cells, images))
    (tmp_path / "sweep.toml").write_text('scene = "plane.json"\nset = [\'output.path="cell.exr"\']\n'
                                         '[grid]\nrender.colour = ["display", "linear"]\n')
    done = runner.invoke(app, ["batch", str(tmp_path / "sweep.toml"), "--out", str(out), "--jobs", "1", "-q"])
    assert done.exit_code == 0, done.output
    assert len(shown) == 2
    for cell, expected in zip(shown, (display, linear)):
        assert bytes_apart(np.round(cell * 255), expected) <= 1
