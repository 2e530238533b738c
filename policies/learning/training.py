"""Headless SAC training for rodlab tasks (docs/tasks.md §8), one ``Args`` dataclass per run.

A run directory holds::

    config.json           Args + git commit + library versions + spaces (written once, kept on resume)
    metrics.csv           one row per log interval: env steps, wall-clock [s], returns, timings
    tb/                   TensorBoard event files (rollout/*, train/*, time/*)
    eval.csv              one row per deterministic evaluation during training (policies/learning/train_monitor.py)
    checkpoint/           model.zip (SB3, with optimizers), replay.npz (filled rows only), state.json
    policy.zip            policy only (actor + critics, no optimizer/buffer), loadable by `rodlab eval`
    policy.json           sidecar: task, config, final training figures

Checkpoints (policies/learning/checkpoint.py) are written as one atomic unit, the first after
``first_checkpoint_minutes`` (1 min), then every ``checkpoint_minutes``, and when SIGINT/SIGTERM or the time
limit stops the run; every counted env step is in the saved replay buffer (none dropped at a stop).
``--resume`` reloads model, optimizers, entropy coefficient and replay buffer, and continues the step
count and wall-clock. Not restored: RNG states and the in-flight episodes (all envs start new episodes,
seeded from (seed, env steps so far)).

Warm start (``--init-from POLICY.zip``, ``Args.init_from``; fresh runs only, not with ``--resume``): the
network weights (actor, critics, target critics) are copied from a policy file written by ``save_policy``
(``runs/*/policy.zip``, ``policies/pretrained/*.zip``) or from a full SB3 checkpoint (``checkpoint/model.zip``),
after checking that it was trained on the same task with the same observation/action shapes and network
layout (``TrainError`` otherwise). The entropy coefficient is taken from the file when it holds one
(SB3 checkpoints; policy files written by this module since ``init_from`` exists store it in
``meta["extra"]["log_ent_coef"]``), else it starts at ``init_ent_coef``. Everything else starts fresh:
the replay buffer is EMPTY (it is refilled from the warm-started policy, after ``learning_starts`` random
transitions), the optimizers' moments, the step/update counters and the wall-clock start at zero.
"""
from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from sim.support.atomicio import write_bytes

from policies.learning.checkpoint import CheckpointError, find_checkpoint, read_state, resume_seed
from policies.learning.checkpoint import load_checkpoint as _load
from policies.learning.checkpoint import save_checkpoint as _save_checkpoint
from policies.learning.precision import (
    PRECISIONS,
    UpdatePlan,
    configure_compile_cache,
    find_compiler,
    plan_updates,
)
from policies.learning.sac import (
    BF16_LAYOUTS,
    POLICY_FORMAT,
    InplaceReLU,
    LayerNormSACPolicy,
    PolicyLoadError,
    RodSAC,
    load_policy,
    read_policy_meta,
    save_policy,
    sb3_policy_weights,
)
from policies.learning.sb3_env import TrainError, make_sb3_env, task_short_name
from policies.learning.train_monitor import monitor_callback

# a setting a saved config.json may still hold -> its value that runs as this version does
RETIRED_SETTINGS = {"compile_split_products": False}


def _translate_retired(data: dict) -> dict:
    """A saved config in this version's terms: ``bf16`` (true/false, before ``precision``) becomes ``precision``
    (bfloat16 / float32), and a run saved before ``precision`` keeps its layout and compile choice as saved."""
    data = dict(data)
    if "bf16" in data and "precision" not in data:
        data["precision"] = "bfloat16" if data.pop("bf16") else "float32"
        data.setdefault("bf16_layout", "float32_io")
        data.setdefault("compile_updates", False)
    return data


