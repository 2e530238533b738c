"""The hand (workbench.session.pull): which nodes it holds, a pull that stays stable whatever the step, the tip moved in the
pulled direction and springing back after release, in teleop and under a running policy."""
from __future__ import annotations

import numpy as np
import pytest

from sim.support.assets import asset_path
from workbench.session import pull
from workbench.session.core import Workbench
from workbench.session.policy_session import PolicySession
from workbench.session.simbridge import ActionRefused


def test_held_nodes_stay_on_the_grabbed_rod():
    np.testing.assert_array_equal(pull.held_nodes(0, 21), [0, 1, 2])
    np.testing.assert_array_equal(pull.held_nodes(10, 21), [8, 9, 10, 11, 12])
    offsets = np.array([0, 11, 21])
    np.testing.assert_array_equal(pull.held_nodes(11, 21, offsets), [11, 12, 13])
    np.testing.assert_array_equal(pull.held_nodes(10, 21, offsets), [8, 9, 10])


@pytest.mark.parametrize("value", [(1.0, np.nan, 0.0), (1.0, 2.0), "abc", (0.0, 0.0, 1e3)])
def test_a_point_that_is_no_place_is_refused(value):
    with pytest.raises(ValueError, match="hand"):
        pull.point(value, "hand")


def test_a_node_alone_settles_on_the_hand_for_any_step():
    """The least stable case (no elastic neighbours): a free mass pulled by the explicit spring settles on the
    hand within a few steps for any mass and step (error contracts by ≈ √(1 − β) per step)."""
    for h, m in ((1e-4, 1e-3), (0.05, 0.2), (0.5, 50.0)):
        p = pull.Pull(node=0, nodes=np.array([0]), offsets=np.zeros((1, 3)), pointer=np.array([0.3, 0.0, 0.0]))
        x, v = np.zeros((1, 3)), np.zeros((1, 3))
        errs = []
        for _ in range(30):
            F = pull.spring_forces(p, x, v, np.array([m]), h)
            v = v + h * F / m  # backward Euler of a free mass under a force held over the step
            x = x + h * v
            errs.append(np.linalg.norm(x[0] - p.pointer))
        assert errs[-1] < 1e-6 * 0.3 and max(errs) < 0.3 * 1.5


def test_pull_moves_the_tip_toward_the_hand_and_it_springs_back():
    wb = Workbench.builtin()
    for _ in range(20):
        wb.step()
    tip0 = wb.tip
    assert wb.grab(tip0 + [0.0, 0.0, 0.01]) == wb.live.n_nodes - 1
    wb.move_hand(tip0 + [0.3, 0.0, 0.01])
    for _ in range(60):
        wb.step()
    moved = wb.tip - tip0
    assert 0.1 < moved[0] < 0.3 and abs(moved[1]) < 1e-9  # toward the hand, short of it (the arm resists)
    fr = wb.frame()
    np.testing.assert_allclose(fr.hand[1], tip0 + [0.3, 0.0, 0.01])
    # the hand holds the pressed point (1 cm above the tip): the spring is drawn from there
    np.testing.assert_allclose(fr.hand[0], wb.tip + [0.0, 0.0, 0.01], atol=1e-12)
    # at rest the spring's force is the arm's resistance: k Σ m_j (p + o_j − x_j) / h² with k = α
    assert fr.hand_force[0] > 1.0 and np.all(np.isfinite(fr.hand_force))
    assert wb.live.last_stats.converged.all()
    wb.release()
    for _ in range(200):
        wb.step()
    assert np.linalg.norm(wb.tip - tip0) < 2e-3
    assert wb.live.ctrl.force is None and wb.frame().hand is None


def test_a_running_policy_feels_the_pull_and_a_recording_cannot_be_pulled():
    wb = Workbench.builtin()
    wb.start_policy(PolicySession("follow_target", "zero", seed=3))
    for _ in range(4):
        wb.step()
    tip0 = wb.tip
    wb.grab(tip0)
    wb.move_hand(tip0 + [0.0, 0.3, 0.0])
    for _ in range(40):
        wb.step()
    assert wb.tip[1] - tip0[1] > 0.05
    wb.stop_policy()
    assert wb.pull is None  # the hand lets go when the rod it held changes


def test_grab_is_refused_in_replay():
    wb = Workbench.builtin()
    wb.mode = "replay"
    with pytest.raises(ActionRefused, match="recording cannot be pulled"):
        wb.grab((0.0, 0.0, 1.0))


