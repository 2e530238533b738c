"""GUI: a grid of N parallel envs of the chosen task under the chosen policy (Policy tab, "Grid of envs"), stepped
in their own thread (``workbench.session.grid``) and drawn vectorised (``workbench.view.grid``). A click on a rod (or the
Focus env slider) moves the camera to that env and shows its readouts. The live session pauses meanwhile."""
from __future__ import annotations

import collections
import threading
import time
from pathlib import Path
from typing import Callable

import numpy as np

from workbench.panels.host import PanelHost
from workbench.panels.policy import NO_POLICY
from workbench.session import HAND_EVENTS, MAX_ENVS, PRETRAINED, GridSession, apply_gestures, page_error
from workbench.view import GROUND_SIZE, GridView, place_camera

STATUS_S = 0.2  # [s] the readouts follow the running grid this often


class GridRunner:
    """Steps a grid session at (at most) real time and redraws it at most ``max_fps`` times a second; after a redraw
    ``on_status()`` (the page's readouts) at most every ``STATUS_S`` — the live session is paused, so nothing else
    refreshes them while the grid runs."""

    def __init__(self, session: GridSession, view: GridView, *, max_fps: float = 30.0, speed: float = 1.0,
                 on_status: Callable[[], None] | None = None, inputs: Callable[[], None] | None = None):
        self.s, self.view = session, view
        self.max_fps, self.speed = max_fps, speed
        self.on_status = on_status
        self.inputs = inputs  # applies what the page asked for since the last step (under the lock)
        self.lock = threading.Lock()
        self.error: BaseException | None = None
        self.frames = 0  # redraws pushed to the page
        self.rtf = 0.0  # measured real-time factor (simulated seconds per wall second)
        self.fps = 0.0  # redraws per second
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="rodlab-grid", daemon=True)

    def start(self) -> "GridRunner":
        self._thread.start()
        return self

    def stop(self, timeout: float = 10.0) -> None:
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    @property
    def alive(self) -> bool:
        return self._thread.is_alive()

    def _loop(self) -> None:
        last = last_status = 0.0
        next_t = win_t0 = time.perf_counter()
        win_steps = win_frames = 0
        while not self._stop.is_set():
            try:
                with self.lock:
                    if self.inputs is not None:
                        self.inputs()
                    self.s.step()
                win_steps += 1
                now = time.perf_counter()
                if now - win_t0 >= 1.0:
                    self.rtf = win_steps * self.s.control_dt / (now - win_t0)
                    self.fps = win_frames / (now - win_t0)
                    win_t0, win_steps, win_frames = now, 0, 0
                if now - last >= 1.0 / self.max_fps:
                    last = now
                    with self.lock:
                        self.view.render()
                    self.frames += 1
                    win_frames += 1
                    if self.on_status is not None and now - last_status >= STATUS_S:
                        last_status = now
                        self.on_status()
                if self.speed != float("inf"):
                    next_t = max(next_t + self.s.control_dt / self.speed, time.perf_counter() - 0.25)
                    self._stop.wait(max(0.0, next_t - time.perf_counter()))
            except Exception as exc:  # noqa: BLE001 - shown in the page; the grid stops
                self.error = exc
                return


