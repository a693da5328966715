"""Resource guards: a scene too large for the memory is refused before anything is built, only regular
files are read, and many objects cost one warning line, not one per object.

The oversized scenes run in a subprocess under a real address-space limit (RLIMIT_AS, 2 GiB) and a
timeout: without the guard they would fail there (MemoryError, exit 1) instead of eating the machine;
the FIFOs are real ones (os.mkfifo), which block a reader forever without the guard.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

import raycast_phong as rp
from raycast_phong.codes import StageName
from raycast_phong.geometry.build import build_geometry
from raycast_phong.io.meshes.source import mesh_source
from raycast_phong.io.scene_file import MAX_SCENE_BYTES
from raycast_phong.io.system import default_budget, parse_size
from raycast_phong.renderer.budget import check_memory, estimate_memory, shape_triangles
from raycast_phong.renderer.diagnosis import diagnose, group_median

CLI = [sys.executable, str(Path(__file__).parents[2] / "cli.py")]
ADDRESS_SPACE = 2 << 30  # plenty for the small renders here (measured: the default scene renders under it)
TIMEOUT = 120  # seconds: a guarded refusal takes about one; a blocked read would take forever


def run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """The CLI in a fresh process with a 2 GiB address space; TimeoutExpired fails the test."""
    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))
    env = {k: v for k, v in os.environ.items() if k != "RAYCAST_PHONG_DEBUG"}
    return subprocess.run([*CLI, *args], cwd=cwd, capture_output=True, text=True, timeout=TIMEOUT,
                          preexec_fn=limit, env=env, stdin=subprocess.DEVNULL)


def assert_one_line_refusal(done: subprocess.CompletedProcess, *needles: str, code: int = 2) -> str:
    lines = done.stderr.strip().splitlines()
    assert done.returncode == code, done.stderr
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


def scene_file(folder: Path, objects: list[dict], render: dict | None = None, name: str = "scene.json",
               output: dict | None = None) -> Path:
    path = folder / name
    data = {"render": {"width": 16, "height": 12, **(render or {})}, "lights": [{"position": [2, 2, 3]}],
            "objects": objects}
    if output:
        data["output"] = output
    path.write_text(json.dumps(data), encoding="utf-8")
    return path


# ---------------------------------------------------------------- the estimate


@pytest.mark.parametrize("obj", [
    {"shape": "icosphere", "subdivisions": 0}, {"shape": "icosphere", "subdivisions": 2},
    {"shape": "uv_sphere"}, {"shape": "uv_sphere", "segments": [5, 3]}, {"shape": "uv_sphere", "segments": [7, 9]},
    {"shape": "box"}, {"shape": "plane"}, {"shape": "plane", "segments": [3, 5]},
    {"shape": "cylinder"}, {"shape": "cylinder", "segments": [7, 3]},
    {"shape": "torus"}, {"shape": "torus", "segments": [3, 5]},
], ids=lambda obj: "-".join(str(v) for v in obj.values()))
def test_the_estimate_counts_the_triangles_trimesh_builds(obj):
    """The guard's count from the keys alone equals the built mesh's, so the estimate follows trimesh."""
    scene = rp.validate_scene({"objects": [obj]})
    assert shape_triangles(scene.objects[0]) == build_geometry(scene).triangles


@pytest.mark.parametrize("suffix, options", [(".obj", {}), (".ply", {}), (".ply", {"encoding": "ascii"}),
                                             (".stl", {}), (".off", {}), (".glb", {})])
def test_mesh_file_triangles_are_read_from_the_header(tmp_path, suffix, options):
    mesh = trimesh.creation.icosphere(subdivisions=2)  # 320 triangles
    path = tmp_path / f"sphere{suffix}"
    mesh.export(path, **options)
    assert mesh_source(path).triangles() == 320


def test_an_ascii_stl_is_bounded_by_its_size(tmp_path):
    path = tmp_path / "sphere.stl"
    trimesh.creation.icosphere(subdivisions=2).export(path, file_type="stl_ascii")
    assert 320 <= mesh_source(path).triangles() <= path.stat().st_size // 86


def test_an_obj_polygon_counts_its_fan_of_triangles(tmp_path):
    path = tmp_path / "quads.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nf 1 2 3 4\nf 1 2 3 4 5\nf\t1 2 3\n")
    assert mesh_source(path).triangles() == 2 + 3 + 1


@pytest.mark.parametrize("text, expected", [("8G", 8 << 30), ("500M", 500 << 20), ("1.5GiB", 3 << 29),
                                            ("2048", 2048), ("64k", 64 << 10), (" 2 TB ", 2 << 40)])
def test_sizes_are_read_in_binary_units(text, expected):
    assert parse_size(text) == expected


@pytest.mark.parametrize("text", ["", "0", "-1G", "8X", "G", "1e9", "8 G B"])
def test_a_malformed_size_is_refused(text):
    with pytest.raises(ValueError, match="expected a size"):
        parse_size(text)


def test_a_malformed_size_of_exactly_the_shown_length_is_echoed_whole():
    """A malformed --max-memory is echoed up to 60 characters of its repr whole (58 letters and the quotes); one
    more is cut to its first 60 and counts the rest."""
    with pytest.raises(ValueError) as whole:
        parse_size("x" * 58)
    assert str(whole.value).endswith("got '" + "x" * 58 + "'")
    with pytest.raises(ValueError) as cut:
        parse_size("x" * 59)
    assert str(cut.value).endswith("got '" + "x" * 59 + "… (1 more characters)")


@pytest.mark.parametrize("count, text", [(1 << 40, "1 TB"), (1 << 30, "1 GB"), ((1 << 30) - 1, "1,024 MB"),
                                         (1 << 20, "1 MB"), (1 << 10, "1 kB"), (1023, "1023 bytes"),
                                         (1000 << 20, "1,000 MB"), (999 << 20, "999 MB"), (1536 << 20, "1.5 GB"),
                                         (1 << 50, "1,024 TB")])
def test_byte_counts_are_written_in_the_largest_unit_they_reach(count, text):
    """format_bytes: a count of exactly a unit is written in it, one byte less in the unit below; three figures,
    and whole units from 999.5 up (a budget of 1000M once read "above the 1e+03 MB budget")."""
    from raycast_phong.io.system import format_bytes
    assert format_bytes(count) == text


@pytest.mark.parametrize("count, text", [(10_000_000, "10M"), (9_949_999, "9.9M"), (1_000_000, "1.0M"),
                                         (999_999, "999,999")])
def test_triangle_counts_are_shortened_from_a_million(count, text):
    """count_text: whole millions from 10M, one decimal from 1M, every digit below."""
    from raycast_phong.io.system import count_text
    assert count_text(count) == text


def test_the_default_budget_is_a_share_of_the_memory_available():
    budget = default_budget()
    assert budget is not None and 0 < budget < os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def test_image_bytes_grow_with_the_pixels_and_the_layers():
    def image(render: dict, aovs: tuple = ()) -> int:
        scene = rp.validate_scene({"render": render, "output": {"aovs": list(aovs)}, "objects": [{"shape": "box"}]})
        return estimate_memory(scene, tile_rays=0).image
    plain = image({"width": 100, "height": 100})
    assert image({"width": 200, "height": 100}) == 2 * plain
    # RGB in float32 (12 B) and its float32 copy for writing (12 B): 24 B a pixel
    assert plain == 100 * 100 * 24
    assert image({"width": 100, "height": 100}, ("depth",)) == 100 * 100 * (24 + 20 + 4)


# ---------------------------------------------------------------- refusals


def test_a_scene_over_the_budget_is_refused_in_python_naming_the_key():
    scene = rp.validate_scene({"objects": [{"shape": "icosphere", "subdivisions": 8}]}, source="s.toml")
    with pytest.raises(rp.SceneError) as refused:
        rp.render(scene, max_memory="64M")  # the message names the scene's own file
    message = str(refused.value)
    assert message.startswith("s.toml: objects.0.subdivisions: 8 needs ≈ ")
    assert "1.3M triangles" in message and "64 MB budget" in message and "--max-memory" in message
    assert check_memory(scene, "8G").triangles == 20 * 4 ** 8  # a larger budget lets it through


def test_the_cli_refuses_a_tessellation_over_the_budget_before_building_it(tmp_path):
    """Three planes of 4096 × 4096 segments, 100M triangles: tens of GB without the guard."""
    planes = [{"shape": "plane", "segments": [4096, 4096], "translate": [i, 0, 0]} for i in range(3)]
    path = scene_file(tmp_path, planes)
    done = run_cli("render", str(path), "-o", "out.png", cwd=tmp_path)
    assert_one_line_refusal(done, "scene.json: objects: 3 objects need ≈ ", "101M triangles", "budget",
                            "objects.0.segments = [4096, 4096]", "--max-memory")
    assert not (tmp_path / "out.png").exists()


@pytest.mark.slow
def test_max_memory_raises_and_lowers_the_budget(tmp_path):
    path = scene_file(tmp_path, [{"shape": "icosphere", "subdivisions": 6}])  # 82k triangles, ≈ 60 MB
    refused = run_cli("render", str(path), "-o", "out.png", "--max-memory", "20M", cwd=tmp_path)
    assert_one_line_refusal(refused, "objects.0.subdivisions: 6", "above the 20 MB budget")
    done = run_cli("render", str(path), "-o", "out.png", "--max-memory", "1G", "-q", cwd=tmp_path)
    assert done.returncode == 0 and (tmp_path / "out.png").stat().st_size > 0, done.stderr


def test_image_layers_over_the_budget_are_refused_naming_the_size(tmp_path):
    path = scene_file(tmp_path, [{"shape": "box"}], render={"width": 16384, "height": 16384},
                      output={"path": "out.exr", "aovs": ["depth", "normal", "face", "ambient", "diffuse",
                                                          "specular", "emission"]})
    done = run_cli("render", str(path), "-o", "out.exr", "--max-memory", "4G", cwd=tmp_path)
    assert_one_line_refusal(done, "render.width × render.height: 16384×16384 pixels and 7 layer(s)",
                            "above the 4 GB budget")


def test_a_malformed_max_memory_is_one_line(tmp_path):
    path = scene_file(tmp_path, [{"shape": "box"}])
    for command in (["render", str(path)], ["plan", str(path)], ["batch", str(path), "--out", "o"],
                    ["side-by-side", str(path), "--vary", "render.shading=flat,phong"], ["study", str(path)]):
        done = run_cli(*command, "--max-memory", "lots", cwd=tmp_path)
        assert_one_line_refusal(done, "--max-memory: expected a size such as 8G")


def test_batch_fails_the_oversized_scene_only(tmp_path):
    folder = tmp_path / "scenes"
    folder.mkdir()
    scene_file(folder, [{"shape": "icosphere", "subdivisions": 8}], name="big.json")
    scene_file(folder, [{"shape": "box"}], name="small.json")
    done = run_cli("batch", str(folder), "--out", "out", "-j", "1", "--max-memory", "100M", cwd=tmp_path)
    assert done.returncode == 1
    failed = [line for line in done.stderr.splitlines() if line.startswith("failed:")]
    assert len(failed) == 1 and "big.json: objects.0.subdivisions: 8" in failed[0] and "budget" in failed[0]
    assert (tmp_path / "out" / "small.png").is_file() and not (tmp_path / "out" / "big.png").exists()


# ---------------------------------------------------------------- only regular files


@pytest.fixture
def fifo(tmp_path) -> Path:
    path = tmp_path / "pipe.toml"
    os.mkfifo(path)
    return path


def test_a_scene_path_that_is_a_fifo_is_refused_at_once(tmp_path, fifo):
    done = run_cli("render", str(fifo), "-o", "out.png", cwd=tmp_path)
    assert_one_line_refusal(done, "pipe.toml", "named pipe (FIFO), not a regular file")


def test_a_device_as_the_scene_is_refused(tmp_path):
    done = run_cli("render", "/dev/zero", "-o", "out.png", cwd=tmp_path)
    assert_one_line_refusal(done, "/dev/zero", "a device, not a regular file")


@pytest.mark.parametrize("kind", ["fifo", "device", "folder"])
def test_a_mesh_path_that_is_not_a_regular_file_is_refused(tmp_path, kind):
    target = {"fifo": "pipe.obj", "device": "/dev/zero", "folder": "meshes"}[kind]
    if kind == "fifo":
        os.mkfifo(tmp_path / target)
    elif kind == "folder":
        (tmp_path / target).mkdir()
    path = scene_file(tmp_path, [{"shape": "mesh", "path": target}])
    for command in (["render", str(path), "-o", "out.png"], ["plan", str(path)]):
        done = run_cli(*command, cwd=tmp_path)
        assert_one_line_refusal(done, "objects.0.path", "not a regular file; give a mesh file")


def test_batch_does_not_block_on_a_fifo_mesh(tmp_path):
    """The batch hashes its inputs before rendering: that read must not wait on a FIFO either."""
    folder = tmp_path / "scenes"
    folder.mkdir()
    os.mkfifo(folder / "pipe.obj")
    scene_file(folder, [{"shape": "mesh", "path": "pipe.obj"}], name="a.json")
    done = run_cli("batch", str(folder), "--out", "out", "-j", "1", cwd=tmp_path)
    assert done.returncode == 1 and "named pipe (FIFO)" in done.stderr, done.stderr


def test_a_scene_file_over_the_size_cap_is_refused_unread(tmp_path):
    path = tmp_path / "huge.toml"
    with open(path, "wb") as handle:
        handle.truncate(MAX_SCENE_BYTES + 1)  # sparse: no disk used
    done = run_cli("render", str(path), "-o", "out.png", cwd=tmp_path)
    assert_one_line_refusal(done, "huge.toml", f"{MAX_SCENE_BYTES + 1:,} bytes", "16 MiB")


# ---------------------------------------------------------------- many objects


def grid_of_spheres(count: int, shading: str) -> rp.Scene:
    side = int(np.ceil(np.sqrt(count)))
    objects = [{"shape": "icosphere", "subdivisions": 1, "radius": 0.4,
                "translate": [i % side - side / 2, i // side - side / 2, 0]} for i in range(count)]
    return rp.validate_scene({"render": {"width": 48, "height": 48, "shading": shading},
                              "camera": {"position": [0, 0, 2 * side]}, "lights": [{"position": [0, 0, 3 * side]}],
                              "objects": objects})


def test_many_objects_with_the_same_warning_share_one_line():
    """300 Gouraud spheres, each with a missed and a sub-pixel highlight: two lines, each with the count."""
    warnings = rp.render(grid_of_spheres(300, "gouraud")).plan.warnings
    assert len(warnings) == 2
    assert all(w.startswith("objects 0, 1, 2 … (300 in all)") for w in warnings), warnings
    assert "(gouraud): vertex normals are 36.0° apart" in warnings[0] and "subdivisions = 3" in warnings[0]
    assert "pixel wide" in warnings[1] and "render.samples = " in warnings[1]


def test_the_grouped_median_is_numpys_median_per_group(rng):
    groups = rng.integers(0, 7, size=500)
    values = rng.normal(size=500)
    medians = group_median(values, groups, 9)
    for group in range(9):
        inside = values[groups == group]
        assert medians[group] == (np.median(inside) if len(inside) else 0.0)


def numpy_object_bounds(vertices, faces, face_object, objects):
    """ObjectFigures' bounds as numpy computed them before the compiled pass (the oracle)."""
    vertex_object = np.full(len(vertices), -1, np.int64)
    vertex_object[faces] = face_object[:, None]
    used = np.flatnonzero(vertex_object >= 0)
    used = used[np.argsort(vertex_object[used], kind="stable")]
    owner, points = vertex_object[used], vertices[used]
    present, first = np.unique(owner, return_index=True)
    centre = np.zeros((objects, 3))
    centre[present] = (np.minimum.reduceat(points, first) + np.maximum.reduceat(points, first)) / 2
    radius = np.zeros(objects)
    radius[present] = np.maximum.reduceat(np.linalg.norm(points - centre[owner], axis=1), first)
    return centre, radius


