"""``rodlab bench accuracy``: run time against error, rodlab against PyElastica.

Scenes (benchmarks.scenes): ``static`` heavy cantilever vs the closed-form elastica, ``dynamic``
cantilever vs Euler-Bernoulli, ``arm`` (paper arm under a time-varying curvature command) vs a converged
rodlab run, ``rl`` (the paper's RL setting on task trajectories, benchmarks.accuracy_rl), ``contact``
(arm pressed into an obstacle, benchmarks.accuracy_contact, when the contact model is available).
For every point: wall time per simulated second (1 env, 1 core) and the error; Pareto fronts,
speed-up at equal error, observed convergence orders.  Prints a summary, writes
``accuracy.json`` and PNG plots to ``--out``.
"""
from __future__ import annotations

import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from . import analysis as an
from .common import base_parser, have_elastica, load, machine_info, pyplot, write_json
from .references import heavy_elastica, trajectory_error
from .rodlab_runs import CONVERGED, PAPER, Solver
from .scenes import ArmCommand, DynamicCantilever, StaticCantilever

SOLVERS = {"conv": CONVERGED, "paper": PAPER, "it1": Solver(tol=1e-3, max_iter=1),
           "it5": Solver(tol=1e-3, max_iter=5), "mid": replace(CONVERGED, integrator="midpoint")}
ORDER_NODES = 21  # node count of the time-convergence study
SCENES = ("rl", "static", "dynamic", "arm", "contact")


def grids(quick: bool) -> dict:
    if quick:
        return {"dts": [1e-3, 1e-2, 5e-2], "nodes": [11, 21], "solvers": ["conv", "paper"],
                "small_dt_solvers": ["conv"], "el_nodes": [11, 21], "el_factors": [1.0], "max_work": 3e5,
                "ref_nodes": 41, "ref_dt": 1e-3, "el_ref_nodes": 21}
    return {"dts": [1e-4, 1e-3, 3e-3, 1e-2, 3e-2, 5e-2, 1e-1], "nodes": [11, 21, 41, 81],
            "solvers": ["conv", "paper", "mid"], "small_dt_solvers": ["conv", "mid"],
            "el_nodes": [11, 21, 41, 81], "el_factors": [2.0, 1.0, 0.5], "max_work": 7e5,
            "ref_nodes": 81, "ref_dt": 2e-4, "el_ref_nodes": 81}


def _timed(fn, repeats: int, budget_s: float = 2.0) -> dict:
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


def _points(g: dict, t_end: float):
    """(solver key, nodes, dt) of the rodlab sweep within the work budget."""
    for key in g["solvers"]:
        for n in g["nodes"]:
            for dt in g["dts"]:
                if dt < 3e-3 and key not in g["small_dt_solvers"]:
                    continue
                if (t_end / dt) * n > g["max_work"]:
                    continue
                yield key, n, dt


def _say(msg: str) -> None:
    print(msg, flush=True)


PEER_ONLY = False  # --peer-only: fill the PyElastica cache, skip every rodlab run


def _run_rodlab_sweep(name, run, scene, g, err_fn, repeats, extra=None):
    pts = []
    if PEER_ONLY:
        return pts
    for key, n, dt in _points(g, scene.t_end):
        try:
            r = _timed(lambda: run(scene, n_nodes=n, dt=dt, solver=SOLVERS[key]), repeats)
        except Exception as exc:  # an unsupported option (e.g. midpoint) must not kill the sweep
            _say(f"  rodlab {name} {key} N={n} dt={dt:g}: skipped ({type(exc).__name__}: {exc})")
            continue
        p = {"sim": "rodlab", "solver": key, "nodes": n, "dt": dt, "cost": r["cpu_s"] / r["sim_s"],
             "cost_wall": r["wall_s"] / r["sim_s"], "stable": r["stable"], **{k: r[k] for k in ("newton_iters_mean", "newton_iters_max",
                                                          "substeps_max", "failed", "unconverged_frac",
                                                          "repeats", "load")}}
        p.update(err_fn(r, n))
        if n == ORDER_NODES and key in ("conv", "mid") and "t" in r:  # time-order study; dropped from JSON
            p["_traj"] = (r["t"], r.get("z", r.get("tip")))
        pts.append(p)
        _say(f"  rodlab {name:7s} {key:5s} N={n:3d} dt={dt:7.0e} cost={p['cost']:.3g} s/s "
             f"err={p['error']:.3g} it={p['newton_iters_mean']:.2f}")
    return pts


PEER_CACHE: dict = {}  # raw PyElastica outputs keyed "scene|N|dt" (see --peer-cache)


