"""Inverse statics: the natural curvature (and twist) that puts a rod's tip at a target position (and tip frame) at
equilibrium (docs/physics.md §3.10).

    from sim.analysis.inverse import reach
    res = reach(spec, targets)        # targets (B, 3): one per env; res.kappa_bar (B, N, 2), res.tip, res.error
    res = reach(spec, targets, orientations=R)   # R (B, 3, 3): tip frames (m1, m2, t) as columns; also τ̄

Each iteration relaxes every env to static equilibrium (:func:`sim.analysis.static.solve_static`, warm-started from the last
one), then takes a damped Gauss–Newton step on the control nodes' natural curvature: with g(x, κ̄) = ∇E − F = 0 at
equilibrium, dx/dκ̄ = −K⁻¹ ∂g/∂κ̄ (K the static Hessian, exact at the stored frames; ∂g/∂κ̄ the difference of two
residuals of the step's own elements, exact as g is affine in κ̄), so the tip's Jacobian costs one factorisation per
env and iteration. Steps are limited to a trust region and κ̄ to ``|κ̄| ≤ bound`` per component. A target out of
reach ends at the closest equilibrium found, with ``converged`` False.

With target tip frames the natural twist at the same nodes is unknown too, and the residual adds the tip edge's
tangent and first director against the target's, each times a length (the rod's by default: a radian weighs as
much as a rod length of distance). Their derivatives follow the equilibrium's: δt = (I − t tᵀ)(δx_b − δx_a)/l for
the tip edge (a, b), and δm1 = −(m1·δt) t + m2 δθ (the reference director is parallel-transported with the tangent).
"""
from __future__ import annotations

import dataclasses
import math

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
    tau_bar: np.ndarray | None = None  # (B, N) the natural twist found (the rest values without orientations)
    twist_coefficients: np.ndarray | None = None  # (B, P) the twist unknowns found ((B, 0) without orientations)
    orientation_error: np.ndarray | None = None  # (B,) [rad] the tip frame's angle from its target (nan without)


def _tip_rows(model, tip: int) -> list[int]:
    dpn = model.dofs_per_node
    return [dpn * tip, dpn * tip + 1] if dpn == 2 else [4 * tip, 4 * tip + 1, 4 * tip + 2]


def _positions(state, tip: int) -> np.ndarray:
    return np.asarray(state.node_pos)[:, tip, :]


