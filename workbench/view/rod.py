"""The rod in the 3-D view: smooth tube, control points, faint rest shape, tip trail, tip frame.

The tube is ONE mesh for the whole rod (``workbench.view.tube``: per-vertex normals and colours), shown as a GLB asset,
the only viser node with per-vertex colours. The page drops a GLB while it parses a new one, so two GLB nodes take
turns: each frame's mesh goes into the hidden one, which is shown at the next frame (or after ``SWAP_DELAY`` when
no frame follows), once the page has had time to parse it. Everything else of that frame (control points, trail,
tip frame, the grip; and what the caller draws, ``on_shown``) is drawn in the same message batch as the swap that
shows its tube, so the page shows one frame whole: the view lags the simulation by one frame at most, all of it.
"""
from __future__ import annotations

import collections
import threading
from typing import Callable

import numpy as np
import trimesh

from sim.geometry import matrix_to_quat, quat_z_to
from workbench.session import Frame, rod_edges
from workbench.view.tube import SIDES, glb_bytes, rods_mesh, tube_mesh

SWAP_DELAY = 0.08  # [s] a tube sent this long ago is shown even if no newer frame comes
GRIP_SCALE = 1.15  # the grip's radius over the rod's (around the tube; the control points' beads, 1.3, stand out)
TRAIL_SECONDS = 2.0  # [s] of simulated time kept in the tip trail
REST_OPACITY = 0.18
CONTROL_COLOR = (250, 210, 30)
TRAIL_COLOR = (90, 60, 200)


class DoubleBufferedGlb:
    """Two GLB nodes under ``name`` showing one mesh: the newest bytes go to the hidden node, which is shown at the
    next :meth:`put` or after ``SWAP_DELAY``; the ``on_shown`` given with them is called when they are shown (in
    the same message batch, under the buffer's lock: the frame's other nodes go with its tube)."""

    def __init__(self, server, name: str, first: bytes):
        self.server = server
        sc = server.scene
        self.nodes = [sc.add_glb(f"{name}/a", first, visible=True), sc.add_glb(f"{name}/b", first, visible=False)]
        self.front = 0
        self.pending = False
        self.shown = True  # the overlay's own visibility
        self._lock = threading.RLock()  # on_shown runs under it, and may show or hide the tube (set_visible)
        self._timer: threading.Timer | None = None
        self._on_shown: Callable[[], None] | None = None

    def _swap(self) -> None:
        back = 1 - self.front
        self.nodes[back].visible = self.shown
        self.nodes[self.front].visible = False
        self.front = back
        self.pending = False
        done, self._on_shown = self._on_shown, None
        if done is not None:
            done()

    def put(self, data: bytes, on_shown: Callable[[], None] | None = None) -> None:
        with self._lock:
            if self.pending:
                self._swap()
            self.nodes[1 - self.front].glb_data = data
            self._on_shown = on_shown
            self.pending = True
            if self._timer is None or not self._timer.is_alive():
                self._timer = threading.Timer(SWAP_DELAY, self.flush)
                self._timer.daemon = True
                self._timer.start()

    def flush(self) -> None:
        """Show the newest bytes now (the page has had ``SWAP_DELAY`` to parse them)."""
        with self.server.atomic(), self._lock:
            if self.pending:
                self._swap()

    def close(self) -> None:
        """Cancel a pending swap (before the server stops)."""
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
            self.pending = False
            self._on_shown = None

    def set_visible(self, on: bool) -> None:
        with self._lock:
            self.shown = bool(on)
            if self.nodes[self.front].visible != self.shown:
                self.nodes[self.front].visible = self.shown

    @property
    def visible_node(self):
        return self.nodes[self.front]


