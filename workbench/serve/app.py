"""The web workbench: a viser server wired to a :class:`workbench.session.core.Workbench`.

    app = WorkbenchApp(Workbench.from_path("assets/scenes/arm.toml"), port=8080).start()
    ...
    app.stop()

The core holds all logic; this module only builds the page (its tabs: :mod:`workbench.panels`), runs the
sim thread (``session.runner.SimThread``) and redraws the scene (``view.scene.SceneView``).
"""
from __future__ import annotations

import collections
import threading
import time
from pathlib import Path

import numpy as np

import sim
from workbench.panels import (
    ComparePanel,
    ControlsPanel,
    EventsPanel,
    FitPanel,
    GridPanel,
    GuiGuard,
    MessageGuard,
    ObstaclesPanel,
    PlotsPanel,
    PolicyPanel,
    RenderPanel,
    ReplayPanel,
    finite_pose,
    guard_callbacks,
    only_value_updates,
)
from workbench.serve.handshake import Guard, start_viser
from workbench.serve.housekeeping import Housekeeping
from workbench.session import (
    HAND_EVENTS,
    ActionRefused,
    Folders,
    Frame,
    SimThread,
    Workbench,
    apply_gestures,
    point,
    ray_nearest_node,
)
from workbench.view import SceneView, boundary_of, scene_info


