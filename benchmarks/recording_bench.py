"""Recording cost for the paper arm (21 nodes): file size per control step and CPU overhead per step.

    .venv/bin/python -m benchmarks.recording_bench [--steps 1000] [--json]           # from the checkout root
    .venv/bin/python -m benchmarks.recording_bench --env follow_target --env-steps 100   # + real task env

Synthetic part: frames of the documented shapes (what ``TaskProbe`` logs per control step) are
recorded with :class:`policies.recording.Recorder`; the size per step is the slope between a short
and a long episode (so the fixed per-episode cost is separated out), the overhead is the wall time
of ``log_step`` per call plus ``end_episode`` (+ ``close``) divided by the steps. Random data do not
compress, so the sizes are upper bounds. ``--env TASK`` also times ``venv.step`` of the real task with
and without the probe attached (1 env).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

N = 21
CONFIGS = {
    "centreline": dict(),
    "default": dict(frames=True, curvature=True, target=True, scalars=20),
    "default+contacts": dict(frames=True, curvature=True, target=True, scalars=20, contacts=2),
    "default+ref_frames": dict(frames=True, ref=True, curvature=True, target=True, scalars=20),
}


def _frames(steps: int, cfg: dict, rng) -> list[dict]:
    out = []
    for k in range(steps):
        d = dict(node_pos=rng.normal(size=(N, 3)))
        if cfg.get("frames"):
            d.update(m1=rng.normal(size=(N - 1, 3)), m2=rng.normal(size=(N - 1, 3)))
        if cfg.get("ref"):
            d.update(d1=rng.normal(size=(N - 1, 3)), d2=rng.normal(size=(N - 1, 3)))
        if cfg.get("curvature"):
            d.update(kappa_bar=rng.normal(size=(N, 2)), kappa=rng.normal(size=(N, 2)))
        if cfg.get("target"):
            d.update(target_pos=rng.normal(size=3))
        if cfg.get("contacts"):
            c = cfg["contacts"]
            d.update(contact_points=rng.normal(size=(c, 3)), contact_normals=rng.normal(size=(c, 3)),
                     contact_normal_force=rng.random(c), contact_edge=np.arange(c), contact_obstacle=np.zeros(c, int))
        if cfg.get("scalars"):
            d["scalars"] = {f"s/{i}": float(rng.normal()) for i in range(cfg["scalars"])}
        out.append(d)
    return out


def _record(path: Path, frames: list[dict]) -> dict:
    from policies.recording import Recorder

    t0 = time.perf_counter()
    rec = Recorder(path)
    rec.begin_episode({"task": "bench"})
    t1 = time.perf_counter()
    for k, d in enumerate(frames):
        rec.log_step(control_step=k, sim_time=0.1 * k, **d)
    t2 = time.perf_counter()
    rec.end_episode()
    rec.close()
    t3 = time.perf_counter()
    return {"bytes": path.stat().st_size, "begin_s": t1 - t0, "log_s": t2 - t1, "end_close_s": t3 - t2}


def bench_synthetic(steps: int, repeats: int) -> dict:
    rng = np.random.default_rng(0)
    short = max(10, steps // 10)
    res = {}
    with tempfile.TemporaryDirectory() as td:
        for name, cfg in CONFIGS.items():
            long_f, short_f = _frames(steps, cfg, rng), _frames(short, cfg, rng)
            best = None
            for r in range(repeats):
                a = _record(Path(td) / f"{name}_s{r}.rrd", short_f)
                b = _record(Path(td) / f"{name}_l{r}.rrd", long_f)
                if best is None or b["log_s"] + b["end_close_s"] < best[1]["log_s"] + best[1]["end_close_s"]:
                    best = (a, b)
            a, b = best
            res[name] = {
                "bytes_per_step": (b["bytes"] - a["bytes"]) / (steps - short),
                "fixed_bytes_per_episode": a["bytes"] - short * (b["bytes"] - a["bytes"]) / (steps - short),
                "log_step_us": 1e6 * b["log_s"] / steps,
                "end_episode_us_per_step": 1e6 * b["end_close_s"] / steps,
                "total_us_per_step": 1e6 * (b["log_s"] + b["end_close_s"]) / steps,
                "begin_episode_ms": 1e3 * b["begin_s"],
                "file_bytes": b["bytes"], "steps": steps,
            }
    return res


def bench_env(task: str, steps: int) -> dict:
    """Wall time per control step of the real task env (1 env), without and with the probe."""
    import policies
    from policies.recording import Recorder, TaskProbe

    def run(probe: bool) -> tuple[float, int]:
        venv = policies.make_vec_env(task, 1, seed=0)
        dim = int(np.prod(venv.single_action_space.shape))
        rng = np.random.default_rng(0)
        with tempfile.TemporaryDirectory() as td:
            rec = Recorder(Path(td) / "env.rrd") if probe else None
            if probe:
                TaskProbe(rec, episodes=1000, max_steps=None).attach(venv)
            venv.reset(seed=0)
            for _ in range(3):                      # warm-up (numba dispatch, first rerun calls)
                venv.step(rng.uniform(-1, 1, (1, dim)).astype(np.float32))
            t0 = time.perf_counter()
            for _ in range(steps):
                venv.step(rng.uniform(-1, 1, (1, dim)).astype(np.float32))
            dt = time.perf_counter() - t0
            size = 0
            if probe:
                t1 = time.perf_counter()
                out = rec.close()
                dt += time.perf_counter() - t1
                size = out.stat().st_size if out else 0
        venv.close()
        return dt / steps, size

    base, _ = run(False)
    rec_t, size = run(True)
    return {"task": task, "steps": steps, "env_step_ms": 1e3 * base, "env_step_recorded_ms": 1e3 * rec_t,
            "overhead_ms_per_step": 1e3 * (rec_t - base), "overhead_pct": 100 * (rec_t - base) / base,
            "file_bytes": size, "bytes_per_step_incl_fixed": size / (steps + 4)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=1000, help="control steps of the long synthetic episode")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--env", default=None, help="also time a real task env (e.g. follow_target)")
    p.add_argument("--env-steps", type=int, default=100)
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    out = {"nodes": N, "synthetic": bench_synthetic(a.steps, a.repeats)}
    if a.env:
        out["env"] = bench_env(a.env, a.env_steps)
    if a.json:
        print(json.dumps(out))
        return 0
    print(f"recording cost, paper arm N={N}, {a.steps}-step episode (best of {a.repeats}):")
    print(f"  {'config':<20} {'B/step':>8} {'fixed B/ep':>10} {'log_step us':>12} {'end us/step':>12} "
          f"{'total us/step':>14}")
    for name, r in out["synthetic"].items():
        print(f"  {name:<20} {r['bytes_per_step']:>8.0f} {r['fixed_bytes_per_episode']:>10.0f} "
              f"{r['log_step_us']:>12.1f} {r['end_episode_us_per_step']:>12.1f} {r['total_us_per_step']:>14.1f}")
    print("  (default = centreline + m1/m2 + commanded/actual curvature + target + 20 scalars, as TaskProbe logs)")
    if a.env:
        e = out["env"]
        print(f"real env {e['task']} (1 env, {e['steps']} control steps): {e['env_step_ms']:.2f} ms/step plain, "
              f"{e['env_step_recorded_ms']:.2f} ms/step recorded -> overhead {e['overhead_ms_per_step']:.2f} ms/step "
              f"({e['overhead_pct']:.0f} %), file {e['file_bytes'] / 1024:.0f} KiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
