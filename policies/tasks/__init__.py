"""The four RL tasks of the paper (docs/tasks.md §4-7) and their gymnasium registration.

``TASKS`` maps short names to gymnasium ids; ``TASK_SPECS`` maps ids to (core class, env class,
default-config factory). :func:`register_tasks` registers every id with gymnasium (idempotent; run on
``import policies``). ``gymnasium.make(id)`` gives the single env (the batched core with B = 1),
``gymnasium.make_vec(id, num_envs=B, vectorization_mode="vector_entry_point")`` or
``policies.make_vec_env`` the batched VectorEnv.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

__all__ = ["TASKS", "TASK_SPECS", "TaskEntry", "register_tasks", "gym_task_id"]

TASKS: dict[str, str] = {
    "follow_target": "rodlab/FollowTarget-v0",
    "follow_target_2d": "rodlab/FollowTarget2D-v0",
    "ik4d": "rodlab/IK4D-v0",
    "tight_obstacles_2d": "rodlab/TightObstacles2D-v0",
    "random_obstacles_3d": "rodlab/RandomObstacles3D-v0",
}


@dataclass(frozen=True)
class TaskEntry:
    """module: policies.tasks submodule; env / core: class names; config: default-config factory name."""

    module: str
    env: str
    core: str
    config: str

    def load(self) -> tuple[type, type, Callable[[], Any]]:
        import importlib

        m = importlib.import_module(f"policies.tasks.{self.module}")
        return getattr(m, self.env), getattr(m, self.core), getattr(m, self.config)


TASK_SPECS: dict[str, TaskEntry] = {
    "rodlab/FollowTarget-v0": TaskEntry("follow_target", "FollowTargetEnv", "FollowTargetCore", "default_config"),
    "rodlab/FollowTarget2D-v0": TaskEntry("follow_target", "FollowTarget2DEnv", "FollowTargetCore",
                                          "default_config_2d"),
    "rodlab/IK4D-v0": TaskEntry("ik4d", "IK4DEnv", "IK4DCore", "default_config"),
    "rodlab/TightObstacles2D-v0": TaskEntry("tight_obstacles_2d", "TightObstacles2DEnv", "TightObstacles2DCore",
                                            "default_config"),
    "rodlab/RandomObstacles3D-v0": TaskEntry("random_obstacles_3d", "RandomObstacles3DEnv",
                                             "RandomObstacles3DCore", "default_config"),
}


def gym_task_id(task: str) -> str:
    """Short name or gymnasium id -> gymnasium id (ValueError naming the choices otherwise)."""
    if task in TASK_SPECS:
        return task
    if task in TASKS:
        return TASKS[task]
    raise ValueError(f"unknown task {task!r}; expected one of {sorted(TASKS)} or {sorted(TASK_SPECS)}")


def register_tasks() -> None:
    """Register the five ids with gymnasium (entry_point: single env; vector_entry_point: BatchedVecEnv)."""
    import functools

    import gymnasium as gym

    for tid, e in TASK_SPECS.items():
        if tid in gym.registry:
            continue
        gym.register(id=tid, entry_point=f"policies.tasks.{e.module}:{e.env}",
                     vector_entry_point=functools.partial(_vector_entry_point, tid), disable_env_checker=False,
                     order_enforce=True, kwargs={}, additional_wrappers=())


def _vector_entry_point(task_id: str, num_envs: int = 1, **kwargs: Any):
    from policies.vec_env import make_vec_env

    return make_vec_env(task_id, num_envs, **kwargs)
