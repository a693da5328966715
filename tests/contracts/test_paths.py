"""Paths (issue 21, item 6): output.path cannot leave the scene's folder through a symbolic link; `-o LINK`
writes the file the link names and keeps the link; a name with a newline keeps progress lines whole;
`batch 'dir/*'` takes no images as scenes; a FIFO named *.toml in a batch folder is reported.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from typer.testing import CliRunner

from raycast_phong.cli import app

runner = CliRunner()
CLI = [sys.executable, str(Path(__file__).parents[2] / "cli.py")]
SCENE = ('[[objects]]\nshape = "box"\n[[lights]]\nposition = [2, 2, 3]\n[render]\nwidth = 8\nheight = 8\n'
         '[output]\npath = "{path}"\n')


def test_output_path_through_a_symlinked_subfolder_is_refused(tmp_path):
    scenes, elsewhere = tmp_path / "scenes", tmp_path / "elsewhere"
    scenes.mkdir()
    elsewhere.mkdir()
    (scenes / "out").symlink_to(elsewhere)
    (scenes / "s.toml").write_text(SCENE.format(path="out/x.png"))
    result = runner.invoke(app, ["render", str(scenes / "s.toml")])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1 and "symbolic link" in lines[0], result.output
    assert not list(elsewhere.iterdir())


def test_output_path_in_a_real_subfolder_still_renders(tmp_path):
    (tmp_path / "out").mkdir()
    (tmp_path / "s.toml").write_text(SCENE.format(path="out/x.png"))
    result = runner.invoke(app, ["render", str(tmp_path / "s.toml"), "-q"])
    assert result.exit_code == 0 and (tmp_path / "out" / "x.png").is_file(), result.output


def test_o_naming_a_symlink_writes_its_target_and_keeps_the_link(tmp_path):
    target, link = tmp_path / "real.png", tmp_path / "link.png"
    target.write_bytes(b"old")
    link.symlink_to(target)
    result = runner.invoke(app, ["render", "-o", str(link), "--width", "8", "--height", "8", "-q"])
    assert result.exit_code == 0, result.output
    assert link.is_symlink() and target.read_bytes()[:4] == b"\x89PNG"


def test_batch_glob_takes_no_images_and_a_fifo_scene_is_reported(tmp_path):
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "a.toml").write_text(SCENE.format(path="a.png"))
    (folder / "old.png").write_bytes(b"\x89PNG not a scene")
    done = subprocess.run([*CLI, "batch", str(folder / "*"), "--out", str(tmp_path / "out"), "-q"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0 and "old" not in done.stderr, done.stderr
    os.mkfifo(folder / "pipe.toml")
    done = subprocess.run([*CLI, "batch", str(folder), "--out", str(tmp_path / "out2"), "-q"],
                          capture_output=True, text=True, timeout=120, stdin=subprocess.DEVNULL)
    assert done.returncode == 1 and "pipe.toml" in done.stderr and "named pipe" in done.stderr, done.stderr


def test_a_scene_name_with_a_newline_keeps_progress_lines_whole(tmp_path):
    folder = tmp_path / "scenes"
    folder.mkdir()
    (folder / "two\nlines.toml").write_text(SCENE.format(path="x.png"))
    done = subprocess.run([*CLI, "batch", str(folder), "--out", str(tmp_path / "out")], capture_output=True,
                          text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    progress = [line for line in done.stderr.splitlines() if line.startswith("[")]
    assert progress == [progress[0]] and progress[0].endswith("rendered: two\\nlines"), done.stderr
