"""StepStats contact rows of edge pairs when more pairs touch than the report lists: a rod resting across 40 fixed rods
(40 crossings, two rows per pair in touch: more than the first capacity); the dropped rows are counted, the report
grows, and once it has grown the rows on the resting rod carry its whole weight and the rods' forces on each other
cancel (with rows capped, the listed forces were a part of the weight)."""
from __future__ import annotations

import numpy as np

from sim import Simulator, build_model, parse_scene
from sim.contact.world import PAIR_REPORT_CAPACITY

R = 0.01
SUPPORTS = 40  # fixed rods across the resting rod, 7.5 mm apart: one crossing each


def _scene() -> dict:
    rod = {"radius": R, "density": 1000.0, "youngs_modulus": 1e8, "poisson_ratio": 0.5, "clamp": "none"}
    xs = np.linspace(-0.146, 0.146, SUPPORTS)
    rods = [dict(rod, name=f"s{i}", nodes=5, length=0.1, start=[float(x), -0.05, 0.0], direction=[0.0, 1.0, 0.0])
            for i, x in enumerate(xs)]
    rods.append(dict(rod, name="top", nodes=41, length=0.3, start=[-0.15, 0.0, 2 * R + 5e-4],
                     direction=[1.0, 0.0, 0.0]))
    return {
        "sim": {"dt": 0.005, "gravity": [0.0, 0.0, -9.81], "damping": 5.0, "newton_tol": 1e-8, "newton_max_iter": 30,
                "accept_unconverged": False},
        "rod": rods,
        "fix": [{"rod": f"s{i}", "nodes": list(range(5))} for i in range(SUPPORTS)],
        "contact": {"stiffness": 1e5, "delta": 1e-3, "friction": 0.0},
    }


def test_pair_rows_beyond_the_capacity_are_counted_then_listed():
    model = build_model(parse_scene(_scene()))
    sim = Simulator(model, envs=1)
    st, ctrl = sim.reset(), sim.make_control()
    top = model.rod_slices()["top"]
    W = float(model.node_mass[top].sum() * 9.81)
    dropped, capacity = [], []
    for _ in range(300):
        s = sim.step(st, ctrl)
        assert s.converged.all() and not s.failed.any()
        dropped.append(int(s.contact_dropped[0]))
        capacity.append(s.contact_edge.shape[1])
    assert max(dropped) > 0 and capacity[0] <= 2 * PAIR_REPORT_CAPACITY  # more rows than the report listed at first
    assert dropped[-1] == 0 and capacity[-1] > capacity[0]  # it grew: every row listed
    k = int(s.contact_count[0])
    edge = s.contact_edge[0, :k]
    force = s.contact_normal_force[0, :k, None] * s.contact_normal[0, :k] + s.contact_friction_force[0, :k]
    on_top = (edge >= top.start) & (edge < top.stop - 1)
    assert on_top.sum() >= SUPPORTS  # every crossing carries it
    np.testing.assert_allclose(force[on_top].sum(axis=0), [0.0, 0.0, W], atol=1e-3 * W)  # its whole weight
    np.testing.assert_allclose(s.contact_force[0], 0.0, atol=1e-6 * W)  # the rods push each other: no net force
