"""Obstacles at run time: geometry in the Model, poses in the State, world arrays derived for the contact kernels.

* :class:`ObstacleGeometry` (``Model.obstacles``): what never changes — kinds, box half extents, mesh triangles and
  BVHs in each mesh's local frame, per-obstacle friction, and each obstacle's spec pose (its start).
* The State's plain arrays (:data:`OBSTACLE_ARRAYS`, leading axis B, M obstacles): ``obstacle_position`` (B, M, 3)
  [m], ``obstacle_orientation`` (B, M, 4) wxyz, ``obstacle_a`` / ``obstacle_b`` (B, M, 3) [m] local geometry
  (capsule ends, sphere centre, plane point / normal), ``obstacle_radius`` (B, M) [m], ``obstacle_active`` (B, M)
  bool. Written directly or through :func:`set_pose`, :func:`set_capsules`, :func:`set_active` (the Simulator's
  ``set_obstacle_pose`` / ``set_capsules`` / ``set_obstacle_active``); copied with the state.
* :class:`ObstacleWorld` (owned by a Simulator): the world arrays the kernels read (end points, rotations, AABBs),
  derived from the poses by :func:`world_arrays`, the one function that does it, before each step.
* :func:`contact_data` joins geometry, world arrays, the state's radius and active flags and the kernels' work space
  (:class:`ContactScratch`) into the :class:`ContactData` the kernels read: the one route, used by the step, the
  static solver, the scene check and the tests.
"""
from __future__ import annotations

from collections import namedtuple
from collections.abc import Sequence

import numpy as np

from sim.contact.mesh import build_bvh, cylinder_triangles, load_mesh_triangles
from sim.geometry.rotations import quat_to_matrix, quat_z_to
from sim.scene.kinds import KIND_CODES
from sim.scene.obstacles import (
    BoxSpec,
    CapsuleSpec,
    CylinderSpec,
    MeshSpec,
    ObstacleSpec,
    PlaneSpec,
    SphereSpec,
)

__all__ = ["ObstacleGeometry", "ObstacleWorld", "OBSTACLE_ARRAYS", "world_arrays", "set_pose", "set_capsules",
           "set_active", "SpecPoses", "spec_contact_data", "ContactData", "ContactScratch", "contact_scratch", "contact_data", "contact_radii",
           "node_radii"]

REPORT_CAPACITY = 64
PAIR_REPORT_CAPACITY = 64  # more StepStats contact rows when edge pairs may touch: two per pair in touch

ContactData = namedtuple("ContactData", [
    "kind", "p0", "p1", "rot", "obstacle_radius", "half", "mesh_root", "tri", "node_lo", "node_hi", "node_child",
    "node_range", "cand", "cand_count", "broadphase_radius", "active", "box", "scratch_f", "scratch_m", "scratch_i",
    "friction", "cand_merge"])
ContactData.__doc__ = "Arrays read by :mod:`sim.contact.obstacles` (fields documented there); a numba namedtuple."
# the kernels' per-env work space: candidate pairs, their count, the rod's largest radius, scratch, and the buffer
# merge_candidates merges candidate lists in
ContactScratch = namedtuple("ContactScratch", ["cand", "cand_count", "broadphase_radius", "scratch_f",
                                               "scratch_m", "scratch_i", "cand_merge"])
#: the State's per-env obstacle arrays (see the module docstring)
OBSTACLE_ARRAYS = ("obstacle_position", "obstacle_orientation", "obstacle_a", "obstacle_b", "obstacle_radius",
                   "obstacle_active")


def contact_scratch(envs: int, n_nodes: int, count: int, edge_radius) -> ContactScratch:
    """Work space of the contact kernels for ``envs`` envs of a rod of ``n_nodes`` nodes and ``count`` obstacles;
    the largest of ``edge_radius`` [m] (one value, or one per edge) is the broad phase's inflation
    (``broadphase_radius``)."""
    B = int(envs)
    return ContactScratch(
        cand=np.zeros((B, max(int(n_nodes) * int(count), 1), 2), dtype=np.int64),
        cand_merge=np.zeros((B, 2 * max(int(n_nodes) * int(count), 1), 2), dtype=np.int64),
        cand_count=np.zeros(B, dtype=np.int64), broadphase_radius=np.array([float(np.max(edge_radius))]),
        scratch_f=np.zeros((B, 128)), scratch_m=np.zeros((B, 2, 6, 6)),
        scratch_i=np.zeros((B, 128), dtype=np.int64))


