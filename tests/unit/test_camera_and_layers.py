"""Where rays go and what the geometric layers say, checked pixel by pixel against hand-built rays.

The rays here are written out from the documented formulas (camera.py: pixel (i, j) → screen
x = 2(i + ½)/W − 1, y = 1 − 2(j + ½)/H, row 0 at the top) for a camera whose frame is known by hand
(eye on +z looking at the origin, up +y: right = +x, up = +y), not through camera_rig, so a camera bug
cannot cancel out. The mesh is a fine icosphere: every ray's true hit lies between its inscribed sphere
(radius r_in, the smallest distance from the centre to a face plane) and its circumscribed one (r), which
bounds hit-or-miss and depth from theory.
"""

import math

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.geometry.build import build_geometry

W, H = 64, 40                        # not square: a swapped width/height or aspect shows
CENTRE, RADIUS = np.array([0.7, 0.4, 0.0]), 0.5  # up and to the right: any flip of x or y shows
EYE = np.array([0.0, 0.0, 5.0])
FOV, VIEW_HEIGHT = 40.0, 2.0
# Float32 rays in Embree's unit frame (scale 0.5, the sphere's half-size; the eye 10 units out) round a
# hit point by ~1e-6 world units: measured, at most 8e-7 off its triangle's plane. 1e-5 is 12× that and
# 1/57 of the gap between the two bounding spheres (r − r_in = 5.7e-4 at 4 subdivisions).
ROUNDING = 1e-5


def camera_frame(roll: float) -> tuple[np.ndarray, np.ndarray]:
    """right and up of a camera on +z looking at the origin with `up` turned by `roll` degrees about z:
    right = forward × up = (0, 0, −1) × (−sin, cos, 0) = (cos, sin, 0), up' = right × forward = (−sin, cos, 0)."""
    c, s = math.cos(math.radians(roll)), math.sin(math.radians(roll))
    return np.array([c, s, 0.0]), np.array([-s, c, 0.0])


def ball_scene(camera: str, shading: str = "phong", samples: int = 1, aovs=("depth", "normal", "face"),
               roll: float = 0.0):
    cam = {"type": "orthographic", "view_height": VIEW_HEIGHT} if camera == "orthographic" else {"fov": FOV}
    return rp.validate_scene({
        "render": {"width": W, "height": H, "shading": shading, "samples": samples, "precision": "float64"},
        "camera": {"position": EYE.tolist(), "look_at": [0, 0, 0], "up": camera_frame(roll)[1].tolist(), **cam},
        "lights": [{"type": "directional", "direction": [0, 0, -1]}],
        "objects": [{"shape": "icosphere", "subdivisions": 4, "radius": RADIUS, "translate": CENTRE.tolist()}],
        "output": {"path": "x.exr", "aovs": list(aovs)},
    })


def hand_rays(camera: str, roll: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) origins and unit directions through the pixel centres, from the formulas alone."""
    x = 2 * (np.arange(W) + 0.5) / W - 1
    y = 1 - 2 * (np.arange(H) + 0.5) / H
    sx, sy = np.meshgrid(x, y)
    right, up = camera_frame(roll)
    if camera == "orthographic":
        half = VIEW_HEIGHT / 2
        origins = EYE + (sx * half * W / H)[..., None] * right + (sy * half)[..., None] * up
        return origins, np.broadcast_to([0.0, 0.0, -1.0], origins.shape)
    half = math.tan(math.radians(FOV) / 2)
    d = [0, 0, -1.0] + (sx * half * W / H)[..., None] * right + (sy * half)[..., None] * up
    return np.broadcast_to(EYE, d.shape), d / np.linalg.norm(d, axis=-1, keepdims=True)


def sphere_entry(origins, directions, radius):
    """Distance along each ray to the sphere (CENTRE, radius), NaN on a miss; and the ray's distance to CENTRE."""
    oc = origins - CENTRE
    b = np.einsum("...i,...i", oc, directions)
    miss_distance = np.linalg.norm(oc - b[..., None] * directions, axis=-1)
    disc = b * b - (np.einsum("...i,...i", oc, oc) - radius ** 2)
    with np.errstate(invalid="ignore"):
        return -b - np.sqrt(disc), miss_distance


def inscribed_radius(scene) -> float:
    geometry = build_geometry(scene)
    v0 = geometry.vertices[geometry.faces[:, 0]]
    return float(np.min(np.einsum("ij,ij->i", v0 - CENTRE, geometry.face_normals)))


@pytest.mark.parametrize("roll", [0.0, 30.0])
@pytest.mark.parametrize("camera", ["perspective", "orthographic"])
def test_the_sphere_covers_exactly_the_pixels_whose_rays_meet_it(camera, roll):
    """Hit where the hand-built ray passes inside r_in, background where it passes outside r: an image
    flipped in x or y, a wrong aspect, field of view or view height, or a shifted raster all fail; the
    camera rolled 30° about its axis (right and up both tilted) makes every component of them count."""
    scene = ball_scene(camera, roll=roll)
    face = rp.render(scene).aovs["face"][..., 0]
    _, miss_distance = sphere_entry(*hand_rays(camera, roll), RADIUS)
    inside = miss_distance < inscribed_radius(scene) - ROUNDING
    outside = miss_distance > RADIUS + ROUNDING
    assert inside.sum() > 80 and outside.sum() > 1500
    assert (face[inside] >= 0).all(), "a ray that meets the sphere missed it"
    assert (face[outside] < 0).all(), "a ray that misses the sphere hit it"


