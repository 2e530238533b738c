"""Parts of ``rodlab bench throughput``: the per-task rodlab vs PyElastica step, and contact cost.

PyElastica is measured per env with several rods (envs) in one simulator, at the paper's settings
(docs/tasks.md §1.6), and scaled to the batch: ``cost(B envs, one control step) = B × (seconds per rod per
sim step) × (sim steps per control step)``.  Two measurements: 1 rod per simulator (the paper's layout,
one env per process) and ``K`` rods per simulator (cheaper per rod); the ratio uses the cheaper one.
PyElastica runs on one core; rodlab uses all numba threads of this machine (recorded).  A
"per-core" ratio (PyElastica spread perfectly over the same number of cores) is reported too.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from .common import load, save_figure
from .rodlab_runs import Solver
from .throughput_timing import arm_doc, time_sim

# task short name -> (elastica sim steps per control step, obstacles kind, planar)
TASKS = {
    "follow_target": (500, None, False),
    "follow_target_2d": (500, None, True),
    "ik4d": (500, None, False),
    "tight_obstacles_2d": (2500, "crevice", True),
    "random_obstacles_3d": (2500, "fence", False),
}
CREVICE = [(0.20, 0.12), (0.60, 0.12), (0.40, 0.00), (0.40, 0.37), (0.40, 0.57), (0.40, 0.77)]
# 8 fence capsules (first 8 of the legacy fixed table of docs/tasks.md §7.6, y-centred): start, end
FENCE = [((0.4425154, 0.49850288, 0.58865217), (0.45413066, -0.49850288, 0.66510208)),
         ((0.47060477, 0.49020672, 0.40550133), (0.53797149, -0.49020672, 0.59057215)),
         ((0.52103567, 0.47770318, 0.45720746), (0.63848153, -0.47770318, 0.18627359)),
         ((0.42403193, 0.46883875, 0.29457996), (0.29228492, -0.46883875, 0.61614434)),
         ((0.54241729, 0.48989333, 0.36434108), (0.48081261, -0.48989333, 0.1740178)),
         ((0.48713428, 0.484539, 0.03351721), (0.40485587, -0.484539, 0.26615021)),
         ((0.46114762, 0.48291636, 0.47846214), (0.3813956, -0.48291636, 0.23187181)),
         ((0.40333985, 0.45045316, 0.06916875), (0.29705281, -0.45045316, -0.35162915))]


def _numba_threads() -> int:
    try:
        import numba
        return int(numba.get_num_threads())
    except Exception:  # pragma: no cover
        return 1


def elastica_cylinders(kind: str | None):
    from .peers.elastica_scenes import CylinderSpec
    if kind == "crevice":
        return tuple(CylinderSpec((x, -0.5, z), (x, 0.5, z), 0.1) for x, z in CREVICE)
    if kind == "fence":
        return tuple(CylinderSpec(s, e, 0.03) for s, e in FENCE)
    return ()


def elastica_rod_step_cost(*, rods: int, obstacles: str | None, planar: bool, steps: int = 200,
                           repeats: int = 3) -> dict:
    """Seconds per rod per sim step of PyElastica at the paper's settings, with the per-step
    rest-curvature update of the paper's control loop."""
    from .peers.elastica_scenes import ElasticaRods, RodSpec
    el = ElasticaRods(RodSpec(), n_rods=rods, dt=2e-4, obstacles=elastica_cylinders(obstacles))
    dk = np.zeros((rods, 21, 2))
    dk[:, 2:20, 0] = 1e-5
    if not planar:
        dk[:, 2:20, 1] = -1e-5

    def run(n):
        for _ in range(n):
            el.add_natural_curvature(dk)
            el.step(1)

    run(5)
    ts, cs = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        run(steps)
        ts.append((time.perf_counter() - t0) / steps / rods)
        cs.append((time.process_time() - c0) / steps / rods)
    return {"rods_per_simulator": rods, "s_per_rod_step": float(np.median(ts)),
            "cpu_s_per_rod_step": float(np.median(cs)), "nan": el.has_nan(),
            "repeats": repeats, "load": load()}


def rodlab_task_step(task: str, *, envs: int, steps: int, repeats: int) -> dict:
    """Median wall time [ms] of one control step of ``envs`` envs of a task core (random actions)."""
    from policies.tasks import TASK_SPECS, gym_task_id
    _, core_cls, cfg_fn = TASK_SPECS[gym_task_id(task)].load()
    t0 = time.perf_counter()
    core = core_cls(cfg_fn(), envs=envs, seed=0)
    core.reset()
    setup_s = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    act = lambda: rng.uniform(-1, 1, size=(envs, core.action_dim)).astype(np.float32)  # noqa: E731
    core.step(act())
    ts, cs, iters = [], [], []
    for _ in range(repeats):
        t1, c1 = time.perf_counter(), time.process_time()
        for _ in range(steps):
            info = core.step(act())[4]
            iters.append(float(np.mean(info["newton_iters"])))
        ts.append((time.perf_counter() - t1) / steps)
        cs.append((time.process_time() - c1) / steps)
    return {"envs": envs, "ms_per_control_step": 1e3 * float(np.median(ts)),
            "cpu_ms_per_control_step": 1e3 * float(np.median(cs)), "setup_s": setup_s,
            "substeps": core.config.substeps, "dt": core.config.dt, "newton_max_iter": core.config.newton_max_iter,
            "newton_iters_per_control_step": float(np.mean(iters)), "repeats": repeats, "load": load()}


