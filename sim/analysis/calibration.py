"""``rodlab fit``: calibrate a scene's parameters so that the simulated rod moves like measured motion.

    rodlab fit SCENE.toml DATA --params youngs_modulus,damping [--controls CONTROLS.csv] [--out FITTED.toml]
               [--report DIR] [--holdout 0.2] [--starts K [--seed S]] [--json]

DATA: a CSV with columns ``t,s,x,y,z`` (time [s] from the scene's initial state, arclength [m] from the rod's first
node along its rest shape, position [m] in the scene's frame) and a ``rod`` column naming the rod when the scene has
several (a missing point is simply absent); or an ``.npz`` with ``t (T,)``, ``s (M,)``, ``pos (T, M, 3)`` (NaN =
missing); or, through ``rodlab fit`` (:mod:`policies.recording.fitdata`), a rodlab ``.rrd`` recording: the node
positions of episode ``--episode K`` (default 0), sim-to-sim. Measurements need not fall on nodes or step times: the
simulated positions are interpolated linearly along the rod and in time. CONTROLS: commanded natural curvature
``t,node,kappa1,kappa2,twist`` (integrated curvature at a node, as the tasks command it), held from each row's time
until the node's next row; absent = the rest controls. In 2-D, kappa1 is the in-plane curvature.

Parameters (``--params``, comma separated): ``youngs_modulus``, ``shear_modulus`` (moves ν), ``density``, ``radius``
(circular sections: the stiffness, mass and contact radius follow it) (each a factor on every rod and edge, fitted in
log space), ``base_position`` (the rods moved, their clamps with them, along each axis; in the plane in 2-D: the
fitted scene moves their start), ``base_orientation`` (the rods turned about the first rod's start [rad]: in 2-D an angle
in the plane, in 3-D about the first edge's directors d1 and d2; the fitted scene turns their direction or rest
points), ``rest_kappa`` (the natural curvature at every interior node that is not commanded, each component; in
2-D the in-plane one: an offset the fitted scene holds as ``natural_curvature``), ``damping`` [1/s], ``gravity`` (the vector; its in-plane components in
2-D), the contact's ``contact_stiffness`` and ``contact_delta`` (factors, in log space) and ``friction`` (the [contact] μ:
obstacles without a μ of their own, and contact between edges), ``obstacle_position`` (every obstacle's placement, each axis; in the plane in
2-D: the fitted scene moves its point, centre, ends or position), and the actuation map from commanded to actual natural curvature, actual = gain · followed + offset, per
commanded node: ``actuation_gain`` (also on the twist), ``actuation_offset`` (κ1 and κ2), ``actuation_play`` (the
half-width w of a backlash, in the commands' units: hysteresis) and ``actuation_lag`` [s] (a time constant τ), one
play and one lag for every commanded node's actuator: followed = the lag of the play of the command
(:func:`play_schedule`, :func:`lag_schedule`; w = 0 and τ = 0 are the command itself). The scene parameters are
bounded by the ranges sim.scene.validate.BOUNDS allows the values they set (every rod and edge; ν in (-1, 0.5] for
the shear modulus), so a fit never returns a scene that does not load; one that ends on a bound is said
(``at_bound``). Gain and offset are unbounded, the lag is in [0, ACTUATION_LAG_MAX_S], the play in [0, the largest
command].

The fit is trust-region least squares on the position residuals with the Jacobian from the tangent mode of
:mod:`sim.analysis.gradients` (docs/physics.md §3.9), or (``--method lbfgs``, for many unknowns) L-BFGS-B on half the
squared residuals with their gradient Jᵀr from one adjoint pass per evaluation. The result: the fitted scene as a new TOML (never over an existing file),
values ± standard errors from the Gauss–Newton covariance, their correlation, the RMS residual (and on a held-out
final part of the motion with ``--holdout``), with ``--report`` a folder with ``fit.json``, ``residuals.csv`` (every
point, held-out ones marked) and plots: measured against fitted markers, the residual over time and along the rod,
the correlation matrix (:func:`write_report`). With ``--starts K`` the fit first searches from K starting points at
once, each an env of one batched simulator (:mod:`sim.analysis.multistart`), and fits from the best.
Ctrl-C keeps the best parameters so far.
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from sim.analysis import gradients as G
from sim.geometry import matrix_from_rotvec, transport_vectors
from sim.geometry.frames import signed_angle
from sim.scene.model import build_model, planar_nodes
from sim.scene.spec import SceneError, dump_scene, load_scene
from sim.scene.validate import BOUNDS
from sim.state import STATE_ARRAYS
from sim.step import Simulator
from sim.support.atomicio import write_text, write_via_path
from sim.support.paths import check_output_path
from sim.support.progress import add_progress_flag, progress_bar, progress_wanted

__all__ = ["FIT_PARAMETERS", "FIT_METHODS", "FitError", "Measurements", "Commands", "FitResult", "FitTrack", "load_measurements",
           "measurements_from_arrays", "node_arclength", "load_controls", "fit", "write_report", "PLOTS",
           "RESIDUAL_COLUMNS", "fit_command"]

FIT_PARAMETERS = ("youngs_modulus", "shear_modulus", "density", "radius", "rest_kappa", "base_position",
                  "base_orientation", "damping",
                  "gravity", "contact_stiffness",
                  "contact_delta", "friction", "obstacle_position", "actuation_gain", "actuation_offset", "actuation_play", "actuation_lag")
_LOG = ("youngs_modulus", "shear_modulus", "density", "radius", "contact_stiffness", "contact_delta")  # fitted as ln of a factor on the scene's value
MAX_TIME_S = 3600.0  # longest motion a fit simulates
ACTUATION_LAG_MAX_S = 10.0  # longest actuator time constant a fit considers
BASE_TURN_MAX = 0.5 * math.pi  # largest turn of the base a fit considers, each component [rad]
BASE_TURN_STEP = 1e-6  # the base turn's tangent: central differences of the initial state at this angle [rad]
UNIT_FACTOR = 100.0  # a measured point farther than this many rod lengths from the rod's start is in wrong units


class FitError(ValueError):
    """Bad data, controls or parameter names for a fit, said with the file, row or name."""


# ---------------------------------------------------------------------------------------------------- input files
@dataclasses.dataclass(frozen=True)
class Measurements:
    """Measured points, one per row: time t [s], arclength s [m] along rod ``rod`` (index into the scene's rods),
    position pos [m]."""

    t: np.ndarray  # (M,)
    s: np.ndarray  # (M,)
    rod: np.ndarray  # (M,) int
    pos: np.ndarray  # (M, 3)

    def subset(self, mask: np.ndarray) -> "Measurements":
        return Measurements(self.t[mask], self.s[mask], self.rod[mask], self.pos[mask])


@dataclasses.dataclass(frozen=True)
class Commands:
    """Commanded natural curvature rows: time [s], node, (κ1, κ2), twist."""

    t: np.ndarray  # (R,)
    node: np.ndarray  # (R,) int
    kappa: np.ndarray  # (R, 2)
    twist: np.ndarray  # (R,)

    @property
    def nodes(self) -> np.ndarray:
        """The commanded nodes, sorted."""
        return np.unique(self.node)


def _rod_lengths(spec) -> list[float]:
    return [float(r.length) for r in spec.rods]


def _read_csv(path: Path, required: tuple[str, ...], optional: tuple[str, ...] = ()) -> list[tuple[int, dict]]:
    try:
        fh = path.open(newline="", encoding="utf-8")
    except OSError as exc:
        raise FitError(f"{path}: cannot read ({exc.strerror or exc})") from None
    with fh:
        reader = csv.DictReader(fh)
        cols = [c.strip() for c in (reader.fieldnames or [])]
        missing = [c for c in required if c not in cols]
        if missing:
            raise FitError(f"{path}: missing column(s) {', '.join(missing)} (has: {', '.join(cols) or 'none'}); "
                           f"expected {','.join(required + optional)}")
        rows = []
        for i, row in enumerate(reader, start=2):  # line 1 is the header
            rows.append((i, {k.strip(): (v or "").strip() for k, v in row.items() if k is not None}))
    if not rows:
        raise FitError(f"{path}: no rows")
    return rows


def _number(path: Path, line: int, name: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise FitError(f"{path}:{line}: {name} = {text!r} is not a number") from None
    if not math.isfinite(v):
        raise FitError(f"{path}:{line}: {name} = {text!r} is not finite")
    return v


def load_measurements(path, spec, *, readers=None, episode: int = 0) -> Measurements:
    """Read measured motion (CSV or .npz, module docstring) for the scene ``spec``, checking every row.
    ``readers``: suffix -> ``reader(path, spec, episode=...)`` returning arrays ``(t (T,), s (M,), pos (T, M, 3))``
    of the first rod, or checked :class:`Measurements`, for further formats (``rodlab fit`` passes the ``.rrd``
    reader of :mod:`policies.recording.fitdata`: sim does not read recordings itself)."""
    path = Path(path)
    names = [r.name for r in spec.rods]
    readers = dict(readers or {})
    if path.suffix in readers:
        got = readers[path.suffix](path, spec, episode=episode)
        return got if isinstance(got, Measurements) else measurements_from_arrays(*got, spec, where=str(path))
    if path.suffix == ".rrd":
        raise FitError(f"{path}: a .rrd recording is read by `rodlab fit` (policies.recording.fitdata); sim.analysis.calibration "
                       "alone reads CSV and .npz")
    if path.suffix == ".npz":
        t, s, pos = _read_npz(path)
        meas, where = _from_grid(t, s, pos, str(path))
    else:
        rows = _read_csv(path, ("t", "s", "x", "y", "z"), ("rod",))
        t, s, rod, pos, where = [], [], [], [], []
        for line, row in rows:
            if len(spec.rods) > 1 or row.get("rod"):
                name = row.get("rod", "")
                if name not in names:
                    raise FitError(f"{path}:{line}: rod {name!r} is not a rod of the scene ({', '.join(names)})")
                rod.append(names.index(name))
            else:
                rod.append(0)
            t.append(_number(path, line, "t", row["t"]))
            s.append(_number(path, line, "s", row["s"]))
            pos.append([_number(path, line, c, row[c]) for c in ("x", "y", "z")])
            where.append(f"{path}:{line}")
        meas = Measurements(np.array(t), np.array(s), np.array(rod, int), np.array(pos, float).reshape(-1, 3))
    return _checked(meas, where, spec, path)


def measurements_from_arrays(t, s, pos, spec, *, rod: int = 0, where: str = "data") -> Measurements:
    """Measurements of rod ``rod`` (index into the scene's rods) from arrays ``t (T,)`` [s], ``s (M,)`` [m],
    ``pos (T, M, 3)`` [m] (NaN = missing), with the checks of an ``.npz`` (``where`` names the source in errors)."""
    if not 0 <= rod < len(spec.rods):
        raise FitError(f"{where}: rod {rod} is not a rod of the scene (it has {len(spec.rods)})")
    t, s, pos = _checked_grid(np.asarray(t, np.float64), np.asarray(s, np.float64), np.asarray(pos, np.float64),
                              where)
    meas, rows = _from_grid(t, s, pos, where, rod)
    return _checked(meas, rows, spec, where)


def _from_grid(t, s, pos, where: str, rod: int = 0) -> tuple[Measurements, list[str]]:
    T, M = t.shape[0], s.shape[0]
    tt, ss = np.repeat(t, M), np.tile(s, T)
    pp = pos.reshape(T * M, 3)
    keep = ~np.any(np.isnan(pp), axis=1)
    meas = Measurements(tt[keep], ss[keep], np.full(int(keep.sum()), rod, int), pp[keep])
    return meas, [f"{where}: t[{i // M}], s[{i % M}]" for i in np.flatnonzero(keep)]


def _checked(meas: Measurements, where: list[str], spec, path) -> Measurements:
    lengths = _rod_lengths(spec)
    if meas.t.size == 0:
        raise FitError(f"{path}: no measured points (every position is missing)")
    for i in range(meas.t.size):
        L = lengths[meas.rod[i]]
        if meas.t[i] < 0.0:
            raise FitError(f"{where[i]}: t = {meas.t[i]:g} s is before the scene's initial state (t = 0)")
        if meas.t[i] > MAX_TIME_S:
            raise FitError(f"{where[i]}: t = {meas.t[i]:g} s is beyond {MAX_TIME_S:g} s (times in seconds?)")
        if not -1e-9 * L <= meas.s[i] <= L * (1.0 + 1e-9):
            raise FitError(f"{where[i]}: s = {meas.s[i]:g} m is off the rod (its length is {L:g} m)")
        if np.linalg.norm(meas.pos[i]) > UNIT_FACTOR * max(1.0, L) + np.linalg.norm(spec.rods[meas.rod[i]].start):
            raise FitError(f"{where[i]}: position {meas.pos[i].tolist()} is more than {UNIT_FACTOR:g} rod lengths "
                           "away: are the units metres?")
    return meas


def _read_npz(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in ("t", "s", "pos") if k not in z.files]
            if missing:
                raise FitError(f"{path}: missing array(s) {', '.join(missing)} (expected t (T,), s (M,), "
                               "pos (T, M, 3))")
            t, s, pos = (np.asarray(z[k], dtype=np.float64) for k in ("t", "s", "pos"))
    except (OSError, ValueError) as exc:
        if isinstance(exc, FitError):
            raise
        raise FitError(f"{path}: not a readable .npz ({exc})") from None
    return _checked_grid(t, s, pos, str(path))


def _checked_grid(t: np.ndarray, s: np.ndarray, pos: np.ndarray, path: str):
    if t.ndim != 1 or s.ndim != 1 or pos.shape != (t.shape[0], s.shape[0], 3):
        raise FitError(f"{path}: shapes t {t.shape}, s {s.shape}, pos {pos.shape}; expected t (T,), s (M,), "
                       "pos (T, M, 3)")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(s))):
        raise FitError(f"{path}: t and s must be finite (mark a missing point with NaN in pos)")
    if np.any(np.diff(t) <= 0.0):
        i = int(np.flatnonzero(np.diff(t) <= 0.0)[0])
        raise FitError(f"{path}: t is not increasing at t[{i + 1}] = {t[i + 1]:g} (after {t[i]:g})")
    bad = np.isinf(pos).any(axis=2)
    if bad.any():
        i, j = np.argwhere(bad)[0]
        raise FitError(f"{path}: pos[{i}, {j}] is infinite (mark a missing point with NaN)")
    return t, s, pos


def load_controls(path, model) -> Commands:
    """Read commanded natural curvature (CSV ``t,node,kappa1,kappa2,twist``) for ``model``; rows of one node must
    come in increasing time."""
    path = Path(path)
    rows = _read_csv(path, ("t", "node", "kappa1", "kappa2", "twist"))
    N = model.node_count
    t, node, kap, tw = [], [], [], []
    last: dict[int, float] = {}
    for line, row in rows:
        ti = _number(path, line, "t", row["t"])
        ni = _number(path, line, "node", row["node"])
        if ni != int(ni) or not 1 <= int(ni) <= N - 2:
            raise FitError(f"{path}:{line}: node {row['node']!r} is not an interior node (1 … {N - 2})")
        ni = int(ni)
        if ti < 0.0:
            raise FitError(f"{path}:{line}: t = {ti:g} s is before the scene's initial state (t = 0)")
        if ni in last and ti <= last[ni]:
            raise FitError(f"{path}:{line}: time {ti:g} s of node {ni} does not come after its previous row "
                           f"({last[ni]:g} s)")
        last[ni] = ti
        t.append(ti)
        node.append(ni)
        kap.append([_number(path, line, "kappa1", row["kappa1"]), _number(path, line, "kappa2", row["kappa2"])])
        tw.append(_number(path, line, "twist", row["twist"]))
    return Commands(np.array(t), np.array(node, int), np.array(kap), np.array(tw))


def command_schedule(cmds: Commands | None, steps: int, dt: float, N: int) -> tuple[np.ndarray, np.ndarray]:
    """(κ (T, N, 2), twist (T, N)) commanded at each step (a row holds from its time; a node before its first row,
    or not commanded: 0, unused)."""
    kap = np.zeros((steps, N, 2))
    tw = np.zeros((steps, N))
    if cmds is None:
        return kap, tw
    times = np.arange(steps) * dt
    for n in cmds.nodes:
        sel = np.flatnonzero(cmds.node == n)
        idx = np.searchsorted(cmds.t[sel], times + 1e-9 * dt, side="right") - 1
        on = idx >= 0
        kap[on, n] = cmds.kappa[sel[idx[on]]]
        tw[on, n] = cmds.twist[sel[idx[on]]]
    return kap, tw


def lag_schedule(commanded: np.ndarray, tau: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """The first-order lag of a command schedule (T, ...) with time constant ``tau`` [s] and its derivative with
    respect to ``tau``: τ ḟ = c − f by backward Euler at ``dt``, f_k = f_{k−1} + α (c_k − f_{k−1}), α = dt/(τ + dt),
    from f = 0 (the command before any row); ``tau`` = 0 gives the commands themselves."""
    if not tau >= 0.0:
        raise FitError(f"actuation_lag must be ≥ 0 s, got {tau!r}")
    alpha = dt / (tau + dt)
    dalpha = -dt / (tau + dt) ** 2
    f = np.empty_like(commanded, dtype=float)
    df = np.empty_like(f)
    f_prev = np.zeros(commanded.shape[1:])
    d_prev = np.zeros(commanded.shape[1:])
    for k in range(commanded.shape[0]):
        gap = commanded[k] - f_prev
        d_prev = (1.0 - alpha) * d_prev + dalpha * gap
        f_prev = f_prev + alpha * gap
        f[k], df[k] = f_prev, d_prev
    return f, df


def play_schedule(commanded: np.ndarray, width: float) -> tuple[np.ndarray, np.ndarray]:
    """The play (backlash) operator on a command schedule (T, ...) with half-width ``width``, per component, and its
    derivative with respect to ``width``: the output stays put while the command moves within ±w of it and is
    dragged along at distance w beyond, y_k = min(c_k + w, max(c_k − w, y_{k−1})), from y = 0 (the command before
    any row). A command that reverses comes back 2w before the output moves: the loop of a hysteresis. ``width`` = 0
    gives the commands themselves."""
    if not width >= 0.0:
        raise FitError(f"actuation_play must be ≥ 0, got {width!r}")
    y = np.empty_like(commanded, dtype=float)
    dy = np.empty_like(y)
    y_prev = np.zeros(commanded.shape[1:])
    d_prev = np.zeros(commanded.shape[1:])
    for k in range(commanded.shape[0]):
        lo, hi = commanded[k] - width, commanded[k] + width
        below, above = y_prev < lo, y_prev > hi  # dragged along at −w or +w; else held (its derivative too)
        y_prev = np.where(below, lo, np.where(above, hi, y_prev))
        d_prev = np.where(below, -1.0, np.where(above, 1.0, d_prev))
        y[k], dy[k] = y_prev, d_prev
    return y, dy


def node_arclength(spec, model=None) -> tuple[np.ndarray, np.ndarray]:
    """(s (N,), rod (N,)) of every node of the scene: its arclength [m] from its rod's first node along the rest
    shape (the ``s`` of measurements) and the index of its rod. A measurement at a node's s is that node."""
    model = build_model(spec) if model is None else model
    lengths = np.asarray(model.rest_edge_length)
    s = np.zeros(model.node_count)
    rod = np.zeros(model.node_count, int)
    for r, sl in enumerate(model.rod_slices().values()):
        idx = np.arange(sl.start, sl.stop)
        arc = np.concatenate([[0.0], np.cumsum(lengths[idx[:-1]])])
        s[idx] = arc * (float(spec.rods[r].length) / arc[-1])
        rod[idx] = r
    return s, rod


# ---------------------------------------------------------------------------------------------------- the problem
@dataclasses.dataclass(frozen=True)
class Unknown:
    """One fitted number: parameter ``name`` (component ``index``: a gravity axis, a commanded node's entry)."""

    name: str
    index: int = 0
    label: str = ""


NU_RANGE = (-1.0 + 1e-9, 0.5)  # ν the shear modulus may set: sim.scene.validate's (-1, 0.5], the open end by a margin


def _clip(v: float, lo: float, hi: float) -> float:
    return min(max(v, lo), hi)


def _rod_values(r, name: str) -> list[float]:
    """Every value of the scene key ``name`` on rod ``r`` (the rod's and its per-edge list's)."""
    v = [float(getattr(r, name))]
    if name == "youngs_modulus" and r.edge_youngs_modulus is not None:
        v += [float(x) for x in r.edge_youngs_modulus]
    if name == "radius" and r.edge_radius is not None:
        v += [float(x) for x in r.edge_radius]
    return v


def _unknown_bounds(spec, u: "Unknown", play_limit: float = np.inf) -> tuple[float, float]:
    """(lowest, highest) of the unknown ``u`` (its z: a log factor, a rate, a component) from sim.scene.validate.BOUNDS."""
    if u.name in ("youngs_modulus", "density", "radius"):
        lo_v, hi_v, _ = BOUNDS[f"rod.{u.name}"]
        lo = max(math.log(lo_v / min(_rod_values(r, u.name))) for r in spec.rods)
        hi = min(math.log(hi_v / max(_rod_values(r, u.name))) for r in spec.rods)
        return lo, hi
    if u.name == "shear_modulus":  # G = E / (2 (1 + ν)); the factor f sets 1 + ν' = (1 + ν) / f
        lo = max(math.log((1.0 + r.poisson_ratio) / (1.0 + NU_RANGE[1])) for r in spec.rods)
        hi = min(math.log((1.0 + r.poisson_ratio) / (1.0 + NU_RANGE[0])) for r in spec.rods)
        return lo, hi
    if u.name == "damping":
        lo_v, hi_v, _ = BOUNDS["sim.damping"]
        return lo_v, hi_v
    if u.name == "gravity":
        lo_v, hi_v, _ = BOUNDS["sim.gravity"]
        return lo_v, hi_v
    if u.name == "contact_stiffness":
        lo_v, hi_v, _ = BOUNDS["contact.stiffness"]
        return math.log(lo_v / spec.contact.stiffness), math.log(hi_v / spec.contact.stiffness)
    if u.name == "contact_delta":
        lo_v, hi_v, _ = BOUNDS["contact.delta"]
        return math.log(lo_v / spec.contact.delta), math.log(hi_v / spec.contact.delta)
    if u.name == "friction":
        lo_v, hi_v, _ = BOUNDS["contact.friction"]
        return lo_v, hi_v
    if u.name == "actuation_lag":
        return 0.0, ACTUATION_LAG_MAX_S
    if u.name == "rest_kappa":  # the scene's natural curvature there plus the offset stays within its bounds
        lo_v, hi_v, _ = BOUNDS["rod.natural_curvature"]
        node, start = u.index // 2, 0
        for rod in spec.rods:
            if node < start + rod.nodes:
                nat = rod.natural_curvature
                held = 0.0 if nat is None else max(abs(v) for v in nat[node - start])
                return lo_v + held, hi_v - held
            start += rod.nodes
        return lo_v, hi_v
    if u.name == "actuation_play":  # wider than every command, the output never moves
        return 0.0, play_limit
    if u.name == "base_orientation":  # [rad], each component
        return -BASE_TURN_MAX, BASE_TURN_MAX
    return -np.inf, np.inf


_ANCHORS = ("point", "center", "start", "position")  # an obstacle spec's position fields; a capsule's end moves along


def _anchor(o) -> tuple:
    """The point an obstacle spec is placed by (a plane's point, a sphere's centre, a capsule's or cylinder's start,
    a box's or mesh's position)."""
    return next(getattr(o, f) for f in _ANCHORS if hasattr(o, f))


def _moved_obstacle(o, d):
    """The obstacle spec ``o`` translated by d (3,) [m]."""
    if not any(d):
        return o
    shift = {f: tuple(float(v) + float(dv) for v, dv in zip(getattr(o, f), d))
             for f in (*_ANCHORS, "end") if hasattr(o, f)}
    return dataclasses.replace(o, **shift)


def _moved_rod(r, d):
    """The rod spec ``r`` translated by d (3,) [m] (its start, or its rest points)."""
    start = tuple(float(v) + float(dv) for v, dv in zip(r.start, d))
    if r.rest_points is None:
        return dataclasses.replace(r, start=start)
    pts = tuple(tuple(float(v) + float(dv) for v, dv in zip(p, d)) for p in r.rest_points)
    return dataclasses.replace(r, start=start, rest_points=pts)


def _turned_rod(r, R: np.ndarray, pivot: np.ndarray):
    """The rod spec ``r`` turned by R (3, 3) about the point ``pivot`` (3,) (its start and direction, or its rest
    points)."""
    start = tuple(float(v) for v in pivot + R @ (np.asarray(r.start, dtype=np.float64) - pivot))
    d = R @ np.asarray(r.direction, dtype=np.float64)
    direction = tuple(float(v) for v in d / np.linalg.norm(d))
    if r.rest_points is None:
        return dataclasses.replace(r, start=start, direction=direction)
    pts = pivot + (np.asarray(r.rest_points, dtype=np.float64) - pivot) @ R.T
    return dataclasses.replace(r, start=start, direction=direction,
                               rest_points=tuple(tuple(float(v) for v in p) for p in pts))


def _bound_text(u: "Unknown") -> str:
    key = {"youngs_modulus": "rod.youngs_modulus", "density": "rod.density", "radius": "rod.radius",
           "damping": "sim.damping",
           "gravity": "sim.gravity", "contact_stiffness": "contact.stiffness", "contact_delta": "contact.delta",
           "friction": "contact.friction", "rest_kappa": "rod.natural_curvature"}.get(u.name)
    if u.name == "actuation_lag":
        return f"actuation_lag in [0, {ACTUATION_LAG_MAX_S:g}] s"
    if u.name == "actuation_play":
        return "actuation_play in [0, the largest command]"
    if key is None:
        return "poisson_ratio in (-1, 0.5]" if u.name == "shear_modulus" else "unbounded"
    lo, hi, unit = BOUNDS[key]
    return f"{key} in [{lo:g}, {hi:g}] {unit}"


class Problem:
    """The simulated positions at the measured points as a function of the unknowns z (log factors, damping,
    gravity, actuation map), and their Jacobian by the tangent mode."""

    LOG = _LOG  # the parameters fitted as the log of a factor on the scene's value

    def __init__(self, spec, meas: Measurements, cmds: Commands | None, params: list[str]):
        self.spec, self.meas, self.cmds = spec, meas, cmds
        bad = [p for p in params if p not in FIT_PARAMETERS]
        if bad:
            raise FitError(f"unknown parameter(s) {', '.join(repr(b) for b in bad)}; known: "
                           f"{', '.join(FIT_PARAMETERS)}")
        if not params:
            raise FitError("--params names no parameter")
        model = build_model(spec)
        self.model0 = model
        self.planar = model.mode == "2d"
        self.dt = model.dt
        self.steps = max(1, int(math.ceil(float(meas.t.max()) / self.dt - 1e-9)))
        if (cmds is None) and any(p.startswith("actuation_") for p in params):
            raise FitError("the actuation map (actuation_gain, actuation_offset, actuation_play, actuation_lag) needs "
                           "--controls: the commanded curvature it maps")
        for name in ("base_position", "base_orientation"):
            if name in params and any(any(f.angular_velocity) for f in spec.fixes):
                raise FitError(f"{name}: a clamp turned about a centre ([[fix]] angular_velocity) turns with the "
                               "base; fit the base of a scene without one")
        narrow = [r.name for r in spec.rods if r.cross_section != "circle"]
        if "radius" in params and narrow:
            raise FitError(f"radius: rod {narrow[0]!r} has a non-circular section (width and height, or semi-axes), "
                           "not a radius")
        if "shear_modulus" in params and self.planar:
            raise FitError("shear_modulus: a 2-D scene has no twist, so the data cannot tell the shear modulus")
        probe = Simulator(model, 1)
        obstacles = model.obstacles.count > 0 and spec.contact.enabled
        if "obstacle_position" in params and not obstacles:
            raise FitError("obstacle_position: the scene has no obstacle contact (no [[obstacle]], or [contact] "
                           "enabled = false)")
        touching = [p for p in params if p in ("contact_stiffness", "contact_delta", "friction")]
        if touching and not (obstacles or bool(probe.kernel_params[0]["rod_pairs"])):
            raise FitError(f"{touching[0]}: the scene has no contact (no [[obstacle]], no self_contact or rod_contact "
                           "between edges, or [contact] enabled = false)")
        self.rest_kb, self.rest_tb = probe._rest_control_arrays()
        self.cmd_kb, self.cmd_tb = command_schedule(cmds, self.steps, self.dt, model.node_count)
        used = (self.cmd_kb[..., 0],) if self.planar else (self.cmd_kb, self.cmd_tb)  # 2-D: κ1 only
        self.play_limit = float(max(np.max(np.abs(c), initial=0.0) for c in used))
        if "actuation_play" in params and not self.play_limit > 0.0:
            raise FitError("actuation_play: every command is 0 over the measured time, so the data cannot tell a play")
        self.unknowns = self._unknowns(params)
        self._weights()

    def _unknowns(self, params: list[str]) -> list[Unknown]:
        out: list[Unknown] = []
        for p in dict.fromkeys(params):
            if p == "gravity":
                axes = (0, 2) if self.planar else (0, 1, 2)
                out += [Unknown(p, a, f"gravity_{'xyz'[a]}") for a in axes]
            elif p == "actuation_gain":
                out += [Unknown(p, int(n), f"actuation_gain[{int(n)}]") for n in self.cmds.nodes]
            elif p == "actuation_offset":
                comps = (0,) if self.planar else (0, 1)
                out += [Unknown(p, 2 * int(n) + c, f"actuation_offset[{int(n)}].kappa{c + 1}")
                        for n in self.cmds.nodes for c in comps]
            elif p in ("actuation_play", "actuation_lag"):
                out.append(Unknown(p, 0, p))
            elif p == "rest_kappa":  # every interior node of every rod, each component (2-D: the in-plane one);
                # not a commanded node: the command sets its natural curvature (actuation_offset shifts it)
                comps = (0,) if self.planar else (0, 1)
                offsets = self.model0.rod_node_offsets
                commanded = set() if self.cmds is None else {int(n) for n in self.cmds.nodes}
                for r, rod in enumerate(self.spec.rods):
                    for i in range(1, rod.nodes - 1):
                        node = int(offsets[r]) + i
                        if node in commanded:
                            continue
                        where = f"{rod.name}[{i}]" if len(self.spec.rods) > 1 else f"{i}"
                        out += [Unknown(p, 2 * node + c, f"rest_kappa[{where}].kappa{c + 1}") for c in comps]
            elif p == "base_position":  # the rods (their clamp with them) moved along each axis (2-D: in the plane)
                out += [Unknown(p, a, f"base_position.{'xyz'[a]}") for a in ((0, 2) if self.planar else (0, 1, 2))]
            elif p == "base_orientation":  # the rods turned about the first rod's start: 2-D in the plane; 3-D
                # about the first edge's two directors (a turn about the rod's own axis is not a scene's to hold)
                out += ([Unknown(p, 0, p)] if self.planar else
                        [Unknown(p, a, f"{p}.d{a + 1}") for a in (0, 1)])
            elif p == "obstacle_position":  # every obstacle moved along each axis (2-D: in the plane)
                for j, o in enumerate(self.spec.obstacles):
                    for a in ((0, 2) if self.planar else (0, 1, 2)):
                        out.append(Unknown(p, 3 * j + a, f"obstacle_position[{o.name or j}].{'xyz'[a]}"))
            else:
                out.append(Unknown(p, 0, p))
        return out

    def _weights(self) -> None:
        """Interpolation of node positions at step states to the measured points: 4 (step, node) pairs each."""
        m, meas = self.model0, self.meas
        slices = list(m.rod_slices().values())
        kf = meas.t / self.dt
        k0 = np.clip(np.floor(kf).astype(int), 0, self.steps - 1)
        wt = np.clip(kf - k0, 0.0, 1.0)
        nodes = np.zeros((meas.t.size, 2), int)
        ws = np.zeros(meas.t.size)
        node_s, _ = node_arclength(self.spec, m)
        for r, sl in enumerate(slices):
            sel = meas.rod == r
            if not sel.any():
                continue
            idx = np.arange(sl.start, sl.stop)
            arc = node_s[idx]
            j = np.clip(np.searchsorted(arc, meas.s[sel], side="right") - 1, 0, idx.size - 2)
            nodes[sel, 0], nodes[sel, 1] = idx[j], idx[j + 1]
            ws[sel] = np.clip((meas.s[sel] - arc[j]) / (arc[j + 1] - arc[j]), 0.0, 1.0)
        self._k = np.stack([k0, k0, k0 + 1, k0 + 1], axis=1)
        self._n = np.stack([nodes[:, 0], nodes[:, 1], nodes[:, 0], nodes[:, 1]], axis=1)
        self._w = np.stack([(1 - wt) * (1 - ws), (1 - wt) * ws, wt * (1 - ws), wt * ws], axis=1)
        self._axes = [0, 2] if self.planar else [0, 1, 2]

    def _node_pos(self, dof: np.ndarray, plane_y: float | None) -> np.ndarray:
        """(..., n) DOFs -> (..., N, 3) node positions (2-D: y = plane_y, or 0 for tangents)."""
        if self.planar:
            q = dof.reshape(dof.shape[:-1] + (-1, 2))
            out = np.zeros(q.shape[:-1] + (3,))
            out[..., 0], out[..., 2] = q[..., 0], q[..., 1]
            if plane_y is not None:
                out[..., 1] = plane_y
            return out
        return dof.reshape(dof.shape[:-1] + (-1, 4))[..., :3]

    def predict(self, node_pos: np.ndarray) -> np.ndarray:
        """(T + 1, N, 3) -> the positions at the measured points (M, 3)."""
        return np.einsum("mq,mqc->mc", self._w, node_pos[self._k, self._n])

    # the scene and controls at z
    def spec_at(self, z: np.ndarray):
        vals = dict(zip([u.label for u in self.unknowns], z))
        spec = self.spec
        fE = math.exp(vals.get("youngs_modulus", 0.0))
        fG = math.exp(vals.get("shear_modulus", 0.0))
        fR = math.exp(vals.get("density", 0.0))
        fr = math.exp(vals.get("radius", 0.0))
        # values are clipped into BOUNDS: the optimiser stays within Problem.bounds, so this only absorbs the
        # rounding of exp(log) at a bound
        E_lo, E_hi, _ = BOUNDS["rod.youngs_modulus"]
        R_lo, R_hi, _ = BOUNDS["rod.density"]
        r_lo, r_hi, _ = BOUNDS["rod.radius"]
        rods = []
        for r in spec.rods:
            if "shear_modulus" in vals:
                nu = min(max((1.0 + r.poisson_ratio) / fG - 1.0, NU_RANGE[0]), NU_RANGE[1])
            else:
                nu = r.poisson_ratio
            edge_e = None if r.edge_youngs_modulus is None else \
                tuple(_clip(fE * v, E_lo, E_hi) for v in r.edge_youngs_modulus)
            edge_r = None if r.edge_radius is None else tuple(_clip(fr * v, r_lo, r_hi) for v in r.edge_radius)
            rods.append(dataclasses.replace(r, youngs_modulus=_clip(r.youngs_modulus * fE, E_lo, E_hi),
                                            poisson_ratio=nu, density=_clip(r.density * fR, R_lo, R_hi),
                                            edge_youngs_modulus=edge_e, radius=_clip(r.radius * fr, r_lo, r_hi),
                                            edge_radius=edge_r))
        g = list(spec.sim.gravity)
        g_lo, g_hi, _ = BOUNDS["sim.gravity"]
        for a, c in enumerate("xyz"):
            if f"gravity_{c}" in vals:
                g[a] = _clip(float(vals[f"gravity_{c}"]), g_lo, g_hi)
        c_lo, c_hi, _ = BOUNDS["sim.damping"]
        sim = dataclasses.replace(spec.sim, gravity=tuple(g),
                                  damping=_clip(float(vals.get("damping", spec.sim.damping)), c_lo, c_hi))
        contact = spec.contact
        if "contact_stiffness" in vals or "friction" in vals or "contact_delta" in vals:
            k_lo, k_hi, _ = BOUNDS["contact.stiffness"]
            m_lo, m_hi, _ = BOUNDS["contact.friction"]
            d_lo, d_hi, _ = BOUNDS["contact.delta"]
            contact = dataclasses.replace(
                contact, stiffness=_clip(contact.stiffness * math.exp(vals.get("contact_stiffness", 0.0)), k_lo, k_hi),
                delta=_clip(contact.delta * math.exp(vals.get("contact_delta", 0.0)), d_lo, d_hi),
                friction=_clip(float(vals.get("friction", contact.friction)), m_lo, m_hi))
        turn = self._turn(z)
        if turn is not None:  # about the first rod's start in the scene, before the shift
            pivot = np.array(spec.rods[0].start, dtype=np.float64)
            rods = [_turned_rod(r, turn, pivot) for r in rods]
        shift = [next((float(zi) for u, zi in zip(self.unknowns, z) if u.name == "base_position" and u.index == a), 0.0)
                 for a in range(3)]
        if any(shift):
            rods = [_moved_rod(r, shift) for r in rods]
        bent = {u.index: float(zi) for u, zi in zip(self.unknowns, z) if u.name == "rest_kappa"}
        if bent:
            rods = self._bent_rods(rods, bent)
        obstacles = spec.obstacles
        moved = {u.index: zi for u, zi in zip(self.unknowns, z) if u.name == "obstacle_position"}
        if moved:
            obstacles = tuple(_moved_obstacle(o, [moved.get(3 * j + a, 0.0) for a in range(3)])
                              for j, o in enumerate(obstacles))
        return dataclasses.replace(spec, sim=sim, rods=tuple(rods), contact=contact, obstacles=obstacles)

    def _turn(self, z: np.ndarray) -> np.ndarray | None:
        """The rotation matrix (3, 3) of the unknowns ``base_orientation`` at z (None without them): 2-D, the angle
        about the plane's normal y; 3-D, the rotation vector a d1 + b d2 of the first edge's directors in the
        scene."""
        ang = {u.index: float(zi) for u, zi in zip(self.unknowns, z) if u.name == "base_orientation"}
        if not ang:
            return None
        if self.planar:
            w = np.array([0.0, ang[0], 0.0])
        else:
            d1 = np.asarray(self.model0.rest_ref_d1[0], dtype=np.float64)
            d2 = np.cross(np.asarray(self.model0.rest_tangent[0], dtype=np.float64), d1)
            w = ang.get(0, 0.0) * d1 + ang.get(1, 0.0) * d2
        return matrix_from_rotvec(w)

    def _turn_tangent(self, z: np.ndarray, u: "Unknown") -> np.ndarray:
        """(1, n) the initial DOFs' change per radian of the unknown ``u`` (base_orientation) at z: the positions
        turned about the base, and in 3-D the twist angles' change that makes the tangent's frames (the stored ones
        carried by parallel transport) the fitted scene's own (its rule for the first director, transported along
        the rod), by central differences of the scene's initial state in the angle (no simulation: a map of
        positions and frames, to ~1e-10)."""
        eps = BASE_TURN_STEP
        base = Simulator(build_model(self.spec_at(z)), 1).reset()
        rows = []
        for sign in (1.0, -1.0):
            zz = np.array(z, dtype=np.float64)
            zz[self.unknowns.index(u)] += sign * eps
            st = Simulator(build_model(self.spec_at(zz)), 1).reset()
            dof = st.dof[0].copy()
            if not self.planar:  # θ: from the base's first directors carried to the turned tangents, to the scene's
                for e in range(dof.shape[0] - 1):
                    d1 = transport_vectors(base.edge_ref_d1[0, e], base.edge_tangent[0, e], st.edge_tangent[0, e])
                    dof[e, 3] = signed_angle(d1, tuple(map(float, st.edge_ref_d1[0, e])),
                                             tuple(map(float, st.edge_tangent[0, e])))
            rows.append(dof.reshape(-1))
        return ((rows[0] - rows[1]) / (2.0 * eps))[None, :]

    def _bent_rods(self, rods: list, bent: dict) -> list:
        """The rods with the natural curvature offsets ``bent`` (2 node + component, in the controls' terms: 2-D, the
        in-plane curvature) added to their scene ``natural_curvature``."""
        m = self.model0
        offsets = m.rod_node_offsets
        comp, sign = planar_nodes(m) if self.planar else (None, None)
        out = []
        for r, rod in enumerate(rods):
            nat = np.zeros((rod.nodes, 2)) if rod.natural_curvature is None else np.array(rod.natural_curvature)
            for i in range(1, rod.nodes - 1):
                node = int(offsets[r]) + i
                if self.planar:  # the controls' in-plane column is the rod's component comp there, signed
                    nat[i, int(comp[node])] += bent.get(2 * node, 0.0) * float(sign[node]) * float(m.planar_sign)
                else:
                    nat[i] += (bent.get(2 * node, 0.0), bent.get(2 * node + 1, 0.0))
            out.append(dataclasses.replace(rod, natural_curvature=tuple((float(a), float(b)) for a, b in nat)))
        return out

    def _value(self, z: np.ndarray, name: str) -> float:
        return next((max(float(zi), 0.0) for u, zi in zip(self.unknowns, z) if u.name == name), 0.0)

    def followed(self, z: np.ndarray) -> tuple[tuple[np.ndarray, np.ndarray], dict]:
        """The commands as the actuators follow them, the lag of the play of each (:func:`play_schedule`,
        :func:`lag_schedule` with the values at ``z``): (κ (T, N, 2), twist (T, N)), and their derivatives with
        respect to ``actuation_play`` and ``actuation_lag`` (each a pair like the first)."""
        w, tau = self._value(z, "actuation_play"), self._value(z, "actuation_lag")
        memo = getattr(self, "_followed", None)  # one Jacobian asks once per unknown at the same z
        if memo is not None and memo[0] == (w, tau):
            return memo[1]
        out, dplay, dlag = [], [], []
        for c in (self.cmd_kb, self.cmd_tb):
            p, dp = play_schedule(c, w)
            f, df = lag_schedule(p, tau, self.dt)
            out.append(f)
            dlag.append(df)
            dplay.append(lag_schedule(dp, tau, self.dt)[0])  # the lag is linear in its input, from 0
        result = (out[0], out[1]), {"actuation_play": tuple(dplay), "actuation_lag": tuple(dlag)}
        self._followed = ((w, tau), result)
        return result

    def controls_at(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(κ̄ (T, N, 2), τ̄ (T, N)) the rod is driven with: rest values, and gain · lagged command + offset at the
        commanded nodes."""
        T = self.steps
        kb = np.broadcast_to(self.rest_kb, (T,) + self.rest_kb.shape).copy()
        tb = np.broadcast_to(self.rest_tb, (T,) + self.rest_tb.shape).copy()
        for u, zi in zip(self.unknowns, z):  # the natural curvature the fitted scene holds (spec_at)
            if u.name == "rest_kappa":
                kb[:, u.index // 2, u.index % 2] += zi
        if self.cmds is None:
            return kb, tb
        gains = {u.index: zi for u, zi in zip(self.unknowns, z) if u.name == "actuation_gain"}
        offs = {u.index: zi for u, zi in zip(self.unknowns, z) if u.name == "actuation_offset"}
        (fk, ft), _ = self.followed(z)
        for n in self.cmds.nodes:
            g = gains.get(int(n), 1.0)
            kb[:, n] = g * fk[:, n] + np.array([offs.get(2 * int(n), 0.0), offs.get(2 * int(n) + 1, 0.0)])
            tb[:, n] = g * ft[:, n]
        if self.planar:
            kb[..., 1] = 0.0
        return kb, tb

    def z0(self) -> np.ndarray:
        z = []
        for u in self.unknowns:
            if u.name in _LOG:
                z.append(0.0)
            elif u.name == "damping":
                z.append(float(self.spec.sim.damping))
            elif u.name == "friction":
                z.append(float(self.spec.contact.friction))
            elif u.name == "gravity":
                z.append(float(self.spec.sim.gravity[u.index]))
            elif u.name == "actuation_gain":
                z.append(1.0)
            else:
                z.append(0.0)
        return np.array(z)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the unknowns: the ranges :data:`sim.scene.validate.BOUNDS` allows the scene values they set (every
        rod's and every edge's value; ν in (-1, 0.5] for the shear modulus), so that no fitted value makes an
        invalid scene. Log factors bounded in log space; the actuation map is unbounded."""
        lo, hi = [], []
        for u in self.unknowns:
            a, b = _unknown_bounds(self.spec, u, self.play_limit)
            if not a < b:
                raise FitError(f"{u.label}: the scene's values already span the whole valid range "
                               f"({_bound_text(u)}): nothing is left to fit")
            lo.append(a)
            hi.append(b)
        return np.array(lo), np.array(hi)

    def rollout(self, z: np.ndarray) -> G.Tape:
        return self.rollouts(np.asarray(z, dtype=np.float64)[None, :])

    def rollouts(self, Z: np.ndarray) -> G.Tape:
        """One rollout of as many envs as rows of ``Z`` (K, P), env e at the unknowns Z[e]: each env with its own
        masses, stiffnesses, damping and gravity (:meth:`sim.step.Simulator.set_env_models`), initial state (the
        base and obstacles where Z[e] puts them) and controls."""
        models = []
        for z in Z:
            try:
                models.append(build_model(self.spec_at(z)))
            except (SceneError, ValueError) as exc:
                raise FitError(f"parameters {self.describe(z)} make no valid scene: {exc}") from None
        K = len(models)
        sim = Simulator(models[0], K)
        try:
            sim.set_env_models(models)
        except ValueError as exc:
            raise FitError(f"--starts: {exc}; fit such a parameter from one start") from None
        state = sim.reset()
        for e, m in enumerate(models[1:], start=1):
            one = Simulator(m, 1).reset()
            for name in STATE_ARRAYS:
                getattr(state, name)[e] = getattr(one, name)[0]
        ctrl = [self.controls_at(z) for z in Z]
        ctrls = []
        for k in range(self.steps):
            c = sim.make_control()
            for e, (kb, tb) in enumerate(ctrl):
                c.kappa_bar[e] = kb[k]
                c.tau_bar[e] = tb[k]
            ctrls.append(c)
        return G.rollout(sim, state, ctrls)

    def residuals(self, tape: G.Tape, env: int = 0) -> np.ndarray:
        pos = self._node_pos(tape.dof[:, env], self.model0.plane_y if self.planar else None)
        return (self.predict(pos) - self.meas.pos)[:, self._axes].reshape(-1)

    def jacobian(self, tape: G.Tape, z: np.ndarray) -> np.ndarray:
        return self.jacobians(tape, z[None, :])[0]

    def jacobians(self, tape: G.Tape, Z: np.ndarray) -> np.ndarray:
        """(K, residuals, P): the Jacobian of every env of ``tape`` (:meth:`rollouts` at Z (K, P)), by one pass
        of the tangent mode for all of them."""
        tangents = []
        for u in self.unknowns:  # each env its own unknown's tangent, side by side along the env axis
            per = [self._tangent(u, z) for z in Z]
            tangents.append({nm: np.concatenate([t[nm] for t in per], axis=1 if nm in ("kappa_bar", "tau_bar") else 0)
                             for nm in per[0]})
        d = tape.jvp(tangents)["dof"]  # (P, T + 1, K, n)
        out = np.empty((Z.shape[0], 0 if d.shape[0] == 0 else self.meas.t.size * len(self._axes), len(tangents)))
        for e in range(Z.shape[0]):
            for q in range(len(tangents)):
                out[e, :, q] = self.predict(self._node_pos(d[q, :, e], None))[:, self._axes].reshape(-1)
        return out

    def gradient(self, tape: G.Tape, z: np.ndarray, r: np.ndarray) -> np.ndarray:
        """Jᵀ r (the gradient of ½‖r‖² with respect to the unknowns) by one adjoint pass, without J: the residuals'
        cotangent spread onto the DOFs of the (step, node) pairs they interpolate, then each unknown's tangent
        dotted with the parameters' gradients."""
        rr = np.zeros((r.size // len(self._axes), 3))
        rr[:, self._axes] = r.reshape(-1, len(self._axes))
        pos = np.zeros((tape.dof.shape[0], self.model0.node_count, 3))
        np.add.at(pos, (self._k, self._n), self._w[:, :, None] * rr[:, None, :])
        c = np.zeros(tape.dof.shape[:1] + tape.dof.shape[2:])  # (T + 1, n)
        if self.planar:
            c[:, 0::2], c[:, 1::2] = pos[:, :, 0], pos[:, :, 2]
        else:
            for a in range(3):
                c[:, a::4] = pos[:, :, a]
        tangents = [self._tangent(u, z) for u in self.unknowns]
        names = tuple(sorted({nm for t in tangents for nm in t}))
        grads = tape.vjp({"dof": c[:, None, :]}, params=names)
        return np.array([sum(float(np.sum(grads[nm] * v)) for nm, v in t.items()) for t in tangents])

    def _tangent(self, u: Unknown, z: np.ndarray) -> dict:
        T, N = self.steps, self.model0.node_count
        if u.name == "youngs_modulus":
            return {"log_youngs_modulus": np.ones(1), "log_shear_modulus": np.ones(1)}
        if u.name == "shear_modulus":
            return {"log_shear_modulus": np.ones(1)}
        if u.name == "density":
            return {"log_density": np.ones(1)}
        if u.name == "radius":
            return {"log_radius": np.ones(1)}
        if u.name == "damping":
            return {"damping": np.ones(1)}
        if u.name == "contact_stiffness":
            return {"log_contact_stiffness": np.ones(1)}
        if u.name == "contact_delta":
            return {"log_contact_delta": np.ones(1)}
        if u.name == "friction":
            return {"friction": np.ones(1)}
        if u.name == "gravity":
            g = np.zeros((1, 3))
            g[0, u.index] = 1.0
            return {"gravity": g}
        if u.name == "base_orientation":  # every node turned, the clamp's too (a constrained DOF keeps its change)
            return {"dof0": self._turn_tangent(z, u)}
        if u.name == "base_position":  # every node moved, the clamp's too (a constrained DOF keeps its change)
            d = np.zeros((1, self.model0.node_count, 2 if self.planar else 4))
            d[0, :, u.index if not self.planar else u.index // 2] = 1.0
            return {"dof0": d.reshape(1, -1)}
        if u.name == "obstacle_position":
            d = np.zeros((1, len(self.spec.obstacles), 3))
            d[0, u.index // 3, u.index % 3] = 1.0
            return {"obstacle_position": d}
        kb = np.zeros((T, 1, N, 2))
        tb = np.zeros((T, 1, N))
        if u.name == "rest_kappa":  # added to every step's natural curvature at its node
            kb[:, 0, u.index // 2, u.index % 2] = 1.0
            return {"kappa_bar": kb}
        if u.name in ("actuation_gain", "actuation_play", "actuation_lag"):
            (fk, ft), derivs = self.followed(z)
            if u.name == "actuation_gain":
                kb[:, 0, u.index] = fk[:, u.index]
                tb[:, 0, u.index] = ft[:, u.index]
            else:  # every commanded node: its gain times the followed command's derivative
                dk, dt_ = derivs[u.name]
                gains = {v.index: zi for v, zi in zip(self.unknowns, z) if v.name == "actuation_gain"}
                for n in self.cmds.nodes:
                    g = gains.get(int(n), 1.0)
                    kb[:, 0, n] = g * dk[:, n]
                    tb[:, 0, n] = g * dt_[:, n]
            if self.planar:
                kb[..., 1] = 0.0
                tb[:] = 0.0
            return {"kappa_bar": kb, "tau_bar": tb}
        kb[:, 0, u.index // 2, u.index % 2] = 1.0
        return {"kappa_bar": kb}

    def values(self, z: np.ndarray) -> dict[str, float]:
        """The unknowns in the scene's units (log factors turned into the fitted values of the first rod)."""
        spec = self.spec_at(z)  # the values the fitted scene holds (clipped into BOUNDS at a bound)
        rod = spec.rods[0]
        out = {}
        for u, zi in zip(self.unknowns, z):
            if u.name == "youngs_modulus":
                out[u.label] = rod.youngs_modulus
            elif u.name == "shear_modulus":
                out[u.label] = rod.youngs_modulus / (2.0 * (1.0 + rod.poisson_ratio))
            elif u.name == "density":
                out[u.label] = rod.density
            elif u.name == "radius":
                out[u.label] = rod.radius
            elif u.name == "contact_stiffness":
                out[u.label] = spec.contact.stiffness
            elif u.name == "contact_delta":
                out[u.label] = spec.contact.delta
            elif u.name == "friction":
                out[u.label] = spec.contact.friction
            elif u.name == "base_position":  # where the fitted scene puts the first rod's start
                out[u.label] = float(spec.rods[0].start[u.index])
            elif u.name == "base_orientation":  # the turn [rad] (the fitted scene holds the turned direction)
                out[u.label] = _clip(float(zi), -BASE_TURN_MAX, BASE_TURN_MAX)
            elif u.name == "obstacle_position":  # where the fitted scene puts the obstacle's anchor point
                out[u.label] = float(_anchor(spec.obstacles[u.index // 3])[u.index % 3])
            elif u.name in ("damping", "gravity", "actuation_lag", "actuation_play"):
                out[u.label] = _clip(float(zi), *_unknown_bounds(self.spec, u, self.play_limit))
            else:
                out[u.label] = float(zi)
        return out

    def describe(self, z: np.ndarray) -> str:
        return ", ".join(f"{k} = {v:.6g}" for k, v in self.values(z).items())


# ---------------------------------------------------------------------------------------------------- the fit
@dataclasses.dataclass(frozen=True)
class FitTrack:
    """The fitted motion and the measurements side by side: the step times ``t`` (T + 1,) [s] and node positions
    ``node_pos`` (T + 1, N, 3) [m] of the fitted rollout (every rod of the scene), and per measured point (M rows)
    its time ``measured_t`` [s], its position ``measured`` (M, 3) [m] and the fitted rod's position there
    ``predicted`` (M, 3) [m] (2-D: y of the motion plane). With a held-out part (``fit(holdout=…)``) the rollout
    and the rows cover the whole motion and ``held_out`` (M,) marks the held-out rows; ``measured_s`` (M,) [m] and
    ``measured_rod`` (M,) are each row's arclength and rod, ``node_s`` (N,) [m] and ``node_rod`` (N,) each node's
    (:func:`node_arclength`), ``axes`` the coordinates fitted (x, z in 2-D)."""

    t: np.ndarray
    node_pos: np.ndarray
    measured_t: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    measured_s: np.ndarray | None = None
    measured_rod: np.ndarray | None = None
    held_out: np.ndarray | None = None
    node_s: np.ndarray | None = None
    node_rod: np.ndarray | None = None
    axes: tuple = (0, 1, 2)
    rod_names: tuple = ()


@dataclasses.dataclass
class FitResult:
    """Fitted values and their standard errors (scene units), correlation, RMS residual [m] (per measured
    coordinate), the held-out RMS (NaN without a held-out part), iterations, seconds, and whether Ctrl-C ended it."""

    params: dict
    stderr: dict
    correlation: np.ndarray
    rms_m: float
    holdout_rms_m: float
    iterations: int
    seconds: float
    interrupted: bool
    spec: object
    residual_rows: list
    unconverged_steps: int
    confounded: list = dataclasses.field(default_factory=list)  # groups of unknowns the data cannot separate
    track: "FitTrack | None" = None  # the fitted motion beside the measured points (for drawing them together)
    at_bound: list = dataclasses.field(default_factory=list)  # unknowns that ended on a bound of Problem.bounds
    # with several starts (fit(starts=K)): each start's values where it began and ended and its RMS residual [m]
    # there, best first (the one then fitted alone)
    starts: list = dataclasses.field(default_factory=list)

    def summary(self) -> dict:
        out = {"params": self.params, "stderr": {k: (None if math.isinf(v) else v) for k, v in self.stderr.items()},
               "not_separable": self.confounded, "at_bound": self.at_bound, "rms_m": self.rms_m,
               "holdout_rms_m": None if math.isnan(self.holdout_rms_m) else self.holdout_rms_m,
               "iterations": self.iterations, "seconds": round(self.seconds, 3)}
        if self.starts:
            out["starts"] = [{"from": s["from"], "to": s["to"], "rms_m": s["rms_m"]} for s in self.starts]
        return out


class _Stopped(Exception):
    """``on_eval`` asked the fit to stop (it then ends as an interrupted one: the best parameters so far)."""


FIT_METHODS = ("lm", "lbfgs")


def fit(spec, meas: Measurements, params: list[str], *, cmds: Commands | None = None, holdout: float = 0.0,
        max_iterations: int = 50, progress: bool = False, log=None, on_eval=None, method: str = "lm",
        starts: int = 1, seed: int = 0) -> FitResult:
    """Fit ``params`` of ``spec`` to ``meas`` (see the module docstring). ``on_eval(evaluation, rms_m, values)``, if
    given, is called after each residual evaluation (its count from 1, the RMS residual [m], the unknowns' values by
    label); returning True stops the fit, which then ends like one interrupted by Ctrl-C (the best so far).
    ``method``: "lm", trust-region least squares with J from the tangent mode (P tangents per evaluation), or
    "lbfgs", L-BFGS-B on ½‖r‖² with its gradient Jᵀr from one adjoint pass (for many unknowns). ``starts`` > 1:
    that many starting points (the scene's values and ``starts`` − 1 drawn around them with ``seed``) searched in
    lock-step as the envs of one batched simulator (:mod:`sim.analysis.multistart`, at most ``max_iterations``
    batched iterations), the best then fitted as one start; the material values, damping, gravity, base, obstacles
    and actuation map may differ per env, the contact's settings may not."""
    import scipy.optimize

    if method not in FIT_METHODS:
        raise FitError(f"unknown method {method!r}; known: {', '.join(FIT_METHODS)}")
    if not 0.0 <= holdout < 1.0:
        raise FitError(f"--holdout must be in [0, 1), got {holdout!r}")
    t_cut = np.inf
    if holdout > 0.0:
        t_cut = float(np.quantile(meas.t, 1.0 - holdout))
        train = meas.subset(meas.t < t_cut)
        if train.t.size < 2:
            raise FitError(f"--holdout {holdout}: no measured points left to fit")
    else:
        train = meas
    if not (isinstance(starts, (int, np.integer)) and starts >= 1):
        raise FitError(f"--starts must be an integer >= 1, got {starts!r}")
    if starts > 1:
        if method != "lm":
            raise FitError("--starts needs --method lm (the starts are Levenberg–Marquardt iterations side by side)")
        shared = [p for p in params if p in ("contact_stiffness", "contact_delta", "friction")]
        if shared:
            raise FitError(f"--starts: {shared[0]} is a [contact] setting every env of a batch shares; fit it from "
                           "one start")
    prob = Problem(spec, train, cmds, params)
    m_res = 3 * train.t.size
    if m_res < len(prob.unknowns):
        raise FitError(f"{train.t.size} measured points cannot determine {len(prob.unknowns)} unknowns")
    t0 = time.perf_counter()
    z_start, searched, n_lock, stopped = prob.z0(), [], 0, False
    if starts > 1:  # Ctrl-C or on_eval stopping the search: the best start as it stands, not polished
        z_start, searched, n_lock, stopped = _search_starts(prob, starts, seed, max_iterations, progress, log, on_eval)
    best = {"cost": np.inf, "z": z_start}
    cache: dict = {}
    evals = [0]
    bar = progress_bar(max_iterations, desc="rodlab fit", unit="eval", enabled=progress)

    def tape_at(z):
        key = z.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = prob.rollout(z)
        return cache[key]

    def fun(z):
        try:
            r = prob.residuals(tape_at(z))
        except G.GradientError as exc:
            raise FitError(f"at {prob.describe(z)}: {exc}") from None
        cost = float(r @ r)
        if cost < best["cost"]:
            best.update(cost=cost, z=z.copy())
        bar.update(1)
        bar.set_postfix_str(f"rms {math.sqrt(cost / max(r.size, 1)) * 1e3:.3g} mm")
        rms = math.sqrt(cost / max(r.size, 1))
        if log is not None:
            log(f"rodlab fit: {prob.describe(z)}: rms {rms:.4g} m")
        evals[0] += 1
        if on_eval is not None and on_eval(evals[0], rms, prob.values(z)):
            raise _Stopped
        return r

    def jac(z):
        return prob.jacobian(tape_at(z), z)

    interrupted = False
    nit = 0
    lo, hi = prob.bounds()
    def loss_and_gradient(z):
        r = fun(z)
        return 0.5 * float(r @ r), prob.gradient(tape_at(z), z, r)

    try:
        if stopped:
            raise _Stopped
        if method == "lm":
            res = scipy.optimize.least_squares(fun, z_start, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac",
                                               max_nfev=max_iterations, xtol=1e-10, ftol=1e-12, gtol=1e-12)
        else:
            res = scipy.optimize.minimize(loss_and_gradient, z_start, jac=True, method="L-BFGS-B",
                                          bounds=list(zip(lo, hi)),
                                          options={"maxfun": max_iterations, "ftol": 1e-15, "gtol": 1e-12})
        nit = int(res.nfev) + n_lock
    except (KeyboardInterrupt, _Stopped):
        interrupted = True
        nit = evals[0] + n_lock
    finally:
        bar.close()
    z = best["z"]
    tape = tape_at(z)
    r = prob.residuals(tape)
    Jm = prob.jacobian(tape, z)
    dof = max(r.size - z.size, 1)
    sigma2 = float(r @ r) / dof
    cov, confounded = _covariance(Jm, sigma2, [u.label for u in prob.unknowns])
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    vals = prob.values(z)
    stderr = {}
    for u, zi, si in zip(prob.unknowns, z, sd):
        stderr[u.label] = vals[u.label] * si if u.name in _LOG else float(si)  # d(e^z) = e^z dz
    lo, hi = prob.bounds()
    tol = 1e-6 * np.maximum(1.0, np.abs(np.where(np.isfinite(lo), lo, 0.0)))
    tol_hi = 1e-6 * np.maximum(1.0, np.abs(np.where(np.isfinite(hi), hi, 0.0)))
    at_bound = [u.label for u, zi, a, b, ta, tb in zip(prob.unknowns, z, lo, hi, tol, tol_hi)
                if zi - a <= ta or b - zi <= tb]
    hold = math.nan
    held = np.zeros(meas.t.size if holdout > 0.0 else train.t.size, bool)
    shown, shown_tape, shown_r = prob, tape, r  # the rows of the report and the track: every measured point
    if holdout > 0.0:
        full = Problem(spec, meas, cmds, params)
        shown, shown_tape = full, full.rollout(z)
        shown_r = full.residuals(shown_tape)
        held = meas.t >= t_cut
        hold = float(np.sqrt(np.mean(shown_r.reshape(meas.t.size, -1)[held] ** 2)))
    rows = _residual_rows(shown, shown_r, held)
    pos = shown._node_pos(shown_tape.dof[:, 0], shown.model0.plane_y if shown.planar else None)
    node_s, node_rod = node_arclength(spec, shown.model0)
    track = FitTrack(t=np.arange(pos.shape[0]) * shown.dt, node_pos=pos, measured_t=shown.meas.t.copy(),
                     measured=shown.meas.pos.copy(), predicted=shown.predict(pos), measured_s=shown.meas.s.copy(),
                     measured_rod=shown.meas.rod.copy(), held_out=held, node_s=node_s, node_rod=node_rod,
                     axes=tuple(shown._axes), rod_names=tuple(rod.name for rod in spec.rods))
    return FitResult(params=vals, stderr=stderr, correlation=corr, rms_m=float(np.sqrt(np.mean(r ** 2))),
                     holdout_rms_m=hold, iterations=nit, seconds=time.perf_counter() - t0, interrupted=interrupted,
                     spec=prob.spec_at(z), residual_rows=rows, unconverged_steps=tape.unconverged,
                     confounded=confounded, track=track, at_bound=at_bound, starts=searched)


def _search_starts(prob: Problem, K: int, seed: int, iterations: int, progress: bool, log, on_eval):
    """The multi-start search of :func:`fit`: (the best start's unknowns, each start's record for
    :attr:`FitResult.starts`, the batched iterations, whether it was stopped)."""
    from sim.analysis.multistart import lockstep_lm, start_points

    Z0 = start_points(prob, K, np.random.default_rng(seed))
    m = max(prob.meas.t.size * len(prob._axes), 1)
    bar = progress_bar(iterations, desc=f"rodlab fit: {K} starts", unit="it", enabled=progress)

    def on_iteration(i: int, cost: np.ndarray, Z: np.ndarray) -> bool:
        rms = math.sqrt(float(np.min(cost)) / m)
        bar.update(1)
        bar.set_postfix_str(f"best rms {rms * 1e3:.3g} mm")
        if log is not None:
            log(f"rodlab fit: {K} starts, iteration {i}: best rms {rms:.4g} m")
        return bool(on_eval is not None and on_eval(i, rms, prob.values(Z[int(np.argmin(cost))])))

    try:
        ms = lockstep_lm(prob, Z0, iterations=iterations, on_iteration=on_iteration)
    except G.GradientError as exc:
        raise FitError(f"{K} starts: {exc}") from None
    finally:
        bar.close()
    order = np.argsort(ms.cost)
    searched = [{"from": prob.values(ms.start[e]), "to": prob.values(ms.z[e]),
                 "rms_m": math.sqrt(float(ms.cost[e]) / m) if np.isfinite(ms.cost[e]) else None} for e in order]
    return ms.z[ms.best].copy(), searched, ms.iterations, ms.interrupted


CONFOUNDED_RCOND = 1e-7  # a direction of the unknowns whose scaled singular value is below this fraction of the
# largest moves the simulated points by less than the rounding of the fit: the data set only a combination


def _covariance(Jm: np.ndarray, sigma2: float, labels: list[str]) -> tuple[np.ndarray, list[list[str]]]:
    """σ² (JᵀJ)⁻¹ of the unknowns, and the groups of unknowns the data cannot separate (their variances are then
    infinite): the parameters that make up each near-null direction of J (columns scaled to unit norm)."""
    norms = np.linalg.norm(Jm, axis=0)
    scale = np.where(norms > 0, norms, 1.0)
    U, S, Vt = np.linalg.svd(Jm / scale, full_matrices=False)
    weak = S < CONFOUNDED_RCOND * (S[0] if S.size else 1.0)
    groups = []
    for v in Vt[weak]:
        big = np.abs(v) > 0.1 * np.abs(v).max()
        groups.append([labels[i] for i in np.flatnonzero(big)])
    for i in np.flatnonzero(norms == 0):
        groups.append([labels[i]])
    Sinv = np.where(weak, 0.0, 1.0 / np.where(S > 0, S, 1.0))
    cov = (Vt.T * Sinv**2) @ Vt * sigma2 / np.outer(scale, scale)
    for g in groups:
        for lab in g:
            i = labels.index(lab)
            cov[i, i] = np.inf
    return cov, groups


def _residual_rows(prob: Problem, r: np.ndarray, held: np.ndarray) -> list:
    """One row per measured point (RESIDUAL_COLUMNS): time, arclength, rod, residual (fitted -
    measured) [m], its length, and the split it belongs to ("fit", or "holdout" for the held-out part)."""
    rr = r.reshape(prob.meas.t.size, -1)
    names = [rod.name for rod in prob.spec.rods]
    out = []
    for i in range(prob.meas.t.size):
        d = np.zeros(3)
        d[prob._axes] = rr[i]
        out.append((float(prob.meas.t[i]), float(prob.meas.s[i]), names[prob.meas.rod[i]], *d.tolist(),
                    float(np.linalg.norm(d)), "holdout" if held[i] else "fit"))
    return out


# ---------------------------------------------------------------------------------------------------- the report
# ``--report DIR``, written atomically (sim.support.atomicio: a reader never sees half a file):
# * fit.json: the JSON summary, the correlation matrix with its labels, the inputs, the fitted scene and ``plots``;
# * residuals.csv: one row per measured point (RESIDUAL_COLUMNS: fitted - measured [m], split ``fit``/``holdout``);
# * overlay.png: each marker's measured x, y, z (dots) against the fitted rod's at its arclength (lines) over time
#   (x, z in 2-D; at most MAX_MARKERS markers: those measured most often);
# * residuals_time.png, residuals_arclength.png: the RMS residual of the points measured at each time / at each
#   arclength (binned when the points do not share arclengths), the held-out part marked;
# * correlation.png: the correlation matrix as an annotated heat map (n/a where the data cannot separate them).
# matplotlib (Agg canvas, no pyplot) is imported inside the functions, so ``import sim.analysis.calibration`` stays light.
RESIDUAL_COLUMNS = ("t", "s", "rod", "dx", "dy", "dz", "distance", "split")  # residuals.csv
PLOTS = ("overlay.png", "residuals_time.png", "residuals_arclength.png", "correlation.png")
MAX_MARKERS = 6  # markers drawn in overlay.png
MAX_ARCLENGTHS = 40  # more distinct arclengths than this on a rod are binned in residuals_arclength.png
_DPI = 100
_HELD_COLOUR = "#d62728"


def write_report(folder, res, **doc) -> list[Path]:
    """Write the report of the fit result ``res`` (sim.analysis.calibration.FitResult) into ``folder``; ``doc``: further entries of
    fit.json (scene, data, fitted_scene, …). Returns the paths written (fit.json last)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    tr = res.track
    if tr is not None:
        figures = (_overlay(tr), _residuals_time(tr), _residuals_arclength(tr),
                   _correlation(list(res.params), res.correlation))
        written += [_save(fig, folder / name) for name, fig in zip(PLOTS, figures)]
    lines = [",".join(RESIDUAL_COLUMNS)] + [",".join(f"{v:.9g}" if isinstance(v, float) else str(v) for v in row)
                                            for row in res.residual_rows]
    written.append(write_text(folder / "residuals.csv", "\n".join(lines) + "\n"))
    full = dict(res.summary(), **doc,
                correlation={"labels": list(res.params), "matrix": np.nan_to_num(res.correlation).tolist()},
                interrupted=res.interrupted, unconverged_steps=res.unconverged_steps,
                plots=[p.name for p in written if p.suffix == ".png"])
    written.append(write_text(folder / "fit.json", json.dumps(full, indent=1)))
    return written


# ------------------------------------------------------------------------------------------- the report: helpers
def _figure(w: float, h: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h), dpi=_DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path: Path) -> Path:
    return write_via_path(path, lambda tmp: fig.savefig(tmp, format="png", dpi=_DPI))


def _held(tr) -> np.ndarray:
    return np.zeros(tr.measured_t.size, bool) if tr.held_out is None else np.asarray(tr.held_out, bool)


def _mark_held_out(ax, tr) -> None:
    held = _held(tr)
    if held.any():
        ax.axvspan(float(tr.measured_t[held].min()), float(max(tr.t[-1], tr.measured_t.max())), color=_HELD_COLOUR,
                   alpha=0.08, label="held out")


def _rows(tr) -> tuple[np.ndarray, np.ndarray]:
    """(s (M,), rod (M,)) of the measured rows (one rod at s = 0 … when the track does not carry them)."""
    s = np.zeros(tr.measured_t.size) if tr.measured_s is None else np.asarray(tr.measured_s)
    rod = np.zeros(tr.measured_t.size, int) if tr.measured_rod is None else np.asarray(tr.measured_rod)
    return s, rod


def _rod_label(tr, r: int) -> str:
    names = tuple(tr.rod_names or ())
    return f"{names[r]} " if len(names) > 1 else ""


def _rms_rows(tr) -> np.ndarray:
    """RMS residual per measured row over the fitted coordinates [m]."""
    d = (tr.predicted - tr.measured)[:, list(tr.axes)]
    return np.sqrt(np.mean(d ** 2, axis=1))


def _along(tr, rod: int, s: float) -> np.ndarray | None:
    """The fitted rod's position at arclength s of rod ``rod`` at every step (T + 1, 3), or None without nodes."""
    if tr.node_s is None or tr.node_rod is None:
        return None
    idx = np.flatnonzero(np.asarray(tr.node_rod) == rod)
    arc = np.asarray(tr.node_s)[idx]
    j = int(np.clip(np.searchsorted(arc, s, side="right") - 1, 0, idx.size - 2))
    w = float(np.clip((s - arc[j]) / (arc[j + 1] - arc[j]), 0.0, 1.0))
    return (1.0 - w) * tr.node_pos[:, idx[j]] + w * tr.node_pos[:, idx[j + 1]]


# --------------------------------------------------------------------------------------------- the report: plots
def _overlay(tr):
    s, rod = _rows(tr)
    keys, counts = np.unique(np.stack([rod.astype(float), s], axis=1), axis=0, return_counts=True)
    order = np.argsort(-counts, kind="stable")[:MAX_MARKERS]
    chosen = keys[np.sort(order)]
    axes = list(tr.axes)
    fig = _figure(9.0, 2.3 * len(axes) + 0.6)
    axs = fig.subplots(len(axes), 1, sharex=True, squeeze=False)[:, 0]
    colours = [f"C{i}" for i in range(10)]
    for k, (r, sk) in enumerate(chosen):
        r = int(r)
        sel = (rod == r) & (s == sk)
        order_t = np.argsort(tr.measured_t[sel], kind="stable")
        line = _along(tr, r, float(sk))
        label = f"{_rod_label(tr, r)}s = {sk:.3g} m"
        for ax, a in zip(axs, axes):
            ax.plot(tr.measured_t[sel][order_t], tr.measured[sel][order_t, a], ".", color=colours[k % 10], ms=3.5,
                    label=f"{label} measured")
            if line is not None:
                ax.plot(tr.t, line[:, a], "-", color=colours[k % 10], lw=1.2, label=f"{label} fitted")
            else:
                ax.plot(tr.measured_t[sel][order_t], tr.predicted[sel][order_t, a], "-", color=colours[k % 10],
                        lw=1.2, label=f"{label} fitted")
    for ax, a in zip(axs, axes):
        _mark_held_out(ax, tr)
        ax.set_ylabel(f"{'xyz'[a]} [m]")
        ax.grid(alpha=0.3)
    axs[-1].set_xlabel("t [s]")
    axs[0].set_title("measured (dots) and fitted (lines) marker positions")
    axs[0].legend(fontsize=7, ncol=2, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    return fig


def _residuals_time(tr):
    rms = _rms_rows(tr)
    held = _held(tr)
    fig = _figure(8.0, 3.4)
    ax = fig.subplots()
    for part, colour, name in ((~held, "C0", "fit"), (held, _HELD_COLOUR, "held out")):
        if not part.any():
            continue
        times, inv = np.unique(tr.measured_t[part], return_inverse=True)
        per_t = np.sqrt(np.bincount(inv, rms[part] ** 2) / np.bincount(inv))
        ax.plot(times, per_t * 1e3, ".-", color=colour, ms=3, lw=1, label=f"{name} (RMS "
                f"{np.sqrt(np.mean(rms[part] ** 2)) * 1e3:.3g} mm)")
    _mark_held_out(ax, tr)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("RMS residual [mm]")
    ax.set_title("residual over time (RMS of the points measured at each time)")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def _residuals_arclength(tr):
    rms = _rms_rows(tr)
    held = _held(tr)
    s, rod = _rows(tr)
    fig = _figure(8.0, 3.4)
    ax = fig.subplots()
    rods = np.unique(rod)
    for k, r in enumerate(rods):
        on_rod = rod == r
        values = np.unique(s[on_rod])
        if values.size > MAX_ARCLENGTHS:  # points at scattered arclengths: bins of equal width
            edges = np.linspace(values.min(), values.max(), MAX_ARCLENGTHS // 2 + 1)
            centres = 0.5 * (edges[:-1] + edges[1:])
            key = centres[np.clip(np.searchsorted(edges, s, side="right") - 1, 0, centres.size - 1)]
        else:
            key = s
        for part, style, name in ((~held, "-", "fit"), (held, "--", "held out")):
            sel = on_rod & part
            if not sel.any():
                continue
            at, inv = np.unique(key[sel], return_inverse=True)
            per_s = np.sqrt(np.bincount(inv, rms[sel] ** 2) / np.bincount(inv))
            colour = _HELD_COLOUR if (name == "held out" and rods.size == 1) else f"C{k % 10}"
            ax.plot(at, per_s * 1e3, "o" + style, color=colour, ms=4, lw=1, label=f"{_rod_label(tr, int(r))}{name}")
    ax.set_xlabel("s [m] (arclength from the rod's first node)")
    ax.set_ylabel("RMS residual [mm]")
    ax.set_title("residual along the rod (RMS over time at each arclength)")
    ax.set_ylim(bottom=0.0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def _correlation(labels: list[str], corr: np.ndarray):
    n = len(labels)
    c = np.asarray(corr, float).reshape(n, n)
    size = max(3.2, 0.75 * n + 2.2)
    fig = _figure(size + 0.8, size)
    ax = fig.subplots()
    im = ax.imshow(np.where(np.isfinite(c), c, np.nan), cmap="RdBu_r", vmin=-1.0, vmax=1.0)
    for i in range(n):
        for j in range(n):
            v = c[i, j]
            txt = f"{v:.2f}".replace("-0.00", "0.00") if np.isfinite(v) else "n/a"
            ax.text(j, i, txt, ha="center", va="center", fontsize=8,
                    color="white" if np.isfinite(v) and abs(v) > 0.6 else "black")
    ax.set_xticks(range(n), labels, rotation=45, ha="right", fontsize=8)
    ax.set_yticks(range(n), labels, fontsize=8)
    ax.set_title("correlation of the fitted values")
    fig.colorbar(im, ax=ax, shrink=0.8)
    return fig


# ---------------------------------------------------------------------------------------------------- command line
def _free_name(scene: Path) -> Path:
    base = scene.with_name(f"{scene.stem}_fitted.toml")
    k = 2
    while base.exists():
        base = scene.with_name(f"{scene.stem}_fitted_{k}.toml")
        k += 1
    return base


def fit_command(argv: list[str] | None = None, *, readers=None) -> int:
    """``rodlab fit``. ``readers``: further DATA formats by suffix (see :func:`load_measurements`); ``rodlab fit``
    itself runs :func:`policies.recording.fitdata.fit_main`, which adds the ``.rrd`` recordings."""
    ap = argparse.ArgumentParser(prog="rodlab fit", description=__doc__.split("\n\n")[0])
    ap.add_argument("scene", help="scene TOML file")
    ap.add_argument("data", help="measured motion: CSV t,s,x,y,z[,rod], .npz (t, s, pos) or a rodlab .rrd "
                                 "recording (node positions of one episode)")
    ap.add_argument("--episode", type=int, default=0, help="episode of an .rrd recording (default 0)")
    ap.add_argument("--params", required=True, help=f"comma-separated: {', '.join(FIT_PARAMETERS)}")
    ap.add_argument("--controls", help="commanded curvature CSV t,node,kappa1,kappa2,twist")
    ap.add_argument("--out", help="fitted scene TOML (default: SCENE_fitted.toml beside the scene; never over an "
                                  "existing file)")
    ap.add_argument("--report", help="folder for fit.json, residuals.csv and the plots (overlay, residuals over "
                                     "time and along the rod, correlation)")
    ap.add_argument("--holdout", type=float, default=0.0, help="fraction of the motion (the last part) held out")
    ap.add_argument("--max-iterations", type=int, default=50, help="most residual evaluations (default 50)")
    ap.add_argument("--method", choices=FIT_METHODS, default="lm",
                    help="lm: trust-region least squares with the tangent-mode Jacobian (default); lbfgs: L-BFGS-B "
                         "with the gradient from one adjoint pass per evaluation (many unknowns)")
    ap.add_argument("--starts", type=int, default=1,
                    help="starting points searched side by side as the envs of one batched simulator, the best then "
                         "fitted (default 1: the scene's values; --method lm)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the starting points drawn (default 0)")
    ap.add_argument("--json", action="store_true", help="print one JSON object on the last line")
    add_progress_flag(ap)
    args = ap.parse_args(argv)
    try:
        return _run(args, readers)
    except (FitError, SceneError, G.GradientError) as exc:
        print(f"rodlab fit: {exc}", file=sys.stderr)
        return 2


def _run(args, readers=None) -> int:
    scene = Path(args.scene)
    spec = load_scene(scene)
    out = Path(args.out) if args.out else _free_name(scene)
    if out.exists():
        what = "the input scene" if out.resolve() == scene.resolve() else "an existing file"
        raise FitError(f"--out {out} is {what}; the fitted scene is always written to a new file")
    try:
        check_output_path(out, suffix=".toml")
        if args.report:
            check_output_path(args.report, folder=True)
    except ValueError as exc:
        raise FitError(str(exc)) from None
    if args.max_iterations < 1:
        raise FitError(f"--max-iterations must be >= 1, got {args.max_iterations}")
    params = [p.strip() for p in args.params.split(",") if p.strip()]
    if args.episode < 0:
        raise FitError(f"--episode must be >= 0, got {args.episode}")
    meas = load_measurements(args.data, spec, readers=readers, episode=args.episode)
    cmds = load_controls(args.controls, build_model(spec)) if args.controls else None
    res = fit(spec, meas, params, cmds=cmds, holdout=args.holdout, max_iterations=args.max_iterations,
              progress=progress_wanted(args.progress, json_output=args.json), method=args.method, starts=args.starts,
              seed=args.seed)
    dump_scene(res.spec, out)
    if args.report:
        write_report(args.report, res, scene=str(scene), data=str(args.data), fitted_scene=str(out))
    if not args.json:
        print(f"rodlab fit: {'interrupted: best so far' if res.interrupted else 'done'} after {res.iterations} "
              f"evaluations in {res.seconds:.1f} s; rms {res.rms_m:.4g} m"
              + ("" if math.isnan(res.holdout_rms_m) else f", held out {res.holdout_rms_m:.4g} m"))
        if res.starts:
            far = [s for s in res.starts if s["rms_m"] is None or s["rms_m"] > 1.01 * res.starts[0]["rms_m"]]
            print(f"  {len(res.starts)} starts: the best ended at rms {res.starts[0]['rms_m']:.4g} m; "
                  f"{len(far)} ended elsewhere (other minima, or stopped short)")
        for k, v in res.params.items():
            print(f"  {k:<28} {v:.6g} ± {res.stderr[k]:.2g}")
        for g in res.confounded:
            print(f"  the data cannot separate {', '.join(g)}: they move the rod the same way (fix all but one, "
                  "e.g. weigh the rod for its density)")
        if res.at_bound:
            print(f"  ended on a bound of the valid scene values (docs/conventions.md, Input bounds): "
                  f"{', '.join(res.at_bound)}; the data would take it further")
        if res.unconverged_steps:
            print(f"  ({res.unconverged_steps} steps ended unconverged and were differentiated as if converged)")
        print(f"rodlab fit: wrote {out}")
    else:
        print(json.dumps(res.summary()))
    return 130 if res.interrupted else 0


if __name__ == "__main__":
    sys.exit(fit_command())
