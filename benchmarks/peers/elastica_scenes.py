"""PyElastica (explicit Cosserat rod) versions of the benchmark scenes.

PyElastica is an optional peer (``pip install rodlab[peers]``); importing this module without it
raises an ``ImportError`` that says so.  Written against the installed PyElastica API (1.0: damping
through ``AnalyticalLinearDamper``, clamps through ``OneEndFixedBC``, rigid ``Cylinder`` +
``RodCylinderContact``).  The settings follow docs/tasks.md §1.6 (the paper's Elastica variant):

* position Verlet, ``dt`` = 2e-4 s for the arm;
* base clamp ``OneEndFixedBC``: position of node 0 and the director of element 0 fixed
  (DisMech instead locks nodes 0 *and* 1 and θ⁰; the effective root differs by up to one edge);
* the PyElastica 0.2.4 internal damping ``nu`` (force ``ν v l`` per node, torque ``ν ω l`` per
  element) is reproduced exactly with ``AnalyticalLinearDamper``'s physical protocol
  (translational constant ``ν l_node``, rotational constant ``ν l_elem``);
* frame mapping: the arm is built in Elastica coordinates whose x and y are swapped relative to the
  world, rod direction +z, normal +x in Elastica coordinates (+y world); all positions read back are
  swapped again, so Elastica's director d1 is world +y and d2 world +x;
* actuation: a DisMech integrated curvature increment ``(Δκ̄1, Δκ̄2)`` at interior node ``n`` and a
  twist increment ``Δm̄`` become ``rest_kappa[:, n-1] += (Δκ̄1, -Δκ̄2, -Δm̄) / l_n`` (``l_n`` the
  Voronoi length).

Arrays handed in and out are node-major and in world coordinates: ``(R, N, 3)`` [m] for ``R`` rods of
``N`` nodes.  One :class:`ElasticaRods` simulator can hold several identical rods (several envs in one
PyElastica simulator, which is how throughput is measured).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

try:
    import elastica as ea
except ImportError as exc:  # pragma: no cover - exercised only without the extra
    raise ImportError("PyElastica is not installed: pip install 'rodlab[peers]' "
                      "(or pip install pyelastica)") from exc

__all__ = ["RodSpec", "CylinderSpec", "ElasticaRods", "elastica_version", "stable_dt_estimate", "run_static",
           "run_dynamic", "run_arm"]


def elastica_version() -> str:
    from elastica.version import VERSION
    return str(VERSION)


@dataclass(frozen=True)
class RodSpec:
    """A straight rod.  ``start``/``direction``/``normal`` in world coordinates; SI units.

    ``damping``: ``None``; ``("paper", ν)`` = PyElastica 0.2.4 internal damping with coefficient ν
    [N s/m²]; ``("uniform", γ)`` = velocity and angular velocity decay rate γ [1/s]
    (equivalent to a DER viscous force ``-η l v`` with ``η = γ ρ A``).
    """

    n_nodes: int = 21
    length: float = 1.0
    radius: float = 0.05
    density: float = 1000.0
    youngs: float = 1e7
    poisson: float = 0.5
    start: tuple[float, float, float] = (0.0, 0.0, 0.0)
    direction: tuple[float, float, float] = (0.0, 0.0, 1.0)
    normal: tuple[float, float, float] = (0.0, 1.0, 0.0)  # world; = +x in Elastica coordinates
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.8)
    damping: tuple[str, float] | None = ("paper", 10.0)
    clamp: bool = True
    swap_xy: bool = True  # the paper's frame mapping (docs/tasks.md §1.6)

    def __post_init__(self):
        if self.n_nodes < 5:
            raise ValueError(f"RodSpec.n_nodes must be >= 5 (PyElastica needs > 3 elements), got {self.n_nodes}")
        for name in ("length", "radius", "density", "youngs"):
            if not getattr(self, name) > 0:
                raise ValueError(f"RodSpec.{name} must be positive")
        if self.damping is not None and self.damping[0] not in ("paper", "uniform"):
            raise ValueError(f"RodSpec.damping kind must be 'paper' or 'uniform', got {self.damping[0]!r}")


@dataclass(frozen=True)
class CylinderSpec:
    """Rigid fixed cylinder obstacle (world coordinates): axis from ``start`` to ``end`` [m]."""

    start: tuple[float, float, float]
    end: tuple[float, float, float]
    radius: float


@dataclass
class ElasticaRods:
    """``n_rods`` identical rods in one PyElastica simulator, optional fixed cylinders per rod.

    ``obstacles``: one list of :class:`CylinderSpec` shared by every rod (each rod gets its own copy
    of the cylinders, so rods never interact).  ``contact_k`` [N/m], ``contact_nu`` [N s/m]: the
    ``RodCylinderContact`` parameters (paper: 1.6e5 and 4.0).
    """

    spec: RodSpec
    n_rods: int = 1
    dt: float = 2e-4
    obstacles: tuple[CylinderSpec, ...] = ()
    contact_k: float = 1.6e5
    contact_nu: float = 4.0
    time: float = field(default=0.0, init=False)

    def __post_init__(self):
        if self.n_rods < 1:
            raise ValueError("ElasticaRods.n_rods must be >= 1")
        if not self.dt > 0:
            raise ValueError("ElasticaRods.dt must be positive")
        self._build()

    # -- frame mapping ------------------------------------------------------------------------
    def _to_el(self, v) -> np.ndarray:
        v = np.asarray(v, dtype=float)
        return v[..., [1, 0, 2]] if self.spec.swap_xy else v.copy()

    _to_world = _to_el  # the swap is its own inverse

    def _build(self) -> None:
        sp = self.spec

        class _Sim(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping, ea.Contact):
            pass

        sim = _Sim()
        n_el = sp.n_nodes - 1
        self.rods = []
        self.cylinders = []
        G = sp.youngs / (2.0 * (1.0 + sp.poisson))
        for _ in range(self.n_rods):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                rod = ea.CosseratRod.straight_rod(
                    n_el, self._to_el(sp.start), self._to_el(sp.direction), self._to_el(sp.normal),
                    sp.length, sp.radius, sp.density, youngs_modulus=sp.youngs, shear_modulus=G)
            sim.append(rod)
            self.rods.append(rod)
            if sp.clamp:
                sim.constrain(rod).using(ea.OneEndFixedBC, constrained_position_idx=(0,),
                                         constrained_director_idx=(0,))
            if any(sp.gravity):
                sim.add_forcing_to(rod).using(ea.GravityForces, acc_gravity=self._to_el(sp.gravity))
            if sp.damping is not None:
                kind, c = sp.damping
                if kind == "uniform":
                    sim.dampen(rod).using(ea.AnalyticalLinearDamper, uniform_damping_constant=c,
                                          time_step=self.dt)
                else:  # 0.2.4 semantics: force nu*v*l_node, torque nu*omega*l_elem
                    l_node = rod.mass / (sp.density * np.pi * sp.radius**2)
                    sim.dampen(rod).using(ea.AnalyticalLinearDamper,
                                          translational_damping_constant=c * l_node,
                                          rotational_damping_constant=c * rod.rest_lengths.copy(),
                                          time_step=self.dt)
            for ob in self.obstacles:
                a = self._to_el(ob.start)
                b = self._to_el(ob.end)
                axis = b - a
                ln = float(np.linalg.norm(axis))
                axis /= ln
                nrm = (np.array([0.0, -axis[2], axis[1]]) if abs(axis[0]) < abs(axis[1])
                       else np.array([-axis[2], 0.0, axis[0]]))
                if np.linalg.norm(nrm) < 1e-9:
                    nrm = np.array([0.0, 1.0, 0.0]) if abs(axis[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
                nrm /= np.linalg.norm(nrm)
                cyl = ea.Cylinder(a, axis, nrm, ln, ob.radius, 1000.0)
                sim.append(cyl)
                sim.constrain(cyl).using(ea.OneEndFixedBC, constrained_position_idx=(0,),
                                         constrained_director_idx=(0,))
                sim.detect_contact_between(rod, cyl).using(ea.RodCylinderContact, k=self.contact_k,
                                                           nu=self.contact_nu)
                self.cylinders.append(cyl)
        sim.finalize()
        self.sim = sim
        self.stepper = ea.PositionVerlet()
        self.voronoi = self.rods[0].rest_voronoi_lengths.copy()  # (N-2,) [m]

    # -- state access (world frame, node-major) -------------------------------------------------
    def node_pos(self) -> np.ndarray:
        """(R, N, 3) node positions [m]."""
        return self._to_world(np.stack([r.position_collection.T for r in self.rods]))

    def node_vel(self) -> np.ndarray:
        """(R, N, 3) node velocities [m/s]."""
        return self._to_world(np.stack([r.velocity_collection.T for r in self.rods]))

    def set_node_vel(self, v: np.ndarray) -> None:
        """Set node velocities from a (R, N, 3) or (N, 3) world array [m/s]."""
        v = np.broadcast_to(self._to_el(v), (self.n_rods, self.spec.n_nodes, 3))
        for r, vr in zip(self.rods, v):
            r.velocity_collection[...] = vr.T

    def tip_directors(self) -> np.ndarray:
        """(R, 3, 3) world-frame DisMech-convention tip frame, rows (m1, m2, t) (docs/tasks.md §1.6)."""
        out = []
        for r in self.rods:
            D = self._to_world(r.director_collection[:, :, -1])  # rows d1, d2, d3 in world coords
            out.append(np.stack([-D[1], -D[0], D[2]]) if self.spec.swap_xy else D)
        return np.stack(out)

    def has_nan(self) -> bool:
        return any(not np.all(np.isfinite(r.position_collection)) for r in self.rods)

    # -- actuation -----------------------------------------------------------------------------
    def _check_mapping(self) -> None:
        sp = self.spec
        if not (sp.swap_xy and np.allclose(sp.direction, (0, 0, 1)) and np.allclose(sp.normal, (0, 1, 0))):
            raise ValueError("ElasticaRods: the DisMech->Elastica curvature mapping needs the paper's "
                             "arm frame (swap_xy=True, direction +z, world normal +y)")

    def add_natural_curvature(self, d_kappa: np.ndarray, d_twist: np.ndarray | None = None) -> None:
        """Add DisMech-convention integrated natural curvature increments.

        ``d_kappa`` (R, N, 2) or (N, 2) [dimensionless], rows 0 and N-1 ignored; ``d_twist`` (R, N)
        or (N,) [rad].  Converted with the paper's rule (module docstring).
        """
        self._check_mapping()
        N = self.spec.n_nodes
        dk = np.broadcast_to(np.asarray(d_kappa, float), (self.n_rods, N, 2))
        inv_l = 1.0 / self.voronoi
        for i, r in enumerate(self.rods):
            r.rest_kappa[0, :] += dk[i, 1:-1, 0] * inv_l
            r.rest_kappa[1, :] += -dk[i, 1:-1, 1] * inv_l
        if d_twist is not None:
            dt_ = np.broadcast_to(np.asarray(d_twist, float), (self.n_rods, N))
            for i, r in enumerate(self.rods):
                r.rest_kappa[2, :] += -dt_[i, 1:-1] * inv_l

    def set_natural_curvature(self, kappa: np.ndarray) -> None:
        """Set (not add) the integrated natural curvature, (R, N, 2) or (N, 2)."""
        self._check_mapping()
        N = self.spec.n_nodes
        k = np.broadcast_to(np.asarray(kappa, float), (self.n_rods, N, 2))
        inv_l = 1.0 / self.voronoi
        for i, r in enumerate(self.rods):
            r.rest_kappa[0, :] = k[i, 1:-1, 0] * inv_l
            r.rest_kappa[1, :] = -k[i, 1:-1, 1] * inv_l

    # -- time stepping -------------------------------------------------------------------------
    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps of ``dt``."""
        st, sim, dt = self.stepper, self.sim, np.float64(self.dt)
        t = np.float64(self.time)
        for _ in range(int(n)):
            t = st.step(sim, t, dt)
        self.time = float(t)


