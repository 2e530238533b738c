"""Per env, the retry/guard ladder around :func:`sim.kernels.newton.substep`, then the env's outputs (energies,
solver figures, contact rows). Shared by the 3-D and the planar rod (``prm.planar``); the batched driver over
all envs is :mod:`sim.kernels.batch`; see :mod:`sim.kernels.newton` for the stages of a (sub)step,
docs/physics.md §6 for the ladder and the guards.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from sim.contact import stages as contact
from sim.kernels.assemble_2d import frames_from_2d
from sim.kernels.data import OK
from sim.kernels.newton import energies, positions, predicted_positions, substep
from sim.kernels.workspace import copy_into
from sim.numba_options import OPT

__all__ = ["env_step", "guard_score"]


@njit(inline="always", **OPT)
def guard_score(pen, lim, grow, rg):
    """How badly a finite retry level trips the guards: max(pen/lim, grow/rg) over the tripped ones, else 0
    (penetration pen beyond its limit lim [m]; residual growth grow beyond rg when rg > 0)."""
    score = pen / lim if pen > lim else 0.0
    if rg > 0.0 and grow > rg:
        score = max(score, grow / rg)
    return score


@njit(inline="always", **OPT)
def _copy_state(x, v, d1, t, beta, to_x, to_v, to_d1, to_t, to_beta):
    copy_into(to_x, x)
    copy_into(to_v, v)
    copy_into(to_d1, d1)
    copy_into(to_t, t)
    copy_into(to_beta, beta)


@njit(**OPT)
def env_step(e, xs, us, d1s, ts, bs, kb, tb, rod, prm, cs, crep, out, w):
    """Advance env e (its state rows xs, us, d1s, ts, bs) by prm.dt through the retry/guard ladder; write its
    outputs. Returns False if the env failed (its state is then left as it was)."""
    planar = prm.planar
    ok = False
    iters = 0
    conv_all = True
    r = 0.0
    r0 = 0.0
    ns = 1
    levels = prm.retry_levels
    # guards: penetration (end configuration deeper than lim) and divergence (an accepted unconverged solve whose
    # residual grew by more than rg over its iterations); a level that trips one is retried with twice the
    # sub-steps, keeping the least-bad finite level result (score = max(pen/lim, growth/rg) > 1) as fallback
    fb_score = np.inf
    rg = prm.divergence_guard
    fb_ns, fb_it, fb_conv, fb_r, fb_r0, fb_mf = 1, 0, False, 0.0, 0.0, 0
    mfall = 0  # midpoint (sub)steps of the level kept that were redone by backward Euler
    lim = prm.max_penetration  # guard limit [m]: raised to (start penetration + limit/4) for a step starting deeper
    for level in range(levels):
        ns = 1 << level
        h = prm.dt / ns
        _copy_state(xs, us, d1s, ts, bs, w.sub_x, w.sub_v, w.sub_d1, w.sub_t, w.sub_beta)
        ok = True
        iters = 0
        mfall = 0
        conv_all = True
        pen = 0.0
        grow = 0.0
        for s in range(ns):
            st, it, conv, r, r0s, pen_s, pen0, fell = substep(e, h, kb, tb, rod, prm, cs, w, level == 0 and s == 0)
            mfall += fell
            if s == 0:
                r0 = r0s
                if level == 0:
                    lim = max(prm.max_penetration, pen0 + 0.25 * prm.max_penetration)
            iters += it
            conv_all = conv_all and conv
            if st != OK:
                ok = False
                break
            pen = max(pen, pen_s)
            if not conv and r0s > 0.0:
                grow = max(grow, r / r0s)
        score = guard_score(pen, lim, grow, rg)
        if ok and score > 0.0 and level < levels - 1:
            if score < fb_score:
                fb_score = score
                _copy_state(w.sub_x, w.sub_v, w.sub_d1, w.sub_t, w.sub_beta, w.fb_x, w.fb_v, w.fb_d1, w.fb_t,
                            w.fb_beta)
                fb_ns, fb_it, fb_conv, fb_r, fb_r0, fb_mf = ns, iters, conv_all, r, r0, mfall
            ok = False
            continue
        if ok:
            break
    if not ok and fb_score < np.inf:
        ok = True
        _copy_state(w.fb_x, w.fb_v, w.fb_d1, w.fb_t, w.fb_beta, w.sub_x, w.sub_v, w.sub_d1, w.sub_t, w.sub_beta)
        ns, iters, conv_all, r, r0, mfall = fb_ns, fb_it, fb_conv, fb_r, fb_r0, fb_mf
    if ok:
        if planar:
            copy_into(xs, w.sub_x)
            copy_into(us, w.sub_v)
            frames_from_2d(xs, prm.plane_y, d1s, ts, bs, w, rod.link)
        else:
            _copy_state(w.sub_x, w.sub_v, w.sub_d1, w.sub_t, w.sub_beta, xs, us, d1s, ts, bs)
    _write_outputs(e, xs, us, d1s, ts, bs, kb, tb, rod, prm, cs, crep, out, w)
    out.residual[e] = r if np.isfinite(r) else np.inf
    out.residual0[e] = r0 if np.isfinite(r0) else np.inf
    out.newton_iters[e] = iters
    out.converged[e] = ok and conv_all
    out.substeps[e] = ns
    out.midpoint_fallbacks[e] = mfall if ok else 0
    out.failed[e] = not ok
    return ok


@njit(**OPT)
def _write_outputs(e, xs, us, d1s, ts, bs, kb, tb, rod, prm, cs, crep, out, w):
    """Energies [J] of the (new or restored) state, whose stored frames are at xs, and its contact rows."""
    planar = prm.planar
    es, eb, et = energies(planar, xs, d1s, ts, bs, kb, tb, rod, prm, w)
    ec = 0.0
    pos, pos0 = w.pos, w.pos0
    if contact.present(prm):
        positions(planar, xs, pos, prm.plane_y)
        # pos0: the step start by the step's velocity (the rows' friction velocity)
        predicted_positions(planar, xs, us, -prm.dt, pos0, prm.plane_y)
        ec = contact.report(e, prm, rod, cs, pos, pos0, crep)
    ek = 0.0
    eg = 0.0
    grav = rod.grav[min(e, rod.grav.shape[0] - 1)]  # external forces: (1, n) shared or (B, n) per env
    for k in range(xs.shape[0]):
        ek += 0.5 * rod.mass[k] * us[k] * us[k] * (0.0 if rod.fixed[k] else 1.0)
        eg -= grav[k] * xs[k]
    out.energy_stretch[e] = es
    out.energy_bend[e] = eb
    out.energy_twist[e] = et
    out.energy_contact[e] = ec
    out.energy_kinetic[e] = ek
    out.energy_gravity[e] = eg
