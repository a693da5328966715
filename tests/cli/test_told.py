"""Warnings that teach instead of nag (issue 34, item 6): the default figure's Gouraud miss is a note (its object
chose Gouraud), an option that changes nothing says so, -q hides information but never a warning, and a batch
keeps every scene's warnings and notes, in its output (once) and in its manifest.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong.cli import app

runner = CliRunner()
SMALL = ["--width", "192", "--height", "72"]  # the default figure, its highlights wider than a pixel

pytestmark = pytest.mark.usefixtures("in_tmp_path")


def lines(text: str, start: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith(start)]


def default_without_its_own_gouraud() -> rp.Scene:
    """The default figure with the middle sphere's Gouraud coming from render.shading, not its own key."""
    data = tomllib.loads(rp.default_scene_path().read_text(encoding="utf-8"))
    del data["objects"][1]["shading"]
    data["render"].update(shading="gouraud", width=192, height=72)
    return rp.validate_scene(data)


def test_the_default_figure_tells_its_gouraud_miss_as_a_note_not_a_warning(tmp_path):
    """The figure shows Gouraud missing the f = 40 highlight on purpose (objects.1 has `shading = "gouraud"`):
    one note with the advice, no warning; -q leaves the note out."""
    result = runner.invoke(app, ["render", "-o", str(tmp_path / "d.png"), *SMALL])
    assert result.exit_code == 0, result.output
    assert lines(result.stderr, "warning:") == []
    [note] = lines(result.stderr, "note:")
    assert note.startswith("note: objects.1 (gouraud, its own `shading`): vertex normals 36.0° apart") and \
        "subdivisions = 3" in note, note
    quiet = runner.invoke(app, ["render", "-o", str(tmp_path / "d.png"), *SMALL, "-q"])
    assert quiet.exit_code == 0 and quiet.output == "", quiet.output


def test_gouraud_from_render_shading_is_still_a_warning():
    """The control: the same sphere, Gouraud because render.shading says so, is warned about."""
    plan = rp.render(default_without_its_own_gouraud()).plan
    assert [w for w in plan.warnings if "(gouraud)" in w] == [w for w in plan.warnings if w.startswith("objects.1")]
    assert any(w.startswith("objects.1 (gouraud): vertex normals are 36.0° apart") for w in plan.warnings)
    assert not any("gouraud" in n for n in plan.notes)


def test_an_option_that_changes_nothing_says_so_even_under_q(tmp_path):
    """Every object of the default figure has its own `shading`: --shading flat writes the scene's own image,
    and says so (a warning: the option did nothing), with -q too."""
    plain, flat = tmp_path / "plain.exr", tmp_path / "flat.exr"
    assert runner.invoke(app, ["render", "-o", str(plain), *SMALL, "-q"]).exit_code == 0
    for quiet in ([], ["-q"]):
        result = runner.invoke(app, ["render", "-o", str(flat), *SMALL, "--shading", "flat", *quiet])
        assert result.exit_code == 0, result.output
        [warning] = lines(result.stderr, "warning: --shading")
        assert warning == ("warning: --shading flat changes nothing in this scene: every object keeps its own "
                           "`shading` key, and objects 1, 2 (2 in all) are not flat; set objects.N.shading to "
                           "change one")
        np.testing.assert_array_equal(rp.read_layer(flat), rp.read_layer(plain))
    plan = runner.invoke(app, ["plan", "--set", "render.shading=phong"])
    assert lines(plan.stderr, "warning: render.shading = phong changes nothing in this scene"), plan.output


def test_own_shading_names_the_objects_render_shading_does_not_reach():
    from raycast_phong.cli.render import own_shading
    scene = rp.load_scene(rp.default_scene_path(), ["render.shading=flat"])
    assert own_shading(scene) == ("objects 1, 2 (2 in all)", 2, True)
    assert own_shading(rp.load_scene(rp.default_scene_path(), ["render.shading=gouraud"])) == \
        ("objects 0, 2 (2 in all)", 2, True)
    mixed = default_without_its_own_gouraud()  # objects.1 follows render.shading (gouraud)
    assert own_shading(mixed) == ("objects 0, 2 (2 in all)", 2, False)


