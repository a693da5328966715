"""The JSON Schema (docs/scene.schema.json, `raycast-phong schema`) accepts what the loader accepts.

Every shipped scene passes both. Then every key of the format, in every table and every kind of object, is set to
values at and past its bounds, of the wrong type and in the documented shorthands: where the schema refuses, the
loader refuses; where the loader refuses and the schema does not, the loader's line is one of the checks no JSON
Schema can state (scene.schema.BEYOND_THE_SCHEMA: a vector's length, one key against another). An editor marks the
schema's errors where their paths point: a wrong key of an [[objects]] entry at that key, not at the whole entry.
"""

from __future__ import annotations

import copy
import json
import math
import sys
import tomllib
from pathlib import Path

import jsonschema
import pytest

import raycast_phong as rp
from raycast_phong.scene.objects import OBJECT_MODELS, OWN_KEYS
from raycast_phong.scene.schema import BEYOND_THE_SCHEMA, scene_json_schema

ROOT = Path(__file__).resolve().parents[2]
SCHEMA = scene_json_schema()
VALIDATOR = jsonschema.Draft202012Validator(SCHEMA)
SHIPPED = sorted((ROOT / "scenes").rglob("*.toml"))

# Values at and past the format's bounds (±1e18 positions, [0, 1] coefficients, 1e38 intensities, 3..4096 segments,
# 0..8 subdivisions, 1..16384 pixels, (0, 180) degrees), of the wrong type, and in the shorthands.
VALUES = [0, -0.0, 1e-9, -1e-9, 0.5, 1, 1.0000001, 2, -1, 3, 8, 9, 16, 17, 179.9, 180, 180.1, 4096, 4097, 16384, 16385,
          1e18, 1.01e18, -1.01e18, 1e38, 1.01e38, 1e39, 2.5, "text", "", True, None, [], [1], [1, 2], [3, 3], [2, 4097],
          [3, 2], [2.0, 3.0], [1, 2, 3], [0.5, 0.5, 0.5], [-0.1, 0.5, 0.5], [1.5, 0.5, 0.5], [0, 0, 0], [0, 1, 0],
          [1e18, 0, 0], [1.01e18, 0, 0], [0, 0, 1e39], [1, 2, 3, 4], ["a", "b", "c"], {"path": "t.png"},
          {"path": "t.png", "wrap": "clamp"}, {"path": "t.png", "wrap": "spiral"}, {"wrap": "clamp"}, "t.png",
          "flat", "blinn", "global", "infinite", "float64", "screen", "linear", "none", "inverse_square",
          "directional", "orthographic", "angle", "file", "exact", "out.exr", "out.PNG", "out.jpg", ["depth"],
          ["depth", "glow"], [1, 0.5, 0.25], [0, 0, 1e38]]
# A line of the loader for each check in BEYOND_THE_SCHEMA: what the schema may accept and the loader refuse.
BEYOND = ("allowed: 1e-150 ≤ length", "the zero vector", "direction is the zero vector", "is parallel to",
          "is the camera position too", "from camera.position", "is not defined", "rays per frame",
          "a pixel channel could reach", "shininess: must be a number, got None")


def base(shape: str = "icosphere") -> dict:
    """A valid scene with every table, a light of each type, a material and one object of `shape`."""
    return {"ambient": 0.1, "render": {"width": 8, "height": 6}, "camera": {},
            "lights": [{"type": "point", "position": [2, 3, 4]}, {"type": "directional", "direction": [0, -1, 0]}],
            "materials": {"m": {"kd": [0.5, 0.5, 0.5]}},
            "objects": [{"shape": shape, **({"path": "a.obj"} if shape == "mesh" else {}), "material": "m"}],
            "output": {}}


def keys() -> list[tuple[str, tuple]]:
    """Every key of the format as (the object's shape, a path into base(shape)): each table's keys from the schema,
    a map's own keys, each kind's own keys on an object of that kind, and on an icosphere and a box the keys every
    object has and every other kind's keys."""
    defs = SCHEMA["$defs"]
    found = [("ambient",)]
    for table in ("render", "camera", "output"):
        found += [(table, key) for key in defs[table.title()]["properties"]]
    found += [("lights", index, key) for index in (0, 1) for key in defs["Light"]["properties"]]
    found += [("materials", "m", key) for key in defs["Material"]["properties"]]
    found += [("materials", "m", "kd_map", key) for key in defs["TextureMap"]["properties"]]
    found = [("icosphere", path) for path in found]
    every = sorted({key for model in OBJECT_MODELS.values() for key in model.model_fields})
    found += [(shape, ("objects", 0, key)) for shape in ("icosphere", "box") for key in every]
    found += [(shape, ("objects", 0, key)) for shape in OBJECT_MODELS if shape not in ("icosphere", "box")
              for key in OWN_KEYS[shape]]
    return found


