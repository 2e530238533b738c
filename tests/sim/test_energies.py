"""Finite-difference checks of every element energy's gradient and Hessian (docs/physics.md §2, §2.4, §1.6).

Bend/twist are evaluated with frames time-parallel transported from a base configuration; at the base the
analytic gradient and symmetric Hessian are exact (§2.4), so they are compared there. Stretch and planar
bending are exact everywhere.
"""
from __future__ import annotations

import numpy as np
import pytest

from sim.energies.bend_twist import bend_twist_element
from sim.energies.planar import planar_bend_element
from sim.energies.stretch import stretch_element, stretch_element_2d
from sim.geometry.frames import initial_reference_frames, reference_twist, transport


def _bt_energy(q, d1o, to, beta_o, params, with_hess=False):
    """Bend+twist energy of the 11-DOF stencil q with frames transported from (d1o, to, beta_o)."""
    x = np.stack([q[0:3], q[4:7], q[8:11]])
    t = np.diff(x, axis=0)
    t /= np.linalg.norm(t, axis=1)[:, None]
    d1 = np.array([transport(tuple(d1o[j]), tuple(to[j]), tuple(t[j])) for j in range(2)])
    d2 = np.cross(t, d1)
    beta = reference_twist(d1, t, 1, beta_o)
    g = np.zeros(11)
    H = np.zeros((11, 11))
    wk = np.zeros((17, 11))
    eb, et = bend_twist_element(tuple(x[0]), tuple(x[1]), tuple(x[2]), tuple(d1[0]), tuple(d2[0]), tuple(d1[1]),
                                tuple(d2[1]), q[3], q[7], beta, *params, g, H, wk, with_hess)
    return eb + et, g, H


def _fd_grad(fun, q, h=1e-6):
    I = np.eye(len(q))
    return np.array([(fun(q + h * I[k]) - fun(q - h * I[k])) / (2 * h) for k in range(len(q))])


def _fd_hess(fun, q, h=1e-4):
    n = len(q)
    I = np.eye(n)
    H = np.zeros((n, n))
    for a in range(n):
        for b in range(a, n):
            ea, eb = h * I[a], h * I[b]
            H[a, b] = H[b, a] = (fun(q + ea + eb) - fun(q + ea - eb) - fun(q - ea + eb) + fun(q - ea - eb)) / (4 * h * h)
    return H


@pytest.mark.parametrize("bend, twist, seed", [(0.02, 0.0, 0), (0.02, 0.6, 1), (0.8, 0.0, 2), (0.8, 1.0, 3),
                                               (0.4, 2.5, 4)])
def test_bend_twist_gradient_and_hessian_at_base(bend, twist, seed):
    rng = np.random.default_rng(seed)
    x = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]]) + bend * 0.1 * rng.standard_normal((3, 3))
    # a random rigid rotation so that no axis is special
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    x = x @ Q.T
    d1o, to = initial_reference_frames(x)
    q = np.zeros(11)
    q[0:3], q[4:7], q[8:11] = x
    q[3], q[7] = twist * rng.standard_normal(2)
    beta_o = 0.0
    params = (0.1, -0.2, 0.3, 1.3, 0.7, 0.9, 0.1)  # κ̄1, κ̄2, τ̄, EI1, EI2, GJ, l_i
    E, g, H = _bt_energy(q, d1o, to, beta_o, params, True)
    fun = lambda qq: _bt_energy(qq, d1o, to, beta_o, params)[0]  # noqa: E731
    gfd = _fd_grad(fun, q)
    Hfd = _fd_hess(fun, q)
    assert np.abs(g - gfd).max() <= 1e-7 * np.abs(g).max()
    assert np.abs(H - Hfd).max() <= 2e-5 * np.abs(H).max()
    assert np.abs(H - H.T).max() <= 1e-12 * np.abs(H).max()


def test_bend_twist_away_from_base_is_first_order_consistent():
    """Away from the transport base the formulas differ from the exact derivatives by O(displacement) (§2.4)."""
    rng = np.random.default_rng(7)
    x = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]]) + 0.05 * rng.standard_normal((3, 3))
    d1o, to = initial_reference_frames(x)
    q0 = np.zeros(11)
    q0[0:3], q0[4:7], q0[8:11] = x
    params = (0.1, -0.2, 0.3, 1.3, 0.7, 0.9, 0.1)
    fun = lambda qq: _bt_energy(qq, d1o, to, 0.0, params)[0]  # noqa: E731
    errs = []
    for s in (1e-3, 4e-3):
        q = q0 + s * rng.standard_normal(11)
        _, g, _ = _bt_energy(q, d1o, to, 0.0, params)
        errs.append(np.abs(g - _fd_grad(fun, q)).max() / np.abs(g).max())
    assert errs[0] < 1e-2 and errs[1] < 5e-2


