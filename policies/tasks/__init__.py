"""The four RL tasks of the paper (docs/tasks.md §4-7) and their gymnasium registration.

``TASKS`` maps short names to gymnasium ids; ``TASK_SPECS`` maps ids to (core class, env class,
default-config factory). :func:`register_tasks` registers every id with gymnasium (idempotent; run on
``import policies``). ``gymnasium.make(id)`` gives the single env (the batched core with B = 1),
``gymnasium.make_vec(id, num_envs=B, vectorization_mode="vector_entry_point")`` or
``policies.make_vec_env`` the batched VectorEnv. The table itself is :mod:`policies.tasks.registry` (plain data,
also read by ``policies.vec_env``).
"""
from __future__ import annotations

from typing import Any

from .registry import TASK_SPECS, TASKS, TaskEntry, field_slices, gym_task_id

__all__ = ["TASKS", "TASK_SPECS", "TaskEntry", "register_tasks", "gym_task_id", "field_slices"]


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
