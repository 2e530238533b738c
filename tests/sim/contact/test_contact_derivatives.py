"""Finite-difference checks of the IMC contact energy, its gradient and Hessian, for every obstacle kind,
across the softplus knee (g = -2delta ... +delta), in penetration, touching (g = 0) and head-on; and of the
friction Jacobian (docs/physics.md §4.1, §4.2, §4.6, §8D.6)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from sim.contact.imc import friction_block, imc_energy
from sim.scene.obstacles import BoxSpec, CapsuleSpec, MeshSpec, PlaneSpec, SphereSpec
from tests.helpers.contact import DELTA, R_ROD, K, accumulate, fd_check, make_set, place_at_gap, report
from tests.helpers.paths import REPO

MESHES = REPO / "assets" / "meshes"
GAPS = [-2 * DELTA, -DELTA, -0.5 * DELTA, 0.0, 0.5 * DELTA, 0.9 * DELTA]


def test_imc_energy_scalar_derivatives_and_reference_numbers():
    for g in np.linspace(-3 * DELTA, 1.2 * DELTA, 43):
        E, dE, d2E = imc_energy(g, K, DELTA)
        h = 1e-9
        Ep, dEp, _ = imc_energy(g + h, K, DELTA)
        Em, dEm, _ = imc_energy(g - h, K, DELTA)
        assert dE == pytest.approx((Ep - Em) / (2 * h), rel=1e-5, abs=1e-6)
        assert d2E == pytest.approx((dEp - dEm) / (2 * h), rel=1e-5, abs=1e-3)
    _, dE0, d2E0 = imc_energy(0.0, K, DELTA)
    assert dE0 == pytest.approx(-K * DELTA * math.log(2) / 15, rel=1e-12)
    assert d2E0 == pytest.approx(0.847 * K, rel=2e-3)
    E, dE, d2E = imc_energy(-10 * DELTA, K, DELTA)  # deep penetration -> k g^2 asymptote
    assert E == pytest.approx(K * (10 * DELTA) ** 2, rel=1e-9) and d2E == pytest.approx(2 * K, rel=1e-9)
    assert imc_energy(DELTA, K, DELTA)[0] < 1e-12 * imc_energy(0.0, K, DELTA)[0]
    assert np.isfinite(imc_energy(-1e3, K, DELTA)).all() and np.isfinite(imc_energy(1e3, K, DELTA)).all()


CASES = {
    "capsule": ([CapsuleSpec((0.2, -0.5, 0.12), (0.2, 0.5, 0.12), 0.1)], [[0.35, 0.0, 0.0], [0.37, 0.03, 0.3]]),
    "capsule_near_parallel": ([CapsuleSpec((0.2, -0.5, 0.12), (0.2, 0.5, 0.12), 0.1)],
                              [[0.35, -0.1, 0.12], [0.3501, 0.1, 0.1201]]),
    "capsule_crossing_end": ([CapsuleSpec((0.0, 0.0, 0.0), (0.0, 0.0, 0.5), 0.03)],
                             [[0.05, -0.2, 0.6], [0.07, 0.2, 0.62]]),
    "sphere": ([SphereSpec((0.0, 0.0, 0.0), 0.2)], [[0.25, -0.1, 0.0], [0.26, 0.1, 0.02]]),
    "sphere_head_on": ([SphereSpec((0.0, 0.0, 0.0), 0.2)], [[0.25, 0.0, 0.0], [0.35, 0.0, 0.0]]),
    "box_face": ([BoxSpec((0.0, 0.0, 0.0), (0.2, 0.1, 0.3), (0.9, 0.1, 0.2, 0.3))],
                 [[0.5, -0.1, 0.0], [0.45, 0.1, 0.05]]),
    "box_head_on": ([BoxSpec((0.0, 0.0, 0.0), (0.2, 0.1, 0.3))], [[0.25, 0.0, 0.0], [0.35, 0.0, 0.0]]),
    "box_edge": ([BoxSpec((0.0, 0.0, 0.0), (0.2, 0.1, 0.3))], [[0.3, 0.2, -0.1], [0.31, 0.21, 0.1]]),
    "box_edge_crossing": ([BoxSpec((0.1, 0.0, 0.0), (0.2, 0.1, 0.3))], [[0.4, 0.3, 0.2], [0.5, 0.05, 0.5]]),
    "mesh_box_face": ([MeshSpec("unit_box.obj", str(MESHES / "unit_box.obj"), (0.4, 0.2, 0.6), (0.0, 0.0, 0.0),
                                (0.9, 0.1, 0.2, 0.3))], [[0.5, -0.1, 0.0], [0.45, 0.1, 0.05]]),
    "mesh_box_edge": ([MeshSpec("unit_box.obj", str(MESHES / "unit_box.obj"), (0.4, 0.2, 0.6))],
                      [[0.3, 0.2, -0.1], [0.31, 0.21, 0.1]]),
    "mesh_torus": ([MeshSpec("torus.stl", str(MESHES / "torus.stl"))], [[0.1, 0.02, 0.12], [0.16, -0.05, 0.2]]),
}


@pytest.mark.parametrize("name", list(CASES))
@pytest.mark.parametrize("gap", GAPS)
def test_edge_contact_gradient_and_hessian_fd(name, gap):
    specs, x0 = CASES[name]
    _, cd = make_set(specs, 2)
    x = place_at_gap(cd, np.array(x0, dtype=float), gap)
    _, out = report(cd, x, delta=1.0)
    assert out["gap"][0, 0] == pytest.approx(gap, abs=1e-9)
    E, eg, eh = fd_check(cd, x)
    assert E > 0
    assert eg < 2e-5, f"gradient rel. error {eg:.2e}"
    assert eh < 2e-4, f"Hessian rel. error {eh:.2e}"


def test_touching_case_force_and_normal_exact():
    """g = 0: force is -E'(0) = k delta ln2 / 15 along the true normal (no spurious extra force)."""
    _, cd = make_set([SphereSpec((0.0, 0.0, 0.0), 0.2)], 2)
    x = np.array([[0.25, -0.1, 0.0], [0.25, 0.1, 0.0]])  # exactly touching at s = 0.5
    E, g, h = accumulate(cd, x)
    f = -(g[0] + g[1])
    assert np.allclose(f, [K * DELTA * math.log(2) / 15, 0, 0], rtol=1e-12, atol=1e-9)
    assert np.allclose(g[0], g[1])  # symmetric split at s = 1/2


