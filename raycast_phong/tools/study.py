"""Error against the cost a user pays, for every setting that trades one for the other: a work-precision study.

The axes: tessellation level, shading model, vertex normals ("mean", "exact", …), precision, samples per
pixel, and (as different problems) the specular model and the shininess. Each setting is rendered once
for its errors against the reference (metrics.measure: the shading error over the pixels both cover, the
highlight loss; and against a supersampled reference, the silhouette and whole-image error), then timed:
every setting once per round in a shuffled order, `repeats` rounds, so a slow spell of the machine hits
different settings each round. A point's time to image is what was measured: the minimum and the median of
its whole render() calls (the Pareto front and the advice separate two points only when these ranges do not
overlap); the sum of its stages' minima is kept as a labelled lower bound.

The levels are either given or chosen (`levels=None`): one more level at a time until every curve's
fitted order (the slope of log RMSE against log edge length over its last three levels) has settled,
or the time budget is spent. study_report.py draws the fronts and writes report.html.
"""

from __future__ import annotations

import copy
import csv
import io
import itertools
import math
import os
import platform
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
import typing
from collections.abc import Callable
from contextlib import suppress
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np

from ..errors import OutputError
from ..io.atomic import write_text
from ..io.files import check_output_file
from ..io.system import usable_cores
from ..records import Geometry
from ..renderer.frame import render
from ..renderer.prepare import Renderer
from ..scene.load import read_scene_dict
from ..scene.objects import NormalsRule
from ..scene.schema import Scene, SceneError, ShadingModel, SpecularModel, validate_scene
from ..shapes import from_file
from .accuracy import max_level, mesh_coverage, reference_image, refine_entry
from .metrics import measure, rmse

THEORY = {"flat": 1.0, "gouraud": 2.0, "phong": 2.0}  # orders in the edge length h, smooth regions
FIT_WINDOW = 3           # the fitted order is the slope over a curve's last three levels
FIRST_AUTO_LEVEL = 1     # level 0 (an icosahedron, 20 triangles) is far from the asymptotic regime
AUTO_TRIANGLES = 2_000_000  # chosen levels stop before the scene would pass this many triangles
SUPERSAMPLING = 4        # the silhouette reference: samples per pixel side, at least 2× the largest swept
# The vertex normals the study can set on every built-in object: the scene format's, but a file's own.
NORMALS = tuple(n for n in typing.get_args(NormalsRule) if n != "file")


@dataclass(frozen=True)
class StudyOptions:
    """What to sweep; None keeps the scene's own value (levels None: choose them, see the module docstring)."""
    levels: tuple[int, ...] | None = (0, 1, 2, 3)
    models: tuple[ShadingModel, ...] = (ShadingModel.FLAT, ShadingModel.GOURAUD, ShadingModel.PHONG)
    speculars: tuple[SpecularModel, ...] | None = None
    precisions: tuple[str, ...] | None = None
    samples: tuple[int, ...] | None = None
    shininess: tuple[float, ...] | None = None  # every material's f (and the default material's)
    normals: tuple[str, ...] | None = None      # every built-in object's `normals` (a mesh keeps its own)
    repeats: int = 3
    budget: float = 120.0                       # seconds for choosing levels (levels None)
    settle: float = 0.1                         # an order has settled when its last two windows differ less
    fine: int | None = None                     # self-convergence reference this many levels finer
    target: float = 0.005                       # the RMSE the advice asks for
    error_level: int | None = None              # the level of the error images (default: the middle one)
    threads: int | None = None
    max_memory: int | None = None               # render()'s memory budget, bytes (default: its own)
    process_start: bool = True                  # time one command-line render in a new process (the advice)


@dataclass(frozen=True)
class StudyRow:
    """One setting of the sweep: its keys, mesh, timings (seconds; min over the rounds) and errors."""
    model: str
    normals: str
    specular: str
    precision: str
    samples: int
    shininess: str          # "scene" when the materials keep their own
    level: int
    triangles: int
    edge_length: float      # mean length of the scene mesh's edges, world units
    seconds_total: float    # seconds_total_measured made non-decreasing along its curve (monotone_times): a
                            # trend line for callers; the report draws and advises on the measured times
    seconds_total_measured: float  # time to image: the minimum of the whole render() call over the rounds
    seconds_total_median: float  # the median of the whole call: [measured, median] is the point's time range
    seconds_total_spread: float  # (median − min) / min of the whole call: how disturbed this point's runs were
    seconds_total_bound: float   # a lower bound, not a run: the sum of the stages' minima (study_row)
    cpu_seconds: float      # CPU time of the render() call over all its threads, min over the rounds
    seconds: float          # frame time (rays + shading), min over the rounds: the cost of one more frame
    seconds_median: float   # the frame time's median
    seconds_spread: float
    geometry_seconds: float  # pooled minimum (pooled_minima); the stages below: min over the rounds
    build_seconds: float
    diagnosis_seconds: float  # the plan's diagnosis: the Gouraud and sub-pixel highlight checks (prepare's timing)
    rest_seconds: float     # the rest of the call: plan, memory check, shading inputs, film; negative when the BVH
                            # was built alongside the normals (prepare's build_ahead), overlapping the geometry
    rays_seconds: float     # summed over worker threads, like RenderResult.timings
    shade_seconds: float
    repeats: int
    rmse: float             # shading error: against the reference at the same samples, pixels both cover fully
    max_error: float
    psnr: float
    mae: float
    silhouette_pixels: int
    highlight_loss: float
    compared_pixels: int
    image_rmse: float       # every pixel, against the supersampled reference: what a viewer sees
    silhouette_rmse: float  # the pixels either image covers only partly (or one covers and the other not)
    reference: str


