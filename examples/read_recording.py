"""Read a recording (.rrd) back into numpy arrays.

Purpose: open one of the shipped example recordings (recordings/examples/) with
policies.recording.read_recording, which returns one EpisodeData per episode (positions (S, N, 3), material
frames, curvature, contacts, scalars such as the reward), and print a short summary of each episode.

Run:  .venv/bin/python examples/read_recording.py [FILE.rrd]
      .venv/bin/python examples/read_recording.py --smoke
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from policies.recording import read_recording

ROOT = Path(__file__).resolve().parents[1]


def summarize(path: Path) -> list[dict]:
    """One dict per episode: task, frames, nodes, tip travel [m], return (sum of the logged reward)."""
    rows = []
    for ep in read_recording(path):
        tip = ep.positions[:, -1].astype(np.float64)
        reward = ep.scalars.get("reward")
        rows.append({"task": ep.meta.get("task", "?"), "frames": int(ep.positions.shape[0]),
                     "nodes": int(ep.positions.shape[1]),
                     "tip_travel_m": float(np.linalg.norm(np.diff(tip, axis=0), axis=1).sum()),
                     "return": float(np.nansum(reward)) if reward is not None else float("nan")})
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("file", nargs="?", default=str(ROOT / "recordings/examples/ik4d.rrd"))
    ap.add_argument("--smoke", action="store_true", help="read the default file (used by the tests)")
    a = ap.parse_args(argv)
    for i, r in enumerate(summarize(Path(a.file))):
        print(f"episode {i}: {r['task']}, {r['frames']} frames of {r['nodes']} nodes, "
              f"tip travelled {r['tip_travel_m']:.2f} m, return {r['return']:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
