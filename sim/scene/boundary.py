"""Point loads (``[[load]]``) and constrained nodes/edges with prescribed motion (``[[fix]]``): the specs, their
TOML parsing, checks and dump, and the per-DOF arrays the Model and the Simulator use (docs/physics.md §3.1, §3.6).

Keys (SI units)::

    [[load]]  rod (the name of the rod it acts on; optional in a one-rod scene, whose [rod] table is "rod"),
              node (int, within that rod; negative counts from its end),
              force [N] (3-vector, default 0), moment [N m] (3-vector, default 0: a couple on edge
              min(node, N-2), its part along the edge's tangent on the edge's twist (3-D), the rest as a pair of
              opposite forces on the edge's two nodes; 2-D: about y only), frame ("world", default, or
              "material": force and moment components along the material frame (m1, m2, t) of edge
              min(node, N-2), so the load turns with the rod — a follower load; 3-D only), torque [N m] (about
              the local tangent, 3-D only, default 0; it acts on the twist of edge min(node, N-2)), start [s]
              (default 0), stop [s] (default: never)
    [[line_load]] rod (as for loads), force_per_length [N/m] (3-vector, world frame: a uniform distributed load
              along the whole rod, each node taking its Voronoi length's share), start [s], stop [s]
    [drag]    normal, tangential [N s/m²] (viscous drag per unit length against the motion across and along the
              rod, resistive-force theory; default 0), flow [m/s] (3-vector: the fluid's uniform velocity,
              default 0); acts on every rod (docs/physics.md §3.1)
    [[fix]]   rod (as for loads), nodes (list of int within that rod, negative from its end), axes (subset of
              "xyz", default "xyz"), twist_edges (list of int within that rod, 3-D only), velocity [m/s] (3-vector: prescribed motion of the
              fixed axes, default 0), twist_rate [rad/s] (of the fixed twist edges, default 0),
              angular_velocity [rad/s] (3-vector: the fixed nodes and edges turn rigidly at ω about ``center``,
              a rotating clamp; needs axes "xyz" and no velocity; in 2-D ω along y), center [m] (3-vector, default:
              the first fixed node's initial position), start [s], stop [s] (the window of the prescribed motion),
              built_in (bool, default false: the rod is built in exactly where an edge the fix holds whole meets
              the free rod, as ``[rod] clamp = "node"``; docs/physics.md §3.6)

Node and edge indices count within their rod; :func:`global_node` / :func:`global_edge` map them onto the
scene's chain of nodes (the rods' nodes concatenated in file order, docs/physics.md §1.7).

Moments and material-frame loads depend on the rod's configuration: they are evaluated at the start of each step
(the edge's vector and material frame the step starts from), so a static solve (which steps to rest) reaches their
exact equilibrium and a dynamic step lags them by one step (docs/physics.md §3.1).

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

from sim.geometry.rotations import matrix_from_rotvec
from sim.scene.tomlio import (
    SceneError,
    check_unknown,
    format_value,
    take_bool,
    take_float,
    take_int,
    take_str,
    take_vec3,
)

__all__ = ["LoadSpec", "LineLoadSpec", "DragSpec", "parse_drag", "dump_drag", "FixSpec", "FrameLoads", "parse_loads",
           "parse_line_loads", "dump_line_loads",
           "frame_load_arrays", "frame_load_forces", "parse_fixes", "dump_loads", "dump_fixes", "check_boundary",
           "ROD_NAME", "node_index", "load_arrays", "motion_arrays", "fixed_dofs", "window_fraction", "rod_layout",
           "rod_span", "global_node", "global_edge", "held_edges"]

ROD_NAME = "rod"  # the name of the single [rod] table (and the default rod name), the ``rod`` key of loads and fixes


@dataclass(frozen=True)
class LoadSpec:
    """A point force [N] and moment [N m] (world frame, or the material frame of edge min(node, N-2) with
    ``frame = "material"``) and a torque [N m] (about the local tangent) on one node."""

    node: int
    force: tuple[float, float, float] = (0.0, 0.0, 0.0)
    torque: float = 0.0
    start: float = 0.0
    stop: float | None = None
    rod: str | None = None
    moment: tuple[float, float, float] = (0.0, 0.0, 0.0)
    frame: str = "world"

    @property
    def follows_rod(self) -> bool:
        """Whether the load depends on the rod's configuration (a moment, or material-frame components)."""
        return self.frame == "material" or any(m != 0.0 for m in self.moment)


