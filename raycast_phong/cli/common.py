"""The `raycast-phong` app and what every command shares: one-line errors and exit codes, the scene argument and
the options several commands take (-q/--quiet and --verbose on all of them, -o/--output with --out as a hidden
old spelling), warning and note lines, --version, shell completion, and output with no escape sequence under
NO_COLOR or TERM=dumb. Each command group is a module of this package; cli/__init__.py assembles them.

Exit status: 0 ok, 2 bad input (scene, mesh, option, output path) or an output that could not be written
(a full disk, a file-size limit: the old file is unchanged), 1 internal error.
"""

from __future__ import annotations

import atexit
import errno
import gc
import io
import json
import os
import re
import sys
import threading
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Annotated

import typer
from typer.core import TyperCommand, TyperGroup

from raycast_phong.codes import View
from raycast_phong.errors import InputError, OutputError

_click_errors = sys.modules[typer.BadParameter.__module__]


def plain_output() -> bool:
    """Whether the program writes no escape sequence at all (no colour, no bold in the help, no cursor moves):
    NO_COLOR set to anything but the empty string (no-color.org) or TERM=dumb."""
    return bool(os.environ.get("NO_COLOR")) or os.environ.get("TERM") == "dumb"


def _colour() -> bool | None:
    """typer.secho's `color` outside a command's context: False (strip the styles) for plain output, else None
    (click's own rule: styles on a terminal only). Inside a command the context says it (OneLineErrors)."""
    return False if plain_output() else None


_RICH_COLOURS: list = []  # typer's help colours as the program found them, restored when NO_COLOR is unset


def _plain_help() -> None:
    """Before a help page: typer draws it with rich, which under NO_COLOR drops colours but keeps bold and dim;
    with no colour system at all it writes none of them (plain_output). Called only when a help page is drawn,
    so no other command loads typer's rich module for it."""
    from typer import rich_utils
    if not _RICH_COLOURS:
        _RICH_COLOURS.append(rich_utils.COLOR_SYSTEM)
    rich_utils.COLOR_SYSTEM = None if plain_output() else _RICH_COLOURS[0]


def _plain_metavars(params: list) -> list:
    """The parameters' value column in --help without typer's type names for Python types: a flag takes no
    value (no `<bool>`), and a repeatable option or a list argument shows its item (`<text>...`, not
    `<list[str]>`). Each parameter's display is replaced once, on the parameter itself."""
    for param in params:
        shown = getattr(param, "display_type_rich", None)
        if shown is None or getattr(shown, "plain", False):
            continue

        def plain(ctx, param=param, shown=shown) -> str | None:
            if getattr(param, "is_flag", False) and not getattr(param, "count", False):
                return None
            text = shown(ctx)
            if text and "list[" in text:
                text = re.sub(r"list\[(.*?)\]", r"\1", text)
                text = (text if text.endswith("...") else text + "...").replace("<str>", "<text>")
            return text
        plain.plain = True
        param.display_type_rich = plain
    return params


class _PlainHelp:
    """A click command's --help with plain metavars (_plain_metavars), drawn without escape sequences under
    NO_COLOR or TERM=dumb (_plain_help)."""

    def get_params(self, ctx):
        return _plain_metavars(super().get_params(ctx))

    def format_help(self, ctx, formatter):
        _plain_help()
        return super().format_help(ctx, formatter)


class PlainHelpCommand(_PlainHelp, TyperCommand):
    """typer's command, its --help plain (_PlainHelp)."""


class App(typer.Typer):
    """typer's app whose commands are PlainHelpCommands (every @app.command of the program, unless it names
    its own class)."""

    def command(self, *args, cls=None, **kwargs):
        return super().command(*args, cls=cls or PlainHelpCommand, **kwargs)


