"""Every colour map key a scene material has (codes.MAP_COLUMNS: ka_map, kd_map, ke_map) is honoured by each
stage that reads maps, the one list of keys they all take: the memory estimate weighs it and refuses a missing
file, the geometry memo's key follows its file, and the render shows it. A stage that restated the keys and left
one out (the estimate once weighed ka_map and kd_map alone) fails here for that key."""

from __future__ import annotations

import os

import numpy as np
import pytest

import raycast_phong as rp
from raycast_phong.codes import MAP_COLUMNS
from raycast_phong.errors import SceneError
from raycast_phong.geometry.memo import BuildMemo
from raycast_phong.io.textures import TEXTURE_BYTES_PER_TEXEL
from raycast_phong.renderer.budget import estimate_memory

# A plane seen head-on in flat ambient, diffuse and emission light; the material's own colours are mid-grey, so
# a black map under any one term darkens the image (ka modulates the ambient, kd the diffuse, ke the emission).
SCENE = """
ambient = 0.5
[render]
width = 8
height = 8
[camera]
type = "orthographic"
position = [0, 0, 5]
view_height = 1.0
[[lights]]
type = "directional"
direction = [0, 0, -1]
[materials.m]
ka = [0.5, 0.5, 0.5]
kd = [0.5, 0.5, 0.5]
ks = [0, 0, 0]
ke = [0.5, 0.5, 0.5]
{key} = "{name}"
[[objects]]
shape = "plane"
size = [4, 4]
rotate = [90, 0, 0]
material = "m"
"""


def scene_with(folder, key: str, name: str = "map.png") -> rp.Scene:
    path = folder / f"{key}.toml"
    path.write_text(SCENE.format(key=key, name=name))
    return rp.load_scene(path)


@pytest.fixture
def black_map(tmp_path):
    rp.write_image(tmp_path / "map.png", np.zeros((32, 64, 3), np.float32))
    return tmp_path


@pytest.mark.parametrize("key", MAP_COLUMNS)
def test_the_estimate_weighs_every_map_key_and_refuses_its_missing_file(black_map, key):
    assert estimate_memory(scene_with(black_map, key)).textures == TEXTURE_BYTES_PER_TEXEL * 64 * 32
    with pytest.raises(SceneError, match=rf"materials\.m\.{key}"):
        estimate_memory(scene_with(black_map, key, "missing.png"))


@pytest.mark.parametrize("key", MAP_COLUMNS)
def test_the_geometry_memo_s_key_follows_every_map_key_s_file(black_map, key):
    """A changed map file (another size, a later time) is another build: the memo's key holds every map's version."""
    scene = scene_with(black_map, key)
    before = BuildMemo().begin(scene, True, np.float32)
    rp.write_image(black_map / "map.png", np.zeros((16, 16, 3), np.float32))
    os.utime(black_map / "map.png", ns=(1, 1))
    assert BuildMemo().begin(scene, True, np.float32) != before


@pytest.mark.parametrize("key", MAP_COLUMNS)
def test_the_render_shows_every_map_key(black_map, key):
    """A black map takes its term away: the image is darker than the same scene without the map."""
    with_map = rp.render(scene_with(black_map, key)).image
    (black_map / "plain.toml").write_text(SCENE.format(key="# no map", name="").replace('# no map = ""', ""))
    plain = rp.render(rp.load_scene(black_map / "plain.toml")).image
    assert with_map.mean() < plain.mean() - 0.1, (with_map.mean(), plain.mean())
