"""The `raycast-phong` command through typer's CliRunner: what it writes, prints and exits with.

Bad input (exit 2) has its own file, test_bad_input.py; this one covers the good runs, the
other commands, the help pages and the internal-error path (exit 1).
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from conftest import write_tiny_scene
from typer.testing import CliRunner

import raycast_phong
from raycast_phong.cli import app

runner = CliRunner()

ICOSPHERE_1_TRIANGLES = 80  # 20 faces × 4 after one subdivision


pytestmark = pytest.mark.usefixtures("in_tmp_path")


@pytest.fixture
def tiny_scene(tmp_path) -> Path:
    return write_tiny_scene(tmp_path, 32, 24, '\n[output]\npath = "tiny.png"\n')


def image_spec(path: Path) -> tuple[int, int, int]:
    """(width, height, channels) of an image file, as OpenImageIO reads it."""
    source = oiio.ImageInput.open(str(path))
    assert source is not None, oiio.geterror()
    spec = source.spec()
    source.close()
    return spec.width, spec.height, spec.nchannels


# ---------------------------------------------------------------- render

def test_render_writes_the_png_and_one_summary_line(tiny_scene, tmp_path):
    output = tmp_path / "out.png"
    result = runner.invoke(app, ["render", str(tiny_scene), "-o", str(output)])
    assert result.exit_code == 0, result.output
    assert image_spec(output) == (32, 24, 3)
    lines = result.stdout.strip().splitlines()
    assert len(lines) == 1, result.stdout
    line = lines[0]
    assert line.startswith(f"{output}: 32×24, ")
    assert f"{ICOSPHERE_1_TRIANGLES} triangles" in line
    assert f"{32 * 24:,} rays" in line
    assert re.search(r"\d+\.\d Mrays/s", line), line
    # The sphere (radius 1, 40° view from 4 away) fills the middle and misses the corners.
    image = raycast_phong.read_layer(output)
    assert image[12, 16].max() > 0.1
    np.testing.assert_array_equal(image[0, 0], 0.0)


def test_render_defaults_to_the_scene_output_path(tiny_scene, tmp_path):
    """Without -o the image goes to output.path, relative to the scene file's folder."""
    elsewhere = tmp_path / "cwd"
    elsewhere.mkdir()
    result = runner.invoke(app, ["render", str(tiny_scene), "--quiet"])
    assert result.exit_code == 0, result.output
    assert result.output == ""  # --quiet: no summary line
    assert image_spec(tmp_path / "tiny.png") == (32, 24, 3)
    assert list(elsewhere.iterdir()) == []


def test_render_options_override_the_scene(tiny_scene, tmp_path):
    output = tmp_path / "small.exr"
    result = runner.invoke(app, ["render", str(tiny_scene), "-o", str(output), "--width", "20",
                                 "--set", "render.height=10", "--shading", "flat"])
    assert result.exit_code == 0, result.output
    assert image_spec(output) == (20, 10, 3)
    assert ": 20×10, " in result.stdout


def test_render_without_a_scene_renders_the_default_figure(tmp_path):
    output = tmp_path / "x.png"
    result = runner.invoke(app, ["render", "--width", "96", "--height", "36", "-o", str(output)])
    assert result.exit_code == 0, result.output
    assert image_spec(output) == (96, 36, 3)
    assert "96×36" in result.stdout
    assert "240 triangles" in result.stdout  # three icospheres of 80 faces
    image = raycast_phong.read_layer(output)
    # Three unit spheres 2.4 apart, seen 10 away with fov 24: the image is 2·10·tan 12° = 4.25 units
    # high and 11.3 wide, so their centres fall on columns 28, 48 and 68, and column 58 (x = 1.2)
    # lies in the gap between two of them.
    row = image[18, :, :].max(axis=1)
    assert (row[[28, 48, 68]] > 0.05).all(), row
    np.testing.assert_array_equal(row[[38, 58]], 0.0)
    np.testing.assert_array_equal(image[0, 0], 0.0)
    np.testing.assert_array_equal(image[35, 95], 0.0)


# ---------------------------------------------------------------- plan, schema, help

