"""The `raycast-phong` command: parse arguments, call the package, turn errors into exit codes.

Exit status: 0 ok, 2 bad input (scene, mesh, option, output path) or an output that could not be written
(a full disk, a file-size limit: the old file is unchanged), 1 internal error.
"""

from __future__ import annotations

import json
import os
import sys
import time
from contextlib import contextmanager
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from typer.core import TyperGroup

import raycast_phong as rp
from raycast_phong.io.atomic import WriteError
from raycast_phong.io.image_io import NO_FONT, ImageError, check_output_path
from raycast_phong.scene.schema import Mode, ShadingModel, SpecularModel

if TYPE_CHECKING:
    from raycast_phong.tools import compare

# The click that typer parses with (typer ≥ 0.2x vendors its own copy): its exception classes.
_click_errors = sys.modules[typer.BadParameter.__module__]


class OneLineErrors(TyperGroup):
    """typer's command group, but a usage error (a bad --width, an unknown option or command) is one line on
    stderr with exit 2, like every other error of the program, instead of rich's boxed message."""

    def main(self, *args, standalone_mode: bool = True, **kwargs):
        if not standalone_mode:
            return super().main(*args, standalone_mode=False, **kwargs)
        try:
            code = super().main(*args, standalone_mode=False, **kwargs)
        except getattr(_click_errors, "NoArgsIsHelpError", ()):
            return super().main(*args, **kwargs)  # no arguments at all: typer shows the help, as it did
        except _click_errors.ClickException as error:
            command = error.ctx.command_path if getattr(error, "ctx", None) else None
            where = f"{command}: " if command else ""
            hint = f" (see {command} --help)" if command else ""
            typer.secho(f"error: {where}{error.format_message()}{hint}", err=True, fg=typer.colors.RED)
            sys.exit(error.exit_code)
        except typer.Abort:
            typer.secho("error: aborted", err=True, fg=typer.colors.RED)
            sys.exit(1)
        sys.exit(code if isinstance(code, int) else 0)  # a command's typer.Exit(code), else success


app = typer.Typer(
    cls=OneLineErrors,
    help="Ray-cast flat, Gouraud and Phong shading with Intel Embree.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode="markdown",
)

SceneArgument = Annotated[Path | None, typer.Argument(
    help="Scene file (.toml or .json, see docs/scene-format.md) or a mesh file (.obj, .ply, .stl, .off, .glb, "
         ".gltf, anything trimesh reads: framed, lit and with its own materials, see docs/meshes.md). Omit it for "
         "the built-in default scene.",
    show_default=False, dir_okay=False)]


class MeshView(str, Enum):
    """Where the default camera of a mesh file looks from (pipeline.mesh_scene.VIEWS)."""
    THREE_QUARTER = "three-quarter"
    FRONT = "front"
    SIDE = "side"
    TOP = "top"
    ISO = "iso"


ViewOption = Annotated[MeshView | None, typer.Option(
    "--view", show_default=False, help="A mesh file's camera: three-quarter (the default: 30° round from the "
    "front, 20° up), front, side, top or iso; it frames the model's bounding sphere.")]
UpOption = Annotated[str | None, typer.Option(
    "--up", metavar="AXIS", show_default=False, help="A mesh file's up axis: x, y, z, -x, -y or -z. Default: the "
    "one its format states (glTF: y), else y.")]


def _view(view: MeshView | None) -> str | None:
    return view.value if view is not None else None
SetOption = Annotated[list[str], typer.Option(
    "--set", metavar="KEY.PATH=VALUE",
    help="Override a scene key, e.g. `render.width=320`, `lights.0.position=[1,2,3]`, "
         "`materials.red.shininess=8`. Repeatable.")]


def _max_memory(text: str | None) -> int | None:
    """--max-memory SIZE in bytes; a malformed size exits 2 with one line."""
    if text is None:
        return None
    from raycast_phong.renderer.budget import parse_size
    try:
        return parse_size(text)
    except ValueError as error:
        fail(f"--max-memory: {error}")


