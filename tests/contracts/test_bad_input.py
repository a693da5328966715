"""Bad input: every kind of mistake in a scene, a mesh, an option or an output path.

Each test runs the CLI as a user would and checks the whole contract for bad input: exit status 2,
a message of one or two lines on stderr that names the scene file, the key path and what is
allowed, no traceback, and an existing output image left byte for byte as it was.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

import raycast_phong
from raycast_phong.cli import app

runner = CliRunner()

# Stands in for a good image the user already has; a refused run must not touch it.
SENTINEL = b"\x89PNG not really: bytes the renderer must leave alone\x00\x01\x02"

# A scene that renders (test_the_base_scene_renders), so each test below fails for its one change only.
BASE: dict[str, Any] = {
    "ambient": [0.1, 0.1, 0.1],
    "render": {"width": 16, "height": 16},
    "camera": {"position": [0, 0, 4], "look_at": [0, 0, 0], "up": [0, 1, 0], "fov": 40},
    "lights": [{"type": "point", "position": [2, 2, 3]}],
    "materials": {"red": {"ka": [1.0, 0.3, 0.3], "kd": [0.9, 0.2, 0.2], "ks": [0.6, 0.6, 0.6], "shininess": 32}},
    "objects": [{"shape": "icosphere", "subdivisions": 1, "material": "red"}],
    "output": {"path": "out.png"},
}
DELETE = object()  # a `changes` value that removes the key


# ---------------------------------------------------------------- helpers

def toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")  # TOML spells them so
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)  # a TOML basic string escapes as JSON does
    return "[" + ", ".join(toml_value(item) for item in value) + "]"


def toml_text(table: dict, prefix: str = "") -> str:
    """TOML for a scene dictionary: plain keys first, then [tables] and [[arrays of tables]]."""
    lines = [f"{key} = {toml_value(value)}" for key, value in table.items()
             if not isinstance(value, dict) and not (isinstance(value, list) and value and isinstance(value[0], dict))]
    for key, value in table.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            lines += ["", f"[{name}]", toml_text(value, name + ".")]
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            for item in value:
                lines += ["", f"[[{name}]]", toml_text(item, name + ".")]
    return "\n".join(lines)


def scene_with(changes: dict[str, Any]) -> dict:
    """BASE with `changes` applied; keys are dotted paths with list indices, "objects.0.path"."""
    scene = copy.deepcopy(BASE)
    for dotted, value in changes.items():
        *parents, last = [int(p) if p.isdigit() else p for p in dotted.split(".")]
        node: Any = scene
        for part in parents:
            node = node[part] if isinstance(node, list) else node.setdefault(part, {})
        if value is DELETE:
            del node[last]
        else:
            node[last] = value
    return scene


def write_scene(folder: Path, changes: dict[str, Any] | None = None, name: str = "scene.toml") -> Path:
    scene = scene_with(changes or {})
    path = folder / name
    path.write_text(json.dumps(scene) if name.endswith(".json") else toml_text(scene), encoding="utf-8")
    return path


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def run_refused(folder: Path, args: list[str], *expected: str, scene: Path | None = None,
                output: Path | None = None) -> str:
    """Run the CLI; check the bad-input contract and that the message holds every `expected` part.

    `output` (default: folder/out.png, the scene's output.path) is created with known bytes first.
    Returns the message.
    """
    output = output or folder / "out.png"
    if output.parent.is_dir():
        output.write_bytes(SENTINEL)
    before = snapshot(folder)
    result = runner.invoke(app, args)
    message = result.output.strip()
    assert "Traceback" not in result.output, result.output
    # CliRunner turns an uncaught exception into exit 1; 2 only comes from the CLI's own refusal.
    assert result.exit_code == 2, f"exit {result.exit_code}: {result.output} {result.exception!r}"
    assert isinstance(result.exception, SystemExit)
    assert result.stdout == "", "a refused run prints no summary"
    assert message.startswith("error: ")
    assert 1 <= len(message.splitlines()) <= 2, message
    if scene is not None:
        assert str(scene) in message, f"the message does not name the scene file: {message}"
    for part in expected:
        assert part in message, f"{part!r} not in: {message}"
    # Nothing written: no new file, no temporary left behind, and the old image as it was.
    assert snapshot(folder) == before
    if output.parent.is_dir():
        assert output.read_bytes() == SENTINEL
    return message


def refuse_scene(tmp_path: Path, changes: dict[str, Any], *expected: str, args: tuple[str, ...] = (),
                 name: str = "scene.toml") -> str:
    """Write BASE with `changes`, render it to the scene's own output.path, expect a refusal."""
    scene = write_scene(tmp_path, changes, name)
    return run_refused(tmp_path, ["render", str(scene), *args], *expected, scene=scene)


pytestmark = pytest.mark.usefixtures("in_tmp_path")


@pytest.fixture
def no_render(monkeypatch):
    """Fail the test if the CLI gets as far as rendering (and allocating the image)."""
    def render(*args, **kwargs):
        pytest.fail("the scene reached the renderer; it should have been refused while loading")
    from raycast_phong.renderer.prepare import Renderer
    monkeypatch.setattr(raycast_phong, "render", render)
    monkeypatch.setattr(Renderer, "prepare", render)  # every render goes through a session's prepare()


# ---------------------------------------------------------------- the control

def test_the_base_scene_renders(tmp_path):
    """Every test below changes one thing in this scene; unchanged, it renders and writes out.png."""
    scene = write_scene(tmp_path)
    result = runner.invoke(app, ["render", str(scene), "--quiet"])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "out.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_no_render_stops_a_scene_that_reaches_the_renderer(tmp_path, no_render):
    """The control for the tests that use `no_render`: the CLI's render does go through the patched name."""
    with pytest.raises(pytest.fail.Exception, match="reached the renderer"):
        runner.invoke(app, ["render", str(write_scene(tmp_path)), "--quiet"], catch_exceptions=False)


def test_the_helpers_write_the_scene_they_are_given(tmp_path):
    import tomllib
    changes = {"render.background": [0.0, math.inf, 0.0], "objects.0.name": 'a "quoted" name'}
    written = tomllib.loads(write_scene(tmp_path, changes).read_text())
    assert written["objects"][0]["name"] == 'a "quoted" name'
    assert written["render"]["background"][1] == math.inf
    assert written["materials"]["red"]["shininess"] == 32
    assert "objects" not in scene_with({"objects": DELETE})


# ---------------------------------------------------------------- syntax

def test_toml_syntax_error(tmp_path):
    scene = tmp_path / "scene.toml"
    scene.write_text(toml_text(BASE).replace("width = 16", "width = "), encoding="utf-8")
    line = toml_text(BASE).splitlines().index("width = 16") + 1
    run_refused(tmp_path, ["render", str(scene)], "TOML syntax error", f"line {line}", scene=scene)


def test_json_syntax_error(tmp_path):
    scene = tmp_path / "scene.json"
    scene.write_text('{\n  "render": {"width": 16,}\n}\n', encoding="utf-8")
    run_refused(tmp_path, ["render", str(scene)], "JSON syntax error", "line 2", scene=scene)


def test_a_json_scene_is_validated_like_toml(tmp_path):
    refuse_scene(tmp_path, {"render.widht": 16}, "render.widht: unknown key", "did you mean 'width'",
                 name="scene.json")


# ---------------------------------------------------------------- keys and types

@pytest.mark.parametrize(("key", "suggested"), [
    ("render.widht", "width"),
    ("objects.0.materal", "material"),
    ("materials.red.shinyness", "shininess"),
    ("lights.0.positon", "position"),
    ("camera.fvo", "fov"),
])
def test_unknown_key_suggests_the_closest_valid_key(tmp_path, key, suggested):
    message = refuse_scene(tmp_path, {key: 1}, f"{key}: unknown key", f"did you mean {suggested!r}?",
                           "valid keys here: ")
    assert message.count(suggested) >= 2  # suggested, and listed among the valid keys


@pytest.mark.parametrize(("key", "value", "allowed"), [
    ("render.width", "32", "must be a whole number, got the string '32'; allowed: 1 ≤ width ≤ 16384"),
    ("render.width", True, "must be a whole number, got true"),
    ("render.width", 12.5, "must be a whole number; allowed: 1 ≤ width ≤ 16384"),
    ("camera.fov", "40", "must be a number, got the string '40'; allowed: 0.0 < fov < 180.0"),
    ("materials.red.shininess", "eight", "must be a number, got the string 'eight'"),
    ("lights.0.position", ["1", 2, 3], "lights.0.position.0: must be a number"),
    ("materials.red.kd", [0.5, 0.5], "must be three numbers [a, b, c] (or one number for all three)"),
    ("render.two_sided", "yes", "must be true or false"),
    ("lights", {"position": [1, 2, 3]}, "lights: must be an array of tables, [[lights]]"),
])
def test_wrong_type(tmp_path, key, value, allowed):
    refuse_scene(tmp_path, {key: value}, f"{key.split('.')[0]}", allowed)


@pytest.mark.parametrize(("key", "value"), [
    ("ka", 1.5), ("kd", [0.5, -0.1, 0.2]), ("ks", 2), ("ke", [0, 0, 3]),
])
def test_coefficient_outside_0_1(tmp_path, key, value):
    refuse_scene(tmp_path, {f"materials.red.{key}": value}, f"materials.red.{key}:",
                 "each coefficient must be in [0, 1]")


@pytest.mark.parametrize("shininess", [-1.0, math.nan])
def test_shininess_negative_or_nan(tmp_path, shininess):
    refuse_scene(tmp_path, {"materials.red.shininess": shininess}, "materials.red.shininess:",
                 "shininess must be ≥ 0 (inf allowed", f"got {shininess}")


def test_infinite_shininess_is_allowed(tmp_path):
    """The format's mirror limit: inf is a valid shininess, not bad input."""
    scene = write_scene(tmp_path, {"materials.red.shininess": math.inf})
    result = runner.invoke(app, ["render", str(scene), "--quiet"])
    assert result.exit_code == 0, result.output


@pytest.mark.parametrize(("key", "value"), [
    ("lights.0.position", [math.nan, 1.0, 1.0]),
    ("camera.position", [0.0, 0.0, math.inf]),
    ("camera.look_at", [0.0, -math.inf, 0.0]),
    ("objects.0.translate", [0.0, math.nan, 0.0]),
    ("objects.0.scale", math.nan),
    ("ambient", [math.nan, 0.0, 0.0]),
    ("render.background", [0.0, -math.inf, 0.0]),
    ("lights.0.diffuse", [0.0, math.inf, 0.0]),
])
def test_nan_or_inf_in_a_list(tmp_path, key, value):
    refuse_scene(tmp_path, {key: value}, f"{key}: must be finite numbers, got [")


# ---------------------------------------------------------------- meshes

def test_missing_mesh_file(tmp_path):
    refuse_scene(tmp_path, {"objects.0.shape": "mesh", "objects.0.subdivisions": DELETE,
                            "objects.0.path": "meshes/nothere.obj"},
                 "objects.0.path: no such mesh file", str(tmp_path / "meshes" / "nothere.obj"))


@pytest.mark.parametrize("name", ["garbage.obj", "garbage.ply"])
def test_unreadable_mesh_file(tmp_path, name):
    # Bytes that are neither UTF-8 text nor any mesh format (fixed, so the test is deterministic).
    (tmp_path / name).write_bytes(bytes(range(256)) * 4)
    refuse_scene(tmp_path, {"objects.0.shape": "mesh", "objects.0.subdivisions": DELETE, "objects.0.path": name},
                 "objects.0.path:",
                 str(tmp_path / name), "a mesh file of a format read here (OBJ, PLY, STL, OFF, glTF/GLB, 3MF, COLLADA)"
                 if name.endswith(".obj") else "its content does not start as a PLY file does")


def test_mesh_file_with_nan_vertices(tmp_path):
    (tmp_path / "nan.obj").write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    refuse_scene(tmp_path, {"objects.0.shape": "mesh", "objects.0.subdivisions": DELETE,
                            "objects.0.path": "nan.obj"}, "objects.0.path:",
                 "has 1 vertex(es) with NaN or infinite coordinates", "must have finite coordinates")


def test_a_good_mesh_file_renders(tmp_path):
    """The control for the mesh tests: the same square without the NaN is accepted."""
    (tmp_path / "square.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    scene = write_scene(tmp_path, {"objects.0.shape": "mesh", "objects.0.subdivisions": DELETE,
                                   "objects.0.path": "square.obj"})
    result = runner.invoke(app, ["render", str(scene)])
    assert result.exit_code == 0, result.output
    assert "2 triangles" in result.stdout


