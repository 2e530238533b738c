"""``rodlab record`` and ``rodlab inspect``.

rodlab record --task T [--policy P | --random | --scripted] [--episodes n] [--envs k] [--seed s]
              [--max-steps m] [--per-sim-step] [--ref-frames] [--progress/--no-progress] --out recordings/NAME.rrd

The output folder must exist (a missing one is named in the error, not created) and is checked for writing before
any episode runs; SIGTERM or Ctrl-C discards the
recording (no file, no hidden part folder); a progress bar with ETA goes to stderr on a terminal.
rodlab inspect FILE.rrd [--json]
"""
from __future__ import annotations

import argparse
import contextlib
import json
import math
import signal
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
from sim.support.paths import check_output_path
from sim.support.progress import add_progress_flag, progress_bar, progress_wanted
from sim.support.text import count

import policies
from policies.tasks import gym_task_id

from .reader import summarize
from .schema import RecordingError


def scripted_actions(t: int, envs: int, dim: int) -> np.ndarray:
    """Open-loop demo actions (envs, dim) in [-1, 1] at control step t: a slow sinusoid per component
    with a phase shift along the action vector (deterministic, policy-free)."""
    k = np.arange(dim)
    a = 0.8 * np.sin(2.0 * math.pi * t / 40.0 + 0.6 * k)
    return np.broadcast_to(a, (envs, dim)).astype(np.float32)


def _policy_fn(args, venv) -> tuple[Any, str]:
    """(callable obs -> actions, policy label)."""
    B = venv.num_envs
    dim = int(np.prod(venv.single_action_space.shape))
    if args.policy:
        from policies.learning import check_compatible, load_policy

        pol, _meta = load_policy(args.policy)
        check_compatible(pol, _Spaces(venv), args.task, args.policy)
        return (lambda obs, t: pol.predict(obs, deterministic=True)[0]), str(args.policy)
    if args.scripted:
        return (lambda obs, t: scripted_actions(t, B, dim)), "scripted"
    rng = np.random.default_rng(args.seed)
    return (lambda obs, t: rng.uniform(-1.0, 1.0, size=(B, dim)).astype(np.float32)), "random"


class _Spaces:
    """Single-env spaces of a vector env in the shape check_compatible expects."""

    def __init__(self, venv) -> None:
        self.observation_space = venv.single_observation_space
        self.action_space = venv.single_action_space


def record(task: str, out: str | Path, *, policy: str | None = None, mode: str = "random", episodes: int = 1,
           envs: int = 1, seed: int = 0, max_steps: int | None = None, per_sim_step: bool = False,
           ref_frames: bool = False, force_scale: float | None = None, show_progress: bool = False) -> dict[str, Any]:
    """Run ``episodes`` episodes of ``task`` and record them to ``out``. mode: "policy" | "random" |
    "scripted" (``policy`` = path for mode "policy"). ``out`` is checked for writing first. Returns
    {"file", "episodes": [summaries]}. ``show_progress``: a progress bar with ETA on stderr."""

    from .probe import TaskProbe
    from .recorder import Recorder

    tid = gym_task_id(task)
    if envs < 1 or episodes < 1:
        raise RecordingError("--episodes and --envs must be >= 1")
    if max_steps is not None and max_steps < 1:
        raise RecordingError(f"--max-steps must be >= 1 (control steps per episode), got {max_steps}")
    check_output_path(out, suffix=".rrd")  # before any work: a folder that cannot be written loses nothing
    envs = min(envs, episodes)
    venv = policies.make_vec_env(tid, envs, seed=seed)
    ns = argparse.Namespace(policy=policy if mode == "policy" else None, scripted=mode == "scripted", seed=seed,
                            task=tid)
    try:
        act, label = _policy_fn(ns, venv)
    except BaseException:
        venv.close()
        raise
    ep_len = int(max_steps) if max_steps is not None else int(venv.config.timeout_steps) + 1
    with Recorder(out, **({} if force_scale is None else {"force_scale": force_scale})) as rec, \
            progress_bar(episodes * ep_len, desc="rodlab record", enabled=show_progress) as bar:
        probe = TaskProbe(rec, episodes=episodes, max_steps=max_steps, per_sim_step=per_sim_step,
                          ref_frames=ref_frames, meta={"task": tid, "policy": label, "seed": seed})
        probe.attach(venv)
        try:
            obs, _ = venv.reset(seed=seed)
            t = np.zeros(envs, np.int64)
            while not probe.done:
                a = np.asarray(act(obs, int(t.max())), np.float32)
                obs, _r, term, trunc, _info = venv.step(a)
                t += 1
                ended = np.asarray(term) | np.asarray(trunc)
                cut = probe.cut_envs()
                if cut.any():
                    obs, _ = venv.reset(options={"reset_mask": cut})
                ended |= cut
                # the bar counts control steps of at most ep_len per episode (an early end counts in full)
                bar.update(int(envs - ended.sum()) + int(np.maximum(ep_len - t[ended] + 1, 1).sum()))
                t[ended] = 0
        finally:
            probe.detach()
            venv.close()
        summaries = list(rec.summaries)
    return {"file": str(out), "episodes": summaries}


