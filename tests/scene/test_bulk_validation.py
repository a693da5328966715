"""Many objects validated a key at a time (scene.bulk.objects_in_bulk): the same objects and the same one-line
errors as pydantic gives one object at a time, and no object left to pydantic that it need not see."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import raycast_phong as rp
from raycast_phong.errors import SceneError
from raycast_phong.scene import bulk, schema
from raycast_phong.scene.objects import OBJECT_MODELS, OWN_KEYS
from raycast_phong.shapes import MESH
from raycast_phong.tolerances import POSITION_LIMIT

INF, NAN = math.inf, math.nan
LENGTH = [1, 0.5, 0, -1, 1e18, 2e18, INF, NAN, True, "1", None, 10**400, -0.0]
TRIPLE = [[1, 2, 3], (1, 2.5, 3), 2, -0.0, [0, 1, 1], [1e18, 0, 0], [1.1e18, 0, 0], [INF, 0, 0], [NAN, 1, 1],
          [1, 2], [1, 2, 3, 4], "x", True, [1, "2", 3], [True, 1, 1], 10**400, [10**400, 0, 0], [-1e18, 1, 1],
          None, {"x": 1}, [2**60 + 1, 1, 1]]
VALUES = {
    "shape": ["box", "plane", "icosphere", "uv_sphere", "cylinder", "torus", "mesh", "Box", 3, None],
    "size": [[1, 2, 3], [1, 2], [0.1, 0.1, 0.1], [0, 1, 1], [1e19, 1, 1], [1, 2, 3, 4], None, "a", [True, 1, 1], 5,
             [NAN, 1, 1], (2, 3), [INF, 1]],
    "translate": TRIPLE, "rotate": TRIPLE, "scale": TRIPLE,
    "radius": LENGTH, "height": LENGTH, "major_radius": LENGTH, "minor_radius": LENGTH,
    "crease_angle": [0, 180, 180.5, -0.0, 30, INF, NAN, True, "30", -1],
    "subdivisions": [0, 8, 9, -1, 2.0, True, "2", 10**30, None],
    "segments": [[3, 3], [2, 3], [3, 4096], [3, 4097], [3.0, 3], None, [3], "a", (8, 8), [True, 4]],
    "name": ["a", None, 3, "", "\x07"],
    "material": ["default", "m", "x", None, 3],
    "shading": ["flat", "phong", "gouraud", "Phong", None, 3],
    "normals": ["mean", "area", "angle", "exact", "file", None, "x"],
    "path": ["a.obj", None],
    "colour": ["red"],  # an unknown key
}


def outcome(data: dict) -> tuple:
    """What validating `data` gives: each object's values with their types and its set fields, or the line."""
    try:
        scene = rp.validate_scene(data, source="s.json")
    except SceneError as error:
        return ("error", str(error))
    return ("scene", [(repr(obj.__dict__), sorted(obj.model_fields_set)) for obj in scene.objects],
            scene.model_dump_json())


