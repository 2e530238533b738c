"""The speed settings `rodlab bench train` can try (policies/learning/train_speed.py) apply and keep the updates working.

No timing is asserted (speed is measured on a quiet machine)."""
from __future__ import annotations

import os

import numpy as np
import pytest
import torch

from policies.learning.train_speed import SpeedSettings, apply_speed_settings
from policies.learning.training import Args, build_sac, make_sb3_env


def _model():
    env = make_sb3_env("ik4d", 4, 0)
    args = Args(task="ik4d", num_envs=4, total_steps=10_000, batch_size=64, net_arch=[32, 32], learning_starts=0)
    model = build_sac(args, env)
    from stable_baselines3.common.logger import configure

    model.set_logger(configure(None, [""]))
    obs = env.reset()
    for _ in range(20):
        act = np.stack([env.action_space.sample() for _ in range(4)])
        nobs, rew, done, infos = env.step(act)
        model.replay_buffer.add(obs, nobs, act, rew, done, infos)
        obs = nobs
    env.close()
    return model


def _params(model):
    return torch.cat([p.detach().flatten().clone() for p in model.policy.parameters()])


@pytest.mark.parametrize("settings", [SpeedSettings(), SpeedSettings(bf16=True)])
def test_settings_apply_and_updates_run(settings):
    model = _model()
    apply_speed_settings(model, settings)
    assert model.bf16_updates is settings.bf16
    for opt in (model.actor.optimizer, model.critic.optimizer, model.ent_coef_optimizer):
        d = opt.defaults
        assert d["eps"] == pytest.approx(1e-7) and d["lr"] == pytest.approx(1e-3)
    before = _params(model)
    model.train(gradient_steps=2, batch_size=64)
    after = _params(model)
    assert torch.isfinite(after).all() and not torch.equal(before, after)  # the updates reached the weights
    assert model._n_updates == 2


@pytest.fixture
def fresh_dynamo():
    """Compiled code of earlier tests (other models, other inductor settings) forgotten before and after."""
    torch._dynamo.reset()
    yield
    torch._dynamo.reset()


def _twin_models(n: int = 2):
    """``n`` models with the same initial weights and replay buffer."""
    models = []
    for _ in range(n):
        torch.manual_seed(0)
        models.append(_model())
    assert all(torch.equal(_params(m), _params(models[0])) for m in models[1:])
    return models


def _adam_moments(model):
    """Every optimizer's per-parameter state (step, first and second moments), flattened in a fixed order."""
    parts = []
    for opt in (model.actor.optimizer, model.critic.optimizer, model.ent_coef_optimizer):
        for p in opt.param_groups[0]["params"]:
            st = opt.state[p]
            parts += [st["step"].reshape(1).float(), st["exp_avg"].flatten(), st["exp_avg_sq"].flatten()]
    return torch.cat(parts)


@pytest.mark.long(seconds=70)
def test_compiled_updates_match_eager_updates(fresh_dynamo):
    """``compile_updates`` computes the same SAC update as the eager code (autograd + torch.optim.Adam): the
    policy's noise is drawn from torch's generator in the eager order (a ~ pi(s), then the TD target's a'), so
    from the same seed the weights, the temperature and the optimizers' moments after three updates agree to
    float32 rounding, and the logged statistics too; the parameters require grad again afterwards. A second
    compiled twin from the same seed gives the same bits (the compiled updates are reproducible). Compiles one
    function (tens of seconds on the 2-core CI machine)."""
    eager, compiled, again = _twin_models(3)
    for model in (compiled, again):
        apply_speed_settings(model, SpeedSettings(compile=True))
    assert compiled.compile_updates and not eager.compile_updates
    initial = _params(eager)
    logs = []
    for model in (eager, compiled, again):
        torch.manual_seed(7)
        np.random.seed(7)  # the replay sampling
        model.train(gradient_steps=3, batch_size=64)
        logs.append(dict(model.logger.name_to_value))
    assert torch.equal(_params(again), _params(compiled)), (_params(again) - _params(compiled)).abs().max()
    assert compiled._compiled_fns is not None and eager._compiled_fns is None
    pe, pc = _params(eager), _params(compiled)
    moved = (pe - initial).abs().max()
    assert moved > 1e-4  # the updates changed the weights ...
    torch.testing.assert_close(pc, pe, rtol=1e-4, atol=1e-5)  # ... and both ways alike
    torch.testing.assert_close(compiled.log_ent_coef.detach(), eager.log_ent_coef.detach(), rtol=1e-5, atol=1e-6)
    assert float(eager.log_ent_coef.detach()) != 0.0  # the temperature moved (it starts at log 1)
    me, mc = _adam_moments(eager), _adam_moments(compiled)
    assert me[0] == 3  # three Adam steps counted
    torch.testing.assert_close(mc, me, rtol=1e-4, atol=1e-6)
    for key in ("train/critic_loss", "train/actor_loss", "train/ent_coef", "train/ent_coef_loss", "train/q_mean",
                "train/log_prob"):
        assert logs[1][key] == pytest.approx(logs[0][key], rel=1e-4, abs=1e-5), key
    assert all(p.requires_grad for p in compiled.policy.parameters() if p is not None)
    assert compiled.log_ent_coef.requires_grad
    # the compiled functions are not part of a saved model (SB3 pickles the rest of the attributes)
    assert "_compiled_fns" in compiled._excluded_save_params()


