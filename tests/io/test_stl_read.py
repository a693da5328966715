"""A binary STL is read by io/meshes/stl.py itself (float32 corners straight from its records), an ASCII one by
trimesh; both give trimesh's points, and the memory guard's floor follows what each read costs."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
import trimesh

from raycast_phong.geometry.build import build_geometry
from raycast_phong.io.meshes import read as mesh_file
from raycast_phong.io.meshes import stl
from raycast_phong.io.meshes.format import TEXT_READ_BYTES_PER_BYTE
from raycast_phong.io.meshes.source import mesh_source, read_mesh
from raycast_phong.scene.schema import validate_scene


def knot_corners() -> np.ndarray:
    mesh = trimesh.creation.torus(1.0, 0.35, major_sections=24, minor_sections=12)
    return mesh.vertices[mesh.faces]


@pytest.fixture
def stl_files(tmp_path):
    mesh = trimesh.Trimesh(*(lambda c: (c.reshape(-1, 3), np.arange(c.size // 3).reshape(-1, 3)))(knot_corners()),
                           process=False)
    mesh.export(tmp_path / "binary.stl")
    mesh.export(tmp_path / "ascii.stl", file_type="stl_ascii")
    return tmp_path / "binary.stl", tmp_path / "ascii.stl"


def test_a_binary_stl_is_read_as_float32_corners_with_trimesh_values(stl_files):
    binary, ascii_file = stl_files
    read = read_mesh(binary, "t")
    theirs = trimesh.load(binary, process=False)
    assert read.vertices.dtype == np.float32  # trimesh's float64 copy is 72 bytes a triangle, this one 36
    np.testing.assert_array_equal(read.vertices.astype(np.float64), theirs.vertices)
    np.testing.assert_array_equal(read.faces, np.arange(3 * len(theirs.faces)).reshape(-1, 3))
    assert read.faces.dtype == np.int64 and read.normals is None and read.corner_colour is None
    assert (read.face_group == -1).all() and read.materials == ()
    # Framing's bounds in float64, as from trimesh's float64 points.
    framed = mesh_file.read_file(mesh_source(binary, "t"), bounds=True)
    corners = theirs.vertices
    centre = (corners.min(axis=0) + corners.max(axis=0)) / 2
    assert framed.centre.dtype == np.float64 and np.array_equal(framed.centre, centre)
    assert framed.radius == float(np.sqrt(((corners - centre) ** 2).sum(axis=1).max()))
    # An ASCII STL is trimesh's to read (float64).
    assert read_mesh(ascii_file, "t").vertices.dtype == np.float64


def test_a_binary_stl_prepares_the_geometry_trimesh_s_read_gave(stl_files, monkeypatch):
    """The merge of the float32 corners gives what trimesh's float64 read of the same file gave: the same
    vertices, faces and normals, bit for bit."""
    binary, _ = stl_files
    scene = validate_scene({"objects": [{"shape": "mesh", "path": str(binary)}]}, source=str(binary))
    ours = build_geometry(scene)
    monkeypatch.setattr(stl, "binary_stl_points", lambda handle: None)  # trimesh reads it
    theirs = build_geometry(scene)
    for name in ("vertices", "faces", "face_normals", "corner_normals"):
        a, b = getattr(ours, name), getattr(theirs, name)
        assert a.dtype == b.dtype and np.array_equal(a, b), name


def test_the_read_floor_of_a_binary_stl_is_its_records_and_copies_of_an_ascii_one_its_parse(stl_files):
    binary, ascii_file = stl_files
    size = binary.stat().st_size
    assert mesh_source(binary).read_floor() == size * stl.BINARY_STL_READ_BYTES_PER_BYTE
    assert (mesh_source(ascii_file).read_floor()
            == ascii_file.stat().st_size * TEXT_READ_BYTES_PER_BYTE)
    # A file named .stl whose size does not match its header's count is not taken for a binary STL.
    odd = binary.with_name("odd.stl")
    odd.write_bytes(binary.read_bytes() + b"\0")
    assert mesh_source(odd).read_floor() == odd.stat().st_size * TEXT_READ_BYTES_PER_BYTE


@pytest.mark.parametrize(("claimed", "refused"), [(0, False), (1, True)])
def test_a_header_only_binary_stl_of_84_bytes_is_counted_from_its_header(tmp_path, claimed, refused):
    """A file of exactly 84 bytes (the header and its count, no record) is a binary STL: counting 1 triangle it is
    cut short and refused, counting 0 it holds 0. Catches `size >= 84` taken as `size > 84` (84 bytes then
    weighed as ASCII text: 0 facets, the false count let through)."""
    from raycast_phong.errors import SceneError
    path = tmp_path / "head.stl"
    path.write_bytes(bytes(80) + claimed.to_bytes(4, "little"))
    if refused:
        with pytest.raises(SceneError, match=r"head\.stl.*binary STL.*counts 1 triangles \(134 bytes\).*has 84 bytes"):
            mesh_source(path).triangles()
    else:
        assert mesh_source(path).triangles() == 0


def test_the_read_floor_of_an_stl_that_cannot_be_opened_is_its_size_as_text(tmp_path):
    """The floor reads the 84-byte header to tell binary from ASCII; a path gone since it was sized (OSError) or
    that is no regular file (SceneError) has no header, so it is weighed as ASCII text: size × TEXT_READ_BYTES_PER_BYTE,
    the read then saying what is wrong. Catches either error let out of the floor."""
    assert stl.floor(tmp_path / "gone.stl", 1000, None) == 1000 * TEXT_READ_BYTES_PER_BYTE
    (tmp_path / "folder.stl").mkdir()
    assert stl.floor(tmp_path / "folder.stl", 4096, None) == 4096 * TEXT_READ_BYTES_PER_BYTE


def _plain_ascii(rng, word) -> bytes:
    """An ASCII STL of 40 facets as exporters write it: mixed-case keywords, indentation by spaces or tabs, CRLF
    on some lines, blank lines, `word()` for each coordinate."""
    lines = ["solid Knot exported"]
    for _ in range(40):
        lines += [f"  FACET normal {word()} {word()} {word()}", "\touter loop"]
        lines += [f"      vertex {word()}\t{word()}  {word()}" + ("\r" if rng.random() < 0.2 else "") for _ in range(3)]
        lines += ["    endloop", "  endfacet"] + ([""] if rng.random() < 0.1 else [])
    return "\n".join([*lines, "endsolid Knot exported", ""]).encode()


def _read_both(tmp_path, data: bytes, monkeypatch):
    """The file read as the reader reads it, and by trimesh's reader (stl_ascii.plain_stl barred)."""
    from raycast_phong.io.meshes import stl_ascii
    path = tmp_path / "a.stl"
    path.write_bytes(data)
    ours = read_mesh(path, "t")
    with monkeypatch.context() as patch:
        patch.setattr(stl_ascii, "plain_stl", lambda data: None)
        theirs = read_mesh(path, "t")
    return ours, theirs


