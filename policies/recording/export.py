"""Export a recorded episode: a standalone HTML player and a PNG picture of one frame.

``rodlab export RECORDING.rrd --episode K --html OUT.html [--png OUT.png --frame N] [--gif OUT.gif]``

* HTML: one self-contained file (data and script inline, nothing fetched) that opens from ``file://`` with no
  server: the rod moving over a timeline with play/pause, speed, orbit/zoom and view presets
  (:mod:`policies.recording.export_page`). Positions are stored as little-endian float32 (as in the recording, see
  docs/architecture.md); episodes longer than ``max_frames`` are decimated evenly (first and last frame kept).
* PNG / GIF: the same default view of one frame / of the whole episode, drawn with matplotlib (no browser
  needed; :mod:`policies.recording.export_image`).

Files are written atomically (:mod:`sim.support.atomicio`) and only to the paths given.
"""
from __future__ import annotations

import argparse
import base64
import html
import json
import math
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np
from sim.support import atomicio

from policies.recording.reader import read_recording
from policies.recording.schema import EpisodeData, RecordingError

from .export_data import ExportError, b64_f32, check_out, frame_indices, obstacle_lists, rod_offsets
from .export_image import export_gif, export_png
from .export_page import PAGE

__all__ = ["ExportError", "load_episode", "rod_offsets", "pack_episode", "episode_html", "unpack_html", "export_html",
           "export_to_folder", "main"]

DEFAULT_MAX_FRAMES = 5000
SERIES = ("tip_error", "reward", "contact/max_normal_force")
META_KEYS = ("task", "policy", "seed", "episode", "env", "scene", "control_dt", "dt", "substeps", "complete",
             "return", "created_utc", "rodlab_version", "git_commit")
_DATA_RE = re.compile(r'<script type="application/json" id="rodlab-data">(.*?)</script>', re.S)


def load_episode(recording: str | Path, episode: int) -> EpisodeData:
    """Episode ``episode`` (0-based, in the order ``rodlab inspect`` lists them) of a .rrd file."""
    eps = read_recording(recording)
    if not isinstance(episode, (int, np.integer)) or not 0 <= int(episode) < len(eps):
        raise ExportError(f"{recording}: episode {episode} out of range: the file has {len(eps)} "
                          f"episode{'s' if len(eps) != 1 else ''} (0..{len(eps) - 1})")
    ep = eps[int(episode)]
    if ep.steps == 0:
        raise ExportError(f"{recording}: episode {episode} has no frames")
    return ep


def _num(v: Any) -> Any:
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, (bool, int, str)):
        return v
    if isinstance(v, (np.integer, np.bool_)):
        return v.item()
    return str(v)


def pack_episode(ep: EpisodeData, *, max_frames: int = DEFAULT_MAX_FRAMES, title: str = "") -> dict[str, Any]:
    """The JSON payload of an export: float32 positions (S, N, 3) in base64, times, target, a few scalar
    series, the static obstacles and the rod layout (``rod_offsets``, :func:`rod_offsets`)."""
    pos = np.asarray(ep.positions, np.float32)
    if pos.ndim != 3 or pos.shape[2] != 3 or pos.shape[0] == 0:
        raise ExportError(f"episode positions have shape {pos.shape}, expected (frames, nodes, 3)")
    if not np.isfinite(pos).all():
        raise ExportError("episode positions contain NaN/inf: nothing sensible to draw")
    idx = frame_indices(pos.shape[0], max_frames)
    t = np.asarray(ep.sim_time, np.float64)[idx]
    series = {}
    for name in SERIES:
        s = ep.scalars.get(name)
        if s is not None and np.isfinite(s).any():
            series[name] = [_num(x) for x in np.asarray(s, np.float64)[idx]]
    tg = None if ep.target_pos is None else np.asarray(ep.target_pos, np.float32)[idx]
    m = ep.meta
    return {
        "version": 1,
        "title": title or f"{m.get('task', 'episode')}  ep {m.get('episode', '?')}  ({m.get('policy', '')})",
        "meta": {k: _num(m[k]) for k in META_KEYS if k in m},
        "n_frames": int(len(idx)), "n_nodes": int(pos.shape[1]), "frame_index": idx.tolist(),
        "positions": b64_f32(pos[idx]),
        "time": [float(x) for x in t],
        "target": None if tg is None else b64_f32(tg),
        "series": series,
        "rod_radius": float(ep.scene.rod_radius), "planar": bool(ep.scene.planar),
        "rod_offsets": rod_offsets(ep),
        "obstacles": obstacle_lists(ep.scene),
    }


