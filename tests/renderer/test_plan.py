"""The render plan leaves out what a scene does not need, never calls it, and changes no pixel."""

import numpy as np
import pytest

import raycast_phong as rp
import raycast_phong.geometry.normals as normals
import raycast_phong.geometry.placing as placing
import raycast_phong.scene.overrides
from raycast_phong.codes import StageName
from raycast_phong.renderer.kernels.layout import COUNTED_TERMS


def scene(**changes):
    data = {
        "render": {"width": 40, "height": 30, "shading": "phong"},
        "camera": {"position": [0, 0.5, 4], "look_at": [0, 0, 0], "fov": 40},
        "ambient": 0.1,
        "lights": [{"type": "point", "position": [2, 2, 3], "diffuse": 0.8, "specular": 1.0}],
        "materials": {"m": {"ka": 1, "kd": 0.6, "ks": 0.4, "ke": 0, "shininess": 20}},
        "objects": [{"shape": "icosphere", "subdivisions": 2, "material": "m"},
                    {"shape": "box", "size": [3, 0.2, 3], "translate": [0, -1.2, 0], "material": "m"}],
    }
    for path, value in changes.items():
        rp.scene.overrides.apply_override(data, f"{path.replace('__', '.')}={value}")
    return rp.validate_scene(data)


# (overrides, stage left out, kernel term that must not be evaluated or None)
CASES = [
    ({"materials__m__ks": "0"}, "specular", "specular"),
    ({"lights__0__specular": "0"}, "specular", "specular"),
    ({}, "attenuation", "attenuation"),
    ({}, "emission", "emission"),
    ({}, "light_ambient", "light_ambient"),
    ({"ambient": "0"}, "scene_ambient", "scene_ambient"),
    ({"materials__m__kd": "0"}, "diffuse", "diffuse"),
    ({"render__viewer": '"infinite"'}, "view_vector_per_point", "view_vector"),
    ({"camera__type": '"orthographic"'}, "view_vector_per_point", "view_vector"),
    ({"render__shading": '"flat"'}, "vertex_normals", None),
    ({}, "crease_split", None),
    ({}, "supersampling", None),
    ({}, "shadow_rays", "shadow_rays"),
]


@pytest.mark.parametrize(("overrides", "stage", "term"), CASES)
def test_left_out_stage_is_reported_and_image_equals_the_full_pipeline(overrides, stage, term):
    s = scene(**overrides)
    plan = rp.build_plan(s)
    assert not plan.keeps(stage), plan.describe()
    lean = rp.render(s)
    full = rp.render(s, plan=rp.build_plan(s, optimize=False))
    np.testing.assert_allclose(lean.image, full.image, atol=1e-6)
    if term is not None:
        assert lean.counts[term] == 0
        if rp.build_plan(s, optimize=False).keeps(stage):
            assert full.counts[term] > 0  # the counter counts: the full pipeline did evaluate it


def test_kept_terms_are_counted():
    s = scene(lights__0__attenuation="[1, 0.1, 0.01]", lights__0__ambient="0.1", materials__m__ke="0.05")
    plan = rp.build_plan(s)
    result = rp.render(s)
    for term in COUNTED_TERMS:
        stage = "view_vector_per_point" if term == "view_vector" else term
        assert plan.keeps(stage), stage
        assert result.counts[term] > 0, term


def test_all_flat_scene_never_computes_vertex_normals(monkeypatch):
    def forbidden(*args, **kwargs):
        raise AssertionError("vertex normals computed for an all-flat scene")

    monkeypatch.setattr(placing, "compute_corner_normals", forbidden)
    result = rp.render(scene(render__shading='"flat"'))
    assert result.image.max() > 0.1
    with pytest.raises(AssertionError, match="vertex normals"):
        rp.render(scene())  # the same scene with Phong shading does need them


def test_crease_split_is_used_only_with_a_crease_angle(monkeypatch):
    calls = []
    original = normals.creased_corners
    monkeypatch.setattr(normals, "creased_corners", lambda *a: calls.append(1) or original(*a))
    rp.render(scene())
    assert calls == []
    rp.render(scene(objects__1__crease_angle="30"))
    assert calls


def test_plan_command_lists_every_stage_with_a_reason():
    text = rp.build_plan(scene(materials__m__ks="0")).describe()
    assert "left out  specular" in text and "every material's k_s or every light's I_s is 0" in text
    assert "kept      diffuse" in text


def test_the_plan_command_and_render_agree_on_whether_a_scene_fits_near_the_budget(tmp_path):
    """One memory check (prepare) for both commands: at the estimate's last byte both go ahead, one byte below
    it both refuse with the same line (exit 2). A global-mode float64 scene with supersampling and layers, where
    an estimate that left out the shadow rays, the precision or the tiles in flight would fall short."""
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    from raycast_phong.renderer.prepare import prepare
    path = tmp_path / "s.toml"
    path.write_text('[render]\nwidth = 64\nheight = 48\nsamples = 2\nmode = "global"\nprecision = "float64"\n'
                    '[output]\naovs = ["depth", "diffuse"]\npath = "x.exr"\n'
                    '[[lights]]\ntype = "point"\nposition = [2, 2, 3]\n'
                    '[[objects]]\nshape = "icosphere"\nsubdivisions = 5\n')
    total = prepare(rp.load_scene(path)).memory.total
    runner = CliRunner()
    for budget, fits in ((total, True), (total - 1, False)):
        plan = runner.invoke(app, ["plan", str(path), "--max-memory", str(budget)])
        render = runner.invoke(app, ["render", str(path), "-q", "-o", str(tmp_path / "x.exr"),
                                     "--max-memory", str(budget)])
        assert (plan.exit_code, render.exit_code) == ((0, 0) if fits else (2, 2)), (budget, plan.output,
                                                                                     render.output)
        if not fits:
            assert "above the" in plan.output and plan.output.strip() == render.output.strip()


def test_a_shininess_of_exactly_the_float32_limit_stays_in_float32_and_a_larger_one_does_not():
    """F32_SHININESS_LIMIT (2^24 / 512 = 32768) is the stiffest highlight float32 shades: at exactly it the plan
    keeps float32, just above it (32769) it shades in float64 and says why. Catches `>` made `>=`."""
    from raycast_phong.codes import StageName
    from raycast_phong.renderer.plan import F32_SHININESS_LIMIT
    assert F32_SHININESS_LIMIT == 32768
    at = rp.build_plan(scene(materials__m__shininess="32768"))
    assert not at.keeps(StageName.FLOAT64_SHADING)
    above = rp.build_plan(scene(materials__m__shininess="32769"))
    assert above.keeps(StageName.FLOAT64_SHADING)
    assert "shininess 32769 > 32768" in above.describe()


def test_a_directional_lights_attenuation_leaves_the_stage_out():
    """f_att is a point light's: a directional light has no distance, so its `attenuation` (accepted, ignored)
    keeps no attenuation stage, and the plan says no point light attenuates. Catches every light counted."""
    s = scene(lights__0__type='"directional"', lights__0__direction="[-1, -1, -1]",
              lights__0__attenuation='"inverse_square"')
    plan = rp.build_plan(s)
    assert not plan.keeps(StageName.ATTENUATION), plan.describe()
    assert "no point light attenuates: f_att = 1" in plan.describe()
    assert rp.render(s).counts["attenuation"] == 0
