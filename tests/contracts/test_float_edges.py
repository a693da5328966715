"""Numbers at the edge of float, and the small print of reading a scene file.

A value that validates must render finitely; one that would overflow (or underflow into 0/0) later is
refused up front: exit 2, one line naming the file, the key and the allowed range, no traceback, no
RuntimeWarning (warnings are errors in this module), and an existing output file left as it was.
The bounds and their reasons: docs/scene-format.md, "Number ranges".
"""

from __future__ import annotations

import copy
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app

runner = CliRunner()
pytestmark = [pytest.mark.usefixtures("in_tmp_path"), pytest.mark.filterwarnings("error")]

SENTINEL = b"an image the user already has"

BASE: dict[str, Any] = {
    "ambient": 0.1,
    "render": {"width": 12, "height": 10},
    "camera": {"position": [0, 0, 4], "look_at": [0, 0, 0]},
    "lights": [{"type": "point", "position": [2, 2, 3]}],
    "objects": [{"shape": "icosphere", "subdivisions": 1}],
}


def scene_file(folder: Path, edit=None, name: str = "scene.json") -> Path:
    """BASE, changed in place by `edit(scene)`, written as JSON (which spells 1e-320 and 1e308 as TOML does)."""
    scene = copy.deepcopy(BASE)
    if edit:
        edit(scene)
    path = folder / name
    path.write_text(json.dumps(scene), encoding="utf-8")
    return path


def refused(folder: Path, scene: Path, *expected: str, args: tuple[str, ...] = ()) -> str:
    """Render `scene` onto an existing out.exr: exit 2, one line naming the file and `expected`, file untouched."""
    output = folder / "out.exr"
    output.write_bytes(SENTINEL)
    result = runner.invoke(app, ["render", str(scene), "-o", str(output), "-q", *args])
    message = result.stderr.strip()
    assert result.exit_code == 2, f"exit {result.exit_code}: {result.output} {result.exception!r}"
    assert message.startswith("error: ") and len(message.splitlines()) == 1, message
    assert str(scene) in message and "Traceback" not in result.output
    for part in expected:
        assert part in message, f"{part!r} not in: {message}"
    assert output.read_bytes() == SENTINEL
    return message


def rendered(folder: Path, scene: Path) -> np.ndarray:
    """Render `scene` to EXR (unclamped): exit 0 and the image, which must be finite and non-negative."""
    output = folder / "out.exr"
    result = runner.invoke(app, ["render", str(scene), "-o", str(output), "-q"])
    assert result.exit_code == 0, f"exit {result.exit_code}: {result.output} {result.exception!r}"
    image = rp.read_image(output)[0]
    assert np.isfinite(image).all() and (image >= 0).all(), (np.nanmin(image), np.nanmax(image))
    return image


def set_path(scene: dict, dotted: str, value: Any) -> None:
    *parents, last = [int(p) if p.isdigit() else p for p in dotted.split(".")]
    node: Any = scene
    for part in parents:
        node = node[part] if isinstance(node, list) else node.setdefault(part, {})
    node[last] = value


# ---------------------------------------------------------------- values that used to overflow later

# (key, value, words of the one-line message). On the code before these bounds each gave an internal error
# with a numpy RuntimeWarning (exit 1) or, for two lights of 9e37, inf pixels with exit 0.
OVERFLOWS = [
    ("lights.0.position", [1e300, 0, 0], "within ±1e+18"),
    ("camera.position", [0, 0, 1e300], "within ±1e+18"),
    ("camera.look_at", [0, 0, -1e300], "within ±1e+18"),
    ("objects.0.translate", [1e300, 0, 0], "within ±1e+18"),
    ("objects.0.scale", 1e300, "within ±1e+18"),
    ("objects.0.radius", 1e300, "radius ≤ 1e+18"),
    ("camera.up", [0, 1e-320, 0], "1e-150 ≤ length ≤ 1e+150"),
    ("camera.up", [0, 1e200, 0], "1e-150 ≤ length ≤ 1e+150"),
    ("lights.0.diffuse", 1e39, "[0, 1e+38]"),
    ("lights.0.specular", 1e308, "[0, 1e+38]"),
    ("ambient", 1e308, "[0, 1e+38]"),
    ("render.background", 1e39, "[0, 1e+38]"),
    ("lights.0.attenuation", [0, 0, 1e39], "0 ≤ c, l, q ≤ 1e+38"),
    ("materials.m.shininess", 3.5e38, "if finite, at most 1e+38"),  # found by tests/contracts/test_fuzz.py, with ks = 0
]


