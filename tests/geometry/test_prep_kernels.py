"""The compiled mesh preparation (geometry/kernels.py, issue 22) gives the numpy code's results bit for bit:
merged vertices, repaired windings, face normals and corner normals, on meshes that take every path
(STL-like repeated points, random flips, open and closed, duplicate faces, a Möbius strip, a high-valence
fan, signed zeros, a closed mesh of no volume)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from prep_reference import compute_corner_normals as reference_corners
from prep_reference import face_normals as reference_face_normals
from prep_reference import merge_duplicate_vertices as reference_merge
from prep_reference import repair_winding as reference_repair

from raycast_phong.geometry import kernels, mesh_repair
from raycast_phong.geometry.mesh_repair import merge_duplicate_vertices, repair_winding
from raycast_phong.geometry.normals import compute_corner_normals, face_normals


def same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a.view(np.uint8), b.view(np.uint8))


def prepare_both(vertices: np.ndarray, faces: np.ndarray) -> None:
    """Every preparation step, new and reference, compared bit for bit (the next step takes the shared result)."""
    merged, remapped = merge_duplicate_vertices(vertices, faces)
    expected = reference_merge(vertices, faces)
    assert same_bits(merged, expected[0]) and np.array_equal(remapped, expected[1])
    repaired, flipped, closed = repair_winding(merged, remapped)
    want = reference_repair(merged, remapped)
    assert (flipped, closed) == want[1:] and np.array_equal(repaired, want[0])
    unit, area = face_normals(merged, repaired)
    unit_ref, area_ref = reference_face_normals(merged, repaired)
    assert same_bits(unit, unit_ref) and same_bits(area, area_ref)
    for weighting in ("mean", "area", "angle"):
        for crease in (180.0, 25.0):
            for dtype in (np.float64, np.float32):
                found = compute_corner_normals(merged, repaired, weighting, crease, dtype, normals=(unit, area))
                assert same_bits(found, reference_corners(merged, repaired, weighting, crease, dtype,
                                                          normals=(unit_ref, area_ref))), (weighting, crease, dtype)


def stl_like(vertices: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    corners = vertices[faces].reshape(-1, 3)
    return corners, np.arange(len(corners)).reshape(-1, 3)


@pytest.mark.parametrize("seed", range(12))
def test_random_meshes_prepare_as_the_numpy_code_did(seed):
    rng = np.random.default_rng(seed)
    mesh = trimesh.creation.icosphere(2) if seed % 3 else trimesh.creation.torus(1.0, 0.3)
    vertices, faces = np.asarray(mesh.vertices) * (-1 if seed % 4 == 0 else 1), np.array(mesh.faces, np.int64)
    flip = rng.random(len(faces)) < (0.0, 0.1, 0.5)[seed % 3]
    faces[flip] = faces[flip, ::-1]
    if seed % 5 == 0:
        faces = faces[: len(faces) // 2]  # open
    if seed % 7 == 0:
        faces = np.concatenate([faces, faces[:3, ::-1]])  # the same triangle twice, wound both ways
    prepare_both(*stl_like(vertices, faces))


def test_two_closed_pieces_wound_apart_are_each_turned_outward():
    one = trimesh.creation.icosphere(1)
    other = trimesh.creation.box()
    vertices = np.concatenate([one.vertices, other.vertices + 3.0])
    faces = np.concatenate([one.faces[:, ::-1], other.faces + len(one.vertices)]).astype(np.int64)
    faces[::7] = faces[::7, ::-1]  # inconsistent, so the graph path runs, and closed: piece volumes decide
    prepare_both(vertices, faces)


def test_a_moebius_strip_is_left_as_it_is():
    n = 24
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False)
    centre = np.column_stack([np.cos(angle), np.sin(angle), np.zeros(n)])
    across = np.column_stack([np.cos(angle / 2) * np.cos(angle), np.cos(angle / 2) * np.sin(angle), np.sin(angle / 2)])
    vertices = np.concatenate([centre - 0.2 * across, centre + 0.2 * across])  # i: inner edge, n + i: outer
    i = np.arange(n)
    j = (i + 1) % n
    # The last quad joins the strip with a half twist: inner i meets outer j.
    jj_in, jj_out = np.where(j == 0, n + j, j), np.where(j == 0, j, n + j)
    faces = np.concatenate([np.column_stack([i, jj_in, jj_out]), np.column_stack([i, jj_out, n + i])]).astype(np.int64)
    faces[::3] = faces[::3, ::-1]  # inconsistent as well, so the orientation runs
    key, edge = np.empty(3 * len(faces), np.int32), np.empty(3 * len(faces), np.int32)
    consistent, closed, flippable, start = mesh_repair.winding_state(faces, len(vertices), key, edge)
    assert not consistent and not closed and flippable
    flip, _, orientable = kernels.orient_pieces(start, key, edge, len(faces))
    assert not orientable.any() and not flip.any()  # one piece that no choice of sides can orient
    prepare_both(vertices, faces)


def test_a_seam_of_three_faces_is_no_flip_s_business_and_skips_the_face_graph(monkeypatch):
    """A face added on an edge of a closed sphere, run the way one of its two faces runs it, makes the winding
    inconsistent, but at an edge of three faces, which no flip mends (as a real scan's seams): the faces come back
    as they are, as the reference leaves them, without the face graph. The control: one face flipped on the
    sphere is mended, through the graph (here refused)."""
    sphere = trimesh.creation.icosphere(2)
    vertices = np.concatenate([sphere.vertices, [[0.0, 0.0, 3.0]]])
    a, b, _ = sphere.faces[0]
    faces = np.concatenate([sphere.faces, [[a, b, len(sphere.vertices)]]]).astype(np.int64)
    key, edge = np.empty(3 * len(faces), np.int32), np.empty(3 * len(faces), np.int32)
    assert mesh_repair.winding_state(faces, len(vertices), key, edge)[:3] == (False, False, False)
    prepare_both(vertices, faces)

    def refused(*_):
        raise AssertionError("the face graph was built")
    monkeypatch.setattr(mesh_repair, "orient_pieces", refused)
    repaired, flipped, closed = repair_winding(vertices, faces)
    assert (flipped, closed) == (0, False) and repaired is faces
    mended = np.array(sphere.faces, np.int64)
    mended[5] = mended[5, ::-1]
    with pytest.raises(AssertionError, match="face graph"):
        repair_winding(np.asarray(sphere.vertices), mended)


def test_a_fan_of_many_faces_sorts_its_large_bucket_as_the_small_ones():
    """A vertex in more than SMALL_BUCKET half-edges takes the merge-sort path of the bucketing."""
    n = 4 * kernels.SMALL_BUCKET
    angle = np.linspace(0, 2 * np.pi, n, endpoint=False)
    vertices = np.concatenate([[[0.0, 0.0, 0.3]], np.column_stack([np.cos(angle), np.sin(angle), np.zeros(n)])])
    rim = np.arange(n) + 1
    faces = np.column_stack([np.zeros(n, np.int64), rim, np.roll(rim, -1)])
    faces[1::3] = faces[1::3, ::-1]
    faces = np.concatenate([faces, faces[:5]])  # duplicates: half-edges traversed twice the same way
    prepare_both(vertices, faces)


def test_a_closed_mesh_of_no_volume_is_decided_by_the_numpy_sum():
    """Two copies of a triangle, wound apart, close a mesh of zero volume: within the rounding bound the
    compiled sign gives way to numpy's sum (0 here: not turned)."""
    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    faces = np.array([[0, 1, 2], [0, 2, 1]], np.int64)
    assert mesh_repair._volume_sign(vertices, faces) == 0.0
    prepare_both(vertices, faces)


def test_signed_zeros_merge_and_nan_file_normals_take_the_sorted_path():
    vertices = np.array([[0.0, 0, 0], [-0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 1, 0], [5, 5, 5]])
    faces = np.array([[0, 2, 3], [1, 2, 4]], np.int64)  # vertex 5 unused: dropped
    merged, remapped = merge_duplicate_vertices(vertices, faces)
    assert len(merged) == 3
    np.testing.assert_array_equal(remapped, [[0, 1, 2], [0, 1, 2]])
    normals = np.array([[0.0, 0, 1], [0, 0, 1], [np.nan, 0, 1], [0, 0, 1], [0, 0, 1], [0, 0, 1]])
    found = merge_duplicate_vertices(vertices, faces, normals)
    expected = reference_merge(vertices, faces, normals)
    assert same_bits(found[0], expected[0]) and np.array_equal(found[1], expected[1])


def test_many_repeated_points_probe_the_hash_table_as_they_merge():
    """A few hundred distinct points repeated thousands of times in random order: long probe runs."""
    rng = np.random.default_rng(5)
    points = rng.integers(-3, 4, (300, 3)).astype(np.float64)
    vertices = points[rng.integers(0, 300, 30_000)]
    faces = rng.integers(0, len(vertices), (10_000, 3))
    merged, remapped = merge_duplicate_vertices(vertices, faces)
    expected = reference_merge(vertices, faces)
    assert same_bits(merged, expected[0]) and np.array_equal(remapped, expected[1])


@pytest.mark.parametrize("seed", range(4))
def test_float32_points_as_a_binary_stl_is_read_merge_as_their_float64_values(seed):
    """A binary STL's corners are read as float32 (io/meshes/stl.binary_stl_points): the merge compares them
    as they are and gives what the float64 path gives those values (the old read), bit for bit, in float64:
    signed zeros joined, the first of each point kept, unused points dropped."""
    rng = np.random.default_rng(seed)
    points = rng.integers(-4, 5, (200, 3)).astype(np.float32) / np.float32(3)  # not exact in float32's bits
    points[rng.random(points.shape) < 0.1] = -0.0
    points[rng.random(points.shape) < 0.1] = 0.0
    vertices = points[rng.integers(0, len(points), 6_000)]
    faces = rng.integers(0, len(vertices) - 100, (2_000, 3))  # the last 100 rows: unused
    merged, remapped = merge_duplicate_vertices(vertices, faces)
    expected = reference_merge(vertices.astype(np.float64), faces)
    assert same_bits(merged, expected[0]) and np.array_equal(remapped, expected[1])
    everything = np.arange(len(vertices)).reshape(-1, 3)  # every row used, nothing to merge: float64 still
    distinct = np.unique(points[np.any(points != 0, axis=1)], axis=0)[:99].astype(np.float32)
    merged, remapped = merge_duplicate_vertices(distinct, everything[:33])
    assert merged.dtype == np.float64 and np.array_equal(merged, distinct.astype(np.float64))
