"""Progress bar with ETA for long command-line work (``rodlab sim``, ``record``, ``eval``), on stderr.

Shown when stderr is a terminal (``auto``), or always/never with the commands' ``--progress`` /
``--no-progress``; commands that print ``--json`` keep it off unless ``--progress`` is given. Uses tqdm.
"""
from __future__ import annotations

import sys
from typing import Any

__all__ = ["progress_bar", "add_progress_flag", "progress_wanted"]


class _Null:
    def update(self, n: int = 1) -> None:
        pass

    def set_postfix_str(self, s: str) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self) -> "_Null":
        return self

    def __exit__(self, *exc: Any) -> None:
        pass


def add_progress_flag(parser: Any) -> None:
    """``--progress`` / ``--no-progress`` (default: a bar on stderr only when it is a terminal and no --json)."""
    import argparse

    parser.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                        help="progress bar with ETA on stderr (default: only when stderr is a terminal and "
                             "--json is not given)")


def progress_wanted(flag: bool | None, *, json_output: bool = False) -> bool:
    """The ``--progress`` decision: explicit flag, else a terminal on stderr and no JSON output."""
    if flag is not None:
        return bool(flag)
    return (not json_output) and sys.stderr.isatty()


def progress_bar(total: int, *, desc: str, unit: str = "step", enabled: bool = True) -> Any:
    """A tqdm bar (total, rate, ETA) on stderr, or a no-op object with the same update/close methods."""
    if not enabled:
        return _Null()
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, unit=unit, dynamic_ncols=True, mininterval=0.5,
                file=sys.stderr)
