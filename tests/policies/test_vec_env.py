"""BatchedVecEnv / SB3 adapter: batch == singles (bitwise), seeding, SAME_STEP autoreset, SB3 checks; wrong
override types and missing scene files give clear errors; the paper's arm comes from the shipped scene file only
(no scene built in code)."""
from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import policies
from policies import SB3VecEnvAdapter, make_vec_env
from sim.scene.spec import SceneError


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
def test_batch_equals_singles(tid):
    _batch_vs_single(tid, 3, 7, timeout_steps=3)           # crosses two autoresets


def test_seeding_determinism():
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


def test_reset_mask_and_infos():
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


def test_gym_make_vec():
    venv = gym.make_vec("rodlab/FollowTarget-v0", num_envs=3, seed=1)
    assert isinstance(venv.unwrapped, policies.BatchedVecEnv) and venv.num_envs == 3
    obs, _ = venv.reset()
    assert obs.shape == (3, 76)


def test_sb3_adapter():
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


def test_sb3_sac_smoke():
    from stable_baselines3 import SAC

    env = SB3VecEnvAdapter(make_vec_env("follow_target_2d", 2, seed=0, timeout_steps=10))
    model = SAC("MlpPolicy", env, learning_starts=10, batch_size=16, buffer_size=200,
                policy_kwargs={"net_arch": [16]}, seed=0, device="cpu")
    model.learn(total_timesteps=40)


def test_bench_env_cli(capsys):
    import json

    from policies.cli import bench_env_main

    assert bench_env_main(["--task", "ik4d", "--envs", "3", "--steps", "2", "--warmup", "0", "--json"]) == 0
    res = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert res["envs"] == 3 and res["ms_per_env_step_median"] > 0 and res["task"] == "rodlab/IK4D-v0"
    assert bench_env_main(["--task", "nope", "--envs", "3"]) == 2


def test_sb3_adapter_keeps_the_reward_terms_of_each_step():
    """The training env (``make_sb3_env``) carries the core's ``reward/<term>`` arrays of the latest step through
    its reward-terms observer, the same values the batched env's info holds (including a finished episode)."""
    from policies.learning.training import make_sb3_env

    env = make_sb3_env("follow_target", 3, seed=4)
    twin = make_vec_env("follow_target", 3, seed=4)
    assert env.reward_terms.latest == {}
    env.reset()
    twin.reset()
    acts = np.random.default_rng(2).uniform(-1, 1, (3, 3, 10)).astype(np.float32)
    for t, a in enumerate(acts):
        if t == 1:
            for core in (env.venv.core, twin.core):
                core.state.dof_vel[1] = np.nan  # a non-finite state: the simulator fails env 1, a done env
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



@pytest.mark.parametrize("kw, match", [
    ({"dt": "0.05"}, r"dt: expected a finite number, got str '0.05'"),
    ({"dt": float("nan")}, r"dt: expected a finite number"),
    ({"newton_max_iter": 2.5}, r"newton_max_iter: expected an integer, got float 2.5"),
    ({"substeps": True}, r"substeps: expected an integer"),
    ({"smoothing": 3}, r"smoothing: expected a string"),
    ({"scene": 1}, r"scene: expected a string"),
    ({"no_such_field": 1}, r"has no field 'no_such_field'"),
    ({"substeps": 2 ** 62}, r"substeps: must be within \[1, 1000\]"),   # found by the fuzz: a hang
])
def test_bad_overrides_name_the_field(kw, match):
    with pytest.raises(ValueError, match=match):
        make_vec_env("follow_target", 2, **kw)


@pytest.mark.parametrize("num_envs, seed", [("2", None), (0, None), (2.0, None), (2, "1"), (2, 1.5)])
def test_bad_num_envs_or_seed(num_envs, seed):
    with pytest.raises(ValueError, match="num_envs|seed"):
        make_vec_env("follow_target", num_envs, seed=seed)


def test_missing_scene_file_is_an_error_not_a_fallback(tmp_path):
    missing = str(tmp_path / "nonexistent.toml")
    with pytest.raises(SceneError, match=r"nonexistent\.toml: file not found"):
        make_vec_env("follow_target", 1, scene=missing)


def test_the_arm_comes_from_the_shipped_file_and_scene_none_means_it():
    import policies.tasks.scenes as scenes

    assert not hasattr(scenes, "_arm_scene_in_code")
    a = make_vec_env("follow_target", 1, seed=0)
    b = make_vec_env("follow_target", 1, seed=0, scene=None)
    assert a.core.model.spec.path.endswith("assets/scenes/arm.toml")
    assert b.core.model.spec.path == a.core.model.spec.path
    np.testing.assert_array_equal(a.core.model.rest_node_pos, b.core.model.rest_node_pos)


def test_integer_dt_override_still_works():
    env = make_vec_env("follow_target", 1, seed=0, dt=1, substeps=np.int64(2))
    obs, _ = env.reset(seed=0)
    assert env.core.model.dt == 1.0 and np.isfinite(obs).all()


def test_reset_mask_takes_integer_indices_too():
    env = make_vec_env("follow_target", 3, seed=0)
    env.reset(seed=0)
    for _ in range(2):
        env.step(np.zeros((3, env.single_action_space.shape[0]), np.float32))
    env.reset(options={"reset_mask": [1]})  # env 1 only
    env.reset(options={"reset_mask": [2]})  # read as a mask, [2] would have reset env 0
    assert env.core.step_count.tolist() == [2, 0, 0]
    env.reset(options={"reset_mask": np.array([True, False, False])})
    assert env.core.step_count.tolist() == [0, 0, 0]
    with pytest.raises(ValueError, match="reset_mask"):
        env.reset(options={"reset_mask": [0, True]})


@pytest.mark.parametrize("kw, match", [
    ({"dt": "0.05"}, r"FollowTargetConfig\.dt: expected a finite number"),
    ({"substeps": 2.5}, r"\.substeps: expected an integer"),
    ({"newton_max_iter": 0}, r"\.newton_max_iter: must be within"),
    ({"timeout_steps": True}, r"\.timeout_steps: expected an integer"),
    ({"smoothing": 3}, r"\.smoothing: expected a string"),
])
def test_task_config_built_directly_checks_its_fields(kw, match):
    from policies.tasks.follow_target import FollowTargetConfig

    with pytest.raises(ValueError, match=match):
        FollowTargetConfig(**kw)
