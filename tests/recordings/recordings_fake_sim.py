"""Kinematic stand-in for ``sim.Simulator`` used by the task-probe tests (not physics).

Same API subset as the real one (reset, make_control, reset_envs, step -> StepStats with every
documented field, material_frames, state.node_pos/edge_theta/node_ref_twist). The rod takes, each
step, the shape whose turning angles equal the natural curvature. Envs with obstacles report
``step % 3`` synthetic contacts (force = 10 * (k + 1) N) so the contact path is exercised.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from tests.fake_sim_base import FakeObstacles, FakeSimBase, fake_set_env_capsules, make_state, ref_d1

__all__ = ["FakeSim", "fake_make_simulator", "fake_set_env_capsules"]

CAP = 4


class FakeSim(FakeSimBase):
    def __init__(self, mode: str, envs: int, dt: float = 0.05, N: int = 21, obstacles: int = 0):
        super().__init__(mode, envs, dt, N, radius=0.05, planar_component=0)
        self.obstacles = obstacles
        self.calls = 0

    def reset(self):
        x, t, th = self._rest()
        dof = self._dof(x)
        return make_state(dof, th, t, FakeObstacles(self))

    def reset_envs(self, state, ctrl, mask):
        self._reset_fields(state, ctrl, mask, ("dof", "dof_vel", "edge_tangent", "edge_ref_d1", "failed",
                                               "time", "node_ref_twist"))

    def step(self, state, ctrl):
        B = self.envs
        self.calls += 1
        x, t, th = self._shape(ctrl.kappa_bar, ctrl.tau_bar)
        q = self._dof(x, th)
        state.dof_vel[:] = (q - state.dof) / self.dt
        state.dof[:] = q
        state.edge_tangent[:] = t
        state.edge_ref_d1[:] = ref_d1(t)
        state.time += self.dt
        has_obs = self.capsules is not None or self.obstacles > 0
        cap = CAP if has_obs else 0
        count = np.full(B, self.calls % 3 if has_obs else 0, np.int64)
        pts = np.zeros((B, cap, 3))
        nrm = np.zeros((B, cap, 3))
        fn = np.zeros((B, cap))
        for k in range(cap):
            pts[:, k] = x[:, 5 + k]
            nrm[:, k] = (1.0, 0.0, 0.0)
            fn[:, k] = 10.0 * (k + 1)
        z = np.zeros(B)
        return SimpleNamespace(
            failed=np.zeros(B, bool), newton_iters=np.full(B, 2), converged=np.ones(B, bool),
            substeps=np.ones(B, np.int64), midpoint_fallbacks=np.zeros(B, np.int64), residual=np.full(B, 1e-3),
            residual0=np.ones(B),
            energy_stretch=z + 0.1, energy_bend=z + 0.2, energy_twist=z + 0.3, energy_contact=z + 0.4,
            energy_kinetic=z + 0.5, energy_gravity=z + 0.6, max_penetration=z.copy(), contact_count=count,
            contact_edge=np.tile(np.arange(cap), (B, 1)), contact_obstacle=np.zeros((B, cap), np.int64),
            contact_partner_edge=np.full((B, cap), -1, np.int64),
            contact_rod_point=pts, contact_obstacle_point=pts.copy(), contact_normal=nrm, contact_normal_force=fn,
            contact_friction_force=np.zeros((B, cap, 3)), contact_gap=np.zeros((B, cap)),
            contact_dropped=np.zeros(B, np.int64), contact_force=(fn[..., None] * nrm).sum(axis=1))


def fake_make_simulator(config, *, envs, task=None):
    obstacles = 0
    if task is not None and hasattr(task, "scene_capsules"):
        obstacles = 1
    sim = FakeSim(config.mode, envs, config.dt, obstacles=obstacles)
    return sim, sim.model