@dataclass(frozen=True)
class Fit:
    """Slope of log RMSE against log edge length for one curve: over its last FIT_WINDOW levels (`order`,
    the asymptotic one) and over all (`order_all`); `settled` when three successive windows agree (fit_orders)."""
    model: str
    group: str              # the curve's other settings, e.g. "exact normals, phong specular, float32, 1 spp, f=100"
    order: float
    order_all: float
    levels: int
    settled: bool
    previous: float         # the order over the window one level before (nan with fewer than FIT_WINDOW + 1)
    key: tuple = ()

    @property
    def theory(self) -> float:
        return THEORY[self.model]


@dataclass(frozen=True)
class ErrorImage:
    """One model's render, its reference and their per-pixel difference at the error-image level, cropped to
    the objects."""
    model: str
    level: int
    triangles: int
    problem: str            # problem_label of its row: one error image per model and problem
    image: np.ndarray
    reference: np.ndarray
    difference: np.ndarray  # (H, W) max over RGB of |render − reference|
    scale: float            # the heat map's top: the largest difference over the pixels both cover fully


@dataclass(frozen=True)
class MachineNoise:
    """How quiet the machine was while the study timed: the spread of the rounds and the load."""
    cpus: int
    load_before: tuple[float, float, float]
    load_after: tuple[float, float, float]
    median_spread: float    # median over the settings of (median − min) / min of the time to image
    worst_spread: float
    rounds: int
    timing_seconds: float   # wall time of the timing rounds

    def sentence(self) -> str:
        return (f"{self.rounds} interleaved rounds on {self.cpus} CPUs; load average {self.load_before[0]:.2f} "
                f"before and {self.load_after[0]:.2f} after; a point's median run was {100 * self.median_spread:.0f}"
                f" % slower than its fastest (median over the points; worst {100 * self.worst_spread:.0f} %)")


@dataclass(frozen=True)
class Machine:
    """What a reader needs to reproduce the times: the CPU, the package, the command and the cost of a process
    start (None: not measured)."""
    cpu: str
    cores: int
    usable_cores: int       # the cores this process may run on (affinity)
    version: str
    python: str
    command: str            # the process's command line, shell-quoted
    folder: str             # the working directory the command ran in
    process_start: float | None = None  # seconds of one command-line render of an 8 × 8 image (process_start)

    def sentence(self) -> str:
        return (f"{self.cpu}, {self.cores} cores ({self.usable_cores} usable); raycast-phong {self.version}, "
                f"Python {self.python}; command: {self.command} (in {self.folder})")


def cpu_model() -> str:
    """The CPU's model name (/proc/cpuinfo on Linux, else platform's guess)."""
    with suppress(OSError):
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    return platform.processor() or platform.machine() or "unknown CPU"


def this_machine(process_start: float | None = None) -> Machine:
    """This process's Machine: the CPU, the cores, the versions, its command line and folder."""
    from .. import __version__
    return Machine(cpu_model(), os.cpu_count() or 1, usable_cores(), __version__, platform.python_version(),
                   shlex.join(sys.argv), os.getcwd(), process_start)


def process_start() -> float | None:
    """Seconds of one `raycast-phong render` of an 8 × 8 image in a new process: the interpreter, the imports and
    the kernels' loading that every command-line render pays beyond the in-process times of the study (None when
    it fails). Its scene and image go to a temporary folder, not the study's."""
    try:
        with tempfile.TemporaryDirectory(prefix="raycast-phong-start-") as folder:
            scene = Path(folder) / "start.toml"
            scene.write_text('[render]\nwidth = 8\nheight = 8\n[[objects]]\nshape = "icosphere"\n')
            began = time.perf_counter()
            done = subprocess.run([sys.executable, "-m", "raycast_phong.cli", "render", str(scene), "-q", "-o",
                                   str(Path(folder) / "start.png")], capture_output=True, timeout=600)
            took = time.perf_counter() - began
    except (OSError, subprocess.TimeoutExpired):  # no temporary folder, a full disk: the advice says "not measured"
        return None
    return took if done.returncode == 0 else None


@dataclass
class Study:
    rows: list[StudyRow]
    fits: list[Fit] = field(default_factory=list)
    scene: str = "<scene>"
    target: float = 0.005
    noise: MachineNoise | None = None
    images: list[ErrorImage] = field(default_factory=list)
    levels_note: str = ""   # how the levels were chosen
    shininess: float = math.nan  # the first object's f, when the sweep keeps the scene's own (orders plot)
    colour: str = "display"   # the scene's render.colour: how the report's pictures are encoded
    machine: Machine | None = None
    objects: tuple[tuple[str, str], ...] = ()  # (shape, normals rule) of each object of the scene (order_reason)


# ---------------------------------------------------------------- scenes of the sweep

def variant(base: Scene, data: dict, *, model: str, specular: str, precision: str, samples: int,
            shininess: float | None, level: int, folder: str, normals: str | None = None) -> Scene:
    """The base scene with every object at `level` and shaded with `model`, and the render keys set.

    Mesh files are Loop-subdivided `level` times into `folder` (level 0: the file as it is); `normals`, when
    given, is set on every built-in object.
    """
    data = copy.deepcopy(data)
    data.setdefault("render", {}).update(shading=model, specular=specular, precision=precision, samples=samples)
    data["objects"] = [dict(entry) for entry in data.get("objects", [])]
    for index, entry in enumerate(data["objects"]):
        entry["shading"] = model  # an object's own shading would otherwise keep it out of the sweep
        if normals is not None and not from_file(base.objects[index]):
            entry["normals"] = normals
        refine_entry(base, index, entry, level, level, Path(folder))
    if shininess is not None:
        materials = {name: dict(values) for name, values in data.get("materials", {}).items()}
        for values in materials.values():
            values["shininess"] = shininess
        if any(obj.material == "default" for obj in base.objects):
            materials.setdefault("default", {})["shininess"] = shininess
        data["materials"] = materials
    return validate_scene(data, source=base.origin, folder=base.folder)


