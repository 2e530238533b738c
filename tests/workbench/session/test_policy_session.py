"""Policy mode without a browser: a task episode stepped one sim step at a time, reward terms,
take-over by hand / hand back, rewind of the task state."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.session.core import Workbench


@pytest.fixture
def wb():
    from workbench.session.policy_session import PolicySession

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
    from workbench.session.policy_session import PolicySession

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


def _short_episodes(core, timeout_steps=3):
    import dataclasses

    core.config = dataclasses.replace(core.config, timeout_steps=timeout_steps)


def test_episode_rewards_are_the_task_step_ones(wb):
    """The session's episodes (sim step by sim step, through the workbench and headless) give the observations,
    rewards, reward terms and episode ends of ``BatchedTask.step`` for the same actions, bit for bit; a finished
    episode is reset by the next control step as the task resets it."""
    from workbench.session.policy_session import PolicySession

    ref = PolicySession("follow_target", "zero", seed=3).core
    headless = PolicySession("follow_target", "zero", seed=3)
    wb.start_policy(PolicySession("follow_target", "zero", seed=3))
    sessions = (wb.policy, headless)
    for core in (ref, *(s.core for s in sessions)):
        _short_episodes(core)
    acts = np.random.default_rng(7).uniform(-1, 1, (9, 1, ref.action_dim)).astype(np.float32)
    for s in sessions:
        s._action = iter(acts).__next__
    ret, ends = 0.0, 0
    for t, a in enumerate(acts):
        obs, reward, term, trunc, info = ref.step(a)
        ret += float(reward[0])
        control_steps(wb, 1)
        for _ in range(headless.substeps):
            headless.sim_step()
        for s in sessions:
            assert s.obs.tobytes() == obs.tobytes(), t
            sc = s.scalars
            assert sc["reward"] == reward[0] and sc["return"] == ret, t
            assert sc["r_distance"] == info["reward/distance"][0] and sc["r_bonus"] == info["reward/bonus"][0]
            assert sc["r_failure"] == info["reward/failure"][0] and sc["tip_error"] == info["tip_distance"][0]
            assert sc["episode_step"] == info["episode_step"][0] and s.done == bool(term[0] or trunc[0])
        if term[0] or trunc[0]:
            ends += 1
            ret = 0.0
            ref.reset()
    assert ends == 2  # two whole 4-step episodes, the third begun
    np.testing.assert_array_equal(wb.live.state.node_pos, ref.state.node_pos)
    np.testing.assert_array_equal(wb.policy.core.target.pos, ref.target.pos)


def test_take_over_in_the_middle_of_a_control_step(wb):
    """A take-over after the first sim step of a policy's control step: the rest of the policy's increment is not
    applied, the hand's curvature is held, and that control step still ends and counts."""
    assert wb.policy.substeps == 2
    control_steps(wb, 2)
    wb.step()                                     # the policy's third control step is half done
    assert wb.policy.core.sim_steps_taken == 1
    wb.take_over()
    wb.set_teleop_value(1, 0, -0.8)
    wb.step()                                     # the control step ends under the hand
    core = wb.policy.core
    assert not core.step_in_progress and wb.policy.scalars["episode_step"] == 3
    kappa, _tau = core.converter.natural_values()
    np.testing.assert_allclose(core.ctrl.kappa_bar, kappa + wb.live.rest_ctrl.kappa_bar)
    assert wb.policy.accumulated()[0][1, 0] == pytest.approx(-0.8)
    wb.step()                                     # a hand-driven control step begins without an action ...
    wb.hand_back()
    wb.step()                                     # ... and a hand-back in its middle ends it, adding nothing
    np.testing.assert_allclose(core.ctrl.kappa_bar, kappa + wb.live.rest_ctrl.kappa_bar)
    assert wb.policy.scalars["episode_step"] == 4
    control_steps(wb, 1)
    assert wb.policy.scalars["episode_step"] == 5


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
    from workbench.session.policy_session import PolicySession

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
