"""Policy evaluation shared by ``rodlab eval``, the workbench and the recorder.

``evaluate(policy_or_path, task=None, *, episodes, seed, num_envs, deterministic, callback)`` runs
``episodes`` full episodes on the batched task env and returns a JSON-ready dict with

* ``avg_discounted_return_mean`` / ``_std``: the paper's (alf's) metric per episode,
  ``R = (1/L) sum_{l=1..L} r_l (1 - gamma^l) / (1 - gamma)`` (= mean over the episode's steps of the
  discounted return-to-go), L = number of rewarded control steps; mean and std over episodes
  (each episode draws its own target/obstacles from the seeded env). With several seeds
  (``eval_seeds``) ``avg_discounted_return_seed_std`` is the std of the per-seed means.
* ``return_mean`` / ``return_std`` (undiscounted), ``episode_length_mean``.
* task metrics from the final observation of each episode: ``final_tip_error_mean`` [m],
  ``reached_rate`` (final tip error < 0.05 m), for IK also ``final_orientation_error_deg_mean`` and
  ``final_yaw_error_deg_mean``; ``min_tip_error_mean`` [m] (closest approach during the episode).

``callback(step: EvalStep) -> bool | None`` is called after every batched step; returning True stops.
``policy_or_path`` may be a path (policy zip or SB3 checkpoint), an SB3 model or policy, or
``"random"`` (uniform random actions; baseline), ``"inverse-statics"`` or ``"trajectory"`` (the model-based
baselines of :mod:`policies.model_based`). Loading a path never unpickles: a full SB3 checkpoint is
refused unless ``trust_pickle=True`` (``rodlab eval --trust-pickle``; see ``policies.learning.sac.load_policy``).
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np
from sim.geometry import from_xyzw, quat_yaw

from policies.elastica import make_elastica_vec_env
from policies.learning.sac import PolicyLoadError, load_policy
from policies.learning.sb3_env import make_sb3_env, task_short_name
from policies.model_based import MODEL_BASED, model_based_controller
from policies.tasks import field_slices
from policies.vec_env import SB3VecEnvAdapter

# Slices into the flat observation (fields concatenated alphabetically, docs/tasks.md §4.3-7.3):
# tip = last state node; dims = 3 or 2 (x, z).
OBS_LAYOUT: dict[str, dict[str, Any]] = {
    "follow_target": {"obs_dim": 76, "tip": slice(37, 40), "target": slice(70, 73)},
    "follow_target_2d": {"obs_dim": 49, "tip": slice(23, 25), "target": slice(45, 47)},
    "ik4d": {"obs_dim": 86, "tip": slice(42, 45), "target": slice(75, 78), "target_quat": slice(78, 82),
             "tip_quat": slice(82, 86)},
    "tight_obstacles_2d": {"obs_dim": 47, "tip": slice(23, 25), "target": slice(45, 47)},
    "random_obstacles_3d": {"obs_dim": 121, "tip": slice(85, 88), "target": slice(118, 121)},
}
REACH_RADIUS = 0.05  # [m] bonus band of every task's reward


@dataclass
class EvalStep:
    """One batched step seen by an ``evaluate`` callback.

    obs (B, obs_dim) before the step; action (B, act_dim) in the env's action space; reward (B,);
    done (B,) bool; infos: list of B dicts (terminal_observation on episode end); next_obs (B, obs_dim)
    (already the reset observation where done); env: the SB3 VecEnv (``env.venv`` / task env give
    simulator state); t: step index since start; episode_index (B,) episode counter per env.
    """

    t: int
    obs: np.ndarray
    action: np.ndarray
    reward: np.ndarray
    done: np.ndarray
    infos: list
    next_obs: np.ndarray
    env: Any
    episode_index: np.ndarray


def _quat_xyzw_to_yaw(q: np.ndarray) -> np.ndarray:
    return quat_yaw(from_xyzw(q))  # task observations carry scalar-last quaternions


def layout_from_fields(fields) -> dict[str, Any]:
    """Slices (tip, target, ...) from a task core's ``obs_fields`` ((name, size), ... in concat order)."""
    sl = field_slices(fields)
    lay: dict[str, Any] = {"obs_dim": max((s.stop for s in sl.values()), default=0)}
    if "state_pos" in sl and "target_pos" in sl:
        sp, tp = sl["state_pos"], sl["target_pos"]
        d = tp.stop - tp.start
        lay["tip"], lay["target"] = slice(sp.stop - d, sp.stop), tp
    if "tip_orientation" in sl and "target_quat" in sl:
        lay["tip_quat"], lay["target_quat"] = sl["tip_orientation"], sl["target_quat"]
    return lay


