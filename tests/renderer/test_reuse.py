"""A FrameCache (renderer/reuse.py) and build_geometry's BuildMemo: the frames of one changing scene reuse what
its change did not touch, and every frame is what a render without them gives, bit for bit."""

from __future__ import annotations

import copy
import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.codes import StageName
from raycast_phong.geometry.build import build_geometry
from raycast_phong.geometry.memo import FRESH, BuildMemo, Memo
from raycast_phong.renderer.frame import FrameCache
from raycast_phong.renderer.reuse import same_bits

SCENES = Path(__file__).resolve().parents[2] / "scenes"

# Shapes of two kinds (two boxes share one), a mesh file with its own materials (.mtl), one with vertex colours,
# and a texture map: every kind of piece the memo keeps.
BASE = {
    "render": {"width": 40, "height": 30},
    "camera": {"position": [0, 3, 9], "look_at": [0, 0, 0]},
    "lights": [{"position": [3, 4, 6]}],
    "materials": {"red": {"kd": [0.9, 0.2, 0.2], "ks": [0.5, 0.5, 0.5]},
                  "checker": {"kd_map": "textures/checker.png"}},
    "objects": [{"shape": "icosphere", "subdivisions": 1, "material": "red", "translate": [-2, 0, 0]},
                {"shape": "box", "translate": [2, 0, 0]}, {"shape": "box", "translate": [2, 1.5, 0]},
                {"shape": "mesh", "path": "meshes/dice.obj", "translate": [0, -1, 0], "scale": [0.5, 0.5, 0.5]},
                {"shape": "mesh", "path": "meshes/painted_knot.ply", "translate": [0, 1.5, 0]},
                {"shape": "uv_sphere", "material": "checker", "translate": [0, 0, -2]}],
}
# (key path, value, whether the geometry is the one before): a change of lights, camera or the render's other
# settings keeps it; materials, shading, placement, tessellation, precision (the normals' dtype) and colour (the
# maps' decoding) do not.
CHANGES = [
    (("lights", 0, "position"), [-3, 4, 6], True),
    (("camera", "position"), [1, 2, 8], True),
    (("render", "samples"), 2, True),
    (("ambient",), [0.2, 0.2, 0.2], True),
    (("render", "mode"), "global", True),
    (("materials", "red", "kd"), [0.1, 0.8, 0.1], False),
    (("render", "shading"), "flat", False),
    (("render", "shading"), "gouraud", False),
    (("objects", 2, "translate"), [2, -1.5, 0], False),
    (("objects", 0, "subdivisions"), 2, False),
    (("render", "precision"), "float64", False),
    (("objects", 3, "rotate"), [0, 30, 0], False),
    (("render", "colour"), "linear", False),  # the maps are decoded anew, from sRGB (the checker has mid values)
]


def changed(table: dict, path: tuple, value) -> dict:
    table = copy.deepcopy(table)
    node = table
    for key in path[:-1]:
        node = node.setdefault(key, {}) if isinstance(key, str) else node[key]
    node[path[-1]] = value
    return table


def scene_of(table: dict, folder: Path = SCENES) -> rp.Scene:
    return rp.validate_scene(table, source="memo", folder=folder)


def assert_same_geometry(got, fresh) -> None:
    """Every field of two Geometry records holds the same bits (textures: the same pixels)."""
    for field in dataclasses.fields(fresh):
        a, b = getattr(got, field.name), getattr(fresh, field.name)
        if isinstance(b, np.ndarray):
            assert same_bits(a, b), field.name
        elif field.name == "textures":
            named = lambda texture: (texture.wrap_s, texture.wrap_t, texture.name)
            assert len(a) == len(b)
            assert all(same_bits(x.pixels, y.pixels) and named(x) == named(y) for x, y in zip(a, b))
        else:
            assert a == b, field.name


