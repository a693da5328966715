"""Fuzzing: scenes generated from the scene's JSON Schema, with extreme and hostile values, through the real CLI.

The contract for any input: exit 0 with a finite, non-negative image of the asked size, or exit 2 with
exactly one line on stderr and the output file untouched; never a traceback, an internal error (exit 1)
or a RuntimeWarning (warnings are errors here, and the CLI would turn one into exit 1).

CI runs a fixed, derandomized set of FUZZ_EXAMPLES examples (a few seconds). Run longer, with fresh
random examples, by setting the number:  RAYCAST_PHONG_FUZZ_EXAMPLES=2000 pytest tests/contracts/test_fuzz.py
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, currently_in_test_context, event, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app
from raycast_phong.scene.schema import scene_json_schema

DEFAULT_EXAMPLES = 40
FUZZ_EXAMPLES = int(os.environ.get("RAYCAST_PHONG_FUZZ_EXAMPLES", DEFAULT_EXAMPLES))
SENTINEL = b"an image the user already has"
runner = CliRunner()

# Numbers at and past every bound the format or float arithmetic has.
EXTREME_NUMBERS = [0, -0.0, 1, -1, 0.5, 1e-320, -1e-320, 5e-324, 1e-150, 1e-160, 1e-12, 1e-13, 1e-300, 1e18,
                   1.0000001e18, -1e18, 1e30, 3.4e38, 3.5e38, 1e38, 1e39, 1e150, 1e200, 1e300, 1e308, -1e308,
                   1.7976931348623157e308, math.inf, -math.inf, math.nan, 2**31, 2**63, -(2**63), 179.9999999,
                   1e-7, 16384, 16385, 65536]
HOSTILE = st.sampled_from(["nan", "inf", "-inf", "1e308", "", "32", "phong ", True, False, None, [], {},
                           [1e308] * 3, ["a", "b", "c"], [[1, 2, 3]], list(range(50)), {"x": 1}])
NUMBERS = st.one_of(st.sampled_from(EXTREME_NUMBERS), *[st.floats(-10, 10, allow_nan=False)] * 4,
                    st.floats(allow_nan=True, allow_infinity=True))
MATERIAL_NAMES = ["default", "m0", "m1", "missing"]
# File names only: a fuzzed path must not reach /dev/zero or a FIFO (another test's business).
MESH_PATHS = ["tri.obj", "missing.obj", "garbage.obj", "", ".", "tri.obj/"]


def hostile_or(strategy: st.SearchStrategy) -> st.SearchStrategy:
    """Mostly `strategy`, now and then (1 in 16) a value of the wrong kind: a scene has dozens of keys, and
    enough of them must be valid together for the example to reach the renderer."""
    return st.one_of(*[strategy] * 15, HOSTILE)


def from_schema(node: dict, defs: dict, key: str = "") -> st.SearchStrategy:
    """Values for a JSON Schema node as pydantic writes them ($ref, anyOf, enum, object, array, number...)."""
    if "$ref" in node:
        return from_schema(defs[node["$ref"].rsplit("/", 1)[1]], defs, key)
    if key == "path":
        return hostile_or(st.sampled_from(MESH_PATHS))
    if key == "material":
        return hostile_or(st.sampled_from(MATERIAL_NAMES))
    if "allOf" in node:  # [[objects]]: one table per kind, an if/then on `shape` each
        return st.one_of([from_schema(part["then"], defs, key) for part in node["allOf"]])
    if "anyOf" in node or "oneOf" in node:
        return st.one_of([from_schema(option, defs, key) for option in node.get("anyOf", node.get("oneOf"))])
    if "const" in node:
        return hostile_or(st.just(node["const"]))
    if "enum" in node:
        return hostile_or(st.sampled_from(node["enum"]))
    kind = node.get("type")
    if kind == "object":
        if "additionalProperties" in node and isinstance(node["additionalProperties"], dict):  # materials
            return hostile_or(st.dictionaries(st.sampled_from(MATERIAL_NAMES[:3]),
                                              from_schema(node["additionalProperties"], defs), max_size=3))
        properties = {name: from_schema(sub, defs, name) for name, sub in node.get("properties", {}).items()}
        return hostile_or(st.fixed_dictionaries({}, optional=properties))
    if kind == "array":
        if "prefixItems" in node:
            items = [from_schema(sub, defs) for sub in node["prefixItems"]]
            exact = st.tuples(*items).map(list)
            # A lone number is a valid triple too; lists of the wrong length or very long ones are not.
            return hostile_or(st.one_of(exact, exact, exact, NUMBERS, st.lists(NUMBERS, max_size=6)))
        item = from_schema(node.get("items", {}), defs)
        if key in ("lights", "objects"):
            return hostile_or(st.lists(item, min_size=0 if key == "lights" else 1, max_size=3))
        return hostile_or(st.lists(item, max_size=4))
    if kind == "number":
        return hostile_or(NUMBERS)
    if kind == "integer":
        return hostile_or(st.one_of(st.integers(-3, 20), st.sampled_from([2**31, -(2**63), 16385, 4097, 0])))
    if kind == "string":
        return hostile_or(st.text(max_size=8))
    if kind == "boolean":
        return hostile_or(st.booleans())
    if kind == "null":
        return st.none()
    return HOSTILE


def affordable(scene: Any) -> Any:
    """Keep a valid scene cheap to render: at most 8×8 pixels, 2×2 samples, ~5k triangles per object.

    Only values the format accepts are shrunk (an out-of-range one must still reach the validator).
    """
    if not isinstance(scene, dict):
        return scene
    render = scene.get("render", scene.setdefault("render", {}))
    if isinstance(render, dict):
        for key, most in (("width", 8), ("height", 8), ("samples", 2)):
            value = render.setdefault(key, most)  # the defaults, 640 × 480, would cost a second
            if isinstance(value, int) and not isinstance(value, bool) and most < value <= 16384:
                render[key] = most
    objects = scene.get("objects")
    for obj in objects if isinstance(objects, list) else ():
        if not isinstance(obj, dict):
            continue
        value = obj.get("subdivisions")
        if isinstance(value, int) and not isinstance(value, bool) and 3 < value <= 8:
            obj["subdivisions"] = 3
        segments = obj.get("segments")
        if isinstance(segments, list):
            obj["segments"] = [min(s, 24) if isinstance(s, int) and not isinstance(s, bool) else s for s in segments]
    return scene


SCHEMA = scene_json_schema()
DEFS = SCHEMA["$defs"]
SCENES = from_schema(SCHEMA, DEFS).map(affordable)


def leaves() -> dict[str, st.SearchStrategy]:
    """Every key of the format as a dotted path into WORKING (first light, first object, material m0), with
    the values the schema allows for it (and hostile ones)."""
    out = {}
    for name, node in SCHEMA["properties"].items():
        if "$ref" in node:
            for key, sub in DEFS[node["$ref"].rsplit("/", 1)[1]]["properties"].items():
                out[f"{name}.{key}"] = from_schema(sub, DEFS, key)
        elif name in ("lights", "objects"):  # every kind's keys for objects: most are another kind's, refused
            for ref in [part["then"]["$ref"] for part in node["items"].get("allOf", [{"then": node["items"]}])]:
                for key, sub in DEFS[ref.rsplit("/", 1)[1]]["properties"].items():
                    strategy = from_schema(sub, DEFS, key)
                    out[f"{name}.0.{key}"] = st.one_of(out[f"{name}.0.{key}"], strategy) \
                        if f"{name}.0.{key}" in out else strategy
        elif name == "materials":
            for key, sub in DEFS["Material"]["properties"].items():
                out[f"materials.m0.{key}"] = from_schema(sub, DEFS, key)
        else:
            out[name] = from_schema(node, DEFS, name)
    return out


LEAVES = leaves()
# A scene that renders: most examples change one to four of its keys, so that hostile values reach the
# later stages (geometry, the BVH, the kernels, the writer) and not only the validator.
WORKING = {"render": {"width": 6, "height": 5}, "lights": [{"position": [2, 2, 3]}],
           "materials": {"m0": {}}, "objects": [{"shape": "icosphere", "subdivisions": 1, "material": "m0"}]}


def set_path(scene: dict, dotted: str, value: Any) -> None:
    *parents, last = [int(p) if p.isdigit() else p for p in dotted.split(".")]
    node: Any = scene
    for part in parents:
        node = node[part] if isinstance(node, list) else node.setdefault(part, {})
    node[last] = value


@st.composite
def scenes(draw) -> Any:
    if draw(st.integers(0, 3)) == 0:
        return draw(SCENES)  # a whole scene from the schema: mostly refused, which is the validator's test
    scene = json.loads(json.dumps(WORKING))
    for key in draw(st.lists(st.sampled_from(sorted(LEAVES)), min_size=1, max_size=4, unique=True)):
        set_path(scene, key, draw(LEAVES[key]))
    # Long lists: 64 lights pass global mode's limit of 63; 30 objects, each cheap.
    for key, many in (("lights", 64), ("objects", 30)):
        if isinstance(scene[key], list):
            scene[key] = scene[key] * draw(st.sampled_from([1, 1, 1, 1, 1, many]))
    return affordable(scene)


def check_contract(folder: Path, scene: Any) -> None:
    """Write `scene` as JSON, render it over an existing out.exr, and check the contract."""
    path = folder / "scene.json"
    path.write_text(json.dumps(scene), encoding="utf-8")  # NaN and Infinity as Python's json writes them
    output = folder / "out.exr"
    output.write_bytes(SENTINEL)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        result = runner.invoke(app, ["render", str(path), "-o", str(output), "-q"], prog_name="raycast-phong")
    stderr = result.stderr.strip()
    shown = f"exit {result.exit_code}\nscene: {json.dumps(scene)[:2000]}\nstderr: {stderr}\n{result.exception!r}"
    assert "Traceback" not in result.output, shown
    assert result.exit_code in (0, 2), shown
    if currently_in_test_context():  # pytest --hypothesis-show-statistics: how many render, how many are refused
        event(f"exit {result.exit_code}")
    if result.exit_code == 2:
        assert len(stderr.splitlines()) == 1 and stderr.startswith("error: "), shown
        assert output.read_bytes() == SENTINEL, shown
        return
    image = rp.read_layer(output)  # RGB; a depth layer is inf where nothing is hit, by design
    loaded = rp.load_scene(path)
    assert image.shape == (loaded.render.height, loaded.render.width, 3), shown
    assert np.isfinite(image).all() and (image >= 0).all(), shown


@pytest.fixture(scope="module")
def folder():
    """One scratch folder for every example (function-scoped fixtures do not mix with @given)."""
    with tempfile.TemporaryDirectory(prefix="raycast-phong-fuzz-") as name:
        path = Path(name)
        (path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", encoding="utf-8")
        (path / "garbage.obj").write_bytes(b"\x00\xff not a mesh \x00" * 8)
        yield path


@settings(max_examples=FUZZ_EXAMPLES, derandomize=FUZZ_EXAMPLES == DEFAULT_EXAMPLES, deadline=None,
          database=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                                HealthCheck.filter_too_much, HealthCheck.function_scoped_fixture])
@pytest.mark.slow
@given(scene=scenes())
def test_any_scene_renders_finitely_or_is_refused_in_one_line(folder, monkeypatch, scene):
    monkeypatch.chdir(folder)
    monkeypatch.delenv("RAYCAST_PHONG_DEBUG", raising=False)
    check_contract(folder, scene)


# Cases the fuzzer found, kept as plain examples so they run even when hypothesis draws other scenes.
FOUND: list[Any] = [
    # The defaults' 640 × 480 with a depth layer (inf on a miss, by design): the contract is on RGB.
    {"render": {}, "lights": [{"position": [2, 2, 3]}], "objects": [{"shape": "icosphere", "subdivisions": 1}],
     "output": {"aovs": ["depth"]}},
    # trimesh's icosphere divided 0 by 0 at radius 1.6e-51 (now built at unit size, then refused as too small).
    {"render": {"width": 6, "height": 5, "samples": 2}, "lights": [{"position": [2, 2, 3]}],
     "objects": [{"shape": "icosphere", "subdivisions": 2, "radius": 1.5784229686664424e-51}]},
    # A shininess past float32 with ks = 0 (so no float64 shading) overflowed the material table's cast.
    {"render": {"width": 6, "height": 5, "samples": 2}, "lights": [{"position": [2, 2, 3]}], "ambient": 0,
     "materials": {"m0": {"ks": 0, "shininess": 3.5e+38}},
     "objects": [{"shape": "icosphere", "subdivisions": 1, "material": "m0"}]},
]


@pytest.mark.parametrize("scene", FOUND)
def test_scenes_the_fuzzer_found(folder, monkeypatch, scene):
    monkeypatch.chdir(folder)
    check_contract(folder, scene)
