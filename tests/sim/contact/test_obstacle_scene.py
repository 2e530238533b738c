"""Obstacle/contact scene tables: validation errors naming file and key, bad meshes, TOML round trip of the
shipped scenes, and per-env obstacle poses in the State (set_pose / set_capsules) with rigid-motion invariance."""
from __future__ import annotations

import dataclasses
import math
import tomllib

import numpy as np
import pytest

from sim import Simulator, build_model
from sim.scene.obstacles import (
    BoxSpec,
    CapsuleSpec,
    ContactSpec,
    MeshSpec,
    SphereSpec,
    dump_obstacles,
    parse_contact,
    parse_obstacles,
    quat_to_matrix,
)
from sim.scene.spec import SceneError, dump_scene, load_scene
from tests.helpers.contact import accumulate, make_set
from tests.helpers.paths import REPO

SCENES = ["default", "mesh_course", "tight_obstacles_2d"]


@pytest.mark.parametrize("name", SCENES)
def test_shipped_scenes_round_trip(name, tmp_path):
    spec = load_scene(REPO / "assets" / "scenes" / f"{name}.toml")
    assert len(spec.obstacles) >= 4
    out = tmp_path / "elsewhere" / f"{name}.toml"   # another folder: mesh paths are rewritten relative to it
    out.parent.mkdir()
    dump_scene(spec, out)
    again = load_scene(out)
    assert again.obstacles == spec.obstacles and again.contact == spec.contact
    for a, b in zip(again.obstacles, spec.obstacles):
        assert getattr(a, "path", None) == getattr(b, "path", None)   # the same mesh file on disk


def test_dump_relative_to_other_dir(tmp_path):
    spec = load_scene(REPO / "assets" / "scenes" / "mesh_course.toml")
    lines = dump_obstacles(spec.obstacles, base_dir=tmp_path)
    doc = tomllib.loads("\n".join(lines))
    obs = parse_obstacles(doc["obstacle"], str(tmp_path / "x.toml"))
    assert obs == spec.obstacles


BAD = [
    ({"type": "cone", "radius": 1.0}, "obstacle[0].type"),
    ({"type": "capsule", "start": [0, 0, 0], "end": [1, 0, 0]}, "obstacle[0].radius"),
    ({"type": "capsule", "start": [0, 0, 0], "end": [1, 0, 0], "radius": -0.1}, "obstacle[0].radius"),
    ({"type": "sphere", "center": [0, 0], "radius": 0.1}, "obstacle[0].center"),
    ({"type": "sphere", "center": [0, 0, 0], "radius": 0.1, "colour": "red"}, "obstacle[0].colour"),
    ({"type": "plane", "point": [0, 0, 0], "normal": [0, 0, 0]}, "obstacle[0].normal"),
    ({"type": "box", "position": [0, 0, 0], "half_extents": [1, 0, 1]}, "obstacle[0].half_extents"),
    ({"type": "box", "position": [0, 0, 0], "half_extents": [1, 1, 1], "orientation": [0, 0, 0, 0]},
     "obstacle[0].orientation"),
    ({"type": "mesh", "file": "does_not_exist.stl"}, "does_not_exist.stl"),
    ({"type": "mesh", "file": "m.obj", "scale": 0.0}, "obstacle[0].scale"),
]


