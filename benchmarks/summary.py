"""Markdown summary of the benchmark JSON files: ``python -m benchmarks.summary [--out docs/bench]``.

Prints the tables used in BENCHMARKS.md (Pareto speed-ups, same-resolution comparison, observed
orders, RL setting study, stress totals, throughput ratios) from accuracy.json, stress.json and
throughput.json in the output folder.  Read-only.
"""
from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from .analysis import pareto_front
from .common import DEFAULT_OUT


def _f(x, fmt=".3g") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return format(x, fmt)


def same_resolution(points: list[dict], *, slack: float = 1.05) -> list[dict]:
    """Per node count N run by both: PyElastica's cheapest stable point, and rodlab's cheapest run whose
    error is within ±(slack-1) of its time-converged error at that N (the error of its smallest-dt run),
    i.e. each simulator at the accuracy its spatial discretisation allows, as cheaply as it gets there.
    Runs that are *better* than time-converged through a cancellation of time and space errors (seen with
    the midpoint rule at dt = 0.1 s in the dynamic scene) are deliberately not used."""
    rows = []
    for n in sorted({p["nodes"] for p in points if p["sim"] == "PyElastica"}):
        el = [p for p in points if p["sim"] == "PyElastica" and p["nodes"] == n and p.get("error") is not None
              and p.get("stable", True)]
        rl_all = [p for p in points if p["sim"] == "rodlab" and p["nodes"] == n and p.get("error") is not None]
        if not el or not rl_all:
            continue
        e = min(el, key=lambda p: p["cost"])
        conv = min(rl_all, key=lambda p: (p["dt"], p["cost"]))["error"]
        ok = [p for p in rl_all if abs(p["error"] - conv) <= (slack - 1.0) * conv]
        r = min(ok, key=lambda p: p["cost"])
        rows.append({"nodes": n, "el_dt": e["dt"], "el_cost": e["cost"], "el_error": e["error"],
                     "rl": r, "speedup": e["cost"] / r["cost"]})
    return rows


def accuracy_md(acc: dict) -> list[str]:
    out = []
    for name, res in acc.get("scenes", {}).items():
        if name == "rl":
            out += [f"### RL setting ({res['envs']} envs x {res['control_steps']} control steps, 3 tasks x 2 action kinds)",
                    "", "| setting | CPU ms / control step (8 envs) | x paper | mean tip error [mm] | max [mm] | "
                    "vs BE ref [mm] | mean Newton it | failed env-steps |", "|---|---|---|---|---|---|---|---|"]
            base = next((s for s in res["settings"] if s["name"].startswith("paper")), None)
            for s in res["settings"]:
                rel = s["ms_per_control_step"] / base["ms_per_control_step"] if base else float("nan")
                out.append(f"| {s['name']} | {s['ms_per_control_step']:.2f} | {rel:.2f} | {1e3 * s['err_mean_m']:.1f} | "
                           f"{1e3 * s['err_max_m']:.0f} | {1e3 * s.get('err_mean_vs_be_reference_m', float('nan')):.1f} | "
                           f"{s['iters_mean']:.2f} | {s['failed']} |")
            out.append("")
            continue
        pts = res.get("points", [])
        out += [f"### {name}", "", f"error: {res.get('error_definition', '')}", ""]
        fr = pareto_front([p for p in pts if p["sim"] == "rodlab"])
        fe = pareto_front([p for p in pts if p["sim"] == "PyElastica"])
        out.append("Pareto fronts (CPU s per simulated s, error):")
        out.append("")
        out.append("| sim | cost | error | N | dt | solver |")
        out.append("|---|---|---|---|---|---|")
        for p in fr:
            out.append(f"| rodlab | {_f(p['cost'])} | {_f(p['error'])} | {p['nodes']} | {p['dt']:.0e} | {p.get('solver')} |")
        for p in fe:
            out.append(f"| PyElastica | {_f(p['cost'])} | {_f(p['error'])} | {p['nodes']} | {p['dt']:.2e} | |")
        out.append("")
        rows = same_resolution(pts)
        if rows:
            out += ["Same node count, rodlab within 5 % of its time-converged error for that N (cheapest such run):", "",
                    "| N | PyElastica dt | PyElastica cost | PyElastica error | rodlab point | rodlab cost | rodlab error | speed-up |",
                    "|---|---|---|---|---|---|---|---|"]
            for r in rows:
                rl = r["rl"]
                desc = f"{rl['solver']} dt {rl['dt']:.0e}" if rl else "none"
                out.append(f"| {r['nodes']} | {r['el_dt']:.2e} | {_f(r['el_cost'])} | {_f(r['el_error'])} | {desc} | "
                           f"{_f(rl['cost']) if rl else '-'} | {_f(rl['error']) if rl else '-'} | {_f(r['speedup'], '.0f')} |")
            out.append("")
        a = res.get("analysis", {})
        if a.get("speedup_at_equal_error"):
            out.append("Speed-up at equal error (cheapest point of each front reaching the error): " + ", ".join(
                f"{_f(r['error'])}: {_f(r['speedup'], '.0f')}x" for r in a["speedup_at_equal_error"]))
            out.append("")
        for kind in ("time", "space"):
            for lab, o in res.get("orders", {}).get(kind, {}).items():
                out.append(f"- observed {kind} order, {lab}: {_f(o['order'], '.2f')}"
                           + (f" (3 smallest dt: {_f(o.get('order_small_dt'), '.2f')})" if "order_small_dt" in o else ""))
        if "model_gap" in res:
            out.append(f"- model gap (converged PyElastica vs converged rodlab): "
                       f"{_f(res['model_gap']['max_tip_distance_over_L'])} L")
        out.append("")
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.summary", description=__doc__.split("\n")[0])
    p.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = p.parse_args(argv)
    lines: list[str] = []
    f = args.out / "accuracy.json"
    if f.exists():
        lines += ["## accuracy", ""] + accuracy_md(json.loads(f.read_text()))
    f = args.out / "throughput.json"
    if f.exists():
        t = json.loads(f.read_text())
        lines += ["## throughput", "", "| task | rodlab CPU ms / control step | PyElastica CPU ms (scaled) | CPU ratio | wall ratio |",
                  "|---|---|---|---|---|"]
        for r in t.get("tasks", {}).get("rows", []):
            if "rodlab" in r and "pyelastica" in r:
                lines.append(f"| {r['task']} | {r['rodlab']['cpu_ms_per_control_step']:.0f} | "
                             f"{r['pyelastica']['cpu_ms_per_control_step_scaled']:.0f} | {r['ratio_cpu_time']:.0f} | "
                             f"{r['ratio_pyelastica_over_rodlab']:.0f} |")
        lines.append("")
    f = args.out / "stress.json"
    if f.exists():
        s = json.loads(f.read_text())
        lines += ["## stress", "", f"totals: {s.get('totals')}", ""]
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
