"""Static equilibrium (``rodlab sim --static``; docs/physics.md §3.8): pseudo-time continuation with
backward-Euler steps whose step size grows to ``dt_max`` and whose velocities are zeroed before every step.

A backward-Euler step from rest solves ``M (x − x0)/h² + ∇E(x) − F = 0``; as ``h`` grows the inertia term fades
and the step becomes a Newton solve of the static residual ``∇E(x) = F`` regularised by ``M/h²``. Starting from the
scene's ``dt`` and multiplying ``h`` by ``growth`` after every step keeps the first steps small (robust from a far
start); a step whose env fails is undone and retried with ``h`` divided by ``growth``. Each step's Newton solve
ends when an update moves no free position by more than ``xtol · L / 10`` (``L`` the rod length; with several
rods the longest) or by the force
test. Stopping rule, per env: ``h`` has reached ``dt_max`` and the whole step moved no free position DOF by more
than ``xtol · L``: a Newton step on the (barely regularised) static residual then changes nothing at that scale.

The point loads active at each env's time act in full (their windows are not integrated over the pseudo-time),
prescribed motion is off (fixed DOFs stay where the State holds them) and damping is 0.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .model import build_model
from .scene import SceneSpec
from .step import Simulator

__all__ = ["StaticResult", "static_spec", "solve_static"]


@dataclasses.dataclass
class StaticResult:
    """Per env (B,): converged, steps taken, the last step's largest free position change [m] and Newton
    residual; ``dt`` the final pseudo-time step [s]."""

    converged: np.ndarray
    steps: np.ndarray
    last_move: np.ndarray
    residual: np.ndarray
    dt: float


def static_spec(spec: SceneSpec, time: float, dt: float, dx_stop: float) -> SceneSpec:
    """The spec of a static pseudo-step of size ``dt`` at ``time``: loads active at ``time`` always on, no
    prescribed motion, no damping, backward Euler with backtracking; its Newton solve stops when an update moves
    no free position by more than ``dx_stop`` [m] (or by the force test)."""
    loads = tuple(dataclasses.replace(ld, start=0.0, stop=None) for ld in spec.loads
                  if ld.start <= time < (math.inf if ld.stop is None else ld.stop))
    fixes = tuple(dataclasses.replace(fx, velocity=(0.0, 0.0, 0.0), twist_rate=0.0, start=0.0, stop=None)
                  for fx in spec.fixes)
    sim = dataclasses.replace(spec.sim, dt=dt, damping=0.0, integrator="backward_euler", line_search="backtrack",
                              newton_dtol=max(dx_stop / dt, 1e-300), newton_tol=min(spec.sim.newton_tol, 1e-10),
                              newton_max_iter=max(spec.sim.newton_max_iter, 50), accept_unconverged=True)
    return dataclasses.replace(spec, sim=sim, loads=loads, fixes=fixes)


def solve_static(spec: SceneSpec, state: Any, ctrl: Any, *, xtol: float = 1e-10, dt_max: float = 1e5,
                 growth: float = 10.0, max_steps: int = 200) -> StaticResult:
    """Relax ``state`` (of a Simulator of ``spec``; changed in place) to static equilibrium under ``ctrl``.

    All envs share the pseudo-time step; envs that have converged keep stepping (their moves stay below the
    tolerance). ``state.time`` is left unchanged."""
    if not (xtol > 0 and dt_max >= spec.sim.dt and growth > 1 and max_steps >= 1):
        raise ValueError("solve_static: need xtol > 0, dt_max >= the scene's dt, growth > 1, max_steps >= 1")
    B = state.dof.shape[0]
    t = float(state.time[0]) if B else 0.0
    if B and not np.all(state.time == t):
        raise ValueError("solve_static: all envs must be at the same time (the active loads depend on it)")
    time0 = state.time.copy()
    sims: dict[float, Simulator] = {}
    h = float(spec.sim.dt)
    length = max(float(r.length) for r in spec.rods)
    conv = np.zeros(B, bool)
    steps = np.zeros(B, np.int64)
    move = np.full(B, np.inf)
    res = np.full(B, np.inf)
    free = None
    for _ in range(max_steps):
        if h not in sims:
            sims[h] = Simulator(build_model(static_spec(spec, t, h, 0.1 * xtol * length)), envs=B)
        sim = sims[h]
        if free is None:
            m = sim.model
            dpn = m.dofs_per_node
            pos_dof = (np.arange(m.node_count * dpn) % dpn) < (3 if dpn == 4 else 2)
            free = np.flatnonzero(pos_dof & ~m.dof_fixed)
        before = state.copy()
        state.dof_vel[...] = 0.0
        stats = sim.step(state, ctrl)
        if state.failed.any():  # undo the step in every env and shrink the pseudo-time step
            _restore(state, before)
            if h <= spec.sim.dt:
                break
            h = max(float(spec.sim.dt), h / growth)
            continue
        steps += 1
        d = np.abs(state.dof.reshape(B, -1)[:, free] - before.dof.reshape(B, -1)[:, free])
        move = d.max(axis=1) if free.size else np.zeros(B)
        res = stats.residual
        conv = (h >= dt_max) & (move <= xtol * length)
        if conv.all():
            break
        h = min(dt_max, h * growth)
    state.dof_vel[...] = 0.0
    state.time[:] = time0
    return StaticResult(converged=conv, steps=steps, last_move=move, residual=np.asarray(res), dt=h)


def _restore(state: Any, before: Any) -> None:
    for name in ("dof", "dof_vel", "edge_ref_d1", "edge_tangent", "node_ref_twist", "time", "failed"):
        getattr(state, name)[...] = getattr(before, name)
