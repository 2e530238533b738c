"""Boundary conditions and point loads drawn with the rod (docs/conventions.md, ``sim.scene.boundary``).

:func:`boundary_of` reads them from a ``sim.Model``: the constrained DOFs (``dof_fixed``: the ``[[fix]]`` tables,
the rod's clamp and locked edges) and the ``[[load]]`` tables of its scene. :class:`BoundaryView` draws them every
frame at the rod's current nodes, in at most three batched nodes plus one label per load:

- fixed nodes: one box per node, aligned with the world axes (the fixed axes are world axes), coloured by kind:
  clamped (the node belongs to an edge whose two nodes are fixed in every axis and, in 3-D, whose twist is fixed),
  pinned (every axis fixed, free to turn) or partial (a subset of the axes fixed);
- fixed edge twists: a ring around the edge's midpoint, normal to the edge;
- point loads: an arrow from the node along the force (length: the contact arrows' scale, ``view_scene``) and a
  label with the force [N] (and the torque about the tangent [N·m]); a load is hidden outside [start, stop).

A scene with neither creates no scene node. The grid of envs (``workbench.view.grid``) draws the glyphs of all its
envs with the same three batched nodes (``set_boundary(b, envs=n)``, ``render`` with (n, N, 3) positions and one
time per env); the load labels are those of one env (the focused one).
"""
from __future__ import annotations

import dataclasses
import threading
from typing import Callable

import numpy as np
import trimesh

from sim.geometry import quat_z_to
from sim.scene import global_node, node_index

KIND_NAMES = ("clamped", "pinned", "partial")
KIND_COLORS = np.array([[35, 35, 42], [0, 150, 170], [245, 245, 245]], dtype=np.uint8)  # by KIND_NAMES
TWIST_COLOR = (150, 60, 200)
LOAD_COLOR = (225, 30, 45)
N_LOAD_LABELS = 8  # labels drawn at most (the largest active loads)
GLYPH_RADII = 2.4  # box edge [rod radii]
GLYPH_MIN = 1.0 / 60.0  # box edge at least this fraction of the rod's length [-]


@dataclasses.dataclass(frozen=True)
class Boundary:
    """What the glyphs show of one scene (node and edge indices counted from 0).

    Attributes:
        n_nodes: the rod's node count.
        fixed_nodes: (F,) nodes with at least one fixed axis.
        fixed_axes: per fixed node, its fixed world axes ("xyz", "z", ...; 2-D rods: of "xz").
        fixed_kind: (F,) index into ``KIND_NAMES``.
        twist_edges: (T,) edges whose twist is fixed (3-D).
        load_nodes: (L,) node of each load; load_force (L, 3) [N] (world frame); load_torque (L,) [N m];
        load_window: (L, 2) [start, stop) [s] (stop = inf when open).
        size: box edge [m].
    """

    n_nodes: int
    fixed_nodes: np.ndarray
    fixed_axes: tuple[str, ...]
    fixed_kind: np.ndarray
    twist_edges: np.ndarray
    load_nodes: np.ndarray
    load_force: np.ndarray
    load_torque: np.ndarray
    load_window: np.ndarray
    size: float

    @property
    def empty(self) -> bool:
        return not (len(self.fixed_nodes) or len(self.twist_edges) or len(self.load_nodes))


def boundary_of(model) -> Boundary:
    """The fixed nodes, fixed twists and loads of a ``sim.Model`` (``dof_fixed`` and ``spec.loads``)."""
    N = int(model.node_count)
    dpn = int(model.dofs_per_node)
    fx = np.asarray(model.dof_fixed, dtype=bool).reshape(N, dpn)
    planar = dpn == 2
    pos = fx if planar else fx[:, :3]  # 2-D: the x and z of the plane (its y is fixed for every node)
    names = "xz" if planar else "xyz"
    full = pos.all(axis=1)
    twist = np.zeros(N - 1, dtype=bool) if planar else fx[:-1, 3].copy()  # row N-1 of θ is no edge
    link = np.asarray(getattr(model, "edge_link", ()), dtype=bool)
    if len(link) != N - 1:
        link = np.ones(N - 1, dtype=bool)
    twist &= link  # a joint edge between two rods has its twist fixed, but is no part of either rod
    locked = full[:-1] & full[1:] & (True if planar else twist)
    clamped = np.zeros(N, dtype=bool)
    clamped[:-1] |= locked
    clamped[1:] |= locked
    nodes = np.flatnonzero(pos.any(axis=1))
    kind = np.where(clamped[nodes], 0, np.where(full[nodes], 1, 2)).astype(np.int64)
    axes = tuple("".join(c for c, f in zip(names, pos[i]) if f) for i in nodes)
    loads = tuple(getattr(getattr(model, "spec", None), "loads", ()) or ())
    spec = getattr(model, "spec", None)
    ln = np.array([global_node(spec, ld.rod, ld.node) if hasattr(spec, "rods") else node_index(ld.node, N)
                   for ld in loads], dtype=np.int64)
    # world-frame forces are drawn; a material-frame (follower) force turns with the rod and is not
    lf = np.array([ld.force if getattr(ld, "frame", "world") == "world" else (0.0, 0.0, 0.0) for ld in loads],
                  dtype=np.float64).reshape(len(loads), 3)
    lt = np.array([ld.torque for ld in loads], dtype=np.float64)
    # [start, stop), stop = inf if open: the point loads' rows (the line loads' follow them)
    lw = np.asarray(model.load_window, dtype=np.float64).reshape(-1, 2)[:len(loads)]
    length = float(np.sum(np.asarray(model.rest_edge_length)[link]))
    size = max(GLYPH_RADII * float(model.radius_max), GLYPH_MIN * length)
    return Boundary(n_nodes=N, fixed_nodes=nodes, fixed_axes=axes, fixed_kind=kind,
                    twist_edges=np.flatnonzero(twist), load_nodes=ln, load_force=lf, load_torque=lt,
                    load_window=lw, size=size)


