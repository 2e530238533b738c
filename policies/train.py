"""Headless SAC training for rodlab tasks (docs/tasks.md §8), one ``Args`` dataclass per run.

A run directory holds::

    config.json           Args + git commit + library versions + spaces (written once, kept on resume)
    metrics.csv           one row per log interval: env steps, wall-clock [s], returns, timings
    tb/                   TensorBoard event files (rollout/*, train/*, time/*)
    checkpoint/           model.zip (SB3, with optimizers), replay.npz (filled rows only), state.json
    policy.zip            policy only (actor + critics, no optimizer/buffer), loadable by `rodlab eval`
    policy.json           sidecar: task, config, final training figures

Checkpoints are written atomically every ``checkpoint_minutes`` and when SIGINT/SIGTERM arrives;
``--resume`` reloads model, optimizers, entropy coefficient and replay buffer, and continues the step
count and wall-clock. Not restored: RNG states and the in-flight episodes (all envs are reset).

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

import csv
import dataclasses
import io
import json
import math
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from policies.sac import PolicyLoadError, _atomic_write_bytes, save_policy


class TrainError(Exception):
    """Bad training input (unknown task, inconsistent resume) with a readable message."""


@dataclass
class Args:
    """Training configuration; defaults follow docs/tasks.md §8.1/8.2 (the paper's setup)."""

    task: str = "follow_target"
    num_envs: int = 500                     # parallel envs (one batched step per iteration)
    total_steps: int = 5_000_000            # env (control) steps summed over envs
    seed: int = 0
    run_dir: str = ""
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
    net_arch: list[int] = field(default_factory=lambda: [256, 256, 256])
    n_critics: int = 2
    entropy_in_target: bool = False         # reference: use_entropy_reward = False
    target_entropy_scale: float = 0.1       # target entropy = sum ln(scale * (high - low)) = -1.609 * dim
    init_ent_coef: float = 1.0
    init_from: str = ""                     # warm start: policy .zip to copy the weights from (fresh runs only)
    # runtime
    torch_threads: int = 1
    checkpoint_minutes: float = 5.0
    time_limit_minutes: float = 0.0         # >0: stop (checkpoint + policy) after this wall time in this session
    save_replay_buffer: bool = True
    log_interval_s: float = 15.0
    device: str = "cpu"

    def to_json(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: dict) -> "Args":
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - names)
        if unknown:
            raise TrainError(f"config has unknown keys {unknown}")
        return cls(**data)


# ------------------------------------------------------------------------------------ environments
def resolve_task(name: str) -> str:
    """Short task name (policies.TASKS) or a gymnasium id (tests: 'Pendulum-v1') -> canonical name."""
    import policies

    tasks = getattr(policies, "TASKS", {}) or {}
    if name in tasks:
        return name
    for short, tid in dict(tasks).items():
        if name == tid:
            return short
    import gymnasium as gym

    if name in gym.registry:
        return name
    known = ", ".join(sorted(tasks)) or "(no rodlab tasks registered yet)"
    raise TrainError(f"unknown task {name!r}; known tasks: {known} (or a gymnasium id such as Pendulum-v1)")


def make_sb3_env(task: str, num_envs: int, seed: int):
    """SB3 VecEnv for a rodlab task (batched env + adapter) or a gymnasium id (DummyVecEnv)."""
    import policies

    task = resolve_task(task)
    if task in (getattr(policies, "TASKS", {}) or {}):
        venv = policies.make_vec_env(task, num_envs, seed=seed)
        adapter = policies.SB3VecEnvAdapter(venv)
        adapter.last_raw_info = {}
        raw_step = venv.step

        def step_and_keep_info(actions):  # keep the batched info dict (per-term rewards) for logging
            out = raw_step(actions)
            adapter.last_raw_info = out[4]
            return out

        venv.step = step_and_keep_info
        return adapter
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv

    return make_vec_env(task, n_envs=num_envs, seed=seed, vec_env_cls=DummyVecEnv)


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


