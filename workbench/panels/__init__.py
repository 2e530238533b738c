"""The side panel's tabs, one class per tab (Controls, Obstacles, Policy, Grid, Replay, Compare, Fit, Plots, Events,
Render), each built on a :class:`workbench.panels.host.PanelHost`, and :class:`GuiGuard`, which validates every
value the page sends before a callback sees it.
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

_LAZY = {
    "ComparePanel": "workbench.panels.compare",
    "ControlsPanel": "workbench.panels.controls",
    "EventsPanel": "workbench.panels.events",
    "FitPanel": "workbench.panels.fit",
    "GridPanel": "workbench.panels.grid",
    "GuiGuard": "workbench.panels.guard",
    "MessageGuard": "workbench.panels.guard",
    "finite_pose": "workbench.panels.guard",
    "guard_callbacks": "workbench.panels.guard",
    "only_value_updates": "workbench.panels.guard",
    "ObstaclesPanel": "workbench.panels.obstacles",
    "PlotsPanel": "workbench.panels.plots",
    "PolicyPanel": "workbench.panels.policy",
    "RenderPanel": "workbench.panels.render",
    "ReplayPanel": "workbench.panels.replay",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_face(__name__, _LAZY)
