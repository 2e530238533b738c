"""The step's numba kernels, gathered: :func:`step_kernel` (:mod:`sim.kernel`: the retry/guard ladder per env),
the Newton loop and (sub)step (:mod:`sim.newton`), the mode's elements (:mod:`sim.solve_3d`, :mod:`sim.solve_2d`)
and the named data they exchange (:mod:`sim.solve_params`)."""
from __future__ import annotations

from .kernel import step_kernel
from .solve_params import (
    ContactReport,
    ControlArrays,
    Params,
    RodData,
    StateArrays,
    StepOutput,
    Workspace,
    params_record,
)

__all__ = ["step_kernel", "Params", "params_record", "ContactReport", "StepOutput", "RodData", "StateArrays",
           "ControlArrays", "Workspace"]