def stable_dt_estimate(spec: RodSpec, *, safety: float = 0.5) -> float:
    """Explicit (position Verlet) stability estimate [s] for a Cosserat rod, times ``safety``.

    Two limits bind in practice: the axial wave CFL ``l / sqrt(E/ρ)`` (runs blew up at 1.0x and
    were stable at 0.7x of it) and the shear-rotation mode of one element, ``2/ω`` with
    ``ω² = α G A / (ρ I)``, i.e. ``r sqrt(ρ / (α G))`` (α = 4/3), independent of ``l`` (heavy
    cantilever r = 2 cm, N = 11/21: stable at 0.85x, unstable at 1.2x).  The estimate is
    ``min(0.8 axial, shear_rot)``; the default safety 0.5 gives 2e-4 s for the paper arm (N = 21),
    the paper's dt.  The arm (N = 21) ran at 2.5e-4 s and blew up at 3e-4 s.
    """
    l = spec.length / (spec.n_nodes - 1)
    G = spec.youngs / (2 * (1 + spec.poisson))
    axial = l / np.sqrt(spec.youngs / spec.density)
    shear_rot = spec.radius * np.sqrt(spec.density / (4.0 / 3.0 * G))
    return safety * min(0.8 * axial, shear_rot)


# ------------------------------------------------------------------------------------------------
# Runners of the accuracy scenes (benchmarks.scenes).  Each returns a dict with the wall time of the
# whole run "wall_s" [s], the simulated time "sim_s" [s], "stable" (no NaN / blow-up) and the sampled
# output.  Setup (rod construction, finalize, numba warm-up) is not timed.
# ------------------------------------------------------------------------------------------------
import time as _time  # noqa: E402