def contact_radii(edge_radius) -> np.ndarray:
    """The contact kernels' ``radius`` argument: (1,) for a rod of one radius, else the (N-1,) edge radii [m]."""
    er = np.asarray(edge_radius, dtype=np.float64).reshape(-1)
    return er[:1].copy() if np.all(er == er[0]) else er.copy()


def node_radii(edge_radius) -> np.ndarray:
    """(N,) radius [m] at each node of a rod with (N-1,) edge radii: the larger of a node's two edges', the rule
    the contact kernels use for plane contact (sim.contact.imc.node_radius)."""
    er = np.asarray(edge_radius, dtype=np.float64).reshape(-1)
    return np.concatenate([er[:1], np.maximum(er[:-1], er[1:]), er[-1:]])


def contact_data(geometry: "ObstacleGeometry", world: "ObstacleWorld", state, scratch: ContactScratch) -> ContactData:
    """The kernels' view of the obstacles of ``state`` (its radius and active arrays; ``world`` derived from its
    poses by :meth:`ObstacleWorld.update`) with the work space ``scratch``."""
    g = geometry
    return ContactData(g.kind, world.p0, world.p1, world.rot, state.obstacle_radius, g.half, g.mesh_root, g.tri,
                       g.node_lo, g.node_hi, g.node_child, g.node_range, scratch.cand, scratch.cand_count,
                       scratch.broadphase_radius, state.obstacle_active, world.box, scratch.scratch_f,
                       scratch.scratch_m, scratch.scratch_i, g.friction, scratch.cand_merge)


