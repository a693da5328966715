"""The scene's limits at their edges (docs/scene-format.md): the ray limit counts width × height × samples² rays,
the brightness bound adds the lights' and the scene's ambient terms, and a path in a message is quoted, so a
line feed in it keeps the message one line. Expectations are the format's numbers, worked out by hand."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

import raycast_phong as rp
from raycast_phong.errors import SceneError
from raycast_phong.geometry.build import build_geometry

SPHERE = [{"shape": "icosphere", "subdivisions": 0}]


def scene(**keys) -> rp.Scene:
    return rp.validate_scene({"objects": SPHERE, **keys})


def test_the_ray_limit_counts_samples_squared():
    """Catches a ray count of width × height × samples (16384² × 3 = 0.8e9 passes; × 3² = 2.4e9 > 2³¹ − 1)."""
    big = {"width": 16384, "height": 16384}
    assert scene(render={**big, "samples": 2}).render.samples == 2  # 16384² × 4 = 2³⁰ rays: allowed
    with pytest.raises(SceneError, match=r"render\.samples: .*rays per frame"):
        scene(render={**big, "samples": 3})
    with pytest.raises(SceneError, match="rays per frame"):
        scene(render={"width": 16384, "height": 8193, "samples": 4})  # 2.15e9: over by a column of pixels
    assert scene(render={"width": 16384, "height": 8191, "samples": 4}).render.samples == 4


@pytest.mark.parametrize(("ambient", "light"), [
    ([0, 0, 0], {"ambient": [6e37, 0, 0], "diffuse": [5e37, 0, 0], "specular": 0}),  # 1.1e38 in red
    ([0, 0, 0], {"ambient": [0, 0, 1e38], "diffuse": 0, "specular": [0, 0, 1e37]}),  # 1.1e38 in blue
    ([0, 6e37, 0], {"ambient": 0, "diffuse": [0, 5e37, 0], "specular": 0}),  # the scene's I_a: 1.1e38 in green
])
def test_the_brightness_bound_counts_the_ambient_terms(ambient, light):
    """Catches a bound 1 + I_a + Σ f_att (I_a,k + I_d,k + I_s,k) that leaves out the light's or scene's ambient."""
    lit = {"type": "directional", "direction": [0, 0, -1], **light}
    with pytest.raises(SceneError, match=r"lights\.0: a pixel channel could reach 1\.1e\+38"):
        scene(ambient=ambient, lights=[lit])
    lower = {key: [v / 2 for v in value] if isinstance(value, list) else value for key, value in light.items()}
    scene(ambient=[v / 2 for v in ambient], lights=[{**lit, **lower}])  # 5.5e37: allowed


def test_an_inverse_square_light_s_ambient_alone_is_refused_once_the_geometry_gives_its_gain():
    """Catches the 1/d² bound (geometry's check) leaving out a light's ambient: a light inside the sphere's box has
    the floor's gain, 1/(1e-6 × half-extent 0.85)² = 1.4e12, times ambient 1e27."""
    light = {"position": [0, 0, 0], "attenuation": "inverse_square", "ambient": 1e27, "diffuse": 0, "specular": 0}
    loaded = scene(lights=[light])  # at validation a 1/d² light's gain is not known yet
    with pytest.raises(SceneError, match=r"lights\.0: with 1/d² attenuation up to 1\.38e\+12"):
        build_geometry(loaded)
    build_geometry(scene(lights=[{**light, "ambient": 1e25}]))  # 1e37: allowed


def test_a_far_inverse_square_light_is_judged_by_its_gain_at_the_scene_not_before():
    """A 1/d² light 10⁴ from the sphere with diffuse and specular 1e38 each (2e38 unattenuated): its gain there is
    below 1e-8, so no pixel channel passes 2e30. The scene is valid and its geometry builds. Catches validation
    giving a 1/d² light a gain of 1 before the geometry can give its own."""
    light = {"position": [0, 0, 1e4], "attenuation": "inverse_square", "ambient": 0, "diffuse": 1e38,
             "specular": 1e38}
    build_geometry(scene(lights=[light]))
    with pytest.raises(SceneError, match=r"lights\.0: a pixel channel could reach 2e\+38"):
        scene(lights=[{**light, "attenuation": "none"}])  # the same light unattenuated: refused at once


def one_line_refusal(make) -> str:
    with pytest.raises(SceneError) as refused:
        make()
    assert "\n" not in str(refused.value), str(refused.value)
    return str(refused.value)


def test_a_line_feed_in_an_output_path_stays_quoted(tmp_path):
    """Catches an output path written into a message unquoted (its line feed then splits the line)."""
    assert r"'a\nb.txt' must end in .png" in one_line_refusal(lambda: scene(output={"path": "a\nb.txt"}))
    assert r"'a\nb.png' (a PNG" in one_line_refusal(lambda: scene(output={"path": "a\nb.png", "aovs": ["depth"]}))
    from raycast_phong.scene.output import render_output
    outside = scene(output={"path": "../a\nb.png"})
    assert r"'../a\nb.png' leaves" in one_line_refusal(lambda: render_output(outside, Path("s.toml"), None, False))


def test_a_line_feed_in_a_symbolic_link_s_target_stays_quoted(tmp_path):
    """Catches the real path an output.path leads to written unquoted (before: a raw line feed in the message)."""
    from raycast_phong.scene.output import render_output
    (tmp_path / "scenes").mkdir()
    (tmp_path / "else\nwhere").mkdir()
    (tmp_path / "scenes" / "out").symlink_to(tmp_path / "else\nwhere")
    loaded = rp.validate_scene({"objects": SPHERE, "output": {"path": "out/x.png"}}, folder=tmp_path / "scenes")
    message = one_line_refusal(lambda: render_output(loaded, tmp_path / "scenes" / "s.toml", None, False))
    assert r"else\nwhere" in message and "symbolic link" in message


def test_a_line_feed_in_a_mesh_path_stays_quoted_where_it_lacks_normals(tmp_path):
    """Catches the mesh path of a normals = "file" refusal written unquoted."""
    (tmp_path / "a\nb.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    loaded = rp.validate_scene({"objects": [{"shape": "mesh", "path": "a\nb.obj", "normals": "file"}]},
                               folder=tmp_path)
    assert "stores no vertex normals" in one_line_refusal(lambda: build_geometry(loaded))


def test_replace_keeps_an_unset_crease_angle_unset(tmp_path):
    """Catches Scene.replace setting every object's crease_angle (180), which smoothed a mesh file without normals
    that is creased at 30° while the key is unset (before: any replace made the cube smooth)."""
    (tmp_path / "cube.obj").write_text("".join(f"v {x} {y} {z}\n" for x in (-1, 1) for y in (-1, 1) for z in (-1, 1))
                                       + "f 1 2 4\nf 1 4 3\nf 5 7 8\nf 5 8 6\nf 1 5 6\nf 1 6 2\n"
                                       + "f 3 4 8\nf 3 8 7\nf 1 3 7\nf 1 7 5\nf 2 6 8\nf 2 8 4\n")
    loaded = rp.validate_scene({"objects": [{"shape": "mesh", "path": "cube.obj"}]}, folder=Path(tmp_path))
    changed = loaded.replace({"render.width": 32})
    assert "crease_angle" not in changed.objects[0].model_fields_set
    g = build_geometry(changed)
    flat = g.face_normals[:, None].repeat(3, axis=1)
    assert abs(g.corner_normals - flat).max() < 1e-9  # creased at 30°: every corner its face's normal
    assert changed.replace({"objects.0.crease_angle": 180}).objects[0].crease_angle == 180


# ---------------------------------------------------------------- each bound at its value and one step past it
# The tests above cross a bound by a wide margin; these take the documented value itself (accepted) and the next
# value (refused), so a bound moved by one step, or `≤` made `<`, is caught. Each pair is absolute, not the schema's
# word against the loader's (tests/scene/test_json_schema.py), which move together when a Field's bound moves.

def refusal(make) -> str:
    with pytest.raises(SceneError) as refused:
        make()
    return str(refused.value)


@pytest.mark.parametrize("side", ["width", "height"])
def test_an_image_side_of_16384_pixels_is_accepted_and_16385_refused(side):
    """docs/scene-format.md: width, height 1..16384. Catches either side's bound moved by one, or made exclusive."""
    other = "height" if side == "width" else "width"
    assert getattr(scene(render={side: 16384, other: 1}).render, side) == 16384
    assert refusal(lambda: scene(render={side: 16385, other: 1})) == (
        f"<scene>: render.{side}: out of range; allowed: 1 ≤ {side} ≤ 16384 (got 16385)")
    assert getattr(scene(render={side: 1}).render, side) == 1
    assert f"render.{side}: out of range" in refusal(lambda: scene(render={side: 0}))


def test_sixteen_samples_are_accepted_and_seventeen_refused():
    """docs/scene-format.md: samples 1..16 (16² = 256 rays a pixel). Catches the bound moved by one or made `<`."""
    assert scene(render={"width": 4, "height": 4, "samples": 16}).render.samples == 16
    assert refusal(lambda: scene(render={"samples": 17})) == (
        "<scene>: render.samples: out of range; allowed: 1 ≤ samples ≤ 16 (got 17)")
    assert "render.samples: out of range" in refusal(lambda: scene(render={"samples": 0}))


def test_a_frame_of_exactly_2_to_the_31_rays_is_one_past_the_limit():
    """2³¹ − 1 is prime, so no frame casts exactly that many rays: 16384 × 8192 × 4² = 2³¹ is the first count past
    it (the test above stops at 16384 × 8191 × 4²). Catches a limit of 2³¹ in place of 2³¹ − 1."""
    assert refusal(lambda: scene(render={"width": 16384, "height": 8192, "samples": 4})) == (
        "<scene>: render.samples: 16384×8192 pixels × 4² samples is more than 2147483647 rays per frame")
    assert "8192×16384 pixels × 4² samples" in refusal(lambda: scene(render={"width": 8192, "height": 16384,
                                                                             "samples": 4}))
    assert scene(render={"width": 16384, "height": 8192, "samples": 2}).render.samples == 2  # 2²⁹ rays


def test_a_field_of_view_just_below_180_degrees_is_accepted_and_180_refused():
    """0 < fov < 180, both ends open. Catches `lt` made `le` (180 would look backward) or `gt` made `ge`."""
    assert scene(camera={"fov": math.nextafter(180.0, 0.0)}).camera.fov < 180.0
    assert "camera.fov: out of range; allowed: 0.0 < fov < 180.0 (got 180)" in refusal(
        lambda: scene(camera={"fov": 180}))
    assert scene(camera={"fov": 5e-324}).camera.fov > 0.0
    assert "camera.fov: out of range" in refusal(lambda: scene(camera={"fov": 0}))


def test_a_viewing_direction_of_exactly_the_least_length_is_accepted_and_the_float_below_refused():
    """look_at − position may be as short as DIRECTION_RANGE[0] (1e-150) and no shorter. Catches `<` made `<=`."""
    assert scene(camera={"position": [0, 0, 0], "look_at": [1e-150, 0, 0]}).camera.look_at[0] == 1e-150
    assert "from camera.position; allowed: at least 1e-150" in refusal(
        lambda: scene(camera={"position": [0, 0, 0], "look_at": [math.nextafter(1e-150, 0.0), 0, 0]}))


def test_an_up_at_exactly_the_parallel_bound_is_refused_and_one_just_past_it_accepted():
    """Up is refused while |f × up| ≤ 1e-9 |f| |up| (the sine of their angle). Looking along x, up = [1, 1e-9, 0]
    has |f × up| = 1e-9 and |up| = 1 in float64: exactly at the bound, refused; [1, 2e-9, 0] is past it. Catches
    `<=` made `<`."""
    camera = {"position": [0, 0, 0], "look_at": [1, 0, 0]}
    assert "camera.up: [1.0, 1e-09, 0.0] is parallel to the viewing direction" in refusal(
        lambda: scene(camera={**camera, "up": [1, 1e-9, 0]}))
    assert scene(camera={**camera, "up": [1, 2e-9, 0]}).camera.up[1] == 2e-9


def test_a_view_height_of_1e18_is_accepted_and_the_next_float_refused():
    """Lengths are in (0, 1e18]. Catches view_height's bound made exclusive or moved past 1e18."""
    ortho = {"type": "orthographic"}
    assert scene(camera={**ortho, "view_height": 1e18}).camera.view_height == 1e18
    assert "camera.view_height: out of range; allowed: 0.0 < view_height ≤ 1e+18" in refusal(
        lambda: scene(camera={**ortho, "view_height": math.nextafter(1e18, math.inf)}))
    assert "camera.view_height: out of range" in refusal(lambda: scene(camera={**ortho, "view_height": 0}))


@pytest.mark.parametrize(("key", "at_limit", "past"), [
    ("crease_angle", 180, math.nextafter(180.0, math.inf)),
    ("crease_angle", 0, -5e-324),
    ("subdivisions", 8, 9),
])
def test_an_objects_bound_holds_on_a_later_object_of_a_bulk_checked_group(key, at_limit, past):
    """Three icospheres with the same keys are one group checked a column at a time (scene/bulk.py); the value at
    the bound is accepted in every row, and the value past it in the last row is refused naming objects.2. Catches
    a bound moved by one or made exclusive in the model or in bulk's column check, and a check of the first row."""
    objects = [{"shape": "icosphere", "subdivisions": 0, key: at_limit} for _ in range(3)]
    assert [getattr(obj, key) for obj in rp.validate_scene({"objects": objects}).objects] == [at_limit] * 3
    objects[2] = {**objects[2], key: past}
    assert refusal(lambda: rp.validate_scene({"objects": objects})).startswith(
        f"<scene>: objects.2.{key}: out of range; allowed: 0")


def test_segments_of_4096_are_accepted_and_4097_in_either_place_of_a_later_object_refused():
    """Each of the two counts is in 3..4096. Catches a pair check that looks only at its first count, or at the first
    object of a group (bulk), and the bound moved by one."""
    spheres = [{"shape": "uv_sphere", "segments": [4096, 4096]}] * 3
    assert [obj.segments for obj in rp.validate_scene({"objects": spheres}).objects] == [(4096, 4096)] * 3
    for bad in ([3, 4097], [4097, 3], [3, 2]):
        changed = [*spheres[:2], {"shape": "uv_sphere", "segments": bad}]
        assert refusal(lambda changed=changed: rp.validate_scene({"objects": changed})) == (
            f"<scene>: objects.2.segments: segments must be two whole numbers in [3, 4096], got {bad}")


def test_the_brightness_bound_allows_exactly_1e38_and_names_the_brightest_of_several_lights():
    """1 + I_a + Σ ... ≤ 1e38: a light's ambient of 1e38 alone (1 + 1e38 rounds to 1e38) is at the bound and
    accepted; a fourth light adding 1e31 is past it, and the line names the brightest light, the third. Catches the
    bound made strict, a sum of the first light only, and a message that always names lights.0."""
    dark = {"type": "directional", "direction": [0, 0, -1], "ambient": 0, "diffuse": 0, "specular": 0}
    lights = [dict(dark), dict(dark), {**dark, "ambient": 1e38}]
    assert scene(ambient=0, lights=lights).lights[2].ambient == (1e38,) * 3
    message = refusal(lambda: scene(ambient=0, lights=[*lights, {**dark, "specular": [1e31, 0, 0]}]))
    assert message.startswith("<scene>: lights.2: a pixel channel could reach 1e+38 ="), message


def test_a_1_over_d_squared_light_closer_than_the_floor_counts_at_the_floor():
    """f_att = 1/max(d, floor)², floor = 1e-6 × the half-extent (docs/scene-format.md): a light 1e-9 off a unit
    sphere's bounding box counts as 1e-6 away, a gain of 1e12, so an intensity of 1e25 stays within 1e38
    (1e37 a term); counted at its own 1e-9 (a gain of 1e18) it would be refused."""
    from raycast_phong.geometry.checks import check_float_range
    light = {"type": "point", "attenuation": "inverse_square", "position": [1 + 1e-9, 0, 0],
             "ambient": 0, "diffuse": 1e25, "specular": 0}
    near = scene(lights=[light], objects=[{"shape": "box", "size": [2, 2, 2]}])
    geometry = build_geometry(near)
    assert [float(x) for x in geometry.box[1]] == [1.0, 1.0, 1.0]
    check_float_range(near, geometry)
    brighter = scene(lights=[{**light, "diffuse": 2e26}], objects=[{"shape": "box", "size": [2, 2, 2]}])
    with pytest.raises(SceneError, match=r"lights\.0"):
        check_float_range(brighter, geometry)  # 2e26 × 1e12 = 2e38: over