MaxMemoryOption = Annotated[str | None, typer.Option(
    "--max-memory", metavar="SIZE", callback=_max_memory, show_default=False,
    help="Memory budget for rendering, e.g. 8G or 500M (K, M, G, T: powers of 1024). A scene whose estimated "
         "geometry and image need more is refused before anything is built. Default: 3/4 of the memory "
         "available now.")]


class ReferenceKind(str, Enum):
    """What `render --reference` measures against (here, not in reference.py, so --help loads no renderer)."""
    ANALYTIC = "analytic"


def fail(message: str, code: int = 2) -> None:
    typer.secho(f"error: {message}", err=True, fg=typer.colors.RED)
    raise typer.Exit(code=code)


def scene_overrides(options: dict[str, object]) -> list[str]:
    """CLI options that stand for scene keys, as `key=value` overrides (None = not given)."""
    out = []
    for key, value in options.items():
        if value is None:
            continue
        value = value.value if hasattr(value, "value") else value
        out.append(f"{key}={json.dumps(value)}")
    return out


@app.command(epilog="""
**Examples**

  raycast-phong render                                  # the default figure → default.png

  raycast-phong render scenes/coloured_lights.toml -o lights.exr

  raycast-phong render scenes/default.toml --shading gouraud --specular blinn --samples 3

  raycast-phong render scene.toml --set render.width=320 --set "lights.0.diffuse=[1, 0, 0]"
""")
def render(
    scene: SceneArgument = None,
    output: Annotated[Path | None, typer.Option("--output", "-o", help="Image to write: .png (8-bit, clamped) or "
                      ".exr (float32, with the scene's AOV layers). Default: the scene's output.path.")] = None,
    shading: Annotated[ShadingModel | None, typer.Option(help="render.shading (objects with their own "
                       "`shading` keep it).")] = None,
    specular: Annotated[SpecularModel | None, typer.Option(help="render.specular: phong (v·r) or "
                        "blinn (n·h).")] = None,
    mode: Annotated[Mode | None, typer.Option(help="render.mode: local (no shadows) or global.")] = None,
    width: Annotated[int | None, typer.Option(help="render.width in pixels, 1..16384.")] = None,
    height: Annotated[int | None, typer.Option(help="render.height in pixels, 1..16384.")] = None,
    samples: Annotated[int | None, typer.Option(help="render.samples: n → n×n rays per pixel, 1..16.")] = None,
    set_: SetOption = [],
    srgb: Annotated[bool, typer.Option("--srgb", help="Encode a PNG with the sRGB curve instead of "
                    "storing the model's display values as they are.")] = False,
    threads: Annotated[int | None, typer.Option(min=1, max=64, help="Worker threads (default: cores).")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar and no summary line.")] = False,
    reference: Annotated[ReferenceKind | None, typer.Option(help="Also measure the render against the exact "
                         "surfaces (docs/accuracy.md): print RMSE, max error and PSNR beside the timing line.")] = None,
    max_memory: MaxMemoryOption = None,
    view: ViewOption = None,
    up: UpOption = None,
) -> None:
    """Render a scene file, a mesh file or the built-in default scene to a PNG or EXR image."""
    overrides = [*scene_overrides({"render.shading": shading, "render.specular": specular, "render.mode": mode,
                                   "render.width": width, "render.height": height, "render.samples": samples}),
                 *set_]
    with exit_codes():
        started = time.perf_counter()
        path = scene or rp.default_scene_path()
        loaded = rp.load_scene(path, overrides, view=_view(view), up=up)
        load_seconds = time.perf_counter() - started
        option = "--output" if output is not None else "output.path"
        if output is None and scene is not None:
            loaded.output.check_inside(str(path))  # a scene writes inside its folder; elsewhere only with -o
        if output is None:
            output = Path(loaded.output.path).name if scene is None else loaded.resolve(loaded.output.path)
        try:
            check_output_path(output, inputs=(path,))
        except ImageError as error:
            fail(f"{path}: {option}: {error}")  # say where the path came from: the option or the scene
        if loaded.output.aovs and Path(output).suffix.lower() != ".exr":
            fail(f"{path}: output.aovs: {list(loaded.output.aovs)} need an .exr output, but -o {output} is a PNG "
                 "(a PNG holds only RGB)")
        if reference is not None:
            from raycast_phong.tools.reference import ExactScene
            ExactScene(loaded, str(path))  # a mesh has no closed form: refuse before rendering
        result = _render_with_progress(loaded, str(path), threads, quiet, max_memory)
        if reference is not None:
            from raycast_phong.tools.accuracy import measured
            result = measured(loaded, result, reference.value, 2, str(path))
        started = time.perf_counter()
        rp.write_image(output, result.image, result.aovs, srgb=srgb)
        result.timings["write"] = time.perf_counter() - started
        result.timings["load"] = load_seconds
    if not quiet:
        for warning in result.plan.warnings:
            typer.secho(f"warning: {warning}", err=True, fg=typer.colors.YELLOW)
        for note in result.plan.notes:
            typer.echo(f"note: {note}", err=True)
        typer.echo(summary_line(result, output))
        if reference is not None:
            typer.echo(error_line(result.errors, result.reference_seconds))


@contextmanager
def exit_codes():
    """Bad input (SceneError, ImageError) and a failed write (WriteError) exit 2 and anything else 1, each with
    one line on stderr."""
    try:
        yield
    except (rp.SceneError, ImageError, WriteError) as error:
        fail(str(error))
    except typer.Exit:
        raise
    except Exception as error:  # anything else is our bug: one line, exit 1, the traceback in a log file
        if _debug():
            raise
        log = _traceback_log(error)
        fail(f"internal error: {type(error).__name__}: {error}" + (f" (traceback in {log})" if log else ""), code=1)


def _traceback_log(error: BaseException) -> str | None:
    """Write the traceback of an internal error to a fresh raycast-phong-error-*.log in the temporary folder
    and return its path (None if even that cannot be written: the one line must still come out)."""
    import tempfile
    import traceback
    try:
        descriptor, path = tempfile.mkstemp(prefix="raycast-phong-error-", suffix=".log")
        with os.fdopen(descriptor, "w", encoding="utf-8") as log:
            log.write("".join(traceback.format_exception(error)))
        return path
    except OSError:
        return None


def _debug() -> bool:
    import os
    return os.environ.get("RAYCAST_PHONG_DEBUG", "") not in ("", "0")


def _render_with_progress(scene: rp.Scene, source: str, threads: int | None, quiet: bool,
                          max_memory: int | None = None) -> rp.RenderResult:
    stage, seconds = _ready_kernels(scene, quiet)
    result = _render_shown(scene, source, threads, quiet, max_memory)
    result.timings[stage] = seconds
    return result


def _ready_kernels(scene: rp.Scene, quiet: bool) -> tuple[str, float]:
    """Have the kernels this scene needs ready before its render, so the frame time, and the Mrays/s printed
    from it, hold neither compilation nor loading: ("compile", seconds) when the cache does not hold them
    (the first render after an install or an edit; said on stderr first), else ("kernels", seconds) for
    loading them from the cache, most of it numba's one-time set-up in a process (≈ 0.25 s)."""
    from raycast_phong.renderer.frame import tile_kernel, warm_kernels_for
    from raycast_phong.renderer.kernels.jit import compiled_before
    cached = compiled_before(tile_kernel())
    if not cached and not quiet:
        typer.echo("compiling the shading kernels, once after an install or an edit (about 10-30 s)...", err=True)
    started = time.perf_counter()
    warm_kernels_for([rp.build_plan(scene)])
    return ("kernels" if cached else "compile"), time.perf_counter() - started


def _render_shown(scene: rp.Scene, source: str, threads: int | None, quiet: bool,
                  max_memory: int | None) -> rp.RenderResult:
    """render(), with a progress bar over the tiles on a terminal."""
    if quiet or not sys.stderr.isatty():
        return rp.render(scene, threads=threads, source=source, max_memory=max_memory)
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn
    columns = (TextColumn("{task.description}"), BarColumn(), TimeRemainingColumn())
    with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("building the BVH", total=None)

        def advance(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total, description=f"rendering {done}/{total} tiles")

        return rp.render(scene, threads=threads, source=source, progress=advance, max_memory=max_memory)


def summary_line(result: rp.RenderResult, output: Path) -> str:
    """One line: size, triangles, rays/s, seconds per stage."""
    h, w = result.image.shape[:2]
    t = result.timings
    shown = ("load", "compile", "kernels", "geometry", "build", "rays", "shadows", "shade", "write")
    stages = ", ".join(f"{name} {t[name]:.3f}s" for name in shown if name in t)
    return (f"{output}: {w}×{h}, {result.triangles:,} triangles, {result.rays:,} rays, "
            f"{result.rays_per_second / 1e6:.1f} Mrays/s; frame {t['frame']:.3f}s ({stages}; rays, shadows "
            f"and shade summed over threads)")


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
) -> None:
    """Render a scene once per value of one key; write the variants side by side over heat maps of how
    much each differs from the last, and print the share of pixels changed, mean and max difference."""
    from raycast_phong.tools import compare  # only this command composes variants
    with exit_codes():
        key, values = compare.parse_vary(vary)
        path = scene or rp.default_scene_path()
        fixed = [*scene_overrides({"render.width": width, "render.height": height}), *set_]
        # every value is checked before any render
        scenes = compare.load_variants(path, fixed, key, values, _view(view), up)
        check_output_path(output, inputs=(path,))
        layers = output if output.suffix.lower() == ".exr" else output.with_name(f"{output.stem}-variants.exr")
        check_output_path(layers, inputs=(path,))
        comparison = compare.compose([rp.render(variant, source=str(path), max_memory=max_memory).image
                                      for variant in scenes], key, values)
        rp.write_image(layers, comparison.image, parts=comparison.parts())
        if layers != output:
            rp.write_image(output, comparison.image)
    for line in variant_lines(key, values, comparison.stats):
        typer.echo(line)
    grid = comparison.layout
    typer.echo(f"{output}: {len(values)} variants of {grid.width}×{grid.height} and their differences, "
               f"{grid.image_width}×{grid.image_height}; exact variants in {layers}")
    if not comparison.labelled:
        typer.secho(f"warning: the image has no labels: {NO_FONT}", err=True, fg=typer.colors.YELLOW)
    if comparison.scale == 0:
        own = key == "render.shading" and any(obj.shading for obj in scenes[0].objects)
        hint = " (objects with their own `shading` keep it)" if own else ""
        typer.secho(f"note: all {len(values)} variants are identical: {key} changes nothing in this scene{hint}",
                    err=True, fg=typer.colors.YELLOW)


