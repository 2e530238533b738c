"""GUI: time-series plots (uPlot) of the live session or of the open recording (``workbench.session.plots`` lays them out).

Live: every scalar of the last ``LIVE_WINDOW`` frames (reward and its terms, tip/orientation error, contact force,
Newton iterations, ...) and the values at the pinned nodes (curvature, moments, axial force: ``workbench.session.pins``), the
episode before the last reset dashed, never joined to the current one. Replay: every
scalar recorded in the episode, with a vertical cursor at the timeline position. First plot: the curvature along the
rod, commanded against actual per component (``workbench.session.rod_curves``), of the live rod or of the replayed frame.
"""
from __future__ import annotations

import time

import numpy as np
from viser import uplot

from workbench.panels.host import PanelHost
from workbench.session import (
    PinSeries,
    Plot,
    curvature_plot,
    layout,
    live_curves,
    live_series,
    replay_curves,
    y_ticks,
)

LIVE_WINDOW = 400  # frames shown in the live plots
#: the Plots tab's "Plot height" choices: each plot's width over its height
PLOT_ASPECTS = {"compact": 2.2, "tall": 1.3, "taller": 0.8}


def _x_range(p: Plot) -> tuple[float, float]:
    """x range of a plot: its data, with 10 % room on the right for live data arriving before the next rescale."""
    x = p.data[0]
    x0, x1 = (float(x[0]), float(x[-1])) if len(x) else (0.0, 1.0)
    span = max(x1 - x0, 1e-6)
    return x0, x1 + (0.1 * span if p.x_room else 0.0)


