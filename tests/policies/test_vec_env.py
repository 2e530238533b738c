"""BatchedVecEnv / SB3 adapter: batch == singles (bitwise), seeding, SAME_STEP autoreset, SB3 checks."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import policies
from policies import SB3VecEnvAdapter, make_vec_env


def _batch_vs_single(tid, B, steps, seed=11, **kw):
    venv = make_vec_env(tid, B, seed=seed, **kw)
    obs_b, _ = venv.reset()
    rng = np.random.default_rng(0)
    acts = rng.uniform(-1, 1, (steps, B) + venv.single_action_space.shape).astype(np.float32)
    traj_b = [obs_b]
    rew_b = []
    for t in range(steps):
        o, r, te, tr, info = venv.step(acts[t])
        traj_b.append(o)
        rew_b.append(r)
    for i in range(B):
        env = gym.make(tid, **kw).unwrapped
        o, _ = env.reset(seed=seed, options={"env_index": i})
        np.testing.assert_array_equal(o, traj_b[0][i])
        for t in range(steps):
            o, r, te, tr, info = env.step(acts[t, i])
            if te or tr:
                o, _ = env.reset()
            np.testing.assert_array_equal(o, traj_b[t + 1][i], err_msg=f"{tid} env {i} step {t}")
            assert r == rew_b[t][i]


@pytest.mark.parametrize("tid", ["rodlab/FollowTarget-v0", "rodlab/RandomObstacles3D-v0"])
def test_batch_equals_singles_fake(fake_sim, tid):
    _batch_vs_single(tid, 3, 7, timeout_steps=3)           # crosses two autoresets


def test_seeding_determinism(fake_sim):
    a = make_vec_env("ik4d", 3, seed=5)
    b = make_vec_env("ik4d", 3, seed=5)
    c = make_vec_env("ik4d", 3, seed=6)
    oa, ob, oc = a.reset()[0], b.reset()[0], c.reset()[0]
    np.testing.assert_array_equal(oa, ob)
    assert not np.array_equal(oa, oc)
    np.testing.assert_array_equal(a.reset(seed=6)[0], oc)
    # list seeds: env i == single env seeded s_i (child 0)
    o, _ = a.reset(seed=[4, 5, 6])
    single = gym.make("rodlab/IK4D-v0").unwrapped
    np.testing.assert_array_equal(single.reset(seed=5)[0], o[1])
    # SeedSequence scheme: spawn(B)[i] == SeedSequence(seed, spawn_key=(i,))
    ss = np.random.SeedSequence(9).spawn(3)[2]
    assert ss.spawn_key == (2,) and ss.entropy == 9


def test_reset_mask_and_infos(fake_sim):
    venv = make_vec_env("follow_target_2d", 4, seed=0)
    obs, _ = venv.reset()
    for _ in range(3):
        obs, *_ = venv.step(np.ones((4, 5), np.float32))
    before = obs.copy()
    obs2, _ = venv.reset(options={"reset_mask": np.array([True, False, False, False])})
    np.testing.assert_array_equal(obs2[1:], before[1:])
    assert np.all(obs2[0, :5] == 0) and venv.core.step_count.tolist() == [0, 3, 3, 3]
    assert venv.metadata["autoreset_mode"] == gym.vector.AutoresetMode.SAME_STEP
    assert venv.observation_space.shape == (4, 49) and venv.action_space.shape == (4, 5)


def test_gym_make_vec(fake_sim):
    venv = gym.make_vec("rodlab/FollowTarget-v0", num_envs=3, seed=1)
    assert isinstance(venv.unwrapped, policies.BatchedVecEnv) and venv.num_envs == 3
    obs, _ = venv.reset()
    assert obs.shape == (3, 76)


def test_sb3_adapter(fake_sim):
    from stable_baselines3.common.vec_env import VecCheckNan, VecMonitor

    venv = make_vec_env("follow_target", 4, seed=0, timeout_steps=4)
    env = VecCheckNan(VecMonitor(SB3VecEnvAdapter(venv)), raise_exception=True)
    env.seed(3)
    obs = env.reset()
    assert obs.shape == (4, 76) and obs.dtype == np.float32
    np.testing.assert_array_equal(obs, make_vec_env("follow_target", 4, seed=3).reset()[0])
    for t in range(5):
        obs, rew, done, infos = env.step(np.zeros((4, 10), np.float32))
        assert rew.shape == (4,) and done.shape == (4,) and len(infos) == 4
    assert done.all()
    for info in infos:
        assert info["TimeLimit.truncated"] is True and info["terminal_observation"].shape == (76,)
        assert "episode" in info and info["episode"]["l"] == 5
    assert env.get_attr("num_envs") == [4] * 4
    assert env.env_is_wrapped(gym.Wrapper) == [False] * 4


def test_sb3_sac_smoke(fake_sim):
    from stable_baselines3 import SAC

    env = SB3VecEnvAdapter(make_vec_env("follow_target_2d", 2, seed=0, timeout_steps=10))
    model = SAC("MlpPolicy", env, learning_starts=10, batch_size=16, buffer_size=200,
                policy_kwargs={"net_arch": [16]}, seed=0, device="cpu")
    model.learn(total_timesteps=40)


def test_bench_env_cli(fake_sim, capsys):
    import json

    from policies.cli import bench_env_main

    assert bench_env_main(["--task", "ik4d", "--envs", "3", "--steps", "2", "--warmup", "0", "--json"]) == 0
    res = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert res["envs"] == 3 and res["ms_per_env_step_median"] > 0 and res["task"] == "rodlab/IK4D-v0"
    assert bench_env_main(["--task", "nope", "--envs", "3"]) == 2


def test_sb3_adapter_keeps_the_reward_terms_of_each_step(fake_sim):
    """The training env (``make_sb3_env``) carries the core's ``reward/<term>`` arrays of the latest step through
    its reward-terms observer, the same values the batched env's info holds (including a finished episode)."""
    from policies.train import make_sb3_env

    env = make_sb3_env("follow_target", 3, seed=4)
    twin = make_vec_env("follow_target", 3, seed=4)
    assert env.reward_terms.latest == {}
    env.reset()
    twin.reset()
    acts = np.random.default_rng(2).uniform(-1, 1, (3, 3, 10)).astype(np.float32)
    for t, a in enumerate(acts):
        if t == 1:
            for core in (env.venv.core, twin.core):
                core.ctrl.kappa_bar[1, 5, 0] = 100.0  # the stand-in simulator fails env 1: a done env
        _, rew, done, _ = env.step(a)
        _, r, term, _, info = twin.step(a)
        want = {k: v for k, v in info.items() if k.startswith("reward/")}
        got = env.reward_terms.latest
        assert sorted(got) == sorted(want) == ["reward/bonus", "reward/distance", "reward/failure"]
        for k in want:
            assert got[k].tobytes() == want[k].tobytes(), (t, k)
        np.testing.assert_allclose(sum(got.values()), rew, rtol=1e-6)  # the terms add up to the reward
        if t == 1:
            assert done[1] and got["reward/failure"][1] == -10.0