def variant_lines(key: str, values: list[str], stats: list[compare.VariantStats]) -> list[str]:
    """One line per variant: the share of pixels changed, mean and max difference against the last."""
    labels = [f"{key} = {value}" for value in values]
    pad = max(len(label) for label in labels)
    from raycast_phong.tools.compare import CHANGED_ABOVE
    lines = [f"{label:<{pad}}  {s.changed:7.2%} of pixels changed (> {CHANGED_ABOVE:g}), "
             f"mean {s.mean:.4g}, max {s.max:.4g}" for label, s in zip(labels, stats)]
    return [f"{line} against {labels[-1]}" for line in lines[:-1]] + [f"{lines[-1]} (the reference)"]


@app.command(epilog="""
**Examples**

  raycast-phong plan                           # the default scene

  raycast-phong plan scenes/attenuation.toml --set render.viewer=infinite
""")
def plan(scene: SceneArgument = None, set_: SetOption = [], max_memory: MaxMemoryOption = None,
         view: ViewOption = None, up: UpOption = None) -> None:
    """Print the render plan: each stage and term, kept or left out, and why; then what the geometry
    tells (repaired windings, highlights the render would miss)."""
    from raycast_phong.renderer.prepare import prepare
    with exit_codes():
        path = scene or rp.default_scene_path()
        loaded = rp.load_scene(path, set_, view=_view(view), up=up)
        # render's own preparation: the same memory check (before building anything), geometry and diagnosis.
        typer.echo(prepare(loaded, source=str(path), max_memory=max_memory).plan.describe())


