"""Static relaxation and reference solutions for the simulator's verification tests."""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_bvp

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


def elastica_tip(alpha, Lf):
    """Cantilever of length Lf with a dead vertical tip load P: EI θ'' + P cos θ = 0, θ(0) = 0, θ'(Lf) = 0
    (θ: downward tangent angle), alpha = P/EI. Returns (x_tip, z_tip) from the clamp."""
    s = np.linspace(0, Lf, 401)

    def rhs(s, y):
        return np.vstack([y[1], -alpha * np.cos(y[0]), np.cos(y[0]), -np.sin(y[0])])

    def bc(ya, yb):
        return np.array([ya[0], yb[1], ya[2], ya[3]])

    y0 = np.zeros((4, s.size))
    y0[2] = s
    sol = solve_bvp(rhs, bc, s, y0, tol=1e-10, max_nodes=100000)
    assert sol.success
    return sol.y[2, -1], sol.y[3, -1]
