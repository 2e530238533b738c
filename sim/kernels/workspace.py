"""One thread's scratch for a step (:class:`Workspace`, allocated per chunk of envs by :func:`alloc_workspace`) and
:func:`copy_into`, the allocation-free array copy the kernels use.

Fields: Newton iterate x, residual f, update dx, line search trial xt, banded Jacobian ab; node positions pos/pos0
(N, 3); frame scratch t, d1, d2 (N-1, 3), elen (N-1,), beta (N,); element gradients/Hessians g4/H4 (2-D stretch),
g6/H6 (3-D stretch, 2-D bend), g11/H11/wk (3-D bend-twist); contact gradient cg (N, 3) and per-edge Hessians ch
(N-1, 6, 6); material directors mf (N-1, 6); the (sub)step start state sub_* and the guard fallback state fb_*
(DOFs, velocities, frames). Every entry is written before it is read, so nothing carries over from one env to the
next. Edge pairs (sim.contact_rod; sized 0 without them): candidate pair indices rp_cand (P,) and their count rp_n
(1,), edge boxes rp_box (N-1, 6), pair derivatives g12 (12,), H12 (12, 12), normal n12 (3,), scratch ws12 (32,);
the Jacobian's coupling outside the band: DOF -> list slot wb_slot (n,) (-1: not listed), listed DOFs wb_dof (K,)
and their count wb_n (1,), coupling matrix wb_M (K, K), B⁻¹ columns wb_Z (K, n + kl), capacitance wb_C (K, K),
its right-hand side wb_r (K,) and pivots wb_piv (K,); K = 3N (3-D) or 2N (planar) position DOFs.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from sim.numba_options import OPT, OPT_ALLOC

from .data import KL_2D, KL_3D

__all__ = ["Workspace", "alloc_workspace", "copy_into"]

Workspace = namedtuple("Workspace", [
    "x", "f", "dx", "xt", "ab", "pos", "pos0", "t", "d1", "d2", "elen", "beta", "g4", "H4", "g6", "H6", "g11",
    "H11", "wk", "cg", "ch", "mf", "sub_x", "sub_v", "sub_d1", "sub_t", "sub_beta", "fb_x", "fb_v", "fb_d1",
    "fb_t", "fb_beta", "rp_cand", "rp_n", "rp_box", "g12", "H12", "n12", "ws12", "wb_slot", "wb_dof", "wb_n",
    "wb_M", "wb_Z", "wb_C", "wb_r", "wb_piv",
])


@njit(**OPT_ALLOC)
def alloc_workspace(N, planar, P):
    """A :class:`Workspace` for a rod of N nodes with P edge pairs that may touch (one per thread and chunk of
    envs; the edge-pair fields are empty when P = 0)."""
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


@njit(inline="always", **OPT)
def copy_into(dst, src):
    """dst[...] = src, element by element, for C-contiguous arrays of one size (no temporary, no reference
    counting)."""
    d = dst.reshape(dst.size)
    s = src.reshape(src.size)
    for i in range(d.shape[0]):
        d[i] = s[i]
