"""Stability of the static equilibrium (sim.analysis.static, docs/physics.md §3.8): a saddle of the energy satisfies ∇E = F
as well as a minimum. A clamped column under twice its buckling load left straight and a slack rope pinned at both
ends left straight are reported unstable (negative directions of the static Hessian); ``to_stable`` reaches the
buckled column of the elastica and of damped dynamics, and the sagging rope; stable equilibria are reported
stable."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.special import ellipk

from sim import Simulator, build_model
from sim.analysis.static import solve_static
from sim.cli import EXIT_UNSTABLE, sim_main
from sim.scene.boundary import FixSpec, LoadSpec
from sim.scene.obstacles import PlaneSpec
from sim.scene.spec import dump_scene
from tests.helpers.rodspec import make_spec

N, R, E = 41, 0.02, 1e7
EI = E * np.pi * R ** 4 / 4
LF = 1.0 - 0.5 / (N - 1)  # effective length of the clamped column (docs/physics.md §3.6)
P_CR = np.pi ** 2 * EI / (4 * LF ** 2)  # Euler load of a clamped-free column


def _column(load_factor, **kw):
    """A cantilever along +x, no gravity, a dead axial load load_factor · P_CR on its tip (−x)."""
    spec = make_spec(nodes=N, radius=R, E=E, dt=5e-3, **kw)
    return dataclasses.replace(spec, loads=(LoadSpec(node=-1, force=(-load_factor * P_CR, 0.0, 0.0)),))


def _imperfect(spec, B=1):
    sim = Simulator(build_model(spec), envs=B)
    state, ctrl = sim.reset(), sim.make_control()
    state.dof[:, :, 2] = 1e-4 * np.linspace(0.0, 1.0, N) ** 2  # lateral imperfection 1e-4 at the tip
    return sim, state, ctrl


def _tip(state, e=0):
    p = state.node_pos[e]
    return p[-1] - 0.5 * (p[0] + p[1])  # from the effective built-in end


def _elastica_tip_deflection(load_factor):
    """Lateral tip deflection of the buckled clamped-free elastica: δ = 2 k/√(P/EI) with K(k) = √(P/EI) L."""
    a = np.sqrt(load_factor * P_CR / EI)
    k = brentq(lambda k: ellipk(k * k) - a * LF, 1e-9, 1.0 - 1e-12)
    return 2.0 * k / a


def test_column_above_its_buckling_load_is_unstable_and_to_stable_buckles_it():
    spec = _column(2.0)
    sim, state, ctrl = _imperfect(spec)
    res = solve_static(spec, state, ctrl)
    assert res.converged.all()
    tip = _tip(state)
    assert abs(tip[2]) < 1e-3 and abs(tip[1]) < 1e-12  # nearly straight: the saddle
    assert not res.stable[0] and res.negative_directions[0] == 2  # a round section buckles in two planes
    assert res.lowest_eigenvalue[0] < 0 and res.perturbations[0] == 0
    res = solve_static(spec, state, ctrl, to_stable=True)
    assert res.converged.all() and res.stable[0] and res.negative_directions[0] == 0
    assert res.perturbations[0] >= 1
    tip = _tip(state)
    ref = _elastica_tip_deflection(2.0)
    assert abs(ref / LF - 0.797) < 1e-3
    assert abs(np.hypot(tip[1], tip[2]) - ref) < 1e-3 * LF, (tip, ref)
    # damped dynamics from the same imperfection reach the same buckle (on the side of the imperfection)
    dyn = _column(2.0, damping=5.0, tol=1e-8, dtol=1e-12)
    dsim, dstate, dctrl = _imperfect(dyn)
    for _ in range(2000):
        dsim.step(dstate, dctrl)
    assert np.abs(dstate.dof_vel).max() < 1e-5
    dtip = _tip(dstate)
    assert abs(np.hypot(tip[1], tip[2]) - abs(dtip[2])) < 1e-5 and abs(tip[0] - dtip[0]) < 1e-5, (tip, dtip)


def test_column_below_its_buckling_load_is_stable():
    spec = _column(0.5)
    _, state, ctrl = _imperfect(spec, B=2)
    res = solve_static(spec, state, ctrl, to_stable=True)
    assert res.converged.all() and res.stable.all()
    assert np.all(res.negative_directions == 0) and np.all(res.lowest_eigenvalue > 0)
    assert np.all(res.perturbations == 0)
    assert abs(_tip(state)[2]) < 1e-3  # the imperfection amplified by 1/(1 − P/P_cr) only


def test_slack_rope_left_straight_is_unstable_and_to_stable_lets_it_sag():
    """A rope (rest length 1/0.95 between pins 1 m apart, prestretch −0.05) starting straight stays straight and
    compressed: unstable; pushed off, it sags under gravity and is stable."""
    n = 41
    spec = make_spec(nodes=n, radius=1e-3, E=1e9, gravity=(0.0, 0.0, -9.8), clamp="none", dt=1e-3)
    spec = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, prestretch=-0.05),
                               fixes=(FixSpec(nodes=(0, -1), twist_edges=(0,)),))
    sim = Simulator(build_model(spec), envs=1)
    state, ctrl = sim.reset(), sim.make_control()
    res = solve_static(spec, state, ctrl)
    assert res.converged.all() and not res.stable[0] and res.negative_directions[0] > 0
    assert abs(state.node_pos[0, n // 2, 2]) < 1e-3
    res = solve_static(spec, state, ctrl, to_stable=True)
    assert res.converged.all() and res.stable[0]
    assert state.node_pos[0, n // 2, 2] < -0.1  # hangs down (not an arch)


def test_cli_reports_unstable_equilibrium_and_to_stable(tmp_path, capsys):
    path = tmp_path / "column.toml"
    dump_scene(_column(2.0), path)
    assert sim_main([str(path), "--static"]) == EXIT_UNSTABLE == 3  # a script can tell a saddle from a rest state
    out = capsys.readouterr().out
    assert "unstable equilibrium in 1 env (first: env 0" in out and "--to-stable" in out, out
    outfile = tmp_path / "s.npz"
    assert sim_main([str(path), "--static", "--to-stable", "--out", str(outfile)]) == 0
    out = capsys.readouterr().out
    assert "stable equilibrium (no negative direction" in out and "pushed off an unstable equilibrium" in out, out
    with np.load(outfile) as z:
        assert z["stable"].all() and np.all(z["negative_directions"] == 0)
        assert abs(z["node_pos"][0, 0, -1, 2]) > 0.7


def test_to_stable_with_contact_buckles_the_column_onto_a_wall():
    """The column under twice its buckling load inside a square duct (four planes 0.1 m from its axis): the
    straight column is still a saddle (the walls are out of reach), and ``to_stable`` brings it to an equilibrium
    leaning on a wall (the elastica's free buckle, 0.8 L, would pass through it) whose static Hessian, contact
    included, has no negative direction; nothing passes through a wall."""
    wall = 0.1
    spec = _column(2.0)
    walls = tuple(PlaneSpec(point=tuple(wall * np.asarray(d)), normal=tuple(-np.asarray(d)))
                  for d in ((0.0, 1.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 1.0), (0.0, 0.0, -1.0)))
    spec = dataclasses.replace(spec, obstacles=walls)
    sim, state, ctrl = _imperfect(spec)
    res = solve_static(spec, state, ctrl)
    assert res.converged.all() and not res.stable[0] and res.negative_directions[0] > 0
    res = solve_static(spec, state, ctrl, to_stable=True)
    assert res.converged.all() and res.stable[0] and res.negative_directions[0] == 0 and res.perturbations[0] >= 1
    off = np.abs(state.node_pos[0, :, 1:]).max(axis=1) + R  # each node's surface: its farthest reach off the axis
    assert off.max() <= wall + 1e-9, off.max()  # no node inside a wall
    assert off.max() > wall - spec.contact.delta  # leaning on one (within the contact law's reach)
    assert np.hypot(*_tip(state)[1:]) > 0.05  # buckled, not straight


def _dense_stability(sim, state, ctrl, e=0):
    """The dense reference: all eigenpairs of the mass-weighted static Hessian on the free DOFs."""
    from sim.analysis.static import static_hessian

    m = sim.model
    free = np.flatnonzero(~np.asarray(m.dof_fixed))
    d = 1.0 / np.sqrt(np.asarray(m.dof_mass)[free])
    S = static_hessian(sim, state, ctrl, e)[np.ix_(free, free)] * d[:, None] * d[None, :]
    w, v = np.linalg.eigh(S)
    return w, v, free, d


@pytest.mark.parametrize("mode,load_factor,nodes", [("3d", 2.0, N), ("3d", 0.5, N), ("2d", 5.0, N), ("2d", 0.5, N),
                                                     ("3d", 2.0, 301)])
def test_banded_stability_matches_the_dense_eigensolver(mode, load_factor, nodes):
    """The banded eigensolver and block inverse iteration of ``static_stability`` against numpy's dense eigensolver on
    the same mass-weighted Hessian, at the straight column (a saddle above its buckling load, a minimum below): the
    same count of negative directions, the same lowest eigenvalue (to 1e-9 of the spectrum's scale), and a lowest
    eigenvector in the dense solver's lowest eigenspace. At 301 nodes the stiffest mode is 3e9 times the buckling
    mode: the column still reads unstable (a tolerance of 1e-9 of the largest diagonal entry read it stable)."""
    from sim.analysis.static import negative_threshold, static_stability

    lf = 1.0 - 0.5 / (nodes - 1)
    spec = make_spec(nodes=nodes, radius=R, E=E, dt=5e-3, mode=mode)
    spec = dataclasses.replace(spec, loads=(LoadSpec(node=-1, force=(-load_factor * np.pi ** 2 * EI / (4 * lf ** 2),
                                                                      0.0, 0.0)),))
    sim = Simulator(build_model(spec), envs=1)
    state, ctrl = sim.reset(), sim.make_control()
    assert solve_static(spec, state, ctrl, check_stability=False).converged.all()   # straight: no imperfection
    neg, lam, vec = static_stability(sim, state, ctrl, 0)
    w, v, free, d = _dense_stability(sim, state, ctrl)
    scale = np.abs(w).max()
    S_diag = np.abs(np.einsum("ij,j,ij->i", v, w, v)).max()
    assert neg == int(np.count_nonzero(w < -negative_threshold(sim.model, S_diag)))
    assert neg == (0 if load_factor < 1 else (2 if mode == "3d" else 1))
    assert abs(lam - w[0]) < 1e-9 * scale
    y = vec[free] / d                                       # back to the mass-weighted coordinates
    low = v[:, np.abs(w - w[0]) <= 1e-6 * abs(w[0])]
    assert np.linalg.norm(y - low @ (low.T @ y)) < 1e-6 * np.linalg.norm(y)
