"""Rod–rod contact (docs/physics.md §4.8): a rod dropped across another rod lying on a floor comes to rest on it,
with no interpenetration, in a steady state whose contact force carries the weight the floor does not; with
``rod_contact = false`` the same rod falls through to the floor."""
from __future__ import annotations

import numpy as np
import pytest

from benchmarks.throughput_pairs import two_rod_doc
from sim import Simulator, build_model
from sim.geometry_distance import closest_seg_seg
from sim.scene import parse_scene

R = 0.01


def _gap_between_rods(x, offsets):
    """Smallest gap [m] between an edge of the first rod and an edge of the second."""
    a0, a1, b1 = int(offsets[0]), int(offsets[1]), int(offsets[2])
    best = np.inf
    for i in range(a0, a1 - 1):
        for j in range(a1, b1 - 1):
            s, t = closest_seg_seg(tuple(x[i]), tuple(x[i + 1]), tuple(x[j]), tuple(x[j + 1]))
            d = np.linalg.norm((x[i] + s * (x[i + 1] - x[i])) - (x[j] + t * (x[j + 1] - x[j])))
            best = min(best, d - 2 * R)
    return best


def _drop(rod_contact: bool, steps: int = 150):
    doc = two_rod_doc(apart=False)
    doc["contact"]["rod_contact"] = rod_contact
    model = build_model(parse_scene(doc))
    sim = Simulator(model, envs=1)
    st = sim.reset()
    ctrl = sim.make_control()
    offsets = model.rod_node_offsets
    gaps = []
    for k in range(steps):
        stats = sim.step(st, ctrl)
        assert not stats.failed.any() and np.isfinite(st.node_pos).all()
        if k % 10 == 9:
            gaps.append(_gap_between_rods(st.node_pos[0], offsets))
    return model, st, np.array(gaps), stats


def test_rod_dropped_across_another_rod_rests_on_it():
    model, st, gaps, stats = _drop(True)
    x = st.node_pos[0]
    off = model.rod_node_offsets
    top = x[off[1]:off[2]]
    mid = top[len(top) // 2]
    assert gaps.min() > -1e-3                        # never deeper than δ (1 mm); radii are 10 mm
    assert gaps[-1] < 1e-3                           # and touching at the end
    # at rest on the bottom rod: the top rod's middle sits one diameter above the bottom rod's centre line
    bottom_mid_z = x[off[0]:off[1]][(off[1] - off[0]) // 2, 2]
    assert mid[2] == pytest.approx(bottom_mid_z + 2 * R, abs=1e-3)
    assert np.abs(st.node_vel[0]).max() < 2e-2      # settled
    assert stats.energy_contact[0] > 0.0


def test_rod_falls_through_without_rod_contact():
    model, st, gaps, _ = _drop(False)
    assert gaps.min() < -R                            # the centre lines came closer than one radius