@app.command(epilog="""
**Examples**

  raycast-phong stability                      # every case, as a table

  raycast-phong stability --case watertightness --case grazing_light

  raycast-phong stability --json > stability.json
""")
def stability(
    case: Annotated[list[str], typer.Option("--case", help="Run only this case (repeatable); "
                    "`--list` shows the names.")] = [],
    as_json: Annotated[bool, typer.Option("--json", help="One JSON object per case, for machines.")] = False,
    list_: Annotated[bool, typer.Option("--list", help="List the case names and exit.")] = False,
) -> None:
    """Run the numerical-stability suite on the installed package: stiff and extreme inputs, each a
    property that can fail. Exit status 1 if any case fails."""
    from raycast_phong.tools import stability as suite
    if list_:
        typer.echo("\n".join(suite.CASES))
        return
    unknown = [name for name in case if name not in suite.CASES]
    if unknown:
        fail(f"--case: unknown case {unknown[0]!r}; cases: {', '.join(suite.CASES)}")
    with exit_codes():
        results = suite.run_all(case or None)
    if as_json:
        typer.echo(json.dumps([{"case": r.case, "property": r.property, "figure": r.figure, "passed": r.passed,
                                "seconds": round(r.seconds, 3)} for r in results], indent=2, ensure_ascii=False))
    else:
        from rich.console import Console
        from rich.table import Table
        table = Table("case", "property", "measured", "", "s", show_lines=True)
        for r in results:
            table.add_row(r.case, r.property, r.figure, "[green]pass[/]" if r.passed else "[red]FAIL[/]",
                          f"{r.seconds:.2f}")
        Console(width=max(140, Console().width)).print(table)
        failed = sum(not r.passed for r in results)
        typer.echo(f"{len(results) - failed} passed, {failed} failed")
    if any(not r.passed for r in results):
        raise typer.Exit(code=1)


