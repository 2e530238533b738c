"""Drawing of a :class:`workbench.session.grid.GridSession`: every env in its own cell, vectorised (one batched mesh for all
rod segments of all envs, one for the joints, one for the targets, one merged mesh for all obstacles, and the fixed
nodes, fixed twists and point loads of ``workbench.view.boundary`` in one batched node per kind of glyph, with the
focused env's load labels), so N envs cost a handful of scene nodes. The glyphs follow the main view's "Fixes and
loads" toggle and arrow scale (``overlays``). A click on a rod or a target focuses that env (``on_focus(env)``)."""
from __future__ import annotations

from typing import Callable

import numpy as np
import trimesh
import viser

from sim.geometry import quat_to_matrix, quat_z_to
from workbench.session import mesh_for_edit
from workbench.view.boundary import Boundary, BoundaryView, boundary_of
from workbench.view.scene import HAND_COLOR, ROD_COLOR, Overlays, arrow_vectors, place_camera

FOCUS_COLOR = np.array([40, 110, 230], dtype=np.uint8)
ROOT = "/grid"


def obstacle_mesh(session) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices, faces) of every env's obstacles, each moved into its cell; None when there are none."""
    verts, faces, off = [], [], 0
    for e in range(session.n):
        for ed in session.obstacles(e):
            try:
                v, f = mesh_for_edit(ed)
            except Exception:  # noqa: BLE001 - an unreadable mesh is left out of the overview
                continue
            R = quat_to_matrix(np.asarray(ed.wxyz, np.float64))
            verts.append(np.asarray(v, np.float64) @ R.T + np.asarray(ed.position, np.float64) + session.offsets[e])
            faces.append(np.asarray(f) + off)
            off += len(v)
    if not verts:
        return None
    return np.concatenate(verts), np.concatenate(faces)


#: (position, look-at) [m] of the oblique view of a 1 m upright arm at the origin; a cell's camera scales it by the
#: cell's rod length
CELL_VIEW = ((1.45, -1.45, 1.05), (0.1, 0.0, 0.45))