class OneLineErrors(_PlainHelp, TyperGroup):
    """typer's command group, but a usage error (a bad --width, an unknown option or command) is one line on
    stderr with exit 2, like every other error of the program, instead of rich's boxed message. Under NO_COLOR
    or TERM=dumb (plain_output) nothing it or a command prints carries an escape sequence: the context's `color`
    is False, which click's echo and secho obey, and the help is drawn without a colour system (_PlainHelp)."""

    def main(self, *args, standalone_mode: bool = True, **kwargs):
        try:
            if not standalone_mode:
                return self._main(*args, standalone_mode=False, **kwargs)
            before = _stdout_identity()
            try:
                code = self._main(*args, standalone_mode=True, **kwargs)
            except SystemExit as done:
                code = done.code
                # typer (a PacifyFlushWrapper) and rich (stdout pointed at /dev/null) meet EPIPE with a silent
                # exit 1: say it as every other failed write
                if type(sys.stdout).__name__ == "PacifyFlushWrapper" or _stdout_identity() != before:
                    raise BrokenPipeError(errno.EPIPE, "Broken pipe") from None
            _flush_or_fail(sys.stdout, "stdout")  # a full disk or a closed pipe shows at the flush too
            sys.exit(code)
        except OSError as error:  # a print to stdout or stderr failed: what --help and errors write to
            _output_failed(error)

    def _main(self, *args, standalone_mode: bool = True, **kwargs):
        from raycast_phong.io.system import check_environment
        kwargs.setdefault("color", _colour())
        try:
            for warning in check_environment():
                typer.secho(f"warning: {one_line(warning)}", err=True, fg=typer.colors.YELLOW, color=_colour())
        except InputError as error:
            typer.secho(f"error: {one_line(str(error))}", err=True, fg=typer.colors.RED, color=_colour())
            sys.exit(2)
        if not standalone_mode:
            return super().main(*args, standalone_mode=False, **kwargs)
        from raycast_phong import compiles
        try:
            with compiles.told(_say_compiling):  # any command's compile not announced by its own warm-up
                code = super().main(*args, standalone_mode=False, **kwargs)
        except getattr(_click_errors, "NoArgsIsHelpError", ()):
            return super().main(*args, **kwargs)  # no arguments at all: typer shows the help, as it did
        except _click_errors.ClickException as error:
            command = error.ctx.command_path if getattr(error, "ctx", None) else None
            where = f"{command}: " if command else ""
            hint = f" (see {command} --help)" if command else ""
            typer.secho(f"error: {one_line(where + _worded(error.format_message()) + hint)}", err=True,
                        fg=typer.colors.RED, color=_colour())
            sys.exit(error.exit_code)
        except typer.Abort:
            typer.secho("error: aborted", err=True, fg=typer.colors.RED, color=_colour())
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)  # a command's typer.Exit(code), else success


def _worded(message: str) -> str:
    """A usage error in the program's words: without the "Value error, " typer's coercion puts before a choice's
    message, and with the closest choice offered ("'phongg' is not one of 'flat', 'gouraud', 'phong' (did you
    mean 'phong'?)")."""
    message = message.replace("Value error, ", "")
    found = re.search(r"'([^']*)' is not one of ((?:'[^']*'(?:, )?)+)", message)
    if found:
        from raycast_phong.values.messages import did_you_mean
        end = found.end()
        message = message[:end] + did_you_mean(found[1], re.findall(r"'([^']*)'", found[2])) + message[end:]
    return message


def _say_compiling(name: str, signature: str) -> None:
    """Told before a kernel compiles (compiles.told, `name` module.function): one line naming the part of the
    program whose kernels compile, so no compile is silent. CPU of a fresh compile (docs/performance.md): the mesh
    readers' 2-4 s, the mesh preparation's about 6 s, the renderer's about 20 s (its frame kernels on 2 cores)."""
    from raycast_phong.compiles import part

    from .progress import say
    what = part(name)
    what, seconds = (what, "a few seconds") if what else ("the renderer's kernels", "10-20 s")
    say(f"compiling {what}, once after an install or an edit ({seconds})...")


class _ClosedStdout(io.TextIOBase):
    """stdout of a program started with it closed (`>&-`, where Python sets sys.stdout to None): a command that
    prints fails as any write to a closed descriptor does (one line, exit 2); one that prints nothing succeeds."""

    def writable(self) -> bool:
        return True

    def write(self, text: str) -> int:
        error = OSError(errno.EBADF, "standard output is closed")
        error.stream = "stdout"  # a failed output, for OneLineErrors' one line, not a bug of the command
        raise error


