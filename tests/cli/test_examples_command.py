"""`raycast-phong scene` alone and `scene --example NAME` (issue 48): the built-in default and the shipped example
scenes are reachable from any folder, with their meshes and maps named where the package keeps them."""

from __future__ import annotations

from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app
from raycast_phong.scene.schema import example_names

runner = CliRunner()


def test_scene_alone_writes_the_default_scene(tmp_path):
    done = runner.invoke(app, ["scene", "-o", str(tmp_path / "d.toml")])
    assert done.exit_code == 0, done.output
    default = rp.load_scene(rp.default_scene_path())
    assert rp.load_scene(tmp_path / "d.toml").objects == default.objects


def test_an_example_is_written_with_its_files_reachable_from_elsewhere(tmp_path):
    done = runner.invoke(app, ["scene", "--example", "mesh", "-o", str(tmp_path / "m.toml")])
    assert done.exit_code == 0, done.output
    result = rp.render_file(tmp_path / "m.toml", ["render.width=32", "render.height=18"])
    assert result.triangles > 1000  # the torus knot, found through the written relative path


def test_example_list_and_a_misspelt_name():
    listed = runner.invoke(app, ["scene", "--example", "list"])
    assert listed.exit_code == 0 and listed.stdout.split() == example_names() and "default" in example_names()
    wrong = runner.invoke(app, ["scene", "--example", "mesj"])
    assert wrong.exit_code == 2 and "did you mean 'mesh'" in wrong.output and "\n" not in wrong.output.strip()


def test_an_example_and_a_scene_together_are_refused(tmp_path):
    done = runner.invoke(app, ["scene", "x.obj", "--example", "mesh"])
    assert done.exit_code == 2 and "give one of them" in done.output


def test_an_error_in_the_built_in_scene_names_it_not_its_installed_path(tmp_path):
    """With no scene argument the built-in scene is read from deep inside the package (site-packages from a
    wheel): its errors name it as a user would, "the built-in scene (default.toml)", the path nowhere."""
    done = runner.invoke(app, ["render", "--set", "camera.fov=500", "-o", str(tmp_path / "a.png")])
    assert done.exit_code == 2
    assert done.output.startswith("error: the built-in scene (default.toml): camera.fov: out of range"), done.output
    assert str(rp.default_scene_path()) not in done.output
