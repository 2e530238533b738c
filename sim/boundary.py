"""Point loads (``[[load]]``) and constrained nodes/edges with prescribed motion (``[[fix]]``): the specs, their
TOML parsing, checks and dump, and the per-DOF arrays the Model and the Simulator use (docs/physics.md §3.1, §3.6).

Keys (SI units)::

    [[load]]  rod (the name of the rod it acts on; optional in a one-rod scene, whose [rod] table is "rod"),
              node (int, within that rod; negative counts from its end),
              force [N] (3-vector, world frame, default 0), torque [N m] (about the local tangent, 3-D only,
              default 0; it acts on the twist of edge min(node, N-2)), start [s] (default 0), stop [s]
              (default: never)
    [[fix]]   rod (as for loads), nodes (list of int within that rod, negative from its end), axes (subset of
              "xyz", default "xyz"), twist_edges (list of int within that rod, 3-D only), velocity [m/s] (3-vector: prescribed motion of the
              fixed axes, default 0), twist_rate [rad/s] (of the fixed twist edges, default 0), start [s],
              stop [s] (the window of the prescribed motion)

Node and edge indices count within their rod; :func:`global_node` / :func:`global_edge` map them onto the
scene's chain of nodes (the rods' nodes concatenated in file order, docs/physics.md §1.7).

A load acts on an env while its time is inside [start, stop): over a step [t, t + dt] the force is weighted by
the fraction of the step inside the window; a prescribed motion moves its DOFs by rate × (the time of the step
inside the window).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .tomlio import SceneError, check_unknown, format_value, take_float, take_int, take_str, take_vec3

__all__ = ["LoadSpec", "FixSpec", "parse_loads", "parse_fixes", "dump_loads", "dump_fixes", "check_boundary",
           "ROD_NAME", "node_index", "load_arrays", "motion_arrays", "fixed_dofs", "window_fraction", "rod_layout",
           "rod_span", "global_node", "global_edge"]

ROD_NAME = "rod"  # the name of the single [rod] table (and the default rod name), the ``rod`` key of loads and fixes


@dataclass(frozen=True)
class LoadSpec:
    """A point force [N] (world frame) and torque [N m] (about the local tangent) on one node."""

    node: int
    force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torque: float = 0.0
    start: float = 0.0
    stop: float | None = None
    rod: str | None = None


@dataclass(frozen=True)
class FixSpec:
    """Constrained node axes and edge twists, optionally moved at ``velocity`` [m/s] / ``twist_rate`` [rad/s]
    during [start, stop)."""

    nodes: tuple[int, ...] = ()
    axes: str = "xyz"
    twist_edges: tuple[int, ...] = ()
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    twist_rate: float = 0.0
    start: float = 0.0
    stop: float | None = None
    rod: str | None = None


_LOAD_KEYS = {"rod", "node", "force", "torque", "start", "stop"}
_FIX_KEYS = {"rod", "nodes", "axes", "twist_edges", "velocity", "twist_rate", "start", "stop"}


def _int_list(t: Mapping[str, Any], name: str, prefix: str, path: str | None) -> tuple[int, ...]:
    v = t.get(name, [])
    if not isinstance(v, (list, tuple)) or any(isinstance(i, bool) or not isinstance(i, int) for i in v):
        raise SceneError(f"{path or '<scene>'}: {prefix}{name}: expected a list of integers, got {v!r}")
    return tuple(int(i) for i in v)


def _tables(tables: Any, kind: str, path: str | None) -> list[dict]:
    if not isinstance(tables, list) or not all(isinstance(t, dict) for t in tables):
        raise SceneError(f"{path or '<scene>'}: {kind}: expected an array of tables [[{kind}]]")
    return tables


def _rod_key(t: Mapping[str, Any], prefix: str, path: str | None) -> str | None:
    return take_str(t, "rod", prefix, path, None) if "rod" in t else None


def _stop(t: Mapping[str, Any], prefix: str, path: str | None) -> float | None:
    return take_float(t, "stop", prefix, path) if "stop" in t else None


def parse_loads(tables: Any, path: str | None) -> tuple[LoadSpec, ...]:
    """The ``[[load]]`` tables (typed; ranges are checked by :func:`check_boundary`)."""
    out = []
    for i, t in enumerate(_tables(tables, "load", path)):
        p = f"load[{i}]."
        check_unknown(t, _LOAD_KEYS, p, path)
        out.append(LoadSpec(node=take_int(t, "node", p, path), force=take_vec3(t, "force", p, path, (0.0, 0.0, 0.0)),
                            torque=take_float(t, "torque", p, path, 0.0), start=take_float(t, "start", p, path, 0.0),
                            stop=_stop(t, p, path), rod=_rod_key(t, p, path)))
    return tuple(out)


def parse_fixes(tables: Any, path: str | None) -> tuple[FixSpec, ...]:
    """The ``[[fix]]`` tables (typed; ranges are checked by :func:`check_boundary`)."""
    out = []
    for i, t in enumerate(_tables(tables, "fix", path)):
        p = f"fix[{i}]."
        check_unknown(t, _FIX_KEYS, p, path)
        out.append(FixSpec(nodes=_int_list(t, "nodes", p, path), axes=take_str(t, "axes", p, path, "xyz"),
                           twist_edges=_int_list(t, "twist_edges", p, path),
                           velocity=take_vec3(t, "velocity", p, path, (0.0, 0.0, 0.0)),
                           twist_rate=take_float(t, "twist_rate", p, path, 0.0),
                           start=take_float(t, "start", p, path, 0.0), stop=_stop(t, p, path),
                           rod=_rod_key(t, p, path)))
    return tuple(out)


def _dump(items: Sequence[Any], kind: str, keys: tuple[str, ...]) -> list[str]:
    lines: list[str] = []
    for it in items:
        lines += ["", f"[[{kind}]]"]
        for k in keys:
            v = getattr(it, k)
            if v is None:
                continue
            lines.append(f"{k} = {format_value(list(v) if isinstance(v, tuple) else v)}")
    return lines[1:]


def dump_loads(loads: Sequence[LoadSpec]) -> list[str]:
    return _dump(loads, "load", ("rod", "node", "force", "torque", "start", "stop"))


def dump_fixes(fixes: Sequence[FixSpec]) -> list[str]:
    return _dump(fixes, "fix", ("rod", "nodes", "axes", "twist_edges", "velocity", "twist_rate", "start", "stop"))


def node_index(i: int, count: int) -> int:
    """Index i (negative counts from the end) into range [0, count)."""
    return i + count if i < 0 else i


def rod_layout(spec: Any) -> tuple[tuple[str, int, int], ...]:
    """(name, first node, node count) of each rod of ``spec`` in file order (their nodes form one chain)."""
    rods = getattr(spec, "rods", None) or (spec.rod,)
    out, off = [], 0
    for r in rods:
        out.append((getattr(r, "name", ROD_NAME), off, int(r.nodes)))
        off += int(r.nodes)
    return tuple(out)


def _names(layout: Sequence[tuple[str, int, int]]) -> str:
    return ", ".join(repr(name) for name, _, _ in layout)


def rod_span(spec: Any, rod: str | None) -> tuple[int, int]:
    """(first node, node count) of the rod named ``rod`` (None: the only rod); SceneError if there is no such
    rod, or ``rod`` is None and the scene has several."""
    layout = rod_layout(spec)
    if rod is None:
        if len(layout) > 1:
            raise SceneError(f"the scene has several rods ({_names(layout)}): name one (rod = ...)")
        return layout[0][1], layout[0][2]
    for name, off, n in layout:
        if name == rod:
            return off, n
    raise SceneError(f"no rod named {rod!r} (the rods: {_names(layout)})")


def global_node(spec: Any, rod: str | None, i: int) -> int:
    """The chain index of node ``i`` (negative counts from the end) of the rod named ``rod``."""
    off, n = rod_span(spec, rod)
    return off + node_index(int(i), n)


def global_edge(spec: Any, rod: str | None, j: int) -> int:
    """The chain index of edge ``j`` (negative counts from the end) of the rod named ``rod``."""
    off, n = rod_span(spec, rod)
    return off + node_index(int(j), n - 1)


def check_boundary(c: Any, spec: Any) -> None:
    """Check the loads and fixes of ``spec`` (``c``: the scene checker of :mod:`sim.validate`)."""
    layout = rod_layout(spec)
    planar = spec.sim.mode == "2d"

    def common(p: str, it: Any) -> int:
        """The node count of the item's rod (after checking its ``rod`` key) and its window."""
        if it.rod is None and len(layout) > 1:
            c.fail(p + "rod", f"the scene has several rods ({_names(layout)}): name the one this acts on")
        N = layout[0][2]
        if it.rod is not None:
            hit = [n for name, _, n in layout if name == it.rod]
            if not hit:
                if len(layout) == 1 and layout[0][0] == ROD_NAME:
                    c.fail(p + "rod", f"no rod named {it.rod!r} (the single [rod] table is {ROD_NAME!r})")
                c.fail(p + "rod", f"no rod named {it.rod!r} (the rods: {_names(layout)})")
            N = hit[0]
        bound = p.split("[")[0] + ".start"
        c.num(p + "start", it.start, bound)
        if it.stop is not None:
            stop = c.num(p + "stop", it.stop, bound)
            if not stop > it.start:
                c.fail(p + "stop", f"must be > start ({it.start!r}), got {stop!r}")
        return N

    def idx(key: str, i: Any, count: int, what: str) -> None:
        if isinstance(i, bool) or not isinstance(i, (int, np.integer)):
            c.fail(key, f"expected an integer {what} index, got {i!r}")
        if not -count <= int(i) < count:
            c.fail(key, f"{what} index {i} out of range for {count} {what}s ([{-count}, {count - 1}])")

    for k, ld in enumerate(getattr(spec, "loads", ()) or ()):
        p = f"load[{k}]."
        N = common(p, ld)
        idx(p + "node", ld.node, N, "node")
        c.vec(p + "force", ld.force, "load.force")
        tq = c.num(p + "torque", ld.torque, "load.torque")
        if planar and tq != 0.0:
            c.fail(p + "torque", "a torque about the tangent needs mode '3d' (the planar rod has no twist)")
        if planar and ld.force[1] != 0.0:
            c.fail(p + "force", "mode '2d' needs a force in the x-z plane (y = 0)")
    for k, fx in enumerate(getattr(spec, "fixes", ()) or ()):
        p = f"fix[{k}]."
        N = common(p, fx)
        ax = fx.axes
        if not isinstance(ax, str) or set(ax) - set("xyz") or len(set(ax)) != len(ax):
            c.fail(p + "axes", f"must be a subset of \"xyz\" (each letter once), got {fx.axes!r}")
        if not fx.nodes and not fx.twist_edges:
            c.fail(p + "nodes", "a fix needs nodes or twist_edges")
        if fx.nodes and not fx.axes:
            c.fail(p + "axes", "empty: name the fixed axes (\"xyz\" or a subset)")
        for i in fx.nodes:
            idx(p + "nodes", i, N, "node")
        if planar and fx.twist_edges:
            c.fail(p + "twist_edges", "fixed edge twist needs mode '3d' (the planar rod has no twist)")
        for j in fx.twist_edges:
            idx(p + "twist_edges", j, N - 1, "edge")
        v = c.vec(p + "velocity", fx.velocity, "fix.velocity")
        for a, name in enumerate("xyz"):
            if v[a] != 0.0 and (name not in fx.axes or not fx.nodes):
                c.fail(p + "velocity", f"component {name} = {v[a]!r} moves an axis that is not fixed "
                                       f"(axes = {fx.axes!r}, nodes = {list(fx.nodes)})")
        w = c.num(p + "twist_rate", fx.twist_rate, "fix.twist_rate")
        if w != 0.0 and not fx.twist_edges:
            c.fail(p + "twist_rate", "a twist rate needs twist_edges")


