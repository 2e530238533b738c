"""The served workbench: :class:`WorkbenchApp` (one viser server, its panels and views, the stepping thread), the
connection handshake that refuses foreign origins and hosts, the keyboard map, process housekeeping, and
``rodlab workbench`` (:func:`workbench_main`).
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

_LAZY = {
    "WorkbenchApp": "workbench.serve.app",
    "default_scene": "workbench.serve.cli",
    "workbench_main": "workbench.serve.cli",
}

__all__ = sorted(_LAZY)

__getattr__, __dir__ = lazy_face(__name__, _LAZY)
