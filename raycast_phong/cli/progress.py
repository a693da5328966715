"""The progress bar every command that can run for seconds shows (render, side-by-side, plan, reference, study,
stability, batch): one line on stderr, redrawn with a carriage return and erased when the work is done.

It is drawn only on a terminal (stderr a tty) and never under -q, and it writes no escape sequence at all, so a
NO_COLOR or TERM=dumb terminal shows it as any other (the carriage return is plain ASCII). Lines printed while
the bar is up (Bar.echo, or say() for a warning, a note or the compiling notice) go above it: the bar is
erased, the line written, the bar drawn again.
"""

from __future__ import annotations

import shutil
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import typer

REDRAW_SECONDS = 0.1  # at most ten redraws a second: a render's tiles finish faster than a terminal wants lines
BAR_CELLS = 24        # the bar's width in characters, shrunk on a narrow terminal


class Bar:
    """One progress line on `stream` when `shown`; echo() prints a line either way (above the bar if it is up)."""

    def __init__(self, stream, shown: bool):
        self._stream, self._shown = stream, shown
        self._lock = threading.Lock()  # a progress callback may come from a worker thread
        self._started = time.perf_counter()
        self._drawn = ""       # what the line shows now ("" when erased)
        self._last = 0.0       # when it was last drawn
        self._state: tuple[int, int | None, str] = (0, None, "")

    def update(self, done: int, total: int | None, description: str) -> None:
        """Show `done` of `total` (None: not known yet, no bar, only the description)."""
        if not self._shown:
            return
        with self._lock:
            changed = description != self._state[2] or done == total
            self._state = (done, total, description)
            now = time.perf_counter()
            if changed or now - self._last >= REDRAW_SECONDS:
                self._draw(self._line(done, total, description))
                self._last = now

    def echo(self, line: str, fg: str | None = None) -> None:
        """Print `line` on stderr as typer.secho does (in colour `fg` where colour is allowed); the bar, if
        shown, stays below it."""
        with self._lock:
            drawn = self._drawn
            self._erase()
            _write(line, fg)
            if drawn:
                self._draw(self._line(*self._state))
            self._stream.flush()

    def close(self) -> None:
        """Erase the bar (the command's own output follows on a clean line)."""
        with self._lock:
            self._erase()
            self._stream.flush()

    def _line(self, done: int, total: int | None, description: str) -> str:
        columns = shutil.get_terminal_size((80, 24)).columns - 1  # the last column would wrap on some terminals
        if total is None or total <= 0:
            return description[:columns]
        share = min(max(done / total, 0.0), 1.0)
        cells = max(4, min(BAR_CELLS, columns // 4))
        filled = round(share * cells)
        elapsed = time.perf_counter() - self._started
        left = f", {_clock(elapsed * (1 - share) / share)} left" if 0 < share < 1 and elapsed > 1 else ""
        line = f"{description} [{'#' * filled}{'.' * (cells - filled)}] {done}/{total}{left}"
        return line[:columns]

    def _draw(self, line: str) -> None:
        # Pad with spaces over a longer previous line: no escape sequence to clear to the line's end.
        self._stream.write("\r" + line.ljust(len(self._drawn)))
        self._stream.flush()
        self._drawn = line

    def _erase(self) -> None:
        if self._drawn:
            self._stream.write("\r" + " " * len(self._drawn) + "\r")
            self._drawn = ""


def _clock(seconds: float) -> str:
    """'0:07', '12:30', '1:02:03'."""
    minutes, second = divmod(int(seconds + 0.5), 60)
    hours, minute = divmod(minutes, 60)
    return f"{hours}:{minute:02}:{second:02}" if hours else f"{minute}:{second:02}"


def shows_progress(quiet: bool) -> bool:
    """Whether a bar is drawn: stderr is a terminal and the command is not under -q."""
    try:
        return not quiet and sys.stderr.isatty()
    except (AttributeError, ValueError):  # a replaced or closed stderr
        return False


_SHOWN: list[Bar] = []  # the bar on the terminal now, if any: other lines on stderr go above it (say)


@contextmanager
def progress_bar(quiet: bool) -> Iterator[Bar]:
    """A Bar on stderr for the block (drawn only when shows_progress), erased when the block ends."""
    bar = Bar(sys.stderr, shows_progress(quiet))
    _SHOWN.append(bar)
    try:
        yield bar
    finally:
        _SHOWN.remove(bar)
        bar.close()


def say(line: str, fg: str | None = None) -> None:
    """A line on stderr (a warning, a note, the compiling notice), above the progress bar if one is up."""
    if _SHOWN:
        _SHOWN[-1].echo(line, fg)
    else:
        _write(line, fg)


def _write(line: str, fg: str | None) -> None:
    # secho only with a colour: without one it would still end the line with a reset sequence
    if fg is None:
        typer.echo(line, err=True)
    else:
        typer.secho(line, err=True, fg=fg)