class ObstacleGeometry:
    """What never changes of a scene's M obstacles (``Model.obstacles``): kinds, box half extents, mesh triangles and
    BVHs (local frames), per-obstacle friction and the spec poses. Shared, never copied."""

    def __init__(self, specs: Sequence[ObstacleSpec] = ()) -> None:
        self.specs = tuple(specs)
        M = len(self.specs)
        self.kind = np.array([KIND_CODES[s.type] for s in self.specs], dtype=np.int64)  # type: ignore
        self.half = np.zeros((M, 3))
        # per-obstacle Coulomb μ; -1 = the [contact] friction (the kernels' scalar μ)
        self.friction = np.array([-1.0 if s.friction is None else float(s.friction) for s in self.specs])
        self.mesh_root = -np.ones(M, dtype=np.int64)
        self.mesh_box = np.zeros((M, 2, 3))  # local AABB of each mesh
        tris, lo, hi, ch, rg = [], [], [], [], []
        ntri = nnode = 0
        seen: dict[tuple, int] = {}
        for i, s in enumerate(self.specs):
            if isinstance(s, BoxSpec):
                self.half[i] = s.half_extents
            elif isinstance(s, (MeshSpec, CylinderSpec)):
                if isinstance(s, CylinderSpec):  # a closed 48-sided prism along local z, centred at the origin
                    length = float(np.linalg.norm(np.subtract(s.end, s.start)))
                    key = ("cylinder", length, float(s.radius))
                else:
                    key = (s.path or s.file, s.scale)
                if key not in seen:
                    t, l_, h_, c_, r_ = build_bvh(cylinder_triangles(key[1], key[2]) if isinstance(s, CylinderSpec)
                                                  else load_mesh_triangles(s.path or s.file, s.scale))
                    c_ = np.where(c_ >= 0, c_ + nnode, -1)
                    r_ = r_.copy()
                    r_[:, 0] += ntri
                    seen[key] = nnode
                    tris.append(t)
                    lo.append(l_)
                    hi.append(h_)
                    ch.append(c_)
                    rg.append(r_)
                    ntri += t.shape[0]
                    nnode += l_.shape[0]
                root = seen[key]
                self.mesh_root[i] = root
                self.mesh_box[i, 0] = np.concatenate(lo)[root]
                self.mesh_box[i, 1] = np.concatenate(hi)[root]
        self.tri = np.concatenate(tris) if tris else np.zeros((0, 3, 3))
        self.node_lo = np.concatenate(lo) if lo else np.zeros((0, 3))
        self.node_hi = np.concatenate(hi) if hi else np.zeros((0, 3))
        self.node_child = np.concatenate(ch).astype(np.int64) if ch else np.zeros((0, 2), dtype=np.int64)
        self.node_range = np.concatenate(rg).astype(np.int64) if rg else np.zeros((0, 2), dtype=np.int64)
        # each obstacle's spec pose and local geometry: where every env starts
        self.position0 = np.zeros((M, 3))
        self.orientation0 = np.tile(np.array([1.0, 0.0, 0.0, 0.0]), (M, 1))
        self.a0 = np.zeros((M, 3))
        self.b0 = np.zeros((M, 3))
        self.radius0 = np.zeros(M)
        for i, s in enumerate(self.specs):
            if isinstance(s, PlaneSpec):
                self.a0[i], self.b0[i] = s.point, s.normal
            elif isinstance(s, SphereSpec):
                self.a0[i], self.radius0[i] = s.center, s.radius
            elif isinstance(s, CapsuleSpec):
                self.a0[i], self.b0[i], self.radius0[i] = s.start, s.end, s.radius
            elif isinstance(s, (BoxSpec, MeshSpec)):
                self.position0[i], self.orientation0[i] = s.position, s.orientation
            elif isinstance(s, CylinderSpec):  # the prism's frame: centre at the axis midpoint, z along the axis
                a, b = np.asarray(s.start, np.float64), np.asarray(s.end, np.float64)
                self.position0[i], self.orientation0[i] = 0.5 * (a + b), quat_z_to(b - a)

    @classmethod
    def from_specs(cls, specs: Sequence[ObstacleSpec]) -> "ObstacleGeometry":
        return cls(specs)

    def __deepcopy__(self, memo) -> "ObstacleGeometry":  # immutable: copies of a Model share it
        return self

    @property
    def count(self) -> int:
        """Number of obstacles M (the solver skips every contact call when 0)."""
        return len(self.specs)

    @property
    def report_capacity(self) -> int:
        """Capacity C of the per-env contact rows in StepStats (0 without obstacles)."""
        return REPORT_CAPACITY if self.count else 0

    @property
    def capsule_ids(self) -> np.ndarray:
        """Indices of the capsule obstacles, in scene order."""
        return np.flatnonzero(self.kind == KIND_CODES["capsule"])

    def effective_friction(self, default: float) -> np.ndarray:
        """(M,) Coulomb μ of each obstacle: its own ``friction`` or ``default`` (the [contact] friction)."""
        return np.where(self.friction >= 0.0, self.friction, float(default))

    def initial_arrays(self, envs: int) -> dict[str, np.ndarray]:
        """The State's :data:`OBSTACLE_ARRAYS` of ``envs`` envs at the spec poses (new arrays)."""
        B, M = int(envs), self.count
        return {"obstacle_position": np.broadcast_to(self.position0, (B, M, 3)).copy(),
                "obstacle_orientation": np.broadcast_to(self.orientation0, (B, M, 4)).copy(),
                "obstacle_a": np.broadcast_to(self.a0, (B, M, 3)).copy(),
                "obstacle_b": np.broadcast_to(self.b0, (B, M, 3)).copy(),
                "obstacle_radius": np.broadcast_to(self.radius0, (B, M)).copy(),
                "obstacle_active": np.ones((B, M), dtype=np.bool_)}

    def shapes(self, envs: int) -> dict[str, tuple[tuple[int, ...], type]]:
        """(shape, dtype) of each of the State's obstacle arrays for ``envs`` envs (the step's input check)."""
        B, M = int(envs), self.count
        return {"obstacle_position": ((B, M, 3), np.float64), "obstacle_orientation": ((B, M, 4), np.float64),
                "obstacle_a": ((B, M, 3), np.float64), "obstacle_b": ((B, M, 3), np.float64),
                "obstacle_radius": ((B, M), np.float64), "obstacle_active": ((B, M), np.bool_)}


