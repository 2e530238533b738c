"""Pictures and videos of the 3-D view as the browser draws it (viser's ``client.camera.get_render``).

* :func:`screenshot`: the current view of one page as a PNG;
* :func:`record_replay`: every frame of the open replay (at most ``max_frames``, evenly spaced) drawn in the page
  and grabbed one by one, written as an MP4 when an ffmpeg writer is installed (``imageio-ffmpeg``), else as an
  animated GIF (Pillow), played at the recorded time × ``speed``.

Files go into the recordings folder only (plain names made here, never a path from the page) and are written
atomically (:mod:`sim.support.atomicio`).
"""
from __future__ import annotations

import io
import math
import time
from pathlib import Path
from typing import Callable

import numpy as np

from policies.recording import frame_indices
from sim.support import atomicio

MAX_WIDTH = 960  # [px] grabbed frames are at most this wide (the page's aspect ratio is kept)
MAX_VIDEO_FRAMES = 300


class RenderError(RuntimeError):
    pass


def has_mp4_writer() -> bool:
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        return False
    return True


def _size(client, max_width: int = MAX_WIDTH) -> tuple[int, int]:
    w, h = int(client.camera.image_width), int(client.camera.image_height)
    if w <= 0 or h <= 0:
        raise RenderError("the page has not reported its view size yet")
    s = min(1.0, max_width / w)
    return max(2, int(h * s) // 2 * 2), max(2, int(w * s) // 2 * 2)  # even sizes (video encoders want them)


def grab(client, *, max_width: int = MAX_WIDTH, timeout: float = 30.0) -> np.ndarray:
    """(H, W, 3) uint8 picture of ``client``'s current view."""
    h, w = _size(client, max_width)
    img = np.asarray(client.camera.get_render(h, w, transport_format="png", timeout=timeout))
    if img.ndim != 3 or img.shape[2] < 3:
        raise RenderError(f"unexpected picture from the page: shape {img.shape}")
    if img.shape[2] == 4:  # transparent background -> white
        a = img[..., 3:4].astype(np.float64) / 255.0
        img = (img[..., :3] * a + 255.0 * (1.0 - a)).astype(np.uint8)
    return img


def unique_name(folder: Path, stem: str, suffix: str) -> Path:
    """``folder/stem.suffix``, or ``stem_2``, ``stem_3`` … when taken."""
    p = folder / f"{stem}{suffix}"
    k = 2
    while p.exists():
        p = folder / f"{stem}_{k}{suffix}"
        k += 1
    return p


def screenshot(client, folder: Path, stem: str = "screenshot") -> Path:
    """Write the page's current view as ``folder/<stem>[_k].png``."""
    from PIL import Image

    img = grab(client)
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="PNG")
    return atomicio.write_bytes(unique_name(Path(folder), stem, ".png"), buf.getvalue(), mkdir=False)


def eta_text(done: int, total: int, elapsed: float) -> str:
    """'frame k / n · ETA 12 s' (no ETA before the first frame)."""
    if done <= 0:
        return f"frame 0 / {total}"
    left = elapsed / done * (total - done)
    return f"frame {done} / {total} · ETA {left:.0f} s"


def record_replay(client, draw: Callable[[int], float], length: int, folder: Path, stem: str, *,
                  max_frames: int = MAX_VIDEO_FRAMES, speed: float = 1.0, mp4: bool | None = None,
                  progress: Callable[[str], None] | None = None, cancelled: Callable[[], bool] | None = None,
                  max_width: int = 640) -> Path:
    """Draw frames ``0 … length-1`` (evenly spaced, at most ``max_frames``) with ``draw(i) -> sim time [s]``, grab
    each from the page and write ``folder/<stem>.mp4`` (or ``.gif``). ``progress`` gets 'frame k / n · ETA …'."""
    from PIL import Image

    if not (isinstance(speed, (int, float)) and math.isfinite(speed) and speed > 0):
        raise RenderError(f"speed must be a positive number (got {speed!r})")
    if length < 1:
        raise RenderError("the episode has no frames")
    mp4 = has_mp4_writer() if mp4 is None else mp4
    idx = frame_indices(length, max_frames)
    frames, times = [], []
    t0 = time.perf_counter()
    for k, i in enumerate(idx):
        if cancelled is not None and cancelled():
            raise RenderError("video cancelled")
        times.append(float(draw(int(i))))
        frames.append(grab(client, max_width=max_width))
        if progress is not None:
            progress(eta_text(k + 1, len(idx), time.perf_counter() - t0))
    t = np.asarray(times)
    dt = np.diff(t, append=t[-1] + (t[-1] - t[-2] if len(t) > 1 else 0.1))
    out = unique_name(Path(folder), stem, ".mp4" if mp4 else ".gif")
    if mp4:
        import imageio.v2 as iio

        fps = float(np.clip(speed / max(float(np.median(dt)), 1e-6), 1.0, 60.0))

        def write(tmp: str) -> None:
            with iio.get_writer(tmp, format="FFMPEG", fps=fps, macro_block_size=2) as wr:
                for f in frames:
                    wr.append_data(f)
    else:
        ms = [int(max(20, min(5000, round(1000 * d / speed)))) if math.isfinite(d) else 100 for d in dt]
        imgs = [Image.fromarray(f).quantize(colors=255) for f in frames]

        def write(tmp: str) -> None:
            imgs[0].save(tmp, format="GIF", save_all=True, append_images=imgs[1:], duration=ms, loop=0)
    return atomicio.write_via_path(out, write, mkdir=False)
