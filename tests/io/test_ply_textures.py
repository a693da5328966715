"""PLY texture comments (issue 33): MeshLab's `comment TextureFile NAME` with per-face `texcoord` lists renders
its image (it rendered grey, and a missing image printed trimesh's 10-line traceback). Minimal files written here."""

from __future__ import annotations

from pathlib import Path

import pytest
from PIL import Image
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app
from raycast_phong.io.meshes.source import mesh_source

runner = CliRunner()
pytestmark = pytest.mark.usefixtures("in_tmp_path")


def write_ply(path: Path, texture: str) -> Path:
    """A unit square facing +Z, two triangles with per-face texcoord lists, as MeshLab writes it."""
    path.write_text("ply\nformat ascii 1.0\ncomment VCGLIB generated\n"
                    f"comment TextureFile {texture}\nelement vertex 4\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
                    "property list uchar float texcoord\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n"
                    "3 0 1 2 6 0 0 1 0 1 1\n3 0 2 3 6 0 0 1 1 0 1\n")
    return path


def test_a_texture_file_comment_renders_its_image(tmp_path):
    """`<this>` is the PLY's own name (MeshLab's placeholder): sq.ply's map is sq_tex.png, a red image."""
    Image.new("RGB", (4, 4), (220, 20, 20)).save(tmp_path / "sq_tex.png")
    write_ply(tmp_path / "sq.ply", "<this>_tex.png")
    image = rp.render_file(tmp_path / "sq.ply", ["render.width=40", "render.height=40", "lights.0.specular=[0,0,0]",
                                                  "render.background=[0,0,0]"],
                           view="front").image
    covered = image.max(axis=2) > 0
    assert covered.mean() > 0.2 and (image[covered][:, 0] > 4 * image[covered][:, 1]).all()


def test_a_missing_texture_file_is_one_note(tmp_path):
    write_ply(tmp_path / "sq.ply", "gone.png")
    done = runner.invoke(app, ["render", str(tmp_path / "sq.ply"), "-o", str(tmp_path / "x.png"), "--set",
                               "render.width=20", "--set", "render.height=20"])
    assert done.exit_code == 0, done.output
    [line] = done.stderr.strip().splitlines()
    assert line.startswith("note:") and "'gone.png' is missing" in line, done.stderr


@pytest.mark.parametrize(("u", "largest"), [("1e39", "1e+39"), ("-4e38", "4e+38")])
def test_a_texture_coordinate_past_float32_is_refused_with_the_largest_and_the_range(tmp_path, u, largest):
    """Texture coordinates are kept as float32 per corner: a PLY's double `s` of 1e39 would become inf there, so
    the file is refused in one line naming it, the largest magnitude and the range (what any reader's coordinates
    are held to, not only OBJ's own check); NaN passes (the kernel reads it as 0)."""
    path = tmp_path / "far.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "property double s\nproperty double t\nelement face 1\nproperty list uchar int vertex_indices\n"
                    f"end_header\n0 0 0 {u} 0\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n")
    done = runner.invoke(app, ["render", str(path), "-o", str(tmp_path / "far.png")])
    assert done.exit_code == 2, done.output
    assert f"far.ply: has a texture coordinate beyond float32's range (largest {largest}); allowed: " \
           "-3.403e+38 .. 3.403e+38" in done.output
    assert not (tmp_path / "far.png").exists()
    path.write_text(path.read_text().replace(u, "nan"))
    assert runner.invoke(app, ["render", str(path), "-o", str(tmp_path / "far.png")]).exit_code == 0


def test_several_texture_files_use_the_first_with_a_note(tmp_path):
    """MeshLab names one TextureFile per image and gives each face a `texnumber`; one map is read per file: the
    first (texnumber 0's), for every face, and a note says how many were named. trimesh's reader keeps the last
    TextureFile: here b.png, which is missing, so the square was drawn in trimesh's grey while the note said
    a.png was read. Catches the note dropped, and the last image read."""
    Image.new("RGB", (4, 4), (220, 20, 20)).save(tmp_path / "a.png")
    path = write_ply(tmp_path / "sq.ply", "a.png")
    path.write_text(path.read_text().replace("comment TextureFile a.png\n",
                                             "comment TextureFile a.png\ncomment TextureFile b.png\n"))
    mesh = mesh_source(path).read()
    assert mesh.notes == (f"{path}: names 2 TextureFile images (a texture number per face); only the first, 'a.png', "
                          "is read, for every face",), mesh.notes
    image = mesh.texture_sources[mesh.materials[mesh.face_group[0]].kd_map].source
    assert image.getpixel((0, 0))[:3] == (220, 20, 20)  # a.png's red
