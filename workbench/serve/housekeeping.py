"""Periodic upkeep of a long workbench session, so what a session holds stays bounded however long it runs and
however fast a client sends.

* viser keeps every message a new page needs in one broadcast buffer. Removing a GUI element or scene node
  leaves a tombstone there that viser sweeps only when a client connects; a session where one page keeps
  loading scenes, policies and grids piles them up. The sweep runs here every few seconds (viser deletes only
  what every connected page has already been sent).
* Page actions run on a pool of threads (viser's, up to 32 per API); glibc gives each thread that allocates at
  once its own arena, up to 8 per core, and keeps memory freed by a thread in that thread's arena, fragmented.
  The session's arenas are capped at :data:`ARENAS` (``mallopt(M_ARENA_MAX)``, before the pool's threads start:
  a few arenas shared by the pool instead of one per busy thread) and ``malloc_trim`` hands free memory back to
  the system every few seconds, so resident memory follows what the session holds.
* glibc serves a block of at least its mmap threshold with a mapping of its own, returned to the system when
  freed, but raises that threshold (up to 32 MB) each time such a block is freed; the arrays of a few MB that
  page actions make and drop (a grid's meshes, a policy's weights, an episode's frames) then come from the arenas
  and fragment them, and resident memory creeps up under a client that keeps loading things. The threshold is
  fixed at :data:`MMAP_THRESHOLD` (``mallopt(M_MMAP_THRESHOLD)``, which also ends its raising).
"""
from __future__ import annotations

import ctypes
import ctypes.util
import threading
from collections.abc import Callable

PERIOD_S = 5.0
ARENAS = 4  # glibc malloc arenas of a workbench process
MMAP_THRESHOLD = 256 * 1024  # [bytes] blocks this large or larger get a mapping of their own (glibc starts at 128 KiB)
_M_ARENA_MAX = -8  # mallopt parameters (malloc.h)
_M_MMAP_THRESHOLD = -3


def _glibc(name: str):
    """The glibc function ``name``, or None (not glibc: musl, macOS)."""
    lib = ctypes.util.find_library("c")
    try:
        return getattr(ctypes.CDLL(lib), name) if lib else None
    except (OSError, AttributeError):
        return None


def _malloc_trim() -> Callable[[], None] | None:
    fn = _glibc("malloc_trim")
    if fn is None:
        return None
    fn.argtypes, fn.restype = [ctypes.c_size_t], ctypes.c_int
    return lambda: fn(0)


def tune_malloc(arenas: int = ARENAS, mmap_threshold: int = MMAP_THRESHOLD) -> bool:
    """Cap glibc's malloc arenas of this process at ``arenas`` (threads started later share them) and fix its mmap
    threshold at ``mmap_threshold`` bytes; False where the C library is not glibc or refused either."""
    fn = _glibc("mallopt")
    if fn is None:
        return False
    fn.argtypes, fn.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    capped = bool(fn(_M_ARENA_MAX, int(arenas)))
    fixed = bool(fn(_M_MMAP_THRESHOLD, int(mmap_threshold)))
    return capped and fixed


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
        self.malloc_tuned = tune_malloc()
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
