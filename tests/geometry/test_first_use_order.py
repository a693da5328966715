"""A large indexed mesh file's vertices numbered in the order its faces first use them (mesh_repair.
number_by_first_use, templates.FIRST_USE_FACES): the same surface corner for corner, the same normals bit for bit
and the same image; only where each vertex sits in memory changes."""

from __future__ import annotations

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong import shapes
from raycast_phong.geometry import templates
from raycast_phong.geometry.build import build_geometry
from raycast_phong.geometry.mesh_repair import number_by_first_use


def shuffled_sphere(seed: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """An icosphere's 5,120 faces, its points moved at random and stored in a random order (as a file whose vertex
    order wanders from its faces')."""
    vertices, faces = shapes.icosphere(4)
    rng = np.random.default_rng(seed)
    vertices = vertices * (1 + 0.03 * rng.standard_normal((len(vertices), 1)))
    order = rng.permutation(len(vertices))  # new position of each point
    moved = np.empty_like(vertices)
    moved[order] = vertices
    return moved, order[np.asarray(faces)]


def numbered_by_first_use(faces: np.ndarray) -> bool:
    """Whether each vertex number first appears (in corner order) right after the ones before it: 0, 1, 2, ..."""
    flat = faces.ravel()
    numbers, at = np.unique(flat, return_index=True)
    return np.array_equal(numbers, np.arange(len(numbers))) and bool((np.diff(at) > 0).all())


def test_first_use_numbering_keeps_every_corner_and_drops_unused_points():
    vertices, faces = shuffled_sphere()
    vertices = np.concatenate([vertices, [[9.0, 9.0, 9.0]]])  # a point no face uses
    assert not numbered_by_first_use(faces)
    renumbered_vertices, renumbered = number_by_first_use(vertices, faces)
    assert numbered_by_first_use(renumbered) and renumbered.dtype == np.int64
    assert len(renumbered_vertices) == len(vertices) - 1
    np.testing.assert_array_equal(renumbered_vertices[renumbered], vertices[faces])  # every corner, same bits


@pytest.mark.parametrize("crease", [180, 30])
def test_a_large_indexed_mesh_is_numbered_by_first_use_and_shades_the_same(monkeypatch, crease):
    vertices, faces = shuffled_sphere()
    scene = rp.mesh_scene(vertices, faces, overrides=["render.width=48", "render.height=36",
                                                      f"objects.0.crease_angle={crease}"])
    as_filed = build_geometry(scene, normal_dtype=np.float32)
    assert not numbered_by_first_use(as_filed.faces)  # 5,120 faces: below FIRST_USE_FACES, the file's order
    kept = rp.render(scene).image
    monkeypatch.setattr(templates, "FIRST_USE_FACES", 1000)
    renumbered = build_geometry(scene, normal_dtype=np.float32)
    assert numbered_by_first_use(renumbered.faces)
    np.testing.assert_array_equal(renumbered.vertices[renumbered.faces], as_filed.vertices[as_filed.faces])
    np.testing.assert_array_equal(renumbered.face_normals, as_filed.face_normals)
    np.testing.assert_array_equal(renumbered.corner_normals, as_filed.corner_normals)
    np.testing.assert_array_equal(rp.render(scene).image, kept)


def test_a_merged_mesh_keeps_the_merges_numbering(monkeypatch):
    """Points the merge joined (an STL's corners): numbered by the merge in file order, which for corners stored
    face by face is already the order of first use; no second pass."""
    vertices, faces = shuffled_sphere()
    corners = vertices[faces].reshape(-1, 3)
    monkeypatch.setattr(templates, "FIRST_USE_FACES", 1000)
    monkeypatch.setattr(templates, "number_by_first_use", lambda *_: pytest.fail("renumbered a merged mesh"))
    geometry = build_geometry(rp.mesh_scene(corners, np.arange(len(corners)).reshape(-1, 3)), normal_dtype=np.float32)
    assert numbered_by_first_use(geometry.faces)
