"""stdout and stderr are outputs too, and stdin an input (issue 21, item 5): a full disk or a closed pipe on
stdout ends in one line and exit 2, not a traceback (or a silent exit 1); `-` and /dev/stdin read a scene
from a pipe, and --help says so.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

CLI = [sys.executable, str(Path(__file__).parents[2] / "cli.py")]
DEFAULT = Path(__file__).parents[2] / "scenes" / "default.toml"
SMALL = ["--width", "16", "--height", "16"]


def run(args: list[str], stdout, stdin=subprocess.DEVNULL) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "RAYCAST_PHONG_DEBUG"}
    return subprocess.run([*CLI, *args], stdout=stdout, stderr=subprocess.PIPE, stdin=stdin, text=True,
                          timeout=300, env=env)


def closed_pipe() -> int:
    """The write end of a pipe whose reader has gone (the caller closes it after the run)."""
    reader, writer = os.pipe()
    os.close(reader)
    return writer


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
@pytest.mark.parametrize("args", [["schema"], ["render", *SMALL], ["--help"]])
def test_stdout_on_a_full_disk_is_one_line_and_exit_2(tmp_path, args):
    if args[0] == "render":
        args = [*args, "-o", str(tmp_path / "o.png")]
    with open("/dev/full", "w") as full:
        done = run(args, full)
    lines = [line for line in done.stderr.splitlines() if not line.startswith(("warning:", "note:"))]
    assert done.returncode == 2 and lines == ["error: stdout: write failed: No space left on device"], done.stderr


@pytest.mark.parametrize("args", [["schema"], ["--help"], ["render", *SMALL]])
def test_a_closed_pipe_on_stdout_is_one_line_and_exit_2(tmp_path, args):
    if args[0] == "render":
        args = [*args, "-o", str(tmp_path / "o.png")]
    writer = closed_pipe()
    try:
        done = run(args, writer)
    finally:
        os.close(writer)
    lines = [line for line in done.stderr.splitlines() if not line.startswith(("warning:", "note:"))]
    assert done.returncode == 2 and lines == ["error: stdout: write failed: the reader closed the pipe"], done.stderr


JSON = '{"objects": [{"shape": "box"}], "lights": [{"position": [2, 2, 3]}], "output": {"path": "j.png"}}'


@pytest.mark.parametrize("name, text", [("-", DEFAULT.read_text()), ("/dev/stdin", DEFAULT.read_text()),
                                        ("-", JSON), ("-", "\ufeff \r\n\t" + JSON)])
def test_a_scene_is_read_from_stdin(tmp_path, name, text):
    """TOML, or JSON when the text starts with `{` after any blanks and a byte-order mark (an editor's, or
    `echo` and a heredoc's line feed): read as TOML, such JSON was a TOML syntax error."""
    source = tmp_path / "piped"
    source.write_text(text, encoding="utf-8")
    with open(source) as stdin:
        done = subprocess.run([*CLI, "render", name, *SMALL, "-q"], cwd=tmp_path, stdin=stdin,
                              capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert sorted(p.name for p in tmp_path.glob("*.png")) == (["j.png"] if "{" in text else ["default.png"])


def test_a_bad_scene_from_stdin_names_it():
    done = subprocess.run([*CLI, "render", "-"], input='{"render": {"width": 0}}', capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 2 and done.stderr.startswith("error: -: render.width: out of range"), done.stderr


def test_help_says_how_to_pipe_a_scene_in():
    done = subprocess.run([*CLI, "render", "--help"], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "COLUMNS": "200"})
    assert "standard input" in done.stdout and "| raycast-phong render -" in done.stdout, done.stdout
