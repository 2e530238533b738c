"""`rodlab fit` across simulators: PyElastica (the Cosserat model with shear of the project's elastica back-end,
policies/elastica) makes the measurements, rodlab fits its rod to them, and the fitted rod reproduces a held-out part
of the motion (docs/physics.md §3.9, Calibration).

Cases, on the paper's arm (N = 21, L = 1 m, r = 5 cm, ρ = 1000 kg/m³, E = 1e7 Pa, vertical, gravity −9.8 z):

* ``release``: bent by the natural curvature κ̄1 = 0.04 at every interior node for 1.5 s, then released (κ̄ = 0):
  it swings back and oscillates; fitted: Young's modulus and damping.
* ``actuated``: driven for 4 s by commanded curvature at nodes 5, 10 and 15 (two sines per node, both bending
  directions, held between rows at 30 Hz); fitted: Young's modulus, damping and the three actuation gains.

Measurements: the nodes at s = 0.2, 0.4, … 1.0 m at 30 Hz for 4 s; the last quarter held out. PyElastica: uniform
damping γ = 1/s (velocity and angular velocity decay), position Verlet at dt = 2e-4 s, clamp ``OneEndFixedBC``.
rodlab: backward Euler at dt = 1/120 s with converged Newton steps, first-edge clamp, started at E = 2e7 Pa,
damping 0.5/s, gains 1. The two models differ (shear, the clamp, the damping law, backward Euler's numerical
damping), so the fitted values are those of the rodlab rod that moves most like the PyElastica one, not PyElastica's.

    .venv/bin/python -m benchmarks.fit_elastica --out docs/bench/fit_elastica.json
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.common import machine_info, write_json
from sim.analysis import Commands, Measurements, command_schedule, fit
from sim.scene import RodSpec, SceneSpec, SimSpec

COMMAND = "python -m benchmarks.fit_elastica"
N, LENGTH, RADIUS, DENSITY, YOUNGS, GAMMA = 21, 1.0, 0.05, 1000.0, 1e7, 1.0
HZ, MARKERS, HOLDOUT = 30.0, (4, 8, 12, 16, 20), 0.25
RELEASE_AT, KAPPA = 1.5, 0.04
ACTUATED = {5: ((0.06, 0.5, 0.0), (0.04, 0.8, 1.0)), 10: ((0.05, 0.7, 2.0), (0.03, 0.4, 0.5)),
            15: ((0.04, 0.9, 1.0), (0.05, 0.6, 2.5))}  # node -> per direction (amplitude, frequency [Hz], phase)
GOAL = 0.01  # held-out RMS ≤ 1 % of the rod's length
SECONDS = 4.0  # measured motion per case


def commands(case: str, seconds: float) -> Commands:
    """The commanded natural curvature of ``case`` as rows (time, node, κ1, κ2, twist), one per node and time."""
    if case == "release":
        nodes = np.arange(1, N - 1)
        return Commands(np.tile([0.0, RELEASE_AT], nodes.size), np.repeat(nodes, 2),
                          np.tile([[KAPPA, 0.0], [0.0, 0.0]], (nodes.size, 1)), np.zeros(2 * nodes.size))
    t = np.arange(0.0, seconds - 1e-9, 1.0 / HZ)
    rows_t, rows_n, rows_k = [], [], []
    for node, waves in ACTUATED.items():
        k = np.stack([a * np.sin(2.0 * np.pi * f * t + p) for a, f, p in waves], axis=1)
        rows_t.append(t)
        rows_n.append(np.full(t.size, node))
        rows_k.append(k)
    return Commands(np.concatenate(rows_t), np.concatenate(rows_n), np.concatenate(rows_k),
                      np.zeros(t.size * len(ACTUATED)))


def elastica_measurements(cmds: Commands, seconds: float) -> tuple[Measurements, float]:
    """The markers of the PyElastica arm driven by ``cmds`` (each row held from its time), and its wall time [s]."""
    from policies.elastica.rods import ElasticaRods
    from policies.elastica.rods import RodSpec as ElasticaRod

    rods = ElasticaRods(ElasticaRod(n_nodes=N, length=LENGTH, radius=RADIUS, density=DENSITY, youngs=YOUNGS,
                                    damping=("uniform", GAMMA)), dt=2e-4)
    t = np.arange(0.0, seconds + 1e-9, 1.0 / HZ)
    kap, _ = command_schedule(cmds, t.size, 1.0 / HZ, N)  # the rows in force at each sample time
    steps = int(round(1.0 / (HZ * rods.dt)))
    pos = np.empty((t.size, len(MARKERS), 3))
    t0 = time.perf_counter()
    for k in range(t.size):
        pos[k] = rods.node_pos()[0, list(MARKERS)]
        rods.set_natural_curvature(kap[k])
        rods.step(steps)
    wall = time.perf_counter() - t0
    if rods.has_nan():
        raise RuntimeError("the PyElastica arm blew up")
    s = np.asarray(MARKERS, float) * LENGTH / (N - 1)
    meas = Measurements(np.repeat(t, len(MARKERS)), np.tile(s, t.size), np.zeros(pos.shape[0] * pos.shape[1], int),
                          pos.reshape(-1, 3))
    return meas, wall


def rodlab_scene(dt: float = 1.0 / 120.0) -> SceneSpec:
    """The rodlab arm the fit starts from (E twice the truth, damping 0.5/s)."""
    return SceneSpec(sim=SimSpec(dt=dt, gravity=(0.0, 0.0, -9.8), newton_tol=1e-8, newton_max_iter=30,
                                 accept_unconverged=False, damping=0.5),
                     rod=RodSpec(nodes=N, length=LENGTH, radius=RADIUS, density=DENSITY, youngs_modulus=2.0 * YOUNGS,
                                 poisson_ratio=0.5, start=(0.0, 0.0, 0.0), direction=(0.0, 0.0, 1.0)))


def run_case(case: str, *, seconds: float = SECONDS, dt: float = 1.0 / 120.0) -> dict[str, Any]:
    """Measure ``case`` with PyElastica, fit rodlab's arm to the first 75 % and return the figures."""
    cmds = commands(case, seconds)
    meas, el_wall = elastica_measurements(cmds, seconds)
    params = ["youngs_modulus", "damping"] + (["actuation_gain"] if case == "actuated" else [])
    t0 = time.perf_counter()
    res = fit(rodlab_scene(dt), meas, params, cmds=cmds, holdout=HOLDOUT)
    wall = time.perf_counter() - t0
    tip = meas.pos.reshape(-1, len(MARKERS), 3)[:, -1]
    return {"case": case, "seconds_of_motion": seconds, "dt": dt, "params": res.params,
            "stderr": {k: float(v) for k, v in res.stderr.items()}, "rms_m": res.rms_m,
            "holdout_rms_m": res.holdout_rms_m, "holdout_rms_of_length": res.holdout_rms_m / LENGTH,
            "tip_travel_m": float(np.linalg.norm(tip.max(axis=0) - tip.min(axis=0))),
            "youngs_error": res.params["youngs_modulus"] / YOUNGS - 1.0, "iterations": res.iterations,
            "fit_seconds": wall, "elastica_seconds": el_wall, "within_goal": res.holdout_rms_m <= GOAL * LENGTH,
            "unconverged_steps": res.unconverged_steps}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog=COMMAND, description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, help="write the figures to this JSON file")
    ap.add_argument("--cases", default="release,actuated", help="comma-separated subset of release, actuated")
    ap.add_argument("--seconds", type=float, default=SECONDS, help="seconds of measured motion per case")
    a = ap.parse_args(argv)
    if not (math.isfinite(a.seconds) and 1.0 <= a.seconds <= 60.0):
        ap.error(f"--seconds must be between 1 and 60 (got {a.seconds:g})")
    cases = a.cases.split(",")
    bad = [c for c in cases if c not in ("release", "actuated")]
    if bad:
        ap.error(f"unknown case {bad[0]!r}; known: release, actuated")
    info = machine_info()
    rows = []
    for case in cases:
        r = run_case(case, seconds=a.seconds)
        rows.append(r)
        fitted = ", ".join(f"{k} = {v:.4g} ± {r['stderr'][k]:.2g}" for k, v in r["params"].items())
        print(f"{case}: {fitted}; RMS {r['rms_m'] * 1e3:.2f} mm, held-out RMS {r['holdout_rms_m'] * 1e3:.2f} mm "
              f"({100 * r['holdout_rms_of_length']:.2f} % of L; goal ≤ {100 * GOAL:g} %), tip travel "
              f"{r['tip_travel_m']:.2f} m, E {100 * r['youngs_error']:+.1f} % from PyElastica's; fit "
              f"{r['fit_seconds']:.1f} s ({r['iterations']} evaluations), PyElastica {r['elastica_seconds']:.1f} s")
    if a.out:
        cmd = (COMMAND + (f" --cases {a.cases}" if a.cases != "release,actuated" else "")
               + (f" --seconds {a.seconds:g}" if a.seconds != SECONDS else "") + f" --out {a.out}")
        write_json(a.out.parent, a.out.name, {"command": cmd, "machine": info, "rows": rows})
    return 0 if all(r["within_goal"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
