"""`rodlab sim` (simulate a scene headless) and `rodlab bench sim` (time one batched step)."""
from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from sim import Simulator, build_model, load_scene
from sim.analysis.static import solve_static
from sim.scene.check import overlap_warning, rod_obstacle_overlaps
from sim.scene.spec import SceneError
from sim.support.assets import asset_path
from sim.support.atomicio import savez
from sim.support.paths import check_output_path
from sim.support.progress import add_progress_flag, progress_bar, progress_wanted
from sim.support.text import count
from sim.warmup import compile_kernels

__all__ = ["sim_main", "bench_sim_main"]


def _atomic_savez(path: str, **arrays) -> None:
    savez(path, compressed=True, **arrays)


_FRAME_BYTES_LIMIT = 4 * 2 ** 30  # --out keeps the frames in memory until the end: refuse more than 4 GiB up front
_MAX_ENVS = 100_000
EXIT_UNSTABLE = 3  # rodlab sim --static: every env converged, some to an unstable equilibrium


def sim_main(argv: list[str] | None = None) -> int:
    """rodlab sim SCENE.toml --duration T [--envs B] [--every K] [--out FILE.npz] [--progress/--no-progress]"""
    ap = argparse.ArgumentParser(prog="rodlab sim", description="Simulate a scene headless (rest controls). "
                                 "Prints a warning when the rod starts inside an obstacle.")
    ap.add_argument("scene", help="scene TOML file")
    ap.add_argument("--duration", type=float, help="simulated time [s] (finite, > 0; required unless --static)")
    ap.add_argument("--static", action="store_true",
                    help="solve for static equilibrium instead (sim.analysis.static: backward-Euler pseudo-time steps growing "
                         "to 1e5 s with zeroed velocities, until a step moves no node by more than "
                         "--static-tol x rod length); --out then holds one frame. Exit status 0: every env at a "
                         "stable equilibrium, 1: some env did not converge, 3: converged, but some env is at an "
                         "unstable one (see --to-stable)")
    ap.add_argument("--static-tol", type=float, default=1e-10, help="relative displacement tolerance of --static")
    ap.add_argument("--to-stable", action="store_true",
                    help="with --static: an env that ends at an unstable equilibrium (a saddle of the energy, e.g. a "
                         "column above its buckling load left straight) is pushed along its most negative "
                         "direction and relaxed again, at most 4 times (docs/physics.md §3.8)")
    ap.add_argument("--envs", type=int, default=1, help=f"number of environments (default 1, at most {_MAX_ENVS})")
    ap.add_argument("--every", type=int, default=1, help="record every K-th step (default 1)")
    ap.add_argument("--out", help="write time, node_pos (frames, envs, nodes of all rods, 3), edge_theta, "
                                  "newton_iters, converged, midpoint_fallbacks, max_penetration, contact_count, contact_dropped "
                                  "(rows not listed), contact_force (the total over every contact) (and "
                                  "per-contact rows: obstacle contacts and edge pairs), rod_node_offsets (where "
                                  "each rod's nodes start, then the total) and rod_names to this .npz; its folder "
                                  "is checked for writing before the simulation starts")
    add_progress_flag(ap)
    a = ap.parse_args(argv)

    def fail(msg: str) -> int:
        print(f"rodlab sim: {msg}", file=sys.stderr)
        return 2

    if not 1 <= a.envs <= _MAX_ENVS or a.every < 1:
        return fail(f"--envs must be in [1, {_MAX_ENVS}] and --every >= 1")
    if a.static:
        if not (math.isfinite(a.static_tol) and a.static_tol > 0):
            return fail(f"--static-tol must be a finite number > 0, got {a.static_tol!r}")
    elif a.duration is None or not (math.isfinite(a.duration) and a.duration > 0):
        return fail(f"--duration must be a finite number > 0 [s], got {a.duration!r}")
    try:
        if a.out:
            check_output_path(a.out)
        spec = load_scene(a.scene)
    except (SceneError, ValueError) as exc:
        return fail(str(exc))
    if a.static:
        return _static_main(a, spec, fail)
    t0 = time.perf_counter()
    model = build_model(spec)
    n = max(1, int(round(a.duration / model.dt)))
    kept = -(-n // a.every)
    if a.out:
        per_env = model.node_count * 3 * 8 + model.node_count * 8 + 64
        if spec.obstacles:
            per_env += 64 * 104  # contact rows (StepStats capacity)
        need = kept * a.envs * per_env
        if need > _FRAME_BYTES_LIMIT:
            return fail(f"--out would keep {kept} frames x {a.envs} envs = {need / 2 ** 30:.1f} GiB in memory "
                        f"(limit {_FRAME_BYTES_LIMIT / 2 ** 30:.0f} GiB); raise --every (e.g. --every "
                        f"{a.every * math.ceil(need / _FRAME_BYTES_LIMIT)}) or shorten --duration")
    sim = Simulator(model, envs=a.envs)
    warn = overlap_warning(rod_obstacle_overlaps(model), a.scene)
    if warn:
        print(warn, file=sys.stderr)
    state = sim.reset()
    ctrl = sim.make_control()
    first = sim.step(state.copy(), ctrl)  # compile / load kernels outside the timing
    t_ready = time.perf_counter() - t0
    frames: dict[str, list] = {"time": [], "node_pos": [], "edge_theta": [], "newton_iters": [], "converged": [],
                               "midpoint_fallbacks": [], "max_penetration": [], "contact_count": [],
                               "contact_dropped": [], "contact_force": []}
    crow = ("contact_edge", "contact_obstacle", "contact_partner_edge", "contact_rod_point", "contact_normal",
            "contact_normal_force", "contact_friction_force", "contact_gap") if first.contact_edge.shape[1] else ()
    for name in crow:
        frames[name] = []
    it_sum, it_max = 0, 0
    dropped_rows = 0  # contact rows that did not fit a step's report (the totals count them; the rows list not)
    fell = np.zeros(a.envs, np.int64)  # midpoint sub-steps redone by backward Euler, per env
    subs = np.zeros(a.envs, np.int64)
    t1 = time.perf_counter()
    with progress_bar(n, desc="rodlab sim", enabled=progress_wanted(a.progress)) as bar:
        for k in range(1, n + 1):
            st = sim.step(state, ctrl)
            it_sum += int(st.newton_iters.sum())
            it_max = max(it_max, int(st.newton_iters.max()))
            fell += st.midpoint_fallbacks
            subs += st.substeps
            bar.update(1)
            if a.out and (k % a.every == 0 or k == n):
                frames["time"].append(k * model.dt)
                frames["node_pos"].append(state.node_pos.copy())
                frames["edge_theta"].append(np.array(state.edge_theta))
                frames["newton_iters"].append(st.newton_iters.copy())
                frames["converged"].append(st.converged.copy())
                frames["midpoint_fallbacks"].append(st.midpoint_fallbacks.copy())
                # contact (sim/contact): max penetration (B,) [m], count (B,) of the listed rows, rows dropped (B,)
                # (not listed: the report was full), total force on the rods (B, 3) [N] over every contact, listed
                # or not; per-row (B, C, ...) (the first contact_count; the rows after them are left from earlier
                # steps; C grows when rows were dropped, so a step's rows are padded to the largest C)
                frames["max_penetration"].append(st.max_penetration.copy())
                frames["contact_count"].append(st.contact_count.copy())
                frames["contact_dropped"].append(st.contact_dropped.copy())
                frames["contact_force"].append(st.contact_force.copy())
                for name in crow:
                    frames[name].append(getattr(st, name).copy())
            dropped_rows += int(st.contact_dropped.sum())
    wall = time.perf_counter() - t1
    if a.out:
        try:
            _atomic_savez(a.out, **{k: _stack_rows(v) if k in crow else np.asarray(v) for k, v in frames.items()},
                          **_rod_arrays(model))
        except OSError as exc:
            return fail(f"{a.out}: cannot write: {exc.strerror or exc}")
        print(f"rodlab sim: wrote {len(frames['time'])} frames to {a.out}")
    print(f"scene {a.scene}: {count(n, 'step')} of {model.dt:g} s, {count(a.envs, 'env')}, mode {model.mode}")
    _print_tips(model, state, 5)
    print(f"newton iterations per step: mean {it_sum / (n * a.envs):.2f}, max {it_max}; "
          f"failed envs: {int(state.failed.sum())}")
    if model.integrator == "midpoint":
        print(_midpoint_line(fell, subs))
    if dropped_rows:
        print(f"contact rows: {dropped_rows} did not fit the steps' reports and are not listed (contact_dropped); "
              "the total contact force and max penetration include them")
    print(f"time per step: {wall / n * 1e3:.3f} ms (kernels ready in {t_ready:.2f} s)")
    return 0


def _stack_rows(frames: list) -> np.ndarray:
    """Stack per-frame contact rows (B, C, ...) whose capacity C grew during the run: padded to the largest C (-1 for
    the integer columns, 0 otherwise; the rows past contact_count are not contacts)."""
    C = max(f.shape[1] for f in frames)
    out = np.full((len(frames), frames[0].shape[0], C) + frames[0].shape[2:], -1 if frames[0].dtype.kind == "i" else 0,
                  dtype=frames[0].dtype)
    for k, f in enumerate(frames):
        out[k, :, :f.shape[1]] = f
    return out


def _midpoint_line(fell: np.ndarray, subs: np.ndarray) -> str:
    """The summary line of a midpoint run: how many sub-steps gained energy and were redone by backward Euler
    (docs/physics.md §3.3), over all envs and for the worst env."""
    total, worst = int(fell.sum()), int(np.argmax(fell))
    line = (f"midpoint fallbacks: {total} of {int(subs.sum())} sub-steps redone by backward Euler "
            f"(gained energy)")
    if total and fell.shape[0] > 1:
        line += f"; most in env {worst}: {int(fell[worst])} of {int(subs[worst])}"
    return line


def _rod_arrays(model) -> dict:
    """The per-rod layout written with the frames: rod_node_offsets (R+1,) int64 (each rod's first node in
    node_pos, then the total) and rod_names (R,) str (docs/physics.md §1.7)."""
    return {"rod_node_offsets": np.asarray(model.rod_node_offsets, dtype=np.int64),
            "rod_names": np.asarray(model.rod_names, dtype=str)}


def _print_tips(model, state, precision: int) -> None:
    """The tip (last node) of env 0: of the rod, or of each rod by name."""
    if model.rod_count == 1:
        print(f"tip position env 0 [m]: {np.array2string(state.node_pos[0, -1], precision=precision)}")
        return
    for name, pos in model.split_rods(state.node_pos[0]).items():
        print(f"tip position of rod {name!r}, env 0 [m]: {np.array2string(pos[-1], precision=precision)}")


def _static_main(a: argparse.Namespace, spec, fail) -> int:
    """``rodlab sim --static``: relax the rest state to equilibrium (sim.analysis.static) and report / write it."""
    t0 = time.perf_counter()
    model = build_model(spec)
    sim = Simulator(model, envs=a.envs)
    state, ctrl = sim.reset(), sim.make_control()
    res = solve_static(spec, state, ctrl, xtol=a.static_tol, to_stable=a.to_stable)
    wall = time.perf_counter() - t0
    if a.out:
        try:
            _atomic_savez(a.out, time=np.zeros(1), node_pos=state.node_pos[None].copy(),
                          edge_theta=np.asarray(state.edge_theta)[None].copy(), converged=res.converged[None],
                          static_steps=res.steps, static_last_move=res.last_move, stable=res.stable,
                          negative_directions=res.negative_directions, **_rod_arrays(model))
        except OSError as exc:
            return fail(f"{a.out}: cannot write: {exc.strerror or exc}")
        print(f"rodlab sim: wrote the static equilibrium to {a.out}")
    print(f"scene {a.scene}: static equilibrium, {count(a.envs, 'env')}, mode {sim.model.mode}")
    _print_tips(model, state, 6)
    print(f"converged envs: {int(res.converged.sum())}/{a.envs} after {int(res.steps.max())} pseudo-time steps "
          f"(last dt {res.dt:g} s, largest last move {float(res.last_move.max()):.3g} m); {wall:.2f} s")
    if res.perturbations.any():
        print(f"pushed off an unstable equilibrium: {count(int((res.perturbations > 0).sum()), 'env')}, "
              f"{count(int(res.perturbations.sum()), 'time')} in all")
    bad = np.flatnonzero(res.converged & ~res.stable)
    if bad.size:
        print(f"unstable equilibrium in {count(bad.size, 'env')} (first: env {int(bad[0])}, "
              f"{count(int(res.negative_directions[bad[0]]), 'negative direction')}, lowest eigenvalue "
              f"{float(res.lowest_eigenvalue[bad[0]]):.3g} 1/s^2)"
              + ("" if a.to_stable else "; --to-stable looks for a stable one nearby"))
    elif res.converged.all():
        print("stable equilibrium (no negative direction of the static Hessian)")
    if not res.converged.all():
        return 1
    return EXIT_UNSTABLE if bad.size else 0


def bench_sim_main(argv: list[str] | None = None) -> int:
    """rodlab bench sim [--scene S] [--envs B] [--steps n] [--repeats r] [--json] [--out FILE]"""
    ap = argparse.ArgumentParser(prog="rodlab bench sim", description="Median time of one batched sim step.")
    ap.add_argument("--scene", default=str(asset_path("scenes/arm.toml")))
    ap.add_argument("--envs", type=int, default=500)
    ap.add_argument("--steps", type=int, default=20, help="timed steps per repeat")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--control-interval", type=int, default=2, help="sim steps per control step (default 2)")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--out", help="also write the JSON to this file")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    compile_s = compile_kernels()
    import_and_compile_s = time.perf_counter() - t0
    model = build_model(load_scene(a.scene))
    sim = Simulator(model, envs=a.envs)
    state = sim.reset()
    ctrl = sim.make_control()
    rng = np.random.default_rng(0)
    rate = 0.01 * rng.uniform(-1, 1, size=(a.envs, 1, 2))
    for _ in range(3):
        sim.step(state, ctrl)
    per_step, per_ctrl, cpu, cpu_run = [], [], [], []
    for _ in range(a.repeats):
        r0 = time.process_time()
        for _ in range(a.steps):
            ctrl.kappa_bar[:, 1:-1, :] += rate / a.control_interval
            c0 = time.process_time()
            s0 = time.perf_counter()
            sim.step(state, ctrl)
            per_step.append(time.perf_counter() - s0)
            cpu.append(time.process_time() - c0)
        cpu_run.append((time.process_time() - r0) / a.steps)  # also what threads spend waiting between steps
        for _ in range(max(1, a.steps // a.control_interval)):
            s0 = time.perf_counter()
            for _ in range(a.control_interval):
                ctrl.kappa_bar[:, 1:-1, :] += rate / a.control_interval
                sim.step(state, ctrl)
            per_ctrl.append(time.perf_counter() - s0)
    import numba
    res = {
        "scene": a.scene, "envs": a.envs, "nodes": model.node_count, "mode": model.mode,
        "newton_max_iter": model.newton_max_iter, "threads": numba.get_num_threads(),
        "ms_per_step_median": 1e3 * statistics.median(per_step),
        "ms_per_step_min": 1e3 * min(per_step),
        "cpu_ms_per_step_median": 1e3 * statistics.median(cpu),
        "cpu_ms_per_step_in_run_median": 1e3 * statistics.median(cpu_run),
        "ms_per_control_step_median": 1e3 * statistics.median(per_ctrl),
        "control_interval": a.control_interval,
        "compile_s": compile_s, "import_and_compile_s": import_and_compile_s,
        "failed_envs": int(state.failed.sum()),
    }
    text = json.dumps(res, indent=None if a.json else 2)
    if a.out:
        Path(a.out).write_text(json.dumps(res, indent=2) + "\n")
    if a.json:
        print(text)
    else:
        print(f"{a.envs} envs x {model.node_count} nodes ({model.mode}), {res['threads']} threads: "
              f"{res['ms_per_step_median']:.2f} ms per sim step (median; min {res['ms_per_step_min']:.2f}), "
              f"{res['ms_per_control_step_median']:.2f} ms per {a.control_interval}-step control step; "
              f"kernels ready in {compile_s:.2f} s")
    return 0
