"""Pictures of a recorded episode, drawn with matplotlib (no browser): a PNG of one frame and an animated GIF
of the episode, in the default view of the HTML player (:mod:`policies.recording.export`): oblique for 3-D tasks, facing
the x-z plane for planar ones. Files are written atomically (:mod:`sim.support.atomicio`).
"""
from __future__ import annotations

import gc
import math
from pathlib import Path
from typing import Any

import numpy as np
from sim.support import atomicio

from policies.recording.schema import EpisodeData

from .export_data import ExportError, check_out, frame_indices, mesh_edges, obstacle_lists, rod_offsets

__all__ = ["export_png", "export_gif", "render_frame"]

GIF_MAX_FRAMES = 300


def _view_basis(planar: bool) -> tuple[np.ndarray, np.ndarray]:
    """Screen right/up vectors of the page's default view (iso, or front for planar tasks)."""
    az, el = (math.radians(-90), 0.0) if planar else (math.radians(-60), math.radians(22))
    e = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    r = np.array([-math.sin(az), math.cos(az), 0.0])
    return r, np.cross(e, r)


def export_png(ep: EpisodeData, frame: int, out: str | Path, *, width: int = 960, height: int = 720) -> Path:
    """Write a PNG of frame ``frame`` of ``ep`` (the HTML page's default view) to ``out`` atomically."""
    if not isinstance(frame, (int, np.integer)) or not 0 <= int(frame) < ep.steps:
        raise ExportError(f"frame {frame} out of range: the episode has {ep.steps} frames (0..{ep.steps - 1})")
    p = check_out(out, ".png")
    fig = _figure(ep, int(frame), width, height)
    return atomicio.write_via_path(p, lambda tmp: fig.savefig(tmp, format="png", dpi=100), mkdir=False)


