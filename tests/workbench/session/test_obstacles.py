"""Obstacle editing without a browser: add/move/delete, contact follows a move without a rebuild,
scene save/load round trip."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.session import obstacles as obst
from workbench.session.core import Workbench


@pytest.fixture
def wb():
    return Workbench.builtin()  # the arm without obstacles


def run(wb, n):
    for _ in range(n):
        wb.step()


def contact_count(wb) -> int:
    st = wb.live.last_stats
    return int(np.asarray(st.contact_count)[0]) if st is not None else 0


def test_add_move_into_rod_makes_contact_without_rebuild(wb):
    i = wb.add_obstacle(obst.ObstacleEdit(kind="sphere", position=(0.45, 0.0, 0.6), radius=0.08))
    run(wb, 5)
    assert contact_count(wb) == 0
    model = wb.live.model
    x_mid0 = wb.live.state.node_pos[0, 12].copy()
    # move the sphere so it overlaps the rod by 1 cm at z = 0.6: it pushes the rod towards -x
    wb.set_obstacle_pose(i, (0.12, 0.0, 0.6), (1.0, 0.0, 0.0, 0.0))
    run(wb, 20)
    assert wb.live.model is model  # no rebuild
    assert contact_count(wb) > 0
    assert wb.live.state.node_pos[0, 12, 0] < x_mid0[0] - 0.005


def test_rotated_capsule_pose_matches_a_rebuilt_scene(wb):
    """Pose through set_pose and the same pose baked into a rebuilt spec give the same contact."""
    i = wb.add_obstacle(obst.ObstacleEdit(kind="capsule", position=(0.5, 0.0, 0.5), radius=0.05, length=0.6))
    q = np.array([np.cos(np.pi / 8), 0.0, np.sin(np.pi / 8), 0.0])  # 45 deg about y
    wb.set_obstacle_pose(i, (0.11, 0.0, 0.55), q)
    run(wb, 10)
    tip_a = wb.tip
    wb2 = Workbench(obst.spec_with(wb.live.base_spec, wb.obstacles))
    run(wb2, 10)
    np.testing.assert_allclose(tip_a, wb2.tip, atol=1e-9)


def test_delete_and_save_load_round_trip(wb, tmp_path):
    wb.add_obstacle(obst.ObstacleEdit(kind="box", position=(0.4, 0.1, 0.3), half_extents=(0.05, 0.1, 0.2),
                                      wxyz=(0.9238795, 0.0, 0.0, 0.3826834), name="crate"))
    wb.add_obstacle(obst.ObstacleEdit(kind="sphere", position=(-0.4, 0.0, 0.7), radius=0.1, name="ball"))
    wb.add_obstacle(obst.ObstacleEdit(kind="capsule", position=(0.0, 0.5, 0.5), radius=0.03, name="bar"))
    wb.set_obstacle_pose(1, (-0.3, 0.2, 0.65), (1.0, 0.0, 0.0, 0.0))
    wb.delete_obstacle(2)
    assert [e.name for e in wb.obstacles] == ["crate", "ball"]
    path = wb.save_scene(tmp_path / "edited.toml")
    other = Workbench.from_path(path)
    assert [e.kind for e in other.obstacles] == ["box", "sphere"]
    np.testing.assert_allclose(other.obstacles[1].position, (-0.3, 0.2, 0.65))
    np.testing.assert_allclose(other.obstacles[0].half_extents, (0.05, 0.1, 0.2))
    np.testing.assert_allclose(np.abs(other.obstacles[0].wxyz @ wb.obstacles[0].wxyz), 1.0, atol=1e-6)
    wb.load_scene(path)
    assert len(wb.obstacles) == 2 and wb.frame_index == 0


def test_mesh_from_assets_is_added(wb):
    meshes = obst.mesh_catalogue()
    assert meshes, "assets/meshes has no mesh files"
    i = wb.add_obstacle(obst.ObstacleEdit(kind="mesh", mesh=str(obst.MESH_DIR / meshes[0]),
                                          position=(0.5, 0.0, 0.5)))
    v, f = obst.mesh_for_edit(wb.obstacles[i])
    assert v.shape[1] == 3 and len(f) > 0
    run(wb, 2)


def test_saved_mesh_scene_reloads_from_another_folder(wb, tmp_path):
    """A scene saved outside assets/ still finds its mesh (file written relative to the saved scene)."""
    meshes = obst.mesh_catalogue()
    wb.add_obstacle(obst.ObstacleEdit(kind="mesh", mesh=str(obst.MESH_DIR / meshes[0]), position=(0.5, 0.0, 0.5)))
    path = wb.save_scene(tmp_path / "deep" / "mine.toml")
    other = Workbench.from_path(path)
    assert [e.kind for e in other.obstacles][-1] == "mesh"
    np.testing.assert_allclose(other.obstacles[-1].position, (0.5, 0.0, 0.5))


def test_scene_with_a_moved_capsule_saves_and_loads(tmp_path):
    """The default scene has a capsule: saving it used to write ``np.float64(...)``, which no TOML reader loads."""
    from sim import load_scene
    from workbench.serve.cli import default_scene

    wb = Workbench.from_path(default_scene())
    i = next(k for k, e in enumerate(wb.obstacles) if e.kind == "capsule")
    wb.set_obstacle_pose(i, wb.obstacles[i].position + np.array([0.0, 0.05, 0.02]), wb.obstacles[i].wxyz)
    path = wb.save_scene(tmp_path / "moved.toml")
    assert "np." not in path.read_text()
    spec = load_scene(path)
    cap = spec.obstacles[i]
    np.testing.assert_allclose(0.5 * (np.array(cap.start) + np.array(cap.end)), wb.obstacles[i].position, atol=1e-12)
    other = Workbench.from_path(path)
    assert [e.kind for e in other.obstacles] == [e.kind for e in wb.obstacles]


def test_cylinder_is_edited_moved_resized_and_saved(wb, tmp_path):
    """A flat-ended cylinder goes through the editor like the other kinds: moved by set_pose (same contact as
    the pose baked into a rebuilt spec), resized, saved as a cylinder and loaded back."""
    from sim import load_scene

    i = wb.add_obstacle(obst.ObstacleEdit(kind="cylinder", position=(0.5, 0.0, 0.5), radius=0.05, length=0.6))
    q = np.array([np.cos(np.pi / 8), 0.0, np.sin(np.pi / 8), 0.0])  # 45 deg about y
    wb.set_obstacle_pose(i, (0.11, 0.0, 0.55), q)
    run(wb, 10)
    assert contact_count(wb) > 0
    tip_a = wb.tip
    wb2 = Workbench(obst.spec_with(wb.live.base_spec, wb.obstacles))
    run(wb2, 10)
    np.testing.assert_allclose(tip_a, wb2.tip, atol=1e-9)
    wb.resize_obstacle(i, (0.04, 0.5, 0.04))
    assert (wb.obstacles[i].radius, wb.obstacles[i].length) == (0.04, 0.5)
    path = wb.save_scene(tmp_path / "cyl.toml")
    cyl = load_scene(path).obstacles[-1]
    assert cyl.type == "cylinder" and cyl.radius == 0.04
    np.testing.assert_allclose(np.linalg.norm(np.subtract(cyl.end, cyl.start)), 0.5, atol=1e-12)
    np.testing.assert_allclose(0.5 * (np.array(cyl.start) + np.array(cyl.end)), (0.11, 0.0, 0.55), atol=1e-12)
    again = Workbench.from_path(path)
    assert again.obstacles[-1].kind == "cylinder"


def test_a_new_obstacle_is_placed_clear_of_the_rod_and_the_others_nearest_the_start_view():
    """``free_position``: a sphere asked for where the rod lies goes to the nearest grid point whose sphere keeps the
    clearance from every node and from the other obstacle, and no grid point nearer would do."""
    rod = np.stack([np.full(21, 0.4), np.zeros(21), np.linspace(0.0, 1.0, 21)], 1)  # through NEW_OBSTACLE_AT
    other = obst.ObstacleEdit(kind="sphere", position=(0.55, 0.0, 0.6), radius=0.05)
    e = obst.ObstacleEdit(kind="sphere", position=(0.0, 0.0, 0.0), radius=0.08)
    p = obst.free_position(e, rod, 0.02, [other])
    need = 0.08 + 0.02 + 0.03
    assert np.linalg.norm(rod - p, axis=1).min() > need
    assert obst.surface_distance(other, p[None])[0] > 0.08 + 0.03
    # every grid point nearer to the start view than p fails one of the two
    near = np.asarray(obst.NEW_OBSTACLE_AT)
    ax = np.arange(-0.8, 0.8 + 1e-9, 0.05)
    g = near + np.stack(np.meshgrid(ax, ax, ax, indexing="ij"), -1).reshape(-1, 3)
    g = g[np.linalg.norm(g - near, axis=1) < np.linalg.norm(p - near) - 1e-9]
    d_rod = np.linalg.norm(g[:, None, :] - rod[None], axis=2).min(axis=1)
    assert not np.any((d_rod > need) & (obst.surface_distance(other, g) > 0.08 + 0.03))
