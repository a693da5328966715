"""Render many scene files into one folder, in worker processes or on a Dask cluster, and keep a manifest.

find_jobs turns files, folders, globs and sweep files into Jobs; prepare_job (in the calling process) loads
each scene and hashes it to decide whether its outputs are current; render_job (in a worker) renders one scene
and writes its image atomically. run_batch drives both through any executor and rewrites DIR/manifest.json
as scenes finish (at most every MANIFEST_INTERVAL, and at the end or on an interrupt), so an interrupted
batch keeps what it finished. A failing scene becomes a failed entry
with a one-line reason; it never stops the others.

Under faults (docs/batch.md, "Faults"): one batch at a time per folder (flock on DIR/.batch.lock); SIGINT or
SIGTERM kills the workers at once and the manifest marks what did not render; workers die with the batch
process (PR_SET_PDEATHSIG); a worker that dies fails only its scene and is replaced.
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
import threading
import time
import traceback
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field, replace
from multiprocessing import connection
from pathlib import Path

from ..codes import SCENE_SUFFIXES
from ..errors import (
    BatchBusy,
    BatchFolderError,
    CorruptManifest,
    ImageError,
    OptionError,
    SceneError,
    WriteError,
)
from ..io.atomic import signals_deferred, write_text
from ..io.files import open_regular
from ..io.image_io import write_image
from ..renderer.intersect import embree_started
from ..scene.load import load_scene
from ..scene.schema import Scene
from .sweep import Job, is_sweep, load_sweep, write_contact_sheets

MANIFEST = "manifest.json"
MANIFEST_FORMAT = 1
LOCK = ".batch.lock"  # held (flock) by the batch writing into the folder
# Statuses of a manifest entry: the last two only after an interrupt (SIGINT, SIGTERM).
RENDERED, UP_TO_DATE, FAILED = "rendered", "up to date", "failed"
INTERRUPTED, NOT_STARTED = "interrupted", "not started"
# Linux's prctl option that has the kernel send a signal to a process when its parent dies.
PR_SET_PDEATHSIG = 1
# The manifest is rewritten at most this often while scenes finish (and always at the end, or on an interrupt):
# rewriting it after every scene cost the parent 4 ms each, O(scenes²) over a batch.
MANIFEST_INTERVAL = 0.5
# A Dask client gives up on an unreachable scheduler after this long rather than hanging the batch.
CONNECT_TIMEOUT = "10s"


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
    before: tuple[int, int, int] | None = None  # _identity(output) when the scene was loaded (see written())

    def written(self) -> bool:
        """Whether the output is a new file since the task was made: its writer renamed a whole image into
        place, even if it died (or was stopped) before it could say so."""
        return _identity(self.output) not in (None, self.before)


@dataclass
class Outcome:
    """One manifest entry: what happened to a job."""
    name: str
    scene: str
    overrides: list[str]
    status: str                       # RENDERED, UP_TO_DATE, FAILED; INTERRUPTED or NOT_STARTED after an interrupt
    reason: str | None = None         # one line, for FAILED; "internal error: …" for a bug, with its traceback
    outputs: list[str] = field(default_factory=list)  # file names in the batch folder
    seconds: dict[str, float] = field(default_factory=dict)  # load, geometry, build, rays, shade, frame, write, total
    rays_per_second: float | None = None
    threads: int | None = None        # render() threads the scene had (see run_batch's `workers`)
    hash: str | None = None
    inputs: dict[str, int] = field(default_factory=dict)  # scene and mesh files → modification time (ns)
    traceback: str | None = None      # for an internal error (a bug, not bad input): where it was raised


@dataclass
class BatchReport:
    """What run_batch did, in job order."""
    folder: Path
    outcomes: list[Outcome]
    sheets: dict[str, str] = field(default_factory=dict)  # sweep name → contact sheet file name
    seconds: float = 0.0
    startup: float = 0.0  # of `seconds`, loading the renderer and its kernels before the first scene (warm_up)
    warnings: list[str] = field(default_factory=list)  # one line each, e.g. a corrupt manifest kept aside

    def count(self, status: str) -> int:
        return sum(outcome.status == status for outcome in self.outcomes)

    @property
    def failed(self) -> list[Outcome]:
        return [outcome for outcome in self.outcomes if outcome.status == FAILED]


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM stopped a batch. run_batch raises it once its workers are gone and the manifest says
    what was done; `report` has every job, those not rendered as INTERRUPTED or NOT_STARTED."""

    def __init__(self, number: int = signal.SIGINT, report: BatchReport | None = None):
        super().__init__(signal.Signals(number).name)
        self.signal, self.report = int(number), report


