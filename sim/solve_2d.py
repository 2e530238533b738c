"""Planar (x–z) rod, 2N unknowns: assembly, Newton, sub-step retry and the batched step kernel (see
:mod:`sim.solve`)."""
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
from .energies.planar import planar_bend_element
from .energies.stretch import stretch_element_2d
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

__all__ = ["step_kernel_2d"]

# ----------------------------------------------------------------------------------------------- 2-D
@njit(**_OPT)
def _assemble_2d(e, x, x0, u, h, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, pos, pos0, f, ab,
                 g4, H4, g6, H6, cg, ch, with_jac, sym):
    """2-D residual and banded Jacobian (half-bandwidth 5; with ``sym`` only its upper half, see _assemble_3d).
    Returns (‖f‖, Es, Eb, 0, Ec)."""
    n = x.shape[0]
    N = n // 2
    kl = 5
    EA = prm.EA
    EI = prm.EI1
    sgn = prm.planar_sign
    damp = prm.damping
    ih = 1.0 / h
    ih2 = ih * ih
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
        f[k] = m * ih2 * (dxk - h * u[k]) - grav[k] + damp * m * dxk * ih
        if with_jac:
            ab[k, kl] = m * ih2 + damp * m * ih
    es = 0.0
    for j in range(N - 1):
        o = 2 * j
        ej, _ = stretch_element_2d((x[o], x[o + 1]), (x[o + 2], x[o + 3]), rest_len[j], EA, g4, H4, with_jac)
        es += ej
        for a in range(4):
            f[o + a] += g4[a]
        if with_jac:
            for a in range(4):
                for b in range(a if sym else 0, 4):
                    ab[o + a, kl + b - a] += H4[a, b]
    eb = 0.0
    for i in range(1, N - 1):
        o = 2 * (i - 1)
        ebi, _ = planar_bend_element((x[o], x[o + 1]), (x[o + 2], x[o + 3]), (x[o + 4], x[o + 5]),
                                     sgn * kb[i, 0], EI, vor_len[i], g6, H6, with_jac)
        eb += ebi
        for a in range(6):
            f[o + a] += g6[a]
        if with_jac:
            for a in range(6):
                for b in range(a if sym else 0, 6):
                    ab[o + a, kl + b - a] += H6[a, b]
    ec = 0.0
    if prm.n_obstacles > 0:
        py = prm.plane_y
        for k in range(N):
            pos[k, 0] = x[2 * k]
            pos[k, 1] = py
            pos[k, 2] = x[2 * k + 1]
            pos0[k, 0] = x0[2 * k]
            pos0[k, 1] = py
            pos0[k, 2] = x0[2 * k + 1]
        cg[:, :] = 0.0
        ch[:, :, :] = 0.0
        ec = contact_accumulate(e, cd, pos, pos0, h, prm.radius, prm.contact_k, prm.contact_delta, prm.friction,
                                prm.friction_nu, prm.friction_on > 0, cg, ch)
        for k in range(N):
            f[2 * k] += cg[k, 0]
            f[2 * k + 1] += cg[k, 2]
        if with_jac:
            for j in range(N - 1):
                for a in range(4):
                    la = (a // 2) * 3 + (0 if a % 2 == 0 else 2)
                    r = 2 * j + a
                    for b in range(a if sym else 0, 4):
                        lb = (b // 2) * 3 + (0 if b % 2 == 0 else 2)
                        c = 2 * j + b
                        ab[r, kl + c - r] += ch[j, la, lb]
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
    return math.sqrt(r2), es, eb, 0.0, ec


@njit(**_OPT)
def _newton_2d(e, x0, u, hs, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, w):
    """2-D analogue of _newton_3d."""
    (x, f, dx, xt, ab, pos, pos0, g4, H4, g6, H6, cg, ch) = w
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
        r, _, _, _, _ = _assemble_2d(e, x, x0, u, hs, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, pos, pos0,
                                     f, ab, g4, H4, g6, H6, cg, ch, True, sym)
        if lazy and it > 0 and not r <= rp:  # the last update raised ‖f‖: backtrack along it
            alpha = 1.0
            for trial in range(4):
                alpha *= 0.5
                for k in range(n):
                    x[k] += alpha * dx[k]  # x = x_prev - alpha dx
                rt, _, _, _, _ = _assemble_2d(e, x, x0, u, hs, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, pos, pos0,
                                             f, ab, g4, H4, g6, H6, cg, ch, False, sym)
                if rt <= rp:
                    break
            r, _, _, _, _ = _assemble_2d(e, x, x0, u, hs, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, pos, pos0,
                                         f, ab, g4, H4, g6, H6, cg, ch, True, sym)
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
        if (band_ldl_solve(ab, n, 5, dx) if sym else band_lu_solve(ab, n, 5, dx)) != 0:
            return 3, it, False, r, r0
        if prm.step_limit > 0 and prm.n_obstacles > 0 and cd.cand_count[e] > 0:  # no update may tunnel (see _newton_3d)
            N = n // 2
            for k in range(N):
                cg[k, 0] = -dx[2 * k]
                cg[k, 1] = 0.0
                cg[k, 2] = -dx[2 * k + 1]
            tcap = contact_step_limit(e, cd, pos, cg, prm.radius, prm.contact_delta)
            if tcap < 1.0:
                for k in range(n):
                    dx[k] *= tcap
        if prm.line_search == 1:
            alpha = 1.0
            for trial in range(5):
                for k in range(n):
                    xt[k] = x[k] - alpha * dx[k]
                rt, _, _, _, _ = _assemble_2d(e, xt, x0, u, hs, kb, rest_len, vor_len, mass, fixed, grav, prm, cd,
                                              pos, pos0, f, ab, g4, H4, g6, H6, cg, ch, False, sym)
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
            if not fixed[k]:
                dmax = max(dmax, abs(dx[k]))
        if not np.isfinite(dmax):
            return 1, it, False, r, r0
        if dmax / hs < dtol:
            conv = True
            break
    return 0, it, conv, r, r0


@njit(**_OPT)
def _substep_2d(e, x0, u, h, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, w, want_pen0):
    """2-D analogue of _substep_3d (frames are updated by the caller): a midpoint step that gains energy is
    redone by backward Euler."""
    st, it, conv, r, r0, pen, pen0 = _substep_with_2d(e, x0, u, h, kb, rest_len, vor_len, mass, fixed, grav, prm,
                                                      cd, w, want_pen0, prm.midpoint != 0)
    if st == 6:
        st, it2, conv, r, r0, pen, pen0 = _substep_with_2d(e, x0, u, h, kb, rest_len, vor_len, mass, fixed, grav,
                                                           prm, cd, w, want_pen0, False)
        it += it2
    return st, it, conv, r, r0, pen, pen0


@njit(**_OPT)
def _mech_energy_2d(e, xs, us, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, w, pos, pos0, h):
    """(E_total, E_total − E_gravity) [J] of a planar state; contact over the current candidates (friction
    off), ``pos`` the node positions of xs."""
    g4, H4, g6, H6, cg, ch = w[7], w[8], w[9], w[10], w[11], w[12]
    es, eb = _energies_2d(xs, kb, rest_len, vor_len, prm, g4, H4, g6, H6)
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
    e_in = es + eb + ek + ec
    return e_in + eg, e_in


@njit(**_OPT)
def _substep_with_2d(e, x0, u, h, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, w, want_pen0, midpoint):
    """One (sub)step by implicit midpoint (``midpoint``) or backward Euler; status 6: a midpoint step gained
    energy (nothing committed)."""
    (x, f, dx, xt, ab, pos, pos0, g4, H4, g6, H6, cg, ch) = w
    n = x0.shape[0]
    N = n // 2
    hs = h if not midpoint else 0.5 * h
    pen0 = 0.0
    if prm.n_obstacles > 0:
        py = prm.plane_y
        for k in range(N):
            pos0[k, 0] = x0[2 * k]
            pos0[k, 1] = py
            pos0[k, 2] = x0[2 * k + 1]
            pos[k, 0] = x0[2 * k] + hs * u[2 * k]  # predicted end of step (contact: swept list)
            pos[k, 1] = py
            pos[k, 2] = x0[2 * k + 1] + hs * u[2 * k + 1]
        contact_broadphase(e, cd, pos0, pos, prm.contact_margin)
        if want_pen0 and cd.cand_count[e] > 0:
            pen0 = -contact_min_gap(e, cd, pos0, prm.radius)
    st, it, conv, r, r0 = _newton_2d(e, x0, u, hs, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, w)
    if st != 0:
        return st, it, False, r, r0, 0.0, pen0
    list_covers_step = False
    if prm.n_obstacles > 0:  # refresh the candidates over the motion actually taken (see _substep_3d)
        py = prm.plane_y
        for k in range(N):
            pos[k, 0] = x[2 * k]
            pos[k, 1] = py
            pos[k, 2] = x[2 * k + 1]
        # backward Euler ends where the solve ended: then the refreshed list already covers the whole
        # sub-step motion and the end-of-sub-step broad phase below is not needed again
        list_covers_step = not midpoint
        if contact_refresh(e, cd, pos0, pos, prm.contact_margin):
            list_covers_step = False
            st, it2, conv, r, r0 = _newton_2d(e, x0, u, hs, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, w)
            it += it2
            if st != 0:
                return st, it, False, r, r0, 0.0, pen0
    if not conv and prm.accept_unconverged == 0:
        return 4, it, False, r, r0, 0.0, pen0
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
    for j in range(N - 1):
        ex = x[2 * j + 2] - x[2 * j]
        ez = x[2 * j + 3] - x[2 * j + 1]
        s = math.sqrt(ex * ex + ez * ez) / rest_len[j] - 1.0
        if not abs(s) <= prm.max_strain:
            return 5, it, conv, r, r0, 0.0, pen0
    for k in range(n):
        if not (np.isfinite(x[k]) and np.isfinite(dx[k])):
            return 1, it, conv, r, r0, 0.0, pen0
    if midpoint and prm.midpoint_energy_tol > 0:  # energy at the start and at the end of the sub-step
        py = prm.plane_y
        for k in range(N):
            pos0[k, 0] = x0[2 * k]
            pos0[k, 1] = py
            pos0[k, 2] = x0[2 * k + 1]
            pos[k, 0] = x[2 * k]
            pos[k, 1] = py
            pos[k, 2] = x[2 * k + 1]
        e0, s0 = _mech_energy_2d(e, x0, u, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, w, pos0, pos0, h)
        e1, s1 = _mech_energy_2d(e, x, dx, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, w, pos, pos0, h)
        if midpoint_gained_energy(e0, s0, e1, s1, prm.midpoint_energy_tol):
            return 6, it, conv, r, r0, 0.0, pen0
    for k in range(n):
        x0[k] = x[k]
        u[k] = dx[k]
    pen = 0.0
    if prm.n_obstacles > 0:  # end-of-sub-step penetration over a list covering the whole sub-step motion
        py = prm.plane_y
        for k in range(N):
            pos[k, 0] = x[2 * k]
            pos[k, 1] = py
            pos[k, 2] = x[2 * k + 1]
        if not list_covers_step:
            contact_broadphase(e, cd, pos0, pos, prm.contact_margin)
        if cd.cand_count[e] > 0:
            pen = -contact_min_gap(e, cd, pos, prm.radius)
    return 0, it, conv, r, r0, pen, pen0


@njit(**_OPT)
def _alloc_env_2d(N):
    """Per-thread step workspace: (sub)step start state, guard fallback state, 3-D frame scratch."""
    n = 2 * N
    return (np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty((N - 1, 3)), np.empty((N - 1, 3)),
            np.empty((N - 1, 3)), np.empty(N - 1), np.empty(N))


@njit(**_OPT)
def _alloc_2d(N):
    n = 2 * N
    return (np.empty(n), np.empty(n), np.zeros(n + 5), np.empty(n), np.empty((n + 5, 11)), np.empty((N, 3)),
            np.empty((N, 3)), np.empty(4), np.empty((4, 4)), np.empty(6), np.empty((6, 6)),
            np.zeros((N, 3)), np.zeros((N - 1, 6, 6)))


@njit(**_OPT)
def _frames_from_2d(xs, py, d1s, ts, bs, pos, t, d1, d2, elen, beta):
    """Update the 3-D frame arrays of a planar state (time-parallel transport from the stored ones)."""
    N = xs.shape[0] // 2
    for k in range(N):
        pos[k, 0] = xs[2 * k]
        pos[k, 1] = py
        pos[k, 2] = xs[2 * k + 1]
    update_frames(pos, d1s, ts, bs, t, d1, d2, elen, beta)
    d1s[:, :] = d1
    ts[:, :] = t
    bs[:] = beta


@njit(**_OPT)
def _energies_2d(xs, kb, rest_len, vor_len, prm, g4, H4, g6, H6):
    """(E_stretch, E_bend) [J] of a planar state."""
    N = xs.shape[0] // 2
    es = 0.0
    for j in range(N - 1):
        o = 2 * j
        ej, _ = stretch_element_2d((xs[o], xs[o + 1]), (xs[o + 2], xs[o + 3]), rest_len[j], prm.EA, g4, H4, False)
        es += ej
    eb = 0.0
    for i in range(1, N - 1):
        o = 2 * (i - 1)
        ebi, _ = planar_bend_element((xs[o], xs[o + 1]), (xs[o + 2], xs[o + 3]), (xs[o + 4], xs[o + 5]),
                                     prm.planar_sign * kb[i, 0], prm.EI1, vor_len[i], g6, H6, False)
        eb += ebi
    return es, eb


@njit(**_OPT)
def _env_step_2d(e, xs, us, d1s, ts, bs, kb, rest_len, vor_len, mass, fixed, grav, prm, cd, crep, fo, io, w, sw):
    """One env's step; w (_alloc_2d) and sw (_alloc_env_2d): the calling thread's workspaces (see _env_step_3d)."""
    n = xs.shape[0]
    N = n // 2
    (x0, u, fb_x, fb_u, t, d1, d2, elen, beta) = sw
    ok = False
    iters = 0
    conv_all = True
    r = 0.0
    r0 = 0.0
    ns = 1
    levels = int(prm.retry_levels)
    fb_pen = np.inf  # penetration / divergence guard fallback (see _env_step_3d): its score
    rg = prm.divergence_guard
    fb_ns, fb_it, fb_conv, fb_r, fb_r0 = 1, 0, False, 0.0, 0.0
    lim = prm.max_penetration  # guard limit [m]: raised to (start penetration + limit/4) for a step starting deeper
    for level in range(levels):
        ns = 1 << level
        h = prm.dt / ns
        x0[:] = xs
        u[:] = us
        ok = True
        iters = 0
        conv_all = True
        pen = 0.0
        grow = 0.0
        for s in range(ns):
            st, it, conv, r, r0s, pen_s, pen0 = _substep_2d(e, x0, u, h, kb, rest_len, vor_len, mass, fixed, grav,
                                                            prm, cd, w, level == 0 and s == 0)
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
                fb_ns, fb_it, fb_conv, fb_r, fb_r0 = ns, iters, conv_all, r, r0
            ok = False
            continue
        if ok:
            break
    if not ok and fb_pen < np.inf:
        ok = True
        x0[:] = fb_x
        u[:] = fb_u
        ns, iters, conv_all, r, r0 = fb_ns, fb_it, fb_conv, fb_r, fb_r0
    (x, f, dx, xt, ab, pos, pos0, g4, H4, g6, H6, cg, ch) = w
    if ok:
        xs[:] = x0
        us[:] = u
        _frames_from_2d(xs, prm.plane_y, d1s, ts, bs, pos, t, d1, d2, elen, beta)
    es, eb = _energies_2d(xs, kb, rest_len, vor_len, prm, g4, H4, g6, H6)
    ec = 0.0
    if prm.n_obstacles > 0:
        py = prm.plane_y
        for k in range(N):
            pos[k, 0] = xs[2 * k]
            pos[k, 1] = py
            pos[k, 2] = xs[2 * k + 1]
        contact_broadphase(e, cd, pos, pos, prm.contact_margin)  # pairs near the state kept (see _env_step_3d)
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
    fo[F_ET] = 0.0
    fo[F_EC] = ec
    fo[F_EK] = ek
    fo[F_EG] = eg
    io[I_ITERS] = iters
    io[I_CONV] = 1 if (ok and conv_all) else 0
    io[I_SUB] = ns
    io[I_FAIL] = 0 if ok else 1
    if prm.n_obstacles > 0:
        py = prm.plane_y
        for k in range(N):
            pos[k, 0] = xs[2 * k]
            pos[k, 1] = py
            pos[k, 2] = xs[2 * k + 1]
            pos0[k, 0] = xs[2 * k] - prm.dt * us[2 * k]  # step start (friction velocity)
            pos0[k, 1] = py
            pos0[k, 2] = xs[2 * k + 1] - prm.dt * us[2 * k + 1]
        contact_report(e, cd, pos, pos0, prm.dt, prm.radius, prm.contact_k, prm.contact_delta, prm.friction, prm.friction_nu,
                       prm.friction_on > 0, crep.count, crep.edge, crep.obstacle, crep.rod_point, crep.obstacle_point,
                       crep.normal, crep.normal_force, crep.friction_force, crep.gap, crep.max_penetration)
    return ok


@njit(parallel=True, **_OPT)
def step_kernel_2d(dof, vel, d1s, ts, bs, times, failed, kappa_bar, rest_len, vor_len, mass, fixed, grav, prm_arr,
                   cd, crep, fo, io):
    """2-D analogue of step_kernel_3d; dof/vel (B, 2N) views of State.dof ([x, z] per node)."""
    B = dof.shape[0]
    N = dof.shape[1] // 2
    nch = (B + _CHUNK - 1) // _CHUNK
    for chunk in prange(nch):  # workspaces once per chunk of envs (see step_kernel_3d)
        prm = prm_arr[0]  # the parameters record, by reference
        w = _alloc_2d(N)
        sw = _alloc_env_2d(N)
        for e in range(chunk * _CHUNK, min(B, chunk * _CHUNK + _CHUNK)):
            for c in range(F_COLS):
                fo[e, c] = 0.0
            for c in range(I_COLS):
                io[e, c] = 0
            if failed[e]:
                continue
            ok = _env_step_2d(e, dof[e], vel[e], d1s[e], ts[e], bs[e], kappa_bar[e], rest_len, vor_len, mass, fixed,
                              grav, prm, cd, crep, fo[e], io[e], w, sw)
            if ok:
                times[e] += prm.dt
            else:
                failed[e] = True
