"""Words for the command lines' messages: a count with its noun in the right number, a number or a dash."""
from __future__ import annotations

import math

__all__ = ["count", "number"]


def count(n: int, noun: str, plural: str | None = None) -> str:
    """``n`` and ``noun``, the noun plural unless n is 1: count(1, "episode") -> "1 episode", count(3, "env") ->
    "3 envs"; ``plural`` for nouns whose plural is not noun + "s"."""
    return f"{n} {noun if n == 1 else (plural or noun + 's')}"


def number(v: float, spec: str = ".2f") -> str:
    """``v`` formatted with ``spec``, or "–" when it is not a finite number (no value yet: no "nan" in a progress
    line)."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        return "–"
    return format(x, spec) if math.isfinite(x) else "–"
