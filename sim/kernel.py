"""The batched step kernel: per env, the retry/guard ladder around :func:`sim.newton.substep`, then the outputs
(energies, solver figures, contact rows). Shared by the 3-D and the planar rod (``prm.planar``); see
:mod:`sim.newton` for the stages of a (sub)step, docs/physics.md §6 for the ladder and the guards.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from .contact_kernels import contact_accumulate, contact_broadphase, contact_report
from .contact_rod import rod_pairs_broadphase, rod_pairs_report
from .newton import _energies, _positions, _predicted_positions, substep
from .solve_2d import KL_2D, frames_from_2d
from .solve_3d import KL_3D
from .solve_params import _CHUNK, _OPT, _OPT_ALLOC, OK, Workspace, copy_into, guard_score

__all__ = ["step_kernel", "alloc_workspace"]


@njit(**_OPT_ALLOC)
def alloc_workspace(N, planar, P):
    """A :class:`sim.solve_params.Workspace` for a rod of N nodes with P edge pairs that may touch (one per thread
    and chunk of envs; the edge-pair fields are empty when P = 0)."""
    dpn = 2 if planar else 4
    kl = KL_2D if planar else KL_3D
    n = dpn * N
    K = (2 if planar else 3) * N if P > 0 else 0
    nslot = n if P > 0 else 0
    nbox = N - 1 if P > 0 else 0
    wb_slot = np.full(nslot, -1, np.int64)
    rp_box = np.empty((nbox, 6))
    return Workspace(
        x=np.empty(n), f=np.empty(n), dx=np.zeros(n + kl), xt=np.empty(n), ab=np.empty((n + kl, 2 * kl + 1)),
        pos=np.empty((N, 3)), pos0=np.empty((N, 3)), t=np.empty((N - 1, 3)), d1=np.empty((N - 1, 3)),
        d2=np.empty((N - 1, 3)), elen=np.empty(N - 1), beta=np.empty(N), g4=np.empty(4), H4=np.empty((4, 4)),
        g6=np.empty(6), H6=np.empty((6, 6)), g11=np.empty(11), H11=np.empty((11, 11)), wk=np.empty((17, 11)),
        cg=np.zeros((N, 3)), ch=np.zeros((N - 1, 6, 6)), mf=np.empty((N - 1, 6)),
        sub_x=np.empty(n), sub_v=np.empty(n), sub_d1=np.empty((N - 1, 3)), sub_t=np.empty((N - 1, 3)),
        sub_beta=np.empty(N), fb_x=np.empty(n), fb_v=np.empty(n), fb_d1=np.empty((N - 1, 3)),
        fb_t=np.empty((N - 1, 3)), fb_beta=np.empty(N), rp_cand=np.zeros(P, np.int64), rp_n=np.zeros(1, np.int64),
        rp_box=rp_box, g12=np.empty(12), H12=np.empty((12, 12)), n12=np.empty(3),
        ws12=np.empty(32), wb_slot=wb_slot, wb_dof=np.zeros(K, np.int64), wb_n=np.zeros(1, np.int64),
        wb_M=np.zeros((K, K)), wb_Z=np.empty((K, n + kl)), wb_C=np.empty((K, K)), wb_r=np.empty(K),
        wb_piv=np.empty(K, np.int64))


@njit(inline="always", **_OPT)
def _copy_state(x, v, d1, t, beta, to_x, to_v, to_d1, to_t, to_beta):
    copy_into(to_x, x)
    copy_into(to_v, v)
    copy_into(to_d1, d1)
    copy_into(to_t, t)
    copy_into(to_beta, beta)


@njit(**_OPT)
def env_step(e, xs, us, d1s, ts, bs, kb, tb, rod, prm, cd, crep, out, w):
    """Advance env e (its state rows xs, us, d1s, ts, bs) by prm.dt through the retry/guard ladder; write its
    outputs. Returns False if the env failed (its state is then left as it was)."""
    planar = prm.planar != 0
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
            st, it, conv, r, r0s, pen_s, pen0, fell = substep(e, h, kb, tb, rod, prm, cd, w, level == 0 and s == 0)
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
    _write_outputs(e, xs, us, d1s, ts, bs, kb, tb, rod, prm, cd, crep, out, w)
    out.residual[e] = r if np.isfinite(r) else np.inf
    out.residual0[e] = r0 if np.isfinite(r0) else np.inf
    out.newton_iters[e] = iters
    out.converged[e] = ok and conv_all
    out.substeps[e] = ns
    out.midpoint_fallbacks[e] = mfall if ok else 0
    out.failed[e] = not ok
    return ok


@njit(**_OPT)
def _write_outputs(e, xs, us, d1s, ts, bs, kb, tb, rod, prm, cd, crep, out, w):
    """Energies [J] of the (new or restored) state, whose stored frames are at xs, and its contact rows."""
    planar = prm.planar != 0
    es, eb, et = _energies(planar, xs, d1s, ts, bs, kb, tb, rod, prm, w)
    ec = 0.0
    pos, pos0 = w.pos, w.pos0
    if prm.n_obstacles > 0 or prm.rod_pairs > 0:
        _positions(planar, xs, pos, prm.plane_y)
        # pos0: the step start by the step's velocity (the rows' friction velocity)
        _predicted_positions(planar, xs, us, -prm.dt, pos0, prm.plane_y)
    if prm.n_obstacles > 0:
        # candidates of the state actually kept (a guard fallback or a restored state is not the configuration
        # the last sub-step's list was built for): energy and report see every pair near it
        contact_broadphase(e, cd, pos, pos, prm.contact_margin, rod.link)
        w.cg[:, :] = 0.0
        w.ch[:, :, :] = 0.0
        ec = contact_accumulate(e, cd, pos, pos, prm.dt, rod.radius, prm.contact_k, prm.contact_delta, prm.friction,
                                prm.friction_nu, prm.friction_on > 0, w.cg, w.ch, rod.link)
        contact_report(e, cd, pos, pos0, prm.dt, rod.radius, prm.contact_k, prm.contact_delta, prm.friction,
                       prm.friction_nu, prm.friction_on > 0, crep.count, crep.edge, crep.obstacle, crep.rod_point,
                       crep.obstacle_point, crep.normal, crep.normal_force, crep.friction_force, crep.gap,
                       crep.max_penetration, rod.link)
    if prm.rod_pairs > 0:  # edge pairs near the state kept: energy, deepest gap, rows after the obstacles'
        rod_pairs_broadphase(rod.pairs, pos, pos, rod.radius, prm.contact_margin, w.rp_box, w.rp_cand, w.rp_n)
        if prm.n_obstacles == 0:
            crep.count[e] = 0
        ep, smallest = rod_pairs_report(e, rod.pairs, w.rp_cand, w.rp_n, pos, pos0, prm.dt, rod.radius,
                                        prm.contact_k, prm.contact_delta, prm.friction, prm.friction_nu, w.g12, w.H12,
                                        w.n12, w.ws12, crep.count, crep.edge, crep.obstacle, crep.partner,
                                        crep.rod_point, crep.obstacle_point, crep.normal, crep.normal_force,
                                        crep.friction_force, crep.gap)
        ec += ep
        pen = max(0.0, -smallest)
        if prm.n_obstacles > 0:
            pen = max(pen, crep.max_penetration[e])
        crep.max_penetration[e] = pen
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


@njit(**_OPT)
def _clear_outputs(out, e):  # a call, not inlined: the outputs are written inside the callee
    out.residual[e] = 0.0
    out.residual0[e] = 0.0
    out.energy_stretch[e] = 0.0
    out.energy_bend[e] = 0.0
    out.energy_twist[e] = 0.0
    out.energy_contact[e] = 0.0
    out.energy_kinetic[e] = 0.0
    out.energy_gravity[e] = 0.0
    out.newton_iters[e] = 0
    out.substeps[e] = 0
    out.midpoint_fallbacks[e] = 0
    out.converged[e] = False
    out.failed[e] = False


@njit(parallel=True, nogil=True, **_OPT_ALLOC)  # nogil: other Python threads (e.g. SAC updates) run meanwhile
def step_kernel(state, ctl, rod, prm_arr, cd, crep, out):
    """Advance all non-failed envs of ``state`` (:class:`sim.solve_params.StateArrays`, dof/vel (B, n)) by prm.dt
    under ``ctl`` (:class:`sim.solve_params.ControlArrays`); per-env results into ``out``
    (:class:`sim.solve_params.StepOutput`) and the contact rows ``crep`` (:class:`sim.solve_params.ContactReport`)."""
    dof, vel, ref_d1, tangent, ref_twist = state.dof, state.vel, state.ref_d1, state.tangent, state.ref_twist
    times, failed = state.time, state.failed  # unpacked before the parallel loop: writes must reach the caller's arrays
    kappa_bar, tau_bar = ctl.kappa_bar, ctl.tau_bar
    B = dof.shape[0]
    N = ref_twist.shape[1]
    nch = (B + _CHUNK - 1) // _CHUNK
    for chunk in prange(nch):  # workspaces are allocated once per chunk of envs, not per env-step
        prm = prm_arr[0]  # the parameters record, by reference
        w = alloc_workspace(N, prm.planar != 0, rod.pairs.shape[0])
        for e in range(chunk * _CHUNK, min(B, chunk * _CHUNK + _CHUNK)):
            _clear_outputs(out, e)
            if failed[e]:
                continue
            ok = env_step(e, dof[e], vel[e], ref_d1[e], tangent[e], ref_twist[e], kappa_bar[e], tau_bar[e], rod, prm,
                          cd, crep, out, w)
            if ok:
                times[e] += prm.dt
            else:
                failed[e] = True