def _stdout_identity() -> tuple[int, int] | None:
    try:
        info = os.fstat(sys.stdout.fileno())
        return info.st_dev, info.st_ino
    except (OSError, ValueError, AttributeError):  # a test runner's stdout has no descriptor
        return None


def _flush_or_fail(stream, name: str) -> None:
    try:
        stream.flush()
    except OSError as error:
        error.stream = name
        raise


def _output_failed(error: OSError) -> None:
    """stdout or stderr could not be written (`> /dev/full`, a reader that closed the pipe): one line on
    stderr if it still takes one, exit 2 (a failed write, like any other output), no traceback; stdout is
    pointed at /dev/null so Python's own flush at exit does not fail again."""
    with suppress(OSError, ValueError):
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    reason = "the reader closed the pipe" if error.errno == errno.EPIPE else (error.strerror or str(error))
    with suppress(OSError, ValueError):
        sys.stderr.write(f"error: {getattr(error, 'stream', 'stdout')}: write failed: {reason}\n")
        sys.stderr.flush()
    os._exit(2)  # nothing left to flush that could be written


def main() -> None:
    """The `raycast-phong` program (the console script, `python -m raycast_phong.cli`, cli.py): app(), then the
    process ends without the interpreter's teardown.

    Tearing the interpreter down after a command frees one by one the objects numba, pydantic and OpenImageIO
    made, with full passes of the cyclic collector over them: 0.2–0.3 s of a 1 s warm `render`, in a process
    that is about to end. So once the command has returned and no other thread of ours runs, what Python's exit
    does that can matter is done here — the atexit handlers (numba's, multiprocessing's, temporary folders'),
    then stdout and stderr flushed (a failure is one line, exit 2, as in OneLineErrors) — and the process ends
    with os._exit and the command's status. With another thread still running (Python waits for it) or without
    CPython's atexit runner, the exit is Python's own. `app()` itself (the tests, embedding) exits as before.

    pydantic's plugins (observability hooks, found by scanning every installed package's entry points: 10-15 ms)
    are left off for the program's own scene models unless PYDANTIC_DISABLE_PLUGINS says otherwise. The cyclic
    collector's young pass runs every 10,000 allocations instead of 700: its passes over what the imports make
    (modules, numba's types, pydantic's schemas; none of it garbage) cost 30-40 ms of a warm render, and a
    command's own cyclic garbage is still found young."""
    os.environ.setdefault("PYDANTIC_DISABLE_PLUGINS", "__all__")
    gc.set_threshold(10_000, 10, 10)
    if sys.stdout is None:  # started with stdout closed (`>&-`): what a command prints fails as a write to it
        sys.stdout = _ClosedStdout()
    try:
        app()
        code = 0
    except SystemExit as done:
        code = done.code
    others = [thread for thread in threading.enumerate()
              if thread is not threading.main_thread() and not thread.daemon and thread.is_alive()]
    run_exit_handlers = getattr(atexit, "_run_exitfuncs", None)
    if others or run_exit_handlers is None:
        sys.exit(code)
    run_exit_handlers()
    if code is None:
        code = 0
    elif not isinstance(code, int):  # sys.exit("text"): the text on stderr, status 1, as Python does
        print(code, file=sys.stderr)
        code = 1
    try:
        _flush_or_fail(sys.stdout, "stdout")
        _flush_or_fail(sys.stderr, "stderr")
    except OSError as error:
        _output_failed(error)
    os._exit(code & 0xFF)


app = App(
    cls=OneLineErrors,
    help="Ray-cast flat, Gouraud and Phong shading with Intel Embree. Every command takes -q/--quiet (only "
         "warnings, errors and the data it exists to print) and --verbose; NO_COLOR or TERM=dumb leave out "
         "every colour and escape sequence.",
    no_args_is_help=True,
    add_completion=True,  # --install-completion / --show-completion for bash, zsh, fish and PowerShell
    pretty_exceptions_enable=False,
    rich_markup_mode="markdown",
)


def _show_version(asked: bool) -> None:
    if asked:
        from raycast_phong import __version__
        typer.echo(f"raycast-phong {__version__}")
        raise typer.Exit()


