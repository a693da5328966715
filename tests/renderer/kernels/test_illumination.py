"""Hand-computed pixels: a plane seen head-on, every term of the model worked out in the test.

The plane faces +z; an orthographic camera looks down −z with an infinite viewer, so v = (0, 0, 1)
everywhere and the centre pixel of a 3×3 image hits the plane exactly at the origin.
"""

import math

import numpy as np
import pytest

import raycast_phong as rp

COS60, SIN60 = 0.5, math.sqrt(3) / 2


def plane_scene(lights, material, *, shading="flat", specular="phong", ambient=0.0, **render):
    return rp.validate_scene({
        "render": {"width": 3, "height": 3, "shading": shading, "specular": specular, "viewer": "infinite",
                   "precision": "float64", **render},
        "camera": {"type": "orthographic", "position": [0, 0, 5], "look_at": [0, 0, 0], "view_height": 1.0},
        "ambient": ambient,
        "lights": lights,
        "materials": {"m": material},
        # The plane's normal is +y in its own frame; 90° about x turns it to +z.
        "objects": [{"shape": "plane", "size": [4, 4], "rotate": [90, 0, 0], "material": "m"}],
    })


def centre(scene) -> np.ndarray:
    return rp.render(scene).image[1, 1].astype(np.float64)


MATERIAL = {"ka": [0.3, 0.2, 0.1], "kd": [0.9, 0.6, 0.3], "ks": [0.5, 0.4, 0.2], "ke": 0, "shininess": 8}
HEAD_ON = {"type": "directional", "direction": [0, 0, -1], "diffuse": [0.8, 0.7, 0.6], "specular": [1.0, 0.9, 0.5]}
AT_60 = {**HEAD_ON, "direction": [-SIN60, 0, -COS60]}  # travels toward −x−z: l = (sin60, 0, cos60)


def test_plane_sits_where_the_tests_assume():
    result = rp.render(plane_scene([HEAD_ON], MATERIAL))
    # Every pixel of the 3×3 image sees the plane, and all get the same value (directional light).
    assert np.allclose(result.image, result.image[1, 1])


@pytest.mark.parametrize("shading", ["flat", "gouraud", "phong"])
def test_head_on_light(shading):
    """l = n = v: l·n = 1, r = n, v·r = 1, so I = I_d k_d + I_s k_s."""
    expected = np.multiply(HEAD_ON["diffuse"], MATERIAL["kd"]) + np.multiply(HEAD_ON["specular"], MATERIAL["ks"])
    np.testing.assert_allclose(centre(plane_scene([HEAD_ON], MATERIAL, shading=shading)), expected, atol=1e-6)


def test_light_at_60_degrees_phong_specular():
    """l·n = cos 60° = 0.5; r = 2(0.5)n − l = (−sin60, 0, cos60); v·r = 0.5; S = 0.5^8."""
    expected = (np.multiply(AT_60["diffuse"], MATERIAL["kd"]) * COS60
                + np.multiply(AT_60["specular"], MATERIAL["ks"]) * 0.5 ** 8)
    np.testing.assert_allclose(centre(plane_scene([AT_60], MATERIAL)), expected, atol=1e-6)


def test_light_at_60_degrees_blinn_specular():
    """h = normalize(l + v) = (sin60, 0, 1.5)/√3; n·h = 1.5/√3 = cos 30°; S = cos(30°)^8."""
    n_dot_h = 1.5 / math.sqrt(SIN60 ** 2 + 1.5 ** 2)
    assert n_dot_h == pytest.approx(math.cos(math.radians(30)))
    expected = (np.multiply(AT_60["diffuse"], MATERIAL["kd"]) * COS60
                + np.multiply(AT_60["specular"], MATERIAL["ks"]) * n_dot_h ** 8)
    np.testing.assert_allclose(centre(plane_scene([AT_60], MATERIAL, specular="blinn")), expected, atol=1e-6)


def test_emission_and_scene_ambient_without_lights():
    material = {**MATERIAL, "ke": [0.05, 0.1, 0.15]}
    expected = np.array([0.05, 0.1, 0.15]) + 0.25 * np.array(MATERIAL["ka"])
    np.testing.assert_allclose(centre(plane_scene([], material, ambient=0.25)), expected, atol=1e-6)


