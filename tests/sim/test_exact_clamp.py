"""The clamp at a node (``[rod] clamp = "node"``, docs/physics.md §3.6): nodes 0, 1 and θ⁰ held as by the first-edge
clamp, the rod built in exactly at node 1 with edge 0's tangent and material frame. Beam theory and the elastica of
the free length ``L − l̄`` (node 1 to the tip) are reached at second order in the edge length, where the first-edge
clamp reaches the textbook length at first order; the twist is exact; the plane and 3-D agree; the scene key parses,
round-trips and is checked. A ``[[fix]]`` with ``built_in`` builds the rod in the same way wherever it holds an edge
whole (a beam built in at both ends)."""
from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest

from sim import Simulator, build_model
from sim.analysis.static import solve_static
from sim.scene import parse_scene
from sim.scene.boundary import FixSpec, LoadSpec
from sim.scene.spec import scene_to_toml
from sim.scene.tomlio import SceneError
from tests.helpers.rodspec import make_spec, small_scene_toml
from tests.helpers.statics import elastica_tip, static_solve

E, R = 1e7, 0.02
EI = E * np.pi * R ** 4 / 4


def _cantilever(N, *, clamp="node", mode="3d", radius=R, **load):
    """(model, state) of a cantilever of length 1 with a tip load, relaxed by the static solver (sim.analysis.static)."""
    spec = make_spec(nodes=N, length=1.0, radius=radius, E=E, dt=1e-2, dtol=1e-14, max_iter=100, clamp=clamp,
                     mode=mode)
    spec = dataclasses.replace(spec, loads=(LoadSpec(node=-1, **load),))
    sim = Simulator(build_model(spec), envs=1)
    state = sim.reset()
    res = solve_static(spec, state, sim.make_control(), xtol=1e-13, check_stability=False, max_steps=400)
    assert res.converged.all()
    return sim.model, state


def _order(errs):
    """Observed orders of convergence of errors at successive doublings of the node count."""
    return [float(np.log2(a / b)) for a, b in zip(errs[:-1], errs[1:])]


def test_small_tip_load_converges_at_second_order_from_node_1():
    """A small tip force F: the deflection of the tip from node 1 tends to F L_f³/(3 EI) with L_f = L − l̄ the free
    length, the error quartering with each doubling of N (the first-edge clamp's error against its textbook length
    halves; docs/physics.md §8D.7)."""
    F = 1e-3
    node_errs, edge_errs = [], []
    for N in (11, 21, 41):
        l = 1.0 / (N - 1)
        m, state = _cantilever(N, force=(0.0, 0.0, -F))
        p = state.node_pos[0]
        assert np.allclose(p[:2], m.rest_node_pos[:2], atol=0.0)          # the clamp's nodes do not move
        expect = F * (1.0 - l) ** 3 / (3 * EI)
        node_errs.append(abs(-(p[-1, 2] - p[1, 2]) - expect) / expect)
        _, ref = _cantilever(N, clamp="first_edge", force=(0.0, 0.0, -F))
        edge_errs.append(abs(-ref.node_pos[0, -1, 2] - F / (3 * EI)) / (F / (3 * EI)))
    assert node_errs[-1] < 2e-3, node_errs
    assert all(1.8 < o < 2.2 for o in _order(node_errs)), node_errs
    assert all(0.8 < o < 1.2 for o in _order(edge_errs)), edge_errs


def test_large_tip_load_approaches_the_elastica_at_second_order():
    """P L_f²/EI = 3 (the tip drops by more than half the length): the tip, from node 1, tends to the elastica's
    (θ(0) = 0 at node 1, free length L_f = L − l̄) at second order. A thin rod (r = 2 mm: axial strain 3r²/4 ≈ 3e-6)
    so that its stretching stays below the discretisation error the test measures (the elastica is inextensible)."""
    errs = []
    r = 0.002
    for N in (21, 41, 81):
        Lf = 1.0 - 1.0 / (N - 1)
        P = 3.0 * (E * np.pi * r ** 4 / 4) / Lf ** 2
        m, state = _cantilever(N, radius=r, force=(0.0, 0.0, -P))
        p = state.node_pos[0]
        xt, zt = elastica_tip(P / m.EI1_max, Lf)
        assert zt < -0.5 * Lf
        tip = p[-1] - p[1]
        errs.append(float(np.hypot(tip[0] - xt, tip[2] - zt)))
        assert abs(tip[1]) < 1e-12
    assert errs[-1] < 5e-4, errs
    assert all(o > 1.7 for o in _order(errs)), errs


