"""The stability suite's cases, each a property that can fail (raycast_phong/tools/stability.py).

`raycast-phong stability` runs the same functions on the installed package; these tests add the
figures' expected values where the issue states them.
"""

import math

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.codes import StageName
from raycast_phong.renderer.plan import F32_SHININESS_LIMIT
from raycast_phong.tools import stability


@pytest.mark.parametrize("name", list(stability.CASES))
def test_case_holds(name):
    result = stability.CASES[name]()
    assert result.passed, f"{result.case}: {result.property} — measured {result.figure}"


def test_every_issue_case_is_in_the_suite():
    assert len(stability.CASES) >= 12


def test_f_zero_is_the_limit_not_numpy_zero_to_the_zero():
    """f = 0: S = 1 where v·r > 0 and 0 where v·r ≤ 0 (not 0**0 = 1 everywhere)."""
    image = rp.render(stability.sphere_scene(0.0, precision="float64")).image
    tiny = rp.render(stability.sphere_scene(1e-6, precision="float64")).image
    np.testing.assert_allclose(image, tiny, atol=1e-4)  # f → 0⁺ is continuous


def test_the_float32_limit_is_where_the_error_reaches_half_an_8bit_step():
    below, _ = stability.float32_highlight_error(F32_SHININESS_LIMIT / 8)
    above, _ = stability.float32_highlight_error(F32_SHININESS_LIMIT * 32)
    assert below < 1 / 512 < above


def test_stiff_gouraud_peak_ratio_collapses_with_f():
    ratios = [stability.gouraud_phong_peak_ratio(f) for f in (10.0, 100.0, 1000.0)]
    assert ratios[0] > 0.01 and ratios[2] < 1e-6


def test_plan_warns_about_gouraud_and_suggests_the_subdivisions_that_resolve_it():
    scene = stability.sphere_scene(100.0, subdivisions=1, shading="gouraud")
    warnings = rp.render(scene).plan.warnings
    suggestion = next(w for w in warnings if "subdivisions =" in w)
    level = int(suggestion.split("subdivisions = ")[1].split(",")[0])
    # 1/√100 = 0.1 rad: an icosphere at that level has vertex normals closer than the highlight.
    fine = stability.sphere_scene(100.0, subdivisions=level, shading="gouraud")
    assert not any("subdivisions =" in w for w in rp.render(fine).plan.warnings)
    assert level >= 3


def test_plan_switches_to_float64_and_says_so():
    plan = rp.build_plan(stability.sphere_scene(1e6))
    assert plan.keeps(StageName.FLOAT64_SHADING)
    assert "shaded in float64" in plan.describe()
    assert rp.render(stability.sphere_scene(1e6, size=16)).image.dtype == np.float64


@pytest.mark.parametrize("sideways", [(0.0, 0.0), (3e-7, -5e-7), (-1.5e-6, 1e-6)])
@pytest.mark.parametrize("distance", [0.0, 1e-30, 1e-12, -1e-12])
@pytest.mark.parametrize("attenuation", ["none", "inverse_square", [1.0, 0.5, 0.25]])
@pytest.mark.parametrize("precision", ["float32", "float64"])
def test_a_light_inside_the_distance_floor_is_head_on(distance, sideways, attenuation, precision):
    """Inside the floor (1e-6 × the half-extent 2 = 2e-6) the light shines along n, wherever the hit lands.

    The lights sideways sit 5.8e-7 and 1.8e-6 from the centre: inside the floor, but far enough off the
    axis that their true direction is almost in the plane (n·l ≤ 2e-6). So the head-on rule, not the last
    bits of Embree's barycentrics, decides the centre pixel — on any CPU. Tolerance: v·r = 1 to a few
    float32 ulps, raised to f = 32, moves S by ≤ 32 × 4 × 6e-8 ≈ 8e-6 of the peak.
    """
    image = rp.render(stability.plane_with_light(distance, attenuation, precision, sideways)).image
    assert np.isfinite(image).all() and image.min() >= 0
    centre = float(image[4, 4].max())
    if attenuation == "inverse_square":
        assert centre == pytest.approx(stability.LIGHT_ON_SURFACE_PEAK, rel=1e-5)
    elif attenuation == "none":
        assert centre == pytest.approx(0.8 * 0.8 + 1.0 * 0.5 + 0.2 * 0.1, rel=1e-5)


def test_a_light_just_outside_the_floor_has_its_true_direction():
    """Just outside the floor (2.4e-6 sideways, 1e-12 up) the light lies almost in the plane: n·l ≈ 4e-7."""
    image = rp.render(stability.plane_with_light(1e-12, "inverse_square", "float64", (2.4e-6, 0.0))).image
    assert float(image[4, 4].max()) < 1e-3 * stability.LIGHT_ON_SURFACE_PEAK


def test_perspective_screen_difference_follows_the_formula():
    measured, predicted = stability.interpolation_difference(9.0)
    assert predicted == pytest.approx(0.5)
    assert abs(measured - predicted) < 0.02


def test_scale_invariance_holds_far_from_the_origin_in_global_mode():
    reference = rp.render(stability.placed_scene(1.0, 0.0, "global")).image
    moved = rp.render(stability.placed_scene(1e3, 4e9, "global")).image
    assert (np.abs(moved - reference).max(axis=2) > 1e-3).mean() <= 0.01
    assert math.isfinite(float(moved.max()))
