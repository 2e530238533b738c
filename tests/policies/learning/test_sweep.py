"""`rodlab sweep` on a real local Ray: a 2-trial sweep end to end, and an interrupted sweep that continues.

Tiny budget: follow_target, 4 envs, small networks, a few dozen env steps per trial.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from policies.learning.checkpoint import read_state
from policies.learning.sweep import SweepError, is_done, make_trials, parse_seeds, parse_sets
from tests.helpers.paths import REPO

TINY = ["--set", "net_arch=32:32", "--set", "batch_size=32", "--set", "learning_starts=16",
        "--set", "updates_per_iter=1", "--set", "eval_minutes=0", "--set", "log_interval_s=0.5",
        "--set", "first_checkpoint_minutes=0.003", "--set", "checkpoint_minutes=0.003"]


def _sweep(out: Path, steps: int, *extra: str, **popen) -> subprocess.Popen:
    env = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1", RAY_USAGE_STATS_ENABLED="0")
    cmd = [sys.executable, "-m", "rodlab_cli", "sweep", "follow_target", "--seeds", "0,1", "--envs", "4",
           "--steps", str(steps), "--cpus-per-trial", "1", "--out", str(out), *TINY, *extra]
    return subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            **popen)


def _finish(proc: subprocess.Popen, timeout: float = 600) -> str:
    out, _ = proc.communicate(timeout=timeout)
    return out


def test_parsing_and_grid(tmp_path):
    sets = parse_sets(["learning_rate=1e-3,3e-4", "net_arch=64:64", "updates_per_iter=2,4", "eval_stochastic=true"])
    assert sets == {"learning_rate": [1e-3, 3e-4], "net_arch": [[64, 64]], "updates_per_iter": [2, 4],
                    "eval_stochastic": [True]}
    assert parse_seeds("0,2-4") == [0, 2, 3, 4]
    trials = make_trials(["follow_target", "ik4d"], [0, 1], sets, tmp_path, envs=8, steps=100,
                         time_limit_minutes=0.0, cpus_per_trial=2)
    assert len(trials) == 2 * 2 * 2 * 2
    names = {t.name for t in trials}
    assert "follow_target__learning_rate=0.001__updates_per_iter=2__s1" in names  # varying keys only
    t = trials[0]
    assert t.args["num_envs"] == 8 and t.args["total_steps"] == 100 and t.args["torch_threads"] == 2
    for bad, msg in ((["no_such=1"], "unknown training setting"), (["seed=1,2"], "set by the sweep"),
                     (["learning_rate=fast"], "cannot read"), (["batch_size"], "key=value")):
        with pytest.raises(SweepError, match=msg):
            parse_sets(bad)
    with pytest.raises(SweepError, match="unknown task"):
        make_trials(["nope"], [0], {}, tmp_path, envs=1, steps=1, time_limit_minutes=0, cpus_per_trial=1)
    # update settings no trial could run with are refused before any trial (or Ray) starts
    with pytest.raises(SweepError, match="--bf16-layout: expected one of"):
        make_trials(["ik4d"], [0], parse_sets(["bf16_layout=half"]), tmp_path, envs=1, steps=1, time_limit_minutes=0,
                    cpus_per_trial=1)
    assert not any(tmp_path.iterdir())


def test_finished_trial_continues_under_a_larger_budget(tmp_path):
    """A trial stopped by a 26-minute limit counts as finished for that limit, not for a larger one or for more
    --steps; one that reached its steps stays finished."""
    def trial(steps, limit):
        return make_trials(["follow_target"], [0], {}, tmp_path, envs=4, steps=steps, time_limit_minutes=limit,
                           cpus_per_trial=1)[0]

    t = trial(5000, 26.0)
    assert not is_done(t)  # no trial_done.json yet
    t.run_dir.mkdir(parents=True)
    done = t.run_dir / "trial_done.json"
    done.write_text(json.dumps({"env_steps": 1000, "wall_s": 26.0 * 60 - 0.5, "time": "x"}))
    assert is_done(t) and is_done(trial(5000, 20.0))
    assert not is_done(trial(5000, 120.0)) and not is_done(trial(5000, 0.0))
    done.write_text(json.dumps({"env_steps": 5000, "wall_s": 60.0, "time": "x"}))
    assert is_done(trial(5000, 120.0)) and is_done(trial(4000, 0.0)) and not is_done(trial(6000, 0.0))
    done.write_text("{not json")
    with pytest.raises(SweepError, match="trial_done.json: unreadable"):
        is_done(t)


@pytest.mark.long(seconds=50)
def test_two_trial_local_sweep_end_to_end(tmp_path):
    out = tmp_path / "sweep"
    log = _finish(_sweep(out, 48))
    assert "2/2 trials finished" in log, log
    for seed in (0, 1):
        run = out / f"follow_target__s{seed}"
        st = read_state(run)
        assert st["num_timesteps"] == 48, log
        assert (run / "trial_done.json").is_file() and (run / "policy.zip").is_file()
        cfg = json.loads((run / "config.json").read_text())["args"]
        assert cfg["seed"] == seed and cfg["net_arch"] == [32, 32] and cfg["num_envs"] == 4
        # the trial runs at the sweep's own niceness (Ray's workers default to 15: starved beside any busy process)
        assert f"niceness {os.nice(0)}, 1 threads" in (run / "train.log").read_text(), log
    assert json.loads((out / "sweep.json").read_text())["trials"][1]["seed"] == 1
    # re-running a finished sweep runs nothing
    mtime = (out / "follow_target__s0" / "policy.zip").stat().st_mtime_ns
    log2 = _finish(_sweep(out, 48))
    assert "2 already finished, 0 to run" in log2 and "2/2 trials finished" in log2, log2
    assert (out / "follow_target__s0" / "policy.zip").stat().st_mtime_ns == mtime


@pytest.mark.slow  # about 1.5 min each: two sweeps of 400 iterations
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_interrupted_sweep_continues_each_trial(tmp_path, sig):
    """Ctrl-C, or a SIGTERM to the sweep (which ray.init would otherwise take over), stops the trials with a
    checkpoint; re-running continues them."""
    out = tmp_path / "sweep"
    steps = 4 * 400
    first = out / "follow_target__s0"
    proc = _sweep(out, steps)
    try:
        deadline = time.monotonic() + 600
        while time.monotonic() < deadline:  # interrupt once trial 0 has a checkpoint, well before its end
            st = read_state(first)
            if st is not None and st["num_timesteps"] >= 40:
                break
            assert proc.poll() is None, proc.stdout.read()
            time.sleep(0.2)
        proc.send_signal(sig)
        log = _finish(proc, 300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, log
    st1 = read_state(first)
    assert 40 <= st1["num_timesteps"] < steps, log
    assert not (first / "trial_done.json").exists()
    assert not (out / "follow_target__s1" / "trial_done.json").exists()
    created = json.loads((first / "config.json").read_text())["created"]
    started = sum((out / f"follow_target__s{s}" / "config.json").exists() for s in (0, 1))  # 1 or 2 (2 cores)

    log2 = _finish(_sweep(out, steps))
    assert f"{started} of them resumed" in log2 and "2/2 trials finished" in log2, log2
    st2 = read_state(first)
    assert st2["num_timesteps"] == steps and st2["n_updates"] > st1["n_updates"]
    assert st2["wall_s"] > st1["wall_s"]
    assert json.loads((first / "config.json").read_text())["created"] == created  # same run, continued
    rows = (first / "metrics.csv").read_text().splitlines()
    steps_logged = [int(r.split(",")[0]) for r in rows[1:]]
    assert min(steps_logged) < st1["num_timesteps"] < max(steps_logged) == steps
    assert read_state(out / "follow_target__s1")["num_timesteps"] == steps