def mean_edge_length(geometry: Geometry) -> float:
    """Mean length of the unique edges of the scene's triangles (world units)."""
    edges = np.sort(geometry.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    edges = np.unique(edges, axis=0)
    return float(np.linalg.norm(geometry.vertices[edges[:, 0]] - geometry.vertices[edges[:, 1]], axis=1).mean())


# ---------------------------------------------------------------- the sweep

@dataclass(frozen=True)
class Setting:
    """One point of the sweep: a problem (specular, f) and the user's choices for it."""
    model: str
    normals: str | None
    specular: str
    precision: str
    samples: int
    shininess: float | None
    level: int


def _check_options(base: Scene, options: StudyOptions) -> None:
    """A mesh needs a self-convergence reference (--fine); every axis needs a value."""
    if options.fine is None:
        for index, obj in enumerate(base.objects):
            if from_file(obj):
                raise SceneError('"mesh" has no closed form; use --fine N',
                                 base.origin.at("objects", index, "shape"))
    if options.repeats < 1 or (options.levels is not None and not options.levels) or not options.models:
        raise SceneError("the study needs at least one level, one model and one repeat", base.origin)
    if not options.budget > 0:
        raise SceneError(f"--budget must be a positive number of seconds, got {options.budget:g}", base.origin)


class _Sweep:
    """The state of one study: scenes, references and measured errors per setting."""

    def __init__(self, path: str | Path, overrides, options: StudyOptions, folder: str):
        self.data = read_scene_dict(path, overrides, max_memory=options.max_memory)  # validated later, per combination
        self.base = validate_scene(self.data, source=str(path), folder=Path(path).parent)
        _check_options(self.base, options)
        self.options, self.folder = options, folder
        self.renderer = Renderer(threads=options.threads, max_memory=options.max_memory)  # every measured render's
        self.models = [getattr(m, "value", m) for m in options.models]  # an enum by its value
        self.problems = [(getattr(s, "value", s), f) for f in (options.shininess or (None,))
                         for s in (options.speculars or (self.base.render.specular,))]
        self.choices = [(nrm, prec, n) for nrm in (options.normals or (None,))
                        for prec in (options.precisions or (self.base.render.precision,))
                        for n in (options.samples or (self.base.render.samples,))]
        self.supersampling = max(SUPERSAMPLING, 2 * max(n for _, _, n in self.choices))
        self.references: dict = {}
        self.meshes: dict = {}
        self.measured: dict[Setting, tuple] = {}   # setting -> (errors, image_rmse, silhouette_rmse, triangles)
        self.images: dict[Setting, tuple] = {}     # setting -> (image, reference image, coverage)
        self.render_seconds: dict[int, float] = {}  # level -> seconds its measuring renders took

    def scene(self, s: Setting, samples: int | None = None) -> Scene:
        return variant(self.base, self.data, model=s.model, specular=s.specular, precision=s.precision,
                       samples=s.samples if samples is None else samples, shininess=s.shininess, level=s.level,
                       folder=self.folder, normals=s.normals)

    def settings(self, level: int) -> list[Setting]:
        """Every setting at `level`; flat shading reads no vertex normals, so only with the first normals."""
        first = self.choices[0][0]
        return [Setting(m, nrm, spec, prec, n, f, level) for spec, f in self.problems
                for nrm, prec, n in self.choices for m in self.models if m != "flat" or nrm == first]

    def warm_up(self) -> None:
        """Compile the shading kernels for every precision before any timed render."""
        for _, prec, _ in self.choices:
            warm = self.scene(Setting(self.models[0], self.choices[0][0], self.problems[0][0], prec, 1,
                                      self.problems[0][1], 0))
            data = warm.model_dump(exclude={"folder"})
            data["render"].update(width=8, height=8)
            render(validate_scene(data, source=warm.origin, folder=warm.folder))

    def check_fits(self, level: int) -> None:
        """Refuse (SceneError) a level whose renders are over the memory budget, before anything is measured."""
        for s in self.settings(level):
            self.renderer.check_fits(self.scene(s))

    def reference(self, s: Setting, samples: int):
        """The reference of s's problem at `samples`, computed once: it depends on neither the model, the normals,
        the precision nor the level."""
        key = (s.specular, samples, s.shininess)
        if key not in self.references:
            self.references[key] = reference_image(self.scene(s, samples=samples), fine=self.options.fine)
        return self.references[key]

    def measure_level(self, level: int, keep_images: bool) -> None:
        """Render every setting at `level` once and measure it (the references are computed once per problem)."""
        for s in self.settings(level):
            scene = self.scene(s)
            reference, fine = self.reference(s, s.samples), self.reference(s, self.supersampling)
            if (s.samples, level) not in self.meshes:
                # One prepare (plan, memory check, geometry) serves both: the render's own triangles.
                ready = self.renderer.prepare(scene)
                self.meshes[s.samples, level] = (mesh_coverage(ready), mean_edge_length(ready.geometry))
            coverage, _ = self.meshes[s.samples, level]
            began = time.perf_counter()
            result = self.renderer.render(scene)
            self.render_seconds[level] = self.render_seconds.get(level, 0.0) + time.perf_counter() - began
            errors = measure(result.image, coverage, reference)
            both_full = (coverage == 1) & (fine.coverage == 1)
            both_empty = (coverage == 0) & (fine.coverage == 0)
            everywhere = np.ones(coverage.shape, bool)
            self.measured[s] = (errors, rmse(result.image, fine.image, everywhere),
                                rmse(result.image, fine.image, ~both_full & ~both_empty), result.triangles)
            first = self.settings(level)[0]  # every problem's images: at the first of the user's other choices
            if keep_images and (s.normals, s.precision, s.samples) == (first.normals, first.precision, first.samples):
                self.images[s] = (result.image, reference.image, coverage == 1, reference.coverage == 1)

    def time_all(self, settings: list[Setting], repeats: int,
                 progress: Callable[[int, int, str], None]) -> tuple[dict, MachineNoise]:
        """`repeats` rounds, every setting once per round, each round in its own shuffled order (seeded), so
        a slow spell hits different neighbours every round and the minimum escapes it; progress(renders done,
        renders in all, "timing round R of N") after each render."""
        scenes = {s: self.scene(s) for s in settings}
        runs: dict[Setting, list[tuple[float, dict]]] = {s: [] for s in settings}
        load_before, start = os.getloadavg(), time.perf_counter()
        for round_ in range(repeats):
            for position, index in enumerate(np.random.default_rng(round_).permutation(len(settings)), 1):
                s = settings[index]
                begin, cpu = time.perf_counter(), time.process_time()
                result = self.renderer.render(scenes[s])
                wall = time.perf_counter() - begin
                runs[s].append((wall, {**result.timings, "cpu": time.process_time() - cpu}))
                progress(round_ * len(settings) + position, repeats * len(settings),
                         f"timing round {round_ + 1} of {repeats}")
        spreads = [spread([wall for wall, _ in r]) for r in runs.values()]
        noise = MachineNoise(os.cpu_count() or 1, load_before, os.getloadavg(), statistics.median(spreads),
                             max(spreads), repeats, time.perf_counter() - start)
        return runs, noise


def spread(times: list[float]) -> float:
    """(median − min) / min: 0 for runs that all took the fastest run's time."""
    fastest = min(times)
    return (statistics.median(times) - fastest) / fastest if fastest > 0 else 0.0


def run_study(path: str | Path, overrides: list[str] | tuple[str, ...] = (), options: StudyOptions = StudyOptions(),
              progress: Callable[[int, int, str], None] | None = None) -> Study:
    """Measure every setting at the given (or chosen) levels, then time them all in interleaved rounds;
    progress(done, total, what) is called as each level starts ("level L": levels done of those known so far)
    and after each timing render ("timing round R of N": renders done of all), then with "done"."""
    progress = progress or (lambda done, total, what: None)
    with tempfile.TemporaryDirectory(prefix="raycast-phong-study-") as folder:
        sweep = _Sweep(path, overrides, options, folder)
        for level in sorted(set(options.levels or ()), reverse=True):  # a given level over the budget: refused
            sweep.check_fits(level)                                    # before anything compiles or is measured
        sweep.warm_up()
        levels, note = choose_levels(sweep, progress)
        settings = [s for level in levels for s in sweep.settings(level)]
        progress(0, len(settings) * options.repeats, "timing")
        runs, noise = sweep.time_all(settings, options.repeats, progress)
        pooled = pooled_minima(runs)
        rows = monotone_times([study_row(s, runs[s], *sweep.measured[s], sweep.meshes[s.samples, s.level][1], pooled)
                               for s in settings])
        started = process_start() if options.process_start else None  # after the rounds: not among them
        study = Study(rows, fit_orders(rows, options.settle), sweep.base.origin.file, options.target, noise,
                      levels_note=note, shininess=sweep.base.material_of(sweep.base.objects[0]).shininess
                      if sweep.base.objects else math.nan, colour=sweep.base.render.colour,
                      machine=this_machine(started),
                      objects=tuple((obj.shape, obj.normals or "mean") for obj in sweep.base.objects))
        study.images = error_images(sweep)
        progress(len(settings) * options.repeats, len(settings) * options.repeats, "done")
    return study


def choose_levels(sweep: _Sweep, progress) -> tuple[list[int], str]:
    """The given levels, measured; or levels added one at a time from FIRST_AUTO_LEVEL until every curve's
    order has settled, the budget would be spent (the next level's renders costing about 4× the last level's,
    and the timing rounds `repeats` × all of them), the shape's finest level or AUTO_TRIANGLES is reached."""
    options = sweep.options
    middle = options.error_level
    if options.levels is not None:
        levels = sorted(set(options.levels))
        keep = middle if middle in levels else levels[len(levels) // 2]
        for level in levels:
            progress(levels.index(level), len(levels), f"level {level}")
            sweep.measure_level(level, keep_images=level == keep)
        return levels, f"levels {', '.join(map(str, levels))} as given"
    finest = min((max_level(obj) for obj in sweep.base.objects), default=8)
    levels: list[int] = []
    start = time.perf_counter()
    why = "the finest level the scene format allows was reached"
    level = FIRST_AUTO_LEVEL
    while level <= finest:
        if levels:
            triangles = max(m[3] for s, m in sweep.measured.items() if s.level == levels[-1])
            if 4 * triangles > AUTO_TRIANGLES:
                why = f"the next level would pass {AUTO_TRIANGLES:,} triangles"
                break
            # Spent so far, the next level's renders (about 4× the last level's) and every level's timing rounds.
            renders = sum(sweep.render_seconds.values()) + 4 * sweep.render_seconds[levels[-1]]
            if time.perf_counter() - start + 4 * sweep.render_seconds[levels[-1]] + options.repeats * renders \
                    > options.budget:
                why = f"the next level would pass the budget of {options.budget:g} s"
                break
        progress(len(levels), len(levels) + 1, f"level {level}")
        sweep.check_fits(level)
        sweep.measure_level(level, keep_images=True)
        levels.append(level)
        level += 1
        if len(levels) > FIT_WINDOW:
            rows = [study_row(s, [(0.0, {})], *m, sweep.meshes[s.samples, s.level][1])  # untimed: for the fits
                    for s, m in sweep.measured.items()]
            fits = fit_orders(rows, options.settle)
            if fits and all(f.settled for f in fits):
                why = f"every order settled (its last three windows within {options.settle:g} of each other)"
                break
    keep = middle if middle in levels else levels[len(levels) // 2]
    for s in [s for s in sweep.images if s.level != keep]:
        del sweep.images[s]
    return levels, f"levels {levels[0]}–{levels[-1]} chosen: {why}"


def pooled_minima(runs: dict[Setting, list[tuple[float, dict]]]) -> dict[tuple, float]:
    """The fastest geometry and BVH stage over every setting that does the same work there: the geometry of
    one level, normals and need of vertex normals (flat needs none), the BVH of one level's vertices.

    A stage's minimum over 5 rounds can still sit inside a busy spell (a geometry stage measured 136, 336
    and 393 ms at one level for three shininesses); pooled over the settings that repeat it, it has 10-30
    runs to escape by. Model, precision, samples and shininess change neither stage.
    """
    pooled: dict[tuple, float] = {}
    for s, timed in runs.items():
        for key, stage in ((("geometry", s.level, s.normals, s.model == "flat"), "geometry"),
                           (("build", s.level), "build")):
            best = min(t.get(stage, math.inf) for _, t in timed)
            pooled[key] = min(pooled.get(key, math.inf), best)
    return pooled


def monotone_times(rows: list[StudyRow]) -> list[StudyRow]:
    """seconds_total: each curve's measured time to image made non-decreasing in the level (the least-squares
    monotone fit, pool adjacent violators), a trend line for callers (docs/tutorial.ipynb). More triangles never
    take less work, but levels a few ms apart can be measured in the wrong order; the report draws and advises
    on the measured times (seconds_total_measured and its median), never on this fit."""
    fitted: dict[int, float] = {}
    for curve in curves(rows).values():
        blocks: list[list] = []  # [mean, count] per pooled block
        for row in curve:
            blocks.append([row.seconds_total_measured, 1])
            while len(blocks) > 1 and blocks[-2][0] > blocks[-1][0]:
                mean, count = blocks.pop()
                blocks[-1] = [(blocks[-1][0] * blocks[-1][1] + mean * count) / (blocks[-1][1] + count),
                              blocks[-1][1] + count]
        values = [mean for mean, count in blocks for _ in range(count)]
        fitted.update({id(row): value for row, value in zip(curve, values)})
    return [replace(row, seconds_total=fitted[id(row)]) for row in rows]


def study_row(s: Setting, runs: list[tuple[float, dict]], errors, image_rmse: float, silhouette_rmse: float,
              triangles: int, edge_length: float, pooled: dict[tuple, float] | None = None) -> StudyRow:
    """One row: a setting's timed runs and its errors.

    Time to image = the minimum (and the median) of the whole render() call over the rounds: what a run took.
    The stages' minima are kept, with their sum as seconds_total_bound: the geometry and BVH pooled over the
    settings that repeat them (pooled_minima), the diagnosis, the frame and the rest of the call. Each minimum
    comes from its own round, so the sum is a lower bound no run reached (220 ms where no call was under 340);
    the rest is each run's wall less its named stages, minimised, so the bound never exceeds the fastest call.
    """
    walls = [wall for wall, _ in runs]
    frames = [t.get("frame", 0.0) for _, t in runs]
    named = ("geometry", "build", "diagnosis", "frame")
    stage = {name: min(t.get(name, 0.0) for _, t in runs)
             for name in ("geometry", "build", "diagnosis", "rays", "shade", "cpu")}
    rest = min(wall - sum(t.get(name, 0.0) for name in named) for wall, t in runs)  # < 0: BVH built alongside
    pooled = pooled or {}
    geometry = pooled.get(("geometry", s.level, s.normals, s.model == "flat"), stage["geometry"])
    build = pooled.get(("build", s.level), stage["build"])
    return StudyRow(model=s.model, normals=s.normals or "scene", specular=s.specular, precision=s.precision,
                    samples=s.samples, shininess="scene" if s.shininess is None else f"{s.shininess:g}",
                    level=s.level, triangles=triangles, edge_length=edge_length,
                    seconds_total=min(walls), seconds_total_measured=min(walls),
                    seconds_total_median=statistics.median(walls),
                    seconds_total_spread=spread(walls),
                    seconds_total_bound=geometry + build + stage["diagnosis"] + min(frames) + rest,
                    cpu_seconds=stage["cpu"], seconds=min(frames), seconds_median=statistics.median(frames),
                    seconds_spread=spread(frames),
                    geometry_seconds=geometry, build_seconds=build, diagnosis_seconds=stage["diagnosis"],
                    rest_seconds=rest, rays_seconds=stage["rays"], shade_seconds=stage["shade"], repeats=len(runs),
                    rmse=errors.rmse, max_error=errors.max_error, psnr=errors.psnr, mae=errors.mae,
                    silhouette_pixels=errors.silhouette_pixels, highlight_loss=errors.highlight_loss,
                    compared_pixels=errors.compared_pixels, image_rmse=image_rmse, silhouette_rmse=silhouette_rmse,
                    reference=errors.reference)


def error_images(sweep: _Sweep) -> list[ErrorImage]:
    """Per problem and model, at the kept level and the first of the user's other choices: render, reference,
    difference."""
    from .difference import difference
    out = []
    for s, (image, reference, covered, reference_covered) in sweep.images.items():
        diff = difference(image, reference).astype(np.float64)
        both = covered & reference_covered
        scale = float(diff[both].max()) if both.any() else float(diff.max())
        crop = _crop(covered | reference_covered | (diff > 0))
        shininess = "scene" if s.shininess is None else f"{s.shininess:g}"
        out.append(ErrorImage(s.model, s.level, sweep.measured[s][3], _problem_text(s.specular, shininess),
                              np.asarray(image, np.float64)[crop],
                              np.asarray(reference, np.float64)[crop], diff[crop], scale))
    return out


def _crop(mask: np.ndarray, margin: int = 4) -> tuple[slice, slice]:
    """The bounding box of `mask` widened by `margin` pixels (the whole image if the mask is empty), so the
    error images show the objects, not the background around them."""
    rows, columns = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not rows.size:
        return slice(None), slice(None)
    return (slice(max(rows[0] - margin, 0), rows[-1] + margin + 1),
            slice(max(columns[0] - margin, 0), columns[-1] + margin + 1))


# ---------------------------------------------------------------- curves, fits, fronts

def curve_key(row: StudyRow) -> tuple:
    return (row.model, row.normals, row.specular, row.precision, row.samples, row.shininess)


def group_label(row: StudyRow) -> str:
    f = "" if row.shininess == "scene" else f", f={row.shininess}"
    normals = "" if row.normals == "scene" else f"{row.normals} normals, "
    return f"{normals}{row.specular} specular, {row.precision}, {row.samples} spp{f}"


def problem_label(row: StudyRow) -> str:
    return _problem_text(row.specular, row.shininess)


def _problem_text(specular: str, shininess: str) -> str:
    return f"{specular} specular" + ("" if shininess == "scene" else f", f = {shininess}")


def setting_label(row: StudyRow) -> str:
    """A point's choices, short: 'phong L3 exact f32 1spp'."""
    normals = "" if row.normals == "scene" else f" {row.normals}"
    return f"{row.model} L{row.level}{normals} {row.precision.replace('float', 'f')} {row.samples}spp"


def _grouped(rows: list[StudyRow], key: Callable[[StudyRow], tuple]) -> dict[tuple, list[StudyRow]]:
    out: dict[tuple, list[StudyRow]] = {}
    for row in rows:
        out.setdefault(key(row), []).append(row)
    return out


def curves(rows: list[StudyRow]) -> dict[tuple, list[StudyRow]]:
    """Rows by curve, each sorted by level."""
    return {key: sorted(curve, key=lambda r: r.level) for key, curve in _grouped(rows, curve_key).items()}


def slope(curve: list[StudyRow]) -> float:
    usable = [r for r in curve if r.rmse > 0 and math.isfinite(r.rmse)]
    if len({r.edge_length for r in usable}) < 2:
        return math.nan
    return float(np.polyfit(np.log([r.edge_length for r in usable]), np.log([r.rmse for r in usable]), 1)[0])


def fit_orders(rows: list[StudyRow], settle: float = 0.1) -> list[Fit]:
    """Per curve (≥ 2 levels): the order over its last FIT_WINDOW levels and over all. Settled when the last
    three windows (each one level finer) give orders within `settle` of each other: two windows alone can
    agree on a pre-asymptotic plateau (the exact sphere's Phong gives 1.76, 1.77, then 1.97, 2.02)."""
    fits = []
    for key, curve in curves(rows).items():
        usable = [r for r in curve if r.rmse > 0 and math.isfinite(r.rmse)]
        if len({r.edge_length for r in usable}) < 2:
            continue
        windows = [slope(usable[len(usable) - FIT_WINDOW - back:len(usable) - back]) for back in range(3)
                   if len(usable) - FIT_WINDOW - back >= 0]
        settled = len(windows) == 3 and max(windows) - min(windows) <= settle
        previous = windows[1] if len(windows) > 1 else math.nan
        fits.append(Fit(key[0], group_label(curve[0]), slope(usable[-FIT_WINDOW:]), slope(usable), len(usable),
                        bool(settled), previous, key))
    return fits


def local_orders(curve: list[StudyRow]) -> list[tuple[StudyRow, float]]:
    """The slope between each pair of successive levels, at the finer one."""
    return [(fine, math.log(fine.rmse / coarse.rmse) / math.log(fine.edge_length / coarse.edge_length))
            for coarse, fine in itertools.pairwise(curve)
            if coarse.rmse > 0 and fine.rmse > 0 and fine.edge_length != coarse.edge_length]


RANGES = {"seconds_total_measured": "seconds_total_median", "seconds": "seconds_median"}  # cost -> its median


def time_range(row: StudyRow, cost: str = "seconds_total_measured") -> tuple[float, float]:
    """A point's measured time as a range: its fastest run to its median run (RANGES)."""
    low = getattr(row, cost)
    return low, max(low, getattr(row, RANGES.get(cost, cost)))


def clearly_faster(a: StudyRow, b: StudyRow, cost: str = "seconds_total_measured") -> bool:
    """Whether a's median run beat b's fastest: their time ranges do not overlap, the order is the settings'."""
    return time_range(a, cost)[1] < time_range(b, cost)[0]


def pareto_front(rows: list[StudyRow], error: str = "rmse", cost: str = "seconds_total_measured") -> list[StudyRow]:
    """The settings no other setting beats in error while being clearly faster (clearly_faster), fastest first.

    Two points whose time ranges overlap are not ordered in time, so neither drops the other.
    """
    usable = [r for r in rows if math.isfinite(getattr(r, error))]
    front = [r for r in usable if not any(q is not r and getattr(q, error) <= getattr(r, error)
                                          and clearly_faster(q, r, cost) for q in usable)]
    return sorted(front, key=lambda r: (getattr(r, cost), getattr(r, error)))


def problems(rows: list[StudyRow]) -> dict[tuple, list[StudyRow]]:
    """Rows by problem, what the scene asks (the reference): the specular model and the shininess."""
    return _grouped(rows, lambda row: (row.specular, row.shininess))


def fastest(rows: list[StudyRow], target: float) -> StudyRow | None:
    """The setting with the shortest measured time to image (its fastest run) whose shading RMSE is at most
    `target`; as_fast gives those the timing rounds cannot tell from it."""
    reaching = [r for r in rows if r.rmse <= target]
    return min(reaching, key=lambda r: r.seconds_total_measured) if reaching else None


def as_fast(rows: list[StudyRow], best: StudyRow, target: float) -> list[StudyRow]:
    """The other settings reaching `target` whose time range overlaps best's: as fast within the spread."""
    return [r for r in rows if r is not best and r.rmse <= target and not clearly_faster(best, r)]


def ms(row: StudyRow, cost: str = "seconds_total_measured") -> str:
    """A point's time range in ms, '10.0–11.2 ms' (min–median of its runs)."""
    low, high = (1e3 * t for t in time_range(row, cost))
    digits = 0 if low >= 100 else 1
    return f"{low:.{digits}f}–{high:.{digits}f} ms"


STALL = 0.8     # the whole-image RMSE "stops falling" when a level keeps more than this share of it (aliasing)


def aliasing(rows: list[StudyRow]) -> tuple[StudyRow, StudyRow] | None:
    """At 1 sample per pixel, on the curve with the lowest finest shading error: the first two successive levels
    where the whole-image RMSE keeps more than STALL of itself while the shading RMSE still falls by a third.
    What is left is the aliasing of the silhouette, which a finer mesh does not remove."""
    ones = [c for c in curves([r for r in rows if r.samples == 1]).values() if len(c) >= 2]
    if not ones:
        return None
    curve = min(ones, key=lambda c: c[-1].rmse)
    return next(((a, b) for a, b in itertools.pairwise(curve)
                 if b.image_rmse > STALL * a.image_rmse and b.rmse < 2 / 3 * a.rmse), None)


def advice(study: Study, target: float | None = None) -> str:
    """What a user acts on, per problem: the fastest setting to RMSE `target` and those the timing rounds cannot
    tell from it, each model's own fastest (times as measured: min–median of the whole call, no difference
    smaller than the spread quoted), where more levels stop helping the whole image (aliasing), the Gouraud
    check's own cost, and what a command-line render pays on top (a process start)."""
    target = study.target if target is None else target
    groups = problems(study.rows)
    sentences = []
    for rows in groups.values():
        where = f" ({problem_label(rows[0])})" if len(groups) > 1 else ""
        best = fastest(rows, target)
        if best is None:
            top = min(rows, key=lambda r: r.rmse)
            sentences.append(f"No setting reaches RMSE {target:g}{where}: the best is {setting_label(top)} with "
                             f"{top.rmse:.4f} ({top.triangles:,} triangles, {ms(top)} to image).")
        else:
            parts = []
            for model in dict.fromkeys(r.model for r in rows):
                mine = fastest([r for r in rows if r.model == model], target)
                if mine is None:
                    top = min((r for r in rows if r.model == model), key=lambda r: r.rmse)
                    parts.append(f"{model} does not get there within the levels tried (best {top.rmse:.4f} at "
                                 f"{top.triangles:,} triangles)")
                else:
                    tie = " (as fast, within the spread)" if mine is not best and not clearly_faster(best, mine) \
                        else ""
                    parts.append(f"{model} {ms(mine)} ({setting_label(mine)}, {mine.triangles:,} triangles){tie}")
            ties = as_fast(rows, best, target)
            tied = "" if not ties else (
                f"; as fast within the timing spread: {', '.join(setting_label(r) for r in ties[:4])}"
                + (f" and {len(ties) - 4} more" if len(ties) > 4 else ""))
            sentences.append(f"Fastest to RMSE {target:g}{where}: {setting_label(best)}, {best.triangles:,} triangles, "
                             f"{ms(best)} to image (RMSE {best.rmse:.4f}){tied}. Per model: " + "; ".join(parts) + ".")
        stalled = aliasing(rows)
        if stalled:
            a, b = stalled
            sentences.append(
                f"At 1 sample per pixel{where} the whole-image RMSE stops falling after level {a.level} "
                f"({a.model}: {a.image_rmse:.2g} at level {a.level}, {b.image_rmse:.2g} at level {b.level}) while the "
                f"shading RMSE still falls ({a.rmse:.2g} → {b.rmse:.2g}): what is left is the silhouette's aliasing, "
                "which a finer mesh does not remove; more samples per pixel do (render.samples, study --samples 1,2).")
    gouraud = [r for r in study.rows if r.model == "gouraud"]
    if gouraud:
        top = max(gouraud, key=lambda r: (r.level, -r.samples))
        others = [r for r in study.rows if r.model != "gouraud" and curve_key(r)[1:] == curve_key(top)[1:]
                  and r.level == top.level]
        beside = "; " + ", ".join(f"{r.model}'s {r.diagnosis_seconds * 1e3:.1f} ms" for r in others) if others else ""
        sentences.append("Gouraud's times include the plan's Gouraud check (the diagnosis that warns when the vertex "
                         f"normals are farther apart than the highlight is wide): {top.diagnosis_seconds * 1e3:.1f} ms "
                         f"of {ms(top)} at level {top.level} ({top.triangles:,} triangles){beside}.")
    started = study.machine.process_start if study.machine else None
    sentences.append("Every time here is in-process: a render() call with the kernels already compiled. A command-line "
                     "render also pays a process start (the interpreter, the imports, the kernels' loading): "
                     + (f"{started:.2f} s for one `raycast-phong render` of an 8 × 8 image on this machine."
                        if started is not None else "not measured in this study."))
    return "\n".join(sentences)


FAR = 0.15       # an order this far from theory is explained beside it (order_reason)
CROSSOVER = 0.4  # h·√f below which the edges resolve the highlight (docs/accuracy.md, Gouraud's crossover)


def highlight_widths(row: StudyRow, scene_shininess: float) -> float:
    """The edge length in highlight widths: h √f (the highlight is about 1/√f radians wide on a unit sphere)."""
    f = scene_shininess if row.shininess == "scene" else float(row.shininess)
    return row.edge_length * math.sqrt(f) if f > 0 and math.isfinite(f) else row.edge_length


def order_reason(fit: Fit, study: Study) -> str:
    """Why a fitted order is more than FAR from theory, from what the study knows (docs/accuracy.md has each
    measurement): a highlight narrower than the edges, averaged normals at an icosahedron's seams, samples
    averaging facets, or an order still moving; empty when the order is near theory."""
    if not math.isfinite(fit.order) or abs(fit.order - fit.theory) <= FAR:
        return ""
    finest = curves(study.rows)[fit.key][-1] if fit.key else None
    if finest is None:
        return ""
    widths = highlight_widths(finest, study.shininess)
    rules = {finest.normals} if finest.normals != "scene" else {rule for _, rule in study.objects}
    averaged = sorted(rules - {"exact"})
    if fit.model != "phong" and fit.order < fit.theory and widths > CROSSOVER:
        return (f"pre-asymptotic: the highlight (about 1/√f wide) is still narrower than the edges, h·√f = "
                f"{widths:.2f} at the finest level, and {fit.model} sees it only through "
                f"{'vertices' if fit.model == 'gouraud' else 'one normal per facet'}; the order reaches theory once "
                f"h·√f is below about {CROSSOVER:g} (more levels)")
    if fit.model != "flat" and fit.order < fit.theory and averaged:
        return (f"averaged vertex normals (normals = {', '.join(averaged)}) are first-order where the facets change "
                "size or shape (an icosphere's seams, a strip one edge wide: the RMSE falls like h^1.5); --normals "
                "exact gives 2")
    if fit.model == "flat" and fit.order > fit.theory and finest.samples > 1:
        return (f"{finest.samples} × {finest.samples} samples average several facets in a pixel at fine levels, a "
                "better estimate than one facet's colour")
    if not fit.settled:
        moving = (f"{fit.levels} levels, too few to see it settle" if math.isnan(fit.previous)
                  else f"the order still moves between windows ({fit.previous:.2f} → {fit.order:.2f})")
        return f"not settled, pre-asymptotic: {moving}; add levels"
    return "no cause known to the study; see docs/accuracy.md"


# ---------------------------------------------------------------- output

CSV_COLUMNS = [f.name for f in fields(StudyRow)]


def write_csv(study: Study, path: Path) -> None:
    """One line per setting; floats as repr, so they read back exactly. Raises WriteError."""
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, CSV_COLUMNS)
    writer.writeheader()
    for row in study.rows:
        writer.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in asdict(row).items()})
    write_text(path, text.getvalue())


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def fits_table(study: Study) -> list[list[str]]:
    """Header and rows of the fitted-order table (summary.md and report.html), each order far from theory with
    its reason (order_reason)."""
    header = ["model", "curve", f"order (last {FIT_WINDOW} levels)", "theory", "why not theory", "window before",
              "all levels", "levels", "settled"]
    return [header] + [[f.model, f.group, f"{f.order:.2f}", f"{f.theory:g}", order_reason(f, study) or "–",
                        "–" if math.isnan(f.previous) else f"{f.previous:.2f}", f"{f.order_all:.2f}", str(f.levels),
                        "yes" if f.settled else "no"] for f in study.fits]


