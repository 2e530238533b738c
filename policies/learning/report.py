"""``rodlab report SWEEP_DIR [SWEEP_DIR ...]``: the paper's Fig. 2 for a sweep (or several), and a time-to-plateau table.

Reads every run directory under SWEEP_DIR (``rodlab sweep`` trials or ``rodlab train`` runs: config.json,
metrics.csv, eval.csv) and groups the seeds of one task and setting (the directory name without its
``__s<seed>`` suffix). Per group:

* curves: the training average discounted return (stochastic policy, episodes finished in each log window;
  metrics.csv) and the deterministic evaluation on fixed seeds (eval.csv), each against env steps and against
  wall-clock; every seed's curve is interpolated linearly on a common axis that ends where the shortest seed
  ends, then mean ± std over seeds;
* time to plateau: the first point at which the seed-mean curve reaches the paper's Table II value minus its
  std (DisMech -> DisMech), for the training and the evaluation curve, in hours and in env steps;
* timing: median iteration time, env-step time and update time over the logged windows with updates;
* the paper's figures beside them: Table II return, wall-clock to 5 M env steps (docs/tasks.md §8.5) and
  the Follow Target iteration time of 122 ms (RTX 3090);
* with ``--iteration-ms TASK=MS``: the time to plateau the runs would take at MS per iteration (env steps to
  plateau / envs × MS, plus the runs' evaluation share), for runs whose measured wall-clock is not the figure to
  quote (trials sharing the machine with other work, or run with fewer threads than the quoted setting); the MS
  comes from a measurement on a quiet machine (``rodlab bench train``), which the report names.

Writes ``REPORT_DIR/fig2.png`` (Agg), ``report.md`` and ``report.json`` (default REPORT_DIR: SWEEP_DIR/report), and
``compare.png`` when a task has several settings (each setting's seed-mean curves overlaid, e.g. the presets).
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import re
import sys
from pathlib import Path

import numpy as np
from sim.support.atomicio import write_bytes, write_via_path

from policies.learning.training_report import PAPER_TABLE_II

PAPER_WALLCLOCK_H = {"follow_target": 0.33, "ik4d": 0.37, "tight_obstacles_2d": 0.6, "random_obstacles_3d": 1.0}
PAPER_ITER_MS = {"follow_target": 122.0}
GRID_POINTS = 400


class ReportError(Exception):
    """Nothing to report (no run directories, unreadable files) with a readable message."""


def _rows(path: Path) -> list[dict]:
    if not path.is_file():
        return []
    with open(path, newline="") as f:
        return [r for r in csv.DictReader(f) if r.get("env_steps")]


def _col(rows: list[dict], key: str) -> np.ndarray:
    out = []
    for r in rows:
        try:
            out.append(float(r.get(key, "nan")))
        except (TypeError, ValueError):
            out.append(math.nan)
    return np.asarray(out, dtype=np.float64)


def find_runs(root: Path) -> list[Path]:
    root = Path(root)
    if (root / "config.json").is_file():
        return [root]
    return sorted(p for p in root.iterdir() if p.is_dir() and (p / "config.json").is_file())


def load_run(run: Path) -> dict:
    try:
        cfg = json.loads((run / "config.json").read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ReportError(f"cannot read {run / 'config.json'}: {exc}") from None
    args = cfg.get("args", {})
    m, e = _rows(run / "metrics.csv"), _rows(run / "eval.csv")
    steps, wall, ret = _col(m, "env_steps"), _col(m, "wall_s"), _col(m, "avg_disc_return_mean")
    ok = np.isfinite(ret)
    upd = _col(m, "update_ms")
    with_upd = upd > 0
    timing = {}
    for key in ("iter_ms", "env_step_ms", "update_ms"):
        v = _col(m, key)[with_upd] if with_upd.any() else _col(m, key)
        v = v[np.isfinite(v)]
        timing[key] = float(np.median(v)) if v.size else math.nan
    es, ew, er = _col(e, "env_steps"), _col(e, "wall_s"), _col(e, "eval_avg_disc_return_mean")
    eok = np.isfinite(er)
    return {"dir": str(run), "task": args.get("task"), "seed": args.get("seed"),
            "group": re.sub(r"__s\d+$", "", run.name),
            "train": {"steps": steps[ok], "hours": wall[ok] / 3600.0, "ret": ret[ok]},
            "eval": {"steps": es[eok], "hours": ew[eok] / 3600.0, "ret": er[eok]},
            "final_steps": float(steps.max()) if steps.size else 0.0,
            "final_hours": float(wall.max() / 3600.0) if wall.size else 0.0, "timing": timing,
            "eval_share": (float(_col(e, "eval_s_total")[-1]) / float(max(wall.max(), ew.max())))
            if e and wall.size and math.isfinite(float(_col(e, "eval_s_total")[-1])) else math.nan,
            "num_envs": args.get("num_envs")}


def seed_mean(curves: list[tuple[np.ndarray, np.ndarray]], n: int = GRID_POINTS, *, hold_last: bool = False):
    """Common axis -> (x, mean, std, seeds per point); NaN before a curve starts.

    The axis ends where the shortest curve ends, or with ``hold_last`` where the longest does, each shorter curve
    then held at its last value (a finished run's policy no longer changes: used for the wall-clock axis, on which
    seeds that ran at different speeds end at different times).
    """
    curves = [(x, y) for x, y in curves if x.size]
    if not curves:
        return None
    end = (max if hold_last else min)(float(x.max()) for x, _ in curves)
    start = min(float(x.min()) for x, _ in curves)
    if end <= start:
        xs = np.array([end])
    else:
        xs = np.linspace(start, end, n)
    ys = np.full((len(curves), xs.size), np.nan)
    for i, (x, y) in enumerate(curves):
        order = np.argsort(x, kind="stable")
        xo, yo = x[order], y[order]
        if hold_last:
            ok = np.isfinite(yo)
            right = float(yo[ok][-1]) if ok.any() else np.nan
        else:
            right = np.nan
        ys[i] = np.interp(xs, xo, yo, left=np.nan, right=right)
    count = np.isfinite(ys).sum(axis=0)
    with np.errstate(invalid="ignore"):
        mean = np.where(count > 0, np.nanmean(np.where(np.isfinite(ys), ys, np.nan), axis=0), np.nan) \
            if count.any() else np.full(xs.size, np.nan)
        std = np.where(count > 0, np.nanstd(ys, axis=0), np.nan)
    # a point counts only once every seed has started (the mean over all seeds)
    full = count == len(curves)
    mean = np.where(full, mean, np.nan)
    std = np.where(full, std, np.nan)
    return xs, mean, std, len(curves)


def first_reach(xs: np.ndarray, mean: np.ndarray, level: float) -> float:
    hit = np.flatnonzero(np.isfinite(mean) & (mean >= level))
    return float(xs[hit[0]]) if hit.size else math.nan


def projected_hours(env_steps: float | None, num_envs: int, iter_ms: float, eval_share: float | None) -> float | None:
    """Hours to reach ``env_steps`` at ``iter_ms`` per iteration of ``num_envs`` env steps, the evaluations during
    training adding their share of the wall-clock (``eval_share`` of the total: ×1/(1 − share))."""
    if env_steps is None or not iter_ms or iter_ms <= 0:
        return None
    hours = env_steps / float(num_envs) * iter_ms / 3.6e6
    share = eval_share or 0.0
    return _num(hours / (1.0 - share)) if share < 1.0 else None


def summarize(runs: list[dict], iteration_ms: dict[str, float] | None = None) -> list[dict]:
    groups: dict[str, list[dict]] = {}
    for r in runs:
        groups.setdefault(r["group"], []).append(r)
    out = []
    for name, rs in sorted(groups.items()):
        task = rs[0]["task"]
        paper = PAPER_TABLE_II.get(task)
        level = paper[0] - paper[1] if paper else math.nan
        row = {"group": name, "task": task, "seeds": sorted(r["seed"] for r in rs), "num_envs": rs[0]["num_envs"],
               "paper_return": paper[0] if paper else None, "paper_std": paper[1] if paper else None,
               "plateau_level": level if paper else None, "paper_wallclock_h": PAPER_WALLCLOCK_H.get(task),
               "paper_iter_ms": PAPER_ITER_MS.get(task), "curves": {}}
        for kind in ("train", "eval"):
            for axis in ("steps", "hours"):
                sm = seed_mean([(r[kind][axis], r[kind]["ret"]) for r in rs], hold_last=axis == "hours")
                if sm is None:
                    continue
                xs, mean, std, n = sm
                row["curves"][f"{kind}_{axis}"] = {"x": xs.tolist(), "mean": _nan_list(mean), "std": _nan_list(std)}
                reach = first_reach(xs, mean, level) if paper else math.nan
                row[f"{kind}_{'env_steps' if axis == 'steps' else 'hours'}_to_plateau"] = _num(reach)
                if axis == "steps":  # the final return: at the env steps every seed reached
                    ok = np.isfinite(mean)
                    row[f"{kind}_final_mean"] = _num(float(mean[ok][-1])) if ok.any() else None
                    sfin = std[np.isfinite(std)]
                    row[f"{kind}_final_std"] = _num(float(sfin[-1])) if sfin.size else None
                    row[f"{kind}_final_env_steps"] = _num(float(xs[ok][-1])) if ok.any() else None
        for key in ("iter_ms", "env_step_ms", "update_ms"):
            v = [r["timing"][key] for r in rs if math.isfinite(r["timing"][key])]
            row[key] = _num(float(np.median(v))) if v else None
        share = [r["eval_share"] for r in rs if math.isfinite(r["eval_share"])]
        row["eval_share_of_wallclock"] = _num(float(np.mean(share))) if share else None
        row["env_steps_max"] = max(r["final_steps"] for r in rs)
        row["hours_max"] = max(r["final_hours"] for r in rs)
        ims = (iteration_ms or {}).get(name, (iteration_ms or {}).get(task))  # a setting's own, else its task's
        if ims:
            row["projected_iter_ms"] = float(ims)
            for kind in ("train", "eval"):
                row[f"{kind}_projected_hours_to_plateau"] = projected_hours(
                    row.get(f"{kind}_env_steps_to_plateau"), row["num_envs"], ims, row["eval_share_of_wallclock"])
        out.append(row)
    return out


def _num(v: float):
    return None if v is None or not math.isfinite(v) else round(float(v), 6)


def _nan_list(a: np.ndarray) -> list:
    return [None if not math.isfinite(v) else round(float(v), 5) for v in a]


def _fmt(v, spec: str = ".2f", none: str = "not reached") -> str:
    return none if v is None else format(v, spec)


def _at_steps(r: dict) -> str:
    """" (at 3.26 M)", or " (at 3.26 / 3.30 M)" when the training and evaluation curves end at different steps."""
    steps = [f"{v / 1e6:.2f}" for v in (r.get("train_final_env_steps"), r.get("eval_final_env_steps")) if v is not None]
    return f" (at {' / '.join(dict.fromkeys(steps))} M)" if steps else ""


def markdown(rows: list[dict]) -> str:
    lines = ["| task / setting | seeds | envs | time to plateau, training [h] | time to plateau, eval [h] | "
             "env steps to plateau, training | env steps to plateau, eval | final training / eval return "
             "(seed mean ± std; at env steps) | iteration [ms] | env step [ms] | updates [ms] | paper: plateau (Table II) | "
             "paper: wall-clock to 5 M steps [h] | paper: iteration [ms] |",
             "|" + "---|" * 14]
    for r in rows:
        paper = f"{r['paper_return']:.2f} ± {r['paper_std']:.2f}" if r["paper_return"] is not None else "—"
        lines.append(
            f"| {r['group']} | {len(r['seeds'])} | {r['num_envs']} | {_fmt(r.get('train_hours_to_plateau'), '.3f')} | "
            f"{_fmt(r.get('eval_hours_to_plateau'), '.3f')} | {_fmt(r.get('train_env_steps_to_plateau'), ',.0f')} | "
            f"{_fmt(r.get('eval_env_steps_to_plateau'), ',.0f')} | "
            f"{_fmt(r.get('train_final_mean'), '.2f', '—')} ± {_fmt(r.get('train_final_std'), '.2f', '—')} / "
            f"{_fmt(r.get('eval_final_mean'), '.2f', '—')} ± {_fmt(r.get('eval_final_std'), '.2f', '—')}"
            f"{_at_steps(r)} | "
            f"{_fmt(r['iter_ms'], '.1f', '—')} | {_fmt(r['env_step_ms'], '.1f', '—')} | {_fmt(r['update_ms'], '.1f', '—')} | "
            f"{paper} | {_fmt(r['paper_wallclock_h'], '.2f', '—')} | {_fmt(r['paper_iter_ms'], '.0f', '—')} |")
    proj = [r for r in rows if r.get("projected_iter_ms")]
    if proj:
        lines += ["", "| task / setting | iteration [ms] (given) | time to plateau at that rate, training [h] | "
                  "time to plateau at that rate, eval [h] | paper: wall-clock to 5 M steps [h] |", "|---|---|---|---|---|"]
        for r in proj:
            lines.append(f"| {r['group']} | {r['projected_iter_ms']:.0f} | "
                         f"{_fmt(r.get('train_projected_hours_to_plateau'), '.3f')} | "
                         f"{_fmt(r.get('eval_projected_hours_to_plateau'), '.3f')} | "
                         f"{_fmt(r['paper_wallclock_h'], '.2f', '—')} |")
    lines += ["", "Time to plateau: first point at which the seed-mean curve reaches the paper's Table II value "
              "minus its std (DisMech -> DisMech); 'not reached' within the runs. Training curve: stochastic policy, "
              "episodes finished in each log window; eval curve: deterministic policy on fixed seeds. Final return: "
              "at the last env step every seed reached. On the wall-clock axis a seed that finished earlier is held "
              "at its last value (seeds that ran at different speeds end at different times). Wall-clock "
              "includes the evaluations during training (their share: report.json eval_share_of_wallclock). Paper wall-clock: docs/tasks.md §8.5."
              + (" 'At that rate': env steps to plateau / envs x the given iteration time, divided by (1 - the runs' "
                 "evaluation share): the wall-clock of these learning curves at a measured quiet-machine "
                 "iteration time." if proj else "")]
    return "\n".join(lines) + "\n"


def plot(rows: list[dict], out_png: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(rows), 2, figsize=(12, 3.6 * len(rows)), squeeze=False)
    for i, r in enumerate(rows):
        for j, axis in enumerate(("steps", "hours")):
            ax = axes[i, j]
            for kind, style, label in (("train", "-", "training (stochastic)"), ("eval", "--", "evaluation (deterministic)")):
                c = r["curves"].get(f"{kind}_{axis}")
                if not c:
                    continue
                x = np.asarray(c["x"], float)
                m = np.asarray([np.nan if v is None else v for v in c["mean"]], float)
                s = np.asarray([np.nan if v is None else v for v in c["std"]], float)
                line, = ax.plot(x, m, style, label=f"{label}, mean of {len(r['seeds'])} seeds")
                ax.fill_between(x, m - s, m + s, color=line.get_color(), alpha=0.2)
            if r["paper_return"] is not None:
                ax.axhline(r["paper_return"], color="gray", ls=":", lw=1)
                ax.axhspan(r["paper_return"] - r["paper_std"], r["paper_return"] + r["paper_std"], color="gray",
                           alpha=0.1, label="paper plateau ± std (Table II)")
            if axis == "hours" and r["paper_wallclock_h"]:
                ax.axvline(r["paper_wallclock_h"], color="gray", ls="--", lw=1, label="paper wall-clock (5 M steps)")
            _label(ax, "env steps" if axis == "steps" else "wall-clock [h]", r["group"])
    return _save(fig, out_png)


def _label(ax, xlabel: str, title: str) -> None:
    ax.set_xlabel(xlabel)
    ax.set_ylabel("average discounted return")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")


def _save(fig, out_png: Path) -> Path:
    import matplotlib.pyplot as plt

    fig.tight_layout()
    write_via_path(out_png, lambda tmp: fig.savefig(tmp, format="png", dpi=90))
    plt.close(fig)
    return out_png


def plot_compare(rows: list[dict], out_png: Path) -> Path | None:
    """The settings of each task side by side (e.g. the presets of ``rodlab sweep --set preset=paper,fast``): per task
    with two or more groups one row, the seed-mean training (solid) and evaluation (dashed) curves of every group
    against env steps and wall-clock [min], the paper's plateau band (Table II) and wall-clock to 5 M steps, and a
    dot where each group's training curve reaches the plateau. None when no task has two groups."""
    tasks: dict[str, list[dict]] = {}
    for r in rows:
        tasks.setdefault(r["task"], []).append(r)
    tasks = {t: rs for t, rs in tasks.items() if len(rs) > 1}
    if not tasks:
        return None
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(tasks), 2, figsize=(12, 3.8 * len(tasks)), squeeze=False)
    for i, (task, rs) in enumerate(sorted(tasks.items())):
        for j, axis in enumerate(("steps", "hours")):
            ax = axes[i, j]
            scale = 60.0 if axis == "hours" else 1.0  # wall-clock in minutes
            for r in rs:
                color = None
                for kind, style in (("train", "-"), ("eval", "--")):
                    c = r["curves"].get(f"{kind}_{axis}")
                    if not c:
                        continue
                    x = np.asarray(c["x"], float) * scale
                    m = np.asarray([np.nan if v is None else v for v in c["mean"]], float)
                    label = f"{r['group']} ({len(r['seeds'])} seeds)" if kind == "train" else None
                    line, = ax.plot(x, m, style, color=color, label=label, lw=1.4)
                    color = line.get_color()
                reach = r.get("train_env_steps_to_plateau" if axis == "steps" else "train_hours_to_plateau")
                if reach is not None and r.get("plateau_level") is not None:
                    ax.plot([reach * scale], [r["plateau_level"]], "o", color=color, ms=5)
            top = rs[0]
            if top["paper_return"] is not None:
                ax.axhspan(top["paper_return"] - top["paper_std"], top["paper_return"] + top["paper_std"],
                           color="gray", alpha=0.12, label="paper plateau ± std (Table II)")
            if axis == "hours" and top["paper_wallclock_h"]:
                ax.axvline(top["paper_wallclock_h"] * scale, color="gray", ls="--", lw=1,
                           label=f"paper wall-clock to 5 M steps ({top['paper_wallclock_h'] * 60:.0f} min)")
            _label(ax, "env steps" if axis == "steps" else "wall-clock from the command's start [min]",
                   f"{task}: training (solid), evaluation (dashed); dot: plateau reached")
    return _save(fig, out_png)


