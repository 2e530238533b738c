"""Contact throughput benchmark: ``python -m benchmarks.contact_bench [--json] [--quick]``.

Prints ms per control step (10 sim steps, 5 Newton iterations, dt = 0.05 s) for

* the paper's 2-D tight-obstacles task (500 envs, 6 capsules; target <= 120 ms on 2 cores),
* the 3-D random-obstacles task (500 envs, 8 random capsules per env re-placed with ``set_capsules``;
  target <= 240 ms),
* cost vs number of obstacles (0-64 spheres, near the rod or far from it; 100 envs, 3-D),
* cost vs mesh size (icosphere meshes of 80 ... 81,920 triangles touching the arm; 100 envs, 3-D), with
  the BVH build time.

The arms are driven like the RL contact tasks with uniform random actions (docs/tasks.md §2.3: natural curvature
K += 0.25 a per control step on 5 control points, clipped to +-2, interpolated over the 10 sim steps). Figures are medians over the timed control steps; the first steps (compile, warm-up)
are not timed. Numba uses all cores it is given (``NUMBA_NUM_THREADS``). Each case also reports the process CPU
time per control step (all threads; on a quiet 2-core machine wall ~ CPU / 2) and the load average, and
the two task cases report the same control steps without obstacles (``no_contact_ms``).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from sim import Simulator, build_model, load_scene
from sim.scene import CapsuleSpec, MeshSpec, SphereSpec
from sim.support.assets import asset_path

SCENES = asset_path("scenes")


def _with(spec, *, obstacles=None, max_iter=5):
    sim = dataclasses.replace(spec.sim, newton_max_iter=max_iter, dt=0.05)
    return dataclasses.replace(spec, sim=sim, obstacles=tuple(obstacles) if obstacles is not None else spec.obstacles)


class RandomPolicy:
    """docs/tasks.md §2.3-2.4 contact-task control with uniform random actions: per control step
    K = clip(K + 0.25 a, -2, 2) on 5 control points (per bending component), spread over node segments
    [1,4), [4,8), [8,12), [12,16), [16,20) (divided by the segment's node count) and interpolated over the
    control step's sim steps."""

    SEG = (1, 4, 8, 12, 16, 20)

    def __init__(self, B, comps, seed):
        self.rng = np.random.default_rng(seed)
        self.K = np.zeros((B, 5, comps))
        self.comps = comps

    def increments(self, substeps):
        a = self.rng.uniform(-1.0, 1.0, size=self.K.shape)
        new = np.clip(self.K + 0.25 * a, -2.0, 2.0)
        dK = new - self.K
        self.K = new
        inc = np.zeros((dK.shape[0], 21, 2))
        for k in range(5):
            lo, hi = self.SEG[k], self.SEG[k + 1]
            inc[:, lo:hi, :self.comps] = dK[:, k, None, :] / (hi - lo)
        return inc / substeps


def run_case(spec, B, *, control_steps=6, warm=2, substeps=10, seed=0, setup=None) -> dict:
    """Median wall time [ms] per control step (``substeps`` sim steps) and contact statistics."""
    model = build_model(spec)
    sim = Simulator(model, envs=B)
    st = sim.reset()
    ctrl = sim.make_control()
    if setup is not None:
        setup(sim, st)
    pol = RandomPolicy(B, 1 if model.mode == "2d" else 2, seed)
    times, cpu, pen, cnt, conv, failed, deep, nstep = [], [], 0.0, [], [], 0, 0, 0
    for c in range(warm + control_steps):
        inc = pol.increments(substeps)
        t0 = time.perf_counter()
        c0 = time.process_time()
        for _ in range(substeps):
            ctrl.kappa_bar += inc
            s = sim.step(st, ctrl)
            if c >= warm:
                ok = ~st.failed
                pen = max(pen, float(s.max_penetration[ok].max(initial=0.0)))
                deep += int(np.sum(s.max_penetration[ok] > spec.contact.delta))
                nstep += int(ok.sum())
                cnt.append(float(s.contact_count.mean()))
                conv.append(float(s.converged.mean()))
                failed += int(s.failed.sum())
        if c >= warm:
            times.append(time.perf_counter() - t0)
            cpu.append(time.process_time() - c0)
    return {"ms_per_control_step": 1e3 * float(np.median(times)),
            "cpu_ms_per_control_step": 1e3 * float(np.median(cpu)), "envs": B, "obstacles": len(spec.obstacles),
            "mean_contacts_per_env": float(np.mean(cnt)) if cnt else 0.0, "max_penetration_m": pen,
            "env_steps_penetration_over_delta": deep / max(nstep, 1),
            "converged_fraction": float(np.mean(conv)) if conv else 1.0, "failed_env_steps": failed}


def _seg_dist_to_arm(a, b):
    """Distance of segments (a, b) (..., 3) to the rest arm, the z-axis segment from 0 to 1 (sampled)."""
    s = np.linspace(0.0, 1.0, 41)
    p = a[..., None, :] + s[:, None] * (b - a)[..., None, :]
    rad = np.hypot(p[..., 0], p[..., 1])
    dz = np.maximum(0.0, np.maximum(-p[..., 2], p[..., 2] - 1.0))
    return np.hypot(rad, dz).min(axis=-1)


def random_capsules(rng, k, m=8, R=0.03, clearance=0.05 + 0.03 + 0.05):
    """docs/tasks.md 3-D obstacles: m capsules of length 1, centres in x[0.3,0.6], y[-0.6,0.6], z[-0.1,0.8],
    random directions; re-drawn while one would touch the straight rest arm (clearance [m])."""
    c = np.zeros((k, m, 3))
    d = np.zeros((k, m, 3))
    todo = np.ones((k, m), bool)
    while todo.any():
        n = int(todo.sum())
        c[todo] = np.stack([rng.uniform(0.3, 0.6, n), rng.uniform(-0.6, 0.6, n), rng.uniform(-0.1, 0.8, n)], -1)
        dd = rng.normal(size=(n, 3))
        d[todo] = dd / np.linalg.norm(dd, axis=-1, keepdims=True)
        todo = _seg_dist_to_arm(c - 0.5 * d, c + 0.5 * d) < clearance
    return c - 0.5 * d, c + 0.5 * d, R


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON document")
    ap.add_argument("--quick", action="store_true", help="fewer envs/steps (smoke run)")
    ap.add_argument("--envs", type=int, default=500)
    args = ap.parse_args(argv)
    B = 50 if args.quick else args.envs
    Bs = 20 if args.quick else 100
    cs = 2 if args.quick else 6
    out: dict = {"threads": __import__("numba").get_num_threads(), "load_average_1min": os.getloadavg()[0],
                 "note": "wall times inflate when other processes load the cores; cpu_ms is process CPU time "
                         "summed over threads (~ wall x threads on a quiet machine)"}
    log = (lambda *a: None) if args.json else print

    arm2d = load_scene(SCENES / "tight_obstacles_2d.toml")
    r = run_case(_with(arm2d), B, control_steps=cs)
    r0 = run_case(_with(arm2d, obstacles=()), B, control_steps=cs)
    r["no_contact_ms"], r["no_contact_cpu_ms"] = r0["ms_per_control_step"], r0["cpu_ms_per_control_step"]
    out["tight_obstacles_2d"] = {**r, "target_ms": 120}
    log(f"2-D tight obstacles, {B} envs: {r['ms_per_control_step']:.1f} ms / control step (target 120); {r}")

    arm3d = load_scene(SCENES / "arm.toml")
    caps = [CapsuleSpec((0.45, -0.5, 0.3), (0.45, 0.5, 0.3), 0.03) for _ in range(8)]
    rng = np.random.default_rng(0)

    def place(sim, state):
        a, b, R = random_capsules(rng, state.env_count)
        sim.set_capsules(state, np.arange(state.env_count), a, b, R)

    probe_sim = Simulator(build_model(_with(arm3d, obstacles=caps)), envs=B)
    place_probe = probe_sim.reset()
    t0 = time.perf_counter()
    place(probe_sim, place_probe)  # sampling (with rejection) + set_capsules for all envs
    t_place = 1e3 * (time.perf_counter() - t0)
    a_, b_, R_ = random_capsules(rng, B)
    t0 = time.perf_counter()
    probe_sim.set_capsules(place_probe, np.arange(B), a_, b_, R_)
    t_set = 1e3 * (time.perf_counter() - t0)
    r = run_case(_with(arm3d, obstacles=caps), B, control_steps=cs, setup=place)
    r0 = run_case(_with(arm3d, obstacles=()), B, control_steps=cs)
    r["no_contact_ms"], r["no_contact_cpu_ms"] = r0["ms_per_control_step"], r0["cpu_ms_per_control_step"]
    out["random_obstacles_3d"] = {**r, "target_ms": 240, "sample_and_place_ms": t_place,
                                   "set_capsules_ms": t_set}
    log(f"3-D random obstacles, {B} envs: {r['ms_per_control_step']:.1f} ms / control step (target 240); {r}")

    rows = []
    for M in (0, 1, 4, 16, 64):
        for where in ("near", "far"):
            if M == 0 and where == "far":
                continue
            ang = np.linspace(0, 2 * np.pi, max(M, 1), endpoint=False)
            z = np.linspace(0.2, 0.95, max(M, 1))
            rad = 0.17 if where == "near" else 10.0
            obs = [SphereSpec((rad * np.cos(a), rad * np.sin(a), zz), 0.1) for a, zz in zip(ang[:M], z[:M])]
            r = run_case(_with(arm3d, obstacles=obs), Bs, control_steps=max(2, cs // 2))
            rows.append({"obstacles": M, "where": where, **r})
            log(f"  {M:3d} spheres {where:4s}, {Bs} envs: {r['ms_per_control_step']:.1f} ms / control step")
    out["vs_obstacle_count"] = rows

    rows = []
    import trimesh

    with tempfile.TemporaryDirectory() as td:
        for sub in (1, 2, 3, 4, 5, 6):
            m = trimesh.creation.icosphere(subdivisions=sub, radius=0.15)
            f = Path(td) / f"ico{sub}.ply"
            m.export(f)
            spec = _with(arm3d, obstacles=[MeshSpec(str(f), str(f), position=(0.22, 0.0, 0.6))])
            t0 = time.perf_counter()
            build_model(spec)
            t_build = 1e3 * (time.perf_counter() - t0)
            r = run_case(spec, Bs, control_steps=max(2, cs // 2))
            rows.append({"triangles": int(len(m.faces)), "bvh_build_ms": t_build, **r})
            log(f"  mesh {len(m.faces):6d} triangles, {Bs} envs: {r['ms_per_control_step']:.1f} ms / control step "
                f"(load+BVH {t_build:.0f} ms)")
    out["vs_mesh_size"] = rows
    if args.json:
        print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
