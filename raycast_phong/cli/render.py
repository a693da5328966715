"""`render` and `plan`: one scene to an image, and what its render would do."""

from __future__ import annotations

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
    check_verbosity,
    exit_codes,
    note,
    quiet_option,
    scene_overrides,
    verbose_option,
    warn,
)
from .progress import progress_bar


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
    quiet: Annotated[bool, quiet_option("progress bar, notes, summary line or reference line")] = False,
    verbose: Annotated[bool, verbose_option("the render plan: each stage kept or left out, and why (as `plan` "
                       "prints it)")] = False,
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
    check_verbosity(quiet, verbose)
    with exit_codes():
        from raycast_phong.compiles import seconds_compiling
        started, compiled_before = time.perf_counter(), seconds_compiling()
        path = scene or rp.default_scene_path()
        with progress_bar(quiet) as bar:  # a large mesh file is read to frame it: seconds
            bar.update(0, None, "loading the scene")
            loaded = rp.load_scene(path, overrides, view=_view(view), up=up, max_memory=max_memory)
        say_kept_shading(loaded, shading, set_, quiet)
        # A mesh reader's kernels compile while the scene loads: that time is reported as `compile`, not `load`.
        reader_compile = seconds_compiling() - compiled_before
        load_seconds = time.perf_counter() - started - reader_compile
        from raycast_phong.scene.output import render_output
        output = render_output(loaded, Path(path), output, builtin=scene is None)
        if reference is not None:
            from raycast_phong.tools.reference import ExactScene
            ExactScene(loaded)  # a mesh has no closed form: refuse before rendering
        result = _render_with_progress(loaded, threads, quiet, max_memory)
        if reference is not None:
            from raycast_phong.tools.accuracy import measured
            result = measured(loaded, result, reference.value, 2)
        started = time.perf_counter()
        rp.write_image(output, result.image, result.aovs, colour=loaded.render.colour)
        result = result.with_timings(write=time.perf_counter() - started, load=load_seconds)
        if reader_compile > 0:
            result = result.with_timings(compile=result.timings.get("compile", 0.0) + reader_compile)
    for warning in result.plan.warnings:  # a warning is said under -q too; a note is information
        warn(warning)
    if not quiet:
        for line in result.plan.notes:
            note(line)
        if verbose:
            typer.echo(result.plan.describe())
        typer.echo(summary_line(result, output))
        if reference is not None:
            typer.echo(error_line(result.errors, result.reference_seconds))


def _render_with_progress(scene: rp.Scene, threads: int | None, quiet: bool,
                          max_memory: int | None = None) -> rp.RenderResult:
    from raycast_phong.renderer.fit import fitted
    fitted(scene, None, threads, max_memory)  # a refused scene loads neither numba nor a kernel: it compiles nothing
    from raycast_phong.renderer.prepare import Renderer
    from raycast_phong.renderer.warmup import ready_kernels
    session = Renderer(threads=threads, max_memory=max_memory)
    stage, seconds = ready_kernels(scene, None if quiet else lambda line: typer.echo(line, err=True))
    with progress_bar(quiet) as bar:  # over the tiles, on a terminal (cli.progress)
        bar.update(0, None, "building the geometry and the BVH")
        result = session.render(scene, progress=lambda done, total: bar.update(done, total, "rendering tiles"))
    return result.with_timings(**{stage: seconds})


def say_kept_shading(scene: rp.Scene, shading: ShadingModel | None, sets: list[str], quiet: bool) -> None:
    """--shading (or --set render.shading=…) changes no object that has its own `shading` key: a warning when
    that is every object (the option changed nothing: the image is the scene's own), else a note."""
    if shading is None and not any(s.replace(" ", "").startswith("render.shading=") for s in sets):
        return
    kept = own_shading(scene)
    if kept is None:
        return
    who, count, every = kept
    model = scene.render.shading.value
    asked = f"--shading {model}" if shading is not None else f"render.shading = {model}"
    if every:
        warn(f"{asked} changes nothing in this scene: every object keeps its own `shading` key, and {who} "
             f"{'is' if count == 1 else 'are'} not {model}; set objects.N.shading to change one")
    elif not quiet:
        note(f"{asked}: {who} {'keeps its' if count == 1 else 'keep their'} own `shading` key")


def own_shading(scene: rp.Scene) -> tuple[str, int, bool] | None:
    """The objects whose own `shading` key differs from render.shading, which therefore changes nothing for them:
    (their key paths as the plan's warnings word them, how many, whether no object follows render.shading at
    all), or None if render.shading is every object's model. One pass per kind of object."""
    import numpy as np

    from raycast_phong.renderer.diagnosis import named_objects, per_object
    model = scene.render.shading
    differ = per_object(scene, lambda obj: obj.shading is not None and obj.shading != model)
    if not differ.any():
        return None
    follows = per_object(scene, lambda obj: obj.shading is None)
    indices = np.flatnonzero(differ).tolist()
    return named_objects(indices), len(indices), not follows.any()


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
         view: ViewOption = None, up: UpOption = None,
         quiet: Annotated[bool, quiet_option("stages or notes (only the plan's warnings)")] = False,
         verbose: Annotated[bool, verbose_option("the geometry's size and how long preparing it took")] = False,
         ) -> None:
    """Print the render plan: each stage and term, kept or left out, and why; then what the geometry
    tells (repaired windings, highlights the render would miss)."""
    from raycast_phong.renderer.prepare import Renderer
    check_verbosity(quiet, verbose)
    with exit_codes():
        path = scene or rp.default_scene_path()
        loaded = rp.load_scene(path, set_, view=_view(view), up=up, max_memory=max_memory)
        say_kept_shading(loaded, None, set_, quiet)
        started = time.perf_counter()
        # render's own preparation: the same memory check (before building anything), geometry and diagnosis.
        with progress_bar(quiet) as bar:
            bar.update(0, None, "preparing the geometry")
            ready = Renderer(max_memory=max_memory).prepare(loaded)
        seconds = time.perf_counter() - started
    if quiet:
        for warning in ready.plan.warnings:
            typer.echo(f"warning   {warning}")
        return
    typer.echo(ready.plan.describe())
    if verbose:
        geometry = ready.geometry
        typer.echo(f"geometry  {len(loaded.objects):,} objects, {len(geometry.faces):,} triangles, "
                   f"{len(geometry.vertices):,} vertices; prepared in {seconds:.3f}s")
