"""PLY lists of any length (issue 45): a binary PLY whose faces mix pentagons, quads and triangles was refused
("unexpected length", blaming a valid header line). The files here are written from the PLY specification in
several list types and both byte orders; what each triangle should get (its fan, its corners' coordinates, its
face's colour) is worked out here by hand."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from raycast_phong.cli import app
from raycast_phong.errors import SceneError
from raycast_phong.io.meshes import ply_lists, ply_rows
from raycast_phong.io.meshes.source import mesh_source

runner = CliRunner()

# A house: a square wall (a quad), a roof (a triangle) and a floor pentagon, convex each.
POINTS = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, 1.8, 0), (0, 0, 1), (1, 0, 1), (1.3, 0, 0.5)]
FACES = [(0, 1, 2, 3), (3, 2, 4), (0, 5, 6, 7, 1)]
COLOURS = [(200, 10, 10), (10, 200, 10), (10, 10, 200)]
# The fan from each polygon's first corner, by hand.
FANS = {(0, 1, 2), (0, 2, 3), (3, 2, 4), (0, 5, 6), (0, 6, 7), (0, 7, 1)}
CODES = {"uchar": "B", "char": "b", "ushort": "H", "short": "h", "uint": "I", "int": "i", "float": "f"}
HEAD = ("ply\nformat {form} 1.0\n{comment}element vertex 8\nproperty float x\nproperty float y\n"
        "property float z\nelement face 3\nproperty list {count} {index} vertex_indices\n"
        "{texcoord}property uchar red\nproperty uchar green\nproperty uchar blue\n"
        "end_header\n")


def uv(point) -> tuple[float, float]:
    return point[0] / 2, point[1] / 2 + point[2] / 4


def write_binary(path: Path, order: str, count: str, index: str, texture: bool = False) -> Path:
    """The house in binary PLY; `texture`: with per-corner texcoord lists and a TextureFile (a white image)."""
    end = "<" if order == "little" else ">"
    texcoord = f"property list {count} float texcoord\n" if texture else ""
    comment = "comment TextureFile house.png\n" if texture else ""
    data = HEAD.format(form=f"binary_{order}_endian", count=count, index=index, texcoord=texcoord,
                       comment=comment).encode()
    data += b"".join(struct.pack(end + "3f", *p) for p in POINTS)
    for face, colour in zip(FACES, COLOURS):
        coords = [c for k in face for c in uv(POINTS[k])]
        data += struct.pack(f"{end}{CODES[count]}{len(face)}{CODES[index]}", len(face), *face)
        if texture:
            data += struct.pack(f"{end}{CODES[count]}{len(coords)}f", len(coords), *coords)
        data += struct.pack("3B", *colour)
    path.write_bytes(data)
    if texture:
        Image.new("RGB", (4, 4), (255, 255, 255)).save(path.parent / "house.png")
    return path


def turned(face) -> tuple[int, ...]:
    """A triangle's corners from its smallest on, its winding kept."""
    face = list(face)
    k = face.index(min(face))
    return tuple(face[k:] + face[:k])


@pytest.mark.parametrize("order", ["little", "big"])
@pytest.mark.parametrize("count,index", [("uchar", "int"), ("uchar", "uint"), ("ushort", "ushort"),
                                         ("char", "short"), ("uint", "uint")])
def test_polygons_of_any_size_are_fans_with_their_face_s_colour(tmp_path, order, count, index):
    read = mesh_source(write_binary(tmp_path / "house.ply", order, count, index)).read()
    assert np.allclose(read.vertices, POINTS)
    faces = [turned(f) for f in read.faces.tolist()]
    assert sorted(faces) == sorted(turned(f) for f in FANS)  # each polygon a fan from its first corner
    for face, colour in zip(faces, read.corner_colour[:, 0]):
        polygon = next(k for k, p in enumerate(FACES) if set(face) <= set(p))
        assert np.argmax(colour) == np.argmax(COLOURS[polygon])  # the face's colour, on each of its triangles


@pytest.mark.parametrize("order", ["little", "big"])
def test_per_corner_texture_coordinates_follow_their_corners(tmp_path, order):
    read = mesh_source(write_binary(tmp_path / "house.ply", order, "uchar", "int", texture=True)).read()
    assert sorted(turned(f) for f in read.faces.tolist()) == sorted(turned(f) for f in FANS)
    assert np.allclose(read.corner_uv, [[uv(POINTS[k]) for k in face] for face in read.faces])


