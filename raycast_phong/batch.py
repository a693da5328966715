"""Render many scene files into one folder, in worker processes or on a Dask cluster, and keep a manifest.

find_jobs turns files, folders, globs and sweep files into Jobs; prepare_job (in the calling process) loads
each scene and hashes it to decide whether its outputs are current; render_job (in a worker) renders one scene
and writes its image atomically. run_batch drives both through any executor and rewrites DIR/manifest.json
as scenes finish (at most every MANIFEST_INTERVAL, and at the end or on an interrupt), so an interrupted
batch keeps what it finished. A failing scene becomes a failed entry
with a one-line reason; it never stops the others.
"""

from __future__ import annotations

import glob
import hashlib
import json
import multiprocessing
import os
import re
import signal
import sys
import time
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Callable, Iterator

from .atomic import replaced_atomically
from .image_io import ImageError, write_image
from .intersect import embree_started
from .scene import Scene, SceneError, load_scene, open_regular

MANIFEST = "manifest.json"
MANIFEST_FORMAT = 1
SCENE_SUFFIXES = (".toml", ".json")
# Statuses of a manifest entry.
RENDERED, UP_TO_DATE, FAILED = "rendered", "up to date", "failed"
# The manifest is rewritten at most this often while scenes finish (and always at the end, or on an interrupt):
# rewriting it after every scene cost the parent 4 ms each, O(scenes²) over a batch.
MANIFEST_INTERVAL = 0.5
# A Dask client gives up on an unreachable scheduler after this long rather than hanging the batch.
CONNECT_TIMEOUT = "10s"


@dataclass(frozen=True)
class Job:
    """One image to make: a scene file, with overrides (a sweep's parameters), named for its output."""
    name: str                          # output file stem, unique within a batch
    scene: Path                        # the scene file
    overrides: tuple[str, ...] = ()    # `key.path=value`, applied as --set
    sweep: str | None = None           # the sweep file's stem, when the job is one cell of a sweep
    cell: tuple[tuple[str, str], ...] = ()  # the sweep's (label, value) per axis, in the grid's order


@dataclass(frozen=True)
class Settings:
    """Options that change the bytes written, besides the scene: part of every job's hash."""
    srgb: bool = False  # PNG outputs sRGB-encoded


@dataclass(frozen=True)
class Task:
    """A job ready for a worker: the validated scene and where its image goes."""
    job: Job
    scene: Scene
    output: Path
    digest: str
    inputs: dict[str, int]  # input_times() when the scene was loaded
    settings: Settings
    threads: int | None  # render() threads: the batch's cores shared among the scenes rendering at once
    load_seconds: float
    max_memory: int | None = None  # render()'s memory budget: the batch's shared among the scenes at once


@dataclass
class Outcome:
    """One manifest entry: what happened to a job."""
    name: str
    scene: str
    overrides: list[str]
    status: str                       # RENDERED, UP_TO_DATE or FAILED
    reason: str | None = None         # one line, for FAILED
    outputs: list[str] = field(default_factory=list)  # file names in the batch folder
    seconds: dict[str, float] = field(default_factory=dict)  # load, geometry, build, rays, shade, frame, write, total
    rays_per_second: float | None = None
    threads: int | None = None        # render() threads the scene had (see run_batch's `workers`)
    hash: str | None = None
    inputs: dict[str, int] = field(default_factory=dict)  # scene and mesh files → modification time (ns)


@dataclass
class BatchReport:
    """What run_batch did, in job order."""
    folder: Path
    outcomes: list[Outcome]
    sheets: dict[str, str] = field(default_factory=dict)  # sweep name → contact sheet file name
    seconds: float = 0.0
    startup: float = 0.0  # of `seconds`, loading the renderer and its kernels before the first scene (warm_up)

    def count(self, status: str) -> int:
        return sum(outcome.status == status for outcome in self.outcomes)

    @property
    def failed(self) -> list[Outcome]:
        return [outcome for outcome in self.outcomes if outcome.status == FAILED]


# ---------------------------------------------------------------- which jobs


def find_jobs(paths: list[str | Path]) -> list[Job]:
    """Scene files, folders (their *.toml and *.json, not recursive), globs and sweep files → Jobs, in order.

    A sweep file (a TOML with a `grid` table, see sweep.py) stands for its product of overrides.
    Raises SceneError when a path matches nothing or two jobs would write the same output name.
    """
    from .sweep import is_sweep, load_sweep
    files: list[Path] = []
    for given in map(str, paths):
        path = Path(given)
        if path.is_dir():
            found = sorted(p for p in path.iterdir() if p.suffix.lower() in SCENE_SUFFIXES and p.is_file())
        elif path.is_file():
            found = [path]
        else:
            found = sorted(Path(p) for p in glob.glob(given, recursive=True) if Path(p).is_file())
        if not found:
            raise SceneError(f"{given}: no such scene file, folder or matching glob")
        files += [p for p in found if p not in files]
    jobs: list[Job] = []
    for path in files:
        jobs += load_sweep(path).jobs() if is_sweep(path) else [Job(name=path.stem, scene=path)]
    seen: dict[str, Job] = {}
    for job in jobs:
        if job.name in seen:
            raise SceneError(f"{job.scene}: its output name {job.name!r} is also {seen[job.name].scene}'s; "
                             "rename one of the files or run them in separate batches")
        seen[job.name] = job
    return jobs


