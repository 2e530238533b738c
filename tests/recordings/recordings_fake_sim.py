"""Kinematic stand-in for ``sim.Simulator`` used by the task-probe tests (not physics).

Same API subset as the real one (reset, make_control, reset_envs, step -> StepStats with every
documented field, material_frames, state.node_pos/edge_theta/node_ref_twist). The rod takes, each
step, the shape whose turning angles equal the natural curvature. Envs with obstacles report
``step % 3`` synthetic contacts (force = 10 * (k + 1) N) so the contact path is exercised.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

CAP = 4


class FakeState(SimpleNamespace):
    @property
    def node_pos(self):
        if self.dof.shape[-1] == 2:
            p = np.zeros(self.dof.shape[:-1] + (3,))
            p[..., 0], p[..., 2] = self.dof[..., 0], self.dof[..., 1]
            return p
        return self.dof[..., :3]

    @property
    def node_vel(self):
        if self.dof_vel.shape[-1] == 2:
            v = np.zeros(self.dof_vel.shape[:-1] + (3,))
            v[..., 0], v[..., 2] = self.dof_vel[..., 0], self.dof_vel[..., 1]
            return v
        return self.dof_vel[..., :3]

    @property
    def edge_theta(self):
        return self.theta

    @property
    def edge_tangent(self):
        return self.tangent

    @property
    def edge_ref_d1(self):
        d1 = np.cross(self.tangent, np.array([0.0, 1.0, 0.0]))
        return d1 / np.linalg.norm(d1, axis=-1, keepdims=True)


class FakeSim:
    def __init__(self, mode: str, envs: int, dt: float = 0.05, N: int = 21, obstacles: int = 0):
        self.mode, self.envs, self.dt, self.N = mode, envs, dt, N
        self.model = SimpleNamespace(node_count=N, mode=mode, dt=dt, radius=0.05, planar_component=0)
        self.capsules = None
        self.obstacles = obstacles
        self.calls = 0

    def _shape(self, kb, tb):
        ax = -np.cumsum(kb[..., 0], axis=-1)[..., :-1]
        ay = -np.cumsum(kb[..., 1], axis=-1)[..., :-1]
        if self.mode == "2d":
            ay = ay * 0
        t = np.stack([np.sin(ax) * np.cos(ay), np.sin(ay), np.cos(ax) * np.cos(ay)], -1)
        t /= np.linalg.norm(t, axis=-1, keepdims=True)
        x = np.concatenate([np.zeros(kb.shape[:-2] + (1, 3)), np.cumsum(0.05 * t, axis=-2)], axis=-2)
        return x, t, np.cumsum(tb, axis=-1)[..., :-1]

    def reset(self):
        B, N = self.envs, self.N
        x, t, th = self._shape(np.zeros((B, N, 2)), np.zeros((B, N)))
        nd = 2 if self.mode == "2d" else 4
        dof = np.zeros((B, N, nd))
        if nd == 2:
            dof[..., 0], dof[..., 1] = x[..., 0], x[..., 2]
        else:
            dof[..., :3] = x
        return FakeState(dof=dof, dof_vel=np.zeros_like(dof), theta=th, tangent=t, failed=np.zeros(B, bool),
                         time=np.zeros(B), node_ref_twist=np.zeros((B, N)))

    def make_control(self):
        return SimpleNamespace(kappa_bar=np.zeros((self.envs, self.N, 2)), tau_bar=np.zeros((self.envs, self.N)))

    def reset_envs(self, state, ctrl, mask):
        fresh = self.reset()
        for k in ("dof", "dof_vel", "theta", "tangent", "failed", "time", "node_ref_twist"):
            getattr(state, k)[mask] = getattr(fresh, k)[mask]
        ctrl.kappa_bar[mask] = 0
        ctrl.tau_bar[mask] = 0

    def step(self, state, ctrl):
        B = self.envs
        self.calls += 1
        x, t, th = self._shape(ctrl.kappa_bar, ctrl.tau_bar)
        q = state.dof.copy()
        if q.shape[-1] == 2:
            q[..., 0], q[..., 1] = x[..., 0], x[..., 2]
        else:
            q[..., :3] = x
        state.dof_vel[:] = (q - state.dof) / self.dt
        state.dof[:] = q
        state.theta[:] = th
        state.tangent[:] = t
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
            substeps=np.ones(B, np.int64), residual=np.full(B, 1e-3), residual0=np.ones(B),
            energy_stretch=z + 0.1, energy_bend=z + 0.2, energy_twist=z + 0.3, energy_contact=z + 0.4,
            energy_kinetic=z + 0.5, energy_gravity=z + 0.6, max_penetration=z.copy(), contact_count=count,
            contact_edge=np.tile(np.arange(cap), (B, 1)), contact_obstacle=np.zeros((B, cap), np.int64),
            contact_rod_point=pts, contact_obstacle_point=pts.copy(), contact_normal=nrm, contact_normal_force=fn,
            contact_friction_force=np.zeros((B, cap, 3)), contact_gap=np.zeros((B, cap)))

    def material_frames(self, state):
        """Same formula as sim.Simulator: d2 = t x d1, (m1, m2) = d1, d2 rotated by theta."""
        t, d1 = state.edge_tangent, state.edge_ref_d1
        d2 = np.cross(t, d1)
        th = state.edge_theta[..., None]
        c, s = np.cos(th), np.sin(th)
        return c * d1 + s * d2, -s * d1 + c * d2, t.copy()


def fake_make_simulator(config, *, envs, task=None):
    obstacles = 0
    if task is not None and hasattr(task, "scene_capsules"):
        obstacles = 1
    sim = FakeSim(config.mode, envs, config.dt, obstacles=obstacles)
    return sim, sim.model


def fake_set_env_capsules(sim, idx, ends, radius):
    if sim.capsules is None:
        sim.capsules = np.zeros((sim.envs,) + ends.shape[1:])
    sim.capsules[idx] = ends
