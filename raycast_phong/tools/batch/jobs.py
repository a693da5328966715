"""A batch's jobs: which scenes (find_jobs: files, folders, globs, sweep files), whether each is up to date
(job_hash, input_times, is_current), and one job from load to written image (prepare_job in the calling
process, render_job wherever it runs: every executor calls it). The records the other modules pass around
(Task, Outcome, BatchReport) live here.
"""

from __future__ import annotations

import glob
import hashlib
import json
import os
import signal
import time
import traceback
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from ... import stops
from ...codes import SCENE_SUFFIXES
from ...errors import ImageError, SceneError, WriteError
from ...io.files import open_regular
from ...io.image_io import write_image
from ...scene.load import load_scene
from ...scene.overrides import SRGB_OVERRIDE
from ...scene.schema import Scene
from ...values.messages import Location, shorten
from ..sweep import Job, is_sweep, load_sweep
from .manifest import is_own_manifest

# Statuses of a manifest entry: the last two only after an interrupt (SIGINT, SIGTERM).
RENDERED, UP_TO_DATE, FAILED = "rendered", "up to date", "failed"


INTERRUPTED, NOT_STARTED = "interrupted", "not started"


@dataclass(frozen=True)
class Settings:
    """Options that change the bytes written, besides the scene: part of every job's hash."""
    srgb: bool = False  # --srgb: every scene loaded with render.colour = "linear" (before a sweep's overrides)

    def overrides(self, job: Job) -> list[str]:
        """The job's overrides as its scene is loaded: --srgb's first, so a sweep over render.colour still wins."""
        return [SRGB_OVERRIDE, *job.overrides] if self.srgb else list(job.overrides)


@dataclass(frozen=True)
class Task:
    """A job ready for a worker: the validated scene and where its image goes.

    A worker may run in another working folder (a Dask worker on another machine), so every path it opens is
    absolute, resolved where the batch runs when the task is made (prepare_job): `scene.folder`, against which
    the scene's mesh and texture paths resolve, and `output`. `job.scene` stays as the user spelled it: on the
    worker it only labels messages and the manifest entry, and is never opened."""
    job: Job
    scene: Scene       # its folder absolute
    output: Path       # absolute
    digest: str
    inputs: dict[str, int]  # input_times() when the scene was loaded
    settings: Settings
    threads: int | None  # render() threads: the batch's cores shared among the scenes rendering at once
    load_seconds: float
    max_memory: int | None = None  # render()'s memory budget: the batch's shared among the scenes at once
    before: tuple[int, int, int] | None = None  # file_identity(output) when the scene was loaded (see written())

    def written(self) -> bool:
        """Whether the output is a new file since the task was made: its writer renamed a whole image into
        place, even if it died (or was stopped) before it could say so."""
        return file_identity(self.output) not in (None, self.before)


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
    warnings: list[str] = field(default_factory=list)  # the render plan's warnings (results one may not want)
    notes: list[str] = field(default_factory=list)     # and its notes; an up-to-date scene keeps its last ones

    def line(self, message: str) -> str:
        """`message` about this scene as one line: its scene file first, and a sweep cell's name after."""
        return _labelled(self.scene, self.name, bool(self.overrides), message)


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


# The signals that stop a batch as Ctrl-C does: `kill`, and a closed terminal (SIGHUP) or Ctrl-\\ (SIGQUIT),
# which would otherwise end it with no manifest written and its workers' temporary files left.
def interrupt(number: int, frame) -> None:
    """Signal handler (the `batch` command's, for STOP_SIGNALS): record the signal, and stop the batch as Ctrl-C
    would; if code that catches BaseException swallows the raise, the next safe point (stop_if_received) acts."""
    stops.record(number)
    raise Interrupted(number)


def stop_if_received() -> None:
    """A safe point of the batch: raise Interrupted for a stop signal received so far (one recorded while the
    program started, or one whose raise someone else's code swallowed)."""
    number = stops.received()
    if number is not None:
        raise Interrupted(number)


MAX_LISTED_BYTES = 16 << 20  # `batch -`: a list of paths on stdin, at most as long as a scene file may be


