"""Outputs and paths: an output that is a folder or one of the inputs is refused (exit 2) before any rendering;
a scene's own output.path stays in its folder unless -o says otherwise; compare fails NaN and inf pixels;
`stability` writes into a fresh temporary folder of its own.
"""

from __future__ import annotations

import importlib
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import write_tiny_scene
from typer.testing import CliRunner

import raycast_phong
import raycast_phong as rp
from raycast_phong.cli import app

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.usefixtures("in_tmp_path")


@pytest.fixture
def no_render(monkeypatch):
    """Fail the test if a command gets as far as rendering."""
    # Imported before the patches: study's `from .accuracy import reference_image` must bind the real one.
    importlib.import_module("raycast_phong.tools.study")

    def render(*args, **kwargs):
        pytest.fail("the command reached the renderer; the output should have been refused first")
    from raycast_phong.renderer.prepare import Renderer
    monkeypatch.setattr(raycast_phong, "render", render)
    monkeypatch.setattr(Renderer, "prepare", render)  # every render goes through a session's prepare()
    monkeypatch.setattr("raycast_phong.tools.accuracy.reference_image", render)
    monkeypatch.setattr("raycast_phong.tools.study.run_study", render)


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def refused(folder: Path, args: list[str], *expected: str) -> str:
    """Run the CLI; expect exit 2, one line naming every `expected` part, and nothing written or changed."""
    before = snapshot(folder)
    result = runner.invoke(app, args)
    assert result.exit_code == 2, (result.exit_code, result.output, result.exception)
    assert isinstance(result.exception, SystemExit) and "Traceback" not in result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    for part in expected:
        assert part in lines[0], f"{part!r} not in {lines[0]}"
    assert snapshot(folder) == before
    return lines[0]


@pytest.fixture
def scene(tmp_path) -> Path:
    return write_tiny_scene(tmp_path, 16, 16)


@pytest.mark.parametrize("command", [
    ["render", "{scene}", "-o", "{tmp}/out.png"],
    ["reference", "{scene}", "-o", "{tmp}/out.png"],
    ["side-by-side", "{scene}", "--vary", "render.shading=flat,phong", "-o", "{tmp}/out.png"],
])
def test_no_render_stops_a_command_that_reaches_the_renderer(scene, tmp_path, no_render, command):
    """The control for the tests that use `no_render`: with a good output, each command does reach a patched
    name (so a refusal below is one made before rendering, not a command the patch never sees)."""
    args = [part.format(scene=scene, tmp=tmp_path) for part in command]
    with pytest.raises(pytest.fail.Exception, match="reached the renderer"):
        runner.invoke(app, args, catch_exceptions=False)


# ---------------------------------------------------------------- a folder as the output

@pytest.mark.parametrize("command", [
    ["render", "{scene}", "-o", "{folder}"],
    ["reference", "{scene}", "-o", "{folder}"],
    ["side-by-side", "{scene}", "--vary", "render.shading=flat,phong", "-o", "{folder}"],
])
@pytest.mark.parametrize("name", ["looks-like.png", "outdir"])
def test_an_output_that_is_a_folder_is_refused_before_rendering(scene, tmp_path, no_render, command, name):
    """Named like an image or not: a folder is said to be one (`-o outdir` said "it has no extension"), with a
    file name in it to give instead."""
    folder = tmp_path / name
    folder.mkdir()
    (folder / "kept.txt").write_text("inside")
    args = [part.format(scene=scene, folder=folder) for part in command]
    said = refused(tmp_path, args, str(folder), "is a folder")
    assert "extension" not in said, said
    assert folder.is_dir()


def test_compare_diff_onto_a_folder_is_refused(tmp_path):
    a = rp.write_image(tmp_path / "a.exr", np.zeros((2, 2, 3), np.float32))
    folder = tmp_path / "diff.png"
    folder.mkdir()
    refused(tmp_path, ["compare", str(a), str(a), "--diff", str(folder)], str(folder), "is a folder")


