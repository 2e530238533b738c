"""rodlab realisations of the accuracy scenes (:mod:`benchmarks.scenes`).

Every runner builds a scene in code (through the validating ``sim.scene.spec.parse_scene``), simulates one
env and returns a dict with the wall time of the stepping loop ``wall_s`` [s] (setup and numba warm-up
excluded), ``sim_s`` [s], ``stable``, the sampled output and Newton statistics
(``newton_iters_mean``, ``newton_iters_max``, ``substeps_max``, ``failed``, ``unconverged_frac``).

Solver settings are passed as a :class:`Solver`; :data:`PAPER` is the paper's RL setting (2 Newton
iterations, ftol 1e-3, unconverged iterates accepted) and :data:`CONVERGED` a tight one.
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .scenes import ArmCommand, DynamicCantilever, StaticCantilever

Mode = Literal["3d", "2d"]
Integrator = Literal["backward_euler", "midpoint"]


@dataclass(frozen=True)
class Solver:
    """Newton settings: relative force tolerance ``tol``, displacement tolerance ``dtol`` [m/s],
    iteration cap ``max_iter``, and whether an unconverged iterate is accepted."""

    tol: float = 1e-3
    max_iter: int = 2
    dtol: float = 1e-2
    accept_unconverged: bool = True
    integrator: Integrator = "backward_euler"
    line_search: Literal["none", "backtrack"] = "none"

    @property
    def label(self) -> str:
        return f"it{self.max_iter}_tol{self.tol:g}"


PAPER = Solver(tol=1e-3, max_iter=2, dtol=1e-2, accept_unconverged=True)
CONVERGED = Solver(tol=1e-10, max_iter=30, dtol=1e-8, accept_unconverged=True)


def scene_dict(*, nodes: int, length: float, radius: float, density: float, youngs: float, poisson: float,
               start=(0.0, 0.0, 0.0), direction=(0.0, 0.0, 1.0), dt: float, gravity=(0.0, 0.0, -9.8),
               damping: float = 0.0, solver: Solver = PAPER, mode: Mode = "3d",
               obstacles: list | None = None, contact: dict | None = None) -> dict:
    """The TOML-equivalent dict of a one-rod scene (see sim/scene/spec.py for the keys)."""
    d = {
        "sim": {"dt": float(dt), "gravity": [float(g) for g in gravity], "damping": float(damping),
                "newton_tol": float(solver.tol), "newton_max_iter": int(solver.max_iter),
                "accept_unconverged": bool(solver.accept_unconverged), "mode": mode,
                "integrator": solver.integrator, "line_search": solver.line_search,
                "newton_dtol": float(solver.dtol)},
        "rod": {"nodes": int(nodes), "length": float(length), "radius": float(radius),
                "density": float(density), "youngs_modulus": float(youngs), "poisson_ratio": float(poisson),
                "start": [float(s) for s in start], "direction": [float(s) for s in direction]},
    }
    if obstacles:
        d["obstacle"] = obstacles
    if contact:
        d["contact"] = contact
    return d


def make_sim(doc: dict, *, envs: int = 1):
    """(Simulator, State, Control) of a scene dict."""
    from sim import Simulator, build_model
    from sim.scene import parse_scene
    model = build_model(parse_scene(doc))
    sim = Simulator(model, envs=envs)
    state = sim.reset()
    ctrl = sim.make_control()
    return sim, state, ctrl


class _Stats:
    def __init__(self) -> None:
        self.iters: list[np.ndarray] = []
        self.substeps_max = 1
        self.failed = 0
        self.unconverged = 0
        self.steps = 0

    def add(self, st) -> None:
        self.iters.append(np.asarray(st.newton_iters).copy())
        self.substeps_max = max(self.substeps_max, int(np.max(st.substeps)))
        self.failed += int(np.sum(st.failed))
        self.unconverged += int(np.sum(~np.asarray(st.converged)))
        self.steps += int(np.size(st.converged))

    def summary(self) -> dict:
        it = np.concatenate(self.iters) if self.iters else np.zeros(1)
        return {"newton_iters_mean": float(it.mean()), "newton_iters_max": int(it.max()),
                "substeps_max": self.substeps_max, "failed": self.failed,
                "unconverged_frac": self.unconverged / max(1, self.steps)}


def _finite(state) -> bool:
    return bool(np.all(np.isfinite(state.dof))) and not bool(np.any(state.failed))


def run_static(scene: StaticCantilever, *, n_nodes: int, dt: float, solver: Solver = CONVERGED,
               mode: Mode = "3d") -> dict:
    """Heavy cantilever until ``scene.t_end``; tip (x, z) [m] at the end."""
    doc = scene_dict(nodes=n_nodes, length=scene.length, radius=scene.radius, density=scene.density,
                     youngs=scene.youngs, poisson=scene.poisson, direction=(1.0, 0.0, 0.0), dt=dt,
                     gravity=(0.0, 0.0, -scene.g), damping=scene.damping, solver=solver, mode=mode)
    sim, state, ctrl = make_sim(doc)
    n = max(1, int(round(scene.t_end / dt)))
    stats = _Stats()
    t0, c0 = time.perf_counter(), time.process_time()
    for _ in range(n):
        stats.add(sim.step(state, ctrl))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    tip = np.asarray(state.node_pos[0, -1])
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": n * dt, "stable": _finite(state), "tip": [tip[0], tip[2]],
            **stats.summary()}


def run_dynamic(scene: DynamicCantilever, *, n_nodes: int, dt: float, solver: Solver = CONVERGED,
                mode: Mode = "3d") -> dict:
    """Euler-Bernoulli cantilever; tip z [m] after every step."""
    doc = scene_dict(nodes=n_nodes, length=scene.length, radius=scene.radius, density=scene.density,
                     youngs=scene.youngs, poisson=scene.poisson, direction=(1.0, 0.0, 0.0), dt=dt,
                     gravity=(0.0, 0.0, 0.0), damping=0.0, solver=solver, mode=mode)
    sim, state, ctrl = make_sim(doc)
    x = np.linspace(0.0, scene.length, n_nodes)
    v = scene.beam.initial_velocity(x)
    v[:2] = 0.0  # nodes 0 and 1 are clamped (first edge locked)
    state.dof_vel[0, :, 2 if mode == "3d" else 1] = v
    n = max(1, int(round(scene.t_end / dt)))
    ts, zs = [0.0], [0.0]
    stats = _Stats()
    t0, c0 = time.perf_counter(), time.process_time()
    for k in range(n):
        stats.add(sim.step(state, ctrl))
        ts.append((k + 1) * dt)
        zs.append(float(state.node_pos[0, -1, 2]))
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": n * dt, "stable": _finite(state), "t": ts, "z": zs, **stats.summary()}


def run_arm(scene: ArmCommand, *, n_nodes: int, dt: float, solver: Solver = CONVERGED,
            sample_dt: float | None = None) -> dict:
    """Paper arm with the curvature command set before every step; tip (K, 3) [m] sampled every
    step (or every ``sample_dt`` if given and larger than dt)."""
    cyl = getattr(scene, "cyl_ends", None)
    obstacles = ([{"type": "capsule", "start": list(cyl[0]), "end": list(cyl[1]), "radius": scene.cyl_radius}]
                 if cyl else None)
    contact = {"stiffness": 1e6, "delta": 5e-3, "friction": 0.0} if cyl else None
    doc = scene_dict(nodes=n_nodes, length=scene.length, radius=scene.radius, density=scene.density,
                     youngs=scene.youngs, poisson=scene.poisson, dt=dt, gravity=(0.0, 0.0, -scene.g),
                     damping=scene.damping, solver=solver, obstacles=obstacles, contact=contact)
    sim, state, ctrl = make_sim(doc)
    pen = 0.0
    n = max(1, int(round(scene.t_end / dt)))
    every = 1 if sample_dt is None else max(1, int(round(sample_dt / dt)))
    ts, tips = [0.0], [np.asarray(state.node_pos[0, -1]).tolist()]
    stats = _Stats()
    kb = ctrl.kappa_bar
    t0, c0 = time.perf_counter(), time.process_time()
    for k in range(n):
        kb[0] = scene.integrated_kappa((k + 1) * dt, n_nodes)
        st = sim.step(state, ctrl)
        stats.add(st)
        if cyl:
            pen = max(pen, float(np.max(st.max_penetration)))
        if (k + 1) % every == 0:
            ts.append((k + 1) * dt)
            tips.append(np.asarray(state.node_pos[0, -1]).tolist())
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": n * dt, "stable": _finite(state), "t": ts, "tip": tips,
            "max_penetration": pen, **stats.summary()}
