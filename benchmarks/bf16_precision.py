"""How much bfloat16 moves a trained critic: Q and dQ/da under autocast against float32, per precision layout.

    .venv/bin/python benchmarks/bf16_precision.py [--policy policies/pretrained/follow_target.zip] [--json]

Observations come from the policy's own task (64 envs, stochastic actions, every 10th of 120 control steps); the
actions are the policy's samples there. Layouts (docs/training.md, "bfloat16 updates"):

* ``all``: every Linear and LayerNorm of the critics in bfloat16 (autocast's CPU rules alone);
* ``f32_heads``: the output layers and LayerNorms in float32, the input layer in bfloat16;
* ``rodlab``: the input and output layers and the LayerNorms in float32, only the hidden products in bfloat16
  (what ``--bf16`` does).

Printed per layout: mean and largest |Q_bf16 - Q_f32|, the relative error of dQ/da (||g - g32|| / ||g32||, the
actor's learning signal), the mean cosine between the two per sample, and the cosine of the critic's parameter
gradients. Written to ``docs/bench/summary/bf16_precision.json``.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.common import base_parser, machine_info, write_summary  # noqa: E402


def _observations(policy, task: str, envs: int = 64, steps: int = 120, every: int = 10):
    import torch as th

    from policies.train import make_sb3_env

    env = make_sb3_env(task, envs, 0)
    obs, kept = env.reset(), []
    try:
        for t in range(steps):
            with th.no_grad():
                act = policy.actor(th.as_tensor(obs), deterministic=False).numpy()
            obs, *_ = env.step(act)
            if t % every == every - 1:
                kept.append(obs.copy())
    finally:
        env.close()
    return th.as_tensor(np.concatenate(kept))


def _layout(critic, name: str) -> None:
    """Set the critic's layers' classes for ``name`` (parameters untouched): ``all`` and ``rodlab`` are the
    policy's own layouts (``set_bf16_layout`` ``all`` / ``float32_io``); ``f32_heads`` keeps only the output layers
    and LayerNorms in float32."""
    from torch import nn

    from policies.sac import _keep_float32, set_bf16_layout

    set_bf16_layout(critic, "float32_io" if name == "rodlab" else "all")
    if name == "f32_heads":
        for q in critic.q_networks:
            _keep_float32(q[-1])
            for m in q:
                if isinstance(m, nn.LayerNorm):
                    _keep_float32(m)


def measure(policy_path: str) -> dict:
    import torch as th
    import torch.nn.functional as F

    from policies.sac import load_policy

    th.manual_seed(0)
    pol, meta = load_policy(policy_path)
    obs = _observations(pol, meta["task"])
    with th.no_grad():
        act = pol.actor(obs, deterministic=False)

    def run(bf16: bool):
        a = act.clone().requires_grad_(True)
        pol.critic.zero_grad()
        with th.autocast("cpu", dtype=th.bfloat16, enabled=bf16):
            q = th.min(th.cat(pol.critic(obs, a), dim=1), dim=1).values.float()
        q.sum().backward()
        grads = th.cat([p.grad.flatten().clone() for p in pol.critic.parameters()])
        return q.detach(), a.grad.detach().float(), grads

    q32, ga32, gp32 = run(False)
    out = {"policy": policy_path, "task": meta["task"], "samples": int(obs.shape[0]),
           "q_f32_mean": float(q32.mean()), "q_f32_std": float(q32.std()), "layouts": {}}
    for name in ("all", "f32_heads", "rodlab"):
        _layout(pol.critic, name)
        q, ga, gp = run(True)
        out["layouts"][name] = {
            "q_abs_err_mean": float((q - q32).abs().mean()), "q_abs_err_max": float((q - q32).abs().max()),
            "dq_da_rel_err": float((ga - ga32).norm() / ga32.norm()),
            "dq_da_cos_mean": float(F.cosine_similarity(ga, ga32, dim=1).mean()),
            "param_grad_cos": float(F.cosine_similarity(gp, gp32, dim=0))}
    _layout(pol.critic, "rodlab")
    return out


def main(argv: list[str] | None = None) -> int:
    p = base_parser("bf16_precision", __doc__.split("\n")[0])
    p.add_argument("--policy", default="policies/pretrained/follow_target.zip")
    a = p.parse_args(argv)
    res = measure(a.policy)
    res["machine"] = machine_info()
    print(f"{res['task']}: {res['samples']} samples, Q (float32) {res['q_f32_mean']:.2f} ± {res['q_f32_std']:.2f}")
    for name, r in res["layouts"].items():
        print(f"  {name:10s} |dQ| mean {r['q_abs_err_mean']:.3f} max {r['q_abs_err_max']:.3f}   dQ/da relative error "
              f"{r['dq_da_rel_err']:.3f} (cosine {r['dq_da_cos_mean']:.3f})   parameter-gradient cosine "
              f"{r['param_grad_cos']:.4f}")
    write_summary(a, "bf16_precision.json", res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