@app.callback()
def _program(version: Annotated[bool, typer.Option("--version", is_eager=True, callback=_show_version,
                                                   help="Print the version and exit.")] = False) -> None:
    """The program's own options, before the command."""


def quiet_option(hides: str) -> object:
    """-q/--quiet for one command, its help saying what it hides besides the progress bar (never a warning or
    an error)."""
    return typer.Option("--quiet", "-q", help=f"Print only warnings, errors and the command's data: no {hides}.")


def verbose_option(adds: str) -> object:
    """--verbose for one command, its help saying what it adds."""
    return typer.Option("--verbose", help=f"Also print {adds}.")


def check_verbosity(quiet: bool, verbose: bool) -> None:
    """-q and --verbose ask for opposite things: exit 2 with one line if both are given."""
    if quiet and verbose:
        fail("-q/--quiet and --verbose: give one of them, not both")


def output_or_old_spelling(command: str, output: Path | None, old: Path | None, default: Path | None = None) -> Path:
    """-o/--output, or its old spelling --out (kept, hidden from --help, so that scripts still run); exit 2
    with one line if both or (without a default) neither is given."""
    if output is not None and old is not None:
        fail(f"{command}: -o/--output and --out (its old spelling) both given; give -o/--output only")
    chosen = output if output is not None else old if old is not None else default
    if chosen is None:
        fail(f"{command}: missing option -o/--output, the output folder (see {command} --help)")
    return chosen


OldOutOption = Annotated[Path | None, typer.Option("--out", hidden=True, show_default=False,
                                                   help="The old spelling of -o/--output.")]


def warn(message: str) -> None:
    """One `warning:` line on stderr (in yellow where colour is allowed, above a progress bar); the commands
    print it under -q too."""
    from .progress import say
    say(f"warning: {one_line(message)}", typer.colors.YELLOW)


def note(message: str) -> None:
    """One `note:` line on stderr (above a progress bar): information, which the commands leave out under -q."""
    from .progress import say
    say(f"note: {one_line(message)}")


SceneArgument = Annotated[Path | None, typer.Argument(
    help="Scene file (.toml or .json, see docs/scene-format.md) or a mesh file (.obj, .ply, .stl, .off, .glb, "
         ".gltf, anything trimesh reads: framed, lit and with its own materials, see docs/meshes.md). Omit it for "
         "the built-in default scene; `-` reads a scene from standard input (TOML, or JSON starting with {), "
         "e.g. `cat scene.toml | raycast-phong render - -o out.png`.",
    show_default=False, dir_okay=False)]


ViewOption = Annotated[View | None, typer.Option(
    "--view", show_default=False, help="A mesh file's camera: three-quarter (the default: 30° round from the "
    "front, 20° up), front, side, top or iso; it frames the model's bounding sphere.")]


UpOption = Annotated[str | None, typer.Option(
    "--up", metavar="AXIS", show_default=False, help="A mesh file's up axis: x, y, z, -x, -y or -z. Default: the "
    "one its format states (glTF: y), else y.")]


def _view(view: View | None) -> str | None:
    return view.value if view is not None else None


SrgbOption = Annotated[bool, typer.Option(
    "--srgb", help="Shorthand for `--set render.colour=linear` (a render.colour given by --set or a sweep wins): "
    "decode 8-bit colour maps from sRGB, light in linear values and encode PNGs with the sRGB curve, as glTF "
    "specifies (a glTF file rendered directly already is). Scene files default to `display`: maps and colours "
    "as stored, the PNG as it is.")]

def _assignments(values: list[str] | None) -> list[str] | None:
    """--set's values checked for their `=` while the command line is parsed, before the scene is read: written
    `--set render.width 320`, the 320 was taken for the scene file ("320: no such scene file")."""
    for value in values or ():
        if "=" not in value:
            from raycast_phong.scene.overrides import NO_EQUALS
            raise typer.BadParameter(f"{value!r} has no '='; {NO_EQUALS}")
    return values


SetOption = Annotated[list[str], typer.Option(
    "--set", metavar="KEY.PATH=VALUE", callback=_assignments,
    help="Override a scene key, e.g. `render.width=320`, `lights.0.position=[1,2,3]`, "
         "`materials.red.shininess=8`. Repeatable.")]


