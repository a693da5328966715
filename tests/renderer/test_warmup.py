"""The CLI's warm-up covers every kernel a scene's render calls, so the "compiling" notice is said before any of
them compiles and no kernel loads inside the timed stages: the mesh preparation's too (issue 22)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from raycast_phong import compiles
from raycast_phong.geometry import kernels
from raycast_phong.geometry.mesh_repair import MESH_FILE_KERNELS
from raycast_phong.geometry.normals import CREASE_KERNELS
from raycast_phong.renderer import warmup
from raycast_phong.scene.schema import validate_scene


def mesh_scene(tmp_path):
    trimesh.creation.icosphere(1).export(tmp_path / "ball.ply")
    return validate_scene({"objects": [{"shape": "mesh", "path": str(tmp_path / "ball.ply")}]}, source="t")


def missing(monkeypatch, module, name: str, kernel: str) -> None:
    """`module.name` (a warm-up) meets a cache miss of `kernel`, as numba's cache reports one (compiles.compiling)."""
    warm = getattr(module, name)

    def missed(*args, **options):
        compiles.compiling(kernel, "(float64, int64)")
        try:
            return warm(*args, **options)
        finally:
            compiles.compiled()  # as numba's save would: an open compile left here stopped later tests' counting
    monkeypatch.setattr(module, name, missed)


def test_a_mesh_file_scene_is_told_it_compiles_when_only_its_preparation_kernels_are_missing(tmp_path, monkeypatch):
    from raycast_phong.geometry import mesh_repair
    said = []
    missing(monkeypatch, mesh_repair, "warm_up_merge", "raycast_phong.geometry.kernels.merge_rows")  # the rest cached
    assert warmup.ready_kernels(mesh_scene(tmp_path), said.append)[0] == "compile" and len(said) == 1
    # Named for what compiles, with its own estimate (it was "the float32 shading kernels ... 13-18 s").
    assert said[0] == ("compiling the mesh preparation's kernels (merge, winding), the first time a scene needs them "
                       "after an install or an edit (a few seconds)...")
    said.clear()  # a scene of built-in shapes calls none of them: nothing to say
    shapes = validate_scene({"objects": [{"shape": "icosphere"}]}, source="t")
    assert warmup.ready_kernels(shapes, said.append)[0] == "kernels" and said == []


def test_an_obj_scene_is_told_it_compiles_when_only_its_polygon_scan_is_missing(tmp_path, monkeypatch):
    """Reading an OBJ calls the polygon scan's kernels (io/meshes/obj_polygons.py); a PLY does not."""
    from raycast_phong.io.meshes import obj_polygons
    said = []
    missing(monkeypatch, obj_polygons, "warm_up", "raycast_phong.io.meshes.obj_polygons._scan")  # the rest cached
    trimesh.creation.icosphere(1).export(tmp_path / "ball.obj")
    obj = validate_scene({"objects": [{"shape": "mesh", "path": str(tmp_path / "ball.obj")}]}, source="t")
    assert warmup.ready_kernels(obj, said.append)[0] == "compile" and len(said) == 1
    assert said[0].startswith("compiling the mesh reader's kernels, the first time a scene needs them"), said
    said.clear()
    assert warmup.ready_kernels(mesh_scene(tmp_path), said.append)[0] == "kernels" and said == []


@pytest.mark.parametrize(("first", "said_first"), [
    ("raycast_phong.renderer.kernels.shadows.no_shadow_rays", "compiling the float32 shading kernels"),
    ("raycast_phong.renderer.kernels.shadows.cast_shadows", "compiling the shadow rays' kernels (global mode)")])
def test_a_local_scene_s_shadow_stand_in_is_announced_as_the_shading_kernels(monkeypatch, first, said_first):
    """A scene in local mode hands the tile kernel shadows.no_shadow_rays (by_address.py), which may be the first
    kernel a fresh install compiles on a busy machine: the notice must not call it global mode's shadow rays
    (a first STL render from a wheel said so); cast_shadows is those."""
    from raycast_phong.renderer import frame
    said = []
    missing(monkeypatch, frame, "warm_kernels_for", first)
    scene = validate_scene({"objects": [{"shape": "icosphere"}]}, source="t")
    assert warmup.ready_kernels(scene, said.append)[0] == "compile" and len(said) == 1
    assert said[0].startswith(said_first), said


