"""StepStats contact rows when more contacts touch than the report lists (issue: rows silently capped at 64): the
dropped rows are counted, the total force and max penetration cover every contact, and the Simulator grows the
report so the next steps list them all; ``rodlab sim --out`` writes the count and the complete total."""
from __future__ import annotations

import numpy as np

from sim import Simulator, build_model, parse_scene
from sim.cli import sim_main
from sim.contact.world import REPORT_CAPACITY
from sim.support.assets import asset_path
from tests.helpers.contact import FLOOR_DOC, FLOOR_NODES

NODES, DOC = FLOOR_NODES, FLOOR_DOC


def _model():
    return build_model(parse_scene(DOC, str(asset_path("scenes") / "_floor.toml")))


def test_rows_beyond_the_capacity_are_counted_then_listed():
    model = _model()
    sim = Simulator(model, envs=2)
    state, ctrl = sim.reset(), sim.make_control()
    first = sim.step(state, ctrl)
    assert REPORT_CAPACITY < NODES
    assert np.all(first.contact_count == REPORT_CAPACITY)
    assert np.all(first.contact_dropped == NODES - REPORT_CAPACITY)  # every node touches; the rest not listed
    listed = (first.contact_normal_force[..., None] * first.contact_normal + first.contact_friction_force).sum(axis=1)
    assert np.all(first.contact_force[:, 2] > 1.2 * listed[:, 2])  # the total covers the unlisted contacts too
    second = sim.step(state, ctrl)  # the report grew: every contact listed, and the total is their sum
    assert np.all(second.contact_dropped == 0) and np.all(second.contact_count == NODES)
    assert second.contact_edge.shape[1] >= NODES
    listed = (second.contact_normal_force[..., None] * second.contact_normal + second.contact_friction_force)
    np.testing.assert_allclose(listed.sum(axis=1), second.contact_force, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(second.max_penetration, np.maximum(0.0, -second.contact_gap[:, :NODES].min(axis=1)),
                               rtol=1e-12)
    weight = 1000.0 * np.pi * 0.01 ** 2 * 2.0 * 9.8
    for stats in (first, second):  # the floor carries the rod (settling: within a factor of 3 of its weight)
        assert np.all((weight / 3 < stats.contact_force[:, 2]) & (stats.contact_force[:, 2] < 3 * weight))


def test_sim_cli_writes_the_dropped_rows_and_the_complete_total(tmp_path, capsys):
    """The rod falls onto the floor: at the impact every node touches at once, more than the report lists; the
    frames say so, the totals count every contact, and the later frames list them all."""
    from sim import dump_scene

    doc = dict(DOC, rod=dict(DOC["rod"], start=[0.0, 0.0, 0.0125]))
    scene = tmp_path / "floor.toml"
    dump_scene(parse_scene(doc, str(asset_path("scenes") / "_floor.toml")), scene)
    out = tmp_path / "run.npz"
    assert sim_main([str(scene), "--duration", "0.1", "--out", str(out), "--no-progress"]) == 0
    assert "did not fit" in capsys.readouterr().out
    with np.load(out) as f:
        dropped, count, force = f["contact_dropped"][:, 0], f["contact_count"][:, 0], f["contact_force"][:, 0]
        fn, normal, fr = f["contact_normal_force"][:, 0], f["contact_normal"][:, 0], f["contact_friction_force"][:, 0]
    hit = int(np.argmax(dropped > 0))
    assert dropped[hit] > 0 and count[hit] == REPORT_CAPACITY and np.all(dropped[hit + 1:] == 0)
    assert fn.shape[1] >= NODES and count[-1] == NODES  # rows padded to the grown capacity
    listed = (fn[..., None] * normal + fr).sum(axis=1)
    assert force[hit, 2] > listed[hit, 2]  # the impact frame's total counts the contacts it did not list
    np.testing.assert_allclose(listed[hit + 1:], force[hit + 1:], rtol=1e-12, atol=1e-12)
