"""Property tests (hypothesis) of the physics kernels on random configurations.

Complements the finite-difference tests in tests/sim/test_energies.py (gradient/Hessian vs FD at chosen
configurations) with structural properties over random inputs:

* energies are >= 0 and vanish at the natural state;
* internal forces are free of net force and net moment (translation / rotation invariance);
* energies are invariant under rigid motions (positions and directors rotated together);
* the Hessian is symmetric and its action matches the change of the gradient (directional FD);
* the 3-D bend kernel and the reduced 2-D kernel agree on planar configurations (docs/physics.md §1.6).
"""
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sim.energies.bend_twist import bend_twist_element, material_curvatures
from sim.energies.planar import planar_bend_element
from sim.energies.stretch import stretch_element
from sim.geometry.frames import initial_reference_frames

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])

coord = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)
vec3 = st.tuples(coord, coord, coord)
angle = st.floats(-math.pi, math.pi, allow_nan=False)
seed = st.integers(0, 2**31 - 1)


def _rotation(rng) -> np.ndarray:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _polyline(rng, max_turn=2.0) -> np.ndarray:
    """Three nodes with edge lengths in [0.02, 0.2] m and a turning angle below ``max_turn`` rad."""
    t0 = rng.normal(size=3)
    t0 /= np.linalg.norm(t0)
    perp = np.cross(t0, rng.normal(size=3))
    perp /= np.linalg.norm(perp)
    phi = rng.uniform(0, max_turn)
    t1 = math.cos(phi) * t0 + math.sin(phi) * perp
    x0 = rng.normal(size=3) * 0.3
    x1 = x0 + rng.uniform(0.02, 0.2) * t0
    x2 = x1 + rng.uniform(0.02, 0.2) * t1
    return np.stack([x0, x1, x2])


def _bend(x, d1, t, the, thf, beta, kb1, kb2, tb, EI1=2.0, EI2=3.0, GJ=1.5, lv=0.1, hess=True):
    d2 = np.cross(t, d1)
    g = np.zeros(11)
    H = np.zeros((11, 11))
    wk = np.zeros((17, 11))  # scratch size documented in bend_twist_element
    eb, et = bend_twist_element(tuple(x[0]), tuple(x[1]), tuple(x[2]), tuple(d1[0]), tuple(d2[0]), tuple(d1[1]),
                                tuple(d2[1]), the, thf, beta, kb1, kb2, tb, EI1, EI2, GJ, lv, g, H, wk, hess)
    return eb, et, g, H


def _frames(x):
    d1, t = initial_reference_frames(x)
    return d1, t


# ------------------------------------------------------------------------------------------------ stretch
@SETTINGS
@given(a=vec3, b=vec3, lbar=st.floats(0.01, 2.0), EA=st.floats(1.0, 1e6), s=seed)
def test_stretch_energy_nonnegative_force_free_and_rotation_covariant(a, b, lbar, EA, s):
    xa, xb = np.array(a), np.array(b)
    if np.linalg.norm(xb - xa) < 1e-3:
        return
    g = np.zeros(6)
    H = np.zeros((6, 6))
    E, eps = stretch_element(tuple(xa), tuple(xb), lbar, EA, g, H, True)
    assert E >= 0.0
    assert E == pytest.approx(0.5 * EA * lbar * eps**2, rel=1e-12)
    f = g.reshape(2, 3)
    scale = max(1.0, np.abs(g).max())
    assert np.abs(f.sum(0)).max() <= 1e-9 * scale                       # no net force
    assert np.abs(np.cross(xa, f[0]) + np.cross(xb, f[1])).max() <= 1e-9 * scale * 3  # no net moment
    np.testing.assert_allclose(H, H.T, atol=1e-9 * max(1.0, np.abs(H).max()))
    R = _rotation(np.random.default_rng(s))
    g2 = np.zeros(6)
    E2, _ = stretch_element(tuple(R @ xa + 0.3), tuple(R @ xb + 0.3), lbar, EA, g2, np.zeros((6, 6)), False)
    assert E2 == pytest.approx(E, rel=1e-9, abs=1e-12 * EA)
    np.testing.assert_allclose(g2.reshape(2, 3), f @ R.T, atol=1e-8 * scale)


# ------------------------------------------------------------------------------------------------ bend/twist
@SETTINGS
@given(s=seed, the=angle, thf=angle, beta=st.floats(-1.0, 1.0))
def test_bend_twist_energy_zero_at_natural_state_and_positive_elsewhere(s, the, thf, beta):
    rng = np.random.default_rng(s)
    x = _polyline(rng)
    d1, t = _frames(x)
    d2 = np.cross(t, d1)
    m1 = np.cos([the, thf])[:, None] * d1 + np.sin([the, thf])[:, None] * d2
    m2 = -np.sin([the, thf])[:, None] * d1 + np.cos([the, thf])[:, None] * d2
    k1, k2 = material_curvatures(tuple(x[0]), tuple(x[1]), tuple(x[2]), tuple(m1[0]), tuple(m2[0]), tuple(m1[1]),
                                 tuple(m2[1]))
    tau = thf - the + beta
    eb, et, g, _ = _bend(x, d1, t, the, thf, beta, k1, k2, tau)
    assert abs(eb) < 1e-20 and abs(et) < 1e-20
    assert np.abs(g).max() < 1e-10
    kb1, kb2, tb = rng.normal(size=3) * 0.5
    eb, et, g, _ = _bend(x, d1, t, the, thf, beta, kb1, kb2, tb)
    assert eb >= 0.0 and et >= 0.0


