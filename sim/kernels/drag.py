"""Viscous drag per unit length (resistive-force theory; docs/physics.md §3.1): residual and Jacobian of the
step, the same function for the 2-D and the 3-D model.

Node ``i`` carries the drag of its share of the rod, ``l_i`` = half of each material edge that meets it (rest
lengths; a joint edge between two rods carries none):

    F_i = −l_i C_i (v_i − U),   C_i = c_t t̂_i t̂_iᵀ + c_n (I − t̂_i t̂_iᵀ),   v_i = (x_i − x0_i)/h

with ``U`` the uniform flow velocity, ``c_n``/``c_t`` [N s/m²] the normal and tangential coefficients, and
``t̂_i`` the node's unit tangent at the (sub)step start (the normalised sum of the unit tangents of its material
edges): lagged, so the Jacobian ``l_i C_i / h`` is symmetric positive semi-definite and keeps the LDLᵀ path, and
without a flow the drag only dissipates (``v·C v ≥ 0``).
"""
from __future__ import annotations

import math

from numba import njit

from sim.numba_options import OPT

__all__ = ["add_drag"]


@njit(inline="always", **OPT)
def _node(x, planar, k):
    """Position (3,) of node k in the DOF vector x (2-D: [x, z] per node, y = 0)."""
    if planar:
        return x[2 * k], 0.0, x[2 * k + 1]
    return x[4 * k], x[4 * k + 1], x[4 * k + 2]


@njit(inline="always", **OPT)
def _unit_edge(x, planar, j):
    """Unit tangent (3,) of edge j of x; (0, 0, 0) for an edge of zero length."""
    a = _node(x, planar, j)
    b = _node(x, planar, j + 1)
    ex, ey, ez = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    n = math.sqrt(ex * ex + ey * ey + ez * ez)
    if n == 0.0:
        return 0.0, 0.0, 0.0
    return ex / n, ey / n, ez / n


@njit(**OPT)
def add_drag(planar, x, x0, h, rest_len, link, prm, f, ab, kl, with_jac, sym):
    """Add the drag residual ``l_i C_i ((x_i − x0_i)/h − U)`` into ``f`` and (``with_jac``) ``l_i C_i / h`` into the
    band ``ab`` (upper half only with ``sym``) for every node; ``x``/``x0`` the iterate and the (sub)step start
    (DOF vectors), ``rest_len``/``link`` the RodData arrays, ``prm`` the Params record (drag_normal,
    drag_tangential, flow_x/y/z)."""
    cn = prm.drag_normal
    ct = prm.drag_tangential
    flow = (prm.flow_x, prm.flow_y, prm.flow_z)
    dpn = 2 if planar else 4
    N = rest_len.shape[0] + 1
    ih = 1.0 / h
    for i in range(N):
        li = 0.0
        t0, t1, t2 = 0.0, 0.0, 0.0
        if i > 0 and link[i - 1] != 0:
            li += 0.5 * rest_len[i - 1]
            a = _unit_edge(x0, planar, i - 1)
            t0, t1, t2 = t0 + a[0], t1 + a[1], t2 + a[2]
        if i < N - 1 and link[i] != 0:
            li += 0.5 * rest_len[i]
            a = _unit_edge(x0, planar, i)
            t0, t1, t2 = t0 + a[0], t1 + a[1], t2 + a[2]
        if li == 0.0:
            continue
        tn = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        if tn > 0.0:
            t0, t1, t2 = t0 / tn, t1 / tn, t2 / tn
        t = (t0, t1, t2)
        p = _node(x, planar, i)
        q = _node(x0, planar, i)
        rv = ((p[0] - q[0]) * ih - flow[0], (p[1] - q[1]) * ih - flow[1], (p[2] - q[2]) * ih - flow[2])
        tv = t0 * rv[0] + t1 * rv[1] + t2 * rv[2]
        # C rv = c_n rv + (c_t − c_n) t (t·rv)
        nc = 2 if planar else 3  # the node's position DOFs: 2-D [x, z], 3-D [x, y, z]
        for ia in range(nc):
            a = 2 * ia if planar else ia
            ra = dpn * i + ia
            f[ra] += li * (cn * rv[a] + (ct - cn) * t[a] * tv)
            if with_jac:
                for ib in range(ia if sym else 0, nc):
                    b = 2 * ib if planar else ib
                    cab = (ct - cn) * t[a] * t[b] + (cn if a == b else 0.0)
                    ab[ra, kl + ib - ia] += li * cab * ih
