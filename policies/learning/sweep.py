"""``rodlab sweep``: seeds x tasks x hyper-parameter grids of ``rodlab train`` runs, scheduled by Ray.

    rodlab sweep TASK [TASK ...] --seeds 0,1,2 [--preset paper] [--envs N] [--steps N] [--time-limit MIN]
                 [--address ADDR] [--set key=v1,v2 ...] [--out DIR] [--cpus-per-trial N]

* **Trials.** One trial per (task, grid point of ``--set``, seed). Each trial is an ordinary training run
  directory ``OUT/<task>[__key=value...]__s<seed>/`` (config.json, metrics.csv, eval.csv, checkpoint/,
  policy.zip; see policies/learning/training.py) plus ``trial.json`` (the trial's ``Args``, grid point and time budget),
  ``train.log`` (the trial's output) and, once finished, ``trial_done.json``. Only ``--set`` keys with
  several values appear in the directory names.
* **Ray.** Without ``--address`` an embedded local Ray is started with this machine's cores
  (``include_dashboard=False``); each trial asks for ``--cpus-per-trial`` CPUs (default: all local cores, so on
  a 2-core machine one trial runs at a time and the others queue). With ``--address`` the sweep joins that
  Ray cluster (``ray.init(address=...)``; default 2 CPUs per trial); OUT must then be on a file system shared by
  the nodes, and the nodes need this repository installed. A trial is a Ray task that starts the training in a
  child process (numba and torch threads = CPUs of the trial) and waits for it. Local trials run at the niceness of
  the sweep command (``nice rodlab sweep ...`` lowers them), not at the 15 Ray gives its workers by default.
* **Resume.** Re-running the same command continues every unfinished trial from its checkpoint (finished trials,
  those with ``trial_done.json``, are not re-run). A trial is finished when it reached ``--steps`` env steps or
  used its ``--time-limit`` minutes of training wall-clock (summed over resumes); re-running with a larger
  ``--steps`` or ``--time-limit`` continues a trial that stopped at the smaller one. On Ctrl-C the local trials are
  sent SIGTERM and write a checkpoint before the sweep exits; a trial whose process was killed outright resumes
  from its last periodic checkpoint.
* **--set key=v1,v2** sets any ``Args`` field (policies/learning/training.py), several values make a grid (the product of
  all ``--set`` options); list values separate their items with ':' (``net_arch=256:256``); an optional field
  takes ``auto`` for "as the run decides" (``compile_updates=auto``). Each trial starts from ``--preset``
  (policies/learning/presets.py), or from its grid value of ``--set preset=paper,fast``, then ``--envs`` and the rest.
* **Progress**: a table of trials (state, env steps, returns, ETA) refreshed in the terminal.
"""
from __future__ import annotations

import argparse
import dataclasses
import fcntl
import itertools
import json
import os
import re
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from sim.support.atomicio import write_bytes

from policies.learning.presets import DEFAULT_PRESET, PRESETS, preset_settings

STARTED_AT = time.perf_counter()  # in a trial's process: when it started (the run's wall-clock counts its start-up)

FIXED_KEYS = {"task", "seed", "run_dir", "num_envs", "total_steps", "time_limit_minutes", "init_from"}


class SweepError(Exception):
    """Bad sweep input (unknown task or field, bad value) with a readable message."""


@dataclass
class Trial:
    name: str
    run_dir: Path
    args: dict            # Args.to_json()
    grid: dict            # the --set values of this trial
    time_limit_minutes: float

    @property
    def task(self) -> str:
        return self.args["task"]


# ------------------------------------------------------------------------------------ parsing
def _convert(name: str, ftype, text: str):
    t = str(ftype)
    if t.endswith(" | None"):  # an optional setting: "auto" (or "none") leaves it to the run
        if text.lower() in ("auto", "none"):
            return None
        t = t[: -len(" | None")]
    try:
        if t in ("int", "<class 'int'>"):
            try:
                return int(text)
            except ValueError:
                f = float(text)  # 1e6
                if not f.is_integer():
                    raise
                return int(f)
        if t in ("float", "<class 'float'>"):
            return float(text)
        if t in ("bool", "<class 'bool'>"):
            low = text.lower()
            if low in ("1", "true", "yes", "on"):
                return True
            if low in ("0", "false", "no", "off"):
                return False
            raise ValueError(text)
        if t.startswith("list"):
            return [int(x) for x in text.split(":") if x]
        return text
    except ValueError:
        raise SweepError(f"--set {name}: cannot read {text!r} as {t}") from None