def listed_paths(stream, warnings: list[str] | None = None) -> list[str]:
    """The paths of `batch -`: one a line of `stream` (bytes, as xargs -d '\\n' reads them), taken literally (no
    glob), blank lines skipped; at most MAX_LISTED_BYTES (`yes | batch -` must not fill the memory). A line with
    a NUL byte names no file on any system: it is left out, with a line in `warnings`, and the others go on."""
    if stream is None:  # the program was started with stdin closed (`<&-`)
        raise SceneError("standard input is closed; pipe the scene paths to `batch -`, one a line", Location("stdin"))
    data = stream.read(MAX_LISTED_BYTES + 1)
    if len(data) > MAX_LISTED_BYTES:
        raise SceneError(f"the list of scene paths is more than the {MAX_LISTED_BYTES >> 20} MiB allowed",
                         Location("stdin"))
    text = data.decode("utf-8", "surrogateescape") if isinstance(data, bytes) else data
    lines = [(number, line.removesuffix("\r")) for number, line in enumerate(text.split("\n"), 1) if line.strip()]
    for number, line in lines:
        if "\0" in line and warnings is not None:
            where = Location("stdin", part=f"line {number}")
            warnings.append(f"{where}: a path with a NUL byte names no file; left out")
    return [line for _, line in lines if "\0" not in line]


def _utf8(text: str) -> bool:
    """Whether `text` (a path as Python decodes it: undecodable bytes as lone surrogates) is valid UTF-8 text."""
    try:
        text.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def find_jobs(paths: list[str | Path], out: str | Path | None = None, listed: list[str] = (),
              warnings: list[str] | None = None) -> list[Job]:
    """Scene files, folders (their *.toml and *.json, not recursive, not hidden), globs and sweep files → Jobs,
    in order; never the manifest of the output folder `out` (a batch may write into a folder it reads).

    A sweep file (a TOML with a `grid` table, see sweep.py) stands for its product of overrides. `-` among the
    paths stands for `listed` (`batch -`: the paths read from stdin, listed_paths): each is a scene file, and
    one that is missing or not a scene becomes a job that fails when loaded, reported as any other scene.
    A file whose name is not UTF-8 (its output image, the manifest and every message name it) is left out, with
    a line in `warnings`, and the others go on.
    Raises SceneError when a given path matches nothing, no job is left, or two jobs would write the same output
    name.
    """
    files: list[Path] = []
    for given in map(str, paths):
        path = Path(given)
        if given == "-":
            files += [Path(line) for line in listed if Path(line) not in files]
            continue
        if path.is_dir():
            # Not only regular files: a FIFO or a device named *.toml is taken, and refused when read, so it is
            # reported as a failed scene instead of being skipped without a word.
            found = sorted(p for p in path.iterdir()
                           if p.suffix.lower() in SCENE_SUFFIXES and not p.name.startswith(".") and not p.is_dir())
        elif path.is_file():
            found = [path]
        else:  # a glob such as 'dir/*' matches the images a batch wrote there too: only scenes and meshes
            found = sorted(Path(p) for p in glob.glob(given, recursive=True)
                           if not Path(p).is_dir() and _is_scene(Path(p)))
        found = [p for p in found if out is None or not is_own_manifest(p, Path(out))]
        if not found:
            raise SceneError("no such scene file, folder or matching glob", Location(given))
        files += [p for p in found if p not in files]
    jobs: list[Job] = []
    for path in files:
        if not _utf8(str(path)):
            if warnings is not None:
                shown = shorten(repr(os.fsencode(path)))
                warnings.append(f"{shown}: a file name that is not UTF-8; left out (rename it)")
            continue
        jobs += load_sweep(path).jobs() if is_sweep(path) else [Job(name=path.stem, scene=path)]
    if not jobs:  # `batch -` given nothing, or only lines and names it leaves out: nothing done is no success
        given = " ".join("stdin" if str(p) == "-" else str(p) for p in paths) or "batch"
        left = f" (every path it named was left out, {len(warnings)} in all, as said above)" if warnings else ""
        raise SceneError(f"no scene to render{left}; allowed: scene files, folders or globs, or `-` with scene "
                         "paths on stdin, one a line", Location(given))
    seen: dict[str, Job] = {}
    for job in jobs:
        if job.name in seen:
            raise SceneError(f"its output name {job.name!r} is also {seen[job.name].scene}'s; rename one of the "
                             "files or run them in separate batches", Location(str(job.scene)))
        seen[job.name] = job
    return jobs


def _is_scene(path: Path) -> bool:
    """A scene file (by suffix) or a mesh file trimesh reads, not an image, a log or a manifest."""
    from ...scene.load import is_mesh_file
    return path.suffix.lower() in SCENE_SUFFIXES or is_mesh_file(path)