@pytest.mark.parametrize(("key", "value", "allowed"), OVERFLOWS, ids=[f"{k}={v}" for k, v, _ in OVERFLOWS])
def test_a_value_that_would_overflow_is_refused_naming_its_key(tmp_path, key, value, allowed):
    def edit(scene):
        scene["materials"] = {"m": {"ks": 0}}
        scene["objects"][0]["material"] = "m"
        set_path(scene, key, value)
    refused(tmp_path, scene_file(tmp_path, edit), f"{key}:", allowed)


def test_a_light_direction_too_short_to_normalise_is_refused(tmp_path):
    scene = scene_file(tmp_path, lambda s: s["lights"].append({"type": "directional", "direction": [0, 0, -1e-320]}))
    refused(tmp_path, scene, "lights.1.direction:", "1e-150 ≤ length ≤ 1e+150")


def test_a_camera_a_subnormal_distance_from_its_target_is_refused(tmp_path):
    scene = scene_file(tmp_path, lambda s: s["camera"].update(position=[0, 0, 1e-320], look_at=[0, 0, 0]))
    refused(tmp_path, scene, "camera.look_at:", "at least 1e-150")


def test_lights_whose_sum_would_overflow_float32_are_refused(tmp_path):
    # Each light alone is in range; together a pixel lit by both would pass float32's 3.4e38.
    def edit(scene):
        scene["lights"] = [{"position": [2, 2, 3], "diffuse": 9e37}, {"position": [-2, 2, 3], "diffuse": 9e37}]
    refused(tmp_path, scene_file(tmp_path, edit), "lights.", "could reach 1.8e+38", "at most 1e+38")


def test_an_inverse_square_light_on_a_tiny_scene_is_refused_if_it_could_overflow(tmp_path):
    # Half-extent 1e-11: the 1/d² floor is 1e-17, so f_att can reach 1e34; × 1e10 passes float32's range.
    def edit(scene):
        scene["objects"][0]["scale"] = 1e-11
        scene["camera"]["position"] = [0, 0, 4e-11]
        scene["lights"][0].update(attenuation="inverse_square", position=[0, 0, 1e-11], diffuse=1e10)
    refused(tmp_path, scene_file(tmp_path, edit), "lights.0:", "1/d² attenuation up to 1e+34")


@pytest.mark.parametrize("scale", [1e-300, 1e-20])
def test_a_scene_smaller_than_the_float32_floor_is_refused(tmp_path, scale):
    refused(tmp_path, scene_file(tmp_path, lambda s: set_path(s, "objects.0.scale", scale)),
            "objects:", "at least 2e-12")


def test_an_object_that_collapses_to_a_point_is_refused(tmp_path):
    # 0.5 + 1e-300 == 0.5: every vertex lands on one point (the plan's highlight estimate divided by zero).
    scene = scene_file(tmp_path, lambda s: s["objects"].append({"shape": "icosphere", "scale": 1e-300,
                                                                 "translate": [0.5, 0.5, 1.2]}))
    refused(tmp_path, scene, "objects.1:", "collapses to a single point")


def test_mesh_coordinates_beyond_the_position_limit_are_refused(tmp_path):
    (tmp_path / "huge.obj").write_text("v 0 0 0\nv 1e300 0 0\nv 0 1e300 0\nf 1 2 3\n", encoding="utf-8")
    scene = scene_file(tmp_path, lambda s: set_path(s, "objects.0", {"shape": "mesh", "path": "huge.obj"}))
    refused(tmp_path, scene, "objects.0.path:", "2 vertex(es) with a coordinate beyond ±1e+18")


def test_an_object_placed_beyond_the_position_limit_is_refused(tmp_path):
    # Each key is in range, their product is not: radius 1e17 × scale 1e3.
    scene = scene_file(tmp_path, lambda s: s["objects"][0].update(radius=1e17, scale=1e3))
    refused(tmp_path, scene, "objects.0:", "reaches a coordinate of 1e+20", "within ±1e+18")


