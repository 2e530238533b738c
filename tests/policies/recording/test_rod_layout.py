"""The rod layout of a scene of several rods in a recording (``/__properties/rods``, policies.recording.schema):
written with the episode, read back through a real .rrd file; a recording without it (all older ones) is one rod."""
from __future__ import annotations

import numpy as np
import pytest

from policies.recording import Recorder, RecordingError, StaticScene, read_recording
from tests.helpers.paths import REPO

EXAMPLES = REPO / "recordings" / "examples"


def _chain(k: int) -> np.ndarray:
    """Two rods (5 and 4 nodes) of one chain, the second lifted 0.3 m above the first."""
    x = np.zeros((9, 3))
    x[:5, 0] = np.linspace(0.0, 1.0, 5)
    x[5:, 1] = np.linspace(-0.4, 0.4, 4)
    x[5:, 2] = 0.3 - 0.01 * k
    return x


def test_two_rod_layout_round_trips_through_a_file(tmp_path, verify):
    out = tmp_path / "two.rrd"
    with Recorder(out) as rec:
        rec.begin_episode({"task": "two_rods"}, StaticScene(rod_radius=0.02, rod_node_offsets=[0, 5, 9],
                                                            rod_names=("base", "cross")))
        for k in range(4):
            rec.log_step(control_step=k, sim_time=0.01 * k, node_pos=_chain(k), m1=np.tile([0.0, 0.0, 1.0], (8, 1)))
        rec.end_episode()
        rec.begin_episode({"task": "one_rod"}, StaticScene(rod_radius=0.02))  # the next episode: one rod
        for k in range(2):
            rec.log_step(control_step=k, sim_time=0.01 * k, node_pos=_chain(k)[:5])
        rec.end_episode()
    verify(out)
    two, one = read_recording(out)
    np.testing.assert_array_equal(two.scene.rod_node_offsets, [0, 5, 9])
    assert two.scene.rod_node_offsets.dtype == np.int64 and two.scene.rod_names == ("base", "cross")
    np.testing.assert_array_equal(two.rod_node_offsets, [0, 5, 9])
    np.testing.assert_allclose(two.positions[3], _chain(3), atol=1e-6)
    # in the file, one line strip per rod (the rerun viewer draws no line across the joint) and no frame arrow on
    # the joint edge (edge 4, between node 4 of "base" and node 5 of "cross")
    import rerun as rr

    reader = rr.chunk.RrdReader(str(out))
    store = next(e for e in reader.recordings() if e.recording_id == two.recording_id)
    strips = []
    for chunk in reader.stream(store=store).to_chunks():
        if chunk.entity_path.lstrip("/") == "world/rod" and not chunk.is_static:
            strips += chunk.to_record_batch().column("LineStrips3D:strips").to_pylist()
    assert [len(s) for s in strips] == [2, 2, 2, 2] and [len(p) for p in strips[0]] == [5, 4]
    assert np.allclose(two.m1[0][4], 0.0) and np.allclose(two.m1[0][3], [0.0, 0.0, 1.0])
    assert "node_offsets" not in two.meta and "names" not in two.meta  # the layout is not episode metadata
    assert one.scene.rod_node_offsets is None and one.scene.rod_names == ()
    np.testing.assert_array_equal(one.rod_node_offsets, [0, 5])


def test_a_recording_without_a_layout_is_one_rod():
    ep = read_recording(EXAMPLES / "follow_target.rrd")[0]  # written before the layout was stored
    assert ep.scene.rod_node_offsets is None
    np.testing.assert_array_equal(ep.rod_node_offsets, [0, ep.positions.shape[1]])


def test_bad_layouts_are_refused(tmp_path):
    for off, names, what in (([0, 5], ("a", "b"), "2 names for 1 rods"), ([1, 5, 9], (), "starting at 0"),
                             ([0, 5, 6], (), "at least 2 nodes"), (None, ("a", "b"), "need rod_node_offsets")):
        with pytest.raises(RecordingError, match=what):
            StaticScene(rod_node_offsets=off, rod_names=names).validated()
    with Recorder(tmp_path / "bad.rrd") as rec:
        rec.begin_episode({}, StaticScene(rod_node_offsets=[0, 5, 10]))
        with pytest.raises(RecordingError, match="end at 10"):
            rec.log_step(control_step=0, sim_time=0.0, node_pos=_chain(0))
        rec.end_episode()


def test_task_recordings_carry_the_models_rod_layout():
    """``rodlab record`` of a task on a scene of several rods stores the model's layout with every episode."""
    import types

    from policies.recording.probe import task_static_scene
    from sim import build_model, load_scene

    model = build_model(load_scene(REPO / "assets" / "scenes" / "two_rods.toml"))
    sc = task_static_scene(types.SimpleNamespace(model=model), 0).validated()
    np.testing.assert_array_equal(sc.rod_node_offsets, [0, 21, 42])
    assert sc.rod_names == ("base", "cross") and len(sc.box_centers) == 1  # the floor plane kept