def test_compiled_updates_with_a_fixed_temperature(fresh_dynamo):
    """A fixed entropy coefficient (SB3's ``ent_coef=<float>``: no temperature optimizer) goes through the compiled
    update too: same weights as eager, the coefficient unchanged, no temperature loss logged."""
    models = _twin_models()
    for model in models:
        model.ent_coef_optimizer = None
        model.ent_coef_tensor = torch.tensor(0.05)
    eager, compiled = models
    compiled.compile_updates = True
    for model in models:
        torch.manual_seed(7)
        np.random.seed(7)
        model.train(gradient_steps=2, batch_size=64)
    torch.testing.assert_close(_params(compiled), _params(eager), rtol=1e-4, atol=1e-5)
    assert compiled.logger.name_to_value["train/ent_coef"] == pytest.approx(0.05)
    assert "train/ent_coef_loss" not in compiled.logger.name_to_value


def test_compiled_update_is_one_graph(fresh_dynamo):
    """The compiled update (losses, gradients, Adam steps) is traced as one graph without breaks: nothing of it
    falls back to Python between kernels."""
    model = _model()
    model.compile_updates = True
    model.train(gradient_steps=0, batch_size=64)  # sets up the compiled-update state without updating
    data = model.replay_buffer.sample(64)
    noise = torch.randn(64, *model.action_space.shape)
    lrs = [torch.tensor(1e-3)] * 3
    for p in model.policy.parameters():
        p.requires_grad_(False)
    explanation = torch._dynamo.explain(model._fused_update)(data, noise, torch.randn_like(noise), *lrs)
    assert explanation.graph_count == 1 and explanation.graph_break_count == 0, explanation.break_reasons


def test_sample_policy_is_sb3s_squashed_gaussian():
    """``_sample_policy`` (side-effect free, usable inside torch.func) draws the same actions and log-probabilities
    as SB3's ``actor.action_log_prob`` from the same seed; with explicit noise it is that draw."""
    model = _model()
    obs = model.replay_buffer.sample(64).observations
    torch.manual_seed(3)
    a_ref, logp_ref = model.actor.action_log_prob(obs)
    torch.manual_seed(3)
    a, logp = model._sample_policy(obs)
    assert torch.equal(a, a_ref) and torch.equal(logp, logp_ref.reshape(-1, 1))
    torch.manual_seed(3)
    noise = torch.randn_like(a)
    a2, logp2 = model._sample_policy(obs, noise)
    assert torch.equal(a2, a_ref) and torch.equal(logp2, logp)


def test_compiled_updates_refuse_an_adam_they_do_not_write_out():
    """The compiled Adam step is plain Adam: an optimizer with AMSGrad (or another class) is refused by name."""
    from policies.learning.sac import _adam_state

    model = _model()
    opt = torch.optim.Adam(model.actor.parameters(), lr=1e-3, amsgrad=True)
    with pytest.raises(ValueError, match="amsgrad"):
        _adam_state(opt)
    with pytest.raises(ValueError, match="SGD"):
        _adam_state(torch.optim.SGD(model.actor.parameters(), lr=1e-3))


