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

from typing import Any

__all__ = ["Workbench", "WorkbenchApp", "PolicySession", "ReplaySession", "workbench_main"]


def __getattr__(name: str) -> Any:
    if name == "Workbench":
        from workbench.core import Workbench
        return Workbench
    if name == "WorkbenchApp":
        from workbench.app import WorkbenchApp
        return WorkbenchApp
    if name == "PolicySession":
        from workbench.policy_session import PolicySession
        return PolicySession
    if name == "ReplaySession":
        from workbench.replay import ReplaySession
        return ReplaySession
    if name == "workbench_main":
        from workbench.cli import workbench_main
        return workbench_main
    raise AttributeError(name)
