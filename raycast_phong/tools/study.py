"""Error against run time for the shading models: a sweep of renders measured against a reference.

For every combination of shading model × specular model × precision × samples × shininess ×
tessellation level: render (median time of `repeats`, the per-stage split kept), measure against the
reference (metrics.measure), and write DIR/study.csv, DIR/error_vs_time.png (matplotlib, optional) and
DIR/summary.md with the fitted convergence orders: the slope of log RMSE against log mean edge length.
"""

from __future__ import annotations

import copy
import csv
import io
import math
import statistics
import tempfile
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np

from ..io.atomic import write_bytes, write_text
from ..io.image_io import ImageError, check_output_file
from ..pipeline.geometry import build_geometry
from ..pipeline.mesh_scene import read_scene_dict
from ..pipeline.render import render
from ..pipeline.scene import (
    Scene,
    SceneError,
    ShadingModel,
    SpecularModel,
    validate_scene,
)
from .accuracy import mesh_coverage, reference_image, refine_entry
from .metrics import measure

THEORY = {"flat": 1.0, "gouraud": 2.0, "phong": 2.0}  # orders in the edge length h, smooth regions
PLOT_HINT = "pip install 'raycast-phong[plot]' (matplotlib) for error_vs_time.png"


@dataclass(frozen=True)
class StudyOptions:
    """What to sweep; None keeps the scene's own value."""
    levels: tuple[int, ...] = (0, 1, 2, 3)
    models: tuple[ShadingModel, ...] = (ShadingModel.FLAT, ShadingModel.GOURAUD, ShadingModel.PHONG)
    speculars: tuple[SpecularModel, ...] | None = None
    precisions: tuple[str, ...] | None = None
    samples: tuple[int, ...] | None = None
    shininess: tuple[float, ...] | None = None  # every material's f (and the default material's)
    repeats: int = 3
    fine: int | None = None                     # self-convergence reference this many levels finer
    target: float = 0.005                       # the RMSE the advice in summary.md asks for
    threads: int | None = None
    max_memory: int | None = None               # render()'s memory budget, bytes (default: its own)


@dataclass(frozen=True)
class StudyRow:
    """One render of the sweep: its settings, mesh, median timings (seconds) and errors."""
    model: str
    specular: str
    precision: str
    samples: int
    shininess: str          # "scene" when the materials keep their own
    level: int
    triangles: int
    edge_length: float      # mean length of the scene mesh's edges, world units
    seconds: float          # median frame time: rays + shading (the cost of one more frame)
    seconds_total: float    # median of geometry + BVH build + frame
    geometry_seconds: float
    build_seconds: float
    rays_seconds: float     # summed over worker threads, like RenderResult.timings
    shade_seconds: float
    rmse: float
    max_error: float
    psnr: float
    mae: float
    silhouette_pixels: int
    highlight_loss: float
    compared_pixels: int
    reference: str


@dataclass(frozen=True)
class Fit:
    """Slope of log RMSE against log edge length over one curve's levels."""
    model: str
    group: str              # the other settings of the curve, e.g. "phong specular, float32, 1 spp, f=100"
    order: float
    levels: int

    @property
    def theory(self) -> float:
        return THEORY[self.model]


@dataclass
class Study:
    rows: list[StudyRow]
    fits: list[Fit] = field(default_factory=list)
    scene: str = "<scene>"
    target: float = 0.005


# ---------------------------------------------------------------- scenes of the sweep

def scene_data(path: str | Path, overrides: list[str] | tuple[str, ...] = ()) -> dict:
    """The scene (or mesh) file parsed, with `--set` overrides applied (validated later, per combination)."""
    return read_scene_dict(Path(path), overrides)


def variant(base: Scene, data: dict, *, model: str, specular: str, precision: str, samples: int,
            shininess: float | None, level: int, folder: str, source: str) -> Scene:
    """The base scene with every object at `level` and shaded with `model`, and the render keys set.

    Mesh files are Loop-subdivided `level` times into `folder` (level 0: the file as it is).
    """
    data = copy.deepcopy(data)
    data.setdefault("render", {}).update(shading=model, specular=specular, precision=precision, samples=samples)
    data["objects"] = [dict(entry) for entry in data.get("objects", [])]
    for index, entry in enumerate(data["objects"]):
        entry["shading"] = model  # an object's own shading would otherwise keep it out of the sweep
        refine_entry(base, index, entry, level, level, Path(folder), source)
    if shininess is not None:
        materials = {name: dict(values) for name, values in data.get("materials", {}).items()}
        for values in materials.values():
            values["shininess"] = shininess
        if any(obj.material == "default" for obj in base.objects):
            materials.setdefault("default", {})["shininess"] = shininess
        data["materials"] = materials
    return validate_scene(data, source=source, folder=base.folder)