def interrupt(number: int, frame) -> None:
    """Signal handler (the `batch` command's, for SIGINT and SIGTERM): stop the batch as Ctrl-C would."""
    raise Interrupted(number)


# ---------------------------------------------------------------- which jobs


def find_jobs(paths: list[str | Path], out: str | Path | None = None) -> list[Job]:
    """Scene files, folders (their *.toml and *.json, not recursive, not hidden), globs and sweep files → Jobs,
    in order; never the manifest of the output folder `out` (a batch may write into a folder it reads).

    A sweep file (a TOML with a `grid` table, see sweep.py) stands for its product of overrides.
    Raises SceneError when a path matches nothing or two jobs would write the same output name.
    """
    files: list[Path] = []
    for given in map(str, paths):
        path = Path(given)
        if path.is_dir():
            found = sorted(p for p in path.iterdir()
                           if p.suffix.lower() in SCENE_SUFFIXES and not p.name.startswith(".") and p.is_file())
        elif path.is_file():
            found = [path]
        else:
            found = sorted(Path(p) for p in glob.glob(given, recursive=True) if Path(p).is_file())
        found = [p for p in found if out is None or not is_own_manifest(p, Path(out))]
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


def is_own_manifest(path: Path, folder: Path) -> bool:
    """Whether `path` is the manifest of the batch folder `folder` (never a scene, however it is spelled)."""
    return path.resolve() == (folder / MANIFEST).resolve()


# ---------------------------------------------------------------- up-to-date check


