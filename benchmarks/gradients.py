"""Derivatives, fitting and inverse statics (``rodlab bench gradients``): what they cost and what they give.

* step derivative: one backward (adjoint) step against one forward step of the paper's arm, per env, and the memory a
  rollout keeps per step (the recorded states, and the linearisation cached for repeated passes), recorded whole and
  checkpointed (``rollout(checkpoint=K)``: memory and the time of an adjoint pass over the rollout);
* fit: 3 parameters (Young's modulus, damping, the actuation gain of one commanded node) of the paper's arm from 10 s
  of synthetic marker data (5 markers at 30 Hz, 1 mm noise) with the exact Jacobian of the tangent mode, and the
  same fit with the Jacobian by finite-difference probing (one extra simulation per parameter: the real2sim
  approach), in the same run;
* multi-start: one batched iteration of K starts against the starts one by one, and a fit a single start misses;
* open-loop trajectory optimisation: the arm's tip made to follow a path from rest controls (L-BFGS-B, adjoint);
* the model-based baselines (inverse statics and the receding-horizon trajectory controller) against the shipped
  SAC policy on Follow Target and 4D IK (same seeds).

Writes ``gradients.json`` into ``--out`` and prints a table.
"""
from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from benchmarks.common import base_parser, machine_info, write_json
from sim.support.assets import asset_path


def _arm_spec(converged: bool = True):
    from sim import load_scene

    spec = load_scene(asset_path("scenes/arm.toml"))
    if converged:  # derivatives are of the converged step: let Newton converge
        spec = dataclasses.replace(spec, sim=dataclasses.replace(spec.sim, newton_tol=1e-10, newton_max_iter=30,
                                                                 accept_unconverged=False, newton_dtol=1e-9))
    return spec


def bench_step(envs: int, repeats: int) -> dict:
    """Forward step vs the backward pass of one step (linearisation included), per env."""
    from sim import Simulator, build_model
    from sim.analysis import rollout

    spec = _arm_spec()
    sim = Simulator(build_model(spec), envs=envs)
    state, ctrl = sim.reset(), sim.make_control()
    rng = np.random.default_rng(0)
    ctrl.kappa_bar[:, 1:-1] += rng.normal(0.0, 0.05, ctrl.kappa_bar[:, 1:-1].shape)
    for _ in range(3):
        sim.step(state, ctrl)  # moving, bent
    rollout(sim, state.copy(), [ctrl])._linear(0, ("kappa_bar",))  # load the kernels (untimed)
    fwd, bwd, lin = [], [], []
    for _ in range(repeats):
        st = state.copy()
        t0 = time.perf_counter()
        sim.step(st, ctrl)
        fwd.append(time.perf_counter() - t0)
        st = state.copy()
        tape = rollout(sim, st, [ctrl])
        n = tape.dof.shape[2]
        t0 = time.perf_counter()
        tape._linear(0, ("kappa_bar",))
        lin.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        tape.vjp({"dof": np.ones((envs, n))}, params=("kappa_bar", "dof0", "vel0"))  # the cached linearisation
        bwd.append(time.perf_counter() - t0)
    N = sim.model.node_count
    # what a recorded step adds to a tape (Tape.nbytes: the state after it, its controls and external forces)
    rec = (rollout(sim, state.copy(), [ctrl, ctrl]).nbytes - rollout(sim, state.copy(), [ctrl]).nbytes) // envs
    lin_bytes = tape._lin[(0, 0)].nbytes // envs  # J's band (factored in place), F, G, a, b, ∂f/∂κ̄ as kept after a pass
    f, b, li = (float(np.median(v)) for v in (fwd, bwd, lin))
    return {"envs": envs, "nodes": N, "dofs": n, "forward_ms_per_env": 1e3 * f / envs,
            "backward_ms_per_env": 1e3 * (b + li) / envs, "linearise_ms_per_env": 1e3 * li / envs,
            "backward_cached_ms_per_env": 1e3 * b / envs, "backward_over_forward": (b + li) / f, "record_bytes_per_env_step": rec,
            "linearisation_bytes_per_env_step": lin_bytes}


