"""The 3D scene of the workbench (viser): rod (``workbench.view.rod``: smooth tube, control points, rest shape, tip
trail, tip frame), fixed nodes, fixed twists and point loads (``workbench.view.boundary``), material frames,
contacts, targets, obstacles with transform gizmos, ground grid, camera presets and "follow tip". One
``server.atomic()`` per frame.
"""
from __future__ import annotations

import collections
import dataclasses
import functools
import threading
from typing import Callable

import numpy as np
import trimesh
import viser

from sim.geometry import matrix_to_quat
from workbench.session import (
    MAX_PINS,
    Frame,
    ObstacleEdit,
    colors,
    mesh_for_edit,
    node_readout,
    node_values,
    readout_text,
    rod_edges,
    value_range,
)
from workbench.view.boundary import Boundary, BoundaryView
from workbench.view.contact_patches import labelled, patches, reach_of
from workbench.view.rod import RodView

ROD_COLOR = np.array([230, 120, 40], dtype=np.uint8)
GIZMO_SCALE = 0.25  # [m] size of the obstacle transform gizmos
OBSTACLE_OPACITY = 0.55  # see-through: contact points and arrows inside an obstacle stay visible
ARROW_MAX = 0.25  # [m] longest contact arrow ("log" / "auto")
ARROW_F0 = 1.0  # [N] force scale of the "log" arrows: length ∝ log(1 + |f| / ARROW_F0)
ARROW_MODES = ("log", "auto", "linear")
N_FORCE_LABELS = 6  # force labels drawn (the largest contact patches, workbench.view.contact_patches)
HAND_COLOR = (30, 140, 255)  # the pull's spring and hand


def arrow_vectors(forces: np.ndarray, mode: str, scale: float) -> np.ndarray:
    """Contact arrow vectors [m] for forces [N] (K, 3): "linear" = ``scale`` m/N; "auto" = the largest force is
    ``ARROW_MAX`` long; "log" = ``ARROW_MAX · log(1 + |f|/F0) / log(1 + max|f|/F0)`` (small forces stay visible,
    large ones stay on screen). Directions are the forces'."""
    f = np.asarray(forces, np.float64).reshape(-1, 3)
    if mode == "linear" or len(f) == 0:
        return scale * f
    mag = np.linalg.norm(f, axis=1)
    top = float(mag.max())
    if top <= 0.0:
        return np.zeros_like(f)
    unit = f / np.maximum(mag, 1e-300)[:, None]
    if mode == "auto":
        length = ARROW_MAX * mag / top
    else:
        length = ARROW_MAX * np.log1p(mag / ARROW_F0) / np.log1p(top / ARROW_F0)
    return unit * length[:, None]


def material_frame_poses(x: np.ndarray, m1: np.ndarray, m2: np.ndarray, rod_offsets=None) -> tuple[np.ndarray, np.ndarray]:
    """(edge midpoints (E, 3), wxyz (E, 4) of the frames (m1, m2, t)) of the material-frame overlay at node positions
    x (N, 3): one per edge of a rod; with ``rod_offsets`` (several rods) none on the edges joining two rods."""
    x = np.asarray(x, np.float64)
    k = rod_edges(len(x), rod_offsets)
    e = x[k + 1] - x[k]
    t = e / np.maximum(np.linalg.norm(e, axis=1), 1e-12)[:, None]
    R = np.stack([np.asarray(m1, np.float64)[k], np.asarray(m2, np.float64)[k], t], axis=-1)
    return 0.5 * (x[k] + x[k + 1]), matrix_to_quat(R)


GROUND_SIZE = 4.0  # [m] side of the floor grid
LIVE_ROOTS = ("/rod", "/boundary", "/contacts", "/obstacles")  # parents of the live scene's nodes (and "/target")
#: camera presets: where each looks from (a direction towards the scene); "front" faces the x-z plane of the 2-D tasks
CAMERAS = {"front": (0.0, -1.0, 0.0), "side": (1.0, 0.0, 0.0), "top": (0.0, -0.004, 1.0), "iso": (1.0, -1.0, 0.72)}
FOV_Y = np.deg2rad(75.0)  # the page camera's vertical field of view (viser's default)
FIT_MARGIN = 1.5  # the framed sphere's radius over the scene's half-diagonal