@pytest.mark.parametrize("table,key", BAD)
def test_bad_obstacle_tables_name_file_and_key(table, key, tmp_path):
    scene = str(tmp_path / "scene.toml")
    (tmp_path / "m.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(SceneError) as ei:
        parse_obstacles([table], scene)
    assert "scene.toml" in str(ei.value) and key in str(ei.value)


@pytest.mark.parametrize("content,problem", [
    ("this is not a mesh\x00\x01", "mesh"),
    ("# no faces\nv 0 0 0\nv 1 0 0\n", "no triangles"),
    ("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n", "non-finite"),
    ("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "zero area"),
])
def test_bad_mesh_files_give_clear_error(content, problem, tmp_path):
    f = tmp_path / "bad.obj"
    f.write_text(content)
    with pytest.raises(SceneError) as ei:
        parse_obstacles([{"type": "mesh", "file": "bad.obj"}], str(tmp_path / "s.toml"))
    msg = str(ei.value)
    assert "bad.obj" in msg and "obstacle[0].file" in msg
    assert problem in msg or "cannot read" in msg


def test_contact_table_defaults_and_errors():
    assert parse_contact(None, "s.toml") == ContactSpec()
    c = parse_contact({"friction": 0.4, "delta": 1e-3}, "s.toml")
    assert c.friction == 0.4 and c.delta == 1e-3 and c.stiffness == 1e6 and c.margin == 5e-2
    with pytest.raises(SceneError, match="contact.delta"):
        parse_contact({"delta": 0.0}, "s.toml")
    with pytest.raises(SceneError, match="contact.stiffnes"):
        parse_contact({"stiffnes": 1.0}, "s.toml")


def _rand_rot(rng):
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


@pytest.mark.parametrize("kind", ["capsule", "box", "mesh"])
def test_set_pose_rigid_motion_invariance(kind):
    """Moving obstacle and rod by the same rigid motion leaves energy unchanged and rotates the gradient.
    (No node sits exactly on the edge of a box face's outline: there the box contact switches between its
    per-node face form and the segment form, and round-off could pick either.)"""
    rng = np.random.default_rng(1)
    mesh = REPO / "assets" / "meshes" / "unit_box.obj"
    spec = {"capsule": CapsuleSpec((0.0, -0.3, 0.0), (0.0, 0.3, 0.0), 0.1),
            "box": BoxSpec((0.0, 0.0, 0.0), (0.1, 0.3, 0.2)),
            "mesh": MeshSpec("unit_box.obj", str(mesh), (0.2, 0.6, 0.4))}[kind]
    obs, cd = make_set([spec], 4, envs=2)
    x = np.array([[0.13, -0.1, -0.19], [0.151, -0.05, -0.05], [0.152, 0.0, 0.1], [0.17, 0.05, 0.25]])
    E0, g0, _ = accumulate(cd, x, e=0)
    assert E0 > 0
    q = _rand_rot(rng)
    R = quat_to_matrix(q)
    p = rng.normal(size=3)
    obs.set_pose(0, p, q, envs=[1])
    E1, g1, _ = accumulate(cd, x @ R.T + p, e=1)
    assert E1 == pytest.approx(E0, rel=1e-9)
    np.testing.assert_allclose(g1, g0 @ R.T, atol=1e-9 * np.abs(g0).max())
    E0b, _, _ = accumulate(cd, x, e=0)  # env 0 untouched
    assert E0b == E0


def test_set_capsules_vectorised_and_validated():
    """Capsules re-placed per env in the State's arrays; the step derives their world arrays; a reset puts the
    envs' obstacles back at the scene's poses; the geometry is the Model's, shared by every state and copy."""
    specs = [CapsuleSpec((0, 0, 0), (0, 0, 1), 0.03) for _ in range(8)] + [SphereSpec((5, 5, 5), 0.1)]
    arm = load_scene(REPO / "assets" / "scenes" / "arm.toml")
    sim = Simulator(build_model(dataclasses.replace(arm, obstacles=tuple(specs))), envs=6)
    state = sim.reset()
    rng = np.random.default_rng(0)
    a = rng.uniform(-1, 1, size=(3, 8, 3))
    b = a + rng.normal(size=(3, 8, 3))
    sim.set_capsules(state, [1, 3, 5], a, b, 0.05)
    np.testing.assert_array_equal(state.obstacle_a[[1, 3, 5], :8], a)
    assert np.all(state.obstacle_radius[[1, 3, 5], :8] == 0.05) and np.all(state.obstacle_radius[0, :8] == 0.03)
    cd = sim.contact_data(state)  # the world arrays the kernels read, derived from the poses
    np.testing.assert_allclose(cd.p0[[1, 3, 5], :8], a)
    np.testing.assert_allclose(cd.p1[[1, 3, 5], :8], b)
    np.testing.assert_allclose(cd.box[1, :8, 0], np.minimum(a[0], b[0]) - 0.05)
    with pytest.raises(ValueError, match="shape"):
        sim.set_capsules(state, [0], a, b, 0.05)
    with pytest.raises(ValueError, match="radius"):
        sim.set_capsules(state, [0], a[:1], b[:1], -1.0)
    sim.reset_envs(state, None, [1])
    np.testing.assert_allclose(sim.contact_data(state).p1[1, 0], [0, 0, 1])
    np.testing.assert_allclose(sim.contact_data(state).p1[3, :8], b[1])  # the other envs keep theirs
    snap = state.copy()
    sim.set_obstacle_pose(state, 8, (0.0, 0.0, 1.0))
    assert not np.array_equal(snap.obstacle_position, state.obstacle_position)  # a copy has its own poses
    assert sim.model.obstacles.tri is Simulator(sim.model, envs=2).model.obstacles.tri


def test_quaternion_matrix_is_rotation():
    R = quat_to_matrix(np.array([math.cos(0.3), 0.0, 0.0, math.sin(0.3)]))
    np.testing.assert_allclose(R @ [1, 0, 0], [math.cos(0.6), math.sin(0.6), 0], atol=1e-12)