def with_value(scene: dict, path: tuple, value) -> dict:
    changed = copy.deepcopy(scene)
    table = changed
    for part in path[:-1]:
        table = table.setdefault(part, {}) if isinstance(table, dict) else table[part]
    table[path[-1]] = copy.deepcopy(value)
    return changed


def loader_line(scene: dict) -> str | None:
    """None if the loader accepts the scene, else its one line."""
    try:
        rp.validate_scene(scene, source="s.json")
    except rp.SceneError as error:
        return str(error)
    return None


def test_the_schema_is_a_valid_draft_2020_12_schema_with_a_description_per_key():
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    assert SCHEMA["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    for name, table in SCHEMA["$defs"].items():
        for key, node in table.get("properties", {}).items():
            assert node.get("description"), f"{name}.{key} has no description"
    for key, node in SCHEMA["properties"].items():
        assert node.get("description") or "$ref" in node, key
    assert all(line in SCHEMA["$comment"] for line in BEYOND_THE_SCHEMA)
    raw = [word for word in ("gt", "ge", "lt", "le") if f'"{word}":' in json.dumps(SCHEMA)]
    assert not raw, f"pydantic's own bounds keywords, which JSON Schema does not know: {raw}"


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_every_shipped_scene_passes_the_schema_and_the_loader(path):
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    assert [error.message for error in VALIDATOR.iter_errors(data)] == []
    assert loader_line(data) is None


def test_the_schema_and_the_loader_agree_on_every_key_past_its_bounds():
    """For each key × value: schema refuses ⇒ loader refuses; loader refuses ⇒ schema refuses, or the loader's
    line is a check beyond the schema. Both accept the base scene, and many of the values (the test counts)."""
    both = {"accepted": 0, "refused": 0, "beyond": 0}
    wrong = []
    for shape, path in keys():
        scene = base(shape)
        assert VALIDATOR.is_valid(scene) and loader_line(scene) is None
        for value in VALUES:
            changed = with_value(scene, path, value)
            valid, line = VALIDATOR.is_valid(changed), loader_line(changed)
            if valid and line is None:
                both["accepted"] += 1
            elif not valid and line is not None:
                both["refused"] += 1
            elif valid and any(words in line for words in BEYOND):
                both["beyond"] += 1
            else:
                wrong.append(f"{'.'.join(map(str, path))} = {json.dumps(value)}: schema "
                             f"{'accepts' if valid else 'refuses'}, loader {line or 'accepts'}")
    assert not wrong, "\n".join(wrong[:40]) + f"\n({len(wrong)} in all)"
    assert both["accepted"] > 400 and both["refused"] > 3000 and both["beyond"] > 0, both


@pytest.mark.parametrize(("path", "value"), [
    (("ambient",), 0.2), (("lights", 0, "diffuse"), 1), (("objects", 0, "scale"), 2.0),  # one number for three
    (("materials", "m", "kd_map"), "t.png"), (("materials", "m", "kd_map"), {"path": "t.png", "wrap": "mirror"}),
    (("objects", 0, "subdivisions"), 2), (("objects", 0, "subdivisions"), 8),
])
def test_the_documented_shorthands_pass_both(path, value):
    changed = with_value(base(), path, value)
    assert VALIDATOR.is_valid(changed) and loader_line(changed) is None


def test_another_kinds_key_at_its_default_passes_both():
    """A file written by an earlier version held every key of every shape at its default."""
    changed = with_value(base("box"), ("objects", 0, "subdivisions"), 2)
    assert VALIDATOR.is_valid(changed) and loader_line(changed) is None


@pytest.mark.parametrize(("path", "value"), [
    (("materials", "m", "kd"), [1.7, 0.5, 0.5]), (("materials", "m", "ks"), -0.1), (("render", "width"), 0),
    (("objects", 0, "subdivisions"), 9), (("objects", 0, "segments"), [2, 8]), (("objects", 0, "radius"), 0),
    (("lights", 0, "attenuation"), [0, 0, 0]), (("output",), {"path": "o.png", "aovs": ["depth"]}),
    (("lights", 1, "direction"), None), (("objects", 0, "normals"), "file"),
])
def test_values_past_the_bounds_fail_both(path, value):
    changed = with_value(base(), path, value)
    assert not VALIDATOR.is_valid(changed) and loader_line(changed) is not None


@pytest.mark.parametrize(("shape", "path", "value"), [("box", ("objects", 0, "subdivisions"), 3),
                                                      ("mesh", ("objects", 0, "path"), ""),
                                                      ("mesh", ("objects", 0, "normals"), "exact")])
def test_an_objects_keys_past_their_kinds_rules_fail_both(shape, path, value):
    changed = with_value(base(shape), path, value)
    assert not VALIDATOR.is_valid(changed) and loader_line(changed) is not None


def error_paths(scene: dict) -> set[tuple]:
    """Where the schema's errors for `scene` point: the keys an editor marks."""
    return {tuple(error.absolute_path) for error in VALIDATOR.iter_errors(scene)}


@pytest.mark.parametrize("shape", ["icosphere", "uv_sphere"])
def test_a_spheres_radius_out_of_range_is_reported_at_radius(shape):
    changed = with_value(base(shape), ("objects", 0, "radius"), -1)
    assert error_paths(changed) == {("objects", 0, "radius")}
    best = jsonschema.exceptions.best_match(VALIDATOR.iter_errors(changed))
    assert tuple(best.absolute_path) == ("objects", 0, "radius") and "-1" in best.message
    assert "s.json: objects.0.radius: " in loader_line(changed)


def test_an_unknown_shape_is_reported_at_shape():
    changed = with_value(base(), ("objects", 0, "shape"), "sphere")
    assert error_paths(changed) == {("objects", 0, "shape")}
    best = jsonschema.exceptions.best_match(VALIDATOR.iter_errors(changed))
    assert "'sphere' is not one of" in best.message and all(f"'{shape}'" in best.message for shape in OBJECT_MODELS)
    assert "s.json: objects.0.shape: " in loader_line(changed)


@pytest.mark.parametrize(("shape", "key"), [(shape, key) for shape, own in OWN_KEYS.items() for key in own])
def test_a_wrong_type_in_a_kinds_own_key_is_reported_at_that_key(shape, key):
    changed = with_value(base(shape), ("objects", 0, key), True)  # true where a number, a list or a file belongs
    assert error_paths(changed) == {("objects", 0, key)}
    assert f"s.json: objects.0.{key}: " in loader_line(changed)


def test_every_refused_value_of_an_objects_key_is_reported_at_that_key():
    """keys() × VALUES on the objects: wherever the schema refuses, each of its errors is at the key set."""
    wrong = []
    for shape, path in keys():
        if path[0] != "objects":
            continue
        for value in VALUES:
            paths = error_paths(with_value(base(shape), path, value))
            if paths - {path}:
                wrong.append(f"{shape}: {'.'.join(map(str, path))} = {json.dumps(value)}: errors at {sorted(paths)}")
    assert not wrong, "\n".join(wrong[:40]) + f"\n({len(wrong)} in all)"


MIRROR = """[materials.mirror]
shininess = inf

[[objects]]
shape = "icosphere"
material = "mirror"
"""


def test_shininess_inf_passes_the_schema_as_it_loads(tmp_path):
    """The documented mirror limit: a float inf as tomllib gives it, and null as taplo (Even Better TOML) hands it to
    its validator, its serde_json having no inf."""
    path = tmp_path / "mirror.toml"
    path.write_text(MIRROR, encoding="utf-8")
    data = tomllib.loads(MIRROR)
    assert data["materials"]["mirror"]["shininess"] == math.inf
    assert [error.message for error in VALIDATOR.iter_errors(data)] == []
    assert rp.load_scene(path).materials["mirror"].shininess == math.inf
    assert VALIDATOR.is_valid(with_value(data, ("materials", "mirror", "shininess"), None))


@pytest.mark.parametrize("value", [1.01e38, sys.float_info.max, -math.inf])
def test_shininess_finite_past_1e38_or_minus_inf_fails_both(value):
    changed = with_value(base(), ("materials", "m", "shininess"), value)
    assert error_paths(changed) == {("materials", "m", "shininess")}
    assert "s.json: materials.m.shininess: " in loader_line(changed)


def documented_keys() -> dict[str, set[str]]:
    """The keys in the first column of each key table of docs/scene-format.md, by section (render, camera, lights,
    materials, objects, output): `width`, `height` in one cell are two keys."""
    import re
    found: dict[str, set[str]] = {}
    section = None
    for line in (ROOT / "docs" / "scene-format.md").read_text(encoding="utf-8").splitlines():
        heading = re.match(r"## `\[+(\w+)(?:\.NAME)?\]+`", line)
        if heading or line.startswith("## "):
            section = heading[1] if heading else None
        elif section and line.startswith("| `"):
            found.setdefault(section, set()).update(re.findall(r"`(\w+)`", line.split("|")[1]))
    return found


def test_the_key_tables_of_scene_format_md_list_exactly_the_models_keys():
    """docs/scene-format.md's tables are written by hand; this holds them to the models the loader and the schema
    are made of: every key in its table, no key that is not one (issue 32)."""
    from raycast_phong.scene.schema import Scene
    defs = SCHEMA["$defs"]
    every_object = {key for model in OBJECT_MODELS.values() for key in model.model_fields}
    models = {"render": set(defs["Render"]["properties"]), "camera": set(defs["Camera"]["properties"]),
              "lights": set(defs["Light"]["properties"]), "output": set(defs["Output"]["properties"]),
              "materials": set(defs["Material"]["properties"]), "objects": every_object}
    assert documented_keys() == models
    assert set(Scene.model_fields) - {"folder"} == {*models, "ambient"}