@dataclass(frozen=True)
class LineLoadSpec:
    """A uniform distributed load [N/m] (world frame) along a whole rod."""

    force_per_length: tuple[float, float, float] = (0.0, 0.0, 0.0)
    start: float = 0.0
    stop: float | None = None
    rod: str | None = None


@dataclass(frozen=True)
class DragSpec:
    """Viscous drag per unit length (resistive-force theory): ``normal`` and ``tangential`` coefficients [N s/m²]
    against the velocity relative to the uniform ``flow`` [m/s] across and along the rod."""

    normal: float = 0.0
    tangential: float = 0.0
    flow: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def acts(self) -> bool:
        """Whether the drag exerts any force (a coefficient above 0)."""
        return self.normal > 0.0 or self.tangential > 0.0


@dataclass(frozen=True)
class FrameLoads:
    """The loads that depend on the configuration, as arrays (K loads): the node a force acts on ``node`` (K,), the
    edge a moment acts on and whose frame a material-frame load uses ``edge`` (K,) (scene-wide indices), ``force``
    (K, 3) [N] and ``moment`` (K, 3) [N m] (world components, or material-frame components where ``material``
    (K,) bool), their windows ``window`` (K, 2) [s]. World-frame forces are not here (they are constant)."""

    node: np.ndarray
    edge: np.ndarray
    force: np.ndarray
    moment: np.ndarray
    material: np.ndarray
    window: np.ndarray

    @property
    def count(self) -> int:
        return int(self.node.shape[0])


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
    angular_velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    center: tuple[float, float, float] | None = None
    built_in: bool = False


@dataclass(frozen=True)
class RotatingFix:
    """A fix turning rigidly (the Model's form of a ``[[fix]]`` with ``angular_velocity``): its nodes and the twist
    edges of the scene's chain, the centre [m], ω [rad/s] and the window [start, stop) [s]."""

    nodes: np.ndarray
    edges: np.ndarray
    center: np.ndarray
    omega: np.ndarray
    window: np.ndarray


_LOAD_KEYS = {"rod", "node", "force", "moment", "frame", "torque", "start", "stop"}
_LINE_LOAD_KEYS = {"rod", "force_per_length", "start", "stop"}
_DRAG_KEYS = {"normal", "tangential", "flow"}
_FIX_KEYS = {"rod", "nodes", "axes", "twist_edges", "velocity", "twist_rate", "start", "stop", "angular_velocity",
             "center", "built_in"}


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
                            stop=_stop(t, p, path), rod=_rod_key(t, p, path),
                            moment=take_vec3(t, "moment", p, path, (0.0, 0.0, 0.0)),
                            frame=take_str(t, "frame", p, path, "world", choices=("world", "material"))))
    return tuple(out)


def parse_line_loads(tables: Any, path: str | None) -> tuple[LineLoadSpec, ...]:
    """The ``[[line_load]]`` tables (typed; checked by :func:`check_boundary`)."""
    out = []
    for i, t in enumerate(_tables(tables, "line_load", path)):
        p = f"line_load[{i}]."
        check_unknown(t, _LINE_LOAD_KEYS, p, path)
        out.append(LineLoadSpec(force_per_length=take_vec3(t, "force_per_length", p, path, (0.0, 0.0, 0.0)),
                                start=take_float(t, "start", p, path, 0.0), stop=_stop(t, p, path),
                                rod=_rod_key(t, p, path)))
    return tuple(out)


def parse_drag(table: Any, path: str | None) -> DragSpec | None:
    """The ``[drag]`` table (None without one; ranges are checked by :func:`check_boundary`)."""
    if table is None:
        return None
    if not isinstance(table, dict):
        raise SceneError(f"{path or '<scene>'}: drag: expected a table [drag]")
    check_unknown(table, _DRAG_KEYS, "drag.", path)
    return DragSpec(normal=take_float(table, "normal", "drag.", path, 0.0),
                    tangential=take_float(table, "tangential", "drag.", path, 0.0),
                    flow=take_vec3(table, "flow", "drag.", path, (0.0, 0.0, 0.0)))


def dump_drag(drag: DragSpec | None) -> list[str]:
    """The ``[drag]`` table's lines (none without drag)."""
    if drag is None:
        return []
    return ["[drag]"] + [f"{k} = {format_value(getattr(drag, k))}" for k in ("normal", "tangential", "flow")]


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
                           rod=_rod_key(t, p, path),
                           angular_velocity=take_vec3(t, "angular_velocity", p, path, (0.0, 0.0, 0.0)),
                           center=take_vec3(t, "center", p, path, (0.0, 0.0, 0.0)) if "center" in t else None,
                           built_in=take_bool(t, "built_in", p, path, False)))
    return tuple(out)


