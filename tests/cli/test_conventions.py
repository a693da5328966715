"""The conventions a well-kept command line keeps (issue 34, item 7): --version, shell completion, NO_COLOR and
TERM=dumb (no escape sequence anywhere, help and errors included), no Python type names as metavars, -q and
--verbose on every command, one spelling of the output option, and a progress bar on the commands that can run
for seconds, on a terminal only and never under -q.
"""

from __future__ import annotations

import io
import os
import select
import subprocess
import sys
from pathlib import Path

import pytest
import typer.main
from typer.testing import CliRunner

import raycast_phong
from raycast_phong.cli import app

runner = CliRunner()
COMMANDS = [command.name or command.callback.__name__ for command in app.registered_commands]
ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.usefixtures("in_tmp_path")


def click_command(name: str):
    return typer.main.get_command(app).commands[name]


def option_names(name: str) -> set[str]:
    """Every visible option name of a command."""
    return {opt for param in click_command(name).params if param.param_type_name == "option" and not param.hidden
            for opt in (*param.opts, *param.secondary_opts)}


def test_version_prints_the_package_version():
    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0, result.output
    assert result.stdout == f"raycast-phong {raycast_phong.__version__}\n"


def test_shell_completion_is_on_and_completes_commands_options_and_choices(monkeypatch):
    helped = runner.invoke(app, ["--help"])
    assert "--install-completion" in helped.stdout and "--show-completion" in helped.stdout
    # --show-completion names the shell it detects from the process tree (shellingham): a pytest-xdist worker's
    # ancestors may hold none typer knows (exit 1 in the full suite, under load), so the test says it is bash.
    import shellingham
    monkeypatch.setattr(shellingham, "detect_shell", lambda *args, **kwargs: ("bash", "/bin/bash"))
    script = runner.invoke(app, ["--show-completion"], prog_name="raycast-phong")
    assert script.exit_code == 0 and "complete -o default -F _raycast_phong_completion raycast-phong" in script.stdout

    def complete(words: str) -> list[str]:
        done = runner.invoke(app, [], prog_name="raycast-phong", env={
            "_RAYCAST_PHONG_COMPLETE": "complete_bash", "COMP_WORDS": words, "COMP_CWORD": str(len(words.split()) - 1)})
        assert done.exit_code == 0, done.output
        return done.stdout.split()

    assert complete("raycast-phong re") == ["render", "reference"]
    assert complete("raycast-phong render --shad") == ["--shading"]
    assert complete("raycast-phong render --shading g") == ["gouraud"]


@pytest.mark.parametrize("name", ["", *COMMANDS])
def test_help_shows_no_python_type_names_as_metavars(name):
    """A flag takes no value (no `<bool>`); a repeatable option or list argument shows its item (no `list[`)."""
    result = runner.invoke(app, [name, "--help"] if name else ["--help"], terminal_width=200)
    assert result.exit_code == 0, result.output
    assert "Usage:" in result.stdout  # the control: this is the help page
    for bad in ("<bool>", "list[", "{PATHS...}"):
        assert bad not in result.stdout, f"`{name} --help` shows {bad}:\n{result.stdout}"


def test_every_command_takes_quiet_and_verbose_and_refuses_both():
    for name in COMMANDS:
        assert {"-q", "--quiet", "--verbose"} <= option_names(name), name
    for args in (["render", "-q", "--verbose"], ["schema", "--verbose", "--quiet"], ["batch", "x", "-q",
                                                                                     "--verbose", "-o", "o"]):
        result = runner.invoke(app, args)
        assert result.exit_code == 2, result.output
        assert result.output == "error: -q/--quiet and --verbose: give one of them, not both\n"


def test_the_output_option_is_spelled_one_way():
    """Every command that writes a file or a folder names it -o/--output; the old --out is hidden and still
    works, and giving both is refused."""
    writers = [name for name in COMMANDS if option_names(name) & {"-o", "--output", "--out"}]
    assert set(writers) >= {"render", "side-by-side", "reference", "study", "batch", "scene"}, writers
    for name in writers:
        assert {"-o", "--output"} <= option_names(name) and "--out" not in option_names(name), name
        assert "--out " not in runner.invoke(app, [name, "--help"], terminal_width=200).stdout, name