def test_compiled_functions_are_not_saved(tmp_path):
    """A checkpoint of a model with compiled update functions saves and loads (they are rebuilt when needed)."""
    import threading

    from policies.learning.sac import RodSAC

    model = _model()
    model.compile_updates = True
    model._compiled_fns = (threading.Lock(),)  # stands for compiled code: cannot be pickled
    model.save(tmp_path / "m.zip")
    loaded = RodSAC.load(tmp_path / "m.zip")
    assert getattr(loaded, "_compiled_fns", None) is None


def test_compile_without_a_compiler_is_refused(monkeypatch, tmp_path, capsys):
    """``rodlab train --compile`` on a machine without a C++ compiler stops before any work with a message."""
    from policies.learning.training import TrainError, train

    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.delenv("CXX", raising=False)
    with pytest.raises(TrainError, match="C\\+\\+ compiler"):
        train(Args(task="ik4d", num_envs=2, total_steps=100, run_dir=str(tmp_path / "run"), compile_updates=True))
    assert not (tmp_path / "run").exists()
    from policies.cli import train_main

    assert train_main(["ik4d", "--compile", "--steps", "100", "--run-dir", str(tmp_path / "cli")]) == 2
    assert "--compile: torch.compile needs a C++ compiler" in capsys.readouterr().err
    assert not (tmp_path / "cli").exists()
    model = _model()
    with pytest.raises(TrainError, match="C\\+\\+ compiler"):  # the Python entry of the benchmarks too
        apply_speed_settings(model, SpeedSettings(compile=True))
    assert not model.compile_updates


def _trained(bf16: bool):
    th_state = torch.get_rng_state()
    np_state = np.random.get_state()
    torch.manual_seed(0)
    np.random.seed(0)
    try:
        model = _model()
        model.bf16_updates = bf16
        model.train(gradient_steps=3, batch_size=64)
        return _params(model)
    finally:
        torch.set_rng_state(th_state)
        np.random.set_state(np_state)


def test_bf16_training_setting_runs_the_updates_in_bfloat16():
    """Args.bf16 (rodlab train --bf16) puts RodSAC's updates under bfloat16 autocast: the same updates from the same
    weights and samples differ from float32 by bfloat16 rounding, and stay finite."""
    a32, b32 = _trained(False), _trained(False)
    assert torch.equal(a32, b32)  # the comparison below is meaningful: float32 twice gives the same bits
    a16 = _trained(True)
    assert torch.isfinite(a16).all() and not torch.equal(a16, a32)
    assert (a16 - a32).abs().max() < 0.05 * a32.abs().max()


def test_precision_is_a_training_setting_and_old_configs_keep_theirs():
    """``Args.precision`` (auto by default); a config.json saved with the earlier ``bf16`` switch loads as the run it
    was: bf16 true -> bfloat16 with the float32_io layout and eager updates unless it said otherwise, false ->
    float32."""
    from policies.learning.training import Args

    fields = {k: v for k, v in Args().to_json().items() if k not in ("precision", "bf16_layout", "compile_updates")}
    assert Args().precision == "auto"
    old = Args.from_json({**fields, "bf16": True})
    assert (old.precision, old.bf16_layout, old.compile_updates) == ("bfloat16", "float32_io", False)
    old = Args.from_json({**fields, "bf16": True, "bf16_layout": "all", "compile_updates": True})
    assert (old.precision, old.bf16_layout, old.compile_updates) == ("bfloat16", "all", True)
    assert Args.from_json({**fields, "bf16": False}).precision == "float32"


