"""The solver's named parameters (:class:`Params`, read as ``prm``), per-env output columns, numba options and
the small decisions both step kernels share (symmetric Jacobian? how badly does a retry level trip the guards?).

Shared by :mod:`sim.newton` (the step), :mod:`sim.solve_3d`, :mod:`sim.solve_2d` (the element assembly) and the
:class:`sim.Simulator` that builds ``prm``.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

# The solver's scalar parameters by name: a namedtuple of float64 (flags 0.0/1.0, planar 1.0 for the 2-D model;
# line_search 0 none, 1 backtrack, 2 auto), built once by the Simulator from the Model. Units: dt [s],
# damping [1/s], newton_dtol [m/s], contact_delta/contact_margin/max_penetration/plane_y [m],
# contact_k [N/m], friction_nu [m/s]; the rest dimensionless. rod_pairs: 1.0 when edges of rods may touch each other
# (self- or rod–rod contact on and allowed pairs exist, sim/contact_rod.py; they use contact_k, contact_delta,
# contact_margin and the [contact] friction μ = friction).
Params = namedtuple("Params", [
    "dt", "damping", "newton_tol", "newton_dtol", "newton_max_iter", "accept_unconverged",
    "midpoint", "line_search", "contact_k", "contact_delta", "friction", "friction_nu", "friction_on",
    "contact_margin", "n_obstacles", "planar_sign", "plane_y", "retry_levels", "max_strain", "max_penetration",
    "step_limit", "divergence_guard", "midpoint_energy_tol", "planar", "rod_pairs",
])
# The kernels receive the parameters as one record of this structured dtype (same names, read as prm.EA ...):
# numba passes a record by reference, where a namedtuple of 28 floats is copied into every call.
PARAMS_DTYPE = np.dtype([(name, np.float64) for name in Params._fields])


def params_record(p: Params) -> np.ndarray:
    """The kernels' form of ``p``: a one-element array of float64 records with the fields of :class:`Params`
    (the kernels read ``prm = prm_arr[0]`` once per chunk of envs)."""
    arr = np.zeros(1, dtype=PARAMS_DTYPE)
    for name, v in zip(Params._fields, p):
        arr[0][name] = float(v)
    return arr


# the per-env contact rows the step kernels write for StepStats (leading axis B; C = report capacity):
# count (B,), edge/obstacle/partner (B, C) int64, rod_point/obstacle_point/normal/friction_force (B, C, 3),
# normal_force/gap (B, C), max_penetration (B,); obstacle rows first, then two rows per edge pair in touch
ContactReport = namedtuple("ContactReport", [
    "count", "edge", "obstacle", "partner", "rod_point", "obstacle_point", "normal", "normal_force", "friction_force", "gap",
    "max_penetration",
])
# what the step kernel writes per env for StepStats (all (B,)): the last and first residual ‖f‖ of the step,
# the energies [J] at its end, Newton iterations (total over sub-steps), sub-steps per step of the level
# accepted (1 = no retry), how many of those sub-steps the implicit midpoint rule redid by backward Euler (0 with
# backward Euler), whether every sub-step converged, whether the env failed in this step
StepOutput = namedtuple("StepOutput", [
    "residual", "residual0", "energy_stretch", "energy_bend", "energy_twist", "energy_contact", "energy_kinetic",
    "energy_gravity", "newton_iters", "substeps", "midpoint_fallbacks", "converged", "failed",
])
# the rod's constant per-edge / per-node / per-DOF arrays (docs/physics.md §1.2): rest edge lengths (N-1,),
# Voronoi lengths (N,), DOF masses, fixed-DOF flags (n,) of one env, and the external forces grav (gravity plus
# point loads): (1, n) shared by all envs, or (B, n) per env when time-windowed loads act (row min(e, rows - 1));
# the stiffnesses: EA [N] per edge (N-1,), EI1/EI2/GJ [N m²] per node (N,) (an interior node: the length-weighted
# mean of its two edges' compliances; docs/physics.md §1.5). The planar rod reads its in-plane bending stiffness
# from EI1. radius [m]: (1,) for a rod of one radius, else (N-1,) per edge (sim.contact_kernels). link (N-1,)
# uint8: 1 for a material edge, 0 for a joint edge between two rods of a scene (docs/physics.md §1.7): no
# stretching, no bending or twisting at its two nodes, no contact, its frame carried along unchanged. pairs (P, 2)
# int64: the edge pairs that may touch (sim.contact_rod.allowed_pairs; (0, 2) without self- or rod–rod contact).
RodData = namedtuple("RodData", ["rest_len", "vor_len", "mass", "fixed", "grav", "EA", "EI1", "EI2", "GJ", "radius",
                                 "link", "pairs"])
# the batched state the kernel advances in place (leading axis B): DOFs and their velocities (B, n), the stored
# reference frames (B, N-1, 3) and reference twist (B, N), time (B,), failed flags (B,)
StateArrays = namedtuple("StateArrays", ["dof", "vel", "ref_d1", "tangent", "ref_twist", "time", "failed"])
# the per-env natural curvature (B, N, 2) and twist (B, N) the step reads (twist unused in 2-D)
ControlArrays = namedtuple("ControlArrays", ["kappa_bar", "tau_bar"])
# One thread's scratch for a step (sim.newton.alloc_workspace): Newton iterate x, residual f, update dx, line
# search trial xt, banded Jacobian ab; node positions pos/pos0 (N, 3); frame scratch t, d1, d2 (N-1, 3), elen
# (N-1,), beta (N,); element gradients/Hessians g4/H4 (2-D stretch), g6/H6 (3-D stretch, 2-D bend), g11/H11/wk
# (3-D bend-twist); contact gradient cg (N, 3) and per-edge Hessians ch (N-1, 6, 6); material directors mf
# (N-1, 6); the (sub)step start state sub_* and the guard fallback state fb_* (DOFs, velocities, frames). Every
# entry is written before it is read, so nothing carries over from one env to the next.
# Edge pairs (sim.contact_rod; sized 0 without them): candidate pair indices rp_cand (P,) and their count rp_n (1,),
# edge boxes rp_box (N-1, 6), pair derivatives g12 (12,), H12 (12, 12), normal n12 (3,), scratch ws12 (32,); the
# Jacobian's coupling outside the band: DOF -> list slot wb_slot (n,) (-1: not listed), listed DOFs wb_dof (K,) and
# their count wb_n (1,), coupling matrix wb_M (K, K), B⁻¹ columns wb_Z (K, n + kl), capacitance wb_C (K, K), its
# right-hand side wb_r (K,) and pivots wb_piv (K,); K = 3N (3-D) or 2N (planar) position DOFs.
Workspace = namedtuple("Workspace", [
    "x", "f", "dx", "xt", "ab", "pos", "pos0", "t", "d1", "d2", "elen", "beta", "g4", "H4", "g6", "H6", "g11",
    "H11", "wk", "cg", "ch", "mf", "sub_x", "sub_v", "sub_d1", "sub_t", "sub_beta", "fb_x", "fb_v", "fb_d1",
    "fb_t", "fb_beta", "rp_cand", "rp_n", "rp_box", "g12", "H12", "n12", "ws12", "wb_slot", "wb_dof", "wb_n",
    "wb_M", "wb_Z", "wb_C", "wb_r", "wb_piv",
])

# (sub)step status codes of sim.newton
OK, NON_FINITE, RESIDUAL_GROWTH, BAD_PIVOT, UNCONVERGED, STRAIN, MIDPOINT_GAINED = range(7)

# envs per workspace allocation in the step kernels' parallel loop
_CHUNK = 8

# numba options of the step's kernels. They allocate nothing (all scratch is in the Workspace), so they are compiled
# without the runtime's reference counting (_nrt=False): its atomic increments and decrements on every array passed
# down the call chain, on arrays that both threads share, cost about a fifth of a step. A kernel that tried to
# allocate would not compile. _OPT_ALLOC: the few functions that allocate (the workspace, the parallel driver).
_OPT_ALLOC = dict(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"})
_OPT = dict(_OPT_ALLOC, _nrt=False)
# the contact kernels: the same without fastmath (their results are compared bit for bit with references)
_OPT_CONTACT = dict(cache=True, _nrt=False)


@njit(inline="always", **_OPT)
def copy_into(dst, src):
    """dst[...] = src, element by element, for C-contiguous arrays of one size (no temporary, no reference
    counting)."""
    d = dst.reshape(dst.size)
    s = src.reshape(src.size)
    for i in range(d.shape[0]):
        d[i] = s[i]


@njit(inline="always", **_OPT)
def jacobian_symmetric(prm):
    """Whether the Newton Jacobian is symmetric: yes unless friction acts (obstacles or edge pairs present and
    μ > 0); the
    kernels then assemble only the band's upper half and factor it by LDLᵀ."""
    return not ((prm.n_obstacles > 0 and prm.friction_on > 0) or (prm.rod_pairs > 0 and prm.friction > 0))


