"""Scene.replace: a validated change of a loaded scene from Python, without CLI strings (issue 34 item 4)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def test_a_change_is_validated_and_keeps_the_scene_s_folder():
    """The change lands where its key path says, the rest is unchanged, and the scene's textures still resolve
    (a dump-and-validate lost the folder: the map then named a file that is not there)."""
    scene = rp.load_scene(SCENES / "textured_sphere.toml")
    changed = scene.replace({"render.width": 32, "render.height": 24, "lights.0.position": [1, 2, 3]})
    assert (changed.render.width, changed.render.height, changed.lights[0].position) == (32, 24, (1.0, 2.0, 3.0))
    assert changed.folder == scene.folder and changed.materials == scene.materials
    assert changed.objects == scene.objects and changed.camera == scene.camera
    assert (scene.render.width, scene.lights[0].position) != (32, (1.0, 2.0, 3.0))  # the original is untouched
    by_cli = rp.load_scene(SCENES / "textured_sphere.toml", ["render.width=32", "render.height=24",
                                                            "lights.0.position=[1, 2, 3]"])
    assert changed == by_cli
    np.testing.assert_array_equal(rp.render(changed).image, rp.render(by_cli).image)


def test_an_empty_change_gives_an_equal_scene():
    scene = rp.load_scene(SCENES / "default.toml")
    assert scene.replace({}) == scene


@pytest.mark.parametrize("changes, message", [
    ({"render.width": -1}, "Scene.replace: render.width: out of range; allowed: 1 ≤ width ≤ 16384 (got -1)"),
    ({"lights.9.position": [0, 0, 0]}, "Scene.replace: lights.9: lights is a list of 1 item; "
                                       "allowed indices: 0 to 0"),
    ({"render..width": 3}, "Scene.replace: 'render..width' is not a key path"),
    ({"nope": 1}, "Scene.replace: nope: unknown key"),
    ({3: 1}, "Scene.replace: 3 is not a key path; expected a string such as 'render.width'"),
    ({("render", "width"): 1}, "Scene.replace: ['render', 'width'] is not a key path"),
])
def test_a_refused_change_is_one_line_naming_its_key(changes, message):
    scene = rp.load_scene(SCENES / "specular.toml")
    with pytest.raises(rp.SceneError) as raised:
        scene.replace(changes)
    assert str(raised.value).startswith(message) and "\n" not in str(raised.value), str(raised.value)


def test_a_list_index_equal_to_the_lists_length_is_one_line():
    """A key path one past a list's last item (lights.1 with one light) is the key path's refusal, naming the
    allowed indices, from --set as from Scene.replace; lights.0 is the last that takes. Catches the bound at the
    length itself (an IndexError)."""
    path = rp.default_scene_path()
    assert len(rp.load_scene(path).lights) == 1
    assert rp.load_scene(path, ["lights.0.position=[1, 2, 3]"]).lights[0].position == (1.0, 2.0, 3.0)
    with pytest.raises(rp.SceneError) as refused:
        rp.load_scene(path, ["lights.1.position=[1, 2, 3]"])
    assert str(refused.value).endswith("lights.1: lights is a list of 1 item; allowed indices: 0 to 0")
    with pytest.raises(rp.SceneError, match="allowed indices: 0 to 0"):
        rp.load_scene(path).replace({"lights.1.position": [1, 2, 3]})


def test_a_folder_key_in_a_table_is_unknown_not_the_scenes_folder(tmp_path):
    """`folder` is where a scene's relative paths start, set from its file: a table may not move it (a scene
    reading maps from anywhere it names). Refused as any unknown key; the scene's own folder given apart stands."""
    from raycast_phong.scene.schema import validate_scene
    data = {"render": {"width": 8, "height": 6}, "objects": [{"shape": "plane"}]}
    with pytest.raises(rp.SceneError) as raised:
        validate_scene({**data, "folder": "/etc"}, "t.toml", tmp_path)
    assert str(raised.value) == "t.toml: folder: unknown key"
    assert validate_scene(data, "t.toml", tmp_path).folder == str(tmp_path)


def test_set_spaces_around_the_equals_sign_belong_to_neither_key_nor_value():
    """`--set "render.width = 320"` is `render.width=320`: the key path and the value are stripped (else the key
    is 'width ' and refused as unknown, and a plain string keeps its leading space)."""
    from raycast_phong.scene.overrides import apply_override
    data: dict = {}
    apply_override(data, "render.width = 320")
    apply_override(data, "output.path =  a.png ")
    assert data == {"render": {"width": 320}, "output": {"path": "a.png"}}


def test_an_index_below_a_missing_key_meets_an_empty_list():
    """A key path through a key the scene lacks makes it on the way: a table for a name, an empty list for an
    index, so `lights.0.position` on a scene without lights is the key path's own refusal (the list is empty),
    not a table {'0': ...} that validation calls a wrong type. A name below a missing key makes a table."""
    from raycast_phong.scene.overrides import apply_override
    with pytest.raises(rp.SceneError) as raised:
        apply_override({}, "lights.0.position=[1, 2, 3]")
    assert str(raised.value).endswith("lights.0: lights is a list of 0 items; allowed indices: none, the list is "
                                      "empty"), str(raised.value)
    data: dict = {}
    apply_override(data, "render.width=8")
    assert data == {"render": {"width": 8}}


def test_shaded_sets_every_object_and_the_render_to_one_model():
    """shaded(scene, model), the flat | Gouraud | Phong figure's one scene per model: render.shading and each
    object's own `shading` (which wins over render.shading) are all `model`; the default scene's spheres start
    in three different models, so an object left alone shows as the wrong model."""
    from raycast_phong.codes import ShadingModel
    from raycast_phong.scene.overrides import shaded
    scene = rp.load_scene(rp.default_scene_path())
    assert len({obj.shading for obj in scene.objects}) > 1
    for model in ShadingModel:
        changed = shaded(scene, model)
        assert changed.render.shading == model
        assert [obj.shading for obj in changed.objects] == [model] * len(scene.objects)
        assert len(changed.objects) == len(scene.objects) and changed.lights == scene.lights