def mean_edge_length(scene: Scene, source: str) -> float:
    """Mean length of the unique edges of the scene's triangles (world units)."""
    geometry = build_geometry(scene, source=source, vertex_normals=False)
    edges = np.sort(geometry.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    edges = np.unique(edges, axis=0)
    return float(np.linalg.norm(geometry.vertices[edges[:, 0]] - geometry.vertices[edges[:, 1]], axis=1).mean())


# ---------------------------------------------------------------- the sweep

def _check_options(base: Scene, options: StudyOptions, source: str) -> None:
    """A mesh needs a self-convergence reference (--fine); every axis needs a value."""
    if options.fine is None:
        for index, obj in enumerate(base.objects):
            if obj.shape == "mesh":
                raise SceneError(f'{source}: objects.{index}.shape: "mesh" has no closed form; use --fine N')
    if options.repeats < 1 or not options.levels or not options.models:
        raise SceneError(f"{source}: the study needs at least one level, one model and one repeat")


def run_study(path: str | Path, overrides: list[str] | tuple[str, ...] = (), options: StudyOptions = StudyOptions(),
              progress: Callable[[int, int, str], None] | None = None) -> Study:
    """Render and measure every combination; the reference is computed once per (specular, samples, f)."""
    source = str(path)
    data = scene_data(path, overrides)
    base = validate_scene(data, source=source, folder=Path(path).parent)
    _check_options(base, options, source)
    speculars = [s.value if hasattr(s, "value") else s for s in (options.speculars or (base.render.specular,))]
    precisions = list(options.precisions or (base.render.precision,))
    samples_list = list(options.samples or (base.render.samples,))
    shininess_list = list(options.shininess or (None,))
    models = [m.value if hasattr(m, "value") else m for m in options.models]
    # Every model at one setting is timed round-robin, repeat by repeat, so a machine that slows down
    # for a while slows all models alike instead of whichever happened to run then.
    groups = [(f, spec, n, prec, level) for f in shininess_list for spec in speculars for n in samples_list
              for prec in precisions for level in options.levels]
    total_renders = len(groups) * len(models)
    rows = []
    with tempfile.TemporaryDirectory(prefix="raycast-phong-study-") as folder:
        def make(**keys) -> Scene:
            return variant(base, data, folder=folder, source=source, **keys)

        # Compile the shading kernels for every precision before any timed render.
        for prec in precisions:
            warm = make(model=models[0], specular=speculars[0], precision=prec, samples=1,
                        shininess=shininess_list[0], level=min(options.levels))
            render(validate_scene({**warm.model_dump(exclude={"folder"}), "render": {
                **warm.render.model_dump(), "width": 8, "height": 8}}, source=source, folder=warm.folder))

        references, meshes = {}, {}
        for done, (f, spec, n, prec, level) in enumerate(groups):
            if progress:
                progress(done * len(models), total_renders, f"level {level}")
            scenes = {model: make(model=model, specular=spec, precision=prec, samples=n, shininess=f, level=level)
                      for model in models}
            first = scenes[models[0]]
            if (spec, n, f) not in references:
                # The reference depends on neither the model, the precision nor the level.
                references[spec, n, f] = reference_image(first, source, fine=options.fine)
            if (n, level) not in meshes:
                meshes[n, level] = (mesh_coverage(first, source), mean_edge_length(first, source))
            coverage, edge = meshes[n, level]
            runs = {model: [] for model in models}
            for _ in range(options.repeats):
                for model in models:
                    runs[model].append(render(scenes[model], threads=options.threads, source=source,
                                              max_memory=options.max_memory))
            for model in models:
                errors = measure(runs[model][-1].image, coverage, references[spec, n, f])
                rows.append(study_row(runs[model], errors, model=model, specular=spec, precision=prec, samples=n,
                                      shininess="scene" if f is None else f"{f:g}", level=level, edge_length=edge))
        if progress:
            progress(total_renders, total_renders, "done")
    return Study(rows, fit_orders(rows), source, options.target)


def study_row(results: list, errors, **setting) -> StudyRow:
    """One row: a setting's repeated renders (medians of their stage times; time to image = geometry + BVH +
    frame) and the last render's errors against the reference."""
    timing = {stage: statistics.median(r.timings.get(stage, 0.0) for r in results)
              for stage in ("geometry", "build", "rays", "shade", "frame")}
    total = statistics.median(r.timings["geometry"] + r.timings["build"] + r.timings["frame"] for r in results)
    return StudyRow(**setting, triangles=results[-1].triangles, seconds=timing["frame"], seconds_total=total,
                    geometry_seconds=timing["geometry"], build_seconds=timing["build"],
                    rays_seconds=timing["rays"], shade_seconds=timing["shade"], rmse=errors.rmse,
                    max_error=errors.max_error, psnr=errors.psnr, mae=errors.mae,
                    silhouette_pixels=errors.silhouette_pixels, highlight_loss=errors.highlight_loss,
                    compared_pixels=errors.compared_pixels, reference=errors.reference)


def curve_key(row: StudyRow) -> tuple:
    return (row.model, row.specular, row.precision, row.samples, row.shininess)


def group_label(row: StudyRow) -> str:
    f = "" if row.shininess == "scene" else f", f={row.shininess}"
    return f"{row.specular} specular, {row.precision}, {row.samples} spp{f}"


def fit_orders(rows: list[StudyRow]) -> list[Fit]:
    """Least-squares slope of log RMSE against log edge length, one per curve (≥ 2 distinct levels)."""
    curves: dict[tuple, list[StudyRow]] = {}
    for row in rows:
        curves.setdefault(curve_key(row), []).append(row)
    fits = []
    for key, curve in curves.items():
        usable = [r for r in curve if r.rmse > 0 and math.isfinite(r.rmse)]
        if len({r.edge_length for r in usable}) < 2:
            continue
        slope = np.polyfit(np.log([r.edge_length for r in usable]), np.log([r.rmse for r in usable]), 1)[0]
        fits.append(Fit(key[0], group_label(curve[0]), float(slope), len(usable)))
    return fits


# ---------------------------------------------------------------- output

CSV_COLUMNS = [f.name for f in fields(StudyRow)]


def write_csv(study: Study, path: Path) -> None:
    """One line per render; floats as repr, so they read back exactly. Raises WriteError."""
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, CSV_COLUMNS)
    writer.writeheader()
    for row in study.rows:
        writer.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in asdict(row).items()})
    write_text(path, text.getvalue())


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def write_plot(study: Study, path: Path) -> bool:
    """Log RMSE against log frame time, one curve per model (and setting), points labelled with triangles.

    Returns False (and writes nothing) when matplotlib is not installed. Raises WriteError.
    """
    try:
        import matplotlib
        matplotlib.use("Agg")  # files only, never a window
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    curves: dict[tuple, list[StudyRow]] = {}
    for row in study.rows:
        curves.setdefault(curve_key(row), []).append(row)
    groups = sorted({group_label(c[0]) for c in curves.values()})
    colours = {"flat": "tab:blue", "gouraud": "tab:orange", "phong": "tab:green"}
    styles = ["-", "--", ":", "-."]
    markers = ["o", "s", "^", "D", "v", "P"]
    figure, axes = plt.subplots(figsize=(7.5, 5.5), dpi=110)
    for key, curve in curves.items():
        curve = sorted((r for r in curve if r.rmse > 0 and math.isfinite(r.rmse)), key=lambda r: r.level)
        if not curve:
            continue
        g = groups.index(group_label(curve[0]))
        label = key[0] + (f" ({group_label(curve[0])})" if len(groups) > 1 else "")
        axes.plot([r.seconds * 1e3 for r in curve], [r.rmse for r in curve], styles[g % 4],
                  marker=markers[g % 6], color=colours.get(key[0], "black"), label=label)
        for r in curve:
            axes.annotate(f"{r.triangles:,}", (r.seconds * 1e3, r.rmse), textcoords="offset points",
                          xytext=(4, 4), fontsize=7, color=colours.get(key[0], "black"))
    axes.set_xscale("log")
    axes.set_yscale("log")
    axes.set_xlabel("frame time, ms (median; rays + shading)")
    axes.set_ylabel("RMSE against the reference (pixels both cover)")
    axes.set_title(f"Work-precision: {Path(study.scene).name}; points labelled with triangle counts", fontsize=10)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=8)
    figure.tight_layout()
    encoded = io.BytesIO()  # encode in memory: the file itself is written, checked and renamed by write_bytes
    figure.savefig(encoded, format="png")
    plt.close(figure)
    write_bytes(path, encoded.getvalue())
    return True


