"""`batch`: many scene files into one folder, in parallel, with progress and a one-line summary."""

from __future__ import annotations

import re
import sys
import time
from pathlib import Path
from typing import Annotated

import typer

from .common import (
    MaxMemoryOption,
    OldOutOption,
    SrgbOption,
    app,
    check_verbosity,
    exit_codes,
    fail,
    one_line,
    output_or_old_spelling,
    quiet_option,
    verbose_option,
    warn,
)
from .progress import progress_bar, shows_progress

MAX_LEFT_OUT = 20  # warnings for paths left out, then one line counting the rest (binary on stdin: thousands)
SCHEDULER = re.compile(r"(?:(tcp)://)?(\[[0-9A-Fa-f:.]+\]|[^\s:/\[\]]+):(\d{1,5})")
HOST_CHARACTERS, LABEL_CHARACTERS = 253, 63  # a DNS name's limits (RFC 1035 §2.3.4): longer ones no resolver takes


def _scheduler(address: str | None) -> str | None:
    """--scheduler as Dask takes it, [PROTOCOL://]HOST:PORT; anything else exits 2 with one line here (Dask's
    own parser raises a bare ValueError deep in its connection code: an internal error)."""
    if address is None:
        return None
    found = SCHEDULER.fullmatch(address)
    if (found is None or not 0 < int(found[3]) < 65536 or len(found[2]) > HOST_CHARACTERS
            or any(len(label) > LABEL_CHARACTERS for label in found[2].split("."))):
        fail(f"--scheduler {address[:80]!r}: not a Dask scheduler's address; allowed: tcp://HOST:PORT with a host "
             f"name of at most {HOST_CHARACTERS} characters and a port from 1 to 65535, e.g. tcp://127.0.0.1:8786 "
             "(tls:// and other protocols need settings this command does not take)")
    return address


@app.command(epilog="""
**Examples**

  raycast-phong batch scenes/ -o renders                 # every scene in the folder, on all cores

  raycast-phong batch "scenes/*.toml" sweeps/shading.toml -o renders --jobs 2

  raycast-phong batch scenes/ -o renders --force         # render even the up-to-date ones

  find . -name "*.toml" | raycast-phong batch - -o renders      # the paths on stdin, one a line

  raycast-phong batch scenes/ -o renders --scheduler tcp://10.0.0.5:8786   # on a Dask cluster
""")
def batch(
    paths: Annotated[list[str], typer.Argument(metavar="PATHS", show_default=False, help="Scene files, folders "
                     "(their .toml and .json files), globs (quoted) and sweep files (see docs/batch.md); - reads "
                     "scene paths from stdin, one a line (as xargs).")],
    output: Annotated[Path | None, typer.Option("--output", "-o", help="Output folder (required): one image per "
                      "scene, named after it, and manifest.json.", show_default=False)] = None,
    out: OldOutOption = None,
    jobs: Annotated[int | None, typer.Option("--jobs", "-j", min=1, max=256, help="Cores to use (default: all): "
                    "N scenes render at once, each in a worker process on one thread; fewer scenes than N share "
                    "the N cores as threads. With 1, scenes render one after another in this process.")] = None,
    force: Annotated[bool, typer.Option("--force", help="Render every scene, even those whose outputs are "
                     "up to date.")] = False,
    scheduler: Annotated[str | None, typer.Option(metavar="tcp://HOST:PORT", callback=_scheduler, help="Run the "
                         "renders on this Dask scheduler (pip install 'raycast-phong[distributed]'); paths are sent "
                         "absolute, so the meshes and textures the scenes name and the output folder must be at "
                         "the same absolute paths on its workers (a shared file system).")] = None,
    srgb: SrgbOption = False,
    quiet: Annotated[bool, quiet_option("progress, notes or summary line (failures and warnings are still "
                     "reported)")] = False,
    verbose: Annotated[bool, verbose_option("a line per scene as it finishes, on a terminal too, with its frame "
                       "time and Mrays/s")] = False,
    max_memory: MaxMemoryOption = None,
) -> None:
    """Render many scene files into one folder, in parallel; skip those whose outputs are up to date.
    A failing scene is reported (file and reason) and the others go on; exit status 1 if any failed.
    A scene's render warnings and notes are printed as it finishes (once; an up-to-date scene's stay in its
    manifest entry). Ctrl-C or `kill` stops the workers at once; exit status 130 (SIGINT) or 143 (SIGTERM)."""
    import signal

    from raycast_phong import stops
    from raycast_phong.tools import batch as batches
    check_verbosity(quiet, verbose)
    out = output_or_old_spelling("batch", output, out)
    # Ctrl-C, `kill` (SIGTERM), a closed terminal (SIGHUP) and SIGQUIT stop the batch: workers killed,
    # temporaries removed, the manifest written. One received while the program started (stops.listen, from
    # cli/__init__.py) is acted on at the batch's first safe point.
    previous = {number: signal.signal(number, batches.interrupt) for number in batches.STOP_SIGNALS}
    try:
        with exit_codes():
            refused: list[str] = []
            listed = batches.listed_paths(getattr(sys.stdin, "buffer", None), warnings=refused) if "-" in paths else []
            try:
                found = batches.find_jobs(paths, out, listed, refused)
            finally:  # before a refusal too: it says why nothing was left
                for warning in refused[:MAX_LEFT_OUT]:
                    warn(warning)
                if len(refused) > MAX_LEFT_OUT:
                    warn(f"and {len(refused) - MAX_LEFT_OUT:,} more path(s) left out")
            report = _batch_with_progress(found, out, jobs, force, batches.Settings(srgb=srgb), scheduler, quiet,
                                          verbose, max_memory)
    except batches.Interrupted as stop:
        _report_interrupt(stop, out)
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
        stops.clear()
    for warning in report.warnings:
        typer.secho(f"warning: {warning}", err=True, fg=typer.colors.YELLOW)
    for outcome in report.failed:
        typer.secho(f"failed: {one_line(outcome.reason)}", err=True, fg=typer.colors.RED)
    if not quiet:
        sheets = "".join(f"; contact sheet {out / name}" for name in report.sheets.values())
        warned = sum(bool(outcome.warnings) for outcome in report.outcomes if outcome.status == batches.RENDERED)
        warned = f"; {warned} rendered with warnings (above)" if warned else ""
        typer.echo(f"{len(report.outcomes)} scenes: {report.count(batches.RENDERED)} rendered, "
                   f"{report.count(batches.UP_TO_DATE)} up to date, {len(report.failed)} failed in "
                   f"{report.seconds:.2f}s ({report.startup:.2f}s of it loading the renderer){warned}; "
                   f"manifest {out / batches.MANIFEST}{sheets}")
    if report.failed:
        raise typer.Exit(code=1)


