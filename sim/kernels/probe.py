"""The step's residual and Jacobian at a given iterate, for analysis outside the step (sim.analysis.gradients): the
whole residual (:func:`assemble_at`), the edge pairs' part alone with its derivatives (:func:`pair_linearisation`,
:func:`pair_residual`), and the sub-steps of a step the retry ladder split (:func:`substeps_at`)."""
from __future__ import annotations

import numpy as np
from numba import njit

from sim.contact import edge_pairs
from sim.contact import stages as contact
from sim.kernels.data import OK, env_rod
from sim.kernels.newton import assemble, positions, substep
from sim.kernels.workspace import alloc_workspace, copy_into
from sim.numba_options import OPT_ALLOC

__all__ = ["assemble_at", "pair_linearisation", "pair_residual", "substeps_at"]


@njit(**OPT_ALLOC)
def _work_from(prm, rod, cd, x0, u0, d1s, ts, bs):
    """A work space and contact sets of their own (an analysis path, not the step's) holding the (sub)step start
    state (x0, u0, frames d1s/ts/bs)."""
    N = bs.shape[0]
    w = alloc_workspace(N, prm.planar, rod.pairs.shape[0])
    cs = contact.alloc(cd, N, rod.pairs.shape[0])
    copy_into(w.sub_x, x0)
    copy_into(w.sub_v, u0)
    copy_into(w.sub_d1, d1s)
    copy_into(w.sub_t, ts)
    copy_into(w.sub_beta, bs)
    return w, cs


@njit(**OPT_ALLOC)
def assemble_at(e, x, x0, u0, d1s, ts, bs, h, kb, tb, rod, prm_arr, cd, f_out, ab_out):
    """Residual f_out (n,) and banded Jacobian ab_out (n + kl, 2 kl + 1) (full band) of env ``e``'s step of size h
    from (x0, u0, frames d1s/ts/bs) at the DOFs x (:func:`_work_from`)."""
    prm = prm_arr[0]
    rod = env_rod(rod, e)
    w, cs = _work_from(prm, rod, cd, x0, u0, d1s, ts, bs)
    copy_into(w.x, x)
    assemble(prm.planar, e, w.x, h, kb, tb, rod, prm, cs, w, True, False)
    copy_into(f_out, w.f)
    copy_into(ab_out, w.ab)


@njit(**OPT_ALLOC)
def _pair_forces(ep, prm, rod, pos, pos0, h, w, out):
    """out (n,) = the residual of the candidate pairs of ``ep`` at node positions ``pos`` from ``pos0`` over h."""
    for r in range(w.f.shape[0]):
        w.f[r] = 0.0
    edge_pairs.add_forces(ep, rod.pairs, rod.pair_links, prm, pos, pos0, h, 2 if prm.planar else 4, rod.fixed,
                          rod.edge_radius, w, False, False)
    for r in range(out.shape[0]):
        out[r] = w.f[r]


@njit(**OPT_ALLOC)
def _pairs_at(prm, rod, x, x0, h, f_out):
    """The candidate pairs at the DOFs ``x`` (a fresh list) and their residual from ``x0`` over h into ``f_out``:
    returns (work space, pair contact, node positions at x, at x0)."""
    planar = prm.planar
    N = x.shape[0] // (2 if planar else 4)
    P = rod.pairs.shape[0]
    w = alloc_workspace(N, planar, P)
    ep = edge_pairs.alloc(N, P)
    pos = np.empty((N, 3))
    pos0 = np.empty((N, 3))
    positions(planar, x, pos, prm.plane_y)
    positions(planar, x0, pos0, prm.plane_y)
    edge_pairs.find_candidates(ep, rod.pairs, pos, pos, rod.edge_radius, prm.contact_margin)
    _pair_forces(ep, prm, rod, pos, pos0, h, w, f_out)
    return w, ep, pos, pos0


