"""Mesh preparation at scale (issue 11): the duplicate-vertex merge, the winding check and repair, the
creased-normal shortcut and float32 corner normals; each checked against an invariant or a hand-made mesh."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from prep_reference import _creased_sums, _creased_vertices

import raycast_phong as rp
from raycast_phong import shapes
from raycast_phong.geometry import kernels, mesh_repair
from raycast_phong.geometry import normals as normal_rules
from raycast_phong.geometry.build import build_geometry
from raycast_phong.geometry.mesh_repair import merge_duplicate_vertices, repair_winding
from raycast_phong.geometry.normals import compute_corner_normals, face_normals


@pytest.fixture
def rng():
    return np.random.default_rng(11)


def split_corners(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    """The mesh as an STL stores it: every face with its own three vertices."""
    vertices = mesh.vertices[mesh.faces].reshape(-1, 3)
    return vertices, np.arange(len(vertices)).reshape(-1, 3)


def half_edges_unique(faces: np.ndarray) -> bool:
    """Consistent winding: no directed edge is used twice."""
    directed = np.stack([faces, np.roll(faces, -1, axis=1)], axis=2).reshape(-1, 2)
    return len(np.unique(directed, axis=0)) == len(directed)


def volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    return trimesh.Trimesh(vertices, faces, process=False).volume


# ---------------------------------------------------------------- merging duplicate vertices


def test_the_merge_joins_every_repeated_point_and_keeps_the_surface():
    sphere = trimesh.creation.icosphere(subdivisions=3)
    vertices, faces = split_corners(sphere)
    merged, remapped = merge_duplicate_vertices(vertices, faces)
    assert len(merged) == len(sphere.vertices)                    # 642 points, each once
    np.testing.assert_array_equal(merged[remapped], vertices[faces])  # every face still has its corners
    assert len(np.unique(merged, axis=0)) == len(merged)


def test_the_merge_drops_unused_vertices_joins_signed_zeros_and_keeps_the_file_order():
    vertices = np.array([[5, 5, 5], [0.0, 0, 0], [1, 0, 0], [-0.0, 0, 0], [0, 1, 0], [1, 0, 0]])
    faces = np.array([[1, 2, 4], [3, 4, 5]])  # vertex 0 unused; 3 is 1 (−0 = +0), 5 is 2
    merged, remapped = merge_duplicate_vertices(vertices, faces)
    np.testing.assert_array_equal(merged, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(remapped, [[0, 1, 2], [0, 2, 1]])


def test_different_file_normals_keep_a_point_apart_and_equal_ones_do_not():
    """As trimesh's process(): a hard edge the file draws (two normals at one point) stays hard."""
    vertices = np.array([[0.0, 0, 0], [0, 0, 0], [1, 0, 0], [1, 0, 0]])
    faces = np.array([[0, 2, 3], [1, 2, 3]])
    normals = np.array([[0, 0, 1], [0, 1, 0], [0, 0, 1], [0, 0, 1.001]])  # 2 and 3 agree to 0.01
    merged, remapped = merge_duplicate_vertices(vertices, faces, normals)
    assert len(merged) == 3
    np.testing.assert_array_equal(remapped, [[0, 2, 2], [1, 2, 2]])  # kept in file order: 0, 1, 2(=3)


def test_colliding_hashes_are_told_apart_by_the_exact_comparison():
    """The merge's hash table nearly full (every slot but one taken: long probe runs through other points'
    slots): the row-by-row comparison must still tell the points apart and merge only equal ones."""
    sphere = trimesh.creation.icosphere(subdivisions=1)
    vertices, _ = split_corners(sphere)
    distinct = len(sphere.vertices)
    table = np.full(1 << distinct.bit_length(), -1, np.int64)  # > distinct slots, < 2 × distinct
    new_of_old, first = np.empty(len(vertices), np.int64), np.empty(len(vertices), np.int64)
    first = first[:kernels.merge_rows(vertices, vertices.view(np.uint64), np.ones(len(vertices), bool), table,
                                      new_of_old, first)]
    assert len(first) == distinct and (table >= 0).sum() == distinct
    np.testing.assert_array_equal(vertices[first][new_of_old], vertices)


