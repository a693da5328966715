"""A plain PLY is read by numpy views of its bytes or one parse of its text (io/meshes/ply.plain_part), without
trimesh, into the very MeshFile trimesh's reader gave; every other PLY still goes to trimesh. The files are written
here from the PLY specification (header lines, then rows of each element in order, either endianness or ASCII)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_obj_plain import assert_same_mesh_file

from raycast_phong.errors import SceneError
from raycast_phong.io.meshes import decimals, ply
from raycast_phong.io.meshes import read as mesh_file
from raycast_phong.io.meshes.source import mesh_source

pytestmark = pytest.mark.usefixtures("in_tmp_path")

RNG = np.random.default_rng(7)
POINTS = RNG.normal(size=(9, 3))
FACES = np.array([[0, 1, 2], [2, 3, 4], [4, 5, 6], [6, 7, 8], [8, 0, 4]])


def write_ply(path: Path, vertex: dict[str, tuple[str, np.ndarray]], faces=FACES, *, big: bool = False,
              face_first: bool = False, index_name: str = "vertex_indices", comments: tuple[str, ...] = (),
              face_extra: dict[str, tuple[str, np.ndarray]] | None = None, ascii: bool = False) -> Path:
    """A binary (or `ascii`) PLY of one `vertex` element (name: (PLY type, values)) and one `face` element of
    triangles; ASCII rows a line each, every value written in its type's shortest round-trip form."""
    kinds = {"float": "f4", "double": "f8", "uchar": "u1", "int": "i4", "ushort": "u2"}
    order = ">" if big else "<"
    vertex_rows = np.zeros(len(POINTS), [(name, order + kinds[kind]) for name, (kind, _) in vertex.items()])
    for name, (_, values) in vertex.items():
        vertex_rows[name] = values
    extra = face_extra or {}
    face_rows = np.zeros(len(faces), [("n", "u1"), ("i", order + "i4", (faces.shape[1],)),
                                      *[(name, order + kinds[kind]) for name, (kind, _) in extra.items()]])
    face_rows["n"], face_rows["i"] = faces.shape[1], faces
    for name, (_, values) in extra.items():
        face_rows[name] = values
    vertex_lines = [f"element vertex {len(POINTS)}", *(f"property {kind} {name}" for name, (kind, _) in vertex.items())]
    face_lines = [f"element face {len(faces)}", f"property list uchar int {index_name}",
                  *(f"property {kind} {name}" for name, (kind, _) in extra.items())]
    blocks = [(face_lines, face_rows), (vertex_lines, vertex_rows)] if face_first else \
        [(vertex_lines, vertex_rows), (face_lines, face_rows)]
    form = "ascii" if ascii else f"binary_{'big' if big else 'little'}_endian"
    header = ["ply", f"format {form} 1.0", *comments, *[line for lines, _ in blocks for line in lines], "end_header"]
    if ascii:
        body = "".join(" ".join(str(value) for field in row.dtype.names for value in np.ravel(row[field])) + "\n"
                       for _, rows in blocks for row in rows).encode()
    else:
        body = b"".join(rows.tobytes() for _, rows in blocks)
    path.write_bytes(("\n".join(header) + "\n").encode() + body)
    return path


def xyz(kind: str = "float") -> dict:
    return {axis: (kind, POINTS[:, k]) for k, axis in enumerate("xyz")}


