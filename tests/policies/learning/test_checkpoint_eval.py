"""Checkpoints lose no transition across stop/kill and resume; evaluation during training is logged.

Real SB3 training of the follow_target task (4 envs, small networks, a few hundred env steps).
"""
from __future__ import annotations

import base64
import csv
import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

import policies.learning.sac as sac
from policies.learning.checkpoint import find_checkpoint, read_state, resume_seed
from policies.learning.training import Args, make_sb3_env, train
from tests.helpers.paths import REPO

TASK = "follow_target"
ENVS = 4


def _args(run_dir: Path, steps: int, **kw) -> Args:
    base = dict(task=TASK, num_envs=ENVS, total_steps=steps, seed=3, run_dir=str(run_dir), batch_size=32,
                learning_starts=16, updates_per_iter=1, net_arch=[32, 32], buffer_size=100_000, log_interval_s=0.0,
                checkpoint_minutes=60.0, first_checkpoint_minutes=60.0, eval_minutes=0.0, precision="float32")
    base.update(kw)
    return Args(**base)


def _replay(run: Path) -> dict[str, np.ndarray]:
    with np.load(find_checkpoint(run) / "replay.npz") as z:
        return {k: z[k].copy() for k in z.files}


def _assert_consistent(run: Path) -> dict:
    """Every env step counted in state.json is a row of the saved replay buffer (none dropped)."""
    st = read_state(run)
    rb = _replay(run)
    assert st["replay_rows"] == rb["observations"].shape[0]
    assert rb["observations"].shape[0] * ENVS == st["num_timesteps"], (rb["observations"].shape, st)
    rows = rb["observations"].shape[0]
    assert (int(rb["pos"]) == rows and not bool(rb["full"])) or (bool(rb["full"]) and int(rb["pos"]) == 0)
    return st


def test_stop_then_resume_keeps_every_transition(tmp_path):
    run = tmp_path / "run"
    train(_args(run, 10**7, time_limit_minutes=0.02))  # stopped by the time limit mid-run
    st1 = _assert_consistent(run)
    assert 0 < st1["num_timesteps"] < 10**7
    rb1 = _replay(run)
    side = json.loads((run / "policy.json").read_text())
    assert side["training"]["stopped_by_time_limit"] is True

    n1 = st1["num_timesteps"]
    train(_args(run, n1 + 10 * ENVS), resume=True)
    st2 = _assert_consistent(run)
    assert st2["num_timesteps"] == n1 + 10 * ENVS
    rb2 = _replay(run)
    rows1 = rb1["observations"].shape[0]
    for key in ("observations", "next_observations", "actions", "rewards", "dones", "timeouts"):
        np.testing.assert_array_equal(rb2[key][:rows1], rb1[key])  # the first session's data is kept
    # the first transition after the resume starts from the resumed envs' reset observation (fresh episodes
    # from the derived seed), not from an observation of the stopped process's episodes
    env = make_sb3_env(TASK, ENVS, resume_seed(3, n1))
    first = env.reset()
    env.close()
    np.testing.assert_allclose(rb2["observations"][rows1], first, rtol=0, atol=1e-6)
    assert not np.allclose(rb2["observations"][rows1], rb1["next_observations"][-1])


_KILL_SCRIPT = """
import sys
from policies.learning.training import Args, train
train(Args(task={task!r}, num_envs={envs}, total_steps=10**8, seed=5, run_dir=sys.argv[1], batch_size=32,
           learning_starts=16, updates_per_iter=1, net_arch=[32, 32], buffer_size=100_000, log_interval_s=1.0,
           checkpoint_minutes=0.004, first_checkpoint_minutes=0.002, eval_minutes=0.0, precision="float32"))
"""


