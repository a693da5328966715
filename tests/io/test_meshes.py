"""A mesh file as a scene (docs/meshes.md): its materials, colours and normals, the framing camera, the
`scene` command's equivalent TOML, and the one-line notes for what a file's side files lack.

Colours are checked against values computed here by hand from the .mtl numbers and the lecture's model.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import trimesh
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app
from raycast_phong.geometry.build import build_geometry
from raycast_phong.io.meshes.source import mesh_source, read_mesh

MESHES = Path(__file__).resolve().parents[2] / "scenes" / "meshes"
SHIPPED = ("dice.obj", "painted_knot.ply", "still_life.glb")
runner = CliRunner()
pytestmark = pytest.mark.usefixtures("in_tmp_path")

# dice.mtl, as written by scenes/meshes/make_meshes.py: (Ka, Kd, Ks, Ke, Ns, illum) per material.
DICE = {"red": ((0.2, 0.05, 0.05), (0.8, 0.1, 0.1), (0.5, 0.5, 0.5), (0, 0, 0), 40, 2),
        "green": ((0.05, 0.2, 0.05), (0.1, 0.7, 0.2), (0.9, 0.9, 0.9), (0, 0, 0), 10, 1),
        "blue": ((0, 0, 0), (0.1, 0.2, 0.9), (0.3, 0.3, 0.3), (0.05, 0.05, 0.1), 80, 2)}
SIDE_MATERIAL = {0: "red", 1: "green", 2: "blue"}  # the axis of a side's normal → its material


def expected_dice_colour(name: str, normal: np.ndarray, to_light: np.ndarray, to_viewer: np.ndarray,
                         ambient: float) -> np.ndarray:
    """k_e + I_a k_a + I_d k_d (n·l) + I_s k_s (r·v)^f from the .mtl's numbers, by the mapping in docs/meshes.md:
    illum 1 has no specular term; I_d = 0.8, I_s = 1 (the light's defaults)."""
    ka, kd, ks, ke, ns, illum = (np.asarray(x, np.float64) if i < 4 else x for i, x in enumerate(DICE[name]))
    n_dot_l = float(normal @ to_light)
    reflected = 2 * n_dot_l * normal - to_light
    specular = 0.0 if illum == 1 or n_dot_l <= 0 else max(float(reflected @ to_viewer), 0.0) ** ns
    return ke + ambient * ka + 0.8 * kd * max(n_dot_l, 0.0) + 1.0 * ks * specular


# The three-quarter view's direction toward the eye (30° round from +z toward +x, 20° up), and the
# direction that mirrors it about +y: a light there puts the highlight of the +y side (green) at its peak.
EYE = np.array([math.cos(math.radians(20)) * math.sin(math.radians(30)), math.sin(math.radians(20)),
                math.cos(math.radians(20)) * math.cos(math.radians(30))])
LIGHTS = {"all sides lit": np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0), "green's highlight": EYE * [-1, 1, -1]}