@dataclass
class Args:
    """Training configuration; defaults follow docs/tasks.md §8.1/8.2 (the paper's setup)."""

    task: str = "follow_target"
    num_envs: int = 500                     # parallel envs (one batched step per iteration)
    total_steps: int = 5_000_000            # env (control) steps summed over envs
    seed: int = 0
    run_dir: str = ""
    preset: str = "paper"                   # the named settings these started from (policies/learning/presets.py)
    algorithm: str = "sac"                  # sac (RodSAC, policies/learning/sac.py) or crossq (policies/learning/crossq.py)
    # SAC
    learning_rate: float = 1e-3
    adam_eps: float = 1e-7
    batch_size: int = 1024
    updates_per_iter: int = 4               # gradient updates per batched env step ("utd_ratio")
    buffer_size: int = 2_000_000            # transitions; capped at total_steps
    learning_starts: int = 1000             # transitions collected (uniform random actions) before updates
    tau: float = 0.005
    target_update_interval: int = 8         # gradient updates between target soft-updates
    gamma: float = 0.99
    n_steps: int = 1                        # n-step returns: TD targets over n rewards (SB3's n-step replay buffer)
    net_arch: list[int] = field(default_factory=lambda: [256, 256, 256])
    critic_net_arch: list[int] = field(default_factory=list)  # crossq: the critics' layers (empty: net_arch)
    n_critics: int = 2
    policy_delay: int = 3                   # crossq: critic updates per actor (and entropy) update
    entropy_in_target: bool = False         # reference: use_entropy_reward = False
    target_entropy_scale: float = 0.1       # target entropy = sum ln(scale * (high - low)) = -1.609 * dim
    init_ent_coef: float = 1.0
    init_from: str = ""                     # warm start: policy .zip to copy the weights from (fresh runs only)
    precision: str = "auto"                 # auto | bfloat16 | float32: how the updates compute, resolved against
                                            # the machine by policies/learning/precision.py (auto: compiled bfloat16 where
                                            # the CPU and a compiler allow it, else float32; docs/training.md)
    bf16_layout: str = "all"                # in bfloat16: all (every layer) or float32_io (input/output layers
                                            # and LayerNorms in float32); policies/learning/sac.py BF16_LAYOUTS
    compile_updates: bool | None = None     # each update one torch.compile-d function; None: as the precision
                                            # resolves (compiled with bfloat16 when a C++ compiler is present)
    # runtime
    torch_threads: int = 1
    checkpoint_minutes: float = 5.0
    first_checkpoint_minutes: float = 1.0   # the first checkpoint comes early, then every checkpoint_minutes
    time_limit_minutes: float = 0.0         # >0: stop (checkpoint + policy) after this wall time in this session
    save_replay_buffer: bool = True
    log_interval_s: float = 15.0
    device: str = "cpu"                     # torch device of the networks and replay sampling: cpu, cuda, cuda:N
    # deterministic evaluation during training (policies/learning/train_monitor.py); 0 disables a trigger
    eval_minutes: float = 3.0               # wall-clock between evaluations
    eval_every_steps: int = 0               # env steps between evaluations (tests, step-based curves)
    eval_episodes: int = 50                 # per evaluation (fixed seeds: the same episodes every time)
    eval_envs: int = 50                     # batched envs of the evaluation env
    eval_seed: int = 1_000_003              # fixed, independent of the training seed
    eval_stochastic: bool = False           # also evaluate the stochastic policy on the same episodes
    keep_best_policy: bool = True           # policy_best.zip = policy of the best evaluation so far

    def to_json(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: dict) -> "Args":
        names = {f.name for f in dataclasses.fields(cls)}
        data = _translate_retired(data)
        # settings that no longer exist, dropped from a saved config when they hold the value that behaves as now
        data = {k: v for k, v in data.items() if not (k in RETIRED_SETTINGS and v == RETIRED_SETTINGS[k])}
        unknown = sorted(set(data) - names)
        if unknown:
            raise TrainError(f"config has unknown keys {unknown}")
        return cls(**data)


