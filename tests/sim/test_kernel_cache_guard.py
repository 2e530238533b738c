"""The stale-cache guard (sim/_cache.py) hashes every module whose numba functions the step kernel compiles in:
numba's own cache only checks a cached function's own file, so a kernel module missing from the list would leave
the fused step kernel running old code after an edit."""
from __future__ import annotations

from pathlib import Path

from sim import _cache

SIM = Path(_cache.__file__).resolve().parent


def test_every_numba_module_is_hashed_or_self_contained():
    numba_modules = sorted(str(p.relative_to(SIM)) for p in SIM.rglob("*.py")
                           if "__pycache__" not in p.parts and "@njit" in p.read_text(encoding="utf-8"))
    missing = [m for m in numba_modules if m not in _cache._SOURCES and m not in _cache.SELF_CONTAINED]
    assert not missing, f"sim/_cache.py _SOURCES lacks {missing}"
    assert "contact/edge_pairs.py" in _cache._SOURCES


def test_self_contained_modules_import_no_kernel_module():
    for rel in _cache.SELF_CONTAINED:
        text = (SIM / rel).read_text(encoding="utf-8")
        for src in _cache._SOURCES:
            stem = Path(src).stem
            assert f"from .{stem} import" not in text and f"from sim.{stem} import" not in text, (rel, stem)
