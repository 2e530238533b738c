"""Closed-form static checks (docs/physics.md §8D): gravity cantilever (small and large deflection), natural
curvature arc (3-D and 2-D), pure twist."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_bvp

from sim import load_scene
from tests.helpers.rodspec import make_spec, with_sim
from tests.helpers.statics import static_solve, turning_angles_xz


def test_gravity_cantilever_small_deflection(scenes_dir):
    """Tip deflection vs w L'^4/(8 EI) with L' = L − l̄/2.

    Clamp convention: nodes 0 and 1 are fixed and the bending stiffness of node 1 acts over its Voronoi
    region [l̄/2, 3l̄/2], so the effective built-in end is the middle of the clamped edge (L' = 0.99 m here; the
    textbook value for L = 1 m, 6.13 mm, is 4% higher)."""
    spec = with_sim(load_scene(scenes_dir / "cantilever_gravity.toml"), dt=1e4, damping=0.0, newton_dtol=1e-14)
    sim, state, stats = static_solve(spec, steps=3)
    m = sim.model
    w = m.spec.rod.density * np.pi * m.radius_max ** 2 * 9.8
    assert abs(w * 1.0 ** 4 / (8 * m.EI1_max) - 6.13e-3) < 0.01e-3
    Lf = 1.0 - 0.5 * m.rest_edge_length[0]
    expect = w * Lf ** 4 / (8 * m.EI1_max)
    tip = state.node_pos[0, -1]
    assert stats.converged.all()
    assert abs(-tip[2] - expect) <= 0.005 * expect, (tip, expect)


def _elastica_tip(q, Lf):
    """Cantilever of free length Lf under distributed weight: EI θ'' + w (Lf − s) cos θ = 0, θ(0) = 0,
    θ'(Lf) = 0 (θ: downward tangent angle), q = w/EI. Returns (x_tip, z_tip) from the clamp."""
    s = np.linspace(0, Lf, 401)

    def rhs(s, y):
        return np.vstack([y[1], -q * (Lf - s) * np.cos(y[0]), np.cos(y[0]), -np.sin(y[0])])

    def bc(ya, yb):
        return np.array([ya[0], yb[1], ya[2], ya[3]])

    y0 = np.zeros((4, s.size))
    y0[2] = s
    sol = solve_bvp(rhs, bc, s, y0, tol=1e-10, max_nodes=100000)
    assert sol.success
    return sol.y[2, -1], sol.y[3, -1]


def test_gravity_cantilever_large_deflection_vs_elastica():
    """Soft rod (w L³/EI ≈ 5); free length and origin from the clamp convention (mid-point of edge 0)."""
    spec = make_spec(nodes=41, length=1.0, radius=0.02, density=500.0, E=1e7, gravity=(0.0, 0.0, -9.8), dt=1e4,
                     line_search="backtrack", max_iter=100, dtol=1e-14)
    sim, state, stats = static_solve(spec, steps=6)
    m = sim.model
    q = m.spec.rod.density * np.pi * m.radius_max ** 2 * 9.8 / m.EI1_max
    Lf = 1.0 - 0.5 * m.rest_edge_length[0]
    xt, zt = _elastica_tip(q, Lf)
    p = state.node_pos[0]
    rel = p[-1] - 0.5 * (p[0] + p[1])
    assert zt < -0.3 * Lf  # genuinely large deflection
    assert abs(rel[0] - xt) < 2e-3 and abs(rel[2] - zt) < 2e-3, (rel, xt, zt)
    assert abs(rel[1]) < 1e-12


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_natural_curvature_gives_polygonal_arc(mode):
    """Uniform κ̄ = 2 tan(φ/2) on a +z rod, no gravity: equilibrium turning angle φ at every node, l = l̄,
    counter-clockwise (toward −x) for positive κ̄1 (docs/physics.md §1.6)."""
    phi = 0.15
    spec = make_spec(nodes=21, direction=(0.0, 0.0, 1.0), E=1e6, radius=0.02, mode=mode, dt=1e4,
                     line_search="backtrack", max_iter=100, dtol=1e-14)

    def ctrl_fn(sim, ctrl):
        ctrl.kappa_bar[:, 1:-1, 0] = 2 * np.tan(phi / 2)

    sim, state, _ = static_solve(spec, steps=4, ctrl_fn=ctrl_fn)
    p = state.node_pos[0]
    ang = turning_angles_xz(p)
    assert np.abs(ang - phi).max() < 1e-8
    lens = np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert np.abs(lens / sim.model.rest_edge_length - 1).max() < 1e-9
    assert p[-1, 0] < -0.5 and np.abs(p[:, 1]).max() < 1e-12


def test_pure_twist_linear_theta_and_energy():
    """Both end edges clamped, θ of the last edge set to Φ: θ linear along the rod, E = GJ Φ²/(2 Σ l_i)."""
    N, Phi = 15, 1.3
    spec = make_spec(nodes=N, direction=(1.0, 0.0, 0.0), E=1e6, dt=1e4, max_iter=100, dtol=1e-14)

    def state_fn(sim, state):
        state.dof[:, N - 2, 3] = Phi

    sim, state, stats = static_solve(spec, steps=3, locked_edges=(N - 2,), state_fn=state_fn)
    th = state.edge_theta[0]
    assert np.allclose(th, Phi * np.arange(N - 1) / (N - 2), atol=1e-9)
    m = sim.model
    expect = m.GJ_max * Phi ** 2 / (2 * m.voronoi_length[1:-1].sum())
    assert np.isclose(stats.energy_twist[0], expect, rtol=1e-9)
    assert stats.energy_bend[0] < 1e-12 * expect
    assert np.abs(state.node_pos[0, :, 1:]).max() < 1e-12
