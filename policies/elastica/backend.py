"""The four tasks on PyElastica (docs/tasks.md §1.6 and each task's "Elastica differences").

``make_elastica_core(task, envs, seed)`` builds the task's ordinary batched core (targets, obstacles, action
converter, observations and rewards stay exactly the task's code) and replaces its simulator by
:class:`ElasticaSimulator`, which offers the part of the ``sim.Simulator`` interface a task uses
(``reset``/``make_control``/``reset_envs``/``step``/``material_frames``/``set_capsules``).

Per control step the task core calls ``step`` ``substeps`` times (2 for the arm tasks, 10 for the obstacle
tasks, each after adding 1/substeps of the control step's natural-curvature increment to the control); every
call advances ``config.dt / dt_elastica`` = 250 Elastica steps of 2e-4 s and spreads the increment it received
evenly over them, so the rest curvature/twist rises linearly over the control period in 500 (arm) or 2500
(obstacle tasks) equal increments before the respective sim steps, as in the paper. DisMech -> Elastica
conversion: ``rest_kappa[:, n-1] += (Δκ̄1, -Δκ̄2, -Δm̄) / l_n`` (policies/elastica/rods.py).

Rod: 21 nodes, radius 0.05 m, E = 1e7 Pa, G = E/3, density 1000, PyElastica 0.2.4 damping ν = 10, gravity,
base clamp (position of node 0, director of element 0). Obstacles: rigid cylinders (one set per env) with
``RodCylinderContact`` k = 1.6e5 N/m, ν = 4.0, no friction; the 3D task's fences move at every reset.
The 2D tasks run the full 3D rod with only κ1 actuated and observe (x, z). A failed env (NaN or a blown-up
rod) is reported as a simulator failure (reward -10, terminated) and restored at its reset.
"""
from __future__ import annotations

import dataclasses
from types import SimpleNamespace
from typing import Any

import numpy as np

from policies.elastica.rods import CylinderSpec, ElasticaRods, RodSpec
from policies.tasks import TASK_SPECS, gym_task_id

__all__ = ["ElasticaSimulator", "make_elastica_core", "ELASTICA_DT", "CONTACT_K", "CONTACT_NU", "DAMPING_NU"]

ELASTICA_DT = 2e-4
CONTACT_K = 1.6e5
CONTACT_NU = 4.0
DAMPING_NU = 10.0
_STATE_KEYS = ("position_collection", "velocity_collection", "acceleration_collection", "omega_collection",
               "alpha_collection", "director_collection", "rest_kappa", "rest_sigma")


