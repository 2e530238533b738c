"""Pinned readouts (workbench.pins): the node a click picks, and values that are the simulator's own."""
from __future__ import annotations

import numpy as np

from sim.curvature import material_curvature
from workbench.core import Workbench
from workbench.pins import MAX_PINS, node_readout, ray_nearest_node, readout_text


def test_the_node_nearest_the_ray_is_picked():
    x = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.1], [0.0, 0.0, 0.2]])
    # a ray along +y passing 1 cm below node 1
    assert ray_nearest_node(x, (0, 1), (0.0, -2.0, 0.09), (0.0, 1.0, 0.0)) == 1
    assert ray_nearest_node(x, (1, 2), (0.0, -2.0, 0.16), (0.0, 2.0, 0.0)) == 2


def test_a_readout_holds_the_simulators_curvature_velocity_and_command():
    wb = Workbench.builtin()
    wb.set_teleop_value(2, 0, 1.2)
    wb.set_teleop_value(3, 1, -0.6)
    wb.set_teleop_value(2, 2, 0.4)
    for _ in range(15):  # still moving: velocities are not zero
        wb.step()
    fr = wb.frame()
    st = wb.live.state
    m1, m2, _ = (np.asarray(a[0]) for a in wb.live.sim.material_frames(st))
    kappa = material_curvature(np.asarray(st.node_pos[0]), m1, m2)
    for node in (5, 10, 14):
        r = node_readout(fr, node)
        np.testing.assert_allclose(r["position"], st.node_pos[0, node], rtol=0, atol=1e-15)
        np.testing.assert_allclose(r["velocity"], st.node_vel[0, node], rtol=0, atol=1e-15)
        assert r["κ1"] == kappa[node, 0] and r["κ2"] == kappa[node, 1]
        assert (r["κ̄1"], r["κ̄2"]) == tuple(wb.live.ctrl.kappa_bar[0, node])
        assert np.isfinite(r["twist"]) and np.isfinite(r["strain"])
    for end in (0, len(fr.node_pos) - 1):  # the simulator's rows 0 and N−1: no curvature at the ends
        assert node_readout(fr, end)["κ1"] == 0.0 == kappa[end, 0]
    assert np.linalg.norm(node_readout(fr, 14)["velocity"]) > 1e-3
    assert abs(node_readout(fr, 10)["κ1"]) > 0.01
    text = readout_text(10, node_readout(fr, 10))
    assert text.startswith("node 10 · (") and f"κ1 {node_readout(fr, 10)['κ1']:+.3f}" in text


def test_a_replayed_frame_without_velocities_or_frames_reads_what_it_has():
    wb = Workbench.builtin()
    fr = wb.frame()
    fr.node_vel, fr.m1, fr.m2, fr.kappa_bar = None, None, None, None
    r = node_readout(fr, 3)
    assert set(r) == {"position", "strain"}
    assert "node 3" in readout_text(3, r)


def test_pins_toggle_and_keep_the_newest(tmp_path):
    from tests.workbench.conftest import make_app

    app = make_app(wait_for_browser=False, recordings_dir=tmp_path / "r", scenes_dir=tmp_path / "s")
    try:
        v = app.view
        for node in range(1, MAX_PINS + 2):
            v.toggle_pin(node)
        assert v.pins == list(range(2, MAX_PINS + 2))
        v.toggle_pin(3)
        assert 3 not in v.pins
        v.render(app.wb.frame())
        assert len(v.pin_texts) == MAX_PINS - 1 and v.pin_texts[0].startswith("node 2 ·")
    finally:
        app.stop()
