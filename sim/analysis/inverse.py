"""Inverse statics: the natural curvature that puts a rod's tip at a target at equilibrium (docs/physics.md §3.10).

    from sim.analysis.inverse import reach
    res = reach(spec, targets)        # targets (B, 3): one per env; res.kappa_bar (B, N, 2), res.tip, res.error

Each iteration relaxes every env to static equilibrium (:func:`sim.analysis.static.solve_static`, warm-started from the last
one), then takes a damped Gauss–Newton step on the control nodes' natural curvature: with g(x, κ̄) = ∇E − F = 0 at
equilibrium, dx/dκ̄ = −K⁻¹ ∂g/∂κ̄ (K the static Hessian, exact at the stored frames; ∂g/∂κ̄ the difference of two
residuals of the step's own elements, exact as g is affine in κ̄), so the tip's Jacobian costs one factorisation per
env and iteration. Steps are limited to a trust region and κ̄ to ``|κ̄| ≤ bound`` per component. A target out of
reach ends at the closest equilibrium found, with ``converged`` False.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import scipy.linalg

from sim.analysis.static import solve_static, static_hessian
from sim.contact.world import spec_contact_data
from sim.kernels.data import KL_2D, KL_3D
from sim.kernels.probe import assemble_at
from sim.scene.model import build_model
from sim.step import Simulator

__all__ = ["ReachResult", "ReachError", "reach"]

_H_STATIC = 1e150  # [s] pseudo-time step: the inertia term M/h² vanishes (sim.analysis.hessian)


class ReachError(ValueError):
    """A reach request that cannot be served, said with what is wrong."""


@dataclasses.dataclass
class ReachResult:
    """Per env (leading axis B): the natural curvature found (B, N, 2) (rest values off the control nodes), the
    tip's equilibrium position (B, 3) [m], its distance to the target (B,) [m], whether it is within ``tol``, the
    iterations taken, the equilibrium State and the coefficients found."""

    kappa_bar: np.ndarray
    tip: np.ndarray
    error: np.ndarray
    converged: np.ndarray
    iterations: int
    state: object
    coefficients: np.ndarray  # (B, P, components) the unknowns found (κ̄ at the control nodes without a basis)


def _tip_rows(model, tip: int) -> list[int]:
    dpn = model.dofs_per_node
    return [dpn * tip, dpn * tip + 1] if dpn == 2 else [4 * tip, 4 * tip + 1, 4 * tip + 2]


def _positions(state, tip: int) -> np.ndarray:
    return np.asarray(state.node_pos)[:, tip, :]


def reach(spec, targets, *, nodes=None, basis=None, tip: int = -1, bound: float = 1.0, tol: float = 1e-5,
          max_iterations: int = 40, trust: float = 0.2, regularisation: float = 1e-9,
          warm: ReachResult | None = None) -> ReachResult:
    """Natural curvature at ``nodes`` (default: every interior node) that puts node ``tip`` of ``spec``'s rod at
    ``targets`` (B, 3) [m] (2-D: the x–z components count) at static equilibrium; ``bound`` the largest |κ̄| per
    component [rad, integrated curvature], ``trust`` the largest change of κ̄ per iteration (2-norm), ``tol`` [m].

    ``basis`` (N, P): the unknowns are P coefficients per component instead, κ̄ = rest + basis @ K (a task's control
    points spread over their regions), ``bound`` then on |K|. ``warm``: the result of a previous call with the same
    scene, nodes and envs, to start from (its equilibrium and coefficients)."""
    model = build_model(spec)
    targets = np.atleast_2d(np.asarray(targets, dtype=np.float64))
    if targets.ndim != 2 or targets.shape[1] != 3 or not np.all(np.isfinite(targets)):
        raise ReachError(f"targets must be finite (B, 3) positions [m], got shape {targets.shape}")
    if not (bound > 0 and tol > 0 and trust > 0 and max_iterations >= 1):
        raise ReachError("reach: need bound > 0, tol > 0, trust > 0, max_iterations >= 1")
    N = model.node_count
    tip = int(tip) % N
    planar = model.mode == "2d"
    if nodes is None:
        nodes = np.arange(1, N - 1)
    nodes = np.asarray(nodes, dtype=int)
    if nodes.size == 0 or nodes.min() < 1 or nodes.max() > N - 2:
        raise ReachError(f"reach: control nodes must be interior nodes 1 … {N - 2}, got {nodes.tolist()}")
    if basis is None:
        basis = np.zeros((N, nodes.size))
        basis[nodes, np.arange(nodes.size)] = 1.0
    basis = np.asarray(basis, dtype=np.float64)
    if basis.ndim != 2 or basis.shape[0] != N or not np.all(np.isfinite(basis)):
        raise ReachError(f"reach: basis must be finite (N = {N}, P), got shape {basis.shape}")
    P = basis.shape[1]
    comps = (0,) if planar else (0, 1)
    B = targets.shape[0]
    sim = Simulator(model, envs=B)
    if sim.has_contact:
        raise ReachError("reach: scenes with contact are not supported yet (disable [contact] or remove the "
                         "obstacles)")
    state, ctrl = sim.reset(), sim.make_control()
    rest = ctrl.kappa_bar.copy()
    coef = np.zeros((B, P, len(comps)))
    if warm is not None:
        if warm.coefficients.shape != coef.shape:
            raise ReachError(f"reach: warm start has coefficients {warm.coefficients.shape}, expected {coef.shape}")
        state = warm.state.copy()
        coef = warm.coefficients.copy()

    def set_controls():
        for i, c in enumerate(comps):
            ctrl.kappa_bar[:, :, c] = rest[:, :, c] + coef[:, :, i] @ basis.T

    set_controls()
    axes = [0, 2] if planar else [0, 1, 2]
    rows = _tip_rows(model, tip)
    kl = KL_2D if planar else KL_3D
    n = state.dof.reshape(B, -1).shape[1]
    cd = spec_contact_data(model.obstacles, 1, N, model.edge_radius, candidates=0)
    fixed = sim.kernel_rod.fixed.astype(bool)
    conv = np.zeros(B, bool)
    it = 0
    err = np.full(B, np.inf)
    for it in range(max_iterations + 1):  # the last pass only measures the equilibrium of the last update
        solve_static(spec, state, ctrl, check_stability=False)
        pos = _positions(state, tip)
        resid = (targets - pos)[:, axes]
        err = np.linalg.norm(resid, axis=1)
        conv = err <= tol
        if conv.all() or it == max_iterations:
            break
        for e in np.flatnonzero(~conv):
            K = static_hessian(sim, state, ctrl, e)
            x = np.ascontiguousarray(state.dof.reshape(B, -1)[e])
            args = (x, x, np.zeros(n), np.ascontiguousarray(state.edge_ref_d1[e]),
                    np.ascontiguousarray(state.edge_tangent[e]), np.ascontiguousarray(state.node_ref_twist[e]),
                    _H_STATIC)
            tb = np.ascontiguousarray(ctrl.tau_bar[e], dtype=np.float64)
            rod = sim.kernel_rod._replace(grav=sim.kernel_rod.grav[:1])
            f0, ab = np.empty(n), np.empty((n + kl, 2 * kl + 1))
            kb = np.ascontiguousarray(ctrl.kappa_bar[e], dtype=np.float64)
            assemble_at(0, *args, kb, tb, rod, sim.kernel_params, cd, f0, ab)
            cols = []
            for p in range(P):
                for c in comps:
                    kb1 = kb.copy()
                    kb1[:, c] += basis[:, p]
                    f1 = np.empty(n)
                    assemble_at(0, *args, kb1, tb, rod, sim.kernel_params, cd, f1, ab)
                    d = f1 - f0
                    d[fixed] = 0.0
                    cols.append(d)
            C = np.stack(cols, axis=1)
            dx = -scipy.linalg.solve(K, C, assume_a="sym")
            Jt = dx[rows]  # (2 or 3, m)
            m = Jt.shape[1]
            A = Jt.T @ Jt
            lam = regularisation * max(float(np.trace(A)) / m, 1e-300)
            step = np.linalg.solve(A + lam * np.eye(m), Jt.T @ resid[e])
            norm = float(np.linalg.norm(step))
            if norm > trust:
                step *= trust / norm
            coef[e] = np.clip(coef[e] + step.reshape(P, len(comps)), -bound, bound)
        set_controls()
    tips = _positions(state, tip).copy()
    return ReachResult(kappa_bar=ctrl.kappa_bar.copy(), tip=tips, error=err, converged=conv, iterations=it,
                       state=state, coefficients=coef)
