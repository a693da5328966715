"""A mesh file's finer version for the "fine" reference (tools/accuracy.refine_entry): Loop subdivision, checked
on an octahedron by hand (Loop 1987: an old vertex of valence n moves to (1 − nβ) v + β Σ neighbours, β =
(5/8 − (3/8 + cos(2π/n)/4)²)/n; an edge point is 3/8 of its ends plus 1/8 of the two opposite corners)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

import raycast_phong as rp
from raycast_phong.tools.accuracy import refine_entry

CORNERS = "1 0 0\n{k} -1 0 0\n{k} 0 1 0\n{k} 0 -1 0\n{k} 0 0 1\n{k} 0 0 -1\n"
FACES = ((1, 3, 5), (3, 2, 5), (2, 4, 5), (4, 1, 5), (3, 1, 6), (2, 3, 6), (4, 2, 6), (1, 4, 6))
# its normals stored (the vertices themselves), so that normals = "file" is allowed
OCTAHEDRON = ("v " + CORNERS.format(k="v") + "vn " + CORNERS.format(k="vn")
              + "".join("f " + " ".join(f"{i}//{i}" for i in face) + "\n" for face in FACES))


@pytest.fixture
def scene(tmp_path):
    (tmp_path / "octa.obj").write_text(OCTAHEDRON)
    (tmp_path / "s.toml").write_text('[[objects]]\nshape = "icosphere"\n[[objects]]\nshape = "mesh"\n'
                                     'path = "octa.obj"\nnormals = "file"\n')
    return rp.load_scene(tmp_path / "s.toml")


def test_a_mesh_is_loop_subdivided_into_a_file_the_fine_scene_names(scene, tmp_path):
    """One iteration: 8 faces become 32 over 6 + 12 vertices. Valence 4, so β = (5/8 − 9/64)/4 = 31/256: the old
    corner (1, 0, 0), whose neighbours sum to 0, moves to 1 − 4·31/256 = 0.515625; the edge from (1, 0, 0) to
    (0, 1, 0), whose opposite corners are (0, 0, ±1), gets the point (3/8, 3/8, 0). The file stores no normals,
    so "file" normals become "mean"."""
    entry = {"shape": "mesh", "path": "octa.obj", "normals": "file"}
    refine_entry(scene, 1, entry, 0, 1, tmp_path)
    assert entry == {"shape": "mesh", "path": str(tmp_path / "object1-loop1.ply"), "normals": "mean"}
    fine = trimesh.load(entry["path"], process=False)
    assert (len(fine.vertices), len(fine.faces)) == (18, 32)
    points = {tuple(np.round(np.abs(p), 9)) for p in fine.vertices}
    assert points == {(0.515625, 0.0, 0.0), (0.0, 0.515625, 0.0), (0.0, 0.0, 0.515625),
                      (0.375, 0.375, 0.0), (0.375, 0.0, 0.375), (0.0, 0.375, 0.375)}


def test_a_shape_is_refined_by_level_and_a_mesh_at_zero_iterations_is_left_as_it_is(scene, tmp_path):
    """The icosphere takes the level as its subdivisions; the mesh with no iterations keeps its own file, and a
    file already made for these iterations is used again, not subdivided twice."""
    shape = {"shape": "icosphere"}
    refine_entry(scene, 0, shape, 3, 3, tmp_path)
    assert shape["subdivisions"] == 3
    mesh = {"shape": "mesh", "path": "octa.obj", "normals": "file"}
    refine_entry(scene, 1, mesh, 0, 0, tmp_path)
    assert mesh == {"shape": "mesh", "path": "octa.obj", "normals": "file"} and not list(tmp_path.glob("*.ply"))
    (tmp_path / "object1-loop2.ply").write_bytes(b"made before")
    again = {"shape": "mesh", "path": "octa.obj"}
    refine_entry(scene, 1, again, 0, 2, tmp_path)
    assert again["path"] == str(tmp_path / "object1-loop2.ply") and "normals" not in again
    assert (tmp_path / "object1-loop2.ply").read_bytes() == b"made before"


def test_the_fine_memory_check_counts_a_mesh_at_four_to_the_levels_its_triangles(tmp_path):
    """docs/accuracy.md, "Levels": a mesh file Loop-subdivided L times has 4^L × the file's triangles, so the
    octahedron (8) at --fine 2 is 128 in all (the file's 8 and 120 more), the count the refusal names."""
    from raycast_phong.errors import SceneError
    from raycast_phong.tools.accuracy import check_fine_memory
    (tmp_path / "octa.obj").write_text(OCTAHEDRON)
    (tmp_path / "s.toml").write_text('[[objects]]\nshape = "mesh"\npath = "octa.obj"\n')
    scene = rp.load_scene(tmp_path / "s.toml")
    with pytest.raises(SceneError, match=r"--fine 2: the refined scene has 128 triangles "):
        check_fine_memory(scene, scene.data(), 2, 1)
