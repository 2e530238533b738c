"""Parts of ``rodlab bench accuracy``: convergence orders, plots, summaries, the RL-setting study.

The RL-setting study (:func:`bench_rl`) drives the 21-node paper arm with the task action converter
(policies.control) over seeded random / bang-bang action sequences, once with a converged reference
(dt = 0.05/25 s, converged Newton) and once per candidate solver setting, and compares the tip positions
at the end of every control step (what the policy observes).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import accuracy_contact
from . import analysis as an
from .common import load, save_figure
from .references import trajectory_error
from .rodlab_runs import Solver, make_sim, scene_dict

EXPECTED = {"time_backward_euler": 1, "time_midpoint": 2,
            "space_vs_continuum": "1 (clamp offset: the first edge is rigid, root moves by O(l))",
            "space_interior": 2}


def add_orders(res: dict) -> None:
    """Observed convergence orders from the sweep points (pops the stored trajectories)."""
    pts = res["points"]
    orders: dict = {"expected": EXPECTED, "time": {}, "space": {}}
    curves_t: dict = {}
    curves_s: dict = {}
    for key in ("conv", "mid"):
        ser = sorted((p for p in pts if p.get("solver") == key and "_traj" in p), key=lambda p: p["dt"])
        if len(ser) >= 3:
            t_ref, y_ref = ser[0]["_traj"]
            hs, es = [], []
            for p in ser[1:]:
                t, y = p["_traj"]
                hs.append(p["dt"])
                es.append(trajectory_error(t, y, t_ref, y_ref))
            lab = f"rodlab {'backward Euler' if key == 'conv' else 'midpoint'} N={ser[0]['nodes']}"
            orders["time"][lab] = {"order": an.observed_order(hs, es),
                                   "order_small_dt": an.observed_order(hs[:3], es[:3]),
                                   "reference_dt": ser[0]["dt"], "dt": hs, "self_convergence_error": es}
            curves_t[lab] = (hs, es)
    for p in pts:
        p.pop("_traj", None)
    for sim_name, key in (("rodlab", "conv"), ("PyElastica", None)):
        by_n: dict = {}
        for p in pts:
            if p["sim"] != sim_name or (key and p.get("solver") != key) or p.get("error") is None:
                continue
            if not p.get("stable", True):
                continue
            if p["nodes"] not in by_n or p["dt"] < by_n[p["nodes"]]["dt"]:
                by_n[p["nodes"]] = p
        ser = [by_n[n] for n in sorted(by_n)]
        if len(ser) >= 2:
            L = res["params"].get("length", 1.0)
            h = [L / (p["nodes"] - 1) for p in ser]
            e = [p["error"] for p in ser]
            orders["space"][f"{sim_name} vs reference"] = {"order": an.observed_order(h, e), "h": h, "error": e,
                                                           "dt": [p["dt"] for p in ser]}
            curves_s[f"{sim_name}"] = (h, e)
            for fld, lab in (("error_root_at_node1", "root at node 1"), ("error_root_at_half_edge", "root at l/2")):
                if fld in ser[0]:
                    e2 = [p[fld] for p in ser]
                    orders["space"][f"{sim_name} vs {lab} reference"] = {"order": an.observed_order(h, e2),
                                                                         "h": h, "error": e2}
                    curves_s[f"{sim_name} ({lab})"] = (h, e2)
    res["orders"] = orders
    res["_curves"] = (curves_t, curves_s)


def plot_scene(plt, res: dict, out: Path) -> None:
    name = res["scene"]
    pts = res["points"]
    series: dict = {}
    for p in pts:
        lab = "PyElastica" if p["sim"] == "PyElastica" else f"rodlab {p['solver']}"
        series.setdefault(lab, []).append(p)
    loads = [p["load"][0] for p in pts if p.get("load")]
    note = (f"{res.get('error_definition', '')}. Load avg during runs {min(loads, default=0):.2f}-"
            f"{max(loads, default=0):.2f} on a shared 2-core machine.")
    fig = an.plot_pareto(plt, f"accuracy: {name} - error vs CPU time per simulated second", series, note=note)
    res.setdefault("figures", []).append(str(save_figure(fig, out, f"accuracy_{name}_pareto.png")))
    curves_t, curves_s = res.pop("_curves", (None, None))
    if curves_t is None:  # replot from the stored orders
        o = res.get("orders", {})
        curves_t = {k: (v["dt"], v["self_convergence_error"]) for k, v in o.get("time", {}).items()}
        curves_s = {k.replace(" vs reference", "").replace(" vs ", " (").replace(" reference", ")"): (v["h"], v["error"])
                    for k, v in o.get("space", {}).items()}
    if curves_t:
        fig = an.plot_convergence(plt, f"{name}: time convergence (self-convergence, converged Newton)",
                                  curves_t, xlabel="dt [s]",
                                  ylabel="max tip distance to the smallest-dt run [m]")
        res["figures"].append(str(save_figure(fig, out, f"accuracy_{name}_order_dt.png")))
    if curves_s:
        fig = an.plot_convergence(plt, f"{name}: space convergence (smallest dt per node count)", curves_s,
                                  xlabel="element length [m]")
        res["figures"].append(str(save_figure(fig, out, f"accuracy_{name}_order_space.png")))


def _fmt(x, f=".3g") -> str:
    return "-" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, f)


def print_summary(name: str, res: dict) -> None:
    print(f"\n=== accuracy / {name} ===")
    a = res.get("analysis")
    if a:
        print("rodlab Pareto front (cost s/s, error, solver, N, dt):")
        for row in a["pareto_rodlab"]:
            print(f"   {row[0]:9.3g} {row[1]:9.3g}  {row[2]:5s} N={row[3]:3d} dt={row[4]:.0e}")
        if a["pareto_pyelastica"]:
            print("PyElastica Pareto front (cost s/s, error, N, dt):")
            for row in a["pareto_pyelastica"]:
                print(f"   {row[0]:9.3g} {row[1]:9.3g}  N={row[2]:3d} dt={row[3]:.2e}")
        for row in a["speedup_at_equal_error"]:
            print(f"   at error {row['error']:.3g}: rodlab {_fmt(row['cost_rodlab'])} s/s, PyElastica "
                  f"{_fmt(row['cost_peer'])} s/s -> speed-up {_fmt(row['speedup'])}x")
        if "min_error" in a:
            print(f"   smallest error reached: rodlab {_fmt(a['min_error']['rodlab'])}, "
                  f"PyElastica {_fmt(a['min_error']['PyElastica'])}")
    for kind in ("time", "space"):
        for lab, o in res.get("orders", {}).get(kind, {}).items():
            print(f"   observed {kind} order, {lab}: {_fmt(o['order'], '.2f')}"
                  + (f" (3 smallest dt: {_fmt(o.get('order_small_dt'), '.2f')})" if 'order_small_dt' in o else ""))
    if "model_gap" in res:
        print(f"   model gap converged PyElastica vs converged rodlab: {res['model_gap']['max_tip_distance_over_L']:.3g} L")
    if "settings" in res:
        print(f"{'setting':22s} {'dt':>6s} {'it':>3s} {'ms/ctrl-step':>12s} {'us/env-step':>11s} "
              f"{'mean err [mm]':>13s} {'max err [mm]':>12s}")
        for s in res["settings"]:
            print(f"{s['name']:22s} {s['dt']:6.3f} {s['max_iter']:3d} {s['ms_per_control_step']:12.2f} "
                  f"{s['us_per_env_control_step']:11.1f} {1e3 * s['err_mean_m']:13.2f} {1e3 * s['err_max_m']:12.2f}")
    for f in res.get("figures", []):
        print(f"   figure: {f}")


# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RLSetting:
    name: str
    dt: float
    solver: Solver


RL_TASKS = {  # task -> (control kind, sim mode, control period [s])
    "follow3d": ("bend", "3d", 0.1),
    "ik4d": ("bend_twist", "3d", 0.1),
    "follow2d": ("bend_2d", "2d", 0.1),
}


def _rl_settings(quick: bool) -> list[RLSetting]:
    conv = Solver(tol=1e-8, max_iter=30, dtol=1e-7)
    mid10 = Solver(tol=1e-3, max_iter=10, integrator="midpoint")
    s = [RLSetting("paper (dt .05, 2 it)", 0.05, Solver(tol=1e-3, max_iter=2)),
         RLSetting("dt .05, converged", 0.05, conv),
         RLSetting("dt .025, 2 it", 0.025, Solver(tol=1e-3, max_iter=2)),
         RLSetting("midpoint dt .05, <=10 it", 0.05, mid10)]
    if not quick:
        s += [RLSetting("dt .05, 3 it", 0.05, Solver(tol=1e-3, max_iter=3)),
              RLSetting("dt .1, 3 it", 0.1, Solver(tol=1e-3, max_iter=3)),
              RLSetting("dt .0125, 2 it", 0.0125, Solver(tol=1e-3, max_iter=2)),
              RLSetting("midpoint dt .05, 5 it", 0.05, Solver(tol=1e-3, max_iter=5, integrator="midpoint")),
              RLSetting("midpoint dt .025, <=10 it", 0.025, mid10)]
    return s


def _rl_rollout(kind: str, mode: str, period: float, setting: RLSetting, actions: np.ndarray) -> dict:
    """Drive B envs through the action sequence (T, B, dim); tip positions (T+1, B, 3) at control-step ends."""
    from policies.control import ActionConverter, control_config
    T, B, _ = actions.shape
    sub = max(1, int(round(period / setting.dt)))
    doc = scene_dict(nodes=21, length=1.0, radius=0.05, density=1000.0, youngs=1e7, poisson=0.5,
                     dt=period / sub, gravity=(0.0, 0.0, -9.8), damping=0.0, solver=setting.solver, mode=mode)
    sim, state, ctrl = make_sim(doc, envs=B)
    conv = ActionConverter(control_config(kind, substeps=sub), envs=B)
    tips = [np.asarray(state.node_pos[:, -1]).copy()]
    iters, fails, subs = [], 0, 1
    t0, c0 = time.perf_counter(), time.process_time()
    for k in range(T):
        inc = conv.convert(actions[k])
        for s in range(sub):
            ActionConverter.apply(ctrl, inc, s)
            st = sim.step(state, ctrl)
            iters.append(np.asarray(st.newton_iters).mean())
            fails += int(np.sum(st.failed))
            subs = max(subs, int(np.max(st.substeps)))
        tips.append(np.asarray(state.node_pos[:, -1]).copy())
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"tips": np.stack(tips), "wall_s": wall, "cpu_s": cpu, "iters_mean": float(np.mean(iters)), "failed": fails,
            "substeps_max": subs, "nan": int(np.sum(~np.isfinite(np.stack(tips))))}


def bench_rl(*, quick: bool, repeats: int) -> dict | None:
    """Error of the paper's RL setting (and candidates) against a converged solution on task trajectories."""
    try:
        import policies.control  # noqa: F401
    except ImportError as exc:
        print(f"rl: skipped ({exc})")
        return None
    B = 4 if quick else 8
    T = 20 if quick else 40
    rng = np.random.default_rng(1234)
    out = {"scene": "rl", "envs": B, "control_steps": T, "tasks": {}, "settings": []}
    # reference: converged implicit midpoint (second order) at dt = 2 ms; the backward-Euler run at the
    # same dt is kept as a second reference (it is first order: ~7 mm mean off at 2 ms)
    ref_setting = RLSetting("reference", 0.05 / (5 if quick else 25),
                            Solver(tol=1e-9, max_iter=30, dtol=1e-8, integrator="midpoint"))
    ref_be_setting = RLSetting("reference BE", ref_setting.dt, Solver(tol=1e-9, max_iter=30, dtol=1e-8))
    agg: dict = {}
    for task, (kind, mode, period) in (list(RL_TASKS.items())[:1] if quick else RL_TASKS.items()):
        from policies.control import control_config
        dim = control_config(kind, substeps=1).action_dim
        for act_kind in ("random", "bang-bang"):
            a = rng.uniform(-1, 1, size=(T, B, dim)).astype(np.float32)
            if act_kind == "bang-bang":
                # hold a random sign pattern for 10 control steps, then flip some components
                a = np.sign(a[::10].repeat(10, axis=0)[:T]).astype(np.float32)
            ref = _rl_rollout(kind, mode, period, ref_setting, a)
            ref_be = _rl_rollout(kind, mode, period, ref_be_setting, a)
            key = f"{task}/{act_kind}"
            out["tasks"][key] = {"reference_dt": ref_setting.dt, "reference_iters_mean": ref["iters_mean"],
                                 "reference_failed": ref["failed"],
                                 "midpoint_vs_backward_euler_reference_mean_m": float(np.mean(
                                     np.linalg.norm(ref["tips"] - ref_be["tips"], axis=-1))),
                                 "tip_travel_m": float(np.mean(np.linalg.norm(ref["tips"][-1] - ref["tips"][0],
                                                                              axis=-1)))}
            for s in _rl_settings(quick):
                r = _rl_rollout(kind, mode, period, s, a)
                d = np.linalg.norm(r["tips"] - ref["tips"], axis=-1)  # (T+1, B)
                d_be = np.linalg.norm(r["tips"] - ref_be["tips"], axis=-1)
                walls = [r["cpu_s"]]  # CPU seconds (1 numba thread): robust to the shared machine's load
                for _ in range(max(0, min(repeats, 2) - 1)):
                    walls.append(_rl_rollout(kind, mode, period, s, a)["cpu_s"])
                row = agg.setdefault(s.name, {"name": s.name, "dt": s.dt, "max_iter": s.solver.max_iter,
                                              "tol": s.solver.tol, "integrator": s.solver.integrator,
                                              "errs": [], "maxs": [], "errs_be": [], "ms": [], "iters": [],
                                              "failed": 0,
                                              "nan": 0, "per_task": {}})
                row["errs"].append(float(d.mean()))
                row["errs_be"].append(float(d_be.mean()))
                row["maxs"].append(float(d.max()))
                row["ms"].append(1e3 * float(np.median(walls)) / T)
                row["iters"].append(r["iters_mean"])
                row["failed"] += r["failed"]
                row["nan"] += r["nan"]
                row["per_task"][key] = {"err_mean_m": float(d.mean()), "err_max_m": float(d.max()),
                                        "ms_per_control_step": 1e3 * float(np.median(walls)) / T}
                print(f"  rl {key:20s} {s.name:24s} err mean {1e3 * d.mean():7.2f} mm max {1e3 * d.max():7.2f} mm"
                      f"  {1e3 * np.median(walls) / T:7.2f} CPU ms/ctrl-step (B={B})", flush=True)
    for row in agg.values():
        ms = float(np.mean(row.pop("ms")))
        out["settings"].append({**{k: v for k, v in row.items() if k not in ("errs", "maxs", "iters", "errs_be")},
                                "err_mean_m": float(np.mean(row["errs"])), "err_max_m": float(np.max(row["maxs"])),
                                "err_mean_vs_be_reference_m": float(np.mean(row["errs_be"])),
                                "iters_mean": float(np.mean(row["iters"])), "ms_per_control_step": ms,
                                "us_per_env_control_step": 1e3 * ms / B})
    out["load"] = load()
    out["note"] = ("tip position difference at the end of every control step against the reference "
                   f"(implicit midpoint, dt {ref_setting.dt:g} s, converged Newton), same action sequence; no "
                   "damping (DisMech RL setting); err_mean_vs_be_reference_m: against converged backward Euler "
                   "at the same small dt; cost: CPU ms per control step of B envs batched (1 numba thread)")
    return out


def bench_contact(*, quick: bool, peer: bool, repeats: int) -> dict | None:
    """Arm pressed into an obstacle (benchmarks/accuracy_contact.py)."""
    return accuracy_contact.bench(quick=quick, peer=peer, repeats=repeats)
