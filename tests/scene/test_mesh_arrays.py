"""A mesh given as arrays or a trimesh.Trimesh (rp.mesh_scene) goes the way a mesh file goes, without a file: the
same image as the same mesh written to a file and loaded, the same checks of its values, the memory estimate
counting its triangles before anything is built, and no file looked for under its placeholder path."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

import raycast_phong as rp
from raycast_phong.renderer.budget import estimate_memory

SIZE = ["render.width=48", "render.height=36"]


@pytest.fixture(scope="module")
def sphere():
    return trimesh.creation.icosphere(subdivisions=2)


def test_arrays_render_as_the_same_mesh_read_from_a_file(sphere, tmp_path):
    given = rp.mesh_scene(np.asarray(sphere.vertices), np.asarray(sphere.faces), overrides=SIZE)
    also = rp.mesh_scene(sphere, overrides=SIZE)
    path = tmp_path / "ball.ply"
    sphere.export(path, encoding="ascii")
    from_file = rp.load_scene(path, SIZE)
    images = [rp.render(scene).image for scene in (given, also, from_file)]
    np.testing.assert_array_equal(images[0], images[1])
    np.testing.assert_allclose(images[0], images[2], atol=1e-5)  # the PLY's text rounds the coordinates
    # framed as the file is (to the PLY's rounding of the bounds)
    np.testing.assert_allclose(given.camera.position, from_file.camera.position, rtol=1e-6)
    np.testing.assert_allclose(given.lights[0].position, from_file.lights[0].position, rtol=1e-6)
    assert (images[0] > 0).any()


def test_the_estimate_counts_the_held_triangles_and_refuses_past_the_budget():
    fine = trimesh.creation.icosphere(subdivisions=5)
    scene = rp.mesh_scene(fine, overrides=SIZE)
    found = estimate_memory(scene)
    assert found.triangles == len(fine.faces) == 20480 and found.geometry > found.image
    with pytest.raises(rp.SceneError, match=r"objects\.0\.path: '<arrays \d+>' needs .* \(20,480 triangles"):
        rp.render(scene, max_memory=found.geometry)


def test_no_file_is_looked_for_and_replace_keeps_the_mesh(sphere, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # an empty folder: nothing named like the placeholder exists
    scene = rp.mesh_scene(sphere, overrides=SIZE).replace({"render.width": 32, "materials.default.kd": 0.5})
    assert scene.objects[0].path.startswith("<arrays ")
    assert rp.render(scene).image.shape == (36, 32, 3)
    assert list(tmp_path.iterdir()) == []


def test_the_arrays_are_copied_when_the_scene_is_made(sphere):
    vertices = np.array(sphere.vertices)
    scene = rp.mesh_scene(vertices, np.asarray(sphere.faces), overrides=SIZE)
    before = rp.render(scene).image
    vertices *= 0.5
    np.testing.assert_array_equal(rp.render(scene).image, before)


@pytest.mark.parametrize(("vertices", "faces", "line"), [
    ([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]], [[0, 1, 2]], "mesh_scene: vertices: 1 vertex(es) of a face with NaN"),
    ([[0, 0, 0], [1, 0, 0], [0, 2e18, 0]], [[0, 1, 2]], "beyond ±1e+18"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 3]], "mesh_scene: faces: faces name vertex 3, but the mesh has 3"),
    ([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.zeros((0, 3), int), "the mesh has no faces"),
    ([[0, 0, 0], [0, 0, 0], [0, 0, 0]], [[0, 1, 2]], "every vertex of the model lies within"),
])
def test_values_a_file_would_be_refused_for_are_one_line(vertices, faces, line):
    with pytest.raises(rp.SceneError) as error:
        rp.mesh_scene(np.asarray(vertices, float), faces)
    assert line in str(error.value) and "\n" not in str(error.value)


@pytest.mark.parametrize(("vertices", "faces", "words"), [
    (np.zeros((3, 2)), [[0, 1, 2]], "vertices must be an array of shape (N, 3) of real numbers, got shape (3, 2)"),
    (np.eye(3), [[0.0, 1.0, 2.0]], "faces must be an array of shape (N, 3) of whole numbers"),
    (np.eye(3), [0, 1, 2], "got shape (3,)"),
])
def test_arrays_of_the_wrong_shape_or_kind_say_what_is_wanted(vertices, faces, words):
    with pytest.raises(ValueError, match=None) as error:
        rp.mesh_scene(vertices, faces)
    assert words in str(error.value)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_normals_that_are_not_finite_are_refused_in_one_line(bad):
    """A NaN or infinite normal would shade its pixels NaN: refused as a file's would be, naming the key."""
    normals = np.array([[0, 0, 1], [0, 0, 1], [0, bad, 1]], float)
    with pytest.raises(rp.SceneError) as error:
        rp.mesh_scene(np.eye(3), [[0, 1, 2]], normals=normals)
    assert "normals: normals hold NaN or infinite values; allowed: finite (V, 3)" in str(error.value)
    assert "\n" not in str(error.value)
    rp.mesh_scene(np.eye(3), [[0, 1, 2]], normals=normals[[0, 0, 0]])  # finite: taken