def _run_elastica_sweep(name, run, scene, g, err_fn, spec_kw, repeats):
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
                r = _timed(lambda: run(scene, n_nodes=n, dt=dt), repeats if f >= 1 else 1, budget_s=1.0)
                PEER_CACHE[key] = r
            p = {"sim": "PyElastica", "nodes": n, "dt": dt, "cost": r["cpu_s"] / r["sim_s"],
                 "cost_wall": r["wall_s"] / r["sim_s"], "stable": r["stable"], "repeats": r["repeats"],
                 "load": r["load"], "reused_from_cache": reused}
            p.update(err_fn(r, n) if r["stable"] else {"error": None})
            pts.append(p)
            _say(f"  PyElastica {name:7s} N={n:3d} dt={dt:8.2e} cost={p['cost']:.3g} s/s "
                 f"{'UNSTABLE' if not p['stable'] else ('err=%.3g' % p['error'] if p['error'] is not None else '')}"
                 f"{' (cached)' if reused else ''}")
    return pts


# ------------------------------------------------------------------------------------------------
def bench_static(g, peer, repeats) -> dict:
    from . import rodlab_runs as rr
    sc = replace(StaticCantilever(), t_end=3.0)
    ref = sc.reference_tip("extensible")
    ref_shear = sc.reference_tip("shearable")
    G = sc.youngs / (2 * (1 + sc.poisson))
    shifted: dict = {}

    def shifted_tip(n, model, frac):
        """Tip of the elastica clamped horizontally at x = frac * l (l the element length)."""
        key = (n, model, frac)
        if key not in shifted:
            l = frac * sc.length / (n - 1)
            s = heavy_elastica(length=sc.length - l, EI=sc.EI, w=sc.density * sc.area * sc.g,
                               EA=sc.youngs * sc.area, GA=G * sc.area, model=model)
            shifted[key] = s.tip + np.array([l, 0.0])
        return shifted[key]

    def err(model):
        r0 = ref if model == "extensible" else ref_shear

        def f(r, n):
            tip = np.asarray(r["tip"])
            return {"error": float(np.linalg.norm(tip - r0) / sc.length),
                    "error_root_at_node1": float(np.linalg.norm(tip - shifted_tip(n, model, 1.0)) / sc.length),
                    "error_root_at_half_edge": float(np.linalg.norm(tip - shifted_tip(n, model, 0.5)) / sc.length),
                    "tip": tip.tolist()}
        return f

    _say(f"static heavy cantilever: reference tip {ref} (extensible), {ref_shear} (shearable)")
    pts = _run_rodlab_sweep("static", rr.run_static, sc, g, err("extensible"), repeats)
    if peer:
        from .peers import elastica_scenes as es
        kw = dict(length=sc.length, radius=sc.radius, density=sc.density, youngs=sc.youngs)
        pts += _run_elastica_sweep("static", es.run_static, sc, g, err("shearable"), kw, repeats)
    return {"scene": "static", "params": vars(sc), "reference_tip": ref.tolist(),
            "reference_tip_shearable": ref_shear.tolist(), "points": pts,
            "error_definition": "|tip - tip_elastica| / L at t_end (rodlab vs extensible elastica, "
                                "PyElastica vs shearable elastica); error_root_at_node1 / _at_half_edge use a clamp moved to x = l / x = l/2"}


def bench_dynamic(g, peer, repeats) -> dict:
    from . import rodlab_runs as rr
    sc = DynamicCantilever()
    beam = sc.beam

    def err(r, n):
        t, z = np.asarray(r["t"]), np.asarray(r["z"])
        return {"error": float(np.max(np.abs(z - beam.tip_z(t))) / beam.amplitude)}

    _say(f"dynamic cantilever: omega1 {beam.omega1:.4f} rad/s, amplitude {beam.amplitude:.4g} m")
    pts = _run_rodlab_sweep("dynamic", rr.run_dynamic, sc, g, err, repeats)
    if peer:
        from .peers import elastica_scenes as es
        kw = dict(length=sc.length, radius=sc.radius, density=sc.density, youngs=sc.youngs)
        pts += _run_elastica_sweep("dynamic", es.run_dynamic, sc, g, err, kw, repeats)
    return {"scene": "dynamic", "params": {**vars(sc), "omega1": beam.omega1, "amplitude": beam.amplitude},
            "points": pts, "error_definition": "max_t |z_tip - z_EB(t)| / amplitude over two periods"}


