"""Events on the workbench's timelines (``policies.recording.events`` finds them): the live history's, a recorded
episode's, the cursor's neighbours, the marks a slider shows and the list the page shows."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from policies.recording import Event, detect, from_columns

MARKS = 24  # events marked on a timeline slider at most (the page stays readable)

__all__ = ["Event", "MARKS", "episode_events", "live_events", "event_marks", "neighbour_event", "events_summary"]


def live_events(frames: Sequence[dict], *, first_frame: int = 0) -> list[Event]:
    """Events of the live history: ``frames`` are the snapshots' scalars in order (``episode_step`` of a policy
    run, ``contact_count``, ``converged``, ``failed``, ``reward``, ``pull_force``, ``hand``)."""
    n = len(frames)
    if n == 0:
        return []

    def col(key: str):
        if not any(key in f for f in frames):
            return None
        return np.array([f.get(key, np.nan) for f in frames], dtype=np.float64)

    steps = col("episode_step")
    starts, ends = [0], []
    if steps is not None:
        back = np.flatnonzero(np.diff(steps) < 0) + 1  # the task's step counter starts again: a new episode
        starts += back.tolist()
        ends += (back - 1).tolist()
    return detect(n, episode_starts=starts, episode_ends=ends, reward=col("reward"),
                  contact_count=col("contact_count"), converged=col("converged"), failed=col("failed"),
                  pull=col("pull_force"), hand=col("hand"), first_frame=first_frame)


def episode_events(ep) -> list[Event]:
    """Events of a recorded episode (``policies.recording.EpisodeData``)."""
    return from_columns(len(ep.positions), ep.scalars, ep.contact_count)


def neighbour_event(events: Sequence[Event], frame: int, step: int) -> Event | None:
    """The first event after ``frame`` (``step`` = +1) or before it (−1), None when there is none."""
    if step > 0:
        return next((e for e in events if e.frame > frame), None)
    return next((e for e in reversed(events) if e.frame < frame), None)


def event_marks(events: Sequence[Event], limit: int = MARKS) -> tuple[int, ...]:
    """Frames to mark on a timeline slider: one per frame with an event, at most ``limit`` (spread evenly)."""
    frames = sorted({e.frame for e in events})
    if len(frames) > limit:
        frames = [frames[i] for i in np.linspace(0, len(frames) - 1, limit).round().astype(int)]
    return tuple(frames)


def events_summary(events: Sequence[Event], around: int, *, count: int = 6) -> str:
    """A short list of the events nearest frame ``around`` (for the page)."""
    if not events:
        return "no events"
    i = int(np.searchsorted([e.frame for e in events], around))
    lo = max(0, min(i - count // 2, len(events) - count))
    part = events[lo:lo + count]
    body = " · ".join(f"{'**' if e.frame == around else ''}{e.frame}: {e.text}{'**' if e.frame == around else ''}"
                      for e in part)
    return f"{len(events)} event{'s' if len(events) != 1 else ''}: {body}"
