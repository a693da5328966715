"""`raycast-phong batch`: failure isolation, the manifest, the up-to-date check, atomic outputs, sweeps.

Scenes are 16×16, so the in-process tests take milliseconds; one test starts a worker pool (--jobs 2) and
one kills a batch in a subprocess, about a second each.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app
from raycast_phong.tools import batch
from raycast_phong.tools.sweep import compose_sheet, load_sweep

runner = CliRunner()
ROOT = Path(__file__).resolve().parents[2]

SCENE = """\
[render]
width = {size}
height = {size}
samples = {samples}

[[lights]]
position = [2, 2, 3]

[materials.red]
kd = [0.9, 0.2, 0.2]
shininess = 32

[[objects]]
shape = "{shape}"
{extra}
material = "red"
"""
# A tetrahedron: the smallest closed mesh, written as text so the test needs no mesh library.
TETRAHEDRON = "v 1 1 1\nv -1 -1 1\nv -1 1 -1\nv 1 -1 -1\nf 1 2 3\nf 1 4 2\nf 1 3 4\nf 2 4 3\n"


def scene_text(shape: str = "icosphere", extra: str = "subdivisions = 1", size: int = 16, samples: int = 1) -> str:
    return SCENE.format(shape=shape, extra=extra, size=size, samples=samples)


@pytest.fixture
def five_scenes(tmp_path: Path) -> Path:
    """Four good scenes (one of them a mesh) and one whose mesh file is missing."""
    folder = tmp_path / "scenes"
    folder.mkdir()
    for index in range(3):
        (folder / f"sphere{index}.toml").write_text(scene_text(extra=f"subdivisions = {index + 1}"))
    (folder / "tetra.obj").write_text(TETRAHEDRON)
    (folder / "mesh.toml").write_text(scene_text(shape="mesh", extra='path = "tetra.obj"'))
    (folder / "broken.toml").write_text(scene_text(shape="mesh", extra='path = "missing.obj"'))
    return folder


def run(*args: str):
    return runner.invoke(app, ["batch", *args])


def images(folder: Path) -> list[Path]:
    """The visible images (pathlib's glob also matches write_image's hidden temporaries)."""
    return sorted(p for p in folder.glob("*.png") if not p.name.startswith(".")) if folder.is_dir() else []


def manifest(folder: Path) -> dict:
    return json.loads((folder / "manifest.json").read_text())["scenes"]


def statuses(folder: Path) -> dict[str, str]:
    return {name: entry["status"] for name, entry in manifest(folder).items()}


def test_a_broken_scene_is_reported_and_the_others_render(five_scenes, tmp_path):
    out = tmp_path / "out"
    result = run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 1
    assert sorted(p.name for p in out.glob("*.png")) == ["mesh.png", "sphere0.png", "sphere1.png", "sphere2.png"]
    entries = manifest(out)
    assert entries["broken"]["status"] == "failed"
    assert entries["broken"]["reason"] == f"{five_scenes / 'broken.toml'}: objects.0.path: no such mesh file " \
                                          f"'{five_scenes / 'missing.obj'}'"
    assert f"failed: {entries['broken']['reason']}" in result.stderr
    good = entries["sphere1"]
    assert good["status"] == "rendered" and good["outputs"] == ["sphere1.png"] and good["hash"].startswith("sha256:")
    assert {"load", "geometry", "build", "rays", "shade", "frame", "write", "total"} <= set(good["seconds"])
    assert good["rays_per_second"] > 0
    assert "5 scenes: 4 rendered, 0 up to date, 1 failed" in result.stdout


def test_a_rerun_renders_only_what_changed(five_scenes, tmp_path):
    out = tmp_path / "out"
    run(str(five_scenes), "--out", str(out), "--jobs", "1")
    written = {p.name: p.stat().st_mtime_ns for p in out.glob("*.png")}
    # Unchanged: nothing renders, no image is rewritten; the broken scene is tried again and fails again.
    assert run(str(five_scenes), "--out", str(out), "--jobs", "1").exit_code == 1
    assert statuses(out) == {"broken": "failed", "mesh": "up to date", "sphere0": "up to date",
                             "sphere1": "up to date", "sphere2": "up to date"}
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("*.png")} == written
    # A changed scene file (a comment is enough: the hash is of the bytes) renders that scene only.
    with open(five_scenes / "sphere0.toml", "a") as scene:
        scene.write("# edited\n")
    run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert [name for name, status in statuses(out).items() if status == "rendered"] == ["sphere0"]
    # So does a changed mesh file, for the scene that reads it.
    (five_scenes / "tetra.obj").write_text(TETRAHEDRON.replace("v 1 1 1", "v 1 1 1.5"))
    run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert [name for name, status in statuses(out).items() if status == "rendered"] == ["mesh"]
    # Touching a scene, or a mesh, re-renders only the scene that reads it (as with make).
    for touched, expected in (("sphere1.toml", "sphere1"), ("tetra.obj", "mesh")):
        stamp = (five_scenes / touched).stat().st_mtime_ns + 1_000_000_000
        os.utime(five_scenes / touched, ns=(stamp, stamp))
        run(str(five_scenes), "--out", str(out), "--jobs", "1")
        assert [name for name, status in statuses(out).items() if status == "rendered"] == [expected]
    # --force renders everything; a deleted output is rendered again.
    run(str(five_scenes), "--out", str(out), "--jobs", "1", "--force")
    assert list(statuses(out).values()).count("rendered") == 4
    (out / "sphere2.png").unlink()
    run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert [name for name, status in statuses(out).items() if status == "rendered"] == ["sphere2"]


@pytest.mark.slow
def test_worker_processes_write_the_same_images(five_scenes, tmp_path):
    """--jobs 2 (a process pool, one render thread each) and --jobs 1 give identical files."""
    assert run(str(five_scenes), "--out", str(tmp_path / "one"), "--jobs", "1").exit_code == 1
    assert run(str(five_scenes), "--out", str(tmp_path / "two"), "--jobs", "2").exit_code == 1
    names = sorted(p.name for p in (tmp_path / "one").glob("*.png"))
    assert names == sorted(p.name for p in (tmp_path / "two").glob("*.png")) and len(names) == 4
    for name in names:
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "two" / name).read_bytes(), name
    assert statuses(tmp_path / "two")["broken"] == "failed"
    # --jobs is a core budget: one thread per scene in either case here; one stale scene gets both cores.
    threads = {name: entry["threads"] for name, entry in manifest(tmp_path / "two").items() if name != "broken"}
    assert set(threads.values()) == {1}
    assert {entry["threads"] for name, entry in manifest(tmp_path / "one").items() if name != "broken"} == {1}
    (tmp_path / "two" / "sphere0.png").unlink()
    run(str(five_scenes / "sphere*.toml"), "--out", str(tmp_path / "two"), "--jobs", "2")
    spheres = {name: status for name, status in statuses(tmp_path / "two").items() if name.startswith("sphere")}
    assert spheres == {"sphere0": "rendered", "sphere1": "up to date", "sphere2": "up to date"}
    assert manifest(tmp_path / "two")["sphere0"]["threads"] == 2


def test_a_changed_texture_renders_the_scene_again(tmp_path):
    """Every file a render reads is an input of its entry: a scene's kd_map and an OBJ's .mtl map_Kd. Rewrite
    either image (same size, so only its bytes tell) and that scene renders again; the other stays up to date."""
    folder = tmp_path / "scenes"
    folder.mkdir()
    rp.write_image(folder / "wood.png", np.full((4, 4, 3), 0.25, np.float32))
    rp.write_image(folder / "paint.png", np.full((4, 4, 3), 0.75, np.float32))
    (folder / "mapped.toml").write_text(scene_text(shape="plane", extra="size = [1, 1]").replace(
        "shininess = 32\n", 'shininess = 32\nkd_map = "wood.png"\n'))
    (folder / "box.mtl").write_text("newmtl p\nKd 1 1 1\nmap_Kd paint.png\n")
    (folder / "box.obj").write_text("mtllib box.mtl\nusemtl p\n" + TETRAHEDRON.replace("f 1 2 3", "vt 0 0\nf 1 2 3"))
    (folder / "obj.toml").write_text(scene_text(shape="mesh", extra='path = "box.obj"').replace(
        'material = "red"\n', ""))
    out = tmp_path / "out"
    assert run(str(folder / "mapped.toml"), str(folder / "obj.toml"), "--out", str(out)).exit_code == 0
    assert run(str(folder / "mapped.toml"), str(folder / "obj.toml"), "--out", str(out)).exit_code == 0
    assert statuses(out) == {"mapped": "up to date", "obj": "up to date"}
    for image, stale in (("wood.png", "mapped"), ("paint.png", "obj")):
        rp.write_image(folder / image, np.full((4, 4, 3), 0.5, np.float32))
        assert run(str(folder / "mapped.toml"), str(folder / "obj.toml"), "--out", str(out)).exit_code == 0
        assert statuses(out) == {"mapped": "up to date", "obj": "up to date", stale: "rendered"}, image


def test_paths_globs_and_duplicate_names(five_scenes, tmp_path):
    found = batch.find_jobs([str(five_scenes / "sphere*.toml"), five_scenes / "mesh.toml"])
    assert [job.name for job in found] == ["sphere0", "sphere1", "sphere2", "mesh"]
    other = tmp_path / "other"
    other.mkdir()
    (other / "mesh.toml").write_text(scene_text())
    result = run(str(five_scenes), str(other), "--out", str(tmp_path / "out"))
    assert result.exit_code == 2
    assert "mesh.toml: its output name 'mesh' is also" in result.stderr
    result = run(str(tmp_path / "nothing-*.toml"), "--out", str(tmp_path / "out"))
    assert result.exit_code == 2 and "no such scene file, folder or matching glob" in result.stderr


def test_leftover_temporary_files_are_removed(five_scenes, tmp_path):
    """A writer killed hard (SIGKILL) can leave write_image's hidden temporary; the next run deletes it."""
    out = tmp_path / "out"
    out.mkdir()
    # a contact sheet's temporary too, whatever sweep it was of
    stale = [out / ".sphere0-abcd1234.png", out / ".manifest-x1y2z3w4.json", out / ".old-contact-abcd1234.png"]
    for path in stale:
        path.write_bytes(b"half an image")
    keep = out / ".unrelated-12345678.png"  # not a name of this batch: left alone
    keep.write_bytes(b"")
    run(str(five_scenes), "--out", str(out), "--jobs", "1")
    assert not any(path.exists() for path in stale) and keep.exists()


