"""Scene / simulator construction for the tasks (the only module of policies/tasks that imports sim).

The task's scene file (``config.scene``, relative to the repository root) is loaded when it exists;
otherwise the paper's arm (docs/tasks.md §1.1) is built in code. Obstacle tasks add their capsules
(``task.scene_capsules()``) and the paper's contact settings when the scene has no obstacles. Either way the task config's solver
settings win over the file's ``[sim]`` table: dt, newton_max_iter, newton_tol, mode, and
``accept_unconverged = true`` (docs/tasks.md §1.2: fixed Newton budget, unconverged iterates accepted).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["REPO_ROOT", "scene_for", "make_simulator", "set_env_capsules"]

REPO_ROOT = Path(__file__).resolve().parents[2]


def _arm_scene_in_code(mode: str):
    from sim.scene import RodSpec, SceneSpec, SimSpec

    sim = SimSpec(dt=0.05, gravity=(0.0, 0.0, -9.8), newton_tol=1e-3, newton_max_iter=2, accept_unconverged=True,
                  mode=mode)  # type: ignore[arg-type]
    rod = RodSpec(nodes=21, length=1.0, radius=0.05, density=1000.0, youngs_modulus=1.0e7, poisson_ratio=0.5,
                  start=(0.0, 0.0, 0.0), direction=(0.0, 0.0, 1.0), clamp="first_edge")
    return SceneSpec(sim=sim, rod=rod)


def scene_for(config: Any, task: Any = None):
    """SceneSpec for a task config (file if present, else in code), with the task's solver settings."""
    from sim import load_scene

    spec = None
    if config.scene:
        p = Path(config.scene)
        p = p if p.is_absolute() else REPO_ROOT / p
        if p.exists():
            spec = load_scene(p)
    if spec is None:
        spec = _arm_scene_in_code(config.mode)
    if task is not None and hasattr(task, "scene_capsules"):
        ends, radius = task.scene_capsules()
        if not spec.obstacles:
            spec = _with_capsules(spec, ends, radius)
        elif getattr(task, "fixed_obstacles", False):
            _check_same_capsules(spec, ends, radius)
    sim = dataclasses.replace(spec.sim, dt=float(config.dt), newton_max_iter=int(config.newton_max_iter),
                              newton_tol=float(config.newton_tol), accept_unconverged=True, mode=config.mode)
    return dataclasses.replace(spec, sim=sim)


def _with_capsules(spec, ends: np.ndarray, radius: float):
    """Add capsule obstacles (M, 2, 3) [m] of ``radius`` [m] and the paper's contact settings
    (docs/tasks.md §1.3: k = 1e6, delta = 5e-3 m, broad-phase margin 5e-2 m, no friction)."""
    from sim.obstacles import CapsuleSpec, ContactSpec

    caps = tuple(CapsuleSpec(start=tuple(float(v) for v in e[0]), end=tuple(float(v) for v in e[1]),
                             radius=float(radius), name=f"obstacle_{i}") for i, e in enumerate(np.asarray(ends)))
    contact = ContactSpec(stiffness=1e6, delta=5e-3, friction=0.0, friction_velocity_tol=1e-2, margin=5e-2,
                          enabled=True)
    return dataclasses.replace(spec, obstacles=tuple(spec.obstacles) + caps, contact=contact)


def _check_same_capsules(spec, ends: np.ndarray, radius: float) -> None:
    got = [(o.start, o.end, o.radius) for o in spec.obstacles if getattr(o, "type", "") == "capsule"]
    want = [(tuple(e[0]), tuple(e[1]), radius) for e in np.asarray(ends, float)]
    same = len(got) == len(want) and all(np.allclose(g[0], w[0]) and np.allclose(g[1], w[1]) and
                                         abs(g[2] - w[2]) < 1e-12 for g, w in zip(got, want))
    if not same:
        raise ValueError(f"{spec.path}: the scene file's capsule obstacles differ from the task config's; "
                         "set scene=None to build the scene from the config")


def make_simulator(config: Any, *, envs: int, task: Any = None):
    """(Simulator(model, envs=B), model) for a task config."""
    from sim import Simulator, build_model

    model = build_model(scene_for(config, task))
    return Simulator(model, envs=envs), model


def set_env_capsules(sim, idx: np.ndarray, ends: np.ndarray, radius: float) -> None:
    """Move the capsule obstacles of envs ``idx`` to ``ends`` (len(idx), M, 2, 3) [m] (in place)."""
    ends = np.asarray(ends, dtype=np.float64)
    sim.obstacles.set_capsules(np.asarray(idx, dtype=np.int64), ends[:, :, 0], ends[:, :, 1], radius)
