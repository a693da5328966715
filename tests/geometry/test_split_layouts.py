"""The geometry build's rarer layouts: a mesh file after a built-in shape, mirroring and double-mirroring scales,
a repaired winding with per-corner UVs and colours, and a memoised build whose normal rule changes. Every
expectation is worked out here from the scene (a sphere's outward direction and latitude, a cube's corners)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import raycast_phong as rp
from raycast_phong.geometry.build import build_geometry
from raycast_phong.geometry.memo import BuildMemo

KD = slice(3, 6)  # k_d's columns in a material table row (docs: k_a, k_d, k_s, k_e, ...)


def write_obj(folder: Path, name: str, text: str, mtl: str | None = None) -> None:
    (folder / f"{name}.obj").write_text((f"mtllib {name}.mtl\n" if mtl else "") + text, encoding="utf-8")
    if mtl:
        (folder / f"{name}.mtl").write_text(mtl, encoding="utf-8")


QUAD = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl own\nf 1 2 3\nf 1 3 4\n"


def test_a_mesh_file_after_a_shape_gets_its_own_material_rows(tmp_path):
    """Catches a file's material rows written at the wrong face offset (or row offset) when a shape comes first."""
    write_obj(tmp_path, "red", QUAD, "newmtl own\nKd 0.9 0.1 0.1\n")
    write_obj(tmp_path, "green", QUAD, "newmtl own\nKd 0.1 0.9 0.1\n")
    sphere = {"shape": "icosphere", "subdivisions": 0, "material": "blue"}
    scene = rp.validate_scene({"materials": {"blue": {"kd": [0.1, 0.1, 0.9]}}, "objects": [
        sphere, {"shape": "mesh", "path": "red.obj", "translate": [3, 0, 0]},
        {**sphere, "translate": [0, 3, 0]}, {"shape": "mesh", "path": "green.obj", "translate": [3, 3, 0]}]},
        folder=tmp_path)
    g = build_geometry(scene)
    # The whole table: the built-in default (k_d 0.8), the scene's "blue", then the files' rows.
    kd = np.concatenate([[[0.8] * 3, [0.1, 0.1, 0.9]], g.file_materials[:, KD]])[g.face_material]
    expected = {0: [0.1, 0.1, 0.9], 1: [0.9, 0.1, 0.1], 2: [0.1, 0.1, 0.9], 3: [0.1, 0.9, 0.1]}
    assert np.bincount(g.face_object).tolist() == [20, 2, 20, 2]
    for index, colour in expected.items():
        np.testing.assert_allclose(kd[g.face_object == index], [colour] * int((g.face_object == index).sum()))


def white_map(folder: Path) -> None:
    Image.new("RGB", (4, 4), (255, 255, 255)).save(folder / "map.png")


@pytest.mark.parametrize("normals", ["mean", "exact"])
@pytest.mark.parametrize("scale", [[-1, -1, 1], [-1, 1, 1], [1, 1, -1], [-1, -1, -1], [2, -2, 2]])
def test_mirrored_and_double_flipped_spheres_keep_faces_corners_and_uvs_outward(tmp_path, scale, normals):
    """Catches a re-winding decided per flipped axis (or not at all) instead of by the scale's sign, for
    faces, corner normals and corner UVs, alone and in a group beside an unscaled sphere."""
    white_map(tmp_path)
    centre = np.array([5.0, 1.0, 2.0])
    sphere = {"shape": "icosphere", "subdivisions": 1, "material": "map", "normals": normals}
    for objects in ([{**sphere, "scale": scale, "translate": centre.tolist()}],
                    [{**sphere, "translate": [-5, 0, 0]}, {**sphere, "scale": scale, "translate": centre.tolist()}]):
        scene = rp.validate_scene({"materials": {"map": {"kd_map": "map.png"}}, "objects": objects},
                                  folder=tmp_path)
        g = build_geometry(scene)
        mine = g.face_object == len(objects) - 1
        corners = g.vertices[g.faces[mine]]  # (F, 3, 3) as the faces wind
        radius = abs(scale[0])
        outward = (corners - centre) / radius  # the unit sphere's normal at each corner
        winding = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        assert (np.einsum("ij,ij->i", winding, corners.mean(axis=1) - centre) > 0).all()
        assert (np.einsum("ij,ij->i", g.face_normals[mine], corners.mean(axis=1) - centre) > 0).all()
        assert (np.einsum("fcj,fcj->fc", g.corner_normals[mine], outward) > 0.9).all()
        if normals == "exact":
            np.testing.assert_allclose(g.corner_normals[mine], outward / np.linalg.norm(outward, axis=-1,
                                                                                         keepdims=True), atol=1e-6)
        # v = (latitude + 90°) / 180° about the local z axis: each corner keeps its own vertex's v.
        local_z = (corners[..., 2] - centre[2]) / scale[2]
        v = 0.5 + np.arcsin(np.clip(local_z, -1, 1)) / math.pi
        np.testing.assert_allclose(g.corner_uv[mine][..., 1], v, atol=1e-5)


