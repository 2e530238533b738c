"""Scene files (TOML) -> frozen :class:`SceneSpec`, and back (:func:`dump_scene`).

Keys (SI units)::

    [sim]  dt [s], gravity [m/s^2] (3-vector), damping [1/s] (default 0; viscous force
           F_k = -damping * m_k * v_k on every node), newton_tol [-] (relative force test),
           newton_max_iter, accept_unconverged (bool), mode ("3d"|"2d", default "3d"),
           integrator ("backward_euler"|"midpoint", default "backward_euler"),
           line_search ("auto"|"backtrack"|"none", default "auto": backtrack only in envs with contact
           candidates and only when an update raised the residual), newton_dtol [m/s] (displacement
           test, default 1e-2), divergence_guard [-] (default 10; 0 = off; docs/physics.md §6.3)
    [rod]  nodes, length [m], radius [m], density [kg/m^3], youngs_modulus [Pa], poisson_ratio [-],
           start [m] (3-vector), direction (3-vector, normalised here), clamp ("first_edge"|"node"|"none",
           default "first_edge"; "node": built in exactly at node 1, docs/physics.md §3.6), cross_section ("circle"|"rectangle"|"ellipse", default "circle":
           radius; "rectangle": width [m] (along m1) and height [m] (along m2); "ellipse": semi_axes [m]
           [a, b] (a along m1); sim/scene/section.py), rest_points [m] (list of [x, y, z]: a non-straight rest
           shape instead of nodes/length/start/direction); radius (circle) and youngs_modulus also take a
           list of nodes - 1 values, one per edge (a non-uniform rod); prestretch [-] (default 0: rest
           edge lengths = initial / (1 + prestretch), the rod starts with that axial strain); natural_curvature
           [-] (list of nodes pairs [κ1, κ2]: integrated natural curvature in the material frame added to the
           rest shape's at each node, so the rod starts away from its stress-free shape; the end nodes' are not
           used; docs/physics.md §1.2)
    [[rod]] several rods in one scene: one table per rod, each with every [rod] key and a ``name`` (a
           non-empty string, unique; required when there are several rods, default "rod"). A file has [rod]
           (one rod, named "rod") or [[rod]] tables, not both. The rods are one chain of nodes in file order
           (docs/physics.md §1.7); arrays over nodes concatenate the rods' nodes, ``Model.rod_node_offsets``
           gives where each rod starts
    [[obstacle]], [contact]   parsed by ``sim.scene.obstacles`` (see there)
    [[load]], [[line_load]], [[fix]]
                              point loads and moments, distributed loads, constrained nodes/edges and prescribed
                              motion: ``sim.scene.boundary`` (their ``rod`` key names the rod; node and edge indices count
                              within that rod)
    [drag]                    viscous drag per unit length in a fluid at rest or in a uniform flow: ``sim.scene.boundary``
"""
from __future__ import annotations

import math
import os
import re
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

from sim.scene import boundary as _bc
from sim.scene import obstacles as _obs
from sim.scene.section import SECTIONS
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
from sim.scene.validate import CLAMPS, check_scene, unit_vector
from sim.support.atomicio import write_text

__all__ = ["SceneError", "SimSpec", "RodSpec", "SceneSpec", "load_scene", "parse_scene", "dump_scene",
           "rest_shape_fields", "rod_key_prefix"]

Mode = Literal["3d", "2d"]
Integrator = Literal["backward_euler", "midpoint"]
LineSearch = Literal["none", "backtrack", "auto"]
Clamp = Literal["first_edge", "node", "none"]


@dataclass(frozen=True)
class SimSpec:
    """[sim] table. Units: dt [s], gravity [m/s^2], damping [1/s], newton_dtol [m/s]."""

    dt: float
    gravity: tuple[float, float, float]
    newton_tol: float
    newton_max_iter: int
    accept_unconverged: bool
    damping: float = 0.0
    mode: Mode = "3d"
    integrator: Integrator = "backward_euler"
    line_search: LineSearch = "auto"
    newton_dtol: float = 1e-2
    divergence_guard: float = 10.0


