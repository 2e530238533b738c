"""Hands on the rod in a real browser: press on the rod and drag pulls it toward the pointer (the spring and its force
drawn while held), releasing the button lets go and the arm springs back; a click pins a readout at a node."""
from __future__ import annotations

import numpy as np
import pytest
from playwright.sync_api import expect

from tests.helpers.workbench import pause_drawn, set_live_playing
from tools.browser import WAIT_MS, expand_folder, newest_client, project, retry_until, wait_for
from workbench.view.scene import place_camera

pytestmark = pytest.mark.browser

PULL_M = 0.3  # how far the pointer moves [m], in the camera's plane through the grabbed point


def test_dragging_the_rod_pulls_it_and_release_lets_it_spring_back(wb_page, shots_dir):
    app, page = wb_page
    wb = app.wb
    wait_for(lambda: wb.frame_index > 3, what="sim running")
    tip0 = wb.tip
    client = newest_client(app)
    eye, at = (0.35, -1.8, 0.6), (0.35, 0.0, 0.6)  # facing the x-z plane: a pointer moving right moves along +x
    place_camera(client, eye, at)
    wait_for(lambda: np.allclose(client.camera.position, eye, atol=1e-3)
             and np.allclose(client.camera.look_at, at, atol=1e-3), what="camera in front of the arm")
    box = page.locator("canvas").first.bounding_box()
    corner = np.array([box["x"], box["y"]])
    # on the rod below the tip, between two control points (a press on a control point's bead bends the rod there)
    node = wb.live.n_nodes - 5
    assert all(abs(node - c) >= 2 for c in wb.teleop.control_nodes())
    grab = np.asarray(wb.live.state.node_pos[0, node], dtype=np.float64)
    uv = project(client.camera, np.stack([grab, grab + [PULL_M, 0.0, 0.0]]), box["width"], box["height"]) + corner
    held = {"down": False}

    def press_and_drag() -> None:
        if held["down"]:  # a try that did not grab: let go before the next
            page.mouse.up()
        page.mouse.move(*uv[0])
        page.mouse.down()
        held["down"] = True
        page.mouse.move(*uv[1], steps=10)

    retry_until(press_and_drag, lambda: wb.pull is not None, what="the rod grabbed")
    assert abs(wb.pull.node - node) <= 1  # where the rod was pressed
    nudge = {"px": 1.0}

    def move_on() -> None:  # the page sends pointer moves throttled: one more move sends the last place
        nudge["px"] = -nudge["px"]
        page.mouse.move(uv[1][0], uv[1][1] + nudge["px"])

    # the hand is where the pointer is, on the camera-facing plane through the pressed point
    retry_until(move_on, lambda: abs(wb.pull.pointer[0] - grab[0] - PULL_M) < 0.03, attempt_s=2.0,
                what="the hand at the pointer")
    wait_for(lambda: wb.tip[0] - tip0[0] > 0.1, timeout=60,
             what=f"the tip pulled along +x (tip {np.round(wb.tip, 3)})")
    assert abs(wb.tip[1] - tip0[1]) < 0.01  # the pull is in the camera's plane (the pressed point's offset kept)
    view = app.view
    wait_for(lambda: view.hand_line.visible and view.hand_label.text.startswith("pull ")
             and view.hand_label.text.endswith(" N"), what="the spring and its force drawn")
    wait_for(lambda: "pulling by hand" in app.controls.status.content, what="the status line says so")
    (shots_dir / "workbench_pull.png").write_bytes(page.screenshot(timeout=WAIT_MS))
    page.mouse.up()
    held["down"] = False
    wait_for(lambda: wb.pull is None, what="let go")
    wait_for(lambda: not view.hand_line.visible, what="the spring gone")
    wait_for(lambda: np.linalg.norm(wb.tip - tip0) < 0.01, timeout=60,
             what=f"the arm back at rest (tip {np.round(wb.tip, 3)}, was {np.round(tip0, 3)})")


