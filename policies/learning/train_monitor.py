"""The training callback of ``policies.learning.training``: episode statistics, logs, checkpoints, evaluation, stopping.

Order inside one SB3 iteration (``collect_rollouts`` with ``train_freq=1``): env step -> ``_on_step``
(statistics, stop requests) -> SB3 stores the transition in the replay buffer -> ``_on_rollout_end``
(checkpoint, evaluation) -> gradient updates. Checkpoints are therefore written only when every counted
env step is in the buffer. A stop request (SIGINT/SIGTERM, time limit) is answered in ``_on_step`` by
storing the step's transition first and then returning False, so no transition is dropped either.

Checkpoints: the first after ``first_checkpoint_minutes`` (default 1 min), then every ``checkpoint_minutes``.

Evaluation during training (``eval_minutes`` and/or ``eval_every_steps``; ``eval_episodes`` episodes on a
separate batched env of ``eval_envs`` envs seeded with the fixed ``eval_seed``, the same episodes every
time and for every training seed; deterministic policy = tanh of the Gaussian mean): one row per
evaluation in ``RUN_DIR/eval.csv`` (env steps, wall-clock, the evaluation's average discounted return,
the stochastic training return of the episodes finished since the previous evaluation, ...) and the
TensorBoard scalars ``eval/*``. With ``keep_best_policy`` the policy of the best evaluation so far is written to
``RUN_DIR/policy_best.zip`` (selected on the fixed evaluation episodes, so its figure there is biased upwards:
re-evaluate it on other seeds with ``rodlab eval``). A final evaluation is made when training ends (not when stopped by a signal). Evaluation time is part of
the run's wall-clock and is also accumulated in the ``eval_s_total`` column.
"""
from __future__ import annotations

import csv
import math
import sys
import time
from pathlib import Path

import numpy as np
from sim.support.text import count, number

from policies.learning.checkpoint import save_checkpoint
from policies.learning.evaluation import evaluate
from policies.learning.sac import save_policy

METRICS_COLUMNS = ["env_steps", "wall_s", "episodes", "return_mean", "avg_disc_return_mean", "ep_len_mean",
                   "env_step_ms", "update_ms", "iter_ms", "steps_per_s", "step_reward_mean", "n_updates"]
EVAL_COLUMNS = ["env_steps", "wall_s", "n_updates", "eval_avg_disc_return_mean", "eval_avg_disc_return_std",
                "eval_return_mean", "eval_episodes", "eval_failures", "eval_final_tip_error_mean",
                "eval_stochastic_avg_disc_return_mean", "train_avg_disc_return_mean", "train_episodes",
                "eval_s", "eval_s_total"]


def evaluate_model(model, args, *, deterministic: bool = True) -> dict:
    """Evaluation of ``model``'s current policy as configured by ``args`` (eval_episodes/envs/seed)."""
    return evaluate(model.policy, args.task, episodes=int(args.eval_episodes), seed=int(args.eval_seed),
                    num_envs=int(min(args.eval_envs, args.eval_episodes)), deterministic=deterministic,
                    gamma=float(args.gamma))


def best_logged_eval(path: Path) -> dict | None:
    """The best deterministic evaluation in eval.csv (where policy_best.zip was saved): its ``env_steps`` and
    ``eval_avg_disc_return_mean``; None when the file holds none."""
    best = None
    if path.is_file():
        with open(path, newline="") as f:
            for r in csv.DictReader(f):
                try:
                    v = float(r.get("eval_avg_disc_return_mean", "nan"))
                except ValueError:
                    continue
                if math.isfinite(v) and (best is None or v > best["eval_avg_disc_return_mean"]):
                    best = {"env_steps": int(float(r["env_steps"])), "eval_avg_disc_return_mean": v}
    return best


def bar_phase(num_timesteps: int, learning_starts: int, updates: int, compiled: bool) -> str:
    """What the training bar says the run is doing: collecting the random transitions SB3 gathers before its first
    update (fast env steps only), the first updates (slow while ``compiled`` updates compile), then training."""
    if num_timesteps <= learning_starts:
        return "warm-up: random actions"
    if updates == 0:
        return "first updates: compiling" if compiled else "first updates"
    return "training"


def _append_csv(path: Path, columns: list[str]):
    new = not path.exists() or path.stat().st_size == 0
    f = open(path, "a", newline="")
    w = csv.writer(f)
    if new:
        w.writerow(columns)
        f.flush()
    return f, w