def test_a_control_point_moved_by_hand_holds_there_at_equilibrium():
    """Dragging a control point's bead (Workbench.reach_to with its node): the sliders become the curvature that
    holds that node at the target, and the live rod settles there."""
    wb = Workbench.builtin()
    node = wb.teleop.control_nodes()[2]
    x0 = np.asarray(wb.live.state.node_pos[0, node], dtype=np.float64).copy()
    target = x0 + [0.08, 0.04, -0.02]
    for _ in range(6):  # a drag sends several moves; each call goes a few iterations further
        err = wb.reach_to(target, node=node)
    assert err < 1e-3
    assert np.abs(wb.teleop.values[:, :2]).max() > 0.05  # the sliders moved
    for _ in range(400):
        wb.step()
    assert np.linalg.norm(wb.live.state.node_pos[0, node] - target) < 3e-3


def test_a_pulled_env_of_the_grid_moves_and_the_others_do_not():
    from workbench.session.grid import GridSession

    g = GridSession("follow_target", "zero", n=3, centred=True)
    g.step()
    t0 = np.asarray(g.core.state.node_pos[:, -1]).copy()
    tip_page = t0[1] + g.offsets[1]
    assert g.grab(1, tip_page) == g.n_nodes - 1
    g.move_hand(tip_page + [0.3, 0.0, 0.0])
    np.testing.assert_allclose(g.hand()[1], tip_page + [0.3, 0.0, 0.0])
    for _ in range(30):
        g.step()
    moved = np.asarray(g.core.state.node_pos[:, -1]) - t0
    assert moved[1, 0] > 0.05 and np.abs(moved[[0, 2]]).max() < 1e-4  # a zero policy: the others stay (settling)
    np.testing.assert_array_equal(moved[0], moved[2])  # and alike: nothing of the pull reached them
    assert g.core.ctrl.force is not None and not g.core.ctrl.force[[0, 2]].any()
    g.release()
    for _ in range(60):
        g.step()
    assert g.core.ctrl.force is None and g.hand() is None
    assert np.abs(np.asarray(g.core.state.node_pos[1, -1]) - t0[1]).max() < 2e-3
    with pytest.raises(ValueError, match="env must be an index"):
        g.grab(3, tip_page)


def test_reach_with_a_target_frame_turns_the_tip_there_with_the_twist():
    """Reach frame (Workbench.reach_to with an orientation): the bending and twist sliders become what holds the tip
    at a pose the arm can take (made by holding known curvature and twist), and the live arm settles in it; 2-D
    scenes and a non-rotation are refused by name."""
    wb = Workbench.builtin()
    wb.teleop.set_mode("absolute")
    wb.teleop.values[:, :2] = [[0.3, -0.2], [0.2, 0.4], [-0.3, 0.1], [0.1, 0.2], [0.2, -0.1]]
    wb.teleop.values[:, 2] = [0.3, -0.2, 0.4, 0.1, -0.3]
    for _ in range(400):
        wb.step()
    pose, frame = wb.tip.copy(), wb.tip_frame.copy()
    wb.teleop.values[:] = 0.0
    for _ in range(8):  # a drag sends several moves; each call goes a few iterations further
        err = wb.reach_to(pose, orientation=frame)
    assert err < 1e-3 and wb.reach_angle < 1e-2, (err, wb.reach_angle)
    assert np.abs(wb.teleop.values[:, 2]).max() > 0.05  # the twist sliders moved
    for _ in range(400):
        wb.step()
    assert np.linalg.norm(wb.tip - pose) < 3e-3
    cos = (np.trace(wb.tip_frame.T @ frame) - 1.0) / 2.0
    assert np.degrees(np.arccos(min(1.0, cos))) < 2.0
    wb.reach_to(pose)  # without a frame again: the twist sliders go back to 0
    assert not wb.teleop.values[:, 2].any() and np.isnan(wb.reach_angle)
    with pytest.raises(ValueError, match="must be a rotation"):
        wb.reach_to(pose, orientation=2.0 * np.eye(3))
    with pytest.raises(ValueError, match="node must be the tip"):
        wb.reach_to(pose, node=3, orientation=np.eye(3))
    flat = Workbench.builtin()
    flat.load_scene(asset_path("scenes/arm_2d.toml"))
    assert flat.tip_frame is None
    with pytest.raises(ValueError, match="a 2-D scene has no tip frame"):
        flat.reach_to(flat.tip, orientation=np.eye(3))
