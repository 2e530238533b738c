"""Periodic upkeep of a long workbench session, so what a session holds stays bounded however long it runs and
however fast a client sends.

* viser keeps every message a new page needs in one broadcast buffer. Removing a GUI element or scene node
  leaves a tombstone there that viser sweeps only when a client connects; a session where one page keeps
  loading scenes, policies and grids piles them up. The sweep runs here every few seconds (viser deletes only
  what every connected page has already been sent).
* Page actions run on a pool of threads; glibc keeps memory freed by a thread in that thread's arena.
  ``malloc_trim`` hands it back to the system, so resident memory follows what the session holds.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import threading
from collections.abc import Callable

PERIOD_S = 5.0


def _malloc_trim() -> Callable[[], None] | None:
    name = ctypes.util.find_library("c")
    try:
        fn = ctypes.CDLL(name).malloc_trim if name else None
    except (OSError, AttributeError):  # not glibc (musl, macOS): nothing to hand back this way
        return None
    if fn is None:
        return None
    fn.argtypes, fn.restype = [ctypes.c_size_t], ctypes.c_int
    return lambda: fn(0)


def sweep_removed(server) -> None:
    """Drop the tombstones of removed elements from viser's broadcast buffer."""
    server._run_garbage_collector()


class Housekeeping:
    """A daemon thread doing the upkeep every ``period`` seconds until :meth:`stop`."""

    def __init__(self, server, period: float = PERIOD_S):
        if not callable(getattr(server, "_run_garbage_collector", None)):
            raise RuntimeError("viser changed: the workbench cannot sweep its message buffer")
        self.server, self.period = server, period
        self.rounds = 0
        self._trim = _malloc_trim()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True, name="workbench-housekeeping")

    def start(self) -> "Housekeeping":
        self._thread.start()
        return self

    def run_once(self) -> None:
        sweep_removed(self.server)
        if self._trim is not None:
            self._trim()
        self.rounds += 1

    def _run(self) -> None:
        while not self._stop.wait(self.period):
            try:
                self.run_once()
            except Exception as exc:  # noqa: BLE001 - upkeep must never end the session: said, then stopped
                print(f"rodlab workbench: housekeeping stopped ({type(exc).__name__}: {exc})", flush=True)
                return

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=self.period + 5.0)
