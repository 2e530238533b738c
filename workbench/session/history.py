"""Snapshots of a live session for rewinding (bounded, in memory)."""
from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

MAX_BYTES = 200 * 2**20  # what the rewind history of one session may hold [bytes]


@dataclasses.dataclass
class Snapshot:
    """Everything needed to continue a session from one frame.

    Attributes:
        index: frame number within the session (0 = after reset).
        time: simulated time [s].
        sim: (State copy, Control copy) from ``LiveSim.snapshot``.
        teleop: ``Teleop.snapshot()``.
        driver: policy/task state (``PolicySession.snapshot()``) or None in teleop mode.
        mode: "teleop" or "policy" at that frame.
        scalars: the frame's live values (for plots).
    """

    index: int
    time: float
    sim: tuple
    teleop: dict
    driver: Any
    mode: str
    scalars: dict


def held_bytes(obj: Any, _depth: int = 0) -> int:
    """Bytes of the numpy arrays ``obj`` holds (through dicts, sequences, dataclasses and plain objects), plus a
    small allowance per Python object: what a snapshot costs to keep."""
    if isinstance(obj, np.ndarray):
        return obj.nbytes + 112
    if _depth > 6 or obj is None or isinstance(obj, (bool, int, float, str, bytes, np.generic)):
        return 64
    if isinstance(obj, dict):
        return 64 + sum(held_bytes(v, _depth + 1) for v in obj.values())
    if isinstance(obj, (list, tuple, set, frozenset)):
        return 64 + sum(held_bytes(v, _depth + 1) for v in obj)
    if dataclasses.is_dataclass(obj):
        return 64 + sum(held_bytes(getattr(obj, f.name), _depth + 1) for f in dataclasses.fields(obj))
    d = getattr(obj, "__dict__", None)
    return 64 + (sum(held_bytes(v, _depth + 1) for v in d.values()) if isinstance(d, dict) else 0)


class History:
    """Bounded list of snapshots; frame numbers keep increasing when old ones are dropped.

    At most ``capacity`` snapshots and about ``max_bytes`` (the size of a snapshot is measured on the first one
    after a clear and again every ``capacity // 10`` appends, as a scene or task may change it); the oldest are
    dropped first and :attr:`dropped` counts them since the last clear (the page says the history was trimmed).
    """

    def __init__(self, capacity: int = 6000, max_bytes: int = MAX_BYTES):
        if capacity < 2:
            raise ValueError("history capacity must be >= 2")
        self.capacity = capacity
        self.max_bytes = int(max_bytes)
        self.dropped = 0
        self._items: list[Snapshot] = []
        self._limit = capacity
        self._since_measured = 0

    @property
    def limit(self) -> int:
        """How many snapshots are kept now (the capacity, or fewer where snapshots are large)."""
        return self._limit

    def clear(self) -> None:
        self._items.clear()
        self.dropped = 0
        self._since_measured = 0

    def append(self, snap: Snapshot) -> None:
        if self._since_measured == 0:
            per = max(held_bytes(snap), 1)
            self._limit = int(max(2, min(self.capacity, self.max_bytes // per)))
        self._since_measured = (self._since_measured + 1) % max(self.capacity // 10, 1)
        self._items.append(snap)
        if len(self._items) > self._limit:
            n = len(self._items) - self._limit
            del self._items[:n]
            self.dropped += n

    def __len__(self) -> int:
        return len(self._items)

    @property
    def first_index(self) -> int:
        return self._items[0].index if self._items else 0

    @property
    def last_index(self) -> int:
        return self._items[-1].index if self._items else 0

    def get(self, index: int) -> Snapshot:
        """Snapshot with frame number ``index`` (KeyError if it is no longer held)."""
        if not self._items or not (self.first_index <= index <= self.last_index):
            raise KeyError(f"frame {index} not in history [{self.first_index}, {self.last_index}]")
        return self._items[index - self.first_index]

    def truncate_after(self, index: int) -> None:
        """Drop every snapshot after frame ``index`` (continuing from a rewound frame)."""
        keep = index - self.first_index + 1
        del self._items[max(keep, 0):]

    def scalars(self) -> list[dict]:
        """The held snapshots' scalars, oldest first (frame ``first_index`` first)."""
        return [s.scalars for s in self._items]

    def series(self, key: str) -> tuple[list[float], list[float]]:
        """(times, values) of one scalar over the held history (missing values skipped)."""
        ts, vs = [], []
        for s in self._items:
            if key in s.scalars:
                ts.append(s.time)
                vs.append(s.scalars[key])
        return ts, vs