def world_arrays(g: ObstacleGeometry, position: np.ndarray, orientation: np.ndarray, a: np.ndarray, b: np.ndarray,
                 radius: np.ndarray, p0: np.ndarray, p1: np.ndarray, rot: np.ndarray, box: np.ndarray) -> None:
    """The world arrays of poses (k, M, ...) into ``p0``, ``p1`` (k, M, 3) [m], ``rot`` (k, M, 3, 3), ``box``
    (k, M, 2, 3) [m] (in place): capsule / sphere / plane points in the world (a plane's ``p1`` its world normal),
    each obstacle's rotation, and its world AABB (padded by its radius; planes unbounded)."""
    if position.shape[1] == 0 or position.shape[0] == 0:
        return
    R = quat_to_matrix(orientation)  # (k, m, 3, 3), normalised there
    la = np.einsum("kmij,kmj->kmi", R, a) + position
    lb_rot = np.einsum("kmij,kmj->kmi", R, b)
    kind = g.kind[None, :, None]
    rad = radius[..., None]
    q1 = np.where(kind == KIND_CODES["plane"], lb_rot, lb_rot + position)
    p0[...] = la
    p1[...] = q1
    rot[...] = R
    lo = np.minimum(la, q1) - rad
    hi = np.maximum(la, q1) + rad
    sph = kind == KIND_CODES["sphere"]
    lo = np.where(sph, la - rad, lo)
    hi = np.where(sph, la + rad, hi)
    for code in (KIND_CODES["box"], KIND_CODES["mesh"]):
        sel = g.kind == code
        if not np.any(sel):
            continue
        if code == KIND_CODES["box"]:
            c_loc = np.zeros((int(sel.sum()), 3))
            h_loc = g.half[sel]
        else:
            mb = g.mesh_box[sel]
            c_loc = 0.5 * (mb[:, 0] + mb[:, 1])
            h_loc = 0.5 * (mb[:, 1] - mb[:, 0])
        Rs = R[:, sel]
        c = np.einsum("kmij,mj->kmi", Rs, c_loc) + position[:, sel]
        ext = np.einsum("kmij,mj->kmi", np.abs(Rs), h_loc)
        lo[:, sel] = c - ext
        hi[:, sel] = c + ext
    pl = g.kind == KIND_CODES["plane"]
    lo[:, pl] = -np.inf
    hi[:, pl] = np.inf
    box[:, :, 0] = lo
    box[:, :, 1] = hi


class ObstacleWorld:
    """The world arrays of B envs' obstacles (``p0``, ``p1``, ``rot``, ``box``, see :func:`world_arrays`), a
    Simulator's work space: :meth:`update` derives them from a state's poses when those changed."""

    _POSE = ("obstacle_position", "obstacle_orientation", "obstacle_a", "obstacle_b", "obstacle_radius")

    def __init__(self, geometry: ObstacleGeometry, envs: int):
        B, M = int(envs), geometry.count
        self.geometry = geometry
        self.p0 = np.zeros((B, M, 3))
        self.p1 = np.zeros((B, M, 3))
        self.rot = np.zeros((B, M, 3, 3))
        self.box = np.zeros((B, M, 2, 3))
        self._seen: tuple[np.ndarray, ...] | None = None  # the poses the arrays were derived from

    def update(self, state) -> "ObstacleWorld":
        """Derive the world arrays from ``state``'s poses, for the envs whose poses differ from the ones last
        derived from (all of them the first time)."""
        if self.geometry.count == 0:
            return self
        poses = tuple(getattr(state, n) for n in self._POSE)
        if self._seen is None:
            _unit_orientations(poses[1])
            world_arrays(self.geometry, *poses, self.p0, self.p1, self.rot, self.box)
            self._seen = tuple(p.copy() for p in poses)
            return self
        if all(np.array_equal(p, q) for p, q in zip(poses, self._seen)):  # the usual step: nothing moved
            return self
        B = poses[0].shape[0]
        changed = np.zeros(B, dtype=bool)
        for p, q in zip(poses, self._seen):
            changed |= (p != q).reshape(B, -1).any(axis=1)  # NaN != NaN: a NaN pose is derived (and quarantined)
        if not changed.any():  # NaN poses seen before (array_equal never calls NaN equal)
            return self
        e = np.flatnonzero(changed)
        _unit_orientations(poses[1][e])
        out = [a[e] for a in (self.p0, self.p1, self.rot, self.box)]
        world_arrays(self.geometry, *(p[e] for p in poses), *out)
        for a, o in zip((self.p0, self.p1, self.rot, self.box), out):
            a[e] = o
        for p, q in zip(poses, self._seen):
            q[e] = p[e]
        return self


def _unit_orientations(q: np.ndarray) -> None:
    """Refuse a zero quaternion among the obstacle orientations ``q`` (..., 4); NaN passes (the quarantine's: the
    env fails and its poses are reset)."""
    n = np.linalg.norm(q, axis=-1)
    if (np.isfinite(n) & (n < 1e-12)).any():
        raise ValueError("state.obstacle_orientation: a quaternion is zero; write unit quaternions wxyz")


def _env_ids(envs, B: int) -> np.ndarray:
    if envs is None:
        return np.arange(B)
    e = np.asarray(envs)
    if e.dtype == np.bool_:
        if e.shape != (B,):
            raise ValueError(f"env mask must have shape ({B},), got {e.shape}")
        return np.flatnonzero(e)
    e = np.atleast_1d(e).astype(np.int64)
    if e.size and (e.min() < 0 or e.max() >= B):
        raise ValueError(f"env ids out of range [0, {B}): {e}")
    return e