def test_given_normals_shade_as_a_files_own(sphere):
    """Normals given with the arrays are the object's own ("file") normals: the sphere's exact ones shade as the
    built-in icosphere of the same triangles with normals = "exact"."""
    exact = np.asarray(sphere.vertices) / np.linalg.norm(sphere.vertices, axis=1)[:, None]
    given = rp.mesh_scene(sphere, normals=exact, overrides=SIZE)
    assert given.objects[0].crease_angle == 180  # a file that stores normals is not creased
    built = given.replace({"objects.0": {"shape": "icosphere", "subdivisions": 2, "normals": "exact"}})
    without = rp.mesh_scene(sphere, overrides=SIZE)
    image = rp.render(given).image
    np.testing.assert_allclose(image, rp.render(built).image, atol=2e-5)
    assert np.abs(image - rp.render(without).image).max() > 1e-3  # the mean normals the mesh alone gets differ


MODELS = __import__("pathlib").Path(__file__).resolve().parents[1] / "data" / "models"


def _as_file_frames(mesh, path, size=SIZE):
    """(the Trimesh's scene, the file's scene) with the file's colour encoding and background (a glTF's colours
    are linear; arrays say nothing, so they are framed for display unless told)."""
    from_file = rp.load_scene(path, size)
    colour = getattr(from_file.render.colour, "value", from_file.render.colour)
    given = rp.mesh_scene(mesh, overrides=[*size, f"render.colour={colour}",
                                           f"render.background={list(from_file.render.background)}"])
    return given, from_file


@pytest.mark.parametrize("name", ["BoxTextured.glb", "cubevc.glb"])
def test_a_trimesh_keeps_its_material_texture_and_colours_as_its_file_does(name):
    """issue 48: mesh_scene(trimesh) dropped the visual (a red box rendered grey). A Trimesh trimesh loaded from a
    textured glTF (metallic-roughness, a base colour map, UVs) or one with vertex colours renders as the file
    itself does, read by the renderer's own reader."""
    mesh = trimesh.load(MODELS / name, force="mesh")
    given, from_file = _as_file_frames(mesh, MODELS / name)
    image, expected = rp.render(given).image, rp.render(from_file).image
    assert np.abs(expected - expected[0, 0]).max() > 0.1  # not a blank frame
    np.testing.assert_allclose(image, expected, atol=1e-6)


def test_a_face_coloured_trimesh_renders_as_its_ply(tmp_path):
    """A box whose faces trimesh colours red, given as the Trimesh and as the PLY trimesh writes of it."""
    box = trimesh.creation.box()
    box.visual.face_colors = [255, 0, 0, 255]
    path = tmp_path / "red.ply"
    box.export(path)
    given, from_file = _as_file_frames(box, path)
    image = rp.render(given).image
    np.testing.assert_allclose(image, rp.render(from_file).image, atol=1e-6)
    covered = np.abs(image - image[0, 0]).max(axis=-1) > 1e-3
    assert covered.sum() > 100 and (image[covered, 0] > 2 * image[covered, 1]).mean() > 0.9  # red, not grey