@pytest.mark.parametrize("camera", ["perspective", "orthographic"])
@pytest.mark.parametrize("shading", ["flat", "gouraud", "phong"])
def test_depth_normal_and_face_layers_describe_the_hit(camera, shading):
    """Per hit pixel, from the hand-built ray alone:
    - depth lies between the entry distances of the circumscribed and the inscribed sphere;
    - the point eye + depth·d lies in the plane of triangle `face` and inside it (barycentrics ≥ 0);
    - the normal is that face's normal (flat), or its corner normals mixed with those barycentrics and
      renormalised (Gouraud and Phong: the layer shows the interpolated normal).
    """
    scene = ball_scene(camera, shading)
    layers = rp.render(scene).aovs
    depth, normal, face = layers["depth"][..., 0], layers["normal"], layers["face"][..., 0].astype(int)
    origins, directions = hand_rays(camera)
    outer, _ = sphere_entry(origins, directions, RADIUS)
    inner, _ = sphere_entry(origins, directions, inscribed_radius(scene))
    hit = (face >= 0) & np.isfinite(inner)  # rays that meet the inscribed sphere: the whole slab is crossed
    assert hit.sum() > 80
    assert np.isinf(depth[face < 0]).all() and (np.abs(normal[face < 0]) == 0).all()
    assert (depth[hit] >= outer[hit] - ROUNDING).all() and (depth[hit] <= inner[hit] + ROUNDING).all()

    geometry = build_geometry(scene)
    f = face[hit]
    point = origins[hit] + depth[hit][:, None] * directions[hit]
    corners = geometry.vertices[geometry.faces[f]]                      # (N, 3, 3)
    plane = np.einsum("ij,ij->i", point - corners[:, 0], geometry.face_normals[f])
    assert np.abs(plane).max() < ROUNDING
    # Barycentrics of the point: areas of the sub-triangles over the face's, signed along its normal.
    twice_area = np.einsum("ij,ij->i", np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]),
                           geometry.face_normals[f])
    weights = np.stack([np.einsum("ij,ij->i", np.cross(corners[:, (j + 1) % 3] - point, corners[:,
                                                                                                (j + 2) % 3] - point),
                                  geometry.face_normals[f]) / twice_area for j in range(3)], axis=1)
    edge = np.linalg.norm(corners[:, 1] - corners[:, 0], axis=1).min()
    slack = 4 * ROUNDING / edge  # the point's rounding, in barycentric units
    assert weights.min() > -slack, "the point is outside the triangle the face layer names"
    if shading == "flat":
        expected = geometry.face_normals[f]
    else:
        expected = np.einsum("ij,ijk->ik", weights, geometry.corner_normals[f])
        expected /= np.linalg.norm(expected, axis=1, keepdims=True)
    # Corner normals of neighbouring vertices differ by the edge's angle (edge / r), so a weight off by
    # `slack` moves the mix by at most slack · edge / r; 1e-6 more for the layer's float32.
    np.testing.assert_allclose(normal[hit], expected, atol=slack * edge / RADIUS + 1e-6)


def test_geometry_layers_come_from_the_pixel_centre_sample():
    """With 3×3 samples the centre sample's ray is the pixel-centre ray ((1 + ½)/3 = ½ exactly), so the
    depth, normal and face layers equal those of one sample per pixel, bit for bit."""
    one, nine = rp.render(ball_scene("perspective")).aovs, rp.render(ball_scene("perspective", samples=3)).aovs
    for name in ("depth", "normal", "face"):
        np.testing.assert_array_equal(nine[name], one[name], err_msg=name)


@pytest.mark.parametrize("shading", ["flat", "gouraud", "phong"])
def test_the_normal_layer_of_a_two_sided_plane_seen_from_below_faces_the_camera(shading):
    """The plane's geometric normal is +y; from below with two-sided shading the layer shows −y."""
    scene = rp.validate_scene({
        "render": {"width": 8, "height": 8, "shading": shading},
        "camera": {"position": [0, -3, 0], "look_at": [0, 0, 0], "up": [0, 0, 1], "fov": 30},
        "lights": [{"type": "point", "position": [0, -3, 0]}],
        "objects": [{"shape": "plane", "size": [4, 4]}],
        "output": {"path": "x.exr", "aovs": ["normal", "depth"]},
    })
    layers = rp.render(scene).aovs
    np.testing.assert_allclose(layers["normal"].reshape(-1, 3), np.tile([0, -1, 0], (64, 1)), atol=1e-6)
    # Depth of pixel-centre rays onto the plane 3 below the eye: 3 / cos(angle off the axis), the nearest
    # (the four centre pixels, ½ pixel off the axis each way) within the float32 rounding of 3.
    half = math.tan(math.radians(15))
    off_axis = math.hypot(0.5 / 4 * half, 0.5 / 4 * half)
    np.testing.assert_allclose(layers["depth"][3:5, 3:5, 0], 3 * math.sqrt(1 + off_axis ** 2), rtol=1e-6)


def test_generate_rays_gives_the_rows_the_generator_gives():
    """The one-off helper (benchmarks use it) returns rows [1, 3) of a 2×2-sample image: 2 rows × W × 4 rays,
    the same as a RayGenerator's, for both camera types."""
    from raycast_phong.renderer.intersect import unit_frame
    from raycast_phong.renderer.pack import RayGenerator, camera_rig, generate_rays
    for camera in ("perspective", "orthographic"):
        scene = ball_scene(camera)
        rig, frame = camera_rig(scene), unit_frame(build_geometry(scene).vertices)
        origins, directions = generate_rays(rig, frame, W, H, 2, 1, 3)
        assert origins.shape == directions.shape == (2 * W * 4, 3)
        expected = RayGenerator(rig, frame, W, H, 2, 3 * W * 4).rows(1, 3)
        np.testing.assert_array_equal(origins, expected[0])
        np.testing.assert_array_equal(directions, expected[1])