def parse_sets(items: list[str]) -> dict[str, list]:
    """``["learning_rate=1e-3,3e-4", ...]`` -> {"learning_rate": [0.001, 0.0003], ...} (typed like Args)."""
    from policies.learning.training import Args

    fields = {f.name: f.type for f in dataclasses.fields(Args)}
    out: dict[str, list] = {}
    for item in items:
        if "=" not in item:
            raise SweepError(f"--set {item!r}: expected key=value[,value...]")
        key, vals = item.split("=", 1)
        key = key.strip()
        if key not in fields:
            raise SweepError(f"--set {key}: unknown training setting; known: {', '.join(sorted(set(fields) - FIXED_KEYS))}")
        if key in FIXED_KEYS:
            raise SweepError(f"--set {key}: set by the sweep itself (use the TASK, --seeds, --envs, --steps, "
                             "--time-limit options)")
        values = [_convert(key, fields[key], v.strip()) for v in vals.split(",") if v.strip()]
        if not values:
            raise SweepError(f"--set {key}: no value given")
        out[key] = values
    return out


def _value_tag(v) -> str:
    s = ":".join(str(x) for x in v) if isinstance(v, list) else str(v)
    return re.sub(r"[^A-Za-z0-9.+-:]", "_", s)


def group_name(task: str, grid: dict) -> str:
    """Trial name without the seed: ``task`` or ``task__key=value__key=value``."""
    return "__".join([task] + [f"{k}={_value_tag(v)}" for k, v in sorted(grid.items())])


def make_trials(tasks: list[str], seeds: list[int], sets: dict[str, list], out: Path, *, envs: int | None,
                steps: int, time_limit_minutes: float, cpus_per_trial: int, preset: str = DEFAULT_PRESET
                ) -> list[Trial]:
    """One trial per (task, grid point, seed). Each starts from its preset's settings (``preset``, or the grid's
    ``preset`` value: ``--set preset=paper,fast`` compares presets), then ``envs`` (when given) and the grid's other
    values."""
    from policies.learning.training import Args, TrainError, check_update_settings, task_short_name

    if not tasks:
        raise SweepError("no task given")
    if not seeds:
        raise SweepError("no seed given")
    if (envs is not None and envs < 1) or steps < 1:
        raise SweepError("--envs and --steps must be positive")
    for name in sets.get("preset", [preset]):
        try:
            preset_settings(name)
        except ValueError as exc:
            raise SweepError(f"--preset: {exc}") from None
    trials = []
    keys = sorted(sets)
    for task in tasks:
        try:
            task = task_short_name(task)
        except TrainError as exc:
            raise SweepError(str(exc)) from None
        for combo in itertools.product(*(sets[k] for k in keys)):
            grid = dict(zip(keys, combo))
            for seed in seeds:
                varying = {k: v for k, v in grid.items() if len(sets[k]) > 1}  # single values stay out of names
                name = f"{group_name(task, varying)}__s{seed}"
                run_dir = out / name
                a = Args(**preset_settings(grid.get("preset", preset)), task=task, total_steps=steps,
                         seed=int(seed), run_dir=str(run_dir), torch_threads=cpus_per_trial)
                if envs is not None:
                    a.num_envs = envs
                for k, v in grid.items():
                    if k != "preset":
                        setattr(a, k, v)
                try:  # before Ray starts: a setting no trial could run with
                    check_update_settings(a)
                except TrainError as exc:
                    raise SweepError(f"{name}: {exc}") from None
                trials.append(Trial(name, run_dir, a.to_json(), grid, float(time_limit_minutes)))
    return trials