def test_some_objects_keeping_their_shading_is_a_note(tmp_path):
    path = tmp_path / "mixed.toml"
    text = rp.default_scene_path().read_text(encoding="utf-8")
    path.write_text(text.replace('shading = "gouraud"\n', ""), encoding="utf-8")
    result = runner.invoke(app, ["render", str(path), "-o", str(tmp_path / "m.png"), *SMALL, "--shading", "flat"])
    assert result.exit_code == 0, result.output
    # objects.0 is flat of its own, objects.1 follows render.shading: only objects.2 (phong) is not flat
    assert lines(result.stderr, "note: --shading flat: objects.2 keeps its own `shading` key"), result.stderr
    assert not lines(result.stderr, "warning: --shading")
    quiet = runner.invoke(app, ["render", str(path), "-o", str(tmp_path / "m.png"), *SMALL, "--shading", "flat",
                                "-q"])
    assert quiet.exit_code == 0 and quiet.output == "", quiet.output


GOURAUD = """\
[render]
width = 24
height = 24
samples = 2
shading = "gouraud"

[[lights]]
position = [2, 2, 3]

[materials.red]
kd = [0.9, 0.2, 0.2]
shininess = 32

[[objects]]
shape = "icosphere"
subdivisions = 1
material = "red"
"""


def test_q_hides_information_never_a_warning(tmp_path):
    """render -q: no summary, no note, but the plan's warning."""
    scene = tmp_path / "warned.toml"
    scene.write_text(GOURAUD, encoding="utf-8")
    result = runner.invoke(app, ["render", str(scene), "-o", str(tmp_path / "w.png"), "-q"])
    assert result.exit_code == 0, result.output
    assert result.stdout == ""
    [warning] = result.stderr.splitlines()
    assert warning.startswith("warning: objects.0 (gouraud): vertex normals are 36.0° apart"), warning


def test_a_batch_says_each_scene_s_warnings_and_notes_once_and_keeps_them_in_its_manifest(tmp_path):
    """Two scenes, one warned (Gouraud from render.shading), one with a note (its object chose Gouraud): each
    line once, naming the scene; the manifest keeps them, an up-to-date scene too, without printing them again;
    -q prints the warning, not the note."""
    warned, noted = tmp_path / "warned.toml", tmp_path / "noted.toml"
    warned.write_text(GOURAUD, encoding="utf-8")
    noted.write_text(GOURAUD + 'shading = "gouraud"\n', encoding="utf-8")
    out = tmp_path / "out"
    args = ["batch", str(warned), str(noted), "-o", str(out), "--jobs", "1"]
    first = runner.invoke(app, args)
    assert first.exit_code == 0, first.output
    [warning] = lines(first.stderr, "warning:")
    [note] = lines(first.stderr, "note:")
    told = "objects.0 (gouraud{}): vertex normals"
    assert warning.startswith(f"warning: {warned}: {told.format('')}"), warning
    assert note.startswith(f"note: {noted}: {told.format(', its own `shading`')}"), note
    assert "1 rendered with warnings" in first.stdout
    entries = json.loads((out / "manifest.json").read_text(encoding="utf-8"))["scenes"]
    assert [len(entries["warned"]["warnings"]), entries["warned"]["notes"]] == [1, []]
    assert [entries["noted"]["warnings"], len(entries["noted"]["notes"])] == [[], 1]
    assert f"warning: {warned}: {entries['warned']['warnings'][0]}" == warning
    again = runner.invoke(app, args)
    assert again.exit_code == 0 and not lines(again.stderr, "warning:") and not lines(again.stderr, "note:")
    kept = json.loads((out / "manifest.json").read_text(encoding="utf-8"))["scenes"]
    assert kept["warned"]["status"] == "up to date"
    assert (kept["warned"]["warnings"], kept["noted"]["notes"]) == (entries["warned"]["warnings"],
                                                                     entries["noted"]["notes"])
    quiet = runner.invoke(app, [*args, "--force", "-q"])
    assert quiet.exit_code == 0 and quiet.stdout == ""
    assert quiet.stderr.splitlines() == [warning]


def test_a_side_by_side_says_its_variants_warnings_once(tmp_path):
    """Variants that share a warning print it once; one only some variants have names them."""
    scene = tmp_path / "warned.toml"
    scene.write_text(GOURAUD, encoding="utf-8")
    result = runner.invoke(app, ["side-by-side", str(scene), "--vary", "render.shading=gouraud,phong", "-o",
                                 str(tmp_path / "s.png")])
    assert result.exit_code == 0, result.output
    [warning] = [line for line in lines(result.stderr, "warning:") if "(gouraud)" in line]
    assert warning.startswith("warning: render.shading = gouraud: objects.0 (gouraud): vertex normals"), warning


def test_the_default_scene_file_says_why_its_gouraud_sphere_is_there():
    text = Path(rp.default_scene_path()).read_text(encoding="utf-8")
    assert "misses the f = 40 highlight: the point of the figure" in text
