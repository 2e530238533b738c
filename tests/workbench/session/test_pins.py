"""Pinned readouts (workbench.session.pins): the node a click picks, and values that are the simulator's own."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim.geometry.curvature import material_curvature
from workbench.session.core import Workbench
from workbench.session.pins import MAX_PINS, node_readout, ray_nearest_node, readout_text


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
    # what the material carries there: the simulator's internal loads (sim.analysis.internal, tests/sim/analysis/test_internal_loads.py)
    loads = wb.live.sim.internal_loads(st, wb.live.ctrl)
    r = node_readout(fr, 10)
    assert (r["M1"], r["M2"], r["T"]) == (loads.bending[0, 10, 0], loads.bending[0, 10, 1], loads.twisting[0, 10])
    assert r["axial force"] == pytest.approx(0.5 * (loads.axial[0, 9] + loads.axial[0, 10]), rel=1e-15)
    assert abs(r["M1"]) > 0.1 and r["contact force"].tolist() == [0.0, 0.0, 0.0] and "gap" not in r
    lines = text.split("\n")
    assert len(lines) == 4 and lines[2].startswith("N ") and f"M1 {r['M1']:+.3g}" in lines[2]
    assert lines[3] == "no contact"


def test_a_readout_holds_the_contact_on_the_nodes_edges():
    """A sphere pressed into the arm: the pinned node's contact is the sum of the contact rows of its two edges and
    the smallest of their gaps; a node away from the sphere has none."""
    from workbench.session.obstacles import ObstacleEdit

    wb = Workbench.builtin()
    i = wb.add_obstacle(ObstacleEdit(kind="sphere", position=np.array([0.4, 0.0, 0.6])))
    for x in np.linspace(0.4, 0.105, 10):
        wb.set_obstacle_pose(i, [x, 0.0, 0.6], [1.0, 0.0, 0.0, 0.0])
        wb.step()
    for _ in range(10):
        wb.step()
    fr = wb.frame()
    st = wb.live.last_stats
    k = int(st.contact_count[0])
    edges = st.contact_edge[0, :k]
    node = int(edges[np.argmax(st.contact_normal_force[0, :k])])
    rows = np.isin(edges, [node - 1, node])
    r = node_readout(fr, node)
    np.testing.assert_allclose(r["contact force"], fr.contact_forces[rows].sum(axis=0), rtol=1e-15)
    assert np.linalg.norm(r["contact force"]) > 1.0 and r["gap"] == st.contact_gap[0, :k][rows].min()
    assert "contact " in readout_text(node, r) and "gap" in readout_text(node, r)
    assert "gap" not in node_readout(fr, 2) and not node_readout(fr, 2)["contact force"].any()


def test_pinned_values_are_plotted_against_time_from_the_history():
    """The Plots tab's pinned series: each frame's curvature, moments and axial force at the pinned nodes, equal to
    the simulator's at that frame, also for the frames before the pin was set."""
    from workbench.session.pins import PinSeries
    from workbench.session.plots import layout, live_series

    wb = Workbench.builtin()
    want = []
    for k in range(12):
        wb.set_teleop_value(2, 0, 0.1 * k)
        wb.step()
        want.append(wb.live.sim.internal_loads(wb.live.state, wb.live.ctrl))
    items = wb.history._items
    series = PinSeries().series(wb.live.sim, items, [6, 12])
    assert {"pin_moment/node 6 M1", "pin_moment/node 12 T", "pin_axial/node 12", "pin_curvature/node 6 κ1"} <= set(series)
    got = series["pin_moment/node 6 M1"][-12:]
    np.testing.assert_array_equal(got, [w.bending[0, 6, 0] for w in want])
    np.testing.assert_array_equal(series["pin_moment/node 12 T"][-12:], [w.twisting[0, 12] for w in want])
    x, episode, vals = live_series(items, wb.live.dt)
    vals.update(series)
    titles = {p.key: p.title for p in layout(x, vals, episode=episode)}
    assert titles["pin_moment"].startswith("pinned nodes: bending moments") and "pin_axial" in titles
    assert PinSeries().series(wb.live.sim, items, []) == {}


def test_a_replayed_frame_without_velocities_or_frames_reads_what_it_has():
    wb = Workbench.builtin()
    fr = wb.frame()
    fr.node_vel, fr.m1, fr.m2, fr.kappa_bar = None, None, None, None
    fr.edge_axial_force, fr.node_moment, fr.contact_edge, fr.contact_gap = None, None, None, None
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
        v.flush()  # the frame shown whole now (not at the next frame)
        assert len(v.pin_texts) == MAX_PINS - 1 and v.pin_texts[0].startswith("node 2 ·")
    finally:
        app.stop()


def test_pinned_series_skip_snapshots_of_another_rod():
    """After the scene changed to a rod of another length, history snapshots of the old rod give no values (NaN),
    never an error in the Plots tab's refresh."""
    from workbench.session.pins import PinSeries

    old = Workbench.builtin()
    for _ in range(3):
        old.step()
    short = Workbench.from_path(Path(__file__).resolve().parents[3] / "assets" / "scenes" / "rope_pinned.toml")
    short.step()
    items = old.history._items + short.history._items
    series = PinSeries().series(short.live.sim, items, [3])
    v = series["pin_curvature/node 3 κ1"]
    assert np.isnan(v[:len(old.history._items)]).all() and np.isfinite(v[len(old.history._items):]).all()