def test_batch_takes_the_old_out_spelling_and_refuses_two(tmp_path):
    scene = tmp_path / "a.toml"
    scene.write_text('[render]\nwidth = 8\nheight = 8\n[[objects]]\nshape = "box"\n', encoding="utf-8")
    old = runner.invoke(app, ["batch", str(scene), "--out", str(tmp_path / "old"), "--jobs", "1", "-q"])
    assert old.exit_code == 0 and (tmp_path / "old" / "a.png").is_file(), old.output
    both = runner.invoke(app, ["batch", str(scene), "--out", "x", "-o", "y"])
    assert both.exit_code == 2 and both.output == ("error: batch: -o/--output and --out (its old spelling) both "
                                                   "given; give -o/--output only\n")
    neither = runner.invoke(app, ["batch", str(scene)])
    assert neither.exit_code == 2 and neither.output.startswith("error: batch: missing option -o/--output")


def test_render_verbose_prints_the_plan_and_quiet_only_the_image(tmp_path):
    verbose = runner.invoke(app, ["render", "-o", str(tmp_path / "v.png"), "--width", "96", "--height", "36",
                                  "--verbose"])
    assert verbose.exit_code == 0, verbose.output
    assert "kept      vertex_normals" in verbose.stdout and verbose.stdout.rstrip().endswith("summed over threads)")
    quiet = runner.invoke(app, ["render", "-o", str(tmp_path / "q.png"), "--width", "192", "--height", "72", "-q"])
    assert quiet.exit_code == 0 and quiet.output == "" and (tmp_path / "q.png").is_file()


def test_compare_quiet_prints_a_verdict_only_when_it_is_not_a_pass(tmp_path):
    import numpy as np
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    raycast_phong.write_image(a, np.zeros((4, 4, 3), np.float32))
    raycast_phong.write_image(b, np.full((4, 4, 3), 0.01, np.float32))
    passed = runner.invoke(app, ["compare", str(a), str(a), "-q"])
    assert passed.exit_code == 0 and passed.output == ""
    warned = runner.invoke(app, ["compare", str(a), str(b), "--fail", "0.1", "--warn", "0.001", "-q"])
    assert warned.exit_code == 0 and warned.stdout.startswith("WARNING: 0 of 16 pixels"), warned.output
    verbose = runner.invoke(app, ["compare", str(a), str(b), "--verbose", "--fail", "0.1"])
    assert f"{a} and {b}: 4×4, 3 channels" in verbose.stdout
    assert verbose.stdout.count("mean error 0.01, max error 0.01") == 3, verbose.stdout


# ---------------------------------------------------------------- NO_COLOR, TERM=dumb, progress on a terminal

# In one process on a terminal: every help page (the program's first: each sets the help's colours), a usage
# error, a warning, a render's progress bar and the stability table.
PROBE = """\
import sys
from raycast_phong.cli import app
runs = [["--help"]] + [[name, "--help"] for name in sys.argv[1:]] + [["render", "--width", "5x"],
        ["plan", "--set", "render.shading=phong"], ["render", "-o", "x.png", "--width", "64", "--height", "240"],
        ["stability", "--case", "watertightness"]]
for args in runs:
    try:
        app(args, prog_name="raycast-phong")
    except SystemExit:
        pass
"""


def in_terminal(args: list[str], env: dict[str, str], cwd: Path) -> bytes:
    """What a program run with stdin, stdout and stderr on a pseudo-terminal writes there."""
    import pty
    controller, terminal = pty.openpty()
    process = subprocess.Popen(args, stdin=terminal, stdout=terminal, stderr=terminal, env=env, cwd=cwd)
    os.close(terminal)
    written = b""
    while True:  # drain as it comes: the terminal's buffer is small
        ready, _, _ = select.select([controller], [], [], 300)
        if not ready:
            process.kill()
            break
        try:
            chunk = os.read(controller, 1 << 16)
        except OSError:  # the program ended and closed its side
            break
        if not chunk:
            break
        written += chunk
    process.wait(60)
    os.close(controller)
    return written


def terminal_env(**extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("NO_COLOR", "FORCE_COLOR", "PY_COLORS", "TERM",
                                                            "RAYCAST_PHONG_DEBUG", "COLUMNS", "TERMINAL_WIDTH")}
    return {**env, "TERM": "xterm-256color", "PYTHONPATH": str(ROOT), **extra}


