"""The sweep machinery shared by the accuracy scenes (``benchmarks.accuracy``, ``benchmarks.accuracy_extra``,
``benchmarks.accuracy_contact``): solver settings, the grids, timed repeats, the rodlab and PyElastica sweeps and
the PyElastica output cache. ``PEER_ONLY`` is set by ``rodlab bench accuracy --peer-only``."""
from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from .common import load
from .rodlab_runs import CONVERGED, PAPER, Solver

__all__ = ["SOLVERS", "ORDER_NODES", "PEER_ONLY", "PEER_CACHE", "grids", "timed", "sweep_points", "say",
           "run_rodlab_sweep", "run_elastica_sweep"]

SOLVERS = {"conv": CONVERGED, "paper": PAPER, "it1": Solver(tol=1e-3, max_iter=1),
           "it5": Solver(tol=1e-3, max_iter=5), "mid": replace(CONVERGED, integrator="midpoint")}
ORDER_NODES = 21  # node count of the time-convergence study


def grids(quick: bool) -> dict:
    if quick:
        return {"dts": [1e-3, 1e-2, 5e-2], "nodes": [11, 21], "solvers": ["conv", "paper"],
                "small_dt_solvers": ["conv"], "el_nodes": [11, 21], "el_factors": [1.0], "max_work": 3e5,
                "ref_nodes": 41, "ref_dt": 1e-3, "el_ref_nodes": 21}
    return {"dts": [1e-4, 1e-3, 3e-3, 1e-2, 3e-2, 5e-2, 1e-1], "nodes": [11, 21, 41, 81],
            "solvers": ["conv", "paper", "mid"], "small_dt_solvers": ["conv", "mid"],
            "el_nodes": [11, 21, 41, 81], "el_factors": [2.0, 1.0, 0.5], "max_work": 7e5,
            "ref_nodes": 81, "ref_dt": 2e-4, "el_ref_nodes": 81}


def timed(fn, repeats: int, budget_s: float = 2.0) -> dict:
    """Run ``fn`` (returns a dict with wall_s) up to ``repeats`` times within ``budget_s``; the median
    wall time is stored in the returned (last) result, with the load average."""
    walls, cpus, res = [], [], None
    t_start = time.perf_counter()
    for _ in range(max(1, repeats)):
        res = fn()
        walls.append(res["wall_s"])
        cpus.append(res["cpu_s"])
        if time.perf_counter() - t_start > budget_s:
            break
    assert res is not None
    res["wall_s"] = float(np.median(walls))
    res["cpu_s"] = float(np.median(cpus))
    res["repeats"] = len(walls)
    res["load"] = load()
    return res


def sweep_points(g: dict, t_end: float):
    """(solver key, nodes, dt) of the rodlab sweep within the work budget."""
    for key in g["solvers"]:
        for n in g["nodes"]:
            for dt in g["dts"]:
                if dt < 3e-3 and key not in g["small_dt_solvers"]:
                    continue
                if (t_end / dt) * n > g["max_work"]:
                    continue
                yield key, n, dt


def say(msg: str) -> None:
    print(msg, flush=True)


PEER_ONLY = False  # --peer-only: fill the PyElastica cache, skip every rodlab run


def run_rodlab_sweep(name, run, scene, g, err_fn, repeats, extra=None):
    pts = []
    if PEER_ONLY:
        return pts
    for key, n, dt in sweep_points(g, scene.t_end):
        try:
            r = timed(lambda: run(scene, n_nodes=n, dt=dt, solver=SOLVERS[key]), repeats)
        except Exception as exc:  # an unsupported option (e.g. midpoint) must not kill the sweep
            say(f"  rodlab {name} {key} N={n} dt={dt:g}: skipped ({type(exc).__name__}: {exc})")
            continue
        p = {"sim": "rodlab", "solver": key, "nodes": n, "dt": dt, "cost": r["cpu_s"] / r["sim_s"],
             "cost_wall": r["wall_s"] / r["sim_s"], "stable": r["stable"], **{k: r[k] for k in ("newton_iters_mean", "newton_iters_max",
                                                          "substeps_max", "failed", "unconverged_frac",
                                                          "repeats", "load")}}
        p.update(err_fn(r, n))
        if n == ORDER_NODES and key in ("conv", "mid") and "t" in r:  # time-order study; dropped from JSON
            p["_traj"] = (r["t"], r.get("z", r.get("tip")))
        pts.append(p)
        say(f"  rodlab {name:7s} {key:5s} N={n:3d} dt={dt:7.0e} cost={p['cost']:.3g} s/s "
             f"err={p['error']:.3g} it={p['newton_iters_mean']:.2f}")
    return pts


PEER_CACHE: dict = {}  # raw PyElastica outputs keyed "scene|N|dt" (see --peer-cache)


def run_elastica_sweep(name, run, scene, g, err_fn, spec_kw, repeats):
    """PyElastica points over ``g['el_nodes']`` x ``g['el_factors']`` (factor of the stability estimate).
    Raw outputs are kept in PEER_CACHE so a later run can reuse them (PyElastica does not change)."""
    from .peers.elastica_scenes import RodSpec, stable_dt_estimate
    pts = []
    for n in g["el_nodes"]:
        dt0 = stable_dt_estimate(RodSpec(n_nodes=n, **spec_kw))
        for f in g["el_factors"]:
            dt = dt0 * f
            if (scene.t_end / dt) * n > 40 * g["max_work"]:
                continue
            key = f"{name}|{n}|{dt:.6e}"
            r = PEER_CACHE.get(key)
            reused = r is not None
            if r is None:
                r = timed(lambda: run(scene, n_nodes=n, dt=dt), repeats if f >= 1 else 1, budget_s=1.0)
                PEER_CACHE[key] = r
            p = {"sim": "PyElastica", "nodes": n, "dt": dt, "cost": r["cpu_s"] / r["sim_s"],
                 "cost_wall": r["wall_s"] / r["sim_s"], "stable": r["stable"], "repeats": r["repeats"],
                 "load": r["load"], "reused_from_cache": reused}
            p.update(err_fn(r, n) if r["stable"] else {"error": None})
            pts.append(p)
            say(f"  PyElastica {name:7s} N={n:3d} dt={dt:8.2e} cost={p['cost']:.3g} s/s "
                 f"{'UNSTABLE' if not p['stable'] else ('err=%.3g' % p['error'] if p['error'] is not None else '')}"
                 f"{' (cached)' if reused else ''}")
    return pts
