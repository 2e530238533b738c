"""PyElastica (explicit Cosserat rod) versions of the benchmark scenes: a static and a dynamic cantilever and
the paper's arm, for the accuracy and throughput comparisons.

The rods themselves (settings, damping, clamp, frame mapping, actuation) are
:mod:`policies.elastica.rods`, shared with the task back-end and documented there and in docs/tasks.md §1.6;
PyElastica is an optional peer (``pip install rodlab[peers]``)."""
from __future__ import annotations

import numpy as np

# The arm itself lives in policies/elastica/rods.py (shared with the task backend); re-exported here.
from policies.elastica.rods import (  # noqa: F401  (ImportError without PyElastica says how to install it)
    CylinderSpec,
    ElasticaRods,
    RodSpec,
    elastica_version,
    stable_dt_estimate,
)

__all__ = ["RodSpec", "CylinderSpec", "ElasticaRods", "elastica_version", "stable_dt_estimate", "run_static",
           "run_dynamic", "run_arm"]


# ------------------------------------------------------------------------------------------------
# Runners of the accuracy scenes (benchmarks.scenes).  Each returns a dict with the wall time of the
# whole run "wall_s" [s], the simulated time "sim_s" [s], "stable" (no NaN / blow-up) and the sampled
# output.  Setup (rod construction, finalize, numba warm-up) is not timed.
# ------------------------------------------------------------------------------------------------
import time as _time  # noqa: E402


def _blown(rods: ElasticaRods, scale: float) -> bool:
    """NaN, a node far away, or an edge stretched/compressed by more than 50 % (explicit blow-up)."""
    p = rods.node_pos()
    if (not np.all(np.isfinite(p))) or float(np.max(np.abs(p))) > 100.0 * scale:
        return True
    l0 = rods.spec.length / (rods.spec.n_nodes - 1)
    strain = np.linalg.norm(np.diff(p, axis=1), axis=-1) / l0 - 1.0
    return bool(np.max(np.abs(strain)) > 0.5)


def run_static(scene, *, n_nodes: int, dt: float) -> dict:
    """Heavy cantilever (scenes.StaticCantilever) until ``scene.t_end``; tip (x, z) at the end."""
    spec = RodSpec(n_nodes=n_nodes, length=scene.length, radius=scene.radius, density=scene.density,
                   youngs=scene.youngs, poisson=scene.poisson, direction=(1.0, 0.0, 0.0),
                   normal=(0.0, 0.0, 1.0), gravity=(0.0, 0.0, -scene.g),
                   damping=("uniform", scene.damping), swap_xy=False)
    rods = ElasticaRods(spec, dt=dt)
    rods.step(1)
    n = int(round(scene.t_end / dt))
    chunk = max(1, int(round(0.1 / dt)))
    t0, c0 = _time.perf_counter(), _time.process_time()
    done, stable = 1, True
    while done < n:
        k = min(chunk, n - done)
        rods.step(k)
        done += k
        if _blown(rods, scene.length):
            stable = False
            break
    wall, cpu = _time.perf_counter() - t0, _time.process_time() - c0
    tip = rods.node_pos()[0, -1]
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": done * dt, "stable": stable, "tip": [tip[0], tip[2]]}


def run_dynamic(scene, *, n_nodes: int, dt: float, sample_dt: float = 0.01) -> dict:
    """Euler-Bernoulli cantilever (scenes.DynamicCantilever); tip z sampled every ``sample_dt``."""
    spec = RodSpec(n_nodes=n_nodes, length=scene.length, radius=scene.radius, density=scene.density,
                   youngs=scene.youngs, poisson=scene.poisson, direction=(1.0, 0.0, 0.0),
                   normal=(0.0, 0.0, 1.0), gravity=(0.0, 0.0, 0.0), damping=None, swap_xy=False)
    rods = ElasticaRods(spec, dt=dt)
    x = np.linspace(0.0, scene.length, n_nodes)
    v = np.zeros((n_nodes, 3))
    v[:, 2] = scene.beam.initial_velocity(x)
    v[0] = 0.0
    rods.set_node_vel(v)
    per = max(1, int(round(sample_dt / dt)))
    n_samples = int(np.floor(scene.t_end / (per * dt) + 1e-9))
    ts, zs = [0.0], [0.0]
    stable = True
    t0, c0 = _time.perf_counter(), _time.process_time()
    for k in range(n_samples):
        rods.step(per)
        ts.append(rods.time)
        zs.append(float(rods.node_pos()[0, -1, 2]))
        if _blown(rods, scene.length):
            stable = False
            break
    wall, cpu = _time.perf_counter() - t0, _time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": rods.time, "stable": stable, "t": ts, "z": zs}


def segment_distances(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances [m] between the segments of polyline ``p`` (N, 3) and the segment ``a``-``b``."""
    p0, p1 = p[:-1], p[1:]
    out = np.empty(len(p0))
    for k in range(len(p0)):  # small N: clamped closest points, sampled refinement for robustness
        u = p1[k] - p0[k]
        v = b - a
        w = p0[k] - a
        A, B, C, D, E = u @ u, u @ v, v @ v, u @ w, v @ w
        den = A * C - B * B
        s = np.clip((B * E - C * D) / den, 0, 1) if den > 1e-14 else 0.0
        t = np.clip((B * s + E) / C, 0, 1)
        s = np.clip((B * t - D) / A, 0, 1)
        out[k] = np.linalg.norm(p0[k] + s * u - (a + t * v))
    return out


def run_arm(scene, *, n_nodes: int, dt: float, sample_dt: float = 0.05) -> dict:
    """Paper arm with the curvature command of scenes.ArmCommand / ArmPress (set before every
    step); tip position (K, 3) [m] sampled every ``sample_dt``; with ArmPress also the cylinder and
    the max penetration [m] (rod radius + cylinder radius - centreline distance) over the samples."""
    spec = RodSpec(n_nodes=n_nodes, length=scene.length, radius=scene.radius, density=scene.density,
                   youngs=scene.youngs, poisson=scene.poisson, gravity=(0.0, 0.0, -scene.g),
                   damping=("uniform", scene.damping))
    cyl = getattr(scene, "cyl_ends", None)
    obst = (CylinderSpec(cyl[0], cyl[1], scene.cyl_radius),) if cyl else ()
    rods = ElasticaRods(spec, dt=dt, obstacles=obst)
    pen = 0.0
    per = max(1, int(round(sample_dt / dt)))
    n_samples = int(np.floor(scene.t_end / (per * dt) + 1e-9))
    ts, tips = [0.0], [rods.node_pos()[0, -1].tolist()]
    stable = True
    t0, c0 = _time.perf_counter(), _time.process_time()
    step = 0
    for k in range(n_samples):
        for _ in range(per):
            step += 1
            rods.set_natural_curvature(scene.integrated_kappa(step * dt, n_nodes))
            rods.step(1)
        ts.append(rods.time)
        pos = rods.node_pos()[0]
        tips.append(pos[-1].tolist())
        if cyl:
            d = segment_distances(pos, np.asarray(cyl[0], float), np.asarray(cyl[1], float))
            pen = max(pen, float(scene.radius + scene.cyl_radius - d.min()))
        if _blown(rods, scene.length):
            stable = False
            break
    wall, cpu = _time.perf_counter() - t0, _time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": rods.time, "stable": stable, "t": ts, "tip": tips,
            "max_penetration": max(0.0, pen)}
