"""One crossing, one contact (docs/physics.md §4.8): a 0.4 m rod resting across two fixed beams, for several places
of the crossings along the edges of both (on nodes of both, on nodes of one, halfway and a quarter along edges).
Each crossing carries half the rod's weight, so its rest gap is the IMC law's gap for that force whatever the
placement; the script prints the rest gaps against it and writes them as JSON.

    .venv/bin/python -m benchmarks.rod_crossing --json docs/bench/pairs/rod_crossing.json
"""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np
from scipy.optimize import brentq

from sim import Simulator, build_model
from sim.contact import imc_energy
from sim.scene import parse_scene
from sim.support.atomicio import write_text

R = 0.01            # [m] radius of the beams and the rod
K, DELTA = 1e5, 1e-3
BEAM_EDGE = 0.05    # [m] the beams' edge length (21 nodes over 1 m)
TOP_LENGTH = 0.4    # [m]
# (shift of the crossings along the beams [m], nodes of the rod): 9 nodes put the crossings on the rod's nodes,
# 11 halfway along its edges; a shift of 0 puts them on the beams' nodes
PLACEMENTS = ((0.0, 9), (0.0, 11), (0.5 * BEAM_EDGE, 9), (0.5 * BEAM_EDGE, 11), (0.25 * BEAM_EDGE, 9),
              (0.1 * BEAM_EDGE, 11))


def beams_doc(shift_x: float, top_nodes: int) -> dict:
    """Two beams along x (fixed at both ends) at y = ±0.1 m and a 0.4 m rod along y across them, dropped from
    0.2 mm above."""
    beam = {"nodes": 21, "length": 1.0, "radius": R, "density": 1000.0, "youngs_modulus": 1e9, "poisson_ratio": 0.5,
            "clamp": "none", "direction": [1.0, 0.0, 0.0]}
    top = {"name": "top", "nodes": top_nodes, "length": TOP_LENGTH, "radius": R, "density": 1000.0,
           "youngs_modulus": 1e9, "poisson_ratio": 0.5, "clamp": "none", "start": [shift_x, -0.2, 2 * R + 2e-4],
           "direction": [0.0, 1.0, 0.0]}
    return {"sim": {"dt": 0.01, "gravity": [0.0, 0.0, -9.81], "damping": 5.0, "newton_tol": 1e-8,
                    "newton_max_iter": 30, "accept_unconverged": True},
            "rod": [dict(beam, name="b1", start=[-0.5, -0.1, 0.0]), dict(beam, name="b2", start=[-0.5, 0.1, 0.0]),
                    top],
            "fix": [{"rod": "b1", "nodes": [0, 1, 19, 20]}, {"rod": "b2", "nodes": [0, 1, 19, 20]}],
            "contact": {"stiffness": K, "delta": DELTA}}


def rod_weight() -> float:
    """[N] the resting rod's weight."""
    return TOP_LENGTH * np.pi * R ** 2 * 1000.0 * 9.81


def law_gap() -> float:
    """[m] the IMC law's gap for half the rod's weight (one crossing's load)."""
    return float(brentq(lambda g: -imc_energy(g, K, DELTA)[1] - rod_weight() / 2, -DELTA, DELTA, xtol=1e-15))


def rest(shift_x: float, top_nodes: int, steps: int = 300) -> dict:
    """The rod at rest after ``steps`` steps: the two crossings' gaps [m] (the smallest gap of the pairs listed at
    each: the rods' distance there), the upward force the beams carry [N], the largest speed [m/s], whether a step
    failed."""
    model = build_model(parse_scene(beams_doc(shift_x, top_nodes)))
    sim = Simulator(model, envs=1)
    st = sim.reset()
    ctrl = sim.make_control()
    failed = False
    for _ in range(steps):
        stats = sim.step(st, ctrl)
        failed |= bool(stats.failed.any()) or not np.isfinite(st.node_pos).all()
    n = int(stats.contact_count[0])
    mine = stats.contact_edge[0, :n] >= model.rod_node_offsets[2]
    fn, normal = stats.contact_normal_force[0, :n][mine], stats.contact_normal[0, :n][mine]
    y = stats.contact_rod_point[0, :n][mine][:, 1]
    gaps = [float(stats.contact_gap[0, :n][mine][side].min()) for side in (y < 0, y > 0)]
    return {"shift_x": shift_x, "top_nodes": top_nodes, "gaps": gaps, "up_force": float((fn * normal[:, 2]).sum()),
            "max_speed": float(np.abs(st.node_vel).max()), "failed": failed}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.rod_crossing", description=__doc__.split("\n\n")[0])
    ap.add_argument("--json", help="write the figures to this file")
    a = ap.parse_args(argv)
    expected = law_gap()
    rows = [rest(sx, n) for sx, n in PLACEMENTS]
    print(f"IMC law's gap for half the rod's weight ({rod_weight() / 2:.4f} N): {expected * 1e6:.3f} um")
    for r in rows:
        print(f"  crossings {r['shift_x'] / BEAM_EDGE:4.2f} of a beam edge along, rod of {r['top_nodes']:2d} nodes: "
              f"gaps {r['gaps'][0] * 1e6:.3f} / {r['gaps'][1] * 1e6:.3f} um, carried {r['up_force'] / rod_weight():.6f}"
              f" of the weight")
    worst = max(abs(g - expected) / expected for r in rows for g in r["gaps"])
    print(f"largest relative difference from the law's gap: {worst:.2e}")
    if a.json:
        write_text(a.json, json.dumps({"command": "python -m benchmarks.rod_crossing --json " + a.json,
                                              "law_gap_m": expected, "placements": rows,
                                              "largest_relative_difference": worst}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