def test_plan_lists_each_stage_kept_or_left_out():
    result = runner.invoke(app, ["plan"])
    assert result.exit_code == 0, result.output
    lines = result.stdout.strip().splitlines()
    told = [line for line in lines if line.startswith(("warning ", "note "))]
    colour = [line for line in lines if line.startswith("colour ")]
    rows = [re.match(r"(kept|left out)\s+(\w+)\s+\S", line) for line in lines if line not in told + colour]
    assert all(rows), result.stdout  # every other line: status, stage, reason
    # One line for the colour setting, after the stages: the lecture's scene is in display colour by default.
    assert len(colour) == 1 and re.match(r"colour\s+display\s+the default for scene files", colour[0]), colour
    # The lecture's point, found by the plan: the 80-face Gouraud sphere misses its f = 40 highlight. The object
    # chose Gouraud itself (its own `shading` key), so the plan tells it as a note with the advice, not a warning.
    assert len(told) == 1 and told[0].startswith("note      objects.1 (gouraud, its own `shading`)"), told
    assert "subdivisions = 3" in told[0]
    stages = {row[2]: row[1] for row in rows}
    # The default figure: smooth objects need vertex normals; no material glows; no shadows in local mode.
    assert stages["vertex_normals"] == "kept"
    assert stages["emission"] == "left out"
    assert stages["shadow_rays"] == "left out"


def test_plan_follows_set(tiny_scene):
    """An all-flat scene needs no vertex normals; the plan says so."""
    smooth = runner.invoke(app, ["plan", str(tiny_scene)])
    flat = runner.invoke(app, ["plan", str(tiny_scene), "--set", "render.shading=flat"])
    assert smooth.exit_code == flat.exit_code == 0, smooth.output + flat.output
    assert re.search(r"^kept\s+vertex_normals", smooth.stdout, re.M), smooth.stdout
    assert re.search(r"^left out\s+vertex_normals", flat.stdout, re.M), flat.stdout


def test_schema_is_json_schema_of_the_scene_format():
    result = runner.invoke(app, ["schema"])
    assert result.exit_code == 0, result.output
    schema = json.loads(result.stdout)
    assert set(schema["properties"]) == {"render", "camera", "ambient", "lights", "materials", "objects", "output"}
    assert schema["additionalProperties"] is False  # unknown keys are an error, as the format says


def test_every_command_has_help_with_examples():
    names = [command.name or command.callback.__name__ for command in app.registered_commands]
    assert set(names) >= {"render", "plan", "schema"}
    for name in names:
        result = runner.invoke(app, [name, "--help"])
        assert result.exit_code == 0, result.output
        assert "Examples" in result.output, f"`{name} --help` has no Examples"
        assert f"raycast-phong {name}" in result.output


def test_no_arguments_shows_help():
    result = runner.invoke(app, [])
    assert "render" in result.output and "plan" in result.output and "schema" in result.output


# ---------------------------------------------------------------- internal error

def test_internal_error_exits_1_with_one_line(tiny_scene, tmp_path, monkeypatch, error_logs_in_the_session_folder):
    def broken_render(*args, **kwargs):
        raise RuntimeError("kernel exploded")
    from raycast_phong.renderer.prepare import Renderer
    monkeypatch.setattr(Renderer, "render", broken_render)
    output = tmp_path / "out.png"
    output.write_bytes(b"an earlier image")
    result = runner.invoke(app, ["render", str(tiny_scene), "-o", str(output)])
    assert result.exit_code == 1, result.output
    assert isinstance(result.exception, SystemExit)  # the CLI's own exit, not an escaped exception
    assert "Traceback" not in result.output
    [line] = result.output.strip().splitlines()
    assert line.startswith("error: internal error: RuntimeError: kernel exploded (traceback in ")
    log = Path(line.split("(traceback in ")[1].rstrip(")"))
    assert log.parent == error_logs_in_the_session_folder  # $RAYCAST_PHONG_ERROR_LOGS: not /tmp, in a test run
    text = log.read_text(encoding="utf-8")
    log.unlink()
    assert "Traceback" in text and "broken_render" in text and "RuntimeError: kernel exploded" in text
    assert output.read_bytes() == b"an earlier image"


# ---------------------------------------------------------------- reference, study, render --reference

def test_render_with_reference_prints_the_errors(tmp_path):
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    result = CliRunner().invoke(app, ["render", "--width", "60", "--height", "24", "--reference", "analytic",
                                      "-o", str(tmp_path / "r.png"), "-q"])
    assert result.exit_code == 0, result.output
    result = CliRunner().invoke(app, ["render", "--width", "60", "--height", "24", "--reference", "analytic",
                                      "-o", str(tmp_path / "r.png")])
    assert result.exit_code == 0 and "against the analytic reference: RMSE" in result.output and "PSNR" in result.output


