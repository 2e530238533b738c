"""Run a shipped policy on its task for a few control steps.

Purpose: load a policy file (policies/pretrained/*.zip; the task is read from the file), build the task's
batched vector env and step it with the policy's deterministic actions, reporting reward and tip distance.
For the paper's metric over whole episodes use ``rodlab eval POLICY.zip`` (policies.learning.evaluation.evaluate).

Run:  .venv/bin/python examples/evaluate_policy.py [POLICY.zip] [--envs 8 --steps 100]
      .venv/bin/python examples/evaluate_policy.py --smoke
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import policies
from policies.learning import load_policy

ROOT = Path(__file__).resolve().parents[1]


def run(path: Path, envs: int, steps: int, seed: int = 0) -> dict[str, float]:
    """Step ``envs`` envs of the policy's task for ``steps`` control steps; returns mean reward and tip distance."""
    pol, meta = load_policy(path)
    venv = policies.make_vec_env(meta["task"], envs, seed=seed)
    try:
        obs, _ = venv.reset(seed=seed)
        rewards, dist = [], np.full(envs, np.nan)
        for _ in range(steps):
            action, _ = pol.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = venv.step(action)
            rewards.append(reward)
            dist = info["tip_distance"]
    finally:
        venv.close()
    return {"task": meta["task"], "mean_reward": float(np.mean(rewards)), "final_tip_distance_m": float(np.mean(dist))}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("policy", nargs="?", default=str(ROOT / "policies/pretrained/follow_target.zip"))
    ap.add_argument("--envs", type=int, default=8)
    ap.add_argument("--steps", type=int, default=100, help="control steps")
    ap.add_argument("--smoke", action="store_true", help="2 envs, 3 steps (used by the tests)")
    a = ap.parse_args(argv)
    envs, steps = (2, 3) if a.smoke else (a.envs, a.steps)
    r = run(Path(a.policy), envs, steps)
    print(f"{r['task']}: {envs} envs x {steps} control steps, mean reward {r['mean_reward']:.3f}, "
          f"final tip distance {r['final_tip_distance_m']:.3f} m")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
