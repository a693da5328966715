"""Bad input that reached "internal error" or a runaway line (issue 21, item 4): nesting thousands deep,
numbers of thousands of digits, `--set` values nested deep, an output name longer than the file system
allows, NUMBA_* settings numba cannot run under; and every error line is one line of bounded length, with
a control character in a key shown escaped.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from raycast_phong.cli import app

runner = CliRunner()
CLI = [sys.executable, str(Path(__file__).parents[2] / "cli.py")]
LINE = 2100  # cli.common.MESSAGE_CHARACTERS and the "error: " before it


def refused(result, *needles: str) -> str:
    """The one error line of a refused run (exit 2, no traceback)."""
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1, result.output[:3000]
    assert "internal error" not in lines[0] and len(lines[0]) < LINE, lines[0][:300]
    for needle in needles:
        assert needle in lines[0], lines[0]
    return lines[0]


DEEP = 100_000


@pytest.mark.parametrize("name, text", [
    ("deep.json", '{"objects": ' + "[" * DEEP + "]" * DEEP + "}"),
    ("deep.toml", "ambient = " + "[" * DEEP + "]" * DEEP + "\n"),
    ("tables.json", '{"render": ' + '{"a": ' * DEEP + "1" + "}" * DEEP + "}"),
])
def test_nesting_thousands_deep_is_bad_input(tmp_path, name, text):
    (tmp_path / name).write_text(text)
    refused(runner.invoke(app, ["render", str(tmp_path / name), "-o", str(tmp_path / "o.png")]),
            name, "nested too deep")


@pytest.mark.parametrize("name, text", [("num.json", '{"render": {"width": ' + "9" * 5000 + "}}"),
                                        ("num.toml", "[render]\nwidth = " + "9" * 5000 + "\n")])
def test_a_number_of_5000_digits_is_bad_input(tmp_path, name, text):
    (tmp_path / name).write_text(text)
    refused(runner.invoke(app, ["render", str(tmp_path / name), "-o", str(tmp_path / "o.png")]), name, "digits")


@pytest.mark.parametrize("value", ["[" * DEEP + "]" * DEEP, "9" * 5000])
def test_a_set_value_nested_deep_or_too_long_is_bad_input(tmp_path, value):
    line = refused(runner.invoke(app, ["render", "--set", f"render.width={value}", "-o", str(tmp_path / "o.png")]),
                   "--set")
    assert "more characters" in line


def test_an_output_name_longer_than_the_file_system_allows(tmp_path):
    refused(runner.invoke(app, ["render", "-o", str(tmp_path / ("a" * 300 + ".png"))]), "longer than the")


def test_a_million_numbers_are_not_echoed_back(tmp_path):
    path = tmp_path / "ambient.json"
    path.write_text(json.dumps({"ambient": [0.5] * 1_000_000}))
    refused(runner.invoke(app, ["render", str(path), "-o", str(tmp_path / "o.png")]), "ambient", "1000000 numbers")


def test_a_control_character_in_a_key_is_named_escaped(tmp_path):
    path = tmp_path / "bell.json"
    path.write_text('{"rend\\u0007er": {}, "x\\u001b[31m": 1}')
    line = refused(runner.invoke(app, ["render", str(path), "-o", str(tmp_path / "o.png")]), r"'rend\x07er'")
    assert "\x07" not in line and "\x1b" not in line


@settings(max_examples=60, deadline=None)
@given(key=st.text(min_size=1, max_size=30), value=st.text(max_size=3000))
def test_any_key_or_value_gives_one_bounded_printable_line(tmp_path_factory, key, value):
    """The fuzz test's rule for error lines, over keys and values of any characters."""
    folder = tmp_path_factory.mktemp("keys")
    path = folder / "scene.json"
    path.write_text(json.dumps({key: value, "render": {"width": value}}))
    result = runner.invoke(app, ["render", str(path), "-o", str(folder / "o.png")])
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1 and lines[0].isprintable() and len(lines[0]) < LINE, \
        result.output[:500]


def run_with(variables: dict[str, str], *args: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "RAYCAST_PHONG_DEBUG"} | variables
    return subprocess.run([*CLI, *args], capture_output=True, text=True, timeout=300, env=env,
                          stdin=subprocess.DEVNULL)


@pytest.mark.parametrize("variables, needle", [({"NUMBA_NUM_THREADS": "0"}, "NUMBA_NUM_THREADS"),
                                               ({"NUMBA_NUM_THREADS": "lots"}, "NUMBA_NUM_THREADS"),
                                               ({"NUMBA_DISABLE_JIT": "1"}, "NUMBA_DISABLE_JIT")])
def test_numba_settings_the_renderer_cannot_run_under_are_refused(tmp_path, variables, needle):
    """Before: NUMBA_NUM_THREADS=0 an internal error from numba's import; NUMBA_DISABLE_JIT=1 an image with a
    sphere missing and exit 0."""
    done = run_with(variables, "render", "-o", str(tmp_path / "o.png"))
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and needle in lines[0], done.stderr
    assert not (tmp_path / "o.png").exists()


def test_a_numba_value_numba_cannot_parse_is_one_warning_line(tmp_path):
    done = run_with({"NUMBA_OPT": "abc"}, "schema")
    assert done.returncode == 0, done.stderr
    assert done.stderr.strip().splitlines() == ["warning: NUMBA_OPT='abc' is not a value numba understands; "
                                                "it is ignored"], done.stderr
