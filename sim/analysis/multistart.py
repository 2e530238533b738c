"""Multi-start Levenberg–Marquardt for ``rodlab fit --starts K`` (docs/physics.md §3.9): K starting points stepped in
lock-step, each one env of one batched rollout, so that an iteration costs one batched simulation and one batched
tangent pass whatever K is.

Start 0 is the scene's own values; the others are drawn around them (:func:`start_points`: a factor of up to
:data:`LOG_SPREAD` either way on the log-space unknowns, a fixed spread on the others, every start within the bounds).
Each start runs its own damped Gauss–Newton iteration: the step solves (JᵀJ + λ diag(JᵀJ)) δ = −Jᵀr, is projected
into the bounds and kept where it lowers the start's cost (λ / 3), else λ × 4. A start stops when its cost falls by
less than a relative :data:`FTOL` or λ exceeds :data:`LAMBDA_MAX`; the search ends when every start has stopped or
after its iterations. The best start is then polished and reported by the one-start fit
(:func:`sim.analysis.calibration.fit`).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import numpy as np

__all__ = ["MultiStart", "start_points", "lockstep_lm", "LOG_SPREAD", "FTOL", "LAMBDA_MAX"]

LOG_SPREAD = math.log(4.0)  # the log-space unknowns' starts: within a factor of 4 of the scene's value
FTOL = 1e-10                # a start stops when an accepted step lowers its cost by less than this fraction
LAMBDA_MAX = 1e10           # ... or when its damping grows past this (no step lowers the cost)
LAMBDA0 = 1e-3


def _spread(prob: Any, name: str) -> float:
    """Half-width of the starts' spread around the scene's value of the unknown ``name`` (not in log space)."""
    length = max(float(r.length) for r in prob.spec.rods)
    return {"damping": 1.0,                      # [1/s]
            "gravity": 2.0,                      # [m/s²]
            "actuation_gain": 0.5,
            "actuation_offset": 0.25 * max(prob.play_limit, 0.1),
            "actuation_play": 0.5 * prob.play_limit,
            "actuation_lag": 0.2,                # [s]
            "rest_kappa": 0.5,                   # integrated curvature
            "base_position": 0.05 * length,      # [m]
            "base_orientation": 0.1,             # [rad]
            "obstacle_position": 0.05 * length}.get(name, 0.0)  # [m]


def start_points(prob: Any, K: int, rng: np.random.Generator) -> np.ndarray:
    """(K, P) starting points of ``prob`` (a :class:`sim.analysis.calibration.Problem`): row 0 its own start, the
    others uniform within the spread around it (:data:`LOG_SPREAD` for the unknowns fitted in log space,
    ``prob.LOG``; :func:`_spread` else), clipped into the bounds."""
    z0 = prob.z0()
    lo, hi = prob.bounds()
    width = np.array([LOG_SPREAD if u.name in prob.LOG else _spread(prob, u.name) for u in prob.unknowns])
    Z = np.clip(z0 + rng.uniform(-1.0, 1.0, size=(K, z0.size)) * width, lo, hi)
    Z[0] = z0
    return Z


@dataclasses.dataclass
class MultiStart:
    """What :func:`lockstep_lm` found: each start's point ``z`` (K, P), its first and last cost (sum of squared
    residuals) ``cost0``, ``cost`` (K,), the index of the best ``best``, the batched iterations and whether the search
    was stopped (Ctrl-C, or ``on_iteration``)."""

    start: np.ndarray
    z: np.ndarray
    cost0: np.ndarray
    cost: np.ndarray
    best: int
    iterations: int
    interrupted: bool


def _costs(prob: Any, tape: Any, K: int) -> tuple[np.ndarray, np.ndarray]:
    R = np.stack([prob.residuals(tape, e) for e in range(K)])
    cost = np.einsum("km,km->k", R, R)
    return R, np.where(np.isfinite(cost), cost, np.inf)


def lockstep_lm(prob: Any, Z0: np.ndarray, *, iterations: int,
                on_iteration: Callable[[int, np.ndarray, np.ndarray], bool] | None = None) -> MultiStart:
    """Levenberg–Marquardt from every row of ``Z0`` (K, P) at once (see the module docstring); ``prob`` provides
    ``rollouts(Z)``, ``residuals(tape, env)``, ``jacobians(tape, Z)`` and ``bounds()``. ``on_iteration(i, cost, Z)``,
    if given, is called after each iteration with the starts' costs and points; returning True stops the search."""
    lo, hi = prob.bounds()
    Z = np.array(Z0, dtype=np.float64)
    K, P = Z.shape
    tape = prob.rollouts(Z)
    R, cost = _costs(prob, tape, K)
    J = prob.jacobians(tape, Z)
    cost0 = cost.copy()
    lam = np.full(K, LAMBDA0)
    active = np.isfinite(cost)
    it = 0
    interrupted = False
    try:
        while it < iterations and active.any():
            it += 1
            cand = Z.copy()
            for e in np.flatnonzero(active):
                A = J[e].T @ J[e]
                g = J[e].T @ R[e]
                D = np.diag(np.maximum(np.diag(A), 1e-12 * max(float(np.max(np.diag(A))), 1e-300)))
                try:
                    step = np.linalg.solve(A + lam[e] * D, -g)
                except np.linalg.LinAlgError:
                    lam[e] *= 4.0
                    continue
                cand[e] = np.clip(Z[e] + step, lo, hi)
            moved = active & np.any(cand != Z, axis=1)
            if not moved.any():
                active &= lam <= LAMBDA_MAX
                continue
            tape_c = prob.rollouts(cand)
            Rc, cost_c = _costs(prob, tape_c, K)
            better = moved & (cost_c < cost)
            worse = moved & ~better
            lam[worse] *= 4.0
            if better.any():
                J_c = prob.jacobians(tape_c, cand)
                small = better & (cost - cost_c <= FTOL * cost)
                Z[better], R[better], J[better] = cand[better], Rc[better], J_c[better]
                cost[better] = cost_c[better]
                lam[better] = np.maximum(lam[better] / 3.0, 1e-12)
                active &= ~small
            active &= lam <= LAMBDA_MAX
            if on_iteration is not None and on_iteration(it, cost.copy(), Z.copy()):
                interrupted = True
                break
    except KeyboardInterrupt:
        interrupted = True
    return MultiStart(start=np.array(Z0, dtype=np.float64), z=Z, cost0=cost0, cost=cost, best=int(np.argmin(cost)),
                      iterations=it, interrupted=interrupted)
