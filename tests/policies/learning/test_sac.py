"""RodSAC extensions (docs/tasks.md §8.1-8.2) and the evaluation metric, on a standard gymnasium env."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch as th

from policies.learning.training import Args, build_sac, make_sb3_env, target_entropy


def _model(**kw):
    args = Args(task="Pendulum-v1", num_envs=2, total_steps=2000, batch_size=32, learning_starts=0, seed=3, **kw)
    env = make_sb3_env("Pendulum-v1", 2, 3)
    model = build_sac(args, env)
    from stable_baselines3.common.logger import configure

    model.set_logger(configure(None, [""]))
    obs = env.reset()
    for _ in range(40):
        act = np.stack([env.action_space.sample() for _ in range(2)])
        nobs, rew, done, infos = env.step(act)
        model.replay_buffer.add(obs, nobs, model.policy.scale_action(act), rew, done, infos)
        obs = nobs
    return model


def test_networks_have_layernorm_3x256():
    model = _model()
    actor_ln = [m for m in model.actor.latent_pi if isinstance(m, th.nn.LayerNorm)]
    assert len(actor_ln) == 3 and all(m.normalized_shape == (256,) for m in actor_ln)
    assert len(model.critic.q_networks) == 2
    for q in model.critic.q_networks:
        lin = [m for m in q if isinstance(m, th.nn.Linear)]
        assert [m.out_features for m in lin] == [256, 256, 256, 1]
        assert sum(isinstance(m, th.nn.LayerNorm) for m in q) == 3
    # the critic's optimizer must hold the LayerNorm critics' parameters (not SB3's replaced plain MLP)
    opt_ids = {id(p) for g in model.critic.optimizer.param_groups for p in g["params"]}
    assert all(id(p) in opt_ids for p in model.critic.parameters())
    assert model.actor.optimizer.defaults["eps"] == pytest.approx(1e-7)


def test_target_entropy_matches_alf_default():
    env = make_sb3_env("Pendulum-v1", 1, 0)  # action in [-2, 2]
    assert target_entropy(env.action_space, 0.1) == pytest.approx(math.log(0.4))
    from gymnasium import spaces

    box = spaces.Box(-1.0, 1.0, (10,), np.float32)
    assert target_entropy(box, 0.1) == pytest.approx(-1.6094 * 10, abs=1e-3)


def test_td_target_has_no_entropy_term():
    model = _model()
    data = model.replay_buffer.sample(64)
    th.manual_seed(0)
    t_small = model.td_target(data, th.tensor(0.01))
    th.manual_seed(0)
    t_big = model.td_target(data, th.tensor(100.0))
    assert th.allclose(t_small, t_big)  # alpha does not enter the critic target
    # and it equals r + gamma (1 - d) min Q'(s', a') with the same sampled a'
    th.manual_seed(0)
    a2, _ = model.actor.action_log_prob(data.next_observations)
    q = th.min(th.cat(model.critic_target(data.next_observations, a2), 1), 1, keepdim=True).values
    assert th.allclose(t_small, data.rewards + (1 - data.dones) * 0.99 * q, atol=1e-6)
    model.entropy_in_target = True
    th.manual_seed(0)
    assert not th.allclose(model.td_target(data, th.tensor(100.0)), t_small)


def test_target_network_updates_every_8_updates_across_calls():
    model = _model()

    def target_vec():
        return th.cat([p.detach().flatten().clone() for p in model.critic_target.parameters()])

    t0 = target_vec()
    model.train(gradient_steps=4, batch_size=32)  # updates 1..4: no target update
    assert th.equal(target_vec(), t0)
    model.train(gradient_steps=4, batch_size=32)  # update 8: one soft update
    t8 = target_vec()
    assert not th.equal(t8, t0)
    critic = th.cat([p.detach().flatten() for p in model.critic.parameters()])
    assert th.allclose(t8, 0.995 * t0 + 0.005 * critic, atol=1e-6)
    assert model._n_updates == 8


def test_avg_discounted_return_metric_formula(monkeypatch):
    """alf: R = (1/L) sum_l r_l (1 - gamma^l) / (1 - gamma); checked on a two-episode fake env."""
    from policies.learning.evaluation import _run_episodes

    rewards = np.array([1.0, 0.0, 2.0, -1.0])
    L, g = len(rewards), 0.9
    expected = sum(r * (1 - g ** (l + 1)) / (1 - g) for l, r in enumerate(rewards)) / L

    class FakeVec:
        num_envs = 1

        def __init__(self):
            from gymnasium import spaces

            self.observation_space = spaces.Box(-1, 1, (1,), np.float32)
            self.action_space = spaces.Box(-1, 1, (1,), np.float32)
            self.t = 0

        def reset(self):
            self.t = 0
            return np.zeros((1, 1), np.float32)

        def step(self, action):
            r = rewards[self.t % L]
            self.t += 1
            done = self.t % L == 0
            info = {"TimeLimit.truncated": True, "terminal_observation": np.zeros(1)} if done else {}
            return np.zeros((1, 1), np.float32), np.array([r]), np.array([done]), [info]

        def close(self):
            pass

    import policies.learning.evaluation as ev

    monkeypatch.setattr(ev, "make_sb3_env", lambda task, n, seed: FakeVec())
    eps = _run_episodes("random", "fake", 2, 0, 1, True, None, g, "fake")
    assert len(eps) == 2
    for e in eps:
        assert e["avg_disc_return"] == pytest.approx(expected)
        assert e["return"] == pytest.approx(rewards.sum())
        assert e["length"] == L