@pytest.mark.parametrize("digits", [7, 17], ids=["exact path", "numpy's parse"])
def test_a_plain_ascii_stl_reads_without_trimesh_as_trimesh_read_it(tmp_path, monkeypatch, digits):
    """stl_ascii.plain_stl gives the MeshFile trimesh's reader gave, bit for bit: coordinates of 7 significant
    digits on the exact path, of 17 (Python's repr, as trimesh itself writes) by numpy's parse of the vertex
    lines; and trimesh's reader is not called for it."""
    from test_obj_plain import assert_same_mesh_file

    from raycast_phong.io.meshes import stl_ascii, trimesh_parts
    rng = np.random.default_rng(digits)
    data = _plain_ascii(rng, lambda: f"{rng.normal() * 10 ** int(rng.integers(-2, 3)):.{digits - 1}e}")
    assert stl_ascii.plain_stl(data) is not None
    ours, theirs = _read_both(tmp_path, data, monkeypatch)
    assert_same_mesh_file(ours, theirs)
    monkeypatch.setattr(trimesh_parts, "load", None)
    assert_same_mesh_file(read_mesh(tmp_path / "a.stl", "t"), theirs)


@pytest.mark.parametrize(("change", "why"), [
    (lambda t: t + b"solid second\nendsolid second\n", "a second solid: trimesh's Scene"),
    (lambda t: t.replace(b"      vertex", b"      vertex 1 2 3\n      vertex", 1), "a facet of four vertices"),
    (lambda t: t.replace(b"endloop", b"", 1), "an endloop missing"),
    (lambda t: t.replace(b"vertex ", b"vertex 1 ", 1), "a vertex of four numbers"),
    (lambda t: t.replace(b"vertex 1.5\t", b"vertex ", 1), "a vertex of two numbers"),
    (lambda t: t.replace(b"vertex ", b"vertex nan ", 1).replace(b"nan ", b"nan", 1), "a word that is no decimal"),
    (lambda t: t.replace(b"solid Knot exported", b"solid vertexmodel", 1), "a name trimesh's split cuts at"),
    (lambda t: t.replace(b"outer loop", b"outer loop vertex", 1), "'vertex' on an outer loop line"),
    (lambda t: t.replace(b"endsolid Knot exported", b"endsolid Knot exported\ngarbage", 1), "words past endsolid"),
    (lambda t: b"solid empty\nendsolid empty\n", "no facet"),
])
def test_any_other_ascii_stl_is_left_to_trimesh(change, why):
    """Anything but the plain form goes to trimesh's reader (which reads it, or says what is wrong)."""
    from raycast_phong.io.meshes import stl_ascii
    rng = np.random.default_rng(1)
    data = change(_plain_ascii(rng, lambda: "1.5"))
    assert stl_ascii.plain_stl(data) is None, why


