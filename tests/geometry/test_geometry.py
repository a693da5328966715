"""Face and vertex normals, crease splitting, shapes and placement."""

import math

import numpy as np
import pytest
import trimesh

import raycast_phong as rp
from raycast_phong.geometry.build import build_geometry
from raycast_phong.geometry.normals import compute_corner_normals, face_normals
from raycast_phong.shapes import plane_mesh


def test_icosphere_vertex_normals_are_the_unit_positions_to_first_order():
    mesh = trimesh.creation.icosphere(subdivisions=3)
    corners = compute_corner_normals(mesh.vertices, mesh.faces, "mean")
    expected = mesh.vertices[mesh.faces]
    assert np.abs(corners - expected).max() < 0.01
    np.testing.assert_allclose(np.linalg.norm(corners, axis=-1), 1.0, atol=1e-12)


def test_mean_area_and_angle_weightings_on_a_hand_made_fan():
    """Vertex 0 is shared by a large face in the x–y plane and a small face tilted 90° about x."""
    vertices = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [1, 0, 0], [0, 0, -1]], float)
    faces = np.array([[0, 1, 2], [0, 3, 4]])  # normals +z (area 2) and +y... check below
    unit, _doubled = face_normals(vertices, faces)
    np.testing.assert_allclose(unit, [[0, 0, 1], [0, 1, 0]], atol=1e-12)
    mean = compute_corner_normals(vertices, faces, "mean")[0, 0]
    area = compute_corner_normals(vertices, faces, "area")[0, 0]
    angle = compute_corner_normals(vertices, faces, "angle")[0, 0]
    np.testing.assert_allclose(mean, np.array([0, 1, 1]) / math.sqrt(2), atol=1e-12)
    np.testing.assert_allclose(area, np.array([0, 0.5, 2]) / math.hypot(0.5, 2), atol=1e-12)
    # Both corner angles at vertex 0 are 90°: the angle weighting equals the mean.
    np.testing.assert_allclose(angle, mean, atol=1e-12)


def test_crease_angle_splits_a_cube_into_face_normals():
    box = trimesh.creation.box()
    unit, _ = face_normals(box.vertices, box.faces)
    creased = compute_corner_normals(box.vertices, box.faces, "mean", crease_angle=30)
    np.testing.assert_allclose(creased, np.repeat(unit[:, None], 3, axis=1), atol=1e-12)
    smooth = compute_corner_normals(box.vertices, box.faces, "mean", crease_angle=180)
    # Uncreased, a cube corner's normal points along the diagonal (averaging the three faces' normals,
    # each counted once per adjacent triangle).
    assert np.abs(smooth - np.repeat(unit[:, None], 3, axis=1)).max() > 0.3


def test_crease_angle_180_and_the_creased_path_agree():
    mesh = trimesh.creation.icosphere(subdivisions=2)
    a = compute_corner_normals(mesh.vertices, mesh.faces, "area", crease_angle=180)
    b = compute_corner_normals(mesh.vertices, mesh.faces, "area", crease_angle=179.999)
    np.testing.assert_allclose(a, b, atol=1e-12)


def test_degenerate_faces_do_not_poison_normals():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], float)
    faces = np.array([[0, 1, 2], [0, 1, 3]])  # the second is a zero-area sliver along x
    corners = compute_corner_normals(vertices, faces, "mean")
    assert np.isfinite(corners).all()
    np.testing.assert_allclose(corners[0], [[0, 0, 1]] * 3, atol=1e-12)


def test_plane_faces_point_up():
    vertices, faces = plane_mesh((2, 3), (2, 3))
    unit, doubled = face_normals(vertices, faces)
    np.testing.assert_allclose(unit, np.tile([0, 1, 0], (len(faces), 1)))
    assert doubled.sum() / 2 == pytest.approx(6.0)


def test_placement_scales_rotates_then_translates_and_mirrors_keep_normals_outward():
    scene = rp.validate_scene({
        "objects": [{"shape": "plane", "size": [2, 2], "scale": [1, -1, 1], "rotate": [90, 0, 0],
                     "translate": [5, 0, 0]}],
    })
    g = build_geometry(scene)
    # Mirror in y turns the up-facing plane down: −y; then 90° about x sends −y to −z.
    np.testing.assert_allclose(g.face_normals, np.tile([0, 0, -1], (len(g.faces), 1)), atol=1e-12)
    np.testing.assert_allclose(g.vertices.mean(axis=0), [5, 0, 0], atol=1e-12)


@pytest.mark.parametrize("shape", ["icosphere", "uv_sphere", "box", "plane", "cylinder", "torus"])
def test_every_builtin_shape_builds_with_unit_normals(shape):
    g = build_geometry(rp.validate_scene({"objects": [{"shape": shape}]}))
    assert g.triangles > 0
    np.testing.assert_allclose(np.linalg.norm(g.corner_normals, axis=-1), 1.0, atol=1e-9)