def test_clicking_the_rod_pins_a_readout_that_follows_the_node(wb_page):
    app, page = wb_page
    wb, view = app.wb, app.view
    view.pins = []
    wb.set_teleop_value(2, 0, 0.8)  # a bent arm: curvature to read
    app.controls.sync_sliders()
    wait_for(lambda: abs(wb.tip[0]) > 0.1, timeout=30, what="the arm bent")
    client = newest_client(app)
    eye, at = (0.2, -1.8, 0.5), (0.2, 0.0, 0.5)
    place_camera(client, eye, at)
    wait_for(lambda: np.allclose(client.camera.position, eye, atol=1e-3)
             and np.allclose(client.camera.look_at, at, atol=1e-3), what="camera in front of the arm")
    box = page.locator("canvas").first.bounding_box()
    node = 10

    def click() -> None:
        x = np.asarray(wb.live.state.node_pos[0, node], dtype=np.float64)
        uv = project(client.camera, x[None], box["width"], box["height"])[0] + np.array([box["x"], box["y"]])
        page.mouse.click(*uv)

    assert node in wb.teleop.control_nodes()  # its bead covers the rod there: the click on the bead pins it
    retry_until(click, lambda: view.pins == [node], what=f"a readout pinned at node {node}")
    wait_for(lambda: view.pin_labels[0].visible and view.pin_texts and view.pin_texts[0].startswith(f"node {node} ·"),
             what="the readout drawn")
    # the readout is the drawn frame's: its curvature is the simulator's at that node (paused, so that no newer frame
    # moves the label between the two reads)
    pause_drawn(app)
    fr = view.last_frame
    st = wb.live.state
    from sim.geometry.curvature import material_curvature
    from workbench.session.pins import node_readout

    r = node_readout(fr, node)
    # (viser skips a pose within np.allclose's default tolerances of the one it holds: compare as it does)
    assert np.allclose(np.asarray(view.pin_labels[0].position), fr.node_pos[node])
    m1, m2, _ = (np.asarray(a[0]) for a in wb.live.sim.material_frames(st))
    if np.allclose(st.node_pos[0], fr.node_pos, atol=1e-12):  # the arm at rest: the frame is the state's
        assert r["κ1"] == pytest.approx(material_curvature(np.asarray(st.node_pos[0]), m1, m2)[node, 0], abs=1e-12)
    assert abs(r["κ1"]) > 0.01
    set_live_playing(app, True)
    # between two beads the click lands on the rod's grip: a second pin at the node nearest the pointer
    other = 12
    assert all(abs(other - c) >= 2 for c in wb.teleop.control_nodes())

    def click_other() -> None:
        x = np.asarray(wb.live.state.node_pos[0, other], dtype=np.float64)
        uv = project(client.camera, x[None], box["width"], box["height"])[0] + np.array([box["x"], box["y"]])
        page.mouse.click(*uv)

    retry_until(click_other, lambda: view.pins == [node, other], what=f"a second readout at node {other}")
    wait_for(lambda: len(view.pin_texts) == 2 and view.pin_texts[1].startswith(f"node {other} ·"),
             what="both readouts drawn")
    # the page's label says what the material carries there, on its own line; the Plots tab plots it against time
    label_js = "() => window.__viserSceneTree?.getState()?.['/rod/pins/0']?.message?.props?.text ?? ''"
    wait_for(lambda: any(ln.startswith("N ") and " M1 " in ln for ln in page.evaluate(label_js).split("\n")),
             what=lambda: f"the internal loads in the page's label (it reads {page.evaluate(label_js)!r})")
    expand_folder(page, "Plots", ".uplot")
    expect(page.get_by_text("pinned nodes: bending moments", exact=False).first).to_be_visible()
    assert {"pin_moment", "pin_curvature", "pin_axial"} <= {p.key for p in app.plots.shown}
    expand_folder(page, "Display", "Clear pins")
    page.get_by_role("button", name="Clear pins").click()
    wait_for(lambda: view.pins == [] and not view.pin_labels[0].visible, what="the pins cleared")


def test_dragging_a_control_point_bends_the_rod_there(wb_page):
    app, page = wb_page
    wb = app.wb
    wait_for(lambda: wb.frame_index > 3, what="sim running")
    node = wb.teleop.control_nodes()[2]
    x0 = np.asarray(wb.live.state.node_pos[0, node], dtype=np.float64).copy()
    client = newest_client(app)
    eye, at = (0.3, -1.8, 0.5), (0.3, 0.0, 0.5)
    place_camera(client, eye, at)
    wait_for(lambda: np.allclose(client.camera.position, eye, atol=1e-3)
             and np.allclose(client.camera.look_at, at, atol=1e-3), what="camera in front of the arm")
    box = page.locator("canvas").first.bounding_box()
    # the bead's front, toward the camera, and 12 cm to its right in the same plane
    front = x0 + [0.0, -1.3 * wb.live.rod_radius, 0.0]
    uv = project(client.camera, np.stack([front, front + [0.12, 0.0, 0.0]]), box["width"], box["height"])
    uv += np.array([box["x"], box["y"]])

    def drag() -> None:
        page.mouse.move(*uv[0])
        page.mouse.down()
        page.mouse.move(*uv[1], steps=10)
        page.mouse.move(uv[1][0], uv[1][1] + 1.0)  # one more move after the page's throttle sends the last place
        page.mouse.up()

    retry_until(drag, lambda: wb.live.state.node_pos[0, node, 0] - x0[0] > 0.06, attempt_s=20.0,
                what=f"control node {node} bent toward +x (at {np.round(wb.live.state.node_pos[0, node], 3)})")
    assert wb.pull is None  # a bead is not the rod's grip: nothing was pulled
    wait_for(lambda: abs(app.controls.sliders[0][0].value - round(float(wb.teleop.values[0, 0]), 2)) < 1e-9,
             what="the page's sliders show the values")
