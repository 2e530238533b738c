"""Time-series plots of the workbench: which scalars go into which plot, and the arrays handed to uPlot.

Pure numpy (no viser): ``workbench.panels.plots`` draws what :func:`layout` returns.

Facts about viser's uPlot client that shape the arrays (checked in headless Chromium):

* data arrive as float arrays, so a gap cannot be sent as ``null``. A NaN sample is skipped by the line
  (the canvas ignores it) but does not break it: the line joins the samples on both sides.
* uPlot's automatic y range starts from the first sample of a series: a leading NaN makes the range NaN and the
  whole plot stays empty. Every plot therefore gets a fixed y range computed here (:func:`y_range`).

Episode resets (sim time going back) therefore never join: the samples of the current episode and of the one
before go into two different series (the previous one dashed); older episodes are left out of the window.
A replay's timeline cursor is a vertical line: two extra samples at the cursor time, NaN in every other series.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from workbench.session.pins import PIN_PLOTS

#: live scalar key (``Frame.scalars``) -> recorded scalar name (docs/architecture.md: recording schema)
LIVE_NAMES = {"reward": "reward", "tip_error": "tip_error", "ori_error": "ori_error",
              "newton_iters": "solver/newton_iters", "contact_force": "contact/max_normal_force",
              "max_penetration": "contact/max_penetration"}
COLORS = ("#d2553c", "#3c78d2", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf")
CURSOR_COLOR = "#222222"
_ORDER = ("reward", "tip_error", "ori_error", "contact/max_normal_force", "contact/max_penetration", "contact/count",
          "solver/newton_iters", "solver/residual", "energy", "solver/wall_time")


def live_name(key: str) -> str | None:
    """Recorded name of a live scalar (``r_<term>`` -> ``reward_terms/<term>``); None for bookkeeping values."""
    if key.startswith("r_"):
        return f"reward_terms/{key[2:]}"
    return LIVE_NAMES.get(key)


def group_of(name: str) -> tuple[str, str]:
    """(plot key, plot title with unit) of a recorded scalar."""
    if name == "reward" or name.startswith("reward_terms/"):
        return "reward", "reward and its terms"
    if name.startswith("energy/"):
        return "energy", "energies [J]"
    prefix = name.split("/", 1)[0]
    if prefix in PIN_PLOTS:
        return prefix, PIN_PLOTS[prefix][0]
    if name in ("solver/newton_iters", "solver/newton_iters_control", "solver/substeps", "solver/converged",
                "solver/midpoint_fallbacks"):
        return "solver/newton_iters", "Newton iterations / substeps"
    titles = {"tip_error": "tip error [m]", "ori_error": "orientation error 1 − (q·q*)² [-]",
              "contact/max_normal_force": "max contact force [N]", "contact/max_penetration": "max penetration [m]",
              "contact/count": "contacts [-]", "solver/residual": "Newton residual [-]",
              "solver/wall_time": "step wall time [s]"}
    return name, titles.get(name, name)


def short_label(name: str) -> str:
    return name.split("/", 1)[1] if "/" in name else name


def y_range(arrays) -> tuple[float, float]:
    """A y range holding every finite value (5 % margin; a flat or empty series gets a unit-sized range)."""
    vals = [np.asarray(a, np.float64) for a in arrays]
    fin = np.concatenate([v[np.isfinite(v)] for v in vals]) if vals else np.zeros(0)
    if fin.size == 0:
        return 0.0, 1.0
    lo, hi = float(fin.min()), float(fin.max())
    span = hi - lo
    if span <= 1e-12 * max(abs(lo), abs(hi), 1.0):
        pad = 0.5 * max(abs(lo), 1e-3)
        return lo - pad, hi + pad
    return lo - 0.05 * span, hi + 0.05 * span


def y_ticks(lo: float, hi: float, count: int = 5) -> tuple[tuple[float, ...], tuple[str, ...]]:
    """Tick values in [``lo``, ``hi``] at a round step (1, 2, 2.5 or 5 × 10^k, about ``count`` of them) and their
    labels, each with the digits the step needs: uPlot's own labels drop them ("0" for 2e-5) and viser cannot pass it
    a formatting function, so the labels are made here. Values under 1e-3 or from 1e5 on (in magnitude) are written
    with an exponent."""
    lo, hi = float(lo), float(hi)
    if not (np.isfinite(lo) and np.isfinite(hi)) or hi <= lo:
        return (), ()
    raw = (hi - lo) / max(count - 1, 1)
    mag = 10.0 ** np.floor(np.log10(raw))
    step = next(m * mag for m in (1.0, 2.0, 2.5, 5.0, 10.0) if m * mag >= raw * (1.0 - 1e-9))
    first = np.ceil(lo / step - 1e-9) * step
    vals = [first + k * step for k in range(int(np.floor((hi - first) / step + 1e-9)) + 1)]
    vals = [0.0 if abs(v) < 1e-9 * step else v for v in vals]
    big = max(abs(lo), abs(hi))
    if big >= 1e5 or big < 1e-3:
        digits = max(0, int(np.ceil(np.log10(big / step) - 1e-9)))  # significant digits beyond the first
        labels = tuple(f"{v:.{digits}e}" for v in vals)
    else:
        decimals = max(0, -int(np.floor(np.log10(step) + 1e-9)) + (1 if step / mag == 2.5 else 0))
        labels = tuple(f"{v:.{decimals}f}" for v in vals)
    return tuple(float(v) for v in vals), labels


def episode_starts(episode: np.ndarray) -> np.ndarray:
    """Indices where a new episode starts (the episode number changes), always including 0."""
    e = np.asarray(episode)
    if e.size == 0:
        return np.zeros(0, dtype=int)
    return np.concatenate([[0], np.nonzero(np.diff(e) != 0)[0] + 1])


def episode_numbers(time: np.ndarray) -> np.ndarray:
    """Episode number per sample: a new episode starts where the sim time goes back (a reset sets it to 0)."""
    t = np.asarray(time, np.float64)
    return np.concatenate([[0], np.cumsum(np.diff(t) < 0)]) if t.size else np.zeros(0, dtype=int)


@dataclasses.dataclass
class Plot:
    """One uPlot: title, series labels/colours/dash (x first) and the data arrays (x first)."""

    key: str
    title: str
    labels: tuple[str, ...]
    colors: tuple[str, ...]
    dashed: tuple[bool, ...]
    data: tuple[np.ndarray, ...]
    y: tuple[float, float]
    x_room: bool = True  # 10 % room on the right of the x range (live time series grow to the right)

    @property
    def signature(self) -> tuple:
        return self.labels, self.colors, self.dashed


def layout(x: np.ndarray, values: dict[str, np.ndarray], *, episode: np.ndarray | None = None,
           cursor: float | None = None, x_label: str = "time [s]") -> list[Plot]:
    """Plots of the named series over ``x`` (ascending).

    Args:
        x: sample positions (seconds), ascending.
        values: recorded name -> samples (same length as ``x``; NaN = not logged at that sample). Series without
            a single finite value are left out.
        episode: per-sample episode number (:func:`episode_numbers`). Only the last two episodes are kept; the
            previous one becomes its own (dashed) series, so no line joins the two across the reset.
        cursor: x of a vertical cursor line drawn in every plot (the replay's timeline position).
    """
    x = np.asarray(x, np.float64)
    prev = np.zeros(len(x), bool)
    if episode is not None and len(x):
        starts = episode_starts(episode)
        i0 = int(starts[-2]) if len(starts) >= 2 else 0
        x = x[i0:]
        values = {k: np.asarray(v, np.float64)[i0:] for k, v in values.items()}
        prev = np.zeros(len(x), bool)
        if len(starts) >= 2:
            prev[: int(starts[-1]) - i0] = True
    groups: dict[str, tuple[str, list[str]]] = {}
    for name in sorted(values):
        v = np.asarray(values[name], np.float64)
        if v.shape != x.shape or not np.isfinite(v).any():
            continue
        key, title = group_of(name)
        groups.setdefault(key, (title, []))[1].append(name)
    order = {k: i for i, k in enumerate(_ORDER)}
    plots = []
    for key in sorted(groups, key=lambda k: (order.get(k, len(order)), k)):
        title, names = groups[key]
        names = sorted(names, key=lambda n: (n != "reward", n))
        labels, colors, dashed, cols = [x_label], ["#000000"], [False], []
        for j, name in enumerate(names):
            v = np.asarray(values[name], np.float64)
            color = COLORS[j % len(COLORS)]
            labels.append(short_label(name))
            colors.append(color)
            dashed.append(False)
            cols.append(np.where(prev, np.nan, v))
            if prev.any():
                labels.append(f"{short_label(name)} (prev. episode)")
                colors.append(color)
                dashed.append(True)
                cols.append(np.where(prev, v, np.nan))
        lo, hi = y_range(cols)
        xs = x
        if cursor is not None and len(x):
            k = int(np.searchsorted(x, cursor))
            xs = np.insert(x, [k, k], [cursor, cursor])
            cols = [np.insert(c, [k, k], [np.nan, np.nan]) for c in cols]
            line = np.full(len(xs), np.nan)
            line[k], line[k + 1] = lo, hi
            cols.append(line)
            labels.append("timeline")
            colors.append(CURSOR_COLOR)
            dashed.append(False)
        plots.append(Plot(key=key, title=title, labels=tuple(labels), colors=tuple(colors), dashed=tuple(dashed),
                          data=(xs, *cols), y=(lo, hi)))
    return plots


def live_series(items, dt: float) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(session time, episode number, recorded name -> values) of history snapshots (``workbench.session.history``).
    Session time is frame index × ``dt`` (it keeps increasing across episode resets)."""
    x = np.array([it.index for it in items], dtype=np.float64) * dt
    t = np.array([it.time for it in items], dtype=np.float64)
    names: dict[str, str] = {}
    for it in items:
        for k in it.scalars:
            if k not in names:
                names[k] = live_name(k)
    vals = {}
    for k, name in names.items():
        if name is not None:
            vals[name] = np.array([it.scalars.get(k, np.nan) for it in items], dtype=np.float64)
    return x, episode_numbers(t), vals


CURVATURE_KEY = "curvature_along_rod"


# per node, the turning angle there (docs/physics.md §1.4); a teleop slider's value is the integrated curvature of a
# region of nodes, shared among them, so a node's value is a fraction of its slider's
CURVATURE_TITLE = ("curvature at each node [rad] (turning angle; dashed: commanded; a slider's value is shared by its "
                   "nodes)")


def curvature_plot(curves: dict) -> Plot | None:
    """The curvature-along-the-rod plot: per component (``workbench.session.rod_curves.curves``) the commanded (natural)
    value dashed and the actual value solid, in the component's colour, against the node index."""
    cols, labels, colors, dashed = [], ["node"], ["#000000"], [False]
    n = 0
    for j, (name, (cmd, act)) in enumerate(curves.items()):
        for kind, v, dash in (("actual", act, False), ("commanded", cmd, True)):
            if v is None:
                continue
            v = np.asarray(v, np.float64)
            n = len(v)
            labels.append(f"{name} {kind}")
            colors.append(COLORS[j % len(COLORS)])
            dashed.append(dash)
            cols.append(v)
    if not cols:
        return None
    x = np.arange(n, dtype=np.float64)
    lo, hi = y_range(cols)
    return Plot(key=CURVATURE_KEY, title=CURVATURE_TITLE, labels=tuple(labels),
                colors=tuple(colors), dashed=tuple(dashed), data=(x, *cols), y=(lo, hi), x_room=False)
