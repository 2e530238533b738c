"""A tiny kinematic stand-in for ``sim.Simulator`` (same API subset), for fast env-structure tests.

The rod relaxes each step half-way toward the shape whose turning angles equal the natural curvature
(tests/fake_sim_base.py). Env e with ``kappa_bar[e, 5, 0] > 50`` reports a failure (to test failure
handling). Not physics.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from tests.fake_sim_base import FakeObstacles, FakeSimBase, fake_set_env_capsules, make_state, ref_d1

__all__ = ["FakeSim", "fake_make_simulator", "fake_set_env_capsules"]


class FakeSim(FakeSimBase):
    def reset(self):
        x, t, th = self._rest()
        dof = self._dof(x)
        return make_state(dof, th, t, FakeObstacles(self))

    def reset_envs(self, state, ctrl, mask):
        self._reset_fields(state, ctrl, mask, ("dof", "dof_vel", "edge_tangent", "edge_ref_d1", "failed",
                                               "time", "node_ref_twist"))

    def step(self, state, ctrl):
        B = self.envs
        live = ~state.failed
        newly = live & (ctrl.kappa_bar[:, 5, 0] > 50)
        x, t, th = self._shape(ctrl.kappa_bar, ctrl.tau_bar)
        q = state.dof.copy()
        new = q + 0.5 * (self._dof(x, th) - q)
        ok = live & ~newly
        state.dof_vel[ok] = (new[ok] - q[ok]) / self.dt
        state.dof[ok] = new[ok]
        state.edge_tangent[ok] = t[ok]
        state.edge_ref_d1[ok] = ref_d1(t[ok])
        state.time[ok] += self.dt
        state.failed |= newly
        return SimpleNamespace(failed=newly.copy(), newton_iters=np.full(B, 2), converged=np.ones(B, bool),
                               substeps=np.ones(B, np.int64))


def fake_make_simulator(config, *, envs, task=None):
    sim = FakeSim(config.mode, envs, config.dt)
    return sim, sim.model