def record_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="rodlab record", description="Run episodes of a task and record them to a "
                                "rerun .rrd file (one recording per episode; open with `rerun FILE.rrd`).")
    p.add_argument("--task", required=True, help="task short name (follow_target, ik4d, ...) or gymnasium id")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--policy", help="policy .zip (e.g. policies/pretrained/<task>.zip)")
    g.add_argument("--random", action="store_true", help="uniform random actions (default)")
    g.add_argument("--scripted", action="store_true", help="open-loop sinusoidal demo actions")
    p.add_argument("--episodes", type=int, default=1)
    p.add_argument("--envs", type=int, default=1, help="parallel envs (episodes are split over them)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--max-steps", type=int, default=None,
                   help="cut each episode after this many control steps (>= 1)")
    p.add_argument("--per-sim-step", action="store_true", help="also record every simulator sub-step")
    p.add_argument("--ref-frames", action="store_true", help="also record the reference frames d1, d2")
    p.add_argument("--force-scale", type=float, default=None,
                   help="contact force arrow length per newton [m/N] (default 2e-4)")
    p.add_argument("--out", required=True, help="output file, e.g. recordings/NAME.rrd")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")

    add_progress_flag(p)
    a = p.parse_args(argv)
    mode = "policy" if a.policy else "scripted" if a.scripted else "random"
    from policies.learning import PolicyLoadError

    folder = Path(a.out).parent
    if not (folder.exists() or folder.is_symlink()):  # a mistyped folder is not silently created
        print(f"rodlab record: {a.out}: folder {folder} does not exist (create it first)", file=sys.stderr)
        return 2
    try:
        with _sigterm_as_interrupt():
            res = record(a.task, a.out, policy=a.policy, mode=mode, episodes=a.episodes, envs=a.envs,
                         seed=a.seed, max_steps=a.max_steps, per_sim_step=a.per_sim_step, ref_frames=a.ref_frames,
                         force_scale=a.force_scale, show_progress=progress_wanted(a.progress, json_output=a.json))
    except (RecordingError, PolicyLoadError, ValueError, FileNotFoundError) as exc:
        print(f"rodlab record: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as exc:
        sig = "terminated" if str(exc) == "SIGTERM" else "interrupted"
        print(f"rodlab record: {sig}; nothing written", file=sys.stderr)
        return 143 if sig == "terminated" else 130
    if a.json:
        print(json.dumps(res))
        return 0
    print(f"wrote {res['file']} ({Path(res['file']).stat().st_size / 1024:.1f} KiB, "
          f"{count(len(res['episodes']), 'episode')})")
    for s in res["episodes"]:
        print(f"  episode {s['episode']} env {s['env']}: {s['steps']} frames, return {s['return']:.3f}, "
              f"max contact force {s['max_contact_force']:.3g} N{'' if s['complete'] else ' (cut)'}")
    return 0


@contextlib.contextmanager
def _sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM raises KeyboardInterrupt("SIGTERM") in the main thread while the block runs, so the recorder's
    ``with`` block discards its hidden part folder (a default SIGTERM would leave it behind)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def _raise(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt("SIGTERM")

    old = signal.signal(signal.SIGTERM, _raise)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def _fmt(x: float, spec: str = ".3f") -> str:
    return "nan" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, spec)


def inspect_main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(prog="rodlab inspect", description="Summarise a rodlab .rrd recording.")
    p.add_argument("file", help="recording .rrd")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    a = p.parse_args(argv)

    try:
        s = summarize(a.file)
    except RecordingError as exc:
        print(f"rodlab inspect: {exc}", file=sys.stderr)
        return 2
    if a.json:
        print(json.dumps(_json_safe(s)))
        return 0
    print(f"{s['file']}: {count(s['episodes'], 'episode')}, {count(s['steps'], 'frame')}, {s['bytes'] / 1024:.1f} KiB "
          f"(rodlab {s['rodlab_version']}, commit {s['git_commit'][:12]})")
    print(f"  mean return {_fmt(s['mean_return'])}, max contact force {_fmt(s['max_contact_force_N'], '.4g')} N")
    print(f"  {'ep':>3} {'env':>3} {'task':<28} {'policy':<14} {'steps':>5} {'t_end[s]':>8} {'return':>10} "
          f"{'max F_c[N]':>10}")
    for r in s["episode_list"]:
        pol = str(r["policy"])
        pol = pol if len(pol) <= 14 else "…" + pol[-13:]
        print(f"  {r['episode']:>3} {r['env']:>3} {str(r['task']):<28} {pol:<14} {r['steps']:>5} "
              f"{r['sim_time_s']:>8.2f} {_fmt(r['return']):>10} {_fmt(r['max_contact_force_N'], '.4g'):>10}"
              f"{'' if r['complete'] else '  (cut)'}")
    return 0


def _json_safe(o: Any) -> Any:
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, dict):
        return {k: _json_safe(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_json_safe(v) for v in o]
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return _json_safe(o.item())
    return o