def rows_table(study: Study) -> list[list[str]]:
    header = ["model", "normals", "specular", "precision", "spp", "f", "level", "triangles", "edge",
              "ms to image, min", "median", "spread", "diagnosis ms", "frame ms", "rest ms",
              "lower bound ms (Σ stage minima)", "RMSE", "max", "PSNR dB", "silhouette RMSE", "image RMSE",
              "highlight loss"]
    return [header] + [[r.model, r.normals, r.specular, r.precision, str(r.samples), r.shininess, str(r.level),
                        f"{r.triangles:,}", f"{r.edge_length:.4f}", f"{r.seconds_total_measured * 1e3:.2f}",
                        f"{r.seconds_total_median * 1e3:.2f}", f"{100 * r.seconds_total_spread:.0f} %",
                        f"{r.diagnosis_seconds * 1e3:.2f}", f"{r.seconds * 1e3:.2f}", f"{r.rest_seconds * 1e3:.2f}",
                        f"{r.seconds_total_bound * 1e3:.2f}", f"{r.rmse:.2e}", f"{r.max_error:.3g}",
                        f"{r.psnr:.1f}", f"{r.silhouette_rmse:.3g}", f"{r.image_rmse:.3g}",
                        f"{r.highlight_loss:.3f}"] for r in study.rows]


