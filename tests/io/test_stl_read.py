"""A binary STL is read by io/meshes/stl.py itself (float32 corners straight from its records), an ASCII one by
trimesh; both give trimesh's points, and the memory guard's floor follows what each read costs."""

from __future__ import annotations

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