def _dump(items: Sequence[Any], kind: str, keys: tuple[str, ...], flags: tuple[str, ...] = ()) -> list[str]:
    """The TOML lines of ``items`` as ``[[kind]]`` tables: ``keys`` (None left out), then the bool ``flags`` that
    are set."""
    lines: list[str] = []
    for it in items:
        lines += ["", f"[[{kind}]]"]
        for k in keys + flags:
            v = getattr(it, k)
            if v is None or (k in flags and not v):
                continue
            lines.append(f"{k} = {format_value(list(v) if isinstance(v, tuple) else v)}")
    return lines[1:]


def dump_loads(loads: Sequence[LoadSpec]) -> list[str]:
    return _dump(loads, "load", ("rod", "node", "force", "moment", "frame", "torque", "start", "stop"))


def dump_line_loads(loads: Sequence[LineLoadSpec]) -> list[str]:
    return _dump(loads, "line_load", ("rod", "force_per_length", "start", "stop"))


def dump_fixes(fixes: Sequence[FixSpec]) -> list[str]:
    return _dump(fixes, "fix", ("rod", "nodes", "axes", "twist_edges", "velocity", "twist_rate", "angular_velocity",
                                "center", "start", "stop"), flags=("built_in",))


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
    """Check the loads and fixes of ``spec`` (``c``: the scene checker of :mod:`sim.scene.validate`)."""
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
        mo = c.vec(p + "moment", ld.moment, "load.moment")
        if ld.frame not in ("world", "material"):
            c.fail(p + "frame", f"must be \"world\" or \"material\", got {ld.frame!r}")
        if planar and ld.frame == "material":
            c.fail(p + "frame", "material-frame (follower) loads need mode '3d'")
        if planar and ld.force[1] != 0.0:
            c.fail(p + "force", "mode '2d' needs a force in the x-z plane (y = 0)")
        if planar and (mo[0] != 0.0 or mo[2] != 0.0):
            c.fail(p + "moment", "mode '2d' bends in the x-z plane: a moment about y only ([0, My, 0])")
        if ld.follows_rod and N < 2:
            c.fail(p + "moment", "a moment or follower load needs an edge (a rod of 2 nodes or more)")
    for k, ll in enumerate(getattr(spec, "line_loads", ()) or ()):
        p = f"line_load[{k}]."
        common(p, ll)
        q = c.vec(p + "force_per_length", ll.force_per_length, "line_load.force_per_length")
        if planar and q[1] != 0.0:
            c.fail(p + "force_per_length", "mode '2d' needs a load in the x-z plane (y = 0)")
    drag = getattr(spec, "drag", None)
    if drag is not None:
        c.num("drag.normal", drag.normal, "drag.normal")
        c.num("drag.tangential", drag.tangential, "drag.tangential")
        u = c.vec("drag.flow", drag.flow, "drag.flow")
        if planar and u[1] != 0.0:
            c.fail("drag.flow", "mode '2d' needs a flow in the x-z plane (y = 0)")
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
        om = c.vec(p + "angular_velocity", fx.angular_velocity, "fix.angular_velocity")
        if fx.center is not None:
            c.vec(p + "center", fx.center, "fix.center")
        if any(om):
            if not fx.nodes or set(fx.axes) != set("xyz"):
                c.fail(p + "angular_velocity", f"a rotating fix turns whole nodes: it needs nodes and axes = \"xyz\" "
                                               f"(axes = {fx.axes!r}, nodes = {list(fx.nodes)})")
            if any(v) or w != 0.0:
                c.fail(p + "angular_velocity", "give a rotating fix no velocity or twist_rate (it turns rigidly)")
            if planar and (om[0] != 0.0 or om[2] != 0.0):
                c.fail(p + "angular_velocity", "mode '2d' turns in the x-z plane: ω along y only")
            ends = {i % N for i in fx.nodes}
            for j in fx.twist_edges:
                if j % (N - 1) not in ends or j % (N - 1) + 1 not in ends:
                    c.fail(p + "twist_edges", f"edge {j} turns with the fix: both its nodes ({j % (N - 1)}, "
                                              f"{j % (N - 1) + 1}) must be among the fix's nodes")
        if not isinstance(fx.built_in, bool):
            c.fail(p + "built_in", f"expected true or false, got {fx.built_in!r}")
        if fx.built_in and not held_edges(fx, N, planar):
            c.fail(p + "built_in", "the rod is built in at the end of an edge the fix holds whole: it needs two "
                                   "neighbouring nodes in all axes" + ("" if planar else " and that edge in "
                                   "twist_edges") + f" (nodes = {list(fx.nodes)}, axes = {fx.axes!r}, "
                                   f"twist_edges = {list(fx.twist_edges)})")