@pytest.mark.parametrize("stretch", [0.7, 1.0, 1.3])
def test_stretch_gradient_and_hessian(stretch):
    rng = np.random.default_rng(1)
    lbar, EA = 0.1, 3.0
    d = rng.standard_normal(3)
    d *= stretch * lbar / np.linalg.norm(d)
    q = np.concatenate([rng.standard_normal(3), np.zeros(3)])
    q[3:] = q[:3] + d

    def ev(qq, hess=False):
        g, H = np.zeros(6), np.zeros((6, 6))
        E, _ = stretch_element(tuple(qq[:3]), tuple(qq[3:]), lbar, EA, g, H, hess)
        return E, g, H

    E, g, H = ev(q, True)
    assert np.isclose(E, 0.5 * EA * lbar * (stretch - 1) ** 2)
    assert np.abs(g - _fd_grad(lambda z: ev(z)[0], q)).max() <= 1e-7 * max(np.abs(g).max(), 1e-12) + 1e-10
    assert np.abs(H - _fd_hess(lambda z: ev(z)[0], q)).max() <= 1e-5 * np.abs(H).max()
    assert np.abs(H - H.T).max() <= 1e-14 * np.abs(H).max()

    def ev2(qq, hess=False):
        g2, H2 = np.zeros(4), np.zeros((4, 4))
        E2, _ = stretch_element_2d(tuple(qq[:2]), tuple(qq[2:]), lbar, EA, g2, H2, hess)
        return E2, g2, H2

    a2 = rng.uniform(-np.pi, np.pi)
    q2 = np.array([0.2, -0.1, 0.2 + stretch * lbar * np.cos(a2), -0.1 + stretch * lbar * np.sin(a2)])
    E2, g2, H2 = ev2(q2, True)
    assert np.abs(g2 - _fd_grad(lambda z: ev2(z)[0], q2)).max() <= 1e-6 * max(np.abs(g2).max(), 1.0)
    assert np.abs(H2 - _fd_hess(lambda z: ev2(z)[0], q2)).max() <= 1e-5 * np.abs(H2).max()


@pytest.mark.parametrize("phi", [0.01, 0.7, -1.5, 2.5])
def test_planar_bend_gradient_and_hessian(phi):
    rng = np.random.default_rng(2)
    a0 = rng.uniform(-np.pi, np.pi)
    e = 0.1 * np.array([np.cos(a0), np.sin(a0)])
    f = 0.13 * np.array([np.cos(a0 + phi), np.sin(a0 + phi)])
    q = np.concatenate([[0.3, -0.2], [0.3, -0.2] + e, [0.3, -0.2] + e + f])

    def ev(qq, hess=False):
        g, H = np.zeros(6), np.zeros((6, 6))
        E, k = planar_bend_element(tuple(qq[0:2]), tuple(qq[2:4]), tuple(qq[4:6]), 0.2, 1.7, 0.115, g, H, hess)
        return E, g, H, k

    E, g, H, k = ev(q, True)
    assert np.isclose(k, 2 * np.tan(phi / 2), rtol=1e-12)
    assert np.abs(g - _fd_grad(lambda z: ev(z)[0], q)).max() <= 1e-7 * np.abs(g).max()
    assert np.abs(H - _fd_hess(lambda z: ev(z)[0], q, h=2e-5)).max() <= 1e-5 * np.abs(H).max()
    assert np.abs(H - H.T).max() <= 1e-12 * np.abs(H).max()


