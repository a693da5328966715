"""OFF read from Geomview's specification (issue 45): the header keyword's prefixes (C colours, N normals, ST),
the optional keyword, polygons of any size, face colours, comments anywhere and `OFF BINARY`. Each file is
written here; what each triangle gets is worked out by hand, and a plain file is checked against trimesh's
own OFF reader (a reader apart from this one)."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import numpy as np
import pytest
import trimesh

from raycast_phong.errors import SceneError
from raycast_phong.io.meshes.source import mesh_source

POINTS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, 1.8, 0), (2, 0, 0), (2, 1, 0)]
FACES = [(0, 1, 2, 3), (3, 2, 4), (1, 5, 6, 2)]
FANS = {(0, 1, 2), (0, 2, 3), (2, 4, 3), (1, 5, 6), (1, 6, 2)}  # each from its smallest corner, winding kept


def turned(face) -> tuple[int, ...]:
    face = list(face)
    k = face.index(min(face))
    return tuple(face[k:] + face[:k])


def text(header: str, vertex=lambda k, p: " ".join(map(str, p)),
         face=lambda k, f: f"{len(f)} {' '.join(map(str, f))}") -> bytes:
    """The mesh as OFF text under `header`, a comment line and a trailing comment on the counts line."""
    lines = [header] if header else []
    lines += ["# a comment line", f"{len(POINTS)} {len(FACES)} 0  # counts, then a comment"]
    lines += [vertex(k, p) for k, p in enumerate(POINTS)] + [face(k, f) for k, f in enumerate(FACES)]
    return ("\n".join(lines) + "\n").encode()


def read(tmp_path: Path, data: bytes):
    path = tmp_path / "m.off"
    path.write_bytes(data)
    return mesh_source(path).read()


@pytest.mark.parametrize("header", ["OFF", "", "# made by hand\nOFF"])
def test_polygons_are_fans_and_the_keyword_is_optional(tmp_path, header):
    found = read(tmp_path, text(header))
    assert np.allclose(found.vertices, POINTS) and {turned(f) for f in found.faces.tolist()} == FANS
    assert found.normals is None and found.corner_colour is None


def test_a_file_of_triangles_reads_as_trimesh_s_reader_reads_it(tmp_path):
    mesh = trimesh.creation.icosphere(2)
    data = trimesh.exchange.off.export_off(mesh).encode()
    ours = read(tmp_path, data)
    theirs = trimesh.load(io.BytesIO(data), file_type="off", process=False)
    assert np.allclose(ours.vertices, theirs.vertices) and np.array_equal(ours.faces, theirs.faces)


@pytest.mark.parametrize("scale", [255, 1.0])
def test_vertex_colours_of_coff_in_either_form(tmp_path, scale):
    """C: r g b a after x y z, 0..255 integers or 0..1 floats: vertex k is red, green or blue by k % 3."""
    rgb = [(0.9, 0.3, 0.1, 1), (0.1, 0.9, 0.3, 1), (0.3, 0.1, 0.9, 1)]  # read as 0..255 if floats, all clip white
    data = text("COFF", vertex=lambda k, p: " ".join(map(str, [*p, *(round(c * scale, 3) for c in rgb[k % 3])])))
    found = read(tmp_path, data)
    for face, colours in zip(found.faces, found.corner_colour):
        assert [np.argmax(c) for c in colours] == [k % 3 for k in face]


@pytest.mark.parametrize("top", ["1", "1.0", "255"])
def test_a_colour_channel_at_the_top_of_either_form_is_full(tmp_path, top):
    """Colours whose channels reach 1 and no more are the 0..1 form (1 is full), those that pass 1 the 0..255 form
    (255 is full): primaries written 1 0 0 or 255 0 0 read as full red, exactly. Catches the two forms told
    apart at the boundary the wrong way (1 read as 1/255)."""
    primaries = [(top, "0", "0"), ("0", top, "0"), ("0", "0", top)]
    data = text("COFF", vertex=lambda k, p: " ".join([*map(str, p), *primaries[k % 3], top]))
    found = read(tmp_path, data)
    for face, colours in zip(found.faces, found.corner_colour):
        np.testing.assert_array_equal(colours, np.eye(3)[[k % 3 for k in face]])


def test_face_colours_colour_their_fans(tmp_path):
    rgb = [(200, 0, 0), (0, 200, 0), (0, 0, 200)]
    data = text("OFF", face=lambda k, f: f"{len(f)} {' '.join(map(str, f))} {' '.join(map(str, rgb[k]))}")
    found = read(tmp_path, data)
    for face, colours in zip(found.faces.tolist(), found.corner_colour):
        polygon = next(k for k, f in enumerate(FACES) if set(face) <= set(f))
        assert all(np.argmax(c) == polygon for c in colours)


@pytest.mark.parametrize("full", ["200", "0.784313725"])
def test_a_face_without_a_colour_among_coloured_faces_is_drawn_white(tmp_path, full):
    """Face colours are optional per face (the OFF specification): a face line with no colour among coloured ones
    is white (every channel 1), not black, whichever form (0..255 or 0..1) the others are written in. Catches the
    missing row filled with 0, and filled with 1 before the form is known (1/255 among 0..255 colours)."""
    rgb = {0: f"{full} 0 0", 2: f"0 0 {full}"}
    data = text("OFF", face=lambda k, f: f"{len(f)} {' '.join(map(str, f))} {rgb.get(k, '')}".rstrip())
    found = read(tmp_path, data)
    for face, colours in zip(found.faces.tolist(), found.corner_colour):
        polygon = next(k for k, f in enumerate(FACES) if set(face) <= set(f))
        expected = [0, 0, 0] if polygon != 1 else [1, 1, 1]
        if polygon != 1:
            expected[0 if polygon == 0 else 2] = 200 / 255
        np.testing.assert_allclose(colours, [expected] * 3, atol=1e-6)


def test_noff_keeps_the_file_s_normals(tmp_path):
    normal = np.array([0.0, 0.6, 0.8])
    found = read(tmp_path, text("NOFF", vertex=lambda k, p: " ".join(map(str, [*p, *normal]))))
    assert found.normals is not None and np.allclose(found.normals, normal)


def binary(colours: bool) -> bytes:
    """OFF BINARY: big-endian counts, float32 vertices, per face Nv, indices, Nc and Nc float32 colours."""
    body = struct.pack(">3i", len(POINTS), len(FACES), 0) + b"".join(struct.pack(">3f", *p) for p in POINTS)
    for k, face in enumerate(FACES):
        colour = [float(k == 0), float(k == 1), float(k == 2), 1.0] if colours else []
        body += struct.pack(f">{len(face) + 1}i", len(face), *face)
        body += struct.pack(">i", len(colour)) + struct.pack(f">{len(colour)}f", *colour)
    return b"OFF BINARY\n" + body


@pytest.mark.parametrize("colours", [False, True])
def test_off_binary(tmp_path, colours):
    found = read(tmp_path, binary(colours))
    assert np.allclose(found.vertices, POINTS) and {turned(f) for f in found.faces.tolist()} == FANS
    if colours:
        for face, corner in zip(found.faces.tolist(), found.corner_colour):
            polygon = next(k for k, f in enumerate(FACES) if set(face) <= set(f))
            assert all(np.argmax(c) == polygon for c in corner)
    path = tmp_path / "m.off"
    with path.open("rb") as handle:
        assert mesh_source(path).format.count(handle, path.stat().st_size, None) >= len(FANS)


@pytest.mark.parametrize(("data", "said"), [
    (text("OFF")[:-30], "cut short"),
    (text("OFF").replace(b"0.5 1.8 0", b"0.5 1.x8 0"), "'1.x8', which is not a number"),
    (text("OFF").replace(b"3 3 2 4", b"3 3 2 9"), "face index outside 0..6"),
    (text("OFF").replace(b"4 0 1 2 3", b"4 0 1 7 3"), "face index outside 0..6"),  # a quad's: the cut skips it
    (text("OFF").replace(b"3 3 2 4", b"5 3 2 4"), "indices where it counts 5"),
    (binary(False)[:-9], "cut short"),
])
def test_a_broken_file_is_one_line_saying_what(tmp_path, data, said):
    with pytest.raises(SceneError) as caught:
        read(tmp_path, data)
    assert said in str(caught.value) and "\n" not in str(caught.value), str(caught.value)


def test_the_read_check_weighs_the_format_s_parse_beside_the_render_s_bytes(tmp_path):
    """An OFF of N triangles is read through trimesh (its parse: OFF's parse_bytes a triangle) and then held for
    the render (MESH_READ_BYTES a triangle): a budget between N × MESH_READ_BYTES and N × both is refused, one
    above both is not. The file's own size floor stays under both budgets."""
    from raycast_phong.io.meshes.size import MESH_READ_BYTES, check_mesh_read, read_floor
    side = 100
    points = [f"{x} {y} 0" for y in range(side + 1) for x in range(side + 1)]
    faces = [f"3 {a} {a + 1} {a + side + 2}\n3 {a} {a + side + 2} {a + side + 1}"
             for a in (y * (side + 1) + x for y in range(side) for x in range(side))]
    path = tmp_path / "grid.off"
    path.write_text(f"OFF\n{len(points)} {2 * side * side} 0\n" + "\n".join(points + faces) + "\n")
    source = mesh_source(path, "grid")
    triangles = source.triangles()
    assert triangles == 2 * side * side
    parse = source.format.parse_bytes
    assert parse > 0
    between, above = triangles * (MESH_READ_BYTES + parse // 2), triangles * (MESH_READ_BYTES + parse) + 1
    assert read_floor(source) < between
    with pytest.raises(SceneError, match="triangles needs"):
        check_mesh_read(source, max_memory=between)
    check_mesh_read(source, max_memory=above)


def test_the_read_check_allows_exactly_what_the_read_needs(tmp_path):
    """The check's limits are inclusive: an OFF of 1 triangle needs MESH_READ_BYTES + OFF's parse_bytes (820
    bytes, above its size floor): allowed at exactly 820, refused at 819; and a budget of exactly the floor still
    counts the triangles (the floor alone is no reason to skip them), so it is refused. Catches `need >
    available` or `floor > available` taken as `>=`."""
    from raycast_phong.io.meshes.size import check_mesh_read, read_floor
    path = tmp_path / "one.off"
    path.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    source = mesh_source(path, "one")
    assert source.triangles() == 1 and source.format.parse_bytes == 550 and read_floor(source) < 820
    check_mesh_read(source, max_memory=820)
    for budget in (819, read_floor(source)):
        with pytest.raises(SceneError, match="1 triangles needs"):
            check_mesh_read(source, max_memory=budget)


def test_a_header_that_does_not_parse_is_weighed_by_the_file_s_size(tmp_path):
    """A malformed count (no number) is not 0 triangles: the estimate falls back to the size bound, a triangle
    for every SMALLEST_TRIANGLE bytes, so a large malformed file is still weighed before the read words it."""
    from raycast_phong.io.meshes.size import SMALLEST_TRIANGLE
    path = tmp_path / "bad.off"
    path.write_text("OFF\nabc 2 0\n" + "0 0 0\n" * 100)
    assert mesh_source(path).triangles() == path.stat().st_size // SMALLEST_TRIANGLE > 0


def test_counts_more_than_the_file_can_hold_are_weighed_by_its_size(tmp_path):
    """An ASCII OFF writes a vertex in 6 bytes and a triangle in 8 at the least: a 71-byte file that claims 20
    triangles (178 bytes at the least) is weighed by its size (the read says it is cut short), not by its claim;
    one whose claim fits is weighed by it."""
    from raycast_phong.io.meshes.size import SMALLEST_TRIANGLE
    path = tmp_path / "claims.off"
    path.write_text("OFF\n3 20 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n" + "#" * 30 + "\n")
    size = path.stat().st_size
    assert size < 6 * 3 + 8 * 20 < 3 * size
    assert mesh_source(path).triangles() == size // SMALLEST_TRIANGLE
    path.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    assert mesh_source(path).triangles() == 1


def test_a_text_off_one_face_line_short_is_refused_as_cut_short(tmp_path):
    """The counts line says 3 vertices and 1 face: with the face line missing the file holds 3 of the 4 lines
    after it, which the reader refuses as cut short, counting them (not reading the vertices as faces)."""
    data = b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n"
    with pytest.raises(SceneError, match=r"holds 3 vertex and face lines where its counts line says 3 \+ 1; "
                                         r"the file is cut short"):
        read(tmp_path, data)


def test_a_binary_off_face_naming_the_vertex_count_is_refused(tmp_path):
    """OFF BINARY with 3 vertices (indices 0..2) and one triangle naming vertex 3, one past the last: refused in
    one line, as the text form is, never read as a vertex that does not exist."""
    body = struct.pack(">3i", 3, 1, 0) + b"".join(struct.pack(">3f", *p) for p in [(0, 0, 0), (1, 0, 0), (0, 1, 0)])
    body += struct.pack(">4i", 3, 0, 1, 3) + struct.pack(">i", 0)
    with pytest.raises(SceneError, match=r"has a face index outside 0\.\.2"):
        read(tmp_path, b"OFF BINARY\n" + body)


def test_a_binary_off_face_colour_of_three_floats_is_read(tmp_path):
    """Geomview's colorspec may be 3 numbers (RGB, no alpha): Nc = 3 colours the face, and the last face's colour,
    ending the file, is read without a fourth value past it. Catches `Nc >= 3` taken as `Nc > 3` (the colours
    dropped) and a fourth channel read where Nc is 3 (the next word, here past the end)."""
    rgb = [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]
    body = struct.pack(">3i", len(POINTS), len(FACES), 0) + b"".join(struct.pack(">3f", *p) for p in POINTS)
    for face, colour in zip(FACES, rgb):
        body += struct.pack(f">{len(face) + 2}i3f", len(face), *face, 3, *colour)
    found = read(tmp_path, b"OFF BINARY\n" + body)
    assert {turned(f) for f in found.faces.tolist()} == FANS
    for face, colours in zip(found.faces.tolist(), found.corner_colour):
        polygon = next(k for k, f in enumerate(FACES) if set(face) <= set(f))
        np.testing.assert_array_equal(colours, np.tile(rgb[polygon], (3, 1)))


def test_a_counts_line_of_two_numbers_is_read_and_counted(tmp_path):
    """NEdges is ignored by every reader and often left out: a counts line of two numbers (`7 3`) is enough, both
    for the read and for the cheap count (7 vertices, 3 polygons: weighed as max(3, 7 - 2) = 5). Catches the
    least count taken as 3 numbers, in either place."""
    data = text("OFF").replace(b"7 3 0  #", b"7 3  #")
    assert b"\n7 3  #" in data
    found = read(tmp_path, data)
    assert {turned(f) for f in found.faces.tolist()} == FANS
    assert mesh_source(tmp_path / "m.off").triangles() == 5


def test_a_face_of_no_corners_is_skipped_and_a_bad_face_after_it_named(tmp_path):
    """A face line `0` (Nv = 0, a polygon of no corners) holds no triangle and is not an error; a face after it
    that counts more indices than it gives is refused naming that face, not the empty one. Catches `Nv < 0`
    taken as `Nv <= 0`."""
    data = text("OFF").replace(b"7 3 0", b"7 4 0").replace(b"4 0 1 2 3\n", b"0\n4 0 1 2 3\n")
    assert {turned(f) for f in read(tmp_path, data).faces.tolist()} == FANS
    with pytest.raises(SceneError, match=r"has face 2 \(line 3 of the faces\) of 3 indices where it counts 5"):
        read(tmp_path, data.replace(b"3 3 2 4", b"5 3 2 4"))


@pytest.mark.parametrize(("data", "said"), [
    (b"# nothing but a comment, no line feed",
     "cannot read the file as OFF: its content does not start as a OFF file does"),
    (b"OFF\n# a comment\n", "has no counts line; allowed: NVertices NFaces NEdges after the header"),
    (b"nOFF\n", "is cut short before its dimension line; allowed: nOFF, then Ndim"),
    (b"OFF\n3 x 0\n", "has the counts line '3 x 0', which is not whole numbers"),
    (b"OFF\n3\n", "has the counts line '3'; allowed: 2 or more whole numbers ≥ 0"),
    (b"OFF\n-1 1 0\n", "has the counts line '-1 1 0'; allowed: 2 or more whole numbers ≥ 0"),
    (b"nOFF\n3.5\n", "has the dimension line (nOFF's Ndim) '3.5', which is not whole numbers"),
    (b"NOFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
     "has vertex lines of 3 numbers; allowed: the same count on every line, at least 6 for its header (NOFF)"),
    (b"OFF\n3 1 0\n0 0 0\n1 0 0 1\n0 1 0\n3 0 1 2\n",
     "has vertex lines of differing numbers; allowed: the same count on every line, at least 3 for its header (OFF)"),
    (b"OFF\n3 1 0\n0 0 0\n1_0 0 0\n0 1 0\n3 0 1 2\n", "has a vertex line numpy cannot read; allowed: decimal numbers"),
    (b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n",
     "has a face index that is not a whole number; allowed: vertex indices 0, 1, ..."),
    (b"OFF BINARY\n" + bytes(8), "is cut short before its binary counts; allowed: three big-endian int32 counts"),
])
def test_a_broken_header_or_line_is_refused_saying_what_is_allowed(tmp_path, data, said):
    """Each refusal of the OFF specification's layout (geomview.org, "OFF Files"): the counts line (whole numbers,
    NVertices and NFaces at the least), nOFF's Ndim line, vertex lines of one length holding what the header's
    prefixes add (N: three more), decimal numbers (`1_0` Python reads, numpy and the specification do not),
    whole face indices, and OFF BINARY's three int32 counts; a file of one comment and no line feed is no OFF
    (its first word is not found: the scan for it ends with the file). One line, the file named once. Catches each
    check dropped or its words changed."""
    with pytest.raises(SceneError) as caught:
        read(tmp_path, data)
    assert str(caught.value) == f"{tmp_path / 'm.off'}: {said}", str(caught.value)


def test_an_off_binary_file_too_short_for_its_counts_is_weighed_by_its_size(tmp_path):
    """`OFF BINARY` then 8 bytes: the three int32 counts (12 bytes) are not there, so the cheap count gives none
    and the file is weighed by its size; the read says it is cut short. Catches the short head read as counts
    (numpy refusing a buffer too small, an internal error)."""
    from raycast_phong.io.meshes.size import SMALLEST_TRIANGLE
    path = tmp_path / "m.off"
    path.write_bytes(b"OFF BINARY\n" + struct.pack(">2i", 3, 1))
    with path.open("rb") as handle:
        assert mesh_source(path).format.count(handle, path.stat().st_size, None) is None
    assert mesh_source(path).triangles() == path.stat().st_size // SMALLEST_TRIANGLE
    with pytest.raises(SceneError, match="is cut short before its binary counts"):
        mesh_source(path).read()


def test_noff_s_dimension_line_is_read_and_its_first_three_coordinates_drawn(tmp_path):
    """nOFF: Ndim (here 4) after the keyword, then vertices of Ndim numbers; 4nOFF adds the homogeneous one
    (Ndim + 1 numbers). x, y, z are the first three, a note says the rest are not drawn; the cheap count skips
    the Ndim line (4 vertices, 2 faces: weighed as max(2, 4 - 2) = 2). Catches Ndim read as the counts, the
    homogeneous number not added to 4nOFF's width, and the count's Ndim line taken as its counts."""
    square = [[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]]
    for header, extra, width in (("nOFF", " 9", 4), ("4nOFF", " 9 1", 4)):
        data = f"{header}\n4\n4 2 0\n" + "".join(f"{x} {y} {z}{extra}\n" for x, y, z in square) + "3 0 1 2\n3 0 2 3\n"
        found = read(tmp_path, data.encode())
        assert found.vertices.tolist() == square and found.faces.tolist() == [[0, 1, 2], [0, 2, 3]], header
        assert [note.split(": ", 1)[1] for note in found.notes] == [
            f"is {'4' if header[0] == '4' else ''}nOFF ({width}-dimensional vertices); the first three coordinates "
            "are drawn"], found.notes
        assert mesh_source(tmp_path / "m.off").triangles() == 2


def test_4off_drops_the_homogeneous_coordinate_with_a_note(tmp_path):
    """4OFF: x y z w a vertex (w = 1 here, where the point is x, y, z whether or not w divides it): drawn at x, y,
    z, one note; in text and in OFF BINARY. Catches the fourth number read as the next vertex's x (the width not
    raised by one), and either note dropped."""
    square = [[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]]
    data = "4OFF\n4 2 0\n" + "".join(f"{x} {y} {z} 1\n" for x, y, z in square) + "3 0 1 2\n3 0 2 3\n"
    body = struct.pack(">3i", 4, 2, 0) + b"".join(struct.pack(">4f", *p, 1) for p in square)
    body += struct.pack(">5i", 3, 0, 1, 2, 0) + struct.pack(">5i", 3, 0, 2, 3, 0)
    for given in (data.encode(), b"4OFF BINARY\n" + body):
        found = read(tmp_path, given)
        assert found.vertices.tolist() == square and found.faces.tolist() == [[0, 1, 2], [0, 2, 3]]
        assert [note.split(": ", 1)[1] for note in found.notes] == [
            "is 4OFF (homogeneous 4-D vertices); x, y, z are drawn without the fourth"], found.notes


def test_stcoff_s_colours_come_before_its_texture_coordinates(tmp_path):
    """STCOFF: x y z, then r g b a, then s t (the specification's order); the colours are read from after x y z
    and the texture coordinates, which no image goes with, are a note. Corner colours: vertex 0 red, 1 green,
    2 blue (0..255). Catches the colours read from the wrong columns (s t taken as colour) and the note dropped."""
    rows = ["0 0 0 255 0 0 255 0.5 0.25", "1 0 0 0 255 0 255 1 0", "0 1 0 0 0 255 255 0 1"]
    found = read(tmp_path, ("STCOFF\n3 1 0\n" + "\n".join(rows) + "\n3 0 1 2\n").encode())
    np.testing.assert_array_equal(found.corner_colour[0], np.eye(3))
    assert [note.split(": ", 1)[1] for note in found.notes] == [
        "its texture coordinates (ST) are not used: OFF names no texture image"], found.notes


def test_cnoff_s_colours_come_after_its_normals(tmp_path):
    """CNOFF: x y z, then the normal nx ny nz, then r g b a (Geomview's order: [N] before [C]). Vertex 0 red,
    1 green, 2 blue, each normal +Z. Catches the colours read from just after x y z (the normal's 0 0 1 taken as
    a blue colour) and the normal read from the colour's columns."""
    rows = ["0 0 0 0 0 1 255 0 0 255", "1 0 0 0 0 1 0 255 0 255", "0 1 0 0 0 1 0 0 255 255"]
    found = read(tmp_path, ("CNOFF\n3 1 0\n" + "\n".join(rows) + "\n3 0 1 2\n").encode())
    np.testing.assert_array_equal(found.corner_colour[0], np.eye(3))
    np.testing.assert_array_equal(found.normals, [[0, 0, 1]] * 3)


def test_a_colormap_index_as_a_vertex_colour_is_not_read_and_said(tmp_path):
    """COFF vertices of one colour number (x y z i: an index into a colormap OFF does not carry): no colour,
    one note. Catches the index read as red (i/255, 1, 1)."""
    found = read(tmp_path, b"COFF\n3 1 0\n0 0 0 7\n1 0 0 7\n0 1 0 7\n3 0 1 2\n")
    assert found.corner_colour is None
    assert [note.split(": ", 1)[1] for note in found.notes] == [
        "its colours are colormap indices, which are not read"], found.notes


def test_coff_binary_s_vertex_colours_are_read(tmp_path):
    """COFF BINARY: each vertex x y z r g b a as float32 (0..1), each face Nv, its indices and Nc (0 here):
    corners red, green, blue. Catches the binary vertex colours not read, or read from the wrong floats."""
    body = struct.pack(">3i", 3, 1, 0)
    for point, colour in zip([(0, 0, 0), (1, 0, 0), (0, 1, 0)], np.eye(3)):
        body += struct.pack(">7f", *point, *colour, 1.0)
    body += struct.pack(">5i", 3, 0, 1, 2, 0)
    found = read(tmp_path, b"COFF BINARY\n" + body)
    assert found.vertices.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]] and found.faces.tolist() == [[0, 1, 2]]
    np.testing.assert_array_equal(found.corner_colour[0], np.eye(3))