# ------------------------------------------------------------------------------------ trial state
def trial_progress(run_dir: Path) -> dict:
    """env steps, wall-clock, last returns of a trial from its files (cheap; for the progress view)."""
    from policies.learning.checkpoint import read_state

    out = {"env_steps": 0, "wall_s": 0.0, "train": float("nan"), "eval": float("nan")}
    st = read_state(run_dir)
    if st:
        out["env_steps"], out["wall_s"] = int(st["num_timesteps"]), float(st["wall_s"])
    for fname, key, col in (("metrics.csv", "train", "avg_disc_return_mean"),
                            ("eval.csv", "eval", "eval_avg_disc_return_mean")):
        rows = _csv_rows(run_dir / fname)
        if rows:
            if fname == "metrics.csv" and int(float(rows[-1]["env_steps"])) >= out["env_steps"]:
                out["env_steps"], out["wall_s"] = int(float(rows[-1]["env_steps"])), float(rows[-1]["wall_s"])
            vals = [float(r[col]) for r in rows if r.get(col) not in (None, "", "nan")]
            if vals:
                out[key] = vals[-1]
    return out


def _csv_rows(path: Path) -> list[dict]:
    import csv

    if not path.is_file():
        return []
    try:
        with open(path, newline="") as f:
            return [r for r in csv.DictReader(f) if r.get("env_steps")]
    except (OSError, csv.Error):
        return []


def _budget_reached(env_steps: int, wall_s: float, total_steps: int, limit_minutes: float) -> bool:
    """A trial's budget is spent: ``total_steps`` env steps, or ``limit_minutes`` of training (0: no limit)."""
    return env_steps >= total_steps or (limit_minutes > 0 and wall_s >= 60.0 * limit_minutes - 1.0)


def is_done(trial: Trial) -> bool:
    """Finished within this command's budget: ``trial_done.json`` is there and its env steps reach ``--steps`` or
    its wall-clock reaches ``--time-limit``. A trial finished under a smaller budget (fewer steps, a shorter time
    limit) is continued when the command raises it."""
    path = trial.run_dir / "trial_done.json"
    if not path.is_file():
        return False
    try:
        rec = json.loads(path.read_text())
        steps, wall_s = int(rec["env_steps"]), float(rec["wall_s"])
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise SweepError(f"{path}: unreadable ({exc}); delete it to continue the trial") from None
    return _budget_reached(steps, wall_s, int(trial.args["total_steps"]), float(trial.time_limit_minutes))


def _write_json(path: Path, data: dict) -> None:

    write_bytes(path, json.dumps(data, indent=1).encode())