NORMALS = {f"n{axis}": ("float", POINTS[:, k] / np.linalg.norm(POINTS, axis=1)) for k, axis in enumerate("xyz")}
COLOURS = {name: ("uchar", RNG.integers(0, 256, len(POINTS))) for name in ("red", "green", "blue", "alpha")}
PLAIN = {
    "float": {"vertex": xyz()},
    "double": {"vertex": xyz("double")},
    "big-endian": {"vertex": xyz(), "big": True},
    "normals": {"vertex": {**xyz(), **NORMALS}},
    "rgb": {"vertex": {**xyz(), **{k: COLOURS[k] for k in ("red", "green", "blue")}}},
    "rgba, big-endian": {"vertex": {**xyz(), **COLOURS}, "big": True},
    "another scalar": {"vertex": {**xyz(), "quality": ("float", RNG.normal(size=len(POINTS)))}},
    "face element first": {"vertex": xyz(), "face_first": True},
    "vertex_index": {"vertex": xyz(), "index_name": "vertex_index"},
}
TRIMESH_READS = {
    "uv per vertex": {"vertex": {**xyz(), "s": ("float", POINTS[:, 0]), "t": ("float", POINTS[:, 1])}},
    "texture file": {"vertex": xyz(), "comments": ("comment TextureFile missing.png",)},
    "face colours": {"vertex": xyz(), "face_extra": {k: ("uchar", np.arange(len(FACES))) for k in ("red", "green",
                                                                                                  "blue")}},
    "16-bit colours": {"vertex": {**xyz(), **{k: ("ushort", COLOURS[k][1] * 200) for k in ("red", "green",
                                                                                             "blue")}}},
    "red and green only": {"vertex": {**xyz(), **{k: COLOURS[k] for k in ("red", "green")}}},
    "integer coordinates": {"vertex": {axis: ("int", np.arange(len(POINTS)) * (k + 1)) for k, axis in
                                        enumerate("xyz")}},
    "quads": {"vertex": xyz(), "faces": np.array([[0, 1, 2, 3], [4, 5, 6, 7]])},
}


def read(path: Path, plain: bool, monkeypatch) -> mesh_file.MeshFile:
    with monkeypatch.context() as patch:
        if not plain:
            patch.setattr(ply, "plain_part", lambda data, header: None)
        return mesh_file.read_file(mesh_source(path), bounds=True)


@pytest.mark.parametrize("ascii", [False, True], ids=["binary", "ascii"])
@pytest.mark.parametrize("case", PLAIN)
def test_a_plain_ply_reads_without_trimesh_as_trimesh_read_it(case, ascii, tmp_path, monkeypatch):
    """Binary and ASCII alike (ASCII: the vertex element first, little- or big-endian meaningless)."""
    if ascii and ({"big", "face_first"} & PLAIN[case].keys()):
        pytest.skip("a binary layout")
    path = write_ply(tmp_path / "plain.ply", **PLAIN[case], ascii=ascii)
    data = path.read_bytes()
    assert ply.plain_part(data, ply.ply_lists.header(data)) is not None
    assert_same_mesh_file(read(path, True, monkeypatch), read(path, False, monkeypatch))


@pytest.mark.parametrize("ascii", [False, True], ids=["binary", "ascii"])
@pytest.mark.parametrize("case", TRIMESH_READS)
def test_any_other_ply_is_left_to_trimesh(case, ascii, tmp_path, monkeypatch):
    path = write_ply(tmp_path / "other.ply", **TRIMESH_READS[case], ascii=ascii)
    data = path.read_bytes()
    assert ply.plain_part(data, ply.ply_lists.header(data)) is None


@pytest.mark.parametrize(("change", "why"), [
    (lambda text: text + "x\n", "a line past the rows (trimesh ignores it): still plain"),
    (lambda text: text.replace("\n3 0 1 2\n", "\n3 0 1 2 7\n"), "a row one number too long"),
    (lambda text: text.replace("\n3 0 1 2\n", "\n3 0 1 x\n"), "a word that is not a number"),
    (lambda text: text.replace("\n3 8 0 4", ""), "a face row missing"),
    (lambda text: text.replace("\n3 0 1 2\n3 2 3 4\n", "\n4 0 1 2 3\n2 3 4\n"), "a quad and a two-gon: as many "
     "numbers as two triangles"),
    (lambda text: "\n" + text[1:].split("\n", 1)[0].rsplit(" ", 1)[0] + "\n" + text[1:].split("\n", 1)[1],
     "a vertex row one number short"),
    (lambda text: text.replace("\n", "\r"), "CR-only line ends"),
])
def test_an_ascii_ply_off_the_plain_layout_is_left_to_trimesh(change, why, tmp_path):
    """ascii_rows reads one row a line, every face a triangle; anything else goes to trimesh (which reads it,
    or says what is wrong), never a Part of misplaced numbers."""
    path = write_ply(tmp_path / "a.ply", xyz(), ascii=True)
    head, body = path.read_text().split("end_header\n")
    text = head + "end_header\n" + change("\n" + body)[1:]
    data = text.encode()
    found = ply.plain_part(data, ply.ply_lists.header(data))
    assert (found is not None) == why.endswith("still plain"), why


