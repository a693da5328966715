"""Every built-in kind of object (shapes/, one module each) against one interface: parametrised over the
registry, so a new kind is checked by adding it there. The closed form of each kind's geometry is tested in
test_shapes.py (against trimesh.creation) and test_exact_normals.py; here, what every kind must have, and that the
registry is the only list of kinds: the schema, the bulk validator and the messages follow it, and a kind added
at run time (docs/pipeline.md's cone) is validated, estimated and rendered with nothing else changed."""

from __future__ import annotations

import ast
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import raycast_phong
from raycast_phong.geometry.build import build_geometry
from raycast_phong.geometry.templates import exact_corner_normals_local, object_mesh, shape_uv
from raycast_phong.renderer.budget import shape_triangles, size_key
from raycast_phong.scene import bulk, schema
from raycast_phong.scene.objects import OBJECT_MODELS, OWN_KEYS
from raycast_phong.shapes import KINDS, kind_of
from raycast_phong.tools.accuracy import level_of, refined
from raycast_phong.values.messages import _model_of

ROOT = Path(__file__).resolve().parents[2]
# Each kind at its defaults, and the kinds below also at other values of their own keys.
VARIANTS = {"icosphere": [{"subdivisions": 3, "radius": 0.5}],
            "uv_sphere": [{"segments": [7, 5], "radius": 2.0}],
            "box": [{"size": [1.0, 2.0, 0.25]}],
            "plane": [{"size": [3.0, 1.0], "segments": [4, 3]}],
            "cylinder": [{"radius": 0.25, "height": 3.0, "segments": [9, 3]}],
            "torus": [{"major_radius": 2.0, "minor_radius": 0.5, "segments": [12, 6]}]}
BUILT = [name for name, kind in KINDS.items() if not kind.from_file]  # a mesh is read from its file, not built
CASES = [(name, keys) for name in BUILT for keys in [{}, *VARIANTS.get(name, [])]]


def scene_of(name: str, keys: dict) -> schema.Scene:
    return schema.validate_scene({"objects": [{"shape": name, **keys}]}, source="t")


def test_the_schema_takes_its_kinds_and_their_keys_from_the_registry():
    """[[objects]] is one model per kind of the registry (the mesh file among them, last), told apart by `shape`;
    each model's own keys are the kind's `keys`, and the bulk validator has a plan for each built-in kind."""
    union, _ = _model_of(schema.Scene.model_fields["objects"].annotation, "objects")
    assert union.key == "shape" and tuple(union.models) == tuple(KINDS) == tuple(OBJECT_MODELS)
    assert list(KINDS)[-1] == "mesh" and KINDS["mesh"].from_file
    for name, kind in KINDS.items():
        assert kind.name == name and OWN_KEYS[name] == tuple(kind.keys.model_fields)
        assert set(kind.keys.model_fields) < set(OBJECT_MODELS[name].model_fields)
    assert set(bulk.PLANS) == set(BUILT)
    assert set(VARIANTS) <= set(KINDS)


def _literals_outside_the_kinds() -> list[str]:
    """Where a module outside shapes/ spells a kind's name as a string: a list or comparison of kinds
    kept by hand. A scene table written in code ({"shape": "plane", ...}) names one, which is fine; so does the
    analytic oracle, which stays apart on purpose (a kind it does not know has no analytic reference)."""
    found = []
    package = Path(raycast_phong.__file__).parent
    for path in sorted(package.rglob("*.py")):
        relative = path.relative_to(package).as_posix()
        if relative.startswith(("shapes/", "io/")) or relative == "tools/reference.py":
            continue  # io/ reads file formats, whose documents have keys of these names (a glTF node's "mesh")
        tree = ast.parse(path.read_text(encoding="utf-8"))
        tables = {id(value) for node in ast.walk(tree) if isinstance(node, ast.Dict)
                  for key, value in zip(node.keys, node.values)
                  if isinstance(key, ast.Constant) and key.value == "shape"}
        found += [f"{relative}:{node.lineno}: {node.value!r}" for node in ast.walk(tree)
                  if isinstance(node, ast.Constant) and node.value in KINDS and id(node) not in tables]
    return found


def test_no_module_outside_the_kinds_spells_a_kinds_name():
    assert _literals_outside_the_kinds() == []


def test_the_literal_scan_sees_a_kinds_name(monkeypatch):
    """The control: were "default" a kind's name, the scan would find the modules that compare with it (on main
    before "mesh" joined the registry, 21 comparisons `shape == "mesh"` in 14 modules were such literals)."""
    monkeypatch.setitem(KINDS, "default", KINDS["box"])  # "default" is compared in several modules
    assert any(": 'default'" in line for line in _literals_outside_the_kinds())