def test_object_bounds_are_the_numpy_figures_bit_for_bit(rng):
    """Each object's bounding centre and radius over the vertices its faces use (diagnosis' object bounds), from the
    compiled pass: numpy's numbers, with objects in any order, unused vertices, and objects without faces."""
    from raycast_phong.geometry.kernels import object_bounds
    for objects in (1, 5):
        sizes = rng.integers(3, 40, size=objects)
        vertices = rng.normal(size=(int(sizes.sum()), 3)) * rng.uniform(0.1, 1e3) + rng.normal(size=3) * 1e4
        faces, face_object = [], []
        for o, (start, size) in enumerate(zip(np.cumsum(sizes) - sizes, sizes)):
            if objects > 1 and o == 2:
                continue  # an object with no faces: centre and radius stay 0
            faces.append(start + rng.integers(0, size - 1, size=(int(size), 3)))  # its last vertex unused
            face_object.append(np.full(int(size), o, np.int32))
        faces, face_object = np.concatenate(faces).astype(np.int32), np.concatenate(face_object)
        order = rng.permutation(len(faces))
        faces, face_object = faces[order], face_object[order]
        centre, radius = np.zeros((objects, 3)), np.zeros(objects)
        object_bounds(vertices, faces, face_object, centre, radius)
        expected = numpy_object_bounds(vertices, faces, face_object, objects)
        assert centre.tobytes() == expected[0].tobytes() and radius.tobytes() == expected[1].tobytes()


