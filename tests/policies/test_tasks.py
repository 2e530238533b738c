"""Task envs: gymnasium/SB3 checkers, observation layout, termination and failure rules.

On the real simulator (a few envs, a few steps); the tasks' behaviour over whole episodes is in
test_tasks_sim.py.
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
def test_check_env_and_layout(tid):
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


def test_sb3_check_env():
    from stable_baselines3.common.env_checker import check_env as sb3_check

    for tid in ("rodlab/FollowTarget-v0", "rodlab/IK4D-v0"):
        sb3_check(gym.make(tid).unwrapped, warn=True)


def test_initial_observation_values():
    env = gym.make("rodlab/TightObstacles2D-v0").unwrapped
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(obs[-2:], [0.8, 0.15], atol=1e-7)           # target_pos last
    np.testing.assert_allclose(obs[5 + 18:5 + 20], [0.0, 1.0], atol=1e-6)  # tip (x, z) = last state_pos
    env = gym.make("rodlab/RandomObstacles3D-v0").unwrapped
    obs, _ = env.reset(seed=0)
    fence = obs[10:58].reshape(8, 2, 3)
    np.testing.assert_allclose(np.linalg.norm(fence[:, 1] - fence[:, 0], axis=-1), 1.0, atol=1e-5)
    assert np.all(fence[..., 0] >= 0.3 - 1e-6) and np.all(fence[..., 0] <= 0.6 + 1e-6)


def test_truncation_counts_timeout_plus_one():
    env = policies.make_vec_env("ik4d", 2, seed=0, timeout_steps=3)
    env.reset()
    a = np.zeros((2, 15), np.float32)
    for k in range(4):
        obs, r, term, trunc, info = env.step(a)
        assert not term.any()
        assert trunc.all() == (k == 3)
    assert info["_final_obs"].all() and info["final_obs"][0].shape == (86,)
    assert np.all(env.core.step_count == 0)          # SAME_STEP: already reset


class _SpoilAfterSimStep:
    """A StepObserver that writes NaN into env ``env``'s state after the last sim step of the next control step.

    The simulator has finished that step, so the reward sees the NaN (a reward explosion); a NaN state given to the
    simulator is refused by it instead (``sim_failed``, the other path)."""

    def __init__(self, env: int):
        self.env, self.armed = env, True

    def on_reset(self, core, mask):
        pass

    def on_sim_step(self, core, substep, stats):
        if self.armed and substep == core.config.substeps - 1:
            core.state.dof[self.env] = np.nan
            core.state.dof_vel[self.env] = np.nan
            self.armed = False

    def on_step(self, core, reward, terminated, truncated, info):
        pass


def test_sim_failure_and_explosion():
    venv = policies.make_vec_env("follow_target", 3, seed=0)
    venv.reset()
    core = venv.core
    core.state.dof_vel[1] = np.nan                  # a non-finite state: the simulator fails env 1
    obs, r, term, trunc, info = venv.step(np.zeros((3, 10), np.float32))
    assert term.tolist() == [False, True, False] and r[1] == -10.0
    assert info["failure_reason"][1] == "sim_failed" and info["final_info"]["failure_reason"][1] == "sim_failed"
    assert info["reward/failure"][1] == -10.0 and info["reward/distance"][1] == 0.0
    assert np.isfinite(obs).all()
    # NaN state after the simulator's step -> reward NaN -> terminated with -10 and a sanitised observation
    core.add_observer(_SpoilAfterSimStep(env=2))
    obs, r, term, trunc, info = venv.step(np.zeros((3, 10), np.float32))
    assert term[2] and r[2] == -10.0 and info["failure_reason"][2] == "reward_explosion"
    assert np.isfinite(info["final_obs"][2]).all() and np.isfinite(obs).all()


def test_bad_actions():
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


def test_config_override_and_validation():
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


def _step_in_parts(core, action):
    """A control step as its three public parts (what the workbench does one sim step at a time)."""
    core.begin_step(action)
    for k in range(core.config.substeps):
        assert core.step_in_progress and core.sim_steps_taken == k
        core.sim_step()
    return core.end_step()


def _assert_bitwise(a, b, where):
    names = ("obs", "reward", "terminated", "truncated")
    for name, x, y in zip(names, a[:4], b[:4]):
        assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), f"{where}: {name}"
    assert list(a[4]) == list(b[4]), where
    for k, x in a[4].items():
        y = b[4][k]
        if x.dtype == object:
            assert x.tolist() == y.tolist(), f"{where}: info[{k!r}]"
        else:
            assert x.dtype == y.dtype and x.tobytes() == y.tobytes(), f"{where}: info[{k!r}]"


class _Counter:
    """A StepObserver counting the calls it gets, with the sim step indices."""

    def __init__(self):
        self.resets, self.sim_steps, self.steps = 0, [], 0

    def on_reset(self, core, mask):
        self.resets += 1

    def on_sim_step(self, core, substep, stats):
        self.sim_steps.append(substep)

    def on_step(self, core, reward, terminated, truncated, info):
        self.steps += 1


@pytest.mark.parametrize("task", sorted(TASKS))
def test_step_equals_its_parts_bitwise(task):
    """``step`` and begin_step / sim_step x substeps / end_step give the same observations, rewards, terminations,
    truncations and infos, bit for bit, through truncation, a simulator failure and a reward explosion."""
    cores = [policies.make_vec_env(task, 3, seed=5, timeout_steps=2).core for _ in range(2)]
    counters = [_Counter(), _Counter()]
    spoilers = [_SpoilAfterSimStep(env=2), _SpoilAfterSimStep(env=2)]
    for core, counter, spoil in zip(cores, counters, spoilers):
        core.add_observer(counter)
        core.add_observer(spoil)
        spoil.armed = False
        core.reset()
    acts = np.random.default_rng(1).uniform(-1, 1, (7, 3, cores[0].action_dim)).astype(np.float32)
    for t, a in enumerate(acts):
        for core, spoil in zip(cores, spoilers):
            if t == 2:
                core.state.dof_vel[1] = np.nan            # a non-finite state: the simulator fails env 1
            if t == 4:
                spoil.armed = True                        # env 2: NaN after the sim step -> reward explosion
        whole, parts = cores[0].step(a), _step_in_parts(cores[1], a)
        _assert_bitwise(whole, parts, f"{task} step {t}")
        assert not cores[1].step_in_progress
        if t == 2:
            assert whole[4]["failure_reason"][1] == "sim_failed"
        if t == 4:
            assert whole[4]["failure_reason"][2] == "reward_explosion"
        done = whole[2] | whole[3]
        if done.any():
            for core in cores:
                np.testing.assert_array_equal(core.reset(done), cores[0].observe())
    n = cores[0].config.substeps
    for c in counters:
        assert c.steps == len(acts) and c.sim_steps == list(range(n)) * len(acts)
    assert counters[0].resets == counters[1].resets


def test_step_parts_refuse_the_wrong_order():
    core = policies.make_vec_env("follow_target", 2, seed=0).core
    core.reset()
    a = np.zeros((2, core.action_dim), np.float32)
    with pytest.raises(RuntimeError, match="begin_step first"):
        core.sim_step()
    with pytest.raises(RuntimeError, match="begin_step first"):
        core.end_step()
    with pytest.raises(ValueError, match="shape"):
        core.begin_step(np.zeros((3, core.action_dim)))
    assert not core.step_in_progress                 # a refused action begins nothing
    core.begin_step(a)
    with pytest.raises(RuntimeError, match="during a control step"):
        core.begin_step(a)
    with pytest.raises(RuntimeError, match="during a control step"):
        core.step(a)
    core.sim_step()
    with pytest.raises(RuntimeError, match="after 1 of 2 sim steps"):
        core.end_step()
    core.sim_step()
    with pytest.raises(RuntimeError, match="end_step next"):
        core.sim_step()
    with pytest.raises(RuntimeError, match="reset of some envs"):
        core.reset(np.array([True, False]))
    assert core.step_in_progress
    core.reset()                                      # every env: the unfinished step is dropped
    assert not core.step_in_progress and core.sim_steps_taken == 0
    assert core.step(a)[4]["episode_step"].tolist() == [1, 1]
    with pytest.raises(ValueError, match="needs an action"):
        core.step(None)


def test_a_failed_step_leaves_no_step_in_progress():
    class Boom:
        def on_reset(self, core, mask):
            pass

        def on_sim_step(self, core, substep, stats):
            raise KeyError("observer failed")

        def on_step(self, core, reward, terminated, truncated, info):
            pass

    core = policies.make_vec_env("follow_target", 1, seed=0).core
    core.reset()
    boom = Boom()
    core.add_observer(boom)
    a = np.zeros((1, core.action_dim), np.float32)
    with pytest.raises(KeyError):
        core.step(a)
    assert not core.step_in_progress
    core.remove_observer(boom)
    assert core.step(a)[4]["episode_step"].tolist() == [1]   # the failed step did not count


def test_step_without_action_leaves_the_controls_to_the_caller():
    """begin_step(None) and sim_step(increment=False) (the workbench's hand control): no increment reaches the
    controls, the converter keeps its values, and the control step still ends with a reward and a counted step."""
    core = policies.make_vec_env("follow_target", 2, seed=0).core
    core.reset()
    core.step(np.ones((2, core.action_dim), np.float32))
    K, kappa = core.converter.K.copy(), core.ctrl.kappa_bar.copy()
    core.begin_step(None)
    core.sim_step()
    core.sim_step()
    obs, reward, term, trunc, info = core.end_step()
    np.testing.assert_array_equal(core.converter.K, K)
    np.testing.assert_array_equal(core.ctrl.kappa_bar, kappa)
    assert info["episode_step"].tolist() == [2, 2] and np.isfinite(reward).all()
    core.begin_step(np.ones((2, core.action_dim), np.float32))  # an action whose increment the caller skips
    core.sim_step(increment=False)
    np.testing.assert_array_equal(core.ctrl.kappa_bar, kappa)
    core.sim_step()                                              # the second share reaches the controls
    assert not np.array_equal(core.ctrl.kappa_bar, kappa)
    core.end_step()