def test_bf16_keeps_q_values_and_log_probabilities_in_float32():
    """Under --bf16 the hidden products run in bfloat16 but the input and output layers and the LayerNorms do not:
    a Q value of about 100 is not rounded to bfloat16's grid (multiples of 0.5 there), and the actor's
    log-probabilities are float32 too."""
    from policies.learning.sac import Float32LayerNorm, Float32Linear

    model = _model()
    critic, actor = model.critic, model.actor
    assert isinstance(actor.mu, Float32Linear) and isinstance(actor.log_std, Float32Linear)
    for mlp in [actor.latent_pi, *critic.q_networks]:  # input layer and LayerNorms float32, hidden products not
        linears = [m for m in mlp if isinstance(m, torch.nn.Linear)]
        assert isinstance(linears[0], Float32Linear) and type(linears[1]) is torch.nn.Linear
        assert all(isinstance(m, Float32LayerNorm) for m in mlp if isinstance(m, torch.nn.LayerNorm))
    assert all(isinstance(q[-1], Float32Linear) for q in critic.q_networks)
    with torch.no_grad():
        for q in critic.q_networks:
            q[-1].bias.fill_(100.0)
    g = torch.Generator().manual_seed(3)
    obs = torch.randn(256, *model.observation_space.shape, generator=g)
    act = torch.rand(256, *model.action_space.shape, generator=g) * 2 - 1
    with torch.no_grad():
        q32 = critic(obs, act)[0]
        with torch.autocast("cpu", dtype=torch.bfloat16):
            q16 = critic(obs, act)[0]
            _, logp16 = actor.action_log_prob(obs)
    assert q16.dtype == torch.float32 and logp16.dtype == torch.float32
    assert not torch.equal(q16, q32)  # the hidden layers did run in bfloat16
    assert (q16 - q32).abs().max() < 0.05 * (q32 - 100.0).abs().max() + 1e-3
    off_grid = (2 * q16 - torch.round(2 * q16)).abs()
    assert off_grid.max() > 0.05  # bfloat16 outputs would all sit on the 0.5 grid
    # the state_dict keys are those of plain Linear heads, so policy files written before load unchanged
    assert "actor.mu.weight" in model.policy.state_dict() and "critic.qf0.6.weight" in model.policy.state_dict()


def test_bf16_updates_see_the_weights_of_the_previous_update():
    """Three bf16 updates in one train() call give the same weights as three calls of one update: every forward pass
    uses the weights the previous optimizer step left (autocast caches its bfloat16 weight copies until its region
    ends, so one region around several updates would run the later ones with the first update's weights)."""
    def run(calls: int, steps: int):
        torch.manual_seed(0)
        np.random.seed(0)
        model = _model()
        model.bf16_updates = True
        torch.manual_seed(1)
        np.random.seed(1)
        for _ in range(calls):
            model.train(gradient_steps=steps, batch_size=64)
        return _params(model)

    th_state, np_state = torch.get_rng_state(), np.random.get_state()
    try:
        one_call, three_calls = run(1, 3), run(3, 1)
    finally:
        torch.set_rng_state(th_state)
        np.random.set_state(np_state)
    assert torch.isfinite(one_call).all()
    assert torch.equal(one_call, three_calls)


def test_bf16_layout_all_runs_every_layer_in_bfloat16_and_switches_back():
    """``set_bf16_layout(policy, "all")`` (``--bf16-layout all``) turns the float32 layers into plain ones: under
    autocast Q and the actor's mean come out in bfloat16; ``float32_io`` restores the float32 layers. Parameters,
    state_dict and the float32 network (no autocast) are the same in both layouts."""
    from policies.learning.sac import Float32Linear, set_bf16_layout

    model = _model()
    policy, critic, actor = model.policy, model.critic, model.actor
    keys = list(policy.state_dict())
    g = torch.Generator().manual_seed(5)
    obs = torch.randn(64, *model.observation_space.shape, generator=g)
    act = torch.rand(64, *model.action_space.shape, generator=g) * 2 - 1

    def forward(autocast: bool):
        with torch.no_grad(), torch.autocast("cpu", dtype=torch.bfloat16, enabled=autocast):
            return critic(obs, act)[0], actor.mu(actor.latent_pi(obs))

    q32, mu32 = forward(False)
    set_bf16_layout(policy, "all")
    assert not any(isinstance(m, Float32Linear) for m in policy.modules())
    assert list(policy.state_dict()) == keys
    q_all, mu_all = forward(True)
    assert q_all.dtype == torch.bfloat16 and mu_all.dtype == torch.bfloat16
    assert torch.equal(forward(False)[0], q32) and torch.equal(forward(False)[1], mu32)
    set_bf16_layout(policy, "float32_io")
    assert isinstance(actor.mu, Float32Linear) and all(isinstance(q[-1], Float32Linear) for q in critic.q_networks)
    q_io, mu_io = forward(True)
    assert q_io.dtype == torch.float32 and mu_io.dtype == torch.float32
    with pytest.raises(ValueError, match="bf16 layout must be one of"):
        set_bf16_layout(policy, "half")


