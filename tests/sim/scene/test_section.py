"""Cross sections (sim/scene/section.py): constants of each section, scene keys and their errors, dump round trip."""
from __future__ import annotations

import dataclasses
import math
import tomllib

import pytest

from sim import build_model, dump_scene, load_scene, parse_scene
from sim.scene.section import rectangle_torsion_constant, section_of
from sim.scene.spec import SceneError

ROD = """
[sim]
dt = 0.01
gravity = [0.0, 0.0, -9.8]
newton_tol = 1e-8
newton_max_iter = 30
accept_unconverged = false
[rod]
nodes = 11
length = 1.0
density = 1000.0
youngs_modulus = 1e6
poisson_ratio = 0.5
start = [0.0, 0.0, 0.0]
direction = [1.0, 0.0, 0.0]
"""


def _scene(extra):
    return parse_scene(tomllib.loads(ROD + extra), "s.toml")


def test_rectangle_torsion_constant_series():
    """Square: J = 0.1406 a⁴ (the series' known value); a thin strip tends to a b³/3 (1 − 0.630 b/a)."""
    assert rectangle_torsion_constant(1.0, 1.0) == pytest.approx(0.140577, abs=2e-6)
    a, b = 1.0, 0.01
    assert rectangle_torsion_constant(a, b) == pytest.approx(a * b ** 3 / 3 * (1 - 0.6302 * b / a), rel=1e-5)
    assert rectangle_torsion_constant(0.02, 0.05) == rectangle_torsion_constant(0.05, 0.02)


def test_section_constants_and_model():
    rect = _scene('cross_section = "rectangle"\nwidth = 0.04\nheight = 0.01\n')
    s = section_of(rect.rod)
    assert s.area == pytest.approx(4e-4) and s.I1 == pytest.approx(0.01 * 0.04 ** 3 / 12)
    assert s.I2 == pytest.approx(0.04 * 0.01 ** 3 / 12) and s.I1 / s.I2 == pytest.approx(16.0)
    m = build_model(rect)
    assert m.EI1_max == pytest.approx(1e6 * s.I1) and m.GJ_max == pytest.approx(1e6 / 3 * s.J)
    assert m.radius_max == pytest.approx(0.5 * math.hypot(0.04, 0.01))  # contact: circumscribed circle
    assert m.node_mass[1] == pytest.approx(1000 * 4e-4 * 0.1)
    assert m.edge_twist_inertia[0] == pytest.approx(1000 * (s.I1 + s.I2) * 0.1)
    ell = _scene('cross_section = "ellipse"\nsemi_axes = [0.03, 0.01]\n')
    e = section_of(ell.rod)
    assert e.I1 == pytest.approx(math.pi * 0.03 ** 3 * 0.01 / 4) and e.I2 == pytest.approx(math.pi * 0.03 * 1e-6 / 4)
    assert e.J == pytest.approx(math.pi * 0.03 ** 3 * 0.01 ** 3 / (0.03 ** 2 + 0.01 ** 2))
    assert build_model(ell).radius_max == 0.03
    circ = _scene("radius = 0.02\n")
    c = section_of(circ.rod)
    assert c.J == pytest.approx(c.I1 + c.I2) and build_model(circ).EI1_max == pytest.approx(1e6 * math.pi * 0.02 ** 4 / 4)


@pytest.mark.parametrize("extra, key", [
    ('cross_section = "square"\nradius = 0.01\n', "rod.cross_section"),
    ('cross_section = "rectangle"\nwidth = 0.04\n', "rod.height"),
    ('cross_section = "rectangle"\nwidth = 0.04\nheight = 0.01\nradius = 0.02\n', "rod.radius"),
    ('cross_section = "rectangle"\nwidth = -0.04\nheight = 0.01\n', "rod.width"),
    ('cross_section = "rectangle"\nwidth = 1e3\nheight = 0.01\n', "rod.width"),
    ('cross_section = "ellipse"\nsemi_axes = [0.03]\n', "rod.semi_axes"),
    ('cross_section = "ellipse"\nsemi_axes = [0.03, 0.0]\n', "rod.semi_axes"),
    ('width = 0.04\nradius = 0.01\n', "rod.width"),
    ('', "rod.radius"),
])
def test_bad_section_names_the_key(extra, key):
    with pytest.raises(SceneError) as ei:
        _scene(extra)
    assert f"s.toml: {key}" in str(ei.value)


def test_api_section_is_checked():
    spec = _scene("radius = 0.02\n")
    bad = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, cross_section="rectangle", width=0.04))
    with pytest.raises(SceneError, match="rod.height"):
        build_model(bad)


@pytest.mark.parametrize("extra", ['cross_section = "rectangle"\nwidth = 0.04\nheight = 0.01\n',
                                   'cross_section = "ellipse"\nsemi_axes = [0.03, 0.01]\n'])
def test_section_round_trip(tmp_path, extra):
    spec = _scene(extra)
    dump_scene(spec, tmp_path / "a.toml")
    back = load_scene(tmp_path / "a.toml")
    assert back.rod == spec.rod