@pytest.fixture
def rng():
    return np.random.default_rng(10)


def test_many_copies_of_a_repaired_mesh_share_one_note(tmp_path):
    """A tetrahedron with one face wound the other way, placed 40 times: one winding note, with the count."""
    (tmp_path / "tet.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 4 3\n")
    def reason(count: int) -> str:
        scene = rp.validate_scene({"objects": [{"shape": "mesh", "path": "tet.obj", "translate": [2 * i, 0, 0]}
                                               for i in range(count)]}, folder=tmp_path)
        plan = rp.build_plan(scene)
        stages = diagnose(plan, scene, build_geometry(scene)).stages
        return next(stage.reason for stage in stages if stage.name == "winding_repair")
    assert reason(1) == "objects.0: the winding of 1 of 4 faces was repaired (and turned outward: the mesh is closed)"
    assert reason(40) == ("objects 0, 1, 2 … (40 in all): the winding of 1 of 4 faces was repaired (and turned "
                          "outward: the mesh is closed)")


PEAK_SCRIPT = """
import json, sys
from pathlib import Path
import raycast_phong as rp
def vm(field):
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1]) * 1024
import trimesh  # the mesh reader's library is code, not the scene's data: part of the baseline
scene = rp.load_scene(sys.argv[1])
rp.render(rp.validate_scene({"render": {"width": 2, "height": 2, "shading": scene.render.shading},
                             "objects": [{"shape": "icosphere"}]}), threads=1)  # kernels loaded: baseline
baseline = vm("VmRSS")
Path("/proc/self/clear_refs").write_text("5")  # VmHWM := VmRSS
rp.render(scene, threads=1)
print(vm("VmHWM") - baseline)
"""


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="needs Linux's /proc/self/clear_refs")
@pytest.mark.parametrize("shading", ["flat", "phong"])
def test_the_estimate_follows_the_measured_peak_of_a_mesh_file(tmp_path, shading):
    """A 327,680-triangle PLY rendered in a fresh process: the estimate covers the real peak (VmHWM above
    the warmed-up baseline), and by no more than 1.6×: a guard that overstates refuses scenes that fit."""
    trimesh.creation.icosphere(subdivisions=7).export(tmp_path / "sphere.ply")
    path = scene_file(tmp_path, [{"shape": "mesh", "path": "sphere.ply"}], render={"width": 8, "height": 8,
                                                                                   "shading": shading})
    done = subprocess.run([sys.executable, "-c", PEAK_SCRIPT, str(path)], capture_output=True, text=True,
                          timeout=TIMEOUT, check=True)
    measured = int(done.stdout.split()[-1])
    scene = rp.load_scene(path)
    plan = rp.build_plan(scene)
    estimate = estimate_memory(scene, smooth=plan.keeps(StageName.VERTEX_NORMALS), tile_rays=64, threads=1)
    assert measured <= estimate.total, (measured, estimate)
    assert estimate.total <= 1.6 * measured, (measured, estimate)