@pytest.mark.parametrize("light", sorted(LIGHTS))
@pytest.mark.parametrize("override", [False, True])
def test_each_material_region_has_its_mtl_colour(override, light):
    """dice.obj, flat shading, a directional light and an infinite viewer: every pixel of a side equals the
    model evaluated with that side's .mtl material; [materials.red] in the overrides replaces the file's red."""
    light = LIGHTS[light]  # toward the light
    sets = ["render.width=160", "render.height=120", "render.shading=flat", "render.viewer=infinite",
            "ambient=0.3", 'lights.0.type="directional"', f"lights.0.direction={(-light).tolist()}",
            'output.aovs=["face"]']
    if override:
        sets += ["materials.red.kd=[0, 0, 1]", "materials.red.ks=0"]
    scene = rp.load_scene(MESHES / "dice.obj", sets)
    result = rp.render(scene)
    geometry = build_geometry(scene)
    face = result.aovs["face"][..., 0].astype(int)
    to_viewer = np.asarray(scene.camera.position) - np.asarray(scene.camera.look_at)
    to_viewer /= np.linalg.norm(to_viewer)
    seen = set()
    for f in np.unique(face[face >= 0]):
        normal = geometry.face_normals[f]
        name = SIDE_MATERIAL[int(np.argmax(np.abs(normal)))]
        expected = expected_dice_colour(name, normal, light, to_viewer, 0.3)
        if override and name == "red":
            expected = 0.3 * np.array([0.2, 0.05, 0.05]) + 0.8 * np.array([0, 0, 1.0]) * max(float(normal @ light), 0)
        pixels = result.image[face == f]
        # float32 shading of a handful of terms each ≤ 1: a few units of 2^-24 relative.
        np.testing.assert_allclose(pixels, np.broadcast_to(expected, pixels.shape), rtol=1e-5, atol=1e-6)
        seen.add(name)
    assert seen == {"red", "green", "blue"}  # the three-quarter view sees +x, +y and +z
    np.testing.assert_allclose(to_viewer, EYE, atol=1e-12)


def test_vertex_colours_are_interpolated_per_corner_as_gl_does(tmp_path):
    """One triangle with red, green and blue corners, lit by ambient only (k_a = the colour): each pixel is
    the corners' colours mixed with its barycentric weights (they sum to 1), not the face mean 1/3 (issue 20,
    item 4). Near the red corner red dominates; every pixel's channels sum to 1."""
    mesh = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False,
                           vertex_colors=[[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]])
    mesh.export(tmp_path / "rgb.ply")
    (tmp_path / "s.toml").write_text('ambient = 1.0\n[render]\nwidth = 32\nheight = 32\nshading = "phong"\n'
                                     '[camera]\nposition = [0.3, 0.3, 2]\nlook_at = [0.3, 0.3, 0]\n'
                                     '[[objects]]\nshape = "mesh"\npath = "rgb.ply"\n')
    image = rp.render(rp.load_scene(tmp_path / "s.toml")).image
    covered = image.max(axis=2) > 0
    assert covered.sum() > 50
    np.testing.assert_allclose(image[covered].sum(axis=1), 1.0, rtol=1e-5)  # weights sum to 1
    assert image[covered].max(axis=0).min() > 0.7  # each corner's colour shows near its corner
    assert image[covered].std(axis=0).min() > 0.1  # a gradient, not one flat colour


@pytest.mark.parametrize("shading", ["flat", "gouraud"])
def test_flat_takes_one_colour_per_face_and_gouraud_lights_each_corner(tmp_path, shading):
    """Flat: the face's colour is the mean of its corners (the colour at the centroid it is lit at): 1/3 in
    every channel. Gouraud: each corner lit with its own colour, then mixed: a gradient as Phong's."""
    mesh = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False,
                           vertex_colors=[[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255]])
    mesh.export(tmp_path / "rgb.ply")
    (tmp_path / "s.toml").write_text(f'ambient = 1.0\n[render]\nwidth = 32\nheight = 32\nshading = "{shading}"\n'
                                     '[camera]\nposition = [0.3, 0.3, 2]\nlook_at = [0.3, 0.3, 0]\n'
                                     '[[objects]]\nshape = "mesh"\npath = "rgb.ply"\n')
    image = rp.render(rp.load_scene(tmp_path / "s.toml")).image
    covered = image.max(axis=2) > 0
    if shading == "flat":
        np.testing.assert_allclose(image[covered], 1 / 3, rtol=1e-5)
    else:
        assert image[covered].std(axis=0).min() > 0.1


