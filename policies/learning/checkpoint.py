"""Training checkpoints of a run directory: written as one unit, loaded without losing transitions.

Layout (``RUN_DIR/checkpoint/``)::

    model.zip     SB3 ``RodSAC`` (networks, optimizers, entropy coefficient, counters)
    replay.npz    filled rows of the replay buffer (observations, next_observations, actions, rewards,
                  dones, timeouts, pos, full)
    state.json    num_timesteps, n_updates, wall_s, replay_rows, ... (written last)

**Atomic as a set.** A checkpoint is written into ``checkpoint.new/`` (each file fsynced, ``state.json``
last), then ``checkpoint/`` is renamed to ``checkpoint.old/``, ``checkpoint.new/`` to ``checkpoint/``, and
``checkpoint.old/`` is deleted. A process killed at any point leaves one complete checkpoint: ``checkpoint/``
when it holds ``state.json``, else ``checkpoint.new/`` (complete once its ``state.json`` exists), else
``checkpoint.old/``. ``find_checkpoint`` applies that rule; ``load_checkpoint`` uses it.

**No transition lost.** ``save_checkpoint`` must be called when every env step counted in
``model.num_timesteps`` is in the replay buffer (after SB3 has stored the step's transition, see
``policies/learning/train_monitor.py``); ``state.json`` records ``replay_rows`` and the loader checks
``replay_rows * n_envs == num_timesteps`` while the buffer has not wrapped. On resume the envs start fresh
episodes (``model._last_obs`` is cleared, so the first new transition is not paired with an observation of
the previous process's episodes) from a seed derived from (seed, num_timesteps), so a resumed run does not
replay the episodes it started with.
"""
from __future__ import annotations

import io
import json
import os
import shutil
import sys
import time
from pathlib import Path

import numpy as np
from sim.support.atomicio import write_bytes

REPLAY_KEYS = ("observations", "next_observations", "actions", "rewards", "dones", "timeouts")


class CheckpointError(Exception):
    """A checkpoint is missing, inconsistent or does not fit the run (readable message)."""


def _write_file(path: Path, write) -> None:
    with open(path, "wb") as f:
        write(f)
        f.flush()
        os.fsync(f.fileno())


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def find_checkpoint(run_dir: str | os.PathLike) -> Path | None:
    """The complete checkpoint folder of ``run_dir`` (see module docstring), or None."""
    run_dir = Path(run_dir)
    for name in ("checkpoint", "checkpoint.new", "checkpoint.old"):
        ck = run_dir / name
        if (ck / "state.json").is_file() and (ck / "model.zip").is_file():
            return ck
    return None


def read_state(run_dir: str | os.PathLike) -> dict | None:
    """``state.json`` of the run's complete checkpoint, or None when there is none."""
    ck = find_checkpoint(run_dir)
    if ck is None:
        return None
    try:
        return json.loads((ck / "state.json").read_text())
    except (OSError, json.JSONDecodeError):
        return None


def save_checkpoint(model, run_dir: Path, *, wall_s: float, save_buffer: bool, extra: dict | None = None) -> Path:
    """Write model, replay buffer (filled rows) and state of ``model`` as one checkpoint; returns its folder."""
    run_dir = Path(run_dir)
    new, cur, old = run_dir / "checkpoint.new", run_dir / "checkpoint", run_dir / "checkpoint.old"
    if new.exists():
        shutil.rmtree(new)
    new.mkdir(parents=True)
    buf = io.BytesIO()
    model.save(buf)
    _write_file(new / "model.zip", lambda f: f.write(buf.getvalue()))
    rb = model.replay_buffer
    rows = rb.buffer_size if rb.full else rb.pos
    if save_buffer:
        def _savez(f):
            np.savez(f, **{k: getattr(rb, k)[:rows] for k in REPLAY_KEYS}, pos=np.int64(rb.pos),
                     full=np.bool_(rb.full))
        _write_file(new / "replay.npz", _savez)
    state = {"num_timesteps": int(model.num_timesteps), "n_updates": int(model._n_updates), "wall_s": float(wall_s),
             "replay_saved": bool(save_buffer), "replay_rows": int(rows), "replay_full": bool(rb.full),
             "n_envs": int(model.n_envs), "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    state.update(extra or {})
    for p in new.iterdir():
        os.chmod(p, 0o644 & ~_umask())
    write_bytes(new / "state.json", json.dumps(state, indent=1).encode())
    _fsync_dir(new)
    if old.exists():
        shutil.rmtree(old)
    if cur.exists():
        os.replace(cur, old)
    os.replace(new, cur)
    _fsync_dir(run_dir)
    if old.exists():
        shutil.rmtree(old)
    return cur


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def resume_seed(seed: int, num_timesteps: int) -> int:
    """Env seed of a run resumed at ``num_timesteps`` (fresh episodes, not a replay of the first ones)."""
    if num_timesteps <= 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), int(num_timesteps)]).generate_state(1)[0] % (2**31 - 1))


