"""The teleop's five control points scale with the rod: the paper's nodes 2, 6, 10, 14, 18 on its 21-node arm, spread
from node 2 to N − 3 on any other rod (a 9-node rod opens in the workbench; a 41-node rod's sliders bend all of it),
the sliders name the nodes of the rod they steer, and a rod too short for five points is refused by name before the
open scene changes."""
from __future__ import annotations

import numpy as np
import pytest

from sim.scene.spec import dump_scene
from tests.helpers.rodspec import make_spec
from workbench.session.teleop import CONTROL_NODES, control_points


def _scene(tmp_path, nodes):
    p = tmp_path / f"rod_{nodes}.toml"
    dump_scene(make_spec(nodes=nodes, dt=0.02, gravity=(0.0, 0.0, -9.8), max_iter=30), p)
    return p


def test_control_points_spread_over_the_rod():
    assert control_points(21) == CONTROL_NODES == (2, 6, 10, 14, 18)
    assert control_points(41) == (2, 11, 20, 29, 38)
    assert control_points(9) == (2, 3, 4, 5, 6)
    assert control_points(7) == (1, 2, 3, 4, 5)
    for n in range(7, 200):
        cp = control_points(n)
        assert len(set(cp)) == 5 and list(cp) == sorted(cp) and cp[0] >= 1 and cp[-1] <= n - 2, (n, cp)
    with pytest.raises(ValueError, match="at least 7 nodes, this rod has 6"):
        control_points(6)


@pytest.mark.parametrize("nodes", [9, 41])
def test_a_rod_of_any_length_opens_and_its_sliders_bend_it_where_they_say(tmp_path, nodes):
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    app = WorkbenchApp(Workbench.from_path(_scene(tmp_path, nodes)), port=0, env_map=False, wait_for_browser=False,
                       scenes_dir=tmp_path / "scenes", recordings_dir=tmp_path / "rec").start()
    try:
        cp = control_points(nodes)
        labels = [app.controls.sliders[k][0].label for k in range(5)]
        assert labels == [f"κ1 at node {c} [rad]" for c in cp]
        wb = app.wb
        wb.set_playing(False)
        wb.set_teleop_value(4, 0, 0.5)       # the last control point
        wb.step()
        kb = np.asarray(wb.live.ctrl.kappa_bar[0, :, 0])
        assert abs(kb[cp[4]]) > 0 and kb[cp[0]] == 0.0 and kb[cp[2]] == 0.0   # bent in the last point's region
    finally:
        app.stop()


def test_a_rod_too_short_is_refused_before_the_open_scene_changes(tmp_path):
    from workbench.session.core import Workbench

    with pytest.raises(ValueError, match=r"rod_5\.toml: rod 'rod': .*at least 7 nodes, this rod has 5"):
        Workbench.from_path(_scene(tmp_path, 5))
    wb = Workbench.builtin()
    with pytest.raises(ValueError, match="at least 7 nodes"):
        wb.load_scene(_scene(tmp_path, 5))
    assert wb.live.n_nodes == 21 and wb.teleop.control_nodes() == CONTROL_NODES


def test_choosing_another_rod_names_its_control_points(tmp_path):
    """Two rods of 21 and 9 nodes: the Rod dropdown's choice relabels the sliders with that rod's control points."""
    from sim.scene.spec import parse_scene
    from tools.browser import wait_for
    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    rod = dict(length=1.0, radius=0.02, density=1000.0, youngs_modulus=1e6, poisson_ratio=0.5, direction=[1, 0, 0])
    doc = {"sim": dict(dt=0.02, gravity=[0, 0, -9.8], newton_tol=1e-6, newton_max_iter=30, accept_unconverged=True),
           "rod": [dict(rod, name="a", nodes=21, start=[0, 0, 0]), dict(rod, name="b", nodes=9, start=[0, 0.5, 0])]}
    path = tmp_path / "two.toml"
    dump_scene(parse_scene(doc), path)
    app = WorkbenchApp(Workbench.from_path(path), port=0, env_map=False, wait_for_browser=False,
                       scenes_dir=tmp_path / "scenes", recordings_dir=tmp_path / "rec").start()
    try:
        first = [f"κ1 at node {c} [rad]" for c in control_points(21)]
        assert [app.controls.sliders[k][0].label for k in range(5)] == first
        app.controls.rod.value = "b"
        want = [f"κ1 at node {c} [rad]" for c in control_points(9)]
        wait_for(lambda: [app.controls.sliders[k][0].label for k in range(5)] == want, what="the sliders relabelled")
        assert app.wb.teleop.control_nodes() == tuple(21 + c for c in control_points(9))
    finally:
        app.stop()
