"""What a GUI panel (a module of :mod:`workbench.panels`) uses of the app that builds it: :class:`PanelHost`, a typing Protocol that
:class:`workbench.serve.app.WorkbenchApp` satisfies. The panels annotate their ``app`` with it, so they need not import
``workbench.serve.app`` (which imports them); at run time this module imports nothing of the workbench."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Protocol

if TYPE_CHECKING:
    from workbench.panels.guard import GuiGuard
    from workbench.session import Folders, Frame, SimThread, Workbench
    from workbench.view import SceneView

__all__ = ["PanelHost"]


class PanelHost(Protocol):
    """The app as the panels see it (attributes set in ``WorkbenchApp.__init__``; the other panels are Any)."""

    wb: "Workbench"
    server: Any  # viser.ViserServer
    view: "SceneView"
    files: "Folders"
    recordings_dir: Path
    checks: "GuiGuard"
    thread: "SimThread"
    tabs: dict[str, Any]  # tab name -> viser tab handle (set by the controls panel)
    render_hooks: list[Callable[["Frame"], None]]
    status_note: str
    notice: tuple[str, float]  # a passing message for the status line and when it was said (time.monotonic())
    waiting_for_browser: bool
    compiling: str  # the kernel being compiled before the first step ("" when none)
    controls: Any  # workbench.panels.controls.ControlsPanel
    policy: Any  # workbench.panels.policy.PolicyPanel
    replay: Any  # workbench.panels.replay.ReplayPanel
    compare: Any  # workbench.panels.compare.ComparePanel

    def request_render(self) -> None: ...

    def refresh_rod_scene(self) -> None: ...

    def sync_obstacle_view(self) -> None: ...

    def _render(self, fr: "Frame") -> None: ...