# ---------------------------------------------------------------- up-to-date check


def job_hash(job: Job, scene: Scene | None, settings: Settings) -> str:
    """sha256 of the package version, the settings, the overrides, the scene file and its meshes' bytes."""
    from . import __version__
    digest = hashlib.sha256()
    header = {"package": __version__, "settings": asdict(settings), "overrides": list(job.overrides)}
    digest.update(json.dumps(header, sort_keys=True).encode())
    for path in input_paths(job, scene):
        digest.update(str(path.name).encode())
        try:  # only a regular file (a FIFO would block), in blocks (a mesh file may be large)
            with open_regular(path, str(path), "file") as handle:
                for block in iter(lambda: handle.read(1 << 20), b""):
                    digest.update(block)
        except (OSError, SceneError):
            digest.update(b"<missing>")  # the render reports the missing file; the hash must still change
    return "sha256:" + digest.hexdigest()


def input_paths(job: Job, scene: Scene | None) -> list[Path]:
    """The files a job's image depends on: its scene file, then the mesh files the scene reads (resolved
    against its folder); the hash and the modification times both cover exactly these."""
    if scene is None:
        return [job.scene]
    return [job.scene, *(scene.resolve(obj.path) for obj in scene.objects if obj.shape == "mesh" and obj.path)]


def input_times(job: Job, scene: Scene | None) -> dict[str, int]:
    """Modification time (ns) of the scene file and of each mesh it reads; -1 for a missing file."""
    times = {}
    for path in input_paths(job, scene):
        try:
            times[str(path)] = path.stat().st_mtime_ns
        except OSError:
            times[str(path)] = -1
    return times


def is_current(previous: dict | None, digest: str, inputs: dict[str, int], folder: Path) -> bool:
    """A previous manifest entry still describes the folder: same hash, same input modification times (so
    `touch` re-renders, as with make), rendered, every output present."""
    return (previous is not None and previous.get("hash") == digest and previous.get("inputs") == inputs
            and previous.get("status") in (RENDERED, UP_TO_DATE)
            and bool(previous.get("outputs")) and all((folder / name).is_file() for name in previous["outputs"]))


def prepare_job(job: Job, folder: Path, settings: Settings, previous: dict | None, force: bool) -> Task | Outcome:
    """Load and hash one job: a Task to render, or an Outcome already (up to date, or a scene that fails to load)."""
    start = time.perf_counter()
    entry = Outcome(name=job.name, scene=str(job.scene), overrides=list(job.overrides), status=FAILED)
    try:
        scene = load_scene(job.scene, job.overrides)
    except SceneError as error:
        entry.reason, entry.hash = _reason(job, str(error)), job_hash(job, None, settings)
        return entry
    load_seconds = time.perf_counter() - start
    digest, inputs = job_hash(job, scene, settings), input_times(job, scene)
    if not force and is_current(previous, digest, inputs, folder):
        return replace(entry, status=UP_TO_DATE, outputs=previous["outputs"], seconds=previous.get("seconds", {}),
                       rays_per_second=previous.get("rays_per_second"), hash=digest, inputs=inputs)
    output = folder / f"{job.name}{Path(scene.output.path).suffix.lower()}"
    return Task(job=job, scene=scene, output=output, digest=digest, inputs=inputs, settings=settings, threads=None,
                load_seconds=load_seconds)


# ---------------------------------------------------------------- one scene (every executor calls this)


def render_job(task: Task) -> Outcome:
    """Render one task and write its image (temporary file, then rename); never raises.

    The one function both the process pool and Dask run, so failure isolation and timings are the same.
    """
    from .render import render
    start = time.perf_counter()
    entry = Outcome(name=task.job.name, scene=str(task.job.scene), overrides=list(task.job.overrides),
                    status=FAILED, hash=task.digest, inputs=task.inputs)
    try:
        result = render(task.scene, threads=task.threads, source=str(task.job.scene), max_memory=task.max_memory)
        written = time.perf_counter()
        write_image(task.output, result.image, result.aovs, srgb=task.settings.srgb)
        result.timings["write"] = time.perf_counter() - written
    except (SceneError, ImageError) as error:
        entry.reason = _reason(task.job, str(error))
        return entry
    except Exception as error:  # a renderer bug in one scene must not stop the batch
        entry.reason = _reason(task.job, f"internal error: {type(error).__name__}: {error}")
        return entry
    seconds = {"load": task.load_seconds, **result.timings, "total": time.perf_counter() - start}
    return replace(entry, status=RENDERED, outputs=[task.output.name],
                   seconds={name: round(value, 6) for name, value in seconds.items()},
                   rays_per_second=round(result.rays_per_second, 1), threads=task.threads)


