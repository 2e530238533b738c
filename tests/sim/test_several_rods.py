"""Several rods in one scene ([[rod]] tables, docs/physics.md §1.7): parsing and dump, errors, the chain model
with its joint edges, rods that do not touch stepping exactly as each alone, fixes/loads by rod name, and the
per-rod layout in `rodlab sim --out`."""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from sim import Simulator, build_model, dump_scene, load_scene
from sim.scene.boundary import FixSpec, LoadSpec
from sim.scene.spec import SceneError, rest_shape_fields
from tests.helpers.rodspec import make_spec, small_scene_toml

REPO = Path(__file__).resolve().parents[2]
TWO_RODS = REPO / "assets" / "scenes" / "two_rods.toml"

_ROD = ('nodes = 5\nlength = 1.0\nradius = 0.01\ndensity = 1000\nyoungs_modulus = 1e6\npoisson_ratio = 0.5\n'
        'direction = [1, 0, 0]\n')


def _scene_text(*rods: str, extra: str = "") -> str:
    head = small_scene_toml("").split("[rod]")[0]
    return head + "".join(f"\n[[rod]]\n{r}" for r in rods) + extra


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


# ------------------------------------------------------------------------------------------------ parsing
def test_rod_tables_parse_in_file_order_and_round_trip(tmp_path):
    text = _scene_text(f'name = "left"\n{_ROD}start = [0, 0, 0]\n',
                       'name = "right"\nnodes = 4\nlength = 0.5\ncross_section = "rectangle"\nwidth = 0.02\n'
                       'height = 0.01\ndensity = 500\nyoungs_modulus = [1e6, 2e6, 3e6]\npoisson_ratio = 0.4\n'
                       'start = [0, 1, 0]\ndirection = [0, 1, 0]\nclamp = "none"\nprestretch = 0.01\n',
                       'name = "bent"\nradius = [0.01, 0.02]\ndensity = 1000\nyoungs_modulus = 1e6\n'
                       'poisson_ratio = 0.5\nrest_points = [[0, 3, 0], [0.1, 3, 0], [0.2, 3, 0.05]]\n')
    spec = load_scene(_write(tmp_path, text))
    assert spec.rod_names == ("left", "right", "bent")
    assert [r.nodes for r in spec.rods] == [5, 4, 3]
    assert spec.rods[1].edge_youngs_modulus == (1e6, 2e6, 3e6) and spec.rods[2].edge_radius == (0.01, 0.02)
    out = tmp_path / "out.toml"
    dump_scene(spec, out)
    assert out.read_text().count("[[rod]]") == 3 and "[rod]\n" not in out.read_text()
    again = load_scene(out)
    assert again.rods == spec.rods and again.sim == spec.sim
    with pytest.raises(ValueError, match="3 rods"):
        spec.rod  # noqa: B018  (several rods: there is no "the" rod)


def test_single_rod_table_stays_one_rod_named_rod(tmp_path):
    spec = load_scene(_write(tmp_path, small_scene_toml("")))
    assert spec.rod_names == ("rod",) and spec.rod is spec.rods[0]
    out = tmp_path / "out.toml"
    dump_scene(spec, out)
    assert "[rod]\n" in out.read_text() and "[[rod]]" not in out.read_text() and "name" not in out.read_text()
    one = load_scene(_write(tmp_path, _scene_text(_ROD + "start = [0, 0, 0]\n")))  # a single [[rod]] table: the name is optional
    assert one.rod_names == ("rod",) and one.rod == spec.rod


def test_replace_rod_and_rods():
    spec = make_spec()
    a = dataclasses.replace(spec.rod, name="a")
    b = dataclasses.replace(spec.rod, name="b", start=(0.0, 1.0, 0.0))
    two = dataclasses.replace(spec, rods=(a, b))
    assert two.rod_names == ("a", "b")
    assert dataclasses.replace(spec, rod=a).rods == (a,)
    with pytest.raises(ValueError, match="rods="):
        dataclasses.replace(two, rod=a)


