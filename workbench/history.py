"""Snapshots of a live session for rewinding (bounded, in memory)."""
from __future__ import annotations

import dataclasses
from typing import Any


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


class History:
    """Bounded list of snapshots; frame numbers keep increasing when old ones are dropped."""

    def __init__(self, capacity: int = 6000):
        if capacity < 2:
            raise ValueError("history capacity must be >= 2")
        self.capacity = capacity
        self._items: list[Snapshot] = []

    def clear(self) -> None:
        self._items.clear()

    def append(self, snap: Snapshot) -> None:
        self._items.append(snap)
        if len(self._items) > self.capacity:
            del self._items[: len(self._items) - self.capacity]

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

    def series(self, key: str) -> tuple[list[float], list[float]]:
        """(times, values) of one scalar over the held history (missing values skipped)."""
        ts, vs = [], []
        for s in self._items:
            if key in s.scalars:
                ts.append(s.time)
                vs.append(s.scalars[key])
        return ts, vs
