"""Hardening, scene values: every bad scene file or value gets a SceneError naming the file and the key
(sim/scene/validate.py, docs/conventions.md "Input bounds"); huge finite directions are normalised exactly."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from sim import Simulator, build_model, load_scene
from sim.scene.spec import SceneError
from sim.scene.validate import BOUNDS, bounds_table
from tests.helpers.rodspec import ARM


def _scene(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_non_utf8_scene_file_is_a_scene_error(tmp_path):
    p = tmp_path / "latin1.toml"
    p.write_bytes(ARM.encode() + b"# caf\xe9\n")
    with pytest.raises(SceneError, match=r"latin1\.toml: not a UTF-8 text file"):
        load_scene(p)


def test_directory_as_scene_is_a_scene_error(tmp_path):
    d = tmp_path / "dir.toml"
    d.mkdir()
    with pytest.raises(SceneError, match=r"dir\.toml: is a directory"):
        load_scene(d)


@pytest.mark.parametrize("edit, key", [
    (("radius = 0.05", "radius = 1e200"), "rod.radius"),
    (("radius = 0.05", "radius = 1e-300"), "rod.radius"),          # zero mass and stiffness: refused
    (("length = 1.0", "length = 1e-300"), "rod.length"),
    (("length = 1.0", "length = 1.7e308"), "rod.length"),
    (("nodes = 21", f"nodes = {2 ** 62}"), "rod.nodes"),
    (("newton_max_iter = 2", "newton_max_iter = 2.5"), "sim.newton_max_iter"),
    (("dt = 0.05", "dt = 1e-300"), "sim.dt"),
    (("density = 1000.0", "density = 1e300"), "rod.density"),
    (("youngs_modulus = 1e7", "youngs_modulus = 1e-300"), "rod.youngs_modulus"),
    (("start = [0.0, 0.0, 0.0]", "start = [1e300, 0.0, 0.0]"), "rod.start"),
    (("gravity = [0.0, 0.0, -9.8]", "gravity = [0.0, 0.0, -1e300]"), "sim.gravity"),
])
def test_huge_or_tiny_finite_values_are_refused_naming_file_and_key(tmp_path, edit, key):
    p = _scene(tmp_path, ARM.replace(*edit))
    with pytest.raises(SceneError) as ei:
        load_scene(p)
    msg = str(ei.value)
    assert str(p) in msg and key in msg, msg


def test_huge_direction_is_normalised_exactly(tmp_path):
    spec = load_scene(_scene(tmp_path, ARM.replace("direction = [0.0, 0.0, 1.0]", "direction = [0, 0, 1e200]")))
    assert spec.rod.direction == (0.0, 0.0, 1.0)
    m = build_model(spec)
    assert np.isfinite(m.rest_node_pos).all() and m.rest_node_pos[-1, 2] == pytest.approx(1.0)


@pytest.mark.parametrize("table, key", [
    ('[[obstacle]]\ntype = "box"\nposition = [0.5, 0, 0.5]\nhalf_extents = [0.1, 0.1, 0.1]\n'
     'orientation = [1e300, 1e300, 0, 0]\n', "orientation"),
    ('[[obstacle]]\ntype = "plane"\npoint = [0, 0, -1]\nnormal = [0, 0, 1e200]\n', "normal"),
])
def test_huge_obstacle_unit_vectors_stay_unit_or_are_refused(tmp_path, table, key):
    """A box orientation [1e300, 1e300, 0, 0] used to become (0, 0, 0, 0) (NaN rotation, the box silently left
    contact) and a plane normal [0, 0, 1e200] became (0, 0, 0): now the loaded vector is unit, or the scene is
    refused naming the key."""
    p = _scene(tmp_path, ARM + "\n" + table)
    try:
        spec = load_scene(p)
    except SceneError as exc:
        assert str(p) in str(exc) and f"obstacle[0].{key}" in str(exc)
        return
    v = np.asarray(getattr(spec.obstacles[0], key))
    assert np.isfinite(v).all() and abs(np.linalg.norm(v) - 1.0) < 1e-12
    m = build_model(spec)
    sim = Simulator(m, envs=1)
    assert np.isfinite(sim.reset().obstacle_orientation).all()


def test_specs_built_in_code_get_the_same_checks():
    spec = load_scene("assets/scenes/arm.toml")
    bad = dataclasses.replace(spec, sim=dataclasses.replace(spec.sim, newton_max_iter=2.5))
    with pytest.raises(SceneError, match="sim.newton_max_iter"):
        build_model(bad)
    bad = dataclasses.replace(spec, rod=dataclasses.replace(spec.rod, radius=1e-300))
    with pytest.raises(SceneError, match="rod.radius"):
        build_model(bad)


def test_every_shipped_scene_is_within_the_bounds(scenes_dir):
    for p in sorted(scenes_dir.glob("*.toml")):
        build_model(load_scene(p))


def test_bounds_are_documented():
    doc = open("docs/conventions.md", encoding="utf-8").read()
    assert "## Input bounds" in doc
    for key in BOUNDS:
        assert f"`{key}`" in doc, key
    assert bounds_table() in doc
