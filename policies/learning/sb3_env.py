"""The environments training and evaluation run on: task names (a rodlab task or a gymnasium id) and the SB3 VecEnv
of a task (``make_sb3_env``). Used by ``policies.learning.training`` (which re-exports these names), ``policies.learning.evaluation`` and
``policies.learning.sweep``; it imports neither of them."""
from __future__ import annotations

__all__ = ["TrainError", "task_short_name", "make_sb3_env"]


class TrainError(Exception):
    """Bad training input (unknown task, inconsistent resume) with a readable message."""


def task_short_name(name: str) -> str:
    """Short task name (policies.TASKS) or a gymnasium id (tests: 'Pendulum-v1') -> canonical name."""
    import policies

    tasks = policies.TASKS
    if name in tasks:
        return name
    for short, tid in dict(tasks).items():
        if name == tid:
            return short
    import gymnasium as gym

    if name in gym.registry:
        return name
    known = ", ".join(sorted(tasks))
    raise TrainError(f"unknown task {name!r}; known tasks: {known} (or a gymnasium id such as Pendulum-v1)")


def make_sb3_env(task: str, num_envs: int, seed: int):
    """SB3 VecEnv for a rodlab task (batched env + adapter) or a gymnasium id (DummyVecEnv)."""
    import policies

    task = task_short_name(task)
    if task in (getattr(policies, "TASKS", {}) or {}):
        venv = policies.make_vec_env(task, num_envs, seed=seed)
        return policies.SB3VecEnvAdapter(venv)  # its reward_terms observer: the per-term rewards for logging
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv

    return make_vec_env(task, n_envs=num_envs, seed=seed, vec_env_cls=DummyVecEnv)
