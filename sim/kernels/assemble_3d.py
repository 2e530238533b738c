"""3-D rod elements of the step (4N unknowns [x, y, z, θ] per node): residual and banded Jacobian, energies.

Called by the shared Newton loop in :mod:`sim.kernels.newton`; ``w`` is the thread's
:class:`sim.kernels.workspace.Workspace`, ``rod`` the :class:`sim.kernels.data.RodData`, ``prm`` the
:class:`sim.kernels.data.Params` record.
"""
from __future__ import annotations

import math

from numba import njit

from sim.contact import stages as contact
from sim.energies.bend_twist import bend_twist_core, material_curvatures, material_directors
from sim.energies.stretch import stretch_element
from sim.geometry.frames import update_frames
from sim.kernels.data import KL_3D
from sim.kernels.drag import add_drag
from sim.numba_options import OPT

__all__ = ["assemble_3d", "energies_3d"]


@njit(**OPT)
def assemble_3d(e, x, h, kb, tb, rod, prm, cs, w, with_jac, sym):
    """Residual w.f (n,) of the implicit (sub)step of size h from the sub-step start (w.sub_x, w.sub_v, frames
    w.sub_d1/sub_t/sub_beta) at iterate x and, if with_jac, its banded Jacobian w.ab (n + 10, 21); with ``sym``
    (no friction: the Jacobian is symmetric) only the upper half (for band_ldl_solve; the lower half is left
    unspecified). Frames at x by time-parallel transport into w.t/d1/d2/beta. Returns (‖f‖ over free DOFs,
    Es, Eb, Et, Ec) [N or N m; J]."""
    x0, u, f, ab, pos = w.sub_x, w.sub_v, w.f, w.ab, w.pos
    t, d1, d2, beta = w.t, w.d1, w.d2, w.beta
    g6, H6, g11, H11, mf = w.g6, w.H6, w.g11, w.H11, w.mf
    rest_len, vor_len, mass, fixed = rod.rest_len, rod.vor_len, rod.mass, rod.fixed
    grav = rod.grav[min(e, rod.grav.shape[0] - 1)]  # external forces of env e (RodData)
    n = x.shape[0]
    N = n // 4
    kl = KL_3D
    damp = rod.damping[0]  # env e's record (sim.kernels.data.env_rod)
    ih = 1.0 / h
    ih2 = ih * ih
    for k in range(N):
        for a in range(3):
            pos[k, a] = x[4 * k + a]
    update_frames(pos, w.sub_d1, w.sub_t, w.sub_beta, t, d1, d2, w.elen, beta, rod.link)
    if with_jac:
        if sym:
            ab[:, kl:] = 0.0  # the LDLᵀ path never reads the lower half
        else:
            ab[:, :] = 0.0
        for k in range(n, n + kl):
            ab[k, kl] = 1.0
    for k in range(n):  # inertia, damping (positions only), gravity
        m = mass[k]
        dxk = x[k] - x0[k]
        fk = m * ih2 * (dxk - h * u[k]) - grav[k]
        jk = m * ih2
        if (k & 3) != 3:
            fk += damp * m * dxk * ih
            jk += damp * m * ih
        f[k] = fk
        if with_jac:
            ab[k, kl] = jk
    if prm.drag_on:  # viscous drag per unit length (docs/physics.md §3.1)
        add_drag(False, x, x0, h, rest_len, rod.link, prm, f, ab, kl, with_jac, sym)
    link = rod.link
    es = 0.0
    for j in range(N - 1):  # stretching (not across a joint edge between two rods)
        if link[j] == 0:
            continue
        o0 = 4 * j
        o1 = 4 * j + 4
        ej, _ = stretch_element((x[o0], x[o0 + 1], x[o0 + 2]), (x[o1], x[o1 + 1], x[o1 + 2]), rest_len[j], rod.EA[j],
                                g6, H6, with_jac)
        es += ej
        for a in range(3):
            f[o0 + a] += g6[a]
            f[o1 + a] += g6[3 + a]
        if with_jac:
            for a in range(6):  # local -> global index is increasing: upper half <=> b >= a
                r = o0 + a if a < 3 else o1 + a - 3
                for b in range(a if sym else 0, 6):
                    c = o0 + b if b < 3 else o1 + b - 3
                    ab[r, kl + c - r] += H6[a, b]
    eb = 0.0
    et = 0.0
    for j in range(N - 1):  # material directors once per edge (each enters two bend/twist elements)
        m1, m2 = material_directors((d1[j, 0], d1[j, 1], d1[j, 2]), (d2[j, 0], d2[j, 1], d2[j, 2]), x[4 * j + 3])
        for a in range(3):
            mf[j, a] = m1[a]
            mf[j, 3 + a] = m2[a]
    for i in range(1, N - 1):  # bending and twisting at the interior nodes (of each rod)
        if link[i - 1] == 0 or link[i] == 0:
            continue
        o = 4 * (i - 1)
        ebi, eti = bend_twist_core(
            (x[o], x[o + 1], x[o + 2]), (x[o + 4], x[o + 5], x[o + 6]), (x[o + 8], x[o + 9], x[o + 10]),
            (mf[i - 1, 0], mf[i - 1, 1], mf[i - 1, 2]), (mf[i - 1, 3], mf[i - 1, 4], mf[i - 1, 5]),
            (mf[i, 0], mf[i, 1], mf[i, 2]), (mf[i, 3], mf[i, 4], mf[i, 5]),
            x[o + 7] - x[o + 3] + beta[i], kb[i, 0], kb[i, 1], tb[i], rod.EI1[i], rod.EI2[i], rod.GJ[i], vor_len[i],
            g11, H11, w.wk, with_jac, sym)
        eb += ebi
        et += eti
        for a in range(11):
            f[o + a] += g11[a]
        if with_jac:
            for a in range(11):
                r = o + a
                for b in range(a if sym else 0, 11):
                    ab[r, kl + b - a] += H11[a, b]
    ec = 0.0
    pos0 = w.pos0
    if contact.present(prm):  # IMC contact and friction (docs/physics.md §4); pos0: the sub-step start's nodes
        for k in range(N):
            for a in range(3):
                pos0[k, a] = x0[4 * k + a]
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
    return math.sqrt(r2), es, eb, et, ec


