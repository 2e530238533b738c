"""PyElastica (explicit Cosserat rod) arm, shared by the task backend (policies/elastica/backend.py) and the
benchmarks (benchmarks/peers/elastica_scenes.py).

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

Obstacles are rigid ``Cylinder`` bodies, one copy per rod (rods never interact). ``obstacle_hold="bc"``
fixes them with ``OneEndFixedBC``; ``"restore"`` (the task backend, whose obstacles move between episodes)
writes their pose back and zeroes their velocities after every step (``move_obstacles`` places them).

Arrays handed in and out are node-major and in world coordinates: ``(R, N, 3)`` [m] for ``R`` rods of
``N`` nodes.  One :class:`ElasticaRods` simulator can hold several identical rods (several envs in one
PyElastica simulator).
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

__all__ = ["RodSpec", "CylinderSpec", "ElasticaRods", "elastica_version", "stable_dt_estimate",
           "cylinder_pose"]


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
    obstacle_hold: str = "bc"
    time: float = field(default=0.0, init=False)

    def __post_init__(self):
        if self.n_rods < 1:
            raise ValueError("ElasticaRods.n_rods must be >= 1")
        if not self.dt > 0:
            raise ValueError("ElasticaRods.dt must be positive")
        if self.obstacle_hold not in ("bc", "restore"):
            raise ValueError(f"ElasticaRods.obstacle_hold must be 'bc' or 'restore', got {self.obstacle_hold!r}")
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
                axis, nrm, ln = cylinder_pose(a, self._to_el(ob.end))
                cyl = ea.Cylinder(a, axis, nrm, ln, ob.radius, 1000.0)
                sim.append(cyl)
                if self.obstacle_hold == "bc":
                    sim.constrain(cyl).using(ea.OneEndFixedBC, constrained_position_idx=(0,),
                                             constrained_director_idx=(0,))
                sim.detect_contact_between(rod, cyl).using(ea.RodCylinderContact, k=self.contact_k,
                                                           nu=self.contact_nu)
                self.cylinders.append(cyl)
        sim.finalize()
        self.sim = sim
        # pose of every cylinder (rod-major: rod r owns cylinders r*M ... r*M+M-1) for obstacle_hold="restore"
        self._cyl_pos = np.stack([c.position_collection.copy() for c in self.cylinders]) if self.cylinders else None
        self._cyl_dir = np.stack([c.director_collection.copy() for c in self.cylinders]) if self.cylinders else None
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
        restore = self.obstacle_hold == "restore" and self.cylinders
        for _ in range(int(n)):
            t = st.step(sim, t, dt)
            if restore:
                self.hold_obstacles()
        self.time = float(t)

    # -- obstacles -----------------------------------------------------------------------------
    def hold_obstacles(self) -> None:
        """Write the cylinders' poses back and zero their velocities (obstacle_hold="restore")."""
        for c, p, d in zip(self.cylinders, self._cyl_pos, self._cyl_dir):
            c.position_collection[...] = p
            c.director_collection[...] = d
            c.velocity_collection[...] = 0.0
            c.omega_collection[...] = 0.0

    def move_obstacles(self, rod: int, ends: np.ndarray) -> None:
        """Place the cylinders of rod ``rod`` along the world segments ``ends`` (M, 2, 3) [m]."""
        M = len(self.obstacles)
        ends = np.asarray(ends, float)
        if ends.shape != (M, 2, 3):
            raise ValueError(f"move_obstacles: expected ({M}, 2, 3) end points, got {ends.shape}")
        for j in range(M):
            k = rod * M + j
            a = self._to_el(ends[j, 0])
            axis, nrm, ln = cylinder_pose(a, self._to_el(ends[j, 1]))
            c = self.cylinders[k]
            if abs(ln - float(c.length)) > 1e-5 * max(ln, 1.0):  # float32 end points
                raise ValueError(f"move_obstacles: obstacle {j} has length {ln}, the cylinder {float(c.length)}")
            self._cyl_pos[k][:, 0] = a + 0.5 * ln * axis
            self._cyl_dir[k][0, :, 0] = nrm
            self._cyl_dir[k][1, :, 0] = np.cross(axis, nrm)
            self._cyl_dir[k][2, :, 0] = axis
            c.position_collection[...] = self._cyl_pos[k]
            c.director_collection[...] = self._cyl_dir[k]
            c.velocity_collection[...] = 0.0
            c.omega_collection[...] = 0.0


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


def cylinder_pose(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(unit axis, unit normal, length) of the cylinder from ``a`` to ``b`` (Elastica coordinates); the normal
    is any perpendicular (docs/tasks.md §7.2: (0, -a_z, a_y) if |a_x| < |a_y|, else (-a_z, 0, a_x))."""
    axis = np.asarray(b, float) - np.asarray(a, float)
    ln = float(np.linalg.norm(axis))
    if not ln > 0:
        raise ValueError("obstacle with zero length")
    axis = axis / ln
    nrm = (np.array([0.0, -axis[2], axis[1]]) if abs(axis[0]) < abs(axis[1])
           else np.array([-axis[2], 0.0, axis[0]]))
    if np.linalg.norm(nrm) < 1e-9:
        nrm = np.array([0.0, 1.0, 0.0]) if abs(axis[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    return axis, nrm / np.linalg.norm(nrm), ln