def job_hash(job: Job, scene: Scene | None, settings: Settings) -> str:
    """sha256 of the package version, the settings, the overrides, the scene's render.colour (a mesh file's
    comes from its format, not its bytes), the scene file and its meshes' bytes."""
    return _hash(job, settings, scene.render.colour if scene is not None else None, input_paths(job, scene))


def _hash(job: Job, settings: Settings, colour: str | None, paths: list[Path]) -> str:
    """job_hash of a scene whose render.colour is `colour` and whose input_paths are `paths`."""
    from ... import __version__
    digest = hashlib.sha256()
    header = {"package": __version__, "settings": asdict(settings), "overrides": list(job.overrides),
              "colour": colour}
    digest.update(json.dumps(header, sort_keys=True).encode())
    for path in paths:
        digest.update(str(path.name).encode())
        try:  # only a regular file (a FIFO would block), in blocks (a mesh file may be large)
            with open_regular(path, str(path), "file") as handle:
                for block in iter(lambda: handle.read(1 << 20), b""):
                    digest.update(block)
        except (OSError, SceneError):
            digest.update(b"<missing>")  # the render reports the missing file; the hash must still change
    return "sha256:" + digest.hexdigest()


def input_paths(job: Job, scene: Scene | None) -> list[Path]:
    """The files a job's image depends on: its scene file, the colour maps its materials name, then the mesh
    files the scene reads (resolved against its folder), their side files (an .obj's .mtl, a .gltf's buffers)
    and the images their materials name, as their io.meshes.source.MeshSource gives them (the one load_scene
    made, so nothing is read again); the hash and the modification times both cover exactly these."""
    return [job.scene] if scene is None else [job.scene, *scene.files_read()]


def input_times(job: Job, scene: Scene | None) -> dict[str, int]:
    """Modification time (ns) of the scene file and of each mesh it reads, keyed by the resolved path (so
    `a.toml`, `./a.toml`, its absolute path and a symlink to it are one file); -1 for a missing file."""
    return _times(input_paths(job, scene))


def _times(paths: list[Path]) -> dict[str, int]:
    times = {}
    for path in paths:
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


def prepare_job(job: Job, folder: Path, settings: Settings, previous: dict | None, force: bool,
                max_memory: int | None = None) -> Task | Outcome:
    """Load and hash one job: a Task to render, or an Outcome already (up to date, or a scene that fails to load).
    A mesh file's framing read keeps to `max_memory` bytes (the batch's budget)."""
    start = time.perf_counter()
    entry = new_entry(job, FAILED)
    if not force and previous is not None:
        unframed = _unframed_mesh_job(job, settings)
        if unframed is not None and is_current(previous, *unframed, folder):
            return _up_to_date(entry, previous, *unframed)
    try:
        scene = absolute_folder(load_scene(job.scene, settings.overrides(job), max_memory=max_memory))
    except SceneError as error:
        entry.reason, entry.hash = reason_line(job, str(error)), job_hash(job, None, settings)
        return entry
    except Exception as error:  # noqa: BLE001 — a loader bug on one file (e.g. a RecursionError) fails that scene only
        return replace(_internal_error(job, entry, error), hash=job_hash(job, None, settings))
    load_seconds = time.perf_counter() - start
    digest, inputs = job_hash(job, scene, settings), input_times(job, scene)
    if not force and is_current(previous, digest, inputs, folder):
        return _up_to_date(entry, previous, digest, inputs)
    output = Path(folder).absolute() / f"{job.name}{Path(scene.output.path).suffix.lower()}"
    return Task(job=job, scene=scene, output=output, digest=digest, inputs=inputs, settings=settings, threads=None,
                load_seconds=load_seconds, before=file_identity(output))


def _up_to_date(entry: Outcome, previous: dict, digest: str, inputs: dict[str, int]) -> Outcome:
    """`entry` up to date: the previous render's outputs, figures, warnings and notes, under today's hash."""
    return replace(entry, status=UP_TO_DATE, outputs=previous["outputs"], seconds=previous.get("seconds", {}),
                   rays_per_second=previous.get("rays_per_second"), hash=digest, inputs=inputs,
                   warnings=_lines(previous.get("warnings")), notes=_lines(previous.get("notes")))