def _frames(state, edge: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(m1, m2, t) (B, 3) of ``edge`` (``sim.Simulator.material_frames`` on one edge)."""
    t = np.asarray(state.edge_tangent)[:, edge]
    d1 = np.asarray(state.edge_ref_d1)[:, edge]
    d2 = np.cross(t, d1)
    th = np.asarray(state.edge_theta)[:, edge, None]
    c, s = np.cos(th), np.sin(th)
    return c * d1 + s * d2, -s * d1 + c * d2, t


def frame_angle(R: np.ndarray, R_target: np.ndarray) -> np.ndarray:
    """(B,) [rad] angle of the rotation between frames (B, 3, 3) and (B, 3, 3) (columns m1, m2, t)."""
    c = 0.5 * (np.einsum("bij,bij->b", R, R_target) - 1.0)
    return np.arccos(np.clip(c, -1.0, 1.0))


def _checked_orientations(orientations, B: int, planar: bool) -> np.ndarray:
    R = np.asarray(orientations, dtype=np.float64)
    if planar:
        raise ReachError("reach: target tip frames need a 3-D scene (the planar rod has no twist)")
    if R.shape != (B, 3, 3) or not np.all(np.isfinite(R)):
        raise ReachError(f"reach: orientations must be finite (B = {B}, 3, 3) frames, got shape {R.shape}")
    if not np.allclose(np.einsum("bki,bkj->bij", R, R), np.eye(3), atol=1e-6) or np.any(np.linalg.det(R) < 0):
        raise ReachError("reach: each orientation must be a rotation matrix (orthonormal columns m1, m2, t)")
    return R


def reach(spec, targets, *, nodes=None, basis=None, tip: int = -1, bound: float = 1.0, tol: float = 1e-5,
          max_iterations: int = 40, trust: float = 0.2, regularisation: float = 1e-9,
          warm: ReachResult | None = None, orientations=None, twist_bound: float = math.pi / 2,
          angle_tol: float = 1e-4, orientation_length: float | None = None) -> ReachResult:
    """Natural curvature at ``nodes`` (default: every interior node) that puts node ``tip`` of ``spec``'s rod at
    ``targets`` (B, 3) [m] (2-D: the x–z components count) at static equilibrium; ``bound`` the largest |κ̄| per
    component [rad, integrated curvature], ``trust`` the largest change of κ̄ per iteration (2-norm), ``tol`` [m].

    ``basis`` (N, P): the unknowns are P coefficients per component instead, κ̄ = rest + basis @ K (a task's control
    points spread over their regions), ``bound`` then on |K|. ``warm``: the result of a previous call with the same
    scene, nodes and envs, to start from (its equilibrium and coefficients).

    ``orientations`` (B, 3, 3): target frames of the tip edge (the edge ending at node ``tip``), columns (m1, m2, t);
    the natural twist through the same nodes or basis is then unknown too, ``|τ̄| ≤ twist_bound`` (per node or
    coefficient), an env converges when also within ``angle_tol`` [rad], and ``orientation_length`` [m] (default the
    rod's length) weighs a unit of frame error against a metre of distance."""
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
    oriented = orientations is not None
    R_target = _checked_orientations(orientations, B, planar) if oriented else None
    if not (twist_bound > 0 and angle_tol > 0):
        raise ReachError("reach: need twist_bound > 0 and angle_tol > 0")
    scale = float(orientation_length) if orientation_length is not None else \
        max(float(r.length) for r in spec.rods)
    if not scale > 0:
        raise ReachError(f"reach: orientation_length must be positive, got {orientation_length!r}")
    if oriented and not 1 <= tip:
        raise ReachError("reach: a tip frame needs the tip edge: the tip node must not be node 0")
    sim = Simulator(model, envs=B)
    if sim.has_contact:
        raise ReachError("reach: scenes with contact are not supported yet (disable [contact] or remove the "
                         "obstacles)")
    state, ctrl = sim.reset(), sim.make_control()
    rest = ctrl.kappa_bar.copy()
    rest_tau = ctrl.tau_bar.copy()
    coef = np.zeros((B, P, len(comps)))
    tcoef = np.zeros((B, P if oriented else 0))
    if warm is not None:
        if warm.coefficients.shape != coef.shape:
            raise ReachError(f"reach: warm start has coefficients {warm.coefficients.shape}, expected {coef.shape}")
        wt = warm.twist_coefficients if warm.twist_coefficients is not None else np.zeros((B, 0))
        if wt.shape != tcoef.shape:
            raise ReachError(f"reach: warm start has twist coefficients {wt.shape}, expected {tcoef.shape}")
        state = warm.state.copy()
        coef = warm.coefficients.copy()
        tcoef = wt.copy()

    def set_controls():
        for i, c in enumerate(comps):
            ctrl.kappa_bar[:, :, c] = rest[:, :, c] + coef[:, :, i] @ basis.T
        if oriented:
            ctrl.tau_bar[:] = rest_tau + tcoef @ basis.T

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
    ang = np.full(B, np.nan)
    edge = tip - 1
    for it in range(max_iterations + 1):  # the last pass only measures the equilibrium of the last update
        solve_static(spec, state, ctrl, check_stability=False)
        pos = _positions(state, tip)
        resid = (targets - pos)[:, axes]
        err = np.linalg.norm(resid, axis=1)
        conv = err <= tol
        if oriented:
            m1, m2, t = _frames(state, edge)
            ang = frame_angle(np.stack([m1, m2, t], axis=-1), R_target)
            conv &= ang <= angle_tol
            resid = np.concatenate([resid, scale * (R_target[:, :, 2] - t), scale * (R_target[:, :, 0] - m1)], axis=1)
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
            for p in range(tcoef.shape[1]):
                f1 = np.empty(n)
                assemble_at(0, *args, kb, tb + basis[:, p], rod, sim.kernel_params, cd, f1, ab)
                d = f1 - f0
                d[fixed] = 0.0
                cols.append(d)
            C = np.stack(cols, axis=1)
            dx = -scipy.linalg.solve(K, C, assume_a="sym")
            Jt = dx[rows]  # (2 or 3, m)
            if oriented:  # the tip edge's tangent and first director (module docstring)
                a = 4 * edge
                length = float(np.linalg.norm(x[a + 4:a + 7] - x[a:a + 3]))
                te, m1e, m2e = t[e], m1[e], m2[e]
                dT = (np.eye(3) - np.outer(te, te)) @ (dx[a + 4:a + 7] - dx[a:a + 3]) / length
                dM1 = -np.outer(te, m1e @ dT) + np.outer(m2e, dx[a + 3])
                Jt = np.concatenate([Jt, scale * dT, scale * dM1], axis=0)
            m = Jt.shape[1]
            A = Jt.T @ Jt
            lam = regularisation * max(float(np.trace(A)) / m, 1e-300)
            step = np.linalg.solve(A + lam * np.eye(m), Jt.T @ resid[e])
            norm = float(np.linalg.norm(step))
            if norm > trust:
                step *= trust / norm
            nk = P * len(comps)
            coef[e] = np.clip(coef[e] + step[:nk].reshape(P, len(comps)), -bound, bound)
            tcoef[e] = np.clip(tcoef[e] + step[nk:], -twist_bound, twist_bound)
        set_controls()
    tips = _positions(state, tip).copy()
    return ReachResult(kappa_bar=ctrl.kappa_bar.copy(), tip=tips, error=err, converged=conv, iterations=it,
                       state=state, coefficients=coef, tau_bar=ctrl.tau_bar.copy(), twist_coefficients=tcoef,
                       orientation_error=ang)