def test_plane_per_node_fd_and_friction_jacobian_exact():
    """Plane contact with friction: n and s are constant, so the full Jacobian must match FD exactly."""
    _, cd = make_set([PlaneSpec((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))], 4)
    x = np.array([[0.0, 0.0, R_ROD - 0.002], [0.1, 0.0, R_ROD + 0.001], [0.2, 0.01, R_ROD - 0.004],
                  [0.3, 0.0, R_ROD + 0.0005]])
    for vel in ([0.3, 0.1, 0.0], [2e-3, -1e-3, 0.0]):  # sliding, and inside the smooth stick ramp
        xp = x - 0.05 * np.array(vel)
        E, eg, eh = fd_check(cd, x, x_prev=xp, mu=0.4, friction_on=True)
        assert eh < 1e-5, f"friction Jacobian rel. error {eh:.2e} (v = {vel})"
    E, eg, eh = fd_check(cd, x)
    assert eg < 1e-6 and eh < 1e-5


@pytest.mark.parametrize("vt", [0.5, 4e-3, 5e-4])
def test_friction_block_jacobian_fd(vt):
    """Edge friction residual vs finite differences with the lagged n and s held fixed (lam follows g)."""
    rng = np.random.default_rng(3)
    n = np.array([0.3, -0.2, 0.9])
    n /= np.linalg.norm(n)
    s, dt, mu, nu, g0 = 0.3, 0.05, 0.5, 1e-2, -1e-3
    t = np.cross(n, rng.normal(size=3))
    t /= np.linalg.norm(t)
    x0 = rng.normal(size=6)
    x = x0 + dt * np.concatenate([vt * t + 0.2 * n, vt * t - 0.1 * n])

    def resid(xx):
        a0, b0 = x0[:3], x0[3:]
        a, b = xx[:3], xx[3:]
        g = g0 + n @ ((1 - s) * (a - x[:3]) + s * (b - x[3:]))
        _, dE, d2E = imc_energy(g, K, DELTA)
        fr = np.zeros(6)
        J = np.zeros((6, 6))
        friction_block(tuple((a - a0) / dt), tuple((b - b0) / dt), s, tuple(n), -dE, d2E, mu, nu, dt, fr, J)
        return fr, J

    fr, J = resid(x)
    assert np.linalg.norm(fr) > 0
    Jn = np.zeros((6, 6))
    eps = 1e-8
    for i in range(6):
        xp = x.copy()
        xm = x.copy()
        xp[i] += eps
        xm[i] -= eps
        Jn[:, i] = (resid(xp)[0] - resid(xm)[0]) / (2 * eps)
    assert np.abs(J - Jn).max() < 1e-5 * np.abs(Jn).max()
    _, dE, _ = imc_energy(g0, K, DELTA)
    mag = np.linalg.norm(fr[:3]) + np.linalg.norm(fr[3:])
    assert mag <= 0.5 * -dE * (1 + 1e-12)  # |F_t| <= mu F_n