def part_tasks(*, envs: int, quick: bool, peer: bool, repeats: int) -> dict:
    out: dict = {"envs": envs, "numba_threads": _numba_threads(), "rows": []}
    K = 4 if quick else 10
    for task, (el_sub, obst, planar) in TASKS.items():
        row: dict = {"task": task}
        try:
            row["rodlab"] = rodlab_task_step(task, envs=envs, steps=2 if quick else 5, repeats=repeats)
        except Exception as exc:
            row["rodlab_error"] = f"{type(exc).__name__}: {exc}"
            print(f"  {task}: rodlab skipped ({row['rodlab_error']})", flush=True)
        if peer:
            one = elastica_rod_step_cost(rods=1, obstacles=obst, planar=planar, steps=50 if quick else 200,
                                         repeats=repeats)
            many = elastica_rod_step_cost(rods=K, obstacles=obst, planar=planar, steps=20 if quick else 100,
                                          repeats=repeats)
            best = min(one["s_per_rod_step"], many["s_per_rod_step"])
            best_cpu = min(one["cpu_s_per_rod_step"], many["cpu_s_per_rod_step"])
            row["pyelastica"] = {"one_rod": one, "k_rods": many, "sim_steps_per_control_step": el_sub,
                                 "ms_per_control_step_scaled": 1e3 * best * el_sub * envs,
                                 "cpu_ms_per_control_step_scaled": 1e3 * best_cpu * el_sub * envs,
                                 "ms_per_env_control_step": 1e3 * best * el_sub}
            if "rodlab" in row:
                r = row["pyelastica"]["ms_per_control_step_scaled"] / row["rodlab"]["ms_per_control_step"]
                row["ratio_pyelastica_over_rodlab"] = r
                row["ratio_per_core"] = r / out["numba_threads"]
                row["ratio_cpu_time"] = (row["pyelastica"]["cpu_ms_per_control_step_scaled"]
                                         / row["rodlab"]["cpu_ms_per_control_step"])
        msg = f"  {task:20s}"
        if "rodlab" in row:
            msg += f" rodlab {row['rodlab']['ms_per_control_step']:9.2f} ms/ctrl-step ({envs} envs)"
        if "pyelastica" in row:
            msg += f"  PyElastica {row['pyelastica']['ms_per_control_step_scaled'] / 1e3:9.2f} s (scaled)"
        if "ratio_pyelastica_over_rodlab" in row:
            msg += (f"  ratio {row['ratio_pyelastica_over_rodlab']:.0f}x (CPU time {row['ratio_cpu_time']:.0f}x,"
                    f" per core {row['ratio_per_core']:.0f}x)")
        print(msg, flush=True)
        out["rows"].append(row)
    return out


# ------------------------------------------------------------------------------------------------
def _capsule(start, end, radius) -> dict:
    return {"type": "capsule", "start": list(map(float, start)), "end": list(map(float, end)),
            "radius": float(radius)}


def obstacle_ring(count: int, *, distance: float) -> list[dict]:
    """``count`` vertical capsules (r = 0.03) on a circle of radius ``distance`` [m] around the arm axis."""
    out = []
    for i in range(count):
        a = 2 * np.pi * i / max(1, count)
        c = (distance * np.cos(a), distance * np.sin(a))
        out.append(_capsule((c[0], c[1], 0.1), (c[0], c[1], 0.9), 0.03))
    return out


def _mesh_file(tmp: Path, subdiv: int) -> tuple[str, int]:
    import trimesh
    m = trimesh.creation.icosphere(subdivisions=subdiv, radius=0.15)
    p = tmp / f"ico{subdiv}.stl"
    m.export(p)
    return str(p), int(len(m.faces))