@dataclass(frozen=True)
class RodSpec:
    """[rod] table. Units: length/radius [m], density [kg/m^3], youngs_modulus [Pa]. direction is unit."""

    nodes: int
    length: float
    radius: float
    density: float
    youngs_modulus: float
    poisson_ratio: float
    start: tuple[float, float, float]
    direction: tuple[float, float, float]
    clamp: Clamp = "first_edge"
    # cross section (sim/scene/section.py): "circle" uses radius; "rectangle" width (along m1) x height (along m2);
    # "ellipse" semi_axes (a along m1, b along m2). For the last two, radius holds the contact radius
    # (circumscribed; derived by the parser, and by build_model from the section whatever the field holds)
    cross_section: str = "circle"
    width: float | None = None
    height: float | None = None
    semi_axes: tuple[float, float] | None = None
    # non-straight rest shape: the nodes' rest positions (N, 3) [m]; then nodes/length/start/direction are the
    # points' (see rest_shape_fields) and build_model places the nodes there (rest curvature from the points)
    rest_points: tuple | None = None
    # non-uniform rod: per-edge radius [m] (circular section) and Young's modulus [Pa], N-1 values each; the
    # scalar radius / youngs_modulus then hold the largest value (build_model uses the lists)
    edge_radius: tuple | None = None
    edge_youngs_modulus: tuple | None = None
    # pre-stretch ε0 [-]: the rest edge lengths are the initial ones / (1 + ε0), so the rod starts with axial
    # strain ε0 (tension E A ε0 where its ends are held; ε0 < 0 starts it compressed)
    prestretch: float = 0.0
    # natural curvature added to the rest shape's: (nodes, 2) integrated [κ1, κ2] per node (ends unused), or None
    natural_curvature: tuple | None = None
    # the rod's name: the ``rod`` key of loads and fixes, and how the outputs' per-rod slices are named
    name: str = _bc.ROD_NAME


@dataclass(frozen=True, init=False)
class SceneSpec:
    """A whole scene. ``path`` is where it was loaded from (None if built in code).

    ``rods``: the rods in file order (their nodes form one chain, in that order). ``SceneSpec(sim, rod=...)``
    builds a one-rod scene and ``spec.rod`` is its only rod; ``SceneSpec(sim, rods=(...))`` a scene of several
    rods (``spec.rod`` then raises: iterate over ``spec.rods``). ``dataclasses.replace(spec, rod=...)`` replaces
    the only rod, ``replace(spec, rods=...)`` all of them."""

    sim: SimSpec
    rods: tuple  # of RodSpec, at least one
    obstacles: tuple
    contact: Any
    path: str | None
    loads: tuple   # of sim.scene.boundary.LoadSpec
    fixes: tuple   # of sim.scene.boundary.FixSpec
    line_loads: tuple  # of sim.scene.boundary.LineLoadSpec
    drag: Any  # sim.scene.boundary.DragSpec, or None: no drag

    def __init__(self, sim: SimSpec, rod: RodSpec | None = None, obstacles: tuple = (), contact: Any = None,
                 path: str | None = None, loads: tuple = (), fixes: tuple = (), *, rods: Any = None,
                 line_loads: tuple = (), drag: Any = None) -> None:
        if rod is not None:
            if rods is not None and len(tuple(rods)) > 1:
                raise ValueError(f"SceneSpec: rod= sets the only rod of a one-rod scene; this one has "
                                 f"{len(tuple(rods))} rods (pass rods=)")
            rods = (rod,)
        if rods is None or len(tuple(rods)) == 0:
            raise ValueError("SceneSpec: needs a rod (rod=RodSpec(...)) or rods (rods=(RodSpec(...), ...))")
        set_ = object.__setattr__
        set_(self, "sim", sim)
        set_(self, "rods", tuple(rods))
        set_(self, "obstacles", obstacles)
        set_(self, "contact", _obs.ContactSpec() if contact is None else contact)
        set_(self, "path", path)
        set_(self, "loads", loads)
        set_(self, "fixes", fixes)
        set_(self, "line_loads", tuple(line_loads))
        set_(self, "drag", drag)

    @property
    def rod(self) -> RodSpec:
        """The only rod of a one-rod scene (ValueError with several: use ``rods``)."""
        if len(self.rods) != 1:
            raise ValueError(f"SceneSpec.rod: the scene has {len(self.rods)} rods "
                             f"({', '.join(repr(r.name) for r in self.rods)}); use spec.rods")
        return self.rods[0]

    @property
    def rod_names(self) -> tuple[str, ...]:
        """The rods' names in file order."""
        return tuple(getattr(r, "name", _bc.ROD_NAME) for r in self.rods)