def test_file_normals_are_read_from_an_obj(tmp_path):
    (tmp_path / "tri.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0.6 0 0.8\nvn 0 0.6 0.8\nf 1//1 2//2 3//3\n")
    scene = rp.validate_scene({"objects": [{"shape": "mesh", "path": "tri.obj", "normals": "file"}]},
                              folder=tmp_path)
    g = build_geometry(scene)
    np.testing.assert_allclose(g.corner_normals[0], [[0, 0, 1], [0.6, 0, 0.8], [0, 0.6, 0.8]], atol=1e-12)


@pytest.mark.parametrize(("fold", "cancels"), [(1e-9, True), (1e-4, False)])
def test_vertex_normals_that_cancel_below_no_direction_fall_back_to_the_face_normals(fold, cancels):
    """Two triangles folded onto each other at an angle `fold` (a knife-edge fin): their normals nearly
    oppose, and at the shared edge their sum has length 2 sin(fold / 2) of the 2 it would have if they
    agreed. Below NO_DIRECTION (1e-6, the kernel's own tolerance for a mixed normal) that sum points
    wherever rounding sends it, so each corner keeps its face's normal; above it, it is used."""
    from raycast_phong.geometry.normals import compute_corner_normals, face_normals
    a = fold  # the second triangle is the first turned by `fold` about the x axis (the shared edge)
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, math.cos(a), math.sin(a)]], np.float64)
    faces = np.array([[0, 1, 2], [1, 0, 3]])
    unit, _ = face_normals(vertices, faces)
    assert np.linalg.norm(unit.sum(axis=0)) == pytest.approx(2 * math.sin(a / 2), rel=1e-6)
    corners = compute_corner_normals(vertices, faces)
    shared = corners[0, 0]  # vertex 0 of face 0, on the fold
    if cancels:
        np.testing.assert_allclose(shared, unit[0], atol=1e-12)
    else:
        np.testing.assert_allclose(shared, unit.sum(axis=0) / np.linalg.norm(unit.sum(axis=0)), atol=1e-9)
        assert abs(shared @ unit[0]) < 1e-3  # the fin's edge normal lies in the bisecting plane


def test_a_malformed_mesh_file_is_bad_input_but_a_bug_stays_an_internal_error(tmp_path, monkeypatch):
    """Whatever trimesh raises for a corrupt file (an UnboundLocalError for this PLY header) is the user's to
    fix: SceneError. An exception that never passed through trimesh is ours and must not be dressed up as
    "cannot read the file"."""
    import trimesh
    (tmp_path / "bad.ply").write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nend_header\n\x00")
    (tmp_path / "odd.stl").write_bytes(bytes(range(256)) * 3)  # not UTF-8: trimesh needs charset-normalizer
    scene = lambda name: rp.validate_scene({"objects": [{"shape": "mesh", "path": name}]}, folder=tmp_path)
    with pytest.raises(rp.SceneError, match=r"objects\.0\.path: cannot read"):
        build_geometry(scene("bad.ply"))
    try:
        build_geometry(scene("odd.stl"))  # binary STL reads any bytes; what matters is no missing module
    except rp.SceneError as error:
        assert "ModuleNotFoundError" not in str(error), error

    def bug(**kwargs):
        raise ZeroDivisionError("a bug, not a file problem")
    monkeypatch.setattr(trimesh, "load", bug)
    with pytest.raises(ZeroDivisionError):
        build_geometry(scene("bad.ply"))


def test_rotate_turns_about_x_then_y_then_z(tmp_path):
    """docs/scene-format.md: rotate is degrees about x, then y, then z. The vertex (1, 2, 3) turned 90° about x is
    (1, -3, 2), then 90° about z (x → y) is (3, 1, 2); the other order would give (-2, -3, 1)."""
    (tmp_path / "tri.obj").write_text("v 1 2 3\nv 0 0 0\nv 1 0 0\nf 1 2 3\n")
    scene = rp.validate_scene({"objects": [{"shape": "mesh", "path": "tri.obj", "rotate": [90, 0, 90]}]},
                              folder=tmp_path)
    g = build_geometry(scene)
    assert any(np.allclose(v, [3, 1, 2], atol=1e-12) for v in g.vertices), g.vertices
    turned = rp.validate_scene({"objects": [{"shape": "mesh", "path": "tri.obj", "rotate": [90, 90, 0]}]},
                               folder=tmp_path)  # (1, -3, 2), then 90° about y (z → x): (2, -3, -1)
    assert any(np.allclose(v, [2, -3, -1], atol=1e-12) for v in build_geometry(turned).vertices)


def test_file_normals_follow_a_stretch_by_the_inverse_transpose(tmp_path):
    """A normal is not a position: under scale S it turns by S⁻¹ (then unit length), so stretching a surface along
    x tilts its normal toward z. (0.6, 0, 0.8) under scale [2, 1, 1] becomes (0.3, 0, 0.8) / |…|."""
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0.6 0 0.8\nf 1//1 2//1 3//1\n")
    scene = rp.validate_scene({"objects": [{"shape": "mesh", "path": "tri.obj", "normals": "file",
                                            "scale": [2, 1, 1]}]}, folder=tmp_path)
    expected = np.array([0.3, 0.0, 0.8]) / math.hypot(0.3, 0.8)
    np.testing.assert_allclose(build_geometry(scene).corner_normals[0], [expected] * 3, atol=1e-6)
