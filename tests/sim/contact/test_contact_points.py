"""One meaning of ``contact_obstacle_point`` for every obstacle kind: the closest point on the obstacle's
surface, so rod point − obstacle point = (gap + rod radius) · normal (docs/architecture.md, StepStats)."""
from __future__ import annotations

import numpy as np
import pytest
from test_contact_derivatives import CASES

from sim.scene.obstacles import PlaneSpec, quat_to_matrix
from tests.helpers.contact import R_ROD, make_set, place_at_gap, report

ALL = dict(CASES, plane=([PlaneSpec((0.0, 0.0, 0.1), (0.0, 0.6, 0.8))], [[0.0, 0.3, 0.5], [0.2, 0.3, 0.55]]))


@pytest.mark.parametrize("name", list(ALL))
def test_obstacle_point_is_on_the_surface(name):
    specs, x0 = ALL[name]
    _, cd = make_set(specs, 2)
    x = place_at_gap(cd, np.array(x0, dtype=float), 2e-3)
    _, out = report(cd, x, delta=1.0)
    k = int(out["count"][0])
    assert k >= 1
    for c in range(k):
        p, q, n, g = out["rod_point"][0, c], out["obstacle_point"][0, c], out["normal"][0, c], out["gap"][0, c]
        np.testing.assert_allclose(p - q, (g + R_ROD) * n, atol=1e-9)
        s = specs[0]
        if s.type == "sphere":
            assert np.linalg.norm(q - np.array(s.center)) == pytest.approx(s.radius, abs=1e-9)
        elif s.type == "capsule":
            a, b = np.array(s.start), np.array(s.end)
            u = np.clip((q - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
            assert np.linalg.norm(q - (a + u * (b - a))) == pytest.approx(s.radius, abs=1e-9)
        elif s.type == "plane":
            assert (q - np.array(s.point)) @ np.array(s.normal) == pytest.approx(0.0, abs=1e-12)
        elif s.type == "box":
            loc = quat_to_matrix(np.array(s.orientation)).T @ (q - np.array(s.position))
            assert np.max(np.abs(loc) / np.array(s.half_extents)) == pytest.approx(1.0, abs=1e-9)