def test_the_analytic_reference_is_refused_when_its_image_exceeds_the_budget(tmp_path):
    """Issue 30 item 3: `reference` at 4096² under --max-memory 1G (≈ 1.4 GB of float64 images) is refused in
    one line before any pixel, naming the keys and the budget (before: it ran, and 16384² passed 3 GB under 2G);
    the same size within a larger budget is not refused by this check."""
    from raycast_phong.tools.accuracy import REFERENCE_PIXEL_BYTES, check_reference_memory
    out = tmp_path / "ref.exr"
    result = runner.invoke(app, ["reference", "--set", "render.width=4096", "--set", "render.height=4096",
                                 "--max-memory", "1G", "-o", str(out)])
    assert result.exit_code == 2 and not out.exists(), result.output
    line = result.output.strip().splitlines()[-1]
    assert "render.width × render.height: 4096×4096 pixels need ≈ 1.38 GB" in line and "1 GB budget" in line, line
    scene = raycast_phong.validate_scene({"render": {"width": 4096, "height": 4096},
                                          "objects": [{"shape": "icosphere"}]}, source="s")
    check_reference_memory(scene, 4096 * 4096 * REFERENCE_PIXEL_BYTES)  # exactly the estimate: fits


def test_the_analytic_reference_budget_counts_width_times_height_pixels():
    """A 4096 × 16 reference is 65,536 pixels: it fits a budget of exactly that many pixels' bytes, which a
    4096 × 4096 one (width counted twice) would not; one pixel's bytes less is refused, naming both sizes."""
    from raycast_phong.errors import SceneError
    from raycast_phong.tools.accuracy import REFERENCE_PIXEL_BYTES, check_reference_memory
    scene = raycast_phong.validate_scene({"render": {"width": 4096, "height": 16},
                                          "objects": [{"shape": "icosphere"}]}, source="s")
    check_reference_memory(scene, 4096 * 16 * REFERENCE_PIXEL_BYTES)
    with pytest.raises(SceneError, match="4096×16 pixels"):
        check_reference_memory(scene, 4096 * 16 * REFERENCE_PIXEL_BYTES - REFERENCE_PIXEL_BYTES)