@app.command("scene", epilog="""
**Examples**

  raycast-phong scene model.obj > model.toml           # then edit it and render model.toml

  raycast-phong scene model.glb --view front --up z -o model.toml   # mesh path written relative to model.toml

  raycast-phong scene model.ply --set render.width=1280 --set render.height=720
""")
def scene_command(
    scene: Annotated[Path, typer.Argument(help="Mesh file (or a scene file, written out with every key).",
                                          show_default=False, dir_okay=False)],
    output: Annotated[Path | None, typer.Option("--output", "-o", help="Write the TOML here (atomically) instead "
                      "of to standard output; the mesh path is then relative to its folder.")] = None,
    set_: SetOption = [],
    view: ViewOption = None,
    up: UpOption = None,
) -> None:
    """Print the scene file a mesh file stands for: its materials, the framing camera, the key light and
    every other key with its value. `render` of that file gives the same image as `render` of the mesh."""
    from raycast_phong.scene.load import is_mesh_file
    from raycast_phong.tools.sweep import scene_toml
    with exit_codes():
        loaded = rp.load_scene(scene, set_, view=_view(view), up=up)
        notes = ()
        if is_mesh_file(scene):
            from raycast_phong.io.mesh_file import mesh_bounds
            notes = mesh_bounds(scene, str(scene)).notes
        header = (f"# The scene `raycast-phong render {scene.name}` renders: written by `raycast-phong scene`.\n"
                  "# A [materials.NAME] table overrides the mesh file's material of that name; see docs/meshes.md.")
        if output is not None:
            from raycast_phong.io.image_io import check_output_file
            check_output_file(output, inputs=(scene,))
        text = scene_toml(loaded, header, relative_to=output.parent if output is not None else None)
        if output is not None:
            from raycast_phong.io.atomic import write_text
            write_text(output, text)
    for note in notes:
        typer.echo(f"note: {note}", err=True)
    if output is None:
        typer.echo(text, nl=False)


