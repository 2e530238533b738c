"""Edge–edge contact (self- and rod–rod, docs/physics.md §4.8): the segment distance's gradient and Hessian against
finite differences in every region, the assembled residual's Jacobian (band + coupling list) against finite
differences, the Woodbury-corrected banded solve against a dense solve, friction's direction, the StepStats rows of
a pair against the assembled residual, the cheap lower bound of a pair's gap, and which pairs may touch."""
from __future__ import annotations

import numpy as np
import pytest

from sim.contact.edge_pairs import (
    EdgePairContact,
    _gap,
    _gap_bound,
    add_forces,
    allowed_pairs,
    pair_links,
    pair_rows,
    seg_seg_derivs,
)
from sim.kernels.banded import dense_to_band
from sim.kernels.data import ContactReport
from sim.kernels.newton import linear_solve
from sim.kernels.workspace import alloc_workspace
from tests.helpers.contact import law

# segment pairs (a, b, p, q) per closest-point region
SEGMENTS = {
    "edge_edge": ((0.0, 0.0, 0.0), (1.0, 0.1, 0.0), (0.4, -0.5, 0.3), (0.6, 0.5, 0.25)),
    "point_edge": ((0.0, 0.0, 0.0), (1.0, 0.0, 0.1), (1.3, -0.5, 0.3), (1.2, 0.5, 0.35)),
    "edge_point": ((0.2, -0.4, 0.1), (0.3, 0.6, 0.0), (0.25, 0.1, 0.4), (0.3, 0.2, 1.0)),
    "point_point": ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.3, 0.2, 0.1), (2.0, 0.5, 0.3)),
    "near_parallel": ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.3, 0.05, 0.001), (1.4, 0.05, 0.0015)),
}


def _derivs(x12):
    g = np.zeros(12)
    H = np.zeros((12, 12))
    n = np.zeros(3)
    ws = np.zeros(32)
    d, s, t = seg_seg_derivs(tuple(x12[0:3]), tuple(x12[3:6]), tuple(x12[6:9]), tuple(x12[9:12]), g, H, n, ws)
    return d, s, t, g, H, n


@pytest.mark.parametrize("name", list(SEGMENTS))
def test_segment_distance_gradient_and_hessian_fd(name):
    x = np.concatenate(SEGMENTS[name]).astype(float)
    d, s, t, g, H, n = _derivs(x)
    a, b, p, q = x[0:3], x[3:6], x[6:9], x[9:12]
    assert d == pytest.approx(np.linalg.norm((a + s * (b - a)) - (p + t * (q - p))), rel=1e-12)
    # a brute-force distance over a fine grid is never smaller
    ss = np.linspace(0, 1, 401)
    P1 = a[None] + ss[:, None] * (b - a)[None]
    P2 = p[None] + ss[:, None] * (q - p)[None]
    assert d <= np.linalg.norm(P1[:, None] - P2[None], axis=-1).min() + 1e-12
    h = 1e-6
    for k in range(12):
        xp = x.copy()
        xm = x.copy()
        xp[k] += h
        xm[k] -= h
        dp, *_, gp, _, _ = _derivs(xp)
        dm, *_, gm, _, _ = _derivs(xm)
        assert g[k] == pytest.approx((dp - dm) / (2 * h), abs=1e-7)
        np.testing.assert_allclose(H[:, k], (gp - gm) / (2 * h), atol=2e-5 * max(1.0, np.abs(H).max()))
    np.testing.assert_allclose(H, H.T, atol=1e-10)


def _two_edge_chain(gap, radius=0.02):
    """A 6-node chain whose edges 0 (nodes 0–1) and 4 (nodes 4–5) cross at centre-line distance 2r + gap; the
    nodes between them make a loop far from both."""
    d = 2 * radius + gap
    x = np.array([[-0.1, 0.0, 0.0], [0.1, 0.02, 0.0], [0.3, 0.3, 0.1], [0.0, 0.5, 0.2], [0.01, -0.1, d - 0.005],
                  [-0.01, 0.1, d + 0.005]])
    return x


def _pairs_record(cand, ncand, N):
    """The edge-pair scratch with the candidate list ``cand`` (its count ``ncand``)."""
    return EdgePairContact(cand, ncand, np.zeros((N - 1, 6)), np.zeros(12), np.zeros((12, 12)), np.zeros(3),
                           np.zeros(32))


def _accumulate(x, x_prev, *, mu=0.0, k=1e5, delta=2e-3, radius=0.02, dt=0.01, fixed=None):
    N = x.shape[0]
    n = 4 * N
    kl = 10
    pairs = np.array([[0, 4]], dtype=np.int64)
    cand = np.array([0], dtype=np.int64)
    ncand = np.array([1], dtype=np.int64)
    w = alloc_workspace(N, False, pairs.shape[0])
    f, ab, cp = w.f, w.ab, w.coupling
    f[:] = 0.0
    ab[:] = 0.0
    fixed = np.zeros(n, bool) if fixed is None else fixed
    E = add_forces(_pairs_record(cand, ncand, N), pairs, pair_links(pairs), law(k=k, delta=delta, mu=mu), x, x_prev, dt, 4, fixed,
                   np.array([radius]), w, False, True)
    wdof, wn, M = cp.dof, cp.count, cp.M
    J = np.zeros((n, n))
    for r in range(n):
        for c in range(max(0, r - kl), min(n, r + kl + 1)):
            J[r, c] = ab[r, kl + c - r]
    for a in range(wn[0]):
        for b in range(wn[0]):
            J[wdof[a], wdof[b]] += M[a, b]
    return E, f, J


