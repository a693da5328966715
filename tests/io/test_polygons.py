"""One rule for polygons in every reader (io/meshes/polygons.py): a concave polygon is cut by ear clipping, not
as a fan that fills its notch (Geomview's OFF: "The polygons may be concave"; pmp-library's L.off was drawn
half filled). The L-shaped hexagon below, written in each format from its specification and started at each of
its six corners: its triangles must be wound as the polygon (a fan from any corner but the reflex one makes one
turn the other way) and cover exactly its area, 3."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from raycast_phong.io.meshes.source import mesh_source

L = [(0, 0, 0), (2, 0, 0), (2, 2, 0), (1, 2, 0), (1, 1, 0), (0, 1, 0)]  # counter-clockwise about +z; corner 4 reflex
AREA = 3.0
TRIANGLE = [(3, 0, 0), (4, 0, 0), (3, 1, 0)]  # beside it, in the uneven files: a PLY of mixed list lengths


def off_text(path: Path, start: int) -> None:
    corners = [(start + k) % 6 for k in range(6)]
    lines = ["OFF", "6 1 0", *(" ".join(map(str, p)) for p in L), "6 " + " ".join(map(str, corners))]
    path.write_text("\n".join(lines) + "\n")


def off_binary(path: Path, start: int, big: bool) -> None:
    """Geomview's big-endian form (a colour count after each face) or pmp-library's little-endian one (none)."""
    end = ">" if big else "<"
    corners = [(start + k) % 6 for k in range(6)]
    body = struct.pack(end + "3i", 6, 1, 0) + b"".join(struct.pack(end + "3f", *p) for p in L)
    body += struct.pack(end + "7i", 6, *corners) + (struct.pack(end + "i", 0) if big else b"")
    path.write_bytes(b"OFF BINARY\n" + body)


def ply_binary(path: Path, start: int, big: bool, uneven: bool) -> None:
    end = ">" if big else "<"
    points = L + (TRIANGLE if uneven else [])
    faces = [[(start + k) % 6 for k in range(6)]] + ([[6, 7, 8]] if uneven else [])
    head = (f"ply\nformat binary_{'big' if big else 'little'}_endian 1.0\nelement vertex {len(points)}\n"
            "property float x\nproperty float y\nproperty float z\n"
            f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n").encode()
    body = b"".join(struct.pack(end + "3f", *p) for p in points)
    body += b"".join(struct.pack(f"{end}B{len(f)}i", len(f), *f) for f in faces)
    path.write_bytes(head + body)


def ply_ascii(path: Path, start: int) -> None:
    """With the triangle beside it and a colour per face (scalars after the polygon list, kept per triangle)."""
    points = L + TRIANGLE
    faces = [[(start + k) % 6 for k in range(6)], [6, 7, 8]]
    head = (f"ply\nformat ascii 1.0\nelement vertex {len(points)}\nproperty float x\nproperty float y\n"
            "property float z\nelement face 2\nproperty list uchar int vertex_indices\nproperty uchar red\n"
            "property uchar green\nproperty uchar blue\nend_header\n")
    rows = [" ".join(map(str, p)) for p in points]
    rows += [f"{len(f)} {' '.join(map(str, f))} {colour}" for f, colour in zip(faces, ("255 0 0", "0 0 255"))]
    path.write_text(head + "\n".join(rows) + "\n")


def obj(path: Path, start: int) -> None:
    corners = [(start + k) % 6 + 1 for k in range(6)]
    path.write_text("".join(f"v {x} {y} {z}\n" for x, y, z in L) + "f " + " ".join(map(str, corners)) + "\n")


WRITERS = {
    "off": ("m.off", off_text),
    "off-binary-geomview": ("m.off", lambda path, start: off_binary(path, start, True)),
    "off-binary-little-endian": ("m.off", lambda path, start: off_binary(path, start, False)),
    "ply-even-little": ("m.ply", lambda path, start: ply_binary(path, start, False, False)),
    "ply-even-big": ("m.ply", lambda path, start: ply_binary(path, start, True, False)),
    "ply-uneven-little": ("m.ply", lambda path, start: ply_binary(path, start, False, True)),
    "ply-uneven-big": ("m.ply", lambda path, start: ply_binary(path, start, True, True)),
    "ply-ascii": ("m.ply", ply_ascii),
    "obj": ("m.obj", obj),
}


@pytest.mark.parametrize("start", range(6))
@pytest.mark.parametrize("form", WRITERS)
def test_a_concave_polygon_is_cut_into_triangles_wound_as_it_covering_its_area(tmp_path, form, start):
    name, write = WRITERS[form]
    write(tmp_path / name, start)
    found = mesh_source(tmp_path / name).read()
    corners = found.vertices[found.faces]
    lying = np.linalg.norm(corners[:, :, :2] - [3.5, 0.5], axis=2).max(axis=1) > 1  # the L's, not the triangle's
    assert lying.sum() == 4  # n − 2: ear clipping cuts as many triangles as a fan
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])[lying]
    assert (normal[:, 2] > 0).all(), normal  # every triangle turns as the polygon does
    assert np.isclose(0.5 * normal[:, 2].sum(), AREA)
    if form == "ply-ascii":  # its face colours: red for the L, blue for the triangle, on every triangle
        colour = found.corner_colour
        assert colour is not None and np.allclose(colour[lying], (1, 0, 0)) and np.allclose(colour[~lying], (0, 0, 1))


def test_convex_polygons_keep_their_fans(tmp_path):
    """A file without concave polygons reads to the fan it always had (0, j+1, j+2), from its first corner."""
    square = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0.5, -0.5, 0)]
    path = tmp_path / "m.off"
    path.write_text("OFF\n5 1 0\n" + "".join(" ".join(map(str, p)) + "\n" for p in square) + "5 4 1 2 3 0\n")
    assert mesh_source(path).read().faces.tolist() == [[4, 1, 2], [4, 2, 3], [4, 3, 0]]


@pytest.mark.parametrize("big", [True, False])
def test_binary_off_counts_are_weighed_in_the_byte_order_the_reader_reads(tmp_path, big):
    """The memory check weighs the counts the reader will read: pmp-library's little-endian file was weighed
    as 67M triangles (the counts read big-endian) and refused as needing 51 GB in a 135-byte file."""
    off_binary(tmp_path / "m.off", 0, big)
    path = tmp_path / "m.off"
    with path.open("rb") as handle:
        assert mesh_source(path).format.count(handle, path.stat().st_size, None) == 4  # weigh(1 face, 6 vertices)


@pytest.mark.parametrize("data", [
    b"OFF\n90000000 90000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",          # text counts far beyond 60 bytes
    b"OFF BINARY\n" + struct.pack(">3i", 90_000_000, 90_000_000, 0) + bytes(40),  # neither byte order fits
])
def test_counts_a_small_file_cannot_hold_are_called_cut_short_not_weighed(tmp_path, data):
    """The memory check weighed what a header claimed: a 216 kB OFF was refused as 'needing 1.49 TB ...
    decimate it'. Counts beyond the file's size leave the weight to the size, and the reader says what is wrong."""
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    (tmp_path / "m.off").write_bytes(data)
    result = CliRunner().invoke(app, ["render", str(tmp_path / "m.off"), "-q", "-o", str(tmp_path / "m.png"),
                                      "--max-memory", "2G"])
    assert result.exit_code == 2 and "cut short" in result.output and "memory" not in result.output, result.output


def test_a_concave_quad_in_an_even_binary_ply_is_cut_not_fanned(tmp_path):
    """A dart, (4,0) (1,1) (0,4) (0,0), concave at its second corner, as a binary PLY's one face (lists all of 4):
    quads are tested too, so its two triangles both turn as it does and cover its area, 4. The fan from its first
    corner would give (4,0) (1,1) (0,4), wound the other way. Catches the concavity test starting at 5 corners."""
    dart = [(4, 0, 0), (1, 1, 0), (0, 4, 0), (0, 0, 0)]
    head = (b"ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
            b"property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n")
    (tmp_path / "d.ply").write_bytes(head + struct.pack("<12f", *(c for p in dart for c in p))
                                     + struct.pack("<B4i", 4, 0, 1, 2, 3))
    found = mesh_source(tmp_path / "d.ply").read()
    corners = found.vertices[found.faces]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert len(found.faces) == 2 and (normal[:, 2] > 0).all(), found.faces
    assert np.isclose(0.5 * normal[:, 2].sum(), 4.0)


def test_an_ascii_ply_s_last_polygon_without_a_line_feed_is_cut(tmp_path):
    """An ASCII PLY whose one face line, the L, ends the file without a line feed: the file's line feeds are then
    exactly its vertex lines', and the face is still found and ear-clipped (4 triangles wound as the L, area 3),
    not left to trimesh's fan."""
    head = ("ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 1\nproperty list uchar int vertex_indices\nend_header\n")
    rows = [" ".join(map(str, p)) for p in L]
    (tmp_path / "m.ply").write_text(head + "\n".join(rows) + "\n6 0 1 2 3 4 5")  # its fan from corner 0 folds
    found = mesh_source(tmp_path / "m.ply").read()
    corners = found.vertices[found.faces]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert len(found.faces) == 4 and (normal[:, 2] > 0).all(), found.faces
    assert np.isclose(0.5 * normal[:, 2].sum(), AREA)


