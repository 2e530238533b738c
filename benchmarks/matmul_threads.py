"""Time of one hidden-layer product of the SAC updates (1024x256 by 256x256) with the thread variables as they are
when torch loads, at ``torch.set_num_threads(2)``: none set, and ``OMP_NUM_THREADS=1 MKL_NUM_THREADS=1`` (what
``rodlab train/bench train --threads 2`` set before they matched ``--threads``; docs/training.md, "Threads").

    .venv/bin/python benchmarks/matmul_threads.py [--repeats 5] [--json]

Each setting runs in a fresh process (the variables are read once, when torch loads). Printed per setting and
dtype (float32, bfloat16): the median over ``--repeats`` of the mean time of 200 products, and CPU time / wall time
of the process over the timed loops (about the number of busy threads). Written to
``docs/bench/summary/matmul_threads.json``.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.common import base_parser, machine_info, write_summary  # noqa: E402

SETTINGS = {"unset": {}, "omp1_mkl1": {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}}
_VARS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS")

_CHILD = """
import json, statistics, sys, time, torch
torch.set_num_threads(2)
repeats, products = int(sys.argv[1]), int(sys.argv[2])
a, w = torch.randn(1024, 256), torch.randn(256, 256)
out = {}
for dtype in ("float32", "bfloat16"):
    x, y = a.to(getattr(torch, dtype)), w.to(getattr(torch, dtype))
    for _ in range(20):
        x @ y
    ms, busy = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(products):
            x @ y
        t1, c1 = time.perf_counter(), time.process_time()
        ms.append((t1 - t0) / products * 1e3)
        busy.append((c1 - c0) / (t1 - t0))
    out[dtype] = {"ms_median": statistics.median(ms), "ms": ms, "cpu_per_wall": statistics.median(busy)}
print(json.dumps(out))
"""


def measure(repeats: int = 5, products: int = 200) -> dict:
    res = {}
    for name, env_vars in SETTINGS.items():
        env = {k: v for k, v in os.environ.items() if k not in _VARS}
        env.update(env_vars)
        done = subprocess.run([sys.executable, "-c", _CHILD, str(repeats), str(products)], env=env,
                              capture_output=True, text=True, check=True)
        res[name] = {"env": env_vars, **json.loads(done.stdout.strip().splitlines()[-1])}
    return {"shape": "1024x256 @ 256x256", "torch_threads": 2, "repeats": repeats, "products_per_repeat": products,
            "settings": res}


def main(argv: list[str] | None = None) -> int:
    p = base_parser("matmul_threads", __doc__.split("\n")[0])
    a = p.parse_args(argv)
    res = measure(repeats=a.repeats or 5, products=20 if a.quick else 200)
    res["machine"] = machine_info()
    for name, r in res["settings"].items():
        print(f"{name:10s} " + "   ".join(f"{dt} {r[dt]['ms_median']:.3f} ms (cpu/wall {r[dt]['cpu_per_wall']:.2f})"
                                          for dt in ("float32", "bfloat16")))
    write_summary(a, "matmul_threads.json", res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