# ------------------------------------------------------------------------------------ environments
def _timed(env):
    """Wrap a VecEnv so that ``last_step_time`` [s] holds the duration of the latest step."""
    from stable_baselines3.common.vec_env import VecEnvWrapper

    class TimedVecEnv(VecEnvWrapper):
        last_step_time = 0.0

        def reset(self):
            return self.venv.reset()

        def step_async(self, actions):
            self._t0 = time.perf_counter()
            self.venv.step_async(actions)

        def step_wait(self):
            out = self.venv.step_wait()
            self.last_step_time = time.perf_counter() - self._t0
            return out

    return TimedVecEnv(env)


def target_entropy(action_space, scale: float) -> float:
    """alf default: sum over action dims of ln(scale * (high - low)); -1.609*dim for [-1, 1], scale 0.1."""
    return float(np.sum(np.log(scale * (action_space.high - action_space.low))))


def check_compiler() -> str:
    """The C++ compiler that torch.compile's CPU back-end will call; ``TrainError`` when there is none."""
    path = find_compiler()
    if path is None:
        raise TrainError("--compile: torch.compile needs a C++ compiler on the PATH (g++, c++ or clang++; set CXX to "
                         "choose one); install one (Debian: apt-get install g++) or train without --compile")
    return path


def build_sac(args: Args, env):
    """A fresh ``RodSAC`` for ``env`` configured from ``args``."""

    return RodSAC(
        LayerNormSACPolicy, env, learning_rate=args.learning_rate,
        buffer_size=_buffer_size(args),
        learning_starts=args.learning_starts, batch_size=args.batch_size, tau=args.tau, gamma=args.gamma,
        train_freq=1, gradient_steps=args.updates_per_iter, ent_coef=f"auto_{args.init_ent_coef}",
        target_update_interval=args.target_update_interval,
        target_entropy=target_entropy(env.action_space, args.target_entropy_scale),
        entropy_in_target=args.entropy_in_target, adam_eps=args.adam_eps, **_replay_buffer(args),
        policy_kwargs=dict(net_arch=list(args.net_arch), n_critics=args.n_critics, activation_fn=InplaceReLU,
                           optimizer_kwargs=dict(eps=args.adam_eps, fused=True)),
        seed=args.seed, device=args.device, verbose=0)


ALGORITHMS = ("sac", "crossq")


def _replay_buffer(args: Args) -> dict:
    """The replay buffer's class and settings, named explicitly so that a checkpoint reloads the same kind: with
    ``n_steps`` > 1 SB3's n-step buffer, whose n and discount would otherwise fall back to its defaults on load."""
    if args.n_steps == 1:
        return dict(replay_buffer_kwargs=dict(handle_timeout_termination=True))
    from stable_baselines3.common.buffers import NStepReplayBuffer

    return dict(replay_buffer_class=NStepReplayBuffer,
                replay_buffer_kwargs=dict(handle_timeout_termination=True, n_steps=args.n_steps, gamma=args.gamma))


def build_crossq(args: Args, env):
    """A fresh ``RodCrossQ`` (policies/learning/crossq.py) for ``env`` configured from ``args``: the run's learning rate,
    batch, updates per env step, entropy target and coefficient as for SAC; no target networks (``tau`` and
    ``target_update_interval`` do not apply), batch renormalisation and sb3-contrib's Adam betas (0.5, 0.999)."""
    from torch import nn

    from policies.learning.crossq import RodCrossQ

    return RodCrossQ(
        "MlpPolicy", env, learning_rate=args.learning_rate, buffer_size=_buffer_size(args),
        learning_starts=args.learning_starts, batch_size=args.batch_size, gamma=args.gamma, train_freq=1,
        gradient_steps=args.updates_per_iter, ent_coef=f"auto_{args.init_ent_coef}",
        target_entropy=target_entropy(env.action_space, args.target_entropy_scale), policy_delay=args.policy_delay,
        **_replay_buffer(args),
        policy_kwargs=dict(net_arch=dict(pi=list(args.net_arch), qf=list(args.critic_net_arch or args.net_arch)),
                           n_critics=args.n_critics, activation_fn=nn.ReLU),
        seed=args.seed, device=args.device, verbose=0)


