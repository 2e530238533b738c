"""rerun recordings of rod episodes: :class:`Recorder` (write), :func:`read_recording` (read back),
``rodlab record`` / ``rodlab inspect`` (:mod:`policies.recording.cli`). Layout: :mod:`.schema`.

Attributes are imported lazily so ``import policies.recording`` does not import rerun.
"""
from __future__ import annotations

from typing import Any

from .schema import EpisodeData, RecordingError, StaticScene

__all__ = ["Recorder", "StaticScene", "EpisodeData", "RecordingError", "read_recording", "summarize"]


def __getattr__(name: str) -> Any:
    if name == "Recorder":
        from .recorder import Recorder
        return Recorder
    if name in ("read_recording", "summarize"):
        from . import reader
        return getattr(reader, name)
    raise AttributeError(name)
