"""Command-line entry points of ``policies`` (dispatched by rodlab_cli.py; each ``main(argv) -> int``).

* ``rodlab train TASK [--envs 500] [--steps N] [--seed s] [--run-dir DIR] [--resume | --init-from P.zip]`` -> train_main
* ``rodlab eval POLICY [--task T] [--episodes 100] [--seed s] [--json]``             -> eval_main
* ``rodlab bench train --task T [--envs 500] [--iters n] [--json]``                  -> bench_train_main
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

from sim.support.paths import check_output_path
from sim.support.progress import add_progress_flag, progress_bar, progress_wanted
from sim.support.text import count

from policies.learning import SpeedSettings, apply_speed_settings
from policies.tasks import gym_task_id

STARTED_AT = time.perf_counter()  # when the command started: a training run's wall-clock includes its start-up


def _threads_env(argv: list[str] | None = None) -> None:
    """Thread counts of OpenMP, MKL and numba, set before torch and numba load them: the command's ``--threads``
    (default 1: the machine is shared and training runs two processes at most). They must match ``--threads``:
    with all three at 1 and only ``torch.set_num_threads(2)``, a two-thread Follow Target iteration took 1.3-1.5x
    as long, its env step on one core (BENCHMARKS.md §6). A variable already set is kept.
    (NUMBA_NUM_THREADS only before numba is loaded: changing it after its thread pool started makes numba raise on
    its next configuration reload, e.g. when this runs inside a test process.)"""
    threads = _argv_threads(argv or [])
    names = ["OMP_NUM_THREADS", "MKL_NUM_THREADS"] + ([] if "numba" in sys.modules else ["NUMBA_NUM_THREADS"])
    for var in names:
        os.environ.setdefault(var, str(threads))


def _argv_threads(argv: list[str]) -> int:
    """The value of ``--threads N`` / ``--threads=N`` in ``argv`` (1 when absent or not a positive integer; argparse
    reports a bad value later)."""
    for i, arg in enumerate(argv):
        text = argv[i + 1] if arg == "--threads" and i + 1 < len(argv) else (
            arg.split("=", 1)[1] if arg.startswith("--threads=") else None)
        if text is not None:
            try:
                return max(1, int(text))
            except ValueError:
                return 1
    return 1


# ----------------------------------------------------------------------------------------- train
def train_main(argv: list[str]) -> int:
    _threads_env(argv)
    from policies.learning import (
        ALGORITHMS,
        BF16_LAYOUTS,
        DEFAULT_PRESET,
        PRECISIONS,
        PRESETS,
        Args,
        TrainError,
        check_compiler,
        check_device,
        preset_settings,
        train,
    )

    d = Args()
    p = argparse.ArgumentParser(prog="rodlab train", description="Train SAC (or CrossQ) on a rodlab task "
                                "(headless). Defaults: the --preset's settings (paper: docs/tasks.md §8.1).")
    p.add_argument("task", nargs="?", default="", help="task short name (e.g. follow_target) or gymnasium id")
    p.add_argument("--preset", choices=list(PRESETS), default=DEFAULT_PRESET,
                   help="named settings the options below start from: " + "; ".join(
                       f"{n}: {pr.summary}" for n, pr in PRESETS.items()) + f" (default {DEFAULT_PRESET}; "
                       "BENCHMARKS.md §6)")
    p.add_argument("--algorithm", choices=ALGORITHMS, default=None,
                   help="sac (default) or crossq (sb3-contrib's CrossQ: no target networks, batch renormalisation)")
    p.add_argument("--policy-delay", type=int, default=None,
                   help=f"crossq: critic updates per actor update (default {d.policy_delay})")
    p.add_argument("--envs", type=int, default=None, help=f"parallel envs (paper: {d.num_envs})")
    p.add_argument("--steps", type=int, default=d.total_steps, help="total env steps over all envs")
    p.add_argument("--seed", type=int, default=d.seed)
    p.add_argument("--run-dir", default="", help="run directory (default runs/<task>__s<seed>__<time>)")
    p.add_argument("--resume", action="store_true", help="continue the run in --run-dir from its checkpoint")
    p.add_argument("--init-from", default="", metavar="POLICY.zip",
                   help="warm start a fresh run: copy actor, critic and target-critic weights (and the entropy "
                        "coefficient when the file holds one) from a policy file of the same task "
                        "(runs/*/policy.zip, policies/pretrained/*.zip or a checkpoint/model.zip); the replay "
                        "buffer starts EMPTY, optimizers and step counters start fresh. Not with --resume")
    p.add_argument("--init-ent-coef", type=float, default=d.init_ent_coef,
                   help=f"initial entropy coefficient alpha (default {d.init_ent_coef}; with --init-from it is "
                        "used only when the policy file holds no entropy coefficient)")
    p.add_argument("--updates", type=int, default=None,
                   help=f"gradient updates per batched env step (paper: {d.updates_per_iter})")
    p.add_argument("--batch-size", type=int, default=None, help=f"replay batch per update (paper: {d.batch_size})")
    p.add_argument("--learning-rate", type=float, default=None, help=f"Adam step size (paper: {d.learning_rate})")
    p.add_argument("--target-update-interval", type=int, default=None,
                   help=f"sac: gradient updates between target-critic soft updates (paper: {d.target_update_interval})")
    p.add_argument("--tau", type=float, default=None, help=f"sac: target-critic soft-update rate (paper: {d.tau})")
    p.add_argument("--n-steps", type=int, default=None,
                   help=f"n-step returns: each TD target sums n rewards (paper: {d.n_steps})")
    p.add_argument("--buffer-size", type=int, default=None, help=f"replay transitions (paper: {d.buffer_size})")
    p.add_argument("--learning-starts", type=int, default=None,
                   help=f"random transitions before the first update (paper: {d.learning_starts})")
    p.add_argument("--checkpoint-minutes", type=float, default=d.checkpoint_minutes)
    p.add_argument("--first-checkpoint-minutes", type=float, default=d.first_checkpoint_minutes,
                   help="the first checkpoint comes after this many minutes, then every --checkpoint-minutes")
    p.add_argument("--eval-minutes", type=float, default=d.eval_minutes,
                   help="deterministic evaluation on fixed seeds every MIN minutes (eval.csv; 0 = off)")
    p.add_argument("--eval-every-steps", type=int, default=d.eval_every_steps,
                   help="also evaluate every N env steps (0 = off)")
    p.add_argument("--eval-episodes", type=int, default=d.eval_episodes, help="episodes per evaluation")
    p.add_argument("--eval-stochastic", action="store_true",
                   help="also evaluate the stochastic policy on the same episodes")
    p.add_argument("--time-limit", type=float, default=0.0, metavar="MIN",
                   help="stop (checkpoint + policy) after MIN minutes of wall-clock in this session")
    p.add_argument("--no-replay-checkpoint", action="store_true", help="do not save the replay buffer")
    p.add_argument("--threads", type=int, default=d.torch_threads, help="torch threads")
    p.add_argument("--precision", choices=PRECISIONS, default=d.precision,
                   help="how the SAC updates compute: auto (default) runs them in bfloat16, compiled, when the CPU "
                        "has bfloat16 instructions and a C++ compiler is present (about half the float32 iteration "
                        "time, the same learning curve: BENCHMARKS.md §6), else float32 with a notice; float32 is "
                        "the paper's precision")
    p.add_argument("--bf16-layout", choices=BF16_LAYOUTS, default=d.bf16_layout,
                   help="in bfloat16: all (default) runs every layer in bfloat16, float32_io keeps the input/output "
                        "layers and LayerNorms in float32 (slower)")
    p.add_argument("--compile", action=argparse.BooleanOptionalAction, default=None,
                   help="each SAC update as one torch.compile-d function (default: with bfloat16 when a C++ compiler "
                        "is present; the first compile takes about 45 s on 2 cores and is cached for later runs)")
    p.add_argument("--log-interval", type=float, default=d.log_interval_s, help="seconds between log lines")
    p.add_argument("--device", default=d.device,
                   help="torch device of the SAC networks and replay sampling: cpu (default), cuda or cuda:N; the "
                        "simulator always runs on the CPU")
    a = p.parse_args(argv)
    if a.resume and not a.run_dir:
        p.error("--resume needs --run-dir")
    if a.resume and a.init_from:
        p.error("--init-from starts a fresh run from a policy's weights; it cannot be combined with --resume")
    if a.init_ent_coef <= 0:
        p.error("--init-ent-coef must be positive")
    if not a.resume and not a.task:
        p.error("TASK is required")
    if a.steps < 1 or any(v is not None and v < 1 for v in (a.envs, a.updates, a.batch_size, a.policy_delay,
                                                           a.n_steps, a.target_update_interval)):
        p.error("--steps, --envs, --updates, --batch-size, --policy-delay, --n-steps and --target-update-interval "
                "must be positive")
    if a.tau is not None and not 0 < a.tau <= 1:
        p.error("--tau must be in (0, 1]")
    if a.learning_rate is not None and not a.learning_rate > 0:
        p.error("--learning-rate must be positive")

    try:  # before any work: a run directory that cannot be written loses nothing
        check_device(a.device)
        if a.compile:
            check_compiler()
    except TrainError as exc:
        print(f"rodlab train: {exc}", file=sys.stderr)
        return 2
    try:
        check_output_path(a.run_dir or "runs", folder=True)
    except ValueError as exc:
        print(f"rodlab train: --run-dir: {exc}", file=sys.stderr)
        return 2
    chosen = {k: v for k, v in dict(num_envs=a.envs, updates_per_iter=a.updates, batch_size=a.batch_size,
                                     learning_rate=a.learning_rate, buffer_size=a.buffer_size,
                                     learning_starts=a.learning_starts, algorithm=a.algorithm,
                                     policy_delay=a.policy_delay, n_steps=a.n_steps, tau=a.tau,
                                     target_update_interval=a.target_update_interval).items() if v is not None}
    args = Args(**{**preset_settings(a.preset), **chosen}, task=a.task, total_steps=a.steps, seed=a.seed,
                run_dir=a.run_dir, checkpoint_minutes=a.checkpoint_minutes,
                save_replay_buffer=not a.no_replay_checkpoint, torch_threads=a.threads,
                log_interval_s=a.log_interval, time_limit_minutes=a.time_limit, init_from=a.init_from,
                init_ent_coef=a.init_ent_coef, first_checkpoint_minutes=a.first_checkpoint_minutes,
                eval_minutes=a.eval_minutes, eval_every_steps=a.eval_every_steps, eval_episodes=a.eval_episodes,
                eval_stochastic=a.eval_stochastic, precision=a.precision, bf16_layout=a.bf16_layout,
                compile_updates=a.compile, device=a.device)
    if a.resume:
        cfg = os.path.join(a.run_dir, "config.json")
        try:
            saved_envs = json.load(open(cfg))["args"]["num_envs"]
        except (OSError, KeyError, json.JSONDecodeError) as exc:
            print(f"rodlab train: cannot read {cfg}: {exc}", file=sys.stderr)
            return 2
        if a.envs is not None and a.envs != saved_envs:
            print(f"rodlab train: --resume keeps the run's {saved_envs} envs (got --envs {a.envs})", file=sys.stderr)
            return 2
        args.num_envs = saved_envs
    try:
        run_dir = train(args, resume=a.resume, started_at=STARTED_AT)
    except TrainError as exc:
        print(f"rodlab train: {exc}", file=sys.stderr)
        return 2
    print(f"run directory: {run_dir}  (policy: {run_dir / 'policy.zip'})")
    return 0


# ----------------------------------------------------------------------------------------- eval
def eval_main(argv: list[str]) -> int:
    _threads_env()
    p = argparse.ArgumentParser(prog="rodlab eval", description="Evaluate a policy file on a task "
                                "(paper's average discounted return + task metrics).")
    p.add_argument("policy", help="policy .zip (policies/pretrained/*.zip, runs/*/policy.zip), 'random', "
                                   "'inverse-statics' (a model-based baseline; reaching tasks) or 'trajectory' "
                                   "(receding-horizon trajectory optimisation; Follow Target)")
    p.add_argument("--task", default=None, help="task (default: the one stored in the policy file)")
    p.add_argument("--episodes", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--seeds", type=int, default=1, help="evaluate seeds seed..seed+n-1")
    p.add_argument("--envs", type=int, default=None, help="parallel envs (default min(episodes, 100))")
    p.add_argument("--stochastic", action="store_true", help="sample actions instead of the mean")
    p.add_argument("--backend", choices=("dismech", "elastica"), default="dismech",
                   help="simulator of the task: rodlab's implicit DER (default) or PyElastica (docs/tasks.md §1.6; "
                        "needs the peers extra)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--record", default=None, metavar="FILE.rrd",
                   help="also record the evaluated episodes to this rerun file (written atomically; its folder is "
                        "checked for writing before the evaluation starts)")

    add_progress_flag(p)
    p.add_argument("--trust-pickle", action="store_true",
                   help="also load a full stable-baselines3 checkpoint (checkpoint/model.zip): it is unpickled, "
                        "which runs code stored in the file; only for files you made or trust")
    a = p.parse_args(argv)
    import contextlib

    import torch

    torch.set_num_threads(1)
    from policies.learning import PolicyLoadError, TrainError, evaluate

    total = max(1, a.episodes) * max(1, a.seeds)
    bar = progress_bar(total, desc="rodlab eval", unit="episode", enabled=progress_wanted(a.progress, json_output=a.json))

    def on_step(step) -> None:  # episodes finished so far (the bar's ETA), never past the total
        bar.update(min(int(step.done.sum()), total - bar.n) if hasattr(bar, "n") else 0)

    try:
        if a.record:
            check_output_path(a.record, suffix=".rrd")  # before the evaluation: nothing is lost
            from policies.recording import record_hook

            hook_cm = record_hook(a.record, episodes=a.episodes, meta={"policy": a.policy, "seed": a.seed})
        else:
            hook_cm = contextlib.nullcontext(None)
        with hook_cm as hook:
            res = evaluate(a.policy, a.task, episodes=a.episodes, seed=a.seed, num_envs=a.envs,
                           deterministic=not a.stochastic, eval_seeds=a.seeds, env_hook=hook,
                           trust_pickle=a.trust_pickle, callback=on_step, backend=a.backend)
    except (PolicyLoadError, TrainError, ValueError) as exc:
        bar.close()
        print(f"rodlab eval: {exc}", file=sys.stderr)
        return 2
    bar.close()
    if a.json:
        print(json.dumps(res))
        return 0
    print(f"task {res['task']}  policy {res['policy']}  {count(res['episodes'], 'episode')}  seed {res['seed']}")
    print(f"  average discounted return  {res['avg_discounted_return_mean']:.2f} ± {res['avg_discounted_return_std']:.2f}"
          f"   (undiscounted return {res['return_mean']:.2f} ± {res['return_std']:.2f})")
    for key in ("final_tip_error", "final_orientation_error_deg", "final_yaw_error_deg"):
        if f"{key}_mean" in res:
            print(f"  {key:<28}{res[key + '_mean']:.4f} ± {res[key + '_std']:.4f}")
    for key in ("reached_rate", "ever_reached_rate", "min_tip_error_mean", "episode_length_mean", "failures"):
        if key in res:
            print(f"  {key:<28}{res[key]}")
    return 0


# ----------------------------------------------------------------------------------------- bench train
def bench_train(task: str, *, envs: int = 500, iters: int = 20, warmup: int = 3, seed: int = 0,
                threads: int = 1, speed=None, device: str = "cpu", batch_size: int | None = None,
                updates: int | None = None) -> dict:
    """Time training iterations (one batched env step + ``updates`` gradient updates of ``batch_size``; the
    training defaults when None).

    Returns ms per iteration split into policy (action sampling), env step, buffer add and updates.
    The replay buffer is first filled with ``learning_starts`` random transitions (untimed).
    """
    import numpy as np
    import torch

    from policies.learning import Args, build_sac, check_device, make_sb3_env

    torch.set_num_threads(threads)
    d = Args()
    args = Args(task=task, num_envs=envs, total_steps=max(envs * (iters + warmup + 10), 20_000), seed=seed,
                device=check_device(device), batch_size=batch_size or d.batch_size,
                updates_per_iter=updates or d.updates_per_iter)
    t_build = time.perf_counter()
    env = make_sb3_env(task, envs, seed)
    model = build_sac(args, env)

    speed = speed or SpeedSettings()
    apply_speed_settings(model, speed)  # settings to try (policies/learning/train_speed.py)
    from stable_baselines3.common.logger import configure

    model.set_logger(configure(None, [""]))
    rb = model.replay_buffer
    obs = env.reset()
    build_s = time.perf_counter() - t_build
    while rb.size() * envs < max(args.learning_starts, args.batch_size):
        act = np.stack([env.action_space.sample() for _ in range(envs)])
        nobs, rew, done, infos = env.step(act)
        rb.add(obs, nobs, act, rew, done, infos)
        obs = nobs
    rows, t_warm, warmup_s = [], time.perf_counter(), 0.0
    for it in range(warmup + iters):
        if it == warmup:
            warmup_s = time.perf_counter() - t_warm  # the untimed iterations: compiling (or loading) compiled updates
        t0 = time.perf_counter()
        act, _ = model.predict(obs, deterministic=False)
        t1 = time.perf_counter()
        nobs, rew, done, infos = env.step(act)
        t2 = time.perf_counter()
        rb.add(obs, nobs, model.policy.scale_action(act), rew, done, infos)
        t3 = time.perf_counter()
        model.train(gradient_steps=args.updates_per_iter, batch_size=args.batch_size)
        _sync(model)
        t4 = time.perf_counter()
        obs = nobs
        if it >= warmup:
            rows.append((t1 - t0, t2 - t1, t3 - t2, t4 - t3, t4 - t0))
    env.close()
    r = 1e3 * np.array(rows)
    names = ["policy_ms", "env_step_ms", "buffer_add_ms", "update_ms", "iteration_ms"]
    out = {"task": task, "envs": envs, "iters": iters, "updates_per_iter": args.updates_per_iter,
           "batch_size": args.batch_size, "torch_threads": threads, "device": args.device,
           "setup_s": round(build_s, 2), "warmup_s": round(warmup_s, 2),
           "speed_settings": speed.label()}
    for j, nm in enumerate(names):
        out[nm] = round(float(np.median(r[:, j])), 2)
        out[nm.replace("_ms", "_ms_mean")] = round(float(r[:, j].mean()), 2)
    out["env_steps_per_s"] = round(envs / (out["iteration_ms"] / 1e3), 1)
    return out


def _sync(model) -> None:
    """Wait for the GPU's queued work (the updates' kernels) so that the timer sees it."""
    if model.device.type == "cuda":
        import torch

        torch.cuda.synchronize(model.device)


def bench_train_main(argv: list[str]) -> int:
    _threads_env(argv)
    from policies.learning import BF16_LAYOUTS

    p = argparse.ArgumentParser(prog="rodlab bench train", description="Time one training iteration "
                                "(batched env step + 4 SAC updates of batch 1024), split into env/update time.")
    p.add_argument("--task", required=True)
    p.add_argument("--envs", type=int, default=500)
    p.add_argument("--iters", type=int, default=20)
    p.add_argument("--warmup", type=int, default=3)
    p.add_argument("--threads", type=int, default=1, help="torch threads")
    p.add_argument("--compile", action="store_true",
                   help="each SAC update as one torch.compile-d function (as rodlab train --compile)")
    p.add_argument("--bf16", action="store_true", help="updates under bfloat16 autocast")
    p.add_argument("--bf16-layout", choices=BF16_LAYOUTS, default="float32_io",
                   help="with --bf16: which layers stay float32 (as rodlab train --bf16-layout)")
    p.add_argument("--device", default="cpu", help="torch device of the updates: cpu (default), cuda or cuda:N")
    p.add_argument("--batch-size", type=int, default=None, help="replay batch of each update (default: training's)")
    p.add_argument("--updates", type=int, default=None, help="updates per iteration (default: training's)")
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    if (a.batch_size is not None and a.batch_size < 1) or (a.updates is not None and a.updates < 1):
        p.error("--batch-size and --updates must be positive")
    from policies.learning import TrainError, check_compiler, configure_compile_cache

    try:
        if a.compile:
            check_compiler()
            configure_compile_cache()
        res = bench_train(a.task, envs=a.envs, iters=a.iters, warmup=a.warmup, threads=a.threads,
                          speed=SpeedSettings(compile=a.compile, bf16=a.bf16, bf16_layout=a.bf16_layout),
                          device=a.device, batch_size=a.batch_size, updates=a.updates)
    except TrainError as exc:
        print(f"rodlab bench train: {exc}", file=sys.stderr)
        return 2
    if a.json:
        print(json.dumps(res))
    else:
        print(f"{res['task']}: {res['envs']} envs, {res['updates_per_iter']} updates x batch {res['batch_size']}, "
              f"{res['torch_threads']} torch thread(s), median of {res['iters']} iterations")
        print(f"  iteration {res['iteration_ms']:.1f} ms = policy {res['policy_ms']:.1f} + env step "
              f"{res['env_step_ms']:.1f} + buffer {res['buffer_add_ms']:.1f} + updates {res['update_ms']:.1f} ms"
              f"   ({res['env_steps_per_s']:.0f} env steps/s)")
    return 0


# ----------------------------------------------------------------------------------------- bench env
def bench_env(task: str, *, envs: int = 500, steps: int = 50, warmup: int = 3, seed: int = 0,
              smoothing: str | None = None) -> dict:
    """Time one batched vector-env step (actions in, observations/rewards out) of ``envs`` envs.

    Actions are drawn uniformly in [-1, 1] before timing. Autoresets that fall in the timed window
    are included (their cost shows in the mean, rarely in the median); ``reset_all_ms`` is a separate
    full reset of every env (for the 3D obstacle task it includes sampling ``envs`` fences).
    """
    import numpy as np

    from policies import make_vec_env  # loads the vector env (torch, SB3)

    t0 = time.perf_counter()
    kw = {} if smoothing is None else {"smoothing": smoothing}
    venv = make_vec_env(task, envs, seed=seed, **kw)
    setup_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    venv.reset()
    reset_ms = 1e3 * (time.perf_counter() - t0)
    rng = np.random.default_rng(seed)
    shape = (envs,) + venv.single_action_space.shape
    acts = rng.uniform(-1, 1, (warmup + steps,) + shape).astype(np.float32)
    times = []
    fails = 0
    for k in range(warmup + steps):
        t0 = time.perf_counter()
        _, _, term, _, info = venv.step(acts[k])
        dt = time.perf_counter() - t0
        if k >= warmup:
            times.append(dt)
            fails += int(np.sum(info["failure_reason"] == "sim_failed"))
    venv.close()
    ms = 1e3 * np.asarray(times)
    return {"task": venv.task_id, "envs": envs, "steps": steps, "substeps": venv.config.substeps,
            "newton_max_iter": venv.config.newton_max_iter,
            "ms_per_env_step_median": round(float(np.median(ms)), 3),
            "ms_per_env_step_mean": round(float(ms.mean()), 3),
            "ms_per_env_step_p90": round(float(np.percentile(ms, 90)), 3),
            "reset_all_ms": round(reset_ms, 2), "setup_s": round(setup_s, 2), "sim_failures": fails,
            "numba_threads": _numba_threads(), "cpu_count": os.cpu_count()}


def _numba_threads() -> int | None:
    try:
        import numba

        return int(numba.get_num_threads())
    except Exception:  # pragma: no cover
        return None


def bench_env_main(argv: list[str]) -> int:
    """``rodlab bench env --task T --envs B [--steps n] [--warmup k] [--threads t] [--json]``."""
    p = argparse.ArgumentParser(prog="rodlab bench env", description="Time one batched vector-env step of a "
                                "task (policy action in, observations/rewards out), all envs in one simulator call.")
    p.add_argument("--task", required=True, help="short name (follow_target, follow_target_2d, ik4d, "
                   "tight_obstacles_2d, random_obstacles_3d) or gymnasium id")
    p.add_argument("--envs", type=int, default=500)
    p.add_argument("--steps", type=int, default=50, help="timed steps")
    p.add_argument("--warmup", type=int, default=3, help="untimed steps first (numba compile / caches)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--threads", type=int, default=None, help="numba threads (default: all cores)")
    p.add_argument("--smoothing", choices=("intended", "reference", "none"), default=None)
    p.add_argument("--json", action="store_true")
    a = p.parse_args(argv)
    if a.envs < 1 or a.steps < 1 or a.warmup < 0:
        p.error("--envs and --steps must be positive, --warmup >= 0")
    if a.threads is not None:
        if "numba" in sys.modules:  # thread pool may already run: change the active count, not the config
            import numba

            numba.set_num_threads(max(1, min(a.threads, numba.config.NUMBA_NUM_THREADS)))
        else:
            os.environ["NUMBA_NUM_THREADS"] = str(a.threads)

    try:
        gym_task_id(a.task)
    except ValueError as exc:
        print(f"rodlab bench env: {exc}", file=sys.stderr)
        return 2
    res = bench_env(a.task, envs=a.envs, steps=a.steps, warmup=a.warmup, seed=a.seed, smoothing=a.smoothing)
    if a.json:
        print(json.dumps(res))
    else:
        print(f"{res['task']}: {res['envs']} envs, {res['substeps']} sim steps x {res['newton_max_iter']} Newton "
              f"iterations per env step, {res['numba_threads']} numba thread(s)")
        print(f"  env step  median {res['ms_per_env_step_median']:.1f} ms  mean {res['ms_per_env_step_mean']:.1f} ms"
              f"  p90 {res['ms_per_env_step_p90']:.1f} ms   (full reset {res['reset_all_ms']:.0f} ms, "
              f"sim failures {res['sim_failures']})")
    return 0