def fit_camera(preset: str, points, fov: float = FOV_Y) -> tuple[tuple, tuple]:
    """(position, look-at) [m] of camera preset ``preset`` framing ``points`` (K, 3) [m]: it looks at the centre of
    their bounding box from the preset's direction, from where a sphere of ``FIT_MARGIN`` × the box's half-diagonal
    (at least 5 cm) fills the vertical field of view ``fov`` (the page is wider than tall, so the width fits too)."""
    return fit_camera_along(CAMERAS[preset], points, fov)


def fit_camera_along(direction, points, fov: float = FOV_Y) -> tuple[tuple, tuple]:
    """:func:`fit_camera` looking from ``direction`` (3,) (from the scene towards the camera; any length)."""
    d = np.asarray(direction, np.float64).reshape(3)
    if not (np.isfinite(d).all() and np.linalg.norm(d) > 1e-9):
        raise ValueError(f"camera direction must be 3 finite numbers, not all zero, got {d.tolist()}")
    p = np.asarray(points, np.float64).reshape(-1, 3)
    p = p[np.isfinite(p).all(axis=1)]
    if len(p) == 0:
        p = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    lo, hi = p.min(axis=0), p.max(axis=0)
    centre = 0.5 * (lo + hi)
    radius = FIT_MARGIN * max(0.5 * float(np.linalg.norm(hi - lo)), 0.05)
    d = d / np.linalg.norm(d)
    pos = centre + d * radius / np.sin(0.5 * fov)
    return tuple(float(v) for v in pos), tuple(float(v) for v in centre)


@dataclasses.dataclass
class Overlays:
    """Display toggles (GUI-controlled)."""

    color_by: str = "curvature"  # one of workbench.session.QUANTITIES
    color_fixed: float | None = None  # colour range max (None = auto: the frame's largest |value|)
    frames: bool = False
    contacts: bool = True
    force_scale: float = 0.005  # arrow length per newton [m/N] ("linear" arrows)
    arrows: str = "log"  # contact arrow length: "log", "auto" (largest force = ARROW_MAX) or "linear"
    control_points: bool = True  # mark the nodes where the natural curvature is commanded
    rest_shape: bool = True  # faint tube of the rest configuration
    trail: bool = True  # the tip's path over the last ``workbench.view.rod.TRAIL_SECONDS``
    tip_frame: bool = True  # the tip's material frame (m1, m2, t) (shown with the IK target's frame)
    follow_tip: bool = False  # the camera's look-at follows the tip (its offset kept)
    boundary: bool = True  # fixed nodes, fixed twists and point loads (``workbench.view.boundary``)


def place_camera(client: viser.ClientHandle, position, look_at) -> None:
    """Put ``client``'s camera at ``position`` looking at ``look_at``, both in one atomic message group: the page
    applies them in the same frame, so it never draws, nor reports back, a camera with one new value and one old.
    (viser's position setter shifts the look-at with it; the look-at set after it states it exactly.)"""
    with client.atomic():
        client.camera.position = position
        client.camera.look_at = look_at


def _one_at_a_time(method):
    """Obstacle drawing methods are called from several callback threads (edits, gizmo, replay): one at a time,
    so the drawn obstacles, the edits and the gizmo always belong together."""
    @functools.wraps(method)
    def locked(self, *args, **kwargs):
        with self._obstacles_lock:
            return method(self, *args, **kwargs)
    return locked