# ------------------------------------------------------------------------------------ one trial (child process)
def run_trial_process(run_dir: Path) -> int:
    """Train (or resume) the trial in ``run_dir`` (reads trial.json); writes trial_done.json when finished."""
    from policies.learning.checkpoint import read_state
    from policies.learning.training import Args, train

    _set_parent_death_signal()
    spec = json.loads((run_dir / "trial.json").read_text())
    args = Args.from_json(spec["args"])
    with open(run_dir / "trial.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # waits for an earlier process of this trial (still checkpointing)
        (run_dir / "trial.pid").write_text(str(os.getpid()))
        print(f"rodlab sweep: trial process {os.getpid()}, niceness {os.nice(0)}, "
              f"{os.environ.get('NUMBA_NUM_THREADS', '?')} threads", flush=True)
        st = read_state(run_dir)
        limit = float(spec.get("time_limit_minutes") or 0.0)
        used_min = (float(st["wall_s"]) / 60.0) if st else 0.0
        if limit > 0:
            args.time_limit_minutes = max(limit - used_min, 1e-3)
        train(args, resume=st is not None, started_at=STARTED_AT)
        st = read_state(run_dir)
        side = json.loads((run_dir / "policy.json").read_text())
        training = side.get("training", {})
        done = _budget_reached(int(st["num_timesteps"]), float(st["wall_s"]), args.total_steps,
                               limit if training.get("stopped_by_time_limit") else 0.0)
        if done and not training.get("stopped_early"):
            _write_json(run_dir / "trial_done.json", {"env_steps": st["num_timesteps"], "wall_s": st["wall_s"],
                                                      "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())})
    return 0


def _set_parent_death_signal() -> None:
    """The trial process stops (SIGTERM -> checkpoint) when the Ray worker that started it dies (set in the child
    itself: a ``preexec_fn`` is not safe in the multi-threaded worker)."""
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    parent = os.environ.get("RODLAB_TRIAL_PARENT")
    if parent and str(os.getppid()) != parent:  # the worker died before prctl took effect
        os.kill(os.getpid(), signal.SIGTERM)


def launch_trial(run_dir: str, cpus: int, cwd: str | None = None) -> dict:
    """Body of the Ray task: run the trial's training in a child process and wait for it. ``cwd``: the sweep's
    working directory (relative run directories and scene paths of the trial are relative to it)."""
    # every library's threads = the trial's cores (policies/cli.py _threads_env)
    env = dict(os.environ, NUMBA_NUM_THREADS=str(cpus), OMP_NUM_THREADS=str(cpus), MKL_NUM_THREADS=str(cpus))
    # the child imports the same rodlab: the sys.path entry this package came from (a checkout or site-packages)
    packages_dir = str(Path(__file__).resolve().parents[2])  # policies/learning/sweep.py -> the folder of policies
    env["PYTHONPATH"] = packages_dir + os.pathsep + env.get("PYTHONPATH", "")
    with open(Path(run_dir) / "train.log", "ab") as log:
        env["RODLAB_TRIAL_PARENT"] = str(os.getpid())
        proc = subprocess.Popen([sys.executable, "-m", "policies.learning.sweep", "_trial", run_dir], cwd=cwd, env=env,
                                stdout=log, stderr=subprocess.STDOUT)
        rc = proc.wait()
    return {"run_dir": run_dir, "returncode": rc}


# ------------------------------------------------------------------------------------ progress view
def _fmt_eta(s: float) -> str:
    if s != s or s == float("inf"):
        return "?"
    s = int(s)
    return f"{s // 3600}h{(s % 3600) // 60:02d}m" if s >= 3600 else f"{s // 60}m{s % 60:02d}s"


def progress_rows(trials: list[Trial], states: dict[str, str], concurrency: int) -> tuple[list[list[str]], str]:
    """Table rows (trial, state, env steps, train / eval return, ETA) and a summary line with the sweep ETA."""
    rates: dict[str, list[float]] = {}
    info = {}
    for t in trials:
        p = trial_progress(t.run_dir)
        info[t.name] = p
        if p["env_steps"] > 0 and p["wall_s"] > 0:
            rates.setdefault(t.task, []).append(p["env_steps"] / p["wall_s"])
    rows, remaining = [], []
    for t in trials:
        p, st = info[t.name], states.get(t.name, "queued")
        total = int(t.args["total_steps"])
        rate = p["env_steps"] / p["wall_s"] if p["env_steps"] > 0 and p["wall_s"] > 0 else (
            sum(rates[t.task]) / len(rates[t.task]) if rates.get(t.task) else float("nan"))
        left = 0.0 if st in ("done", "failed") else max(total - p["env_steps"], 0) / rate if rate == rate else float("nan")
        if t.time_limit_minutes > 0 and st not in ("done", "failed"):
            left = min(left, max(60.0 * t.time_limit_minutes - p["wall_s"], 0.0)) if left == left else \
                max(60.0 * t.time_limit_minutes - p["wall_s"], 0.0)
        remaining.append(left)
        rows.append([t.name, st, f"{p['env_steps']:,}/{total:,}", f"{p['train']:.2f}", f"{p['eval']:.2f}",
                     _fmt_eta(left)])
    n_done = sum(states.get(t.name) == "done" for t in trials)
    eta = sum(remaining) / max(1, min(concurrency, len(trials) - n_done)) if remaining else 0.0
    summary = (f"{n_done}/{len(trials)} trials done, {sum(states.get(t.name) == 'running' for t in trials)} running; "
               f"sweep ETA {_fmt_eta(eta)}")
    return rows, summary


HEADER = ["trial", "state", "env steps", "train ret", "eval ret", "ETA"]


def _render(rows, summary):
    from rich.table import Table

    tab = Table(title="rodlab sweep", caption=summary)
    for h in HEADER:
        tab.add_column(h, justify="left" if h in ("trial", "state") else "right")
    for r in rows:
        tab.add_row(*r)
    return tab


# ------------------------------------------------------------------------------------ driver
def _trial_running(t: Trial) -> bool:
    lock = t.run_dir / "trial.lock"
    if not lock.exists():
        return False
    with open(lock, "a") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return True
        fcntl.flock(f, fcntl.LOCK_UN)
    return False


def _stop_local_trials(trials: list[Trial], wait_s: float = 300.0) -> None:
    """SIGTERM the local training processes of ``trials`` (they checkpoint and exit) and wait for them."""
    for t in trials:
        try:
            pid = int((t.run_dir / "trial.pid").read_text())
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace")
        except (OSError, ValueError):
            continue
        if "policies.learning.sweep" in cmd and str(t.run_dir) in cmd:
            try:
                os.kill(pid, signal.SIGTERM)
            except OSError:
                pass
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline and any(_trial_running(t) for t in trials):
        time.sleep(0.5)


def run_sweep(trials: list[Trial], out: Path, *, address: str | None, cpus_per_trial: int,
              poll_s: float = 2.0, print_every_s: float = 30.0, command: list[str] | None = None) -> dict:
    """Run (or continue) ``trials`` on Ray; returns {trial name: final state}. Raises KeyboardInterrupt
    after stopping the local trials when interrupted."""
    out.mkdir(parents=True, exist_ok=True)
    _write_json(out / "sweep.json", {"command": command or [], "address": address, "cpus_per_trial": cpus_per_trial,
                                      "trials": [{"name": t.name, "task": t.task, "seed": t.args["seed"],
                                                  "grid": t.grid} for t in trials]})
    states: dict[str, str] = {}
    for t in trials:
        t.run_dir.mkdir(parents=True, exist_ok=True)
        _write_json(t.run_dir / "trial.json", {"name": t.name, "args": t.args, "grid": t.grid,
                                               "time_limit_minutes": t.time_limit_minutes})
        states[t.name] = "done" if is_done(t) else ("resume" if (t.run_dir / "config.json").exists() else "queued")
    pending = [t for t in trials if states[t.name] != "done"]
    n_done = len(trials) - len(pending)
    print(f"rodlab sweep: {len(trials)} trials in {out} ({n_done} already finished, {len(pending)} to run"
          f"{', ' + str(sum(s == 'resume' for s in states.values())) + ' of them resumed' if pending else ''})",
          flush=True)
    if not pending:
        return states
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    try:
        import ray
    except ImportError:
        raise SweepError("Ray is not installed: pip install 'rodlab[sweep]' (make test installs it)") from None

    term_handler = signal.getsignal(signal.SIGTERM)  # ray.init installs its own SIGTERM handler: keep ours
    if address:
        ray.init(address=address, log_to_driver=False)
        concurrency = max(1, int(ray.cluster_resources().get("CPU", cpus_per_trial)) // cpus_per_trial)
    else:
        ncpu = os.cpu_count() or 1
        # Ray runs its workers at niceness 15 by default: a trial's training would then get almost no CPU beside
        # any other busy process of the machine; 0 keeps the trials at the niceness of the sweep command itself
        ray.init(num_cpus=ncpu, include_dashboard=False, log_to_driver=False,
                 object_store_memory=128 * 1024 * 1024, _system_config={"worker_niceness": 0})
        concurrency = max(1, ncpu // cpus_per_trial)
    if callable(term_handler):
        signal.signal(signal.SIGTERM, term_handler)
    task_fn = ray.remote(num_cpus=cpus_per_trial, max_retries=0)(launch_trial)
    refs = {task_fn.remote(str(t.run_dir), cpus_per_trial, os.getcwd()): t for t in pending}
    live = None
    try:
        if sys.stdout.isatty():
            from rich.live import Live

            live = Live(refresh_per_second=1, transient=False)
            live.start()
        last_print = 0.0
        while refs:
            ready, _ = ray.wait(list(refs), num_returns=1, timeout=poll_s)
            for r in ready:
                t = refs.pop(r)
                res = ray.get(r)
                states[t.name] = "done" if is_done(t) else ("failed" if res["returncode"] != 0 else "stopped")
                msg = f"trial {t.name}: {states[t.name]} (exit code {res['returncode']}; log {t.run_dir / 'train.log'})"
                (live.console.print if live else print)(msg)
            for t in refs.values():
                if states[t.name] != "running" and _trial_running(t):
                    states[t.name] = "running"
            rows, summary = progress_rows(trials, states, concurrency)
            if live is not None:
                live.update(_render(rows, summary))
            elif time.monotonic() - last_print >= print_every_s or not refs:
                running = [r for r in rows if r[1] == "running"]
                detail = "; ".join(f"{r[0]} {r[2]} (ETA {r[5]})" for r in running)
                print(f"[{time.strftime('%H:%M:%S')}] {summary}" + (f" | {detail}" if detail else ""), flush=True)
                last_print = time.monotonic()
    except KeyboardInterrupt:
        if live is not None:
            live.stop()
            live = None
        if not address:
            print("\nrodlab sweep: interrupted; stopping the running trials (they write a checkpoint) ...",
                  file=sys.stderr, flush=True)
            _stop_local_trials(list(refs.values()))
        for r in refs:
            ray.cancel(r, force=True)
        raise
    finally:
        if live is not None:
            live.stop()
        ray.shutdown()
    return states


def parse_seeds(text: str) -> list[int]:
    try:
        seeds = []
        for part in text.split(","):
            part = part.strip()
            if "-" in part[1:]:
                lo, hi = part.split("-", 1)
                seeds.extend(range(int(lo), int(hi) + 1))
            elif part:
                seeds.append(int(part))
        return seeds
    except ValueError:
        raise SweepError(f"--seeds {text!r}: expected integers such as 0,1,2 or 0-4") from None


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["_trial"]:  # internal: one trial's training process (started by launch_trial)
        return run_trial_process(Path(argv[1]))
    from policies.learning.training import Args

    d = Args()
    p = argparse.ArgumentParser(prog="rodlab sweep", description="Seeds x tasks x hyper-parameter sweep of "
                                "`rodlab train` runs on Ray (local, or a cluster with --address). Re-run the same "
                                "command to continue an interrupted sweep.")
    p.add_argument("tasks", nargs="+", metavar="TASK")
    p.add_argument("--seeds", default="0", help="comma-separated seeds or ranges (0,1,2 or 0-4; default 0)")
    p.add_argument("--preset", choices=list(PRESETS), default=DEFAULT_PRESET,
                   help=f"named training settings each trial starts from (default {DEFAULT_PRESET}; as rodlab train "
                        "--preset; --set preset=paper,fast makes them a grid)")
    p.add_argument("--envs", type=int, default=None, help=f"parallel envs per trial (default: the preset's; paper "
                                                          f"{d.num_envs})")
    p.add_argument("--steps", type=int, default=d.total_steps, help=f"env steps per trial (default {d.total_steps:,})")
    p.add_argument("--time-limit", type=float, default=0.0, metavar="MIN",
                   help="training wall-clock budget per trial in minutes, summed over resumes (0 = none)")
    p.add_argument("--address", default=None, help="join this Ray cluster (default: start a local Ray)")
    p.add_argument("--cpus-per-trial", type=int, default=None,
                   help="CPUs per trial (default: all local cores; 2 with --address)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=V1,V2",
                   help="training setting (an Args field of policies/learning/training.py); several values make a grid")
    p.add_argument("--out", default=None, help="sweep directory (default runs/sweep_<tasks>)")
    a = p.parse_args(argv)
    try:
        cpus = a.cpus_per_trial or (2 if a.address else (os.cpu_count() or 1))
        if cpus < 1:
            raise SweepError("--cpus-per-trial must be positive")
        if not a.address and cpus > (os.cpu_count() or 1):
            raise SweepError(f"--cpus-per-trial {cpus} exceeds this machine's {os.cpu_count()} cores")
        if a.time_limit < 0:
            raise SweepError("--time-limit must be >= 0")
        sets = parse_sets(a.set)
        out = Path(a.out or f"runs/sweep_{'_'.join(a.tasks)}")
        trials = make_trials(a.tasks, parse_seeds(a.seeds), sets, out, envs=a.envs, steps=a.steps,
                             time_limit_minutes=a.time_limit, cpus_per_trial=cpus, preset=a.preset)
    except SweepError as exc:
        print(f"rodlab sweep: {exc}", file=sys.stderr)
        return 2
    def _term(signum, frame):
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, _term)
    try:
        states = run_sweep(trials, out, address=a.address, cpus_per_trial=cpus, command=["rodlab", "sweep", *argv])
    except KeyboardInterrupt:
        print(f"rodlab sweep: stopped; re-run the same command to continue ({out})", file=sys.stderr)
        return 130
    except SweepError as exc:
        print(f"rodlab sweep: {exc}", file=sys.stderr)
        return 2
    bad = [n for n, s in states.items() if s != "done"]
    print(f"rodlab sweep: {len(states) - len(bad)}/{len(states)} trials finished in {out}"
          + (f"; not finished: {', '.join(bad)}" if bad else "") + f"  (report: rodlab report {out})")
    return 0 if not bad else 1


if __name__ == "__main__":
    sys.exit(main())