@app.command(epilog="""
**Examples**

  raycast-phong schema > scene.schema.json
""")
def schema() -> None:
    """Print the JSON Schema of the scene format (the same as docs/scene.schema.json)."""
    from raycast_phong.scene.schema import scene_json_schema
    typer.echo(json.dumps(scene_json_schema(), indent=2, ensure_ascii=False))


@app.command(epilog="""
**Examples**

  raycast-phong view                                    # the default figure, in the browser

  raycast-phong view scenes/specular.toml --port 0 --no-browser   # any free port; open the printed URL

  raycast-phong view scenes/meshes/torus_knot.ply       # a mesh file, framed and lit
""")
def view(
    scene: Annotated[Path | None, typer.Argument(help="Scene file (.toml, .json) or a mesh file (any format "
                     "trimesh reads). Omit it for the built-in default scene.", show_default=False,
                     dir_okay=False)] = None,
    port: Annotated[int, typer.Option(min=0, max=65535, help="Port to listen on; 0 for any free one.")] = 8765,
    host: Annotated[str, typer.Option(help="Address to listen on. Anything but 127.0.0.1 lets other machines "
                    "reach the page (they still need the token).")] = "127.0.0.1",
    no_browser: Annotated[bool, typer.Option("--no-browser", help="Only print the URL.")] = False,
) -> None:
    """Explore a scene live in the browser: switch shading models, drag the light, compare two settings
    (docs/view.md). Prints the page's URL with its access token; Ctrl-C stops the server."""
    try:
        from raycast_phong.tools import view as live
    except ImportError as error:
        fail(f"the view needs its extra packages ({error.name} is missing): pip install 'raycast-phong[view]'")
    if host not in ("127.0.0.1", "localhost", "::1"):
        typer.secho(f"warning: --host {host}: the page is reachable from other machines; anyone with the URL's "
                    "token can use it", err=True, fg=typer.colors.YELLOW)
    with exit_codes():
        try:
            live.serve(scene, host=host, port=port, open_browser=not no_browser,
                       announce=lambda url: typer.echo(f"raycast-phong view: open {url}"))
        except OSError as error:
            fail(str(error))
        except KeyboardInterrupt:
            pass


