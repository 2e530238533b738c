"""Per-env implicit Newton solve (3-D and 2-D), sub-step retry, and the fused batched numba kernels.

One call of :func:`step_kernel_3d` / :func:`step_kernel_2d` advances every non-failed env by one step ``dt``
(``prange`` over envs; env e only reads and writes row e, so a batch gives the same bits as envs alone).
Per (sub)step (docs/physics.md §3.4): guess x = x0 + 0.01·u·h on free DOFs; Newton: frames by time-parallel
transport from the (sub)step-start frames, residual f and banded Jacobian J (constrained DOFs: identity rows
and columns, zero RHS), force test ‖f‖ ≤ tol·‖f0‖, banded LU (pivots checked), x ← x − αΔx, displacement
test max|Δx|/h < dtol on free position DOFs, accept at max_iter if allowed. Then backward Euler
(u = (x − x0)/h) or implicit midpoint (BE solve over h/2, x_new = 2x_½ − x0, u_new = 2u_½ − u0), and the
end-of-step frame update. Failure (non-finite, residual growth > 1e6, bad pivot, |strain| > 0.9, or
unconverged when accept_unconverged is false) -> retry with 2, 4, 8, 16 sub-steps, else the env is restored
and flagged failed. Penetration guard (obstacle scenes only): a finite level whose deepest end-of-sub-step
penetration exceeds max(max_penetration, p0 + max_penetration/4) (p0 = penetration at the step start) is also retried with
more sub-steps; it never fails an env: the finest level is accepted however deep, and if that level diverges,
the least-penetrating finite coarser result is used. Divergence guard (divergence_guard > 0): an accepted unconverged
(sub)step whose residual grew by more than divergence_guard over its iterations is retried the same way; both guards
share one fallback, scored by max(pen/limit, growth/divergence_guard).
"""
from __future__ import annotations

from .solve_2d import step_kernel_2d
from .solve_3d import step_kernel_3d
from .solve_params import *  # noqa: F403  (re-exported: Params, F_*/I_* output columns)
from .solve_params import F_COLS, I_COLS, ContactReport, Params, params_record

__all__ = ["step_kernel_3d", "step_kernel_2d", "Params", "params_record", "ContactReport", "F_COLS", "I_COLS"]
