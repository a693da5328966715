"""A SceneError carries where its problem is (values.messages.Location: the file, what in it when that is no key,
the key path), and its line is that location, worded in one place, then the problem."""

from __future__ import annotations

import pytest

import raycast_phong as rp
from raycast_phong.errors import SceneError
from raycast_phong.geometry.build import build_geometry
from raycast_phong.renderer.budget import check_memory
from raycast_phong.scene.overrides import apply_override
from raycast_phong.values.messages import Location, located


def caught(call) -> SceneError:
    with pytest.raises(SceneError) as error:
        call()
    found = error.value
    assert str(found) == f"{found.where}: {found.problem}"  # one line: the location, then the problem
    return found


def test_a_location_words_its_file_part_and_key_path():
    assert str(Location("s.toml")) == "s.toml"
    assert str(Location("s.toml").at("objects", 3, "radius")) == "s.toml: objects.3.radius"
    assert str(Location("s.toml", part="--set 'a=1'").at("a")) == "s.toml: --set 'a=1': a"
    assert str(Location("s.toml").at("materials", "my mat", "kd_map")) == "s.toml: materials.'my mat'.kd_map"
    assert located("s.toml") == Location("s.toml") and located(Location("x")).file == "x"


def test_each_stage_raises_at_the_key_it_refuses(tmp_path):
    def scene(*objects, **tables):
        return rp.validate_scene({"objects": list(objects), **tables}, source="s.toml", folder=tmp_path)

    error = caught(lambda: scene({"shape": "box", "size": [1, 2]}))
    assert error.where == Location("s.toml", ("objects", 0, "size")) and error.problem.startswith("must be 3")
    data = {"objects": [{"shape": "box"}]}
    error = caught(lambda: apply_override(data, "objects.5.size=[1, 2, 3]", source="s.toml"))
    assert error.where == Location("s.toml", ("objects", "5"), part="--set 'objects.5.size=[1, 2, 3]'")
    thin = scene({"shape": "box"}, {"shape": "torus", "minor_radius": 1e-12})
    assert caught(lambda: build_geometry(thin)).where == Location("s.toml", ("objects", 1))
    missing = scene({"shape": "mesh", "path": "gone.obj"})
    error = caught(lambda: build_geometry(missing))  # located from the scene's origin
    assert error.where == Location("s.toml", ("objects", 0, "path")) and error.problem.startswith("no such mesh")
    fine = scene({"shape": "icosphere", "subdivisions": 8})
    error = caught(lambda: check_memory(fine, 1 << 20))
    assert error.where == Location("s.toml", ("objects", 0, "subdivisions"))


@pytest.mark.parametrize("value", [5, [1, 2], True])
def test_a_map_that_is_neither_a_file_name_nor_a_table_says_what_a_map_is(value):
    """Issue 30 item 10: kd_map = 5 was once taken as the file '5', then called no table of keys; a map is a file
    name or a table, and the line says so."""
    with pytest.raises(rp.SceneError) as raised:
        rp.validate_scene({"materials": {"m": {"kd_map": value}}, "objects": [{"shape": "uv_sphere", "material": "m"}]},
                          source="s.toml")
    assert str(raised.value).startswith('s.toml: materials.m.kd_map: must be an image file name or a table '
                                        '{ path = "...", wrap = "clamp" }'), str(raised.value)


@pytest.mark.parametrize(("table", "said"), [
    ({"render": {"shading": "phon"}}, "render.shading: Input should be 'flat', 'gouraud' or 'phong' (got the string "
                                      "'phon') (did you mean 'phong'?)"),
    ({"render": {"terminator": "hanikka"}}, "(did you mean 'hanika'?)"),
    ({"render": {"shading": "xyz"}}, "(got the string 'xyz')"),  # nothing close: no guess
])
def test_a_mistyped_choice_in_a_scene_offers_the_closest_one(table, said):
    """As on the command line (`--shading phongg`): pydantic's "Input should be ..." and the closest choice."""
    with pytest.raises(rp.SceneError) as refused:
        rp.validate_scene(table)
    assert str(refused.value).endswith(said), str(refused.value)
    assert ("did you mean" in str(refused.value)) == ("xyz" not in said)


@pytest.mark.parametrize("text, key", [('"a[0]" = 1\n', "a[0]"), ('[render]\n"w[1]" = 2\n', "w[1]"),
                                       ('["lights=[{x"]\ny = 1\n', "lights=[{x")])
def test_an_unknown_key_with_a_bracket_is_named_not_an_internal_error(tmp_path, text, key):
    """A quoted TOML key may hold '[' ("a[0]" = 1): validation names it as any unknown key, with the keys
    allowed there. describe_error dropped every loc part with a '[' as one of pydantic's union-branch names,
    left an empty loc and raised IndexError: an internal error (exit 1) instead of one line about the file."""
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(rp.SceneError, match=r"unknown key.*; valid keys here: ") as refused:
        rp.load_scene(path)
    assert key in str(refused.value)


def test_a_value_or_key_of_exactly_shown_characters_is_echoed_whole_and_one_more_is_cut():
    """A value echoed in a message is cut past SHOWN_CHARACTERS (80), counting what it leaves out; a key path's
    part of up to 80 characters is written plain, a longer one quoted and cut."""
    from raycast_phong.values.messages import SHOWN_CHARACTERS, dotted, shorten
    assert SHOWN_CHARACTERS == 80
    assert shorten("v" * 80) == "v" * 80
    assert shorten("v" * 81) == "v" * 80 + "… (1 more characters)"
    assert dotted(("materials", "k" * 80, "kd")) == f"materials.{'k' * 80}.kd"
    assert dotted(("materials", "k" * 81, "kd")) == f"materials.'{'k' * 79}… (3 more characters).kd"