def build_model(args: Args, env):
    """A fresh ``RodSAC`` for ``env`` configured from ``args``."""

    from policies.sac import InplaceReLU, LayerNormSACPolicy, RodSAC

    return RodSAC(
        LayerNormSACPolicy, env, learning_rate=args.learning_rate,
        buffer_size=max(min(args.buffer_size, args.total_steps), args.num_envs * 2),
        learning_starts=args.learning_starts, batch_size=args.batch_size, tau=args.tau, gamma=args.gamma,
        train_freq=1, gradient_steps=args.updates_per_iter, ent_coef=f"auto_{args.init_ent_coef}",
        target_update_interval=args.target_update_interval,
        target_entropy=target_entropy(env.action_space, args.target_entropy_scale),
        entropy_in_target=args.entropy_in_target, adam_eps=args.adam_eps,
        replay_buffer_kwargs=dict(handle_timeout_termination=True),
        policy_kwargs=dict(net_arch=list(args.net_arch), n_critics=args.n_critics, activation_fn=InplaceReLU,
                           optimizer_kwargs=dict(eps=args.adam_eps, fused=True)),
        seed=args.seed, device=args.device, verbose=0)


def git_commit() -> str:
    try:
        root = Path(__file__).resolve().parent.parent
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

    from policies.sac import POLICY_FORMAT, load_policy, read_policy_meta, sb3_policy_weights

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
        src_task = resolve_task(src_task)
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
    """Atomically write checkpoint/model.zip, replay.npz (filled rows) and state.json (written last)."""
    ck = run_dir / "checkpoint"
    ck.mkdir(parents=True, exist_ok=True)
    buf = io.BytesIO()
    model.save(buf)
    _atomic_write_bytes(ck / "model.zip", buf.getvalue())
    if save_buffer:
        rb = model.replay_buffer
        n = rb.buffer_size if rb.full else rb.pos
        tmp = ck / "replay.npz.tmp"
        with open(tmp, "wb") as f:
            np.savez(f, observations=rb.observations[:n], next_observations=rb.next_observations[:n],
                     actions=rb.actions[:n], rewards=rb.rewards[:n], dones=rb.dones[:n], timeouts=rb.timeouts[:n],
                     pos=np.int64(rb.pos), full=np.bool_(rb.full))
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, ck / "replay.npz")
    state = {"num_timesteps": int(model.num_timesteps), "n_updates": int(model._n_updates), "wall_s": wall_s,
             "replay_saved": bool(save_buffer), "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    _atomic_write_bytes(ck / "state.json", json.dumps(state, indent=1).encode())


def load_checkpoint(args: Args, run_dir: Path, env):
    """-> (model, state dict). Replay buffer restored when present; raises TrainError when unusable."""
    from policies.sac import RodSAC

    ck = run_dir / "checkpoint"
    if not (ck / "state.json").is_file() or not (ck / "model.zip").is_file():
        raise TrainError(f"--resume: no checkpoint in {ck} (expected model.zip and state.json)")
    state = json.loads((ck / "state.json").read_text())
    try:
        model = RodSAC.load(ck / "model.zip", env=env, device=args.device)
    except Exception as exc:  # SB3 raises assorted errors on corrupt zips / space mismatch
        raise TrainError(f"--resume: cannot load {ck / 'model.zip'}: {exc}") from None
    model.num_timesteps = int(state["num_timesteps"])
    want = max(min(args.buffer_size, args.total_steps), args.num_envs * 2)
    if want > model.buffer_size:  # the run was extended (--steps larger): grow the buffer (capped at total steps)
        from stable_baselines3.common.buffers import ReplayBuffer

        model.buffer_size = want
        model.replay_buffer = ReplayBuffer(want, model.observation_space, model.action_space, device=model.device,
                                           n_envs=model.n_envs, handle_timeout_termination=True)
    if (ck / "replay.npz").is_file():
        rb = model.replay_buffer
        with np.load(ck / "replay.npz") as z:
            n = z["observations"].shape[0]
            if n > rb.buffer_size or z["observations"].shape[1:] != rb.observations.shape[1:]:
                raise TrainError(f"--resume: replay buffer shape {z['observations'].shape} does not fit "
                                 f"{rb.observations.shape}")
            for key in ("observations", "next_observations", "actions", "rewards", "dones", "timeouts"):
                getattr(rb, key)[:n] = z[key]
            rb.pos, rb.full = int(z["pos"]) % rb.buffer_size, bool(z["full"]) or n == rb.buffer_size
    else:
        print("resume: no replay buffer in checkpoint, starting with an empty one", file=sys.stderr)
    return model, state


# ------------------------------------------------------------------------------------ monitoring
def _monitor_callback(args: Args, run_dir: Path, wall_offset: float, stop_flag: dict):
    from stable_baselines3.common.callbacks import BaseCallback

    class RunMonitor(BaseCallback):
        """Episode statistics (incl. alf's average discounted return), logs, progress and checkpoints."""

        def _on_training_start(self) -> None:
            n = self.training_env.num_envs
            self.ret = np.zeros(n)
            self.disc_sum = np.zeros(n)      # sum_l c_l r_l, c_l = (1 - gamma^l) / (1 - gamma)
            self.disc_c = np.zeros(n)
            self.length = np.zeros(n, dtype=np.int64)
            self.terms: dict[str, np.ndarray] = {}
            self.done_eps: list[tuple[float, float, int]] = []
            self.done_terms: dict[str, list[float]] = {}
            self.t_start = time.perf_counter()
            self.steps_start = self.num_timesteps
            self.last_log = self.last_ck = time.perf_counter()
            self.env_t, self.upd_t, self.iters = [], [], 0
            self.last_iter_t = time.perf_counter()
            self.iter_t: list[float] = []
            self.win_rew_sum, self.win_rew_n = 0.0, 0
            self.last = {"ret": math.nan, "dret": math.nan}
            self.tty = sys.stderr.isatty()
            self.bar = None
            if self.tty:
                from tqdm import tqdm
                self.bar = tqdm(total=args.total_steps, initial=self.num_timesteps, unit="step", unit_scale=True,
                                dynamic_ncols=True, mininterval=1.0)
            csv_path = run_dir / "metrics.csv"
            new = not csv_path.exists()
            self.csv_f = open(csv_path, "a", newline="")
            self.csv = csv.writer(self.csv_f)
            if new:
                self.csv.writerow(["env_steps", "wall_s", "episodes", "return_mean", "avg_disc_return_mean",
                                   "ep_len_mean", "env_step_ms", "update_ms", "iter_ms", "steps_per_s",
                                   "step_reward_mean", "n_updates"])

        def wall(self) -> float:
            return wall_offset + time.perf_counter() - self.t_start

        def _on_step(self) -> bool:
            now = time.perf_counter()
            self.iter_t.append(now - self.last_iter_t)
            self.last_iter_t = now
            self.iters += 1
            env = self.training_env
            self.env_t.append(getattr(env, "last_step_time", math.nan))
            self.upd_t.append(self.model.last_update_time)
            self.model.last_update_time = 0.0
            rew = np.asarray(self.locals["rewards"], dtype=np.float64)
            dones = np.asarray(self.locals["dones"], dtype=bool)
            self.length += 1
            self.disc_c = 1.0 + args.gamma * self.disc_c
            self.ret += rew
            self.win_rew_sum += float(rew.sum())
            self.win_rew_n += rew.size
            self.disc_sum += self.disc_c * rew
            raw = getattr(env, "last_raw_info", None)  # batched info of rodlab envs: "reward/<term>" (B,)
            if isinstance(raw, dict):
                for k, v in raw.items():
                    if k.startswith("reward/") and np.shape(v) == rew.shape:
                        self.terms.setdefault(k, np.zeros(len(rew)))
                        self.terms[k] += np.nan_to_num(np.asarray(v, dtype=np.float64))
            for i in np.flatnonzero(dones):
                self.done_eps.append((self.ret[i], self.disc_sum[i] / max(self.length[i], 1), int(self.length[i])))
                for k, acc in self.terms.items():
                    self.done_terms.setdefault(k, []).append(acc[i])
                    acc[i] = 0.0
                self.ret[i] = self.disc_sum[i] = self.disc_c[i] = 0.0
                self.length[i] = 0
            if self.bar is not None:
                self.bar.update(len(rew))
            if now - self.last_log >= args.log_interval_s:
                self._log()
            if now - self.last_ck >= args.checkpoint_minutes * 60.0:
                save_checkpoint(self.model, run_dir, wall_s=self.wall(), save_buffer=args.save_replay_buffer)
                self.last_ck = time.perf_counter()
            if args.time_limit_minutes > 0 and now - self.t_start >= 60.0 * args.time_limit_minutes:
                if not stop_flag.get("time_limit"):
                    print(f"\ntime limit of {args.time_limit_minutes} min reached: stopping", file=sys.stderr, flush=True)
                stop_flag["time_limit"] = True
                return False
            return not stop_flag["stop"]

        def _log(self) -> None:
            now = time.perf_counter()
            sps = (self.num_timesteps - self.steps_start) / max(now - self.t_start, 1e-9)
            lg = self.logger
            env_ms = 1e3 * float(np.nanmean(self.env_t)) if self.env_t else math.nan
            upd = [u for u in self.upd_t if u > 0]
            upd_ms = 1e3 * float(np.mean(upd)) if upd else 0.0
            iter_ms = 1e3 * float(np.mean(self.iter_t)) if self.iter_t else math.nan
            n_eps = len(self.done_eps)
            if n_eps:
                arr = np.array(self.done_eps, dtype=np.float64)
                self.last = {"ret": arr[:, 0].mean(), "dret": arr[:, 1].mean(), "len": arr[:, 2].mean()}
                lg.record("rollout/ep_return_mean", self.last["ret"])
                lg.record("rollout/avg_discounted_return", self.last["dret"])
                lg.record("rollout/ep_len_mean", self.last["len"])
                lg.record("rollout/episodes", n_eps)
                for k, v in self.done_terms.items():
                    lg.record(f"rollout/ep_{k}", float(np.mean(v)))
            step_rew = self.win_rew_sum / max(self.win_rew_n, 1) if self.win_rew_n else math.nan
            lg.record("rollout/step_reward_mean", step_rew)
            lg.record("time/env_step_ms", env_ms)
            lg.record("time/update_ms", upd_ms)
            lg.record("time/iter_ms", iter_ms)
            lg.record("time/steps_per_s", sps)
            lg.record("time/wall_s", self.wall())
            lg.dump(step=self.num_timesteps)
            if n_eps or self.win_rew_n:
                nan = math.nan
                self.csv.writerow([self.num_timesteps, round(self.wall(), 2), n_eps,
                                   self.last["ret"] if n_eps else nan, self.last["dret"] if n_eps else nan,
                                   self.last["len"] if n_eps else nan, env_ms, upd_ms, iter_ms, sps, step_rew,
                                   int(self.model._n_updates)])
                self.csv_f.flush()
            self.win_rew_sum, self.win_rew_n = 0.0, 0
            msg = (f"ret {self.last['ret']:.2f} | avg-disc-ret {self.last['dret']:.2f} | r/step {step_rew:.3f} | "
                   f"{sps:.0f} steps/s | "
                   f"env {env_ms:.0f} ms + update {upd_ms:.0f} ms / iter")
            if self.bar is not None:
                self.bar.set_postfix_str(msg, refresh=False)
            else:
                print(f"[{time.strftime('%H:%M:%S')}] {self.num_timesteps}/{args.total_steps} steps | {msg}",
                      file=sys.stderr, flush=True)
            self.done_eps.clear()
            self.done_terms.clear()
            self.env_t, self.upd_t, self.iter_t = [], [], []
            self.last_log = now

        def _on_training_end(self) -> None:
            self._log()
            if self.bar is not None:
                self.bar.close()
            self.csv_f.close()

    return RunMonitor()


# ------------------------------------------------------------------------------------ main entry
def train(args: Args, *, resume: bool = False) -> Path:
    """Train (or resume) a run; returns the run directory. Writes policy.zip at the end or on stop."""
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
        if args.task and resolve_task(args.task) != saved.task:
            raise TrainError(f"--resume: run in {run_dir} trains task {saved.task!r}, not {args.task!r}")
        saved.total_steps = args.total_steps
        saved.time_limit_minutes = args.time_limit_minutes
        saved.run_dir = str(run_dir)
        args = saved
    else:
        args.task = resolve_task(args.task)
        args.run_dir = str(run_dir)
        if (run_dir / "checkpoint" / "state.json").exists():
            raise TrainError(f"{run_dir} already holds a checkpoint; pass --resume or choose another --run-dir")
        if args.init_from and not Path(args.init_from).is_file():  # fail before creating the run directory
            raise TrainError(f"--init-from: policy file not found: {args.init_from}")
    run_dir.mkdir(parents=True, exist_ok=True)

    env = _timed(make_sb3_env(args.task, args.num_envs, args.seed))
    if resume:
        model, state = load_checkpoint(args, run_dir, env)
        wall_offset = float(state.get("wall_s", 0.0))
    else:
        model, wall_offset = build_model(args, env), 0.0
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
        cfg = {"args": args.to_json(), "git_commit": git_commit(), "algorithm": "RodSAC (policies/sac.py)",
               "versions": {"torch": th.__version__, "stable_baselines3": stable_baselines3.__version__,
                            "gymnasium": gymnasium.__version__, "numpy": np.__version__},
               "obs_shape": list(env.observation_space.shape), "action_shape": list(env.action_space.shape),
               "target_entropy": float(model.target_entropy), "created": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
        if init_info is not None:
            cfg["init_from"] = init_info
        _atomic_write_bytes(run_dir / "config.json", json.dumps(cfg, indent=1).encode())
    model.set_logger(configure(str(run_dir / "tb"), ["tensorboard"]))

    stop_flag = {"stop": False}

    def _handler(signum, frame):
        if stop_flag["stop"] and signum == signal.SIGINT:
            raise KeyboardInterrupt
        stop_flag["stop"] = True
        print(f"\nsignal {signal.Signals(signum).name}: checkpointing and stopping ...", file=sys.stderr, flush=True)

    old = {s: signal.signal(s, _handler) for s in (signal.SIGINT, signal.SIGTERM)}
    monitor = _monitor_callback(args, run_dir, wall_offset, stop_flag)
    try:
        remaining = args.total_steps - model.num_timesteps
        if remaining > 0:
            model.learn(total_timesteps=remaining, callback=monitor, log_interval=None, reset_num_timesteps=not resume)
    finally:
        for s, h in old.items():
            signal.signal(s, h)
        wall = monitor.wall() if hasattr(monitor, "t_start") else wall_offset
        save_checkpoint(model, run_dir, wall_s=wall, save_buffer=args.save_replay_buffer)
        summary = {"env_steps": int(model.num_timesteps), "gradient_updates": int(model._n_updates),
                   "wall_s": round(wall, 1), "stopped_early": stop_flag["stop"],
                   "stopped_by_time_limit": bool(stop_flag.get("time_limit")),
                   "last_train_return": float(monitor.last["ret"]) if hasattr(monitor, "last") else None,
                   "last_train_avg_disc_return": float(monitor.last["dret"]) if hasattr(monitor, "last") else None}
        save_policy(model, run_dir / "policy.zip", task=args.task,
                    extra={"training": summary, "log_ent_coef": _log_ent_coef(model)})
        side = {"task": args.task, "config": args.to_json(), "git_commit": git_commit(), "training": summary}
        _atomic_write_bytes(run_dir / "policy.json", json.dumps(side, indent=1).encode())
        env.close()
    return run_dir


__all__ = ["Args", "TrainError", "PolicyLoadError", "train", "make_sb3_env", "resolve_task", "build_model",
           "save_checkpoint", "load_checkpoint", "target_entropy", "warm_start"]