def one_at_a_time(data: dict) -> tuple:
    """The same through pydantic alone, as before objects_in_bulk."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(schema, "objects_in_bulk", lambda objects: objects)
        return outcome(data)


GOOD = {"size": [[1, 2, 3], [0.1, 0.1, 0.1], (2, 3), [1, 2]], "translate": [[1, 2, 3], (1, 2.5, 3), 2, -0.0,
        [1e18, 0, 0], [-1e18, 1, 1], [2**60 + 1, 1, 1]], "rotate": [[1, 2, 3], 2, -0.0, [0, 1, 1], [1.1e18, 0, 0]],
        "scale": [[1, 2, 3], -2, [1e18, -1, 1e-300]], "radius": [1, 0.5, 1e18, 2**60 + 1],
        "crease_angle": [0, 180, -0.0, 30.5], "subdivisions": [0, 1, 8, 2.0], "segments": [[3, 3], (8, 4096), [3.0, 3]],
        "name": ["a", None, ""], "material": ["default", "m"], "shading": ["flat", "phong", "gouraud", None],
        "normals": ["mean", "area", "angle", "exact", None]}
GOOD |= {"height": GOOD["radius"], "major_radius": GOOD["radius"], "minor_radius": GOOD["radius"]}
# Good for pydantic but left to it by the bulk path (2.0 as a whole number; a numpy array from Python): rows of
# one group that go both ways
GOOD["translate"] = GOOD["translate"] + [np.array([1.0, 2.0, 3.0])]


@st.composite
def objects(draw) -> dict:
    """Mostly valid objects (each key its shape reads, with a good value), some with one value of any kind."""
    shape = draw(st.sampled_from(VALUES["shape"][:6]))
    keys = ["translate", "rotate", "scale", "name", "material", "shading", "normals", "crease_angle",
            *OWN_KEYS[shape]]
    obj = {"shape": shape}
    for key in draw(st.lists(st.sampled_from(keys), max_size=5, unique=True)):
        obj[key] = draw(st.sampled_from(GOOD[key]))
    if draw(st.booleans()):
        key = draw(st.sampled_from(sorted(VALUES)))
        obj[key] = draw(st.sampled_from(VALUES[key]))
    return obj


@st.composite
def group(draw) -> list[dict]:
    """Objects that share one shape and one set of keys (one bulk group), each key's value drawn per object:
    mostly good, some of any kind, so good and bad rows of one column meet."""
    shape = draw(st.sampled_from(VALUES["shape"][:6]))
    keys = draw(st.lists(st.sampled_from(["translate", "rotate", "scale", "name", "material", "shading", "normals",
                                          "crease_angle", *OWN_KEYS[shape]]), max_size=5, unique=True))
    rows = []
    for _ in range(draw(st.integers(1, 6))):
        rows.append({"shape": shape, **{key: draw(st.sampled_from(GOOD[key] if draw(st.integers(0, 3))
                                                                  else VALUES[key])) for key in keys}})
    return rows


@settings(max_examples=300, deadline=None)
@given(rows=group())
def test_good_and_bad_rows_of_one_group_are_what_pydantic_gives(rows):
    data = {"materials": {"m": {}}, "objects": rows}
    assert outcome(data) == one_at_a_time(data)


@settings(max_examples=400, deadline=None)
@given(templates=st.lists(objects(), min_size=1, max_size=4), picks=st.lists(st.integers(0, 3), min_size=1, max_size=8))
def test_bulk_gives_what_pydantic_gives_one_object_at_a_time(templates, picks):
    """Any mix of good and bad values, repeated so that objects share their keys (a group): the Objects
    (every value with its type: 2 → 2.0, "phong" → ShadingModel.PHONG, -0.0 kept) and their set fields are
    pydantic's, and so is the error line naming the object's index and key."""
    data = {"materials": {"m": {}}, "objects": [dict(templates[i % len(templates)]) for i in picks]}
    assert outcome(data) == one_at_a_time(data)


@pytest.mark.parametrize("key, value", [("translate", [1, "2", 3]), ("radius", 0), ("scale", [0, 1, 1]),
                                        ("size", [1, 2]), ("size", [0, 1, 1]), ("size", [1, 1, 2e18]),
                                        ("material", "nowhere"), ("radius", 10**400),
                                        ("segments", [3, 4097]), ("shading", "Phong")])
def test_an_error_in_the_last_of_many_objects_is_the_same_line(key, value):
    """One bad value in object 9,999 of 10,000 boxes: the line names that object and key, word for word as
    before (the other rows of the group pass in bulk)."""
    boxes = [{"shape": "box", "size": [0.1, 0.1, 0.1], "translate": [i, 0, 0], key: value} for i in range(10_000)]
    for box in boxes[:-1]:
        box[key] = {"translate": [1, 2, 3], "radius": 1, "scale": 1, "size": [1, 1, 1], "material": "default",
                    "segments": [3, 3], "shading": "phong"}[key]
    if key in ("radius", "segments"):
        for box in boxes:
            box["shape"] = "uv_sphere" if key == "segments" else "icosphere"
            del box["size"]
    data = {"objects": boxes}
    found = outcome(data)
    assert found == one_at_a_time(data)
    assert found[0] == "error" and "objects.9999" in found[1], found


def test_valid_objects_do_not_go_through_pydantic_one_at_a_time():
    """Every valid object of a group comes back its kind's model (made from the column checks), every invalid
    one as it was, for pydantic to word: validating 10⁶ objects one at a time took 12 s."""
    rows = [{"shape": "box", "translate": [i, 0, 0]} for i in range(1000)] + [{"shape": "box", "translate": "x"}]
    rows += [{"shape": "torus", "major_radius": 2, "segments": [8, 4]}] * 3
    made = bulk.objects_in_bulk(rows)
    assert all(isinstance(obj, OBJECT_MODELS["box"]) for obj in made[:1000])
    assert made[1000] is rows[1000]
    assert made[0] == OBJECT_MODELS["box"](shape="box", translate=[0, 0, 0])
    assert made[-1] == OBJECT_MODELS["torus"](shape="torus", major_radius=2.0, segments=(8, 4))


def test_every_object_key_is_checked_in_bulk_or_left_to_pydantic():
    """One validator's rules: for each built-in kind, bulk checking knows every key of its model or names it as
    pydantic's alone (a mesh file is pydantic's), and the bounds it applies are read from the fields' own
    Field(...) (a bound changed there changes both): at each bound, and past it, it accepts what pydantic does."""
    assert set(bulk.PLANS) == set(OBJECT_MODELS) - {MESH.name}
    for shape, plan in bulk.PLANS.items():
        left = bulk.LEFT_TO_PYDANTIC.get(shape, frozenset())
        assert set(OBJECT_MODELS[shape].model_fields) == set(plan) | left and not set(plan) & left, shape
    fields = OBJECT_MODELS["icosphere"].model_fields
    assert bulk.bounds(fields["crease_angle"].metadata)[:3] == (0.0, True, 180.0)
    assert bulk.bounds(fields["subdivisions"].metadata)[:3] == (0, True, 8)
    assert bulk.bounds(fields["radius"].metadata) == (0.0, False, POSITION_LIMIT, False)
    checked = 0
    for shape in bulk.PLANS:
        for key, field in OBJECT_MODELS[shape].model_fields.items():
            if field.annotation not in (int, float):
                continue
            low, allowed, high, _ = bulk.bounds(field.metadata)
            for value, ok in ((low, allowed), (high, True), (high * 2 if high > 0 else 1, False)):
                value = int(value) if field.annotation is int else float(value)
                row = {"shape": shape, key: value}
                made = bulk._build_group(shape, tuple(row), [row])[0] is not None
                try:
                    OBJECT_MODELS[shape].model_validate(row)
                    single = True
                except Exception:  # noqa: BLE001 - pydantic's refusal
                    single = False
                assert made == single == ok, (shape, key, value, field.metadata)
                checked += 1
    assert checked >= 3 * 9  # crease_angle of each kind, radius (3 kinds), subdivisions, height, the torus' two