def held_edges(fx: FixSpec, count: int, planar: bool) -> list[int]:
    """The edges (indices within the fix's rod of ``count`` nodes) that ``fx`` holds whole: both nodes in all axes
    (x and z in 2-D) and, in 3-D, the edge's twist."""
    if not (set("xz") if planar else set("xyz")) <= set(fx.axes):
        return []
    nodes = {node_index(int(i), count) for i in fx.nodes}
    twist = {node_index(int(j), count - 1) for j in fx.twist_edges}
    return [j for j in range(count - 1) if j in nodes and j + 1 in nodes and (planar or j in twist)]


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


def load_arrays(spec: Any, N: int, dpn: int, voronoi_length: np.ndarray | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """The constant loads: (forces (L, N * dpn) [N or N m] per load, windows (L, 2) [s] with stop = inf when open):
    the point loads' world-frame forces and torques, then the line loads (``voronoi_length`` (N,) [m]: each node's
    share). Moments and material-frame forces are :func:`frame_load_arrays`'."""
    loads = getattr(spec, "loads", ()) or ()
    lines = getattr(spec, "line_loads", ()) or ()
    L = len(loads) + len(lines)
    F = np.zeros((L, N, dpn))
    win = np.zeros((L, 2))
    for k, ld in enumerate(loads):
        off, n = rod_span(spec, ld.rod)
        i = node_index(ld.node, n)
        if ld.frame == "world":
            for a, s in _axis_dofs("xyz", dpn == 2):
                F[k, off + i, s] = ld.force[a]
        if dpn == 4:  # the twist of the rod's edge min(i, n - 2)
            F[k, off + min(i, n - 2), 3] += ld.torque
        win[k] = (ld.start, math.inf if ld.stop is None else ld.stop)
    for m, ll in enumerate(lines):
        k = len(loads) + m
        off, n = rod_span(spec, ll.rod)
        if voronoi_length is None:
            raise ValueError("line loads need the nodes' Voronoi lengths")
        for a, s in _axis_dofs("xyz", dpn == 2):
            F[k, off:off + n, s] = ll.force_per_length[a] * voronoi_length[off:off + n]
        win[k] = (ll.start, math.inf if ll.stop is None else ll.stop)
    return F.reshape(L, N * dpn), win


def frame_load_arrays(spec: Any) -> FrameLoads:
    """The point loads that depend on the configuration (:attr:`LoadSpec.follows_rod`) as :class:`FrameLoads`."""
    loads = [ld for ld in (getattr(spec, "loads", ()) or ()) if ld.follows_rod]
    node = np.zeros(len(loads), np.int64)
    edge = np.zeros(len(loads), np.int64)
    force = np.zeros((len(loads), 3))
    moment = np.zeros((len(loads), 3))
    material = np.zeros(len(loads), bool)
    win = np.zeros((len(loads), 2))
    for k, ld in enumerate(loads):
        off, n = rod_span(spec, ld.rod)
        i = node_index(ld.node, n)
        node[k], edge[k] = off + i, off + min(i, n - 2)
        material[k] = ld.frame == "material"
        if material[k]:
            force[k] = ld.force
        moment[k] = ld.moment
        win[k] = (ld.start, math.inf if ld.stop is None else ld.stop)
    return FrameLoads(node=node, edge=edge, force=force, moment=moment, material=material, window=win)


def frame_load_forces(fl: FrameLoads, weight: np.ndarray, pos: np.ndarray, frames: Any, dpn: int) -> np.ndarray:
    """(B, N * dpn): the generalised forces of the configuration-dependent loads ``fl`` at node positions ``pos``
    (B, N, 3), each scaled by its ``weight`` (B, K) (the fraction of the step in its window). ``frames``: a callable
    giving the material frame (m1, m2, t) (B, N-1, 3) each, called only when a load is in the material frame.
    A moment M on edge j (e = x_{j+1} − x_j, t = e/|e|): its tangential part (M·t) on the twist of edge j (3-D),
    its normal part M⊥ as the forces ±(M⊥ × e)/|e|² on nodes j + 1 and j, whose couple e × F is M⊥
    (docs/physics.md §3.1)."""
    B, N = pos.shape[0], pos.shape[1]
    out = np.zeros((B, N, dpn))
    j, node = fl.edge, fl.node
    e = pos[:, j + 1] - pos[:, j]                                  # (B, K, 3)
    ee = np.einsum("bki,bki->bk", e, e)
    t = e / np.sqrt(ee)[..., None]
    force = np.broadcast_to(fl.force, e.shape).copy()
    moment = np.broadcast_to(fl.moment, e.shape).copy()
    if fl.material.any():
        m1, m2, tt = (a[:, j] for a in frames())
        sel = fl.material
        for arr in (force, moment):
            comp = arr[:, sel]
            arr[:, sel] = (comp[..., 0:1] * m1[:, sel] + comp[..., 1:2] * m2[:, sel] + comp[..., 2:3] * tt[:, sel])
    along = np.einsum("bki,bki->bk", moment, t)
    normal = moment - along[..., None] * t
    pair = np.cross(normal, e) / ee[..., None]                      # on node j + 1; its opposite on node j
    w = weight[..., None]
    slots = [(0, 0), (2, 1)] if dpn == 2 else [(0, 0), (1, 1), (2, 2)]
    for a, s in slots:
        np.add.at(out[..., s], (slice(None), node), w[..., 0] * force[..., a])
        np.add.at(out[..., s], (slice(None), j + 1), w[..., 0] * pair[..., a])
        np.add.at(out[..., s], (slice(None), j), -w[..., 0] * pair[..., a])
    if dpn == 4:
        np.add.at(out[..., 3], (slice(None), j), weight * along)
    return out.reshape(B, N * dpn)


def rotating_fixes(spec: Any, rest: np.ndarray) -> tuple[RotatingFix, ...]:
    """The fixes with an angular velocity, on the scene's chain of nodes (``rest`` (N, 3): the initial node
    positions, for the default centre)."""
    out = []
    for fx in getattr(spec, "fixes", ()) or ():
        if not any(fx.angular_velocity):
            continue
        nodes = np.array([global_node(spec, fx.rod, i) for i in fx.nodes], np.int64)
        edges = np.array([global_edge(spec, fx.rod, j) for j in fx.twist_edges], np.int64)
        center = rest[nodes[0]] if fx.center is None else np.asarray(fx.center, np.float64)
        out.append(RotatingFix(nodes=nodes, edges=edges, center=np.array(center, np.float64),
                               omega=np.asarray(fx.angular_velocity, np.float64),
                               window=np.array([fx.start, math.inf if fx.stop is None else fx.stop])))
    return tuple(out)


def turn_fix(rf: RotatingFix, dof: np.ndarray, tangent: np.ndarray, ref_d1: np.ndarray, seconds: float,
             transport) -> None:
    """Turn one env's fixed nodes and twist edges of ``rf`` rigidly by ω × ``seconds`` about its centre, in place in
    ``dof`` (N, dpn). A twist edge's angle θ is set so that its material frame is the turned one once the step has
    transported the reference director ``ref_d1`` from ``tangent`` (the step start's) onto the new tangent, as the
    step does (docs/physics.md §1.3, §3.6)."""
    R = matrix_from_rotvec(rf.omega * seconds)
    c = rf.center
    if dof.shape[1] == 2:  # 2-D: (x, z) per node, a turn about y
        xz = dof[rf.nodes]
        p = np.column_stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]]) - c
        q = p @ R.T + c
        dof[rf.nodes, 0], dof[rf.nodes, 1] = q[:, 0], q[:, 2]
        return
    dof[rf.nodes, :3] = (dof[rf.nodes, :3] - c) @ R.T + c
    for j in rf.edges:
        t0, d1 = tangent[j], ref_d1[j]
        th = dof[j, 3]
        m1 = math.cos(th) * d1 + math.sin(th) * np.cross(t0, d1)
        e = dof[j + 1, :3] - dof[j, :3]
        t1 = e / np.linalg.norm(e)
        d1n = np.asarray(transport(d1, t0, t1), np.float64)
        target = R @ m1
        new = math.atan2(float(np.cross(d1n, target) @ t1), float(d1n @ target))
        dof[j, 3] = th + (new - th + math.pi) % (2.0 * math.pi) - math.pi  # continuous in time


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
