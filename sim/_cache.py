"""Guard against stale numba caches.

numba's ``cache=True`` only checks the source file of the cached function itself, so a change in a callee
defined in another module (an energy, ``geometry/frames.py``, ``geometry/vec3.py``, ``contact/obstacles.py``) would leave the fused kernels in
``sim/kernels/`` stale. :func:`invalidate_if_sources_changed` hashes all kernel sources and, when the hash differs
from the stamp written last time, deletes the cached ``*.nbi``/``*.nbc`` files of those modules.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

_HERE = Path(__file__).resolve().parent
_SOURCES = ["numba_options.py", "geometry/frames.py", "kernels/banded.py", "kernels/data.py", "kernels/workspace.py",
            "kernels/assemble_3d.py", "kernels/assemble_2d.py", "kernels/drag.py", "kernels/newton.py",
            "kernels/ladder.py", "kernels/batch.py", "contact/imc.py", "contact/obstacles.py", "contact/edge_pairs.py", "contact/stages.py",
            "geometry/distance.py", "geometry/vec3.py", "scene/kinds.py",
            "energies/stretch.py", "energies/bend_twist.py", "energies/planar.py", "analysis/hessian.py", "kernels/probe.py", "kernels/linearise.py"]
# modules whose numba functions call no numba function of another module (their own cache check suffices)
SELF_CONTAINED = ["contact/mesh.py", "analysis/local_maps.py"]


def _cache_dirs() -> list[Path]:
    dirs = sorted({(_HERE / rel).parent / "__pycache__" for rel in _SOURCES + SELF_CONTAINED})
    env = os.environ.get("NUMBA_CACHE_DIR")
    if env:
        dirs.append(Path(env))
    return dirs


def invalidate_if_sources_changed() -> bool:
    """Delete the numba cache files of the sim kernels if their sources changed. Returns True if it did."""
    h = hashlib.sha256()
    for rel in _SOURCES:
        p = _HERE / rel
        try:
            h.update(rel.encode() + b"\0" + p.read_bytes())
        except OSError:
            h.update(rel.encode() + b"\0missing")
    digest = h.hexdigest()
    stamp = _HERE / "__pycache__" / "kernel_sources.sha256"
    try:
        if stamp.read_text().strip() == digest:
            return False
    except OSError:
        pass
    stems = {Path(r).stem for r in _SOURCES}
    for d in _cache_dirs():
        if not d.is_dir():
            continue
        for f in d.rglob("*"):
            if f.suffix in (".nbi", ".nbc") and f.name.split(".")[0] in stems:
                try:
                    f.unlink()
                except OSError:
                    pass
    try:
        stamp.parent.mkdir(exist_ok=True)
        tmp = stamp.with_suffix(f".tmp{os.getpid()}")
        tmp.write_text(digest + "\n")
        os.replace(tmp, stamp)
    except OSError:
        pass
    return True