def _blown(rods: ElasticaRods, scale: float) -> bool:
    """NaN, a node far away, or an edge stretched/compressed by more than 50 % (explicit blow-up)."""
    p = rods.node_pos()
    if (not np.all(np.isfinite(p))) or float(np.max(np.abs(p))) > 100.0 * scale:
        return True
    l0 = rods.spec.length / (rods.spec.n_nodes - 1)
    strain = np.linalg.norm(np.diff(p, axis=1), axis=-1) / l0 - 1.0
    return bool(np.max(np.abs(strain)) > 0.5)


def run_static(scene, *, n_nodes: int, dt: float) -> dict:
    """Heavy cantilever (scenes.StaticCantilever) until ``scene.t_end``; tip (x, z) at the end."""
    spec = RodSpec(n_nodes=n_nodes, length=scene.length, radius=scene.radius, density=scene.density,
                   youngs=scene.youngs, poisson=scene.poisson, direction=(1.0, 0.0, 0.0),
                   normal=(0.0, 0.0, 1.0), gravity=(0.0, 0.0, -scene.g),
                   damping=("uniform", scene.damping), swap_xy=False)
    rods = ElasticaRods(spec, dt=dt)
    rods.step(1)
    n = int(round(scene.t_end / dt))
    chunk = max(1, int(round(0.1 / dt)))
    t0, c0 = _time.perf_counter(), _time.process_time()
    done, stable = 1, True
    while done < n:
        k = min(chunk, n - done)
        rods.step(k)
        done += k
        if _blown(rods, scene.length):
            stable = False
            break
    wall, cpu = _time.perf_counter() - t0, _time.process_time() - c0
    tip = rods.node_pos()[0, -1]
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": done * dt, "stable": stable, "tip": [tip[0], tip[2]]}


