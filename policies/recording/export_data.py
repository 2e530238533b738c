"""What every export format of a recorded episode shares (``policies.recording.export``: HTML player; ``policies.recording.export_image``:
PNG / GIF; ``workbench.view.render``): the error type, the frames kept, where each rod starts, the obstacles as
plain lists and the output-name check."""
from __future__ import annotations

import base64
from pathlib import Path
from typing import Any

import numpy as np

from policies.recording.schema import EpisodeData

__all__ = ["MAX_MESH_EDGES", "ExportError", "b64_f32", "mesh_edges", "obstacle_lists", "frame_indices", "rod_offsets",
           "check_out"]

MAX_MESH_EDGES = 50_000


class ExportError(ValueError):
    """Bad export request (episode or frame out of range, unusable output path)."""


def b64_f32(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a, dtype="<f4").tobytes()).decode("ascii")


def mesh_edges(faces: np.ndarray) -> np.ndarray:
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    e = np.unique(np.sort(e, axis=1), axis=0)
    return e[:MAX_MESH_EDGES]


def obstacle_lists(sc: Any) -> dict[str, Any]:
    out: dict[str, Any] = {"capsules": [], "spheres": [], "boxes": [], "meshes": []}
    if sc.capsules is not None:
        for ab, r in zip(np.asarray(sc.capsules, float), np.asarray(sc.capsule_radii, float)):
            out["capsules"].append([*map(float, ab.reshape(6)), float(r)])
    if sc.sphere_centers is not None:
        for c, r in zip(np.asarray(sc.sphere_centers, float), np.asarray(sc.sphere_radii, float)):
            out["spheres"].append([*map(float, c), float(r)])
    if sc.box_centers is not None:
        n = len(sc.box_centers)
        quats = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)) if sc.box_quats is None else np.asarray(sc.box_quats, float)
        for c, h, q in zip(np.asarray(sc.box_centers, float), np.asarray(sc.box_half_sizes, float), quats):
            out["boxes"].append([*map(float, c), *map(float, h), *map(float, q)])
    for v, f in sc.meshes:
        out["meshes"].append({"v": b64_f32(np.asarray(v).reshape(-1, 3)),
                              "e": mesh_edges(np.asarray(f, np.int64).reshape(-1, 3)).reshape(-1).tolist()})
    return out


def frame_indices(n_frames: int, max_frames: int) -> np.ndarray:
    """Frames kept in an export: all of them, or ``max_frames`` evenly spaced ones (first and last kept)."""
    if max_frames < 2:
        raise ExportError(f"max_frames must be >= 2 (got {max_frames})")
    if n_frames <= max_frames:
        return np.arange(n_frames)
    return np.unique(np.round(np.linspace(0, n_frames - 1, max_frames)).astype(np.int64))


def rod_offsets(ep: EpisodeData) -> list[int]:
    """Where each rod's nodes start in the episode's centreline, then N (``[0, N]``: one rod, also for a
    recording that stores no rod layout); the edge from one rod's last node to the next rod's first is not drawn."""
    off = getattr(ep.scene, "rod_node_offsets", None)
    n = int(np.asarray(ep.positions).shape[1])
    return [0, n] if off is None else [int(k) for k in off]


def check_out(out: str | Path, suffix: str) -> Path:
    p = Path(out)
    if p.suffix.lower() != suffix:
        raise ExportError(f"{p}: the output file name must end in {suffix}")
    if p.is_dir():
        raise ExportError(f"{p}: is a folder")
    if not p.parent.is_dir():
        raise ExportError(f"{p}: folder {p.parent} does not exist")
    return p
