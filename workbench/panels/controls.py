"""GUI: status line, play controls, display toggles, teleop sliders."""
from __future__ import annotations

import time

import numpy as np

from sim.geometry import matrix_to_quat, quat_to_matrix
from workbench.panels.host import PanelHost
from workbench.session import CONTROL_NODES, KAPPA_LIMIT, QUANTITIES, TWIST_LIMIT, colorbar_html
from workbench.view import ARROW_MODES, CAMERAS

COMP_LABELS = ("κ1", "κ2", "τ")
NOTICE_S = 10.0  # [s] a failed page action is named in the status line this long


KEYS_HELP = ("Keys: **space** play / pause · **→** one step or frame (pauses; a replay too) · **r** reset · **[ ]** previous / next event "
             "(not while typing in a field) · **drag the rod** to pull it (a spring from your hand, its force shown "
             "in N; release lets go) · **drag a yellow bead** to bend the rod there · **click the rod** to pin a readout "
             "at a node · drag empty space to turn the view")
TABS = ("Run", "Teleop", "Obstacles", "Policy", "Recordings", "Plots", "Fit", "Display")


REACH_GIZMO_SCALE = 0.2  # [m] size of the Reach target's gizmo
REACH_LIMIT_M = 10.0  # [m] targets farther from the origin are not taken


def slider_label(k: int, comp: int, nodes: tuple[int, ...] = CONTROL_NODES) -> str:
    """Label of the teleop slider for control point k (0..4) and component comp (0..2); ``nodes``: the steered rod's
    control points (node indices within that rod)."""
    return f"{COMP_LABELS[comp]} at node {nodes[k]} [rad]"


def slider_hint(k: int, comp: int, nodes: tuple[int, ...] = CONTROL_NODES) -> str:
    what = ("bend about the first material axis (in-plane bend in 2-D tasks)", "bend about the second material axis",
            "twist about the centreline")[comp]
    return (f"{what} given to the nodes around node {nodes[k]}. Absolute mode: the integrated natural "
            f"{'twist' if comp == 2 else 'curvature'} of that region [rad] (docs/tasks.md §2.3-2.4). Delta mode: "
            "the action in [-1, 1] added once per control step")