@pytest.mark.parametrize("rods, extra, match", [
    ((f'name = "a"\n{_ROD}start = [0, 0, 0]\n', f'{_ROD}start = [0, 1, 0]\n'), "", r"rod\[1\].name: missing"),
    ((f'name = "a"\n{_ROD}start = [0, 0, 0]\n', f'name = "a"\n{_ROD}start = [0, 1, 0]\n'), "",
     "duplicate rod name 'a'"),
    ((f'name = ""\n{_ROD}start = [0, 0, 0]\n',), "", "non-empty"),
    ((f'name = "a"\n{_ROD}start = [0, 0, 0]\n', f'name = "b"\n{_ROD}start = [0, 1, 0]\n'),
     '\n[[fix]]\nnodes = [0]\n', r"fix\[0\].rod: the scene has several rods \('a', 'b'\)"),
    ((f'name = "a"\n{_ROD}start = [0, 0, 0]\n', f'name = "b"\n{_ROD}start = [0, 1, 0]\n'),
     '\n[[load]]\nrod = "c"\nnode = 0\n', r"load\[0\].rod: no rod named 'c' \(the rods: 'a', 'b'\)"),
    ((f'name = "a"\n{_ROD}start = [0, 0, 0]\n', f'name = "b"\n{_ROD}start = [0, 1, 0]\n'),
     '\n[[fix]]\nrod = "b"\nnodes = [5]\n', r"fix\[0\].nodes: node index 5 out of range for 5 nodes"),
    ((f'name = "a"\n{_ROD}start = [0, 0, 0]\n', f'name = "b"\n{_ROD.replace("nodes = 5", "nodes = 2")}'
      'start = [0, 1, 0]\n'), "", r"rod\['b'\].nodes: must be >= 3"),
    ((f'name = "a"\n{_ROD}start = [0, 0, 0]\n', f'name = "b"\n{_ROD.replace("radius = 0.01", "radius = -1")}'
      'start = [0, 1, 0]\n'), "", r"rod\['b'\].radius"),
    ((f'name = "a"\n{_ROD}start = [0, 0, 0]\n', f'name = "b"\n{_ROD}start = [0, 1, 0]\nlength2 = 1\n'), "",
     r"rod\['b'\].length2"),
])
def test_bad_rod_tables_are_named(tmp_path, rods, extra, match):
    with pytest.raises(SceneError, match=match):
        load_scene(_write(tmp_path, _scene_text(*rods, extra=extra)))


def test_rod_and_rod_tables_together_are_refused(tmp_path):
    text = small_scene_toml("") + f'\n[[rod]]\nname = "b"\n{_ROD}start = [0, 1, 0]\n'
    with pytest.raises(SceneError, match=r"one \[rod\] table or \[\[rod\]\] tables"):
        load_scene(_write(tmp_path, text))


def test_planar_rods_share_one_plane(tmp_path):
    text = _scene_text(f'name = "a"\n{_ROD}start = [0, 0, 0]\n', f'name = "b"\n{_ROD}start = [0, 0.5, 1]\n')
    text = text.replace("[sim]\n", '[sim]\nmode = "2d"\n')
    with pytest.raises(SceneError, match=r"rod\['b'\].start: mode '2d' needs every rod in one plane"):
        load_scene(_write(tmp_path, text))


# ------------------------------------------------------------------------------------------------ the chain model
def _two(spec, a, b):
    return dataclasses.replace(spec, rods=(dataclasses.replace(a, name="a"), dataclasses.replace(b, name="b")))


def test_chain_model_has_joint_edges_without_material():
    spec = make_spec(gravity=(0.0, 0.0, -9.8))
    a = spec.rod
    b = dataclasses.replace(a, nodes=6, radius=0.01, start=(0.0, 1.0, 0.0), clamp="none")
    m, ma, mb = build_model(_two(spec, a, b)), build_model(spec), build_model(dataclasses.replace(spec, rod=b))
    assert m.node_count == 17 and m.rod_names == ("a", "b") and list(m.rod_node_offsets) == [0, 11, 17]
    assert m.edge_link.tolist() == [True] * 10 + [False] + [True] * 5
    j = 10
    assert m.edge_EA[j] == 0.0 and m.rest_edge_length[j] == 1.0 and m.edge_radius[j] == 0.01
    np.testing.assert_array_equal(m.node_mass, np.concatenate([ma.node_mass, mb.node_mass]))
    np.testing.assert_array_equal(m.voronoi_length, np.concatenate([ma.voronoi_length, mb.voronoi_length]))
    np.testing.assert_array_equal(m.rest_kappa_bar, np.concatenate([ma.rest_kappa_bar, mb.rest_kappa_bar]))
    fixed = m.dof_fixed.reshape(-1, 4)
    assert fixed[j, 3] and fixed[-1, 3] and fixed[0].all() and not fixed[11].any()  # a clamped, b free
    assert m.locked_edges == (0,)
    assert m.radius_max == 0.02 and m.EA_max == ma.EA_max
    sl = m.rod_slices()
    assert sl == {"a": slice(0, 11), "b": slice(11, 17)}
    parts = m.split_rods(np.zeros((2, 3, 17, 3)))
    assert parts["a"].shape == (2, 3, 11, 3) and parts["b"].shape == (2, 3, 6, 3)


