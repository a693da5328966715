"""`reference`, `study` and `stability`: the exact image, the work-precision study and the numerical-stability
suite (docs/accuracy.md)."""

from __future__ import annotations

import json
import math
import textwrap
import time
from pathlib import Path
from typing import Annotated

import typer

import raycast_phong as rp
from raycast_phong.codes import ShadingModel, SpecularModel

from .common import (
    MaxMemoryOption,
    OldOutOption,
    SceneArgument,
    SetOption,
    UpOption,
    ViewOption,
    _view,
    app,
    check_verbosity,
    exit_codes,
    fail,
    output_or_old_spelling,
    quiet_option,
    scene_overrides,
    verbose_option,
)
from .progress import progress_bar


@app.command("reference", epilog="""
**Examples**

  raycast-phong reference scenes/default.toml -o ref.exr        # exact spheres, float64

  raycast-phong reference scenes/mesh.toml --fine 2 -o ref.exr  # a mesh: Loop-subdivided twice, Phong, float64
""")
def reference_command(
    scene: SceneArgument = None,
    output: Annotated[Path, typer.Option("--output", "-o", help="Image to write (.exr keeps float values; "
                      ".png is clamped to 8 bits).")] = Path("reference.exr"),
    fine: Annotated[int | None, typer.Option(min=1, max=6, help="Self-convergence reference instead: every "
                    "mesh Loop-subdivided N times and every shape N levels finer, Phong shading, float64. "
                    "The only choice for a scene with a mesh file.")] = None,
    set_: SetOption = [],
    max_memory: MaxMemoryOption = None,
    view: ViewOption = None,
    up: UpOption = None,
    quiet: Annotated[bool, quiet_option("progress bar or summary line")] = False,
    verbose: Annotated[bool, verbose_option("how much of the image the surfaces cover and the brightest "
                       "specular value (what the error figures are measured over)")] = False,
) -> None:
    """Render the analytic reference: the same camera, lights, materials and model on the exact sphere,
    plane, box, cylinder and torus, in float64, with the true normal."""
    from raycast_phong.io.files import check_output_path
    from raycast_phong.tools.accuracy import reference_image
    check_verbosity(quiet, verbose)
    with exit_codes():
        path = scene or rp.default_scene_path()
        loaded = rp.load_scene(path, set_, view=_view(view), up=up, max_memory=max_memory)
        check_output_path(output, inputs=(path, *loaded.files_read()))
        started = time.perf_counter()
        with progress_bar(quiet) as bar:
            bar.update(0, None, "computing the reference" if fine is None else "rendering the finer reference")
            exact = reference_image(loaded, fine=fine, max_memory=max_memory)
        seconds = time.perf_counter() - started
        rp.write_image(output, exact.image.astype("float32"), colour=loaded.render.colour)
    if quiet:
        return
    h, w = exact.image.shape[:2]
    typer.echo(f"{output}: {w}×{h} {exact.kind} reference in {seconds:.3f}s")
    if verbose:
        covered = (exact.coverage > 0).mean()
        typer.echo(f"surfaces cover {covered:.1%} of the pixels ({(exact.coverage == 1).mean():.1%} fully); "
                   f"brightest specular value {exact.specular.max():.4g}")


