"""Scene files: the shipped scenes load, validation errors name file + key + problem, TOML round trip."""
from __future__ import annotations

import math

import pytest

from sim import build_model, dump_scene, load_scene
from sim.scene.spec import SceneError, parse_scene
from tests.helpers.rodspec import ARM


def _write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_shipped_arm_scene_and_derived_constants(scenes_dir):
    spec = load_scene(scenes_dir / "arm.toml")
    assert spec.rod.nodes == 21 and spec.sim.newton_max_iter == 2 and spec.sim.accept_unconverged
    m = build_model(spec)
    # docs/physics.md §8E derived constants
    assert math.isclose(m.EA_max, 7.854e4, rel_tol=1e-3)
    assert math.isclose(m.EI1_max, 49.09, rel_tol=1e-3) and m.EI1_max == m.EI2_max
    assert math.isclose(m.GJ_max, 32.72, rel_tol=1e-3)
    assert math.isclose(m.node_mass[5], 0.3927, rel_tol=1e-3)
    assert math.isclose(m.node_mass.sum(), 7.854, rel_tol=1e-3)
    assert m.dof_fixed.reshape(21, 4)[:2, :3].all() and m.dof_fixed.reshape(21, 4)[0, 3]
    assert not m.dof_fixed.reshape(21, 4)[2:, :3].any()
    m2 = build_model(load_scene(scenes_dir / "arm_2d.toml"))
    assert m2.mode == "2d" and m2.planar_component == 0 and m2.planar_sign == 1.0


@pytest.mark.parametrize("edit, key, problem", [
    (("radius = 0.05", ""), "rod.radius", "missing"),
    (("nodes = 21", "nodes = 2.5"), "rod.nodes", "integer"),
    (("nodes = 21", "nodes = 2"), "rod.nodes", ">= 3"),
    (("radius = 0.05", "radius = 0.0"), "rod.radius", "> 0"),
    (("radius = 0.05", "radius = -1"), "rod.radius", "> 0"),
    (("dt = 0.05", "dt = inf"), "sim.dt", "finite"),
    (("dt = 0.05", "dt = nan"), "sim.dt", "finite"),
    (("poisson_ratio = 0.5", "poisson_ratio = 0.6"), "rod.poisson_ratio", "(-1, 0.5]"),
    (("poisson_ratio = 0.5", "poisson_ratio = -1.0"), "rod.poisson_ratio", "(-1, 0.5]"),
    (("gravity = [0.0, 0.0, -9.8]", "gravity = [0.0, -9.8]"), "sim.gravity", "3 numbers"),
    (("gravity = [0.0, 0.0, -9.8]", 'gravity = "down"'), "sim.gravity", "3 numbers"),
    (("accept_unconverged = true", "accept_unconverged = 1"), "sim.accept_unconverged", "true/false"),
    (("newton_max_iter = 2", "newton_max_iter = 0"), "sim.newton_max_iter", ">= 1"),
    (("direction = [0.0, 0.0, 1.0]", "direction = [0.0, 0.0, 0.0]"), "rod.direction", "non-zero"),
    (("density = 1000.0", "density = 1000.0\ndensty = 3.0"), "rod.densty", "unknown key"),
    (("newton_tol = 1e-3", 'newton_tol = 1e-3\nmode = "4d"'), "sim.mode", "one of"),
    (("newton_tol = 1e-3", 'newton_tol = 1e-3\nmode = "2d"\n'), None, None),
    (("newton_tol = 1e-3", "newton_tol = 1e-3\ndivergence_guard = 0.5"), "sim.divergence_guard", "> 1"),
    (("newton_tol = 1e-3", "newton_tol = 1e-3\ndivergence_guard = -2.0"), "sim.divergence_guard", ">= 0"),
    (("newton_tol = 1e-3", 'newton_tol = 1e-3\ndivergence_guard = "on"'), "sim.divergence_guard", "number"),
])
def test_validation_errors_name_file_key_and_problem(tmp_path, edit, key, problem):
    p = _write(tmp_path, ARM.replace(*edit))
    if key is None:
        assert load_scene(p).sim.mode == "2d"
        return
    with pytest.raises(SceneError) as ei:
        load_scene(p)
    msg = str(ei.value)
    assert str(p) in msg and key in msg and problem in msg


def test_2d_needs_planar_direction(tmp_path):
    text = ARM.replace("newton_tol = 1e-3", 'newton_tol = 1e-3\nmode = "2d"').replace(
        "direction = [0.0, 0.0, 1.0]", "direction = [0.0, 1.0, 1.0]")
    with pytest.raises(SceneError, match="rod.direction"):
        load_scene(_write(tmp_path, text))


def test_missing_table_and_bad_toml(tmp_path):
    with pytest.raises(SceneError, match=r"\[rod\].*missing"):
        load_scene(_write(tmp_path, ARM.split("[rod]")[0]))
    with pytest.raises(SceneError, match="invalid TOML"):
        load_scene(_write(tmp_path, "[sim\n"))
    with pytest.raises(SceneError, match="not found"):
        load_scene(tmp_path / "nope.toml")
    with pytest.raises(SceneError, match="unknown table"):
        parse_scene({"sim": {}, "rod": {}, "rods": {}}, "x.toml")


@pytest.mark.parametrize("name", ["arm.toml", "arm_2d.toml", "cantilever_dynamic.toml", "cantilever_gravity.toml"])
def test_round_trip(tmp_path, scenes_dir, name):
    spec = load_scene(scenes_dir / name)
    out = tmp_path / "rt.toml"
    dump_scene(spec, out)
    spec2 = load_scene(out)
    assert spec2.sim == spec.sim and spec2.rod == spec.rod and spec2.contact == spec.contact
    assert spec2.obstacles == spec.obstacles
    dump_scene(spec2, tmp_path / "rt2.toml")
    assert (tmp_path / "rt2.toml").read_text() == out.read_text()


def test_round_trip_odd_values(tmp_path):
    spec = parse_scene(__import__("tomllib").loads(ARM.replace("dt = 0.05", "dt = 1.234567890123e-7").replace(
        "radius = 0.05", "radius = 3")), "mem.toml")
    dump_scene(spec, tmp_path / "o.toml")
    assert load_scene(tmp_path / "o.toml").sim.dt == 1.234567890123e-7
    assert load_scene(tmp_path / "o.toml").rod.radius == 3.0