def test_even_lists_are_left_to_trimesh_and_walk_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr(ply_rows, "walk_rows", None)  # called: a TypeError
    data = write_binary(tmp_path / "h.ply", "little", "uchar", "int").read_bytes()
    quad = data.replace(b"element face 3", b"element face 1")[: data.index(b"end_header\n") + 11 + 8 * 12 + 1 + 16 + 3]
    assert ply_lists.evened(quad, ply_lists.header(quad), []) is None  # one quad: every list as long as the first
    ascii_ = HEAD.format(form="ascii", count="uchar", index="int", texcoord="", comment="").encode()
    ascii_ += b"0 0 0\n" * 8 + b"4 0 1 2 3 1 1 1\n3 3 2 4 1 1 1\n5 0 5 6 7 1 1 1\n"
    assert ply_lists.evened(ascii_, ply_lists.header(ascii_), []) is None


def test_a_strip_element_of_uneven_rows_is_joined_into_one_strip(tmp_path):
    """Two strips of 4 and 3 indices: joined by -1, then cut as strips (triangles (0,1,2), (2,1,3), (3,2,4))."""
    head = (b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
            b"property float z\nelement tristrips 2\nproperty list uchar int vertex_indices\nend_header\n")
    body = b"".join(struct.pack("<3f", *p) for p in POINTS[:5])
    body += struct.pack("<B4i", 4, 0, 1, 2, 3) + struct.pack("<B3i", 3, 2, 3, 4)
    (tmp_path / "s.ply").write_bytes(head + body)
    read = mesh_source(tmp_path / "s.ply").read()
    assert sorted(map(tuple, read.faces.tolist())) == sorted([(0, 1, 2), (2, 1, 3), (2, 3, 4)])


@pytest.mark.parametrize("cut", [1, 7, 20])
def test_uneven_lists_cut_short_are_one_line_naming_no_valid_header_line(tmp_path, cut):
    data = write_binary(tmp_path / "h.ply", "little", "uchar", "int").read_bytes()
    (tmp_path / "cut.ply").write_bytes(data[:-cut])
    with pytest.raises(SceneError) as error:
        mesh_source(tmp_path / "cut.ply").read()
    text = str(error.value)
    assert "\n" not in text and "header line" not in text and "cut.ply" in text


@pytest.mark.parametrize(("extra", "kind"), [("", "points"), ("property float f_dc_0\nproperty float opacity\n",
                                                              "Gaussian splats")])
@pytest.mark.parametrize("faces", ["", "element face 0\nproperty list uchar int vertex_indices\n"])
def test_a_point_cloud_is_refused_saying_it_is_one(tmp_path, extra, kind, faces):
    """A scan's points or a splat file: no faces, or an empty face element (draco's point clouds). It was
    'holds no triangles' (or 'corrupt'), with no reason."""
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            f"property float z\n{extra}{faces}end_header\n").encode()
    width = 3 + extra.count("property")
    (tmp_path / "p.ply").write_bytes(head + np.arange(3 * width, dtype="<f4").tobytes())
    with pytest.raises(SceneError) as caught:
        mesh_source(tmp_path / "p.ply").read()
    assert f"holds no triangles (a point cloud of 3 {kind}, no faces" in str(caught.value), str(caught.value)


@pytest.mark.parametrize("texture", [False, True])
def test_faces_rewritten_a_few_at_a_time_give_the_same_triangles(tmp_path, monkeypatch, texture):
    """The rewrite works FACE_CHUNK faces at a time (its index arrays stay small): one face a chunk gives the
    same triangles, colours and texture coordinates as all at once."""
    whole = mesh_source(write_binary(tmp_path / "a.ply", "little", "uchar", "int", texture)).read()
    monkeypatch.setattr(ply_lists, "FACE_CHUNK", 1)
    chunked = mesh_source(write_binary(tmp_path / "b.ply", "little", "uchar", "int", texture)).read()
    assert np.array_equal(whole.faces, chunked.faces)
    for name in ("corner_colour", "corner_uv"):
        a, b = getattr(whole, name), getattr(chunked, name)
        assert (a is None and b is None) or np.array_equal(a, b)


