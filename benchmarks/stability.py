"""Stability check of a static equilibrium (``rodlab bench stability``): the banded eigensolver of
``sim.analysis.static.static_stability`` against the dense eigensolver on the same mass-weighted static Hessian, against the
rod's node count.

The scene: a clamped column under twice its buckling load, straight (a saddle with two negative directions).
Each figure is the median of ``--repeats`` runs, the two solvers measured in the same run; both must agree on the
count of negative directions and the lowest eigenvalue. Writes ``stability.json`` into ``--out`` and prints a table.
"""
from __future__ import annotations

import dataclasses
import time

import numpy as np

from benchmarks.common import base_parser, machine_info, write_json


def _saddle(nodes: int):
    """(sim, state, ctrl) of the straight column at twice its Euler load (statically solved, it stays straight)."""
    from sim import Simulator, build_model
    from sim.analysis import solve_static
    from sim.scene import LoadSpec, RodSpec, SceneSpec, SimSpec

    R, E = 0.02, 1e7
    EI = E * np.pi * R ** 4 / 4
    lf = 1.0 - 0.5 / (nodes - 1)
    p_cr = np.pi ** 2 * EI / (4 * lf ** 2)
    spec = SceneSpec(sim=SimSpec(dt=5e-3, gravity=(0.0, 0.0, 0.0), newton_tol=1e-10, newton_max_iter=50,
                                 accept_unconverged=False),
                     rod=RodSpec(nodes=nodes, length=1.0, radius=R, density=1000.0, youngs_modulus=E,
                                 poisson_ratio=0.5, start=(0.0, 0.0, 0.0), direction=(1.0, 0.0, 0.0)))
    spec = dataclasses.replace(spec, loads=(LoadSpec(node=-1, force=(-2.0 * p_cr, 0.0, 0.0)),))
    sim = Simulator(build_model(spec), envs=1)
    state, ctrl = sim.reset(), sim.make_control()
    solve_static(spec, state, ctrl, check_stability=False)  # straight: the saddle
    return sim, state, ctrl


def _dense(sim, state, ctrl) -> tuple[int, float, float]:
    from sim.analysis import negative_threshold, static_hessian

    m = sim.model
    free = np.flatnonzero(~np.asarray(m.dof_fixed))
    d = 1.0 / np.sqrt(np.asarray(m.dof_mass)[free])
    S = static_hessian(sim, state, ctrl, 0)[np.ix_(free, free)] * d[:, None] * d[None, :]
    w = np.linalg.eigh(S)[0]
    thr = negative_threshold(m, float(np.abs(np.diag(S)).max()))
    return int(np.count_nonzero(w < -thr)), float(w[0]), float(np.abs(w).max())


def bench(nodes: int, repeats: int) -> dict:
    from sim.analysis import static_stability

    sim, state, ctrl = _saddle(nodes)
    static_stability(sim, state, ctrl, 0)  # warm (the Hessian kernel's compile)
    tb, td = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        neg, lam, _ = static_stability(sim, state, ctrl, 0)
        tb.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        neg_d, lam_d, scale = _dense(sim, state, ctrl)
        td.append(time.perf_counter() - t0)
    if neg != neg_d or abs(lam - lam_d) > 1e-9 * scale:  # rounding: relative to the spectrum's scale
        raise SystemExit(f"banded and dense disagree at {nodes} nodes: {neg} vs {neg_d}, {lam} vs {lam_d}")
    return {"nodes": nodes, "dofs": int(state.dof[0].size), "negative_directions": neg, "lowest_eigenvalue": lam,
            "banded_s_median": float(np.median(tb)), "dense_s_median": float(np.median(td)),
            "dense_over_banded": float(np.median(td) / np.median(tb))}


def main(argv: list[str] | None = None) -> int:
    p = base_parser("rodlab bench stability", __doc__.split("\n")[0])
    p.add_argument("--nodes", default="101,301,1001", help="node counts (default 101,301,1001)")
    args = p.parse_args(argv)
    nodes = [21, 51] if args.quick else [int(v) for v in args.nodes.split(",")]
    reps = args.repeats or (1 if args.quick else 3)
    out: dict = {"machine": machine_info(), "rows": []}
    print("nodes  DOFs   negative  banded [s]  dense [s]  dense/banded")
    for n in nodes:
        row = bench(n, reps)
        out["rows"].append(row)
        print(f"{n:5d} {row['dofs']:5d} {row['negative_directions']:9d} {row['banded_s_median']:11.4f} "
              f"{row['dense_s_median']:10.4f} {row['dense_over_banded']:12.1f}")
    out["machine"]["loadavg_at_end"] = machine_info()["loadavg_at_start"]
    path = write_json(args.out, "stability.json", out)
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