def task_metrics(task: str, obs: np.ndarray, layout: dict | None = None) -> dict[str, np.ndarray]:
    """Per-env metrics from observations (B, obs_dim): tip_error [m], IK orientation/yaw error [deg].

    ``layout`` (from ``layout_from_fields``) overrides the static ``OBS_LAYOUT`` table."""
    lay = layout or OBS_LAYOUT.get(task)
    if lay is not None and "tip" not in lay:
        return {}
    if lay is None or obs.shape[-1] != lay["obs_dim"]:
        return {}
    out = {"tip_error": np.linalg.norm(obs[..., lay["tip"]] - obs[..., lay["target"]], axis=-1)}
    if "tip_quat" in lay:
        q, qt = obs[..., lay["tip_quat"]], obs[..., lay["target_quat"]]
        q = q / np.maximum(np.linalg.norm(q, axis=-1, keepdims=True), 1e-12)
        qt = qt / np.maximum(np.linalg.norm(qt, axis=-1, keepdims=True), 1e-12)
        dot = np.clip(np.abs(np.sum(q * qt, axis=-1)), 0.0, 1.0)
        out["orientation_error_deg"] = np.degrees(2.0 * np.arccos(dot))
        dyaw = _quat_xyzw_to_yaw(q) - _quat_xyzw_to_yaw(qt)
        out["yaw_error_deg"] = np.degrees(np.abs((dyaw + np.pi) % (2 * np.pi) - np.pi))
    return out


def _resolve_policy(policy_or_path, trust_pickle: bool = False) -> tuple[Any, dict]:
    if isinstance(policy_or_path, str) and policy_or_path in ("random",) + MODEL_BASED:
        return policy_or_path, {"task": None}
    if isinstance(policy_or_path, (str, os.PathLike)):
        return load_policy(policy_or_path, trust_pickle=trust_pickle)
    pol = getattr(policy_or_path, "policy", policy_or_path)  # SB3 model -> its policy
    if not hasattr(pol, "predict"):
        raise PolicyLoadError(f"cannot evaluate object of type {type(policy_or_path).__name__}")
    return pol, {"task": None}


def check_compatible(meta_or_policy, env, task: str, source: str = "policy") -> None:
    """Raise PolicyLoadError when the policy's observation/action shapes differ from the task's."""
    pol = meta_or_policy
    obs_shape = tuple(pol.observation_space.shape)
    act_shape = tuple(pol.action_space.shape)
    if obs_shape != tuple(env.observation_space.shape) or act_shape != tuple(env.action_space.shape):
        raise PolicyLoadError(
            f"{source} does not fit task {task!r}: the policy takes observations {obs_shape} and gives actions "
            f"{act_shape}, the task has observations {tuple(env.observation_space.shape)} and actions "
            f"{tuple(env.action_space.shape)} (was it trained for another task?)")


