"""Small helpers shared by the scene parsers: typed key access with clear errors, and a TOML writer.

Every error is a :class:`SceneError` whose message names the file, the key (``table.key``) and the
problem. The writer is hand-written (no extra dependency) and only covers what scene files use:
bool, int, float, str and flat lists of those.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

__all__ = ["SceneError", "take_float", "take_int", "take_bool", "take_str", "take_vec3", "check_unknown",
           "format_value"]

_MISSING = object()


class SceneError(ValueError):
    """A scene file (or SceneSpec) is invalid. The message names file, key and problem."""


def _where(path: str | None, key: str) -> str:
    return f"{path or '<scene>'}: {key}"


def _get(table: Mapping[str, Any], name: str, prefix: str, path: str | None, default: Any) -> Any:
    if name in table:
        return table[name]
    if default is _MISSING:
        raise SceneError(f"{_where(path, prefix + name)}: missing required key")
    return default


def take_float(table: Mapping[str, Any], name: str, prefix: str, path: str | None, default: Any = _MISSING,
               *, positive: bool = False, nonnegative: bool = False) -> float:
    """Read a finite float (ints are accepted) from ``table[name]``."""
    v = _get(table, name, prefix, path, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise SceneError(f"{_where(path, prefix + name)}: expected a number, got {type(v).__name__} {v!r}")
    v = float(v)
    if not math.isfinite(v):
        raise SceneError(f"{_where(path, prefix + name)}: must be finite, got {v!r}")
    if positive and not v > 0:
        raise SceneError(f"{_where(path, prefix + name)}: must be > 0, got {v!r}")
    if nonnegative and not v >= 0:
        raise SceneError(f"{_where(path, prefix + name)}: must be >= 0, got {v!r}")
    return v


def take_int(table: Mapping[str, Any], name: str, prefix: str, path: str | None, default: Any = _MISSING,
             *, minimum: int | None = None) -> int:
    """Read an integer (not a bool, not a float)."""
    v = _get(table, name, prefix, path, default)
    if isinstance(v, bool) or not isinstance(v, int):
        raise SceneError(f"{_where(path, prefix + name)}: expected an integer, got {type(v).__name__} {v!r}")
    if minimum is not None and v < minimum:
        raise SceneError(f"{_where(path, prefix + name)}: must be >= {minimum}, got {v}")
    return int(v)


def take_bool(table: Mapping[str, Any], name: str, prefix: str, path: str | None, default: Any = _MISSING) -> bool:
    """Read a TOML boolean."""
    v = _get(table, name, prefix, path, default)
    if not isinstance(v, bool):
        raise SceneError(f"{_where(path, prefix + name)}: expected true/false, got {type(v).__name__} {v!r}")
    return v


def take_str(table: Mapping[str, Any], name: str, prefix: str, path: str | None, default: Any = _MISSING,
             *, choices: tuple[str, ...] | None = None) -> str:
    """Read a string, optionally restricted to ``choices``."""
    v = _get(table, name, prefix, path, default)
    if not isinstance(v, str):
        raise SceneError(f"{_where(path, prefix + name)}: expected a string, got {type(v).__name__} {v!r}")
    if choices is not None and v not in choices:
        raise SceneError(f"{_where(path, prefix + name)}: must be one of {list(choices)}, got {v!r}")
    return v


def take_vec3(table: Mapping[str, Any], name: str, prefix: str, path: str | None,
              default: Any = _MISSING) -> tuple[float, float, float]:
    """Read a list of 3 finite numbers."""
    v = _get(table, name, prefix, path, default)
    if not isinstance(v, (list, tuple)) or len(v) != 3:
        raise SceneError(f"{_where(path, prefix + name)}: expected a list of 3 numbers, got {v!r}")
    out = []
    for c in v:
        if isinstance(c, bool) or not isinstance(c, (int, float)):
            raise SceneError(f"{_where(path, prefix + name)}: expected numbers, got {c!r}")
        if not math.isfinite(float(c)):
            raise SceneError(f"{_where(path, prefix + name)}: must be finite, got {v!r}")
        out.append(float(c))
    return (out[0], out[1], out[2])


def check_unknown(table: Mapping[str, Any], allowed: set[str], prefix: str, path: str | None) -> None:
    """Reject keys not in ``allowed`` (catches typos such as ``youngs_modulous``)."""
    for k in table:
        if k not in allowed:
            raise SceneError(f"{_where(path, prefix + k)}: unknown key (allowed: {sorted(allowed)})")


def format_value(v: Any) -> str:
    """Format a value as a TOML value (bool, int, float, str, flat list/tuple).

    numpy scalars and 1-D arrays are written as the plain Python values they hold (``np.float64(0.35)``
    becomes ``0.35``: numpy's own ``repr`` is not TOML)."""
    tolist = getattr(v, "tolist", None)
    if tolist is not None and not isinstance(v, (str, list, tuple)):  # numpy scalar or array
        v = tolist()
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(int(v))
    if isinstance(v, float):
        if not math.isfinite(v):
            raise ValueError(f"cannot write non-finite float {v!r} to TOML")
        r = float.__repr__(float(v))
        return r if any(ch in r for ch in ".eE") else r + ".0"
    if isinstance(v, str):
        out = ['"']
        for ch in v:
            if ch == '"':
                out.append('\\"')
            elif ch == "\\":
                out.append("\\\\")
            elif ord(ch) < 0x20 or ord(ch) == 0x7F:
                out.append(f"\\u{ord(ch):04x}")
            else:
                out.append(ch)
        out.append('"')
        return "".join(out)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(format_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")
