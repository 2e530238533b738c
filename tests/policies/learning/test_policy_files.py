"""Policy files are data: loading never unpickles (issue: a policy zip could run code in `rodlab eval`, the
workbench and `rodlab train --init-from`). A full SB3 checkpoint loads only with an explicit --trust-pickle."""
from __future__ import annotations

import json
import zipfile

import pytest

from policies.learning.sac import PolicyLoadError, load_policy, read_policy_meta
from tests.helpers.cli import rodlab
from tests.helpers.payloads import rodlab_zip, sb3_zip


def test_rodlab_eval_never_unpickles_an_sb3_zip(tmp_path, capsys):
    marker = tmp_path / "PWNED"
    bad = sb3_zip(tmp_path / "model.zip", marker)
    out = rodlab(capsys, "eval", str(bad), "--task", "follow_target", "--episodes", "1")
    assert not marker.exists(), "the pickle payload in the SB3 zip ran"
    assert out.returncode == 2, out.stderr
    assert "--trust-pickle" in out.stderr and "Traceback" not in out.stderr


def test_rodlab_eval_never_unpickles_policy_pt(tmp_path, capsys):
    marker = tmp_path / "PWNED"
    bad = rodlab_zip(tmp_path / "policy.zip", marker, task="Pendulum-v1")
    out = rodlab(capsys, "eval", str(bad), "--episodes", "1")
    assert not marker.exists()
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert "policy.pt is not a plain tensor file" in out.stderr
    assert "weights_only=False" not in out.stderr  # no advice to switch the protection off


def test_load_policy_refuses_sb3_without_trust_and_payload_never_runs(tmp_path):
    marker = tmp_path / "PWNED"
    bad = sb3_zip(tmp_path / "model.zip", marker)
    with pytest.raises(PolicyLoadError, match="stable-baselines3 checkpoint.*--trust-pickle"):
        load_policy(bad)
    assert read_policy_meta(bad)["format"] == "sb3"  # reading the metadata is JSON only
    assert not marker.exists()


def test_trust_pickle_loads_a_real_sb3_checkpoint_with_a_warning(tmp_path, capsys):
    import gymnasium as gym

    from policies.learning.sac import LayerNormSACPolicy, RodSAC

    model = RodSAC(LayerNormSACPolicy, gym.make("Pendulum-v1"), policy_kwargs={"net_arch": [8]}, buffer_size=100)
    path = tmp_path / "model.zip"
    model.save(path)
    with pytest.raises(PolicyLoadError, match="--trust-pickle"):
        load_policy(path)
    pol, meta = load_policy(path, trust_pickle=True)
    assert meta["format"] == "sb3" and tuple(pol.observation_space.shape) == (3,)
    assert "warning" in capsys.readouterr().err


@pytest.mark.parametrize("meta", [[1, 2, 3], "text", 42, None])
def test_meta_json_must_be_an_object(tmp_path, meta):
    p = tmp_path / "p.zip"
    with zipfile.ZipFile(p, "w") as zf:
        zf.writestr("meta.json", json.dumps(meta))
        zf.writestr("policy.pt", b"")
    with pytest.raises(PolicyLoadError, match="meta.json must be a JSON object"):
        read_policy_meta(p)
    with pytest.raises(PolicyLoadError, match="meta.json must be a JSON object"):
        load_policy(p)


def test_garbage_policy_pt_is_a_clear_error(tmp_path):
    good_meta = {"format": "rodlab-sac-policy/1", "task": "Pendulum-v1", "obs_low": [-1.0] * 3,
                 "obs_high": [1.0] * 3, "action_low": [-1.0], "action_high": [1.0], "net_arch": [8], "n_critics": 2}
    for i, blob in enumerate((b"\x00garbage\xff" * 10, b"", b"PK\x03\x04broken")):
        p = tmp_path / f"g{i}.zip"
        with zipfile.ZipFile(p, "w") as zf:
            zf.writestr("meta.json", json.dumps(good_meta))
            zf.writestr("policy.pt", blob)
        with pytest.raises(PolicyLoadError, match="policy.pt is not a plain tensor file") as exc:
            load_policy(p)
        assert "weights_only" not in str(exc.value)


def test_train_init_from_reads_weights_only(tmp_path):
    """--init-from with an SB3-shaped zip: only tensor entries are read (weights_only); the payload never runs."""
    from policies.learning.training import TrainError, train
    from tests.helpers.training import train_args

    marker = tmp_path / "PWNED"
    bad = sb3_zip(tmp_path / "model.zip", marker, task="Pendulum-v1")
    with pytest.raises(TrainError, match="policy.pth is not a plain tensor file"):
        train(train_args(tmp_path / "run", 8, task="Pendulum-v1", init_from=str(bad)))
    assert not marker.exists()