def test_bf16_layout_is_a_training_and_speed_setting(tmp_path):
    """``rodlab train --bf16-layout all`` reaches the model (the trained layers are plain ones); an unknown layout is
    refused before a run directory is made."""
    from policies.learning.sac import Float32Linear
    from policies.learning.training import TrainError, train

    assert Args().bf16_layout == "all"
    assert Args.from_json({**Args().to_json(), "bf16_layout": "float32_io"}).bf16_layout == "float32_io"
    with pytest.raises(TrainError, match="--bf16-layout: expected one of float32_io, all"):
        train(Args(task="ik4d", precision="bfloat16", bf16_layout="half", run_dir=str(tmp_path / "bad")))
    assert not (tmp_path / "bad").exists()
    with pytest.raises(ValueError, match="bf16_layout must be one of"):
        SpeedSettings(bf16=True, bf16_layout="half")
    model = _model()
    apply_speed_settings(model, SpeedSettings(bf16=True, bf16_layout="all"))
    assert model.bf16_updates and not any(isinstance(m, Float32Linear) for m in model.policy.modules())
    assert SpeedSettings(bf16=True, bf16_layout="all").label() == "bf16=all"
    assert SpeedSettings().label() == "float32" and SpeedSettings(compile=True).label() == "compile"


@pytest.mark.parametrize(("argv", "threads"), [([], "1"), (["ik4d", "--threads", "2"], "2"), (["--threads=3"], "3"),
                                              (["--threads", "x"], "1")])
def test_library_threads_follow_the_threads_option(monkeypatch, argv, threads):
    """``--threads N`` sets OpenMP's and MKL's thread counts to N before torch loads them (with them at 1 a two-thread
    iteration took 1.3-1.5x as long, BENCHMARKS.md §6); a value set by the user is kept."""
    from policies.cli import _threads_env

    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.delenv(var, raising=False)
    _threads_env(argv)
    assert (os.environ["OMP_NUM_THREADS"], os.environ["MKL_NUM_THREADS"]) == (threads, threads)
    monkeypatch.setenv("OMP_NUM_THREADS", "7")
    _threads_env(["--threads", "2"])
    assert os.environ["OMP_NUM_THREADS"] == "7"


def _critic_like(x, params):
    """A small critic: Linear -> LayerNorm -> ReLU -> Linear(., 1), squared error against 1 (its gradients take
    every kind of product the pass rewrites: biases, a one-column output, an outer product, a column sum)."""
    h = torch.nn.functional.linear(x, params["w1"], params["b1"])
    h = torch.relu(torch.nn.functional.layer_norm(h, (h.shape[-1],)))
    q = torch.nn.functional.linear(h, params["w2"], params["b2"])
    return ((q - 1.0) ** 2).mean()


def _critic_like_inputs(rows: int):
    """Weights of ``_critic_like`` (12 -> 32 -> 1) and a batch of ``rows`` inputs, from a fixed seed."""
    gen = torch.Generator().manual_seed(0)
    params = {"w1": torch.randn(32, 12, generator=gen) / 4, "b1": torch.randn(32, generator=gen),
              "w2": torch.randn(1, 32, generator=gen) / 4, "b2": torch.randn(1, generator=gen)}
    return params, torch.randn(rows, 12, generator=gen)


def _critic_grads(bf16: bool):
    """(params, x) -> (gradients, loss) of ``_critic_like``, under bfloat16 autocast when ``bf16``."""
    def grads(p, x):
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
            return torch.func.grad_and_value(lambda q: _critic_like(x, q))(p)

    return grads


def _compiled_with(fn, graph_pass):
    """``fn`` compiled with ``graph_pass`` as inductor's post-grad pass (not served from inductor's cache)."""
    return torch.compile(fn, dynamic=False, options={"post_grad_custom_post_pass": graph_pass,
                                                     "fx_graph_cache": False})


def test_run_settings_reach_the_model():
    """``configure_updates`` puts a run's update plan (bfloat16, its layout, compiled updates; from ``Args`` through
    ``update_plan``) on the model, and a float32 plan takes them off again."""
    from policies.learning.sac import Float32Linear
    from policies.learning.training import configure_updates, update_plan

    model = _model()
    plan = update_plan(Args(task="ik4d", precision="bfloat16", bf16_layout="all", compile_updates=True))
    configure_updates(model, plan)
    assert model.bf16_updates and model.compile_updates
    assert not any(isinstance(m, Float32Linear) for m in model.policy.modules())  # every layer in bfloat16
    configure_updates(model, update_plan(Args(task="ik4d", precision="float32", bf16_layout="float32_io")))
    assert not model.bf16_updates and not model.compile_updates
    assert any(isinstance(m, Float32Linear) for m in model.policy.modules())