def test_values_just_inside_the_bounds_render_finitely(tmp_path):
    """The bounds are not stricter than needed: a 1e17 sphere seen from 9e17, a light at 1e18, a background
    and ambient of 1e38 (the EXR keeps them) all render."""
    def edit(scene):
        scene["objects"][0]["radius"] = 1e17
        scene["camera"]["position"] = [0, 0, 9e17]
        scene["lights"][0]["position"] = [1e18, 1e18, 1e18]
        scene["render"]["background"] = 1e38
        scene["ambient"] = 1e38 - 2  # 1 + I_a + Σ I ≤ 1e38 in every channel
    image = rendered(tmp_path, scene_file(tmp_path, edit))
    assert image.max() == pytest.approx(1e38, rel=1e-6)


# ---------------------------------------------------------------- attenuation [c, l, q] = [0, 0, 1]

def plane_under_a_light(height: float, attenuation) -> dict:
    """An orthographic look straight down at a white plane (k_d = 1, nothing else) lit by a point light
    `height` above its centre; the centre pixel (odd size) sees the point under the light head-on."""
    return {"ambient": 0, "render": {"width": 5, "height": 5, "precision": "float64"},
            "camera": {"type": "orthographic", "position": [0, 10, 0], "look_at": [0, 0, 0], "up": [0, 0, -1],
                       "view_height": 1},
            "lights": [{"position": [0, height, 0], "diffuse": 1, "specular": 0, "attenuation": attenuation}],
            "materials": {"white": {"ka": 0, "kd": 1, "ks": 0}},
            "objects": [{"shape": "plane", "size": [4, 4], "material": "white"}]}


@pytest.mark.parametrize(("height", "expected"), [
    (2.0, 0.25),  # f_att = min(1, 1/(0 + 0·2 + 1·2²)) = 1/4, n·l = 1
    (0.5, 1.0),   # 1/d² = 4 is clamped to 1
    (0.0, 1.0),   # the light on the surface: c + l·d + q·d² = 0, the clamp's limit 1, l = n (inside the floor)
])
def test_pure_inverse_square_attenuation_by_hand(tmp_path, height, expected):
    path = tmp_path / "plane.json"
    path.write_text(json.dumps(plane_under_a_light(height, [0, 0, 1])), encoding="utf-8")
    image = rendered(tmp_path, path)
    # float64 shading; the hit point is off the exact centre by Embree's float32 rounding (≈ 1e-7 relative),
    # which moves d² by about that much: 1e-6 is ten times that and still far from any other reading.
    np.testing.assert_allclose(image[2, 2], expected, rtol=1e-6)


def test_the_analytic_reference_agrees_at_zero_distance():
    """illuminate_exact at d = 0 with c = 0: f_att = 1 and l = n, no division by zero (warnings are errors)."""
    from raycast_phong.tools.reference import illuminate_exact
    scene = rp.validate_scene(plane_under_a_light(0.0, [0, 0, 1]))
    points, normals = np.zeros((1, 3)), np.array([[0.0, 1.0, 0.0]])
    material = np.array([[0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0, 0, 32.0]])
    _, diffuse, _, _ = illuminate_exact(scene, points, normals, normals, material, np.ones((1, 1), bool), 2.0)
    np.testing.assert_array_equal(diffuse, [[1.0, 1.0, 1.0]])


@pytest.mark.parametrize("attenuation", [[0, 0, 1], [0, 1, 0], [0, 0.5, 2], [1, 0, 0]])
def test_every_non_negative_attenuation_not_all_zero_is_accepted(attenuation):
    scene = copy.deepcopy(BASE)
    scene["lights"][0]["attenuation"] = attenuation
    assert rp.validate_scene(scene).lights[0].attenuation == tuple(float(x) for x in attenuation)


# ---------------------------------------------------------------- reading the file

def test_a_byte_order_mark_is_accepted(tmp_path):
    toml = tmp_path / "bom.toml"
    toml.write_bytes(b"\xef\xbb\xbf" + b'[render]\nwidth = 8\nheight = 6\n[[objects]]\nshape = "box"\n')
    assert rp.load_scene(toml).render.width == 8
    bom_json = tmp_path / "bom.json"
    bom_json.write_bytes(b"\xef\xbb\xbf" + json.dumps(BASE).encode())
    assert rp.load_scene(bom_json).render.width == 12