@app.command(epilog="""
**Examples**

  raycast-phong batch scenes/ --out renders              # every scene in the folder, on all cores

  raycast-phong batch "scenes/*.toml" sweeps/shading.toml --out renders --jobs 2

  raycast-phong batch scenes/ --out renders --force      # render even the up-to-date ones

  raycast-phong batch scenes/ --out renders --scheduler tcp://10.0.0.5:8786   # on a Dask cluster
""")
def batch(
    paths: Annotated[list[str], typer.Argument(metavar="PATHS...", show_default=False, help="Scene files, folders "
                     "(their .toml and .json files), globs (quoted) and sweep files (see docs/batch.md).")],
    out: Annotated[Path, typer.Option("--out", help="Output folder: one image per scene, named after it, and "
                   "manifest.json.", show_default=False)],
    jobs: Annotated[int | None, typer.Option("--jobs", "-j", min=1, max=256, help="Cores to use (default: all): "
                    "N scenes render at once, each in a worker process on one thread; fewer scenes than N share "
                    "the N cores as threads. With 1, scenes render one after another in this process.")] = None,
    force: Annotated[bool, typer.Option("--force", help="Render every scene, even those whose outputs are "
                     "up to date.")] = False,
    scheduler: Annotated[str | None, typer.Option(metavar="tcp://HOST:PORT", help="Run the renders on this "
                         "Dask scheduler (pip install 'raycast-phong[distributed]'); scene files and the output "
                         "folder must be at the same paths on its workers.")] = None,
    srgb: Annotated[bool, typer.Option("--srgb", help="Encode PNG outputs with the sRGB curve.")] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress and no summary; failures are still "
                     "reported.")] = False,
    max_memory: MaxMemoryOption = None,
) -> None:
    """Render many scene files into one folder, in parallel; skip those whose outputs are up to date.
    A failing scene is reported (file and reason) and the others go on; exit status 1 if any failed.
    Ctrl-C or `kill` stops the workers at once; exit status 130 (SIGINT) or 143 (SIGTERM)."""
    import signal

    from raycast_phong.tools import batch as batches
    # Ctrl-C and `kill` (SIGTERM) both stop the batch: workers killed, temporaries removed, the manifest written.
    previous = {number: signal.signal(number, batches.interrupt) for number in (signal.SIGINT, signal.SIGTERM)}
    try:
        with exit_codes():
            found = batches.find_jobs(paths, out)
            report = _batch_with_progress(found, out, jobs, force, batches.Settings(srgb=srgb), scheduler, quiet,
                                          max_memory)
    except batches.Interrupted as stop:
        _report_interrupt(stop, out)
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
    for warning in report.warnings:
        typer.secho(f"warning: {warning}", err=True, fg=typer.colors.YELLOW)
    for outcome in report.failed:
        typer.secho(f"failed: {outcome.reason}", err=True, fg=typer.colors.RED)
    if not quiet:
        sheets = "".join(f"; contact sheet {out / name}" for name in report.sheets.values())
        typer.echo(f"{len(report.outcomes)} scenes: {report.count(batches.RENDERED)} rendered, "
                   f"{report.count(batches.UP_TO_DATE)} up to date, {len(report.failed)} failed in "
                   f"{report.seconds:.2f}s ({report.startup:.2f}s of it loading the renderer); "
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
                         quiet: bool, max_memory: int | None = None):
    """run_batch with a progress bar over the scenes on a terminal, one line per scene otherwise."""
    from raycast_phong.tools.batch import run_batch
    options = {"workers": jobs, "force": force, "settings": settings, "scheduler": scheduler, "max_memory": max_memory}
    if quiet:
        return run_batch(found, out, **options)
    if not sys.stderr.isatty():
        started = time.perf_counter()

        def line(outcome, done: int, total: int) -> None:
            typer.echo(f"[{done}/{total} {time.perf_counter() - started:.2f}s] {outcome.status}: {outcome.name}",
                       err=True)
        return run_batch(found, out, progress=line, **options)
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress(*columns, console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("scenes", total=len(found))

        def advance(outcome, done: int, total: int) -> None:
            bar.update(task, completed=done, description=f"{outcome.status}: {outcome.name}")

        return run_batch(found, out, progress=advance, **options)


# ---------------------------------------------------------------- accuracy: reference and study (docs/accuracy.md)


def error_line(errors, seconds: float) -> str:
    """One line: RMSE, max and PSNR against the reference, and the silhouette and highlight figures."""
    return (f"against the {errors.reference} reference: RMSE {errors.rmse:.5f}, max {errors.max_error:.4f}, "
            f"PSNR {errors.psnr:.1f} dB over {errors.compared_pixels:,} pixels both cover; "
            f"{errors.silhouette_pixels:,} silhouette pixels, highlight loss {errors.highlight_loss:.3f} "
            f"(reference {seconds:.3f}s)")


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
    view: ViewOption = None,
    up: UpOption = None,
) -> None:
    """Render the analytic reference: the same camera, lights, materials and model on the exact sphere,
    plane, box, cylinder and torus, in float64, with the true normal."""
    from raycast_phong.tools.accuracy import reference_image
    with exit_codes():
        path = scene or rp.default_scene_path()
        loaded = rp.load_scene(path, set_, view=_view(view), up=up)
        check_output_path(output, inputs=(path,))
        started = time.perf_counter()
        exact = reference_image(loaded, str(path), fine=fine)
        seconds = time.perf_counter() - started
        rp.write_image(output, exact.image.astype("float32"))
    h, w = exact.image.shape[:2]
    typer.echo(f"{output}: {w}×{h} {exact.kind} reference in {seconds:.3f}s")


def _numbers(text: str | None, kind: type, option: str) -> tuple | None:
    """'0,1,2' → (0, 1, 2); None stays None; a bad item exits 2 naming the option."""
    if text is None:
        return None
    try:
        return tuple(kind(item) for item in text.split(",") if item.strip())
    except ValueError:
        fail(f"{option}: expected numbers separated by commas, got {text!r}")