def build(scene: rp.Scene, memo: Memo = FRESH):
    """build_geometry as render() calls it: the plan decides the corner normals and their dtype."""
    plan = rp.build_plan(scene)
    return build_geometry(scene, vertex_normals=plan.keeps(StageName.VERTEX_NORMALS), normal_dtype=plan.real,
                          memo=memo)


def test_a_memo_gives_the_geometry_a_fresh_build_gives_and_keeps_it_when_nothing_it_reads_changed():
    memo = BuildMemo()
    table = BASE
    built = build(scene_of(table), memo)
    for path, value, kept in CHANGES:
        table = changed(table, path, value)
        before, built = built, build(scene_of(table), memo)
        assert (built is before) == kept, path
        assert_same_geometry(built, build(scene_of(table)))


def test_frames_through_a_frame_cache_are_the_images_render_gives(tmp_path):
    cached = rp.Renderer(cache=FrameCache())
    table = BASE
    for path, value, _ in [((), None, None), *CHANGES, (("objects", 0, "subdivisions"), 1, False)]:
        if path:
            table = changed(table, path, value)
        scene = scene_of(table)
        got, fresh = cached.render(scene), rp.render(scene)
        assert same_bits(got.image, fresh.image), path
        assert got.plan == fresh.plan and got.counts == fresh.counts, path


def test_a_mesh_file_or_map_changed_on_disk_is_read_again(tmp_path):
    """The memo keys a mesh file and a map on their versions: rewritten, each is read anew."""
    shutil.copytree(SCENES / "meshes", tmp_path / "meshes")
    shutil.copytree(SCENES / "textures", tmp_path / "textures")
    memo = BuildMemo()
    first = build(scene_of(BASE, tmp_path), memo)
    assert build(scene_of(BASE, tmp_path), memo) is first
    dice = tmp_path / "meshes" / "dice.obj"
    lines = dice.read_text().splitlines()
    at = next(k for k, line in enumerate(lines) if line.startswith("v "))
    x, y, z = (float(word) for word in lines[at].split()[1:4])
    lines[at] = f"v {x + 0.25} {y} {z}"  # one vertex moved
    dice.write_text("\n".join(lines) + "\n")
    moved = build(scene_of(BASE, tmp_path), memo)
    assert moved is not first and not same_bits(moved.vertices, first.vertices)
    assert_same_geometry(moved, build(scene_of(BASE, tmp_path)))
    from raycast_phong.io.image_io import write_image
    write_image(tmp_path / "textures" / "checker.png", np.full((4, 4, 3), 0.5, np.float32))  # another image
    repainted = build(scene_of(BASE, tmp_path), memo)
    assert repainted is not moved
    assert_same_geometry(repainted, build(scene_of(BASE, tmp_path)))
    assert not same_bits(repainted.textures[0].pixels, moved.textures[0].pixels)


def test_a_map_named_by_a_mesh_files_mtl_changed_on_disk_is_decoded_again(tmp_path):
    """A mesh file's own map (its .mtl's map_Kd) is not a key of the scene, so the memo holds the version it
    decoded: repainted (red to blue) the map is read anew, and the geometry is a fresh build's; unchanged, the
    memo's geometry is given back as it is."""
    from raycast_phong.io.image_io import write_image
    (tmp_path / "q.obj").write_text("mtllib q.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\n"
                                    "usemtl m\nf 1/1 2/2 3/3\n")
    (tmp_path / "q.mtl").write_text("newmtl m\nKd 1 1 1\nmap_Kd paint.png\n")
    write_image(tmp_path / "paint.png", np.broadcast_to(np.float32([1, 0, 0]), (4, 4, 3)).copy())
    table = {"render": {"width": 20, "height": 20}, "camera": {"position": [0, 0, 4], "look_at": [0, 0, 0]},
             "objects": [{"shape": "mesh", "path": "q.obj"}]}
    memo = BuildMemo()
    first = build(scene_of(table, tmp_path), memo)
    assert build(scene_of(table, tmp_path), memo) is first
    np.testing.assert_array_equal(first.textures[0].pixels[0, 0], [1, 0, 0])
    write_image(tmp_path / "paint.png", np.broadcast_to(np.float32([0, 0, 1]), (4, 4, 3)).copy())
    repainted = build(scene_of(table, tmp_path), memo)
    assert repainted is not first
    np.testing.assert_array_equal(repainted.textures[0].pixels[0, 0], [0, 0, 1])
    assert_same_geometry(repainted, build(scene_of(table, tmp_path)))


