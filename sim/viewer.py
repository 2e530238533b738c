"""Viewer protocol (one interface, several backends) and the null backend used by tests and benchmarks."""
from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

__all__ = ["Viewer", "NullViewer"]


@runtime_checkable
class Viewer(Protocol):
    """Frame-based viewer: ``begin_frame(t)``, ``log_state(model, state)``, ``log_contacts(stats)``,
    ``log_scalar(name, value)``, ``end_frame()``. Backends: viser (workbench), rerun (recordings), null."""

    def begin_frame(self, t: float) -> None: ...

    def log_state(self, model: Any, state: Any) -> None: ...

    def log_contacts(self, stats: Any) -> None: ...

    def log_scalar(self, name: str, value: float) -> None: ...

    def end_frame(self) -> None: ...


class NullViewer:
    """Discards everything (counts frames, for tests)."""

    def __init__(self) -> None:
        self.frames = 0

    def begin_frame(self, t: float) -> None:
        pass

    def log_state(self, model: Any, state: Any) -> None:
        pass

    def log_contacts(self, stats: Any) -> None:
        pass

    def log_scalar(self, name: str, value: float) -> None:
        pass

    def end_frame(self) -> None:
        self.frames += 1
