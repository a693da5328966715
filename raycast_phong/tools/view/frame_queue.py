"""The server's frame threads, and the order they take the pages' work in.

Every page's frames share the server's FRAME_THREADS threads. Taken first come, first served, sixty pages
asking for full 1280×720 frames kept a seventh page's draft waiting 3.5-6.2 s. Here the threads take, turn
about, the cheapest work waiting (a draft before a full request's check of its steps before a preview before a
full frame; the older of two alike) and the oldest: a page that drags waits at most about one frame for its
draft however many full frames are waiting, and a full frame still runs every other turn however many drafts
keep coming.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable
from concurrent.futures import Executor, Future
from dataclasses import dataclass, field
from typing import Any

# What a step costs, for the order: a draft is a quarter of the pixels at one sample; a full request's check of
# its steps (validation, milliseconds) after it, so that other pages' checks, which each open a full frame's
# turn, do not go before a dragging page's draft; a preview every pixel at one sample; a full frame (and a save)
# every sample.
COST = {"draft": 0, "check": 1, "preview": 2, "full": 3}


@dataclass(order=True)
class _Work:
    cost: int
    number: int                                   # the order it came in
    future: Future = field(compare=False)
    call: Callable[[], Any] = field(compare=False)


class FrameQueue(Executor):
    """An executor of `threads` threads that takes the cheapest and the oldest waiting work by turns
    (`at(cost).submit(...)`; a plain submit costs what a full frame does). Its threads start with the first
    work and are daemons, so a server stopped mid-frame does not wait for the frame at exit."""

    def __init__(self, threads: int, name: str):
        self._size, self._name = threads, name
        self._ready = threading.Condition()
        self._waiting: list[_Work] = []
        self._numbers = itertools.count()
        self._turns = itertools.count()
        self._threads: list[threading.Thread] = []
        self._stopped = False

    def at(self, cost: int) -> Executor:
        """This queue, for work of `cost` (COST): what asyncio's run_in_executor is given."""
        return _Costed(self, cost)

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        return self.submit_at(COST["full"], fn, *args, **kwargs)

    def submit_at(self, cost: int, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        future: Future = Future()
        with self._ready:
            if self._stopped:
                raise RuntimeError("cannot schedule new futures after shutdown")
            self._waiting.append(_Work(cost, next(self._numbers), future, lambda: fn(*args, **kwargs)))
            if len(self._threads) < self._size:
                thread = threading.Thread(target=self._work, name=f"{self._name}_{len(self._threads)}",
                                          daemon=True)
                self._threads.append(thread)
                thread.start()
            self._ready.notify()
        return future

    def _take(self) -> _Work:
        """The next work (the lock held, something waiting): the cheapest, then the oldest, turn about."""
        cheapest = next(self._turns) % 2 == 0
        work = min(self._waiting) if cheapest else min(self._waiting, key=lambda w: w.number)
        self._waiting.remove(work)
        return work

    def _work(self) -> None:
        while True:
            with self._ready:
                while not self._waiting and not self._stopped:
                    self._ready.wait()
                if not self._waiting:
                    return
                work = self._take()
            if not work.future.set_running_or_notify_cancel():
                continue
            self._run(work)
            # Let go of the call and what it holds (a page's renderer session and its FrameCache) now, not when
            # this thread takes its next work: a closed page's cache must be freed with it.
            del work

    @staticmethod
    def _run(work: _Work) -> None:
        try:
            result = work.call()
        except BaseException as error:  # noqa: BLE001 — the future carries it to the caller
            work.future.set_exception(error)
        else:
            work.future.set_result(result)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        with self._ready:
            self._stopped = True
            if cancel_futures:
                for work in self._waiting:
                    work.future.cancel()
                self._waiting.clear()
            self._ready.notify_all()
        if wait:
            for thread in self._threads:
                thread.join()


@dataclass(frozen=True)
class _Costed(Executor):
    queue: FrameQueue
    cost: int

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        return self.queue.submit_at(self.cost, fn, *args, **kwargs)
