"""Batched vector environment over one simulator, and its stable-baselines3 adapter.

:class:`BatchedVecEnv` is a ``gymnasium.vector.VectorEnv`` whose B sub-environments are ONE task
core (one ``sim.Simulator(envs=B)``; converter, targets and rewards vectorised in numpy), so a step
of 500 envs is a handful of numpy calls plus ``substeps`` batched simulator calls.

Autoreset: **SAME_STEP** (``metadata["autoreset_mode"] = AutoresetMode.SAME_STEP``). When env i
ends (terminated or truncated) inside ``step``, the returned ``obs[i]`` is already the first
observation of its next episode; the last observation of the finished episode is in
``info["final_obs"][i]`` (object array, mask ``info["_final_obs"]``) and that step's info in
``info["final_info"]`` (dict of arrays, mask ``info["_final_info"]``). The top-level info arrays hold
the values of the step just taken for every env (done ones included). Rewards/terminated/truncated
are those of the finished step. ``reset(options={"reset_mask": m})`` resets only the envs in ``m`` (a
boolean mask of length B, or integer env indices).

Seeding: ``reset(seed=s)`` (or ``make_vec_env(..., seed=s)``) gives env i the generator
``PCG64(SeedSequence(s).spawn(B)[i])``; ``reset(seed=[s_0, ..., s_{B-1}])`` gives env i
``PCG64(SeedSequence(s_i).spawn(1)[0])``. A single env reproduces env i of a batch seeded ``s`` with
``env.reset(seed=s, options={"env_index": i})``; later episodes follow from the same generator.
"""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from sim.scene import env_mask  # a boolean mask, or integer env indices (never guessed)

from .tasks.base import BatchedTask, RewardTermsObserver, check_field_value
from .tasks.env import action_space, observation_space
from .tasks.registry import TASK_SPECS, gym_task_id

__all__ = ["BatchedVecEnv", "SB3VecEnvAdapter", "make_vec_env", "vector_entry_point", "check_overrides"]


class BatchedVecEnv(VectorEnv):
    """Gymnasium VectorEnv of ``core.envs`` envs stepped in one batched simulator call (SAME_STEP autoreset)."""

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP, "render_modes": []}

    def __init__(self, core: BatchedTask, *, task_id: str | None = None):
        self.core = core
        self.task_id = task_id
        self.num_envs = core.envs
        self.single_observation_space = observation_space(core)
        self.single_action_space = action_space(core)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.metadata = dict(type(self).metadata)
        self._mask_all = np.ones(self.num_envs, dtype=bool)

    @property
    def config(self):
        return self.core.config

    def reset(self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None):
        """Reset all envs (or ``options["reset_mask"]``); ``seed`` re-seeds every env (see module doc)."""
        if seed is not None:
            self.core.seed(seed)
            self._np_random_seed = seed if isinstance(seed, int) else None
        mask = None
        if options and "reset_mask" in options:

            mask = env_mask(options["reset_mask"], self.num_envs, "reset_mask")
        obs = self.core.reset(mask)
        return obs, {}

    def step(self, actions):
        obs, rew, term, trunc, info = self.core.step(actions)
        done = term | trunc
        mask = self._mask_all
        out: dict[str, Any] = {}
        for k, v in info.items():
            out[k] = v
            out["_" + k] = mask
        if done.any():
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in np.nonzero(done)[0]:
                final_obs[i] = obs[i].copy()
            fi: dict[str, Any] = {}
            for k, v in info.items():
                fi[k] = v
                fi["_" + k] = done
            out["final_obs"], out["_final_obs"] = final_obs, done.copy()
            out["final_info"], out["_final_info"] = fi, done.copy()
            obs = self.core.reset(done)
        return obs, rew, term, trunc, out

    def close_extras(self, **kwargs: Any) -> None:
        self.core.close()

    def __repr__(self) -> str:
        return f"BatchedVecEnv({self.task_id or type(self.core).__name__}, num_envs={self.num_envs})"