def job_hash(job: Job, scene: Scene | None, settings: Settings) -> str:
    """sha256 of the package version, the settings, the overrides, the scene file and its meshes' bytes."""
    from .. import __version__
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
    against its folder) and their side files (mesh_file.side_files); the hash and the modification times
    both cover exactly these."""
    if scene is None:
        return [job.scene]
    from ..io.mesh_file import side_files  # an .obj's .mtl, a .gltf's buffers change the image too
    meshes = [scene.resolve(obj.path) for obj in scene.objects if obj.shape == "mesh" and obj.path]
    return [job.scene, *meshes, *(side for mesh in meshes for side in side_files(mesh))]


def input_times(job: Job, scene: Scene | None) -> dict[str, int]:
    """Modification time (ns) of the scene file and of each mesh it reads, keyed by the resolved path (so
    `a.toml`, `./a.toml`, its absolute path and a symlink to it are one file); -1 for a missing file."""
    times = {}
    for path in input_paths(job, scene):
        try:
            times[str(path.resolve())] = path.stat().st_mtime_ns
        except OSError:
            times[str(path.resolve())] = -1
    return times


def is_current(previous: dict | None, digest: str, inputs: dict[str, int], folder: Path) -> bool:
    """A previous manifest entry still describes the folder: same hash, same input modification times (so
    `touch` re-renders, as with make), rendered, every output present."""
    outputs = previous.get("outputs") if previous is not None else None
    return (previous is not None and previous.get("hash") == digest and previous.get("inputs") == inputs
            and previous.get("status") in (RENDERED, UP_TO_DATE) and isinstance(outputs, list) and bool(outputs)
            and all(isinstance(name, str) and (folder / name).is_file() for name in outputs))


def prepare_job(job: Job, folder: Path, settings: Settings, previous: dict | None, force: bool) -> Task | Outcome:
    """Load and hash one job: a Task to render, or an Outcome already (up to date, or a scene that fails to load)."""
    start = time.perf_counter()
    entry = _entry(job, FAILED)
    try:
        scene = load_scene(job.scene, job.overrides)
    except SceneError as error:
        entry.reason, entry.hash = _reason(job, str(error)), job_hash(job, None, settings)
        return entry
    except Exception as error:  # noqa: BLE001 — a loader bug on one file (e.g. a RecursionError) fails that scene only
        return replace(_internal_error(job, entry, error), hash=job_hash(job, None, settings))
    load_seconds = time.perf_counter() - start
    digest, inputs = job_hash(job, scene, settings), input_times(job, scene)
    if not force and is_current(previous, digest, inputs, folder):
        return replace(entry, status=UP_TO_DATE, outputs=previous["outputs"], seconds=previous.get("seconds", {}),
                       rays_per_second=previous.get("rays_per_second"), hash=digest, inputs=inputs)
    output = folder / f"{job.name}{Path(scene.output.path).suffix.lower()}"
    return Task(job=job, scene=scene, output=output, digest=digest, inputs=inputs, settings=settings, threads=None,
                load_seconds=load_seconds, before=_identity(output))


# ---------------------------------------------------------------- one scene (every executor calls this)


def render_job(task: Task) -> Outcome:
    """Render one task and write its image (temporary file, then rename); never raises.

    The one function both the process pool and Dask run, so failure isolation and timings are the same.
    """
    from ..renderer.frame import render
    start = time.perf_counter()
    entry = _entry(task.job, FAILED, hash=task.digest, inputs=task.inputs)
    try:
        result = render(task.scene, threads=task.threads, source=str(task.job.scene), max_memory=task.max_memory)
        written = time.perf_counter()
        write_image(task.output, result.image, result.aovs, srgb=task.settings.srgb)
        result.timings["write"] = time.perf_counter() - written
    except (SceneError, ImageError, WriteError) as error:  # a failed write is a failed scene, never rendered
        entry.reason = _reason(task.job, str(error))
        return entry
    except Exception as error:  # noqa: BLE001 — a renderer bug in one scene must not stop the batch
        return _internal_error(task.job, entry, error)
    seconds = {"load": task.load_seconds, **result.timings, "total": time.perf_counter() - start}
    return replace(entry, status=RENDERED, outputs=[task.output.name],
                   seconds={name: round(value, 6) for name, value in seconds.items()},
                   rays_per_second=round(result.rays_per_second, 1), threads=task.threads)


def _entry(job: Job, status: str, **fields) -> Outcome:
    """A manifest entry for `job`."""
    return Outcome(name=job.name, scene=str(job.scene), overrides=list(job.overrides), status=status, **fields)


def _internal_error(job: Job, entry: Outcome, error: BaseException) -> Outcome:
    """`entry` failed by a bug, not by bad input: "internal error: …" and the traceback, kept in the manifest."""
    return replace(entry, status=FAILED, reason=_reason(job, f"internal error: {type(error).__name__}: {error}"),
                   traceback="".join(traceback.format_exception(error)))


def _reason(job: Job, message: str) -> str:
    """One line that starts with the scene file (SceneError messages already do), and names a sweep cell's values."""
    line = message.splitlines()[0] if message else "unknown error"
    line = line if line.startswith(str(job.scene)) else f"{job.scene}: {line}"
    return f"{line} (sweep cell {job.name})" if job.sweep else line


# ---------------------------------------------------------------- executors


def _in_process(tasks: list[Task], started: set[str]) -> Iterator[Outcome]:
    for task in tasks:
        started.add(task.job.name)
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
    from ..renderer.frame import warm_kernels_for
    from ..renderer.plan import build_plan
    plans = []
    for task in tasks:
        try:
            plans.append(build_plan(task.scene))
        except SceneError:  # bad input: that scene's own render reports it; it must not stop the others
            continue
    warm_kernels_for(plans)
    return time.perf_counter() - start


