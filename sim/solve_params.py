"""Indices into the solver's float parameter vector ``prm`` and per-env output columns, and numba options.

Shared by :mod:`sim.solve_3d`, :mod:`sim.solve_2d` and the :class:`sim.Simulator` that fills ``prm``.
"""
from __future__ import annotations

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
