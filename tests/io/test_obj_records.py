"""OBJ records read as the OBJ and MTL specifications say (issue 33): relative face indices, several .mtl files on
one `mtllib`, index 0 refused, a map option after its file name, vertex colours beside materials.

Each case is a minimal file written here, checked against positions, names and colours worked out by hand.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from raycast_phong.cli import app
from raycast_phong.io.meshes import mtl
from raycast_phong.io.meshes import read as mesh_file
from raycast_phong.io.meshes.source import mesh_source, read_mesh

runner = CliRunner()
pytestmark = pytest.mark.usefixtures("in_tmp_path")


def read(path: Path) -> mesh_file.MeshFile:
    return read_mesh(path, str(path))


def triangles(mesh: mesh_file.MeshFile) -> list[tuple]:
    """Each face's corner positions, in file order per face, sorted over faces (trimesh may group them)."""
    return sorted(tuple(map(tuple, mesh.vertices[face].round(9).tolist())) for face in mesh.faces)


SQUARE = "v 0 0 {z}\nv 1 0 {z}\nv 1 1 {z}\nv 0 1 {z}\n"


def square(z: float) -> list[tuple]:
    """The two triangles of the square at height z, fanned from its first corner as trimesh fans a quad."""
    a, b, c, d = (0, 0, z), (1, 0, z), (1, 1, z), (0, 1, z)
    return [(a, b, c), (c, d, a)]


def test_relative_face_indices_count_back_from_their_own_line(tmp_path):
    """`f -4 -3 -2 -1` names the four `v` lines above it, not the file's last four: two squares stay two
    (a Cornell box collapsed onto one quad). Triangles, quads and a concave polygon alike."""
    concave = "v 0 0 5\nv 4 0 5\nv 4 4 5\nv 2 1 5\nv 0 4 5\n"  # a dart: concave at its 4th corner
    text = (SQUARE.format(z=0) + "f -4 -3 -2 -1\n" + SQUARE.format(z=1) + "f -4 -3 -2\n"
            + concave + "f -5 -4 -3 -2 -1\n" + SQUARE.format(z=9))  # vertices after the faces: what -1 hit
    (tmp_path / "rel.obj").write_text(text)
    found = triangles(read(tmp_path / "rel.obj"))
    dart = [(0, 0, 5), (4, 0, 5), (4, 4, 5), (2, 1, 5), (0, 4, 5)]
    assert square(0)[0] in found and square(0)[1] in found
    assert ((0, 0, 1), (1, 0, 1), (1, 1, 1)) in found
    assert len(found) == 6 and all(corner in dart for face in found[3:] for corner in face), found
    assert not any(corner[2] == 9 for face in found for corner in face)


def test_relative_texture_and_normal_indices_count_back_from_their_own_line(tmp_path):
    """vt and vn indices count back over the `vt` and `vn` lines above the face, each in its own list."""
    from PIL import Image
    Image.new("RGB", (2, 2), (255, 255, 255)).save(tmp_path / "t.png")
    (tmp_path / "m.mtl").write_text("newmtl t\nmap_Kd t.png\n")
    text = ("mtllib m.mtl\nusemtl t\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0.1 0.2\nvt 0.3 0.4\nvt 0.5 0.6\n"
            "vn 1 0 0\nvn 0 1 0\nvn 0 0 1\nf -3/-3/-3 -2/-2/-2 -1/-1/-1\n"
            "vt 0.9 0.9\nvn 0 0 -1\n")  # defined after the face: a count from the file's end would take these
    (tmp_path / "uv.obj").write_text(text)
    mesh = read(tmp_path / "uv.obj")
    [face] = mesh.faces.tolist()
    assert mesh.vertices[face].tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    np.testing.assert_allclose(mesh.corner_uv[0], [[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]], atol=1e-6)
    np.testing.assert_allclose(mesh.normals[face], np.eye(3))


