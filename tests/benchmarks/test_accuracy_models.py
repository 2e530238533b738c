"""The models' accuracy benchmark (benchmarks/accuracy_models.py) at its smallest sizes, each figure held to the
bound of the verification test it copies (written out here, not read from the script), so that neither the
benchmark's set-ups nor the figures in BENCHMARKS.md can drift away from the tests."""
import json

import pytest

from benchmarks import accuracy_models as am


def _values(rows):
    return [r["value"] for r in rows]


def test_stepped_cantilever_is_second_order():
    """tests/sim/test_nonuniform.py: |error| < 1e-3 at N = 41, error ratios 3.5–4.5 per halving of the edge."""
    e21, e41, e81, r1, r2 = _values(am.stepped_cantilever((21, 41, 81)))
    assert abs(e41) < 1e-3
    assert 3.5 < r1 < 4.5 and 3.5 < r2 < 4.5
    assert r1 == pytest.approx(e21 / e41) and r2 == pytest.approx(e41 / e81)


@pytest.mark.parametrize("iters", [2, 3])
def test_incline_sticks_under_the_newton_budget(iters):
    """tests/sim/contact/test_friction_newton.py: the settled creep within 5 % of the regularised one, its spread
    under 5 % of it, never up the slope (≤ 1e-6 m/s), friction within 2 % of W sin α."""
    creep, spread, up, friction = _values(am.incline(iters))
    assert abs(creep) < 0.05 and spread < 0.05 and up <= 1e-6 and abs(friction) < 0.02


def test_capstan_holds():
    """test_friction_newton.py: over 3 s the heavy end slips 0–5 mm and the rope stays within 2 mm of the drum."""
    slip, step_slip, off = _values(am.capstan(3.0))
    assert 0.0 <= slip < 5e-3 and step_slip <= slip and abs(off) < 2e-3


def test_buckled_column_matches_the_elastica():
    """tests/sim/analysis/test_static_stability.py: the tip within 1e-3 L' of the elastica, from 2 negative directions
    to none."""
    (row,) = am.buckled_column()
    assert abs(row["value"]) < 1e-3
    assert row["negative_directions_before"] == 2 and row["negative_directions_after"] == 0 and row["stable"]


def test_drag_matches_resistive_force_theory():
    """tests/sim/test_drag.py: the sedimentation velocity to 1e-6 (the test's rtol), the cross-flow cantilever
    within 2 % of q L⁴/8EI."""
    (sed,) = _values(am.sedimentation((45.0,)))
    assert sed < 1e-6
    (flow,) = _values(am.cross_flow())
    assert abs(flow) < 2e-2


def test_end_moment_and_line_load_match_beam_theory():
    """tests/sim/test_loads.py: the arc within 2 mm at N = 41 with an error ratio 3–5; the line load within 2 %."""
    _, e41, ratio = _values(am.end_moment((21, 41)))
    assert e41 < 2e-3 and 3.0 < ratio < 5.0
    (q,) = _values(am.line_load())
    assert abs(q) < 2e-2


def test_node_clamp_is_second_order():
    """tests/sim/test_exact_clamp.py: the small force's error quarters per doubling of N (order 1.8–2.2), the large
    load's tip at least by 2^1.7, both small at the finest N."""
    small, small_ratio, large, large_ratio = (_values(am.node_clamp((21, 41)))[i] for i in (1, 2, 4, 5))
    assert abs(small) < 2e-3 and 2 ** 1.8 < small_ratio < 2 ** 2.2
    assert large < 1e-3 and large_ratio > 2 ** 1.7


def test_rotating_clamp_and_internal_loads():
    """tests/sim/test_rotating_clamp.py: nodes to 1e-14 m, frame to 1e-12; test_internal_loads.py: axial force
    to 1e-9, bending moment to 1e-3."""
    nodes, frame = _values(am.rotating_clamp())
    assert nodes < 1e-14 and frame < 1e-12
    axial, bending = _values(am.internal_loads())
    assert abs(axial) < 1e-9 and abs(bending) < 1e-3


def test_cli_quick_writes_every_row_within_its_bound(tmp_path, capsys):
    out = tmp_path / "m.json"
    assert am.main(["--quick", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    data = json.loads(out.read_text())
    assert data["command"].startswith("python -m benchmarks.accuracy_models --quick")
    assert {"cpu_model", "numpy"} <= set(data["machine"])
    rows = data["rows"]
    assert {r["case"] for r in rows} == {"stepped_cantilever", "incline_2_iterations", "incline_3_iterations",
                                         "capstan", "buckled_column", "sedimentation", "cross_flow", "end_moment",
                                         "line_load", "node_clamp", "rotating_clamp", "internal_loads"}
    assert all(r["within"] for r in rows) and "OUTSIDE" not in printed
    assert printed.count("\n") == len(rows) + 1