def test_study_out_that_is_a_file_or_holds_a_folder_of_an_output_name_is_refused(scene, tmp_path, no_render):
    (tmp_path / "study.txt").write_text("a file")
    refused(tmp_path, ["study", str(scene), "--out", str(tmp_path / "study.txt")], "must be a folder")
    out = tmp_path / "study"
    (out / "study.csv").mkdir(parents=True)
    refused(tmp_path, ["study", str(scene), "--out", str(out)], str(out / "study.csv"), "is a folder")


# ---------------------------------------------------------------- an input as the output

@pytest.mark.parametrize("spelling", ["same", "relative", "dotted", "link"])
def test_compare_diff_onto_one_of_the_compared_images_is_refused(tmp_path, spelling):
    a = rp.write_image(tmp_path / "a.png", np.full((4, 4, 3), 0.25, np.float32))
    b = rp.write_image(tmp_path / "b.png", np.full((4, 4, 3), 0.75, np.float32))
    if spelling == "link":
        (tmp_path / "link.png").symlink_to(b)
    diff = {"same": str(b), "relative": "b.png", "dotted": f"{tmp_path}/sub/../b.png", "link": "link.png"}[spelling]
    (tmp_path / "sub").mkdir()
    refused(tmp_path, ["compare", str(a), str(b), "--diff", diff], diff, "is the input")


@pytest.mark.parametrize("command", ["render", "reference"])
def test_an_output_onto_the_scene_file_is_refused(tmp_path, no_render, command):
    """A scene file read through a link named like an image: -o onto that name would replace the scene."""
    scene = write_tiny_scene(tmp_path, 16, 16)
    disguised = tmp_path / "scene.png"
    disguised.symlink_to(scene)
    refused(tmp_path, [command, str(disguised), "-o", str(tmp_path / "." / "scene.png")], "is the input")


def test_the_side_by_side_sibling_exr_may_not_be_the_scene(tmp_path, no_render):
    """NAME.png writes NAME-variants.exr too: a scene file of that name is refused, not replaced."""
    scene = write_tiny_scene(tmp_path, 16, 16)
    disguised = tmp_path / "cmp-variants.exr"
    disguised.symlink_to(scene)
    refused(tmp_path, ["side-by-side", str(disguised), "--vary", "render.shading=flat,phong", "-o",
                       str(tmp_path / "cmp.png")], "is the input")


# ---------------------------------------------------------------- a scene's own output.path

@pytest.mark.parametrize("path", ["../escaped.png", "sub/../../escaped.png", "{tmp}/escaped.png", "~/escaped.png"])
def test_a_scene_output_path_may_not_leave_the_scene_folder(tmp_path, monkeypatch, no_render, path):
    """An absolute path, ~ or '..' is refused as spelled, before its real location is looked at: the line says
    the path leaves the folder, not that a symbolic link (there is none) takes it out."""
    monkeypatch.setenv("HOME", str(tmp_path))  # so that ~ is tmp_path: even a failing run writes nowhere else
    path = path.format(tmp=tmp_path)
    folder = tmp_path / "scenes"
    folder.mkdir()
    scene = write_tiny_scene(folder, 16, 16, f'\n[output]\npath = "{path}"\n')
    message = refused(tmp_path, ["render", str(scene)], str(scene), "output.path", path, "-o")
    assert "leaves the scene's folder (an absolute path, ~ or '..')" in message and "symbolic link" not in message
    assert not (tmp_path / "escaped.png").exists()