class GridView:
    """Scene nodes of a grid session. ``overlays``: the main view's display toggles (the boundary glyphs follow its
    ``boundary`` toggle and contact-arrow scale; default: a fresh ``Overlays``); ``boundary``: the glyphs' source
    (default: ``boundary_of`` the session's model)."""

    def __init__(self, server: viser.ViserServer, session, on_focus: Callable[[int], None] | None = None, *,
                 overlays: Overlays | None = None, boundary: Boundary | None = None,
                 on_grab: Callable[[int, object], None] | None = None):
        self.server, self.s = server, session
        self.overlays = overlays if overlays is not None else Overlays()
        sc = server.scene
        n, N = session.n, session.n_nodes
        self.n_edges = n * (N - 1)
        cyl = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=12)
        sph = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
        self.focus = 0
        self.rods = sc.add_batched_meshes_simple(
            f"{ROOT}/rods", cyl.vertices, cyl.faces, batched_wxyzs=np.tile([1.0, 0, 0, 0], (self.n_edges, 1)),
            batched_positions=np.zeros((self.n_edges, 3)), batched_scales=np.full((self.n_edges, 3), 1e-3),
            batched_colors=self._colors(N - 1), lod="off")
        self.joints = sc.add_batched_meshes_simple(
            f"{ROOT}/joints", sph.vertices, sph.faces, batched_wxyzs=np.tile([1.0, 0, 0, 0], (n * N, 1)),
            batched_positions=np.zeros((n * N, 3)), batched_scales=np.full(n * N, 1e-3),
            batched_colors=self._colors(N), lod="off")
        tg = session.targets()
        self.targets = None
        if tg is not None:
            self.targets = sc.add_batched_meshes_simple(
                f"{ROOT}/targets", sph.vertices, sph.faces, batched_wxyzs=np.tile([1.0, 0, 0, 0], (n, 1)),
                batched_positions=tg, batched_scales=np.full(n, 0.03),
                batched_colors=np.tile([40, 200, 60], (n, 1)).astype(np.uint8), lod="off")
        self.labels = [sc.add_label(f"{ROOT}/label_{e}", f"env {e}", position=tuple(session.offsets[e]
                                                                                     + [0.0, -0.3, 0.0]))
                       for e in range(n)]
        self.obstacles = None
        self._obst_version = -1
        self.boundary = BoundaryView(server, name=f"{ROOT}/boundary")
        self.boundary.set_boundary(boundary if boundary is not None else boundary_of(session.core.model), envs=n)
        if on_focus is not None:
            self.rods.on_click(lambda ev: on_focus(int(ev.instance_index) // (N - 1))
                               if ev.instance_index is not None else None)
            self.joints.on_click(lambda ev: on_focus(int(ev.instance_index) // N)
                                 if ev.instance_index is not None else None)
            if self.targets is not None:
                self.targets.on_click(lambda ev: on_focus(int(ev.instance_index))
                                      if ev.instance_index is not None else None)
        # a drag on an env's rod pulls it (workbench.session.pull): ``on_grab(env, event)`` on the server's event loop, in the
        # order of the drag's phases
        self.hand_line = sc.add_line_segments(f"{ROOT}/hand", np.zeros((1, 2, 3)), HAND_COLOR, thickness=4.0,
                                              thickness_units="screen", visible=False)
        if on_grab is not None:
            for node, per_env in ((self.rods, N - 1), (self.joints, N)):
                async def dragged(ev, per_env=per_env) -> None:
                    if ev.instance_index is not None:
                        on_grab(int(ev.instance_index) // per_env, ev)

                node.on_drag("left")(dragged)
        self.frames = 0

    def _colors(self, per_env: int) -> np.ndarray:
        c = np.tile(ROD_COLOR, (self.s.n, 1))
        c[self.focus] = FOCUS_COLOR
        return np.repeat(c, per_env, axis=0).astype(np.uint8)

    def set_focus(self, env: int) -> None:
        """Colour env ``env`` apart and move every page's camera to its cell."""
        self.focus = int(env)
        N = self.s.n_nodes
        self.rods.batched_colors = self._colors(N - 1)
        self.joints.batched_colors = self._colors(N)
        self.look_at(env)

    def cell_camera(self, env: int | None) -> tuple[np.ndarray, np.ndarray]:
        """(position, look-at) of the camera on one env's cell, or on the whole grid (None)."""
        pos, look = (np.asarray(v, np.float64) for v in CELL_VIEW)
        scale = self.s.rod_length
        if env is None:  # the grid left of the page's centre: the control panel covers the right part
            centre = 0.5 * (self.s.offsets.min(axis=0) + self.s.offsets.max(axis=0)) + look * scale
            span = float(np.ptp(self.s.offsets[:, :2], axis=0).max()) + self.s.spacing
            d = (pos - look) / np.linalg.norm(pos - look)
            right = np.cross(-d, [0.0, 0.0, 1.0])
            right /= np.linalg.norm(right)
            look = centre + 0.3 * span * right
            return look + d * 1.3 * span, look
        c = self.s.offsets[int(env)]
        return c + look + (pos - look) * max(scale, 0.3), c + look * scale

    def look_at(self, env: int | None) -> None:
        pos, look = self.cell_camera(env)
        for client in self.server.get_clients().values():
            place_camera(client, tuple(pos), tuple(look))

    def render(self) -> None:
        s = self.s
        x = s.positions()
        e = np.diff(x, axis=1).reshape(-1, 3)
        length = np.linalg.norm(e, axis=1)
        t = e / np.maximum(length, 1e-12)[:, None]
        r = s.rod_radius
        tg = s.targets() if self.targets is not None else None
        with self.server.atomic():
            self.rods.batched_positions = (0.5 * (x[:, :-1] + x[:, 1:])).reshape(-1, 3)
            self.rods.batched_wxyzs = quat_z_to(t)
            self.rods.batched_scales = np.stack([np.full_like(length, r), np.full_like(length, r), length], 1)
            self.joints.batched_positions = x.reshape(-1, 3)
            self.joints.batched_scales = np.full(len(x.reshape(-1, 3)), r)
            if tg is not None:
                self.targets.batched_positions = tg
            hand = s.hand()
            if hand is not None:
                self.hand_line.points = hand[None]
            if self.hand_line.visible != (hand is not None):
                self.hand_line.visible = hand is not None
            ov = self.overlays
            self.boundary.render(x, s.times(), ov.boundary, lambda f: arrow_vectors(f, ov.arrows, ov.force_scale),
                                 label_env=self.focus)
            if s.obstacles_version != self._obst_version:
                self._obst_version = s.obstacles_version
                mesh = obstacle_mesh(s)
                if self.obstacles is not None:
                    self.obstacles.remove()
                    self.obstacles = None
                if mesh is not None:
                    self.obstacles = self.server.scene.add_mesh_simple(f"{ROOT}/obstacles", mesh[0], mesh[1],
                                                                       color=(110, 130, 170), opacity=0.55)
        self.frames += 1

    def remove(self) -> None:
        for h in (self.rods, self.joints, self.targets, self.obstacles, self.hand_line, *self.labels,
                  *self.boundary.nodes):
            if h is not None:
                h.remove()
