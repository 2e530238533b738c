"""`rodlab eval --record FILE` writes the evaluated episodes to a readable .rrd."""

from policies.cli import eval_main
from policies.recording import read_recording
from tests.helpers.paths import REPO

POLICY = REPO / "policies" / "pretrained" / "ik4d.zip"


def test_eval_record_writes_episodes(tmp_path, capsys):
    assert POLICY.is_file(), f"the shipped policy {POLICY} is missing"
    out = tmp_path / "eval.rrd"
    assert eval_main([str(POLICY), "--episodes", "1", "--envs", "1", "--json", "--record", str(out)]) == 0
    assert out.exists()
    eps = read_recording(out)
    assert len(eps) == 1
    assert eps[0].positions.shape[0] == 102  # reset frame + 101 control steps of 4D IK