def build_model(args: Args, env):
    """A fresh model of the run's algorithm."""
    return build_crossq(args, env) if args.algorithm == "crossq" else build_sac(args, env)


def git_commit() -> str:
    try:
        root = Path(__file__).resolve().parent  # git finds the work tree of a checkout from the package folder
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, timeout=5)
        sha = out.stdout.strip() if out.returncode == 0 else "unknown (no commit yet)"
        dirty = subprocess.run(["git", "status", "--porcelain"], cwd=root, capture_output=True, text=True, timeout=5)
        return sha + ("+dirty" if dirty.stdout.strip() else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def warm_start(model, path: str | os.PathLike, task: str) -> dict:
    """Copy the network weights of the policy file ``path`` into ``model`` (a fresh ``RodSAC``) in place.

    Loads actor, critics and target critics (a policy-only zip stores no target critics: they start equal
    to the critics, as after ``load_policy``) and the entropy coefficient when the file holds one. The
    replay buffer, optimizer moments and counters are not touched (the buffer stays empty). Raises
    ``TrainError`` for a missing/unreadable file, another task, or mismatching shapes/network layout.
    Returns a JSON-able description of the source (for config.json).
    """
    import torch as th

    p = Path(path)
    if not p.is_file():
        raise TrainError(f"--init-from: policy file not found: {p}")
    try:
        meta = read_policy_meta(p)
    except PolicyLoadError as exc:
        raise TrainError(f"--init-from: {exc}") from None
    src_task = meta.get("task")
    if not src_task:
        raise TrainError(f"--init-from: {p} does not say which task it was trained on "
                         "(no task in meta.json / sidecar config.json)")
    try:
        src_task = task_short_name(src_task)
    except TrainError:
        pass
    if src_task != task:
        raise TrainError(f"--init-from: {p} was trained on task {src_task!r}, not {task!r}")
    log_ent = None
    try:
        if meta.get("format") == "sb3":
            pol, log_ent = sb3_policy_weights(p, model.policy)  # weights only: the file is never unpickled
        elif meta.get("format") == POLICY_FORMAT:
            pol, meta = load_policy(p, device=model.device)
            v = (meta.get("extra") or {}).get("log_ent_coef")
            log_ent = float(v) if v is not None else None
        else:
            raise TrainError(f"--init-from: {p}: unknown policy format {meta.get('format')!r}")
    except PolicyLoadError as exc:
        raise TrainError(f"--init-from: {exc}") from None
    except (KeyError, ValueError, RuntimeError, OSError, EOFError) as exc:
        raise TrainError(f"--init-from: cannot load {p} ({type(exc).__name__}: {exc})") from None
    for what, have, want in (("observation", pol.observation_space, model.observation_space),
                             ("action", pol.action_space, model.action_space)):
        if tuple(have.shape) != tuple(want.shape):
            raise TrainError(f"--init-from: {p} has {what} shape {tuple(have.shape)}, task {task!r} has "
                             f"{tuple(want.shape)}")
    if not (np.allclose(pol.action_space.low, model.action_space.low)
            and np.allclose(pol.action_space.high, model.action_space.high)):
        raise TrainError(f"--init-from: {p} has other action bounds than task {task!r}")
    sd, own = pol.state_dict(), model.policy.state_dict()
    bad = sorted(k for k in set(own) | set(sd) if k not in sd or k not in own or sd[k].shape != own[k].shape)
    if bad:
        raise TrainError(f"--init-from: the network in {p} (net_arch {meta.get('net_arch')}, n_critics "
                         f"{meta.get('n_critics')}) does not match this run's; differing parameters: {bad[:4]}")
    model.policy.load_state_dict(sd)  # in place: the optimizers keep pointing at the same tensors
    if log_ent is not None and isinstance(getattr(model, "log_ent_coef", None), th.Tensor):
        with th.no_grad():
            model.log_ent_coef.fill_(log_ent)
    return {"path": str(p), "task": src_task, "format": meta.get("format"),
            "log_ent_coef": log_ent, "ent_coef_from_file": log_ent is not None,
            "source_training": (meta.get("extra") or {}).get("training")}


def _log_ent_coef(model) -> float | None:
    import torch as th

    v = getattr(model, "log_ent_coef", None)
    return float(v.detach().reshape(-1)[0]) if isinstance(v, th.Tensor) else None


# ------------------------------------------------------------------------------------ checkpoints
def save_checkpoint(model, run_dir: Path, *, wall_s: float, save_buffer: bool) -> None:
    """Write one checkpoint of ``model`` into RUN_DIR/checkpoint/ (see policies/learning/checkpoint.py)."""

    _save_checkpoint(model, run_dir, wall_s=wall_s, save_buffer=save_buffer)


def load_checkpoint(args: Args, run_dir: Path, env):
    """-> (model, state dict). Replay buffer restored when present; raises TrainError when unusable."""

    try:
        return _load(run_dir, env, device=args.device, buffer_size=_buffer_size(args), algorithm=args.algorithm)
    except CheckpointError as exc:
        raise TrainError(f"--resume: {exc}") from None


def check_update_settings(args: Args) -> None:
    """``TrainError`` naming the option when the update settings name nothing or contradict each other (checked by
    ``train`` and, for every trial before any starts, by ``rodlab sweep``)."""
    if args.bf16_layout not in BF16_LAYOUTS:
        raise TrainError(f"--bf16-layout: expected one of {', '.join(BF16_LAYOUTS)}, got {args.bf16_layout!r}")
    if args.precision not in PRECISIONS:
        raise TrainError(f"--precision: expected one of {', '.join(PRECISIONS)}, got {args.precision!r}")
    if args.algorithm not in ALGORITHMS:
        raise TrainError(f"--algorithm: expected one of {', '.join(ALGORITHMS)}, got {args.algorithm!r}")
    if args.algorithm == "crossq" and (args.precision == "bfloat16" or args.compile_updates):
        raise TrainError("--algorithm crossq runs its updates eagerly in float32 (sb3-contrib's CrossQ); "
                         "--precision bfloat16 and --compile are SAC's")
    if args.n_steps < 1:
        raise TrainError(f"--n-steps must be at least 1, got {args.n_steps}")
    if args.policy_delay < 1:
        raise TrainError(f"--policy-delay must be at least 1, got {args.policy_delay}")
    if args.compile_updates:
        check_compiler()


def gradient_updates(args: Args, done_steps: int = 0) -> int:
    """The gradient updates a run of ``args`` still makes after ``done_steps`` env steps (one batched env step
    makes ``updates_per_iter`` once ``learning_starts`` transitions are collected)."""
    iters = max(0, args.total_steps - max(args.learning_starts, done_steps)) // max(1, args.num_envs)
    return iters * args.updates_per_iter


def update_plan(args: Args, done_steps: int = 0) -> UpdatePlan:
    """How this run's updates compute on this machine (``policies.learning.precision.plan_updates``)."""
    check_update_settings(args)
    if args.algorithm == "crossq":
        return UpdatePlan(bf16=False, bf16_layout=args.bf16_layout, compiled=False,
                          reason="CrossQ: sb3-contrib's eager float32 updates")
    try:
        return plan_updates(args.precision, device=args.device, gradient_updates=gradient_updates(args, done_steps),
                            bf16_layout=args.bf16_layout, compile_updates=args.compile_updates)
    except ValueError as exc:
        raise TrainError(f"--precision: {exc}") from None


def configure_updates(model, plan: UpdatePlan) -> None:
    """The run's update plan on a new or loaded model: bfloat16 and its layout, compiled updates (none of them is
    part of a checkpoint, so a resumed run plans them again from its config)."""
    model.set_update_settings(bf16=plan.bf16, bf16_layout=plan.bf16_layout, compile_updates=plan.compiled)


def _buffer_size(args: Args) -> int:
    return max(min(args.buffer_size, args.total_steps), args.num_envs * 2)


def check_device(name: str) -> str:
    """``name`` as a torch device string; raises ``TrainError`` for a malformed name or an absent GPU."""
    import torch as th

    try:
        dev = th.device(name)
    except (RuntimeError, TypeError) as exc:
        raise TrainError(f"--device: {name!r} is not a torch device (cpu, cuda, cuda:N): {exc}") from None
    if dev.type == "cuda":
        if not th.cuda.is_available():
            raise TrainError(f"--device {name}: this torch ({th.__version__}) sees no CUDA GPU")
        if dev.index is not None and dev.index >= th.cuda.device_count():
            raise TrainError(f"--device {name}: only {th.cuda.device_count()} CUDA device(s)")
    elif dev.type != "cpu":
        raise TrainError(f"--device {name}: only cpu and cuda devices are supported")
    return str(dev)


# ------------------------------------------------------------------------------------ main entry
def train(args: Args, *, resume: bool = False, started_at: float | None = None) -> Path:
    """Train (or resume) a run; returns the run directory. Writes policy.zip at the end or on stop.

    ``started_at``: the ``time.perf_counter()`` at which the command started (``rodlab train``, a sweep trial), so
    a fresh run's wall-clock counts its start-up (imports, env and model set-up) too; None counts from here."""
    started_at = time.perf_counter() if started_at is None else started_at
    import torch as th
    from stable_baselines3.common.logger import configure

    th.set_num_threads(max(1, args.torch_threads))
    run_dir = Path(args.run_dir) if args.run_dir else Path("runs") / f"{args.task}__s{args.seed}__{time.strftime('%Y%m%d-%H%M%S')}"
    if resume and args.init_from:
        raise TrainError("--init-from starts a fresh run from a policy's weights; it cannot be combined with "
                         "--resume (which continues the run's own checkpoint)")
    if resume:
        cfg_path = run_dir / "config.json"
        if not cfg_path.is_file():
            raise TrainError(f"--resume: {cfg_path} not found")
        saved = Args.from_json(json.loads(cfg_path.read_text())["args"])
        if args.task and task_short_name(args.task) != saved.task:
            raise TrainError(f"--resume: run in {run_dir} trains task {saved.task!r}, not {args.task!r}")
        saved.total_steps = args.total_steps
        saved.time_limit_minutes = args.time_limit_minutes
        saved.device = args.device  # a run may continue on another device (the checkpoint maps its tensors)
        saved.run_dir = str(run_dir)
        args = saved
    else:
        args.task = task_short_name(args.task)
        args.run_dir = str(run_dir)
        if find_checkpoint(run_dir) is not None:
            raise TrainError(f"{run_dir} already holds a checkpoint; pass --resume or choose another --run-dir")
        if args.init_from and not Path(args.init_from).is_file():  # fail before creating the run directory
            raise TrainError(f"--init-from: policy file not found: {args.init_from}")
    args.device = check_device(args.device)  # before the run directory is made
    check_update_settings(args)
    run_dir.mkdir(parents=True, exist_ok=True)

    state = read_state(run_dir) if resume else None
    plan = update_plan(args, int(state["num_timesteps"]) if state else 0)
    if plan.compiled:
        configure_compile_cache()
    print(plan.notice(), file=sys.stderr, flush=True)
    if resume and state is None:
        raise TrainError(f"--resume: no checkpoint in {run_dir / 'checkpoint'} (expected model.zip and state.json)")
    # a resumed run starts fresh episodes from its own seed (not a replay of the first episodes)
    env_seed = resume_seed(args.seed, int(state["num_timesteps"])) if state else args.seed
    env = _timed(make_sb3_env(args.task, args.num_envs, env_seed))
    if resume:
        model, state = load_checkpoint(args, run_dir, env)
        wall_offset = float(state.get("wall_s", 0.0))
        model.set_random_seed(env_seed)  # SB3's load re-seeds the env with the run's seed: use the derived one
    else:
        model = build_model(args, env)
        wall_offset = time.perf_counter() - started_at  # the start-up belongs to the run's wall-clock
    configure_updates(model, plan)
    init_info = None
    if args.init_from and not resume:
        try:
            init_info = warm_start(model, args.init_from, args.task)
        except TrainError:
            env.close()
            raise
        print(f"warm start from {args.init_from} (actor + critics"
              f"{' + entropy coefficient' if init_info['ent_coef_from_file'] else ''}; empty replay buffer)",
              file=sys.stderr, flush=True)
    if not resume or not (run_dir / "config.json").exists():
        import gymnasium
        import stable_baselines3
        cfg = {"args": args.to_json(), "git_commit": git_commit(), "algorithm": ("RodCrossQ (policies/learning/crossq.py)" if args.algorithm == "crossq"
                                                            else "RodSAC (policies/learning/sac.py)"),
               "versions": {"torch": th.__version__, "stable_baselines3": stable_baselines3.__version__,
                            "gymnasium": gymnasium.__version__, "numpy": np.__version__},
               "obs_shape": list(env.observation_space.shape), "action_shape": list(env.action_space.shape),
               "updates": plan.to_json(), "target_entropy": float(model.target_entropy), "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
        if init_info is not None:
            cfg["init_from"] = init_info
        write_bytes(run_dir / "config.json", json.dumps(cfg, indent=1).encode())
    model.set_logger(configure(str(run_dir / "tb"), ["tensorboard"]))

    stop_flag = {"stop": False}

    def _handler(signum, frame):
        if stop_flag["stop"] and signum == signal.SIGINT:
            raise KeyboardInterrupt
        stop_flag["stop"] = True
        print(f"\nsignal {signal.Signals(signum).name}: checkpointing and stopping ...", file=sys.stderr, flush=True)

    old = {s: signal.signal(s, _handler) for s in (signal.SIGINT, signal.SIGTERM)}
    monitor = monitor_callback(args, run_dir, wall_offset, stop_flag,
                               eval_s_offset=float((state or {}).get("eval_s_total", 0.0)))
    try:
        remaining = args.total_steps - model.num_timesteps
        if remaining > 0:
            model.learn(total_timesteps=remaining, callback=monitor, log_interval=None, reset_num_timesteps=not resume)
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        wall = monitor.wall() if hasattr(monitor, "t_start") else wall_offset
        eval_s = float(getattr(monitor, "eval_s_total", (state or {}).get("eval_s_total", 0.0)))
        _save_checkpoint(model, run_dir, wall_s=wall, save_buffer=args.save_replay_buffer,
                         extra={"eval_s_total": eval_s})
        summary = {"env_steps": int(model.num_timesteps), "gradient_updates": int(model._n_updates),
                   "wall_s": round(wall, 1), "stopped_early": stop_flag["stop"],
                   "stopped_by_time_limit": bool(stop_flag.get("time_limit")),
                   "last_train_return": float(monitor.last["ret"]) if hasattr(monitor, "last") else None,
                   "last_train_avg_disc_return": float(monitor.last["dret"]) if hasattr(monitor, "last") else None,
                   "last_eval": getattr(monitor, "last_eval_result", None), "eval_s_total": round(eval_s, 2),
                   "updates": plan.to_json()}
        save_policy(model, run_dir / "policy.zip", task=args.task,
                    extra={"training": summary, "log_ent_coef": _log_ent_coef(model)})
        side = {"task": args.task, "config": args.to_json(), "git_commit": git_commit(), "training": summary}
        write_bytes(run_dir / "policy.json", json.dumps(side, indent=1).encode())
        env.close()
    return run_dir


__all__ = ["Args", "TrainError", "PolicyLoadError", "train", "make_sb3_env", "task_short_name", "build_sac",
           "build_crossq", "build_model",
           "save_checkpoint", "load_checkpoint", "target_entropy", "warm_start"]
