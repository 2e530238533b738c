"""The single gymnasium Env of a task: the batched core with B = 1 (same code path as the VectorEnv)."""
from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from .base import OBS_LIMIT, BatchedTask, TaskConfig, child_generator

__all__ = ["RodTaskEnv", "observation_space", "action_space"]


def observation_space(core: BatchedTask) -> gym.spaces.Box:
    """Box(-1e6, 1e6, (obs_dim,), float32): observations are sanitised (NaN -> 0, clipped to +-1e6)."""
    return gym.spaces.Box(-OBS_LIMIT, OBS_LIMIT, shape=(core.obs_dim,), dtype=np.float32)


def action_space(core: BatchedTask) -> gym.spaces.Box:
    """Box(-1, 1, (action_dim,), float32)."""
    return gym.spaces.Box(-1.0, 1.0, shape=(core.action_dim,), dtype=np.float32)


class RodTaskEnv(gym.Env):
    """Base of the per-task single envs. Subclasses set ``core_cls`` and ``default_config``.

    ``reset(seed=s, options={"env_index": i})`` seeds the env with child i of ``SeedSequence(s)``, i.e.
    exactly like env i of ``make_vec_env(task, B, seed=s)`` (default i = 0). ``info`` holds the
    per-term rewards (``reward/<term>``), ``failed``, ``failure_reason`` and solver counters.
    Stepping after ``terminated``/``truncated`` without ``reset`` continues the episode (the counter
    keeps growing; a failed simulator env stays frozen and keeps returning the failure reward).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": []}
    core_cls: ClassVar[type[BatchedTask]] = BatchedTask
    config_cls: ClassVar[type[TaskConfig]] = TaskConfig

    def __init__(self, config: TaskConfig | None = None, *, render_mode: str | None = None, **overrides: Any):
        if render_mode is not None:
            raise ValueError(f"{type(self).__name__}: render_mode {render_mode!r} not supported "
                             "(use `rodlab record` / the workbench to visualise)")
        cfg = self.config_cls() if config is None else config
        if overrides:
            import dataclasses

            cfg = dataclasses.replace(cfg, **overrides)
        self.config = cfg
        self.core = self.core_cls(cfg, envs=1)
        self.observation_space = observation_space(self.core)
        self.action_space = action_space(self.core)
        self._seeded = False

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        options = options or {}
        index = int(options.get("env_index", 0))
        if seed is not None:
            self.core.rngs = [child_generator(seed, index)]
            self._seeded = True
        elif not self._seeded:
            self.core.seed(None)
            self._seeded = True
        obs = self.core.reset()
        return obs[0], {}

    def step(self, action):
        a = np.asarray(action, dtype=np.float32)
        if a.shape != (self.core.action_dim,):
            raise ValueError(f"{type(self).__name__}.step: action has shape {a.shape}, "
                             f"expected ({self.core.action_dim},)")
        obs, rew, term, trunc, info = self.core.step(a[None])
        row = {k: (v[0].item() if isinstance(v[0], np.generic) else v[0]) for k, v in info.items()}
        return obs[0], float(rew[0]), bool(term[0]), bool(trunc[0]), row

    def close(self) -> None:
        self.core.close()