def run_dynamic(scene, *, n_nodes: int, dt: float, sample_dt: float = 0.01) -> dict:
    """Euler-Bernoulli cantilever (scenes.DynamicCantilever); tip z sampled every ``sample_dt``."""
    spec = RodSpec(n_nodes=n_nodes, length=scene.length, radius=scene.radius, density=scene.density,
                   youngs=scene.youngs, poisson=scene.poisson, direction=(1.0, 0.0, 0.0),
                   normal=(0.0, 0.0, 1.0), gravity=(0.0, 0.0, 0.0), damping=None, swap_xy=False)
    rods = ElasticaRods(spec, dt=dt)
    x = np.linspace(0.0, scene.length, n_nodes)
    v = np.zeros((n_nodes, 3))
    v[:, 2] = scene.beam.initial_velocity(x)
    v[0] = 0.0
    rods.set_node_vel(v)
    per = max(1, int(round(sample_dt / dt)))
    n_samples = int(np.floor(scene.t_end / (per * dt) + 1e-9))
    ts, zs = [0.0], [0.0]
    stable = True
    t0, c0 = _time.perf_counter(), _time.process_time()
    for k in range(n_samples):
        rods.step(per)
        ts.append(rods.time)
        zs.append(float(rods.node_pos()[0, -1, 2]))
        if _blown(rods, scene.length):
            stable = False
            break
    wall, cpu = _time.perf_counter() - t0, _time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": rods.time, "stable": stable, "t": ts, "z": zs}


