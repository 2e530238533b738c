"""Words for the command lines' messages: a count with its noun in the right number."""
from __future__ import annotations

__all__ = ["count"]


def count(n: int, noun: str, plural: str | None = None) -> str:
    """``n`` and ``noun``, the noun plural unless n is 1: count(1, "episode") -> "1 episode", count(3, "env") ->
    "3 envs"; ``plural`` for nouns whose plural is not noun + "s"."""
    return f"{n} {noun if n == 1 else (plural or noun + 's')}"