def _process_pool(tasks: list[Task], jobs: int, started: set[str]) -> Iterator[Outcome]:
    """Each task in a pool of `jobs` worker processes, one task per worker at a time (a worker is sent its
    next scene only when it has returned the last, so an interrupt finds no queued scenes to finish).

    Workers are forked from this process while it has started no Embree threads (the CLI's case), else from
    a fork server (e.g. inside a test run that rendered already). A worker that dies (the OOM killer, a
    crash) fails only the scene it had; a new worker takes the rest. Leaving early (an interrupt, an error)
    kills the workers at once: their only effect on disk is a rename, and run_batch removes their temporaries.
    """
    methods = multiprocessing.get_all_start_methods()
    if "fork" in methods and not embree_started():
        # This process has imported everything, loaded the kernels (warm_up) and started no Embree threads:
        # forked workers inherit the imports (0.7 s each otherwise) and the kernels (0.15 s each).
        context = multiprocessing.get_context("fork")
    else:
        context = multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")
    # Import the package once in the fork server, not once per worker.
    if context.get_start_method() == "forkserver":
        context.set_forkserver_preload(["raycast_phong.tools.batch", "raycast_phong.renderer.frame"])
    parent = os.getpid() if context.get_start_method() == "fork" else None
    queue, workers, finished = deque(tasks), [], False
    try:
        while queue or any(worker.task is not None for worker in workers):
            while queue and len(workers) < jobs:
                workers.append(_Worker(context, parent))
            for worker in [worker for worker in workers if worker.task is None]:
                if not queue:  # two workers may finish together with one task left
                    break
                task = queue.popleft()
                started.add(task.job.name)
                if not worker.give(task):  # it had died: the task fails with it (so a broken pool cannot loop)
                    workers.remove(worker)
                    yield _died(task, worker.process.exitcode)
            busy = [worker for worker in workers if worker.task is not None]
            ready = connection.wait([worker.connection for worker in busy] + [worker.sentinel for worker in busy])
            for worker in busy:
                if worker.connection in ready or worker.sentinel in ready:
                    task, outcome = worker.task, worker.take()
                    if outcome is None or worker.sentinel in ready:  # it is dying (its pipes close first): reap it
                        worker.stop(False)
                        workers.remove(worker)
                    yield outcome if outcome is not None else _died(task, worker.process.exitcode)
        finished = True
    finally:
        for worker in workers:
            worker.stop(finished)


class _Worker:
    """One worker process and the pipe it gets its tasks through; `task` is the one it is rendering."""

    def __init__(self, context, parent: int | None):
        self.connection, theirs = context.Pipe()
        self.process = context.Process(target=_work, args=(theirs, parent), daemon=True)
        # The worker starts with SIGINT and SIGTERM blocked, so neither lands before it has its own handlers.
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, (signal.SIGINT, signal.SIGTERM))
        try:
            self.process.start()
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
        theirs.close()
        self.sentinel = self.process.sentinel
        self.task: Task | None = None

    def give(self, task: Task) -> bool:
        """Send the worker its next task; False if it has died (then it is stopped)."""
        try:
            self.connection.send(task)
        except OSError:
            self.stop(False)
            return False
        self.task = task
        return True

    def take(self) -> Outcome | None:
        """The finished task's Outcome, or None if the worker died before sending it."""
        self.task = None
        try:
            return self.connection.recv() if self.connection.poll() else None
        except (EOFError, OSError):
            return None

    def stop(self, gently: bool) -> None:
        """Gently: tell an idle worker to leave and wait for it; else kill it (SIGKILL) at once."""
        if gently:
            try:
                self.connection.send(None)
            except OSError:
                pass
            self.process.join(timeout=5)
        if self.process.is_alive():
            self.process.kill()
        self.process.join()
        self.connection.close()


def _work(tasks: connection.Connection, parent: int | None) -> None:
    """A worker process: render the tasks it receives until it receives None or the batch is gone."""
    _die_with_parent(parent)
    # SIGTERM unwinds (write_image's `finally` removes its temporary file); Ctrl-C is the parent's to handle.
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(128 + signal.SIGTERM))
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, (signal.SIGINT, signal.SIGTERM))
    try:
        while (task := tasks.recv()) is not None:
            tasks.send(render_job(task))
    except (EOFError, OSError):  # the batch process is gone
        pass


