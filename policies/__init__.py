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

from sim.support.lazy import lazy_face

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


__getattr__, __dir__ = lazy_face(__name__, _LAZY)

try:
    register_tasks()
except ImportError:  # pragma: no cover - gymnasium not installed: control/teleop still usable
    pass