def test_a_frame_cache_reuses_the_bvh_when_the_vertices_and_faces_are_the_same(monkeypatch):
    from raycast_phong.renderer import embree_library as embree
    built = []
    original = embree.EmbreeScene
    monkeypatch.setattr(embree, "EmbreeScene", lambda *args: built.append(1) or original(*args))
    cached = rp.Renderer(cache=FrameCache())
    table = BASE
    for path, value, expected in [((), None, 1), (("lights", 0, "position"), [1, 1, 5], 1),
                                  (("render", "shading"), "flat", 1), (("render", "precision"), "float64", 1),
                                  (("objects", 1, "translate"), [2, 0, 1], 2)]:
        if path:
            table = changed(table, path, value)
        cached.render(scene_of(table))
        assert len(built) == expected, path


@pytest.mark.parametrize("value", [0.0, -0.0])
def test_same_bits_tells_minus_zero_from_zero(value):
    assert same_bits(np.array([0.0]), np.array([value])) == (np.signbit(value) == np.signbit(0.0))


def test_a_file_whose_parts_are_partly_coloured_keeps_its_material_rows_from_build_to_build(tmp_path):
    """A part without vertex colours is marked -1 in the file's corner colours, which tell its faces' material
    rows; the geometry's colours turn them into 1. Kept by a memo, the file must keep its -1 for the next build."""
    import trimesh
    coloured = trimesh.creation.box()
    coloured.visual.vertex_colors = np.tile([200, 40, 40, 255], (len(coloured.vertices), 1)).astype(np.uint8)
    plain = trimesh.creation.box()
    plain.apply_translation([3, 0, 0])
    trimesh.Scene([coloured, plain]).export(tmp_path / "two.glb")
    table = {"camera": {"position": [1.5, 2, 8], "look_at": [1.5, 0, 0]}, "lights": [{"position": [3, 4, 6]}],
             "render": {"width": 24, "height": 16}, "objects": [{"shape": "mesh", "path": "two.glb"}]}
    memo = BuildMemo()
    build(scene_of(table, tmp_path), memo)
    for model in ("flat", "phong"):  # a shading change rebuilds the geometry from the kept file
        table = changed(table, ("render", "shading"), model)
        assert_same_geometry(build(scene_of(table, tmp_path), memo), build(scene_of(table, tmp_path)))


def test_a_refused_scene_leaves_the_memo_as_the_last_good_build_left_it():
    """A scene refused half-way through its build (an object placed past the coordinate limit) adds nothing to
    the memo, however often it comes: it holds the last good build's pieces, which the next frame reuses."""
    from raycast_phong.errors import SceneError
    from raycast_phong.tolerances import POSITION_LIMIT
    memo = BuildMemo()
    good = build(scene_of(BASE), memo)
    held = (len(memo._templates), len(memo._parts))
    for k in range(3):
        with pytest.raises(SceneError, match="reaches a coordinate"):
            far = changed(BASE, ("objects", 0, "translate"), [POSITION_LIMIT, k, 0])
            build(scene_of(changed(far, ("objects", 0, "radius"), POSITION_LIMIT)), memo)
        assert (len(memo._templates), len(memo._parts)) == held
    assert build(scene_of(BASE), memo) is good


