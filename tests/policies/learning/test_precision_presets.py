"""The training defaults a new user gets: the precision plan (compiled bfloat16 where the machine allows it, float32
with a notice otherwise), the named presets, and CrossQ as a second algorithm through the same run directory."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

from policies.learning import precision
from policies.learning.precision import MIN_COMPILED_UPDATES, cpu_has_bf16, plan_updates
from policies.learning.presets import DEFAULT_PRESET, PRESETS, preset_settings
from policies.learning.training import Args, TrainError, gradient_updates, train, update_plan
from tests.helpers.training import train_args

LONG = 10 * MIN_COMPILED_UPDATES


@pytest.mark.parametrize(("kw", "label", "why"), [
    (dict(bf16_cpu=True, compiler="/usr/bin/g++"), "bfloat16 compiled", "bfloat16 instructions and a C++ compiler"),
    (dict(bf16_cpu=True, compiler=None), "float32 eager", "no C++ compiler"),
    (dict(bf16_cpu=False, compiler="/usr/bin/g++"), "float32 eager", "no bfloat16 instructions"),
    (dict(bf16_cpu=True, compiler="/usr/bin/g++", device="cuda:0"), "float32 eager", "measured on CPUs only"),
    (dict(bf16_cpu=True, compiler="/usr/bin/g++", gradient_updates=MIN_COMPILED_UPDATES - 1), "float32 eager",
     "a short run"),
])
def test_auto_precision_takes_the_fast_path_only_where_the_machine_allows_it(kw, label, why):
    plan = plan_updates("auto", **{"gradient_updates": LONG, **kw})
    assert plan.label == label and why in plan.reason
    assert plan.notice().startswith(f"updates: {label} (")


def test_asked_for_precisions_and_their_compile_choice():
    assert plan_updates("float32", gradient_updates=LONG, bf16_cpu=True, compiler="g++").label == "float32 eager"
    assert plan_updates("bfloat16", gradient_updates=10, bf16_cpu=False, compiler="g++").label == "bfloat16 compiled"
    eager = plan_updates("bfloat16", gradient_updates=LONG, compiler=None)
    assert eager.label == "bfloat16 eager" and "no C++ compiler" in eager.reason
    assert plan_updates("bfloat16", gradient_updates=LONG, compiler="g++", compile_updates=False).label == \
        "bfloat16 eager"
    assert plan_updates("float32", gradient_updates=LONG, compiler="g++", compile_updates=True).label == \
        "float32 compiled"
    with pytest.raises(ValueError, match="C\\+\\+ compiler"):
        plan_updates("float32", gradient_updates=LONG, compiler=None, compile_updates=True)
    with pytest.raises(ValueError, match="precision must be one of auto, bfloat16, float32"):
        plan_updates("half", gradient_updates=LONG)


def test_cpu_bfloat16_instructions_are_read_from_cpuinfo():
    assert cpu_has_bf16("processor : 0\nflags\t\t: fpu sse2 avx512f avx512_bf16 amx_tile\n")
    assert cpu_has_bf16("flags : fpu amx_bf16\n")
    assert cpu_has_bf16("Features\t: fp asimd bf16 i8mm\n")  # Arm
    assert not cpu_has_bf16("flags : fpu sse2 avx2 avx512f avx512bw\n")  # AVX-512 without BF16
    assert not cpu_has_bf16("")


def test_a_run_without_a_compiler_trains_in_float32_and_says_why(monkeypatch, tmp_path, capsys):
    """The default (auto) path on a machine whose CPU has bfloat16 but no C++ compiler is on the PATH: the run trains
    eagerly in float32, prints one notice naming the missing compiler and records the plan in its files."""
    monkeypatch.setattr(precision, "cpu_has_bf16", lambda cpuinfo=None: True)
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    monkeypatch.delenv("CXX", raising=False)
    run = tmp_path / "run"
    train(train_args(run, 80, precision="auto"))
    err = capsys.readouterr().err
    notices = [line for line in err.splitlines() if line.startswith("updates: ")]
    assert notices == ["updates: float32 eager (no C++ compiler for torch.compile on the PATH; install g++ for the "
                       "compiled bfloat16 updates (about half the iteration time))"]
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["updates"]["label"] == "float32 eager" and cfg["args"]["precision"] == "auto"
    side = json.loads((run / "policy.json").read_text())
    assert side["training"]["updates"]["label"] == "float32 eager"


def test_the_plan_counts_the_updates_the_run_still_makes():
    args = Args(task="follow_target", num_envs=500, total_steps=2_000_000, learning_starts=1000, updates_per_iter=4)
    assert gradient_updates(args) == (2_000_000 - 1000) // 500 * 4
    assert gradient_updates(args, done_steps=1_990_000) == 10_000 // 500 * 4
    short = update_plan(Args(task="follow_target", total_steps=2000, num_envs=4))
    assert short.label == "float32 eager"  # 1000 updates: on any machine


def test_compiled_updates_are_cached_in_rodlabs_folder(monkeypatch, tmp_path):
    """The compile cache lives in RODLAB_CACHE_DIR (else ~/.cache/rodlab), replacing torch's default in the
    temporary folder, but a folder the user chose is kept."""
    from torch._inductor.runtime.cache_dir_utils import default_cache_dir

    monkeypatch.setenv("RODLAB_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", default_cache_dir())  # as torch leaves it once it looked
    assert precision.configure_compile_cache() == tmp_path / "cache" / "torchinductor"
    assert os.environ["TORCHINDUCTOR_CACHE_DIR"] == str(tmp_path / "cache" / "torchinductor")
    assert (tmp_path / "cache" / "torchinductor").is_dir()
    monkeypatch.setenv("TORCHINDUCTOR_CACHE_DIR", str(tmp_path / "mine"))
    assert precision.configure_compile_cache() == tmp_path / "mine"
    monkeypatch.delenv("RODLAB_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert precision.compile_cache_dir() == tmp_path / "xdg" / "rodlab" / "torchinductor"


def test_presets_resolve_to_the_documented_settings():
    """paper: the paper's table A.1 (docs/tasks.md §8.1), which are also Args' defaults; fast: the same on 100
    envs. Unknown names are refused with the known ones."""
    assert DEFAULT_PRESET == "paper" and set(PRESETS) == {"paper", "fast"}
    paper = Args(**preset_settings("paper"))
    assert (paper.num_envs, paper.updates_per_iter, paper.batch_size, paper.learning_rate, paper.algorithm) == \
        (500, 4, 1024, 1e-3, "sac")
    assert paper == Args()
    fast = Args(**preset_settings("fast"))
    assert (fast.preset, fast.num_envs, fast.updates_per_iter, fast.batch_size, fast.algorithm) == \
        ("fast", 100, 4, 1024, "sac")
    with pytest.raises(ValueError, match="unknown preset 'quick'; known: paper, fast"):
        preset_settings("quick")


def test_the_command_line_starts_from_the_preset_and_its_options_win(tmp_path):
    from policies.cli import train_main

    run = tmp_path / "run"
    assert train_main(["follow_target", "--preset", "fast", "--envs", "4", "--steps", "40", "--batch-size", "16",
                       "--learning-starts", "8", "--precision", "float32", "--run-dir", str(run),
                       "--eval-minutes", "0"]) == 0
    saved = json.loads((run / "config.json").read_text())["args"]
    assert (saved["preset"], saved["num_envs"], saved["batch_size"], saved["updates_per_iter"]) == ("fast", 4, 16, 4)
    run = tmp_path / "run2"
    assert train_main(["follow_target", "--preset", "fast", "--steps", "300", "--batch-size", "16",
                       "--learning-starts", "100", "--updates", "1", "--precision", "float32", "--run-dir", str(run),
                       "--eval-minutes", "0"]) == 0
    assert json.loads((run / "config.json").read_text())["args"]["num_envs"] == 100  # the preset's


def test_a_sweep_compares_presets_as_a_grid(tmp_path):
    from policies.learning.sweep import SweepError, make_trials, parse_sets

    trials = make_trials(["follow_target"], [0], parse_sets(["preset=paper,fast"]), tmp_path, envs=None, steps=100,
                         time_limit_minutes=0.0, cpus_per_trial=1)
    by_name = {t.name: t.args for t in trials}
    assert set(by_name) == {"follow_target__preset=paper__s0", "follow_target__preset=fast__s0"}
    assert by_name["follow_target__preset=fast__s0"]["num_envs"] == 100
    assert by_name["follow_target__preset=paper__s0"]["num_envs"] == 500
    (only,) = make_trials(["follow_target"], [0], parse_sets(["batch_size=256"]), tmp_path, envs=8, steps=100,
                          time_limit_minutes=0.0, cpus_per_trial=1, preset="fast")
    assert (only.args["preset"], only.args["num_envs"], only.args["batch_size"]) == ("fast", 8, 256)
    assert parse_sets(["compile_updates=auto,true,off", "precision=float32"]) == \
        {"compile_updates": [None, True, False], "precision": ["float32"]}
    with pytest.raises(SweepError, match="unknown preset"):
        make_trials(["follow_target"], [0], parse_sets(["preset=nope"]), tmp_path, envs=None, steps=100,
                    time_limit_minutes=0.0, cpus_per_trial=1)


def test_crossq_trains_saves_resumes_evaluates_and_reports(tmp_path):
    """``--algorithm crossq``: a few hundred env steps train, checkpoint, resume (the update counter and replay
    buffer continue), write a policy file that loads as weights only and evaluates, and the run reads into the
    report like a SAC run."""
    from policies.learning.checkpoint import read_state
    from policies.learning.crossq import CrossQPolicy
    from policies.learning.evaluation import evaluate
    from policies.learning.report import report
    from policies.learning.sac import load_policy, read_policy_meta

    run = tmp_path / "follow_target__crossq__s1"
    train(train_args(run, 160, algorithm="crossq", policy_delay=2, eval_every_steps=80, eval_episodes=2,
                     eval_envs=2))
    st1 = read_state(run)
    assert st1["num_timesteps"] == 160 and st1["n_updates"] > 0
    cfg = json.loads((run / "config.json").read_text())
    assert cfg["algorithm"].startswith("RodCrossQ") and cfg["updates"]["label"] == "float32 eager"
    train(train_args(run, 240, algorithm="crossq", policy_delay=2, eval_every_steps=80, eval_episodes=2,
                     eval_envs=2), resume=True)
    st2 = read_state(run)
    assert st2["num_timesteps"] == 240 and st2["n_updates"] > st1["n_updates"]
    assert read_policy_meta(run / "policy.zip")["algorithm"] == "crossq"
    pol, meta = load_policy(run / "policy.zip")
    assert isinstance(pol, CrossQPolicy) and meta["critic_net_arch"] == [32, 32, 32]
    res = evaluate(run / "policy.zip", episodes=2, seed=0, num_envs=2)
    assert res["episodes"] == 2 and np.isfinite(res["avg_discounted_return_mean"])
    rep = report([run], tmp_path / "report")
    (group,) = rep["groups"]
    assert group["group"] == "follow_target__crossq" and group["seeds"] == [1]


def test_crossq_refuses_sacs_update_options(tmp_path):
    with pytest.raises(TrainError, match="crossq runs its updates eagerly in float32"):
        train(train_args(tmp_path / "a", 40, algorithm="crossq", precision="bfloat16"))
    with pytest.raises(TrainError, match="--algorithm: expected one of sac, crossq"):
        train(train_args(tmp_path / "b", 40, algorithm="td3"))
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


@pytest.mark.parametrize("algorithm", ["sac", "crossq"])
def test_n_step_returns_train_and_resume_with_their_buffer(tmp_path, algorithm):
    """``--n-steps 5``: the replay buffer is SB3's n-step buffer (its samples carry the n-step discount), the TD
    targets use it, and a resumed run that grows its buffer keeps n and the discount."""
    from stable_baselines3.common.buffers import NStepReplayBuffer

    from policies.learning.checkpoint import read_state
    from policies.learning.training import build_model, load_checkpoint, make_sb3_env

    args = train_args(tmp_path / "unused", 40, algorithm=algorithm, n_steps=5)
    env = make_sb3_env(args.task, args.num_envs, 0)
    try:
        model = build_model(args, env)
        assert isinstance(model.replay_buffer, NStepReplayBuffer) and model.replay_buffer.n_steps == 5
    finally:
        env.close()
    run = tmp_path / "run"
    train(train_args(run, 120, algorithm=algorithm, n_steps=5, buffer_size=30))
    train(train_args(run, 200, algorithm=algorithm, n_steps=5, buffer_size=60), resume=True)
    assert read_state(run)["num_timesteps"] == 200
    resumed = train_args(run, 300, algorithm=algorithm, n_steps=5, buffer_size=120)
    env = make_sb3_env(resumed.task, resumed.num_envs, 0)
    try:
        model, _ = load_checkpoint(resumed, run, env)
        rb = model.replay_buffer
        assert isinstance(rb, NStepReplayBuffer) and (rb.n_steps, rb.gamma) == (5, resumed.gamma)
        assert rb.buffer_size == 120 // resumed.num_envs  # grown, still an n-step buffer
    finally:
        env.close()
    with pytest.raises(TrainError, match="--n-steps must be at least 1"):
        train(train_args(tmp_path / "bad", 40, n_steps=0))
