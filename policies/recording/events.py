"""Events of an episode: the moments worth jumping to on its timeline.

One detector serves recorded episodes (the recorder writes them beside the scalars they come from, as text at
``events``, so the rerun viewer lists them) and the workbench's live history (``workbench.session.events``): per-frame
series in, a list of :class:`Event` out, in frame order.

- ``episode start`` / ``episode end``: where an episode begins and ends (recordings: the episode's first and last
  frame; live policy runs: where the task's step counter starts again);
- ``first contact``: the first frame of an episode (or of a stretch after contact was lost) with a contact;
- ``failed step``: a step the simulator gave up on (its env was reset to rest; the reason is the step's);
- ``unconverged``: the first frame of a run of steps whose Newton solve was accepted unconverged (the run's length);
- ``reward spike``: a reward farther than :data:`SPIKE_MADS` median absolute deviations from the episode's median
  (and than :data:`SPIKE_MIN` from it), e.g. a failure penalty or a bonus;
- ``pull`` / ``released``: where a hand grabbed the rod and let go (``workbench.session.pull``);
- ``take-over`` / ``hand back``: where the user took over from the policy and handed back.
"""
from __future__ import annotations

import dataclasses
from typing import Sequence

import numpy as np

SPIKE_MADS = 8.0  # a reward this many median absolute deviations from the median is a spike
SPIKE_MIN = 1e-6  # ... and at least this far from it


@dataclasses.dataclass(frozen=True)
class Event:
    """One moment: ``frame`` (index on the timeline it belongs to), ``kind`` (see the module), ``text`` (short)."""

    frame: int
    kind: str
    text: str


def _series(values, n: int) -> np.ndarray | None:
    if values is None:
        return None
    a = np.asarray(values, dtype=np.float64).reshape(-1)
    return a if a.size == n else None


def _rises(a: np.ndarray) -> np.ndarray:
    """Frames where a boolean series turns on (frame 0 counts when it starts on)."""
    on = a.astype(bool)
    return np.flatnonzero(on & ~np.concatenate([[False], on[:-1]]))


def detect(n: int, *, episode_starts: Sequence[int] = (0,), episode_ends: Sequence[int] = (), reward=None,
           contact_count=None, converged=None, failed=None, pull=None, hand=None, first_frame: int = 0,
           reason: str = "") -> list[Event]:
    """Events of ``n`` frames from their per-frame series (any may be None: not logged). ``episode_starts`` and
    ``episode_ends``: frame indices (0-based within the series); ``first_frame`` is added to every frame (the live
    history's first kept frame). ``reason``: what a failed step says."""
    ev: list[Event] = []
    starts = sorted({int(s) for s in episode_starts if 0 <= int(s) < n})
    for s in starts:
        ev.append(Event(s, "episode start", "episode start"))
    for e in episode_ends:
        if 0 <= int(e) < n:
            ev.append(Event(int(e), "episode end", "episode end"))
    bounds = [*starts, n] if starts and starts[0] == 0 else [0, *starts, n]
    cc = _series(contact_count, n)
    if cc is not None:
        for a, b in zip(bounds[:-1], bounds[1:]):
            for j, f in enumerate(_rises(cc[a:b] > 0)):
                ev.append(Event(a + int(f), "first contact", "first contact" if j == 0 else "contact again"))
    fl = _series(failed, n)
    if fl is not None:
        for f in np.flatnonzero(fl > 0):
            ev.append(Event(int(f), "failed step", f"failed step{': ' + reason if reason else ''}"))
    cv = _series(converged, n)
    if cv is not None:
        bad = (cv < 0.5) & np.isfinite(cv)
        for f in _rises(bad):
            run = int(np.argmax(~bad[f:])) if not bad[f:].all() else n - f
            ev.append(Event(int(f), "unconverged", f"unconverged ({run} step{'s' if run != 1 else ''})"))
    r = _series(reward, n)
    if r is not None:
        for a, b in zip(bounds[:-1], bounds[1:]):
            seg = r[a:b]
            fin = seg[np.isfinite(seg)]
            if fin.size < 5:
                continue
            med = float(np.median(fin))
            mad = float(np.median(np.abs(fin - med)))
            dev = np.abs(seg - med)
            for f in np.flatnonzero((dev > SPIKE_MADS * mad) & (dev > SPIKE_MIN) & np.isfinite(seg)):
                ev.append(Event(a + int(f), "reward spike", f"reward {seg[f]:+.3g}"))
    for series, on, off in ((pull, "pull", "released"), (hand, "take-over", "hand back")):
        s = _series(series, n)
        if s is None:
            continue
        held = s > 0
        for f in _rises(held):
            ev.append(Event(int(f), on, f"{on} ({s[f]:.3g} N)" if on == "pull" else on))
        for f in np.flatnonzero(held[:-1] & ~held[1:]) + 1:
            ev.append(Event(int(f), off, off))
    out = [Event(e.frame + first_frame, e.kind, e.text) for e in ev]
    return sorted(out, key=lambda e: (e.frame, e.kind))


def from_columns(n: int, scalars: dict, contact_count=None) -> list[Event]:
    """Events of an episode of ``n`` frames from its recorded scalars (name -> (n,) array, NaN where not logged;
    ``docs/architecture.md``, recording schema) and contact counts."""
    cc = contact_count if contact_count is not None else scalars.get("contact/count")
    return detect(n, episode_starts=(0,), episode_ends=(n - 1,) if n else (), reward=scalars.get("reward"),
                  contact_count=cc, converged=scalars.get("solver/converged"), failed=scalars.get("solver/failed"),
                  pull=scalars.get("hand/pull_force"), hand=scalars.get("hand/take_over"))


#: how a recording marks each kind in its text log (rerun's levels)
LEVELS = {"failed step": "ERROR", "unconverged": "WARN", "reward spike": "WARN"}