def test_a_latin1_obj_file_is_read(tmp_path):
    """A comment in Latin-1 (not UTF-8) does not make an OBJ unreadable."""
    (tmp_path / "café.obj").write_bytes("# caf\xe9 mod\xe8le\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".encode("latin-1"))
    scene = write_scene(tmp_path, {"objects.0.shape": "mesh", "objects.0.subdivisions": DELETE,
                                   "objects.0.path": "café.obj"})
    result = runner.invoke(app, ["render", str(scene)])
    assert result.exit_code == 0, result.output
    assert "1 triangles" in result.stdout


# ---------------------------------------------------------------- references

@pytest.mark.parametrize(("name", "hint"), [("rde", " (did you mean 'red'?)"), ("blue", "")])
def test_undefined_material(tmp_path, name, hint):
    message = refuse_scene(tmp_path, {"objects.0.material": name},
                           f"objects.0.material: material {name!r} is not defined{hint}; defined: red")
    assert hint or "did you mean" not in message


def test_scene_without_objects(tmp_path):
    refuse_scene(tmp_path, {"objects": DELETE}, "objects: the scene has no [[objects]]; add at least one")


# ---------------------------------------------------------------- image size and camera

@pytest.mark.parametrize(("key", "value"), [("render.width", 0), ("render.height", 0), ("render.width", 100000),
                                            ("render.height", -3)])