_SIM_KEYS = {"dt", "gravity", "damping", "newton_tol", "newton_max_iter", "accept_unconverged", "mode",
             "integrator", "line_search", "newton_dtol", "divergence_guard"}
_ROD_KEYS = {"nodes", "length", "radius", "density", "youngs_modulus", "poisson_ratio", "start", "direction",
             "clamp", "cross_section", "width", "height", "semi_axes", "rest_points", "prestretch",
             "natural_curvature", "name"}


def _table(doc: dict, name: str, path: str | None, *, required: bool = True) -> dict | None:
    if name not in doc:
        if required:
            raise SceneError(f"{path or '<scene>'}: [{name}]: missing required table")
        return None
    t = doc[name]
    if not isinstance(t, dict):
        raise SceneError(f"{path or '<scene>'}: {name}: expected a table [{name}]")
    return t


def _take_shape(r: dict, where: str, path: str | None, rp: str = "rod.") -> dict:
    """nodes/length/start/direction of a straight rod, or rest_points (and those derived from them); ``rp`` the
    rod table's key prefix in messages."""
    if "rest_points" not in r:
        nodes = take_int(r, "nodes", rp, path)
        if nodes < 3:
            raise SceneError(f"{where}: {rp}nodes: must be >= 3, got {nodes}")
        return {"nodes": nodes, "length": take_float(r, "length", rp, path, positive=True),
                "start": take_vec3(r, "start", rp, path),
                "direction": unit_vector(take_vec3(r, "direction", rp, path), f"{where}: {rp}direction")}
    for k in ("nodes", "length", "start", "direction"):
        if k in r:
            raise SceneError(f"{where}: {rp}{k}: not used with rest_points (the points give the nodes, length, "
                             "start and direction)")
    v = r["rest_points"]
    if not isinstance(v, list) or len(v) < 3:
        raise SceneError(f"{where}: {rp}rest_points: expected a list of at least 3 points [[x, y, z], ...], "
                         f"got {v!r:.80}")
    pts = tuple(take_vec3({"rest_points": p}, "rest_points", rp, path) for p in v)
    return rest_shape_fields(pts, f"{where}: {rp}rest_points")


def rest_shape_fields(points, where: str = "rod.rest_points") -> dict:
    """RodSpec fields of a rod whose rest shape is the polyline ``points`` (N, 3): nodes, length (the polyline's),
    start (the first point), direction (of the first edge), rest_points."""
    pts = tuple(tuple(float(c) for c in p) for p in points)
    seg = [math.dist(a, b) for a, b in zip(pts[:-1], pts[1:])]
    if not all(math.isfinite(x) and x > 0.0 for x in seg):
        raise SceneError(f"{where}: consecutive points must differ (edge lengths {min(seg)!r} .. {max(seg)!r})")
    d = unit_vector([b - a for a, b in zip(pts[0], pts[1])], where)
    return {"nodes": len(pts), "length": math.fsum(seg), "start": pts[0], "direction": d, "rest_points": pts}


def _take_section(r: dict, where: str, path: str | None, rp: str = "rod.") -> dict:
    """The cross-section keys of a rod table: radius, or width/height, or semi_axes (sim/scene/section.py)."""
    kind = take_str(r, "cross_section", rp, path, "circle", choices=SECTIONS)
    need = {"circle": ("radius",), "rectangle": ("width", "height"), "ellipse": ("semi_axes",)}[kind]
    for k in ("radius", "width", "height", "semi_axes"):
        if k in r and k not in need:
            raise SceneError(f"{where}: {rp}{k}: not used by cross_section = {kind!r} (it takes "
                             f"{' and '.join(need)})")
    if kind == "circle":
        if isinstance(r.get("radius"), list):
            er = _take_edge_list(r, "radius", path, rp)
            return {"radius": max(er), "edge_radius": er}
        return {"radius": take_float(r, "radius", rp, path, positive=True)}
    if isinstance(r.get("radius"), list):
        raise SceneError(f"{where}: {rp}radius: a per-edge list needs cross_section = \"circle\"")
    if kind == "rectangle":
        w = take_float(r, "width", rp, path, positive=True)
        h = take_float(r, "height", rp, path, positive=True)
        return {"cross_section": kind, "width": w, "height": h, "radius": 0.5 * math.hypot(w, h)}
    v = r.get("semi_axes", None)
    if not isinstance(v, list) or len(v) != 2:
        raise SceneError(f"{where}: {rp}semi_axes: expected a list of 2 numbers [a, b], got {v!r}")
    ab = tuple(take_float({"semi_axes": c}, "semi_axes", rp, path, positive=True) for c in v)
    return {"cross_section": kind, "semi_axes": ab, "radius": max(ab)}


