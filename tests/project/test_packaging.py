"""The wheel holds every module and data file of the package: built from the tracked files alone (as a clean
clone has them), not from an editable install, which finds modules a wheel leaves out."""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = (".py", ".toml", ".html", ".js", ".css")  # modules, the default scene, the view's page


def tracked_files() -> list[str]:
    try:
        listed = subprocess.run(["git", "ls-files", "-z"], cwd=ROOT, capture_output=True, check=True, timeout=60)
    except (OSError, subprocess.CalledProcessError):
        pytest.skip("needs a git checkout to know which files a clean clone has")
    return [name for name in listed.stdout.decode().split("\0") if name]


@pytest.mark.slow
def test_the_wheel_holds_every_module_and_data_file(tmp_path):
    source = tmp_path / "clone"
    for name in tracked_files():
        if (ROOT / name).is_file():
            (source / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, source / name)
    (source / "scenes" / "default.png").write_bytes(b"a render README's examples write beside the scene")
    built = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q",
                            "-w", str(tmp_path / "dist"), str(source)], capture_output=True, text=True, timeout=600)
    assert built.returncode == 0, built.stderr[-2000:]
    (wheel,) = (tmp_path / "dist").glob("raycast_phong-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        shipped = {name for name in archive.namelist() if name.startswith("raycast_phong/")}
    wanted = {path.relative_to(source).as_posix() for path in (source / "raycast_phong").rglob("*")
              if path.suffix in SHIPPED and "__pycache__" not in path.parts}
    assert wanted - shipped == set(), "tracked files the wheel leaves out"
    assert "raycast_phong/tools/batch/manifest.py" in shipped  # the package a hand-written list once left out
    assert "raycast_phong/py.typed" in shipped  # PEP 561: the annotations are public
    assert not any(name.startswith(("tests/", "benchmarks/", "cli.py")) for name in archive.namelist())
    # The example scenes with their meshes and maps (setup.py), so the default scene and --example work anywhere.
    examples = {path.relative_to(source / "scenes").as_posix() for path in (source / "scenes").rglob("*")
                if path.is_file() and path.suffix != ".py" and path.name != "default.png"}
    assert {f"raycast_phong/data/scenes/{name}" for name in examples} <= shipped
    assert "raycast_phong/data/scenes/default.png" not in shipped  # a render's output is no example
    assert "raycast_phong/data/scenes/textures/checker.png" in shipped  # a map is
    with zipfile.ZipFile(wheel) as archive:
        metadata = archive.read(next(n for n in archive.namelist() if n.endswith(".dist-info/METADATA"))).decode()
        licence = [n for n in archive.namelist() if n.endswith("licenses/LICENSE")]
    assert "License-Expression: MIT" in metadata and licence, metadata[:600]