@pytest.mark.parametrize("gap", [-2e-3, -1e-3, 0.0, 1e-3])
def test_assembled_pair_jacobian_fd(gap):
    """Band + coupling list = the full Jacobian of the pair's residual (no friction: exact)."""
    x = _two_edge_chain(gap)
    E, f, J = _accumulate(x, x)
    assert E > 0.0
    h = 1e-7
    for node in range(6):
        for a in range(3):
            xp = x.copy()
            xm = x.copy()
            xp[node, a] += h
            xm[node, a] -= h
            Ep, fp, _ = _accumulate(xp, xp)
            Em, fm, _ = _accumulate(xm, xm)
            col = 4 * node + a
            assert f[col] == pytest.approx((Ep - Em) / (2 * h), rel=1e-5, abs=1e-6)
            np.testing.assert_allclose(J[:, col], (fp - fm) / (2 * h), rtol=1e-4, atol=1e-3)
    # the blocks between the two edges are off the band (node 1 to node 4: 12 DOFs apart) and were listed
    assert np.abs(J[0:3, 16:19]).max() > 0.0


def test_pair_friction_opposes_sliding():
    x = _two_edge_chain(-1e-3)
    x_prev = x.copy()
    x_prev[0:2, 0] -= 0.005  # edge 0 moved +x by 0.5 m/s relative to edge 4
    _, f0, _ = _accumulate(x, x_prev, mu=0.0)
    _, f1, _ = _accumulate(x, x_prev, mu=0.5)
    fr = f1 - f0  # the residual's friction part = minus the friction force
    force_on_edge0 = -(fr[0:3] + fr[4:7])
    force_on_edge4 = -(fr[16:19] + fr[20:23])
    assert force_on_edge0[0] < 0.0 and force_on_edge4[0] > 0.0
    np.testing.assert_allclose(force_on_edge0, -force_on_edge4, atol=1e-12)
    # sliding (|v_t| > ν): |friction| = μ λ
    _, dE_only, _ = _accumulate(x, x, mu=0.0)
    lam = np.linalg.norm(dE_only[0:3] + dE_only[4:7])
    assert np.linalg.norm(force_on_edge0) == pytest.approx(0.5 * lam, rel=1e-6)


