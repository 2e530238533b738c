"""Compiled against eager SAC updates (``rodlab train --compile``), interleaved in one process.

    .venv/bin/python benchmarks/compile_ab.py [--tasks follow_target,ik4d,...] [--threads 2] [--rounds 20] [--json]

Per task, four models of the same network and replay buffer (``benchmarks/update_profile.py``'s ``sac_model``):
float32 and ``--bf16 --bf16-layout all``, each eager and compiled. After warm-up calls (which compile), one
training iteration's updates (``model.train(4, 1024)``) of each model in turn, ``--rounds`` times: every model sees
the same drifts of a shared machine, which whole-command runs minutes apart do not (their iteration times spread by
±15 % on the 2-core VM). Reports the median ms per iteration's updates and compiled/eager per precision.
With ``--variants ...,bf16_all_compiled_split`` (or ``float32_compiled_split``) it also times the compiled
updates with the graph pass ``SplitThinProducts`` (policies/compile_passes.py) and reports split/unsplit.
Written to ``docs/bench/summary/compile_ab.json`` (or ``--out DIR``).
"""
from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.common import base_parser, machine_info, write_summary  # noqa: E402
from benchmarks.update_profile import sac_model  # noqa: E402

VARIANTS = {
    "float32": {},
    "float32_compiled": {"compile": True},
    "bf16_all": {"bf16": True, "bf16_layout": "all"},
    "bf16_all_compiled": {"bf16": True, "bf16_layout": "all", "compile": True},
    # the compiled updates with the graph pass SplitThinProducts (policies/compile_passes.py)
    "float32_compiled_split": {"compile": True, "split_products": True},
    "bf16_all_compiled_split": {"bf16": True, "bf16_layout": "all", "compile": True, "split_products": True},
}
DEFAULT_VARIANTS = ("float32", "float32_compiled", "bf16_all", "bf16_all_compiled")
UPDATES, BATCH = 4, 1024


def compare(task: str, rounds: int, warmup: int = 3, variants: tuple[str, ...] = DEFAULT_VARIANTS) -> dict:
    models = {name: sac_model(task, VARIANTS[name]) for name in variants}
    t0 = time.perf_counter()
    for model in models.values():
        for _ in range(warmup):
            model.train(gradient_steps=UPDATES, batch_size=BATCH)
    warm_s = time.perf_counter() - t0
    times: dict[str, list[float]] = {name: [] for name in models}
    for _ in range(rounds):
        for name, model in models.items():
            t = time.perf_counter()
            model.train(gradient_steps=UPDATES, batch_size=BATCH)
            times[name].append(1e3 * (time.perf_counter() - t))
    med = {name: statistics.median(v) for name, v in times.items()}
    ratios = {eager: med[f"{eager}_compiled"] / med[eager] for eager in ("float32", "bf16_all")
              if eager in med and f"{eager}_compiled" in med}
    split = {prec: med[f"{prec}_compiled_split"] / med[f"{prec}_compiled"] for prec in ("float32", "bf16_all")
             if f"{prec}_compiled" in med and f"{prec}_compiled_split" in med}
    out = {"updates_ms_median": med, "updates_ms_runs": times, "warmup_s": warm_s, "compiled_over_eager": ratios,
           "split_over_unsplit": split}
    if "bf16_all_compiled" in med and "float32" in med:
        out["bf16_all_compiled_over_float32"] = med["bf16_all_compiled"] / med["float32"]
    return out


def main(argv: list[str] | None = None) -> int:
    p = base_parser("compile_ab", __doc__.split("\n")[0])
    p.add_argument("--tasks", default="follow_target,ik4d,tight_obstacles_2d,random_obstacles_3d")
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--rounds", type=int, default=20)
    p.add_argument("--variants", default=",".join(DEFAULT_VARIANTS), help=f"some of {', '.join(VARIANTS)}")
    a = p.parse_args(argv)
    variants = tuple(v for v in a.variants.split(",") if v)
    unknown = sorted(set(variants) - set(VARIANTS))
    if unknown or not variants:
        p.error(f"--variants: unknown {', '.join(unknown) or '(none given)'}; known: {', '.join(VARIANTS)}")
    import torch

    torch.set_num_threads(a.threads)
    res = {"threads": a.threads, "rounds": a.rounds, "variants": list(variants), "updates_per_iteration": UPDATES, "batch_size": BATCH,
           "tasks": {}}
    for task in a.tasks.split(","):
        r = compare(task, a.rounds, variants=variants)
        res["tasks"][task] = r
        m = r["updates_ms_median"]
        print(f"{task}: updates of one iteration, median of {a.rounds} [ms]: "
              + ", ".join(f"{k} {v:.1f}" for k, v in m.items())
              + "".join(f"; compiled/eager {k} {v:.2f}" for k, v in r["compiled_over_eager"].items())
              + "".join(f"; split/unsplit {k} {v:.2f}" for k, v in r["split_over_unsplit"].items()), flush=True)
    res["machine"] = machine_info()
    write_summary(a, "compile_ab.json", res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
