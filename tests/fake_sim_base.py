"""Shared parts of the kinematic stand-ins for ``sim.Simulator`` used by fast tests (not physics).

The rod takes the shape whose turning angles equal the natural curvature (kappa1 bends toward -x, kappa2
toward -y), twist = cumulative natural twist. Subclasses (tests/policies/policies_fake_sim.py,
tests/recordings/recordings_fake_sim.py) decide how ``step`` moves toward it and what it reports.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from sim.state import State


class FakeObstacles:
    """``state.obstacles`` of a fake state: capsules re-placed through it land on the fake simulator."""

    def __init__(self, sim):
        self.sim = sim

    def copy(self) -> "FakeObstacles":
        return self


def make_state(dof, theta, tangent, obstacles=None) -> State:
    """A real :class:`sim.state.State` for the fakes (so they cannot drift from the State API): twist angles
    ``theta`` (B, N-1) go into the θ slots of a 3-D ``dof`` (B, N, 4); 2-D states have none."""
    B, N = dof.shape[:2]
    if dof.shape[-1] == 4:
        dof[:, :-1, 3] = theta
    return State(dof=dof, dof_vel=np.zeros_like(dof), edge_ref_d1=ref_d1(tangent), edge_tangent=tangent.copy(),
                 node_ref_twist=np.zeros((B, N)), time=np.zeros(B), failed=np.zeros(B, bool),
                 obstacles=obstacles)


def ref_d1(t):
    d1 = np.cross(t, np.array([0.0, 1.0, 0.0]))      # for t = +z: (-1, 0, 0)
    return d1 / np.linalg.norm(d1, axis=-1, keepdims=True)


class FakeSimBase:
    def __init__(self, mode: str, envs: int, dt: float = 0.05, N: int = 21, **model):
        self.mode, self.envs, self.dt, self.N = mode, envs, dt, N
        self.model = SimpleNamespace(node_count=N, mode=mode, dt=dt, **model)
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

    def _dof(self, x, theta=None):
        """(B, N, 2|4) DOFs of node positions x (B, N, 3) and twist angles theta (B, N-1) (default 0)."""
        nd = 2 if self.mode == "2d" else 4
        dof = np.zeros(x.shape[:-1] + (nd,))
        if nd == 2:
            dof[..., 0], dof[..., 1] = x[..., 0], x[..., 2]
        else:
            dof[..., :3] = x
            if theta is not None:
                dof[..., :-1, 3] = theta
        return dof

    def _rest(self):
        B, N = self.envs, self.N
        return self._shape(np.zeros((B, N, 2)), np.zeros((B, N)))

    def make_control(self):
        return SimpleNamespace(kappa_bar=np.zeros((self.envs, self.N, 2)), tau_bar=np.zeros((self.envs, self.N)))

    def _reset_fields(self, state, ctrl, mask, fields):
        fresh = self.reset()
        for k in fields:
            getattr(state, k)[mask] = getattr(fresh, k)[mask]
        ctrl.kappa_bar[mask] = 0
        ctrl.tau_bar[mask] = 0

    def material_frames(self, state):
        """Same formula as sim.Simulator: d2 = t x d1, (m1, m2) = d1, d2 rotated by theta."""
        t, d1 = state.edge_tangent, state.edge_ref_d1
        d2 = np.cross(t, d1)
        th = state.edge_theta[..., None]
        c, s = np.cos(th), np.sin(th)
        return c * d1 + s * d2, -s * d1 + c * d2, t.copy()


def fake_set_env_capsules(state, idx, ends, radius):
    sim = state.obstacles.sim
    if sim.capsules is None:
        sim.capsules = np.zeros((sim.envs,) + ends.shape[1:])
    sim.capsules[idx] = ends