def _take_edge_list(r: dict, key: str, path: str | None, rp: str = "rod.") -> tuple:
    """A per-edge list rod.<key> = [v_0, ..., v_{N-2}] of positive numbers (its length is checked against the
    nodes by sim/scene/validate.py)."""
    v = r[key]
    if len(v) < 2:
        raise SceneError(f"{path or '<scene>'}: {rp}{key}: a per-edge list needs one value per edge (nodes - 1), "
                         f"got {len(v)}")
    return tuple(take_float({key: c}, key, rp, path, positive=True) for c in v)


def rod_key_prefix(name: str, several: bool) -> str:
    """How messages address a rod table's keys: ``rod.`` for the rod of a one-rod scene, ``rod['name'].`` when
    there are several."""
    return f"rod[{name!r}]." if several else "rod."


def _rod_tables(doc: dict, path: str | None) -> list[tuple[dict, str, str]]:
    """The rod tables of a document: ([rod] or each [[rod]], name, key prefix), names checked."""
    where = path or "<scene>"
    if "rod" not in doc:
        raise SceneError(f"{where}: [rod]: missing required table ([rod] for one rod, [[rod]] tables for several)")
    v = doc["rod"]
    tables = [v] if isinstance(v, dict) else v
    if not isinstance(tables, list) or not tables or not all(isinstance(t, dict) for t in tables):
        raise SceneError(f"{where}: rod: expected a table [rod] or an array of tables [[rod]]")
    several = len(tables) > 1
    out: list[tuple[dict, str, str]] = []
    seen: set[str] = set()
    for i, t in enumerate(tables):
        key = f"rod[{i}].name" if several else "rod.name"
        if "name" in t:
            name = take_str(t, "name", f"rod[{i}]." if several else "rod.", path)
            if not name.strip():
                raise SceneError(f"{where}: {key}: must be a non-empty name, got {name!r}")
        elif several:
            raise SceneError(f"{where}: {key}: missing; each of several [[rod]] tables needs a unique name")
        else:
            name = _bc.ROD_NAME
        if name in seen:
            raise SceneError(f"{where}: {key}: duplicate rod name {name!r} (rod names must be unique)")
        seen.add(name)
        out.append((t, name, rod_key_prefix(name, several)))
    return out


def _parse_rod(r: dict, name: str, rp: str, sim: SimSpec, where: str, path: str | None) -> RodSpec:
    check_unknown(r, _ROD_KEYS, rp, path)
    nu = take_float(r, "poisson_ratio", rp, path)
    if not (-1.0 < nu <= 0.5):
        raise SceneError(f"{where}: {rp}poisson_ratio: must be in (-1, 0.5], got {nu!r}")
    sec = _take_section(r, where, path, rp)
    if isinstance(r.get("youngs_modulus"), list):
        sec["edge_youngs_modulus"] = _take_edge_list(r, "youngs_modulus", path, rp)
        youngs = max(sec["edge_youngs_modulus"])
    else:
        youngs = take_float(r, "youngs_modulus", rp, path, positive=True)
    rod = RodSpec(
        radius=sec.pop("radius"),
        density=take_float(r, "density", rp, path, positive=True),
        youngs_modulus=youngs,
        poisson_ratio=nu,
        clamp=take_str(r, "clamp", rp, path, "first_edge", choices=CLAMPS),  # type: ignore
        prestretch=take_float(r, "prestretch", rp, path, 0.0),
        name=name,
        **sec,
        **_take_shape(r, where, path, rp),
    )
    if "natural_curvature" in r:
        v = r["natural_curvature"]
        if not isinstance(v, list) or len(v) != rod.nodes:
            raise SceneError(f"{where}: {rp}natural_curvature: expected {rod.nodes} pairs [kappa1, kappa2] (one per "
                             f"node), got {v!r:.80}")
        pairs = []
        for i, pair in enumerate(v):
            if not (isinstance(pair, list) and len(pair) == 2
                    and all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in pair)):
                raise SceneError(f"{where}: {rp}natural_curvature[{i}]: expected a pair of numbers [kappa1, kappa2], "
                                 f"got {pair!r:.80}")
            pairs.append((float(pair[0]), float(pair[1])))
        rod = replace(rod, natural_curvature=tuple(pairs))
    if sim.mode == "2d":
        if abs(rod.direction[1]) > 1e-12:
            raise SceneError(f"{where}: {rp}direction: mode '2d' needs a direction in the x-z plane (y = 0), "
                             f"got {list(rod.direction)}")
    return rod


