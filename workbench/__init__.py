"""rodlab web workbench (viser): teleop, obstacle editing, policies, replay of recordings.

Public surface::

    from workbench import Workbench, WorkbenchApp
    wb = Workbench.from_path("assets/scenes/default.toml")   # headless core (testable, no GUI)
    app = WorkbenchApp(wb, port=8080).start()                 # viser page + real-time sim thread
    app.stop()

Packages by role, each used through its ``__init__`` (docs/architecture.md): :mod:`workbench.session` (the state
without a page), :mod:`workbench.view` (the 3-D scene), :mod:`workbench.panels` (the side panel's tabs),
:mod:`workbench.serve` (the server, the handshake and ``rodlab workbench``). Names are imported lazily so that
``import workbench`` stays cheap.
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

_LAZY = {"Workbench": "workbench.session", "PolicySession": "workbench.session", "ReplaySession": "workbench.session",
         "WorkbenchApp": "workbench.serve", "workbench_main": "workbench.serve"}

__all__ = ["Workbench", "WorkbenchApp", "PolicySession", "ReplaySession", "workbench_main"]

__getattr__, __dir__ = lazy_face(__name__, _LAZY)
