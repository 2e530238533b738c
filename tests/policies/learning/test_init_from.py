"""Warm start (``rodlab train TASK --init-from POLICY.zip``): weights copied before the first update, clear errors.

Same tiny setup as test_train_eval.py (4 envs, 3x32 nets, a few hundred steps on follow_target).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch as th

from policies.learning.sac import load_policy, read_policy_meta
from policies.learning.training import TrainError, train
from tests.helpers.training import TASK, train_args


def _state(path):
    pol, meta = load_policy(path)
    return {k: v.clone() for k, v in pol.state_dict().items()}, meta


@pytest.fixture(scope="module")
def source(tmp_path_factory):
    """A small trained run (with gradient updates, so its weights and entropy coefficient moved)."""
    run = tmp_path_factory.mktemp("src") / "run"
    train(train_args(run, 120))
    return run


def test_warm_start_copies_weights_before_first_update(source, tmp_path):
    src_sd, src_meta = _state(source / "policy.zip")
    assert src_meta["extra"]["log_ent_coef"] is not None and src_meta["extra"]["log_ent_coef"] != 0.0
    run = tmp_path / "ws"
    # no gradient update at all (learning_starts never reached): the saved policy is the warm-started one
    train(train_args(run, 40, seed=7, learning_starts=10**9, init_from=str(source / "policy.zip")))
    new_sd, new_meta = _state(run / "policy.zip")
    assert set(new_sd) == set(src_sd)
    for k in src_sd:
        assert th.equal(new_sd[k], src_sd[k]), k
    # target critics start equal to the critics (a policy file holds no target critics)
    ck = th.load(_sb3_policy_pt(run / "checkpoint" / "model.zip"), weights_only=True)
    for k, v in ck.items():
        if k.startswith("critic_target."):
            assert th.equal(v, src_sd["critic." + k[len("critic_target."):]]), k
    assert math.isclose(new_meta["extra"]["log_ent_coef"], src_meta["extra"]["log_ent_coef"], rel_tol=1e-6)
    assert new_meta["extra"]["training"]["gradient_updates"] == 0
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["args"]["init_from"] == str(source / "policy.zip")
    assert cfg["init_from"]["ent_coef_from_file"] is True
    assert cfg["init_from"]["source_training"]["env_steps"] == 120
    # the replay buffer starts empty: only this run's 40 transitions (10 rows of 4 envs) are in it
    with np.load(run / "checkpoint" / "replay.npz") as z:
        assert z["observations"].shape[:2] == (10, 4)

    # ... and training continues from there (weights move once updates start)
    run2 = tmp_path / "ws2"
    train(train_args(run2, 80, seed=7, learning_starts=8, init_from=str(source / "checkpoint" / "model.zip")))
    moved, _ = _state(run2 / "policy.zip")
    assert any(not th.equal(moved[k], src_sd[k]) for k in src_sd)


def _sb3_policy_pt(model_zip):
    import io
    import zipfile

    with zipfile.ZipFile(model_zip) as zf:
        return io.BytesIO(zf.read("policy.pth"))


def test_init_ent_coef_used_when_file_has_none(source, tmp_path):
    """Older policy files (e.g. the shipped ones) hold no entropy coefficient: Args.init_ent_coef applies."""
    import zipfile

    old = tmp_path / "old.zip"
    with zipfile.ZipFile(source / "policy.zip") as zin, zipfile.ZipFile(old, "w") as zout:
        meta = json.loads(zin.read("meta.json"))
        meta["extra"].pop("log_ent_coef")
        zout.writestr("meta.json", json.dumps(meta))
        zout.writestr("policy.pt", zin.read("policy.pt"))
    assert "log_ent_coef" not in read_policy_meta(old)["extra"]
    run = tmp_path / "ws"
    train(train_args(run, 40, learning_starts=10**9, init_from=str(old), init_ent_coef=0.01))
    _, meta = _state(run / "policy.zip")
    assert math.isclose(meta["extra"]["log_ent_coef"], math.log(0.01), rel_tol=1e-5)
    assert json.loads((run / "config.json").read_text())["init_from"]["ent_coef_from_file"] is False


def test_warm_start_errors_are_clear(source, tmp_path):
    with pytest.raises(TrainError, match="--init-from: policy file not found"):
        train(train_args(tmp_path / "a", 40, init_from=str(tmp_path / "missing.zip")))
    assert not (tmp_path / "a").exists()
    bad = tmp_path / "bad.zip"
    bad.write_text("garbage")
    with pytest.raises(TrainError, match="--init-from: .*not a readable policy zip"):
        train(train_args(tmp_path / "b", 40, init_from=str(bad)))
    other = "MountainCarContinuous-v0"
    with pytest.raises(TrainError, match=f"trained on task '{TASK}', not '{other}'"):
        train(train_args(tmp_path / "c", 40, task=other, init_from=str(source / "policy.zip")))
    with pytest.raises(TrainError, match="does not match this run's"):
        train(train_args(tmp_path / "d", 40, net_arch=[16, 16], init_from=str(source / "policy.zip")))
    with pytest.raises(TrainError, match="cannot be combined with --resume"):
        train(train_args(source, 200, init_from=str(source / "policy.zip")), resume=True)


def test_warm_start_shape_mismatch(tmp_path):
    """Same task name on the file but other observation shape (a file from an older task version)."""
    import zipfile

    src = tmp_path / "pend"
    train(train_args(src, 40, task="Pendulum-v1", learning_starts=10**9))
    forged = tmp_path / "forged.zip"
    with zipfile.ZipFile(src / "policy.zip") as zin, zipfile.ZipFile(forged, "w") as zout:
        meta = json.loads(zin.read("meta.json"))
        meta["task"] = "MountainCarContinuous-v0"  # 2-d observations, 1-d actions; Pendulum: 3-d, 1-d
        zout.writestr("meta.json", json.dumps(meta))
        zout.writestr("policy.pt", zin.read("policy.pt"))
    with pytest.raises(TrainError, match=r"observation shape \(3,\), task 'MountainCarContinuous-v0' has \(2,\)"):
        train(train_args(tmp_path / "x", 40, task="MountainCarContinuous-v0", init_from=str(forged)))


def test_cli_rejects_init_from_with_resume(tmp_path, capsys):
    from policies.cli import train_main

    with pytest.raises(SystemExit) as exc:
        train_main(["Pendulum-v1", "--run-dir", str(tmp_path), "--resume", "--init-from", "x.zip"])
    assert exc.value.code == 2
    assert "cannot be combined with --resume" in capsys.readouterr().err
    assert train_main(["Pendulum-v1", "--envs", "2", "--steps", "10", "--run-dir", str(tmp_path / "r"),
                       "--init-from", str(tmp_path / "missing.zip")]) == 2
    err = capsys.readouterr().err
    assert "rodlab train: --init-from: policy file not found" in err and "Traceback" not in err