def _random_off(rng, words) -> bytes:
    """A COFF of 300 vertices and 200 polygons of 3-6 corners, some with a face colour, as exporters write it:
    comments (whole lines, after numbers, against a number), blank lines, tabs, CRLF line ends; `words()` writes
    a decimal."""
    lines = ["COFF", "# made here", "", "300 200 0\t# counts"]
    for _ in range(300):
        lines.append("\t".join([words() for _ in range(3)] + [str(int(rng.integers(0, 256))) for _ in range(3)]))
        if rng.random() < 0.1:
            lines.append("  # a comment among the vertices")
        elif rng.random() < 0.1:
            lines[-1] += "#a comment against the last number"
    for _ in range(200):
        corners = int(rng.integers(3, 7))
        face = [str(corners), *map(str, rng.choice(300, corners, replace=False))]
        if rng.random() < 0.3:
            face += [f"{rng.random():.3f}" for _ in range(3)]
        lines.append(" ".join(face) + ("\r" if rng.random() < 0.2 else ""))
    return ("\n".join(lines) + "\n").encode()


def test_a_text_off_s_compiled_read_is_numpy_s_parse_bit_for_bit(tmp_path, monkeypatch):
    """The compiled pass (off._compiled_body) and numpy's parse of the same text give the same mesh to the bit,
    and the compiled pass is what read it (numpy's parse, the fallback, is barred while it reads)."""
    from raycast_phong.io.meshes import off
    rng = np.random.default_rng(3)

    def word() -> str:
        return f"{rng.normal() * 10 ** int(rng.integers(-3, 4)):.{int(rng.integers(1, 12))}g}"

    data = _random_off(rng, word)
    with monkeypatch.context() as patch:
        patch.setattr(off, "_numbers", None)
        compiled = off.parse(data, [], "m.off")
    with monkeypatch.context() as patch:
        patch.setattr(off, "_compiled_body", lambda *arguments: None)
        parsed = off.parse(data, [], "m.off")
    for ours, numpy_s in zip(compiled, parsed, strict=True):
        if isinstance(ours, np.ndarray):
            assert ours.dtype == numpy_s.dtype and ours.tobytes() == numpy_s.tobytes()
        else:
            assert ours == numpy_s


