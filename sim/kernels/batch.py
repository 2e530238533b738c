"""The batched step kernel :func:`step_kernel`: a ``prange`` over chunks of envs, one
:class:`sim.kernels.workspace.Workspace` per chunk, each env advanced by :func:`sim.kernels.ladder.env_step`. Env e
only reads and writes row e, so a batch gives the same bits as the envs alone.
"""
from __future__ import annotations

from numba import njit, prange

from sim.contact import stages as contact
from sim.kernels.data import env_rod
from sim.kernels.ladder import env_step
from sim.kernels.workspace import alloc_workspace
from sim.numba_options import OPT, OPT_ALLOC

__all__ = ["step_kernel"]

# envs per workspace allocation in the step kernel's parallel loop
CHUNK = 8


@njit(**OPT)
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


@njit(parallel=True, nogil=True, **OPT_ALLOC)  # nogil: other Python threads (e.g. SAC updates) run meanwhile
def step_kernel(state, ctl, rod, prm_arr, cd, crep, out):
    """Advance all non-failed envs of ``state`` (:class:`sim.kernels.data.StateArrays`, dof/vel (B, n)) by
    prm.dt under ``ctl`` (:class:`sim.kernels.data.ControlArrays`) with the rod ``rod``
    (:class:`sim.kernels.data.RodData`), the parameters ``prm_arr`` (:meth:`sim.kernels.data.Params.record`) and
    the obstacles ``cd`` (:class:`sim.contact.world.ContactData`, joined per chunk of envs with the contact
    implementations' scratch into a :class:`sim.contact.ContactSets`); per-env results into ``out``
    (:class:`sim.kernels.data.StepOutput`) and the contact rows ``crep`` (:class:`sim.kernels.data.ContactReport`)."""
    dof, vel, ref_d1, tangent, ref_twist = state.dof, state.vel, state.ref_d1, state.tangent, state.ref_twist
    times, failed = state.time, state.failed  # unpacked before the parallel loop: writes must reach the caller's arrays
    kappa_bar, tau_bar = ctl.kappa_bar, ctl.tau_bar
    B = dof.shape[0]
    N = ref_twist.shape[1]
    nch = (B + CHUNK - 1) // CHUNK
    for chunk in prange(nch):  # workspaces are allocated once per chunk of envs, not per env-step
        prm = prm_arr[0]  # the parameters record, by reference
        w = alloc_workspace(N, prm.planar, rod.pairs.shape[0])
        cs = contact.alloc(cd, N, rod.pairs.shape[0])
        for e in range(chunk * CHUNK, min(B, chunk * CHUNK + CHUNK)):
            _clear_outputs(out, e)
            if failed[e]:
                continue
            ok = env_step(e, dof[e], vel[e], ref_d1[e], tangent[e], ref_twist[e], kappa_bar[e], tau_bar[e],
                          env_rod(rod, e), prm, cs, crep, out, w)
            if ok:
                times[e] += prm.dt
            else:
                failed[e] = True