def test_an_ascii_ply_is_read_as_written_by_hand(tmp_path):
    """The numbers of a small ASCII file, as trimesh reads them: each value in its declared type (a `float`
    0.1 is float32's 0.1, a `double` keeps 0.1), indices as written."""
    text = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty double y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n0.1 0.1 0\n1 0 0\n0 1 -2.5\n"
            "3 2 0 1\n")
    part = ply.plain_part(text.encode(), ply.ply_lists.header(text.encode()))
    np.testing.assert_array_equal(part.vertices, [[np.float64(np.float32(0.1)), 0.1, 0], [1, 0, 0], [0, 1, -2.5]])
    np.testing.assert_array_equal(part.faces, [[2, 0, 1]])
    assert part.vertices.dtype == np.float64 and part.faces.dtype == np.int64


def test_the_colours_and_normals_of_a_plain_ply_are_the_file_s(tmp_path, monkeypatch):
    """Hand-checked against the values written: 8-bit colour / 255 at each face corner, normals as stored."""
    path = write_ply(tmp_path / "c.ply", **PLAIN["normals"] | {"vertex": {**xyz(), **NORMALS, **COLOURS}})
    read_back = read(path, True, monkeypatch)
    rgb = np.column_stack([COLOURS[k][1] for k in ("red", "green", "blue")]).astype(np.float32) / 255
    np.testing.assert_array_equal(read_back.corner_colour, rgb[FACES])
    np.testing.assert_array_equal(read_back.normals, np.column_stack([NORMALS[k][1] for k in ("nx", "ny", "nz")])
                                  .astype(np.float32).astype(np.float64))
    np.testing.assert_array_equal(read_back.faces, FACES)


def test_a_mixed_polygon_ply_is_read_without_trimesh_after_its_fans(tmp_path, monkeypatch):
    """A quad beside a triangle (uneven lists): rewritten as fans (ply_lists), then read plainly, as trimesh read
    the rewrite. The quad is a convex square (a twisted one is ear-clipped: tests/io/test_polygons.py)."""
    points = POINTS.copy()
    points[:4] = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    rows = np.zeros(len(points), [(axis, "<f4") for axis in "xyz"])
    for k, axis in enumerate("xyz"):
        rows[axis] = points[:, k]
    body = rows.tobytes() + bytes([4]) + np.array([0, 1, 2, 3], "<i4").tobytes() + bytes([3]) + \
        np.array([4, 5, 6], "<i4").tobytes()
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(POINTS)}\nproperty float x\n"
              "property float y\nproperty float z\nelement face 2\nproperty list uchar int vertex_indices\n"
              "end_header\n")
    path = tmp_path / "mixed.ply"
    path.write_bytes(header.encode() + body)
    plain = read(path, True, monkeypatch)
    assert_same_mesh_file(plain, read(path, False, monkeypatch))
    np.testing.assert_array_equal(plain.faces, [[0, 1, 2], [0, 2, 3], [4, 5, 6]])


