"""The flat-ended ``cylinder`` obstacle (docs/physics.md §4.5): scene round trip, a flat end face (where a capsule
of the same axis and radius is round), and its side within the prism's facet error."""
from __future__ import annotations

import numpy as np
import pytest

from sim.contact.obstacles import find_candidates
from sim.scene.obstacles import CapsuleSpec, CylinderSpec, dump_obstacles, parse_obstacles
from sim.scene.tomlio import SceneError
from tests.helpers.contact import R_ROD, make_set, report

CYL = dict(type="cylinder", start=[0.0, 0.0, 0.0], end=[0.0, 0.0, 0.4], radius=0.1, friction=0.3)


def test_cylinder_scene_round_trip_and_errors():
    (spec,) = parse_obstacles([CYL], None)
    assert isinstance(spec, CylinderSpec) and spec.radius == 0.1 and spec.friction == 0.3
    import tomllib
    text = "\n".join(dump_obstacles([spec]))
    assert parse_obstacles(tomllib.loads(text)["obstacle"], None) == (spec,)
    with pytest.raises(SceneError, match="end"):
        parse_obstacles([dict(CYL, end=[0.0, 0.0, 0.0])], None)


def _gap(spec, seg):
    _, cd = make_set([spec], 2)
    x = np.array(seg, dtype=float)
    find_candidates(0, cd, x, x, 1.0)
    _, out = report(cd, x, delta=1.0)
    k = int(out["count"][0])
    assert k >= 1
    return float(out["gap"][0, :k].min())


def test_flat_end_face_and_round_side():
    cyl = CylinderSpec((0.0, 0.0, 0.0), (0.0, 0.0, 0.4), 0.1)
    cap = CapsuleSpec((0.0, 0.0, 0.0), (0.0, 0.0, 0.4), 0.1)
    h = 0.4 + R_ROD + 2e-3  # a rod edge lying across the top face, 2 mm above it
    top = [[-0.05, 0.01, h], [0.05, 0.01, h]]
    assert _gap(cyl, top) == pytest.approx(2e-3, abs=1e-9)  # flat: the plane z = 0.4
    assert _gap(cap, top) < -0.05  # a capsule's round end reaches 0.1 m higher
    # side: an edge across the axis direction, 2 mm outside the radius (facet error <= R (1 - cos(pi/48)))
    x = 0.1 + R_ROD + 2e-3
    side = [[x, -0.05, 0.2], [x, 0.05, 0.2]]
    assert abs(_gap(cyl, side) - 2e-3) <= 0.1 * (1 - np.cos(np.pi / 48)) + 1e-9