def bench_checkpoint(envs: int, steps: int, every: int, repeats: int) -> dict:
    """A rollout of ``steps`` steps of the paper arm (a drifting command) recorded whole and checkpointed every
    ``every`` steps: the bytes each keeps per env and step (:attr:`Tape.nbytes`, controls included) and the time of
    one adjoint pass over the whole rollout (the checkpointed one steps each segment again)."""
    from sim import Simulator, build_model
    from sim.analysis import rollout

    sim = Simulator(build_model(_arm_spec()), envs=envs)
    rng = np.random.default_rng(0)
    N = sim.model.node_count
    kb = rng.normal(0.0, 0.01, (steps, envs, N, 2)).cumsum(axis=0)
    ctrls = []
    for k in range(steps):
        c = sim.make_control()
        c.kappa_bar[:] = kb[k]
        ctrls.append(c)
    out: dict = {"envs": envs, "steps": steps, "every": every}
    for name, kw in (("whole", {}), ("checkpointed", {"checkpoint": every})):
        times = []
        for _ in range(repeats):
            tape = rollout(sim, sim.reset(), ctrls, **kw)
            n = tape.dof.shape[2]
            t0 = time.perf_counter()
            tape.vjp({"dof": np.ones((envs, n))}, params=("kappa_bar", "dof0"))
            times.append(time.perf_counter() - t0)
        out[name] = {"bytes_per_env_step": tape.nbytes / (envs * steps), "adjoint_s_median": float(np.median(times))}
    out["memory_ratio"] = out["checkpointed"]["bytes_per_env_step"] / out["whole"]["bytes_per_env_step"]
    out["time_ratio"] = out["checkpointed"]["adjoint_s_median"] / out["whole"]["adjoint_s_median"]
    return out


def bench_unconverged_gap(steps: int, iterations=(2, 3, 5, 30)) -> dict:
    """The paper's arm as the tasks run it (2 Newton iterations, accepted unconverged), and with 3, 5 and 30: the
    derivative the implicit function theorem gives (that of the converged steps) against central differences of
    what was computed. The force tolerance is set far below reach, so each step takes exactly its iteration cap
    (or converges) and the computed map is smooth; the 30-iteration row is the check (converged: the gap is the
    finite differences' own error)."""
    from sim import Simulator, build_model
    from sim.analysis import rollout

    base = _arm_spec(converged=False)
    rng = np.random.default_rng(0)
    out = {"steps": steps, "rows": []}
    for it in iterations:
        spec = dataclasses.replace(base, sim=dataclasses.replace(base.sim, newton_max_iter=int(it), newton_tol=1e-13,
                                                                 newton_dtol=1e-12))
        sim = Simulator(build_model(spec), envs=1)
        N = sim.model.node_count
        kb = np.random.default_rng(0).normal(0.0, 0.03, (steps, 1, N, 2)).cumsum(axis=0)  # a drifting command
        direction = rng.normal(0.0, 1.0, kb.shape)

        def run(k, tape=False, sim=sim):
            st = sim.reset()
            ctrls = []
            for i in range(steps):
                c = sim.make_control()
                c.kappa_bar[:] = k[i]
                ctrls.append(c)
            if tape:
                return rollout(sim, st, ctrls)
            for c in ctrls:
                sim.step(st, c)
            return st.dof.reshape(1, -1).copy()

        tape = run(kb, tape=True)
        jvp = tape.jvp({"kappa_bar": direction})["dof"][-1]
        eps = 1e-6
        fd = (run(kb + eps * direction) - run(kb - eps * direction)) / (2 * eps)
        out["rows"].append({"newton_iterations": int(it), "unconverged_steps": tape.unconverged,
                            "relative_gap": float(np.linalg.norm(jvp - fd) / np.linalg.norm(fd))})
    return out