def test_image_size_is_refused_before_allocating(tmp_path, no_render, key, value):
    name = key.split(".")[1]
    refuse_scene(tmp_path, {key: value}, f"{key}: out of range; allowed: 1 ≤ {name} ≤ 16384", f"(got {value})")


def test_absurd_size_from_the_command_line(tmp_path, no_render):
    refuse_scene(tmp_path, {}, "render.width: out of range; allowed: 1 ≤ width ≤ 16384 (got 100000)",
                 args=("--width", "100000"))


def test_absurd_ray_count_is_refused(tmp_path, no_render):
    """Each side within range, but 16384² pixels × 16² samples is more rays than a frame may have."""
    refuse_scene(tmp_path, {"render.width": 16384, "render.height": 16384, "render.samples": 16},
                 "render.samples:", "16384×16384 pixels × 16² samples", "2147483647 rays per frame")


@pytest.mark.parametrize("fov", [0, 180, -5, math.nan])
def test_fov_out_of_range(tmp_path, fov):
    refuse_scene(tmp_path, {"camera.fov": fov}, "camera.fov: out of range; allowed: 0.0 < fov < 180.0")


@pytest.mark.parametrize(("changes", "expected"), [
    ({"camera.up": [0, 0, 0]}, "camera.up: the zero vector; give any direction not parallel to look_at − position"),
    ({"camera.up": [0, 0, 1]}, "camera.up: [0.0, 0.0, 1.0] is parallel to the viewing direction"),
    ({"camera.up": [0, 0, -3]}, "camera.up: [0.0, 0.0, -3.0] is parallel to the viewing direction"),
    ({"camera.look_at": [0, 0, 4]}, "camera.look_at: [0.0, 0.0, 4.0] is the camera position too"),
])
def test_camera_without_a_frame(tmp_path, changes, expected):
    message = refuse_scene(tmp_path, changes, expected)
    assert "choose" in message or "must differ from camera.position" in message or "give any" in message


