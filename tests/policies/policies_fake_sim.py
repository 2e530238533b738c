"""A tiny kinematic stand-in for ``sim.Simulator`` (same API subset), for fast env-structure tests.

The rod relaxes each step half-way toward the shape whose turning angles equal the natural
curvature (kappa1 bends toward -x, kappa2 toward -y), twist = cumulative natural twist. Env e with
``kappa_bar[e, 5, 0] > 50`` reports a failure (to test failure handling). Not physics.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np


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


class FakeSim:
    def __init__(self, mode: str, envs: int, dt: float = 0.05, N: int = 21):
        self.mode, self.envs, self.dt, self.N = mode, envs, dt, N
        self.model = SimpleNamespace(node_count=N, mode=mode, dt=dt)
        self.capsules = None

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
        return FakeState(dof=dof, dof_vel=np.zeros_like(dof), edge_theta=th, edge_tangent=t,
                         edge_ref_d1=self._ref_d1(t), failed=np.zeros(B, bool), time=np.zeros(B))

    @staticmethod
    def _ref_d1(t):
        d1 = np.cross(t, np.array([0.0, 1.0, 0.0]))      # for t = +z: (-1, 0, 0)
        return d1 / np.linalg.norm(d1, axis=-1, keepdims=True)

    def make_control(self):
        return SimpleNamespace(kappa_bar=np.zeros((self.envs, self.N, 2)), tau_bar=np.zeros((self.envs, self.N)))

    def reset_envs(self, state, ctrl, mask):
        fresh = self.reset()
        for k in ("dof", "dof_vel", "edge_theta", "edge_tangent", "edge_ref_d1", "failed", "time"):
            getattr(state, k)[mask] = getattr(fresh, k)[mask]
        ctrl.kappa_bar[mask] = 0
        ctrl.tau_bar[mask] = 0

    def step(self, state, ctrl):
        B = self.envs
        live = ~state.failed
        newly = live & (ctrl.kappa_bar[:, 5, 0] > 50)
        x, t, th = self._shape(ctrl.kappa_bar, ctrl.tau_bar)
        q = state.dof.copy()
        tgt = np.zeros_like(q)
        if q.shape[-1] == 2:
            tgt[..., 0], tgt[..., 1] = x[..., 0], x[..., 2]
        else:
            tgt[..., :3] = x
        new = q + 0.5 * (tgt - q)
        ok = live & ~newly
        state.dof_vel[ok] = (new[ok] - q[ok]) / self.dt
        state.dof[ok] = new[ok]
        state.edge_theta[ok] = th[ok]
        state.edge_tangent[ok] = t[ok]
        state.edge_ref_d1[ok] = self._ref_d1(t[ok])
        state.time[ok] += self.dt
        state.failed |= newly
        return SimpleNamespace(failed=newly.copy(), newton_iters=np.full(B, 2), converged=np.ones(B, bool),
                               substeps=np.ones(B, np.int64))

    def material_frames(self, state):
        t, d1 = state.edge_tangent, state.edge_ref_d1
        d2 = np.cross(t, d1)
        c, s = np.cos(state.edge_theta)[..., None], np.sin(state.edge_theta)[..., None]
        return c * d1 + s * d2, -s * d1 + c * d2, t


def fake_make_simulator(config, *, envs, task=None):
    sim = FakeSim(config.mode, envs, config.dt)
    return sim, sim.model


def fake_set_env_capsules(sim, idx, ends, radius):
    if sim.capsules is None:
        sim.capsules = np.zeros((sim.envs,) + ends.shape[1:])
    sim.capsules[idx] = ends
