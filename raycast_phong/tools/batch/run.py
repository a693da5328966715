"""run_batch: the driver. Prepare every job, run the tasks through one executor (this process, worker
processes or a Dask cluster), record each outcome in the manifest as it comes, and on an interrupt stop the
workers, settle every job's entry and write the manifest before raising Interrupted.
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, replace
from pathlib import Path

from ...errors import BatchFolderError
from ...io.atomic import signals_deferred
from ..sweep import Job, write_contact_sheets
from .cluster import on_cluster
from .jobs import (
    INTERRUPTED,
    NOT_STARTED,
    RENDERED,
    BatchReport,
    Interrupted,
    Outcome,
    Settings,
    Task,
    new_entry,
    prepare_job,
    stop_if_received,
)
from .manifest import folder_lock, is_own_manifest, open_manifest, remove_temporaries, write_manifest
from .supervisor import in_process, process_pool, warm_up

# The manifest is rewritten at most this often while scenes finish (and always at the end, or on an interrupt):
# rewriting it after every scene costs the parent 4 ms each, O(scenes²) over a batch.
MANIFEST_INTERVAL = 0.5
DEFAULT_SETTINGS = Settings()


def run_batch(jobs: list[Job], folder: str | Path, *, workers: int | None = None, force: bool = False,
              settings: Settings = DEFAULT_SETTINGS, scheduler: str | None = None,
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


# A worker process holds Python, numpy, numba's compiled kernels, Embree and trimesh before its first scene:
# about 150 MB (40 workers on a 2-core machine took 6 GB in 2 s).
WORKER_BYTES = 150 << 20


def worker_count(asked: int | None, budget: int | None) -> tuple[int, str | None]:
    """Scenes to render at once: --jobs, at most the machine's cores and as many workers as the budget holds
    (each WORKER_BYTES and its scenes' share), and the warning that says so when the cap applies."""
    cores = os.cpu_count() or 1
    wanted = asked or cores
    fits = max(1, budget // (2 * WORKER_BYTES)) if budget else wanted
    count = max(1, min(wanted, cores, fits))
    if count == wanted:
        return count, None
    from ...io.system import format_bytes
    why = (f"the machine has {cores} cores" if count == cores else
           f"each worker takes about {format_bytes(WORKER_BYTES)} and its scenes as much again of the "
           f"{format_bytes(budget)} budget")
    return count, f"--jobs {wanted}: {count} worker{'s' * (count != 1)} instead, as {why}"


def _run_locked(jobs: list[Job], folder: Path, workers: int | None, force: bool, settings: Settings,
                scheduler: str | None, progress: Callable[[Outcome, int, int], None] | None,
                max_memory: int | None) -> BatchReport:
    """run_batch, with the folder locked."""
    started = time.perf_counter()
    manifest, warning = open_manifest(folder)
    remove_temporaries(folder, [job.name for job in jobs])
    budget = None
    if scheduler is None:
        from ...io.system import budget_of
        budget = budget_of(max_memory)
    cores, capped = worker_count(workers, budget) if scheduler is None else (workers or os.cpu_count() or 1, None)
    outcomes: dict[str, Outcome] = {}
    tasks: list[Task] = []
    begun: set[str] = set()  # names the executor has started
    said: list[str] = []  # what the executor tells on its way (a cluster's lost workers)
    written = time.perf_counter()
    processes = threads = 0
    startup = 0.0
    executed: Iterator[Outcome] | None = None  # the executor's generator: closing it stops the workers

    def record(outcome: Outcome) -> None:
        nonlocal written
        stop_if_received()  # a safe point: the outcome before it is recorded in full, this one after the stop
        outcomes[outcome.name] = outcome
        manifest["scenes"][outcome.name] = asdict(outcome)
        if time.perf_counter() - written >= MANIFEST_INTERVAL:
            write_manifest(folder, manifest)
            written = time.perf_counter()
        if progress:
            progress(outcome, len(outcomes), len(jobs))

    def report() -> BatchReport:
        return BatchReport(folder=folder, outcomes=[outcomes[job.name] for job in jobs], startup=startup,
                           warnings=[w for w in (warning, capped, *said) if w])

    try:
        stop_if_received()  # a signal while the program started: the manifest says every scene is not started
        for job in jobs:
            item = prepare_job(job, folder, settings, manifest["scenes"].get(job.name), force, max_memory)
            stop_if_received()  # loading a mesh scene imports trimesh, whose import guards swallow a raise
            if isinstance(item, Task):
                tasks.append(item)
            else:
                record(item)
        processes = min(cores, len(tasks)) if scheduler is None else 0
        threads = max(1, cores // processes) if processes else 1  # a Dask worker's own threads run the scenes
        if scheduler is None:
            max_memory = budget // max(processes, 1) if budget else None
        tasks = [replace(task, threads=threads, max_memory=max_memory) for task in tasks]
        startup = warm_up(tasks) if scheduler is None else 0.0
        stop_if_received()
        executed = _executor(tasks, scheduler, processes, begun, said)
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
    done.sheets = write_contact_sheets(jobs, done, force, budget or max_memory)
    manifest["sheets"].update(done.sheets)
    done.seconds = time.perf_counter() - started
    manifest["batch"] = {"seconds": round(done.seconds, 6), "startup": round(startup, 6), "cores": cores,
                         "processes": processes, "threads": threads, "scheduler": scheduler}
    write_manifest(folder, manifest)
    return done


def _executor(tasks: list[Task], scheduler: str | None, processes: int, begun: set[str],
              warnings: list[str]) -> Iterator[Outcome]:
    """The tasks' outcomes as they finish: on a Dask cluster (its lost workers said in `warnings`), in this
    process, or on worker processes."""
    if scheduler is not None:
        return on_cluster(tasks, scheduler, begun, warnings)
    if processes <= 1:
        return in_process(tasks, begun)
    return process_pool(tasks, processes, begun)


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


def _unfinished(job: Job, task: Task | None, begun: bool) -> Outcome:
    """The entry of a job an interrupt stopped before its Outcome came back: RENDERED if its image was
    written meanwhile (the rename is atomic, so the file is whole; its timings are lost), else INTERRUPTED
    (it was rendering) or NOT_STARTED."""
    if task is None:
        return new_entry(job, NOT_STARTED)
    entry = new_entry(job, NOT_STARTED, hash=task.digest, inputs=task.inputs)
    if begun and task.written():
        return replace(entry, status=RENDERED, outputs=[task.output.name], threads=task.threads)
    return replace(entry, status=INTERRUPTED) if begun else entry
