"""Planar (x–z) rod elements of the step (2N unknowns [x, z] per node): residual and banded Jacobian, energies,
and the 3-D frames of a planar state.

Called by the shared Newton loop in :mod:`sim.kernels.newton` and the ladder in :mod:`sim.kernels.ladder` (same
arguments as :mod:`sim.kernels.assemble_3d`).
"""
from __future__ import annotations

import math

from numba import njit

from sim.contact import stages as contact
from sim.energies.planar import planar_bend_element
from sim.energies.stretch import stretch_element_2d
from sim.geometry.frames import update_frames
from sim.kernels.data import KL_2D
from sim.kernels.drag import add_drag
from sim.kernels.workspace import copy_into
from sim.numba_options import OPT

__all__ = ["assemble_2d", "energies_2d", "frames_from_2d"]


@njit(**OPT)
def assemble_2d(e, x, h, kb, tb, rod, prm, cs, w, with_jac, sym):
    """2-D residual w.f and banded Jacobian w.ab (n + 5, 11) (see :func:`sim.kernels.assemble_3d.assemble_3d`; ``tb`` is
    unused). Returns (‖f‖, Es, Eb, 0, Ec)."""
    x0, u, f, ab = w.sub_x, w.sub_v, w.f, w.ab
    g4, H4, g6, H6 = w.g4, w.H4, w.g6, w.H6
    rest_len, vor_len, mass, fixed = rod.rest_len, rod.vor_len, rod.mass, rod.fixed
    grav = rod.grav[min(e, rod.grav.shape[0] - 1)]  # external forces of env e (RodData)
    n = x.shape[0]
    N = n // 2
    kl = KL_2D
    sgn = prm.planar_sign
    damp = rod.damping[0]  # env e's record (sim.kernels.data.env_rod)
    ih = 1.0 / h
    ih2 = ih * ih
    if with_jac:
        if sym:
            ab[:, kl:] = 0.0  # the LDLᵀ path never reads the lower half
        else:
            ab[:, :] = 0.0
        for k in range(n, n + kl):
            ab[k, kl] = 1.0
    for k in range(n):  # inertia, damping, gravity
        m = mass[k]
        dxk = x[k] - x0[k]
        f[k] = m * ih2 * (dxk - h * u[k]) - grav[k] + damp * m * dxk * ih
        if with_jac:
            ab[k, kl] = m * ih2 + damp * m * ih
    if prm.drag_on:  # viscous drag per unit length (docs/physics.md §3.1)
        add_drag(True, x, x0, h, rest_len, rod.link, prm, f, ab, kl, with_jac, sym)
    link = rod.link
    es = 0.0
    for j in range(N - 1):  # stretching (not across a joint edge between two rods)
        if link[j] == 0:
            continue
        o = 2 * j
        ej, _ = stretch_element_2d((x[o], x[o + 1]), (x[o + 2], x[o + 3]), rest_len[j], rod.EA[j], g4, H4, with_jac)
        es += ej
        for a in range(4):
            f[o + a] += g4[a]
        if with_jac:
            for a in range(4):
                for b in range(a if sym else 0, 4):
                    ab[o + a, kl + b - a] += H4[a, b]
    eb = 0.0
    for i in range(1, N - 1):  # bending at the interior nodes (of each rod)
        if link[i - 1] == 0 or link[i] == 0:
            continue
        o = 2 * (i - 1)
        ebi, _ = planar_bend_element((x[o], x[o + 1]), (x[o + 2], x[o + 3]), (x[o + 4], x[o + 5]),
                                     sgn * kb[i, 0], rod.EI1[i], vor_len[i], g6, H6, with_jac)
        eb += ebi
        for a in range(6):
            f[o + a] += g6[a]
        if with_jac:
            for a in range(6):
                for b in range(a if sym else 0, 6):
                    ab[o + a, kl + b - a] += H6[a, b]
    ec = 0.0
    pos, pos0 = w.pos, w.pos0
    if contact.present(prm):  # IMC contact and friction (docs/physics.md §4), on the nodes in the plane y = plane_y
        py = prm.plane_y
        for k in range(N):
            pos[k, 0] = x[2 * k]
            pos[k, 1] = py
            pos[k, 2] = x[2 * k + 1]
            pos0[k, 0] = x0[2 * k]
            pos0[k, 1] = py
            pos0[k, 2] = x0[2 * k + 1]
        ec = contact.accumulate(e, prm, rod, cs, w, h, with_jac, sym)
    r2 = 0.0
    for k in range(n):  # constrained DOFs: identity rows and columns, zero residual
        if fixed[k]:
            f[k] = 0.0
            if with_jac:
                for c in range(max(0, k - kl), min(n, k + kl + 1)):
                    ab[k, kl + c - k] = 0.0
                    ab[c, kl + k - c] = 0.0
                ab[k, kl] = 1.0
        else:
            r2 += f[k] * f[k]
    return math.sqrt(r2), es, eb, 0.0, ec


@njit(**OPT)
def energies_2d(xs, kb, rod, prm, w):
    """(E_stretch, E_bend, 0) [J] of a planar state."""
    rest_len, vor_len, link = rod.rest_len, rod.vor_len, rod.link
    N = xs.shape[0] // 2
    es = 0.0
    for j in range(N - 1):
        if link[j] == 0:
            continue
        o = 2 * j
        ej, _ = stretch_element_2d((xs[o], xs[o + 1]), (xs[o + 2], xs[o + 3]), rest_len[j], rod.EA[j], w.g4, w.H4,
                                   False)
        es += ej
    eb = 0.0
    for i in range(1, N - 1):
        if link[i - 1] == 0 or link[i] == 0:
            continue
        o = 2 * (i - 1)
        ebi, _ = planar_bend_element((xs[o], xs[o + 1]), (xs[o + 2], xs[o + 3]), (xs[o + 4], xs[o + 5]),
                                     prm.planar_sign * kb[i, 0], rod.EI1[i], vor_len[i], w.g6, w.H6, False)
        eb += ebi
    return es, eb, 0.0


@njit(**OPT)
def frames_from_2d(xs, py, d1s, ts, bs, w, link):
    """Update the stored 3-D frames (d1s, ts, bs) of a planar state to its DOFs xs (time-parallel transport;
    ``link``: RodData.link)."""
    pos = w.pos
    N = xs.shape[0] // 2
    for k in range(N):
        pos[k, 0] = xs[2 * k]
        pos[k, 1] = py
        pos[k, 2] = xs[2 * k + 1]
    update_frames(pos, d1s, ts, bs, w.t, w.d1, w.d2, w.elen, w.beta, link)
    copy_into(d1s, w.d1)
    copy_into(ts, w.t)
    copy_into(bs, w.beta)