def _figure(ep: EpisodeData, frame: int, width: int, height: int) -> Any:
    """A matplotlib Figure of one frame (Agg canvas; pyplot is not used)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pos = np.asarray(ep.positions, np.float64)
    if not np.isfinite(pos[frame]).all():
        raise ExportError(f"frame {frame}: positions contain NaN/inf")
    r, u = _view_basis(bool(ep.scene.planar))

    def xy(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a = np.asarray(a, np.float64).reshape(-1, 3)
        return a @ r, a @ u

    fig = Figure(figsize=(width / 100, height / 100), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_aspect("equal")
    ax.axis("off")
    allp = pos[np.isfinite(pos).all(axis=2)]
    X, Y = xy(allp)
    span = max(float(np.ptp(X)), float(np.ptp(Y)), 0.1) * 0.6 + 2 * ep.scene.rod_radius
    cx, cy = 0.5 * (X.min() + X.max()), 0.5 * (Y.min() + Y.max())
    ax.set_xlim(cx - span * width / height, cx + span * width / height)
    ax.set_ylim(cy - span, cy + span)
    pts_per_m = height / 100 * 72 / (2 * span)
    sc = ep.scene
    grey = (0.43, 0.45, 0.51, 0.45)
    from matplotlib.patches import Circle
    if sc.capsules is not None:
        for ab, rad in zip(sc.capsules, sc.capsule_radii):
            x, y = xy(ab)
            if math.hypot(x[1] - x[0], y[1] - y[0]) < 0.5 * rad:  # seen end-on: a disc
                ax.add_patch(Circle((x[0], y[0]), rad, color=grey))
            else:
                ax.plot(x, y, color=grey, lw=max(1.0, 2 * rad * pts_per_m), solid_capstyle="round")
    if sc.sphere_centers is not None:
        for c, rad in zip(sc.sphere_centers, sc.sphere_radii):
            x, y = xy(c)
            ax.add_patch(Circle((x[0], y[0]), rad, color=grey))
    for b in obstacle_lists(sc)["boxes"]:
        c, h, q = np.array(b[:3]), np.array(b[3:6]), np.array(b[6:10])
        from scipy.spatial.transform import Rotation
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
        cs = c + Rotation.from_quat(q).apply(corners)
        for i in range(8):
            for bit in (1, 2, 4):
                j = i ^ bit
                if i < j:
                    ax.plot(*xy(cs[[i, j]]), color=(0.27, 0.29, 0.35), lw=1)
    for v, f in sc.meshes:
        v = np.asarray(v).reshape(-1, 3)
        for i, j in mesh_edges(np.asarray(f, np.int64).reshape(-1, 3))[:5000]:
            ax.plot(*xy(v[[i, j]]), color=(0.27, 0.29, 0.35), lw=0.5)
    tip = pos[: frame + 1, -1]
    ax.plot(*xy(tip), color=(0.9, 0.55, 0.12, 0.6), lw=1.2)
    rx, ry = xy(pos[frame])
    n = len(rx)
    joints = {int(j) - 1 for j in rod_offsets(ep)[1:-1]}  # edges joining two rods: not drawn
    for k in range(n - 1):
        if k in joints:
            continue
        t = k / max(1, n - 2)
        col = tuple((np.array([24, 54, 140]) + t * (np.array([60, 190, 210]) - np.array([24, 54, 140]))) / 255)
        ax.plot(rx[k:k + 2], ry[k:k + 2], color=col, lw=max(3.0, 2 * sc.rod_radius * pts_per_m),
                solid_capstyle="round")
    ax.plot(rx[:1], ry[:1], "s", color="#111", ms=6)
    if ep.target_pos is not None and np.isfinite(ep.target_pos[frame]).all():
        tx, ty = xy(ep.target_pos[frame])
        ax.plot(tx, ty, marker="+", ms=14, mew=2, color="#d62728", zorder=5)
        ax.plot(tx, ty, marker="o", ms=12, mfc="none", mew=2, color="#d62728", zorder=5)
    m = ep.meta
    ax.text(0.01, 0.99, f"{m.get('task', '')}  ep {m.get('episode', '?')}\nframe {frame} / {ep.steps - 1}  "
            f"t = {float(ep.sim_time[frame]):.3f} s", transform=ax.transAxes, va="top", fontsize=10)
    return fig


def render_frame(ep: EpisodeData, frame: int, *, width: int = 640, height: int = 480) -> np.ndarray:
    """Frame ``frame`` drawn as an (height, width, 3) uint8 image."""
    fig = _figure(ep, int(frame), width, height)
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()


def export_gif(ep: EpisodeData, out: str | Path, *, max_frames: int = GIF_MAX_FRAMES, speed: float = 1.0,
               width: int = 640, height: int = 480) -> Path:
    """Write an animated GIF of the episode (at most ``max_frames`` evenly spaced frames, shown at ``speed``
    times simulated time, looping) to ``out`` atomically."""
    from PIL import Image


    if not (isinstance(speed, (int, float)) and math.isfinite(speed) and speed > 0):
        raise ExportError(f"speed must be a positive number (got {speed!r})")
    p = check_out(out, ".gif")
    pos = np.asarray(ep.positions)
    if not np.isfinite(pos).all():
        raise ExportError("episode positions contain NaN/inf: nothing sensible to draw")
    idx = frame_indices(ep.steps, max_frames)
    # each frame kept in the palette form the GIF writer turns it into anyway (a third of its RGB bytes); the
    # frames' matplotlib figures hold reference cycles, collected here rather than left to a full collection,
    # which a long session runs seldom
    imgs = [Image.fromarray(render_frame(ep, int(k), width=width, height=height)).convert(
        "P", palette=Image.Palette.ADAPTIVE) for k in idx]
    gc.collect()
    t = np.asarray(ep.sim_time, np.float64)[idx]
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2] if len(t) > 1 else 0.1))
    ms = [int(max(20, min(5000, round(1000 * d / speed)))) if math.isfinite(d) else 100 for d in dt]

    def write(tmp: str) -> None:
        imgs[0].save(tmp, format="GIF", save_all=True, append_images=imgs[1:], duration=ms, loop=0)

    return atomicio.write_via_path(p, write, mkdir=False)
