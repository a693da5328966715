"""An object's keys are its kind's (scene.objects: one model per kind of the registry, told apart by `shape`):
the lines for a key of the wrong kind, a missing or unknown shape and an unknown key, and scene files written
by earlier versions, which held every key of every shape."""

from __future__ import annotations

import pickle

import pytest

import raycast_phong as rp
from raycast_phong.errors import SceneError
from raycast_phong.scene.objects import OBJECT_MODELS


def refused(*objects) -> str:
    with pytest.raises(SceneError) as error:
        rp.validate_scene({"objects": list(objects)}, source="s.toml")
    return str(error.value)


@pytest.mark.parametrize(("obj", "line"), [
    ({"shape": "box", "height": 3}, 'objects.0.height: does not apply to shape = "box" (height is a key of cylinder); '
                                    "a box reads size besides the keys of every object; remove it"),
    ({"shape": "icosphere", "segments": [8, 8]},
     'objects.0.segments: does not apply to shape = "icosphere" (segments is a key of uv_sphere, plane, cylinder and '
     "torus); an icosphere reads radius, subdivisions besides the keys of every object; remove it"),
    ({"shape": "mesh", "path": "a.obj", "radius": 2}, 'objects.0.radius: does not apply to shape = "mesh" (radius is a '
     "key of icosphere, uv_sphere and cylinder); a mesh reads path besides the keys of every object; remove it"),
    # pydantic's check of the value would have come first: the key itself is the mistake
    ({"shape": "box", "radius": True}, 'objects.0.radius: does not apply to shape = "box" (radius is a key of '
                                       "icosphere, uv_sphere and cylinder); a box reads size besides the keys of "
                                       "every object; remove it"),
])
def test_a_key_of_another_kind_names_the_kinds_that_read_it(obj, line):
    assert refused(obj) == f"s.toml: {line}"


def test_a_kinds_own_key_is_checked_with_its_own_bounds_and_named():
    assert refused({"shape": "box", "size": [1, 2]}) == ("s.toml: objects.0.size: must be 3 numbers [x, y, z], each in "
                                                         "(0, 1e+18], got [1.0, 2.0]")
    assert refused({"shape": "plane", "size": [1, 0]}) == ("s.toml: objects.0.size: must be 2 numbers [width, depth], "
                                                           "each in (0, 1e+18], got [1.0, 0.0]")
    assert refused({"shape": "torus", "minor_radius": 0}) == ("s.toml: objects.0.minor_radius: out of range; allowed: "
                                                              "0.0 < minor_radius ≤ 1e+18 (got 0)")
    assert refused({"shape": "box", "normals": "file"}) == ('s.toml: objects.0.normals: normals = "file" needs a mesh '
                                                            'file; shape = "box" has no stored normals')


def test_the_shape_key_is_worded_as_a_choice_of_the_registrys_kinds():
    kinds = "'icosphere', 'uv_sphere', 'box', 'plane', 'cylinder', 'torus'"
    assert refused({"radius": 1}) == f"s.toml: objects.0.shape: this key is required; allowed: {kinds}, 'mesh'"
    assert refused({"shape": "box"}, {"shape": "cone"}) == (f"s.toml: objects.1.shape: Input should be {kinds} or "
                                                            "'mesh' (got the string 'cone')")
    assert refused({"shape": 3}).endswith("or 'mesh' (got 3)")
    assert refused(3) == "s.toml: objects.0: must be a table of keys (got 3)"


def test_an_unknown_key_lists_the_keys_of_the_objects_kind():
    assert refused({"shape": "cylinder", "hieght": 1}) == (
        "s.toml: objects.0.hieght: unknown key (did you mean 'height'?); valid keys here: name, shape, radius, height, "
        "segments, material, shading, normals, crease_angle, translate, rotate, scale")


def test_a_scene_written_with_every_key_of_every_shape_still_reads():
    """An earlier version wrote each object with every key of every shape at its default (model_dump): those
    keys are dropped, the object keeps its own, and the same keys set otherwise are refused."""
    every = {"subdivisions": 2, "radius": 1.0, "height": 2.0, "major_radius": 1.0, "minor_radius": 0.25,
             "material": "default", "crease_angle": 180.0, "translate": [0.0, 0.0, 0.0], "rotate": [0.0, 0.0, 0.0],
             "scale": [1.0, 1.0, 1.0]}
    objects = [{"shape": "box", **every, "size": [1.0, 2.0, 3.0]}, {"shape": "plane", **every},
               {"shape": "torus", **every, "minor_radius": 0.5}, {"shape": "mesh", **every, "path": "a.obj"}]
    scene = rp.validate_scene({"objects": objects}, source="s.toml")
    assert [type(obj).__name__ for obj in scene.objects] == ["Box", "Plane", "Torus", "Mesh"]
    assert scene.objects[0].size == (1.0, 2.0, 3.0) and scene.objects[2].minor_radius == 0.5
    assert "radius" not in scene.objects[0].model_fields_set and not hasattr(scene.objects[0], "radius")
    assert "does not apply" in refused({"shape": "box", **every, "subdivisions": 3})


def test_a_scene_pickles_with_its_kinds_models():
    """The kinds' models are made from the registry, and each is a name of scene.objects, as pickle needs."""
    scene = rp.validate_scene({"objects": [{"shape": kind} for kind in OBJECT_MODELS if kind != "mesh"]})
    assert pickle.loads(pickle.dumps(scene)) == scene
