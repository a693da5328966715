"""Every built-in kind of object (geometry/shapes/, one module each) against one interface: parametrised over the
registry, so a new kind is checked by adding it there. The closed form of each kind's geometry is tested in
test_shapes.py (against trimesh.creation) and test_exact_normals.py; here, what every kind must have."""

from __future__ import annotations

import numpy as np
import pytest

from raycast_phong import codes
from raycast_phong.geometry.build import build_geometry, exact_corner_normals_local, object_mesh, shape_uv
from raycast_phong.geometry.shapes import KINDS, kind_of
from raycast_phong.renderer.budget import shape_triangles, size_key
from raycast_phong.scene import schema
from raycast_phong.tools.accuracy import level_of, refined

# Each kind at its defaults and at other values of its own keys (the keys are the schema's, SHAPE_KEYS).
VARIANTS = {"icosphere": [{}, {"subdivisions": 3, "radius": 0.5}],
            "uv_sphere": [{}, {"segments": [7, 5], "radius": 2.0}],
            "box": [{}, {"size": [1.0, 2.0, 0.25]}],
            "plane": [{}, {"size": [3.0, 1.0], "segments": [4, 3]}],
            "cylinder": [{}, {"radius": 0.25, "height": 3.0, "segments": [9, 3]}],
            "torus": [{}, {"major_radius": 2.0, "minor_radius": 0.5, "segments": [12, 6]}]}
CASES = [(name, keys) for name in KINDS for keys in VARIANTS[name]]


def scene_of(name: str, keys: dict) -> schema.Scene:
    return schema.validate_scene({"objects": [{"shape": name, **keys}]}, source="t")


def test_the_registry_is_the_list_of_built_in_kinds():
    """codes.SHAPES (the schema's choices) and SHAPE_KEYS name exactly the registry's kinds and the mesh file;
    every kind has its variants here, so none goes untested."""
    assert codes.SHAPES == (*KINDS, "mesh")
    assert set(schema.SHAPE_KEYS) == {*KINDS, "mesh"}
    assert set(VARIANTS) == set(KINDS)
    assert all(kind.name == name for name, kind in KINDS.items())


@pytest.mark.parametrize(("name", "keys"), CASES)
def test_a_kind_builds_what_it_counts_closed_and_wound_outward(name, keys):
    scene = scene_of(name, keys)
    obj = scene.objects[0]
    vertices, faces = object_mesh(scene, obj, 0, "t")[:2]
    assert shape_triangles(obj) == KINDS[name].triangles(obj) == len(faces) == build_geometry(scene).triangles
    assert size_key(obj) in (*schema.SHAPE_KEYS[name], "shape")
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
    vertices, faces = object_mesh(scene, obj, 0, "t")[:2]
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


@pytest.mark.parametrize("name", list(KINDS))
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