@pytest.mark.parametrize("form", ["ascii", "binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize(("vertex_extra", "face_list", "line"), [
    ("property float\n", "property list uchar int vertex_indices\n", 7),  # a scalar with no name
    ("", "property list uchar int\n", 8),  # a list with no name
    ("", "property list uchar\n", 8),  # a list with neither an entry type nor a name
])
def test_a_nameless_property_is_refused_in_one_line_naming_its_header_line(tmp_path, form, vertex_extra, face_list,
                                                                            line):
    """Catches a header parse that takes `property float` or `property list uchar int` without a name (an
    IndexError, exit 1) or lets trimesh read it (before: an ASCII file's nameless scalar was taken silently, the
    next property read from its column), instead of refusing it as bad input naming the line."""
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    head = (f"ply\nformat {form} 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            f"{vertex_extra}element face 1\n{face_list}end_header\n").encode()
    width = 3 + bool(vertex_extra)
    if form == "ascii":
        body = "".join(" ".join(["1"] * width) + "\n" for _ in range(3)).encode() + b"3 0 1 2\n"
    else:
        end = "<" if "little" in form else ">"
        body = struct.pack(f"{end}{3 * width}f", *range(3 * width)) + struct.pack(f"{end}B3i", 3, 0, 1, 2)
    (tmp_path / "p.ply").write_bytes(head + body)
    assert ply_lists.header(head + body) is None
    with pytest.raises(SceneError) as caught:
        mesh_source(tmp_path / "p.ply").read()
    assert f"header line {line}: " in str(caught.value) and "no name" in str(caught.value), str(caught.value)
    done = CliRunner().invoke(app, ["render", str(tmp_path / "p.ply"), "-o", str(tmp_path / "p.png")])
    lines = done.stderr.strip().splitlines()
    assert done.exit_code == 2 and len(lines) == 1 and f"header line {line}: " in lines[0], done.output


def test_a_texcoord_list_uneven_on_a_later_face_is_left_out_with_a_note(tmp_path):
    """Every face's list must hold two values a corner, not only the first face's: a file whose third polygon has
    one value fewer (9 for 5 corners) keeps its faces and colours, and leaves the texture coordinates out, said."""
    path = write_binary(tmp_path / "house.ply", "little", "uchar", "int", texture=True)
    data = path.read_bytes()
    head, body = data.split(b"end_header\n", 1)
    face = FACES[2]
    coords = [c for k in face for c in uv(POINTS[k])]
    whole = struct.pack(f"<B{len(coords)}f", len(coords), *coords)
    cut = struct.pack(f"<B{len(coords) - 1}f", len(coords) - 1, *coords[:-1])
    assert body.count(whole) == 1
    path.write_bytes(head + b"end_header\n" + body.replace(whole, cut))
    read = mesh_source(path).read()
    assert sorted(turned(f) for f in read.faces.tolist()) == sorted(turned(f) for f in FANS)
    assert read.corner_uv is None  # left out: not a misread uv on every face after the short one
    assert any("its face list 'texcoord' is not one or two entries a corner" in note for note in read.notes), \
        read.notes


@pytest.mark.parametrize(("count", "byte", "listed"), [("char", 0x7F, 127), ("char", 0x80, None),
                                                       ("short", 0x7FFF, 32767), ("short", 0x8000, None),
                                                       ("uchar", 0x80, 128)])
def test_a_signed_list_count_at_its_sign_bit_is_negative(count, byte, listed):
    """The row walk reads a list's count in two's complement when its type is signed: a char count byte of 0x7F
    is 127 entries, 0x80 is -128 (no rows fit: the file is refused), while a uchar 0x80 is 128. Catches the sign
    taken from the next value up (0x80 read as +128)."""
    from raycast_phong.io.meshes.ply_rows import walk_rows
    width = {"char": 1, "uchar": 1, "short": 2}[count]
    head = byte.to_bytes(width, "little")
    data = np.frombuffer(head + bytes(4 * (listed or byte)), np.uint8)  # room for +byte entries: only the sign refuses
    starts, found = np.empty(2, np.int64), np.zeros((1, 1), np.int64)
    fits = walk_rows(data, 0, 1, np.array([0], np.int64), np.array([width], np.int64), np.array([4], np.int64),
                     np.array([count != "uchar"], np.bool_), False, starts, found)
    assert fits == (listed is not None)
    if listed is not None:
        assert found[0, 0] == listed and starts.tolist() == [0, width + 4 * listed]


def test_a_face_list_empty_on_every_face_is_left_out_and_the_faces_read(tmp_path):
    """A binary PLY of two triangles whose `texcoord` list is empty on every face (0 entries: a writer's untextured
    faces) is a valid PLY; it was refused as not following the format (trimesh's reader cannot take a list of
    length 0, and the lists, all one length, were left to it). Now the empty list is left out, said, and the
    triangles read. Catches the empty list taken as even (`first < 0` for `first <= 0`)."""
    head = (b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            b"property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
            b"property list uchar float texcoord\nend_header\n")
    body = struct.pack("<12f", 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0)
    body += struct.pack("<B3iB", 3, 0, 1, 2, 0) + struct.pack("<B3iB", 3, 0, 2, 3, 0)
    (tmp_path / "e.ply").write_bytes(head + body)
    read = mesh_source(tmp_path / "e.ply").read()
    assert read.faces.tolist() == [[0, 1, 2], [0, 2, 3]] and read.corner_uv is None
    assert any("its face list 'texcoord' is not one or two entries a corner; it is left out" in note
               for note in read.notes), read.notes


def test_a_uchar_count_of_128_or_more_corners_is_unsigned_in_the_row_walk(tmp_path):
    """A binary PLY of a 130-gon (a uchar count of 130, past the sign bit) beside a triangle, so the rows are
    walked: the uchar count is 130 corners, the polygon a fan of 128 triangles, 129 in all. Catches the count's
    signedness taken the wrong way in element_rows (130 read as -126: the rows refused)."""
    ring = [(np.cos(a), np.sin(a), 0.0) for a in np.linspace(0, 2 * np.pi, 130, endpoint=False)]
    points = [*ring, (3, 0, 0), (4, 0, 0), (3, 1, 0)]
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\nproperty float x\n"
            "property float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\n"
            "end_header\n").encode()
    body = b"".join(struct.pack("<3f", *p) for p in points)
    body += struct.pack("<B130i", 130, *range(130)) + struct.pack("<B3i", 3, 130, 131, 132)
    (tmp_path / "ring.ply").write_bytes(head + body)
    read = mesh_source(tmp_path / "ring.ply").read()
    assert len(read.faces) == 129
    faces = read.faces.tolist()
    assert sorted(map(tuple, faces))[:2] == [(0, 1, 2), (0, 2, 3)] and [130, 131, 132] in faces