def test_a_kind_added_to_the_registry_alone_is_validated_estimated_and_rendered():
    """docs/pipeline.md's worked cone, run as it is, then registered (its one line in shapes.KINDS) in a fresh
    process before the schema is imported: the scene format, its messages, the bulk validator, the memory
    estimate, the geometry and a render all take it, with no other change."""
    text = (ROOT / "docs" / "pipeline.md").read_text(encoding="utf-8")
    section = text[text.index("## Adding a built-in kind of object"):]
    example = re.search(r"^```python\n(.*?)^```", section, re.S | re.M).group(1)
    checks = """
from raycast_phong import shapes
shapes.KINDS["cone"] = Cone()
import numpy as np
import raycast_phong as rp
from raycast_phong.errors import SceneError
from raycast_phong.renderer.budget import shape_triangles
from raycast_phong.scene import bulk
from raycast_phong.scene.objects import OBJECT_MODELS
from raycast_phong.scene.schema import scene_json_schema

def refused(obj):
    try:
        rp.validate_scene({"objects": [obj]}, source="s.toml")
    except SceneError as error:
        return str(error)
    raise AssertionError(obj)

assert refused({"shape": "cone", "radius": 0}) == ("s.toml: objects.0.radius: out of range; allowed: "
                                                   "0.0 < radius ≤ 1e+18 (got 0)")
assert refused({"shape": "cone", "size": [1, 1, 1]}).startswith(
    's.toml: objects.0.size: does not apply to shape = "cone" (size is a key of box and plane); a cone reads '
    'radius, height, segments besides the keys of every object')
assert "(height is a key of cylinder and cone)" in refused({"shape": "box", "height": 3})
assert "'torus', 'cone' or 'mesh' (got the string 'cne')" in refused({"shape": "cne"})
assert "Cone" in scene_json_schema()["$defs"]
made = bulk.objects_in_bulk([{"shape": "cone", "translate": [i, 0, 0]} for i in range(100)])
assert all(type(obj) is OBJECT_MODELS["cone"] for obj in made)
cone = {"shape": "cone", "radius": 0.8, "segments": [12, 3], "rotate": [-90, 0, 0]}
scene = rp.validate_scene({"render": {"width": 24, "height": 18}, "lights": [{"position": [2, 2, 3]}],
                           "objects": [cone]})
assert shape_triangles(scene.objects[0]) == 24
image = rp.render(scene).image
assert image[9, 12].max() > 0.1 and image[0, 0].max() == 0  # the cone in the middle, the background black
print("cone rendered")
"""
    done = subprocess.run([sys.executable, "-c", example + checks], capture_output=True, text=True, timeout=600,
                          cwd=ROOT)
    assert done.returncode == 0 and "cone rendered" in done.stdout, done.stderr[-3000:]


@pytest.mark.parametrize(("name", "keys"), CASES)
def test_a_kind_builds_what_it_counts_closed_and_wound_outward(name, keys):
    scene = scene_of(name, keys)
    obj = scene.objects[0]
    vertices, faces = object_mesh(scene, 0)[:2]
    assert shape_triangles(obj) == KINDS[name].triangles(obj) == len(faces) == build_geometry(scene).triangles
    assert size_key(obj) in (*OWN_KEYS[name], "shape")
    assert np.isfinite(vertices).all() and faces.min() >= 0 and faces.max() < len(vertices)
    # Every directed edge once: the faces agree on their winding; closed unless it is the plane.
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    assert len(np.unique(edges, axis=0)) == len(edges)
    corners = vertices[faces]
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    if name == "plane":
        assert (cross[:, 1] > 0).all()  # normal +y
    else:
        assert len(np.unique(np.sort(edges, axis=1), axis=0)) * 2 == len(edges)  # each edge has two faces
        assert np.einsum("ij,ij->", corners[:, 0], cross) > 0  # 6 × the enclosed volume: wound outward


@pytest.mark.parametrize(("name", "keys"), CASES)
def test_a_kind_gives_uvs_in_range_and_exact_normals_of_unit_length(name, keys):
    scene = scene_of(name, keys)
    obj = scene.objects[0]
    vertices, faces = object_mesh(scene, 0)[:2]
    uv = shape_uv(obj, vertices, faces)
    assert uv.shape == (len(faces), 3, 2) and np.isfinite(uv).all()
    # u may pass 1 by less than one face's width where a face crosses the seam (shapes.surfaces._seamless).
    assert uv.min() >= 0.0 and uv[..., 1].max() <= 1.0 + 1e-12 and uv[..., 0].max() < 1.5
    exact = exact_corner_normals_local(obj, vertices, faces)
    assert exact.shape == (len(faces), 3, 3)
    np.testing.assert_allclose(np.linalg.norm(exact, axis=-1), 1.0, atol=1e-12)
    corners = vertices[faces]
    cross = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert (np.einsum("fkj,fj->fk", exact, cross) > 0).all()  # on the face's outer side at every corner


@pytest.mark.parametrize("name", BUILT)
def test_a_kinds_levels_round_trip_and_refine(name):
    """refined(level) gives keys the schema accepts, level_of reads the level back, and a finer level has at
    least as many triangles (a box's 12 flat faces are exact at every level). From L = 2, the format's default
    (a plane's L = 0 and 1 would ask for 1 and 2 segments, below the format's 3)."""
    obj = scene_of(name, {}).objects[0]
    kind = kind_of(obj)
    counts = []
    for level in range(2, min(kind.max_level, 5) + 1):
        finer = scene_of(name, refined(obj, level)).objects[0]
        assert level_of(finer) == (level if refined(obj, level) else 0)
        counts.append(kind.triangles(finer))
    assert counts == sorted(counts) and (counts[-1] > counts[0]) == bool(refined(obj, 3))
    assert kind.curved == (name not in ("box", "plane"))
