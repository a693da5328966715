"""A scene of many built-in objects: objects that share a shape are built once and placed together
(geometry.build's groups), with the same bits as each object built alone, and errors still name the object."""

from __future__ import annotations

import numpy as np
import pytest

import raycast_phong as rp
import raycast_phong.geometry.build as build
import raycast_phong.geometry.templates as templates

LIGHT = {"type": "point", "position": [5, 6, 7]}
MIXED = [  # shapes, rotations, scales (one mirroring), normal rules and creases, repeated so groups form
    {"shape": "box", "size": [1, 2, 3], "translate": [1, 0, 0]},
    {"shape": "icosphere", "subdivisions": 1, "rotate": [10, 20, 30], "scale": [1, 2, 1]},
    {"shape": "box", "size": [1, 2, 3], "rotate": [0, 45, 0], "scale": [-1, 1, 1], "translate": [0, 3, 0]},
    {"shape": "torus", "segments": [8, 6], "normals": "exact", "rotate": [90, 0, 0], "scale": [2, 2, 2]},
    {"shape": "icosphere", "subdivisions": 1, "translate": [4, 4, 4], "shading": "flat"},
    {"shape": "cylinder", "segments": [7, 3], "crease_angle": 30, "rotate": [5, 5, 5]},
    {"shape": "torus", "segments": [8, 6], "normals": "exact", "scale": [1, -1, 1], "translate": [-3, 0, 0]},
    {"shape": "plane", "segments": [3, 4], "rotate": [0, 0, 33]},
    {"shape": "cylinder", "segments": [7, 3], "crease_angle": 30, "translate": [0, -4, 0], "material": "red"},
]


def scene_of(objects: list[dict]) -> rp.Scene:
    return rp.validate_scene({"lights": [LIGHT], "objects": objects, "materials": {"red": {"kd": [1, 0, 0]}}})


def test_a_group_gives_every_object_the_bits_it_has_alone():
    """The scene's mesh equals its objects built one scene at a time and concatenated: vertices, faces, face
    and corner normals bit for bit, materials and models per face (a batched placement must not round
    differently from a single one)."""
    together = build.build_geometry(scene_of(MIXED))
    alone = [build.build_geometry(scene_of([obj])) for obj in MIXED]
    offsets = np.cumsum([0] + [len(g.vertices) for g in alone])
    np.testing.assert_array_equal(together.vertices, np.concatenate([g.vertices for g in alone]))
    np.testing.assert_array_equal(together.faces, np.concatenate([g.faces + o for g, o in zip(alone, offsets)]))
    np.testing.assert_array_equal(together.face_normals, np.concatenate([g.face_normals for g in alone]))
    np.testing.assert_array_equal(together.corner_normals, np.concatenate([g.corner_normals for g in alone]))
    np.testing.assert_array_equal(together.face_model, np.concatenate([g.face_model for g in alone]))
    np.testing.assert_array_equal(together.face_object, np.repeat(np.arange(len(MIXED)), [g.triangles for g in alone]))
    red = together.face_material[together.face_object == 8]
    assert (red == 1).all() and (together.face_material[together.face_object != 8] == 0).all()


def test_objects_that_share_a_shape_are_built_once(monkeypatch):
    """Ten thousand boxes of two sizes cost two shape builds, not ten thousand (positive control: two
    different sizes are two builds), and each group of consecutive boxes lands where the scene puts it."""
    calls = []
    original = templates.object_mesh
    monkeypatch.setattr(templates, "object_mesh", lambda *a, **k: calls.append(a[1]) or original(*a, **k))
    rng = np.random.default_rng(5)
    boxes = [{"shape": "box", "size": [0.1, 0.1, 0.2 if i < 5000 else 0.1], "translate": rng.uniform(-9, 9, 3).tolist(),
              "rotate": [0, float(rng.uniform(0, 90)), 0]} for i in range(10_000)]
    geometry = build.build_geometry(scene_of(boxes))
    assert sorted(calls) == [0, 5000]
    assert geometry.triangles == 12 * len(boxes)
    # Each box is where its scene says: the centroid of its eight corners is its translate.
    centres = geometry.vertices.reshape(len(boxes), 8, 3).mean(axis=1)
    np.testing.assert_allclose(centres, [b["translate"] for b in boxes], atol=1e-12)


@pytest.mark.parametrize("bad, message", [
    ({"translate": [9e17, 0, 0], "scale": [2e17, 1, 1]}, "reaches a coordinate of"),
    ({"scale": [1e-300, 1e-300, 1e-300], "translate": [1e10, 1e10, 1e10]}, "collapses to a single point"),
])
def test_an_error_in_a_group_names_its_object(bad, message):
    objects = [{"shape": "box", "translate": [i, 0, 0]} for i in range(50)]
    objects[37] = {**objects[37], **bad}
    with pytest.raises(rp.SceneError, match=rf"objects\.37: placed.*{message}"):
        build.build_geometry(scene_of(objects))


