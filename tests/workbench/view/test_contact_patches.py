"""Contact patches (workbench.view.contact_patches): neighbouring contact rows make one patch labelled with its total
force, separate touches get one label each, and a patch carrying a noise-sized force gets none."""
from __future__ import annotations

import numpy as np
import pytest

from workbench.view.contact_patches import LABEL_FRACTION, labelled, patches, reach_of


def test_neighbouring_rows_are_one_patch_and_far_ones_another():
    # a rod along x with edges of 5 cm: rows on edges 2-5 (one touch) and 14-15 (another), the latter weaker
    pts = np.array([[0.05 * j + 0.025, 0.0, 0.0] for j in (2, 3, 4, 5, 14, 15)])
    f = np.array([[0, 0, 3.0], [0, 0, 5.0], [0, 0, 4.0], [0, 0, 1.0], [0, 0, 0.5], [0, 0, 0.7]])
    x = np.array([[0.05 * i, 0.0, 0.0] for i in range(21)])
    assert reach_of(x) == pytest.approx(0.075)
    found = patches(pts, f, reach_of(x))
    assert [q.rows.tolist() for q in found] == [[0, 1, 2, 3], [4, 5]]
    np.testing.assert_allclose(found[0].force, [0, 0, 13.0])
    assert found[0].main_row == 1 and found[1].main_row == 5
    assert labelled(found, 6) == found and labelled(found, 1) == found[:1]


def test_a_noise_sized_patch_gets_no_label():
    pts = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    f = np.array([[187.0, 0, 0], [5e-5, 0, 0], [0.0, 0, 0]])
    found = patches(pts, f, 0.1)
    assert len(found) == 3
    assert labelled(found, 6) == found[:1]
    at = patches(pts[:2], [[1.0, 0, 0], [LABEL_FRACTION, 0, 0]], 0.1)
    below = patches(pts[:2], [[1.0, 0, 0], [0.99 * LABEL_FRACTION, 0, 0]], 0.1)
    assert len(labelled(at, 6)) == 2 and len(labelled(below, 6)) == 1
    assert patches(np.zeros((0, 3)), np.zeros((0, 3)), 0.1) == [] and labelled([], 6) == []


def test_two_rods_at_rest_read_one_label_per_touch(tmp_path):
    """assets/scenes/two_rods.toml at rest: 35 contact rows make four patches, each labelled with its total: the base
    on the floor (its weight and what the crossing rod adds), the crossing (the force the rods press each other with,
    one side of each pair), and the crossing rod's two ends on the floor; the forces balance both rods' weights."""
    from pathlib import Path

    from workbench.serve.app import WorkbenchApp
    from workbench.session.core import Workbench

    scene = Path(__file__).resolve().parents[3] / "assets" / "scenes" / "two_rods.toml"
    app = WorkbenchApp(Workbench.from_path(scene), port=0, env_map=False, wait_for_browser=False,
                       recordings_dir=tmp_path / "r", scenes_dir=tmp_path / "s")
    try:
        wb = app.wb
        wb.set_playing(False)
        for _ in range(150):
            wb.step()
        fr = wb.frame()
        assert len(fr.contact_points) > 20
        found = patches(fr.contact_points, fr.contact_forces, reach_of(fr.node_pos), fr.contact_obstacle,
                        fr.contact_edge, fr.contact_partner_edge)
        assert len(found) == 4
        weight = 9.8 * float(wb.live.model.node_mass.sum())
        base_w = 9.8 * float(wb.live.model.node_mass[:21].sum())
        floor = [q for q in found if (fr.contact_obstacle[q.rows] >= 0).all()]
        crossing = [q for q in found if (fr.contact_obstacle[q.rows] < 0).all()]
        assert len(floor) == 3 and len(crossing) == 1
        assert sum(q.force[2] for q in floor) == pytest.approx(weight, rel=1e-2)
        on_base = floor[0].force[2] - base_w  # the largest floor patch is under the base: what the crossing adds
        assert crossing[0].magnitude == pytest.approx(on_base, rel=2e-2)
        app.view.render(fr)
        app.view.flush()
        texts = sorted(lab.text for lab in app.view.force_labels if lab.visible)
        assert texts == sorted(f"{q.magnitude:.3g} N" for q in found)
        # a recording's frame has no row data: grouped by distance alone, the crossing joins the base's patch
        assert len(patches(fr.contact_points, fr.contact_forces, reach_of(fr.node_pos))) == 3
    finally:
        app.stop()
