"""One place that checks every scene number and every simulator API input (docs/conventions.md, "Input bounds").

* :func:`check_scene` - every number of a :class:`~sim.scene.spec.SceneSpec` is finite and inside the physical
  bounds of :data:`BOUNDS`; derived quantities (node mass, stiffnesses) are finite and positive. Called by
  ``parse_scene`` (errors name the file) and by ``build_model`` (specs built in code). Raises
  :class:`~sim.scene.tomlio.SceneError` naming the file, the key and the problem.
* :func:`check_step_inputs` - ``Simulator.step`` arguments: type, shape, dtype of every field (named).
* :func:`quarantine_nonfinite` - envs whose state holds NaN/inf are marked failed and their state is
  replaced by the rest configuration (time kept), so no NaN is passed on.
* :func:`env_mask` - ``reset_envs`` selection: boolean mask or integer indices (never guessed).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from sim.scene.boundary import check_boundary
from sim.scene.section import SECTIONS, section_of
from sim.scene.tomlio import SceneError

CLAMPS = ("first_edge", "node", "none")  # [rod] clamp (sim/scene/spec.py; docs/physics.md §3.6)

__all__ = ["BOUNDS", "check_scene", "check_step_inputs", "quarantine_nonfinite", "env_mask", "unit_vector",
           "bounds_table"]

# key -> (lowest, highest, unit). Closed intervals; (0, x] written as lowest = 0 with "exclusive" below.
BOUNDS: dict[str, tuple[float, float, str]] = {
    "sim.dt": (1e-9, 1e5, "s"),
    "sim.gravity": (-1e4, 1e4, "m/s^2"),
    "sim.damping": (0.0, 1e9, "1/s"),
    "sim.newton_tol": (1e-300, 1e6, "-"),
    "sim.newton_max_iter": (1, 10_000, "-"),
    "sim.newton_dtol": (1e-300, 1e6, "m/s"),
    "sim.divergence_guard": (0.0, 1e12, "-"),
    "rod.nodes": (3, 10_000, "-"),
    "rod.length": (1e-6, 1e4, "m"),
    "rod.radius": (1e-7, 1e2, "m"),
    "rod.density": (1e-3, 1e6, "kg/m^3"),
    "rod.youngs_modulus": (1.0, 1e13, "Pa"),
    "rod.start": (-1e6, 1e6, "m"),
    "rod.rest_points": (-1e6, 1e6, "m"),
    "rod.width": (1e-7, 1e2, "m"),
    "rod.height": (1e-7, 1e2, "m"),
    "rod.semi_axes": (1e-7, 1e2, "m"),
    "rod.prestretch": (-0.5, 0.5, "-"),
    "rod.natural_curvature": (-10.0, 10.0, "-"),
    "load.force": (-1e9, 1e9, "N"),
    "load.torque": (-1e9, 1e9, "N m"),
    "load.moment": (-1e9, 1e9, "N m"),
    "line_load.force_per_length": (-1e9, 1e9, "N/m"),
    "drag.normal": (0.0, 1e9, "N s/m^2"),
    "drag.tangential": (0.0, 1e9, "N s/m^2"),
    "drag.flow": (-1e4, 1e4, "m/s"),
    "line_load.start": (0.0, 1e9, "s"),
    "load.start": (0.0, 1e9, "s"),
    "fix.velocity": (-1e3, 1e3, "m/s"),
    "fix.twist_rate": (-1e4, 1e4, "rad/s"),
    "fix.angular_velocity": (-1e4, 1e4, "rad/s"),
    "fix.center": (-1e4, 1e4, "m"),
    "fix.start": (0.0, 1e9, "s"),
    "obstacle.coordinates": (-1e6, 1e6, "m"),
    "obstacle.radius": (1e-6, 1e4, "m"),
    "obstacle.half_extents": (1e-6, 1e4, "m"),
    "obstacle.scale": (1e-6, 1e6, "-"),
    "contact.stiffness": (1e-6, 1e15, "N/m"),
    "contact.delta": (1e-9, 1e3, "m"),
    "contact.friction": (0.0, 1e3, "-"),
    "contact.friction_velocity_tol": (1e-12, 1e6, "m/s"),
    "contact.margin": (0.0, 1e6, "m"),
    "contact.max_penetration": (1e-12, 1e12, "m"),  # a huge value turns the penetration guard off
}
_UNIT_TOL = 1e-9  # a stored direction / normal / quaternion must be unit to this tolerance


def bounds_table() -> str:
    """The markdown table of :data:`BOUNDS` (docs/conventions.md quotes it)."""
    rows = ["| key | lowest | highest | unit |", "|---|---|---|---|"]
    rows += [f"| `{k}` | {lo:g} | {hi:g} | {u} |" for k, (lo, hi, u) in BOUNDS.items()]
    return "\n".join(rows)


def unit_vector(v: Any, where: str) -> tuple[float, ...]:
    """``v`` / |v| without overflow or underflow (scaled by its largest component first); SceneError if zero
    or not finite."""
    a = np.asarray(v, dtype=np.float64)
    if not np.all(np.isfinite(a)):
        raise SceneError(f"{where}: must be finite, got {list(v)}")
    big = float(np.max(np.abs(a))) if a.size else 0.0
    if not big > 0.0:
        raise SceneError(f"{where}: must be a non-zero vector, got {list(v)}")
    a = a / big
    a = a / float(np.sqrt(np.sum(a * a)))
    return tuple(float(c) for c in a)


class _Checker:
    def __init__(self, where: str) -> None:
        self.where = where

    def fail(self, key: str, msg: str) -> None:
        raise SceneError(f"{self.where}: {key}: {msg}")

    def num(self, key: str, v: Any, bound: str | None = None, *, positive: bool = False) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
            self.fail(key, f"expected a number, got {type(v).__name__} {v!r}")
        x = float(v)
        if not math.isfinite(x):
            self.fail(key, f"must be finite, got {x!r}")
        if positive and not x > 0:
            self.fail(key, f"must be > 0, got {x!r}")
        lo, hi, unit = BOUNDS[bound or key]
        if not lo <= x <= hi:
            self.fail(key, f"must be within [{lo:g}, {hi:g}] {unit} (docs/conventions.md, Input bounds), got {x!r}")
        return x

    def integer(self, key: str, v: Any, bound: str | None = None) -> int:
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            self.fail(key, f"expected an integer, got {type(v).__name__} {v!r}")
        lo, hi, _ = BOUNDS[bound or key]
        if not lo <= int(v) <= hi:
            self.fail(key, f"must be an integer within [{lo:g}, {hi:g}], got {v!r}")
        return int(v)

    def vec(self, key: str, v: Any, bound: str, n: int = 3) -> np.ndarray:
        if not isinstance(v, (tuple, list, np.ndarray)) or len(v) != n:
            self.fail(key, f"expected {n} numbers, got {v!r}")
        for c in v:
            self.num(key, c, bound)
        return np.asarray(v, dtype=np.float64)

    def unit(self, key: str, v: Any, n: int = 3) -> None:
        if not isinstance(v, (tuple, list, np.ndarray)) or len(v) != n:
            self.fail(key, f"expected {n} numbers, got {v!r}")
        a = np.asarray(v, dtype=np.float64)
        if not np.all(np.isfinite(a)) or abs(float(np.linalg.norm(a)) - 1.0) > _UNIT_TOL:
            self.fail(key, f"must be a finite unit vector (normalised when loaded), got {list(v)}")

    def choice(self, key: str, v: Any, choices: tuple) -> None:
        if v not in choices:
            self.fail(key, f"must be one of {list(choices)}, got {v!r}")


def check_scene(spec: Any, where: str | None = None) -> None:
    """Check every number of ``spec`` against :data:`BOUNDS` (and derived masses/stiffnesses); raise
    SceneError naming ``where`` (default ``spec.path``), the key and the problem."""
    c = _Checker(where or getattr(spec, "path", None) or "<scene>")
    s = spec.sim
    c.num("sim.dt", s.dt, positive=True)
    c.vec("sim.gravity", s.gravity, "sim.gravity")
    c.num("sim.damping", s.damping)
    c.num("sim.newton_tol", s.newton_tol, positive=True)
    c.integer("sim.newton_max_iter", s.newton_max_iter)
    c.num("sim.newton_dtol", s.newton_dtol, positive=True)
    g = c.num("sim.divergence_guard", s.divergence_guard)
    if 0.0 < g <= 1.0:
        c.fail("sim.divergence_guard", f"must be 0 (off) or > 1 (a residual growth factor), got {g!r}")
    if not isinstance(s.accept_unconverged, (bool, np.bool_)):
        c.fail("sim.accept_unconverged", f"expected true/false, got {s.accept_unconverged!r}")
    c.choice("sim.mode", s.mode, ("3d", "2d"))
    c.choice("sim.integrator", s.integrator, ("backward_euler", "midpoint"))
    c.choice("sim.line_search", s.line_search, ("none", "backtrack", "auto"))
    rods = tuple(getattr(spec, "rods", None) or (spec.rod,))
    names = [getattr(r, "name", "rod") for r in rods]
    for i, name in enumerate(names):
        if not isinstance(name, str) or not name.strip():
            c.fail(f"rod[{i}].name", f"must be a non-empty name, got {name!r}")
        if name in names[:i]:
            c.fail(f"rod[{i}].name", f"duplicate rod name {name!r} (rod names must be unique)")
    for r, name in zip(rods, names):
        _check_rod(c, r, s.mode, f"rod[{name!r}]." if len(rods) > 1 else "rod.")
    if s.mode == "2d" and len(rods) > 1:  # one motion plane: every rod at the first rod's y
        y0 = _first_point(rods[0])[1]
        for r, name in zip(rods[1:], names[1:]):
            if _first_point(r)[1] != y0:
                c.fail(f"rod[{name!r}].start", f"mode '2d' needs every rod in one plane y = const (the first "
                                                 f"rod's y = {y0!r}), got y = {_first_point(r)[1]!r}")
    for i, ob in enumerate(getattr(spec, "obstacles", ()) or ()):
        _check_obstacle(c, i, ob)
    _check_contact(c, spec.contact)
    check_boundary(c, spec)


def _first_point(r: Any) -> tuple:
    pts = getattr(r, "rest_points", None)
    return tuple(pts[0]) if pts is not None else tuple(r.start)


def _check_rod(c: _Checker, r: Any, mode: str, rp: str) -> None:
    """The keys of one rod table (``rp``: its key prefix in messages, ``rod.`` or ``rod['name'].``)."""
    n = c.integer(rp + "nodes", r.nodes, "rod.nodes")
    if getattr(r, "rest_points", None) is not None:  # before length: it is the points' (sim/scene/spec.py)
        _check_rest_points(c, r, n, mode, rp)
    length = c.num(rp + "length", r.length, "rod.length", positive=True)
    sec = _check_section(c, r, rp)  # before radius: for a non-circular section radius is derived from it
    radius = c.num(rp + "radius", r.radius, "rod.radius", positive=True)
    rho = c.num(rp + "density", r.density, "rod.density", positive=True)
    E = c.num(rp + "youngs_modulus", r.youngs_modulus, "rod.youngs_modulus", positive=True)
    # per-edge lists (a non-uniform rod): one value per edge, each within the key's bounds; the derived checks
    # below then use the smallest
    er = _edge_list(c, rp + "radius", "rod.radius", getattr(r, "edge_radius", None), n)
    if er is not None:
        if sec is not None:
            c.fail(rp + "radius", 'a per-edge list needs cross_section = "circle"')
        radius = min(er)
    eE = _edge_list(c, rp + "youngs_modulus", "rod.youngs_modulus", getattr(r, "edge_youngs_modulus", None), n)
    if eE is not None:
        E = min(eE)
    nu = r.poisson_ratio
    if isinstance(nu, bool) or not isinstance(nu, (int, float, np.floating)) or not -1.0 < float(nu) <= 0.5:
        c.fail(rp + "poisson_ratio", f"must be in (-1, 0.5], got {nu!r}")
    c.vec(rp + "start", r.start, "rod.start")
    c.unit(rp + "direction", r.direction)
    c.choice(rp + "clamp", r.clamp, CLAMPS)
    c.num(rp + "prestretch", getattr(r, "prestretch", 0.0), "rod.prestretch")
    nat = getattr(r, "natural_curvature", None)
    if nat is not None:
        if not isinstance(nat, (tuple, list, np.ndarray)) or len(nat) != n:
            c.fail(rp + "natural_curvature", f"expected rod.nodes = {n} pairs [kappa1, kappa2], got "
                                             f"{len(nat) if hasattr(nat, '__len__') else nat!r}")
        for pair in nat:
            c.vec(rp + "natural_curvature", pair, "rod.natural_curvature", n=2)
    # derived quantities (docs/physics.md §1.5): all must be positive normal floats
    seg = length / (n - 1)
    if sec is None:
        area = math.pi * radius * radius
        derived = {"node mass [kg]": rho * area * seg / 2.0, "EA [N]": E * area,
                   "EI [N m^2]": E * math.pi * radius ** 4 / 4.0,
                   "twist inertia [kg m^2]": rho * math.pi * radius ** 4 / 2.0 * seg}
    else:
        derived = {"node mass [kg]": rho * sec.area * seg / 2.0, "EA [N]": E * sec.area,
                   "EI [N m^2]": E * min(sec.I1, sec.I2), "GJ [N m^2]": E * sec.J / 3.0,
                   "twist inertia [kg m^2]": rho * sec.polar * seg}
    for name, val in derived.items():
        if not (math.isfinite(val) and val > 1e-290):
            c.fail(rp.rstrip("."), f"derived {name} = {val!r} is not a positive finite number (check radius, "
                                   "length, density, youngs_modulus)")


def _edge_list(c: _Checker, key: str, bound: str, v: Any, n: int) -> list[float] | None:
    """A per-edge list (None if absent): n - 1 numbers within the bounds of ``key``."""
    if v is None:
        return None
    if not isinstance(v, (tuple, list, np.ndarray)) or len(v) != n - 1:
        c.fail(key, f"a per-edge list needs one value per edge (rod.nodes - 1 = {n - 1}), got "
                    f"{len(v) if hasattr(v, '__len__') else v!r}")
    return [c.num(key, x, bound, positive=True) for x in v]


def _check_rest_points(c: _Checker, r: Any, n: int, mode: str, rp: str = "rod.") -> None:
    """rest_points: n finite points within the bounds, no zero edge, no turn of 170° or more, planar in 2-D."""
    pts = r.rest_points
    if not isinstance(pts, (tuple, list, np.ndarray)) or len(pts) != n:
        c.fail(rp + "rest_points", f"expected rod.nodes = {n} points, got {len(pts) if hasattr(pts, '__len__') else pts!r}")
    for p in pts:
        c.vec(rp + "rest_points", p, "rod.rest_points")
    x = np.asarray(pts, dtype=np.float64)
    e = np.diff(x, axis=0)
    le = np.linalg.norm(e, axis=1)
    if not (le > 1e-7).all():
        j = int(np.argmin(le))
        c.fail(rp + "rest_points", f"points {j} and {j + 1} are {le[j]:.3g} m apart (edges must be > 1e-07 m)")
    t = e / le[:, None]
    cosang = np.einsum("ij,ij->i", t[:-1], t[1:])
    if cosang.size and cosang.min() <= math.cos(math.radians(170.0)):
        i = int(np.argmin(cosang)) + 1
        c.fail(rp + "rest_points", f"the polyline turns by {math.degrees(math.acos(max(-1.0, cosang.min()))):.1f} "
                                  f"deg at point {i} (must be < 170 deg)")
    if mode == "2d" and np.abs(x[:, 1] - x[0, 1]).max() > 0.0:
        c.fail(rp + "rest_points", "mode '2d' needs every point in one plane y = const (the first point's y)")


def _check_section(c: _Checker, r: Any, rp: str = "rod.") -> Any:
    """Cross-section keys (sim/scene/section.py); returns the Section of a non-circular rod, else None."""
    kind = getattr(r, "cross_section", "circle")
    c.choice(rp + "cross_section", kind, SECTIONS)
    if kind == "circle":
        return None
    if kind == "rectangle":
        for k in ("width", "height"):
            c.num(rp + k, getattr(r, k), "rod." + k, positive=True)
    else:
        c.vec(rp + "semi_axes", r.semi_axes, "rod.semi_axes", 2)
        for v in r.semi_axes:
            c.num(rp + "semi_axes", v, "rod.semi_axes", positive=True)
    return section_of(r)


def _check_obstacle(c: _Checker, i: int, ob: Any) -> None:
    p = f"obstacle[{i}]."
    typ = getattr(ob, "type", None)
    if typ == "plane":
        c.vec(p + "point", ob.point, "obstacle.coordinates")
        c.unit(p + "normal", ob.normal)
    elif typ == "sphere":
        c.vec(p + "center", ob.center, "obstacle.coordinates")
        c.num(p + "radius", ob.radius, "obstacle.radius", positive=True)
    elif typ == "capsule":
        c.vec(p + "start", ob.start, "obstacle.coordinates")
        c.vec(p + "end", ob.end, "obstacle.coordinates")
        c.num(p + "radius", ob.radius, "obstacle.radius", positive=True)
    elif typ == "cylinder":
        c.vec(p + "start", ob.start, "obstacle.coordinates")
        c.vec(p + "end", ob.end, "obstacle.coordinates")
        c.num(p + "radius", ob.radius, "obstacle.radius", positive=True)
    elif typ == "box":
        c.vec(p + "position", ob.position, "obstacle.coordinates")
        c.vec(p + "half_extents", ob.half_extents, "obstacle.half_extents")
        c.unit(p + "orientation", ob.orientation, 4)
    elif typ == "mesh":
        c.vec(p + "position", ob.position, "obstacle.coordinates")
        c.vec(p + "scale", ob.scale, "obstacle.scale")
        c.unit(p + "orientation", ob.orientation, 4)
    else:
        c.fail(p + "type", f"unknown obstacle type {typ!r}")
    if getattr(ob, "friction", None) is not None:
        c.num(p + "friction", ob.friction, "contact.friction")


def _check_contact(c: _Checker, ct: Any) -> None:
    c.num("contact.stiffness", ct.stiffness, positive=True)
    c.num("contact.delta", ct.delta, positive=True)
    c.num("contact.friction", ct.friction)
    c.num("contact.friction_velocity_tol", ct.friction_velocity_tol, positive=True)
    c.num("contact.margin", ct.margin)
    if ct.max_penetration is not None:
        c.num("contact.max_penetration", ct.max_penetration, positive=True)


# ---------------------------------------------------------------------------------------------- API inputs
def state_arrays(state: Any) -> tuple[str, ...]:
    """The per-env arrays of a State, read from its dataclass fields (those typed np.ndarray): the list
    ``sim.state.STATE_ARRAYS`` is made of (sim.state imports this module). ``()`` for an object that is not a
    dataclass."""
    if not dataclasses.is_dataclass(state):
        return ()
    return tuple(f.name for f in dataclasses.fields(state) if f.type in ("np.ndarray", np.ndarray))




def _array(obj: Any, owner: str, name: str, shape: tuple, dtype: Any, *, writable: bool) -> np.ndarray:
    """``obj.name`` checked: an ndarray of ``shape`` and ``dtype`` (state: exactly; ctrl, not writable: any
    real integer/float dtype, converted to float64 by the step)."""
    if not hasattr(obj, name):
        raise ValueError(f"{owner}.{name}: missing (expected a {owner.capitalize()} object, got "
                         f"{type(obj).__name__})")
    a = getattr(obj, name)
    if not isinstance(a, np.ndarray):
        raise ValueError(f"{owner}.{name}: expected a numpy array of shape {shape}, got {type(a).__name__}")
    if a.dtype != np.dtype(dtype) and (writable or a.dtype.kind not in "iuf"):
        kind = {"O": "object", "U": "str", "S": "bytes", "c": "complex"}.get(a.dtype.kind, a.dtype.name)
        raise ValueError(f"{owner}.{name}: expected dtype {np.dtype(dtype).name}, got {kind} "
                         f"(no implicit cast; convert with np.asarray(..., dtype=np.{np.dtype(dtype).name}))")
    if a.shape != shape:
        raise ValueError(f"{owner}.{name}: expected shape {shape}, got {a.shape}")
    if writable and (not a.flags.c_contiguous or not a.flags.writeable):
        raise ValueError(f"{owner}.{name}: expected a writable C-contiguous {np.dtype(dtype).name} array")
    return a


def check_step_inputs(sim: Any, state: Any, ctrl: Any) -> None:
    """Check ``Simulator.step(state, ctrl)`` arguments; ValueError naming the field and the problem."""
    if state is None or not hasattr(state, "dof"):
        raise ValueError(f"step: state: expected a sim.State (from Simulator.reset()), got {type(state).__name__}")
    if ctrl is None or not hasattr(ctrl, "kappa_bar"):
        raise ValueError(f"step: ctrl: expected a sim.Control (from Simulator.make_control()), got "
                         f"{type(ctrl).__name__}")
    B, N = sim.envs, sim.model.node_count
    nd = 4 if sim.model.mode == "3d" else 2
    want = {"dof": ((B, N, nd), np.float64), "dof_vel": ((B, N, nd), np.float64),
            "edge_ref_d1": ((B, N - 1, 3), np.float64), "edge_tangent": ((B, N - 1, 3), np.float64),
            "node_ref_twist": ((B, N), np.float64), "time": ((B,), np.float64), "failed": ((B,), np.bool_),
            **sim.model.obstacles.shapes(B)}  # the obstacles' poses: (B, M, ...) for the scene's M obstacles
    for name in state_arrays(state) or want:
        if name not in want:
            raise ValueError(f"step: state.{name}: not a field of sim.State")
        _array(state, "state", name, *want[name], writable=True)
    # (a zero obstacle quaternion is refused where the poses are read: sim.contact.world.ObstacleWorld.update)
    for name, shp in (("kappa_bar", (B, N, 2)), ("tau_bar", (B, N))):
        a = _array(ctrl, "ctrl", name, shp, np.float64, writable=False)
        if not np.isfinite(a).all():
            raise ValueError(f"ctrl.{name}: contains NaN or inf")
    if getattr(ctrl, "force", None) is not None:
        a = _array(ctrl, "ctrl", "force", (B, N, 3), np.float64, writable=False)
        if not np.isfinite(a).all():
            raise ValueError("ctrl.force: contains NaN or inf")


def quarantine_nonfinite(sim: Any, state: Any, stats: Any = None, also: np.ndarray | None = None) -> np.ndarray:
    """Envs whose state (dof, dof_vel, frames, twist, time, obstacle poses) holds NaN/inf: mark them failed and
    replace their state by the rest configuration (time kept when finite, else 0; obstacle poses only where they
    were not finite, back to the scene's), so no NaN stays in the state. With
    ``stats``, those envs' StepStats numbers are zeroed and ``stats.failed`` set; ``also``: more envs treated so
    (the ones quarantined before the step). Returns the (B,) mask."""
    floats = [name for name in state_arrays(state) if name != "failed" and not name.startswith("obstacle_")]
    poses = [name for name in state_arrays(state) if name.startswith("obstacle_") and name != "obstacle_active"]
    arrays = [getattr(state, name) for name in floats]  # every state field, before and after
    if stats is not None:  # contact rows: only the filled ones (up to the largest contact_count)
        cmax = int(stats.contact_count.max()) if stats.contact_count.size else 0
        arrays += [a[:, :cmax] if name.startswith("contact_") and name != "contact_force" and a.ndim >= 2 else a
                   for name, a in vars(stats).items() if isinstance(a, np.ndarray) and a.dtype.kind == "f"]
    def nonfinite(arrays_) -> np.ndarray:
        out = np.zeros(state.dof.shape[0], dtype=bool)
        for a in arrays_:
            if a.size and not math.isfinite(float(a.sum())):  # fast path: one sum per array
                out |= ~np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)
        return out

    bad_poses = nonfinite([getattr(state, name) for name in poses])  # obstacles written with NaN: back to spec
    bad = nonfinite(arrays) | bad_poses
    if also is not None and stats is not None:
        bad |= also
    if not bad.any():
        return bad
    fresh = sim.reset()
    t = state.time.copy()
    for name in floats:
        getattr(state, name)[bad] = getattr(fresh, name)[bad]
    for name in poses:  # a failed env keeps its (finite) obstacle poses: the task re-places them at its reset
        getattr(state, name)[bad_poses] = getattr(fresh, name)[bad_poses]
    state.time[bad] = np.where(np.isfinite(t[bad]), t[bad], 0.0)
    state.failed[bad] = True
    if stats is not None:
        for name, a in vars(stats).items():
            if isinstance(a, np.ndarray) and a.dtype.kind in "fiu":
                a[bad] = 0
        stats.failed[bad] = True
        stats.converged[bad] = False
    return bad


def env_mask(sel: Any, envs: int, what: str = "reset_envs") -> np.ndarray:
    """(envs,) bool mask from ``sel``: a boolean array/list of length ``envs`` (a mask), or integer indices
    (a list, tuple, integer array or a single int; negative counts from the end). Anything else (floats,
    mixed bool/int lists, out-of-range indices) raises ValueError."""
    if isinstance(sel, (bool, np.bool_)):
        raise ValueError(f"{what}: expected a boolean mask of length envs or integer env indices, got a bool")
    if isinstance(sel, (int, np.integer)):
        sel = [int(sel)]
    if isinstance(sel, (list, tuple)):
        kinds = {type(x) for x in sel}
        if kinds and all(issubclass(k, (bool, np.bool_)) for k in kinds):
            arr = np.asarray(sel, dtype=bool)
        elif all(issubclass(k, (int, np.integer)) and not issubclass(k, (bool, np.bool_)) for k in kinds):
            arr = np.asarray(sel, dtype=np.int64).reshape(-1)
        else:
            raise ValueError(f"{what}: a list must hold only bools (a mask) or only integers (indices), got "
                             f"{sorted(k.__name__ for k in kinds)}")
    else:
        arr = np.asarray(sel)
    if arr.dtype == np.bool_:
        if arr.shape != (envs,):
            raise ValueError(f"{what}: boolean mask: expected shape ({envs},), got {arr.shape}")
        return arr.copy()
    if arr.dtype.kind not in "iu" or arr.ndim != 1:
        raise ValueError(f"{what}: expected a boolean mask of shape ({envs},) or 1-D integer indices, got "
                         f"dtype {arr.dtype} shape {arr.shape}")
    if arr.size and (arr.min() < -envs or arr.max() >= envs):
        raise ValueError(f"{what}: env index out of range [0, {envs - 1}]: {arr.tolist()}")
    mask = np.zeros(envs, dtype=bool)
    mask[arr] = True
    return mask