def test_a_relative_index_before_the_first_vertex_is_one_line(tmp_path):
    (tmp_path / "far.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 -3 -2\n")
    done = runner.invoke(app, ["render", str(tmp_path / "far.obj"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert "line 4" in line and "-4" in line and "3 `v` lines above it" in line and "allowed" in line, line


@pytest.mark.parametrize(("corner", "kind"), [("0", "`v`"), ("1/0", "`vt`"), ("1//0", "`vn`")])
def test_face_index_0_is_refused_naming_the_line(tmp_path, corner, kind):
    """OBJ indices start at 1 (or count back from -1): 0 names nothing. trimesh read it as the first vertex."""
    (tmp_path / "zero.obj").write_text(f"v 0 0 0\nvt 0 0\nvn 0 0 1\nv 1 0 0\nv 0 1 0\nf {corner} 2 3\n")
    done = runner.invoke(app, ["render", str(tmp_path / "zero.obj"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert line.startswith(f"error: {tmp_path / 'zero.obj'}:") and "line 6" in line, line
    assert f"index 0 ({kind})" in line and "allowed: 1" in line, line
    assert not (tmp_path / "x.png").exists()


def test_every_mtl_an_mtllib_names_is_read(tmp_path):
    """`mtllib a.mtl b\\ c.mtl d\\ e.mtl` names three files (a backslash escapes a space); each defines a
    material a `usemtl` group uses. A name also defined by an earlier file keeps the earlier definition."""
    (tmp_path / "a.mtl").write_text("newmtl red\nKd 1 0 0\n")
    (tmp_path / "b c.mtl").write_text("newmtl green\nKd 0 1 0\nnewmtl red\nKd 0 0 0\n")
    (tmp_path / "d e.mtl").write_text("newmtl blue\nKd 0 0 1\n")
    faces = "".join(f"usemtl {name}\nv {k} 0 0\nv {k + 1} 0 0\nv {k} 1 0\nf -3 -2 -1\n"
                    for k, name in enumerate(("red", "green", "blue")))
    (tmp_path / "three.obj").write_text("mtllib a.mtl b\\ c.mtl d\\ e.mtl\n" + faces)
    mesh = read(tmp_path / "three.obj")
    assert mesh.notes == () or not any("material file" in note for note in mesh.notes), mesh.notes
    kd = {m.name: m.kd for m in mesh.materials}
    assert kd == {"red": (1, 0, 0), "green": (0, 1, 0), "blue": (0, 0, 1)}, kd
    for face, group in zip(mesh.faces, mesh.face_group):  # the face at x = k has the k-th material
        assert mesh.materials[group].name == ("red", "green", "blue")[int(mesh.vertices[face][:, 0].min())]
    names = ("a.mtl", "b c.mtl", "d e.mtl")
    assert list(mesh_source(tmp_path / "three.obj").side_files) == [tmp_path / n for n in names]


def test_an_mtllib_naming_one_file_with_a_space_and_several_lines_are_read(tmp_path):
    """`mtllib my model.mtl` naming an existing file is that file (as read before); a second `mtllib` line
    adds its materials; a missing one is one note and the others still count."""
    (tmp_path / "my model.mtl").write_text("newmtl red\nKd 1 0 0\n")
    (tmp_path / "more.mtl").write_text("newmtl green\nKd 0 1 0\n")
    text = ("mtllib my model.mtl\nmtllib more.mtl gone.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
            "usemtl green\nf 1 3 2\n")
    (tmp_path / "two.obj").write_text(text)
    mesh = read(tmp_path / "two.obj")
    assert sorted(m.name for m in mesh.materials) == ["green", "red"]
    assert [n for n in mesh.notes if "material file" in n] == [
        f"{tmp_path / 'two.obj'}: its material file 'gone.mtl' is missing; the default material is used"]


def test_a_map_option_after_the_file_name_is_not_part_of_the_name(tmp_path):
    """`map_Kd wood.png -bm 0.5`: the name is wood.png (the .mtl specification puts options first, but
    exporters write some after); `map_Bump -bm 1 n.png` skips -bm before the name as before."""
    from PIL import Image
    Image.new("RGB", (2, 2), (255, 255, 255)).save(tmp_path / "wood.png")
    assert "-bm" in mtl.MAP_OPTIONS
    notes: list[str] = []
    sources: list = []
    found = mtl.parse_mtl("newmtl w\nmap_Kd wood.png -bm 0.5\nmap_Bump -bm 1 n.png\n"
                                "newmtl c\nmap_Kd wood.png -clamp on -s 1 1 1\n", tmp_path / "m.mtl", notes, sources)
    assert found["w"].kd_map >= 0 and sources[found["w"].kd_map].source == tmp_path / "wood.png", notes
    assert sources[found["c"].kd_map].wrap_s == "clamp"
    assert not any("'wood.png" in note for note in notes), notes
    assert any("not applied: map_bump n.png" in note for note in notes), notes
    assert mtl.map_file(["my", "wood.png"]) == "my wood.png"  # spaces in a name stay


def test_vertex_colours_are_kept_beside_usemtl_materials(tmp_path):
    """`v x y z r g b` in a file whose faces have a `usemtl` material: both are kept (the colours multiply the
    material's k_a and k_d, docs/meshes.md); they were dropped."""
    (tmp_path / "m.mtl").write_text("newmtl grey\nKa 0.5 0.5 0.5\nKd 0.5 0.5 0.5\n")
    text = ("mtllib m.mtl\nv 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nv 1 1 0 1 1 1\n"
            "usemtl grey\nf 1 2 3\nf 2 4 3\n")
    (tmp_path / "c.obj").write_text(text)
    mesh = read(tmp_path / "c.obj")
    assert [m.name for m in mesh.materials] == ["grey"] and (mesh.face_group == 0).all()
    colour = {(1, 0, 0): (0, 0, 0), (0, 1, 0): (1, 0, 0), (0, 0, 1): (0, 1, 0), (1, 1, 1): (1, 1, 0)}
    assert mesh.corner_colour is not None
    for face, corners in zip(mesh.faces, mesh.corner_colour):
        for vertex, rgb in zip(mesh.vertices[face], corners):
            assert tuple(vertex) == colour[tuple(rgb.round(6))], (vertex, rgb)
    # the same 8-bit values as the file without materials gives (0.3 is 76/255 either way)
    shaded = text.replace("1 1 0 1 1 1", "1 1 0 0.3 0.3 0.3")
    (tmp_path / "c.obj").write_text(shaded)
    (tmp_path / "plain.obj").write_text(shaded.replace("mtllib m.mtl\n", "").replace("usemtl grey\n", ""))
    with_material, plain = read(tmp_path / "c.obj"), read(tmp_path / "plain.obj")
    assert plain.materials == () and with_material.materials
    np.testing.assert_array_equal(with_material.corner_colour, plain.corner_colour)
    assert np.isclose(with_material.corner_colour, 76 / 255).any()


def test_vertex_colours_multiply_the_materials_ka(tmp_path):
    """Lit by the ambient term alone (ambient 1, no lights), a red-vertex triangle with Ka 0.5 is k_a × red =
    (0.5, 0, 0) at every pixel; it rendered grey (0.5, 0.5, 0.5) when the colours were dropped."""
    import raycast_phong as rp
    (tmp_path / "m.mtl").write_text("newmtl g\nKa 0.5 0.5 0.5\nKd 0.5 0.5 0.5\nKs 0 0 0\n")
    (tmp_path / "t.obj").write_text("mtllib m.mtl\nv 0 0 0 1 0 0\nv 1 0 0 1 0 0\nv 0 1 0 1 0 0\nusemtl g\nf 1 2 3\n")
    (tmp_path / "s.toml").write_text('ambient = 1.0\nlights = []\n[render]\nwidth = 32\nheight = 32\n[camera]\n'
                                     'position = [0.3, 0.3, 2]\nlook_at = [0.3, 0.3, 0]\n'
                                     '[[objects]]\nshape = "mesh"\npath = "t.obj"\n')
    image = rp.render(rp.load_scene(tmp_path / "s.toml")).image
    covered = image.max(axis=2) > 0
    assert covered.sum() > 50
    np.testing.assert_allclose(image[covered], np.broadcast_to([0.5, 0.0, 0.0], image[covered].shape), atol=1e-6)


@pytest.mark.parametrize("value", ["4e38", "-1e39", "inf"])
def test_a_texture_coordinate_beyond_float32_is_one_line_naming_its_line(tmp_path, value):
    """UVs are kept as float32 per corner: `vt 4e38 0` overflowed the cast with numpy's RuntimeWarning (issue 30,
    item 10). Now one line: the file, the `vt` line (counted in the file as written, before a concave polygon
    above it is cut into more lines), the value and the range."""
    concave = "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 2 1 0\nv 0 4 0\nvt 0 0\nf 1/1 2/1 3/1 4/1 5/1\n"  # cut into 3 lines
    (tmp_path / "big.obj").write_text(concave + f"vt 1 {value}\nf 1/1 2/2 3/1\n")
    done = runner.invoke(app, ["render", str(tmp_path / "big.obj"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert line.startswith(f"error: {tmp_path / 'big.obj'}:") and "line 8" in line and value in line, line
    assert "allowed: -3.403e+38 .. 3.403e+38" in line, line
    assert not (tmp_path / "x.png").exists()


def test_a_ply_coordinate_beyond_float32_is_one_line_without_numpy_warnings(tmp_path):
    """A `property float x` of 5e38 is infinite as float32: trimesh's cast warned before the one-line refusal."""
    header = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
              "element face 1\nproperty list uchar int vertex_indices\nend_header\n")
    (tmp_path / "big.ply").write_text(header + "0 0 0\n5e38 0 0\n0 1 0\n3 0 1 2\n")
    import warnings
    with warnings.catch_warnings(record=True) as warned:
        warnings.simplefilter("always")
        done = runner.invoke(app, ["render", str(tmp_path / "big.ply"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert "infinite coordinates" in line, line
    assert not [w for w in warned if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in warned]


@pytest.mark.parametrize("encoding, mark", [("utf-16-be", b"\xfe\xff"), ("utf-16-le", b"\xff\xfe"),
                                            ("utf-8", b"\xef\xbb\xbf")])
def test_an_obj_with_a_byte_order_mark_is_decoded(tmp_path, encoding, mark):
    """assimp's box_UTF16BE.obj: UTF-16 with its BOM read as bytes gave "holds no triangles"."""
    text = "# é\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
    (tmp_path / "bom.obj").write_bytes(mark + text.encode(encoding))
    assert triangles(read(tmp_path / "bom.obj")) == [((0, 0, 0), (1, 0, 0), (0, 1, 0))]


def test_a_utf16_mark_before_bytes_that_are_not_utf16_is_one_line(tmp_path):
    (tmp_path / "odd.obj").write_bytes(b"\xff\xfe" + "v 0 0 0\n".encode("utf-16-le") + b"v")
    done = runner.invoke(app, ["render", str(tmp_path / "odd.obj"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    message = " ".join(done.stderr.split())
    assert "UTF-16-LE byte-order mark but byte 18 is not UTF-16-LE" in message and "Traceback" not in done.output


def test_a_hash_inside_a_material_name_is_part_of_it(tmp_path):
    """Godot 4 names materials `StandardMaterial3D#-92`: `#` starts a comment only at the start of a word (issue
    45). Two names that differ only after their `#` stay two materials; trailing comments are dropped, on
    `usemtl` lines too (trimesh kept the space before one in the name, and lost the material)."""
    (tmp_path / "m.mtl").write_text("# Godot 4\nnewmtl StandardMaterial3D#-92\nKd 0.9 0.1 0.1 # red\n"
                                    "newmtl StandardMaterial3D#-93   # its twin\nKd 0.1 0.1 0.9\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                                    "usemtl StandardMaterial3D#-92 # a comment\nf 1 2 3\n"
                                    "usemtl StandardMaterial3D#-93\nf 1 3 4\n")
    read = read_mesh(tmp_path / "m.obj", "t")
    assert sorted(m.name for m in read.materials) == ["StandardMaterial3D#-92", "StandardMaterial3D#-93"]
    for face, group in zip(read.faces, read.face_group):
        red = np.allclose(read.vertices[face][:, 0].sum(), 2.0)  # (0,0), (1,0), (1,1): the first face
        assert read.materials[group].kd == ((0.9, 0.1, 0.1) if red else (0.1, 0.1, 0.9))


@pytest.mark.parametrize("faces", ["f 1/1 2/2 3/1\n", "f 1/1 2/2 3/1 4/1\n"], ids=["triangle", "quad"])
def test_a_texture_coordinate_of_exactly_float32_s_largest_reads_and_the_next_float_is_refused(tmp_path, faces):
    """UV_LIMIT is float32's largest finite value, allowed itself: `vt 1 3.4028234663852886e+38` (the second value
    of the second `vt`) reads and renders; the next float64 above it is refused naming its line. Catches `≤` made `<`
    in the OBJ reader's or the common reader's check, and a line search that stops at the first `vt` or value."""
    import raycast_phong as rp
    largest = float(np.finfo(np.float32).max)
    square = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 {}\n" + faces
    (tmp_path / "at.obj").write_text(square.format(repr(largest)))
    assert np.isfinite(rp.render_file(tmp_path / "at.obj", ["render.width=8", "render.height=8"]).image).all()
    past = repr(float(np.nextafter(largest, np.inf)))
    (tmp_path / "past.obj").write_text(square.format(past))
    done = runner.invoke(app, ["render", str(tmp_path / "past.obj"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert f"line 6: texture coordinate {past} is beyond float32's range" in line, line


def test_an_obj_starting_with_a_utf8_byte_order_mark_reads_its_first_vertex(tmp_path):
    """A UTF-8 byte-order mark (EF BB BF, as Windows editors write) before the first `v` line is dropped whole:
    the triangle's three vertices all read, the first one too, at (0, 0, 0), (1, 0, 0), (0, 1, 0)."""
    path = tmp_path / "bom.obj"
    path.write_bytes(b"\xef\xbb\xbfv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    found = mesh_source(path).read()
    assert found.faces.tolist() == [[0, 1, 2]]
    assert found.vertices.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]


def test_transparency_and_illum_notes_name_only_the_materials_past_their_defaults(tmp_path):
    """`d 1`, `Tr 0` and `illum 2` (what most exporters write) and a material that leaves them out are opaque
    Phong: not named; `d 0.99`, `Tr 0.01` and `illum 3` are, each note naming only those. Catches the
    boundaries taken the wrong way (d <= 1, Tr >= 0, illum >= 2 said of every material)."""
    notes: list[str] = []
    mtl.parse_mtl("newmtl opaque\nKd 1 1 1\nd 1\nTr 0\nillum 2\nnewmtl plain\nKd 1 1 1\n"
                  "newmtl veiled\nd 0.99\nnewmtl tinted\nTr 0.01\nnewmtl mirror\nillum 3\n", tmp_path / "m.mtl", notes)
    assert notes == [f"{tmp_path / 'm.mtl'}: transparency (d < 1 or Tr > 0) is ignored: material(s) 'veiled', "
                     "'tinted' render opaque",
                     f"{tmp_path / 'm.mtl'}: illum 3 render as illum 2 (Phong); reflection and refraction are out of "
                     "scope"], notes


@pytest.mark.parametrize("words, name", [
    (["-mm", "0", "1", "wood.png"], "wood.png"),  # base and gain: two values
    (["-o", "0.5", "0.5", "0", "-s", "2", "2", "1", "wood.png"], "wood.png"),  # three each
    (["-bm", "0.5", "-imfchan", "l", "bump map.png"], "bump map.png"),  # one each; a space in the name kept
])
def test_each_map_option_takes_as_many_values_as_the_specification_gives_it(words, name):
    """The .mtl specification's texture map options: -mm base gain, -o/-s/-t u v w, the others one value. Catches
    -mm taking one value (`map_Kd -mm 0 1 wood.png` naming the file '1 wood.png')."""
    assert mtl.map_file(words) == name


def test_a_material_without_an_illum_line_keeps_its_specular_as_illum_2_does(tmp_path):
    """No `illum`: the lecture's full model (illum 2), so a given Ks shines; `illum 1` drops it (colour and
    ambient only). Catches the default taken as 1 (every such exporter's highlight gone)."""
    notes: list[str] = []
    found = mtl.parse_mtl("newmtl plain\nKs 1 1 1\nnewmtl two\nKs 1 1 1\nillum 2\nnewmtl one\nKs 1 1 1\nillum 1\n",
                          tmp_path / "m.mtl", notes, [])
    assert [found[name].ks for name in ("plain", "two", "one")] == [(1.0, 1.0, 1.0), (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)]


def test_a_one_value_map_option_without_its_value_leaves_the_file_name(tmp_path):
    """`map_Kd -clamp wood.png` (the option's on/off left out): the last word is the file, never taken as the
    option's value; and three maps that are not applied are listed whole, with no `...` (that is for a fourth).
    Catches the value loop reaching the last word and the list cut at 3 rather than after it."""
    from PIL import Image
    Image.new("RGB", (2, 2), (255, 255, 255)).save(tmp_path / "wood.png")
    assert mtl.map_file(["-clamp", "wood.png"]) == "wood.png"
    notes: list[str] = []
    sources: list = []
    found = mtl.parse_mtl("newmtl w\nmap_Kd -clamp wood.png\nbump wood.png\nmap_Ks wood.png\nrefl wood.png\n",
                          tmp_path / "m.mtl", notes, sources)
    assert sources[found["w"].kd_map].source == tmp_path / "wood.png" and sources[found["w"].kd_map].wrap_s == "repeat"
    assert notes == [f"{tmp_path / 'm.mtl'}: only colour maps (map_Kd, map_Ka, map_Ke) are applied; not applied: "
                     "bump wood.png, map_ks wood.png, refl wood.png"], notes


@pytest.mark.parametrize(("extra", "read"), [(0, True), (1, False)])
def test_an_mtl_of_exactly_max_side_file_bytes_is_read_and_one_byte_more_is_not(tmp_path, extra, read):
    """An .mtl of 16 MiB (MAX_SIDE_FILE, what a scene file may be) is read, its material defined; one a byte
    longer is a note and the default material. The files are sparse: a material, then zeros. Catches the limit
    one off or doubled (the size is written here, not taken from the module)."""
    from raycast_phong.io.meshes.mtl import read_obj_materials
    path = tmp_path / "big.mtl"
    with path.open("wb") as handle:
        handle.write(b"newmtl red\nKd 1 0 0\n")
        handle.truncate((16 << 20) + extra)
    found = read_obj_materials(tmp_path / "m.obj", ["big.mtl"])
    if read:
        assert found.library["red"].kd == (1.0, 0.0, 0.0) and found.notes == (), found.notes
    else:
        assert found.library == {} and len(found.notes) == 1 and "'big.mtl' cannot be read" in found.notes[0], \
            found.notes


def test_an_mtllib_whose_whole_text_is_too_long_for_a_file_name_is_its_words(tmp_path):
    """`mtllib a.mtl <300 letters>.mtl`: the whole text cannot be one file (the system refuses a name over 255
    bytes, an OSError), so the statement is its two words, each a name, and the read goes on. Catches the
    OSError let through (the OBJ refused for a name no file can have)."""
    long = "b" * 300 + ".mtl"
    assert mtl.mtllib_names([f"a.mtl {long}".encode()], tmp_path) == ["a.mtl", long]


def test_an_mtllib_line_that_is_not_utf8_is_read_as_latin1(tmp_path):
    """`mtllib café.mtl` written in Latin-1 (é the one byte 0xE9, not UTF-8): the name is read as Latin-1, as the
    OBJ itself is, so the file café.mtl is found and its material used. Catches the line kept as its raw bytes
    (decoded with replacement: 'caf\\ufffd.mtl', missing)."""
    (tmp_path / "café.mtl").write_text("newmtl red\nKd 1 0 0\n", encoding="utf-8")
    (tmp_path / "l.obj").write_bytes(b"mtllib caf\xe9.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with (tmp_path / "l.obj").open("rb") as handle:
        assert mtl.scan_mtllib(handle) == ["café.mtl".encode()]
    mesh = read(tmp_path / "l.obj")
    assert [(m.name, m.kd) for m in mesh.materials] == [("red", (1.0, 0.0, 0.0))], mesh.notes


@pytest.mark.parametrize("value", ["nan", "inf", "-inf"])
def test_a_coefficient_that_is_not_finite_keeps_its_default_and_is_said(tmp_path, value):
    """`Kd nan 0 0` (Python's float reads nan and inf): not a number a colour can be, so Kd keeps the scene
    default (codes.MATERIAL_DEFAULTS: 0.8 0.8 0.8) and the note names it. Catches the finite check dropped (a NaN
    k_d reaching the kernel, or inf clamped to 1)."""
    from raycast_phong.codes import MATERIAL_DEFAULTS
    notes: list[str] = []
    found = mtl.parse_mtl(f"newmtl m\nKd {value} 0 0\nKa 0.25 0.25 0.25\n", tmp_path / "m.mtl", notes)
    assert found["m"].kd == MATERIAL_DEFAULTS["kd"] == (0.8, 0.8, 0.8) and found["m"].ka == (0.25, 0.25, 0.25)
    assert notes == [f"{tmp_path / 'm.mtl'}: 1 value(s) are not numbers and keep their defaults (first: m: Kd "
                     f"{value} 0 0)"], notes


def test_a_map_option_stops_taking_values_at_a_word_that_is_not_a_number(tmp_path):
    """`map_Kd -s 2 fuze uv.jpg`: -s takes up to three numbers (u [v [w]]); `fuze` is not one, so it starts the
    file name, spaces kept. Catches the word skipped as a value ('uv.jpg') or the loop never leaving."""
    assert mtl.map_file(["-s", "2", "fuze", "uv.jpg"]) == "fuze uv.jpg"


def test_an_option_after_the_name_without_its_values_is_part_of_the_name(tmp_path):
    """`map_Kd wood.png -o`: -o needs one to three numbers (u [v [w]]), so a bare `-o` ending the statement is no
    option and stays in the name; `-clamp on` after it still is one. Catches an option taken with no value."""
    assert mtl.map_file(["wood.png", "-o"]) == "wood.png -o"
    assert mtl.map_file(["wood.png", "-o", "-clamp", "on"]) == "wood.png -o"
    assert mtl.map_file(["wood.png", "-o", "1", "-clamp", "on"]) == "wood.png"


def test_a_map_whose_name_is_too_long_for_a_file_is_missing(tmp_path):
    """`map_Kd <300 letters>.png`: no file can have that name (the system refuses it with an OSError): the map is
    a missing texture, one note, and the material keeps its Kd. Catches the OSError let through."""
    from raycast_phong.io.files import shown_name
    long = "t" * 300 + ".png"
    notes: list[str] = []
    found = mtl.parse_mtl(f"newmtl m\nKd 1 0 0\nmap_Kd {long}\n", tmp_path / "m.mtl", notes, [])
    assert found["m"].kd_map == -1 and found["m"].kd == (1.0, 0.0, 0.0)
    said = f"{tmp_path / 'm.mtl'}: texture {shown_name(long)} is missing"
    assert [note for note in notes if "missing" in note] == [said], notes