def _run(spec, steps):
    sim = Simulator(build_model(spec), envs=2)
    state, ctrl = sim.reset(), sim.make_control()
    for _ in range(steps):
        sim.step(state, ctrl)
    assert not state.failed.any()
    return state


def _exact(**kw):
    """Settings under which every solve does the same iterations whatever else is in the scene: a fixed count
    of Newton iterations (no tolerance reached, no guard): the rods' solves share nothing else."""
    return make_spec(tol=1e-300, dtol=1e-300, max_iter=6, accept=True, **kw)


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_rods_apart_step_exactly_as_each_alone(mode):
    spec = _exact(gravity=(0.0, 0.0, -9.8), dt=0.005, mode=mode)
    spec = dataclasses.replace(spec, sim=dataclasses.replace(spec.sim, divergence_guard=0.0))
    a = spec.rod  # a clamped cantilever along x, bending under gravity
    # a thinner, stiffer rod of other node count hanging straight down from a clamp, then curving away
    pts = [(3.0, 0.0, 0.0), (3.0, 0.0, -0.1)] + [(3.0 + 0.1 * math.sin(0.3 * k), 0.0, -0.1 - 0.1 * math.cos(0.3 * k))
                                                  for k in range(1, 7)]
    b = dataclasses.replace(a, radius=0.015, youngs_modulus=3e6, **rest_shape_fields(pts))
    alone_a = _run(spec, 5)
    alone_b = _run(dataclasses.replace(spec, rod=b), 5)
    both = _two(spec, a, b)
    together = _run(both, 5)
    assert build_model(both).rod_planar[0] != build_model(both).rod_planar[1] or mode == "3d"
    np.testing.assert_array_equal(together.dof[:, :11], alone_a.dof)
    np.testing.assert_array_equal(together.dof[:, 11:], alone_b.dof)
    np.testing.assert_array_equal(together.dof_vel[:, 11:], alone_b.dof_vel)
    if mode == "3d":
        np.testing.assert_array_equal(together.edge_ref_d1[:, 11:], alone_b.edge_ref_d1)
        np.testing.assert_array_equal(together.node_ref_twist[:, 11:], alone_b.node_ref_twist)


@pytest.mark.parametrize("mode", ["3d", "2d"])
def test_rods_touching_end_to_end_give_no_nan(mode):
    spec = make_spec(gravity=(0.0, 0.0, -9.8), mode=mode, accept=True, max_iter=10, tol=1e-6, dtol=1e-6)
    a = spec.rod
    b = dataclasses.replace(a, start=(1.0, 0.0, 0.0), clamp="none")  # starts where a ends: a zero-length joint
    m = build_model(_two(spec, a, b))
    assert np.linalg.norm(m.rest_node_pos[11] - m.rest_node_pos[10]) == 0.0
    state = _run(_two(spec, a, b), 10)
    assert np.isfinite(state.dof).all() and np.isfinite(state.edge_ref_d1).all()
    assert np.isfinite(state.node_ref_twist).all()
    assert state.node_pos[0, -1, 2] < -0.01  # b falls, a hangs on its clamp


def test_fixes_and_loads_address_a_rod_by_name():
    spec = make_spec(clamp="none")
    a = spec.rod
    b = dataclasses.replace(a, nodes=6, start=(0.0, 1.0, 0.0))
    two = dataclasses.replace(_two(spec, a, b),
                              fixes=(FixSpec(rod="b", nodes=(0, -1), axes="z", twist_edges=(-1,)),),
                              loads=(LoadSpec(rod="b", node=-1, force=(0.0, 0.0, 2.0), torque=0.5),
                                     LoadSpec(rod="a", node=2, force=(1.0, 0.0, 0.0))))
    m = build_model(two)
    fixed = m.dof_fixed.reshape(-1, 4)
    assert fixed[11, 2] and fixed[16, 2] and not fixed[11, :2].any() and fixed[15, 3]
    assert not fixed[:11, :3].any()
    F = m.load_force.reshape(2, -1, 4)
    assert F[0, 16, 2] == 2.0 and F[0, 15, 3] == 0.5 and F[1, 2, 0] == 1.0
    with pytest.raises(SceneError, match="several rods"):
        build_model(dataclasses.replace(two, loads=(LoadSpec(node=0),)))