def test_objects_that_differ_only_in_placement_are_one_set_of_alike_objects():
    """scene/alike.py: sets numbered in the order of their first object; name, translate, rotate and scale do
    not make a new set, any other key does; every mesh object is a set of its own."""
    from raycast_phong.scene.alike import alike
    box = {"shape": "box"}
    objects = [box, {**box, "translate": [1, 2, 3], "rotate": [0, 9, 0], "scale": 2, "name": "b"},
               {**box, "material": "red"}, {"shape": "icosphere"}, {**box, "size": [1, 1, 3]},
               {"shape": "mesh", "path": "a.obj"}, {"shape": "mesh", "path": "a.obj"}, {**box, "shading": "flat"},
               {**box, "translate": [5, 5, 5]}]
    sets = alike(scene_of(objects))
    assert sets.of.tolist() == [0, 0, 1, 2, 3, 4, 5, 6, 0]
    assert sets.first.tolist() == [0, 2, 3, 4, 5, 6, 7]
    assert sets.count.tolist() == [3, 1, 1, 1, 1, 1, 1]
    grouped = sets.grouped(np.array([0, 1, 1, 1, 1, 1, 0]))  # sets 0 and 6 one group, the rest another
    assert [g.tolist() for g in grouped] == [[0, 1, 7, 8], [2, 3, 4, 5, 6]]
    assert [o.shape for o in sets.firsts(scene_of(objects).objects)] == ["box", "box", "icosphere", "box", "mesh",
                                                                         "mesh", "box"]


def test_a_scene_of_many_objects_is_decided_once_per_set_of_alike_objects(monkeypatch):
    """The plan, the memory estimate and the geometry look up materials and shading models per set of alike
    objects, not per object: 20,000 boxes of two materials cost the same number of look-ups as 200."""
    from raycast_phong.renderer.budget import estimate_memory
    from raycast_phong.renderer.diagnosis import diagnose
    from raycast_phong.renderer.plan import build_plan
    counted = {"material_of": 0, "shading_of": 0}
    for name in counted:
        original = getattr(rp.Scene, name)
        monkeypatch.setattr(rp.Scene, name, lambda self, obj, name=name, original=original:
                            counted.__setitem__(name, counted[name] + 1) or original(self, obj))

    def look_ups(count: int) -> dict:
        boxes = [{"shape": "box", "size": [0.1, 0.1, 0.1], "translate": [i % 100, i // 100, 0],
                  "material": "red" if i % 2 else "default", "rotate": [0, i % 90, 0]} for i in range(count)]
        scene = scene_of(boxes)
        for name in counted:
            counted[name] = 0
        geometry = build.build_geometry(scene)
        estimate_memory(scene)
        diagnose(build_plan(scene), scene, geometry)
        return dict(counted)

    few, many = look_ups(200), look_ups(20_000)
    assert few == many and 0 < sum(many.values()) < 40


def test_a_group_of_textured_objects_gives_each_its_own_corner_uvs(tmp_path):
    """Per-corner texture coordinates of a group follow each object's winding: a mirrored object's faces are
    reversed, so are its corners' UVs; the whole equals the objects built alone and concatenated."""
    import OpenImageIO as oiio
    image = str(tmp_path / "map.png")
    out = oiio.ImageOutput.create(image)
    assert out.open(image, oiio.ImageSpec(2, 2, 3, "uint8")) and out.write_image(np.full((2, 2, 3), 200, np.uint8))
    assert out.close()
    objects = [{"shape": "box", "size": [1, 2, 3], "translate": [3 * i, 0, 0], "material": "map",
                "scale": [-1, 1, 1] if i % 3 == 1 else [1, 1, 1], "rotate": [0, 10 * i, 0]} for i in range(7)]

    def scene(objects):
        return rp.validate_scene({"lights": [LIGHT], "objects": objects, "materials": {"map": {"kd_map": "map.png"}}},
                                 folder=tmp_path)

    together = build.build_geometry(scene(objects))
    alone = [build.build_geometry(scene([obj])) for obj in objects]
    assert len(together.corner_uv) == len(together.faces)
    np.testing.assert_array_equal(together.corner_uv, np.concatenate([g.corner_uv for g in alone]))
    assert not np.array_equal(alone[0].corner_uv, alone[1].corner_uv)  # the mirrored box's corners are reversed
