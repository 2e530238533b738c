"""Recorder -> .rrd -> reader round trip with synthetic numpy data of the documented shapes."""
from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from policies.recording import Recorder, RecordingError, StaticScene, read_recording
from policies.recording.reader import list_episodes

N = 21
F32 = dict(rtol=1e-6, atol=1e-6)      # stored as float32


def _scene(rng) -> StaticScene:
    v = rng.random((5, 3))
    return StaticScene(rod_radius=0.05, capsules=rng.random((3, 2, 3)), capsule_radii=np.full(3, 0.03),
                       sphere_centers=rng.random((2, 3)), sphere_radii=[0.1, 0.2],
                       box_centers=[[0.5, 0.0, 0.2]], box_half_sizes=[[0.1, 0.2, 0.3]],
                       box_quats=[[0.0, 0.0, np.sin(0.3), np.cos(0.3)]],
                       meshes=((v, np.array([[0, 1, 2], [0, 2, 3], [1, 3, 4]])),))


def _frame(rng, k: int, *, contacts: bool = True) -> dict:
    c = (k % 4) if contacts else 0
    return dict(node_pos=rng.normal(size=(N, 3)), m1=rng.normal(size=(N - 1, 3)), m2=rng.normal(size=(N - 1, 3)),
                d1=rng.normal(size=(N - 1, 3)), d2=rng.normal(size=(N - 1, 3)),
                contact_points=rng.normal(size=(c, 3)), contact_normals=rng.normal(size=(c, 3)),
                contact_normal_force=rng.random(c) * 80.0, contact_friction=rng.normal(size=(c, 3)),
                contact_edge=rng.integers(0, N - 1, c), contact_obstacle=rng.integers(-1, 3, c),
                contact_partner_edge=rng.integers(-1, N - 1, c),
                kappa_bar=rng.normal(size=(N, 2)), kappa=rng.normal(size=(N, 2)), tau_bar=rng.normal(size=N),
                tau=rng.normal(size=N), target_pos=rng.normal(size=3), target_quat=rng.normal(size=4),
                scalars={"reward": float(rng.normal()), "reward_terms/distance": float(rng.normal()),
                         "tip_error": float(rng.random()), "energy/stretch": float(rng.random()),
                         "energy/bend": float(rng.random()), "energy/twist": float(rng.random()),
                         "energy/contact": float(rng.random()), "solver/newton_iters": float(rng.integers(1, 6)),
                         "solver/residual": float(rng.random() * 1e-3), "solver/converged": 1.0,
                         "solver/wall_time": float(rng.random() * 1e-3)})


def _check_frame(ep, k: int, d: dict) -> None:
    np.testing.assert_allclose(ep.positions[k], d["node_pos"], **F32)
    for key in ("m1", "m2", "d1", "d2"):
        np.testing.assert_allclose(getattr(ep, key)[k], d[key], **F32)
    c = len(d["contact_normal_force"])
    assert ep.contact_count[k] == c
    np.testing.assert_allclose(ep.contact_points[k, :c], d["contact_points"], **F32)
    np.testing.assert_allclose(ep.contact_normals[k, :c], d["contact_normals"], **F32)
    np.testing.assert_allclose(ep.contact_normal_force[k, :c], d["contact_normal_force"], rtol=0, atol=0)
    np.testing.assert_allclose(ep.contact_friction[k, :c], d["contact_friction"], **F32)
    np.testing.assert_array_equal(ep.contact_edge[k, :c], d["contact_edge"])
    np.testing.assert_array_equal(ep.contact_obstacle[k, :c], d["contact_obstacle"])
    np.testing.assert_array_equal(ep.contact_partner_edge[k, :c], d["contact_partner_edge"])
    assert np.all(ep.contact_edge[k, c:] == -1)
    np.testing.assert_allclose(ep.kappa_bar[k], d["kappa_bar"], **F32)
    np.testing.assert_allclose(ep.kappa[k], d["kappa"], **F32)
    np.testing.assert_allclose(ep.tau_bar[k], d["tau_bar"], **F32)
    np.testing.assert_allclose(ep.tau[k], d["tau"], **F32)
    np.testing.assert_allclose(ep.target_pos[k], d["target_pos"], **F32)
    np.testing.assert_allclose(ep.target_quat[k], d["target_quat"], **F32)
    for name, v in d["scalars"].items():
        assert ep.scalars[name][k] == v          # scalars are float64: exact