def test_gltf_metallic_roughness_is_mapped_as_documented():
    """still_life.glb's gold: base (255, 196, 77), metallic 1, roughness 0.3 → k_s = base, f = 2/0.3⁴ − 2 (a
    narrow lobe: k_s as stated)."""
    scene = rp.load_scene(MESHES / "still_life.glb")
    gold, plastic = scene.materials["gold"], scene.materials["red_plastic"]
    base = np.array([255, 196, 77]) / 255
    np.testing.assert_allclose(gold.kd, base)
    np.testing.assert_allclose(gold.ka, base)
    np.testing.assert_allclose(gold.ks, base)  # 0.04 + (base − 0.04) × 1
    assert gold.shininess == pytest.approx(2 / 0.3**4 - 2)
    f = 2 / 0.6**4 - 2  # 13.4: a lobe wider than f = 32, so its peak is lowered (docs/meshes.md, "Highlights")
    np.testing.assert_allclose(plastic.ks, 0.04 * (f + 2) / 34)  # metallic 0: the dielectric F0
    assert plastic.shininess == pytest.approx(f)


@pytest.mark.parametrize(("size", "share"), [((320, 240), math.pi * 0.45**2 * 240 / 320),
                                             ((120, 240), math.pi * 0.45**2 * 120 / 240)])
def test_the_camera_frames_the_bounding_sphere(tmp_path, size, share):
    """A sphere mesh's silhouette is the bounding sphere's: a disc whose radius is FILL = 0.9 of the smaller
    half-side of the image, so it covers π (0.45)² × (smaller side / larger side) of the pixels; a portrait
    size given by --set is framed for that size."""
    trimesh.creation.icosphere(subdivisions=5, radius=2.0).apply_translation([10, -3, 5]).export(tmp_path / "s.stl")
    width, height = size
    image = rp.render(rp.load_scene(tmp_path / "s.stl", [f"render.width={width}", f"render.height={height}",
                                                                    "render.background=[0, 0, 0]"])).image
    covered = image.max(axis=2) > 0
    # The 20,480-face icosphere's outline is inside the true circle by < 0.1% of its area; pixels on the
    # outline add about 2 · 2πρ / (W H) of noise.
    assert covered.mean() == pytest.approx(share, rel=0.02)
    assert not (covered[0].any() or covered[-1].any() or covered[:, 0].any() or covered[:, -1].any())
    rows, columns = np.nonzero(covered)
    assert abs(rows.mean() - (height - 1) / 2) < 1 and abs(columns.mean() - (width - 1) / 2) < 1


@pytest.mark.parametrize("name", SHIPPED)
def test_the_scene_command_writes_a_toml_that_renders_the_same_image(tmp_path, name):
    toml = tmp_path / "model.toml"
    done = runner.invoke(app, ["scene", str(MESHES / name), "-o", str(toml), "--set", "render.width=96",
                               "--set", "render.height=72"])
    assert done.exit_code == 0, done.output
    direct = rp.render(rp.load_scene(MESHES / name, ["render.width=96", "render.height=72"])).image
    written = rp.render(rp.load_scene(toml)).image
    assert direct.max() > 0.05
    np.testing.assert_array_equal(written, direct)


def test_the_scene_command_prints_to_stdout_with_an_absolute_mesh_path():
    done = runner.invoke(app, ["scene", str(MESHES / "dice.obj"), "--view", "front"])
    assert done.exit_code == 0, done.output
    assert f'path = "{MESHES / "dice.obj"}"' in done.stdout
    assert "[materials.red]" in done.stdout and 'kd = [0.8, 0.1, 0.1]' in done.stdout


def copy_dice(folder: Path, mtl: str | None) -> Path:
    shutil.copy(MESHES / "dice.obj", folder / "dice.obj")
    if mtl is not None:
        (folder / "dice.mtl").write_text(mtl, encoding="utf-8")
    return folder / "dice.obj"