def make_vec_env(task: str, num_envs: int, *, seed: int | None = None, config: Any = None,
                 **overrides: Any) -> BatchedVecEnv:
    """Batched VectorEnv of ``num_envs`` envs of ``task`` (short name from ``TASKS`` or gymnasium id).

    config: the task's config dataclass (default: the task's ``default_config()``); ``overrides``
    replace single fields of it (e.g. ``smoothing="reference"``). ``seed`` seeds the generators now
    (equivalent to ``reset(seed=seed)``); the envs are reset once so observations are valid, but
    callers should still call ``reset()`` first as usual.
    """
    tid = gym_task_id(task)
    _, core_cls, default = TASK_SPECS[tid].load()
    if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
        raise ValueError(f"make_vec_env: num_envs must be a positive integer, got {num_envs!r}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))):
        raise ValueError(f"make_vec_env: seed must be an integer or None, got {type(seed).__name__} {seed!r}")
    cfg = default() if config is None else config
    if not dataclasses.is_dataclass(cfg) or isinstance(cfg, type):
        raise ValueError(f"make_vec_env: config must be a task config instance, got {type(cfg).__name__}")
    if overrides:
        check_overrides(cfg, overrides)
        cfg = dataclasses.replace(cfg, **overrides)
    core = core_cls(cfg, envs=int(num_envs), seed=seed)
    venv = BatchedVecEnv(core, task_id=tid)
    return venv


def check_overrides(cfg: Any, overrides: dict[str, Any]) -> None:
    """Refuse config overrides that are unknown fields or of the wrong kind (ValueError naming the field;
    the rules are :func:`policies.tasks.base.check_field_value`, checked against the field's current value)."""
    name = type(cfg).__name__
    fields = {f.name for f in dataclasses.fields(cfg)}
    for k, v in overrides.items():
        if k not in fields:
            raise ValueError(f"make_vec_env: {name} has no field {k!r} (fields: {sorted(fields)})")
        check_field_value(f"make_vec_env: {name}", k, getattr(cfg, k), v)


def vector_entry_point(task_id: str, num_envs: int = 1, **kwargs: Any) -> BatchedVecEnv:
    """``gymnasium.make_vec(id, num_envs=B)`` creator (kwargs: seed, config, config field overrides)."""
    return make_vec_env(task_id, num_envs, **kwargs)


# --------------------------------------------------------------------------- stable-baselines3
try:  # SB3 is a dependency, but keep gymnasium-only use working without it
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv as _SB3VecEnv
except ImportError:  # pragma: no cover
    _SB3VecEnv = object  # type: ignore[assignment,misc]


class SB3VecEnvAdapter(_SB3VecEnv):  # type: ignore[misc,valid-type]
    """stable-baselines3 ``VecEnv`` view of a :class:`BatchedVecEnv`.

    ``step_wait`` returns obs (B, obs_dim) float32, rewards (B,) float32, dones (B,) bool and a list
    of B info dicts; a done env's dict holds ``terminal_observation`` (last obs of the episode),
    ``TimeLimit.truncated`` (truncated and not terminated), ``failure_reason`` and ``tip_distance``;
    the returned obs row is already the next episode's first observation (SB3 convention).
    ``seed(s)`` followed by ``reset()`` re-seeds like ``make_vec_env(..., seed=s)`` (env i gets child i
    of ``SeedSequence(s)``), not SB3's ``s + i`` per env.
    ``reward_terms`` (a :class:`~policies.tasks.base.RewardTermsObserver` of the task core) holds the
    ``reward/<term>`` arrays (B,) of the latest step, which SB3's per-env infos do not carry (training logs them).
    """

    def __init__(self, venv: BatchedVecEnv):
        self.venv = venv
        self.reward_terms = RewardTermsObserver()
        venv.core.add_observer(self.reward_terms)
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._actions: np.ndarray | None = None
        self._base_seed: int | None = None

    # SB3 API ---------------------------------------------------------------
    def seed(self, seed: int | None = None):
        self._base_seed = seed
        return [seed] * self.num_envs

    def reset(self) -> np.ndarray:
        seed, self._base_seed = self._base_seed, None
        obs, _ = self.venv.reset(seed=seed)
        if hasattr(self, "_reset_seeds"):
            self._reset_seeds()
        if hasattr(self, "_reset_options"):
            self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=np.float32).reshape(self.num_envs, -1)

    def step_wait(self):
        if self._actions is None:
            raise RuntimeError("SB3VecEnvAdapter.step_wait called without step_async")
        obs, rew, term, trunc, info = self.venv.step(self._actions)
        self._actions = None
        dones = term | trunc
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if dones.any():
            final = info["final_obs"]
            for i in np.nonzero(dones)[0]:
                infos[i] = {
                    "terminal_observation": final[i],
                    "TimeLimit.truncated": bool(trunc[i] and not term[i]),
                    "failure_reason": info["failure_reason"][i],
                    "tip_distance": float(info["tip_distance"][i]) if "tip_distance" in info else float("nan"),
                }
        return obs, rew.astype(np.float32), dones, infos

    def close(self) -> None:
        self.venv.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        n = len(self._get_indices(indices))
        target = self.venv if hasattr(self.venv, attr_name) else self.venv.core
        return [getattr(target, attr_name)] * n

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        target = self.venv if hasattr(self.venv, attr_name) else self.venv.core
        setattr(target, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        n = len(self._get_indices(indices))
        target = self.venv if hasattr(self.venv, method_name) else self.venv.core
        res = getattr(target, method_name)(*method_args, **method_kwargs)
        return [res] * n

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(self._get_indices(indices))

    def get_images(self):  # pragma: no cover - no rendering
        return [None] * self.num_envs