def test_saved_config_with_a_retired_setting():
    """A run's config.json written when ``compile_split_products`` still existed loads when it holds the value that
    runs as now (off), and names the key otherwise; ``--split-products`` is no option any more."""
    from policies.cli import bench_train_main
    from policies.learning.training import TrainError

    saved = Args(task="ik4d").to_json()
    assert Args.from_json({**saved, "compile_split_products": False}) == Args(task="ik4d")
    with pytest.raises(TrainError, match="unknown keys .*compile_split_products"):
        Args.from_json({**saved, "compile_split_products": True})
    with pytest.raises(SystemExit) as exc:
        bench_train_main(["--task", "ik4d", "--compile", "--split-products"])
    assert exc.value.code == 2


@pytest.mark.parametrize("bf16", [False, True])
def test_unit_product_loops_rewrite_and_keep_the_precision(fresh_dynamo, bf16):
    """``UnitProductLoops`` (policies/learning/compile_passes.py, part of ``--compile``) turns the bfloat16 products with a
    unit dimension of a critic's loss and gradients into float32 loops rounded once, leaves the wide products and
    float32 alone, and is as close to the float32 gradients as the library's bfloat16 products are."""
    from policies.learning.compile_passes import UnitProductLoops

    params, x = _critic_like_inputs(256)
    grads, loops = _critic_grads(bf16), UnitProductLoops()
    (g_c, loss_c), (g_e, loss_e) = _compiled_with(grads, loops)(params, x), grads(params, x)
    if bf16:  # forward: the output layer (dot + bias); backward: its input gradient and its weight gradient
        assert loops.rewritten == {"dot_bias": 1, "outer": 1, "sum_rows": 1}
        assert loops.uuid() == UnitProductLoops().uuid()  # inductor's cache key: one per version of the pass
    else:
        assert not loops.rewritten
    tol = {"rtol": 2e-2, "atol": 2e-2} if bf16 else {"rtol": 1e-5, "atol": 1e-6}
    torch.testing.assert_close(loss_c, loss_e, **tol)
    g_ref, _ = _critic_grads(False)(params, x)
    for k in params:
        torch.testing.assert_close(g_c[k], g_e[k], **tol)
        if bf16:  # no less precise than the eager bfloat16 gradient (one rounding, like the library)
            err_c = (g_c[k] - g_ref[k]).norm() / g_ref[k].norm()
            err_e = (g_e[k] - g_ref[k]).norm() / g_ref[k].norm()
            assert err_c <= 1.5 * err_e + 1e-3, (k, float(err_c), float(err_e))


def test_replay_samples_are_sb3s():
    """``RodSAC._sample_replay`` draws the same random numbers and returns the same batch (values, dtypes,
    shapes) as SB3's ``ReplayBuffer.sample``, also from a buffer that has wrapped around and with time-outs
    that cancel a done; buffers it does not handle go to SB3's method."""
    model = _model()
    rb = model.replay_buffer
    rng = np.random.default_rng(1)
    n_envs = rb.n_envs
    for _ in range(rb.buffer_size + 7):  # wraps around
        obs = rng.standard_normal((n_envs, *rb.obs_shape)).astype(np.float32)
        done = rng.random(n_envs) < 0.2
        infos = [{"TimeLimit.truncated": bool(t)} for t in rng.random(n_envs) < 0.5]
        rb.add(obs, obs + 1, rng.uniform(-1, 1, (n_envs, rb.action_dim)).astype(np.float32),
               rng.standard_normal(n_envs).astype(np.float32), done, infos)
    assert rb.full and rb.timeouts.any() and (rb.dones * rb.timeouts).any()
    for seed in range(3):
        np.random.seed(seed)
        ref = rb.sample(64)
        state_ref = np.random.get_state()[1].copy()
        np.random.seed(seed)
        got = model._sample_replay(64)
        assert np.array_equal(np.random.get_state()[1], state_ref)  # the same draws, no more
        for field, a, b in zip(ref._fields, ref, got):
            assert (a is None and b is None) or (a.dtype == b.dtype and a.shape == b.shape and torch.equal(a, b)), field
    rb.optimize_memory_usage = True  # SB3's own sampling for a buffer that shares observation storage
    np.random.seed(0)
    ref = rb.sample(64)
    np.random.seed(0)
    assert torch.equal(model._sample_replay(64).observations, ref.observations)