def test_a_mesh_file_renders_as_before_the_merge_replaced_trimesh_process(tmp_path):
    """An STL (every point repeated per face) and the same mesh as a PLY give the same image: the
    merge restores the shared vertices the vertex-normal mean needs."""
    knot = trimesh.creation.torus(1.0, 0.35, major_sections=24, minor_sections=12)
    knot.export(tmp_path / "knot.ply")
    trimesh.Trimesh(*split_corners(knot), process=False).export(tmp_path / "knot.stl")

    def image(name: str) -> np.ndarray:
        scene = rp.validate_scene({"render": {"width": 48, "height": 36}, "camera": {"position": [0, 3, 4]},
                                   "lights": [{"position": [3, 4, 5]}],
                                   "objects": [{"shape": "mesh", "path": name}]}, folder=tmp_path)
        return rp.render(scene).image
    np.testing.assert_array_equal(image("knot.stl"), image("knot.ply"))


# ---------------------------------------------------------------- winding


def test_a_consistent_mesh_costs_no_copy_and_reports_nothing():
    sphere = trimesh.creation.icosphere(subdivisions=2)
    faces = np.asarray(sphere.faces)
    repaired, flipped, closed = repair_winding(sphere.vertices, faces)
    assert repaired is faces and flipped == 0 and closed


@pytest.mark.parametrize("inside_out", [False, True])
def test_randomly_flipped_faces_of_a_closed_mesh_come_back_consistent_and_outward(rng, inside_out):
    sphere = trimesh.creation.icosphere(subdivisions=3)
    faces = sphere.faces[:, ::-1].copy() if inside_out else sphere.faces.copy()
    flip = rng.random(len(faces)) < 0.3
    faces[flip] = faces[flip, ::-1]
    repaired, flipped, closed = repair_winding(sphere.vertices, faces)
    assert closed and half_edges_unique(repaired) and volume(sphere.vertices, repaired) > 0
    assert flipped == (len(faces) - flip.sum() if inside_out else flip.sum())


def test_an_inside_out_consistent_closed_mesh_is_turned_outward():
    sphere = trimesh.creation.icosphere(subdivisions=2)
    repaired, flipped, closed = repair_winding(sphere.vertices, sphere.faces[:, ::-1])
    assert (flipped, closed) == (len(sphere.faces), True) and volume(sphere.vertices, repaired) > 0


def test_each_closed_piece_is_turned_outward_by_its_own_volume():
    """A large sphere and a small inside-out one with some faces flipped: the small one's volume is
    outweighed by the large one's, so a whole-mesh volume (trimesh's fix_inversion) would leave it inward."""
    large = trimesh.creation.icosphere(subdivisions=2, radius=3.0)
    small = trimesh.creation.icosphere(subdivisions=2, radius=0.5)
    small_faces = small.faces[:, ::-1] + len(large.vertices)
    small_faces[:7] = small_faces[:7, ::-1]
    vertices = np.vstack([large.vertices, small.vertices + np.array([10.0, 0, 0])])
    faces = np.vstack([large.faces, small_faces])
    repaired, flipped, closed = repair_winding(vertices, faces)
    assert closed and flipped == len(small.faces) - 7
    assert volume(vertices, repaired[len(large.faces):]) > 0 and volume(vertices, repaired[:len(large.faces)]) > 0


def test_an_open_mesh_keeps_the_orientation_most_of_its_faces_have(rng):
    vertices, faces = shapes.plane_mesh((2.0, 2.0), (12, 12))
    flip = rng.random(len(faces)) < 0.2
    faces = faces.copy()
    faces[flip] = faces[flip, ::-1]
    repaired, flipped, closed = repair_winding(vertices, faces)
    unit, _ = face_normals(vertices, repaired)
    assert not closed and flipped == flip.sum() and (unit[:, 1] > 0.999).all()  # all up again


