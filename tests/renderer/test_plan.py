"""The render plan leaves out what a scene does not need, never calls it, and changes no pixel."""

import numpy as np
import pytest

import raycast_phong as rp
import raycast_phong.geometry.build as geometry
import raycast_phong.geometry.normals as normals
import raycast_phong.scene.schema
from raycast_phong.renderer.kernels.illumination import COUNTED_TERMS


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
        rp.scene.schema.apply_override(data, f"{path.replace('__', '.')}={value}")
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
    ({}, "shadow_rays", None),
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

    monkeypatch.setattr(geometry, "compute_corner_normals", forbidden)
    result = rp.render(scene(render__shading='"flat"'))
    assert result.image.max() > 0.1
    with pytest.raises(AssertionError, match="vertex normals"):
        rp.render(scene())  # the same scene with Phong shading does need them


def test_crease_split_is_used_only_with_a_crease_angle(monkeypatch):
    calls = []
    original = normals._creased_sums
    monkeypatch.setattr(normals, "_creased_sums", lambda *a: calls.append(1) or original(*a))
    rp.render(scene())
    assert calls == []
    rp.render(scene(objects__1__crease_angle="30"))
    assert calls


def test_plan_command_lists_every_stage_with_a_reason():
    text = rp.build_plan(scene(materials__m__ks="0")).describe()
    assert "left out  specular" in text and "every material's k_s or every light's I_s is 0" in text
    assert "kept      diffuse" in text
