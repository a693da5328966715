"""A large mesh's BVH built on a thread of its own while its normals are made (prepare.BuildAhead): the same BVH,
so the same image, bit for bit, as the one render() builds after the preparation; an error of the build still
reaches the caller; a prepare() that is not rendered (the plan command, the warm-up) starts nothing."""

from __future__ import annotations

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong import shapes
from raycast_phong.errors import EmbreeError
from raycast_phong.renderer import prepare as module
from raycast_phong.renderer.intersect import Accelerator


@pytest.fixture
def low_threshold(monkeypatch):
    """Build ahead from 1,000 faces, so that small meshes take the path a 1M-triangle scan takes."""
    monkeypatch.setattr(module, "BUILD_AHEAD_FACES", 1000)


def bumpy_mesh_scene(overrides: tuple[str, ...] = ()):
    """An icosphere's 5,120 faces with its points moved at random, some faces wound the wrong way (the repair flips
    them before they are placed), given as arrays: one mesh object, as render_file of a scan makes."""
    vertices, faces = shapes.icosphere(4)
    rng = np.random.default_rng(5)
    vertices = vertices * (1 + 0.03 * rng.standard_normal((len(vertices), 1)))
    faces = np.asarray(faces).copy()
    faces[::7] = faces[::7, ::-1]
    return rp.mesh_scene(vertices, faces, overrides=["render.width=48", "render.height=36", *overrides])


def spheres_scene():
    """Three icospheres in two groups (5,120 faces each outside, 1,280 in the middle): their BVH starts once every
    object is placed."""
    return rp.validate_scene({
        "render": {"width": 48, "height": 36},
        "camera": {"position": [0, 0, 6], "look_at": [0, 0, 0]},
        "objects": [{"shape": "icosphere", "subdivisions": 4 if x else 3, "translate": [x, 0, 0],
                     "scale": [0.7, 0.7, 0.7]} for x in (-1.5, 0, 1.5)],
    })


SCENES = {
    "one mesh, placed": lambda: bumpy_mesh_scene(("objects.0.scale=[1.5, 0.5, 1]", "objects.0.rotate=[20, 40, 10]",
                                                  "objects.0.translate=[3, -2, 1]")),
    "one mesh, crease 60": lambda: bumpy_mesh_scene(("objects.0.crease_angle=60",)),
    "three objects": spheres_scene,
}


@pytest.mark.parametrize("name", SCENES)
def test_the_bvh_built_ahead_gives_the_image_of_the_one_built_after(low_threshold, name):
    scene = SCENES[name]()
    ahead = module.Renderer(threads=2).prepare(scene, build_ahead=True)
    assert ahead.ahead is not None and ahead.ahead.started
    image = ahead.render().image
    after = module.Renderer(threads=2).prepare(scene)
    assert after.ahead is None
    expected = after.render().image
    assert (expected > 0).any()
    np.testing.assert_array_equal(image, expected)
    np.testing.assert_array_equal(ahead.render().image, expected)  # a second render builds its own
    np.testing.assert_array_equal(rp.render(scene, threads=2).image, expected)


def test_the_build_ahead_gets_the_placed_vertices_and_the_geometrys_faces(low_threshold, monkeypatch):
    """The BVH is built from the Geometry's own world vertices and int32 faces (no copies), in its unit frame."""
    seen = []
    monkeypatch.setattr(Accelerator, "of_mesh", classmethod(
        lambda cls, vertices, faces, frame: seen.append((vertices, faces, frame)) or Accelerator.__new__(cls)))
    ready = module.Renderer(threads=2).prepare(SCENES["one mesh, placed"](), build_ahead=True)
    ready.ahead.take()
    (vertices, faces, frame), = seen
    geometry = ready.geometry
    assert np.shares_memory(vertices, geometry.vertices) and faces is geometry.faces and faces.dtype == np.int32
    np.testing.assert_array_equal(vertices, geometry.vertices)
    assert frame is ready.frame
    np.testing.assert_array_equal(frame.center, module.unit_frame(geometry.vertices).center)


def test_an_error_of_the_build_ahead_reaches_the_caller(low_threshold, monkeypatch):
    def refused(cls, vertices, faces, frame):
        raise EmbreeError("Embree failed while building the BVH: out of memory")
    monkeypatch.setattr(Accelerator, "of_mesh", classmethod(refused))
    with pytest.raises(EmbreeError, match="out of memory"):
        rp.render(bumpy_mesh_scene(), threads=2)


def test_nothing_is_built_ahead_unless_a_render_on_two_threads_asks_for_it(low_threshold):
    scene = bumpy_mesh_scene()
    assert module.Renderer(threads=2).prepare(scene).ahead is None  # the plan command, the accuracy tools, the warm-up
    assert module.Renderer(threads=1).prepare(scene, build_ahead=True).ahead is None  # a batch worker's one thread
    assert not module.Renderer(threads=2).prepare(spheres_scene(), build_ahead=False).ahead


def test_a_mesh_below_the_threshold_builds_after():
    scene = bumpy_mesh_scene()
    assert len(scene.mesh_sources) == 1 and module.BUILD_AHEAD_FACES > 5120
    ready = module.Renderer(threads=2).prepare(scene, build_ahead=True)
    assert not ready.ahead.started
    assert (ready.render().image > 0).any()