@njit(inline="always", **_OPT)
def guard_score(pen, lim, grow, rg):
    """How badly a finite retry level trips the guards: max(pen/lim, grow/rg) over the tripped ones, else 0
    (penetration pen beyond its limit lim [m]; residual growth grow beyond rg when rg > 0)."""
    score = pen / lim if pen > lim else 0.0
    if rg > 0.0 and grow > rg:
        score = max(score, grow / rg)
    return score


@njit(inline="always", **_OPT)
def lazy_line_search(prm, cd, e, w):
    """Whether env ``e``'s Newton loop backtracks lazily (``line_search = "auto"``, the default): only in
    an env with contact candidates (obstacle or edge pairs: where friction's stick law and the stiff contact
    potential make full Newton steps overshoot), and only when an update raised ‖f‖; otherwise the full step
    costs nothing extra. The decision is read once per Newton solve (the candidate list is fixed during it)."""
    return prm.line_search == 2 and has_candidates(prm, cd, e, w)


@njit(inline="always", **_OPT)
def has_candidates(prm, cd, e, w):
    """Whether env ``e`` has contact candidates now: obstacle pairs (cd) or edge pairs (the Workspace's list)."""
    return (prm.n_obstacles > 0 and cd.cand_count[e] > 0) or (prm.rod_pairs > 0 and w.rp_n[0] > 0)


