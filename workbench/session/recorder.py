"""Record the live workbench session (``SessionRecorder``) to an .rrd file in the recordings folder with
``policies.recording.Recorder`` (the file appears atomically when recording stops).

One rerun episode per continuous stretch: a rewind (time going backwards), a reset or an
obstacle edit ends the current episode and starts the next one, so every episode's static
scene is right.
"""
from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np

from sim.geometry import quat_to_matrix
from workbench.session.frame import Frame
from workbench.session.obstacles import ObstacleEdit, mesh_for_edit

SCALAR_NAMES = {"reward": "reward", "tip_error": "tip_error", "ori_error": "ori_error", "newton_iters": "solver/newton_iters",
                "contact_force": "contact/max_normal_force", "max_penetration": "contact/max_penetration",
                "converged": "solver/converged", "failed": "solver/failed", "contact_count": "contact/count",
                "pull_force": "hand/pull_force", "hand": "hand/take_over", "contact_dropped": "contact/dropped",
                "contact_net_force": "contact/net_force"}


def static_scene(edits: list[ObstacleEdit], rod_radius: float, *, planar: bool = False, rod_offsets=None,
                 rod_names=()):
    """``StaticScene`` (world frame) of the workbench obstacles; ``rod_offsets`` (R+1,) and ``rod_names`` (R,): the
    layout of a scene of several rods (None: one rod)."""
    from policies.recording import StaticScene

    caps, crad, sc, sr, bc, bh, bq, meshes = [], [], [], [], [], [], [], []
    for e in edits:
        R = quat_to_matrix(np.asarray(e.wxyz, dtype=np.float64))
        if e.kind == "capsule":
            ax = R[:, 2] * 0.5 * e.length
            caps.append([e.position - ax, e.position + ax])
            crad.append(e.radius)
        elif e.kind == "sphere":
            sc.append(e.position)
            sr.append(e.radius)
        elif e.kind == "box":
            bc.append(e.position)
            bh.append(e.half_extents)
            bq.append([e.wxyz[1], e.wxyz[2], e.wxyz[3], e.wxyz[0]])
        else:
            v, f = mesh_for_edit(e)
            meshes.append((np.asarray(v, np.float64) @ R.T + e.position, np.asarray(f, np.int64)))

    def arr(a, shape):
        return np.asarray(a, dtype=np.float64).reshape(shape) if a else None

    return StaticScene(rod_radius=rod_radius, capsules=arr(caps, (-1, 2, 3)), capsule_radii=arr(crad, (-1,)),
                       sphere_centers=arr(sc, (-1, 3)), sphere_radii=arr(sr, (-1,)),
                       box_centers=arr(bc, (-1, 3)), box_half_sizes=arr(bh, (-1, 3)), box_quats=arr(bq, (-1, 4)),
                       meshes=tuple(meshes), planar=planar,
                       rod_node_offsets=None if rod_offsets is None else np.asarray(rod_offsets, np.int64),
                       rod_names=tuple(rod_names) if rod_offsets is not None else ())


class SessionRecorder:
    """Streams workbench frames into a ``Recorder``.

    Args:
        path: output .rrd (default recordings/workbench-<UTC time>.rrd).
        meta: episode metadata (task, policy, scene, ...).
        obstacles: callable returning the current obstacle list (for each episode's static scene).
        planar: a 2-D rod (the episode is marked planar and its one in-plane natural curvature is logged).
        rod_names: callable returning the names of the scene's rods; an episode of several rods (the frames'
            ``rod_offsets``) stores its layout with them, and a frame of another layout starts a new episode.
    """

    def __init__(self, path: str | Path, *, meta: dict, obstacles, rod_radius: float, planar: bool = False,
                 rod_names=None):
        from policies.recording import Recorder

        self.path = Path(path)
        self.rec = Recorder(self.path, on_error="keep")
        self.meta = dict(meta)
        self._obstacles = obstacles
        self.rod_radius = rod_radius
        self.planar = bool(planar)
        self.frames = 0
        self._t_last = -np.inf
        self._step = 0
        self._open = False
        self._rod_names = rod_names
        self._layout: tuple[int, ...] | None = None  # the open episode's rod offsets (None: one rod)
        # the sim thread logs frames while page actions (a moved obstacle, a stop) end the episode or close
        self._lock = threading.RLock()
        self._closed = False

    @staticmethod
    def default_path(root: str | Path) -> Path:
        return Path(root) / f"workbench-{time.strftime('%Y%m%d-%H%M%S', time.gmtime())}.rrd"

    def new_episode(self) -> None:
        """End the current episode (if any); the next frame starts a new one."""
        with self._lock:
            if self._open:
                self._open = False
                self.rec.end_episode()

    def log(self, fr: Frame) -> None:
        """Add one frame (ignored once the recording is closed)."""
        with self._lock:
            if not self._closed:
                self._log(fr)

    def _log(self, fr: Frame) -> None:
        off = getattr(fr, "rod_offsets", None)
        layout = None if off is None or len(off) <= 2 else tuple(int(k) for k in off)
        if self._open and (fr.time < self._t_last or layout != self._layout):
            self.new_episode()
        if not self._open:
            names = tuple(self._rod_names()) if layout is not None and self._rod_names is not None else ()
            if layout is not None and len(names) != len(layout) - 1:
                names = ()
            self.rec.begin_episode(self.meta, static_scene(self._obstacles(), self.rod_radius, planar=self.planar,
                                                             rod_offsets=layout, rod_names=names))
            self._open = True
            self._layout = layout
            self._step = 0
        kw = {}
        if fr.m1 is not None and fr.m2 is not None:
            kw.update(m1=fr.m1, m2=fr.m2)
        if fr.contact_normals is not None and fr.contact_normal_force is not None and len(fr.contact_points):
            kw.update(contact_points=fr.contact_points, contact_normals=fr.contact_normals,
                      contact_normal_force=fr.contact_normal_force)
        if fr.kappa_bar is not None:  # the commanded (natural) curvature: replays plot it against the actual
            kw["kappa_bar"] = fr.kappa_bar[:, :1] if self.planar else fr.kappa_bar
        if len(fr.targets):
            kw["target_pos"] = fr.targets[0]
        scalars = {}
        for k, v in fr.scalars.items():
            name = SCALAR_NAMES.get(k) or (f"reward_terms/{k[2:]}" if k.startswith("r_") else None)
            if name is not None and np.isfinite(v):
                scalars[name] = float(v)
        self.rec.log_step(control_step=self._step, sim_step=self._step, sim_time=fr.time, node_pos=fr.node_pos,
                          scalars=scalars, **kw)
        self._step += 1
        self._t_last = fr.time
        self.frames += 1

    def close(self) -> Path | None:
        """Finish and write the file (atomic); returns its path (None if nothing was recorded)."""
        with self._lock:
            if self._closed:
                return None
            self._closed = True
            self.new_episode()
            out = self.rec.close()
            return out if self.frames else None