def _axis_dofs(axes: str, planar: bool) -> list[tuple[int, int]]:
    """(world axis, DOF slot) pairs of ``axes`` (2-D: x -> 0, z -> 1; y is the plane's, already fixed)."""
    if planar:
        return [(a, s) for a, s in ((0, 0), (2, 1)) if "xyz"[a] in axes]
    return [(a, a) for a in range(3) if "xyz"[a] in axes]


def fixed_dofs(spec: Any, fixed: np.ndarray) -> None:
    """Set the flags of the DOFs the fixes constrain in ``fixed`` (N, dofs per node; N the scene's total)."""
    planar = fixed.shape[1] == 2
    for fx in getattr(spec, "fixes", ()) or ():
        for i in fx.nodes:
            for _, s in _axis_dofs(fx.axes, planar):
                fixed[global_node(spec, fx.rod, i), s] = True
        for j in fx.twist_edges:
            fixed[global_edge(spec, fx.rod, j), 3] = True


def load_arrays(spec: Any, N: int, dpn: int) -> tuple[np.ndarray, np.ndarray]:
    """(forces (L, N * dpn) [N or N m] per load, windows (L, 2) [s] with stop = inf when open)."""
    loads = getattr(spec, "loads", ()) or ()
    F = np.zeros((len(loads), N, dpn))
    win = np.zeros((len(loads), 2))
    for k, ld in enumerate(loads):
        off, n = rod_span(spec, ld.rod)
        i = node_index(ld.node, n)
        for a, s in _axis_dofs("xyz", dpn == 2):
            F[k, off + i, s] = ld.force[a]
        if dpn == 4:  # the twist of the rod's edge min(i, n - 2)
            F[k, off + min(i, n - 2), 3] += ld.torque
        win[k] = (ld.start, math.inf if ld.stop is None else ld.stop)
    return F.reshape(len(loads), N * dpn), win