def parse_scene(doc: dict[str, Any], path: str | None = None) -> SceneSpec:
    """Validate a parsed TOML document into a SceneSpec (raises SceneError naming file/key/problem)."""
    where = path or "<scene>"
    for k in doc:
        if k not in ("sim", "rod", "obstacle", "contact", "load", "line_load", "fix", "drag"):
            raise SceneError(f"{where}: {k}: unknown table (allowed: sim, rod, obstacle, contact, load, line_load, "
                             "fix, drag)")
    s = _table(doc, "sim", path)
    assert s is not None
    rod_tables = _rod_tables(doc, path)
    check_unknown(s, _SIM_KEYS, "sim.", path)
    sim = SimSpec(
        dt=take_float(s, "dt", "sim.", path, positive=True),
        gravity=take_vec3(s, "gravity", "sim.", path),
        damping=take_float(s, "damping", "sim.", path, 0.0, nonnegative=True),
        newton_tol=take_float(s, "newton_tol", "sim.", path, positive=True),
        newton_max_iter=take_int(s, "newton_max_iter", "sim.", path, minimum=1),
        accept_unconverged=take_bool(s, "accept_unconverged", "sim.", path),
        mode=take_str(s, "mode", "sim.", path, "3d", choices=("3d", "2d")),  # type: ignore[arg-type]
        integrator=take_str(s, "integrator", "sim.", path, "backward_euler",
                            choices=("backward_euler", "midpoint")),  # type: ignore[arg-type]
        line_search=take_str(s, "line_search", "sim.", path, "auto",
                             choices=("none", "backtrack", "auto")),  # type: ignore[arg-type]
        newton_dtol=take_float(s, "newton_dtol", "sim.", path, 1e-2, positive=True),
        divergence_guard=take_float(s, "divergence_guard", "sim.", path, 10.0, nonnegative=True),
    )
    if 0.0 < sim.divergence_guard <= 1.0:
        raise SceneError(f"{where}: sim.divergence_guard: must be 0 (off) or > 1 (a residual growth factor), "
                         f"got {sim.divergence_guard!r}")
    rods = tuple(_parse_rod(r, name, rp, sim, where, path) for r, name, rp in rod_tables)
    if sim.mode == "2d":
        if sim.gravity[1] != 0.0:
            raise SceneError(f"{where}: sim.gravity: mode '2d' needs gravity in the x-z plane (y = 0)")
    obs_tables = doc.get("obstacle", [])
    if not isinstance(obs_tables, list) or not all(isinstance(t, dict) for t in obs_tables):
        raise SceneError(f"{where}: obstacle: expected an array of tables [[obstacle]]")
    obstacles = _obs.parse_obstacles(obs_tables, path)
    contact = _obs.parse_contact(_table(doc, "contact", path, required=False), path)
    spec = SceneSpec(sim=sim, rods=rods, obstacles=tuple(obstacles), contact=contact, path=path,
                     loads=_bc.parse_loads(doc.get("load", []), path), fixes=_bc.parse_fixes(doc.get("fix", []), path),
                     line_loads=_bc.parse_line_loads(doc.get("line_load", []), path),
                     drag=_bc.parse_drag(doc.get("drag"), path))
    check_scene(spec, where)  # every number finite and within the physical bounds (sim/scene/validate.py)
    return spec


