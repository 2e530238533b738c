"""Delta natural-curvature action converter (docs/tasks.md §2), batched over environments.

The policy (or the workbench teleop) sends per-control-point *increments* of natural curvature
(and, for IK, natural twist) in ``[-1, 1]``. Once per control step :meth:`ActionConverter.convert`

1. scales and accumulates them with clipping (float32, docs/tasks.md §2.3):
   ``K_new = clip(K_old + s_kappa * a_bend, -2, 2)``, ``T_new = clip(T_old + s_tau * a_twist, -pi/2, pi/2)``;
2. takes the increments *after* clipping, ``dK = K_new - K_old`` (saturated components give 0);
3. spreads each control point's increment over the nodes of its region ("Voronoi smoothing",
   §2.4), weight ``1 / (nodes in the region)``;
4. divides by the number of sim steps of the control step (linear ramp, §2.5).

:meth:`ActionConverter.apply` then adds the per-sim-step increment to a ``Control``
(``kappa_bar`` (B, N, 2), ``tau_bar`` (B, N)) before *each* of the sim steps, so that after the
last one the simulator holds ``w_n * K_new`` at node ``n`` (running sum, never re-set absolutely).

Smoothing modes (``smoothing=``):

* ``"intended"`` (default): regions are nodes 1-3 / 4-7 / 8-11 / 12-15 / 16-19 (weights 1/3, 1/4 ...);
  every interior node is actuated and each region's weights sum to 1 (the evident intent, O1).
* ``"reference"``: the as-implemented mapping of the reference code, shifted by one node: node 1 is
  never actuated, regions 2-4 / 5-8 / 9-12 / 13-16 / 17-19, the last region keeps weight 1/4 (sum 3/4).
  Use this to compare with the paper's numbers.
* ``"none"``: each control point's value goes to its own node only (weight 1); the reference's unused
  non-smoothed path (its absolute-twist defect, O6, is not reproduced).

Twist always goes to the natural twist ``tau_bar`` of the same nodes as the curvature (the evident
intent; the reference's DisMech ``delta_theta`` indexing defect, O2, writes out of bounds and is not
reproduced in any mode).

This module depends on numpy only (no gymnasium / sim import), so the teleop can use it directly.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

__all__ = [
    "ActionConverter",
    "ControlConfig",
    "ControlIncrement",
    "ControlKind",
    "Smoothing",
    "control_config",
    "smoothing_weights",
    "smoothing_basis",
    "CONTROL_POINTS",
    "STATE_NODES",
]

ControlKind = Literal["bend_2d", "bend", "bend_twist", "contact_bend_2d", "contact_bend"]
Smoothing = Literal["intended", "reference", "none"]

#: control-point nodes for the 21-node arm (every 4th node from 2, interior only)
CONTROL_POINTS: tuple[int, ...] = (2, 6, 10, 14, 18)
#: observed nodes (every 2nd node from 2, up to and including the tip)
STATE_NODES: tuple[int, ...] = (2, 4, 6, 8, 10, 12, 14, 16, 18, 20)

_KINDS = ("bend_2d", "bend", "bend_twist", "contact_bend_2d", "contact_bend")
_SMOOTHINGS = ("intended", "reference", "none")


@dataclass(frozen=True)
class ControlConfig:
    """Parameters of the action converter.

    kind: control type (docs/tasks.md §2.2) - decides action dim, planar or not, twist or not.
    kappa_scale: s_kappa, natural-curvature increment per unit action [dimensionless, integrated].
    twist_scale: s_tau, natural-twist increment per unit action [rad] (``bend_twist`` only).
    kappa_limit: |K| bound of the accumulated per-control-point curvature.
    twist_limit: |T| bound of the accumulated per-control-point twist [rad].
    substeps: sim steps per control step (the linear ramp spreads the increment over them).
    smoothing: spatial distribution over the region of each control point (see module doc).
    temporal_interpolation: if False the whole increment is applied before the first sim step.
    n_nodes: rod node count N. control_points: control-point node indices (interior, ascending).
    """

    kind: ControlKind = "bend"
    kappa_scale: float = 0.05
    twist_scale: float = 0.05
    kappa_limit: float = 2.0
    twist_limit: float = math.pi / 2
    substeps: int = 2
    smoothing: Smoothing = "intended"
    temporal_interpolation: bool = True
    n_nodes: int = 21
    control_points: tuple[int, ...] = field(default=CONTROL_POINTS)

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise ValueError(f"ControlConfig.kind must be one of {_KINDS}, got {self.kind!r}")
        if self.smoothing not in _SMOOTHINGS:
            raise ValueError(f"ControlConfig.smoothing must be one of {_SMOOTHINGS}, got {self.smoothing!r}")
        if int(self.substeps) < 1:
            raise ValueError(f"ControlConfig.substeps must be >= 1, got {self.substeps}")
        cp = tuple(int(c) for c in self.control_points)
        if not cp or any(c < 1 or c > self.n_nodes - 2 for c in cp) or list(cp) != sorted(set(cp)):
            raise ValueError(
                f"ControlConfig.control_points must be ascending interior nodes in 1..{self.n_nodes - 2}, got {cp}"
            )
        for name in ("kappa_scale", "twist_scale", "kappa_limit", "twist_limit"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"ControlConfig.{name} must be finite and >= 0, got {v}")

    @property
    def planar(self) -> bool:
        """True for the 2D kinds (one curvature component per control point)."""
        return self.kind.endswith("_2d")

    @property
    def has_twist(self) -> bool:
        return self.kind == "bend_twist"

    @property
    def n_points(self) -> int:
        return len(self.control_points)

    @property
    def n_components(self) -> int:
        """Curvature components per control point: 1 (2D) or 2 (3D)."""
        return 1 if self.planar else 2

    @property
    def bend_dim(self) -> int:
        return self.n_points * self.n_components

    @property
    def action_dim(self) -> int:
        """5 (2D), 10 (3D bend), 15 (bend + twist) for the paper's arm."""
        return self.bend_dim + (self.n_points if self.has_twist else 0)