def test_the_framing_check_counts_the_render_bytes_per_triangle():
    """io.meshes.size checks a framing read below the renderer with its own copy of the measured figure."""
    from raycast_phong.io.meshes.size import MESH_READ_BYTES
    from raycast_phong.renderer.budget import FLAT_BYTES
    assert MESH_READ_BYTES == FLAT_BYTES


def test_a_scene_whose_text_would_not_fit_once_parsed_is_refused_before_the_parse(tmp_path):
    """Issue 30 item 3: a scene's parse costs up to SCENE_READ_BYTES a byte of text (nested empty lists,
    measured 35×), so 977 kB of text under a 10 MB budget is refused before tomllib runs; the same text fits
    a 100 MB one."""
    from raycast_phong.errors import SceneError
    from raycast_phong.io.scene_file import SCENE_READ_BYTES, read_scene_file
    path = tmp_path / "lists.toml"
    path.write_text("x = [" + "[[]]," * 200_000 + "]\n")
    assert SCENE_READ_BYTES >= 35
    with pytest.raises(SceneError, match=r"lists\.toml: reading its 977 kB of text needs ≈ 38.1 MB of memory, "
                                         r"more than the 10 MB available"):
        read_scene_file(path, max_memory=10 << 20)
    assert len(read_scene_file(path, max_memory=100 << 20)["x"]) == 200_000