@njit(**OPT_ALLOC)
def pair_linearisation(prm_arr, rod, x, x0, h, step, richardson, of_start, dofs, cols, start_cols):
    """The derivatives of the residual of the edge pairs alone at the DOFs ``x`` (n,) of a step of size h from
    ``x0`` (its slip velocity (x − x0)/h), over the candidate pairs at ``x`` (a fresh list: with the contact margin
    ≥ δ every pair the step's solution felt, and each pair's terms as there), with respect to the position DOFs of
    the nodes of the pairs within reach (gap < δ), constrained ones too (a change of them is carried: the caller
    sets their columns apart): their indices into ``dofs`` (returns their count s), the columns ∂f/∂x' into
    ``cols[:, :s]`` (n, ≥ s) and with ``of_start`` ∂f/∂x (the start's positions) into ``start_cols[:, :s]``.
    Central differences of step ε = ``step`` times the largest coordinate (at least 1 m); with ``richardson`` also
    at ε/2, combined as (4 D(ε/2) − D(ε))/3."""
    prm = prm_arr[0]
    planar = prm.planar
    dpn = 2 if planar else 4
    n = x.shape[0]
    N = n // dpn
    fp = np.empty(n)
    fm = np.empty(n)
    w, ep, pos, pos0 = _pairs_at(prm, rod, x, x0, h, fp)
    near = np.zeros(N, np.bool_)
    for m in range(ep.count[0]):
        c = ep.cand[m]
        i = rod.pairs[c, 0]
        j = rod.pairs[c, 1]
        if edge_pairs.pair_gap(pos, rod.edge_radius, i, j) < prm.contact_delta:
            near[i] = True
            near[i + 1] = True
            near[j] = True
            near[j + 1] = True
    scale = 1.0
    for k in range(N):
        for a in range(3):
            scale = max(scale, abs(pos[k, a]), abs(pos0[k, a]))
    s = 0
    for k in range(N):
        if not near[k]:
            continue
        for a in range(3):
            if planar and a == 1:
                continue
            d = dpn * k + (a if not planar else a // 2)
            dofs[s] = d
            for which in range(2 if of_start else 1):
                arr = pos if which == 0 else pos0
                out = cols if which == 0 else start_cols
                v = arr[k, a]
                for level in range(2 if richardson else 1):
                    eps = step * scale * (0.5 if level == 1 else 1.0)
                    arr[k, a] = v + eps
                    _pair_forces(ep, prm, rod, pos, pos0, h, w, fp)
                    arr[k, a] = v - eps
                    _pair_forces(ep, prm, rod, pos, pos0, h, w, fm)
                    arr[k, a] = v
                    for r in range(n):
                        dr = (fp[r] - fm[r]) / (2.0 * eps)
                        out[r, s] = dr if level == 0 else (4.0 * dr - out[r, s]) / 3.0
            s += 1
    return s


@njit(**OPT_ALLOC)
def pair_residual(prm_arr, rod, x, x0, h, f_out):
    """The residual of the edge pairs alone at the DOFs ``x`` of a step of size h from ``x0`` into ``f_out`` (n,),
    over the candidate pairs at ``x`` (as :func:`pair_linearisation`)."""
    _pairs_at(prm_arr[0], rod, x, x0, h, f_out)


@njit(**OPT_ALLOC)
def substeps_at(e, x, v, d1, t, beta, kb, tb, ns, rod, prm_arr, cd, xs, vs, d1s, ts, bs, fell):
    """Env ``e``'s step taken as ``ns`` sub-steps of prm.dt / ns from the state (x, v, d1, t, beta), as the retry
    ladder's level of ns sub-steps takes them (:func:`sim.kernels.ladder.env_step`): the state before each sub-step
    and after the last into xs, vs (ns + 1, n), d1s, ts (ns + 1, E, 3), bs (ns + 1, N), and into fell (ns,) 1 where a
    midpoint sub-step was redone by backward Euler. Returns how many sub-steps succeeded (ns: all)."""
    prm = prm_arr[0]
    rod = env_rod(rod, e)
    w, cs = _work_from(prm, rod, cd, x, v, d1, t, beta)
    h = prm.dt / ns
    for s in range(ns + 1):
        copy_into(xs[s], w.sub_x)
        copy_into(vs[s], w.sub_v)
        copy_into(d1s[s], w.sub_d1)
        copy_into(ts[s], w.sub_t)
        copy_into(bs[s], w.sub_beta)
        if s == ns:
            break
        st, it, conv, r, r0, pen, pen0, f = substep(e, h, kb, tb, rod, prm, cs, w, False)
        if st != OK:
            return s
        fell[s] = f
    return ns
