"""rodlab web workbench (viser): teleop, obstacle editing, policies, replay of recordings.

Public surface::

    from workbench import Workbench, WorkbenchApp
    wb = Workbench.from_path("assets/scenes/default.toml")   # headless core (testable, no GUI)
    app = WorkbenchApp(wb, port=8080).start()                 # viser page + real-time sim thread
    app.stop()

``rodlab workbench`` is :func:`workbench.cli.workbench_main`. Names are imported lazily so that
``import workbench`` stays cheap.
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

_LAZY = {"Workbench": "workbench.core", "WorkbenchApp": "workbench.app", "PolicySession": "workbench.policy_session",
         "ReplaySession": "workbench.replay", "workbench_main": "workbench.cli"}

__all__ = ["Workbench", "WorkbenchApp", "PolicySession", "ReplaySession", "workbench_main"]

__getattr__, __dir__ = lazy_face(__name__, _LAZY)