@pytest.mark.parametrize("problem", ["missing mtl", "missing texture"])
def test_a_missing_mtl_or_texture_is_one_line_and_the_render_goes_on(tmp_path, problem):
    if problem == "missing mtl":
        path = copy_dice(tmp_path, None)
        wanted = ["its material file 'dice.mtl' is missing"]
    else:
        mtl = (MESHES / "dice.mtl").read_text(encoding="utf-8").replace("illum 1", "illum 1\nmap_Kd gone.png")
        path = copy_dice(tmp_path, mtl)
        wanted = ["texture 'gone.png' is missing"]
    done = runner.invoke(app, ["render", str(path), "-o", "out.png", "--width", "40", "--height", "30"])
    assert done.exit_code == 0, done.output
    notes = [line for line in done.stderr.splitlines() if line.startswith("note: ")]
    assert len(notes) == len(wanted) and all(w in n for w, n in zip(wanted, notes)), done.stderr
    assert rp.read_layer("out.png").max() > 0


def test_normals_come_from_the_file_unless_the_scene_names_a_rule():
    """dice.obj stores one normal per side: Phong shading keeps the sides flat; normals = "mean" rounds them."""
    sets = ["render.width=64", "render.height=48", 'output.aovs=["normal", "face"]']
    for normals, axis_aligned in ((None, True), ("mean", False)):
        extra = [f'objects.0.normals="{normals}"'] if normals else []
        result = rp.render(rp.load_scene(MESHES / "dice.obj", sets + extra))
        normal = result.aovs["normal"][result.aovs["face"][..., 0] >= 0]
        assert np.isclose(np.abs(normal).max(axis=1), 1.0, atol=1e-6).all() == axis_aligned


def test_a_mesh_file_that_is_not_one_is_one_line_naming_it(tmp_path):
    (tmp_path / "bad.ply").write_text("not a ply\n")
    done = runner.invoke(app, ["render", str(tmp_path / "bad.ply")])
    assert done.exit_code == 2
    [line] = done.stderr.strip().splitlines()
    assert line.startswith(f"error: {tmp_path / 'bad.ply'}: cannot read")
    done = runner.invoke(app, ["render", str(tmp_path / "model.obj")])
    assert done.exit_code == 2 and done.stderr.strip() == f"error: {tmp_path / 'model.obj'}: no such mesh file"
    done = runner.invoke(app, ["render", str(MESHES / "dice.obj"), "--view", "front", "--up", "w"])
    assert done.exit_code == 2 and "--up 'w'; allowed: x, y, z, -x, -y, -z" in done.stderr


def test_a_mesh_file_is_read_once_for_framing_and_render(monkeypatch):
    """load_scene reads the file to frame it; the render takes that reading instead of a second one."""
    from raycast_phong.io.meshes import read as mesh_file
    reads = []
    real = mesh_file.read_file
    monkeypatch.setattr(mesh_file, "read_file", lambda *a, **k: reads.append(a) or real(*a, **k))
    rp.render_file(MESHES / "painted_knot.ply", ["render.width=16", "render.height=12"])
    assert len(reads) == 1


