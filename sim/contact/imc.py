"""What both contact implementations share (docs/physics.md §4): the IMC potential of a gap, smooth Coulomb
friction, and the rod's radius per edge and per node.

``radius`` arguments are the rod's edge radii [m] as the kernels take them (``RodData.edge_radius``): (1,) for a rod
of one radius or (N-1,) one per edge; an edge's capsule has its own radius, a node (plane contact) the larger of its
two edges'.
"""
from __future__ import annotations

import math

from numba import njit

from sim.geometry.vec3 import vdot
from sim.numba_options import OPT_CONTACT

__all__ = ["imc_energy", "coulomb_factor", "friction_tangent_entry", "friction_block", "row3", "edge_radius",
           "node_radius"]


@njit(**OPT_CONTACT)
def imc_energy(g, k, delta):
    """IMC squared-softplus energy of gap g [m]: returns (E [J], dE/dg [N], d2E/dg2 [N/m])."""
    K1 = 15.0 / delta
    s = -K1 * g
    L = max(s, 0.0) + math.log1p(math.exp(-abs(s)))
    if s >= 0.0:
        sig = 1.0 / (1.0 + math.exp(-s))
    else:
        ex = math.exp(s)
        sig = ex / (1.0 + ex)
    return k * L * L / (K1 * K1), -2.0 * k * L * sig / K1, 2.0 * k * (sig * sig + L * sig * (1.0 - sig))


@njit(inline="always", **OPT_CONTACT)
def coulomb_factor(vtn, nu):
    """Smooth Coulomb factor γ(|v_t|) and its derivative γ' (docs/physics.md §4.6): 1 and 0 when sliding
    (|v_t| > ν), else tanh(K2 |v_t| / 2) with K2 = 15/ν."""
    if vtn > nu:
        return 1.0, 0.0
    K2 = 15.0 / nu
    gam = 2.0 / (1.0 + math.exp(-K2 * vtn)) - 1.0
    return gam, 0.5 * K2 * (1.0 - gam * gam)


@njit(inline="always", **OPT_CONTACT)
def friction_tangent_entry(a1, dgam, gam, vtn, t, n, mu, d2E, i, j):
    """Entry (i, j) of smooth Coulomb friction's 3×3 Jacobian block before the nodal weights (docs/physics.md §4.6):
    a1 [γ' t tᵀ + γ/|v_t| (P − t tᵀ)] − μ E'' γ t nᵀ with a1 = μ λ / dt, P = I − n nᵀ (t, n unit 3-vectors)."""
    P = (1.0 if i == j else 0.0) - n[i] * n[j]
    return a1 * (dgam * t[i] * t[j] + gam / vtn * (P - t[i] * t[j])) - mu * d2E * gam * t[i] * n[j]


@njit(**OPT_CONTACT)
def friction_block(va, vb, s, n, lam, d2E, mu, nu, dt, fr, J):
    """Smooth Coulomb friction of one contact on edge nodes (a, b), weights (1-s, s).

    ``va``, ``vb`` node velocities [m/s] (obstacles are static), ``n`` unit normal (lagged), ``lam`` =
    -E'(g) >= 0 normal force [N], ``d2E`` = E''(g). Writes the residual ``fr`` (6,) (= minus the friction
    force on the nodes) and its Jacobian ``J`` (6, 6) w.r.t. the node positions (through the velocity
    (x - x_prev)/dt and through lam; n and s held fixed). Returns the total friction force on the rod
    as a tuple [N].
    """
    fr[:] = 0.0
    J[:, :] = 0.0
    w0 = 1.0 - s
    w1 = s
    vc = (w0 * va[0] + w1 * vb[0], w0 * va[1] + w1 * vb[1], w0 * va[2] + w1 * vb[2])
    vn = vdot(vc, n)
    vt = (vc[0] - vn * n[0], vc[1] - vn * n[1], vc[2] - vn * n[2])
    vtn = math.sqrt(vdot(vt, vt))
    if vtn <= 1e-15 or lam <= 0.0 or mu <= 0.0:
        return (0.0, 0.0, 0.0)
    t = (vt[0] / vtn, vt[1] / vtn, vt[2] / vtn)
    gam, dgam = coulomb_factor(vtn, nu)
    w = (w0, w1)
    c = mu * lam * gam
    for kk in range(2):
        for i in range(3):
            fr[3 * kk + i] = c * w[kk] * t[i]
    # (mu lam / dt) [dgam t t^T + gam/|vt| (P - t t^T)] w_k w_l  -  mu E'' gam w_k w_l t n^T
    a1 = mu * lam / dt
    for i in range(3):
        for j in range(3):
            blk = friction_tangent_entry(a1, dgam, gam, vtn, t, n, mu, d2E, i, j)
            for kk in range(2):
                for ll in range(2):
                    J[3 * kk + i, 3 * ll + j] = blk * w[kk] * w[ll]
    return (-c * t[0], -c * t[1], -c * t[2])


@njit(**OPT_CONTACT)
def row3(x, k):
    return (x[k, 0], x[k, 1], x[k, 2])


@njit(inline="always", **OPT_CONTACT)
def edge_radius(radius, j):
    """Radius [m] of edge j: ``radius`` is (1,) for a rod of one radius or (N-1,) per edge."""
    return radius[min(j, radius.shape[0] - 1)]


@njit(inline="always", **OPT_CONTACT)
def node_radius(radius, k):
    """Radius [m] at node k (plane contact): the larger of its edges' (``radius`` as in :func:`edge_radius`)."""
    m = radius.shape[0] - 1
    return max(radius[min(max(k - 1, 0), m)], radius[min(k, m)])