def test_tip_torque_twists_the_rod_from_node_1_exactly():
    """A torque T on the last node: the twist angle grows from the clamp at node 1, edge j ≥ 1 turned by
    T s_j / GJ with s_j its midpoint's distance from node 1 (l̄/2 for edge 1), so the last edge's Φ = T (L − 3l̄/2)/GJ;
    the twist energy is T Φ / 2."""
    N, T = 15, 0.02
    spec = make_spec(nodes=N, E=1e6, dt=1e4, dtol=1e-14, max_iter=100, clamp="node")
    spec = dataclasses.replace(spec, loads=(LoadSpec(node=-1, torque=T),))
    sim, state, stats = static_solve(spec, steps=3)
    m = sim.model
    l = 1.0 / (N - 1)
    s = np.concatenate([[0.0], 0.5 * l + l * np.arange(N - 2)])     # edge 0 (the clamp's) and edges 1.. from node 1
    Phi = T * s / m.GJ_max
    np.testing.assert_allclose(state.edge_theta[0], Phi, atol=1e-9 * Phi[-1])
    assert np.isclose(Phi[-1], T * (1.0 - 1.5 * l) / m.GJ_max)
    assert np.isclose(stats.energy_twist[0], 0.5 * T * Phi[-1], rtol=1e-9)
    assert np.abs(state.node_pos[0, :, 1:]).max() < 1e-12


def test_planar_rod_matches_the_3d_rod():
    """The plane and 3-D give the same clamped-at-node-1 cantilever under a large tip load."""
    P = 2.0 * EI
    tips = [(_cantilever(21, mode=mode, force=(0.0, 0.0, -P))[1].node_pos[0, -1]) for mode in ("3d", "2d")]
    np.testing.assert_allclose(tips[0], tips[1], atol=1e-9)


def test_only_node_1_changes_in_the_model():
    """Against the first-edge clamp, the node clamp changes node 1's bending length (half of edge 1) and its
    stiffnesses (edge 1's, none of edge 0's), and nothing else: the locked DOFs and the masses are the same."""
    spec = make_spec(nodes=6, E=1e6)
    edge_E = (5e6, 1e6, 1e6, 2e6, 1e6)
    spec = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, edge_youngs_modulus=edge_E))
    a = build_model(spec)
    b = build_model(dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, clamp="node")))
    l = 0.2
    assert b.voronoi_length[1] == pytest.approx(0.5 * l)
    np.testing.assert_array_equal(np.delete(a.voronoi_length, 1), np.delete(b.voronoi_length, 1))
    assert b.node_EI1[1] == pytest.approx(1e6 * np.pi * 0.02 ** 4 / 4)  # edge 1's, not the harmonic mean with edge 0
    assert a.node_EI1[1] > b.node_EI1[1]
    np.testing.assert_array_equal(np.delete(a.node_GJ, 1), np.delete(b.node_GJ, 1))
    np.testing.assert_array_equal(a.dof_fixed, b.dof_fixed)
    np.testing.assert_array_equal(a.node_mass, b.node_mass)
    assert a.locked_edges == b.locked_edges == (0,)


def test_scene_key_parses_round_trips_and_is_checked():
    spec = parse_scene(tomllib.loads(small_scene_toml('clamp = "node"')))
    assert spec.rod.clamp == "node"
    again = parse_scene(tomllib.loads(scene_to_toml(spec)))
    assert again.rod.clamp == "node"
    with pytest.raises(SceneError, match=r"rod\.clamp.*first_edge.*node.*none"):
        parse_scene(tomllib.loads(small_scene_toml('clamp = "nodes"')))