@app.command(epilog="""
**Examples**

  raycast-phong study scenes/default.toml -o study/          # levels chosen until the orders settle

  raycast-phong study --levels 0,1,2,3,4 --precision float32,float64 --samples 1,2 -o study/

  raycast-phong study --normals mean,exact --budget 300 -o study/   # the icosphere's seams, measured

  raycast-phong study scenes/specular.toml --shininess 10,100,1000 --models gouraud,phong -o stiff/
""")
def study(
    scene: SceneArgument = None,
    output: Annotated[Path | None, typer.Option("--output", "-o", show_default=False, help="Folder for "
                      "report.html, study.csv, the PNG plots and summary.md. Default: study.")] = None,
    out: OldOutOption = None,
    levels: Annotated[str, typer.Option(help="Tessellation levels (docs/accuracy.md: icosphere subdivisions, "
                      "segments 8·2^L, meshes Loop-subdivided L times), or auto: from level 1 up until every "
                      "fitted order settles or --budget is spent.")] = "auto",
    budget: Annotated[float, typer.Option(min=1.0, max=86400.0, help="Seconds the study may spend choosing "
                      "levels (--levels auto).")] = 120.0,
    normals: Annotated[str | None, typer.Option(help="Vertex normals of every built-in object, e.g. mean,exact "
                       "(default: the scene's).")] = None,
    models: Annotated[str, typer.Option(help="Shading models.")] = "flat,gouraud,phong",
    specular: Annotated[str | None, typer.Option(help="Specular models, e.g. phong,blinn (default: the "
                        "scene's).")] = None,
    precision: Annotated[str | None, typer.Option(help="float32,float64 (default: the scene's).")] = None,
    samples: Annotated[str | None, typer.Option(help="Samples per pixel side, e.g. 1,2 (default: the "
                       "scene's).")] = None,
    shininess: Annotated[str | None, typer.Option(help="Set every material's f, e.g. 10,100,1000.")] = None,
    repeats: Annotated[int, typer.Option(min=1, max=50, help="Timing rounds, every setting once per round; the "
                       "fastest counts, the spread is reported.")] = 5,
    fine: Annotated[int | None, typer.Option(min=1, max=6, help="Measure against a self-convergence "
                    "reference N levels finer (needed for mesh files).")] = None,
    target: Annotated[float, typer.Option(help="The RMSE the advice aims for.")] = 0.005,
    error_level: Annotated[int | None, typer.Option(min=0, max=9, help="The level of the error images "
                           "(default: the middle level).")] = None,
    width: Annotated[int | None, typer.Option(help="render.width in pixels, 1..16384.")] = None,
    height: Annotated[int | None, typer.Option(help="render.height in pixels, 1..16384.")] = None,
    set_: SetOption = [],
    max_memory: MaxMemoryOption = None,
    quiet: Annotated[bool, quiet_option("progress bar, fitted orders, advice or summary line")] = False,
    verbose: Annotated[bool, verbose_option("each step as it starts (a level measured, a timing round), with "
                       "the seconds since the start")] = False,
) -> None:
    """Work-precision study: measure every setting against the reference, time them all in interleaved rounds;
    write report.html (fronts, fitted orders, error images, advice, the machine's noise), study.csv and the plots."""
    from raycast_phong.codes import Precision
    from raycast_phong.tools import lists
    from raycast_phong.tools.study import NORMALS, StudyOptions, advice, check_study_folder, run_study
    check_verbosity(quiet, verbose)
    out = output_or_old_spelling("study", output, out, Path("study"))
    with exit_codes():
        options = StudyOptions(
            levels=None if levels.strip() == "auto" else lists.numbers(levels, int, "--levels"),
            models=lists.choices(models, ShadingModel, "--models", ShadingModel), budget=budget,
            error_level=error_level, normals=lists.choices(normals or None, NORMALS, "--normals"),
            speculars=lists.choices(specular, SpecularModel, "--specular", SpecularModel),
            precisions=lists.choices(precision or None, Precision, "--precision"),
            samples=lists.numbers(samples, int, "--samples"), shininess=lists.numbers(shininess, float, "--shininess"),
            repeats=repeats, fine=fine, target=target, max_memory=max_memory)
        overrides = [*scene_overrides({"render.width": width, "render.height": height}), *set_]
        path = scene or rp.default_scene_path()
        check_study_folder(out, path)
        with progress_bar(quiet) as bar:
            started, step = time.perf_counter(), [""]

            def advance(done: int, total: int, what: str) -> None:
                if verbose and what != step[0]:  # a line per step, not per render of a timing round
                    bar.echo(f"[{time.perf_counter() - started:.1f}s] {what}")
                step[0] = what
                bar.update(done, total, f"study: {what}")

            bar.update(0, None, "study: loading the renderer")
            result = run_study(path, overrides, options, progress=advance)
            bar.update(0, None, "study: writing the report")
            from raycast_phong.tools.study_report import write_study
            written = write_study(result, out)
    if quiet:
        return
    typer.echo(result.levels_note)
    from raycast_phong.tools.study import order_reason
    for fit in result.fits:
        reason = order_reason(fit, result)  # the report's "why not theory", so the terminal says it too
        typer.echo(f"{fit.model:8} {fit.group}: order {fit.order:.2f} over the last levels, {fit.order_all:.2f} over "
                   f"all (theory {fit.theory:g}){'' if fit.settled else '; not settled'}"
                   f"{f'. Why not {fit.theory:g}: {reason}' if reason else ''}")
    typer.echo(advice(result))
    typer.echo(f"machine: {result.noise.sentence()}")
    typer.echo(f"{written['report']}: {len(result.rows)} settings; {written['csv']}, plots and summary.md beside it")