def bench_fit(seconds: float, repeats: int) -> dict:
    """3 parameters from ``seconds`` of motion: exact Jacobian vs finite-difference probing."""
    import tempfile
    from pathlib import Path

    import scipy.optimize

    from sim import build_model
    from sim.analysis import Measurements, Problem, fit, load_controls

    spec = _arm_spec()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "commands.csv"
        rows = ["t,node,kappa1,kappa2,twist"]
        for k, t in enumerate(np.arange(0.0, seconds, 1.0)):  # a new command every second
            rows.append(f"{t:.3f},10,{0.15 * math.sin(1.3 * k + 0.2):.5f},{0.1 * math.cos(0.7 * k):.5f},0")
        path.write_text("\n".join(rows) + "\n")
        cmds = load_controls(path, build_model(spec))
    params = ["youngs_modulus", "damping", "actuation_gain"]
    t = np.arange(0.0, seconds + 1e-9, 1.0 / 30.0)
    s = np.linspace(0.2, 1.0, 5)
    meas0 = Measurements(np.repeat(t, 5), np.tile(s, t.size), np.zeros(t.size * 5, int), np.zeros((t.size * 5, 3)))
    prob = Problem(spec, meas0, cmds, params)
    z_true = np.array([math.log(1.3), 0.3, 0.8])
    pos = prob.predict(prob._node_pos(prob.rollout(z_true).dof[:, 0], None))
    meas = Measurements(meas0.t, meas0.s, meas0.rod, pos + np.random.default_rng(1).normal(0.0, 1e-3, pos.shape))
    truth = prob.values(z_true)
    out: dict = {"seconds_of_motion": seconds, "steps": prob.steps, "points": int(meas.t.size), "params": params,
                 "truth": truth}
    exact, probe = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = fit(spec, meas, params, cmds=cmds)
        exact.append(time.perf_counter() - t0)
        out["exact"] = {"values": res.params, "stderr": res.stderr, "rms_m": res.rms_m, "evaluations": res.iterations,
                        "relative_error": {k: abs(res.params[k] - v) / abs(v) for k, v in truth.items()}}
        pr = Problem(spec, meas, cmds, params)
        lo, hi = pr.bounds()
        t0 = time.perf_counter()
        ls = scipy.optimize.least_squares(lambda z: pr.residuals(pr.rollout(z)), pr.z0(), jac="2-point",
                                          bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=50, xtol=1e-10,
                                          ftol=1e-12, gtol=1e-12)
        probe.append(time.perf_counter() - t0)
        vals = pr.values(ls.x)
        out["probing"] = {"values": vals, "rms_m": float(np.sqrt(np.mean(ls.fun ** 2))), "evaluations": int(ls.nfev),
                          "relative_error": {k: abs(vals[k] - v) / abs(v) for k, v in truth.items()}}
    out["exact"]["seconds_median"] = float(np.median(exact))
    out["probing"]["seconds_median"] = float(np.median(probe))
    out["probing_over_exact"] = out["probing"]["seconds_median"] / out["exact"]["seconds_median"]
    return out


def bench_starts(starts: int, repeats: int) -> dict:
    """Multi-start fitting: one batched iteration of ``starts`` starts (rollout and tangents of every env at once)
    against the same starts one by one, on the paper's arm (3 parameters, 2 s of markers); and a fit one start
    misses (the stiffness of a swinging rod from 1/3.5 of it: a minimum per count of periods) from one start and from
    ``starts``."""
    import tempfile
    from pathlib import Path

    from sim import build_model
    from sim.analysis import Measurements, Problem, fit, load_controls, start_points
    from sim.scene import RodSpec, SceneSpec, SimSpec

    spec = _arm_spec()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "commands.csv"
        path.write_text("t,node,kappa1,kappa2,twist\n0,10,0.15,0.1,0\n1,10,-0.1,0.05,0\n")
        cmds = load_controls(path, build_model(spec))
    t = np.arange(0.0, 2.0 + 1e-9, 1.0 / 30.0)
    s = np.linspace(0.2, 1.0, 5)
    meas = Measurements(np.repeat(t, 5), np.tile(s, t.size), np.zeros(t.size * 5, int), np.zeros((t.size * 5, 3)))
    prob = Problem(spec, meas, cmds, ["youngs_modulus", "damping", "actuation_gain"])
    Z = start_points(prob, starts, np.random.default_rng(0))
    batched, alone = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        prob.jacobians(prob.rollouts(Z), Z)
        batched.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        for z in Z:
            prob.jacobian(prob.rollout(z), z)
        alone.append(time.perf_counter() - t0)
    out: dict = {"starts": starts, "steps": prob.steps, "iteration_batched_s_median": float(np.median(batched)),
                 "iteration_one_by_one_s_median": float(np.median(alone))}
    out["one_by_one_over_batched"] = out["iteration_one_by_one_s_median"] / out["iteration_batched_s_median"]
    # a stiff, lightly damped rod without gravity, its curvature stepped at one node: it swings about the shape the
    # command sets, several periods in 1.5 s, so the residual has a minimum per count of periods
    swing = SceneSpec(sim=SimSpec(dt=0.005, gravity=(0.0, 0.0, 0.0), newton_tol=1e-10, newton_max_iter=30,
                                  accept_unconverged=False, damping=0.05, mode="2d", line_search="none",
                                  newton_dtol=1e-9),
                      rod=RodSpec(nodes=9, length=1.0, radius=0.01, density=1000.0, youngs_modulus=2e8,
                                  poisson_ratio=0.5, start=(0.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0)))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "step.csv"
        path.write_text("t,node,kappa1,kappa2,twist\n0,4,0.4,0,0\n")
        step = load_controls(path, build_model(swing))
    t = np.arange(0.0, 1.5 + 1e-9, 1.0 / 30.0)
    m0 = Measurements(np.repeat(t, 5), np.tile(np.linspace(0.25, 1.0, 5), t.size), np.zeros(t.size * 5, int),
                      np.zeros((t.size * 5, 3)))
    sp = Problem(swing, m0, step, ["youngs_modulus"])
    pos = sp.predict(sp._node_pos(sp.rollout(np.array([math.log(3.5)])).dof[:, 0], 0.0))
    noisy = Measurements(m0.t, m0.s, m0.rod, pos + np.random.default_rng(1).normal(0.0, 1e-3, pos.shape) * [1, 0, 1])
    for k in (1, starts):
        t0 = time.perf_counter()
        res = fit(swing, noisy, ["youngs_modulus"], cmds=step, starts=k)
        out[f"swinging_{k}_starts"] = {"seconds": time.perf_counter() - t0, "rms_m": res.rms_m,
                                       "relative_error": abs(res.params["youngs_modulus"] / 7e8 - 1.0),
                                       "iterations": res.iterations}
    return out