def _report_interrupt(stop, out: Path) -> None:
    """One line for a batch a signal stopped, and its exit status, 128 + the signal's number."""
    import signal

    from raycast_phong.tools import batch as batches
    line = f"interrupted by {signal.Signals(stop.signal).name}"
    if stop.report is not None:
        for warning in stop.report.warnings:
            typer.secho(f"warning: {warning}", err=True, fg=typer.colors.YELLOW)
        counts = ", ".join(f"{stop.report.count(status)} {status}" for status in
                           (batches.RENDERED, batches.UP_TO_DATE, batches.FAILED, batches.INTERRUPTED,
                            batches.NOT_STARTED))
        line += f": {counts}; manifest {out / batches.MANIFEST}"
    typer.secho(line, err=True, fg=typer.colors.RED)
    raise typer.Exit(code=128 + stop.signal)


def _batch_with_progress(found, out: Path, jobs: int | None, force: bool, settings, scheduler: str | None,
                         quiet: bool, verbose: bool, max_memory: int | None = None):
    """run_batch with, as each scene finishes, its render warnings (always) and notes (not under -q), and a
    progress bar over the scenes on a terminal or one line per scene elsewhere (and on a terminal too with
    --verbose); under -q neither."""
    from raycast_phong.tools.batch import RENDERED, run_batch
    options = {"workers": jobs, "force": force, "settings": settings, "scheduler": scheduler, "max_memory": max_memory}
    started = time.perf_counter()
    with progress_bar(quiet) as bar:
        lines = not quiet and (verbose or not shows_progress(quiet))

        def finished(outcome, done: int, total: int) -> None:
            if lines:
                timing = ""
                if verbose and outcome.status == RENDERED and "frame" in outcome.seconds:
                    timing = f" (frame {outcome.seconds['frame']:.3f}s, {outcome.rays_per_second / 1e6:.1f} Mrays/s)"
                # one_line: a name with a newline stays on its line
                bar.echo(f"[{done}/{total} {time.perf_counter() - started:.2f}s] {outcome.status}: "
                         f"{one_line(outcome.name)}{timing}")
            if outcome.status == RENDERED:  # said once, when it renders; an up-to-date scene's are in the manifest
                for kind, message in [*(("warning", w) for w in outcome.warnings),
                                      *(("note", n) for n in ([] if quiet else outcome.notes))]:
                    if (outcome.scene, message) in said:  # another cell of one sweep: the same line again
                        said[(outcome.scene, message)] += 1
                        continue
                    said[(outcome.scene, message)] = 0
                    bar.echo(f"{kind}: {one_line(outcome.line(message))}",
                             **({"fg": typer.colors.YELLOW} if kind == "warning" else {}))
            bar.update(done, total, f"{outcome.status}: {one_line(outcome.name)}")

        said: dict[tuple[str, str], int] = {}  # (scene, warning or note) → times it came again
        bar.update(0, len(found), "scenes")
        report = run_batch(found, out, progress=finished, **options)
        again = sum(1 for count in said.values() if count)
        if again and not quiet:
            bar.echo(f"note: {again} of the lines above came again in other sweep cells of the same scene: each said "
                     "once (every scene's own are in the manifest)")
        return report
