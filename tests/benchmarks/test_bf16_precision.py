"""benchmarks/bf16_precision.py on the shipped Follow Target critic: the float32 layers --bf16 keeps do reduce the
error bfloat16 puts into Q and dQ/da, and the script writes its JSON."""
from __future__ import annotations

import json

from benchmarks.bf16_precision import main


def test_float32_layers_reduce_the_bfloat16_error(tmp_path, capsys):
    assert main(["--out", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "bf16_precision.json").read_text())
    lay = res["layouts"]
    assert res["samples"] == 768 and res["task"] == "follow_target"
    for key in ("q_abs_err_mean", "dq_da_rel_err"):
        assert 0 < lay["rodlab"][key] < lay["f32_heads"][key] < lay["all"][key]
    assert lay["rodlab"]["q_abs_err_mean"] < 0.5 * lay["all"]["q_abs_err_mean"]
    assert lay["rodlab"]["dq_da_cos_mean"] > lay["all"]["dq_da_cos_mean"]
    assert "rodlab" in capsys.readouterr().out