@app.command(epilog="""
**Examples**

  raycast-phong stability                      # every case, as a table

  raycast-phong stability --case watertightness --case grazing_light

  raycast-phong stability --json > stability.json
""")
def stability(
    case: Annotated[list[str], typer.Option("--case", metavar="NAME", help="Run only this case (repeatable); "
                    "`--list` shows the names.")] = [],
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object per case, for machines.")] = False,
    list_: Annotated[bool, typer.Option("--list", help="List the case names and exit.")] = False,
    quiet: Annotated[bool, quiet_option("progress bar and no passing case: only the failing ones (with --json, "
                     "the JSON as ever)")] = False,
    verbose: Annotated[bool, verbose_option("a line per case as it finishes, with its seconds")] = False,
) -> None:
    """Run the numerical-stability suite on the installed package: stiff and extreme inputs, each a
    property that can fail. Exit status 1 if any case fails."""
    from raycast_phong.tools import stability as suite
    check_verbosity(quiet, verbose)
    if list_:
        typer.echo("\n".join(suite.CASES))
        return
    unknown = [name for name in case if name not in suite.CASES]
    if unknown:
        fail(f"--case: unknown case {unknown[0]!r}; cases: {', '.join(suite.CASES)}")
    with exit_codes(), progress_bar(quiet) as bar:
        running = ["", time.perf_counter()]  # the case under way and when it started

        def advance(done: int, total: int, name: str) -> None:
            if verbose and done:
                bar.echo(f"[{done}/{total}] {running[0]}: {time.perf_counter() - running[1]:.2f}s")
            running[:] = [name, time.perf_counter()]
            bar.update(done, total, f"stability: {name}")

        results = suite.run_all(case or None, progress=advance)
    failed = sum(not r.passed for r in results)
    if as_json:
        typer.echo(json.dumps([{"case": r.case, "property": r.property, "figure": r.figure, "passed": r.passed,
                                "value": r.value, "limit": r.limit, "at_least": r.at_least,
                                "margin": None if r.margin is None else (r.margin if math.isfinite(r.margin) else None),
                                "seconds": round(r.seconds, 3)} for r in results], indent=2, ensure_ascii=False))
    elif not quiet or failed:  # under -q only the failing cases
        from rich.console import Console

        from .common import plain_output
        shown = [r for r in results if not (r.passed and quiet)]
        rows = [(r, "—" if r.value is None else f"{r.value:.3g} {'≥' if r.at_least else '≤'} {r.limit:.3g}",
                 "—" if r.margin is None else ("∞" if math.isinf(r.margin) else f"{r.margin:.3g}×")) for r in shown]
        # With no colour system the output holds no escape sequence (NO_COLOR, TERM=dumb). The terminal's own width
        # (80 when piped): a table below WIDE_TABLE columns breaks its words ("propert y"), so a block per case then.
        console = Console(**({"color_system": None} if plain_output() else {}))
        if console.width >= WIDE_TABLE:
            console.print(_stability_table(rows))
        else:
            for r, checked, margin in rows:
                verdict = typer.style("pass", fg="green") if r.passed else typer.style("FAIL", fg="red")
                typer.echo(f"{r.case}: {verdict} ({checked}, margin {margin}, {r.seconds:.2f} s)")  # styles: a tty
                for label, text in (("property", r.property), ("measured", r.figure)):
                    typer.echo("\n".join(textwrap.wrap(f"{label}: {text}", console.width, initial_indent="  ",
                                                        subsequent_indent="    ", break_long_words=False)))
        typer.echo(f"{len(results) - failed} passed, {failed} failed")
    if failed:
        raise typer.Exit(code=1)


WIDE_TABLE = 120  # columns from which the stability table keeps its words whole


def _stability_table(rows):
    """The stability results as a rich table: case, property, measured, checked, margin, result, seconds."""
    from rich.table import Table
    table = Table(show_lines=True)
    for name, ratio in (("case", 1), ("property", 3), ("measured", 2)):
        table.add_column(name, ratio=ratio, overflow="fold")  # a word too long for its column breaks, never cut
    for name in ("checked", "margin", "result", "s"):
        table.add_column(name, no_wrap=True)
    for r, checked, margin in rows:
        table.add_row(r.case, r.property, r.figure, checked, margin,
                      "[green]pass[/]" if r.passed else "[red]FAIL[/]", f"{r.seconds:.2f}")
    return table