def _max_memory(text: str | None) -> int | None:
    """--max-memory SIZE in bytes; a malformed size exits 2 with one line."""
    if text is None:
        return None
    from raycast_phong.io.system import parse_size  # a light module: no numba, no trimesh
    try:
        budget = parse_size(text)
    except ValueError as error:
        fail(f"--max-memory: {error}")
    return budget


MaxMemoryOption = Annotated[str | None, typer.Option(
    "--max-memory", metavar="SIZE", callback=_max_memory, show_default=False,
    help="Memory budget for rendering, e.g. 8G or 500M (K, M, G, T: powers of 1024). A scene whose estimated "
         "geometry and image need more is refused before anything is built. Default: 3/4 of the memory "
         "available now.")]


MESSAGE_CHARACTERS = 2000  # an error line is one line of bounded length, whatever a value held


def one_line(message: str, limit: int = MESSAGE_CHARACTERS) -> str:
    """`message` as one printable line: control characters (a newline, a bell, an escape) shown escaped, and
    cut to `limit` characters with how many were left out. Every error line passes here."""
    if not message.isprintable():
        message = "".join(c if c.isprintable() else repr(c)[1:-1] for c in message)
    return message if len(message) <= limit else f"{message[:limit]}… ({len(message) - limit:,} more characters)"


def fail(message: str, code: int = 2) -> None:
    typer.secho(f"error: {one_line(message)}", err=True, fg=typer.colors.RED)
    raise typer.Exit(code=code)


def scene_overrides(options: dict[str, object]) -> list[str]:
    """CLI options that stand for scene keys, as `key=value` overrides (None = not given; an enum by its value)."""
    return [f"{key}={json.dumps(getattr(value, 'value', value))}" for key, value in options.items()
            if value is not None]


@contextmanager
def exit_codes():
    """Bad input (errors.InputError) and an output that cannot be made (errors.OutputError) exit 2 and anything
    else 1, each with one line on stderr."""
    try:
        yield
    except (InputError, OutputError) as error:
        fail(_built_in_named(str(error)))
    except typer.Exit:
        raise
    except OSError as error:
        if getattr(error, "stream", None):  # stdout or stderr could not be written: OneLineErrors says so, exit 2
            raise
        _internal(error)
    except Exception as error:  # noqa: BLE001 - anything else is our bug: one line, exit 1, the traceback logged
        _internal(error)


def _built_in_named(message: str) -> str:
    """`message` with the built-in scene's path (deep in site-packages from a wheel) said as a user names it,
    "the built-in scene (default.toml)": what render, plan, view and the others read with no scene argument."""
    from ..scene.schema import default_scene_path
    path = str(default_scene_path())
    return message.replace(path, f"the built-in scene ({Path(path).name})")


def _internal(error: Exception) -> None:
    """An error that is our bug: one line, exit 1, the traceback in a log file (raised as is under debug)."""
    if os.environ.get("RAYCAST_PHONG_DEBUG", "") not in ("", "0"):
        raise error
    log = _traceback_log(error)
    fail(f"internal error: {type(error).__name__}: {error}" + (f" (traceback in {log})" if log else ""), code=1)


ERROR_LOGS_VARIABLE = "RAYCAST_PHONG_ERROR_LOGS"


def _traceback_log(error: BaseException) -> str | None:
    """Write the traceback of an internal error to a fresh raycast-phong-error-*.log in the temporary folder
    (or in $RAYCAST_PHONG_ERROR_LOGS: the test suite keeps its own there) and return its path (None if even
    that cannot be written: the one line must still come out)."""
    import tempfile
    import traceback
    try:
        descriptor, path = tempfile.mkstemp(prefix="raycast-phong-error-", suffix=".log",
                                            dir=os.environ.get(ERROR_LOGS_VARIABLE) or None)
        # backslashreplace: a traceback that quotes a file name which is not UTF-8 must still be written
        with os.fdopen(descriptor, "w", encoding="utf-8", errors="backslashreplace") as log:
            log.write("".join(traceback.format_exception(error)))
        return path
    except OSError:
        return None