def test_an_empty_polygon_ending_an_uneven_file_is_walked(tmp_path):
    """A binary PLY of a quad, a triangle and a face of no corners (a uchar count of 0, the file's last byte): the
    row walk reads that count at the very end as 0 entries, and the quad and triangle read as their fans. Catches
    the walk refusing a count that ends the data, or a count of 0."""
    head = (b"ply\nformat binary_little_endian 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
            b"property float z\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n")
    body = struct.pack("<15f", 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0.5, 1.8, 0)
    body += struct.pack("<B4i", 4, 0, 1, 2, 3) + struct.pack("<B3i", 3, 3, 2, 4) + struct.pack("<B", 0)
    (tmp_path / "e.ply").write_bytes(head + body)
    read = mesh_source(tmp_path / "e.ply").read()
    assert sorted(turned(f) for f in read.faces.tolist()) == [(0, 1, 2), (0, 2, 3), (2, 4, 3)]


@pytest.mark.parametrize(("past", "shown"), [(0, "'property float'"), (1, "'floa'")])
def test_a_bad_header_line_is_read_within_the_first_64_kib(tmp_path, past, shown):
    """A header's bad line is looked for in the file's first 64 KiB (HEADER_LIMIT): a nameless `property float`
    (after comments) ending exactly at byte 65,536 is named whole; a byte later, only `property floa` lies within
    the limit, named as a bad type. Catches the limit one off or doubled (the size is written here)."""
    start = b"ply\nformat ascii 1.0\n"
    tail = b"element vertex 1\nproperty float"
    padding = (1 << 16) - len(start) - len(tail) + past
    comments = b"".join(b"comment " + b"x" * 91 + b"\n" for _ in range(padding // 100))
    comments += b"comment " + b"x" * (padding - len(comments) - 9) + b"\n"
    data = start + comments + tail
    assert len(data) == (1 << 16) + past
    (tmp_path / "p.ply").write_bytes(data + b"\nend_header\n1\n")
    with pytest.raises(SceneError) as caught:
        mesh_source(tmp_path / "p.ply").read()
    assert f"property type {shown} is not a PLY type, or the property has no name" in str(caught.value), \
        str(caught.value)


STRIP_HEAD = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
              "element tristrips 1\nproperty list uchar int {name}\nend_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n")


@pytest.mark.parametrize(("name", "strip"), [
    ("vertex_indices", "4 0 1 3 2"),  # the square: (0, 1, 3) and (3, 1, 2), the second reversed to keep the winding
    ("indices", "4 0 1 3 2"),         # a list not named vertex_indices: not a strip of vertices
    ("vertex_indices", "2 0 1"),      # two indices: no triangle
    ("vertex_indices", "1 0"),        # one index (with its -1, two): too short to window
    ("vertex_indices", "4 0 0 1 1"),  # every triangle repeats a vertex (a strip's join): none drawn
])
def test_an_ascii_strip_makes_its_triangles_or_none(tmp_path, name, strip):
    """An ASCII `tristrips` element, which trimesh reads as vertices alone: triangle i of a strip is (s_i, s_i+1,
    s_i+2), every other one reversed; a strip of fewer than 3 indices, one whose triangles all repeat a vertex, or
    one whose list is not vertex_indices (the PLY description's name) holds no triangle, and the file is refused
    as holding none. Catches the short strip windowed (numpy's error), the empty result returned as a part, and
    the missing list let out as an internal error."""
    path = tmp_path / "s.ply"
    path.write_text(STRIP_HEAD.format(name=name) + strip + "\n")
    if (name, strip) == ("vertex_indices", "4 0 1 3 2"):
        assert mesh_source(path).read().faces.tolist() == [[0, 1, 3], [3, 1, 2]]
        return
    with pytest.raises(SceneError) as caught:
        mesh_source(path).read()
    assert str(caught.value) == (f"{path}: holds no triangles; expected a mesh file of a format read here (OBJ, PLY, "
                                 "STL, OFF, glTF/GLB, 3MF, COLLADA)"), str(caught.value)


ASCII_QUAD = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float {x}\nproperty float y\nproperty float z\n"
              "element face 1\nproperty list uchar int vertex_indices\nend_header\n{body}")
