"""Helpers for the verification tests."""
from __future__ import annotations

import numpy as np

from sim import Simulator, build_model


def static_solve(spec, *, steps=20, ctrl_fn=None, locked_edges=(), state_fn=None):
    """Relax to equilibrium with large backward-Euler steps; returns (sim, state, stats)."""
    sim = Simulator(build_model(spec, locked_edges=locked_edges), envs=1)
    state = sim.reset()
    ctrl = sim.make_control()
    if ctrl_fn is not None:
        ctrl_fn(sim, ctrl)
    if state_fn is not None:
        state_fn(sim, state)
    stats = None
    for _ in range(steps):
        stats = sim.step(state, ctrl)
        assert not stats.failed.any()
    return sim, state, stats


def turning_angles_xz(p):
    """Counter-clockwise turning angles (x right, z up) at interior nodes of a planar polyline p (N, 3)."""
    e = np.diff(p[:, [0, 2]], axis=0)
    cr = e[:-1, 0] * e[1:, 1] - e[:-1, 1] * e[1:, 0]
    dt = (e[:-1] * e[1:]).sum(1)
    return np.arctan2(cr, dt)