def _die_with_parent(parent: int | None) -> None:
    """Make this worker die with the process that started it (`parent`, or whichever it has now), even when
    that one is killed with SIGKILL: on Linux the kernel sends SIGKILL (PR_SET_PDEATHSIG); elsewhere, or if
    that fails, a thread checks every 0.2 s."""
    parent = parent or os.getppid()
    told = False
    if sys.platform.startswith("linux"):
        import ctypes
        told = ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    if not told:
        def watch() -> None:
            while os.getppid() == parent:
                time.sleep(0.2)
            os._exit(1)
        threading.Thread(target=watch, daemon=True).start()
    if os.getppid() != parent:  # it died before the kernel was told
        os._exit(1)


def _died(task: Task, exitcode: int | None) -> Outcome:
    """The Outcome of a task whose worker process died: FAILED, unless the image was written just before."""
    if task.written():
        return _entry(task.job, RENDERED, outputs=[task.output.name], hash=task.digest, inputs=task.inputs,
                      threads=task.threads)
    remove_temporaries(task.output.parent, [task.job.name])  # killed mid-write, it left its temporary file
    how = f"killed by {signal.Signals(-exitcode).name}" if exitcode and exitcode < 0 else f"exit status {exitcode}"
    return _entry(task.job, FAILED, reason=_reason(task.job, f"its worker process died ({how}; out of memory?)"),
                  hash=task.digest, inputs=task.inputs)


def _result(future: Future, task: Task) -> Outcome:
    """A finished Dask future's Outcome; a worker that died (a crash, not an exception) fails only its task."""
    try:
        return future.result()
    except Exception as error:  # noqa: BLE001
        return _entry(task.job, FAILED, reason=_reason(task.job, f"worker failed: {type(error).__name__}: {error}"),
                      hash=task.digest, inputs=task.inputs)


def _dask(tasks: list[Task], scheduler: str, started: set[str]) -> Iterator[Outcome]:
    """Each task on an existing Dask cluster; the scene files and output folder must be at the same paths there."""
    try:
        from distributed import Client, as_completed
    except ImportError:
        raise OptionError(f"--scheduler {scheduler}: Dask is not installed; pip install 'raycast-phong[distributed]'") \
            from None
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as error:
        raise OptionError(f"--scheduler {scheduler}: cannot connect ({error})") from None
    with client:
        # pure=False: a re-run must render again, not reuse a result the cluster remembers.
        futures = {client.submit(render_job, task, pure=False): task for task in tasks}
        started.update(task.job.name for task in tasks)
        for future in as_completed(futures):
            yield _result(future, futures[future])


# ---------------------------------------------------------------- the manifest and the folder lock


def read_manifest(folder: Path) -> dict:
    """DIR/manifest.json, or an empty manifest if there is none.

    Raises CorruptManifest for a file that is not a batch manifest (format MANIFEST_FORMAT), BatchFolderError for
    one that cannot be read (BatchFolderError; e.g. a folder of that name).
    """
    path = folder / MANIFEST
    try:
        text = path.read_bytes()
    except FileNotFoundError:
        return {"format": MANIFEST_FORMAT, "scenes": {}, "sheets": {}}
    except OSError as error:
        raise BatchFolderError(f"{path}: cannot read the batch manifest ({error.strerror})") from None
    try:
        data = json.loads(text)
    except (ValueError, RecursionError) as error:  # not UTF-8, not JSON, or nested too deep
        raise CorruptManifest(f"not JSON ({type(error).__name__}: {str(error).splitlines()[0][:80]})") from None
    if not (isinstance(data, dict) and data.get("format") == MANIFEST_FORMAT and isinstance(data.get("scenes"), dict)
            and all(isinstance(entry, dict) for entry in data["scenes"].values())
            and isinstance(data.setdefault("sheets", {}), dict)):
        raise CorruptManifest(f"not a batch manifest of format {MANIFEST_FORMAT}")
    return data