def _fixed_beam(N, mode="3d"):
    """A beam of length 1 built in at nodes 1 and N − 2 by two ``[[fix]]`` tables with ``built_in`` (the end edges
    held whole), a small force on its middle node."""
    twist = (lambda j: (j,)) if mode == "3d" else (lambda j: ())
    spec = make_spec(nodes=N, length=1.0, radius=R, E=E, dt=1e-2, dtol=1e-14, max_iter=100, clamp="none", mode=mode)
    return dataclasses.replace(spec, loads=(LoadSpec(node=N // 2, force=(0.0, 0.0, -1e-3)),),
                               fixes=(FixSpec(nodes=(0, 1), twist_edges=twist(0), built_in=True),
                                      FixSpec(nodes=(-2, -1), twist_edges=twist(-1), built_in=True)))


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_beam_built_in_at_both_ends_by_fixes(mode):
    """Both ends built in by ``[[fix]]`` tables (nodes 1 and N − 2): the middle deflection under a central force
    tends to F L_f³/(192 EI) over the free length L_f = L − 2 l̄ at second order."""
    F, errs = 1e-3, []
    for N in (11, 21, 41):
        spec = _fixed_beam(N, mode)
        sim = Simulator(build_model(spec), envs=1)
        state = sim.reset()
        assert solve_static(spec, state, sim.make_control(), xtol=1e-13, check_stability=False).converged.all()
        p = state.node_pos[0]
        expect = F * (1.0 - 2.0 / (N - 1)) ** 3 / (192 * EI)
        errs.append(abs(-(p[N // 2, 2] - p[1, 2]) - expect) / expect)
        assert p[-2, 2] == p[1, 2] == 0.0
    assert errs[-1] < 1e-2, errs                                   # 12.5 %, 2.5 %, 0.55 %
    assert all(1.8 < o < 2.5 for o in _order(errs)), errs          # orders 2.34, 2.16 (2.07, 2.04 at N = 81, 161)


def test_built_in_fix_is_the_node_clamp():
    """``[[fix]] nodes = [0, 1], twist_edges = [0], built_in = true`` on an unclamped rod is ``clamp = "node"``: the
    same model arrays, the same rest state under a load; without ``built_in`` it is the first-edge clamp's."""
    base = make_spec(nodes=9, E=1e6, clamp="none")
    by_fix = build_model(dataclasses.replace(base, fixes=(FixSpec(nodes=(0, 1), twist_edges=(0,), built_in=True),)))
    by_clamp = build_model(dataclasses.replace(base, rod=dataclasses.replace(base.rod, clamp="node")))
    plain = build_model(dataclasses.replace(base, fixes=(FixSpec(nodes=(0, 1), twist_edges=(0,)),)))
    first_edge = build_model(dataclasses.replace(base, rod=dataclasses.replace(base.rod, clamp="first_edge")))
    for name in ("voronoi_length", "node_EI1", "node_EI2", "node_GJ", "dof_fixed", "node_mass"):
        np.testing.assert_array_equal(getattr(by_fix, name), getattr(by_clamp, name), err_msg=name)
        np.testing.assert_array_equal(getattr(plain, name), getattr(first_edge, name), err_msg=name)
    assert by_fix.voronoi_length[1] == 0.5 * plain.voronoi_length[1]


def test_built_in_fix_is_checked_and_round_trips():
    def scene(fix_lines):
        return small_scene_toml('clamp = "none"') + "[[fix]]\n" + fix_lines + "\n"

    spec = parse_scene(tomllib.loads(scene("nodes = [-2, -1]\ntwist_edges = [-1]\nbuilt_in = true")))
    assert spec.fixes[0].built_in
    text = scene_to_toml(spec)
    assert "built_in = true" in text and parse_scene(tomllib.loads(text)).fixes == spec.fixes
    plain = parse_scene(tomllib.loads(scene("nodes = [0]")))
    assert "built_in" not in scene_to_toml(plain)
    for bad, why in (("nodes = [0, 1]\naxes = \"xz\"\ntwist_edges = [0]\nbuilt_in = true", "all axes"),
                     ("nodes = [0, 2]\ntwist_edges = [0]\nbuilt_in = true", "two neighbouring nodes"),
                     ("nodes = [0, 1]\nbuilt_in = true", "twist_edges"),
                     ("nodes = [0, 1]\ntwist_edges = [0]\nbuilt_in = 1", "built_in")):
        with pytest.raises(SceneError, match=r"fix\[0\]\.built_in.*" + why if why != "built_in" else "built_in"):
            parse_scene(tomllib.loads(scene(bad)))