class RodView:
    """Scene nodes of one rod (under ``name``)."""

    def __init__(self, server, n_nodes: int, *, name: str = "/rod", sides: int = SIDES):
        self._nodes_lock = threading.RLock()  # set_scene (page callbacks) and render (the drawing thread)
        self.server = server
        self.sides = sides
        sc = server.scene
        x0 = np.stack([np.zeros(n_nodes), np.zeros(n_nodes), np.linspace(0.0, 1e-3, n_nodes)], 1)
        self.tube = DoubleBufferedGlb(server, f"{name}/tube", glb_bytes(tube_mesh(x0, 1e-4, sides=sides)))
        self.last_mesh = None  # the TubeMesh of the last frame (tests)
        sph = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
        self._sphere = sph
        self._name = name
        self.control_nodes: tuple[int, ...] = ()
        self.controls = None
        self.control_labels: list = []  # "node k" beside each control point's bead (the sliders name the same nodes)
        self.rest = None
        self.rest_nodes: np.ndarray | None = None
        self.trail = sc.add_line_segments(f"{name}/trail", np.zeros((1, 2, 3)), TRAIL_COLOR, thickness=2.5,
                                          thickness_units="screen", visible=False)
        self.trail_points: collections.deque = collections.deque()
        self.tip_frame = sc.add_frame(f"{name}/tip_frame", axes_length=0.1, axes_radius=0.006, visible=False)
        # what the pointer grabs: one unseen cylinder per edge around the tube. The tube's GLB is sent anew every
        # frame, and the page drops a drag when its node's mesh is replaced; the grip's cylinders only move.
        cyl = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=8)
        self._cylinder = cyl
        self.grip = None
        self._edges = np.zeros(0, dtype=np.int64)  # the rod edge of each grip cylinder
        self._on_grab = None
        self._on_pick = None
        self._on_bend = None
        self.grip_enabled = True  # off: presses go through the rod (Reach's target gizmo sits on the tip)

    # ------------------------------------------------------------------ per scene
    def set_scene(self, rest_nodes: np.ndarray | None, control_nodes, radius: float, rod_offsets=None) -> None:
        """The rest shape (N, 3) [m] (drawn as a faint tube, one per rod with ``rod_offsets``, see
        :func:`workbench.view.tube.rods_mesh`) and the control nodes (marked on the rod)."""
        with self._nodes_lock:  # one thread at a time rebuilds or draws these nodes
            return self._set_scene_unlocked(rest_nodes, control_nodes, radius, rod_offsets)

    def _set_scene_unlocked(self, rest_nodes: np.ndarray | None, control_nodes, radius: float, rod_offsets=None) -> None:
        sc = self.server.scene
        if self.rest is not None:
            self.rest.remove()
            self.rest = None
        self.rest_nodes = None if rest_nodes is None else np.asarray(rest_nodes, np.float64)
        if self.rest_nodes is not None:
            m = rods_mesh(self.rest_nodes, radius, rod_offsets, sides=self.sides)
            self.rest = sc.add_mesh_simple(f"{self._name}/rest", m.vertices, m.faces, color=(150, 150, 160),
                                           opacity=REST_OPACITY, cast_shadow=False, receive_shadow=False,
                                           visible=False)
        cn = tuple(int(c) for c in control_nodes)
        if cn != self.control_nodes or self.controls is None:
            if self.controls is not None:
                self.controls.remove()
            k = max(len(cn), 1)
            self.controls = sc.add_batched_meshes_simple(
                f"{self._name}/control_points", self._sphere.vertices, self._sphere.faces,
                batched_wxyzs=np.tile([1.0, 0.0, 0.0, 0.0], (k, 1)), batched_positions=np.zeros((k, 3)),
                batched_scales=np.full(k, 1e-4), batched_colors=np.tile(CONTROL_COLOR, (k, 1)), lod="off",
                visible=False)
            for lab in self.control_labels:
                lab.remove()
            self.control_labels = [sc.add_label(f"{self._name}/control_label_{c}", f"node {c}", visible=False,
                                                depth_test=False, anchor="bottom-left", font_screen_scale=0.8)
                                   for c in cn]
            self.control_nodes = cn
            if self._on_bend is not None or self._on_pick is not None:
                self._bind_bend()
        self.clear_trail()

    def clear_trail(self) -> None:
        self.trail_points.clear()

    # ------------------------------------------------------------------ per frame
    def render(self, fr: Frame, colors: np.ndarray, ov, on_shown: Callable[[], None] | None = None) -> None:
        """Send frame ``fr``'s tube (call inside ``server.atomic()``); its control points, trail, tip frame and grip,
        then ``on_shown()``, are drawn when that tube is shown: at the next :meth:`render` or :meth:`flush`, or
        after ``SWAP_DELAY``. ``ov``: the view's ``Overlays`` (rest_shape, control_points, trail, tip_frame)."""
        with self._nodes_lock:  # one thread at a time rebuilds or draws these nodes
            x = np.asarray(fr.node_pos, np.float64)
            m1 = fr.m1 if fr.m1 is not None and len(fr.m1) == len(x) - 1 else None
            nr = fr.node_radius if fr.node_radius is not None and len(fr.node_radius) == len(x) else float(fr.rod_radius)
            mesh = rods_mesh(x, nr, getattr(fr, "rod_offsets", None), m1=m1, colors=colors, sides=self.sides)
            self.last_mesh = mesh
            data = glb_bytes(mesh)

        def shown() -> None:
            with self._nodes_lock:
                self._overlays(fr, x, m1, ov)
            if on_shown is not None:
                on_shown()
        self.tube.put(data, shown)

    def flush(self) -> None:
        """Show the last rendered frame now, whole (a paused page, a video frame, a test)."""
        self.tube.flush()

    def _overlays(self, fr: Frame, x: np.ndarray, m1, ov) -> None:
        r = float(fr.rod_radius)
        if self.rest is not None:
            show = bool(ov.rest_shape) and self.rest_nodes is not None and len(self.rest_nodes) == len(x)
            if self.rest.visible != show:
                self.rest.visible = show
        cn = [c for c in self.control_nodes if 0 <= c < len(x)]
        show_c = bool(ov.control_points) and bool(cn) and len(cn) == len(self.control_nodes)
        if show_c:
            self.controls.batched_positions = x[cn]
            self.controls.batched_scales = np.full(len(cn), 1.3 * r)
        if self.controls is not None and self.controls.visible != show_c:
            self.controls.visible = show_c
        for lab, c in zip(self.control_labels, self.control_nodes):  # just above and beside each bead
            if show_c:
                lab.position = tuple(x[c] + 1.5 * r)
            if lab.visible != show_c:
                lab.visible = show_c
        self._trail(fr, bool(ov.trail))
        self._tip_frame(fr, x, m1, bool(ov.tip_frame))
        self._grip(x, r, getattr(fr, "rod_offsets", None))

    # ------------------------------------------------------------------ the grip (workbench.session.pull)
    def on_grab(self, callback) -> None:
        """``callback(event)`` on every phase of a left-button drag that starts on the rod (viser's
        ``SceneNodeDragEvent``; ``start_position`` is where the rod was pressed)."""
        self._on_grab = callback
        if self.grip is not None:
            self.grip.on_drag("left")(callback)

    def on_pick(self, callback) -> None:
        """``callback(nodes, event)`` on a click on the rod: the nodes under the pointer (the two ends of the clicked
        edge, or a control point's node when its bead is clicked) and viser's ``SceneNodePointerEvent`` (its ray)."""
        self._on_pick = callback
        if self.grip is not None:
            self._bind_pick()
        if self.controls is not None:
            self._bind_bend()

    def on_bend(self, callback) -> None:
        """``callback(node, event)`` on every phase of a left-button drag that starts on a control point's bead:
        the control node and viser's ``SceneNodeDragEvent``."""
        self._on_bend = callback
        if self.controls is not None:
            self._bind_bend()

    def _bind_bend(self) -> None:
        nodes = self.control_nodes

        def dragged(ev) -> None:
            i = ev.instance_index
            if self._on_bend is not None and isinstance(i, int) and 0 <= i < len(nodes):
                self._on_bend(int(nodes[i]), ev)

        def clicked(ev) -> None:  # the bead covers the rod there: a click on it pins its node
            i = ev.instance_index
            if self._on_pick is not None and isinstance(i, int) and 0 <= i < len(nodes):
                self._on_pick((int(nodes[i]),), ev)

        self.controls.remove_drag_callback()
        self.controls.remove_click_callback()
        self.controls.on_drag("left")(dragged)
        self.controls.on_click(clicked)

    def _bind_pick(self) -> None:
        edges = self._edges

        def picked(ev) -> None:
            i = ev.instance_index
            if isinstance(i, int) and 0 <= i < len(edges):
                self._on_pick((int(edges[i]), int(edges[i]) + 1), ev)

        self.grip.on_click(picked)

    def _grip(self, x: np.ndarray, r: float, rod_offsets) -> None:
        k = rod_edges(len(x), rod_offsets)
        e = x[k + 1] - x[k]
        length = np.linalg.norm(e, axis=1)
        q = quat_z_to(e / np.maximum(length, 1e-12)[:, None])
        scales = np.stack([np.full(len(k), GRIP_SCALE * r), np.full(len(k), GRIP_SCALE * r), length], 1)
        mid = 0.5 * (x[k] + x[k + 1])
        if self.grip is None or not np.array_equal(self._edges, k):
            if self.grip is not None:
                self.grip.remove()
            c = self._cylinder
            self.grip = self.server.scene.add_batched_meshes_simple(
                f"{self._name}/grip", c.vertices, c.faces, batched_wxyzs=q, batched_positions=mid,
                batched_scales=scales, opacity=0.0, cast_shadow=False, receive_shadow=False, lod="off",
                visible=self.grip_enabled)
            self._edges = k
            if self._on_grab is not None:
                self.grip.on_drag("left")(self._on_grab)
            if self._on_pick is not None:
                self._bind_pick()
            return
        self.grip.batched_wxyzs = q
        self.grip.batched_positions = mid
        self.grip.batched_scales = scales
        if self.grip.visible != self.grip_enabled:
            self.grip.visible = self.grip_enabled

    def _trail(self, fr: Frame, on: bool) -> None:
        pts = self.trail_points
        t = float(fr.time)
        if pts and t < pts[-1][0]:  # time went back: a reset, a rewind or another episode
            pts.clear()
        if not pts or t > pts[-1][0]:
            pts.append((t, np.asarray(fr.node_pos[-1], np.float64).copy()))
        while pts and pts[0][0] < t - TRAIL_SECONDS:
            pts.popleft()
        show = on and len(pts) >= 2
        if show:
            p = np.stack([q for _, q in pts])
            self.trail.points = np.stack([p[:-1], p[1:]], 1)
        if self.trail.visible != show:
            self.trail.visible = show

    def _tip_frame(self, fr: Frame, x: np.ndarray, m1, on: bool) -> None:
        show = on and m1 is not None and fr.m2 is not None
        if show:
            t = x[-1] - x[-2]
            t = t / max(float(np.linalg.norm(t)), 1e-300)
            R = np.stack([np.asarray(m1[-1], np.float64), np.asarray(fr.m2[-1], np.float64), t], axis=-1)
            self.tip_frame.position = tuple(x[-1])
            self.tip_frame.wxyz = tuple(matrix_to_quat(R))
        if self.tip_frame.visible != show:
            self.tip_frame.visible = show

    def trail_positions(self) -> np.ndarray:
        """(K, 3) tip positions in the trail (oldest first)."""
        return np.stack([q for _, q in self.trail_points]) if self.trail_points else np.zeros((0, 3))


def scene_info(wb) -> tuple[np.ndarray | None, tuple[int, ...]]:
    """(rest node positions (N, 3), control nodes) of the live rod of a ``Workbench``: the simulator's reset
    configuration, and the control points of the task's action converter (teleop: ``workbench.session.teleop``)."""
    with wb.lock:
        rest = np.asarray(wb.live.sim.reset().node_pos[0], np.float64).copy()
        nodes = wb.teleop.control_nodes()  # the steered rod's, in the scene's chain of nodes
    pol = getattr(wb, "policy", None)
    try:
        if pol is not None:
            nodes = tuple(int(c) for c in pol.core.converter.cfg.control_points)
    except AttributeError:
        pass
    return rest, tuple(nodes)