SQUARE_LINES = "0 0 0\n1 0 0\n1 1 0\n0 1 0\n"


@pytest.mark.parametrize("body", [SQUARE_LINES.replace("1 0 0", "1 0 abc") + "4 0 1 2 3\n",
                                  SQUARE_LINES + "4 0 1 2 x\n"])
def test_an_ascii_polygon_file_with_a_word_that_is_not_a_number_is_one_line(tmp_path, body):
    """An ASCII PLY of a quad whose vertex or face line holds a word that is not a number: the concave-polygon
    scan leaves the file to trimesh, which cannot read it: the renderer's one line, exit 2. It was an internal
    error with a traceback: numpy 2's text reader raises ValueError where numpy 1 warned, and the scan caught
    only the warning."""
    (tmp_path / "w.ply").write_text(ASCII_QUAD.format(x="x", body=body))
    done = runner.invoke(app, ["render", str(tmp_path / "w.ply"), "-o", str(tmp_path / "o.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert line.startswith(f"error: {tmp_path / 'w.ply'}: cannot read the file as PLY: its content does not follow "
                           "the PLY format where the reader stopped"), line
    assert ply_lists.ascii_cut(ASCII_QUAD.format(x="x", body=body).encode(),
                               ply_lists.header(ASCII_QUAD.format(x="x", body=body).encode())) is None


@pytest.mark.parametrize(("x", "body", "said"), [
    ("x", SQUARE_LINES[:12], "holds no triangles; expected"),  # 2 of its 4 vertex lines: no face line
    ("px", SQUARE_LINES + "4 0 1 2 3\n", "cannot read the file as PLY"),  # no x: not a mesh trimesh reads
    ("x", SQUARE_LINES + "4 0 1 2 nan\n", "has 1 face(s) with a vertex index outside 0..3"),
])
def test_an_ascii_polygon_file_the_concave_scan_cannot_read_is_left_to_the_reader(tmp_path, x, body, said):
    """The concave-polygon scan reads only the plain form (vertex lines of x, y, z; whole face lines): a file cut
    short before its faces, one without x, or a face index that is not finite is left as it is (ascii_cut gives
    None) and refused by the read in one line. Catches each guard dropped (an IndexError, a KeyError or a NaN
    index cut, an internal error)."""
    data = ASCII_QUAD.format(x=x, body=body).encode()
    assert ply_lists.ascii_cut(data, ply_lists.header(data)) is None
    (tmp_path / "c.ply").write_bytes(data)
    with pytest.raises(SceneError) as caught:
        mesh_source(tmp_path / "c.ply").read()
    assert str(caught.value).startswith(f"{tmp_path / 'c.ply'}: {said}"), str(caught.value)


@pytest.mark.parametrize("body", [SQUARE_LINES.replace("1 0 0", "1 0 0 5") + "4 0 1 2 3\n",  # a vertex line long
                                  SQUARE_LINES + "5 0 1 2 3\n",                               # a face count over
                                  SQUARE_LINES + "4 0 1 2 3\n"])                              # convex: no cut
def test_an_ascii_quad_the_scan_need_not_cut_is_left_as_written(body):
    """ascii_cut rewrites only concave polygons of the plain form: a file whose vertex lines do not hold the
    header's numbers, a face that counts more indices than it gives, or a convex quad is given back as None
    (trimesh reads it, fanning the quad). Catches the table reshaped whatever its size (numpy's error) and a
    rewrite made with nothing to cut."""
    data = ASCII_QUAD.format(x="x", body=body).encode()
    assert ply_lists.ascii_cut(data, ply_lists.header(data)) is None


def test_a_convex_ascii_quad_is_fanned(tmp_path):
    """The square 0 1 2 3 (convex) as two triangles of its fan from a corner, covering it once: the corners'
    positions of both triangles span the square and share its diagonal."""
    (tmp_path / "q.ply").write_text(ASCII_QUAD.format(x="x", body=SQUARE_LINES + "4 0 1 2 3\n"))
    found = mesh_source(tmp_path / "q.ply").read()
    assert sorted(turned(f) for f in found.faces.tolist()) == [(0, 1, 2), (0, 2, 3)]


def uneven_file(extra_head: str, extra_body: bytes, face_list: str = "vertex_indices") -> bytes:
    """The house's vertices and polygons (uneven lists), little-endian, then `extra_head`'s element."""
    data = (f"ply\nformat binary_little_endian 1.0\nelement vertex 8\nproperty float x\nproperty float y\n"
            f"property float z\nelement face 3\nproperty list uchar int {face_list}\n{extra_head}end_header\n").encode()
    data += b"".join(struct.pack("<3f", *p) for p in POINTS)
    data += b"".join(struct.pack(f"<B{len(face)}i", len(face), *face) for face in FACES)
    return data + extra_body


@pytest.mark.parametrize(("head", "body", "name"), [
    ("element edge 2\nproperty list uchar int vertex_indices\n", struct.pack("<B2iB3i", 2, 0, 1, 3, 1, 2, 3), "edge"),
    ("element tristrips 2\nproperty list uchar int vertex_indices\nproperty uchar flag\n",
     struct.pack("<B3iBB4iB", 3, 0, 1, 2, 0, 4, 0, 1, 2, 3, 0), "tristrips"),
])
def test_another_element_of_uneven_lists_is_left_out_and_the_faces_read(tmp_path, head, body, name):
    """An element of uneven lists that is neither `face` nor a one-list `tristrips` (edges; strips with a flag
    beside their list) is left out, one note naming it; the faces read as their fans. Catches the note dropped
    and the element's rows kept in the rewrite (the file then misread)."""
    (tmp_path / "e.ply").write_bytes(uneven_file(head, body))
    found = mesh_source(tmp_path / "e.ply").read()
    assert sorted(turned(f) for f in found.faces.tolist()) == sorted(turned(f) for f in FANS)
    assert f"its element {name!r} has lists of uneven length; it is left out" in found.notes, found.notes


def test_a_face_element_of_uneven_lists_without_vertex_indices_holds_no_triangles(tmp_path):
    """A face element whose only list is not vertex_indices (nor vertex_index, its common variant) names no
    polygon: left out, said, and the file refused as holding no triangles, the reason given. Catches a list
    of another name taken for the polygons."""
    (tmp_path / "n.ply").write_bytes(uneven_file("", b"", face_list="corners"))
    with pytest.raises(SceneError) as caught:
        mesh_source(tmp_path / "n.ply").read()
    assert str(caught.value).startswith(f"{tmp_path / 'n.ply'}: holds no triangles (its element 'face' has lists of "
                                        "uneven length; it is left out)"), str(caught.value)


def test_face_properties_before_the_polygon_list_are_stepped_over(tmp_path):
    """A face row of a uchar flag and a per-corner texcoord list before vertex_indices (the PLY description
    orders a row's properties as the header does): the polygon's indices are found after them. The quad (2 0),
    (0.5 0.5), (0 2), (0 0) is concave at its second corner, so its fan from the first corner would leave it
    (the diagonal (2 0)-(0 2) runs outside); its only triangulation takes the diagonal from that corner, 1-3:
    (1, 2, 3) and (3, 0, 1). A triangle beside it makes the lists uneven. Each triangle keeps its corners'
    coordinates. Catches the scalar's or the list's bytes not counted before the polygon (the concave test then
    reads other bytes as indices, and the quad is fanned)."""
    points = [(2, 0, 0), (0.5, 0.5, 0), (0, 2, 0), (0, 0, 0), (3, 0, 0)]
    faces = [(0, 1, 2, 3), (0, 4, 1)]
    data = (b"ply\nformat binary_little_endian 1.0\ncomment TextureFile t.png\nelement vertex 5\n"
            b"property float x\nproperty float y\nproperty float z\nelement face 2\nproperty uchar flag\n"
            b"property list uchar float texcoord\nproperty list uchar int vertex_indices\nend_header\n")
    data += b"".join(struct.pack("<3f", *p) for p in points)
    for face in faces:
        coords = [c for k in face for c in uv(points[k])]
        data += struct.pack(f"<BB{len(coords)}fB{len(face)}i", 7, len(coords), *coords, len(face), *face)
    (tmp_path / "q.ply").write_bytes(data)
    Image.new("RGB", (4, 4), (255, 255, 255)).save(tmp_path / "t.png")
    found = mesh_source(tmp_path / "q.ply").read()
    assert sorted(turned(f) for f in found.faces.tolist()) == [(0, 1, 3), (0, 4, 1), (1, 2, 3)]
    assert np.allclose(found.corner_uv, [[uv(points[k]) for k in face] for face in found.faces])


def test_a_header_whose_element_count_or_format_is_wrong_does_not_parse(tmp_path):
    """`element vertex x` (no whole count) and `format binary_middle_endian` (the PLY formats are ascii,
    binary_little_endian and binary_big_endian) are no PLY header: header() gives None, so the read names the
    bad element line, and the unknown format is not read as little-endian (it is refused). Catches either
    check dropped (int('x') raised; the body read in a format the file does not have)."""
    good = write_binary(tmp_path / "h.ply", "little", "uchar", "int").read_bytes()
    assert ply_lists.header(good) is not None
    bad_count = good.replace(b"element vertex 8", b"element vertex x")
    assert ply_lists.header(bad_count) is None
    (tmp_path / "c.ply").write_bytes(bad_count)
    with pytest.raises(SceneError, match=r"header line 3: 'element vertex x' is not an element"):
        mesh_source(tmp_path / "c.ply").read()
    middle = good.replace(b"binary_little_endian", b"binary_middle_endian")
    assert ply_lists.header(middle) is None
    (tmp_path / "m.ply").write_bytes(middle)
    with pytest.raises(SceneError) as caught:  # trimesh reads it as big-endian: its indices out of range
        mesh_source(tmp_path / "m.ply").read()
    assert str(caught.value).startswith(f"{tmp_path / 'm.ply'}: ") and "\n" not in str(caught.value)


def test_a_vertex_element_whose_z_is_a_list_is_refused_in_one_line(tmp_path):
    """A vertex element with x and y scalars and z a list (one entry each) has no positions the concave-polygon
    test can use (_points gives none), and trimesh cannot read it as vertices: the renderer's one line. Catches
    the missing z looked up anyway (a KeyError, an internal error)."""
    data = (b"ply\nformat binary_little_endian 1.0\nelement vertex 8\nproperty float x\nproperty float y\n"
            b"property list uchar float z\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n")
    data += b"".join(struct.pack("<2fBf", p[0], p[1], 1, p[2]) for p in POINTS)
    data += b"".join(struct.pack(f"<B{len(face)}i", len(face), *face) for face in FACES)
    (tmp_path / "z.ply").write_bytes(data)
    with pytest.raises(SceneError) as caught:
        mesh_source(tmp_path / "z.ply").read()
    assert str(caught.value).startswith(f"{tmp_path / 'z.ply'}: cannot read the file as PLY"), str(caught.value)