def load_scene(path: str | os.PathLike) -> SceneSpec:
    """Read and validate a scene TOML file."""
    p = str(path)
    try:
        with open(p, "rb") as fh:
            doc = tomllib.load(fh)
    except FileNotFoundError:
        raise SceneError(f"{p}: file not found") from None
    except IsADirectoryError:
        raise SceneError(f"{p}: is a directory, not a scene file") from None
    except UnicodeDecodeError as exc:
        raise SceneError(f"{p}: not a UTF-8 text file (byte {exc.start}: {exc.reason}); scene files are "
                         "UTF-8 TOML") from None
    except tomllib.TOMLDecodeError as exc:
        if _mixes_rod_tables(p):
            raise SceneError(f"{p}: rod: a file has one [rod] table or [[rod]] tables (one per rod), not "
                             "both") from None
        raise SceneError(f"{p}: invalid TOML: {exc}") from None
    except OSError as exc:
        raise SceneError(f"{p}: cannot read: {exc.strerror or exc}") from None
    return parse_scene(doc, p)


def _mixes_rod_tables(path: str) -> bool:
    """Whether the file has both a ``[rod]`` and a ``[[rod]]`` header (TOML rejects that; say so plainly)."""
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError:
        return False
    heads = {m.group(1) for m in re.finditer(r"^\s*(\[\[?)\s*rod\s*\]\]?\s*(?:#.*)?$", text, re.M)}
    return heads == {"[", "[["}


def scene_to_toml(spec: SceneSpec, *, base_dir: str | os.PathLike | None = None) -> str:
    """The TOML text of a SceneSpec (all keys written explicitly).

    ``base_dir``: the folder the text will be saved in; mesh ``file`` paths are then written relative to it,
    so the saved scene finds its meshes wherever it is written (without it, as they were loaded)."""
    lines = ["[sim]"]
    for k in ("dt", "gravity", "damping", "newton_tol", "newton_max_iter", "accept_unconverged", "mode",
              "integrator", "line_search", "newton_dtol", "divergence_guard"):
        lines.append(f"{k} = {format_value(getattr(spec.sim, k))}")
    single = len(spec.rods) == 1 and getattr(spec.rods[0], "name", _bc.ROD_NAME) == _bc.ROD_NAME
    for rod in spec.rods:
        lines += ["", "[rod]" if single else "[[rod]]"]
        if not single:
            lines.append(f"name = {format_value(rod.name)}")
        lines += _rod_lines(rod)
    extra = _obs.dump_obstacles(spec.obstacles, base_dir=base_dir)
    if extra:
        lines += [""] + list(extra)
    lines += [""] + list(_obs.dump_contact(spec.contact))
    for extra in (_bc.dump_fixes(spec.fixes), _bc.dump_loads(spec.loads), _bc.dump_line_loads(spec.line_loads),
                  _bc.dump_drag(spec.drag)):
        if extra:
            lines += [""] + extra
    return "\n".join(lines) + "\n"


def _rod_lines(rod: RodSpec) -> list[str]:
    """The key lines of one rod table (without its header and name)."""
    lines = []
    sec = getattr(rod, "cross_section", "circle")
    keys = {"circle": ("radius",), "rectangle": ("cross_section", "width", "height"),
            "ellipse": ("cross_section", "semi_axes")}[sec]
    shape = ("nodes", "length", "start", "direction") if rod.rest_points is None else ()
    for k in ("nodes", "length", *keys, "density", "youngs_modulus", "poisson_ratio", "start", "direction",
              "clamp"):
        if k in ("nodes", "length", "start", "direction") and k not in shape:
            continue
        v = getattr(rod, k)
        per_edge = getattr(rod, f"edge_{k}", None) if k in ("radius", "youngs_modulus") else None
        if per_edge is not None:
            v = per_edge
        lines.append(f"{k} = {format_value(list(v) if isinstance(v, tuple) else v)}")
    if getattr(rod, "prestretch", 0.0):
        lines.append(f"prestretch = {format_value(rod.prestretch)}")
    if rod.rest_points is not None:
        lines.append("rest_points = [" + ", ".join(format_value(list(p)) for p in rod.rest_points) + "]")
    if getattr(rod, "natural_curvature", None) is not None:
        lines.append("natural_curvature = [" + ", ".join(format_value(list(p)) for p in rod.natural_curvature) + "]")
    return lines


def dump_scene(spec: SceneSpec, path: str | os.PathLike) -> None:
    """Write ``spec`` as TOML to ``path`` atomically (``sim.support.atomicio``: usual file mode); mesh paths relative to it."""
    p = Path(path)
    write_text(p, scene_to_toml(spec, base_dir=p.resolve().parent), mkdir=False)