class SceneView:
    """Owns every scene node of the workbench page."""

    def __init__(self, server: viser.ViserServer, n_nodes: int, *, env_map: bool = True, shadows: bool = True):
        self.server = server
        self._obstacles_lock = threading.RLock()
        self.overlays = Overlays()
        sc = server.scene
        sc.set_up_direction("+z")
        if not env_map:
            sc.configure_environment_map(hdri=None)
        self.set_shadows(shadows)
        server.initial_camera.position, server.initial_camera.look_at = fit_camera("iso", [[0, 0, 0], [0, 0, 1.0]])
        self.camera: tuple[str, tuple, tuple] = ("iso", *fit_camera("iso", [[0, 0, 0], [0, 0, 1.0]]))  # the last preset
        self.ground = sc.add_grid("/ground", width=GROUND_SIZE, height=GROUND_SIZE, cell_size=0.1, section_size=0.5,
                                  plane="xy")
        # the live scene's nodes hang below these frames, so one switch hides them all (:meth:`show_live`)
        self.live_roots = [sc.add_frame(name, show_axes=False) for name in LIVE_ROOTS]
        self.live_shown = True
        sc.add_light_directional("/sun", intensity=1.5, wxyz=(0.88, 0.28, 0.28, 0.25))
        sc.add_light_hemisphere("/sky", sky_color=(255, 255, 255), ground_color=(120, 120, 120), intensity=1.2)
        self.n_nodes = n_nodes
        n_e = n_nodes - 1
        ident = np.tile([1.0, 0.0, 0.0, 0.0], (n_e, 1))
        self.rod = RodView(server, n_nodes)
        self.boundary = BoundaryView(server)
        self.frames = sc.add_batched_axes(
            "/rod/frames", batched_wxyzs=ident, batched_positions=np.zeros((n_e, 3)),
            axes_length=0.12, axes_radius=0.006, visible=False)
        self.contact_arrows = sc.add_arrows(
            "/contacts/forces", points=np.zeros((1, 2, 3)), colors=(240, 30, 200),
            shaft_radius=0.008, head_radius=0.02, head_length=0.03, visible=False)
        self.contact_points = sc.add_point_cloud(
            "/contacts/points", points=np.zeros((1, 3)), colors=(240, 30, 200), point_size=0.03,
            point_shape="circle", visible=False)
        self.force_labels = [sc.add_label(f"/contacts/label_{j}", "", visible=False, depth_test=False,
                                          anchor="bottom-left") for j in range(N_FORCE_LABELS)]
        self.target = sc.add_icosphere("/target", radius=0.03, color=(40, 200, 60), visible=False)
        # the hand pulling the rod (workbench.session.pull): its spring from the grabbed node, the hand and the force
        self.hand_line = sc.add_line_segments("/rod/hand/spring", np.zeros((1, 2, 3)), HAND_COLOR, thickness=4.0,
                                              thickness_units="screen", visible=False)
        self.hand_point = sc.add_icosphere("/rod/hand/point", radius=0.02, color=HAND_COLOR, visible=False)
        self.hand_label = sc.add_label("/rod/hand/label", "", visible=False, depth_test=False, anchor="bottom-left")
        # readouts pinned at nodes (workbench.session.pins), oldest first
        self.pins: list[int] = []
        self.pin_labels = [sc.add_label(f"/rod/pins/{j}", "", visible=False, depth_test=False, anchor="top-left")
                           for j in range(MAX_PINS)]
        self.pin_texts: list[str] = []  # what the labels said in the last frame (tests)
        self.target_frame = sc.add_frame("/target/frame", axes_length=0.1, axes_radius=0.006,
                                         visible=False)
        self.obstacle_nodes: list[tuple] = []
        self._gizmo = None
        self._edits: list[ObstacleEdit] = []
        self._on_move = None
        self.selected: int | None = None
        self.color_range: tuple[str, float, float] = ("none", 0.0, 1.0)  # what the rod's colours mean now
        self.last_frame: Frame | None = None  # the frame shown (each is shown whole, with its tube: render)
        self._following: dict[int, _Following] = {}  # per page (client id), while the camera follows the tip

    # ------------------------------------------------------------------ per frame
    def toggle_pin(self, node: int) -> None:
        """Pin a readout at ``node`` (a fifth replaces the oldest), or unpin it if it has one."""
        pins = list(self.pins)
        if node in pins:
            pins.remove(node)
        else:
            pins = (pins + [int(node)])[-MAX_PINS:]
        self.pins = pins

    def _render_pins(self, fr: Frame) -> None:
        n = len(fr.node_pos)
        pins = [p for p in self.pins if 0 <= p < n]
        texts = []
        for j, lab in enumerate(self.pin_labels):
            if j < len(pins):
                text = readout_text(pins[j], node_readout(fr, pins[j]))
                texts.append(text)
                lab.text = text
                lab.position = tuple(np.asarray(fr.node_pos[pins[j]], np.float64))
                if not lab.visible:
                    lab.visible = True
            elif lab.visible:
                lab.visible = False
        self.pin_texts = texts

    def _render_hand(self, fr: Frame) -> None:
        hand = getattr(fr, "hand", None)
        parts = (self.hand_line, self.hand_point, self.hand_label)
        if hand is None:
            for p in parts:
                if p.visible:
                    p.visible = False
            return
        self.hand_line.points = hand[None]
        self.hand_point.position = tuple(hand[1])
        f = np.linalg.norm(fr.hand_force) if fr.hand_force is not None else 0.0
        self.hand_label.text = f"pull {f:.3g} N"
        self.hand_label.position = tuple(hand[1])
        for p in parts:
            if not p.visible:
                p.visible = True

    def render(self, fr: Frame, *, boundary: bool = True, on_shown: Callable[[Frame], None] | None = None) -> None:
        """Send one frame. Its tube is shown once the page has had it to parse (``view_rod``: at the next frame, or
        after ``SWAP_DELAY``, or at :meth:`flush`), and with it, in one atomic message batch, every other node of the
        frame (overlays, contacts, target, the camera following the tip) and ``on_shown(fr)``: the page shows
        each frame whole. ``boundary``: the frame is of the live scene, whose fixes and loads are drawn (when their
        overlay is on)."""
        ov = self.overlays
        vals = node_values(fr, ov.color_by)
        if vals is not None:
            lo, hi = value_range(vals, ov.color_by, ov.color_fixed)
            node_c = colors(vals, lo, hi, ov.color_by)
            self.color_range = (ov.color_by, lo, hi)
        else:
            node_c = np.tile(ROD_COLOR, (len(fr.node_pos), 1))
            self.color_range = ("none", 0.0, 1.0)

        def shown() -> None:
            self._draw_with_tube(fr, boundary)
            self.last_frame = fr  # the frame the page shows (what a click on the rod hits)
            if on_shown is not None:
                on_shown(fr)
        with self.server.atomic():
            self.rod.render(fr, node_c, ov, on_shown=shown)

    def flush(self) -> None:
        """Show the last frame sent now, whole."""
        self.rod.flush()

    def _draw_with_tube(self, fr: Frame, boundary: bool) -> None:
        """Every node of ``fr`` but the rod's own, drawn with the swap that shows its tube (inside its batch)."""
        x = fr.node_pos
        ov = self.overlays
        self._render_hand(fr)
        self._render_pins(fr)
        self.boundary.render(x, fr.time, ov.boundary and boundary,
                             lambda f: arrow_vectors(f, ov.arrows, ov.force_scale))
        if ov.frames and fr.m1 is not None and fr.m2 is not None:
            pos, wxyz = material_frame_poses(x, fr.m1, fr.m2, getattr(fr, "rod_offsets", None))
            self.frames.batched_positions = pos
            self.frames.batched_wxyzs = wxyz
            self.frames.visible = True
        elif self.frames.visible:
            self.frames.visible = False
        k = len(fr.contact_points)
        if ov.contacts and k > 0:
            p = fr.contact_points
            vec = arrow_vectors(fr.contact_forces, ov.arrows, ov.force_scale)
            self.contact_arrows.points = np.stack([p, p + vec], 1)
            self.contact_points.points = p
            self.contact_arrows.visible = True
            self.contact_points.visible = True
            # one label per contact patch (its total force), at the tip of its strongest arrow
            found = patches(p, fr.contact_forces, reach_of(x), getattr(fr, "contact_obstacle", None),
                            getattr(fr, "contact_edge", None), getattr(fr, "contact_partner_edge", None))
            shown = labelled(found, N_FORCE_LABELS)
            for j, lab in enumerate(self.force_labels):
                if j < len(shown):
                    i = shown[j].main_row
                    lab.text = f"{shown[j].magnitude:.3g} N"
                    lab.position = tuple(p[i] + vec[i])
                    if not lab.visible:
                        lab.visible = True
                elif lab.visible:
                    lab.visible = False
        elif self.contact_arrows.visible:
            self.contact_arrows.visible = False
            self.contact_points.visible = False
            for lab in self.force_labels:
                if lab.visible:
                    lab.visible = False
        if len(fr.targets) and self.live_shown:
            self.target.position = fr.targets[0]
            if not self.target.visible:
                self.target.visible = True
            show_f = fr.target_wxyz is not None
            if show_f:
                self.target_frame.wxyz = fr.target_wxyz
            if self.target_frame.visible != show_f:
                self.target_frame.visible = show_f
        else:  # no target in this frame (e.g. teleop after a task), or the live scene hidden: no marker, no frame
            if self.target.visible:
                self.target.visible = False
            if self.target_frame.visible:
                self.target_frame.visible = False
        if ov.follow_tip:
            self.follow(fr.tip)
        elif self._following:
            self.unfollow()

    def follow(self, tip) -> None:
        """Every page's camera looks at ``tip``, keeping its offset from the look-at point.

        The offset is read from the page's camera when following starts, and again only when the user has moved that
        camera: a report matching none of the cameras this view placed. A report mixing the position of one placed
        camera with the look-at of another (the page reports on its own schedule while the server moves it) leaves the
        kept offset as it is; read back, it would shift the offset by the tip's motion between the two. The position
        and look-at of a new camera are sent together (:func:`place_camera`)."""
        tip = np.asarray(tip, np.float64)
        if not np.all(np.isfinite(tip)):
            return
        clients = self.server.get_clients()
        for gone in self._following.keys() - clients.keys():  # pages closed while following
            del self._following[gone]
        for cid, client in clients.items():
            try:
                view = _one_report(client.camera)
            except (AssertionError, ValueError):  # the page has not reported its camera yet
                continue
            if view is None:
                continue  # reports kept arriving (the page is being dragged): its next frame places it
            pos, look = view
            kept = self._following.get(cid)
            if kept is None or _moved_by_user(pos, look, kept.placed):
                kept = self._following[cid] = _Following(pos - look, collections.deque([(pos, look)],
                                                                                      maxlen=PLACED_KEPT))
            new_pos = tip + kept.offset
            if float(np.abs(tip - look).max()) <= 1e-6 and float(np.abs(new_pos - pos).max()) <= 1e-6:
                continue
            kept.placed.append((new_pos, tip))
            place_camera(client, new_pos, tip)

    def unfollow(self) -> None:
        """Following stopped: the next :meth:`follow` reads each page's camera afresh."""
        self._following.clear()

    def set_rod_scene(self, rest_nodes, control_nodes, radius: float, rod_offsets=None) -> None:
        """Rest shape and control points of the live rod (``workbench.view.rod.scene_info``); ``rod_offsets``: where each
        rod starts when the scene has several (``sim.Model.rod_node_offsets``)."""
        self.rod.set_scene(rest_nodes, control_nodes, radius, rod_offsets)

    def set_boundary(self, b: Boundary | None) -> None:
        """Fixed nodes, fixed twists and point loads of the live scene (``workbench.view.boundary.boundary_of``)."""
        self.boundary.set_boundary(b)

    def show_live(self, shown: bool) -> None:
        """Show or hide the whole live scene (rod and its overlays, fixes and loads, contacts, target, obstacles and
        their gizmo), e.g. while a grid of envs is drawn in its place; the floor grid and lights stay. The target comes
        back with the next rendered frame."""
        self.live_shown = bool(shown)
        with self.server.atomic():
            for root in self.live_roots:
                root.visible = self.live_shown
            if not self.live_shown:
                self.target.visible = False
                self.target_frame.visible = False
            with self._obstacles_lock:
                if self._gizmo is not None:
                    self._gizmo.visible = self.live_shown

    def set_shadows(self, on: bool) -> None:
        """Shadows of the default lights on the floor (with software WebGL, most of the cost of a page's frame)."""
        self.shadows = bool(on)
        self.server.scene.configure_default_lights(True, cast_shadow=self.shadows)

    def set_ground(self, size: float = GROUND_SIZE) -> None:
        """Side of the floor grid [m] (a grid of envs spreads wider than the live scene)."""
        size = float(size)
        if self.ground.width != size:
            self.ground.width = self.ground.height = size

    def fit_points(self, fr: Frame | None = None) -> np.ndarray:
        """What a camera preset frames: the rod of frame ``fr`` (default: the last frame drawn), its targets and the
        obstacles (their centres padded by their size; planes left out)."""
        fr = fr if fr is not None else self.last_frame
        pts = [np.asarray(fr.node_pos, np.float64), np.asarray(fr.targets, np.float64).reshape(-1, 3)] if fr else []
        for ed in self._edits:
            if ed.kind == "plane":
                continue
            if ed.kind == "sphere":
                size = ed.radius
            elif ed.kind == "box":
                size = float(np.linalg.norm(ed.half_extents))
            elif ed.kind in ("capsule", "cylinder"):
                size = ed.radius + 0.5 * ed.length
            else:  # a mesh: its centre, padded by a scaled 10 cm
                size = 0.1 * ed.scale
            pts.append(np.asarray(ed.position, np.float64) + size * np.vstack([np.eye(3), -np.eye(3)]))
        return np.vstack(pts) if pts else np.zeros((0, 3))

    def set_camera(self, preset: str, frame: Frame | None = None) -> None:
        """Move every page's camera (and the start view of pages opened later) to preset ``preset`` of ``CAMERAS``,
        fitted to the scene (:func:`fit_camera`, :meth:`fit_points`: of ``frame``, default the frame drawn now);
        ``camera`` holds what was set."""
        pos, look = fit_camera(preset, self.fit_points(frame))
        self.camera = (preset, pos, look)
        self.server.initial_camera.position, self.server.initial_camera.look_at = pos, look
        for client in self.server.get_clients().values():
            place_camera(client, pos, look)

    def fit_view(self, client, frame: Frame | None = None) -> None:
        """Frame the scene (:meth:`fit_points`) in ``client``'s page from the direction it looks from now (the
        page's orbit kept, its distance and look-at fitted); the other pages keep their cameras."""
        cam = client.camera
        d = np.asarray(cam.position, np.float64) - np.asarray(cam.look_at, np.float64)
        if not (np.isfinite(d).all() and np.linalg.norm(d) > 1e-9):  # no direction to keep: the oblique preset's
            d = np.asarray(CAMERAS["iso"], np.float64)
        place_camera(client, *fit_camera_along(d, self.fit_points(frame)))

    # ------------------------------------------------------------------ obstacles
    @_one_at_a_time
    def sync_obstacles(self, edits: list[ObstacleEdit],
                       on_move: Callable[[int, np.ndarray, np.ndarray], None] | None,
                       on_select: Callable[[int], None] | None = None, selected: int | None = None) -> None:
        """Recreate the obstacle nodes. With ``on_move`` (editing) a click on an obstacle calls ``on_select`` and the
        one selected obstacle carries a transform gizmo (``on_move`` called on browser drags); without it (replay)
        the obstacles are display-only."""
        for parent, mesh in self.obstacle_nodes:
            mesh.remove()
            parent.remove()
        self.obstacle_nodes = []
        self._edits = edits
        self._on_move = on_move
        sc = self.server.scene
        for i, ed in enumerate(edits):
            name = f"/obstacles/{i}"
            parent = sc.add_frame(name, show_axes=False, position=tuple(ed.position), wxyz=tuple(ed.wxyz))
            try:
                verts, faces = mesh_for_edit(ed)
            except Exception:  # noqa: BLE001 - unreadable mesh: draw a marker instead
                m = trimesh.creation.icosphere(subdivisions=1, radius=0.05)
                verts, faces = m.vertices, m.faces
            if ed.kind == "plane":
                mesh = sc.add_mesh_simple(f"{name}/mesh", verts, faces, color=(150, 165, 190), opacity=0.25)
            else:
                mesh = sc.add_mesh_simple(f"{name}/mesh", verts, faces, color=(110, 130, 170), opacity=OBSTACLE_OPACITY)
            if on_move is not None and on_select is not None:
                mesh.on_click(lambda _e, i=i: on_select(i))
            self.obstacle_nodes.append((parent, mesh))
        self.select(selected)

    @_one_at_a_time
    def select(self, index: int | None) -> None:
        """Put the transform gizmo on obstacle ``index`` (None or a display-only scene: no gizmo)."""
        if self._gizmo is not None:
            self._gizmo.remove()
            self._gizmo = None
        ok = index is not None and 0 <= index < len(self.obstacle_nodes) and self._on_move is not None
        if not ok:
            self.selected = None
            return
        ed, on_move = self._edits[index], self._on_move
        parent = self.obstacle_nodes[index][0]
        g = self.server.scene.add_transform_controls("/obstacle_gizmo", scale=GIZMO_SCALE, position=tuple(ed.position),
                                                     wxyz=tuple(ed.wxyz), depth_test=False, visible=self.live_shown)

        def _cb(_event, i=index) -> None:
            pos, q = np.asarray(g.position), np.asarray(g.wxyz)
            if np.all(np.isfinite(pos)) and np.all(np.isfinite(q)):
                parent.position, parent.wxyz = tuple(pos), tuple(q)
            on_move(i, pos, q)

        g.on_update(_cb)
        self._gizmo, self.selected = g, index

    @_one_at_a_time
    def move_obstacle(self, index: int, position, wxyz) -> None:
        """Show obstacle ``index`` at a pose set from the server (numeric fields): its mesh and its gizmo."""
        if 0 <= index < len(self.obstacle_nodes):
            parent = self.obstacle_nodes[index][0]
            parent.position, parent.wxyz = tuple(position), tuple(wxyz)
            if self._gizmo is not None and self.selected == index:
                self._gizmo.position, self._gizmo.wxyz = tuple(position), tuple(wxyz)

    def gizmo(self, index: int):
        """The transform gizmo, which sits on obstacle ``index`` only when that one is selected."""
        if self.selected != index or self._gizmo is None:
            raise KeyError(f"obstacle {index} is not selected (selected: {self.selected})")
        return self._gizmo


PLACED_KEPT = 32  # cameras placed by :meth:`SceneView.follow` that a page's report may still mix (per page)
PLACED_TOL = 1e-4  # [m] a reported position or look-at within this of a placed one is that one


@dataclasses.dataclass
class _Following:
    offset: np.ndarray  # camera position - look-at, kept while following
    placed: collections.deque  # the last (position, look-at) pairs sent to the page


def _moved_by_user(pos: np.ndarray, look: np.ndarray, placed) -> bool:
    """True when a page's reported camera is none of the placed ones, nor a mix of two of them (position of one,
    look-at of another): the user moved it."""
    def near(a, b) -> bool:
        return float(np.abs(a - b).max()) <= PLACED_TOL
    return not (any(near(pos, p) for p, _ in placed) and any(near(look, q) for _, q in placed))


def _one_report(cam, tries: int = 8) -> tuple[np.ndarray, np.ndarray] | None:
    """(position, look-at) of one camera report of a page: the position read on both sides of the look-at agrees;
    None when reports kept arriving in between ``tries`` times."""
    for _ in range(tries):
        pos = np.array(cam.position, np.float64)
        look = np.array(cam.look_at, np.float64)
        if np.array_equal(pos, np.asarray(cam.position)):
            return pos, look
    return None
