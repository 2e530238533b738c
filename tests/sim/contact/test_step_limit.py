"""Tunnelling safeguards (docs/physics.md §6.4): the Newton step limit
(``update_fraction``) and the candidate refresh, unit-level and in the simulator."""
from __future__ import annotations

import numpy as np
import pytest

from sim import Simulator, build_model, parse_scene
from sim.contact.obstacles import find_candidates, merge_candidates, smallest_gap, update_fraction
from tests.helpers.paths import REPO

DELTA = 5e-3
R_ROD = 0.05
R_CAP = 0.1


def capsule_sim():
    """A horizontal rod (21 nodes along x at z = 0.5) and a capsule along y at x = 0.5, z = 0.2 (R 0.1)."""
    doc = {"sim": dict(dt=0.05, gravity=[0.0, 0.0, 0.0], damping=0.0, newton_tol=1e-3, newton_max_iter=5,
                       accept_unconverged=True, mode="3d"),
           "rod": dict(nodes=21, length=1.0, radius=R_ROD, density=1000.0, youngs_modulus=1e7, poisson_ratio=0.5,
                       start=[0.0, 0.0, 0.5], direction=[1.0, 0.0, 0.0], clamp="none"),
           "obstacle": [dict(type="capsule", start=[0.5, -0.5, 0.2], end=[0.5, 0.5, 0.2], radius=R_CAP)]}
    sim = Simulator(build_model(parse_scene(doc, str(REPO / "assets" / "scenes" / "_t.toml"))), envs=1)
    x = np.zeros((21, 3))
    x[:, 0] = np.linspace(0.0, 1.0, 21)
    x[:, 2] = 0.5
    return sim.contact_data(sim.reset()), x


def gap(cd, x):
    find_candidates(0, cd, x, x, 1.0)
    return -smallest_gap(0, cd, x, np.array([R_ROD]))   # penetration (>= 0)


def test_update_through_an_obstacle_stops_at_delta():
    """Rod 0.15 m above the capsule surface, update 1 m straight down (through it): the allowed fraction
    brings the rod to delta penetration, not further."""
    cd, x = capsule_sim()
    d = np.zeros_like(x)
    d[:, 2] = -1.0
    find_candidates(0, cd, x, x + d, 0.05)
    t = update_fraction(0, cd, x, d, np.array([R_ROD]), DELTA)
    assert 0.14 < t < 0.16
    assert gap(cd, x + t * d) == pytest.approx(DELTA, abs=1e-4)


def test_sliding_and_receding_updates_are_not_limited():
    cd, x = capsule_sim()
    x = x.copy()
    x[:, 2] = 0.2 + R_CAP + R_ROD - 0.002   # resting 2 mm deep on the capsule
    for d in (np.tile([0.0, 0.3, 0.0], (21, 1)), np.tile([0.0, 0.0, 0.2], (21, 1))):  # slide along y, lift off
        find_candidates(0, cd, x, x + d, 0.05)
        assert update_fraction(0, cd, x, d, np.array([R_ROD]), DELTA) == 1.0


def test_penetrating_pair_goes_at_most_delta_deeper():
    cd, x = capsule_sim()
    x = x.copy()
    x[:, 2] = 0.2 + R_CAP + R_ROD - 0.01    # 10 mm deep
    d = np.zeros_like(x)
    d[:, 2] = -0.1
    find_candidates(0, cd, x, x + d, 0.05)
    t = update_fraction(0, cd, x, d, np.array([R_ROD]), DELTA)
    assert gap(cd, x + t * d) == pytest.approx(0.01 + DELTA, abs=1e-4)


def test_refresh_adds_the_pairs_of_the_motion_taken():
    """A list built for a motion away from the capsule misses it; refreshing over the solved motion (onto
    the capsule) adds its pairs and reports that it did; a second refresh adds nothing."""
    cd, x = capsule_sim()
    up = x.copy()
    up[:, 2] += 0.3
    down = x.copy()
    down[:, 2] -= 0.25
    assert find_candidates(0, cd, x, up, 0.05) == 0
    assert merge_candidates(0, cd, x, down, 0.05)
    assert cd.cand_count[0] > 0
    assert not merge_candidates(0, cd, x, down, 0.05)


@pytest.mark.parametrize("mode", ["2d", "3d"])
def test_step_limit_alone_stops_a_fast_swing(mode):
    """The penetration guard's scenario (arm swinging at 10 rad/s into a capsule, which unguarded and unlimited
    ends a step deeper than the arm radius) with the guard off: the step limit alone keeps the arm out."""
    from test_penetration_guard import swing_into_capsule

    hist = swing_into_capsule(mode, {"max_penetration": 1e9, "step_limit": True})
    pen = max(float(s.max_penetration[0]) for s in hist)
    assert pen <= 4 * DELTA, f"penetrated {1e3 * pen:.1f} mm"
    assert all(int(s.substeps[0]) == 1 for s in hist)
