"""Internal loads (``sim.analysis.internal``, docs/physics.md §2.5) at static equilibria against statics: the axial force of a
hanging rod is the weight below each edge, the bending moment along a cantilever is the tip load times its lever arm
(3-D and 2-D), the twisting moment of a twisted rod is the end torque, and a rod that has taken its natural shape
holds no moment."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim import LoadSpec, Simulator, build_model
from sim.analysis.internal import internal_loads
from sim.analysis.static import solve_static
from tests.helpers.rodspec import make_spec


def _relaxed(spec):
    sim = Simulator(build_model(spec), envs=1)
    st, ctrl = sim.reset(), sim.make_control()
    res = solve_static(spec, st, ctrl, xtol=1e-13, check_stability=False, max_steps=400)
    assert res.converged.all()
    return sim, st, ctrl


def test_hanging_rod_carries_the_weight_below_each_edge():
    """A rod clamped at the top and hanging under gravity: edge j holds up nodes j+1 … N−1, N_j = g Σ m_k (exact for
    the discrete rod: stretching is the only element a straight rod loads). Edge 0 lies inside the clamp, which holds
    both its nodes: it is not strained and reads 0."""
    spec = make_spec(nodes=11, length=1.0, radius=0.01, E=1e6, direction=(0.0, 0.0, -1.0), gravity=(0.0, 0.0, -9.81),
                     dt=1e3, dtol=1e-14, max_iter=100)
    sim, st, ctrl = _relaxed(spec)
    loads = sim.internal_loads(st, ctrl)
    below = 9.81 * np.cumsum(sim.model.node_mass[::-1])[::-1][1:]
    np.testing.assert_allclose(loads.axial[0, 1:], below[1:], rtol=1e-9)
    assert loads.axial[0, 0] == 0.0
    assert np.abs(loads.bending).max() < 1e-9 * below.max() and np.abs(loads.twisting).max() < 1e-12


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_cantilever_moment_is_the_tip_load_times_its_lever_arm(mode):
    """A cantilever along +x under a tip load P (−z), deflected by ≈ 19 % of its length: the moment at node i is
    P (x_tip − x_i), with the deformed lever arm, about m1 (κ2 bends a +x rod in the x–z plane); measured 2e-4
    relative at 21 nodes (8e-6 at a 4 % deflection: the discretisation's O(φ²)); the other component and the twist
    are 0."""
    P, n = 0.05, 21
    spec = make_spec(nodes=n, length=1.0, radius=0.01, E=1e7, dt=1e3, dtol=1e-14, max_iter=100, mode=mode)
    spec = dataclasses.replace(spec, loads=(LoadSpec(node=n - 1, force=(0.0, 0.0, -P)),))
    sim, st, ctrl = _relaxed(spec)
    x = st.node_pos[0]
    assert 0.15 < -x[-1, 2] < 0.25  # large enough that the deformed lever arm differs from the straight one
    m = sim.internal_loads(st, ctrl)
    inner = slice(2, n - 1)  # node 1 is held by the clamp's second node
    lever = x[-1, 0] - x[inner, 0]
    np.testing.assert_allclose(np.abs(m.bending[0, inner, 1]), P * lever, rtol=1e-3)
    assert np.ptp(np.sign(m.bending[0, inner, 1])) == 0  # one sense of bending along the whole rod
    assert np.abs(m.bending[0, :, 0]).max() < 1e-9 and np.abs(m.twisting[0]).max() < 1e-9
    assert m.bending[0, 0].tolist() == [0.0, 0.0] and m.bending[0, -1].tolist() == [0.0, 0.0]


def test_twisted_rod_carries_the_end_torque():
    """A straight rod clamped at one end (position and twist) with a torque T about its axis at the other: the
    twisting moment is T at every interior node (the clamp's node 1 holds the reaction), and nothing bends."""
    T, n = 0.003, 11
    spec = make_spec(nodes=n, length=1.0, radius=0.01, E=1e6, dt=1e3, dtol=1e-14, max_iter=100)
    spec = dataclasses.replace(spec, loads=(LoadSpec(node=n - 1, torque=T),))
    sim, st, ctrl = _relaxed(spec)
    m = sim.internal_loads(st, ctrl)
    np.testing.assert_allclose(m.twisting[0, 2:-1], T, rtol=1e-9)
    assert abs(st.edge_theta[0, -1]) > 0.1  # it did twist
    assert np.abs(m.bending).max() < 1e-9


def test_a_rod_in_its_natural_shape_holds_no_moment():
    """Natural curvature on a free-ended cantilever without loads: the rod curls until its curvature is the natural
    one, so the moments vanish although κ does not (a moment is stiffness × the strain away from natural)."""
    n = 15
    spec = make_spec(nodes=n, length=0.5, radius=0.01, E=1e6, dt=1e3, dtol=1e-14, max_iter=100)
    sim = Simulator(build_model(spec), envs=2)
    st, ctrl = sim.reset(), sim.make_control()
    sim.set_natural_curvature(ctrl, [0.1, -0.05], nodes=slice(1, n - 1), envs=1)
    sim.set_natural_twist(ctrl, 0.02, nodes=slice(1, n - 1), envs=1)
    res = solve_static(spec, st, ctrl, xtol=1e-13, check_stability=False, max_steps=400)
    assert res.converged.all()
    m = sim.internal_loads(st, ctrl)
    assert m.bending.shape == (2, n, 2) and m.twisting.shape == (2, n) and m.axial.shape == (2, n - 1)
    scale = float(sim.model.EI1_max * 0.1 / sim.model.voronoi_length[1])  # the moment the curl would need if held
    assert np.abs(m.bending).max() < 1e-8 * scale and np.abs(m.twisting).max() < 1e-8 * scale
    assert np.abs(m.axial).max() < 1e-8 * scale
    assert np.abs(st.node_pos[1, :, 2]).max() > 0.05  # env 1 curled, env 0 straight
    # the free function on the same data, and a clear error for data of another rod
    m1, m2, _ = sim.material_frames(st)
    again = internal_loads(sim.model, st.node_pos, m1, m2, ctrl.kappa_bar, ctrl.tau_bar)
    np.testing.assert_array_equal(again.bending, m.bending)
    with pytest.raises(ValueError, match="nodes"):
        internal_loads(sim.model, st.node_pos[:, :-1], m1, m2, ctrl.kappa_bar)
