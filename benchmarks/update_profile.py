"""Where the time of the SAC updates goes: torch.profiler self-time of one update, grouped by kind of operation.

    .venv/bin/python benchmarks/update_profile.py [--task follow_target] [--threads 2] [--updates 24]
        [--settings float32,bf16,bf16_all,bf16_all_compiled] [--json]

The model is the one ``rodlab train`` builds (table A.1 network, batch 1024), its replay buffer filled with random
transitions of the task; per setting (float32, ``--bf16``, ``--bf16 --bf16-layout all``, the last with ``--compile``) 8 warm-up
updates, then ``--updates`` updates under the profiler. Groups (self CPU time per update, ms): ``products``
(addmm, mm, bmm), ``layer_norm`` (forward and backward), ``relu`` (forward and backward), ``casts`` (copy_,
_to_copy: dtype casts and the bias broadcast of addmm), ``reductions`` (sum, mean: bias gradients, losses),
``adam``, ``fused`` (the generated loops of ``--compile``, which hold the elementwise work, LayerNorm, ReLU and
Adam of a compiled update), ``other``. The profiler adds its own overhead, so the total exceeds ``rodlab bench train``'s update
time a little; the shares are what matter. Beside the profile, the same number of updates is timed without the
profiler (``wall_ms_per_update``) and once more under cProfile, whose own time of Python functions
(``python_ms_per_update``: SB3, the SAC code, torch's Python layers, without the C++ operators they call) tells how
much of the wall time is Python. Written to ``docs/bench/summary/update_profile_<task>.json``.
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.common import base_parser, machine_info, write_summary  # noqa: E402

GROUPS = {
    "products": ("aten::addmm", "aten::mm", "aten::bmm", "aten::baddbmm"),
    "layer_norm": ("aten::native_layer_norm", "aten::native_layer_norm_backward"),
    "relu": ("aten::clamp_min_", "aten::clamp_min", "aten::relu", "aten::relu_", "aten::threshold_backward"),
    "casts": ("aten::copy_", "aten::_to_copy"),
    "reductions": ("aten::sum", "aten::mean"),
    "adam": ("aten::_fused_adam_", "aten::_foreach_add_", "aten::_foreach_mul_", "aten::_foreach_addcmul_",
             "aten::_foreach_addcdiv_", "aten::_foreach_sqrt", "aten::_foreach_div_", "aten::_foreach_lerp_"),
}
SETTINGS = {"float32": {}, "bf16": {"bf16": True}, "bf16_all": {"bf16": True, "bf16_layout": "all"},
            "bf16_all_compiled": {"bf16": True, "bf16_layout": "all", "compile": True},
            "bf16_all_compiled_split": {"bf16": True, "bf16_layout": "all", "compile": True, "split_products": True}}
DEFAULT_SETTINGS = ("float32", "bf16", "bf16_all", "bf16_all_compiled")
#: the generated loops of a compiled update (inductor's kernel profile names them ``graph_<n>_cpp_fused_...``)
FUSED_MARK = "cpp_fused"


def sac_model(task: str, setting: dict):
    """The model `rodlab train` builds for `task` with the speed `setting` (SpeedSettings keywords), its replay
    buffer holding 1280 random transitions."""
    import numpy as np

    from policies.train import Args, build_sac, make_sb3_env
    from policies.train_speed import SpeedSettings, apply_speed_settings

    envs = 16
    env = make_sb3_env(task, envs, 0)
    model = build_sac(Args(task=task, num_envs=envs, total_steps=100_000), env)
    apply_speed_settings(model, SpeedSettings(**setting))
    from stable_baselines3.common.logger import configure

    model.set_logger(configure(None, [""]))
    obs = env.reset()
    rng = np.random.default_rng(0)
    for _ in range(80):  # 1280 transitions: more than one batch
        act = rng.uniform(-1, 1, (envs, *env.action_space.shape)).astype(np.float32)
        nobs, rew, done, infos = env.step(act)
        model.replay_buffer.add(obs, nobs, act, rew, done, infos)
        obs = nobs
    env.close()
    return model


def profile_setting(task: str, setting: dict, updates: int) -> dict:
    from torch.profiler import ProfilerActivity, profile

    model = sac_model(task, setting)
    model.train(gradient_steps=8, batch_size=1024)
    with profile(activities=[ProfilerActivity.CPU]) as prof:
        model.train(gradient_steps=updates, batch_size=1024)
    ms = {g: 0.0 for g in GROUPS} | {"fused": 0.0, "other": 0.0}
    owner = {op: g for g, ops in GROUPS.items() for op in ops}
    for ev in prof.key_averages():
        if FUSED_MARK in ev.key:
            ms["fused"] += ev.self_cpu_time_total / 1e3 / updates
            continue
        if not ev.key.startswith("aten::"):
            continue  # autograd/optimizer wrappers: their self time is bookkeeping, the aten ops hold the work
        ms[owner.get(ev.key, "other")] += ev.self_cpu_time_total / 1e3 / updates
    total = sum(ms.values())
    return {"ms_per_update": ms, "total_ms_per_update": total,
            "share": {g: v / total for g, v in ms.items()} if total > 0 else {},
            **_wall_and_python(model, updates)}


def _wall_and_python(model, updates: int) -> dict:
    """Wall time per update without a profiler, and the own time of Python functions per update (cProfile;
    built-in and C functions, whose file name pstats gives as ``~``, excluded)."""
    import cProfile
    import pstats
    import time

    t0 = time.perf_counter()
    model.train(gradient_steps=updates, batch_size=1024)
    wall = (time.perf_counter() - t0) / updates
    prof = cProfile.Profile()
    prof.enable()
    model.train(gradient_steps=updates, batch_size=1024)
    prof.disable()
    own = sum(row[2] for (filename, _, _), row in pstats.Stats(prof).stats.items() if filename != "~")
    return {"wall_ms_per_update": 1e3 * wall, "python_ms_per_update": 1e3 * own / updates}


def main(argv: list[str] | None = None) -> int:
    p = base_parser("update_profile", __doc__.split("\n")[0])
    p.add_argument("--task", default="follow_target")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--updates", type=int, default=24)
    p.add_argument("--settings", default=",".join(DEFAULT_SETTINGS), help=f"some of {', '.join(SETTINGS)}")
    a = p.parse_args(argv)
    chosen = [name for name in a.settings.split(",") if name]
    unknown = sorted(set(chosen) - set(SETTINGS))
    if unknown or not chosen:
        p.error(f"--settings: unknown {', '.join(unknown) or '(none given)'}; known: {', '.join(SETTINGS)}")
    import torch

    torch.set_num_threads(a.threads)
    from torch._inductor import config as inductor_config

    res = {"task": a.task, "threads": a.threads, "updates": a.updates, "batch_size": 1024,
           "settings": {}}
    with inductor_config.patch({"cpp.enable_kernel_profile": True}):  # the compiled setting's loops in the profile
        for name in chosen:
            res["settings"][name] = profile_setting(a.task, SETTINGS[name], a.updates)
    res["machine"] = machine_info()
    for name, r in res["settings"].items():
        parts = "  ".join(f"{g} {v:.1f}" for g, v in r["ms_per_update"].items())
        print(f"{name:9s} {r['total_ms_per_update']:6.1f} ms/update:  {parts}   (wall {r['wall_ms_per_update']:.1f}, "
              f"Python {r['python_ms_per_update']:.1f})")
    write_summary(a, f"update_profile_{a.task}.json", res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
