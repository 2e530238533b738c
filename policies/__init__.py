"""rodlab policies: action converter, the four RL tasks, batched vector envs (training lives beside).

Public surface::

    from policies import make_vec_env, TASKS, SB3VecEnvAdapter
    venv = make_vec_env("follow_target", 500, seed=0)       # BatchedVecEnv (gymnasium VectorEnv)
    sb3_env = SB3VecEnvAdapter(venv)                         # stable-baselines3 VecEnv

``import policies`` registers rodlab/FollowTarget-v0, rodlab/FollowTarget2D-v0, rodlab/IK4D-v0,
rodlab/TightObstacles2D-v0 and rodlab/RandomObstacles3D-v0 with gymnasium (when gymnasium is
installed). Names are resolved lazily, so ``policies.control`` (numpy only) works without gymnasium.
"""
from __future__ import annotations

import importlib
from typing import Any

from .tasks import TASK_SPECS, TASKS, gym_task_id, register_tasks

__all__ = [
    "ActionConverter",
    "ControlConfig",
    "control_config",
    "TASKS",
    "TASK_SPECS",
    "register_tasks",
    "gym_task_id",
    "BatchedVecEnv",
    "SB3VecEnvAdapter",
    "make_vec_env",
]

_LAZY = {
    "ActionConverter": "policies.control",
    "ControlConfig": "policies.control",
    "control_config": "policies.control",
    "BatchedVecEnv": "policies.vec_env",
    "SB3VecEnvAdapter": "policies.vec_env",
    "make_vec_env": "policies.vec_env",
}


def __getattr__(name: str) -> Any:
    mod = _LAZY.get(name)
    if mod is None:
        raise AttributeError(f"module 'policies' has no attribute {name!r}")
    value = getattr(importlib.import_module(mod), name)
    globals()[name] = value
    return value


try:
    register_tasks()
except ImportError:  # pragma: no cover - gymnasium not installed: control/teleop still usable
    pass
