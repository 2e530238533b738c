"""Workbench logic without a browser: teleop modes, snapshots/rewind, history, frames."""
from __future__ import annotations

import numpy as np
import pytest

from sim.geometry import matrix_to_quat as quat_from_matrix
from sim.geometry import quat_z_to
from workbench.session.core import Workbench
from workbench.session.frame import curvature_magnitude
from workbench.session.history import History, Snapshot, held_bytes


@pytest.fixture
def wb():
    return Workbench.builtin()


def run(wb, n):
    for _ in range(n):
        wb.step()


def test_absolute_teleop_writes_converter_natural_values_and_bends(wb):
    tip0 = wb.tip.copy()
    wb.set_teleop_value(2, 0, 1.0)  # kappa1 of the middle control point
    run(wb, 30)
    kappa, tau = wb.teleop.converter.natural_values()
    np.testing.assert_allclose(wb.live.ctrl.kappa_bar[0], kappa[0] + wb.live.rest_ctrl.kappa_bar[0])
    # the owned nodes of control point 2 carry the whole value (weights sum to 1)
    owner = wb.teleop.converter.owner
    assert np.isclose(wb.live.ctrl.kappa_bar[0, owner == 2, 0].sum(), 1.0)
    assert np.linalg.norm((wb.tip - tip0)[:2]) > 0.1


def test_delta_mode_accumulates_like_the_task_converter(wb):
    wb.set_teleop_mode("delta")
    wb.set_teleop_value(0, 1, 1.0)  # kappa2 of control point 0, full action
    steps = 10 * wb.teleop.substeps  # 10 control steps
    run(wb, steps)
    acc = wb.teleop.accumulated()
    assert acc[0, 1] == pytest.approx(10 * 0.05, rel=1e-5)
    assert np.all(acc[1:, :] == 0) and acc[0, 0] == 0
    # switching back to absolute shows the accumulated value on the sliders, control unchanged
    before = wb.live.ctrl.kappa_bar.copy()
    wb.set_teleop_mode("absolute")
    assert wb.teleop.values[0, 1] == pytest.approx(0.5, rel=1e-5)
    wb.step()
    np.testing.assert_allclose(wb.live.ctrl.kappa_bar, before, atol=1e-6)


def test_delta_mode_saturates_at_the_curvature_limit(wb):
    wb.set_teleop_mode("delta")
    wb.set_teleop_value(4, 0, 1.0)
    run(wb, 2 * 45)  # 45 control steps of +0.05 -> clipped at 2
    assert wb.teleop.accumulated()[4, 0] == pytest.approx(2.0)


def test_rewind_restores_state_and_replays_deterministically(wb):
    wb.set_teleop_value(1, 0, 0.8)
    run(wb, 10)
    tip10 = wb.tip.copy()
    wb.set_teleop_value(3, 1, -1.2)
    run(wb, 10)
    tip20 = wb.tip.copy()
    assert not np.allclose(tip10, tip20)
    wb.rewind(10)
    assert wb.frame_index == 10 and not wb.playing
    np.testing.assert_array_equal(wb.tip, tip10)
    assert wb.history.last_index == 10
    # the teleop values of frame 10 are back (second slider not moved yet)
    assert wb.teleop.values[3, 1] == 0.0 and wb.teleop.values[1, 0] == pytest.approx(0.8)
    wb.set_teleop_value(3, 1, -1.2)
    run(wb, 10)
    np.testing.assert_allclose(wb.tip, tip20, atol=1e-12)


def test_rewind_to_a_dropped_frame_is_a_clear_error(wb):
    run(wb, 3)
    with pytest.raises(KeyError, match="frame 99"):
        wb.rewind(99)


def test_reset_clears_history_and_straightens(wb):
    wb.set_teleop_value(2, 0, 1.0)
    run(wb, 20)
    wb.reset()
    assert wb.frame_index == 0 and len(wb.history) == 1
    np.testing.assert_allclose(wb.live.ctrl.kappa_bar, wb.live.rest_ctrl.kappa_bar)
    assert wb.teleop.values.sum() == 0


def test_play_pause_and_advance(wb):
    wb.set_playing(False)
    assert wb.advance() is False and wb.frame_index == 0
    wb.set_playing(True)
    assert wb.advance() is True and wb.frame_index == 1


def test_history_is_bounded_and_keeps_frame_numbers():
    h = History(capacity=5)
    for i in range(12):
        h.append(Snapshot(index=i, time=0.1 * i, sim=(), teleop={}, driver=None, mode="teleop",
                          scalars={"reward": float(i)}))
    assert len(h) == 5 and h.first_index == 7 and h.last_index == 11
    assert h.get(9).index == 9
    with pytest.raises(KeyError):
        h.get(3)
    h.truncate_after(8)
    assert h.last_index == 8
    t, v = h.series("reward")
    assert v == [7.0, 8.0]


def test_frame_has_true_radius_frames_and_curvature(wb):
    wb.set_teleop_value(2, 0, 1.5)
    run(wb, 20)
    fr = wb.frame()
    n = wb.live.n_nodes
    assert fr.node_pos.shape == (n, 3) and fr.rod_radius == pytest.approx(wb.live.rod_radius)
    assert fr.node_curvature.shape == (n,) and fr.node_curvature.max() > 0.05
    assert fr.m1.shape == (n - 1, 3)
    np.testing.assert_allclose(np.linalg.norm(fr.m1, axis=1), 1.0, atol=1e-9)


