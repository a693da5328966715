"""The framing camera of a mesh file (scene/framing.py): where each view stands, computed by hand from the
axes docs/meshes.md names, and how far, checked by what the distance must achieve (the bounding sphere's
outline fills 0.9 of the image's smaller half-extent), not by restating the formula."""

import math

import numpy as np
import pytest

from raycast_phong.errors import SceneError
from raycast_phong.scene.framing import check_view, frame_camera
from raycast_phong.values.messages import Location

FILL = 0.9  # docs/meshes.md: the model's bounding sphere fills 90 % of the smaller half of the image
C20, S20, C30, S30 = math.cos(math.radians(20)), math.sin(math.radians(20)), math.cos(math.radians(30)), 0.5

# (up, view) → the unit direction from the model's centre to the camera, and the camera's up. Y up: front +Z,
# right +X; Z up (Blender): front −Y, right +X; X up: front +Z, right = X × Z = −Y.
CASES = [
    ((0, 1, 0), "front", (0, 0, 1), (0, 1, 0)),
    ((0, 1, 0), "side", (1, 0, 0), (0, 1, 0)),
    ((0, 1, 0), "top", (0, 1, 0), (0, 0, -1)),
    ((0, 1, 0), "iso", (1 / math.sqrt(3),) * 3, (0, 1, 0)),
    ((0, 1, 0), "three-quarter", (C20 * S30, S20, C20 * C30), (0, 1, 0)),
    ((0, 0, 1), "front", (0, -1, 0), (0, 0, 1)),
    ((0, 0, 1), "side", (1, 0, 0), (0, 0, 1)),
    ((0, 0, 1), "top", (0, 0, 1), (0, 1, 0)),
    ((0, 0, 1), "three-quarter", (C20 * S30, -C20 * C30, S20), (0, 0, 1)),
    ((0, 0, -1), "front", (0, 1, 0), (0, 0, -1)),
    ((1, 0, 0), "side", (0, -1, 0), (1, 0, 0)),
    ((1, 0, 0), "top", (1, 0, 0), (0, 0, -1)),
]


@pytest.mark.parametrize(("up", "view", "direction", "camera_up"), CASES)
def test_each_view_stands_where_its_axes_say(up, view, direction, camera_up):
    """Each view's camera on its axis from the centre, looking at the centre, with the up the docs name (the
    top view: the model's front at the bottom of the image)."""
    centre = np.array([1.0, -2.0, 3.0])
    camera = frame_camera(centre, 2.0, np.array(up, float), view, (640.0, 480.0), 45.0, False)
    offset = np.asarray(camera["position"]) - centre
    assert np.allclose(offset / np.linalg.norm(offset), direction, atol=1e-12)
    assert camera["look_at"] == pytest.approx(list(centre))
    assert camera["up"] == pytest.approx(list(camera_up))
    assert "view_height" not in camera


def _filled(camera: dict, radius: float, size: tuple[float, float], fov: float) -> float:
    """The share of the smaller half-extent the sphere's outline takes: a sphere at distance d subtends the
    half-angle asin(r/d); the image's half-height is tan(fov/2) at unit distance, its half-width aspect × that."""
    d = np.linalg.norm(np.subtract(camera["position"], camera["look_at"]))
    outline = math.tan(math.asin(radius / d))
    half_height = math.tan(math.radians(fov) / 2)
    return outline / min(half_height, size[0] / size[1] * half_height)


@pytest.mark.parametrize(("size", "fov"), [((640.0, 480.0), 45.0), ((300.0, 600.0), 60.0), ((100.0, 100.0), 20.0),
                                           ((1000.0, 10.0), 90.0)])
def test_the_sphere_fills_nine_tenths_of_the_smaller_half_extent(size, fov):
    """Wide and tall images alike: the smaller half-extent (the width's when the image is taller than wide)
    holds the outline with a tenth to spare."""
    camera = frame_camera(np.zeros(3), 3.0, np.array([0.0, 1.0, 0.0]), "front", size, fov, False)
    assert _filled(camera, 3.0, size, fov) == pytest.approx(FILL, rel=1e-12)


@pytest.mark.parametrize(("size", "height"), [((400.0, 200.0), 2 * 3.0 / FILL), ((200.0, 400.0), 4 * 3.0 / FILL)])
def test_an_orthographic_view_holds_the_diameter_in_nine_tenths_of_the_smaller_side(size, height):
    """view_height: the diameter 6 over 0.9 when the height is the smaller side; twice that for an image twice
    as tall as wide, whose width (half the height) must then hold it."""
    camera = frame_camera(np.zeros(3), 3.0, np.array([0.0, 1.0, 0.0]), "side", size, 45.0, True)
    assert camera["view_height"] == pytest.approx(height, rel=1e-12)
    assert np.linalg.norm(camera["position"]) == pytest.approx(9.0)  # three radii: clear of the model


def test_an_unknown_view_is_refused_with_the_allowed_ones():
    with pytest.raises(SceneError) as refused:
        check_view("back", Location("m.obj"))
    message = str(refused.value)
    assert "m.obj" in message and "--view 'back'" in message
    assert "allowed: three-quarter, front, side, top, iso" in message
    check_view(None, Location("m.obj"))
    check_view("iso", Location("m.obj"))