def test_an_ascii_stl_s_scan_is_warmed_and_a_binary_one_s_not(stl_files):
    from raycast_phong.io.meshes import stl_ascii
    binary, ascii_file = stl_files
    for path, expected in ((binary, ()), (ascii_file, (stl_ascii.warm_up,))):
        with path.open("rb") as handle:
            assert stl.warm_up(handle) == expected, path.name


def test_a_binary_stl_read_a_few_records_at_a_time_gives_every_corner(stl_files, monkeypatch):
    """The records are read RECORDS_READ at a time: with 7 (288 triangles: 41 whole reads and a last of 1) the
    corners are trimesh's, in file order; a read that comes back short (the file shrank under the reader) gives
    None, the file then trimesh's to word."""
    import io

    binary, _ = stl_files
    theirs = trimesh.load(binary, process=False).vertices
    monkeypatch.setattr(stl, "RECORDS_READ", 7)
    with binary.open("rb") as handle:
        corners = stl.binary_stl_points(handle)
    assert corners.dtype == np.float32 and corners.shape == theirs.shape
    np.testing.assert_array_equal(corners.astype(np.float64), theirs)

    class Shrinking(io.FileIO):
        """Its third read finds the end of the file."""
        reads = 0

        def readinto(self, buffer):
            self.reads += 1
            return super().readinto(buffer) if self.reads < 4 else 0  # the 84-byte header is read() first

    with Shrinking(binary) as handle:
        assert stl.binary_stl_points(handle) is None and handle.reads == 4


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_framing_radius_is_numpy_s_largest_row_sum_bit_for_bit(dtype, monkeypatch):
    """read._radius, column by column in blocks, gives the bits of sqrt(max(((p − c)²).sum(axis=1))) in float64:
    points far from the origin and of every size, several seeds, blocks of 5 rows and of RADIUS_ROWS; and a point
    whose squares' sum depends on the order they are added in, added (dx² + dy²) + dz² as numpy's row sum adds."""
    for seed in range(8):
        rng = np.random.default_rng(seed)
        points = (rng.standard_normal((20_000, 3)) * 10.0 ** rng.uniform(-3, 4, (20_000, 1))
                  + rng.uniform(-1e4, 1e4, 3)).astype(dtype)
        centre = (points.min(axis=0).astype(np.float64) + points.max(axis=0).astype(np.float64)) / 2
        expected = float(np.sqrt(((points.astype(np.float64) - centre) ** 2).sum(axis=1).max()))
        assert mesh_file._radius(points, centre) == expected, seed
        with monkeypatch.context() as patch:
            patch.setattr(mesh_file, "RADIUS_ROWS", 5)
            assert mesh_file._radius(points, centre) == expected, seed
    # Float32 coordinates' squares add up exactly in float64 almost always; these float64 ones do not: added
    # (dx² + dz²) + dy² their root is one unit in the last place less (2.908607914449797).
    pair = np.array([[0.1, 0.2, 2.9], [-0.1, -0.2, -2.9]], dtype)
    centre = np.zeros(3)
    x, y, z = (float(value) for value in pair[0])
    assert mesh_file._radius(pair, centre) == math.sqrt((x * x + y * y) + z * z)


@pytest.mark.parametrize(("corner", "refused"), [
    ("1e18 0 0", None), ("0 0 -1e18", None),
    ("1.000001e18 0 0", "1 vertex(es) with a coordinate beyond ±1e+18"),
    ("0 0 -1.000001e18", "1 vertex(es) with a coordinate beyond ±1e+18"),
    ("0 nan 0", "1 vertex(es) with NaN or infinite coordinates"),
    ("0 0 -inf", "1 vertex(es) with NaN or infinite coordinates"),
])
def test_a_mesh_file_s_coordinates_are_held_to_the_position_limit_exactly(tmp_path, corner, refused):
    """Every vertex of a face within ±1e18 (POSITION_LIMIT), read off the vertices' bounding box: exactly ±1e18
    is taken on either side, a millionth past it refused, as are NaN and ±inf; a vertex no face uses is not
    checked (the last, at 1e30)."""
    from raycast_phong.errors import SceneError
    path = tmp_path / "edge.obj"
    path.write_text(f"v 0 0 0\nv 1 0 0\nv {corner}\nv 1e30 0 0\nf 1 2 3\n", encoding="utf-8")
    if refused is None:
        assert read_mesh(path, "t").faces.tolist() == [[0, 1, 2]]
    else:
        with pytest.raises(SceneError, match=re.escape(refused)):
            read_mesh(path, "t")
