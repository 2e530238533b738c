"""The linearisation of recorded steps for their derivatives (sim.analysis.gradients; docs/physics.md §3.9), all
envs of a step in one parallel call.

Per env: the full band of ∂f/∂x' at the step's solution with no DOF constrained. In 3-D the Newton Jacobian of the
bend–twist elements treats the reference directors as moved by zero-twist transport; the step transports them from
the step start, so each element's block in its 9 position columns gains two exact terms per edge (the director's
turn about its tangent, and the curl of zero-twist transport times the element's torque; docs/physics.md §3.9).
The natural curvature and twist enter each element's force affinely, so their columns are the element's own
curvature and twist gradients times −EI/l, −GJ/l (exact), kept by element. With friction (``Wanted.start``) the
position columns come from central differences of the whole residual instead, grouped so that one pair of
residual evaluations gives 2·kl + 1 columns at once (columns 2·kl + 1 apart touch disjoint rows of the band): the
lagged normal and closest point turn with them too. In 2-D the band is exact and the curvature columns are
residual differences (a unit change, nodes three apart in one evaluation: their elements share no row). The
stiffness and mass factors' columns: a second rod record with the factor doubled. With obstacle contact, the
candidates of each env over its step's motion (start to solution) are listed first, so its residual and band
carry the contact the step's solution felt. A workspace per chunk of envs: an analysis path, not the step's.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import get_num_threads, njit, prange

from sim.contact import stages as contact
from sim.energies.bend_twist import bend_twist_core
from sim.geometry.frames import transport
from sim.geometry.vec3 import vcross, vdot, vmul, vnorm, vsub
from sim.kernels.banded import band_lu_apply, band_lu_apply_transposed, band_lu_factor
from sim.kernels.data import KL_2D, KL_3D, env_rod
from sim.kernels.newton import assemble, positions
from sim.kernels.workspace import alloc_workspace, copy_into
from sim.numba_options import OPT_ALLOC

__all__ = ["ELEMENT_ROWS", "RodFactors", "Wanted", "Linearisation", "linearise_step", "factor_bands", "solve_bands"]


ELEMENT_ROWS = {False: 11, True: 6}  # rows of one element's curvature columns, 3-D (False) and 2-D (True) by planar


class RodFactors(NamedTuple):
    """The rod record and three copies with one factor doubled, for the columns of the residual's dependence on
    that factor: the stretching and bending stiffness (``stiffer``), the twisting stiffness (``twist_stiffer``) and
    the mass (``heavier``)."""

    rod: object
    stiffer: object
    twist_stiffer: object
    heavier: object


class Wanted(NamedTuple):
    """Which columns besides the band :func:`linearise_step` computes; ``start``: the band of the residual's
    dependence on the step's start positions (friction's slip velocity; the band of ∂f/∂x' then comes from
    differences too: the Newton Jacobian leaves out how the lagged normal turns)."""

    kappa_bar: bool
    tau_bar: bool
    factors: bool
    start: bool = False
    fd_step: float = 1e-6  # the differences' step, relative to the largest coordinate (at least 1 m)


class Linearisation(NamedTuple):
    """What :func:`linearise_step` writes, per env (leading axis B): ``band`` (B, n + kl, 2 kl + 1) of ∂f/∂x';
    ``kappa_bar`` (B, N, L, 2) ∂f/∂κ̄ by element: entry (i, l, c) is row dpn (i − 1) + l of κ̄_c at node i's column
    (:data:`ELEMENT_ROWS` L rows from the element's first DOF, dpn DOFs per node; the columns of the end nodes 0);
    ``tau_bar`` (B, N, L) ∂f/∂τ̄ alike; ``factors`` (B, n, 3) the columns of the
    doubled stiffness, twisting stiffness and mass; ``start`` (B, n + kl, 2 kl + 1) the band of ∂f/∂x of the
    start's position DOFs (its other columns 0). An array whose columns are not wanted may be a placeholder."""

    band: np.ndarray
    kappa_bar: np.ndarray
    tau_bar: np.ndarray
    factors: np.ndarray
    start: np.ndarray


def linearise_step(start, solution, ctrl, h, rods: RodFactors, prm_arr, cd, wanted: Wanted,
                   out: Linearisation) -> None:
    """For every env of one recorded step — its start ``start`` (a :class:`sim.kernels.data.StateArrays`), its
    solution ``solution`` (B, n) of the residual of step ``h`` (a number, or one per env: (B,)) and the natural
    curvature and twist it ran with ``ctrl`` (a
    :class:`sim.kernels.data.ControlArrays`) — write into ``out`` the band of ∂f/∂x' at the solution and the
    ``wanted`` columns; the factors' columns come from ``rods`` (damping's column is m (x' − x)/h: the caller's).
    ``rods.rod``'s fixed flags must be all 0 (the caller constrains afterwards). The parallel kernel under it takes
    the records' arrays one by one (numba 0.68's parallel lowering fails on these records inside a prange kernel)."""
    hs = np.ascontiguousarray(np.broadcast_to(np.asarray(h, dtype=np.float64), (solution.shape[0],)))
    _linearise_envs(start.dof, start.vel, start.ref_d1, start.tangent, start.ref_twist, solution, ctrl.kappa_bar,
                    ctrl.tau_bar, hs, get_num_threads(), rods.rod, rods.stiffer, rods.twist_stiffer, rods.heavier,
                    prm_arr, cd, wanted.kappa_bar, wanted.tau_bar, wanted.factors, wanted.start, wanted.fd_step, out.band,
                    out.kappa_bar, out.tau_bar, out.factors, out.start)


@njit(**OPT_ALLOC)
def _position_columns(e, x1, kb, tb, h, rod, prm, cs, w, of_start, step, richardson, band, xp, fp, fm):
    """The position columns of ∂f/∂x' (``of_start`` False) or of ∂f/∂x (the step's start, True) into ``band`` by
    central differences of the residual, 2 kl + 1 columns per pair of evaluations (columns that far apart touch
    disjoint rows of the band); with ``richardson`` also at half the step, combined as (4 D(ε/2) − D(ε))/3 (the
    ε² error cancels: friction's law turns over slips of a few µm)."""
    planar = prm.planar
    kl = KL_2D if planar else KL_3D
    n = x1.shape[0]
    base = w.sub_x.copy() if of_start else x1
    scale = 1.0
    for c in range(n):
        if planar or c % 4 != 3:
            scale = max(scale, abs(base[c]))
    stride = 2 * kl + 1
    for level in range(2 if richardson else 1):
        eps = step * scale * (0.5 if level == 1 else 1.0)
        for color in range(stride):
            for sign in (1.0, -1.0):
                copy_into(xp, base)
                for c in range(color, n, stride):
                    if planar or c % 4 != 3:
                        xp[c] += sign * eps
                if of_start:
                    copy_into(w.sub_x, xp)
                    _residual(e, x1, kb, tb, h, rod, prm, cs, w, fp if sign > 0 else fm)
                else:
                    _residual(e, xp, kb, tb, h, rod, prm, cs, w, fp if sign > 0 else fm)
            for c in range(color, n, stride):
                if not (planar or c % 4 != 3):
                    continue
                for r in range(max(0, c - kl), min(n, c + kl + 1)):
                    d = (fp[r] - fm[r]) / (2.0 * eps)
                    band[r, kl + c - r] = d if level == 0 else (4.0 * d - band[r, kl + c - r]) / 3.0
    if of_start:
        copy_into(w.sub_x, base)


@njit(inline="always", **OPT_ALLOC)
def _edge_frame(w, j, a, b):
    """Tangent and reference director of edge j from a to b (3-tuples), transported from the step start (w.sub_d1,
    w.sub_t) as :func:`sim.geometry.frames.update_frames` does."""
    e = vsub(b, a)
    t = vmul(1.0 / vnorm(e), e)
    return t, transport((w.sub_d1[j, 0], w.sub_d1[j, 1], w.sub_d1[j, 2]), (w.sub_t[j, 0], w.sub_t[j, 1], w.sub_t[j, 2]),
                        t)


@njit(**OPT_ALLOC)
def _element_force(xm, xi, xp, te, d1e, tf, d1f, i, trig, x1, kb, tb, rod, w, with_hess):
    """The bend–twist element of interior node i at positions xm, xi, xp with its edges' tangents and transported
    reference directors (te, d1e), (tf, d1f) (:func:`_edge_frame`), its reference twist updated from w.sub_beta as
    :func:`sim.geometry.frames.reference_twist` does, and trig = (cos, sin) of its edges' twist angles: the force
    into w.g11 (its curvature and twist gradients in w.wk[0:3]), the Hessian into w.H11 if ``with_hess``."""
    u = transport(d1e, te, tf)
    dlt = math.atan2(vdot(tf, vcross(u, d1f)), vdot(u, d1f)) - w.sub_beta[i]
    dlt -= 2.0 * math.pi * math.floor((dlt + math.pi) / (2.0 * math.pi))
    beta = w.sub_beta[i] + dlt
    d2e = vcross(te, d1e)
    d2f = vcross(tf, d1f)
    ce, se, cf, sf = trig
    m1e = (ce * d1e[0] + se * d2e[0], ce * d1e[1] + se * d2e[1], ce * d1e[2] + se * d2e[2])
    m2e = (ce * d2e[0] - se * d1e[0], ce * d2e[1] - se * d1e[1], ce * d2e[2] - se * d1e[2])
    m1f = (cf * d1f[0] + sf * d2f[0], cf * d1f[1] + sf * d2f[1], cf * d1f[2] + sf * d2f[2])
    m2f = (cf * d2f[0] - sf * d1f[0], cf * d2f[1] - sf * d1f[1], cf * d2f[2] - sf * d1f[2])
    bend_twist_core(xm, xi, xp, m1e, m2e, m1f, m2f, x1[4 * i + 3] - x1[4 * i - 1] + beta, kb[i, 0], kb[i, 1], tb[i],
                    rod.EI1[i], rod.EI2[i], rod.GJ[i], rod.vor_len[i], w.g11, w.H11, w.wk, with_hess, False)


@njit(inline="always", **OPT_ALLOC)
def _holonomy_rate(w, j, t, length):
    """s with dφ = s·(δx_b − δx_a): the rate at which edge j (from node a to b; unit tangent t, length ``length``)
    turns its time-parallel transported reference director about t as its nodes move. Transported from the start
    tangent t₀, d = P(t₀ → t) d₀ turns, beyond the zero-twist transport the Newton Jacobian assumes, by
    dφ = −(t₀ × t)·δt / (1 + t₀·t) with δt = (I − t tᵀ) δe / |e|, and (t₀ × t) ⟂ t. Zero where the transport keeps
    the director (1 + t₀·t ≤ 1e-12, :func:`sim.geometry.frames.transport`)."""
    t0 = (w.sub_t[j, 0], w.sub_t[j, 1], w.sub_t[j, 2])
    c = vdot(t0, t)
    if 1.0 + c <= 1e-12:
        return (0.0, 0.0, 0.0)
    return vmul(-1.0 / ((1.0 + c) * length), vcross(t0, t))


@njit(inline="always", **OPT_ALLOC)
def _add_edge_turn(band, kl, o, a, b, col, t, length, rate, H, g):
    """Into the element's rows of ``band`` (first DOF o), the position columns of its edge from local node a to b
    (θ column ``col`` of the element's H and g): H[:, col] ∂φ/∂x for the director's turn (``rate``:
    :func:`_holonomy_rate`), and g[col] [t]× / (2 |e|²) on the edge's node blocks, + on (a, a), (b, b), − across:
    the zero-twist transport is not integrable (its turn round a small loop of tangents is the enclosed area), so
    the derivative of the force the frames feed differs from the element's symmetric Hessian by that curl times
    the element's torque g[col]."""
    k = g[col] / (2.0 * length * length)
    for side in range(2):
        node = a if side == 0 else b
        sign = -1.0 if side == 0 else 1.0
        for q in range(3):
            c = 4 * node + q
            dphi = sign * rate[q]
            for r in range(11):
                band[o + r, kl + c - r] += H[r, col] * dphi
            for rn in (a, b):  # (k [t]×)[p, q] on the edge's node blocks
                s = k if rn == node else -k
                for p in range(3):
                    skew = 0.0
                    if p != q:
                        m = 3 - p - q
                        skew = t[m] if (q - p) % 3 == 2 else -t[m]
                    band[o + 4 * rn + p, kl + c - 4 * rn - p] += s * skew


@njit(**OPT_ALLOC)
def _bend_twist_columns(x1, kb, tb, rod, w, positions_too, want_kb, want_tb, band, kb_out, tb_out):
    """Per interior node of a 3-D rod, from its bend–twist element alone: with ``positions_too`` its Newton block in
    its 9 position columns of ``band`` made the exact derivative of its force (:func:`_add_edge_turn` per edge:
    the Newton Jacobian treats the reference directors as moved by zero-twist transport; the step transports them
    from the step start, so they also turn about their tangents, which moves the force as the same change of θ_e,
    θ_f does — the material directors rotate and the reference twist changes by dφ_f − dφ_e); the columns of
    ∂f/∂κ̄ (``kb_out`` (N, 11, 2)) and ∂f/∂τ̄ (``tb_out`` (N, 11)) by element (:class:`Linearisation`) if wanted
    (exact: the force is affine in both)."""
    kl = KL_3D
    N = w.sub_beta.shape[0]
    link = rod.link
    H, wk = w.H11, w.wk
    for i in range(1, N - 1):
        if link[i - 1] == 0 or link[i] == 0:
            continue
        o = 4 * (i - 1)
        xm = (x1[o], x1[o + 1], x1[o + 2])
        xi = (x1[o + 4], x1[o + 5], x1[o + 6])
        xp = (x1[o + 8], x1[o + 9], x1[o + 10])
        trig = (math.cos(x1[o + 3]), math.sin(x1[o + 3]), math.cos(x1[o + 7]), math.sin(x1[o + 7]))
        te, d1e = _edge_frame(w, i - 1, xm, xi)
        tf, d1f = _edge_frame(w, i, xi, xp)
        _element_force(xm, xi, xp, te, d1e, tf, d1f, i, trig, x1, kb, tb, rod, w, positions_too)
        s1 = rod.EI1[i] / rod.vor_len[i]
        s2 = rod.EI2[i] / rod.vor_len[i]
        s3 = rod.GJ[i] / rod.vor_len[i]
        for a in range(11):
            if want_kb:
                kb_out[i, a, 0] = -s1 * wk[0, a]
                kb_out[i, a, 1] = -s2 * wk[1, a]
            if want_tb:
                tb_out[i, a] = -s3 * wk[2, a]
        if not positions_too:
            continue
        le = vnorm(vsub(xi, xm))
        lf = vnorm(vsub(xp, xi))
        _add_edge_turn(band, kl, o, 0, 1, 3, te, le, _holonomy_rate(w, i - 1, te, le), H, w.g11)
        _add_edge_turn(band, kl, o, 1, 2, 7, tf, lf, _holonomy_rate(w, i, tf, lf), H, w.g11)


@njit(**OPT_ALLOC)
def _residual(e, x, kb, tb, h, rod, prm, cs, w, out):
    """out = f(x) of env e from the start state already in w.sub_*."""
    copy_into(w.x, x)
    assemble(prm.planar, e, w.x, h, kb, tb, rod, prm, cs, w, False, False)
    copy_into(out, w.f)


@njit(parallel=True, **OPT_ALLOC)
def _linearise_envs(x0s, u0s, d1s, ts, bs, x1s, kbs, tbs, hs, threads, rod, rod_e, rod_g, rod_m, prm_arr, cd,
                    want_kb, want_tb, want_scalars, want_start, fd_step, ab_out, kb_out, tb_out, sc_out, start_out):
    """For every env e of one recorded step: ab_out[e] (n + kl, 2 kl + 1) the band of ∂f/∂x' at x1s[e];
    kb_out[e] (N, L, 2) ∂f/∂κ̄, tb_out[e] (N, L) ∂f/∂τ̄ by element (:class:`Linearisation`; if wanted); sc_out[e]
    (n, 3) the columns of the factors on stiffness (rod_e), twisting stiffness (rod_g) and mass (rod_m), each
    doubled, if wanted (damping's column is m (x' − x)/h: the caller's); with ``want_start`` start_out[e] the band
    of ∂f/∂x (start positions) and the band's position columns by differences in 2-D too. ``rod``'s fixed flags
    must be all 0 (the caller constrains afterwards)."""
    B = x1s.shape[0]
    n = x1s.shape[1]
    N = bs.shape[1]
    planar = prm_arr[0].planar
    chunks = max(1, min(B, threads))  # a workspace per chunk of envs (one chunk per thread), not per env
    for cp in prange(chunks):
        chunk = np.int64(cp)  # signed: the kernels take min(e, rows − 1) (an unsigned index would turn it float)
        prm = prm_arr[0]  # the parameters record, by reference (read inside the parallel loop, as the step does)
        w = alloc_workspace(N, planar, rod.pairs.shape[0])
        cs = contact.alloc(cd, N, rod.pairs.shape[0])
        f0 = np.empty(n)
        fp = np.empty(n)
        fm = np.empty(n)
        xp = np.empty(n)
        kb1 = np.empty((N, 2))
        for e in range(chunk * B // chunks, (chunk + 1) * B // chunks):
            _linearise_env(e, x0s, u0s, d1s, ts, bs, x1s, kbs, tbs, hs[e], rod, rod_e, rod_g, rod_m, prm, cd, cs, w,
                           want_kb, want_tb, want_scalars, want_start, fd_step, ab_out, kb_out, tb_out, sc_out,
                           start_out, f0, fp, fm, xp, kb1)


@njit(**OPT_ALLOC)
def _linearise_env(e, x0s, u0s, d1s, ts, bs, x1s, kbs, tbs, h, rod, rod_e, rod_g, rod_m, prm, cd, cs, w, want_kb,
                   want_tb, want_scalars, want_start, fd_step, ab_out, kb_out, tb_out, sc_out, start_out, f0, fp, fm,
                   xp, kb1):
    """Env e of :func:`_linearise_envs` with the work space of its chunk."""
    rod, rod_e, rod_g, rod_m = env_rod(rod, e), env_rod(rod_e, e), env_rod(rod_g, e), env_rod(rod_m, e)
    n = x1s.shape[1]
    N = bs.shape[1]
    planar = prm.planar
    copy_into(w.sub_x, x0s[e])
    copy_into(w.sub_v, u0s[e])
    copy_into(w.sub_d1, d1s[e])
    copy_into(w.sub_t, ts[e])
    copy_into(w.sub_beta, bs[e])
    x1 = x1s[e]
    kb = kbs[e]
    tb = tbs[e]
    if contact.present(prm):  # the candidates over the step's motion (obstacle contact)
        positions(planar, x0s[e], w.pos0, prm.plane_y)
        positions(planar, x1, w.pos, prm.plane_y)
        contact.broadphase(e, prm, rod, cs, w.pos0, w.pos)
    copy_into(w.x, x1)
    assemble(planar, e, w.x, h, kb, tb, rod, prm, cs, w, True, False)
    ab = ab_out[e]
    copy_into(ab, w.ab)
    copy_into(f0, w.f)  # the residual at the solution
    if want_start:  # friction: position columns by central differences of the whole residual
        _position_columns(e, x1, kb, tb, h, rod, prm, cs, w, False, fd_step, True, ab, xp, fp, fm)
        _position_columns(e, x1, kb, tb, h, rod, prm, cs, w, True, fd_step, True, start_out[e], xp, fp, fm)
    if not planar:
        _bend_twist_columns(x1, kb, tb, rod, w, not want_start, want_kb, want_tb, ab,
                            kb_out[min(e, kb_out.shape[0] - 1)], tb_out[min(e, tb_out.shape[0] - 1)])
    elif want_kb:  # 2-D: a unit change of κ̄ at nodes three apart per evaluation (their elements share no row)
        for color in range(3):
            copy_into(kb1, kb)
            for i in range(1 + color, N - 1, 3):
                kb1[i, 0] += 1.0
            _residual(e, x1, kb1, tb, h, rod, prm, cs, w, fp)
            for i in range(1 + color, N - 1, 3):
                for r in range(2 * (i - 1), min(n, 2 * (i + 2))):
                    kb_out[e, i, r - 2 * (i - 1), 0] = fp[r] - f0[r]
    if want_scalars:
        _residual(e, x1, kb, tb, h, rod_e, prm, cs, w, fp)
        for r in range(n):
            sc_out[e, r, 0] = fp[r] - f0[r]
        _residual(e, x1, kb, tb, h, rod_g, prm, cs, w, fp)
        for r in range(n):
            sc_out[e, r, 1] = fp[r] - f0[r]
        _residual(e, x1, kb, tb, h, rod_m, prm, cs, w, fp)
        for r in range(n):
            sc_out[e, r, 2] = fp[r] - f0[r]


@njit(parallel=True, **OPT_ALLOC)
def factor_bands(ab, kl, status):
    """LU (no pivoting, :func:`sim.kernels.banded.band_lu_factor`) of every env's padded band ``ab`` (B, n + kl,
    2 kl + 1) in place; ``status`` (B,) 0 or 1 + the first bad pivot. The factors serve solves with A and with Aᵀ
    (:func:`solve_bands`)."""
    n = ab.shape[1] - kl
    for e in prange(ab.shape[0]):
        if kl == KL_3D:  # the width as a constant: the inner loops unroll (sim.kernels.banded)
            status[e] = band_lu_factor(ab[e], n, KL_3D)
        elif kl == KL_2D:
            status[e] = band_lu_factor(ab[e], n, KL_2D)
        else:
            status[e] = band_lu_factor(ab[e], n, kl)


@njit(parallel=True, **OPT_ALLOC)
def solve_bands(lu, kl, transpose, rhs, out):
    """out[e] = A_e⁻¹ rhs[e] (or A_e⁻ᵀ rhs[e] if ``transpose``) for every env from the factors :func:`factor_bands`
    left in ``lu``; rhs, out (B, n, Q)."""
    B, n, Q = rhs.shape
    for e in prange(B):
        b = np.empty(n + kl)
        for q in range(Q):
            for i in range(n):
                b[i] = rhs[e, i, q]
            for i in range(n, n + kl):
                b[i] = 0.0
            _apply(lu[e], n, kl, b, transpose)
            for i in range(n):
                out[e, i, q] = b[i]


@njit(inline="always", **OPT_ALLOC)
def _apply(lu, n, kl, b, transpose):
    """b = A⁻¹ b or A⁻ᵀ b from the factors in ``lu`` (:mod:`sim.kernels.banded`), the usual widths passed as
    constants (their loops unroll)."""
    if kl == KL_3D:
        _apply_width(lu, n, KL_3D, b, transpose)
    elif kl == KL_2D:
        _apply_width(lu, n, KL_2D, b, transpose)
    else:
        _apply_width(lu, n, kl, b, transpose)


@njit(inline="always", **OPT_ALLOC)
def _apply_width(lu, n, kl, b, transpose):
    if transpose:
        band_lu_apply_transposed(lu, n, kl, b)
    else:
        band_lu_apply(lu, n, kl, b)