def load_active(b: Boundary, time: float) -> np.ndarray:
    """(L,) whether each load acts at ``time`` [s] (start <= time < stop)."""
    return (b.load_window[:, 0] <= time) & (time < b.load_window[:, 1])


def ring_poses(b: Boundary, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(midpoints (T, 3), wxyz (T, 4) taking +z along the edge) of the fixed-twist edges at node positions x (N, 3);
    x (B, N, 3) of B envs: (B·T, 3), (B·T, 4), env by env."""
    e = b.twist_edges
    a, c = x[..., e, :].reshape(-1, 3), x[..., e + 1, :].reshape(-1, 3)
    return 0.5 * (a + c), quat_z_to(c - a)


def load_arrows(b: Boundary, x: np.ndarray, time: float, vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(indices of the active loads with a force, their arrows (K, 2, 3): node -> node + vector) for the arrow
    vectors (L, 3) [m] of all loads."""
    k = np.flatnonzero(load_active(b, time) & (np.abs(b.load_force).max(axis=1) > 0.0))
    p = x[b.load_nodes[k]]
    return k, np.stack([p, p + vectors[k]], 1)


def batched_load_arrows(b: Boundary, x: np.ndarray, times: np.ndarray,
                        vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`load_arrows` of B envs at once: node positions x (B, N, 3), each env's time (B,) [s]. Returns
    (env (K,), load index (K,), arrows (K, 2, 3)) of the active loads with a force, env by env."""
    t = np.asarray(times, np.float64).reshape(-1, 1)
    act = (b.load_window[:, 0] <= t) & (t < b.load_window[:, 1]) & (np.abs(b.load_force).max(axis=1) > 0.0)
    env, k = np.nonzero(act)  # (B, L) -> row-major: env by env
    p = x[env, b.load_nodes[k]]
    return env, k, np.stack([p, p + vectors[k]], 1).reshape(-1, 2, 3)


def load_text(force, torque: float) -> str:
    """Label of a load: |F| [N] and, when nonzero, the torque about the tangent [N·m]."""
    s = f"{float(np.linalg.norm(force)):.3g} N"
    return s + (f" · {torque:.3g} N·m" if torque != 0.0 else "")


class BoundaryView:
    """Scene nodes of the boundary glyphs (under ``name``); none while the scene has no fixes or loads."""

    def __init__(self, server, *, name: str = "/boundary"):
        self._nodes_lock = threading.RLock()  # set_boundary (page callbacks) and render (the drawing thread)
        self.server = server
        self.name = name
        self.b: Boundary | None = None
        self.fixed = self.rings = self.arrows = None
        self.labels: list = []
        self.envs = 1
        self._sent: dict[str, np.ndarray] = {}
        self._box = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
        self._torus = trimesh.creation.torus(1.0, 0.12, major_sections=24, minor_sections=8)

    @property
    def nodes(self) -> list:
        """Every scene node of the glyphs."""
        return [h for h in (self.fixed, self.rings, self.arrows) if h is not None] + self.labels

    def set_boundary(self, b: Boundary | None, *, envs: int = 1) -> None:
        """Replace the glyphs (None or an empty ``Boundary``: none); ``envs``: how many envs of the scene are drawn
        (the grid of envs; each env's glyphs at its own nodes, in the same batched nodes)."""
        with self._nodes_lock:  # one thread at a time rebuilds or draws these nodes
            self._set_boundary_unlocked(b, envs)

    def _set_boundary_unlocked(self, b: Boundary | None, envs: int) -> None:
        for h in self.nodes:
            h.remove()
        self.fixed = self.rings = self.arrows = None
        self.labels = []
        self._sent = {}
        self.envs = max(int(envs), 1)
        self.b = None if b is None or b.empty else b
        if self.b is None:
            return
        b, sc, s, m = self.b, self.server.scene, self.b.size, self.envs
        if len(b.fixed_nodes):
            n = m * len(b.fixed_nodes)
            self.fixed = sc.add_batched_meshes_simple(
                f"{self.name}/fixed_nodes", self._box.vertices, self._box.faces,
                batched_wxyzs=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), batched_positions=np.zeros((n, 3)),
                batched_scales=np.full(n, s), batched_colors=np.tile(KIND_COLORS[b.fixed_kind], (m, 1)), lod="off",
                flat_shading=True, visible=False)
        if len(b.twist_edges):
            n = m * len(b.twist_edges)
            self.rings = sc.add_batched_meshes_simple(
                f"{self.name}/twist_edges", self._torus.vertices, self._torus.faces,
                batched_wxyzs=np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)), batched_positions=np.zeros((n, 3)),
                batched_scales=np.full(n, s), batched_colors=np.tile(TWIST_COLOR, (n, 1)), lod="off",
                visible=False)
        if len(b.load_nodes):
            self.arrows = sc.add_arrows(f"{self.name}/loads", points=np.zeros((1, 2, 3)), colors=LOAD_COLOR,
                                        shaft_radius=0.006, head_radius=0.016, head_length=0.03, visible=False)
            self.labels = [sc.add_label(f"{self.name}/load_label_{j}", "", visible=False, depth_test=False,
                                        anchor="bottom-left") for j in range(min(len(b.load_nodes), N_LOAD_LABELS))]

    def _send(self, handle, attr: str, key: str, value: np.ndarray) -> None:
        """Set ``handle.attr`` only when the value changed (a paused rod sends nothing)."""
        last = self._sent.get(key)
        if last is None or last.shape != value.shape or not np.array_equal(last, value):
            setattr(handle, attr, value)
            self._sent[key] = value

    @staticmethod
    def _show(handle, on: bool) -> None:
        if handle.visible != on:
            handle.visible = on

    def render(self, x: np.ndarray, time, on: bool, arrow_vectors: Callable[[np.ndarray], np.ndarray], *,
               label_env: int = 0) -> None:
        """Follow node positions x (N, 3) [m] at ``time`` [s]; ``on``: the overlay's toggle; ``arrow_vectors``:
        forces (L, 3) [N] -> arrow vectors [m]. Several envs (``set_boundary(..., envs=B)``): x (B, N, 3) and
        ``time`` one per env (B,); the load labels are env ``label_env``'s."""
        with self._nodes_lock:  # one thread at a time rebuilds or draws these nodes
            self._render_unlocked(x, time, on, arrow_vectors, label_env)

    def _render_unlocked(self, x: np.ndarray, time, on: bool, arrow_vectors: Callable[[np.ndarray], np.ndarray],
                         label_env: int) -> None:
        b = self.b
        if b is None:
            return
        X = np.asarray(x, np.float64).reshape(-1, *np.shape(x)[-2:])  # (B, N, 3)
        times = np.broadcast_to(np.asarray(time, np.float64).reshape(-1), (len(X),))
        ok = bool(on) and X.shape[1:] == (b.n_nodes, 3) and len(X) == self.envs
        if self.fixed is not None:
            if ok:
                self._send(self.fixed, "batched_positions", "fixed", X[:, b.fixed_nodes].reshape(-1, 3))
            self._show(self.fixed, ok)
        if self.rings is not None:
            if ok:
                p, q = ring_poses(b, X)
                self._send(self.rings, "batched_positions", "rings", p)
                self._send(self.rings, "batched_wxyzs", "rings_q", q)
            self._show(self.rings, ok)
        if self.arrows is None:
            return
        if ok:
            env, k, pts = batched_load_arrows(b, X, times, arrow_vectors(b.load_force))
        else:
            env = k = np.zeros(0, np.int64)
        if len(k):
            self._send(self.arrows, "points", "arrows", pts)
        self._show(self.arrows, len(k) > 0)
        e = int(np.clip(label_env, 0, len(X) - 1))
        act = np.flatnonzero(load_active(b, float(times[e]))) if ok else np.zeros(0, np.int64)
        act = act[np.argsort(-np.linalg.norm(b.load_force[act], axis=1), kind="stable")]
        tips = {int(i): pts[j, 1] for j, i in enumerate(k) if env[j] == e}
        for j, lab in enumerate(self.labels):
            if j < len(act):
                i = int(act[j])
                text = load_text(b.load_force[i], float(b.load_torque[i]))
                if lab.text != text:
                    lab.text = text
                self._send(lab, "position", f"label_{j}",
                           np.asarray(tips.get(i, X[e, b.load_nodes[i]]), np.float64))
            self._show(lab, j < len(act))
