"""The status line's contact summary: every contact counted and the net contact force from the step's own total
(StepStats.contact_force), also when the report did not list every contact; two rods pressing each other add
nothing to the net force (equal and opposite)."""
from __future__ import annotations

import re

import numpy as np

from sim import parse_scene
from sim.support.assets import asset_path
from tests.helpers.contact import FLOOR_DOC, FLOOR_NODES
from workbench.panels.controls import contact_status
from workbench.session.simbridge import LiveSim

NODES, DOC = FLOOR_NODES, FLOOR_DOC


def _net(line: str) -> float:
    return float(re.search(r"net contact force \*\*([-+0-9.e]+) N\*\*", line).group(1))


def test_every_contact_counted_and_the_net_force_is_the_steps_total():
    live = LiveSim(parse_scene(DOC, str(asset_path("scenes") / "_floor.toml")))
    assert contact_status(live.frame()) == ""  # before a step: no contacts
    st = live.step()
    fr = live.frame()
    dropped = int(st.contact_dropped[0])
    assert dropped > 0 and len(fr.contact_points) + dropped == NODES
    line = contact_status(fr)
    assert line.startswith(f"contacts {NODES} · ") and f"{dropped} not drawn" in line
    total = float(np.linalg.norm(st.contact_force[0]))
    listed = float(np.linalg.norm(fr.contact_forces.sum(axis=0)))
    assert listed < 0.9 * total  # the rows drawn are part of the contacts ...
    assert _net(line) == float(f"{total:.3g}")  # ... the net force counts them all
    st = live.step()  # the report grew: every contact listed
    line = contact_status(live.frame())
    assert line.startswith(f"contacts {NODES} · ") and "not drawn" not in line
    np.testing.assert_allclose(_net(line), np.linalg.norm(st.contact_force[0]), rtol=2e-3)


def test_a_replayed_frame_sums_the_rows_it_has():
    live = LiveSim(parse_scene(DOC, str(asset_path("scenes") / "_floor.toml")))
    live.step()
    live.step()
    fr = live.frame()
    fr.scalars = {}  # a recording's frame: its rows, no step total
    np.testing.assert_allclose(_net(contact_status(fr)), np.linalg.norm(fr.contact_forces.sum(axis=0)), rtol=2e-3)