@pytest.mark.parametrize("attenuation", [[1, -1, 0], [-1, 0, 0], [1, 0, -0.5], [0, 0, 0], [0, 0, 1e39]])
def test_attenuation_out_of_range(tmp_path, attenuation):
    # [0, 0, 1] is allowed now (pure 1/d² under the clamp): tests/contracts/test_float_edges.py
    refuse_scene(tmp_path, {"lights.0.attenuation": attenuation}, "lights.0.attenuation:",
                 f"[c, l, q] = {attenuation}", "with 0 ≤ c, l, q ≤ 1e+38, not all zero")


def test_attenuation_name_not_known(tmp_path):
    refuse_scene(tmp_path, {"lights.0.attenuation": "linear"}, "lights.0.attenuation:",
                 'allowed: "none", "inverse_square" or [c, l, q]', "got 'linear'")


# ---------------------------------------------------------------- output

def test_output_folder_missing(tmp_path):
    scene = write_scene(tmp_path)
    run_refused(tmp_path, ["render", str(scene), "-o", "/nonexistent/dir/x.png"],
                "--output: /nonexistent/dir/x.png: the output folder '/nonexistent/dir' does not exist",
                "create it or choose an existing folder", scene=scene)


def test_output_with_unsupported_extension(tmp_path):
    scene = write_scene(tmp_path)
    run_refused(tmp_path, ["render", str(scene), "-o", str(tmp_path / "x.jpg")], "--output: ",
                "must end in .png (8-bit) or .exr (float32), not '.jpg'", scene=scene,
                output=tmp_path / "x.jpg")