def test_a_scene_whose_validation_would_not_fit_is_refused_before_it_is_validated(tmp_path, monkeypatch):
    """Issue 30 item 3: validation takes up to VALIDATED_ITEM_BYTES an object, light or material (10⁶ boxes
    grew 1.69 GB before the geometry estimate refused them), counted before it starts: 10,000 boxes and a
    light under 10 MB are refused naming the counts, without a model made; under 100 MB they validate."""
    from raycast_phong.errors import SceneError
    from raycast_phong.scene import load, schema
    path = tmp_path / "boxes.toml"
    path.write_text("objects = [" + ",".join(['{shape="box"}'] * 10_000) + ']\n[[lights]]\ntype = "point"\n'
                    "position = [0, 5, 5]\n")
    made = []
    monkeypatch.setattr(schema, "objects_in_bulk", lambda objects: made.append(1) or objects)
    with pytest.raises(SceneError, match=r"boxes\.toml: validating its 10,000 objects, 1 light needs ≈ 14\.6 MB of "
                                         r"memory, more than the 10 MB available"):
        load.load_scene(path, max_memory=10 << 20)
    assert not made
    assert len(load.load_scene(path, max_memory=100 << 20).objects) == 10_000



def test_validation_s_memory_counts_materials_and_takes_a_budget_of_exactly_its_need(tmp_path):
    """VALIDATED_ITEM_BYTES for each object, light and material (a table of named materials counts as the lists
    do): 40 objects and 60 materials need 100 items' bytes, so a budget of exactly that validates and one byte
    less is refused, naming both counts. Catches the materials left out and the bound made strict."""
    from raycast_phong.errors import SceneError
    from raycast_phong.scene.load import VALIDATED_ITEM_BYTES, load_scene
    path = tmp_path / "mixed.toml"
    path.write_text("objects = [" + ",".join(['{shape="box"}'] * 40) + "]\n"
                    + "".join(f"[materials.m{k}]\nkd = [0.5, 0.5, 0.5]\n" for k in range(60)))
    need = 100 * VALIDATED_ITEM_BYTES
    assert len(load_scene(path, max_memory=need).materials) == 60
    with pytest.raises(SceneError, match=r"mixed\.toml: validating its 40 objects, 60 materials needs ≈ 150 kB"):
        load_scene(path, max_memory=need - 1)

