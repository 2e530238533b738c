"""rerun recordings of rod episodes: :class:`Recorder` (write), :func:`read_recording` (read back), the events on an
episode's timeline (:func:`detect`), a task's probe that records while it runs (:class:`TaskProbe`), and the export of
an episode to a standalone HTML player, PNG or GIF (:func:`export_to_folder`, ``rodlab export``);
``rodlab record`` / ``rodlab inspect`` (:mod:`policies.recording.cli`). Layout: :mod:`.schema`.

Attributes are imported lazily so ``import policies.recording`` does not import rerun.
"""
from __future__ import annotations

from sim.support.lazy import lazy_face

from .schema import EpisodeData, RecordingError, StaticScene

_LAZY = {"Recorder": "policies.recording.recorder", "read_recording": "policies.recording.reader",
         "summarize": "policies.recording.reader",
         "Event": "policies.recording.events", "detect": "policies.recording.events",
         "from_columns": "policies.recording.events",
         "TaskProbe": "policies.recording.probe", "record_hook": "policies.recording.probe",
         "task_target": "policies.recording.probe",
         "ExportError": "policies.recording.export_data", "export_to_folder": "policies.recording.export",
         "frame_indices": "policies.recording.export_data"}

__all__ = ["StaticScene", "EpisodeData", "RecordingError", *_LAZY]

__getattr__, __dir__ = lazy_face(__name__, _LAZY)
