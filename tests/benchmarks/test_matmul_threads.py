"""benchmarks/matmul_threads.py runs both thread settings in fresh processes and writes its JSON (no timing is
asserted: the figures are taken on a quiet machine)."""
from __future__ import annotations

import json

from benchmarks.matmul_threads import main


def test_both_settings_measured_and_written(tmp_path, capsys):
    assert main(["--quick", "--repeats", "2", "--out", str(tmp_path)]) == 0
    res = json.loads((tmp_path / "matmul_threads.json").read_text())
    assert set(res["settings"]) == {"unset", "omp1_mkl1"}
    assert res["settings"]["omp1_mkl1"]["env"] == {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    for r in res["settings"].values():
        for dtype in ("float32", "bfloat16"):
            assert len(r[dtype]["ms"]) == 2 and all(t > 0 for t in r[dtype]["ms"])
    assert "omp1_mkl1" in capsys.readouterr().out