def test_geometry_helpers():
    # quarter circle of 4 edges: each interior node turns by pi/8 -> |kappa| = 2 tan(pi/16)
    a = np.linspace(0, np.pi / 2, 5)
    x = np.stack([np.sin(a), np.zeros(5), 1 - np.cos(a)], 1)
    k = curvature_magnitude(x)
    np.testing.assert_allclose(k[1:-1], 2 * np.tan(np.pi / 16), rtol=1e-9)
    assert k[0] == 0 and k[-1] == 0
    d = np.array([[1.0, 0, 0], [0, 0, -1], [0, 0, 1], [0.3, -0.4, 0.5]])
    q = quat_z_to(d)
    w, xx, y, z = q.T
    # rotate +z by q and compare with the normalised direction
    rz = np.stack([2 * (xx * z + w * y), 2 * (y * z - w * xx), 1 - 2 * (xx * xx + y * y)], 1)
    np.testing.assert_allclose(rz, d / np.linalg.norm(d, axis=1, keepdims=True), atol=1e-12)
    R = np.diag([-1.0, -1.0, 1.0])
    np.testing.assert_allclose(np.abs(quat_from_matrix(R)), [0, 0, 0, 1], atol=1e-12)


def test_gravity_toggle_keeps_state_and_removes_sag(wb):
    run(wb, 20)
    sag = 1.0 - wb.tip[2]
    assert sag > 1e-4  # self-weight compresses the upright rod (~0.5 mm)
    wb.set_gravity(False)
    run(wb, 60)
    assert 1.0 - wb.tip[2] < 0.2 * sag  # without gravity the rod springs back to its rest length
    wb.set_gravity(True)
    run(wb, 60)
    assert 1.0 - wb.tip[2] == pytest.approx(sag, rel=0.2)


def test_teleop_steers_the_chosen_rod_of_a_two_rod_scene():
    """In a scene of several rods the sliders steer the rod chosen; the rod left keeps its last control, its slider
    values come back when it is chosen again, and a reset or a bad index are handled."""
    from pathlib import Path

    wb = Workbench.builtin()
    wb.load_scene(Path(__file__).resolve().parents[3] / "assets" / "scenes" / "two_rods.toml")
    assert wb.teleop_rods() == ["base", "cross"] and wb.teleop_rod == 0
    n0 = int(wb.live.rod_offsets[1])
    assert wb.teleop.control_nodes() == tuple(int(c) for c in wb.teleop.converter.cfg.control_points)
    rest = wb.live.rest_ctrl.kappa_bar.copy()
    wb.set_teleop_rod(1)
    assert wb.teleop.first_node == n0 and all(c >= n0 for c in wb.teleop.control_nodes())
    wb.set_teleop_value(2, 0, 1.0)
    run(wb, 3)
    kb = np.asarray(wb.live.ctrl.kappa_bar)
    assert np.allclose(kb[:, :n0], rest[:, :n0])  # the first rod is not steered
    moved = np.abs(kb[:, n0:] - rest[:, n0:]).max()
    assert moved > 0.1
    wb.set_teleop_rod(0)  # rod 1 keeps its curvature; rod 0's sliders are its own (zero)
    assert np.allclose(wb.teleop.values, 0.0)
    run(wb, 2)
    assert np.allclose(np.asarray(wb.live.ctrl.kappa_bar)[:, n0:], kb[:, n0:])
    wb.set_teleop_rod(1)
    assert wb.teleop.values[2, 0] == 1.0
    for bad in (2, -1, "1", 1.0, True):
        with pytest.raises(ValueError, match="teleop rod"):
            wb.set_teleop_rod(bad)
    wb.reset()
    assert np.allclose(wb.teleop.values, 0.0)
    wb.set_teleop_rod(0)
    wb.load_scene(Path(__file__).resolve().parents[3] / "assets" / "scenes" / "default.toml")
    assert wb.teleop_rods() == ["rod"]
    assert wb.teleop_rod == 0 and wb.teleop.first_node == 0


def test_history_holds_about_its_byte_budget_and_counts_what_it_dropped():
    big = np.zeros(10_000)  # 80 kB per snapshot
    h = History(capacity=1000, max_bytes=1_000_000)
    for i in range(40):
        h.append(Snapshot(index=i, time=0.1 * i, sim=(big.copy(),), teleop={}, driver=None, mode="teleop",
                          scalars={}))
    assert h.limit == 12 and len(h) == 12  # 1 MB / (80 kB + a little per object)
    assert h.dropped == 28 and h.first_index == 28 and h.last_index == 39
    h.clear()
    assert h.dropped == 0 and len(h) == 0


def test_a_session_history_stays_within_its_budget():
    """A real session's snapshots (state, controls, teleop) are measured, not assumed small."""
    wb = Workbench.builtin()
    wb.history = History(capacity=1000, max_bytes=200_000)
    for _ in range(60):
        wb.step()
    per = held_bytes(wb.history.get(wb.history.last_index))
    assert per > 4_000  # node positions, velocities, frames and controls of the arm
    assert len(wb.history) == wb.history.limit == 200_000 // per
    assert len(wb.history) * per <= 200_000
    assert wb.history.dropped == 60 - len(wb.history)
