"""What precedes a failed step: the Newton residual growth of accepted unconverged steps.

    .venv/bin/python -m benchmarks.failure_precursors [--envs 128] [--steps 60] [--out docs/bench]

The paper arm (2 Newton iterations, unconverged accepted) driven like the stress benchmark's sim part
(contact-scale random / bang-bang curvature commands saturating at |K| = 2). For every env-step that did not
fail it records residual/residual0 (‖f‖ at the last Newton iteration over ‖f‖ at the first); for every env
that failed, the largest ratio over the 3 steps before its failure. Writes failure_precursors.json.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from .rodlab_runs import Solver, make_sim, scene_dict
from .stress import curvature_commands


def run(kind: str, *, envs: int, steps: int, seed: int = 0) -> dict:
    doc = scene_dict(nodes=21, length=1.0, radius=0.05, density=1000.0, youngs=1e7, poisson=0.5, dt=0.05,
                     gravity=(0.0, 0.0, -9.8), solver=Solver(tol=1e-3, max_iter=2), mode="3d", obstacles=None)
    sim, state, ctrl = make_sim(doc, envs=envs)
    ratios, fail_step, t = [], np.full(envs, -1), 0
    for dk in curvature_commands(kind, envs=envs, nodes=21, control_steps=steps, seed=seed):
        for _ in range(2):
            ctrl.kappa_bar += dk / 2
            alive = ~state.failed.copy()
            st = sim.step(state, ctrl)
            r = st.residual / np.maximum(st.residual0, 1e-300)
            ratios.append(np.where(alive & ~st.failed, r, np.nan))
            fail_step[alive & st.failed] = t
            t += 1
    R = np.asarray(ratios)
    pre = [float(np.nanmax(R[max(0, f - 3):f, e])) for e, f in enumerate(fail_step) if f > 0]
    q = np.nanquantile(R, [0.5, 0.9, 0.99, 1.0])
    return {"actions": kind, "envs": envs, "control_steps": steps, "failed_envs": int((fail_step >= 0).sum()),
            "ratio_quantiles_ok_steps": {"p50": q[0], "p90": q[1], "p99": q[2], "max": q[3]},
            "ratio_before_failure": {"min": min(pre, default=None), "median": float(np.median(pre)) if pre else None},
            "ok_steps_with_ratio_above_10": int(np.nansum(R > 10.0)), "ok_steps": int(np.isfinite(R).sum())}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.failure_precursors", description=__doc__.split("\n")[0])
    p.add_argument("--envs", type=int, default=128)
    p.add_argument("--steps", type=int, default=60, help="control steps (2 sim steps each)")
    p.add_argument("--out", type=Path, default=Path("docs/bench"))
    a = p.parse_args(argv)
    res = {"command": "python -m benchmarks.failure_precursors " + " ".join(argv if argv is not None else sys.argv[1:]),
           "runs": [run(kind, envs=a.envs, steps=a.steps) for kind in ("random", "bang-bang")]}
    for r in res["runs"]:
        print(json.dumps(r))
    a.out.mkdir(parents=True, exist_ok=True)
    tmp = a.out / "failure_precursors.json.tmp"
    tmp.write_text(json.dumps(res, indent=1))
    tmp.replace(a.out / "failure_precursors.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