@app.command(epilog="""
**Examples**

  raycast-phong study scenes/default.toml --out study/          # levels chosen until the orders settle

  raycast-phong study --levels 0,1,2,3,4 --precision float32,float64 --samples 1,2 --out study/

  raycast-phong study --normals mean,exact --budget 300 --out study/   # the icosphere's seams, measured

  raycast-phong study scenes/specular.toml --shininess 10,100,1000 --models gouraud,phong --out stiff/
""")
def study(
    scene: SceneArgument = None,
    out: Annotated[Path, typer.Option("--out", help="Folder for report.html, study.csv, the PNG plots and "
                   "summary.md.")] = Path("study"),
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
) -> None:
    """Work-precision study: measure every setting against the reference, time them all in interleaved rounds;
    write report.html (fronts, fitted orders, error images, advice, the machine's noise), study.csv and the plots."""
    from raycast_phong.tools import study as sweep

    def choices(text: str | None, enum, option: str) -> tuple | None:
        if text is None:
            return None
        allowed = [e.value for e in enum]
        items = [item.strip() for item in text.split(",") if item.strip()]
        for item in items:
            if item not in allowed:
                fail(f"{option}: {item!r} is not one of {', '.join(allowed)}")
        return tuple(enum(item) for item in items)

    for item in (precision or "").split(","):
        if item.strip() and item.strip() not in ("float32", "float64"):
            fail(f"--precision: {item.strip()!r} is not one of float32, float64")
    for item in (normals or "").split(","):
        if item.strip() and item.strip() not in sweep.NORMALS:
            fail(f"--normals: {item.strip()!r} is not one of {', '.join(sweep.NORMALS)}")
    options = sweep.StudyOptions(
        levels=None if levels.strip() == "auto" else _numbers(levels, int, "--levels"),
        models=choices(models, ShadingModel, "--models"), budget=budget, error_level=error_level,
        normals=tuple(n.strip() for n in normals.split(",") if n.strip()) if normals else None,
        speculars=choices(specular, SpecularModel, "--specular"),
        precisions=tuple(p.strip() for p in precision.split(",") if p.strip()) if precision else None,
        samples=_numbers(samples, int, "--samples"), shininess=_numbers(shininess, float, "--shininess"),
        repeats=repeats, fine=fine, target=target, max_memory=max_memory)
    overrides = [*scene_overrides({"render.width": width, "render.height": height}), *set_]
    with exit_codes():
        path = scene or rp.default_scene_path()
        sweep.check_study_folder(out, path)
        result = sweep.run_study(path, overrides, options)
        from raycast_phong.tools.study_report import write_study
        written = write_study(result, out)
    typer.echo(result.levels_note)
    for fit in result.fits:
        typer.echo(f"{fit.model:8} {fit.group}: order {fit.order:.2f} over the last levels, {fit.order_all:.2f} over "
                   f"all (theory {fit.theory:g}){'' if fit.settled else '; not settled'}")
    typer.echo(sweep.advice(result))
    typer.echo(f"machine: {result.noise.sentence()}")
    typer.echo(f"{written['report']}: {len(result.rows)} settings; {written['csv']}, plots and summary.md beside it")


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
) -> None:
    """Compare two images as idiff does: mean, RMS, PSNR, the largest error and where. Exit status 0 pass
    (warnings included), 1 fail, 2 unreadable input or different sizes."""
    from raycast_phong.io.image_io import compare_files
    from raycast_phong.tools.difference import difference_map
    with exit_codes():
        if diff is not None:
            check_output_path(diff, inputs=(a, b))  # before reading: --diff onto an input would replace it
        found = compare_files(a, b, fail_, warn)
        if diff is not None:
            rp.write_image(diff, difference_map(found.a, found.b))
    (x, y), channel = found.max_at, found.max_channel
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
    typer.echo(f"{'WARNING' if found.warned else 'PASS'}: {counts}")


if __name__ == "__main__":
    app()