def _obstacle_id(g: ObstacleGeometry, i: int) -> int:
    if not 0 <= int(i) < g.count:
        raise IndexError(f"obstacle index {i} out of range [0, {g.count})")
    return int(i)


def set_pose(g: ObstacleGeometry, state, i: int, position, orientation_wxyz=(1.0, 0.0, 0.0, 0.0), *,
             envs=None) -> None:
    """Set obstacle ``i``'s pose in ``state``: ``position`` (3,) or (k, 3) [m], ``orientation_wxyz`` (4,) or (k, 4)
    (normalised here), for ``envs`` (default all; indices or a (B,) mask)."""
    i = _obstacle_id(g, i)
    ids = _env_ids(envs, state.obstacle_position.shape[0])
    p = np.broadcast_to(np.asarray(position, dtype=np.float64), (len(ids), 3))
    q = np.broadcast_to(np.asarray(orientation_wxyz, dtype=np.float64), (len(ids), 4))
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(q))) or np.any(np.linalg.norm(q, axis=1) < 1e-12):
        raise ValueError("set_pose: position/orientation must be finite and the quaternion non-zero")
    state.obstacle_position[ids, i] = p
    state.obstacle_orientation[ids, i] = q / np.linalg.norm(q, axis=1, keepdims=True)


def set_capsules(g: ObstacleGeometry, state, env_ids, starts, ends, radius, *, obstacle_ids=None) -> None:
    """Re-place capsules per env in ``state`` (vectorised, e.g. at reset).

    ``starts``/``ends`` (k, m, 3) [m] world end points for envs ``env_ids`` (k,) and the m capsule obstacles
    ``obstacle_ids`` (default: all capsules in scene order); ``radius`` scalar, (m,) or (k, m) [m]. The capsules'
    poses are reset to identity for those envs.
    """
    ids = _env_ids(env_ids, state.obstacle_position.shape[0])
    obs = g.capsule_ids if obstacle_ids is None else np.asarray(obstacle_ids, dtype=np.int64)
    if np.any(g.kind[obs] != KIND_CODES["capsule"]):
        raise ValueError("set_capsules: obstacle_ids must all be capsules")
    k, m = len(ids), len(obs)
    a = np.asarray(starts, dtype=np.float64)
    b = np.asarray(ends, dtype=np.float64)
    if a.shape != (k, m, 3) or b.shape != (k, m, 3):
        raise ValueError(f"set_capsules: starts/ends must have shape ({k}, {m}, 3), got {a.shape}, {b.shape}")
    rad = np.broadcast_to(np.asarray(radius, dtype=np.float64), (k, m))
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))) or np.any(~(rad > 0)):
        raise ValueError("set_capsules: end points must be finite and radius > 0")
    ix = np.ix_(ids, obs)
    state.obstacle_a[ix] = a
    state.obstacle_b[ix] = b
    state.obstacle_radius[ix] = rad
    state.obstacle_position[ix] = 0.0
    state.obstacle_orientation[ix] = np.array([1.0, 0.0, 0.0, 0.0])


def set_active(g: ObstacleGeometry, state, i: int, active: bool, *, envs=None) -> None:
    """Enable/disable obstacle ``i`` in ``state`` for ``envs`` (disabled obstacles cost nothing)."""
    state.obstacle_active[_env_ids(envs, state.obstacle_active.shape[0]), _obstacle_id(g, i)] = bool(active)


class SpecPoses:
    """Obstacle arrays of ``envs`` envs at the spec poses (:meth:`ObstacleGeometry.initial_arrays` as attributes),
    for the kernels' data outside a State (the scene check, the derivatives' linearisation)."""

    def __init__(self, geometry: ObstacleGeometry, envs: int):
        for name, a in geometry.initial_arrays(envs).items():
            setattr(self, name, a)


def spec_contact_data(geometry: ObstacleGeometry, envs: int, n_nodes: int, edge_radius, *,
                      candidates: int | None = None, active=None) -> ContactData:
    """:func:`contact_data` of ``envs`` envs with every obstacle at its spec pose and a work space for
    ``candidates`` obstacles per node (default all M; 0 where no contact is computed); ``active`` (envs, M) bool
    replaces the active flags."""
    poses = SpecPoses(geometry, envs)
    if active is not None:
        poses.obstacle_active[...] = active
    world = ObstacleWorld(geometry, envs).update(poses)
    count = geometry.count if candidates is None else int(candidates)
    return contact_data(geometry, world, poses, contact_scratch(envs, n_nodes, count, edge_radius))