def _reason(job: Job, message: str) -> str:
    """One line that starts with the scene file (SceneError messages already do), and names a sweep cell's values."""
    line = message.splitlines()[0] if message else "unknown error"
    line = line if line.startswith(str(job.scene)) else f"{job.scene}: {line}"
    return f"{line} (sweep cell {job.name})" if job.sweep else line


# ---------------------------------------------------------------- executors


def _in_process(tasks: list[Task]) -> Iterator[Outcome]:
    for task in tasks:
        yield render_job(task)


def warm_up(tasks: list[Task]) -> float:
    """Load the renderer (its imports: numba, trimesh, Embree) and the numba kernels the tasks need
    (precisions, shadow rays) before any scene; the seconds it took.

    The once-per-command start-up every batch pays, whatever --jobs: doing it here, not in the first
    render, lets forked workers start warm and lets the batch report it apart from the scenes.
    """
    if not tasks:
        return 0.0
    start = time.perf_counter()
    import numpy as np
    from .plan import build_plan
    from .render import warm_kernels
    plans = []
    for task in tasks:
        try:
            plans.append(build_plan(task.scene))
        except Exception:  # that scene's own render reports it; it must not stop the others
            pass
    if plans:
        warm_kernels(tuple({np.float64 if plan.keeps("float64_shading") else np.float32 for plan in plans}),
                     shadows=any(plan.keeps("shadow_rays") for plan in plans))
    return time.perf_counter() - start


def _worker_start() -> None:
    """Turn SIGTERM into SystemExit in a worker, so write_image's `finally` removes its temporary file."""
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(128 + signal.SIGTERM))
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle; it stops the pool


def _process_pool(tasks: list[Task], jobs: int) -> Iterator[Outcome]:
    """Each task in a pool of `jobs` processes: forked from this one while it has started no Embree
    threads (the CLI's case), else from a fork server (e.g. inside a test run that rendered already)."""
    methods = multiprocessing.get_all_start_methods()
    if "fork" in methods and not embree_started():
        # This process has imported everything, loaded the kernels (warm_up) and started no Embree threads:
        # forked workers inherit the imports (0.7 s each otherwise) and the kernels (0.15 s each).
        context = multiprocessing.get_context("fork")
    else:
        context = multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")
    # Import the package once in the fork server, not once per worker.
    if context.get_start_method() == "forkserver":
        context.set_forkserver_preload(["raycast_phong.batch", "raycast_phong.render"])
    pool = ProcessPoolExecutor(max_workers=jobs, mp_context=context, initializer=_worker_start)
    try:
        pending = {pool.submit(render_job, task): task for task in tasks}
        while pending:
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                yield _result(future, pending.pop(future))
    finally:
        pool.shutdown(wait=True, cancel_futures=True)  # let running renders finish their atomic writes


def _result(future: Future, task: Task) -> Outcome:
    """A finished future's Outcome; a worker that died (a crash, not an exception) fails only its task."""
    try:
        return future.result()
    except Exception as error:
        return Outcome(name=task.job.name, scene=str(task.job.scene), overrides=list(task.job.overrides),
                       status=FAILED, reason=_reason(task.job, f"worker failed: {type(error).__name__}: {error}"),
                       hash=task.digest, inputs=task.inputs)


def _dask(tasks: list[Task], scheduler: str) -> Iterator[Outcome]:
    """Each task on an existing Dask cluster; the scene files and output folder must be at the same paths there."""
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise SceneError(f"--scheduler {scheduler}: Dask is not installed; pip install 'raycast-phong[distributed]'") \
            from None
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as error:
        raise SceneError(f"--scheduler {scheduler}: cannot connect ({error})") from None
    with client:
        # pure=False: a re-run must render again, not reuse a result the cluster remembers.
        futures = {client.submit(render_job, task, pure=False): task for task in tasks}
        for future in as_completed(futures):
            yield _result(future, futures[future])


# ---------------------------------------------------------------- the manifest


def read_manifest(folder: Path) -> dict:
    """DIR/manifest.json, or an empty manifest if there is none or it is unreadable (then everything renders)."""
    try:
        data = json.loads((folder / MANIFEST).read_text())
    except (OSError, ValueError):
        return {"format": MANIFEST_FORMAT, "scenes": {}, "sheets": {}}
    if not isinstance(data, dict) or data.get("format") != MANIFEST_FORMAT or not isinstance(data.get("scenes"), dict):
        return {"format": MANIFEST_FORMAT, "scenes": {}, "sheets": {}}
    data.setdefault("sheets", {})
    return data


