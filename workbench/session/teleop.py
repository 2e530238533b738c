"""Hand control of the rod: absolute natural curvature per control point, or delta actions
through the same action converter as the tasks (``policies.control.ActionConverter``).

Control points are nodes 2, 6, 10, 14, 18 (docs/tasks.md §2.1); each carries (κ1, κ2, twist).
Absolute mode writes ``w_n · K_k`` into the natural curvature / twist of every node n owned by
control point k (the converter's spatial weights, docs/tasks.md §2.4, ``natural_values()``). Delta mode feeds the slider
values as an action in [-1, 1] to the converter once per control step and adds its per-sim-step
increments, exactly as a task does.
"""
from __future__ import annotations

import copy
import types
from typing import Literal

import numpy as np

from policies.control import ActionConverter, control_config

TeleopMode = Literal["absolute", "delta"]
COMPONENTS = ("k1", "k2", "twist")
CONTROL_NODES = (2, 6, 10, 14, 18)  # the paper's arm (21 nodes)
MIN_NODES = 7  # the five control points need five distinct interior nodes
KAPPA_LIMIT = 2.0
TWIST_LIMIT = float(np.pi / 2)


def control_points(n_nodes: int) -> tuple[int, ...]:
    """The five teleop control points of a rod of ``n_nodes`` nodes, spread evenly from node 2 to node N − 3 (the
    paper's 2, 6, 10, 14, 18 at 21 nodes; from node 1 to N − 2 on a rod of 7 or 8 nodes). ValueError below 7."""
    n = int(n_nodes)
    if n < MIN_NODES:
        raise ValueError(f"the workbench steers a rod through five control points: it needs at least {MIN_NODES} "
                         f"nodes, this rod has {n}")
    lo, hi = (2, n - 3) if n >= 9 else (1, n - 2)
    return tuple(int(round(lo + i * (hi - lo) / 4)) for i in range(5))


def make_converter(*, n_nodes: int = 21, substeps: int = 2):
    """The tasks' converter for the 15-dim bend + twist action (s_κ = s_τ = 0.05) at the rod's control points
    (:func:`control_points`), B = 1."""

    return ActionConverter(control_config("bend_twist", substeps=substeps, n_nodes=n_nodes,
                                          control_points=control_points(n_nodes)), envs=1)


class Teleop:
    """Slider values → natural curvature/twist of a live rod.

    Args:
        n_nodes: nodes of the rod.
        substeps: sim steps per control step (delta mode applies increments over these).
        first_node: index of the rod's first node in the scene's chain of nodes (a scene of several rods).
    """

    def __init__(self, *, n_nodes: int = 21, substeps: int = 2, first_node: int = 0):
        self.n_nodes = n_nodes
        self.first_node = int(first_node)
        self.substeps = substeps
        self.mode: TeleopMode = "absolute"
        self.values = np.zeros((5, 3))  # absolute: K1, K2, T per control point; delta: action in [-1, 1]
        self.converter = make_converter(n_nodes=n_nodes, substeps=substeps)
        self._pending = None
        self._sub = 0

    # ---------------------------------------------------------------- state
    def snapshot(self) -> dict:
        return copy.deepcopy({"mode": self.mode, "values": self.values, "conv": self.converter,
                              "pending": self._pending, "sub": self._sub})

    def restore(self, snap: dict) -> None:
        snap = copy.deepcopy(snap)
        self.mode, self.values, self.converter = snap["mode"], snap["values"], snap["conv"]
        self._pending, self._sub = snap["pending"], snap["sub"]

    def reset(self) -> None:
        self.values[:] = 0.0
        self.converter.reset()
        self._pending, self._sub = None, 0

    def set_mode(self, mode: TeleopMode) -> None:
        if mode not in ("absolute", "delta"):
            raise ValueError(f"teleop mode must be 'absolute' or 'delta', got {mode!r}")
        if mode == self.mode:
            return
        if mode == "absolute":  # sliders show the accumulated values the converter reached
            self.values[:] = self.accumulated()
        else:  # converter continues from what the sliders had set
            self._set_converter(self.values[:, :2], self.values[:, 2])
            self.values[:] = 0.0
        self.mode = mode
        self._pending, self._sub = None, 0

    def set_value(self, k: int, comp: int, value: float) -> None:
        lim = (TWIST_LIMIT if comp == 2 else KAPPA_LIMIT) if self.mode == "absolute" else 1.0
        self.values[k, comp] = float(np.clip(value, -lim, lim))

    def control_nodes(self) -> tuple[int, ...]:
        """The steered rod's control points as indices into the scene's chain of nodes."""
        return tuple(self.first_node + int(c) for c in self.converter.cfg.control_points)

    def accumulated(self) -> np.ndarray:
        """(5, 3) the natural (κ1, κ2, twist) per control point currently commanded."""
        if self.mode == "absolute":
            return self.values.copy()
        c = self.converter
        return np.concatenate([c.K[0].astype(np.float64), c.T[0].astype(np.float64)[:, None]], axis=1)

    def _set_converter(self, K: np.ndarray, T: np.ndarray) -> None:
        self.converter.K[0] = np.clip(K, -KAPPA_LIMIT, KAPPA_LIMIT)
        self.converter.T[0] = np.clip(T, -TWIST_LIMIT, TWIST_LIMIT)

    # ---------------------------------------------------------------- apply
    def apply(self, ctrl, rest=None) -> None:
        """Write this sim step's control into ``ctrl`` (a sim ``Control`` with B = 1); ``rest``: the
        rest-shape control (absolute values are added to it). In a scene of several rods teleop steers one rod
        (``n_nodes`` nodes from ``first_node`` in the chain); the others keep the control they last had."""
        if ctrl.kappa_bar.shape[1] > self.n_nodes:
            a, b = self.first_node, self.first_node + self.n_nodes
            ctrl, rest = _rod_view(ctrl, a, b), None if rest is None else _rod_view(rest, a, b)
        if self.mode == "absolute":
            self._set_converter(self.values[:, :2], self.values[:, 2])
            kappa, tau = self.converter.natural_values()
            ctrl.kappa_bar[...] = kappa + (0.0 if rest is None else rest.kappa_bar)
            ctrl.tau_bar[...] = tau + (0.0 if rest is None else rest.tau_bar)
            return
        if self._pending is None or self._sub >= self.substeps:
            action = np.concatenate([self.values[:, :2].reshape(-1), self.values[:, 2]])
            self._pending = self.converter.convert(action[None])
            self._sub = 0
        self.converter.apply(ctrl, self._pending, self._sub)
        self._sub += 1


def _rod_view(ctrl, a: int, b: int) -> types.SimpleNamespace:
    """Views of a Control's nodes a..b-1 (writes reach ``ctrl``)."""
    return types.SimpleNamespace(kappa_bar=ctrl.kappa_bar[:, a:b], tau_bar=ctrl.tau_bar[:, a:b])