@pytest.mark.skipif(sys.platform == "win32", reason="needs a pseudo-terminal")
def test_no_color_and_a_dumb_terminal_get_no_escape_sequence_anywhere(tmp_path):
    """Help pages (rich), errors, warnings (click's colours), the stability table and the progress bar: not one
    escape sequence under NO_COLOR or TERM=dumb. The control: the same run on a colour terminal has some."""
    probe = [sys.executable, "-c", PROBE, *COMMANDS]
    coloured = in_terminal(probe, terminal_env(), tmp_path)
    assert b"\x1b[" in coloured  # the control: help, errors and warnings are coloured on a terminal
    for env in (terminal_env(NO_COLOR="1"), terminal_env(TERM="dumb")):
        written = in_terminal(probe, env, tmp_path)
        assert b"\x1b[" not in written, written[max(0, written.find(b"\x1b[") - 300):][:600]
        for shown in (b"Usage: raycast-phong schema", b"error: raycast-phong render: Invalid value for '--width'",
                      b"warning: render.shading = phong changes nothing", b"\rrendering tiles [",
                      b"watertightness", b"1 passed, 0 failed"):
            assert shown in written, (shown, written[-2000:])


@pytest.mark.skipif(sys.platform == "win32", reason="needs a pseudo-terminal")
def test_the_progress_bar_is_shown_on_a_terminal_only_and_never_under_q(tmp_path):
    render = [sys.executable, str(ROOT / "cli.py"), "render", "-o", "x.png", "--width", "64", "--height", "240"]
    assert b"\rrendering tiles [" in in_terminal(render, terminal_env(), tmp_path)
    assert b"rendering tiles" not in in_terminal([*render, "-q"], terminal_env(), tmp_path)
    piped = subprocess.run(render, capture_output=True, env=terminal_env(), cwd=tmp_path, timeout=300)
    assert piped.returncode == 0 and b"\r" not in piped.stderr and b"rendering tiles" not in piped.stderr


@pytest.fixture
def a_terminal(monkeypatch):
    """Draw the bar as on a terminal (CliRunner's stderr is not one); -q still hides it."""
    from raycast_phong.cli import progress
    monkeypatch.setattr(progress, "shows_progress", lambda quiet: not quiet)


@pytest.mark.parametrize(("args", "shown"), [
    (["study", "--width", "16", "--height", "8", "--levels", "0,1", "--repeats", "2", "-o", "s"],
     ["\rstudy: level 0", "\rstudy: timing round 2 of 2 ["]),
    (["stability", "--case", "watertightness", "--case", "grazing_light"], ["\rstability: grazing_light ["]),
    (["side-by-side", "--vary", "render.shading=flat,phong", "--width", "32", "--height", "12", "-o", "c.png"],
     ["\rrender.shading = phong (2/2) ["]),
    (["plan"], ["\rpreparing the geometry"]),
    (["reference", "--set", "render.width=16", "--set", "render.height=8", "-o", "r.exr"],
     ["\rcomputing the reference"]),
    (["batch", str(ROOT / "scenes" / "default.toml"), str(ROOT / "scenes" / "specular.toml"), "-o", "b", "-j", "1"],
     ["\rscenes [", "] 2/2"]),
])
def test_the_commands_that_can_take_seconds_show_progress(a_terminal, args, shown):
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    for text in shown:
        assert text in result.stderr, (text, result.stderr[-1500:])
    quiet = runner.invoke(app, [*args, "-q", *(["--force"] if args[0] == "batch" else [])])
    assert quiet.exit_code == 0 and "\r" not in quiet.stderr, quiet.stderr[-500:]


def test_study_verbose_prints_each_step(a_terminal):
    result = runner.invoke(app, ["study", "--width", "16", "--height", "8", "--levels", "0,1", "--repeats", "2",
                                 "-o", "s", "--verbose"])
    assert result.exit_code == 0, result.output
    # Each printed line is the last of its carriage-return segments: the bar drawn and erased before it.
    printed = [piece.split("\r")[-1] for piece in result.stderr.split("\n")]
    steps = [line.split("] ", 1)[1] for line in printed if line.startswith("[")]
    assert steps == ["level 0", "level 1", "timing", "timing round 1 of 2", "timing round 2 of 2", "done"], steps


def test_the_bar_writes_no_escape_keeps_to_the_terminal_and_puts_lines_above_itself(monkeypatch):
    from raycast_phong.cli import progress
    monkeypatch.setattr("shutil.get_terminal_size", lambda fallback=None: os.terminal_size((40, 10)))
    stream = io.StringIO()
    bar = progress.Bar(stream, shown=True)
    bar.update(0, None, "building the geometry and the BVH of a scene with a long name")  # no total yet
    bar.update(3, 10, "rendering tiles with a description far longer than the terminal is wide")
    monkeypatch.setattr(sys, "stderr", stream)
    bar.echo("a finished scene")
    bar.update(10, 10, "rendering tiles")
    bar.close()
    written = stream.getvalue()
    assert "\x1b" not in written
    assert all(len(part) <= 39 for part in written.replace("\n", "\r").split("\r")), written
    # the line goes above the bar: erase, the line, the bar drawn again
    assert "\r" + " " * 39 + "\ra finished scene\n\rrendering tiles with a description far " in written
    last = "rendering tiles [#########] 10/10"  # 9 cells: a quarter of the 39 usable columns
    assert written.endswith("\r" + last.ljust(39) + "\r" + " " * len(last) + "\r"), written
    hidden = io.StringIO()
    quiet = progress.Bar(hidden, shown=False)
    quiet.update(1, 2, "x")
    quiet.close()
    assert hidden.getvalue() == ""


