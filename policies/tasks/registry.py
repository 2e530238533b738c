"""The task table: short names -> gymnasium ids (``TASKS``), ids -> (module, env class, core class, default-config
factory) (``TASK_SPECS``), and :func:`gym_task_id`. Plain data, read by ``policies.tasks`` (gymnasium registration)
and ``policies.vec_env``; it imports no task module (each is loaded on demand by :meth:`TaskEntry.load`)."""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any, Callable

__all__ = ["TASKS", "TASK_SPECS", "TaskEntry", "gym_task_id", "field_slices"]

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


def field_slices(fields) -> dict[str, slice]:
    """Each field's columns in an observation that concatenates ``fields`` ((name, size), … in order: a task
    core's ``obs_fields``)."""
    out, off = {}, 0
    for name, size in fields:
        out[name] = slice(off, off + int(size))
        off += int(size)
    return out