def test_a_moebius_strip_cannot_be_oriented_and_is_left_as_it_is():
    """Non-orientable: no choice of windings is consistent. The repair must end, and change nothing."""
    n = 12
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    rims = [np.column_stack([(1 + s * np.cos(t / 2)) * np.cos(t), (1 + s * np.cos(t / 2)) * np.sin(t),
                             s * np.sin(t / 2)]) for s in (-0.3, 0.3)]
    vertices = np.vstack(rims)  # a_i = i on one rim, b_i = n + i on the other
    a, b = np.arange(n), n + np.arange(n)
    # After a full turn the strip comes back upside down: a's next is b_0, b's next is a_0.
    a_next, b_next = np.r_[a[1:], b[0]], np.r_[b[1:], a[0]]
    faces = np.vstack([np.column_stack([a, a_next, b_next]), np.column_stack([a, b_next, b])])
    repaired, flipped, closed = repair_winding(vertices, faces)
    assert not closed and flipped == 0
    np.testing.assert_array_equal(repaired, faces)


# ---------------------------------------------------------------- normals


def bumpy_sphere() -> trimesh.Trimesh:
    sphere = trimesh.creation.icosphere(subdivisions=4)  # ≈ 4.8° between neighbouring faces
    bumps = 1 + 0.15 * np.sign(np.sin(7 * sphere.vertices[:, 0]))  # steps: real creases between smooth areas
    return trimesh.Trimesh(sphere.vertices * bumps[:, None], sphere.faces, process=False)


@pytest.mark.parametrize("weighting", ["mean", "area", "angle"])
@pytest.mark.parametrize("crease_angle", [20, 45, 80])
def test_the_creased_shortcut_equals_the_pairwise_rule_bit_for_bit(weighting, crease_angle):
    """Vertices far from any crease skip the (corner, neighbour) pairs; the result must be what every
    corner gets from the pairwise rule."""
    mesh = bumpy_sphere()
    vertices, faces = mesh.vertices, np.asarray(mesh.faces)
    unit, doubled = face_normals(vertices, faces)
    weights = {"mean": np.ones(faces.shape), "area": np.repeat(doubled[:, None], 3, axis=1),
               "angle": normal_rules.corner_angles(vertices, faces)}[weighting]
    reach = weights * np.linalg.norm(unit, axis=1)[:, None]
    contribution = np.concatenate([weights[:, :, None] * unit[:, None, :], reach[:, :, None]], axis=2).reshape(-1, 4)
    sums = _creased_sums(faces.ravel(), contribution, np.repeat(unit, 3, axis=0), crease_angle)
    pairwise = normal_rules._normalise_or(sums[:, :3], np.repeat(unit, 3, axis=0), sums[:, 3:]).reshape(-1, 3, 3)
    found = compute_corner_normals(vertices, faces, weighting, crease_angle)
    np.testing.assert_array_equal(found, pairwise)
    # The mesh exercises both paths: some vertices take the pairwise rule, some the shortcut.
    vertex_normal = np.zeros((len(vertices), 3))
    vertex_normal[faces.ravel()] = compute_corner_normals(vertices, faces, weighting).reshape(-1, 3)
    split = _creased_vertices(unit, faces.ravel(), vertex_normal, np.zeros(len(vertices), bool), crease_angle)
    assert 0 < split.sum() < len(vertices)


def test_float32_corner_normals_are_the_float64_ones_rounded():
    scene = rp.validate_scene({"objects": [{"shape": "torus"}, {"shape": "box", "crease_angle": 30}]})
    wide = build_geometry(scene, normal_dtype=np.float64)
    narrow = build_geometry(scene, normal_dtype=np.float32)
    assert narrow.corner_normals.dtype == np.float32
    np.testing.assert_array_equal(narrow.corner_normals, wide.corner_normals.astype(np.float32))


