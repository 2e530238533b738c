"""3-D rod: assembly, Newton, sub-step retry and the batched step kernel (see :mod:`sim.solve`)."""
# ruff: noqa: F405
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .banded import band_ldl_solve, band_lu_solve
from .contact_kernels import (
    contact_accumulate,
    contact_broadphase,
    contact_min_gap,
    contact_refresh,
    contact_report,
    contact_step_limit,
)
from .energies.bend_twist import bend_twist_core, material_curvatures, material_directors
from .energies.stretch import stretch_element
from .frames import update_frames
from .solve_params import *  # noqa: F403  (F_*/I_* output columns)
from .solve_params import (
    _CHUNK,
    _OPT,
    guard_score,
    jacobian_symmetric,
    lazy_line_search,
    midpoint_gained_energy,
    newton_dtol,
)

__all__ = ["step_kernel_3d"]

# ----------------------------------------------------------------------------------------------- 3-D
@njit(**_OPT)
def _assemble_3d(e, x, x0, u, h, d1o, to, bo, kb, tb, rest_len, vor_len, mass, fixed, grav, prm, cd,
                 pos, pos0, t, d1, d2, elen, beta, f, ab, g6, H6, g11, H11, wk, cg, ch, mf, with_jac, sym):
    """Residual f (n,) and, if with_jac, banded Jacobian ab (n, 21) at x; with ``sym`` (no friction: the
    Jacobian is symmetric) only its upper half is assembled (for band_ldl_solve; the lower half is left
    unspecified). Returns (‖f‖, Es, Eb, Et, Ec)."""
    n = x.shape[0]
    N = n // 4
    kl = 10
    EA = prm.EA
    EI1 = prm.EI1
    EI2 = prm.EI2
    GJ = prm.GJ
    damp = prm.damping
    ih = 1.0 / h
    ih2 = ih * ih
    for k in range(N):
        for a in range(3):
            pos[k, a] = x[4 * k + a]
    update_frames(pos, d1o, to, bo, t, d1, d2, elen, beta)
    if with_jac:
        if sym:
            ab[:, kl:] = 0.0  # the LDLᵀ path never reads the lower half
        else:
            ab[:, :] = 0.0
        for k in range(n, n + kl):
            ab[k, kl] = 1.0
    for k in range(n):
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
    es = 0.0
    for j in range(N - 1):
        o0 = 4 * j
        o1 = 4 * j + 4
        ej, _ = stretch_element((x[o0], x[o0 + 1], x[o0 + 2]), (x[o1], x[o1 + 1], x[o1 + 2]), rest_len[j], EA,
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
    for i in range(1, N - 1):
        o = 4 * (i - 1)
        ebi, eti = bend_twist_core(
            (x[o], x[o + 1], x[o + 2]), (x[o + 4], x[o + 5], x[o + 6]), (x[o + 8], x[o + 9], x[o + 10]),
            (mf[i - 1, 0], mf[i - 1, 1], mf[i - 1, 2]), (mf[i - 1, 3], mf[i - 1, 4], mf[i - 1, 5]),
            (mf[i, 0], mf[i, 1], mf[i, 2]), (mf[i, 3], mf[i, 4], mf[i, 5]),
            x[o + 7] - x[o + 3] + beta[i], kb[i, 0], kb[i, 1], tb[i], EI1, EI2, GJ, vor_len[i],
            g11, H11, wk, with_jac, sym)
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
    if prm.n_obstacles > 0:
        for k in range(N):
            for a in range(3):
                pos0[k, a] = x0[4 * k + a]
        cg[:, :] = 0.0
        ch[:, :, :] = 0.0
        ec = contact_accumulate(e, cd, pos, pos0, h, prm.radius, prm.contact_k, prm.contact_delta, prm.friction,
                                prm.friction_nu, prm.friction_on > 0, cg, ch)
        for k in range(N):
            for a in range(3):
                f[4 * k + a] += cg[k, a]
        if with_jac:
            for j in range(N - 1):
                for a in range(6):
                    r = 4 * j + a if a < 3 else 4 * j + 1 + a
                    for b in range(a if sym else 0, 6):
                        c = 4 * j + b if b < 3 else 4 * j + 1 + b
                        ab[r, kl + c - r] += ch[j, a, b]
    r2 = 0.0
    for k in range(n):
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


@njit(**_OPT)
def _newton_3d(e, x0, u, hs, d1o, to, bo, kb, tb, rest_len, vor_len, mass, fixed, grav, prm, cd, w):
    """Newton iterations of one (sub)step of size hs from the guess x = x0 + 0.01·u·hs (into w's x).

    Returns (status, iterations, converged, ‖f‖ last, ‖f0‖); status 0 = ok (converged or unconverged at
    the iteration cap), 1 non-finite, 2 residual growth, 3 bad pivot."""
    (x, f, dx, xt, ab, pos, pos0, t, d1, d2, elen, beta, g6, H6, g11, H11, wk, cg, ch, mf) = w
    n = x0.shape[0]
    maxit = int(prm.newton_max_iter)
    tol = prm.newton_tol
    dtol = newton_dtol(prm, cd, e)
    sym = jacobian_symmetric(prm)
    for k in range(n):
        x[k] = x0[k] if fixed[k] else x0[k] + 0.01 * u[k] * hs
    r0 = 0.0
    r = 0.0
    conv = False
    it = 0
    rp = 0.0
    lazy = lazy_line_search(prm, cd, e)
    while it < maxit:
        r, _, _, _, _ = _assemble_3d(e, x, x0, u, hs, d1o, to, bo, kb, tb, rest_len, vor_len, mass, fixed, grav,
                                     prm, cd, pos, pos0, t, d1, d2, elen, beta, f, ab, g6, H6, g11, H11, wk,
                                     cg, ch, mf, True, sym)
        if lazy and it > 0 and not r <= rp:  # the last update raised ‖f‖: backtrack along it
            alpha = 1.0
            for trial in range(4):
                alpha *= 0.5
                for k in range(n):
                    x[k] += alpha * dx[k]  # x = x_prev - alpha dx
                rt, _, _, _, _ = _assemble_3d(e, x, x0, u, hs, d1o, to, bo, kb, tb, rest_len, vor_len, mass, fixed, grav,
                                             prm, cd, pos, pos0, t, d1, d2, elen, beta, f, ab, g6, H6, g11, H11, wk,
                                             cg, ch, mf, False, sym)
                if rt <= rp:
                    break
            r, _, _, _, _ = _assemble_3d(e, x, x0, u, hs, d1o, to, bo, kb, tb, rest_len, vor_len, mass, fixed, grav,
                                         prm, cd, pos, pos0, t, d1, d2, elen, beta, f, ab, g6, H6, g11, H11, wk,
                                         cg, ch, mf, True, sym)
        if not np.isfinite(r):
            return 1, it, False, r, r0
        if it == 0:
            r0 = r
        elif r > 1e6 * r0:
            return 2, it, False, r, r0
        if r <= tol * r0 and (it > 0 or r == 0.0):
            conv = True
            break
        rp = r
        for k in range(n):
            dx[k] = f[k]
        if (band_ldl_solve(ab, n, 10, dx) if sym else band_lu_solve(ab, n, 10, dx)) != 0:
            return 3, it, False, r, r0
        if prm.step_limit > 0 and prm.n_obstacles > 0 and cd.cand_count[e] > 0:  # no update may tunnel (pos = nodes at x)
            N = n // 4
            for k in range(N):
                for a in range(3):
                    cg[k, a] = -dx[4 * k + a]
            tcap = contact_step_limit(e, cd, pos, cg, prm.radius, prm.contact_delta)
            if tcap < 1.0:
                for k in range(n):
                    dx[k] *= tcap
        if prm.line_search == 1:
            alpha = 1.0
            for trial in range(5):
                for k in range(n):
                    xt[k] = x[k] - alpha * dx[k]
                rt, _, _, _, _ = _assemble_3d(e, xt, x0, u, hs, d1o, to, bo, kb, tb, rest_len, vor_len, mass,
                                              fixed, grav, prm, cd, pos, pos0, t, d1, d2, elen, beta, f, ab,
                                              g6, H6, g11, H11, wk, cg, ch, mf, False, sym)
                if (np.isfinite(rt) and rt <= r) or trial == 4:
                    break
                alpha *= 0.5
            for k in range(n):
                x[k] = xt[k]
        else:
            for k in range(n):
                x[k] -= dx[k]
        it += 1
        dmax = 0.0
        for k in range(n):
            if (k & 3) != 3 and not fixed[k]:
                dmax = max(dmax, abs(dx[k]))
        if not np.isfinite(dmax):
            return 1, it, False, r, r0
        if dmax / hs < dtol:
            conv = True
            break
    return 0, it, conv, r, r0


@njit(**_OPT)
def _substep_3d(e, x0, u, d1o, to, bo, h, kb, tb, rest_len, vor_len, mass, fixed, grav, prm, cd, w, want_pen0):
    """One implicit (sub)step of size h with the scene's integrator; a midpoint step that gains energy (see
    :func:`sim.solve_params.midpoint_gained_energy`) is redone by backward Euler. On success x0, u, d1o, to, bo
    hold the new values.

    Returns (status, iterations, converged, ‖f‖ last, ‖f0‖, max penetration [m] at the end of the sub-step,
    max penetration [m] at its start (only if want_pen0)) (penetrations 0 without obstacles or contact
    candidates); status 0 = ok."""
    st, it, conv, r, r0, pen, pen0 = _substep_with_3d(e, x0, u, d1o, to, bo, h, kb, tb, rest_len, vor_len, mass,
                                                      fixed, grav, prm, cd, w, want_pen0, prm.midpoint != 0)
    if st == 6:
        st, it2, conv, r, r0, pen, pen0 = _substep_with_3d(e, x0, u, d1o, to, bo, h, kb, tb, rest_len, vor_len,
                                                           mass, fixed, grav, prm, cd, w, want_pen0, False)
        it += it2
    return st, it, conv, r, r0, pen, pen0


@njit(**_OPT)
def _mech_energy_3d(e, xs, us, d1s, ts, bs, kb, tb, rest_len, vor_len, mass, fixed, grav, prm, cd, w, pos, pos0, h):
    """(E_total, E_total − E_gravity) [J] of a state whose frames (d1s, ts, bs) are at xs; contact energy over
    the current candidates (friction off), with ``pos`` the node positions of xs."""
    mf, cg, ch = w[19], w[17], w[18]
    es, eb, et = _energies_3d(xs, d1s, ts, bs, kb, tb, rest_len, vor_len, prm, mf)
    ek = 0.0
    eg = 0.0
    for k in range(xs.shape[0]):
        if not fixed[k]:
            ek += 0.5 * mass[k] * us[k] * us[k]
        eg -= grav[k] * xs[k]
    ec = 0.0
    if prm.n_obstacles > 0 and cd.cand_count[e] > 0:
        ec = contact_accumulate(e, cd, pos, pos0, h, prm.radius, prm.contact_k, prm.contact_delta, prm.friction,
                                prm.friction_nu, False, cg, ch)
    e_in = es + eb + et + ek + ec
    return e_in + eg, e_in


@njit(**_OPT)
def _substep_with_3d(e, x0, u, d1o, to, bo, h, kb, tb, rest_len, vor_len, mass, fixed, grav, prm, cd, w, want_pen0,
                     midpoint):
    """One (sub)step by implicit midpoint (``midpoint``) or backward Euler; status 6: a midpoint step gained
    energy (nothing committed)."""
    (x, f, dx, xt, ab, pos, pos0, t, d1, d2, elen, beta, g6, H6, g11, H11, wk, cg, ch, mf) = w
    n = x0.shape[0]
    N = n // 4
    hs = h if not midpoint else 0.5 * h
    pen0 = 0.0
    if prm.n_obstacles > 0:
        for k in range(N):
            for a in range(3):
                pos0[k, a] = x0[4 * k + a]
                pos[k, a] = x0[4 * k + a] + hs * u[4 * k + a]  # predicted end of step (contact: swept list)
        contact_broadphase(e, cd, pos0, pos, prm.contact_margin)
        if want_pen0 and cd.cand_count[e] > 0:
            pen0 = -contact_min_gap(e, cd, pos0, prm.radius)
    st, it, conv, r, r0 = _newton_3d(e, x0, u, hs, d1o, to, bo, kb, tb, rest_len, vor_len, mass, fixed, grav, prm, cd, w)
    if st != 0:
        return st, it, False, r, r0, 0.0, pen0
    list_covers_step = False
    if prm.n_obstacles > 0:
        # the solve can carry the rod onto pairs that the predicted-motion list missed (a control change moves
        # it far from x0 + h u): refresh the list over the motion actually taken; if it gained pairs, solve again
        for k in range(N):
            for a in range(3):
                pos[k, a] = x[4 * k + a]
        # backward Euler ends where the solve ended: then the refreshed list already covers the whole
        # sub-step motion and the end-of-sub-step broad phase below is not needed again
        list_covers_step = not midpoint
        if contact_refresh(e, cd, pos0, pos, prm.contact_margin):
            list_covers_step = False
            st, it2, conv, r, r0 = _newton_3d(e, x0, u, hs, d1o, to, bo, kb, tb, rest_len, vor_len, mass, fixed,
                                             grav, prm, cd, w)
            it += it2
            if st != 0:
                return st, it, False, r, r0, 0.0, pen0
    if not conv and prm.accept_unconverged == 0:
        return 4, it, False, r, r0, 0.0, pen0
    # velocity / position update (u_new into dx)
    if not midpoint:
        for k in range(n):
            dx[k] = (x[k] - x0[k]) / h
    else:
        for k in range(n):
            uh = (x[k] - x0[k]) / hs
            x[k] = 2.0 * x[k] - x0[k]
            dx[k] = 2.0 * uh - u[k]
            if fixed[k]:
                dx[k] = 0.0
    for k in range(N):
        for a in range(3):
            pos[k, a] = x[4 * k + a]
    update_frames(pos, d1o, to, bo, t, d1, d2, elen, beta)
    for j in range(N - 1):
        s = elen[j] / rest_len[j] - 1.0
        if not abs(s) <= prm.max_strain:
            return 5, it, conv, r, r0, 0.0, pen0
    for k in range(n):
        if not (np.isfinite(x[k]) and np.isfinite(dx[k])):
            return 1, it, conv, r, r0, 0.0, pen0
    if midpoint and prm.midpoint_energy_tol > 0:  # energy at the start (frames d1o, to, bo) and at the end (d1, t, beta)
        for k in range(N):
            for a in range(3):
                pos0[k, a] = x0[4 * k + a]
        e0, s0 = _mech_energy_3d(e, x0, u, d1o, to, bo, kb, tb, rest_len, vor_len, mass, fixed, grav, prm, cd, w,
                                 pos0, pos0, h)
        for k in range(N):
            for a in range(3):
                pos[k, a] = x[4 * k + a]
        e1, s1 = _mech_energy_3d(e, x, dx, d1, t, beta, kb, tb, rest_len, vor_len, mass, fixed, grav, prm, cd, w,
                                 pos, pos0, h)
        if midpoint_gained_energy(e0, s0, e1, s1, prm.midpoint_energy_tol):
            return 6, it, conv, r, r0, 0.0, pen0
    for j in range(N - 1):
        for a in range(3):
            d1o[j, a] = d1[j, a]
            to[j, a] = t[j, a]
    for i in range(N):
        if not np.isfinite(beta[i]):
            return 1, it, conv, r, r0, 0.0, pen0
        bo[i] = beta[i]
    for k in range(n):
        x0[k] = x[k]
        u[k] = dx[k]
    pen = 0.0
    if prm.n_obstacles > 0:  # pos: end-of-sub-step, pos0: start positions; list over the whole sub-step motion
        if not list_covers_step:
            contact_broadphase(e, cd, pos0, pos, prm.contact_margin)
        if cd.cand_count[e] > 0:
            pen = -contact_min_gap(e, cd, pos, prm.radius)
    return 0, it, conv, r, r0, pen, pen0


@njit(**_OPT)
def _alloc_env_3d(N):
    """Per-thread step workspace: the (sub)step start state and the penetration-guard fallback state."""
    n = 4 * N
    return (np.empty(n), np.empty(n), np.empty((N - 1, 3)), np.empty((N - 1, 3)), np.empty(N),
            np.empty(n), np.empty(n), np.empty((N - 1, 3)), np.empty((N - 1, 3)), np.empty(N))


@njit(**_OPT)
def _alloc_3d(N):
    n = 4 * N
    return (np.empty(n), np.empty(n), np.zeros(n + 10), np.empty(n), np.empty((n + 10, 21)), np.empty((N, 3)),
            np.empty((N, 3)), np.empty((N - 1, 3)), np.empty((N - 1, 3)), np.empty((N - 1, 3)), np.empty(N - 1),
            np.empty(N), np.empty(6), np.empty((6, 6)), np.empty(11), np.empty((11, 11)), np.empty((17, 11)),
            np.zeros((N, 3)), np.zeros((N - 1, 6, 6)), np.empty((N - 1, 6)))


@njit(**_OPT)
def _energies_3d(xs, d1s, ts, bs, kb, tb, rest_len, vor_len, prm, mf):
    """(E_stretch, E_bend, E_twist) [J] of a state whose stored frames (d1s, ts, bs) are at xs (mf: (N-1, 6)
    scratch for the material directors)."""
    N = xs.shape[0] // 4
    EA = prm.EA
    es = 0.0
    for j in range(N - 1):
        o = 4 * j
        ex = xs[o + 4] - xs[o]
        ey = xs[o + 5] - xs[o + 1]
        ez = xs[o + 6] - xs[o + 2]
        eps = math.sqrt(ex * ex + ey * ey + ez * ez) / rest_len[j] - 1.0
        es += 0.5 * EA * rest_len[j] * eps * eps
        a0, a1, a2 = d1s[j, 0], d1s[j, 1], d1s[j, 2]
        t0, t1, t2 = ts[j, 0], ts[j, 1], ts[j, 2]
        m1, m2 = material_directors((a0, a1, a2), (t1 * a2 - t2 * a1, t2 * a0 - t0 * a2, t0 * a1 - t1 * a0), xs[o + 3])
        for a in range(3):
            mf[j, a] = m1[a]
            mf[j, 3 + a] = m2[a]
    eb = 0.0
    et = 0.0
    for i in range(1, N - 1):
        o = 4 * (i - 1)
        k1, k2 = material_curvatures((xs[o], xs[o + 1], xs[o + 2]), (xs[o + 4], xs[o + 5], xs[o + 6]),
                                     (xs[o + 8], xs[o + 9], xs[o + 10]), (mf[i - 1, 0], mf[i - 1, 1], mf[i - 1, 2]),
                                     (mf[i - 1, 3], mf[i - 1, 4], mf[i - 1, 5]), (mf[i, 0], mf[i, 1], mf[i, 2]),
                                     (mf[i, 3], mf[i, 4], mf[i, 5]))
        lv = vor_len[i]
        eb += 0.5 / lv * (prm.EI1 * (k1 - kb[i, 0]) ** 2 + prm.EI2 * (k2 - kb[i, 1]) ** 2)
        tw = xs[o + 7] - xs[o + 3] + bs[i] - tb[i]
        et += 0.5 * prm.GJ / lv * tw * tw
    return es, eb, et


@njit(**_OPT)
def _env_step_3d(e, xs, us, d1s, ts, bs, kb, tb, rest_len, vor_len, mass, fixed, grav, prm, cd, crep, fo, io, w,
                 sw):
    """One env's step; w (_alloc_3d) and sw (_alloc_env_3d) are the calling thread's workspaces, every entry
    written before it is read, so a workspace carries nothing from one env to the next."""
    n = xs.shape[0]
    N = n // 4
    (x0, u, d1o, to, bo, fb_x, fb_u, fb_d1, fb_t, fb_b) = sw
    ok = False
    iters = 0
    conv_all = True
    r = 0.0
    r0 = 0.0
    ns = 1
    levels = int(prm.retry_levels)
    # guards: penetration (end configuration deeper than lim) and divergence (an accepted unconverged solve whose
    # residual grew by more than rg over its iterations); a level that trips one is retried with twice the
    # sub-steps, keeping the least-bad finite level result (score = max(pen/lim, growth/rg) > 1) as fallback
    fb_pen = np.inf
    rg = prm.divergence_guard
    fb_ns, fb_it, fb_conv, fb_r, fb_r0 = 1, 0, False, 0.0, 0.0
    lim = prm.max_penetration  # guard limit [m]: raised to (start penetration + limit/4) for a step starting deeper
    for level in range(levels):
        ns = 1 << level
        h = prm.dt / ns
        x0[:] = xs
        u[:] = us
        d1o[:, :] = d1s
        to[:, :] = ts
        bo[:] = bs
        ok = True
        iters = 0
        conv_all = True
        pen = 0.0
        grow = 0.0
        for s in range(ns):
            st, it, conv, r, r0s, pen_s, pen0 = _substep_3d(e, x0, u, d1o, to, bo, h, kb, tb, rest_len, vor_len,
                                                            mass, fixed, grav, prm, cd, w, level == 0 and s == 0)
            if s == 0:
                r0 = r0s
                if level == 0:
                    lim = max(prm.max_penetration, pen0 + 0.25 * prm.max_penetration)
            iters += it
            conv_all = conv_all and conv
            if st != 0:
                ok = False
                break
            pen = max(pen, pen_s)
            if not conv and r0s > 0.0:
                grow = max(grow, r / r0s)
        score = guard_score(pen, lim, grow, rg)
        if ok and score > 0.0 and level < levels - 1:
            if score < fb_pen:
                fb_pen = score
                fb_x[:] = x0
                fb_u[:] = u
                fb_d1[:, :] = d1o
                fb_t[:, :] = to
                fb_b[:] = bo
                fb_ns, fb_it, fb_conv, fb_r, fb_r0 = ns, iters, conv_all, r, r0
            ok = False
            continue
        if ok:
            break
    if not ok and fb_pen < np.inf:
        ok = True
        x0[:] = fb_x
        u[:] = fb_u
        d1o[:, :] = fb_d1
        to[:, :] = fb_t
        bo[:] = fb_b
        ns, iters, conv_all, r, r0 = fb_ns, fb_it, fb_conv, fb_r, fb_r0
    if ok:
        xs[:] = x0
        us[:] = u
        d1s[:, :] = d1o
        ts[:, :] = to
        bs[:] = bo
    # energies at the (new or restored) state; its stored frames are the frames at xs
    (x, f, dx, xt, ab, pos, pos0, t, d1, d2, elen, beta, g6, H6, g11, H11, wk, cg, ch, mf) = w
    es, eb, et = _energies_3d(xs, d1s, ts, bs, kb, tb, rest_len, vor_len, prm, mf)
    ec = 0.0
    if prm.n_obstacles > 0:
        for k in range(N):
            for a in range(3):
                pos[k, a] = xs[4 * k + a]
        # candidates of the state actually kept (a guard fallback or a restored state is not the configuration
        # the last sub-step's list was built for): energy and report see every pair near it
        contact_broadphase(e, cd, pos, pos, prm.contact_margin)
        cg[:, :] = 0.0
        ch[:, :, :] = 0.0
        ec = contact_accumulate(e, cd, pos, pos, prm.dt, prm.radius, prm.contact_k, prm.contact_delta, prm.friction,
                                prm.friction_nu, prm.friction_on > 0, cg, ch)
    ek = 0.0
    eg = 0.0
    for k in range(n):
        ek += 0.5 * mass[k] * us[k] * us[k] * (0.0 if fixed[k] else 1.0)
        eg -= grav[k] * xs[k]
    fo[F_RES] = r if np.isfinite(r) else np.inf
    fo[F_RES0] = r0 if np.isfinite(r0) else np.inf
    fo[F_ES] = es
    fo[F_EB] = eb
    fo[F_ET] = et
    fo[F_EC] = ec
    fo[F_EK] = ek
    fo[F_EG] = eg
    io[I_ITERS] = iters
    io[I_CONV] = 1 if (ok and conv_all) else 0
    io[I_SUB] = ns
    io[I_FAIL] = 0 if ok else 1
    if prm.n_obstacles > 0:
        for k in range(N):
            for a in range(3):
                pos[k, a] = xs[4 * k + a]
                pos0[k, a] = xs[4 * k + a] - prm.dt * us[4 * k + a]  # step start (friction velocity)
        contact_report(e, cd, pos, pos0, prm.dt, prm.radius, prm.contact_k, prm.contact_delta, prm.friction, prm.friction_nu,
                       prm.friction_on > 0, crep.count, crep.edge, crep.obstacle, crep.rod_point, crep.obstacle_point,
                       crep.normal, crep.normal_force, crep.friction_force, crep.gap, crep.max_penetration)
    return ok


@njit(parallel=True, **_OPT)
def step_kernel_3d(dof, vel, d1s, ts, bs, times, failed, kappa_bar, tau_bar, rest_len, vor_len, mass, fixed,
                   grav, prm_arr, cd, crep, fo, io):
    """Advance all non-failed envs by prm.dt. dof/vel (B, 4N) views of State.dof; outputs fo (B, F_COLS),
    io (B, I_COLS) and the contact rows crep (a ContactReport)."""
    B = dof.shape[0]
    N = dof.shape[1] // 4
    nch = (B + _CHUNK - 1) // _CHUNK
    for chunk in prange(nch):  # workspaces are allocated once per chunk of envs, not per env-step
        prm = prm_arr[0]  # the parameters record, by reference
        w = _alloc_3d(N)
        sw = _alloc_env_3d(N)
        for e in range(chunk * _CHUNK, min(B, chunk * _CHUNK + _CHUNK)):
            for c in range(F_COLS):
                fo[e, c] = 0.0
            for c in range(I_COLS):
                io[e, c] = 0
            if failed[e]:
                continue
            ok = _env_step_3d(e, dof[e], vel[e], d1s[e], ts[e], bs[e], kappa_bar[e], tau_bar[e], rest_len, vor_len,
                              mass, fixed, grav, prm, cd, crep, fo[e], io[e], w, sw)
            if ok:
                times[e] += prm.dt
            else:
                failed[e] = True