def test_an_mtllib_that_is_a_fifo_is_one_note_and_never_blocks(tmp_path):
    """An OBJ whose `mtllib` names a FIFO: reading it would wait for a writer forever. It is refused as not a
    regular file (one note) by our .mtl reader and by the resolver trimesh is given, and the render goes on."""
    import os
    import subprocess
    import sys
    path = copy_dice(tmp_path, None)
    os.mkfifo(tmp_path / "dice.mtl")
    command = [sys.executable, "-m", "raycast_phong.cli", "render", str(path), "-o", "out.png", "--width", "32",
               "--height", "24"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    notes = [line for line in done.stderr.splitlines() if line.startswith("note: ")]
    assert len(notes) == 1 and "named pipe (FIFO)" in notes[0] and "default material is used" in notes[0], notes
    assert (tmp_path / "out.png").is_file()


def test_the_scene_command_never_writes_over_its_mesh(tmp_path):
    path = copy_dice(tmp_path, (MESHES / "dice.mtl").read_text(encoding="utf-8"))
    before = path.read_bytes()
    done = runner.invoke(app, ["scene", str(path), "-o", str(path)])
    assert done.exit_code == 2 and len(done.stderr.strip().splitlines()) == 1, done.output
    assert path.read_bytes() == before


def test_batch_renders_a_mesh_file_again_when_its_mtl_changes(tmp_path):
    """The .mtl is one of the files a mesh file's image depends on: batch's up-to-date rule covers it."""
    import json
    path = copy_dice(tmp_path, (MESHES / "dice.mtl").read_text(encoding="utf-8"))
    out = tmp_path / "out"
    sets = ["--jobs", "1", "--quiet"]

    def statuses() -> dict:
        manifest = json.loads((out / "manifest.json").read_text(encoding="utf-8"))
        return {name: entry["status"] for name, entry in manifest["scenes"].items()}

    assert runner.invoke(app, ["batch", str(path), "--out", str(out), *sets]).exit_code == 0
    assert runner.invoke(app, ["batch", str(path), "--out", str(out), *sets]).exit_code == 0
    assert statuses() == {"dice": "up to date"}
    before = rp.read_layer(out / "dice.png")
    mtl = (tmp_path / "dice.mtl").read_text()
    (tmp_path / "dice.mtl").write_text(mtl.replace("Kd 0.1 0.2 0.9", "Kd 0.9 0.2 0.1"))  # blue: lit in this view
    assert runner.invoke(app, ["batch", str(path), "--out", str(out), *sets]).exit_code == 0
    assert statuses() == {"dice": "rendered"}
    assert not np.array_equal(rp.read_layer(out / "dice.png"), before)


def test_mtl_mapping_edge_cases_and_their_notes(tmp_path):
    """illum 0 is the colour only (k_e = Kd + Ke); one number is grey; a missing key takes the default's value;
    values outside [0, 1] are clamped; a value that is not a number keeps the default; Tr, illum 3 and maps
    are said once each, with the render going on."""
    from raycast_phong.io.meshes.mtl import parse_mtl
    notes: list[str] = []
    found = parse_mtl("newmtl flat\nKd 0.5 0.25 0.125\nKe 0.25 0 0\nillum 0\n"
                      "newmtl grey\nKa 0.3\nKd 1.5 0.5 -1\nKs nonsense\nTr 0.2\nillum 3\nbump b.png\n",
                      tmp_path / "m.mtl", notes)
    flat, grey = found["flat"], found["grey"]
    assert (flat.ka, flat.kd, flat.ks, flat.ke) == ((0, 0, 0), (0, 0, 0), (0, 0, 0), (0.75, 0.25, 0.125))
    assert grey.ka == (0.3, 0.3, 0.3) and grey.kd == (1.0, 0.5, 0.0)
    assert grey.ks == (0.5, 0.5, 0.5) and grey.shininess == 32  # the default material's k_s and f
    said = "\n".join(notes)
    assert len(notes) == 6, said  # not numbers, clamped, transparency, illum 3, b.png missing, maps not applied
    for words in ("Ks nonsense", "clamped", "transparency", "illum 3", "not applied: bump b.png",
                  "'b.png' is missing"):
        assert words in said, said


def test_a_mesh_file_too_large_to_read_for_framing_is_one_line_before_any_read(tmp_path, monkeypatch):
    """Framing reads the file before render()'s memory check: a PLY whose header promises 10¹² faces is
    refused from its header (the read would try to allocate them), one line naming the file, exit 2."""
    from raycast_phong.io.meshes import read as mesh_file
    header = ("ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
              "property float z\nelement face 1000000000000\nproperty list uchar int vertex_indices\nend_header\n")
    (tmp_path / "huge.ply").write_bytes(header.encode() + bytes(64))
    monkeypatch.setattr(mesh_file, "read_file", lambda *a, **k: pytest.fail("the file was read"))
    done = runner.invoke(app, ["render", str(tmp_path / "huge.ply"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert line.startswith(f"error: {tmp_path / 'huge.ply'}: reading its 1000000M triangles needs"), line
    assert "more than the" in line and "available" in line and not (tmp_path / "x.png").exists()


def test_a_model_whose_vertices_all_coincide_is_one_line_not_a_camera_error(tmp_path):
    """Nothing to frame: the camera would sit on its target (and a numpy warning escaped before)."""
    (tmp_path / "point.obj").write_text("v 1 2 3\nv 1 2 3\nv 1 2 3\nf 1 2 3\n")
    done = runner.invoke(app, ["render", str(tmp_path / "point.obj"), "-o", str(tmp_path / "x.png")])
    assert done.exit_code == 2, done.output
    [line] = done.stderr.strip().splitlines()
    assert line == (f"error: {tmp_path / 'point.obj'}: every vertex of the model lies within 0 of [1.0, 2.0, 3.0]; "
                    "allowed: a model at least 2e-12 across"), line


def test_an_obj_is_scanned_for_its_mtllib_once_per_version(tmp_path, monkeypatch):
    """An OBJ's .mtl files are found by scanning the OBJ for `mtllib` (all of it when there is none: 0.3 s for
    78 MB). Framing, the render's read and batch want them; the scan is the file's MeshSource's, made once when
    the scene is loaded and handed on with it, and a rewrite that names another .mtl is seen."""
    import os

    from raycast_phong.io.meshes import obj as obj_format
    from raycast_phong.io.meshes.source import mesh_source, mesh_sources
    path = tmp_path / "tri.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    scans = []
    real = obj_format.scan_mtllib
    monkeypatch.setattr(obj_format, "scan_mtllib", lambda handle: scans.append(handle.name) or real(handle))
    scene = rp.load_scene(path, ["render.width=16", "render.height=12"])
    rp.render(scene)
    assert [source.side_files for source in mesh_sources(scene).values()] == [()]
    assert len(scans) == 1, scans
    path.write_text("mtllib other.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    os.utime(path, ns=(1, 1))  # a new version even on a coarse clock: the size and mtime differ
    assert [source.side_files for source in mesh_sources(scene).values()] == [(tmp_path / "other.mtl",)]
    assert mesh_source(path).side_files == (tmp_path / "other.mtl",)


def test_a_scene_file_s_obj_is_scanned_for_its_mtllib_once_by_the_render_command(tmp_path, monkeypatch):
    """`render s.toml` naming an OBJ: the output check (every file the scene reads, .mtl included) and prepare()
    want its MeshSource; the check keeps the one it makes with the scene. It was made three times (scanned 42 MB
    of a 1M-triangle OBJ three times)."""
    from raycast_phong.io.meshes import obj as obj_format
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "s.toml").write_text('[render]\nwidth = 16\nheight = 12\n[[objects]]\nshape = "mesh"\n'
                                     'path = "tri.obj"\n[[lights]]\ntype = "point"\nposition = [3, 4, 6]\n')
    scans = []
    real = obj_format.scan_mtllib
    monkeypatch.setattr(obj_format, "scan_mtllib", lambda handle: scans.append(handle.name) or real(handle))
    done = runner.invoke(app, ["render", str(tmp_path / "s.toml"), "-o", str(tmp_path / "out.png"), "-q"])
    assert done.exit_code == 0, done.output
    assert len(scans) == 1, scans


def test_an_obj_is_counted_once_for_the_framing_check_and_the_render(tmp_path, monkeypatch):
    """A MeshSource counts an OBJ's face lines (0.37 s for 78 MB) once: the framing's memory check and render()'s
    estimate both ask the source the scene carries, and a new version of the file is counted again."""
    import os

    from raycast_phong.io.meshes import size as memory
    from raycast_phong.io.meshes.source import mesh_source
    path = tmp_path / "tri.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    counted = []
    real = memory.count_triangles
    monkeypatch.setattr(memory, "count_triangles", lambda *a: counted.append(a[0].path.suffix) or real(*a))
    rp.render_file(path, ["render.width=16", "render.height=12"])
    assert counted == [".obj"]
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    os.utime(path, ns=(1, 1))
    assert mesh_source(path).triangles() == 2 and counted == [".obj", ".obj"]


def test_face_colours_drive_kd_and_ka_like_vertex_colours(tmp_path):
    """A face colour is the colour of each of its three corners: pure red is k_a = 1, not 1/3."""
    mesh = trimesh.Trimesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], process=False,
                           face_colors=[[255, 0, 0, 255]])
    mesh.export(tmp_path / "red.ply")
    (tmp_path / "s.toml").write_text('ambient = 1.0\n[render]\nwidth = 32\nheight = 32\n[camera]\n'
                                     'position = [0.3, 0.3, 2]\nlook_at = [0.3, 0.3, 0]\n'
                                     '[[objects]]\nshape = "mesh"\npath = "red.ply"\n')
    image = rp.render(rp.load_scene(tmp_path / "s.toml")).image
    covered = image.max(axis=2) > 0
    assert covered.sum() > 50
    np.testing.assert_allclose(image[covered], np.broadcast_to([1.0, 0.0, 0.0], image[covered].shape), rtol=1e-6)


def test_an_mtl_material_name_keeps_its_spaces(tmp_path):
    """`newmtl red paint` names the material "red paint" (as `usemtl red paint` refers to it): two names that
    share a first word stay two materials."""
    from raycast_phong.io.meshes.mtl import parse_mtl
    notes: list[str] = []
    materials = parse_mtl("newmtl red paint\nKd 1 0 0\nnewmtl red glaze\nKd 0 1 0\n", tmp_path / "m.mtl", notes)
    assert sorted(materials) == ["red glaze", "red paint"]
    assert materials["red paint"].kd == (1.0, 0.0, 0.0) and materials["red glaze"].kd == (0.0, 1.0, 0.0)


@pytest.mark.parametrize(("up", "axis"), [("x", 0), ("y", 1), ("z", 2), ("-z", 2)])
def test_the_up_option_is_the_camera_up_and_the_front_view_looks_across_it(tmp_path, up, axis):
    trimesh.creation.box().export(tmp_path / "box.obj")
    camera = rp.load_scene(tmp_path / "box.obj", up=up, view="front").camera
    expected = np.zeros(3)
    expected[axis] = -1.0 if up.startswith("-") else 1.0
    np.testing.assert_array_equal(camera.up, expected)
    assert abs(np.subtract(camera.position, camera.look_at)[axis]) < 1e-9  # the eye is level with the centre


COLLADA = """<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><up_axis>Y_UP</up_axis></asset>
  <library_images>
    <image id="file2" name="file2"><init_from>./MAP</init_from></image>
  </library_images>
  <library_effects>
    <effect id="fx"><profile_COMMON>
      <newparam sid="surf"><surface type="2D"><init_from>file2</init_from></surface></newparam>
      <newparam sid="samp"><sampler2D><source>surf</source></sampler2D></newparam>
      <technique sid="common"><phong><diffuse><texture texture="samp" texcoord="UV"/></diffuse></phong></technique>
    </profile_COMMON></effect>
  </library_effects>
  <library_materials><material id="mat"><instance_effect url="#fx"/></material></library_materials>
  <library_geometries><geometry id="g"><mesh>
    <source id="pos"><float_array id="pa" count="9">0 0 0 1 0 0 0 1 0</float_array>
      <technique_common><accessor source="#pa" count="3" stride="3"><param name="X" type="float"/>
        <param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
    <vertices id="v"><input semantic="POSITION" source="#pos"/></vertices>
    <triangles count="1" material="m"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="s"><node id="n"><instance_geometry url="#g"><bind_material>
    <technique_common><instance_material symbol="m" target="#mat"/></technique_common>
  </bind_material></instance_geometry></node></visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#s"/></scene>
</COLLADA>
"""


@pytest.mark.parametrize("present", [False, True])
def test_a_collada_files_missing_texture_is_a_note(tmp_path, present):
    """trimesh's COLLADA reader drops a map whose image is missing without a word (duck.dae rendered white):
    the read names it (the <image>'s init_from, a URI: %20 is a space), and says nothing when it is there."""
    (tmp_path / "tri.dae").write_text(COLLADA.replace("MAP", "duck%20map.tga"))
    if present:
        (tmp_path / "duck map.tga").write_bytes(b"")
    notes = read_mesh(tmp_path / "tri.dae", "scene.toml: objects.0.path").notes
    said = [note for note in notes if "duck map.tga" in note]
    assert said == ([] if present else [f"{tmp_path / 'tri.dae'}: texture 'duck map.tga' is missing"])
    assert not any("glTF" in note for note in notes)  # trimesh reads its materials as PBR: the note says so


def test_the_framing_radius_in_blocks_is_the_whole_array_s_to_the_bit():
    """read._radius takes max |p − centre| a block of RADIUS_ROWS points at a time: every row's sum and the
    maximum are those of the whole-array expression, so the bits are too, wherever the farthest point lies (the
    first block, a middle one, the last and partial one)."""
    from raycast_phong.io.meshes.read import RADIUS_ROWS, _radius
    rng = np.random.default_rng(7)
    points = rng.standard_normal((2 * RADIUS_ROWS + 5, 3)).astype(np.float32)
    centre = np.array([0.1, -0.2, 0.3])
    for far in (0, RADIUS_ROWS + 3, len(points) - 1):
        placed = points.copy()
        placed[far] = (40.0, -30.0, 20.0)
        whole = float(np.sqrt(((placed - centre) ** 2).sum(axis=1).max()))
        assert _radius(placed, centre) == whole
        assert whole > 50  # the planted point is the farthest


@pytest.mark.parametrize("reference", [
    "maps/wood.png",                   # a relative URI, as the specification writes it
    "./maps/wood%20grain.png",         # percent-encoded (the file is 'wood grain.png')
    "maps\\wood.png",                  # Windows' separators
    "\\maps\\wood.png",                # from the root of the drive the document was on: beside it here
    "file://maps\\wood.png",           # 3ds Max's file:// before a relative path
    "C:\\Users\\me\\Desktop\\wood.png",  # an absolute path of the exporter's machine: the name beside the document
    "maps/WOOD.PNG",                   # Windows' file names ignore case
])
def test_a_collada_image_reference_names_the_file_an_exporter_meant(tmp_path, reference):
    """Found on a fresh corpus (assimp's test/models/Collada: `\\..\\LWO\\...\\EarthCylindric.jpg` for the file
    earthCylindric.jpg, `file://..\\LWO\\...`): such maps were 'missing' and the model rendered untextured. The
    one rule (collada.image_file) gives the read, the note, the batch's inputs and the memory estimate the file."""
    from raycast_phong.io.meshes.collada import image_file
    maps = tmp_path / "maps"
    maps.mkdir()
    wanted = "wood grain.png" if "grain" in reference else "wood.png"
    rp.write_image(maps / wanted, np.full((4, 8, 3), 0.5, np.float32))
    if "Desktop" in reference:
        (maps / wanted).rename(tmp_path / wanted)
    expected = (tmp_path if "Desktop" in reference else maps) / wanted
    assert image_file(tmp_path, reference).resolve() == expected.resolve()
    (tmp_path / "tri.dae").write_text(COLLADA.replace("./MAP", reference.replace("&", "&amp;")))
    source = mesh_source(tmp_path / "tri.dae")
    assert [image.resolve() for image in source.images] == [expected.resolve()]
    assert source.format.texture_sizes(source) == ((4, 8),)
    read = read_mesh(tmp_path / "tri.dae", "scene.toml: objects.0.path")
    assert len(read.texture_sources) == 1 and not any("missing" in note for note in read.notes), read.notes