def test_an_ascii_ply_s_face_of_no_corners_leaves_its_concave_polygon_cut(tmp_path):
    """An ASCII PLY whose face lines are `0` (a polygon of no corners) and the L: the empty face is no reason to
    leave the file to trimesh's fans, so the L is still ear-clipped (4 triangles wound as it, area 3). Catches
    a count of 0 corners taken as a bad face line (`< 0` made `<= 0`)."""
    head = ("ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 2\nproperty list uchar int vertex_indices\nend_header\n")
    rows = [" ".join(map(str, p)) for p in L]
    (tmp_path / "m.ply").write_text(head + "\n".join(rows) + "\n0\n6 0 1 2 3 4 5\n")
    found = mesh_source(tmp_path / "m.ply").read()
    corners = found.vertices[found.faces]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert len(found.faces) == 4 and (normal[:, 2] > 0).all(), found.faces
    assert np.isclose(0.5 * normal[:, 2].sum(), AREA)


@pytest.mark.parametrize("start", range(6))
def test_an_ascii_ply_s_cut_polygons_are_counted_in_its_rewritten_header(tmp_path, start):
    """ply_lists.ascii_cut writes each concave polygon's triangles as lines of their own: the rewritten header's
    face count must be the face lines it now holds (the PLY format counts an element's rows), one more per
    triangle past the first of each cut polygon, not per corner."""
    from raycast_phong.io.meshes import ply_lists
    ply_ascii(tmp_path / "m.ply", start)
    data = (tmp_path / "m.ply").read_bytes()
    cut = ply_lists.ascii_cut(data, ply_lists.header(data))
    vertex, face = ply_lists.header(cut).elements[:2]
    lines = [line for line in cut[ply_lists.header(cut).body:].split(b"\n") if line.strip()]
    assert face.rows == len(lines) - vertex.rows == 5  # the L's 4 triangles and the triangle
