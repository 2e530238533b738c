"""The linearisation of recorded steps for their derivatives (sim.analysis.gradients; docs/physics.md §3.9), all envs of a step
in one parallel call.

Per env: the full band of ∂f/∂x' at the step's solution with no DOF constrained; in 3-D its position columns by
central differences of the residual, grouped so that one pair of residual evaluations gives 2·kl + 1 columns at once
(columns 2·kl + 1 apart touch disjoint rows of the band); the columns of the residual's dependence on the natural
curvature and twist of every node (affine: a unit change, nodes three apart in one evaluation: their elements share
no row) and on the stiffness and mass factors (a second rod record with the factor doubled). With
obstacle contact, the candidates of each env over its step's motion (start to solution) are listed first, so its
residual and band carry the contact the step's solution felt. A workspace per env: an analysis path, not the
step's.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, prange

from sim.contact import stages as contact
from sim.kernels.data import KL_2D, KL_3D
from sim.kernels.newton import assemble, positions
from sim.kernels.workspace import alloc_workspace, copy_into
from sim.numba_options import OPT_ALLOC

__all__ = ["RodFactors", "Wanted", "Linearisation", "linearise_step"]


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
    ``kappa_bar`` (B, n, N, 2) ∂f/∂κ̄; ``tau_bar`` (B, n, N) ∂f/∂τ̄; ``factors`` (B, n, 3) the columns of the
    doubled stiffness, twisting stiffness and mass; ``start`` (B, n + kl, 2 kl + 1) the band of ∂f/∂x of the
    start's position DOFs (its other columns 0). An array whose columns are not wanted may be a placeholder."""

    band: np.ndarray
    kappa_bar: np.ndarray
    tau_bar: np.ndarray
    factors: np.ndarray
    start: np.ndarray


def linearise_step(start, solution, ctrl, h: float, rods: RodFactors, prm_arr, cd, wanted: Wanted,
                   out: Linearisation) -> None:
    """For every env of one recorded step — its start ``start`` (a :class:`sim.kernels.data.StateArrays`), its
    solution ``solution`` (B, n) and the natural curvature and twist it ran with ``ctrl`` (a
    :class:`sim.kernels.data.ControlArrays`) — write into ``out`` the band of ∂f/∂x' at the solution and the
    ``wanted`` columns; the factors' columns come from ``rods`` (damping's column is m (x' − x)/h: the caller's).
    ``rods.rod``'s fixed flags must be all 0 (the caller constrains afterwards). The parallel kernel under it takes
    the records' arrays one by one (numba 0.68's parallel lowering fails on these records inside a prange kernel)."""
    _linearise_envs(start.dof, start.vel, start.ref_d1, start.tangent, start.ref_twist, solution, ctrl.kappa_bar,
                    ctrl.tau_bar, h, rods.rod, rods.stiffer, rods.twist_stiffer, rods.heavier, prm_arr, cd,
                    wanted.kappa_bar, wanted.tau_bar, wanted.factors, wanted.start, wanted.fd_step, out.band,
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


@njit(**OPT_ALLOC)
def _residual(e, x, kb, tb, h, rod, prm, cs, w, out):
    """out = f(x) of env e from the start state already in w.sub_*."""
    copy_into(w.x, x)
    assemble(prm.planar, e, w.x, h, kb, tb, rod, prm, cs, w, False, False)
    copy_into(out, w.f)


@njit(parallel=True, **OPT_ALLOC)
def _linearise_envs(x0s, u0s, d1s, ts, bs, x1s, kbs, tbs, h, rod, rod_e, rod_g, rod_m, prm_arr, cd,
                    want_kb, want_tb, want_scalars, want_start, fd_step, ab_out, kb_out, tb_out, sc_out, start_out):
    """For every env e of one recorded step: ab_out[e] (n + kl, 2 kl + 1) the band of ∂f/∂x' at x1s[e];
    kb_out[e] (n, N, 2) ∂f/∂κ̄, tb_out[e] (n, N) ∂f/∂τ̄ (if wanted); sc_out[e] (n, 3) the columns of the
    factors on stiffness (rod_e), twisting stiffness (rod_g) and mass (rod_m), each doubled, if wanted (damping's
    column is m (x' − x)/h: the caller's); with ``want_start`` start_out[e] the band of ∂f/∂x (start positions)
    and the band's position columns by differences in 2-D too. ``rod``'s fixed flags must be all 0 (the caller
    constrains afterwards)."""
    B = x1s.shape[0]
    n = x1s.shape[1]
    N = bs.shape[1]
    planar = prm_arr[0].planar
    dpn = 2 if planar else 4
    for ep in prange(B):
        e = np.int64(ep)  # a signed index: the kernels take min(e, rows - 1) (an unsigned one would turn it float)
        prm = prm_arr[0]  # the parameters record, by reference (read inside the parallel loop, as the step does)
        w = alloc_workspace(N, planar, rod.pairs.shape[0])
        cs = contact.alloc(cd, N, rod.pairs.shape[0])
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
        f0 = w.xt.copy()
        _residual(e, x1, kb, tb, h, rod, prm, cs, w, f0)
        fp = f0.copy()
        fm = f0.copy()
        xp = x1.copy()
        if want_start or not planar:  # position columns by central differences
            _position_columns(e, x1, kb, tb, h, rod, prm, cs, w, False, fd_step, want_start, ab, xp, fp, fm)
        if want_start:
            _position_columns(e, x1, kb, tb, h, rod, prm, cs, w, True, fd_step, True, start_out[e], xp, fp, fm)
        if want_kb or want_tb:
            kb1 = kb.copy()
            tb1 = tb.copy()
            ncomp = 1 if planar else 2
            for color in range(3):
                for comp in range(ncomp + (1 if want_tb and not planar else 0)):
                    if comp < ncomp and not want_kb:
                        continue
                    copy_into(kb1, kb)
                    copy_into(tb1, tb)
                    for i in range(1 + color, N - 1, 3):
                        if comp < ncomp:
                            kb1[i, comp] += 1.0
                        else:
                            tb1[i] += 1.0
                    _residual(e, x1, kb1, tb1, h, rod, prm, cs, w, fp)
                    for i in range(1 + color, N - 1, 3):
                        lo = dpn * (i - 1)
                        hi = min(n, dpn * (i + 2))
                        for r in range(lo, hi):
                            d = fp[r] - f0[r]
                            if comp < ncomp:
                                kb_out[e, r, i, comp] = d
                            else:
                                tb_out[e, r, i] = d
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
