"""A recorded episode as measured motion for ``rodlab fit`` (sim-to-sim): the node positions of one episode of a
rodlab ``.rrd`` recording as the arrays ``sim.analysis.calibration`` takes, and the ``rodlab fit`` entry that reads ``.rrd`` DATA.

sim does not import policies (sim <- policies <- workbench), so the recording is read here and handed to
``sim.analysis.calibration`` as arrays: ``t (T,)`` [s] the frames' simulated time since reset, ``s (M,)`` [m] each recorded node's
arclength from its rod's first node (along the scene's rest shape when the scene is given, else along the first
frame), ``pos (T, M, 3)`` [m]. The episode must start from the scene's initial state (t = 0 is the scene's
``reset``); frames logged twice at one time (per-sim-step logging) count once.
"""
from __future__ import annotations

import os
from typing import Any

import numpy as np

from .schema import EpisodeData, RecordingError

__all__ = ["recording_to_measurements", "episode_to_measurements", "read_rrd_measurements", "fit_main"]


def _episode(path: str | os.PathLike[str], episode: int) -> EpisodeData:
    from .reader import read_recording

    eps = read_recording(path)
    for ep in eps:
        if int(ep.meta.get("episode", -1)) == int(episode):
            return ep
    have = ", ".join(str(int(ep.meta.get("episode", -1))) for ep in eps)
    raise RecordingError(f"{path}: no episode {episode} (the file has episode(s) {have})")


def episode_to_measurements(ep: EpisodeData, *, spec: Any = None, rod: int = 0,
                            where: str = "recording") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t (T,), s (M,), pos (T, M, 3)) of rod ``rod`` (index in the recorded layout) of a read episode."""
    off = ep.rod_node_offsets
    if not 0 <= rod < len(off) - 1:
        raise RecordingError(f"{where}: no rod {rod} (the recording has {len(off) - 1})")
    pos = np.asarray(ep.positions[:, off[rod]:off[rod + 1]], np.float64)
    t = np.asarray(ep.sim_time, np.float64)
    if t.size == 0:
        raise RecordingError(f"{where}: the episode has no frames")
    if np.any(np.diff(t) < 0.0):
        i = int(np.flatnonzero(np.diff(t) < 0.0)[0]) + 1
        raise RecordingError(f"{where}: sim_time goes back at frame {i} ({t[i]:g} s after {t[i - 1]:g} s)")
    first = np.concatenate([[True], np.diff(t) > 0.0])  # one frame per time
    t, pos = t[first], pos[first]
    if spec is not None:
        from sim.analysis import node_arclength

        s_all, rod_of = node_arclength(spec)
        s = s_all[rod_of == rod]
        if s.size != pos.shape[1]:
            name = spec.rods[rod].name if rod < len(spec.rods) else rod
            raise RecordingError(f"{where}: rod {rod} has {pos.shape[1]} recorded nodes but the scene's rod {name!r} "
                                 f"has {s.size}: a recording of another scene?")
    else:
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pos[0], axis=0), axis=1))])
    return t, s, pos


def recording_to_measurements(path: str | os.PathLike[str], episode: int = 0, *, spec: Any = None,
                              rod: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Node positions of episode ``episode`` (its index in the file, as ``rodlab inspect`` lists it) of the .rrd at
    ``path`` as ``(t (T,) [s], s (M,) [m], pos (T, M, 3) [m])`` of rod ``rod``: the arrays of a ``rodlab fit``
    ``.npz`` (``sim.analysis.calibration.measurements_from_arrays``). With the scene ``spec``, s is along its rest shape (the s the
    fit interpolates at: a recorded node is the scene's node) and the node counts are checked."""
    return episode_to_measurements(_episode(path, episode), spec=spec, rod=rod, where=f"{path}: episode {episode}")


def read_rrd_measurements(path: str | os.PathLike[str], spec: Any, *, episode: int = 0):
    """``sim.analysis.calibration.load_measurements`` reader of ``.rrd`` DATA: every rod of the scene from episode ``episode``
    (raises sim.analysis.calibration.FitError naming the file)."""
    from sim.analysis import FitError, Measurements, measurements_from_arrays

    try:
        ep = _episode(path, episode)
        if len(spec.rods) != len(ep.rod_node_offsets) - 1:
            raise FitError(f"{path}: episode {episode} records {len(ep.rod_node_offsets) - 1} rod(s), the scene has "
                           f"{len(spec.rods)}: a recording of another scene?")
        parts = []
        for r in range(len(spec.rods)):
            where = f"{path}: episode {episode}" + (f", rod {spec.rods[r].name!r}" if len(spec.rods) > 1 else "")
            t, s, pos = episode_to_measurements(ep, spec=spec, rod=r, where=where)
            parts.append(measurements_from_arrays(t, s, pos, spec, rod=r, where=where))
    except RecordingError as exc:
        raise FitError(str(exc)) from None
    return Measurements(*(np.concatenate([getattr(p, k) for p in parts]) for k in ("t", "s", "rod", "pos")))


def fit_main(argv: list[str] | None = None) -> int:
    """``rodlab fit`` (sim.analysis.fit_command) with ``.rrd`` recordings as DATA."""
    from sim.analysis import fit_command

    return fit_command(argv, readers={".rrd": read_rrd_measurements})