def test_scene_output_path_with_unsupported_extension(tmp_path):
    (tmp_path / "x.jpg").write_bytes(SENTINEL)
    refuse_scene(tmp_path, {"output.path": "x.jpg"}, "output.path: 'x.jpg' must end in .png or .exr")
    assert (tmp_path / "x.jpg").read_bytes() == SENTINEL


def test_aovs_with_a_png_output_option(tmp_path):
    """The scene asks for layers (its default output becomes out.exr); -o names a PNG."""
    scene = write_scene(tmp_path, {"output": {"aovs": ["depth"]}})
    run_refused(tmp_path, ["render", str(scene), "-o", str(tmp_path / "out.png")],
                "output.aovs: ['depth'] need an .exr output", "-o", scene=scene)


def test_aovs_with_a_png_output_path(tmp_path):
    refuse_scene(tmp_path, {"output.aovs": ["depth", "normal"]},
                 "output.aovs: ['depth', 'normal'] need an .exr output, but output.path is 'out.png'")


def test_aovs_without_an_output_path_default_to_exr(tmp_path):
    scene = write_scene(tmp_path, {"output": {"aovs": ["depth"]}})
    result = runner.invoke(app, ["render", str(scene), "--quiet"])
    assert result.exit_code == 0, result.output
    channels = raycast_phong.read_image(tmp_path / "out.exr")[1]
    assert channels == ("R", "G", "B", "depth.Z")


# ---------------------------------------------------------------- --set

@pytest.mark.parametrize(("assignment", "expected"), [  # one without '=': tests/cli/test_conventions.py
    ("lights.5.position=[1, 1, 1]", "lights.5: lights is a list of 1 item; allowed indices: 0 to 0"),
    ("objects.first.shape=box", "objects.first: objects is a list of 1 item; allowed indices: 0 to 0"),
    ("render.width.x=3", "render.width is the value 16, not a table, so it has no key 'x'"),
    ("=3", "'' is not a key path"),
])
def test_set_with_bad_syntax_or_index(tmp_path, assignment, expected):
    refuse_scene(tmp_path, {}, f"--set {assignment!r}: ", expected, args=("--set", assignment))


def test_set_splits_at_the_first_equals_sign_so_a_value_may_hold_one():
    """`--set KEY=VALUE`: a key path holds no '=', a value may (a file name, a quoted string): the assignment
    splits at the first one. Catches a split at the last, which made `output.path="a` the key."""
    from raycast_phong.scene.overrides import apply_override
    data: dict = {}
    apply_override(data, 'output.path="a=b.png"')
    apply_override(data, "render.background=[0.5, 0.5, 0.5]")
    assert data == {"output": {"path": "a=b.png"}, "render": {"background": [0.5, 0.5, 0.5]}}


