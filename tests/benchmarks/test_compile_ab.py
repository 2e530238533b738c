"""benchmarks/compile_ab.py times real eager and compiled updates, interleaved, and writes its JSON (no timing is
asserted: the figures are taken on a quiet machine)."""
from __future__ import annotations

import json

import pytest

from benchmarks.compile_ab import main


def test_compiled_and_eager_updates_are_timed_side_by_side(tmp_path, capsys):
    assert main(["--tasks", "ik4d", "--rounds", "2", "--threads", "1", "--variants", "float32,float32_compiled",
                 "--out", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "compile_ab.json").read_text())
    r = res["tasks"]["ik4d"]
    assert set(r["updates_ms_median"]) == {"float32", "float32_compiled"}
    assert all(len(v) == 2 and min(v) > 0 for v in r["updates_ms_runs"].values())
    assert r["compiled_over_eager"]["float32"] == pytest.approx(
        r["updates_ms_median"]["float32_compiled"] / r["updates_ms_median"]["float32"])
    assert "compiled/eager float32" in capsys.readouterr().out


def test_unknown_variant_is_refused(capsys):
    with pytest.raises(SystemExit):
        main(["--variants", "float16"])
    assert "--variants: unknown float16" in capsys.readouterr().err