def bench_arm(g, peer, repeats) -> dict:
    from . import rodlab_runs as rr
    sc = ArmCommand()
    if PEER_ONLY:
        from .peers import elastica_scenes as es
        kw = dict(length=sc.length, radius=sc.radius, density=sc.density, youngs=sc.youngs)
        _run_elastica_sweep("arm", es.run_arm, sc, g, lambda r, n: {"error": None}, kw, repeats)
        return None
    _say(f"arm: converged rodlab reference N={g['ref_nodes']} dt={g['ref_dt']:g} ...")
    t0 = time.perf_counter()
    ref = rr.run_arm(sc, n_nodes=g["ref_nodes"], dt=g["ref_dt"], solver=CONVERGED, sample_dt=0.01)
    ref2 = rr.run_arm(sc, n_nodes=g["ref_nodes"], dt=2 * g["ref_dt"], solver=CONVERGED, sample_dt=0.01)
    ref_t, ref_tip = np.asarray(ref["t"]), np.asarray(ref["tip"])
    ref_err_est = trajectory_error(ref2["t"], ref2["tip"], ref_t, ref_tip, scale=sc.length)
    _say(f"  reference done in {time.perf_counter() - t0:.1f} s; |ref(2dt) - ref(dt)| = {ref_err_est:.2e}")

    def err(r, n):
        return {"error": trajectory_error(r["t"], r["tip"], ref_t, ref_tip, scale=sc.length)}

    pts = _run_rodlab_sweep("arm", lambda s, **kw: rr.run_arm(s, **kw), sc, g, err, repeats)
    out = {"scene": "arm", "params": vars(sc), "reference": {"nodes": g["ref_nodes"], "dt": g["ref_dt"],
                                                              "dt_halving_change": ref_err_est},
           "error_definition": "max_t |tip - tip_ref(t)| / L, tip_ref = converged rodlab run"}
    if peer:
        from .peers import elastica_scenes as es
        kw = dict(length=sc.length, radius=sc.radius, density=sc.density, youngs=sc.youngs)
        pts += _run_elastica_sweep("arm", es.run_arm, sc, g, err, kw, repeats)
        nref = g["el_ref_nodes"]
        dt_ref = es.stable_dt_estimate(es.RodSpec(n_nodes=nref, **kw)) * 0.5
        key = f"arm_ref|{nref}|{dt_ref:.6e}"
        eref = PEER_CACHE.get(key) or es.run_arm(sc, n_nodes=nref, dt=dt_ref, sample_dt=0.01)
        PEER_CACHE[key] = eref
        gap = trajectory_error(eref["t"], eref["tip"], ref_t, ref_tip, scale=sc.length)
        out["model_gap"] = {"elastica_nodes": nref, "elastica_dt": dt_ref, "max_tip_distance_over_L": gap,
                            "note": "converged PyElastica vs converged rodlab: shear, rotary inertia, "
                                    "rotational damping and clamp convention"}
        _say(f"  model gap (converged PyElastica N={nref} vs converged rodlab): {gap:.3g} L")
    out["points"] = pts
    return out


# ------------------------------------------------------------------------------------------------
def analyse(res: dict) -> dict:
    pts = res["points"]
    rl = [p for p in pts if p["sim"] == "rodlab"]
    el = [p for p in pts if p["sim"] == "PyElastica"]
    fr_r, fr_e = an.pareto_front(rl), an.pareto_front(el)
    out = {"pareto_rodlab": [(p["cost"], p["error"], p.get("solver"), p["nodes"], p["dt"]) for p in fr_r],
           "pareto_pyelastica": [(p["cost"], p["error"], p["nodes"], p["dt"]) for p in fr_e],
           "speedup_at_equal_error": an.speedup_table(fr_r, fr_e)}
    if el:
        best_e = min((p["error"] for p in fr_e), default=math.inf)
        best_r = min((p["error"] for p in fr_r), default=math.inf)
        out["min_error"] = {"rodlab": best_r, "PyElastica": best_e}
    return out


