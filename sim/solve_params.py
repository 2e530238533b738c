"""Indices into the solver's float parameter vector ``prm`` and per-env output columns, numba options, and the
two small decisions both step kernels share (symmetric Jacobian? how badly does a retry level trip the guards?).

Shared by :mod:`sim.solve_3d`, :mod:`sim.solve_2d` and the :class:`sim.Simulator` that fills ``prm``.
"""
from __future__ import annotations

from numba import njit

# indices into the float64 parameter vector ``prm``
P_EA, P_EI1, P_EI2, P_GJ, P_DT, P_DAMP, P_TOL, P_DTOL, P_MAXIT, P_ACCEPT, P_INTEG, P_LS = range(12)
P_RADIUS, P_CK, P_CDELTA, P_CMU, P_CNU, P_CFRIC, P_CMARGIN, P_NOBS, P_SIGN2D, P_PLANEY = range(12, 22)
P_LEVELS, P_STRAIN, P_MAXPEN, P_CCD, P_RGUARD = 22, 23, 24, 25, 26
PRM_SIZE = 27
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
    return not (prm[P_NOBS] > 0 and prm[P_CFRIC] > 0)


@njit(inline="always", **_OPT)
def guard_score(pen, lim, grow, rg):
    """How badly a finite retry level trips the guards: max(pen/lim, grow/rg) over the tripped ones, else 0
    (penetration pen beyond its limit lim [m]; residual growth grow beyond rg when rg > 0)."""
    score = pen / lim if pen > lim else 0.0
    if rg > 0.0 and grow > rg:
        score = max(score, grow / rg)
    return score