class GridPanel:
    def __init__(self, app: PanelHost):
        self.app = app
        self._hand_events: collections.deque = collections.deque(maxlen=HAND_EVENTS)  # drags for the grid's thread
        gui = app.server.gui
        with app.tabs["Policy"], gui.add_folder("Grid of envs"):
            self.envs = gui.add_slider("Envs", min=1, max=MAX_ENVS, step=1, initial_value=16,
                                       hint=f"how many parallel envs of the task (at most {MAX_ENVS}), each in its "
                                            "own cell with its own target and obstacles")
            self.run_btn = gui.add_button("Run grid", hint="run the envs under the Task and Policy file chosen "
                                                           "above (the live session pauses)")
            self.focus = gui.add_slider("Focus env", min=0, max=MAX_ENVS - 1, step=1, initial_value=0,
                                        hint="the env whose readouts are shown; clicking a rod in the view also "
                                             "focuses it and moves the camera there")
            self.whole_btn = gui.add_button("Whole grid", hint="camera on all the cells")
            self.stop_btn = gui.add_button("Stop grid", hint="remove the grid (the live session stays paused)")
            self.msg = gui.add_markdown("")
        self.session: GridSession | None = None
        self.view: GridView | None = None
        self.runner: GridRunner | None = None
        self._syncing = False
        self._cameras: dict[int, tuple[tuple, tuple]] = {}  # page -> (camera position, look-at) before the grid
        # Run grid, Stop grid and the session's end come on different callback threads: one at a time, so a grid
        # is never built over another being built (whose thread and simulator would be left running)
        self._lock = threading.RLock()
        for h in (self.envs, self.focus):
            app.checks.track(h)
        self._wire()

    def _say(self, text: str) -> None:
        self.msg.content = text

    def _wire(self) -> None:
        ok = self.app.checks

        @self.run_btn.on_click
        def _(_e) -> None:
            if ok.number(self.envs, self._say, 1, MAX_ENVS):
                self.start_listed()

        @self.stop_btn.on_click
        def _(_e) -> None:
            self.stop()

        @self.whole_btn.on_click
        def _(_e) -> None:
            if self.view is not None:
                self.view.look_at(None)

        @self.focus.on_update
        def _(_e) -> None:
            if self._syncing or self.session is None:
                return
            if ok.number(self.focus, self._say, 0, self.session.n - 1):
                self.set_focus(int(self.focus.value))

    def start_listed(self) -> None:
        """Start the grid with the Policy tab's Task and Policy file (listed options only)."""
        pol = self.app.policy
        task, policy = pol.task.value, pol.policy.value
        if task not in tuple(pol.task.options) or policy not in pol._policies():
            self._say("choose a task and a policy from the lists")
            return

        try:
            self.start(task, policy if policy in NO_POLICY else str(PRETRAINED / Path(policy).name),
                       int(self.envs.value))
        except Exception as exc:  # noqa: BLE001 - a policy that does not fit, a task that fails to build
            self._say(f"⚠ {page_error(exc)}")

    def start(self, task: str, policy: str, n: int, *, speed: float = 1.0, max_fps: float = 30.0) -> GridSession:
        """Run ``n`` envs of ``task`` under ``policy`` (trusted callers; the page uses :meth:`start_listed`). The grid
        takes the live scene's place (which is hidden, and paused) until :meth:`stop`."""
        with self._lock:
            return self._start(task, policy, n, speed=speed, max_fps=max_fps)

    def _start(self, task: str, policy: str, n: int, *, speed: float, max_fps: float) -> GridSession:
        running = self.session is not None
        self._teardown()
        self._say(f"building {n} envs of {task} …")
        app = self.app
        try:
            session = GridSession(task, policy, n, centred=True)
        except BaseException:
            if running:
                self._show_live()
            raise
        if not running:  # where each page looked: Stop grid goes back there
            self._cameras = self._camera_poses()
        app.wb.set_playing(False)
        app.controls.set_quiet(app.controls.playing, False)
        app.view.show_live(False)
        app.view.set_ground(max(GROUND_SIZE, float(np.ptp(session.offsets[:, :2], axis=0).max()) + session.spacing))
        self.session = session
        self._hand_events.clear()
        self.view = GridView(app.server, session, on_focus=self.set_focus, overlays=app.view.overlays,
                             on_grab=self._grabbed)
        self.view.render()
        self._syncing = True
        try:
            self.focus.max = max(n - 1, 1)
            self.focus.value = 0
        finally:
            self._syncing = False
        app.checks.accept(self.focus)
        self.view.look_at(None)
        self.runner = GridRunner(session, self.view, max_fps=max_fps, speed=speed, on_status=self._refresh,
                                 inputs=self._apply_hand_events).start()
        self.update_status()
        return session

    def _grabbed(self, env: int, ev) -> None:
        """A drag on env ``env``'s rod (on the event loop): queued for the grid's thread."""
        self._hand_events.append((ev.phase, (env, ev.start_position), ev.end_position))

    def _apply_hand_events(self) -> None:
        """The queued drags, in order, on the running grid (its thread, under its lock): the hand pulls that env's
        rod (``GridSession.grab`` / ``move_hand`` / ``release``); a refused one is said in the status line."""
        s = self.session
        if s is None:
            self._hand_events.clear()
            return
        apply_gestures(self._hand_events, lambda env_at: s.grab(*env_at), s.move_hand, s.release,
                       lambda exc: self._say(f"⚠ {exc}"))

    def _camera_poses(self) -> dict[int, tuple[tuple, tuple]]:
        out = {}
        for cid, client in self.app.server.get_clients().items():
            try:
                out[cid] = (tuple(client.camera.position), tuple(client.camera.look_at))
            except (AssertionError, ValueError):  # the page has not reported its camera yet
                continue
        return out

    def _refresh(self) -> None:
        """The grid's readouts and the status line, from the grid's thread (the live session is paused)."""
        self.update_status()
        self.app.controls.update_status()

    def set_focus(self, env: int) -> None:
        """Focus env ``env``: its colour, the camera on its cell, its readouts below."""
        session, view = self.session, self.view  # a stop on another callback thread may clear them
        if session is None or view is None or not 0 <= int(env) < session.n:
            return
        if int(self.focus.value) != int(env):  # the slider first: whoever sees the view focused sees it too
            self._syncing = True
            try:
                self.focus.value = int(env)
            finally:
                self._syncing = False
            self.app.checks.accept(self.focus)
        view.set_focus(int(env))
        self.update_status()

    def stop(self) -> None:
        """Remove the grid: the live scene is shown again and every page's camera goes back to where it was before
        the grid (a page opened since: the start view)."""
        with self._lock:
            if self.session is None and self.view is None:
                return
            self._teardown()
            self._show_live()
        self._say("grid stopped")

    def close(self) -> None:
        """The session ends: the grid's thread stops and its simulator is freed (nothing redrawn)."""
        with self._lock:
            self._teardown()

    def _show_live(self) -> None:
        app = self.app
        app.view.set_ground()
        app.view.show_live(True)
        cameras, self._cameras = self._cameras, {}
        start = (tuple(app.server.initial_camera.position), tuple(app.server.initial_camera.look_at))
        for cid, client in app.server.get_clients().items():
            place_camera(client, *cameras.get(cid, start))
        app.request_render()

    def _teardown(self) -> None:
        if self.runner is not None:
            self.runner.stop()
            self.runner = None
        if self.view is not None:
            self.view.remove()
            self.view = None
        if self.session is not None:
            self.session.core.close()
            self.session = None

    def status_lines(self) -> list[str] | None:
        """The status line's first lines while the grid runs (None when it does not)."""
        s, r = self.session, self.runner
        if s is None or r is None:
            return None
        return [f"**grid** · {s.task} · {s.name} · {s.n} envs · control step {s.steps}"
                f" · t = {s.steps * s.control_dt:.2f} s",
                f"real-time factor **{r.rtf:.2f}** · {r.fps:.0f} frames/s · the live session is paused "
                "(Stop grid goes back to it)"]

    def update_status(self) -> None:
        s, r, view = self.session, self.runner, self.view  # a stop on another thread may clear them
        if s is None or r is None or view is None:
            return
        if r.error is not None:
            self._say(f"⚠ grid stopped: {r.error}")
            return
        e = int(view.focus)
        self._say(f"**{s.task}** · {s.name} · {s.n} envs · control step {s.steps}  \n{s.readout(e)}")
