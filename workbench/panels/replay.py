"""GUI: open a recorded episode (.rrd), scrub its timeline, play at a chosen speed (its plots:
``workbench.panels.plots``)."""
from __future__ import annotations

from pathlib import Path

from policies.recording import ExportError, export_to_folder
from workbench.panels.host import PanelHost
from workbench.session import FileAccessError, ReplaySession, list_recordings, page_error

NONE = "(no recordings)"


class ReplayPanel:
    def __init__(self, app: PanelHost):
        self.app = app
        gui = app.server.gui
        with app.tabs["Recordings"]:
            files = self._files()
            self.file = gui.add_dropdown("Recording", files, initial_value=files[0],
                                         hint=".rrd files in the recordings folder")
            self.open_btn = gui.add_button("Open recording", hint="show the recording (the live session pauses)")
            self.episode = gui.add_dropdown("Episode", ["0"], initial_value="0", hint="episode of the recording")
            self.timeline = gui.add_slider("Timeline", min=0, max=1, step=1, initial_value=0,
                                           hint="frame of the episode (the plots' cursor follows it)")
            self.play = gui.add_checkbox("Play recording", initial_value=False, hint="play from this frame")
            self.speed = gui.add_dropdown("Replay speed [×]", ("0.25", "0.5", "1", "2", "4"), initial_value="1",
                                          hint="times the recorded time")
            self.close_btn = gui.add_button("Close recording", hint="back to the live session")
            self.export_html_btn = gui.add_button(
                "Export HTML", hint="write a standalone player of this episode (opens from file://, no server) "
                                    "into the recordings folder")
            self.export_png_btn = gui.add_button("Export PNG", hint="write a picture of this frame into the "
                                                                    "recordings folder")
            self.msg = gui.add_markdown("")
        self._scrubbing = False
        self._shown_index = 0  # the replay frame the Timeline slider was last set to (by the page or the server)
        for h in (self.file, self.episode, self.timeline, self.speed):
            app.checks.track(h)
        self._wire()

    def _files(self) -> list[str]:
        """Recordings in the recordings folder, named relative to it."""
        root = self.app.recordings_dir
        files = [str(p.relative_to(root)) for p in list_recordings(root) if p.is_relative_to(root)]
        return files or [NONE]

    def refresh_list(self) -> None:
        files = self._files()
        self.file.options = files
        if self.file.value not in files:
            self.file.value = files[0]
        self.app.checks.accept(self.file)
        if getattr(self.app, "compare", None) is not None:
            self.app.compare.refresh_list()

    def _say(self, text: str) -> None:
        self.msg.content = text

    def open_listed(self) -> ReplaySession | None:
        """Open the recording chosen in the page: a listed name, inside the recordings folder."""
        if not self.app.checks.option(self.file, self._say):
            return None
        if self.file.value == NONE:
            self._say("no .rrd files in the recordings folder")
            return None
        path = None
        try:
            path = self.app.files.recording(self.file.value)
            self._say(f"reading {path.name} …")
            return self.open(path)
        except (FileAccessError, OSError, ValueError) as exc:  # RecordingError is a ValueError
            self._say(f"⚠ {page_error(exc, path)}")
            return None

    def open(self, path) -> ReplaySession:
        """Open a recording (trusted callers: tests, screenshots; the page uses :meth:`open_listed`).
        A relative path is taken relative to the recordings folder."""
        p = Path(path)
        p = p if p.is_absolute() else self.app.recordings_dir / p
        session = ReplaySession.open(p)
        session.speed = float(self.speed.value)
        self.app.wb.open_replay(session)
        self.episode.options = [str(i) for i in range(len(session.episodes))]
        self.episode.value = "0"
        self.app.checks.accept(self.episode)
        self._select()
        return session

    def _select(self) -> None:
        s = self.app.wb.replay
        if s is None:
            return
        with self.app.wb.lock:
            s.select(int(self.episode.value))
        self._scrubbing = True
        try:
            self.timeline.max = max(s.length - 1, 1)
            self.timeline.value = 0
        finally:
            self._scrubbing = False
        self._shown_index = 0
        self.app.checks.accept(self.timeline)
        meta = s.ep.meta
        self.msg.content = (f"`{s.path.name if s.path else ''}` · episode {s.episode_index} · {s.length} frames  \n"
                            f"task {meta.get('task', '?')} · policy {meta.get('policy', '?')}")
        self.app.view.sync_obstacles(s.obstacles, None)
        self._plot(force=True)
        self.app.request_render()

    def _wire(self) -> None:
        app, wb, ok = self.app, self.app.wb, self.app.checks

        @self.file.on_update
        def _(_e) -> None:
            ok.option(self.file, self._say)

        @self.open_btn.on_click
        def _(_e) -> None:
            self.open_listed()

        @self.episode.on_update
        def _(_e) -> None:
            if ok.option(self.episode, self._say):
                self._select()

        @self.timeline.on_update
        def _(_e) -> None:
            if self._scrubbing or wb.replay is None or not ok.number(self.timeline, self._say):
                return
            with wb.lock:
                if wb.replay is None:  # closed by another action since the check
                    return
                wb.replay.seek(int(self.timeline.value))
                self._shown_index = wb.replay.index
            self._plot()
            app.request_render()

        @self.play.on_update
        def _(_e) -> None:
            if wb.replay is not None:
                if self.play.value and wb.replay.index >= wb.replay.length - 1:
                    wb.replay.seek(0)
                wb.replay.playing = bool(self.play.value)

        @self.speed.on_update
        def _(_e) -> None:
            if ok.option(self.speed, self._say) and wb.replay is not None:
                wb.replay.speed = float(self.speed.value)

        @self.export_html_btn.on_click
        def _(_e) -> None:
            self.export(png=False)

        @self.export_png_btn.on_click
        def _(_e) -> None:
            self.export(png=True)

        @self.close_btn.on_click
        def _(_e) -> None:
            wb.close_replay()
            self.play.value = False
            self.msg.content = ""
            app.sync_obstacle_view()
            app.request_render()

    def export(self, *, png: bool) -> Path | None:
        """Write the open episode as a standalone HTML player (or the current frame as a PNG) into the
        recordings folder, named after the recording and episode; the message line says where."""

        rs = self.app.wb.replay
        if rs is None:
            self._say("open a recording first")
            return None
        stem = f"{rs.path.stem if rs.path else 'episode'}_ep{rs.episode_index}"
        try:
            out = export_to_folder(rs.ep, self.app.files.recordings, stem, frame=rs.index if png else None)
        except (ExportError, OSError) as exc:
            self._say(f"export failed: {exc}")
            return None
        self._say(f"exported {out.name} to the recordings folder")
        return out

    def _plot(self, force: bool = False) -> None:
        """The Plots tab follows the replay at the next redraw (the stepping thread draws it)."""
        plots = getattr(self.app, "plots", None)
        if plots is not None and self.app.wb.replay is not None:
            plots.request_replay(force=force)

    def update_status(self) -> None:
        wb = self.app.wb
        if wb.mode == "replay" and wb.replay is not None:
            s = wb.replay
            # the server moved the replay (played, stepped with → / Step, an event sought): the slider follows. A
            # frame the page chose is the replay's once its callback has run (then _shown_index is that frame), so a
            # value the page is sending is never put back here.
            if s.index != self._shown_index:
                self._scrubbing = True
                try:
                    self.timeline.value = s.index
                finally:
                    self._scrubbing = False
                self._shown_index = s.index
                self.app.checks.accept(self.timeline)
            if s.playing != bool(self.play.value):  # played or paused from the Run tab (space)
                self.play.value = s.playing