def bench_trajectory(steps: int) -> dict:
    """Open-loop trajectory optimisation: the paper's arm's tip made to follow a path its controls can follow (made by
    random bounded deltas of every interior node's curvature), from rest controls."""
    from sim import Simulator, build_model
    from sim.analysis import optimise_controls

    sim = Simulator(build_model(_arm_spec()), envs=1)
    rng = np.random.default_rng(0)
    st, c = sim.reset(), sim.make_control()
    path = []
    for _ in range(steps):
        c.kappa_bar[:, 1:-1] += rng.uniform(-0.02, 0.02, c.kappa_bar[:, 1:-1].shape)
        sim.step(st, c)
        path.append(st.dof.reshape(1, -1, 4)[0, -1, :3].copy())
    res = optimise_controls(sim, sim.reset(), np.array(path), max_delta=0.02, max_iterations=300)
    err = np.linalg.norm(res.positions[:, 0] - np.array(path), axis=1)
    return {"steps": steps, "unknowns": int(steps * (sim.model.node_count - 2) * 2), "evaluations": res.evaluations,
            "seconds": res.seconds, "cost0": float(res.cost0[0]), "cost": float(res.cost[0]),
            "tip_error_max_m": float(err.max()), "tip_error_final_m": float(err[-1])}


def bench_baseline(episodes: int) -> dict:
    from pathlib import Path

    import policies
    from policies.learning import evaluate

    out = {}
    root = Path(policies.__file__).parent / "pretrained"
    for task, zip_name in (("follow_target", "follow_target.zip"), ("ik4d", "ik4d.zip")):
        row = {}
        pols = [("inverse_statics", "inverse-statics"), ("trajectory", "trajectory"), ("sac", str(root / zip_name))]
        for name, pol in pols:
            r = evaluate(pol, task, episodes=episodes, num_envs=min(episodes, 10), seed=0)
            row[name] = {k: r.get(k) for k in ("avg_discounted_return_mean", "avg_discounted_return_std",
                                               "final_tip_error_mean", "final_orientation_error_deg_mean",
                                               "reached_rate", "wall_s")}
        out[task] = row
    return out


