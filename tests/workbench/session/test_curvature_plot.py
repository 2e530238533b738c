"""Curvature along the rod (Plots tab): the actual curvature follows the commanded one in a settled live rod
(3-D components and the 2-D in-plane one); a replay computes it from the recorded frames; in headless Chromium the
plot shows commanded and actual series and follows the replay timeline."""
from __future__ import annotations

import numpy as np
import pytest

from tools.browser import expand_folder, slider_thumb, wait_for
from workbench.session.plots import CURVATURE_KEY, curvature_plot
from workbench.session.plots import CURVATURE_TITLE as TITLE
from workbench.session.rod_curves import PLANAR, curves, live_curves, replay_curves


def _arc_frames(n: int = 11, bend: float = 0.0):
    """A planar arc in the x-z plane (turning ``bend`` rad per node) with m1 = ŷ: κ2 = −κb·ŷ = bend-ish, κ1 = 0."""
    ang = np.concatenate([[0.0], np.cumsum(np.full(n - 2, bend))])
    e = np.stack([np.sin(ang), np.zeros_like(ang), np.cos(ang)], 1) * 0.1
    x = np.concatenate([np.zeros((1, 3)), np.cumsum(e, 0)])
    t = e / np.linalg.norm(e, axis=1, keepdims=True)
    m1 = np.tile([0.0, 1.0, 0.0], (n - 1, 1))
    return x, m1, np.cross(t, m1)


def test_arc_curvature_is_two_tan_half_angle():
    x, m1, m2 = _arc_frames(bend=0.2)
    c = curves(x, m1, m2)
    np.testing.assert_allclose(np.abs(c["κ2"][1][1:-1]), 2 * np.tan(0.1), rtol=1e-9)
    np.testing.assert_allclose(c["κ1"][1], 0.0, atol=1e-12)
    np.testing.assert_allclose(c["twist"][1], 0.0, atol=1e-12)
    assert c["κ1"][0] is None  # nothing commanded


def test_live_actual_follows_commanded_3d():
    from workbench.session.core import Workbench

    wb = Workbench.builtin()
    wb.set_teleop_mode("absolute")
    wb.set_teleop_value(2, 0, 0.5)
    wb.set_teleop_value(3, 2, 0.3)
    for _ in range(300):
        wb.step()
    c = live_curves(wb)
    assert set(c) == {"κ1", "κ2", "twist"}
    for name in c:
        cmd, act = c[name]
        assert np.abs(cmd).max() > 0.05 or name == "κ2"
        # settled under gravity: within a few percent of the largest commanded value
        assert np.abs(cmd - act).max() < 0.02, name
    plot = curvature_plot(c)
    assert plot.key == CURVATURE_KEY and "twist commanded" in plot.labels and plot.dashed[plot.labels.index(
        "twist commanded")]


def test_live_planar_task_has_one_in_plane_component():
    from workbench.session.core import Workbench
    from workbench.session.policy_session import PolicySession

    wb = Workbench.builtin()
    s = PolicySession("tight_obstacles_2d", "zero")
    wb.start_policy(s)
    for _ in range(250):
        s.core.ctrl.kappa_bar[0, 8:12, 0] = 0.1
        wb.step()
    c = live_curves(wb)
    assert list(c) == [PLANAR]
    cmd, act = c[PLANAR]
    np.testing.assert_allclose(act[8:12], 0.1, atol=0.01)
    assert np.abs(act[14:]).max() < 0.01


def _write(path, frames: int = 12):
    from policies.recording import Recorder
    from policies.recording.schema import StaticScene

    rec = Recorder(path)
    rec.begin_episode({"task": "synthetic", "policy": "none"}, StaticScene(rod_radius=0.02))
    for k in range(frames):
        x, m1, m2 = _arc_frames(bend=0.02 * k)
        rec.log_step(control_step=k, sim_time=0.01 * k, node_pos=x, m1=m1, m2=m2, scalars={"tip_error": 0.1})
    rec.end_episode()
    rec.close()


def test_replay_curves_from_recorded_frames(tmp_path):
    from workbench.session.replay import ReplaySession

    _write(tmp_path / "arc.rrd")
    rs = ReplaySession.open(tmp_path / "arc.rrd")
    k0, k1 = replay_curves(rs.ep, 0), replay_curves(rs.ep, rs.length - 1)
    assert k0["κ2"][0] is None  # the recording holds no commanded curvature
    np.testing.assert_allclose(k0["κ2"][1], 0.0, atol=1e-6)
    np.testing.assert_allclose(np.abs(k1["κ2"][1][1:-1]), 2 * np.tan(0.11), rtol=1e-4)


CHARTS_JS = """() => Object.values(window.__viserTestpoints?.uplots ?? {}).map(({chart}) => ({
    title: chart.root.querySelector('.u-title')?.textContent ?? '',
    labels: chart.series.map(s => String(s.label)),
    data: chart.data.map(col => Array.from(col, v => (Number.isFinite(v) ? v : null))),
}))"""


def _chart(page):
    return next((c for c in page.evaluate(CHARTS_JS) if c["title"] == TITLE), None)


@pytest.mark.browser
def test_browser_curvature_plot_live_and_replay(wb_page):
    app, page = wb_page
    wb = app.wb
    wb.set_teleop_value(2, 0, 0.4)
    expand_folder(page, "Plots", ".uplot")

    def live_ok() -> bool:
        c = _chart(page)
        if c is None or "κ1 commanded" not in c["labels"]:
            return False
        cmd = c["data"][c["labels"].index("κ1 commanded")]
        want = float(live_curves(wb)["κ1"][0].max())
        return want > 0.05 and len(cmd) == wb.live.n_nodes and max(cmd) == pytest.approx(want, abs=1e-6)

    wait_for(live_ok, timeout=30, what="live curvature plot with the commanded κ1")
    c = _chart(page)
    assert {"κ1 actual", "κ2 actual", "twist actual", "twist commanded"} <= set(c["labels"])
    # replay: the plot follows the timeline
    _write(app.recordings_dir / "arc.rrd")
    app.replay.open("arc.rrd")
    wait_for(lambda: (c := _chart(page)) is not None and c["labels"] == ["node", "κ1 actual", "κ2 actual",
                                                                          "twist actual"], what="replay curves")
    i2 = _chart(page)["labels"].index("κ2 actual")
    assert max(abs(v) for v in _chart(page)["data"][i2]) < 1e-5
    expand_folder(page, "Recordings", "Open recording")
    th = slider_thumb(page, "Timeline")
    th.focus()
    th.press("End")
    wait_for(lambda: max(abs(v) for v in _chart(page)["data"][i2]) == pytest.approx(2 * np.tan(0.11), rel=1e-3),
             timeout=20, what="curvature plot at the last frame")