def cheapest(rows: list[StudyRow], target: float) -> dict[str, StudyRow | None]:
    """Per model, the render with the fewest triangles (then the shortest frame) with RMSE ≤ target.

    Fewest triangles rather than fastest: at these image sizes frame times differ by less than their
    run-to-run noise, while the triangle count is exact.
    """
    best: dict[str, StudyRow | None] = {}
    for row in rows:
        best.setdefault(row.model, None)
        known = best[row.model]
        if row.rmse <= target and (known is None or (row.triangles, row.seconds) < (known.triangles, known.seconds)):
            best[row.model] = row
    return best


def advice(study: Study, target: float | None = None) -> str:
    """'To reach RMSE 0.005 on this scene: flat needs N triangles and X ms, …', one sentence per setting."""
    target = study.target if target is None else target
    groups: dict[str, list[StudyRow]] = {}
    for row in study.rows:
        groups.setdefault(group_label(row), []).append(row)
    sentences = []
    for label, rows in groups.items():
        parts = []
        for model, row in cheapest(rows, target).items():
            mine = [r for r in rows if r.model == model]
            if row is None:
                best = min(mine, key=lambda r: r.rmse)
                parts.append(f"{model} does not get there within the levels tried (best RMSE {best.rmse:.4f} at "
                             f"{best.triangles:,} triangles, {best.seconds * 1e3:.1f} ms)")
            else:
                parts.append(f"{model} needs {row.triangles:,} triangles and {row.seconds * 1e3:.1f} ms "
                             f"(level {row.level}, RMSE {row.rmse:.4f})")
        where = f" ({label})" if len(groups) > 1 else ""
        sentences.append(f"To reach RMSE {target:g} on this scene{where}: " + "; ".join(parts) + ".")
    return "\n".join(sentences)