def test_file_normals_per_vertex_equal_the_per_corner_rule_and_fall_back_to_the_face():
    """Normalised per vertex then gathered, bit for bit what normalising every corner gives; a vertex whose
    file normal is zero (no direction) takes each face's own normal."""
    sphere = trimesh.creation.icosphere(subdivisions=2)
    vertices, faces = sphere.vertices, np.asarray(sphere.faces)
    normals = sphere.vertices * np.linspace(0.5, 2.0, len(vertices))[:, None]  # not unit: must be normalised
    normals[::5] = 0.0
    unit, _ = face_normals(vertices, faces)
    found = normal_rules.file_corner_normals(normals, faces, unit)
    per_corner = normal_rules._normalise_or(normals[faces], np.repeat(unit[:, None, :], 3, axis=1))
    np.testing.assert_array_equal(found, per_corner)
    np.testing.assert_array_equal(found[faces == 0], unit[(faces == 0).any(axis=1)])  # vertex 0 has no normal
    assert normal_rules.file_corner_normals(normals, faces, unit, np.float32).dtype == np.float32


@pytest.mark.parametrize("chunk", [1, 7, 100])
def test_chunked_steps_give_the_one_chunk_answers_at_any_chunk_size(monkeypatch, chunk):
    """Signed volumes run in chunks (FACE_CHUNK = 2^18 faces) to bound their temporaries: larger than any mesh
    here, so with tiny chunks every boundary is crossed. The normals (compiled passes) must not change; a volume
    is one sum over the faces, regrouped by the chunks: within F·ε·F, since each of its F additions errs by at
    most ε times a running sum of at most F terms of size ≤ 1 (the unit sphere). A chunk that skipped or
    repeated faces is off by a whole term."""
    sphere = trimesh.creation.icosphere(subdivisions=3)  # 1,280 faces; adjacent normals ~9° apart
    vertices, faces = np.asarray(sphere.vertices), np.asarray(sphere.faces, np.int64)
    piece = np.arange(len(faces)) % 3
    sign = np.where(np.arange(len(faces)) % 5 == 0, -1.0, 1.0)

    def normals():
        return (*face_normals(vertices, faces), compute_corner_normals(vertices, faces, "area", 10.0))

    def volumes():
        return np.concatenate([mesh_repair._signed_volumes(vertices, faces),
                               mesh_repair._signed_volumes(vertices, faces, piece, 3, sign)])
    whole_normals, whole_volumes = normals(), volumes()
    for module, name in ((normal_rules, "FACE_CHUNK"), (mesh_repair, "FACE_CHUNK")):
        monkeypatch.setattr(module, name, chunk)
    for found, expected in zip(normals(), whole_normals):
        np.testing.assert_array_equal(found, expected)
    np.testing.assert_allclose(volumes(), whole_volumes, rtol=0, atol=len(faces) ** 2 * np.finfo(float).eps)


@pytest.mark.parametrize("weighting", ["mean", "area", "angle"])
def test_faces_meeting_at_exactly_the_crease_angle_are_not_split(weighting):
    """docs/scene-format.md: faces meeting at *more than* crease_angle are split. A cube's faces meet at 90°: at
    crease_angle = 90 every corner gathers every face round its vertex (the uncreased normals), at 89.9 every
    corner is its face's normal. Catches the comparison's slack turned the wrong way (a cube at 90 faceted)."""
    cube = trimesh.creation.box()
    vertices, faces = np.asarray(cube.vertices), np.asarray(cube.faces)
    smooth = compute_corner_normals(vertices, faces, weighting, crease_angle=90.0)
    uncreased = compute_corner_normals(vertices, faces, weighting, crease_angle=180.0)
    assert (np.abs(uncreased) > 0.3).all()  # the control: no corner is a face's normal ((0, 0, ±1) and so on)
    np.testing.assert_allclose(smooth, uncreased, rtol=0, atol=1e-12)
    creased = compute_corner_normals(vertices, faces, weighting, crease_angle=89.9)
    unit, _ = face_normals(vertices, faces)
    np.testing.assert_allclose(creased, np.repeat(unit[:, None], 3, axis=1), rtol=0, atol=1e-12)
