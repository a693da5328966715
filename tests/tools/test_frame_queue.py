"""The live view's frame threads (tools/view/frame_queue.py): by turns the cheapest and the oldest work waiting."""

from __future__ import annotations

import threading

import pytest

from raycast_phong.tools.view.frame_queue import COST, FrameQueue


def run_in_order(queue: FrameQueue, costs: list[int]) -> list[int]:
    """Hold the queue's one thread with a first job, queue `costs` (named by their index), release it, and
    return the order the queued jobs ran in."""
    release, started, ran = threading.Event(), threading.Event(), []
    queue.at(COST["full"]).submit(lambda: started.set() or release.wait(30))
    assert started.wait(30)
    futures = [queue.at(cost).submit(ran.append, name) for name, cost in enumerate(costs)]
    release.set()
    for future in futures:
        future.result(30)
    return ran


def test_a_draft_waits_at_most_one_full_frame_behind_many():
    """Five full frames of other pages wait (0..4), then a page's draft (5): the draft runs second (the
    oldest full frame's turn comes first), not sixth as first come, first served ran it."""
    queue = FrameQueue(1, "test")
    try:
        order = run_in_order(queue, [COST["full"]] * 5 + [COST["draft"]])
    finally:
        queue.shutdown()
    assert order == [0, 5, 1, 2, 3, 4]


def test_a_full_frame_runs_every_other_turn_however_many_drafts_keep_coming():
    """One full frame (0) queued before six drafts (1..6): the oldest's turn runs it first, where taking the
    cheapest always would run it last (and never, while drafts keep coming)."""
    queue = FrameQueue(1, "test")
    try:
        order = run_in_order(queue, [COST["full"]] + [COST["draft"]] * 6)
    finally:
        queue.shutdown()
    assert order == list(range(7))  # and the drafts among themselves: the older first


def test_costs_order_a_draft_a_preview_and_a_full_frame_and_alike_the_older_first():
    queue = FrameQueue(1, "test")
    try:
        # turns: oldest (0), cheapest (the draft, 3), oldest (1), cheapest (the preview, 2)
        order = run_in_order(queue, [COST["full"], COST["full"], COST["preview"], COST["draft"]])
    finally:
        queue.shutdown()
    assert order == [0, 3, 1, 2]


def test_an_error_reaches_the_caller_and_shutdown_cancels_what_waits():
    queue = FrameQueue(2, "test")
    assert queue.submit(lambda: 6 * 7).result(30) == 42
    with pytest.raises(ZeroDivisionError):
        queue.at(COST["draft"]).submit(lambda: 1 / 0).result(30)
    release, started = threading.Event(), threading.Semaphore(0)
    running = [queue.submit(lambda: started.release() or release.wait(30)) for _ in range(2)]
    assert started.acquire(timeout=30) and started.acquire(timeout=30)  # both threads busy
    waiting = queue.submit(lambda: "never")
    queue.shutdown(wait=False, cancel_futures=True)
    assert waiting.cancelled()
    release.set()
    assert all(future.result(30) for future in running)
    with pytest.raises(RuntimeError, match="after shutdown"):
        queue.submit(lambda: None)