def test_set_value_is_validated_like_the_file(tmp_path):
    refuse_scene(tmp_path, {}, "materials.red.kd: each coefficient must be in [0, 1]",
                 args=("--set", "materials.red.kd=[2, 0, 0]"))


def test_plan_refuses_bad_input_too(tmp_path):
    scene = write_scene(tmp_path, {"camera.fov": 180})
    run_refused(tmp_path, ["plan", str(scene)], "camera.fov: out of range", scene=scene)


@pytest.mark.parametrize("address", ["notaurl", "tcp://host", "tcp://127.0.0.1:0", "tcp://127.0.0.1:99999",
                                     "tcp://127.0.0.1:65536",  # one past the largest port
                                     "tcp://[::1]:8786x", "127.0.0.1 :8786", "tls://127.0.0.1:8786",
                                     "tcp://" + "a" * 10_000 + ":8786", "tcp://" + "a" * 64 + ".org:8786"])
def test_a_scheduler_that_is_not_an_address_is_one_line(tmp_path, address):
    """`batch --scheduler notaurl` was an internal error (Dask's parser raised ValueError in its connection code);
    so were tls:// (Dask wants an SSL context) and a host name past DNS's limits (the idna codec refuses it)."""
    (tmp_path / "s.toml").write_text('[[objects]]\nshape = "icosphere"\n')
    result = runner.invoke(app, ["batch", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"),
                                 "--scheduler", address])
    assert result.exit_code == 2, result.output
    assert result.stderr.count("\n") == 1 and "not a Dask scheduler's address" in result.stderr, result.stderr
    assert not (tmp_path / "out").exists()


def test_numba_threads_that_only_look_like_digits_are_one_line(tmp_path):
    """NUMBA_NUM_THREADS=¹ passed str.isdigit() and int() raised: a traceback for every command."""
    result = runner.invoke(app, ["render", "--width", "8", "--height", "8", "-o", str(tmp_path / "x.png")],
                           env={"NUMBA_NUM_THREADS": "¹"})
    assert result.exit_code == 2 and "NUMBA_NUM_THREADS='¹'" in result.stderr, result.output
    assert result.stderr.count("\n") == 1


def test_an_obj_whose_vertices_have_two_coordinates_is_one_line(tmp_path):
    """`v x y` records: an internal IndexError in the bounding box; now the file and what is allowed."""
    (tmp_path / "flat.obj").write_text("v 0 0\nv 1 0\nv 0 1\nf 1 2 3\n")
    result = runner.invoke(app, ["render", str(tmp_path / "flat.obj"), "-o", str(tmp_path / "x.png")])
    assert result.exit_code == 2, result.output
    assert "gives its vertices 2 coordinate(s) each; allowed: 3 (x, y, z)" in result.stderr
    assert result.stderr.count("\n") == 1 and not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("kind", ["not a library", "FIFO", "missing"])
def test_an_embree_library_variable_that_names_no_library_is_one_line(tmp_path, kind):
    """RAYCAST_PHONG_EMBREE_LIBRARY naming a non-Embree file was an internal error ("reinstall embreex"), and a
    FIFO blocked dlopen for ever: the variable is the user's input, refused in one line naming it, exit 2. In a
    process of its own (the library is loaded once per process) with a timeout."""
    import os
    import subprocess
    import sys
    target = tmp_path / "libfake.so"
    if kind == "not a library":
        target.write_bytes(b"not a shared object\n")
    elif kind == "FIFO":
        os.mkfifo(target)
    env = {**os.environ, "RAYCAST_PHONG_EMBREE_LIBRARY": str(target)}
    env.pop("RAYCAST_PHONG_DEBUG", None)
    done = subprocess.run([sys.executable, "-m", "raycast_phong.cli", "render", "--width", "8", "--height", "8",
                           "-o", str(tmp_path / "x.png")], env=env, capture_output=True, text=True, timeout=120,
                          stdin=subprocess.DEVNULL)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith(f"error: RAYCAST_PHONG_EMBREE_LIBRARY={target}: ") and done.stderr.count("\n") == 1
    assert "internal error" not in done.stderr and not (tmp_path / "x.png").exists()


