"""The page's callback pool (``workbench.panels.guard``): one call of each callback at a time, at most one waiting
(with the newest arguments), the waiting one started when the running one returns; different callbacks still run
side by side, and an exception is reported without stopping what waits."""
from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

from tools.browser import wait_for
from workbench.panels.guard import _GuardedExecutor


def _pool(errors: list):
    inner = ThreadPoolExecutor(max_workers=8)
    return inner, _GuardedExecutor(inner, errors.append)


def test_a_callback_never_overlaps_itself_and_runs_its_newest_call_next():
    errors: list = []
    inner, pool = _pool(errors)
    release = threading.Event()
    lock = threading.Lock()
    running, most, seen = 0, 0, []

    def action(n: int) -> None:
        nonlocal running, most
        with lock:
            running += 1
            most = max(most, running)
        if n == 0:
            release.wait(60.0)
        seen.append(n)
        with lock:
            running -= 1

    try:
        pool.submit(action, 0)
        wait_for(lambda: running == 1, what="the first call running")
        for n in range(1, 6):  # pressed again and again while the first call runs
            pool.submit(action, n)
        assert pool.waiting() == 1 and pool.busy() == 2 and pool.coalesced == 4
        release.set()
        wait_for(lambda: pool.busy() == 0, what="the calls done")
        assert seen == [0, 5] and most == 1 and not errors
        pool.submit(action, 6)  # once idle, a call runs at once again
        wait_for(lambda: seen == [0, 5, 6], what="a later call")
    finally:
        inner.shutdown(wait=True)


def test_different_callbacks_run_side_by_side_and_a_failure_is_reported():
    errors: list = []
    inner, pool = _pool(errors)
    both = threading.Barrier(2, timeout=60.0)
    done: list = []

    def a(_x) -> None:
        both.wait()  # returns only once b runs too
        done.append("a")

    def b(x) -> None:
        if x == 1:
            both.wait()
        raise KeyError(f"b fails ({x})")

    try:
        pool.submit(a, 1)
        pool.submit(b, 1)
        pool.submit(b, 2)  # waits for b's first call, then runs although that one failed
        wait_for(lambda: pool.busy() == 0 and len(errors) == 2, what="both callbacks done")
        assert done == ["a"] and sorted(str(e) for e in errors) == ["'b fails (1)'", "'b fails (2)'"]
    finally:
        both.abort()
        inner.shutdown(wait=True)