@SETTINGS
@given(s=seed, the=angle, thf=angle)
def test_bend_twist_forces_have_no_net_force_and_hessian_is_symmetric(s, the, thf):
    rng = np.random.default_rng(s)
    x = _polyline(rng)
    d1, t = _frames(x)
    kb1, kb2, tb = rng.normal(size=3) * 0.5
    _, _, g, H = _bend(x, d1, t, the, thf, 0.0, kb1, kb2, tb)
    fx = g[[0, 1, 2]] + g[[4, 5, 6]] + g[[8, 9, 10]]
    scale = max(1.0, np.abs(g).max())
    assert np.abs(fx).max() <= 1e-9 * scale
    np.testing.assert_allclose(H, H.T, atol=1e-8 * max(1.0, np.abs(H).max()))


@SETTINGS
@given(s=seed, the=angle, thf=angle)
def test_bend_twist_energy_invariant_under_rigid_motion(s, the, thf):
    rng = np.random.default_rng(s)
    x = _polyline(rng)
    d1, t = _frames(x)
    kb1, kb2, tb = rng.normal(size=3) * 0.5
    eb, et, g, _ = _bend(x, d1, t, the, thf, 0.2, kb1, kb2, tb, hess=False)
    R = _rotation(rng)
    shift = rng.normal(size=3)
    eb2, et2, g2, _ = _bend(x @ R.T + shift, d1 @ R.T, t @ R.T, the, thf, 0.2, kb1, kb2, tb, hess=False)
    assert eb2 == pytest.approx(eb, rel=1e-8, abs=1e-14)
    assert et2 == pytest.approx(et, rel=1e-8, abs=1e-14)
    pos = [0, 1, 2, 4, 5, 6, 8, 9, 10]
    np.testing.assert_allclose(g2[pos].reshape(3, 3), g[pos].reshape(3, 3) @ R.T,
                               atol=1e-7 * max(1.0, np.abs(g).max()))
    np.testing.assert_allclose(g2[[3, 7]], g[[3, 7]], atol=1e-7 * max(1.0, np.abs(g).max()))


@SETTINGS
@given(s=seed)
def test_bend_hessian_action_matches_gradient_change_on_theta(s):
    # θ enters only through the material frame (no frame transport), so the Hessian is exact in θ:
    # a central difference of the gradient along θ must match H[:, θ] to O(h²)
    rng = np.random.default_rng(s)
    x = _polyline(rng, max_turn=1.5)
    d1, t = _frames(x)
    the, thf = rng.uniform(-1, 1, size=2)
    kb1, kb2, tb = rng.normal(size=3) * 0.3
    _, _, g, H = _bend(x, d1, t, the, thf, 0.0, kb1, kb2, tb)
    h = 1e-6
    for k, (a, b) in ((3, (the + h, thf)), (7, (the, thf + h))):
        _, _, gp, _ = _bend(x, d1, t, a, b, 0.0, kb1, kb2, tb, hess=False)
        a2, b2 = (the - h, thf) if k == 3 else (the, thf - h)
        _, _, gm, _ = _bend(x, d1, t, a2, b2, 0.0, kb1, kb2, tb, hess=False)
        np.testing.assert_allclose((gp - gm) / (2 * h), H[:, k], atol=1e-5 * max(1.0, np.abs(H).max()))


# ------------------------------------------------------------------------------------------------ 2-D vs 3-D
@SETTINGS
@given(s=seed, kbar=st.floats(-1.0, 1.0))
def test_planar_kernel_matches_3d_kernel_on_planar_configurations(s, kbar):
    rng = np.random.default_rng(s)
    # a planar 3-node polyline in x-z, first edge roughly along +z (the RL arm) or +-x
    base = rng.choice([0.0, math.pi / 2, -math.pi / 2])  # angle of the first edge from +z toward +x
    a0 = base + rng.uniform(-0.4, 0.4)
    a1 = a0 + rng.uniform(-1.5, 1.5)
    l0, l1 = rng.uniform(0.03, 0.1, size=2)
    x = np.zeros((3, 3))
    x[1] = x[0] + l0 * np.array([math.sin(a0), 0.0, math.cos(a0)])
    x[2] = x[1] + l1 * np.array([math.sin(a1), 0.0, math.cos(a1)])
    d1, t = _frames(x)
    d2 = np.cross(t, d1)
    k1, k2 = material_curvatures(tuple(x[0]), tuple(x[1]), tuple(x[2]), tuple(d1[0]), tuple(d2[0]), tuple(d1[1]),
                                 tuple(d2[1]))
    g2 = np.zeros(6)
    H2 = np.zeros((6, 6))
    xz = x[:, [0, 2]]
    e2d, kap = planar_bend_element(tuple(xz[0]), tuple(xz[1]), tuple(xz[2]), kbar, 2.0, 0.1, g2, H2, True)
    # exactly one 3-D component is in-plane and equals +-κ_2D
    comps = np.array([k1, k2])
    c = int(np.argmax(np.abs(comps)))
    assert abs(comps[1 - c]) <= 1e-9 * max(1.0, abs(kap))
    assert abs(abs(comps[c]) - abs(kap)) <= 1e-9 * max(1.0, abs(kap))
    sign = 1.0 if abs(kap) < 1e-12 else float(np.sign(comps[c]) * np.sign(kap))
    kb = [0.0, 0.0]
    kb[c] = sign * kbar
    eb, et, g3, _ = _bend(x, d1, t, 0.0, 0.0, 0.0, kb[0], kb[1], 0.0, EI1=2.0, EI2=2.0)
    assert eb == pytest.approx(e2d, rel=1e-9, abs=1e-14)
    np.testing.assert_allclose(g3[[0, 2, 4, 6, 8, 10]], g2, atol=1e-8 * max(1.0, np.abs(g2).max()))
    assert np.abs(g3[[1, 5, 9]]).max() <= 1e-9 * max(1.0, np.abs(g2).max())  # no out-of-plane force
