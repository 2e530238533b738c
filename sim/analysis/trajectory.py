"""Open-loop trajectory optimisation: the natural curvature (and twist) of every step that brings a node of the rod
along target positions, by L-BFGS-B with the gradient of one adjoint pass per evaluation (docs/physics.md §3.9).

The controls are the tasks' delta-curvature actions: at each step the natural curvature of the optimised nodes moves
by Δ from the step before (``|Δ| ≤ max_delta`` per component, box bounds), starting from the rest values. The
objective of every env:

    Σ_k w_k ‖x_node(k) − target_k‖² + effort · Σ_k ‖Δ_k‖²

over the step ends k = 1 … T (a NaN target row has no weight). The B envs of the simulator are optimised together as
one sum of independent problems (a batch of targets, or several starts).
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from sim.analysis.gradients import GradientError, rollout

__all__ = ["TrajectoryResult", "optimise_controls"]


@dataclasses.dataclass
class TrajectoryResult:
    """What :func:`optimise_controls` found: the controls of every step (``kappa_bar`` (T, B, N, 2), ``tau_bar``
    (T, B, N)), the optimised node's positions at the step ends (``positions`` (T, B, 3)), the objective at the start
    and at the end per env (``cost0``, ``cost`` (B,)), the objective evaluations and the wall time."""

    kappa_bar: np.ndarray
    tau_bar: np.ndarray
    positions: np.ndarray
    cost0: np.ndarray
    cost: np.ndarray
    evaluations: int
    seconds: float


def optimise_controls(sim, state, targets, *, node: int = -1, nodes=None, twist: bool = False,
                      max_delta: float = 0.05, effort: float = 0.0, max_iterations: int = 200,
                      weights=None) -> TrajectoryResult:
    """Optimise the per-step natural curvature of ``nodes`` (default: every interior node; with ``twist`` in 3-D
    their natural twist too) so that node ``node`` follows ``targets`` (T, 3) or (T, B, 3) [m] over T steps of
    ``sim`` from ``state`` (not changed). ``weights`` (T,) scales each step's distance term (default 1). Raises
    ValueError for bad input and :class:`sim.analysis.gradients.GradientError` for a scene the derivatives do not
    cover."""
    import scipy.optimize

    B, N = sim.envs, sim.model.node_count
    planar = sim.model.mode == "2d"
    tg = np.asarray(targets, dtype=np.float64)
    if tg.ndim == 2 and tg.shape[1] == 3:
        tg = np.broadcast_to(tg[:, None, :], (tg.shape[0], B, 3))
    if tg.ndim != 3 or tg.shape[1:] != (B, 3) or tg.shape[0] < 1:
        raise ValueError(f"targets: expected (T, 3) or (T, {B}, 3) positions, got shape {np.shape(targets)}")
    T = tg.shape[0]
    if not -N <= node < N:
        raise ValueError(f"node {node} is not a node of the rod (0 … {N - 1})")
    node %= N
    nodes = np.arange(1, N - 1) if nodes is None else np.asarray(nodes, dtype=np.int64)
    if nodes.size == 0 or nodes.min() < 0 or nodes.max() >= N:
        raise ValueError(f"nodes: expected node indices in 0 … {N - 1}, got {nodes.tolist()}")
    if not (max_delta > 0.0 and np.isfinite(max_delta)):
        raise ValueError(f"max_delta must be a positive number, got {max_delta!r}")
    if not (effort >= 0.0 and np.isfinite(effort)):
        raise ValueError(f"effort must be a number >= 0, got {effort!r}")
    w = np.ones(T) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != (T,) or not np.all(np.isfinite(w)) or np.any(w < 0.0):
        raise ValueError(f"weights: expected {T} numbers >= 0")
    have = np.isfinite(tg).all(axis=2)  # (T, B)
    tg = np.where(have[..., None], tg, 0.0)
    comps = [(0, "kappa_bar")] if planar else [(0, "kappa_bar"), (1, "kappa_bar")]
    if twist and not planar:
        comps.append((None, "tau_bar"))
    C = len(comps)
    rest = sim.make_control()
    axes = [0, 1] if planar else [0, 1, 2]  # the node's position DOFs (2-D: x and z)
    dpn = 2 if planar else 4
    xyz = [0, 2] if planar else [0, 1, 2]
    evals = [0]
    keep: dict = {}

    def controls(z):
        d = z.reshape(T, B, nodes.size, C)
        level = np.cumsum(d, axis=0)  # κ̄_k − κ̄_rest: the sum of the deltas so far
        out = []
        for k in range(T):
            c = sim.make_control()
            for j, (comp, name) in enumerate(comps):
                if name == "kappa_bar":
                    c.kappa_bar[:, nodes, comp] = rest.kappa_bar[:, nodes, comp] + level[k, :, :, j]
                else:
                    c.tau_bar[:, nodes] = rest.tau_bar[:, nodes] + level[k, :, :, j]
            out.append(c)
        return out

    def evaluate(z):
        tape = rollout(sim, state.copy(), controls(z))
        x = tape.dof[1:, :, dpn * node + np.array(axes)]  # (T, B, len(axes))
        err = x - tg[:, :, xyz]
        err = err * have[..., None]
        per_env = np.einsum("t,tbc->b", w, err**2) + effort * np.sum(z.reshape(T, B, -1) ** 2, axis=(0, 2))
        cot = np.zeros(tape.dof.shape)
        cot[1:, :, dpn * node + np.array(axes)] = 2.0 * w[:, None, None] * err
        grads = tape.vjp({"dof": cot}, params=tuple({name for _, name in comps}))
        g_level = np.zeros((T, B, nodes.size, C))
        for j, (comp, name) in enumerate(comps):
            g_level[..., j] = grads[name][:, :, nodes, comp] if name == "kappa_bar" else grads[name][:, :, nodes]
        g = np.cumsum(g_level[::-1], axis=0)[::-1]  # level = cumsum(Δ): ∂/∂Δ_k = Σ_{k' ≥ k} ∂/∂level_k'
        g = g.reshape(-1) + 2.0 * effort * z
        evals[0] += 1
        keep["tape"], keep["positions"], keep["per_env"] = tape, x, per_env
        return float(per_env.sum()), g

    t0 = time.perf_counter()
    z0 = np.zeros(T * B * nodes.size * C)
    evaluate(z0)
    cost0 = keep["per_env"].copy()
    res = scipy.optimize.minimize(evaluate, z0, jac=True, method="L-BFGS-B",
                                  bounds=[(-max_delta, max_delta)] * z0.size,
                                  options={"maxfun": max_iterations, "ftol": 1e-15, "gtol": 1e-14})
    evaluate(res.x)  # the state of the result (L-BFGS-B's last evaluation need not be its answer)
    ctrls = controls(res.x)
    pos = np.zeros((T, B, 3))
    pos[..., xyz] = keep["positions"]
    if planar:
        pos[..., 1] = sim.model.plane_y
    if not np.all(np.isfinite(pos)):
        raise GradientError("the optimised controls drive the rod to non-finite positions")
    return TrajectoryResult(kappa_bar=np.stack([c.kappa_bar for c in ctrls]), tau_bar=np.stack([c.tau_bar for c in ctrls]),
                            positions=pos, cost0=cost0, cost=keep["per_env"].copy(), evaluations=evals[0],
                            seconds=time.perf_counter() - t0)
