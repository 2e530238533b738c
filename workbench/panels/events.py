"""GUI: events on the timeline (``workbench.session.events``) — the Run tab's "Events" folder lists the events near the cursor,
"Previous event" / "Next event" (keys [ and ]) move the cursor to them, and the timeline sliders mark them.

The cursor is the replay's frame while a recording is open (the buttons seek it) and the "Rewind to frame" slider in a
live session (the buttons move the slider; "Rewind" then goes there, as rewinding drops the frames after it)."""
from __future__ import annotations

import time

from viser import _messages as vm

from workbench.panels.host import PanelHost
from workbench.session import Event, episode_events, event_marks, events_summary, live_events, neighbour_event

REFRESH_S = 1.0  # the live session's events are looked for at most this often


def set_marks(slider, frames) -> None:
    """Marks under a slider at ``frames`` (viser keeps them in the slider's private ``_marks`` property)."""
    want = tuple(vm.GuiSliderMark(value=float(f), label=None) for f in frames) or None
    if slider._marks != want:
        slider._marks = want


class EventsPanel:
    def __init__(self, app: PanelHost):
        self.app = app
        gui = app.server.gui
        with app.tabs["Run"], gui.add_folder("Events"):
            self.prev_btn = gui.add_button("Previous event", hint="the event before the cursor (key [): a replay "
                                                                  "seeks there; live, the Rewind slider moves there")
            self.next_btn = gui.add_button("Next event", hint="the event after the cursor (key ])")
            self.list = gui.add_markdown("no events")
        self.events: list[Event] = []
        self._key = None  # what the events were found for
        self._when = 0.0
        self._wire()

    # ------------------------------------------------------------------ finding them
    def _source(self):
        """(key, events-finder) of what the page shows: the open episode, or the live history."""
        wb = self.app.wb
        if wb.mode == "replay" and wb.replay is not None:
            rs = wb.replay
            return ("replay", id(rs), rs.episode_index), lambda: episode_events(rs.ep)
        h = wb.history
        frames = h.scalars()
        return ("live", h.first_index, h.last_index, len(frames)), lambda: live_events(
            frames, first_frame=h.first_index)

    def refresh(self, *, force: bool = False) -> list[Event]:
        """Find the events again when what is shown changed (the live history at most every ``REFRESH_S``)."""
        wb = self.app.wb
        now = time.monotonic()
        if not force and wb.mode != "replay" and now - self._when < REFRESH_S:
            return self.events
        with wb.lock:
            key, find = self._source()
            if key != self._key or force:
                self.events = find()
                self._key = key
        self._when = now
        frames = event_marks(self.events)
        replay = key[0] == "replay"
        set_marks(self.app.replay.timeline, frames if replay else ())
        set_marks(self.app.policy.rewind, () if replay else frames)
        return self.events

    def cursor(self) -> int:
        wb = self.app.wb
        if wb.mode == "replay" and wb.replay is not None:
            return int(wb.replay.index)
        return int(self.app.policy.rewind.value)

    # ------------------------------------------------------------------ moving to them
    def jump(self, step: int) -> Event | None:
        """Move the cursor to the next (``step`` = +1) or previous (−1) event; returns it (None: none there)."""
        self.refresh(force=True)
        ev = neighbour_event(self.events, self.cursor(), step)
        if ev is None:
            self.list.content = f"no event {'after' if step > 0 else 'before'} frame {self.cursor()}"
            return None
        wb = self.app.wb
        if wb.mode == "replay" and wb.replay is not None:
            self.app.replay.timeline.value = ev.frame  # its callback seeks the replay
        else:
            self.app.policy.choose_rewind_frame(ev.frame)
        self._show(ev.frame)
        self.app.request_render()
        return ev

    def _show(self, around: int) -> None:
        text = events_summary(self.events, around)
        if self.list.content != text:
            self.list.content = text

    def update_status(self) -> None:
        self.refresh()
        self._show(self.cursor())

    def _wire(self) -> None:
        @self.prev_btn.on_click
        def _(_e) -> None:
            self.jump(-1)

        @self.next_btn.on_click
        def _(_e) -> None:
            self.jump(+1)