def write_manifest(folder: Path, manifest: dict) -> None:
    """Rewrite DIR/manifest.json atomically (temporary file, then rename)."""
    from . import __version__
    manifest = {**manifest, "format": MANIFEST_FORMAT, "package_version": __version__}
    with replaced_atomically(folder / MANIFEST, prefix=".manifest-") as temporary:
        temporary.write_text(json.dumps(manifest, indent=2, ensure_ascii=False), encoding="utf-8")


def remove_temporaries(folder: Path, names: list[str]) -> list[Path]:
    """Delete what a killed writer left: write_image's `.NAME-XXXXXXXX.png|exr` and `.manifest-*.json`."""
    pattern = re.compile(r"\.(?P<name>.+)-[A-Za-z0-9_]{8}\.(png|exr)$|\.manifest-[A-Za-z0-9_]{8}\.json$")
    wanted, removed = set(names) | {"contact"}, []
    for path in folder.iterdir():
        match = pattern.match(path.name)
        if match and (match["name"] is None or match["name"] in wanted or match["name"].endswith("-contact")):
            path.unlink(missing_ok=True)
            removed.append(path)
    return removed


# ---------------------------------------------------------------- the batch


def run_batch(jobs: list[Job], folder: str | Path, *, workers: int | None = None, force: bool = False,
              settings: Settings = Settings(), scheduler: str | None = None,
              progress: Callable[[Outcome, int, int], None] | None = None,
              max_memory: int | None = None) -> BatchReport:
    """Render every job that is not up to date into `folder`; write folder/manifest.json after each scene.

    Parameters
    ----------
    workers: the cores the batch may use (default: all of them), like make's -j. Scenes render side by side,
        one per worker process, each on one thread; with fewer scenes to render than cores, fewer processes
        get more threads each. With 1 (or one scene to render) the scenes render in this process, one after
        another, on `workers` threads.
    scheduler: a Dask scheduler address (tcp://host:port); the renders run on that cluster instead.
    progress: called as progress(outcome, done, total) after each job.
    max_memory: memory budget in bytes for the scenes rendering at once on this machine (default: render()'s,
        3/4 of the memory available); each of the P worker processes gets 1/P of it. Dask workers use their own.
    """
    from .sweep import write_contact_sheets
    started = time.perf_counter()
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ImageError(f"{folder}: cannot create the output folder ({error.strerror})") from None
    manifest = read_manifest(folder)
    remove_temporaries(folder, [job.name for job in jobs])
    cores = workers or os.cpu_count() or 1
    prepared = [prepare_job(job, folder, settings, manifest["scenes"].get(job.name), force) for job in jobs]
    tasks = [item for item in prepared if isinstance(item, Task)]
    processes = min(cores, len(tasks)) if scheduler is None else 0
    threads = max(1, cores // processes) if processes else 1  # a Dask worker's own threads run the scenes
    if scheduler is None:
        from .memory import default_budget
        budget = max_memory or default_budget()
        max_memory = budget // max(processes, 1) if budget else None
    tasks = [replace(task, threads=threads, max_memory=max_memory) for task in tasks]
    outcomes: dict[str, Outcome] = {}
    written = time.perf_counter()
    startup = warm_up(tasks) if scheduler is None else 0.0

    def record(outcome: Outcome) -> None:
        nonlocal written
        outcomes[outcome.name] = outcome
        manifest["scenes"][outcome.name] = asdict(outcome)
        if time.perf_counter() - written >= MANIFEST_INTERVAL:
            write_manifest(folder, manifest)
            written = time.perf_counter()
        if progress:
            progress(outcome, len(outcomes), len(jobs))

    try:
        for item in prepared:
            if isinstance(item, Outcome):
                record(item)
        if scheduler is not None:
            executed = _dask(tasks, scheduler)
        elif processes <= 1:
            executed = _in_process(tasks)
        else:
            executed = _process_pool(tasks, processes)
        for outcome in executed:
            record(outcome)
    finally:  # an interrupted batch keeps the entries of the scenes it finished
        write_manifest(folder, manifest)
    report = BatchReport(folder=folder, outcomes=[outcomes[job.name] for job in jobs], startup=startup)
    report.sheets = write_contact_sheets(jobs, report, settings, force)
    manifest["sheets"].update(report.sheets)
    report.seconds = time.perf_counter() - started
    manifest["batch"] = {"seconds": round(report.seconds, 6), "startup": round(startup, 6), "cores": cores,
                         "processes": processes, "threads": threads, "scheduler": scheduler}
    write_manifest(folder, manifest)
    return report
