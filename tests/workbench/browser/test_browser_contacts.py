"""Contacts: arrow lengths readable for small and large forces (log / auto / linear), the force in N written at the
largest contacts, the net contact force in the status line (real browser)."""
from __future__ import annotations

import re

import numpy as np
import pytest
from playwright.sync_api import expect

from tools.browser import WAIT_MS, wait_for
from workbench.view.scene import ARROW_MAX, arrow_vectors


def test_arrow_lengths():
    f = np.array([[1.0, 0, 0], [0, 20.0, 0], [0, 0, 240.0]])
    for mode in ("log", "auto"):
        v = arrow_vectors(f, mode, 0.005)
        n = np.linalg.norm(v, axis=1)
        assert n.max() == pytest.approx(ARROW_MAX) and np.all(np.diff(n) > 0)  # ordered, largest = ARROW_MAX
        assert np.allclose(v / n[:, None], f / np.linalg.norm(f, axis=1)[:, None])  # directions kept
    n_log = np.linalg.norm(arrow_vectors(f, "log", 0.005), axis=1)
    assert n_log[0] > 0.03 and n_log[1] > 0.1  # 1 N and 20 N stay visible next to 240 N
    assert np.allclose(arrow_vectors(f, "linear", 0.005), 0.005 * f)
    assert np.allclose(arrow_vectors(np.zeros((2, 3)), "log", 0.005), 0.0)


@pytest.mark.browser
def test_contact_force_labels_and_total(wb_page):
    from workbench.session.obstacles import ObstacleEdit

    app, page = wb_page
    wb = app.wb
    x = wb.live.state.node_pos[0]
    c = x[12] + np.array([0.09, 0.0, 0.0])  # a sphere of radius 0.08 pressing on the rod's side
    wb.add_obstacle(ObstacleEdit(kind="sphere", position=c, radius=0.08, name="press"))
    wait_for(lambda: app.view.last_frame is not None and len(app.view.last_frame.contact_points) > 0, timeout=90,
             what="contacts")
    wait_for(lambda: app.view.force_labels[0].visible, what="force label")
    fr = app.view.last_frame
    text = app.view.force_labels[0].text
    assert re.fullmatch(r"[0-9.e+-]+ N", text)
    wait_for(lambda: "net contact force" in app.controls.status.content, what="net force in the status")
    expect(page.get_by_text("net contact force", exact=False).first).to_be_visible()
    expect(page.get_by_text(re.compile(r"^[0-9.e+-]+ N$")).first).to_be_attached(timeout=WAIT_MS)
    arrows = np.asarray(app.view.contact_arrows.points)
    assert np.linalg.norm(arrows[:, 1] - arrows[:, 0], axis=1).max() <= ARROW_MAX + 1e-9
    assert len(fr.contact_forces)
