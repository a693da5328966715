"""The scene writer (issue 34 item 2): `raycast-phong scene` and the view's "Save scene" write TOML that
tomllib parses and load_scene reads back to the same scene, with every file the scene names (meshes,
texture maps) rebased to the folder the file is written to."""

from __future__ import annotations

import os
import shutil
import tomllib
from pathlib import Path

import pytest

import raycast_phong as rp
from raycast_phong.io.scene_toml import scene_toml, toml_value

SCENES = Path(__file__).resolve().parents[2] / "scenes"
EXAMPLES = sorted(SCENES.glob("*.toml")) + sorted(p for p in (SCENES / "meshes").iterdir()
                                                  if p.suffix.lower() in {".obj", ".ply", ".glb"})


def resolved(scene: rp.Scene) -> dict:
    """The scene as JSON data with every file it names (but its own output, which is relative to the scene
    file wherever that is) made absolute: two scenes naming the same files from different folders are equal."""
    data = scene.model_dump(mode="json", exclude={"folder"})
    for key, path in scene.named_files().items():
        if key[0] == "objects":
            data["objects"][key[1]]["path"] = str(scene.resolve(path).resolve())
        elif key[0] == "materials":  # ("materials", NAME, MAP, "path"): NAME may hold dots
            data["materials"][key[1]][key[2]]["path"] = str(scene.resolve(path).resolve())
    return data


def round_trip(scene: rp.Scene, folder: Path) -> tuple[rp.Scene, dict]:
    """Write the scene into `folder` as scene_toml does for `raycast-phong scene -o`; read it back."""
    folder.mkdir(parents=True, exist_ok=True)
    target = folder / "written.toml"
    text = scene_toml(scene, "# a header", relative_to=folder)
    parsed = tomllib.loads(text)  # valid TOML, not only to our own loader
    target.write_text(text, encoding="utf-8")
    return rp.load_scene(target), parsed


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_every_example_scene_reads_back_the_same_from_another_folder(path, tmp_path):
    scene = rp.load_scene(path)
    again, parsed = round_trip(scene, tmp_path / "elsewhere" / "deeper")
    assert resolved(again) == resolved(scene)
    for obj in parsed.get("objects", []):  # a mesh path is written relative to the new file's folder
        if "path" in obj:
            assert not os.path.isabs(obj["path"]), obj["path"]


MAP_KEYS = ("ka_map", "kd_map", "ke_map")


@pytest.mark.parametrize("key", ["objects.0.path", *(f"materials.m.{k}.path" for k in MAP_KEYS)])
def test_each_key_that_names_a_file_is_rebased_and_reads_back(key, tmp_path):
    source = tmp_path / "source"
    (source / "textures").mkdir(parents=True)
    shutil.copy(SCENES / "textures" / "checker.png", source / "textures" / "checker.png")
    shutil.copy(SCENES / "meshes" / "torus_knot.ply", source / "knot.ply")
    name = "brushed steel.v2"  # a material name that must be quoted, with a dot in it
    material: dict = {"kd": [0.6, 0.5, 0.4], "shininess": 32}
    obj: dict = {"shape": "uv_sphere", "material": name}
    if key == "objects.0.path":
        obj = {"shape": "mesh", "path": "knot.ply", "material": name}
    else:
        material[key.split(".")[2]] = {"path": "textures/checker.png", "wrap": "clamp"}
    data = {"camera": {"position": [0, 0, 4]}, "lights": [{"position": [1, 2, 3]}],
            "materials": {name: material}, "objects": [obj]}
    scene = rp.validate_scene(data, source="generated", folder=source)
    named = scene.named_files()
    expected_key = ("objects", 0, "path") if key == "objects.0.path" else ("materials", name, key.split(".")[2], "path")
    assert set(named) == {expected_key, ("output", "path")}

    again, parsed = round_trip(scene, tmp_path / "written" / "here")
    assert resolved(again) == resolved(scene)
    written = parsed["objects"][0]["path"] if key.startswith("objects.") else \
        parsed["materials"][name][key.split(".")[2]]["path"]
    expected = os.path.relpath(scene.resolve(next(iter(named.values()))), tmp_path / "written" / "here")
    assert written == expected and written.startswith("../../source/")
    if not key.startswith("objects."):
        assert parsed["materials"][name][key.split(".")[2]]["wrap"] == "clamp"


def test_the_file_reads_as_a_scene_written_by_hand_and_values_stay_one_line():
    text = scene_toml(rp.load_scene(SCENES / "textured_sphere.toml"), "a header\n# its second line")
    assert text.startswith("# a header\n# its second line\n\nambient = [0.1, 0.1, 0.1]\n")
    for line in ("[render]", "[[lights]]", "position = [3.0, 4.0, 6.0]", "[materials.checker.kd_map]",
                 "[[objects]]", "[output]", "aovs = []"):
        assert f"\n{line}\n" in text, line
    texture = {"path": "a b.png", "wrap": "clamp"}
    assert "\n" not in toml_value(texture) and tomllib.loads(f"v = {toml_value(texture)}")["v"] == texture
    assert tomllib.loads(f"v = {toml_value(['depth', 1.5, float('inf'), True])}")["v"] == ["depth", 1.5,
                                                                                          float("inf"), True]


@pytest.mark.parametrize("path, overrides, colour", [
    (SCENES / "textured_sphere.toml", [], "display"), (SCENES / "textured_sphere.toml", ["render.colour=linear"],
                                                       "linear"),
    (SCENES / "meshes" / "still_life.glb", [], "linear"), (SCENES / "meshes" / "dice.obj", [], "display")])
def test_the_colour_setting_is_written_and_reads_back(path, overrides, colour, tmp_path):
    """render.colour is written with the other render keys: a glTF's scene (linear by its format) stays linear
    once it is a scene file, whose own default is display."""
    scene = rp.load_scene(path, overrides)
    again, parsed = round_trip(scene, tmp_path)
    assert scene.render.colour == parsed["render"]["colour"] == again.render.colour == colour


def test_an_unset_crease_angle_stays_unset_so_a_file_without_normals_stays_creased(tmp_path):
    """Written out, an object's unset crease_angle read 180: a mesh file without normals, creased at 30° in
    the scene, came back smoothed. Set ones are kept."""
    mesh = tmp_path / "m.obj"
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "s.toml").write_text('[[objects]]\nshape = "mesh"\npath = "m.obj"\n')
    scene = rp.load_scene(tmp_path / "s.toml")
    written = tmp_path / "back.toml"
    written.write_text(scene_toml(scene, relative_to=tmp_path))
    again = rp.load_scene(written)
    assert "crease_angle" not in tomllib.loads(written.read_text())["objects"][0]
    assert "crease_angle" not in again.objects[0].model_fields_set
    creased = scene.replace({"objects.0.crease_angle": 45})
    assert tomllib.loads(scene_toml(creased, relative_to=tmp_path))["objects"][0]["crease_angle"] == 45