def monitor_callback(args, run_dir: Path, wall_offset: float, stop_flag: dict, eval_s_offset: float = 0.0):
    """The ``RunMonitor`` callback for ``model.learn`` (see module docstring)."""
    from stable_baselines3.common.callbacks import BaseCallback

    class RunMonitor(BaseCallback):
        def _on_training_start(self) -> None:
            n = self.training_env.num_envs
            self.ret = np.zeros(n)
            self.disc_sum = np.zeros(n)      # sum_l c_l r_l, c_l = (1 - gamma^l) / (1 - gamma)
            self.disc_c = np.zeros(n)
            self.length = np.zeros(n, dtype=np.int64)
            self.terms: dict[str, np.ndarray] = {}
            self.done_eps: list[tuple[float, float, int]] = []
            self.done_terms: dict[str, list[float]] = {}
            self.eval_window: list[float] = []
            self.t_start = time.perf_counter()
            self.steps_start = self.num_timesteps
            self.last_log = self.last_ck = self.last_eval = time.perf_counter()
            self.last_eval_steps = self.num_timesteps
            self.n_checkpoints = 0
            self.eval_s_total = eval_s_offset
            self.env_t, self.upd_t, self.iters = [], [], 0
            self.last_iter_t = time.perf_counter()
            self.iter_t: list[float] = []
            self.win_rew_sum, self.win_rew_n = 0.0, 0
            self.last = {"ret": math.nan, "dret": math.nan}
            self.last_eval_result: dict | None = None
            logged = best_logged_eval(run_dir / "eval.csv")  # a resumed run keeps its policy_best.zip
            self.best_eval = -math.inf if logged is None else logged["eval_avg_disc_return_mean"]
            self.bar = None
            self.updates = 0  # updates seen (the bar's phase)
            self.phase = ""
            if sys.stderr.isatty():
                from tqdm import tqdm
                self.bar = tqdm(total=args.total_steps, initial=self.num_timesteps, unit="step", unit_scale=True,
                                dynamic_ncols=True, mininterval=1.0)
                self._show_phase()
            self.csv_f, self.csv = _append_csv(run_dir / "metrics.csv", METRICS_COLUMNS)
            self.eval_f, self.eval_csv = _append_csv(run_dir / "eval.csv", EVAL_COLUMNS)

        def _show_phase(self) -> None:
            """The bar's label follows the run's phase (env steps race ahead during SB3's warm-up, then slow down)."""
            phase = bar_phase(self.num_timesteps, int(getattr(self.model, "learning_starts", 0)), self.updates,
                              bool(getattr(self.model, "compile_updates", False)))
            if phase != self.phase:
                self.phase = phase
                self.bar.set_description_str(phase, refresh=True)

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
            if self.model.last_update_time > 0.0:
                self.updates += 1
            self.model.last_update_time = 0.0
            rew = np.asarray(self.locals["rewards"], dtype=np.float64)
            dones = np.asarray(self.locals["dones"], dtype=bool)
            self.length += 1
            self.disc_c = 1.0 + args.gamma * self.disc_c
            self.ret += rew
            self.win_rew_sum += float(rew.sum())
            self.win_rew_n += rew.size
            self.disc_sum += self.disc_c * rew
            observer = getattr(env, "reward_terms", None)  # rodlab envs: the core's "reward/<term>" (B,) arrays
            latest = getattr(observer, "latest", None)
            if isinstance(latest, dict):
                for k, v in latest.items():
                    if np.shape(v) == rew.shape:
                        self.terms.setdefault(k, np.zeros(len(rew)))
                        self.terms[k] += np.nan_to_num(np.asarray(v, dtype=np.float64))
            for i in np.flatnonzero(dones):
                dret = self.disc_sum[i] / max(self.length[i], 1)
                self.done_eps.append((self.ret[i], dret, int(self.length[i])))
                self.eval_window.append(dret)
                for k, acc in self.terms.items():
                    self.done_terms.setdefault(k, []).append(acc[i])
                    acc[i] = 0.0
                self.ret[i] = self.disc_sum[i] = self.disc_c[i] = 0.0
                self.length[i] = 0
            if self.bar is not None:
                self.bar.update(len(rew))
                self._show_phase()
            if now - self.last_log >= args.log_interval_s:
                self._log()
            if args.time_limit_minutes > 0 and now - self.t_start >= 60.0 * args.time_limit_minutes:
                if not stop_flag.get("time_limit"):
                    print(f"\ntime limit of {args.time_limit_minutes} min reached: stopping", file=sys.stderr, flush=True)
                stop_flag["time_limit"] = True
            if stop_flag["stop"] or stop_flag.get("time_limit"):
                self._store_pending_transition()
                return False
            return True

        def _store_pending_transition(self) -> None:
            """Store this step's transition (SB3 stores it only after ``_on_step`` returns True)."""
            loc = self.locals
            self.model._store_transition(self.model.replay_buffer, loc["buffer_actions"], loc["new_obs"],
                                         loc["rewards"], loc["dones"], loc["infos"])

        def _on_rollout_end(self) -> None:
            now = time.perf_counter()
            period = args.checkpoint_minutes if self.n_checkpoints else args.first_checkpoint_minutes
            if now - self.last_ck >= 60.0 * period:
                self.checkpoint()
            due_steps = args.eval_every_steps > 0 and self.num_timesteps - self.last_eval_steps >= args.eval_every_steps
            due_time = args.eval_minutes > 0 and now - self.last_eval >= 60.0 * args.eval_minutes
            if args.eval_episodes > 0 and (due_steps or due_time):
                self.run_eval()

        def checkpoint(self) -> None:
            save_checkpoint(self.model, run_dir, wall_s=self.wall(), save_buffer=args.save_replay_buffer,
                            extra={"eval_s_total": self.eval_s_total})
            self.n_checkpoints += 1
            self.last_ck = time.perf_counter()

        def run_eval(self) -> dict:
            t0 = time.perf_counter()
            res = evaluate_model(self.model, args)
            stoch = evaluate_model(self.model, args, deterministic=False) if args.eval_stochastic else None
            dt = time.perf_counter() - t0
            self.eval_s_total += dt
            tr = float(np.mean(self.eval_window)) if self.eval_window else math.nan
            row = {"env_steps": int(self.num_timesteps), "wall_s": round(self.wall(), 2),
                   "n_updates": int(self.model._n_updates),
                   "eval_avg_disc_return_mean": res["avg_discounted_return_mean"],
                   "eval_avg_disc_return_std": res["avg_discounted_return_std"], "eval_return_mean": res["return_mean"],
                   "eval_episodes": res["episodes"], "eval_failures": res["failures"],
                   "eval_final_tip_error_mean": res.get("final_tip_error_mean", math.nan),
                   "eval_stochastic_avg_disc_return_mean": stoch["avg_discounted_return_mean"] if stoch else math.nan,
                   "train_avg_disc_return_mean": tr, "train_episodes": len(self.eval_window),
                   "eval_s": round(dt, 3), "eval_s_total": round(self.eval_s_total, 3)}
            self.eval_csv.writerow([row[c] for c in EVAL_COLUMNS])
            self.eval_f.flush()
            lg = self.logger
            lg.record("eval/avg_discounted_return", row["eval_avg_disc_return_mean"])
            lg.record("eval/avg_discounted_return_std", row["eval_avg_disc_return_std"])
            lg.record("eval/train_avg_discounted_return", tr)
            if stoch:
                lg.record("eval/stochastic_avg_discounted_return", row["eval_stochastic_avg_disc_return_mean"])
            lg.record("eval/wall_s", row["wall_s"])
            lg.dump(step=self.num_timesteps)
            self.eval_window = []
            if args.keep_best_policy and row["eval_avg_disc_return_mean"] > self.best_eval:
                self.best_eval = row["eval_avg_disc_return_mean"]
                save_policy(self.model, run_dir / "policy_best.zip", task=args.task,
                            extra={"best_eval": row, "selected_on": "eval.csv (fixed evaluation seeds)"})
            self.last_eval, self.last_eval_steps = time.perf_counter(), self.num_timesteps
            self.last_eval_result = row
            msg = (f"eval at {self.num_timesteps} steps: avg-disc-ret {number(row['eval_avg_disc_return_mean'])} ± "
                   f"{number(row['eval_avg_disc_return_std'])} (deterministic, {count(res['episodes'], 'episode')}, "
                   f"{dt:.1f} s); training {number(tr)}")
            (self.bar.write if self.bar is not None else lambda m: print(m, file=sys.stderr, flush=True))(msg)
            return row

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
            msg = (f"ret {number(self.last['ret'])} | avg-disc-ret {number(self.last['dret'])} | r/step "
                   f"{number(step_rew, '.3f')} | {sps:.0f} steps/s | env {number(env_ms, '.0f')} ms + update "
                   f"{upd_ms:.0f} ms / iter")
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
            if args.eval_episodes > 0 and (args.eval_minutes > 0 or args.eval_every_steps > 0) \
                    and self.num_timesteps > self.last_eval_steps and not stop_flag["stop"]:
                self.run_eval()
            if self.bar is not None:
                self.bar.close()
            self.csv_f.close()
            self.eval_f.close()

    return RunMonitor()


__all__ = ["monitor_callback", "evaluate_model", "METRICS_COLUMNS", "EVAL_COLUMNS"]