def test_reference_command_and_the_mesh_error(tmp_path):
    from typer.testing import CliRunner

    import raycast_phong as rp
    from raycast_phong.cli import app
    out = tmp_path / "ref.exr"
    result = CliRunner().invoke(app, ["reference", "--set", "render.width=30", "--set", "render.height=12",
                                      "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert rp.read_layer(out).shape == (12, 30, 3)
    scene = tmp_path / "scene.toml"
    scene.write_text('[[objects]]\nshape = "mesh"\npath = "x.ply"\n')
    result = CliRunner().invoke(app, ["reference", str(scene), "-o", str(out)])
    assert result.exit_code == 2
    assert result.output.strip().splitlines()[-1] == (f'error: {scene}: objects.0.shape: "mesh" has no closed '
                                                      'form; use --fine N')


def test_study_command_writes_its_report_and_files(tmp_path):
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    result = CliRunner().invoke(app, ["study", "--width", "24", "--height", "12", "--levels", "0,1",
                                      "--repeats", "1", "--normals", "mean,exact", "--out", str(tmp_path / "s")])
    assert result.exit_code == 0, result.output
    assert {p.name for p in (tmp_path / "s").iterdir()} == {
        "study.csv", "error_vs_time.png", "convergence.png", "silhouette.png", "highlight.png", "orders.png",
        "error_images.png", "summary.md", "report.html"}
    assert "order" in result.output and "RMSE 0.005" in result.output and "machine:" in result.output
    # Each order far from theory says why in the terminal too, the report's words (two levels: all are far).
    reasons = [line.split("|")[5].strip() for line in (tmp_path / "s" / "summary.md").read_text().splitlines()
               if line.count("|") == 10 and " normals, " in line.split("|")[2]]  # the fitted-order table's rows
    assert reasons and all(reason != "–" and "Why not" in result.output and reason in result.output
                           for reason in reasons), (reasons, result.output)
    bad = CliRunner().invoke(app, ["study", "--normals", "file", "--out", str(tmp_path / "u")])
    assert bad.exit_code == 2 and "--normals: 'file' is not one of mean, area, angle, exact" in bad.output
    bad = CliRunner().invoke(app, ["study", "--models", "flat,smooth", "--out", str(tmp_path / "t")])
    assert bad.exit_code == 2 and "--models: 'smooth' is not one of flat, gouraud, phong" in bad.output


@pytest.mark.parametrize("cache", [None, "kernels"])
def test_help_of_every_command_loads_no_array_or_image_library(tmp_path, cache):
    """The CLI modules parse and print: `--help` of any command imports neither numpy nor numba, trimesh, Embree
    or OpenImageIO (each command imports what it runs inside its body); NUMBA_CACHE_DIR set (a string numba
    cannot fail to read) changes nothing: it imported numba and numpy ahead of every command."""
    import os
    import subprocess
    import sys
    env = {name: value for name, value in os.environ.items() if not name.startswith("NUMBA_")}
    if cache:
        env["NUMBA_CACHE_DIR"] = str(tmp_path / cache)
    names = [command.name or command.callback.__name__ for command in app.registered_commands]
    probe = ("import sys\nfrom raycast_phong.cli import app\n"
             "for name in sys.argv[1:]:\n"
             "    try:\n        app([name, '--help'])\n    except SystemExit:\n        pass\n"
             "print([m for m in ('numpy', 'numba', 'trimesh', 'embreex', 'OpenImageIO') if m in sys.modules])")
    done = subprocess.run([sys.executable, "-c", probe, *names], capture_output=True, text=True, timeout=120,
                          env=env)
    assert len(names) == 11 and done.stdout.strip().splitlines()[-1] == "[]", done.stdout[-500:] + done.stderr


TEXTURED = Path(__file__).resolve().parents[2] / "scenes" / "textured_sphere.toml"


def test_plan_says_whether_textures_and_vertex_colours_are_sampled_and_how_maps_are_decoded():
    """`plan` lists the two optional surface terms, kept or left out, how the maps are decoded for the scene's
    render.colour, and the colour setting with its reason."""
    textured = runner.invoke(app, ["plan", str(TEXTURED)])
    assert textured.exit_code == 0, textured.output
    line = next(line for line in textured.output.splitlines() if line.split()[1:2] == ["textures"])
    assert line.startswith("kept") and "checker.png" in line and "used as stored (colour = display)" in line
    assert re.search(r"^colour\s+display\s+the default for scene files", textured.output, re.M), textured.output
    assert re.search(r"left out\s+vertex_colours", textured.output)
    knot = runner.invoke(app, ["plan", str(TEXTURED.parent / "meshes" / "painted_knot.ply")])
    assert re.search(r"kept\s+vertex_colours", knot.output) and re.search(r"left out\s+textures", knot.output)
    assert re.search(r"^colour\s+display\s+the default for a \.ply file rendered directly", knot.output, re.M)
    linear = runner.invoke(app, ["plan", str(TEXTURED), "--set", "render.colour=linear"])
    assert "8-bit ones decoded from sRGB to linear values (colour = linear)" in linear.output, linear.output
    assert re.search(r"^colour\s+linear\s+render.colour is set", linear.output, re.M), linear.output


def test_a_textured_render_says_nothing_about_its_maps_brightness(tmp_path):
    """Today's default shows a map as its image does: the note that apologised for darker maps on every
    textured PNG (no --srgb) is gone, in both colour settings."""
    sets = ["--width", "16", "--height", "12"]
    for extra in ([], ["--srgb"], ["--set", "render.colour=linear"]):
        done = runner.invoke(app, ["render", str(TEXTURED), "-o", str(tmp_path / "a.png"), *sets, *extra])
        assert done.exit_code == 0, done.output
        assert "note:" not in done.output and "darker" not in done.output, done.output


def test_an_error_line_of_exactly_the_limit_is_kept_whole_and_one_more_is_cut():
    """Every error line passes cli.common.one_line: up to MESSAGE_CHARACTERS (2000) it is kept whole, one character
    more is cut to 2000 with the count left out; a line feed is shown escaped, never ends the line."""
    from raycast_phong.cli.common import MESSAGE_CHARACTERS, one_line
    assert MESSAGE_CHARACTERS == 2000
    assert one_line("a" * 2000) == "a" * 2000
    assert one_line("a" * 2001) == "a" * 2000 + "… (1 more characters)"
    assert one_line("a\nb") == "a\\nb"


def test_scene_verbose_names_every_file_the_scene_reads_and_not_the_one_it_writes(tmp_path):
    """`scene --verbose`: one `reads KEY: PATH` line on stderr for each file the scene reads (a mesh, a map),
    resolved from the scene's folder; not output.path, the file a render writes; the TOML still on stdout."""
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    raycast_phong.write_image(tmp_path / "paint.png", np.zeros((2, 2, 3), np.float32))
    (tmp_path / "s.toml").write_text('[materials.a]\nkd_map = "paint.png"\n[[objects]]\nshape = "mesh"\n'
                                     'path = "tri.obj"\n[[objects]]\nshape = "plane"\nmaterial = "a"\n'
                                     '[output]\npath = "shot.png"\n')
    done = runner.invoke(app, ["scene", "--verbose", str(tmp_path / "s.toml")])
    assert done.exit_code == 0, done.output
    reads = sorted(line for line in done.stderr.splitlines() if line.startswith("reads "))
    assert reads == [f"reads materials.a.kd_map.path: {tmp_path / 'paint.png'}",
                     f"reads objects.0.path: {tmp_path / 'tri.obj'}"], done.stderr
    assert "shot.png" in done.stdout and "shot.png" not in done.stderr
    quiet = runner.invoke(app, ["scene", str(tmp_path / "s.toml")])
    assert quiet.exit_code == 0 and "reads " not in quiet.stderr