def main(argv: list[str] | None = None) -> int:
    p = base_parser("rodlab bench gradients", __doc__.split("\n")[0])
    p.add_argument("--envs", type=int, default=50, help="envs of the step-derivative timing (default 50)")
    p.add_argument("--fit-seconds", type=float, default=10.0, help="seconds of motion to fit (default 10)")
    p.add_argument("--episodes", type=int, default=10, help="episodes per task of the baseline comparison")
    p.add_argument("--parts", default="step,gap,fit,starts,trajectory,baseline")
    p.add_argument("--starts", type=int, default=8, help="starts of the multi-start figures (default 8)")
    args = p.parse_args(argv)
    parts = set(args.parts.split(","))
    reps = args.repeats or (1 if args.quick else 3)
    out: dict = {"machine": machine_info()}
    if "step" in parts:
        out["step"] = bench_step(4 if args.quick else args.envs, reps)
        st = out["step"]
        print(f"step ({st['envs']} envs): forward {st['forward_ms_per_env']:.3f} ms/env, backward "
              f"{st['backward_ms_per_env']:.3f} ms/env ({st['backward_over_forward']:.0f}x; linearisation "
              f"{st['linearise_ms_per_env']:.3f}); memory {st['record_bytes_per_env_step']} B recorded + "
              f"{st['linearisation_bytes_per_env_step']} B linearisation per env-step")
        out["checkpoint"] = ck = bench_checkpoint(4 if args.quick else min(args.envs, 100), 10 if args.quick else 100,
                                                  5 if args.quick else 10, reps)
        print(f"rollout of {ck['steps']} steps ({ck['envs']} envs): kept {ck['whole']['bytes_per_env_step']:.0f} B per "
              f"env-step whole, {ck['checkpointed']['bytes_per_env_step']:.0f} B checkpointed every {ck['every']} "
              f"({ck['memory_ratio']:.2f}x); adjoint pass {ck['whole']['adjoint_s_median']:.2f} s vs "
              f"{ck['checkpointed']['adjoint_s_median']:.2f} s ({ck['time_ratio']:.2f}x)")
    if "gap" in parts:
        out["unconverged_gap"] = g = bench_unconverged_gap(10 if args.quick else 40)
        for row in g["rows"]:
            print(f"paper arm, {g['steps']} steps of {row['newton_iterations']} Newton iterations "
                  f"({row['unconverged_steps']} unconverged): relative gap {row['relative_gap']:.3g}")
    if "fit" in parts:
        out["fit"] = bench_fit(1.0 if args.quick else args.fit_seconds, reps)
        ft = out["fit"]
        print(f"fit ({ft['seconds_of_motion']:g} s, {ft['points']} points): exact {ft['exact']['seconds_median']:.1f} s "
              f"({ft['exact']['evaluations']} evaluations), probing {ft['probing']['seconds_median']:.1f} s "
              f"({ft['probing']['evaluations']}); ratio {ft['probing_over_exact']:.2f}; errors "
              f"{ {k: round(v, 4) for k, v in ft['exact']['relative_error'].items()} }")
    if "starts" in parts:
        out["starts"] = ms = bench_starts(2 if args.quick else args.starts, reps)
        one, many = ms["swinging_1_starts"], ms[f"swinging_{ms['starts']}_starts"]
        print(f"{ms['starts']} starts: a batched iteration {ms['iteration_batched_s_median']:.2f} s, one by one "
              f"{ms['iteration_one_by_one_s_median']:.2f} s ({ms['one_by_one_over_batched']:.2f}x); swinging rod: one "
              f"start rms {one['rms_m'] * 1e3:.2f} mm ({one['seconds']:.1f} s), {ms['starts']} starts "
              f"{many['rms_m'] * 1e3:.2f} mm, E off by {many['relative_error']:.2%} ({many['seconds']:.1f} s)")
    if "trajectory" in parts:
        out["trajectory"] = tr = bench_trajectory(10 if args.quick else 50)
        print(f"trajectory ({tr['steps']} steps, {tr['unknowns']} unknowns): cost {tr['cost0']:.3g} -> {tr['cost']:.3g} "
              f"in {tr['evaluations']} evaluations, {tr['seconds']:.1f} s; tip error max {tr['tip_error_max_m'] * 1e3:.2f} "
              f"mm, final {tr['tip_error_final_m'] * 1e3:.2f} mm")
    if "baseline" in parts:
        out["baseline"] = bench_baseline(2 if args.quick else args.episodes)
        for task, row in out["baseline"].items():
            print(task, {k: round(v["avg_discounted_return_mean"], 2) for k, v in row.items()})
    out["machine"]["loadavg_at_end"] = machine_info()["loadavg_at_start"]
    path = write_json(args.out, "gradients.json", out)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