def test_a_kernel_compiled_for_float32_only_is_told_to_compile_for_float64(tmp_path):
    """The cache holds a kernel per signature: a float64 call after float32 ones compiles, and is told so (it
    was silent when the check asked for "some signature"). A kernel of its own in a fresh cache folder, in a
    process of its own: three calls, three processes."""
    module = tmp_path / "tiny_kernel.py"
    module.write_text("from raycast_phong.jit import kernel\n\n@kernel()\ndef twice(x):\n    return x + x\n")
    code = ("import sys, numpy as np; sys.path.insert(0, sys.argv[1]); from raycast_phong import compiles, jit\n"
            "jit.LIGHT_LOAD = sys.argv[3] == 'light'\n"
            "with compiles.told(lambda name, sig: print('told', name, sig)) as heard:\n"
            "    import tiny_kernel; assert tiny_kernel.twice(getattr(np, sys.argv[2])(1.5)) == 3\n"
            "print('heard', heard)\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    told = []
    # The last process loads as numba itself does (jit.LIGHT_LOAD off: numba's internals it relies on missing):
    # slower to start, the same kernel, and a cached one is still not told.
    for precision, load in (("float32", "light"), ("float32", "light"), ("float64", "light"), ("float64", "numba")):
        done = subprocess.run([sys.executable, "-c", code, str(tmp_path), precision, load], capture_output=True,
                              text=True, timeout=300, env=env)
        assert done.returncode == 0, done.stderr
        told.append(done.stdout)
    # the first call: compiled, and told first
    assert told[0] == "told tiny_kernel.twice (float32,)\nheard ['tiny_kernel.twice']\n", told[0]
    assert told[1] == "heard []\n", told[1]  # the same signature again: loaded from the cache, nothing told
    assert told[2] == "told tiny_kernel.twice (float64,)\nheard ['tiny_kernel.twice']\n", told[2]
    assert told[3] == "heard []\n", told[3]


def test_the_warm_up_loads_the_mesh_preparation_kernels_with_the_types_a_file_gives_them(tmp_path):
    """After ready_kernels, preparing real files (a PLY's float64 points, a binary STL's float32 corners) adds no
    signature to any kernel: none compiles or loads inside the geometry stage."""
    from raycast_phong.geometry.build import build_geometry
    scene = mesh_scene(tmp_path)
    warmup.ready_kernels(scene)
    every = {name: getattr(kernels, name) for name in dir(kernels) if hasattr(getattr(kernels, name), "signatures")}
    assert all(every[name].signatures for name in (*MESH_FILE_KERNELS, *CREASE_KERNELS))
    before = {name: len(dispatcher.signatures) for name, dispatcher in every.items()}
    mesh = trimesh.creation.icosphere(2)
    trimesh.Trimesh(mesh.vertices[mesh.faces].reshape(-1, 3), np.arange(3 * len(mesh.faces)).reshape(-1, 3),
                    process=False).export(tmp_path / "ball.stl")
    flipped = mesh.faces.copy()
    flipped[::7] = flipped[::7, ::-1]  # inconsistent: the orientation pass
    trimesh.Trimesh(mesh.vertices, flipped, process=False).export(tmp_path / "flipped.ply")
    for name in ("ball.ply", "ball.stl", "flipped.ply"):
        scene = validate_scene({"objects": [{"shape": "mesh", "path": str(tmp_path / name)}]}, source="t")
        build_geometry(scene, normal_dtype=np.float32)  # render()'s, shading in float32
    assert {name: len(dispatcher.signatures) for name, dispatcher in every.items()} == before


def test_numba_s_set_up_leaves_scipy_linalg_unimported():
    """numba's first kernel call imports scipy.linalg for a BLAS probe (0.15-0.2 s of start-up) unless jit.set_up
    answers it first; the kernels still run."""
    code = ("import sys, numpy as np; from raycast_phong.geometry.normals import face_normals; "
            "unit, area = face_normals(np.eye(3), np.array([[0, 1, 2]])); assert area[0] > 0; "
            "print('scipy.linalg' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "False"


def test_a_missing_mesh_file_is_refused_before_the_compiling_notice(tmp_path, monkeypatch):
    """The first render after an install compiles for a minute: a scene whose mesh file is missing is told so at
    once, in the read's own words, and never hears "compiling" first."""

    from raycast_phong.errors import SceneError
    from raycast_phong.renderer import frame
    said = []
    missing(monkeypatch, frame, "warm_kernels_for", "render_band")  # nothing cached: the notice would be said
    scene = validate_scene({"objects": [{"shape": "icosphere"}, {"shape": "mesh", "path": str(tmp_path / "no.ply")}]},
                           source="s.toml")
    with pytest.raises(SceneError, match=r"^s\.toml: objects\.1\.path: no such mesh file"):
        warmup.ready_kernels(scene, said.append)
    assert said == []
    shapes = validate_scene({"objects": [{"shape": "icosphere"}]}, source="t")  # the control: it is said
    assert warmup.ready_kernels(shapes, said.append)[0] == "compile" and len(said) == 1


def test_the_plain_obj_scan_is_warmed_only_for_an_obj_it_may_read(tmp_path, monkeypatch):
    """io/meshes/obj_plain.py's scan runs on an OBJ that names no material library; one that does (its first MB says
    `mtllib`) never reaches it, so its first render does not compile it (leave out what a scene does not need)."""
    from raycast_phong.io.meshes import obj_plain
    warmed = []
    monkeypatch.setattr(obj_plain, "warm_up", lambda: warmed.append(True))
    mesh = trimesh.creation.icosphere(1)
    mesh.export(tmp_path / "plain.obj")
    (tmp_path / "named.obj").write_text("mtllib named.mtl\n" + (tmp_path / "plain.obj").read_text())
    for name, expected in (("named.obj", []), ("plain.obj", [True])):
        warmed.clear()
        warmup.ready_kernels(validate_scene({"objects": [{"shape": "mesh", "path": str(tmp_path / name)}]},
                                            source="t"))
        assert warmed == expected, name


@pytest.mark.parametrize("line_end", ["\n", "\r"])
def test_the_ascii_ply_rows_are_warmed_only_for_an_ascii_ply(tmp_path, monkeypatch, line_end):
    """ply_rows.number_rows reads an ASCII PLY's rows; a binary PLY (numpy views) never runs it, so its first render
    does not compile it. A header of carriage-return lines (the PLY description's own line end) is ASCII too."""
    from raycast_phong.io.meshes import ply_lists
    warmed = []
    monkeypatch.setattr(ply_lists, "warm_up", lambda: warmed.append(True))
    mesh = trimesh.creation.icosphere(1)
    mesh.export(tmp_path / "binary.ply")
    text = mesh.export(file_type="ply", encoding="ascii")
    (tmp_path / "ascii.ply").write_bytes(text.replace(b"\n", line_end.encode()))
    for name, expected in (("binary.ply", []), ("ascii.ply", [True])):
        warmed.clear()
        warmup.ready_kernels(validate_scene({"objects": [{"shape": "mesh", "path": str(tmp_path / name)}]},
                                            source="t"))
        assert warmed == expected, name


def test_an_obj_given_alone_is_not_warmed_again_after_its_framing_read(tmp_path, monkeypatch):
    """A mesh file given alone is read to frame its camera (load_scene), and that read, which compiled the reader
    kernels it needed, waits for the render (its MeshSource holds it): the warm-up leaves the OBJ reader alone (a file
    of triangles never needs the concave-polygon test, 1.5 s of compile). A scene file that names the OBJ is read
    only in the render: then the reader is warmed first."""
    import raycast_phong as rp
    from raycast_phong.io.meshes import obj_polygons
    warmed = []
    monkeypatch.setattr(obj_polygons, "warm_up", lambda: warmed.append(True))
    trimesh.creation.icosphere(1).export(tmp_path / "ball.obj")
    warmup.ready_kernels(rp.load_scene(tmp_path / "ball.obj"))
    assert warmed == []
    warmup.ready_kernels(validate_scene({"objects": [{"shape": "mesh", "path": str(tmp_path / "ball.obj")}]},
                                        source="t"))
    assert warmed == [True]


WARM_MODE = """
import sys
import raycast_phong as rp
from raycast_phong.renderer.kernels import shadows
from raycast_phong.renderer.warmup import ready_kernels
scene = rp.validate_scene({"render": {"mode": sys.argv[1]}, "lights": [{"type": "point", "position": [2, 2, 3]}],
                           "objects": [{"shape": "icosphere"}]}, source="t")
ready_kernels(scene)
print(len(shadows.cast_shadows.overloads), len(shadows.no_shadow_rays.overloads))
"""


def test_global_mode_s_shadow_rays_are_made_ready_only_for_a_scene_in_global_mode():
    """The tile kernel calls the shadow rays by address (renderer/by_address.py), so its own warm-up does not bring
    them: ready_kernels does, for a scene in global mode (their compile is then announced and kept out of the frame),
    and leaves them out for a local one, which gets the stand-in."""
    counts = {}
    for mode in ("local", "global"):
        done = subprocess.run([sys.executable, "-c", WARM_MODE, mode], capture_output=True, text=True, timeout=300,
                              env={k: v for k, v in os.environ.items() if k != "RAYCAST_PHONG_COMPILE_PROCESSES"})
        assert done.returncode == 0, done.stderr
        counts[mode] = done.stdout.split()
    assert counts == {"local": ["0", "1"], "global": ["1", "1"]}, counts
