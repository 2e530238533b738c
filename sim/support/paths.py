"""Output-path checks for commands that write files: the path can be written, checked before long work starts."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any

__all__ = ["check_output_path"]


def check_output_path(path: Any, *, folder: bool = False, suffix: str | None = None) -> Path:
    """Check, before any work, that ``path`` (a file, or with ``folder=True`` a folder) can be written: no part
    of its parent is a file, missing parent folders can be created (they are, as the writer would), and a file
    can be created there. Raises ValueError ``"PATH: problem"``; returns the Path."""
    p = Path(os.fspath(path))
    if str(p) == "":
        raise ValueError("output path is empty")
    if suffix is not None and p.suffix != suffix:
        raise ValueError(f"{p}: output file must end in {suffix}")
    if folder:
        if p.exists() and not p.is_dir():
            raise ValueError(f"{p}: exists and is a file, not a folder")
        target = p
    else:
        if p.is_dir():
            raise ValueError(f"{p}: is a folder; give a file name")
        target = p.parent if str(p.parent) else Path(".")
    for anc in [target, *target.parents]:
        if anc.exists():
            if not anc.is_dir():
                raise ValueError(f"{p}: {anc} is a file, not a folder")
            break
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{p}: cannot create folder {target}: {exc.strerror or exc}") from None
    try:
        fd, probe = tempfile.mkstemp(prefix=".write-check-", dir=str(target))
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise ValueError(f"{p}: folder {target} is not writable: {exc.strerror or exc}") from None
    return p
