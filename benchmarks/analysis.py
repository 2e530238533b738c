"""Pareto fronts, speed-up at equal error, observed convergence orders, and the plots of accuracy.py.

A *point* is a dict with at least ``cost`` (wall seconds per simulated second) and ``error``
(dimensionless); non-finite or unstable points are ignored by the analysis.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def _ok(p: dict) -> bool:
    return (p.get("stable", True) and p.get("error") is not None and p.get("cost") is not None
            and math.isfinite(p["error"]) and math.isfinite(p["cost"]) and p["error"] > 0)


def pareto_front(points: Sequence[dict], *, rel: float = 5e-3) -> list[dict]:
    """Points not dominated in (cost, error), sorted by increasing cost (decreasing error); a point must
    improve the error by more than ``rel`` (relative) to enter the front."""
    pts = sorted((p for p in points if _ok(p)), key=lambda p: (p["cost"], p["error"]))
    front: list[dict] = []
    best = math.inf
    for p in pts:
        if p["error"] < best * (1.0 - rel):
            front.append(p)
            best = p["error"]
    return front


def cost_at_error(front: Sequence[dict], err: float) -> float:
    """Cheapest cost on a front that reaches an error <= ``err`` (inf if none)."""
    costs = [p["cost"] for p in front if p["error"] <= err]
    return min(costs) if costs else math.inf


def speedup_table(front_a: Sequence[dict], front_b: Sequence[dict], *, levels: int = 6) -> list[dict]:
    """cost_b / cost_a at error levels reachable by both fronts (log-spaced between the larger of the
    two minimum errors and the smaller of the two maximum errors)."""
    if not front_a or not front_b:
        return []
    lo = max(min(p["error"] for p in front_a), min(p["error"] for p in front_b))
    hi = min(max(p["error"] for p in front_a), max(p["error"] for p in front_b))
    if not hi >= lo:
        return []
    out = []
    for e in np.geomspace(lo, hi, levels) if hi > lo else [lo]:
        ca, cb = cost_at_error(front_a, e), cost_at_error(front_b, e)
        out.append({"error": float(e), "cost_rodlab": ca, "cost_peer": cb,
                    "speedup": cb / ca if ca > 0 and math.isfinite(ca) and math.isfinite(cb) else None})
    return out


def observed_order(h: Sequence[float], err: Sequence[float]) -> float | None:
    """Least-squares slope of log(err) against log(h) (None with fewer than 2 usable points)."""
    h_ = np.asarray(h, float)
    e_ = np.asarray(err, float)
    m = np.isfinite(h_) & np.isfinite(e_) & (h_ > 0) & (e_ > 0)
    if m.sum() < 2:
        return None
    return float(np.polyfit(np.log(h_[m]), np.log(e_[m]), 1)[0])


def plot_pareto(plt, title: str, series: dict[str, list[dict]], *, note: str = ""):
    """Error against CPU time per simulated second, one marker series per label, fronts as lines."""
    fig, ax = plt.subplots(figsize=(7.2, 5.0))
    colors = {"rodlab": "tab:blue", "PyElastica": "tab:red"}
    markers = ["o", "s", "^", "v", "D", "P", "X", "*"]
    for i, (label, pts) in enumerate(series.items()):
        good = [p for p in pts if _ok(p)]
        if not good:
            continue
        base = label.split(" ")[0]
        c = colors.get(base, None)
        ax.scatter([p["cost"] for p in good], [p["error"] for p in good], s=18, alpha=0.55,
                   marker=markers[i % len(markers)], color=c, label=label)
    for base, c in colors.items():
        allp = [p for lab, pts in series.items() if lab.split(" ")[0] == base for p in pts]
        fr = pareto_front(allp)
        if fr:
            ax.step([p["cost"] for p in fr], [p["error"] for p in fr], where="post", color=c, lw=1.6,
                    label=f"{base} Pareto front")
            for p in fr:
                ax.annotate(f"N{p['nodes']} dt{p['dt']:.0e}" + (f" {p['solver']}" if p.get("solver") else ""),
                            (p["cost"], p["error"]), fontsize=5.5, color=c, xytext=(3, 2),
                            textcoords="offset points")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("CPU time per simulated second [s/s] (1 env, 1 thread)")
    ax.set_ylabel("error")
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    if note:
        fig.text(0.01, -0.02, note, fontsize=7, ha="left", va="top", wrap=True)
    return fig


def plot_convergence(plt, title: str, curves: dict[str, tuple[list[float], list[float]]], *, xlabel: str,
                     slopes: Sequence[int] = (1, 2), note: str = "", ylabel: str = "error"):
    """log-log error against step (dt or element length) with reference slopes."""
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    for label, (h, e) in curves.items():
        h_, e_ = np.asarray(h, float), np.asarray(e, float)
        m = np.isfinite(e_) & (e_ > 0)
        if m.any():
            ax.loglog(h_[m], e_[m], "o-", label=label)
    allh = [x for h, _ in curves.values() for x in h]
    alle = [x for _, e in curves.values() for x in e if x and x > 0 and math.isfinite(x)]
    if allh and alle:
        h0, h1 = min(allh), max(allh)
        e_mid = float(np.exp(np.mean(np.log(alle))))
        hm = math.sqrt(h0 * h1)
        for s in slopes:
            hh = np.array([h0, h1])
            ax.loglog(hh, e_mid * (hh / hm) ** s, "k--" if s == 1 else "k:", lw=0.8, label=f"slope {s}")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    if note:
        fig.text(0.01, -0.02, note, fontsize=7, ha="left", va="top", wrap=True)
    return fig