class ElasticaSimulator:
    """B identical PyElastica arms (one per env) standing in for ``sim.Simulator`` inside a task core."""

    def __init__(self, config: Any, envs: int, *, obstacles: np.ndarray | None = None, obstacle_radius: float = 0.0,
                 dt: float = ELASTICA_DT, damping_nu: float = DAMPING_NU, contact_k: float = CONTACT_K,
                 contact_nu: float = CONTACT_NU):
        self.envs = B = int(envs)
        self.planar = config.mode == "2d"
        ratio = float(config.dt) / float(dt)
        self.steps_per_call = int(round(ratio))
        if self.steps_per_call < 1 or abs(ratio - self.steps_per_call) > 1e-6:
            raise ValueError(f"ElasticaSimulator: the task's dt {config.dt} is not a multiple of dt {dt}")
        obst = ()
        if obstacles is not None:
            obst = tuple(CylinderSpec(tuple(map(float, e[0])), tuple(map(float, e[1])), float(obstacle_radius))
                         for e in np.asarray(obstacles, float))
        self.rods = ElasticaRods(RodSpec(damping=("paper", float(damping_nu))), n_rods=B, dt=float(dt),
                                 obstacles=obst, contact_k=float(contact_k), contact_nu=float(contact_nu),
                                 obstacle_hold="restore")
        self.n_nodes = N = self.rods.spec.n_nodes
        self._initial = [{k: getattr(r, k).copy() for k in _STATE_KEYS} for r in self.rods.rods]
        self._initial_cyl = (self.rods._cyl_pos.copy(), self.rods._cyl_dir.copy()) if self.rods.cylinders else None
        self.applied_kappa = np.zeros((B, N, 2))
        self.applied_tau = np.zeros((B, N))
        self.sim_steps = 0

    # ------------------------------------------------------------------ state / control
    def make_control(self) -> SimpleNamespace:
        return SimpleNamespace(kappa_bar=np.zeros((self.envs, self.n_nodes, 2)),
                               tau_bar=np.zeros((self.envs, self.n_nodes)))

    def reset(self) -> SimpleNamespace:
        B, N = self.envs, self.n_nodes
        D = 2 if self.planar else 4
        self.state = SimpleNamespace(dof=np.zeros((B, N, D)), dof_vel=np.zeros((B, N, D)),
                                     failed=np.zeros(B, dtype=bool), edge_tangent=np.zeros((B, N - 1, 3)),
                                     edge_ref_d1=np.zeros((B, N - 1, 3)), edge_theta=np.zeros((B, N - 1)))
        self._sync(self.state)
        return self.state

    def set_capsules(self, state, idx, starts, ends, radius) -> None:
        """Move the obstacles of envs ``idx`` to the segments (len(idx), M, 3) ``starts`` -> ``ends`` (as
        ``sim.Simulator.set_capsules``; the PyElastica rods hold them)."""
        rods = self.rods
        if rods.obstacles and abs(float(radius) - rods.obstacles[0].radius) > 1e-12:
            raise ValueError("ElasticaSimulator: the obstacle radius cannot change")
        for k, i in enumerate(np.asarray(idx, dtype=np.int64)):
            rods.move_obstacles(int(i), np.stack([np.asarray(starts[k], float), np.asarray(ends[k], float)], axis=1))

    def reset_envs(self, state, ctrl, mask) -> None:
        """Straight rod at rest, natural curvature/twist 0, for the envs in ``mask``."""
        for i in np.flatnonzero(np.asarray(mask, dtype=bool)):
            r = self.rods.rods[i]
            for k, v in self._initial[i].items():
                getattr(r, k)[...] = v
        m = np.asarray(mask, dtype=bool)
        ctrl.kappa_bar[m] = 0.0
        ctrl.tau_bar[m] = 0.0
        self.applied_kappa[m] = 0.0
        self.applied_tau[m] = 0.0
        state.failed[m] = False
        self._sync(state)

    def _sync(self, state) -> None:
        pos, vel = self.rods.node_pos(), self.rods.node_vel()
        if self.planar:
            state.dof[...] = pos[:, :, [0, 2]]
            state.dof_vel[...] = vel[:, :, [0, 2]]
        else:
            state.dof[:, :, :3] = pos
            state.dof_vel[:, :, :3] = vel
        bad = ~(np.all(np.isfinite(pos), axis=(1, 2)) & np.all(np.isfinite(vel), axis=(1, 2)))
        bad |= np.max(np.abs(np.nan_to_num(pos, nan=1e9)), axis=(1, 2)) > 100.0
        state.failed |= bad

    # ------------------------------------------------------------------ stepping
    def step(self, state, ctrl) -> SimpleNamespace:
        """Advance config.dt (``steps_per_call`` Elastica steps), spreading the new control increment evenly."""
        n = self.steps_per_call
        dk = (ctrl.kappa_bar - self.applied_kappa) / n
        dtau = (ctrl.tau_bar - self.applied_tau) / n
        self.applied_kappa = ctrl.kappa_bar.copy()
        self.applied_tau = ctrl.tau_bar.copy()
        inv_l = 1.0 / self.rods.voronoi
        inc = np.stack([dk[:, 1:-1, 0], -dk[:, 1:-1, 1], -dtau[:, 1:-1]], axis=1) * inv_l  # (B, 3, N-2)
        active = [(r, inc[i]) for i, r in enumerate(self.rods.rods) if np.any(inc[i])]
        for _ in range(n):
            for r, d in active:
                r.rest_kappa += d
            self.rods.step(1)
        self.sim_steps += n
        self._sync(state)
        B = self.envs
        return SimpleNamespace(failed=state.failed.copy(), newton_iters=np.zeros(B, dtype=np.int64),
                               converged=np.ones(B, dtype=bool), substeps=np.ones(B, dtype=np.int64))

    def material_frames(self, _edges=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(m1, m2, t) of the last element in world coordinates, each (B, 1, 3) (docs/tasks.md §1.6 mapping)."""
        D = self.rods.tip_directors()  # (B, 3, 3) rows (m1, m2, t)
        return D[:, 0][:, None], D[:, 1][:, None], D[:, 2][:, None]


def _obstacles_of(core) -> tuple[np.ndarray | None, float]:
    cfg = core.config
    if hasattr(cfg, "capsules"):                       # 2D Tight Obstacles: fixed discs (axes along y)
        return cfg.capsules(), float(cfg.obstacle_radius)
    if hasattr(core, "fences"):                        # 3D Random Obstacles: re-sampled at every reset
        return core.fences[0].astype(np.float64), float(cfg.fence.radius)
    return None, 0.0


def make_elastica_core(task: str, envs: int, *, seed: int | None = None, config: Any = None, **overrides: Any):
    """The task's batched core (policies/tasks) stepped by PyElastica instead of the implicit simulator.

    ``config`` / ``overrides``: as ``policies.make_vec_env`` (e.g. ``timeout_steps=3`` for a short episode).
    The follow_target_2d task exists for DisMech only (docs/tasks.md §4.1) and is refused.
    """
    tid = gym_task_id(task)
    if tid.endswith("FollowTarget2D-v0"):
        raise ValueError("follow_target_2d has no Elastica variant (docs/tasks.md §4.1); use follow_target")
    _, core_cls, default = TASK_SPECS[tid].load()
    cfg = default() if config is None else config
    if overrides:
        cfg = dataclasses.replace(cfg, **overrides)
    core = core_cls(cfg, envs=int(envs), seed=seed)
    obstacles, radius = _obstacles_of(core)
    core.sim = ElasticaSimulator(cfg, core.envs, obstacles=obstacles, obstacle_radius=radius)
    core.model = None
    core.state = core.sim.reset()
    core.ctrl = core.sim.make_control()
    core.backend = "elastica"
    core.reset()
    return core