def test_stdin_or_stdout_closed_is_one_line(tmp_path):
    """`render - <&-`, `batch - <&-` (an AttributeError on None) and `plan >&-` (the same at the final flush):
    one line, exit 2; a command that prints nothing still succeeds with stdout closed."""
    import subprocess
    import sys
    scene = tmp_path / "s.toml"
    scene.write_text('[render]\nwidth = 8\nheight = 8\n[[objects]]\nshape = "icosphere"\n')
    cli = f"{sys.executable} -m raycast_phong.cli"
    cases = {f"{cli} render - -o {tmp_path / 'a.png'} <&-": (2, "standard input is closed"),
             f"{cli} batch - --out {tmp_path / 'out'} <&-": (2, "standard input is closed"),
             f"{cli} plan {scene} >&-": (2, "error: stdout: write failed: standard output is closed"),
             f"{cli} render {scene} -q -o {tmp_path / 'b.png'} >&-": (0, "")}
    for command, (code, says) in cases.items():
        done = subprocess.run(["bash", "-c", command], capture_output=True, text=True, timeout=120)
        assert done.returncode == code and says in done.stderr, (command, done.stderr)
        assert done.stderr.count("\n") == (1 if code else 0), (command, done.stderr)
    assert (tmp_path / "b.png").is_file() and not (tmp_path / "a.png").exists()


def test_a_list_of_paths_one_byte_over_the_limit_is_refused_not_cut(monkeypatch):
    """`batch -` reads one byte past MAX_LISTED_BYTES to know a list is too long: one that is is refused, never
    read in part (its last paths dropped silently); one exactly at the limit is read whole."""
    import io

    from raycast_phong.errors import SceneError
    from raycast_phong.tools.batch import jobs
    monkeypatch.setattr(jobs, "MAX_LISTED_BYTES", 2 << 20)
    line = b"s" * 1023 + b"\n"
    exact = line * 2048  # 2 MiB
    assert len(jobs.listed_paths(io.BytesIO(exact))) == 2048
    with pytest.raises(SceneError, match="the list of scene paths is more than the 2 MiB allowed"):
        jobs.listed_paths(io.BytesIO(exact + b"t"))