def test_energies_invariant_under_rigid_motion():
    rng = np.random.default_rng(3)
    x = np.array([[0.0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]]) + 0.03 * rng.standard_normal((3, 3))
    d1, t = initial_reference_frames(x)
    th = (0.3, -0.4)
    params = (0.1, -0.2, 0.3, 1.3, 0.7, 0.9, 0.1)
    Q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    if np.linalg.det(Q) < 0:
        Q[:, 0] *= -1
    shift = rng.standard_normal(3)

    def energy(xx, dd1, tt):
        d2 = np.cross(tt, dd1)
        g, H, wk = np.zeros(11), np.zeros((11, 11)), np.zeros((17, 11))
        eb, et = bend_twist_element(tuple(xx[0]), tuple(xx[1]), tuple(xx[2]), tuple(dd1[0]), tuple(d2[0]),
                                    tuple(dd1[1]), tuple(d2[1]), th[0], th[1], 0.05, *params, g, H, wk, False)
        g6, H6 = np.zeros(6), np.zeros((6, 6))
        es = sum(stretch_element(tuple(xx[j]), tuple(xx[j + 1]), 0.1, 2.0, g6, H6, False)[0] for j in range(2))
        return eb + et + es

    E0 = energy(x, d1, t)
    E1 = energy(x @ Q.T + shift, d1 @ Q.T, t @ Q.T)
    assert abs(E1 - E0) <= 1e-12 * abs(E0)
    g, H = np.zeros(6), np.zeros((6, 6))
    xr = x[:, [0, 2]]
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, -s], [s, c]])
    xr2 = xr @ R.T + [1.0, -2.0]
    Ep = planar_bend_element(tuple(xr[0]), tuple(xr[1]), tuple(xr[2]), 0.1, 1.0, 0.1, g, H, False)[0]
    Ep2 = planar_bend_element(tuple(xr2[0]), tuple(xr2[1]), tuple(xr2[2]), 0.1, 1.0, 0.1, g, H, False)[0]
    assert abs(Ep - Ep2) <= 1e-12 * abs(Ep)


def test_planar_curvature_matches_3d_kappa1_for_upright_rod():
    """§1.6: for a rod along +z, κ1 = κ_2D; a positive κ turns the tangent counter-clockwise (toward −x)."""
    phi = 0.4
    x = np.array([[0.0, 0, 0], [0.0, 0, 0.1], [-0.1 * np.sin(phi), 0, 0.1 + 0.1 * np.cos(phi)]])
    d1, t = initial_reference_frames(x)
    d2 = np.cross(t, d1)
    g, H, wk = np.zeros(11), np.zeros((11, 11)), np.zeros((17, 11))
    eb, _ = bend_twist_element(tuple(x[0]), tuple(x[1]), tuple(x[2]), tuple(d1[0]), tuple(d2[0]), tuple(d1[1]),
                               tuple(d2[1]), 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, g, H, wk, False)
    g6, H6 = np.zeros(6), np.zeros((6, 6))
    _, k2d = planar_bend_element((0.0, 0.0), (0.0, 0.1), tuple(x[2, [0, 2]]), 0.0, 1.0, 1.0, g6, H6, False)
    assert np.isclose(k2d, 2 * np.tan(phi / 2))
    assert np.isclose(eb, 0.5 * k2d ** 2)  # only κ1 = κ_2D is non-zero
    from sim.energies.bend_twist import material_curvatures
    k1, k2 = material_curvatures(tuple(x[0]), tuple(x[1]), tuple(x[2]), tuple(d1[0]), tuple(d2[0]), tuple(d1[1]),
                                 tuple(d2[1]))
    assert np.isclose(k1, k2d) and abs(k2) < 1e-14


def test_bend_twist_core_upper_only_matches_full_upper_triangle():
    """The solver's symmetric path asks the element for the upper triangle only: it must equal the full
    Hessian's upper triangle (and the gradient and energies must not change)."""
    from sim.energies.bend_twist import bend_twist_core, material_directors

    rng = np.random.default_rng(7)
    x = np.cumsum(rng.uniform(0.05, 0.1, (3, 3)), axis=0)
    d1, t = initial_reference_frames(x)
    d2 = np.cross(t, d1)
    th = rng.standard_normal(2)
    m1e, m2e = material_directors(tuple(d1[0]), tuple(d2[0]), th[0])
    m1f, m2f = material_directors(tuple(d1[1]), tuple(d2[1]), th[1])
    out = []
    for upper in (False, True):
        g, H, wk = np.zeros(11), np.full((11, 11), np.nan), np.zeros((17, 11))
        E = bend_twist_core(tuple(x[0]), tuple(x[1]), tuple(x[2]), m1e, m2e, m1f, m2f, th[1] - th[0] + 0.1,
                            0.1, -0.2, 0.3, 1.3, 0.7, 0.9, 0.1, g, H, wk, True, upper)
        out.append((E, g, H))
    (E0, g0, H0), (E1, g1, H1) = out
    iu = np.triu_indices(11)
    assert E0 == E1 and np.array_equal(g0, g1)
    assert np.all(np.isfinite(H0)) and np.array_equal(H0[iu], H1[iu])