def test_round_trip_batched_envs_and_episodes(tmp_path, verify):
    rng = np.random.default_rng(1)
    out = tmp_path / "run.rrd"
    scene = _scene(rng)
    truth: dict[int, list] = {}
    with Recorder(out) as rec:
        # two envs interleaved, env 0 runs two episodes of different lengths
        ep0 = rec.begin_episode({"task": "rodlab/FollowTarget-v0", "seed": 7, "policy": "random"}, scene, env=0)
        ep1 = rec.begin_episode({"task": "rodlab/FollowTarget-v0", "seed": 7, "policy": "random"}, scene, env=1)
        truth[ep0], truth[ep1] = [], []
        for k in range(12):
            for e, idx in ((0, ep0), (1, ep1)):
                d = _frame(rng, k)
                rec.log_step(env=e, control_step=k, sim_time=0.1 * k, **d)
                truth[idx].append(d)
        rec.end_episode(env=0)
        ep2 = rec.begin_episode({"task": "rodlab/FollowTarget-v0", "seed": 7, "policy": "random"},
                                StaticScene(rod_radius=0.04), env=0)
        truth[ep2] = []
        for k in range(5):
            d = _frame(rng, k, contacts=False)
            rec.log_step(env=0, control_step=k, sim_time=0.1 * k, **d)
            truth[ep2].append(d)
        s2 = rec.end_episode(env=0)
        s1 = rec.end_episode(env=1)
        assert not out.exists()                  # nothing under the final name before close
    assert out.exists()
    verify(out)
    assert len(list_episodes(out)) == 3
    eps = read_recording(out)
    assert [int(e.meta["episode"]) for e in eps] == [0, 1, 2]
    assert [int(e.meta["env"]) for e in eps] == [0, 1, 0]
    for ep in eps:
        frames = truth[int(ep.meta["episode"])]
        assert ep.steps == len(frames)
        np.testing.assert_array_equal(ep.control_step, np.arange(len(frames)))
        np.testing.assert_allclose(ep.sim_time, 0.1 * np.arange(len(frames)), atol=1e-9)
        for k, d in enumerate(frames):
            _check_frame(ep, k, d)
        assert ep.meta["task"] == "rodlab/FollowTarget-v0" and ep.meta["seed"] == 7
        assert ep.meta["policy"] == "random"
        for key in ("rodlab_version", "git_commit", "created_utc"):
            assert isinstance(ep.meta[key], str) and ep.meta[key]
        ret = sum(d["scalars"]["reward"] for d in frames)
        assert ep.episode_return == pytest.approx(ret)
        fmax = max((float(np.max(d["contact_normal_force"])) for d in frames if len(d["contact_normal_force"])),
                   default=0.0)
        assert ep.max_contact_force == pytest.approx(fmax)
    assert s1["steps"] == 12 and s2["steps"] == 5
    # static scene round trip
    sc = eps[0].scene
    np.testing.assert_allclose(sc.capsules, scene.capsules)
    np.testing.assert_allclose(sc.capsule_radii, scene.capsule_radii, rtol=1e-6)
    np.testing.assert_allclose(sc.sphere_centers, scene.sphere_centers, **F32)
    np.testing.assert_allclose(sc.sphere_radii, scene.sphere_radii)
    np.testing.assert_allclose(sc.box_centers, scene.box_centers, **F32)
    np.testing.assert_allclose(sc.box_half_sizes, scene.box_half_sizes, **F32)
    np.testing.assert_allclose(sc.box_quats, scene.box_quats)
    np.testing.assert_allclose(sc.meshes[0][0], scene.meshes[0][0], **F32)
    np.testing.assert_array_equal(sc.meshes[0][1], scene.meshes[0][1])
    assert eps[2].scene.rod_radius == pytest.approx(0.04) and eps[2].scene.capsules is None
    assert eps[2].contact_count is not None and not eps[2].contact_count.any()


