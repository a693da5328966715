"""`side-by-side` and `compare`: variants of one scene composed with their differences, and two image files
measured against each other."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

import raycast_phong as rp

from .common import (
    MaxMemoryOption,
    SceneArgument,
    SetOption,
    UpOption,
    ViewOption,
    _view,
    app,
    check_verbosity,
    exit_codes,
    note,
    quiet_option,
    scene_overrides,
    verbose_option,
    warn,
)
from .progress import progress_bar

if TYPE_CHECKING:
    from raycast_phong.tools import compare

@app.command("side-by-side", epilog="""
**Examples**

  raycast-phong side-by-side scenes/specular.toml --vary render.shading=flat,gouraud,phong -o shading.png

  raycast-phong side-by-side scenes/specular.toml --vary render.specular=phong,blinn -o specular.exr

  raycast-phong side-by-side --vary "lights.0.position=[3,4,6],[-3,4,6]" --width 480 --height 180

  raycast-phong side-by-side --vary materials.clay.shininess=8,64,512 --set render.samples=2
""")
def side_by_side(
    vary: Annotated[str, typer.Option(metavar="KEY.PATH=V1,V2[,...]", show_default=False, help="The scene key to "
                    "vary and two or more values, each applied as `--set KEY.PATH=V` would be, e.g. "
                    "`render.shading=flat,gouraud,phong` or `lights.0.position=[1,2,3],[3,2,1]` (split at the commas "
                    "outside brackets and quotes). Every variant is compared with the last.")],
    scene: SceneArgument = None,
    output: Annotated[Path, typer.Option("--output", "-o", help="The composed image: .png (8-bit, panels "
                      "clamped) or .exr (float32, with the variants as parts `variant0`, … of channels "
                      "`variant0.R/G/B`, …). With NAME.png, that EXR is written beside it as NAME-variants.exr.")
                      ] = Path("side-by-side.png"),
    width: Annotated[int | None, typer.Option(help="render.width in pixels, 1..16384.")] = None,
    height: Annotated[int | None, typer.Option(help="render.height in pixels, 1..16384.")] = None,
    set_: SetOption = [],
    max_memory: MaxMemoryOption = None,
    view: ViewOption = None,
    up: UpOption = None,
    quiet: Annotated[bool, quiet_option("progress bar, per-variant lines, summary line or note")] = False,
    verbose: Annotated[bool, verbose_option("each variant's render: size, triangles, rays, Mrays/s and seconds "
                       "per stage")] = False,
) -> None:
    """Render a scene once per value of one key; write the variants side by side over heat maps of how
    much each differs from the last, and print the share of pixels changed, mean and max difference."""
    from raycast_phong.io.files import check_output_path
    from raycast_phong.io.image_io import NO_FONT
    from raycast_phong.tools import compare  # only this command composes variants

    from .render import summary_line
    check_verbosity(quiet, verbose)
    with exit_codes():
        key, values = compare.parse_vary(vary)
        path = scene or rp.default_scene_path()
        fixed = [*scene_overrides({"render.width": width, "render.height": height}), *set_]
        # every value is checked before any render
        scenes = compare.load_variants(path, fixed, key, values, _view(view), up, max_memory)
        inputs = (path, *(file for variant in scenes for file in variant.files_read()))
        check_output_path(output, inputs=inputs)
        layers = output if output.suffix.lower() == ".exr" else output.with_name(f"{output.stem}-variants.exr")
        check_output_path(layers, inputs=inputs)
        from raycast_phong.io.system import budget_of
        each = compare.render_budget(scenes, budget_of(max_memory))
        results, session = [], rp.Renderer(max_memory=each)
        with progress_bar(quiet) as bar:
            for number, (variant, value) in enumerate(zip(scenes, values), 1):
                label = f"{key} = {value} ({number}/{len(scenes)})"
                bar.update(0, None, label)
                results.append(session.render(variant, progress=lambda done, total, label=label:
                                              bar.update(done, total, label)))
        from raycast_phong.io.encoding import display_values
        # Each panel as its PNG would show it (sRGB-encoded for render.colour = linear), so variants of different
        # colour settings compare as seen; the differences are measured on those values too.
        comparison = compare.compose([display_values(result.image, variant.render.colour)
                                      for result, variant in zip(results, scenes)], key, values)
        rp.write_image(layers, comparison.image, parts=comparison.parts())
        if layers != output:
            rp.write_image(output, comparison.image)
    if not comparison.labelled:
        warn(f"the image has no labels: {NO_FONT}")
    for line in told_once(key, values, [result.plan.warnings for result in results]):
        warn(line)
    if quiet:
        return
    for line in told_once(key, values, [result.plan.notes for result in results]):
        note(line)
    if verbose:
        for value, result in zip(values, results):
            typer.echo(f"{key} = {value}: {summary_line(result, output).split(': ', 1)[1]}")
    for line in variant_lines(key, values, comparison.stats):
        typer.echo(line)
    grid = comparison.layout
    typer.echo(f"{output}: {len(values)} variants of {grid.width}×{grid.height} and their differences, "
               f"{grid.image_width}×{grid.image_height}; exact variants in {layers}")
    if comparison.scale == 0:
        own = key == "render.shading" and any(obj.shading for obj in scenes[0].objects)
        hint = " (objects with their own `shading` keep it)" if own else ""
        typer.secho(f"note: all {len(values)} variants are identical: {key} changes nothing in this scene{hint}",
                    err=True, fg=typer.colors.YELLOW)


def told_once(key: str, values: list[str], told: list[tuple[str, ...]]) -> list[str]:
    """The variants' render warnings (or notes), each said once: as it is when every variant has it, else after
    the values of the variants that do (`render.shading = gouraud: objects.0 (gouraud): …`)."""
    lines = []
    for line in dict.fromkeys(line for lines_of_one in told for line in lines_of_one):
        having = [value for value, lines_of_one in zip(values, told) if line in lines_of_one]
        lines.append(line if len(having) == len(values) else f"{key} = {', '.join(having)}: {line}")
    return lines


def variant_lines(key: str, values: list[str], stats: list[compare.VariantStats]) -> list[str]:
    """One line per variant: the share of pixels changed, mean and max difference against the last."""
    labels = [f"{key} = {value}" for value in values]
    pad = max(len(label) for label in labels)
    from raycast_phong.tools.compare import CHANGED_ABOVE
    lines = [f"{label:<{pad}}  {s.changed:7.2%} of pixels changed (> {CHANGED_ABOVE:g}), "
             f"mean {s.mean:.4g}, max {s.max:.4g}" for label, s in zip(labels, stats)]
    return [f"{line} against {labels[-1]}" for line in lines[:-1]] + [f"{lines[-1]} (the reference)"]


@app.command("compare", epilog="""
**Examples**

  raycast-phong compare render.png reference.png                 # any pixel off by > 1e-6 fails

  raycast-phong compare a.exr b.exr --fail 1e-3 --fail-percent 0.2 --diff diff.png

  raycast-phong compare a.png b.png --fail 0.02 --warn 0.004     # 5 and 1 8-bit steps