def test_a_listed_path_with_a_nul_byte_is_left_out_and_the_batch_goes_on(tmp_path):
    """`batch -` with a NUL byte in one line was an internal error for the whole batch (ValueError: embedded null
    byte): that line is left out with a warning, the others render."""
    import subprocess
    import sys
    scene = tmp_path / "s.toml"
    scene.write_text('[render]\nwidth = 8\nheight = 8\n[[objects]]\nshape = "icosphere"\n')
    done = subprocess.run([sys.executable, "-m", "raycast_phong.cli", "batch", "-", "--out", str(tmp_path / "out"),
                           "-q"], input=f"{scene}\nbad\0name.toml\n".encode(), capture_output=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stderr.decode() == "warning: stdin: line 2: a path with a NUL byte names no file; left out\n"
    assert (tmp_path / "out" / "s.png").is_file()


@pytest.mark.parametrize(("document", "says"), [
    ('{"asset": {"version": "2.0"}, "x": ' + "[" * 100_000 + "]" * 100_000 + "}", "nested deeper"),
    ('{"asset": {"version": "2.0"}, "buffers": 7, "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}]}',
     "cannot read"),
    ('{"asset": {"version": "2.0"}, "meshes": [{"primitives": 5}], "nodes": [{"mesh": 0}], '
     '"scenes": [{"nodes": [0]}]}', "cannot read"),
])
def test_a_gltf_whose_json_is_not_a_gltf_document_is_one_line(tmp_path, document, says):
    """A glTF nested 10⁵ deep (RecursionError) or whose buffer list is a number (TypeError in the side-file
    scan) was an internal error; a primitive list that is a number is trimesh's to word."""
    (tmp_path / "bad.gltf").write_text(document)
    result = runner.invoke(app, ["render", str(tmp_path / "bad.gltf"), "-o", str(tmp_path / "x.png")])
    assert result.exit_code == 2, result.output
    assert says in result.stderr and result.stderr.count("\n") == 1 and "internal error" not in result.stderr


@pytest.mark.parametrize(("given", "lines"), [(b"", 0), (b"a\0b\n\x00\x01\n" * 15, 30)])
def test_a_batch_left_with_no_scene_is_bad_input(tmp_path, given, lines):
    """`batch -` given nothing, or only lines it leaves out (binary input), rendered nothing and said exit 0:
    now exit 2 with one error line, after at most MAX_LEFT_OUT warnings and a count of the rest."""
    import subprocess
    import sys

    from raycast_phong.cli.batch import MAX_LEFT_OUT
    done = subprocess.run([sys.executable, "-m", "raycast_phong.cli", "batch", "-", "--out", str(tmp_path / "out")],
                          input=given, capture_output=True, timeout=300)
    assert done.returncode == 2, done.stderr
    said = done.stderr.decode().splitlines()
    assert said[-1].startswith("error: stdin: no scene to render") and "internal error" not in done.stderr.decode()
    assert len(said) == 1 + min(lines, MAX_LEFT_OUT) + (lines > MAX_LEFT_OUT), said
    if lines > MAX_LEFT_OUT:
        assert said[-2] == f"warning: and {lines - MAX_LEFT_OUT} more path(s) left out"
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("lines", [20, 21])
def test_paths_left_out_are_each_said_up_to_20_and_the_21st_is_counted(tmp_path, lines):
    """MAX_LEFT_OUT (20) warnings are printed whole: 20 left-out lines are 20 warnings and no count (not "and 0
    more"), 21 are 20 warnings and "and 1 more". Catches `>` made `>=` and the limit or the slice moved by one
    (the test above gives 30 lines, far past it)."""
    from raycast_phong.cli.batch import MAX_LEFT_OUT
    done = runner.invoke(app, ["batch", "-", "--out", str(tmp_path / "out")], input=b"a\0b\n" * lines)
    assert done.exit_code == 2, done.output
    said = done.stderr.splitlines()
    warned = [line for line in said if line.startswith("warning: stdin: line ")]
    assert MAX_LEFT_OUT == 20 and len(warned) == 20 and warned[-1].startswith("warning: stdin: line 20:"), said
    counted = [line for line in said if "more path(s) left out" in line]
    assert counted == (["warning: and 1 more path(s) left out"] if lines == 21 else []), said
    # the error counts the paths left out, not the lines printed (20 warnings and a count said "22 line(s)")
    assert f"every path it named was left out, {lines} in all" in said[-1], said


@pytest.mark.parametrize("threads, allowed", [("1", True), ("1024", True), ("0", False), ("1025", False)])
def test_numba_threads_from_1_to_1024_are_taken_and_outside_that_refused(monkeypatch, threads, allowed):
    """NUMBA_NUM_THREADS is checked before numba is imported: a whole number from 1 to 1024, both ends included
    (the message says "from 1 to 1024"); 0 and 1025 are one line (OptionError), not numba's own failure."""
    from raycast_phong.errors import OptionError
    from raycast_phong.io.system import check_environment
    monkeypatch.setenv("NUMBA_NUM_THREADS", threads)
    if allowed:
        assert check_environment() == []
    else:
        with pytest.raises(OptionError, match=f"NUMBA_NUM_THREADS='{threads}'.*from 1 to 1024"):
            check_environment()


@pytest.mark.parametrize("framing", [{"view": "front"}, {"up": "+z"}, {"view": "top", "up": "-y"}])
def test_view_or_up_for_a_scene_file_is_refused_naming_both(tmp_path, framing):
    """--view and --up frame a mesh file; a scene file has its own [camera], so either one given with a scene file
    is refused (not silently ignored), in one line naming the file."""
    from raycast_phong.errors import SceneError
    from raycast_phong.scene.load import load_scene
    path = write_scene(tmp_path)
    with pytest.raises(SceneError) as refused:
        load_scene(path, **framing)
    assert str(refused.value) == f"{path}: --view and --up frame a mesh file; a scene file has its own [camera]"
