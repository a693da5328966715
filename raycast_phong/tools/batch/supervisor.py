"""Running a batch's tasks on this machine: in this process, or supervising a pool of worker processes
(one task per worker at a time, workers that die with the batch, a dead worker failing only its scene);
warm_up loads the renderer and its kernels once before either.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Iterator
from contextlib import suppress
from multiprocessing import connection

from ...errors import SceneError
from ...renderer.intersect import embree_started
from ...stops import STOP_SIGNALS
from .jobs import RENDERED, Outcome, Task, failed, new_entry, render_job
from .manifest import remove_temporaries

# Linux's prctl option that has the kernel send a signal to a process when its parent dies.
PR_SET_PDEATHSIG = 1


def in_process(tasks: list[Task], started: set[str]) -> Iterator[Outcome]:
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
    from ...renderer.frame import warm_kernels_for
    from ...renderer.plan import build_plan
    plans = []
    for task in tasks:
        try:
            plans.append(build_plan(task.scene))
        except SceneError:  # bad input: that scene's own render reports it; it must not stop the others
            continue
    warm_kernels_for(plans)
    return time.perf_counter() - start


def process_pool(tasks: list[Task], jobs: int, started: set[str]) -> Iterator[Outcome]:
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
        # The worker starts with the stop signals blocked, so none lands before it has its own handlers.
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
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
            with suppress(OSError):
                self.connection.send(None)
            self.process.join(timeout=5)
        if self.process.is_alive():
            self.process.kill()
        self.process.join()
        self.connection.close()


def _work(tasks: connection.Connection, parent: int | None) -> None:
    """A worker process: render the tasks it receives until it receives None or the batch is gone."""
    _die_with_parent(parent)
    # SIGTERM unwinds (write_image's `finally` removes its temporary file); Ctrl-C, a closed terminal (SIGHUP,
    # sent to the whole process group) and SIGQUIT are the parent's to handle: it stops the workers itself.
    for number in STOP_SIGNALS:
        signal.signal(number, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(128 + signal.SIGTERM))
    signal.pthread_sigmask(signal.SIG_UNBLOCK, STOP_SIGNALS)
    with suppress(EOFError, OSError):  # the batch process is gone
        while (task := tasks.recv()) is not None:
            tasks.send(render_job(task))


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
        return new_entry(task.job, RENDERED, outputs=[task.output.name], hash=task.digest, inputs=task.inputs,
                      threads=task.threads)
    remove_temporaries(task.output.parent, [task.job.name])  # killed mid-write, it left its temporary file
    how = f"killed by {signal.Signals(-exitcode).name}" if exitcode and exitcode < 0 else f"exit status {exitcode}"
    return failed(task, f"its worker process died ({how}; out of memory?)")