@pytest.mark.slow
def test_a_killed_batch_leaves_no_partial_image_and_a_rerun_completes_it(tmp_path):
    folder = tmp_path / "scenes"
    folder.mkdir()
    count = 8
    for index in range(count):  # 192×192 with 3×3 samples: ~0.1 s each, so the kill lands mid-batch
        (folder / f"s{index}.toml").write_text(scene_text(extra="subdivisions = 3", size=192, samples=3))
    out = tmp_path / "out"
    command = [sys.executable, "-m", "raycast_phong.cli", "batch", str(folder), "--out", str(out), "--jobs", "1"]
    process = subprocess.Popen(command, cwd=ROOT, start_new_session=True, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while not images(out) and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.01)
    assert process.poll() is None, process.communicate()[1].decode()
    os.killpg(process.pid, signal.SIGTERM)
    process.wait(timeout=30)
    leftovers = [p.name for p in out.iterdir() if p.name.startswith(".") and p.name != batch.LOCK]
    assert leftovers == [], leftovers
    finished = images(out)
    assert 1 <= len(finished) < count, "the batch finished before the kill; make the scenes slower"
    for path in finished:  # every visible image is whole
        assert rp.read_image(path)[0].shape == (192, 192, 3)
    result = run(str(folder), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 0
    assert len(images(out)) == count
    assert list(statuses(out).values()).count("up to date") >= len(finished) - 1  # the last may predate its entry


SWEEP = """\
scene = "base.toml"
set = ["render.width=12", "render.height=10"]

[grid]
render.shading = ["flat", "gouraud", "phong"]
materials.red.shininess = [8, 512]
objects.0.subdivisions = [1, 3]
"""


def test_a_sweep_renders_the_product_and_a_contact_sheet(tmp_path):
    (tmp_path / "base.toml").write_text(scene_text())
    (tmp_path / "shading.toml").write_text(SWEEP)
    out = tmp_path / "out"
    result = run(str(tmp_path / "shading.toml"), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 0, result.stderr
    images = sorted(p.name for p in out.glob("shading--*.png"))
    assert len(images) == 12
    assert "shading--shading=gouraud--shininess=512--subdivisions=3.png" in images
    sheet = rp.read_image(out / "shading-contact.png")[0]
    # 6 rows (shading × shininess) by 2 columns (subdivisions, the last axis), as compose_sheet lays them out.
    jobs = load_sweep(tmp_path / "shading.toml").jobs()
    cells = [rp.read_image(out / f"{job.name}.png")[0] for job in jobs]
    expected, grid = compose_sheet([job.cell for job in jobs], cells)
    assert (grid.rows, grid.columns, grid.width, grid.height) == (6, 2, 12, 10)
    assert sheet.shape == (grid.image_height, grid.image_width, 3) == expected.shape
    for index, cell in enumerate(cells):
        x, y = grid.origin(*divmod(index, 2))
        np.testing.assert_array_equal(sheet[y:y + 10, x:x + 12], cell)
    assert json.loads((out / "manifest.json").read_text())["sheets"] == {"shading": "shading-contact.png"}


@pytest.mark.parametrize(("text", "message"), [
    ('scene = "base.toml"\n[grid]\nrender.shading = "flat"\n', "grid.render.shading: must be a non-empty list"),
    ('scene = "base.toml"\nsweep = 1\n[grid]\nrender.shading = ["flat"]\n', "sweep: unknown key"),
    ('[grid]\nrender.shading = ["flat"]\n', "scene: must be the base scene file"),
])
def test_a_bad_sweep_file_exits_2_naming_the_key(tmp_path, text, message):
    (tmp_path / "base.toml").write_text(scene_text())
    (tmp_path / "bad.toml").write_text(text)
    result = run(str(tmp_path / "bad.toml"), "--out", str(tmp_path / "out"))
    assert result.exit_code == 2
    assert result.stderr.strip() == f"error: {tmp_path / 'bad.toml'}: {message}" or message in result.stderr


def test_a_bad_sweep_value_fails_that_cell_only(tmp_path):
    (tmp_path / "base.toml").write_text(scene_text())
    (tmp_path / "widths.toml").write_text('scene = "base.toml"\n[grid]\nrender.width = [8, 0]\n')
    out = tmp_path / "out"
    result = run(str(tmp_path / "widths.toml"), "--out", str(out), "--jobs", "1")
    assert result.exit_code == 1
    assert statuses(out) == {"widths--width=8": "rendered", "widths--width=0": "failed"}
    assert "render.width: out of range" in manifest(out)["widths--width=0"]["reason"]
    assert (out / "widths-contact.png").is_file()


def test_forked_workers_from_a_fresh_command_match_one_process(five_scenes, tmp_path):
    """A fresh `batch` command has not started Embree, so it warms the kernels and forks its workers
    (the pytest process here has started Embree, so in-process runs use the fork server instead)."""
    run(str(five_scenes), "--out", str(tmp_path / "one"), "--jobs", "1")
    command = [sys.executable, "-m", "raycast_phong.cli", "batch", str(five_scenes), "--out",
               str(tmp_path / "forked"),
               "--jobs", "2"]
    done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert done.returncode == 1  # the broken scene
    names = sorted(p.name for p in (tmp_path / "one").glob("*.png"))
    assert names == sorted(p.name for p in (tmp_path / "forked").glob("*.png")) and len(names) == 4
    for name in names:
        assert (tmp_path / "one" / name).read_bytes() == (tmp_path / "forked" / name).read_bytes()


def test_warming_the_kernels_starts_no_embree():
    probe = ("from raycast_phong.renderer.frame import warm_kernels; "
             "from raycast_phong.renderer.intersect import embree_started; "
             "warm_kernels(); print(embree_started()); import raycast_phong as rp; "
             "rp.render(rp.load_scene(rp.default_scene_path(), ['render.width=8', 'render.height=6'])); "
             "print(embree_started())")  # the control: a render does start it
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert done.stdout.split() == ["False", "True"], done.stderr


def test_warm_up_loads_only_the_kernels_the_scenes_need(tmp_path):
    """A batch of local float32 scenes loads the float32 shading kernel and no shadow-ray kernel, and the
    manifest records that start-up apart from the scenes."""
    probe = """
import json, sys
from pathlib import Path
from raycast_phong.tools import batch
from raycast_phong.renderer.kernels import tile
from raycast_phong.renderer.kernels.shadows import shadow_rays
folder = sys.argv[1]
open(folder + "/a.toml", "w").write('[render]\\nwidth = 8\\nheight = 8\\n[[objects]]\\nshape = "icosphere"\\n')
report = batch.run_batch(batch.find_jobs([folder + "/a.toml"]), folder + "/out", workers=1)
# The shading inputs' types of the kernel that shades: the tile kernel.
shade = [str(s[6]) for s in tile.render_band.signatures]
print(json.dumps(dict(shade=shade, shadow=len(shadow_rays.signatures),
                      startup=report.startup, batch=batch.read_manifest(Path(folder) / "out")["batch"])))
"""
    done = subprocess.run([sys.executable, "-c", probe, str(tmp_path)], capture_output=True, text=True, timeout=120,
                          cwd=ROOT)
    found = json.loads(done.stdout)
    signature = found["shade"][0].lower() if len(found["shade"]) == 1 else ""
    assert "array(float32" in signature and "array(float64" not in signature, found["shade"]
    assert found["shadow"] == 0
    assert 0 < found["batch"]["startup"] == round(found["startup"], 6) < found["batch"]["seconds"], found
    assert (found["batch"]["cores"], found["batch"]["processes"], found["batch"]["threads"]) == (1, 1, 1)


def test_batch_reads_scene_paths_from_stdin(tmp_path):
    """`batch -` takes the scene paths on stdin, one a line (as `find … | xargs`), literally (a name with a
    space or a `*`), blank lines skipped; a line naming no file or not a scene fails as that scene, reported
    with the others, and the rest render (before: '-: no such scene file', exit 2)."""
    (tmp_path / "a b.toml").write_text(scene_text())
    (tmp_path / "c*.toml").write_text(scene_text("box", ""))
    (tmp_path / "notes.txt").write_text("not a scene\n")
    listed = (f"{tmp_path / 'a b.toml'}\n\n{tmp_path / 'c*.toml'}\r\n{tmp_path / 'gone.toml'}\n"
              f"{tmp_path / 'notes.txt'}\n")
    out = tmp_path / "out"
    result = runner.invoke(app, ["batch", "-", "--out", str(out), "--jobs", "1"], input=listed)
    assert result.exit_code == 1, result.output
    manifest = json.loads((out / "manifest.json").read_text())["scenes"]
    assert {name: entry["status"] for name, entry in manifest.items()} == {
        "a b": "rendered", "c*": "rendered", "gone": "failed", "notes": "failed"}
    failed = [line for line in result.output.splitlines() if line.startswith("failed:")]
    assert len(failed) == 2 and "gone.toml" in failed[0] and "notes.txt" in failed[1], result.output
    assert "4 scenes: 2 rendered" in result.output


def test_batch_help_says_how_to_pipe_paths_in():
    result = runner.invoke(app, ["batch", "--help"])
    assert "- reads scene paths from stdin" in " ".join(result.output.replace("│", " ").split()), result.output


def test_a_sweeps_cells_say_a_shared_warning_once_with_the_base_scene_s_plain_path(tmp_path, monkeypatch):
    """Every cell of a sweep over scenes/specular.toml warns of the sub-pixel highlight: said once (with the first
    cell's name), then a note that lines came again; the base scene, named "../scenes/specular.toml" from the
    sweep's folder, is said as scenes/specular.toml from the working folder, not sweeps/../scenes/specular.toml."""
    (tmp_path / "scenes").mkdir()
    (tmp_path / "sweeps").mkdir()
    (tmp_path / "scenes" / "specular.toml").write_text((ROOT / "scenes" / "specular.toml").read_text())
    (tmp_path / "sweeps" / "s.toml").write_text('scene = "../scenes/specular.toml"\n'
                                                'set = ["render.width=240", "render.height=90"]\n\n'
                                                '[grid]\nrender.shading = ["flat", "phong"]\n')
    monkeypatch.chdir(tmp_path)
    done = run("sweeps/s.toml", "--out", "out", "--jobs", "1")
    assert done.exit_code == 0, done.output
    warned = [line for line in done.output.splitlines() if line.startswith("warning: ")]
    highlight = [line for line in warned if "may fall between pixel centres" in line]
    assert len(highlight) == 1 and highlight[0].startswith("warning: scenes/specular.toml: "), warned
    assert ".." not in "".join(warned), warned
    assert "came again in other sweep cells of the same scene: each said once" in done.output, done.output
    entries = manifest(tmp_path / "out")
    assert all(any("pixel centres" in w for w in entry["warnings"]) for entry in entries.values()), entries


def test_an_obj_s_mtl_changed_alone_renders_its_scene_again(tmp_path):
    """The up-to-date rule weighs a mesh's side files: an OBJ scene batched once is up to date, and after its .mtl
    alone changes (the OBJ, the scene and the image as they were) it renders again, in the new colour."""
    folder, out = tmp_path / "scenes", tmp_path / "out"
    folder.mkdir()
    (folder / "tri.obj").write_text("mtllib tri.mtl\nv -1 -1 0\nv 1 -1 0\nv 0 1 0\nusemtl m\nf 1 2 3\n")
    (folder / "tri.mtl").write_text("newmtl m\nKd 0.9 0.1 0.1\n")
    (folder / "s.toml").write_text('[render]\nwidth = 16\nheight = 16\n[camera]\nposition = [0, 0, 3]\n'
                                   '[[lights]]\nposition = [0, 0, 3]\n[[objects]]\nshape = "mesh"\npath = "tri.obj"\n')
    assert run(str(folder), "--out", str(out), "--jobs", "1").exit_code == 0
    red = rp.read_image(out / "s.png")[0][8, 8]
    assert run(str(folder), "--out", str(out), "--jobs", "1").exit_code == 0
    assert statuses(out) == {"s": "up to date"}
    (folder / "tri.mtl").write_text("newmtl m\nKd 0.1 0.1 0.9\n")
    assert run(str(folder), "--out", str(out), "--jobs", "1").exit_code == 0
    assert statuses(out) == {"s": "rendered"}
    blue = rp.read_image(out / "s.png")[0][8, 8]
    assert red[0] > red[2] and blue[2] > blue[0], (red, blue)


def test_a_sweep_whose_fixed_settings_change_renders_its_cells_again(tmp_path):
    """A sweep's `set` list is part of every cell (the cells keep their names): batched once, its cells are up to
    date; with the list changed (the scene as it was) they render again at the new size."""
    (tmp_path / "base.toml").write_text(scene_text())
    sweep = tmp_path / "s.toml"
    sweep.write_text('scene = "base.toml"\nset = ["render.width=12", "render.height=10"]\n\n[grid]\n'
                     'render.shading = ["flat", "phong"]\n')
    out = tmp_path / "out"
    for _ in range(2):
        assert run(str(sweep), "--out", str(out), "--jobs", "1").exit_code == 0
    assert set(statuses(out).values()) == {"up to date"}
    sweep.write_text(sweep.read_text().replace("render.width=12", "render.width=14"))
    assert run(str(sweep), "--out", str(out), "--jobs", "1").exit_code == 0
    assert set(statuses(out).values()) == {"rendered"}
    assert {rp.read_image(path)[0].shape for path in out.glob("s--*.png")} == {(10, 14, 3)}


def test_sweep_axes_that_share_a_last_part_are_named_by_their_whole_key_paths(tmp_path):
    """docs/batch.md: a cell is named by each axis's last key part, or its whole path where two axes share one
    (two materials' shininess), so the names stay distinct; an axis whose last part is its own keeps it."""
    (tmp_path / "base.toml").write_text(scene_text() + '\n[materials.blue]\nkd = [0.2, 0.2, 0.9]\n')
    (tmp_path / "s.toml").write_text('scene = "base.toml"\n\n[grid]\nmaterials.red.shininess = [8, 64]\n'
                                     'materials.blue.shininess = [8, 64]\nrender.shading = ["flat"]\n')
    sweep = load_sweep(tmp_path / "s.toml")
    assert sweep.labels() == ["materials.red.shininess", "materials.blue.shininess", "shading"]
    names = [job.name for job in sweep.jobs()]
    assert len(set(names)) == 4
    assert names[0] == "s--materials.red.shininess=8--materials.blue.shininess=8--shading=flat"


@pytest.mark.parametrize(("text", "words"), [
    ('scene = "b.toml"\n[grid\n', "s.toml: TOML syntax error: "),
    (b"scene = '\xff'\n[grid]\na = [1]\n", "s.toml: cannot read the sweep file ("),
    ('scene = "b.toml"\nmode = 1\n[grid]\na = [1]\n', "s.toml: mode: unknown key; a sweep file has scene, set, grid"),
    ('scene = 3\n[grid]\na = [1]\n', "s.toml: scene: must be the base scene file, a string relative to the sweep"),
    ('scene = "b.toml"\nset = "render.width=3"\n[grid]\na = [1]\n', 's.toml: set: must be a list of "key.path='),
    ('scene = "b.toml"\nset = ["render.width"]\n[grid]\na = [1]\n', 's.toml: set: must be a list of "key.path='),
    ('scene = "b.toml"\ngrid = 3\n', "s.toml: grid: must be a table of key paths and value lists"),
    ('scene = "b.toml"\n[grid]\n', "s.toml: grid: must be a table of key paths and value lists"),
    ('scene = "b.toml"\n', "s.toml: grid: must be a table of key paths and value lists"),
    ('scene = "b.toml"\n[grid]\na = []\n', "s.toml: grid.a: must be a non-empty list of values, got []"),
])
def test_a_sweep_file_s_mistake_is_one_line_naming_its_key(tmp_path, text, words):
    """Every check of load_sweep in the words docs/batch.md gives: the file, the key, what is allowed (a file
    without `grid` too, which load_sweep is given from Python; it raised KeyError)."""
    path = tmp_path / "s.toml"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(rp.SceneError) as refused:
        load_sweep(path)
    assert str(refused.value).startswith(str(tmp_path / words)) and "\n" not in str(refused.value), refused.value


def test_each_worker_process_gets_its_share_of_the_batch_memory_budget(tmp_path, monkeypatch):
    """max_memory is the budget of the scenes rendering at once: with P worker processes each render gets 1/P
    of it. Two scenes on --jobs 2 with four cores (os.cpu_count faked, so two processes on any machine) under
    8 GiB: each task carries 4 GiB, not the whole 8. The executor is stopped before anything renders: only the
    tasks' budgets are looked at."""
    from raycast_phong.tools.batch import run as batch_run
    for name in ("a", "b"):
        (tmp_path / f"{name}.toml").write_text(scene_text())
    jobs = batch.find_jobs([str(tmp_path / "a.toml"), str(tmp_path / "b.toml")])
    seen = []

    class Stop(Exception):
        pass

    def executor(tasks, scheduler, processes, begun, said):
        seen.append((processes, [task.max_memory for task in tasks]))
        raise Stop

    monkeypatch.setattr(os, "cpu_count", lambda: 4)
    monkeypatch.setattr(batch_run, "warm_up", lambda tasks: 0.0)
    monkeypatch.setattr(batch_run, "_executor", executor)
    with pytest.raises(Stop):
        batch.run_batch(jobs, tmp_path / "out", workers=2, max_memory=8 << 30)
    assert seen == [(2, [4 << 30, 4 << 30])]


def test_a_mesh_file_is_judged_up_to_date_without_reading_it_whole_under_render_overrides(tmp_path, monkeypatch):
    """A mesh file rendered directly is judged up to date from its file and overrides alone (no framing, no
    read through trimesh: jobs._unframed_mesh_job) when the overrides are render, camera, lights, ambient or
    output keys, --srgb's render.colour among them: the second run loads no scene. Without --srgb the colour is
    the format's default, another hash: that run loads it and renders again. Catches the override's colour
    ignored (the hash then differs from the render's and every such job is loaded whole again)."""
    from raycast_phong.tools.batch import jobs
    mesh = tmp_path / "tetra.obj"
    mesh.write_text(TETRAHEDRON)
    out = tmp_path / "out"
    assert run(str(mesh), "--out", str(out), "--jobs", "1", "--srgb").exit_code == 0
    assert statuses(out) == {"tetra": "rendered"}
    real = jobs.load_scene
    loaded = []
    monkeypatch.setattr(jobs, "load_scene", lambda *args, **kwargs: loaded.append(args) or real(*args, **kwargs))
    assert run(str(mesh), "--out", str(out), "--jobs", "1", "--srgb").exit_code == 0
    assert statuses(out) == {"tetra": "up to date"} and loaded == []
    assert run(str(mesh), "--out", str(out), "--jobs", "1").exit_code == 0
    assert statuses(out) == {"tetra": "rendered"} and len(loaded) == 1
    # A sweep over the mesh: its render.* overrides judged the same way, an object's key by the full load.
    sweep, out = tmp_path / "s.toml", tmp_path / "swept"
    for keys, loads in (('"render.width=12"', 0), ('"render.width=12", "objects.0.scale=[2, 2, 2]"', 1)):
        sweep.write_text(f'scene = "tetra.obj"\nset = [{keys}]\n[grid]\n"render.height" = [10, 11]\n')
        assert run(str(sweep), "--out", str(out), "--jobs", "1").exit_code == 0
        assert set(statuses(out).values()) == {"rendered"}
        loaded.clear()
        assert run(str(sweep), "--out", str(out), "--jobs", "1").exit_code == 0
        assert set(statuses(out).values()) == {"up to date"} and len(loaded) == 2 * loads, keys



@pytest.mark.parametrize("keys", ['"render.width=8"', '"objects.0.scale=[2, 2, 2]"'], ids=["unframed", "loaded"])
def test_an_up_to_date_entry_keeps_its_render_s_notes_and_warnings(tmp_path, keys):
    """docs/batch.md: an up-to-date scene keeps the warnings and notes of the render that made its image. An OBJ
    whose .mtl is missing (a note), swept over two heights, is judged up to date by its file alone under a render
    key (jobs._unframed_mesh_job) and by the full load under an object's key: both keep the note. Catches the
    unframed path's entry made without them (it once was)."""
    (tmp_path / "t.obj").write_text("mtllib gone.mtl\n" + TETRAHEDRON)
    sweep, out = tmp_path / "s.toml", tmp_path / "out"
    sweep.write_text(f'scene = "t.obj"\nset = [{keys}]\n[grid]\n"render.height" = [10, 11]\n')
    assert run(str(sweep), "--out", str(out), "--jobs", "1").exit_code == 0
    first = manifest(out)
    assert {entry["status"] for entry in first.values()} == {"rendered"}
    assert all(any("gone.mtl" in line for line in entry["notes"]) for entry in first.values()), first
    assert run(str(sweep), "--out", str(out), "--jobs", "1").exit_code == 0
    second = manifest(out)
    assert {entry["status"] for entry in second.values()} == {"up to date"}, second
    assert {name: (entry["notes"], entry["warnings"]) for name, entry in second.items()} == \
        {name: (entry["notes"], entry["warnings"]) for name, entry in first.items()}



def test_a_failed_cell_is_dark_red_on_the_contact_sheet(tmp_path):
    """docs/batch.md: a failed cell is dark red on the sheet (FAILED_RGB, 0.35, 0.06, 0.06), so it cannot pass for
    a black render nor for the sheet's backdrop; the rendered cell beside it is its image."""
    (tmp_path / "base.toml").write_text(scene_text())
    (tmp_path / "widths.toml").write_text('scene = "base.toml"\n[grid]\nrender.width = [8, 0]\n')
    out = tmp_path / "out"
    assert run(str(tmp_path / "widths.toml"), "--out", str(out), "--jobs", "1").exit_code == 1
    sheet = rp.read_image(out / "widths-contact.png")[0]
    cell = rp.read_image(out / "widths--width=8.png")[0]
    _, grid = compose_sheet([(("width", "8"),), (("width", "0"),)], [cell, None])
    assert (grid.rows, grid.columns, grid.width, grid.height) == (1, 2, 8, 16)
    x, y = grid.origin(0, 0)
    np.testing.assert_array_equal(sheet[y:y + 16, x:x + 8], cell)
    x, y = grid.origin(0, 1)
    np.testing.assert_allclose(sheet[y + 1, x + 1], (0.35, 0.06, 0.06), atol=0.01)  # a corner, clear of "failed"


def test_force_rewrites_a_contact_sheet_even_when_no_cell_rendered(tmp_path):
    """--force makes every output again, the sheet too: a sweep rendered once, then its base scene broken and the
    batch forced, every cell fails and the sheet shows them dark red (not the first run's images, kept because no
    cell rendered)."""
    (tmp_path / "base.toml").write_text(scene_text())
    sweep = tmp_path / "s.toml"
    sweep.write_text('scene = "base.toml"\n[grid]\nrender.shading = ["flat", "phong"]\n')
    out = tmp_path / "out"
    assert run(str(sweep), "--out", str(out), "--jobs", "1").exit_code == 0
    (tmp_path / "base.toml").write_text("[render\n")
    assert run(str(sweep), "--out", str(out), "--jobs", "1", "--force").exit_code == 1
    assert set(statuses(out).values()) == {"failed"}
    sheet = rp.read_image(out / "s-contact.png")[0]
    _, grid = compose_sheet([job.cell for job in load_sweep(sweep).jobs()], [None, None])
    for column in range(2):
        x, y = grid.origin(0, column)
        np.testing.assert_allclose(sheet[y + 1, x + 1], (0.35, 0.06, 0.06), atol=0.01)


def test_a_cell_value_s_file_name_drops_brackets_quotes_and_blanks():
    """sweep.slug, as its docstring says: brackets, quotes and blanks dropped (`[1, 2]` is `1,2`, not `1,-2`),
    any other character not safe in a file name made '-', and a value that leaves nothing (`""`) named `empty`."""
    from raycast_phong.tools.sweep import slug
    assert slug("[1, 2]") == "1,2"
    assert slug('"a/b c"') == "a-bc"
    assert slug('""') == "empty"


def test_a_sweep_file_is_told_by_its_grid_table_whatever_the_case_of_its_suffix(tmp_path):
    """is_sweep: a `.TOML` file with a top-level `grid` table is a sweep, as a `.toml` one is (suffixes are
    compared without case); a scene file, without `grid`, is not."""
    from raycast_phong.tools.sweep import is_sweep
    (tmp_path / "S.TOML").write_text('scene = "base.toml"\n[grid]\nrender.width = [8]\n')
    (tmp_path / "base.TOML").write_text(scene_text())
    assert is_sweep(tmp_path / "S.TOML") and not is_sweep(tmp_path / "base.TOML")


def test_row_labels_appear_from_two_rows_and_may_be_twice_a_cell_s_width():
    """sheet_layout: a sheet of two rows or more has its row labels at the left (one row has none), each at
    most max(2 W, 240) px wide: a long label beside 200 px cells takes more than 240 px (up to 400), beside
    100 px cells exactly 240."""
    from raycast_phong.tools.sweep import sheet_layout
    assert sheet_layout(1, 2, 12, 10, ["a=1"]).label_width == 0
    assert sheet_layout(2, 2, 12, 10, ["a=1", "a=2"]).label_width > 0
    long = "x" * 60
    assert 240 < sheet_layout(2, 1, 200, 20, [long, long]).label_width <= 400
    assert sheet_layout(2, 1, 100, 20, [long, long]).label_width == 240


def test_the_manifest_says_the_cores_processes_and_threads_a_batch_used(tmp_path, monkeypatch):
    """manifest["batch"]: with --jobs 2 on four cores (os.cpu_count faked) and one scene to render, the batch has 2
    cores, renders in 1 process (no more than there are scenes) on 2 threads; each number in its own field."""
    monkeypatch.setattr(os, "cpu_count", lambda: 4)
    (tmp_path / "a.toml").write_text(scene_text())
    out = tmp_path / "out"
    assert run(str(tmp_path / "a.toml"), "--out", str(out), "--jobs", "2").exit_code == 0
    found = batch.read_manifest(out)["batch"]
    assert (found["cores"], found["processes"], found["threads"]) == (2, 1, 2), found


def test_a_second_sweep_into_the_same_folder_keeps_the_first_sweep_s_sheet_in_the_manifest(tmp_path):
    """The manifest keeps what is not in this batch (docs/batch.md), its `sheets` too: two sweeps batched one
    after the other into one folder leave both sheets listed."""
    (tmp_path / "base.toml").write_text(scene_text())
    out = tmp_path / "out"
    for name in ("one", "two"):
        (tmp_path / f"{name}.toml").write_text('scene = "base.toml"\n[grid]\nrender.shading = ["flat"]\n')
        assert run(str(tmp_path / f"{name}.toml"), "--out", str(out), "--jobs", "1").exit_code == 0
    sheets = json.loads((out / "manifest.json").read_text())["sheets"]
    assert sheets == {"one": "one-contact.png", "two": "two-contact.png"}
