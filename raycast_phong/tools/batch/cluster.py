"""Running a batch's tasks on an existing Dask cluster (`--scheduler tcp://HOST:PORT`, the `distributed`
extra). A Task's paths are absolute (prepare_job), so a worker's working folder does not matter; the meshes and
textures the scenes name and the output folder must be at those same absolute paths on its workers (the
scene files are read here only).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from concurrent.futures import Future
from contextlib import contextmanager, suppress

from ...errors import OptionError
from .jobs import Outcome, Task, failed, render_job

# A Dask client gives up on an unreachable scheduler after this long rather than hanging the batch, and on a
# scheduler with no worker after WORKER_WAIT seconds (its tasks would wait for ever).
CONNECT_TIMEOUT = "10s"
WORKER_WAIT = 30.0


def cluster_outcome(future: Future, task: Task) -> Outcome:
    """A finished Dask future's Outcome; a worker that died (a crash, not an exception) fails only its task."""
    try:
        return future.result()
    except Exception as error:  # noqa: BLE001
        return failed(task, f"worker failed: {type(error).__name__}: {error}")


@contextmanager
def _dask_quiet() -> Iterator[None]:
    """Dask's own loggers silenced while the batch uses the cluster: a scheduler that dies mid-batch makes them
    print a 30-line traceback; each task it took down fails with one line in the report instead."""
    names = [name for name in logging.root.manager.loggerDict if name.split(".")[0] == "distributed"]
    loggers = [logging.getLogger(name) for name in ("distributed", "tornado", "asyncio", *names)]
    before = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for logger, level in zip(loggers, before):
            logger.setLevel(level)


def on_cluster(tasks: list[Task], scheduler: str, started: set[str], warnings: list[str]) -> Iterator[Outcome]:
    """Each task on an existing Dask cluster; the mesh and texture files and the output folder must be at the same
    absolute paths there. A worker that leaves mid-batch is a line in `warnings` (Dask runs its scenes again on
    another); with no worker left for WORKER_WAIT seconds, the scenes not finished fail, each with one line,
    instead of waiting for ever."""
    try:
        from distributed import Client, wait
    except ImportError:
        raise OptionError(f"--scheduler {scheduler}: Dask is not installed; pip install 'raycast-phong[distributed]'") \
            from None
    try:
        client = Client(scheduler, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as error:
        raise OptionError(f"--scheduler {scheduler}: cannot connect ({error})") from None
    with _dask_quiet(), client:  # quiet until the client has closed
        start = time.monotonic()
        try:
            client.wait_for_workers(1, timeout=WORKER_WAIT)
        except (TimeoutError, OSError):
            waited = time.monotonic() - start
            why = (f"has no worker (waited {WORKER_WAIT:g} s); start one there: dask worker {scheduler}"
                   if waited >= WORKER_WAIT * 0.9 else
                   f"stopped answering after {waited:.0f} s, before any worker joined; is it still running?")
            raise OptionError(f"--scheduler {scheduler}: the scheduler {why}") from None
        # pure=False: a re-run must render again, not reuse a result the cluster remembers.
        futures = {client.submit(render_job, task, pure=False): task for task in tasks}
        started.update(task.job.name for task in tasks)
        pending, known, alone = set(futures), _workers(client) or set(), None
        while pending:
            with suppress(Exception):  # a timeout, or futures a dying scheduler cancelled: their state says
                wait(pending, timeout=WATCH_SECONDS, return_when="FIRST_COMPLETED")
            done = {future for future in pending if future.done()}
            pending -= done
            for future in sorted(done, key=lambda f: futures[f].job.name):
                yield cluster_outcome(future, futures[future])
            now = _workers(client)
            if now is None:  # the scheduler did not answer this time: nothing learnt
                continue
            warnings += [f"--scheduler {scheduler}: worker {address} left the cluster ({len(now)} left); Dask runs "
                         "the scenes it held again on another" for address in sorted(known - now)]
            known = now
            alone = None if now else alone if alone is not None else time.monotonic()
            if pending and alone is not None and time.monotonic() - alone >= WORKER_WAIT:
                for future in sorted(pending, key=lambda f: futures[f].job.name):
                    future.cancel()
                    yield failed(futures[future],
                                 f"no worker left on the scheduler for {WORKER_WAIT:g} s; not rendered")
                return


WATCH_SECONDS = 2.0  # how often a batch on a cluster looks at its workers while scenes render


def _workers(client) -> set[str] | None:
    """The addresses of the cluster's workers now, or None when the scheduler does not answer."""
    try:
        return set(client.scheduler_info(n_workers=-1).get("workers", {}))
    except (OSError, TimeoutError):
        return None
