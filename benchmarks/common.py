"""Shared helpers of the benchmarks: machine record, timing, atomic JSON/PNG output, CLI bits."""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sim.support.atomicio import write_via_path

# developer output: the benchmarks run from a checkout (they are not installed), relative to the working directory
DEFAULT_OUT = Path("docs") / "bench"


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def load() -> list[float]:
    """1/5/15-minute load averages (the machine is shared; record with every figure)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return [float("nan")] * 3


def machine_info() -> dict[str, Any]:
    """CPU model, core counts, library versions, numba threads, load average."""
    info: dict[str, Any] = {
        "cpu_model": cpu_model(),
        "logical_cores": os.cpu_count(),
        "usable_cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "loadavg_at_start": load(),
        "utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
    try:
        import numba
        info["numba"] = numba.__version__
        info["numba_threads"] = numba.get_num_threads()
    except Exception:  # pragma: no cover
        pass
    try:
        from benchmarks.peers.elastica_scenes import elastica_version
        info["pyelastica"] = elastica_version()
    except ImportError:
        info["pyelastica"] = None
    return info


def median_time(fn: Callable[[], Any], *, repeats: int = 5, warmup: int = 1) -> dict[str, float]:
    """Run ``fn`` ``warmup`` + ``repeats`` times; wall-clock seconds (median, min, max) + load."""
    for _ in range(warmup):
        fn()
    ts = []
    for _ in range(max(1, repeats)):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return {"median_s": statistics.median(ts), "min_s": min(ts), "max_s": max(ts),
            "repeats": len(ts), "load": load()}


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating,)):
        x = float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if isinstance(x, float) and not np.isfinite(x):
        return None if np.isnan(x) else ("inf" if x > 0 else "-inf")
    return x


def _atomic_write(path: Path, write: Callable[[str], None]) -> None:

    write_via_path(path, write)


def write_json(out_dir: Path, name: str, data: dict[str, Any]) -> Path:
    """Write ``data`` to ``out_dir/name`` atomically; returns the path."""
    path = Path(out_dir) / name
    text = json.dumps(_jsonable(data), indent=1)

    def w(tmp: str) -> None:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text + "\n")
    _atomic_write(path, w)
    return path


def save_figure(fig: Any, out_dir: Path, name: str) -> Path:
    """Save a matplotlib figure as PNG atomically and close it."""
    import matplotlib.pyplot as plt
    path = Path(out_dir) / name

    def w(tmp: str) -> None:
        fig.savefig(tmp, dpi=110, bbox_inches="tight", format="png")
    _atomic_write(path, w)
    plt.close(fig)
    return path


def pyplot():
    """matplotlib.pyplot with the headless Agg backend."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def base_parser(prog: str, doc: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=prog, description=doc)
    p.add_argument("--quick", action="store_true", help="small configuration (minutes, for CI/smoke runs)")
    p.add_argument("--json", action="store_true", help="also print the result JSON to stdout")
    p.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder (default docs/bench/)")
    p.add_argument("--no-peer", action="store_true", help="skip PyElastica even if installed")
    p.add_argument("--repeats", type=int, default=None, help="timing repeats (median is reported)")
    return p


def have_elastica() -> bool:
    try:
        import elastica  # noqa: F401
        return True
    except ImportError:
        return False
