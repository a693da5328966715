"""The built-in shapes' texture coordinates (issue 20: a textured sphere is a three-line scene)."""

from __future__ import annotations

import numpy as np

from raycast_phong import shapes
from raycast_phong.shapes import plane_mesh


def test_sphere_uv_is_longitude_and_latitude_without_a_seam_jump():
    vertices, faces = shapes.uv_sphere((16, 16))
    uv = shapes.sphere_uv(vertices, faces)
    centre = vertices[faces].mean(axis=1)
    centre /= np.linalg.norm(centre, axis=1, keepdims=True)
    # Each face's mean UV is near its centre's exact longitude and latitude (within one segment step).
    u = (np.arctan2(centre[:, 1], centre[:, 0]) / (2 * np.pi)) % 1.0
    v = 0.5 + np.arcsin(centre[:, 2]) / np.pi
    mean = uv.mean(axis=1)
    du = np.abs(((mean[:, 0] - u) + 0.5) % 1.0 - 0.5)
    assert du.max() < 1 / 32 and np.abs(mean[:, 1] - v).max() < 1 / 16
    assert np.ptp(uv[..., 0], axis=1).max() <= 1 / 32 + 1e-12  # no face spans the seam the long way round


def test_plane_and_box_uv_cover_the_unit_square():
    vertices, faces = plane_mesh((4.0, 2.0), (2, 2))
    uv = shapes.planar_uv(vertices, faces)
    corners = vertices[faces]
    np.testing.assert_allclose(uv[..., 0], corners[..., 0] / 4 + 0.5)
    np.testing.assert_allclose(uv[..., 1], 0.5 - corners[..., 2] / 2)
    vertices, faces = shapes.box([1.0, 2.0, 3.0])
    uv = shapes.box_uv(vertices, faces)
    assert uv.min() == 0 and uv.max() == 1
    for side in range(6):  # each side's two triangles cover the whole square
        assert {tuple(p) for p in uv[2 * side:2 * side + 2].reshape(-1, 2)} == {(0, 0), (0, 1), (1, 0), (1, 1)}


def test_cylinder_and_torus_uv_are_continuous_within_faces():
    vertices, faces = shapes.cylinder(1.0, 2.0, 16)
    assert np.ptp(shapes.cylinder_uv(vertices, faces)[..., 0], axis=1).max() <= 0.5  # side 1/16, a cap ½
    vertices, faces = shapes.torus(1.0, 0.25, 16, 8)
    assert np.ptp(shapes.torus_uv(vertices, faces, 1.0), axis=1).max() <= 1 / 8 + 1e-12
