"""Options and fixtures shared by the whole test suite.

    pytest --update-references    rewrite the reference images instead of comparing against them

The option and the `assert_image_matches` / `image_references` fixtures come from raycast-phong's own pytest
plugin (raycast_phong/pytest_plugin.py, registered by the installed package's pytest11 entry point).
"""

from __future__ import annotations

from pathlib import Path

import pytest

pytest_plugins = ["pytester"]  # the plugin's own tests (tests/project/test_pytest_plugin.py) run pytest inside pytest


# One low-poly red sphere in the middle, lit from the upper right: flat, Gouraud and Phong differ on it,
# the corners are background. Tests format in the size (and an [output] table if they need one).
TINY_SCENE = """\
ambient = [0.1, 0.1, 0.1]

[render]
width = {width}
height = {height}

[camera]
position = [0, 0, 4]
look_at = [0, 0, 0]
fov = 40

[[lights]]
position = [2, 2, 3]

[materials.red]
ka = [1.0, 0.3, 0.3]
kd = [0.9, 0.2, 0.2]
ks = [0.6, 0.6, 0.6]

[[objects]]
shape = "icosphere"
subdivisions = 1
material = "red"
"""


def write_tiny_scene(folder: Path, width: int, height: int, extra: str = "") -> Path:
    """TINY_SCENE at width × height, with `extra` TOML appended, as folder/tiny.toml."""
    path = folder / "tiny.toml"
    path.write_text(TINY_SCENE.format(width=width, height=height) + extra, encoding="utf-8")
    return path


@pytest.fixture
def in_tmp_path(tmp_path, monkeypatch):
    """Run in tmp_path, so a default-named output can never land in the repository; no debug tracebacks."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("RAYCAST_PHONG_DEBUG", raising=False)


def pixel_centre_rays(rig, width: int, height: int):
    """The eye and the unit direction (H, W, 3) through every pixel centre of a perspective camera_rig,
    written from the scene format (x right, y up, row 0 at the top), independent of camera.py."""
    import numpy as np
    x = (np.arange(width) + 0.5) / width * 2 - 1
    y = 1 - (np.arange(height) + 0.5) / height * 2
    sx, sy = np.meshgrid(x * rig.half_width, y * rig.half_height)
    d = rig.forward + sx[..., None] * rig.right + sy[..., None] * rig.up
    return rig.eye, d / np.linalg.norm(d, axis=-1, keepdims=True)


@pytest.fixture(autouse=True, scope="session")
def error_logs_in_the_session_folder(tmp_path_factory):
    """Internal-error tracebacks (cli.common._traceback_log) of this run, and of the commands it starts, go to
    a folder of the session's own instead of piling up as raycast-phong-error-*.log in /tmp."""
    import os
    folder = tmp_path_factory.mktemp("error-logs")
    before = os.environ.get("RAYCAST_PHONG_ERROR_LOGS")
    os.environ["RAYCAST_PHONG_ERROR_LOGS"] = str(folder)
    yield folder
    if before is None:
        os.environ.pop("RAYCAST_PHONG_ERROR_LOGS", None)
    else:
        os.environ["RAYCAST_PHONG_ERROR_LOGS"] = before


@pytest.fixture(autouse=True, scope="session")
def kernels_ready(tmp_path_factory):
    """Every kernel compiled (or loaded from the cache) before the first test, as after an install's first render.

    A render on an empty cache says "compiling ..." first (renderer/warmup.py); tests that run the CLI check its
    exact output, so which of them came first on a fresh clone must not decide what they see. The tests of the
    notice itself stand in for a cache miss (compiles.compiling, as numba's cache reports one)."""
    import trimesh

    from raycast_phong.renderer.warmup import ready_kernels
    from raycast_phong.scene.schema import validate_scene
    folder = tmp_path_factory.mktemp("warm")
    trimesh.creation.icosphere(1).export(folder / "ball.stl")  # no normals: the crease split's kernels too
    trimesh.creation.icosphere(1).export(folder / "ball.obj")  # an OBJ's polygon scan
    for precision, name in (("float32", "ball.stl"), ("float64", "ball.stl"), ("float32", "ball.obj")):
        ready_kernels(validate_scene({"render": {"precision": precision},
                                      "objects": [{"shape": "mesh", "path": str(folder / name)}]}, source="t"))