def test_the_command_line_may_write_outside_the_scene_folder(tmp_path):
    folder = tmp_path / "scenes"
    folder.mkdir()
    scene = write_tiny_scene(folder, 8, 8, '\n[output]\npath = "../escaped.png"\n')
    result = runner.invoke(app, ["render", str(scene), "-q", "-o", str(folder / ".." / "chosen.png")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "chosen.png").is_file() and not (tmp_path / "escaped.png").exists()


def test_a_scene_output_path_below_its_folder_is_written_there(tmp_path):
    (tmp_path / "renders").mkdir()
    scene = write_tiny_scene(tmp_path, 8, 8, '\n[output]\npath = "renders/./x.png"\n')
    assert runner.invoke(app, ["render", str(scene), "-q"]).exit_code == 0
    assert (tmp_path / "renders" / "x.png").is_file()


# ---------------------------------------------------------------- compare: NaN and inf

def test_compare_fails_an_image_with_nan_or_inf_pixels_and_counts_them(tmp_path):
    image = np.zeros((4, 5, 3), np.float32)
    bad = image.copy()
    bad[0, 0, 1] = np.nan          # 2 pixels with NaN (one of them also infinite)
    bad[3, 4] = [np.nan, np.inf, 0]
    bad[1, 2, 0] = -np.inf         # and 2 with inf
    a = rp.write_image(tmp_path / "a.exr", image)
    b = rp.write_image(tmp_path / "b.exr", bad)
    # Against itself (OpenImageIO counts no difference) and with every pixel allowed to fail: still a failure.
    for args in ([str(b), str(b)], [str(a), str(b), "--fail-percent", "100"]):
        result = runner.invoke(app, ["compare", *args])
        assert result.exit_code == 1, result.output
        assert f"FAILURE: {b}: 2 pixels with NaN, 2 with inf" in result.stdout
        assert "RuntimeWarning" not in result.output
    assert f"{a}:" not in runner.invoke(app, ["compare", str(a), str(b)]).stdout  # the finite image is not named


def test_the_diff_of_an_image_with_nan_shows_it_at_the_top_of_the_scale(tmp_path):
    image = np.zeros((2, 3, 3), np.float32)
    bad = image.copy()
    bad[0, 0] = 0.5
    bad[1, 2, 2] = np.nan
    a, b = rp.write_image(tmp_path / "a.exr", image), rp.write_image(tmp_path / "b.exr", bad)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = runner.invoke(app, ["compare", str(a), str(b), "--diff", str(tmp_path / "d.exr")])
    assert result.exit_code == 1 and not [str(w.message) for w in caught]
    heat = rp.read_layer(tmp_path / "d.exr")
    assert np.isfinite(heat).all()
    np.testing.assert_allclose(heat[0, 0], [0.988362, 0.998364, 0.644924], atol=1e-6)  # 0.5, the largest: pale yellow
    np.testing.assert_allclose(heat[1, 2], heat[0, 0])  # NaN drawn at the top of the scale too
    np.testing.assert_allclose(heat[0, 1], [0.001462, 0.000466, 0.013866], atol=1e-6)  # no difference: black


# ---------------------------------------------------------------- stability's scratch folder

def test_stability_writes_into_a_fresh_temporary_folder(tmp_path):
    """A file planted where the suite used to write (TMP/raycast-phong-stability) changes nothing, and the
    run leaves nothing behind in TMP."""
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    (temporary / "raycast-phong-stability").write_text("planted by someone else")
    env = {**{k: v for k, v in os.environ.items() if k != "RAYCAST_PHONG_DEBUG"}, "TMPDIR": str(temporary)}
    done = subprocess.run([sys.executable, "-m", "raycast_phong.cli", "stability", "--case",
                           "perspective_against_screen", "--json"],
                          cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert '"passed": true' in done.stdout
    assert sorted(p.name for p in temporary.iterdir()) == ["raycast-phong-stability"]
    assert (temporary / "raycast-phong-stability").read_text() == "planted by someone else"


def test_layers_go_to_an_exr_output_whatever_the_case_of_its_suffix(tmp_path):
    """output.aovs need an .exr: `-o OUT.EXR` is one (check_output_path takes the suffix in any case, and so must
    the layers' check), so the render writes it with its depth layer; `-o OUT.PNG` is still refused."""
    scene = write_tiny_scene(tmp_path, 8, 6, '\n[output]\naovs = ["depth"]\n')
    result = runner.invoke(app, ["render", str(scene), "-o", str(tmp_path / "OUT.EXR")])
    assert result.exit_code == 0, result.output
    assert rp.read_layer(tmp_path / "OUT.EXR", "depth").shape == (6, 8, 1)
    result = runner.invoke(app, ["render", str(scene), "-o", str(tmp_path / "OUT.PNG")])
    assert result.exit_code == 2 and "need an .exr output" in result.stderr, result.output