def main(argv: list[str] | None = None) -> int:
    p = base_parser("rodlab bench accuracy", __doc__.split("\n")[0])
    p.add_argument("--scenes", default=",".join(SCENES),
                   help=f"comma-separated subset of {','.join(SCENES)}")
    p.add_argument("--peer-cache", type=Path, default=None,
                   help="JSON of raw PyElastica outputs to reuse/extend (default: OUT/accuracy_peer_raw[_quick].json;"
                        " delete it to re-measure PyElastica)")
    p.add_argument("--peer-only", action="store_true", help="only fill the PyElastica cache (no rodlab runs)")
    p.add_argument("--replot", action="store_true", help="only redraw the figures (and analysis) from OUT/accuracy.json")
    args = p.parse_args(argv)
    if args.replot:
        import json

        from . import accuracy_extra as ax
        f = Path(args.out) / ("accuracy_quick.json" if args.quick else "accuracy.json")
        result = json.loads(f.read_text())
        plt = pyplot()
        for name, res in result["scenes"].items():
            if "points" in res:
                res["analysis"] = analyse(res)
                res["figures"] = []
                ax.plot_scene(plt, res, args.out)
                ax.print_summary(name, res)
        write_json(f.parent, f.name, result)
        return 0
    global PEER_ONLY
    PEER_ONLY = bool(args.peer_only)
    scenes = [s.strip() for s in args.scenes.split(",") if s.strip()]
    for s in scenes:
        if s not in SCENES:
            p.error(f"--scenes: unknown scene {s!r} (choose from {', '.join(SCENES)})")
    peer = have_elastica() and not args.no_peer
    if not peer and not args.no_peer:
        _say("PyElastica not installed: peer columns skipped (pip install 'rodlab[peers]')")
    g = grids(args.quick)
    repeats = args.repeats or (1 if args.quick else 3)
    result = {"benchmark": "accuracy", "quick": args.quick, "machine": machine_info(), "grids": g,
              "command": "rodlab bench accuracy " + " ".join(argv or sys.argv[1:]), "scenes": {}}
    _say(f"machine: {result['machine']['cpu_model']}, {result['machine']['logical_cores']} cores, "
         f"load {result['machine']['loadavg_at_start']}")
    try:  # single-env runs: one numba thread, so CPU time = work (robust to the shared machine's load)
        import numba
        numba.set_num_threads(1)
    except Exception:  # pragma: no cover
        pass
    from . import rodlab_runs as rr
    if not PEER_ONLY:
        rr.run_static(StaticCantilever(t_end=0.01), n_nodes=11, dt=1e-2)  # numba warm-up, not timed
    import json
    cache_path = args.peer_cache or Path(args.out) / ("accuracy_peer_raw_quick.json" if args.quick
                                                      else "accuracy_peer_raw.json")
    if peer and cache_path.exists():
        try:
            PEER_CACHE.update(json.loads(cache_path.read_text()))
            _say(f"reusing {len(PEER_CACHE)} cached PyElastica runs from {cache_path}")
        except (OSError, ValueError) as exc:
            _say(f"ignoring unreadable peer cache {cache_path}: {exc}")
    result["peer_cache"] = str(cache_path)
    out_json = Path(args.out) / ("accuracy_quick.json" if args.quick else "accuracy.json")
    if out_json.exists() and not PEER_ONLY:  # keep the scenes this run does not redo
        try:
            old = json.loads(out_json.read_text()).get("scenes", {})
            for k, v in old.items():
                if k not in scenes:
                    v["from_previous_run"] = True
                    result["scenes"][k] = v
        except (OSError, ValueError):
            pass
    plt = pyplot()
    from . import accuracy_extra as ax
    for name in scenes:
        t0 = time.perf_counter()
        if peer and cache_path.exists():  # another run may have filled it meanwhile
            try:
                for k, v in json.loads(cache_path.read_text()).items():
                    PEER_CACHE.setdefault(k, v)
            except (OSError, ValueError):
                pass
        if name == "static":
            res = bench_static(g, peer, repeats)
        elif name == "dynamic":
            res = bench_dynamic(g, peer, repeats)
        elif name == "arm":
            res = bench_arm(g, peer, repeats)
        elif name == "rl":
            res = ax.bench_rl(quick=args.quick, repeats=repeats)
        else:
            res = ax.bench_contact(quick=args.quick, peer=peer, repeats=repeats)
        if peer and PEER_CACHE:
            write_json(cache_path.parent, cache_path.name, PEER_CACHE)
        if res is None:
            continue
        if "points" in res:
            res["analysis"] = analyse(res)
            ax.add_orders(res)
            ax.plot_scene(plt, res, args.out)
        res["wall_s_total"] = time.perf_counter() - t0
        res["load_at_end"] = load()
        result["scenes"][name] = res
        ax.print_summary(name, res)
        if not PEER_ONLY:
            write_json(args.out, "accuracy.json" if not args.quick else "accuracy_quick.json", result)
    if args.json:
        print(json.dumps(result, default=str)[:200000])
    _say(f"wrote {Path(args.out) / ('accuracy_quick.json' if args.quick else 'accuracy.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
