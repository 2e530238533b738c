"""Replay of recorded episodes (.rrd read with ``policies.recording``): timeline, speed, frames.

A :class:`ReplaySession` turns one ``EpisodeData`` into :class:`workbench.session.frame.Frame` objects
(the same overlays as the live view) and its static scene into display-only obstacles.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.geometry import quat_z_to
from workbench.session.frame import Frame, curvature_magnitude, edge_strain, several_rods
from workbench.session.obstacles import ObstacleEdit

# scalar name in the recording -> name shown in the workbench plots / status
PLOT_KEYS = {"reward": "reward", "tip_error": "tip_error", "contact/max_normal_force": "contact_force",
             "solver/newton_iters": "newton_iters", "contact/dropped": "contact_dropped",
             "contact/net_force": "contact_net_force"}


def list_recordings(root: str | Path | None = None) -> list[Path]:
    """Every .rrd below ``root`` (default: recordings/ in the working directory), newest first."""
    root = Path(root) if root else Path("recordings")
    if not root.is_dir():
        return []
    return sorted(root.rglob("*.rrd"), key=lambda p: p.stat().st_mtime, reverse=True)


def read_episodes(path: str | Path) -> list:
    """``policies.recording.read_recording`` (one ``EpisodeData`` per episode)."""
    from policies.recording import read_recording  # lazy: rerun is heavy

    return list(read_recording(path))


def obstacles_of(scene) -> list[ObstacleEdit]:
    """Display obstacles of a recording's ``StaticScene``."""
    out: list[ObstacleEdit] = []
    if scene is None:
        return out
    if scene.capsules is not None:
        for ab, r in zip(scene.capsules, scene.capsule_radii):
            a, b = np.asarray(ab[0], float), np.asarray(ab[1], float)
            out.append(ObstacleEdit(kind="capsule", position=0.5 * (a + b), wxyz=quat_z_to(b - a),
                                    radius=float(r), length=float(np.linalg.norm(b - a)), name="capsule"))
    if scene.sphere_centers is not None:
        for c, r in zip(scene.sphere_centers, scene.sphere_radii):
            out.append(ObstacleEdit(kind="sphere", position=c, radius=float(r), name="sphere"))
    if scene.box_centers is not None:
        quats = scene.box_quats if scene.box_quats is not None else [None] * len(scene.box_centers)
        for c, h, q in zip(scene.box_centers, scene.box_half_sizes, quats):
            wxyz = (1.0, 0.0, 0.0, 0.0) if q is None else (q[3], q[0], q[1], q[2])
            out.append(ObstacleEdit(kind="box", position=c, wxyz=wxyz, half_extents=h, name="box"))
    for i, (v, f) in enumerate(scene.meshes):
        out.append(ObstacleEdit(kind="mesh", mesh=f"<recorded mesh {i}>", mesh_data=(v, f), name=f"mesh {i}"))
    return out


class ReplaySession:
    """Timeline over the episodes of one recording file.

    Args:
        episodes: list of ``EpisodeData`` (at least one).
        path: the file they came from (shown in the page).
    """

    def __init__(self, episodes: list, *, path: str | Path | None = None):
        if not episodes:
            raise ValueError(f"{path or 'recording'}: no episodes in this recording")
        self.episodes = episodes
        self.path = Path(path) if path else None
        self.playing = False
        self.speed = 1.0
        self.select(0)

    @classmethod
    def open(cls, path: str | Path) -> "ReplaySession":
        return cls(read_episodes(path), path=path)

    def select(self, episode: int) -> None:
        self.ep = self.episodes[int(episode)]
        self.episode_index = int(episode)
        self.index = 0
        t = np.asarray(self.ep.sim_time, dtype=np.float64)
        d = np.diff(t)
        self.frame_dt = float(np.median(d[d > 0])) if np.any(d > 0) else 0.05
        x0 = np.asarray(self.ep.positions[0], dtype=np.float64)
        self._rest = np.maximum(np.linalg.norm(np.diff(x0, axis=0), axis=1), 1e-9)
        self.obstacles = obstacles_of(self.ep.scene)
        # several rods: each drawn as its own tube (an older recording has no layout: one rod)
        self.rod_offsets = several_rods(getattr(self.ep.scene, "rod_node_offsets", None))

    @property
    def length(self) -> int:
        return int(self.ep.steps)

    def seek(self, index: int) -> None:
        self.index = int(np.clip(index, 0, self.length - 1))

    def step_frame(self) -> bool:
        """One frame on, whatever the play state (the Step button, →); stays at the last. Returns whether the frame
        changed."""
        if self.index >= self.length - 1:
            return False
        self.index += 1
        return True

    def advance(self) -> bool:
        """Next frame when playing; stops at the end. Returns whether the frame changed."""
        if not self.playing:
            return False
        if self.index >= self.length - 1:
            self.playing = False
            return False
        self.index += 1
        return True

    def series(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """(sim_time, values) of a recorded scalar (None if it was not logged)."""
        v = self.ep.scalars.get(name)
        if v is None:
            return None
        return np.asarray(self.ep.sim_time, dtype=np.float64), np.asarray(v, dtype=np.float64)

    def frame(self) -> Frame:
        ep, i = self.ep, self.index
        x = np.asarray(ep.positions[i], dtype=np.float64)

        def unit(a):
            if a is None:
                return None
            a = np.asarray(a[i], dtype=np.float64)
            return a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)

        cp, cf = np.zeros((0, 3)), np.zeros((0, 3))
        if ep.contact_count is not None and ep.contact_points is not None:
            k = int(ep.contact_count[i])
            cp = np.asarray(ep.contact_points[i, :k], dtype=np.float64)
            cf = np.zeros_like(cp)
            if ep.contact_normals is not None and ep.contact_normal_force is not None:
                cf = cf + np.asarray(ep.contact_normals[i, :k]) * np.asarray(ep.contact_normal_force[i, :k])[:, None]
            if ep.contact_friction is not None:
                cf = cf + np.asarray(ep.contact_friction[i, :k])
        targets = np.zeros((0, 3))
        twxyz = None
        if ep.target_pos is not None and np.all(np.isfinite(ep.target_pos[i])):
            targets = np.asarray(ep.target_pos[i], dtype=np.float64).reshape(1, 3)
            if ep.target_quat is not None and np.all(np.isfinite(ep.target_quat[i])):
                q = np.asarray(ep.target_quat[i], dtype=np.float64)
                twxyz = np.array([q[3], q[0], q[1], q[2]])
        scalars = {}
        for rec_name, name in PLOT_KEYS.items():
            v = ep.scalars.get(rec_name)
            if v is not None and np.isfinite(v[i]):
                scalars[name] = float(v[i])
        for name, v in ep.scalars.items():
            if name.startswith("reward_terms/") and np.isfinite(v[i]):
                scalars[name.replace("reward_terms/", "r_")] = float(v[i])
        off = self.rod_offsets
        return Frame(node_pos=x, rod_radius=float(ep.scene.rod_radius), m1=unit(ep.m1), m2=unit(ep.m2),
                     node_curvature=curvature_magnitude(x, off), edge_strain=edge_strain(x, self._rest),
                     contact_points=cp, contact_forces=cf, targets=targets, target_wxyz=twxyz,
                     time=float(ep.sim_time[i]), scalars=scalars,
                     rod_offsets=None if off is None else off.copy())