class ControlsPanel:
    def __init__(self, app: PanelHost):
        self.app = app
        gui = app.server.gui
        wb = app.wb
        self.status = gui.add_markdown("starting…")
        self.colorbar = gui.add_html("")  # above the tabs: the rod's colours read the same whichever tab is open
        self.msg = gui.add_markdown("")
        group = gui.add_tab_group()
        app.tabs = {name: group.add_tab(name) for name in TABS}
        with app.tabs["Run"]:
            self.playing = gui.add_checkbox("Playing", initial_value=wb.playing, hint="run the simulation")
            self.step_btn = gui.add_button("Step", hint="pause and advance one sim step")
            self.reset_btn = gui.add_button("Reset", hint="fresh rod (a new episode while a policy runs)")
            self.gravity = gui.add_checkbox("Gravity", initial_value=True,
                                            hint="gravity on/off (teleop only: a task keeps its own)")
            self.speed = gui.add_slider("Speed [× real time]", min=0.1, max=4.0, step=0.1, initial_value=1.0,
                                        hint="simulated seconds per wall-clock second")
            self.keys_help = gui.add_markdown(KEYS_HELP)
        with app.tabs["Display"]:
            self.color_by = gui.add_dropdown("Colour by", QUANTITIES, initial_value="curvature",
                                             hint="rod colour: |κ| curvature, signed material curvatures κ1/κ2, twist, "
                                                  "axial strain, or commanded − actual curvature (integrated values, "
                                                  "docs/physics.md §1.4)")
            self.color_range = gui.add_dropdown("Colour range", ("auto", "fixed"), initial_value="auto",
                                                hint="auto: the largest value in the frame; fixed: the value below")
            self.color_max = gui.add_number("Fixed range max", initial_value=0.5, min=1e-6, max=100.0, step=0.01,
                                            hint="largest |value| of the colour map when the range is fixed")
            self.frames = gui.add_checkbox("Material frames", initial_value=False,
                                           hint="the material frame (m1, m2, tangent) of every edge")
            self.contacts = gui.add_checkbox("Contacts", initial_value=True, hint="contact points and forces")
            self.arrows = gui.add_dropdown("Force arrows", ARROW_MODES, initial_value="log",
                                           hint="contact arrow length: log (small and large forces both readable), "
                                                "auto (largest force = 25 cm) or linear (the m/N below); each "
                                                "arrow's force in N is written at its tip")
            self.force_scale = gui.add_slider("Force arrow [m/N]", min=0.0005, max=0.05, step=0.0005,
                                              initial_value=0.005, hint="arrow length per newton (linear arrows)")
            self.control_points = gui.add_checkbox("Control points", initial_value=True,
                                                   hint="yellow beads on the nodes whose natural curvature the "
                                                        "sliders or the policy command (docs/tasks.md §2.1)")
            self.rest_shape = gui.add_checkbox("Rest shape", initial_value=True,
                                               hint="faint tube: the rod's rest configuration (no commanded "
                                                    "curvature, no load)")
            self.trail = gui.add_checkbox("Tip trail", initial_value=True,
                                          hint="the tip's path over the last 2 s of simulated time (cleared on "
                                               "reset)")
            self.tip_frame = gui.add_checkbox("Tip frame", initial_value=True,
                                              hint="the tip's material frame (m1 red, m2 green, tangent blue); in "
                                                   "the IK task beside the target's frame")
            self.shadows = gui.add_checkbox("Shadows", initial_value=app.view.shadows,
                                            hint="shadows on the floor; turn them off when the page is slow (software "
                                                 "WebGL, where they are most of the cost of a frame)")
            self.boundary = gui.add_checkbox("Fixes and loads", initial_value=True,
                                             hint="boxes on the fixed nodes (black: clamped, teal: pinned, every "
                                                  "axis fixed; white: some axes fixed), rings on edges whose twist "
                                                  "is fixed, and an arrow along each point load while it acts "
                                                  "(length as the force arrows; its force in N, torque in N·m)")
            self.clear_pins = gui.add_button("Clear pins",
                                             hint="click the rod to pin a readout at the nearest node (position, "
                                                  "speed, κ1/κ2 against the commanded natural curvature, twist, "
                                                  "strain; up to 4, following the node live and in replays); click "
                                                  "a pinned node again to unpin it")
            self.camera = gui.add_button_group("Camera", ("front", "side", "top", "iso"),
                                               hint="view presets: front looks along +y at the x-z plane")
            self.fit_view = gui.add_button("Fit view", hint="frame the rod, its targets and obstacles from the "
                                                             "direction you look from now")
            self.follow = gui.add_checkbox("Follow tip", initial_value=False,
                                           hint="the camera looks at the tip every frame, keeping its distance "
                                                "and direction (orbit and zoom still work)")
        with app.tabs["Teleop"]:
            rods = wb.teleop_rods()
            self.rod = gui.add_dropdown("Rod", rods, initial_value=rods[wb.teleop_rod],
                                        hint="the rod the sliders steer (a scene of several rods); the others keep "
                                             "the curvature they were last given")
            self.rod.visible = len(rods) > 1
            self.mode = gui.add_dropdown("Teleop mode", ("absolute", "delta"), initial_value="absolute",
                                         hint="absolute: sliders are the natural curvature; delta: actions as a "
                                              "policy sends them")
            self.sliders: list[list] = []
            for k in range(5):
                row = []
                for c in range(3):
                    lim = TWIST_LIMIT if c == 2 else KAPPA_LIMIT
                    s = gui.add_slider(slider_label(k, c), min=-round(lim, 2), max=round(lim, 2),
                                       step=0.01, initial_value=0.0, hint=slider_hint(k, c))
                    row.append(s)
                self.sliders.append(row)
            self.zero_btn = gui.add_button("Zero sliders", hint="every slider back to 0")
            self.reach = gui.add_checkbox("Reach", initial_value=False,
                                          hint="drag the target at the tip and the arm follows: the sliders become the "
                                               "curvature that holds the tip there at equilibrium (inverse statics, "
                                               "docs/physics.md §3.10; obstacles left out)")
            self.reach_frame = gui.add_checkbox("Reach frame", initial_value=False,
                                                hint="turn the target too: the tip's frame follows it, the twist "
                                                     "sliders with the bending ones (3-D scenes)")
        self.reach_gizmo = None  # the target's transform gizmo while Reach is on
        self._syncing = False
        for h in (self.speed, self.color_by, self.color_range, self.color_max, self.arrows, self.force_scale, self.mode, self.rod, *(s for row in self.sliders for s in row)):
            app.checks.track(h)
        self._wire()

    def _say(self, text: str) -> None:
        self.msg.content = text

    def _wire(self) -> None:
        app, wb = self.app, self.app.wb
        ok = app.checks

        @self.playing.on_update
        def _(_e) -> None:
            # the box only shows the session's state when the server sets it (sync_sliders, set_quiet): a late
            # sync that read the state before another thread changed it must not pause or start the session
            if not self._syncing:
                wb.set_playing(self.playing.value)
                app.request_render()  # a paused session draws nothing by itself: the readouts (a replay's Play box,
                # "paused" in the status line) follow at this redraw

        @self.step_btn.on_click
        def _(_e) -> None:
            wb.set_playing(False)
            self.set_quiet(self.playing, False)
            wb.step()
            app.request_render()

        @self.reset_btn.on_click
        def _(_e) -> None:
            wb.reset()
            self.sync_sliders()
            app.request_render()

        @self.gravity.on_update
        def _(_e) -> None:
            if not self._syncing:  # not when the box only shows a new scene's gravity
                wb.set_gravity(self.gravity.value)

        @self.speed.on_update
        def _(_e) -> None:
            if ok.number(self.speed, self._say):
                app.thread.speed = float(self.speed.value)

        @self.color_by.on_update
        def _(_e) -> None:
            if not ok.option(self.color_by, self._say):
                return
            app.view.overlays.color_by = self.color_by.value
            app.request_render()

        @self.color_range.on_update
        @self.color_max.on_update
        def _(_e) -> None:
            if not (ok.option(self.color_range, self._say) and ok.number(self.color_max, self._say, 1e-6, 100.0)):
                return
            fixed = self.color_range.value == "fixed"
            app.view.overlays.color_fixed = float(self.color_max.value) if fixed else None
            app.request_render()

        @self.frames.on_update
        def _(_e) -> None:
            app.view.overlays.frames = self.frames.value
            app.request_render()

        @self.shadows.on_update
        def _(_e) -> None:
            app.view.set_shadows(self.shadows.value)

        @self.contacts.on_update
        def _(_e) -> None:
            app.view.overlays.contacts = self.contacts.value
            app.request_render()

        def _toggle(handle, attr: str) -> None:
            @handle.on_update
            def _(_e) -> None:
                setattr(app.view.overlays, attr, bool(handle.value))
                app.request_render()

        for handle, attr in ((self.control_points, "control_points"), (self.rest_shape, "rest_shape"),
                             (self.trail, "trail"), (self.tip_frame, "tip_frame"), (self.boundary, "boundary"),
                             (self.follow, "follow_tip")):
            _toggle(handle, attr)

        @self.arrows.on_update
        def _(_e) -> None:
            if not ok.option(self.arrows, self._say):
                return
            app.view.overlays.arrows = self.arrows.value
            app.request_render()

        @self.force_scale.on_update
        def _(_e) -> None:
            if not ok.number(self.force_scale, self._say):
                return
            app.view.overlays.force_scale = float(self.force_scale.value)
            app.request_render()

        @self.mode.on_update
        def _(_e) -> None:
            if not ok.option(self.mode, self._say):
                return
            wb.set_teleop_mode(self.mode.value)
            self.sync_sliders()

        @self.rod.on_update
        def _(_e) -> None:
            if self._syncing or not ok.option(self.rod, self._say):
                return
            wb.set_teleop_rod(list(self.rod.options).index(self.rod.value))
            self.label_sliders()  # the chosen rod's control points (rods of different lengths differ)
            self.sync_sliders()
            app.refresh_rod_scene()

        for k in range(5):
            for c in range(3):
                s = self.sliders[k][c]

                def _cb(_e, k=k, c=c, s=s) -> None:
                    if not self._syncing and ok.number(s, self._say):
                        wb.set_teleop_value(k, c, float(s.value))

                s.on_update(_cb)

        @self.clear_pins.on_click
        def _(_e) -> None:
            app.view.pins = []
            app.request_render()

        @self.camera.on_click
        def _(_e) -> None:
            if self.camera.value in CAMERAS:
                app.view.set_camera(self.camera.value)

        @self.fit_view.on_click
        def _(e) -> None:
            if e.client is not None:  # the page that asked: the others keep their views
                app.view.fit_view(e.client)

        @self.reach.on_update
        def _(_e) -> None:
            self.show_reach(bool(self.reach.value))

        @self.reach_frame.on_update
        def _(_e) -> None:
            if self.reach_frame.value and wb.tip_frame is None:
                self.reach_frame.value = False
                self._say("Reach frame: a 2-D scene has no tip frame to turn")
                return
            if self.reach.value:  # the gizmo again, with its rotation rings or without
                self.show_reach(True)

        @self.zero_btn.on_click
        def _(_e) -> None:
            with wb.lock:
                for k in range(5):
                    for c in range(3):
                        wb.set_teleop_value(k, c, 0.0)
            self.sync_sliders()

    def show_reach(self, on: bool) -> None:
        """Reach on: a target gizmo at the tip, each move of it sets the sliders by inverse statics
        (``Workbench.reach_to``); off: the gizmo goes."""
        app, wb = self.app, self.app.wb
        if self.reach_gizmo is not None:
            self.reach_gizmo.remove()
            self.reach_gizmo = None
        app.view.rod.grip_enabled = not on  # the target's gizmo sits on the tip: a press there is the gizmo's
        app.request_render()
        if not on:
            return
        if wb.mode != "teleop" or len(wb.teleop_rods()) > 1:
            app.view.rod.grip_enabled = True
            self.reach.value = False
            self._say("Reach steers one rod by hand: stop the policy (or take over), one rod in the scene")
            return
        frame = wb.tip_frame if self.reach_frame.value else None  # the target's frame starts as the tip's
        g = app.server.scene.add_transform_controls(
            "/reach_target", scale=REACH_GIZMO_SCALE, disable_rotations=frame is None,
            position=tuple(float(v) for v in wb.tip), depth_test=False,
            wxyz=(1.0, 0.0, 0.0, 0.0) if frame is None else tuple(float(v) for v in matrix_to_quat(frame)))

        def _moved(_event) -> None:
            pos = np.asarray(g.position, dtype=np.float64)
            if pos.shape != (3,) or not np.all(np.isfinite(pos)) or np.abs(pos).max() > REACH_LIMIT_M:
                self._say(f"Reach: a target beyond ±{REACH_LIMIT_M:g} m is ignored")
                return
            orientation = None
            if frame is not None:
                q = np.asarray(g.wxyz, dtype=np.float64)
                if q.shape != (4,) or not np.all(np.isfinite(q)) or np.linalg.norm(q) < 1e-6:
                    self._say("Reach frame: the target's orientation is not a rotation; ignored")
                    return
                orientation = quat_to_matrix(q / np.linalg.norm(q))
            err = wb.reach_to(pos, orientation=orientation)
            self.sync_sliders()
            off = [] if err < 1e-3 else [f"{err * 100:.1f} cm"]
            if orientation is not None and not wb.reach_angle < 1e-2:
                off.append(f"{np.degrees(wb.reach_angle):.1f}°")
            self._say("" if not off else f"Reach: the closest equilibrium found is {' and '.join(off)} from the "
                                         "target (out of reach, or still converging: move on)")

        g.on_update(_moved)
        self.reach_gizmo = g

    def set_rods(self, names: list[str], current: int) -> None:
        """The rods of the live scene in the Rod dropdown (shown only with several rods), and the sliders' labels
        naming the steered rod's control points."""
        self.label_sliders()
        self._syncing = True
        try:
            if tuple(self.rod.options) != tuple(names):
                self.rod.options = tuple(names)
            if self.rod.value != names[current]:
                self.rod.value = names[current]
        finally:
            self._syncing = False
        self.rod.visible = len(names) > 1
        self.app.checks.accept(self.rod)

    def label_sliders(self) -> None:
        """Each slider names the node of the steered rod it bends about (the control points scale with the rod)."""
        wb = self.app.wb
        with wb.lock:
            nodes = tuple(int(c) for c in wb.teleop.converter.cfg.control_points)
        for k, row in enumerate(self.sliders):
            for c, h in enumerate(row):
                label = slider_label(k, c, nodes)
                if h.label != label:
                    h.label = label
                    h.hint = slider_hint(k, c, nodes)

    def sync_gravity(self) -> None:
        """The Gravity box of the live scene: ticked when gravity acts, greyed out where there is none to switch (a
        scene without gravity) or it is the task's (a policy run)."""
        wb = self.app.wb
        with wb.lock:
            spec = getattr(wb.live, "base_spec", None)
            g = np.asarray(getattr(getattr(spec, "sim", None), "gravity", (0.0, 0.0, 0.0)), dtype=np.float64)
            has = bool(np.any(g != 0.0))
            on = has and bool(wb.live.gravity)
            task = wb.policy is not None
        self.gravity.disabled = not has or task
        if self.gravity.value != on:
            self.set_quiet(self.gravity, on)

    def set_planar(self, planar: bool) -> None:
        """2-D tasks: only the in-plane (κ1) sliders are shown."""
        for row in self.sliders:
            for c in (1, 2):
                if row[c].visible == planar:
                    row[c].visible = not planar

    def set_quiet(self, handle, value) -> None:
        """Set a GUI value without running our own callback logic."""
        self._syncing = True
        try:
            handle.value = value
        finally:
            self._syncing = False

    def sync_sliders(self) -> None:
        """Show the core's teleop values (after mode switch, reset, rewind, take-over)."""
        wb = self.app.wb
        with wb.lock:
            mode = wb.teleop.mode
            vals = wb.teleop.values.copy()
        delta = mode == "delta"
        self._syncing = True
        try:
            if self.mode.value != mode:
                self.mode.value = mode
            for k in range(5):
                for c in range(3):
                    s = self.sliders[k][c]
                    lim = 1.0 if delta else (TWIST_LIMIT if c == 2 else KAPPA_LIMIT)
                    s.min, s.max = -round(lim, 2), round(lim, 2)
                    s.value = float(np.round(vals[k, c], 2))
            self.playing.value = wb.playing
        finally:
            self._syncing = False
        for row in self.sliders:
            for s in row:
                self.app.checks.accept(s)
        self.app.checks.accept(self.mode)

    def update_status(self) -> None:
        app, wb = self.app, self.app.wb
        th = app.thread
        fr = app.view.last_frame
        tip = fr.tip if fr is not None else np.zeros(3)
        rp = wb.replay if wb.mode == "replay" else None
        if rp is not None:
            head = (f"**replay** · episode {rp.episode_index} · frame {rp.index} / {rp.length - 1}"
                    f" · t = {fr.time if fr else 0.0:.2f} s{'' if rp.playing else ' · paused'}")
        else:
            head = (f"**{wb.mode}**{' (hand)' if wb.hand_control else ''} · frame {wb.frame_index}"
                    f" · t = {fr.time if fr else 0.0:.2f} s")
            compiling = getattr(app, "compiling", "")
            if compiling:  # the first start: minutes (cached afterwards)
                head += f" · compiling kernels: {compiling} (first start only, cached afterwards) …"
            elif app.waiting_for_browser:
                head += " · paused until a browser connects"
            elif not wb.playing:
                head += " · paused"
        grid = getattr(app, "grid", None)
        grid_lines = grid.status_lines() if grid is not None else None
        if grid_lines:  # a grid of envs is drawn in place of the paused live scene: the status is the grid's
            lines = grid_lines
            fr = None
        else:
            lines = [head,
                     f"real-time factor **{th.rtf:.2f}** · step {th.step_ms:.1f} ms · {th.fps:.0f} frames/s",
                     f"tip ({tip[0]:+.3f}, {tip[1]:+.3f}, {tip[2]:+.3f}) m"]
        if fr is not None and getattr(fr, "hand", None) is not None and fr.hand_force is not None:
            lines.append(f"pulling by hand · **{float(np.linalg.norm(fr.hand_force)):.3g} N** · release to let go")
        if fr is not None:
            line = contact_status(fr)
            if line:
                lines.append(line)
        if fr is not None and fr.scalars:
            keys = [k for k in ("reward", "tip_error", "newton_iters", "contact_force") if k in fr.scalars]
            lines.append(" · ".join(f"{k} {fr.scalars[k]:.3g}" for k in keys))
        bar = colorbar_html(*app.view.color_range)
        if self.colorbar.content != bar:
            self.colorbar.content = bar
        if th.error is not None:
            lines.append(f"⚠ error: {th.error}")
        if getattr(app, "status_note", ""):
            lines.append(app.status_note)
        note, at = getattr(app, "notice", ("", 0.0))
        if note and time.monotonic() - at < NOTICE_S:
            lines.append(note)
        self.status.content = "  \n".join(lines)


def contact_status(fr) -> str:
    """The status line's contact summary of frame ``fr``: how many contacts and the net contact force on the rods
    (the vector sum: what holds the rods up or pushes them; two rods pressing each other add nothing to it), every
    contact counted where the step reported its total (live sessions), else the sum of the rows drawn (replays);
    contacts the step's report did not list are said. Empty without contacts."""
    listed = len(fr.contact_points)
    dropped = int(fr.scalars.get("contact_dropped", 0.0))
    if listed + dropped == 0:
        return ""
    net = fr.scalars.get("contact_net_force")
    if net is None:
        net = float(np.linalg.norm(np.asarray(fr.contact_forces, np.float64).sum(axis=0)))
    line = f"contacts {listed + dropped} · net contact force **{net:.3g} N**"
    if dropped:
        line += f" · {dropped} not drawn this step (the report grows for the next)"
    return line
