"""`raycast-phong scene` refusals: an -o naming the mesh file it reads (under any spelling) leaves the file as it
was, and a line feed in a path keeps the error on one line."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from typer.testing import CliRunner

from raycast_phong.cli import app
from raycast_phong.errors import OptionError

runner = CliRunner()
pytestmark = pytest.mark.usefixtures("in_tmp_path")
TRIANGLE = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def one_error_line(result) -> str:
    lines = result.stderr.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


@pytest.mark.parametrize("spelling", ["m.obj", "./m.obj", "sub/../m.obj", "symlink.obj", "hardlink.obj"])
def test_scene_o_naming_its_own_mesh_is_refused_and_the_mesh_kept(tmp_path, spelling):
    """Catches `scene m.obj -o m.obj` (or another spelling of it) writing the TOML over the mesh."""
    mesh = tmp_path / "m.obj"
    mesh.write_bytes(TRIANGLE)
    (tmp_path / "sub").mkdir()
    (tmp_path / "symlink.obj").symlink_to(mesh)
    os.link(mesh, tmp_path / "hardlink.obj")
    line = one_error_line(runner.invoke(app, ["scene", "m.obj", "-o", spelling]))
    assert "the output is the input" in line
    assert mesh.read_bytes() == TRIANGLE and (tmp_path / "symlink.obj").is_symlink()


def test_scene_o_naming_its_meshs_material_file_is_refused_and_the_file_kept(tmp_path):
    """Catches `scene t.obj -o t.mtl` writing TOML over the material library the OBJ reads (found by a replay of
    issue 50's cases): every file the scene reads is an input, not only the one named on the command line."""
    (tmp_path / "t.obj").write_bytes(b"mtllib t.mtl\nusemtl red\n" + TRIANGLE)
    (tmp_path / "t.mtl").write_text("newmtl red\nKd 1 0 0\n")
    line = one_error_line(runner.invoke(app, ["scene", "t.obj", "-o", "t.mtl"]))
    assert "the output is the input t.mtl" in line
    assert (tmp_path / "t.mtl").read_text() == "newmtl red\nKd 1 0 0\n"


@pytest.mark.parametrize("command", [["render"], ["reference"],
                                     ["side-by-side", "--vary", "render.shading=flat,phong"]])
def test_an_image_output_that_is_a_map_the_scene_reads_is_refused_and_kept(tmp_path, command):
    """Catches `render s.toml -o tex.png` writing the image over the colour map the scene reads (and the same
    for the reference and side-by-side): refused before anything renders, the map unchanged."""
    import numpy as np

    from raycast_phong.io.image_io import write_image
    write_image(tmp_path / "tex.png", np.full((4, 4, 3), 0.5, np.float32))
    kept = (tmp_path / "tex.png").read_bytes()
    (tmp_path / "s.toml").write_text('[render]\nwidth = 16\nheight = 12\n[materials.m]\nkd_map = "tex.png"\n'
                                     '[[objects]]\nshape = "plane"\nmaterial = "m"\n')
    line = one_error_line(runner.invoke(app, [command[0], "s.toml", *command[1:], "-o", "tex.png"]))
    assert "the output is the input tex.png" in line
    assert (tmp_path / "tex.png").read_bytes() == kept


def test_scene_o_beside_its_mesh_still_writes(tmp_path):
    """Catches a refusal too wide: an -o beside the mesh (another file) must still be written."""
    (tmp_path / "m.obj").write_bytes(TRIANGLE)
    result = runner.invoke(app, ["scene", "m.obj", "-o", "m.toml"])
    assert result.exit_code == 0, result.output
    assert 'path = "m.obj"' in (tmp_path / "m.toml").read_text() and (tmp_path / "m.obj").read_bytes() == TRIANGLE


def test_a_line_feed_in_the_scene_path_stays_one_line(tmp_path):
    """Catches a path with a line feed printed raw: in the command's error line, and in the OptionError's words."""
    from raycast_phong.cli.scene import _chosen
    assert r"a\nb.obj" in one_error_line(runner.invoke(app, ["scene", "a\nb.obj"]))
    assert r"a\nb.obj" in one_error_line(runner.invoke(app, ["scene", "a\nb.obj", "--example", "mesh"]))
    with pytest.raises(OptionError) as refused:
        _chosen(Path("a\nb.obj"), "mesh")
    assert "\n" not in str(refused.value) and r"'a\nb.obj'" in str(refused.value)