@njit(**OPT)
def energies_3d(xs, d1s, ts, bs, kb, tb, rod, prm, w):
    """(E_stretch, E_bend, E_twist) [J] of a state whose stored frames (d1s, ts, bs) are at xs (w.mf: scratch for
    the material directors)."""
    rest_len, vor_len, mf, link = rod.rest_len, rod.vor_len, w.mf, rod.link
    N = xs.shape[0] // 4
    es = 0.0
    for j in range(N - 1):
        o = 4 * j
        if link[j] != 0:
            ex = xs[o + 4] - xs[o]
            ey = xs[o + 5] - xs[o + 1]
            ez = xs[o + 6] - xs[o + 2]
            eps = math.sqrt(ex * ex + ey * ey + ez * ez) / rest_len[j] - 1.0
            es += 0.5 * rod.EA[j] * rest_len[j] * eps * eps
        a0, a1, a2 = d1s[j, 0], d1s[j, 1], d1s[j, 2]
        t0, t1, t2 = ts[j, 0], ts[j, 1], ts[j, 2]
        m1, m2 = material_directors((a0, a1, a2), (t1 * a2 - t2 * a1, t2 * a0 - t0 * a2, t0 * a1 - t1 * a0), xs[o + 3])
        for a in range(3):
            mf[j, a] = m1[a]
            mf[j, 3 + a] = m2[a]
    eb = 0.0
    et = 0.0
    for i in range(1, N - 1):
        if link[i - 1] == 0 or link[i] == 0:
            continue
        o = 4 * (i - 1)
        k1, k2 = material_curvatures((xs[o], xs[o + 1], xs[o + 2]), (xs[o + 4], xs[o + 5], xs[o + 6]),
                                     (xs[o + 8], xs[o + 9], xs[o + 10]), (mf[i - 1, 0], mf[i - 1, 1], mf[i - 1, 2]),
                                     (mf[i - 1, 3], mf[i - 1, 4], mf[i - 1, 5]), (mf[i, 0], mf[i, 1], mf[i, 2]),
                                     (mf[i, 3], mf[i, 4], mf[i, 5]))
        lv = vor_len[i]
        eb += 0.5 / lv * (rod.EI1[i] * (k1 - kb[i, 0]) ** 2 + rod.EI2[i] * (k2 - kb[i, 1]) ** 2)
        tw = xs[o + 7] - xs[o + 3] + bs[i] - tb[i]
        et += 0.5 * rod.GJ[i] / lv * tw * tw
    return es, eb, et
