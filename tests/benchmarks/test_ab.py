"""benchmarks/ab.py: interleaved runs, medians and the B/A ratio (no timing is asserted)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from benchmarks import ab

REPO = Path(__file__).resolve().parents[2]


def test_refuses_a_folder_that_is_not_a_checkout(tmp_path):
    with pytest.raises(SystemExit) as exc:
        ab.main(["--a", str(tmp_path), "--b", str(REPO)])
    assert exc.value.code == 2


def test_medians_ratio_and_interleaving(tmp_path, monkeypatch):
    calls = []
    figures = {"a": iter([10.0, 30.0, 20.0]), "b": iter([5.0, 9.0, 7.0])}

    def fake_run(tree, args):
        side = "a" if tree == tmp_path / "a" else "b"
        calls.append(side)
        v = next(figures[side])
        return {"ms_per_env_step_median": v}

    for side in ("a", "b"):
        (tmp_path / side).mkdir()
        (tmp_path / side / "rodlab_cli.py").write_text("")
    monkeypatch.setattr(ab, "run_case", fake_run)
    out = tmp_path / "ab.json"
    assert ab.main(["--a", str(tmp_path / "a"), "--b", str(tmp_path / "b"), "--runs", "3",
                    "--cases", "env step ik4d", "--out", str(out)]) == 0
    assert calls == ["a", "b"] * 3                       # interleaved, A first
    row = json.loads(out.read_text())["cases"][0]
    assert row["a_median_ms"] == 20.0 and row["b_median_ms"] == 7.0
    assert row["ratio_b_over_a"] == pytest.approx(0.35)
    assert row["a_min_ms"] == 10.0 and row["b_min_ms"] == 5.0 and row["ratio_of_fastest"] == pytest.approx(0.5)
    assert row["a_spread"] == pytest.approx(3.0) and row["b_spread"] == pytest.approx(1.8)
