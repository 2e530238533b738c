"""Plot layout (workbench.session.plots): every series kept, episodes split, fixed y range, timeline cursor."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.session.plots import episode_numbers, layout, live_name


def test_leading_nan_series_kept_with_finite_range():
    x = np.arange(6.0)
    vals = {"reward": np.array([np.nan, -1.0, -0.5, -0.2, -0.1, 0.0]),
            "solver/newton_iters": np.array([np.nan, np.nan, 3, 4, 2, 3.0]),
            "energy/bend": np.linspace(0, 1, 6), "energy/kinetic": np.linspace(1, 0, 6),
            "ori_error": np.linspace(0.5, 0.1, 6), "never": np.full(6, np.nan)}
    plots = {p.key: p for p in layout(x, vals)}
    assert set(plots) == {"reward", "solver/newton_iters", "energy", "ori_error"}  # all-NaN series left out
    assert plots["energy"].labels == ("time [s]", "bend", "kinetic")
    for p in plots.values():
        lo, hi = p.y
        assert np.isfinite([lo, hi]).all() and lo < hi
        for col in p.data[1:]:
            fin = col[np.isfinite(col)]
            assert fin.size and lo <= fin.min() and fin.max() <= hi


def test_episodes_split_into_current_and_previous_series():
    t = np.array([0, 1, 2, 3, 0, 1, 2, 0, 1.0])  # three episodes: only the last two are shown
    x = np.arange(len(t)) * 0.1
    ep = episode_numbers(t)
    assert ep.tolist() == [0, 0, 0, 0, 1, 1, 1, 2, 2]
    (p,) = layout(x, {"reward": np.arange(len(t), dtype=float)}, episode=ep)
    assert p.labels == ("time [s]", "reward", "reward (prev. episode)")
    xs, cur, prev = p.data
    assert np.allclose(xs, x[4:])
    assert np.isfinite(cur).tolist() == [False] * 3 + [True] * 2
    assert np.isfinite(prev).tolist() == [True] * 3 + [False] * 2
    assert p.dashed == (False, False, True)


def test_cursor_is_a_vertical_line_at_the_timeline_time():
    x = np.linspace(0, 1, 11)
    (p,) = layout(x, {"tip_error": np.linspace(0.3, 0.1, 11)}, cursor=0.45)
    xs, v, line = p.data
    assert p.labels[-1] == "timeline"
    k = np.nonzero(np.isfinite(line))[0]
    assert len(k) == 2 and np.allclose(xs[k], 0.45) and np.allclose(line[k], p.y)
    assert np.all(np.diff(xs) >= 0) and not np.isfinite(v[k]).any()


def test_live_names():
    assert live_name("r_distance") == "reward_terms/distance"
    assert live_name("contact_force") == "contact/max_normal_force"
    assert live_name("episode_step") is None and live_name("return") is None


def test_solver_counts_share_one_plot():
    from workbench.session.plots import group_of

    key = group_of("solver/newton_iters")
    for name in ("solver/substeps", "solver/converged", "solver/midpoint_fallbacks"):
        assert group_of(name) == key


@pytest.mark.parametrize("lo, hi", [(0.0, 1.0), (0.0, 2e-5), (-3e-5, 1e-4), (100.0, 187.0), (0.0, 3.7e6),
                                    (-1.2, 0.7), (0.95, 1.05), (1e-3, 1.2e-3), (1234.5, 1234.9), (-5e-4, -1e-4)])
def test_y_ticks_are_round_inside_the_range_and_every_label_tells_its_value(lo, hi):
    """The y labels carry the digits their values need: no "0" for 2e-5, no two ticks with one label."""
    from workbench.session.plots import y_ticks

    vals, labels = y_ticks(lo, hi)
    assert 2 <= len(vals) <= 7 and len(labels) == len(vals)
    assert all(lo - 1e-12 <= v <= hi + 1e-12 for v in vals)
    assert len(set(labels)) == len(labels)
    step = vals[1] - vals[0]
    for v, t in zip(vals, labels):
        assert float(t) == pytest.approx(v, abs=1e-6 * step)
    m = step / 10.0 ** np.floor(np.log10(step))
    assert min(abs(m - r) for r in (1.0, 2.0, 2.5, 5.0, 10.0)) < 1e-9  # a round step


def test_y_ticks_of_no_range_are_none():
    from workbench.session.plots import y_ticks

    assert y_ticks(1.0, 1.0) == ((), ()) and y_ticks(0.0, float("nan")) == ((), ())


def test_the_page_plots_carry_those_ticks(tmp_path):
    """Each uPlot the Plots tab creates gets the y ticks and labels of its fixed range (and keeps them in step when
    the range changes)."""
    from tests.workbench.conftest import make_app
    from workbench.session.plots import y_ticks

    app = make_app(wait_for_browser=False, recordings_dir=tmp_path / "r", scenes_dir=tmp_path / "s")
    try:
        wb = app.wb
        wb.set_playing(False)
        for k in range(30):
            wb.set_teleop_value(2, 0, 0.05 * k)
            wb.step()
        app.plots.update_live()
        assert app.plots.handles
        for p in app.plots.shown:
            h = app.plots.handles[p.key]
            lo, hi = app.plots._range[p.key]
            vals, labels = y_ticks(lo, hi)
            assert list(h.axes[1]["values"]) == list(labels) and list(h.axes[1]["splits"]) == list(vals)
    finally:
        app.stop()