def open_manifest(folder: Path) -> tuple[dict, str | None]:
    """read_manifest, but a corrupt manifest is renamed to manifest.json.corrupt-N (kept for a look) and the
    batch starts afresh: returns the manifest and that one-line warning (else None)."""
    try:
        return read_manifest(folder), None
    except CorruptManifest as error:
        path = folder / MANIFEST
        kept = next(path.with_name(f"{MANIFEST}.corrupt-{n}") for n in range(1, 1 << 20)
                    if not path.with_name(f"{MANIFEST}.corrupt-{n}").exists())
        try:
            path.rename(kept)  # the folder lock is held: nothing else writes these names meanwhile
        except OSError as failure:
            raise BatchFolderError(f"{path}: {error}, and cannot keep it aside ({failure.strerror})") from None
        return read_manifest(folder), f"{path}: {error}; kept as {kept.name}, every scene renders again"


@contextmanager
def folder_lock(folder: Path) -> Iterator[None]:
    """Hold DIR/.batch.lock (flock) while the block runs: two batches writing into one folder would delete
    each other's temporary files and overwrite each other's manifest entries. A second batch is refused at
    once (BatchBusy, exit 2), naming the process that holds the folder, rather than waiting unseen."""
    import fcntl
    path = folder / LOCK
    try:
        descriptor = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as error:
        raise BatchFolderError(f"{path}: cannot create the batch lock ({error.strerror})") from None
    try:
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(descriptor, 32, 0).decode(errors="replace").strip()
            raise BatchBusy(f"{folder}: another batch{f' (process {holder})' if holder.isdigit() else ''} is "
                             "writing into this folder; wait for it to finish, or use another --out") from None
        try:
            os.ftruncate(descriptor, 0)
            os.pwrite(descriptor, f"{os.getpid()}\n".encode(), 0)  # for the message above; the lock is the flock
        except OSError as error:
            raise BatchFolderError(f"{path}: cannot write the batch lock ({error.strerror})") from None
        yield
    finally:
        os.close(descriptor)  # releases the flock