def evaluate(policy_or_path, task: str | None = None, *, episodes: int = 100, seed: int = 0,
             num_envs: int | None = None, deterministic: bool = True,
             callback: Callable[[EvalStep], bool | None] | None = None, gamma: float = 0.99,
             eval_seeds: int = 1, env_hook: Callable[[Any], Any] | None = None, trust_pickle: bool = False,
             backend: str = "dismech") -> dict:
    """Evaluate a policy for ``episodes`` episodes (per seed) -> metrics dict (see module docstring).

    Seeds used: ``seed, seed+1, ..., seed+eval_seeds-1``. ``num_envs`` defaults to min(episodes, 100).
    ``backend``: "dismech" (rodlab's simulator) or "elastica" (the task on PyElastica, policies/elastica).
    ``env_hook(env)`` is called once per seed right after the SB3 VecEnv is built, before its first
    ``reset()`` (e.g. ``TaskProbe(rec, ...).attach`` to record final sim frames before auto-resets).
    ``trust_pickle``: also load full SB3 checkpoints (unpickles the file: only for trusted files).
    Raises PolicyLoadError (bad/missing/untrusted file, shape mismatch) or ValueError (no task known).
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    policy, meta = _resolve_policy(policy_or_path, trust_pickle)
    task = task or meta.get("task")
    if not task:
        raise ValueError("no task given and the policy file does not name one; pass task=... / --task")
    task = task_short_name(task)
    n = int(num_envs or min(episodes, 100))
    per_seed, all_eps = [], []
    t0 = time.perf_counter()
    for s in range(seed, seed + max(1, eval_seeds)):
        eps = _run_episodes(policy, task, episodes, s, n, deterministic, callback, gamma, env_hook=env_hook,
                            backend=backend, source=str(policy_or_path) if isinstance(policy_or_path, (str, os.PathLike)) else "policy")
        per_seed.append(float(np.mean([e["avg_disc_return"] for e in eps])))
        all_eps.extend(eps)
    R = np.array([e["avg_disc_return"] for e in all_eps])
    G = np.array([e["return"] for e in all_eps])
    out: dict[str, Any] = {
        "task": task, "policy": str(policy_or_path) if isinstance(policy_or_path, (str, Path)) else type(policy).__name__,
        "episodes": len(all_eps), "seed": seed, "eval_seeds": max(1, eval_seeds), "num_envs": n,
        "deterministic": deterministic, "gamma": gamma, "backend": backend,
        "avg_discounted_return_mean": float(R.mean()), "avg_discounted_return_std": float(R.std()),
        "avg_discounted_return_seed_means": per_seed,
        "avg_discounted_return_seed_std": float(np.std(per_seed)),
        "return_mean": float(G.mean()), "return_std": float(G.std()),
        "episode_length_mean": float(np.mean([e["length"] for e in all_eps])),
        "failures": int(sum(e["terminated"] for e in all_eps)),
    }
    for key in ("tip_error", "orientation_error_deg", "yaw_error_deg"):
        vals = [e[f"final_{key}"] for e in all_eps if f"final_{key}" in e]
        if vals:
            out[f"final_{key}_mean"] = float(np.mean(vals))
            out[f"final_{key}_std"] = float(np.std(vals))
    if any("min_tip_error" in e for e in all_eps):
        out["min_tip_error_mean"] = float(np.mean([e["min_tip_error"] for e in all_eps]))
        out["reached_rate"] = float(np.mean([e["final_tip_error"] < REACH_RADIUS for e in all_eps]))
        out["ever_reached_rate"] = float(np.mean([e["min_tip_error"] < REACH_RADIUS for e in all_eps]))
    out["wall_s"] = round(time.perf_counter() - t0, 2)
    return out


def _run_episodes(policy, task, episodes, seed, n, deterministic, callback, gamma, source,
                  env_hook=None, backend: str = "dismech") -> list[dict]:
    if backend == "elastica":  # the task on PyElastica (policies/elastica), same observations and rewards
        env = SB3VecEnvAdapter(make_elastica_vec_env(task, n, seed=seed))
    elif backend == "dismech":
        env = make_sb3_env(task, n, seed)
    else:
        raise ValueError(f"unknown backend {backend!r}; expected 'dismech' or 'elastica'")
    try:
        controller = None
        if policy in MODEL_BASED:  # a model-based baseline (policies.model_based), built for this env
            controller = model_based_controller(policy, env)
        elif policy != "random":
            check_compatible(policy, env, task, source)
        if env_hook is not None:
            env_hook(env)
        env.action_space.seed(seed)
        fields = getattr(getattr(getattr(env, "venv", None), "core", None), "obs_fields", None)
        layout = layout_from_fields(fields) if fields else None
        quota = np.array([episodes // n + (i < episodes % n) for i in range(n)])
        count = np.zeros(n, dtype=np.int64)
        ret, dsum, dc = np.zeros(n), np.zeros(n), np.zeros(n)
        length = np.zeros(n, dtype=np.int64)
        min_err = np.full(n, np.inf)
        results: list[dict] = []
        obs = env.reset()
        t = 0
        while np.any(count < quota):
            if controller is not None:
                action, _ = controller.predict(obs)
            elif policy == "random":
                action = np.stack([env.action_space.sample() for _ in range(n)])
            else:
                action, _ = policy.predict(obs, deterministic=deterministic)
            next_obs, rew, done, infos = env.step(action)
            rew = np.asarray(rew, dtype=np.float64)
            done = np.asarray(done, dtype=bool)
            length += 1
            dc = 1.0 + gamma * dc
            ret += rew
            dsum += dc * rew
            final_obs = np.array(next_obs, dtype=np.float64, copy=True)
            for i in np.flatnonzero(done):
                if infos[i].get("terminal_observation") is not None:
                    final_obs[i] = infos[i]["terminal_observation"]
            m = task_metrics(task, final_obs, layout)
            if "tip_error" in m:
                err = np.where(np.isfinite(m["tip_error"]), m["tip_error"], np.inf)
                min_err = np.minimum(min_err, err)
            if callback is not None and callback(EvalStep(t, obs, action, rew, done, infos, next_obs, env,
                                                          count.copy())):
                break
            for i in np.flatnonzero(done):
                if count[i] < quota[i]:
                    ep = {"return": float(ret[i]), "avg_disc_return": float(dsum[i] / max(length[i], 1)),
                          "length": int(length[i]),
                          "terminated": bool(not infos[i].get("TimeLimit.truncated", False))}
                    for k, v in m.items():
                        ep[f"final_{k}"] = float(v[i])
                    if "tip_error" in m:
                        ep["min_tip_error"] = float(min_err[i])
                    results.append(ep)
                count[i] += 1
                ret[i] = dsum[i] = dc[i] = 0.0
                length[i] = 0
                min_err[i] = np.inf
            obs = next_obs
            t += 1
        if not results:  # stopped by the callback before any episode ended: report partial episodes
            results = [{"return": float(ret[i]), "avg_disc_return": float(dsum[i] / max(length[i], 1)),
                        "length": int(length[i]), "terminated": False} for i in range(n)]
        return results
    finally:
        env.close()


__all__ = ["evaluate", "EvalStep", "task_metrics", "check_compatible", "OBS_LAYOUT", "PolicyLoadError"]
