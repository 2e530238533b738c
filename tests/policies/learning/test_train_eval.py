"""End-to-end: train -> checkpoint -> resume -> save -> load -> evaluate, signal checkpointing, bad input.

Runs on the real follow_target task (tiny nets, few steps); a task that cannot be built fails the test.
"""
from __future__ import annotations

import json
import os
import signal
import threading
from pathlib import Path

import numpy as np
import pytest

from policies.learning.evaluation import evaluate
from policies.learning.sac import PolicyLoadError, load_policy, read_policy_meta
from policies.learning.training import Args, TrainError, train
from tests.helpers.cli import rodlab
from tests.helpers.training import train_args


def test_train_checkpoint_resume_save_load_evaluate(tmp_path):
    run = tmp_path / "run"
    train(train_args(run, 120))
    cfg = json.loads((run / "config.json").read_text())
    assert Args.from_json(cfg["args"]) == train_args(run, 120, task=cfg["args"]["task"])  # config round-trips
    assert cfg["git_commit"] and cfg["obs_shape"]
    state1 = json.loads((run / "checkpoint" / "state.json").read_text())
    assert state1["num_timesteps"] == 120
    with np.load(run / "checkpoint" / "replay.npz") as z:
        assert z["observations"].shape[:2] == (30, 4)  # 120 transitions / 4 envs, filled rows only
    assert state1["n_updates"] > 0

    train(train_args(run, 200), resume=True)  # continues the step count, buffer and update counter
    state2 = json.loads((run / "checkpoint" / "state.json").read_text())
    assert state2["num_timesteps"] == 200
    assert state2["n_updates"] == state1["n_updates"] + 2 * 20  # one iteration = 4 env steps + 2 updates
    assert state2["wall_s"] >= state1["wall_s"]
    with np.load(run / "checkpoint" / "replay.npz") as z:
        assert z["observations"].shape[:2] == (50, 4)  # restored 30 rows + 20 new ones (buffer grown)
    rows = (run / "metrics.csv").read_text().splitlines()
    assert rows[0].startswith("env_steps,wall_s")
    assert list((run / "tb").glob("**/events.out.tfevents*"))

    meta = read_policy_meta(run / "policy.zip")
    assert meta["task"] == cfg["args"]["task"]
    pol, _ = load_policy(run / "policy.zip")
    assert (run / "policy.zip").stat().st_size < (run / "checkpoint" / "model.zip").stat().st_size
    res = evaluate(run / "policy.zip", episodes=2, seed=0, num_envs=2)  # task taken from the file
    for key in ("avg_discounted_return_mean", "avg_discounted_return_std", "episodes", "task"):
        assert key in res
    assert res["episodes"] == 2 and np.isfinite(res["avg_discounted_return_mean"])
    # the loaded policy acts like the trained one
    obs = np.zeros((1, *pol.observation_space.shape), np.float32)
    a1, _ = pol.predict(obs, deterministic=True)
    assert a1.shape == (1, *pol.action_space.shape)