def part_obstacles(*, quick: bool, repeats: int) -> dict:
    """Cost against obstacle count (capsules near the arm), mesh triangles, and none / far / near."""
    B = 20 if quick else 100
    out: dict = {"envs": B, "count": [], "mesh": [], "placement": {}}
    for name, obst in (("none", []), ("far (2 m away)", obstacle_ring(8, distance=2.0)),
                       ("near (touching range)", obstacle_ring(8, distance=0.12))):
        try:
            r = time_sim(arm_doc(solver=Solver(tol=1e-3, max_iter=5), obstacles=obst or None), envs=B,
                         repeats=repeats)
        except Exception as exc:
            print(f"  contact placement {name}: skipped ({type(exc).__name__}: {exc})", flush=True)
            return out
        out["placement"][name] = r
        print(f"  8 capsules {name:24s}: {r['ms_per_step']:8.3f} ms/step (CPU {r['cpu_ms_per_step']:8.3f}, B={B}) "
              f"it {r['iters_mean']:.2f} failed envs {r['failed_envs']}", flush=True)
    for n in ([0, 4, 16] if quick else [0, 1, 4, 16, 64]):
        r = time_sim(arm_doc(solver=Solver(tol=1e-3, max_iter=5), obstacles=obstacle_ring(n, distance=0.12) or None),
                     envs=B, repeats=repeats)
        r["obstacles"] = n
        out["count"].append(r)
        print(f"  {n:3d} capsules near: {r['ms_per_step']:8.3f} ms/step (CPU {r['cpu_ms_per_step']:8.3f}, B={B}) "
              f"it {r['iters_mean']:.2f} failed envs {r['failed_envs']}", flush=True)
    with tempfile.TemporaryDirectory() as td:
        for sd in ([1, 3] if quick else [1, 2, 3, 4, 5]):
            f, tris = _mesh_file(Path(td), sd)
            mesh = {"type": "mesh", "file": f, "scale": 1.0, "position": [0.25, 0.0, 0.6],
                    "orientation": [1.0, 0.0, 0.0, 0.0]}
            try:
                r = time_sim(arm_doc(solver=Solver(tol=1e-3, max_iter=5), obstacles=[mesh]), envs=B,
                             repeats=repeats)
            except Exception as exc:
                print(f"  mesh: skipped ({type(exc).__name__}: {exc})", flush=True)
                break
            r["triangles"] = tris
            out["mesh"].append(r)
            print(f"  mesh {tris:6d} triangles: {r['ms_per_step']:8.3f} ms/step (CPU {r['cpu_ms_per_step']:8.3f}, "
                  f"B={B}) it {r['iters_mean']:.2f} failed envs {r['failed_envs']}", flush=True)
    return out


# ------------------------------------------------------------------------------------------------
def plot_tasks(plt, tasks: dict, out: Path, sfx: str) -> str | None:
    """Bars of CPU seconds per control step of all envs (rodlab measured, PyElastica per-env x envs);
    CPU time because wall time on the shared machine varies with the other users' load."""
    rows = [r for r in tasks["rows"] if "rodlab" in r]
    if not rows:
        return None
    fig, ax = plt.subplots(figsize=(8, 4))
    x = np.arange(len(rows))
    ax.bar(x - 0.2, [r["rodlab"]["cpu_ms_per_control_step"] / 1e3 for r in rows], 0.4, label="rodlab (measured)")
    if any("pyelastica" in r for r in rows):
        ax.bar(x + 0.2, [r.get("pyelastica", {}).get("cpu_ms_per_control_step_scaled", np.nan) / 1e3 for r in rows],
               0.4, label="PyElastica (per-env measured, x envs)")
        for i, r in enumerate(rows):
            if "ratio_cpu_time" in r:
                ax.text(i, r["pyelastica"]["cpu_ms_per_control_step_scaled"] / 1e3, f"{r['ratio_cpu_time']:.0f}x",
                        ha="center", va="bottom", fontsize=8)
    ax.set_yscale("log")
    ax.set_xticks(x, [r["task"] for r in rows], rotation=15, fontsize=8)
    ax.set_ylabel(f"CPU seconds per control step of {tasks['envs']} envs")
    ax.set_title("one parallel control step per task (paper settings of both simulators)", fontsize=10)
    ax.legend(fontsize=8)
    loads = [r["rodlab"]["load"][0] for r in rows]
    wall = ", ".join(f"{r['ratio_pyelastica_over_rodlab']:.0f}x" for r in rows if "ratio_pyelastica_over_rodlab" in r)
    fig.text(0.01, -0.05, f"rodlab numba threads {tasks['numba_threads']}; PyElastica 1 core; load avg "
             f"{min(loads):.1f}-{max(loads):.1f}; wall-time ratios {wall}", fontsize=7)
    return str(save_figure(fig, out, f"throughput_tasks{sfx}.png"))


def plot_obstacles(plt, obs: dict, out: Path, sfx: str) -> str | None:
    if not obs.get("count") and not obs.get("mesh"):
        return None
    fig, axs = plt.subplots(1, 2, figsize=(10, 4))
    if obs.get("count"):
        c = obs["count"]
        axs[0].plot([r["obstacles"] for r in c], [r["ms_per_step"] for r in c], "o-")
        axs[0].set_xlabel("capsule obstacles (all within contact range)")
        axs[0].set_ylabel(f"ms per step ({obs['envs']} envs)")
        axs[0].grid(True, alpha=0.3)
    if obs.get("mesh"):
        m = obs["mesh"]
        axs[1].semilogx([r["triangles"] for r in m], [r["ms_per_step"] for r in m], "o-")
        axs[1].set_xlabel("mesh triangles (one icosphere near the arm)")
        axs[1].grid(True, alpha=0.3)
    fig.suptitle("rodlab: contact cost", fontsize=10)
    return str(save_figure(fig, out, f"throughput_contact{sfx}.png"))