def write_manifest(folder: Path, manifest: dict) -> None:
    """Rewrite DIR/manifest.json atomically (temporary file, checked write, then rename); raises WriteError."""
    from .. import __version__
    manifest = {**manifest, "format": MANIFEST_FORMAT, "package_version": __version__}
    write_text(folder / MANIFEST, json.dumps(manifest, indent=2, ensure_ascii=False), prefix=".manifest-")


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

    Raises BatchBusy when another batch is writing into `folder` (see folder_lock), and Interrupted on
    KeyboardInterrupt (SIGINT, or SIGTERM through `interrupt`) once the workers are stopped and the manifest
    is written.
    """
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise BatchFolderError(f"{folder}: cannot create the output folder ({error.strerror})") from None
    jobs = [job for job in jobs if not is_own_manifest(job.scene, folder)]
    with folder_lock(folder):
        return _run_locked(jobs, folder, workers, force, settings, scheduler, progress, max_memory)


def _run_locked(jobs: list[Job], folder: Path, workers: int | None, force: bool, settings: Settings,
                scheduler: str | None, progress: Callable[[Outcome, int, int], None] | None,
                max_memory: int | None) -> BatchReport:
    """run_batch, with the folder locked."""
    started = time.perf_counter()
    manifest, warning = open_manifest(folder)
    remove_temporaries(folder, [job.name for job in jobs])
    cores = workers or os.cpu_count() or 1
    outcomes: dict[str, Outcome] = {}
    tasks: list[Task] = []
    begun: set[str] = set()  # names the executor has started
    written = time.perf_counter()
    processes = threads = 0
    startup = 0.0
    executed: Iterator[Outcome] | None = None  # the executor's generator: closing it stops the workers

    def record(outcome: Outcome) -> None:
        nonlocal written
        outcomes[outcome.name] = outcome
        manifest["scenes"][outcome.name] = asdict(outcome)
        if time.perf_counter() - written >= MANIFEST_INTERVAL:
            write_manifest(folder, manifest)
            written = time.perf_counter()
        if progress:
            progress(outcome, len(outcomes), len(jobs))

    def report() -> BatchReport:
        return BatchReport(folder=folder, outcomes=[outcomes[job.name] for job in jobs], startup=startup,
                           warnings=[warning] if warning else [])

    try:
        for job in jobs:
            item = prepare_job(job, folder, settings, manifest["scenes"].get(job.name), force)
            if isinstance(item, Task):
                tasks.append(item)
            else:
                record(item)
        processes = min(cores, len(tasks)) if scheduler is None else 0
        threads = max(1, cores // processes) if processes else 1  # a Dask worker's own threads run the scenes
        if scheduler is None:
            from ..renderer.budget import default_budget
            budget = max_memory or default_budget()
            max_memory = budget // max(processes, 1) if budget else None
        tasks = [replace(task, threads=threads, max_memory=max_memory) for task in tasks]
        startup = warm_up(tasks) if scheduler is None else 0.0
        executed = _executor(tasks, scheduler, processes, begun)
        for outcome in executed:
            record(outcome)
    except (KeyboardInterrupt, SystemExit) as stop:
        with signals_deferred():  # a second Ctrl-C must not cut the clean-up short
            if executed is not None:
                executed.close()  # the workers are killed before anything below looks at the folder
            remove_temporaries(folder, [job.name for job in jobs])
            _settle(jobs, tasks, begun, outcomes, manifest)
            write_manifest(folder, manifest)
        if isinstance(stop, SystemExit):
            raise
        raise Interrupted(getattr(stop, "signal", signal.SIGINT), report()) from None
    except BaseException:
        if executed is not None:
            executed.close()
        write_manifest(folder, manifest)  # keep the entries of the scenes that finished
        raise
    write_manifest(folder, manifest)
    done = report()
    done.sheets = write_contact_sheets(jobs, done, settings, force)
    manifest["sheets"].update(done.sheets)
    done.seconds = time.perf_counter() - started
    manifest["batch"] = {"seconds": round(done.seconds, 6), "startup": round(startup, 6), "cores": cores,
                         "processes": processes, "threads": threads, "scheduler": scheduler}
    write_manifest(folder, manifest)
    return done


def _executor(tasks: list[Task], scheduler: str | None, processes: int, begun: set[str]) -> Iterator[Outcome]:
    """The tasks' outcomes as they finish: on a Dask cluster, in this process, or on worker processes."""
    if scheduler is not None:
        return _dask(tasks, scheduler, begun)
    if processes <= 1:
        return _in_process(tasks, begun)
    return _process_pool(tasks, processes, begun)


def _settle(jobs: list[Job], tasks: list[Task], begun: set[str], outcomes: dict[str, Outcome],
            manifest: dict) -> None:
    """After an interrupt: every job without an outcome gets one (rendered if its image was written after
    all, else interrupted or not started), and every job's manifest entry is written from its outcome
    again, since the signal may have landed inside record(), between its two updates."""
    by_name = {task.job.name: task for task in tasks}
    for job in jobs:
        if job.name not in outcomes:
            outcomes[job.name] = _unfinished(job, by_name.get(job.name), job.name in begun)
        manifest["scenes"][job.name] = asdict(outcomes[job.name])


def _identity(path: Path) -> tuple[int, int, int] | None:
    """Which file is at `path` (device, inode, modification time), None if none: an atomic write changes it."""
    try:
        stat = path.stat()
    except OSError:
        return None
    return stat.st_dev, stat.st_ino, stat.st_mtime_ns


def _unfinished(job: Job, task: Task | None, begun: bool) -> Outcome:
    """The entry of a job an interrupt stopped before its Outcome came back: RENDERED if its image was
    written meanwhile (the rename is atomic, so the file is whole; its timings are lost), else INTERRUPTED
    (it was rendering) or NOT_STARTED."""
    if task is None:
        return _entry(job, NOT_STARTED)
    entry = _entry(job, NOT_STARTED, hash=task.digest, inputs=task.inputs)
    if begun and task.written():
        return replace(entry, status=RENDERED, outputs=[task.output.name], threads=task.threads)
    return replace(entry, status=INTERRUPTED) if begun else entry