def test_a_budget_given_as_text_caps_the_scene_read_as_bytes_do(tmp_path):
    """render(max_memory='8G') and load_scene(max_memory='1M') take the CLI's spelling: the scene-file read's
    check reads it with the one parse_size (a str compared with an int was a TypeError)."""
    from raycast_phong.errors import SceneError
    from raycast_phong.scene.load import load_scene
    path = tmp_path / "boxes.toml"
    path.write_text("objects = [" + ",".join(['{shape="box"}'] * 1000) + "]\n")
    assert len(load_scene(path, max_memory="8G").objects) == 1000
    with pytest.raises(SceneError, match="more than the 1 MB available"):
        load_scene(path, max_memory="1M")


def test_load_scene_passes_its_budget_to_the_scene_file_read(tmp_path):
    """load_scene(max_memory=...) caps the scene-file read too, not only validation: 977 kB of nested lists
    (SCENE_READ_BYTES = 40 a byte: 38.1 MB to parse) under a 10 MB budget are refused as text before the parse,
    although the table has no object, light or material for the validation check to count."""
    from raycast_phong.errors import SceneError
    from raycast_phong.scene.load import load_scene
    path = tmp_path / "lists.toml"
    path.write_text("x = [" + "[[]]," * 200_000 + "]\n")
    with pytest.raises(SceneError, match=r"lists\.toml: reading its 977 kB of text needs ≈ 38.1 MB of memory, "
                                         r"more than the 10 MB available"):
        load_scene(path, max_memory=10 << 20)