def test_a_trimesh_s_simple_material_is_read_as_its_mtl_is(tmp_path):
    """trimesh reads an OBJ's .mtl into a SimpleMaterial (8-bit colours, glossiness, an image): on the lecture's
    model it gives the .mtl's own reading (k_a, k_d, k_s through the lobe rule, f), and its image is the k_d map,
    weighed by the memory estimate at its size."""
    from PIL import Image
    mesh = trimesh.load(MODELS / "fuze.obj", force="mesh", process=False)
    given = rp.mesh_scene(mesh)
    assert dict(given.materials) == dict(rp.load_scene(MODELS / "fuze.obj").materials)
    (source,) = given.mesh_sources.values()
    with Image.open(MODELS / "fuze uv.jpg") as image:
        assert source.texture_sizes == ((image.height, image.width),)
    assert [m.kd_map for m in source.read().materials] == [0]


def test_a_vertex_at_exactly_the_position_limit_is_taken_and_only_those_past_it_counted():
    """Coordinates may be ±POSITION_LIMIT (1e18) exactly: such arrays are taken; beside a vertex past it, the
    refusal counts only that one. Catches `<=` made `<` in the check and in its count."""
    from raycast_phong.scene.mesh_arrays import held_mesh
    from raycast_phong.tolerances import POSITION_LIMIT
    assert POSITION_LIMIT == 1e18
    edge = [[0, 0, 0], [1e18, 0, 0], [0, -1e18, 0]]
    held_mesh(np.asarray(edge, float), [[0, 1, 2]])  # (mesh_scene then refuses to frame it: the test below)
    with pytest.raises(rp.SceneError, match=r"vertices: 1 vertex\(es\) of a face with NaN, infinite or beyond"):
        held_mesh(np.asarray([*edge, [0, 0, 2e18]], float), [[0, 1, 2], [0, 1, 3]])


@pytest.mark.parametrize("size, framed", [(1e17, True), (1e18, False)])
def test_a_model_whose_framing_camera_would_pass_the_position_limit_is_refused_for_its_extent(tmp_path, size, framed):
    """A model 1e18 across is taken as arrays (every coordinate within ±1e18) but its framing camera would stand
    past 1e18: refused naming the model's extent, not a camera.position the caller never gave, for arrays and for
    a file alike (one home: scene.framing); one 1e17 across frames, its camera within the limit."""
    from typer.testing import CliRunner

    from raycast_phong.cli import app
    vertices = np.asarray([[0, 0, 0], [size, 0, 0], [0, size, 0]], float)
    path = tmp_path / "far.obj"
    path.write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in vertices.tolist()) + "f 1 2 3\n")
    if framed:
        assert max(abs(x) for x in rp.mesh_scene(vertices, [[0, 1, 2]]).camera.position) < 1e18
        return
    extent = r"a model 1.41e\+18 across at \[5e\+17, 5e\+17, 0.0\] is too large"
    with pytest.raises(rp.SceneError, match=extent) as error:
        rp.mesh_scene(vertices, [[0, 1, 2]])
    assert "camera.position" not in str(error.value)
    done = CliRunner().invoke(app, ["scene", str(path)])
    assert done.exit_code == 2 and "far.obj" in done.output and "too large or too far out to frame" in done.output
    assert "camera.position" not in done.output and len(done.output.strip().splitlines()) == 1, done.output


