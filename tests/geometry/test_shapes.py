"""The numpy shapes (shapes.py) build trimesh.creation's triangles, closed and wound outward.

Two meshes are compared as sets of oriented triangles over matched vertices: each vertex of one lies within
a tolerance of exactly one vertex of the other, and the triangles, each read from its smallest vertex on in
its own cyclic order, are the same rows. A flipped triangle reads (a, c, b), so it does not match.
"""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from raycast_phong import shapes

EPS = np.finfo(np.float64).eps
# Revolved shapes and the box: the same products and sums as trimesh's on the same inputs; the tolerance
# allows cos/sin a few ulps apart on another CPU's SIMD path, and the poles, where trimesh keeps sin π ≈ 1.2e-16.
ROUNDING = 4 * EPS
CELL = 1e-6  # matching grid: far above the tolerances, far below the closest vertices here (≥ 1e-3 apart)


def icosphere_tolerance(subdivisions: int) -> float:
    """Each level, both builders take a midpoint (≤ 1 ulp), divide by a norm (≤ 3 ulps; trimesh adds ≤ 3
    more re-projecting every vertex), and the parents' errors carry over, stretched at most 1/cos 31.7° ≈ 1.18
    (half the icosahedron's edge angle): ≤ 12 ulps per level, plus the icosahedron's own projection."""
    return 12 * EPS * (subdivisions + 1)


def trimesh_mesh(mesh: trimesh.Trimesh) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(mesh.vertices, np.float64), np.asarray(mesh.faces, np.int64)


def same_triangles(mine, theirs, tolerance: float) -> None:
    """Assert the two (vertices, faces) are the same oriented triangles over vertices within `tolerance`."""
    (v1, f1), (v2, f2) = mine, theirs
    assert len(v1) == len(v2) and len(f1) == len(f2)
    both = np.concatenate([v1, v2]) / CELL
    # Shift the grid until no coordinate lies within the tolerance of a cell edge: partners then share a cell.
    margin = 2 * tolerance / CELL
    for shift in np.linspace(0.0, 1.0, 8, endpoint=False):
        fraction = (both + shift) % 1.0
        if ((fraction > margin) & (fraction < 1 - margin)).all():
            break
    else:
        pytest.fail("no grid shift keeps every coordinate off a cell edge")
    _, ids = np.unique(np.floor(both + shift).astype(np.int64), axis=0, return_inverse=True)
    ids = ids.ravel()
    mine_ids, their_ids = ids[:len(v1)], ids[len(v1):]
    assert len(np.unique(mine_ids)) == len(v1) and len(np.unique(their_ids)) == len(v2), "vertices do not pair up"
    position = np.empty((ids.max() + 1, 3))
    position[mine_ids] = v1
    assert np.abs(position[their_ids] - v2).max() <= tolerance

    def oriented(faces: np.ndarray) -> np.ndarray:
        triangles = ids_of[faces]
        first = np.argmin(triangles, axis=1)[:, None]
        triangles = np.take_along_axis(triangles, (first + np.arange(3)) % 3, axis=1)  # keeps the cyclic order
        return triangles[np.lexsort(triangles.T[::-1])]

    ids_of = mine_ids
    mine_triangles = oriented(f1)
    ids_of = their_ids
    np.testing.assert_array_equal(mine_triangles, oriented(f2))


@pytest.mark.parametrize("subdivisions", [0, 1, 2, 6])
def test_icosphere_is_trimeshs(subdivisions):
    same_triangles(shapes.icosphere(subdivisions), trimesh_mesh(trimesh.creation.icosphere(subdivisions)),
                   icosphere_tolerance(subdivisions))


@pytest.mark.parametrize("segments", [(3, 3), (4, 5), (32, 16), (7, 64)])
def test_uv_sphere_is_trimeshs(segments):
    same_triangles(shapes.uv_sphere(segments), trimesh_mesh(trimesh.creation.uv_sphere(1.0, list(segments))),
                   ROUNDING)


@pytest.mark.parametrize("extents", [(1.0, 1.0, 1.0), (1.0, 0.5, 0.25), (0.3, 1.0, 0.7)])
def test_box_is_trimeshs(extents):
    same_triangles(shapes.box(extents), trimesh_mesh(trimesh.creation.box(extents=extents)), ROUNDING)


@pytest.mark.parametrize(("radius", "height", "sections"), [(1.0, 1.0, 3), (0.5, 1.0, 32), (1.0, 0.01, 64)])
def test_cylinder_is_trimeshs(radius, height, sections):
    mesh = trimesh.creation.cylinder(radius=radius, height=height, sections=sections)
    same_triangles(shapes.cylinder(radius, height, sections), trimesh_mesh(mesh), ROUNDING)


@pytest.mark.parametrize(("major", "minor", "sections"), [(1.0, 0.25, (32, 16)), (1.0, 0.5, (3, 3)),
                                                         (0.3, 1.0, (7, 5))])
def test_torus_is_trimeshs(major, minor, sections):
    mesh = trimesh.creation.torus(major, minor, *sections)
    same_triangles(shapes.torus(major, minor, *sections), trimesh_mesh(mesh), ROUNDING)


SHAPES = {  # name: (mesh builder, its enclosed volume, and how close the mesh must come to it)
    "icosphere 0": (lambda: shapes.icosphere(0), 4 / 3 * np.pi, 0.4),
    "icosphere 4": (lambda: shapes.icosphere(4), 4 / 3 * np.pi, 0.01),
    "uv sphere 3×3": (lambda: shapes.uv_sphere((3, 3)), 4 / 3 * np.pi, 0.7),
    # 1.6M triangles, and trimesh drops those of area below 1e-8 near the poles, leaving holes
    "uv sphere 4096×96": (lambda: shapes.uv_sphere((4096, 96)), 4 / 3 * np.pi, 1e-3),
    "box": (lambda: shapes.box((1.0, 0.5, 0.25)), 0.125, 1e-12),
    "cylinder 3": (lambda: shapes.cylinder(1.0, 0.5, 3), 0.5 * 3 * np.sin(2 * np.pi / 3) / 2, 1e-12),  # a prism
    "cylinder 64": (lambda: shapes.cylinder(0.5, 1.0, 64), np.pi * 0.25, 0.01),
    "torus": (lambda: shapes.torus(1.0, 0.25, 64, 32), 2 * np.pi ** 2 * 0.25 ** 2, 0.01),
}


@pytest.mark.parametrize("name", list(SHAPES))
def test_shapes_are_closed_and_wound_outward(name):
    """Every directed edge has exactly one partner running back (closed, consistently wound) and the
    signed volume Σ det[a, b, c] / 6 is the shape's, positive: it turns negative if the winding flips."""
    build, volume, relative = SHAPES[name]
    vertices, faces = build()
    start, end = faces.ravel(), faces[:, [1, 2, 0]].ravel()
    forward = np.unique(start * len(vertices) + end, return_counts=True)
    assert (forward[1] == 1).all()
    np.testing.assert_array_equal(forward[0], np.sort(end * len(vertices) + start))
    signed = np.linalg.det(vertices[faces]).sum() / 6
    assert abs(signed / volume - 1) <= relative, signed