def test_hard_kill_leaves_a_consistent_checkpoint_that_resumes(tmp_path):
    run = tmp_path / "run"
    env = dict(os.environ, OMP_NUM_THREADS="1", NUMBA_NUM_THREADS="1")
    proc = subprocess.Popen([sys.executable, "-c", _KILL_SCRIPT.format(task=TASK, envs=ENVS), str(run)], cwd=REPO,
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 600
        while time.monotonic() < deadline:  # wait for the second periodic checkpoint
            st = read_state(run)
            if st is not None and st["num_timesteps"] >= 40 * ENVS and (run / "checkpoint.old").exists() is False:
                break
            assert proc.poll() is None, proc.stderr.read()
            time.sleep(0.2)
        time.sleep(0.3)
        os.kill(proc.pid, signal.SIGKILL)  # no chance to write a final checkpoint
        proc.wait(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert find_checkpoint(run) is not None
    st = _assert_consistent(run)
    n = st["num_timesteps"]
    train(_args(run, n + 5 * ENVS, seed=5), resume=True)
    st2 = _assert_consistent(run)
    assert st2["num_timesteps"] == n + 5 * ENVS
    assert st2["n_updates"] >= st["n_updates"] + 5


def test_first_checkpoint_is_early(tmp_path, monkeypatch):
    import policies.learning.train_monitor as tm

    calls = []
    real = tm.save_checkpoint

    def spy(model, run_dir, **kw):
        calls.append(int(model.num_timesteps))
        return real(model, run_dir, **kw)

    monkeypatch.setattr(tm, "save_checkpoint", spy)
    run = tmp_path / "run"
    # first checkpoint after ~0 s, the next ones only after an hour: exactly one periodic checkpoint, early
    train(_args(run, 30 * ENVS, first_checkpoint_minutes=1e-6, checkpoint_minutes=60.0))
    assert calls == [ENVS]
    _assert_consistent(run)
    assert not (run / "checkpoint.new").exists() and not (run / "checkpoint.old").exists()
    assert oct((run / "checkpoint" / "model.zip").stat().st_mode & 0o777) == oct(0o644 & ~_umask())


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


def test_evaluation_during_training_is_logged(tmp_path):
    run = tmp_path / "run"
    # ik4d: 101-step episodes keep the evaluations short
    train(_args(run, 60 * ENVS, task="ik4d", eval_every_steps=25 * ENVS, eval_episodes=2, eval_envs=2,
                eval_stochastic=True))
    with open(run / "eval.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    # evaluations at >= 100 and >= 200 env steps, and a final one at 240
    assert [int(r["env_steps"]) for r in rows] == [100, 200, 240]
    for r in rows:
        assert int(r["eval_episodes"]) == 2
        assert np.isfinite(float(r["eval_avg_disc_return_mean"]))
        assert np.isfinite(float(r["eval_stochastic_avg_disc_return_mean"]))
        assert float(r["wall_s"]) > 0 and float(r["eval_s"]) > 0
    assert float(rows[-1]["eval_s_total"]) >= float(rows[0]["eval_s_total"])
    # fixed evaluation seeds: evaluating the final policy again gives the logged figure
    from policies.learning.evaluation import evaluate

    again = evaluate(run / "policy.zip", episodes=2, seed=1_000_003, num_envs=2)
    assert abs(again["avg_discounted_return_mean"] - float(rows[-1]["eval_avg_disc_return_mean"])) < 1e-3
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    ea = EventAccumulator(str(run / "tb"))
    ea.Reload()
    assert "eval/avg_discounted_return" in ea.Tags()["scalars"]
    side = json.loads((run / "policy.json").read_text())
    assert side["training"]["last_eval"]["env_steps"] == 240
    # policy_best.zip: the policy of the best of the three evaluations
    from policies.learning.sac import read_policy_meta

    best = read_policy_meta(run / "policy_best.zip")["extra"]["best_eval"]
    assert best["eval_avg_disc_return_mean"] == max(float(r["eval_avg_disc_return_mean"]) for r in rows)
    again = evaluate(run / "policy_best.zip", episodes=2, seed=1_000_003, num_envs=2)
    assert abs(again["avg_discounted_return_mean"] - best["eval_avg_disc_return_mean"]) < 1e-3


def test_a_checkpoint_that_names_the_old_sac_module_resumes(tmp_path, monkeypatch):
    """SB3 pickles a model's policy class and activation by module name. Checkpoints written before the learning
    package existed name them ``policies.sac.*``: such a run still resumes (policies.learning.sac.LEGACY_MODULES),
    and without that alias it could not."""

    run = tmp_path / "run"
    with monkeypatch.context() as old:  # saved as an older rodlab saved it: the classes live in policies.sac
        old.setitem(sys.modules, "policies.sac", sac)
        for cls in (sac.LayerNormSACPolicy, sac.InplaceReLU):
            old.setattr(cls, "__module__", "policies.sac")
        train(_args(run, 40 * ENVS))
    assert "policies.sac" not in sys.modules
    with zipfile.ZipFile(find_checkpoint(run) / "model.zip") as z:
        data = json.loads(z.read("data"))
    pickled = base64.b64decode(data["policy_class"][":serialized:"])
    assert b"policies.sac" in pickled and b"policies.learning" not in pickled

    n1 = read_state(run)["num_timesteps"]
    with monkeypatch.context() as none:
        none.setattr(sac, "LEGACY_MODULES", {})
        with pytest.raises(Exception, match="cannot load"):
            train(_args(run, n1 + 10 * ENVS), resume=True)
    train(_args(run, n1 + 10 * ENVS), resume=True)
    assert read_state(run)["num_timesteps"] == n1 + 10 * ENVS
    assert "policies.sac" not in sys.modules  # the alias is gone again after loading
