"""A/B speed comparison of two checkouts of rodlab, run back to back on the same machine.

Each case is one `rodlab bench ...` command (JSON output) run in checkout A, then in checkout B, then A
again, and so on (``--runs`` times each, interleaved so slow drifts of the machine hit both sides alike).
The figure of a case is the median over its runs; the ratio is median(B) / median(A). Each row also gives the
ratio of the fastest runs and each side's spread (slowest / fastest run): on a shared host whose spread is wider
than the difference looked for, the fastest runs are the better comparison.

    git worktree add --detach /tmp/rodlab-old <commit>      # the code to compare against
    python -m benchmarks.ab --a /tmp/rodlab-old --b . --runs 3 --out /tmp/ab.json

Both checkouts run with this interpreter (``PYTHONPATH`` set to the checkout, so its own ``sim``/``policies``
are imported) and the same thread settings; the first run of each side also pays its numba cache load,
which the commands' own warm-up steps keep out of the timed part.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

from benchmarks.common import write_json

# name -> (arguments of rodlab, JSON key of the figure in ms)
CASES: dict[str, tuple[list[str], str]] = {
    "sim step, paper arm, 500 envs": (["bench", "sim", "--envs", "500", "--json"], "ms_per_step_median"),
    "control step, paper arm, 500 envs": (["bench", "sim", "--envs", "500", "--json"], "ms_per_control_step_median"),
    "env step follow_target, 500 envs": (["bench", "env", "--task", "follow_target", "--envs", "500",
                                          "--steps", "20", "--json"], "ms_per_env_step_median"),
    "env step ik4d, 500 envs": (["bench", "env", "--task", "ik4d", "--envs", "500", "--steps", "20", "--json"],
                                "ms_per_env_step_median"),
    "env step tight_obstacles_2d, 500 envs": (["bench", "env", "--task", "tight_obstacles_2d", "--envs", "500",
                                               "--steps", "10", "--json"], "ms_per_env_step_median"),
    "env step random_obstacles_3d, 500 envs": (["bench", "env", "--task", "random_obstacles_3d", "--envs", "500",
                                                "--steps", "10", "--json"], "ms_per_env_step_median"),
}


def run_case(tree: Path, args: list[str]) -> dict:
    """One command in checkout ``tree``; its JSON output (the last line that parses)."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    out = subprocess.run([sys.executable, str(tree / "rodlab_cli.py"), *args], cwd=tree, env=env,
                         capture_output=True, text=True, check=False)
    if out.returncode != 0:
        raise RuntimeError(f"{tree}: rodlab {' '.join(args)} failed ({out.returncode}):\n{out.stderr[-2000:]}")
    for line in reversed(out.stdout.strip().splitlines()):
        try:
            return json.loads(line)
        except json.JSONDecodeError:
            continue
    raise RuntimeError(f"{tree}: rodlab {' '.join(args)} printed no JSON:\n{out.stdout[-2000:]}")


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.ab", description=__doc__.split("\n\n")[0])
    p.add_argument("--a", type=Path, required=True, help="checkout A (the reference, e.g. the previous code)")
    p.add_argument("--b", type=Path, default=Path("."), help="checkout B (default: this one)")
    p.add_argument("--runs", type=int, default=3)
    p.add_argument("--cases", default="", help="comma-separated substrings selecting cases (default: all)")
    p.add_argument("--out", type=Path, help="write the figures as JSON here")
    a = p.parse_args(argv)
    trees = {"a": a.a.resolve(), "b": a.b.resolve()}
    for side, tree in trees.items():
        if not (tree / "rodlab_cli.py").is_file():
            p.error(f"--{side} {tree}: not a rodlab checkout (no rodlab_cli.py)")
    if a.runs < 1:
        p.error("--runs must be >= 1")
    wanted = [s for s in a.cases.split(",") if s]
    cases = {k: v for k, v in CASES.items() if not wanted or any(w in k for w in wanted)}
    # one command may serve several cases (sim step and control step): run each command once per repeat
    commands = {tuple(args) for args, _ in cases.values()}
    raw: dict[str, dict[tuple, list[dict]]] = {"a": {c: [] for c in commands}, "b": {c: [] for c in commands}}
    total = len(commands) * a.runs * 2
    done = 0
    for cmd in sorted(commands):
        for _ in range(a.runs):
            for side in ("a", "b"):
                raw[side][cmd].append(run_case(trees[side], list(cmd)))
                done += 1
                print(f"[{done}/{total}] {side}: rodlab {' '.join(cmd)}", file=sys.stderr, flush=True)
    rows = []
    for name, (args, key) in cases.items():
        va = [float(r[key]) for r in raw["a"][tuple(args)]]
        vb = [float(r[key]) for r in raw["b"][tuple(args)]]
        ma, mb = statistics.median(va), statistics.median(vb)
        rows.append({"case": name, "command": "rodlab " + " ".join(args), "key": key, "a_ms": va, "b_ms": vb,
                     "a_median_ms": ma, "b_median_ms": mb, "ratio_b_over_a": mb / ma,
                     # a busy host only adds time: the fastest runs compare the code where the medians are noisy
                     "a_min_ms": min(va), "b_min_ms": min(vb), "ratio_of_fastest": min(vb) / min(va),
                     "a_spread": max(va) / min(va), "b_spread": max(vb) / min(vb)})
    width = max(len(r["case"]) for r in rows)
    print(f"{'case':<{width}}  {'A median':>9}  {'B median':>9}  {'B/A':>6}  {'fastest B/A':>11}  {'spread A, B':>12}")
    for r in rows:
        print(f"{r['case']:<{width}}  {r['a_median_ms']:9.2f}  {r['b_median_ms']:9.2f}  {r['ratio_b_over_a']:6.3f}  "
              f"{r['ratio_of_fastest']:11.3f}  {r['a_spread']:5.2f}, {r['b_spread']:4.2f}")
    if a.out:
        write_json(a.out.parent, a.out.name, {"a": str(trees["a"]), "b": str(trees["b"]), "runs": a.runs,
                                              "cases": rows})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
