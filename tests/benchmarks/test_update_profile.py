"""benchmarks/update_profile.py profiles real SAC updates per precision setting and writes its JSON (no timing is
asserted: the figures are taken on a quiet machine)."""
from __future__ import annotations

import json

import pytest

from benchmarks.update_profile import main


def test_profile_groups_the_work_of_the_updates(tmp_path, capsys):
    assert main(["--task", "ik4d", "--updates", "2", "--threads", "1", "--out", str(tmp_path),
                 "--settings", "float32,bf16,bf16_all"]) == 0
    res = json.loads((tmp_path / "update_profile_ik4d.json").read_text())
    assert set(res["settings"]) == {"float32", "bf16", "bf16_all"}
    for r in res["settings"].values():
        ms = r["ms_per_update"]
        assert ms["products"] > 0 and ms["layer_norm"] > 0 and ms["relu"] > 0 and ms["adam"] > 0
        assert sum(r["share"].values()) == pytest.approx(1.0)
        assert r["total_ms_per_update"] == pytest.approx(sum(ms.values()))
        assert 0 < r["python_ms_per_update"] < r["wall_ms_per_update"]
    assert "bf16_all" in capsys.readouterr().out


@pytest.mark.slow
def test_profile_of_the_compiled_update_finds_the_fused_loops(tmp_path):
    """With ``--compile`` the LayerNorm, ReLU and Adam work runs inside generated loops, which the profile counts
    as ``fused``; the products stay library calls. Compiles the full-size update (about a minute)."""
    import torch

    torch._dynamo.reset()
    assert main(["--task", "ik4d", "--updates", "2", "--threads", "1", "--out", str(tmp_path),
                 "--settings", "bf16_all_compiled"]) == 0
    ms = json.loads((tmp_path / "update_profile_ik4d.json").read_text())["settings"]["bf16_all_compiled"][
        "ms_per_update"]
    assert ms["fused"] > 0 and ms["products"] > 0
    assert ms["layer_norm"] == 0 and ms["adam"] == 0


def test_unknown_setting_is_refused(capsys):
    with pytest.raises(SystemExit):
        main(["--settings", "float32,float16"])
    assert "unknown float16" in capsys.readouterr().err
