"""Task envs on the real simulator: checkers, batch == singles bitwise, first rewards, failures,
and each task being solvable in principle (a scripted controller beats random actions)."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from policies import make_vec_env
from policies.tasks.scripted import arc_controller

ALL = ["rodlab/FollowTarget-v0", "rodlab/FollowTarget2D-v0", "rodlab/IK4D-v0", "rodlab/TightObstacles2D-v0",
       "rodlab/RandomObstacles3D-v0"]


@pytest.mark.parametrize("tid", ALL)
def test_check_env_real(tid):
    env = gym.make(tid)
    check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize("tid,B,steps,timeout", [
    ("rodlab/FollowTarget-v0", 3, 6, 3), ("rodlab/FollowTarget2D-v0", 3, 6, 3), ("rodlab/IK4D-v0", 3, 6, 3),
    ("rodlab/TightObstacles2D-v0", 2, 3, 1), ("rodlab/RandomObstacles3D-v0", 2, 3, 1)])
def test_batch_equals_singles_real(tid, B, steps, timeout):
    venv = make_vec_env(tid, B, seed=21, timeout_steps=timeout)
    traj = [venv.reset()[0]]
    rews = []
    acts = np.random.default_rng(0).uniform(-1, 1, (steps, B) + venv.single_action_space.shape).astype(np.float32)
    for t in range(steps):
        o, r, *_ = venv.step(acts[t])
        traj.append(o)
        rews.append(r)
    for i in range(B):
        env = gym.make(tid, timeout_steps=timeout).unwrapped
        o, _ = env.reset(seed=21, options={"env_index": i})
        np.testing.assert_array_equal(o, traj[0][i])
        for t in range(steps):
            o, r, te, tr, _ = env.step(acts[t, i])
            if te or tr:
                o, _ = env.reset()
            np.testing.assert_array_equal(o, traj[t + 1][i], err_msg=f"env {i} step {t}")
            assert r == rews[t][i]


def test_determinism_by_seed():
    a = make_vec_env("ik4d", 2, seed=3)
    b = make_vec_env("ik4d", 2, seed=3)
    a.reset()
    b.reset()
    act = np.random.default_rng(1).uniform(-1, 1, (5, 2, 15)).astype(np.float32)
    for t in range(5):
        oa, ra, *_ = a.step(act[t])
        ob, rb, *_ = b.step(act[t])
    np.testing.assert_array_equal(oa, ob)
    np.testing.assert_array_equal(ra, rb)


def test_first_rewards_match_reference():
    for task, expect in (("tight_obstacles_2d", -1.36), ("random_obstacles_3d", -1.06)):
        venv = make_vec_env(task, 2, seed=0)
        obs, _ = venv.reset()
        _, r, te, tr, info = venv.step(np.zeros((2,) + venv.single_action_space.shape, np.float32))
        assert r == pytest.approx([expect, expect], abs=0.01)
        assert not te.any() and not tr.any()
    venv = make_vec_env("follow_target", 1, seed=0)
    obs, _ = venv.reset()
    np.testing.assert_allclose(obs[0, 10 + 27:10 + 30], [0, 0, 1.0], atol=2e-3)   # tip ~ (0, 0, 1)
    venv = make_vec_env("ik4d", 1, seed=0)
    obs, _ = venv.reset()
    np.testing.assert_allclose(np.abs(obs[0, -4:]), [0, 0, 1, 0], atol=1e-3)        # yaw pi


def test_real_sim_failure_ends_episode():
    venv = make_vec_env("follow_target", 3, seed=0)
    venv.reset()
    venv.core.ctrl.kappa_bar[1, 2:19, 0] = 500.0      # impossible natural curvature: solver gives up
    obs, r, te, tr, info = venv.step(np.zeros((3, 10), np.float32))
    assert te.tolist() == [False, True, False] and r[1] == -10.0
    assert info["failure_reason"][1] == "sim_failed" and np.isfinite(obs).all()
    assert np.isfinite(info["final_obs"][1]).all()
    assert venv.core.step_count[1] == 0 and not venv.core.state.failed[1]   # autoreset cleared it


def test_reference_smoothing_changes_dynamics():
    outs = []
    for sm in ("intended", "reference"):
        venv = make_vec_env("follow_target_2d", 1, seed=0, smoothing=sm)
        venv.reset()
        for _ in range(5):
            o, *_ = venv.step(np.ones((1, 5), np.float32))
        outs.append(o[0])
    tip_i, tip_r = outs[0][5 + 18:5 + 20], outs[1][5 + 18:5 + 20]
    assert tip_i[0] < tip_r[0] < 0.0            # both bend toward -x; the reference mapping bends less
    np.testing.assert_array_equal(outs[0][:5], outs[1][:5])   # same K


@pytest.mark.parametrize("task,margin", [("follow_target", 0.3), ("ik4d", 0.3)])
def test_scripted_controller_beats_random(task, margin):
    B, steps = 6, 60
    means = {}
    for mode in ("random", "scripted"):
        venv = make_vec_env(task, B, seed=4, timeout_steps=steps)
        venv.reset()
        rng = np.random.default_rng(0)
        total = np.zeros(B)
        for _ in range(steps):
            if mode == "random":
                a = rng.uniform(-1, 1, (B,) + venv.single_action_space.shape).astype(np.float32)
            else:
                a = arc_controller(venv.core)
            _, r, te, _, _ = venv.step(a)
            assert not te.any()
            total += r
        means[mode] = total.mean() / steps
    assert means["scripted"] > means["random"] + margin, means


def test_sb3_checks_real():
    from stable_baselines3.common.env_checker import check_env as sb3_check
    from stable_baselines3.common.vec_env import VecCheckNan

    from policies import SB3VecEnvAdapter

    sb3_check(gym.make("rodlab/RandomObstacles3D-v0").unwrapped, warn=True)
    env = VecCheckNan(SB3VecEnvAdapter(make_vec_env("tight_obstacles_2d", 2, seed=0, timeout_steps=1)),
                      raise_exception=True)
    env.reset()
    for _ in range(2):
        obs, rew, done, infos = env.step(np.ones((2, 5), np.float32))
    assert done.all() and all(i["TimeLimit.truncated"] for i in infos)


def test_fences_reach_the_simulator_and_start_contact_free():
    venv = make_vec_env("random_obstacles_3d", 3, seed=2, timeout_steps=0)
    obs, _ = venv.reset()
    for _ in range(2):                                   # every step ends an episode -> autoreset re-samples
        fences = obs[:, 10:58].reshape(3, 8, 2, 3)
        ob = venv.core.sim.contact_data(venv.core.state)  # the world arrays the kernels read
        np.testing.assert_allclose(ob.p0, fences[:, :, 0], atol=1e-6)
        np.testing.assert_allclose(ob.p1, fences[:, :, 1], atol=1e-6)
        assert np.allclose(venv.core.state.obstacle_radius, 0.03)
        core = venv.core
        core.converter.apply(core.ctrl, core.converter.convert(np.zeros((3, 10))), 0)
        stats = core.sim.step(core.state, core.ctrl)          # zero action from rest: no contact
        assert np.all(stats.contact_count == 0) and not stats.failed.any()
        obs, *_ = venv.step(np.zeros((3, 10), np.float32))
    assert not np.array_equal(obs[:, 10:58], fences.reshape(3, -1))


@pytest.mark.parametrize("tid", ALL)
def test_tasks_have_no_friction(tid):
    """The paper's tasks are frictionless (docs/tasks.md: contact k 1e6, δ 5e-3 m, μ 0): the friction law and its
    Newton schedule (docs/physics.md §4.6) do not enter their dynamics, so changing them leaves learning curves
    alone."""
    venv = make_vec_env(tid, 1, seed=0)
    prm = venv.core.sim.kernel_params[0]
    assert not bool(prm["friction_on"]) and float(prm["friction"]) == 0.0