def test_a_warning_said_while_a_bar_is_up_goes_above_it(monkeypatch):
    """warn() (and note() and the compiling notice) during a bar: the bar is erased, the line written on a line
    of its own, the bar drawn again, not the line glued to the bar's text."""
    from raycast_phong.cli import progress
    from raycast_phong.cli.common import warn
    stream = io.StringIO()
    monkeypatch.setattr(sys, "stderr", stream)
    monkeypatch.setattr(progress, "shows_progress", lambda quiet: True)
    monkeypatch.setattr("shutil.get_terminal_size", lambda fallback=None: os.terminal_size((120, 30)))
    with progress.progress_bar(False) as bar:
        bar.update(1, 4, "rendering tiles")
        warn("something to know")
    drawn = "rendering tiles [######..................] 1/4"
    assert stream.getvalue() == (f"\r{drawn}\r{' ' * len(drawn)}\rwarning: something to know\n\r{drawn}"
                                 f"\r{' ' * len(drawn)}\r")


@pytest.mark.parametrize(("args", "said"), [
    (["render", "--shading", "phongg"], "Invalid value for '--shading': 'phongg' is not one of 'flat', 'gouraud', "
                                        "'phong' (did you mean 'phong'?)"),
    (["render", "--mode", "globl"], "'globl' is not one of 'local', 'global' (did you mean 'global'?)"),
    (["render", "--specular", "xyz"], "'xyz' is not one of 'phong', 'blinn'. (see"),  # nothing close: no guess
])
def test_a_mistyped_choice_is_one_line_in_the_program_s_words_with_the_closest_choice(args, said):
    """typer's coercion said "Value error, 'phongg' is not one of ..." (pydantic's prefix) and offered nothing."""
    done = runner.invoke(app, [*args, "-o", "never.png"])
    assert done.exit_code == 2, done.output
    line = done.output.strip()
    assert "\n" not in line and line.startswith("error: ") and "Value error" not in line, line
    assert said in line, line


@pytest.mark.parametrize("command", ["render", "plan", "scene"])
def test_a_set_without_its_equals_sign_is_said_before_the_scene_is_read(command):
    """`--set render.width 320` took 320 for the scene file ("320: no such scene file"): the assignment's missing
    '=' is said first, whatever follows it."""
    done = runner.invoke(app, [command, "--set", "render.width", "320"])
    assert done.exit_code == 2, done.output
    line = done.output.strip()
    assert "\n" not in line and "'render.width' has no '='; expected KEY.PATH=VALUE" in line, line
    assert "no such scene file" not in line


def test_a_comma_list_of_numbers_skips_empty_items_and_refuses_a_word_naming_the_option():
    """tools.lists.numbers: `--levels 0,,1,` is (0, 1) (blanks and empty items skipped, as `items` does for
    names); a word among the numbers is one OptionError naming the option and the text given."""
    from raycast_phong.errors import OptionError
    from raycast_phong.tools.lists import numbers
    assert numbers("0,,1, ", int, "--levels") == (0, 1)
    assert numbers(None, int, "--levels") is None
    with pytest.raises(OptionError, match=r"^--levels: expected numbers separated by commas, got '0,x'$"):
        numbers("0,x", int, "--levels")


def test_the_bar_rounds_its_filled_cells_and_its_clock_pads_minutes_and_seconds(monkeypatch):
    """cli.progress: on a wide terminal the bar has 24 cells, 2/7 of them filled rounds 6.86 to 7 (not down to 6);
    the time left reads as a clock, '0:07', '12:30', '1:02:03'."""
    import shutil

    from raycast_phong.cli import progress
    monkeypatch.setattr(shutil, "get_terminal_size", lambda fallback=(80, 24): os.terminal_size((200, 24)))
    bar = progress.Bar(io.StringIO(), True)
    assert bar._line(2, 7, "x") == "x [" + "#" * 7 + "." * 17 + "] 2/7"
    assert [progress._clock(s) for s in (7, 750, 3723)] == ["0:07", "12:30", "1:02:03"]
