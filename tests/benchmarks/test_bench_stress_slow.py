"""The numerical stress benchmark in its quick configuration (slow: minutes)."""
import json

import pytest


@pytest.mark.slow
def test_stress_quick_never_produces_nan(tmp_path):
    from benchmarks import stress
    rc = stress.main(["--quick", "--out", str(tmp_path)])
    res = json.loads((tmp_path / "stress_quick.json").read_text())
    assert res["totals"]["errors"] == 0
    assert res["totals"]["nan"] == 0
    assert res["totals"]["env_steps"] > 0
    assert rc == 0