@pytest.mark.parametrize("suffix", ["ply", "ascii.ply", "stl", "ascii.stl", "off", "obj"])
def test_reading_a_plain_mesh_file_does_not_import_trimesh(suffix, tmp_path):
    """trimesh's import (with SciPy's) is 0.3-0.7 s of a process: only a file it alone reads pays for it."""
    path = tmp_path / f"plain.{suffix}"
    if suffix.endswith("ply"):
        write_ply(path, vertex=xyz(), ascii=suffix == "ascii.ply")
    elif suffix == "stl":
        corners = POINTS[FACES].astype("<f4")
        records = np.zeros(len(FACES), [("normal", "<f4", 3), ("corners", "<f4", (3, 3)), ("spare", "<u2")])
        records["corners"] = corners
        path.write_bytes(bytes(80) + np.uint32(len(FACES)).tobytes() + records.tobytes())
    elif suffix == "ascii.stl":
        corners = ["".join(f"vertex {x} {y} {z}\n" for x, y, z in POINTS[face]) for face in FACES]
        facets = "".join(f"facet normal 0 0 1\nouter loop\n{three}endloop\nendfacet\n" for three in corners)
        path.write_text(f"solid plain\n{facets}endsolid plain\n")
    else:
        points = "".join(f"{'v ' if suffix == 'obj' else ''}{x} {y} {z}\n" for x, y, z in POINTS)
        faces = "".join(f"f {a + 1} {b + 1} {c + 1}\n" if suffix == "obj" else f"3 {a} {b} {c}\n" for a, b, c in FACES)
        head = "" if suffix == "obj" else f"OFF\n{len(POINTS)} {len(FACES)} 0\n"
        path.write_text(head + points + faces)
    code = ("import sys; from raycast_phong.io.meshes.source import read_mesh; "
            f"mesh = read_mesh(__import__('pathlib').Path({str(path)!r})); "
            "assert len(mesh.faces) == 5, mesh.faces; print('trimesh' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


@pytest.mark.parametrize("end", [b"\r", b"\r\n"])
@pytest.mark.parametrize("form", ["ascii", "binary_little_endian"])
def test_a_header_of_carriage_return_terminated_lines_is_read(tmp_path, form, end):
    """The PLY description says "carriage-return terminated lines"; Rhino 6 writes CR alone (its end_header
    `\\r\\n`), and the file was refused as having no end_header. The body follows the header's last byte."""
    from raycast_phong.io.meshes.source import read_mesh
    corners = np.array([[0, 0, 0], [1, 0, 0], [0, 2, 0]], np.float32)
    lines = [b"ply", f"format {form} 1.0".encode(), b"element vertex 3", b"property float x", b"property float y",
             b"property float z", b"element face 1", b"property list uchar int vertex_indices"]
    head = b"\r".join(lines) + b"\rend_header" + end
    if form == "ascii":
        body = b"\r".join(" ".join(f"{v:g}" for v in row).encode() for row in corners) + b"\r3 0 1 2\r"
    else:
        body = corners.tobytes() + bytes([3]) + np.array([0, 1, 2], "<i4").tobytes()
    path = tmp_path / "cr.ply"
    path.write_bytes(head + body)
    mesh = read_mesh(path)
    assert np.array_equal(mesh.vertices[mesh.faces[0]], corners)


def test_a_format_line_without_its_version_is_read(tmp_path):
    """`format binary_little_endian` with the version left out (two words, where writers put `1.0`): the header
    parses with its format and the file reads as with the version. Catches the format line needing 3 words."""
    path = write_ply(tmp_path / "plain.ply", xyz())
    data = path.read_bytes().replace(b"format binary_little_endian 1.0\n", b"format binary_little_endian\n", 1)
    path.write_bytes(data)
    assert ply.ply_lists.header(data).format == "binary_little_endian"
    found = mesh_source(path).read()
    np.testing.assert_array_equal(found.vertices, POINTS.astype(np.float32).astype(np.float64))
    np.testing.assert_array_equal(found.faces, FACES)


def test_a_bad_element_line_in_a_carriage_return_header_is_named_by_its_line(tmp_path):
    """A header of CR-terminated lines (the PLY description's own line end) with no end_header: its lines are
    still told apart, so `element vertex x` (a count that is not a whole number) is named as header line 3.
    Catches the CRs left as they are when no end_header ends them (the header one line, only "no end_header"
    said) and the element check dropped."""
    path = tmp_path / "cr.ply"
    path.write_bytes(b"ply\rformat ascii 1.0\relement vertex x\rproperty float x\r")
    with pytest.raises(SceneError) as caught:
        mesh_source(path).read()
    assert str(caught.value) == (f"{path}: header line 3: 'element vertex x' is not an element; allowed: element "
                                 "NAME COUNT, COUNT a whole number"), str(caught.value)


def test_a_header_without_end_header_is_refused_saying_so(tmp_path):
    """The PLY header ends at `end_header`; one that never does (cut short) is refused naming how far it was
    looked for (the file's 70 bytes here). Catches the end_header check's words or the bytes counted wrong."""
    path = tmp_path / "open.ply"
    data = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
    path.write_bytes(data)
    with pytest.raises(SceneError) as caught:
        mesh_source(path).read()
    assert str(caught.value) == (f"{path}: has no end_header line in its first {len(data)} bytes; allowed: a PLY "
                                 "header ending in end_header"), str(caught.value)


def test_a_carriage_return_header_longer_than_the_count_s_read_is_counted(tmp_path):
    """The cheap count reads 4096 bytes: a CR-terminated header whose end_header lies past them (long comments
    after the elements) still has its `element face 7` found, its lines told apart without the end_header.
    Catches the CRs left in place (no line starts with `element`: the count weighed by the file's size instead)."""
    comments = b"".join(b"comment " + b"x" * 91 + b"\r" for _ in range(50))  # 5000 bytes
    head = (b"ply\rformat ascii 1.0\relement vertex 9\rproperty float x\rproperty float y\rproperty float z\r"
            b"element face 7\rproperty list uchar int vertex_indices\r" + comments + b"end_header\r")
    path = tmp_path / "long.ply"
    path.write_bytes(head + b"0 0 0\r" * 9 + b"3 0 1 2\r" * 7)
    assert head.find(b"end_header") > 4096
    assert mesh_source(path).triangles() == 7


def _word(rng) -> str:
    """A decimal as exporters write them: a sign or not, digits around a point or not, an exponent or not;
    at most 15 digits and 10^±22, on the exact path."""
    digits = "".join(rng.choice(list("0123456789"), size=int(rng.integers(1, 16))))
    cut = int(rng.integers(0, len(digits) + 1))
    word = rng.choice(["", "-", "+"]) + (digits[:cut] + "." + digits[cut:] if rng.random() < 0.7 else digits)
    return word + (f"{rng.choice(['e', 'E'])}{int(rng.integers(-7, 8))}" if rng.random() < 0.3 else "")


def test_an_ascii_ply_s_compiled_rows_are_numpy_s_parse_bit_for_bit(monkeypatch):
    """ply_lists._rows reads the rows in one compiled pass; its float64 values must be the very bits numpy's
    parse of the same text gives (the parse trimesh makes), over random decimals separated by spaces, tabs and
    CRLF line ends; and the compiled pass must be what read them (numpy's parse, the fallback, is barred)."""
    rng = np.random.default_rng(11)
    rows = [[_word(rng) for _ in range(5)] for _ in range(400)]
    lines = [rng.choice([" ", "\t", "  "]).join(row) + rng.choice(["", " ", "\r"]) for row in rows]
    faces = [f"3 {a} {b} {c}" for a, b, c in rng.integers(0, 400, (50, 3))]
    text = ("\n".join(lines) + "\n" + "\n".join(faces)).encode()  # the last line without its line feed
    expected = np.fromstring(text[:text.index(faces[0].encode())], sep=" ").reshape(-1, 5)
    monkeypatch.setattr(decimals, "numpy_rows", None)
    read = ply.ply_lists._rows(text, 0, len(rows), 5, len(faces))
    assert read[0].tobytes() == expected.tobytes()
    np.testing.assert_array_equal(read[1], [[3, *map(int, face.split()[1:])] for face in faces])


@pytest.mark.parametrize(("body", "why"), [
    ("1 2 3\n4 5\n3 0 1 1\n", "a row one word short"),
    ("1 2 3\n4 5 6 7\n3 0 1 1\n", "a row one word long"),
    ("1 2 3 4\n5 6\n3 0 1 1\n", "a row one word long, the next one short: as many numbers in all"),
    ("1 2 3\n\n4 5 6\n3 0 1 1\n", "a blank line among the rows"),
    ("1 2 3\n4 5 6\n3 0 1 1 1\n", "a face row one word long"),
    ("1 2 3\n4 5 6\n", "the face rows missing"),
    ("1 2 3\n4 5 nan x\n3 0 1 1\n", "a row one word long, the word off the exact path"),
])
def test_an_ascii_ply_s_rows_off_one_row_a_line_are_none(body, why):
    """Every row on its own line, `width` words each: anything else is not the plain layout (trimesh reads it,
    or says what is wrong), never rows of misplaced numbers."""
    assert ply.ply_lists._rows(body.encode(), 0, 2, 3, 1) is None, why


@pytest.mark.parametrize(("body", "why"), [
    ("1 2 1e30\n4 5 6\n3 0 1 1\n", "a power of ten past 10^22"),
    ("1 2 12345678901234567890\n4 5 6\n3 0 1 1\n", "twenty digits: past 2^53"),
    ("1 2 nan\n4 5 -inf\n3 0 1 1\n", "words numpy reads as numbers"),
    ("1 2 3\n4 5 6\n3 0 1 1e0\n", "only the faces' words: an exponent on an index is exact, still read"),
    ("1 2 3\n4 5 6\n3 0 1 12345678901234567890\n", "a face index of twenty digits"),
    ("1 2 3\x0b\n4 5 6\n3 0 1 1\n", "whitespace the pass does not split on"),
    ("1 2 1e18446744073709551621\n4 5 6\n3 0 1 1\n", "an exponent of 2^64 + 5: inf, not 1e5 wrapped round"),
    ("1 2 3\n4 5 6\n3 0 1 12345678901234567890\n# a line past the rows\n", "a line past the face rows, "
     "which trimesh ignores: numpy's parse of the faces stops at their last line"),
])
def test_an_ascii_ply_s_words_off_the_exact_path_are_numpy_s_parse(body, why):
    """Where a word is off the compiled pass's exact path, numpy's parse reads that section, as before."""
    data = body.encode()
    read = ply.ply_lists._rows(data, 0, 2, 3, 1)
    cut = data.index(b"\n3 ") + 1
    end = data.find(b"\n", cut) + 1 or len(data)
    np.testing.assert_array_equal(read[0], np.fromstring(data[:cut], sep=" ").reshape(2, 3), why)
    np.testing.assert_array_equal(read[1], np.fromstring(data[cut:end], sep=" ").reshape(1, 4), why)


def test_an_ascii_ply_header_s_row_count_allocates_nothing_the_file_cannot_hold():
    """`element vertex 10^12` in a 200-byte file: the compiled pass would allocate 24 TB for its rows; it gives
    up from the file's size first, and the read says the file is short (trimesh's words) without a MemoryError."""
    text = ("ply\nformat ascii 1.0\nelement vertex 1000000000000\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 0 0\n")
    data = text.encode()
    header = ply.ply_lists.header(data)
    assert ply.ply_lists._rows(data, header.body, 10 ** 12, 3, 1) is None
    assert ply.ply_lists.ascii_rows(data, header) is None


def test_an_ascii_face_index_past_its_declared_type_is_refused_not_wrapped(tmp_path):
    """`property list uchar int`: an index of 2³² + 1 is not an int; cast to int32 it would wrap to vertex 1 and
    draw a wrong triangle silently (trimesh's cast). Read as written, it is out of range: one line."""
    from raycast_phong.io.meshes.source import read_mesh
    path = tmp_path / "wrap.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n"
                    f"3 0 {2**32 + 1} 2\n")
    with pytest.raises(SceneError) as refused:
        read_mesh(path)
    assert "4294967297" in str(refused.value) and "\n" not in str(refused.value), refused.value


def test_an_ascii_ply_whose_concave_quad_is_cut_is_read_without_trimesh(tmp_path, monkeypatch):
    """An ASCII PLY of a concave quad (a dart: its fourth corner is reflex) is refused by plain_part as written,
    then cut by ascii_cut into two triangles, which plain_part reads: trimesh's reader is never called, and the
    cut is ear clipping's (the fan from corner 0 would cover the notch), so both triangles turn one way."""
    from raycast_phong.io.meshes import trimesh_parts
    path = tmp_path / "dart.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                    "0 0 0\n2 1 0\n0 2 0\n0.5 1 0\n4 0 1 2 3\n")
    monkeypatch.setattr(trimesh_parts, "load", None)
    mesh = mesh_file.read_file(mesh_source(path), bounds=True)
    corners = mesh.vertices[mesh.faces]
    turns = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])[:, 2]
    assert len(mesh.faces) == 2 and (turns > 0).all() and np.isclose(turns.sum() / 2, 1.5), (mesh.faces, turns)