def motion_arrays(spec: Any, N: int, dpn: int) -> tuple[np.ndarray, np.ndarray]:
    """(rates (M, N * dpn) [m/s or rad/s] per moving fix, windows (M, 2) [s])."""
    moving = [fx for fx in (getattr(spec, "fixes", ()) or ()) if any(fx.velocity) or fx.twist_rate != 0.0]
    R = np.zeros((len(moving), N, dpn))
    win = np.zeros((len(moving), 2))
    for k, fx in enumerate(moving):
        for i in fx.nodes:
            for a, s in _axis_dofs(fx.axes, dpn == 2):
                R[k, global_node(spec, fx.rod, i), s] = fx.velocity[a]
        for j in fx.twist_edges:
            R[k, global_edge(spec, fx.rod, j), 3] = fx.twist_rate
        win[k] = (fx.start, math.inf if fx.stop is None else fx.stop)
    return R.reshape(len(moving), N * dpn), win


def window_fraction(time: np.ndarray, dt: float, win: np.ndarray) -> np.ndarray:
    """(B, K): the fraction of each env's step [t, t + dt] inside each window [start, stop)."""
    t = np.asarray(time, dtype=np.float64)[:, None]
    lo = np.maximum(t, win[None, :, 0])
    hi = np.minimum(t + dt, win[None, :, 1])
    return np.clip((hi - lo) / dt, 0.0, 1.0)
