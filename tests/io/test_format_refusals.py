"""Broken files trimesh cannot read are refused in the renderer's words, naming the line, never with trimesh's or
numpy's exception text (issue 33). Minimal files written here, after openscad's invalidvertex.stl and
unparseable.stl, tinyobjloader's test-nan.obj and assimp's fuzzed crash-*.ply."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from raycast_phong.cli import app

runner = CliRunner()
pytestmark = pytest.mark.usefixtures("in_tmp_path")

STL = ("solid s\n facet normal 0 0 1\n  outer loop\n   vertex 0 0 0\n   vertex 1 0 0\n   {third}\n  endloop\n"
       " endfacet\nendsolid s\n")
PLY_HEAD = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"

CASES = {
    "word.stl": (STL.format(third="vertex 0 1 blah").encode(), "line 6: a vertex needs three numbers (x y z), "
                 "and 'blah' is not a number"),
    "control.stl": (STL.format(third="vertex 0 \x10 1").encode(), "line 6: a vertex needs three numbers (x y z), "
                    "and '\\x10' is not a number"),
    "ind.obj": (b"v 0 0 0\nv 1 0 0 # a comment\nv 1.#IND 1 0\nf 1 2 3\n",
                "line 3: v value '1.#IND' is not a number; allowed: decimal numbers"),
    "fuzzed.ply": (PLY_HEAD + b"property \x00\x00\x00\t\x07\x00\x00\x00\x03",
                   "header line 5: property type '\\x00\\x00\\x00' is not a PLY type"),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_broken_file_is_refused_naming_its_line(tmp_path, name):
    data, expected = CASES[name]
    (tmp_path / name).write_bytes(data)
    done = runner.invoke(app, ["render", str(tmp_path / name), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    message = " ".join(done.stderr.split())
    assert f"{name}: {expected}" in message, message  # the path once (issue 45), then the line
    assert message.count(name) == 1, message
    assert "Error" not in message and "Traceback" not in done.output and not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("suffix, text", [(".gltf", b'{"asset": {"version": "2.0"}}'), (".obj", b"v 0 0 0\n"),
                                          (".ply", b"ply\nformat ascii 1.0\n")])
def test_a_utf8_byte_order_mark_before_a_text_format_is_not_its_content(tmp_path, suffix, text):
    """Editors on Windows write a UTF-8 byte-order mark (EF BB BF) first: the content check reads past it, so a
    .gltf whose JSON follows a BOM is still JSON (not refused as "does not start as a glTF file does"), an OBJ
    still an OBJ and a PLY a PLY."""
    from raycast_phong.io.meshes import content, format_of
    assert content.sniff(b"\xef\xbb\xbf" + text) == content.sniff(text) == {".gltf": "JSON", ".obj": "OBJ",
                                                                               ".ply": "PLY"}[suffix]
    path = tmp_path / f"bom{suffix}"
    path.write_bytes(b"\xef\xbb\xbf" + text)
    content.check_file_content(path, format_of(path), "bom")  # no SceneError


@pytest.mark.parametrize("vertices", ["   vertex 0 0 0\n   vertex 1 0 0\n",
                                      "   vertex 0 0 0\n   vertex 1 0 0\n   vertex 0 1 0\n   vertex 0 1 1\n"])
def test_an_ascii_stl_trimesh_cannot_read_whose_vertex_lines_are_right_is_refused_in_general_words(tmp_path,
                                                                                                    vertices):
    """A facet's outer loop holds exactly three vertices (the STL format); one of two or four, each vertex line
    three numbers, stops trimesh's reader. No vertex line is to blame, so no line is named: the refusal is the
    general one, exit 2, one line. Catches a line blamed where none is wrong."""
    text = STL.format(third="").replace("   vertex 0 0 0\n   vertex 1 0 0\n   \n", vertices)
    (tmp_path / "loop.stl").write_text(text)
    done = runner.invoke(app, ["render", str(tmp_path / "loop.stl"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert line == (f"error: {tmp_path / 'loop.stl'}: cannot read the file as STL: its content does not follow the "
                    "STL format where the reader stopped (the file is corrupt, cut short, or another format); allowed: "
                    "a mesh file of a format read here (OBJ, PLY, STL, OFF, glTF/GLB, 3MF, COLLADA)"), line
    assert not (tmp_path / "x.png").exists()


def _suffixes() -> list[str]:
    from raycast_phong.io.meshes import FORMATS
    return [suffix for kind in FORMATS for suffix in kind.suffixes]


@pytest.mark.parametrize("suffix", _suffixes())
def test_a_git_lfs_pointer_is_named_as_one_for_every_format(tmp_path, suffix):
    """A model from a repository cloned without Git LFS is a three-line pointer (f3d's testing/data, a fresh
    corpus): it was 'holds no triangles' as an OBJ, 'a binary STL whose header counts 959,853,881 triangles', a
    COLLADA 'corpus cut short'. Every format of the registry says what it is and how to fetch the file."""
    pointer = ("version https://git-lfs.github.com/spec/v1\noid sha256:"
               "01fcfd22f33506876c80cf8e889569e8a1843e9330be86d21a39a19f41a01936\nsize 787284\n")
    (tmp_path / f"model{suffix}").write_text(pointer)
    done = runner.invoke(app, ["render", str(tmp_path / f"model{suffix}"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    line = " ".join(done.stderr.split())
    assert "is a Git LFS pointer to the 787,284 bytes of the real file" in line and "git lfs pull" in line, line
    assert done.stderr.count("\n") == 1 and not (tmp_path / "x.png").exists()


def test_an_mni_surface_object_named_obj_is_named_as_one(tmp_path):
    """An MNI (BIC) surface object shares the .obj suffix (neuroimaging: pyvista's vtk-data mni-surface-mesh.obj):
    read as a Wavefront OBJ it 'holds no triangles'. Its 'P' line says what it is; a Wavefront OBJ whose first
    word is a vertex is still read."""
    (tmp_path / "brain.obj").write_text("P 0.3 0.3 0.4 10 1 3\n0 0 0\n1 0 0\n0 1 0\n\n0 0 1\n0 0 1\n0 0 1\n\n1\n"
                                        "0 1 1 1 1\n\n3\n\n0 1 2\n")
    done = runner.invoke(app, ["render", str(tmp_path / "brain.obj"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    line = " ".join(done.stderr.split())
    assert "its content is an MNI (BIC) surface object" in line and "shares the .obj suffix" in line, line
    (tmp_path / "plain.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert runner.invoke(app, ["render", str(tmp_path / "plain.obj"), "-o", str(tmp_path / "y.png"), "-q"]
                         ).exit_code == 0
