"""Stretching energy of one edge (docs/physics.md §2.1), exact gradient and Hessian, 3-D and 2-D.

E_s = ½ EA l̄ ε², ε = |e|/l̄ − 1, e = x_b − x_a. Local DOF order: [x_a, x_b] (6 in 3-D, 4 in 2-D).
Units: positions [m], EA [N], energy [J], gradient [N], Hessian [N/m].
"""
from __future__ import annotations

import math

from numba import njit

__all__ = ["stretch_element", "stretch_element_2d"]


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"})
def stretch_element(xa, xb, lbar, EA, g, H, with_hess):
    """3-D edge (xa, xb: 3-tuples). Writes g (6,) and, if with_hess, H (6, 6). Returns (energy, strain)."""
    e0 = xb[0] - xa[0]
    e1 = xb[1] - xa[1]
    e2 = xb[2] - xa[2]
    le = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    eps = le / lbar - 1.0
    t = (e0 / le, e1 / le, e2 / le)
    fs = EA * eps
    for a in range(3):
        g[a] = -fs * t[a]
        g[3 + a] = fs * t[a]
    if with_hess:
        c0 = EA * (1.0 / lbar - 1.0 / le)
        c1 = EA / le
        for a in range(3):
            for b in range(3):
                k = c1 * t[a] * t[b]
                if a == b:
                    k += c0
                H[a, b] = k
                H[3 + a, 3 + b] = k
                H[a, 3 + b] = -k
                H[3 + a, b] = -k
    return 0.5 * EA * lbar * eps * eps, eps


@njit(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"})
def stretch_element_2d(xa, xb, lbar, EA, g, H, with_hess):
    """2-D edge (xa, xb: 2-tuples (x, z)). Writes g (4,) and, if with_hess, H (4, 4). Returns (energy, strain)."""
    e0 = xb[0] - xa[0]
    e1 = xb[1] - xa[1]
    le = math.sqrt(e0 * e0 + e1 * e1)
    eps = le / lbar - 1.0
    t = (e0 / le, e1 / le)
    fs = EA * eps
    for a in range(2):
        g[a] = -fs * t[a]
        g[2 + a] = fs * t[a]
    if with_hess:
        c0 = EA * (1.0 / lbar - 1.0 / le)
        c1 = EA / le
        for a in range(2):
            for b in range(2):
                k = c1 * t[a] * t[b]
                if a == b:
                    k += c0
                H[a, b] = k
                H[2 + a, 2 + b] = k
                H[a, 2 + b] = -k
                H[2 + a, b] = -k
    return 0.5 * EA * lbar * eps * eps, eps
