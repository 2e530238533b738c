"""The solver's named parameters (:class:`Params`, read as ``prm``), per-env output columns, numba options and
the small decisions both step kernels share (symmetric Jacobian? how badly does a retry level trip the guards?).

Shared by :mod:`sim.solve_3d`, :mod:`sim.solve_2d` and the :class:`sim.Simulator` that builds ``prm``.
"""
from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

# The solver's scalar parameters by name: a namedtuple of float64 (flags 0.0/1.0; line_search 0 none,
# 1 backtrack, 2 auto), built once by the Simulator from the Model. Units: EA [N], EI1/EI2/GJ [N m²], dt [s],
# damping [1/s], newton_dtol [m/s], radius/contact_delta/contact_margin/max_penetration/plane_y [m],
# contact_k [N/m], friction_nu [m/s]; the rest dimensionless.
Params = namedtuple("Params", [
    "EA", "EI1", "EI2", "GJ", "dt", "damping", "newton_tol", "newton_dtol", "newton_max_iter", "accept_unconverged",
    "midpoint", "line_search", "radius", "contact_k", "contact_delta", "friction", "friction_nu", "friction_on",
    "contact_margin", "n_obstacles", "planar_sign", "plane_y", "retry_levels", "max_strain", "max_penetration",
    "step_limit", "divergence_guard", "midpoint_energy_tol",
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
# count (B,), edge/obstacle (B, C) int64, rod_point/obstacle_point/normal/friction_force (B, C, 3),
# normal_force/gap (B, C), max_penetration (B,)
ContactReport = namedtuple("ContactReport", [
    "count", "edge", "obstacle", "rod_point", "obstacle_point", "normal", "normal_force", "friction_force", "gap",
    "max_penetration",
])
# columns of the float / int per-env outputs
F_RES, F_RES0, F_ES, F_EB, F_ET, F_EC, F_EK, F_EG, F_PEN = range(9)
F_COLS = 9
I_ITERS, I_CONV, I_SUB, I_FAIL = range(4)
I_COLS = 4

# envs per workspace allocation in the step kernels' parallel loop
_CHUNK = 8

_OPT = dict(cache=True, error_model="numpy", fastmath={"contract", "arcp", "nsz"})


@njit(inline="always", **_OPT)
def jacobian_symmetric(prm):
    """Whether the Newton Jacobian is symmetric: yes unless friction acts (obstacles present and μ > 0); the
    kernels then assemble only the band's upper half and factor it by LDLᵀ."""
    return not (prm.n_obstacles > 0 and prm.friction_on > 0)


@njit(inline="always", **_OPT)
def guard_score(pen, lim, grow, rg):
    """How badly a finite retry level trips the guards: max(pen/lim, grow/rg) over the tripped ones, else 0
    (penetration pen beyond its limit lim [m]; residual growth grow beyond rg when rg > 0)."""
    score = pen / lim if pen > lim else 0.0
    if rg > 0.0 and grow > rg:
        score = max(score, grow / rg)
    return score


@njit(inline="always", **_OPT)
def lazy_line_search(prm, cd, e):
    """Whether env ``e``'s Newton loop backtracks lazily (``line_search = "auto"``, the default): only in
    an env with contact candidates (where friction's stick law and the stiff contact potential make full
    Newton steps overshoot), and only when an update raised ‖f‖; otherwise the full step costs nothing
    extra. The decision is read once per Newton solve (the candidate list is fixed during it)."""
    return prm.line_search == 2 and prm.n_obstacles > 0 and cd.cand_count[e] > 0


@njit(inline="always", **_OPT)
def newton_dtol(prm, cd, e):
    """Displacement-test tolerance [m/s] of env ``e``'s Newton solve: ``newton_dtol``, capped at 1 % of the
    friction velocity tolerance ν where friction can act (contact candidates and μ > 0): the stick law
    γ(|v_t|/ν) resolves velocities on the scale ν, so an update that still changes velocities by ~ν is
    not converged (docs/physics.md §4.6)."""
    dtol = prm.newton_dtol
    if prm.friction_on > 0 and prm.n_obstacles > 0 and cd.cand_count[e] > 0:
        dtol = min(dtol, 0.01 * prm.friction_nu)
    return dtol


@njit(inline="always", **_OPT)
def midpoint_gained_energy(e0, s0, e1, s1, tol):
    """Whether an implicit-midpoint (sub)step gained energy beyond ``tol``: total energy e1 at its end exceeds
    e0 at its start by more than tol · max(s0, s1) (s: the energy without the gravity potential, whose zero is
    arbitrary). Within a step κ̄, τ̄ and the constraints are fixed and damping/friction only dissipate, so a
    gain is the midpoint rule's own nonlinear instability; the sub-step is then redone by backward Euler."""
    return e1 - e0 > tol * max(s0, s1)