def test_a_repaired_winding_keeps_each_corners_uv_and_colour(tmp_path):
    """Catches per-corner UVs (and vertex colours) left in the file's corner order when a face is re-wound."""
    points = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    faces = [(0, 2, 1), (3, 1, 0), (0, 3, 2), (1, 2, 3)]  # outward but the second, wound inward

    def uv(p):
        return p[0] + 0.5 * p[2], p[1] + 0.25 * p[2]  # a different (u, v) at every vertex
    text = "".join(f"v {x} {y} {z} {x} {y} {z}\n" for x, y, z in points)  # the colour is the position
    text += "".join("vt {} {}\n".format(*uv(p)) for p in points) + "usemtl own\n"
    text += "".join("f " + " ".join(f"{k + 1}/{k + 1}" for k in face) + "\n" for face in faces)
    white_map(tmp_path)
    write_obj(tmp_path, "tetra", text, "newmtl own\nKd 1 1 1\nmap_Kd map.png\n")
    g = build_geometry(rp.validate_scene({"objects": [{"shape": "mesh", "path": "tetra.obj"}]}, folder=tmp_path))
    assert any("winding of 1 of 4 faces was repaired" in note for note in g.notes)
    corners = g.vertices[g.faces]
    np.testing.assert_allclose(g.corner_uv, [[uv(p) for p in face] for face in corners], atol=1e-6)
    np.testing.assert_allclose(g.corner_colour, corners, atol=1e-6)
    winding = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert (np.einsum("ij,ij->i", winding, corners.mean(axis=1) - 0.25) > 0).all()


# A cube of side 2 about the origin, its 12 triangles wound outward; with each face's own normal per corner.
CUBE_POINTS = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
CUBE_QUADS = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]


def cube_obj(file_normals: bool) -> str:
    text = "".join("v {} {} {}\n".format(*p) for p in CUBE_POINTS)
    normals = [(-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)]
    text += "".join("vn {} {} {}\n".format(*n) for n in normals) if file_normals else ""
    for k, (a, b, c, d) in enumerate(CUBE_QUADS):
        for tri in ((a, b, c), (a, c, d)):
            text += "f " + " ".join(f"{i + 1}//{k + 1}" if file_normals else f"{i + 1}" for i in tri) + "\n"
    return text


def creased(g) -> bool:
    """Every corner normal is its face's (a cube creased at its 90° edges, or the file's flat normals)."""
    return np.allclose(g.corner_normals, np.repeat(g.face_normals[:, None], 3, axis=1), atol=1e-6)


def angle_smooth(g) -> bool:
    """Every corner normal is its vertex's direction from the centre (a cube smoothed by corner angle)."""
    corners = g.vertices[g.faces]
    return np.allclose(g.corner_normals, corners / np.linalg.norm(corners, axis=-1, keepdims=True), atol=1e-6)


def smooth(g) -> bool:
    """Every corner normal leans toward its vertex's diagonal on all three axes (a cube not creased)."""
    corners = g.vertices[g.faces]
    return bool((g.corner_normals * np.sign(corners) > 0.3).all())


def test_a_memoised_build_follows_a_changed_normal_rule_and_crease(tmp_path):
    """Catches a live view's memo keeping the last normals (the file's, or another rule's or crease's) after
    objects.N.normals or crease_angle changed."""
    write_obj(tmp_path, "flat", cube_obj(True))
    write_obj(tmp_path, "bare", cube_obj(False))
    memo = BuildMemo()
    steps = [  # (the object's keys, what its corner normals must be)
        ({"path": "flat.obj"}, creased),  # the file's own normals: flat
        ({"path": "flat.obj", "normals": "angle"}, angle_smooth),  # a rule: the file's normals no longer
        ({"path": "flat.obj", "normals": "angle", "crease_angle": 30}, creased),
        ({"path": "flat.obj", "normals": "angle", "crease_angle": 180}, angle_smooth),
        ({"path": "flat.obj"}, creased),
        ({"path": "bare.obj"}, creased),  # no normals in the file, nothing set: creased at 30°
        ({"path": "bare.obj", "crease_angle": 180}, smooth),  # set, to the key's default: not creased
        ({"path": "bare.obj"}, creased),
    ]
    for keys, expected in steps:
        scene = rp.validate_scene({"objects": [{"shape": "mesh", **keys}]}, folder=tmp_path)
        assert expected(build_geometry(scene, memo=memo)), keys
    for keys, expected in [({"crease_angle": 180, "normals": "angle"}, angle_smooth), ({"crease_angle": 30}, creased),
                           ({"normals": "angle"}, angle_smooth)]:
        scene = rp.validate_scene({"objects": [{"shape": "box", **keys}]})
        assert expected(build_geometry(scene, memo=memo)), keys


def test_two_boxes_alike_but_for_their_normal_rule_each_get_their_own_normals():
    """Catches objects of one shape and size sharing one build although their `normals` rules differ (the group
    key without the rule): a box smoothed by corner angle has every corner normal along its vertex's diagonal;
    smoothed by the mean of its triangles (two a face, one or two at a corner) some lean off it."""
    scene = rp.validate_scene({"objects": [
        {"shape": "box", "crease_angle": 180, "normals": "angle"},
        {"shape": "box", "crease_angle": 180, "normals": "mean", "translate": [5, 0, 0]}]})
    g = build_geometry(scene)
    for index, centre, diagonal in ((0, (0, 0, 0), True), (1, (5, 0, 0), False)):
        mine = g.face_object == index
        corners = g.vertices[g.faces[mine]] - np.array(centre)
        along = np.allclose(g.corner_normals[mine], corners / np.linalg.norm(corners, axis=-1, keepdims=True),
                            atol=1e-6)
        assert along == diagonal, index
