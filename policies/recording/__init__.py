"""rerun recordings of rod episodes: :class:`Recorder` (write), :func:`read_recording` (read back),
``rodlab record`` / ``rodlab inspect`` (:mod:`policies.recording.cli`). Layout: :mod:`.schema`.

Attributes are imported lazily so ``import policies.recording`` does not import rerun.
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

from .schema import EpisodeData, RecordingError, StaticScene

__all__ = ["Recorder", "StaticScene", "EpisodeData", "RecordingError", "read_recording", "summarize"]


_LAZY = {"Recorder": "policies.recording.recorder", "read_recording": "policies.recording.reader",
         "summarize": "policies.recording.reader"}

__getattr__, __dir__ = lazy_face(__name__, _LAZY)
