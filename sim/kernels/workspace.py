"""One thread's scratch for a step (:class:`Workspace`, allocated per chunk of envs by :func:`alloc_workspace`) and
:func:`copy_into`, the allocation-free array copy the kernels use.

Fields: Newton iterate x, residual f, update dx, line search trial xt, banded Jacobian ab; node positions pos/pos0
(N, 3) and a node update dpos (N, 3); frame scratch t, d1, d2 (N-1, 3), elen (N-1,), beta (N,); element
gradients/Hessians g4/H4 (2-D stretch), g6/H6 (3-D stretch, 2-D bend), g11/H11/wk (3-D bend-twist); material
directors mf (N-1, 6); the (sub)step start state sub_* and the guard fallback state fb_* (DOFs, velocities, frames);
the Jacobian's coupling outside the band ``coupling`` (:class:`sim.contact.edge_pairs.Coupling`, empty without edge
pairs). Every entry is written before it is read, so nothing carries over from one env to the next. The contact
implementations' own scratch is in their records (:mod:`sim.contact.stages`).
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from sim.contact.edge_pairs import alloc_coupling
from sim.kernels.data import KL_2D, KL_3D
from sim.numba_options import OPT, OPT_ALLOC

__all__ = ["Workspace", "alloc_workspace", "copy_into"]

Workspace = namedtuple("Workspace", [
    "x", "f", "dx", "xt", "ab", "pos", "pos0", "t", "d1", "d2", "elen", "beta", "g4", "H4", "g6", "H6", "g11",
    "H11", "wk", "dpos", "mf", "sub_x", "sub_v", "sub_d1", "sub_t", "sub_beta", "fb_x", "fb_v", "fb_d1", "fb_t",
    "fb_beta", "coupling",
])


@njit(**OPT_ALLOC)
def alloc_workspace(N, planar, P):
    """A :class:`Workspace` for a rod of N nodes with P edge pairs that may touch (one per thread and chunk of
    envs; the coupling list is empty when P = 0)."""
    dpn = 2 if planar else 4
    kl = KL_2D if planar else KL_3D
    n = dpn * N
    K = (2 if planar else 3) * N if P > 0 else 0
    return Workspace(
        x=np.empty(n), f=np.empty(n), dx=np.zeros(n + kl), xt=np.empty(n), ab=np.empty((n + kl, 2 * kl + 1)),
        pos=np.empty((N, 3)), pos0=np.empty((N, 3)), t=np.empty((N - 1, 3)), d1=np.empty((N - 1, 3)),
        d2=np.empty((N - 1, 3)), elen=np.empty(N - 1), beta=np.empty(N), g4=np.empty(4), H4=np.empty((4, 4)),
        g6=np.empty(6), H6=np.empty((6, 6)), g11=np.empty(11), H11=np.empty((11, 11)), wk=np.empty((17, 11)),
        dpos=np.zeros((N, 3)), mf=np.empty((N - 1, 6)),
        sub_x=np.empty(n), sub_v=np.empty(n), sub_d1=np.empty((N - 1, 3)), sub_t=np.empty((N - 1, 3)),
        sub_beta=np.empty(N), fb_x=np.empty(n), fb_v=np.empty(n), fb_d1=np.empty((N - 1, 3)),
        fb_t=np.empty((N - 1, 3)), fb_beta=np.empty(N), coupling=alloc_coupling(n, K, kl))


@njit(inline="always", **OPT)
def copy_into(dst, src):
    """dst[...] = src, element by element, for C-contiguous arrays of one size (no temporary, no reference
    counting)."""
    d = dst.reshape(dst.size)
    s = src.reshape(src.size)
    for i in range(d.shape[0]):
        d[i] = s[i]