""")
def compare_images(
    a: Annotated[Path, typer.Argument(help="First image (.png, .exr, any format OpenImageIO reads).",
                                      show_default=False)],
    b: Annotated[Path, typer.Argument(help="Second image, of the same size.", show_default=False)],
    diff: Annotated[Path | None, typer.Option("--diff", help="Write a heat map of max over channels of "
                    "|A − B| (black 0, pale yellow the largest difference).")] = None,
    fail_: Annotated[float, typer.Option("--fail", min=0.0, help="A pixel fails when a channel differs by more.")
                     ] = 1e-6,
    warn: Annotated[float, typer.Option("--warn", min=0.0, help="A pixel warns when a channel differs by more.")
                    ] = 1e-6,
    fail_percent: Annotated[float, typer.Option("--fail-percent", min=0.0, max=100.0, help="The comparison fails "
                            "only when more than this percentage of pixels fail.")] = 0.0,
    max_memory: MaxMemoryOption = None,
    quiet: Annotated[bool, quiet_option("error figures and no PASS line (a WARNING or FAILURE verdict is "
                     "still printed)")] = False,
    verbose: Annotated[bool, verbose_option("each image's size and channels, and the mean and largest "
                       "difference of each channel")] = False,
) -> None:
    """Compare two images as idiff does: mean, RMS, PSNR, the largest error and where. Exit status 0 pass
    (warnings included), 1 fail, 2 unreadable input or different sizes."""
    from raycast_phong.io.files import check_output_path
    from raycast_phong.io.image_io import compare_files
    from raycast_phong.tools.difference import difference_map
    check_verbosity(quiet, verbose)
    with exit_codes():
        if diff is not None:
            check_output_path(diff, inputs=(a, b))  # before reading: --diff onto an input would replace it
        from raycast_phong.io.system import budget_of
        found = compare_files(a, b, fail_, warn, budget_of(max_memory))
        if diff is not None:
            rp.write_image(diff, difference_map(found.a, found.b))
    (x, y), channel = found.max_at, found.max_channel
    if verbose:
        height, width, channels = found.a.shape
        typer.echo(f"{a} and {b}: {width}×{height}, {channels} channels")
        import numpy as np
        with np.errstate(invalid="ignore"):  # inf − inf: a non-finite pixel is counted below, left out here
            error = np.abs(found.a.astype(np.float64) - found.b)
        for c in range(channels):
            finite = error[..., c][np.isfinite(error[..., c])]
            figures = f"mean error {finite.mean():.6g}, max error {finite.max():.6g}" if finite.size else \
                "no finite pixel"
            typer.echo(f"channel {c}: {figures}")
    if not quiet:
        typer.echo(f"mean error {found.mean:.6g}, RMS error {found.rms:.6g}, PSNR {found.psnr:.2f} dB, "
                   f"max error {found.max:.6g} at pixel ({x}, {y}) channel {channel}")
    nonfinite = dict.fromkeys(f"{name}: {nan} pixel{'s' * (nan != 1)} with NaN, {inf} with inf"
                              for name, nan, inf in zip((a, b), found.nan, found.inf) if nan or inf)
    if nonfinite:  # not a number is no measurement: the comparison fails whatever --fail-percent allows
        typer.secho(f"FAILURE: {'; '.join(nonfinite)}", fg=typer.colors.RED)
        raise typer.Exit(code=1)
    share = 100.0 * found.failed / max(found.pixels, 1)
    counts = (f"{found.failed} of {found.pixels} pixels ({share:.3g}%) over --fail {fail_:g}, "
              f"{found.warned} over --warn {warn:g}")
    if diff is not None:
        counts += f"; heat map {diff}"
    if share > fail_percent:
        typer.secho(f"FAILURE: {counts} (allowed {fail_percent:g}%)", fg=typer.colors.RED)
        raise typer.Exit(code=1)
    if found.warned or not quiet:
        typer.echo(f"{'WARNING' if found.warned else 'PASS'}: {counts}")
