"""Self-contact (docs/physics.md §4.8): a clamped rod commanded to curl 1.25 turns, tighter than a closed loop,
touches itself and comes to rest on itself: it neither passes through nor fails, in 3-D and in the plane. The same
command without ``self_contact`` passes through (what the contact prevents)."""
from __future__ import annotations

import tomllib

import numpy as np
import pytest

from sim import Simulator, build_model, parse_scene
from sim.contact.edge_pairs import model_pairs
from sim.geometry.distance import closest_seg_seg

RADIUS = 0.02
DELTA = 2e-3

SCENE = """
[sim]
dt = 0.01
gravity = [0.0, 0.0, 0.0]
damping = 5.0
newton_tol = 1e-6
newton_max_iter = 30
accept_unconverged = false
mode = "{mode}"
[rod]
nodes = 41
length = 1.0
radius = {radius}
density = 1000.0
youngs_modulus = 1e6
poisson_ratio = 0.5
start = [0.0, 0.0, 0.0]
direction = [1.0, 0.0, 0.0]
[contact]
stiffness = 1e5
delta = {delta}
self_contact = {self_contact}
"""


def _model(mode, self_contact):
    text = SCENE.format(mode=mode, radius=RADIUS, delta=DELTA, self_contact="true" if self_contact else "false")
    return build_model(parse_scene(tomllib.loads(text)))


def min_pair_gap(model, x, pairs):
    """Smallest gap [m] over the edge pairs that may touch (the pairs of the self-contact scene)."""
    best = np.inf
    for i, j in pairs:
        s, t = closest_seg_seg(tuple(x[i]), tuple(x[i + 1]), tuple(x[j]), tuple(x[j + 1]))
        d = np.linalg.norm((x[i] + s * (x[i + 1] - x[i])) - (x[j] + t * (x[j + 1] - x[j])))
        best = min(best, d - 2 * RADIUS)
    return best


def curl(mode, self_contact, steps=450):
    m = _model(mode, self_contact)
    pairs = model_pairs(_model(mode, True))
    sim = Simulator(m, envs=1)
    st = sim.reset()
    ctrl = sim.make_control()
    N = m.node_count
    total = 2 * np.pi * 1.25  # integrated curvature over the rod: a loop and a quarter
    gaps, failed, converged = [], False, True
    for k in range(steps):
        ctrl.kappa_bar[:, 1:-1, 0] = min(1.0, (k + 1) / 150) * total / (N - 2)
        stats = sim.step(st, ctrl)
        failed |= bool(stats.failed.any())
        converged &= bool(stats.converged.all())
        if k % 25 == 24:
            gaps.append(min_pair_gap(m, st.node_pos[0], pairs))
        assert np.isfinite(st.node_pos).all()
    return np.array(gaps), failed, converged, stats


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_curled_rod_touches_itself_and_does_not_pass_through(mode):
    gaps, failed, converged, stats = curl(mode, True)
    assert not failed and converged
    assert gaps.min() > -2 * DELTA            # never deeper than the contact's smoothing scale
    assert gaps[-1] < DELTA                   # ... and it does touch: the loop is closed on itself
    assert stats.energy_contact[0] > 0.0
    assert stats.max_penetration[0] == pytest.approx(max(0.0, -gaps[-1]), abs=1e-12)  # the deepest pair's, reported


def test_curled_rod_passes_through_itself_without_self_contact():
    gaps, failed, _, _ = curl("3d", False)
    assert gaps.min() < -RADIUS               # the centre lines came closer than one radius: interpenetration


def test_batched_envs_match_envs_alone_bit_for_bit():
    """Envs share a thread's work space (candidate list, coupling list): a batch gives each env's bits alone."""
    m = _model("3d", True)
    turns = np.array([0.6, 1.25, 1.1])

    def run(idx):
        sim = Simulator(m, envs=len(idx))
        st = sim.reset()
        ctrl = sim.make_control()
        for k in range(300):
            ctrl.kappa_bar[:, 1:-1, 0] = (min(1.0, (k + 1) / 150) * 2 * np.pi * turns[idx] / (m.node_count - 2))[:, None]
            sim.step(st, ctrl)
        return st.node_pos

    together = run(np.arange(3))
    for e in range(3):
        np.testing.assert_array_equal(together[e], run(np.array([e]))[0])


def test_pairs_that_do_not_touch_cost_no_newton_iteration():
    """A long rod hanging as a cantilever, self_contact on: as it swings, pairs a few edges apart enter the
    broad-phase margin every step (refresh over the motion taken) but none comes within δ, so none calls for a
    second Newton solve: the same iterations and, to the solver tolerance, the same motion as with self_contact off."""
    from benchmarks.throughput_pairs import _hanging_doc

    runs = {}
    for on in (False, True):
        model = build_model(parse_scene(_hanging_doc(on)))
        assert (model_pairs(model).shape[0] > 0) == on
        sim = Simulator(model, envs=1)
        state, ctrl = sim.reset(), sim.make_control()
        iters = [int(sim.step(state, ctrl).newton_iters[0]) for _ in range(40)]
        runs[on] = (iters, state.node_pos[0].copy(), sim)
    assert runs[True][0] == runs[False][0]
    np.testing.assert_allclose(runs[True][1], runs[False][1], atol=1e-8)
    sim = runs[True][2]
    stats = sim.step(sim.reset(), sim.make_control())
    assert stats.contact_count[0] == 0 and stats.energy_contact[0] == 0.0
