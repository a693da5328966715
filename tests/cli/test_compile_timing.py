"""Every compile is reported as `compile` (issue 48, item 1): a mesh reader's kernels compile while the scene loads,
and that time was shown as `load 16.0s`."""

from __future__ import annotations

import re
import time

from typer.testing import CliRunner

import raycast_phong as rp
from raycast_phong import compiles
from raycast_phong.cli import app

runner = CliRunner()


def test_nested_compiles_count_once_from_the_outermost_miss_to_its_save():
    before = compiles.seconds_compiling()
    compiles.compiling("outer", "()")
    time.sleep(0.05)
    compiles.compiling("callee", "()")  # compiled within the outer one
    time.sleep(0.05)
    compiles.compiled()
    compiles.compiled()
    spent = compiles.seconds_compiling() - before
    assert 0.1 <= spent < 0.5
    compiles.compiled()  # a save without a miss (nothing open) counts nothing
    assert compiles.seconds_compiling() - before == spent


def test_a_compile_while_the_scene_loads_is_reported_as_compile_not_load(tmp_path, monkeypatch):
    real = rp.load_scene

    def loading_with_a_compile(*args, **kwargs):
        compiles.compiling("io.meshes.ply_rows.walk_rows", "()")
        time.sleep(0.3)
        compiles.compiled()
        return real(*args, **kwargs)

    monkeypatch.setattr(rp, "load_scene", loading_with_a_compile)
    done = runner.invoke(app, ["render", "-o", str(tmp_path / "x.png"), "--width", "32", "--height", "12"])
    assert done.exit_code == 0, done.output
    load = float(re.search(r"load ([0-9.]+)s", done.output)[1])
    compile_ = float(re.search(r"compile ([0-9.]+)s", done.output)[1])
    assert compile_ >= 0.3 and load < 0.3, done.output
