"""Rod–rod contact (docs/physics.md §4.8): a rod dropped across another rod lying on a floor comes to rest on it,
with no interpenetration, in a steady state whose contact force carries the weight the floor does not (the
StepStats contact rows of the edge pairs and the floor balance each rod's weight); with ``rod_contact = false`` the
same rod falls through to the floor."""
from __future__ import annotations

import functools

import numpy as np
import pytest

from benchmarks.throughput_pairs import two_rod_doc
from sim import Simulator, build_model
from sim.geometry.distance import closest_seg_seg
from sim.scene.spec import parse_scene

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


@functools.lru_cache(maxsize=None)  # one run per setting for the tests of this file (they only read it)
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


def test_contact_rows_of_the_edge_pairs_balance_the_weights():
    model, st, _, stats = _drop(True)
    k = int(stats.contact_count[0])
    edge, obstacle, partner = (a[0, :k] for a in (stats.contact_edge, stats.contact_obstacle,
                                                  stats.contact_partner_edge))
    normal, fn, fr = stats.contact_normal[0, :k], stats.contact_normal_force[0, :k], stats.contact_friction_force[0, :k]
    point, other, gap = stats.contact_rod_point[0, :k], stats.contact_obstacle_point[0, :k], stats.contact_gap[0, :k]
    pair = obstacle == -1
    assert np.all(partner[~pair] == -1) and np.all(obstacle[~pair] == 0)  # the floor's rows
    rows = np.flatnonzero(pair)
    assert rows.size >= 2 and rows.size % 2 == 0 and rows[0] == k - rows.size  # after the obstacle rows, two per pair
    off = model.rod_node_offsets
    for a, b in rows.reshape(-1, 2):
        assert (edge[a], partner[a]) == (partner[b], edge[b])        # the same pair seen from each edge
        assert off[0] <= min(edge[a], edge[b]) < off[1] - 1 and off[1] <= max(edge[a], edge[b]) < off[2] - 1
        np.testing.assert_allclose(normal[a], -normal[b], atol=1e-15)
        np.testing.assert_allclose(fr[a], -fr[b], atol=1e-15)
        # the pair's net normal force (its terms: a crossing near a node is shared with the neighbouring pairs)
        assert fn[a] == fn[b] > 0.0 and abs(gap[a]) < 1e-3
        np.testing.assert_allclose(np.linalg.norm(normal[a]), 1.0, rtol=1e-12)
        d = point[a] - point[b]                                       # centre-line points, 2r + gap apart
        assert np.linalg.norm(d) == pytest.approx(gap[a] + 2 * R, abs=1e-12)
        np.testing.assert_allclose(other[a], point[b] + R * d / np.linalg.norm(d), atol=1e-12)  # partner's surface
    # one contact: the pairs' net normal forces carry the top rod's weight, not a multiple of it
    # at rest, each rod's weight is carried by its rows: the floor's (node rows) and the other rod's (edge rows)
    force = normal * fn[:, None] + fr
    node_mass = np.asarray(model.dof_mass).reshape(-1, 4)[:, 0]
    for lo, hi in ((off[0], off[1]), (off[1], off[2])):
        mine = np.where(pair, (edge >= lo) & (edge < hi - 1), (edge >= lo) & (edge < hi))
        assert force[mine, 2].sum() == pytest.approx(9.81 * node_mass[lo:hi].sum(), rel=1e-6)
    top = (edge >= off[1]) & pair
    assert force[top, 2].sum() > 0.2 * 9.81 * node_mass[off[1]:off[2]].sum()  # the bottom rod carries a good part
    # a row is its pair's share of the crossing; their sum has the crossing's direction: up on the top rod
    assert np.linalg.norm(force[top, :2].sum(axis=0)) < 1e-3 * force[top, 2].sum()


def test_without_edge_pairs_no_pair_rows():
    _, _, _, stats = _drop(False)
    k = int(stats.contact_count[0])
    assert k > 0 and np.all(stats.contact_obstacle[0, :k] == 0) and np.all(stats.contact_partner_edge[0, :k] == -1)
