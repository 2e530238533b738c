"""Timing one batched ``sim.step`` of the paper arm: the scene document and the timer shared by the throughput
parts (``benchmarks.throughput``, ``benchmarks.throughput_tasks``, ``benchmarks.throughput_pairs``)."""
from __future__ import annotations

import time

import numpy as np

from .common import load
from .rodlab_runs import Solver, make_sim, scene_dict

__all__ = ["ARM", "PAPER_SOLVER", "time_sim", "arm_doc"]

ARM = dict(length=1.0, radius=0.05, density=1000.0, youngs=1e7, poisson=0.5)
PAPER_SOLVER = Solver(tol=1e-3, max_iter=2)


def time_sim(doc: dict, *, envs: int, steps: int = 10, repeats: int = 5, planar: bool = False,
             setup=None) -> dict:
    """Median wall (and CPU) time of one batched ``sim.step`` of ``envs`` envs, driven by a per-env sinusoidal
    natural-curvature command (so every step has Newton work).  ``setup(sim, state, ctrl)`` may place
    obstacles.  Returns ms per step, µs per env-step, mean Newton iterations, load."""
    sim, state, ctrl = make_sim(doc, envs=envs)
    if setup is not None:
        setup(sim, state, ctrl)
    N = ctrl.kappa_bar.shape[1]
    rng = np.random.default_rng(0)
    phase = rng.uniform(0, 2 * np.pi, size=(envs, 1))
    amp = 0.6 / (N - 1)  # integrated curvature: 0.6 rad total bend at full amplitude
    dt = doc["sim"]["dt"]
    k = [0]
    iters: list[float] = []

    def one():
        k[0] += 1
        t = k[0] * dt
        ctrl.kappa_bar[:, 1:-1, 0] = amp * np.sin(2.0 * t + phase)
        if not planar:
            ctrl.kappa_bar[:, 1:-1, 1] = amp * np.cos(1.3 * t + phase)
        st = sim.step(state, ctrl)
        iters.append(float(np.mean(st.newton_iters)))

    one()  # warm-up (numba dispatch, caches)
    ts, cs = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(steps):
            one()
        ts.append((time.perf_counter() - t0) / steps)
        cs.append((time.process_time() - c0) / steps)
    ms = 1e3 * float(np.median(ts))
    return {"envs": envs, "ms_per_step": ms, "us_per_env_step": 1e3 * ms / envs,
            "cpu_ms_per_step": 1e3 * float(np.median(cs)), "failed_envs": int(np.sum(state.failed)),
            "iters_mean": float(np.mean(iters)), "nan": int(np.sum(~np.isfinite(state.dof))),
            "repeats": repeats, "load": load()}


def arm_doc(*, nodes: int = 21, dt: float = 0.05, solver: Solver = PAPER_SOLVER, mode: str = "3d",
            radius: float | None = None, **kw) -> dict:
    a = dict(ARM)
    if radius is not None:
        a["radius"] = radius
    return scene_dict(nodes=nodes, dt=dt, solver=solver, mode=mode, gravity=(0.0, 0.0, -9.8), **a, **kw)