class PlotsPanel:
    """The Plots tab. Only the stepping thread draws it (``update_status``, from the app's redraw): the page's
    callbacks (a replay's timeline, the plot height) ask for a redraw instead, since viser lets one thread at a time
    enter the tab and the handles here are shared."""

    def __init__(self, app: PanelHost, container=None):
        self.app = app
        self.folder = container if container is not None else app.tabs["Plots"]
        self.handles: dict[str, object] = {}
        self._sig: dict[str, tuple] = {}
        self._range: dict[str, tuple[float, float]] = {}
        self._xrange: dict[str, tuple[float, float]] = {}
        self._replay_key: tuple | None = None
        self._replay_asked = 0  # bumped by request_replay(force=True): the next redraw draws the episode afresh
        self._aspect_shown = self.aspect = PLOT_ASPECTS["compact"]
        self.shown: list[Plot] = []  # what the page shows now (tests read it)
        self.pin_series = PinSeries()  # the pinned nodes' values over the live history
        with self.folder:
            self.height = app.server.gui.add_dropdown(
                "Plot height", tuple(PLOT_ASPECTS), initial_value="compact",
                hint="how tall each plot is drawn (taller plots: more room for the y axis; the panel scrolls)")
        app.checks.track(self.height)

        @self.height.on_update
        def _(_e) -> None:
            if app.checks.option(self.height, lambda msg: setattr(app, "notice", (f"⚠ {msg}", time.monotonic()))):
                self.set_aspect(PLOT_ASPECTS[self.height.value])

    def set_aspect(self, aspect: float) -> None:
        """Draw every plot ``aspect`` times as wide as tall (the plots shown now, at the next redraw, and those made
        later)."""
        self.aspect = float(aspect)
        self.app.request_render()

    def request_replay(self, *, force: bool = False) -> None:
        """Show the open episode at its timeline position at the next redraw (``force``: drawn afresh even if the
        episode and position look unchanged, e.g. a recording opened again)."""
        if force:
            self._replay_asked += 1
        self.app.request_render()

    # ------------------------------------------------------------------ drawing
    def show(self, plots: list[Plot]) -> None:
        if self._aspect_shown != self.aspect:
            self._aspect_shown = aspect = self.aspect
            for h in self.handles.values():
                h.aspect = aspect
        keys = [p.key for p in plots]
        for k in list(self.handles):
            if k not in keys:
                self._drop(k)
        for i, p in enumerate(plots):
            h = self.handles.get(p.key)
            if h is not None and self._sig[p.key] != (p.signature, i):
                self._drop(p.key)
                h = None
            if h is None:
                self._create(p, i)
                continue
            (lo, hi), (x0, x1) = self._range[p.key], self._xrange[p.key]
            xr = _x_range(p)
            if (p.y[0] < lo or p.y[1] > hi or (hi - lo) > 4.0 * (p.y[1] - p.y[0])
                    or xr[0] > x0 + 0.1 * (x1 - x0) or xr[0] < x0 or float(p.data[0][-1]) > x1):
                self._range[p.key], self._xrange[p.key] = p.y, xr
                h.scales = self._scales(p.y, xr)
                h.axes = self._axes(p.y)
            h.data = p.data
        self.shown = plots

    def _drop(self, key: str) -> None:
        self.handles.pop(key).remove()
        self._sig.pop(key, None)
        self._range.pop(key, None)
        self._xrange.pop(key, None)

    @staticmethod
    def _scales(y: tuple[float, float], x: tuple[float, float]) -> dict:
        # fixed ranges: uPlot's own y range is NaN when a series starts with NaN (see workbench.session.plots), and viser's
        # wrapper does not move an automatic x range along with live data
        return {"x": {"time": False, "auto": False, "range": [float(x[0]), float(x[1])]},
                "y": {"auto": False, "range": [float(y[0]), float(y[1])]}}

    @staticmethod
    def _axes(y: tuple[float, float]) -> tuple[dict, dict]:
        """The x axis as uPlot draws it; the y axis with the ticks and labels of ``workbench.session.plots.y_ticks`` (every
        digit a value needs), wide enough for its longest label."""
        splits, labels = y_ticks(*y)
        width = 16 + 7 * max((len(t) for t in labels), default=4)
        return {}, {"splits": list(splits), "values": list(labels), "size": width}

    def _create(self, p: Plot, order: int) -> None:
        series = [uplot.Series(label=p.labels[0])]
        for label, color, dashed in zip(p.labels[1:], p.colors[1:], p.dashed[1:]):
            s = uplot.Series(label=label, stroke=color, width=1.5 if label == "timeline" else 2)
            if dashed:
                s["dash"] = [6, 4]
            series.append(s)
        with self.folder:
            self.handles[p.key] = self.app.server.gui.add_uplot(
                data=p.data, series=tuple(series), scales=self._scales(p.y, _x_range(p)), axes=self._axes(p.y),
                title=p.title,
                aspect=self.aspect, order=1000.0 + order)
        self._sig[p.key] = (p.signature, order)
        self._range[p.key], self._xrange[p.key] = p.y, _x_range(p)

    # ------------------------------------------------------------------ sources
    def show_replay(self, session, *, force: bool = False) -> None:
        """Every scalar of the open episode, cursor at the timeline position."""
        key = (self._replay_asked, id(session), session.episode_index, session.index)
        if not force and key == self._replay_key:
            return
        self._replay_key = key
        ep = session.ep
        t = np.asarray(ep.sim_time, dtype=np.float64)
        vals = {name: np.asarray(v, dtype=np.float64) for name, v in ep.scalars.items()}
        curv = curvature_plot(replay_curves(ep, session.index)) if session.length else None
        self.show(([curv] if curv is not None else []) + layout(t, vals, cursor=float(t[session.index]) if len(t) else None))

    def update_live(self) -> None:
        wb = self.app.wb
        with wb.lock:
            items = wb.history._items[-LIVE_WINDOW:]
            dt = float(wb.live.dt)
            sim = wb.live.sim
        curv = curvature_plot(live_curves(wb))
        head = [curv] if curv is not None else []
        if len(items) < 2:
            self.show(head)
            return
        x, episode, vals = live_series(items, dt)
        vals.update(self.pin_series.series(sim, items, self.app.view.pins))
        self.show(head + layout(x, vals, episode=episode, x_label="session time [s]"))

    def update_status(self) -> None:
        wb = self.app.wb
        if wb.mode == "replay" and wb.replay is not None:
            self.show_replay(wb.replay)
        else:
            self._replay_key = None
            self.update_live()