def test_a_key_given_twice_in_json_is_an_error_naming_it(tmp_path):
    path = tmp_path / "twice.json"
    path.write_text('{"render": {"width": 8, "height": 6, "width": 9}, "objects": [{"shape": "box"}]}',
                    encoding="utf-8")
    refused(tmp_path, path, "render.width:", "given twice", "each key once")


@pytest.mark.parametrize(("shape", "key", "value"), [("box", "subdivisions", 3), ("icosphere", "major_radius", 2.0),
                                                     ("plane", "radius", 0.5), ("mesh", "segments", [8, 8])])
def test_a_key_the_shape_does_not_read_is_an_error(tmp_path, shape, key, value):
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", encoding="utf-8")
    extra = {"path": "tri.obj"} if shape == "mesh" else {}
    scene = scene_file(tmp_path, lambda s: set_path(s, "objects.0", {"shape": shape, key: value, **extra}))
    refused(tmp_path, scene, f"objects.0.{key}:", f'does not apply to shape = "{shape}"')


# ---------------------------------------------------------------- options

@pytest.mark.parametrize("args", [["render", "--width", "abc"], ["render", "--bogus"], ["nope"],
                                  ["render", "--threads", "999"]])
def test_an_option_error_is_one_line(args):
    result = runner.invoke(app, args, prog_name="raycast-phong")
    message = result.stderr.strip()
    assert result.exit_code == 2, result.output
    assert len(message.splitlines()) == 1 and message.startswith("error: raycast-phong"), message
    assert "╭" not in result.output and "Usage:" not in result.output


def test_an_option_error_is_one_line_from_the_real_command():
    """The console script as a user runs it (typer's rich formatting depends on the real streams)."""
    cli = Path(__file__).resolve().parents[2] / "cli.py"
    done = subprocess.run([sys.executable, "-W", "error", str(cli), "render", "--width", "abc"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stdout == "", done
    assert len(done.stderr.strip().splitlines()) == 1 and "'--width'" in done.stderr, done.stderr


@pytest.mark.parametrize(("look_at", "warned"), [([0, 0, 8], True), ([0, 0, 0], False), ([8, 0, 4], False)])
def test_a_scene_entirely_behind_the_camera_warns_once(tmp_path, look_at, warned):
    # Looking away from the sphere (+z from z = 4); at it; sideways (the sphere's rim is in front of the eye plane).
    scene = scene_file(tmp_path, lambda s: s["camera"].update(look_at=look_at))
    result = runner.invoke(app, ["render", str(scene), "-o", str(tmp_path / "out.png")])
    assert result.exit_code == 0, result.output
    lines = [line for line in result.stderr.splitlines() if "behind the camera" in line]
    assert len(lines) == (1 if warned else 0), result.stderr
    if warned:
        assert lines[0].startswith("warning: every object is behind the camera")


def test_a_tiny_shape_beside_a_normal_one_renders(tmp_path):
    # trimesh's icosphere at radius 1e-20 divided 0 by 0 (it merges vertices closer than an absolute 1e-8):
    # shapes are now built at unit size and scaled, so the speck is just too small to see.
    scene = scene_file(tmp_path, lambda s: s["objects"].append({"shape": "icosphere", "subdivisions": 2,
                                                                 "radius": 1e-20, "translate": [0, 0, 1.5]}))
    rendered(tmp_path, scene)


@pytest.mark.parametrize("obj", [{"shape": "torus", "minor_radius": 1e-12}, {"shape": "cylinder", "radius": 1e-12}])
def test_a_shape_too_thin_for_float32_is_refused(tmp_path, obj):
    refused(tmp_path, scene_file(tmp_path, lambda s: set_path(s, "objects.0", obj)), "objects.0:", "no triangles")


def test_a_bright_inverse_square_light_far_away_is_accepted(tmp_path):
    # I_d + I_s = 1.8e38 would pass the limit at f_att = 1, but 1e10 from the scene 1/d² is at most 1e-20.
    def edit(scene):
        scene["lights"][0].update(position=[0, 0, 1e10], diffuse=9e37, specular=9e37, attenuation="inverse_square")
    image = rendered(tmp_path, scene_file(tmp_path, edit))
    assert image.max() > 1e17  # 9e37 · 1e-20 · k_d n·l: the light does reach the sphere