TIMES = ("Times to image are the whole render() call as measured: its minimum and median over the rounds "
         "(spread = (median − min) / min). Its parts: geometry, BVH, diagnosis (the plan's Gouraud and sub-pixel "
         "highlight checks), frame (rays and shading) and the rest (plan, memory check, shading inputs, film; "
         "negative when the BVH was built alongside the normals). "
         "The lower bound sums each stage's minimum from different rounds: no run took that little.")


def markdown_table(rows: list[list[str]]) -> list[str]:
    return ["| " + " | ".join(rows[0]) + " |", "|" + "---|" * len(rows[0])] + \
        ["| " + " | ".join(row) + " |" for row in rows[1:]]


def summary_markdown(study: Study, plots: dict) -> str:
    lines = [f"# Error against run time: {study.scene}", "", study.levels_note + ".", ""]
    if study.machine:
        lines += [f"Machine: {study.machine.sentence()}.", ""]
    if study.noise:
        lines += [f"Timing: {study.noise.sentence()}.", ""]
    lines += ["\n\n".join(advice(study).splitlines()), "", "## Fitted convergence orders", "",
              "Slope of log RMSE against log mean edge length (least squares).", ""]
    lines += markdown_table(fits_table(study))
    lines += ["", "## Settings", "", TIMES, ""]
    lines += markdown_table(rows_table(study))
    lines += [""] + [f"![{key}]({plot.path.name})" for key, plot in plots.items()] + [""]
    return "\n".join(lines)


OUTPUTS = {"csv": "study.csv", "plot": "error_vs_time.png", "convergence": "convergence.png",
           "silhouette": "silhouette.png", "highlight": "highlight.png", "orders": "orders.png",
           "errors": "error_images.png", "summary": "summary.md", "report": "report.html"}


def check_study_folder(folder: Path, scene: str | Path) -> None:
    """Refuse, before the first render, an output folder (-o) that is a file or that holds a folder (or the scene) under
    one of the OUTPUTS' names. Raises OutputError (ImageError from check_output_file)."""
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{folder}: -o/--output must be a folder, but it is a file")
    if folder.is_dir():
        for name in OUTPUTS.values():
            check_output_file(folder / name, inputs=(scene,))