def test_a_light_or_camera_change_measures_the_geometrys_box_once(monkeypatch):
    """The float-range check and the behind-the-camera warning ask for the geometry's bounding box on every frame:
    it is measured once per Geometry (Geometry.box), so a page's frames that move a light or the camera reduce no
    vertices (each such pass took 5-7 ms a frame on a 1.11M-triangle scan, and the camera's product with the
    vertices woke numpy's threaded BLAS, which then spun a core beside the frame's bands)."""
    from raycast_phong import records
    from raycast_phong.geometry import checks
    measured = []
    original = records.bounding_box
    counting = lambda vertices: measured.append(len(vertices)) or original(vertices)
    monkeypatch.setattr(records, "bounding_box", counting)
    monkeypatch.setattr(checks, "bounding_box", counting, raising=False)
    cached, table = rp.Renderer(cache=FrameCache()), BASE
    cached.render(scene_of(table))
    first = len(measured)
    for path, value in [(("lights", 0, "position"), [1, 1, 5]), (("camera", "position"), [1, 2, 8]),
                        (("lights", 0, "position"), [-2, 3, 5])]:
        table = changed(table, path, value)
        cached.render(scene_of(table))
    assert first >= 1 and len(measured) == first, measured


def test_the_behind_the_camera_warning_from_the_box_is_the_vertices_own():
    """Whether every vertex is behind the camera's plane, answered from the box where the plane misses it and
    from the vertices where it cuts it (a box whose corner is in front while every vertex is behind)."""
    from raycast_phong.geometry.checks import behind_camera
    from raycast_phong.records import Geometry
    vertices = np.array([[0.0, 0.0, 0.0], [2.0, 2.0, 0.0]])
    empty = np.zeros((0, 3))
    geometry = Geometry(vertices, np.zeros((0, 3), np.int32), empty, np.zeros((0, 3, 3)), np.zeros(0, np.int32),
                        np.zeros(0, np.int8), np.zeros(0, np.int32))
    for eye, look_at in [((1.5, 0.5, 0.0), (2.5, -0.5, 0.0)),   # the plane cuts the box, both vertices behind
                         ((1.5, 0.5, 0.0), (0.5, 1.5, 0.0)),    # the plane cuts it, both in front
                         ((-5.0, 1.0, 0.0), (0.0, 1.0, 0.0)),   # the box in front
                         ((5.0, 1.0, 0.0), (9.0, 1.0, 0.0)),    # the box behind
                         ((2.0, 1.0, 0.0), (3.0, 1.0, 0.0)),    # the plane through the far vertex: on it, behind
                         ((1.0, 1.0, 5.0), (1.0, 1.0, 4.0))]:   # the plane holds the whole (flat) box
        scene = rp.validate_scene({"camera": {"position": list(eye), "look_at": list(look_at)},
                                   "objects": [{"shape": "icosphere"}]})
        forward = np.subtract(look_at, eye)
        exact = not (vertices @ forward).max() > np.asarray(eye) @ forward
        assert (behind_camera(scene, geometry) is not None) == exact, (eye, look_at)


def test_a_frame_cache_builds_a_new_bvh_when_only_the_faces_change():
    """A bent quad (one corner raised) split along either diagonal: the same vertices to the bit, other faces,
    another surface. Rendered through one cached session after each other, each frame is the image a fresh render
    gives. Catches the cache's BVH kept for the same vertices whatever the faces."""
    vertices = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.8], [-1.0, 1.0, 0.0]])
    splits = [np.array([[0, 1, 2], [0, 2, 3]]), np.array([[0, 1, 3], [1, 2, 3]])]
    scenes = [rp.mesh_scene(vertices, faces, overrides=["render.width=32", "render.height=24",
                                                        "render.shading=flat"]) for faces in splits]
    fresh = [rp.render(scene).image for scene in scenes]
    assert not same_bits(fresh[0], fresh[1])  # the control: the two splits look different
    cached = rp.Renderer(cache=FrameCache())
    for scene, image in zip(scenes + scenes[:1], fresh + fresh[:1]):
        assert same_bits(cached.render(scene).image, image)