def episode_html(ep: EpisodeData, *, max_frames: int = DEFAULT_MAX_FRAMES, title: str = "") -> str:
    """The standalone HTML page of an episode (a string)."""
    data = pack_episode(ep, max_frames=max_frames, title=title)
    # JSON inside <script>: escape '<', '>' and '&' so no recorded string can close the element
    blob = json.dumps(data, separators=(",", ":"), allow_nan=False)
    blob = blob.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")
    return PAGE.replace("__TITLE__", html.escape(data["title"])).replace("__DATA__", blob)


def unpack_html(text: str) -> dict[str, Any]:
    """Read the payload back from an exported page; ``positions`` and ``target`` as numpy arrays."""
    mt = _DATA_RE.search(text)
    if mt is None:
        raise ExportError("not a rodlab episode export (no embedded data)")
    d = json.loads(mt.group(1))
    pos = np.frombuffer(base64.b64decode(d["positions"]), "<f4")
    d["positions"] = pos.reshape(d["n_frames"], d["n_nodes"], 3)
    if d["target"] is not None:
        d["target"] = np.frombuffer(base64.b64decode(d["target"]), "<f4").reshape(d["n_frames"], 3)
    return d


def export_html(ep: EpisodeData, out: str | Path, *, max_frames: int = DEFAULT_MAX_FRAMES, title: str = "") -> Path:
    """Write the standalone HTML page of ``ep`` to ``out`` (atomically); returns the path."""
    p = check_out(out, ".html")
    return atomicio.write_text(p, episode_html(ep, max_frames=max_frames, title=title), mkdir=False)


def export_to_folder(ep: EpisodeData, folder: str | Path, stem: str, *, frame: int | None = None) -> Path:
    """For the workbench's export buttons: write ``<folder>/<stem>.html`` (the player), or with ``frame``
    ``<folder>/<stem>_f<frame>.png``; ``stem`` is a plain file name (no folders), so nothing is written
    outside ``folder``."""
    if not re.fullmatch(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,100}", stem or "") or ".." in stem:
        raise ExportError(f"{stem!r}: use a plain file name (letters, digits, '_', '-', '.')")
    folder = Path(folder)
    if not folder.is_dir():
        raise ExportError(f"{folder}: no such folder")
    if frame is None:
        return export_html(ep, folder / f"{stem}.html")
    return export_png(ep, frame, folder / f"{stem}_f{int(frame)}.png")


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(
        prog="rodlab export",
        description="Export a recorded episode: a standalone HTML player (opens from file://, no server) "
                    "and/or a PNG of one frame.")
    ap.add_argument("recording", help="recording .rrd")
    ap.add_argument("--episode", type=int, default=0, help="episode index, 0-based as `rodlab inspect` lists "
                    "them (default 0)")
    ap.add_argument("--html", help="write the standalone HTML player here (.html)")
    ap.add_argument("--png", help="write a PNG of one frame here (.png)")
    ap.add_argument("--gif", help="write an animated GIF of the episode here (.gif)")
    ap.add_argument("--speed", type=float, default=1.0, help="GIF playback speed relative to simulated time "
                    "(default 1)")
    ap.add_argument("--frame", type=int, default=None, help="frame of the PNG, 0-based (default: last frame)")
    ap.add_argument("--max-frames", type=int, default=DEFAULT_MAX_FRAMES,
                    help=f"decimate longer episodes to this many frames in the HTML (default {DEFAULT_MAX_FRAMES})")
    a = ap.parse_args(argv)
    if not a.html and not a.png and not a.gif:
        ap.error("nothing to do: give --html OUT.html, --png OUT.png and/or --gif OUT.gif")
    if a.frame is not None and not a.png:
        ap.error("--frame applies to --png")
    try:
        for out, suf in ((a.html, ".html"), (a.png, ".png"), (a.gif, ".gif")):
            if out:
                check_out(out, suf)
        ep = load_episode(a.recording, a.episode)
        if a.html:
            p = export_html(ep, a.html, max_frames=a.max_frames)
            print(f"wrote {p} ({p.stat().st_size / 1024:.0f} KiB, {min(ep.steps, a.max_frames)} frames)")
        if a.png:
            frame = ep.steps - 1 if a.frame is None else a.frame
            p = export_png(ep, frame, a.png)
            print(f"wrote {p} (frame {frame})")
        if a.gif:
            p = export_gif(ep, a.gif, speed=a.speed)
            print(f"wrote {p} ({p.stat().st_size / 1024:.0f} KiB)")
    except (RecordingError, ExportError) as exc:
        print(f"rodlab export: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"rodlab export: cannot write: {exc}", file=sys.stderr)
        return 2
    return 0
