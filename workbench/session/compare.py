"""Compare: a second recorded episode drawn as a ghost (translucent, another colour) over the shown one.

The ghost steps with whatever the page draws: each drawn frame (a replayed episode or the live session) has a
simulated time, and the ghost shows its own frame nearest to that time (its last frame once it has ended), so two
recordings play together on one timeline and a live policy runs beside a recorded episode of the same task.
Vectorised: one batched mesh for the ghost's segments, one for its joints, one marker for its target. A recording of
several rods (its ``scene.rod_node_offsets``) draws no segment on the edges joining two rods.
"""
from __future__ import annotations

import numpy as np
import trimesh

from sim.geometry import quat_z_to
from workbench.session.frame import rod_edges, several_rods
from workbench.session.policy_session import PolicySession

GHOST_COLOR = np.array([30, 90, 255], dtype=np.uint8)
GHOST_OPACITY = 0.45
ROOT = "/ghost"


class Ghost:
    """One recorded episode (``EpisodeData``) aligned by simulated time."""

    def __init__(self, ep, *, label: str = ""):
        self.ep = ep
        self.label = label
        self.t = np.asarray(ep.sim_time, np.float64)
        if len(self.t) == 0:
            raise ValueError(f"{label or 'ghost'}: the episode has no frames")
        self.index = 0

    def index_at(self, time: float) -> int:
        """The ghost frame shown at simulated time ``time`` [s]: the last one at or before it (0 before the
        start, the last frame after the end)."""
        if not np.isfinite(time):
            return self.index
        return int(np.clip(np.searchsorted(self.t, float(time) + 1e-9, side="right") - 1, 0, len(self.t) - 1))

    def positions(self, i: int) -> np.ndarray:
        return np.asarray(self.ep.positions[i], np.float64)

    @property
    def rod_offsets(self) -> np.ndarray | None:
        """Where each rod's nodes start (then N) in a recording of several rods, else None."""
        return getattr(getattr(self.ep, "scene", None), "rod_node_offsets", None)

    def edges(self) -> np.ndarray:
        """(E,) the edges drawn as segments: every edge of a rod, none joining two rods."""
        return rod_edges(self.positions(0).shape[0], self.rod_offsets)

    def target(self, i: int) -> np.ndarray | None:
        tp = self.ep.target_pos
        if tp is None or not np.all(np.isfinite(tp[i])):
            return None
        return np.asarray(tp[i], np.float64)


class GhostView:
    """The ghost's scene nodes; :meth:`draw` follows a drawn frame's time."""

    def __init__(self, server, ghost: Ghost):
        self.server, self.g = server, ghost
        n = ghost.positions(0).shape[0]
        self.edges = ghost.edges()
        ne = len(self.edges)
        cyl = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=12)
        sph = trimesh.creation.icosphere(subdivisions=1, radius=1.0)
        self.radius = float(getattr(ghost.ep.scene, "rod_radius", 0.02) or 0.02)
        sc = server.scene
        self.rod = sc.add_batched_meshes_simple(
            f"{ROOT}/edges", cyl.vertices, cyl.faces, batched_wxyzs=np.tile([1.0, 0, 0, 0], (ne, 1)),
            batched_positions=np.zeros((ne, 3)), batched_scales=np.full((ne, 3), 1e-3),
            batched_colors=np.tile(GHOST_COLOR, (ne, 1)), opacity=GHOST_OPACITY, lod="off", cast_shadow=False)
        self.joints = sc.add_batched_meshes_simple(
            f"{ROOT}/nodes", sph.vertices, sph.faces, batched_wxyzs=np.tile([1.0, 0, 0, 0], (n, 1)),
            batched_positions=np.zeros((n, 3)), batched_scales=np.full(n, 1e-3),
            batched_colors=np.tile(GHOST_COLOR, (n, 1)), opacity=GHOST_OPACITY, lod="off", cast_shadow=False)
        self.target = sc.add_icosphere(f"{ROOT}/target", radius=0.03, color=tuple(int(c) for c in GHOST_COLOR),
                                       opacity=0.5, visible=False)
        self.shown = -1

    def draw(self, time: float) -> None:
        i = self.g.index_at(time)
        if i == self.shown:
            return
        self.g.index = self.shown = i
        x = self.g.positions(i)
        k = self.edges
        e = x[k + 1] - x[k]
        length = np.linalg.norm(e, axis=1)
        r = self.radius
        tg = self.g.target(i)
        with self.server.atomic():
            self.rod.batched_positions = 0.5 * (x[k] + x[k + 1])
            self.rod.batched_wxyzs = quat_z_to(e / np.maximum(length, 1e-12)[:, None])
            self.rod.batched_scales = np.stack([np.full_like(length, r), np.full_like(length, r), length], 1)
            self.joints.batched_positions = x
            self.joints.batched_scales = np.full(len(x), r)
            if tg is not None:
                self.target.position = tuple(tg)
            if self.target.visible != (tg is not None):
                self.target.visible = tg is not None

    def remove(self) -> None:
        for h in (self.rod, self.joints, self.target):
            h.remove()


class PolicyEpisode:
    """One episode of a task run headless under a policy, every sim step kept (what :class:`Ghost` needs of an
    ``EpisodeData``: ``positions``, ``sim_time``, ``target_pos``, ``scene.rod_radius``)."""

    def __init__(self, positions, sim_time, target_pos, rod_radius: float, meta: dict, rod_node_offsets=None):
        self.positions = np.asarray(positions, np.float64)
        self.sim_time = np.asarray(sim_time, np.float64)
        self.target_pos = None if target_pos is None else np.asarray(target_pos, np.float64)
        self.scene = type("Scene", (), {"rod_radius": float(rod_radius),
                                        "rod_node_offsets": several_rods(rod_node_offsets)})()
        self.meta = meta


def policy_episode(task: str, policy: str, *, seed: int = 0, max_sim_steps: int = 5000) -> PolicyEpisode:
    """The first episode of ``task`` (seed ``seed``: the same target and obstacles as a live session started with
    that seed) under ``policy``, stepped sim step by sim step as the workbench steps it (``PolicySession``)."""
    s = PolicySession(task, policy, seed=seed)
    core = s.core

    def snap():
        tg = s.targets()
        return (np.asarray(core.state.node_pos[0], np.float64).copy(), float(np.asarray(core.state.time)[0]),
                None if tg is None else tg[0].copy())

    frames = [snap()]
    for _ in range(int(max_sim_steps)):
        s.sim_step(None)
        frames.append(snap())
        if s.done:
            break
    pos, t, tg = zip(*frames)
    return PolicyEpisode(np.stack(pos), np.array(t), None if tg[0] is None else np.stack(tg),
                         float(core.model.radius_max), {"task": s.task, "policy": s.name},
                         getattr(core.model, "rod_node_offsets", None))
