"""`rodlab report` on a fake sweep directory with known curves (time to plateau known in closed form)."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from policies.learning.report import ReportError, main, report
from policies.learning.train_monitor import EVAL_COLUMNS, METRICS_COLUMNS
from policies.learning.training_report import PAPER_TABLE_II


def _fake_run(root: Path, task: str, seed: int, *, rate: float, scale: float, envs: int = 500,
              minutes: int = 60) -> Path:
    """Return R(t) = scale * t / 3600 [1/h] linear in wall-clock, env steps = rate * t."""
    run = root / f"{task}__s{seed}"
    run.mkdir(parents=True)
    (run / "config.json").write_text(json.dumps({"args": {"task": task, "seed": seed, "num_envs": envs}}))
    with open(run / "metrics.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(METRICS_COLUMNS)
        for k in range(1, minutes + 1):
            t = 60.0 * k
            ret = scale * t / 3600.0
            # the episode return is logged only in some windows (NaN in the others), as in real runs
            w.writerow([int(rate * t), t, 500 if k % 2 == 0 else 0, 6 * ret, ret if k % 2 == 0 else "nan", 501,
                        15.0, 100.0 + seed, 120.0 + seed, rate, 0.1, 4 * k])
    with open(run / "eval.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(EVAL_COLUMNS)
        for k in range(1, minutes // 3 + 1):
            t = 180.0 * k
            row = {c: 0.0 for c in EVAL_COLUMNS}
            row.update(env_steps=int(rate * t), wall_s=t, eval_avg_disc_return_mean=0.5 * scale * t / 3600.0)
            w.writerow([row[c] for c in EVAL_COLUMNS])
    return run


def test_report_on_fake_sweep(tmp_path):
    root = tmp_path / "sweep"
    mean, std = PAPER_TABLE_II["follow_target"]
    level = mean - std
    # three seeds with slopes 150, 200, 250 per hour: the seed mean is 200 t[h]; it crosses `level` at level/200 h
    for seed, scale in enumerate((150.0, 200.0, 250.0)):
        _fake_run(root, "follow_target", seed, rate=1000.0, scale=scale)
    _fake_run(root, "ik4d", 0, rate=800.0, scale=10.0)  # never reaches the paper's plateau
    res = report(root)
    groups = {g["group"]: g for g in res["groups"]}
    ft = groups["follow_target"]
    assert ft["seeds"] == [0, 1, 2]
    t_reach = level / 200.0
    # the grid has 400 points over the hour: first grid point at or after the crossing
    assert t_reach <= ft["train_hours_to_plateau"] <= t_reach + 1.0 / 399 + 1e-9
    assert ft["train_env_steps_to_plateau"] == pytest.approx(1000.0 * 3600.0 * ft["train_hours_to_plateau"],
                                                             rel=0.02)
    # the evaluation curve rises at half the rate: twice the time
    assert 2 * t_reach <= ft["eval_hours_to_plateau"] <= 2 * t_reach + 1.0 / 399 + 1e-9
    assert ft["train_final_mean"] == pytest.approx(200.0 * 1.0, rel=1e-3)  # at 1 h
    assert ft["train_final_std"] == pytest.approx(np.std([150.0, 200.0, 250.0]), rel=1e-3)
    assert ft["iter_ms"] == pytest.approx(121.0) and ft["update_ms"] == pytest.approx(101.0)
    assert ft["paper_return"] == mean and ft["paper_wallclock_h"] == 0.33 and ft["paper_iter_ms"] == 122.0
    ik = groups["ik4d"]
    assert ik["train_hours_to_plateau"] is None and ik["eval_hours_to_plateau"] is None
    md = Path(res["markdown"]).read_text()
    assert "| follow_target | 3 | 500 |" in md and "not reached" in md
    png = Path(res["png"])
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert json.loads(Path(res["json"]).read_text())["groups"][0]["group"] == "follow_target"


def test_report_projects_time_to_plateau_at_a_given_iteration_time(tmp_path):
    root = tmp_path / "sweep"
    for seed, scale in enumerate((150.0, 200.0, 250.0)):
        _fake_run(root, "follow_target", seed, rate=1000.0, scale=scale)
    res = report(root, iteration_ms={"follow_target": 160.0})
    ft = res["groups"][0]
    steps = ft["train_env_steps_to_plateau"]
    # eval.csv's eval_s_total is 0 in the fake runs: no evaluation share
    assert ft["train_projected_hours_to_plateau"] == pytest.approx(steps / 500 * 0.160 / 3600, rel=1e-5)  # rounded to 1e-6 h
    assert "| follow_target | 160 |" in res["table"]
    assert main([str(root), "--iteration-ms", "follow_target=fast"]) == 2
    # a group of another setting of the same task takes its own iteration time when one is given
    for seed in (0, 1):
        (root / f"follow_target__s{seed}").rename(root / f"follow_target__fast__s{seed}")
    _fake_run(root, "follow_target", 0, rate=1000.0, scale=200.0)
    res = report(root, iteration_ms={"follow_target": 160.0, "follow_target__fast": 80.0})
    groups = {g["group"]: g for g in res["groups"]}
    assert groups["follow_target__fast"]["projected_iter_ms"] == 80.0
    assert groups["follow_target"]["projected_iter_ms"] == 160.0


def test_report_on_seeds_that_ran_at_different_speeds(tmp_path):
    """Seed 1 steps twice as fast and stops after 30 min: the final return is read at the env steps both seeds
    reached, and on the wall-clock axis the finished seed is held at its last value, so the seed mean still
    crosses the plateau after that seed ended."""
    root = tmp_path / "sweep"
    mean, std = PAPER_TABLE_II["follow_target"]
    level = mean - std
    _fake_run(root, "follow_target", 0, rate=1000.0, scale=240.0)               # 3.6 M steps in 1 h, R = 240
    _fake_run(root, "follow_target", 1, rate=2000.0, scale=60.0, minutes=30)    # 3.6 M steps in 0.5 h, R = 30
    res = report(root)
    ft = res["groups"][0]
    assert ft["train_final_env_steps"] == pytest.approx(3.6e6)
    assert "(at 3.60 M)" in res["table"]  # training and evaluation curves end at the same env step here
    assert ft["train_final_mean"] == pytest.approx((240.0 + 30.0) / 2, rel=1e-3)
    assert ft["train_final_std"] == pytest.approx((240.0 - 30.0) / 2, rel=1e-3)
    # mean over wall-clock: 150 t before 0.5 h (below the level), (240 t + 30) / 2 after
    t_reach = (2 * level - 30.0) / 240.0
    assert 0.5 < t_reach < 1.0
    assert t_reach <= ft["train_hours_to_plateau"] <= t_reach + 1.0 / 399 + 1e-9
    assert ft["train_env_steps_to_plateau"] is not None


def test_report_errors(tmp_path, capsys):
    with pytest.raises(ReportError, match="no run directories"):
        report(tmp_path)
    assert main([str(tmp_path / "missing")]) == 2
    assert "is not a directory" in capsys.readouterr().err


def test_report_over_several_sweep_directories(tmp_path, capsys):
    """One figure and table over the runs of several sweeps (one sweep per task, as `rodlab sweep` writes them)."""
    for seed, scale in enumerate((150.0, 250.0)):
        _fake_run(tmp_path / "ft", "follow_target", seed, rate=1000.0, scale=scale)
    _fake_run(tmp_path / "ik", "ik4d", 0, rate=800.0, scale=10.0)
    out = tmp_path / "all"
    res = report([tmp_path / "ft", tmp_path / "ik"], out)
    assert [g["group"] for g in res["groups"]] == ["follow_target", "ik4d"]
    assert res["groups"][0]["seeds"] == [0, 1] and (out / "fig2.png").is_file()
    with pytest.raises(ReportError, match="need --out"):
        report([tmp_path / "ft", tmp_path / "ik"])
    with pytest.raises(ReportError, match="no run directories"):
        report([tmp_path / "ft", tmp_path], out)
    assert main([str(tmp_path / "ft"), str(tmp_path / "ik"), "--out", str(out)]) == 0
    assert "| ik4d | 1 |" in capsys.readouterr().out