def load_checkpoint(run_dir: Path, env, *, device: str, buffer_size: int, algorithm: str = "sac"):
    """-> (model, state). Restores model, counters and replay buffer (grown to ``buffer_size`` when larger);
    ``algorithm``: the run's (sac: ``RodSAC``, crossq: ``RodCrossQ``).

    Raises ``CheckpointError`` when there is no usable checkpoint or the buffer does not fit.
    """
    if algorithm == "crossq":
        from policies.learning.crossq import RodCrossQ as model_class
    else:
        from policies.learning.sac import RodSAC as model_class
    from policies.learning.sac import legacy_module_names

    ck = find_checkpoint(run_dir)
    if ck is None:
        raise CheckpointError(f"no checkpoint in {Path(run_dir) / 'checkpoint'} (expected model.zip and state.json)")
    try:
        state = json.loads((ck / "state.json").read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise CheckpointError(f"cannot read {ck / 'state.json'}: {exc}") from None
    try:
        with legacy_module_names():  # a checkpoint written before the learning package names policies.sac
            model = model_class.load(ck / "model.zip", env=env, device=device)
    except Exception as exc:  # SB3 raises assorted errors on corrupt zips / space mismatch
        raise CheckpointError(f"cannot load {ck / 'model.zip'}: {exc}") from None
    model.num_timesteps = int(state["num_timesteps"])
    model._last_obs = None  # the envs are new: start fresh episodes (SB3 resets them in learn())
    model._last_original_obs = None
    if buffer_size > model.buffer_size:  # the run was extended (--steps larger): grow the buffer
        old_rb = model.replay_buffer  # its kind (an n-step buffer keeps its n and discount)
        n_step = {"n_steps": old_rb.n_steps, "gamma": old_rb.gamma} if hasattr(old_rb, "n_steps") else {}
        model.buffer_size = buffer_size
        model.replay_buffer = type(old_rb)(buffer_size, model.observation_space, model.action_space,
                                           device=model.device, n_envs=model.n_envs, handle_timeout_termination=True,
                                           **n_step)
    if (ck / "replay.npz").is_file():
        rb = model.replay_buffer
        with np.load(ck / "replay.npz") as z:
            n = z["observations"].shape[0]
            if n > rb.buffer_size or z["observations"].shape[1:] != rb.observations.shape[1:]:
                raise CheckpointError(f"replay buffer shape {z['observations'].shape} does not fit "
                                      f"{rb.observations.shape}")
            full, pos = bool(z["full"]), int(z["pos"])
            grown = full and n < rb.buffer_size  # a wrapped ring copied into a larger buffer: oldest row first
            for key in REPLAY_KEYS:
                getattr(rb, key)[:n] = np.roll(z[key], -pos, axis=0) if grown else z[key]
            if full and not grown:
                rb.pos, rb.full = pos % rb.buffer_size, True
            else:
                rb.pos, rb.full = n % rb.buffer_size, n == rb.buffer_size
        rows = state.get("replay_rows")
        if rows is not None and int(rows) != n:
            raise CheckpointError(f"{ck}: replay.npz holds {n} rows, state.json says {rows}")
    elif state.get("replay_saved", True):
        raise CheckpointError(f"{ck}: state.json says the replay buffer was saved, but replay.npz is missing")
    else:
        print("resume: no replay buffer in checkpoint, starting with an empty one", file=sys.stderr)
    return model, state


__all__ = ["CheckpointError", "find_checkpoint", "read_state", "save_checkpoint", "load_checkpoint", "resume_seed"]
