"""``[rod] natural_curvature`` (docs/physics.md §1.2): a natural curvature added to the rest shape's without moving
the initial configuration. A free-ended cantilever without gravity bends to the arc its natural curvature makes
(each interior node turns the rod by 2 atan(κ/2)); the key round-trips through a scene file and bad values are
refused by name."""
from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from sim import build_model
from sim.scene.spec import parse_scene, scene_to_toml
from sim.scene.tomlio import SceneError
from tests.helpers.rodspec import small_scene_toml
from tests.helpers.statics import static_solve

KAPPA = 0.2
DOC = small_scene_toml(f"natural_curvature = [[0, 0], [{KAPPA}, 0], [{KAPPA}, 0], [{KAPPA}, 0], [0, 0]]")


def test_a_cantilever_bends_to_its_natural_curvature():
    spec = parse_scene(tomllib.loads(DOC.replace("dt = 0.01", "dt = 100.0")))  # backward-Euler steps ≈ statics
    model = build_model(spec)
    assert np.allclose(model.rest_kappa_bar[1:-1, 0], KAPPA) and np.allclose(model.rest_node_pos[:, 1:], 0.0)
    sim, state, stats = static_solve(spec, steps=200)  # starts straight, relaxes to its natural shape
    assert stats.converged.all()
    x = state.node_pos[0]
    e = np.diff(x, axis=0)
    turn = [math.atan2(np.linalg.norm(np.cross(a, b)), float(a @ b)) for a, b in zip(e[:-1], e[1:])]
    assert np.allclose(turn, 2.0 * math.atan(KAPPA / 2.0), atol=1e-6), turn  # at rest on the natural shape


def test_scene_key_round_trip_and_bad_values():
    spec = parse_scene(tomllib.loads(DOC))
    assert spec.rod.natural_curvature[1] == (KAPPA, 0.0)
    assert parse_scene(tomllib.loads(scene_to_toml(spec))) == spec
    for bad, what in (("[[0, 0]]", "expected 5 pairs"),
                      ('[[0, "a"], [0, 0], [0, 0], [0, 0], [0, 0]]', r"natural_curvature\[0\]: expected a pair"),
                      ("[[0, 50], [0, 0], [0, 0], [0, 0], [0, 0]]", "within")):
        text = DOC.replace(DOC.split("natural_curvature = ")[1].split("\n")[0], bad)
        with pytest.raises(SceneError, match=what):
            build_model(parse_scene(tomllib.loads(text)))
