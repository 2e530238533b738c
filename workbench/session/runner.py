"""The simulation thread: steps the workbench at real time and pushes frames to the view.

Real time means one sim step of ``dt`` per ``dt / speed`` seconds of wall clock. When a step
takes longer than that the loop falls behind and the real-time factor (shown in the page)
drops below the requested speed. ``speed=float('inf')`` steps as fast as possible (benchmarks).
"""
from __future__ import annotations

import sys
import threading
import time
import traceback
from typing import Callable

from workbench.session.core import Workbench


class SimThread:
    """Background loop ``advance → render`` with real-time pacing and rate statistics.

    Args:
        wb: the workbench core.
        render: called with each new frame (``SceneView.render`` + GUI readouts).
        speed: target real-time factor (1.0 = real time).
        prepare: called once in the thread before the first step (the app compiles the kernels there).
        inputs: called in the thread before each step (the app applies the page's hand gestures there).
    """

    def __init__(self, wb: Workbench, render: Callable, *, speed: float = 1.0, max_fps: float = 60.0,
                 prepare: Callable[[], None] | None = None, inputs: Callable[[], bool] | None = None):
        self.wb = wb
        self.render = render
        self.prepare = prepare  # run first in the thread, before any step (compiling the kernels)
        self.inputs = inputs  # applies what the page asked for since the last step; True when anything changed
        self.speed = speed
        self.max_fps = max_fps  # scene updates per second at most (the newest frame wins)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.frames = 0  # frames rendered since start
        self.rtf = 0.0  # measured real-time factor (sim seconds per wall second)
        self.fps = 0.0  # scene updates per second (rendered frames)
        self.steps = 0  # sim steps since start
        self.step_ms = 0.0  # last sim step wall time [ms]
        self.error: BaseException | None = None
        self._reported: set[tuple[str, str]] = set()  # (exception type, where) already printed
        self._dirty = threading.Event()

    def start(self) -> "SimThread":
        self._thread = threading.Thread(target=self._loop, name="rodlab-sim", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout: float = 5.0) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout)

    def request_render(self) -> None:
        """Ask for a redraw although nothing stepped (paused edits, rewind, overlay toggles)."""
        self._dirty.set()

    def _loop(self) -> None:
        wb = self.wb
        if self.prepare is not None:
            try:
                self.prepare()
            except Exception as exc:  # noqa: BLE001 - shown in the page; the first step will say more
                self.error = exc
        next_t = time.perf_counter()
        win_t0, win_sim0, win_frames = time.perf_counter(), 0.0, 0
        sim_elapsed = 0.0
        last_render = 0.0
        pending = False
        while not self._stop.is_set():
            try:
                if self.inputs is not None and self.inputs():
                    self._dirty.set()
                rp = wb.replay if wb.mode == "replay" else None
                was_playing = rp is not None and rp.playing
                moved = wb.advance()
                if was_playing and not rp.playing:  # a replay stopped at its end: the page is told (Play box)
                    self._dirty.set()
                if moved:
                    self.steps += 1
                    self.step_ms = 1000.0 * wb.live.step_time if wb.mode != "replay" else 0.0
                    sim_elapsed += self._frame_dt()
                pending = pending or moved
                now = time.perf_counter()
                if self._dirty.is_set() or (pending and now - last_render >= 1.0 / self.max_fps):
                    self._dirty.clear()
                    pending = False
                    last_render = now
                    self.render(wb.frame())
                    self.frames += 1
                    win_frames += 1
                    now = time.perf_counter()
                if now - win_t0 >= 1.0:
                    self.rtf = (sim_elapsed - win_sim0) / (now - win_t0)
                    self.fps = win_frames / (now - win_t0)
                    win_t0, win_sim0, win_frames = now, sim_elapsed, 0
                if not moved:
                    self._dirty.wait(0.005 if pending else 0.02)
                    next_t = time.perf_counter()
                    continue
                pace = self._pace()
                if pace <= 0.0:
                    continue
                next_t += pace
                delay = next_t - time.perf_counter()
                if delay > 0:
                    self._stop.wait(delay)
                elif delay < -0.25:  # far behind: do not try to catch up in a burst
                    next_t = time.perf_counter()
            except Exception as exc:  # noqa: BLE001 - keep the page alive, show the error
                self._failed(exc)
                wb.set_playing(False)
                self._stop.wait(0.1)

    def _failed(self, exc: BaseException) -> None:
        """A step or a redraw failed: the page shows it (``error``) and the session pauses; the first failure of each
        kind and place is also printed with its traceback, so it reaches the terminal and the logs."""
        self.error = exc
        tb = traceback.extract_tb(exc.__traceback__)
        key = (type(exc).__name__, f"{tb[-1].filename}:{tb[-1].lineno}" if tb else "?")
        if key not in self._reported:
            self._reported.add(key)
            print(f"rodlab workbench: the stepping thread failed ({key[0]} at {key[1]}); the session is paused:",
                  file=sys.stderr, flush=True)
            traceback.print_exception(type(exc), exc, exc.__traceback__)

    def _frame_dt(self) -> float:
        wb = self.wb
        if wb.mode == "replay" and wb.replay is not None:
            return wb.replay.frame_dt
        return wb.live.dt

    def _pace(self) -> float:
        """Wall seconds per frame (0 = as fast as possible)."""
        wb = self.wb
        speed = wb.replay.speed if (wb.mode == "replay" and wb.replay is not None) else self.speed
        if speed == float("inf") or speed <= 0:
            return 0.0
        return self._frame_dt() / speed
