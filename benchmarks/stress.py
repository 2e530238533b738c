"""``rodlab bench stress``: numerical stress test (must never produce NaN).

Two parts (``--parts``):

* ``tasks`` -- every task (policies.tasks) with ``--envs`` envs (200) under random and saturating
  (bang-bang) actions for ``--env-steps`` control env-steps each (1e5; ``--quick`` 2e3), envs reset when
  their episode ends; variants: dt 4x the paper's, targets 5x faster (Follow).
* ``sim``   -- the arm driven directly (random / bang-bang natural-curvature commands, contact-task
  scale 0.25, saturating at |K| = 2) across E = 1e5 ... 1e9 Pa, 11 ... 201 nodes, thin (r = 5 mm) and
  thick (r = 0.2 m) rods, dt up to 4x, and obstacles spawned intersecting the rod (also with Newton run to
  convergence); each run ends with a passive hold (command frozen) during which the total energy must not
  grow. (An accepted unconverged contact step can end inside the barrier and show a one-step rise of the
  contact energy, released the next step; steps whose Newton solve converged rise no more than its tolerance
  allows. Both maxima are reported.)

Reported per run: NaN count (state and observations; must be 0), failed steps (envs frozen after all
sub-step retries), recovered steps (a retry with sub-steps succeeded), unconverged steps, max
penetration [m], energy growth during the hold [J and relative], Newton iteration histogram, wall time.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .common import base_parser, load, machine_info, pyplot, save_figure, write_json
from .rodlab_runs import Solver, make_sim, scene_dict

PARTS = ("tasks", "sim")
TASKS = ("follow_target", "follow_target_2d", "ik4d", "tight_obstacles_2d", "random_obstacles_3d")


@dataclass
class Tally:
    """Counters over sim steps (one entry per env-step)."""

    env_steps: int = 0
    nan: int = 0
    failed: int = 0
    recovered: int = 0
    unconverged: int = 0
    max_penetration: float = 0.0
    iters_hist: np.ndarray = field(default_factory=lambda: np.zeros(65, np.int64))
    substeps_hist: dict = field(default_factory=dict)

    def add(self, st, state) -> None:
        it = np.clip(np.asarray(st.newton_iters), 0, 64)
        self.iters_hist += np.bincount(it.ravel(), minlength=65)[:65]
        sub = np.asarray(st.substeps)
        failed = np.asarray(st.failed, bool)
        self.env_steps += sub.size
        self.failed += int(failed.sum())
        self.recovered += int(((sub > 1) & ~failed).sum())
        self.unconverged += int((~np.asarray(st.converged, bool)).sum())
        for s, c in zip(*np.unique(sub, return_counts=True)):
            self.substeps_hist[int(s)] = self.substeps_hist.get(int(s), 0) + int(c)
        pen = np.asarray(st.max_penetration)
        if pen.size:
            self.max_penetration = max(self.max_penetration, float(np.nanmax(pen)))
        self.nan += int((~np.isfinite(state.dof)).sum())

    def summary(self) -> dict:
        h = self.iters_hist
        n = max(1, int(h.sum()))
        last = int(np.nonzero(h)[0].max()) if h.any() else 0
        mean = float((np.arange(65) * h).sum() / n)
        return {"env_steps": self.env_steps, "nan": self.nan, "failed_steps": self.failed,
                "recovered_steps": self.recovered, "unconverged_steps": self.unconverged,
                "max_penetration_m": self.max_penetration, "newton_iters_hist": h[:last + 1].tolist(),
                "newton_iters_mean": mean, "substeps_hist": self.substeps_hist}


def _actions(kind: str, rng, shape, k: int, hold: dict) -> np.ndarray:
    if kind == "random":
        return rng.uniform(-1, 1, size=shape).astype(np.float32)
    # bang-bang: saturating ±1, sign pattern redrawn every 20 control steps
    if k % 20 == 0 or "a" not in hold:
        hold["a"] = np.where(rng.random(shape) < 0.5, -1.0, 1.0).astype(np.float32)
    return hold["a"]


# ------------------------------------------------------------------------------------------------
def run_task(task: str, *, envs: int, env_steps: int, actions: str, overrides: dict | None = None,
             seed: int = 0) -> dict:
    """Task core under random / bang-bang actions; StepStats of every sim step are tallied."""
    from policies.tasks import TASK_SPECS, gym_task_id
    _, core_cls, cfg_fn = TASK_SPECS[gym_task_id(task)].load()
    cfg = cfg_fn()
    if overrides:
        cfg = replace(cfg, **overrides)
    core = core_cls(cfg, envs=envs, seed=seed)
    core.reset()
    tally = Tally()
    sim_step = core.sim.step

    def wrapped(state, ctrl):
        st = sim_step(state, ctrl)
        tally.add(st, state)
        return st

    core.sim.step = wrapped  # instance attribute: tallies every sim step of the task's own loop
    rng = np.random.default_rng(seed)
    n_ctrl = max(1, env_steps // envs)
    obs_nan = 0
    episodes = 0
    hold: dict = {}
    t0 = time.perf_counter()
    for k in range(n_ctrl):
        obs, rew, term, trunc, info = core.step(_actions(actions, rng, (envs, core.action_dim), k, hold))
        obs_nan += int((~np.isfinite(obs)).sum()) + int((~np.isfinite(rew)).sum())
        done = np.asarray(term) | np.asarray(trunc)
        if done.any():
            episodes += int(done.sum())
            core.reset(done)
    wall = time.perf_counter() - t0
    return {"task": task, "actions": actions, "envs": envs, "control_steps": n_ctrl,
            "env_control_steps": n_ctrl * envs, "episodes_ended": episodes, "obs_nan": obs_nan,
            "overrides": overrides or {}, "wall_s": wall, "load": load(), **tally.summary()}


# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SimCase:
    name: str
    nodes: int = 21
    youngs: float = 1e7
    radius: float = 0.05
    dt: float = 0.05
    substeps: int = 2
    max_iter: int = 2
    obstacles: tuple = ()
    mode: str = "3d"


def sim_cases(quick: bool) -> list[SimCase]:
    through = {"type": "capsule", "start": [-0.3, 0.0, 0.5], "end": [0.3, 0.0, 0.5], "radius": 0.05}
    inside = {"type": "sphere", "center": [0.0, 0.02, 0.7], "radius": 0.08}
    cases = [SimCase("paper arm"), SimCase("E 1e5", youngs=1e5), SimCase("E 1e9", youngs=1e9),
             SimCase("N 11", nodes=11), SimCase("N 201", nodes=201), SimCase("thin r 5 mm", radius=0.005),
             SimCase("thick r 0.2 m", radius=0.2), SimCase("dt 4x (0.2 s)", dt=0.2),
             SimCase("capsule through the arm", obstacles=(through,), max_iter=5),
             SimCase("sphere inside the arm", obstacles=(inside,), max_iter=5)]
    if not quick:
        cases += [SimCase("E 1e6", youngs=1e6), SimCase("E 1e8", youngs=1e8), SimCase("N 51", nodes=51),
                  SimCase("N 101", nodes=101), SimCase("dt 2x (0.1 s)", dt=0.1),
                  SimCase("thin r 5 mm, dt 4x", radius=0.005, dt=0.2),
                  SimCase("2d, E 1e5, dt 4x", youngs=1e5, dt=0.2, mode="2d"),
                  SimCase("capsule through, dt 4x", obstacles=(through,), max_iter=5, dt=0.2),
                  # same as the two intersecting cases above with Newton run to convergence: the energy rise seen
                  # with the 5-iteration cap comes from accepted unconverged contact steps, not from the model
                  SimCase("capsule through, converged Newton", obstacles=(through,), max_iter=50),
                  SimCase("sphere inside, converged Newton", obstacles=(inside,), max_iter=50)]
    return cases


def _segments(n_nodes: int, points: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """Node -> control segment and weight (the converter's 'intended' smoothing scaled to N nodes)."""
    owner = np.full(n_nodes, -1)
    w = np.zeros(n_nodes)
    b = np.linspace(1, n_nodes - 1, points + 1).round().astype(int)
    for k in range(points):
        owner[b[k]:b[k + 1]] = k
        w[b[k]:b[k + 1]] = 1.0 / max(1, b[k + 1] - b[k])
    return owner, w


def curvature_commands(actions: str, *, envs: int, nodes: int, control_steps: int, components: int = 2,
                       seed: int = 0):
    """Per control step, the natural-curvature increment (envs, nodes, 2) of the sim part's commands: 5 control
    points moved by 0.25 x (random | bang-bang) per step, saturating at |K| = 2, spread over their nodes."""
    owner, w = _segments(nodes)
    act = owner >= 0
    K = np.zeros((envs, 5, components))
    rng = np.random.default_rng(seed)
    hold: dict = {}
    for k in range(control_steps):
        a = _actions(actions, rng, (envs, 5, components), k, hold)
        K_new = np.clip(K + 0.25 * a, -2.0, 2.0)
        dk = np.zeros((envs, nodes, 2))
        dk[:, act, :components] = w[act][None, :, None] * (K_new - K)[:, owner[act], :]
        K = K_new
        yield dk


def run_sim_case(case: SimCase, *, envs: int, control_steps: int, actions: str, hold_steps: int = 20,
                 seed: int = 0) -> dict:
    doc = scene_dict(nodes=case.nodes, length=1.0, radius=case.radius, density=1000.0, youngs=case.youngs,
                     poisson=0.5, dt=case.dt, gravity=(0.0, 0.0, -9.8),
                     solver=Solver(tol=1e-3, max_iter=case.max_iter), mode=case.mode,  # type: ignore[arg-type]
                     obstacles=list(case.obstacles) or None)
    sim, state, ctrl = make_sim(doc, envs=envs)
    tally = Tally()
    t0 = time.perf_counter()
    for dk in curvature_commands(actions, envs=envs, nodes=case.nodes, control_steps=control_steps,
                                 components=1 if case.mode == "2d" else 2, seed=seed):
        dk /= case.substeps
        for _ in range(case.substeps):
            ctrl.kappa_bar += dk
            tally.add(sim.step(state, ctrl), state)
    # passive hold: command frozen, backward Euler must not gain energy
    energies, converged = [], []
    for _ in range(hold_steps):
        st = sim.step(state, ctrl)
        tally.add(st, state)
        e = sum(np.asarray(getattr(st, f"energy_{n}")) for n in
                ("stretch", "bend", "twist", "contact", "kinetic", "gravity"))
        energies.append(e)
        converged.append(np.asarray(st.converged, bool).copy())
    wall = time.perf_counter() - t0
    E = np.asarray(energies)  # (hold, B)
    ok = ~np.asarray(state.failed, bool)
    # per-step energy change split by whether that step's Newton solve converged (backward Euler solved to
    # convergence dissipates up to its tolerance; accepted unconverged steps carry no such guarantee)
    dE = E[1:] - E[:-1]
    cv = np.asarray(converged)[1:] & ok[None, :]
    ucv = ~np.asarray(converged)[1:] & ok[None, :]
    step_rise = {"energy_step_rise_converged_max_J": float(np.max(dE[cv])) if cv.any() else None,
                 "energy_step_rise_unconverged_max_J": float(np.max(dE[ucv])) if ucv.any() else None,
                 "hold_steps_unconverged": int(ucv.sum()), "hold_steps": int(ok.sum()) * max(0, len(E) - 1)}
    growth = (E[1:] - E[0]).max(axis=0) if len(E) > 1 else np.zeros(envs)
    scale = np.maximum(np.abs(E).max(axis=0), 1e-12)
    g_ok = growth[ok] if ok.any() else np.zeros(1)
    return {"case": case.name, "actions": actions, "envs": envs, "control_steps": control_steps,
            "params": {k: v for k, v in vars(case).items() if k != "obstacles"},
            "obstacles": len(case.obstacles), "energy_growth_max_J": float(np.nanmax(g_ok)),
            "energy_growth_max_rel": float(np.nanmax(g_ok / scale[ok])) if ok.any() else 0.0,
            "envs_failed_at_end": int((~ok).sum()), **step_rise, "wall_s": wall, "load": load(), **tally.summary()}


# ------------------------------------------------------------------------------------------------
def _line(r: dict) -> str:
    name = r.get("task", r.get("case"))
    ov = r.get("overrides")
    if ov:
        name += " " + ",".join(f"{k}={v}" for k, v in ov.items())
    s = (f"  {name:36s} {r['actions']:9s} env-steps {r['env_steps']:8d} NaN {r['nan'] + r.get('obs_nan', 0):3d} "
         f"failed {r['failed_steps']:5d} recovered {r['recovered_steps']:5d} unconv {r['unconverged_steps']:7d} "
         f"pen {1e3 * r['max_penetration_m']:6.2f} mm it {r['newton_iters_mean']:.2f}")
    if "energy_growth_max_J" in r:
        s += f" dE+ {r['energy_growth_max_J']:.2e} J ({r['energy_growth_max_rel']:.1e})"
        rc, ru = r.get("energy_step_rise_converged_max_J"), r.get("energy_step_rise_unconverged_max_J")
        s += f" step-rise conv {rc:.1e}" if rc is not None else " step-rise conv -"
        s += f" unconv {ru:.1e} ({r.get('hold_steps_unconverged', 0)} st)" if ru is not None else ""
    return s + f"  {r['wall_s']:.1f} s"


def main(argv: list[str] | None = None) -> int:
    p = base_parser("rodlab bench stress", __doc__.split("\n")[0])
    p.add_argument("--parts", default=",".join(PARTS), help="comma-separated subset of tasks,sim")
    p.add_argument("--envs", type=int, default=None, help="envs per task run (default 200, quick 16)")
    p.add_argument("--env-steps", type=int, default=None,
                   help="control env-steps per task and action kind (default 100000, quick 2000)")
    p.add_argument("--tasks", default=",".join(TASKS), help="comma-separated subset of the tasks")
    p.add_argument("--sim-envs", type=int, default=None,
                   help="envs per simulator case (default 256 = 1e5 sim env-steps per case and action kind; quick 8)")
    args = p.parse_args(argv)
    parts = [s.strip() for s in args.parts.split(",") if s.strip()]
    tasks = [s.strip() for s in args.tasks.split(",") if s.strip()]
    for s in parts:
        if s not in PARTS:
            p.error(f"--parts: unknown part {s!r}")
    for s in tasks:
        if s not in TASKS:
            p.error(f"--tasks: unknown task {s!r} (choose from {', '.join(TASKS)})")
    envs = args.envs or (16 if args.quick else 200)
    steps = args.env_steps or (2000 if args.quick else 100_000)
    if envs < 1 or steps < 1:
        p.error("--envs and --env-steps must be >= 1")
    name = "stress_quick.json" if args.quick else "stress.json"
    res = {"benchmark": "stress", "quick": args.quick, "machine": machine_info(), "envs": envs,
           "env_steps": steps, "command": "rodlab bench stress " + " ".join(argv if argv is not None else sys.argv[1:]),
           "tasks": [], "sim": []}
    print(f"machine: {res['machine']['cpu_model']}, load {res['machine']['loadavg_at_start']}", flush=True)
    if "tasks" in parts:
        for task in tasks:
            variants = [None, {"dt": 0.2}]
            if task.startswith("follow_target"):
                variants.append({"target_speed": 2.5})
            for ov in variants:
                for actions in ("random", "bang-bang"):
                    n = steps if ov is None else max(envs, steps // 5)
                    try:
                        r = run_task(task, envs=envs, env_steps=n, actions=actions, overrides=ov)
                    except Exception as exc:
                        r = {"task": task, "actions": actions, "overrides": ov, "error": f"{type(exc).__name__}: {exc}"}
                        print(f"  {task} {ov} {actions}: ERROR {r['error']}", flush=True)
                        res["tasks"].append(r)
                        continue
                    res["tasks"].append(r)
                    print(_line(r), flush=True)
                    write_json(args.out, name, res)
    if "sim" in parts:
        for case in sim_cases(args.quick):
            for actions in ("random", "bang-bang"):
                try:
                    r = run_sim_case(case, envs=args.sim_envs or (8 if args.quick else 256),
                                     control_steps=20 if args.quick else 200, actions=actions)
                except Exception as exc:
                    r = {"case": case.name, "actions": actions, "error": f"{type(exc).__name__}: {exc}"}
                    print(f"  {case.name} {actions}: ERROR {r['error']}", flush=True)
                    res["sim"].append(r)
                    continue
                res["sim"].append(r)
                print(_line(r), flush=True)
                write_json(args.out, name, res)
    rows = [r for r in res["tasks"] + res["sim"] if "error" not in r]
    res["totals"] = {"runs": len(rows), "errors": len(res["tasks"] + res["sim"]) - len(rows),
                     "nan": sum(r["nan"] + r.get("obs_nan", 0) for r in rows),
                     "failed_steps": sum(r["failed_steps"] for r in rows),
                     "recovered_steps": sum(r["recovered_steps"] for r in rows),
                     "env_steps": sum(r["env_steps"] for r in rows),
                     "max_penetration_m": max((r["max_penetration_m"] for r in rows), default=0.0)}
    res["load_at_end"] = load()
    res["figures"] = [plot(res, args.out, quick=args.quick)] if rows else []
    write_json(args.out, name, res)
    t = res["totals"]
    print(f"TOTAL: {t['runs']} runs, {t['env_steps']} env sim-steps, NaN {t['nan']}, failed {t['failed_steps']}, "
          f"recovered {t['recovered_steps']}, max penetration {1e3 * t['max_penetration_m']:.2f} mm, "
          f"errors {t['errors']}", flush=True)
    if args.json:
        import json
        print(json.dumps(res, default=str))
    print(f"wrote {Path(args.out) / name}")
    return 0 if t["nan"] == 0 and t["errors"] == 0 else 1


def plot(res: dict, out: Path, *, quick: bool) -> str:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    h = np.zeros(65)
    for r in res["tasks"] + res["sim"]:
        if "newton_iters_hist" in r:
            hh = np.asarray(r["newton_iters_hist"], float)
            h[:len(hh)] += hh
    last = int(np.nonzero(h)[0].max()) + 1 if h.any() else 1
    ax.bar(np.arange(last), h[:last] / max(1.0, h.sum()))
    ax.set_yscale("log")
    ax.set_xlabel("Newton iterations per env-step (all stress runs)")
    ax.set_ylabel("fraction of env-steps")
    t = res.get("totals", {})
    ax.set_title(f"stress: NaN {t.get('nan')}, failed {t.get('failed_steps')}, recovered {t.get('recovered_steps')}"
                 f" of {t.get('env_steps')} env-steps", fontsize=9)
    return str(save_figure(fig, out, "stress_newton_iters_quick.png" if quick else "stress_newton_iters.png"))


if __name__ == "__main__":
    sys.exit(main())
