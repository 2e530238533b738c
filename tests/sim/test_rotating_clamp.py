"""Rotating clamps ([[fix]] with angular_velocity, docs/physics.md §3.6): the fixed nodes and twist edges turn
rigidly at ω about the centre, exactly (positions and material frame), in 3-D and 2-D; a stiff rod follows as a
rigid body, a twisted one turns along; the checks name what is wrong; the TOML round trip keeps it."""
from __future__ import annotations

import dataclasses
import math
import tomllib

import numpy as np
import pytest

from sim import FixSpec, Simulator, build_model, parse_scene
from sim.geometry.rotations import matrix_from_rotvec as rotation_matrix
from sim.scene.spec import SceneError, scene_to_toml
from tests.helpers.rodspec import make_spec


def _clamped(fix: FixSpec, *, E=1e6, mode="3d", damping=2.0, direction=(1.0, 0.0, 0.0)):
    spec = make_spec(nodes=11, length=0.5, radius=0.01, E=E, clamp="none", dt=0.01, damping=damping, mode=mode,
                     direction=direction)
    spec = dataclasses.replace(spec, fixes=(fix,))
    sim = Simulator(build_model(spec))
    return sim, sim.reset(), sim.make_control()


def test_the_clamp_turns_rigidly_about_its_centre_and_a_stiff_rod_follows():
    """ω = π/2 rad/s about z through node 0 for 1 s: the clamped edge lies along +y to round-off, its material frame
    is the turned one, its nodes move at ω × r; a stiff rod (E = 1e9) turned slowly stays straight behind it."""
    w = 0.5 * math.pi
    fix = FixSpec(nodes=(0, 1), twist_edges=(0,), angular_velocity=(0.0, 0.0, w), stop=1.0)
    sim, st, ctrl = _clamped(fix, E=1e9, damping=5.0)
    x0 = st.node_pos[0].copy()
    m1_0, m2_0, _ = (a[0, 0].copy() for a in sim.material_frames(st))
    for _ in range(100):
        assert sim.step(st, ctrl).converged.all()
    R = rotation_matrix([0.0, 0.0, w])
    np.testing.assert_allclose(st.node_pos[0, :2], x0[:2] @ R.T, atol=1e-14)
    m1, m2, _ = (a[0, 0] for a in sim.material_frames(st))
    np.testing.assert_allclose(m1, R @ m1_0, atol=1e-12)
    np.testing.assert_allclose(m2, R @ m2_0, atol=1e-12)
    v = st.node_vel[0, 1]  # the last step's prescribed velocity: the chord of the turn over the step
    np.testing.assert_allclose(np.linalg.norm(v), 0.05 * 2.0 * math.sin(0.5 * w * 0.01) / 0.01, rtol=1e-9)
    for _ in range(100):  # the clamp stopped: the rod settles along +y
        sim.step(st, ctrl)
    np.testing.assert_allclose(st.node_pos[0, -1], [0.0, 0.5, 0.0], atol=2e-3)
    np.testing.assert_allclose(st.node_pos[0, :2], x0[:2] @ R.T, atol=1e-14)  # held after the window


def test_a_clamp_turning_about_the_rod_twists_it_along():
    """ω along the rod's own axis: the clamp's nodes stay where they are, its edge's material frame turns by ω t
    exactly, and the twist travels to the free end, which turns along once it has settled."""
    w = 0.5 * math.pi
    fix = FixSpec(nodes=(0, 1), twist_edges=(0,), angular_velocity=(w, 0.0, 0.0), stop=1.0)
    sim, st, ctrl = _clamped(fix)
    x0 = st.node_pos[0].copy()
    m1_0 = sim.material_frames(st)[0][0].copy()
    for _ in range(100):
        sim.step(st, ctrl)
    np.testing.assert_allclose(st.node_pos[0], x0, atol=1e-12)
    R = rotation_matrix([w, 0.0, 0.0])
    m1 = sim.material_frames(st)[0][0]
    np.testing.assert_allclose(m1[0], R @ m1_0[0], atol=1e-12)
    for _ in range(300):
        sim.step(st, ctrl)
    np.testing.assert_allclose(sim.material_frames(st)[0][0, -1], R @ m1_0[-1], atol=1e-3)


def test_the_planar_clamp_turns_in_its_plane():
    w = -0.25 * math.pi  # about y: +x turns towards +z (a quarter turn in the 2 s window)
    fix = FixSpec(nodes=(0, 1), angular_velocity=(0.0, w, 0.0), stop=2.0)
    sim, st, ctrl = _clamped(fix, mode="2d")
    x0 = st.node_pos[0].copy()
    for _ in range(200):
        sim.step(st, ctrl)
    R = rotation_matrix([0.0, 2.0 * w, 0.0])  # 2 s at ω
    np.testing.assert_allclose(st.node_pos[0, :2], x0[:2] @ R.T, atol=1e-14)
    assert st.node_pos[0, 1, 2] == pytest.approx(0.05, abs=1e-14)  # edge 0 now points up


@pytest.mark.parametrize("fix, message", [
    (FixSpec(nodes=(0, 1), axes="xy", angular_velocity=(0.0, 0.0, 1.0)), "axes"),
    (FixSpec(nodes=(0, 1), velocity=(0.1, 0.0, 0.0), angular_velocity=(0.0, 0.0, 1.0)), "no velocity"),
    (FixSpec(nodes=(0, 1), twist_edges=(1,), angular_velocity=(0.0, 0.0, 1.0)), "both its nodes"),
    (FixSpec(nodes=(0, 1), angular_velocity=(0.0, 0.0, float("nan"))), "angular_velocity"),
])
def test_a_rotating_fix_that_cannot_turn_rigidly_is_refused_by_name(fix, message):
    spec = dataclasses.replace(make_spec(nodes=11, clamp="none"), fixes=(fix,))
    with pytest.raises(SceneError, match=message):
        build_model(spec)


def test_a_planar_fix_turns_about_y_only():
    spec = dataclasses.replace(make_spec(nodes=11, clamp="none", mode="2d"),
                               fixes=(FixSpec(nodes=(0, 1), angular_velocity=(0.0, 0.0, 1.0)),))
    with pytest.raises(SceneError, match="ω along y"):
        build_model(spec)


def test_round_trip():
    fix = FixSpec(nodes=(0, 1), twist_edges=(0,), angular_velocity=(0.0, 0.0, 1.5), center=(0.0, 0.0, 0.1),
                  start=0.5, stop=2.0)
    spec = dataclasses.replace(make_spec(nodes=11, clamp="none"), fixes=(fix,))
    back = parse_scene(tomllib.loads(scene_to_toml(spec)))
    assert back.fixes == (fix,)
    sim = Simulator(build_model(spec))
    assert sim.model.rotating_fixes[0].center.tolist() == [0.0, 0.0, 0.1]
