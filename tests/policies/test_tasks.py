"""Task envs: gymnasium/SB3 checkers, observation layout, termination and failure rules.

Structure tests run on a kinematic stand-in of the simulator (``fake_sim``); behaviour tests on the
real simulator live in test_tasks_sim.py.
"""
from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import policies
from policies import TASKS

DIMS = {  # id: (obs, action)
    "rodlab/FollowTarget-v0": (76, 10),
    "rodlab/FollowTarget2D-v0": (49, 5),
    "rodlab/IK4D-v0": (86, 15),
    "rodlab/TightObstacles2D-v0": (47, 5),
    "rodlab/RandomObstacles3D-v0": (121, 10),
}


def test_registry():
    assert set(TASKS.values()) == set(DIMS)
    for tid in DIMS:
        assert tid in gym.registry
    with pytest.raises(ValueError, match="unknown task"):
        policies.gym_task_id("nope")


@pytest.mark.parametrize("tid", sorted(DIMS))
def test_check_env_and_layout(fake_sim, tid):
    env = gym.make(tid)
    check_env(env.unwrapped, skip_render_check=True)
    obs_dim, act_dim = DIMS[tid]
    assert env.observation_space.shape == (obs_dim,) and env.observation_space.dtype == np.float32
    assert env.action_space.shape == (act_dim,)
    doc = type(env.unwrapped).__doc__
    for word in ("Observation", "Action", "Reward", "Termination"):
        assert word in doc
    core = env.unwrapped.core
    names = [n for n, _ in core.obs_fields]
    assert names == sorted(names)                      # alphabetical, as the paper's network
    obs, _ = env.reset(seed=3)
    obs2, r, term, trunc, info = env.step(env.action_space.sample())
    assert {"reward/distance", "reward/bonus", "failed", "failure_reason", "tip_distance"} <= set(info)
    parts = [k for k in info if k.startswith("reward/") and k != "reward/failure"]
    assert r == pytest.approx(sum(info[k] for k in parts))
    env.close()


def test_sb3_check_env(fake_sim):
    from stable_baselines3.common.env_checker import check_env as sb3_check

    for tid in ("rodlab/FollowTarget-v0", "rodlab/IK4D-v0"):
        sb3_check(gym.make(tid).unwrapped, warn=True)


def test_initial_observation_values(fake_sim):
    env = gym.make("rodlab/TightObstacles2D-v0").unwrapped
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(obs[-2:], [0.8, 0.15], atol=1e-7)           # target_pos last
    np.testing.assert_allclose(obs[5 + 18:5 + 20], [0.0, 1.0], atol=1e-6)  # tip (x, z) = last state_pos
    env = gym.make("rodlab/RandomObstacles3D-v0").unwrapped
    obs, _ = env.reset(seed=0)
    fence = obs[10:58].reshape(8, 2, 3)
    np.testing.assert_allclose(np.linalg.norm(fence[:, 1] - fence[:, 0], axis=-1), 1.0, atol=1e-5)
    assert np.all(fence[..., 0] >= 0.3 - 1e-6) and np.all(fence[..., 0] <= 0.6 + 1e-6)


def test_truncation_counts_timeout_plus_one(fake_sim):
    env = policies.make_vec_env("ik4d", 2, seed=0, timeout_steps=3)
    env.reset()
    a = np.zeros((2, 15), np.float32)
    for k in range(4):
        obs, r, term, trunc, info = env.step(a)
        assert not term.any()
        assert trunc.all() == (k == 3)
    assert info["_final_obs"].all() and info["final_obs"][0].shape == (86,)
    assert np.all(env.core.step_count == 0)          # SAME_STEP: already reset


def test_sim_failure_and_explosion(fake_sim):
    venv = policies.make_vec_env("follow_target", 3, seed=0)
    venv.reset()
    core = venv.core
    core.ctrl.kappa_bar[1, 5, 0] = 100.0            # the stand-in simulator fails env 1
    obs, r, term, trunc, info = venv.step(np.zeros((3, 10), np.float32))
    assert term.tolist() == [False, True, False] and r[1] == -10.0
    assert info["failure_reason"][1] == "sim_failed" and info["final_info"]["failure_reason"][1] == "sim_failed"
    assert info["reward/failure"][1] == -10.0 and info["reward/distance"][1] == 0.0
    assert np.isfinite(obs).all()
    # NaN state -> reward NaN -> terminated with -10 and a sanitised observation
    core.state.dof[2] = np.nan
    core.state.dof_vel[2] = np.nan
    obs, r, term, trunc, info = venv.step(np.zeros((3, 10), np.float32))
    assert term[2] and r[2] == -10.0 and info["failure_reason"][2] == "reward_explosion"
    assert np.isfinite(info["final_obs"][2]).all() and np.isfinite(obs).all()


def test_bad_actions(fake_sim):
    env = gym.make("rodlab/FollowTarget-v0").unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(5))
    with pytest.raises(ValueError, match="NaN"):
        env.step(np.full(10, np.nan))
    venv = policies.make_vec_env("follow_target", 2, seed=0)
    venv.reset()
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros((3, 10)))


def test_config_override_and_validation(fake_sim):
    from policies.tasks.follow_target import default_config

    cfg = dataclasses.replace(default_config(), smoothing="reference", target_speed=0.2)
    venv = policies.make_vec_env("follow_target", 2, seed=0, config=cfg)
    assert venv.core.converter.cfg.smoothing == "reference"
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.target_speed = 1.0  # type: ignore[misc]
    with pytest.raises(ValueError, match="target_lo"):
        policies.make_vec_env("follow_target", 1, target_lo=(0, 0))
    with pytest.raises(ValueError, match="smoothing"):
        policies.make_vec_env("follow_target", 1, smoothing="bogus")
