"""The static Hessian of one env at its stored state (docs/physics.md §3.8): the Jacobian of the step's residual
with the inertia term removed (a pseudo-time step of 1e150 s), assembled by the step's own element functions at the
transport base (the state's frames), where the bending and twisting Hessians are exact (§2.4).

Used once per static solve (not per step), so it may allocate: one Workspace per call.
"""
from __future__ import annotations

from numba import njit

from sim.contact import stages as contact
from sim.kernels.data import KL_2D, KL_3D, env_rod
from sim.kernels.newton import assemble, positions
from sim.kernels.workspace import alloc_workspace, copy_into
from sim.numba_options import OPT_ALLOC

__all__ = ["static_jacobian"]

_H_STATIC = 1e150  # [s] pseudo-time step of the assembly: M/h² is below any float's resolution of the stiffness


@njit(**OPT_ALLOC)
def static_jacobian(e, x, d1, t, beta, kb, tb, rod, prm_arr, cd):
    """The full band (n + kl, 2 kl + 1) of the static Jacobian of env e (row r, column c at [r, kl + c − r];
    constrained DOFs: identity rows and columns) at DOFs x (n,) with the stored frames d1, t, beta, and the
    off-band coupling of touching edge pairs: the DOFs (K,) and their dense block (K, K) (K = 0 without).
    ``prm_arr``: the Simulator's one-record parameter array (:meth:`sim.kernels.data.Params.record`)."""
    prm = prm_arr[0]
    rod = env_rod(rod, e)
    planar = prm.planar
    n = x.shape[0]
    N = rod.vor_len.shape[0]
    kl = KL_2D if planar else KL_3D
    w = alloc_workspace(N, planar, rod.pairs.shape[0])
    cs = contact.alloc(cd, N, rod.pairs.shape[0])
    copy_into(w.sub_x, x)
    copy_into(w.x, x)
    for k in range(n):
        w.sub_v[k] = 0.0
    copy_into(w.sub_d1, d1)
    copy_into(w.sub_t, t)
    copy_into(w.sub_beta, beta)
    if contact.present(prm):
        positions(planar, x, w.pos, prm.plane_y)
        positions(planar, x, w.pos0, prm.plane_y)
        contact.broadphase(e, prm, rod, cs, w.pos0, w.pos)
    assemble(planar, e, w.x, _H_STATIC, kb, tb, rod, prm, cs, w, True, False)
    cp = w.coupling
    K = cp.count[0]
    return w.ab[:n + kl].copy(), cp.dof[:K].copy(), cp.M[:K, :K].copy()
