"""GUI: a screenshot of the 3-D view and a video of the open replay, grabbed from the page that asked
(``workbench.view.render``), written into the recordings folder. Progress and ETA show in the status line. The
video looks from the page's direction at the whole episode (framed to every frame's rod, targets and obstacles), and
the page's view comes back afterwards."""
from __future__ import annotations

import threading
import time

import numpy as np

from workbench.panels.host import PanelHost
from workbench.view import (
    CAMERAS,
    MAX_VIDEO_FRAMES,
    SWAP_DELAY,
    RenderError,
    fit_camera_along,
    has_mp4_writer,
    place_camera,
    record_replay,
    screenshot,
)


class RenderPanel:
    def __init__(self, app: PanelHost):
        self.app = app
        gui = app.server.gui
        kind = "MP4" if has_mp4_writer() else "animated GIF (no ffmpeg writer installed)"
        with app.tabs["Recordings"], gui.add_folder("Picture / video of the view"):
            self.shot_btn = gui.add_button("Screenshot", hint="save this page's 3-D view as a PNG in the recordings "
                                                              "folder")
            self.video_btn = gui.add_button("Record video", hint=f"play the open recording frame by frame (at most "
                                                                 f"{MAX_VIDEO_FRAMES} frames) and save the view as "
                                                                 f"an {kind} in the recordings folder")
            self.cancel_btn = gui.add_button("Cancel video", hint="stop the video being recorded", visible=False)
            self.msg = gui.add_markdown("")
        self.thread: threading.Thread | None = None
        self._cancel = threading.Event()
        self.last_path = None
        self.last_error: str | None = None
        self._wire()

    def _client(self, event):
        c = getattr(event, "client", None)
        if c is not None:
            return c
        clients = self.app.server.get_clients()
        if not clients:
            raise RenderError("no page is connected")
        return clients[max(clients)]

    def _say(self, text: str) -> None:
        self.msg.content = text

    def _wire(self) -> None:
        @self.shot_btn.on_click
        def _(event) -> None:
            self.take_screenshot(self._client(event))

        @self.video_btn.on_click
        def _(event) -> None:
            self.start_video(self._client(event))

        @self.cancel_btn.on_click
        def _(_e) -> None:
            self._cancel.set()

    def close(self, timeout: float = 10.0) -> None:
        """The session ends: a video being recorded is cancelled and waited for."""
        self._cancel.set()
        t = self.thread
        if t is not None and t.is_alive() and t is not threading.current_thread():
            t.join(timeout)

    def take_screenshot(self, client):
        try:
            out = screenshot(client, self.app.files.recordings)
        except (RenderError, OSError, TimeoutError) as exc:
            self._say(f"⚠ screenshot failed: {exc}")
            return None
        except RuntimeError:  # viser: the page went away (closed, reloaded) before its frame came back
            if self._connected(client):
                raise
            self._say("⚠ screenshot not taken: the page that asked for it has closed")
            return None
        self.last_path = out
        self._say(f"saved {out.name} to the recordings folder")
        return out

    def start_video(self, client) -> threading.Thread | None:
        """Record the open replay in a background thread (one at a time)."""
        rs = self.app.wb.replay
        if rs is None or self.app.wb.mode != "replay":
            self._say("open a recording first (Recordings tab)")
            return None
        if self.thread is not None and self.thread.is_alive():
            self._say("a video is being recorded")
            return None
        self._cancel.clear()
        self.last_error = None
        t = threading.Thread(target=self._record, args=(client, rs), name="rodlab-video", daemon=True)
        t.start()  # started before it is published: a watcher never sees a thread that is not alive yet
        self.thread = t
        return t

    def _connected(self, client) -> bool:
        return getattr(client, "client_id", None) in self.app.server.get_clients()

    def _frame_episode(self, client, rs) -> None:
        """Point ``client``'s camera, from the direction it looks from, at the whole episode: every frame's rod, its
        targets and the obstacles fill the view (the rod is as large in the video as its motion allows)."""
        with self.app.wb.lock:
            fr = rs.frame()
            pos = np.asarray(rs.ep.positions, np.float64).reshape(-1, 3)
        pts = np.vstack([self.app.view.fit_points(fr), pos])
        d = np.asarray(client.camera.position, np.float64) - np.asarray(client.camera.look_at, np.float64)
        if not (np.isfinite(d).all() and np.linalg.norm(d) > 1e-9):
            d = np.asarray(CAMERAS["iso"], np.float64)
        place_camera(client, *fit_camera_along(d, pts))

    def _record(self, client, rs) -> None:
        app, wb = self.app, self.app.wb
        start, rs.playing = rs.index, False
        stem = f"{rs.path.stem if rs.path else 'episode'}_ep{rs.episode_index}"

        def draw(i: int) -> float:
            with wb.lock:
                rs.seek(i)
                fr = rs.frame()
            app._render(fr)
            time.sleep(SWAP_DELAY)  # the page parses the frame's tube (view_rod), then it is shown whole
            app.view.flush()
            return fr.time

        def progress(text: str) -> None:
            app.status_note = f"recording video · {text}"
            self._say(app.status_note)

        self.cancel_btn.visible = True
        view0 = _view_of(client)  # None while the page has not reported its camera
        try:
            if view0 is not None:
                self._frame_episode(client, rs)
            out = record_replay(client, draw, rs.length, app.files.recordings, stem, speed=rs.speed,
                                progress=progress, cancelled=self._cancel.is_set)
        except (RenderError, OSError, TimeoutError, ValueError) as exc:
            self.last_error = str(exc)
            self._say(f"⚠ video not written: {exc}")
        except RuntimeError as exc:  # viser: the page went away (closed, reloaded) before a frame came back
            if self._connected(client):
                raise
            self.last_error = f"the page closed before the video was done ({exc})"
            self._say("⚠ video not written: the page that asked for it has closed")
        else:
            self.last_path = out
            self._say(f"saved {out.name} to the recordings folder")
        finally:
            if view0 is not None and self._connected(client):
                place_camera(client, *view0)  # the page's own view again
            app.status_note = ""
            self.cancel_btn.visible = False
            with wb.lock:
                rs.seek(start)
            app.request_render()


def _view_of(client) -> tuple[tuple, tuple] | None:
    """(position, look-at) of ``client``'s camera, or None before the page has reported one."""
    try:
        cam = client.camera
        return tuple(cam.position), tuple(cam.look_at)
    except (AssertionError, ValueError, AttributeError):
        return None
