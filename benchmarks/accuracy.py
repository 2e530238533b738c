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

from . import accuracy_extra as ax
from . import accuracy_sweeps as sw
from . import analysis as an
from . import rodlab_runs as rr
from .accuracy_sweeps import PEER_CACHE, grids, run_elastica_sweep, run_rodlab_sweep
from .accuracy_sweeps import say as _say
from .common import base_parser, have_elastica, load, machine_info, pyplot, write_json
from .references import heavy_elastica, trajectory_error
from .rodlab_runs import CONVERGED
from .scenes import ArmCommand, DynamicCantilever, StaticCantilever

SCENES = ("rl", "static", "dynamic", "arm", "contact")


# ------------------------------------------------------------------------------------------------
def bench_static(g, peer, repeats) -> dict:
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
    pts = run_rodlab_sweep("static", rr.run_static, sc, g, err("extensible"), repeats)
    if peer:
        from .peers import elastica_scenes as es
        kw = dict(length=sc.length, radius=sc.radius, density=sc.density, youngs=sc.youngs)
        pts += run_elastica_sweep("static", es.run_static, sc, g, err("shearable"), kw, repeats)
    return {"scene": "static", "params": vars(sc), "reference_tip": ref.tolist(),
            "reference_tip_shearable": ref_shear.tolist(), "points": pts,
            "error_definition": "|tip - tip_elastica| / L at t_end (rodlab vs extensible elastica, "
                                "PyElastica vs shearable elastica); error_root_at_node1 / _at_half_edge use a clamp moved to x = l / x = l/2"}


def bench_dynamic(g, peer, repeats) -> dict:
    sc = DynamicCantilever()
    beam = sc.beam

    def err(r, n):
        t, z = np.asarray(r["t"]), np.asarray(r["z"])
        return {"error": float(np.max(np.abs(z - beam.tip_z(t))) / beam.amplitude)}

    _say(f"dynamic cantilever: omega1 {beam.omega1:.4f} rad/s, amplitude {beam.amplitude:.4g} m")
    pts = run_rodlab_sweep("dynamic", rr.run_dynamic, sc, g, err, repeats)
    if peer:
        from .peers import elastica_scenes as es
        kw = dict(length=sc.length, radius=sc.radius, density=sc.density, youngs=sc.youngs)
        pts += run_elastica_sweep("dynamic", es.run_dynamic, sc, g, err, kw, repeats)
    return {"scene": "dynamic", "params": {**vars(sc), "omega1": beam.omega1, "amplitude": beam.amplitude},
            "points": pts, "error_definition": "max_t |z_tip - z_EB(t)| / amplitude over two periods"}


def bench_arm(g, peer, repeats) -> dict:
    sc = ArmCommand()
    if sw.PEER_ONLY:
        from .peers import elastica_scenes as es
        kw = dict(length=sc.length, radius=sc.radius, density=sc.density, youngs=sc.youngs)
        run_elastica_sweep("arm", es.run_arm, sc, g, lambda r, n: {"error": None}, kw, repeats)
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

    pts = run_rodlab_sweep("arm", lambda s, **kw: rr.run_arm(s, **kw), sc, g, err, repeats)
    out = {"scene": "arm", "params": vars(sc), "reference": {"nodes": g["ref_nodes"], "dt": g["ref_dt"],
                                                              "dt_halving_change": ref_err_est},
           "error_definition": "max_t |tip - tip_ref(t)| / L, tip_ref = converged rodlab run"}
    if peer:
        from .peers import elastica_scenes as es
        kw = dict(length=sc.length, radius=sc.radius, density=sc.density, youngs=sc.youngs)
        pts += run_elastica_sweep("arm", es.run_arm, sc, g, err, kw, repeats)
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
    sw.PEER_ONLY = bool(args.peer_only)
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
    if not sw.PEER_ONLY:
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
    if out_json.exists() and not sw.PEER_ONLY:  # keep the scenes this run does not redo
        try:
            old = json.loads(out_json.read_text()).get("scenes", {})
            for k, v in old.items():
                if k not in scenes:
                    v["from_previous_run"] = True
                    result["scenes"][k] = v
        except (OSError, ValueError):
            pass
    plt = pyplot()
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
        if not sw.PEER_ONLY:
            write_json(args.out, "accuracy.json" if not args.quick else "accuracy_quick.json", result)
    if args.json:
        print(json.dumps(result, default=str)[:200000])
    _say(f"wrote {Path(args.out) / ('accuracy_quick.json' if args.quick else 'accuracy.json')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
