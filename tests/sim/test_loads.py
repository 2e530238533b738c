"""Point loads and boundary conditions against beam theory (docs/physics.md §3.1, §3.6, §8D): tip-loaded cantilever (linear
F L³/3EI and the large-deflection elastica, with convergence in N), pinned-pinned beam under a midspan load, a
clamp carried by prescribed motion, a tip moment (a circular arc), a line load (gravity by another name, q L⁴/8EI)
and a follower force (the dead load of its final direction)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim import Simulator, build_model
from sim.analysis.gradients import GradientError, rollout
from sim.analysis.static import solve_static
from sim.scene.boundary import FixSpec, LineLoadSpec, LoadSpec
from tests.helpers.rodspec import make_spec
from tests.helpers.statics import elastica_tip, static_solve, turning_angles_xz

E, R = 1e7, 0.02


def _cantilever(N, F, steps=3, **kw):
    spec = make_spec(nodes=N, length=1.0, radius=R, E=E, dt=1e4, dtol=1e-14, max_iter=100, **kw)
    spec = dataclasses.replace(spec, loads=(LoadSpec(node=-1, force=(0.0, 0.0, -F)),))
    sim, state, stats = static_solve(spec, steps=steps)
    assert stats.converged.all()
    p = state.node_pos[0]
    return sim.model, p[-1] - 0.5 * (p[0] + p[1])  # from the effective built-in end (middle of the clamped edge)


def test_tip_loaded_cantilever_small_load_converges_to_FL3_over_3EI():
    """δ = F L³/(3 EI) is reached as N grows (the clamp's effective end is the middle of edge 0, so the error
    against the textbook length halves with each doubling of N); with the free length L' = L − l̄/2 the discrete
    rod matches beam theory at every N."""
    F = 1e-3
    errs = []
    for N in (11, 21, 41):
        m, tip = _cantilever(N, F)
        EI = m.EI1_max
        d_free = F * (1.0 - 0.5 * m.rest_edge_length[0]) ** 3 / (3 * EI)
        assert abs(-tip[2] - d_free) < 5e-3 * d_free, (N, tip, d_free)
        errs.append(abs(-tip[2] - F / (3 * EI)) / (F / (3 * EI)))
    assert errs[0] > errs[1] > errs[2]
    assert 1.7 < errs[0] / errs[1] < 2.3 and 1.7 < errs[1] / errs[2] < 2.3, errs


def test_tip_loaded_cantilever_large_load_vs_elastica():
    """P L²/EI = 3: the tip drops by more than half the length; the discrete rod approaches the elastica as N
    doubles (reference by shooting the elastica BVP with scipy)."""
    errs = []
    for N in (21, 41):
        EI = E * np.pi * R ** 4 / 4
        P = 3.0 * EI
        m, tip = _cantilever(N, P, steps=8, line_search="backtrack")
        Lf = 1.0 - 0.5 * m.rest_edge_length[0]
        xt, zt = elastica_tip(P / m.EI1_max, Lf)
        assert zt < -0.5 * Lf
        errs.append(float(np.hypot(tip[0] - xt, tip[2] - zt)))
        assert abs(tip[1]) < 1e-12
    assert errs[1] < errs[0] and errs[1] < 3e-3, errs


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_pinned_pinned_beam_midspan_load(mode):
    """Ends pinned by axes only (node 0 fixed in x, y, z; the last node in y, z: a roller), no clamp: the
    midspan deflection is F L³/(48 EI). In 3-D the twist of edge 0 is fixed (else spinning the rod about its
    own axis costs nothing)."""
    N, F = 21, 1e-3
    spec = make_spec(nodes=N, length=1.0, radius=R, E=E, dt=1e4, dtol=1e-14, max_iter=100, clamp="none", mode=mode)
    spec = dataclasses.replace(
        spec, loads=(LoadSpec(node=N // 2, force=(0.0, 0.0, -F)),),
        fixes=(FixSpec(nodes=(0,), axes="xyz", twist_edges=(0,) if mode == "3d" else ()),
               FixSpec(nodes=(-1,), axes="yz")))
    sim, state, stats = static_solve(spec, steps=3)
    assert stats.converged.all()
    p = state.node_pos[0]
    expect = F / (48 * sim.model.EI1_max)
    assert abs(-p[N // 2, 2] - expect) < 5e-3 * expect, (p[N // 2], expect)
    assert p[-1, 0] < 1.0  # the roller end slides in
    assert np.allclose(p[[0, -1], 2], 0.0, atol=1e-15)
    # the pinned ends turn freely: end slope F L²/(16 EI) (the clamp would hold them level)
    slope = (p[1, 2] - p[0, 2]) / (p[1, 0] - p[0, 0])
    assert abs(-slope - F / (16 * sim.model.EI1_max)) < 0.02 * F / (16 * sim.model.EI1_max)


def test_moving_clamp_carries_the_rod():
    """A clamped rod under gravity whose clamp (nodes 0, 1) is carried 0.1 m up and 0.05 m along y by prescribed
    motion, then relaxed: the equilibrium is the one of the fixed clamp, shifted by the prescribed displacement."""
    base = make_spec(nodes=11, E=E, radius=R, gravity=(0.0, 0.0, -9.8), dt=0.01, damping=2.0, dtol=1e-12,
                     max_iter=100)
    move = FixSpec(nodes=(0, 1), velocity=(0.0, 0.5, 1.0), stop=0.1)
    moving = dataclasses.replace(base, fixes=(move,))
    sim = Simulator(build_model(moving), envs=1)
    state, ctrl = sim.reset(), sim.make_control()
    for _ in range(15):
        sim.step(state, ctrl)
        assert not state.failed.any()
    assert np.allclose(state.node_pos[0, :2] - sim.model.rest_node_pos[:2], [0.0, 0.05, 0.1], atol=1e-14)
    # relax both with large steps (the motion's window is over; the same fix stays a plain clamp)
    relax = Simulator(build_model(dataclasses.replace(moving, sim=dataclasses.replace(base.sim, dt=1e4))), envs=1)
    for _ in range(4):
        relax.step(state, ctrl)
    ref = static_solve(dataclasses.replace(base, sim=dataclasses.replace(base.sim, dt=1e4)), steps=4)[1]
    assert np.allclose(state.node_pos[0], ref.node_pos[0] + [0.0, 0.05, 0.1], atol=1e-9)


def test_tip_torque_twists_the_rod_linearly():
    """A torque T about the tangent on the last node (it acts on the last edge's twist) of a rod clamped at edge 0:
    θ grows linearly to Φ = T Σ l_i / GJ (interior Voronoi lengths), the rod stays straight, and the twist energy
    is T Φ / 2."""
    N, T = 15, 0.02
    spec = make_spec(nodes=N, E=1e6, dt=1e4, dtol=1e-14, max_iter=100)
    spec = dataclasses.replace(spec, loads=(LoadSpec(node=-1, torque=T),))
    sim, state, stats = static_solve(spec, steps=3)
    m = sim.model
    Phi = T * m.voronoi_length[1:-1].sum() / m.GJ_max
    assert np.allclose(state.edge_theta[0], Phi * np.arange(N - 1) / (N - 2), atol=1e-9 * Phi)
    assert np.isclose(stats.energy_twist[0], 0.5 * T * Phi, rtol=1e-9)
    assert np.abs(state.node_pos[0, :, 1:]).max() < 1e-12


def _relaxed(spec):
    """(model, state) at the static equilibrium of ``spec`` (sim.analysis.static: moments and follower loads evaluated at
    each pseudo-time step's start, so the rest state is their exact equilibrium)."""
    sim = Simulator(build_model(spec), envs=1)
    state, ctrl = sim.reset(), sim.make_control()
    res = solve_static(spec, state, ctrl, xtol=1e-13, check_stability=False, max_steps=400)
    assert res.converged.all()
    return sim, state


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_tip_moment_bends_a_cantilever_into_a_circular_arc(mode):
    """A couple M about y on the last node (a pair of opposite forces on the last edge): the bending moment is M at
    every node, so every turning angle is the same (a discrete circle), and the tip follows the arc of curvature
    M/EI from the clamp's effective end, to second order in the edge length."""
    errs = []
    for N in (21, 41):
        spec = make_spec(nodes=N, length=1.0, radius=R, E=E, dt=1e4, dtol=1e-14, max_iter=100, mode=mode)
        EI = E * np.pi * R ** 4 / 4
        Lf = 1.0 - 0.5 / (N - 1)
        M = 1.0 * EI / Lf                          # one radian of turning over the free length
        spec = dataclasses.replace(spec, loads=(LoadSpec(node=-1, moment=(0.0, -M, 0.0)),))
        sim, state = _relaxed(spec)
        p = state.node_pos[0]
        ang = turning_angles_xz(p)[1:]                # node 1 is the clamp's: from there on, all equal
        np.testing.assert_allclose(ang, ang.mean(), rtol=1e-7)
        assert ang.mean() > 0                         # a moment of −y turns +x toward +z (counter-clockwise)
        base = 0.5 * (p[0] + p[1])
        kappa = M / EI
        arc = np.array([np.sin(kappa * Lf) / kappa, 0.0, (1 - np.cos(kappa * Lf)) / kappa])
        errs.append(float(np.linalg.norm(p[-1] - base - arc)))
        assert np.abs(p[:, 1]).max() < 1e-12
    assert errs[1] < 2e-3 and 3.0 < errs[0] / errs[1] < 5.0, errs  # second order


def test_moment_along_the_tangent_is_a_torque():
    """A moment along the rod's tangent acts on the twist of the edge like [[load]] torque does."""
    base = make_spec(nodes=15, E=1e6, dt=1e4, dtol=1e-14, max_iter=100)
    _, by_torque = _relaxed(dataclasses.replace(base, loads=(LoadSpec(node=-1, torque=0.02),)))
    _, by_moment = _relaxed(dataclasses.replace(base, loads=(LoadSpec(node=-1, moment=(0.02, 0.0, 0.0)),)))
    np.testing.assert_allclose(by_moment.edge_theta, by_torque.edge_theta, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(by_moment.node_pos, by_torque.node_pos, atol=1e-12)


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_line_load_is_a_weight_per_length(mode):
    """A uniform line load q = ρ A g down is gravity by another name (each node takes its Voronoi length's share,
    as its lumped mass does): the same rest shape; and a small one bends a cantilever by q L⁴/8EI."""
    N = 21
    base = make_spec(nodes=N, length=1.0, radius=R, E=E, dt=1e4, dtol=1e-14, max_iter=100, mode=mode)
    rho_a = 1000.0 * np.pi * R ** 2
    heavy = dataclasses.replace(base, sim=dataclasses.replace(base.sim, gravity=(0.0, 0.0, -9.81)))
    loaded = dataclasses.replace(base, line_loads=(LineLoadSpec(force_per_length=(0.0, 0.0, -9.81 * rho_a)),))
    _, a = _relaxed(heavy)
    _, b = _relaxed(loaded)
    np.testing.assert_allclose(b.node_pos, a.node_pos, atol=1e-12)
    q = 1e-3
    sim, st = _relaxed(dataclasses.replace(base, line_loads=(LineLoadSpec(force_per_length=(0.0, 0.0, -q)),)))
    p = st.node_pos[0]
    Lf = 1.0 - 0.5 * sim.model.rest_edge_length[0]
    expect = q * Lf ** 4 / (8 * sim.model.EI1_max)
    assert -(p[-1, 2] - 0.5 * (p[0, 2] + p[1, 2])) == pytest.approx(expect, rel=2e-2)


def test_follower_force_turns_with_the_rod():
    """A tip force along the last edge's material director m1 (frame = "material"): at its equilibrium it is the
    dead load that equals it there (the same world force holds the same shape), and not the dead load of its
    direction at rest (the rod turned the force with it)."""
    base = make_spec(nodes=21, length=1.0, radius=R, E=E, dt=1e4, dtol=1e-14, max_iter=100)
    EI = E * np.pi * R ** 4 / 4
    F = 1.5 * EI
    follower = dataclasses.replace(base, loads=(LoadSpec(node=-1, force=(F, 0.0, 0.0), frame="material"),))
    sim, st = _relaxed(follower)
    m1, _, _ = sim.material_frames(st)
    world = F * m1[0, -1]
    assert abs(world[0]) > 0.1 * F                          # the tip turned: the force has turned with it
    _, dead = _relaxed(dataclasses.replace(base, loads=(LoadSpec(node=-1, force=tuple(world)),)))
    np.testing.assert_allclose(dead.node_pos, st.node_pos, atol=1e-9)
    m1_rest = sim.material_frames(sim.reset())[0][0, -1]
    _, at_rest = _relaxed(dataclasses.replace(base, loads=(LoadSpec(node=-1, force=tuple(F * m1_rest)),)))
    assert np.abs(at_rest.node_pos - st.node_pos).max() > 0.02                   # 4 cm apart


def test_configuration_dependent_loads_have_no_derivatives_yet():
    spec = dataclasses.replace(make_spec(nodes=5), loads=(LoadSpec(node=-1, moment=(0.0, 0.1, 0.0)),))
    sim = Simulator(build_model(spec), envs=1)
    with pytest.raises(GradientError, match="moments or material-frame loads"):
        rollout(sim, sim.reset(), [sim.make_control()])