def test_light_behind_the_surface_gives_ambient_and_emission_only():
    """l·n < 0: no diffuse, and no specular whatever v·r says."""
    behind = {**HEAD_ON, "direction": [0, 0, 1], "ambient": [0.2, 0.2, 0.2]}
    material = {**MATERIAL, "ke": 0.01}
    expected = 0.01 + 0.1 * np.array(MATERIAL["ka"]) + 0.2 * np.array(MATERIAL["ka"])
    got = centre(plane_scene([behind], material, ambient=0.1, two_sided=False))
    np.testing.assert_allclose(got, expected, atol=1e-6)


@pytest.mark.parametrize(("attenuation", "f_att"), [
    ("none", 1.0),
    ("inverse_square", 1 / 2.5 ** 2),
    ([1.0, 0.2, 0.1], 1 / (1.0 + 0.2 * 2.5 + 0.1 * 2.5 ** 2)),
    ([0.5, 0.0, 0.0], 1.0),  # 1/c = 2 is clamped to 1
])
def test_point_light_attenuation(attenuation, f_att):
    """A point light 2.5 above the hit at the origin: l = n, d = 2.5, r = n, v·r = 1."""
    light = {"type": "point", "position": [0, 0, 2.5], "diffuse": [0.8, 0.7, 0.6], "specular": [1.0, 0.9, 0.5],
             "ambient": [0.1, 0.2, 0.3], "attenuation": attenuation}
    expected = f_att * (np.multiply(light["ambient"], MATERIAL["ka"]) + np.multiply(light["diffuse"], MATERIAL["kd"])
                        + np.multiply(light["specular"], MATERIAL["ks"]))
    # Phong shading evaluates the model at the hit point itself.
    np.testing.assert_allclose(centre(plane_scene([light], MATERIAL, shading="phong")), expected, atol=1e-6)


def test_two_coloured_lights_add_per_channel():
    red = {"type": "directional", "direction": [0, 0, -1], "diffuse": [1, 0, 0], "specular": [0, 0, 0]}
    green = {"type": "directional", "direction": [-SIN60, 0, -COS60], "diffuse": [0, 1, 0], "specular": [0, 0, 1]}
    kd, ks = MATERIAL["kd"], MATERIAL["ks"]
    expected = np.array([kd[0] * 1.0, kd[1] * COS60, ks[2] * 0.5 ** 8])
    np.testing.assert_allclose(centre(plane_scene([red, green], MATERIAL)), expected, atol=1e-6)


@pytest.mark.parametrize(("shininess", "expected_s"), [(0, 1.0), (1, 0.5), (8, 0.5 ** 8), (math.inf, 0.0)])
def test_shininess_limits(shininess, expected_s):
    """f = 0 is the f → 0⁺ limit (S = 1 where v·r > 0); f = inf keeps only the mirror direction."""
    light = {**AT_60, "diffuse": 0}
    material = {**MATERIAL, "shininess": shininess}
    expected = np.multiply(AT_60["specular"], MATERIAL["ks"]) * expected_s
    np.testing.assert_allclose(centre(plane_scene([light], material)), expected, atol=1e-6)


def test_float32_precision_agrees_with_float64():
    scene = plane_scene([AT_60], MATERIAL)
    single = rp.render(scene.model_copy(update={"render": scene.render.model_copy(update={"precision": "float32"})}))
    np.testing.assert_allclose(single.image[1, 1], centre(scene), atol=1e-6)


@pytest.mark.parametrize("shading", ["flat", "phong"])
def test_an_infinite_shininess_keeps_the_exact_mirror_direction(shading):
    """f = inf: S = 1 where v·r = 1 exactly and 0 elsewhere. Head on (l = n = v, a plane whose normal the
    rotation gives exactly) v·r = 1, so I = I_s k_s: the one direction f = inf keeps, at its boundary."""
    light = {**HEAD_ON, "diffuse": 0}
    material = {**MATERIAL, "shininess": math.inf}
    expected = np.multiply(HEAD_ON["specular"], MATERIAL["ks"])
    np.testing.assert_allclose(centre(plane_scene([light], material, shading=shading)), expected, atol=1e-6)