def summary_markdown(study: Study, plotted: bool) -> str:
    lines = [f"# Error against run time: {study.scene}", ""]
    lines += ["\n\n".join(advice(study).splitlines()), ""]
    lines += ["## Fitted convergence orders", "",
              "Slope of log RMSE against log mean edge length over the levels (least squares).", "",
              "| model | curve | measured order | theory | levels |", "|---|---|---:|---:|---:|"]
    lines += [f"| {f.model} | {f.group} | {f.order:.2f} | {f.theory:g} | {f.levels} |" for f in study.fits]
    lines += ["", "## Renders", "",
              "| model | specular | precision | spp | f | level | triangles | edge | ms | RMSE | max | PSNR dB "
              "| silhouette px | highlight loss |",
              "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in study.rows:
        lines.append(f"| {r.model} | {r.specular} | {r.precision} | {r.samples} | {r.shininess} | {r.level} | "
                     f"{r.triangles:,} | {r.edge_length:.4f} | {r.seconds * 1e3:.2f} | {r.rmse:.5f} | "
                     f"{r.max_error:.4f} | {r.psnr:.1f} | {r.silhouette_pixels} | {r.highlight_loss:.3f} |")
    lines += ["", "![error against time](error_vs_time.png)" if plotted else f"No plot: {PLOT_HINT}.", ""]
    return "\n".join(lines)


OUTPUTS = {"csv": "study.csv", "plot": "error_vs_time.png", "summary": "summary.md"}


def check_study_folder(folder: Path, scene: str | Path) -> None:
    """Refuse, before the first render, a --out that is a file or that holds a folder (or the scene) under
    one of the OUTPUTS' names. Raises ImageError."""
    if folder.exists() and not folder.is_dir():
        raise ImageError(f"{folder}: --out must be a folder, but it is a file")
    if folder.is_dir():
        for name in OUTPUTS.values():
            check_output_file(folder / name, inputs=(scene,))


def write_study(study: Study, folder: Path) -> dict[str, Path | None]:
    """DIR/study.csv, DIR/error_vs_time.png (None without matplotlib) and DIR/summary.md, each replaced
    atomically. Raises WriteError when one cannot be written (those before it are written, it is unchanged)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ImageError(f"{folder}: cannot create the output folder ({error.strerror})") from None
    written: dict[str, Path | None] = {key: folder / name for key, name in OUTPUTS.items()}
    write_csv(study, written["csv"])
    plotted = write_plot(study, written["plot"])
    if not plotted:
        written["plot"] = None
    write_text(written["summary"], summary_markdown(study, plotted))
    return written
