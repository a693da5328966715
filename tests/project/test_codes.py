"""codes.py is the one home of the shared vocabularies: the schema's choices and the numbers compiled code
compares come from it."""

from __future__ import annotations

import typing

from raycast_phong import codes
from raycast_phong.scene import schema


def test_the_integer_codes_follow_the_enums_order():
    assert [codes.MODEL_CODE[m] for m in (codes.ShadingModel.FLAT, codes.ShadingModel.GOURAUD,
                                          codes.ShadingModel.PHONG)] == [0, 1, 2]
    assert codes.LIGHT_CODE == {codes.LightKind.POINT: 0, codes.LightKind.DIRECTIONAL: 1}


def test_the_schema_offers_exactly_the_codes():
    aov = typing.get_args(schema.Output.model_fields["aovs"].annotation)[0]
    assert typing.get_args(aov) == codes.LAYERS == codes.GEOMETRY_LAYERS + codes.TERM_LAYERS
    assert typing.get_args(schema.Light.model_fields["type"].annotation) == tuple(k.value for k in codes.LightKind)
    assert schema.Render.model_fields["shading"].annotation is codes.ShadingModel
    assert schema.ShadingModel is codes.ShadingModel  # the old import path names the same class
    dumped = schema.DEFAULT_MATERIAL.model_dump()
    assert {k: v for k, v in dumped.items() if not k.endswith("_map")} == {**codes.MATERIAL_DEFAULTS}
    assert tuple(k for k in dumped if k.endswith("_map")) == codes.MAP_COLUMNS
    assert typing.get_args(schema.TextureMap.model_fields["wrap"].annotation) == codes.WRAP_MODES
    assert len(codes.MATERIAL_COLUMNS) == 5 and codes.MATERIAL_WIDTH == 4 * 3 + 1


def test_plan_stages_are_named_by_the_stage_vocabulary():
    """A stage is named by codes.StageName wherever it is read: a misspelt name is an error where the plan is
    built, and no module but the plan spells a stage as a string literal to plan.keeps; the plan of a scene
    names every stage of the vocabulary that is decided before the geometry."""
    import re
    from pathlib import Path

    import pytest

    from raycast_phong.records import Stage
    from raycast_phong.renderer.plan import build_plan
    with pytest.raises(ValueError, match="float46_shading"):
        Stage("float46_shading", True, "a typo")
    assert Stage(codes.StageName.TEXTURES, True, "x").name == "textures"  # kept as the plain string JSON shows
    root = Path(__file__).resolve().parents[2]
    spelled = [f"{path.relative_to(root)}:{number}" for path in [*root.glob("raycast_phong/**/*.py"),
                                                                 *root.glob("tests/**/*.py")]
               for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
               if re.search(r"keeps\(\s*[\"']", line) and path.name != "plan.py"]
    assert spelled == []
    scene = schema.validate_scene({"lights": [{"position": [1, 1, 1]}], "objects": [{"shape": "icosphere"}]})
    later = {codes.StageName.WINDING_REPAIR, codes.StageName.TEXTURES, codes.StageName.VERTEX_COLOURS}
    assert {stage.name for stage in build_plan(scene).stages} == {name.value for name in codes.StageName} - later
