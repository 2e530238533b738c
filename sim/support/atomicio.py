"""Atomic file writes with the usual file mode (docs/conventions.md: files written atomically).

Every writer puts the bytes into a temporary file in the destination folder, flushes and fsyncs it,
gives it the mode a plain ``open(path, "w")`` would give (``0o666 & ~umask``, usually 0644; ``mkstemp``
alone leaves 0600) and renames it over the destination with ``os.replace``. A reader therefore sees
either the old file or the complete new one, never a partial file; on any error the temporary file
is removed and the destination is untouched.

    write_bytes(path, data)            write_text(path, text)
    savez(path, compressed=True, **arrays)
    write_via_path(path, fn)           # fn(tmp_path: str) writes the file itself (e.g. savefig)
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable

__all__ = ["default_mode", "write_bytes", "write_text", "savez", "write_via_path"]


def _umask() -> int:
    """The process umask, read without changing it (Linux: /proc/self/status), else via os.umask."""
    try:
        with open("/proc/self/status", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError):
        pass
    old = os.umask(0o022)  # fallback (not thread-safe for a moment; only where /proc is missing)
    os.umask(old)
    return old


def default_mode() -> int:
    """Mode of a newly created regular file: 0o666 minus the umask (0o644 with the usual umask 022)."""
    return 0o666 & ~_umask()


def write_via_path(path: str | os.PathLike, write: Callable[[str], None], *, mkdir: bool = True) -> Path:
    """Call ``write(tmp)`` to fill a temporary file beside ``path``, then move it to ``path`` atomically."""
    p = Path(path)
    if mkdir:
        p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp" + p.suffix, dir=str(p.parent))
    os.close(fd)
    try:
        write(tmp)
        with open(tmp, "rb+") as fh:
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, default_mode())
        os.replace(tmp, p)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return p


def write_bytes(path: str | os.PathLike, data: bytes, *, mkdir: bool = True) -> Path:
    """Write ``data`` to ``path`` atomically (mode 0o666 & ~umask)."""
    def w(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            fh.write(data)

    return write_via_path(path, w, mkdir=mkdir)


def write_text(path: str | os.PathLike, text: str, *, encoding: str = "utf-8", mkdir: bool = True) -> Path:
    """Write ``text`` to ``path`` atomically (mode 0o666 & ~umask)."""
    return write_bytes(path, text.encode(encoding), mkdir=mkdir)


def savez(path: str | os.PathLike, *, compressed: bool = True, mkdir: bool = True, **arrays) -> Path:
    """``numpy.savez(_compressed)`` to ``path`` atomically (the name is kept as given, no ``.npz`` added)."""
    import numpy as np

    def w(tmp: str) -> None:
        with open(tmp, "wb") as fh:
            (np.savez_compressed if compressed else np.savez)(fh, **arrays)

    return write_via_path(path, w, mkdir=mkdir)