def test_only_the_positions_the_framing_chose_are_held_to_the_limit():
    """A model 1e18 across with the camera and light positions its user gave is shown from there (the framing
    placed nothing past the limit); one 1e17 across whose `camera.fov = 1` puts the framing camera ~40 times
    farther is refused for its extent, as the default framing of a larger one is. Catches the check made before
    the overrides (then the user's own positions did not count, and the narrow field of view went unseen)."""
    large = np.asarray([[0, 0, 0], [1e18, 0, 0], [0, 1e18, 0]], float)
    given = ["camera.position=[5e17, 5e17, 9e17]", "camera.look_at=[5e17, 5e17, 0]", "lights.0.position=[0, 0, 9e17]"]
    assert rp.mesh_scene(large, [[0, 1, 2]], overrides=given).camera.position == (5e17, 5e17, 9e17)
    with pytest.raises(rp.SceneError, match=r"too large or too far out to frame") as error:
        rp.mesh_scene(large / 10, [[0, 1, 2]], overrides=["camera.fov=1"])
    assert "camera.position" not in str(error.value)


def test_a_mesh_file_s_scene_carries_the_source_its_framing_read(tmp_path):
    """load_scene of a mesh file keeps the MeshSource the framing made (Scene.mesh_sources, under the file's real
    path), as mesh_scene keeps its arrays' source, so prepare() does not read the file a second time."""
    from raycast_phong.io.meshes.source import source_key
    path = tmp_path / "tri.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    scene = rp.load_scene(path)
    assert list(scene.mesh_sources) == [source_key(path)]
    assert scene.mesh_sources[source_key(path)].triangles() == 1


def test_only_the_vertices_a_face_uses_are_checked_and_framed():
    """As a file's read: a vertex no face names may be NaN or far out (it is never drawn), and the framing's
    bounding sphere holds the used vertices only, so the scene is the one without it."""
    from raycast_phong.scene.mesh_arrays import held_mesh
    used = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]])
    for stray in ([np.nan, 0.0, 0.0], [0.0, 0.0, 1e30], [50.0, 50.0, 50.0]):
        held = held_mesh(np.vstack([used, stray]), [[0, 1, 2]])[1].held
        assert held.centre.tolist() == [1.0, 1.0, 0.0] and held.radius == pytest.approx(math.sqrt(2.0))
        scene = rp.mesh_scene(np.vstack([used, stray]), [[0, 1, 2]])
        assert scene.camera == rp.mesh_scene(used, [[0, 1, 2]]).camera


def test_a_negative_face_index_is_refused_naming_it():
    """A face index below 0 names no vertex (numpy would read -1 as the last one): refused as one past the end
    is, naming the index and the range allowed."""
    with pytest.raises(rp.SceneError) as error:
        rp.mesh_scene(np.eye(3), [[0, 1, -1]])
    assert "faces: faces name vertex -1, but the mesh has 3 vertices; allowed: 0 ≤ index < 3" in str(error.value)


def test_a_trimesh_s_given_vertex_normals_are_its_own():
    """A Trimesh made with vertex normals (cached by trimesh) keeps them as a file's stored normals, as when they
    are passed as `normals`; one without gets none (trimesh would compute them on asking)."""
    from raycast_phong.scene.mesh_arrays import held_mesh
    normals = np.array([[0.0, 0.6, 0.8]] * 3)
    given = trimesh.Trimesh(np.eye(3), [[0, 1, 2]], vertex_normals=normals, process=False)
    held = held_mesh(given)[1].held
    assert held.stores_normals and np.allclose(held.normals, normals)
    bare = held_mesh(trimesh.Trimesh(np.eye(3), [[0, 1, 2]], process=False))[1].held
    assert not bare.stores_normals and bare.normals is None


def test_a_trimesh_texture_s_size_is_height_then_width():
    """ArraySource.texture_sizes are (height, width), as every MeshSource's, though PIL says (width, height): an
    image 8 wide and 2 tall is (2, 8)."""
    from PIL import Image

    from raycast_phong.scene.mesh_arrays import held_mesh
    box = trimesh.creation.box()
    uv = np.random.default_rng(0).random((len(box.vertices), 2))
    box.visual = trimesh.visual.TextureVisuals(uv=uv, image=Image.new("RGB", (8, 2), (200, 10, 10)))
    assert held_mesh(box)[1].texture_sizes == ((2, 8),)
