"""Policy mode without a browser: a task episode stepped one sim step at a time, reward terms,
take-over by hand / hand back, rewind of the task state."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.core import Workbench


@pytest.fixture
def wb():
    from workbench.policy_session import PolicySession

    w = Workbench.builtin()
    w.start_policy(PolicySession("follow_target", "random", seed=3))
    return w


def control_steps(wb, n):
    for _ in range(n * wb.policy.substeps):
        wb.step()


def test_policy_episode_advances_with_reward_terms(wb):
    assert wb.mode == "policy"
    control_steps(wb, 4)
    sc = wb.policy.scalars
    assert sc["episode_step"] == 4
    assert sc["reward"] == pytest.approx(sc["r_distance"] + sc["r_bonus"])
    assert sc["tip_error"] > 0 and np.isfinite(sc["return"])
    fr = wb.frame()
    assert fr.targets.shape == (1, 3)  # the moving target is drawn
    assert fr.scalars["reward"] == sc["reward"]


def test_sim_steps_match_the_task_step(wb):
    """Stepping sim step by sim step gives the same rod as the task's own control step."""
    from workbench.policy_session import PolicySession

    ref = PolicySession("follow_target", "zero", seed=3)
    wb.start_policy(PolicySession("follow_target", "zero", seed=3))
    a = np.zeros((1, ref.core.action_dim), np.float32)
    a[0, 2] = 1.0
    wb.policy._action = lambda: a.copy()
    control_steps(wb, 3)
    for _ in range(3):
        ref.core.step(a)
    np.testing.assert_allclose(wb.live.state.node_pos, ref.core.state.node_pos, atol=1e-12)
    np.testing.assert_allclose(wb.policy.core.target.pos, ref.core.target.pos)


def test_take_over_and_hand_back(wb):
    control_steps(wb, 3)
    K, _T = wb.policy.accumulated()
    wb.take_over()
    assert wb.hand_control and wb.teleop.mode == "absolute"
    np.testing.assert_allclose(wb.teleop.values[:, :2], K, atol=1e-6)  # sliders start where the policy was
    wb.set_teleop_value(2, 0, 1.5)
    control_steps(wb, 2)
    assert wb.policy.accumulated()[0][2, 0] == pytest.approx(1.5)  # the task sees the hand's curvature
    assert wb.policy.scalars["episode_step"] == 5  # the episode went on
    wb.hand_back()
    control_steps(wb, 1)
    assert not wb.hand_control and wb.policy.scalars["episode_step"] == 6


def test_rewind_restores_task_state(wb):
    control_steps(wb, 2)
    idx = wb.frame_index
    tgt = wb.policy.core.target.pos.copy()
    tip = wb.tip.copy()
    control_steps(wb, 5)
    assert not np.allclose(wb.policy.core.target.pos, tgt)
    wb.rewind(idx)
    np.testing.assert_array_equal(wb.policy.core.target.pos, tgt)
    np.testing.assert_array_equal(wb.tip, tip)
    assert wb.policy.scalars["episode_step"] == 2
    control_steps(wb, 1)
    assert wb.policy.scalars["episode_step"] == 3


def test_stop_policy_returns_to_teleop_scene(wb):
    wb.stop_policy()
    assert wb.mode == "teleop" and wb.policy is None
    wb.step()


def test_random_fence_is_drawn_and_restored_by_rewind():
    from workbench.policy_session import PolicySession

    wb = Workbench.builtin()
    wb.start_policy(PolicySession("random_obstacles_3d", "zero", seed=1))

    def mids():
        return np.array([e.position for e in wb.obstacles])

    fence0 = wb.policy.core.fences[0].astype(np.float64).mean(axis=1)
    assert len(wb.obstacles) == 8 and all(e.kind == "capsule" for e in wb.obstacles)
    np.testing.assert_allclose(mids(), fence0, atol=1e-6)
    control_steps(wb, 1)
    idx = wb.frame_index
    wb.policy.done = True  # end the episode: the next control step starts a new one with a new fence
    control_steps(wb, 1)
    assert not np.allclose(mids(), fence0, atol=1e-3)
    wb.rewind(idx)
    np.testing.assert_allclose(mids(), fence0, atol=1e-6)
    np.testing.assert_allclose(wb.policy.core.fences[0].mean(axis=1), fence0, atol=1e-6)