def test_sim_step_frames_and_sparse_scalars(tmp_path, verify):
    """Per-sim-step frames share a control_step; scalars missing on a frame read back as NaN."""
    rng = np.random.default_rng(2)
    out = tmp_path / "sub.rrd"
    pos = []
    with Recorder(out) as rec:
        rec.begin_episode({"task": "t"}, None)
        for j in range(9):
            p = rng.normal(size=(N, 3))
            pos.append(p)
            sc = {"energy/bend": float(j)}
            if j % 3 == 0:
                sc["reward"] = float(j) * 0.5
            rec.log_step(control_step=(j + 2) // 3, sim_step=j, sim_time=0.05 * j, node_pos=p, scalars=sc,
                         kappa_bar=rng.normal(size=N))
        rec.end_episode()
    verify(out)
    (ep,) = read_recording(out)
    np.testing.assert_array_equal(ep.sim_step, np.arange(9))
    np.testing.assert_array_equal(ep.control_step, [(j + 2) // 3 for j in range(9)])
    np.testing.assert_allclose(ep.positions, np.stack(pos), **F32)
    np.testing.assert_array_equal(ep.scalars["energy/bend"], np.arange(9.0))
    r = ep.scalars["reward"]
    assert np.all(np.isnan(r[[1, 2, 4, 5, 7, 8]])) and list(r[[0, 3, 6]]) == [0.0, 1.5, 3.0]
    assert ep.episode_return == pytest.approx(4.5)
    assert ep.kappa_bar.shape == (9, N, 1) and ep.kappa is None and ep.m1 is None
    assert ep.contact_count is None and ep.max_contact_force == 0.0


@pytest.mark.parametrize("bad, match", [
    (dict(node_pos=np.zeros((N, 2))), r"node_pos: expected shape \(21, 3\), got \(21, 2\)"),
    (dict(m1=np.zeros((N, 3))), r"m1: expected shape \(20, 3\)"),
    (dict(contact_points=np.zeros((2, 3))), "contacts need"),
    (dict(contact_points=np.zeros((2, 3)), contact_normals=np.zeros((2, 3)), contact_normal_force=np.zeros(3)),
     r"contact_normal_force: expected shape \(2\)"),
    (dict(kappa=np.zeros((N, 3))), "kappa: expected"),
    (dict(target_quat=np.zeros(4)), "target_quat needs target_pos"),
    (dict(scalars={"bad name": 1.0}), "scalar name"),
    (dict(scalars={"reward": "x"}), "not a number"),
    (dict(node_pos=np.full((N, 3), np.nan)), "NaN"),
])
def test_bad_frames_are_rejected_with_the_field_named(tmp_path, bad, match):
    with Recorder(tmp_path / "bad.rrd") as rec:
        rec.begin_episode({"task": "t"}, None)
        rec.log_step(control_step=0, sim_time=0.0, node_pos=np.zeros((N, 3)))
        kw = dict(control_step=1, sim_time=0.1, node_pos=np.zeros((N, 3)))
        kw.update(bad)
        with pytest.raises(RecordingError, match=match):
            rec.log_step(**kw)
        rec.end_episode()
    (ep,) = read_recording(tmp_path / "bad.rrd")
    assert ep.steps == 1                         # the rejected frame left no trace


def test_protocol_errors(tmp_path):
    with pytest.raises(RecordingError, match="must end in .rrd"):
        Recorder(tmp_path / "x.txt")
    rec = Recorder(tmp_path / "p.rrd")
    with pytest.raises(RecordingError, match="no open episode"):
        rec.log_step(control_step=0, sim_time=0.0, node_pos=np.zeros((N, 3)))
    rec.begin_episode({"task": "t"})
    with pytest.raises(RecordingError, match="already has an open episode"):
        rec.begin_episode({"task": "t"})
    rec.log_step(control_step=3, sim_time=0.3, node_pos=np.zeros((N, 3)))
    with pytest.raises(RecordingError, match="went backwards"):
        rec.log_step(control_step=2, sim_time=0.4, node_pos=np.zeros((N, 3)))
    with pytest.raises(RecordingError, match="already logged"):
        rec.log_step(control_step=3, sim_time=0.3, node_pos=np.zeros((N, 3)))
    with pytest.raises(RecordingError, match="metadata key"):
        rec.begin_episode({"bad key": 1}, env=5)
    with pytest.raises(RecordingError, match="capsules"):
        rec.begin_episode({}, StaticScene(capsules=np.zeros((2, 3))), env=6)
    rec.abort()
    assert not (tmp_path / "p.rrd").exists()
    assert list(tmp_path.iterdir()) == []       # no part folder left behind


def test_exception_discards_by_default_and_keep_writes_finished(tmp_path, verify):
    out = tmp_path / "e.rrd"
    with pytest.raises(ZeroDivisionError):
        with Recorder(out) as rec:
            rec.begin_episode({"task": "t"})
            rec.log_step(control_step=0, sim_time=0.0, node_pos=np.zeros((N, 3)))
            rec.end_episode()
            1 / 0
    assert not out.exists() and list(tmp_path.iterdir()) == []
    with pytest.raises(ZeroDivisionError):
        with Recorder(out, on_error="keep") as rec:
            rec.begin_episode({"task": "t"})
            rec.log_step(control_step=0, sim_time=0.0, node_pos=np.ones((N, 3)))
            rec.end_episode()
            rec.begin_episode({"task": "t"})
            rec.log_step(control_step=0, sim_time=0.0, node_pos=np.ones((N, 3)))
            1 / 0
    verify(out)
    eps = read_recording(out)
    assert [e.meta["complete"] for e in eps] == [True, False]   # the open one was ended at close
    assert [p.name for p in tmp_path.iterdir()] == ["e.rrd"]


def test_overwrites_existing_file_atomically(tmp_path, verify):
    out = tmp_path / "o.rrd"
    out.write_bytes(b"old")
    with Recorder(out) as rec:
        rec.begin_episode({"task": "t"})
        assert out.read_bytes() == b"old"        # old content stays until close
        rec.log_step(control_step=0, sim_time=0.0, node_pos=np.zeros((N, 3)))
        rec.end_episode()
    verify(out)
    assert read_recording(out)[0].steps == 1


def test_reader_errors_name_the_file(tmp_path):
    with pytest.raises(RecordingError, match="no such recording"):
        read_recording(tmp_path / "missing.rrd")
    bad = tmp_path / "junk.rrd"
    bad.write_bytes(b"not an rrd file at all")
    with pytest.raises(RecordingError, match="junk.rrd"):
        read_recording(bad)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(n=st.integers(2, 30), counts=st.lists(st.integers(0, 5), min_size=1, max_size=12), seed=st.integers(0, 99))
def test_round_trip_any_size(tmp_path_factory, n, counts, seed):
    """Any node count and any per-frame contact counts (including none at all) read back exactly."""
    rng = np.random.default_rng(seed)
    out = tmp_path_factory.mktemp("h") / "h.rrd"
    frames = []
    with Recorder(out, blueprint=False) as rec:
        rec.begin_episode({"task": "t"})
        for k, c in enumerate(counts):
            d = dict(node_pos=rng.normal(size=(n, 3)), m1=rng.normal(size=(n - 1, 3)),
                     contact_points=rng.normal(size=(c, 3)), contact_normals=rng.normal(size=(c, 3)),
                     contact_normal_force=rng.random(c), scalars={"reward": float(rng.normal())})
            rec.log_step(control_step=k, sim_time=0.05 * k, **d)
            frames.append(d)
        rec.end_episode()
    (ep,) = read_recording(out)
    assert ep.positions.shape == (len(counts), n, 3)
    assert ep.contact_points.shape == (len(counts), max(counts), 3)
    np.testing.assert_array_equal(ep.contact_count, counts)
    for k, d in enumerate(frames):
        c = counts[k]
        np.testing.assert_allclose(ep.positions[k], d["node_pos"], **F32)
        np.testing.assert_allclose(ep.m1[k], d["m1"], **F32)
        np.testing.assert_allclose(ep.contact_points[k, :c], d["contact_points"], **F32)
        np.testing.assert_array_equal(ep.contact_normal_force[k, :c], d["contact_normal_force"])
        assert ep.scalars["reward"][k] == d["scalars"]["reward"]


def _threads() -> int:
    return len(os.listdir("/proc/self/task"))


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="counts threads through Linux /proc")
def test_finished_episodes_release_their_streams(tmp_path):
    """Each episode is a rerun stream with native threads; a recorder that ends many episodes (a workbench
    session recording for hours) must not keep them."""
    rng = np.random.default_rng(5)
    with Recorder(tmp_path / "warm.rrd") as rec:  # rerun's own start-up threads
        rec.begin_episode({"task": "t"}, None)
        rec.log_step(control_step=0, sim_time=0.0, node_pos=rng.normal(size=(N, 3)))
        rec.end_episode()
    before = _threads()
    out = tmp_path / "many.rrd"
    with Recorder(out) as rec:
        for k in range(30):
            rec.begin_episode({"task": "t", "seed": k}, None)
            for j in range(3):
                rec.log_step(control_step=j, sim_time=0.05 * j, node_pos=rng.normal(size=(N, 3)))
            rec.end_episode()
        during = _threads()
        rec.begin_episode({"task": "t"}, None)  # left open: closed (and released) by close()
        rec.log_step(control_step=0, sim_time=0.0, node_pos=rng.normal(size=(N, 3)))
    assert during - before < 6, f"{during - before} threads kept after 30 finished episodes"
    assert _threads() - before < 6
    assert len(list_episodes(out)) == 31


@pytest.mark.skipif(not os.path.isdir("/proc/self/task"), reason="counts threads through Linux /proc")
def test_every_file_gets_its_layout_and_files_keep_no_threads(tmp_path):
    """The viewer layout (blueprint) goes into every file; making it must not leave rerun threads behind."""
    import rerun as rr

    def one(path, planar: bool) -> None:
        with Recorder(path) as rec:
            rec.begin_episode({"task": "t"}, StaticScene(planar=planar))
            rec.log_step(control_step=0, sim_time=0.0, node_pos=np.zeros((N, 3)), scalars={"reward": 1.0})
            rec.end_episode()

    one(tmp_path / "warm.rrd", False)
    before = _threads()
    paths = [tmp_path / f"f{k}.rrd" for k in range(12)]
    for k, p in enumerate(paths):
        one(p, planar=k % 2 == 1)
    assert _threads() - before < 6
    for p in paths:
        assert [b.application_id for b in rr.chunk.RrdReader(str(p)).blueprints()] == ["rodlab"]
        assert len(read_recording(p)) == 1