@pytest.mark.parametrize(("change", "why"), [
    (b"1e30", "a power of ten past 10^22"),
    (b"nan", "a word numpy reads as a number"),
    (b"12345678901234567890", "twenty digits"),
])
def test_a_text_off_with_a_word_off_the_exact_path_is_numpy_s_parse(tmp_path, change, why):
    """A word the compiled pass does not read exactly sends the file to numpy's parse: the same numbers as numpy
    reads them (here the first vertex's x)."""
    from raycast_phong.io.meshes import off
    data = text("OFF").replace(b"0 0 0\n", b"%s 0 0\n" % change, 1)
    vertices = off.parse(data, [], "m.off")[0]
    assert np.array_equal(vertices[0], [np.fromstring(change, sep=" ")[0], 0, 0], equal_nan=True), why


def test_a_text_off_s_reader_kernel_is_warmed_and_a_binary_one_s_not(tmp_path):
    """MeshFormat.warm_up: a text OFF reads its lines by the compiled pass, `OFF BINARY` never does."""
    from raycast_phong.io.meshes import off
    with io.BytesIO(text("# a comment\nCOFF")) as handle:
        assert off.warm_up(handle) == (off._warm_lines,)
    with io.BytesIO(binary(False)) as handle:
        assert off.warm_up(handle) == ()
