"""`render` and `plan`: one scene to an image, and what its render would do."""

from __future__ import annotations

import sys
import time
from enum import Enum
from pathlib import Path
from typing import Annotated

import typer

import raycast_phong as rp
from raycast_phong.codes import Mode, ShadingModel, SpecularModel

from .common import (
    MaxMemoryOption,
    SceneArgument,
    SetOption,
    SrgbOption,
    UpOption,
    ViewOption,
    _view,
    app,
    exit_codes,
    scene_overrides,
)


class ReferenceKind(str, Enum):
    """What `render --reference` measures against (here, not in reference.py, so --help loads no renderer)."""
    ANALYTIC = "analytic"


@app.command(epilog="""
**Examples**

  raycast-phong render                                  # the default figure → default.png

  raycast-phong render scenes/coloured_lights.toml -o lights.exr

  raycast-phong render scenes/default.toml --shading gouraud --specular blinn --samples 3

  raycast-phong render scene.toml --set render.width=320 --set "lights.0.diffuse=[1, 0, 0]"
""")
def render(
    scene: SceneArgument = None,
    output: Annotated[Path | None, typer.Option("--output", "-o", help="Image to write: .png (8-bit, clamped; "
                      "through the sRGB curve when render.colour = linear) or .exr (float32, unencoded, with the "
                      "scene's AOV layers). Default: the scene's output.path.")] = None,
    shading: Annotated[ShadingModel | None, typer.Option(help="render.shading (objects with their own "
                       "`shading` keep it).")] = None,
    specular: Annotated[SpecularModel | None, typer.Option(help="render.specular: phong (v·r) or "
                        "blinn (n·h).")] = None,
    mode: Annotated[Mode | None, typer.Option(help="render.mode: local (no shadows) or global.")] = None,
    width: Annotated[int | None, typer.Option(help="render.width in pixels, 1..16384.")] = None,
    height: Annotated[int | None, typer.Option(help="render.height in pixels, 1..16384.")] = None,
    samples: Annotated[int | None, typer.Option(help="render.samples: n → n×n rays per pixel, 1..16.")] = None,
    set_: SetOption = [],
    srgb: SrgbOption = False,
    threads: Annotated[int | None, typer.Option(min=1, max=64, help="Worker threads (default: cores).")] = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar and no summary line.")] = False,
    reference: Annotated[ReferenceKind | None, typer.Option(help="Also measure the render against the exact "
                         "surfaces (docs/accuracy.md): print RMSE, max error and PSNR beside the timing line.")] = None,
    max_memory: MaxMemoryOption = None,
    view: ViewOption = None,
    up: UpOption = None,
) -> None:
    """Render a scene file, a mesh file or the built-in default scene to a PNG or EXR image."""
    from raycast_phong.scene.overrides import SRGB_OVERRIDE
    overrides = [*scene_overrides({"render.shading": shading, "render.specular": specular, "render.mode": mode,
                                   "render.width": width, "render.height": height, "render.samples": samples}),
                 *([SRGB_OVERRIDE] if srgb else []), *set_]
    with exit_codes():
        started = time.perf_counter()
        path = scene or rp.default_scene_path()
        loaded = rp.load_scene(path, overrides, view=_view(view), up=up, max_memory=max_memory)
        load_seconds = time.perf_counter() - started
        from raycast_phong.scene.output import render_output
        output = render_output(loaded, Path(path), output, builtin=scene is None)
        if reference is not None:
            from raycast_phong.tools.reference import ExactScene
            ExactScene(loaded, str(path))  # a mesh has no closed form: refuse before rendering
        result = _render_with_progress(loaded, str(path), threads, quiet, max_memory)
        if reference is not None:
            from raycast_phong.tools.accuracy import measured
            result = measured(loaded, result, reference.value, 2, str(path))
        started = time.perf_counter()
        rp.write_image(output, result.image, result.aovs, colour=loaded.render.colour)
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


def _render_with_progress(scene: rp.Scene, source: str, threads: int | None, quiet: bool,
                          max_memory: int | None = None) -> rp.RenderResult:
    from raycast_phong.renderer.warmup import ready_kernels
    stage, seconds = ready_kernels(scene, None if quiet else lambda line: typer.echo(line, err=True), source)
    result = _render_shown(scene, source, threads, quiet, max_memory)
    result.timings[stage] = seconds
    return result


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


def error_line(errors, seconds: float) -> str:
    """One line: RMSE, max and PSNR against the reference, and the silhouette and highlight figures."""
    return (f"against the {errors.reference} reference: RMSE {errors.rmse:.5f}, max {errors.max_error:.4f}, "
            f"PSNR {errors.psnr:.1f} dB over {errors.compared_pixels:,} pixels both cover; "
            f"{errors.silhouette_pixels:,} silhouette pixels, highlight loss {errors.highlight_loss:.3f} "
            f"(reference {seconds:.3f}s)")


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
        loaded = rp.load_scene(path, set_, view=_view(view), up=up, max_memory=max_memory)
        # render's own preparation: the same memory check (before building anything), geometry and diagnosis.
        typer.echo(prepare(loaded, source=str(path), max_memory=max_memory).plan.describe())