def report(sweep_dir: str | Path | list, out_dir: str | Path | None = None,
           iteration_ms: dict[str, float] | None = None) -> dict:
    """Report of one sweep directory, or of several (one figure and table over all their runs; ``out_dir`` needed)."""

    dirs = [Path(d) for d in sweep_dir] if isinstance(sweep_dir, (list, tuple)) else [Path(sweep_dir)]
    if not dirs:
        raise ReportError("no sweep directory given")
    if len(dirs) > 1 and out_dir is None:
        raise ReportError("several sweep directories need --out (the report's folder)")
    runs = []
    for d in dirs:
        if not d.is_dir():
            raise ReportError(f"{d} is not a directory")
        found = find_runs(d)
        if not found:
            raise ReportError(f"no run directories (with config.json) in {d}")
        runs += [load_run(p) for p in found]
    sweep_dir = dirs[0]
    rows = summarize(runs, iteration_ms)
    out = Path(out_dir) if out_dir else sweep_dir / "report"
    out.mkdir(parents=True, exist_ok=True)
    png = plot(rows, out / "fig2.png")
    compare = plot_compare(rows, out / "compare.png")
    md = markdown(rows)
    write_bytes(out / "report.md", md.encode())
    write_bytes(out / "report.json", json.dumps({"groups": rows}, indent=1).encode())
    return {"png": str(png), "compare_png": str(compare) if compare else None, "markdown": str(out / "report.md"),
            "json": str(out / "report.json"), "table": md, "groups": rows}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="rodlab report", description="Learning curves (mean ± std over seeds, "
                                "against env steps and wall-clock) and time-to-plateau table of a sweep.")
    p.add_argument("sweep_dir", nargs="+", help="sweep directory (rodlab sweep --out) or one run directory; several "
                   "make one report over all their runs (with --out)")
    p.add_argument("--out", default=None, help="output directory (default SWEEP_DIR/report for one directory)")
    p.add_argument("--iteration-ms", action="append", default=[], metavar="TASK=MS",
                   help="also give the time to plateau at MS ms per iteration for TASK (a quiet-machine "
                        "measurement, e.g. rodlab bench train); TASK may also name one group (a setting, e.g. "
                        "follow_target__bf16), which then takes its own value; repeatable")
    a = p.parse_args(argv)
    try:
        ims = {}
        for item in a.iteration_ms:
            task, sep, val = item.partition("=")
            try:
                ms = float(val)
            except ValueError:
                ms = float("nan")
            if not sep or not task or not math.isfinite(ms) or ms <= 0:
                raise ReportError(f"--iteration-ms {item!r}: expected TASK=MS with MS a positive number")
            ims[task] = ms
        res = report(a.sweep_dir, a.out, ims)
    except ReportError as exc:
        print(f"rodlab report: {exc}", file=sys.stderr)
        return 2
    print(res["table"])
    print(f"figure {res['png']}" + (f", settings side by side {res['compare_png']}" if res["compare_png"] else "")
          + f"\ntable {res['markdown']} and {res['json']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