def _unframed_mesh_job(job: Job, settings: Settings) -> tuple[str, dict[str, int]] | None:
    """(job_hash, input_times) of a job that renders a mesh file directly, without framing it: a batch frames
    (reads whole, through trimesh) only the meshes it will render. Neither depends on the framing: the inputs
    are the file, its side files and images (its MeshSource), and render.colour is the format's default unless
    an override sets it. None for a scene file, or overrides that could add inputs (keys outside render.*,
    camera, lights, ambient and output): the job is loaded as before. A result that differs from the full
    load's can only miss an up-to-date job, never call a stale one current: both hash the same header and
    files, and a previous entry's hash was the full load's."""
    from ...scene.framing import mesh_colour
    from ...scene.load import is_mesh_file
    if not is_mesh_file(job.scene):
        return None
    colour = mesh_colour(job.scene)[0]
    for assignment in settings.overrides(job):
        key, _, value = assignment.partition("=")
        if key.strip() == "render.colour":
            colour = value.strip().strip("\"'")
        elif key.strip().split(".")[0] not in ("camera", "lights", "ambient", "output", "render") \
                or key.strip() == "render":
            return None  # a material map, an object's path: inputs the scene would name; a whole [render] table
    from ...io.meshes.source import mesh_source
    path = Path(job.scene)
    paths = [job.scene, path, *mesh_source(path).files_read]
    return _hash(job, settings, colour, paths), _times(paths)


def absolute_folder(scene: Scene) -> Scene:
    """`scene` with its folder absolute (this process's working folder joined, nothing else changed, as the
    operating system would resolve the relative path here), so its relative mesh and texture paths name the same
    files in a worker whose working folder is another."""
    return scene.model_copy(update={"folder": str(Path(scene.folder).absolute())})


def render_job(task: Task) -> Outcome:
    """Render one task and write its image (temporary file, then rename); never raises.

    The one function both the process pool and Dask run, so failure isolation and timings are the same.
    """
    from ...renderer.frame import render
    start = time.perf_counter()
    entry = new_entry(task.job, FAILED, hash=task.digest, inputs=task.inputs)
    try:
        result = render(task.scene, threads=task.threads, max_memory=task.max_memory)
        written = time.perf_counter()
        write_image(task.output, result.image, result.aovs, colour=task.scene.render.colour)
        result = result.with_timings(write=time.perf_counter() - written)
    except (SceneError, ImageError, WriteError) as error:  # a failed write is a failed scene, never rendered
        return failed(task, str(error))
    except Exception as error:  # noqa: BLE001 — a renderer bug in one scene must not stop the batch
        return _internal_error(task.job, entry, error)
    seconds = {"load": task.load_seconds, **result.timings, "total": time.perf_counter() - start}
    return replace(entry, status=RENDERED, outputs=[task.output.name],
                   seconds={name: round(value, 6) for name, value in seconds.items()},
                   rays_per_second=round(result.rays_per_second, 1), threads=task.threads,
                   warnings=list(result.plan.warnings), notes=list(result.plan.notes))


def _lines(kept: object) -> list[str]:
    """The warnings or notes a previous manifest entry kept: its strings (an edited manifest may hold others)."""
    return [line for line in kept if isinstance(line, str)] if isinstance(kept, list) else []


def new_entry(job: Job, status: str, **fields) -> Outcome:
    """A manifest entry for `job`."""
    return Outcome(name=job.name, scene=str(job.scene), overrides=list(job.overrides), status=status, **fields)


def failed(task: Task, message: str) -> Outcome:
    """The FAILED manifest entry of a task, `message` its reason (reason_line)."""
    return new_entry(task.job, FAILED, reason=reason_line(task.job, message), hash=task.digest, inputs=task.inputs)


def _internal_error(job: Job, entry: Outcome, error: BaseException) -> Outcome:
    """`entry` failed by a bug, not by bad input: "internal error: …" and the traceback, kept in the manifest."""
    return replace(entry, status=FAILED, reason=reason_line(job, f"internal error: {type(error).__name__}: {error}"),
                   traceback="".join(traceback.format_exception(error)))


def reason_line(job: Job, message: str) -> str:
    """One line that starts with the scene file (SceneError messages already do), and names a sweep cell's values."""
    return _labelled(str(job.scene), job.name, bool(job.sweep), message.splitlines()[0] if message else
                     "unknown error")


def _labelled(scene: str, name: str, cell: bool, line: str) -> str:
    line = line if line.startswith(scene) else f"{scene}: {line}"
    return f"{line} (sweep cell {name})" if cell else line


def file_identity(path: Path) -> tuple[int, int, int] | None:
    """Which file is at `path` (device, inode, modification time), None if none: an atomic write changes it."""
    try:
        stat = path.stat()
    except OSError:
        return None
    return stat.st_dev, stat.st_ino, stat.st_mtime_ns
