"""Training curves (PNG) and shipping of trained policies into ``policies/pretrained/``.

    python -m policies.learning.training_report plot RUN_DIR [RUN_DIR ...] --out docs/training_<task>.png
    python -m policies.learning.training_report ship RUN_DIR --name follow_target [--episodes 50] [--seed 100]

``plot`` reads each run's ``metrics.csv`` (written by policies/learning/training.py) and draws the training
average discounted return (alf metric, stochastic policy) against env steps and against wall-clock.
``ship`` copies ``RUN_DIR/policy.zip`` (``--policy best``: ``RUN_DIR/policy_best.zip``, the policy of the run's
best evaluation during training) to ``policies/pretrained/<name>.zip`` and writes ``<name>.json`` beside it: task,
training config + summary, where the policy came from, evaluation of the policy and of a random policy on the same
seeds, and the paper's reference figure (Table II, DisMech -> DisMech). ``--only-if-better`` first evaluates the
candidate and the policy already shipped under that name on the same episodes and replaces it only when the
candidate's average discounted return is at least as high (the rule for replacing a shipped policy, docs/training.md).
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import shutil
import sys
from pathlib import Path

from sim.support.assets import package_data_dir
from sim.support.atomicio import write_bytes, write_via_path

PAPER_TABLE_II = {  # DisMech -> DisMech average discounted return, mean ± std over seeds
    "follow_target": (96.26, 9.37), "ik4d": (186.24, 63.18), "tight_obstacles_2d": (40.91, 2.98),
    "random_obstacles_3d": (27.17, 19.03),
}
PRETRAINED = package_data_dir("policies", "pretrained")  # shipped policies: package data of policies


def read_metrics(run_dir: str | Path) -> dict[str, list[float]]:
    """Columns of RUN_DIR/metrics.csv as float lists (empty dict if absent)."""
    path = Path(run_dir) / "metrics.csv"
    if not path.is_file():
        return {}
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) for r in rows] for k in (rows[0].keys() if rows else [])}


def plot_training_curves(run_dirs: list[str | Path], out_png: str | Path, *, title: str | None = None) -> Path:
    """2x2 panels: episode avg discounted return (top) and windowed mean per-step reward (bottom, every log
    interval, so also between the few episode ends of long episodes) against env steps and wall-clock [h]."""
    import math

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex="col")
    for rd in run_dirs:
        m = read_metrics(rd)
        if not m:
            continue
        cfg = {}
        if (Path(rd) / "config.json").is_file():
            cfg = json.loads((Path(rd) / "config.json").read_text()).get("args", {})
        label = f"{Path(rd).name} ({cfg.get('num_envs', '?')} envs)"
        hours = [w / 3600 for w in m["wall_s"]]
        ep = [i for i, v in enumerate(m["avg_disc_return_mean"]) if not math.isnan(v)]
        for col, xs in ((0, m["env_steps"]), (1, hours)):
            axes[0, col].plot([xs[i] for i in ep], [m["avg_disc_return_mean"][i] for i in ep], "o-", label=label)
            if "step_reward_mean" in m:
                axes[1, col].plot(xs, m["step_reward_mean"], lw=1, label=label)
        task = cfg.get("task")
        if task in PAPER_TABLE_II:
            for ax in axes[0]:
                ax.axhline(PAPER_TABLE_II[task][0], color="gray", ls="--", lw=1)
            axes[0, 0].text(0, PAPER_TABLE_II[task][0], " paper plateau (Table II, DisMech)", color="gray",
                            va="top", fontsize=8)
    axes[1, 0].set_xlabel("env steps (summed over envs)")
    axes[1, 1].set_xlabel("wall-clock [h] (2-core CPU shared with other jobs)")
    axes[0, 0].set_ylabel("avg discounted return\n(training episodes, stochastic)")
    axes[1, 0].set_ylabel("mean reward per step\n(training, per log interval)")
    for ax in axes.flat:
        ax.grid(alpha=0.3)
    axes[0, 1].legend(fontsize=8, loc="lower right")
    fig.suptitle(title or "SAC training")
    fig.tight_layout()

    out = write_via_path(out_png, lambda tmp: fig.savefig(tmp, format="png", dpi=100))
    plt.close(fig)
    return out


class ShipError(Exception):
    """The policy cannot be shipped (missing file, or not better than the shipped one with only_if_better)."""


POLICY_FILES = {"final": "policy.zip", "best": "policy_best.zip"}


def ship(run_dir: str | Path, name: str, *, episodes: int = 50, seed: int = 100, num_envs: int | None = None,
         policy: str = "final", only_if_better: bool = False, dest_dir: str | Path | None = None) -> dict:
    """Copy the run's policy into ``dest_dir`` (policies/pretrained/) as <name>.zip and write <name>.json.

    Returns the JSON written. With ``only_if_better`` and a policy already shipped as <name>.zip, both are first
    evaluated on the same ``episodes`` (seed ``seed``); a candidate with a lower average discounted return raises
    ``ShipError`` and nothing is written.
    """

    from policies.learning.evaluation import evaluate
    from policies.learning.train_monitor import best_logged_eval

    run_dir = Path(run_dir)
    if policy not in POLICY_FILES:
        raise ShipError(f"policy must be one of {sorted(POLICY_FILES)}, got {policy!r}")
    src = run_dir / POLICY_FILES[policy]
    for f in (src, run_dir / "config.json"):
        if not f.is_file():
            raise ShipError(f"{f} not found")
    dest = Path(dest_dir) if dest_dir is not None else PRETRAINED
    dest.mkdir(parents=True, exist_ok=True)
    dst = dest / f"{name}.zip"
    compared = ev = None
    if only_if_better and dst.is_file():
        cand = evaluate(src, episodes=episodes, seed=seed, num_envs=num_envs)
        cur = evaluate(dst, episodes=episodes, seed=seed, num_envs=num_envs)
        compared = {"candidate": cand["avg_discounted_return_mean"], "shipped": cur["avg_discounted_return_mean"],
                    "episodes": episodes, "seed": seed}
        if cand["avg_discounted_return_mean"] < cur["avg_discounted_return_mean"]:
            raise ShipError(f"{src} evaluates {cand['avg_discounted_return_mean']:.2f} on {episodes} episodes (seed "
                            f"{seed}), below the shipped {dst.name} ({cur['avg_discounted_return_mean']:.2f}): not "
                            "replaced")
        ev = {**cand, "policy": str(dst)}  # the file shipped is the candidate: its evaluation is not run again
    tmp = dst.with_suffix(".zip.tmp")
    shutil.copyfile(src, tmp)
    tmp.replace(dst)
    side_path = run_dir / "policy.json"
    side = json.loads(side_path.read_text()) if side_path.is_file() else {}
    cfg = json.loads((run_dir / "config.json").read_text())
    if ev is None:
        ev = evaluate(dst, episodes=episodes, seed=seed, num_envs=num_envs)
    rnd = evaluate("random", ev["task"], episodes=episodes, seed=seed, num_envs=num_envs)
    out = {
        "task": ev["task"], "policy_file": dst.name, "git_commit": cfg.get("git_commit"),
        "source": {"run": run_dir.name, "file": src.name, "from_scratch": not cfg["args"].get("init_from"),
                   "selected_at": best_logged_eval(run_dir / "eval.csv") if policy == "best" else None,
                   "compared_with_shipped": compared},
        "config": cfg["args"], "training": side.get("training"), "target_entropy": cfg.get("target_entropy"),
        "evaluation": ev, "random_policy_evaluation": rnd,
        "paper_table_ii_dismech": PAPER_TABLE_II.get(ev["task"]),
        "eval_command": f"rodlab eval policies/pretrained/{name}.zip --episodes {episodes} --seed {seed} --json",
    }
    out = _finite(out)
    write_bytes(dest / f"{name}.json", json.dumps(out, indent=1, allow_nan=False).encode())
    return out


def _finite(obj):
    """``obj`` with every non-finite float replaced by None (the JSON written is strict)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m policies.learning.training_report")
    sub = p.add_subparsers(dest="cmd", required=True)
    pp = sub.add_parser("plot")
    pp.add_argument("runs", nargs="+")
    pp.add_argument("--out", required=True)
    pp.add_argument("--title", default=None)
    ps = sub.add_parser("ship")
    ps.add_argument("run")
    ps.add_argument("--name", required=True)
    ps.add_argument("--episodes", type=int, default=50)
    ps.add_argument("--seed", type=int, default=100)
    ps.add_argument("--envs", type=int, default=None)
    ps.add_argument("--policy", choices=sorted(POLICY_FILES), default="final",
                    help="final: RUN/policy.zip; best: RUN/policy_best.zip (best evaluation during training)")
    ps.add_argument("--only-if-better", action="store_true",
                    help="replace a shipped policy of that name only if this one evaluates at least as well on the "
                         "same episodes")
    a = p.parse_args(argv)
    if a.cmd == "plot":
        print(plot_training_curves(a.runs, a.out, title=a.title))
    else:
        import torch

        torch.set_num_threads(1)
        try:
            res = ship(a.run, a.name, episodes=a.episodes, seed=a.seed, num_envs=a.envs, policy=a.policy,
                       only_if_better=a.only_if_better)
        except ShipError as exc:
            print(f"ship: {exc}", file=sys.stderr)
            return 1
        ev, rnd = res["evaluation"], res["random_policy_evaluation"]
        print(f"{a.name}: avg disc return {ev['avg_discounted_return_mean']:.2f} ± {ev['avg_discounted_return_std']:.2f} "
              f"(random {rnd['avg_discounted_return_mean']:.2f}); paper {res['paper_table_ii_dismech']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