class WorkbenchApp:
    """Server + page + sim thread.

    Args:
        wb: the core session.
        host/port: where to serve (port 0 = any free port; read ``app.port``). Every request is checked
            (``workbench.serve.handshake``: loopback Host, same Origin, a token on a non-loopback bind).
        env_map: viser's HDRI lighting (off in tests: SwiftShader stalls on it).
        shadows: shadows on the floor at start (the Display tab toggles them; with software WebGL
            they are most of the page's cost of a frame).
        speed: initial real-time factor (``float('inf')`` = as fast as possible).
        recordings_dir / scenes_dir / data_dir / max_upload_mb: the folders the page may use (``workbench.session.files``).
        wait_for_browser: stay paused at frame 0 until the first page connects (:meth:`start`).
    """

    def __init__(self, wb: Workbench, *, host: str = "127.0.0.1", port: int = 8080,
                 env_map: bool = True, shadows: bool = True, speed: float = 1.0, recordings_dir: str | Path | None = None,
                 scenes_dir: str | Path | None = None, max_upload_mb: float = 50.0, wait_for_browser: bool = True,
                 data_dir: str | Path | None = None):
        self.wb = wb
        self.wait_for_browser = wait_for_browser
        self.waiting_for_browser = False
        self.files = Folders.create(scenes_dir=scenes_dir, recordings_dir=recordings_dir,
                                    max_upload_mb=max_upload_mb, data_dir=data_dir)
        self.recordings_dir = self.files.recordings
        self.guard = Guard.for_host(host)
        self.checks = GuiGuard()
        try:
            self.server = start_viser(host, port, self.guard)
        except BaseException:
            self.files.cleanup()
            raise
        self.refused_values: dict[tuple[str, str], int] = {}  # (element label, why) -> count; bounded by the GUI
        if not only_value_updates(self.server, self._value_refused):
            self.stop_server_and_cleanup()
            raise RuntimeError("viser changed: GUI updates from the page could not be restricted to values")
        self.messages = MessageGuard()
        if not self.messages.install(self.server):
            self.stop_server_and_cleanup()
            raise RuntimeError("viser changed: the message types a client may send could not be restricted")
        self.callback_errors: dict[tuple[str, str], int] = {}  # (exception type, where) -> count
        if not guard_callbacks(self.server, self._callback_failed):
            self.stop_server_and_cleanup()
            raise RuntimeError("viser changed: the workbench's callbacks could not be guarded")
        self.server.gui.configure_theme(control_width="large", show_share_button=False)
        self.view = SceneView(self.server, wb.live.n_nodes, env_map=env_map, shadows=shadows)
        self._draw_lock = threading.Lock()  # one frame drawn at a time (:meth:`_render`)
        self.render_hooks: list = []  # called with each drawn frame after the view (ghost of a compared episode)
        self.status_note = ""  # a line appended to the status (video progress)
        self.notice = ("", 0.0)  # (text, when): why the last page action failed, shown for NOTICE_S
        self.compiling = ""  # what kernel is being compiled (shown in the status line); "" when none
        # the page's hand gestures (press on the tube and drag), in the page's order; the sim thread applies them
        self._hand_events: collections.deque = collections.deque(maxlen=HAND_EVENTS)
        self.thread = SimThread(wb, self._render, speed=speed, prepare=self._compile_kernels,
                                inputs=self._apply_hand_events)
        self.housekeeping = Housekeeping(self.server)
        self.controls = ControlsPanel(self)
        self.panels = [self.controls]
        self._build_optional_panels()
        self._last_gui = 0.0
        self._gui_late = False
        self._camera_key: tuple | None = None  # the scene the camera was last fitted to (fit_camera_to_scene)
        wb.on_scene_changed.append(self._scene_changed)
        self._scene_changed()
        self._bind_hand()

    def _build_optional_panels(self) -> None:
        self.obstacles = ObstaclesPanel(self)
        self.policy = PolicyPanel(self)
        self.replay = ReplayPanel(self)
        self.plots = PlotsPanel(self)
        self.pictures = RenderPanel(self)
        self.grid = GridPanel(self)
        self.compare = ComparePanel(self)
        self.events = EventsPanel(self)
        self.fit = FitPanel(self)
        self.panels += [self.obstacles, self.policy, self.replay, self.plots, self.pictures, self.grid, self.compare,
                        self.events, self.fit]

    def _value_refused(self, label: str, why: str) -> None:
        n = self.refused_values.get((label, why), 0)
        self.refused_values[(label, why)] = n + 1
        if n == 0:  # one line per element and reason, however often a client repeats it
            print(f"rodlab workbench: refused a value for {label!r} from a client: {why}", flush=True)

    def _callback_failed(self, exc: BaseException) -> None:
        """A page action failed: the status line says why; an unexpected error is also logged, with its
        traceback, once per kind and place."""
        if isinstance(exc, ActionRefused):
            self.notice = (f"⚠ {exc}", time.monotonic())
            return
        import traceback

        tb = traceback.extract_tb(exc.__traceback__)
        where = f"{tb[-1].filename}:{tb[-1].lineno}" if tb else "?"
        key = (type(exc).__name__, where)
        n = self.callback_errors.get(key, 0)
        self.callback_errors[key] = n + 1
        self.notice = (f"⚠ that action failed: {type(exc).__name__}: {str(exc)[:200]}", time.monotonic())
        if n == 0:
            print(f"rodlab workbench: a page action failed ({type(exc).__name__} at {where}):", flush=True)
            traceback.print_exception(type(exc), exc, exc.__traceback__)

    @property
    def port(self) -> int:
        return self.server.get_port()

    @property
    def url(self) -> str:
        """The page's address (with the per-launch token when bound to a non-loopback address)."""
        return self.guard.url(self.port)

    def start(self) -> "WorkbenchApp":
        """Start the sim thread. With ``wait_for_browser`` (the default) the session stays paused at frame 0
        until the first page connects, so the first view is the start of the session."""
        if self.wait_for_browser and not self.server.get_clients():
            self.waiting_for_browser = True
            self.wb.set_playing(False)
            self.controls.set_quiet(self.controls.playing, False)
            self.server.on_client_connect(self._first_client)
        self._render(self.wb.frame())
        self.view.flush()  # the first frame whole at once (no earlier tube for the page to show meanwhile)
        self.fit_camera_to_scene()
        self.thread.start()
        self.housekeeping.start()
        return self

    def fit_camera_to_scene(self) -> None:
        """A new scene (another rod, a task opened or closed) opens framed by the camera: facing its plane when it is
        planar (a 2-D task or scene), the oblique view otherwise. Obstacle edits and moves keep the camera."""
        m = self.wb.live.model
        planar = bool(getattr(self.wb.policy, "planar", False)) or m.mode == "2d"
        rest = np.asarray(m.rest_node_pos, np.float64)
        key = (planar, m.node_count, *np.round(rest.min(axis=0), 3), *np.round(rest.max(axis=0), 3))
        if key != self._camera_key:
            self._camera_key = key
            self.view.set_camera("front" if planar else "iso", frame=self.wb.frame())

    def _compile_kernels(self) -> None:
        """Compile (or load from numba's cache) the step kernels before the first step, in the sim thread, saying in
        the status line what is being compiled: the first start compiles for minutes, and the page would otherwise
        show the last status of a session that does not move. ``sim.compile_kernels`` is looked up at call time (a
        test replaces it with a slow stand-in)."""

        def stage(what: str) -> None:
            self.compiling = what
            self.controls.update_status()  # the sim thread is busy: nothing else refreshes it meanwhile

        try:
            sim.compile_kernels(on_stage=stage)
        finally:
            self.compiling = ""
            self.request_render()

    def _first_client(self, _client) -> None:
        if not self.waiting_for_browser:
            return
        self.waiting_for_browser = False
        self.wb.set_playing(True)
        self.controls.set_quiet(self.controls.playing, True)
        self.request_render()

    def stop(self) -> None:
        """Stop every thread the session started (its stepping thread, a running grid, a video being recorded),
        close an open recording and the server."""
        self.housekeeping.stop()
        self.thread.stop()
        for p in self.panels:  # a panel's own threads end with the session
            close = getattr(p, "close", None)
            if close is not None:
                close()
        self.view.rod.tube.close()  # no delayed tube swap after the server has gone
        rec, self.wb.recorder = self.wb.recorder, None  # no lock: the sim thread may be mid-step
        if rec is not None:
            rec.close()
        self.server.stop()
        self.files.cleanup()

    def stop_server_and_cleanup(self) -> None:
        self.server.stop()
        self.files.cleanup()

    def request_render(self) -> None:
        self.thread.request_render()

    # ------------------------------------------------------------------ callbacks
    def _scene_changed(self) -> None:
        if self.wb.mode == "replay":
            return
        planar = bool(getattr(self.wb.policy, "planar", False))
        self.controls.set_planar(planar)
        self.controls.sync_gravity()
        self.sync_obstacle_view()
        self.fit_camera_to_scene()
        self.sync_boundary_view()
        self.controls.set_rods(self.wb.teleop_rods(), self.wb.teleop_rod)
        self.refresh_rod_scene()

    def refresh_rod_scene(self) -> None:
        """Redraw the rest shape and control points of the live scene (the steered rod's)."""
        self.view.set_rod_scene(*scene_info(self.wb), self.wb.live.rod_radius, self.wb.live.rod_offsets)
        self.request_render()

    def sync_boundary_view(self) -> None:
        """Redraw the fixed nodes, fixed twists and loads of the live scene."""
        with self.wb.lock:
            b = boundary_of(self.wb.live.model)
        self.view.set_boundary(b)

    def sync_obstacle_view(self) -> None:
        """Redraw the live obstacles: clickable, the gizmo on the one selected in the Obstacles tab."""
        self.view.sync_obstacles(self.wb.obstacles, self._on_gizmo, on_select=self.obstacles.select,
                                 selected=self.obstacles.selected_index())

    def _on_gizmo(self, index: int, position, wxyz) -> None:
        pose = finite_pose(position, wxyz)
        if pose is None or not 0 <= index < len(self.wb.obstacles):  # not finite / far away: ignored
            return
        self.wb.set_obstacle_pose(index, *pose)
        self.obstacles.show_pose(index)
        self.request_render()

    def _bind_hand(self) -> None:
        """Press on the rod and drag: the hand pulls the rod (``Workbench.grab`` / ``move_hand`` /
        ``release``, workbench.session.pull). The callback runs on the server's event loop, in the order the page sent the
        drag's start, moves and end, and only queues them: the sim thread applies them between steps."""
        async def on_drag(ev) -> None:
            self._hand_events.append((ev.phase, ev.start_position, ev.end_position))
            self.request_render()

        self.view.rod.on_grab(on_drag)
        self.view.rod.on_pick(self._pick)
        self.view.rod.on_bend(self._bend)

    def _bend(self, node: int, ev) -> None:
        """A control point's bead dragged: the sliders become the curvature that holds that node where the pointer
        is, at equilibrium (``Workbench.reach_to``, as Reach does for the tip); the live rod follows."""
        if ev.phase == "start":
            return
        try:
            target = point(ev.end_position, "control point target")
        except ValueError as exc:
            self.notice = (f"⚠ {exc}", time.monotonic())
            return
        self.wb.reach_to(target, node=node)
        self.controls.sync_sliders()

    def _pick(self, nodes: tuple[int, ...], ev) -> None:
        """A click on the rod pins (or unpins) a readout at the clicked node nearest the pointer's ray
        (workbench.session.pins)."""
        fr = self.view.last_frame
        if fr is None or not all(0 <= k < len(fr.node_pos) for k in nodes):
            return
        try:
            origin, direction = point(ev.ray_origin, "ray origin"), point(ev.ray_direction, "ray direction")
        except ValueError:  # not a ray a page sends
            return
        self.view.toggle_pin(ray_nearest_node(np.asarray(fr.node_pos), nodes, origin, direction))
        self.request_render()

    def _apply_hand_events(self) -> bool:
        """Apply the queued hand gestures (in the sim thread); a refused one is said in the status line. Returns
        whether there were any."""
        return apply_gestures(self._hand_events, self.wb.grab, self.wb.move_hand, self.wb.release,
                              lambda exc: setattr(self, "notice", (f"⚠ {exc}", time.monotonic())),
                              errors=(ValueError, ActionRefused))

    def _run_hooks(self, fr: Frame) -> None:
        for hook in list(self.render_hooks):
            hook(fr)

    def _render(self, fr: Frame) -> None:
        """Draw ``fr`` and call the render hooks with it. The stepping thread and a video being recorded both
        draw: one frame is drawn whole (view and hooks) before another starts, so the page never shows parts of
        two frames."""
        with self._draw_lock:
            self._draw(fr)

    def _draw(self, fr: Frame) -> None:
        # a recording does not carry fixes and loads; the hooks draw with the frame's tube (SceneView.render)
        self.view.render(fr, boundary=self.wb.mode != "replay", on_shown=self._run_hooks)
        now = time.perf_counter()
        if now - self._last_gui > 0.2:
            self._last_gui = now
            self._gui_late = False
            for p in self.panels:
                upd = getattr(p, "update_status", None)
                if upd is not None:
                    upd()
        elif not self._gui_late:  # readouts skipped: one more redraw soon, so a paused page is not left stale
            self._gui_late = True
            t = threading.Timer(0.25, self.request_render)
            t.daemon = True
            t.start()