@njit(inline="always", **_OPT)
def newton_dtol(prm, cd, e, w):
    """Displacement-test tolerance [m/s] of env ``e``'s Newton solve: ``newton_dtol``, capped at 1 % of the
    friction velocity tolerance ν where friction can act (contact candidates and μ > 0): the stick law
    γ(|v_t|/ν) resolves velocities on the scale ν, so an update that still changes velocities by ~ν is
    not converged (docs/physics.md §4.6)."""
    dtol = prm.newton_dtol
    if ((prm.friction_on > 0 and prm.n_obstacles > 0 and cd.cand_count[e] > 0)
            or (prm.friction > 0 and prm.rod_pairs > 0 and w.rp_n[0] > 0)):
        dtol = min(dtol, 0.01 * prm.friction_nu)
    return dtol


@njit(inline="always", **_OPT)
def midpoint_gained_energy(e0, s0, e1, s1, tol):
    """Whether an implicit-midpoint (sub)step gained energy beyond ``tol``: total energy e1 at its end exceeds
    e0 at its start by more than tol · max(s0, s1) (s: the energy without the gravity potential, whose zero is
    arbitrary). Within a step κ̄, τ̄ and the constraints are fixed and damping/friction only dissipate, so a
    gain is the midpoint rule's own nonlinear instability; the sub-step is then redone by backward Euler."""
    return e1 - e0 > tol * max(s0, s1)
