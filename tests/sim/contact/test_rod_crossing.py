"""One crossing of two rods is one contact wherever it falls along their edges (docs/physics.md §4.8, "One crossing,
one contact"): each rod counts as its edges less its interior nodes, so the contact energy of two straight rods
crossing at a gap g is E(g) whether the crossing falls inside edges, on a node of one rod or on a node of both, its
forces are the energy's gradient, and a rod resting across two fixed beams comes to rest at the same gap — the
closed-form gap of the IMC law under its weight — for every placement of the crossings, and so does a soft rod
draped across another on a floor (where the crossing sits in a kink of both rods)."""
from __future__ import annotations

import numpy as np
import pytest

from benchmarks import rod_crossing
from sim.contact.edge_pairs import add_forces, alloc, allowed_pairs, find_candidates, pair_energy, pair_links
from sim.contact.imc import imc_energy
from sim.kernels.workspace import alloc_workspace
from tests.helpers.contact import law

R = 0.01
K, DELTA = 1e5, 1e-3
EDGE = 0.05


def _crossing_energy(shift_a: float, shift_b: float, gap: float) -> float:
    """Contact energy [J] of rod A (11 nodes along x, edges of 5 cm) and rod B (11 nodes along y, 2r + gap above)
    crossing at x = shift_a along A and y = shift_b along B (0: on a node of each)."""
    xa = np.stack([EDGE * np.arange(-5, 6) - shift_a, np.zeros(11), np.zeros(11)], axis=1)
    xb = np.stack([np.zeros(11), EDGE * np.arange(-5, 6) - shift_b, np.full(11, 2 * R + gap)], axis=1)
    x = np.concatenate([xa, xb])                         # one chain: edge 10 joins the two rods
    rods = np.array([0] * 10 + [-1] + [1] * 10)
    lbar = np.linalg.norm(np.diff(x, axis=0), axis=1)
    pairs = allowed_pairs(lbar, np.array([R]), rods, self_contact=False, rod_contact=True, delta=DELTA)
    ep = alloc(x.shape[0], pairs.shape[0])
    radius = np.array([R])
    find_candidates(ep, pairs, x, x, radius, 10 * DELTA)
    return pair_energy(ep, pairs, pair_links(pairs), law(k=K, delta=DELTA), x, radius)


@pytest.mark.parametrize("gap", [-3e-4, 0.0, 4e-4])
def test_a_crossing_counts_once_wherever_it_falls(gap):
    one = imc_energy(gap, K, DELTA)[0]
    shifts = [0.0, 1e-6, 0.2 * EDGE, 0.5 * EDGE, 0.97 * EDGE, EDGE]
    for sa in shifts:
        for sb in shifts:
            # inside edges, on a node of one rod (2 pairs touch there) or of both (4 pairs): one contact
            assert _crossing_energy(sa, sb, gap) == pytest.approx(one, rel=1e-9), (sa, sb)


def _kinked_chain(kink: float, gap: float) -> np.ndarray:
    """Rod A (11 nodes along x) bent down by ``kink`` [rad] at its middle node on each side (a valley), rod B across
    it along y, bent up at its middle node by the same angle (a ridge), their middle nodes 2r + gap apart."""
    s = EDGE * np.arange(-5, 6)
    xa = np.stack([s, np.zeros(11), np.abs(s) * np.tan(kink)], axis=1)
    xb = np.stack([np.zeros(11), s, 2 * R + gap - np.abs(s) * np.tan(kink)], axis=1)
    return np.concatenate([xa, xb])


def _pair_terms(x):
    """(energy, residual (N, 3), pairs, ep, links) of the chain of two 11-node rods at x."""
    rods = np.array([0] * 10 + [-1] + [1] * 10)
    lbar = np.full(21, EDGE)
    pairs = allowed_pairs(lbar, np.array([R]), rods, self_contact=False, rod_contact=True, delta=DELTA)
    ep = alloc(x.shape[0], pairs.shape[0])
    radius = np.array([R])
    find_candidates(ep, pairs, x, x, radius, 10 * DELTA)
    w = alloc_workspace(x.shape[0], False, pairs.shape[0])
    w.f[:] = 0.0
    w.ab[:] = 0.0
    links = pair_links(pairs)
    E = add_forces(ep, pairs, links, law(k=K, delta=DELTA), x, x, 0.01, 4, np.zeros(4 * x.shape[0], bool), radius, w,
                   False, False)
    return E, w.f.reshape(-1, 4)[:, :3].copy(), pairs, ep, links


@pytest.mark.parametrize("kink", [0.0, 0.02, 0.1])
def test_the_residual_is_the_gradient_of_the_energy_at_a_kinked_crossing(kink):
    """Where both rods bend toward each other at a node, each of the 4 pairs has its own minimum beside it; the
    node terms keep one contact, and the residual (forces of every term) is the energy's gradient."""
    x = _kinked_chain(kink, 2e-4)
    E, f, *_ = _pair_terms(x)
    if kink == 0.0:
        assert E == pytest.approx(imc_energy(2e-4, K, DELTA)[0], rel=1e-9)
    h = 1e-8
    for node in (4, 5, 6, 15, 16, 17):
        for a in range(3):
            xp, xm = x.copy(), x.copy()
            xp[node, a] += h
            xm[node, a] -= h
            fd = (_pair_terms(xp)[0] - _pair_terms(xm)[0]) / (2 * h)
            assert f[node, a] == pytest.approx(fd, rel=1e-5, abs=1e-7 * np.abs(f).max())


def test_a_rod_across_two_beams_rests_at_the_same_gap_wherever_the_crossings_fall():
    # each crossing carries half the rod's weight: the IMC law's gap for that force
    expected = rod_crossing.law_gap()
    for shift_x, top_nodes in rod_crossing.PLACEMENTS:
        r = rod_crossing.rest(shift_x, top_nodes)
        assert not r["failed"] and r["max_speed"] < 5e-3             # at rest (it may only drift along the beams)
        assert r["up_force"] == pytest.approx(rod_crossing.rod_weight(), rel=1e-4)
        np.testing.assert_allclose(r["gaps"], expected, rtol=1e-3, err_msg=f"crossings at {shift_x}, {top_nodes} nodes")