# ------------------------------------------------------------------------------------------------ rodlab sim
def test_rodlab_sim_writes_the_rod_layout(tmp_path, capsys):
    from sim.cli import sim_main

    out = tmp_path / "two.npz"
    assert sim_main([str(TWO_RODS), "--duration", "0.05", "--out", str(out), "--no-progress"]) == 0
    assert "rod 'cross'" in capsys.readouterr().out
    with np.load(out) as z:
        assert z["node_pos"].shape == (5, 1, 42, 3)
        assert z["rod_node_offsets"].tolist() == [0, 21, 42] and z["rod_names"].tolist() == ["base", "cross"]
        assert np.isfinite(z["node_pos"]).all()
        cross = z["node_pos"][:, 0, 21:]
        assert cross[-1, :, 2].mean() < cross[0, :, 2].mean()  # the cross rod falls


def test_rodlab_sim_contact_rows_of_two_rods_at_rest(tmp_path, monkeypatch):
    """Once "cross" rests on "base": the .npz lists the pair rows after the floor's, and the total contact force
    carries the two rods' weight, from the listed rows only (rows after contact_count are what earlier steps left
    there: here they are made huge)."""
    from sim import Simulator, build_model, load_scene
    from sim.cli import sim_main

    step = Simulator.step

    def step_leaving_rows(self, state, ctrl):
        stats = step(self, state, ctrl)
        for e, k in enumerate(stats.contact_count):
            stats.contact_normal_force[e, k:] = 1e6
            stats.contact_normal[e, k:] = (0.0, 0.0, 1.0)
        return stats

    monkeypatch.setattr(Simulator, "step", step_leaving_rows)

    out = tmp_path / "two.npz"
    assert sim_main([str(TWO_RODS), "--duration", "2", "--every", "50", "--out", str(out), "--no-progress"]) == 0
    model = build_model(load_scene(TWO_RODS))
    weight = 9.8 * np.asarray(model.dof_mass).reshape(-1, 4)[:, 0].sum()
    with np.load(out) as z:
        k = int(z["contact_count"][-1, 0])
        obstacle, partner = z["contact_obstacle"][-1, 0, :k], z["contact_partner_edge"][-1, 0, :k]
        pair = obstacle == -1
        assert pair.sum() >= 2 and not pair[: k - pair.sum()].any()  # the floor's rows, then the pairs'
        assert (partner[pair] >= 0).all() and (partner[~pair] == -1).all()
        np.testing.assert_allclose(z["contact_force"][-1, 0], [0.0, 0.0, weight], atol=2e-3 * weight)


def test_rodlab_sim_single_rod_npz_has_the_layout(tmp_path):
    from sim.cli import sim_main

    out = tmp_path / "one.npz"
    assert sim_main([str(REPO / "assets" / "scenes" / "arm.toml"), "--duration", "0.1", "--out", str(out),
                     "--no-progress"]) == 0
    with np.load(out) as z:
        assert z["rod_node_offsets"].tolist() == [0, z["node_pos"].shape[2]] and z["rod_names"].tolist() == ["rod"]


def test_static_solve_of_two_rods(tmp_path):
    from sim.cli import sim_main

    spec = make_spec(gravity=(0.0, 0.0, -9.8), E=1e7)
    b = dataclasses.replace(spec.rod, start=(0.0, 1.0, 0.0))
    p = tmp_path / "s.toml"
    dump_scene(_two(spec, spec.rod, b), p)
    out = tmp_path / "st.npz"
    assert sim_main([str(p), "--static", "--out", str(out), "--no-progress"]) == 0
    with np.load(out) as z:
        assert z["rod_node_offsets"].tolist() == [0, 11, 22]
        x = z["node_pos"][0, 0]
    assert x[10, 2] < -1e-3  # the cantilevers sag, both alike
    np.testing.assert_allclose(x[10], x[21] - [0.0, 1.0, 0.0], atol=1e-9)
