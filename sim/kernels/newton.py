"""The implicit (sub)step, shared by the 3-D and the planar rod: Newton loop, (sub)step and the decisions the
solve takes from the parameters (docs/physics.md §3.4). The retry/guard ladder around it is in
:mod:`sim.kernels.ladder`, the batched driver in :mod:`sim.kernels.batch`.

The mode (``prm.planar``) selects the element functions: :mod:`sim.kernels.assemble_3d` (4N unknowns) or
:mod:`sim.kernels.assemble_2d` (2N unknowns); all the rest is written once. A (sub)step of size h runs these
stages:

    predict     guess x = x0 + 0.01·u·h on free DOFs; contact candidates over the predicted motion
    newton      repeat: frames (time-parallel transport) + assemble residual f and banded Jacobian J
                (constrained DOFs: identity rows/columns, zero residual) → force test ‖f‖ ≤ tol·‖f0‖ →
                banded solve (LDLᵀ when J is symmetric, else LU; pivots checked) → tunnelling limit →
                line search (``backtrack``: every step; ``auto``: only after an update raised ‖f‖ with contact
                candidates) → displacement test max|Δx|/h < dtol on free position DOFs
    refresh     candidates over the motion actually taken; new pairs → solve again
    accept      unconverged at max_iter only if allowed
    integrate   backward Euler u = (x − x0)/h, or implicit midpoint (solve over h/2, x = 2x½ − x0,
                u = 2u½ − u0); end frames; |strain| ≤ max_strain; finite; a midpoint step that gained energy is
                redone by backward Euler
    commit      the sub-step start state becomes the new state; end-of-sub-step penetration

Failed (sub)steps, the retry ladder and the penetration and divergence guards: docs/physics.md §6.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from sim.contact import stages as contact
from sim.geometry.frames import update_frames
from sim.kernels.assemble_2d import assemble_2d, energies_2d
from sim.kernels.assemble_3d import assemble_3d, energies_3d
from sim.kernels.banded import band_ldl_apply, band_ldl_factor, band_lu_apply, band_lu_factor, dense_lu_solve
from sim.kernels.data import (
    BAD_PIVOT,
    KL_2D,
    KL_3D,
    MIDPOINT_GAINED,
    NON_FINITE,
    OK,
    RESIDUAL_GROWTH,
    STRAIN,
    UNCONVERGED,
    LineSearch,
)
from sim.kernels.workspace import copy_into
from sim.numba_options import OPT

__all__ = ["newton", "substep", "substep_with", "mech_energy", "assemble", "energies", "positions",
           "predicted_positions", "linear_solve", "jacobian_symmetric", "midpoint_gained_energy"]


# ------------------------------------------------------------------------------------------- the solve's decisions
@njit(inline="always", **OPT)
def jacobian_symmetric(prm):
    """Whether the Newton Jacobian is symmetric: yes unless friction can act in a contact
    (:func:`sim.contact.stages.symmetric`); the kernels then assemble only the band's upper half and factor it by
    LDLᵀ."""
    return contact.symmetric(prm)


@njit(inline="always", **OPT)
def lazy_line_search(prm, cs, e):
    """Whether env ``e``'s Newton loop backtracks lazily (``line_search = "auto"``, the default): only in
    an env with contact candidates (obstacle or edge pairs: where friction's stick law and the stiff contact
    potential make full Newton steps overshoot), and only when an update raised ‖f‖; otherwise the full step
    costs nothing extra. The decision is read once per Newton solve (the candidate list is fixed during it)."""
    return prm.line_search == LineSearch.AUTO and contact.has_candidates(e, prm, cs)


@njit(inline="always", **OPT)
def newton_dtol(prm, cs, e):
    """Displacement-test tolerance [m/s] of env ``e``'s Newton solve: ``newton_dtol``, capped at 1 % of the
    friction velocity tolerance ν where friction can act (contact candidates and μ > 0): the stick law
    γ(|v_t|/ν) resolves velocities on the scale ν, so an update that still changes velocities by ~ν is
    not converged (docs/physics.md §4.6)."""
    dtol = prm.newton_dtol
    if contact.friction_acts(e, prm, cs):
        dtol = min(dtol, 0.01 * prm.friction_nu)
    return dtol


@njit(inline="always", **OPT)
def midpoint_gained_energy(e0, s0, e1, s1, tol, floor):
    """Whether an implicit-midpoint (sub)step gained energy beyond ``tol``: total energy e1 at its end exceeds
    e0 at its start by more than tol · max(s0, s1) (s: the energy without the gravity potential, whose zero is
    arbitrary) and by more than ``floor`` [J] (below it a gain is the rounding of energies near 0). Within a step
    κ̄, τ̄ and the constraints are fixed and damping/friction only dissipate, so a gain is the midpoint rule's own
    nonlinear instability; the sub-step is then redone by backward Euler."""
    return e1 - e0 > max(tol * max(s0, s1), floor)


# ------------------------------------------------------------------------------------- the mode's element functions
@njit(inline="always", **OPT)
def assemble(planar, e, x, h, kb, tb, rod, prm, cs, w, with_jac, sym):
    """Frames at x, residual w.f and (with_jac) Jacobian w.ab; returns (‖f‖, Es, Eb, Et, Ec)."""
    if planar:
        return assemble_2d(e, x, h, kb, tb, rod, prm, cs, w, with_jac, sym)
    return assemble_3d(e, x, h, kb, tb, rod, prm, cs, w, with_jac, sym)


@njit(inline="always", **OPT)
def energies(planar, xs, d1s, ts, bs, kb, tb, rod, prm, w):
    """(E_stretch, E_bend, E_twist) [J] of a state with its stored frames."""
    if planar:
        return energies_2d(xs, kb, rod, prm, w)
    return energies_3d(xs, d1s, ts, bs, kb, tb, rod, prm, w)


@njit(inline="always", **OPT)
def positions(planar, x, pos, py):
    """pos (N, 3) = the node positions of DOFs x (2-D: in the plane y = py)."""
    if planar:
        for k in range(pos.shape[0]):
            pos[k, 0] = x[2 * k]
            pos[k, 1] = py
            pos[k, 2] = x[2 * k + 1]
    else:
        for k in range(pos.shape[0]):
            for a in range(3):
                pos[k, a] = x[4 * k + a]


@njit(inline="always", **OPT)
def predicted_positions(planar, x, u, s, pos, py):
    """pos (N, 3) = the node positions of x + s·u."""
    if planar:
        for k in range(pos.shape[0]):
            pos[k, 0] = x[2 * k] + s * u[2 * k]
            pos[k, 1] = py
            pos[k, 2] = x[2 * k + 1] + s * u[2 * k + 1]
    else:
        for k in range(pos.shape[0]):
            for a in range(3):
                pos[k, a] = x[4 * k + a] + s * u[4 * k + a]


@njit(inline="always", **OPT)
def _node_motion(planar, dx, out):
    """out (N, 3) = the node displacements of the update x ← x − dx."""
    if planar:
        for k in range(out.shape[0]):
            out[k, 0] = -dx[2 * k]
            out[k, 1] = 0.0
            out[k, 2] = -dx[2 * k + 1]
    else:
        for k in range(out.shape[0]):
            for a in range(3):
                out[k, a] = -dx[4 * k + a]


# ------------------------------------------------------------------------------------------------ Newton's stages
@njit(inline="always", **OPT)
def _predict(x, x0, u, fixed, hs):
    """Initial guess x = x0 + 0.01·u·hs on free DOFs."""
    for k in range(x.shape[0]):
        x[k] = x0[k] if fixed[k] else x0[k] + 0.01 * u[k] * hs


@njit(inline="always", **OPT)
def _band_apply(planar, sym, ab, n, b):
    """b ← B⁻¹ b from the band's factors (b of length n + kl). The half bandwidths are passed as constants: the
    solvers are inlined and their loops unrolled for them."""
    if planar:
        if sym:
            band_ldl_apply(ab, n, KL_2D, b)
        else:
            band_lu_apply(ab, n, KL_2D, b)
    elif sym:
        band_ldl_apply(ab, n, KL_3D, b)
    else:
        band_lu_apply(ab, n, KL_3D, b)


@njit(inline="always", **OPT)
def linear_solve(planar, w, n, sym):
    """dx = J⁻¹ f (in place in w.dx): the banded solve, plus the Woodbury correction when edge pairs coupled
    DOFs outside the band (w.coupling.count[0] > 0, :func:`_woodbury`); False on a bad pivot or a singular correction."""
    dx = w.dx
    for k in range(n):
        dx[k] = w.f[k]
    if planar:
        st = band_ldl_factor(w.ab, n, KL_2D) if sym else band_lu_factor(w.ab, n, KL_2D)
    else:
        st = band_ldl_factor(w.ab, n, KL_3D) if sym else band_lu_factor(w.ab, n, KL_3D)
    if st != 0:
        return False
    _band_apply(planar, sym, w.ab, n, dx)
    if w.coupling.count[0] > 0:
        return _woodbury(planar, sym, w, n)
    return True


@njit(**OPT)
def _woodbury(planar, sym, w, n):
    """Correct dx = B⁻¹ f (w.dx; B the factored band) to (B + E M Eᵀ)⁻¹ f, where M (w.coupling.M, K × K) couples
    the listed DOFs w.coupling.dof (E their unit columns): dx − Z (I + M Eᵀ Z)⁻¹ M Eᵀ dx with Z = B⁻¹ E (docs/physics.md
    §4.8). K band solves and one dense K × K solve."""
    cp = w.coupling
    K = cp.count[0]
    Z, M, C, r, dof, dx = cp.Z, cp.M, cp.C, cp.r, cp.dof, w.dx
    for b in range(K):
        zb = Z[b]
        for i in range(zb.shape[0]):
            zb[i] = 0.0
        zb[dof[b]] = 1.0
        _band_apply(planar, sym, w.ab, n, zb)
    for a in range(K):
        acc = 0.0
        for c in range(K):
            acc += M[a, c] * dx[dof[c]]
        r[a] = acc
        for b in range(K):
            v = 0.0
            for c in range(K):
                v += M[a, c] * Z[b, dof[c]]
            C[a, b] = v + (1.0 if a == b else 0.0)
    if not dense_lu_solve(C, K, r, cp.piv):
        return False
    for b in range(K):
        wv = r[b]
        for i in range(n):
            dx[i] -= wv * Z[b, i]
    return True


@njit(inline="always", **OPT)
def _limit_update(planar, e, rod, cs, prm, w):
    """Shorten dx so that no update carries a rod edge through an obstacle or another edge (w.pos: the nodes
    at x)."""
    _node_motion(planar, w.dx, w.dpos)
    tcap = contact.step_limit(e, prm, rod, cs, w.pos, w.dpos)
    if tcap < 1.0:
        for k in range(w.x.shape[0]):
            w.dx[k] *= tcap


@njit(**OPT)
def _backtrack(planar, e, hs, rp, kb, tb, rod, prm, cs, w, sym):
    """Lazy line search: the last full update raised ‖f‖ above rp; step back along it (halving) until ‖f‖ ≤ rp
    or 4 halvings, then re-assemble with the Jacobian. Returns the new ‖f‖."""
    x, dx = w.x, w.dx
    alpha = 1.0
    for trial in range(4):
        alpha *= 0.5
        for k in range(x.shape[0]):
            x[k] += alpha * dx[k]  # x = x_prev - alpha dx
        rt = assemble(planar, e, x, hs, kb, tb, rod, prm, cs, w, False, sym)[0]
        if rt <= rp:
            break
    return assemble(planar, e, x, hs, kb, tb, rod, prm, cs, w, True, sym)[0]


@njit(**OPT)
def _line_search(planar, e, hs, r, kb, tb, rod, prm, cs, w, sym):
    """Backtracking line search on ‖f‖: x ← x − α·dx with α = 1, ½, … (5 tries; the last is taken anyway)."""
    x, xt, dx = w.x, w.xt, w.dx
    n = x.shape[0]
    alpha = 1.0
    for trial in range(5):
        for k in range(n):
            xt[k] = x[k] - alpha * dx[k]
        rt = assemble(planar, e, xt, hs, kb, tb, rod, prm, cs, w, False, sym)[0]
        if (np.isfinite(rt) and rt <= r) or trial == 4:
            break
        alpha *= 0.5
    for k in range(n):
        x[k] = xt[k]


@njit(inline="always", **OPT)
def _max_position_update(dx, fixed, dpn):
    """max |dx| over the free position DOFs (not the twist angles)."""
    dmax = 0.0
    for k in range(fixed.shape[0]):
        if not fixed[k] and not (dpn == 4 and (k & 3) == 3):
            dmax = max(dmax, abs(dx[k]))
    return dmax


@njit(**OPT)
def newton(e, hs, kb, tb, rod, prm, cs, w):
    """Newton iterations of one (sub)step of size hs from the sub-step start (w.sub_*), iterate in w.x.

    Returns (status, iterations, converged, ‖f‖ last, ‖f0‖); status OK (converged, or unconverged at the
    iteration cap), NON_FINITE, RESIDUAL_GROWTH or BAD_PIVOT."""
    planar = prm.planar
    x, dx, fixed = w.x, w.dx, rod.fixed
    n = x.shape[0]
    dpn = 2 if planar else 4
    maxit = prm.newton_max_iter
    tol = prm.newton_tol
    dtol = newton_dtol(prm, cs, e)
    sym = jacobian_symmetric(prm)
    lazy = lazy_line_search(prm, cs, e)
    limit = prm.step_limit and contact.has_candidates(e, prm, cs)
    _predict(x, w.sub_x, w.sub_v, fixed, hs)
    r0 = 0.0
    r = 0.0
    rp = 0.0
    conv = False
    it = 0
    while it < maxit:
        r = assemble(planar, e, x, hs, kb, tb, rod, prm, cs, w, True, sym)[0]
        if lazy and it > 0 and not r <= rp:
            r = _backtrack(planar, e, hs, rp, kb, tb, rod, prm, cs, w, sym)
        if not np.isfinite(r):
            return NON_FINITE, it, False, r, r0
        if it == 0:
            r0 = r
        elif r > 1e6 * r0:
            return RESIDUAL_GROWTH, it, False, r, r0
        if r <= tol * r0 and (it > 0 or r == 0.0):
            conv = True
            break
        rp = r
        if not linear_solve(planar, w, n, sym):
            return BAD_PIVOT, it, False, r, r0
        if limit:
            _limit_update(planar, e, rod, cs, prm, w)
        if prm.line_search == LineSearch.BACKTRACK:
            _line_search(planar, e, hs, r, kb, tb, rod, prm, cs, w, sym)
        else:
            for k in range(n):
                x[k] -= dx[k]
        it += 1
        dmax = _max_position_update(dx, fixed, dpn)
        if not np.isfinite(dmax):
            return NON_FINITE, it, False, r, r0
        if dmax / hs < dtol:
            conv = True
            break
    return OK, it, conv, r, r0


# ------------------------------------------------------------------------------------------------ one (sub)step
@njit(**OPT)
def mech_energy(e, xs, us, d1s, ts, bs, kb, tb, rod, prm, cs, w, pos, pos0, h):
    """(E_total, E_total − E_gravity) [J] of a state whose frames (d1s, ts, bs) are at xs; contact energy over
    the current candidates (friction off), ``pos`` the node positions of xs."""
    es, eb, et = energies(prm.planar, xs, d1s, ts, bs, kb, tb, rod, prm, w)
    ek = 0.0
    eg = 0.0
    grav = rod.grav[min(e, rod.grav.shape[0] - 1)]  # external forces: (1, n) shared or (B, n) per env
    for k in range(xs.shape[0]):
        if not rod.fixed[k]:
            ek += 0.5 * rod.mass[k] * us[k] * us[k]
        eg -= grav[k] * xs[k]
    ec = contact.energy(e, prm, rod, cs, pos, pos0, h)
    e_in = es + eb + et + ek + ec
    return e_in + eg, e_in


@njit(inline="always", **OPT)
def _integrate(w, fixed, h, hs, midpoint):
    """The new velocity into w.dx (and, for the midpoint rule, the end position into w.x)."""
    x, x0, u, dx = w.x, w.sub_x, w.sub_v, w.dx
    if not midpoint:
        for k in range(x.shape[0]):
            dx[k] = (x[k] - x0[k]) / h
    else:
        for k in range(x.shape[0]):
            uh = (x[k] - x0[k]) / hs
            x[k] = 2.0 * x[k] - x0[k]
            dx[k] = 2.0 * uh - u[k]
            if fixed[k]:
                dx[k] = 0.0


@njit(inline="always", **OPT)
def _strain_ok(pos, rest_len, link, max_strain):
    """|edge strain| ≤ max_strain on every material edge (node positions pos; ``link`` RodData.link)."""
    for j in range(rest_len.shape[0]):
        if link[j] == 0:
            continue
        ex = pos[j + 1, 0] - pos[j, 0]
        ey = pos[j + 1, 1] - pos[j, 1]
        ez = pos[j + 1, 2] - pos[j, 2]
        if not abs(math.sqrt(ex * ex + ey * ey + ez * ez) / rest_len[j] - 1.0) <= max_strain:
            return False
    return True


@njit(**OPT)
def substep_with(e, h, kb, tb, rod, prm, cs, w, want_pen0, midpoint):
    """One (sub)step of size h from w.sub_* by implicit midpoint (``midpoint``) or backward Euler; on success
    w.sub_* hold the new state.

    Returns (status, iterations, converged, ‖f‖ last, ‖f0‖, max penetration [m] at the end of the sub-step,
    max penetration [m] at its start (only if want_pen0)); penetrations are 0 without contact candidates.
    Status MIDPOINT_GAINED: a midpoint step gained energy (nothing committed)."""
    planar = prm.planar
    py = prm.plane_y
    touch = contact.present(prm)
    x, dx, pos, pos0 = w.x, w.dx, w.pos, w.pos0
    x0, u = w.sub_x, w.sub_v
    hs = 0.5 * h if midpoint else h
    # predict: contact candidates over the predicted motion x0 → x0 + hs·u
    pen0 = 0.0
    if touch:
        positions(planar, x0, pos0, py)
        predicted_positions(planar, x0, u, hs, pos, py)
        contact.broadphase(e, prm, rod, cs, pos0, pos)
        if want_pen0:
            pen0 = contact.penetration(e, prm, rod, cs, pos0)
    # newton
    st, it, conv, r, r0 = newton(e, hs, kb, tb, rod, prm, cs, w)
    if st != OK:
        return st, it, False, r, r0, 0.0, pen0
    # refresh: the solve can carry the rod onto pairs the predicted-motion list missed (a control change moves it
    # far from x0 + h u); refresh the lists over the motion actually taken and, if that calls for it, solve again
    # (each implementation says when: sim.contact.stages.refresh). Backward Euler ends where the solve ended: the
    # refreshed lists then cover the whole sub-step motion.
    list_covers_step = False
    if touch:
        positions(planar, x, pos, py)
        added, resolve = contact.refresh(e, prm, rod, cs, pos0, pos)
        list_covers_step = not midpoint and not added
        if resolve:
            st, it2, conv, r, r0 = newton(e, hs, kb, tb, rod, prm, cs, w)
            it += it2
            if st != OK:
                return st, it, False, r, r0, 0.0, pen0
    # accept
    if not conv and not prm.accept_unconverged:
        return UNCONVERGED, it, False, r, r0, 0.0, pen0
    # integrate; end frames and checks
    _integrate(w, rod.fixed, h, hs, midpoint)
    positions(planar, x, pos, py)
    if not planar:
        update_frames(pos, w.sub_d1, w.sub_t, w.sub_beta, w.t, w.d1, w.d2, w.elen, w.beta, rod.link)
    if not _strain_ok(pos, rod.rest_len, rod.link, prm.max_strain):
        return STRAIN, it, conv, r, r0, 0.0, pen0
    for k in range(x.shape[0]):
        if not (np.isfinite(x[k]) and np.isfinite(dx[k])):
            return NON_FINITE, it, conv, r, r0, 0.0, pen0
    if midpoint and prm.midpoint_energy_tol > 0:  # energy at the start (frames sub_*) and at the end (t, d1, beta)
        positions(planar, x0, pos0, py)
        e0, s0 = mech_energy(e, x0, u, w.sub_d1, w.sub_t, w.sub_beta, kb, tb, rod, prm, cs, w, pos0, pos0, h)
        e1, s1 = mech_energy(e, x, dx, w.d1, w.t, w.beta, kb, tb, rod, prm, cs, w, pos, pos0, h)
        if midpoint_gained_energy(e0, s0, e1, s1, prm.midpoint_energy_tol, prm.midpoint_energy_floor):
            return MIDPOINT_GAINED, it, conv, r, r0, 0.0, pen0
    # commit
    if not planar:
        for i in range(w.beta.shape[0]):
            if not np.isfinite(w.beta[i]):
                return NON_FINITE, it, conv, r, r0, 0.0, pen0
        copy_into(w.sub_d1, w.d1)
        copy_into(w.sub_t, w.t)
        copy_into(w.sub_beta, w.beta)
    copy_into(x0, x)
    for k in range(x.shape[0]):
        u[k] = dx[k]
    pen = 0.0
    if touch:  # pos: end of sub-step, pos0: its start; the lists must cover the whole sub-step motion
        if not list_covers_step:
            contact.broadphase(e, prm, rod, cs, pos0, pos)
        pen = contact.penetration(e, prm, rod, cs, pos)
    return OK, it, conv, r, r0, pen, pen0


@njit(**OPT)
def substep(e, h, kb, tb, rod, prm, cs, w, want_pen0):
    """One (sub)step with the scene's integrator; a midpoint step that gains energy (see
    :func:`midpoint_gained_energy`) is redone by backward Euler. Returns what
    :func:`substep_with` does and, last, 1 if the (sub)step was redone by backward Euler, else 0."""
    st, it, conv, r, r0, pen, pen0 = substep_with(e, h, kb, tb, rod, prm, cs, w, want_pen0, prm.midpoint)
    fell = 0
    if st == MIDPOINT_GAINED:
        fell = 1
        st, it2, conv, r, r0, pen, pen0 = substep_with(e, h, kb, tb, rod, prm, cs, w, want_pen0, False)
        it += it2
    return st, it, conv, r, r0, pen, pen0, fell