def _report(x, x_prev, *, mu, rows_before=0, cap=8, k=1e5, delta=2e-3, radius=0.02, dt=0.01):
    """The contact rows of the one pair (edges 0 and 4) appended after ``rows_before`` obstacle rows."""
    rows = ContactReport.zeros(1, cap)
    rows.count[0] = rows_before
    rows.edge[:] = 7
    rows.obstacle[:] = 3
    rows.partner[:] = 9
    pairs = np.array([[0, 4]])
    energy, smallest = pair_rows(0, _pairs_record(np.array([0]), np.array([1]), x.shape[0]), pairs, pair_links(pairs),
                                 law(k=k, delta=delta, mu=mu), x, x_prev, dt, np.array([radius]), rows)
    return dict(count=rows.count, edge=rows.edge, obstacle=rows.obstacle, partner=rows.partner,
                rod_point=rows.rod_point, other=rows.obstacle_point, normal=rows.normal, fn=rows.normal_force,
                fr=rows.friction_force, gap=rows.gap, energy=energy, smallest_gap=smallest)


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_pair_rows_carry_the_assembled_contact_force(mu):
    """Each of the pair's two rows states the force on its edge: normal force times normal plus friction equals
    minus the residual the assembly adds on that edge's two nodes (a sliding pair, with and without friction)."""
    x = _two_edge_chain(-1e-3)
    x_prev = x.copy()
    x_prev[0:2, 0] -= 0.005
    energy, f, _ = _accumulate(x, x_prev, mu=mu)
    out = _report(x, x_prev, mu=mu, rows_before=2)
    assert out["count"][0] == 4
    # the same energy by the same formula, compiled in two kernels (FMA contraction may differ in the last bit)
    assert out["energy"] == pytest.approx(energy, rel=1e-14) and energy > 0.0
    assert out["smallest_gap"] == out["gap"][0, 2]
    np.testing.assert_array_equal(out["partner"][0, :2], [-1, -1])  # the obstacle rows before: no partner
    np.testing.assert_array_equal(out["edge"][0, :2], [7, 7])  # ...and otherwise untouched
    np.testing.assert_array_equal(out["edge"][0, 2:4], [0, 4])
    np.testing.assert_array_equal(out["partner"][0, 2:4], [4, 0])
    np.testing.assert_array_equal(out["obstacle"][0, 2:4], [-1, -1])
    force = out["normal"][0, 2:4] * out["fn"][0, 2:4, None] + out["fr"][0, 2:4]
    np.testing.assert_allclose(force[0], -(f[0:3] + f[4:7]), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(force[1], -(f[16:19] + f[20:23]), rtol=1e-12, atol=1e-12)
    gap = out["gap"][0, 2]
    assert gap == out["gap"][0, 3] and -2e-3 < gap < 0.0 and out["fn"][0, 2] > 0.0
    d = out["rod_point"][0, 2] - out["rod_point"][0, 3]  # centre-line points 2r + gap apart along the normal
    np.testing.assert_allclose(d, (0.04 + gap) * out["normal"][0, 2], atol=1e-14)
    np.testing.assert_allclose(out["other"][0, 2], out["rod_point"][0, 3] + 0.02 * out["normal"][0, 2], atol=1e-14)
    if mu:
        assert np.linalg.norm(out["fr"][0, 2]) == pytest.approx(mu * out["fn"][0, 2], rel=1e-6)  # sliding
        assert out["fr"][0, 2, 0] < 0.0  # against edge 0's motion (+x)
    full = _report(x, x_prev, mu=mu, rows_before=7)  # a full report lists no pair, but counts its energy
    assert full["count"][0] == 7 and full["energy"] == out["energy"]


def test_gap_bound_never_exceeds_the_gap():
    """The bounding-sphere bound that lets far candidates skip the closest-point computation is a lower bound of
    the exact gap: random pairs, collinear chains (where it is tight), crossing and far-off-origin edges."""
    rng = np.random.default_rng(7)
    r = np.array([0.01])
    cases = [rng.normal(size=(4, 3)) * rng.choice([1e-3, 1.0, 100.0]) + rng.normal(size=3) * rng.choice([0, 1e3])
             for _ in range(4000)]
    line = np.linspace(0.0, 0.3, 31)
    for off in (0.0, 1e3, -7.3e4):  # a straight chain: pairs k edges apart, the bound equals the gap
        chain = np.stack([line + off, np.full(31, off), np.full(31, 0.5)], axis=1)
        cases += [np.concatenate([chain[i:i + 2], chain[i + k:i + k + 2]]) for i in range(20) for k in range(2, 10)]
    tight = 0
    for x in cases:
        g, b = _gap(x, r, 0, 2), _gap_bound(x, r, 0, 2)
        assert b <= g, (x, b, g)
        tight += g - b < 1e-9 * (1.0 + np.abs(x).max())
    assert tight >= 3 * 160  # the collinear chains: tight up to the rounding slack


def test_woodbury_solve_matches_dense():
    rng = np.random.default_rng(3)
    N = 12
    n = 4 * N
    kl = 10
    A = np.zeros((n, n))
    for i in range(n):
        for j in range(max(0, i - kl), min(n, i + kl + 1)):
            A[i, j] = rng.normal() * 0.1
    A = A + A.T + np.diag(np.full(n, 8.0))
    w = alloc_workspace(N, False, 1)
    w.ab[:, :] = dense_to_band(A, kl)
    dofs = [0, 1, 2, 40, 41, 42, 20]
    Mfull = np.zeros((n, n))
    for a in dofs:
        for b in dofs:
            if abs(a - b) > kl:
                Mfull[a, b] = rng.normal()
    Mfull = Mfull + Mfull.T
    cp = w.coupling
    for s, d in enumerate(dofs):
        cp.slot[d] = s
        cp.dof[s] = d
    cp.count[0] = len(dofs)
    cp.M[:len(dofs), :len(dofs)] = Mfull[np.ix_(dofs, dofs)]
    f = rng.normal(size=n)
    w.f[:] = f
    assert linear_solve(False, w, n, False)
    expect = np.linalg.solve(A + Mfull, f)
    np.testing.assert_allclose(w.dx[:n], expect, rtol=1e-10, atol=1e-12)


def test_allowed_pairs_exclude_neighbours_along_the_rod():
    E = 20
    lbar = np.full(E, 0.01)
    r = np.array([0.02])
    pairs = allowed_pairs(lbar, r, np.zeros(E, np.int64), self_contact=True, rod_contact=False, delta=1e-3)
    # edges i < j touch when straight if the arc between them is below 2r + δ = 0.041: j - i - 1 edges of 0.01
    assert pairs.shape[0] > 0
    gaps = (pairs[:, 1] - pairs[:, 0] - 1) * 0.01
    assert gaps.min() >= 0.041 - 1e-12
    assert allowed_pairs(lbar, r, np.zeros(E, np.int64), self_contact=False, rod_contact=True,
                         delta=1e-3).shape == (0, 2)
    # two rods joined by a joint edge (rod id -1): all cross pairs, never the joint
    rods = np.array([0] * 9 + [-1] + [1] * 10)
    cross = allowed_pairs(lbar, r, rods, self_contact=False, rod_contact=True, delta=1e-3)
    assert cross.shape[0] == 9 * 10 and not np.any(cross == 9)