def segment_distances(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances [m] between the segments of polyline ``p`` (N, 3) and the segment ``a``-``b``."""
    p0, p1 = p[:-1], p[1:]
    out = np.empty(len(p0))
    for k in range(len(p0)):  # small N: clamped closest points, sampled refinement for robustness
        u = p1[k] - p0[k]
        v = b - a
        w = p0[k] - a
        A, B, C, D, E = u @ u, u @ v, v @ v, u @ w, v @ w
        den = A * C - B * B
        s = np.clip((B * E - C * D) / den, 0, 1) if den > 1e-14 else 0.0
        t = np.clip((B * s + E) / C, 0, 1)
        s = np.clip((B * t - D) / A, 0, 1)
        out[k] = np.linalg.norm(p0[k] + s * u - (a + t * v))
    return out


def run_arm(scene, *, n_nodes: int, dt: float, sample_dt: float = 0.05) -> dict:
    """Paper arm with the curvature command of scenes.ArmCommand / ArmPress (set before every
    step); tip position (K, 3) [m] sampled every ``sample_dt``; with ArmPress also the cylinder and
    the max penetration [m] (rod radius + cylinder radius - centreline distance) over the samples."""
    spec = RodSpec(n_nodes=n_nodes, length=scene.length, radius=scene.radius, density=scene.density,
                   youngs=scene.youngs, poisson=scene.poisson, gravity=(0.0, 0.0, -scene.g),
                   damping=("uniform", scene.damping))
    cyl = getattr(scene, "cyl_ends", None)
    obst = (CylinderSpec(cyl[0], cyl[1], scene.cyl_radius),) if cyl else ()
    rods = ElasticaRods(spec, dt=dt, obstacles=obst)
    pen = 0.0
    per = max(1, int(round(sample_dt / dt)))
    n_samples = int(np.floor(scene.t_end / (per * dt) + 1e-9))
    ts, tips = [0.0], [rods.node_pos()[0, -1].tolist()]
    stable = True
    t0, c0 = _time.perf_counter(), _time.process_time()
    step = 0
    for k in range(n_samples):
        for _ in range(per):
            step += 1
            rods.set_natural_curvature(scene.integrated_kappa(step * dt, n_nodes))
            rods.step(1)
        ts.append(rods.time)
        pos = rods.node_pos()[0]
        tips.append(pos[-1].tolist())
        if cyl:
            d = segment_distances(pos, np.asarray(cyl[0], float), np.asarray(cyl[1], float))
            pen = max(pen, float(scene.radius + scene.cyl_radius - d.min()))
        if _blown(rods, scene.length):
            stable = False
            break
    wall, cpu = _time.perf_counter() - t0, _time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": rods.time, "stable": stable, "t": ts, "tip": tips,
            "max_penetration": max(0.0, pen)}
