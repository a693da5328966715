"""The public API type-checks in a user's script under `mypy --strict` (py.typed): every name of
raycast_phong.__all__ is an explicit re-export, and what the documented calls return has its real type, not Any."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import raycast_phong as rp

ROOT = Path(__file__).resolve().parents[2]

# A user's script: each documented call, and the type mypy must reveal for it (docs/api.md).
CALLS = {
    'rp.load_scene("scenes/default.toml")': "raycast_phong.scene.schema.Scene",
    "rp.validate_scene({})": "raycast_phong.scene.schema.Scene",
    "rp.mesh_scene(np.zeros((3, 3)), np.array([[0, 1, 2]]))": "raycast_phong.scene.schema.Scene",
    "rp.render(rp.load_scene(rp.default_scene_path()))": "raycast_phong.records.RenderResult",
    'rp.Renderer(threads=2, max_memory="1G").render(rp.load_scene(rp.default_scene_path()))':
        "raycast_phong.records.RenderResult",
    'rp.render_file("model.obj")': "raycast_phong.records.RenderResult",
    "rp.build_plan(rp.load_scene(rp.default_scene_path()))": "raycast_phong.records.RenderPlan",
    'rp.write_image("x.png", np.zeros((2, 2, 3), np.float32))': "pathlib.Path",
    "rp.default_scene_path()": "pathlib.Path",
    'rp.read_image("x.png")[1]': "tuple[str, ...]",
}


def test_the_public_names_are_spelled_once_for_python_and_once_for_type_checkers():
    """__all__ is written out for type checkers (sorted(_HOMES) is invisible to them): the same names."""
    assert rp.__all__ == sorted(rp._HOMES)
    text = (ROOT / "raycast_phong" / "__init__.py").read_text()
    exported = set(re.findall(r"import (\w+) as (\w+)", text))
    assert {name for name, alias in exported if name == alias} == set(rp.__all__)


def test_a_users_script_type_checks_under_mypy_strict(tmp_path):
    pytest.importorskip("mypy")
    script = tmp_path / "user.py"
    lines = ["import numpy as np", "import raycast_phong as rp", "",
             "result: rp.RenderResult = rp.render(rp.load_scene(rp.default_scene_path()))",
             "pixels: np.ndarray = result.image",
             "try:", "    rp.load_scene('missing.toml')", "except rp.SceneError as error:", "    print(error)",
             "model: rp.ShadingModel = rp.ShadingModel.PHONG",
             *(f"reveal_type({call})" for call in CALLS)]
    script.write_text("\n".join(lines) + "\n")
    done = subprocess.run([sys.executable, "-m", "mypy", "--strict", "--follow-imports=silent", "--no-incremental",
                           "--cache-dir", str(tmp_path / "cache"), str(script)], capture_output=True, text=True,
                          cwd=tmp_path, env={**os.environ, "MYPYPATH": str(ROOT)}, timeout=300)
    revealed = re.findall(r'Revealed type is "([^"]+)"', done.stdout)
    errors = [line for line in done.stdout.splitlines() if ": error:" in line]
    assert not errors, done.stdout
    assert revealed == list(CALLS.values()), "\n".join(f"{c}: {r}" for c, r in zip(CALLS, revealed))
