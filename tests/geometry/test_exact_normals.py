"""normals = "exact": a built-in shape's true surface normal at every face corner (geometry.exact_corner_normals)."""

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.geometry.build import build_geometry


def geometry(**obj):
    return build_geometry(rp.validate_scene({"objects": [obj]}))


def corner_normal_at(g, point, face_normal=None):
    """The corner normals of every corner at `point` (world), optionally only on faces with that face normal."""
    hits = np.isclose(g.vertices[g.faces], point, atol=1e-9).all(axis=-1)
    if face_normal is not None:
        hits &= np.isclose(g.face_normals, face_normal, atol=1e-9).all(axis=-1)[:, None]
    assert hits.any(), f"no corner at {point}"
    return g.corner_normals[hits]


def test_sphere_scaled_into_an_ellipsoid_gets_the_ellipsoid_normal():
    # World = diag(2, 1, 1) · local; the ellipsoid x²/4 + y² + z² = 1 has gradient (x/2, 2y, 2z)/2 ∝ (x/4, y, z).
    g = geometry(shape="icosphere", subdivisions=1, normals="exact", scale=[2, 1, 1])
    p = g.vertices[g.faces]
    expected = p * [0.25, 1, 1]
    np.testing.assert_allclose(g.corner_normals, expected / np.linalg.norm(expected, axis=-1, keepdims=True),
                               atol=1e-12)


def test_mirrored_sphere_keeps_each_corner_with_its_vertex():
    # A mirroring scale reverses the winding (place()); the corners' normals must follow their vertices.
    g = geometry(shape="uv_sphere", segments=[8, 4], normals="exact", scale=[-1, 1, 1], translate=[3, 0, 0])
    p = g.vertices[g.faces] - [3, 0, 0]
    np.testing.assert_allclose(g.corner_normals, p / np.linalg.norm(p, axis=-1, keepdims=True), atol=1e-12)


def test_torus_normal_points_away_from_the_tube_centre():
    g = geometry(shape="torus", major_radius=1.0, minor_radius=0.25, segments=[8, 4], normals="exact")
    for point, normal in [((1.25, 0, 0), (1, 0, 0)), ((0.75, 0, 0), (-1, 0, 0)), ((1, 0, 0.25), (0, 0, 1)),
                          ((0, 1.25, 0), (0, 1, 0))]:
        found = corner_normal_at(g, point)
        np.testing.assert_allclose(found, np.broadcast_to(normal, found.shape), atol=1e-12)


def test_cylinder_rim_is_radial_on_the_side_and_axial_on_the_cap():
    # Rx(90°): (x, y, z) → (x, y cos 90° − z sin 90°, y sin 90° + z cos 90°) = (x, −z, y).
    g = geometry(shape="cylinder", radius=1.0, height=2.0, segments=[8, 3], normals="exact", rotate=[90, 0, 0])
    rim = (1.0, -1.0, 0.0)  # local (1, 0, 1): x stays, y = −z = −1, z = y = 0
    cap = (0.0, -1.0, 0.0)  # local +z → world −y
    on_cap = corner_normal_at(g, rim, face_normal=cap)
    np.testing.assert_allclose(on_cap, np.broadcast_to(cap, on_cap.shape), atol=1e-12)
    side = corner_normal_at(g, rim)
    side = side[np.abs(side[:, 1]) < 0.5]
    assert len(side) >= 1
    np.testing.assert_allclose(side, np.broadcast_to((1, 0, 0), side.shape), atol=1e-12)


@pytest.mark.parametrize("shape", ["box", "plane"])
def test_flat_shapes_get_their_face_normals(shape):
    g = geometry(shape=shape, normals="exact", scale=[-2, 1, 3], rotate=[10, 20, 30])
    np.testing.assert_allclose(g.corner_normals, np.repeat(g.face_normals[:, None], 3, axis=1), atol=1e-12)


def test_mean_normals_differ_from_exact_by_order_h_squared_on_a_uv_sphere():
    """Away from the poles the uv sphere's mean normals are second-order accurate: the angle to the exact
    normal falls 4× per halving of the edge (measured 0.00073, 0.00020, 0.000049 rad, about 0.02 h², max over
    |z| < 0.5 at levels 2-4; near the poles it is first order). Were "exact" the mean, the angle would be 0."""
    worst = []
    for level in (2, 3, 4):
        segments = [8 * 2 ** level, 4 * 2 ** level]
        exact = geometry(shape="uv_sphere", segments=segments, normals="exact")
        mean = geometry(shape="uv_sphere", segments=segments, normals="mean")
        angle = np.arccos(np.clip(np.einsum("fki,fki->fk", exact.corner_normals, mean.corner_normals), -1, 1))
        band = np.abs(exact.corner_normals[..., 2]) < 0.5
        worst.append(angle[band].max())
        h = np.pi / (4 * 2 ** level)  # the latitude step, radians on the unit sphere
        assert 0.01 * h ** 2 < worst[-1] < 0.04 * h ** 2
    ratios = np.array(worst[:-1]) / np.array(worst[1:])
    assert np.all((ratios > 3.2) & (ratios < 4.8)), ratios


def test_exact_normals_are_refused_for_a_mesh_file():
    with pytest.raises(rp.SceneError, match=r'objects\.0.*normals = "exact" needs a built-in shape'):
        rp.validate_scene({"objects": [{"shape": "mesh", "path": "x.obj", "normals": "exact"}]})
