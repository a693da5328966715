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


# ---------------------------------------------------------------- the framed scene table (framed_dict)

TRIANGLE = (np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]]), [[0, 1, 2]])


def test_minus_z_up_frames_as_the_cases_above_say():
    """`up="-z"`: the sign is kept, so the front view stands on +Y with the camera's up −Z (the (0, 0, -1) case
    above), not as +z's."""
    import raycast_phong as rp
    scene = rp.mesh_scene(*TRIANGLE, view="front", up="-z")
    offset = np.subtract(scene.camera.position, scene.camera.look_at)
    assert np.allclose(offset / np.linalg.norm(offset), (0.0, 1.0, 0.0), atol=1e-12)
    assert scene.camera.up == pytest.approx((0.0, 0.0, -1.0))


def test_the_key_light_stands_above_and_left_of_the_camera_as_far_as_it():
    """docs/meshes.md: a key light above and to the left of the camera, as far from the model's centre as the
    camera. The front view with Y up looks down −Z, so left is −X and above is +Y."""
    import raycast_phong as rp
    scene = rp.mesh_scene(*TRIANGLE, view="front")
    centre = np.asarray(scene.camera.look_at)
    light = np.asarray(scene.lights[0].position) - centre
    assert light[0] < -0.1 * np.linalg.norm(light) and light[1] > 0.1 * np.linalg.norm(light)
    assert light[2] > 0  # on the camera's side of the model
    assert np.linalg.norm(light) == pytest.approx(np.linalg.norm(np.subtract(scene.camera.position, centre)))


def test_a_key_path_set_with_spaces_round_its_equals_sign_still_wins_over_the_framing():
    """`--set "camera.position = [0, 0, 9]"` sets camera.position as `camera.position=[0, 0, 9]` does, and the
    framing (which places what no override set) leaves it there."""
    import raycast_phong as rp
    for spelled in ("camera.position=[0, 0, 9]", "camera.position = [0, 0, 9]"):
        assert rp.mesh_scene(*TRIANGLE, overrides=[spelled]).camera.position == (0.0, 0.0, 9.0), spelled


def test_layers_make_the_default_output_an_exr_but_a_given_path_stands():
    """output.aovs need an .exr: a mesh's default output.path becomes NAME.exr (docs: "out.exr" when aovs are
    asked for), but an output.path the overrides give is the user's and is kept."""
    import raycast_phong as rp
    assert rp.mesh_scene(*TRIANGLE, name="tri", overrides=['output.aovs=["depth"]']).output.path == "tri.exr"
    assert rp.mesh_scene(*TRIANGLE, name="tri").output.path == "tri.png"
    given = rp.mesh_scene(*TRIANGLE, name="tri", overrides=['output.aovs=["depth"]', 'output.path="mine.exr"'])
    assert given.output.path == "mine.exr"


def test_the_background_is_byte_51_in_either_colour_setting():
    """docs/meshes.md, "Background": dark grey, 0.2 as written in the PNG. Display colour writes values as they
    are (0.2); linear colour goes through the sRGB curve, so the value is 0.2 decoded: ((0.2 + 0.055) / 1.055)^2.4
    = 0.0331."""
    from raycast_phong.io.encoding import DISPLAY, LINEAR
    from raycast_phong.scene.framing import framed_dict
    from raycast_phong.scene.mesh_arrays import held_mesh
    found = held_mesh(*TRIANGLE)[1].bounds()
    assert framed_dict(found, "t", "t", DISPLAY)["render"]["background"] == [0.2, 0.2, 0.2]
    assert framed_dict(found, "t", "t", LINEAR)["render"]["background"] == pytest.approx([0.0331] * 3, abs=1e-4)


def test_a_model_exactly_the_smallest_extent_across_is_framed_and_a_smaller_one_refused():
    """A model at least 2 · MIN_EXTENT across is framed (the refusal says so); half that is refused."""
    from types import SimpleNamespace

    from raycast_phong.scene.framing import framed_dict
    from raycast_phong.tolerances import MIN_EXTENT

    def found(radius):
        return SimpleNamespace(centre=np.zeros(3), radius=radius, up=None, materials=[], stores_normals=True)
    assert framed_dict(found(MIN_EXTENT), "t", "t", "display")["camera"]["look_at"] == [0.0, 0.0, 0.0]
    with pytest.raises(SceneError, match=r"allowed: a model at least 2e-12 across"):
        framed_dict(found(MIN_EXTENT / 2), "t", "t", "display")


@pytest.mark.parametrize("size", [["render.height=0"], ["render.width=0"], ["render.height=-5"]])
def test_a_size_of_zero_is_validation_s_refusal_not_the_framing_s_crash(size):
    """The framing aims for the size the overrides chose, but a width or height validation will refuse is not
    divided by: the scene is refused in one line naming the key, not a ZeroDivisionError."""
    import raycast_phong as rp
    with pytest.raises(SceneError, match=r"render\.(width|height): out of range"):
        rp.mesh_scene(*TRIANGLE, overrides=size)