def test_sigint_checkpoints_and_stops(tmp_path):
    run = tmp_path / "run"
    timer = threading.Timer(3.0, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        train(train_args(run, 10_000_000, learning_starts=10**9))  # never finishes on its own
    finally:
        timer.cancel()
    state = json.loads((run / "checkpoint" / "state.json").read_text())
    assert 0 < state["num_timesteps"] < 10_000_000
    side = json.loads((run / "policy.json").read_text())
    assert side["training"]["stopped_early"] is True
    assert (run / "policy.zip").is_file()


def test_resume_errors_are_clear(tmp_path):
    with pytest.raises(TrainError, match="config.json"):
        train(train_args(tmp_path / "nothing", 100), resume=True)
    with pytest.raises(TrainError, match="unknown task"):
        train(train_args(tmp_path / "x", 100, task="no_such_task"))


def test_bad_policy_files(tmp_path):
    with pytest.raises(PolicyLoadError, match="not found"):
        load_policy(tmp_path / "missing.zip")
    bad = tmp_path / "corrupt.zip"
    bad.write_bytes(b"PK\x03\x04 this is not a zip")
    with pytest.raises(PolicyLoadError, match="not a readable policy zip"):
        load_policy(bad)
    import zipfile

    weird = tmp_path / "weird.zip"
    with zipfile.ZipFile(weird, "w") as zf:
        zf.writestr("meta.json", json.dumps({"format": "rodlab-sac-policy/1", "task": "x"}))
    with pytest.raises(PolicyLoadError, match="corrupt or incompatible"):
        load_policy(weird)


def test_policy_for_wrong_task_is_rejected(tmp_path):
    run = tmp_path / "run"
    train(train_args(run, 80, task="Pendulum-v1", learning_starts=10**9))
    with pytest.raises(PolicyLoadError, match="does not fit task"):
        evaluate(run / "policy.zip", "MountainCarContinuous-v0", episodes=1)


def test_cli_reports_bad_input_without_traceback(tmp_path, capsys):
    from policies.cli import eval_main

    assert eval_main([str(tmp_path / "missing.zip"), "--task", "Pendulum-v1"]) == 2
    err = capsys.readouterr().err
    assert "rodlab eval:" in err and "not found" in err and "Traceback" not in err
    bad = tmp_path / "bad.zip"
    bad.write_text("garbage")
    out = rodlab(capsys, "eval", str(bad), "--task", "Pendulum-v1")
    assert out.returncode == 2
    assert "Traceback" not in out.stderr and "not a readable policy zip" in out.stderr


def test_device_is_checked_before_any_work(tmp_path, capsys):
    """`--device` names a torch device this machine has; otherwise a one-line error and no run directory."""
    import torch

    from policies.cli import bench_train_main, train_main
    from policies.learning.training import check_device

    assert check_device("cpu") == "cpu"
    with pytest.raises(TrainError, match="not a torch device"):
        check_device("gpu0")
    with pytest.raises(TrainError, match="only cpu and cuda"):
        check_device("meta")
    run = tmp_path / "run"
    assert train_main(["Pendulum-v1", "--steps", "100", "--run-dir", str(run), "--device", "gpu0"]) == 2
    assert "--device" in capsys.readouterr().err and not run.exists()
    if not torch.cuda.is_available():
        with pytest.raises(TrainError, match="sees no CUDA GPU"):
            check_device("cuda")
        assert bench_train_main(["--task", "ik4d", "--envs", "2", "--device", "cuda:0"]) == 2
        assert "sees no CUDA GPU" in capsys.readouterr().err
    else:  # a GPU machine: an index past the last device is refused
        with pytest.raises(TrainError, match="CUDA device"):
            check_device(f"cuda:{torch.cuda.device_count()}")


def test_ship_copies_and_refuses_a_worse_policy(tmp_path, monkeypatch):
    """training_report ship: final or best policy into a pretrained folder with its source; --only-if-better keeps
    the shipped file when the candidate evaluates lower on the same episodes."""
    import policies.learning.evaluation as ev_mod
    from policies.learning.training_report import ShipError, main, ship

    run = tmp_path / "run"
    train(train_args(run, 120, task="Pendulum-v1", eval_every_steps=40, eval_episodes=2, eval_envs=2))
    assert (run / "policy_best.zip").is_file()
    dest = tmp_path / "pretrained"
    out = ship(run, "pend", episodes=2, seed=3, dest_dir=dest)
    assert (dest / "pend.zip").read_bytes() == (run / "policy.zip").read_bytes()
    js = json.loads((dest / "pend.json").read_text())
    assert js == out and js["source"] == {"run": "run", "file": "policy.zip", "from_scratch": True,
                                          "selected_at": None, "compared_with_shipped": None}
    json.loads((dest / "pend.json").read_text(), parse_constant=lambda c: pytest.fail(f"{c} in the JSON"))
    assert np.isfinite(js["evaluation"]["avg_discounted_return_mean"])

    real = ev_mod.evaluate
    scores = {"policy_best.zip": -5.0, "pend.zip": -1.0}

    def fake(policy, *a, **kw):
        res = real(policy, *a, **kw)
        res["avg_discounted_return_mean"] = scores.get(Path(str(policy)).name, res["avg_discounted_return_mean"])
        return res

    monkeypatch.setattr(ev_mod, "evaluate", fake)
    before = (dest / "pend.zip").read_bytes()
    with pytest.raises(ShipError, match="below the shipped"):
        ship(run, "pend", episodes=2, seed=3, dest_dir=dest, policy="best", only_if_better=True)
    assert (dest / "pend.zip").read_bytes() == before
    scores["policy_best.zip"] = -1.0  # as good as the shipped one: replaced
    out = ship(run, "pend", episodes=2, seed=3, dest_dir=dest, policy="best", only_if_better=True)
    assert (dest / "pend.zip").read_bytes() == (run / "policy_best.zip").read_bytes()
    assert out["source"]["file"] == "policy_best.zip"
    import csv

    rows = list(csv.DictReader(open(run / "eval.csv")))
    top = max(rows, key=lambda r: float(r["eval_avg_disc_return_mean"]))
    assert out["source"]["selected_at"] == {"env_steps": int(top["env_steps"]),
                                            "eval_avg_disc_return_mean": float(top["eval_avg_disc_return_mean"])}
    assert out["source"]["compared_with_shipped"] == {"candidate": -1.0, "shipped": -1.0, "episodes": 2, "seed": 3}
    with pytest.raises(ShipError, match="not found"):
        ship(tmp_path / "nothing", "pend", dest_dir=dest)
    assert main(["ship", str(tmp_path / "nothing"), "--name", "x"]) == 1


def test_training_logs_the_reward_terms(tmp_path, monkeypatch):
    """The reward terms reach the training log through the env's reward-terms observer: per finished episode
    ``rollout/ep_reward/<term>`` is logged, and the term means add up to the logged episode return."""
    import functools

    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    import policies

    monkeypatch.setattr(policies, "make_vec_env", functools.partial(policies.make_vec_env, timeout_steps=3))
    run = tmp_path / "run"
    train(train_args(run, 48, learning_starts=16, updates_per_iter=1, eval_episodes=0))  # 4-step episodes
    ea = EventAccumulator(str(run / "tb"))
    ea.Reload()
    terms = ["rollout/ep_reward/bonus", "rollout/ep_reward/distance", "rollout/ep_reward/failure"]
    assert set(terms) <= set(ea.Tags()["scalars"])
    ret = {e.step: e.value for e in ea.Scalars("rollout/ep_return_mean")}
    parts = [{e.step: e.value for e in ea.Scalars(t)} for t in terms]
    assert len(ret) >= 2 and all(set(p) == set(ret) for p in parts)
    for step, value in ret.items():
        assert sum(p[step] for p in parts) == pytest.approx(value, rel=1e-5, abs=1e-5), step
    assert any(p < 0 for p in parts[1].values())  # the distance term is a real (negative) reward
