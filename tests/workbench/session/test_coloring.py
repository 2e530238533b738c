"""Rod colouring (workbench.session.coloring): signed curvatures and twist of known shapes, ranges, the colour bar; and in a
real browser, the colour bar follows the chosen quantity and the fixed range."""
from __future__ import annotations

import re

import numpy as np
import pytest
from playwright.sync_api import expect

from tools.browser import WAIT_MS, expand_folder, wait_for
from workbench.session.coloring import colorbar_html, colors, node_values, value_range
from workbench.session.frame import Frame


def _arc(n: int = 11, turn: float = 0.1, twist: float = 0.0) -> Frame:
    """A planar arc in x-z (each node turns the tangent by ``turn`` about -y) with m1 = the in-plane normal, and
    the material frame rotated by ``twist`` more about the tangent at each edge."""
    ang = turn * np.arange(n - 1)
    t = np.stack([np.sin(ang), np.zeros_like(ang), np.cos(ang)], 1)
    x = np.concatenate([np.zeros((1, 3)), np.cumsum(0.05 * t, axis=0)])
    m1 = np.stack([np.cos(ang), np.zeros_like(ang), -np.sin(ang)], 1)
    m2 = np.cross(t, m1)
    phi = twist * np.arange(n - 1)[:, None]
    m1, m2 = np.cos(phi) * m1 + np.sin(phi) * m2, -np.sin(phi) * m1 + np.cos(phi) * m2
    return Frame(node_pos=x, rod_radius=0.01, m1=m1, m2=m2, edge_strain=np.linspace(-1e-3, 1e-3, n - 1))


def test_signed_curvature_twist_and_strain():
    fr = _arc(turn=0.1)
    k1, k2 = node_values(fr, "κ1"), node_values(fr, "κ2")
    mag = 2 * np.tan(0.05)  # |κb| = 2 tan(φ/2)
    assert np.allclose(np.abs(k1) + np.abs(k2), mag) and np.allclose(node_values(fr, "curvature"), mag)
    assert np.ptp(np.sign(k1 + k2)) == 0  # one sign along a constant arc
    mirrored = _arc(turn=-0.1)
    assert np.allclose(node_values(mirrored, "κ1") + node_values(mirrored, "κ2"), -(k1 + k2))  # signed
    assert np.allclose(node_values(fr, "twist"), 0.0, atol=1e-9)
    assert np.allclose(node_values(_arc(turn=0.0, twist=0.03), "twist"), 0.03)
    s = node_values(fr, "strain")
    assert s[0] < 0 < s[-1]
    assert node_values(Frame(node_pos=fr.node_pos, rod_radius=0.01), "κ1") is None  # needs material frames


def test_ranges_colours_and_bar():
    v = np.array([-0.2, 0.0, 0.1])
    assert value_range(v, "κ1") == (-0.2, 0.2) and value_range(np.abs(v), "curvature") == (0.0, 0.2)
    assert value_range(v, "κ1", fixed=0.5) == (-0.5, 0.5)
    c = colors(v, -0.2, 0.2, "κ1")
    assert c[0, 2] > c[0, 0] and c[2, 0] > c[2, 2]  # negative blue, positive red
    html = colorbar_html("twist", -0.25, 0.25)
    assert "twist [rad]" in html and "-0.25" in html and "0.25" in html


@pytest.mark.browser
def test_colour_bar_follows_quantity_and_range(wb_page):
    app, page = wb_page
    wb = app.wb
    wb.set_teleop_value(2, 0, 1.5)  # bend and twist the rod so every quantity is non-zero
    wb.set_teleop_value(3, 2, 1.0)
    expand_folder(page, "Display", "top")
    bar = page.locator(".rodlab-colorbar")
    expect(bar).to_contain_text("|κ| curvature [rad]", timeout=WAIT_MS)

    def bar_range() -> tuple[float, float]:
        lo, hi = (float(bar.locator(f"span.{k}").inner_text()) for k in ("lo", "hi"))
        return lo, hi

    wait_for(lambda: bar_range()[1] > 0.05, timeout=30, what="curvature range from the bent rod")
    wb.set_playing(False)  # the bent rod's paused frame is drawn again with each choice below
    assert bar_range()[0] == 0.0
    for quantity, text in (("κ1", "κ1 [rad]"), ("twist", "twist [rad]")):
        page.get_by_label("Colour by").click()
        page.get_by_role("option", name=quantity, exact=True).click()
        expect(bar).to_contain_text(text, timeout=WAIT_MS)
        wait_for(lambda: bar_range()[0] < 0 and bar_range()[0] == pytest.approx(-bar_range()[1]), timeout=15,
                 what=f"symmetric range for {quantity}")
    # a fixed range
    page.get_by_label("Colour range").click()
    page.get_by_role("option", name="fixed", exact=True).click()
    field = page.get_by_label("Fixed range max")
    field.fill("0.8")
    field.press("Enter")
    wait_for(lambda: bar_range() == (-0.8, 0.8), timeout=15, what="fixed range in the colour bar")
    assert re.search(r"twist", app.controls.colorbar.content)
    expand_folder(page, "Run", "Step")  # the colour bar stays in view whichever tab is open
    expect(bar).to_be_visible()
    app.controls.color_range.value = "auto"
    app.controls.color_by.value = "curvature"