_SCALES = {"bend_2d": 0.05, "bend": 0.05, "bend_twist": 0.05, "contact_bend_2d": 0.25, "contact_bend": 0.25}


def control_config(kind: ControlKind, *, substeps: int, smoothing: Smoothing = "intended", **kw) -> ControlConfig:
    """The paper's converter settings for ``kind`` (s_kappa 0.05, or 0.25 for the contact kinds)."""
    if kind not in _SCALES:
        raise ValueError(f"unknown control kind {kind!r}; expected one of {_KINDS}")
    kw.setdefault("kappa_scale", _SCALES[kind])
    return ControlConfig(kind=kind, substeps=substeps, smoothing=smoothing, **kw)


def smoothing_basis(cfg: ControlConfig) -> np.ndarray:
    """(N, P) node curvature per unit accumulated curvature of each control point: the converter's spatial
    weights as a matrix (node κ̄ = basis @ K), for solvers that work on the control points' values."""
    owner, weight = smoothing_weights(cfg.n_nodes, cfg.control_points, cfg.smoothing)
    basis = np.zeros((cfg.n_nodes, cfg.n_points))
    on = np.flatnonzero(owner >= 0)
    basis[on, owner[on]] = weight[on]
    return basis


def smoothing_weights(
    n_nodes: int, control_points: tuple[int, ...], smoothing: Smoothing
) -> tuple[np.ndarray, np.ndarray]:
    """Node -> (owning control point, weight).

    Returns ``owner`` (N,) int64 (-1 = node not actuated) and ``weight`` (N,) float64.
    Region boundaries are ``[1, mid_0, ..., mid_{P-2}, N-1]`` with ``mid_k = (c_k + c_{k+1}) // 2``;
    region k = nodes ``[b_k, b_{k+1})``, weight ``1 / (b_{k+1} - b_k)``. ``"reference"`` shifts the
    nodes by +1 and drops nodes beyond N-2 (keeping the weight), as the reference code does.
    """
    cp = list(control_points)
    owner = np.full(n_nodes, -1, dtype=np.int64)
    weight = np.zeros(n_nodes, dtype=np.float64)
    if smoothing == "none":
        for k, c in enumerate(cp):
            owner[c], weight[c] = k, 1.0
        return owner, weight
    bounds = [1] + [(cp[k] + cp[k + 1]) // 2 for k in range(len(cp) - 1)] + [n_nodes - 1]
    shift = 1 if smoothing == "reference" else 0
    for k in range(len(cp)):
        count = bounds[k + 1] - bounds[k]
        for n in range(bounds[k] + shift, bounds[k + 1] + shift):
            if 1 <= n <= n_nodes - 2:
                owner[n], weight[n] = k, 1.0 / count
    return owner, weight


@dataclass
class ControlIncrement:
    """Per-sim-step increments of one control step.

    dkappa: (B, N, 2) float64, added to ``Control.kappa_bar`` before each sim step (2D: [..., 1] = 0).
    dtau: (B, N) float64, added to ``Control.tau_bar`` (zeros unless the kind has twist).
    steps: number of sim steps that receive the increment (``substeps``, or 1 without the ramp).
    """

    dkappa: np.ndarray
    dtau: np.ndarray
    steps: int


class ActionConverter:
    """Batched delta natural-curvature converter (docs/tasks.md §2) for ``envs`` environments.

    State: ``K`` (B, P, C) float32 accumulated curvature per control point (C = 1 in 2D, 2 in 3D),
    ``T`` (B, P) float32 accumulated twist [rad]. ``kappa_obs`` / ``twist_obs`` give them in the
    observation layout (interleaved kappa1, kappa2 per point).
    """

    def __init__(self, cfg: ControlConfig, *, envs: int = 1):
        if int(envs) < 1:
            raise ValueError(f"ActionConverter: envs must be >= 1, got {envs}")
        self.cfg = cfg
        self.envs = int(envs)
        self.owner, self.weight = smoothing_weights(cfg.n_nodes, cfg.control_points, cfg.smoothing)
        self._nodes = np.nonzero(self.owner >= 0)[0]          # actuated nodes
        self._own = self.owner[self._nodes]                    # their control point
        self._w = self.weight[self._nodes]                     # their weight
        P, C = cfg.n_points, cfg.n_components
        self.K = np.zeros((self.envs, P, C), dtype=np.float32)
        self.T = np.zeros((self.envs, P), dtype=np.float32)

    # ------------------------------------------------------------------ state
    def reset(self, mask: np.ndarray | None = None) -> None:
        """Zero K and T of the envs in ``mask`` ((B,) bool; all if None)."""
        if mask is None:
            self.K[:] = 0.0
            self.T[:] = 0.0
        else:
            m = np.asarray(mask, dtype=bool)
            self.K[m] = 0.0
            self.T[m] = 0.0

    @property
    def kappa_obs(self) -> np.ndarray:
        """(B, P*C) float32: K interleaved (kappa1_0, kappa2_0, kappa1_1, ...) - ``curr_kappa_bar``."""
        return self.K.reshape(self.envs, -1)

    @property
    def twist_obs(self) -> np.ndarray:
        """(B, P) float32: T - ``curr_twist_bar``."""
        return self.T

    def natural_values(self) -> tuple[np.ndarray, np.ndarray]:
        """What the simulator holds after a full control step: ``(kappa (B,N,2), tau (B,N))`` = w_n * K/T."""
        kappa = np.zeros((self.envs, self.cfg.n_nodes, 2))
        tau = np.zeros((self.envs, self.cfg.n_nodes))
        C = self.cfg.n_components
        kappa[:, self._nodes, :C] = self._w[None, :, None] * self.K[:, self._own, :].astype(np.float64)
        if self.cfg.has_twist:
            tau[:, self._nodes] = self._w[None, :] * self.T[:, self._own].astype(np.float64)
        return kappa, tau

    # ------------------------------------------------------------------ step
    def check_action(self, action) -> np.ndarray:
        """Validate ``action`` -> (B, action_dim) float32 clipped to [-1, 1]; ValueError on bad shape / NaN."""
        a = np.asarray(action, dtype=np.float32)
        dim = self.cfg.action_dim
        if a.shape == (dim,) and self.envs == 1:
            a = a[None]
        if a.shape != (self.envs, dim):
            raise ValueError(
                f"action has shape {np.shape(action)}, expected ({self.envs}, {dim})"
                + (f" or ({dim},)" if self.envs == 1 else "")
                + f" for control kind {self.cfg.kind!r}"
            )
        if not np.all(np.isfinite(a)):
            bad = np.nonzero(~np.all(np.isfinite(a), axis=1))[0]
            raise ValueError(f"action contains NaN/inf (env rows {bad[:10].tolist()})")
        return np.clip(a, -1.0, 1.0)

    def convert(self, action) -> ControlIncrement:
        """Accumulate one control step's action (B, action_dim) in [-1, 1] and return the per-sim-step increment."""
        cfg = self.cfg
        a = self.check_action(action)
        B, P, C = self.envs, cfg.n_points, cfg.n_components
        a_bend = a[:, : cfg.bend_dim].reshape(B, P, C)
        lim = np.float32(cfg.kappa_limit)
        K_new = np.clip(self.K + np.float32(cfg.kappa_scale) * a_bend, -lim, lim)
        dK = K_new.astype(np.float64) - self.K.astype(np.float64)  # exact
        self.K = K_new
        steps = cfg.substeps if cfg.temporal_interpolation else 1
        dkappa = np.zeros((B, cfg.n_nodes, 2))
        dkappa[:, self._nodes, :C] = (self._w[None, :, None] * dK[:, self._own, :]) / steps
        dtau = np.zeros((B, cfg.n_nodes))
        if cfg.has_twist:
            tl = np.float32(cfg.twist_limit)
            T_new = np.clip(self.T + np.float32(cfg.twist_scale) * a[:, cfg.bend_dim:], -tl, tl)
            dT = T_new.astype(np.float64) - self.T.astype(np.float64)
            self.T = T_new
            dtau[:, self._nodes] = (self._w[None, :] * dT[:, self._own]) / steps
        return ControlIncrement(dkappa=dkappa, dtau=dtau, steps=steps)

    @staticmethod
    def apply(ctrl, inc: ControlIncrement, substep: int) -> None:
        """Add the increment for sim step ``substep`` (0-based) of the control step to ``ctrl`` in place.

        ``ctrl`` needs ``kappa_bar`` (B, N, 2) and ``tau_bar`` (B, N) float arrays (a ``sim.Control``).
        Without temporal interpolation only substep 0 receives the (whole) increment.
        """
        if substep >= inc.steps:
            return
        ctrl.kappa_bar += inc.dkappa
        ctrl.tau_bar += inc.dtau
