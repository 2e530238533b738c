"""Scene / simulator construction for the tasks (the only module of policies/tasks that imports sim).

The task's scene file (``config.scene``) is loaded: a path starting with ``assets/`` names a shipped scene
(``sim.support.assets``, found in a checkout and in an installed rodlab alike), any other relative path is taken
relative to the working directory; a missing or invalid file is a ``SceneError`` (no fallback: the paper's arm (docs/tasks.md §1.1) has one source of truth, the shipped
``assets/scenes/arm.toml``, also used when ``config.scene`` is None). Obstacle tasks add their capsules
(``task.scene_capsules()``) and the paper's contact settings when the scene has no obstacles. Either way the task config's solver
settings win over the file's ``[sim]`` table: dt, newton_max_iter, newton_tol, mode, and
``accept_unconverged = true`` (docs/tasks.md §1.2: fixed Newton budget, unconverged iterates accepted).
"""
from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np
from sim import Simulator, build_model, load_scene
from sim.scene import CapsuleSpec, ContactSpec
from sim.support.assets import asset_path

__all__ = ["ARM_SCENE", "scene_for", "scene_path", "make_simulator", "set_env_capsules"]

ARM_SCENE = "assets/scenes/arm.toml"  # the paper's arm (docs/tasks.md §1.1)


def scene_for(config: Any, task: Any = None):
    """SceneSpec for a task config (``config.scene``, or the shipped arm when None), with the task's solver
    settings. A missing or invalid file raises SceneError naming it."""

    spec = load_scene(scene_path(config.scene or ARM_SCENE))
    if task is not None and hasattr(task, "scene_capsules"):
        ends, radius = task.scene_capsules()
        if not spec.obstacles:
            spec = _with_capsules(spec, ends, radius)
        elif getattr(task, "fixed_obstacles", False):
            _check_same_capsules(spec, ends, radius)
    sim = dataclasses.replace(spec.sim, dt=config.dt, newton_max_iter=config.newton_max_iter,
                              newton_tol=config.newton_tol, accept_unconverged=True, mode=config.mode)
    return dataclasses.replace(spec, sim=sim)


def scene_path(scene: str | Path) -> Path:
    """The file of a task config's ``scene``: absolute as given; ``assets/...`` the shipped asset; any other
    relative path relative to the working directory."""
    p = Path(scene)
    if p.is_absolute():
        return p
    return asset_path(p) if p.parts[:1] == ("assets",) else p


def _with_capsules(spec, ends: np.ndarray, radius: float):
    """Add capsule obstacles (M, 2, 3) [m] of ``radius`` [m] and the paper's contact settings
    (docs/tasks.md §1.3: k = 1e6, delta = 5e-3 m, broad-phase margin 5e-2 m, no friction)."""

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
                         "set scene=None to use the arm scene with the config's capsules")


def make_simulator(config: Any, *, envs: int, task: Any = None):
    """(Simulator(model, envs=B), model) for a task config."""

    model = build_model(scene_for(config, task))
    return Simulator(model, envs=envs), model


def set_env_capsules(sim, state, idx: np.ndarray, ends: np.ndarray, radius: float) -> None:
    """Move the capsule obstacles of envs ``idx`` of ``state`` (their poses are arrays of the state) to ``ends``
    (len(idx), M, 2, 3) [m] (in place), through ``sim.set_capsules`` (a ``sim.Simulator`` or the PyElastica
    back-end's stand-in)."""
    ends = np.asarray(ends, dtype=np.float64)
    sim.set_capsules(state, np.asarray(idx, dtype=np.int64), ends[:, :, 0], ends[:, :, 1], radius)
