"""The step's residual and Jacobian at a given iterate, for analysis outside the step (sim.analysis.gradients)."""
from __future__ import annotations

from numba import njit

from sim.contact import stages as contact
from sim.kernels.newton import assemble
from sim.kernels.workspace import alloc_workspace, copy_into
from sim.numba_options import OPT_ALLOC

__all__ = ["assemble_at"]


@njit(**OPT_ALLOC)
def assemble_at(e, x, x0, u0, d1s, ts, bs, h, kb, tb, rod, prm_arr, cd, f_out, ab_out):
    """Residual f_out (n,) and banded Jacobian ab_out (n + kl, 2 kl + 1) (full band) of env ``e``'s step of size h
    from (x0, u0, frames d1s/ts/bs) at the DOFs x. A workspace per call: an analysis path, not the step's."""
    prm = prm_arr[0]
    N = bs.shape[0]
    w = alloc_workspace(N, prm.planar, rod.pairs.shape[0])
    cs = contact.alloc(cd, N, rod.pairs.shape[0])
    copy_into(w.sub_x, x0)
    copy_into(w.sub_v, u0)
    copy_into(w.sub_d1, d1s)
    copy_into(w.sub_t, ts)
    copy_into(w.sub_beta, bs)
    copy_into(w.x, x)
    assemble(prm.planar, e, w.x, h, kb, tb, rod, prm, cs, w, True, False)
    copy_into(f_out, w.f)
    copy_into(ab_out, w.ab)
